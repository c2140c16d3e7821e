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
from scipy import linalg
from scipy.linalg import blas

from gpmultirate.observations.base import ColumnBlock, Observation

__all__ = ["ReducedObservation", "reduce_observation"]


def reduce_observation(observation: Observation, y: np.ndarray):
    """``(observation, y)`` for the evidence and the posterior.

    With more samples than coefficients (``M > P``), the long-record
    reduction :class:`ReducedObservation` and its ``z``; otherwise, and for
    an observation that is a reduction already, ``(observation, y)``.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> op = DownsampledConvolution(np.arange(1.0, 31.0), factor=1, order=4)
    >>> data, z = reduce_observation(op, np.ones(30))
    >>> type(data).__name__, z.shape
    ('ReducedObservation', (4,))
    """
    if observation.n_discarded > 0 or observation.n_outputs <= observation.n_coefficients:
        return observation, y
    reduction = ReducedObservation(observation, y)
    return reduction, reduction.z


class ReducedObservation(Observation):
    """The ``P x P`` observation ``(R, z)`` equivalent to ``M > P`` slow samples.

    An :class:`~gpmultirate.observations.base.Observation` whose regressor
    is the upper-triangular ``R`` and whose outputs are ``z``
    (``n_outputs = P``); ``n_discarded = M - P`` and ``residual = rho^2``
    carry the rest of the evidence.  Products with matrices of the sparsity
    of ``R`` use triangular BLAS (half the flops).

    Parameters
    ----------
    observation : Observation
        Any observation with more outputs than coefficients; its rows are
        read block by block (:meth:`~Observation.regressor_rows`).
    y : ndarray of shape (M,)
    block_rows : int, optional
        Rows of ``Phi`` per block; by default ``max(2 P, 1024)``.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> rng = np.random.default_rng(0)
    >>> op = DownsampledConvolution(rng.standard_normal(60), factor=2, order=5)
    >>> y = rng.standard_normal(op.n_outputs)
    >>> reduced = ReducedObservation(op, y)
    >>> reduced.shape, reduced.n_discarded
    ((5, 5), 25)
    >>> bool(np.allclose(reduced.matrix.T @ reduced.matrix, op.matrix.T @ op.matrix))
    True
    """

    def __init__(self, observation: Observation, y: np.ndarray, block_rows: int | None = None):
        P = observation.n_coefficients
        M = observation.n_outputs
        block = block_rows or max(2 * P, 1024)
        top = np.zeros((0, P + 1))
        for start in range(0, M, block):
            rows = observation.regressor_rows(start, start + block)
            stacked = np.empty((top.shape[0] + rows.shape[0], P + 1), order="F")
            stacked[: top.shape[0]] = top
            stacked[top.shape[0] :, :P] = rows
            stacked[top.shape[0] :, P] = y[start : start + block]
            top = linalg.qr(stacked, mode="r", overwrite_a=True, check_finite=False)[0]
            top = top[: P + 1]
        if top.shape[0] < P + 1:  # fewer rows than columns so far
            top = np.vstack([top, np.zeros((P + 1 - top.shape[0], P + 1))])
        self._matrix = np.ascontiguousarray(top[:P, :P])
        self._matrix.setflags(write=False)
        self.z = top[:P, P].copy()
        self.residual = float(top[P, P] ** 2)
        self.n_discarded = M - P
        self.order = observation.order
        self.n_inputs = observation.n_inputs
        self.n_outputs = P
        self._lags = observation.lags

    @property
    def lags(self) -> np.ndarray:
        """The lags (and inputs) of the reduced observation's coefficients."""
        return self._lags

    @property
    def matrix(self) -> np.ndarray:
        """The upper-triangular factor ``R`` (read-only)."""
        return self._matrix

    def input_block(self, k: int):
        """The columns of input ``k`` of ``R``: triangular only for a single input."""
        if self.n_inputs == 1:
            return self
        return ColumnBlock(self, k)

    def regressor_shaped_outer(self, H, G):
        # G^T is a Fortran-ordered lower-triangular view of G: no copies.
        # (H G^T)^T = G H^T = op(G^T) H^T with op = transpose
        return blas.dtrmm(1.0, G.T, H.T, side=0, lower=1, trans_a=1).T

    def symmetric_times_regressor_shaped(self, W, G):
        # W is symmetric, so its transpose is a Fortran-ordered view of W
        return blas.dtrmm(1.0, G.T, W.T, side=1, lower=1, trans_a=1)

    def discarded_log_likelihood(self, noise_level: float) -> tuple[float, float, float]:
        """Value, derivative and Fisher information in ``log(noise_level)`` of the rest.

        The ``M - P`` discarded components are independent ``N(0, gamma)``
        with sum of squares ``rho^2``.
        """
        n = self.n_discarded
        value = -0.5 * n * (np.log(2.0 * np.pi * noise_level)) - 0.5 * self.residual / noise_level
        grad = -0.5 * n + 0.5 * self.residual / noise_level
        return float(value), float(grad), 0.5 * n

    def __repr__(self) -> str:
        return (
            f"ReducedObservation(order={self.order}, n_inputs={self.n_inputs}, "
            f"n_discarded={self.n_discarded})"
        )
