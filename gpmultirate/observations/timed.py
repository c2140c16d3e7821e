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

Its readings are not a matrix on the integer lags, so the routes of the
integer-lag observations (the long-record reduction, the diagonal recursion,
the filters of DC) do not apply.  The covariance of the readings is formed by
the kernel's terms below:

* TC, DC and SS by their semiseparable structure between integer lags
  (:mod:`gpmultirate.kernels.offsets`): ``O(M P + M^2 P)``, the products
  with the pieces being first-order recursions;
* PK and constants, of rank two and one at any lag, by their bases;
* sums and constant multiples through the walker's own terms;
* independent inputs (:class:`~gpmultirate.kernels.PerInputKernel`) as the
  sum of each input's term on that input's readings (:meth:`TimedConvolution.input_block`);
* any other kernel densely, from the kernel at the real lags, grouped by
  the distinct offsets: ``O(G^2 P^2)`` kernel entries for ``G`` distinct
  offsets (as cheap as on the ticks for ``G = 1``, meant for small problems
  otherwise).

The derivatives of the structured terms are exact to rounding: the complex
step on the hyperparameter values.

The exposure integral is Gauss-Legendre quadrature with
:data:`QUADRATURE_NODES` nodes on each piece of the window between fast
ticks, where the output is smooth.  The covariance of TC, DC and SS has a
kink where two lags meet.  Where their pieces are single exponentials (TC,
DC with ``beta > 0``, SS), the double integral of two windows on the same
integer lag is in closed form
(:func:`~gpmultirate.kernels.offsets.ordered_exponential_integral`, a
divided difference of ``exp``; it agrees with the quadrature to ``1e-12``);
DC with ``beta < 0`` splits the double integral at the kink
(:func:`_ordered_integral`), and the cross-covariance with ``g`` at real lags
likewise, so with an exposure they are exact to rounding (8 and 16 nodes
agree to ``1e-10``; a brute-force double sum with 96 nodes agrees to its own
error, about ``1e-6``).  PK and constants are smooth: exact to rounding as
well.  The dense route integrates by the points; for smooth kernels (RBF)
its error is below ``1e-8``, for a kinked kernel inside a product, or TC/DC
of several inputs, it falls as the square of the nodes (about ``5e-4`` of
the covariance with 16 nodes).
"""

from __future__ import annotations

import copy
import numbers

import numpy as np
from scipy import linalg, sparse
from sklearn.gaussian_process.kernels import ConstantKernel, Product, Sum

from gpmultirate.exceptions import MemoryLimitError
from gpmultirate.kernels.inputs import PerInputKernel
from gpmultirate.kernels.lag import PK
from gpmultirate.kernels.offsets import (
    _exp_integral, offset_structure, ordered_exponential_integral, supports_offsets,
    times_lower,
)
from gpmultirate.kernels.structure import (
    ConstantTerm, ObservedTerm, ScaledTerm, SumTerm, split_constant,
)
from gpmultirate.memory import available_memory
from gpmultirate.observations.base import Observation
from gpmultirate.observations.experiment import Experiment, check_records, is_record_list
from gpmultirate.observations.sampled import check_initial_conditions
from gpmultirate.validation import as_real_array, check_inputs, check_int

__all__ = [
    "QUADRATURE_NODES", "TimedConvolution", "build_timed_experiment", "check_sample_times",
    "check_duration", "check_windows", "on_the_ticks", "predict_readings",
]

#: Gauss-Legendre nodes on each piece of an exposure window between two ticks
QUADRATURE_NODES = 16
#: the complex step of the derivatives (relative to the value)
_STEP = 1e-30
#: kernel entries formed at once by the dense route and the cross-covariance
_BLOCK_ENTRIES = 2**22


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
    windows' points is formed; the pieces of the windows between ticks
    (whose pairs the exact covariance integrates) are counted against the
    available memory.

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
    # the exact covariance forms a few (pieces x pieces) float arrays and one
    # point per node of each piece
    needed = 8.0 * (4.0 * pieces**2 + 8.0 * pieces * nodes)
    available = available_memory()
    if needed > available:
        raise MemoryLimitError(
            f"exposure {exposure:g} over {times.size} readings cuts their windows into "
            f"{pieces:.0f} pieces between the fast ticks, whose exact covariance needs about "
            f"{needed / 1e9:.3g} GB but {available / 1e9:.4g} GB are available: use a shorter "
            "exposure or fewer readings")


def _window_points(times, exposure: float, latency: float, nodes: int):
    """The quadrature points of every reading, and the pieces of its window between ticks.

    Returns ``(reading, instant, weight, piece)`` per point and
    ``(start, stop)`` per piece (one piece per reading without exposure).
    """
    ends = times - latency
    if exposure == 0.0:
        index = np.arange(times.shape[0])
        return index, ends, np.ones(times.shape[0]), index, (ends, ends)
    xi, w = np.polynomial.legendre.leggauss(nodes)
    readings, instants, weights, starts, stops = [], [], [], [], []
    for m, end in enumerate(ends):
        start = end - exposure
        cuts = np.arange(np.floor(start) + 1.0, np.ceil(end))
        edges = np.concatenate([[start], cuts[(cuts > start) & (cuts < end)], [end]])
        for low, high in zip(edges[:-1], edges[1:]):
            half = 0.5 * (high - low)
            instants.append(low + half * (xi + 1.0))
            weights.append(w * half / exposure)
            readings.append(np.full(nodes, m))
            starts.append(low)
            stops.append(high)
    piece = np.repeat(np.arange(len(starts)), nodes)
    return (np.concatenate(readings), np.concatenate(instants), np.concatenate(weights), piece,
            (np.array(starts), np.array(stops)))


def _ordered_integral(f, h, a1, b1, a2, b2, xi, w):
    """``int_{x in [a1, b1]} int_{y in [a2, b2], y < x} f(x) h(y) dy dx``, elementwise.

    The region's edge ``y = x`` is where the kernel has its kink; on each
    side of ``x = b2`` the integrand is smooth, so nested Gauss-Legendre
    rules on the two parts are exact to rounding for the exponentials and
    cosines of the lag kernels.
    """
    low = np.maximum(a1, a2)
    high = np.maximum(b1, low)
    split = np.clip(b2, low, high)
    total = 0.0
    for start, stop, follows_x in ((low, split, True), (split, high, False)):
        half = 0.5 * (stop - start)
        x = start[..., None] + half[..., None] * (xi + 1.0)
        upper = x if follows_x else np.broadcast_to(b2[..., None], x.shape)
        inner_half = 0.5 * (upper - a2[..., None])
        y = a2[..., None, None] + inner_half[..., None] * (xi + 1.0)
        inner = (h(y) @ w) * inner_half
        total = total + ((f(x) * inner) @ w) * half
    return total


def _cell_integrals(found, r, f, h, a, b, nodes):
    """Over each cell ``[a, b]``: the integrals of ``f_r`` and ``h_r``, and of ``f_r(x) h_r(y)``
    over its triangle ``y < x`` (closed form for exponentials, else Gauss-Legendre)."""
    if found.rates is not None:
        lam, mu = found.rates[r]
        return (_exp_integral(lam, a, b), _exp_integral(mu, a, b),
                ordered_exponential_integral(lam, mu, a, b, a, b))
    xi, w = np.polynomial.legendre.leggauss(nodes)
    half = 0.5 * (b - a)
    x = a[:, None] + half[:, None] * (xi + 1.0)
    return ((f(x) @ w) * half, (h(x) @ w) * half, _ordered_integral(f, h, a, b, a, b, xi, w))


def _step_product(A, B):
    """``A @ B`` for real or complex-step matrices, in real products.

    A complex-step value is ``x + i h x'`` with ``h`` far below rounding, so
    the product of the two imaginary parts (``O(h^2)``) is dropped, as the
    complex step drops it from the real part: three real products where
    the complex one takes four, two where one factor is real.
    """
    a_complex, b_complex = np.iscomplexobj(A), np.iscomplexobj(B)
    if not (a_complex or b_complex):
        return A @ B
    if not b_complex:
        return (A.real @ B) + 1j * (A.imag @ B)
    if not a_complex:
        return (A @ B.real) + 1j * (A @ B.imag)
    return (A.real @ B.real) + 1j * (A.imag @ B.real + A.real @ B.imag)


def _base_at_points(found, d):
    """``k(d_i, d_j)`` at the offsets, from the lower pieces (``k(x, y) = sum_r A_r[0, 0]
    f_r(x) h_r(y)`` for ``x >= y``): ``O(M)`` exponentials instead of ``O(M^2)`` powers."""
    later = d[:, None] >= d[None, :]
    out = 0.0
    for p_r, q_r, _, f, h in found.lower:
        outer = np.multiply.outer(f(d), h(d))
        out = out + p_r[0] * q_r[0] * np.where(later, outer, outer.T)
    return out


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
        reading, instant, weight, piece, (starts, stops) = _window_points(
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
        self._parts = [self]
        kept_pieces = np.unique(piece[keep])
        piece_ticks = ticks[np.searchsorted(piece, kept_pieces)]
        self._set_points(renumber[reading[keep]], ticks[keep], instant[keep] - ticks[keep],
                         weight[keep], np.zeros(int(keep.sum()), dtype=np.int64),
                         np.searchsorted(kept_pieces, piece[keep]),
                         starts[kept_pieces] - piece_ticks, stops[kept_pieces] - piece_ticks)

    def _set_points(self, reading, ticks, offsets, weights, record, piece, piece_start,
                    piece_stop):
        self._reading, self._ticks, self._offsets = reading, ticks, offsets
        self._weights, self._record = weights, record
        # the windows' pieces between ticks, as offsets from their tick
        self._piece, self._piece_start, self._piece_stop = piece, piece_start, piece_stop
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
        stacked._parts = [part for record in records for part in record._parts]
        stacked.u, stacked._inputs = first.u, first._inputs
        stacked.used = np.concatenate([r.used for r in records])
        stacked.sample_times = np.concatenate([r.sample_times for r in records])
        shift, part_shift, piece_shift = 0, 0, 0
        pieces = []
        for record in records:
            pieces.append((record._reading + shift, record._ticks, record._offsets,
                           record._weights, record._record + part_shift,
                           record._piece + piece_shift, record._piece_start, record._piece_stop))
            shift += record.n_outputs
            part_shift += len(record._parts)
            piece_shift += record._piece_start.shape[0]
        stacked._set_points(*(np.concatenate(column) for column in zip(*pieces)))
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
            lags = np.arange(P)
            for r, part in enumerate(self._parts):
                mine = records == r
                index = ticks[mine][:, None] - lags[None, :]
                x = part._inputs
                if part.initial_conditions == "periodic":
                    block = x[np.remainder(index, x.shape[0])]
                else:
                    inside = (index >= 0) & (index < x.shape[0])
                    block = np.where(inside[..., None], x[np.clip(index, 0, x.shape[0] - 1)], 0.0)
                # (n, P, n_inputs) -> input-major columns
                rows[mine] = np.transpose(block, (0, 2, 1)).reshape(index.shape[0], -1)
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
        step = max(1, _BLOCK_ENTRIES // (4 * P))
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
        and a phase per point.

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
        index = np.asarray(index, dtype=np.int64)
        P = self.order
        rows = self.unique_rows()[:, input * P:(input + 1) * P]
        envelope = alpha ** (0.5 * np.arange(P))
        spectrum = np.fft.rfft(rows * envelope, n=2 * n_fft, axis=1)[:, index]
        omegas = np.pi * index / n_fft
        out = np.zeros((self.n_outputs, index.shape[0]), dtype=complex)
        step = max(1, _BLOCK_ENTRIES // (4 * max(index.shape[0], 1)))
        for start in range(0, self.n_points, step):
            stop = min(start + step, self.n_points)
            d = self._offsets[start:stop, None]
            phase = alpha ** (0.5 * d) * np.exp(-1j * d * omegas[None, :])
            out += self._reading_sum(start, stop) @ (spectrum[self._row_id[start:stop]] * phase)
        return out

    def damped_sinusoids(self, rate: float, omega: float, input: int = 0,
                         with_lag: bool = False) -> np.ndarray:
        """The readings of PK's basis ``e^(-rate x) cos(omega x)``, ``e^(-rate x) sin(omega x)``.

        As :meth:`lag_functionals` of these two functions (and, with
        ``with_lag``, of ``x`` times each), by their separable form: at
        ``x = j + d`` each is a combination of its values at the integer lag
        ``j`` with weights of the offset ``d``, so the regressor rows meet
        the bases once, ``O(R P)``, and each point adds ``O(1)``.

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
        P = self.order
        j = np.arange(P, dtype=float)
        ec, es = np.exp(-rate * j) * np.cos(omega * j), np.exp(-rate * j) * np.sin(omega * j)
        columns = [ec, es, j * ec, j * es] if with_lag else [ec, es]
        at_ticks = self.unique_rows()[:, input * P:(input + 1) * P] @ np.column_stack(columns)
        at_points = at_ticks[self._row_id]
        d = self._offsets
        decay = np.exp(-rate * d)
        cos, sin = decay * np.cos(omega * d), decay * np.sin(omega * d)
        C0, S0 = at_points[:, 0], at_points[:, 1]
        values = [cos * C0 - sin * S0, sin * C0 + cos * S0]
        if with_lag:  # (j + d) times each: the lag-weighted rows plus d times the plain ones
            C1, S1 = at_points[:, 2], at_points[:, 3]
            values += [cos * C1 - sin * S1 + d * values[0], sin * C1 + cos * S1 + d * values[1]]
        return np.asarray(self._reading_sum(0, self.n_points) @ np.column_stack(values))

    # -------------------------------------------------------- with a kernel
    def observe_kernel(self, kernel, path: str = "") -> ObservedTerm:
        """``kernel`` seen through these readings: the tree of terms (see the module)."""
        return timed_term(kernel, self, path)

    def kernel_matrix(self, kernel, eval_gradient: bool = False):
        if eval_gradient:
            return kernel(self.lags, eval_gradient=True)
        return kernel(self.lags)

    def covariance(self, kernel, eval_gradient: bool = False):
        """The prior covariance of the noise-free readings (and its gradient in ``theta``)."""
        term = timed_term(kernel, self)
        if not eval_gradient:
            return term.covariance()
        S, items = term.covariance_with_derivatives()
        grad = np.stack([_dense(item) for item in items], axis=-1) if items else (
            np.empty(S.shape + (0,)))
        return S, grad

    def cross_covariance(self, kernel, lags) -> np.ndarray:
        """``Cov(g(lags), y)``, shape ``(n, M)``.

        From the kernel at the real lags of the quadrature points; for TC, DC
        and SS under an exposure, the integral over the lag of the window that
        meets ``lags`` is split at its kink (exact to rounding).
        """
        lags = np.asarray(lags, dtype=float)
        if lags.ndim == 1:
            lags = lags[:, None]
        if isinstance(kernel, Sum):
            return self.cross_covariance(kernel.k1, lags) + self.cross_covariance(kernel.k2, lags)
        split = split_constant(kernel) if isinstance(kernel, Product) else None
        if split is not None:
            return float(split[0].constant_value) * self.cross_covariance(split[1], lags)
        out = self._point_cross_covariance(kernel, lags)
        if (self.exposure > 0.0 and self.n_inputs == 1 and supports_offsets(kernel)
                and float(getattr(kernel, "beta", 1.0)) != 0.0):
            out += self._kink_correction(kernel, lags[:, 0])
        return out

    def _kink_correction(self, kernel, lags) -> np.ndarray:
        """Exact minus quadrature, for the window lags on the same integer lag as ``lags``."""
        values = {h.name: float(getattr(kernel, h.name)) for h in kernel.hyperparameters}
        found = offset_structure(kernel, values, self.order)
        whole = np.floor(lags).astype(np.int64)
        frac = lags - whole
        inside = np.flatnonzero(whole < self.order)
        out = np.zeros((lags.shape[0], self.n_outputs))
        if inside.size == 0:
            return out
        whole, frac = whole[inside], frac[inside]
        rows = self.unique_rows()
        scale = np.real(found.scale) ** whole.astype(float)
        # the quadrature's own value of the k = whole term
        point_u = rows[self._row_id][:, whole]  # (points, n)
        base = np.real(found.base(frac, self._offsets))  # (n, points)
        approx = (point_u.T * base) * self._weights
        # its exact value, piece by piece: k(d, x) = sum_r A_r f_r(max) h_r(min)
        xi, w = np.polynomial.legendre.leggauss(self.nodes)
        start, stop = self._piece_start, self._piece_stop
        first_point = np.searchsorted(self._piece, np.arange(start.shape[0]))
        piece_u = rows[self._row_id[first_point]][:, whole].T  # (n, pieces)
        d = frac[:, None]
        exact = 0.0
        for p_r, q_r, _, f, h in found.lower:
            A00 = float(np.real(p_r[0] * q_r[0]))
            for low, high, after in ((start[None, :], np.minimum(stop[None, :], d), False),
                                     (np.maximum(start[None, :], d), stop[None, :], True)):
                half = 0.5 * np.maximum(high - low, 0.0)
                x = low[..., None] + half[..., None] * (xi + 1.0)
                if after:  # x > d
                    part = (np.real(f(x)) @ w) * np.real(h(d))
                else:
                    part = (np.real(h(x)) @ w) * np.real(f(d))
                exact = exact + A00 * part * half
        exact = exact * piece_u / self.exposure
        correction = np.zeros((inside.size, self.n_outputs))
        np.add.at(correction.T, self._reading[first_point], exact.T)
        np.add.at(correction.T, self._reading, -approx.T)
        out[inside] = correction * scale[:, None]
        return out

    def _point_cross_covariance(self, kernel, lags) -> np.ndarray:
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
            block = copy.copy(self)
            block.__dict__.pop("_blocks", None)
            if len(self._parts) == 1 and self._parts[0] is self:
                block._parts = [block]
            else:
                block._parts = [part.input_block(k) for part in self._parts]
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


# ---------------------------------------------------------------- the terms
class _TimedTerm(ObservedTerm):
    """A leaf kernel seen through timed readings; subclasses provide :meth:`_build`.

    ``_build(values)`` returns the covariance of the readings for the
    hyperparameter ``values`` (real, or complex for the complex step); the
    derivative with respect to a free ``theta`` entry is
    ``Im build(value + i h) / h`` times ``d value / d theta``.
    """

    def _values(self) -> dict:
        return {h.name: float(getattr(self.kernel, h.name)) for h in self.kernel.hyperparameters}

    def _free(self):
        return [h for h in self.kernel.hyperparameters if not h.fixed]

    def _build(self, values):
        raise NotImplementedError

    def covariance(self):
        if getattr(self, "_covariance", None) is None:
            S = np.real(self._build(self._values()))
            self._covariance = 0.5 * (S + S.T)
        return self._covariance

    def _derivatives(self):
        values = self._values()
        items = []
        for h in self._free():
            step = _STEP * max(abs(values[h.name]), 1.0)
            moved = dict(values)
            moved[h.name] = values[h.name] + 1j * step
            built = self._build(moved)
            if getattr(self, "_covariance", None) is None:
                # the real part of the complex step is the value to O(step^2): no build of its own
                S = np.real(built)
                self._covariance = 0.5 * (S + S.T)
            dS = np.imag(built) / step
            transform = getattr(self.kernel, "theta_transform", None)
            chain = (values[h.name] if transform is None
                     else float(transform(h.name).derivative(values[h.name])))
            dS = chain * 0.5 * (dS + dS.T)
            items.append(dS)
        return items

    def covariance_with_derivatives(self):
        items = self._derivatives()
        return self.covariance(), items

    def covariance_with_contractor(self):
        items = self._derivatives()
        return self.covariance(), lambda W: np.array([np.sum(W * dS) for dS in items])

    def regressor_times_kernel(self):
        return self.observation.cross_covariance(self.kernel, self.observation.lags).T

    def low_rank(self):
        return None

    def precision(self):
        return None


class ShiftScaledTimedTerm(_TimedTerm):
    """TC, DC or SS through timed readings, by the semiseparable structure.

    With the strictly lower pieces ``A_r, f_r, h_r`` and the shift scale
    ``c`` (:func:`~gpmultirate.kernels.offsets.offset_structure`), the
    readings' covariance is

    ``S = sum_r (X_r A_r Y_r^T + Y_r A_r^T X_r^T) + Q ((R C R^T) o H) Q^T``

    with ``X_r = Q diag(f_r) R`` and ``Y_r = Q diag(h_r) R`` (``R`` the
    points' regressor rows, ``Q`` the quadrature sums), ``C = diag(c^k)``
    and ``H = k(d_i, d_j)`` at the points' offsets.
    """

    def _build(self, values):
        obs = self.observation
        P = obs.order
        found = offset_structure(self.kernel, values, P)
        d = obs._offsets
        S = 0.0
        for p, q, c, f, h in found.lower:
            X = obs.weighted_rows(f(d))
            Y = obs.weighted_rows(h(d))
            part = _step_product(times_lower(X, p, q, c), Y.T)
            S = S + part + part.T
        rows = obs.unique_rows()
        scale = found.scale ** np.arange(P, dtype=float)
        G = _step_product(rows * scale, rows.T)
        if obs.exposure == 0.0:
            ids = obs._row_id
            return S + G[np.ix_(ids, ids)] * _base_at_points(found, d)
        return S + self._windows_on_equal_lags(found, G)

    def _windows_on_equal_lags(self, found, G):
        """``sum_k c^k`` times the kernel at the offsets, integrated over pairs of window pieces.

        ``k(k + x, k + y) = c^k k(x, y)`` has its kink at ``x = y``, with
        ``k(x, y) = sum_r A_r[0, 0] f_r(x) h_r(y)`` for ``x > y``.  The ends
        of all the pieces cut ``[0, 1]`` into cells; a piece is a run of
        cells, and the integral over ``y < x`` of two pieces is the sum of
        ``F_a H_b`` over their cells ``a > b`` (``F``, ``H`` the integrals of
        ``f_r``, ``h_r`` over a cell) plus, over their common cells, the
        integral ``T_a`` over the triangle ``y < x`` of the cell.  These are
        in closed form where ``f_r`` and ``h_r`` are exponentials
        (:func:`~gpmultirate.kernels.offsets.ordered_exponential_integral`),
        otherwise by Gauss-Legendre quadrature on the cell (nested on the
        triangle, :func:`_ordered_integral`), where the integrands are
        smooth.  The sums over runs of cells are differences of cumulative
        sums: ``O(n E)`` for ``n`` pieces and ``E <= 2 n`` cells.
        """
        obs = self.observation
        start, stop = obs._piece_start, obs._piece_stop
        n_pieces = start.shape[0]
        first_point = np.searchsorted(obs._piece, np.arange(n_pieces))
        reading = obs._reading[first_point]
        row = obs._row_id[first_point]
        edges = np.unique(np.concatenate([start, stop]))
        low, high = np.searchsorted(edges, start), np.searchsorted(edges, stop)
        a, b = edges[:-1], edges[1:]
        cells = np.arange(a.shape[0] + 1)
        # common cells of two pieces: from max(low) to max(min(high), max(low))
        common_low = np.maximum.outer(low, low)
        common_high = np.maximum(np.minimum.outer(high, high), common_low)
        block = max(1, _BLOCK_ENTRIES // (4 * cells.shape[0]))
        value = 0.0
        for r, (p_r, q_r, _, f, h) in enumerate(found.lower):
            F, H, T = _cell_integrals(found, r, f, h, a, b, obs.nodes)
            zero = np.zeros(1, dtype=F.dtype)
            cum_H = np.concatenate([zero, np.cumsum(H)])
            cum_T = np.concatenate([zero, np.cumsum(T)])
            # I[i, j] = int_{x in piece i} int_{y in piece j, y < x} f_r(x) h_r(y)
            I = np.empty((n_pieces, n_pieces), dtype=F.dtype)
            for j0 in range(0, n_pieces, block):
                j = slice(j0, min(j0 + block, n_pieces))
                # V[j, x]: the integral of h_r over the cells of piece j before cell x
                before = np.clip(cells[None, :-1], low[j, None], high[j, None])
                V = cum_H[before] - cum_H[low[j], None]
                W = np.concatenate([np.zeros((V.shape[0], 1), dtype=V.dtype),
                                    np.cumsum(V * F, axis=1)], axis=1)
                I[:, j] = (W[:, high] - W[:, low]).T
            I += cum_T[common_high] - cum_T[common_low]
            value = value + p_r[0] * q_r[0] * (I + I.T)
        pieces = value * G[np.ix_(row, row)] / obs.exposure**2
        Q = sparse.csr_matrix(
            (np.ones(n_pieces), (reading, np.arange(n_pieces))),
            shape=(obs.n_outputs, n_pieces),
        )
        return np.asarray(Q @ np.asarray(Q @ pieces).T).T

    def regressor_times_kernel(self):
        # Cov(y_i, g(l)): k > l from f_r(d) h_r(0), k < l from f_r(0) h_r(d), k = l from c^k k(d, 0)
        obs = self.observation
        P = obs.order
        found = offset_structure(self.kernel, self._values(), P)
        d = obs._offsets
        zero = np.zeros(1)
        out = 0.0
        for p, q, c, f, h in found.lower:
            out = out + times_lower(obs.weighted_rows(f(d)), p, q, c) * float(np.real(h(zero)[0]))
            out = out + float(np.real(f(zero)[0])) * times_lower(
                obs.weighted_rows(h(d)), p, q, c, transpose=True)
        scale = found.scale ** np.arange(P, dtype=float)
        out = out + obs.weighted_rows(found.base(d, zero)[:, 0]) * scale
        return np.real(out)


class LowRankTimedTerm(_TimedTerm):
    """PK or a constant through timed readings: ``S = U D U^T``, ``U`` the basis's readings."""

    def _factors(self, values):
        obs = self.observation
        P = obs.order
        if isinstance(self.kernel, ConstantKernel):
            U = obs.weighted_rows().sum(axis=1, keepdims=True)
            return U, np.array([[values["constant_value"]]])
        alpha, omega = values["alpha"], values["omega"]
        rows = obs.point_rows()
        lags = np.arange(P)[None, :] + obs._offsets[:, None]
        envelope = alpha ** (lags / 2.0)
        cos_part = np.einsum("ij,ij->i", rows, envelope * np.cos(omega * lags))
        sin_part = np.einsum("ij,ij->i", rows, envelope * np.sin(omega * lags))
        Q = sparse.csr_matrix(
            (obs._weights, (obs._reading, np.arange(obs.n_points))),
            shape=(obs.n_outputs, obs.n_points),
        )
        U = np.column_stack([Q @ cos_part, Q @ sin_part])
        D = np.diag([values["sigma1"] ** 2, values["sigma2"] ** 2])
        return U, D

    def _build(self, values):
        U, D = self._factors(values)
        return (U @ D) @ U.T

    def roles(self):
        if not isinstance(self.kernel, ConstantKernel):
            return super().roles()
        return ConstantTerm(self.kernel, None, self.path).roles()

    def scale_roles(self):
        if not isinstance(self.kernel, ConstantKernel):
            return super().scale_roles()
        return [0] if self._free() else None


class DenseTimedTerm(_TimedTerm):
    """Any kernel through timed readings, from the kernel at the real lags, by distinct offsets."""

    def _pairs(self, eval_gradient: bool):
        obs = self.observation
        rows = obs.point_rows()
        offsets, group = np.unique(obs._offsets, return_inverse=True)
        group = group.reshape(-1)
        n = obs.n_points
        n_theta = self.kernel.n_dims if eval_gradient else 0
        S = np.zeros((n, n))
        dS = np.zeros((n_theta, n, n))
        members = [np.flatnonzero(group == g) for g in range(offsets.shape[0])]
        lags = [obs.point_lags(o) for o in offsets]
        for a in range(offsets.shape[0]):
            for b in range(a, offsets.shape[0]):
                ia, ib = members[a], members[b]
                if eval_gradient:
                    # scikit-learn's gradients are of k(X, X): both offsets' lags stacked
                    both = lags[a] if a == b else np.vstack([lags[a], lags[b]])
                    K, dK = self.kernel(both, eval_gradient=True)
                    size = lags[a].shape[0]
                    K, dK = K[:size, -size:], dK[:size, -size:]
                else:
                    K = self.kernel(lags[a], lags[b])
                block = rows[ia] @ K @ rows[ib].T
                S[np.ix_(ia, ib)] = block
                S[np.ix_(ib, ia)] = block.T
                for j in range(n_theta):
                    block = rows[ia] @ dK[:, :, j] @ rows[ib].T
                    dS[j][np.ix_(ia, ib)] = block
                    dS[j][np.ix_(ib, ia)] = block.T
        return S, dS

    def covariance(self):
        if getattr(self, "_covariance", None) is None:
            S, _ = self._pairs(False)
            S = self.observation.point_sum(S)
            self._covariance = 0.5 * (S + S.T)
        return self._covariance

    def _derivatives(self):
        S, dS = self._pairs(True)
        point_sum = self.observation.point_sum
        if getattr(self, "_covariance", None) is None:
            S = point_sum(S)
            self._covariance = 0.5 * (S + S.T)
        return [point_sum(d) for d in dS]


def timed_term(kernel, observation: TimedConvolution, path: str = "") -> ObservedTerm:
    """The walker for timed readings: sums and constant multiples kept, leaves by their structure.

    TC, DC (``beta != 0``) and SS of one input take their semiseparable term,
    PK of one input and constants their low-rank term; independent inputs
    (:class:`~gpmultirate.kernels.PerInputKernel`) the sum of each input's
    term on its own readings; every other kernel (products, inputs coupled,
    any scikit-learn kernel) the dense term.
    """
    if isinstance(kernel, Sum):
        return SumTerm(
            kernel, timed_term(kernel.k1, observation, path + "k1__"),
            timed_term(kernel.k2, observation, path + "k2__"), observation, path,
        )
    if isinstance(kernel, Product):
        split = split_constant(kernel)
        if split is not None:
            constant, other, first = split
            inner = timed_term(other, observation, path + ("k2__" if first else "k1__"))
            return ScaledTerm(kernel, constant, inner, first, observation, path)
        return DenseTimedTerm(kernel, observation, path)
    if isinstance(kernel, ConstantKernel):
        return LowRankTimedTerm(kernel, observation, path)
    if isinstance(kernel, PerInputKernel) and kernel.n_inputs == observation.n_inputs:
        # independent inputs: the sum of each input's readings (input_block), each input's
        # kernel walked again on its own
        return kernel.observed(observation, path)
    if observation.n_inputs == 1:
        if supports_offsets(kernel) and float(getattr(kernel, "beta", 1.0)) != 0.0:
            return ShiftScaledTimedTerm(kernel, observation, path)
        if type(kernel) is PK:
            return LowRankTimedTerm(kernel, observation, path)
    return DenseTimedTerm(kernel, observation, path)


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
    """
    if isinstance(data, TimedConvolution):
        joint = TimedConvolution.stack([data, readings])
        S = timed_term(kernel, joint).covariance()
        M = data.n_outputs
        cross = S[M:, :M]
        mean = cross @ posterior.alpha
        V = linalg.solve_triangular(posterior.L, cross.T, lower=True, check_finite=False)
        var = np.diag(S[M:, M:]) - np.einsum("ij,ij->j", V, V)
        return mean, np.maximum(var, 0.0)
    term = timed_term(kernel, readings)
    prior = np.diag(term.covariance())
    with_lags = term.regressor_times_kernel()  # Cov(readings, g(0..P-1))
    K = kernel(data.lags)
    jitter = 1e-10 * max(float(np.mean(np.diag(K))), 1e-300)
    factor = linalg.cho_factor(K + jitter * np.eye(K.shape[0]), lower=True)
    A = linalg.cho_solve(factor, with_lags.T).T  # Cov(r, g) K^{-1}
    mean, posterior_var = posterior.linear_map(A)
    var = prior - np.einsum("ij,ij->i", A, with_lags) + posterior_var
    return mean, np.maximum(var, 0.0)
