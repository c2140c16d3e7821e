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
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from gpmultirate.crossvalidation import held_out_predictions
from gpmultirate.metrics import fit_percent
from gpmultirate.validation import check_int

__all__ = [
    "DefaultOrder",
    "MAX_CHECKED_SAMPLES",
    "MIN_CHECKED_ORDER",
    "OrderSelection",
    "auto_orders",
    "default_order",
    "held_out_fits",
    "order_candidates",
    "prior_envelope_lag",
    "prior_tail_lag",
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


# ---------------------------------------------------------------- the default order
#: records of at most this many fast samples keep the default order ``P = N``
SHORT_RECORD = 2048
#: the first order the default rule fits on a longer record; it doubles from there
PILOT_ORDER = 512
#: the prior's tail beyond the chosen order adds at most this fraction of the
#: noise variance to the output (for an input of the record's power)
TAIL_TOLERANCE = 1e-2
#: the shortest order the default rule chooses
MIN_DEFAULT_ORDER = 10
#: the prior's variance has decayed when it stays below ``exp(-ENVELOPE_DECAY)``
#: of its peak: the default prior's slowest decay within an order ``P``
#: (:func:`~gpmultirate.resonances.slowest_decay`) reaches ``exp(-4)`` at lag
#: ``P``, so a prior tuned within 10 % of that bound reads as not decayed
ENVELOPE_DECAY = 4.4
#: log evidence (nats) a doubled pilot order must gain over the previous
#: one for the doubling to go on when the prior has not decayed
EVIDENCE_GAIN = 2.0
#: a last pilot's tuned prior negligible beyond at most this share of its
#: order is cut there, its hyperparameters held (``trim`` of
#: :func:`default_order`): the steps after the fit (bands, the state-space
#: reduction, modal draws) cost about the square of the order, so a cut to
#: 3/4 saves about 40 % of them, while the cut costs one posterior at the
#: shorter order (on a camera log of ``benchmarks/camera_log.py`` cut from
#: 7,992 to 4,037 lags: 5 s, and the steps after the fit 71 s to 26 s);
#: closer to the order the saving falls towards that cost
TRIM_SHARE = 0.75


def prior_tail_lag(kernel, input_power, noise_level: float, n_lags: int,
                   tolerance: float = TAIL_TOLERANCE) -> int:
    """The lag beyond which the prior's impulse response is negligible against the noise.

    The smallest ``L`` such that, for every input ``k``,
    ``power_k * sum_{L <= t < n_lags} k_k(t, t) <= tolerance * noise_level``:
    the output variance the prior gives the lags ``L..n_lags-1`` for an
    input of power ``power_k`` (white) is a small fraction of the noise
    variance.  ``n_lags`` when no such lag is within the window (the prior
    has not decayed: the window is too short).

    Parameters
    ----------
    kernel : sklearn Kernel
        The tuned prior over lag: one input, or a
        :class:`~gpmultirate.kernels.PerInputKernel` (points ``(input, lag)``).
    input_power : sequence of float
        ``mean(u_k**2)`` of each input.
    noise_level : float
        The noise variance.
    n_lags : int
        The window, usually the order the prior was tuned at.
    tolerance : float, default=TAIL_TOLERANCE

    Returns
    -------
    int in ``1..n_lags``

    Examples
    --------
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate.kernels import DC
    >>> # variance 0.9**t: the tail from L sums to 10 * 0.9**L, below 1e-2 * 1e-2 from L = 110
    >>> prior_tail_lag(C(1.0) * DC(alpha=0.9, beta=0.5), [1.0], 1e-2, 400)
    110
    >>> prior_tail_lag(C(1.0) * DC(alpha=0.9, beta=0.5), [1.0], 1e-2, 50)
    50
    """
    lags = np.arange(n_lags, dtype=float)
    powers = [float(p) for p in input_power]
    if len(powers) == 1:
        variances = [kernel.diag(lags[:, None])]
    else:
        variances = [
            kernel.diag(np.column_stack([np.full(n_lags, float(k)), lags]))
            for k in range(len(powers))
        ]
    lag = 1
    for power, variance in zip(powers, variances):
        tail = power * np.cumsum(np.maximum(variance, 0.0)[::-1])[::-1]
        small = np.flatnonzero(tail <= tolerance * noise_level)
        lag = max(lag, int(small[0]) if small.size else n_lags)
    return lag


def prior_envelope_lag(kernel, n_inputs: int, n_lags: int,
                       decay: float = ENVELOPE_DECAY) -> int:
    """The lag from which the prior's variance stays below ``exp(-decay)`` of its peak.

    The smallest ``L`` such that, for every input, the prior variance
    ``k(t, t)`` of every lag ``L <= t < n_lags`` is at most
    ``exp(-decay)`` times its largest value over the window; ``n_lags``
    when no such lag is within the window.  Where
    :func:`prior_tail_lag` weighs the prior's tail against the noise (a
    prior scaled down by a large noise estimate looks negligible early),
    this reads the shape of the tuned decay alone: a prior tuned to the
    slowest decay the order allows (the default prior's bound,
    :func:`~gpmultirate.resonances.slowest_decay`, ``exp(-4)`` at lag
    ``P``) reaches beyond the order, and an order chosen at least this
    long lets the default prior at that order hold the decay the data
    asked for.

    Parameters
    ----------
    kernel : sklearn Kernel
        One input, or a :class:`~gpmultirate.kernels.PerInputKernel`.
    n_inputs : int
    n_lags : int
    decay : float, default=ENVELOPE_DECAY

    Returns
    -------
    int in ``1..n_lags``

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.kernels import DC
    >>> # variance 0.99**t falls below exp(-4.4) from lag 438
    >>> prior_envelope_lag(DC(alpha=0.99, beta=0.5), 1, 1000)
    438
    >>> # the default prior's slowest decay within 512 lags reaches beyond them
    >>> prior_envelope_lag(DC(alpha=np.exp(-4 / 512), beta=0.5), 1, 1024) > 512
    True
    """
    lags = np.arange(n_lags, dtype=float)
    if n_inputs == 1:
        variances = [kernel.diag(lags[:, None])]
    else:
        variances = [kernel.diag(np.column_stack([np.full(n_lags, float(k)), lags]))
                     for k in range(n_inputs)]
    lag = 1
    for variance in variances:
        variance = np.maximum(variance, 0.0)
        peak = variance.max()
        if peak == 0.0:
            continue
        above = np.flatnonzero(variance > np.exp(-decay) * peak)
        lag = max(lag, int(above[-1]) + 1 if above.size else 1)
    return min(lag, n_lags)


@dataclass(frozen=True)
class DefaultOrder:
    """The result of :func:`default_order`.

    Attributes
    ----------
    order : int
        The chosen order.
    table : dict
        ``"order"`` (the orders fitted, in turn), ``"score"`` (the lag
        beyond which each one's tuned prior is negligible against the
        noise, :func:`prior_tail_lag`), ``"criterion"``
        (``"prior_tail"``) and ``"best_order"``: the estimator's
        ``order_selection_``.
    fit : object or None
        What ``fit_at`` returned at the chosen order, when it was fitted
        there (None when the chosen order is shorter than the last fit).

    Examples
    --------
    >>> DefaultOrder(order=300, table={}, fit=None).order
    300
    """

    order: int
    table: dict
    fit: object


def default_order(
    fit_at: Callable[[int], object],
    tail_lag: Callable[[object], int],
    longest: int,
    n_samples: int,
    n_inputs: int = 1,
    log: Callable[[str], None] | None = None,
    evidence: Callable[[object], float] | None = None,
    trim: Callable[[int], object] | None = None,
) -> DefaultOrder:
    """The default FIR order of a record: from the tuned decay of the prior, doubling.

    The rule: fit at ``PILOT_ORDER`` (or ``longest`` if shorter), read the
    lag ``L`` beyond which the tuned prior is negligible against the tuned
    noise (``tail_lag``, read over twice the order: the prior goes on beyond
    it); while ``L`` reaches the order (the prior has not decayed within
    the order tried: the response is longer),
    double the order, at most ``longest``; a doubling that would cross the
    number of slow samples per input stops just below it first (there the
    fit reduces a long record to ``P x P``; at ``M`` close to ``P`` neither
    route is cheap).  The doubling also stops when the doubled order's
    ``evidence`` gains less than ``EVIDENCE_GAIN`` nats over the previous
    one (the data do not support the longer response the prior asks for,
    and each doubling costs up to eight times the last fit); the longer
    order is kept with its fit, or the shorter one, fitted again, where
    the longer one lost evidence.  The order is then ``L``
    (at least ``MIN_DEFAULT_ORDER``) when that is at most half the last
    order fitted or when it makes the fit a long-record one (more slow
    samples than coefficients, ``n_inputs * L < n_samples``) where the last
    fit was not, fitted again; when ``L`` is at most ``TRIM_SHARE`` of the
    last order, the order is ``L`` with the last pilot's hyperparameters
    held (``trim``: the prior beyond ``L`` adds under ``TAIL_TOLERANCE`` of
    the noise variance, so the cut changes the fit by less, and the steps
    after it cost the shorter order's); otherwise the last order fitted is
    kept, with its fit.

    Parameters
    ----------
    fit_at : callable
        ``fit_at(order)`` fits at one order (the pilot fits).
    tail_lag : callable
        ``tail_lag(fit)``: the lag beyond which that fit's tuned prior is
        negligible (:func:`prior_tail_lag` over a window longer than the
        order); read as at most the order.
    longest : int
        The longest order the data allow (the record length ``N``).
    n_samples : int
        The number of used slow samples ``M``.
    n_inputs : int, default=1
    log : callable, optional
        Called with a line of progress after each fit: its order and time,
        the lag read, and the next order with an estimate of the time it
        takes (a fit's time grows about like ``P^2`` on a long record), and
        the chosen order with the time its fit takes when it is fitted again.
    evidence : callable, optional
        ``evidence(fit)``: that fit's log evidence, comparable between
        orders (the same slow samples); None: the doubling goes on while
        the prior has not decayed.
    trim : callable, optional
        ``trim(order)``: the fit at a shorter order with the last pilot's
        tuned hyperparameters held, or None where it is to be fitted
        afterwards (from those hyperparameters); without it the last
        order fitted is kept where ``L`` is more than half of it.

    Returns
    -------
    DefaultOrder

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> fit_at = lambda order: SimpleNamespace(order=order)
    >>> # a response that lasts 200 lags: order 200, fitted again
    >>> result = default_order(fit_at, lambda fit: min(200, fit.order), 10**5, 33333)
    >>> result.order, result.table["order"].tolist(), result.fit
    (200, [512], None)
    >>> # 700 lags: 512 is too short, 1024 is not, and its fit is kept
    >>> result = default_order(fit_at, lambda fit: min(700, fit.order), 10**5, 33333)
    >>> result.order, result.table["order"].tolist(), result.fit.order
    (1024, [512, 1024], 1024)
    >>> # 700 lags of 1024 are more than TRIM_SHARE of it; 600 are not: cut there
    >>> result = default_order(fit_at, lambda fit: min(600, fit.order), 10**5, 33333,
    ...                        trim=lambda order: SimpleNamespace(order=order))
    >>> result.order, result.table["order"].tolist(), result.fit.order
    (600, [512, 1024], 600)
    """
    order = min(PILOT_ORDER, longest)
    # the longest order with more slow samples than coefficients: the doubling
    # stops there once, since at M close to P neither route is cheap
    below = (n_samples - 1) // n_inputs

    def longer(order):
        following = min(2 * order, longest)
        return below if order < below < following else following

    tried, lags = [], []
    seconds = 0.0
    previous = None  # (order, evidence) of the last pilot; its fit is not held (memory)
    while True:
        start = time.perf_counter()
        fit = None  # the last pilot's matrices are freed before the next is fitted
        fit = fit_at(order)
        seconds = time.perf_counter() - start
        lag = min(int(tail_lag(fit)), order)
        tried.append(order)
        lags.append(lag)
        decayed = lag < order
        value = None if evidence is None else float(evidence(fit))
        if not decayed and previous is not None and value is not None and (
                value < previous[1] + EVIDENCE_GAIN):
            if value < previous[1]:  # the shorter order explains the data better: refit it
                order, fit = previous[0], None
            if log is not None:
                log(f"default order: fitted order {tried[-1]} in {seconds:.1f} s, the prior "
                    f"has not decayed by lag {tried[-1]} but the evidence gains "
                    f"{value - previous[1]:.1f} nats over order {previous[0]}: order {order}")
            lag = order
            break
        previous = (order, value)
        if log is not None:
            # a doubled order cost 2-8 times as much in the benchmark: the time left, roughly
            following = longer(order)
            said = (f"the prior is negligible beyond lag {lag}" if decayed or order >= longest
                    else f"the prior has not decayed by lag {order}: next order {following}, "
                         f"about {seconds * (following / order) ** 2:.0f} s left")
            log(f"default order: fitted order {order} in {seconds:.1f} s, {said}")
        if decayed or order >= longest:
            break
        order = longer(order)
    chosen = max(lag, min(MIN_DEFAULT_ORDER, order))
    long_route = n_inputs * chosen < n_samples <= n_inputs * order
    if chosen < order and (2 * chosen <= order or long_route):
        fit = None
        if log is not None:
            log(f"default order: {chosen}, fitting it (about "
                f"{seconds * (chosen / order) ** 2:.0f} s left)")
    elif chosen < order and trim is not None and chosen <= TRIM_SHARE * order:
        start = time.perf_counter()
        fit = None  # the last pilot's matrices are freed before the cut is fitted
        fit = trim(chosen)
        if log is not None:
            log(f"default order: {chosen}, the prior of order {order} cut there"
                + ("" if fit is None else
                   f", its hyperparameters held ({time.perf_counter() - start:.1f} s)"))
    else:
        chosen = order
    table = {
        "order": np.array(tried),
        "score": np.array(lags, dtype=float),
        "criterion": "prior_tail",
        "best_order": int(chosen),
    }
    return DefaultOrder(order=int(chosen), table=table, fit=fit)
