"""Choosing the sampling: candidate schemes ranked by the bands they predict.

For one input, each :class:`~gpmultirate.design.SamplingScheme` (a factor, the
offsets of several slow sensors, regular or jittered instants, an exposure)
gives a predicted band (:mod:`gpmultirate.design.predicted`); the comparison
summarizes it over the user's range by the band radius
(:mod:`gpmultirate.design.bands`), in the mean and at the worst frequency,
and above the slow Nyquist frequency of each scheme.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gpmultirate.design.bands import band_radius
from gpmultirate.design.criterion import check_criterion
from gpmultirate.design.multisine import check_band
from gpmultirate.design.predicted import predicted_frequency_response
from gpmultirate.design.prior import design_prior
from gpmultirate.design.sampling import SamplingScheme
from gpmultirate.validation import check_level

__all__ = ["SamplingComparison", "compare_sampling"]


@dataclass(frozen=True)
class SamplingComparison:
    """Candidate sampling schemes and their predicted bands over a frequency range.

    Attributes
    ----------
    schemes : list of SamplingScheme
    frequency_responses : list of FrequencyResponse
        The predicted band of each scheme.
    mean_radius, worst_radius : ndarray of shape (n_schemes,)
        The band radius over the range: mean and largest.
    above_slow_nyquist : ndarray of shape (n_schemes,)
        The mean band radius over the part of the range above each scheme's
        slow Nyquist frequency (NaN where there is none).
    n_readings : ndarray of shape (n_schemes,)
        The readings each scheme takes of the record.
    criterion : str
        ``"mean"`` or ``"worst"``: what :attr:`best` minimizes.
    """

    schemes: list
    frequency_responses: list
    mean_radius: np.ndarray
    worst_radius: np.ndarray
    above_slow_nyquist: np.ndarray
    n_readings: np.ndarray
    criterion: str

    @property
    def best(self) -> SamplingScheme:
        """The scheme of the narrowest band by :attr:`criterion`."""
        score = self.mean_radius if self.criterion == "mean" else self.worst_radius
        return self.schemes[int(np.argmin(score))]

    def table(self) -> str:
        """The comparison as a Markdown table."""
        lines = ["| scheme | readings | mean band radius | worst band radius | "
                 "mean above slow Nyquist |", "|---|---:|---:|---:|---:|"]
        for s, n, m, w, a in zip(self.schemes, self.n_readings, self.mean_radius,
                                 self.worst_radius, self.above_slow_nyquist):
            lines.append(f"| {s.label} | {n} | {m:.4g} | {w:.4g} | {a:.4g} |")
        return "\n".join(lines)


def compare_sampling(prior, u, schemes, band_hz=None, noise_level=None, level: float = 0.95,
                     criterion: str = "mean", *, order=None,
                     sample_time=None) -> SamplingComparison:
    """Rank candidate sampling schemes of one input by the bands they predict.

    Parameters
    ----------
    prior : FIRGaussianProcess (fitted), sklearn Kernel or DesignPrior
    u : array-like of shape (N,)
        The planned input.
    schemes : sequence of SamplingScheme
        The candidates (factor, offsets, jitter, exposure, or instants).
    band_hz : (f_lo, f_hi), optional
        The range the bands are compared over; default up to the fast
        Nyquist frequency.
    noise_level, order, sample_time : optional
        As for :func:`~gpmultirate.design.predicted_frequency_response`;
        the noise variance is that of one reading, the same for every scheme.
    level : float, default=0.95
    criterion : {"mean", "worst"}, default="mean"

    Returns
    -------
    SamplingComparison

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate.kernels import DC
    >>> from gpmultirate.design import SamplingScheme
    >>> u = np.random.default_rng(0).standard_normal(120)
    >>> found = compare_sampling(C(1.0) * DC(0.9, 0.5), u, [
    ...     SamplingScheme(factor=4), SamplingScheme(factor=4, offsets=(0, 2))], order=40)
    >>> found.best.label, found.n_readings.tolist()
    ('F=4, offsets (0, 2)', [30, 60])
    """
    prior = design_prior(prior, order=order, sample_time=sample_time, noise_level=noise_level)
    level = check_level(level)
    criterion = check_criterion(criterion)
    schemes = list(schemes) if not isinstance(schemes, SamplingScheme) else [schemes]
    if not schemes or not all(isinstance(s, SamplingScheme) for s in schemes):
        raise ValueError("schemes must be a non-empty sequence of SamplingScheme")
    T = prior.sample_time
    low, high = check_band((0.0, 0.5 / T) if band_hz is None else band_hz, T)
    n_samples = np.asarray(u).shape[0]
    freqs = np.fft.rfftfreq(2 * n_samples, d=T)
    freqs = freqs[(freqs >= low - 1e-12) & (freqs <= high + 1e-12)]
    frfs, mean, worst, above, readings = [], [], [], [], []
    for scheme in schemes:
        frf = predicted_frequency_response(prior, u, freqs=freqs, level=level, scheme=scheme)
        radius = band_radius(frf)
        frfs.append(frf)
        mean.append(radius.mean())
        worst.append(radius.max())
        upper = freqs > frf.slow_nyquist
        above.append(radius[upper].mean() if np.any(upper) else np.nan)
        readings.append(scheme.instants(n_samples).shape[0])
    return SamplingComparison(schemes, frfs, np.array(mean), np.array(worst), np.array(above),
                              np.array(readings), criterion)
