r"""Slow samples at their own instants: exposure, latency, and instants between the ticks.

The input is held, ``u[j]`` acting over ``[j, j + 1)`` (time in fast
sample periods), so the output at any real time ``t`` is

.. math::

    y(t) = \sum_j u[j] \, g(t - j), \qquad t - j \in [0, P),

with ``g`` the Gaussian process over continuous lag.  A sensor with
exposure ``E`` and latency ``L`` reports, at its stamp ``t``,
``(1/E) * integral of y over [t - L - E, t - L]`` (``y(t - L)`` when
``E = 0``).  Every reading is a linear functional of ``g``, so the evidence,
the posterior and its bands stay exact Gaussian computations;
:class:`TimedConvolution` is that observation.

The covariance of the readings is formed by the kernel's terms for readings
at their own instants: the walker (:func:`~gpmultirate.kernels.observe`)
asks this observation for each leaf, and the observation asks a structured
kernel for its :meth:`~gpmultirate.kernels.StructuredKernel.observed_at_instants`:

* TC, DC and SS by their rows on the integer lags (:meth:`TimedConvolution.on_integer_lags`:
  between integer lags these kernels are the hold's interpolation of their
  integer values) plus the bridge (:meth:`TimedConvolution.bridge_rows`,
  :mod:`gpmultirate.kernels.hold`), every route of the integer lags applying
  to the first;
* PK and constants, of rank two and one at any lag, by their bases
  (:mod:`gpmultirate.kernels.instants`);
* sums and constant multiples through the walker's own terms;
* independent inputs (:class:`~gpmultirate.kernels.PerInputKernel`) as the
  sum of each input's term on that input's readings (:meth:`TimedConvolution.input_block`);
* any other kernel densely, from the kernel at the real lags, grouped by
  the distinct offsets: ``O(G^2 P^2)`` kernel entries for ``G`` distinct
  offsets (as cheap as on the ticks for ``G = 1``, meant for small problems
  otherwise).

The exposure integral is Gauss-Legendre quadrature with
:data:`QUADRATURE_NODES` nodes on each piece of the window between fast
ticks, where the output is smooth: exact for TC, DC and SS (a polynomial and
a sine on each piece), PK and constants; the dense route's error is below
``1e-8`` for smooth kernels (RBF).
"""

from __future__ import annotations

import copy
import numbers

import numpy as np
from scipy import linalg, signal, sparse

from gpmultirate.exceptions import MemoryLimitError
from gpmultirate.kernels.instants import BLOCK_ENTRIES, ConstantTimedTerm, DenseTimedTerm
from gpmultirate.kernels.hold import HOLD_POINTS, bridge_shape, mode_start
from gpmultirate.kernels.structure import ObservedTerm, observe
from gpmultirate.memory import available_memory
from gpmultirate.observations.base import Observation
from gpmultirate.observations.convolution import regressor_rows
from gpmultirate.observations.experiment import Experiment, check_records, is_record_list
from gpmultirate.observations.interpolated import InterpolatedConvolution
from gpmultirate.observations.sampled import check_initial_conditions
from gpmultirate.validation import as_real_array, check_inputs, check_int

__all__ = [
    "QUADRATURE_NODES", "TimedConvolution", "build_timed_experiment", "check_sample_times",
    "check_duration", "check_windows", "on_the_ticks", "predict_readings",
]

#: Gauss-Legendre nodes on each piece of an exposure window between two ticks
QUADRATURE_NODES = 16
# the floats a quadrature point holds while the readings are formed: its reading, instant,
# weight, tick and offset, and its weights on the integer lags (the twelve of the stencil
# and, near the order's ends, up to 48 more)
_NUMBERS_PER_POINT = 64


def check_sample_times(times, n_samples: int, name: str = "sample_times") -> np.ndarray:
    """Return strictly increasing real instants in ``[0, n_samples)`` (fast sample periods).

    Examples
    --------
    >>> check_sample_times([0.0, 2.5, 4.2], 6)
    array([0. , 2.5, 4.2])
    """
    arr = as_real_array(times, name)
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-D array of instants; got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    if arr.min() < 0 or arr.max() >= n_samples:
        raise ValueError(
            f"{name} must lie in [0, {n_samples}) (the record of u, in fast sample periods); "
            f"got values from {arr.min():g} to {arr.max():g}"
        )
    if np.any(np.diff(arr) <= 0):
        raise ValueError(f"{name} must be strictly increasing")
    return arr.copy()


def check_duration(value, name: str) -> float:
    """``value`` as a non-negative finite float; a string or a bool is not a duration.

    Examples
    --------
    >>> check_duration(2, "exposure")
    2.0
    >>> check_duration("0.5", "exposure")
    Traceback (most recent call last):
    ...
    ValueError: exposure must be a real number; got '0.5' (a str)
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Real, np.number)):
        raise ValueError(f"{name} must be a real number; got {value!r} "
                         f"(a {type(value).__name__})")
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a non-negative real number; got {value!r}") from None
    if not np.isfinite(value) or value < 0:
        raise ValueError(f"{name} must be a non-negative real number; got {value!r}")
    return value


def check_windows(times, n_samples: int, exposure: float, latency: float,
                  nodes: int = QUADRATURE_NODES) -> None:
    """Refuse an ``exposure`` or ``latency`` that leaves no reading inside the record.

    The window of the reading stamped ``t`` is ``[t - L - E, t - L]``: a
    window longer than the record (``E > N``) or a latency that puts every
    window's end before the record starts is a ``ValueError`` naming the
    parameter.  Checked from the stamps alone, before any array of the
    windows' points is formed; the points of the windows' pieces between
    ticks, with their rows' interpolation weights, are counted against the
    available memory (no pair of pieces is formed: the readings are rows
    on the integer lags, whose ``M x M`` and ``M x P`` arrays the fit's own
    memory estimate counts).

    Examples
    --------
    >>> check_windows(np.array([3.0, 6.0]), 8, exposure=0.5, latency=1.0)
    >>> check_windows(np.array([3.0, 6.0]), 8, exposure=0.0, latency=7.0)
    Traceback (most recent call last):
    ...
    ValueError: latency must leave a reading inside the record: every reading's window ends ...
    """
    if exposure > n_samples:
        raise ValueError(
            f"exposure must not exceed the record, {n_samples} fast sample periods (a window "
            f"longer than the record); got {exposure:g}")
    if latency >= n_samples or times.size == 0 or times.max() - latency < 0:
        raise ValueError(
            f"latency must leave a reading inside the record: every reading's window ends "
            f"before the record starts (the latest stamp is "
            f"{times.max() if times.size else 0:g}, the record {n_samples} fast sample "
            f"periods long); got {latency:g}")
    if exposure == 0.0:
        return
    ends = times - latency
    pieces = float(np.sum(np.ceil(ends) - np.floor(ends - exposure)))
    # each node of each piece is a point with a few numbers of its own and the weights of
    # its interpolation on the integer lags (the stencil, the lags at the order's ends)
    needed = 8.0 * _NUMBERS_PER_POINT * pieces * nodes
    available = available_memory()
    if needed > available:
        raise MemoryLimitError(
            f"exposure {exposure:g} over {times.size} readings cuts their windows into "
            f"{pieces:.0f} pieces between the fast ticks, whose exact covariance needs about "
            f"{needed / 1e9:.3g} GB but {available / 1e9:.4g} GB are available: use a shorter "
            "exposure or fewer readings")


def _window_points(times, exposure: float, latency: float, nodes: int):
    """The quadrature points of every reading: ``(reading, instant, weight)`` per point.

    Gauss-Legendre nodes on each piece of the window between ticks (one
    point per reading without exposure).
    """
    ends = times - latency
    if exposure == 0.0:
        return np.arange(times.shape[0]), ends, np.ones(times.shape[0])
    xi, w = np.polynomial.legendre.leggauss(nodes)
    readings, instants, weights = [], [], []
    for m, end in enumerate(ends):
        start = end - exposure
        cuts = np.arange(np.floor(start) + 1.0, np.ceil(end))
        edges = np.concatenate([[start], cuts[(cuts > start) & (cuts < end)], [end]])
        for low, high in zip(edges[:-1], edges[1:]):
            half = 0.5 * (high - low)
            instants.append(low + half * (xi + 1.0))
            weights.append(w * half / exposure)
            readings.append(np.full(nodes, m))
    return np.concatenate(readings), np.concatenate(instants), np.concatenate(weights)


# the largest |omega (d - c)| for which the phases of damped_spectrum are a power series: its
# terms sum to at most e^reach in size, so rounding stays within e^3 (20) units of the last place
_SERIES_REACH = 3.0


def _phase_terms(reach: float):
    """Terms of the series of ``exp(-i theta)``, ``|theta| <= reach``, to below rounding.

    The remainder after ``n`` terms is at most ``reach^n / n!`` (Taylor's,
    ``theta`` real); the series stops where that falls below ``2^-56``.
    None beyond :data:`_SERIES_REACH`.  Offsets in ``[0, 1)`` and ``omega
    <= pi`` give ``reach <= pi / 2``: 22 terms.
    """
    if not np.isfinite(reach) or reach > _SERIES_REACH:
        return None
    n, bound = 1, reach
    while bound > 2.0 ** -56:
        n += 1
        bound *= reach / n
    return n


#: rows of :meth:`TimedConvolution.unique_rows` formed at a time
_ROW_CHUNK = 256


def _lag_rows(x: np.ndarray, ticks: np.ndarray, order: int, periodic: bool) -> np.ndarray:
    """``x[n - j]`` for each tick ``n`` and lag ``j < order``: zero outside the record, or periodic.

    Examples
    --------
    >>> _lag_rows(np.array([1.0, 2.0, 3.0]), np.array([-1, 0, 2, 4]), 2, False)
    array([[0., 0.],
           [1., 0.],
           [3., 2.],
           [0., 0.]])
    >>> _lag_rows(np.array([1.0, 2.0, 3.0]), np.array([0, 4]), 3, True)
    array([[1., 3., 2.],
           [2., 1., 3.]])
    """
    extended, at = _extended(x, ticks, order, periodic)
    return regressor_rows(extended, order, at)


def _extended(x: np.ndarray, ticks: np.ndarray, order: int, periodic: bool):
    """``x`` extended over every tick asked for, and each tick's position in it.

    Periodic: one period with its last ``order - 1`` samples before it (every
    lag of a tick inside); else zeros before the record and after it, as far
    as the ticks reach (lags before the extension's start are zero).
    """
    n = x.shape[0]
    if periodic:
        return x[np.arange(-(order - 1), n) % n], np.remainder(ticks, n) + order - 1
    low, high = min(0, int(ticks.min())), max(n - 1, int(ticks.max()))
    return np.concatenate([np.zeros(-low), x, np.zeros(high - (n - 1))]), ticks - low


def _damped_sums(x: np.ndarray, ticks: np.ndarray, order: int, periodic: bool, rate: float,
                 omega: float, with_lag: bool) -> list:
    """``sum_{j < order} x[n - j] q^j`` (and ``j q^j x[n - j]``) at each tick, ``q = e^(-rate + i omega)``.

    ``x`` zero outside the record, or periodic (:func:`_extended`); by the
    recursions ``z_i = x_i + q z_(i-1)`` and ``w_i = q (z_(i-1) + w_(i-1))``
    (``w = sum_j j q^j x[i - j]``) over the extended record, the lags from
    ``order`` on taken off as ``q^order`` times the sums ``order`` ticks
    earlier.  ``rate > 0``.

    Examples
    --------
    >>> x, ticks = np.array([1.0, -2.0, 0.5, 3.0]), np.array([-1, 1, 3, 5])
    >>> q = np.exp(-0.3 + 0.7j)
    >>> direct = [sum(x[n - j] * q**j for j in range(3) if 0 <= n - j < 4) for n in ticks]
    >>> bool(np.allclose(_damped_sums(x, ticks, 3, False, 0.3, 0.7, False)[0], direct))
    True
    """
    extended, at = _extended(x, ticks, order, periodic)
    q = np.exp(-rate + 1j * omega)
    z = signal.lfilter([1.0], [1.0, -q], extended.astype(complex))
    earlier = at - order
    inside = earlier >= 0
    back = np.where(inside, earlier, 0)
    tail = q**order
    sums = [z[at] - tail * np.where(inside, z[back], 0.0)]
    if with_lag:
        w = signal.lfilter([0.0, q], [1.0, -2.0 * q, q * q], extended.astype(complex))
        sums.append(w[at] - tail * np.where(inside, w[back] + order * z[back], 0.0))
    return sums


class TimedConvolution(Observation):
    """The readings of a slow sensor at its own instants, with exposure and latency.

    Reading ``m``, stamped ``t_m`` (in fast sample periods), is
    ``(1/E) * integral of y over [t_m - L - E, t_m - L]`` with
    ``y(t) = sum_j u[j] g(t - j)`` the output of the held input (``y(t_m - L)``
    for ``E = 0``).  On the ticks without exposure it is the
    :class:`~gpmultirate.observations.SampledConvolution` of the same
    instants.  Several records are stacked with :meth:`stack`.

    Parameters
    ----------
    u : array-like of shape (N,) or (N, n_inputs)
        The fast-rate input(s).
    sample_times : array-like of shape (M,)
        Strictly increasing stamps in ``[0, N)``, in fast sample periods.
    order : int
        ``P``: the response is zero beyond lag ``P``.
    exposure : float, default=0.0
        ``E``, in fast sample periods.
    latency : float, default=0.0
        ``L``, in fast sample periods.
    initial_conditions : {"zero", "discard", "periodic"}, default="zero"
        As for :class:`~gpmultirate.observations.SampledConvolution`;
        ``"discard"`` uses the readings whose window starts at or after
        ``P - 1``.
    nodes : int, default=QUADRATURE_NODES
        Gauss-Legendre nodes per piece of an exposure window.

    Attributes
    ----------
    sample_times : ndarray
        The stamps of the used readings.
    used : ndarray of bool
        Which of the given readings are used.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate.kernels import DC, observe
    >>> from gpmultirate.observations import SampledConvolution, TimedConvolution
    >>> u = np.random.default_rng(0).standard_normal(30)
    >>> timed = TimedConvolution(u, [2.0, 5.0, 9.0], order=8)
    >>> ticks = SampledConvolution(u, [2, 5, 9], order=8)
    >>> kernel = C(2.0) * DC(0.8, 0.6)
    >>> bool(np.allclose(observe(kernel, timed).covariance(), observe(kernel, ticks).covariance()))
    True
    >>> between = TimedConvolution(u, [2.5, 5.25, 9.9], order=8, exposure=0.5, latency=0.1)
    >>> observe(kernel, between).covariance().shape
    (3, 3)
    """

    #: the covariance of the readings comes from the kernel at real lags: no reduction
    reducible = False

    has_regressor = False
    between_ticks = True
    file_layout = "timed"

    def __init__(self, u, sample_times, order: int, exposure: float = 0.0,
                 latency: float = 0.0, initial_conditions: str = "zero",
                 nodes: int = QUADRATURE_NODES):
        inputs = check_inputs(u, "u")
        n_samples = inputs.shape[0]
        self.initial_conditions = check_initial_conditions(initial_conditions)
        high = None if self.initial_conditions == "zero" else n_samples
        self.order = check_int(order, "order", low=1, high=high)
        self.exposure = check_duration(exposure, "exposure")
        self.latency = check_duration(latency, "latency")
        self.nodes = check_int(nodes, "nodes", low=1)
        given = check_sample_times(sample_times, n_samples)
        check_windows(given, n_samples, self.exposure, self.latency, self.nodes)
        reading, instant, weight = _window_points(
            given, self.exposure, self.latency, self.nodes)
        ticks = np.floor(instant).astype(np.int64)
        if self.initial_conditions == "discard":
            late = np.ones(given.shape[0], dtype=bool)
            np.logical_and.at(late, reading, ticks >= self.order - 1)
            if not np.any(late):
                raise ValueError(
                    f"initial_conditions='discard' leaves no reading: every window starts "
                    f"before order - 1 = {self.order - 1}; use a lower order or a longer record"
                )
        else:
            late = np.ones(given.shape[0], dtype=bool)
        keep = late[reading]
        renumber = np.cumsum(late) - 1
        inputs.setflags(write=False)
        self._inputs = inputs
        self.u = inputs[:, 0] if inputs.shape[1] == 1 else inputs
        self.n_inputs = inputs.shape[1]
        self.used = late
        self.used.setflags(write=False)
        self.sample_times = given[late]
        self.sample_times.setflags(write=False)
        self._stacked = None  # one record: its own part (see :attr:`_parts`)
        self._set_points(renumber[reading[keep]], ticks[keep], instant[keep] - ticks[keep],
                         weight[keep], np.zeros(int(keep.sum()), dtype=np.int64))

    @property
    def _parts(self) -> list:
        """The records of the readings: the stacked ones, or this one alone.

        Not held as ``[self]``: an observation in a reference cycle outlives
        its last use until the cyclic collector runs, and its cached rows
        with it (a pilot's 0.6 GB beside the next fit on a camera log).
        """
        return [self] if self._stacked is None else self._stacked

    def _set_points(self, reading, ticks, offsets, weights, record):
        self._reading, self._ticks, self._offsets = reading, ticks, offsets
        self._weights, self._record = weights, record
        self.n_outputs = int(reading.max()) + 1 if reading.size else 0
        # one regressor row per distinct (record, tick): the points of a window share them
        keys = record * (int(ticks.max()) + 2 + self.order) + ticks if ticks.size else ticks
        _, first, self._row_id = np.unique(keys, return_index=True, return_inverse=True)
        self._row_id = self._row_id.reshape(-1)
        self._unique = (record[first], ticks[first])
        self._rows = None
        self._gather = None

    @classmethod
    def stack(cls, records) -> "TimedConvolution":
        """Several records of one system, their readings concatenated in order.

        Parameters
        ----------
        records : sequence of TimedConvolution
            Equal ``order``, ``n_inputs`` and ``initial_conditions``.
        """
        records = list(records)
        if not records:
            raise ValueError("records must hold at least one observation")
        first = records[0]
        for i, record in enumerate(records):
            if (record.order, record.n_inputs, record.initial_conditions) != (
                first.order, first.n_inputs, first.initial_conditions
            ):
                raise ValueError(
                    f"record {i} differs from record 0 in order, inputs or initial conditions"
                )
        if len(records) == 1:
            return first
        stacked = cls.__new__(cls)
        stacked.__dict__.update(
            order=first.order, n_inputs=first.n_inputs, initial_conditions=first.initial_conditions,
            exposure=first.exposure, latency=first.latency, nodes=first.nodes,
        )
        stacked._stacked = [part for record in records for part in record._parts]
        stacked.u, stacked._inputs = first.u, first._inputs
        stacked.used = np.concatenate([r.used for r in records])
        stacked.sample_times = np.concatenate([r.sample_times for r in records])
        shift, part_shift = 0, 0
        points = []
        for record in records:
            points.append((record._reading + shift, record._ticks, record._offsets,
                           record._weights, record._record + part_shift))
            shift += record.n_outputs
            part_shift += len(record._parts)
        stacked._set_points(*(np.concatenate(column) for column in zip(*points)))
        return stacked

    # ------------------------------------------------------------ the data
    @property
    def records(self) -> list:
        """The stacked records (each a TimedConvolution)."""
        return list(self._parts)

    @property
    def n_samples(self) -> int:
        """The length of the longest record."""
        return max(part._inputs.shape[0] for part in self._parts)

    @property
    def slow_factor(self) -> int:
        """The median spacing of the stamps, rounded: the ratio of the fast to the slow rate."""
        spacing = np.concatenate([np.diff(part.sample_times) for part in self._parts])
        return max(1, int(round(float(np.median(spacing))))) if spacing.size else 1

    @property
    def n_points(self) -> int:
        """The number of instants the readings are formed from (quadrature nodes)."""
        return self._offsets.shape[0]

    # the points, as the kernels' terms read them (:mod:`gpmultirate.kernels.instants`)
    @property
    def point_offsets(self) -> np.ndarray:
        """Each point's offset from its tick, in ``[0, 1)``: shape ``(n_points,)``."""
        return self._offsets

    @property
    def point_readings(self) -> np.ndarray:
        """The reading each point belongs to: shape ``(n_points,)``."""
        return self._reading

    @property
    def point_weights(self) -> np.ndarray:
        """Each point's quadrature weight in its reading (1 without exposure)."""
        return self._weights

    @property
    def point_row_ids(self) -> np.ndarray:
        """Each point's row in :meth:`unique_rows` (its record and tick)."""
        return self._row_id


    @property
    def matrix(self):
        """Not available: the readings are no matrix on the integer lags."""
        raise TypeError(
            "a TimedConvolution has no regressor on the integer lags: its readings see the "
            "impulse response between them; use its covariance through the kernel's terms"
        )

    def regressor_rows(self, start, stop):
        raise TypeError("a TimedConvolution has no regressor on the integer lags")

    def unique_rows(self) -> np.ndarray:
        """The regressor rows of the points' distinct ``(record, tick)``: ``(R, n_inputs P)``."""
        if self._rows is None:
            records, ticks = self._unique
            P = self.order
            rows = np.empty((ticks.shape[0], self.n_inputs * P))
            for r, part in enumerate(self._parts):
                mine = np.flatnonzero(records == r)
                periodic = part.initial_conditions == "periodic"
                for k in range(self.n_inputs):  # input-major columns
                    x = part._inputs[:, k]
                    # a few rows at a time: no (rows, P) index arrays beside the result
                    for at in range(0, mine.shape[0], _ROW_CHUNK):
                        chunk = mine[at : at + _ROW_CHUNK]
                        rows[chunk, k * P : (k + 1) * P] = _lag_rows(x, ticks[chunk], P,
                                                                     periodic)
            rows.setflags(write=False)
            self._rows = rows
        return self._rows

    def point_rows(self) -> np.ndarray:
        """The regressor row of each point's tick, ``(n_points, n_inputs P)``."""
        return self.unique_rows()[self._row_id]

    def gather(self, values=None) -> sparse.csr_matrix:
        """The sparse ``(M, R)`` matrix that sums ``weight * value`` of the points into readings.

        Row ``m``, column ``r``: the sum over the points of reading ``m``
        on the distinct row ``r`` of ``weight * values``.
        """
        values = self._weights if values is None else self._weights * values
        return sparse.csr_matrix(
            (values, (self._reading, self._row_id)),
            shape=(self.n_outputs, self._row_id.max() + 1),
        )

    def weighted_rows(self, values=None) -> np.ndarray:
        """``sum_points weight * value * row``, per reading: ``(M, n_inputs P)``."""
        rows = self.unique_rows()
        if values is not None and np.iscomplexobj(values):
            # real sparse products: the rows are real
            return (np.asarray(self.gather(values.real) @ rows)
                    + 1j * np.asarray(self.gather(values.imag) @ rows))
        return np.asarray(self.gather(values) @ rows)

    def point_sum(self, X: np.ndarray) -> np.ndarray:
        """``Q X Q^T`` for a matrix ``X`` over pairs of points (``Q`` the quadrature sums)."""
        if self.exposure == 0.0:
            return X
        Q = sparse.csr_matrix(
            (self._weights, (self._reading, np.arange(self.n_points))),
            shape=(self.n_outputs, self.n_points),
        )
        half = np.asarray(Q @ X)
        return np.asarray(Q @ half.T).T

    def point_lags(self, offset: float) -> np.ndarray:
        """The kernel input of the lags ``k + offset``: ``(P, 1)``, or ``(input, lag)`` pairs."""
        lags = self.lags.copy()
        lags[:, -1] += offset
        return lags

    # ------------------------------------------- responses given as functions
    def _reading_sum(self, start: int, stop: int):
        """The sparse ``(M, stop - start)`` matrix that sums weighted points into readings."""
        return sparse.csr_matrix(
            (self._weights[start:stop], (self._reading[start:stop], np.arange(stop - start))),
            shape=(self.n_outputs, stop - start),
        )

    def lag_functionals(self, functions, input: int = 0) -> np.ndarray:
        """The readings of impulse responses given as functions of the continuous lag.

        Reading ``m`` of a response ``f`` of input ``k`` is the sum over the
        reading's points ``p`` (its instant, or the quadrature nodes of its
        exposure window) of ``weight_p * sum_j u_k[tick_p - j] f(j + offset_p)``,
        ``j = 0..P-1``: what the sensor would read if ``g`` of that input
        were ``f`` (and of the others zero).

        Parameters
        ----------
        functions : callable
            ``functions(x)`` with ``x`` of shape ``(n,)`` (real lags in
            ``[0, P)``) returns the values of ``q`` functions, ``(n, q)``.
        input : int, default=0

        Returns
        -------
        ndarray of shape (M, q)

        Examples
        --------
        >>> import numpy as np
        >>> u = np.random.default_rng(0).standard_normal(20)
        >>> timed = TimedConvolution(u, [4.5, 9.75], order=6, exposure=0.5)
        >>> ones = timed.lag_functionals(lambda x: np.ones((x.shape[0], 1)))
        >>> bool(np.allclose(ones[:, 0], [u[:5].sum(), u[4:10].sum()]))
        True
        """
        input = check_int(input, "input", low=0, high=self.n_inputs - 1)
        P = self.order
        rows = self.unique_rows()[:, input * P:(input + 1) * P]
        lags = np.arange(P, dtype=float)
        out = None
        step = max(1, BLOCK_ENTRIES // (4 * P))
        for start in range(0, self.n_points, step):
            stop = min(start + step, self.n_points)
            x = lags[None, :] + self._offsets[start:stop, None]
            values = np.asarray(functions(x.reshape(-1)), dtype=float)
            values = values.reshape(stop - start, P, -1)
            # every point: its regressor row times the functions at its lags
            per_point = np.einsum("pj,pjq->pq", rows[self._row_id[start:stop]], values)
            part = self._reading_sum(start, stop) @ per_point
            out = part if out is None else out + part
        return np.asarray(out)

    def damped_spectrum(self, alpha: float, n_fft: int, index, input: int = 0) -> np.ndarray:
        """The readings of ``alpha^(x/2) exp(-i omega x)`` for ``omega = pi * index / n_fft``.

        As :meth:`lag_functionals` of the damped complex exponentials (real
        part: PK's cosine basis; minus the imaginary part: its sine basis),
        from one real FFT of length ``2 n_fft`` of the damped regressor rows
        and a phase per point.  At ``x = j + d`` the function is its value
        at the integer lag ``j`` times ``alpha^(d/2) exp(-i omega d)``; the
        phase ``exp(-i omega (d - c))`` about the offsets' centre ``c`` is a
        short power series in ``d - c``, so the points of a reading on one
        tick are summed once into the series' moments and the frequencies
        meet the ``(reading, tick)`` pairs, not every quadrature point.

        Parameters
        ----------
        alpha : float
            The decay per fast sample of the envelope ``alpha^(x/2)``.
        n_fft : int
        index : array-like of int
            In ``1..n_fft``.
        input : int, default=0

        Returns
        -------
        ndarray of shape (M, len(index)), complex

        Examples
        --------
        >>> import numpy as np
        >>> u = np.random.default_rng(0).standard_normal(20)
        >>> timed = TimedConvolution(u, [4.5, 9.25, 14.0], order=6, exposure=0.5)
        >>> omega = np.pi * 3 / 8
        >>> direct = timed.lag_functionals(
        ...     lambda x: np.column_stack([0.9 ** (x / 2) * np.cos(omega * x)]))
        >>> bool(np.allclose(timed.damped_spectrum(0.9, 8, [3]).real, direct))
        True
        """
        input = check_int(input, "input", low=0, high=self.n_inputs - 1)
        index = np.asarray(index, dtype=np.int64).reshape(-1)
        P = self.order
        out = np.zeros((self.n_outputs, index.shape[0]), dtype=complex)
        if index.size == 0 or self.n_points == 0:
            return out
        rows = self.unique_rows()[:, input * P:(input + 1) * P]
        envelope = alpha ** (0.5 * np.arange(P))
        spectrum = np.fft.rfft(rows * envelope, n=2 * n_fft, axis=1)
        omegas = np.pi * index / n_fft
        d = self._offsets
        centre = 0.5 * (float(d.min()) + float(d.max()))
        radius = 0.5 * (float(d.max()) - float(d.min()))
        # |omega (d - c)| <= r max|omega| over every point and frequency bounds the remainder
        n_terms = _phase_terms(radius * float(np.max(np.abs(omegas))))
        if n_terms is None:
            return self._pointwise_spectrum(alpha, spectrum[:, index], omegas, out)
        # the moments of each (reading, tick) pair: sum of w alpha^(d/2) ((d - c) / r)^q
        n_rows = int(self._row_id.max()) + 1
        pairs, pair_of = np.unique(self._reading * n_rows + self._row_id, return_inverse=True)
        pair_of = pair_of.reshape(-1)
        scaled = (d - centre) / radius if radius > 0.0 else np.zeros_like(d)
        term = self._weights * alpha ** (0.5 * d)
        moments = np.empty((pairs.shape[0], n_terms))
        for q in range(n_terms):
            moments[:, q] = np.bincount(pair_of, weights=term, minlength=pairs.shape[0])
            term = term * scaled
        # exp(-i omega (d - c)) = sum_q (-i omega r)^q / q! ((d - c) / r)^q
        series = np.empty((n_terms, omegas.shape[0]), dtype=complex)
        series[0] = np.exp(-1j * omegas * centre)
        for q in range(1, n_terms):
            series[q] = series[q - 1] * (-1j * omegas * radius / q)
        pair_rows = pairs % n_rows
        to_readings = sparse.csr_matrix(
            (np.ones(pairs.shape[0]), (pairs // n_rows, np.arange(pairs.shape[0]))),
            shape=(self.n_outputs, pairs.shape[0]),
        )
        step = max(1, BLOCK_ENTRIES // (4 * pairs.shape[0]))
        for start in range(0, index.shape[0], step):
            block = slice(start, min(start + step, index.shape[0]))
            phase = moments @ series[:, block].real + 1j * (moments @ series[:, block].imag)
            # the bins of the block gathered once, for the pairs' rows
            bins = spectrum[np.ix_(pair_rows, index[block])]
            out[:, block] = to_readings @ (bins * phase)
        return out

    def _pointwise_spectrum(self, alpha, spectrum, omegas, out):
        """:meth:`damped_spectrum` with the phase of every point formed (offsets spread wide)."""
        step = max(1, BLOCK_ENTRIES // (4 * max(omegas.shape[0], 1)))
        for start in range(0, self.n_points, step):
            stop = min(start + step, self.n_points)
            d = self._offsets[start:stop, None]
            phase = alpha ** (0.5 * d) * np.exp(-1j * d * omegas[None, :])
            out += self._reading_sum(start, stop) @ (spectrum[self._row_id[start:stop]] * phase)
        return out

    def damped_sinusoids(self, rate: float, omega: float, input: int = 0,
                         with_lag: bool = False, hold: bool = False) -> np.ndarray:
        """The readings of PK's basis ``e^(-rate x) cos(omega x)``, ``e^(-rate x) sin(omega x)``.

        As :meth:`lag_functionals` of these two functions (and, with
        ``with_lag``, of ``x`` times each), by their separable form: at
        ``x = j + d`` each is a combination of its values at the integer lag
        ``j`` with weights of the offset ``d``, so the regressor rows meet
        the bases once, ``O(R P)``, and each point adds ``O(1)``.  With
        ``hold`` the first cell, ``x = d``, is the mode's step response
        (:func:`~gpmultirate.kernels.hold.mode_start`; ``with_lag`` then
        gives its derivative in ``-rate + i omega`` there): each point's
        value less its input at its own tick times the difference.

        Returns
        -------
        ndarray of shape (M, 2), or (M, 4) with ``with_lag``

        Examples
        --------
        >>> import numpy as np
        >>> u = np.random.default_rng(0).standard_normal(20)
        >>> timed = TimedConvolution(u, [4.5, 9.25, 14.0], order=6, exposure=0.5)
        >>> f = lambda x: np.column_stack([np.exp(-0.1 * x) * np.cos(2.0 * x),
        ...                                np.exp(-0.1 * x) * np.sin(2.0 * x)])
        >>> bool(np.allclose(timed.damped_sinusoids(0.1, 2.0), timed.lag_functionals(f)))
        True
        """
        input = check_int(input, "input", low=0, high=self.n_inputs - 1)
        at_points = self._damped_at_ticks(rate, omega, input, with_lag)[self._row_id]
        d = self._offsets
        decay = np.exp(-rate * d)
        cos, sin = decay * np.cos(omega * d), decay * np.sin(omega * d)
        C0, S0 = at_points[:, 0], at_points[:, 1]
        values = [cos * C0 - sin * S0, sin * C0 + cos * S0]
        if with_lag:  # (j + d) times each: the lag-weighted rows plus d times the plain ones
            C1, S1 = at_points[:, 2], at_points[:, 3]
            values += [cos * C1 - sin * S1 + d * values[0], sin * C1 + cos * S1 + d * values[1]]
        if hold:  # lag j = 0 of each point: its tick's input times what the hold takes off
            now = self._inputs_at_ticks(input)[self._row_id]
            taken = mode_start(d, rate, omega, 1 if with_lag else 0)
            values = [v - now * part for v, part in zip(values, (x for p in taken for x in p))]
        return np.asarray(self._reading_sum(0, self.n_points) @ np.column_stack(values))

    def _inputs_at_ticks(self, input: int) -> np.ndarray:
        """``u[n]`` of ``input`` at each distinct row's tick ``n`` (zero outside, or periodic)."""
        records, ticks = self._unique
        out = np.empty(ticks.shape[0])
        for r, part in enumerate(self._parts):
            mine = np.flatnonzero(records == r)
            out[mine] = _lag_rows(part._inputs[:, input], ticks[mine], 1,
                                  part.initial_conditions == "periodic")[:, 0]
        return out

    def _damped_at_ticks(self, rate: float, omega: float, input: int, with_lag: bool):
        """``sum_j u[n - j] e^(-rate j) (cos, sin)(omega j)`` (and ``j`` times each) per distinct row.

        A decaying basis (real ``rate > 0`` and ``omega``) by a first-order
        complex recursion over the input, ``O(N)``, the sum over ``P`` lags as
        the recursion's value less ``q^P`` times its value ``P`` ticks earlier
        (``q = e^(-rate + i omega)``); the lag-weighted sums by its square.
        Otherwise the regressor rows, ``O(R P)``.
        """
        P = self.order
        # complex values (the complex step of the derivatives) keep the rows: a recursion
        # over e^(-rate + i omega) mixes the cosine's and the sine's parts, which the step's
        # imaginary part cannot survive
        if not (np.isrealobj(rate) and np.isrealobj(omega) and rate > 0.0):
            j = np.arange(P, dtype=float)
            ec, es = np.exp(-rate * j) * np.cos(omega * j), np.exp(-rate * j) * np.sin(omega * j)
            columns = [ec, es, j * ec, j * es] if with_lag else [ec, es]
            return self.unique_rows()[:, input * P:(input + 1) * P] @ np.column_stack(columns)
        records, ticks = self._unique
        out = np.empty((ticks.shape[0], 4 if with_lag else 2))
        for r, part in enumerate(self._parts):
            mine = np.flatnonzero(records == r)
            sums = _damped_sums(part._inputs[:, input], ticks[mine], P,
                                part.initial_conditions == "periodic", rate, omega, with_lag)
            out[mine] = np.column_stack([f(v) for v in sums for f in (np.real, np.imag)])
        return out

    # -------------------------------------------------------- with a kernel
    def on_integer_lags(self):
        """These readings as rows on the integer lags, by the hold's interpolation.

        The :class:`~gpmultirate.observations.InterpolatedConvolution` of
        :data:`~gpmultirate.kernels.hold.HOLD_POINTS` nodes: for TC, DC and
        SS, whose values between integer lags are that interpolation
        (:mod:`gpmultirate.kernels.hold`), the readings exactly; None where a
        record is shorter than the nodes.  Kept: the evidence asks for it at
        every evaluation.
        """
        if "_on_lags" not in self.__dict__:
            short = min(part._inputs.shape[0] for part in self._parts) < HOLD_POINTS
            # it reads a copy of these readings without their caches (the arrays shared):
            # one that read ``self`` would close a reference cycle, and an observation in
            # one outlives its last use, rows and all, until the cyclic collector runs
            self._on_lags = (None if short
                             else InterpolatedConvolution(copy.copy(self), HOLD_POINTS))
        return self._on_lags

    def bridge_rows(self) -> np.ndarray:
        """``Psi``: the regressor rows of the points weighted by the bridge's shape ``s(d)``.

        Reading ``m``'s row is ``sum_points weight * s(offset) * row``, shape
        ``(M, n_inputs P)`` (:func:`~gpmultirate.kernels.hold.bridge_shape`); kept.
        """
        if "_bridge_rows" not in self.__dict__:
            self._bridge_rows = self.weighted_rows(bridge_shape(self._offsets))
        return self._bridge_rows

    def structured_term(self, kernel, path: str = "") -> ObservedTerm:
        """A structured leaf through these readings: the kernel's ``observed_at_instants``."""
        return kernel.observed_at_instants(self, path)

    def constant_term(self, kernel, path: str = "") -> ObservedTerm:
        """A constant through these readings: rank one, the readings of the constant 1."""
        return ConstantTimedTerm(kernel, self, path)

    def dense_term(self, kernel, path: str = "") -> ObservedTerm:
        """Any kernel through these readings, from the kernel at their real lags."""
        return DenseTimedTerm(kernel, self, path)

    def kernel_matrix(self, kernel, eval_gradient: bool = False):
        if eval_gradient:
            return kernel(self.lags, eval_gradient=True)
        return kernel(self.lags)

    def covariance(self, kernel, eval_gradient: bool = False):
        """The prior covariance of the noise-free readings (and its gradient in ``theta``)."""
        term = observe(kernel, self)
        if not eval_gradient:
            return term.covariance()
        S, items = term.covariance_with_derivatives()
        grad = np.stack([_dense(item) for item in items], axis=-1) if items else (
            np.empty(S.shape + (0,)))
        return S, grad

    def cross_covariance(self, kernel, lags) -> np.ndarray:
        """``Cov(g(lags), y)``, shape ``(n, M)``.

        Each kernel's term answers: TC, DC and SS by their rows on the
        integer lags, other kernels from their values at the real lags of
        the quadrature points.
        """
        lags = np.asarray(lags, dtype=float)
        if lags.ndim == 1:
            lags = lags[:, None]
        return observe(kernel, self).cross_covariance(lags)

    def dense_cross_covariance(self, kernel, lags) -> np.ndarray:
        """``Cov(g(lags), y)`` from the kernel at the real lags of the readings' points."""
        rows = self.unique_rows()
        out = np.zeros((lags.shape[0], self.n_outputs))
        offsets, group = np.unique(self._offsets, return_inverse=True)
        group = group.reshape(-1)
        for g, offset in enumerate(offsets):
            mine = np.flatnonzero(group == g)
            K = kernel(lags, self.point_lags(offset))  # (n, nP)
            # every point of this offset: K row . its regressor row, summed into its reading
            values = K @ rows[self._row_id[mine]].T  # (n, points)
            np.add.at(out.T, self._reading[mine], (values * self._weights[mine]).T)
        return out

    def input_block(self, k: int) -> "TimedConvolution":
        """The readings of input ``k`` alone: the same points, that input's column.

        Independent inputs (:class:`~gpmultirate.kernels.PerInputKernel`) give
        readings whose covariance is the sum of each input's; each input's
        term then takes its own structure (a semiseparable DC, say) instead
        of the dense route.
        """
        k = check_int(k, "k", low=0, high=self.n_inputs - 1)
        if self.n_inputs == 1:
            return self
        blocks = self.__dict__.setdefault("_blocks", {})
        if k not in blocks:
            block = copy.copy(self)  # without the caches (``__getstate__``), arrays shared
            if self._stacked is not None:
                block._stacked = [part.input_block(k) for part in self._stacked]
            block._inputs = self._inputs[:, k:k + 1]
            block.u = block._inputs[:, 0]
            block.n_inputs = 1
            block._rows = block._gather = None
            blocks[k] = block
        return blocks[k]

    def __eq__(self, other) -> bool:
        if not isinstance(other, TimedConvolution):
            return NotImplemented
        return (
            self.order == other.order and len(self._parts) == len(other._parts)
            and all(
                a.exposure == b.exposure and a.latency == b.latency and a.nodes == b.nodes
                and a.initial_conditions == b.initial_conditions
                and np.array_equal(a.sample_times, b.sample_times)
                and np.array_equal(a._inputs, b._inputs)
                for a, b in zip(self._parts, other._parts)
            )
        )

    __hash__ = None

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_rows"] = None
        state.pop("_blocks", None)
        state.pop("_on_lags", None)
        state.pop("_bridge_rows", None)
        return state

    def __repr__(self) -> str:
        return (
            f"TimedConvolution(records={len(self._parts)}, n_inputs={self.n_inputs}, "
            f"order={self.order}, M={self.n_outputs}, exposure={self.exposure:g}, "
            f"latency={self.latency:g}, initial_conditions={self.initial_conditions!r})"
        )

    def fitted_readings(self, posterior, y: np.ndarray, noise_level: float) -> list:
        """The posterior mean of the noise-free readings, one array per record.

        The fit of readings at their own instants works in data space with
        white noise: the noise-free part of ``y`` is ``y - gamma S_y^{-1} y``
        (``posterior.alpha`` is ``S_y^{-1} y``).
        """
        return self.split_by_record(y - noise_level * posterior.alpha)

    def posterior_readings(self, posterior, data, kernel):
        """Mean and variance of these noise-free readings under a fit's posterior
        (:func:`predict_readings`)."""
        return predict_readings(posterior, data, kernel, self)


def _dense(item) -> np.ndarray:
    if isinstance(item, tuple):
        U, D = item
        return U @ D @ U.T
    return item


def on_the_ticks(sample_times, exposure: float, latency: float):
    """The integer instants of ``sample_times`` when every reading is a fast sample, else None.

    That is without exposure and with every ``t - latency`` an integer: the
    readings are then the :class:`~gpmultirate.observations.SampledConvolution`
    of those instants (lists for several records).
    """
    if exposure != 0.0:
        return None
    several = is_record_list(sample_times)
    out = []
    for times in (sample_times if several else [sample_times]):
        shifted = as_real_array(times, "sample_times") - latency
        if shifted.ndim != 1 or not np.all(np.isfinite(shifted)):
            return None
        if np.any(shifted != np.round(shifted)):
            return None
        out.append(np.round(shifted).astype(np.int64))
    return out if several else out[0]


def build_timed_experiment(u, y_slow, sample_times, *, order=None, exposure=0.0, latency=0.0,
                           initial_conditions="zero") -> Experiment:
    """Check the data of a fit at the readings' own instants and build their observation.

    Parameters
    ----------
    u : array-like of shape (N,) or (N, n_inputs), or a list of them
    y_slow : array-like of shape (M,), or a list of them
        ``NaN`` marks a reading that was not measured.
    sample_times : array-like of shape (M,), or a list of them
        The stamps, strictly increasing in ``[0, N)``, in fast sample periods.
    order : int or None
        ``P``; by default the length of the longest record.
    exposure, latency : float
        In fast sample periods.
    initial_conditions : {"zero", "discard", "periodic"}

    Returns
    -------
    Experiment

    Examples
    --------
    >>> import numpy as np
    >>> experiment = build_timed_experiment(np.ones(12), [1.0, np.nan, 2.0], [1.5, 4.2, 8.7],
    ...                                     order=4, exposure=0.5)
    >>> experiment.observation.sample_times, experiment.y
    (array([1.5, 8.7]), array([1., 2.]))
    """
    inputs, several = check_records(u)
    if several:
        for name, value in (("y_slow", y_slow), ("sample_times", sample_times)):
            if not is_record_list(value) or len(value) != len(inputs):
                raise ValueError(
                    f"{name} must be a list with one entry per record of u ({len(inputs)})")
    elif is_record_list(y_slow) and len(y_slow) > 1:
        raise ValueError("y_slow is a list of records but u is not: give u as a list too")
    ys = list(y_slow) if several else [y_slow]
    times = list(sample_times) if several else [sample_times]
    ic = check_initial_conditions(initial_conditions)
    longest = max(x.shape[0] for x in inputs)
    high = longest if ic == "zero" else min(x.shape[0] for x in inputs)
    order = high if order is None else check_int(order, "order", low=1, high=high)
    exposure = check_duration(exposure, "exposure")
    latency = check_duration(latency, "latency")
    records, used_y = [], []
    for r, (x, y, t) in enumerate(zip(inputs, ys, times)):
        label = f"[{r}]" if several else ""
        y = as_real_array(y, "y_slow" + label).reshape(-1) if np.ndim(y) else None
        if y is None or y.shape[0] == 0:
            raise ValueError(f"y_slow{label} must be a non-empty 1-D array")
        if np.any(np.isinf(y)):
            raise ValueError(f"y_slow{label} must not contain inf (NaN marks a missing reading)")
        t = check_sample_times(t, x.shape[0], "sample_times" + label)
        if t.shape[0] != y.shape[0]:
            raise ValueError(
                f"sample_times{label} must have one entry per reading of y_slow{label} "
                f"({y.shape[0]}); got {t.shape[0]}"
            )
        measured = np.isfinite(y)
        if not np.any(measured):
            raise ValueError(f"y_slow{label} has no finite sample: nothing was measured")
        try:
            record = TimedConvolution(x, t[measured], order, exposure, latency, ic)
        except ValueError as error:
            raise ValueError(f"record {r}: {error}" if several else str(error)) from None
        records.append(record)
        used_y.append(y[measured][record.used])
    return Experiment(TimedConvolution.stack(records), np.concatenate(used_y), inputs[0].shape[1])


def predict_readings(posterior, data, kernel, readings: TimedConvolution):
    """Mean and variance of the noise-free ``readings`` under the posterior of a fit.

    ``data`` is the observation the posterior conditioned on.  A timed
    ``data`` (its posterior in the data space) is conditioned on directly,
    the readings stacked with it as a record of the same system; data on the
    integer lags see ``g`` between the ticks only through ``g(0..P-1)``, so
    the readings are the prior given those, averaged over their posterior.
    ``kernel`` is the kernel the posterior conditioned with; the spread a
    posterior adds after conditioning
    (:meth:`~gpmultirate.covariance.GaussianCoefficients.readings_spread`)
    is added to the variances.
    """
    if isinstance(data, TimedConvolution):
        joint = TimedConvolution.stack([data, readings])
        # only the readings' covariance with the data and their own variances
        cross, prior = observe(kernel, joint).covariance_blocks(data.n_outputs)
        mean, explained = posterior.given_data(cross)
        var = prior - explained + posterior.readings_spread(readings)
        return mean, np.maximum(var, 0.0)
    term = observe(kernel, readings)
    _, prior = term.covariance_blocks(0)
    with_lags = term.regressor_times_kernel()  # Cov(readings, g(0..P-1))
    K = kernel(data.lags)
    jitter = 1e-10 * max(float(np.mean(np.diag(K))), 1e-300)
    factor = linalg.cho_factor(K + jitter * np.eye(K.shape[0]), lower=True)
    A = linalg.cho_solve(factor, with_lags.T).T  # Cov(r, g) K^{-1}
    mean, posterior_var = posterior.linear_map(A)
    var = prior - np.einsum("ij,ij->i", A, with_lags) + posterior_var
    return mean, np.maximum(var, 0.0)
