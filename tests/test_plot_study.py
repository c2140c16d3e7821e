"""Tests of gpmultirate.plotting.plot_study on hand-made study results."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from gpmultirate.study import StudyResult, run_paper_study  # noqa: E402
from gpmultirate.plotting import GoFPlot, StudyPlot, plot_study  # noqa: E402

ORDERS = np.array([10, 20, 30])


@pytest.fixture(autouse=True)
def _no_show_and_close(monkeypatch):
    def forbidden(*args, **kwargs):
        raise AssertionError("plotting functions must never call plt.show()")

    monkeypatch.setattr(plt, "show", forbidden)
    yield
    plt.close("all")


@pytest.fixture
def result():
    ls = np.array([[80.0, np.nan, np.nan], [84.0, np.nan, np.nan], [82.0, np.nan, np.nan]])
    dc = np.array([[90.0, 95.0, 96.0], [92.0, 97.0, 97.0], [94.0, 93.0, 98.0]])
    pk = dc + 2.0
    gof = {"LS": ls, "DC": dc, "PK": pk}
    identifiable = {"LS": np.isfinite(ls), "DC": np.ones((3, 3), bool),
                    "PK": np.ones((3, 3), bool)}
    zeros = {m: np.zeros((3, 3)) for m in gof}
    return StudyResult(orders=ORDERS, methods=("LS", "DC", "PK"), gof=gof,
                       identifiable=identifiable, fit_seconds=zeros,
                       n_warnings={m: np.zeros((3, 3), int) for m in gof},
                       snr_db=np.full(3, 50.0), run_seconds=np.ones(3), random_state=0,
                       n_samples=60, factor=3)  # M = 20


def test_draws_mean_and_band_per_method_on_given_axes(result):
    fig, ax = plt.subplots()
    before = plt.get_fignums()
    drawn = plot_study(result, ax=ax)
    assert plt.get_fignums() == before  # no new figure
    assert isinstance(drawn, StudyPlot) and drawn.ax is ax
    assert list(drawn.plots) == ["LS", "DC", "PK"]
    for method, plot in drawn.plots.items():
        assert isinstance(plot, GoFPlot) and plot.line.get_label() == method
        np.testing.assert_array_equal(plot.line.get_xdata(), ORDERS)
        values = result.gof[method]
        expected = np.array([np.mean(c[np.isfinite(c)]) if np.isfinite(c).any() else np.nan
                             for c in values.T])
        np.testing.assert_allclose(plot.line.get_ydata(), expected)
    # band of DC at P = 10: mean 92 +- 2 * std(90, 92, 94) = 92 +- 4
    vertices = drawn.plots["DC"].band.get_paths()[0].vertices
    at_10 = vertices[np.isclose(vertices[:, 0], 10.0), 1]
    np.testing.assert_allclose([at_10.min(), at_10.max()], [88.0, 96.0])
    # colours and markers of the paper's Fig. 5
    assert drawn.plots["LS"].line.get_marker() == "o"
    assert drawn.plots["PK"].line.get_marker() == "^"
    assert float(drawn.slow_samples_line.get_xdata()[0]) == 20.0
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["LS", "DC", "PK"]


def test_methods_subset_n_std_and_overlay(result):
    drawn = plot_study(result, methods=["PK"], n_std=1)
    assert list(drawn.plots) == ["PK"]
    vertices = drawn.plots["PK"].band.get_paths()[0].vertices
    at_10 = vertices[np.isclose(vertices[:, 0], 10.0), 1]
    np.testing.assert_allclose([at_10.min(), at_10.max()], [92.0, 96.0])
    again = plot_study(result, ax=drawn.ax, methods="LS")
    assert again.slow_samples_line is None  # the P = M marker is drawn once
    assert len(drawn.ax.get_legend().get_texts()) == 2


def test_y_limits_keep_every_mean_in_view_in_any_overlay_order(result):
    for first, second in (("LS", "PK"), ("PK", "LS")):
        fig, ax = plt.subplots()
        plot_study(result, ax=ax, methods=first)
        plot_study(result, ax=ax, methods=second)
        bottom, top = ax.get_ylim()
        assert bottom < 82.0 - 2 * 2.0 and top >= 100.0  # LS at P = 10: 82 +- 2 std 2
        plt.close(fig)
    # an isolated order (LS has a value only at P = 10) gets an error bar
    drawn = plot_study(result, methods="LS")
    segments = drawn.errorbars["LS"].lines[2][0].get_segments()
    np.testing.assert_allclose(segments[0][:, 1], [78.0, 86.0])


def test_invalid_arguments(result):
    with pytest.raises(ValueError, match="methods"):
        plot_study(result, methods=["GP"])
    with pytest.raises(ValueError, match="methods"):
        plot_study(result, methods=[])
    with pytest.raises(ValueError, match="n_std"):
        plot_study(result, n_std=0)
    with pytest.raises(ValueError, match="result"):
        plot_study({"orders": ORDERS})
    with pytest.raises(ValueError, match="ax"):
        plot_study(result, ax="axes")


def test_smoke_with_a_real_study():
    study = run_paper_study(2, (5, 19, 20), "LS", n_samples=60, progress=False)
    drawn = plot_study(study)
    ydata = drawn.plots["LS"].line.get_ydata()
    assert np.isfinite(ydata[:2]).all() and np.isnan(ydata[2])
