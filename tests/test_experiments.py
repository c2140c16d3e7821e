"""Tests of gpmultirate.study on tiny studies (N = 60, M = 20), against numpy formulas."""

import csv
import math

import numpy as np
import pytest

import gpmultirate.study.runner as ex
from gpmultirate import FIRGaussianProcess
from gpmultirate.study import (
    StudyResult,
    paper_example,
    paper_kernels,
    run_paper_study,
    run_trial,
    simulate_run,
)

N, F, M, T = 60, 3, 20, 0.1
ORDERS = (5, 19, 20)  # 19 < M <= 20: the least-squares boundary
SEED = 3
TINY = {"n_samples": N, "progress": False}


@pytest.fixture(scope="module")
def study():
    return run_paper_study(2, ORDERS, ("LS", "DC"), random_state=SEED, n_jobs=1, **TINY)


def gof_formula(y, y_hat):
    return 100 * (1 - np.sum((y - y_hat) ** 2) / np.sum((y - np.mean(y)) ** 2))


def slow_regressor(u, order, factor):
    """Row m is [u(mF), u(mF - 1), ..., u(mF - P + 1)], zero before the record (eq. 8)."""
    rows = range(0, len(u), factor)
    return np.array([[u[m - i] if m - i >= 0 else 0.0 for i in range(order)] for m in rows])


# ------------------------------------------------------------------ kernels
def test_paper_kernels_have_the_papers_values_and_formula():
    kernels = paper_kernels(T)
    assert set(kernels) == {"DC", "PK"}
    assert kernels["DC"][1] == kernels["PK"][1] == 1e-5
    lags = np.array([[0.0], [1.0], [3.0], [7.0]])  # the paper's integer lags
    t, s = lags[:, 0][:, None], lags[:, 0][None, :]
    alpha, beta = np.exp(-0.5 * T), np.exp(-0.1 * T)
    dc = alpha ** ((t + s) / 2) * beta ** np.abs(t - s)  # eq. (16), lambda = 1
    np.testing.assert_allclose(kernels["DC"][0](lags), dc, rtol=1e-12)
    # eq. (18)-(19) in the paper's gamma form, sigma_1 = sigma_2 = 1: gamma1 = 1, gamma2 = 0
    pk = dc.copy()
    for hz in (0.4, 2.0):
        omega = 2 * np.pi * hz * T
        gamma1, gamma2 = 1.0, 0.0
        pk += alpha ** ((t + s) / 2) * (gamma1 * np.cos(omega * (t - s))
                                        + gamma2 * np.cos(omega * (t + s)))
    np.testing.assert_allclose(kernels["PK"][0](lags), pk, rtol=1e-12, atol=1e-15)


def test_paper_kernels_rejects_a_sample_time_putting_2hz_above_nyquist():
    with pytest.raises(ValueError, match="sample_time"):
        paper_kernels(0.25)
    with pytest.raises(ValueError, match="sample_time"):
        paper_kernels(-0.1)


# --------------------------------------------------------------------- data
def test_simulate_run_is_deterministic_and_matches_its_description():
    seed = np.random.SeedSequence(11)
    a, b = simulate_run(seed, n_samples=600), simulate_run(seed, n_samples=600)
    np.testing.assert_array_equal(a.y_slow, b.y_slow)  # the seed object is not consumed
    assert a.u.shape == a.u_val.shape == a.y_val.shape == (600,)
    for u in (a.u, a.u_val):
        assert np.sqrt(np.mean(u**2)) == pytest.approx(1.0)
        spectrum = np.abs(np.fft.rfft(u))
        np.testing.assert_allclose(spectrum[1:300], spectrum[1], rtol=1e-9)  # flat, all bins
        assert spectrum[0] < 1e-9 and spectrum[300] < 1e-9
    assert abs(np.corrcoef(a.u, a.u_val)[0, 1]) < 0.2  # independent phases
    np.testing.assert_array_equal(a.y_slow, a.y_fast_noisy[::3])
    np.testing.assert_allclose(a.y_val, a.system.simulate(a.u_val))
    assert 40 <= a.snr_db <= 60
    noise = a.y_fast_noisy - a.y_fast
    measured = 10 * np.log10(np.var(a.y_fast) / np.var(noise))
    assert measured == pytest.approx(a.snr_db, abs=1.0)  # 600 noise samples: ~0.3 dB spread
    # each run has its own perturbed system; the system does not depend on N
    other = simulate_run(np.random.SeedSequence(12), n_samples=60)
    assert not np.allclose(other.system.A, a.system.A)
    np.testing.assert_array_equal(simulate_run(seed, n_samples=60).system.A, a.system.A)


# -------------------------------------------------------------------- study
def test_shapes_masks_and_settings(study):
    assert study.methods == ("LS", "DC")
    np.testing.assert_array_equal(study.orders, ORDERS)
    assert study.n_runs == 2 and study.n_slow_samples == M and study.random_state == SEED
    for method in study.methods:
        for name in ("gof", "identifiable", "fit_seconds", "n_warnings"):
            assert getattr(study, name)[method].shape == (2, len(ORDERS))
        assert np.all(study.fit_seconds[method] >= 0)
    expected = np.broadcast_to(np.array(ORDERS) < M, (2, len(ORDERS)))
    np.testing.assert_array_equal(study.identifiable["LS"], expected)
    np.testing.assert_array_equal(np.isnan(study.gof["LS"]), ~expected)
    assert study.identifiable["DC"].all() and np.isfinite(study.gof["DC"]).all()
    assert study.snr_db.shape == (2,) and np.all((study.snr_db >= 40) & (study.snr_db <= 60))


def test_gof_is_least_squares_on_noise_free_validation_data(study):
    """Recompute the least-squares column from the run's data with numpy alone."""
    seeds = np.random.SeedSequence(SEED).spawn(2)
    for run in range(2):
        data = simulate_run(seeds[run], n_samples=N)
        for j, order in enumerate(ORDERS[:2]):
            phi = slow_regressor(data.u, order, F)
            g = np.linalg.lstsq(phi, data.y_slow, rcond=None)[0]
            y_hat = np.convolve(data.u_val, g)[:N]
            assert study.gof["LS"][run, j] == pytest.approx(gof_formula(data.y_val, y_hat),
                                                            rel=1e-8)
        assert study.snr_db[run] == data.snr_db


@pytest.mark.slow
def test_same_results_for_n_jobs_2_other_orders_and_methods_subset(study):
    """Run i depends only on (random_state, i): not on n_jobs, the grid or the methods."""
    other = run_paper_study(2, (19,), ("DC", "LS"), random_state=SEED, n_jobs=2, **TINY)
    np.testing.assert_array_equal(other.orders, [19])
    assert other.methods == ("DC", "LS")
    columns = [ORDERS.index(19)]
    for method in ("LS", "DC"):
        np.testing.assert_array_equal(other.gof[method], study.gof[method][:, columns])
    np.testing.assert_array_equal(other.snr_db, study.snr_db)
    ls_only = run_paper_study(2, (20, 19, 5), "LS", random_state=SEED, **TINY)
    assert ls_only.methods == ("LS",) and set(ls_only.gof) == {"LS"}
    np.testing.assert_array_equal(ls_only.gof["LS"], study.gof["LS"])


def test_random_state_reproduces_and_differs():
    first = run_paper_study(3, (5, 10), "LS", random_state=None, **TINY)
    again = run_paper_study(3, (5, 10), "LS", random_state=first.random_state, **TINY)
    np.testing.assert_array_equal(first.gof["LS"], again.gof["LS"])
    other = run_paper_study(3, (5, 10), "LS", random_state=first.random_state + 1, **TINY)
    assert not np.array_equal(first.gof["LS"], other.gof["LS"])
    # a SeedSequence object gives the same study every time it is passed
    seed = np.random.SeedSequence(5)
    a = run_paper_study(2, (5,), "LS", random_state=seed, **TINY)
    b = run_paper_study(2, (5,), "LS", random_state=seed, **TINY)
    np.testing.assert_array_equal(a.gof["LS"], b.gof["LS"])
    c = run_paper_study(2, (5,), "LS", random_state=5, **TINY)
    np.testing.assert_array_equal(a.gof["LS"], c.gof["LS"])


def test_only_the_full_order(study):
    result = run_paper_study(1, (N,), ("LS",), **TINY)
    assert result.gof["LS"].shape == (1, 1) and np.isnan(result.gof["LS"]).all()
    assert not result.identifiable["LS"].any()
    assert "| 60 | not identifiable |" in result.to_markdown()


def test_progress_lines_on_stderr(capsys):
    run_paper_study(3, (5,), "LS", n_samples=N, progress=True)
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert captured.out == ""
    assert [line.split(" (")[0] for line in lines] == [f"run {k}/3 done" for k in (1, 2, 3)]
    assert all(line.endswith(" s)") for line in lines)


def test_kernel_methods_use_the_paper_kernels_and_default_tuning(monkeypatch):
    """PK (and DC) are FIRGaussianProcess(kernel, factor, order, noise_level) as specified.

    A real PK fit takes seconds; the constructor arguments are recorded and the
    fit itself is made cheap by fixing the hyperparameters.
    """
    calls = []

    class Recording(FIRGaussianProcess):
        def fit(self, u, y_slow):
            calls.append(self.get_params(deep=False))
            self.optimizer = None
            return super().fit(u, y_slow)

    monkeypatch.setattr(ex, "FIRGaussianProcess", Recording)
    result = run_paper_study(1, (10, 60), ("PK", "DC"), **TINY)
    assert result.methods == ("PK", "DC") and np.isfinite(result.gof["PK"]).all()
    reference = paper_kernels(T)
    defaults = FIRGaussianProcess().get_params(deep=False)
    assert len(calls) == 4
    for params, (method, order) in zip(calls, [("PK", 10), ("PK", 60), ("DC", 10), ("DC", 60)]):
        assert params["kernel"].get_params() == reference[method][0].get_params()
        assert (params["factor"], params["order"], params["noise_level"]) == (F, order, 1e-5)
        for name in ("optimizer", "n_restarts_optimizer", "noise_level_bounds", "offset"):
            assert params[name] == defaults[name]


# ------------------------------------------------------------------ tables
def test_summary_matches_numpy(study):
    rows = study.summary()
    assert len(rows) == 2 * len(ORDERS)
    assert [(r["method"], r["order"]) for r in rows] == [
        (m, p) for m in ("LS", "DC") for p in ORDERS]
    for row in rows:
        column = study.gof[row["method"]][:, ORDERS.index(row["order"])]
        finite = column[np.isfinite(column)]
        assert row["n_ok"] == finite.size and row["n_runs"] == 2
        if finite.size:
            assert row["mean"] == pytest.approx(np.mean(finite), rel=1e-12)
            assert row["std"] == pytest.approx(np.std(finite, ddof=1), rel=1e-12)
        else:
            assert math.isnan(row["mean"]) and math.isnan(row["std"])
        assert row["identifiable"] == (row["method"] == "DC" or row["order"] < M)


def test_markdown_table(study):
    lines = study.to_markdown(digits=2).strip().splitlines()
    assert lines[0] == "| P | LS GoF [%] | DC GoF [%] |"
    assert len(lines) == 2 + len(ORDERS)
    for j, (order, line) in enumerate(zip(ORDERS, lines[2:])):
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert cells[0] == str(order)
        for method, cell in zip(("LS", "DC"), cells[1:]):
            values = study.gof[method][:, j]
            if method == "LS" and order >= M:
                assert cell == "not identifiable"
            else:
                assert cell == f"{np.mean(values):.2f} ± {np.std(values, ddof=1):.2f}"


def test_markdown_partial_and_single_run():
    result = StudyResult(
        orders=np.array([10]), methods=("DC",), gof={"DC": np.array([[90.0], [np.nan]])},
        identifiable={"DC": np.array([[True], [True]])}, fit_seconds={"DC": np.zeros((2, 1))},
        n_warnings={"DC": np.zeros((2, 1), dtype=int)}, snr_db=np.array([50.0, 45.0]),
        run_seconds=np.ones(2), random_state=0)
    assert "| 10 | 90.00 (1/2 runs) |" in result.to_markdown()


@pytest.mark.parametrize("values, cell", [
    ([80.0, 84.0], "82.00 ± 2.83"),
    ([99.51, 99.53], "99.520 ± 0.014"),  # std 0.0141: two significant digits need 3 decimals
    ([99.99960, 99.99968], "99.9996 ± 0.0001"),  # at most 4 decimals
])
def test_markdown_decimals_follow_the_spread(values, cell):
    result = StudyResult(
        orders=np.array([600]), methods=("PK",), gof={"PK": np.array(values)[:, None]},
        identifiable={"PK": np.ones((2, 1), bool)}, fit_seconds={"PK": np.zeros((2, 1))},
        n_warnings={"PK": np.zeros((2, 1), dtype=int)}, snr_db=np.array([50.0, 45.0]),
        run_seconds=np.ones(2), random_state=0)
    expected = f"| 600 | {cell} |"
    assert expected in result.to_markdown()


def test_csv_summary_and_runs(study, tmp_path):
    study.to_csv(tmp_path / "summary.csv")
    with open(tmp_path / "summary.csv", newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 2 * len(ORDERS)
    for row in rows:
        column = study.gof[row["method"]][:, ORDERS.index(int(row["order"]))]
        if np.isfinite(column).all():
            assert float(row["mean"]) == pytest.approx(np.mean(column), rel=1e-12)
            assert float(row["std"]) == pytest.approx(np.std(column, ddof=1), rel=1e-12)
        else:
            assert math.isnan(float(row["mean"]))
        assert int(row["n_ok"]) == np.isfinite(column).sum()

    study.to_csv(tmp_path / "runs.csv", runs=True)
    with open(tmp_path / "runs.csv", newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 2 * 2 * len(ORDERS)
    for row in rows:
        run, j = int(row["run"]), ORDERS.index(int(row["order"]))
        np.testing.assert_equal(float(row["gof"]), study.gof[row["method"]][run, j])
        assert row["identifiable"] == str(bool(study.identifiable[row["method"]][run, j]))
        assert float(row["snr_db"]) == study.snr_db[run]


def test_json_round_trip(study, tmp_path):
    study.to_json(tmp_path / "study.json")
    text = (tmp_path / "study.json").read_text()
    assert "NaN" not in text  # strict JSON
    back = StudyResult.from_json(tmp_path / "study.json")
    assert back.methods == study.methods and back.random_state == study.random_state
    np.testing.assert_array_equal(back.orders, study.orders)
    for name in ("gof", "identifiable", "fit_seconds", "n_warnings"):
        for method in study.methods:
            original, loaded = getattr(study, name)[method], getattr(back, name)[method]
            np.testing.assert_array_equal(loaded, original)
            assert loaded.dtype == original.dtype
    assert back.to_markdown() == study.to_markdown()
    with pytest.raises(ValueError, match="data"):
        StudyResult.from_dict({"format": "something else"})


# --------------------------------------------------------------- validation
@pytest.mark.parametrize("kwargs, name", [
    ({"n_runs": 0}, "n_runs"),
    ({"orders": (0, 10)}, "orders"),
    ({"orders": (61,)}, "orders"),
    ({"orders": ()}, "orders"),
    ({"orders": (10.5,)}, "orders"),
    ({"orders": (10, 10)}, "orders"),
    ({"methods": ("LS", "GP")}, "methods"),
    ({"methods": ()}, "methods"),
    ({"methods": ("LS", "LS")}, "methods"),
    ({"snr_db": (60.0, 40.0)}, "snr_db"),
    ({"snr_db": (np.nan, 40.0)}, "snr_db"),
    ({"snr_db": "high"}, "snr_db"),
    ({"factor": 0}, "factor"),
    ({"factor": 61}, "factor"),
    ({"n_jobs": 0}, "n_jobs"),
    ({"n_jobs": 1.5}, "n_jobs"),
    ({"n_samples": 2, "orders": (1,)}, "n_samples"),
    ({"sample_time": 0.0}, "sample_time"),
    ({"perturbation": 1.0}, "perturbation"),
    ({"random_state": -1}, "random_state"),
    ({"progress": "yes"}, "progress"),
])
def test_invalid_arguments_name_the_argument(kwargs, name):
    arguments = {"n_runs": 1, "orders": (10,), "methods": ("LS",), "n_samples": N,
                 "progress": False, **kwargs}
    with pytest.raises(ValueError, match=name):
        run_paper_study(**arguments)


# The study of Section 5 of M. van Haren, R. S. Smith, T. Oomen, "System
# Identification Beyond the Nyquist Frequency: A Kernel-Regularized Approach",
# Control Engineering Practice 164:106425 (2025): 100 Monte Carlo runs; N = 600
# fast samples, T = 0.1 s, every third sample kept (F = 3, M = 200); SNR drawn
# uniformly in [40, 60] dB; every parameter within 10 % of nominal; FIR orders
# P = 50, 100, ..., 600; least squares and the DC and PK kernel estimators.
# Written out here once, not derived from the library's constants.
PAPER_STUDY = {"n_runs": 100, "n_samples": 600, "factor": 3, "sample_time": 0.1,
               "snr_db": (40.0, 60.0), "perturbation": 0.1,
               "orders": [50, 100, 150, 200, 250, 300, 350, 400, 450, 500, 550, 600],
               "methods": ("LS", "DC", "PK")}
PAPER_CONFIG = {k: PAPER_STUDY[k]
                for k in ("n_samples", "factor", "sample_time", "snr_db", "perturbation")}


def test_default_study_runs_the_papers_configuration(monkeypatch):
    # run_paper_study() with no arguments: record what each run is asked to do
    calls = []

    def recording_trial(seed, orders, methods, *, run, **config):
        calls.append({"orders": np.asarray(orders).tolist(), "methods": tuple(methods),
                      "config": config})
        shape = np.shape(orders)
        return ex.TrialResult(
            run=run, gof={m: np.zeros(shape) for m in methods},
            identifiable={m: np.ones(shape, dtype=bool) for m in methods},
            fit_seconds={m: np.zeros(shape) for m in methods},
            n_warnings={m: np.zeros(shape, dtype=int) for m in methods},
            snr_db=50.0, seconds=0.0)

    monkeypatch.setattr(ex, "run_trial", recording_trial)
    study = run_paper_study(progress=False)
    assert len(calls) == PAPER_STUDY["n_runs"] == study.n_runs
    for call in calls:
        assert call["orders"] == PAPER_STUDY["orders"]
        assert call["methods"] == PAPER_STUDY["methods"]
        assert call["config"] == PAPER_CONFIG
    assert study.orders.tolist() == PAPER_STUDY["orders"]
    assert tuple(study.methods) == PAPER_STUDY["methods"]
    assert (study.n_samples, study.factor, study.sample_time, tuple(study.snr_range),
            study.perturbation) == tuple(PAPER_CONFIG.values())
    assert study.n_slow_samples == 200  # M = N / F


def test_default_trial_simulates_and_fits_the_papers_configuration(monkeypatch):
    # run_trial(seed) with no other arguments: the real simulation, fits recorded
    simulated, fitted = [], []

    def recording_simulation(seed, **config):
        data = simulate_run(seed, **config)
        simulated.append((config, data))
        return data

    def recording_fit(method, order, data):
        fitted.append((method, order))
        return None, 0.0, 0

    monkeypatch.setattr(ex, "simulate_run", recording_simulation)
    monkeypatch.setattr(ex, "fit_method", recording_fit)
    trial = run_trial(0)
    [(config, data)] = simulated
    assert config == PAPER_CONFIG
    assert data.u.shape == data.u_val.shape == (600,) and data.y_slow.shape == (200,)
    assert data.factor == 3 and data.sample_time == 0.1 and 40 <= data.snr_db <= 60
    assert fitted == [(m, p) for m in PAPER_STUDY["methods"] for p in PAPER_STUDY["orders"]]
    assert trial.run == 0 and sorted(trial.gof) == sorted(PAPER_STUDY["methods"])


# ------------------------------------------------------------------ example
def test_paper_example_picks_the_best_least_squares_order():
    example = paper_example(SEED, None, methods=("LS", "DC"), n_samples=N)
    assert example.order == N and sorted(example.models) == ["DC", "LS"]
    np.testing.assert_array_equal(example.ls_orders, [10])  # 10, 20, ... below M = 20
    example = paper_example(SEED, 30, methods=("LS", "DC"), ls_orders=range(2, 20, 3),
                            n_samples=N)
    assert example.order == 30 and example.models["DC"].coef_.shape == (30,)
    scores = [example.models["LS"].__class__(factor=F, order=int(p)).fit(
        example.data.u, example.data.y_slow).score(example.data.u_val, example.data.y_val)
        for p in example.ls_orders]
    np.testing.assert_allclose(example.ls_gof, scores)
    assert example.ls_order == example.ls_orders[int(np.argmax(scores))]
    assert example.models["LS"].coef_.shape == (example.ls_order,)
    data = example.data
    for method, model in example.models.items():
        assert example.gof[method] == pytest.approx(model.score(data.u_val, data.y_val))
    # the data are those of run 0 of the study with the same seed
    run0 = simulate_run(np.random.SeedSequence(SEED).spawn(1)[0], n_samples=N)
    np.testing.assert_array_equal(data.y_slow, run0.y_slow)
    assert example.true_impulse_response().shape == (30,)
    assert example.true_frequency_response().shape == (N // 2 + 1,)


def test_paper_example_arguments():
    example = paper_example(0, 20, ls_order=7, methods="LS", n_samples=N)
    assert list(example.models) == ["LS"] and example.ls_order == 7
    with pytest.raises(ValueError, match="ls_order"):
        paper_example(0, 20, ls_order=M, methods="LS", n_samples=N)
    with pytest.raises(ValueError, match="order"):
        paper_example(0, N + 1, methods="LS", n_samples=N)
    with pytest.raises(ValueError, match="methods"):
        paper_example(0, 20, methods=("XX",), n_samples=N)


@pytest.mark.slow
def test_rst_table_has_the_markdown_cells():
    from gpmultirate.study import run_paper_study

    result = run_paper_study(n_runs=2, orders=(10, 20), n_samples=60, progress=False)
    markdown_cells = [
        cell.strip()
        for line in result.to_markdown().splitlines()[2:]
        for cell in line.strip("|").split("|")
    ]
    rst_cells = [
        line.split("- ", 1)[1] for line in result.to_rst().splitlines()[3:] if "- " in line
    ][len(result.methods) + 1:]
    assert rst_cells == markdown_cells
