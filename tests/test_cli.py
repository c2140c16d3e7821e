"""Tests of the ``gpmultirate`` command on tiny configurations."""

import csv
import importlib.metadata
import runpy
import sys

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from gpmultirate.cli import build_parser, main  # noqa: E402
from gpmultirate.study import StudyResult  # noqa: E402

PNG = b"\x89PNG\r\n\x1a\n"
TINY = ["--runs", "1", "--n-samples", "60", "--orders", "10", "20", "--n-jobs", "1"]
FIGURES = ("gof_vs_order.png", "bode.png", "impulse_response.png", "intersample.png")
TABLES = ("study.csv", "study_runs.csv", "study.md", "study.rst", "study.json")
DEMO_OPTIONS = ("--runs", "--orders", "--methods", "--n-jobs", "--seed", "--output",
                "--no-figures", "--quiet", "--n-samples", "--factor", "--snr", "--example-order")


@pytest.mark.slow
def test_demo_writes_tables_and_figures(tmp_path, capsys):
    out = tmp_path / "results"
    argv = ["demo", *TINY, "--methods", "LS", "DC", "--output", str(out), "--quiet",
            "--example-order", "30"]
    assert main(argv) == 0
    assert plt.get_fignums() == []  # figures are not left open in pyplot
    captured = capsys.readouterr()
    assert captured.err == ""  # --quiet
    for name in TABLES:
        assert (out / name).stat().st_size > 0
    for name in FIGURES:
        assert (out / name).read_bytes()[:8] == PNG

    result = StudyResult.from_json(out / "study.json")
    assert result.n_runs == 1 and result.methods == ("LS", "DC")
    np.testing.assert_array_equal(result.orders, [10, 20])
    assert np.isnan(result.gof["LS"][0, 1])  # P = 20 = M
    table = result.to_markdown()
    assert table in captured.out  # the table printed is the one of the saved study
    assert table in (out / "study.md").read_text(encoding="utf-8")
    with open(out / "study.csv", newline="") as stream:
        rows = {(r["method"], int(r["order"])): r for r in csv.DictReader(stream)}
    assert float(rows[("DC", 20)]["mean"]) == pytest.approx(result.gof["DC"][0, 1])
    assert rows[("LS", 20)]["identifiable"] == "False"


def test_demo_progress_and_no_figures(tmp_path, capsys):
    assert main(["demo", *TINY, "--methods", "LS", "--output", str(tmp_path),
                 "--no-figures"]) == 0
    err = capsys.readouterr().err
    assert "run 1/1 done" in err and "wrote" in err
    assert "left" not in err  # no estimate after the last run
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(TABLES)


@pytest.mark.slow
def test_example1_writes_the_figure(tmp_path):
    assert main(["example1", "--output", str(tmp_path), "--n-samples", "120", "--quiet"]) == 0
    assert (tmp_path / "example1.png").read_bytes()[:8] == PNG


def test_help_is_short_and_each_command_documents_its_options(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    assert len(text.splitlines()) < 30
    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices
    assert set(commands) == {"demo", "design", "example1", "fit", "predict"}
    for name in commands:
        assert name in text
    for option in DEMO_OPTIONS:
        assert option in commands["demo"].format_help()
    # each command's help names every option it declares, found from the parser itself
    for name, sub in commands.items():
        with pytest.raises(SystemExit):
            main([name, "--help"])
        help_text = capsys.readouterr().out
        for action in sub._actions:
            for option in action.option_strings:
                assert option in help_text, (name, option)


@pytest.mark.parametrize("argv", [["fit", "data.csv", "--input", "u", "--output", "y",
                                   "--sample-tim", "0.1"],
                                  ["demo", "--run", "2"], ["fit", "--inp", "u"]])
def test_option_abbreviations_are_refused(argv, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    assert "unrecognized arguments" in capsys.readouterr().err


def test_help_loads_no_heavy_library():
    import subprocess
    import sys

    for argv in (["--help"], ["fit", "--help"], ["predict", "--help"]):
        code = ("import sys; from gpmultirate.__main__ import main\n"
                "try:\n    main(" + repr(argv) + ")\nexcept SystemExit:\n    pass\n"
                "print(sorted(m for m in ('numpy', 'scipy', 'sklearn', 'matplotlib', 'joblib') "
                "if m in sys.modules), file=sys.stderr)")
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              check=True)
        assert done.stderr.strip().splitlines()[-1] == "[]", (argv, done.stderr)


def test_light_constants_of_the_parser_match_the_library():
    from gpmultirate import arguments, report
    from gpmultirate.study import METHODS
    from gpmultirate.study.journal import JOURNAL_NAME

    assert arguments.METHODS == METHODS and arguments.JOURNAL_NAME == JOURNAL_NAME
    assert report.FIT_KERNELS == arguments.FIT_KERNELS


@pytest.mark.parametrize("argv", [
    [],
    ["unknown"],
    ["demo", "--bogus"],
    ["demo", "--runs", "0"],
    ["demo", "--runs", "two"],
    ["demo", "--orders", "0"],
    ["demo", "--orders", "700"],  # above the default N = 600
    ["demo", "--orders", "100", "100"],
    ["demo", "--methods", "GP"],
    ["demo", "--n-jobs", "0"],
    ["demo", "--seed", "-1"],
    ["demo", "--factor", "0"],
    ["demo", "--snr", "60", "40"],
    ["demo", "--snr", "nan", "40"],
    ["demo", "--n-samples", "60", "--example-order", "61"],
    ["example1", "--factor", "1"],
    ["example1", "--n-samples", "6", "--factor", "4"],
])
def test_bad_arguments_exit_with_status_2(argv, capsys, tmp_path):
    with pytest.raises(SystemExit) as exit_info:
        main([*argv, "--output", str(tmp_path)] if argv[:1] in (["demo"], ["example1"])
             else argv)
    assert exit_info.value.code == 2
    assert "error" in capsys.readouterr().err


def test_output_must_be_a_directory(tmp_path, capsys):
    target = tmp_path / "file.txt"
    target.write_text("x")
    with pytest.raises(SystemExit) as exit_info:
        main(["demo", *TINY, "--output", str(target)])
    assert exit_info.value.code == 2


def test_python_dash_m_runs_the_command(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["gpmultirate", "--version"])
    with pytest.raises(SystemExit) as exit_info:
        runpy.run_module("gpmultirate", run_name="__main__")
    assert exit_info.value.code == 0
    assert capsys.readouterr().out.startswith("gpmultirate ")


def test_console_script_is_declared():
    entry_points = importlib.metadata.entry_points(group="console_scripts")
    assert any(ep.name == "gpmultirate" and ep.value == "gpmultirate.__main__:main"
               for ep in entry_points)


# ------------------------------------------------------------------ progress
def test_demo_progress_shows_the_time_left(tmp_path, capsys):
    assert main(["demo", "--runs", "3", "--n-samples", "30", "--orders", "5", "--n-jobs", "1",
                 "--methods", "LS", "--output", str(tmp_path), "--no-figures"]) == 0
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith("run ")]
    assert len(lines) == 3
    assert all("left" in line for line in lines[:2]) and "left" not in lines[2]


def test_time_left_and_its_format():
    from gpmultirate.study.runner import format_duration, time_left

    # 4 of 10 tasks in 20 s: 5 s per task, 6 tasks to go
    assert time_left(20.0, 4, 10) == pytest.approx(30.0)
    assert time_left(20.0, 10, 10) == 0.0
    assert time_left(1.0, 0, 10) == float("inf")
    assert format_duration(59.4) == "59 s"
    assert format_duration(61) == "1 min 1 s"
    assert format_duration(3 * 3600 + 125) == "3 h 2 min"
    assert format_duration(float("inf")) == "unknown time"


# ---------------------------------------------------------------- fit, predict
FIT_FILES = ("model.npz", "bode.png", "impulse.png", "intersample.png", "residuals.png",
             "summary.json", "summary.md", "state_space.npz")
N_FAST, ORDER = 90, 30


def _system(seed=0, n_inputs=1):
    rng = np.random.default_rng(seed)
    lags = np.arange(ORDER)
    g = [0.8**lags * np.cos((0.7 + 0.3 * k) * lags) for k in range(n_inputs)]
    u = rng.standard_normal((N_FAST, n_inputs))
    y = sum(np.convolve(u[:, k], g[k])[:N_FAST] for k in range(n_inputs))
    return u, y + 1e-3 * rng.standard_normal(N_FAST)


def _write_csv(path, columns: dict) -> None:
    names = list(columns)
    with open(path, "w", encoding="utf-8") as stream:
        stream.write(",".join(names) + "\n")
        for row in zip(*columns.values()):
            stream.write(",".join("" if np.isnan(v) else repr(float(v)) for v in row) + "\n")


def _dense_posterior(model, u, indices, y):
    """Posterior mean, covariance and log evidence at lags 0..P-1 from the dense formulas."""
    P = model.coef_.shape[-1]
    K = model.kernel_(np.arange(P, dtype=float)[:, None])
    Phi = np.array([[u[n - i] if n - i >= 0 else 0.0 for i in range(P)] for n in indices])
    S = Phi @ K @ Phi.T + model.noise_level_ * np.eye(len(indices))
    gain = np.linalg.solve(S, Phi @ K).T
    mean = gain @ y
    cov = K - gain @ Phi @ K
    _, logdet = np.linalg.slogdet(S)
    evidence = -0.5 * y @ np.linalg.solve(S, y) - 0.5 * logdet - 0.5 * len(y) * np.log(2 * np.pi)
    return mean, cov, evidence


@pytest.mark.slow
def test_fit_on_irregular_samples_matches_the_dense_posterior(tmp_path, capsys):
    import json

    import gpmultirate as gm

    u, y_fast = _system()
    rng = np.random.default_rng(1)
    indices = np.sort(rng.choice(N_FAST, size=35, replace=False))
    y = np.full(N_FAST, np.nan)
    y[indices] = y_fast[indices]
    data = tmp_path / "data.csv"
    _write_csv(data, {"u": u[:, 0], "y": y})
    out = tmp_path / "fit"
    assert main(["fit", str(data), "--input", "u", "--output", "y", "--order", str(ORDER),
                 "--sample-time", "0.01", "--out", str(out), "--quiet"]) == 0
    assert capsys.readouterr().err == ""
    for name in FIT_FILES:
        assert (out / name).stat().st_size > 0
    for name in ("bode.png", "impulse.png", "intersample.png"):
        assert (out / name).read_bytes()[:8] == PNG
    assert sorted(p.name for p in out.iterdir() if p.name.startswith(".")) == []

    model = gm.load_model(out / "model.npz")
    np.testing.assert_array_equal(model.observation_.sample_indices, indices)
    assert model.sample_time == 0.01
    mean, cov, evidence = _dense_posterior(model, u[:, 0], indices, y_fast[indices])
    np.testing.assert_allclose(model.coef_, mean, rtol=1e-6, atol=1e-9)

    summary = json.loads((out / "summary.json").read_text())
    assert summary["data"]["n_slow_samples"] == 35 and summary["data"]["offset"] is None
    assert summary["model"]["log_evidence"] == pytest.approx(evidence, rel=1e-8)
    assert summary["model"]["noise_level"] == pytest.approx(model.noise_level_)
    assert summary["model"]["order"] == ORDER
    assert "log evidence" in (out / "summary.md").read_text()

    # predict: the convolution with the posterior mean, std from the dense covariance
    new_u = np.random.default_rng(2).standard_normal(50)
    new = tmp_path / "new.npz"
    np.savez(new, excitation=new_u)
    csv_out = tmp_path / "prediction.csv"
    assert main(["predict", str(out / "model.npz"), str(new), "--input", "excitation",
                 "--out", str(csv_out), "--quiet"]) == 0
    table = np.genfromtxt(csv_out, delimiter=",", names=True)
    assert table.dtype.names == ("index", "time", "y", "y_std")
    T = np.array([[new_u[n - i] if n - i >= 0 else 0.0 for i in range(ORDER)]
                  for n in range(50)])
    np.testing.assert_allclose(table["y"], T @ mean, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(table["y_std"], np.sqrt(np.diag(T @ cov @ T.T)), rtol=1e-5,
                               atol=1e-9)
    np.testing.assert_allclose(table["time"], 0.01 * np.arange(50))
    # existing outputs are kept unless --force
    with pytest.raises(SystemExit) as info:
        main(["predict", str(out / "model.npz"), str(new), "--input", "excitation",
              "--out", str(csv_out)])
    assert info.value.code == 2 and "--force" in capsys.readouterr().err
    assert main(["predict", str(out / "model.npz"), str(new), "--input", "excitation",
                 "--out", str(csv_out), "--force", "--quiet"]) == 0


@pytest.mark.slow
def test_fit_on_a_grid_with_missing_samples_uses_the_slow_rate(tmp_path):
    """Every third sample with gaps: the same model as fit(..., sample_indices=...)."""
    import json

    import gpmultirate as gm

    u, y_fast = _system(3)
    indices = np.setdiff1d(np.arange(1, N_FAST, 3), [7, 40, 41 + 2])
    y = np.full(N_FAST, np.nan)
    y[indices] = y_fast[indices]
    data = tmp_path / "data.csv"
    _write_csv(data, {"y": y, "u": u[:, 0]})
    out = tmp_path / "fit"
    assert main(["fit", str(data), "--input", "u", "--output", "y", "--order", str(ORDER),
                 "--out", str(out), "--quiet"]) == 0
    model = gm.load_model(out / "model.npz")
    reference = gm.FIRGaussianProcess(order=ORDER).fit(u[:, 0], y_fast[indices],
                                                       sample_indices=indices)
    np.testing.assert_allclose(model.coef_, reference.coef_, rtol=1e-5, atol=1e-8)
    assert model.observation_.slow_factor == 3  # the slow Nyquist frequency of the plots
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["data"]["factor"], summary["data"]["offset"]) == (3, 1)
    assert "3 missing" in summary["data"]["sampling"]  # rows 7, 40 and 43


@pytest.mark.slow
def test_fit_factor_offset_and_validation(tmp_path):
    import json

    import gpmultirate as gm

    u, y = _system(4)
    data = tmp_path / "data.npz"
    np.savez(data, u=u[:, 0], y=y)
    u_val, y_val = _system(5)
    val = tmp_path / "val.mat"
    scipy_io = pytest.importorskip("scipy.io")
    scipy_io.savemat(val, {"u": u_val[:, 0], "y": y_val})
    out = tmp_path / "fit"
    assert main(["fit", str(data), "--input", "u", "--output", "y", "--factor", "3",
                 "--offset", "2", "--order", str(ORDER), "--validate", str(val),
                 "--kernel", "tc", "--out", str(out), "--quiet"]) == 0
    model = gm.load_model(out / "model.npz")
    assert "TC" in str(model.kernel_)
    np.testing.assert_array_equal(model.y_slow_, y[2::3])
    summary = json.loads((out / "summary.json").read_text())
    prediction = np.convolve(u_val[:, 0], model.coef_)[:N_FAST]
    gof = 100 * (1 - np.sum((y_val - prediction) ** 2) / np.sum((y_val - y_val.mean()) ** 2))
    assert summary["validation"]["gof_percent"] == pytest.approx(gof, rel=1e-9)
    assert gof > 90


@pytest.mark.slow
def test_fit_two_inputs_and_other_kernels(tmp_path):
    import json

    import gpmultirate as gm

    u, y = _system(6, n_inputs=2)
    y_slow = np.where(np.arange(N_FAST) % 2 == 0, y, np.nan)
    data = tmp_path / "data.mat"
    import scipy.io

    scipy.io.savemat(data, {"U": u, "y": y_slow})
    for kernel in ("ss", "auto"):
        out = tmp_path / kernel
        assert main(["fit", str(data), "--input", "U:0", "U:1", "--output", "y", "--order",
                     str(ORDER), "--kernel", kernel, "--out", str(out), "--quiet"]) == 0
        model = gm.load_model(out / "model.npz")
        assert model.coef_.shape == (2, ORDER)
        summary = json.loads((out / "summary.json").read_text())
        assert summary["model"]["n_inputs"] == 2
        if kernel == "ss":
            assert str(model.kernel_).count("SS") == 2
    assert (tmp_path / "ss" / "bode.png").read_bytes()[:8] == PNG


@pytest.mark.slow
def test_fit_refuses_to_overwrite_and_force_replaces(tmp_path, capsys):
    u, y = _system(7)
    data = tmp_path / "data.csv"
    _write_csv(data, {"u": u[:, 0], "y": np.where(np.arange(N_FAST) % 3 == 0, y, np.nan)})
    out = tmp_path / "fit"
    out.mkdir()
    (out / "summary.md").write_text("mine")
    argv = ["fit", str(data), "--input", "u", "--output", "y", "--order", "10", "--out",
            str(out), "--quiet"]
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert "summary.md" in line and "--force" in line
    assert sorted(p.name for p in out.iterdir()) == ["summary.md"]
    assert (out / "summary.md").read_text() == "mine"
    assert main([*argv, "--force"]) == 0
    assert (out / "summary.md").read_text() != "mine"
    assert sorted(p.name for p in out.iterdir()) == sorted(FIT_FILES)


@pytest.mark.parametrize("extra, words", [
    (["--kernel", "pk"], "--kernel"),
    (["--order", "0"], "--order"),
    (["--order", "91"], "--order"),
    (["--order", "best"], "--order"),
    (["--tuning", "loo"], "--tuning"),
    (["--cv", "1"], "--cv"),
    (["--factor", "0"], "--factor"),
    (["--factor", "3", "--offset", "3"], "--offset"),
    (["--sample-time", "-1"], "--sample-time"),
    (["--sample-time", "nan"], "--sample-time"),
    (["--initial-conditions", "rest"], "--initial-conditions"),
    (["--input", "u", "u"], "--input"),
    (["--input", "y"], "--output"),
    (["--validate", "missing.csv"], "missing.csv"),
    (["--example", "robot-arm"], "--example"),
])
def test_fit_option_errors_are_one_line(extra, words, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    u, y = _system(8)
    _write_csv(tmp_path / "data.csv",
               {"u": u[:, 0], "y": np.where(np.arange(N_FAST) % 3 == 0, y, np.nan)})
    with pytest.raises(SystemExit) as info:
        main(["fit", "data.csv", "--input", "u", "--output", "y", "--out", "fit", *extra])
    assert info.value.code == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("gpmultirate fit: error: ") and words in line
    assert not (tmp_path / "fit").exists()


def test_validation_output_must_be_complete(tmp_path, capsys):
    u, y = _system(9)
    _write_csv(tmp_path / "d.csv", {"u": u[:, 0], "y": np.where(np.arange(N_FAST) % 3 == 0,
                                                                 y, np.nan)})
    with pytest.raises(SystemExit):
        main(["fit", str(tmp_path / "d.csv"), "--input", "u", "--output", "y", "--validate",
              str(tmp_path / "d.csv"), "--out", str(tmp_path / "fit")])
    (line,) = capsys.readouterr().err.splitlines()
    assert "d.csv" in line and "every row" in line
    assert not (tmp_path / "fit").exists()


@pytest.mark.parametrize("argv, words", [
    (["missing.npz", "data.csv", "--input", "u"], "missing.npz"),
    (["data.csv", "data.csv", "--input", "u"], "data.csv"),
    (["model.npz", "data.csv", "--input", "u", "v"], "--input"),
    (["model.npz", "data.csv", "--input", "w"], "no column"),
])
def test_predict_errors_are_one_line(argv, words, tmp_path, capsys, monkeypatch):
    import gpmultirate as gm

    monkeypatch.chdir(tmp_path)
    u, y = _system(10)
    _write_csv(tmp_path / "data.csv", {"u": u[:, 0], "v": u[:, 0]})
    gm.save_model(gm.FIRGaussianProcess(factor=3, order=10).fit(u[:, 0], y[::3]),
                  tmp_path / "model.npz")
    with pytest.raises(SystemExit) as info:
        main(["predict", *argv, "--out", "p.csv"])
    assert info.value.code == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("gpmultirate predict: error: ") and words in line
    assert not (tmp_path / "p.csv").exists()


def test_robot_arm_csv_is_the_robot_arm_every_third_sample():
    from gpmultirate.datasets import load_robot_arm, robot_arm_csv
    from gpmultirate.io import read_columns

    columns = read_columns(robot_arm_csv(), ["u", "y_slow"])
    data = load_robot_arm()
    np.testing.assert_array_equal(columns["u"], data.u)
    kept = np.arange(1024) % 3 == 0
    np.testing.assert_array_equal(columns["y_slow"][kept], data.y[kept])
    assert np.isnan(columns["y_slow"][~kept]).all()


@pytest.mark.slow
def test_fit_example_robot_arm(tmp_path, capsys):
    import json

    from gpmultirate.datasets import load_robot_arm

    out = tmp_path / "fit"
    data = load_robot_arm()
    val = tmp_path / "val.csv"
    _write_csv(val, {"u": data.u, "y_slow": data.y})
    assert main(["fit", "--example", "robot-arm", "--order", "300", "--validate", str(val),
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "validation fit" in printed and "(NRMSE; GoF" in printed
    summary = json.loads((out / "summary.json").read_text())
    assert summary["data"]["n_slow_samples"] == 342
    assert summary["validation"]["gof_percent"] > 80


@pytest.mark.slow
def test_fit_writes_the_state_space_when_the_model_has_one(tmp_path, monkeypatch):
    """With ``to_state_space`` (a shift register of the FIR coefficients here) the file holds
    its matrices, and simulating them gives back the impulse response."""
    import json

    from scipy import signal

    import gpmultirate as gm

    def to_state_space(self):
        g = np.asarray(self.coef_, dtype=float)
        P = g.shape[0]
        A = np.eye(P - 1, k=-1)
        B = np.eye(P - 1, 1)
        C = g[None, 1:]
        D = g[None, :1]
        return signal.StateSpace(A, B, C, D, dt=self.sample_time)

    monkeypatch.setattr(gm.FIRGaussianProcess, "to_state_space", to_state_space, raising=False)
    u, y = _system(11)
    data = tmp_path / "data.csv"
    _write_csv(data, {"u": u[:, 0], "y": np.where(np.arange(N_FAST) % 3 == 0, y, np.nan)})
    out = tmp_path / "fit"
    assert main(["fit", str(data), "--input", "u", "--output", "y", "--order", "12",
                 "--sample-time", "0.5", "--out", str(out), "--quiet"]) == 0
    with np.load(out / "state_space.npz", allow_pickle=False) as system:
        A, B, C, D, dt = (system[k] for k in ("A", "B", "C", "D", "dt"))
    assert float(dt) == 0.5 and A.shape == (11, 11)
    # the impulse response of (A, B, C, D), by direct recursion
    x, response = np.zeros((11, 1)), []
    for k in range(12):
        impulse = 1.0 if k == 0 else 0.0
        response.append((C @ x + D * impulse).item())
        x = A @ x + B * impulse
    model = gm.load_model(out / "model.npz")
    np.testing.assert_allclose(response, model.coef_, rtol=1e-12)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["state_space"]["order"] == 11
    assert not any("state_space" in note for note in summary["notes"])


def test_fit_out_must_be_a_directory(tmp_path, capsys):
    target = tmp_path / "file.txt"
    target.write_text("x")
    with pytest.raises(SystemExit) as info:
        main(["fit", "--example", "robot-arm", "--out", str(target)])
    assert info.value.code == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert "--out" in line and "not a directory" in line


@pytest.mark.slow
def test_fit_auto_order_by_cross_validation(tmp_path):
    import json

    import gpmultirate as gm

    u, y = _system(4)
    data = tmp_path / "data.npz"
    np.savez(data, u=u[:, 0], y=y)
    u_val, y_val = _system(5)
    val = tmp_path / "val.npz"
    np.savez(val, u=u_val[:, 0], y=y_val)
    out = tmp_path / "fit"
    assert main(["fit", str(data), "--input", "u", "--output", "y", "--factor", "3",
                 "--order", "auto", "--tuning", "cross_validation", "--cv", "4",
                 "--validate", str(val), "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    model = gm.load_model(out / "model.npz")
    selection = summary["order_selection"]
    assert selection["criterion"] == "cv_log_predictive"
    assert selection["orders"] == gm.estimators.auto_orders(N_FAST)
    best = selection["orders"][int(np.argmax(selection["score"]))]
    assert selection["best_order"] == best
    assert summary["model"]["order"] == best == model.coef_.shape[0]
    assert summary["model"]["tuning"] == "cross_validation"
    prediction = np.convolve(u_val[:, 0], model.coef_)[:N_FAST]
    fit = 100 * (1 - np.linalg.norm(y_val - prediction) / np.linalg.norm(y_val - y_val.mean()))
    assert summary["validation"]["fit_percent"] == pytest.approx(fit, rel=1e-9)
    assert "Order selection" in (out / "summary.md").read_text()
