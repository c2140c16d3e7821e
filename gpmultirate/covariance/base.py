"""What every route of the data covariance shares: the Gaussian log density, factors, ``Remainder``.

The helpers here are the one home of formulas the routes and the noise
models use: :func:`log_gaussian` (eq. 19 with the noise inside the
determinant), :func:`robust_cholesky`, :func:`inverse_from_cholesky`,
:func:`kernel_root` (``K = F F^T``) and :func:`cholesky_or_raise`.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy import linalg

from gpmultirate.exceptions import NotPositiveDefinite, NumericalWarning

__all__ = [
    "LOG_2PI",
    "DataCovariance",
    "Remainder",
    "cholesky_or_raise",
    "inverse_from_cholesky",
    "kernel_root",
    "log_gaussian",
    "robust_cholesky",
]

LOG_2PI = np.log(2.0 * np.pi)


def log_gaussian(quadratic: float, log_det: float, n: int) -> float:
    """``log N(y; 0, Ky)`` from ``y^T Ky^{-1} y``, ``log det Ky`` and ``n = len(y)``.

    The log marginal likelihood of eq. (19) with the noise inside the
    determinant (see the reading notes):
    ``-1/2 y^T Ky^{-1} y - 1/2 log det Ky - n/2 log(2 pi)``.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.stats import multivariate_normal
    >>> value = log_gaussian(0.5**2 / 2.0, np.log(2.0), 1)
    >>> bool(np.isclose(value, multivariate_normal(0.0, 2.0).logpdf(0.5)))
    True
    """
    return float(-0.5 * quadratic - 0.5 * log_det - 0.5 * n * LOG_2PI)


def robust_cholesky(A: np.ndarray, what: str = "data covariance") -> tuple[np.ndarray, float]:
    """Lower Cholesky factor of a symmetric matrix, adding jitter if needed.

    Returns the factor and the jitter that was added to the diagonal.  A
    :class:`~gpmultirate.exceptions.NumericalWarning` is emitted when jitter
    was needed; a :class:`ValueError` when even large jitter fails.

    Examples
    --------
    >>> import numpy as np
    >>> L, jitter = robust_cholesky(np.array([[4.0, 2.0], [2.0, 2.0]]))
    >>> L.tolist(), jitter
    ([[2.0, 0.0], [1.0, 1.0]], 0.0)
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


def inverse_from_cholesky(L: np.ndarray) -> np.ndarray:
    """The symmetric inverse ``(L L^T)^{-1}`` from a lower Cholesky factor (LAPACK potri).

    Examples
    --------
    >>> import numpy as np
    >>> A = np.array([[4.0, 2.0], [2.0, 2.0]])
    >>> bool(np.allclose(inverse_from_cholesky(np.linalg.cholesky(A)), np.linalg.inv(A)))
    True
    """
    inverse, info = linalg.lapack.dpotri(L, lower=1)
    if info != 0:
        return linalg.cho_solve((L, True), np.eye(L.shape[0]), check_finite=False)
    # potri fills the lower triangle; the upper one is that of L, zero
    diagonal = np.diag(inverse).copy()
    inverse += inverse.T
    inverse[np.diag_indices_from(inverse)] = diagonal
    return inverse


def cholesky_or_raise(C: np.ndarray, lower: bool = True, overwrite: bool = False) -> np.ndarray:
    """The Cholesky factor of ``C``, or :class:`~gpmultirate.exceptions.NotPositiveDefinite`.

    For the small matrices of the structured routes (a posterior precision,
    a capacitance): the caller then takes another route instead of jitter.

    Examples
    --------
    >>> import numpy as np
    >>> cholesky_or_raise(np.array([[4.0]])).tolist()
    [[2.0]]
    """
    try:
        return linalg.cholesky(C, lower=lower, overwrite_a=overwrite, check_finite=False)
    except linalg.LinAlgError as error:
        raise NotPositiveDefinite(str(error)) from None


def kernel_root(K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``K = F F^T`` on the kept eigenvalues, and ``F^{+T}``: ``(F, inv_root)``.

    Directions of numerically zero prior variance (eigenvalues below
    ``1e-14`` of the largest) are dropped, so ``F`` may have fewer columns
    than ``K``.

    Examples
    --------
    >>> import numpy as np
    >>> K = np.array([[2.0, 1.0], [1.0, 2.0]])
    >>> F, inv_root = kernel_root(K)
    >>> bool(np.allclose(F @ F.T, K)), bool(np.allclose(inv_root.T @ F, np.eye(2)))
    (True, True)
    """
    values, vectors = linalg.eigh(0.5 * (K + K.T), check_finite=False)
    keep = values > max(values.max(), 0.0) * 1e-14
    if not np.any(keep):
        raise ValueError("the kernel matrix is zero at lags 0..order-1")
    return vectors[:, keep] * np.sqrt(values[keep]), vectors[:, keep] / np.sqrt(values[keep])


class Remainder:
    """The likelihood of the samples a long-record reduction summarized.

    Under white noise the ``n`` components that a reduction
    (:class:`~gpmultirate.observations.ReducedObservation`) leaves out are
    independent ``N(0, gamma)`` with the sum of squares ``rho^2``; they add
    ``-n/2 log(2 pi gamma) - rho^2 / (2 gamma)`` to the log evidence.

    Parameters
    ----------
    n : int
        The number of discarded components (zero: no remainder).
    sum_of_squares : float
        ``rho^2``.
    noise_level : float
        ``gamma``.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.stats import norm
    >>> value, grad, fisher = Remainder(2, 0.6**2 + 0.8**2, 0.3).log_likelihood()
    >>> bool(np.isclose(value, norm(0.0, np.sqrt(0.3)).logpdf([0.6, 0.8]).sum()))
    True
    """

    def __init__(self, n: int, sum_of_squares: float, noise_level: float):
        self.n = int(n)
        self.sum_of_squares = float(sum_of_squares)
        self.noise_level = float(noise_level)

    def log_likelihood(self) -> tuple[float, float, float]:
        """Value, derivative and Fisher information in ``log(gamma)``; all zero without samples."""
        n = self.n
        if n == 0:
            return 0.0, 0.0, 0.0
        noise_level = self.noise_level
        value = log_gaussian(self.sum_of_squares / noise_level, n * np.log(noise_level), n)
        grad = -0.5 * n + 0.5 * self.sum_of_squares / noise_level
        return float(value), float(grad), 0.5 * n


class DataCovariance:
    """``Ky = S + N`` of one observation, factored; subclasses are the routes.

    Every route answers :meth:`inv_quad_logdet`, :meth:`solve` and
    :meth:`posterior`; the log density and the remainder of a reduced record
    are added here, once.  The noise model builds the route its structure
    offers (``noise.data_covariance(term)``, :mod:`gpmultirate.noise`).

    Attributes
    ----------
    term : ObservedTerm
        The kernel seen through the observation.
    noise : noise model
        :mod:`gpmultirate.noise` (``N``, its ``theta``).
    remainder : Remainder
    size : int
        The number of (reduced) data.
    """

    def __init__(self, term, noise, remainder: Remainder):
        self.term = term
        self.noise = noise
        self.remainder = remainder
        self.size = term.observation.n_outputs

    @property
    def observation(self):
        """The observation ``S`` is seen through."""
        return self.term.observation

    @property
    def kernel(self):
        """The kernel of ``S``."""
        return self.term.kernel

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``Ky^{-1} b`` for ``b`` of shape ``(M,)`` or ``(M, k)``."""
        raise NotImplementedError

    def inv_quad_logdet(self, y: np.ndarray) -> tuple[float, float]:
        """``y^T Ky^{-1} y`` and ``log det Ky`` together."""
        raise NotImplementedError

    def log_likelihood(self, y: np.ndarray) -> float:
        """``log N(y; 0, Ky)`` plus the remainder of a reduced record: the log evidence."""
        quadratic, log_det = self.inv_quad_logdet(y)
        return log_gaussian(quadratic, log_det, self.size) + self.remainder.log_likelihood()[0]

    def log_likelihood_gradient(self, y: np.ndarray) -> tuple[float, np.ndarray]:
        """The log evidence and its gradient in ``theta`` (the kernel's, then the noise's)."""
        raise NotImplementedError

    def posterior(self, y: np.ndarray):
        """The posterior of the coefficients given ``y`` (eq. 15), from this route's factor."""
        raise NotImplementedError
