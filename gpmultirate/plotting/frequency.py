"""Bode plot of a :class:`~gpmultirate.responses.FrequencyResponse` (Fig. 6, 10, 11).

:func:`plot_bode` draws the FRF magnitude and phase with their credible
bands (the projections of the credible ellipse of ``(Re G, Im G)``, see
:class:`~gpmultirate.responses.FrequencyResponse`), hatches the frequencies
where the phase is undefined, and adds the true FRF, the FRF error and the
slow and fast Nyquist frequencies; it draws the data it is given and
computes nothing about the model.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import PolyCollection
from matplotlib.colors import to_rgba
from matplotlib.lines import Line2D

from gpmultirate.plotting.axes import (
    NYQUIST_GID,
    check_axes,
    check_choice,
    draw_band,
    label_marker,
    to_db,
)
from gpmultirate.responses import FrequencyResponse
from gpmultirate.validation import check_positive

__all__ = ["BodePlot", "plot_bode"]

_TRUE_GID = "gpmultirate-true-frf"
_BAND_GID = "gpmultirate-magnitude-band"
_UNDEFINED_GID = "gpmultirate-phase-undefined"
_HATCHES = ("////", "\\\\\\\\", "xxxx", "----")


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
        Shaded credible bands (``None`` with ``show_band=False``); the
        magnitude band has the legend entry ``"<label>, <level> % band"``.
        The phase band leaves out the frequencies where the phase is
        undefined.
    true_magnitude_line, true_phase_line : Line2D or None
        The true FRF, if ``true_frf`` was given.
    error_line : Line2D or None
        ``error_scale * |G0 - G|`` on the magnitude axes, with ``show_error``.
    nyquist_lines : list of Line2D
        Vertical markers at the slow and fast Nyquist frequencies on every
        axes; markers already drawn by an earlier call are reused.
    nyquist_labels : list of Text
        Their labels on the magnitude axes.
    phase_undefined_spans : list of Polygon
        Hatched spans over the whole phase axes, one per stretch of
        frequencies where the credible region contains 0 (the phase is
        undefined); the first has the legend entry
        ``"<label>: phase undefined"``.  Empty without a phase axes.

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import numpy as np
    >>> from gpmultirate.plotting import plot_bode
    >>> from gpmultirate.responses import FrequencyResponse
    >>> frf = FrequencyResponse.from_gaussian(
    ...     np.linspace(0.0, 1.0, 5), np.linspace(1.0, 0.5, 5) + 0j, np.full(5, 1e-3),
    ...     np.full(5, 1e-3), np.zeros(5), sample_time=0.5, factor=2)
    >>> drawn = plot_bode(frf)
    >>> drawn.magnitude_line.get_xdata().tolist()
    [0.0, 0.25, 0.5, 0.75, 1.0]
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
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
    phase_undefined_spans: list | None = None


def _nyquist_markers(axes: list, frf: FrequencyResponse, xscale: str) -> tuple[list, list]:
    """Vertical lines at both Nyquist frequencies, drawn once per axes."""
    lines, labels = [], []
    for ax in axes:
        for which, freq in (("slow", frf.slow_nyquist), ("fast", frf.fast_nyquist)):
            existing = [ln for ln in ax.get_lines() if ln.get_gid() == NYQUIST_GID[which]]
            if existing:
                lines.extend(existing)
                continue
            lines.append(
                ax.axvline(freq, color="0.4", linestyle="-.", linewidth=0.8,
                           gid=NYQUIST_GID[which], label="_nolegend_")
            )
            if ax is axes[0]:
                # the fast Nyquist frequency usually ends the axis, so its label ends at
                # the line; on a log axis the two lines are close, so both labels do
                ha = "right" if which == "fast" or xscale == "log" else "center"
                text = f"{which} Nyquist" + (" " if ha == "right" else "")
                labels.append(label_marker(ax, freq, text, NYQUIST_GID[which], ha=ha))
    return lines, labels


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
    """Bode plot of an identified FRF with its credible bands.

    Draws ``|G|`` of ``frf.mean`` (in dB by default) and its phase in
    degrees, the pointwise credible bands of :class:`FrequencyResponse`
    shaded and outlined (both are projections of the credible ellipse of
    ``(Re G, Im G)``, so they hold the truth wherever the ellipse does),
    optionally the true FRF (dashed black) and the FRF error
    ``error_scale * |G0 - G|`` (dotted, in the estimate's colour; the paper
    uses ``error_scale=0.1``), and vertical markers at the slow and fast
    Nyquist frequencies.

    Where the ellipse contains 0 the magnitude band runs down to the bottom
    of the axes (20 dB below the lowest curve) and the phase is undefined:
    the phase axes are hatched over those frequencies in the estimate's
    colour, with no phase curve and no phase band there.  The legend holds
    the estimate, its band with its level (``"PK, 95 % band"``) and the
    hatching (``"PK: phase undefined"``).  Calling it again with the
    returned axes overlays another estimate in the next colour of the axes'
    cycle and with another hatch.

    Parameters
    ----------
    frf : FrequencyResponse
        From ``model.frequency_response(...)``.
    axes : Axes or pair of Axes, optional
        ``(magnitude, phase)`` axes, or a single magnitude Axes with
        ``phase=False``.  By default a new figure with two stacked axes.
    label : str, optional
        Legend entry of the estimate; ``"estimate"`` by default.
    color : matplotlib colour, optional
        Colour of the estimate and its band; default the next colour of the
        magnitude axes' cycle.
    true_frf : complex array-like of shape (n,), optional
        True FRF at ``frf.freqs``.  Its phase is shifted by a multiple of 360
        degrees onto the estimate's branch at the start of every stretch
        where the estimate's phase is defined (the estimate's phase restarts
        after each stretch where it is not), and the line is broken where
        the shift changes.
    show_band : bool, default=True
        Shade the credible bands (the hatching of an undefined phase is
        drawn either way).
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
        Draw the phase axes (below the magnitude axes of a new figure).
    xscale : {"linear", "log"}, default="linear"
        Frequency axis; the paper uses a linear axis up to the fast Nyquist
        frequency.  With ``"log"`` the zero frequency is left out.
    legend : bool, default=True
        Draw (or redraw) the legend of the magnitude axes, with the labelled
        artists of both axes.

    The frequency axis is labelled in ``frf.frequency_unit`` (Hz, or
    cycles/sample when the sample time is 1).

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
    >>> [t.get_text() for t in bode.axes[0].get_legend().get_texts()][:3]
    ['DC', 'DC, 95 % band', 'true']
    >>> again = plot_bode(frf, axes=bode.axes, label="again")  # overlays
    >>> again.axes == bode.axes
    True
    >>> import matplotlib.pyplot as plt
    >>> plt.close("all")
    """
    if not isinstance(frf, FrequencyResponse):
        raise ValueError(f"frf must be a FrequencyResponse; got {type(frf).__name__}")
    xscale = check_choice(xscale, "xscale", ("linear", "log"))
    error_scale = check_positive(error_scale, "error_scale")
    if label is not None and not isinstance(label, str):
        raise ValueError(f"label must be a string or None; got {type(label).__name__}")
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
        ax_mag, ax_phase = (check_axes(a, "axes") for a in axes)
    else:
        if isinstance(axes, (Sequence, np.ndarray)) and len(axes) >= 1:
            axes = axes[0]
        ax_mag, ax_phase = check_axes(axes, "axes"), None

    keep = freqs > 0 if xscale == "log" else np.ones(freqs.shape, dtype=bool)
    if not np.any(keep):
        raise ValueError("frf must have positive frequencies for xscale='log'")
    f = freqs[keep]
    defined = frf.phase_defined[keep]
    name = "estimate" if label is None else label
    band_label = f"{name}, {100 * frf.level:g} % band"

    def magnitude(values):
        return to_db(values) if db else values

    (mag_line,) = ax_mag.plot(f, magnitude(frf.magnitude[keep]), color=color, label=name)
    color = mag_line.get_color()
    result = BodePlot(axes=(ax_mag, ax_phase), magnitude_line=mag_line,
                      nyquist_lines=[], nyquist_labels=[], phase_undefined_spans=[])
    if show_band:
        upper = magnitude(frf.magnitude_upper[keep])
        floor = band_floor(frf.magnitude[keep], db)
        # a band that reaches 0 (or nearly) stops BAND_DEPTH_DB below the magnitude at
        # that frequency: on a log axis 0 is at minus infinity, and a floor shared by all
        # frequencies drew a comb of spikes down to the bottom of the axes
        low = frf.magnitude_lower[keep]
        clipped = ~(magnitude(np.maximum(low, np.finfo(float).tiny)) > floor)
        lower = np.where(clipped, floor, magnitude(np.maximum(low, np.finfo(float).tiny)))
        result.magnitude_band = draw_band(ax_mag, f, lower, upper, color, label=band_label,
                                          edge=True)
        result.magnitude_band.set_gid(_BAND_GID)
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
        phase_deg = np.degrees(frf.phase)[keep]
        (result.phase_line,) = ax_phase.plot(f, np.where(defined, phase_deg, np.nan),
                                             color=color, label="_nolegend_")
        if show_band:
            result.phase_band = draw_band(
                ax_phase, f, np.degrees(frf.phase_lower[keep]),
                np.degrees(frf.phase_upper[keep]), color, where=defined, edge=True)
        # a different hatch for each estimate overlaid on the axes
        earlier = {a.get_gid() for a in ax_phase.patches
                   if (a.get_gid() or "").startswith(_UNDEFINED_GID)}
        hatch = _HATCHES[len(earlier) % len(_HATCHES)]
        gid = f"{_UNDEFINED_GID}-{len(earlier)}"
        for left, right in _undefined_spans(f, defined, xscale):
            result.phase_undefined_spans.append(ax_phase.axvspan(
                left, right, facecolor="none", edgecolor=to_rgba(color, 0.6), hatch=hatch,
                gid=gid,
                linewidth=0.0, zorder=0.5,
                label="_nolegend_" if result.phase_undefined_spans
                else f"{name}: phase undefined"))
        if true_frf is not None:
            true_deg = np.degrees(np.unwrap(np.angle(true_frf)))[keep]
            x, y = _aligned_true_phase(f, true_deg, phase_deg, defined)
            (result.true_phase_line,) = ax_phase.plot(
                x, y, color="k", linestyle="--", linewidth=1.0, zorder=2.5)

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
    used[-1].set_xlabel(f"frequency [{frf.frequency_unit}]")
    if legend:
        handles, labels = ax_mag.get_legend_handles_labels()
        if ax_phase is not None:
            more, more_labels = ax_phase.get_legend_handles_labels()
            handles, labels = handles + more, labels + more_labels
        if handles:
            ax_mag.legend(handles, labels, fontsize="small", loc="best")
    return result


#: How far below the magnitude a band that reaches 0 is drawn, in dB.
BAND_DEPTH_DB = 20.0


def band_floor(magnitude, db: bool = True) -> np.ndarray:
    """Where a magnitude band that reaches ``|G| = 0`` stops: ``BAND_DEPTH_DB`` below ``|G|``.

    Parameters
    ----------
    magnitude : array-like
        ``|G|`` at each frequency (not in dB).
    db : bool, default=True
        The floor in dB, else as a magnitude.

    Returns
    -------
    ndarray
        The floor at each frequency; where ``|G| = 0`` the lowest floor of
        the others (or -100 dB).

    Examples
    --------
    >>> from gpmultirate.plotting.frequency import band_floor
    >>> band_floor([1.0, 0.1]).tolist()
    [-20.0, -40.0]
    """
    mag = np.asarray(magnitude, dtype=float)
    positive = mag > 0
    with np.errstate(divide="ignore"):
        floor_db = np.where(positive, 20 * np.log10(np.where(positive, mag, 1.0)), np.nan)
    floor_db = floor_db - BAND_DEPTH_DB
    fill = np.nanmin(floor_db) if np.any(positive) else -100.0
    floor_db = np.where(positive, floor_db, fill)
    return floor_db if db else 10 ** (floor_db / 20)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``(start, stop)`` of every run of True in ``mask``."""
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def _undefined_spans(f: np.ndarray, defined: np.ndarray, xscale: str) -> list:
    """Frequency intervals of the runs where the phase is undefined, to mid-bin."""
    def middle(x0, x1):
        return float(np.sqrt(x0 * x1) if xscale == "log" else 0.5 * (x0 + x1))

    spans = []
    for start, stop in _runs(~defined):
        left = f[start] if start == 0 else middle(f[start - 1], f[start])
        right = f[stop - 1] if stop == f.shape[0] else middle(f[stop - 1], f[stop])
        if right <= left:  # a single undefined frequency at an end of the axis
            width = (f[-1] - f[0]) / max(2 * (f.shape[0] - 1), 1) or 0.5
            left, right = (left - width, right) if start else (left, right + width)
        spans.append((float(left), float(right)))
    return spans


def _aligned_true_phase(f, true_deg, phase_deg, defined) -> tuple[np.ndarray, np.ndarray]:
    """The true phase shifted by whole turns to the estimate's branch, per defined run.

    The estimate's phase restarts after every stretch where it is undefined,
    so the true phase is put on the estimate's branch at the start of each
    defined run (and keeps that shift through the undefined stretch after it);
    the line is broken where the shift changes.
    """
    n = f.shape[0]
    shift = np.zeros(n)
    runs = _runs(defined)
    if not runs:
        runs = [(0, n)]
    current = None
    for start, _ in runs:
        k = 360.0 * np.round((phase_deg[start] - true_deg[start]) / 360.0)
        if current is None:
            shift[:start] = k
        shift[start:] = k
        current = k
    y = true_deg + shift
    breaks = np.flatnonzero(np.diff(shift) != 0) + 1
    if breaks.size == 0:
        return f, y
    return (np.insert(np.asarray(f, dtype=float), breaks, np.nan),
            np.insert(y, breaks, np.nan))
