"""Estimators of fast-rate FIR models from slow-rate output data.

* :class:`FIRGaussianProcess`: the kernel-regularised estimate of eq. (15)
  viewed as a Gaussian-process posterior over continuous lag, with
  marginal-likelihood tuning (eq. 19, noise inside the log-determinant).
* :class:`LeastSquaresFIR`: the least-squares baseline of eq. (11), which
  refuses non-unique problems (Lemma 1 and 2).

Both take one input or several (``u`` of shape ``(N, n_inputs)``), one record
or several (lists), slow samples at ``offset + m * factor`` or at any
``sample_indices``, missing samples as ``NaN``, and the initial conditions
``"zero"`` (at rest, the paper's case), ``"discard"`` or ``"periodic"``.
"""

from __future__ import annotations


import numbers
import warnings

import numpy as np
from scipy import linalg
from sklearn.base import BaseEstimator, clone
from sklearn.gaussian_process.kernels import ConstantKernel, Kernel
from sklearn.utils.validation import check_is_fitted

from gpmultirate import tuning
from gpmultirate.crossvalidation import CrossValidation, contiguous_folds, held_out_predictions
from gpmultirate.exceptions import HeldOutWarning, IdentifiabilityError
from gpmultirate.memory import check_fit_memory
from gpmultirate.export import StateSpaceMixin
from gpmultirate.inference import (
    GaussianCoefficients,
    LogEvidence,
    blas_threads_for,
    gaussian_samples,
)
from gpmultirate.kernels import (
    DC,
    PerInputKernel,
    check_lags,
    input_kernels,
    kernel_for_inputs,
    like_inputs,
    rescaled,
)
from gpmultirate.metrics import fit_percent, goodness_of_fit
from gpmultirate.observations import build_experiment, regressor_rows
from gpmultirate.observations.experiment import check_records, is_record_list
from gpmultirate.resonances import slowest_decay
from gpmultirate.responses import (
    FrequencyResponse,
    check_frequencies,
    default_frequencies,
    dft_matrix,
)
from gpmultirate.validation import (
    check_bounds,
    check_int,
    check_level,
    check_positive,
    check_rng,
    check_signal,
)

__all__ = ["FIRGaussianProcess", "LeastSquaresFIR"]


class _FIRModelMixin:
    """Prediction, scoring and frequency response shared by the FIR estimators.

    Subclasses set ``coef_``, ``operator_``, ``n_inputs_`` and ``posterior_``
    (a :class:`~gpmultirate.inference.GaussianCoefficients` of the
    input-major coefficient vector) in ``fit``, and implement
    ``impulse_response``.
    """

    #: whether the impulse response is defined between the integer lags
    continuous_lags = False

    @property
    def _order(self) -> int:
        return self.operator_.order

    def _shaped(self, flat: np.ndarray) -> np.ndarray:
        """Coefficient-like values ``(n_inputs * n,)`` as ``(n_inputs, n)`` for several inputs."""
        if self.n_inputs_ > 1:
            return flat.reshape(self.n_inputs_, -1)
        return flat

    def _check_prediction_input(self, u, name: str = "u") -> np.ndarray:
        inputs, several_records = check_records(u, name)
        if several_records:
            raise ValueError(f"{name} must be one record here; got a list")
        x = inputs[0]
        if x.shape[1] != self.n_inputs_:
            raise ValueError(
                f"{name} must have {self.n_inputs_} input column(s), as in fit; got {x.shape[1]}"
            )
        return x

    def _fast_rows(self, x: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Rows of the fast-rate regressor of input(s) ``x`` (all inputs side by side)."""
        periodic = self.initial_conditions == "periodic"
        return np.hstack([
            regressor_rows(x[:, k], self._order, rows, periodic=periodic)
            for k in range(x.shape[1])
        ])

    def predict(self, u, return_std: bool = False):
        """Fast-rate output of the model for input ``u``.

        ``y(n) = sum_k sum_i g_k(i) u_k(n - i)`` for ``n = 0..len(u)-1``,
        starting at rest (for ``initial_conditions="periodic"``, in periodic
        steady state: ``u`` is one period).  For the training input this is
        the intersample (fast-rate) response.

        Parameters
        ----------
        u : array-like of shape (n,) or (n, n_inputs), or a list of them
            Fast-rate input, shaped as in ``fit``; a list gives a list.
        return_std : bool, default=False
            Also return the posterior standard deviation of the noise-free
            output (``sqrt(diag(T Sigma T^T))`` with ``T`` the convolution
            matrix of ``u`` and ``Sigma`` the coefficient covariance).

        Returns
        -------
        y : ndarray of shape (n,)
        std : ndarray of shape (n,), only if ``return_std``
        """
        check_is_fitted(self, "coef_")
        if is_record_list(u):
            return [self.predict(u_r, return_std) for u_r in u]
        x = self._check_prediction_input(u)
        n = x.shape[0]
        periodic = self.initial_conditions == "periodic"
        coef = self.posterior_.coef.reshape(self.n_inputs_, -1)
        if not return_std and not periodic:
            return sum(np.convolve(x[:, k], coef[k])[:n] for k in range(x.shape[1]))
        # rows of the convolution matrix in blocks: memory O(block P), not O(n P)
        block = max(1, _PREDICT_BLOCK_ENTRIES // coef.size)
        mean, var = np.empty(n), np.empty(n)
        for start in range(0, n, block):
            rows = np.arange(start, min(start + block, n))
            A = self._fast_rows(x, rows)
            if return_std:
                mean[rows], var[rows] = self.posterior_.linear_map(A)
            else:
                mean[rows] = A @ self.posterior_.coef
        return (mean, np.sqrt(var)) if return_std else mean

    def score(self, u, y_fast) -> float:
        """Goodness of fit in percent (eq. 20) of ``predict(u)`` against ``y_fast``.

        Parameters
        ----------
        u : array-like of shape (n,) or (n, n_inputs)
            Fast-rate validation input.
        y_fast : array-like of shape (n,)
            Fast-rate validation output.

        Returns
        -------
        float
        """
        check_is_fitted(self, "coef_")
        y_fast = check_signal(y_fast, "y_fast")
        x = self._check_prediction_input(u)
        if x.shape[0] != y_fast.shape[0]:
            raise ValueError(
                f"y_fast must have the length of u ({x.shape[0]}); got {y_fast.shape[0]}"
            )
        if np.ptp(y_fast) == 0:
            raise ValueError("y_fast must not be constant: the goodness of fit is undefined")
        return goodness_of_fit(y_fast, self.predict(u))

    def _input(self, input) -> int:
        if input is None:
            if self.n_inputs_ > 1:
                raise ValueError(
                    f"input must be given for a model of {self.n_inputs_} inputs "
                    f"(0..{self.n_inputs_ - 1})"
                )
            return 0
        return check_int(input, "input", low=0, high=self.n_inputs_ - 1)

    def frequency_response(
        self, freqs=None, sample_time: float | None = None, level: float = 0.95, input=None
    ) -> FrequencyResponse:
        """FRF of the identified model with a pointwise credible band.

        Valid at every frequency up to the fast Nyquist frequency, also
        beyond the slow Nyquist frequency ``1 / (2 F T)``.

        Parameters
        ----------
        freqs : array-like of shape (n,), optional
            Frequencies in Hz; by default the DFT bins of the training record.
        sample_time : float, optional
            Fast sample time ``T`` in seconds; by default the model's
            ``sample_time``.
        level : float, default=0.95
            Credible level of the band, in (0, 1).
        input : int, optional
            The input whose FRF is returned; needed for several inputs.

        Returns
        -------
        FrequencyResponse
        """
        check_is_fitted(self, "coef_")
        level = check_level(level)
        k = self._input(input)
        if sample_time is None:
            sample_time = self.sample_time
        if freqs is None:
            sample_time = check_positive(sample_time, "sample_time")
            freqs = default_frequencies(self.operator_.n_samples, sample_time)
        freqs, sample_time = check_frequencies(freqs, sample_time)
        P = self._order
        E = dft_matrix(freqs, sample_time, P)
        # the DFT of input k's block of the input-major coefficients
        A = np.zeros((E.shape[0], self.n_inputs_ * P), dtype=complex)
        A[:, k * P : (k + 1) * P] = E
        re, im = np.ascontiguousarray(A.real), np.ascontiguousarray(A.imag)
        var_re, var_im, cov = self.posterior_.pair_variances(re, im)
        return FrequencyResponse.from_gaussian(
            freqs,
            A @ self.posterior_.coef,
            var_re,
            var_im,
            cov,
            level=level,
            sample_time=sample_time,
            factor=self.operator_.slow_factor,
        )

    def sample_impulse_responses(self, lags=None, n_samples: int = 1, random_state=None):
        """Draw impulse responses from the posterior (for least squares, the estimate's distribution).

        Parameters
        ----------
        lags : array-like of shape (n,), optional
            Lags in fast samples; default ``0..P-1``.
        n_samples : int, default=1
        random_state : int, RandomState or None

        Returns
        -------
        ndarray of shape (n, n_samples), or (n_inputs, n, n_samples) for several inputs
        """
        n_samples = check_int(n_samples, "n_samples", low=1)
        mean, cov = self.impulse_response(lags, return_cov=True)
        draws = gaussian_samples(mean.reshape(-1), cov, n_samples, check_rng(random_state))
        if self.n_inputs_ > 1:
            return draws.reshape(self.n_inputs_, -1, n_samples)
        return draws


# entries of the convolution matrix formed at once by predict(..., return_std=True)
_PREDICT_BLOCK_ENTRIES = 2**22


def _unit_scales(experiment) -> list[float]:
    """Output power per unit input power, one per input: the data's units for the prior."""
    inputs = np.vstack(_record_inputs(experiment))
    power_y = float(np.mean(experiment.y**2)) or 1.0
    return [power_y / (float(np.mean(inputs[:, k] ** 2)) or 1.0) for k in range(inputs.shape[1])]


def _initial_kernel(kernel, experiment, normalize: bool = True):
    """The prior of the fit in the data's units: the user's kernel(s), or the default.

    With ``normalize`` the user's kernel is a prior in normalized units
    (input and output divided by their RMS): each input's amplitudes and
    their bounds are multiplied by that input's unit scale
    (:func:`~gpmultirate.kernels.rescaled`).  The default kernel is
    ``ConstantKernel(c) * DC()`` with ``c`` that scale, bounds ``c * 1e-8 ..
    c * 1e8``, and ``alpha`` at most
    :func:`~gpmultirate.resonances.slowest_decay` of the order: its envelope
    falls at least by ``e^-2`` by lag ``P``.
    """
    n = experiment.n_inputs
    scales = _unit_scales(experiment)
    if kernel is not None:
        kernel = kernel_for_inputs(kernel, n)
        if not normalize:
            return kernel
        kernels = [rescaled(k, c) for k, c in zip(input_kernels(kernel), scales)]
        return like_inputs(kernels, kernel)
    # the FIR model says the response has died out by lag P: the default prior agrees
    slowest = slowest_decay(experiment.observation.order)
    kernels = [
        ConstantKernel(c, (c * 1e-8, c * 1e8))
        * DC(alpha=min(0.9, slowest), alpha_bounds=(1e-4, slowest))
        for c in scales
    ]
    return kernels[0] if n == 1 else PerInputKernel(kernels)


# the held-out check after evidence tuning: its shortest order; the margins in
# percentage points of held-out fit by which a shorter order must predict better
# to replace the default order N, and to be named in a warning for an explicit order
MIN_CHECKED_ORDER = 10
ORDER_MARGIN = 1.0
HELD_OUT_MARGIN = 5.0
# the most slow samples it checks: each candidate order needs M x M matrices
MAX_CHECKED_SAMPLES = 4000


def auto_orders(longest: int) -> list[int]:
    """The candidate orders of ``order="auto"``: ``N, N/2, ..., N/32``, at least 10.

    Examples
    --------
    >>> auto_orders(600)
    [18, 37, 75, 150, 300, 600]
    >>> auto_orders(12)
    [12]
    """
    orders = {longest} | {longest // 2**k for k in range(1, 6) if longest // 2**k >= 10}
    return sorted(orders)


def _order_candidates(order):
    """None for one order (an int or None), "auto", or the checked list of candidates."""
    if order is None or isinstance(order, numbers.Integral) and not isinstance(order, bool):
        return None
    if isinstance(order, str):
        if order == "auto":
            return "auto"
        raise ValueError(f"order must be an integer, 'auto' or a list of integers; got {order!r}")
    try:
        candidates = [check_int(o, "order", low=1) for o in order]
    except TypeError:
        raise ValueError(
            f"order must be an integer, 'auto' or a list of integers; got {order!r}"
        ) from None
    if not candidates:
        raise ValueError("order must not be an empty list")
    return sorted(set(candidates))


def _check_tuning(tuning_criterion) -> str:
    if not isinstance(tuning_criterion, str) or tuning_criterion not in (
        "evidence", "cross_validation"
    ):
        raise ValueError(
            f"tuning must be 'evidence' or 'cross_validation'; got {tuning_criterion!r}"
        )
    return tuning_criterion


def _record_inputs(experiment):
    """The inputs of every record, as ``(N, n_inputs)`` arrays."""
    out = []
    for record in experiment.observation.records:
        u = np.asarray(record.u, dtype=float)
        out.append(u[:, None] if u.ndim == 1 else u)
    return out


class FIRGaussianProcess(StateSpaceMixin, _FIRModelMixin, BaseEstimator):
    """Fast-rate FIR model as a Gaussian process over lag, from slow-rate data.

    The impulse response ``g(t)``, ``t >= 0`` real, has a zero-mean Gaussian
    process prior with covariance ``kernel``; the slow samples
    ``y_slow[m] = sum_{i<P} g(i) u[n_m - i] + e[m]``, ``n_m = offset + m F``
    (or ``sample_indices[m]``), observe it through a
    :class:`~gpmultirate.DownsampledConvolution` (or a
    :class:`~gpmultirate.SampledConvolution`) with white noise of variance
    ``noise_level`` (the ``gamma`` of eq. 15).  The posterior mean at lags
    ``0..P-1`` is the kernel-regularised estimate of eq. (15).

    With several inputs (``u`` of shape ``(N, n_inputs)``) each input has
    its own impulse response ``g_k``; the prior makes them independent, the
    posterior does not.  Several records (lists of ``u`` and ``y_slow``)
    share the hyperparameters and the noise level.

    Parameters
    ----------
    kernel : sklearn Kernel, list of them, or "auto", optional
        Prior covariance over lag; a list gives one kernel per input, and
        one kernel for several inputs is copied for each (each copy tuned
        separately).  Default ``ConstantKernel(c) * DC(alpha=0.9, beta=0.9)``
        per input, with ``c`` and its bounds set from the data, and ``alpha``
        bounded so that the prior's envelope ``alpha^(t/2)`` falls at least
        by ``e^-2`` by lag ``P`` (the FIR model's own assumption: the
        response has died out by then).  ``"auto"``:
        that default plus up to ``max_resonances`` PK terms whose frequencies
        are found from the data (see :mod:`gpmultirate.resonances`).
    factor : int, default=1
        Downsampling factor ``F`` (ignored when ``sample_indices`` are given).
    order : int, "auto" or sequence of int, optional
        FIR order ``P`` in ``1..N``, shared by all inputs.  Default: ``N``,
        the length of the (longest) record, unless the held-out check after
        evidence tuning finds that a shorter order ``N/2, ..., N/32`` (at
        least 10) predicts held-out slow samples more than one point of fit
        better at the tuned hyperparameters; the model is then fitted again
        at the best of them (see *Tuning that generalizes* in the user
        guide).  An integer is used as given.  ``"auto"`` or a list of
        candidate orders: fit each candidate and keep the one the tuning
        criterion (``tuning``) prefers, per used slow sample; ``"auto"``
        tries ``N, N/2, N/4, ..., N/32`` (at least 10).  The candidates and
        their scores are reported in ``order_selection_``.
    offset : int, default=0
        Fast index of the first slow sample, ``0..F-1``.
    noise_level : float, default=1.0
        Noise variance ``gamma``; the initial value when it is tuned.
    noise_level_bounds : pair of floats, "fixed" or "auto", default="auto"
        Bounds for tuning ``noise_level``; ``"auto"`` is
        ``(1e-12, 10) * mean(y_slow**2)``.
    optimizer : "marginal_likelihood" or None, default="marginal_likelihood"
        Tune the free hyperparameters and the noise level by maximising the
        log marginal likelihood (Fisher scoring up to 1000 slow samples after
        the reduction of long records, L-BFGS-B above and, above 200
        coefficients, where the evidence goes through DC's precision; see
        the theory page and :mod:`gpmultirate.tuning`); ``None`` uses them
        exactly as given.
    tuning : {"evidence", "cross_validation"}, default="evidence"
        The criterion the hyperparameters (and an ``"auto"`` order)
        maximize: ``"evidence"``, the log marginal likelihood (eq. 19);
        ``"cross_validation"``, the log density of held-out blocks of slow
        samples predicted from the others (K-fold over time, ``cv`` folds;
        see :mod:`gpmultirate.crossvalidation`), which judges the model by
        what it predicts rather than by how well it explains the data.  It
        works in data space: ``O(M^3)`` per evaluation for ``M`` slow
        samples.  After evidence tuning, the held-out fit of the tuned model
        is compared with that of shorter orders (same folds, same
        hyperparameters): with the default order a clearly better shorter
        order replaces ``N``, with an explicit order a warning names it.
    cv : int, default=5
        The number of folds of ``"cross_validation"`` (and of the held-out
        check after evidence tuning): contiguous blocks of slow samples of
        each record.
    n_restarts_optimizer : int, default=0
        Extra optimizer runs from random points drawn uniformly in the log
        bounds; the best optimum is kept.
    random_state : int, RandomState or None, default=None
        Seed of the restarts.
    initial_conditions : {"zero", "discard", "periodic"}, default="zero"
        ``"zero"``: the system is at rest before the record (the paper's
        case); ``"discard"``: the input before the record is unknown, so
        only slow samples at fast index ``>= order - 1`` are used;
        ``"periodic"``: ``u`` is one period of a periodic input in steady
        state (the regressor is circular).
    sample_time : float, default=1.0
        Fast sample time ``T`` in seconds, used by :meth:`frequency_response`
        (frequencies in Hz), the plots and the exports.  Left at 1.0,
        frequencies are in cycles per sample.
    max_resonances : int, default=4
        With ``kernel="auto"``, the most PK terms the search may add.
    normalize : bool, default=True
        When tuning, read the initial values and bounds of ``kernel``'s
        amplitudes, ``noise_level`` and explicit ``noise_level_bounds`` in
        normalized units: input(s) and output divided by their RMS (as
        scikit-learn's ``normalize_y`` does for the output).  The tuned fit
        then does not depend on the units of ``u`` and ``y``: an amplitude of
        1 (``ConstantKernel(1.0)``) is an impulse response of the size the
        data call for, and scikit-learn's default amplitude bounds
        ``(1e-5, 1e5)`` span that scale.  ``kernel_``, ``noise_level_``, the
        posterior, the bands and the evidence are in the data's units.  With
        ``optimizer=None``, or ``normalize=False``, the kernel and noise
        level are used in the data's units exactly as given.

    Attributes
    ----------
    coef_ : ndarray of shape (P,), or (n_inputs, P) for a 2-D ``u``
        Posterior mean of ``g`` at lags ``0..P-1`` (eq. 15).
    n_inputs_ : int
        The number of inputs.
    kernel_ : sklearn Kernel
        The kernel with the tuned hyperparameters.
    noise_level_ : float
        The tuned (or given) noise variance.
    log_marginal_likelihood_value_ : float
        Log evidence of the slow data at ``kernel_`` and ``noise_level_``
        (scikit-learn's sign and constants: higher is better).
    operator_ : Observation
        The observation operator of the training data: a
        :class:`~gpmultirate.DownsampledConvolution` in the paper's case, a
        :class:`~gpmultirate.SampledConvolution` or a stack of records
        otherwise.
    y_slow_ : ndarray of shape (M,)
        The slow samples the model was fitted to (the used ones: finite,
        and late enough for ``"discard"``; records concatenated).
    noise_level_bounds_ : pair of floats or "fixed"
        The bounds of ``noise_level`` used for tuning (``"auto"`` resolved).
    posterior_ : GaussianCoefficients
        The posterior of the coefficients at lags ``0..P-1``.
    optimizer_result_ : scipy.optimize.OptimizeResult or None
        The best optimizer run (``x`` in ``theta`` coordinates, ``fun`` the
        negative log evidence, or the negative cross-validated log
        predictive likelihood), or None when nothing was tuned.
    cv_log_predictive_likelihood_ : float
        With ``tuning="cross_validation"``: the sum over the folds of the
        log density of the held-out slow samples at the tuned values.
    order_selection_ : dict
        With ``order="auto"`` or a list: ``"order"`` (the candidates),
        ``"score"`` (the criterion per used slow sample, higher is better),
        ``"criterion"`` (``"log_evidence"`` or ``"cv_log_predictive"``) and
        ``"best_order"`` (the fitted order).  With the default order, where
        the held-out check ran: the candidates ``N/32, ..., N``, their
        held-out fit in percent (``"criterion"`` ``"held_out_fit"``) and the
        fitted order.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> import gpmultirate as gm
    >>> from gpmultirate.kernels import DC
    >>> rng = np.random.default_rng(0)
    >>> g = 0.9 ** np.arange(60) * np.cos(0.5 * np.arange(60))
    >>> u = rng.standard_normal(120)
    >>> y_slow = np.convolve(u, g)[:120][::3] + 0.05 * rng.standard_normal(40)
    >>> model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=60).fit(u, y_slow)
    >>> model.coef_.shape
    (60,)
    >>> mean, std = model.impulse_response([0.5, 1.5], return_std=True)
    >>> bool(np.all(std > 0))
    True

    Two inputs, and a slow sample that was not measured:

    >>> u2 = rng.standard_normal((120, 2))
    >>> y2 = (np.convolve(u2[:, 0], g)[:120] + np.convolve(u2[:, 1], -g)[:120])[::3]
    >>> y2 += 1e-2 * rng.standard_normal(40)
    >>> y2[5] = np.nan
    >>> model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=20).fit(u2, y2)
    >>> model.coef_.shape, model.frequency_response(input=1).magnitude.shape
    ((2, 20), (61,))
    """

    continuous_lags = True

    def __init__(
        self,
        kernel: Kernel | None = None,
        factor: int = 1,
        order: int | None = None,
        offset: int = 0,
        noise_level: float = 1.0,
        noise_level_bounds="auto",
        optimizer: str | None = "marginal_likelihood",
        n_restarts_optimizer: int = 0,
        random_state=None,
        initial_conditions: str = "zero",
        sample_time: float = 1.0,
        max_resonances: int = 4,
        normalize: bool = True,
        tuning: str = "evidence",
        cv: int = 5,
    ):
        self.kernel = kernel
        self.factor = factor
        self.order = order
        self.offset = offset
        self.noise_level = noise_level
        self.noise_level_bounds = noise_level_bounds
        self.optimizer = optimizer
        self.n_restarts_optimizer = n_restarts_optimizer
        self.random_state = random_state
        self.initial_conditions = initial_conditions
        self.sample_time = sample_time
        self.max_resonances = max_resonances
        self.normalize = normalize
        self.tuning = tuning
        self.cv = cv

    # ------------------------------------------------------------------ fit
    def fit(self, u, y_slow, sample_indices=None) -> "FIRGaussianProcess":
        """Condition the prior on slow data, tuning hyperparameters if asked.

        Parameters
        ----------
        u : array-like of shape (N,) or (N, n_inputs), or a list of them
            Fast-rate input(s); a list holds one record per entry.
        y_slow : array-like of shape (M,), or a list of them
            Slow output, ``y_slow[m] = y[offset + m * factor]`` (then
            ``M = len(range(offset, N, factor))``) or ``y[sample_indices[m]]``;
            ``NaN`` marks a sample that was not measured.
        sample_indices : array-like of int, or a list of them, optional
            The fast-sample index of each slow sample, strictly increasing
            in ``0..N-1``; ``factor`` and ``offset`` are then ignored.

        Returns
        -------
        self
        """
        criterion = _check_tuning(self.tuning)
        n_folds = check_int(self.cv, "cv", low=2)
        candidates = _order_candidates(self.order)
        for name in ("order_selection_", "cv_log_predictive_likelihood_", "resonances_"):
            self.__dict__.pop(name, None)  # made by some fits only: none left from a refit
        if candidates is not None:
            return self._fit_order_selection(u, y_slow, sample_indices, candidates, criterion)
        experiment = self._fit_order(u, y_slow, sample_indices, self.order, criterion, n_folds)
        if criterion == "evidence" and self.optimizer is not None:
            with blas_threads_for(experiment.observation):
                self._check_shorter_orders(u, y_slow, sample_indices, experiment, n_folds)
        return self

    def _fit_order(self, u, y_slow, sample_indices, order, criterion, n_folds):
        """Fit at one order; returns the experiment (observation and used samples)."""
        experiment = build_experiment(
            u, y_slow, sample_indices, factor=self.factor, offset=self.offset,
            order=order, initial_conditions=self.initial_conditions,
        )
        operator, y = experiment.observation, experiment.y
        if not (self.optimizer is None or (
            isinstance(self.optimizer, str) and self.optimizer == "marginal_likelihood"
        )):
            raise ValueError(
                f"optimizer must be 'marginal_likelihood' or None; got {self.optimizer!r}"
            )
        n_restarts = check_int(self.n_restarts_optimizer, "n_restarts_optimizer", low=0)
        check_rng(self.random_state)
        check_positive(self.sample_time, "sample_time")
        noise = check_positive(self.noise_level, "noise_level")
        auto = isinstance(self.kernel, str) and self.kernel == "auto"
        if isinstance(self.kernel, str) and not auto:
            raise ValueError(f"kernel must be a scikit-learn kernel, a list of them or 'auto'; "
                             f"got {self.kernel!r}")
        max_resonances = check_int(self.max_resonances, "max_resonances", low=0)
        # normalized units are a start and bounds for tuning: without tuning
        # the kernel and the noise level are used exactly as given
        normalize = bool(self.normalize) and self.optimizer is not None
        kernel = _initial_kernel(None if auto else self.kernel, experiment, normalize)
        # refuse now what would be killed for lack of memory halfway
        n_free = sum(h.n_elements for h in kernel.hyperparameters if not h.fixed)
        check_fit_memory(operator.n_outputs, operator.n_coefficients, n_free + 1)
        noise_bounds = self._resolve_noise_bounds(y, normalize)
        if normalize:
            noise *= float(np.mean(y**2)) or 1.0  # given in normalized units
        if self.optimizer is not None and not isinstance(noise_bounds, str):
            noise = float(np.clip(noise, *noise_bounds))
        self.operator_ = operator
        self.y_slow_ = y
        self.noise_level_bounds_ = noise_bounds
        self.optimizer_result_ = None
        self.n_inputs_ = experiment.n_inputs
        with blas_threads_for(operator):
            if auto:
                from gpmultirate import resonances

                search = resonances.search_resonances(
                    operator, y, kernel, noise, noise_bounds, max_resonances=max_resonances,
                    sample_time=self.sample_time, random_state=self.random_state,
                )
                kernel, noise = search.kernel, search.noise_level
                self.optimizer_result_ = search.optimizer_result
                self.resonances_ = search.resonances
            evidence = LogEvidence(operator, y, kernel, noise, noise_bounds)
            objective = evidence
            if criterion == "cross_validation":
                check_fit_memory(y.shape[0], y.shape[0], kernel.theta.shape[0] + 1)
                objective = CrossValidation(operator, y, kernel, noise, noise_bounds, n_folds)
            if self.optimizer is not None and (not auto or objective is not evidence):
                # with "auto", the search tuned by the evidence: cross-validation goes on from there
                result = tuning.maximize(objective, n_restarts, self.random_state)
                if result is not None:
                    self.optimizer_result_ = result
                    kernel, noise = evidence.split(result.x)
            self.posterior_ = evidence.posterior(kernel, noise)
            if objective is not evidence:
                moved = objective.moved_to(kernel, noise)
                self.cv_log_predictive_likelihood_ = float(moved(moved.theta))
        # kept for log_marginal_likelihood(theta) and the posterior at real lags
        self._evidence = evidence.moved_to(kernel, noise)
        if self.optimizer_result_ is not None:
            tuning.warn_at_bounds(self._evidence)
        self.kernel_ = kernel
        self.noise_level_ = noise
        self.coef_ = self._shaped(self.posterior_.coef)
        self.log_marginal_likelihood_value_ = self.posterior_.log_marginal_likelihood
        return experiment

    def _fit_order_selection(self, u, y_slow, sample_indices, candidates, criterion):
        """Fit every candidate order and keep the one the criterion prefers."""
        if candidates == "auto":
            longest = build_experiment(
                u, y_slow, sample_indices, factor=self.factor, offset=self.offset,
                initial_conditions=self.initial_conditions,
            ).observation.order
            candidates = auto_orders(longest)
        n_folds = check_int(self.cv, "cv", low=2)
        fits, caught = [], []
        for order in candidates:
            model = clone(self)
            with warnings.catch_warnings(record=True) as record:
                warnings.simplefilter("always")
                model._fit_order(u, y_slow, sample_indices, order, criterion, n_folds)
            fits.append(model)
            caught.append(record)
        if criterion == "evidence":
            values = [m.log_marginal_likelihood_value_ for m in fits]
        else:
            values = [m.cv_log_predictive_likelihood_ for m in fits]
        # per used slow sample: "discard" uses fewer samples at higher orders
        scores = np.array([v / m.y_slow_.shape[0] for v, m in zip(values, fits)])
        best = int(np.argmax(scores))
        params = self.get_params(deep=False)
        self.__dict__.update(
            {key: value for key, value in vars(fits[best]).items() if key not in params}
        )
        self.order_selection_ = {
            "order": np.array(candidates),
            "score": scores,
            "criterion": "log_evidence" if criterion == "evidence" else "cv_log_predictive",
            "best_order": int(candidates[best]),
        }
        for w in caught[best]:  # only the kept model's warnings concern the user
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        return self

    def _check_shorter_orders(self, u, y_slow, sample_indices, experiment, n_folds):
        """Compare the held-out fit of the tuned model with that of shorter orders; act on it.

        The same hyperparameters, the same folds (as ``tuning="cross_validation"``);
        only the order is cut.  With the default order (``order=None``) the
        candidates are :func:`auto_orders` of ``N``, and when one predicts the
        held-out slow samples more than ``ORDER_MARGIN`` points of fit better
        than ``N``, the model is fitted again at that order;
        ``order_selection_`` reports every candidate's held-out fit.  With an
        explicit order ``P`` the candidates are ``P/2, P/4, P/8`` and a
        :class:`~gpmultirate.HeldOutWarning` names one that predicts more than
        ``HELD_OUT_MARGIN`` points better.  Skipped where it would cost more
        than the fit (at least as many slow samples as coefficients, where
        the fit works on the ``P x P`` problem and the check would need
        ``M x M`` matrices; as many is checked for the default order, the
        single-rate case), beyond ``MAX_CHECKED_SAMPLES`` slow samples, or
        where it is not comparable (``"discard"`` uses other samples at other
        orders).
        """
        operator, y = experiment.observation, experiment.y
        order, n_samples = operator.order, y.shape[0]
        default_order = self.order is None
        # the fit works in data space for M < P; at M = P (single rate) only the
        # default order is checked, and never with M x M matrices beyond the limit
        data_space = n_samples < operator.n_coefficients or (
            default_order and n_samples == operator.n_coefficients)
        if (self.initial_conditions == "discard" or not data_space
                or n_samples > MAX_CHECKED_SAMPLES or order < 2 * MIN_CHECKED_ORDER):
            return
        try:
            folds = contiguous_folds([r.n_outputs for r in operator.records], n_folds)
        except ValueError:
            return  # fewer samples than folds: nothing to hold out
        if default_order:
            orders = auto_orders(order)
        else:
            orders = [order // d for d in (8, 4, 2) if order // d >= MIN_CHECKED_ORDER] + [order]
        fits = {}
        for shorter in orders:
            observation = operator if shorter == order else build_experiment(
                u, y_slow, sample_indices, factor=self.factor, offset=self.offset,
                order=shorter, initial_conditions=self.initial_conditions,
            ).observation
            try:
                mean, _ = held_out_predictions(
                    observation, self.kernel_, self.noise_level_, y, folds
                )
            except ValueError:
                return
            fits[shorter] = fit_percent(y, mean)
        best = max(fits, key=fits.get)  # the shortest of equal fits
        if default_order:
            chosen = best if fits[best] > fits[order] + ORDER_MARGIN else order
            if chosen != order:
                self._fit_order(u, y_slow, sample_indices, chosen, "evidence", n_folds)
            self.order_selection_ = {
                "order": np.array(orders),
                "score": np.array([fits[o] for o in orders]),
                "criterion": "held_out_fit",
                "best_order": int(chosen),
            }
        elif fits[best] > fits[order] + HELD_OUT_MARGIN:
            warnings.warn(
                f"held-out slow samples are predicted clearly better at a shorter order: "
                f"order={best} fits {fits[best]:.1f} % of them, order={order} "
                f"{fits[order]:.1f} % ({n_folds}-fold cross-validation over time at the tuned "
                "hyperparameters). The marginal likelihood trusts the model, and measured data "
                "with drift, disturbances or a little nonlinearity can make it prefer a worse "
                f"predictor: try order={best}, or order='auto' with "
                "tuning='cross_validation'.",
                HeldOutWarning,
                stacklevel=3,
            )

    def _resolve_noise_bounds(self, y, normalize: bool):
        power = float(np.mean(y**2)) or 1.0
        if isinstance(self.noise_level_bounds, str) and self.noise_level_bounds == "auto":
            return (1e-12 * power, 10.0 * power)
        bounds = check_bounds(self.noise_level_bounds, "noise_level_bounds")
        if normalize and not isinstance(bounds, str):
            return (bounds[0] * power, bounds[1] * power)  # given in normalized units
        return bounds

    # ------------------------------------------------------------ evidence
    def log_marginal_likelihood(self, theta=None, eval_gradient: bool = False):
        """Log marginal likelihood of the training data (eq. 19, corrected).

        Parameters
        ----------
        theta : array-like, optional
            Hyperparameters in tuning coordinates: ``kernel_.theta`` (the
            log of each free value, ``artanh`` of DC's ``beta``) followed by
            ``log(noise_level)`` unless the noise level is fixed.  By default
            the fitted value is returned.
        eval_gradient : bool, default=False
            Also return the gradient with respect to ``theta``.

        Returns
        -------
        float, or (float, ndarray) with ``eval_gradient``
        """
        check_is_fitted(self, "coef_")
        if theta is None:
            if eval_gradient:
                raise ValueError("eval_gradient requires theta")
            return self.log_marginal_likelihood_value_
        theta = check_signal(theta, "theta", min_length=0)
        evidence = self._evidence
        n_expected = evidence.theta.shape[0]
        if theta.shape[0] != n_expected:
            raise ValueError(f"theta must have {n_expected} entries; got {theta.shape[0]}")
        return evidence(theta, eval_gradient=eval_gradient)

    # ----------------------------------------------------------- posterior
    def impulse_response(self, lags=None, return_std: bool = False, return_cov: bool = False):
        """Posterior of the impulse response ``g(t)`` at real lags ``t >= 0``.

        Non-integer lags use the kernel on continuous lag (the Gaussian
        process / RKHS view of the estimate).

        Parameters
        ----------
        lags : array-like of shape (n,), optional
            Lags in fast samples; default ``0..P-1``.
        return_std : bool, default=False
            Also return the posterior standard deviation.
        return_cov : bool, default=False
            Also return the posterior covariance (exclusive with ``return_std``).

        Returns
        -------
        mean : ndarray of shape (n,), or (n_inputs, n) for several inputs
        std : ndarray of the shape of ``mean``, only with ``return_std``
        cov : ndarray of shape (n, n), only with ``return_cov``; for several
            inputs ``(n_inputs * n, n_inputs * n)``, of the input-major
            flattened ``mean``
        """
        check_is_fitted(self, "coef_")
        if return_std and return_cov:
            raise ValueError("return_std and return_cov cannot both be True")
        X = self._points(lags)
        if not (return_std or return_cov):
            return self._shaped(self.posterior_.mean_at_lags(X))
        mean, second = self.posterior_.at_lags(X, full_cov=return_cov)
        if return_cov:
            return self._shaped(mean), second
        return self._shaped(mean), self._shaped(np.sqrt(second))

    def _points(self, lags) -> np.ndarray:
        """The kernel inputs of the lags: a column, or ``(input, lag)`` pairs input-major."""
        lags = np.arange(self._order, dtype=float) if lags is None else check_lags(lags, "lags")
        if self.n_inputs_ == 1:
            return lags[:, None]
        inputs = np.repeat(np.arange(self.n_inputs_, dtype=float), lags.shape[0])
        return np.column_stack([inputs, np.tile(lags, self.n_inputs_)])


class LeastSquaresFIR(StateSpaceMixin, _FIRModelMixin, BaseEstimator):
    """Least-squares FIR model from slow-rate data (paper eq. 11).

    The estimate is unique only when the order is below the number of slow
    samples (Lemma 1) and the regressor has full column rank, which fails
    for instance for zero-order-hold inputs (Lemma 2); otherwise ``fit``
    raises :class:`~gpmultirate.IdentifiabilityError`.

    Parameters
    ----------
    factor : int, default=1
        Downsampling factor ``F`` (ignored when ``sample_indices`` are given).
    order : int
        FIR order ``P``; ``n_inputs * P`` must be below the number of used
        slow samples ``M``.
    offset : int, default=0
        Fast index of the first slow sample, ``0..F-1``.
    initial_conditions : {"zero", "discard", "periodic"}, default="zero"
        As for :class:`FIRGaussianProcess`.
    sample_time : float, default=1.0
        Fast sample time in seconds, as for :class:`FIRGaussianProcess`.

    Attributes
    ----------
    coef_ : ndarray of shape (P,), or (n_inputs, P) for a 2-D ``u``
    n_inputs_ : int
    noise_variance_ : float
        Residual variance ``||y - Phi g||^2 / (M - P)`` (NaN when ``M = P + 0``).
    coef_covariance_ : ndarray of shape (n_inputs * P, n_inputs * P)
        ``noise_variance_ (Phi^T Phi)^{-1}``, used for the bands of
        :meth:`predict` and :meth:`frequency_response`.
    operator_ : Observation
    posterior_ : GaussianCoefficients
        The Gaussian distribution ``N(coef_, coef_covariance_)``.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import LeastSquaresFIR
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> g = 0.5 ** np.arange(10)
    >>> y_slow = np.convolve(u, g)[:300][::3]
    >>> LeastSquaresFIR(factor=3, order=10).fit(u, y_slow).coef_[:3].round(6)
    array([1.  , 0.5 , 0.25])
    """

    def __init__(self, factor: int = 1, order: int | None = None, offset: int = 0,
                 initial_conditions: str = "zero", sample_time: float = 1.0):
        self.factor = factor
        self.order = order
        self.offset = offset
        self.initial_conditions = initial_conditions
        self.sample_time = sample_time

    def fit(self, u, y_slow, sample_indices=None) -> "LeastSquaresFIR":
        """Solve the least-squares problem of eq. (10)-(11).

        Parameters
        ----------
        u : array-like of shape (N,) or (N, n_inputs), or a list of them
        y_slow : array-like of shape (M,), or a list of them
            ``NaN`` marks a sample that was not measured.
        sample_indices : array-like of int, or a list of them, optional
            As for :meth:`FIRGaussianProcess.fit`.

        Returns
        -------
        self

        Raises
        ------
        IdentifiabilityError
            If ``n_inputs * order >= M`` (the used slow samples) or the
            regressor is rank deficient.
        """
        if self.order is None:
            raise ValueError("order must be given: an integer below the number of slow samples")
        check_positive(self.sample_time, "sample_time")
        experiment = build_experiment(
            u, y_slow, sample_indices, factor=self.factor, offset=self.offset,
            order=self.order, initial_conditions=self.initial_conditions,
        )
        operator, y = experiment.observation, experiment.y
        M, P = operator.n_outputs, operator.n_coefficients
        check_fit_memory(M, P, 0)
        if P >= M:
            inputs = f" x {operator.n_inputs} inputs" if operator.n_inputs > 1 else ""
            raise IdentifiabilityError(
                f"order={operator.order}{inputs} is not below the number of used slow samples "
                f"M={M}: the least-squares FIR estimate is not unique (Lemma 1). Use a lower "
                "order, more data, or FIRGaussianProcess, whose prior makes any order unique."
            )
        U, s, Vt = linalg.svd(operator.matrix, full_matrices=False, check_finite=False)
        tolerance = max(M, P) * np.finfo(float).eps * (s[0] if s.size else 0.0)
        rank = int(np.sum(s > tolerance))
        if rank < P:
            hold = any(
                _is_zero_order_hold(x[:, k], operator.slow_factor)
                for x in _record_inputs(experiment) for k in range(x.shape[1])
            )
            hint = (
                "The input is constant between slow samples (zero-order hold, Lemma 2): "
                "excite the system at the fast rate. " if hold else ""
            )
            raise IdentifiabilityError(
                f"the regressor has rank {rank} < {P} coefficients, so the least-squares FIR "
                f"estimate is not unique. {hint}Use a fast-rate (e.g. multisine or random) "
                "input, a lower order, or FIRGaussianProcess."
            )
        coef = Vt.T @ ((U.T @ y) / s)
        residual = y - operator.matrix @ coef
        noise_variance = float(residual @ residual / (M - P))
        root = Vt.T / s  # coef covariance = noise_variance * root @ root.T
        self.operator_ = operator
        self.n_inputs_ = experiment.n_inputs
        self.coef_ = self._shaped(coef)
        self.noise_variance_ = noise_variance
        self.coef_covariance_ = noise_variance * (root @ root.T)
        self.posterior_ = GaussianCoefficients(coef, self.coef_covariance_, np.zeros((0, P)))
        return self

    def impulse_response(self, lags=None, return_std: bool = False, return_cov: bool = False):
        """The estimate at integer lags, with its standard deviation or covariance.

        Least squares estimates the coefficients only: ``lags`` must be
        integers in ``0..P-1``.  The covariance is :attr:`coef_covariance_`.

        Parameters
        ----------
        lags : array-like of int, optional
            Lags in ``0..P-1``; default all of them.
        return_std, return_cov : bool, default=False
            Also return the standard deviation or the covariance.

        Returns
        -------
        mean : ndarray of shape (n,), or (n_inputs, n) for several inputs
        std : ndarray of the shape of ``mean``, only with ``return_std``
        cov : ndarray, only with ``return_cov`` (input-major for several inputs)
        """
        check_is_fitted(self, "coef_")
        if return_std and return_cov:
            raise ValueError("return_std and return_cov cannot both be True")
        order = self._order
        if lags is None:
            index = np.arange(order)
        else:
            lags = check_signal(lags, "lags")
            index = np.round(lags).astype(int)
            if np.any(np.abs(lags - index) > 1e-9) or np.any(index < 0) or np.any(index >= order):
                raise ValueError(
                    f"lags must be integers in 0..{order - 1} for a least-squares FIR model"
                )
        # the input-major positions of the lags of every input
        index = (np.arange(self.n_inputs_)[:, None] * order + index[None, :]).reshape(-1)
        mean = self.posterior_.coef[index]
        if not (return_std or return_cov):
            return self._shaped(mean)
        cov = self.coef_covariance_[np.ix_(index, index)]
        if return_cov:
            return self._shaped(mean), cov
        return self._shaped(mean), self._shaped(np.sqrt(np.maximum(np.diag(cov), 0.0)))


def _is_zero_order_hold(u: np.ndarray, factor: int) -> bool:
    """True when ``u`` is constant on every block of ``factor`` samples, for some alignment."""
    if factor < 2 or u.shape[0] < 2 * factor:
        return False
    for shift in range(factor):
        head = u[shift:]
        n_blocks = head.shape[0] // factor
        blocks = head[: n_blocks * factor].reshape(n_blocks, factor)
        if np.allclose(blocks, blocks[:, :1], rtol=1e-12, atol=1e-14 * np.max(np.abs(u))):
            return True
    return False
