"""Tests of gpmultirate.MultiOutputFIR: one model per output column.

The reference for every output is the single estimator fitted alone to that
column (under one BLAS thread, as MultiOutputFIR fits it; on these small
problems the single estimator's own rule is one thread as well), so the
comparisons are exact.  Missing samples of one output are checked against a
fit of that output's measured samples only, given by their instants.
"""

import hashlib
import io
import json
import pathlib
import pickle
import subprocess
import sys

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.exceptions import NotFittedError
from sklearn.gaussian_process.kernels import ConstantKernel as C
from threadpoolctl import threadpool_limits

import gpmultirate as gm
from gpmultirate import FIRGaussianProcess, LeastSquaresFIR, MultiOutputFIR
from gpmultirate.kernels import DC
from gpmultirate.persistence import ModelFileError

N, FACTOR, ORDER, LS_ORDER = 240, 3, 40, 15
M = N // FACTOR


def responses(n_outputs=3, n_inputs=2):
    """Impulse responses ``(n_outputs, n_inputs, ORDER)``: shared modes, other shapes."""
    lags = np.arange(ORDER)
    modes = [0.8**lags, 0.9**lags * np.cos(0.9 * lags)]
    g = np.empty((n_outputs, n_inputs, ORDER))
    for j in range(n_outputs):
        for k in range(n_inputs):
            g[j, k] = sum(np.sin((i + 1) * (j + 1) * 0.7 + k) * m for i, m in enumerate(modes))
    return g


def simulate(u, g, rng, noise=1e-3):
    """Slow outputs ``(M, n_outputs)`` of inputs ``u`` ``(N, n_inputs)`` through ``g``."""
    n = u.shape[0]
    y = np.column_stack([
        sum(np.convolve(u[:, k], g[j, k])[:n] for k in range(u.shape[1]))
        for j in range(g.shape[0])
    ])
    return y[::FACTOR] + noise * rng.standard_normal((len(range(0, n, FACTOR)), g.shape[0]))


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(0)
    u = rng.standard_normal((N, 2))
    y_slow = simulate(u, responses(), rng)
    y_slow[[4, 30, 31], 1] = np.nan  # not measured at output 1 only
    y_slow[60, 2] = np.nan
    u_new = rng.standard_normal((100, 2))
    return u, y_slow, u_new


ESTIMATORS = {
    "gp": lambda: FIRGaussianProcess(factor=FACTOR, order=ORDER),
    "gp kernel": lambda: FIRGaussianProcess(C(1.0) * DC(), factor=FACTOR, order=ORDER,
                                            n_restarts_optimizer=1, random_state=3),
    "ls": lambda: LeastSquaresFIR(factor=FACTOR, order=LS_ORDER),
}


@pytest.fixture(scope="module")
def fitted(data):
    u, y_slow, _ = data
    return {name: MultiOutputFIR(make()).fit(u, y_slow) for name, make in ESTIMATORS.items()}


def alone(make, u, y, **kwargs):
    with threadpool_limits(limits=1, user_api="blas"):
        return make().fit(u, y, **kwargs)


def assert_same_fit(a, b):
    """Two single-output models with the same estimate and hyperparameters, bit for bit."""
    np.testing.assert_array_equal(a.coef_, b.coef_)
    if hasattr(a, "kernel_"):
        np.testing.assert_array_equal(a.kernel_.theta, b.kernel_.theta)
        assert a.noise_level_ == b.noise_level_
        assert a.log_marginal_likelihood_value_ == b.log_marginal_likelihood_value_
    else:
        np.testing.assert_array_equal(a.coef_covariance_, b.coef_covariance_)


# ------------------------------------------------------------ each output
@pytest.mark.parametrize("name", list(ESTIMATORS))
def test_each_output_is_the_estimator_fitted_alone(fitted, data, name):
    u, y_slow, u_new = data
    model = fitted[name]
    assert model.n_outputs_ == 3 and model.n_inputs_ == 2 and len(model.estimators_) == 3
    predicted = model.predict(u_new)
    for j in range(3):
        single = alone(ESTIMATORS[name], u, y_slow[:, j])
        assert_same_fit(model.estimators_[j], single)
        np.testing.assert_array_equal(model.coef_[j], single.coef_)
        np.testing.assert_array_equal(predicted[:, j], single.predict(u_new))


def test_outputs_have_their_own_hyperparameters(fitted):
    thetas = [e.kernel_.theta for e in fitted["gp"].estimators_]
    assert not np.array_equal(thetas[0], thetas[1]) and not np.array_equal(thetas[1], thetas[2])
    noise = [e.noise_level_ for e in fitted["gp"].estimators_]
    assert len(set(noise)) == 3


def test_missing_samples_are_per_output(fitted, data):
    """NaN at output 1 is the same as fitting its measured samples at their instants."""
    u, y_slow, _ = data
    model = fitted["gp"]
    measured = np.flatnonzero(np.isfinite(y_slow[:, 1]))
    direct = alone(ESTIMATORS["gp"], u, y_slow[measured, 1], sample_indices=FACTOR * measured)
    np.testing.assert_allclose(model.coef_[1], direct.coef_, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(model.estimators_[1].kernel_.theta, direct.kernel_.theta,
                               rtol=1e-10)
    assert model.estimators_[0].y_slow_.shape == (M,)
    assert model.estimators_[1].y_slow_.shape == (M - 3,)


def test_the_fit_recovers_the_true_responses(data):
    """Noise 1e-3, no missing samples: every output's estimate near its true response."""
    u, _, _ = data
    rng = np.random.default_rng(5)
    g = responses()
    y_slow = simulate(u, g, rng, noise=1e-4)
    model = MultiOutputFIR(FIRGaussianProcess(factor=FACTOR, order=ORDER)).fit(u, y_slow)
    error = np.linalg.norm(model.coef_ - g, axis=-1) / np.linalg.norm(g, axis=-1)
    assert error.max() < 0.05


# ------------------------------------------------------------ parallel
@pytest.mark.slow
@pytest.mark.parametrize("name", ["gp kernel", "ls"])
def test_serial_and_two_processes_identical(fitted, data, name):
    u, y_slow, u_new = data
    parallel = MultiOutputFIR(ESTIMATORS[name](), n_jobs=2).fit(u, y_slow)
    serial = fitted[name]
    for a, b in zip(serial.estimators_, parallel.estimators_):
        assert_same_fit(a, b)
    np.testing.assert_array_equal(serial.predict(u_new), parallel.predict(u_new))


# ------------------------------------------------------------ data layouts
def test_one_input_and_records_and_sample_indices():
    rng = np.random.default_rng(2)
    g = responses(n_outputs=2, n_inputs=1)
    us = [rng.standard_normal((n, 1)) for n in (150, 120)]
    ys = [simulate(u, g, rng) for u in us]
    us = [u[:, 0] for u in us]  # one input, 1-D
    ys[1][3, 0] = np.nan
    indices = [np.arange(0, 150, FACTOR), np.arange(0, 120, FACTOR)]
    make = ESTIMATORS["gp"]
    model = MultiOutputFIR(make()).fit(us, ys, sample_indices=indices)
    assert model.coef_.shape == (2, ORDER)
    predicted = model.predict(us)
    assert isinstance(predicted, list) and [p.shape for p in predicted] == [(150, 2), (120, 2)]
    for j in range(2):
        single = alone(make, us, [y[:, j] for y in ys], sample_indices=indices)
        assert_same_fit(model.estimators_[j], single)
        np.testing.assert_array_equal(predicted[1][:, j], single.predict(us[1]))


def test_a_single_column_is_one_output(data):
    u, y_slow, u_new = data
    model = MultiOutputFIR(ESTIMATORS["ls"]()).fit(u, y_slow[:, :1])
    assert model.n_outputs_ == 1 and model.coef_.shape == (1, 2, LS_ORDER)
    assert model.predict(u_new).shape == (100, 1)
    single = alone(ESTIMATORS["ls"], u, y_slow[:, 0])
    np.testing.assert_array_equal(model.frequency_response(input=1).mean,
                                  single.frequency_response(input=1).mean)


def test_shapes_and_delegation(fitted, data):
    u, _, u_new = data
    model = fitted["gp"]
    assert model.coef_.shape == (3, 2, ORDER)
    mean, std = model.predict(u_new, return_std=True)
    assert mean.shape == std.shape == (100, 3) and np.all(std > 0)
    for j in range(3):
        mean_j, std_j = model.estimators_[j].predict(u_new, return_std=True)
        np.testing.assert_array_equal(mean[:, j], mean_j)
        np.testing.assert_array_equal(std[:, j], std_j)
        frf = model.frequency_response(level=0.9, input=1, output=j)
        expected = model.estimators_[j].frequency_response(level=0.9, input=1)
        np.testing.assert_array_equal(frf.mean, expected.mean)
        np.testing.assert_array_equal(frf.magnitude_lower, expected.magnitude_lower)
        lags = [0.5, 3.25, 10.0]
        got = model.impulse_response(lags, return_std=True, output=j)
        want = model.estimators_[j].impulse_response(lags, return_std=True)
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])
    assert model.impulse_response(output=2).shape == (2, ORDER)


# ------------------------------------------------------------ errors
def test_one_dimensional_y_slow_refused(data):
    u, y_slow, _ = data
    with pytest.raises(ValueError, match=r"y_slow must be 2-D .*fit the estimator itself"):
        MultiOutputFIR(ESTIMATORS["ls"]()).fit(u, y_slow[:, 0])


@pytest.mark.parametrize("bad", [np.zeros((80, 3, 1)), np.zeros((80, 0)), np.zeros((0, 3)),
                                 "y", None, np.full((80, 2), 1j)])
def test_bad_y_slow_refused(data, bad):
    with pytest.raises(ValueError, match="y_slow"):
        MultiOutputFIR(ESTIMATORS["ls"]()).fit(data[0], bad)


def test_records_need_the_same_outputs(data):
    u, y_slow, _ = data
    with pytest.raises(ValueError, match=r"y_slow\[1\] has 2 outputs; y_slow\[0\] has 3"):
        MultiOutputFIR(ESTIMATORS["ls"]()).fit([u, u], [y_slow, y_slow[:, :2]])


@pytest.mark.parametrize("output", [-1, 3, 1.5, "0", True, None])
def test_bad_output_refused(fitted, output):
    model = fitted["gp"]
    with pytest.raises(ValueError, match="output"):
        model.frequency_response(input=0, output=output)
    with pytest.raises(ValueError, match="output"):
        model.impulse_response(output=output)


@pytest.mark.parametrize("n_jobs", [0, 1.5, True, "2"])
def test_bad_n_jobs_refused(data, n_jobs):
    with pytest.raises(ValueError, match="n_jobs"):
        MultiOutputFIR(ESTIMATORS["ls"](), n_jobs=n_jobs).fit(data[0], data[1])


@pytest.mark.parametrize("estimator", [None, "DC", DC(), FIRGaussianProcess])
def test_bad_estimator_refused(data, estimator):
    with pytest.raises(ValueError, match="estimator"):
        MultiOutputFIR(estimator).fit(data[0], data[1])


@pytest.mark.parametrize("n_jobs", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_an_output_that_fails_is_named(data, n_jobs):
    u, y_slow, _ = data
    y = y_slow.copy()
    y[:, 2] = np.nan
    with pytest.raises(ValueError, match=r"no finite sample in column 2 \(output 2\)"):
        MultiOutputFIR(ESTIMATORS["ls"](), n_jobs=n_jobs).fit(u, y)
    y[:3, 2] = y_slow[:3, 2]  # three samples: too few for least squares at this order
    with pytest.raises(ValueError) as info:
        MultiOutputFIR(ESTIMATORS["ls"](), n_jobs=n_jobs).fit(u, y)
    if sys.version_info >= (3, 11):  # exceptions carry notes
        assert "while fitting output 2 (column 2 of y_slow)" in info.value.__notes__


def test_unfitted_model_refused(data):
    model = MultiOutputFIR(ESTIMATORS["ls"]())
    with pytest.raises(NotFittedError):
        model.predict(data[2])
    with pytest.raises(NotFittedError):
        gm.save_model(model, io.BytesIO())


def test_parameters_and_caller_arrays_untouched(data):
    u, y_slow, _ = (a.copy() for a in data)
    estimator = ESTIMATORS["gp"]()
    model = MultiOutputFIR(estimator, n_jobs=1)
    assert model.get_params(deep=False) == {"estimator": estimator, "n_jobs": 1}
    assert model.fit(u, y_slow) is model
    assert model.estimator is estimator and not hasattr(estimator, "coef_")
    assert all(e is not estimator for e in model.estimators_)
    np.testing.assert_array_equal(u, data[0])
    np.testing.assert_array_equal(y_slow, data[1])
    again = clone(model).set_params(estimator__order=20)
    assert again.estimator.order == 20 and estimator.order == ORDER


# ------------------------------------------------------------ persistence
@pytest.mark.parametrize("name", ["gp kernel", "ls"])
def test_save_load_and_pickle_round_trips(fitted, data, name, tmp_path):
    u, _, u_new = data
    model = fitted[name]
    gm.save_model(model, tmp_path / "model.npz")
    loaded = gm.load_model(tmp_path / "model.npz")
    unpickled = pickle.loads(pickle.dumps(model))
    for other in (loaded, unpickled):
        assert type(other) is MultiOutputFIR and other.n_outputs_ == 3
        assert repr(other.get_params()) == repr(model.get_params())
        np.testing.assert_array_equal(other.coef_, model.coef_)
        np.testing.assert_array_equal(other.predict(u_new), model.predict(u_new))
        for a, b in zip(other.estimators_, model.estimators_):
            assert_same_fit(a, b)
        band, expected = (m.frequency_response(input=0, output=2) for m in (other, model))
        np.testing.assert_array_equal(band.magnitude_lower, expected.magnitude_lower)


def read_members(path):
    with np.load(path, allow_pickle=False) as archive:
        members = {key: archive[key] for key in archive.files}
    return json.loads(bytes(members.pop("header")).decode("utf-8")), members


def test_file_layout_stores_the_shared_input_once(fitted, data, tmp_path):
    model = fitted["gp"]
    gm.save_model(model, tmp_path / "model.npz")
    header, members = read_members(tmp_path / "model.npz")
    assert header["format_version"] == 3 and header["estimator"] == "MultiOutputFIR"
    assert header["template"]["estimator"] == "FIRGaussianProcess"
    outputs = header["fitted"]["outputs"]
    assert header["fitted"]["n_outputs"] == len(outputs) == 3
    assert [o["format_version"] for o in outputs] == [2, 2, 2]  # two inputs: records layout
    inputs = {o["arrays"]["u_0"] for o in outputs}
    assert len(inputs) == 1
    np.testing.assert_array_equal(members[inputs.pop()], data[0])
    slow = [members[o["arrays"]["y_slow_0"]] for o in outputs]
    assert [s.shape[0] for s in slow] == [M, M - 3, M - 1]


def test_one_input_outputs_use_layout_one(data, tmp_path):
    u, y_slow, u_new = data
    model = MultiOutputFIR(ESTIMATORS["ls"]()).fit(u[:, 0], np.nan_to_num(y_slow))
    gm.save_model(model, tmp_path / "model.npz")
    header, _ = read_members(tmp_path / "model.npz")
    assert [o["format_version"] for o in header["fitted"]["outputs"]] == [1, 1, 1]
    loaded = gm.load_model(tmp_path / "model.npz")
    np.testing.assert_array_equal(loaded.predict(u_new[:, 0]), model.predict(u_new[:, 0]))


def test_tampered_multi_output_file_refused(fitted, tmp_path):
    path = tmp_path / "model.npz"
    gm.save_model(fitted["ls"], path)
    raw = bytearray(path.read_bytes())
    start = raw.find(fitted["ls"].estimators_[1].coef_covariance_.tobytes()[:64])
    assert start > 0
    raw[start + 9] ^= 0x01
    path.write_bytes(bytes(raw))
    with pytest.raises(ModelFileError):
        gm.load_model(path)


def test_saving_refuses_a_template_it_cannot_store(fitted):
    model = clone(fitted["ls"])
    model.__dict__.update({k: v for k, v in fitted["ls"].__dict__.items() if k.endswith("_")})
    model.estimator = object()
    with pytest.raises(TypeError, match="estimator of a MultiOutputFIR"):
        gm.save_model(model, io.BytesIO())


@pytest.mark.slow
def test_importing_the_package_imports_no_dask():
    code = ("import sys, gpmultirate, gpmultirate.multioutput, gpmultirate.persistence; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed')))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, cwd=pathlib.Path(__file__).resolve().parents[1])
    assert done.stdout.strip() == "[]"


def test_nested_lists_are_one_record_when_u_is_one(data):
    u, y_slow, _ = data
    y = np.nan_to_num(y_slow)
    from_lists = MultiOutputFIR(ESTIMATORS["ls"]()).fit(u[:, 0].tolist(), y.tolist())
    from_arrays = MultiOutputFIR(ESTIMATORS["ls"]()).fit(u[:, 0], y)
    assert from_lists.n_outputs_ == 3
    np.testing.assert_array_equal(from_lists.coef_, from_arrays.coef_)


def checksum(header, arrays):
    """SHA-256 as the persistence module documents it, to forge files with valid checksums."""
    digest = hashlib.sha256()
    content = {key: value for key, value in header.items() if key != "sha256"}
    digest.update(json.dumps(content, sort_keys=True, separators=(",", ":")).encode() + b"\n")
    for name in sorted(arrays):
        a = arrays[name]
        digest.update(f"{name}:{a.dtype.str}:{','.join(map(str, a.shape))}\n".encode())
        digest.update(a.tobytes())
    return digest.hexdigest()


def forge(path, edit):
    header, members = read_members(path)
    edit(header, members)
    header["sha256"] = checksum(header, members)
    encoded = np.frombuffer(json.dumps(header).encode("utf-8"), dtype=np.uint8)
    with open(path, "wb") as file:
        np.savez(file, header=encoded, **members)


def test_forged_file_with_a_valid_checksum_loads_the_same(fitted, tmp_path):
    """The checksum above is the module's: an unchanged forged file loads."""
    path = tmp_path / "model.npz"
    gm.save_model(fitted["ls"], path)
    forge(path, lambda header, members: None)
    np.testing.assert_array_equal(gm.load_model(path).coef_, fitted["ls"].coef_)


def first_output(edit):
    return lambda header, members: edit(header["fitted"]["outputs"][0])


INCONSISTENT = {
    "missing array": first_output(lambda o: o["arrays"].update(coef="array_99")),
    "array not used": lambda h, m: m.update(array_99=np.zeros(3)),
    "nested version 3": first_output(lambda o: o.update(format_version=3)),
    "unknown template": lambda h, m: h["template"].update(estimator="Evil"),
    "unknown parameter": lambda h, m: h["params"].update(callback="print"),
    "bad n_jobs": lambda h, m: h["params"].update(n_jobs=0),
    "n_outputs": lambda h, m: h["fitted"].update(n_outputs=4),
    "no outputs": lambda h, m: h["fitted"].update(n_outputs=0, outputs=[]),
    "extra entry": first_output(lambda o: o.update(code="print")),
    "other estimator": first_output(lambda o: o.update(estimator="MultiOutputFIR")),
}


@pytest.mark.parametrize("edit", INCONSISTENT.values(), ids=list(INCONSISTENT))
def test_inconsistent_multi_output_file_refused(fitted, tmp_path, edit):
    path = tmp_path / "model.npz"
    gm.save_model(fitted["ls"], path)
    forge(path, edit)
    with pytest.raises(ModelFileError):
        gm.load_model(path)


def test_predict_command_writes_every_output(fitted, data, tmp_path):
    from gpmultirate.cli import main

    u, _, u_new = data
    model = fitted["gp"]
    gm.save_model(model, tmp_path / "model.npz")
    columns = "u0,u1\n" + "".join(f"{a!r},{b!r}\n" for a, b in u_new.tolist())
    (tmp_path / "new.csv").write_text(columns)
    assert main(["predict", str(tmp_path / "model.npz"), str(tmp_path / "new.csv"), "--input",
                 "u0", "u1", "--out", str(tmp_path / "p.csv"), "--quiet"]) == 0
    table = np.genfromtxt(tmp_path / "p.csv", delimiter=",", names=True)
    assert table.dtype.names == ("index", "time", "y_0", "y_std_0", "y_1", "y_std_1",
                                 "y_2", "y_std_2")
    mean, std = model.predict(u_new, return_std=True)
    for j in range(3):
        np.testing.assert_array_equal(table[f"y_{j}"], mean[:, j])
        np.testing.assert_array_equal(table[f"y_std_{j}"], std[:, j])


def test_outputs_whose_default_order_is_cut_differently_share_one_lag_axis(tmp_path):
    # the same fixed long prior for a slow response measured with little noise and a
    # fast one in heavy noise: the held-out check cuts the second order further
    from sklearn.gaussian_process.kernels import ConstantKernel

    from gpmultirate.kernels import DC

    rng = np.random.default_rng(4)
    u = rng.standard_normal(600)
    y_long = np.convolve(u, 0.99 ** np.arange(600))[:600] + 0.01 * rng.standard_normal(600)
    y_short = np.convolve(u, 0.6 ** np.arange(20))[:600] + 0.5 * rng.standard_normal(600)
    y_slow = np.column_stack([y_long, y_short])[::3]
    kernel = ConstantKernel(1.0, "fixed") * DC(alpha=0.999, beta=0.5, alpha_bounds="fixed",
                                               beta_bounds="fixed")
    model = gm.MultiOutputFIR(gm.FIRGaussianProcess(kernel, factor=3)).fit(u, y_slow)
    orders = [e.coef_.shape[0] for e in model.estimators_]
    assert orders[0] > orders[1]
    assert model.coef_.shape == (2, orders[0])
    np.testing.assert_array_equal(model.coef_[0], model.estimators_[0].coef_)
    np.testing.assert_array_equal(model.coef_[1, : orders[1]], model.estimators_[1].coef_)
    assert not np.any(model.coef_[1, orders[1]:])
    # the padded coefficients are the model: the same prediction as the short FIR
    u_new = rng.standard_normal(300)
    prediction = model.predict(u_new)
    for j in range(2):
        np.testing.assert_allclose(prediction[:, j], np.convolve(u_new, model.coef_[j])[:300],
                                   rtol=1e-10, atol=1e-12)
    gm.save_model(model, tmp_path / "m.npz")
    loaded = gm.load_model(tmp_path / "m.npz")
    np.testing.assert_array_equal(loaded.coef_, model.coef_)
    np.testing.assert_array_equal(loaded.predict(u_new), prediction)


def test_predict_include_noise_is_each_outputs_measurement_band():
    rng = np.random.default_rng(5)
    u = rng.standard_normal(240)
    g = 0.7 ** np.arange(20)
    y_fast = np.convolve(u, g)[:240]
    Y = np.column_stack([y_fast[::3], -2 * y_fast[::3]]) + 0.05 * rng.standard_normal((80, 2))
    model = MultiOutputFIR(FIRGaussianProcess(factor=3, order=20)).fit(u, Y)
    mean, std = model.predict(u, return_std=True, include_noise=True)
    for j, estimator in enumerate(model.estimators_):
        m_j, s_j = estimator.predict(u, return_std=True, include_noise=True)
        np.testing.assert_allclose(mean[:, j], m_j)
        np.testing.assert_allclose(std[:, j], s_j)
        assert np.all(s_j > estimator.predict(u, return_std=True)[1])
    with pytest.raises(ValueError, match="return_std"):
        model.predict(u, include_noise=True)


def test_an_all_nan_output_column_is_named():
    rng = np.random.default_rng(6)
    u = rng.standard_normal(120)
    Y = np.column_stack([rng.standard_normal(40), np.full(40, np.nan), rng.standard_normal(40)])
    with pytest.raises(ValueError, match=r"column 1 \(output 1\)"):
        MultiOutputFIR(FIRGaussianProcess(factor=3, order=10)).fit(u, Y)
