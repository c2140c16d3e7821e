"""The figures of a fit and of a study, as the ``gpmultirate`` command draws them.

:func:`fit_figures` draws a fitted model's Bode plot, impulse response and
intersample output (``bode.png``, ``impulse.png`` and ``intersample.png`` of
``gpmultirate fit``); :func:`study_figure` the goodness of fit against the
order over a study's runs and :func:`example_figures` one run's models (the figures of
``gpmultirate demo``).  The figures are bare :class:`matplotlib.figure.Figure`
objects rendered by the Agg canvas: they never touch pyplot's state or open
a window.  Save one with ``figure.savefig(path)``.
"""

from __future__ import annotations

import numpy as np

from gpmultirate.plotting.frequency import plot_bode
from gpmultirate.plotting.overview import plot_overview
from gpmultirate.plotting.study import plot_study
from gpmultirate.plotting.time import plot_impulse_response, plot_intersample
from gpmultirate.responses import ImpulseResponse, OutputPrediction

__all__ = ["bode_xscale", "example_figures", "fit_figures", "nonidentifiable_figure",
           "study_figure"]

#: the most frequencies of the Bode figure (beyond it a log-spaced grid, not the DFT bins)
BODE_FREQUENCIES = 2048
#: the most lags of the impulse-response figure (4 per sample on short responses)
IMPULSE_POINTS = 2049

_STYLES = {"LS": "tab:red", "DC": "tab:blue", "PK": "tab:green"}
_DESCRIPTIONS = {"LS": "least squares", "DC": "DC kernel", "PK": "prior-knowledge kernel"}


def _figure(**kwargs):
    # A bare Figure renders with the Agg canvas and never touches pyplot's state.
    from matplotlib.figure import Figure

    return Figure(layout="constrained", **kwargs)


def bode_xscale(freqs) -> str:
    """The frequency axis of a Bode figure: ``"log"`` when the positive frequencies span
    more than two decades, else ``"linear"``.

    Examples
    --------
    >>> bode_xscale([0.0, 0.001, 0.5]), bode_xscale([0.0, 0.01, 0.5])
    ('log', 'linear')
    """
    f = np.asarray(freqs, dtype=float)
    f = f[f > 0]
    return "log" if f.size > 1 and f.max() / f.min() > 100 else "linear"


def fit_figures(model, u, samples=None, inputs=None, *, xscale: str = "auto") -> dict:
    """The figures of a fitted model with their 95 % credible bands.

    Parameters
    ----------
    model : FIRGaussianProcess
        A fitted estimator.
    u : array-like of shape (n_samples,) or (n_samples, n_inputs)
        The input it was fitted to.
    samples : SlowSamples, optional
        The slow samples it was fitted to
        (:func:`gpmultirate.io.read_slow_samples`); by default read from the
        model.
    inputs : sequence of str, optional
        Names of the inputs, for the titles; default ``u0, u1, ...``.
    xscale : {"auto", "linear", "log"}, default="auto"
        The frequency axis of ``bode.png``; ``auto`` is :func:`bode_xscale`.

    Returns
    -------
    dict of str to matplotlib.figure.Figure
        ``bode.png``: magnitude and phase per input, at the DFT bins of
        the record (``BODE_FREQUENCIES`` log-spaced frequencies from the
        first bin to the Nyquist frequency on a longer record);
        ``impulse.png``: the impulse response per input at four lags per
        sample (fewer where that would exceed ``IMPULSE_POINTS``; at the
        integer lags only where the curve between them falls back towards
        0, a prior with little correlation between lags) over the
        first ``max(60, N / 4)`` lags; ``intersample.png``: the fast-rate output
        predicted from the slow samples over the record
        (:func:`~gpmultirate.plotting.overview.plot_overview`: binned beyond
        ``OVERVIEW_POINTS`` samples) and over 20 slow periods in its middle.

    Examples
    --------
    >>> import numpy as np
    >>> import gpmultirate as gm
    >>> from gpmultirate.plotting.report import fit_figures
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(60)
    >>> g = 0.8 ** np.arange(15) * np.cos(0.7 * np.arange(15))
    >>> y = np.convolve(u, g)[:60] + 0.01 * rng.standard_normal(60)
    >>> model = gm.FIRGaussianProcess(order=15, factor=3).fit(u, y[::3])
    >>> figures = fit_figures(model, u, inputs=["u"])
    >>> sorted(figures)
    ['bode.png', 'impulse.png', 'intersample.png']
    >>> figures["bode.png"].savefig(__import__("io").BytesIO(), format="png")
    """
    from gpmultirate.io import model_slow_samples
    from gpmultirate.progress import step

    if samples is None:
        samples = model_slow_samples(model)
    indices, values = samples.indices, samples.values
    n_inputs = model.n_inputs_
    names = list(inputs) if inputs is not None else [f"u{k}" for k in range(n_inputs)]
    prediction_length = np.shape(u)[0]
    figures = {}
    # Bode: one magnitude and phase pair per input
    fig = _figure(figsize=(4.8 * n_inputs + 1.2, 5.6))
    axes = fig.subplots(2, n_inputs, sharex=True, squeeze=False)
    from gpmultirate.plotting.axes import check_choice

    xscale = check_choice(xscale, "xscale", ("auto", "linear", "log"))
    freqs = _bode_frequencies(model)
    for k in range(n_inputs):
        with step("FRF"):
            frf = model.frequency_response(freqs, input=k if n_inputs > 1 else None)
        scale = bode_xscale(frf.freqs) if xscale == "auto" else xscale
        plot_bode(frf, axes=(axes[0, k], axes[1, k]), label="GP posterior mean", xscale=scale)
        axes[0, k].set_title(f"input {names[k]}", fontsize="medium", loc="left")
    figures["bode.png"] = fig

    # impulse responses at 4 lags per sample, between the integer lags too
    order = model.coef_.shape[-1]
    shown = min(order, max(60, prediction_length // 4))
    per_sample = max(1, min(4, (IMPULSE_POINTS - 1) // max(1, shown - 1)))
    lags = np.linspace(0.0, shown - 1.0, per_sample * (shown - 1) + 1)
    with step("bands"):
        mean, std = model.impulse_response(lags, return_std=True)
    mean, std = mean.reshape(n_inputs, -1), std.reshape(n_inputs, -1)
    if per_sample > 1 and not _smooth_between_lags(mean, per_sample):
        # a prior with little correlation between neighbouring lags pulls the curve
        # back to 0 between them: drawn there, the response looks like noise
        lags, mean, std = lags[::per_sample], mean[:, ::per_sample], std[:, ::per_sample]
    fig = _figure(figsize=(8.5, 2.6 * n_inputs + 0.4))
    axes = fig.subplots(n_inputs, 1, sharex=True, squeeze=False)[:, 0]
    for k, ax in enumerate(axes):
        response = ImpulseResponse(lags=lags, mean=mean[k], std=std[k], level=0.95,
                                   continuous=bool(model.continuous_lags))
        drawn = plot_impulse_response(response, ax=ax, label="posterior mean (95 % band)")
        # a band thinner than the line is invisible at the figure's scale: say how wide
        half = 1.96 * float(np.max(std[k]))
        span = float(np.ptp(mean[k])) or 1.0
        if half < 0.01 * span:
            drawn.mean_line.set_label(f"posterior mean (95 % band within ±{half:.2g}, "
                                      "thinner than the line)")
        ax.set_title(f"impulse response of input {names[k]}", fontsize="medium", loc="left")
        ax.legend(fontsize="small")
        if ax is not axes[-1]:
            ax.set_xlabel("")
    if shown < order:
        axes[-1].set_xlabel(f"lag [samples] (the first {shown} of P = {order})")
    figures["impulse.png"] = fig

    # fast-rate output on the record, all of it and a zoom on 20 slow periods
    instants = getattr(samples, "sample_times", None)  # a slow log: readings off the ticks
    with step("bands"):
        prediction = OutputPrediction.from_model(
            model, u, y_slow=None if instants is not None else values,
            sample_indices=indices if instants is None else np.unique(indices))
    n = prediction.time.shape[0]
    spacing = (max(1, int(round(float(np.median(np.diff(indices))))))
               if indices.size > 1 else 1)
    width = min(n, 20 * spacing)
    start = max(0, (n - width) // 2)
    fig = _figure(figsize=(8.5, 5.6))
    full, zoom = fig.subplots(2, 1)
    if instants is None:
        overview = plot_overview(prediction, ax=full, label="prediction (95 % band)")
    else:  # the readings at their stamps
        overview = plot_overview(prediction, ax=full, label="prediction (95 % band)",
                                 slow_time=np.asarray(instants) * float(model.sample_time),
                                 slow_values=values)
    title = "fast-rate output predicted from the slow samples"
    if overview.bin_width > 1:
        title += f" (range per {overview.bin_width} fast samples)"
    full.set_title(title, fontsize="medium", loc="left")
    if instants is None:
        plot_intersample(prediction, ax=zoom, window=(start, start + width),
                         label="prediction (95 % band)")
    else:  # the band between the ticks, the readings at their instants
        with step("bands"):
            plot_intersample(model, u, y_slow=values, sample_times=samples.stamps, ax=zoom,
                             window=(start, start + width), label="sensor reading (95 % band)")
    zoom.set_title(f"fast samples {start}..{start + width - 1}", fontsize="medium", loc="left")
    for ax in (full, zoom):
        ax.legend(fontsize="small")
    figures["intersample.png"] = fig
    return figures


def _smooth_between_lags(mean, per_sample: int) -> bool:
    """Whether the curve between the integer lags stays near the straight line between
    them (within half the response's root mean square), so it is worth drawing.

    Examples
    --------
    >>> t = np.linspace(0, 10, 41)
    >>> _smooth_between_lags(np.sin(t)[None], 4), _smooth_between_lags((t % 1 == 0)[None] * 1.0, 4)
    (True, False)
    """
    peak = float(np.max(np.abs(mean))) if mean.size else 0.0
    mean = mean / (peak if np.isfinite(peak) and peak > 0 else 1.0)  # no overflow near 1e308
    integer = mean[:, ::per_sample]
    grid = np.arange(mean.shape[1]) / per_sample
    straight = np.stack([np.interp(grid, np.arange(integer.shape[1]), row) for row in integer])
    scale = np.sqrt(np.mean(integer ** 2)) or 1.0
    return bool(np.sqrt(np.mean((mean - straight) ** 2)) <= 0.5 * scale)


def _bode_frequencies(model):
    """The DFT bins of the record, or log-spaced frequencies when there are too many.

    A long record has more bins than a figure shows (and each costs a row of
    the band's computation).  On the log axis the log-spaced grid is finer
    than the bins at low frequencies; a peak of damping ``zeta`` gets about
    ``2 zeta BODE_FREQUENCIES / log(N / 2)`` frequencies in its half-power
    bandwidth (9 for ``zeta = 0.02`` and ``N = 20,000``).
    """
    from gpmultirate.responses import default_frequencies

    sample_time = float(model.sample_time)
    freqs = default_frequencies(model.observation_.n_samples, sample_time)
    if freqs.size <= BODE_FREQUENCIES:
        return None  # the model's default: the same bins
    return np.concatenate([[0.0], np.geomspace(freqs[1], freqs[-1], BODE_FREQUENCIES - 1)])


def _format_gof(value: float) -> str:
    # enough decimals to tell 99.9990 % from 100 %
    return f"{value:.2f}" if value < 99.99 else f"{value:.4f}"


def study_figure(result):
    """Goodness of fit against the order over a study's runs (``gof_vs_order.png``).

    Parameters
    ----------
    result : StudyResult
        From :func:`gpmultirate.study.run_paper_study`.

    Returns
    -------
    matplotlib.figure.Figure
        The mean and ± 2 standard deviations per estimator.

    Examples
    --------
    >>> from gpmultirate.study import run_paper_study
    >>> from gpmultirate.plotting.report import study_figure
    >>> result = run_paper_study(1, [6], ["LS"], n_samples=30, factor=3, n_jobs=1)
    >>> study_figure(result).axes[0].get_title()
    'GoF on validation data, mean ± 2 std over 1 run'
    """
    fig = _figure(figsize=(6.4, 4.2))
    ax = fig.subplots()
    plot_study(result, ax=ax)
    ax.set_title(f"GoF on validation data, mean ± 2 std over {result.n_runs} "
                 f"run{'s' if result.n_runs > 1 else ''}", fontsize="medium")
    return fig


def example_figures(example) -> dict:
    """One study run's models against the truth (paper Fig. 6): the figures of ``demo``.

    Parameters
    ----------
    example : PaperExample
        From :func:`gpmultirate.study.paper_example`.

    Returns
    -------
    dict of str to matplotlib.figure.Figure
        ``bode.png``: the magnitude per estimator with the true FRF and
        ``0.1 |G0 - G|`` at the frequencies the multisine excites;
        ``impulse_response.png``: posterior mean and 95 % band over the
        first lags, with the true response; ``intersample.png``: the output
        between the slow samples over 20 slow periods in the record's middle.
    """
    methods = list(example.models)
    data = example.data
    n = data.u.shape[0]
    titles = {m: (f"{m} ({_DESCRIPTIONS[m]}), P = "
                  f"{example.ls_order if m == 'LS' else example.order}, "
                  f"GoF {_format_gof(example.gof[m])} %") for m in methods}
    figures = {}

    def panels(height):
        fig = _figure(figsize=(8.5, height * len(methods) + 0.4))
        axes = fig.subplots(len(methods), 1, sharex=True, squeeze=False)[:, 0]
        return fig, axes

    def finish(ax, axes, method):
        ax.set_title(titles[method], fontsize="medium", loc="left", pad=14)
        ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
        if ax is not axes[-1]:
            ax.set_xlabel("")

    # Bode magnitude per estimator with the true FRF and 0.1 |G0 - G| (paper Fig. 6), at
    # the DFT bins of the record, the frequencies the multisine excites
    freqs = example.frequencies()
    true_frf = example.true_frequency_response(freqs)
    fig, axes = panels(2.6)
    for ax, method in zip(axes, methods):
        frf = example.models[method].frequency_response(freqs, sample_time=data.sample_time)
        plot_bode(frf, axes=ax, phase=False, label=method, color=_STYLES[method],
                  true_frf=true_frf, show_error=True, error_scale=0.1)
        finish(ax, axes, method)
    figures["bode.png"] = fig

    # impulse responses: posterior mean and 95 % band over the first lags, true markers
    n_lags = min(example.order, max(60, n // 4))
    true_g = example.true_impulse_response(n_lags)
    fig, axes = panels(2.4)
    for ax, method in zip(axes, methods):
        model = example.models[method]
        shown = min(model.coef_.shape[0], n_lags)
        lags = (np.linspace(0.0, shown - 1.0, 4 * (shown - 1) + 1) if model.continuous_lags
                else np.arange(shown))
        plot_impulse_response(ImpulseResponse.from_model(model, lags), ax=ax, label=method,
                              color=_STYLES[method], true_response=true_g)
        finish(ax, axes, method)
    if n_lags < example.order:
        axes[-1].set_xlabel(f"lag [samples] (the first {n_lags} of P)")
    figures["impulse_response.png"] = fig

    # intersample output on the training input: 20 slow periods in the middle
    width = min(n, 20 * data.factor)
    start = max(0, (n - width) // 2)
    start -= start % data.factor
    fig, axes = panels(2.4)
    for ax, method in zip(axes, methods):
        prediction = OutputPrediction.from_model(
            example.models[method], data.u, y_fast=data.y_fast, y_slow=data.y_slow,
            sample_time=data.sample_time)
        plot_intersample(prediction, ax=ax, window=(start, min(n, start + width)),
                         label=method, color=_STYLES[method])
        finish(ax, axes, method)
    figures["intersample.png"] = fig
    return figures


def nonidentifiable_figure(example):
    """Three fast-rate models with identical slow-rate outputs (paper Example 1, Fig. 2).

    Parameters
    ----------
    example : NonidentifiableExample
        From :func:`gpmultirate.study.nonidentifiable_example`.

    Returns
    -------
    matplotlib.figure.Figure
        The four panels of :func:`gpmultirate.plotting.plot_nonidentifiable_example`
        (``example1.png`` of ``gpmultirate example1``).

    Examples
    --------
    >>> from gpmultirate.study import nonidentifiable_example
    >>> from gpmultirate.plotting.report import nonidentifiable_figure
    >>> len(nonidentifiable_figure(nonidentifiable_example(40, 4)).axes)
    4
    """
    from gpmultirate.plotting.time import plot_nonidentifiable_example

    fig = _figure(figsize=(9.0, 6.0))
    plot_nonidentifiable_example(example, axes=fig.subplots(2, 2))
    return fig
