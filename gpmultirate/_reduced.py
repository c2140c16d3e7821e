"""Sufficient statistics of long records: the evidence in the parameter space.

With more slow samples than coefficients (``M > P``) the slow data enter the
posterior and the evidence only through a ``P x P`` triangular factor.  The
QR factorisation ``[Phi y] = Q [[R, z], [0, rho]]`` (``Q`` with orthonormal
columns) gives, after completing ``Q`` to an orthogonal basis,

    Q_full^T y ~ N(0, blockdiag(R K R^T + gamma I_P, gamma I_{M-P})),

whose first ``P`` entries are ``z`` and whose other entries have the sum of
squares ``rho^2`` (the least-squares residual when ``Phi`` has full column
rank).  Nothing here needs full rank: ``Phi = Q_1 R`` exactly.  So the log evidence is that
of the ``P``-sample problem ``(R, z)`` plus
``-(M - P)/2 log(2 pi gamma) - rho^2 / (2 gamma)``, and the posterior of the
coefficients is that of ``(R, z)`` exactly (T. Chen and L. Ljung,
"Implementation of algorithms for tuning parameters in regularized least
squares problems in system identification", Automatica 49(7), 2013).

The factor is accumulated over blocks of rows of ``Phi``, so the ``M x P``
regressor is never held in memory: ``O(M P^2)`` time once, ``O(P^2)`` memory.
Each evaluation of the evidence then costs ``O(P^3)`` instead of ``O(M^3)``.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy import linalg

from gpmultirate._contraction import kernel_matrix


class ReducedObservation:
    """The ``P x P`` observation ``(R, z)`` equivalent to ``M > P`` slow samples.

    Behaves like a :class:`~gpmultirate.operator.DownsampledConvolution`
    whose regressor is ``R`` and whose outputs are ``z`` (``n_outputs = P``);
    ``n_discarded = M - P`` and ``residual = rho^2`` carry the rest of the
    evidence.

    Parameters
    ----------
    operator : DownsampledConvolution
    y : ndarray of shape (M,)
    block_rows : int, optional
        Rows of ``Phi`` per block; by default ``max(4 P, 1024)``.
    """

    def __init__(self, operator, y: np.ndarray, block_rows: int | None = None):
        P = operator.order
        M = operator.n_outputs
        block = block_rows or max(2 * P, 1024)
        top = np.zeros((0, P + 1))
        for start in range(0, M, block):
            rows = operator.sample_indices[start : start + block]
            stacked = np.empty((top.shape[0] + rows.shape[0], P + 1), order="F")
            stacked[: top.shape[0]] = top
            stacked[top.shape[0] :, :P] = _regressor_rows(operator.u, P, rows)
            stacked[top.shape[0] :, P] = y[start : start + block]
            top = linalg.qr(stacked, mode="r", overwrite_a=True, check_finite=False)[0]
            top = top[: P + 1]
        if top.shape[0] < P + 1:  # fewer rows than columns so far
            top = np.vstack([top, np.zeros((P + 1 - top.shape[0], P + 1))])
        self.matrix = np.ascontiguousarray(top[:P, :P])
        self.matrix.setflags(write=False)
        self.z = top[:P, P].copy()
        self.residual = float(top[P, P] ** 2)
        self.n_discarded = M - P
        self.upper_triangular = True  # lets products with the regressor use BLAS trmm
        self.order = P
        self.n_outputs = P
        self.lags = operator.lags

    def kernel_matrix(self, kernel, eval_gradient: bool = False):
        """The prior covariance ``K`` at lags ``0..P-1``."""
        if not eval_gradient:
            return kernel_matrix(kernel, self.lags[:, 0])
        return kernel(self.lags, eval_gradient=eval_gradient)

    def discarded_log_likelihood(self, noise_level: float) -> tuple[float, float, float]:
        """Value, derivative and Fisher information in ``log(noise_level)`` of the rest.

        The ``M - P`` discarded components are independent ``N(0, gamma)``
        with sum of squares ``rho^2``.
        """
        n = self.n_discarded
        value = -0.5 * n * (np.log(2.0 * np.pi * noise_level)) - 0.5 * self.residual / noise_level
        grad = -0.5 * n + 0.5 * self.residual / noise_level
        return float(value), float(grad), 0.5 * n


def _regressor_rows(u: np.ndarray, order: int, rows: np.ndarray) -> np.ndarray:
    """Rows ``Phi[r, i] = u[rows[r] - i]`` (zero before the record), as a strided view."""
    padded = np.concatenate([np.zeros(order - 1), np.asarray(u, dtype=float)])
    windows = sliding_window_view(padded, order)[:, ::-1]  # window n ends at u[n]
    return windows[rows]


def tuning_data(operator, y: np.ndarray):
    """``(operator, y)`` for ``M <= P``, else the reduced ``(R, z)`` observation."""
    if operator.n_outputs <= operator.order:
        return operator, y
    reduced = ReducedObservation(operator, y)
    return reduced, reduced.z
