"""The order steps of a fit: choose the order, then check it.

* :func:`fit_order`: the fit at the chosen order (``order="auto"`` or a
  list: :func:`~gpmultirate.orders.select_order`; the default order of a
  long record: :func:`default_order_rule`, the pilot fits of
  :func:`~gpmultirate.orders.default_order`; an integer, or ``N`` for a
  short record: as given);
* :func:`check_shorter_orders`: after evidence tuning, the held-out fit at
  shorter orders (:func:`~gpmultirate.orders.held_out_fits`), which may
  replace the default order or name a better one in a warning;
* :func:`check_long_enough`: an :class:`~gpmultirate.OrderWarning` when an
  explicit order looks too short for the data's memory
  (:func:`order_too_short`); the default order is raised instead
  (:func:`raise_short_default_order`), never followed by that warning.

Each takes the fit at one order as a function ``fit_at(data, order,
settings, start=None)`` (:func:`~gpmultirate.fitting.one_order.fit_at_order`)
and returns what it chose; the estimator adopts it.
"""

from __future__ import annotations

import logging
import time
import warnings
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from gpmultirate import orders
from gpmultirate.crossvalidation import contiguous_folds
from gpmultirate.exceptions import HeldOutWarning, OrderWarning
from gpmultirate.fitting.between_ticks import experiment_of
from gpmultirate.fitting.disturbance import calls_for_disturbance
from gpmultirate.fitting.prior import input_powers, input_powers_of
from gpmultirate.inference import blas_threads_for
from gpmultirate.orders import MAX_CHECKED_SAMPLES, MIN_CHECKED_ORDER

__all__ = [
    "HELD_OUT_MARGIN",
    "ORDER_MARGIN",
    "PilotStart",
    "RESIDUAL_CORRELATION",
    "check_long_enough",
    "check_shorter_orders",
    "default_order_rule",
    "fit_checked_order",
    "fit_order",
    "order_too_short",
    "pilot_lag",
    "raise_short_default_order",
]

#: the logger of a fit's progress (the default order's pilot fits, the resonance search)
_LOG = logging.getLogger("gpmultirate.fit")

#: residual lag-one autocorrelation above which a too-short order is reported
RESIDUAL_CORRELATION = 0.3

# the margins in percentage points of held-out fit by which a shorter order
# must predict better to replace the default order N, and to be named in a
# warning for an explicit order
ORDER_MARGIN = 1.0
HELD_OUT_MARGIN = 5.0


def fit_checked_order(data, settings, fit_at):
    """The fit at the chosen order after the order's checks: ``(fit, order_selection table)``.

    :func:`fit_order`; then, unless the order was chosen among candidates,
    :func:`check_shorter_orders` after evidence tuning (which may fit the
    default order again, shorter) and :func:`check_long_enough` (for the
    default order :func:`raise_short_default_order`).
    """
    fitted, table = fit_order(data, settings, fit_at)
    if settings.candidates is not None:
        return fitted, table
    if settings.criterion == "evidence" and settings.tuned:
        with blas_threads_for(fitted.experiment.observation):
            refit, checked = check_shorter_orders(data, fitted, settings, fit_at)
        fitted = fitted if refit is None else refit
        table = table if checked is None else checked
    if settings.order is None:
        return raise_short_default_order(data, fitted, table, settings, fit_at)
    check_long_enough(fitted.observation_, fitted.y_slow_, fitted.posterior_, fitted.kernel_,
                      fitted.noise_level_, fitted.noise_model, settings)
    return fitted, table


def raise_short_default_order(data, fitted, table, settings, fit_at):
    """The default order, raised while :func:`order_too_short` calls it short.

    The default order is the library's choice, so the check of
    :func:`check_long_enough` does not warn about it: where the check's
    two signs (the tuned prior not negligible by the order, correlated
    residuals) call it too short, the fit is done again at the longer
    order the warning would name, and kept when its log evidence gains at
    least :data:`~gpmultirate.orders.EVIDENCE_GAIN` nats (per used slow
    sample, times their number: ``"discard"`` uses fewer at longer
    orders); otherwise the shorter order stays, the data not supporting a
    longer one, and the progress log says so (the warnings of a refit not
    kept are dropped).  Returns ``(fit, table)``, the table's
    ``best_order`` the order kept.
    """
    while True:
        longer = order_too_short(fitted.observation_, fitted.y_slow_, fitted.posterior_,
                                 fitted.kernel_, fitted.noise_level_, fitted.noise_model,
                                 settings)
        if longer is None:
            return fitted, table
        order = fitted.observation_.order
        start = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            refit = fit_at(data, longer, settings)
        n_used = fitted.y_slow_.shape[0]
        gain = (refit.log_marginal_likelihood_value_ / refit.y_slow_.shape[0]
                - fitted.log_marginal_likelihood_value_ / n_used) * n_used
        kept = longer if gain >= orders.EVIDENCE_GAIN else order
        _LOG.info("order %d looked short for the data's memory; order %d (%.1f s) gains "
                  "%.1f nats of evidence: order %d", order, longer,
                  time.perf_counter() - start, gain, kept)
        if kept == order:
            return fitted, table
        for w in caught:  # only the kept fit's warnings concern the user
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        fitted = refit
        if table is not None:
            table = {**table, "best_order": int(longer)}


def fit_order(data, settings, fit_at):
    """The fit at the order the settings ask for: ``(fit, order_selection table or None)``.

    ``order="auto"`` or a list of candidates: each is fitted and the tuning
    criterion picks one; the default order (``order=None``): ``N`` for a
    short record, otherwise :func:`default_order_rule` (its last pilot fit
    is kept when it can be); an integer: as given.
    """
    if settings.candidates is not None:
        candidates = settings.candidates
        if candidates == "auto":
            candidates = orders.auto_orders(experiment_of(data, None, settings).observation.order)
        selection = orders.select_order(
            lambda order: fit_at(data, order, settings), candidates, settings.criterion
        )
        return selection.fit, selection.table
    order, rule, pilot = settings.order, None, None
    if order is None:
        rule, pilot = default_order_rule(data, settings, fit_at)
        if rule is not None:
            order = rule.order
            if rule.fit is not None:
                return rule.fit, rule.table
    start = time.perf_counter()
    fitted = fit_at(data, order, settings if rule is None else replace(
        settings, order_from_data=True,
        start_tuned=pilot is not None and pilot.tuned), start=pilot)
    if rule is None:
        return fitted, None
    _LOG.info("fitted order %d in %.1f s", fitted.observation_.order,
              time.perf_counter() - start)
    return fitted, rule.table


def pilot_lag(kernel, powers, noise_level: float, order: int) -> int:
    """The lag a pilot fit at ``order`` reads its response's length from.

    The larger of :func:`~gpmultirate.orders.prior_tail_lag` (the tuned
    prior's tail against the tuned noise) and
    :func:`~gpmultirate.orders.prior_envelope_lag` (the tuned decay alone),
    both over twice the order: a prior cut by the order has not decayed,
    nor has a decay tuned to the order's bound, however small the prior is
    against the noise (a short pilot that sees little of a long response
    leaves most of it to the noise estimate).
    """
    window = 2 * order
    return max(orders.prior_tail_lag(kernel, powers, noise_level, window),
               orders.prior_envelope_lag(kernel, len(powers), window))


class PilotStart(NamedTuple):
    """The start of the fit at the default order: a pilot's tuned prior and noise level.

    ``tuned``: tuned at that order already (the pilot's own order, or cut
    from it where its prior is negligible), so the resonance search starts
    from them without tuning them again.
    """

    kernel: object
    noise_level: float
    tuned: bool = False


def default_order_rule(data, settings, fit_at):
    """The default order of a record longer than ``SHORT_RECORD``.

    :func:`~gpmultirate.orders.default_order`, from pilot fits.

    None for a shorter record (its default order is ``N``).  The pilot
    fits tune the plain prior (the user's kernel, or the default without
    the resonance search) by the evidence; the last one is kept as the
    fit when the rule keeps its order and the fit asks for nothing more.
    Their warnings are those of the kept fit only.  Returns the rule
    and the start of the fit at its order: for the resonance search, the
    last pilot's tuned ``(kernel, noise level)`` (the search starts from
    them instead of from the untuned prior, and does not tune them again
    where the rule keeps that pilot's order or cuts it:
    :class:`PilotStart`); for a fit tuned by the evidence at the order of
    a pilot (fitted again), that pilot's; else None.
    """
    whole = experiment_of(data, None, settings)
    longest = whole.observation.order
    if longest <= orders.SHORT_RECORD:
        return None, None
    powers = input_powers(whole)
    pilot = replace(settings, auto=False, criterion="evidence", noise_kernel="white")
    caught = {}
    last = []
    tuned = {}  # each white pilot's tuned (kernel, noise level), by order: no matrices

    def fit_pilot(order):
        # each pilot's tuning starts where the last one's ended (the prior's decay moves
        # little from one order to its double)
        start = tuned.get(max(tuned)) if tuned and pilot.tuned else None
        last.clear()  # the last pilot is not held while the next one is fitted
        with warnings.catch_warnings(record=True) as record:
            warnings.simplefilter("always")
            fitted = fit_at(data, order, pilot, start)
        caught[order] = record
        last[:] = [fitted]
        if fitted.noise_model is None:
            tuned[order] = (fitted.kernel_, fitted.noise_level_)
        return fitted

    def tail_lag(fitted):
        return pilot_lag(fitted.kernel_, powers, fitted.noise_level_,
                         fitted.observation_.order)

    # the pilots' evidence is comparable where every order uses the same slow samples
    evidence = (None if settings.initial_conditions == "discard"
                else lambda fitted: fitted.log_marginal_likelihood_value_)
    # a pilot fit at the cut order is kept where the fit asks for no more than a pilot
    held = (not settings.auto and settings.criterion == "evidence"
            and settings.noise_kernel in ("white", "auto"))

    def trim(order):
        # the last pilot's prior cut at a shorter order: its hyperparameters held there
        # (and where the fit goes on, its start)
        kernel, noise = tuned[order] = tuned[max(tuned)]
        caught[order] = list(caught[max(tuned)])
        if not held:
            return None
        result = last[0].optimizer_result_
        last.clear()  # the last pilot is not held while the cut is fitted
        with warnings.catch_warnings(record=True) as record:
            warnings.simplefilter("always")
            cut = fit_at(data, order, replace(pilot, tuned=False), (kernel, noise))
        caught[order] += record
        if not np.array_equal(cut.kernel_.theta, kernel.theta):
            return None  # outside the shorter order's bounds: tuned there from this start
        return replace(cut, optimizer_result_=result)

    rule = orders.default_order(fit_pilot, tail_lag, longest, whole.y.shape[0],
                                whole.n_inputs, log=_LOG.info, evidence=evidence,
                                trim=trim)
    start = None
    if settings.auto:
        # the last pilot's (white) tuned prior and noise level: tuned for the search where
        # the rule keeps that pilot's order or cuts it (the prior negligible beyond the cut)
        start = PilotStart(*tuned[max(tuned)], tuned=pilot.tuned and rule.order in tuned
                           and tuned[rule.order] is tuned[max(tuned)])
    elif not settings.auto and settings.tuned and settings.criterion == "evidence":
        # the order of a pilot fitted again (the doubled order lost evidence, or the fit
        # goes on with a disturbance): its tuning starts where that pilot's ended, a few
        # evaluations where the plain start took as many as the pilot (60 at order 3,996
        # of a 20 s camera log)
        start = PilotStart(*tuned[rule.order]) if rule.order in tuned else None
    if rule.fit is not None and (settings.auto or settings.criterion != "evidence"
                                 or settings.noise_kernel not in ("white", "auto")
                                 or (settings.noise_kernel == "auto"
                                     and calls_for_disturbance(
                                         rule.fit.experiment, rule.fit.kernel_,
                                         rule.fit.noise_level_, check_tail=False))):
        rule = replace(rule, fit=None)  # the fit at that order goes on from here
        _LOG.info("default order: %d, fitting it with the full settings", rule.order)
    if rule.fit is not None:
        for w in caught[rule.order]:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        _LOG.info("default order: %d (the pilot fit at that order is kept)", rule.order)
    return rule, start


def check_shorter_orders(data, fitted, settings, fit_at):
    """Compare the held-out fit of the tuned model with that of shorter orders.

    ``fitted``: the tuned :class:`~gpmultirate.fitting.one_order.Fit`.  The
    same hyperparameters, the same folds (as ``tuning="cross_validation"``);
    only the order is cut (:func:`~gpmultirate.orders.held_out_fits`).
    With the default order (``order=None``) the candidates are
    :func:`~gpmultirate.orders.auto_orders` of ``N``, and when one
    predicts the held-out slow samples more than ``ORDER_MARGIN`` points
    of fit better than ``N``, the model is fitted again at that order;
    the table reports every candidate's held-out fit.  With an explicit
    order ``P`` the candidates are ``P/2, P/4, P/8`` and a
    :class:`~gpmultirate.HeldOutWarning` names one that predicts more than
    ``HELD_OUT_MARGIN`` points better.  Skipped where it would cost more
    than the fit (at least as many slow samples as coefficients, where
    the fit works on the ``P x P`` problem and the check would need
    ``M x M`` matrices; as many is checked for the default order, the
    single-rate case), beyond ``MAX_CHECKED_SAMPLES`` slow samples, or
    where it is not comparable (``"discard"`` uses other samples at other
    orders).

    Returns
    -------
    refit : Fit or None
        The fit at the shorter order that replaces the default order.
    table : dict or None
        The ``order_selection_`` of the default order's check.
    """
    experiment = fitted.experiment
    observation, y = experiment.observation, experiment.y
    order, n_samples = observation.order, y.shape[0]
    default_order = settings.order is None
    n_folds = settings.n_folds
    # the fit works in data space for M < P; at M = P (single rate) only the
    # default order is checked, and never with M x M matrices beyond the limit
    data_space = n_samples < observation.n_coefficients or (
        default_order and n_samples == observation.n_coefficients)
    if (settings.initial_conditions == "discard" or not data_space
            or n_samples > MAX_CHECKED_SAMPLES or order < 2 * MIN_CHECKED_ORDER
            or np.ptp(y) == 0):  # the fit in percent of a constant output is undefined
        return None, None
    try:
        folds = contiguous_folds([r.n_outputs for r in observation.records], n_folds)
    except ValueError:
        return None, None  # fewer samples than folds: nothing to hold out
    if default_order:
        candidates = orders.auto_orders(order)
    else:
        candidates = [order // d for d in (8, 4, 2) if order // d >= MIN_CHECKED_ORDER]
        candidates.append(order)
    fits = orders.held_out_fits(
        lambda p: observation if p == order else experiment_of(data, p, settings).observation,
        candidates, fitted.kernel_,
        fitted.noise_level_ if fitted.noise_model is None else fitted.noise_model, y, folds,
    )
    if fits is None:
        return None, None
    best = max(fits, key=fits.get)  # the shortest of equal fits
    if default_order:
        chosen = best if fits[best] > fits[order] + ORDER_MARGIN else order
        refit = fit_at(data, chosen, settings) if chosen != order else None
        return refit, {
            "order": np.array(candidates),
            "score": np.array([fits[o] for o in candidates]),
            "criterion": "held_out_fit",
            "best_order": int(chosen),
        }
    if fits[best] > fits[order] + HELD_OUT_MARGIN:
        warnings.warn(
            f"held-out slow samples are predicted clearly better at a shorter order: "
            f"order={best} fits {fits[best]:.1f} % of them, order={order} "
            f"{fits[order]:.1f} % ({n_folds}-fold cross-validation over time at the tuned "
            "hyperparameters). The marginal likelihood trusts the model, and measured data "
            "with drift, disturbances or a little nonlinearity can make it prefer a worse "
            f"predictor: try order={best}, or order='auto' with "
            "tuning='cross_validation'.",
            HeldOutWarning,
            stacklevel=4,
        )
    return None, None


def check_long_enough(observation, y, posterior, kernel, noise_level: float, noise_model,
                      settings) -> None:
    """Warn when an explicit order is too short for the data's memory.

    :func:`order_too_short`; the :class:`~gpmultirate.OrderWarning` names
    the longer order it returns.
    """
    longer = order_too_short(observation, y, posterior, kernel, noise_level, noise_model,
                             settings)
    if longer is None:
        return
    order = observation.order
    correlation = _residual_correlation(observation, y, posterior, noise_level)
    default = ("" if settings.order is None
               else " (or the default order=None, which reads it from the data)")
    warnings.warn(
        f"order={order} looks too short for the data's memory: the tuned prior has not "
        f"decayed against the noise by lag {order} and the residuals of the slow samples "
        f"are correlated from one to the next ({correlation:.2f} at lag one); the noise "
        f"level and the bands are then too large. Try order={longer}{default}.",
        OrderWarning,
        stacklevel=4,
    )


def _residual_correlation(observation, y, posterior, noise_level: float) -> float | None:
    """The lag-one autocorrelation of the slow samples' residuals (None: all zero)."""
    products = squares = 0.0
    start = 0
    for record, fitted in zip(observation.records,
                              observation.fitted_readings(posterior, y, noise_level)):
        residual = y[start : start + record.n_outputs] - fitted
        start += record.n_outputs
        products += float(residual[1:] @ residual[:-1])
        squares += float(residual @ residual)
    return None if squares == 0.0 else products / squares


def order_too_short(observation, y, posterior, kernel, noise_level: float, noise_model,
                    settings) -> int | None:
    """A longer order when the fitted one is too short for the data's memory, else None.

    ``observation``, ``y``, ``posterior``, ``kernel``, ``noise_level``,
    ``noise_model``: the fit's.  Where the fit has more slow samples than
    coefficients (the held-out check does not run there), two signs
    together: the tuned prior, continued beyond the order, is not
    negligible against the noise from the last lag on
    (:func:`~gpmultirate.orders.prior_tail_lag` reaches the order), and
    the residuals of the slow samples (against the observation's
    :meth:`~gpmultirate.observations.Observation.fitted_readings`) are
    correlated from one slow sample to the next (lag-one autocorrelation
    above ``RESIDUAL_CORRELATION`` and four standard errors).  The
    longer order is twice the order, at most the record's length.
    """
    order = observation.order
    # under a disturbance model correlated residuals are the model's, not a short order's
    if (observation.n_outputs <= observation.n_coefficients
            or settings.initial_conditions == "periodic" or noise_model is not None):
        return None
    inputs = [np.asarray(r.u, dtype=float) for r in observation.records]
    longest = max(x.shape[0] for x in inputs)
    if order >= longest:
        return None
    powers = input_powers_of(inputs)
    if orders.prior_tail_lag(kernel, powers, noise_level, 2 * order) < order:
        return None
    correlation = _residual_correlation(observation, y, posterior, noise_level)
    if correlation is None or correlation <= max(RESIDUAL_CORRELATION,
                                                 4.0 / np.sqrt(observation.n_outputs)):
        return None
    return min(2 * order, longest)
