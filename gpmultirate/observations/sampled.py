"""Convolutions sampled at any instants, with several inputs, and several records.

* :class:`SampledConvolution`: the response of an FIR model to the known
  input(s) ``u``, observed at given fast-sample instants (dropped frames,
  a slow clock that is no integer multiple of the fast one), with the
  system at rest before the record (``"zero"``), with an unknown past
  (``"discard"``: only instants whose regressor row needs no unknown input
  are used) or in periodic steady state (``"periodic"``: ``u`` is one period).
* :class:`RecordStack`: several records of the same system, stacked.

Their regressors are built by :func:`~gpmultirate.observations.regressor_rows`,
the one place where eq. (8) is written.
"""

from __future__ import annotations

import numpy as np

from gpmultirate.observations.base import Observation, UniformSampling
from gpmultirate.observations.convolution import regressor_rows
from gpmultirate.observations.gram import extended_input, uniform_gram
from gpmultirate.validation import check_int, check_sample_indices, check_inputs

__all__ = ["INITIAL_CONDITIONS", "RecordStack", "SampledConvolution"]

#: the accepted values of ``initial_conditions``
INITIAL_CONDITIONS = ("zero", "discard", "periodic")
#: how much longer than the instants a uniform grid holding them may be for the
#: diagonal recursion to compute on it (the unmeasured samples are dropped after)
GRID_SLACK = 1.5


def check_initial_conditions(value) -> str:
    """Return ``value`` if it is one of :data:`INITIAL_CONDITIONS`, else raise ValueError."""
    if not isinstance(value, str) or value not in INITIAL_CONDITIONS:
        raise ValueError(
            f"initial_conditions must be one of {', '.join(map(repr, INITIAL_CONDITIONS))}; "
            f"got {value!r}"
        )
    return value


class SampledConvolution(Observation):
    """The response to known inputs, observed at given fast-sample instants.

    ``y[m] = sum_k sum_{i<P} g_k(i) u_k(n_m - i)`` with ``n_m`` the entries
    of ``sample_indices``.

    Parameters
    ----------
    u : array-like of shape (N,) or (N, n_inputs)
        The fast-rate input(s).
    sample_indices : array-like of int
        Strictly increasing fast-sample indices in ``0..N-1``.
    order : int
        FIR order ``P``, at least 1 (at most ``N`` unless the initial
        conditions are ``"zero"``).
    initial_conditions : {"zero", "discard", "periodic"}, default="zero"
        ``"zero"``: the input is zero before the record; ``"discard"``: it
        is unknown, so only instants ``n >= P - 1`` are used (see
        :attr:`used`); ``"periodic"``: ``u`` is one period of a periodic
        input in steady state, ``u(n) = u(n mod N)``.

    Attributes
    ----------
    sample_indices : ndarray
        The instants that are used.
    used : ndarray of bool
        Which of the given instants are used (all but, with ``"discard"``,
        those before ``P - 1``).
    n_inputs : int

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import SampledConvolution
    >>> op = SampledConvolution(np.arange(1.0, 7.0), [0, 3, 4], order=3)
    >>> op.matrix
    array([[1., 0., 0.],
           [4., 3., 2.],
           [5., 4., 3.]])
    >>> u = np.column_stack([np.arange(1.0, 7.0), np.ones(6)])
    >>> SampledConvolution(u, [1, 5], order=2, initial_conditions="periodic").matrix
    array([[2., 1., 1., 1.],
           [6., 5., 1., 1.]])
    """

    def __init__(self, u, sample_indices, order: int, initial_conditions: str = "zero"):
        inputs = check_inputs(u, "u")
        n_samples = inputs.shape[0]
        self.initial_conditions = check_initial_conditions(initial_conditions)
        high = None if self.initial_conditions == "zero" else n_samples
        self.order = check_int(order, "order", low=1, high=high)
        given = check_sample_indices(sample_indices, n_samples, "sample_indices")
        if self.initial_conditions == "discard":
            used = given >= self.order - 1
            if not np.any(used):
                raise ValueError(
                    f"initial_conditions='discard' leaves no slow sample: every instant is "
                    f"before order - 1 = {self.order - 1}; use a lower order or a longer record"
                )
        else:
            used = np.ones(given.shape[0], dtype=bool)
        inputs.setflags(write=False)
        self.u = inputs[:, 0] if inputs.shape[1] == 1 else inputs
        self._inputs = inputs
        self.n_inputs = inputs.shape[1]
        self.used = used
        self.used.setflags(write=False)
        self.sample_indices = given[used]
        self.sample_indices.setflags(write=False)
        self._matrix = None
        self._blocks = {}

    @property
    def n_samples(self) -> int:
        return self._inputs.shape[0]

    @property
    def n_outputs(self) -> int:
        return self.sample_indices.shape[0]

    @property
    def slow_factor(self) -> int:
        """The median spacing of the instants: the ratio of the fast to the mean slow rate."""
        spacing = np.diff(self.sample_indices)
        return max(1, int(round(float(np.median(spacing))))) if spacing.size else 1

    @property
    def uniform_sampling(self) -> UniformSampling | None:
        """The uniform grid of a single input from rest that holds the instants, if any.

        The instants are the grid ``offset + m * F`` or most of it (samples
        missing from a uniform sampling): a grid at most
        ``GRID_SLACK`` times as long as the instants, starting before ``F``.
        """
        index = self.sample_indices
        if self.n_inputs != 1 or self.initial_conditions != "zero" or index.shape[0] < 2:
            return None
        step = int(np.gcd.reduce(np.diff(index)))
        offset = int(index[0]) % step
        n_grid = (int(index[-1]) - offset) // step + 1
        if n_grid > GRID_SLACK * index.shape[0]:
            return None
        if n_grid == index.shape[0]:
            return UniformSampling(self.u, step, offset, n_grid)
        return UniformSampling(self.u, step, offset, n_grid, (index - offset) // step)

    def structured_gram(self, y=None):
        """``Phi^T Phi`` and ``Phi^T y`` by FFT when the instants lie on a uniform grid.

        The grid is ``first + m * step`` with ``step`` the greatest common
        divisor of the spacings; when at least half of it is observed, the
        Gram of the whole grid (:mod:`~gpmultirate.observations.gram`) less
        the rows of the missing instants, else None (no structure).
        """
        index = self.sample_indices
        if index.shape[0] < 2:
            return None
        step = int(np.gcd.reduce(np.diff(index)))
        first = int(index[0])
        n_grid = (int(index[-1]) - first) // step + 1
        if n_grid > 2 * index.shape[0]:
            return None
        on_grid = (index - first) // step
        skip = np.setdiff1d(np.arange(n_grid), on_grid)
        grid_y = None
        if y is not None:
            grid_y = np.zeros(n_grid)
            grid_y[on_grid] = y
        periodic = self.initial_conditions == "periodic"
        extended = np.stack(
            [extended_input(self._inputs[:, k], self.order, periodic) for k in range(self.n_inputs)]
        )
        return uniform_gram(extended, first, step, n_grid, self.order, grid_y, skip=skip)

    def _rows(self, rows, k: int, view: bool = False) -> np.ndarray:
        return regressor_rows(
            self._inputs[:, k], self.order, rows, view=view,
            periodic=self.initial_conditions == "periodic",
        )

    @property
    def matrix(self) -> np.ndarray:
        """The regressor, ``(M, n_inputs * P)`` input-major (built once, read-only)."""
        if self._matrix is None:
            matrix = self.regressor_rows(0, self.n_outputs)
            matrix.setflags(write=False)
            self._matrix = matrix
        return self._matrix

    def regressor_rows(self, start: int, stop: int) -> np.ndarray:
        """Rows ``start..stop-1`` of ``Phi``, without forming the rest."""
        if self._matrix is not None:
            return self._matrix[start:stop]
        rows = self.sample_indices[start:stop]
        return np.hstack([self._rows(rows, k) for k in range(self.n_inputs)])

    def regressor_view(self) -> np.ndarray:
        """A strided view of the regressor when the instants are uniform, else the matrix."""
        sampling = self.uniform_sampling
        if sampling is None or sampling.selection is not None or sampling.offset != self.sample_indices[0]:
            return self.matrix
        return self._rows(self.sample_indices, 0, view=True)

    def input_block(self, k: int) -> "SampledConvolution":
        """The observation of input ``k`` alone, at the same instants."""
        if self.n_inputs == 1:
            return self
        if k not in self._blocks:
            block = SampledConvolution.__new__(SampledConvolution)
            block.__dict__.update(
                self.__dict__, u=self._inputs[:, k], _inputs=self._inputs[:, k : k + 1],
                n_inputs=1, _matrix=None, _blocks={}, _gram=None,
            )
            self._blocks[k] = block
        return self._blocks[k]

    def __eq__(self, other) -> bool:
        if not isinstance(other, SampledConvolution):
            return NotImplemented
        return (
            self.order == other.order
            and self.initial_conditions == other.initial_conditions
            and np.array_equal(self.sample_indices, other.sample_indices)
            and np.array_equal(self._inputs, other._inputs)
        )

    __hash__ = None

    def __setstate__(self, state):
        self.__dict__.update(state)
        for name in ("_inputs", "used", "sample_indices"):
            array = np.array(getattr(self, name))
            array.setflags(write=False)
            setattr(self, name, array)
        self.u = self._inputs[:, 0] if self._inputs.shape[1] == 1 else self._inputs

    def __repr__(self) -> str:
        return (
            f"SampledConvolution(N={self.n_samples}, n_inputs={self.n_inputs}, "
            f"order={self.order}, M={self.n_outputs}, "
            f"initial_conditions={self.initial_conditions!r})"
        )


class RecordStack(Observation):
    """Several records of one system: their observations stacked row-wise.

    The records share the coefficients (and so the order and the number of
    inputs); their outputs are concatenated in order.

    Parameters
    ----------
    records : sequence of Observation
        At least one; equal ``order`` and ``n_inputs``.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.observations import RecordStack
    >>> first = DownsampledConvolution(np.arange(1.0, 5.0), factor=2, order=2)
    >>> second = DownsampledConvolution(np.ones(3), factor=1, order=2)
    >>> RecordStack([first, second]).matrix
    array([[1., 0.],
           [3., 2.],
           [1., 0.],
           [1., 1.],
           [1., 1.]])
    """

    def __init__(self, records):
        records = list(records)
        if not records:
            raise ValueError("records must hold at least one observation")
        first = records[0]
        for i, record in enumerate(records):
            if record.order != first.order or record.n_inputs != first.n_inputs:
                raise ValueError(
                    f"record {i} has order {record.order} and {record.n_inputs} inputs; "
                    f"record 0 has order {first.order} and {first.n_inputs} inputs"
                )
        self._records = records
        self.order = first.order
        self.n_inputs = first.n_inputs
        self.starts = np.cumsum([0] + [r.n_outputs for r in records])
        self.n_outputs = int(self.starts[-1])
        self._matrix = None
        self._blocks = {}

    @property
    def matrix(self) -> np.ndarray:
        if self._matrix is None:
            matrix = np.vstack([record.matrix for record in self._records])
            matrix.setflags(write=False)
            self._matrix = matrix
        return self._matrix

    @property
    def records(self) -> list:
        """The stacked records."""
        return list(self._records)

    @property
    def n_samples(self) -> int:
        """The length of the longest record."""
        return max(record.n_samples for record in self._records)

    @property
    def slow_factor(self) -> int:
        """The median over the records of their slow factors."""
        return max(1, int(round(float(np.median([r.slow_factor for r in self._records])))))

    def regressor_rows(self, start: int, stop: int) -> np.ndarray:
        """Rows ``start..stop-1`` of the stacked regressor, read from the records."""
        parts = []
        for record, first in zip(self._records, self.starts[:-1]):
            low, high = max(start, first), min(stop, first + record.n_outputs)
            if low < high:
                parts.append(record.regressor_rows(low - first, high - first))
        if not parts:
            return np.zeros((0, self.n_coefficients))
        return np.vstack(parts)

    def structured_gram(self, y=None):
        """The sum of the records' Gram matrices when every record has a structured one, else None."""
        gram, projection = 0.0, None if y is None else 0.0
        for record, start, stop in zip(self._records, self.starts[:-1], self.starts[1:]):
            found = record.structured_gram(None if y is None else y[start:stop])
            if found is None:
                return None
            gram = gram + found[0]
            if y is not None:
                projection = projection + found[1]
        return gram, projection

    def input_block(self, k: int) -> "RecordStack":
        """The records' observations of input ``k`` alone."""
        if self.n_inputs == 1:
            return self
        if k not in self._blocks:
            self._blocks[k] = RecordStack([record.input_block(k) for record in self._records])
        return self._blocks[k]

    def __eq__(self, other) -> bool:
        if not isinstance(other, RecordStack):
            return NotImplemented
        return len(self._records) == len(other.records) and all(
            a == b for a, b in zip(self._records, other.records)
        )

    __hash__ = None

    def __repr__(self) -> str:
        return f"RecordStack({len(self._records)} records, order={self.order}, M={self.n_outputs})"
