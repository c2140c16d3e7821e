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
When the observation offers a structured Gram matrix (a convolution on a
uniform grid, by FFT in ``O(F N log N + P^2)``), the factor is instead its
Cholesky factor, ``[[R, z], [0, rho]]`` being the Cholesky factor of
``[Phi y]^T [Phi y]`` as well; that route is taken only where it keeps the
accuracy of the QR route (:func:`factor_from_gram`).
Each evaluation of the evidence then costs ``O(P^3)`` instead of ``O(M^3)``.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg
from scipy.linalg import blas, lapack

from gpmultirate.observations.base import ColumnBlock, Observation

__all__ = ["ReducedObservation", "factor_by_qr", "factor_from_gram", "reduce_observation"]

#: largest condition number of the Cholesky factor the Gram route accepts
#: (that of the Gram matrix is its square)
MAX_CONDITION = 1e6
#: smallest ``rho^2 / y^T y`` the Gram route accepts: ``rho^2`` keeps about
#: ``16 + log10(MIN_RESIDUAL)`` digits
MIN_RESIDUAL = 1e-8


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
    if (observation.n_discarded > 0 or observation.n_outputs <= observation.n_coefficients
            or not getattr(observation, "reducible", True)):
        return observation, y
    reduction = ReducedObservation(observation, y)
    return reduction, reduction.z


class ReducedObservation(Observation):
    """The ``P x P`` observation ``(R, z)`` equivalent to ``M > P`` slow samples.

    An :class:`~gpmultirate.observations.base.Observation` whose regressor
    is the upper-triangular ``R`` and whose outputs are ``z``
    (``n_outputs = P``); ``n_discarded = M - P`` and ``residual = rho^2``
    are the statistics of the rest of the evidence (its likelihood is the
    noise model's :meth:`~gpmultirate.noise.WhiteNoise.remainder`).  Products with matrices of the sparsity
    of ``R`` use triangular BLAS (half the flops).

    Parameters
    ----------
    observation : Observation
        Any observation with more outputs than coefficients.
    y : ndarray of shape (M,)
    block_rows : int, optional
        Rows of ``Phi`` per block of the QR route; by default ``max(2 P, 1024)``.
    method : {"auto", "qr"}, default="auto"
        ``"auto"``: from the Gram matrix when the observation offers a
        structured one (:meth:`~Observation.structured_gram`, a convolution
        on a uniform grid: ``O(F N log N + P^2)``) and it is well enough
        conditioned (:func:`factor_from_gram`), else by QR; ``"qr"``: the
        QR factorisation of ``[Phi y]`` read block by block
        (:meth:`~Observation.regressor_rows`), ``O(M P^2)``.

    Attributes
    ----------
    z : ndarray of shape (P,)
    residual : float
        ``rho^2``.
    route : str
        ``"gram"`` or ``"qr"``: how the factor was computed.

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

    def __init__(self, observation: Observation, y: np.ndarray, block_rows: int | None = None,
                 method: str = "auto"):
        if method not in ("auto", "qr"):
            raise ValueError(f"method must be 'auto' or 'qr'; got {method!r}")
        P = observation.n_coefficients
        M = observation.n_outputs
        factor = None
        if method == "auto":
            found = observation.structured_gram(y)
            if found is not None:
                factor = factor_from_gram(*found, float(y @ y))
        #: how the factor was computed: "gram" (structured Gram, Cholesky) or "qr"
        self.route = "qr" if factor is None else "gram"
        if factor is None:
            factor = factor_by_qr(observation, y, block_rows)
        R, self.z, self.residual = factor
        self._matrix = np.ascontiguousarray(R)
        self._matrix.setflags(write=False)
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

    def gram(self, y=None, block_rows=None):
        """``R^T R`` (kept) and ``R^T y``: the Gram matrix of ``Phi`` and ``Phi^T y`` for ``y = z``."""
        if getattr(self, "_gram", None) is None:
            R = self._matrix
            gram = R.T @ R
            gram += gram.T
            gram *= 0.5
            gram.setflags(write=False)
            self._gram = gram
        projection = None if y is None else self._matrix.T @ y
        return self._gram, projection

    def __repr__(self) -> str:
        return (
            f"ReducedObservation(order={self.order}, n_inputs={self.n_inputs}, "
            f"n_discarded={self.n_discarded})"
        )


def factor_by_qr(observation: Observation, y: np.ndarray, block_rows: int | None = None):
    """``(R, z, rho^2)`` from the QR factorisation of ``[Phi y]``, accumulated over blocks of rows.

    ``O(M P^2)``; exact for any regressor, of full rank or not.
    """
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
    return top[:P, :P], top[:P, P].copy(), float(top[P, P] ** 2)


def factor_from_gram(gram: np.ndarray, projection: np.ndarray, sum_of_squares: float):
    """``(R, z, rho^2)`` from ``Phi^T Phi``, ``Phi^T y`` and ``y^T y``, or None.

    ``R`` is the Cholesky factor of the Gram matrix, ``R^T z = Phi^T y`` and
    ``rho^2 = y^T y - z^T z``: the same factor as the QR route up to the
    signs of rows.  The Gram route squares the condition number and computes
    the residual by a difference, so it gives up (None: use
    :func:`factor_by_qr`) where that would cost accuracy: a Gram matrix that
    is not numerically positive definite or whose factor has a condition
    number above :data:`MAX_CONDITION`, and a residual below
    :data:`MIN_RESIDUAL` times ``y^T y`` (more digits cancelled than kept).
    """
    try:
        R = linalg.cholesky(gram, lower=False, check_finite=False)
    except linalg.LinAlgError:
        return None
    rcond, info = lapack.dtrcon(R, norm="1", uplo="U", diag="N")
    if info != 0 or not rcond * MAX_CONDITION > 1.0:
        return None
    z = linalg.solve_triangular(R, projection, trans="T", check_finite=False)
    residual = sum_of_squares - float(z @ z)
    if not residual > MIN_RESIDUAL * sum_of_squares:
        return None
    return R, z, residual
