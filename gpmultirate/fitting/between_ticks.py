"""Readings between the fast ticks: their route, and the check of an interpolated fit.

Readings at their own instants (``fit(..., sample_times=t)``) are observed
exactly (:class:`~gpmultirate.observations.TimedConvolution`, an ``M x M``
data covariance), or interpolated on the integer lags
(:class:`~gpmultirate.observations.InterpolatedConvolution`, a regressor, so
a long record takes the ``P x P`` route).  For TC, DC and SS both routes
read the same prior between integer lags (:mod:`gpmultirate.kernels.hold`):
the exact one with its bridge, the interpolated one leaving the bridge to
the noise.  The steps here:

* :func:`readings_of`: what a fit observes, the fast samples of some
  indices (readings on the ticks) or the readings at their own instants;
* :func:`experiment_of`: the experiment of a fit at one order, on the ticks
  or by the route of ``between_ticks`` (``"auto"``: interpolated for a long
  record);
* :func:`check_interpolation`: the estimated error of an interpolated fit,
  and whether the fit should be made again exactly.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass

import numpy as np

from gpmultirate.exceptions import NumericalWarning
from gpmultirate.observations import build_experiment
from gpmultirate.observations.experiment import Experiment, check_records, is_record_list
from gpmultirate.observations.interpolated import DEFAULT_POINTS, InterpolatedConvolution
from gpmultirate.observations.timed import (
    build_timed_experiment, check_sample_times, check_windows, on_the_ticks,
)

__all__ = [
    "BETWEEN_TICKS",
    "EXACT_UP_TO",
    "INTERPOLATED_ABOVE",
    "INTERPOLATION_TOLERANCE",
    "InterpolationCheck",
    "TimedSamples",
    "check_between_ticks",
    "check_interpolation",
    "experiment_of",
    "readings_of",
]

_LOG = logging.getLogger("gpmultirate.fit")

#: the routes of readings between the fast ticks (``between_ticks``)
BETWEEN_TICKS = ("auto", "exact", "interpolated")
#: ``between_ticks="auto"`` interpolates above this many readings (and more than coefficients)
INTERPOLATED_ABOVE = 1000
#: ``between_ticks="auto"``: the largest estimated interpolation error, in noise std
INTERPOLATION_TOLERANCE = 0.2
#: ``between_ticks="auto"``: readings fitted exactly where the interpolation is not enough
EXACT_UP_TO = 3000


class TimedSamples(list):
    """``[sample_times]`` of a fit whose readings are not all fast samples."""


def check_between_ticks(route) -> str:
    """``between_ticks`` checked: one of :data:`BETWEEN_TICKS`."""
    if not (isinstance(route, str) and route in BETWEEN_TICKS):
        raise ValueError(f"between_ticks must be one of {BETWEEN_TICKS}; got {route!r}")
    return route


def readings_of(sample_indices, sample_times, exposure: float, latency: float, u=None):
    """What a fit observes: the ``sample_indices``, or :class:`TimedSamples`.

    Readings on the fast ticks (no exposure, ``t - latency`` integers) are
    the fast samples of those indices, with every fast path of the ticks.
    With the input(s) ``u``, the ``sample_times`` are checked against each
    record first, with the exposure and latency
    (:func:`~gpmultirate.observations.timed.check_windows`): their errors
    name them, not the fast samples they fall on.

    Examples
    --------
    >>> readings_of(None, [3.0, 6.0], 0.0, 0.0)
    array([3, 6])
    >>> readings_of(None, [3.5, 6.0], 0.0, 0.0)
    [[3.5, 6.0]]
    """
    if sample_times is None:
        if exposure or latency:
            raise ValueError(
                "exposure and latency apply to readings at their own instants: give "
                "sample_times (in the units of sample_time)"
            )
        return sample_indices
    if sample_indices is not None:
        raise ValueError("give sample_indices or sample_times, not both")
    if u is not None:
        _check_against_records(u, sample_times, exposure, latency)
    ticks = on_the_ticks(sample_times, exposure, latency)
    # a latency may place early readings before the record (the output at
    # rest there): no fast sample, so they are readings at their own instants
    if ticks is not None and min(np.min(t) for t in (ticks if is_record_list(ticks) else
                                                     [ticks])) >= 0:
        return ticks
    return TimedSamples([sample_times])


def _check_against_records(u, sample_times, exposure, latency) -> None:
    """The stamps of each record in its range, and the windows inside it."""
    inputs, several = check_records(u)
    if several != is_record_list(sample_times) or (several and len(sample_times) != len(inputs)):
        return  # the shapes of the lists are refused with the data
    for r, (x, times) in enumerate(zip(inputs, sample_times if several else [sample_times])):
        label = f"[{r}]" if several else ""
        times = check_sample_times(times, x.shape[0], "sample_times" + label)
        try:
            check_windows(times, x.shape[0], exposure, latency)
        except ValueError as error:
            raise type(error)(f"record {r}: {error}" if several else str(error)) from None


def experiment_of(data, order, settings) -> Experiment:
    """The experiment of a fit at ``order`` (None: the longest record's length).

    ``data``: ``(u, y_slow, sample_indices)`` as :func:`readings_of` gives
    the last; ``settings``: the fit's
    :class:`~gpmultirate.fitting.settings.Settings`.  Readings at their own
    instants are the exact timed observation, or its interpolation on the
    integer lags (``settings.between_ticks``; ``"auto"``: for a long record,
    more readings than coefficients and than ``INTERPOLATED_ABOVE``).
    """
    u, y_slow, sample_indices = data
    if isinstance(sample_indices, TimedSamples):
        experiment = build_timed_experiment(
            u, y_slow, sample_indices[0], order=order, exposure=settings.exposure,
            latency=settings.latency, initial_conditions=settings.initial_conditions,
        )
        timed = experiment.observation
        route = settings.between_ticks
        shortest = min(record.n_samples for record in timed.records)
        if route == "interpolated" or (route == "auto" and timed.n_outputs > max(
                timed.n_coefficients, INTERPOLATED_ABOVE) and shortest >= DEFAULT_POINTS):
            return Experiment(InterpolatedConvolution(timed), experiment.y, experiment.n_inputs)
        return experiment
    return build_experiment(
        u, y_slow, sample_indices, factor=settings.factor, offset=settings.offset,
        order=order, initial_conditions=settings.initial_conditions,
    )


@dataclass(frozen=True)
class InterpolationCheck:
    """The check of a fit of interpolated readings.

    ``error``: the estimated rms error of the interpolated readings of the
    posterior mean, in standard deviations of the white noise (the fit's
    ``interpolation_error_``); ``refit``: fit the readings again, exactly.
    """

    error: float
    refit: bool = False


def check_interpolation(observation, coef, noise_level: float,
                        route: str) -> InterpolationCheck | None:
    """Estimate an interpolated fit's error; with ``route="auto"``, say whether to fit again.

    The estimate is the observation's
    :meth:`~gpmultirate.observations.Observation.interpolation_check` of the
    posterior mean ``coef`` in standard deviations of the white noise
    (``noise_level`` its variance); None where the data are not interpolated
    or nothing can be said.  Above ``INTERPOLATION_TOLERANCE`` the default
    route fits the readings again, exactly, up to ``EXACT_UP_TO`` readings;
    beyond, a ``NumericalWarning`` gives the estimate.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.observations import DownsampledConvolution
    >>> check_interpolation(DownsampledConvolution(np.ones(9), 3, 4), np.ones(4), 1.0, "auto")
    """
    error = observation.interpolation_check(coef)
    if error is None:
        return None
    error = error / np.sqrt(noise_level)
    _LOG.info("interpolated readings (%d lags): estimated error %.3g noise std",
              observation.points, error)
    if route != "auto" or error <= INTERPOLATION_TOLERANCE:
        return InterpolationCheck(error)
    if observation.n_outputs > EXACT_UP_TO:
        warnings.warn(
            f"the readings between the ticks are interpolated with an estimated error of "
            f"{error:.2g} noise standard deviations; "
            "between_ticks='exact' models them exactly (an M x M covariance)",
            NumericalWarning, stacklevel=3)
        return InterpolationCheck(error)
    _LOG.info("fitting the readings again, exactly")
    return InterpolationCheck(error, refit=True)
