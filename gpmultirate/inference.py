"""Inference: the posterior of the FIR coefficients and the log evidence.

With ``Ky = Phi K Phi^T + gamma I_M`` (the covariance of the slow data) and
its Cholesky factor ``L``:

* posterior mean of the coefficients, eq. (15): ``K Phi^T Ky^{-1} y``;
* posterior covariance: ``K - B^T B`` with ``B = L^{-1} Phi K``;
* log marginal likelihood, eq. (19) with the noise inside the determinant:
  ``-1/2 y^T Ky^{-1} y - 1/2 log det Ky - M/2 log(2 pi)``;
* its gradient by the trace identity
  ``d/dtheta_j = 1/2 tr((a a^T - Ky^{-1}) dKy/dtheta_j)`` with
  ``a = Ky^{-1} y``, evaluated as ``1/2 sum(A * dK_j)`` with
  ``A = Phi^T (a a^T - Ky^{-1}) Phi`` so that no ``Phi dK Phi^T`` product is
  formed per hyperparameter.

Every route evaluates the Gaussian log density through one function,
:func:`log_gaussian` (eq. 19, corrected); the structured products come from
the kernel's terms (:func:`gpmultirate.kernels.observe`) and the
observation's reduction, never from type tests here.  :class:`LogEvidence`
packages the evidence as a function of ``theta`` (the hyperparameters in their
tuning coordinates: the log of most, ``artanh`` of DC's ``beta``) for tuning.
"""

from __future__ import annotations

import contextlib
import warnings

import numpy as np
from scipy import linalg

from sklearn.base import clone
from threadpoolctl import ThreadpoolController

from gpmultirate.exceptions import NumericalWarning
from gpmultirate.kernels import observe
from gpmultirate.kernels.structure import cross_kernel
from gpmultirate.observations import reduce_observation

__all__ = [
    "DataSpacePosterior",
    "GaussianCoefficients",
    "LogEvidence",
    "ParameterSpacePosterior",
    "PrecisionPosterior",
    "blas_threads_for",
    "gaussian_samples",
    "inverse_from_cholesky",
    "log_gaussian",
    "log_marginal_likelihood",
    "log_marginal_likelihood_fisher",
    "one_blas_thread",
    "posterior",
    "robust_cholesky",
]

LOG_2PI = np.log(2.0 * np.pi)

# Below this size the matrices of a fit are too small for threaded BLAS to pay
# off, and on a busy machine its threads spin against each other: one thread.
SINGLE_THREAD_SIZE = 1500


_controller = None


def _blas_controller() -> ThreadpoolController:
    """One controller per process: finding the loaded libraries costs milliseconds.

    ``threadpool_limits`` scans every loaded shared library on each call
    (8 ms with scipy and scikit-learn loaded, twice per fit); the BLAS
    libraries a fit uses are loaded with numpy and scipy, before it.
    """
    global _controller
    if _controller is None:
        _controller = ThreadpoolController()
    return _controller


def one_blas_thread():
    """A context with one BLAS thread (the process's one thread controller).

    Examples
    --------
    >>> with one_blas_thread():
    ...     pass
    """
    return _blas_controller().limit(limits=1, user_api="blas")


def blas_threads_for(observation):
    """A context with one BLAS thread for small problems, no limit otherwise.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> with blas_threads_for(DownsampledConvolution(np.ones(90), 3, 30)):
    ...     pass
    """
    if max(observation.n_outputs, observation.n_coefficients) <= SINGLE_THREAD_SIZE:
        return one_blas_thread()
    return contextlib.nullcontext()


def log_gaussian(quadratic: float, log_det: float, n: int) -> float:
    """``log N(y; 0, Ky)`` from ``y^T Ky^{-1} y``, ``log det Ky`` and ``n = len(y)``.

    The log marginal likelihood of eq. (19) with the noise inside the
    determinant (see the reading notes):
    ``-1/2 y^T Ky^{-1} y - 1/2 log det Ky - n/2 log(2 pi)``.

    Examples
    --------
    >>> from scipy.stats import multivariate_normal
    >>> value = log_gaussian(0.5**2 / 2.0, np.log(2.0), 1)
    >>> bool(np.isclose(value, multivariate_normal(0.0, 2.0).logpdf(0.5)))
    True
    """
    return float(-0.5 * quadratic - 0.5 * log_det - 0.5 * n * LOG_2PI)


def gaussian_samples(mean: np.ndarray, cov: np.ndarray, n_samples: int, rng) -> np.ndarray:
    """Draws of ``N(mean, cov)`` as columns, for a positive semidefinite ``cov``.

    The covariance is decomposed by ``eigh`` (negative rounding eigenvalues
    clipped to zero), which also serves singular covariances.
    """
    values, vectors = linalg.eigh(cov, check_finite=False)
    root = vectors * np.sqrt(np.maximum(values, 0.0))
    return mean[:, None] + root @ rng.standard_normal((mean.shape[0], n_samples))


def robust_cholesky(A: np.ndarray, what: str = "data covariance") -> tuple[np.ndarray, float]:
    """Lower Cholesky factor of a symmetric matrix, adding jitter if needed.

    Returns the factor and the jitter that was added to the diagonal.  A
    :class:`~gpmultirate.exceptions.NumericalWarning` is emitted when jitter
    was needed; a :class:`ValueError` when even large jitter fails.
    """
    if not np.all(np.isfinite(A)):
        raise ValueError(f"the {what} has non-finite entries; check the hyperparameters")
    try:
        return linalg.cholesky(A, lower=True, check_finite=False), 0.0
    except linalg.LinAlgError:
        pass
    scale = float(np.mean(np.abs(np.diag(A)))) or 1.0
    for relative in 10.0 ** np.arange(-12, -3):
        jitter = relative * scale
        try:
            L = linalg.cholesky(
                A + jitter * np.eye(A.shape[0]), lower=True, check_finite=False
            )
        except linalg.LinAlgError:
            continue
        warnings.warn(
            f"the {what} is not numerically positive definite; added {jitter:.2g} "
            "to its diagonal",
            NumericalWarning,
            stacklevel=3,
        )
        return L, jitter
    raise ValueError(
        f"the {what} is not positive definite even with jitter "
        f"{1e-4 * scale:.2g}; increase noise_level or check the kernel"
    )


class GaussianCoefficients:
    """Gaussian distribution of FIR coefficients with covariance ``K - B^T B``.

    The covariance is kept in this factored form so that linear functionals
    (outputs, FRF values) never need the ``P x P`` posterior covariance.
    """

    def __init__(self, coef: np.ndarray, K: np.ndarray, B: np.ndarray):
        self.coef = coef
        self.K = K
        self.B = B

    def linear_map(self, A: np.ndarray, full_cov: bool = False):
        """Mean and covariance (or variance) of ``A g`` for a ``(q, P)`` matrix ``A``."""
        mean = A @ self.coef
        if full_cov:
            BA = self.B @ A.T
            cov = A @ self.K @ A.T - BA.T @ BA
            return mean, 0.5 * (cov + cov.T)
        return mean, self.pair_variances(A, None)[0]

    def pair_variances(self, A1: np.ndarray, A2: np.ndarray | None):
        """``Var(A1 g)``, ``Var(A2 g)`` and ``Cov(A1 g, A2 g)`` row by row.

        Each projection is formed once; with ``A2=None`` only the first
        variance is computed (the others are None).
        """
        K1, B1 = A1 @ self.K, self.B @ A1.T
        var1 = np.einsum("ij,ij->i", K1, A1) - np.einsum("ij,ij->j", B1, B1)
        if A2 is None:
            return np.maximum(var1, 0.0), None, None
        K2, B2 = A2 @ self.K, self.B @ A2.T
        var2 = np.einsum("ij,ij->i", K2, A2) - np.einsum("ij,ij->j", B2, B2)
        cov = np.einsum("ij,ij->i", K1, A2) - np.einsum("ij,ij->j", B1, B2)
        return np.maximum(var1, 0.0), np.maximum(var2, 0.0), cov

    def covariance(self) -> np.ndarray:
        """The ``P x P`` covariance ``K - B^T B``."""
        cov = self.K - self.B.T @ self.B
        return 0.5 * (cov + cov.T)


class DataSpacePosterior(GaussianCoefficients):
    """Posterior of the FIR coefficients given slow data, in the M x M data space.

    Parameters
    ----------
    operator : Observation
    kernel : sklearn Kernel over lags
    noise_level : float
        Noise variance ``gamma`` of the slow samples.
    y : ndarray of shape (M,)
    """

    def __init__(self, operator, kernel, noise_level: float, y: np.ndarray):
        term = observe(kernel, operator)
        K = term.kernel_matrix()
        PhiK = term.regressor_times_kernel()
        # the structured S (filters, recursion) rather than the O(M^2 P) PhiK Phi^T
        Ky = term.covariance().copy()
        Ky[np.diag_indices_from(Ky)] += noise_level
        self.L, self.jitter = robust_cholesky(Ky)
        self.alpha = linalg.cho_solve((self.L, True), y, check_finite=False)
        B = linalg.solve_triangular(self.L, PhiK, lower=True, check_finite=False)
        # eq. (15): K Phi^T (Phi K Phi^T + gamma I)^{-1} y
        super().__init__(PhiK.T @ self.alpha, K, B)
        self.log_marginal_likelihood = log_gaussian(
            y @ self.alpha, 2.0 * np.log(np.diag(self.L)).sum(), y.shape[0]
        )

    def mean_at_lags(self, operator, kernel, X: np.ndarray) -> np.ndarray:
        """Posterior mean of ``g`` at the kernel inputs ``X`` (real lags, as a column)."""
        return operator.cross_covariance(kernel, X) @ self.alpha

    def at_lags(self, operator, kernel, X: np.ndarray, full_cov: bool):
        """Posterior mean and variance (or covariance) of ``g`` at the kernel inputs ``X``."""
        cross = operator.cross_covariance(kernel, X)
        mean = cross @ self.alpha
        V = linalg.solve_triangular(self.L, cross.T, lower=True, check_finite=False)
        if full_cov:
            cov = kernel(X) - V.T @ V
            return mean, 0.5 * (cov + cov.T)
        var = kernel.diag(X) - np.einsum("ij,ij->j", V, V)
        return mean, np.maximum(var, 0.0)


class _FactoredCoefficients(GaussianCoefficients):
    """Coefficients whose covariance ``Sigma = S S^T`` is used through products ``A S``.

    Subclasses provide :meth:`times_root`; variances of linear functionals
    are then row norms of ``A S``.
    """

    def times_root(self, A: np.ndarray) -> np.ndarray:
        """``A S`` for a ``(q, P)`` matrix ``A``."""
        raise NotImplementedError

    def pair_variances(self, A1: np.ndarray, A2: np.ndarray | None):
        F1 = self.times_root(A1)
        var1 = np.einsum("ij,ij->i", F1, F1)
        if A2 is None:
            return var1, None, None
        F2 = self.times_root(A2)
        return var1, np.einsum("ij,ij->i", F2, F2), np.einsum("ij,ij->i", F1, F2)

    def linear_map(self, A: np.ndarray, full_cov: bool = False):
        mean = A @ self.coef
        AF = self.times_root(A)
        if full_cov:
            return mean, AF @ AF.T
        return mean, np.einsum("ij,ij->i", AF, AF)


class ParameterSpacePosterior(_FactoredCoefficients):
    """Posterior of the FIR coefficients in the parameter space, for ``M > P``.

    With ``K = F F^T`` (eigen-decomposition, dropping directions of
    numerically zero prior variance) and ``g = F z``, ``z ~ N(0, I)``, the
    posterior mean of ``z`` solves the stacked least-squares problem

        min_z ||y - Phi F z||^2 / gamma + ||z||^2,

    which is solved by a QR factorisation of ``[Phi F / sqrt(gamma); I]``:
    its accuracy is that of least squares, not of the ``M x M`` matrix
    ``Phi K Phi^T + gamma I``, whose condition number grows as ``1/gamma``
    when ``M > P``.  The evidence follows from the same factor:
    ``y^T Ky^{-1} y`` is the minimum above and
    ``log det Ky = M log gamma + log det(R^T R)``.
    """

    def __init__(self, operator, kernel, noise_level: float, y: np.ndarray):
        Phi = operator.matrix
        K = operator.kernel_matrix(kernel)
        values, vectors = linalg.eigh(0.5 * (K + K.T), check_finite=False)
        keep = values > max(values.max(), 0.0) * 1e-14
        if not np.any(keep):
            raise ValueError("the kernel matrix is zero at lags 0..order-1")
        self.inv_root = vectors[:, keep] / np.sqrt(values[keep])  # F^{+T}
        F = vectors[:, keep] * np.sqrt(values[keep])
        root_noise = np.sqrt(noise_level)
        rank = F.shape[1]
        stacked = np.vstack([Phi @ F / root_noise, np.eye(rank)])
        Q, R = linalg.qr(stacked, mode="economic", check_finite=False)
        z = linalg.solve_triangular(R, Q[: y.shape[0]].T @ (y / root_noise), check_finite=False)
        self.z = z
        self.R = R
        residual = y - Phi @ (F @ z)
        quad = residual @ residual / noise_level + z @ z
        log_det = y.shape[0] * np.log(noise_level) + 2.0 * np.log(np.abs(np.diag(R))).sum()
        self.log_marginal_likelihood = log_gaussian(quad, log_det, y.shape[0])
        self.factor = linalg.solve_triangular(R, F.T, trans="T", check_finite=False).T
        super().__init__(F @ z, K, None)

    def times_root(self, A: np.ndarray) -> np.ndarray:
        return A @ self.factor

    def covariance(self) -> np.ndarray:
        return self.factor @ self.factor.T

    def mean_at_lags(self, operator, kernel, X: np.ndarray) -> np.ndarray:
        """Posterior mean of ``g`` at the kernel inputs ``X`` (real lags, as a column)."""
        return cross_kernel(kernel, X, operator.lags) @ (self.inv_root @ self.z)

    def at_lags(self, operator, kernel, X: np.ndarray, full_cov: bool):
        """Posterior of ``g(X)``: the prior conditional on ``g(0..P-1)``, averaged."""
        J = cross_kernel(kernel, X, operator.lags) @ self.inv_root
        mean = J @ self.z
        JS = J @ linalg.solve_triangular(self.R, np.eye(self.R.shape[0]), check_finite=False)
        if full_cov:
            cov = kernel(X) - J @ J.T + JS @ JS.T
            return mean, 0.5 * (cov + cov.T)
        var = kernel.diag(X) - np.einsum("ij,ij->i", J, J) + np.einsum("ij,ij->i", JS, JS)
        return mean, np.maximum(var, 0.0)


class PrecisionPosterior(_FactoredCoefficients):
    """Posterior of the FIR coefficients through a tridiagonal ``K^{-1}``, for ``M > P``.

    For a prior whose precision ``Q = K^{-1}`` is tridiagonal (DC, a
    constant times DC: :mod:`gpmultirate.kernels.precision`), the posterior
    precision of the reduced observation ``C = Q + Phi^T Phi / gamma`` is
    factored once, ``C = L L^T`` (:func:`_solve_by_precision`, shared with
    the evidence): the mean is ``mu = C^{-1} Phi^T y / gamma``, eq. (15),
    and the covariance ``Sigma = C^{-1} = S S^T`` with ``S = L^{-T}``,
    applied by triangular solves.  One Cholesky factorization replaces the
    two ``eigh`` and the QR of :class:`ParameterSpacePosterior`.  Built by
    :meth:`attempt`, which gives None where that route does not apply.

    Parameters
    ----------
    coef : ndarray of shape (P,)
        The posterior mean ``mu``.
    L : ndarray of shape (P, P)
        Lower Cholesky factor of ``C``.
    precision : TridiagonalPrecision
        ``Q = K^{-1}``.
    log_marginal_likelihood : float
        The evidence of the (reduced) observation.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import DC
    >>> rng = np.random.default_rng(0)
    >>> op = DownsampledConvolution(rng.standard_normal(300), factor=2, order=20)
    >>> y = op.matvec(0.8 ** np.arange(20)) + 0.01 * rng.standard_normal(op.n_outputs)
    >>> type(posterior(op, C(1.0) * DC(0.8, 0.5), 1e-4, y)).__name__
    'PrecisionPosterior'
    """

    def __init__(self, coef, L, precision, log_marginal_likelihood: float):
        # every use of the covariance goes through L: no P x P prior matrix is kept
        super().__init__(coef, None, None)
        self.L = L
        self.precision = precision
        self.log_marginal_likelihood = log_marginal_likelihood

    @classmethod
    def attempt(cls, operator, kernel, noise_level: float, y: np.ndarray):
        """The posterior of a square or reduced observation through ``K^{-1}``, or None.

        None when the kernel's term offers no precision
        (:meth:`~gpmultirate.kernels.ObservedTerm.precision`) or ``C`` is not
        numerically positive definite.
        """
        precision = _square_precision(observe(kernel, operator), operator)
        found = None if precision is None else _solve_by_precision(
            operator, precision, noise_level, y)
        if found is None:
            return None
        L, mu, _, value = found
        return cls(mu, L, precision, value)

    def times_root(self, A: np.ndarray) -> np.ndarray:
        # A L^{-T} = (L^{-1} A^T)^T
        return linalg.solve_triangular(self.L, A.T, lower=True, check_finite=False).T

    def covariance(self) -> np.ndarray:
        return inverse_from_cholesky(self.L)

    def mean_at_lags(self, operator, kernel, X: np.ndarray) -> np.ndarray:
        """Posterior mean of ``g`` at the kernel inputs ``X`` (real lags, as a column)."""
        return cross_kernel(kernel, X, operator.lags) @ self.precision.times(self.coef)

    def at_lags(self, operator, kernel, X: np.ndarray, full_cov: bool):
        """Posterior of ``g(X)``: the prior conditional on ``g(0..P-1)``, averaged.

        With ``J = k(X, lags) K^{-1}`` (``K^{-1}`` tridiagonal): mean ``J mu``,
        covariance ``k(X, X) - J k(lags, X) + J Sigma J^T``.
        """
        cross = cross_kernel(kernel, X, operator.lags)
        J = self.precision.times(cross.T).T
        mean = J @ self.coef
        JS = self.times_root(J)
        if full_cov:
            cov = kernel(X) - J @ cross.T + JS @ JS.T
            return mean, 0.5 * (cov + cov.T)
        var = kernel.diag(X) - np.einsum("ij,ij->i", J, cross) + np.einsum("ij,ij->i", JS, JS)
        return mean, np.maximum(var, 0.0)


def posterior(operator, kernel, noise_level: float, y: np.ndarray) -> GaussianCoefficients:
    """The posterior in whichever space is smaller: data (``M <= P``) or parameters.

    For ``M > P`` the data are first reduced to the ``P x P`` factor of
    :class:`~gpmultirate.observations.ReducedObservation` (never holding
    ``Phi``), whose least-squares form gives the same posterior; ``operator``
    may be such a reduction already (``y`` is then its ``z``).  The posterior
    of the reduction is :class:`PrecisionPosterior` where the prior has a
    tridiagonal precision, else :class:`ParameterSpacePosterior`.
    """
    data, z = reduce_observation(operator, y)
    if data.n_discarded == 0:
        return DataSpacePosterior(data, kernel, noise_level, z)
    result = PrecisionPosterior.attempt(data, kernel, noise_level, z)
    if result is None:
        result = ParameterSpacePosterior(data, kernel, noise_level, z)
    result.log_marginal_likelihood += data.discarded_log_likelihood(noise_level)[0]
    return result


def log_marginal_likelihood(
    operator, kernel, noise_level: float, y: np.ndarray, eval_gradient: bool, noise_free: bool
):
    """Log evidence of the slow data and its gradient with respect to ``theta``.

    The gradient has the kernel's ``theta`` first and, when ``noise_free`` is
    true, the derivative with respect to ``log(noise_level)`` last.
    """
    term = observe(kernel, operator)
    precision = _square_precision(term, operator)
    if precision is not None:
        found = _log_marginal_likelihood_by_precision(
            operator, precision, noise_level, y, eval_gradient, noise_free
        )
        if found is not None:
            return found
    if eval_gradient:
        S, contract = term.covariance_with_contractor()
    else:
        S = term.covariance()
    Ky = S.copy()
    Ky[np.diag_indices_from(Ky)] += noise_level
    L, _ = robust_cholesky(Ky)
    alpha = linalg.cho_solve((L, True), y, check_finite=False)
    rest_value, rest_grad, _ = operator.discarded_log_likelihood(noise_level)
    value = log_gaussian(y @ alpha, 2.0 * np.log(np.diag(L)).sum(), y.shape[0]) + rest_value
    if not eval_gradient:
        return value
    W = inverse_from_cholesky(L)
    W *= -1.0
    W = linalg.blas.dger(1.0, alpha, alpha, a=W, overwrite_a=True)  # + alpha alpha^T
    grad = 0.5 * contract(W)
    if noise_free:
        grad = np.append(grad, 0.5 * np.trace(W) * noise_level + rest_grad)
    return value, grad


def _square_precision(term, operator):
    """The prior's tridiagonal precision where the evidence and posterior go through it.

    Square (or reduced, ``M = P``) data and a term that offers one
    (:meth:`~gpmultirate.kernels.ObservedTerm.precision`); None otherwise.
    """
    if operator.n_outputs != operator.n_coefficients:
        return None
    return term.precision()


def _solve_by_precision(operator, precision, noise_level, y):
    """The posterior precision's Cholesky factor, the posterior mean and the evidence, or None.

    For a square (or reduced, ``M = P``) observation and a tridiagonal
    ``Q = K^{-1}``, with ``A = Phi^T Phi`` and ``C = Q + A / gamma`` (the
    posterior precision), ``mu = C^{-1} Phi^T y / gamma`` (eq. 15 by the
    matrix inversion lemma) and

    * ``y^T Ky^{-1} y = |y - Phi mu|^2 / gamma + mu^T Q mu``;
    * ``log det Ky = M log gamma + log det K + log det C`` (``M = P``).

    Returns ``(L, mu, |y - Phi mu|^2, log N(y; 0, Ky))`` with ``C = L L^T``,
    or None when ``C`` is not numerically positive definite.
    """
    A, _ = operator.gram()  # kept by the observation: the same in every evaluation
    b = operator.rmatvec(y)
    C = A / noise_level
    P = C.shape[0]
    C.flat[:: P + 1] += precision.diagonal
    C.flat[1 :: P + 1] += precision.off_diagonal
    C.flat[P :: P + 1] += precision.off_diagonal
    try:
        L = linalg.cholesky(C, lower=True, overwrite_a=True, check_finite=False)
    except linalg.LinAlgError:
        return None
    mu = linalg.cho_solve((L, True), b / noise_level, check_finite=False)
    residual = y - operator.matvec(mu)
    squares = float(residual @ residual)
    quadratic = squares / noise_level + float(mu @ precision.times(mu))
    log_det = (P * np.log(noise_level) + precision.log_det_covariance
               + 2.0 * np.log(np.diag(L)).sum())
    return L, mu, squares, log_gaussian(quadratic, log_det, P)


def _log_marginal_likelihood_by_precision(operator, precision, noise_level, y, eval_gradient,
                                          noise_free):
    """The evidence of a square (or reduced) observation through a tridiagonal ``K^{-1}``.

    With ``Q = K^{-1}`` and ``Sigma = C^{-1}`` (:func:`_solve_by_precision`):

    * ``d/d theta_j = -1/2 (mu^T dQ_j mu + tr(Sigma dQ_j) + d log det K / d theta_j)``;
    * ``d/d log gamma = 1/2 |y - Phi mu|^2 / gamma - 1/2 tr(Sigma Q)``.

    ``dQ_j`` and ``Q`` are tridiagonal, so only the tridiagonal band of
    ``Sigma`` is needed: a Cholesky factorisation and a triangular inverse,
    about a quarter of the flops of the data-space route.  None when ``C``
    is not numerically positive definite (the data-space route then answers).
    """
    found = _solve_by_precision(operator, precision, noise_level, y)
    if found is None:
        return None
    L, mu, squares, value = found
    rest_value, rest_grad, _ = operator.discarded_log_likelihood(noise_level)
    value += rest_value
    if not eval_gradient:
        return value
    inverse, info = linalg.lapack.dtrtri(L, lower=1)
    if info != 0:
        return None
    # the band of Sigma = L^{-T} L^{-1}, and of Sigma + mu mu^T
    sigma_diagonal = np.einsum("ki,ki->i", inverse, inverse)
    sigma_off = np.einsum("ki,ki->i", inverse[:, :-1], inverse[:, 1:])
    band_diagonal = sigma_diagonal + mu * mu
    band_off = sigma_off + mu[:-1] * mu[1:]
    grad = np.array([
        -0.5 * (d @ band_diagonal + 2.0 * (o @ band_off) + log_det_j)
        for (d, o), log_det_j in zip(precision.derivatives, precision.log_det_gradient)
    ])
    if noise_free:
        trace = precision.diagonal @ sigma_diagonal + 2.0 * (precision.off_diagonal @ sigma_off)
        grad = np.append(grad, 0.5 * squares / noise_level - 0.5 * trace + rest_grad)
    return value, grad


def inverse_from_cholesky(L: np.ndarray) -> np.ndarray:
    """The symmetric inverse ``(L L^T)^{-1}`` from a lower Cholesky factor (LAPACK potri)."""
    inverse, info = linalg.lapack.dpotri(L, lower=1)
    if info != 0:
        return linalg.cho_solve((L, True), np.eye(L.shape[0]), check_finite=False)
    # potri fills the lower triangle; the upper one is that of L, zero
    diagonal = np.diag(inverse).copy()
    inverse += inverse.T
    inverse[np.diag_indices_from(inverse)] = diagonal
    return inverse


def log_marginal_likelihood_fisher(
    operator, kernel, noise_level: float, y: np.ndarray, noise_free: bool
):
    """Log evidence, its gradient and its Fisher information in ``theta``.

    With ``a = Ky^{-1} y`` and ``V_j = Ky^{-1} dKy_j`` (``dKy_j`` the
    derivative of the data covariance with respect to ``theta_j``):

    * gradient ``g_j = 1/2 (a^T dKy_j a - tr V_j)``;
    * Fisher information ``F_jk = 1/2 tr(V_j V_k)``, the expected negative
      Hessian of the log evidence.

    A dense derivative costs one matrix product ``Ky^{-1} dKy_j``; low-rank
    derivatives (PK terms, constants) stay factored, ``dKy_j = U D U^T``
    with ``B = Ky^{-1} U``, so their traces cost ``O(M^2 r)``.  The entries
    follow the kernel's ``theta`` and, when ``noise_free``, ``log(noise_level)``
    last.
    """
    S, items = observe(kernel, operator).covariance_with_derivatives()
    Ky = S.copy()  # S may itself be an item (the derivative of an amplitude)
    Ky[np.diag_indices_from(Ky)] += noise_level
    L, _ = robust_cholesky(Ky)
    M = y.shape[0]
    inverse = inverse_from_cholesky(L)
    a = inverse @ y
    value = log_gaussian(y @ a, 2.0 * np.log(np.diag(L)).sum(), M)
    terms = []  # ("dense", dS, V, V^T) or ("factor", U, B, D)
    solved = {}  # factors shared by the items of one PK term are solved once
    for item in items:
        if isinstance(item, tuple):
            U, D = item
            if id(U) not in solved:
                solved[id(U)] = inverse @ U
            terms.append(("factor", U, solved[id(U)], D))
        else:
            product = inverse @ item
            # tr(V_j V_k) = sum(V_j * V_k^T): keep the transpose contiguous
            terms.append(("dense", item, product, np.ascontiguousarray(product.T)))
    if noise_free:
        scaled = noise_level * inverse  # symmetric: its own transpose
        terms.append(("dense", None, scaled, scaled))
    n = len(terms)
    grad = np.empty(n)
    fisher = np.empty((n, n))
    for j, term in enumerate(terms):
        if term[0] == "factor":
            _, U, B, D = term
            Ua = U.T @ a
            grad[j] = 0.5 * (Ua @ D @ Ua - np.sum(D * (B.T @ U)))
        else:
            _, dS, V, _ = term
            quad = noise_level * (a @ a) if dS is None else a @ dS @ a
            grad[j] = 0.5 * (quad - np.trace(V))
        for k in range(j + 1):
            fisher[j, k] = fisher[k, j] = 0.5 * _trace_of_product(term, terms[k])
    rest_value, rest_grad, rest_fisher = operator.discarded_log_likelihood(noise_level)
    value += rest_value
    if noise_free:
        grad[-1] += rest_grad
        fisher[-1, -1] += rest_fisher
    return value, grad, fisher


def _trace_of_product(term1, term2) -> float:
    """``tr(V1 V2)`` for ``V = Ky^{-1} dKy`` given as dense products or factors."""
    if term1[0] == "factor" and term2[0] == "factor":
        _, U1, _, D1 = term1
        _, _, B2, D2 = term2
        C = U1.T @ B2  # U1^T Ky^{-1} U2
        return float(np.sum((D1 @ C) * (C @ D2)))
    if term1[0] == "factor":
        term1, term2 = term2, term1
    V = term1[2]
    if term2[0] == "factor":
        _, U, B, D = term2
        # tr(V B D U^T) = sum((U^T V B) * D^T)
        return float(np.sum(((U.T @ V) @ B) * D.T))
    return float(np.vdot(V, term2[3]))


def resonance_grid_log_marginal_likelihood(
    operator, kernel, term, name: str, noise_level: float, y: np.ndarray, values: np.ndarray
):
    """Log evidence for each value of the hyperparameter ``name`` of one low-rank summand.

    ``term`` must be a summand of ``kernel`` (not inside a product) whose
    structured term is low rank (:meth:`~gpmultirate.kernels.ObservedTerm.low_rank`),
    such as a PK resonance; returns None otherwise.  The rest of the data
    covariance is factored once and the summand enters each candidate by
    the matrix determinant lemma and the Woodbury identity: ``O(M^2)`` per
    candidate instead of ``O(M^3)``.
    """
    tree = observe(kernel, operator)
    S_rest = tree.covariance_without(term)
    found = None if S_rest is None else tree.candidate_factors(term, name, values)
    if found is None:
        return None
    U, weights = found
    Ky = S_rest
    Ky[np.diag_indices_from(Ky)] += noise_level
    L, _ = robust_cholesky(Ky)
    w = linalg.solve_triangular(L, y, lower=True, check_finite=False)
    half_log_det = np.log(np.diag(L)).sum()
    rest = operator.discarded_log_likelihood(noise_level)[0]
    A = linalg.solve_triangular(L, U, lower=True, check_finite=False)
    result = np.empty(len(values))
    start = 0
    for k, weight in enumerate(weights):
        rank = weight.shape[0]
        # B = L^{-1} U_k D^{1/2}, for the positive semidefinite weight D
        d, Q = np.linalg.eigh(weight)
        B = A[:, start : start + rank] @ (Q * np.sqrt(np.maximum(d, 0.0)))
        start += rank
        C = np.eye(rank) + B.T @ B
        b = B.T @ w
        chol = np.linalg.cholesky(C)
        v = np.linalg.solve(chol, b)
        # Woodbury: quadratic w^T w - v^T v; determinant lemma: det Ky = det(L L^T) det C
        result[k] = log_gaussian(
            w @ w - v @ v, 2.0 * (half_log_det + np.log(np.diag(chol)).sum()), y.shape[0]
        ) + rest
    return result


class LogEvidence:
    """The log marginal likelihood of the data as a function of ``theta``.

    The objective that tuning maximizes: ``theta`` is the kernel's ``theta``
    followed, when the noise level is tuned, by ``log(noise_level)``.  Long
    records are reduced once here (:meth:`~gpmultirate.observations.Observation.reduced`),
    so an evaluation never costs more than ``O(P^3)``.

    Parameters
    ----------
    observation : Observation
    y : ndarray of shape (M,)
    kernel : sklearn Kernel
        The kernel at the initial hyperparameters (not modified).
    noise_level : float
        The noise variance; the initial value when it is tuned.
    noise_bounds : pair of floats or "fixed"

    Attributes
    ----------
    data, z : Observation and ndarray
        The observation and outputs the evidence is computed from (reduced
        when ``M > P``).
    noise_is_free : bool
        Whether ``log(noise_level)`` is the last entry of ``theta``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import DC
    >>> rng = np.random.default_rng(0)
    >>> op = DownsampledConvolution(rng.standard_normal(90), factor=3, order=30)
    >>> y = op.matvec(0.8 ** np.arange(30)) + 0.01 * rng.standard_normal(op.n_outputs)
    >>> evidence = LogEvidence(op, y, C(1.0) * DC(), 1e-3, (1e-6, 1.0))
    >>> value, gradient = evidence(evidence.theta, eval_gradient=True)
    >>> gradient.shape
    (4,)
    """

    #: whether :meth:`with_fisher` is available (Fisher scoring may be used)
    has_fisher = True

    def __init__(self, observation, y, kernel, noise_level: float, noise_bounds):
        self.data, self.z = reduce_observation(observation, y)
        self.kernel = kernel
        self.noise_level = float(noise_level)
        self.noise_bounds = noise_bounds
        self.noise_is_free = not isinstance(noise_bounds, str)
        self._work = None

    @property
    def n_outputs(self) -> int:
        """Outputs of the (reduced) data: the size of every data-space matrix."""
        return self.data.n_outputs

    @property
    def theta(self) -> np.ndarray:
        """The initial ``theta``: the kernel's and, if tuned, ``log(noise_level)``."""
        theta = self.kernel.theta
        return np.append(theta, np.log(self.noise_level)) if self.noise_is_free else theta

    @property
    def bounds(self) -> np.ndarray:
        """Bounds of ``theta`` (the kernel's ``bounds``, log noise bounds), of shape ``(n, 2)``."""
        bounds = self.kernel.bounds.reshape(-1, 2)
        if self.noise_is_free:
            bounds = np.vstack([bounds, np.log(self.noise_bounds)])
        return bounds

    def roles(self) -> list:
        """One :class:`~gpmultirate.kernels.Role` per kernel entry of ``theta``."""
        return observe(self.kernel).roles()

    def scale_positions(self):
        """``[(position, power)]`` of the amplitudes that scale the whole kernel, or None."""
        term = observe(self.kernel)
        positions = term.scale_roles()
        if positions is None:
            return None
        roles = term.roles()
        return [(i, roles[i].power) for i in positions]

    def amplitude_couplings(self):
        """Correlations and the amplitudes scaling their terms, as positions in ``theta``.

        ``[(correlation, amplitude, power)]`` with the amplitude's power (see
        :meth:`~gpmultirate.kernels.ObservedTerm.amplitude_couplings`).
        """
        term = observe(self.kernel)
        roles = term.roles()
        return [(j, a, roles[a].power) for j, a in term.amplitude_couplings()]

    def scale_groups(self, theta):
        """``[(positions, powers, S_part)]`` of independently scaled parts of ``S`` at ``theta``, or None."""
        kernel, _ = self.split(theta)
        tree = observe(kernel, self.data)
        groups = tree.scale_groups()
        if groups is None:
            return None
        roles = tree.roles()
        return [(positions, [roles[i].power for i in positions], S) for positions, S in groups]

    def split(self, theta, into=None):
        """The kernel and noise level of ``theta``.

        With ``into`` (a kernel of the same structure) its ``theta`` is set
        in place instead of cloning.
        """
        n_kernel = self.kernel.theta.shape[0]
        if into is None:
            kernel = self.kernel.clone_with_theta(theta[:n_kernel])
        else:
            into.theta = theta[:n_kernel]
            kernel = into
        noise = float(np.exp(theta[n_kernel])) if self.noise_is_free else self.noise_level
        return kernel, noise

    def moved_to(self, kernel, noise_level: float) -> "LogEvidence":
        """The same objective, on the same (reduced) data, started at ``kernel`` and ``noise_level``."""
        moved = type(self).__new__(type(self))
        moved.__dict__.update(self.__dict__)
        moved.kernel, moved.noise_level = kernel, float(noise_level)
        return moved

    def reusing_kernel(self) -> "LogEvidence":
        """A copy whose evaluations set the hyperparameters of one working kernel in place.

        An optimizer evaluates hundreds of points, and a deep copy of the
        kernel per point is a large part of a small problem's cost.
        """
        reusing = self.moved_to(self.kernel, self.noise_level)
        reusing._work = clone(self.kernel)
        return reusing

    @property
    def by_precision(self) -> bool:
        """Whether evaluations go through the prior's tridiagonal precision.

        So they do for square or reduced data (``M = P``) and a prior that
        offers one (DC, a constant times DC): each evaluation is then a
        ``P x P`` Cholesky factor and a triangular inverse, much cheaper than
        the data-space Fisher information.
        """
        return _square_precision(observe(self.kernel, self.data), self.data) is not None

    def covariance(self) -> np.ndarray:
        """``S = Phi K Phi^T`` of the (reduced) data at the initial kernel."""
        return observe(self.kernel, self.data).covariance()

    def __call__(self, theta, eval_gradient: bool = False):
        """The log evidence at ``theta`` and, with ``eval_gradient``, its gradient."""
        kernel, noise = self.split(theta, into=self._work)
        return log_marginal_likelihood(
            self.data, kernel, noise, self.z, eval_gradient, self.noise_is_free
        )

    def with_fisher(self, theta):
        """The log evidence, its gradient and its Fisher information at ``theta``."""
        kernel, noise = self.split(theta, into=self._work)
        return log_marginal_likelihood_fisher(
            self.data, kernel, noise, self.z, self.noise_is_free
        )

    def along(self, theta, index: int, values):
        """The log evidence for each value of ``theta[index]``, or None.

        ``values`` are hyperparameter values (not their ``theta`` coordinates).  None unless
        the entry belongs to a low-rank summand of the kernel.
        """
        role = self.roles()[index]
        kernel, noise = self.split(theta, into=self._work)
        prefix = role.name[: -len(role.leaf_name)].rstrip("_")
        owner = kernel.get_params()[prefix] if prefix else kernel
        return resonance_grid_log_marginal_likelihood(
            self.data, kernel, owner, role.leaf_name, noise, self.z, values
        )

    def posterior(self, kernel, noise_level: float):
        """The posterior of the coefficients for ``kernel`` and ``noise_level``."""
        return posterior(self.data, kernel, noise_level, self.z)
