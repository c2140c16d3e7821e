"""Validation metrics."""

from __future__ import annotations

import numpy as np

from gpmultirate.validation import check_signal

__all__ = ["goodness_of_fit", "fit_percent"]


def goodness_of_fit(y_true, y_pred) -> float:
    """Goodness of fit in percent (paper eq. 20).

    ``100 (1 - ||y - y_hat||^2 / ||y - mean(y)||^2)``: 100 is a perfect fit,
    0 is as good as the mean, and it is unbounded below.

    Parameters
    ----------
    y_true : array-like of shape (n,)
        Measured (validation) output; must not be constant.
    y_pred : array-like of shape (n,)
        Model output.

    Returns
    -------
    float

    Examples
    --------
    >>> from gpmultirate import goodness_of_fit
    >>> goodness_of_fit([1.0, 2.0, 3.0], [1.0, 2.0, 2.0])
    50.0
    """
    spread, error = _squared_norms(y_true, y_pred)
    return float(100.0 * (1.0 - error / spread))


def fit_percent(y_true, y_pred) -> float:
    """Normalized fit in percent, as MATLAB's ``compare`` reports it.

    ``100 (1 - ||y - y_hat|| / ||y - mean(y)||)`` with Euclidean norms (not
    squared, unlike :func:`goodness_of_fit`): 100 is a perfect fit, 0 is as
    good as the mean, and it is unbounded below.  For the same prediction,
    ``fit = 100 (1 - sqrt(1 - GoF / 100))``.

    Parameters
    ----------
    y_true : array-like of shape (n,)
        Measured (validation) output; must not be constant.
    y_pred : array-like of shape (n,)
        Model output.

    Returns
    -------
    float

    Examples
    --------
    >>> from gpmultirate.metrics import fit_percent
    >>> fit_percent([1.0, 2.0, 3.0], [1.0, 2.0, 2.0])
    29.28932188134524
    """
    spread, error = _squared_norms(y_true, y_pred)
    return float(100.0 * (1.0 - np.sqrt(error / spread)))


def _squared_norms(y_true, y_pred) -> tuple[float, float]:
    """``||y - mean(y)||^2`` and ``||y - y_hat||^2`` of checked signals."""
    y_true = check_signal(y_true, "y_true")
    y_pred = check_signal(y_pred, "y_pred")
    if y_true.shape != y_pred.shape:
        raise ValueError(
            f"y_pred must have the length of y_true ({y_true.shape[0]}); got {y_pred.shape[0]}"
        )
    spread = np.sum((y_true - y_true.mean()) ** 2)
    if np.ptp(y_true) == 0 or spread == 0:
        raise ValueError("y_true must not be constant: the fit is undefined")
    return float(spread), float(np.sum((y_true - y_pred) ** 2))
