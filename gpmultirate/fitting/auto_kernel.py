"""``kernel="auto"``: the resonance search of a fit, and its terms judged again.

:func:`search` runs :func:`~gpmultirate.resonances.search_resonances` from
the fit's starting prior (white noise); when the fit then chooses a
disturbance model, :func:`rejudge` asks
:func:`~gpmultirate.resonances.resonances_under_disturbance` which terms the
disturbance does not explain, and tunes the disturbance again without the
others.  Where the data call for a disturbance before any term is found,
:func:`search_under_disturbance` runs the search under it instead (a slow
drift, seen with white noise, hides modes from the scans and brings terms
that follow it).  They return their results; the search itself lives in
:mod:`gpmultirate.resonances`.
"""

from __future__ import annotations

import logging
from typing import NamedTuple

import numpy as np

from gpmultirate import resonances, tuning
from gpmultirate.fitting.disturbance import (
    AUTO_NOISE_DENSE_GATE,
    AUTO_NOISE_MARGIN,
    DisturbanceFit,
    choose_disturbance,
    fit_disturbance,
    white_from,
)
from gpmultirate.inference import LogEvidence
from gpmultirate.kernels.spread import conditioning_kernel
from gpmultirate.observations import WhitenedObservation

__all__ = ["UnderDisturbance", "WHITENED_NOISE_BOUNDS", "rejudge", "search",
           "search_under_disturbance"]

_LOG = logging.getLogger("gpmultirate.fit")

#: bounds of the noise variance of the search under a disturbance, relative to the
#: disturbance model it whitens by (1: the model's own noise)
WHITENED_NOISE_BOUNDS = (1e-4, 1e2)


def search(observation, y, kernel, noise_level: float, noise_bounds, settings,
           tuned: bool = False):
    """The resonance search from ``kernel`` and ``noise_level`` (white noise) on the data.

    Returns the :class:`~gpmultirate.resonances.ResonanceSearch`: the kernel
    with its PK terms, the tuned noise level, the optimizer's run and the
    :class:`~gpmultirate.resonances.Resonance` of each term.  With
    ``settings.start_tuned`` (the start is the default order's pilot, tuned
    at this order or cut to it) or ``tuned`` (tuned on these data already)
    the base is not tuned again.
    """
    return resonances.search_resonances(
        observation, y, kernel, noise_level, noise_bounds,
        max_resonances=settings.max_resonances, sample_time=settings.sample_time,
        random_state=settings.random_state, n_folds=settings.n_folds,
        tune_base=not (settings.start_tuned or tuned),
    )


class UnderDisturbance(NamedTuple):
    """What :func:`search_under_disturbance` decided.

    ``searched``: the search under the disturbance, or None where the fit
    goes on with the search with white noise from ``start``;
    ``decided``: the disturbance fit with the search's terms (the fit's
    noise model and prior), or None; ``start``: the base kernel and white
    noise level tuned on the data, and the optimizer's run (None where
    nothing was tuned); ``white``: whether the disturbance check kept white
    noise at ``start`` as it is (a search with white noise that keeps no term
    ends there, and needs no second check).
    """

    searched: object
    decided: DisturbanceFit | None
    start: tuple
    white: bool = False


def search_under_disturbance(experiment, kernel, noise_level: float, noise_bounds, settings,
                             experiment_at=None) -> UnderDisturbance | None:
    """The resonance search under the disturbance the data call for, when they call for one.

    With white noise a slow drift dominates the scans: modes go unseen, and
    terms near the slow-rate images of zero frequency follow the drift
    (``benchmarks/automatic.py``, drift family: a fit 0.7-0.9 points below
    the oracle's, a mode missed).  So, before any term is searched, the base
    kernel is tuned with white noise and the disturbance chosen as a plain
    fit chooses it (:func:`~gpmultirate.fitting.disturbance.choose_disturbance`).
    Where one is kept, the search runs on the samples whitened by its
    covariance (:class:`~gpmultirate.observations.WhitenedObservation`:
    white noise there, so the scans, the pruning and the held-out check
    work unchanged), from the prior tuned with it.  The disturbance is then
    tuned again with the terms found, from its own values
    (:func:`~gpmultirate.fitting.disturbance.fit_disturbance`).  With
    ``noise_kernel="auto"`` it is kept when it still gains
    ``AUTO_NOISE_MARGIN`` nats over white noise tuned from there
    (:func:`~gpmultirate.fitting.disturbance.white_from`); otherwise the
    terms explained what looked like a disturbance, and the fit goes on
    with the search with white noise.  A disturbance the user named stays.

    Returns None where it does not apply (``noise_kernel="white"``,
    cross-validation, no tuning, readings without a regressor, more than
    ``AUTO_NOISE_DENSE_GATE`` slow samples): the fit searches with white
    noise from its start.
    """
    observation, y = experiment.observation, experiment.y
    if (settings.noise_kernel == "white" or settings.criterion != "evidence"
            or not settings.tuned or not observation.has_regressor
            or y.shape[0] > AUTO_NOISE_DENSE_GATE):
        return None
    evidence = LogEvidence(observation, y, kernel, noise_level, noise_bounds)
    result = None
    if not settings.start_tuned:
        result = tuning.maximize(evidence, 0, settings.random_state)
        if result is not None:
            kernel, noise_level = evidence.split(result.x)
    start = (kernel, noise_level, result)
    moved = evidence.moved_to(kernel, noise_level)
    white_score = float(moved(moved.theta))  # the log evidence alone, no posterior formed
    first = choose_disturbance(experiment, kernel, noise_level, noise_bounds, white_score,
                               settings, experiment_at=experiment_at)
    if first is None or first.noise_model is None:
        return UnderDisturbance(None, None, start, white=first is None)
    covariance = first.noise_model.add_to(np.zeros((y.shape[0], y.shape[0])))
    whitened = WhitenedObservation(observation, covariance)
    _LOG.info("resonance search: under the disturbance %s", first.noise_model.kernel)
    searched = resonances.search_resonances(
        whitened, whitened.whiten(y), first.kernel, 1.0, WHITENED_NOISE_BOUNDS,
        max_resonances=settings.max_resonances, sample_time=settings.sample_time,
        random_state=settings.random_state, n_folds=settings.n_folds, tune_base=False,
        held_out=False)  # judged held out under the disturbance itself, by rejudge
    if not searched.resonances:
        return UnderDisturbance(searched, first, start)
    terms = conditioning_kernel(searched.kernel)
    level = first.noise_model.level or noise_level
    decided = fit_disturbance(observation, y, terms, level, noise_bounds, None, settings,
                              start=first.noise_model)
    if settings.noise_kernel != "auto":  # the disturbance the user named stays
        return UnderDisturbance(searched, decided, start)
    white = white_from(decided, observation, y, noise_bounds, settings)
    if white is not None and decided.score <= white.score + AUTO_NOISE_MARGIN:
        _LOG.info("resonance search: with its terms white noise comes within %.1f nats of "
                  "the disturbance; searched again with white noise",
                  decided.score - white.score)
        return UnderDisturbance(None, None, start)
    return UnderDisturbance(searched, decided, start)


def rejudge(observation, y, fitted: DisturbanceFit, found: list, noise_level: float,
            noise_bounds, settings) -> tuple[list, DisturbanceFit | None]:
    """The resonances ``found`` (with white noise) that the disturbance of ``fitted`` leaves.

    Returns the kept :class:`~gpmultirate.resonances.Resonance` list and,
    when terms or the base kernel beside them were dropped, the disturbance
    tuned again from ``fitted``'s noise model with the kernel without them
    (None when every term and base stays).
    ``noise_level``: the white level the disturbance started from.
    """
    kept, reduced = resonances.resonances_under_disturbance(
        observation, y, fitted.evidence, fitted.kernel, fitted.noise_model,
        [r.input for r in found], settings.n_folds)
    if reduced is fitted.kernel:  # every term and base stays
        return found, None
    if len(kept) < len(found):
        _LOG.info("resonance search: %d term(s) dropped, the disturbance explains them",
                  len(found) - len(kept))
    else:
        _LOG.info("resonance search: the base kernel dropped beside the terms, the "
                  "disturbance explains what it took")
    refitted = fit_disturbance(observation, y, reduced, noise_level, noise_bounds, None,
                               settings, start=fitted.noise_model)
    return [found[r] for r in kept], refitted
