"""Goodness of fit against model order over Monte Carlo runs (Fig. 5, 9).

* :func:`plot_gof_vs_order` draws a :class:`~gpmultirate.study.GoFSummary`
  (mean and ``+- n_std`` sample standard deviations per order).
* :func:`plot_study` draws every method of a
  :class:`~gpmultirate.study.StudyResult` in the paper's styles.

The statistics come from :class:`~gpmultirate.study.GoFSummary`; these
functions only draw them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import PolyCollection
from matplotlib.lines import Line2D

from gpmultirate.plotting.axes import axes_or_new, draw_band, label_marker
from gpmultirate.study.results import GoFSummary, StudyResult
from gpmultirate.validation import check_positive

__all__ = ["STUDY_STYLES", "GoFPlot", "StudyPlot", "plot_gof_vs_order", "plot_study"]

#: Colours and markers of the paper's Fig. 5: LS red circles, DC blue squares, PK green
#: triangles.
STUDY_STYLES = {
    "LS": {"color": "tab:red", "marker": "o"},
    "DC": {"color": "tab:blue", "marker": "s"},
    "PK": {"color": "tab:green", "marker": "^"},
}
_SLOW_SAMPLES_GID = "gpmultirate-slow-samples"


@dataclass
class GoFPlot:
    """Axes and artists drawn by :func:`plot_gof_vs_order`.

    Attributes
    ----------
    ax : Axes
    line : Line2D
        Mean goodness of fit over the runs; NaN (a gap) where not shown.
    band : PolyCollection or None
        Mean +- ``n_std`` sample standard deviations; ``None`` for a single run.

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> from gpmultirate.plotting import plot_gof_vs_order
    >>> drawn = plot_gof_vs_order([10, 20], [[90.0, 95.0], [92.0, 93.0]])
    >>> drawn.band is not None
    True
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """

    ax: Axes
    line: Line2D
    band: PolyCollection | None


def plot_gof_vs_order(
    orders,
    gof=None,
    *,
    ax: Axes | None = None,
    label: str | None = None,
    color=None,
    marker: str | None = None,
    identifiable=None,
    n_std: float = 2.0,
) -> GoFPlot:
    """Mean goodness of fit against model order, with a ``+- n_std`` std band.

    Draws the mean of a :class:`~gpmultirate.study.GoFSummary` per order and
    its band ``mean +- n_std std``, as in the paper's Fig. 5.  Orders where
    no run has a value, or where ``identifiable`` is False (least squares
    with ``P >= M``), are left out of the line and the band.  Given the
    orders and a table of values instead, the summary is first built by
    :meth:`GoFSummary.from_runs <gpmultirate.study.GoFSummary.from_runs>`.

    Parameters
    ----------
    orders : GoFSummary or array-like of shape (n_orders,)
        The statistics to draw, or the model orders ``P``.
    gof : array-like of shape (n_runs, n_orders) or (n_orders,)
        Only with orders: goodness of fit in percent (eq. 20), NaN where not
        computed.
    ax : Axes, optional
        Axes to draw on; by default a new figure.
    label, color, marker : optional
        Legend entry, colour and marker of the mean line.
    identifiable : bool array-like of shape (n_orders,) or gof's shape, optional
        Only with orders: where the estimate exists; entries marked False are
        treated as NaN.
    n_std : float, default=2
        Half-width of the band in sample standard deviations.

    Returns
    -------
    GoFPlot

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import numpy as np
    >>> from gpmultirate.plotting import plot_gof_vs_order
    >>> from gpmultirate.study import GoFSummary
    >>> orders = np.array([10, 50, 100, 200])
    >>> gof = np.array([[90.0, 95.0, 93.0, np.nan], [92.0, 97.0, 91.0, np.nan]])
    >>> drawn = plot_gof_vs_order(orders, gof, label="LS", marker="o",
    ...                           identifiable=orders < 150)
    >>> drawn.line.get_ydata()
    array([91., 96., 92., nan])
    >>> summary = GoFSummary.from_runs(orders, gof)
    >>> plot_gof_vs_order(summary, ax=drawn.ax, label="again").line.get_ydata()
    array([91., 96., 92., nan])
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """
    if isinstance(orders, GoFSummary):
        if gof is not None or identifiable is not None:
            raise ValueError("gof and identifiable must not be given with a GoFSummary")
        summary = orders
    else:
        if gof is None:
            raise ValueError("gof must be given with orders (or pass a GoFSummary)")
        summary = GoFSummary.from_runs(orders, gof, identifiable)
    n_std = check_positive(n_std, "n_std")

    ax = axes_or_new(ax)
    (line,) = ax.plot(summary.orders, summary.mean, color=color, marker=marker, markersize=4,
                      label=label)
    band = None
    if summary.n_runs > 1:
        band = draw_band(ax, summary.orders, *summary.band(n_std), line.get_color())
    ax.set_xlabel("model order P")
    ax.set_ylabel("GoF [%]")
    ax.grid(True, alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize="small", loc="lower right")
    return GoFPlot(ax=ax, line=line, band=band)


@dataclass
class StudyPlot:
    """Axes and artists drawn by :func:`plot_study`.

    Attributes
    ----------
    ax : Axes
    plots : dict of str to GoFPlot
        Mean line and band of each method, in the order drawn.
    slow_samples_line : Line2D or None
        Vertical marker at ``P = M``, the number of slow samples, above which
        least squares is not identifiable; ``None`` when ``M`` is outside the
        orders of the study or the marker was already drawn.
    errorbars : dict of str to ErrorbarContainer
        ``+- n_std`` error bars at orders whose neighbours have no value,
        where the band has no width to show (for instance a study of two
        orders); methods without such orders are left out.

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> from gpmultirate.plotting import plot_study
    >>> from gpmultirate.study import run_paper_study
    >>> drawn = plot_study(run_paper_study(2, (5, 30), "LS", n_samples=60, progress=False))
    >>> sorted(drawn.errorbars)  # P = 5 is the only order with a value
    ['LS']
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """

    ax: Axes
    plots: dict
    slow_samples_line: Line2D | None
    errorbars: dict


def plot_study(result: StudyResult, *, ax: Axes | None = None, methods=None,
               n_std: float = 2) -> StudyPlot:
    """Goodness of fit against model order for every method of a study (Fig. 5).

    For each method, :func:`plot_gof_vs_order` draws the mean over the runs
    and a band of ``+- n_std`` sample standard deviations
    (:meth:`StudyResult.gof_summary <gpmultirate.study.StudyResult.gof_summary>`),
    leaving out the orders where the model is not identifiable; a vertical
    line marks ``P = M``.  Orders whose neighbours have no value get error
    bars, since a band needs two orders to have a width.  The lower y-limit
    keeps the means in view without letting a very wide band squash them.

    Parameters
    ----------
    result : StudyResult
        From :func:`gpmultirate.study.run_paper_study`.
    ax : Axes, optional
        Axes to draw on; by default a new figure.
    methods : sequence of str, optional
        Methods to draw, a subset of ``result.methods``; default all.
    n_std : float, default=2
        Half-width of the bands in sample standard deviations (the paper's 2).

    Returns
    -------
    StudyPlot

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> from gpmultirate.study import run_paper_study
    >>> from gpmultirate.plotting import plot_study
    >>> result = run_paper_study(n_runs=2, orders=(5, 10, 20), methods=("LS",),
    ...                          n_samples=60, progress=False)
    >>> drawn = plot_study(result)
    >>> sorted(drawn.plots), float(drawn.slow_samples_line.get_xdata()[0])
    (['LS'], 20.0)
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """
    if not isinstance(result, StudyResult):
        raise ValueError(f"result must be a StudyResult; got {type(result).__name__}")
    if methods is None:
        methods = tuple(result.methods)
    elif isinstance(methods, str):
        methods = (methods,)
    methods = tuple(methods)
    unknown = [m for m in methods if m not in result.methods]
    if not methods or unknown:
        raise ValueError(
            f"methods must be a non-empty subset of {tuple(result.methods)}; got {methods!r}"
        )
    n_std = check_positive(n_std, "n_std")
    ax = axes_or_new(ax)
    previous_ylim = ax.get_ylim() if ax.has_data() else None  # overlaying: only widen
    plots, errorbars = {}, {}
    for method in methods:
        summary = result.gof_summary(method)
        drawn = plot_gof_vs_order(summary, ax=ax, label=method, n_std=n_std,
                                  **STUDY_STYLES.get(method, {}))
        plots[method] = drawn
        shown = np.isfinite(summary.mean)
        neighbours = np.zeros_like(shown)
        neighbours[1:] |= shown[:-1]
        neighbours[:-1] |= shown[1:]
        isolated = shown & ~neighbours
        if np.any(isolated) and drawn.band is not None:
            # one value has no spread: a zero-length bar
            std = np.where(np.isfinite(summary.std), summary.std, 0.0)[isolated]
            errorbars[method] = ax.errorbar(
                summary.orders[isolated], summary.mean[isolated], yerr=n_std * std,
                fmt="none", ecolor=drawn.line.get_color(), elinewidth=1.0, capsize=4,
                label="_nolegend_")

    slow_line = None
    n_slow = result.n_slow_samples
    orders = np.asarray(result.orders)
    already = any(ln.get_gid() == _SLOW_SAMPLES_GID for ln in ax.get_lines())
    if not already and orders.min() <= n_slow <= orders.max():
        slow_line = ax.axvline(n_slow, color="0.4", linestyle="-.", linewidth=0.8,
                               gid=_SLOW_SAMPLES_GID, label="_nolegend_")
        label_marker(ax, n_slow, f"P = M = {n_slow}", _SLOW_SAMPLES_GID, inside=True)
    _set_gof_limits(ax, plots, errorbars, previous_ylim)
    return StudyPlot(ax=ax, plots=plots, slow_samples_line=slow_line, errorbars=errorbars)


def _set_gof_limits(ax: Axes, plots: dict, errorbars: dict, previous_ylim) -> None:
    """y-limits that show every mean and the bands, within reason."""
    means = np.concatenate([p.line.get_ydata() for p in plots.values()]).astype(float)
    means = means[np.isfinite(means)]
    if not means.size:
        return
    # GoF <= 100 %; below, show the bands, but not more than half again the
    # spread of the means (a band reaching -1000 % would flatten everything)
    lowest_mean = float(means.min())
    lows = [lowest_mean]
    for method, plot in plots.items():
        if plot.band is not None:
            lows.extend(v[:, 1].min() for v in
                        (path.vertices for path in plot.band.get_paths()) if v.size)
        if method in errorbars:
            bars = errorbars[method].lines[2][0].get_segments()
            lows.extend(segment[:, 1].min() for segment in bars)
    top = max(100.0, float(means.max()))
    bottom = max(min(lows), lowest_mean - 0.5 * max(top - lowest_mean, 1.0))
    span = max(top - bottom, 1e-9)
    bottom, top = bottom - 0.03 * span, top + 0.03 * span
    if previous_ylim is not None:
        bottom, top = min(bottom, previous_ylim[0]), max(top, previous_ylim[1])
    ax.set_ylim(bottom, top)
