"""Axes helpers shared by the figures of :mod:`gpmultirate.plotting`.

They check the axes a function is given or make a new figure, shade bands,
convert magnitudes to dB and label marker lines, the same way for every
figure of the package.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import PolyCollection
from matplotlib.colors import to_rgba
from matplotlib.text import Text

__all__ = [
    "BAND_ALPHA",
    "NYQUIST_GID",
    "axes_or_new",
    "check_axes",
    "check_choice",
    "draw_band",
    "label_marker",
    "to_db",
]

#: Opacity of every shaded credible band.
BAND_ALPHA = 0.25
#: ``gid`` of the Nyquist marker lines, so that overlays draw each marker once.
NYQUIST_GID = {"slow": "gpmultirate-slow-nyquist", "fast": "gpmultirate-fast-nyquist"}


def check_axes(ax, name: str) -> Axes:
    """Return ``ax`` if it is a matplotlib Axes, else raise a ValueError naming ``name``.

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> from matplotlib.figure import Figure
    >>> ax = Figure().subplots()
    >>> check_axes(ax, "ax") is ax
    True
    """
    if not isinstance(ax, Axes):
        raise ValueError(f"{name} must be a matplotlib Axes; got {type(ax).__name__}")
    return ax


def axes_or_new(ax, name: str = "ax") -> Axes:
    """The given Axes (checked), or the Axes of a new figure when ``ax`` is None.

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import matplotlib.pyplot as plt
    >>> ax = axes_or_new(None)
    >>> axes_or_new(ax) is ax
    True
    >>> plt.close("all")
    """
    if ax is None:
        _, ax = plt.subplots(layout="constrained")
        return ax
    return check_axes(ax, name)


def check_choice(value, name: str, choices: tuple) -> str:
    """Return ``value`` if it is one of ``choices``, else raise a ValueError naming ``name``.

    Examples
    --------
    >>> check_choice("log", "xscale", ("linear", "log"))
    'log'
    """
    if value not in choices:
        raise ValueError(f"{name} must be one of {choices}; got {value!r}")
    return value


def to_db(magnitude: np.ndarray) -> np.ndarray:
    """``20 log10 |.|`` with NaN (a gap in the plot) for zero magnitudes.

    Examples
    --------
    >>> import numpy as np
    >>> to_db(np.array([10.0, 0.0]))
    array([20., nan])
    """
    out = np.full(magnitude.shape, np.nan)
    positive = magnitude > 0
    out[positive] = 20.0 * np.log10(magnitude[positive])
    return out


def draw_band(ax: Axes, x, lower, upper, color, *, label: str = "_nolegend_",
              where=None, edge: bool = False) -> PolyCollection:
    """Shade ``lower <= y <= upper`` over ``x``, by default without a legend entry.

    ``label`` gives it a legend entry, ``where`` (bool array over ``x``) shades
    only the runs where it is True, and ``edge=True`` outlines the band with a
    thin line in its colour, so that overlapping bands stay apart.

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> from matplotlib.figure import Figure
    >>> ax = Figure().subplots()
    >>> band = draw_band(ax, [0, 1], [0, 0], [1, 2], "tab:blue")
    >>> band in ax.collections, band.get_label()
    (True, '_nolegend_')
    """
    if edge:
        return ax.fill_between(x, lower, upper, where=where,
                               facecolor=to_rgba(color, BAND_ALPHA),
                               edgecolor=to_rgba(color, 0.7), linewidth=0.6, label=label)
    return ax.fill_between(
        x, lower, upper, where=where, color=color, alpha=BAND_ALPHA, linewidth=0, label=label
    )


def label_marker(ax: Axes, x: float, text: str, gid: str | None = None, *,
                 ha: str = "center", inside: bool = False) -> Text:
    """Label of a vertical marker line at ``x`` (a Nyquist frequency, ``P = M``).

    By default horizontal, just above the axes, clear of the data and the
    legend; ``inside=True`` writes it vertically along the line, near the
    bottom, for axes with a title.

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> from matplotlib.figure import Figure
    >>> ax = Figure().subplots()
    >>> label_marker(ax, 0.5, "slow Nyquist").get_text()
    'slow Nyquist'
    """
    if inside:
        return ax.annotate(text, xy=(x, 0.03), xycoords=ax.get_xaxis_transform(),
                           xytext=(-2, 0), textcoords="offset points", rotation=90,
                           ha="right", va="bottom", fontsize="small", color="0.3", gid=gid)
    return ax.annotate(text, xy=(x, 1.0), xycoords=ax.get_xaxis_transform(),
                       xytext=(0, 2), textcoords="offset points", ha=ha, va="bottom",
                       fontsize="small", color="0.3", gid=gid)
