"""The reference formulas of the data-space route for any noise covariance ``N``.

Eq. (15) and (19) with ``N`` in place of ``gamma I``, written from the paper
with plain dense algebra and no structure: what every structured route and
noise model (:mod:`gpmultirate.noise`) is tested against.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from gpmultirate.covariance.base import log_gaussian

__all__ = ["dense_log_evidence", "dense_posterior"]


def dense_log_evidence(Phi, K, y, N, dK=None, dN=None, eval_gradient: bool = False):
    """The reference log evidence ``log N(y; 0, Phi K Phi^T + N)`` and its gradient.

    Eq. (19) with the noise covariance ``N`` in place of ``gamma I``; the
    gradient by the trace identity, ``1/2 tr((alpha alpha^T - Ky^{-1}) dKy_j)``,
    for the kernel's entries (``Phi dK_j Phi^T``) then the noise's (``dN_j``).

    Parameters
    ----------
    Phi : ndarray of shape (M, P)
    K : ndarray of shape (P, P)
    y : ndarray of shape (M,)
    N : ndarray of shape (M, M)
    dK : ndarray of shape (P, P, n_kernel), optional
    dN : ndarray of shape (M, M, n_noise), optional
    eval_gradient : bool, default=False

    Returns
    -------
    value : float
    gradient : ndarray, only with ``eval_gradient``

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.stats import multivariate_normal
    >>> Phi, K, N, y = np.eye(2), np.eye(2), 0.5 * np.eye(2), np.array([0.3, -1.0])
    >>> bool(np.isclose(dense_log_evidence(Phi, K, y, N),
    ...                 multivariate_normal(np.zeros(2), 1.5 * np.eye(2)).logpdf(y)))
    True
    """
    Ky = Phi @ K @ Phi.T + N
    L = linalg.cholesky(Ky, lower=True, check_finite=False)
    alpha = linalg.cho_solve((L, True), y, check_finite=False)
    M = y.shape[0]
    value = log_gaussian(y @ alpha, 2.0 * np.log(np.diag(L)).sum(), M)
    if not eval_gradient:
        return value
    W = np.outer(alpha, alpha) - linalg.cho_solve((L, True), np.eye(M), check_finite=False)
    grad = []
    if dK is not None:
        A = Phi.T @ W @ Phi
        grad.extend(0.5 * (A.reshape(1, -1) @ dK.reshape(A.size, -1))[0])
    if dN is not None:
        grad.extend(0.5 * (W.reshape(1, -1) @ dN.reshape(W.size, -1))[0])
    return value, np.array(grad)


def dense_posterior(Phi, K, y, N):
    """Posterior mean and covariance of ``g`` given ``y = Phi g + v``, ``v ~ N(0, N)``.

    Eq. (15) with ``N`` in place of ``gamma I``: ``mu = K Phi^T Ky^{-1} y`` and
    ``Sigma = K - K Phi^T Ky^{-1} Phi K``.

    Examples
    --------
    >>> import numpy as np
    >>> mu, Sigma = dense_posterior(np.eye(1), np.eye(1), np.array([2.0]), np.eye(1))
    >>> mu.round(12).tolist(), Sigma.round(12).tolist()
    ([1.0], [[0.5]])
    """
    Ky = Phi @ K @ Phi.T + N
    L = linalg.cholesky(Ky, lower=True, check_finite=False)
    PhiK = Phi @ K
    B = linalg.solve_triangular(L, PhiK, lower=True, check_finite=False)
    mu = PhiK.T @ linalg.cho_solve((L, True), y, check_finite=False)
    Sigma = K - B.T @ B
    return mu, 0.5 * (Sigma + Sigma.T)
