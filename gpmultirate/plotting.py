"""Figures of identified fast-rate FIR models, in the style of the paper.

Every function draws on axes it is given (``ax=`` or, for the Bode plot,
``axes=(magnitude, phase)``), creates a figure only when none is given,
returns the axes and the artists it drew, and never calls ``plt.show()``.
Calling a function again on the same axes overlays, so that several
estimates (least squares, DC kernel, PK kernel) share one figure.

* :func:`plot_bode`: FRF magnitude and phase with credible bands, the true
  FRF, the FRF error and the slow and fast Nyquist frequencies (Fig. 6, 10, 11).
* :func:`plot_impulse_response`: posterior impulse response over continuous
  lag with a band and posterior draws.
* :func:`plot_intersample`: fast-rate (intersample) output predicted from
  slow samples.
* :func:`plot_gof_vs_order`: goodness of fit against model order over Monte
  Carlo runs (Fig. 5, 9).
* :func:`nonidentifiable_example` and :func:`plot_nonidentifiable_example`:
  three fast-rate models with identical slow-rate outputs (Example 1, Fig. 2).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import matplotlib.pyplot as plt
import numpy as np
import scipy.linalg
import scipy.stats
from matplotlib.axes import Axes
from matplotlib.collections import PolyCollection
from matplotlib.lines import Line2D
from matplotlib.text import Text
from sklearn.utils import check_random_state

from gpmultirate.validation import check_int, check_level, check_positive, check_signal
from gpmultirate.frequency import FrequencyResponse
from gpmultirate.operator import DownsampledConvolution

__all__ = [
    "BodePlot",
    "GoFPlot",
    "ImpulseResponsePlot",
    "IntersamplePlot",
    "NonidentifiableExample",
    "nonidentifiable_example",
    "plot_bode",
    "plot_gof_vs_order",
    "plot_impulse_response",
    "plot_intersample",
    "plot_nonidentifiable_example",
]

_BAND_ALPHA = 0.25
_TRUE_GID = "gpmultirate-true-frf"
_NYQUIST_GID = {"slow": "gpmultirate-slow-nyquist", "fast": "gpmultirate-fast-nyquist"}
# Line styles of the paper's Fig. 2 for theta, theta* and theta'.
_EXAMPLE_STYLES = (
    {"color": "tab:green", "linestyle": "-", "label": r"$\theta$"},
    {"color": "tab:red", "linestyle": "--", "label": r"$\theta^*$"},
    {"color": "tab:blue", "linestyle": ":", "label": r"$\theta^\prime$"},
)


# --------------------------------------------------------------- return types
@dataclass
class BodePlot:
    """Axes and artists drawn by :func:`plot_bode`.

    Attributes
    ----------
    axes : tuple of (Axes, Axes or None)
        The magnitude and the phase axes (``None`` with ``phase=False``).
    magnitude_line, phase_line : Line2D
        Magnitude and phase of the posterior-mean FRF (``phase_line`` is
        ``None`` with ``phase=False``).
    magnitude_band, phase_band : PolyCollection or None
        Shaded credible bands (``None`` with ``show_band=False``).
    true_magnitude_line, true_phase_line : Line2D or None
        The true FRF, if ``true_frf`` was given.
    error_line : Line2D or None
        ``error_scale * |G0 - G|`` on the magnitude axes, with ``show_error``.
    nyquist_lines : list of Line2D
        Vertical markers at the slow and fast Nyquist frequencies on every
        axes; markers already drawn by an earlier call are reused.
    nyquist_labels : list of Text
        Their labels on the magnitude axes.
    """

    axes: tuple
    magnitude_line: Line2D
    phase_line: Line2D | None = None
    magnitude_band: PolyCollection | None = None
    phase_band: PolyCollection | None = None
    true_magnitude_line: Line2D | None = None
    true_phase_line: Line2D | None = None
    error_line: Line2D | None = None
    nyquist_lines: list | None = None
    nyquist_labels: list | None = None


@dataclass
class ImpulseResponsePlot:
    """Axes and artists drawn by :func:`plot_impulse_response`.

    Attributes
    ----------
    ax : Axes
    mean_line : Line2D
        Posterior mean (or least-squares estimate) against lag.
    band : PolyCollection or None
        ``mean +- z std`` for the credible level; ``None`` without a covariance.
    sample_lines : list of Line2D
        Posterior draws, one line each (empty with ``n_samples=0``).
    true_markers : Line2D or None
        The true coefficients at integer lags, if given.
    """

    ax: Axes
    mean_line: Line2D
    band: PolyCollection | None
    sample_lines: list
    true_markers: Line2D | None


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
        The true fast-rate output, if ``y_fast`` was given.
    slow_markers : Line2D or None
        The slow samples at their fast-rate times, if ``y_slow`` was given.
    """

    ax: Axes
    mean_line: Line2D
    band: PolyCollection
    fast_line: Line2D | None
    slow_markers: Line2D | None


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
    """

    ax: Axes
    line: Line2D
    band: PolyCollection | None


@dataclass
class NonidentifiableExample:
    """Three fast-rate FIR models with identical slow-rate outputs (Example 1).

    Attributes
    ----------
    u : ndarray of shape (N,)
        The impulsive fast-rate input.
    models : ndarray of shape (3, P)
        Impulse responses ``theta``, ``theta*`` and ``theta'``, ``P = N``.
    y_slow : ndarray of shape (M,)
        The slow-rate output, the same for the three models.
    y_fast : ndarray of shape (3, N)
        The fast-rate outputs, which differ.
    factor : int
        Downsampling factor ``F``.
    """

    u: np.ndarray
    models: np.ndarray
    y_slow: np.ndarray
    y_fast: np.ndarray
    factor: int


# ------------------------------------------------------------------ helpers
def _check_axes(ax, name: str) -> Axes:
    if not isinstance(ax, Axes):
        raise ValueError(f"{name} must be a matplotlib Axes; got {type(ax).__name__}")
    return ax


def _axes_or_new(ax, name: str = "ax") -> Axes:
    if ax is None:
        _, ax = plt.subplots(layout="constrained")
        return ax
    return _check_axes(ax, name)


def _check_choice(value, name: str, choices: tuple) -> str:
    if value not in choices:
        raise ValueError(f"{name} must be one of {choices}; got {value!r}")
    return value


def _db(magnitude: np.ndarray) -> np.ndarray:
    """``20 log10 |.|`` with NaN (a gap in the plot) for zero magnitudes."""
    out = np.full(magnitude.shape, np.nan)
    positive = magnitude > 0
    out[positive] = 20.0 * np.log10(magnitude[positive])
    return out


def _band(ax: Axes, x, lower, upper, color) -> PolyCollection:
    return ax.fill_between(
        x, lower, upper, color=color, alpha=_BAND_ALPHA, linewidth=0, label="_nolegend_"
    )


def _z_value(level: float) -> float:
    """Two-sided standard normal quantile of a credible ``level``."""
    return float(scipy.stats.norm.ppf(0.5 + check_level(level) / 2.0))


def _fitted_coef(model) -> np.ndarray:
    coef = getattr(model, "coef_", None)
    if coef is None:
        raise ValueError(
            f"model must be a fitted FIR estimator with coef_; got {type(model).__name__}"
        )
    return np.asarray(coef, dtype=float)


def _nyquist_markers(axes: list, frf: FrequencyResponse, xscale: str) -> tuple[list, list]:
    """Vertical lines at both Nyquist frequencies, drawn once per axes."""
    lines, labels = [], []
    for ax in axes:
        for which, freq in (("slow", frf.slow_nyquist), ("fast", frf.fast_nyquist)):
            existing = [ln for ln in ax.get_lines() if ln.get_gid() == _NYQUIST_GID[which]]
            if existing:
                lines.extend(existing)
                continue
            lines.append(
                ax.axvline(freq, color="0.4", linestyle="-.", linewidth=0.8,
                           gid=_NYQUIST_GID[which], label="_nolegend_")
            )
            if ax is axes[0]:
                # the fast Nyquist frequency usually ends the axis, so its label ends at
                # the line; on a log axis the two lines are close, so both labels do
                ha = "right" if which == "fast" or xscale == "log" else "center"
                text = f"{which} Nyquist" + (" " if ha == "right" else "")
                labels.append(_nyquist_label(ax, freq, text, _NYQUIST_GID[which], ha=ha))
    return lines, labels


def _nyquist_label(ax: Axes, freq: float, text: str, gid: str | None = None, *,
                   ha: str = "center", inside: bool = False) -> Text:
    """Label of a marker line at ``freq``.

    By default horizontal, just above the axes, clear of the data and the
    legend; ``inside=True`` writes it vertically along the line, near the
    bottom, for axes with a title.
    """
    if inside:
        return ax.annotate(text, xy=(freq, 0.03), xycoords=ax.get_xaxis_transform(),
                           xytext=(-2, 0), textcoords="offset points", rotation=90,
                           ha="right", va="bottom", fontsize="small", color="0.3", gid=gid)
    return ax.annotate(text, xy=(freq, 1.0), xycoords=ax.get_xaxis_transform(),
                       xytext=(0, 2), textcoords="offset points", ha=ha, va="bottom",
                       fontsize="small", color="0.3", gid=gid)


# ---------------------------------------------------------------- Bode plot
def plot_bode(
    frf: FrequencyResponse,
    *,
    axes=None,
    label: str | None = None,
    color=None,
    true_frf=None,
    show_band: bool = True,
    show_error: bool = False,
    error_scale: float = 1.0,
    show_nyquist: bool = True,
    db: bool = True,
    phase: bool = True,
    xscale: str = "linear",
    legend: bool = True,
) -> BodePlot:
    """Bode plot of an identified FRF with its credible band.

    Draws ``|G|`` of ``frf.mean`` (in dB by default) and its unwrapped phase
    in degrees, the pointwise credible bands of :class:`FrequencyResponse`
    shaded, optionally the true FRF (dashed black) and the FRF error
    ``error_scale * |G0 - G|`` (dotted, in the estimate's colour; the paper
    uses ``error_scale=0.1``), and vertical markers at the slow and fast
    Nyquist frequencies.  Calling it again with the returned axes overlays
    another estimate.

    Parameters
    ----------
    frf : FrequencyResponse
        From ``model.frequency_response(...)``.
    axes : Axes or pair of Axes, optional
        ``(magnitude, phase)`` axes, or a single magnitude Axes with
        ``phase=False``.  By default a new figure with two stacked axes.
    label : str, optional
        Legend entry of the estimate.
    color : matplotlib colour, optional
        Colour of the estimate and its band; default the next colour of the
        magnitude axes' cycle.
    true_frf : complex array-like of shape (n,), optional
        True FRF at ``frf.freqs``.  Its phase is shifted by a multiple of 360
        degrees to start on the estimate's branch.
    show_band : bool, default=True
        Shade the credible bands.
    show_error : bool, default=False
        Plot ``error_scale * |true_frf - frf.mean|`` (needs ``true_frf``).
    error_scale : float, default=1.0
        Scale of the error curve.
    show_nyquist : bool, default=True
        Mark the slow Nyquist frequency ``1 / (2 F T)`` and the fast one
        ``1 / (2 T)``.
    db : bool, default=True
        Magnitude in dB on a linear axis; otherwise ``|G|`` on a log axis.
    phase : bool, default=True
        Draw the phase axes.
    xscale : {"linear", "log"}, default="linear"
        Frequency axis; the paper uses a linear axis up to the fast Nyquist
        frequency.  With ``"log"`` the zero frequency is left out.
    legend : bool, default=True
        Draw (or redraw) the legend of the magnitude axes when it has
        labelled artists.

    Returns
    -------
    BodePlot
        The axes and every artist drawn.

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> import gpmultirate as gm
    >>> from gpmultirate.kernels import DC
    >>> from gpmultirate.plotting import plot_bode
    >>> rng = np.random.default_rng(0)
    >>> g = 0.9 ** np.arange(40) * np.cos(0.8 * np.arange(40))
    >>> u = rng.standard_normal(120)
    >>> y_slow = np.convolve(u, g)[:120:3]
    >>> model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=40,
    ...                               noise_level=1e-4, optimizer=None).fit(u, y_slow)
    >>> frf = model.frequency_response(sample_time=0.1)
    >>> true = np.fft.rfft(g, 120)  # FRF of g at the same DFT bins
    >>> bode = plot_bode(frf, label="DC", true_frf=true, show_error=True, error_scale=0.1)
    >>> bode.axes[0].get_ylabel(), len(bode.nyquist_lines)
    ('magnitude [dB]', 4)
    >>> again = plot_bode(frf, axes=bode.axes, label="again")  # overlays
    >>> again.axes == bode.axes
    True
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """
    if not isinstance(frf, FrequencyResponse):
        raise ValueError(f"frf must be a FrequencyResponse; got {type(frf).__name__}")
    xscale = _check_choice(xscale, "xscale", ("linear", "log"))
    error_scale = check_positive(error_scale, "error_scale")
    freqs = frf.freqs
    if true_frf is not None:
        true_frf = np.asarray(true_frf)
        if true_frf.shape != freqs.shape or not np.all(np.isfinite(true_frf)):
            raise ValueError(
                f"true_frf must be a finite array of shape {freqs.shape} (one value per "
                f"frequency of frf); got shape {true_frf.shape}"
            )
        true_frf = true_frf.astype(complex)
    if show_error and true_frf is None:
        raise ValueError("true_frf must be given with show_error=True")

    if axes is None:
        if phase:
            _, (ax_mag, ax_phase) = plt.subplots(
                2, 1, sharex=True, layout="constrained", height_ratios=(3, 2),
                figsize=(6.4, 5.6),
            )
        else:
            _, ax_mag = plt.subplots(layout="constrained")
            ax_phase = None
    elif phase:
        if isinstance(axes, Axes) or not isinstance(axes, (Sequence, np.ndarray)) \
                or len(axes) != 2:
            raise ValueError("axes must be a pair (magnitude Axes, phase Axes) with phase=True")
        ax_mag, ax_phase = (_check_axes(a, "axes") for a in axes)
    else:
        if isinstance(axes, (Sequence, np.ndarray)) and len(axes) >= 1:
            axes = axes[0]
        ax_mag, ax_phase = _check_axes(axes, "axes"), None

    keep = freqs > 0 if xscale == "log" else np.ones(freqs.shape, dtype=bool)
    if not np.any(keep):
        raise ValueError("frf must have positive frequencies for xscale='log'")
    f = freqs[keep]

    def magnitude(values):
        return _db(values) if db else values

    (mag_line,) = ax_mag.plot(f, magnitude(frf.magnitude[keep]), color=color, label=label)
    color = mag_line.get_color()
    result = BodePlot(axes=(ax_mag, ax_phase), magnitude_line=mag_line,
                      nyquist_lines=[], nyquist_labels=[])
    if show_band:
        result.magnitude_band = _band(ax_mag, f, magnitude(frf.magnitude_lower[keep]),
                                      magnitude(frf.magnitude_upper[keep]), color)
    if true_frf is not None:
        already = any(ln.get_gid() == _TRUE_GID for ln in ax_mag.get_lines())
        (result.true_magnitude_line,) = ax_mag.plot(
            f, magnitude(np.abs(true_frf[keep])), color="k", linestyle="--", linewidth=1.0,
            label="_nolegend_" if already else "true", gid=_TRUE_GID, zorder=2.5)
    if show_error:
        error_label = ("" if error_scale == 1 else f"{error_scale:g}") + r"$|G_0 - G|$"
        (result.error_line,) = ax_mag.plot(
            f, magnitude(error_scale * np.abs(true_frf - frf.mean)[keep]), color=color,
            linestyle=":", label=error_label if label is None else f"{label}: {error_label}")

    if ax_phase is not None:
        phase_deg = np.degrees(frf.phase)
        (result.phase_line,) = ax_phase.plot(f, phase_deg[keep], color=color, label=label)
        if show_band:
            result.phase_band = _band(ax_phase, f, np.degrees(frf.phase_lower[keep]),
                                      np.degrees(frf.phase_upper[keep]), color)
        if true_frf is not None:
            true_deg = np.degrees(np.unwrap(np.angle(true_frf)))
            true_deg += 360.0 * np.round((phase_deg[0] - true_deg[0]) / 360.0)
            (result.true_phase_line,) = ax_phase.plot(
                f, true_deg[keep], color="k", linestyle="--", linewidth=1.0, zorder=2.5)

    used = [a for a in (ax_mag, ax_phase) if a is not None]
    if show_nyquist:
        result.nyquist_lines, result.nyquist_labels = _nyquist_markers(used, frf, xscale)
    for ax in used:
        ax.set_xscale(xscale)
        ax.margins(x=0)
        ax.grid(True, which="major", alpha=0.3)
    ax_mag.set_yscale("linear" if db else "log")
    ax_mag.set_ylabel("magnitude [dB]" if db else "magnitude")
    if ax_phase is not None:
        ax_phase.set_ylabel("phase [deg]")
    used[-1].set_xlabel("frequency [Hz]")
    if legend and ax_mag.get_legend_handles_labels()[0]:
        ax_mag.legend(fontsize="small", loc="best")
    return result


# ---------------------------------------------------------- impulse response
def plot_impulse_response(
    model,
    lags=None,
    *,
    ax: Axes | None = None,
    level: float = 0.95,
    n_samples: int = 0,
    random_state=None,
    true_response=None,
    label: str | None = None,
    color=None,
) -> ImpulseResponsePlot:
    """Posterior impulse response over continuous lag with a credible band.

    For a :class:`~gpmultirate.FIRGaussianProcess` the posterior mean and
    standard deviation of ``g(t)`` come from ``model.impulse_response(lags,
    return_std=True)`` at real lags (by default 4 points per sample over
    ``0..P-1``), the band is ``mean +- z std`` with ``z`` the two-sided
    normal quantile of ``level``, and ``n_samples`` posterior draws come from
    ``model.sample_impulse_responses``.  For a model without
    ``impulse_response`` (:class:`~gpmultirate.LeastSquaresFIR`) ``coef_`` is
    drawn at integer lags with markers, and the band and draws use
    ``coef_covariance_`` when the model has one.

    Parameters
    ----------
    model : fitted FIRGaussianProcess or LeastSquaresFIR
    lags : array-like of shape (n,), optional
        Lags in fast samples; integers in ``0..P-1`` for models without
        ``impulse_response``.
    ax : Axes, optional
        Axes to draw on; by default a new figure.
    level : float, default=0.95
        Credible level of the band, in (0, 1).
    n_samples : int, default=0
        Number of posterior draws to plot as thin lines.
    random_state : int, RandomState or None
        Seed of the draws.
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
    >>> rng = np.random.default_rng(0)
    >>> g = 0.9 ** np.arange(40) * np.cos(0.8 * np.arange(40))
    >>> u = rng.standard_normal(120)
    >>> model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=40, noise_level=1e-4,
    ...                               optimizer=None).fit(u, np.convolve(u, g)[:120:3])
    >>> drawn = plot_impulse_response(model, n_samples=3, random_state=0, true_response=g)
    >>> drawn.mean_line.get_xdata().shape, len(drawn.sample_lines)
    ((157,), 3)
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """
    coef = _fitted_coef(model)
    order = coef.shape[0]
    z = _z_value(level)
    n_samples = check_int(n_samples, "n_samples", low=0)
    if true_response is not None:
        true_response = check_signal(true_response, "true_response")
    continuous = callable(getattr(model, "impulse_response", None))

    if continuous:
        if lags is None:
            lags = np.linspace(0.0, order - 1.0, 4 * (order - 1) + 1)
        mean, std = model.impulse_response(lags, return_std=True)
        lags = np.asarray(lags, dtype=float).reshape(-1)
        draws = (model.sample_impulse_responses(lags, n_samples=n_samples,
                                                random_state=random_state)
                 if n_samples else np.empty((lags.shape[0], 0)))
    else:
        if lags is None:
            index = np.arange(order)
        else:
            lags = check_signal(lags, "lags")
            index = np.round(lags).astype(int)
            if np.any(np.abs(lags - index) > 1e-9) or np.any(index < 0) or np.any(index >= order):
                raise ValueError(
                    f"lags must be integers in 0..{order - 1} for a model without "
                    "impulse_response (a least-squares FIR model)"
                )
        lags, mean = index.astype(float), coef[index]
        covariance = getattr(model, "coef_covariance_", None)
        std, draws = None, np.empty((lags.shape[0], 0))
        if covariance is not None:
            covariance = np.asarray(covariance, dtype=float)[np.ix_(index, index)]
            std = np.sqrt(np.maximum(np.diag(covariance), 0.0))
            if n_samples:
                values, vectors = scipy.linalg.eigh(covariance)
                root = vectors * np.sqrt(np.maximum(values, 0.0))
                noise = check_random_state(random_state).standard_normal((lags.shape[0],
                                                                         n_samples))
                draws = mean[:, None] + root @ noise
        elif n_samples:
            raise ValueError("n_samples must be 0 for a model without a coefficient covariance")

    ax = _axes_or_new(ax)
    style = {} if continuous else {"marker": ".", "markersize": 4}
    (mean_line,) = ax.plot(lags, mean, color=color, label=label, zorder=3, **style)
    color = mean_line.get_color()
    band = None if std is None else _band(ax, lags, mean - z * std, mean + z * std, color)
    sample_lines = [
        ax.plot(lags, draws[:, j], color=color, linewidth=0.6, alpha=0.6,
                label="_nolegend_")[0]
        for j in range(draws.shape[1])
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
def plot_intersample(
    model,
    u,
    *,
    y_fast=None,
    y_slow=None,
    factor: int | None = None,
    offset: int | None = None,
    sample_time: float = 1.0,
    ax: Axes | None = None,
    level: float = 0.95,
    window=None,
    label: str | None = None,
    color=None,
) -> IntersamplePlot:
    """Fast-rate output predicted from slow samples, with its credible band.

    Draws ``model.predict(u, return_std=True)`` (the noise-free fast-rate
    output and its posterior standard deviation) with the band ``mean +- z
    std``, the true fast-rate output ``y_fast`` (dashed black) and the slow
    samples ``y_slow`` as circles at their fast-rate times ``(offset + m
    factor) T``: between them lies the intersample behaviour the model
    reconstructs.

    Parameters
    ----------
    model : fitted FIRGaussianProcess or LeastSquaresFIR
    u : array-like of shape (N,)
        Fast-rate input.
    y_fast : array-like of shape (N,), optional
        True fast-rate output.
    y_slow : array-like of shape (M,), optional
        Slow samples, ``M = len(range(offset, N, factor))``.
    factor, offset : int, optional
        Placement of the slow samples; by default the model's
        (``model.operator_``), else ``1`` and ``0``.
    sample_time : float, default=1.0
        Fast sample time ``T`` in seconds (the time axis is ``n T``).
    ax : Axes, optional
        Axes to draw on; by default a new figure.
    level : float, default=0.95
        Credible level of the band, in (0, 1).
    window : pair of int, optional
        Fast-sample range ``(start, stop)`` to draw, ``0 <= start < stop <= N``.
    label : str, optional
        Legend entry of the prediction.
    color : matplotlib colour, optional
        Colour of the prediction and its band.

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
    >>> rng = np.random.default_rng(0)
    >>> g = 0.9 ** np.arange(40) * np.cos(0.8 * np.arange(40))
    >>> u = rng.standard_normal(120)
    >>> y_fast = np.convolve(u, g)[:120]
    >>> model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=40, noise_level=1e-4,
    ...                               optimizer=None).fit(u, y_fast[::3])
    >>> drawn = plot_intersample(model, u, y_fast=y_fast, y_slow=y_fast[::3],
    ...                          sample_time=0.1, window=(30, 60))
    >>> drawn.slow_markers.get_xdata()[:3].round(2)
    array([3. , 3.3, 3.6])
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """
    _fitted_coef(model)
    u = check_signal(u, "u")
    n = u.shape[0]
    operator = getattr(model, "operator_", None)
    if factor is None:
        factor = operator.factor if operator is not None else 1
    if offset is None:
        offset = operator.offset if operator is not None else 0
    factor = check_int(factor, "factor", low=1)
    offset = check_int(offset, "offset", low=0, high=factor - 1)
    sample_time = check_positive(sample_time, "sample_time")
    z = _z_value(level)
    if y_fast is not None:
        y_fast = check_signal(y_fast, "y_fast")
        if y_fast.shape[0] != n:
            raise ValueError(f"y_fast must have len(u) = {n} samples; got {y_fast.shape[0]}")
    slow_index = np.arange(offset, n, factor)
    if y_slow is not None:
        y_slow = check_signal(y_slow, "y_slow")
        if y_slow.shape[0] != slow_index.shape[0]:
            raise ValueError(
                f"y_slow must have len(range(offset, len(u), factor)) = {slow_index.shape[0]} "
                f"samples; got {y_slow.shape[0]}"
            )
    if window is None:
        start, stop = 0, n
    else:
        if not isinstance(window, (Sequence, np.ndarray)) or len(window) != 2:
            raise ValueError(f"window must be a pair (start, stop); got {window!r}")
        start, stop = (check_int(w, "window", low=0, high=n) for w in window)
        if start >= stop:
            raise ValueError(f"window must satisfy start < stop; got {window!r}")

    mean, std = model.predict(u, return_std=True)
    fast = slice(start, stop)
    time = np.arange(n) * sample_time
    ax = _axes_or_new(ax)
    (mean_line,) = ax.plot(time[fast], mean[fast], color=color, label=label, zorder=3)
    color = mean_line.get_color()
    band = _band(ax, time[fast], (mean - z * std)[fast], (mean + z * std)[fast], color)
    fast_line = slow_markers = None
    if y_fast is not None:
        (fast_line,) = ax.plot(time[fast], y_fast[fast], color="k", linestyle="--",
                               linewidth=1.0, label="true fast-rate output", zorder=2.5)
    if y_slow is not None:
        shown = (slow_index >= start) & (slow_index < stop)
        (slow_markers,) = ax.plot(
            time[slow_index[shown]], y_slow[shown], linestyle="none", marker="o",
            markersize=5, markerfacecolor="none", markeredgewidth=1.2, color="k",
            label="slow-rate samples", zorder=4)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("output")
    ax.margins(x=0)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize="small", loc="upper right")
    return IntersamplePlot(ax=ax, mean_line=mean_line, band=band, fast_line=fast_line,
                           slow_markers=slow_markers)


# ------------------------------------------------------------ GoF vs order
def plot_gof_vs_order(
    orders,
    gof,
    *,
    ax: Axes | None = None,
    label: str | None = None,
    color=None,
    marker: str | None = None,
    identifiable=None,
    n_std: float = 2.0,
) -> GoFPlot:
    """Mean goodness of fit against model order, with a ``+- n_std`` std band.

    Over the Monte Carlo runs (rows of ``gof``) the mean and the sample
    standard deviation are taken per order, ignoring NaN entries (runs where
    the model was not computed), as in the paper's Fig. 5.  Orders where no
    run has a value, or where ``identifiable`` is False (least squares with
    ``P >= M``), are left out of the line and the band.

    Parameters
    ----------
    orders : array-like of shape (n_orders,)
        Model orders ``P``.
    gof : array-like of shape (n_runs, n_orders) or (n_orders,)
        Goodness of fit in percent (eq. 20), NaN where not computed.
    ax : Axes, optional
        Axes to draw on; by default a new figure.
    label, color, marker : optional
        Legend entry, colour and marker of the mean line.
    identifiable : bool array-like of shape (n_orders,) or gof's shape, optional
        Where the estimate exists; entries marked False are treated as NaN.
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
    >>> orders = np.array([10, 50, 100, 200])
    >>> gof = np.array([[90.0, 95.0, 93.0, np.nan], [92.0, 97.0, 91.0, np.nan]])
    >>> drawn = plot_gof_vs_order(orders, gof, label="LS", marker="o",
    ...                           identifiable=orders < 150)
    >>> drawn.line.get_ydata()
    array([91., 96., 92., nan])
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """
    orders = check_signal(orders, "orders")
    try:
        gof = np.array(gof, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError("gof must be an array of goodness-of-fit values") from exc
    if gof.ndim == 1:
        gof = gof[None, :]
    if gof.ndim != 2 or gof.shape[1] != orders.shape[0]:
        raise ValueError(
            f"gof must have shape (n_runs, {orders.shape[0]}) or ({orders.shape[0]},) to match "
            f"orders; got shape {np.shape(gof)}"
        )
    if np.any(np.isinf(gof)):
        raise ValueError("gof must not contain inf (use NaN for missing values)")
    n_std = check_positive(n_std, "n_std")
    if identifiable is not None:
        mask = np.asarray(identifiable)
        if mask.dtype != bool:
            raise ValueError(f"identifiable must be a boolean array; got dtype {mask.dtype}")
        if mask.shape not in (orders.shape, gof.shape):
            raise ValueError(
                f"identifiable must have shape {orders.shape} or {gof.shape}; got {mask.shape}"
            )
        gof = np.where(mask, gof, np.nan)

    # nan-aware mean and sample std, written out to avoid warnings on empty columns
    finite = np.isfinite(gof)
    count = finite.sum(axis=0)
    total = np.where(finite, gof, 0.0).sum(axis=0)
    mean = np.full(count.shape, np.nan)
    mean[count > 0] = total[count > 0] / count[count > 0]
    deviation = np.where(finite, gof - mean, 0.0)
    std = np.full(count.shape, np.nan)
    several = count > 1
    std[several] = np.sqrt((deviation[:, several] ** 2).sum(axis=0) / (count[several] - 1))

    ax = _axes_or_new(ax)
    (line,) = ax.plot(orders, mean, color=color, marker=marker, markersize=4, label=label)
    band = None
    if gof.shape[0] > 1:
        shown = np.isfinite(std)
        band = ax.fill_between(
            orders, np.where(shown, mean - n_std * std, np.nan),
            np.where(shown, mean + n_std * std, np.nan), color=line.get_color(),
            alpha=_BAND_ALPHA, linewidth=0, label="_nolegend_")
    ax.set_xlabel("model order P")
    ax.set_ylabel("GoF [%]")
    ax.grid(True, alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize="small", loc="lower right")
    return GoFPlot(ax=ax, line=line, band=band)


# ------------------------------------------------- non-identifiable example
def nonidentifiable_example(
    n_samples: int = 1000, factor: int = 4, random_state=None
) -> NonidentifiableExample:
    """Three FIR models with identical slow-rate outputs (the paper's Example 1).

    The input is an impulse at ``n = 0`` of ``N = n_samples`` fast samples and
    the order is ``P = N``, so the regressor ``Phi`` (eq. 8) of the
    ``M = ceil(N / F)`` slow samples has a null space of dimension ``P - M``.
    ``theta`` is a decaying oscillation below the slow Nyquist frequency;
    ``theta*`` and ``theta'`` add to it the orthogonal projection onto that
    null space (:func:`scipy.linalg.null_space`) of a decaying oscillation at
    a random frequency between the slow and the fast Nyquist frequency.  The
    three slow outputs ``Phi theta`` are equal, the fast-rate models are not.

    Parameters
    ----------
    n_samples : int, default=1000
        ``N = P``; at least ``2 * factor``.
    factor : int, default=4
        Downsampling factor ``F >= 2``.
    random_state : int, RandomState or None
        Seed of the added oscillations.

    Returns
    -------
    NonidentifiableExample

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.plotting import nonidentifiable_example
    >>> example = nonidentifiable_example(200, factor=4, random_state=0)
    >>> example.models.shape, example.y_slow.shape
    ((3, 200), (50,))
    >>> bool(np.allclose(example.y_fast[1, ::4], example.y_fast[0, ::4]))
    True
    """
    factor = check_int(factor, "factor", low=2)
    n_samples = check_int(n_samples, "n_samples", low=2 * factor)
    rng = check_random_state(random_state)
    u = np.zeros(n_samples)
    u[0] = 1.0
    operator = DownsampledConvolution(u, factor, n_samples)
    null = scipy.linalg.null_space(operator.matrix)

    lags = np.arange(n_samples)
    decay = np.exp(-lags / (n_samples / 20.0))
    slow_nyquist, fast_nyquist = 0.5 / factor, 0.5  # cycles per fast sample
    base = decay * np.sin(2 * np.pi * 0.5 * slow_nyquist * lags)
    models = [base]
    for _ in range(2):
        frequency = rng.uniform(1.2 * slow_nyquist, 0.9 * fast_nyquist)
        phase = rng.uniform(0.0, 2 * np.pi)
        extra = 0.5 * decay * np.cos(2 * np.pi * frequency * lags + phase)
        models.append(base + null @ (null.T @ extra))
    models = np.array(models)
    y_fast = np.array([np.convolve(u, model)[:n_samples] for model in models])
    return NonidentifiableExample(u=u, models=models, y_slow=operator.matvec(models[0]),
                                  y_fast=y_fast, factor=factor)


def plot_nonidentifiable_example(
    example: NonidentifiableExample,
    *,
    axes=None,
    sample_time: float = 1.0,
    n_lags: int | None = None,
) -> np.ndarray:
    """Four panels of the paper's Fig. 2 for :func:`nonidentifiable_example`.

    Top left: slow-rate output spectrum ``|Y_l|`` up to the slow Nyquist
    frequency; top right: slow-rate outputs in time; both are identical for
    the three models.  Bottom left: the fast-rate FRFs, which differ; bottom
    right: the impulse responses, which coincide only at lags that are
    multiples of the factor (minor grid).  Line styles follow the paper:
    ``theta`` solid green, ``theta*`` dashed red, ``theta'`` dotted blue.

    Parameters
    ----------
    example : NonidentifiableExample
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
    >>> from gpmultirate.plotting import nonidentifiable_example, plot_nonidentifiable_example
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
        axes = np.array([_check_axes(a, "axes") for a in flat], dtype=object).reshape(2, 2)

    factor = example.factor
    n_samples = example.u.shape[0]
    n_lags = min(16 * factor, n_samples) if n_lags is None else check_int(
        n_lags, "n_lags", low=1, high=n_samples)
    slow_time = factor * sample_time
    slow_nyquist, fast_nyquist = 0.5 / slow_time, 0.5 / sample_time
    slow_outputs = example.y_fast[:, ::factor]
    slow_freqs = np.fft.rfftfreq(slow_outputs.shape[1], d=slow_time)
    fast_freqs = np.fft.rfftfreq(n_samples, d=sample_time)
    n_slow = -(-n_lags // factor)
    for j, style in enumerate(_EXAMPLE_STYLES):
        axes[0, 0].plot(slow_freqs, _db(np.abs(np.fft.rfft(slow_outputs[j]))), **style)
        axes[0, 1].plot(np.arange(n_slow) * slow_time, slow_outputs[j, :n_slow],
                        marker="ox+"[j], markersize=5 + j, markerfacecolor="none", **style)
        # the DFT of the coefficients is the FRF at the bins k / (N T)
        axes[1, 0].plot(fast_freqs, _db(np.abs(np.fft.rfft(example.models[j]))), **style)
        axes[1, 1].plot(np.arange(n_lags), example.models[j, :n_lags], marker=".",
                        markersize=4, **style)

    axes[0, 0].set(xlabel="frequency [Hz]", ylabel=r"$|Y_l|$ [dB]", xlim=(0, slow_nyquist),
                   title="slow-rate output spectrum")
    axes[0, 1].set(xlabel="time [s]", ylabel=r"$y_l$", title="slow-rate output")
    axes[1, 0].set(xlabel="frequency [Hz]", ylabel=r"$|G|$ [dB]", xlim=(0, fast_nyquist),
                   title="fast-rate FRF")
    axes[1, 0].axvline(slow_nyquist, color="0.4", linestyle="-.", linewidth=0.8,
                       gid=_NYQUIST_GID["slow"])
    _nyquist_label(axes[1, 0], slow_nyquist, "slow Nyquist", inside=True)
    axes[1, 1].set(xlabel="lag [samples]", ylabel=r"$g$", title="impulse response")
    # slow samples see only every factor-th coefficient: mark those lags
    axes[1, 1].set_xticks(np.arange(0, n_lags, 2 * factor))
    axes[1, 1].set_xticks(np.arange(0, n_lags, factor), minor=True)
    axes[1, 1].grid(True, which="minor", alpha=0.15)
    for ax in axes.flat:
        ax.grid(True, alpha=0.3)
    axes[0, 1].legend(fontsize="small", loc="upper right")
    return axes


# ------------------------------------------------------- Monte Carlo study
# Colours and markers of the paper's Fig. 5: LS red circles, DC blue squares, PK green triangles.
_STUDY_STYLES = {
    "LS": {"color": "tab:red", "marker": "o"},
    "DC": {"color": "tab:blue", "marker": "s"},
    "PK": {"color": "tab:green", "marker": "^"},
}
_SLOW_SAMPLES_GID = "gpmultirate-slow-samples"


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
    """

    ax: Axes
    plots: dict
    slow_samples_line: Line2D | None
    errorbars: dict


def plot_study(result, *, ax: Axes | None = None, methods=None, n_std: float = 2) -> StudyPlot:
    """Goodness of fit against model order for every method of a study (Fig. 5).

    For each method, :func:`plot_gof_vs_order` draws the mean over the runs
    and a band of ``+- n_std`` sample standard deviations, leaving out the
    orders where the model is not identifiable; a vertical line marks
    ``P = M``.  Orders whose neighbours have no value get error bars,
    since a band needs two orders to have a width.  The lower y-limit keeps
    the means in view without letting a very wide band squash them.

    Parameters
    ----------
    result : StudyResult
        From :func:`gpmultirate.experiments.run_paper_study` (any object with
        ``orders``, ``methods``, ``gof``, ``identifiable`` and
        ``n_slow_samples``).
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
    >>> from gpmultirate.experiments import run_paper_study
    >>> from gpmultirate.plotting import plot_study
    >>> result = run_paper_study(n_runs=2, orders=(5, 10, 20), methods=("LS",),
    ...                          n_samples=60, progress=False)
    >>> drawn = plot_study(result)
    >>> sorted(drawn.plots), float(drawn.slow_samples_line.get_xdata()[0])
    (['LS'], 20.0)
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """
    for name in ("orders", "methods", "gof", "identifiable"):
        if not hasattr(result, name):
            raise ValueError(
                f"result must be a StudyResult (no attribute {name!r}); "
                f"got {type(result).__name__}"
            )
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
    ax = _axes_or_new(ax)
    previous_ylim = ax.get_ylim() if ax.has_data() else None  # overlaying: only widen
    orders = np.asarray(result.orders)
    plots, errorbars = {}, {}
    for method in methods:
        style = _STUDY_STYLES.get(method, {})
        drawn = plot_gof_vs_order(
            orders, result.gof[method], ax=ax, label=method,
            identifiable=np.asarray(result.identifiable[method], dtype=bool), n_std=n_std,
            **style)
        plots[method] = drawn
        mean = np.asarray(drawn.line.get_ydata(), dtype=float)
        shown = np.isfinite(mean)
        neighbours = np.zeros_like(shown)
        neighbours[1:] |= shown[:-1]
        neighbours[:-1] |= shown[1:]
        isolated = shown & ~neighbours
        if np.any(isolated) and drawn.band is not None:
            gof = np.where(np.asarray(result.identifiable[method], dtype=bool),
                           np.asarray(result.gof[method], dtype=float), np.nan)[:, isolated]
            std = np.array([np.std(c[np.isfinite(c)], ddof=1) if np.isfinite(c).sum() > 1
                            else 0.0 for c in gof.T])
            errorbars[method] = ax.errorbar(
                orders[isolated], mean[isolated], yerr=n_std * std, fmt="none",
                ecolor=drawn.line.get_color(), elinewidth=1.0, capsize=4, label="_nolegend_")

    slow_line = None
    n_slow = getattr(result, "n_slow_samples", None)
    already = any(ln.get_gid() == _SLOW_SAMPLES_GID for ln in ax.get_lines())
    if n_slow is not None and not already and orders.min() <= n_slow <= orders.max():
        slow_line = ax.axvline(n_slow, color="0.4", linestyle="-.", linewidth=0.8,
                               gid=_SLOW_SAMPLES_GID, label="_nolegend_")
        _nyquist_label(ax, n_slow, f"P = M = {n_slow}", _SLOW_SAMPLES_GID, inside=True)

    means = np.concatenate([p.line.get_ydata() for p in plots.values()]).astype(float)
    means = means[np.isfinite(means)]
    if means.size:
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
    return StudyPlot(ax=ax, plots=plots, slow_samples_line=slow_line, errorbars=errorbars)


__all__ += ["StudyPlot", "plot_study"]
