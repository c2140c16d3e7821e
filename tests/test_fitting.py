"""The steps of FIRGaussianProcess.fit (gpmultirate.fitting), each on its own.

Each step takes what it needs as arguments and returns what it chose; the
numbers are checked against dense formulas written here.
"""

import warnings
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import ConstantKernel as C
from sklearn.gaussian_process.kernels import Matern

import gpmultirate as gm
from gpmultirate.fitting import auto_kernel, between_ticks, disturbance, order, prior
from gpmultirate.fitting.one_order import fit_at_order
from gpmultirate.fitting.settings import check_settings
from gpmultirate.inference import GaussianCoefficients
from gpmultirate.kernels import DC
from gpmultirate.observations import (
    DownsampledConvolution,
    InterpolatedConvolution,
    TimedConvolution,
    build_experiment,
)

FACTOR = 3


def _dense_regressor(u, order, indices):
    """``Phi[m, i] = u[n_m - i]`` (zero before the record), by loops."""
    Phi = np.zeros((len(indices), order))
    for m, n in enumerate(indices):
        for i in range(order):
            if n - i >= 0:
                Phi[m, i] = u[n - i]
    return Phi


def _dense_log_evidence(Phi, K, y, N):
    S = Phi @ K @ Phi.T + N
    sign, logdet = np.linalg.slogdet(S)
    return float(-0.5 * y @ np.linalg.solve(S, y) - 0.5 * logdet
                 - 0.5 * y.shape[0] * np.log(2 * np.pi))


def _drifting(seed=0, n=240, drift=0.05):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    y = np.convolve(u, 0.85 ** np.arange(30))[:n]
    walk = np.cumsum(drift * rng.standard_normal(n))
    return u, (y + walk + 0.05 * rng.standard_normal(n))[::FACTOR]


# ------------------------------------------------------------ observations
def test_fitted_readings_on_the_ticks_are_the_dense_regressor_times_the_mean():
    rng = np.random.default_rng(0)
    us = [rng.standard_normal((40, 2)), rng.standard_normal((31, 2))]
    ys = [rng.standard_normal(14), rng.standard_normal(11)]
    observation = build_experiment(us, ys, factor=FACTOR, order=6).observation
    coef = rng.standard_normal(12)
    fitted = observation.fitted_readings(SimpleNamespace(coef=coef), None, 1.0)
    for u, got in zip(us, fitted):
        indices = np.arange(0, u.shape[0], FACTOR)
        expected = (_dense_regressor(u[:, 0], 6, indices) @ coef[:6]
                    + _dense_regressor(u[:, 1], 6, indices) @ coef[6:])
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


def test_fitted_readings_at_own_instants_are_the_posterior_mean_of_the_noise_free_part():
    # y - gamma S^-1 y = K_rr S^-1 y, S = K_rr + gamma I: checked with K_rr formed here
    rng = np.random.default_rng(1)
    u = rng.standard_normal(60)
    times = np.arange(2, 60, 3) + rng.uniform(0, 1, 20)
    readings = TimedConvolution(u, times, 15)
    kernel = C(0.5) * DC(0.8, 0.9)
    K_rr = readings.covariance(kernel)
    gamma = 0.05
    y = rng.standard_normal(20)
    alpha = np.linalg.solve(K_rr + gamma * np.eye(20), y)
    fitted = readings.fitted_readings(SimpleNamespace(alpha=alpha), y, gamma)
    assert len(fitted) == 1
    np.testing.assert_allclose(fitted[0], K_rr @ alpha, rtol=1e-8, atol=1e-10)


def test_interpolated_readings_are_read_through_their_regressor():
    rng = np.random.default_rng(2)
    u = rng.standard_normal(300)
    timed = TimedConvolution(u, np.arange(30, 300, 3) + rng.uniform(0, 1, 90), 20)
    interpolated = InterpolatedConvolution(timed)
    coef = rng.standard_normal(20)
    np.testing.assert_allclose(
        interpolated.fitted_readings(SimpleNamespace(coef=coef), None, 1.0)[0],
        interpolated.matrix @ coef, rtol=1e-12)
    assert interpolated.interpolation_check(coef) == gm.observations.interpolation_error(
        interpolated, coef)
    assert DownsampledConvolution(u, 3, 20).interpolation_check(coef) is None
    # new readings are modelled as the fit modelled its own; exactly on a record
    # shorter than the interpolation's nodes
    new = TimedConvolution(u, np.arange(1, 280, 7) + 0.5, 20)
    model = interpolated.readings_model(new)
    assert isinstance(model, InterpolatedConvolution) and model.points == interpolated.points
    np.testing.assert_array_equal(model.matrix, InterpolatedConvolution(new).matrix)
    few = TimedConvolution(u[:10], [4.5, 8.5], 20)
    assert interpolated.readings_model(few) is few
    assert DownsampledConvolution(u, 3, 20).readings_model(new) is new


def test_posterior_of_readings_on_a_regressor_is_the_dense_linear_map():
    rng = np.random.default_rng(3)
    u = rng.standard_normal(50)
    observation = DownsampledConvolution(u, 2, 8)
    root = rng.standard_normal((8, 8))
    K = root @ root.T
    B = 0.3 * rng.standard_normal((3, 8))
    posterior = GaussianCoefficients(rng.standard_normal(8), K, B)
    mean, var = observation.posterior_readings(posterior, None, None)
    Phi = _dense_regressor(u, 8, np.arange(0, 50, 2))
    np.testing.assert_allclose(mean, Phi @ posterior.coef, rtol=1e-12)
    np.testing.assert_allclose(var, np.diag(Phi @ (K - B.T @ B) @ Phi.T), rtol=1e-10)


# ------------------------------------------------------------ settings
def test_settings_name_the_first_bad_parameter_and_keep_the_given_values():
    with pytest.raises(ValueError, match="tuning"):
        check_settings(gm.FIRGaussianProcess(tuning="loo", cv=1))
    with pytest.raises(ValueError, match="exposure"):
        check_settings(gm.FIRGaussianProcess(exposure=-1.0))
    with pytest.raises(ValueError, match="between_ticks"):
        check_settings(gm.FIRGaussianProcess(between_ticks="cubic"))
    kernel = C(2.0) * DC()
    settings = check_settings(gm.FIRGaussianProcess(kernel, factor=3, offset=1, order=[20, 10],
                                                    optimizer=None, noise_kernel="auto"))
    assert settings.kernel is kernel and settings.candidates == [10, 20]
    assert settings.factor == 3 and settings.offset == 1 and not settings.tuned
    assert settings.noise_kernel == "white"  # nothing is tuned: "auto" is white
    with pytest.raises(AttributeError):
        settings.order = 5  # frozen: the steps return results, they change no settings


# ------------------------------------------------------------ prior
def test_default_prior_is_in_the_data_units_and_decays_by_the_order():
    rng = np.random.default_rng(4)
    u, y = 3.0 * rng.standard_normal(90), 0.2 * rng.standard_normal(30)
    experiment = build_experiment(u, y, factor=FACTOR, order=40)
    settings = check_settings(gm.FIRGaussianProcess(factor=FACTOR, order=40))
    kernel, noise, bounds = prior.starting_prior(experiment, settings)
    scale = np.mean(y**2) / np.mean(u**2)
    assert kernel.k1.constant_value == pytest.approx(scale, rel=1e-12)
    assert kernel.k1.constant_value_bounds == pytest.approx((scale * 1e-8, scale * 1e8))
    # the envelope alpha^(t/2) falls by e^-2 by lag 40
    assert kernel.k2.alpha_bounds[1] ** (40 / 2) == pytest.approx(np.exp(-2), rel=1e-6)
    assert noise == pytest.approx(np.mean(y**2), rel=1e-12)  # noise_level=1, normalized
    assert bounds == pytest.approx((1e-12 * np.mean(y**2), 10 * np.mean(y**2)))
    # kernel="auto" starts from a pilot's tuned prior when given one
    start = (C(7.0) * DC(0.5, 0.5), 0.25)
    auto = replace(settings, auto=True, kernel="auto")
    kernel, noise, _ = prior.starting_prior(experiment, auto, start)
    assert repr(kernel) == repr(start[0]) and kernel is not start[0] and noise == 0.25


# ------------------------------------------------------------ between the ticks
def test_readings_on_the_ticks_are_fast_samples_and_others_timed():
    np.testing.assert_array_equal(between_ticks.readings_of(None, [0.0, 3.0], 0.0, 0.0), [0, 3])
    timed = between_ticks.readings_of(None, [0.5, 3.0], 0.0, 0.0)
    assert isinstance(timed, between_ticks.TimedSamples) and timed[0] == [0.5, 3.0]
    # an exposure takes readings off the ticks even at integer stamps
    assert isinstance(between_ticks.readings_of(None, [1.0, 3.0], 0.5, 0.0),
                      between_ticks.TimedSamples)
    with pytest.raises(ValueError, match="not both"):
        between_ticks.readings_of([0, 3], [0.5, 3.0], 0.0, 0.0)
    with pytest.raises(ValueError, match="sample_times"):
        between_ticks.readings_of(None, None, 1.0, 0.0)


def test_route_of_the_experiment_follows_the_record_and_the_setting():
    rng = np.random.default_rng(5)
    u = rng.standard_normal(3030)
    times = between_ticks.TimedSamples([np.arange(0, 3030, 3) + rng.uniform(0, 1, 1010)])
    y = rng.standard_normal(1010)
    settings = check_settings(gm.FIRGaussianProcess(order=20))

    def route(data, **changes):
        return type(between_ticks.experiment_of(data, 20, replace(settings, **changes))
                    .observation).__name__

    assert route((u, y, times)) == "InterpolatedConvolution"  # 1,010 readings > 1,000
    assert route((u, y, times), between_ticks="exact") == "TimedConvolution"
    short = (u[:150], y[:50], between_ticks.TimedSamples([times[0][:50]]))
    assert route(short) == "TimedConvolution"
    assert route(short, between_ticks="interpolated") == "InterpolatedConvolution"
    ticks = between_ticks.experiment_of((u[:30], y[:10], None), 5, replace(settings, factor=3,
                                                                           offset=2))
    np.testing.assert_array_equal(ticks.observation.sample_indices, np.arange(2, 30, 3))


def test_interpolation_check_acts_on_the_error_in_noise_standard_deviations():
    def observation(error, n_outputs=500):
        return SimpleNamespace(interpolation_check=lambda coef: error, points=12,
                               n_outputs=n_outputs)

    tolerance = between_ticks.INTERPOLATION_TOLERANCE
    assert between_ticks.check_interpolation(observation(None), None, 1.0, "auto") is None
    # 0.3 raw against a noise variance of 4: 0.15 noise std, kept
    check = between_ticks.check_interpolation(observation(0.3), None, 4.0, "auto")
    assert check.error == pytest.approx(0.15) and not check.refit and 0.15 < tolerance
    check = between_ticks.check_interpolation(observation(0.3), None, 1.0, "auto")
    assert check.error == pytest.approx(0.3) and check.refit
    # asked for: kept whatever the error
    assert not between_ticks.check_interpolation(observation(5.0), None, 1.0,
                                                 "interpolated").refit
    with pytest.warns(gm.NumericalWarning, match="estimated error of 0.3"):
        check = between_ticks.check_interpolation(
            observation(0.3, between_ticks.EXACT_UP_TO + 1), None, 1.0, "auto")
    assert not check.refit


# ------------------------------------------------------------ disturbance
def test_noise_kernel_is_checked():
    kernel = C(0.1) * Matern(10.0, nu=1.5)
    assert disturbance.check_noise_kernel(kernel) is kernel
    with pytest.raises(ValueError, match="noise_kernel must be"):
        disturbance.check_noise_kernel("pink")


def test_a_disturbance_at_fixed_values_scores_the_dense_log_evidence():
    u, y = _drifting()
    observation = DownsampledConvolution(u, FACTOR, 30)
    kernel = C(0.5) * DC(0.8, 0.9)
    settings = check_settings(gm.FIRGaussianProcess(factor=FACTOR, order=30, optimizer=None))
    noise = C(0.2) * Matern(20.0, nu=1.5)
    fitted = disturbance.fit_disturbance(observation, y, kernel, 0.01, (1e-5, 1.0), noise,
                                         settings)
    instants = np.arange(0, 240, FACTOR, dtype=float)[:, None]
    N = 0.01 * np.eye(80) + noise(instants)
    Phi = _dense_regressor(u, 30, np.arange(0, 240, FACTOR))
    K = kernel(np.arange(30.0)[:, None])
    assert fitted.optimizer_result is None and repr(fitted.kernel) == repr(kernel)
    assert fitted.score == pytest.approx(_dense_log_evidence(Phi, K, y, N), rel=1e-9)
    assert fitted.posterior.log_marginal_likelihood == pytest.approx(fitted.score, rel=1e-12)
    # white noise asks for nothing
    assert disturbance.choose_disturbance(
        build_experiment(u, y, factor=FACTOR, order=30), kernel, 0.01, (1e-5, 1.0), 0.0,
        replace(settings, noise_kernel="white")) is None


def test_auto_calls_for_a_disturbance_on_a_drifting_record_only():
    calls = {}
    for name, drift in (("drifting", 0.05), ("white", 0.0)):
        u, y = _drifting(seed=2, drift=drift)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            white = gm.FIRGaussianProcess(factor=FACTOR, order=30, noise_kernel="white").fit(u, y)
            auto = gm.FIRGaussianProcess(factor=FACTOR, order=30).fit(u, y)
        experiment = build_experiment(u, y, factor=FACTOR, order=30)
        calls[name] = disturbance.calls_for_disturbance(experiment, white.kernel_,
                                                        white.noise_level_)
        assert (auto.noise_kernel_ != "white") == calls[name]
    assert calls == {"drifting": True, "white": False}


# ------------------------------------------------------------ resonances
def test_resonances_judged_again_keep_the_terms_the_disturbance_leaves(monkeypatch):
    import gpmultirate.resonances

    u, y = _drifting()
    observation = DownsampledConvolution(u, FACTOR, 30)
    settings = check_settings(gm.FIRGaussianProcess(factor=FACTOR, order=30, optimizer=None))
    start = disturbance.fit_disturbance(observation, y, C(0.5) * DC(0.8, 0.9), 0.01,
                                        (1e-5, 1.0), "matern12", settings)
    found = [SimpleNamespace(input=0, name="first"), SimpleNamespace(input=0, name="second")]
    reduced = C(0.4) * DC(0.7, 0.9)
    calls = []

    def judged(kept, changed=True):
        def judge(observation, y, evidence, kernel, noise, inputs, n_folds):
            calls.append((evidence, kernel, noise, inputs))
            return kept, reduced if changed else kernel
        return judge

    monkeypatch.setattr(gpmultirate.resonances, "resonances_under_disturbance",
                        judged([0, 1], changed=False))
    left, refitted = auto_kernel.rejudge(observation, y, start, found, 0.01, (1e-5, 1.0),
                                         settings)
    assert left == found and refitted is None
    assert calls[0][0] is start.evidence and calls[0][2] is start.noise_model
    assert calls[0][3] == [0, 0]
    # every term kept, a base dropped (a kernel of its own): fitted again
    monkeypatch.setattr(gpmultirate.resonances, "resonances_under_disturbance", judged([0, 1]))
    left, refitted = auto_kernel.rejudge(observation, y, start, found, 0.01, (1e-5, 1.0),
                                         settings)
    assert left == found and repr(refitted.kernel) == repr(reduced)
    monkeypatch.setattr(gpmultirate.resonances, "resonances_under_disturbance", judged([1]))
    left, refitted = auto_kernel.rejudge(observation, y, start, found, 0.01, (1e-5, 1.0),
                                         settings)
    assert left == found[1:]
    # fitted again from the disturbance without the term (here nothing is tuned): its
    # evidence at the reduced kernel and the Matern 1/2 disturbance's start, 0.01 each
    instants = np.arange(0, 240, FACTOR, dtype=float)[:, None]
    N = 0.01 * np.eye(80) + 0.01 * Matern(10.0, nu=0.5)(instants)
    Phi = _dense_regressor(u, 30, np.arange(0, 240, FACTOR))
    K = reduced(np.arange(30.0)[:, None])
    assert repr(refitted.kernel) == repr(reduced)
    assert refitted.score == pytest.approx(_dense_log_evidence(Phi, K, y, N), rel=1e-9)


# ------------------------------------------------------------ order
@pytest.mark.filterwarnings("ignore:tuning ended on a bound")
def test_order_steps_fit_the_orders_they_choose():
    rng = np.random.default_rng(6)
    u = rng.standard_normal(240)
    y = (np.convolve(u, 0.8 ** np.arange(40))[:240] + 0.05 * rng.standard_normal(240))[::3]
    data = (u, y, None)
    tried = []

    def fit_at(data, order, settings, start=None):
        tried.append(order)
        return fit_at_order(data, order, settings, start)

    base = check_settings(gm.FIRGaussianProcess(factor=FACTOR, order=30))
    fitted, table = order.fit_order(data, base, fit_at)
    assert tried == [30] and table is None and fitted.observation_.order == 30
    tried.clear()
    fitted, table = order.fit_order(data, replace(base, candidates=[10, 20, 40], order=None),
                                    fit_at)
    assert tried == [10, 20, 40] and fitted.observation_.order == table["best_order"]
    per_sample = [fit_at_order(data, p, base).log_marginal_likelihood_value_ / 80
                  for p in (10, 20, 40)]
    np.testing.assert_allclose(table["score"], per_sample, rtol=1e-12)
    # the default order of a short record is its length, then the held-out check
    tried.clear()
    fitted, table = order.fit_checked_order(data, replace(base, order=None), fit_at)
    assert tried[0] is None and table["criterion"] == "held_out_fit"
    assert fitted.observation_.order == table["best_order"]
    scores = dict(zip(table["order"], table["score"]))
    best = max(scores, key=scores.get)
    expected = best if scores[best] > scores[240] + order.ORDER_MARGIN else 240
    assert table["best_order"] == expected and tried[1:] == ([expected] if expected != 240
                                                             else [])


def test_too_short_order_is_reported_with_the_lag_one_correlation_of_the_residuals():
    rng = np.random.default_rng(7)
    n = 3000
    u = rng.standard_normal(n)
    g = 0.97 ** np.arange(300)
    y = (np.convolve(u, g)[:n] + 0.01 * rng.standard_normal(n))[::FACTOR]
    settings = check_settings(gm.FIRGaussianProcess(factor=FACTOR, order=10,
                                                     noise_kernel="white"))  # no disturbance check
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fitted = fit_at_order((u, y, None), 10, settings)
    Phi = _dense_regressor(u, 10, np.arange(0, n, FACTOR))
    residual = y - Phi @ fitted.posterior_.coef
    correlation = residual[1:] @ residual[:-1] / (residual @ residual)
    args = (fitted.observation_, y, fitted.posterior_, fitted.kernel_, fitted.noise_level_)
    with pytest.warns(gm.OrderWarning, match=f"{correlation:.2f} at lag one") as caught:
        order.check_long_enough(*args, None, settings)
    assert "order=20 (or the default order=None" in str(caught[0].message)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        order.check_long_enough(*args, "a disturbance model", settings)  # its colour
        order.check_long_enough(*args, None, replace(settings, initial_conditions="periodic"))


@pytest.mark.parametrize("order, why", [(1200, "not more than the 1200 coefficients"),
                                         (300, "not on one uniform grid")])
def test_the_skipped_disturbance_check_says_why(order, why, caplog, monkeypatch):
    """Frames every 10th sample (a uniform grid) with no more slow samples than
    coefficients: the message names the coefficients, not the grid."""
    import logging

    rng = np.random.default_rng(4)
    u = rng.standard_normal(11_000)
    observation = DownsampledConvolution(u, 10, order)
    y = observation.matvec(0.9 ** np.arange(order)) + 0.01 * rng.standard_normal(1100)
    experiment = build_experiment(u, y, factor=10, order=order)
    if order < 1100:  # more samples than coefficients, off one grid: no AR(1) gain
        monkeypatch.setattr(disturbance, "ar1_evidence_gain", lambda *args: None)
    with caplog.at_level(logging.INFO, logger="gpmultirate"):
        assert not disturbance.calls_for_disturbance(experiment, C(1.0) * DC(0.9, 0.9), 1e-4,
                                                     check_tail=False)
    assert f"1100 slow samples: {why}" in caplog.text


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:tuning ended on a bound")
def test_a_pilots_order_fitted_again_starts_from_that_pilots_tuning(monkeypatch):
    """When the default order falls back to a pilot's order (the doubled order lost
    evidence), the fit at that order starts from that pilot's tuned prior, not from the
    plain prior: it reaches the pilot's optimum in no more evaluations than the pilot took."""
    from gpmultirate import orders

    rng = np.random.default_rng(8)
    u = rng.standard_normal(3000)
    y = (np.convolve(u, 0.99 ** np.arange(900) * np.cos(0.3 * np.arange(900)))[:3000]
         + 0.1 * rng.standard_normal(3000))[::FACTOR]
    data = (u, y, None)
    pilots, calls = {}, []

    def ladder(fit_at, tail_lag, longest, n_samples, n_inputs=1, log=None, evidence=None,
               trim=None):
        for p in (512, 999):
            pilots[p] = fit_at(p)
        # the doubled order lost evidence: the shorter one is fitted again
        return orders.DefaultOrder(order=512, table={"order": np.array([512, 999])}, fit=None)

    def fit_at(data, order_, settings, start=None):
        calls.append((order_, start))
        return fit_at_order(data, order_, settings, start)

    monkeypatch.setattr(orders, "default_order", ladder)
    base = check_settings(gm.FIRGaussianProcess(factor=FACTOR, noise_kernel="white"))
    fitted, _ = order.fit_order(data, base, fit_at)
    assert [c[0] for c in calls] == [512, 999, 512]
    assert calls[0][1] is None  # the first pilot from the plain prior, the next from its end
    assert calls[1][1][0].theta == pytest.approx(pilots[512].kernel_.theta)
    kernel, noise, tuned = calls[-1][1]
    assert kernel.theta == pytest.approx(pilots[512].kernel_.theta)
    assert noise == pilots[512].noise_level_ and not tuned  # tuned again from there
    # the plain start repeats the pilot's run evaluation for evaluation
    assert fitted.optimizer_result_.nfev < pilots[512].optimizer_result_.nfev
    assert fitted.log_marginal_likelihood_value_ >= (
        pilots[512].log_marginal_likelihood_value_ - 1e-6)
    # a plain start where no pilot was fitted at the order
    calls.clear()
    monkeypatch.setattr(orders, "default_order", lambda fit_at, *args, **kwargs: (
        fit_at(512), orders.DefaultOrder(order=300, table={}, fit=None))[1])
    order.fit_order(data, base, fit_at)
    assert calls[-1] == (300, None)


def test_a_start_tuned_at_another_order_keeps_this_orders_bounds():
    # the default prior bounds DC's decay by the order (slowest_decay): a start tuned at
    # 512 lags brings its values to a fit at 999 lags, not its tighter bound on alpha
    from gpmultirate.resonances import slowest_decay

    rng = np.random.default_rng(2)
    u = rng.standard_normal(3000)
    y = np.convolve(u, 0.99 ** np.arange(900))[:3000][::FACTOR]
    data = (u, y, None)
    settings = check_settings(gm.FIRGaussianProcess(factor=FACTOR, noise_kernel="white"))
    short = between_ticks.experiment_of(data, 512, settings)
    tuned, _, _ = prior.starting_prior(short, settings)
    tuned = tuned.clone_with_theta(tuned.bounds[:, 1])  # every value on its upper bound
    assert np.exp(tuned.bounds[1, 1]) == pytest.approx(slowest_decay(512))
    longer = between_ticks.experiment_of(data, 999, settings)
    plain, _, _ = prior.starting_prior(longer, settings)
    started, noise, _ = prior.starting_prior(longer, settings, (tuned, 0.25))
    np.testing.assert_array_equal(started.bounds, plain.bounds)
    assert np.exp(started.bounds[1, 1]) == pytest.approx(slowest_decay(999))
    np.testing.assert_allclose(started.theta, tuned.theta)  # inside the wider bounds
    assert noise == 0.25
    # a value outside this order's bounds is clipped to them
    wide = tuned.clone_with_theta(plain.bounds[:, 1])
    shorter = between_ticks.experiment_of(data, 300, settings)
    clipped, _, _ = prior.starting_prior(shorter, settings, (wide, 0.25))
    assert np.exp(clipped.theta[1]) == pytest.approx(slowest_decay(300))
    # a start of another structure is taken as it is
    other = C(2.0) * DC(alpha=0.9, beta=0.5) + C(1.0)
    taken, _, _ = prior.starting_prior(longer, settings, (other, 0.25))
    assert repr(taken) == repr(other)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:tuning ended on a bound")
def test_a_doubled_pilot_from_the_last_pilots_end_reaches_the_plain_starts_optimum():
    """The default order's pilots after the first start from the last one's tuned prior:
    the doubled order's tuning then ends where the plain start's does (same evidence to
    0.01 nats), in fewer evaluations."""
    rng = np.random.default_rng(8)
    u = rng.standard_normal(3000)
    y = (np.convolve(u, 0.99 ** np.arange(900) * np.cos(0.3 * np.arange(900)))[:3000]
         + 0.1 * rng.standard_normal(3000))[::FACTOR]
    data = (u, y, None)
    base = check_settings(gm.FIRGaussianProcess(factor=FACTOR, noise_kernel="white"))
    first = fit_at_order(data, 512, base)
    plain = fit_at_order(data, 999, base)
    warm = fit_at_order(data, 999, base, (first.kernel_, first.noise_level_))
    assert warm.log_marginal_likelihood_value_ == pytest.approx(
        plain.log_marginal_likelihood_value_, abs=1e-2)
    assert warm.optimizer_result_.nfev < plain.optimizer_result_.nfev
