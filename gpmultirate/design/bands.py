"""One number per frequency for the width of a frequency-response band.

The credible region of ``G(f)`` is an ellipse in the complex plane
(:class:`~gpmultirate.FrequencyResponse`).  A design compares many of them,
so it reads each as the **band radius**

    r(f) = sqrt(chi2_2(level) (var Re G + var Im G) / 2),

the radius of the credible circle of a complex Gaussian with the same total
variance ``E|G - mean|^2``.  It is exact for a circular band, depends on
the input and the sampling only through the posterior covariance (never on
the output or the mean) and is smooth in them, so that it can be minimized.
Where ``|G|`` is well above it, the magnitude band is about ``|G| +- r``, or
``+- 20 log10(1 + r / |G|)`` dB.
"""

from __future__ import annotations

import numpy as np

from gpmultirate.responses import FrequencyResponse

__all__ = ["band_decibels", "band_radius", "chi2_2"]


def chi2_2(level: float) -> float:
    """Quantile of the chi-square distribution with two degrees of freedom at ``level``.

    Examples
    --------
    >>> round(chi2_2(0.95), 4)
    5.9915
    """
    return float(-2.0 * np.log1p(-level))


def band_radius(frf: FrequencyResponse) -> np.ndarray:
    """The band radius ``r(f)`` of each frequency of ``frf``, in the units of ``G``.

    Examples
    --------
    >>> frf = FrequencyResponse.from_gaussian([0.0], [1.0 + 0j], [0.02], [0.02], [0.0])
    >>> band_radius(frf).round(4)  # a circle: the magnitude band's half-width
    array([0.3462])
    >>> bool(np.isclose(frf.magnitude_upper[0] - 1.0, band_radius(frf)[0]))
    True
    """
    if not isinstance(frf, FrequencyResponse):
        raise ValueError(f"frf must be a FrequencyResponse; got {type(frf).__name__}")
    total = frf.real_std ** 2 + frf.imag_std ** 2
    return np.sqrt(chi2_2(frf.level) * total / 2.0)


def band_decibels(radius, magnitude) -> np.ndarray:
    """The magnitude band's upper half-width in dB, ``20 log10(1 + r / |G|)``.

    Examples
    --------
    >>> band_decibels([0.122], [1.0]).round(3)  # 1 dB: r / |G| = 0.122
    array([1.])
    """
    radius = np.asarray(radius, dtype=float)
    magnitude = np.asarray(magnitude, dtype=float)
    with np.errstate(divide="ignore"):
        return 20.0 * np.log10(1.0 + radius / magnitude)
