"""From the user's arrays to an observation: records, inputs, instants and missing samples.

:func:`build_experiment` checks ``u``, ``y_slow`` and ``sample_indices`` as
the estimators accept them and returns the observation of the used slow
samples with those samples.  The paper's case (one record from rest, one
input, a slow sample every ``factor`` fast samples, none missing) stays a
:class:`~gpmultirate.observations.DownsampledConvolution`, with every fast
path of the uniform structure.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gpmultirate.observations.base import Observation
from gpmultirate.observations.convolution import DownsampledConvolution
from gpmultirate.observations.sampled import (
    RecordStack,
    SampledConvolution,
    check_initial_conditions,
)
from gpmultirate.validation import as_real_array, check_inputs, check_int, check_sample_indices

__all__ = ["Experiment", "build_experiment", "check_records", "is_record_list", "is_record_pair"]


@dataclass
class Experiment:
    """The observation of the used slow samples.

    Attributes
    ----------
    observation : Observation
    y : ndarray of shape (M,)
        The used slow samples (finite, and for ``"discard"`` late enough),
        records concatenated.
    n_inputs : int
    """

    observation: Observation
    y: np.ndarray
    n_inputs: int


def is_record_list(x) -> bool:
    """Whether ``x`` is a list of records: a list or tuple of arrays (not of numbers)."""
    return (
        isinstance(x, (list, tuple)) and len(x) > 0
        and all(isinstance(e, (list, tuple, np.ndarray)) and np.ndim(e) >= 1 for e in x)
    )


def is_record_pair(u, y_slow) -> bool:
    """Whether ``u`` and ``y_slow`` are records: both lists (or tuples) of arrays.

    Otherwise each is one array-like, as in scikit-learn: ``u2.tolist()`` is
    the array ``u2``, ``y[:, None].tolist()`` the column ``y[:, None]``.

    Examples
    --------
    >>> import numpy as np
    >>> is_record_pair([np.ones(4), np.ones(6)], [np.ones(2), np.ones(3)])
    True
    >>> is_record_pair([[1.0, 2.0], [3.0, 4.0]], np.ones(2))
    False
    """
    return is_record_list(u) and is_record_list(y_slow)


def records_of(u, y_slow) -> bool:
    """:func:`is_record_pair`, refusing records of ``u`` (a list of numpy arrays) whose
    ``y_slow`` is one array: reading them as one array would be a silent mistake."""
    several_records = is_record_pair(u, y_slow)
    if not several_records and is_record_list(u) and all(isinstance(e, np.ndarray) for e in u):
        raise ValueError(
            f"y_slow must be a list with one entry per record of u ({len(u)}); "
            f"got {type(y_slow).__name__}"
        )
    return several_records


def check_records(u, name: str = "u", several_records: bool | None = None):
    """``(inputs, several_records)``: each record's input as ``(N, n_inputs)``, and whether
    ``u`` was a list of records.  A single input given as a column ``(N, 1)`` is one input.
    ``several_records`` overrides the reading of ``u`` alone (:func:`is_record_list`)."""
    if several_records is None:
        several_records = is_record_list(u)
    records = list(u) if several_records else [u]
    if not records:
        raise ValueError(f"{name} must hold at least one record; got an empty list")
    inputs = []
    for r, u_r in enumerate(records):
        label = f"{name}[{r}]" if several_records else name
        inputs.append(check_inputs(u_r, label))
        if inputs[-1].shape[1] != inputs[0].shape[1]:
            raise ValueError(
                f"{label} has {inputs[-1].shape[1]} inputs; {name}[0] has {inputs[0].shape[1]}: "
                "every record needs the same inputs"
            )
    return inputs, several_records


def _slow_samples(y, label: str) -> np.ndarray:
    y = as_real_array(y, label)
    if y.ndim == 2 and 1 in y.shape and y.size > 0:
        y = y.reshape(-1)
    if y.ndim != 1 or y.shape[0] == 0:
        raise ValueError(f"{label} must be a non-empty 1-D array; got shape {y.shape}")
    if np.any(np.isinf(y)):
        raise ValueError(f"{label} must not contain inf (NaN marks a sample that was not measured)")
    return y


def build_experiment(
    u, y_slow, sample_indices=None, *, factor=1, offset=0, order=None,
    initial_conditions="zero",
) -> Experiment:
    """Check the data of a fit and build the observation of its used slow samples.

    Parameters
    ----------
    u : array-like of shape (N,) or (N, n_inputs), or a list of them
        The input(s); a list holds one record per entry.
    y_slow : array-like of shape (M,), or a list of them
        The slow samples; ``NaN`` marks one that was not measured.
    sample_indices : array-like of int, or a list of them, optional
        The fast-sample index of each entry of ``y_slow``; by default
        ``offset + m * factor``.
    factor, offset : int
        Used when ``sample_indices`` is None.
    order : int or None
        ``P``; by default the length of the longest record.
    initial_conditions : {"zero", "discard", "periodic"}

    Returns
    -------
    Experiment

    Examples
    --------
    >>> import numpy as np
    >>> u = np.arange(1.0, 10.0)
    >>> experiment = build_experiment(u, [1.0, np.nan, 3.0], factor=3, order=4)
    >>> experiment.observation.sample_indices, experiment.y
    (array([0, 6]), array([1., 3.]))
    """
    several_records = records_of(u, y_slow)
    inputs, several_records = check_records(u, several_records=several_records)
    if several_records:
        if not is_record_list(y_slow) or len(y_slow) != len(inputs):
            raise ValueError(
                f"y_slow must be a list with one entry per record of u ({len(inputs)}); "
                f"got {type(y_slow).__name__}"
                + (f" of length {len(y_slow)}" if isinstance(y_slow, (list, tuple)) else "")
            )
        if sample_indices is not None and (
            not is_record_list(sample_indices) or len(sample_indices) != len(inputs)
        ):
            raise ValueError(
                f"sample_indices must be a list with one entry per record of u ({len(inputs)})"
            )
    ys = list(y_slow) if several_records else [y_slow]
    indices = (
        [None] * len(inputs) if sample_indices is None
        else (list(sample_indices) if several_records else [sample_indices])
    )
    ic = check_initial_conditions(initial_conditions)
    factor = check_int(factor, "factor", low=1)
    offset = check_int(offset, "offset", low=0, high=factor - 1)
    longest = max(x.shape[0] for x in inputs)
    high = longest if ic == "zero" else min(x.shape[0] for x in inputs)
    order = high if order is None else check_int(order, "order", low=1, high=high)
    n_inputs = inputs[0].shape[1]

    observations, used_y = [], []
    for r, (x, y, index) in enumerate(zip(inputs, ys, indices)):
        label = f"[{r}]" if several_records else ""
        y = _slow_samples(y, "y_slow" + label)
        N = x.shape[0]
        if index is None:
            if offset >= N:
                raise ValueError(f"offset must be smaller than len(u{label}) = {N}; got {offset}")
            index = np.arange(offset, N, factor)
            if y.shape[0] != index.shape[0]:
                raise ValueError(
                    f"y_slow{label} must have len(range(offset, len(u{label}), factor)) = "
                    f"{index.shape[0]} samples; got {y.shape[0]}"
                )
        else:
            index = check_sample_indices(index, N, "sample_indices" + label)
            if index.shape[0] != y.shape[0]:
                raise ValueError(
                    f"sample_indices{label} must have one entry per sample of y_slow{label} "
                    f"({y.shape[0]}); got {index.shape[0]}"
                )
        measured = np.isfinite(y)
        if not np.any(measured):
            raise ValueError(f"y_slow{label} has no finite sample: nothing was measured")
        plain = (
            not several_records and sample_indices is None and bool(np.all(measured))
            and ic == "zero" and n_inputs == 1 and order <= N
        )
        if plain:
            observation = DownsampledConvolution(x[:, 0], factor, order, offset)
            observations.append(observation)
            used_y.append(y)
            continue
        try:
            observation = SampledConvolution(x, index[measured], order, ic)
        except ValueError as error:
            raise ValueError(f"record {r}: {error}" if several_records else str(error)) from None
        observations.append(observation)
        used_y.append(y[measured][observation.used])
    observation = observations[0] if len(observations) == 1 else RecordStack(observations)
    return Experiment(observation=observation, y=np.concatenate(used_y), n_inputs=n_inputs)
