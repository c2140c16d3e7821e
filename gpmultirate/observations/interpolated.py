r"""Readings between the ticks of a long record, by interpolating the response in lag.

A reading at ``n + d`` (``n`` a fast tick, ``0 <= d < 1``) sees the impulse
response at the lags ``k + d``.  Interpolating it from the integer lags,

.. math::

    g(k + d) \approx \sum_s w_s(d) \, g(k + s),

with the Lagrange weights ``w_s`` of the nodes ``s`` (by default the twelve
``-5 .. 6``; four, ``-1 .. 2``, are the cubic, two, ``0, 1``, the linear
interpolation), makes the reading a row on the integer lags.  Away from the
ends of the lags every lag takes the same nodes, and the row is the
combination ``sum_s w_s(d) phi_{n+s}`` of the fast regressor rows of the
ticks around the instant.  At the ends: the response is zero at negative
lags (it is causal, so the nodes below lag 0 read zeros), and it is not
read beyond ``P - 1`` (the order cuts it, so the nodes of the lags near
``P - 1`` stop there: across the cut the zeros would make the
interpolation ring); a reading at ``n + d`` sees no input after ``n``.
Those lags' entries are formed lag by lag.  An exposure averages rows over
the quadrature points of its window (exact for the interpolant, a
polynomial on each piece between ticks).  :class:`InterpolatedConvolution`
is that regressor: an ordinary observation on the integer lags, so the
long-record reduction (the ``P x P`` parameter space) and every route of
the integer-lag observations apply unchanged.

The remainder ``g(k + d) - sum_s w_s(d) g(k + s)`` is left out of the
model: it enters as extra noise, absorbed by the tuned noise level.  It is
small where the response is smooth on the scale of a fast period, and
large where it has content near the fast Nyquist frequency (no
interpolation from the integer lags sees that); its size is measured in
:doc:`/cameras` against the exact readings, and :func:`interpolation_error`
estimates it for a fitted response.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.linalg import blas

from gpmultirate.kernels.hold import HOLD_POINTS, lagrange_weights, stencil
from gpmultirate.observations.base import Observation
from gpmultirate.observations.gram import extended_input

__all__ = ["DEFAULT_POINTS", "InterpolatedConvolution", "interpolation_error",
           "lagrange_weights", "stencil"]

#: the interpolation nodes of a reading by default: the hold's (a polynomial of degree eleven)
DEFAULT_POINTS = HOLD_POINTS
#: quadrature points whose entries at the edge lags are formed at a time (a 100 s record
#: read at 500 Hz with an exposure has 4.8 million: 0.9 GB of them at once)
_POINT_CHUNK = 2**16


class InterpolatedConvolution(Observation):
    """The readings of a :class:`~gpmultirate.observations.TimedConvolution` on the integer lags.

    Each reading's row is the interpolation of the fast regressor rows
    around its instants (see the module); the model leaves out the
    response's deviation from its interpolation between the integer lags.

    Parameters
    ----------
    timed : TimedConvolution
        The readings (records, exposure, latency, initial conditions).
    points : int, default=DEFAULT_POINTS
        The number of integer lags each value between them is interpolated
        from (even: as many on each side; 2 is the linear, 4 the cubic
        interpolation).  The nodes are the same at every tick of a record: the input
        before it is zero (or periodic), and none after the reading's tick is read.

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

    # the model is fitted on the integer lags but read between them; a model file holds
    # the timed readings it interpolates (:attr:`records`)
    between_ticks = True
    file_layout = "timed"

    def __init__(self, timed, points: int = DEFAULT_POINTS):
        nodes = stencil(points)
        # readings at their own instants (the TimedConvolution, which imports this module)
        if not (isinstance(timed, Observation) and hasattr(timed, "point_offsets")):
            raise ValueError(f"timed must be a TimedConvolution; got {type(timed).__name__}")
        self.points = int(points)
        self.timed = timed
        self.order = timed.order
        self.n_inputs = timed.n_inputs
        self.n_outputs = timed.n_outputs
        self.sample_times = timed.sample_times
        self.exposure, self.latency = timed.exposure, timed.latency
        self.initial_conditions = timed.initial_conditions
        parts = timed._parts
        lengths = np.array([part._inputs.shape[0] for part in parts])
        if lengths.min() < points:
            raise ValueError(f"every record must have at least points={points} fast samples; "
                             f"the shortest has {int(lengths.min())}")
        P = self.order
        record, ticks, offsets = timed._record, timed._ticks.copy(), timed._offsets
        before = ticks < 0  # an exposure window reaching before the record
        periodic = self.initial_conditions == "periodic"
        if periodic:
            ticks[before] += lengths[record[before]]  # the input repeats before the record
        weights = timed._weights.copy()
        if not periodic:
            weights[before] = 0.0  # the output is zero before a record that starts at rest
            ticks[before] = 0
        # away from the ends of the lags, every lag k takes the same nodes k + s: the
        # reading is the combination sum_s w_s(d) phi_{n+s} of the fast rows of the ticks
        # n + s (rows of ticks outside the record from the input padded: zero after it)
        self._pad = (1 - nodes[0], nodes[-1])  # ticks before and after a record
        padded = lengths + sum(self._pad)
        starts = np.concatenate([[0], np.cumsum(padded)])
        columns = (starts[record] + self._pad[0] + ticks)[:, None] + nodes[None, :]
        combination = lagrange_weights(nodes, offsets) * weights[:, None]
        self._combination = sparse.csr_matrix(
            (combination.reshape(-1), (np.repeat(timed._reading, points), columns.reshape(-1))),
            shape=(self.n_outputs, int(starts[-1])),
        )
        self._combination.sum_duplicates()
        self._starts = starts
        # the lags near 0 and P - 1, formed lag by lag: the response is zero at negative lags
        # (causal) but not read beyond P - 1 (the order cuts it), so the nodes of the
        # lags k near P - 1 are cut to those up to P - 1, and no input after n is read
        edge = min(points, P)
        self._edge_lags = np.unique(np.r_[np.arange(edge), np.arange(max(P - edge, 0), P)])
        inside = np.full(P, -1)
        inside[self._edge_lags] = np.arange(self._edge_lags.shape[0])
        near = np.unique(np.r_[np.arange(min(edge + points, P)),
                               np.arange(max(P - edge - points, 0), P)])
        self._edges = np.zeros((self.n_outputs, self._edge_lags.shape[0], self.n_inputs))
        for start in range(0, offsets.shape[0], _POINT_CHUNK):
            chunk = slice(start, start + _POINT_CHUNK)
            self._add_edges(parts, lengths, record[chunk], ticks[chunk], offsets[chunk],
                            weights[chunk], timed._reading[chunk], near, inside, nodes)
        self._matrix = None
        self._gram = None

    def _add_edges(self, parts, lengths, record, ticks, offsets, weights, reading, near,
                   inside, nodes):
        """Add some points' entries at the edge lags to their readings' (``self._edges``)."""
        P = self.order
        periodic = self.initial_conditions == "periodic"
        # by edge lag, then point: each lag's update is one contiguous array
        per_lag = np.zeros((self._edge_lags.shape[0], offsets.shape[0], self.n_inputs))
        inputs = np.zeros((offsets.shape[0], self.n_inputs))
        weights_of = {}  # the lags of most k are the whole stencil: their weights are shared
        for k in near:
            lags = np.arange(k + nodes[0], min(k + nodes[-1], P - 1) + 1)
            key = lags.shape[0]
            if key not in weights_of:
                weights_of[key] = np.ascontiguousarray(
                    (lagrange_weights(lags - k, offsets) * weights[:, None]).T)
            first = int(np.searchsorted(lags, 0))  # the response is zero before lag 0
            w, lags = weights_of[key][first:], lags[first:]
            for r, part in enumerate(parts):
                mine = record == r
                index = ticks[mine] - k
                values = np.zeros((index.shape[0], self.n_inputs))
                seen = (index >= 0) | periodic
                values[seen] = part._inputs[index[seen] % lengths[r]]
                inputs[mine] = values
            for j, lag in enumerate(lags):
                if inside[lag] >= 0:
                    per_lag[inside[lag]] += w[j][:, None] * inputs
        np.add.at(self._edges, reading, per_lag.transpose(1, 0, 2))

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

    def _extended(self, part) -> list:
        """Each input of a record over its padded ticks, lags before them included.

        ``x[n - k]`` of tick ``n`` and lag ``k < P`` is entry ``n + P - 1 - k``.
        """
        periodic = part.initial_conditions == "periodic"
        before, after = self._pad
        return [np.concatenate([extended_input(part._inputs[:, k], self.order + before,
                                               periodic), np.zeros(after)])
                for k in range(self.n_inputs)]

    def regressor_rows(self, start: int, stop: int) -> np.ndarray:
        """Rows ``start..stop-1`` of the interpolated regressor.

        A reading's row is ``sum_n c_n x[n - k]`` over the few ticks ``n``
        its combination holds: one correlation of those taps with the input
        around them, ``O(P S)`` for ``S`` ticks (about 15 at the default
        nodes and a short exposure) without any ``(S, P)`` gather.
        """
        block = self._combination[start:stop]
        P = self.order
        rows = np.zeros((block.shape[0], self.n_inputs * P))
        indptr, columns, values = block.indptr, block.indices, block.data
        filled = np.flatnonzero(np.diff(indptr))
        if filled.size:
            firsts = columns[indptr[filled]]
            record = np.searchsorted(self._starts, firsts, side="right") - 1
            inputs = {}
            for m, r in zip(filled.tolist(), record.tolist()):
                if r not in inputs:
                    inputs[r] = self._extended(self.timed._parts[r])
                ticks = columns[indptr[m]:indptr[m + 1]] - self._starts[r]
                first = int(ticks.min())
                taps = np.zeros(int(ticks.max()) - first + 1)
                np.add.at(taps, ticks - first, values[indptr[m]:indptr[m + 1]])
                for k, extended in enumerate(inputs[r]):
                    window = extended[first:first + P - 1 + taps.shape[0]]
                    rows[m, k * P:(k + 1) * P] = np.correlate(window, taps, "valid")[::-1]
        for k in range(self.n_inputs):
            rows[:, k * P + self._edge_lags] = self._edges[start:stop, :, k]
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
        return f"InterpolatedConvolution({self.timed!r}, points={self.points})"

    def fitted_readings(self, posterior, y: np.ndarray, noise_level: float) -> list:
        """The posterior mean of the readings by the interpolation, one array per record."""
        return self.split_by_record(self.matvec(posterior.coef))

    def readings_model(self, readings):
        """New ``readings`` as this fit modelled its own: interpolated on the integer lags.

        Readings of a record shorter than the interpolation's nodes are modelled exactly.
        """
        if readings.n_samples < self.points:
            return readings
        return InterpolatedConvolution(readings, self.points)

    def interpolation_check(self, coef) -> float | None:
        """:func:`interpolation_error` of the response ``coef`` (None when it cannot say)."""
        return interpolation_error(self, coef)


def interpolation_error(observation: InterpolatedConvolution, coef,
                        max_readings: int = 256) -> float | None:
    """The rms error of the interpolated readings of ``coef``, estimated.

    The readings of the response ``coef`` (on the integer lags) by
    ``observation``'s interpolation against those of its band-limited
    interpolation (the lags' values shifted by a phase in frequency, exact
    for a response without content at and above the fast Nyquist
    frequency), both of ``coef`` tapered to zero over its last lags (where
    the order cuts it), over up to ``max_readings`` readings of the first
    record, from its middle.  Measured against responses known at every
    real lag (``tests/test_interpolated.py``): within 15 % of the true
    error where that comes from content above a quarter of the fast
    sampling frequency (where it is large); below, where the error is
    small and comes mostly from the response's start at lag 0, down to a
    quarter of it.

    Parameters
    ----------
    observation : InterpolatedConvolution
    coef : array-like of shape (n_inputs * order,)
        The response on the integer lags (a posterior mean, say).
    max_readings : int, default=256

    Returns
    -------
    float or None
        None for an order below twice the interpolation's nodes.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.observations import TimedConvolution
    >>> u = np.random.default_rng(0).standard_normal(400)
    >>> readings = InterpolatedConvolution(TimedConvolution(u, np.arange(50, 400, 3.5), 40))
    >>> smooth = np.sin(np.pi * np.arange(40) / 40) ** 4  # smooth on a fast period
    >>> rough = np.cos(2.5 * np.arange(40))  # 0.4 cycles per fast period
    >>> bool(interpolation_error(readings, smooth) < 1e-3 < 1.0 < interpolation_error(readings, rough))
    True
    """
    P, n_inputs = observation.order, observation.n_inputs
    coef = np.asarray(coef, dtype=float).reshape(n_inputs, P)
    reach = observation.points
    if P < 2 * reach:
        return None
    taper = np.ones(P)
    taper[P - reach:] = 0.5 * (1.0 + np.cos(np.pi * np.arange(1, reach + 1) / (reach + 1)))
    coef = coef * taper
    # some readings of the first record, from its middle
    record = observation.timed.records[0]
    times = record.sample_times
    middle = max(0, (times.shape[0] - max_readings) // 2)
    times = times[middle:middle + max_readings]
    readings = type(record)(record.u, times, P, exposure=observation.exposure,
                                latency=observation.latency,
                                initial_conditions=observation.initial_conditions)
    interpolated = InterpolatedConvolution(readings, observation.points).matrix @ coef.reshape(-1)
    n_fft = 1 << int(np.ceil(np.log2(2 * P)))
    frequencies = np.fft.rfftfreq(n_fft)
    reference = np.zeros(times.shape[0])
    for k in range(n_inputs):
        spectrum = np.fft.rfft(coef[k], n_fft)

        def band_limited(x, spectrum=spectrum):
            x = x.reshape(-1, P)  # rows: the lags k + d of one point
            shift = np.exp(2j * np.pi * frequencies[None, :] * x[:, :1])
            return np.fft.irfft(spectrum[None, :] * shift, n_fft)[:, :P].reshape(-1, 1)

        reference += readings.lag_functionals(band_limited, input=k)[:, 0]
    return float(np.sqrt(np.mean((interpolated - reference) ** 2)))
