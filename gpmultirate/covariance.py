"""The data covariance ``Ky = S + N`` as an object: its factorization and what it answers.

``S = Phi K Phi^T`` is the kernel seen through the observation
(:func:`gpmultirate.kernels.observe`) and ``N`` the noise model
(:class:`WhiteNoise`, ``gamma I``).  :func:`data_covariance` returns one
:class:`DataCovariance` that owns the factorization of ``S + N`` and answers,
from that one factor,

* :meth:`~DataCovariance.solve` (``Ky^{-1} b``) and
  :meth:`~DataCovariance.inv_quad_logdet` (``y^T Ky^{-1} y`` and
  ``log det Ky`` together);
* :meth:`~DataCovariance.log_likelihood`, the Gaussian log density of
  eq. (19) (with the noise inside the determinant) plus the :class:`Remainder`
  of a reduced long record;
* :meth:`~DataCovariance.log_likelihood_gradient`, the gradient in ``theta``
  (the kernel's, then the noise model's) by the trace identity, through the
  kernel term's gradient contraction, and, for the dense route,
  :meth:`~DenseCovariance.log_likelihood_fisher`.

The routes are subclasses, chosen in :func:`data_covariance` by the structure
that builds them:

* :class:`DenseCovariance`: the Cholesky factor of ``S + N`` in the data space;
* :class:`WoodburyCovariance`: a dense covariance plus a low-rank summand
  ``U D U^T`` (a PK resonance at one candidate of a grid), by the Woodbury
  identity and the matrix determinant lemma;
* :class:`PrecisionCovariance`: square or reduced data (``M = P``) and a
  kernel term that offers a tridiagonal precision ``Q = K^{-1}`` (DC): the
  posterior precision ``C = Q + Phi^T Phi / gamma`` is factored instead;
* :class:`ParameterSpaceCovariance`: a reduced long record seen from the
  parameter space, ``K = F F^T``, through a QR factor of
  ``[Phi F / sqrt(gamma); I]`` (the accuracy of least squares).

Beside them, :class:`SpectralCovariance` is ``c S + gamma I (+ W W^T)`` for
every scale ``c`` and noise level ``gamma`` at once, from one
eigendecomposition of ``S``: what the scale prefit of tuning and the
resonance search of ``kernel="auto"`` scan.

The Gaussian log density is written once, in :func:`log_gaussian`.
"""

from __future__ import annotations

import warnings
import weakref

import numpy as np
from scipy import linalg

from gpmultirate.exceptions import NotPositiveDefinite, NumericalWarning
from gpmultirate.kernels import observe

__all__ = [
    "AR1Covariance",
    "DataCovariance",
    "DenseCovariance",
    "ParameterSpaceCovariance",
    "PrecisionCovariance",
    "Remainder",
    "SpectralCovariance",
    "WhiteNoise",
    "WoodburyCovariance",
    "data_covariance",
    "inverse_from_cholesky",
    "log_gaussian",
    "robust_cholesky",
    "takes_precision_route",
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


# ------------------------------------------------------------------ noise
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
        value = (-0.5 * n * (np.log(2.0 * np.pi * noise_level))
                 - 0.5 * self.sum_of_squares / noise_level)
        grad = -0.5 * n + 0.5 * self.sum_of_squares / noise_level
        return float(value), float(grad), 0.5 * n


class WhiteNoise:
    """White measurement noise ``N = gamma I`` over the slow samples.

    The noise side of the data covariance.  Its hyperparameters enter
    ``theta`` through it: :attr:`theta` is ``[log(gamma)]`` when the level is
    tuned (``bounds`` not ``"fixed"``) and empty otherwise, after the
    kernel's entries.  White noise is what the long-record reduction and the
    precision route rely on (:attr:`white`); a noise model with structure
    of its own (coloured noise over the sample instants) would answer the
    same questions and set ``white = False``.

    Parameters
    ----------
    noise_level : float
        ``gamma > 0``.
    bounds : pair of floats or "fixed", default="fixed"

    Examples
    --------
    >>> import numpy as np
    >>> noise = WhiteNoise(0.1, (1e-3, 1.0))
    >>> noise.theta, noise.with_theta(np.log([0.2])).level
    (array([-2.30258509]), 0.2)
    >>> noise.add_to(np.zeros((2, 2)))
    array([[0.1, 0. ],
           [0. , 0.1]])
    """

    #: whether ``N`` is a multiple of the identity
    white = True

    def __init__(self, noise_level: float, bounds="fixed"):
        self.level = float(noise_level)
        self.noise_bounds = bounds
        self.is_free = not isinstance(bounds, str)

    @property
    def theta(self) -> np.ndarray:
        """``[log(gamma)]`` when tuned, else empty."""
        return np.array([np.log(self.level)]) if self.is_free else np.empty(0)

    @property
    def bounds(self) -> np.ndarray:
        """Bounds of :attr:`theta`, of shape ``(len(theta), 2)``."""
        if not self.is_free:
            return np.empty((0, 2))
        return np.log(np.asarray(self.noise_bounds, dtype=float)).reshape(1, 2)

    def with_theta(self, theta) -> "WhiteNoise":
        """The same noise model at ``theta`` (its own entries of the whole ``theta``)."""
        if not self.is_free:
            return self
        return WhiteNoise(float(np.exp(theta[0])), self.noise_bounds)

    def add_to(self, S: np.ndarray) -> np.ndarray:
        """``S + N`` in place (``S`` square, of the size of the data); returns ``S``."""
        S[np.diag_indices_from(S)] += self.level
        return S

    def contract(self, W: np.ndarray, weight: float = 1.0) -> np.ndarray:
        """``[weight tr(W dN / d theta_j)]_j`` for symmetric ``W``: ``weight tr(W) gamma``."""
        if not self.is_free:
            return np.empty(0)
        return np.array([weight * np.trace(W) * self.level])

    def remainder(self, observation) -> Remainder:
        """The likelihood of what a reduction of ``observation`` summarized (none otherwise)."""
        return Remainder(observation.n_discarded, observation.residual, self.level)


# ------------------------------------------------------------ the routes
class DataCovariance:
    """``Ky = S + N`` of one observation, factored; subclasses are the routes.

    Every route answers :meth:`inv_quad_logdet` and :meth:`solve`; the log
    density and the remainder of a reduced record are added here, once.

    Attributes
    ----------
    term : ObservedTerm
        The kernel seen through the observation.
    noise : WhiteNoise
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


class DenseCovariance(DataCovariance):
    """``S + N`` by its Cholesky factor ``L`` in the data space.

    Parameters
    ----------
    term : ObservedTerm
    noise : WhiteNoise
    remainder : Remainder
    S : ndarray of shape (M, M), optional
        ``S`` when already formed (it is not modified); by default the term's.
    contract : callable, optional
        ``W -> [tr(W dS_j)]_j``, the term's gradient contraction, for
        :meth:`log_likelihood_gradient`.
    derivatives : list, optional
        The term's ``dS_j`` (dense, or factors ``(U, D)``), for
        :meth:`log_likelihood_fisher`.

    Attributes
    ----------
    L : ndarray of shape (M, M)
    jitter : float
        What :func:`robust_cholesky` had to add to the diagonal.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import RBF
    >>> from gpmultirate import DownsampledConvolution
    >>> op = DownsampledConvolution(np.arange(1.0, 13.0), factor=3, order=6)
    >>> Ky = data_covariance(RBF(2.0), op, WhiteNoise(0.1))
    >>> type(Ky).__name__
    'DenseCovariance'
    >>> dense = op.matrix @ RBF(2.0)(op.lags) @ op.matrix.T + 0.1 * np.eye(op.n_outputs)
    >>> y = np.ones(op.n_outputs)
    >>> bool(np.allclose(Ky.solve(y), np.linalg.solve(dense, y)))
    True
    """

    def __init__(self, term, noise, remainder, S=None, contract=None, derivatives=None,
                 copy: bool = True):
        super().__init__(term, noise, remainder)
        if S is None:
            S = term.covariance()
        self.contract = contract
        self.derivatives = derivatives
        # S may be held by the contractor (the derivative of an amplitude): copied
        Ky = S.copy() if copy else S
        self.L, self.jitter = robust_cholesky(noise.add_to(Ky))
        self._whitened = None

    @classmethod
    def of(cls, kernel, observation, noise, derivatives: str | None = None) -> "DenseCovariance":
        """The dense route whatever the structure offers (cross-validation needs ``Ky^{-1}``).

        ``derivatives`` as in :func:`data_covariance`.
        """
        return cls._of_term(observe(kernel, observation), noise, noise.remainder(observation),
                            derivatives)

    @classmethod
    def _of_term(cls, term, noise, remainder, derivatives):
        if derivatives == "contraction":
            S, contract = term.covariance_with_contractor()
            return cls(term, noise, remainder, S, contract=contract)
        if derivatives == "matrices":
            S, items = term.covariance_with_derivatives()
            return cls(term, noise, remainder, S, derivatives=items)
        return cls(term, noise, remainder)

    def log_det(self) -> float:
        """``log det Ky``."""
        return 2.0 * np.log(np.diag(self.L)).sum()

    def solve(self, b):
        return linalg.cho_solve((self.L, True), b, check_finite=False)

    def whiten(self, b: np.ndarray) -> np.ndarray:
        """``L^{-1} b``."""
        return linalg.solve_triangular(self.L, b, lower=True, check_finite=False)

    def inverse(self) -> np.ndarray:
        """``Ky^{-1}`` (symmetric, a new array)."""
        return inverse_from_cholesky(self.L)

    def inv_quad_logdet(self, y):
        return float(y @ self.solve(y)), self.log_det()

    def whitened(self, y: np.ndarray) -> np.ndarray:
        """``L^{-1} y``, kept for the last ``y`` (the low-rank updates share it)."""
        if self._whitened is None or self._whitened[0] is not y:
            self._whitened = (y, self.whiten(y))
        return self._whitened[1]

    def log_likelihood_gradient(self, y):
        """The log evidence and its gradient: ``1/2 tr((a a^T - Ky^{-1}) dKy_j)``, ``a = Ky^{-1} y``."""
        L = self.L
        alpha = linalg.cho_solve((L, True), y, check_finite=False)
        rest_value, rest_grad, _ = self.remainder.log_likelihood()
        value = log_gaussian(y @ alpha, 2.0 * np.log(np.diag(L)).sum(), y.shape[0]) + rest_value
        W = inverse_from_cholesky(L)
        W *= -1.0
        W = linalg.blas.dger(1.0, alpha, alpha, a=W, overwrite_a=True)  # + alpha alpha^T
        grad = 0.5 * self.contract(W)
        if self.noise.is_free:
            noise_grad = self.noise.contract(W, 0.5)
            noise_grad[-1] += rest_grad
            grad = np.append(grad, noise_grad)
        return value, grad

    def log_likelihood_fisher(self, y):
        """The log evidence, its gradient and its Fisher information in ``theta``.

        With ``a = Ky^{-1} y`` and ``V_j = Ky^{-1} dKy_j``: gradient
        ``g_j = 1/2 (a^T dKy_j a - tr V_j)`` and Fisher information
        ``F_jk = 1/2 tr(V_j V_k)``.  Low-rank derivatives ``U D U^T`` stay
        factored (``B = Ky^{-1} U``), so their traces cost ``O(M^2 r)``.
        """
        L = self.L
        M = y.shape[0]
        inverse = inverse_from_cholesky(L)
        a = inverse @ y
        value = log_gaussian(y @ a, 2.0 * np.log(np.diag(L)).sum(), M)
        noise_level = self.noise.level
        terms = []  # ("dense", dS, V, V^T) or ("factor", U, B, D)
        solved = {}  # factors shared by the items of one PK term are solved once
        for item in self.derivatives:
            if isinstance(item, tuple):
                U, D = item
                if id(U) not in solved:
                    solved[id(U)] = inverse @ U
                terms.append(("factor", U, solved[id(U)], D))
            else:
                product = inverse @ item
                # tr(V_j V_k) = sum(V_j * V_k^T): keep the transpose contiguous
                terms.append(("dense", item, product, np.ascontiguousarray(product.T)))
        if self.noise.is_free:  # dN = gamma I
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
        rest_value, rest_grad, rest_fisher = self.remainder.log_likelihood()
        value += rest_value
        if self.noise.is_free:
            grad[-1] += rest_grad
            fisher[-1, -1] += rest_fisher
        return value, grad, fisher

    def plus_low_rank(self, U: np.ndarray, weights) -> list:
        """``Ky + U_k D_k U_k^T`` for each weight ``D_k``: one :class:`WoodburyCovariance` each.

        ``U`` holds the factors ``U_k`` side by side (their ranks are those
        of the weights); it is whitened by ``L`` once for all of them.
        """
        A = self.whiten(U)
        updates = []
        start = 0
        for weight in weights:
            rank = weight.shape[0]
            # B = L^{-1} U_k D^{1/2}, for the positive semidefinite weight D
            d, Q = np.linalg.eigh(weight)
            B = A[:, start : start + rank] @ (Q * np.sqrt(np.maximum(d, 0.0)))
            start += rank
            updates.append(WoodburyCovariance(self, B))
        return updates


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


class WoodburyCovariance(DataCovariance):
    """A dense covariance plus a low-rank summand: ``L L^T + L B B^T L^T``.

    By the Woodbury identity and the determinant lemma, with
    ``C = I + B^T B = G G^T`` and ``w = L^{-1} y``:
    ``y^T Ky^{-1} y = w^T w - |G^{-1} B^T w|^2`` and
    ``log det Ky = log det(L L^T) + log det C``: ``O(M^2)`` on top of the
    base's factor.  Built by :meth:`DenseCovariance.plus_low_rank`.

    Parameters
    ----------
    base : DenseCovariance
    B : ndarray of shape (M, r)
        ``L^{-1} U D^{1/2}``.
    """

    def __init__(self, base: DenseCovariance, B: np.ndarray):
        super().__init__(base.term, base.noise, base.remainder)
        self.base = base
        self.B = B
        self.G = np.linalg.cholesky(np.eye(B.shape[1]) + B.T @ B)

    def solve(self, b):
        base = self.base
        x = base.whiten(b)
        x = x - self.B @ linalg.cho_solve((self.G, True), self.B.T @ x, check_finite=False)
        return linalg.solve_triangular(base.L, x, lower=True, trans="T", check_finite=False)

    def inv_quad_logdet(self, y):
        w = self.base.whitened(y)
        v = np.linalg.solve(self.G, self.B.T @ w)
        half_log_det = np.log(np.diag(self.base.L)).sum()
        return w @ w - v @ v, 2.0 * (half_log_det + np.log(np.diag(self.G)).sum())


class PrecisionCovariance(DataCovariance):
    """``S + gamma I`` of square or reduced data (``M = P``) through a tridiagonal ``K^{-1}``.

    With ``Q = K^{-1}`` (the term's
    :meth:`~gpmultirate.kernels.ObservedTerm.precision`), ``A = Phi^T Phi``
    and the posterior precision ``C = Q + A / gamma = L L^T``:
    ``mu = C^{-1} Phi^T y / gamma`` (eq. 15 by the matrix inversion lemma),

    * ``y^T Ky^{-1} y = |y - Phi mu|^2 / gamma + mu^T Q mu``;
    * ``log det Ky = M log gamma + log det K + log det C``.

    Raises :class:`NotPositiveDefinite` when ``C`` cannot be factored
    (:func:`data_covariance` then takes the dense route).

    Parameters
    ----------
    term : ObservedTerm
    noise : WhiteNoise
    remainder : Remainder
    precision : TridiagonalPrecision

    Attributes
    ----------
    L : ndarray of shape (P, P)
        Lower Cholesky factor of ``C``.
    """

    def __init__(self, term, noise, remainder, precision):
        super().__init__(term, noise, remainder)
        self.precision = precision
        A, _ = self.observation.gram()  # kept by the observation: the same in every evaluation
        C = A / noise.level
        P = C.shape[0]
        C.flat[:: P + 1] += precision.diagonal
        C.flat[1 :: P + 1] += precision.off_diagonal
        C.flat[P :: P + 1] += precision.off_diagonal
        self.L = _cholesky_of_posterior_precision(C)
        self._solved = None

    def posterior_mean(self, y: np.ndarray):
        """``mu`` and ``|y - Phi mu|^2`` (kept for the last ``y``)."""
        if self._solved is None or self._solved[0] is not y:
            observation, noise_level = self.observation, self.noise.level
            b = observation.rmatvec(y)
            mu = linalg.cho_solve((self.L, True), b / noise_level, check_finite=False)
            residual = y - observation.matvec(mu)
            self._solved = (y, mu, float(residual @ residual))
        return self._solved[1], self._solved[2]

    def solve(self, b):
        # Ky^{-1} b = (b - Phi C^{-1} Phi^T b / gamma) / gamma
        Phi, noise_level = self.observation.matrix, self.noise.level
        inner = linalg.cho_solve((self.L, True), Phi.T @ b, check_finite=False)
        return (b - Phi @ inner / noise_level) / noise_level

    def inv_quad_logdet(self, y):
        mu, squares = self.posterior_mean(y)
        precision, noise_level = self.precision, self.noise.level
        quadratic = squares / noise_level + float(mu @ precision.times(mu))
        log_det = (self.size * np.log(noise_level) + precision.log_det_covariance
                   + 2.0 * np.log(np.diag(self.L)).sum())
        return quadratic, log_det

    def log_likelihood_gradient(self, y):
        """The log evidence and its gradient through the band of ``Sigma = C^{-1}``.

        * ``d/d theta_j = -1/2 (mu^T dQ_j mu + tr(Sigma dQ_j) + d log det K / d theta_j)``;
        * ``d/d log gamma = 1/2 |y - Phi mu|^2 / gamma - 1/2 tr(Sigma Q)``.

        ``dQ_j`` and ``Q`` are tridiagonal, so only the tridiagonal band of
        ``Sigma`` is needed: a triangular inverse, about a quarter of the flops
        of the dense route.
        """
        L, precision, noise_level = self.L, self.precision, self.noise.level
        value = self.log_likelihood(y)
        mu, squares = self.posterior_mean(y)
        _, rest_grad, _ = self.remainder.log_likelihood()
        inverse, info = linalg.lapack.dtrtri(L, lower=1)
        if info != 0:
            inverse = linalg.solve_triangular(L, np.eye(L.shape[0]), lower=True,
                                              check_finite=False)
        # the band of Sigma = L^{-T} L^{-1}, and of Sigma + mu mu^T
        sigma_diagonal = np.einsum("ki,ki->i", inverse, inverse)
        sigma_off = np.einsum("ki,ki->i", inverse[:, :-1], inverse[:, 1:])
        band_diagonal = sigma_diagonal + mu * mu
        band_off = sigma_off + mu[:-1] * mu[1:]
        grad = np.array([
            -0.5 * (d @ band_diagonal + 2.0 * (o @ band_off) + log_det_j)
            for (d, o), log_det_j in zip(precision.derivatives, precision.log_det_gradient)
        ])
        if self.noise.is_free:
            trace = precision.diagonal @ sigma_diagonal + 2.0 * (precision.off_diagonal @ sigma_off)
            grad = np.append(grad, 0.5 * squares / noise_level - 0.5 * trace + rest_grad)
        return value, grad


def _cholesky_of_posterior_precision(C: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor of ``C`` (overwritten), or :class:`NotPositiveDefinite`."""
    try:
        return linalg.cholesky(C, lower=True, overwrite_a=True, check_finite=False)
    except linalg.LinAlgError as error:
        raise NotPositiveDefinite(str(error)) from None


def _kernel_root(K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``K = F F^T`` on the kept eigenvalues, and ``F^{+T}``: ``(F, inv_root)``."""
    values, vectors = linalg.eigh(0.5 * (K + K.T), check_finite=False)
    keep = values > max(values.max(), 0.0) * 1e-14
    if not np.any(keep):
        raise ValueError("the kernel matrix is zero at lags 0..order-1")
    return vectors[:, keep] * np.sqrt(values[keep]), vectors[:, keep] / np.sqrt(values[keep])


class ParameterSpaceCovariance(DataCovariance):
    """``S + gamma I`` of reduced data seen from the parameter space, for ``M > P``.

    With ``K = F F^T`` (eigen-decomposition, dropping directions of
    numerically zero prior variance) the stacked matrix
    ``[Phi F / sqrt(gamma); I] = Q R`` gives
    ``y^T Ky^{-1} y = min_z |y - Phi F z|^2 / gamma + |z|^2`` and
    ``log det Ky = M log gamma + log det(R^T R)``: the accuracy of least
    squares, not that of ``Phi K Phi^T + gamma I``, whose condition number
    grows as ``1/gamma`` when ``M > P``.

    Attributes
    ----------
    K : ndarray of shape (P, P)
    F, inv_root : ndarray of shape (P, r)
        ``K = F F^T`` and ``F^{+T}``.
    Q, R : ndarray
        The economic QR factors of the stacked matrix.
    """

    def __init__(self, term, noise, remainder):
        super().__init__(term, noise, remainder)
        observation = self.observation
        Phi = observation.matrix
        K = observation.kernel_matrix(self.kernel)
        self.K = K
        self.F, self.inv_root = _kernel_root(K)
        root_noise = np.sqrt(noise.level)
        rank = self.F.shape[1]
        stacked = np.vstack([Phi @ self.F / root_noise, np.eye(rank)])
        self.Q, self.R = linalg.qr(stacked, mode="economic", check_finite=False)
        self._solved = None

    def whitened_coefficients(self, y: np.ndarray) -> np.ndarray:
        """The posterior mean of ``z`` (``g = F z``), kept for the last ``y``."""
        if self._solved is None or self._solved[0] is not y:
            root_noise = np.sqrt(self.noise.level)
            z = linalg.solve_triangular(self.R, self.Q[: y.shape[0]].T @ (y / root_noise),
                                        check_finite=False)
            self._solved = (y, z)
        return self._solved[1]

    def solve(self, b):
        # Ky^{-1} b = (b - Phi F (R^T R)^{-1} F^T Phi^T b / gamma) / gamma
        Phi, noise_level = self.observation.matrix, self.noise.level
        PhiF = Phi @ self.F
        inner = linalg.solve_triangular(self.R, PhiF.T @ b, trans="T", check_finite=False)
        inner = linalg.solve_triangular(self.R, inner, check_finite=False)
        return (b - PhiF @ inner / noise_level) / noise_level

    def inv_quad_logdet(self, y):
        noise_level = self.noise.level
        z = self.whitened_coefficients(y)
        residual = y - self.observation.matrix @ (self.F @ z)
        quad = residual @ residual / noise_level + z @ z
        log_det = y.shape[0] * np.log(noise_level) + 2.0 * np.log(np.abs(np.diag(self.R))).sum()
        return quad, log_det


#: the ``O(M P^2)`` products of the regressor that :class:`AR1Covariance` reuses:
#: ``(weak references to the observation and its regressor, the records' sizes, products)``
_AR1_GRAMS: list = []


def _ar1_gram(observation, Phi, ar1):
    """The :class:`~gpmultirate.noise.AR1Statistics` Gram of ``Phi``, formed once per observation."""
    counts = tuple(ar1.counts)
    for ref, matrix, sizes, gram in _AR1_GRAMS:
        if ref() is observation and matrix() is Phi and sizes == counts:
            return gram
    gram = ar1.statistics(Phi, np.zeros(Phi.shape[0])).gram
    _AR1_GRAMS.insert(0, (weakref.ref(observation), weakref.ref(Phi), counts, gram))
    del _AR1_GRAMS[4:]
    return gram


class AR1Covariance(DataCovariance):
    """``S + N`` for AR(1) noise ``N`` (a Matérn 1/2 disturbance on one uniform grid), ``M > P``.

    The noise's precision ``Q = T(a) / q`` is tridiagonal, so prewhitening
    the data and the regressor is exact: the problem is a white-noise one in
    the parameter space.  With ``G = Phi^T Q Phi``, ``b = Phi^T Q y``,
    ``c = y^T Q y`` (combinations of products formed once in ``O(M P^2)``,
    :class:`~gpmultirate.noise.AR1Statistics`), ``K = F F^T`` and
    ``C = I + F^T G F = R^T R``:

    * ``y^T Ky^{-1} y = c - |R^{-T} F^T b|^2``;
    * ``log det Ky = log det N + log det C``;

    each evaluation costs ``O(P^3)``, none ``O(M^3)``.  The posterior of
    ``g = F z`` has mean ``F C^{-1} F^T b`` and covariance ``F C^{-1} F^T``:
    the attributes of :class:`ParameterSpaceCovariance` (``F``,
    ``inv_root``, ``R``, :meth:`whitened_coefficients`), so
    :class:`~gpmultirate.inference.ParameterSpacePosterior` answers it.

    Parameters
    ----------
    term : ObservedTerm
    noise : KernelNoise
        The noise model whose ``structure()`` is ``ar1``.
    remainder : Remainder
    ar1 : AR1Noise

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C, Matern
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import TC
    >>> from gpmultirate.noise import KernelNoise, dense_log_evidence, noise_instants
    >>> rng = np.random.default_rng(0)
    >>> op = DownsampledConvolution(rng.standard_normal(120), factor=3, order=10)
    >>> y = rng.standard_normal(op.n_outputs)
    >>> noise = KernelNoise(C(0.5) * Matern(6.0, nu=0.5), noise_instants(op))
    >>> covariance = data_covariance(TC(0.7), op, noise)
    >>> type(covariance).__name__
    'AR1Covariance'
    >>> reference = dense_log_evidence(op.matrix, TC(0.7)(op.lags), y, noise.matrix())
    >>> bool(np.isclose(covariance.log_likelihood(y), reference, rtol=1e-10))
    True
    """

    def __init__(self, term, noise, remainder, ar1):
        super().__init__(term, noise, remainder)
        self.ar1 = ar1
        observation = self.observation
        Phi = observation.matrix
        self.Phi = Phi
        K = term.kernel_matrix()
        self.K = K
        self.F, self.inv_root = _kernel_root(K)
        self.gram = _ar1_gram(observation, Phi, ar1)
        a, q = ar1.pole, ar1.innovation_variance
        plain, interior, off = self.gram
        self.G = (plain + a * a * interior - a * off) / q
        C = self.F.T @ self.G @ self.F
        C[np.diag_indices_from(C)] += 1.0
        try:
            self.R = linalg.cholesky(C, lower=False, check_finite=False)
        except linalg.LinAlgError as error:
            raise NotPositiveDefinite(str(error)) from None
        self._solved = None

    def _of(self, y: np.ndarray):
        """``(statistics, b, c, v, z)`` for ``y``, kept for the last ``y``."""
        if self._solved is None or self._solved[0] is not y:
            statistics = self.ar1.statistics(self.Phi, y, self.gram)
            _, bt, ct = statistics.quadratic_forms(self.ar1.pole)
            q = self.ar1.innovation_variance
            b, c = bt / q, ct / q
            v = linalg.solve_triangular(self.R, self.F.T @ b, trans="T", check_finite=False)
            z = linalg.solve_triangular(self.R, v, check_finite=False)
            self._solved = (y, (statistics, b, c, v, z))
        return self._solved[1]

    def whitened_coefficients(self, y: np.ndarray) -> np.ndarray:
        """The posterior mean of ``z`` (``g = F z``)."""
        return self._of(y)[4]

    def _apply_precision(self, b: np.ndarray) -> np.ndarray:
        d, o = self.ar1.precision()
        out = d.reshape((-1,) + (1,) * (b.ndim - 1)) * b
        o = o.reshape((-1,) + (1,) * (b.ndim - 1))
        out[:-1] += o * b[1:]
        out[1:] += o * b[:-1]
        return out

    def solve(self, b):
        # Ky^{-1} b = Q b - Q Phi F C^{-1} F^T Phi^T Q b
        Qb = self._apply_precision(np.asarray(b, dtype=float))
        PhiF = self.Phi @ self.F
        inner = linalg.solve_triangular(self.R, PhiF.T @ Qb, trans="T", check_finite=False)
        inner = linalg.solve_triangular(self.R, inner, check_finite=False)
        return Qb - self._apply_precision(PhiF @ inner)

    def inv_quad_logdet(self, y):
        _, _, c, v, _ = self._of(y)
        log_det = self.ar1.log_det() + 2.0 * np.log(np.diag(self.R)).sum()
        return float(c - v @ v), float(log_det)

    def log_likelihood_gradient(self, y):
        """The log evidence and its gradient (the kernel's, then the noise's), in ``O(P^3)``.

        With ``mu``, ``Sigma`` the posterior: the kernel's entries are
        ``1/2 (beta^T dK_j beta - tr(H dK_j))``, ``beta = b - G mu``,
        ``H = G - G Sigma G``; the noise's
        :meth:`~gpmultirate.noise.AR1Noise.evidence_gradient`.
        """
        value = self.log_likelihood(y)
        statistics, b, _, _, z = self._of(y)
        mu = self.F @ z
        root = linalg.solve_triangular(self.R, self.F.T, trans="T", check_finite=False)
        Sigma = root.T @ root
        beta = b - self.G @ mu
        GS = self.G @ Sigma
        H = self.G - GS @ self.G
        _, contract = self.term.parameter_contractor()
        grad = 0.5 * np.asarray(contract(np.outer(beta, beta) - H), dtype=float)
        if self.noise.is_free:
            grad = np.append(grad, self.ar1.evidence_gradient(statistics, mu, Sigma))
        return value, grad


class SpectralCovariance:
    """``c S + gamma I``, and a low-rank update of it, for any ``c`` and ``gamma``.

    With ``S = Q diag(s) Q^T`` decomposed once (the eigenvalues clipped at
    zero), ``c S + gamma I = Q diag(c s + gamma) Q^T``: the quadratic form
    and the log-determinant cost ``O(M)`` for each scale ``c`` and noise
    level ``gamma``, with ``y`` rotated once (``Q^T y``).  A low-rank summand
    ``W W^T`` given in the rotated coordinates is added through the
    capacitance ``I + W^T diag(c s + gamma)^{-1} W`` (Woodbury and the
    matrix determinant lemma).

    Parameters
    ----------
    S : ndarray of shape (M, M)
        The kernel's data covariance without noise (symmetric, PSD).
    y : ndarray of shape (M,)
        The data.

    Examples
    --------
    >>> import numpy as np
    >>> A = np.array([[2.0, 1.0], [1.0, 2.0]])
    >>> spectral = SpectralCovariance(A, np.array([1.0, 0.0]))
    >>> d = spectral.diagonal(0.5, 0.1)
    >>> quad = float(np.sum(spectral.rotated_y**2 / d))
    >>> bool(np.isclose(quad, np.linalg.solve(0.5 * A + 0.1 * np.eye(2), [1.0, 0.0])[0]))
    True
    """

    def __init__(self, S: np.ndarray, y: np.ndarray):
        s, Q = linalg.eigh(S, check_finite=False)
        self.eigenvalues = np.maximum(s, 0.0)
        self.vectors = Q
        self.rotated_y = Q.T @ y

    def diagonal(self, scale: float, noise_level: float) -> np.ndarray:
        """The eigenvalues of ``scale * S + noise_level * I``."""
        return scale * self.eigenvalues + noise_level

    def rotate(self, A: np.ndarray) -> np.ndarray:
        """``Q^T A``: a matrix of the data space in the eigenvectors' coordinates."""
        return self.vectors.T @ A

    @staticmethod
    def capacitance_cholesky(W: np.ndarray, scaled_W: np.ndarray) -> np.ndarray:
        """The lower Cholesky factor of ``I + W^T D^{-1} W``, given ``scaled_W = D^{-1} W``."""
        return np.linalg.cholesky(np.eye(W.shape[1]) + W.T @ scaled_W)


def data_covariance(kernel, observation, noise, derivatives: str | None = None,
                    space: str = "data") -> DataCovariance:
    """``S + N`` of ``observation`` under ``kernel`` and ``noise``, by the route its structure offers.

    Parameters
    ----------
    kernel : sklearn Kernel
    observation : Observation
        Possibly a reduction (:func:`~gpmultirate.observations.reduce_observation`).
    noise : WhiteNoise
    derivatives : {None, "contraction", "matrices"}
        What the gradient needs: the term's contraction
        (:meth:`DataCovariance.log_likelihood_gradient`) or its derivative
        matrices (:meth:`DenseCovariance.log_likelihood_fisher`, dense).
    space : {"data", "posterior"}
        ``"data"``: square or reduced data (``M = P``) with white noise go
        through the kernel term's tridiagonal precision where it offers one
        (:class:`PrecisionCovariance`), else :class:`DenseCovariance`.
        ``"posterior"``: the routes of the posterior: dense for data that are
        not a reduction, and a reduction through the precision or else
        :class:`ParameterSpaceCovariance`.

    Returns
    -------
    DataCovariance

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import DC, TC
    >>> op = DownsampledConvolution(np.arange(1.0, 41.0), factor=2, order=20)
    >>> type(data_covariance(C(1.0) * DC(0.8, 0.5), op, WhiteNoise(0.1))).__name__
    'PrecisionCovariance'
    >>> type(data_covariance(TC(0.8), op, WhiteNoise(0.1))).__name__
    'DenseCovariance'
    """
    term = observe(kernel, observation)
    remainder = noise.remainder(observation)
    ar1 = _ar1_structure(observation, noise)
    if ar1 is not None and derivatives != "matrices":
        try:
            return AR1Covariance(term, noise, remainder, ar1)
        except NotPositiveDefinite:
            pass
    if derivatives != "matrices" and _precision_applies(observation, noise, space):
        precision = term.precision()
        if precision is not None:
            try:
                return PrecisionCovariance(term, noise, remainder, precision)
            except NotPositiveDefinite:
                pass
    if space == "posterior" and observation.n_discarded > 0:
        return ParameterSpaceCovariance(term, noise, remainder)
    return DenseCovariance._of_term(term, noise, remainder, derivatives)


def _ar1_structure(observation, noise):
    """The AR(1) form of a coloured noise model on a long record (``M > P``), or None.

    So it is for a noise model whose ``structure()`` is an
    :class:`~gpmultirate.noise.AR1Noise` (a pure ``C * Matern(nu=0.5)``
    disturbance on one uniform grid), on data that are a regressor on the
    integer lags, not a reduction, with more samples than coefficients: there
    :class:`AR1Covariance` keeps the long-record cost.
    """
    if (noise.white or getattr(observation, "n_discarded", 0) > 0
            or not getattr(observation, "has_regressor", True)):
        return None
    if observation.n_outputs <= observation.n_coefficients:
        return None
    structure = getattr(noise, "structure", None)
    ar1 = structure() if structure is not None else None
    if ar1 is None or ar1.n_samples != observation.n_outputs:
        return None
    return ar1


def _precision_applies(observation, noise, space: str) -> bool:
    """Whether the data are of the shape and the noise of the kind the precision route needs."""
    if not noise.white:
        return False
    if space == "posterior":
        return observation.n_discarded > 0
    return observation.n_outputs == observation.n_coefficients


def takes_precision_route(kernel, observation, noise) -> bool:
    """Whether :func:`data_covariance` goes through the kernel term's tridiagonal precision.

    So it does for square or reduced data (``M = P``), white noise and a
    term that offers one (DC, a constant times DC); nothing is factored
    here.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import DC, TC
    >>> op = DownsampledConvolution(np.arange(1.0, 41.0), factor=2, order=20)
    >>> takes_precision_route(DC(0.8, 0.5), op, WhiteNoise(0.1))
    True
    >>> takes_precision_route(TC(0.8), op, WhiteNoise(0.1))
    False
    """
    return (_precision_applies(observation, noise, "data")
            and observe(kernel, observation).precision() is not None)
