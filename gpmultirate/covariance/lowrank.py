"""Low-rank summands: the Woodbury identity and the matrix determinant lemma, once.

A covariance ``D + W W^T`` with ``D`` cheap to invert (a diagonal, or the
identity after whitening by a factor of the rest) and ``W`` of few columns
``r`` is answered through the capacitance ``C = I + W^T D^{-1} W``.  With
``C - I = Q diag(lambda) Q^T`` and ``beta = Q^T W^T D^{-1} y``:

* ``y^T (D + W W^T)^{-1} y = y^T D^{-1} y - sum_j beta_j^2 / (1 + lambda_j)``;
* ``log det(D + W W^T) = log det D + sum_j log(1 + lambda_j)``;

so the log evidence gains :func:`woodbury_gain` over that of ``D``.  This
is the one home of the formula: :class:`WoodburyCovariance` (a PK
resonance at one candidate of a grid), the resonance scan (its ``2 x 2``
capacitance in closed form, over grids of frequencies and amplitudes) and
the joint tuning of resonances over a spectral base
(:class:`DiagonalPlusLowRank`) use it.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from gpmultirate.covariance.base import DataCovariance

__all__ = ["DiagonalPlusLowRank", "WoodburyCovariance", "woodbury_gain", "woodbury_terms"]


def woodbury_gain(eigenvalues, squared_projections):
    """The log evidence a low-rank summand adds: ``1/2 sum_j (b_j^2 / (1 + l_j) - log(1 + l_j))``.

    ``l_j`` are the eigenvalues of ``W^T D^{-1} W`` and ``beta_j^2`` the
    squared projections ``b_j^2`` of ``W^T D^{-1} y`` on its eigenvectors; the sum is
    over the last axis (arrays broadcast, for grids of candidates).

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.stats import multivariate_normal
    >>> D, w, y = np.diag([1.0, 2.0]), np.array([[1.0], [0.5]]), np.array([0.3, -1.2])
    >>> l = w.T @ np.linalg.solve(D, w)
    >>> beta2 = (w.T @ np.linalg.solve(D, y)) ** 2
    >>> reference = (multivariate_normal(np.zeros(2), D + w @ w.T).logpdf(y)
    ...              - multivariate_normal(np.zeros(2), D).logpdf(y))
    >>> bool(np.isclose(woodbury_gain(l[0], beta2), reference))
    True
    """
    reduction, increase = woodbury_terms(eigenvalues, squared_projections)
    return 0.5 * (reduction - increase)


def woodbury_terms(eigenvalues, squared_projections):
    """``(sum_j beta_j^2 / (1 + l_j), sum_j log(1 + l_j))``, over the last axis.

    What a low-rank summand takes off ``y^T Ky^{-1} y`` and adds to
    ``log det Ky`` (see :func:`woodbury_gain`).
    """
    eigenvalues = np.asarray(eigenvalues, dtype=float)
    return (np.sum(squared_projections / (1.0 + eigenvalues), axis=-1),
            np.sum(np.log1p(eigenvalues), axis=-1))


class DiagonalPlusLowRank:
    """``diag(d) + W W^T`` by the Woodbury identity and the determinant lemma.

    Parameters
    ----------
    d : ndarray of shape (M,) or None
        The positive diagonal; None for the identity (a covariance whitened
        by a factor of the rest).
    W : ndarray of shape (M, r)

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> d, W, y = rng.uniform(1, 2, 5), rng.standard_normal((5, 2)), rng.standard_normal(5)
    >>> update = DiagonalPlusLowRank(d, W)
    >>> A = np.diag(d) + W @ W.T
    >>> quad, log_det = update.inv_quad_logdet(y)
    >>> bool(np.isclose(quad, y @ np.linalg.solve(A, y)))
    True
    >>> bool(np.isclose(log_det, np.linalg.slogdet(A)[1]))
    True
    >>> bool(np.allclose(update.solve(y), np.linalg.solve(A, y)))
    True
    """

    def __init__(self, d: np.ndarray | None, W: np.ndarray):
        self.d = d
        self.inv_d = None if d is None else 1.0 / d
        self.W = W
        self.DW = W if d is None else self.inv_d[:, None] * W  # D^{-1} W
        # the capacitance C = I + W^T D^{-1} W = G G^T
        self.G = np.linalg.cholesky(np.eye(W.shape[1]) + W.T @ self.DW)
        self._E = None

    def _inv_d_times(self, b: np.ndarray) -> np.ndarray:
        if self.inv_d is None:
            return b
        return self.inv_d.reshape((-1,) + (1,) * (np.ndim(b) - 1)) * b

    def _whitened(self, b: np.ndarray) -> np.ndarray:
        """``G^{-1} W^T D^{-1} b``."""
        return linalg.solve_triangular(self.G, self.DW.T @ b, lower=True, check_finite=False)

    @property
    def E(self) -> np.ndarray:
        """``D^{-1} W G^{-T}``: ``D^{-1} - E E^T`` is the inverse."""
        if self._E is None:
            self._E = linalg.solve_triangular(self.G, self.DW.T, lower=True,
                                              check_finite=False).T
        return self._E

    def inv_quad_logdet(self, y: np.ndarray) -> tuple[float, float]:
        """``y^T (D + W W^T)^{-1} y`` and ``log det(D + W W^T)``."""
        v = self._whitened(y)
        log_det_d = 0.0 if self.d is None else np.sum(np.log(self.d))
        return (float(y @ self._inv_d_times(y) - v @ v),
                float(log_det_d + 2.0 * np.log(np.diag(self.G)).sum()))

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``(D + W W^T)^{-1} b`` for ``b`` of shape ``(M,)`` or ``(M, k)``."""
        return self._inv_d_times(b) - self.E @ self._whitened(b)

    def inverse_diagonal(self) -> np.ndarray:
        """The diagonal of ``(D + W W^T)^{-1}``."""
        ones = np.ones(self.W.shape[0]) if self.inv_d is None else self.inv_d
        return ones - np.einsum("ij,ij->i", self.E, self.E)

    def inverse_times_low_rank(self) -> np.ndarray:
        """``(D + W W^T)^{-1} W = D^{-1} W C^{-1}``."""
        return linalg.cho_solve((self.G, True), self.DW.T, check_finite=False).T


class WoodburyCovariance(DataCovariance):
    """A dense covariance plus a low-rank summand: ``L L^T + L B B^T L^T``.

    Whitened by the base's factor ``L`` the covariance is ``I + B B^T``
    (:class:`DiagonalPlusLowRank`): with ``w = L^{-1} y``,
    ``y^T Ky^{-1} y = w^T (I + B B^T)^{-1} w`` and
    ``log det Ky = log det(L L^T) + log det(I + B^T B)``: ``O(M^2)`` on top
    of the base's factor.  Built by
    :meth:`~gpmultirate.covariance.DenseCovariance.plus_low_rank`.

    Parameters
    ----------
    base : DenseCovariance
    B : ndarray of shape (M, r)
        ``L^{-1} U D^{1/2}``.
    """

    def __init__(self, base, B: np.ndarray):
        super().__init__(base.term, base.noise, base.remainder)
        self.base = base
        self.B = B
        self.update = DiagonalPlusLowRank(None, B)

    def solve(self, b):
        base = self.base
        x = self.update.solve(base.whiten(b))
        return linalg.solve_triangular(base.L, x, lower=True, trans="T", check_finite=False)

    def inv_quad_logdet(self, y):
        quad, log_det = self.update.inv_quad_logdet(self.base.whitened(y))
        return quad, log_det + self.base.log_det()
