"""Time-domain figures: impulse response, intersample output and Example 1 (Fig. 2).

* :func:`plot_impulse_response` draws an
  :class:`~gpmultirate.responses.ImpulseResponse`: mean, credible band and
  posterior draws against lag.
* :func:`plot_intersample` draws an
  :class:`~gpmultirate.responses.OutputPrediction`: the fast-rate output
  predicted from slow samples, with its band and the slow samples.
* :func:`plot_nonidentifiable_example` draws a
  :class:`~gpmultirate.study.NonidentifiableExample` in four panels.

The first two also accept a fitted model, as before; the data object is then
built by its ``from_model`` constructor, and only drawn here.
"""

from __future__ import annotations

from dataclasses import dataclass

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import PolyCollection
from matplotlib.lines import Line2D

from gpmultirate.plotting.axes import (
    NYQUIST_GID,
    axes_or_new,
    check_axes,
    draw_band,
    label_marker,
    to_db,
)
from gpmultirate.observations.timed import check_sample_times
from gpmultirate.responses import ImpulseResponse, OutputPrediction, normal_quantile
from gpmultirate.study.examples import NonidentifiableExample
from gpmultirate.units import in_fast_periods
from gpmultirate.validation import (
    check_inputs, check_int, check_level, check_positive, check_signal,
)

__all__ = [
    "EXAMPLE_STYLES",
    "ImpulseResponsePlot",
    "IntersamplePlot",
    "plot_impulse_response",
    "plot_intersample",
    "plot_nonidentifiable_example",
]

#: Line styles of the paper's Fig. 2 for theta, theta* and theta'.
EXAMPLE_STYLES = (
    {"color": "tab:green", "linestyle": "-", "label": r"$\theta$"},
    {"color": "tab:red", "linestyle": "--", "label": r"$\theta^*$"},
    {"color": "tab:blue", "linestyle": ":", "label": r"$\theta^\prime$"},
)


def _refuse_model_arguments(kind: str, given: dict) -> None:
    """A data object already fixes what the model-only arguments would choose."""
    named = sorted(name for name, value in given.items() if value is not None)
    if named:
        raise ValueError(
            f"{', '.join(named)} must not be given with an {kind}: they apply only to a "
            f"fitted model (use {kind}.from_model)"
        )


# ---------------------------------------------------------- impulse response
@dataclass
class ImpulseResponsePlot:
    """Axes and artists drawn by :func:`plot_impulse_response`.

    Attributes
    ----------
    ax : Axes
    mean_line : Line2D
        Posterior mean (or least-squares estimate) against lag.
    band : PolyCollection or None
        ``mean +- z std`` for the credible level; ``None`` without a standard deviation.
    sample_lines : list of Line2D
        Posterior draws, one line each (empty without draws).
    true_markers : Line2D or None
        The true coefficients at integer lags, if given.

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import numpy as np
    >>> from gpmultirate.plotting import plot_impulse_response
    >>> from gpmultirate.responses import ImpulseResponse
    >>> drawn = plot_impulse_response(ImpulseResponse(np.arange(3.0), np.ones(3)))
    >>> drawn.band is None, drawn.sample_lines
    (True, [])
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """

    ax: Axes
    mean_line: Line2D
    band: PolyCollection | None
    sample_lines: list
    true_markers: Line2D | None


def plot_impulse_response(
    response,
    lags=None,
    *,
    ax: Axes | None = None,
    level: float | None = None,
    n_samples: int | None = None,
    random_state=None,
    true_response=None,
    label: str | None = None,
    color=None,
) -> ImpulseResponsePlot:
    """Impulse response with its credible band and posterior draws.

    Draws ``response.mean`` against ``response.lags`` (a curve for a model
    over continuous lag, markers at integer lags otherwise), the band
    ``response.lower .. response.upper`` and one thin line per column of
    ``response.samples``.  Given a fitted model instead, the response is
    first built by :meth:`ImpulseResponse.from_model
    <gpmultirate.responses.ImpulseResponse.from_model>` with ``lags``,
    ``level``, ``n_samples`` and ``random_state``.

    Parameters
    ----------
    response : ImpulseResponse or fitted FIRGaussianProcess or LeastSquaresFIR
        What to draw.
    lags : array-like of shape (n,), optional
        Only with a model: lags in fast samples (integers in ``0..P-1`` for
        least squares); by default 4 points per sample over ``0..P-1`` for a
        model over continuous lag, else ``0..P-1``.
    ax : Axes, optional
        Axes to draw on; by default a new figure.
    level : float, default=0.95
        Only with a model: credible level of the band, in (0, 1).
    n_samples : int, default=0
        Only with a model: number of posterior draws to plot as thin lines.
    random_state : int, RandomState or None
        Only with a model: seed of the draws.
    true_response : array-like of shape (n_true,), optional
        True coefficients, drawn as black circles at lags ``0..n_true-1``.
    label : str, optional
        Legend entry of the mean.
    color : matplotlib colour, optional
        Colour of the mean, band and draws.

    Returns
    -------
    ImpulseResponsePlot

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> import gpmultirate as gm
    >>> from gpmultirate.kernels import DC
    >>> from gpmultirate.plotting import plot_impulse_response
    >>> from gpmultirate.responses import ImpulseResponse
    >>> rng = np.random.default_rng(0)
    >>> g = 0.9 ** np.arange(40) * np.cos(0.8 * np.arange(40))
    >>> u = rng.standard_normal(120)
    >>> model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=40, noise_level=1e-4,
    ...                               optimizer=None).fit(u, np.convolve(u, g)[:120:3])
    >>> response = ImpulseResponse.from_model(model, n_samples=3, random_state=0)
    >>> drawn = plot_impulse_response(response, true_response=g)
    >>> drawn.mean_line.get_xdata().shape, len(drawn.sample_lines)
    ((157,), 3)
    >>> again = plot_impulse_response(model, n_samples=3, random_state=0, ax=drawn.ax)
    >>> bool(np.array_equal(again.sample_lines[0].get_ydata(), response.samples[:, 0]))
    True
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """
    if isinstance(response, ImpulseResponse):
        _refuse_model_arguments("ImpulseResponse", {
            "lags": lags, "level": level, "n_samples": n_samples,
            "random_state": random_state})
    else:
        response = ImpulseResponse.from_model(
            response, lags, level=0.95 if level is None else level,
            n_samples=0 if n_samples is None else n_samples, random_state=random_state)
    if true_response is not None:
        true_response = check_signal(true_response, "true_response")

    ax = axes_or_new(ax)
    style = {} if response.continuous else {"marker": ".", "markersize": 4}
    (mean_line,) = ax.plot(response.lags, response.mean, color=color, label=label, zorder=3,
                           **style)
    color = mean_line.get_color()
    band = (None if response.std is None
            else draw_band(ax, response.lags, response.lower, response.upper, color))
    sample_lines = [
        ax.plot(response.lags, response.samples[:, j], color=color, linewidth=0.6, alpha=0.6,
                label="_nolegend_")[0]
        for j in range(response.n_samples)
    ]
    true_markers = None
    if true_response is not None:
        (true_markers,) = ax.plot(
            np.arange(true_response.shape[0]), true_response, linestyle="none", marker="o",
            markersize=3, markerfacecolor="none", markeredgewidth=0.8, color="k",
            label="true", zorder=2.5)
    ax.axhline(0.0, color="0.6", linewidth=0.6, zorder=0)
    ax.set_xlabel("lag [samples]")
    ax.set_ylabel("impulse response")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize="small", loc="upper right")
    return ImpulseResponsePlot(ax=ax, mean_line=mean_line, band=band,
                               sample_lines=sample_lines, true_markers=true_markers)


# ------------------------------------------------------- intersample output
@dataclass
class IntersamplePlot:
    """Axes and artists drawn by :func:`plot_intersample`.

    Attributes
    ----------
    ax : Axes
    mean_line : Line2D
        Predicted fast-rate output.
    band : PolyCollection
        ``mean +- z std`` of the noise-free predicted output.
    fast_line : Line2D or None
        The true fast-rate output, if the prediction has one.
    slow_markers : Line2D or None
        The slow samples at their fast-rate times, if the prediction has them.

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import numpy as np
    >>> from gpmultirate.plotting import plot_intersample
    >>> from gpmultirate.responses import OutputPrediction
    >>> drawn = plot_intersample(OutputPrediction(np.arange(4.0), np.ones(4), np.ones(4)))
    >>> drawn.fast_line is None and drawn.slow_markers is None
    True
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """

    ax: Axes
    mean_line: Line2D
    band: PolyCollection
    fast_line: Line2D | None
    slow_markers: Line2D | None


def plot_intersample(
    prediction,
    u=None,
    *,
    y_fast=None,
    y_slow=None,
    factor: int | None = None,
    offset: int | None = None,
    sample_time: float | None = None,
    ax: Axes | None = None,
    level: float | None = None,
    window=None,
    label: str | None = None,
    color=None,
    sample_times=None,
    between: int | None = None,
) -> IntersamplePlot:
    """Fast-rate output predicted from slow samples, with its credible band.

    Draws ``prediction.mean`` against ``prediction.time`` with the band
    ``prediction.lower .. prediction.upper``, the true fast-rate output
    (dashed black) and the slow samples as circles at their fast-rate times:
    between them lies the intersample behaviour the model reconstructs.
    Given a fitted model and its input ``u`` instead, the prediction is first
    built by :meth:`OutputPrediction.from_model
    <gpmultirate.responses.OutputPrediction.from_model>` with ``y_fast``,
    ``y_slow``, ``factor``, ``offset``, ``sample_time`` and ``level``.

    Parameters
    ----------
    prediction : OutputPrediction or fitted FIRGaussianProcess or LeastSquaresFIR
        What to draw.
    u : array-like of shape (N,) or (N, n_inputs)
        Only with a model: the fast-rate input(s).
    y_fast : array-like of shape (N,), optional
        Only with a model: true fast-rate output.
    y_slow : array-like of shape (M,), optional
        Only with a model: slow samples, ``M = len(range(offset, N, factor))``.
    factor, offset : int, optional
        Only with a model: placement of the slow samples; by default the
        model's (``model.factor``, ``model.offset``).  For slow samples at
        given instants build the prediction with
        ``OutputPrediction.from_model(..., sample_indices=...)``.
    sample_time : float, optional
        Only with a model: fast sample time ``T`` in seconds (the time axis
        is ``n T``); by default the model's ``sample_time``.
    ax : Axes, optional
        Axes to draw on; by default a new figure.
    level : float, default=0.95
        Only with a model: credible level of the band, in (0, 1).
    window : pair of int, optional
        Fast-sample range ``(start, stop)`` to draw, ``0 <= start < stop <= N``.
    label : str, optional
        Legend entry of the prediction.
    color : matplotlib colour, optional
        Colour of the prediction and its band.
    sample_times : array-like of float, optional
        Only with a fitted :class:`~gpmultirate.FIRGaussianProcess`: the
        instant of each slow sample of ``y_slow`` (frames at their own
        instants), in the units of the model's ``sample_time`` as in
        ``fit`` (fast sample periods when it is 1); the samples are drawn there.
    between : int, optional
        Only with a fitted :class:`~gpmultirate.FIRGaussianProcess`: draw
        the band continuously, at ``between`` instants per fast period,
        from ``model.predict(u, sample_times=grid, return_std=True)`` (the
        reading the sensor would report at each instant, with the model's
        exposure and latency; without them, the output itself).  By default
        8 when ``sample_times`` is given or the model was fitted to readings
        at their own instants; otherwise the band is drawn on the fast ticks.

    Returns
    -------
    IntersamplePlot

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> import gpmultirate as gm
    >>> from gpmultirate.kernels import DC
    >>> from gpmultirate.plotting import plot_intersample
    >>> from gpmultirate.responses import OutputPrediction
    >>> rng = np.random.default_rng(0)
    >>> g = 0.9 ** np.arange(40) * np.cos(0.8 * np.arange(40))
    >>> u = rng.standard_normal(120)
    >>> y_fast = np.convolve(u, g)[:120]
    >>> model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=40, noise_level=1e-4,
    ...                               optimizer=None).fit(u, y_fast[::3])
    >>> prediction = OutputPrediction.from_model(model, u, y_fast=y_fast, y_slow=y_fast[::3],
    ...                                          sample_time=0.1)
    >>> drawn = plot_intersample(prediction, window=(30, 60))
    >>> drawn.slow_markers.get_xdata()[:3].round(2)
    array([3. , 3.3, 3.6])
    >>> same = plot_intersample(model, u, y_slow=y_fast[::3], sample_time=0.1, window=(30, 60))
    >>> same.slow_markers.get_xdata()[:3].round(2)
    array([3. , 3.3, 3.6])
    >>> frames = plot_intersample(model, u, y_slow=y_fast[::3], sample_times=np.arange(0, 120, 3),
    ...                           sample_time=0.1, window=(30, 60), between=4)
    >>> frames.mean_line.get_xdata()[:3]
    array([3.   , 3.025, 3.05 ])
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """
    if isinstance(prediction, OutputPrediction):
        _refuse_model_arguments("OutputPrediction", {
            "u": u, "y_fast": y_fast, "y_slow": y_slow, "factor": factor, "offset": offset,
            "sample_time": sample_time, "level": level, "sample_times": sample_times,
            "between": between})
    elif _continuous(prediction, sample_times, between):
        if factor is not None or offset is not None:
            raise ValueError("factor and offset do not apply to a band between the ticks: give "
                             "the instants of the slow samples as sample_times")
        return _plot_between(prediction, u, y_fast, y_slow, sample_times, sample_time, ax,
                             0.95 if level is None else level, window, label, color,
                             8 if between is None else between)
    else:
        if u is None:
            raise ValueError("u must be given with a fitted model: the fast-rate input")
        prediction = OutputPrediction.from_model(
            prediction, u, y_fast=y_fast, y_slow=y_slow, factor=factor, offset=offset,
            sample_time=sample_time,
            level=0.95 if level is None else level)
    if window is not None:
        prediction = prediction.select(window)

    ax = axes_or_new(ax)
    (mean_line,) = ax.plot(prediction.time, prediction.mean, color=color, label=label,
                           zorder=3)
    color = mean_line.get_color()
    band = draw_band(ax, prediction.time, prediction.lower, prediction.upper, color)
    fast_line = slow_markers = None
    if prediction.y_fast is not None:
        (fast_line,) = ax.plot(prediction.time, prediction.y_fast, color="k", linestyle="--",
                               linewidth=1.0, label="true fast-rate output", zorder=2.5)
    if prediction.y_slow is not None:
        slow_markers = _slow_markers(ax, prediction.slow_time, prediction.y_slow,
                                     "slow-rate samples")
    return _finish_intersample(ax, mean_line, band, fast_line, slow_markers)


def _continuous(model, sample_times, between) -> bool:
    """Whether ``plot_intersample`` draws ``model``'s band between the ticks."""
    timed = getattr(getattr(model, "observation_", None), "between_ticks", False)
    if sample_times is None and between is None and not timed:
        return False
    # a FIRGaussianProcess: its posterior and the sensor's exposure
    if not (hasattr(model, "exposure") and hasattr(model, "posterior_")):
        raise ValueError(
            f"sample_times and between need a fitted FIRGaussianProcess (a model between the "
            f"integer lags); got {type(model).__name__}"
        )
    return True


def _plot_between(model, u, y_fast, y_slow, sample_times, sample_time, ax, level, window,
                  label, color, between) -> IntersamplePlot:
    """The band of ``model.predict(u, sample_times=grid)`` on a grid between the ticks."""
    if u is None:
        raise ValueError("u must be given with a fitted model: the fast-rate input")
    n = check_inputs(u, "u").shape[0]
    between = check_int(between, "between", low=1)
    level = check_level(level)
    stamp_unit = getattr(model, "sample_time", None) or 1.0  # the unit of the model's stamps
    if sample_time is None:
        sample_time = stamp_unit
    sample_time = check_positive(sample_time, "sample_time")
    start, stop = 0, n
    if window is not None:
        if not isinstance(window, (tuple, list, np.ndarray)) or len(window) != 2:
            raise ValueError(f"window must be a pair (start, stop); got {window!r}")
        start, stop = (check_int(w, "window", low=0, high=n) for w in window)
        if start >= stop:
            raise ValueError(f"window must satisfy start < stop; got {window!r}")
    if y_slow is not None:
        if sample_times is None:
            raise ValueError("y_slow between the ticks needs sample_times: the instant of "
                             "each slow sample, in the units of the model's sample_time")
        times = check_sample_times(in_fast_periods(sample_times, stamp_unit), n)
        y_slow = np.asarray(y_slow, dtype=float).reshape(-1)
        if y_slow.shape != times.shape:
            raise ValueError(f"y_slow must have one sample per instant of sample_times "
                             f"({times.shape[0]}); got {y_slow.shape[0]}")
    elif sample_times is not None:
        check_sample_times(in_fast_periods(sample_times, stamp_unit), n)
    if y_fast is not None:
        y_fast = check_signal(y_fast, "y_fast")
        if y_fast.shape[0] != n:
            raise ValueError(f"y_fast must have len(u) = {n} samples; got {y_fast.shape[0]}")
    grid = np.arange(start * between, stop * between) / between
    mean, std = model.predict(u, sample_times=grid * stamp_unit, return_std=True)
    z = normal_quantile(level)
    ax = axes_or_new(ax)
    time = grid * sample_time
    (mean_line,) = ax.plot(time, mean, color=color, label=label, zorder=3)
    color = mean_line.get_color()
    band = draw_band(ax, time, mean - z * std, mean + z * std, color)
    fast_line = slow_markers = None
    if y_fast is not None:
        ticks = np.arange(start, stop)
        (fast_line,) = ax.plot(ticks * sample_time, y_fast[start:stop], color="k",
                               linestyle="--", linewidth=1.0, label="true fast-rate output",
                               zorder=2.5)
    if y_slow is not None:
        shown = (times >= start) & (times < stop) & np.isfinite(y_slow)
        slow_markers = _slow_markers(ax, times[shown] * sample_time, y_slow[shown],
                                     "slow samples at their instants")
    return _finish_intersample(ax, mean_line, band, fast_line, slow_markers)


def _slow_markers(ax, times, values, label: str):
    """The slow samples as open circles at their instants (in seconds)."""
    (markers,) = ax.plot(times, values, linestyle="none", marker="o", markersize=5,
                         markerfacecolor="none", markeredgewidth=1.2, color="k", label=label,
                         zorder=4)
    return markers


def _finish_intersample(ax, mean_line, band, fast_line, slow_markers) -> IntersamplePlot:
    """Labels, margins and legend of an intersample plot, and what it drew."""
    ax.set_xlabel("time [s]")
    ax.set_ylabel("output")
    ax.margins(x=0)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize="small", loc="upper right")
    return IntersamplePlot(ax=ax, mean_line=mean_line, band=band, fast_line=fast_line,
                           slow_markers=slow_markers)


# ------------------------------------------------- non-identifiable example
def plot_nonidentifiable_example(
    example: NonidentifiableExample,
    *,
    axes=None,
    sample_time: float = 1.0,
    n_lags: int | None = None,
) -> np.ndarray:
    """Four panels of the paper's Fig. 2 for a :class:`~gpmultirate.study.NonidentifiableExample`.

    Top left: slow-rate output spectrum ``|Y_l|`` up to the slow Nyquist
    frequency; top right: slow-rate outputs in time; both are identical for
    the three models.  Bottom left: the fast-rate FRFs, which differ; bottom
    right: the impulse responses, which coincide only at lags that are
    multiples of the factor (minor grid).  Line styles follow the paper:
    ``theta`` solid green, ``theta*`` dashed red, ``theta'`` dotted blue.

    Parameters
    ----------
    example : NonidentifiableExample
        From :func:`~gpmultirate.study.nonidentifiable_example`.
    axes : array of Axes of shape (2, 2) or 4 Axes, optional
        By default a new 2 x 2 figure.
    sample_time : float, default=1.0
        Fast sample time ``T`` in seconds.
    n_lags : int, optional
        Fast samples shown in the two time-domain panels; default
        ``16 * factor`` (the responses decay well before ``N``).

    Returns
    -------
    ndarray of Axes, shape (2, 2)

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> from gpmultirate.plotting import plot_nonidentifiable_example
    >>> from gpmultirate.study import nonidentifiable_example
    >>> axes = plot_nonidentifiable_example(nonidentifiable_example(200, random_state=0))
    >>> axes.shape, [len(ax.get_lines()) >= 3 for ax in axes.flat]
    ((2, 2), [True, True, True, True])
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """
    if not isinstance(example, NonidentifiableExample):
        raise ValueError(
            f"example must be a NonidentifiableExample; got {type(example).__name__}"
        )
    sample_time = check_positive(sample_time, "sample_time")
    if axes is None:
        _, axes = plt.subplots(2, 2, layout="constrained", figsize=(9.0, 6.0))
    else:
        flat = list(np.asarray(axes, dtype=object).flat)
        if len(flat) != 4:
            raise ValueError(f"axes must hold 4 Axes; got {len(flat)}")
        axes = np.array([check_axes(a, "axes") for a in flat], dtype=object).reshape(2, 2)

    factor = example.factor
    n_samples = example.u.shape[0]
    n_lags = min(16 * factor, n_samples) if n_lags is None else check_int(
        n_lags, "n_lags", low=1, high=n_samples)
    slow_time = factor * sample_time
    slow_nyquist, fast_nyquist = 0.5 / slow_time, 0.5 / sample_time
    slow_outputs = example.slow_outputs
    slow_freqs, slow_spectra = example.slow_spectra(sample_time)
    fast_freqs, frfs = example.frequency_responses(sample_time)
    n_slow = -(-n_lags // factor)
    for j, style in enumerate(EXAMPLE_STYLES):
        axes[0, 0].plot(slow_freqs, to_db(np.abs(slow_spectra[j])), **style)
        axes[0, 1].plot(np.arange(n_slow) * slow_time, slow_outputs[j, :n_slow],
                        marker="ox+"[j], markersize=5 + j, markerfacecolor="none", **style)
        axes[1, 0].plot(fast_freqs, to_db(np.abs(frfs[j])), **style)
        axes[1, 1].plot(np.arange(n_lags), example.models[j, :n_lags], marker=".",
                        markersize=4, **style)

    axes[0, 0].set(xlabel="frequency [Hz]", ylabel=r"$|Y_l|$ [dB]", xlim=(0, slow_nyquist),
                   title="slow-rate output spectrum")
    axes[0, 1].set(xlabel="time [s]", ylabel=r"$y_l$", title="slow-rate output")
    axes[1, 0].set(xlabel="frequency [Hz]", ylabel=r"$|G|$ [dB]", xlim=(0, fast_nyquist),
                   title="fast-rate FRF")
    axes[1, 0].axvline(slow_nyquist, color="0.4", linestyle="-.", linewidth=0.8,
                       gid=NYQUIST_GID["slow"])
    label_marker(axes[1, 0], slow_nyquist, "slow Nyquist", inside=True)
    axes[1, 1].set(xlabel="lag [samples]", ylabel=r"$g$", title="impulse response")
    # slow samples see only every factor-th coefficient: mark those lags
    axes[1, 1].set_xticks(np.arange(0, n_lags, 2 * factor))
    axes[1, 1].set_xticks(np.arange(0, n_lags, factor), minor=True)
    axes[1, 1].grid(True, which="minor", alpha=0.15)
    for ax in axes.flat:
        ax.grid(True, alpha=0.3)
    axes[0, 1].legend(fontsize="small", loc="upper right")
    return axes
