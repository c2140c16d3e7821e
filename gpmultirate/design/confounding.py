"""Which excited frequencies the slow samples cannot tell apart.

Sampled every ``F`` fast samples, a sinusoid of frequency ``f`` gives the
same slow samples as one at ``f + j / (F T)`` or ``j / (F T) - f`` (any
integer ``j``): both *alias* onto the same frequency in ``[0, 1 / (2 F T)]``.
When an input excites two such frequencies, the slow data see only a
combination of the response at both; only the prior separates them.
:func:`confounded_frequencies` lists those groups for any input.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gpmultirate.validation import check_int, check_positive, check_sample_time, check_signal

__all__ = ["Confounding", "alias_frequency", "confounded_frequencies"]


def alias_frequency(freqs, factor: int, sample_time: float = 1.0) -> np.ndarray:
    """The frequency in ``[0, 1 / (2 F T)]`` that each of ``freqs`` aliases onto at the slow rate.

    Examples
    --------
    >>> alias_frequency([0.1, 0.2, 0.3, 0.45], factor=3).round(4)
    array([0.1   , 0.1333, 0.0333, 0.1167])
    """
    freqs = np.asarray(freqs, dtype=float)
    slow_rate = 1.0 / (factor * sample_time)
    return np.abs(freqs - np.round(freqs / slow_rate) * slow_rate)


@dataclass(frozen=True)
class Confounding:
    """The excited frequencies of an input and the groups the slow samples confound.

    Attributes
    ----------
    freqs : ndarray
        The excited DFT bins of the input, in Hz (cycles per sample when
        ``sample_time`` is 1).
    power : ndarray
        The input's power at each of them (sums to the mean square of the
        excited part).
    alias : ndarray
        The slow-rate frequency each aliases onto.
    groups : list of ndarray
        The excited frequencies that alias onto the same slow frequency, two or
        more per group, each group in increasing order.
    slow_nyquist : float
    """

    freqs: np.ndarray
    power: np.ndarray
    alias: np.ndarray
    groups: list
    slow_nyquist: float

    @property
    def confounded(self) -> np.ndarray:
        """Whether each excited frequency shares its alias with another excited one."""
        inside = np.zeros(self.freqs.shape[0], dtype=bool)
        for group in self.groups:
            inside |= np.isin(self.freqs, group)
        return inside

    def __repr__(self) -> str:
        return (f"Confounding({self.freqs.shape[0]} excited frequencies, "
                f"{int(self.confounded.sum())} in {len(self.groups)} confounded groups, "
                f"slow Nyquist {self.slow_nyquist:g})")


def confounded_frequencies(u, factor: int, sample_time: float = 1.0,
                           threshold: float = 1e-6) -> Confounding:
    """Which frequencies excited by ``u`` alias onto each other at the slow rate.

    Parameters
    ----------
    u : array-like of shape (N,)
        Any input (one period of a periodic one: its DFT bins are its lines).
    factor : int
        Downsampling factor ``F``.
    sample_time : float, default=1.0
        Fast sample time ``T`` in seconds.
    threshold : float, default=1e-6
        A bin is excited when its power exceeds ``threshold`` times the
        largest bin's.

    Returns
    -------
    Confounding

    Examples
    --------
    >>> import numpy as np
    >>> n = np.arange(60)
    >>> u = np.cos(2 * np.pi * 4 * n / 60) + np.cos(2 * np.pi * 16 * n / 60)
    >>> found = confounded_frequencies(u, factor=3)
    >>> found.groups  # 16/60 = 1/3 - 4/60: the same slow samples as 4/60
    [array([0.06666667, 0.26666667])]
    >>> confounded_frequencies(np.cos(2 * np.pi * 4 * n / 60), factor=3).groups
    []
    """
    u = check_signal(u, "u")
    if u.ndim != 1:
        raise ValueError(f"u must be a 1-D array; got shape {u.shape}")
    factor = check_int(factor, "factor", low=1)
    sample_time = check_sample_time(sample_time)
    threshold = check_positive(threshold, "threshold", allow_zero=True)
    n_samples = u.shape[0]
    spectrum = np.fft.rfft(u) / n_samples
    power = np.abs(spectrum) ** 2
    power[1:] *= 2.0
    if n_samples % 2 == 0:
        power[-1] /= 2.0  # the Nyquist bin is its own mirror
    freqs = np.fft.rfftfreq(n_samples, d=sample_time)
    excited = power > threshold * power.max() if power.max() > 0 else np.zeros_like(power, bool)
    freqs, power = freqs[excited], power[excited]
    alias = alias_frequency(freqs, factor, sample_time)
    # aliases of distinct bins are equal up to rounding, or at least a bin apart
    resolution = 1.0 / (n_samples * sample_time)
    keys = np.round(alias / (0.5 * resolution)).astype(np.int64)
    groups = []
    for key in np.unique(keys):
        members = freqs[keys == key]
        if members.shape[0] > 1:
            groups.append(np.sort(members))
    return Confounding(freqs=freqs, power=power, alias=alias, groups=groups,
                       slow_nyquist=0.5 / (factor * sample_time))
