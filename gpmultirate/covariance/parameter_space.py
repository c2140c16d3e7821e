"""The parameter-space route: a reduced long record seen through ``K = F F^T`` and a QR factor."""

from __future__ import annotations

import numpy as np
from scipy import linalg

from gpmultirate.covariance.base import DataCovariance, kernel_root
from gpmultirate.covariance.posteriors import ParameterSpacePosterior

__all__ = ["ParameterSpaceCovariance"]


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
        self.F, self.inv_root = kernel_root(K)
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

    def posterior(self, y):
        return ParameterSpacePosterior(self, y)

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
