"""The observation operator: a downsampled convolution with the input (eq. 8).

The slow-rate output of an FIR model ``g`` of order ``P`` driven by the
fast-rate input ``u`` is

    y_l(m) = sum_{i=0}^{P-1} g_i u(offset + m F - i),    m = 0..M-1,

with ``u(n) = 0`` for ``n < 0`` (the system starts at rest).  In matrix form
``y_l = Phi g`` with the regressor ``Phi`` of the paper's eq. (8).  With a
Gaussian-process prior ``g ~ GP(0, k)`` the slow data have covariance
``Phi K Phi^T`` and cross-covariance ``k(t, 0..P-1) Phi^T`` with ``g(t)``.
"""

from __future__ import annotations

import numpy as np

from gpmultirate.validation import check_array, check_int, check_signal

__all__ = ["DownsampledConvolution", "convolution_matrix"]


class DownsampledConvolution:
    """Downsampled convolution with a known fast-rate input (paper eq. 8).

    Parameters
    ----------
    u : array-like of shape (N,)
        Fast-rate input; samples before the record are taken as zero.
    factor : int
        Downsampling factor ``F >= 1``.
    order : int
        FIR order ``P`` in ``1..N`` (number of lags ``0..P-1``).
    offset : int, default=0
        Index of the first slow sample on the fast grid, ``0..F-1``; slow
        sample ``m`` is fast sample ``offset + m * F``.

    Attributes
    ----------
    n_samples : int
        ``N``, the length of ``u``.
    n_outputs : int
        ``M = len(range(offset, N, factor))``, the number of slow samples.
    sample_indices : ndarray of shape (M,)
        Fast-sample index of each slow sample.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> op = DownsampledConvolution(np.arange(1.0, 7.0), factor=2, order=3)
    >>> op.matrix
    array([[1., 0., 0.],
           [3., 2., 1.],
           [5., 4., 3.]])
    >>> op.matvec(np.array([1.0, 0.0, 0.0]))
    array([1., 3., 5.])
    """

    def __init__(self, u, factor: int, order: int, offset: int = 0):
        u = check_signal(u, "u")
        self.factor = check_int(factor, "factor", low=1)
        self.order = check_int(order, "order", low=1, high=u.shape[0])
        self.offset = check_int(offset, "offset", low=0, high=self.factor - 1)
        if self.offset >= u.shape[0]:
            raise ValueError(
                f"offset must be smaller than len(u) = {u.shape[0]}; got {self.offset}"
            )
        u.setflags(write=False)
        self.u = u
        self.sample_indices = np.arange(self.offset, u.shape[0], self.factor)
        self.sample_indices.setflags(write=False)
        self._matrix = None

    @property
    def n_samples(self) -> int:
        return self.u.shape[0]

    @property
    def n_outputs(self) -> int:
        return self.sample_indices.shape[0]

    @property
    def shape(self) -> tuple[int, int]:
        """``(M, P)``, the shape of the regressor."""
        return (self.n_outputs, self.order)

    @property
    def lags(self) -> np.ndarray:
        """Lags ``0..P-1`` as a kernel input of shape ``(P, 1)``."""
        return np.arange(self.order, dtype=float)[:, None]

    @property
    def matrix(self) -> np.ndarray:
        """The regressor ``Phi`` of shape ``(M, P)`` (built once, read-only)."""
        if self._matrix is None:
            matrix = convolution_matrix(self.u, self.order, self.sample_indices)
            matrix.setflags(write=False)
            self._matrix = matrix
        return self._matrix

    def matvec(self, coef) -> np.ndarray:
        """Return ``Phi @ coef``: the slow output of FIR coefficients ``coef``.

        ``coef`` has shape ``(P,)`` or ``(P, k)``.
        """
        coef = check_array(coef, "coef", rows=self.order)
        return self.matrix @ coef

    def rmatvec(self, y) -> np.ndarray:
        """Return ``Phi.T @ y`` for ``y`` of shape ``(M,)`` or ``(M, k)``."""
        y = check_array(y, "y", rows=self.n_outputs)
        return self.matrix.T @ y

    def kernel_matrix(self, kernel, eval_gradient: bool = False):
        """Return the prior covariance ``K`` of the coefficients at lags ``0..P-1``."""
        if not eval_gradient:
            from gpmultirate._contraction import kernel_matrix

            return kernel_matrix(kernel, self.lags[:, 0])
        return kernel(self.lags, eval_gradient=eval_gradient)

    def covariance(self, kernel, eval_gradient: bool = False):
        """Return the prior covariance ``Phi K Phi^T`` of the noise-free slow output.

        With ``eval_gradient=True`` also return its gradient with respect to
        ``kernel.theta``, of shape ``(M, M, n_theta)``.
        """
        Phi = self.matrix
        if not eval_gradient:
            K = self.kernel_matrix(kernel)
            return _symmetrize(Phi @ K @ Phi.T)
        K, dK = self.kernel_matrix(kernel, eval_gradient=True)
        cov = _symmetrize(Phi @ K @ Phi.T)
        grad = np.einsum("mi,ijk,nj->mnk", Phi, dK, Phi, optimize=True)
        return cov, grad

    def cross_covariance(self, kernel, lags) -> np.ndarray:
        """Return ``Cov(g(lags), y_l) = k(lags, 0..P-1) Phi^T``, shape ``(n, M)``."""
        return kernel(lags, self.lags) @ self.matrix.T

    def __eq__(self, other) -> bool:
        if not isinstance(other, DownsampledConvolution):
            return NotImplemented
        return (
            self.factor == other.factor
            and self.order == other.order
            and self.offset == other.offset
            and np.array_equal(self.u, other.u)
        )

    __hash__ = None

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_matrix"] = None
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self.u = np.array(self.u)
        self.u.setflags(write=False)
        self.sample_indices = np.array(self.sample_indices)
        self.sample_indices.setflags(write=False)

    def __repr__(self) -> str:
        return (
            f"DownsampledConvolution(N={self.n_samples}, factor={self.factor}, "
            f"order={self.order}, offset={self.offset}, M={self.n_outputs})"
        )


def convolution_matrix(u: np.ndarray, order: int, rows=None) -> np.ndarray:
    """Matrix ``T[r, i] = u[rows[r] - i]`` (zero for negative indices), ``i < order``.

    With ``rows = 0..N-1`` this maps FIR coefficients to the fast-rate output
    from rest; ``order`` may exceed ``len(u)``.

    Examples
    --------
    >>> convolution_matrix(np.array([1.0, 2.0]), 3)
    array([[1., 0., 0.],
           [2., 1., 0.]])
    """
    u = np.asarray(u, dtype=float)
    rows = np.arange(u.shape[0]) if rows is None else np.asarray(rows)
    padded = np.concatenate([np.zeros(order - 1), u])
    index = rows[:, None] - np.arange(order)[None, :] + order - 1
    return padded[index]


def _symmetrize(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A + A.T)
