"""Sampling schemes: when the slow sensor(s) read the output, and how.

A :class:`SamplingScheme` is the part of an experiment that is not the
input: the downsampling ``factor``, the ``offsets`` of one or several slow
sensors reading the same output (each every ``factor`` fast samples, at its
own phase), regular or jittered instants, or instants given outright, and
the exposure of each reading.  :meth:`SamplingScheme.observation` builds the
observation of the readings exactly as a fit builds it
(:func:`~gpmultirate.observations.build_experiment` on the fast ticks,
:func:`~gpmultirate.observations.timed.build_timed_experiment` between
them), with outputs that are never read: the posterior covariance does not
depend on them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gpmultirate.observations import build_experiment
from gpmultirate.observations.timed import build_timed_experiment, check_duration, on_the_ticks
from gpmultirate.validation import as_real_array, check_int, check_positive, check_rng

__all__ = ["SamplingScheme", "as_scheme"]


@dataclass(frozen=True)
class SamplingScheme:
    """How the slow samples of an experiment are taken.

    Parameters
    ----------
    factor : int, default=3
        Downsampling factor ``F``: each sensor reads every ``F`` fast samples.
    offsets : int or tuple of int, default=0
        The fast index of each sensor's first reading, in ``0..F-1``; several
        offsets are several slow sensors reading the same output (their
        readings are merged, with independent noise).
    jitter : float, default=0.0
        Half-width, in fast sample periods, of uniform random deviations of
        the instants from the regular grid (a camera's clock); below ``F / 2``.
    exposure : float, default=0.0
        Each reading is the mean output over the ``exposure`` before its
        instant, in fast sample periods.
    sample_times : array-like, optional
        The instants outright, in fast sample periods (``factor``, ``offsets``
        and ``jitter`` are then ignored).
    random_state : int or None, default=0
        Seed of the jitter, so that a scheme always means the same instants.
    name : str, optional
        Label of the scheme in comparisons.

    Examples
    --------
    >>> scheme = SamplingScheme(factor=3, offsets=(0, 1))
    >>> scheme.instants(12)
    array([ 0,  1,  3,  4,  6,  7,  9, 10])
    >>> scheme.label
    'F=3, offsets (0, 1)'
    """

    factor: int = 3
    offsets: object = 0
    jitter: float = 0.0
    exposure: float = 0.0
    sample_times: object = None
    random_state: object = 0
    name: str | None = None

    def __post_init__(self) -> None:
        factor = check_int(self.factor, "factor", low=1)
        offsets = np.atleast_1d(np.asarray(self.offsets))
        if offsets.ndim != 1 or offsets.size == 0 or not np.issubdtype(offsets.dtype, np.integer):
            raise ValueError(f"offsets must be an integer or a sequence of integers in "
                             f"0..{factor - 1}; got {self.offsets!r}")
        offsets = tuple(check_int(int(o), "offsets", low=0, high=factor - 1) for o in offsets)
        if len(set(offsets)) != len(offsets):
            raise ValueError(f"offsets must be distinct; got {offsets}")
        jitter = check_positive(self.jitter, "jitter", allow_zero=True)
        if jitter and not jitter < factor / 2 / len(offsets):
            raise ValueError(f"jitter must be below factor / (2 * number of offsets) = "
                             f"{factor / 2 / len(offsets):g} so that the instants stay in "
                             f"order; got {jitter}")
        object.__setattr__(self, "factor", factor)
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "jitter", jitter)
        object.__setattr__(self, "exposure", check_duration(self.exposure, "exposure"))
        if self.sample_times is not None:
            times = as_real_array(self.sample_times, "sample_times").reshape(-1)
            times.setflags(write=False)
            object.__setattr__(self, "sample_times", times)
        check_rng(self.random_state)

    @property
    def label(self) -> str:
        """A short description, or the scheme's ``name``."""
        if self.name is not None:
            return self.name
        if self.sample_times is not None:
            text = f"{self.sample_times.shape[0]} given instants"
        else:
            text = f"F={self.factor}" + (
                f", offset {self.offsets[0]}" if len(self.offsets) == 1 and self.offsets[0]
                else (f", offsets {self.offsets}" if len(self.offsets) > 1 else ""))
            if self.jitter:
                text += f", jitter +-{self.jitter:g}"
        if self.exposure:
            text += f", exposure {self.exposure:g}"
        return text

    def instants(self, n_samples: int) -> np.ndarray:
        """The reading instants of a record of ``n_samples`` fast samples, in fast periods.

        Integers (fast-sample indices) for regular readings, floats otherwise.
        """
        n_samples = check_int(n_samples, "n_samples", low=1)
        if self.sample_times is not None:
            return np.array(self.sample_times)
        ticks = np.unique(np.concatenate(
            [np.arange(o, n_samples, self.factor) for o in self.offsets]))
        if not self.jitter:
            return ticks
        rng = check_rng(self.random_state)
        times = ticks + rng.uniform(-self.jitter, self.jitter, size=ticks.shape[0])
        return np.clip(times, 0.0, np.nextafter(n_samples - 1.0, 0.0) if n_samples > 1 else 0.0)

    def observation(self, u, order: int, *, latency: float = 0.0, initial_conditions="zero"):
        """The observation of this scheme's readings of a response of ``order`` lags to ``u``.

        Built as a fit builds it, with outputs that are never read.
        """
        u = np.asarray(u, dtype=float)
        n_samples = u.shape[0]
        plain = (self.sample_times is None and len(self.offsets) == 1 and not self.jitter
                 and not self.exposure and not latency)
        if plain:
            # the paper's case keeps the uniform structure's fast paths
            return build_experiment(
                u, np.zeros(len(range(self.offsets[0], n_samples, self.factor))),
                factor=self.factor, offset=self.offsets[0], order=order,
                initial_conditions=initial_conditions).observation
        times = self.instants(n_samples)
        ticks = on_the_ticks(times, self.exposure, latency)
        if ticks is not None:
            return build_experiment(u, np.zeros(ticks.shape[0]), ticks, order=order,
                                    initial_conditions=initial_conditions).observation
        return build_timed_experiment(
            u, np.zeros(times.shape[0]), times, order=order, exposure=self.exposure,
            latency=latency, initial_conditions=initial_conditions).observation


def as_scheme(scheme=None, *, factor=3, offset=0, sample_times=None, exposure=0.0):
    """A :class:`SamplingScheme` from one, or from the arguments of the design functions."""
    if scheme is not None:
        if not isinstance(scheme, SamplingScheme):
            raise ValueError(f"scheme must be a SamplingScheme; got {type(scheme).__name__}")
        return scheme
    return SamplingScheme(factor=factor, offsets=offset, sample_times=sample_times,
                          exposure=exposure)
