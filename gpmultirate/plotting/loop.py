"""Figures of closed-loop quantities: a :class:`~gpmultirate.closedloop.LoopResponse` with its band."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import PolyCollection
from matplotlib.lines import Line2D

from gpmultirate.plotting.axes import axes_or_new, draw_band, to_db

__all__ = ["LoopResponsePlot", "plot_loop_response", "plot_intersample_performance"]


@dataclass
class LoopResponsePlot:
    """Axes and artists drawn by :func:`plot_loop_response` (and per response by
    :func:`plot_intersample_performance`).

    Attributes
    ----------
    ax : Axes
    lines : list of Line2D
        The magnitude (dB) of each response drawn.
    bands : list of PolyCollection
        Its credible band.
    """

    ax: Axes
    lines: list
    bands: list


def plot_loop_response(response, ax=None, label: str | None = None, color=None,
                       truth=None) -> LoopResponsePlot:
    """Magnitude in dB of a loop response with its band (and a true magnitude, dashed).

    Parameters
    ----------
    response : LoopResponse
    ax : Axes, optional
        Drawn on a new figure when None.
    label : str, optional
        Legend entry; by default the response's name.
    color : matplotlib colour, optional
    truth : array-like of shape (n,), optional
        A true magnitude to compare with (a simulated plant's).

    Returns
    -------
    LoopResponsePlot

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import numpy as np
    >>> from gpmultirate.closedloop.response import loop_response
    >>> response = loop_response(np.array([1.0, 2.0]), np.array([1.0, 0.5]),
    ...                          np.array([[0.9, 0.4], [1.1, 0.6]]), 0.95, 0.01, "plant")
    >>> drawn = plot_loop_response(response)
    >>> np.round(drawn.lines[0].get_ydata(), 1).tolist()
    [0.0, -6.0]
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """
    ax = axes_or_new(ax)
    line, = ax.plot(response.freqs, to_db(np.abs(response.mean)), color=color,
                    label=response.name if label is None else label)
    band = draw_band(ax, response.freqs, to_db(response.magnitude_lower),
                     to_db(response.magnitude_upper), line.get_color())
    lines = [line]
    if truth is not None:
        true_line, = ax.plot(response.freqs, to_db(np.abs(np.asarray(truth))), "--",
                             color=line.get_color(), linewidth=0.9, label="_nolegend_")
        lines.append(true_line)
    unit = "Hz" if response.sample_time != 1.0 else "cycles/sample"
    ax.set_xlabel(f"frequency [{unit}]")
    ax.set_ylabel("magnitude [dB]")
    return LoopResponsePlot(ax, lines, [band])


def plot_intersample_performance(performance, ax=None) -> LoopResponsePlot:
    """The fast output's gain and the frames' gain of a camera loop, with their bands.

    The gap between the two is what the loop does between the frames.

    Parameters
    ----------
    performance : IntersamplePerformance
    ax : Axes, optional

    Returns
    -------
    LoopResponsePlot
        Both responses' lines and bands (the fast output first).
    """
    ax = axes_or_new(ax)
    fast = plot_loop_response(performance.fast, ax=ax, label="fast output (between frames)")
    frames = plot_loop_response(performance.frames, ax=ax, label="frames")
    ax.set_title(f"closed loop, r to the output ({performance.fast.level:.0%} bands)")
    ax.legend(loc="best")
    return LoopResponsePlot(ax, fast.lines + frames.lines, fast.bands + frames.bands)
