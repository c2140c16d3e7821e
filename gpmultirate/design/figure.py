"""Drawing predicted bands: the band radius over frequency, before and after a design.

:func:`plot_band_radius` draws what it is given on an ``ax`` and returns the
lines; it never shows.  :func:`design_figure` makes the bare figure of
``gpmultirate design`` (magnitude bands and radii) without pyplot.
"""

from __future__ import annotations

import numpy as np

from gpmultirate.design.bands import band_radius

__all__ = ["design_figure", "plot_band_radius"]


def plot_band_radius(frequency_responses, labels=None, ax=None, band_hz=None):
    """Draw the band radius of predicted (or fitted) frequency responses against frequency.

    Parameters
    ----------
    frequency_responses : sequence of FrequencyResponse
    labels : sequence of str, optional
    ax : matplotlib Axes, optional
        Default a new figure's axes (through pyplot).
    band_hz : (f_lo, f_hi), optional
        The design's range, shaded.

    Returns
    -------
    list of matplotlib Line2D
        One line per response, then the slow Nyquist line.

    Examples
    --------
    >>> from matplotlib.figure import Figure
    >>> from gpmultirate.responses import FrequencyResponse
    >>> frf = FrequencyResponse.from_gaussian([0.1, 0.2, 0.3], [0j] * 3, [1.0] * 3,
    ...                                       [1.0] * 3, [0.0] * 3, factor=3)
    >>> len(plot_band_radius([frf], ["flat"], ax=Figure().subplots()))
    2
    """
    if ax is None:
        import matplotlib.pyplot as plt

        ax = plt.figure().subplots()
    frequency_responses = list(frequency_responses)
    labels = [None] * len(frequency_responses) if labels is None else list(labels)
    lines = []
    for frf, label in zip(frequency_responses, labels):
        lines += ax.semilogy(frf.freqs, band_radius(frf), label=label)
    first = frequency_responses[0]
    lines.append(ax.axvline(first.slow_nyquist, color="0.4", linestyle=":",
                            label="slow Nyquist"))
    if band_hz is not None:
        ax.axvspan(band_hz[0], band_hz[1], color="0.9", zorder=0)
    ax.set_xlabel(f"frequency [{first.frequency_unit}]")
    ax.set_ylabel(f"band radius ({first.level:.0%})")
    ax.legend(loc="best")
    return lines


def design_figure(before, after, band_hz, reference=None):
    """The figure of a design: the pilot's magnitude with both bands, and the band radii.

    Parameters
    ----------
    before, after : FrequencyResponse
        Predicted bands of the reference input and of the designed one.
    band_hz : (f_lo, f_hi)
    reference : FrequencyResponse, optional
        The pilot model's FRF at the same frequencies: the bands are drawn
        around its magnitude.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    figure = Figure(layout="constrained", figsize=(8, 6.5))
    top, bottom = figure.subplots(2, 1, sharex=True)
    if reference is not None:
        magnitude = reference.magnitude
        for frf, label, color in ((before, "before", "C0"), (after, "designed", "C1")):
            radius = band_radius(frf)
            top.fill_between(frf.freqs, np.maximum(magnitude - radius, magnitude * 1e-3),
                             magnitude + radius, color=color, alpha=0.3,
                             label=f"{label}: predicted band")
        top.semilogy(reference.freqs, magnitude, color="k", label="pilot model |G|")
        top.set_yscale("log")
        top.set_ylabel("|G|")
        top.axvline(after.slow_nyquist, color="0.4", linestyle=":")
        top.legend(loc="best")
    else:
        top.set_visible(False)
    plot_band_radius([before, after], ["before", "designed"], ax=bottom, band_hz=band_hz)
    return figure
