"""Order selection as a step of its own, and the parameters checked before the data."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate import orders
from gpmultirate.kernels import DC


@pytest.fixture(scope="module")
def small():
    rng = np.random.default_rng(3)
    g = 0.85 ** np.arange(40) * np.cos(0.4 * np.arange(40))
    u = rng.standard_normal(180)
    y_slow = np.convolve(u, g)[:180][::3] + 0.02 * rng.standard_normal(60)
    return u, y_slow


@pytest.mark.parametrize("params, name", [
    ({"tuning": "bogus"}, "tuning"),
    ({"cv": 1}, "cv"),
    ({"order": "longest"}, "order"),
    ({"order": 0}, "order"),
    ({"optimizer": "adam"}, "optimizer"),
    ({"n_restarts_optimizer": -1}, "n_restarts_optimizer"),
    ({"noise_level": -1.0}, "noise_level"),
    ({"noise_level_bounds": (2.0, 1.0)}, "noise_level_bounds"),
    ({"kernel": "rbf"}, "kernel"),
    ({"max_resonances": -1}, "max_resonances"),
    ({"initial_conditions": "rest"}, "initial_conditions"),
    ({"factor": 0}, "factor"),
    ({"offset": 3, "factor": 3}, "offset"),
    ({"sample_time": 0.0}, "sample_time"),
])
def test_every_parameter_is_checked_before_the_data(params, name):
    # the data are invalid too (y_slow is not finite and too long): the
    # parameter's error comes first, as in scikit-learn
    model = gm.FIRGaussianProcess(**params)
    with pytest.raises(ValueError, match=name):
        model.fit(np.ones(10), np.full(50, np.inf))


def test_select_order_returns_the_best_per_sample_score_and_reissues_its_warnings_only():
    from types import SimpleNamespace
    import warnings

    def fit_at(order):
        warnings.warn(f"at {order}", UserWarning)
        n = 10 if order < 30 else 5  # "discard": fewer samples at higher orders
        return SimpleNamespace(log_marginal_likelihood_value_=-float(order) / 4,
                               y_slow_=np.zeros(n))

    with pytest.warns(UserWarning) as record:
        selection = orders.select_order(fit_at, [10, 20, 40])
    # per sample: -0.25, -0.5, -2.0
    assert selection.order == 10 == selection.table["best_order"]
    np.testing.assert_allclose(selection.table["score"], [-0.25, -0.5, -2.0])
    assert [str(w.message) for w in record] == ["at 10"]
    assert selection.fit.y_slow_.shape == (10,)


def test_order_selection_fits_the_estimator_as_a_direct_fit_at_the_chosen_order(small):
    u, y_slow = small
    kernel = C(1.0) * DC()
    model = gm.FIRGaussianProcess(kernel, factor=3, order=[15, 30, 60]).fit(u, y_slow)
    best = model.order_selection_["best_order"]
    direct = gm.FIRGaussianProcess(kernel, factor=3, order=best).fit(u, y_slow)
    np.testing.assert_array_equal(model.coef_, direct.coef_)
    assert model.log_marginal_likelihood_value_ == direct.log_marginal_likelihood_value_
    assert model.get_params()["order"] == [15, 30, 60]  # the parameter is left as given
    # the evidence per slow sample of each candidate, from independent fits
    for order, score in zip(model.order_selection_["order"], model.order_selection_["score"]):
        alone = gm.FIRGaussianProcess(kernel, factor=3, order=int(order)).fit(u, y_slow)
        assert score == pytest.approx(alone.log_marginal_likelihood_value_ / y_slow.shape[0])


def test_the_default_prior_in_data_units_scales_with_the_units(small):
    from gpmultirate.estimators import prior_in_data_units
    from gpmultirate.observations import build_experiment

    u, y_slow = small
    one = build_experiment(u, y_slow, None, factor=3, order=30)
    scaled = build_experiment(10 * u, 1e3 * y_slow, None, factor=3, order=30)
    k1, n1, b1 = prior_in_data_units(None, one, 0.5, "auto", True, True)
    k2, n2, b2 = prior_in_data_units(None, scaled, 0.5, "auto", True, True)
    # output power grows 1e6, input power 1e2: the amplitude by 1e4, the noise by 1e6
    assert k2.k1.constant_value == pytest.approx(1e4 * k1.k1.constant_value)
    assert n2 == pytest.approx(1e6 * n1)
    assert b2[1] == pytest.approx(1e6 * b1[1])
    assert n1 == pytest.approx(0.5 * np.mean(y_slow**2))
    # without normalization the user's kernel and noise are used as given
    kernel, noise, _ = prior_in_data_units(C(2.0) * DC(), one, 0.5, "fixed", False, False)
    assert kernel.k1.constant_value == 2.0 and noise == 0.5


# ------------------------------------------------------------ the default order
def _record(n, g, factor=3, snr_db=40.0, seed=0):
    """``(u, y_slow, u_val, y_val)``: white input, FIR ``g``, noise at ``snr_db`` on the slow samples."""
    rng = np.random.default_rng(seed)
    u, u_val = rng.standard_normal(n), rng.standard_normal(n)
    y, y_val = np.convolve(u, g)[:n], np.convolve(u_val, g)[:n]
    y_slow = y[::factor].copy()
    y_slow += 10 ** (-snr_db / 20) * np.std(y_slow) * rng.standard_normal(y_slow.shape[0])
    return u, y_slow, u_val, y_val


def test_prior_tail_lag_matches_the_geometric_tail():
    # C * DC has variance c alpha^t on the diagonal: the tail from L is c alpha^L / (1 - alpha)
    c, alpha, power, noise = 2.0, 0.95, 3.0, 1e-3
    kernel = C(c) * DC(alpha=alpha, beta=0.5)
    lag = orders.prior_tail_lag(kernel, [power], noise, 2000, tolerance=1e-2)
    tail = lambda L: power * c * (alpha**L - alpha**2000) / (1 - alpha)  # noqa: E731
    assert tail(lag) <= 1e-2 * noise < tail(lag - 1)
    # two inputs: the slower one decides
    two = gm.kernels.PerInputKernel([C(c) * DC(alpha=0.5, beta=0.5), kernel])
    assert orders.prior_tail_lag(two, [power, power], noise, 2000) == lag
    # a prior that has not decayed within the window: the window
    assert orders.prior_tail_lag(kernel, [power], noise, 50) == 50


def test_default_order_keeps_p_equal_n_for_the_paper_size_record():
    from gpmultirate import simulation as sim

    rng = np.random.default_rng(0)
    system = sim.paper_system(0.1, perturbation=0.1, random_state=rng)
    u = sim.multisine(600, random_state=rng)
    data = sim.simulate_experiment(system, u, 3, snr_db=40.0, random_state=rng)
    model = gm.FIRGaussianProcess(factor=3).fit(data.u, data.y_slow)
    # today's route: the fit at P = N, then the held-out check over N/32..N
    assert 600 <= orders.SHORT_RECORD and 2048 <= orders.SHORT_RECORD  # the measured records too
    assert model.order_selection_["criterion"] == "held_out_fit"
    assert model.order_selection_["order"][-1] == 600
    best = model.order_selection_["best_order"]
    assert model.coef_.shape == (best,)
    direct = gm.FIRGaussianProcess(factor=3, order=best).fit(data.u, data.y_slow)
    if best == 600:
        np.testing.assert_array_equal(model.coef_, direct.coef_)


@pytest.mark.slow
def test_default_order_of_a_longer_record_is_read_from_the_tuned_prior():
    g = 0.9 ** np.arange(200)  # negligible against 40 dB noise well before lag 200
    u, y_slow, u_val, y_val = _record(2400, g)
    model = gm.FIRGaussianProcess(factor=3).fit(u, y_slow)
    selection = model.order_selection_
    assert selection["criterion"] == "prior_tail"
    order = selection["best_order"]
    assert model.coef_.shape == (order,) and order < y_slow.shape[0] < 2400  # long-record route
    # the order is the tuned prior's negligible lag, recomputed from the pilot fit: its
    # tail against the noise, or its decay's envelope, whichever is longer
    pilot = gm.FIRGaussianProcess(factor=3, order=int(selection["order"][0])).fit(u, y_slow)
    window = 2 * pilot.coef_.shape[0]
    lag = max(orders.prior_tail_lag(pilot.kernel_, [np.mean(u**2)], pilot.noise_level_, window),
              orders.prior_envelope_lag(pilot.kernel_, 1, window))
    assert order == max(lag, orders.MIN_DEFAULT_ORDER) == int(selection["score"][0])
    # and it is fitted as an explicit order is
    direct = gm.FIRGaussianProcess(factor=3, order=order).fit(u, y_slow)
    np.testing.assert_array_equal(model.coef_, direct.coef_)
    assert model.score(u_val, y_val) > 99.0


@pytest.mark.slow
def test_too_short_an_order_is_reported_and_a_good_one_is_not():
    g = 0.97 ** np.arange(600) * np.cos(0.3 * np.arange(600))
    u, y_slow, _, _ = _record(3000, g)
    with pytest.warns(gm.OrderWarning, match=r"order=40 looks too short.*Try order=80"):
        gm.FIRGaussianProcess(factor=3, order=40).fit(u, y_slow)
    with warnings_as_errors(gm.OrderWarning):
        gm.FIRGaussianProcess(factor=3, order=400).fit(u, y_slow)


def warnings_as_errors(category):
    import warnings

    class _Context(warnings.catch_warnings):
        def __enter__(self):
            super().__enter__()
            warnings.simplefilter("error", category)

    return _Context()


def test_the_memory_refusal_names_an_order_that_fits(monkeypatch):
    from gpmultirate.memory import MemoryLimitError, fit_memory_estimate

    monkeypatch.setenv("GPMULTIRATE_MEMORY_LIMIT", str(50 * 10**6))
    u = np.random.default_rng(0).standard_normal((3000, 2))
    y_slow = u[::3, 0].copy()
    with pytest.raises(MemoryLimitError, match=r"order=(\d+)") as caught:
        gm.FIRGaussianProcess(factor=3, order=3000).fit(u, y_slow)
    import re

    order = int(re.search(r"order=(\d+)", str(caught.value)).group(1))
    # two inputs: 2 * order coefficients; 6 free hyperparameters and the noise
    assert fit_memory_estimate(1000, 2 * order, 7) <= 50 * 10**6
    assert fit_memory_estimate(1000, 2 * (order + 1), 7) > 50 * 10**6


@pytest.mark.slow
def test_default_order_on_a_long_paper_like_record_predicts_as_a_well_chosen_order():
    from gpmultirate import simulation as sim

    rng = np.random.default_rng(0)
    system = sim.paper_system(0.1, perturbation=0.1, random_state=rng)
    u = sim.multisine(30_000, random_state=rng)
    u_val = sim.multisine(30_000, random_state=rng)
    data = sim.simulate_experiment(system, u, 3, snr_db=40.0, random_state=rng)
    y_val = system.simulate(u_val)
    model = gm.FIRGaussianProcess(factor=3).fit(data.u, data.y_slow)
    order = model.coef_.shape[0]
    assert order < data.y_slow.shape[0]  # the long-record route
    chosen = gm.FIRGaussianProcess(factor=3, order=1500).fit(data.u, data.y_slow)
    assert model.score(u_val, y_val) >= chosen.score(u_val, y_val) - 0.5
    assert model.score(u_val, y_val) >= 99.5


@pytest.mark.slow
def test_default_order_with_the_resonance_search_runs_the_search_once_at_the_chosen_order():
    g = 0.97 ** np.arange(400) * np.cos(0.6 * np.arange(400))
    u, y_slow, u_val, y_val = _record(2400, g)
    model = gm.FIRGaussianProcess(kernel="auto", factor=3).fit(u, y_slow)
    plain = gm.FIRGaussianProcess(factor=3).fit(u, y_slow)
    # the pilots tune the plain default prior: the same order as the plain fit
    assert model.order_selection_["best_order"] == plain.order_selection_["best_order"]
    assert model.coef_.shape == (model.order_selection_["best_order"],)
    assert hasattr(model, "resonances_")
    assert model.score(u_val, y_val) >= plain.score(u_val, y_val) - 1.0


def test_the_study_drops_the_order_warning_of_its_short_orders():
    from gpmultirate.study import simulate_run
    from gpmultirate.study.runner import fit_method

    data = simulate_run(0, n_samples=600)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model, _, _ = fit_method("DC", 50, data)
    assert model is not None
    assert not any(issubclass(w.category, gm.OrderWarning) for w in caught)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        gm.FIRGaussianProcess(factor=data.factor, order=50).fit(data.u, data.y_slow)
    assert any(issubclass(w.category, gm.OrderWarning) for w in caught)


@pytest.mark.slow
def test_the_resonance_search_starts_from_the_last_pilot_tuned_prior(monkeypatch):
    from gpmultirate import resonances, tuning
    from gpmultirate.inference import LogEvidence

    g = 0.97 ** np.arange(400) * np.cos(0.6 * np.arange(400))
    u, y_slow, _, _ = _record(2400, g)
    seen = []
    search = resonances.search_resonances

    def spy(observation, y, kernel, noise, bounds, **kwargs):
        seen.append((observation, y, kernel, noise, bounds))
        return search(observation, y, kernel, noise, bounds, **kwargs)

    monkeypatch.setattr(resonances, "search_resonances", spy)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gm.FIRGaussianProcess(kernel="auto", factor=3).fit(u, y_slow)
    assert len(seen) == 1
    observation, y, kernel, noise, bounds = seen[0]
    # the start is the plain prior tuned by a pilot (at a longer order here): tuning it
    # again at the chosen order gains little (from the untuned default prior: 505 against
    # 3298 nats)
    evidence = LogEvidence(observation, y, kernel, noise, bounds)
    start = evidence(evidence.theta)
    tuned = -tuning.maximize(evidence).fun
    assert tuned - start <= 1e-3 * abs(tuned)


def test_kernel_names_are_the_kernels_they_stand_for():
    # "dc" is the default prior to the digit; "tc" is a scaled TC, tuned from the same start
    rng = np.random.default_rng(3)
    u = rng.standard_normal(240)
    y = np.convolve(u, 0.8 ** np.arange(20))[:240][::3] + 0.01 * rng.standard_normal(80)
    fits = {k: gm.FIRGaussianProcess(factor=3, order=30, kernel=k).fit(u, y)
            for k in (None, "dc", "tc")}
    assert np.array_equal(fits["dc"].coef_, fits[None].coef_)
    assert type(fits["tc"].kernel_.k2).__name__ == "TC"
    assert not np.allclose(fits["tc"].coef_, fits["dc"].coef_)
