"""The estimators with readings at their own instants (sample_times, exposure, latency)."""

import numpy as np
import pytest
from scipy import linalg
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate.kernels import DC

from test_timed import _dense_reference

N, F, P = 90, 3, 12


def _data(seed=0):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(N)
    g = 0.8 ** np.arange(P) * np.cos(0.6 * np.arange(P))
    ticks = np.arange(0, N, F)
    y = np.convolve(u, g)[:N][ticks] + 1e-2 * rng.standard_normal(ticks.shape[0])
    times = ticks + rng.uniform(0, 1, ticks.shape[0])
    return u, y, ticks, times


def test_times_on_the_ticks_give_the_fit_of_the_indices():
    u, y, ticks, _ = _data()
    a = gm.FIRGaussianProcess(C(1.0) * DC(), order=P).fit(u, y, sample_indices=ticks)
    b = gm.FIRGaussianProcess(C(1.0) * DC(), order=P).fit(u, y, sample_times=ticks * 1.0)
    assert np.allclose(a.coef_, b.coef_)
    assert np.isclose(a.log_marginal_likelihood_value_, b.log_marginal_likelihood_value_)
    # a latency of whole periods: the stamps are late by it
    c = gm.FIRGaussianProcess(C(1.0) * DC(), order=P, latency=2.0).fit(
        u, y[:-1], sample_times=ticks[:-1] + 2.0)
    d = gm.FIRGaussianProcess(C(1.0) * DC(), order=P).fit(u, y[:-1], sample_indices=ticks[:-1])
    assert np.allclose(c.coef_, d.coef_)


def test_prediction_at_the_ticks_is_predict():
    u, y, ticks, times = _data()
    for model in (
        gm.FIRGaussianProcess(C(1.0) * DC(), order=P).fit(u, y, sample_indices=ticks),
        gm.FIRGaussianProcess(C(1.0) * DC(), order=P).fit(u, y, sample_times=times),
    ):
        mean, std = model.predict(u, return_std=True)
        at_ticks, at_std = model.predict(u, sample_times=np.arange(N, dtype=float), return_std=True)
        assert np.allclose(at_ticks, mean, rtol=1e-6, atol=1e-7 * np.abs(mean).max())
        assert np.allclose(at_std, std, rtol=1e-5, atol=1e-6 * std.max())


def test_readings_predicted_as_a_dense_gaussian_conditional():
    _check_readings(0.0, 1e-6, 1)


@pytest.mark.slow
def test_readings_with_exposure_predicted_as_a_dense_gaussian_conditional():
    _check_readings(0.4, 1e-4, 96)


def _check_readings(exposure, tol, n):
    # fixed hyperparameters: the readings' mean and std are S (S + g I)^{-1} y and its variance
    u, y, ticks, times = _data(1)
    kernel = C(0.8) * DC(0.75, 0.7)
    noise = 1e-3
    # the reference's record: N = 24 fast samples, order 7
    u, y, times = u[:24], y[:7], times[:7]
    model = gm.FIRGaussianProcess(kernel, order=7, noise_level=noise, optimizer=None,
                                  normalize=False, exposure=exposure, latency=0.3)
    model.fit(u, y, sample_times=times)
    new = np.array([5.5, 17.25, 22.0])
    both = np.concatenate([times, new])
    both_u = u
    S_all = _dense_reference(kernel, both_u, np.sort(both), exposure, 0.3, n=n)
    order = np.argsort(both)
    rank = np.empty_like(order)
    rank[order] = np.arange(order.shape[0])
    S_all = S_all[np.ix_(rank, rank)]
    M = times.shape[0]
    Ky = S_all[:M, :M] + noise * np.eye(M)
    mean_ref = S_all[M:, :M] @ linalg.solve(Ky, y)
    var_ref = np.diag(S_all[M:, M:] - S_all[M:, :M] @ linalg.solve(Ky, S_all[:M, M:]))
    mean, std = model.predict(u, sample_times=new, return_std=True)
    assert np.allclose(mean, mean_ref, rtol=tol, atol=tol * np.abs(mean_ref).max())
    assert np.allclose(std, np.sqrt(var_ref), rtol=tol)


def test_records_and_missing_readings():
    u, y, _, times = _data()
    y = y.copy()
    y[4] = np.nan
    model = gm.FIRGaussianProcess(C(1.0) * DC(), order=P).fit(
        [u[:45], u[45:]], [y[:15], y[15:]], sample_times=[times[:15], times[15:] - 45])
    assert model.y_slow_.shape == (29,)
    assert isinstance(model.operator_, gm.TimedConvolution)


@pytest.mark.slow
def test_two_inputs():
    # several inputs take the dense route (a kernel over (input, lag) pairs)
    u, y, _, times = _data()
    u2 = np.column_stack([u, np.roll(u, 7)])
    model = gm.FIRGaussianProcess(order=6).fit(u2[:45], y[:15],
                                                sample_times=times[:15])
    assert model.coef_.shape == (2, 6)


def test_least_squares_on_the_ticks_only():
    u, y, ticks, times = _data()
    a = gm.LeastSquaresFIR(order=P).fit(u, y, sample_indices=ticks)
    b = gm.LeastSquaresFIR(order=P).fit(u, y, sample_times=ticks * 1.0)
    assert np.allclose(a.coef_, b.coef_)
    with pytest.raises(ValueError, match="no model between the integer lags"):
        gm.LeastSquaresFIR(order=P).fit(u, y, sample_times=times)
    with pytest.raises(ValueError, match="no model between the integer lags"):
        a.predict(u, sample_times=[1.5])


def test_checks():
    u, y, ticks, times = _data()
    with pytest.raises(ValueError, match="not both"):
        gm.FIRGaussianProcess(order=P).fit(u, y, sample_indices=ticks, sample_times=times)
    with pytest.raises(ValueError, match="give sample_times"):
        gm.FIRGaussianProcess(order=P, exposure=0.5).fit(u, y, sample_indices=ticks)
    with pytest.raises(ValueError, match="exposure must be a non-negative"):
        gm.FIRGaussianProcess(order=P, exposure=-0.5).fit(u, y, sample_times=times)
    with pytest.raises(ValueError, match="kernel='auto'"):
        gm.FIRGaussianProcess("auto", order=P).fit(u, y, sample_times=times)
    with pytest.raises(ValueError, match="strictly increasing"):
        gm.FIRGaussianProcess(order=P).fit(u, y, sample_times=times[::-1])
    model = gm.FIRGaussianProcess(exposure=0.5)
    assert model.get_params()["exposure"] == 0.5


def test_saving_a_model_between_the_ticks_is_refused(tmp_path):
    u, y, _, times = _data()
    model = gm.FIRGaussianProcess(C(1.0) * DC(), order=P).fit(u, y, sample_times=times)
    with pytest.raises(ValueError, match="cannot be saved yet"):
        gm.save_model(model, tmp_path / "model.npz")
