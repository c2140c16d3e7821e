r"""Readings between the ticks of a long record, by interpolating the response in lag.

A reading at ``n + d`` (``n`` a fast tick, ``0 <= d < 1``) sees the impulse
response at the lags ``k + d``.  Interpolating it from the integer lags,

.. math::

    g(k + d) \approx \sum_s w_s(d) \, g(k + s),

with the Lagrange weights ``w_s`` of the nodes ``s`` (``-1, 0, 1, 2``, cubic,
or ``0, 1``, linear), makes the reading a combination of the fast samples
``y[n + s] = phi_{n+s} g``: a row on the integer lags,
``sum_s w_s(d) phi_{n+s}``.  An exposure averages such rows over the
quadrature points of its window (exact for the interpolant, a polynomial on
each piece between ticks).  A reading at ``n + d`` sees no input after
``n``: the entries of the later ticks' rows that do (their lags below the
tick's distance) are taken out.  :class:`InterpolatedConvolution` is that
regressor: an ordinary observation on the integer lags, so the
long-record reduction (the ``P x P`` parameter space) and every route of
the integer-lag observations apply unchanged.

The remainder ``g(k + d) - sum_s w_s(d) g(k + s)`` is left out of the
model: it enters as extra noise, absorbed by the tuned noise level.  It is
small where the response is smooth on the scale of a fast period (cubic:
fourth order in the fast sample time); its effect on a fit is measured in
:doc:`/cameras` against the exact observation
(:class:`~gpmultirate.observations.TimedConvolution`).  Near the record's
ends the stencil moves inside the record (no input outside it is read).
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy import sparse
from scipy.linalg import blas

from gpmultirate.observations.base import Observation
from gpmultirate.observations.gram import extended_input
from gpmultirate.observations.timed import TimedConvolution

__all__ = ["INTERPOLATIONS", "InterpolatedConvolution", "lagrange_weights"]

#: the interpolation nodes of each kind, relative to the tick before the instant
INTERPOLATIONS = {"linear": np.array([0, 1]), "cubic": np.array([-1, 0, 1, 2])}


def lagrange_weights(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The Lagrange weights of integer ``nodes`` at the points ``x``: ``(len(x), len(nodes))``.

    Examples
    --------
    >>> w = lagrange_weights(np.array([-1, 0, 1, 2]), np.array([0.5]))
    >>> w * 16
    array([[-1.,  9.,  9., -1.]])
    """
    nodes = np.asarray(nodes, dtype=float)
    x = np.asarray(x, dtype=float)
    out = np.ones((x.shape[0], nodes.shape[0]))
    for j, node in enumerate(nodes):
        for other in nodes:
            if other != node:
                out[:, j] *= (x - other) / (node - other)
    return out


class InterpolatedConvolution(Observation):
    """The readings of a :class:`~gpmultirate.observations.TimedConvolution` on the integer lags.

    Each reading's row is the interpolation of the fast regressor rows
    around its instants (see the module); the model leaves out the
    response's deviation from its interpolation between the integer lags.

    Parameters
    ----------
    timed : TimedConvolution
        The readings (records, exposure, latency, initial conditions).
    interpolation : {"cubic", "linear"}, default="cubic"

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.observations import TimedConvolution
    >>> u = np.random.default_rng(0).standard_normal(40)
    >>> timed = TimedConvolution(u, [10.5, 20.25, 30.0], order=6)
    >>> interpolated = InterpolatedConvolution(timed)
    >>> interpolated.matrix.shape
    (3, 6)
    >>> g = np.sin(np.pi * np.arange(6.0) / 6) ** 2  # smooth, zero at lag 0
    >>> exact = [sum(u[j] * np.sin(np.pi * (t - j) / 6) ** 2 for j in range(40) if 0 <= t - j < 6)
    ...          for t in (10.5, 20.25, 30.0)]
    >>> bool(np.allclose(interpolated.matrix @ g, exact, atol=0.1))
    True
    """

    def __init__(self, timed, interpolation: str = "cubic"):
        if interpolation not in INTERPOLATIONS:
            raise ValueError(
                f"interpolation must be one of {sorted(INTERPOLATIONS)}; got {interpolation!r}")
        if not isinstance(timed, TimedConvolution):
            raise ValueError(f"timed must be a TimedConvolution; got {type(timed).__name__}")
        self.interpolation = interpolation
        self.timed = timed
        self.order = timed.order
        self.n_inputs = timed.n_inputs
        self.n_outputs = timed.n_outputs
        self.sample_times = timed.sample_times
        self.exposure, self.latency = timed.exposure, timed.latency
        self.initial_conditions = timed.initial_conditions
        nodes = INTERPOLATIONS[interpolation]
        parts = timed._parts
        lengths = np.array([part._inputs.shape[0] for part in parts])
        # the stencil's first tick, kept inside its record
        record, ticks = timed._record, timed._ticks.copy()
        before = ticks < 0  # an exposure window reaching before the record
        if self.initial_conditions == "periodic":
            ticks[before] += lengths[record[before]]  # the input repeats before the record
        first = np.clip(ticks + nodes[0], 0, np.maximum(lengths[record] - nodes.shape[0], 0))
        position = ticks + timed._offsets - first  # the instant, from the stencil's first tick
        weights = lagrange_weights(nodes - nodes[0], position) * timed._weights[:, None]
        if self.initial_conditions != "periodic":
            weights[before] = 0.0  # the output is zero before a record that starts at rest
        starts = np.concatenate([[0], np.cumsum(lengths)])
        columns = (starts[record] + first)[:, None] + np.arange(nodes.shape[0])[None, :]
        readings = np.repeat(timed._reading, nodes.shape[0])
        # (M, ticks of all records): the weight of each fast regressor row in each reading
        self._combination = sparse.csr_matrix(
            (weights.reshape(-1), (readings, columns.reshape(-1))),
            shape=(self.n_outputs, int(starts[-1])),
        )
        self._combination.sum_duplicates()
        self._starts = starts
        # causality: a reading at n + d sees no input after n, but the rows of the
        # stencil's later ticks n + s do (their lags k < s): those entries are taken out
        shift = first[:, None] + np.arange(nodes.shape[0])[None, :] - ticks[:, None]
        width = max(int(shift.max()), 0) if shift.size else 0
        correction = np.zeros((self.n_outputs, width, self.n_inputs))
        for k in range(width):
            late = shift > k  # the stencil's tick tau = n + s sees u[tau - k], after n
            point, slot = np.nonzero(late)
            tau = first[point] + slot
            for r, part in enumerate(parts):
                mine = record[point] == r
                values = part._inputs[tau[mine] - k] * weights[point[mine], slot[mine], None]
                np.add.at(correction[:, k], timed._reading[point[mine]], values)
        self._correction = correction
        self._matrix = None
        self._gram = None

    @property
    def records(self) -> list:
        """The timed records this observation interpolates."""
        return self.timed.records

    @property
    def u(self):
        """The fast-rate input of the first record."""
        return self.timed.u

    @property
    def n_samples(self) -> int:
        """The length of the longest record."""
        return self.timed.n_samples

    @property
    def slow_factor(self) -> int:
        """The ratio of the fast to the slow rate, as the timed readings give it."""
        return self.timed.slow_factor

    def _windows(self, part):
        """The fast regressor rows of a record as a view: row ``n`` is ``x[n - k]``, ``k < P``."""
        periodic = part.initial_conditions == "periodic"
        out = []
        for k in range(self.n_inputs):
            extended = extended_input(part._inputs[:, k], self.order, periodic)
            out.append(sliding_window_view(extended, self.order)[:, ::-1])
        return out

    def regressor_rows(self, start: int, stop: int) -> np.ndarray:
        """Rows ``start..stop-1`` of the interpolated regressor."""
        block = self._combination[start:stop].tocoo()
        P = self.order
        rows = np.zeros((block.shape[0], self.n_inputs * P))
        record = np.searchsorted(self._starts, block.col, side="right") - 1
        for r, part in enumerate(self.timed._parts):
            mine = record == r
            if not np.any(mine):
                continue
            tick = block.col[mine] - self._starts[r]
            target, weight = block.row[mine], block.data[mine]
            for k, windows in enumerate(self._windows(part)):
                # one slot per entry of a reading: add the weighted fast rows
                by_reading = np.argsort(target, kind="stable")
                target_k, tick_k, weight_k = (target[by_reading], tick[by_reading],
                                              weight[by_reading])
                slot = np.arange(target_k.shape[0]) - np.searchsorted(target_k, target_k)
                for s in range(int(slot.max()) + 1 if slot.size else 0):
                    here = slot == s
                    rows[target_k[here], k * P:(k + 1) * P] += (
                        weight_k[here, None] * windows[tick_k[here]])
        correction = self._correction[start:stop]
        width = min(correction.shape[1], P)
        for k in range(self.n_inputs):
            rows[:, k * P:k * P + width] -= correction[:, :width, k]
        return rows

    @property
    def matrix(self) -> np.ndarray:
        """The whole ``(M, n_inputs P)`` regressor (kept; long records read it by blocks)."""
        if self._matrix is None:
            matrix = self.regressor_rows(0, self.n_outputs)
            matrix.setflags(write=False)
            self._matrix = matrix
        return self._matrix

    def structured_gram(self, y=None):
        """``Phi^T Phi`` and ``Phi^T y`` from blocks of rows by symmetric rank-k updates.

        ``O(M P^2 / 2)``, half the flops of the QR route; the reduction
        checks its conditioning and falls back to QR.
        """
        P = self.n_coefficients
        block = max(2 * P, 1024)
        gram = np.zeros((P, P), order="F")
        projection = None if y is None else np.zeros(P)
        for start in range(0, self.n_outputs, block):
            rows = self.regressor_rows(start, start + block)
            gram = blas.dsyrk(1.0, rows, beta=1.0, c=gram, trans=1, lower=0, overwrite_c=1)
            if y is not None:
                projection += rows.T @ y[start:start + block]
        upper = np.triu(gram)
        gram = upper + np.triu(upper, 1).T
        return gram, projection

    def __repr__(self) -> str:
        return (f"InterpolatedConvolution({self.timed!r}, "
                f"interpolation={self.interpolation!r})")
