"""Validation metrics."""

from __future__ import annotations

import numpy as np

from gpmultirate.validation import check_signal

__all__ = ["goodness_of_fit"]


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
    y_true = check_signal(y_true, "y_true")
    y_pred = check_signal(y_pred, "y_pred")
    if y_true.shape != y_pred.shape:
        raise ValueError(
            f"y_pred must have the length of y_true ({y_true.shape[0]}); got {y_pred.shape[0]}"
        )
    spread = np.sum((y_true - y_true.mean()) ** 2)
    if np.ptp(y_true) == 0 or spread == 0:
        raise ValueError("y_true must not be constant: the goodness of fit is undefined")
    return float(100.0 * (1.0 - np.sum((y_true - y_pred) ** 2) / spread))
