"""Models fitted to readings at their own instants: model files and the command line."""

import io
import json
import warnings

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate.cli import main
from gpmultirate.exceptions import ModelFileError
from gpmultirate.kernels import DC

N, P, F = 45, 8, 3
LAGS = np.linspace(0.0, P - 1.0, 29)


def _record(seed, n_inputs=1, n=N, between=None):
    """Inputs, readings stamped off the ticks (one missing), and the stamps.

    The stamps are at random instants between the ticks, or ``between`` after them.
    """
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, n_inputs)) if n_inputs > 1 else rng.standard_normal(n)
    g = 0.8 ** np.arange(P) * np.cos(0.6 * np.arange(P))
    ticks = np.arange(2, n - 3, F)
    x = u if n_inputs == 1 else u @ np.linspace(1.0, 0.5, n_inputs)
    y = np.convolve(x, g)[:n][ticks] + 1e-2 * rng.standard_normal(ticks.shape[0])
    y[3] = np.nan
    if between is not None:
        return u, y, ticks + between
    return u, y, ticks + rng.uniform(0.0, 1.0, ticks.shape[0])


def _saved_and_loaded(model):
    buffer = io.BytesIO()
    gm.save_model(model, buffer)
    buffer.seek(0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)  # "differs from the saved one" fails
        return buffer, gm.load_model(buffer)


def _header(buffer):
    buffer.seek(0)
    with np.load(buffer) as archive:
        return json.loads(bytes(archive["header"]).decode()), sorted(archive.files)


def _assert_same_predictions(model, loaded, us, stamps):
    several = isinstance(us, list)
    for a, b in zip(model.predict(us, return_std=True), loaded.predict(us, return_std=True)):
        for x, y in zip(a if several else [a], b if several else [b]):
            np.testing.assert_array_equal(x, y)
    a = model.predict(us, return_std=True, sample_times=stamps)
    b = loaded.predict(us, return_std=True, sample_times=stamps)
    for x, y in zip(np.concatenate([np.ravel(v) for v in a]), np.concatenate(
            [np.ravel(v) for v in b])):
        assert x == y
    for x, y in zip(model.impulse_response(LAGS, return_std=True),
                    loaded.impulse_response(LAGS, return_std=True)):
        np.testing.assert_array_equal(x, y)
    freqs = np.linspace(0.0, 0.5 / model.sample_time, 16)
    last = model.n_inputs_ - 1
    a, b = (m.frequency_response(freqs, input=last) for m in (model, loaded))
    for name in ("mean", "real_std", "imag_std", "magnitude_lower", "magnitude_upper"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_records_with_exposure_and_latency_round_trip():
    records = [_record(1), _record(2, n=39)]
    us, ys, stamps = (list(v) for v in zip(*records))
    model = gm.FIRGaussianProcess(C(1.5) * DC(0.8, 0.5), order=P, exposure=0.005,
                                  latency=0.003, optimizer=None, noise_level=1e-4,
                                  sample_time=0.01)
    model.fit(us, ys, sample_times=[s * 0.01 for s in stamps])
    buffer, loaded = _saved_and_loaded(model)
    header, names = _header(buffer)
    assert header["format_version"] == 5 and header["fitted"]["layout"] == "timed"
    assert header["params"]["exposure"] == 0.005 and header["params"]["latency"] == 0.003
    assert "sample_times_1" in names and "sample_indices_0" not in names
    # the missing reading is not stored; the stamps of the others are, exactly
    times = model.observation_.records[0].sample_times
    np.testing.assert_array_equal(loaded.observation_.records[0].sample_times, times)
    assert times.shape[0] == len(stamps[0]) - 1
    assert isinstance(loaded.observation_, gm.TimedConvolution)
    assert loaded.observation_ == model.observation_
    assert loaded.get_params() == model.get_params()
    assert loaded.log_marginal_likelihood_value_ == model.log_marginal_likelihood_value_
    _assert_same_predictions(model, loaded, us, [np.array([5.5, 20.25, 40.7]) * 0.01,
                                                 np.array([0.2, 7.1, 8.2]) * 0.01])


def test_tuned_model_round_trips_with_its_optimizer_result():
    u, y, stamps = _record(3)
    model = gm.FIRGaussianProcess(C(1.0) * DC(), order=P, exposure=0.5, latency=0.3)
    model.fit(u, y, sample_times=stamps)
    _, loaded = _saved_and_loaded(model)
    assert loaded.kernel_ == model.kernel_ and loaded.noise_level_ == model.noise_level_
    np.testing.assert_array_equal(loaded.optimizer_result_.x, model.optimizer_result_.x)
    _assert_same_predictions(model, loaded, u, np.array([1.5, 22.75]))
    # the loaded model fits again as the saved one did (same parameters, same data)
    refit = clone(loaded).fit(u, y, sample_times=stamps)
    assert refit.kernel_ == model.kernel_


@pytest.mark.parametrize("exposure", [0.0, 0.5])
def test_interpolated_readings_round_trip(exposure):
    u, y, stamps = _record(4)
    model = gm.FIRGaussianProcess(C(1.5) * DC(0.8, 0.5), order=P, exposure=exposure,
                                  latency=0.3, between_ticks="interpolated", optimizer=None,
                                  noise_level=1e-4)
    model.fit(u, y, sample_times=stamps)
    assert isinstance(model.observation_, gm.InterpolatedConvolution)
    buffer, loaded = _saved_and_loaded(model)
    assert _header(buffer)[0]["fitted"]["layout"] == "timed"
    assert isinstance(loaded.observation_, gm.InterpolatedConvolution)
    assert loaded.log_marginal_likelihood_value_ == model.log_marginal_likelihood_value_
    _assert_same_predictions(model, loaded, u, np.array([1.5, 22.75]))


def test_two_inputs_round_trip():
    # the readings share their offset from the ticks: the dense route of two inputs is quick
    records = [_record(4, n_inputs=2, between=0.5), _record(5, n_inputs=2, between=0.5)]
    us, ys, stamps = (list(v) for v in zip(*records))
    model = gm.FIRGaussianProcess(C(1.0) * DC(0.8, 0.5), order=P, latency=0.3,
                                  optimizer=None, noise_level=1e-4)
    model.fit(us, ys, sample_times=stamps)
    _, loaded = _saved_and_loaded(model)
    assert loaded.coef_.shape == (2, P)
    _assert_same_predictions(model, loaded, us, [np.array([3.5, 30.5]), np.array([9.5])])


def test_many_outputs_at_their_own_instants_round_trip():
    u, y, stamps = _record(6)
    y2 = 0.5 * y + 0.1
    template = gm.FIRGaussianProcess(C(1.0) * DC(0.8, 0.5), order=P, exposure=0.25,
                                     optimizer=None, noise_level=1e-4)
    model = gm.MultiOutputFIR(template).fit(u, np.column_stack([y, y2]), sample_times=stamps)
    buffer, loaded = _saved_and_loaded(model)
    header, _ = _header(buffer)
    assert header["format_version"] == 5
    assert [o["format_version"] for o in header["fitted"]["outputs"]] == [5, 5]
    for a, b in zip(model.predict(u, return_std=True, sample_times=[4.5, 9.2]),
                    loaded.predict(u, return_std=True, sample_times=[4.5, 9.2])):
        np.testing.assert_array_equal(a, b)


def test_latency_of_whole_periods_on_the_ticks_round_trips():
    # stamps late by whole periods are fast samples: a version 2 file with the latency
    u, y, _ = _record(7)
    ticks = np.arange(2, N - 3, F)
    model = gm.FIRGaussianProcess(C(1.0) * DC(0.8, 0.5), order=P, latency=2.0,
                                  optimizer=None, noise_level=1e-4)
    model.fit(u, y, sample_times=ticks + 2.0)
    buffer, loaded = _saved_and_loaded(model)
    assert _header(buffer)[0]["format_version"] == 2
    assert loaded.latency == 2.0
    _assert_same_predictions(model, loaded, u, np.array([6.0, 10.5]))


def _forge(buffer, edit):
    from gpmultirate.persistence import _checksum

    header, _ = _header(buffer)
    buffer.seek(0)
    with np.load(buffer) as archive:
        members = {k: archive[k] for k in archive.files if k != "header"}
    edit(header, members)
    header["sha256"] = _checksum(header, members)
    out = io.BytesIO()
    np.savez(out, header=np.frombuffer(json.dumps(header).encode(), dtype=np.uint8), **members)
    out.seek(0)
    return out


@pytest.mark.parametrize("edit, match", [
    (lambda h, m: h.update(format_version=2), "layout"),
    (lambda h, m: h["fitted"].update(layout="records"), "layout"),
    (lambda h, m: m.update(sample_times_0=m["sample_times_0"][::-1].copy()), "increasing"),
    (lambda h, m: h["fitted"].update(quadrature_nodes="many"), "quadrature_nodes"),
    (lambda h, m: h.update(estimator="LeastSquaresFIR"), "version 1 or 2"),
])
def test_inconsistent_timed_file_refused(edit, match):
    u, y, stamps = _record(8)
    model = gm.FIRGaussianProcess(C(1.0) * DC(0.8, 0.5), order=P, exposure=0.5,
                                  optimizer=None, noise_level=1e-4).fit(u, y, sample_times=stamps)
    buffer, _ = _saved_and_loaded(model)
    with pytest.raises(ModelFileError, match=match):
        gm.load_model(_forge(buffer, edit))


def test_version_4_file_reads_exposure_and_latency_in_fast_periods():
    # before 0.2.0 the exposure and latency of a model file were in fast periods
    u, y, stamps = _record(10)
    T = 0.01
    model = gm.FIRGaussianProcess(C(1.0) * DC(0.8, 0.5), order=P, exposure=0.5 * T,
                                  latency=0.25 * T, sample_time=T, optimizer=None,
                                  noise_level=1e-4).fit(u, y, sample_times=stamps * T)
    buffer, loaded = _saved_and_loaded(model)

    def old(header, members):
        header.update(format_version=4)
        header["params"].update(exposure=0.5, latency=0.25)

    previous = gm.load_model(_forge(buffer, old))
    assert previous.exposure == pytest.approx(0.5 * T, rel=1e-15)
    assert previous.latency == pytest.approx(0.25 * T, rel=1e-15)
    assert previous.log_marginal_likelihood_value_ == model.log_marginal_likelihood_value_
    instants = np.array([3.5, 17.25, 30.0]) * T
    for a, b in zip(model.predict(u, return_std=True, sample_times=instants),
                    previous.predict(u, return_std=True, sample_times=instants)):
        np.testing.assert_allclose(a, b, rtol=1e-12)
    assert loaded.exposure == model.exposure and loaded.latency == model.latency


def test_other_quadrature_is_reported():
    u, y, stamps = _record(9)
    model = gm.FIRGaussianProcess(C(1.0) * DC(0.8, 0.5), order=P, exposure=0.5,
                                  optimizer=None, noise_level=1e-4).fit(u, y, sample_times=stamps)
    buffer, _ = _saved_and_loaded(model)
    with pytest.warns(UserWarning, match="quadrature nodes"):
        gm.load_model(_forge(buffer, lambda h, m: h["fitted"].update(quadrature_nodes=8)))


# ------------------------------------------------------------------ the command line
T = 0.001


def _camera_files(tmp_path, n=300):
    """A fast input file and a camera log: frames off the ticks, exposure, latency."""
    rng = np.random.default_rng(11)
    u = rng.standard_normal(n)
    g = 0.8 ** np.arange(P) * np.cos(0.6 * np.arange(P))
    ticks = np.arange(2, n - 3, F)
    stamps = ticks + rng.uniform(0.0, 1.0, ticks.shape[0])
    y = np.convolve(u, g)[:n][ticks] + 1e-2 * rng.standard_normal(ticks.shape[0])
    fast = tmp_path / "fast.csv"
    fast.write_text("u\n" + "".join(f"{v:.17g}\n" for v in u))
    slow = tmp_path / "camera.csv"
    slow.write_text("t,y\n" + "".join(f"{t * T:.17g},{v:.17g}\n" for t, v in zip(stamps, y)))
    return u, y, stamps, fast, slow


def _assert_command_line_readings(model_file, model, u, fast, instants, folder):
    """``gpmultirate predict --slow`` at ``instants``: the library's readings and bands."""
    frames = folder / "frames.csv"
    frames.write_text("t\n" + "".join(f"{t * T:.17g}\n" for t in instants))
    target = folder / "readings.csv"
    assert main(["predict", str(model_file), str(fast), "--input", "u", "--slow",
                 str(frames), "--time", "t", "--out", str(target), "--quiet"]) == 0
    table = np.genfromtxt(target, delimiter=",", names=True)
    mean, std = model.predict(u, return_std=True, sample_times=instants * T)
    np.testing.assert_allclose(table["time"], instants * T, rtol=1e-12)
    np.testing.assert_allclose(table["y"], mean, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(table["y_std"], std, rtol=1e-13)
    return table


@pytest.mark.slow  # the figures of the fit take most of its 15 s
def test_camera_fit_writes_a_model_that_predicts_readings(tmp_path, capsys):
    from gpmultirate.io import read_slow_log
    from gpmultirate.residuals import analyze_residuals

    u, y, _, fast, slow = _camera_files(tmp_path)
    out = tmp_path / "fit"
    assert main(["fit", str(fast), "--input", "u", "--sample-time", str(T), "--slow", str(slow),
                 "--output", "y", "--time", "t", "--exposure", "0.0005", "--latency", "0.0002",
                 "--order", str(P), "--kernel", "dc", "--out", str(out), "--quiet"]) == 0
    assert "not written" not in capsys.readouterr().err
    model = gm.load_model(out / "model.npz")
    # the residuals are those of the readings at their instants (exposure and latency applied)
    assert (out / "residuals.png").exists()
    assert (model.exposure, model.latency, model.sample_time) == (5e-4, 2e-4, T)
    # the saved model is the fit of the library on the same data (times in seconds)
    stamps = read_slow_log(slow, "t", sample_time=T, n_samples=u.shape[0]).stamps
    direct = gm.FIRGaussianProcess(order=P, sample_time=T, exposure=5e-4, latency=2e-4).fit(
        u, y, sample_times=stamps)
    summary = json.loads((out / "summary.json").read_text())
    assert np.isclose(summary["model"]["log_evidence"], direct.log_marginal_likelihood_value_,
                      rtol=1e-9)
    np.testing.assert_allclose(model.coef_, direct.coef_, rtol=1e-7, atol=1e-9)
    whiteness = analyze_residuals(direct, u, y, sample_times=stamps, max_lag=25)
    assert summary["model"]["noise"]["ljung_box_p_value"] == pytest.approx(whiteness.p_value,
                                                                  rel=1e-6)
    # readings at the instants of another log, with their bands, as the library gives them
    instants = np.array([10.25, 57.5, 123.875, 250.0])
    table = _assert_command_line_readings(out / "model.npz", model, u, fast, instants, tmp_path)
    assert table.shape == (4,) and np.all(table["y_std"] > 0)


def test_predict_readings_of_a_saved_camera_model(tmp_path):
    u, y, stamps, fast, _ = _camera_files(tmp_path, n=120)
    model = gm.FIRGaussianProcess(C(1.0) * DC(0.8, 0.5), order=P, sample_time=T,
                                  exposure=0.5 * T, latency=0.2 * T, optimizer=None,
                                  noise_level=1e-4)
    gm.save_model(model.fit(u, y, sample_times=stamps * T), tmp_path / "model.npz")
    instants = np.array([10.25, 57.5, 100.875])
    _assert_command_line_readings(tmp_path / "model.npz", model, u, fast, instants, tmp_path)


# ------------------------------------------------ tuning by cross-validation between the ticks
def _dense_held_out_density(S, noise, y, folds):
    """``sum_k log p(y_B | y_rest)`` by conditioning the dense Gaussian, fold by fold."""
    from scipy.stats import multivariate_normal

    K = S + noise * np.eye(y.shape[0])
    total = 0.0
    for B in folds:
        R = np.setdiff1d(np.arange(y.shape[0]), B)
        gain = np.linalg.solve(K[np.ix_(R, R)], K[np.ix_(R, B)]).T
        mean = gain @ y[R]
        cov = K[np.ix_(B, B)] - gain @ K[np.ix_(R, B)]
        total += multivariate_normal(mean, cov).logpdf(y[B])
    return total


def _brute_force_covariance(kernel, u, stamps, latency):
    """Readings without exposure: ``sum_ij u[i] u[j] k(t_m - L - i, t_n - L - j)``, lags in [0, P)."""
    ends = np.asarray(stamps) - latency
    lags = ends[:, None] - np.arange(u.shape[0])[None, :]
    inside = (lags >= 0) & (lags < P)
    # the kernel is c * DC: between integer lags its values are the Lagrange interpolation
    # of the integer lags n - 5 .. n + 6 (zero below 0, cut at P - 1) plus the bridge
    # 0.1^2 sin(pi d) sin(pi e) k(n, n) on a shared cell n
    K = kernel(np.arange(P, dtype=float)[:, None])
    rows, bridges = [], []
    for m in range(ends.shape[0]):
        row, bridge = np.zeros(P), np.zeros(P)
        for j in np.flatnonzero(inside[m]):
            x = lags[m, j]
            n = int(np.floor(x))
            nodes = [n] if x == n else [n + s for s in range(-5, 7) if n + s <= P - 1]
            for node in nodes:
                weight = np.prod([(x - o) / (node - o) for o in nodes if o != node])
                if node >= 0:
                    row[node] += u[j] * weight
            bridge[n] += u[j] * np.sin(np.pi * (x - n))
        rows.append(row)
        bridges.append(bridge)
    rows, bridges = np.array(rows), np.array(bridges)
    return rows @ K @ rows.T + bridges @ np.diag(0.1**2 * np.diag(K)) @ bridges.T


@pytest.mark.parametrize("exposure", [0.0, 0.5])
def test_cross_validation_between_the_ticks_is_the_dense_held_out_density(exposure):
    from gpmultirate.crossvalidation import contiguous_folds
    from gpmultirate.kernels import observe

    u, y, stamps = _record(12)
    measured = np.isfinite(y)
    y, stamps = y[measured], stamps[measured]
    kernel = C(1.5) * DC(0.8, 0.5)
    model = gm.FIRGaussianProcess(kernel, order=P, exposure=exposure, latency=0.3,
                                  tuning="cross_validation", cv=4, optimizer=None,
                                  noise_level=1e-3)
    model.fit(u, y, sample_times=stamps)
    assert isinstance(model.observation_, gm.TimedConvolution)
    folds = contiguous_folds([y.shape[0]], 4)
    if exposure == 0.0:
        S = _brute_force_covariance(kernel, u, stamps, 0.3)
    else:  # the readings' covariance, tested against dense quadrature in test_timed
        S = observe(kernel, model.observation_).covariance()
    expected = _dense_held_out_density(S, 1e-3, y, folds)
    assert abs(model.cv_log_predictive_likelihood_ - expected) < 1e-8 * max(1.0, abs(expected))


@pytest.mark.slow  # 2 s: tuning by cross-validation
def test_tuning_by_cross_validation_between_the_ticks():
    from gpmultirate.crossvalidation import contiguous_folds

    u, y, stamps = _record(12)
    measured = np.isfinite(y)
    y, stamps = y[measured], stamps[measured]
    start = C(1.5) * DC(0.8, 0.5)
    model = gm.FIRGaussianProcess(start, order=P, latency=0.3, tuning="cross_validation", cv=4)
    model.fit(u, y, sample_times=stamps)
    folds = contiguous_folds([y.shape[0]], 4)
    tuned = _dense_held_out_density(_brute_force_covariance(model.kernel_, u, stamps, 0.3),
                                    model.noise_level_, y, folds)
    assert abs(model.cv_log_predictive_likelihood_ - tuned) < 1e-8 * abs(tuned)
    # the tuning raised the held-out density above that of the start
    assert tuned > _dense_held_out_density(_brute_force_covariance(start, u, stamps, 0.3),
                                           1e-2, y, folds) + 1.0


# ------------------------------------------------ the resonance search between the ticks
def _response(x):
    """A smooth response over continuous lag and its basis-like partner: ``(n, 2)``."""
    return np.column_stack([0.8 ** x * np.cos(1.3 * x), 0.9 ** x * np.sin(2.4 * x)])


def _brute_force_readings(f, u, stamps, exposure, latency, nodes=40):
    """``(1/E) int y`` with ``y(t) = sum_j u[j] f(t - j)``, Gauss-Legendre on every piece."""
    xi, w = np.polynomial.legendre.leggauss(nodes)
    out = []
    for t in stamps:
        end, start = t - latency, t - latency - exposure
        edges = [start] + [k for k in range(int(np.ceil(start)), int(np.ceil(end)))
                           if start < k < end] + [end]
        total = 0.0
        for a, b in zip(edges[:-1], edges[1:]):
            for s, weight in zip(a + (b - a) * (xi + 1) / 2, w * (b - a) / 2):
                j = np.arange(u.shape[0])
                inside = (s - j >= 0) & (s - j < P)
                total += weight * (u[inside] @ f(s - j[inside]))
        out.append(total / exposure)
    return np.array(out)


def test_readings_of_responses_given_as_functions():
    u2, _, stamps = _record(13, n_inputs=2)
    timed = gm.TimedConvolution(u2, stamps, order=P, exposure=0.5, latency=0.3)
    for k in (0, 1):
        expected = _brute_force_readings(_response, u2[:, k], stamps, 0.5, 0.3)
        np.testing.assert_allclose(timed.lag_functionals(_response, input=k), expected,
                                   rtol=1e-10, atol=1e-12)
    # the damped exponentials of the scan: one FFT for every frequency
    alpha, n_fft, index = 0.85, 16, np.arange(1, 17)
    omegas = np.pi * index / n_fft
    spectrum = timed.damped_spectrum(alpha, n_fft, index, input=1)
    basis = timed.lag_functionals(lambda x: np.hstack([
        alpha ** (x[:, None] / 2) * np.cos(np.outer(x, omegas)),
        alpha ** (x[:, None] / 2) * np.sin(np.outer(x, omegas))]), input=1)
    np.testing.assert_allclose(spectrum.real, basis[:, :16], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(-spectrum.imag, basis[:, 16:], rtol=1e-10, atol=1e-12)


def test_resonance_scan_of_readings_on_the_ticks_is_that_of_the_fast_samples():
    from gpmultirate.observations import SampledConvolution
    from gpmultirate.resonances import resonance_scan

    u, y, _ = _record(14, n=120)
    ticks = np.arange(2, 117, F)
    y = np.convolve(u, 0.95 ** np.arange(P) * np.sin(2.4 * np.arange(P)))[:120][ticks]
    kernel = C(1.0) * DC(0.8, 0.5)
    timed = gm.TimedConvolution(u, ticks.astype(float), order=P)
    sampled = SampledConvolution(u, ticks, order=P)
    a = resonance_scan(timed, y, kernel, 1e-3)
    b = resonance_scan(sampled, y, kernel, 1e-3)
    assert a[0].shape == b[0].shape and np.max(b[0]) > 1.0
    np.testing.assert_allclose(a[0], b[0], rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(a[1], b[1], rtol=1e-8)


def test_resonant_model_between_the_ticks_is_the_evidence_of_its_kernel():
    from scipy.optimize import approx_fprime

    from gpmultirate.inference import LogEvidence
    from gpmultirate.kernels import PK
    from gpmultirate.resonances import _ResonantModel

    u, y, stamps = _record(15)
    measured = np.isfinite(y)
    timed = gm.TimedConvolution(u, stamps[measured], order=P, exposure=0.5, latency=0.3)
    y = y[measured]
    evidence = LogEvidence(timed, y, C(1.0) * DC(0.8, 0.5), 1e-3, (1e-8, 1.0))
    model = _ResonantModel(evidence)
    model.terms = [(0, PK(alpha=0.9, omega=2.0, sigma1=0.5, sigma2=0.3))]
    x = model._pack() + np.array([0.1, 0.2, 0.0, 0.05, -0.1, 0.2])
    value, gradient = model._log_evidence(x, eval_gradient=True)
    model._unpack(x)
    dense = LogEvidence(timed, y, model.kernel(), model.noise_level, "fixed")
    assert abs(value - dense(dense.theta)) < 1e-8 * abs(value)
    numeric = approx_fprime(x, lambda v: model._log_evidence(v), 1e-6)
    np.testing.assert_allclose(gradient, numeric, rtol=1e-4, atol=1e-4 * np.abs(numeric).max())


@pytest.mark.slow  # 3 s: two tuned fits of 100 frames
def test_auto_kernel_finds_a_resonance_above_the_slow_nyquist_frequency():
    rng = np.random.default_rng(5)
    n, order, omega = 300, 60, 2.2  # the slow Nyquist frequency is pi / 3 = 1.05

    def g(x):
        return 0.3 * 0.9 ** x + 0.97 ** x * np.sin(omega * x)

    def readings(u, stamps, latency):  # the output at t - latency, from g between the lags
        out = []
        for t in stamps - latency:
            j = np.arange(u.shape[0])
            inside = (t - j >= 0) & (t - j < order)
            out.append(u[inside] @ g(t - j[inside]))
        return np.array(out)

    u = rng.standard_normal(n)
    ticks = np.arange(2, n - 1, F)
    stamps = ticks + rng.uniform(0.0, 1.0, ticks.shape[0])
    y = readings(u, stamps, 0.2)
    y += 10 ** (-45 / 20) * np.std(y) * rng.standard_normal(y.shape[0])
    u_val = rng.standard_normal(n)
    y_val = np.convolve(u_val, g(np.arange(order)))[:n]

    def gof(model):
        error = np.linalg.norm(y_val - model.predict(u_val))
        return 100.0 * (1.0 - error / np.linalg.norm(y_val - y_val.mean()))

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = gm.FIRGaussianProcess(C(1.0) * DC(), order=order, latency=0.2).fit(
            u, y, sample_times=stamps)
        auto = gm.FIRGaussianProcess("auto", order=order, latency=0.2).fit(
            u, y, sample_times=stamps)
    assert isinstance(auto.observation_, gm.TimedConvolution)
    found = [2 * np.pi * r.frequency_hz for r in auto.resonances_]
    assert any(abs(w - omega) < 0.02 for w in found)
    # the mode found leaves at most half the DC prior's error (measured: 1.6 against 4.9)
    assert 100.0 - gof(auto) < 0.5 * (100.0 - gof(plain)) and gof(auto) > 97.0
    # the model file keeps the resonances
    _, loaded = _saved_and_loaded(auto)
    assert loaded.resonances_ == auto.resonances_
    np.testing.assert_array_equal(loaded.predict(u_val), auto.predict(u_val))


def test_resonance_scan_of_given_frequencies_between_the_ticks():
    # given frequencies take the functionals of the bases; the grid takes the FFT
    from gpmultirate.resonances import resonance_scan

    u, y, stamps = _record(16, n=120)
    measured = np.isfinite(y)
    timed = gm.TimedConvolution(u, stamps[measured], order=32, exposure=0.5)
    kernel = C(1.0) * DC(0.8, 0.5)
    grid = resonance_scan(timed, y[measured], kernel, 1e-3)
    chosen = grid[2][::7]
    given = resonance_scan(timed, y[measured], kernel, 1e-3, omegas=chosen)
    np.testing.assert_allclose(given[0], grid[0][:, ::7], rtol=1e-9, atol=1e-9)
    assert np.max(grid[0]) > 0.0


def _damped_exponentials(alpha, omegas):
    """``alpha^(x/2) cos(omega x)`` and ``alpha^(x/2) sin(omega x)`` at the real lags ``x``."""
    return lambda x: np.hstack([alpha ** (x[:, None] / 2) * np.cos(np.outer(x, omegas)),
                                alpha ** (x[:, None] / 2) * np.sin(np.outer(x, omegas))])


@pytest.mark.parametrize("exposure, latency, seed", [
    (0.0, 0.0, 21), (0.0, 0.4, 22), (0.5, 0.3, 23), (2.0, 0.0, 24), (2.6, 0.7, 25)])
def test_damped_spectrum_is_the_readings_of_the_damped_exponentials(exposure, latency, seed):
    # the phases of the points as a series per (reading, tick): to rounding, at every
    # frequency up to pi, for slow and fast decays
    order, n_fft = 40, 40
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((160, 2))
    stamps = np.sort(rng.choice(np.arange(5, 157), 40, replace=False) + rng.uniform(0, 1, 40))
    timed = gm.TimedConvolution(u, stamps, order=order, exposure=exposure, latency=latency)
    index = np.arange(1, n_fft + 1)
    omegas = np.pi * index / n_fft
    for alpha in (1.0 - 1e-9, 0.99, np.exp(-2.0 * 60.0 / order), 0.05):
        spectrum = timed.damped_spectrum(alpha, n_fft, index, input=1)
        basis = timed.lag_functionals(_damped_exponentials(alpha, omegas), input=1)
        scale = np.abs(basis).max()
        np.testing.assert_allclose(spectrum.real, basis[:, :n_fft], rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(-spectrum.imag, basis[:, n_fft:], rtol=0, atol=1e-12 * scale)
    # a subset of the grid is those columns of the whole
    chosen = index[::3]
    np.testing.assert_allclose(timed.damped_spectrum(0.9, n_fft, chosen),
                               timed.damped_spectrum(0.9, n_fft, index)[:, ::3],
                               rtol=1e-13, atol=1e-13 * scale)


def test_damped_spectrum_of_stacked_records_against_the_readings_point_by_point():
    # an independent sum over the quadrature points of every window, record by record
    rng = np.random.default_rng(26)
    records, expected = [], []
    alpha, n_fft, index = 0.93, 8, np.array([1, 3, 4, 8])
    omegas = np.pi * index / n_fft
    f = _damped_exponentials(alpha, omegas)
    for n in (40, 33):
        u = rng.standard_normal(n)
        stamps = np.arange(3, n - 2, F) + rng.uniform(0.0, 1.0, (n - 5 + F - 1) // F)
        records.append(gm.TimedConvolution(u, stamps, order=P, exposure=1.4, latency=0.2))
        expected.append(_brute_force_readings(f, u, stamps, 1.4, 0.2))
    stacked = gm.TimedConvolution.stack(records)
    spectrum = stacked.damped_spectrum(alpha, n_fft, index)
    expected = np.vstack(expected)
    scale = np.abs(expected).max()
    np.testing.assert_allclose(spectrum.real, expected[:, :4], rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(-spectrum.imag, expected[:, 4:], rtol=0, atol=1e-12 * scale)


def test_damped_spectrum_beyond_the_series_reach_takes_the_phases_point_by_point(monkeypatch):
    from gpmultirate.observations import timed as timed_module

    u, _, stamps = _record(27)
    timed = gm.TimedConvolution(u, stamps, order=P, exposure=0.8)
    index = np.arange(1, 9)
    series = timed.damped_spectrum(0.8, 8, index)
    monkeypatch.setattr(timed_module, "_SERIES_REACH", 0.0)
    assert timed_module._phase_terms(0.1) is None
    pointwise = timed.damped_spectrum(0.8, 8, index)
    basis = timed.lag_functionals(_damped_exponentials(0.8, np.pi * index / 8))
    np.testing.assert_allclose(pointwise.real, basis[:, :8], rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(series, pointwise, rtol=1e-12, atol=1e-13)


def test_phase_series_terms_reach_rounding():
    from math import factorial

    from gpmultirate.observations.timed import _phase_terms

    assert _phase_terms(0.0) == 1 and _phase_terms(3.5) is None
    for reach in (0.3, np.pi / 2, 3.0):
        n = _phase_terms(reach)
        theta = np.linspace(-reach, reach, 41)
        series = sum((-1j * theta) ** q / factorial(q) for q in range(n))
        assert np.max(np.abs(series - np.exp(-1j * theta))) < 1e-15  # rounding, e^reach ulps
        shorter = sum((-1j * theta) ** q / factorial(q) for q in range(n - 2))
        assert np.max(np.abs(shorter - np.exp(-1j * theta))) > 2e-16  # not more than needed


def test_resonance_scan_between_the_ticks_skips_only_frequencies_the_input_does_not_excite():
    from scipy import signal

    from gpmultirate.observations import SampledConvolution
    from gpmultirate.resonances import MIN_EXCITATION, _scan, resonance_scan
    from gpmultirate.covariance import DenseCovariance
    from gpmultirate.noise import WhiteNoise

    rng = np.random.default_rng(28)
    n, order = 150, 24
    # high-passed: the first frequency of the grid is not excited either
    u = signal.lfilter(*signal.butter(6, 0.5, "high"), rng.standard_normal(n))
    g = 0.9 ** np.arange(order) * np.sin(2.3 * np.arange(order))
    ticks = np.arange(2, n - 1, F)
    y = np.convolve(u, g)[:n][ticks] + 1e-3 * rng.standard_normal(ticks.shape[0])
    kernel = C(1.0) * DC(0.8, 0.5)
    # on the ticks: the scan of the fast samples, which forms every frequency
    timed = gm.TimedConvolution(u, ticks.astype(float), order=order)
    a = resonance_scan(timed, y, kernel, 1e-3)
    b = resonance_scan(SampledConvolution(u, ticks, order=order), y, kernel, 1e-3)
    skipped = np.all(b[0] == 0.0, axis=0)
    assert 0.3 < skipped.mean() < 0.9 and np.max(b[0]) > 1.0
    np.testing.assert_allclose(a[0], b[0], rtol=1e-8, atol=1e-8)
    kept = ~skipped
    kept[0] = True
    np.testing.assert_allclose(a[1][:, kept], b[1][:, kept], rtol=1e-8)
    # off the ticks with exposure: the same gains as a scan told every frequency is excited
    between = gm.TimedConvolution(u, ticks + rng.uniform(0.0, 1.0, ticks.shape[0]),
                                  order=order, exposure=1.5)
    whiten = DenseCovariance.of(kernel, between, WhiteNoise(1e-3)).whiten
    seen = {}
    gain, sigma, omegas, _ = _scan(between, y, 0, whiten, seen=seen)
    unseen = seen[0] < MIN_EXCITATION
    assert 0.1 < unseen.mean() < 0.9 and unseen[0]
    every, every_sigma, _, _ = _scan(between, y, 0, whiten, seen={0: np.ones(omegas.size)})
    every[:, unseen] = 0.0
    np.testing.assert_allclose(gain, every, rtol=1e-12, atol=1e-12 * np.max(every))
    np.testing.assert_array_equal(sigma[:, ~unseen], every_sigma[:, ~unseen])
    np.testing.assert_array_equal(sigma[:, 0], every_sigma[:, 0])


def test_readings_of_damped_sinusoids_by_their_separable_form():
    u2, _, stamps = _record(17, n_inputs=2)
    timed = gm.TimedConvolution(u2, stamps, order=P, exposure=0.7, latency=0.3)
    rate, omega = 0.12, 2.3

    def basis(x):
        ec, es = np.exp(-rate * x) * np.cos(omega * x), np.exp(-rate * x) * np.sin(omega * x)
        return np.column_stack([ec, es, x * ec, x * es])

    for k in (0, 1):
        expected = _brute_force_readings(basis, u2[:, k], stamps, 0.7, 0.3)
        np.testing.assert_allclose(timed.damped_sinusoids(rate, omega, k, with_lag=True),
                                   expected, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(timed.damped_sinusoids(rate, omega, k), expected[:, :2],
                                   rtol=1e-10, atol=1e-12)


def test_predict_readings_of_a_tick_model_with_the_cameras_exposure(tmp_path, capsys):
    """--exposure/--latency give a model fitted on the ticks the sensor of the readings."""
    u, y, stamps, fast, _ = _camera_files(tmp_path, n=120)
    model = gm.FIRGaussianProcess(C(1.0) * DC(0.8, 0.5), order=P, factor=F, sample_time=T,
                                  optimizer=None, noise_level=1e-4)
    model.fit(u, np.convolve(u, 0.8 ** np.arange(P))[:120:F])
    gm.save_model(model, tmp_path / "model.npz")
    frames = tmp_path / "frames.csv"
    instants = np.array([10.25, 57.5, 100.875])
    frames.write_text("# frames of the camera\nt\n" + "".join(f"{t * T:.17g}\n" for t in instants))
    target = tmp_path / "readings.csv"
    assert main(["predict", str(tmp_path / "model.npz"), str(fast), "--input", "u", "--slow",
                 str(frames), "--time", "t", "--exposure", "0.0005", "--latency", "0.0002",
                 "--out", str(target)]) == 0
    err = capsys.readouterr().err
    assert "3 readings, exposure 0.0005 s, latency 0.0002 s" in err and "fast samples" not in err
    table = np.genfromtxt(target, delimiter=",", names=True)
    # a reading is the mean of the output over [t - L - E, t - L]: the mean of the model's
    # output at the instants of a fine midpoint grid over that window
    offsets = -0.7 + 0.5 * (np.arange(400) + 0.5) / 400
    mean = np.array([np.mean(model.predict(u, sample_times=(t + offsets) * T)) for t in instants])
    np.testing.assert_allclose(table["y"], mean, rtol=1e-4)
    assert np.all(table["y_std"] > 0)
    # the exposure changes the readings, and without it the command says so
    plain = model.predict(u, sample_times=instants * T)
    assert np.max(np.abs(plain - mean)) > 1e-3
    assert main(["predict", str(tmp_path / "model.npz"), str(fast), "--input", "u", "--slow",
                 str(frames), "--time", "t", "--out", str(tmp_path / "plain.csv")]) == 0
    assert "give --exposure/--latency" in capsys.readouterr().err
    # and --exposure without a slow log is refused
    with pytest.raises(SystemExit):
        main(["predict", str(tmp_path / "model.npz"), str(fast), "--input", "u", "--exposure",
              "0.001", "--out", str(tmp_path / "x.csv")])
    assert "--exposure/--latency" in capsys.readouterr().err
