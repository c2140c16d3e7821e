"""A slow log beside the fast record: reading it, and the command line of a camera."""

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate.cli import main
from gpmultirate.io import DataFileError, SlowLog, read_slow_log
from gpmultirate.kernels import DC

T = 0.001
N = 120
P = 15


def _write(path, header, rows):
    lines = [",".join(header)] + [",".join(str(v) for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def _camera(tmp_path):
    """A fast input file and a camera log: frames off the ticks, exposure and latency."""
    rng = np.random.default_rng(1)
    u = rng.standard_normal(N)
    g = 0.8 ** np.arange(P) * np.cos(0.6 * np.arange(P))
    ticks = np.arange(2, N - 3, 3)
    times = ticks + rng.uniform(0.0, 1.0, ticks.shape[0])
    y = np.convolve(u, g)[:N][ticks] + 1e-2 * rng.standard_normal(ticks.shape[0])
    fast = _write(tmp_path / "fast.csv", ["u"], [[f"{v:.17g}"] for v in u])
    slow = _write(tmp_path / "camera.csv", ["t", "y"],
                  [[f"{t * T:.17g}", f"{v:.17g}"] for t, v in zip(times, y)])
    return u, y, times, fast, slow


def test_read_slow_log(tmp_path):
    _, y, times, _, slow = _camera(tmp_path)
    log = read_slow_log(slow, "t", "y", sample_time=T, n_samples=N, exposure=5e-4,
                        latency=2e-4)
    assert isinstance(log, SlowLog)
    np.testing.assert_allclose(log.sample_times, times, rtol=1e-12)
    np.testing.assert_array_equal(log.values, y)
    # exposure, latency and stamps in seconds, the units of the estimator's sample_time
    assert log.estimator_params == {"exposure": 5e-4, "latency": 2e-4}
    np.testing.assert_array_equal(log.fit_params["sample_times"], log.stamps)
    assert log.factor == 3 and log.offset is None
    assert "exposure 0.0005 s" in log.description
    np.testing.assert_array_equal(log.indices, np.floor(times))
    # stamps on the ticks stay on them, whatever the rounding of t / T
    on = _write(tmp_path / "on.csv", ["t"], [["0.003"], ["0.006"], ["0.009"]])
    stamps = read_slow_log(on, "t", sample_time=T, n_samples=N)
    np.testing.assert_array_equal(stamps.sample_times, [3.0, 6.0, 9.0])
    assert stamps.values is None


@pytest.mark.parametrize("rows, header, match", [
    ([["0.004", "1"], ["0.003", "2"]], ["t", "y"], "comes before stamp 1"),
    ([["0.003", "1"], ["0.003", "2"]], ["t", "y"], "repeats stamp 1"),
    ([["0.003", "1"], ["0.2", "2"]], ["t", "y"], "outside the record"),
    ([["-0.001", "1"], ["0.003", "2"]], ["t", "y"], "outside the record"),
    ([["0.003", "1"], ["late", "2"]], ["t", "y"], "'late' is not a number"),
    ([["0.003", "1"], ["0.004", "x"]], ["t", "y"], "'x' is not a number"),
    ([["0.003", "1"], ["", "2"]], ["t", "y"], "stamp 2 is missing"),
    ([["0.003", "1"], ["0.004", "2"]], ["time", "y"], "no column 't'"),
    ([["0.003", "1"], ["0.004", "2"]], ["t", "z"], "no column 'y'"),
])
def test_malformed_slow_logs(tmp_path, rows, header, match):
    path = _write(tmp_path / "bad.csv", header, rows)
    with pytest.raises(DataFileError, match=match):
        read_slow_log(path, "t", "y", sample_time=T, n_samples=N)


def test_slow_log_arguments(tmp_path):
    _, _, _, _, slow = _camera(tmp_path)
    with pytest.raises(ValueError, match="sample_time"):
        read_slow_log(slow, "t", "y", sample_time=0.0, n_samples=N)
    with pytest.raises(ValueError, match="exposure"):
        read_slow_log(slow, "t", "y", sample_time=T, n_samples=N, exposure=-1.0)


@pytest.mark.slow
def test_fit_and_predict_a_camera_from_the_command_line(tmp_path, capsys):
    u, y, times, fast, slow = _camera(tmp_path)
    out = tmp_path / "fit"
    argv = ["fit", str(fast), "--input", "u", "--sample-time", str(T), "--slow", str(slow),
            "--output", "y", "--time", "t", "--exposure", "0.0005", "--latency", "0.0002",
            "--order", str(P), "--out", str(out)]
    assert main(argv) == 0
    written = sorted(p.name for p in out.iterdir())
    assert {"model.npz", "summary.json", "summary.md", "intersample.png", "bode.png"} <= set(written)
    # the same fit through the library: the summary's evidence is its evidence
    import json
    summary = json.loads((out / "summary.json").read_text())
    model = gm.FIRGaussianProcess(order=P, sample_time=T, exposure=5e-4, latency=2e-4).fit(
        u, y, sample_times=read_slow_log(slow, "t", sample_time=T, n_samples=N).stamps)
    assert np.isclose(summary["model"]["log_evidence"], model.log_marginal_likelihood_value_)
    assert "time stamps of their own" in summary["data"]["sampling"]


def test_predict_readings_at_given_instants(tmp_path, capsys):
    u, y, times, fast, slow = _camera(tmp_path)
    ticks = np.arange(0, N, 3)
    model = gm.FIRGaussianProcess(C(1.0) * DC(), order=P, sample_time=T, optimizer=None,
                                  noise_level=1e-4).fit(
        u, np.convolve(u, 0.8 ** np.arange(P))[:N][ticks], sample_indices=ticks)
    gm.save_model(model, tmp_path / "model.npz")
    target = tmp_path / "readings.csv"
    assert main(["predict", str(tmp_path / "model.npz"), str(fast), "--input", "u", "--slow",
                 str(slow), "--time", "t", "--out", str(target), "--quiet"]) == 0
    table = np.genfromtxt(target, delimiter=",", names=True)
    loaded = gm.load_model(tmp_path / "model.npz")
    mean, std = loaded.predict(u, return_std=True, sample_times=times * T)
    np.testing.assert_allclose(table["time"], times * T, rtol=1e-12)
    np.testing.assert_allclose(table["y"], mean, rtol=1e-9)
    np.testing.assert_allclose(table["y_std"], std, rtol=1e-9)


@pytest.mark.parametrize("rows, match", [
    ([["0.004", "1"], ["0.003", "2"]], "comes before"),
    ([["0.003", "1"], ["0.003", "2"]], "repeats"),
    ([["0.003", "1"], ["0.5", "2"]], "outside the record"),
    ([["0.003", "1"], ["0.004", "two"]], "not a number"),
])
def test_malformed_slow_file_is_one_line_and_writes_nothing(tmp_path, capsys, rows, match):
    _, _, _, fast, _ = _camera(tmp_path)
    slow = _write(tmp_path / "bad.csv", ["t", "y"], rows)
    out = tmp_path / "fit"
    with pytest.raises(SystemExit) as exit_:
        main(["fit", str(fast), "--input", "u", "--sample-time", str(T), "--slow", str(slow),
              "--output", "y", "--time", "t", "--out", str(out), "--quiet"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and match in err and "bad.csv" in err
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize("extra, match", [
    (["--time", "t"], "--slow/--time"),
    (["--slow", "camera.csv"], "--slow/--time"),
    (["--exposure", "0.001"], "only with a slow log"),
])
def test_slow_options_belong_together(tmp_path, capsys, extra, match):
    _, _, _, fast, _ = _camera(tmp_path)
    with pytest.raises(SystemExit) as exit_:
        main(["fit", str(fast), "--input", "u", "--output", "y", "--out",
              str(tmp_path / "fit"), *extra])
    assert exit_.value.code == 2 and match in capsys.readouterr().err


def test_missing_time_column_on_the_command_line(tmp_path, capsys):
    _, _, _, fast, slow = _camera(tmp_path)
    with pytest.raises(SystemExit) as exit_:
        main(["fit", str(fast), "--input", "u", "--slow", str(slow), "--output", "y",
              "--time", "stamp", "--sample-time", str(T), "--out", str(tmp_path / "fit")])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and "no column 'stamp'" in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("option, value", [("--latency", "100"), ("--latency", "0.2"),
                                           ("--exposure", "100")])
def test_time_options_beyond_the_record_are_one_line(tmp_path, capsys, option, value):
    _, _, _, fast, slow = _camera(tmp_path)  # a record of 0.12 s
    out = tmp_path / "fit"
    with pytest.raises(SystemExit) as exit_:
        main(["fit", str(fast), "--input", "u", "--sample-time", str(T), "--slow", str(slow),
              "--output", "y", "--time", "t", option, value, "--order", str(P),
              "--out", str(out), "--quiet"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"argument {option}:" in err and " s" in err
    assert not out.exists() or not any(out.iterdir())
