"""Argument checks shared by the public entry points.

Every check raises :class:`ValueError` (or :class:`TypeError` for an object of
the wrong kind) with a message that starts with the argument's name.
"""

from __future__ import annotations

import numbers

import numpy as np


def check_signal(x, name: str, *, min_length: int = 1) -> np.ndarray:
    """Return ``x`` as a new finite 1-D float array."""
    if isinstance(x, (str, bytes)) or x is None:
        raise ValueError(f"{name} must be a 1-D array of real numbers; got {type(x).__name__}")
    try:
        arr = np.array(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a 1-D array of real numbers") from exc
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
        expected = f"{low}..{high}" if high is not None else f">= {low}"
        raise ValueError(f"{name} must be in {expected}; got {value}")
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
