"""The dense route: ``S + N`` by its Cholesky factor in the data space.

The fallback of every noise model (any ``N`` that can be added to ``S``),
and the route cross-validation needs (``Ky^{-1}`` and its blocks:
:class:`HeldOutBlock`).  Low-rank summands on top of it are
:class:`~gpmultirate.covariance.lowrank.WoodburyCovariance`.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from gpmultirate.covariance.base import (
    DataCovariance,
    cholesky_or_raise,
    inverse_from_cholesky,
    log_gaussian,
    robust_cholesky,
)
from gpmultirate.covariance.lowrank import WoodburyCovariance
from gpmultirate.covariance.posteriors import DataSpacePosterior
from gpmultirate.exceptions import NotPositiveDefinite
from gpmultirate.kernels import observe

__all__ = ["DenseCovariance", "HeldOutBlock", "matrix_log_density"]


class DenseCovariance(DataCovariance):
    """``S + N`` by its Cholesky factor ``L`` in the data space.

    Parameters
    ----------
    term : ObservedTerm
    noise : noise model
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
    >>> from gpmultirate.covariance import data_covariance
    >>> from gpmultirate.noise import WhiteNoise
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

        ``derivatives`` as in :func:`~gpmultirate.covariance.data_covariance`.
        """
        term = observe(kernel, observation)
        remainder = noise.remainder(observation)
        if derivatives == "matrices":
            return cls.with_derivatives(term, noise, remainder)
        return cls.of_term(term, noise, remainder, gradient=derivatives == "contraction")

    @classmethod
    def of_term(cls, term, noise, remainder, gradient: bool = False) -> "DenseCovariance":
        """The dense route of an observed kernel term: what every noise model falls back on.

        With ``gradient``, ``S`` is formed with the term's gradient
        contraction, for :meth:`log_likelihood_gradient`.
        """
        if gradient:
            S, contract = term.covariance_with_contractor()
            return cls(term, noise, remainder, S, contract=contract)
        return cls(term, noise, remainder)

    @classmethod
    def with_derivatives(cls, term, noise, remainder) -> "DenseCovariance":
        """The dense route with the term's derivative matrices, for :meth:`log_likelihood_fisher`."""
        S, items = term.covariance_with_derivatives()
        return cls(term, noise, remainder, S, derivatives=items)

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

    def posterior(self, y):
        return DataSpacePosterior(self, y)

    def held_out(self, y: np.ndarray, folds) -> tuple[np.ndarray, np.ndarray, list]:
        """``A = Ky^{-1}``, ``a = A y`` and the :class:`HeldOutBlock` of each fold."""
        A = self.inverse()
        alpha = A @ y
        return A, alpha, [HeldOutBlock(A, alpha, B) for B in folds]

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
        if self.noise.is_free:  # the noise's own: dN = gamma I for white noise
            terms.extend(self.noise.fisher_terms(inverse))
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


class HeldOutBlock:
    """The prediction of the data ``y_B`` of a block ``B`` from the other data.

    With ``A = Ky^{-1}`` and ``a = A y``: the residual
    ``y_B - E[y_B | y_rest] = A_BB^{-1} a_B`` and the covariance
    ``A_BB^{-1}``, from the Cholesky factor of ``A_BB`` (no refit).

    Parameters
    ----------
    A : ndarray of shape (M, M)
        ``Ky^{-1}``.
    alpha : ndarray of shape (M,)
        ``Ky^{-1} y``.
    B : ndarray of int
        The indices of the block.

    Examples
    --------
    >>> import numpy as np
    >>> Ky = np.array([[2.0, 0.5, 0.1], [0.5, 1.0, 0.2], [0.1, 0.2, 1.5]])
    >>> y = np.array([0.3, -0.2, 0.7])
    >>> A = np.linalg.inv(Ky)
    >>> block = HeldOutBlock(A, A @ y, np.array([0]))
    >>> rest = [1, 2]
    >>> mean = Ky[0, rest] @ np.linalg.solve(Ky[np.ix_(rest, rest)], y[rest])
    >>> bool(np.isclose(block.residual[0], y[0] - mean))
    True
    """

    def __init__(self, A: np.ndarray, alpha: np.ndarray, B: np.ndarray):
        self.indices = B
        self.L, _ = robust_cholesky(A[np.ix_(B, B)], "held-out precision")
        self.residual = linalg.cho_solve((self.L, True), alpha[B], check_finite=False)

    def log_density(self, alpha: np.ndarray) -> float:
        """``log N(r_B; 0, A_BB^{-1})``: ``r^T A_BB r = a_B^T r_B``, ``log det = -log det A_BB``."""
        B = self.indices
        return log_gaussian(alpha[B] @ self.residual, -2.0 * np.log(np.diag(self.L)).sum(),
                            B.shape[0])

    def covariance(self) -> np.ndarray:
        """``A_BB^{-1}``, the covariance of the prediction."""
        return linalg.cho_solve((self.L, True), np.eye(self.indices.shape[0]),
                                check_finite=False)

    def variances(self) -> np.ndarray:
        """The diagonal of ``A_BB^{-1}``."""
        inverse = linalg.solve_triangular(self.L, np.eye(self.indices.shape[0]), lower=True,
                                          check_finite=False)
        return np.sum(inverse**2, axis=0)


def matrix_log_density(Ky: np.ndarray, y: np.ndarray) -> float:
    """``log N(y; 0, Ky)`` of a dense covariance, or ``-inf`` when it is not positive definite.

    For scans over candidate covariances (no jitter: a candidate that
    cannot be factored is no candidate).

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.stats import multivariate_normal
    >>> Ky, y = np.array([[2.0, 0.5], [0.5, 1.0]]), np.array([0.3, -0.4])
    >>> bool(np.isclose(matrix_log_density(Ky, y), multivariate_normal(np.zeros(2), Ky).logpdf(y)))
    True
    >>> matrix_log_density(-Ky, y)
    -inf
    """
    try:
        L = cholesky_or_raise(Ky)
    except NotPositiveDefinite:
        return -np.inf
    z = linalg.solve_triangular(L, y, lower=True, check_finite=False)
    return log_gaussian(z @ z, 2.0 * np.log(np.diag(L)).sum(), y.shape[0])
