"""The observation: a downsampled convolution with the input (eq. 8).

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
from numpy.lib.stride_tricks import sliding_window_view

from gpmultirate.observations.base import Observation, UniformSampling
from gpmultirate.observations.gram import extended_input, uniform_gram
from gpmultirate.validation import check_int, check_signal

__all__ = ["DownsampledConvolution", "convolution_matrix", "regressor_rows"]


class DownsampledConvolution(Observation):
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

    #: a model file holds the input, the factor and the offset (format version 1)
    file_layout = "downsampled"

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
    def slow_factor(self) -> int:
        """The ratio of the fast to the slow sample rate, ``F``."""
        return self.factor

    @property
    def uniform_sampling(self) -> UniformSampling:
        """The input, factor and offset: the samples are uniformly spaced."""
        return UniformSampling(self.u, self.factor, self.offset, self.n_outputs)

    @property
    def matrix(self) -> np.ndarray:
        """The regressor ``Phi`` of shape ``(M, P)`` (built once, read-only)."""
        if self._matrix is None:
            matrix = convolution_matrix(self.u, self.order, self.sample_indices)
            matrix.setflags(write=False)
            self._matrix = matrix
        return self._matrix

    def regressor_view(self) -> np.ndarray:
        """Read-only strided view equal to :attr:`matrix` (no copy)."""
        return regressor_rows(self.u, self.order, self.sample_indices, view=True)

    def regressor_rows(self, start: int, stop: int) -> np.ndarray:
        """Rows ``start..stop-1`` of ``Phi``, without forming the rest."""
        if self._matrix is not None:
            return self._matrix[start:stop]
        return regressor_rows(self.u, self.order, self.sample_indices[start:stop])

    def structured_gram(self, y=None):
        """``Phi^T Phi`` and ``Phi^T y`` by FFT: ``O(F N log N + P^2)`` (see :mod:`~gpmultirate.observations.gram`)."""
        return uniform_gram(
            extended_input(self.u, self.order)[None], self.offset, self.factor,
            self.n_outputs, self.order, y,
        )

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


def regressor_rows(u: np.ndarray, order: int, rows, view: bool = False,
                   periodic: bool = False) -> np.ndarray:
    """Rows of the convolution regressor: ``T[r, i] = u[rows[r] - i]`` (zero before the record).

    The one place where the regressor of eq. (8) is built.  Row ``r`` is a
    window of the zero-padded input ending at ``u[rows[r]]``, read backwards.

    Parameters
    ----------
    u : ndarray of shape (N,)
        The input.
    order : int
        ``P``, the number of lags ``0..P-1``; may exceed ``N``.
    rows : array-like of int
        Fast-sample indices ``n`` in ``0..N-1``.
    view : bool, default=False
        With ``rows`` a uniformly spaced increasing sequence, return a
        read-only strided view of the input instead of a new array.
    periodic : bool, default=False
        ``u`` is one period of a periodic input: ``u[n - i]`` is
        ``u[(n - i) mod N]`` instead of zero for ``n < i``.

    Returns
    -------
    ndarray of shape (len(rows), order)

    Examples
    --------
    >>> regressor_rows(np.array([1.0, 2.0, 3.0]), 2, [0, 2])
    array([[1., 0.],
           [3., 2.]])
    """
    u = np.asarray(u, dtype=float)
    rows = np.asarray(rows)
    if periodic:
        padded = u[np.arange(-(order - 1), u.shape[0]) % u.shape[0]]
        return sliding_window_view(padded, order)[:, ::-1][rows]
    if view and rows.shape[0] > 1:
        step = int(rows[1] - rows[0])
        # window q of the reversed, padded input is u(N-1-q), u(N-2-q), ...;
        # fast sample n is window N-1-n, so the rows run backwards in q
        reversed_padded = np.concatenate([u[::-1], np.zeros(order - 1)])
        windows = sliding_window_view(reversed_padded, order)
        first = u.shape[0] - 1 - int(rows[0])
        last = u.shape[0] - 1 - int(rows[-1])
        return windows[first : (last - 1 if last > 0 else None) : -step]
    padded = np.concatenate([np.zeros(order - 1), u])
    windows = sliding_window_view(padded, order)[:, ::-1]  # window n ends at u[n]
    return windows[rows]


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
    return regressor_rows(u, order, rows)
