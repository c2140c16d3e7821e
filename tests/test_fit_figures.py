"""The figures of ``gpmultirate fit`` rendered on a short and a long record: what they draw."""

import numpy as np
import pytest

import gpmultirate as gm
from gpmultirate.io import read_slow_samples
from gpmultirate.plotting.overview import OVERVIEW_POINTS, envelope, plot_overview
from gpmultirate.plotting.report import bode_xscale, fit_figures
from gpmultirate.responses import OutputPrediction


def _record(n, factor, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    lags = np.arange(40)
    g = 0.9 ** lags * np.cos(0.9 * lags)
    y = np.convolve(u, g)[:n] + 0.02 * rng.standard_normal(n)
    column = np.full(n, np.nan)
    column[::factor] = y[::factor]
    samples = read_slow_samples(column)
    model = gm.FIRGaussianProcess(order=40, sample_time=0.01, **samples.estimator_params)
    return model.fit(u, samples.y_slow), u, samples


@pytest.fixture(scope="module")
def short():
    return _record(120, 3)


@pytest.fixture(scope="module")
def long():
    return _record(6000, 10)


def _drawn(figure):
    figure.canvas.draw()  # renders: the artists below are what the file shows
    return figure


@pytest.mark.parametrize("which", ["short", "long"])
def test_every_figure_renders_and_draws_its_data(which, request):
    model, u, samples = request.getfixturevalue(which)
    figures = {name: _drawn(f) for name, f in fit_figures(model, u, samples, ["u"]).items()}
    n, m = u.shape[0], samples.values.shape[0]

    # Bode: the lower edge of the magnitude band is never more than 20 dB below the magnitude
    ax_mag, ax_phase = figures["bode.png"].axes[:2]
    assert ax_mag.get_xscale() == ("linear" if which == "short" else "log")
    line = ax_mag.get_lines()[0]
    f, mag_db = line.get_xdata(), line.get_ydata()
    band = [c for c in ax_mag.collections if c.get_label().endswith("% band")][0]
    vertices = np.concatenate([p.vertices for p in band.get_paths()])
    assert np.all(np.isfinite(vertices))
    reference = np.interp(vertices[:, 0], f, mag_db)
    assert np.all(vertices[:, 1] >= reference - 20 - 1e-6)
    low, high = ax_mag.get_ylim()
    assert high - low < 200  # no axis stretched down to a floor of -120 dB or below

    # overview: one point per fast sample on a short record, bins on a long one; every
    # slow sample drawn
    full = figures["intersample.png"].axes[0]
    markers = [ln for ln in full.get_lines() if ln.get_marker() == "o"]
    assert len(markers) == 1 and markers[0].get_xdata().shape == (m,)
    np.testing.assert_allclose(markers[0].get_ydata(), samples.values)
    if which == "short":
        assert full.get_lines()[0].get_xdata().shape == (n,)
    else:
        assert "range per" in full.get_title(loc="left")
        drawn_points = sum(p.vertices.shape[0] for c in full.collections for p in c.get_paths())
        assert drawn_points < 6 * OVERVIEW_POINTS
        assert full.get_xlim()[1] == pytest.approx((n - 1) * 0.01, rel=0.02)

    # impulse response: the band is visible, or the legend says how narrow it is
    ax = figures["impulse.png"].axes[0]
    mean_line = ax.get_lines()[0]
    label = mean_line.get_label()
    band = ax.collections[0]
    heights = np.ptp(np.concatenate([p.vertices for p in band.get_paths()])[:, 1])
    assert heights > 0
    y = mean_line.get_ydata()
    std = model.impulse_response(mean_line.get_xdata(), return_std=True)[1]
    if 1.96 * std.max() < 0.01 * np.ptp(y):
        assert "thinner than the line" in label
    else:
        assert "thinner" not in label


def test_the_frequency_axis_can_be_chosen(short):
    model, u, samples = short
    figure = fit_figures(model, u, samples, xscale="log")["bode.png"]
    assert figure.axes[0].get_xscale() == "log"
    with pytest.raises(ValueError, match="xscale"):
        fit_figures(model, u, samples, xscale="loglog")
    assert bode_xscale(np.linspace(0, 0.5, 1001)) == "log"  # 0.0005 .. 0.5
    assert bode_xscale(np.linspace(0, 0.5, 11)) == "linear"


def test_the_envelope_keeps_every_extreme():
    rng = np.random.default_rng(2)
    x = rng.standard_normal(10_001)
    low, high = envelope(x, 7)
    assert low.shape == (1429,) and low.min() == x.min() and high.max() == x.max()
    for b in (0, 500, 1428):
        np.testing.assert_equal([low[b], high[b]], [x[7 * b:7 * b + 7].min(),
                                                    x[7 * b:7 * b + 7].max()])


def test_overview_bins_a_long_prediction_and_draws_readings_at_their_stamps():
    from matplotlib.figure import Figure

    t = np.arange(20_000) * 0.01
    prediction = OutputPrediction(time=t, mean=np.sin(t), std=np.full(t.shape, 0.1))
    stamps = np.arange(5.0, 195.0, 0.37)
    drawn = plot_overview(prediction, ax=Figure().subplots(), slow_time=stamps,
                          slow_values=np.sin(stamps))
    assert drawn.bin_width == -(-20_000 // OVERVIEW_POINTS)
    np.testing.assert_array_equal(drawn.slow_markers.get_xdata(), stamps)
    band = np.concatenate([p.vertices for p in drawn.band.get_paths()])
    assert band[:, 1].min() == pytest.approx(-1.0 - 1.96 * 0.1, abs=2e-3)
    with pytest.raises(ValueError, match="max_points"):
        plot_overview(prediction, max_points=1)
