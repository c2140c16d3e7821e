"""Frequency responses drawn from a fitted model's posterior, and their bands.

The loop quantities (a plant from a process sensitivity, a closed loop's
gain between the frames) are nonlinear in the identified response, so their
bands come from posterior draws: each draw of the impulse response gives
the quantity, and the band is the pointwise equal-tailed interval of the
magnitudes over the draws.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sklearn.utils.validation import check_is_fitted

from gpmultirate.responses import default_frequencies, dft_matrix
from gpmultirate.validation import check_int, check_level

__all__ = ["LoopResponse", "frequency_draws", "loop_response"]


@dataclass(frozen=True)
class LoopResponse:
    """A loop quantity over frequency with a credible band from posterior draws.

    Attributes
    ----------
    freqs : ndarray of shape (n,)
        Frequencies in Hz (cycles per sample when ``sample_time`` is 1).
    mean : ndarray of shape (n,)
        The quantity at the posterior-mean impulse response(s) (complex
        where it has a phase).
    magnitude_lower, magnitude_upper : ndarray of shape (n,)
        The pointwise equal-tailed ``level`` interval of ``|quantity|`` over
        the draws.
    level : float
    n_samples : int
        The posterior draws the band is read from.
    sample_time : float
    name : str
        What the quantity is, for a figure's legend.
    """

    freqs: np.ndarray
    mean: np.ndarray
    magnitude_lower: np.ndarray
    magnitude_upper: np.ndarray
    level: float
    n_samples: int
    sample_time: float
    name: str

    @property
    def magnitude(self) -> np.ndarray:
        """``|mean|``."""
        return np.abs(self.mean)

    def contains(self, magnitude) -> np.ndarray:
        """Whether each magnitude lies in the band (e.g. a true plant's ``|G|``)."""
        magnitude = np.asarray(magnitude, dtype=float)
        return (magnitude >= self.magnitude_lower) & (magnitude <= self.magnitude_upper)


def frequency_draws(model, freqs, n_samples: int, random_state=None):
    """The model's FRF at ``freqs`` (Hz): posterior mean and ``n_samples`` draws.

    Returns ``(mean, draws)`` of shapes ``(n,)`` and ``(n_samples, n)``.
    """
    check_is_fitted(model, "coef_")
    order = int(np.asarray(model.coef_).shape[-1])
    if np.ndim(model.coef_) != 1:
        raise ValueError("the loop tools take a model of one input")
    E = dft_matrix(np.asarray(freqs, dtype=float), float(model.sample_time), order)
    draws = model.sample_impulse_responses(np.arange(order), n_samples=n_samples,
                                           random_state=random_state)
    return E @ np.asarray(model.coef_, dtype=float), (E @ draws).T


def check_loop_frequencies(model, freqs):
    """Frequencies in Hz below the fast Nyquist frequency; by default the record's DFT bins."""
    if freqs is None:
        freqs = default_frequencies(model.observation_.n_samples, float(model.sample_time))
    freqs = np.array(freqs, dtype=float).reshape(-1)
    if freqs.size == 0 or not np.all(np.isfinite(freqs)) or np.any(freqs < 0):
        raise ValueError("freqs must be a non-empty array of finite non-negative frequencies")
    return freqs


def loop_response(freqs, mean, draws, level, sample_time, name) -> LoopResponse:
    """A :class:`LoopResponse` from the quantity at the mean and at each draw."""
    level = check_level(level)
    n_samples = check_int(np.shape(draws)[0], "n_samples", low=2)
    tail = 50.0 * (1.0 - level)
    lower, upper = np.percentile(np.abs(draws), [tail, 100.0 - tail], axis=0)
    arrays = [np.array(a) for a in (freqs, mean, lower, upper)]
    for a in arrays:
        a.setflags(write=False)
    return LoopResponse(*arrays, level=level, n_samples=n_samples,
                        sample_time=float(sample_time), name=name)
