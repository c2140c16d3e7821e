"""Tests of gpmultirate.plotting: what is drawn, where, and that the data are right."""

import inspect

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from sklearn.gaussian_process.kernels import ConstantKernel as C  # noqa: E402

import gpmultirate as gm  # noqa: E402
from gpmultirate.kernels import DC  # noqa: E402
from gpmultirate.plotting import (  # noqa: E402
    BodePlot,
    GoFPlot,
    ImpulseResponsePlot,
    IntersamplePlot,
    plot_bode,
    plot_gof_vs_order,
    plot_impulse_response,
    plot_intersample,
    plot_nonidentifiable_example,
)
from gpmultirate.study import NonidentifiableExample, nonidentifiable_example  # noqa: E402

Z95 = 1.959963984540054  # two-sided 95 % standard normal quantile
N, FACTOR, ORDER, T = 120, 3, 40, 0.1


@pytest.fixture(autouse=True)
def _no_show_and_close(monkeypatch):
    def forbidden(*args, **kwargs):
        raise AssertionError("plotting functions must never call plt.show()")

    monkeypatch.setattr(plt, "show", forbidden)
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(0)
    g = 0.9 ** np.arange(ORDER) * np.cos(0.8 * np.arange(ORDER))
    u = rng.standard_normal(N)
    y_fast = np.convolve(u, g)[:N]
    y_slow = y_fast[::FACTOR] + 1e-3 * rng.standard_normal(N // FACTOR)
    return {"g": g, "u": u, "y_fast": y_fast, "y_slow": y_slow}


@pytest.fixture(scope="module")
def gp(data):
    model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=FACTOR, order=ORDER,
                                  noise_level=1e-4, optimizer=None)
    return model.fit(data["u"], data["y_slow"])


@pytest.fixture(scope="module")
def ls(data):
    return gm.LeastSquaresFIR(factor=FACTOR, order=10).fit(data["u"], data["y_slow"])


@pytest.fixture(scope="module")
def frf(gp):
    return gp.frequency_response(sample_time=T)


@pytest.fixture(scope="module")
def true_frf(data, frf):
    # DTFT of the true coefficients at the frequencies of frf, written out
    n = np.arange(ORDER)
    return np.exp(-2j * np.pi * np.outer(frf.freqs, n) * T) @ data["g"]


def band_vertices(band):
    return np.concatenate([path.vertices for path in band.get_paths()])


def assert_band_between(band, x, lower, upper, atol=1e-9):
    """Every vertex of a fill_between lies at some x with lower <= y <= upper, and both
    curves are reached."""
    vertices = band_vertices(band)
    index = np.array([np.argmin(np.abs(x - vx)) for vx in vertices[:, 0]])
    assert np.allclose(x[index], vertices[:, 0])
    assert np.all(vertices[:, 1] >= lower[index] - atol)
    assert np.all(vertices[:, 1] <= upper[index] + atol)
    for curve in (lower, upper):
        assert np.all([np.any(np.isclose(vertices[:, 1][index == i], curve[i], atol=atol))
                       for i in range(len(x))])


def db(x):
    return 20 * np.log10(np.abs(x))


# ---------------------------------------------------------------- Bode plot
class TestPlotBode:
    def test_new_figure_and_returned_artists(self, frf, true_frf):
        before = set(plt.get_fignums())
        bode = plot_bode(frf, label="DC", true_frf=true_frf, show_error=True, error_scale=0.1)
        assert len(set(plt.get_fignums()) - before) == 1
        assert isinstance(bode, BodePlot)
        ax_mag, ax_phase = bode.axes
        assert bode.magnitude_line in ax_mag.get_lines()
        assert bode.phase_line in ax_phase.get_lines()
        assert bode.magnitude_band in ax_mag.collections
        assert bode.phase_band in ax_phase.collections
        assert ax_mag.get_yscale() == "linear" and ax_mag.get_xscale() == "linear"

    def test_plotted_values(self, frf, true_frf):
        bode = plot_bode(frf, true_frf=true_frf, show_error=True, error_scale=0.1)
        np.testing.assert_allclose(bode.magnitude_line.get_xdata(), frf.freqs)
        np.testing.assert_allclose(bode.magnitude_line.get_ydata(), db(frf.mean))
        phase = np.degrees(np.unwrap(np.angle(frf.mean)))
        np.testing.assert_allclose(bode.phase_line.get_ydata(), phase)
        np.testing.assert_allclose(bode.true_magnitude_line.get_ydata(), db(true_frf))
        true_phase = np.degrees(np.unwrap(np.angle(true_frf)))
        shift = bode.true_phase_line.get_ydata() - true_phase
        np.testing.assert_allclose(np.round(shift / 360) * 360, shift, atol=1e-9)
        np.testing.assert_allclose(bode.error_line.get_ydata(),
                                   db(0.1 * (true_frf - frf.mean)))

    def test_bands_lie_between_bounds(self, frf):
        bode = plot_bode(frf)
        assert_band_between(bode.magnitude_band, frf.freqs, db(frf.magnitude_lower),
                            db(frf.magnitude_upper))
        assert_band_between(bode.phase_band, frf.freqs, np.degrees(frf.phase_lower),
                            np.degrees(frf.phase_upper))
        # the mean lies inside its band
        assert np.all(db(frf.magnitude_lower) <= db(frf.mean) + 1e-9)
        assert np.all(db(frf.mean) <= db(frf.magnitude_upper) + 1e-9)

    def test_given_axes_and_overlay(self, frf, ls):
        fig, axes = plt.subplots(2, 1)
        before = plt.get_fignums()
        first = plot_bode(frf, axes=axes, label="GP")
        second = plot_bode(ls.frequency_response(sample_time=T), axes=axes, label="LS")
        assert plt.get_fignums() == before
        assert first.axes == second.axes == tuple(axes)
        assert first.magnitude_line.get_color() != second.magnitude_line.get_color()
        assert {first.magnitude_line, second.magnitude_line} <= set(axes[0].get_lines())
        labels = [t.get_text() for t in axes[0].get_legend().get_texts()]
        # every estimate and its band; the LS estimate of order 10 has frequencies
        # where its credible region contains 0
        assert labels == ["GP", "GP, 95 % band", "LS", "LS, 95 % band",
                          "LS: phase undefined"]
        # each Nyquist marker is drawn once per axes, also after the overlay
        for ax in axes:
            gids = [ln.get_gid() for ln in ax.get_lines() if ln.get_gid()]
            assert sorted(gids) == ["gpmultirate-fast-nyquist", "gpmultirate-slow-nyquist"]
        positions = sorted(ln.get_xdata()[0] for ln in second.nyquist_lines[:2])
        assert positions == pytest.approx([1 / (2 * FACTOR * T), 1 / (2 * T)])

    def test_true_frf_has_one_legend_entry(self, frf, true_frf):
        bode = plot_bode(frf, label="a", true_frf=true_frf)
        plot_bode(frf, axes=bode.axes, label="b", true_frf=true_frf)
        labels = [t.get_text() for t in bode.axes[0].get_legend().get_texts()]
        assert labels.count("true") == 1

    def test_linear_magnitude_log_frequency_no_phase(self, frf):
        fig, ax = plt.subplots()
        bode = plot_bode(frf, axes=ax, db=False, phase=False, xscale="log", show_band=False,
                         show_nyquist=False)
        assert bode.axes == (ax, None) and bode.phase_line is None
        assert bode.magnitude_band is None and bode.nyquist_lines == []
        assert ax.get_yscale() == "log" and ax.get_xscale() == "log"
        np.testing.assert_allclose(bode.magnitude_line.get_xdata(), frf.freqs[1:])
        np.testing.assert_allclose(bode.magnitude_line.get_ydata(), np.abs(frf.mean[1:]))

    @pytest.mark.parametrize(
        "kwargs, name",
        [
            ({"true_frf": np.ones(3)}, "true_frf"),
            ({"show_error": True}, "true_frf"),
            ({"xscale": "symlog"}, "xscale"),
            ({"error_scale": -1.0}, "error_scale"),
            ({"axes": "ax"}, "axes"),
        ],
    )
    def test_invalid_arguments(self, frf, kwargs, name):
        with pytest.raises(ValueError, match=name):
            plot_bode(frf, **kwargs)

    def test_invalid_frf_and_single_axes_with_phase(self, frf):
        with pytest.raises(ValueError, match="frf"):
            plot_bode(np.ones(3))
        fig, ax = plt.subplots()
        with pytest.raises(ValueError, match="axes"):
            plot_bode(frf, axes=ax)


# --------------------------------------------------------- impulse response
class TestPlotImpulseResponse:
    def test_default_grid_band_and_draws(self, gp, data):
        drawn = plot_impulse_response(gp, n_samples=2, random_state=0,
                                      true_response=data["g"], label="DC")
        assert isinstance(drawn, ImpulseResponsePlot)
        lags = drawn.mean_line.get_xdata()
        np.testing.assert_allclose(lags, np.arange(157) / 4)  # 4 points per sample
        mean, std = gp.impulse_response(lags, return_std=True)
        np.testing.assert_allclose(drawn.mean_line.get_ydata(), mean)
        # at integer lags the mean is the regularised estimate coef_
        np.testing.assert_allclose(drawn.mean_line.get_ydata()[::4], gp.coef_, atol=1e-10)
        assert_band_between(drawn.band, lags, mean - Z95 * std, mean + Z95 * std)
        assert len(drawn.sample_lines) == 2
        assert all(line in drawn.ax.get_lines() for line in drawn.sample_lines)
        np.testing.assert_array_equal(drawn.true_markers.get_xdata(), np.arange(ORDER))
        np.testing.assert_array_equal(drawn.true_markers.get_ydata(), data["g"])

    def test_level_sets_band_width(self, gp):
        lags = np.array([0.5, 3.25, 10.0])
        drawn = plot_impulse_response(gp, lags, level=0.5)
        mean, std = gp.impulse_response(lags, return_std=True)
        z50 = 0.6744897501960817
        assert_band_between(drawn.band, lags, mean - z50 * std, mean + z50 * std)

    def test_least_squares_at_integer_lags(self, ls):
        fig, ax = plt.subplots()
        before = plt.get_fignums()
        drawn = plot_impulse_response(ls, ax=ax, n_samples=1, random_state=1)
        assert plt.get_fignums() == before and drawn.ax is ax
        np.testing.assert_array_equal(drawn.mean_line.get_xdata(), np.arange(10))
        np.testing.assert_allclose(drawn.mean_line.get_ydata(), ls.coef_)
        half = Z95 * np.sqrt(np.diag(ls.coef_covariance_))
        assert_band_between(drawn.band, np.arange(10.0), ls.coef_ - half, ls.coef_ + half)
        assert len(drawn.sample_lines) == 1

    def test_overlay(self, gp, ls):
        first = plot_impulse_response(gp)
        second = plot_impulse_response(ls, ax=first.ax)
        assert second.ax is first.ax
        assert {first.mean_line, second.mean_line} <= set(first.ax.get_lines())

    def test_invalid_arguments(self, gp, ls):
        with pytest.raises(ValueError, match="lags"):
            plot_impulse_response(ls, [0.5])
        with pytest.raises(ValueError, match="lags"):
            plot_impulse_response(ls, [10])
        with pytest.raises(ValueError, match="level"):
            plot_impulse_response(gp, level=1.5)
        with pytest.raises(ValueError, match="n_samples"):
            plot_impulse_response(gp, n_samples=-1)
        with pytest.raises(ValueError, match="model"):
            plot_impulse_response(gm.LeastSquaresFIR(order=3))
        with pytest.raises(ValueError, match="ax"):
            plot_impulse_response(gp, ax=object())


# ------------------------------------------------------- intersample output
class TestPlotIntersample:
    def test_slow_samples_at_fast_times(self, gp, data):
        drawn = plot_intersample(gp, data["u"], y_fast=data["y_fast"], y_slow=data["y_slow"],
                                 sample_time=T)
        assert isinstance(drawn, IntersamplePlot)
        np.testing.assert_allclose(drawn.slow_markers.get_xdata(),
                                   np.arange(0, N, FACTOR) * T)
        np.testing.assert_array_equal(drawn.slow_markers.get_ydata(), data["y_slow"])
        np.testing.assert_array_equal(drawn.fast_line.get_ydata(), data["y_fast"])
        time = np.arange(N) * T
        mean, std = gp.predict(data["u"], return_std=True)
        np.testing.assert_allclose(drawn.mean_line.get_ydata(), mean)
        assert_band_between(drawn.band, time, mean - Z95 * std, mean + Z95 * std)

    def test_window_offset_and_given_axes(self, data):
        y_slow = data["y_fast"][1::FACTOR]
        model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=FACTOR, order=ORDER, offset=1,
                                      noise_level=1e-4, optimizer=None).fit(data["u"], y_slow)
        fig, ax = plt.subplots()
        before = plt.get_fignums()
        drawn = plot_intersample(model, data["u"], y_slow=y_slow, ax=ax, window=(30, 60))
        assert plt.get_fignums() == before and drawn.ax is ax and drawn.fast_line is None
        np.testing.assert_array_equal(drawn.mean_line.get_xdata(), np.arange(30, 60))
        # offset 1 taken from the model: slow samples at fast indices 31, 34, ..., 58
        np.testing.assert_array_equal(drawn.slow_markers.get_xdata(), np.arange(31, 60, 3))
        np.testing.assert_array_equal(drawn.slow_markers.get_ydata(), y_slow[10:20])

    def test_invalid_arguments(self, gp, data):
        u = data["u"]
        with pytest.raises(ValueError, match="window"):
            plot_intersample(gp, u, window=(60, 30))
        for window in [(0, N + 1), (0, 10, 20), 5, (0.5, 10)]:
            with pytest.raises(ValueError, match="window"):
                plot_intersample(gp, u, window=window)
        with pytest.raises(ValueError, match="y_slow"):
            plot_intersample(gp, u, y_slow=np.ones(3))
        with pytest.raises(ValueError, match="y_fast"):
            plot_intersample(gp, u, y_fast=np.ones(3))
        with pytest.raises(ValueError, match="offset"):
            plot_intersample(gp, u, offset=FACTOR)
        with pytest.raises(ValueError, match="sample_time"):
            plot_intersample(gp, u, sample_time=0.0)


# ------------------------------------------------------------ GoF vs order
class TestPlotGoFVsOrder:
    orders = np.array([10, 20, 40, 80])
    gof = np.array([[90.0, 92.0, 80.0, np.nan],
                    [94.0, 96.0, np.nan, np.nan],
                    [92.0, 91.0, 70.0, np.nan]])

    def test_nan_aware_mean_and_band(self):
        drawn = plot_gof_vs_order(self.orders, self.gof, label="LS", marker="o")
        assert isinstance(drawn, GoFPlot)
        mean = np.array([92.0, 93.0, 75.0, np.nan])
        np.testing.assert_allclose(drawn.line.get_ydata(), mean)
        std = np.array([2.0, np.std([92, 96, 91], ddof=1), np.std([80, 70], ddof=1)])
        assert_band_between(drawn.band, self.orders[:3].astype(float), mean[:3] - 2 * std,
                            mean[:3] + 2 * std)
        # no band where no run has a value
        assert np.all(band_vertices(drawn.band)[:, 0] <= 40)

    def test_identifiable_mask_and_overlay(self):
        fig, ax = plt.subplots()
        before = plt.get_fignums()
        ls = plot_gof_vs_order(self.orders, self.gof, ax=ax, label="LS",
                               identifiable=self.orders < 30, n_std=1)
        dc = plot_gof_vs_order(self.orders, np.full((2, 4), 95.0), ax=ax, label="DC")
        assert plt.get_fignums() == before and ls.ax is dc.ax is ax
        assert np.isnan(ls.line.get_ydata()[2:]).all()
        assert np.all(band_vertices(ls.band)[:, 0] <= 20)
        assert [t.get_text() for t in ax.get_legend().get_texts()] == ["LS", "DC"]

    def test_one_run(self):
        drawn = plot_gof_vs_order(self.orders, [1.0, 2.0, np.nan, 4.0])
        assert drawn.band is None
        np.testing.assert_array_equal(drawn.line.get_ydata(), [1.0, 2.0, np.nan, 4.0])

    @pytest.mark.parametrize(
        "kwargs, name",
        [
            ({"gof": np.ones((2, 3))}, "gof"),
            ({"gof": np.full(4, np.inf)}, "gof"),
            ({"identifiable": np.ones(3, dtype=bool)}, "identifiable"),
            ({"identifiable": np.ones(4)}, "identifiable"),
            ({"n_std": 0}, "n_std"),
        ],
    )
    def test_invalid_arguments(self, kwargs, name):
        arguments = {"gof": self.gof} | kwargs
        with pytest.raises(ValueError, match=name):
            plot_gof_vs_order(self.orders, **arguments)


# ------------------------------------------------- non-identifiable example
class TestNonidentifiableExample:
    def test_paper_defaults_and_sizes(self):
        # defaults are the paper's N = P = 1000, F = 4 (not run here: an SVD of 250 x 1000)
        defaults = inspect.signature(nonidentifiable_example).parameters
        assert defaults["n_samples"].default == 1000 and defaults["factor"].default == 4
        example = nonidentifiable_example(100, factor=4, random_state=0)
        assert isinstance(example, NonidentifiableExample)
        assert example.models.shape == (3, 100) and example.y_fast.shape == (3, 100)
        assert example.y_slow.shape == (25,) and example.factor == 4
        assert example.u[0] == 1 and np.count_nonzero(example.u) == 1

    @pytest.mark.parametrize("n_samples, factor", [(200, 4), (90, 3), (31, 2)])
    def test_identical_slow_outputs_different_models(self, n_samples, factor):
        example = nonidentifiable_example(n_samples, factor, random_state=1)
        models = example.models
        for j in (1, 2):
            assert np.max(np.abs(models[j] - models[0])) > 1e-3
        assert np.max(np.abs(models[1] - models[2])) > 1e-3
        for j in range(3):
            y = np.convolve(example.u, models[j])[:n_samples]
            np.testing.assert_allclose(y, example.y_fast[j], atol=1e-12)
            np.testing.assert_allclose(y[::factor], example.y_slow, rtol=0, atol=1e-10)

    def test_invalid_arguments(self):
        with pytest.raises(ValueError, match="factor"):
            nonidentifiable_example(100, factor=1)
        with pytest.raises(ValueError, match="n_samples"):
            nonidentifiable_example(7, factor=4)

    def test_plot_panels(self):
        example = nonidentifiable_example(200, factor=4, random_state=0)
        axes = plot_nonidentifiable_example(example, sample_time=T)
        assert axes.shape == (2, 2)
        slow_spectra = [line.get_ydata() for line in axes[0, 0].get_lines()]
        np.testing.assert_allclose(slow_spectra[1], slow_spectra[0], atol=1e-8)
        np.testing.assert_allclose(
            slow_spectra[0], db(np.fft.rfft(example.y_slow)), atol=1e-8)
        assert axes[0, 0].get_xlim()[1] == pytest.approx(1 / (2 * 4 * T))
        frfs = [line.get_ydata() for line in axes[1, 0].get_lines()[:3]]
        assert np.max(np.abs(frfs[1] - frfs[0])) > 1.0
        impulse = axes[1, 1].get_lines()
        np.testing.assert_array_equal(impulse[2].get_ydata(), example.models[2, :64])

    def test_plot_on_given_axes(self):
        example = nonidentifiable_example(40, factor=4, random_state=0)
        fig, axes = plt.subplots(2, 2)
        before = plt.get_fignums()
        returned = plot_nonidentifiable_example(example, axes=axes)
        assert plt.get_fignums() == before
        assert list(returned.flat) == list(axes.flat)
        with pytest.raises(ValueError, match="axes"):
            plot_nonidentifiable_example(example, axes=axes[0])
        with pytest.raises(ValueError, match="example"):
            plot_nonidentifiable_example(example.models)
