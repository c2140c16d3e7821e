"""Choosing the FIR order: a step of its own that returns what it chose.

:class:`~gpmultirate.FIRGaussianProcess` fits at one order.  The order
itself is chosen here, in steps that each return their result and leave the
estimator alone:

* :func:`select_order`: ``order="auto"`` or a list of candidates; every
  candidate is fitted and the one the tuning criterion prefers (per used
  slow sample) is returned, with the table of every candidate's score;
* :func:`held_out_fits`: the held-out check after evidence tuning, the fit
  in percent of held-out slow samples predicted at several orders with the
  same hyperparameters and the same folds.

The estimator turns these results into its attributes
(``order_selection_``) and fits at the chosen order.
"""

from __future__ import annotations

import numbers
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from gpmultirate.crossvalidation import held_out_predictions
from gpmultirate.metrics import fit_percent
from gpmultirate.validation import check_int

__all__ = [
    "MAX_CHECKED_SAMPLES",
    "MIN_CHECKED_ORDER",
    "OrderSelection",
    "auto_orders",
    "held_out_fits",
    "order_candidates",
    "select_order",
]

# the held-out check after evidence tuning: its shortest order; the most slow
# samples it checks (each candidate order needs M x M matrices)
MIN_CHECKED_ORDER = 10
MAX_CHECKED_SAMPLES = 4000


def auto_orders(longest: int) -> list[int]:
    """The candidate orders of ``order="auto"``: ``N, N/2, ..., N/32``, at least 10.

    Examples
    --------
    >>> auto_orders(600)
    [18, 37, 75, 150, 300, 600]
    >>> auto_orders(12)
    [12]
    """
    orders = {longest} | {longest // 2**k for k in range(1, 6) if longest // 2**k >= 10}
    return sorted(orders)


def order_candidates(order):
    """None for one order (an int or None), ``"auto"``, or the checked sorted list of candidates.

    Examples
    --------
    >>> order_candidates(40) is None, order_candidates("auto"), order_candidates([60, 30, 60])
    (True, 'auto', [30, 60])
    """
    if order is None or isinstance(order, numbers.Integral) and not isinstance(order, bool):
        return None
    if isinstance(order, str):
        if order == "auto":
            return "auto"
        raise ValueError(f"order must be an integer, 'auto' or a list of integers; got {order!r}")
    try:
        candidates = [check_int(o, "order", low=1) for o in order]
    except TypeError:
        raise ValueError(
            f"order must be an integer, 'auto' or a list of integers; got {order!r}"
        ) from None
    if not candidates:
        raise ValueError("order must not be an empty list")
    return sorted(set(candidates))


@dataclass(frozen=True)
class OrderSelection:
    """The result of :func:`select_order`.

    Attributes
    ----------
    order : int
        The chosen order.
    table : dict
        ``"order"`` (the candidates), ``"score"`` (the criterion per used
        slow sample, higher is better), ``"criterion"`` (``"log_evidence"``
        or ``"cv_log_predictive"``) and ``"best_order"``: the estimator's
        ``order_selection_``.
    fit : object
        What ``fit_at`` returned for the chosen order (the estimator adopts
        it instead of fitting that order again).

    Examples
    --------
    >>> OrderSelection(order=30, table={"best_order": 30}, fit=None).order
    30
    """

    order: int
    table: dict
    fit: object


def select_order(
    fit_at: Callable[[int], object],
    candidates: Sequence[int],
    criterion: str = "evidence",
) -> OrderSelection:
    """Fit every candidate order and return the one the criterion prefers.

    Parameters
    ----------
    fit_at : callable
        ``fit_at(order)`` fits at one order and returns an object with
        ``log_marginal_likelihood_value_``, ``cv_log_predictive_likelihood_``
        (for ``criterion="cross_validation"``) and ``y_slow_`` (the used slow
        samples).
    candidates : sequence of int
    criterion : {"evidence", "cross_validation"}
        The log evidence, or the cross-validated log predictive likelihood,
        each divided by the number of used slow samples (``"discard"`` uses
        fewer at higher orders).

    Returns
    -------
    OrderSelection
        The warnings of the chosen order's fit are issued again; those of
        the others are dropped (they do not concern the fitted model).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> import numpy as np
    >>> def fit_at(order):
    ...     return SimpleNamespace(log_marginal_likelihood_value_=-abs(order - 40.0),
    ...                            y_slow_=np.zeros(10))
    >>> select_order(fit_at, [20, 40, 80]).order
    40
    """
    fits, caught = [], []
    for order in candidates:
        with warnings.catch_warnings(record=True) as record:
            warnings.simplefilter("always")
            fits.append(fit_at(order))
        caught.append(record)
    if criterion == "evidence":
        values = [f.log_marginal_likelihood_value_ for f in fits]
    else:
        values = [f.cv_log_predictive_likelihood_ for f in fits]
    scores = np.array([v / f.y_slow_.shape[0] for v, f in zip(values, fits)])
    best = int(np.argmax(scores))
    for w in caught[best]:  # only the kept model's warnings concern the user
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    table = {
        "order": np.array(candidates),
        "score": scores,
        "criterion": "log_evidence" if criterion == "evidence" else "cv_log_predictive",
        "best_order": int(candidates[best]),
    }
    return OrderSelection(order=int(candidates[best]), table=table, fit=fits[best])


def held_out_fits(
    observation_at: Callable[[int], object],
    orders: Sequence[int],
    kernel,
    noise_level: float,
    y: np.ndarray,
    folds,
) -> dict[int, float] | None:
    """The fit in percent of held-out slow samples at each order, same hyperparameters and folds.

    Parameters
    ----------
    observation_at : callable
        ``observation_at(order)``: the observation of the data at that order.
    orders : sequence of int
    kernel, noise_level
        The tuned prior and noise variance, shared by every order.
    y : ndarray of shape (M,)
        The used slow samples.
    folds : list of ndarray
        The held-out samples of each fold
        (:func:`~gpmultirate.crossvalidation.contiguous_folds`).

    Returns
    -------
    dict or None
        ``{order: fit_percent}``; None where a fold cannot be predicted.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.crossvalidation import contiguous_folds
    >>> from gpmultirate.kernels import DC
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(90)
    >>> y = np.convolve(u, 0.8 ** np.arange(30))[:90][::3]
    >>> fits = held_out_fits(lambda p: DownsampledConvolution(u, 3, p), [10, 30],
    ...                      DC(0.8, 0.9), 1e-4, y, contiguous_folds([30], 3))
    >>> sorted(fits)
    [10, 30]
    """
    fits = {}
    for order in orders:
        observation = observation_at(order)
        try:
            mean, _ = held_out_predictions(observation, kernel, noise_level, y, folds)
        except ValueError:
            return None
        fits[order] = fit_percent(y, mean)
    return fits

