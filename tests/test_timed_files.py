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
    model = gm.FIRGaussianProcess(C(1.5) * DC(0.8, 0.5), order=P, exposure=0.5, latency=0.3,
                                  optimizer=None, noise_level=1e-4, sample_time=0.01)
    model.fit(us, ys, sample_times=stamps)
    buffer, loaded = _saved_and_loaded(model)
    header, names = _header(buffer)
    assert header["format_version"] == 4 and header["fitted"]["layout"] == "timed"
    assert header["params"]["exposure"] == 0.5 and header["params"]["latency"] == 0.3
    assert "sample_times_1" in names and "sample_indices_0" not in names
    # the missing reading is not stored; the stamps of the others are, exactly
    times = model.observation_.records[0].sample_times
    np.testing.assert_array_equal(loaded.observation_.records[0].sample_times, times)
    assert times.shape[0] == len(stamps[0]) - 1
    assert isinstance(loaded.observation_, gm.TimedConvolution)
    assert loaded.observation_ == model.observation_
    assert loaded.get_params() == model.get_params()
    assert loaded.log_marginal_likelihood_value_ == model.log_marginal_likelihood_value_
    _assert_same_predictions(model, loaded, us, [np.array([5.5, 20.25, 40.7]),
                                                 np.array([0.2, 7.1, 8.2])])


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
    assert header["format_version"] == 4
    assert [o["format_version"] for o in header["fitted"]["outputs"]] == [4, 4]
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


def test_other_quadrature_is_reported():
    u, y, stamps = _record(9)
    model = gm.FIRGaussianProcess(C(1.0) * DC(0.8, 0.5), order=P, exposure=0.5,
                                  optimizer=None, noise_level=1e-4).fit(u, y, sample_times=stamps)
    buffer, _ = _saved_and_loaded(model)
    with pytest.warns(UserWarning, match="quadrature nodes"):
        gm.load_model(_forge(buffer, lambda h, m: h["fitted"].update(quadrature_nodes=8)))
