"""Residual analysis: correlations against direct sums, bands against the asymptotic
formulas and Monte Carlo, the whiteness verdict on white and AR(1) residuals."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from scipy import signal, stats  # noqa: E402
from sklearn.gaussian_process.kernels import ConstantKernel as C  # noqa: E402

import gpmultirate as gm  # noqa: E402
from gpmultirate.kernels import DC  # noqa: E402
from gpmultirate.plotting import plot_residuals  # noqa: E402
from gpmultirate.residuals import analyze_residuals, residual_correlations  # noqa: E402

Z99 = 2.5758293035489  # two-sided 99 % normal quantile


def _ar1(rng, n, pole):
    return signal.lfilter([1.0], [1.0, -pole], rng.standard_normal(n))


def _analysis(e, max_lag=20, u=None, input_lags=(0,), confidence=0.99):
    n = e.shape[0]
    return residual_correlations(e, np.arange(n), np.ones(n) if u is None else u,
                                 max_lag=max_lag, input_lags=np.asarray(input_lags),
                                 confidence=confidence)


def test_autocorrelation_and_ljung_box_against_direct_formulas():
    rng = np.random.default_rng(0)
    e = _ar1(rng, 300, 0.3)
    a = _analysis(e, max_lag=15)
    full = np.correlate(e, e, mode="full")[299:] / (e @ e)
    np.testing.assert_allclose(a.autocorrelation, full[:16], rtol=1e-12, atol=1e-15)
    N = 300
    k = np.arange(1, 16)
    q = N * (N + 2) * np.sum(full[1:16] ** 2 / (N - k))
    assert a.ljung_box == pytest.approx(q, rel=1e-12)
    assert a.p_value == pytest.approx(stats.chi2.sf(q, 15), rel=1e-10)
    # Bartlett: z / sqrt(N) to first order in k / N
    np.testing.assert_allclose(a.autocorrelation_bound, Z99 * np.sqrt(N - np.arange(16)) / N,
                               rtol=1e-9)
    np.testing.assert_allclose(a.autocorrelation_bound[1:], Z99 / np.sqrt(N),
                               rtol=15 / (2 * N) + 1e-3)
    assert a.confidence == 0.99 and a.n_residuals == 300


def test_confidence_level_changes_the_band():
    e = np.random.default_rng(1).standard_normal(200)
    a95 = _analysis(e, confidence=0.95)
    assert a95.autocorrelation_bound[1] == pytest.approx(1.959964 * np.sqrt(199) / 200,
                                                         rel=1e-6)


def test_band_holds_its_level_in_monte_carlo():
    rng = np.random.default_rng(2)
    N, draws = 250, 3000
    E = rng.standard_normal((draws, N))
    r1 = np.sum(E[:, :-1] * E[:, 1:], axis=1) / np.sum(E * E, axis=1)
    r5 = np.sum(E[:, :-5] * E[:, 5:], axis=1) / np.sum(E * E, axis=1)
    a = _analysis(E[0], max_lag=5)
    for r, k in ((r1, 1), (r5, 5)):
        outside = np.mean(np.abs(r) > a.autocorrelation_bound[k])
        assert 0.004 < outside < 0.02  # 0.01 expected; binomial sd 0.0018


def test_band_with_gaps_counts_the_measured_pairs():
    rng = np.random.default_rng(3)
    N, draws = 300, 3000
    missing = rng.random(N) < 0.3
    e0 = rng.standard_normal(N)
    e0[missing] = np.nan
    a = _analysis(e0, max_lag=3)
    present = ~missing
    pairs = np.sum(present[:-2] & present[2:])
    n = present.sum()
    assert a.autocorrelation_bound[2] == pytest.approx(Z99 * np.sqrt(pairs) / n, rel=1e-12)
    # direct lag-2 sum over the measured pairs
    filled = np.where(present, e0, 0.0)
    assert a.autocorrelation[2] == pytest.approx(
        np.sum(filled[:-2] * filled[2:]) / np.sum(filled**2), rel=1e-12)
    E = np.where(present, rng.standard_normal((draws, N)), 0.0)
    r2 = np.sum(E[:, :-2] * E[:, 2:], axis=1) / np.sum(E * E, axis=1)
    assert 0.004 < np.mean(np.abs(r2) > a.autocorrelation_bound[2]) < 0.02


def test_verdict_white_on_white_residuals_in_most_draws():
    rng = np.random.default_rng(4)
    verdicts = [_analysis(rng.standard_normal(400)).white for _ in range(300)]
    assert np.mean(verdicts) >= 0.96  # 0.99 expected


def test_verdict_not_white_on_ar1_residuals():
    rng = np.random.default_rng(5)
    verdicts = [_analysis(_ar1(rng, 400, 0.5)).white for _ in range(100)]
    assert np.mean(verdicts) <= 0.05
    assert _analysis(_ar1(rng, 400, 0.5)).share_outside > 0.1


def test_cross_correlation_against_direct_computation():
    rng = np.random.default_rng(6)
    N, F = 301, 3
    u = rng.standard_normal((N, 2)) + [0.0, 0.5]
    index = np.arange(1, N, F)
    e = rng.standard_normal(index.shape[0])
    e[4] = np.nan
    lags = np.arange(-7, 12)
    a = residual_correlations(e, index, u, max_lag=5, input_lags=lags, confidence=0.99)
    measured = np.isfinite(e)
    n = measured.sum()
    rms_e = np.sqrt(np.nansum(e**2) / n)
    for j in range(2):
        rms_u = np.sqrt(np.mean(u[:, j] ** 2))
        for t, tau in enumerate(lags):
            total, square = 0.0, 0.0
            for m, i in enumerate(index):
                if measured[m] and 0 <= i - tau < N:
                    total += e[m] * u[i - tau, j]
                    square += u[i - tau, j] ** 2
            assert a.cross_correlation[j, t] == pytest.approx(total / (n * rms_e * rms_u),
                                                              rel=1e-10, abs=1e-14)
            assert a.cross_correlation_bound[j, t] == pytest.approx(
                Z99 * np.sqrt(square) / (n * rms_u), rel=1e-10)


def test_cross_correlation_band_in_monte_carlo():
    rng = np.random.default_rng(7)
    N, draws, tau = 600, 4000, 4
    u = _ar1(rng, N, 0.8)[:, None]  # a coloured input: the band is conditional on it
    index = np.arange(0, N, 2)
    a0 = residual_correlations(rng.standard_normal(index.shape[0]), index, u, max_lag=3,
                               input_lags=[tau], confidence=0.99)
    # the statistic of each draw, as the direct computation above checks it
    E = rng.standard_normal((draws, index.shape[0]))
    source = index - tau
    inside = source >= 0
    rms_e = np.sqrt(np.mean(E * E, axis=1))
    rms_u = np.sqrt(np.mean(u[:, 0] ** 2))
    c = E[:, inside] @ u[source[inside], 0] / (index.shape[0] * rms_e * rms_u)
    assert np.isclose(c[0], residual_correlations(E[0], index, u, max_lag=3, input_lags=[tau],
                                                  confidence=0.99).cross_correlation[0, 0])
    outside = np.mean(np.abs(c) > a0.cross_correlation_bound[0, 0])
    assert 0.004 < outside < 0.02  # 0.01 expected; binomial sd 0.0016


def _system(rng, N, noise, frequency=0.5):
    u = rng.standard_normal(N)
    g = 0.8 ** np.arange(30) * np.cos(frequency * np.arange(30))
    return u, np.convolve(u, g)[:N] + noise


@pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
def test_analyze_residuals_of_fitted_models():
    rng = np.random.default_rng(8)
    N, F = 1200, 3
    u, y = _system(rng, N, 0.05 * rng.standard_normal(N))
    ls = gm.LeastSquaresFIR(factor=F, order=30, offset=1).fit(u, y[1::F])
    a = analyze_residuals(ls, u, y[1::F])
    np.testing.assert_allclose(a.residuals, y[1::F] - ls.predict(u)[1::F])
    np.testing.assert_array_equal(a.sample_indices, np.arange(1, N, F))
    assert a.white
    assert a.input_lags[0] == -25 * F and a.input_lags[-1] == 25 * F
    u, y = _system(rng, N, 0.05 * rng.standard_normal(N), frequency=0.0)
    gp = gm.FIRGaussianProcess(C(1.0) * DC(), factor=F, order=30).fit(u, y[::F])
    assert analyze_residuals(gp, u, y[::F]).white
    u, y = _system(rng, N, 0.05 * rng.standard_normal(N))
    # a model too short leaves the response at lags 5.. in the cross-correlation
    short = gm.LeastSquaresFIR(factor=F, order=5).fit(u, y[::F])
    cut = analyze_residuals(short, u, y[::F], input_lags=np.arange(0, 30))
    assert np.all(np.abs(cut.cross_correlation[0, 5:8]) > cut.cross_correlation_bound[0, 5:8])
    assert np.all(np.abs(cut.cross_correlation[0, :5]) < cut.cross_correlation_bound[0, :5])


@pytest.mark.slow
def test_analyze_residuals_white_in_most_monte_carlo_fits_and_not_with_ar1_noise():
    rng = np.random.default_rng(9)
    N, F = 900, 3
    white, coloured = [], []
    for _ in range(40):
        u, y = _system(rng, N, 0.1 * rng.standard_normal(N))
        white.append(analyze_residuals(gm.LeastSquaresFIR(factor=F, order=30).fit(u, y[::F]),
                                       u, y[::F]).white)
        u, y = _system(rng, N, 0.1 * _ar1(rng, N, 0.95))
        coloured.append(analyze_residuals(
            gm.LeastSquaresFIR(factor=F, order=30).fit(u, y[::F]), u, y[::F]).white)
    assert np.mean(white) >= 0.9
    assert np.mean(coloured) <= 0.1


def test_sample_indices_and_discarded_samples():
    rng = np.random.default_rng(10)
    N = 600
    u, y = _system(rng, N, 0.05 * rng.standard_normal(N))
    index = np.sort(rng.choice(N, 200, replace=False))
    model = gm.LeastSquaresFIR(order=30).fit(u, y[index], sample_indices=index)
    a = analyze_residuals(model, u, y[index], index, input_lags=np.arange(3))
    np.testing.assert_allclose(a.residuals, y[index] - model.predict(u)[index])
    discard = gm.LeastSquaresFIR(factor=3, order=30, initial_conditions="discard").fit(u, y[::3])
    b = analyze_residuals(discard, u, y[::3])
    skipped = np.arange(0, N, 3) < 29
    assert np.all(np.isnan(b.residuals[skipped])) and np.all(np.isfinite(b.residuals[~skipped]))
    assert b.n_residuals == np.sum(~skipped)
    with_gap = y[::3].copy()
    with_gap[50] = np.nan
    assert analyze_residuals(model.set_params(), u, with_gap, np.arange(0, N, 3)).n_residuals == 199


def test_readings_at_their_own_instants():
    rng = np.random.default_rng(11)
    N = 240
    u, y = _system(rng, N, 0.0 * rng.standard_normal(N))
    times = np.arange(1, N - 3, 3) + rng.uniform(0.0, 1.0, 79)
    g = np.convolve(u, np.ones(2))[:N]  # any readings: the residuals are what is checked
    readings = np.interp(times, np.arange(N), g) + 0.01 * rng.standard_normal(times.shape[0])
    model = gm.FIRGaussianProcess(order=20, exposure=0.3, noise_kernel="white").fit(
        u, readings, sample_times=times)
    a = analyze_residuals(model, u, readings, sample_times=times, input_lags=np.arange(3))
    np.testing.assert_allclose(a.residuals, readings - model.predict(u, sample_times=times))
    np.testing.assert_array_equal(a.sample_indices, np.floor(times).astype(int))
    with pytest.raises(ValueError, match="not both"):
        analyze_residuals(model, u, readings, np.floor(times).astype(int), sample_times=times)
    with pytest.raises(ValueError, match="^sample_times"):
        analyze_residuals(model, u, readings, sample_times=times[:-1])


def test_arguments_are_checked_and_not_modified():
    rng = np.random.default_rng(11)
    u, y = _system(rng, 300, 0.05 * rng.standard_normal(300))
    model = gm.LeastSquaresFIR(factor=3, order=10).fit(u, y[::3])
    y_slow = y[::3].copy()
    before = y_slow.copy()
    analyze_residuals(model, u, y_slow)
    np.testing.assert_array_equal(y_slow, before)
    with pytest.raises(ValueError, match="y_slow"):
        analyze_residuals(model, u, y_slow[:-1])
    with pytest.raises(ValueError, match="max_lag"):
        analyze_residuals(model, u, y_slow, max_lag=0)
    with pytest.raises(ValueError, match="max_lag"):
        analyze_residuals(model, u, y_slow, max_lag=200)
    with pytest.raises(ValueError, match="confidence"):
        analyze_residuals(model, u, y_slow, confidence=1.5)
    with pytest.raises(ValueError, match="input_lags"):
        analyze_residuals(model, u, y_slow, input_lags=3)
    with pytest.raises(ValueError, match="input_lags"):
        analyze_residuals(model, u, y_slow, input_lags=[0.5])
    a = analyze_residuals(model, u, y_slow)
    with pytest.raises(ValueError):
        a.autocorrelation[0] = 2.0


def test_plot_residuals_draws_the_analysis():
    rng = np.random.default_rng(12)
    e = _ar1(rng, 300, 0.6)
    u = rng.standard_normal((300, 2))
    a = residual_correlations(e, np.arange(300), u, max_lag=12, input_lags=np.arange(-4, 5),
                              confidence=0.99)
    drawn = plot_residuals(a)
    assert len(drawn.axes) == 3 and len(drawn.cross_correlation_stems) == 2
    tops = [segment[1, 1] for segment in drawn.autocorrelation_stems.get_segments()]
    np.testing.assert_allclose(tops, a.autocorrelation[1:])
    tops = [segment[1, 1] for segment in drawn.cross_correlation_stems[1].get_segments()]
    np.testing.assert_allclose(tops, a.cross_correlation[1])
    assert "not white" in drawn.axes[0].get_title()
    fig, ax = plt.subplots()
    single = plot_residuals(a, ax=ax)
    assert single.axes == [ax] and single.cross_correlation_stems == []
    with pytest.raises(ValueError, match="ax"):
        plot_residuals(a, ax="axes")
    with pytest.raises(ValueError, match="analysis"):
        plot_residuals(e)
    plt.close("all")


def test_all_nan_record_is_named_not_max_lag():
    rng = np.random.default_rng(2)
    u = rng.standard_normal(300)
    y = np.convolve(u, 0.5 ** np.arange(10))[:300:3]
    model = gm.LeastSquaresFIR(factor=3, order=10).fit(u, y)
    with pytest.raises(ValueError, match="0 measured") as info:
        analyze_residuals(model, u, np.full(100, np.nan))
    assert "max_lag" not in str(info.value)
    with pytest.raises(ValueError, match="max_lag must be >= 1; got 0"):
        analyze_residuals(model, u, y, max_lag=0)


@pytest.mark.parametrize("scale", [1e-300, 1e211, 1e300])
def test_correlations_are_scale_free_near_the_float_range(scale):
    rng = np.random.default_rng(8)
    e = rng.standard_normal(200)
    u = rng.standard_normal(600)
    index = np.arange(0, 600, 3)
    reference = residual_correlations(e, index, u, max_lag=10, input_lags=np.arange(-5, 6),
                                      confidence=0.95)
    scaled = residual_correlations(e * scale, index, u / scale, max_lag=10,
                                   input_lags=np.arange(-5, 6), confidence=0.95)
    np.testing.assert_allclose(scaled.autocorrelation, reference.autocorrelation, rtol=1e-12)
    np.testing.assert_allclose(scaled.cross_correlation, reference.cross_correlation,
                               rtol=1e-10, atol=1e-14)
    assert scaled.p_value == pytest.approx(reference.p_value, rel=1e-10)
