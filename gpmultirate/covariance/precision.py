"""The precision route: square or reduced data through a tridiagonal ``K^{-1}`` (DC)."""

from __future__ import annotations

import numpy as np
from scipy import linalg

from gpmultirate.covariance.base import DataCovariance, cholesky_or_raise
from gpmultirate.covariance.posteriors import PrecisionPosterior

__all__ = ["PrecisionCovariance"]


class PrecisionCovariance(DataCovariance):
    """``S + gamma I`` of square or reduced data (``M = P``) through a tridiagonal ``K^{-1}``.

    With ``Q = K^{-1}`` (the term's
    :meth:`~gpmultirate.kernels.ObservedTerm.precision`), ``A = Phi^T Phi``
    and the posterior precision ``C = Q + A / gamma = L L^T``:
    ``mu = C^{-1} Phi^T y / gamma`` (eq. 15 by the matrix inversion lemma),

    * ``y^T Ky^{-1} y = |y - Phi mu|^2 / gamma + mu^T Q mu``;
    * ``log det Ky = M log gamma + log det K + log det C``.

    Raises :class:`NotPositiveDefinite` when ``C`` cannot be factored
    (white noise then takes the dense route).

    Parameters
    ----------
    term : ObservedTerm
    noise : WhiteNoise
        (:class:`~gpmultirate.noise.WhiteNoise`)
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
        self.L = cholesky_or_raise(C, overwrite=True)
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

    def posterior(self, y):
        return PrecisionPosterior(self, y)

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
