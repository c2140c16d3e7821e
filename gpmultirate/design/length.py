"""The record length an experiment needs for a target band.

The band of a longer record is narrower: more slow samples see the same
response through the same noise.  For a kind of input (a flat random-phase
multisine over the range, or the designed one) :func:`required_length`
searches the shortest record, a multiple of the factor, whose predicted band
radius over the range (mean or worst, absolute or relative to a pilot
model's ``|G|``) meets the target for a fraction ``probability`` of the
inputs' random phases: doubling the length until it is met, then bisecting.

The band of a new draw of the phases is bounded by the upper prediction
bound of the ``n_draws`` draws at ``probability``,
``mean + t_{n-1}(probability) s sqrt(1 + 1/n)`` (Student's t): a new input of
the recommended length meets the target with that probability, where the
bands of the draws spread normally, not only in the draws that were seen.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.stats

from gpmultirate.design.criterion import BandCriterion, check_criterion
from gpmultirate.design.multisine import (
    check_band,
    design_multisine,
    flat_multisine,
    relative_weights,
)
from gpmultirate.design.prior import design_prior
from gpmultirate.design.sampling import SamplingScheme
from gpmultirate.inference import blas_threads_for
from gpmultirate.validation import check_int, check_level, check_positive, check_rng

__all__ = ["INPUTS", "RecordLength", "required_length", "upper_prediction_bound"]

#: the inputs :func:`required_length` plans with
INPUTS = ("flat", "designed")
#: frequencies of the range the band counts at, whatever the record length
N_FREQUENCIES = 101


@dataclass(frozen=True)
class RecordLength:
    """The answer of :func:`required_length`.

    Attributes
    ----------
    n_samples : int
        The shortest record (fast samples) found to meet the target.
    duration : float
        Its length in seconds (``n_samples * T``).
    achieved : float
        The band at that length: the upper prediction bound at
        ``probability`` of the criterion over the inputs' phases (band
        radius, or its dB for a relative target).
    target : float
    tried : dict
        Every length tried and its ``achieved`` value.
    """

    n_samples: int
    duration: float
    achieved: float
    target: float
    tried: dict = field(default_factory=dict)


def upper_prediction_bound(values, probability: float) -> float:
    """The bound a new draw stays below with ``probability``, from normal draws ``values``.

    ``mean + t_{n-1}(probability) s sqrt(1 + 1/n)``; the largest value for one draw.

    Examples
    --------
    >>> round(upper_prediction_bound([1.0, 2.0, 3.0], 0.95), 4)
    5.3717
    """
    values = np.asarray(values, dtype=float)
    n = values.shape[0]
    if n < 2:
        return float(values.max())
    spread = values.std(ddof=1) * np.sqrt(1.0 + 1.0 / n)
    return float(values.mean() + scipy.stats.t.ppf(probability, n - 1) * spread)


def required_length(prior, target, band_hz, factor=3, rms=1.0, noise_level=None,
                    sample_time=None, criterion="mean", input="flat", *, order=None, offset=0,
                    relative=False, level=0.95, probability=0.95, n_draws=10,
                    random_state=None, max_samples=None,
                    resolution: float = 0.02) -> RecordLength:
    """The shortest record whose predicted band over ``band_hz`` meets ``target``.

    Parameters
    ----------
    prior : FIRGaussianProcess (fitted), sklearn Kernel or DesignPrior
    target : float
        The band radius to reach (:func:`~gpmultirate.design.band_radius`), in
        the units of ``G``; with ``relative=True``, the magnitude band's
        half-width in dB, ``20 log10(1 + r / |G|)`` with ``|G|`` the pilot model's.
    band_hz : (f_lo, f_hi)
        The range, in Hz.
    factor, rms, noise_level, sample_time, order, offset
        As for :func:`~gpmultirate.design.design_multisine`.
    criterion : {"mean", "worst"}, default="mean"
        The band's mean over the range, or its largest value.
    input : {"flat", "designed"}, default="flat"
        A flat random-phase multisine over ``band_hz``, or
        :func:`~gpmultirate.design.design_multisine` (a design per length and
        phase draw: slower).
    relative : bool, default=False
    level : float, default=0.95
    probability : float, default=0.95
        The fraction of phase draws that must meet the target.
    n_draws : int, default=10
        Phase draws per length (the same draws at every length).
    random_state : int, RandomState or None
    max_samples : int, optional
        The longest record tried; default 64 times the shortest.
    resolution : float, default=0.02
        The bisection stops when the shortest length known to meet the target
        is within this fraction of the longest known to miss it (or a factor
        apart): the answer errs on the long side by at most that much.

    Returns
    -------
    RecordLength

    Examples
    --------
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate.kernels import DC
    >>> answer = required_length(C(1.0) * DC(0.8, 0.5), 0.1, (0.0, 0.5), order=20,
    ...                          noise_level=1e-2, n_draws=3, random_state=0)
    >>> answer.n_samples % 3, answer.achieved <= 0.1
    (0, True)
    """
    prior = design_prior(prior, order=order, sample_time=sample_time, noise_level=noise_level)
    target = check_positive(target, "target")
    T = prior.sample_time
    band = check_band(band_hz, T)
    factor = check_int(factor, "factor", low=1)
    rms = check_positive(rms, "rms")
    criterion = check_criterion(criterion)
    if not (isinstance(input, str) and input in INPUTS):
        raise ValueError(f"input must be one of {INPUTS}; got {input!r}")
    level = check_level(level)
    probability = check_level(probability, "probability")
    n_draws = check_int(n_draws, "n_draws", low=1)
    resolution = check_positive(resolution, "resolution", allow_zero=True)
    seeds = check_rng(random_state).randint(0, 2**31 - 1, size=n_draws)
    scheme = SamplingScheme(factor=factor, offsets=offset)
    freqs = np.linspace(band[0], band[1], N_FREQUENCIES)
    weights = relative_weights(prior, freqs) if relative else None
    objective = BandCriterion(prior, freqs, criterion, weights, level)
    # a record at least the order long, with a bin of the range, in whole slow periods
    shortest = prior.order if prior.initial_conditions == "zero" else factor
    shortest = max(shortest, int(np.ceil(1.0 / (T * max(band[1] - band[0], 1e-300)))), 3)
    shortest = factor * int(np.ceil(shortest / factor))
    longest = 64 * shortest if max_samples is None else check_int(
        max_samples, "max_samples", low=shortest)

    def threshold(value):
        return 20.0 * np.log10(1.0 + value) if relative else value

    tried = {}

    def achieved(n_samples: int) -> float:
        if n_samples not in tried:
            values = []
            for seed in seeds:
                if input == "flat":
                    u = flat_multisine(n_samples, band, rms, T, random_state=seed)
                else:
                    u = design_multisine(prior, n_samples, factor, band, rms,
                                         random_state=seed, criterion=criterion,
                                         offset=offset, relative=relative, level=level)
                with blas_threads_for(scheme.observation(u, prior.order)):
                    values.append(objective.value(u, scheme).value)
            tried[n_samples] = float(threshold(upper_prediction_bound(values, probability)))
        return tried[n_samples]

    low, high = None, shortest
    while achieved(high) > target:
        low = high
        if high >= longest:
            raise ValueError(
                f"target {target:g} is not met by records up to max_samples = {longest} "
                f"(the band there is {tried[high]:.4g}): raise max_samples, the rms or the "
                "target")
        high = min(2 * high, longest)
    while low is not None and high - low > max(factor, resolution * high):
        middle = factor * ((low + high) // (2 * factor))
        if middle <= low or middle >= high:
            break
        if achieved(middle) > target:
            low = middle
        else:
            high = middle
    return RecordLength(n_samples=high, duration=high * T, achieved=tried[high],
                        target=target, tried=dict(sorted(tried.items())))
