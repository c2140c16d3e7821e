"""``kernel="auto"``: the resonance search of a fit, and its terms judged again.

:func:`search` runs :func:`~gpmultirate.resonances.search_resonances` from
the fit's starting prior (white noise); when the fit then chooses a
disturbance model, :func:`rejudge` asks
:func:`~gpmultirate.resonances.resonances_under_disturbance` which terms the
disturbance does not explain, and tunes the disturbance again without the
others.  Both return their results; the search itself lives in
:mod:`gpmultirate.resonances`.
"""

from __future__ import annotations

import logging

from gpmultirate import resonances
from gpmultirate.fitting.disturbance import DisturbanceFit, fit_disturbance

__all__ = ["rejudge", "search"]

_LOG = logging.getLogger("gpmultirate.fit")


def search(observation, y, kernel, noise_level: float, noise_bounds, settings):
    """The resonance search from ``kernel`` and ``noise_level`` (white noise) on the data.

    Returns the :class:`~gpmultirate.resonances.ResonanceSearch`: the kernel
    with its PK terms, the tuned noise level, the optimizer's run and the
    :class:`~gpmultirate.resonances.Resonance` of each term.  With
    ``settings.start_tuned`` (the start is the default order's pilot, tuned
    at this order or cut to it) the base is not tuned again.
    """
    return resonances.search_resonances(
        observation, y, kernel, noise_level, noise_bounds,
        max_resonances=settings.max_resonances, sample_time=settings.sample_time,
        random_state=settings.random_state, n_folds=settings.n_folds,
        tune_base=not settings.start_tuned,
    )


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
