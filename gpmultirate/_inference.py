"""Linear algebra of the Gaussian-process posterior in the data space.

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
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy import linalg

from gpmultirate._reduced import ReducedObservation
from gpmultirate._structured import (
    observed_with_contractor,
    observed_with_derivatives,
    observed_without,
    regressor_times_kernel,
)
from gpmultirate.exceptions import NumericalWarning

LOG_2PI = np.log(2.0 * np.pi)


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
    operator : DownsampledConvolution
    kernel : sklearn Kernel over lags
    noise_level : float
        Noise variance ``gamma`` of the slow samples.
    y : ndarray of shape (M,)
    """

    def __init__(self, operator, kernel, noise_level: float, y: np.ndarray):
        K = operator.kernel_matrix(kernel)
        PhiK = regressor_times_kernel(kernel, operator, K)
        # the structured S (filters, recursion) rather than the O(M^2 P) PhiK Phi^T
        Ky = observed_with_contractor(kernel, operator, need_gradient=False)[0].copy()
        Ky[np.diag_indices_from(Ky)] += noise_level
        self.L, self.jitter = robust_cholesky(Ky)
        self.alpha = linalg.cho_solve((self.L, True), y, check_finite=False)
        B = linalg.solve_triangular(self.L, PhiK, lower=True, check_finite=False)
        # eq. (15): K Phi^T (Phi K Phi^T + gamma I)^{-1} y
        super().__init__(PhiK.T @ self.alpha, K, B)
        self.log_marginal_likelihood = float(
            -0.5 * y @ self.alpha
            - np.log(np.diag(self.L)).sum()
            - 0.5 * y.shape[0] * LOG_2PI
        )

    def mean_at_lags(self, operator, kernel, lags: np.ndarray) -> np.ndarray:
        """Posterior mean of ``g`` at real lags."""
        return operator.cross_covariance(kernel, lags[:, None]) @ self.alpha

    def at_lags(self, operator, kernel, lags: np.ndarray, full_cov: bool):
        """Posterior mean and variance (or covariance) of ``g`` at real lags."""
        cross = operator.cross_covariance(kernel, lags[:, None])
        mean = cross @ self.alpha
        V = linalg.solve_triangular(self.L, cross.T, lower=True, check_finite=False)
        if full_cov:
            cov = kernel(lags[:, None]) - V.T @ V
            return mean, 0.5 * (cov + cov.T)
        var = kernel.diag(lags[:, None]) - np.einsum("ij,ij->j", V, V)
        return mean, np.maximum(var, 0.0)


class ParameterSpacePosterior(GaussianCoefficients):
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
        self.log_marginal_likelihood = float(-0.5 * quad - 0.5 * log_det - 0.5 * y.shape[0] * LOG_2PI)
        self.factor = linalg.solve_triangular(R, F.T, trans="T", check_finite=False).T
        super().__init__(F @ z, K, None)

    def pair_variances(self, A1: np.ndarray, A2: np.ndarray | None):
        F1 = A1 @ self.factor
        var1 = np.einsum("ij,ij->i", F1, F1)
        if A2 is None:
            return var1, None, None
        F2 = A2 @ self.factor
        return var1, np.einsum("ij,ij->i", F2, F2), np.einsum("ij,ij->i", F1, F2)

    def linear_map(self, A: np.ndarray, full_cov: bool = False):
        mean = A @ self.coef
        AF = A @ self.factor
        if full_cov:
            return mean, AF @ AF.T
        return mean, np.einsum("ij,ij->i", AF, AF)

    def covariance(self) -> np.ndarray:
        return self.factor @ self.factor.T

    def mean_at_lags(self, operator, kernel, lags: np.ndarray) -> np.ndarray:
        """Posterior mean of ``g`` at real lags."""
        return kernel(lags[:, None], operator.lags) @ (self.inv_root @ self.z)

    def at_lags(self, operator, kernel, lags: np.ndarray, full_cov: bool):
        """Posterior of ``g(lags)``: the prior conditional on ``g(0..P-1)``, averaged."""
        J = kernel(lags[:, None], operator.lags) @ self.inv_root
        mean = J @ self.z
        JS = J @ linalg.solve_triangular(self.R, np.eye(self.R.shape[0]), check_finite=False)
        if full_cov:
            cov = kernel(lags[:, None]) - J @ J.T + JS @ JS.T
            return mean, 0.5 * (cov + cov.T)
        var = kernel.diag(lags[:, None]) - np.einsum("ij,ij->i", J, J) + np.einsum("ij,ij->i", JS, JS)
        return mean, np.maximum(var, 0.0)


def posterior(operator, kernel, noise_level: float, y: np.ndarray) -> GaussianCoefficients:
    """The posterior in whichever space is smaller: data (``M <= P``) or parameters.

    For ``M > P`` the data are first reduced to the ``P x P`` factor of
    :class:`~gpmultirate._reduced.ReducedObservation` (never holding ``Phi``),
    whose least-squares form gives the same posterior; ``operator`` may be
    such a reduction already (``y`` is then ignored).
    """
    if isinstance(operator, ReducedObservation) or operator.n_outputs > operator.order:
        reduced = operator if isinstance(operator, ReducedObservation) else (
            ReducedObservation(operator, y)
        )
        result = ParameterSpacePosterior(reduced, kernel, noise_level, reduced.z)
        result.log_marginal_likelihood += reduced.discarded_log_likelihood(noise_level)[0]
        return result
    return DataSpacePosterior(operator, kernel, noise_level, y)


def _discarded(operator, noise_level):
    """The evidence of the samples a reduced observation left out (zeros otherwise)."""
    if isinstance(operator, ReducedObservation):
        return operator.discarded_log_likelihood(noise_level)
    return 0.0, 0.0, 0.0


def log_marginal_likelihood(
    operator, kernel, noise_level: float, y: np.ndarray, eval_gradient: bool, noise_free: bool
):
    """Log evidence of the slow data and its gradient with respect to log hyperparameters.

    The gradient has the kernel's ``theta`` first and, when ``noise_free`` is
    true, the derivative with respect to ``log(noise_level)`` last.
    """
    S, contract = observed_with_contractor(kernel, operator, need_gradient=eval_gradient)
    Ky = S.copy()
    Ky[np.diag_indices_from(Ky)] += noise_level
    L, _ = robust_cholesky(Ky)
    alpha = linalg.cho_solve((L, True), y, check_finite=False)
    rest_value, rest_grad, _ = _discarded(operator, noise_level)
    value = float(
        -0.5 * y @ alpha - np.log(np.diag(L)).sum() - 0.5 * y.shape[0] * LOG_2PI + rest_value
    )
    if not eval_gradient:
        return value
    W = _inverse_from_cholesky(L)
    W *= -1.0
    W = linalg.blas.dger(1.0, alpha, alpha, a=W, overwrite_a=True)  # + alpha alpha^T
    grad = 0.5 * contract(W)
    if noise_free:
        grad = np.append(grad, 0.5 * np.trace(W) * noise_level + rest_grad)
    return value, grad


def _inverse_from_cholesky(L: np.ndarray) -> np.ndarray:
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
    """Log evidence, its gradient and its Fisher information in log hyperparameters.

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
    S, items = observed_with_derivatives(kernel, operator)
    Ky = S.copy()  # S may itself be an item (the derivative of an amplitude)
    Ky[np.diag_indices_from(Ky)] += noise_level
    L, _ = robust_cholesky(Ky)
    M = y.shape[0]
    inverse = _inverse_from_cholesky(L)
    a = inverse @ y
    value = float(-0.5 * y @ a - np.log(np.diag(L)).sum() - 0.5 * M * LOG_2PI)
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
    rest_value, rest_grad, rest_fisher = _discarded(operator, noise_level)
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
    operator, kernel, term, noise_level: float, y: np.ndarray, omegas: np.ndarray
):
    """Log evidence for each resonance frequency in ``omegas`` of one PK ``term``.

    ``term`` must be a summand of ``kernel`` (not inside a product); returns
    None otherwise.  The rest of the data covariance is factored once and the
    term, of rank two, enters each candidate by the matrix determinant lemma
    and the Woodbury identity: ``O(M^2)`` per candidate instead of
    ``O(M^3)``.
    """
    S_rest = observed_without(kernel, term, operator)
    if S_rest is None:
        return None
    Ky = S_rest
    Ky[np.diag_indices_from(Ky)] += noise_level
    L, _ = robust_cholesky(Ky)
    w = linalg.solve_triangular(L, y, lower=True, check_finite=False)
    base = float(
        -0.5 * w @ w - np.log(np.diag(L)).sum() - 0.5 * y.shape[0] * LOG_2PI
        + _discarded(operator, noise_level)[0]
    )
    values = term._check_hyperparameters()
    roots = np.array([values["sigma1"], values["sigma2"]])
    lags = operator.lags[:, 0]
    parts = [term._parts(lags, values["alpha"], omega) for omega in omegas]
    U = operator.matrix @ np.column_stack([v for pair in parts for v in pair])
    A = linalg.solve_triangular(L, U, lower=True, check_finite=False)
    result = np.empty(len(omegas))
    for k in range(len(omegas)):
        B = A[:, 2 * k : 2 * k + 2] * roots  # L^{-1} U_k D^{1/2}
        C = np.eye(2) + B.T @ B
        b = B.T @ w
        chol = np.linalg.cholesky(C)
        v = np.linalg.solve(chol, b)
        result[k] = base + 0.5 * v @ v - np.log(np.diag(chol)).sum()
    return result
