"""The hold-out split of a single-rate record, and the real-data benchmark's evaluation of it."""

from __future__ import annotations

import importlib.util
import pathlib
import sys

import numpy as np
import pytest

import gpmultirate as gm
from gpmultirate.datasets import load_cd_player_arm, load_robot_arm
from gpmultirate.holdout import holdout_split

BENCHMARK = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "real_data.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("real_data_benchmark", BENCHMARK)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        del sys.modules[spec.name]


def fit_by_hand(y, y_pred):
    """MATLAB compare's fit and the paper's GoF, written out."""
    error = np.sqrt(np.sum((y - y_pred) ** 2))
    spread = np.sqrt(np.sum((y - np.mean(y)) ** 2))
    return 100 * (1 - error / spread), 100 * (1 - error**2 / spread**2)


class Replay:
    """A 'fitted model' whose output is given."""

    def __init__(self, output):
        self.output = np.asarray(output, dtype=float)
        self.seen = None

    def predict(self, u):
        self.seen = np.array(u, copy=True)
        return self.output


class KnownFIR:
    """A 'fitted model' with a given impulse response, simulated from rest."""

    def __init__(self, g):
        self.g = np.asarray(g, dtype=float)

    def predict(self, u):
        return np.convolve(u, self.g)[: len(u)]


# ------------------------------------------------------------------ the split
def test_split_by_hand():
    u = np.arange(10.0)
    y = 100.0 + np.arange(10.0) ** 2
    split = holdout_split(u, y, factor=3)
    # floor(2/3 * 10) = 6 estimation samples; slow output at fast 0, 3
    assert split.n_estimation == 6
    np.testing.assert_array_equal(split.u, u)
    np.testing.assert_array_equal(split.u_estimation, u[:6])
    np.testing.assert_array_equal(split.y_slow, [100.0, 109.0])
    np.testing.assert_array_equal(split.y_validation, [136.0, 149.0, 164.0, 181.0])
    assert split.factor == 3 and split.y_mean == 0.0
    np.testing.assert_array_equal(split.u_mean, [0.0])


def test_split_of_a_multiple_of_three_keeps_two_thirds():
    split = holdout_split(np.ones(300), np.arange(300.0), factor=4)
    assert split.n_estimation == 200
    np.testing.assert_array_equal(split.y_slow, np.arange(0.0, 200.0, 4.0))


def test_split_other_fraction_and_single_rate():
    split = holdout_split(np.ones(10), np.arange(10.0), factor=1, estimation_fraction=0.5)
    np.testing.assert_array_equal(split.y_slow, np.arange(5.0))
    np.testing.assert_array_equal(split.y_validation, np.arange(5.0, 10.0))


def test_center_subtracts_the_estimation_means():
    u = np.column_stack([np.arange(9.0), 10.0 + np.arange(9.0) ** 2])
    y = np.array([1.0, 5.0, 2.0, 7.0, 3.0, 9.0, 50.0, 60.0, 70.0])
    split = holdout_split(u, y, factor=2, center=True)
    # estimation: fast 0..5; inputs' means over them, output's over fast 0, 2, 4
    u_mean = [np.mean([0, 1, 2, 3, 4, 5]), 10.0 + np.mean([0, 1, 4, 9, 16, 25])]
    np.testing.assert_allclose(split.u_mean, u_mean)
    np.testing.assert_allclose(split.u, u - u_mean)
    assert split.y_mean == pytest.approx(2.0)
    np.testing.assert_allclose(split.y_slow, [-1.0, 0.0, 1.0])
    np.testing.assert_array_equal(split.y_validation, [50.0, 60.0, 70.0])  # not centred


def test_split_keeps_the_callers_arrays_and_returns_read_only_copies():
    u = np.arange(12.0)
    y = np.arange(12.0) ** 2
    u_before, y_before = u.copy(), y.copy()
    split = holdout_split(u, y, factor=2, center=True)
    np.testing.assert_array_equal(u, u_before)
    np.testing.assert_array_equal(y, y_before)
    assert u.flags.writeable and y.flags.writeable
    for array in (split.u, split.y_slow, split.y_validation, split.u_mean):
        assert not array.flags.writeable
        assert not np.shares_memory(array, u) and not np.shares_memory(array, y)


def test_split_shapes_follow_the_input():
    data = load_cd_player_arm()
    assert holdout_split(data.u, data.y[:, 0], 3).u.shape == (2048, 2)
    assert holdout_split(data.u[:, 0], data.y[:, 0], 3).u.shape == (2048,)
    assert holdout_split(data.u[:, :1], data.y[:, 0], 3).u.shape == (2048, 1)


@pytest.mark.parametrize("kwargs, match", [
    ({"u": np.ones(5), "y": np.ones(6)}, "y must have the length of u"),
    ({"y": np.ones((9, 2))}, "y must be 1-D"),
    ({"y": np.r_[np.ones(8), np.nan]}, "y must be finite"),
    ({"u": np.r_[np.ones(8), np.inf]}, "u must be finite"),
    ({"u": np.ones((9, 2, 1))}, "u must be 1-D"),
    ({"factor": 0}, "factor must be >= 1"),
    ({"factor": 2.5}, "factor must be an integer"),
    ({"estimation_fraction": 0.0}, "estimation_fraction must be a number in"),
    ({"estimation_fraction": 1.0}, "estimation_fraction must be a number in"),
    ({"estimation_fraction": True}, "estimation_fraction must be a number in"),
    ({"estimation_fraction": "2/3"}, "estimation_fraction must be a number in"),
    ({"estimation_fraction": 0.05}, "leaves 0 estimation"),
    ({"estimation_fraction": 0.95}, "and 1 validation"),
])
def test_split_rejects_bad_input(kwargs, match):
    arguments = {"u": np.arange(9.0), "y": np.arange(9.0) ** 2, "factor": 2, **kwargs}
    factor = arguments.pop("factor")
    with pytest.raises(ValueError, match=match):
        holdout_split(arguments.pop("u"), arguments.pop("y"), factor, **arguments)


# --------------------------------------------------------------- evaluation
def test_evaluate_scores_the_validation_part_by_hand():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(30)
    y = rng.standard_normal(30) + 3.0
    output = rng.standard_normal(30)
    split = holdout_split(u, y, factor=3, center=True)
    model = Replay(output)
    score = split.evaluate(model)
    np.testing.assert_array_equal(model.seen, u - u[:20].mean())  # the whole record
    y_pred = output[20:] + np.mean(y[:20:3])
    np.testing.assert_allclose(score.y_pred, y_pred)
    fit, gof = fit_by_hand(y[20:], y_pred)
    assert score.fit_percent == pytest.approx(fit, rel=1e-12)
    assert score.goodness_of_fit == pytest.approx(gof, rel=1e-12)


def test_evaluate_simulates_over_the_whole_record():
    # an FIR of 10 taps: the first validation outputs depend on estimation inputs
    rng = np.random.default_rng(1)
    g = 0.7 ** np.arange(10)
    u = rng.standard_normal(60)
    y = np.convolve(u, g)[:60]
    split = holdout_split(u, y, factor=2)
    assert split.evaluate(KnownFIR(g)).fit_percent == pytest.approx(100.0, abs=1e-9)
    # simulated from rest at the start of the validation part instead, it is not exact
    from_rest = np.convolve(u[40:], g)[:20]
    assert gm.fit_percent(y[40:], from_rest) < 99.0


def test_evaluate_rejects_a_prediction_of_the_wrong_shape():
    split = holdout_split(np.arange(9.0), np.arange(9.0) ** 2, factor=2)
    with pytest.raises(ValueError, match=r"one output per input sample, shape \(9,\)"):
        split.evaluate(Replay(np.zeros(8)))


# ------------------------------------------------- the benchmark's helper
def least_squares_by_hand(u, y, factor, order):
    """Centre, fit eq. (11) on the slow rows by lstsq, simulate the whole record, score."""
    n_est = 2 * len(u) // 3
    u_c = u - u[:n_est].mean()
    rows = np.arange(0, n_est, factor)
    y_slow = y[rows]
    y_mean = y_slow.mean()
    lags = rows[:, None] - np.arange(order)[None, :]
    phi = np.where(lags >= 0, u_c[np.clip(lags, 0, None)], 0.0)
    g = np.linalg.lstsq(phi, y_slow - y_mean, rcond=None)[0]
    y_pred = np.convolve(u_c, g)[: len(u)][n_est:] + y_mean
    return fit_by_hand(y[n_est:], y_pred)


def test_benchmark_evaluate_least_squares_on_a_slice(bench):
    data = load_robot_arm()
    u, y = data.u[:300], data.y[:300]
    ls = next(m for m in bench.METHODS if m.name == "LS")
    row = bench.evaluate(ls, u, y, factor=3, order=30)
    fit, gof = least_squares_by_hand(u, y, 3, 30)
    assert row["status"] == "ok"
    assert row["fit_percent"] == pytest.approx(fit, abs=1e-6)
    assert row["gof"] == pytest.approx(gof, abs=1e-6)
    assert (row["M"], row["order"], row["N estimation"], row["N validation"]) == (67, 30, 200, 100)
    assert row["time min"] <= row["time median"] <= row["time max"]


def test_benchmark_evaluate_reports_least_squares_not_identifiable(bench):
    data = load_robot_arm()
    ls = next(m for m in bench.METHODS if m.name == "LS")
    row = bench.evaluate(ls, data.u[:300], data.y[:300], factor=3, order=67)  # order = M
    assert row["status"] == "not identifiable"
    assert np.isnan(row["fit_percent"]) and np.isnan(row["gof"])


@pytest.mark.slow  # three fits of a two-input model: 2.6 s
def test_benchmark_evaluate_gaussian_process_on_a_slice(bench):
    data = load_cd_player_arm()
    u, y = data.u[:240], data.y[:240, 1]
    dc = next(m for m in bench.METHODS if m.name == "DC")
    row = bench.evaluate(dc, u, y, factor=3, order=40, repeats=2)
    # the same fit made here, scored by hand
    split = holdout_split(u, y, 3, center=True)
    model = dc.make(3, 40).fit(split.u_estimation, split.y_slow)
    y_pred = model.predict(split.u)[160:] + split.y_mean
    fit, gof = fit_by_hand(y[160:], y_pred)
    assert row["status"] == "ok" and row["n_inputs"] == 2
    assert row["fit_percent"] == pytest.approx(fit, abs=1e-9)
    assert row["gof"] == pytest.approx(gof, abs=1e-9)


def test_benchmark_order_grid_and_plan(bench):
    assert bench.order_grid(682) == (100, 200, 400, 682)
    assert bench.order_grid(1365) == (100, 200, 400, 800, 1365)
    assert bench.order_grid(100) == (100,)
    robot = bench.RECORDS[0]
    cells, fits = bench.plan([robot], bench.METHODS, (2, 3), orders=(50,))
    # orders 50 and N = 682; LS, DC, DC + resonances at both factors and both orders,
    # single-rate DC once per order, the default and the order selection once per factor
    assert len(cells) == 3 * 2 * 2 + 2 * 2 + 2 + 2
    assert len(fits) == 3 * 2 * 2 + 2 + 2 + 2
    by_name = {m.name: m for m in bench.METHODS}
    # the default order is not order N: the held-out check may cut it
    assert cells[robot, by_name["default"], 3, None] != cells[
        robot, by_name["DC + resonances"], 3, 682]
    assert cells[robot, by_name["single-rate DC"], 2, 50] == cells[
        robot, by_name["single-rate DC"], 3, 50]


def _row(method, factor, order, fit, fit_factor=None, status="ok"):
    return {"record": "robot arm", "method": method, "factor": factor,
            "fit factor": factor if fit_factor is None else fit_factor, "order": order,
            "requested order": order, "M": 10, "n_inputs": 1, "N estimation": 682,
            "N validation": 342, "status": status, "fit_percent": fit, "gof": fit,
            "time min": 1.0, "time median": 1.0, "time max": 1.0, "cpu median": 1.0,
            "warnings": 0, "resonances": ""}


def test_benchmark_summary_checks_the_targets(bench):
    robot = bench.RECORDS[:1]
    rows = [_row("DC", 3, 100, 80.0), _row("DC", 3, 682, 84.0),
            _row("LS", 3, 100, 70.0), _row("LS", 3, 682, np.nan, status="not identifiable"),
            _row("default", 3, 682, 82.5),
            _row("DC", 2, 682, 90.0), _row("LS", 2, 100, 89.0), _row("default", 2, 682, 88.5)]
    entries = {e["factor"]: e for e in bench.summary(rows, robot, (2, 3))}
    # F = 3: 82.5 >= 84 - 2 and >= 70; F = 2: 88.5 >= 90 - 2 but below LS's 89
    assert entries[3]["best DC"]["order"] == 682 and entries[3]["best LS"]["order"] == 100
    assert entries[3]["within 2 of DC"] and entries[3]["not below LS"]
    assert entries[2]["within 2 of DC"] and not entries[2]["not below LS"]
    rows.append(_row("default", 4, 682, 50.0))
    rows.append(_row("DC", 4, 682, 52.1))
    entry = bench.summary(rows, robot, (4,))[0]
    assert not entry["within 2 of DC"] and entry["not below LS"]  # no LS at F = 4


def test_benchmark_tables_round_trip_through_csv(bench, tmp_path):
    rows = [_row("DC", 3, 100, 80.0), _row("single-rate DC", 3, 100, 85.0, fit_factor=1),
            _row("LS", 3, 100, np.nan, status="not identifiable")]
    first = tmp_path / "first"
    bench.report(rows, first, bench.RECORDS[:1], bench.METHODS, (3,))
    second = tmp_path / "second"
    bench.report([_row("DC", 2, 100, 70.0), _row("DC", 3, 100, 1.0)], second,
                 bench.RECORDS[:1], bench.METHODS, (2, 3))
    merged = bench.read_rows([first / "real_data.csv", second / "real_data.csv"])
    cells = {(r["method"], r["factor"]): r for r in merged}
    assert len(merged) == 5  # the repeated DC cell at F = 3 kept once, from the first file
    assert cells["DC", 3]["fit_percent"] == 80.0 and cells["DC", 2]["fit_percent"] == 70.0
    assert cells["single-rate DC", 2]["fit_percent"] == 85.0  # one fit, every factor
    assert cells["LS", 3]["status"] == "not identifiable" and np.isnan(cells["LS", 3]["gof"])
    text = (first / "real_data_results.rst").read_text()
    assert "not identifiable" in text and "80.0 / 80.0" in text
