"""Whether a fit's bands can be trusted: its innovations, and its noise estimate.

Under the fitted model the slow samples are ``y ~ N(0, Ky)`` with
``Ky = Phi K Phi^T + N`` (eq. 19), and the *innovations* ``e = L^{-1} y``
(``Ky = L L^T``, samples in time order, records one after the other) are
independent standard normal: each is the standardized error of predicting
one slow sample from the earlier ones.  Their autocorrelation is therefore
a test of the whole model -- prior, order and noise together -- that holds
its level on a well-specified fit whatever the factor and the order, where
the residuals ``y - Phi g`` of a fit with more coefficients than samples
are shrunk and correlated by the fit itself.

:func:`check_fit` reads three signs that the bands are not to be trusted:

* **correlated innovations**: the Ljung-Box statistic of ``e`` over
  ``min(25, M / 5)`` slow lags is beyond the chi-squared quantile of
  ``MISSPECIFICATION_LEVEL`` (model error the prior shrank away, a
  resonance the kernel misses, a cut tail, or a disturbance), and the
  correlations are large enough to matter: the spectrum of ``e`` over the
  model's (:func:`innovation_spectrum`) leaves :data:`TRUSTED_RATIO` at
  some frequency by more than twice its estimate's relative error;
* **innovations of the wrong size**: ``sum e^2`` is beyond the two-sided
  chi-squared quantiles of ``MISSPECIFICATION_LEVEL`` with ``M`` degrees
  of freedom (the noise estimate has absorbed model error, or the prior
  and the noise do not match the data's size), and ``mean(e^2)`` is
  outside :data:`TRUSTED_RATIO`;
* **a noise estimate at its bound**: the white noise variance within 1 %
  of its lower bound in log terms, where the fit explains the data by the
  prior alone and its bands rest on the bound.

A sign counts only where it matters: :data:`TRUSTED_RATIO` are the
variance ratios within which a 95 % band still holds 0.90-0.98 of what it
bounds, so that a long record's significant but tiny correlations do not
call trusted bands untrusted.

:func:`check_misspecification` runs it after a tuned fit (not where the
hyperparameters are the user's, ``optimizer=None``, as when a model file is
read) and warns once with a
:class:`~gpmultirate.exceptions.MisspecificationWarning` that names what to
try, read from :func:`~gpmultirate.diagnosis.explain_residuals` where it
finds something specific (``kernel="auto"``, a longer order, a disturbance
model), else all three.  Up to ``CHECKED_SAMPLES`` slow samples (one
``M x M`` Cholesky factorization, of the size the fit's dense route
already works with); beyond, the fit is not checked.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import linalg, stats

from gpmultirate.exceptions import MisspecificationWarning
from gpmultirate.inference import blas_threads_for
from gpmultirate.kernels import observe

__all__ = [
    "CHECKED_SAMPLES",
    "MISSPECIFICATION_LEVEL",
    "MisspecificationCheck",
    "TRUSTED_RATIO",
    "check_fit",
    "check_misspecification",
    "innovations",
    "innovation_spectrum",
]

#: the level of each test of :func:`check_fit` (two tests and the bound): the
#: false-alarm rate on well-specified fits stays near ``2e-3`` where the
#: hyperparameters are known, and was measured at 0 of 60 with them tuned
#: (docs/disturbances.rst)
MISSPECIFICATION_LEVEL = 1e-3
#: the largest number of slow samples :func:`check_fit` checks
CHECKED_SAMPLES = 2000
#: slow lags of the Ljung-Box test of the innovations (at most a fifth of them)
INNOVATION_LAGS = 25
#: the variance ratios that leave a 95 % band's coverage within 0.90-0.98:
#: ``(1.96 / 2.326)^2`` and ``(1.96 / 1.645)^2``; a sign counts only when it is
#: both significant and outside them (long records make tiny effects significant)
TRUSTED_RATIO = (0.71, 1.42)


@dataclass(frozen=True)
class MisspecificationCheck:
    """The signs that a fit's bands are not to be trusted (none: they are).

    Attributes
    ----------
    reasons : tuple of str
        One phrase per sign found.
    ljung_box_p_value : float
        The p-value of the innovations' Ljung-Box test.
    variance_p_value : float
        The two-sided p-value of ``sum e^2`` against chi-squared with ``M``
        degrees of freedom.
    noise_at_bound : bool
    """

    reasons: tuple
    ljung_box_p_value: float
    variance_p_value: float
    noise_at_bound: bool = False

    @property
    def trusted(self) -> bool:
        """Whether no sign was found."""
        return not self.reasons


def innovations(observation, y, kernel, noise_level: float, noise_model=None) -> np.ndarray:
    """``L^{-1} y`` with ``L L^T = Phi K Phi^T + N`` of the fitted model: iid ``N(0, 1)`` under it.

    Parameters
    ----------
    observation : Observation
    y : ndarray of shape (M,)
    kernel : sklearn Kernel
        The lag kernel of the fit.
    noise_level : float
        The white noise variance ``gamma`` (``N = gamma I``) when ``noise_model``
        is None.
    noise_model : NoiseModel, optional
        A disturbance model (:mod:`gpmultirate.noise`): ``N`` is its matrix.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import TC
    >>> rng = np.random.default_rng(0)
    >>> observation = DownsampledConvolution(rng.standard_normal(300), 3, 40)
    >>> kernel = ConstantKernel(1.0) * TC(alpha=0.8)
    >>> K = kernel(np.arange(40.0)[:, None])
    >>> g = np.linalg.cholesky(K + 1e-12 * np.eye(40)) @ rng.standard_normal(40)
    >>> y = observation.matvec(g) + 0.1 * rng.standard_normal(100)
    >>> e = innovations(observation, y, kernel, 0.01)
    >>> bool(abs(np.mean(e**2) - 1.0) < 0.3)
    True
    """
    with blas_threads_for(observation):
        # one M x M array: the covariance, then its factor in place
        Ky = np.array(observe(kernel, observation).covariance(), dtype=float)
        if noise_model is None or getattr(noise_model, "white", False):
            Ky[np.diag_indices_from(Ky)] += float(noise_level)
        else:
            Ky = noise_model.add_to(Ky)
        L = linalg.cholesky(Ky, lower=True, overwrite_a=True, check_finite=False)
        return linalg.solve_triangular(L, np.asarray(y, dtype=float), lower=True,
                                       check_finite=False)


def _autocorrelation(e: np.ndarray, lags: int) -> np.ndarray:
    centred = e - e.mean()
    denominator = float(centred @ centred)
    if denominator <= 0:
        return np.zeros(lags)
    return np.array([centred[k:] @ centred[:-k] for k in range(1, lags + 1)]) / denominator


def _ljung_box(r: np.ndarray, M: int) -> float:
    lags = r.shape[0]
    q = M * (M + 2.0) * float(np.sum(r**2 / (M - np.arange(1, lags + 1))))
    return float(stats.chi2.sf(q, df=lags))


def innovation_spectrum(r: np.ndarray, n_frequencies: int = 65) -> np.ndarray:
    """``S(w) = 1 + 2 sum_k (1 - k / (K + 1)) r_k cos(w k)`` on ``n_frequencies`` points of
    ``[0, pi]``: the innovations' spectrum over the model's (Bartlett weights, ``K`` lags).

    1 at every frequency for white innovations.  Where it is above 1 the
    data vary more at that frequency than the fitted model says, and the
    bands of what the data see there (the response near that frequency, or
    its aliases) are too narrow by about its square root; where it is
    below 1, too wide.  ``S(0)`` is the variance of long averages.

    Examples
    --------
    >>> innovation_spectrum(np.zeros(5), 3)
    array([1., 1., 1.])
    >>> innovation_spectrum(np.array([0.5, 0.25, 0.125]), 2)
    array([2.0625, 0.4375])
    """
    K = r.shape[0]
    k = np.arange(1, K + 1)
    w = np.linspace(0.0, np.pi, n_frequencies)
    return 1.0 + 2.0 * np.cos(np.outer(w, k)) @ ((1.0 - k / (K + 1.0)) * r)


def _at_lower_bound(noise_level: float, bounds) -> bool:
    if isinstance(bounds, str) or noise_level is None:
        return False
    low, high = (float(b) for b in bounds)
    if not (low > 0 and high > low):
        return False
    span = np.log(high) - np.log(low)
    return bool(np.log(noise_level) - np.log(low) <= 0.01 * span)


def check_fit(observation, y, kernel, noise_level: float, noise_model=None,
              noise_bounds="fixed", posterior=None) -> MisspecificationCheck | None:
    """The signs that the fitted model does not describe the data; None beyond
    ``CHECKED_SAMPLES`` slow samples, with fewer than 20, or where the fitted
    data covariance is singular in floating point (not checked).

    Parameters
    ----------
    observation, y, kernel, noise_level, noise_model
        The fit, as in :func:`innovations`.
    noise_bounds : pair of floats or "fixed"
        The bounds of the white noise variance (its lower bound is a sign).
    posterior : GaussianCoefficients, optional
        The fit's posterior of these data: where it holds the factor of
        their covariance (:meth:`~gpmultirate.covariance.DataSpacePosterior.innovations`),
        the innovations come from it instead of a covariance and a
        factorization of their own.

    Returns
    -------
    MisspecificationCheck or None

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import TC
    >>> rng = np.random.default_rng(1)
    >>> observation = DownsampledConvolution(rng.standard_normal(600), 3, 40)
    >>> kernel = ConstantKernel(1.0) * TC(alpha=0.8)
    >>> y = observation.matvec(0.8 ** np.arange(40)) + 0.1 * rng.standard_normal(200)
    >>> check_fit(observation, y, kernel, 0.01).trusted
    True
    >>> drift = np.cumsum(0.1 * rng.standard_normal(200))
    >>> check_fit(observation, y + drift, kernel, 0.01).reasons[0].startswith(
    ...     "the innovations are correlated")
    True
    """
    y = np.asarray(y, dtype=float)
    M = y.shape[0]
    if M > CHECKED_SAMPLES or M < 20:
        return None
    e = None if posterior is None else posterior.innovations(y)
    try:
        if e is None:
            e = innovations(observation, y, kernel, noise_level, noise_model)
    except np.linalg.LinAlgError:  # a covariance singular in floating point: not checked
        return None
    lags = max(1, min(INNOVATION_LAGS, M // 5))
    r = _autocorrelation(e, lags)
    box = _ljung_box(r, M)
    spectrum = innovation_spectrum(r)
    total = float(e @ e)
    variance = float(2.0 * min(stats.chi2.sf(total, df=M), stats.chi2.cdf(total, df=M)))
    reasons = []
    low, high = TRUSTED_RATIO
    # beyond the ratios by more than twice the estimate's relative error (Bartlett:
    # var S / S^2 = 2 K / (3 M)), so that its wiggles on short records do not count
    spread = 1.0 + 2.0 * np.sqrt(2.0 * lags / (3.0 * M))
    if box < MISSPECIFICATION_LEVEL and (spectrum.max() / spread > high
                                         or spectrum.min() * spread < low):
        reasons.append(f"the innovations are correlated (Ljung-Box p = {box:.1e}; their "
                       f"spectrum spans {spectrum.min():.2g}-{spectrum.max():.2g} times the "
                       "model's)")
    if variance < MISSPECIFICATION_LEVEL and not low <= total / M <= high:
        size = "larger" if total > M else "smaller"
        reasons.append(f"the innovations are {size} than the model says (mean square "
                       f"{total / M:.3g}, p = {variance:.1e})")
    white = noise_model is None or getattr(noise_model, "white", False)
    at_bound = white and _at_lower_bound(noise_level, noise_bounds)
    if at_bound:
        reasons.append("the noise estimate is at its lower bound")
    return MisspecificationCheck(tuple(reasons), box, variance, at_bound)


#: what to try when nothing more specific is found
GENERIC_REMEDIES = ('kernel="auto" (a resonance the prior misses)',
                    "a longer order (order=...)",
                    'a disturbance model (noise_kernel="matern32" or "matern12")')


def _remedies(model, u, y_slow, sample_indices, sample_times) -> tuple:
    """The remedies :func:`~gpmultirate.diagnosis.explain_residuals` names for one record."""
    from gpmultirate.diagnosis import explain_residuals
    from gpmultirate.residuals import analyze_residuals

    if isinstance(u, (list, tuple)) and isinstance(y_slow, (list, tuple)):
        return ()
    try:
        analysis = analyze_residuals(model, u, y_slow, sample_indices, sample_times=sample_times,
                                     confidence=1.0 - MISSPECIFICATION_LEVEL)
        return explain_residuals(analysis, model).remedies
    except (ValueError, np.linalg.LinAlgError):
        return ()


def check_misspecification(model, check, u, y_slow, sample_indices=None,
                           sample_times=None) -> str | None:
    """After a fit: warn once when ``check`` (:func:`check_fit`) found a sign; the message.

    The message names the signs and what to try: the remedies
    :func:`~gpmultirate.diagnosis.explain_residuals` reads from the slow
    residuals of ``u``, ``y_slow`` (one record), else ``kernel="auto"``, a
    longer order and a disturbance model.  Returns it (None when the fit is
    trusted or was not checked).
    """
    if check is None or check.trusted:
        return None
    remedies = [r for r in _remedies(model, u, y_slow, sample_indices, sample_times)]
    tried = remedies if remedies else list(GENERIC_REMEDIES)
    if getattr(model, "kernel", None) == "auto":
        tried = [r for r in tried if not r.startswith('kernel="auto"')] or list(GENERIC_REMEDIES[1:])
    message = ("the fitted model leaves structure in the data, and its bands may not hold "
               "their level: " + "; ".join(check.reasons) + ". Try " + ", or ".join(tried))
    warnings.warn(message, MisspecificationWarning, stacklevel=3)
    return message
