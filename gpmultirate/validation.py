"""Argument checks shared by the public entry points.

Every check raises :class:`ValueError` (or :class:`TypeError` for an object of
the wrong kind) with a message that starts with the argument's name.
"""

from __future__ import annotations

import numbers

import numpy as np


def as_real_array(x, name: str) -> np.ndarray:
    """Return a new float array of ``x``; complex, text and objects are refused."""
    if isinstance(x, (str, bytes, dict)) or x is None:
        raise ValueError(f"{name} must be an array of real numbers; got {type(x).__name__}")
    try:
        raw = np.asarray(x)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be an array of real numbers") from exc
    if raw.dtype.kind not in "iuf":
        raise ValueError(
            f"{name} must be an array of real numbers; got dtype {raw.dtype} "
            "(complex values are not accepted)"
        )
    return np.array(raw, dtype=float)


def check_array(x, name: str, *, rows: int | None = None, ndims=(1, 2)) -> np.ndarray:
    """Return ``x`` as a new finite float array with the given dimensions and rows."""
    arr = as_real_array(x, name)
    if arr.ndim not in ndims:
        raise ValueError(f"{name} must have {' or '.join(map(str, ndims))} dimensions; got shape {arr.shape}")
    if rows is not None and arr.shape[0] != rows:
        raise ValueError(f"{name} must have {rows} rows; got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return arr


def check_rng(random_state, name: str = "random_state"):
    """scikit-learn's ``check_random_state`` with errors that name the argument."""
    from sklearn.utils import check_random_state

    if isinstance(random_state, (bool, float, str)):
        raise ValueError(f"{name} must be None, an int seed or a RandomState; got {random_state!r}")
    if isinstance(random_state, np.random.Generator):
        # scikit-learn works with RandomState: seed one from the generator
        return np.random.RandomState(random_state.integers(2**32, dtype=np.uint64))
    try:
        return check_random_state(random_state)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} is invalid: {exc}") from exc


def check_signal(x, name: str, *, min_length: int = 1) -> np.ndarray:
    """Return ``x`` as a new finite 1-D float array."""
    arr = as_real_array(x, name)
    if arr.ndim == 2 and 1 in arr.shape and arr.size > 0:
        arr = arr.reshape(-1)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be 1-D; got shape {arr.shape}")
    if arr.shape[0] < min_length:
        raise ValueError(f"{name} must have at least {min_length} samples; got {arr.shape[0]}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return arr


def check_int(value, name: str, *, low: int, high: int | None = None) -> int:
    """Return ``value`` as an int in ``[low, high]``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{name} must be an integer; got {value!r}")
    value = int(value)
    if value < low or (high is not None and value > high):
        expected = f"in {low}..{high}" if high is not None else f">= {low}"
        raise ValueError(f"{name} must be {expected}; got {value}")
    return value


def check_positive(value, name: str, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a finite positive (or non-negative) float."""
    if isinstance(value, (bool, str)) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a real number; got {value!r}")
    value = float(value)
    ok = value >= 0 if allow_zero else value > 0
    if not np.isfinite(value) or not ok:
        expected = "non-negative" if allow_zero else "positive"
        raise ValueError(f"{name} must be finite and {expected}; got {value!r}")
    return value


def check_level(level, name: str = "level") -> float:
    """Return a credible level in (0, 1)."""
    if isinstance(level, (bool, str)) or not isinstance(level, numbers.Real):
        raise ValueError(f"{name} must be a number in (0, 1); got {level!r}")
    level = float(level)
    if not (0.0 < level < 1.0):
        raise ValueError(f"{name} must be in (0, 1); got {level!r}")
    return level


def check_bounds(bounds, name: str):
    """Return a pair ``(low, high)`` with ``0 < low <= high`` or ``"fixed"``."""
    if isinstance(bounds, str):
        if bounds != "fixed":
            raise ValueError(f"{name} must be a pair (low, high) or 'fixed'; got {bounds!r}")
        return bounds
    try:
        low, high = (float(b) for b in bounds)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a pair (low, high) or 'fixed'; got {bounds!r}") from exc
    if not (np.isfinite(low) and np.isfinite(high) and 0 < low <= high):
        raise ValueError(f"{name} must satisfy 0 < low <= high (finite); got {bounds!r}")
    return (low, high)


def check_inputs(u, name: str = "u") -> np.ndarray:
    """Return the input(s) ``u`` as a new finite float array of shape ``(N, n_inputs)``.

    A 1-D ``u`` is one input.

    Examples
    --------
    >>> check_inputs([1.0, 2.0, 3.0]).shape
    (3, 1)
    """
    arr = as_real_array(u, name)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise ValueError(
            f"{name} must be 1-D (one input) or 2-D of shape (n_samples, n_inputs); "
            f"got shape {arr.shape}"
        )
    if arr.shape[0] < 1 or arr.shape[1] < 1:
        raise ValueError(f"{name} must have at least one sample and one input; got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return np.array(arr, dtype=float)


def check_sample_indices(indices, n_samples: int, name: str = "sample_indices") -> np.ndarray:
    """Return strictly increasing integer fast-sample indices in ``0..n_samples-1``.

    Examples
    --------
    >>> check_sample_indices([0, 3, 7], 10)
    array([0, 3, 7])
    """
    arr = np.asarray(indices)
    if arr.dtype == bool or arr.dtype.kind not in "iuf" or arr.ndim != 1 or arr.size == 0:
        raise ValueError(
            f"{name} must be a non-empty 1-D array of integer fast-sample indices; "
            f"got {arr.dtype} of shape {arr.shape}"
        )
    if arr.dtype.kind == "f":
        if not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr)):
            raise ValueError(f"{name} must hold integers")
    # the range is checked on the values as given: a cast would wrap 1e20 or 2**64 - 1
    if np.any(arr < 0) or np.any(arr > n_samples - 1):
        raise ValueError(
            f"{name} must lie in 0..{n_samples - 1} (the fast samples of u); "
            f"got values from {arr.min():.17g} to {arr.max():.17g}"
            if arr.dtype.kind == "f" else
            f"{name} must lie in 0..{n_samples - 1} (the fast samples of u); "
            f"got values from {arr.min()} to {arr.max()}"
        )
    index = arr.astype(np.int64)
    if index[0] < 0 or index[-1] >= n_samples or np.any(index < 0) or np.any(index >= n_samples):
        raise ValueError(
            f"{name} must lie in 0..{n_samples - 1} (the fast samples of u); "
            f"got values from {index.min()} to {index.max()}"
        )
    if np.any(np.diff(index) <= 0):
        raise ValueError(f"{name} must be strictly increasing")
    return index


def check_n_jobs(n_jobs):
    """Return ``n_jobs`` as joblib takes it: None or a non-zero integer."""
    if n_jobs is None:
        return None
    if isinstance(n_jobs, bool) or not isinstance(n_jobs, numbers.Integral) or n_jobs == 0:
        raise ValueError(
            f"n_jobs must be None or a non-zero integer (negative counts back from all "
            f"CPUs, as in joblib); got {n_jobs!r}"
        )
    return int(n_jobs)


def check_sample_time(value, name: str = "sample_time") -> float:
    """Return a fast sample time in seconds: finite, positive, with ``1 / value`` a normal float.

    Frequencies are ``1 / sample_time`` times cycles per sample; a sample
    time below about ``5.6e-309`` makes them infinite.

    Examples
    --------
    >>> check_sample_time(0.01)
    0.01
    """
    value = check_positive(value, name)
    inverse = 1.0 / value
    if not (np.isfinite(inverse) and inverse >= np.finfo(float).tiny):
        raise ValueError(
            f"{name} must be a sample time in seconds whose inverse (the sample rate) is a "
            f"finite normal float, between {1 / np.finfo(float).max:.3g} and "
            f"{1 / np.finfo(float).tiny:.3g}; got {value!r}"
        )
    return value

