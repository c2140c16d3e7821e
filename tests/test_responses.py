"""Tests of gpmultirate.responses: the data objects, their statistics and how they are drawn."""

import ast
import dataclasses
import pathlib

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import scipy.stats  # noqa: E402
from sklearn.gaussian_process.kernels import ConstantKernel as C  # noqa: E402

import gpmultirate as gm  # noqa: E402
from gpmultirate.kernels import DC  # noqa: E402
from gpmultirate.plotting import (  # noqa: E402
    plot_gof_vs_order,
    plot_impulse_response,
    plot_intersample,
)
from gpmultirate.responses import (  # noqa: E402
    FrequencyResponse,
    ImpulseResponse,
    OutputPrediction,
    normal_quantile,
)
from gpmultirate.study import GoFSummary  # noqa: E402

N, FACTOR, ORDER, T = 120, 3, 40, 0.1
PACKAGE = pathlib.Path(gm.__file__).resolve().parent


@pytest.fixture(autouse=True)
def _close_figures():
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


def z_of(level):
    return scipy.stats.norm.ppf(0.5 + level / 2)


def band_vertices(band):
    return np.concatenate([path.vertices for path in band.get_paths()])


# ------------------------------------------------------------ ImpulseResponse
class TestImpulseResponse:
    @pytest.mark.parametrize("level", [0.5, 0.9, 0.95])
    def test_band_is_mean_plus_minus_z_std(self, gp, level):
        response = ImpulseResponse.from_model(gp, [0.5, 3.25, 10.0], level=level)
        np.testing.assert_allclose(response.lower, response.mean - z_of(level) * response.std)
        np.testing.assert_allclose(response.upper, response.mean + z_of(level) * response.std)
        assert normal_quantile(level) == pytest.approx(z_of(level))

    def test_std_is_the_root_of_the_covariance_diagonal(self, gp):
        lags = np.array([0.0, 2.5, 7.75, 30.0])
        response = ImpulseResponse.from_model(gp, lags)
        _, cov = gp.impulse_response(lags, return_cov=True)
        np.testing.assert_allclose(response.std, np.sqrt(np.diag(cov)), rtol=1e-6,
                                   atol=1e-12)

    def test_default_lags(self, gp, ls):
        continuous = ImpulseResponse.from_model(gp)
        assert continuous.continuous
        np.testing.assert_allclose(continuous.lags, np.arange(4 * (ORDER - 1) + 1) / 4)
        # at integer lags the posterior mean is the regularised estimate
        np.testing.assert_allclose(continuous.mean[::4], gp.coef_, atol=1e-10)
        integer = ImpulseResponse.from_model(ls)
        assert not integer.continuous
        np.testing.assert_array_equal(integer.lags, np.arange(10))
        np.testing.assert_allclose(integer.mean, ls.coef_)
        np.testing.assert_allclose(integer.std, np.sqrt(np.diag(ls.coef_covariance_)))
        assert integer.samples.shape == (10, 0)

    @pytest.mark.parametrize("which", ["gp", "ls"])
    def test_draws_have_the_posterior_covariance(self, request, which):
        """Monte Carlo: mean and covariance of many draws against the exact posterior."""
        model = request.getfixturevalue(which)
        lags = np.array([0.5, 3.25, 10.0, 20.75]) if which == "gp" else np.array([0, 3, 5, 9])
        n_draws = 20_000
        response = ImpulseResponse.from_model(model, lags, n_samples=n_draws, random_state=0)
        assert response.samples.shape == (4, n_draws)
        mean, cov = model.impulse_response(lags, return_cov=True)
        scale = np.sqrt(np.max(np.diag(cov)))
        np.testing.assert_allclose(response.samples.mean(axis=1), mean, atol=0.05 * scale)
        np.testing.assert_allclose(np.cov(response.samples), cov, atol=0.05 * scale**2)

    def test_same_seed_same_draws(self, gp):
        first = ImpulseResponse.from_model(gp, n_samples=2, random_state=3)
        second = ImpulseResponse.from_model(gp, n_samples=2, random_state=3)
        np.testing.assert_array_equal(first.samples, second.samples)

    def test_repr_is_short(self, gp):
        response = ImpulseResponse.from_model(gp, n_samples=50, random_state=0)
        assert repr(response) == ("ImpulseResponse(157 lags in [0, 39], continuous lags, "
                                  "level=0.95, std, 50 samples)")
        large = ImpulseResponse(np.arange(100_000.0), np.zeros(100_000))
        assert len(repr(large)) < 120 and "no std" in repr(large)

    def test_frozen_and_read_only(self):
        lags = np.arange(3.0)
        response = ImpulseResponse(lags, np.ones(3), np.ones(3))
        with pytest.raises(dataclasses.FrozenInstanceError):
            response.level = 0.5
        with pytest.raises(ValueError):
            response.mean[0] = 2.0
        lags[0] = 7.0  # the object holds its own copy
        assert response.lags[0] == 0.0

    @pytest.mark.parametrize(
        "kwargs, name",
        [
            ({"mean": np.ones(2)}, "mean"),
            ({"std": -np.ones(3)}, "std"),
            ({"std": np.ones(2)}, "std"),
            ({"samples": np.ones((2, 4))}, "samples"),
            ({"samples": np.ones(3)}, "samples"),
            ({"level": 1.5}, "level"),
            ({"continuous": "yes"}, "continuous"),
            ({"lags": [[0.0, 1.0], [2.0, 3.0]]}, "lags"),
        ],
    )
    def test_invalid_fields(self, kwargs, name):
        fields = {"lags": np.arange(3.0), "mean": np.zeros(3)} | kwargs
        with pytest.raises(ValueError, match=name):
            ImpulseResponse(**fields)

    def test_invalid_model_arguments(self, gp, ls):
        with pytest.raises(ValueError, match="model"):
            ImpulseResponse.from_model(gm.FIRGaussianProcess(C(1.0) * DC(), order=3))
        with pytest.raises(ValueError, match="model"):
            ImpulseResponse.from_model(object())
        with pytest.raises(ValueError, match="n_samples"):
            ImpulseResponse.from_model(gp, n_samples=-1)
        with pytest.raises(ValueError, match="level"):
            ImpulseResponse.from_model(gp, level=0.0)
        with pytest.raises(ValueError, match="lags"):
            ImpulseResponse.from_model(ls, [0.5])


# ------------------------------------------------------------ OutputPrediction
class TestOutputPrediction:
    def test_from_model(self, gp, data):
        prediction = OutputPrediction.from_model(gp, data["u"], y_fast=data["y_fast"],
                                                 y_slow=data["y_slow"], sample_time=T,
                                                 level=0.9)
        np.testing.assert_allclose(prediction.time, np.arange(N) * T)
        np.testing.assert_array_equal(prediction.slow_index, np.arange(0, N, FACTOR))
        np.testing.assert_allclose(prediction.slow_time, np.arange(0, N, FACTOR) * T)
        # the mean is the convolution of the input with the estimate
        np.testing.assert_allclose(prediction.mean, np.convolve(data["u"], gp.coef_)[:N],
                                   atol=1e-10)
        np.testing.assert_allclose(prediction.lower, prediction.mean - z_of(0.9) * prediction.std)
        np.testing.assert_allclose(prediction.upper, prediction.mean + z_of(0.9) * prediction.std)
        np.testing.assert_array_equal(prediction.y_slow, data["y_slow"])

    def test_offset_from_the_model(self, data):
        y_slow = data["y_fast"][1::FACTOR]
        model = gm.LeastSquaresFIR(factor=FACTOR, order=10, offset=1).fit(data["u"], y_slow)
        prediction = OutputPrediction.from_model(model, data["u"], y_slow=y_slow)
        np.testing.assert_array_equal(prediction.slow_index, np.arange(1, N, FACTOR))
        assert np.all(prediction.std > 0)

    def test_select_window(self):
        full = OutputPrediction(time=0.5 * np.arange(10), mean=np.arange(10.0),
                                std=np.ones(10), slow_index=np.arange(1, 10, 3),
                                y_fast=-np.arange(10.0), y_slow=np.array([1.0, 4.0, 7.0]))
        part = full.select((3, 8))
        np.testing.assert_array_equal(part.time, 0.5 * np.arange(3, 8))
        np.testing.assert_array_equal(part.y_fast, -np.arange(3.0, 8.0))
        np.testing.assert_array_equal(part.slow_time, [2.0, 3.5])
        np.testing.assert_array_equal(part.y_slow, [4.0, 7.0])

    def test_repr_is_short(self):
        n = 100_000
        prediction = OutputPrediction(time=np.arange(n) * 0.1, mean=np.zeros(n),
                                      std=np.ones(n), slow_index=np.arange(0, n, 4))
        assert repr(prediction) == ("OutputPrediction(100000 fast samples over [0, 9999.9] s, "
                                    "25000 slow samples, level=0.95)")

    @pytest.mark.parametrize(
        "kwargs, name",
        [
            ({"mean": np.ones(2)}, "mean"),
            ({"std": -np.ones(4)}, "std"),
            ({"y_fast": np.ones(3)}, "y_fast"),
            ({"slow_index": np.array([0, 4])}, "slow_index"),
            ({"slow_index": np.array([0.0, 2.0])}, "slow_index"),
            ({"slow_index": np.array([0, 2]), "y_slow": np.ones(3)}, "y_slow"),
            ({"level": -0.1}, "level"),
        ],
    )
    def test_invalid_fields(self, kwargs, name):
        fields = {"time": np.arange(4.0), "mean": np.zeros(4), "std": np.ones(4)} | kwargs
        with pytest.raises(ValueError, match=name):
            OutputPrediction(**fields)

    def test_invalid_model_arguments(self, gp, data):
        with pytest.raises(ValueError, match="model"):
            OutputPrediction.from_model(gm.LeastSquaresFIR(order=3), data["u"])
        with pytest.raises(ValueError, match="factor"):
            OutputPrediction.from_model(gp, data["u"], factor=0)
        with pytest.raises(ValueError, match="window"):
            OutputPrediction(np.arange(3.0), np.zeros(3), np.ones(3)).select((2, 2))


# -------------------------------------------------- drawing the data objects
class TestDrawingDataObjects:
    def test_impulse_response_draws_exactly_its_arrays(self):
        rng = np.random.default_rng(1)
        response = ImpulseResponse(lags=np.array([0.0, 0.5, 1.0, 2.0]), mean=rng.normal(size=4),
                                   std=rng.uniform(0.1, 0.2, 4), level=0.8,
                                   samples=rng.normal(size=(4, 3)), continuous=True)
        drawn = plot_impulse_response(response, label="data")
        np.testing.assert_array_equal(drawn.mean_line.get_xdata(), response.lags)
        np.testing.assert_array_equal(drawn.mean_line.get_ydata(), response.mean)
        assert drawn.mean_line.get_marker() in ("None", None, "")
        assert [line.get_ydata().tolist() for line in drawn.sample_lines] == \
            response.samples.T.tolist()
        vertices = band_vertices(drawn.band)
        for x, low, high in zip(response.lags, response.lower, response.upper):
            at_x = vertices[np.isclose(vertices[:, 0], x), 1]
            np.testing.assert_allclose([at_x.min(), at_x.max()], [low, high])

    def test_integer_lags_get_markers_and_no_band_without_std(self):
        response = ImpulseResponse(np.arange(5.0), np.ones(5), continuous=False)
        drawn = plot_impulse_response(response)
        assert drawn.band is None and drawn.mean_line.get_marker() == "."

    def test_model_only_arguments_are_refused_with_a_data_object(self):
        response = ImpulseResponse(np.arange(5.0), np.ones(5))
        for kwargs, name in [({"lags": [1.0]}, "lags"), ({"level": 0.9}, "level"),
                             ({"n_samples": 2}, "n_samples"),
                             ({"random_state": 0}, "random_state")]:
            with pytest.raises(ValueError, match=name):
                plot_impulse_response(response, **kwargs)
        prediction = OutputPrediction(np.arange(4.0), np.zeros(4), np.ones(4))
        with pytest.raises(ValueError, match="u"):
            plot_intersample(prediction, np.ones(4))
        with pytest.raises(ValueError, match="sample_time"):
            plot_intersample(prediction, sample_time=0.1)

    def test_model_and_data_object_give_the_same_figure(self, gp, data):
        from_model = plot_impulse_response(gp, n_samples=2, random_state=4)
        response = ImpulseResponse.from_model(gp, n_samples=2, random_state=4)
        from_data = plot_impulse_response(response)
        for a, b in [(from_model.mean_line, from_data.mean_line),
                     *zip(from_model.sample_lines, from_data.sample_lines)]:
            np.testing.assert_array_equal(a.get_ydata(), b.get_ydata())
        np.testing.assert_array_equal(band_vertices(from_model.band),
                                      band_vertices(from_data.band))

    def test_intersample_draws_exactly_its_arrays(self):
        prediction = OutputPrediction(time=0.2 * np.arange(12), mean=np.sin(np.arange(12.0)),
                                      std=np.full(12, 0.1), level=0.5,
                                      slow_index=np.arange(2, 12, 4),
                                      y_fast=np.cos(np.arange(12.0)), y_slow=np.ones(3))
        drawn = plot_intersample(prediction, window=(1, 9))
        np.testing.assert_array_equal(drawn.mean_line.get_xdata(), prediction.time[1:9])
        np.testing.assert_array_equal(drawn.mean_line.get_ydata(), prediction.mean[1:9])
        np.testing.assert_array_equal(drawn.fast_line.get_ydata(), prediction.y_fast[1:9])
        np.testing.assert_array_equal(drawn.slow_markers.get_xdata(), prediction.time[[2, 6]])
        vertices = band_vertices(drawn.band)
        assert vertices[:, 1].min() == pytest.approx(
            (prediction.mean - z_of(0.5) * 0.1)[1:9].min())

    def test_gof_summary_is_drawn_as_given(self):
        orders = np.array([10, 20, 30])
        gof = np.array([[90.0, 80.0, np.nan], [94.0, np.nan, np.nan], [92.0, 86.0, 70.0]])
        summary = GoFSummary.from_runs(orders, gof)
        np.testing.assert_allclose(summary.mean, np.nanmean(gof, axis=0))
        np.testing.assert_allclose(summary.std[:2], [np.std([90, 94, 92], ddof=1),
                                                     np.std([80, 86], ddof=1)])
        assert np.isnan(summary.std[2]) and summary.count.tolist() == [3, 2, 1]
        drawn = plot_gof_vs_order(summary, n_std=1.5)
        np.testing.assert_array_equal(drawn.line.get_ydata(), summary.mean)
        lower, _ = summary.band(1.5)
        assert band_vertices(drawn.band)[:, 1].min() == pytest.approx(np.nanmin(lower))
        with pytest.raises(ValueError, match="gof"):
            plot_gof_vs_order(summary, gof)


# ------------------------------------------------------------ compatibility
def test_no_module_imports_private_names_of_another():
    """The modules of this restructuring use only public names of each other."""
    files = [PACKAGE / "responses.py",
             PACKAGE / "cli.py", *sorted((PACKAGE / "plotting").glob("*.py")),
             *sorted((PACKAGE / "study").glob("*.py"))]
    for path in files:
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("gpmultirate"):
                private = [a.name for a in node.names if a.name.startswith("_")
                           and a.name != "__version__"]
                assert not private, f"{path.name} imports {private} from {node.module}"
