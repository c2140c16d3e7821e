"""Estimators of fast-rate FIR models from slow-rate output data.

* :class:`FIRGaussianProcess`: the kernel-regularised estimate of eq. (15)
  viewed as a Gaussian-process posterior over continuous lag, with
  marginal-likelihood tuning (eq. 19, noise inside the log-determinant).
* :class:`LeastSquaresFIR`: the least-squares baseline of eq. (11), which
  refuses non-unique problems (Lemma 1 and 2).
"""

from __future__ import annotations

import contextlib

import numpy as np
from scipy import linalg
from sklearn.base import BaseEstimator, clone
from sklearn.gaussian_process.kernels import ConstantKernel, Kernel
from sklearn.utils.validation import check_is_fitted
from threadpoolctl import threadpool_limits

from gpmultirate import tuning
from gpmultirate.inference import GaussianCoefficients, LogEvidence, gaussian_samples
from gpmultirate.validation import (
    check_bounds,
    check_int,
    check_kernel,
    check_rng,
    check_level,
    check_positive,
    check_signal,
)
from gpmultirate.exceptions import IdentifiabilityError
from gpmultirate.frequency import (
    FrequencyResponse,
    check_frequencies,
    default_frequencies,
    dft_matrix,
)
from gpmultirate.kernels import DC, check_lags
from gpmultirate.metrics import goodness_of_fit
from gpmultirate.observations import DownsampledConvolution, convolution_matrix

__all__ = ["FIRGaussianProcess", "LeastSquaresFIR"]


class _FIRModelMixin:
    """Prediction, scoring and frequency response shared by the FIR estimators.

    Subclasses set ``coef_``, ``operator_`` and ``posterior_`` (a
    :class:`~gpmultirate.inference.GaussianCoefficients`) and implement
    ``impulse_response``.
    """

    #: whether the impulse response is defined between the integer lags
    continuous_lags = False

    def predict(self, u, return_std: bool = False):
        """Fast-rate output of the model for input ``u``, starting at rest.

        ``y(n) = sum_i g_i u(n - i)`` for ``n = 0..len(u)-1``.  For the
        training input this is the intersample (fast-rate) response.

        Parameters
        ----------
        u : array-like of shape (n,)
            Fast-rate input.
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
        u = check_signal(u, "u")
        if not return_std:
            return np.convolve(u, self.coef_)[: u.shape[0]]
        # rows of the convolution matrix in blocks: memory O(block P), not O(n P)
        order = self.coef_.shape[0]
        block = max(1, _PREDICT_BLOCK_ENTRIES // order)
        mean, var = np.empty(u.shape[0]), np.empty(u.shape[0])
        for start in range(0, u.shape[0], block):
            rows = np.arange(start, min(start + block, u.shape[0]))
            mean[rows], var[rows] = self.posterior_.linear_map(
                convolution_matrix(u, order, rows)
            )
        return mean, np.sqrt(var)

    def score(self, u, y_fast) -> float:
        """Goodness of fit in percent (eq. 20) of ``predict(u)`` against ``y_fast``.

        Parameters
        ----------
        u : array-like of shape (n,)
            Fast-rate validation input.
        y_fast : array-like of shape (n,)
            Fast-rate validation output.

        Returns
        -------
        float
        """
        y_fast = check_signal(y_fast, "y_fast")
        u = check_signal(u, "u")
        if u.shape != y_fast.shape:
            raise ValueError(
                f"y_fast must have the length of u ({u.shape[0]}); got {y_fast.shape[0]}"
            )
        if np.ptp(y_fast) == 0:
            raise ValueError("y_fast must not be constant: the goodness of fit is undefined")
        return goodness_of_fit(y_fast, self.predict(u))

    def frequency_response(
        self, freqs=None, sample_time: float = 1.0, level: float = 0.95
    ) -> FrequencyResponse:
        """FRF of the identified model with a pointwise credible band.

        Valid at every frequency up to the fast Nyquist frequency, also
        beyond the slow Nyquist frequency ``1 / (2 F T)``.

        Parameters
        ----------
        freqs : array-like of shape (n,), optional
            Frequencies in Hz; by default the DFT bins of the training record.
        sample_time : float, default=1.0
            Fast sample time ``T`` in seconds.
        level : float, default=0.95
            Credible level of the band, in (0, 1).

        Returns
        -------
        FrequencyResponse
        """
        check_is_fitted(self, "coef_")
        level = check_level(level)
        if freqs is None:
            sample_time = check_positive(sample_time, "sample_time")
            freqs = default_frequencies(self.operator_.n_samples, sample_time)
        freqs, sample_time = check_frequencies(freqs, sample_time)
        E = dft_matrix(freqs, sample_time, self.coef_.shape[0])
        re, im = np.ascontiguousarray(E.real), np.ascontiguousarray(E.imag)
        var_re, var_im, cov = self.posterior_.pair_variances(re, im)
        return FrequencyResponse.from_gaussian(
            freqs,
            E @ self.coef_,
            var_re,
            var_im,
            cov,
            level=level,
            sample_time=sample_time,
            factor=self.operator_.factor,
        )

    def sample_impulse_responses(self, lags=None, n_samples: int = 1, random_state=None):
        """Draw impulse responses from the posterior (or, for least squares, the estimate's distribution).

        Parameters
        ----------
        lags : array-like of shape (n,), optional
            Lags in fast samples; default ``0..P-1``.
        n_samples : int, default=1
        random_state : int, RandomState or None

        Returns
        -------
        ndarray of shape (n, n_samples)
        """
        n_samples = check_int(n_samples, "n_samples", low=1)
        mean, cov = self.impulse_response(lags, return_cov=True)
        return gaussian_samples(mean, cov, n_samples, check_rng(random_state))


# Below this size the matrices of a fit are too small for threaded BLAS to pay
# off, and on a busy machine its threads spin against each other: one thread.
_SINGLE_THREAD_SIZE = 1500
# entries of the convolution matrix formed at once by predict(..., return_std=True)
_PREDICT_BLOCK_ENTRIES = 2**22


def _blas_threads_for(operator):
    """Limit BLAS to one thread for small problems; no limit otherwise."""
    if max(operator.n_outputs, operator.order) <= _SINGLE_THREAD_SIZE:
        return threadpool_limits(limits=1, user_api="blas")
    return contextlib.nullcontext()


def _check_slow_output(y_slow, operator) -> np.ndarray:
    y = check_signal(y_slow, "y_slow")
    if y.shape[0] != operator.n_outputs:
        raise ValueError(
            f"y_slow must have len(range(offset, len(u), factor)) = {operator.n_outputs} "
            f"samples; got {y.shape[0]}"
        )
    return y


class FIRGaussianProcess(_FIRModelMixin, BaseEstimator):
    """Fast-rate FIR model as a Gaussian process over lag, from slow-rate data.

    The impulse response ``g(t)``, ``t >= 0`` real, has a zero-mean Gaussian
    process prior with covariance ``kernel``; the slow samples
    ``y_slow[m] = sum_{i<P} g(i) u[offset + m F - i] + e[m]`` observe it
    through a :class:`~gpmultirate.DownsampledConvolution` with white noise of
    variance ``noise_level`` (the ``gamma`` of eq. 15).  The posterior mean at
    lags ``0..P-1`` is the kernel-regularised estimate of eq. (15).

    Parameters
    ----------
    kernel : sklearn Kernel, optional
        Prior covariance over lag.  Default
        ``ConstantKernel(c) * DC(alpha=0.9, beta=0.9)`` with ``c`` and its
        bounds set from the data.
    factor : int, default=1
        Downsampling factor ``F``.
    order : int, optional
        FIR order ``P`` in ``1..N``; default ``N = len(u)``.
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
        the reduction of long records, L-BFGS-B above; see the theory
        page and :mod:`gpmultirate.tuning`); ``None`` uses them exactly as
        given.
    n_restarts_optimizer : int, default=0
        Extra optimizer runs from random points drawn uniformly in the log
        bounds; the best optimum is kept.
    random_state : int, RandomState or None, default=None
        Seed of the restarts.

    Attributes
    ----------
    coef_ : ndarray of shape (P,)
        Posterior mean of ``g`` at lags ``0..P-1`` (eq. 15).
    kernel_ : sklearn Kernel
        The kernel with the tuned hyperparameters.
    noise_level_ : float
        The tuned (or given) noise variance.
    log_marginal_likelihood_value_ : float
        Log evidence of the slow data at ``kernel_`` and ``noise_level_``
        (scikit-learn's sign and constants: higher is better).
    operator_ : DownsampledConvolution
        The observation operator of the training input.
    y_slow_ : ndarray of shape (M,)
        The slow output the model was fitted to.
    noise_level_bounds_ : pair of floats or "fixed"
        The bounds of ``noise_level`` used for tuning (``"auto"`` resolved).
    posterior_ : GaussianCoefficients
        The posterior of the coefficients at lags ``0..P-1``.
    optimizer_result_ : scipy.optimize.OptimizeResult or None
        The best optimizer run (``x`` in ``theta`` coordinates, ``fun`` the
        negative log evidence), or None when nothing was tuned.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> import gpmultirate as gm
    >>> from gpmultirate.kernels import DC
    >>> rng = np.random.default_rng(0)
    >>> g = 0.9 ** np.arange(60) * np.cos(0.5 * np.arange(60))
    >>> u = rng.standard_normal(120)
    >>> y_slow = np.convolve(u, g)[:120][::3] + 1e-3 * rng.standard_normal(40)
    >>> model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=60).fit(u, y_slow)
    >>> model.coef_.shape
    (60,)
    >>> mean, std = model.impulse_response([0.5, 1.5], return_std=True)
    >>> bool(np.all(std > 0))
    True
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

    # ------------------------------------------------------------------ fit
    def fit(self, u, y_slow) -> "FIRGaussianProcess":
        """Condition the prior on slow data, tuning hyperparameters if asked.

        Parameters
        ----------
        u : array-like of shape (N,)
            Fast-rate input, the system at rest before it.
        y_slow : array-like of shape (M,)
            Slow output, ``y_slow[m] = y[offset + m * factor]``, with
            ``M = len(range(offset, N, factor))``.

        Returns
        -------
        self
        """
        u = check_signal(u, "u")
        order = u.shape[0] if self.order is None else self.order
        operator = DownsampledConvolution(u, self.factor, order, self.offset)
        y = _check_slow_output(y_slow, operator)
        if not (self.optimizer is None or (
            isinstance(self.optimizer, str) and self.optimizer == "marginal_likelihood"
        )):
            raise ValueError(
                f"optimizer must be 'marginal_likelihood' or None; got {self.optimizer!r}"
            )
        n_restarts = check_int(self.n_restarts_optimizer, "n_restarts_optimizer", low=0)
        check_rng(self.random_state)
        noise = check_positive(self.noise_level, "noise_level")
        kernel = self._initial_kernel(u, y)
        noise_bounds = self._resolve_noise_bounds(y)
        if self.optimizer is not None and not isinstance(noise_bounds, str):
            noise = float(np.clip(noise, *noise_bounds))
        self.operator_ = operator
        self.y_slow_ = y
        self.noise_level_bounds_ = noise_bounds
        self.optimizer_result_ = None
        with _blas_threads_for(operator):
            evidence = LogEvidence(operator, y, kernel, noise, noise_bounds)
            if self.optimizer is not None:
                result = tuning.maximize(evidence, n_restarts, self.random_state)
                if result is not None:
                    self.optimizer_result_ = result
                    kernel, noise = evidence.split(result.x)
            self.posterior_ = evidence.posterior(kernel, noise)
        # kept for log_marginal_likelihood(theta) and the posterior at real lags
        self._evidence = evidence.moved_to(kernel, noise)
        self.kernel_ = kernel
        self.noise_level_ = noise
        self.coef_ = self.posterior_.coef
        self.log_marginal_likelihood_value_ = self.posterior_.log_marginal_likelihood
        return self

    def _initial_kernel(self, u, y):
        if self.kernel is None:
            # scale reference: output power per unit input power
            reference = (np.mean(y**2) or 1.0) / (np.mean(u**2) or 1.0)
            return ConstantKernel(reference, (reference * 1e-8, reference * 1e8)) * DC()
        return clone(check_kernel(self.kernel))

    def _resolve_noise_bounds(self, y):
        if isinstance(self.noise_level_bounds, str) and self.noise_level_bounds == "auto":
            power = float(np.mean(y**2)) or 1.0
            return (1e-12 * power, 10.0 * power)
        return check_bounds(self.noise_level_bounds, "noise_level_bounds")

    # ------------------------------------------------------------ evidence
    def log_marginal_likelihood(self, theta=None, eval_gradient: bool = False):
        """Log marginal likelihood of the training data (eq. 19, corrected).

        Parameters
        ----------
        theta : array-like, optional
            Log hyperparameters: ``kernel_.theta`` followed by
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
        mean : ndarray of shape (n,)
        std : ndarray of shape (n,), only with ``return_std``
        cov : ndarray of shape (n, n), only with ``return_cov``
        """
        check_is_fitted(self, "coef_")
        if return_std and return_cov:
            raise ValueError("return_std and return_cov cannot both be True")
        lags = self._lags(lags)
        if not (return_std or return_cov):
            return self.posterior_.mean_at_lags(self._evidence.data, self.kernel_, lags)
        mean, second = self.posterior_.at_lags(
            self._evidence.data, self.kernel_, lags, full_cov=return_cov
        )
        return (mean, second) if return_cov else (mean, np.sqrt(second))

    def _lags(self, lags) -> np.ndarray:
        if lags is None:
            return np.arange(self.coef_.shape[0], dtype=float)
        return check_lags(lags, "lags")


class LeastSquaresFIR(_FIRModelMixin, BaseEstimator):
    """Least-squares FIR model from slow-rate data (paper eq. 11).

    The estimate is unique only when the order is below the number of slow
    samples (Lemma 1) and the regressor has full column rank, which fails
    for instance for zero-order-hold inputs (Lemma 2); otherwise ``fit``
    raises :class:`~gpmultirate.IdentifiabilityError`.

    Parameters
    ----------
    factor : int, default=1
        Downsampling factor ``F``.
    order : int
        FIR order ``P``, below the number of slow samples ``M``.
    offset : int, default=0
        Fast index of the first slow sample, ``0..F-1``.

    Attributes
    ----------
    coef_ : ndarray of shape (P,)
    noise_variance_ : float
        Residual variance ``||y - Phi g||^2 / (M - P)`` (NaN when ``M = P + 0``).
    coef_covariance_ : ndarray of shape (P, P)
        ``noise_variance_ (Phi^T Phi)^{-1}``, used for the bands of
        :meth:`predict` and :meth:`frequency_response`.
    operator_ : DownsampledConvolution
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

    def __init__(self, factor: int = 1, order: int | None = None, offset: int = 0):
        self.factor = factor
        self.order = order
        self.offset = offset

    def fit(self, u, y_slow) -> "LeastSquaresFIR":
        """Solve the least-squares problem of eq. (10)-(11).

        Parameters
        ----------
        u : array-like of shape (N,)
        y_slow : array-like of shape (M,)

        Returns
        -------
        self

        Raises
        ------
        IdentifiabilityError
            If ``order >= M`` or the regressor is rank deficient.
        """
        u = check_signal(u, "u")
        if self.order is None:
            raise ValueError("order must be given: an integer below the number of slow samples")
        operator = DownsampledConvolution(u, self.factor, self.order, self.offset)
        y = _check_slow_output(y_slow, operator)
        M, P = operator.shape
        if P >= M:
            raise IdentifiabilityError(
                f"order={P} is not below the number of slow samples M={M}: the "
                "least-squares FIR estimate is not unique (Lemma 1). Use order < M, "
                "more data, or FIRGaussianProcess, whose prior makes any order unique."
            )
        U, s, Vt = linalg.svd(operator.matrix, full_matrices=False, check_finite=False)
        tolerance = max(M, P) * np.finfo(float).eps * (s[0] if s.size else 0.0)
        rank = int(np.sum(s > tolerance))
        if rank < P:
            hint = (
                "The input is constant between slow samples (zero-order hold, Lemma 2): "
                "excite the system at the fast rate. "
                if _is_zero_order_hold(u, operator.factor)
                else ""
            )
            raise IdentifiabilityError(
                f"the regressor has rank {rank} < order={P}, so the least-squares FIR "
                f"estimate is not unique. {hint}Use a fast-rate (e.g. multisine or random) "
                "input, a lower order, or FIRGaussianProcess."
            )
        coef = Vt.T @ ((U.T @ y) / s)
        residual = y - operator.matrix @ coef
        noise_variance = float(residual @ residual / (M - P))
        root = Vt.T / s  # coef covariance = noise_variance * root @ root.T
        self.operator_ = operator
        self.coef_ = coef
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
        mean : ndarray of shape (n,)
        std : ndarray of shape (n,), only with ``return_std``
        cov : ndarray of shape (n, n), only with ``return_cov``
        """
        check_is_fitted(self, "coef_")
        if return_std and return_cov:
            raise ValueError("return_std and return_cov cannot both be True")
        order = self.coef_.shape[0]
        if lags is None:
            index = np.arange(order)
        else:
            lags = check_signal(lags, "lags")
            index = np.round(lags).astype(int)
            if np.any(np.abs(lags - index) > 1e-9) or np.any(index < 0) or np.any(index >= order):
                raise ValueError(
                    f"lags must be integers in 0..{order - 1} for a least-squares FIR model"
                )
        mean = self.coef_[index]
        if not (return_std or return_cov):
            return mean
        cov = self.coef_covariance_[np.ix_(index, index)]
        if return_cov:
            return mean, cov
        return mean, np.sqrt(np.maximum(np.diag(cov), 0.0))


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
