"""Residual figure: a :class:`~gpmultirate.residuals.ResidualAnalysis` drawn as ``resid`` does.

The top panel is the autocorrelation of the residuals over slow lags with
its band for white residuals; one panel per input below it holds the
cross-correlation with that input over fast lags and its band.  Bars
outside the shaded band are what to look at: at small slow lags, coloured
noise (the bands of the fit are then too narrow); in the cross-correlation
at positive lags, dynamics the model is missing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import matplotlib.pyplot as plt
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection, PolyCollection

from gpmultirate.plotting.axes import check_axes
from gpmultirate.residuals import ResidualAnalysis

__all__ = ["ResidualPlot", "plot_residuals"]


@dataclass
class ResidualPlot:
    """Axes and artists drawn by :func:`plot_residuals`.

    Attributes
    ----------
    axes : list of Axes
        The autocorrelation axes, then one per input drawn.
    autocorrelation_stems : LineCollection
        One vertical line per lag ``1..max_lag``.
    autocorrelation_band : PolyCollection
        The band ``+- bound`` for white residuals.
    cross_correlation_stems : list of LineCollection
        One per input drawn.
    cross_correlation_bands : list of PolyCollection
        One per input drawn.

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import numpy as np
    >>> from gpmultirate.plotting.residuals import plot_residuals
    >>> from gpmultirate.residuals import residual_correlations
    >>> analysis = residual_correlations(np.random.default_rng(0).standard_normal(200),
    ...                                  np.arange(200), np.ones(200), max_lag=10,
    ...                                  input_lags=[-1, 0, 1], confidence=0.99)
    >>> drawn = plot_residuals(analysis)
    >>> len(drawn.axes), len(drawn.autocorrelation_stems.get_segments())
    (2, 10)
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """

    axes: list
    autocorrelation_stems: LineCollection
    autocorrelation_band: PolyCollection
    cross_correlation_stems: list
    cross_correlation_bands: list


def _stems(ax: Axes, x, y, bound, color) -> tuple[LineCollection, PolyCollection]:
    band = ax.fill_between(x, -bound, bound, step="mid", color="0.6", alpha=0.3, linewidth=0)
    stems = ax.vlines(x, 0.0, y, color=color, linewidth=1.2)
    ax.axhline(0.0, color="0.3", linewidth=0.6)
    return stems, band


def plot_residuals(analysis: ResidualAnalysis, *, ax=None, color=None) -> ResidualPlot:
    """Autocorrelation of the residuals and their cross-correlation with each input.

    Parameters
    ----------
    analysis : ResidualAnalysis
        Made by :func:`~gpmultirate.residuals.analyze_residuals`.
    ax : Axes or sequence of Axes, optional
        Where to draw.  A sequence: the autocorrelation on the first, the
        cross-correlation with input ``j`` on entry ``j + 1`` (inputs
        without an Axes are not drawn).  A single Axes: the autocorrelation
        only.  None: a new figure with one panel per correlation.
    color : matplotlib colour, optional
        Colour of the bars.

    Returns
    -------
    ResidualPlot

    Raises
    ------
    ValueError
        If ``analysis`` is not a ResidualAnalysis or ``ax`` holds something
        other than Axes.

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import numpy as np
    >>> import gpmultirate as gm
    >>> from gpmultirate.plotting.residuals import plot_residuals
    >>> from gpmultirate.residuals import analyze_residuals
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal((600, 2))
    >>> y = np.convolve(u[:, 0], 0.7 ** np.arange(15))[:600] + 0.1 * rng.standard_normal(600)
    >>> model = gm.LeastSquaresFIR(factor=2, order=15).fit(u, y[::2])
    >>> drawn = plot_residuals(analyze_residuals(model, u, y[::2], max_lag=10))
    >>> len(drawn.axes), len(drawn.cross_correlation_stems)
    (3, 2)
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """
    if not isinstance(analysis, ResidualAnalysis):
        raise ValueError(
            f"analysis must be a ResidualAnalysis (from analyze_residuals); got "
            f"{type(analysis).__name__}"
        )
    n_inputs = analysis.cross_correlation.shape[0]
    if ax is None:
        _, created = plt.subplots(1 + n_inputs, 1, layout="constrained", squeeze=False,
                                  figsize=(6.4, 2.2 * (1 + n_inputs)))
        axes = list(created[:, 0])
    elif isinstance(ax, Sequence) or hasattr(ax, "__array__"):
        axes = [check_axes(a, f"ax[{i}]") for i, a in enumerate(list(ax)[: 1 + n_inputs])]
        if not axes:
            raise ValueError("ax must hold at least one Axes")
    else:
        axes = [check_axes(ax, "ax")]

    lags = analysis.lags[1:]
    auto_stems, auto_band = _stems(axes[0], lags, analysis.autocorrelation[1:],
                                   analysis.autocorrelation_bound[1:], color)
    verdict = "white" if analysis.white else "not white"
    axes[0].set_title(
        f"residual autocorrelation ({verdict}: Ljung-Box p = {analysis.p_value:.3g}; "
        f"{100 * analysis.confidence:g} % band)", fontsize="medium")
    axes[0].set_xlabel("lag [slow samples]")
    stems, bands = [], []
    for j, axis in enumerate(axes[1:]):
        s, b = _stems(axis, analysis.input_lags, analysis.cross_correlation[j],
                      analysis.cross_correlation_bound[j], color)
        stems.append(s)
        bands.append(b)
        axis.set_title(f"cross-correlation with input {j}", fontsize="medium")
        axis.set_xlabel("lag [fast samples] (positive: input before residual)")
    return ResidualPlot(axes=axes, autocorrelation_stems=auto_stems,
                        autocorrelation_band=auto_band, cross_correlation_stems=stems,
                        cross_correlation_bands=bands)
