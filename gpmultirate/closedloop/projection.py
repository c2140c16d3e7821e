"""The first stage of closed-loop identification: the part of the input the excitation explains.

In a loop, the plant input ``u`` is the excitation ``r`` plus what the
controller made of the measured output, disturbance included.  A fit of
``y_slow`` on ``u`` then sees an input correlated with the noise, and is
biased where the loop acts.  The two-stage (projection) method removes that
correlation: a model of ``u`` from ``r`` alone gives ``u_r``, the part of
``u`` that ``r`` caused, and the multirate fit runs on ``u_r``; what it
leaves, ``G (u - u_r)``, is independent of ``r`` and joins the noise.

A loop that a slow sensor closes through a hold is periodically time
varying: the response of ``u`` to an impulse of ``r`` depends on where in
the frame the impulse falls.  A time-invariant model of ``u`` from ``r``
is orthogonal to its error only on average over the phases of the frame,
while the slow samples all sit on one phase.  So the first stage can take
one kernel-regularized FIR per phase ``n mod period``:
``u(n) = sum_i h_p(i) r(n - i) + w(n)``, ``p = n mod period``, with ``w``
then orthogonal to every sample of ``r`` at every phase.  The default is
one time-invariant FIR (``period=1``): ``u_r`` depends on ``r`` alone, so
the disturbance's path into the fit is cut whatever the first stage's
error, and on the camera loops of ``benchmarks/closed_loop.py`` the phased
first stage changed the plant's error by less than its spread (least
squares of both stages, 3 loops of 80,000 samples: bias 0.0167 against
0.0158, the direct fit's 0.0715).  Each FIR is a
:class:`~gpmultirate.FIRGaussianProcess` at the fast rate with the prior
``C * TC`` (eq. 16) tuned by its evidence (eq. 19).

The first stage's uncertainty: :meth:`ExcitationModel.sample_inputs`
draws projected inputs from its posterior.  Refitting the plant on such
draws at the tuned hyperparameters moves its frequency response by about
1 % of the posterior variance or less on the camera loops of the benchmark
(:doc:`/closed_loop`), so the bands of the fit are the second stage's
posterior; the suite checks that ratio.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from gpmultirate.kernels import TC
from gpmultirate.validation import check_int

__all__ = ["ExcitationModel", "fit_excitation_model", "project_input", "check_excitation"]

#: First-stage FIR order when none is given: the loop's memory, in fast samples, is
#: covered by this many lags or the record's length over four, whichever is shorter.
DEFAULT_EXCITATION_ORDER = 256


@dataclass(frozen=True)
class ExcitationModel:
    """The first stage's posterior: one FIR from the excitation to the input per phase.

    Attributes
    ----------
    period : int
        The number of phases (the slow sensor's ``factor``; 1 for a
        time-invariant model).
    order : int
        Lags ``0..order-1`` of each FIR.
    coef : ndarray of shape (period, order)
        Posterior mean of ``h_p``; ``coef[p]`` acts on the samples ``n`` with
        ``n mod period = p``.
    covariance : ndarray of shape (period, order, order)
        Posterior covariance of each ``h_p`` (the phases are independent).
    amplitude, decay, noise_level : float
        The tuned prior ``amplitude * TC(decay)`` and the variance of ``w``.
    log_marginal_likelihood : float
        Summed log evidence of the phases at the tuned values.
    explained : float
        Share of the input's power in ``u_r``.
    identity : bool
        True when the excitation is the input itself (open-loop data): ``u_r = u``.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.closedloop import fit_excitation_model
    >>> rng = np.random.default_rng(0)
    >>> r = rng.standard_normal(600)
    >>> u = r + 0.5 * np.concatenate([[0.0], r[:-1]]) + 0.1 * rng.standard_normal(600)
    >>> import gpmultirate as gm
    >>> first = fit_excitation_model(u, r, gm.FIRGaussianProcess, period=2, order=8)
    >>> np.round(first.coef[:, :2], 1)
    array([[1. , 0.5],
           [1. , 0.5]])
    """

    period: int
    order: int
    coef: np.ndarray
    covariance: np.ndarray
    amplitude: float
    decay: float
    noise_level: float
    log_marginal_likelihood: float
    explained: float
    identity: bool = False

    def project(self, excitation, coef=None) -> np.ndarray:
        """``u_r(n) = sum_i h_p(i) r(n - i)`` for the excitation ``r`` (with ``coef`` in place of the mean)."""
        r = np.asarray(excitation, dtype=float)
        if self.identity:
            return r.copy()
        coef = self.coef if coef is None else coef
        regressor = _regressor(r, self.order)
        out = np.empty(r.shape[0])
        for p in range(self.period):
            out[p::self.period] = regressor[p::self.period] @ coef[p]
        return out

    def sample_inputs(self, excitation, n_samples: int, random_state=None) -> np.ndarray:
        """Projected inputs drawn from the first stage's posterior, shape ``(n_samples, N)``."""
        rng = np.random.default_rng(random_state)
        r = np.asarray(excitation, dtype=float)
        if self.identity:
            return np.tile(r, (n_samples, 1))
        roots = [_psd_root(c) for c in self.covariance]
        draws = np.empty((n_samples, r.shape[0]))
        for s in range(n_samples):
            coef = np.array([m + root @ rng.standard_normal(root.shape[1])
                             for m, root in zip(self.coef, roots)])
            draws[s] = self.project(r, coef)
        return draws


def _psd_root(cov: np.ndarray) -> np.ndarray:
    w, v = np.linalg.eigh(0.5 * (cov + cov.T))
    return v * np.sqrt(np.maximum(w, 0.0))


def _regressor(r: np.ndarray, order: int) -> np.ndarray:
    """Rows ``[r(n), r(n-1), ..., r(n-order+1)]`` for ``n = 0..N-1`` (zero before the record)."""
    padded = np.concatenate([np.zeros(order - 1), r])
    return sliding_window_view(padded, order)[:, ::-1]


def check_excitation(excitation, u: np.ndarray) -> np.ndarray:
    """The excitation as a new float array shaped like the one-input, one-record ``u``.

    Raises a ``ValueError`` naming ``excitation`` for a list of records,
    several columns, another length, a non-finite value or a zero signal.
    """
    if isinstance(excitation, (list, tuple)) and excitation and np.ndim(excitation[0]) == 1 \
            and len(excitation[0]) > 1:
        raise ValueError("excitation must be one record: the fit with excitation= takes one")
    try:
        r = np.array(excitation, dtype=float)
    except (TypeError, ValueError):
        raise ValueError("excitation must be a real array of the fast rate, like u") from None
    if r.ndim == 2 and r.shape[1] == 1:
        r = r[:, 0]
    if r.ndim != 1:
        raise ValueError(f"excitation must be 1-D (one record, one input); got shape {r.shape}")
    if r.shape[0] != u.shape[0]:
        raise ValueError(f"excitation must have the length of u ({u.shape[0]}); got {r.shape[0]}")
    if not np.all(np.isfinite(r)):
        raise ValueError("excitation must be finite (no NaN or inf): it is known at every sample")
    if not np.any(r):
        raise ValueError("excitation must not be zero at every sample")
    return r


def fit_excitation_model(u, excitation, estimator, period: int = 1,
                         order: int | None = None) -> ExcitationModel:
    """Tune and condition the first stage: ``u`` from ``excitation``, one FIR per phase.

    Each phase is a :class:`~gpmultirate.FIRGaussianProcess` with the prior
    ``C * TC`` (eq. 16), white noise and ``order`` lags, tuned by its
    evidence (eq. 19): the phase's samples of ``u`` are its "slow" output,
    ``r`` its fast input (``factor=period``, ``offset=p``).

    Parameters
    ----------
    u : array-like of shape (N,)
        The plant input the loop produced.
    excitation : array-like of shape (N,)
        The external signal ``r``, independent of the disturbances.
    estimator : class
        The kernel estimator of each phase, :class:`~gpmultirate.FIRGaussianProcess`
        (the estimator passes its own class: this module does not import it).
    period : int, default=1
        Phases of the loop's time variation (up to the frame's length in
        fast samples for a camera's loop); 1: one time-invariant FIR.
    order : int, optional
        Lags of each FIR; by default ``min(DEFAULT_EXCITATION_ORDER, N // (4 period))``
        (at least 1).

    Returns
    -------
    ExcitationModel
        With ``identity=True`` (no first stage) when ``excitation`` equals ``u``.
    """
    from sklearn.gaussian_process.kernels import ConstantKernel

    u = np.asarray(u, dtype=float).reshape(-1)
    r = check_excitation(excitation, u)
    period = check_int(period, "period", low=1, high=max(1, u.shape[0] // 2))
    power = float(np.mean(u * u))
    if np.array_equal(r, u):
        return ExcitationModel(period, 1, np.ones((period, 1)), np.zeros((period, 1, 1)),
                               1.0, 0.0, 0.0, np.inf, 1.0, identity=True)
    if order is None:
        order = max(1, min(DEFAULT_EXCITATION_ORDER, u.shape[0] // (4 * period)))
    order = check_int(order, "order", low=1, high=u.shape[0])
    lags = np.arange(order)
    coef, covariance, fits = [], [], []
    for p in range(period):
        stage = estimator(ConstantKernel(1.0) * TC(0.9), factor=period, offset=p,
                                   order=order, noise_kernel="white")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the first stage's own order checks: not the user's fit
            stage.fit(r, u[p::period])
        mean, cov = stage.impulse_response(lags, return_cov=True)
        coef.append(mean)
        covariance.append(cov)
        fits.append(stage)
    decay = float(np.mean([f.kernel_.k2.alpha for f in fits]))
    model = ExcitationModel(
        period=period, order=order, coef=np.array(coef), covariance=np.array(covariance),
        amplitude=float(np.mean([f.kernel_.k1.constant_value for f in fits])), decay=decay,
        noise_level=float(np.mean([f.noise_level_ for f in fits])),
        log_marginal_likelihood=float(sum(f.log_marginal_likelihood_value_ for f in fits)),
        explained=0.0)
    projected = model.project(r)
    explained = float(np.mean(projected**2) / power) if power > 0 else 0.0
    return ExcitationModel(**{**model.__dict__, "explained": explained})


def project_input(u, excitation, estimator, period: int = 1, order: int | None = None):
    """The projected input ``u_r`` and the first stage that made it.

    The single call :meth:`gpmultirate.FIRGaussianProcess.fit` makes for
    ``excitation=``; ``u`` is one record of one input.

    Returns
    -------
    u_r : ndarray of shape (N,)
    model : ExcitationModel

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.closedloop import project_input
    >>> u = np.random.default_rng(1).standard_normal(50)
    >>> import gpmultirate as gm
    >>> u_r, first = project_input(u, u, gm.FIRGaussianProcess)  # open loop: r is u
    >>> bool(np.array_equal(u_r, u)), first.identity
    (True, True)
    """
    model = fit_excitation_model(u, excitation, estimator, period=period, order=order)
    return model.project(check_excitation(excitation, np.asarray(u, dtype=float).reshape(-1))), model


def loop_input(u, excitation, estimator):
    """The input a fit runs on, and the first stage: ``(u, None)`` without an excitation.

    With an excitation, ``u`` must be one record of one input; the result is
    ``(u_r, ExcitationModel)`` from :func:`project_input`, whose phases are
    fitted by ``estimator`` (the calling estimator's class).
    """
    if excitation is None:
        return u, None
    if isinstance(u, (list, tuple)) and u and np.ndim(u[0]) >= 1 and isinstance(
            u[0], np.ndarray):
        raise ValueError("excitation is for one record of one input; u is a list of records")
    x = np.asarray(u, dtype=float)
    if x.ndim == 2 and x.shape[1] == 1:
        x = x[:, 0]
    if x.ndim != 1:
        raise ValueError(f"excitation is for one input: u must be 1-D; got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("u must be finite (no NaN or inf)")
    projected, model = project_input(x, excitation, estimator)
    if np.ndim(u) == 2:
        projected = projected[:, None]
    return projected, model
