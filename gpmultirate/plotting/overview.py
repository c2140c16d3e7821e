"""The overview of a whole record's predicted output: readable at any length.

A fast record of tens of thousands of samples drawn as a line is a solid
blob.  :func:`plot_overview` draws the prediction as it is on a short record
and, beyond ``max_points`` fast samples, as an envelope over bins of
``ceil(N / max_points)`` samples: per bin the range of the predicted mean
(dark) and the range of the credible band (light), so that no excursion of
the mean or of the band is lost by the decimation.  The slow samples are
always drawn, smaller on a long record.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import PolyCollection
from matplotlib.lines import Line2D

from gpmultirate.plotting.axes import axes_or_new, draw_band
from gpmultirate.responses import OutputPrediction

__all__ = ["OVERVIEW_POINTS", "OverviewPlot", "envelope", "plot_overview"]

#: The most fast samples an overview draws one by one; beyond, bins.
OVERVIEW_POINTS = 1200


@dataclass(frozen=True)
class OverviewPlot:
    """What :func:`plot_overview` drew.

    Attributes
    ----------
    ax : Axes
    band : PolyCollection
        The credible band (per bin: the lowest lower and highest upper edge).
    mean : Line2D or PolyCollection
        The predicted mean: a line, or per bin its range.
    slow_markers : Line2D or None
        The slow samples (or readings) at their instants.
    bin_width : int
        Fast samples per bin (1: drawn one by one).
    """

    ax: Axes
    band: PolyCollection
    mean: object
    slow_markers: Line2D | None
    bin_width: int


def envelope(values, width: int):
    """Per bin of ``width`` consecutive values: the smallest and the largest.

    Parameters
    ----------
    values : array-like of shape (n,)
    width : int
        Values per bin (the last bin may be shorter).

    Returns
    -------
    low, high : ndarray of shape (ceil(n / width),)

    Examples
    --------
    >>> from gpmultirate.plotting.overview import envelope
    >>> envelope([1.0, 3.0, 2.0, -1.0, 5.0], 2)
    (array([ 1., -1.,  5.]), array([3., 2., 5.]))
    """
    x = np.asarray(values, dtype=float)
    n = x.shape[0]
    bins = -(-n // width)
    padded = np.concatenate([x, np.full(bins * width - n, np.nan)]).reshape(bins, width)
    return np.nanmin(padded, axis=1), np.nanmax(padded, axis=1)


def plot_overview(prediction: OutputPrediction, *, ax=None, max_points: int = OVERVIEW_POINTS,
                  slow_time=None, slow_values=None, label: str | None = None,
                  color=None) -> OverviewPlot:
    """The predicted output over the whole record, as a line or as a binned envelope.

    Parameters
    ----------
    prediction : OutputPrediction
        The fast-rate prediction with its band (and its slow samples, drawn
        unless ``slow_time`` is given).
    ax : Axes, optional
    max_points : int, default=OVERVIEW_POINTS
        Beyond this many fast samples, draw ``ceil(N / max_points)``-sample bins.
    slow_time, slow_values : array-like, optional
        Readings at their own instants (seconds) to draw instead of the
        prediction's slow samples.
    label : str, optional
        Legend label of the mean.
    color : optional
        Colour of the mean and band.

    Returns
    -------
    OverviewPlot

    Examples
    --------
    >>> import numpy as np
    >>> from matplotlib.figure import Figure
    >>> from gpmultirate.responses import OutputPrediction
    >>> from gpmultirate.plotting.overview import plot_overview
    >>> t = np.arange(5000) * 0.01
    >>> prediction = OutputPrediction(time=t, mean=np.sin(t), std=np.full(5000, 0.1),
    ...                               slow_index=np.arange(0, 5000, 10),
    ...                               y_slow=np.sin(t[::10]))
    >>> drawn = plot_overview(prediction, ax=Figure().subplots())
    >>> drawn.bin_width, drawn.slow_markers.get_xdata().shape
    (5, (500,))
    """
    if not isinstance(prediction, OutputPrediction):
        raise ValueError(f"prediction must be an OutputPrediction; got "
                         f"{type(prediction).__name__}")
    if isinstance(max_points, bool) or not isinstance(max_points, (int, np.integer)) \
            or max_points < 2:
        raise ValueError(f"max_points must be an integer of at least 2; got {max_points!r}")
    ax = axes_or_new(ax)
    n = prediction.time.shape[0]
    width = max(1, -(-n // int(max_points)))
    if width == 1:
        (mean,) = ax.plot(prediction.time, prediction.mean, color=color, label=label, zorder=3)
        color = mean.get_color()
        band = draw_band(ax, prediction.time, prediction.lower, prediction.upper, color)
    else:
        starts = prediction.time[::width]
        ends = np.append(prediction.time[width::width], prediction.time[-1])
        centre = 0.5 * (starts + ends)
        low, high = envelope(prediction.mean, width)
        band_low = envelope(prediction.lower, width)[0]
        band_high = envelope(prediction.upper, width)[1]
        mean = ax.fill_between(centre, low, high, color=color or "C0", alpha=0.8,
                               linewidth=0.6, label=None if label is None
                               else f"{label}: range per {width} samples", zorder=3)
        color = mean.get_facecolor()[0][:3]
        band = draw_band(ax, centre, band_low, band_high, color)
    markers = None
    times = prediction.slow_time if slow_time is None else np.asarray(slow_time, dtype=float)
    values = prediction.y_slow if slow_time is None else np.asarray(slow_values, dtype=float)
    if times is not None and values is not None:
        size = 5 if values.shape[0] <= 200 else 2.5 if values.shape[0] <= 1000 else 1.5
        (markers,) = ax.plot(times, values, linestyle="none", marker="o", markersize=size,
                             markerfacecolor="none", markeredgewidth=0.8, color="k",
                             label="slow samples", zorder=4)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("output")
    ax.margins(x=0)
    return OverviewPlot(ax=ax, band=band, mean=mean, slow_markers=markers, bin_width=width)
