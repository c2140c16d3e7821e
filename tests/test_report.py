"""The library functions behind ``gpmultirate fit`` and ``predict``: the slow samples of a
column, the fit report, the state-space file, the prediction table and the writers."""

import io
import json
import os
from pathlib import Path

import numpy as np
import pytest
from scipy import signal

import gpmultirate as gm
from gpmultirate.export import load_state_space, save_state_space
from gpmultirate.io import (
    DataFileError,
    check_folder,
    read_record,
    read_slow_samples,
    write_file,
    write_folder,
)
from gpmultirate.report import FitReport, fit_files, fit_report, prediction_csv

REFERENCE = Path(__file__).parent / "data" / "cli_reference"
N_FAST, ORDER = 90, 30


def _system(seed):
    # the data of tests/test_cli.py, from which the reference files were written
    rng = np.random.default_rng(seed)
    lags = np.arange(ORDER)
    g = 0.8**lags * np.cos(0.7 * lags)
    u = rng.standard_normal(N_FAST)
    return u, np.convolve(u, g)[:N_FAST] + 1e-3 * rng.standard_normal(N_FAST)


def _write_csv(path, columns):
    with open(path, "w", encoding="utf-8") as stream:
        stream.write(",".join(columns) + "\n")
        for row in zip(*columns.values()):
            stream.write(",".join("" if np.isnan(v) else repr(float(v)) for v in row) + "\n")


# ------------------------------------------------------------ read_slow_samples
def test_slow_samples_on_a_grid_with_gaps():
    y = np.full(20, np.nan)
    rows = [2, 5, 8, 11, 17]  # every third row from 2; row 14 is missing
    y[rows] = [1.0, 2.0, 3.0, 4.0, 5.0]
    original = y.copy()
    samples = read_slow_samples(y)
    np.testing.assert_array_equal(y, original)  # the caller's array is not touched
    assert (samples.factor, samples.offset, samples.n_samples) == (3, 2, 20)
    np.testing.assert_array_equal(samples.indices, rows)
    # the grid 2, 5, ..., 17 by hand
    np.testing.assert_array_equal(samples.y_slow, [1.0, 2.0, 3.0, 4.0, np.nan, 5.0])
    assert samples.n_missing == 1 and samples.uniform
    assert samples.estimator_params == {"factor": 3, "offset": 2}
    assert samples.fit_params == {}
    assert samples.description == "one sample in 3, from row 2, 1 missing"


def test_slow_samples_at_irregular_instants():
    y = np.full(20, np.nan)
    y[[0, 3, 4, 9, 12]] = 1.0
    samples = read_slow_samples(list(y))
    assert samples.offset is None and not samples.uniform and samples.n_missing == 0
    assert samples.factor == 3  # median of the spacings 3, 1, 5, 3
    np.testing.assert_array_equal(samples.fit_params["sample_indices"], [0, 3, 4, 9, 12])
    np.testing.assert_array_equal(samples.y_slow, np.ones(5))
    assert samples.estimator_params == {}
    assert samples.description == "irregular instants, median spacing 3"


def test_slow_samples_with_factor_and_offset_keep_those_rows():
    y = np.arange(10.0)
    y[4] = np.nan
    samples = read_slow_samples(y, factor=2, offset=0)
    np.testing.assert_array_equal(samples.indices, [0, 2, 6, 8])
    np.testing.assert_array_equal(samples.y_slow, [0.0, 2.0, np.nan, 6.0, 8.0])
    single = read_slow_samples(y[:3], offset=0)  # factor 1
    assert single.factor == 1 and single.n_missing == 0


@pytest.mark.parametrize("column, kwargs, words", [
    (np.ones((3, 2)), {}, "one-dimensional"),
    ([1.0, np.inf], {}, "row 1"),
    ([np.nan, np.nan], {}, "no measured"),
    ([1.0, np.nan, np.nan], {"factor": 2, "offset": 1}, "at the kept rows"),
    ([1.0, 2.0], {"factor": 2, "offset": 2}, "offset must lie in 0..factor-1"),
    ([1.0, 2.0], {"factor": 5, "offset": 3}, "below the 2 rows"),
    ([1.0, 2.0], {"factor": 1.5}, "factor must be an integer"),
    ([1.0, 2.0], {"factor": 0}, "factor must be at least 1"),
    ([1.0, 2.0], {"offset": -1}, "offset must be at least 0"),
])
def test_slow_samples_errors_name_the_argument(column, kwargs, words):
    with pytest.raises(ValueError, match=words):
        read_slow_samples(column, **kwargs)


def test_slow_samples_give_the_fit_of_sample_indices():
    u, y = _system(3)
    rows = np.setdiff1d(np.arange(1, N_FAST, 3), [7, 40])
    column = np.full(N_FAST, np.nan)
    column[rows] = y[rows]
    samples = read_slow_samples(column)
    model = gm.FIRGaussianProcess(order=ORDER, **samples.estimator_params).fit(
        u, samples.y_slow, **samples.fit_params)
    reference = gm.FIRGaussianProcess(order=ORDER).fit(u, y[rows], sample_indices=rows)
    np.testing.assert_allclose(model.coef_, reference.coef_, rtol=1e-5, atol=1e-8)


# ------------------------------------------------------------------- read_record
def test_read_record(tmp_path):
    path = tmp_path / "d.csv"
    path.write_text("a,b,y\n1,2,3\n4,5,\n")
    u, y = read_record(path, ["a", "b"], "y")
    np.testing.assert_array_equal(u, [[1.0, 2.0], [4.0, 5.0]])
    np.testing.assert_array_equal(y, [3.0, np.nan])
    u, none = read_record(path, ["a"])
    assert none is None and u.shape == (2,)
    with pytest.raises(DataFileError, match="row 1; the output of validation data"):
        read_record(path, ["a"], "y", complete=True)
    path.write_text("u,y\n1,3\n,4\n")
    with pytest.raises(DataFileError, match="input column 'u' has a missing value"):
        read_record(path, ["u"], "y")


# -------------------------------------------------------------------- the report
def _tokens_match(text, reference):
    """Equal text, with numbers equal to 6 digits (the last digits depend on the BLAS)."""
    def tokens(value):
        return value.replace("(", " ").replace(")", " ").replace("=", " ").replace(
            ",", " ").split()

    got, expected = tokens(text), tokens(reference)
    assert len(got) == len(expected)
    for a, b in zip(got, expected):
        try:
            assert float(a) == pytest.approx(float(b), rel=1e-6, abs=1e-12), (a, b)
        except ValueError:
            assert a == b


def _plain_match(got, expected):
    if isinstance(expected, dict):
        assert list(got) == list(expected)
        for key in expected:
            _plain_match(got[key], expected[key])
    elif isinstance(expected, list):
        assert len(got) == len(expected)
        for a, b in zip(got, expected):
            _plain_match(a, b)
    elif isinstance(expected, float):
        assert got == pytest.approx(expected, rel=1e-6, abs=1e-12)
    else:
        assert got == expected


@pytest.mark.slow
@pytest.mark.parametrize("case", ["grid", "irregular"])
def test_fit_files_equal_what_the_command_wrote(case, tmp_path):
    """The library gives the files the command line wrote before it was thinned."""
    u, y = _system(3)
    if case == "grid":
        rows = np.setdiff1d(np.arange(1, N_FAST, 3), [7, 40, 43])
        kernel, kernel_option, sample_time = None, "dc", 0.01
    else:
        rows = np.sort(np.random.default_rng(1).choice(N_FAST, size=35, replace=False))
        kernel_option, sample_time = "tc", 1.0
        from sklearn.gaussian_process.kernels import ConstantKernel

        kernel = ConstantKernel(1.0, (1e-8, 1e8)) * gm.kernels.TC()
    column = np.full(N_FAST, np.nan)
    column[rows] = y[rows]
    _write_csv(tmp_path / "data.csv", {"u": u, "y": column})
    u, column = read_record(tmp_path / "data.csv", ["u"], "y")
    samples = read_slow_samples(column)
    model = gm.FIRGaussianProcess(kernel=kernel, order=ORDER, sample_time=sample_time,
                                  **samples.estimator_params)
    model.fit(u, samples.y_slow, **samples.fit_params)
    validation = None
    if case == "grid":
        u_val, y_val = _system(5)
        _write_csv(tmp_path / "val.csv", {"u": u_val, "y": y_val})
        validation = read_record(tmp_path / "val.csv", ["u"], "y", complete=True)
    files, report = fit_files(model, u, samples, file=f"DATA/{case}.csv", inputs=["u"],
                              output="y", validation=validation,
                              validation_file="DATA/val.csv" if validation else None,
                              kernel_option=kernel_option)
    expected = json.loads((REFERENCE / f"{case}_summary.json").read_text())
    _plain_match(json.loads(files["summary.json"]), expected)
    _tokens_match(files["summary.md"].decode(),
                  (REFERENCE / f"{case}_summary.md").read_text())
    assert FitReport.from_dict(json.loads(files["summary.json"])) == report
    with np.load(io.BytesIO(files["state_space.npz"])) as got, \
            np.load(REFERENCE / f"{case}_state_space.npz") as reference:
        assert sorted(got.files) == sorted(reference.files)
        # a realization is unique up to a change of state coordinates: compare Markov
        # parameters C A^k B and D
        for k in range(ORDER):
            markov = [arrays["C"] @ np.linalg.matrix_power(arrays["A"], k) @ arrays["B"]
                      for arrays in (got, reference)]
            np.testing.assert_allclose(*markov, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(got["D"], reference["D"], rtol=1e-6, atol=1e-12)
        assert float(got["dt"]) == float(reference["dt"]) == sample_time
    assert files["bode.png"][:8] == b"\x89PNG\r\n\x1a\n"
    assert gm.load_model(io.BytesIO(files["model.npz"])).coef_.shape == (ORDER,)


def test_fit_report_numbers_are_the_closed_forms():
    u, y = _system(4)
    model = gm.FIRGaussianProcess(order=ORDER, factor=3, offset=2).fit(u, y[2::3])
    u_val, y_val = _system(5)
    report = fit_report(model, validation=(u_val, y_val))
    # the log evidence: the dense Gaussian density of the slow samples
    rows = np.arange(2, N_FAST, 3)
    K = model.kernel_(np.arange(ORDER, dtype=float)[:, None])
    Phi = np.array([[u[n - i] if n - i >= 0 else 0.0 for i in range(ORDER)] for n in rows])
    S = Phi @ K @ Phi.T + model.noise_level_ * np.eye(rows.size)
    _, logdet = np.linalg.slogdet(S)
    evidence = -0.5 * (y[2::3] @ np.linalg.solve(S, y[2::3]) + logdet
                       + rows.size * np.log(2 * np.pi))
    assert report.model["log_evidence"] == pytest.approx(evidence, rel=1e-8)
    # goodness of fit and MATLAB's fit percentage of the convolution with coef_
    prediction = np.convolve(u_val, model.coef_)[:N_FAST]
    error, spread = y_val - prediction, y_val - y_val.mean()
    assert report.validation["gof_percent"] == pytest.approx(
        100 * (1 - error @ error / (spread @ spread)), rel=1e-10)
    assert report.validation["fit_percent"] == pytest.approx(
        100 * (1 - np.linalg.norm(error) / np.linalg.norm(spread)), rel=1e-10)
    assert report.data == {"file": None, "inputs": ["u"], "output": "y",
                           "n_samples": N_FAST, "n_slow_samples": 30,
                           "sampling": "one sample in 3, from row 2", "factor": 3,
                           "offset": 2, "sample_time": 1.0}
    assert report.model["noise_level"] == model.noise_level_
    assert report.state_space is None and "resonances" not in report.to_dict()
    markdown = report.to_markdown()
    assert f"log evidence: {evidence:.6g}" in markdown and "## Validation" in markdown


def test_report_of_a_model_that_is_not_fitted_is_refused():
    from sklearn.exceptions import NotFittedError

    with pytest.raises(NotFittedError):
        fit_report(gm.FIRGaussianProcess())


# --------------------------------------------------------------- the state space
def _markov(system, n):
    A, B, C, D = (np.asarray(getattr(system, name)) for name in "ABCD")
    x, out = np.zeros((A.shape[0], B.shape[1])), []
    for k in range(n):  # the response to a unit impulse, by direct recursion
        impulse = np.eye(B.shape[1]) if k == 0 else np.zeros((B.shape[1], B.shape[1]))
        out.append(C @ x + D @ impulse)
        x = A @ x + B @ impulse
    return np.array(out)


def test_state_space_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    A = 0.5 * rng.standard_normal((3, 3)) / 3
    system = signal.StateSpace(A, rng.standard_normal((3, 2)), rng.standard_normal((1, 3)),
                               rng.standard_normal((1, 2)), dt=0.25)
    path = tmp_path / "ss.npz"
    save_state_space(system, path)
    loaded = load_state_space(path)
    assert loaded.dt == 0.25
    np.testing.assert_array_equal(_markov(loaded, 8), _markov(system, 8))
    with np.load(path, allow_pickle=False) as arrays:  # readable without gpmultirate
        assert sorted(arrays.files) == ["A", "B", "C", "D", "dt"]
    with pytest.raises(FileExistsError):
        save_state_space(system, path, overwrite=False)
    assert [p.name for p in tmp_path.iterdir()] == ["ss.npz"]  # no temporary left


def test_state_space_of_an_estimator_and_its_sample_time():
    u, y = _system(6)
    model = gm.FIRGaussianProcess(order=ORDER, factor=3, sample_time=0.5).fit(u, y[::3])
    buffer = io.BytesIO()
    save_state_space(model, buffer)
    loaded = load_state_space(io.BytesIO(buffer.getvalue()))
    assert loaded.dt == 0.5
    # the reduced model's impulse response is close to the FIR it reduces
    np.testing.assert_allclose(_markov(loaded, ORDER)[:, 0, 0], model.coef_, atol=0.05)
    unit = signal.StateSpace([[0.0]], [[1.0]], [[1.0]], [[0.0]], dt=True)
    buffer = io.BytesIO()
    save_state_space(unit, buffer)
    assert load_state_space(io.BytesIO(buffer.getvalue())).dt == 1.0


@pytest.mark.parametrize("system, words", [
    (signal.StateSpace([[0.0]], [[1.0]], [[1.0]], [[0.0]]), "discrete-time"),
    (object(), "matrices A, B, C and D"),
    (signal.StateSpace([[np.nan]], [[1.0]], [[1.0]], [[0.0]], dt=1), "finite"),
])
def test_state_space_errors(system, words):
    with pytest.raises(ValueError, match=words):
        save_state_space(system, io.BytesIO())


# ------------------------------------------------------------ the prediction table
def test_prediction_csv_is_the_convolution_with_its_std():
    u, y = _system(7)
    model = gm.FIRGaussianProcess(order=ORDER, factor=3, sample_time=0.1).fit(u, y[::3])
    new = np.random.default_rng(8).standard_normal(25)
    table = np.genfromtxt(io.StringIO(prediction_csv(model, new)), delimiter=",", names=True)
    assert table.dtype.names == ("index", "time", "y", "y_std")
    np.testing.assert_allclose(table["y"], np.convolve(new, model.coef_)[:25], rtol=1e-9,
                               atol=1e-12)
    _, std = model.predict(new, return_std=True)
    np.testing.assert_allclose(table["y_std"], std, rtol=1e-12)
    np.testing.assert_allclose(table["time"], 0.1 * np.arange(25))


def test_prediction_csv_refuses_non_finite_values(monkeypatch):
    u, y = _system(7)
    model = gm.LeastSquaresFIR(order=5).fit(u, y)
    monkeypatch.setattr(model, "predict",
                        lambda u, return_std=False: (np.ones(3), np.array([1.0, np.nan, 1.0])))
    with pytest.raises(ValueError, match="not finite"):
        prediction_csv(model, np.ones(3))


# ------------------------------------------------------------------------ writers
def test_write_folder_replaces_as_a_whole(tmp_path):
    folder = tmp_path / "out"
    write_folder(folder, {"a": b"1", "b": b"2"})
    with pytest.raises(FileExistsError, match="exists"):
        write_folder(folder, {"a": b"3"}, replaceable=["b"])
    with pytest.raises(FileExistsError, match="b is not a result file"):
        write_folder(folder, {"a": b"3"}, overwrite=True)
    write_folder(folder, {"a": b"3"}, overwrite=True, replaceable=["b"])
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == {"a": b"3"}
    (folder / "mine").write_bytes(b"x")
    with pytest.raises(FileExistsError, match="may hold only results"):
        write_folder(folder, {"a": b"4"}, overwrite=True)
    assert (folder / "a").read_bytes() == b"3"
    with pytest.raises(ValueError, match="plain file names"):
        write_folder(tmp_path / "other", {"../a": b""})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    mode = os.stat(folder).st_mode & 0o777
    assert mode == 0o777 & ~_umask()


def _umask():
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def test_check_folder_and_write_file(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(FileExistsError, match="not a directory"):
        check_folder(tmp_path / "file", ["a"])
    check_folder(tmp_path / "missing", ["a"])
    path = tmp_path / "sub" / "t.csv"
    write_file(path, b"1")
    with pytest.raises(FileExistsError):
        write_file(path, b"2")
    write_file(path, b"2", overwrite=True)
    assert path.read_bytes() == b"2" and sorted(os.listdir(path.parent)) == ["t.csv"]
    assert os.stat(path).st_mode & 0o777 == 0o666 & ~_umask()


def _summary(**extra):
    base = {"data": {"file": "d.csv", "inputs": ["u"], "output": "y", "n_samples": 90,
                     "n_slow_samples": 30, "sampling": "one sample in 3, from row 0",
                     "factor": 3, "offset": 0, "sample_time": 0.01},
            "model": {"estimator": "FIRGaussianProcess", "order": 30, "n_inputs": 1,
                      "initial_conditions": "zero", "kernel": "DC()", "hyperparameters": {},
                      "tuning": "evidence", "log_evidence": 1.0, "noise_level": 0.04},
            "notes": [], "warnings": []}
    base.update(extra)
    return FitReport.from_dict(base)


def test_the_summary_reports_the_fit_percent_beside_the_goodness_of_fit():
    report = _summary(validation={"file": "v.csv", "n_samples": 90, "gof_percent": 99.986,
                                  "fit_percent": 98.81})
    assert report.headline().endswith("validation fit 98.81 % (NRMSE; GoF 99.99 %)")
    page = report.to_markdown()
    assert "- fit: 98.81 % (normalized root-mean-square error" in page
    assert "goodness of fit (paper eq. 20, model.score): 99.99 %" in page
    # the two are one prediction's: fit = 100 (1 - sqrt(1 - GoF / 100))
    y = np.sin(np.arange(50.0))
    y_hat = y + 0.05 * np.cos(np.arange(50.0) * 3)
    gof, fit = gm.goodness_of_fit(y, y_hat), gm.fit_percent(y, y_hat)
    assert fit == pytest.approx(100 * (1 - np.sqrt(1 - gof / 100)))


def test_the_default_order_table_says_where_the_prior_decays_not_the_order_again():
    report = _summary(order_selection={"criterion": "prior_tail", "orders": [512, 1024],
                                       "score": [512.0, 300.0], "best_order": 300})
    page = report.to_markdown()
    assert "| order fitted | tuned prior negligible beyond lag |" in page
    assert "| 512 | not within the order (512) |" in page and "| 1024 | 300 |" in page


def test_the_summary_says_what_the_residuals_leave_and_the_modes():
    noise = {"model": "white", "white_level": 0.04, "residuals_white": False,
             "ljung_box_p_value": 1e-20, "whiteness_p_value": 1e-9,
             "residuals_explained": "the residuals do not look white (Ljung-Box p = 1e-09): a "
                                    "peak in the residual spectrum at 2.1 Hz ... kernel=\"auto\"",
             "residual_remedies": ['kernel="auto"']}
    modes = {"n_states": 2, "level": 0.95, "n_draws": 100, "consistent": True,
             "error_bound": 0.5, "text": "1 peak(s) in |G| (2.1 Hz); 1 supported",
             "modes": [{"frequency": 2.1, "damping": 0.02, "gain": 10.0,
                        "frequency_interval": [2.09, 2.11], "damping_interval": [0.01, 0.03],
                        "gain_interval": [9.0, 11.0], "presence": 1.0}],
             "peaks": [{"frequency": 2.1, "magnitude": 9.5, "prominence": 9.0,
                        "probability": 1.0, "supported": True, "mode": 0}]}
    report = _summary(modes=modes)
    report = FitReport(data=report.data, model={**report.model, "noise": noise},
                       modes=report.modes)
    page = report.to_markdown()
    assert "(Ljung-Box p = 1e-09 under the fitted model, 1e-20 against chi-squared" in page
    assert "  - what is left: a peak in the residual spectrum at 2.1 Hz" in page
    assert "| 2.1 | 2.09 .. 2.11 | 0.02 | 0.01 .. 0.03 | 10 | 9 .. 11 | 100 % |" in page
    assert "| 2.1 | 9.5 | 100 % | yes | 2.1 Hz |" in page
    assert "too narrow until the model explains them" in page
    assert FitReport.from_dict(report.to_dict()) == report
