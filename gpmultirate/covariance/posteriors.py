"""The posterior of the FIR coefficients, as each route of the data covariance gives it.

Every :class:`~gpmultirate.covariance.DataCovariance` answers
``posterior(y)`` from its own factor:

* :class:`DataSpacePosterior` (the dense route, ``M <= P``): eq. (15),
  ``K Phi^T Ky^{-1} y``, covariance ``K - B^T B`` with ``B = L^{-1} Phi K``;
* :class:`ParameterSpacePosterior` (a reduced long record, AR(1) noise):
  ``g = F z`` with the posterior of ``z`` from the stacked least-squares
  factor ``R``;
* :class:`PrecisionPosterior` (a tridiagonal prior precision): the posterior
  precision ``C = L L^T``.

:class:`SpreadPosterior` adds to any of them, after conditioning, the spread
of the frequencies and decays of PK terms tuned on the data
(:mod:`gpmultirate.kernels.spread`).

Each holds the observation and the kernel it answers for, so it answers the
posterior at real lags (``at_lags``) on its own.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from gpmultirate.covariance.base import inverse_from_cholesky, log_gaussian
from gpmultirate.kernels.spread import spread_factor
from gpmultirate.kernels.structure import cross_kernel, observe

__all__ = [
    "DataSpacePosterior",
    "GaussianCoefficients",
    "ParameterSpacePosterior",
    "PrecisionPosterior",
    "SpreadPosterior",
    "gaussian_samples",
]


def gaussian_samples(mean: np.ndarray, cov: np.ndarray, n_samples: int, rng) -> np.ndarray:
    """Draws of ``N(mean, cov)`` as columns, for a positive semidefinite ``cov``.

    The covariance is decomposed by ``eigh`` (negative rounding eigenvalues
    clipped to zero), which also serves singular covariances, into its
    symmetric square root ``V sqrt(L) V^T``: unlike the eigenvectors, whose
    signs and bases within nearly equal eigenvalues move with the last digits
    of ``cov`` (another BLAS, another order of sums), that root is a
    continuous function of ``cov``, so a seed gives the same draws to
    rounding wherever the covariance is the same to rounding; from
    ``CHOLESKY_MIN_SIZE`` on by a Cholesky factorization, about ten times
    cheaper (a ``4,096 x 4,096`` ``eigh`` takes tens of seconds), with a
    jitter of at most ``1e-8`` times the largest variance where rounding
    leaves the covariance not quite positive definite (``eigh`` where even
    that fails).  Both are roots ``R R^T = cov``: the draws have the same
    distribution, not the same values for a seed.
    """
    root = _cholesky_root(cov) if mean.shape[0] >= CHOLESKY_MIN_SIZE else None
    if root is None:
        values, vectors = linalg.eigh(cov, check_finite=False)
        root = (vectors * np.sqrt(np.maximum(values, 0.0))) @ vectors.T
    return mean[:, None] + root @ rng.standard_normal((mean.shape[0], n_samples))


#: the size from which :func:`gaussian_samples` draws through a Cholesky factor
CHOLESKY_MIN_SIZE = 512


def _cholesky_root(cov: np.ndarray) -> np.ndarray | None:
    """A lower factor ``L L^T = cov + jitter I`` (jitter 0, then up to 1e-8 of the largest variance)."""
    largest = float(np.max(np.diag(cov))) if cov.size else 0.0
    if not np.isfinite(largest) or largest <= 0.0:
        return None
    for jitter in (0.0, 1e-12, 1e-10, 1e-8):
        try:
            shifted = cov + (jitter * largest) * np.eye(cov.shape[0]) if jitter else cov
            return linalg.cholesky(shifted, lower=True, check_finite=False)
        except linalg.LinAlgError:
            continue
    return None


class GaussianCoefficients:
    """Gaussian distribution of FIR coefficients with covariance ``K - B^T B``.

    The covariance is kept in this factored form so that linear functionals
    (outputs, FRF values) never need the ``P x P`` posterior covariance.
    """

    def __init__(self, coef: np.ndarray, K, B: np.ndarray):
        self.coef = coef
        # the prior's P x P matrix, or a function that makes it when it is first asked for
        # (a fit that only reads the mean and the evidence never holds it)
        self._K = K
        self.B = B

    @property
    def K(self) -> np.ndarray:
        """The prior covariance ``K`` of the coefficients (``P x P``)."""
        if callable(self._K):
            self._K = self._K()
        return self._K

    def innovations(self, y: np.ndarray) -> np.ndarray | None:
        """``L^{-1} y`` for the factor ``L L^T`` of the data's covariance the fit holds; None here.

        Only a posterior formed in data space holds that factor
        (:class:`DataSpacePosterior`); elsewhere the innovations cost a
        factorization of their own (:func:`~gpmultirate.misspecification.innovations`).
        """
        return None

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

    def readings_spread(self, readings) -> np.ndarray | float:
        """The variance a posterior adds after conditioning to ``readings`` (noise-free
        data of an observation); none here (:class:`SpreadPosterior` adds its terms')."""
        return 0.0


class DataSpacePosterior(GaussianCoefficients):
    """Posterior of the FIR coefficients given slow data, in the M x M data space.

    Holds the observation and the kernel, so that it answers the posterior at
    real lags (:meth:`at_lags`) on its own.

    Parameters
    ----------
    covariance : DenseCovariance
        ``Ky = S + gamma I`` of the data (:func:`~gpmultirate.covariance.data_covariance`).
    y : ndarray of shape (M,)
    """

    def __init__(self, covariance, y: np.ndarray):
        term = covariance.term
        self.observation, self.kernel = covariance.observation, covariance.kernel
        PhiK = term.regressor_times_kernel()
        self.L, self.jitter = covariance.L, covariance.jitter
        self.alpha = covariance.solve(y)
        B = covariance.whiten(PhiK)
        # eq. (15): K Phi^T (Phi K Phi^T + gamma I)^{-1} y; K (P x P) made when first asked
        # for (a pilot fit of the default order reads the mean and the evidence only: 0.5 GB
        # at order 7,992)
        super().__init__(PhiK.T @ self.alpha, term.kernel_matrix, B)
        self.log_marginal_likelihood = log_gaussian(
            y @ self.alpha, 2.0 * np.log(np.diag(self.L)).sum(), y.shape[0]
        )

    def mean_at_lags(self, X: np.ndarray) -> np.ndarray:
        """Posterior mean of ``g`` at the kernel inputs ``X`` (real lags, as a column)."""
        return self.observation.cross_covariance(self.kernel, X) @ self.alpha

    def given_data(self, cross: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean and explained variance of quantities whose covariance with the data is ``cross``.

        ``cross`` of shape ``(q, M)``: the mean ``cross Ky^{-1} y`` and
        ``diag(cross Ky^{-1} cross^T)``, which a quantity's prior variance
        less is its posterior variance (readings stacked with the data).
        """
        V = linalg.solve_triangular(self.L, cross.T, lower=True, check_finite=False)
        return cross @ self.alpha, np.einsum("ij,ij->j", V, V)

    def innovations(self, y: np.ndarray) -> np.ndarray:
        """``L^{-1} y`` with the fit's own factor of ``Phi K Phi^T + N`` (jitter included)."""
        return linalg.solve_triangular(self.L, np.asarray(y, dtype=float), lower=True,
                                       check_finite=False)

    def at_lags(self, X: np.ndarray, full_cov: bool = False):
        """Posterior mean and variance (or covariance) of ``g`` at the kernel inputs ``X``."""
        kernel = self.kernel
        cross = self.observation.cross_covariance(kernel, X)
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

    which is solved by a QR factorisation of ``[Phi F / sqrt(gamma); I]``
    (:class:`~gpmultirate.covariance.ParameterSpaceCovariance`): its accuracy
    is that of least squares, not of the ``M x M`` matrix
    ``Phi K Phi^T + gamma I``, whose condition number grows as ``1/gamma``
    when ``M > P``.  The evidence follows from the same factor.

    Parameters
    ----------
    covariance : ParameterSpaceCovariance
    y : ndarray of shape (M,)
    """

    def __init__(self, covariance, y: np.ndarray):
        self.observation, self.kernel = covariance.observation, covariance.kernel
        self.inv_root = covariance.inv_root
        self.z = covariance.whitened_coefficients(y)
        self.R = covariance.R
        self.log_marginal_likelihood = covariance.log_likelihood(y)
        F = covariance.F
        self.factor = linalg.solve_triangular(self.R, F.T, trans="T", check_finite=False).T
        super().__init__(F @ self.z, covariance.K, None)

    def times_root(self, A: np.ndarray) -> np.ndarray:
        return A @ self.factor

    def covariance(self) -> np.ndarray:
        return self.factor @ self.factor.T

    def mean_at_lags(self, X: np.ndarray) -> np.ndarray:
        """Posterior mean of ``g`` at the kernel inputs ``X`` (real lags, as a column)."""
        return cross_kernel(self.kernel, X, self.observation.lags) @ (self.inv_root @ self.z)

    def at_lags(self, X: np.ndarray, full_cov: bool = False):
        """Posterior of ``g(X)``: the prior conditional on ``g(0..P-1)``, averaged."""
        kernel = self.kernel
        J = cross_kernel(kernel, X, self.observation.lags) @ self.inv_root
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
    factored once, ``C = L L^T``
    (:class:`~gpmultirate.covariance.PrecisionCovariance`, shared with the
    evidence): the mean is ``mu = C^{-1} Phi^T y / gamma``, eq. (15), and
    the covariance ``Sigma = C^{-1} = S S^T`` with ``S = L^{-T}``, applied by
    triangular solves.  One Cholesky factorization replaces the two ``eigh``
    and the QR of :class:`ParameterSpacePosterior`.

    Parameters
    ----------
    covariance : PrecisionCovariance
    y : ndarray of shape (P,)

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import DC
    >>> rng = np.random.default_rng(0)
    >>> op = DownsampledConvolution(rng.standard_normal(300), factor=2, order=20)
    >>> y = op.matvec(0.8 ** np.arange(20)) + 0.01 * rng.standard_normal(op.n_outputs)
    >>> from gpmultirate.inference import posterior
    >>> type(posterior(op, C(1.0) * DC(0.8, 0.5), 1e-4, y)).__name__
    'PrecisionPosterior'
    """

    def __init__(self, covariance, y: np.ndarray):
        self.observation, self.kernel = covariance.observation, covariance.kernel
        mu, _ = covariance.posterior_mean(y)
        # every use of the covariance goes through L: no P x P prior matrix is kept
        super().__init__(mu, None, None)
        self.L = covariance.L
        self.precision = covariance.precision
        self.log_marginal_likelihood = covariance.log_likelihood(y)

    def times_root(self, A: np.ndarray) -> np.ndarray:
        # A L^{-T} = (L^{-1} A^T)^T
        return linalg.solve_triangular(self.L, A.T, lower=True, check_finite=False).T

    def covariance(self) -> np.ndarray:
        return inverse_from_cholesky(self.L)

    def mean_at_lags(self, X: np.ndarray) -> np.ndarray:
        """Posterior mean of ``g`` at the kernel inputs ``X`` (real lags, as a column)."""
        return cross_kernel(self.kernel, X, self.observation.lags) @ self.precision.times(self.coef)

    def at_lags(self, X: np.ndarray, full_cov: bool = False):
        """Posterior of ``g(X)``: the prior conditional on ``g(0..P-1)``, averaged.

        With ``J = k(X, lags) K^{-1}`` (``K^{-1}`` tridiagonal): mean ``J mu``,
        covariance ``k(X, X) - J k(lags, X) + J Sigma J^T``.
        """
        kernel = self.kernel
        cross = cross_kernel(kernel, X, self.observation.lags)
        J = self.precision.times(cross.T).T
        mean = J @ self.coef
        JS = self.times_root(J)
        if full_cov:
            cov = kernel(X) - J @ cross.T + JS @ JS.T
            return mean, 0.5 * (cov + cov.T)
        var = kernel.diag(X) - np.einsum("ij,ij->i", J, cross) + np.einsum("ij,ij->i", JS, JS)
        return mean, np.maximum(var, 0.0)


class SpreadPosterior(GaussianCoefficients):
    """A posterior with the spread of its PK terms' frequencies added after conditioning.

    ``conditioned`` is the posterior given the data under the kernel without
    the spread (:func:`~gpmultirate.kernels.spread.conditioning_kernel`);
    every covariance adds the spread's, ``V V^T`` with ``V`` the columns of
    :func:`~gpmultirate.kernels.spread.spread_factor` of ``prior_kernel``
    (at the coefficients' lags, at real lags, through readings).  The mean,
    the evidence, the innovations and what the data explain
    (:meth:`given_data`) are ``conditioned``'s.

    Parameters
    ----------
    conditioned : GaussianCoefficients
        A posterior of a route (:class:`DataSpacePosterior`,
        :class:`ParameterSpacePosterior`, ...), with ``observation`` and
        ``kernel``.
    prior_kernel : sklearn Kernel
        ``conditioned.kernel`` with the spreads
        (``PK(posterior_spread=True)`` terms).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.inference import posterior
    >>> from gpmultirate.kernels import DC, PK
    >>> from gpmultirate.kernels.spread import conditioning_kernel
    >>> rng = np.random.default_rng(0)
    >>> op = DownsampledConvolution(rng.standard_normal(300), factor=2, order=40)
    >>> g = 0.9 ** np.arange(40) * np.cos(0.7 * np.arange(40))
    >>> y = op.matvec(g) + 0.01 * rng.standard_normal(op.n_outputs)
    >>> kernel = C(0.1) * DC(0.8, 0.5) + PK(0.81, 0.7, omega_std=0.01, posterior_spread=True)
    >>> plain = posterior(op, conditioning_kernel(kernel), 1e-4, y)
    >>> spread = SpreadPosterior(plain, kernel)
    >>> bool(np.allclose(spread.coef, plain.coef))
    True
    >>> lags = np.array([[10.0], [30.5]])
    >>> bool(np.all(spread.at_lags(lags)[1] > plain.at_lags(lags)[1]))
    True
    """

    def __init__(self, conditioned, prior_kernel):
        self.conditioned = conditioned
        self.observation, self.kernel = conditioned.observation, conditioned.kernel
        self.prior_kernel = prior_kernel
        self.log_marginal_likelihood = conditioned.log_marginal_likelihood
        self.V = spread_factor(prior_kernel, self.observation.lags)
        super().__init__(conditioned.coef, None, None)

    def given_data(self, cross: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """What the data explain (:meth:`DataSpacePosterior.given_data`), without the spread."""
        return self.conditioned.given_data(cross)

    @property
    def alpha(self) -> np.ndarray:
        """``Ky^{-1} y`` of a data-space ``conditioned`` (:class:`DataSpacePosterior`)."""
        return self.conditioned.alpha

    @property
    def K(self) -> np.ndarray:
        """The prior covariance of the coefficients with the spread, ``K0 + V V^T``."""
        return self.conditioned.K + self.V @ self.V.T

    def innovations(self, y: np.ndarray) -> np.ndarray | None:
        return self.conditioned.innovations(y)

    def linear_map(self, A: np.ndarray, full_cov: bool = False):
        mean, second = self.conditioned.linear_map(A, full_cov)
        AV = A @ self.V
        if full_cov:
            return mean, second + AV @ AV.T
        return mean, second + np.einsum("ij,ij->i", AV, AV)

    def pair_variances(self, A1: np.ndarray, A2: np.ndarray | None):
        var1, var2, cov = self.conditioned.pair_variances(A1, A2)
        V1 = A1 @ self.V
        var1 = var1 + np.einsum("ij,ij->i", V1, V1)
        if A2 is None:
            return var1, None, None
        V2 = A2 @ self.V
        return (var1, var2 + np.einsum("ij,ij->i", V2, V2),
                cov + np.einsum("ij,ij->i", V1, V2))

    def covariance(self) -> np.ndarray:
        return self.conditioned.covariance() + self.V @ self.V.T

    def mean_at_lags(self, X: np.ndarray) -> np.ndarray:
        """Posterior mean of ``g`` at the kernel inputs ``X`` (real lags, as a column)."""
        return self.conditioned.mean_at_lags(X)

    def at_lags(self, X: np.ndarray, full_cov: bool = False):
        """Posterior mean and variance (or covariance) of ``g`` at the kernel inputs ``X``."""
        mean, second = self.conditioned.at_lags(X, full_cov=full_cov)
        W = spread_factor(self.prior_kernel, X)
        if full_cov:
            return mean, second + W @ W.T
        return mean, second + np.einsum("ij,ij->i", W, W)

    def readings_spread(self, readings) -> np.ndarray:
        """The spread's variance of each noise-free reading of ``readings``."""
        with_spread = observe(self.prior_kernel, readings).covariance_blocks(0)[1]
        without = observe(self.kernel, readings).covariance_blocks(0)[1]
        return np.maximum(with_spread - without, 0.0)
