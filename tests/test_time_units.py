"""Times in the user's units: stamps, exposure and latency in the units of ``sample_time``.

The reference of every comparison is the same fit with the times given in
fast sample periods and ``sample_time`` 1 (the observations' own units, whose
numbers are tested against dense closed forms in ``test_timed.py``).
"""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate.kernels import DC
from gpmultirate.residuals import analyze_residuals
from gpmultirate.units import in_fast_periods

T = 0.001
N, P, F = 240, 20, 3


def _camera(seed=0, n=N):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    g = 0.8 ** np.arange(P) * np.cos(0.6 * np.arange(P))
    ticks = np.arange(2, n - 3, F)
    times = ticks + rng.uniform(0.05, 0.95, ticks.shape[0])
    y = np.convolve(u, g)[:n][ticks] + 1e-2 * rng.standard_normal(ticks.shape[0])
    return u, y, times


def _fixed(**params):
    return gm.FIRGaussianProcess(C(1.0) * DC(0.8, 0.5), order=P, optimizer=None,
                                 noise_level=1e-4, **params)


def test_stamps_in_seconds_fit_like_fast_periods():
    # the case: sample_time=0.001 and a camera log's stamps in seconds
    u, y, times = _camera()
    stamps = times * T
    reference = gm.FIRGaussianProcess(order=P).fit(u, y, sample_times=times)
    seconds = gm.FIRGaussianProcess(order=P, sample_time=T).fit(u, y, sample_times=stamps)
    np.testing.assert_allclose(seconds.coef_, reference.coef_, rtol=1e-10, atol=1e-12)
    assert seconds.noise_level_ == pytest.approx(reference.noise_level_, rel=1e-10)
    assert seconds.log_marginal_likelihood_value_ == pytest.approx(
        reference.log_marginal_likelihood_value_, rel=1e-10)
    np.testing.assert_array_equal(stamps, times * T)  # the caller's array is untouched


def test_exposure_latency_and_predictions_in_seconds():
    u, y, times = _camera(1)
    reference = _fixed(exposure=0.5, latency=0.2).fit(u, y, sample_times=times)
    seconds = _fixed(exposure=0.5 * T, latency=0.2 * T, sample_time=T).fit(
        u, y, sample_times=times * T)
    np.testing.assert_allclose(seconds.coef_, reference.coef_, rtol=1e-10, atol=1e-13)
    new = np.array([10.25, 57.5, 123.875, 200.0])
    ours = seconds.predict(u, return_std=True, include_noise=True, sample_times=new * T)
    theirs = reference.predict(u, return_std=True, include_noise=True, sample_times=new)
    for a, b in zip(ours, theirs):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-13)
    ours = analyze_residuals(seconds, u, y, sample_times=times * T, max_lag=10)
    theirs = analyze_residuals(reference, u, y, sample_times=times, max_lag=10)
    np.testing.assert_allclose(ours.residuals, theirs.residuals, rtol=1e-9, atol=1e-12)


def test_several_records_and_least_squares_on_the_ticks():
    u, y, times = _camera(2)
    v, z, other = _camera(3, n=150)
    reference = _fixed().fit([u, v], [y, z], sample_times=[times, other])
    seconds = _fixed(sample_time=T).fit([u, v], [y, z], sample_times=[times * T, other * T])
    np.testing.assert_allclose(seconds.coef_, reference.coef_, rtol=1e-10, atol=1e-13)
    # ticks in seconds stay ticks, whatever the rounding of t / T
    ticks = np.arange(2, N - 3, F)
    y_ticks = np.convolve(u, 0.7 ** np.arange(P))[:N][ticks]
    a = gm.LeastSquaresFIR(order=P).fit(u, y_ticks, sample_indices=ticks)
    logged = np.array([float(f"{k * T:.6g}") for k in ticks])  # as a log file writes them
    assert np.any(logged / T != ticks)  # the division alone would take some off their tick
    np.testing.assert_array_equal(in_fast_periods(logged, T), ticks)
    b = gm.LeastSquaresFIR(order=P, sample_time=T).fit(u, y_ticks, sample_times=logged)
    np.testing.assert_array_equal(a.coef_, b.coef_)


def test_squeezed_stamps_name_the_unit_mix_up():
    u, y, times = _camera(4)
    with pytest.raises(ValueError, match="look like seconds while sample_time is 1.0"):
        gm.FIRGaussianProcess(order=P).fit(u, y, sample_times=times * T)
    with pytest.raises(ValueError, match="look like seconds"):
        _fixed().fit(u, y[:5], sample_times=np.arange(5) * 0.2)
    model = _fixed(sample_time=T).fit(u, y, sample_times=times * T)
    with pytest.raises(ValueError, match="units of sample_time"):
        model.predict(u, sample_times=times)  # fast periods given to a model in seconds
    with pytest.raises(ValueError, match="units of sample_time"):
        _fixed(sample_time=T).fit(u, y, sample_times=times)
    # a few readings early in the record are no mix-up
    early = _fixed().fit(u, y[:3], sample_times=[0.5, 2.5, 4.5])
    assert early.coef_.shape == (P,)


def test_plot_intersample_takes_stamps_in_seconds():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from gpmultirate.plotting import plot_intersample

    u, y, times = _camera(5)
    reference = _fixed(exposure=0.5).fit(u, y, sample_times=times)
    seconds = _fixed(exposure=0.5 * T, sample_time=T).fit(u, y, sample_times=times * T)
    window = (30, 60)
    a = plot_intersample(reference, u, y_slow=y, sample_times=times, window=window,
                         sample_time=T, between=4)
    b = plot_intersample(seconds, u, y_slow=y, sample_times=times * T, window=window,
                         between=4)
    np.testing.assert_allclose(b.mean_line.get_xdata(), a.mean_line.get_xdata(), rtol=1e-12)
    np.testing.assert_allclose(b.mean_line.get_ydata(), a.mean_line.get_ydata(), rtol=1e-8,
                               atol=1e-12)
    shown = (times >= window[0]) & (times < window[1])
    np.testing.assert_allclose(b.slow_markers.get_xdata(), times[shown] * T, rtol=1e-12)
    plt.close("all")


def test_many_outputs_take_the_estimators_units():
    u, y, times = _camera(6)
    y2 = 0.5 * y + 0.01
    reference = gm.MultiOutputFIR(_fixed()).fit(u, np.column_stack([y, y2]), sample_times=times)
    seconds = gm.MultiOutputFIR(_fixed(sample_time=T)).fit(
        u, np.column_stack([y, y2]), sample_times=times * T)
    new = np.array([4.5, 9.2, 100.0])
    for a, b in zip(seconds.predict(u, return_std=True, sample_times=new * T),
                    reference.predict(u, return_std=True, sample_times=new)):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-13)


def test_a_fine_grid_at_the_start_is_no_unit_mix_up():
    # predict takes instants as fine as wanted: only readings are checked for squeezing
    u, y, times = _camera(7)
    model = _fixed().fit(u, y, sample_times=times)
    grid = np.arange(0, 80) / 8  # ten fast periods, eight instants in each
    mean = model.predict(u, sample_times=grid)
    np.testing.assert_allclose(mean[::8], model.predict(u)[:10], rtol=1e-9, atol=1e-12)
    with pytest.raises(ValueError, match="look like seconds"):
        analyze_residuals(model, u, y, sample_times=times * T)
