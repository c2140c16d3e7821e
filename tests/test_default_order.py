"""The default order's rules: a pilot that cannot see the memory, the evidence, no contradiction."""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate import orders, resonances
from gpmultirate.fitting import order as order_steps
from gpmultirate.kernels import DC, PerInputKernel
from gpmultirate.resonances import slowest_decay


def test_prior_envelope_lag_matches_the_geometric_decay():
    # C * DC has variance c alpha^t: below exp(-4.4) of its peak from t >= 4.4 / -log(alpha)
    for alpha in (0.9, 0.99, 0.999):
        lag = orders.prior_envelope_lag(C(3.0) * DC(alpha=alpha, beta=0.5), 1, 20_000)
        assert lag == int(np.ceil(orders.ENVELOPE_DECAY / -np.log(alpha)))
    # two inputs: the slower decides, whatever their scales
    two = PerInputKernel([C(1e6) * DC(alpha=0.9, beta=0.5), C(1e-6) * DC(alpha=0.99, beta=0.5)])
    assert orders.prior_envelope_lag(two, 2, 2000) == int(np.ceil(4.4 / -np.log(0.99)))
    # not decayed within the window: the window
    assert orders.prior_envelope_lag(DC(alpha=0.999, beta=0.5), 1, 100) == 100


def test_a_pilot_whose_decay_sits_on_the_orders_bound_reads_as_not_decayed():
    # a pilot at 512 lags that sees little of a long response: DC's decay on the default
    # prior's bound, the prior's scale small against a noise estimate that absorbed the rest
    order = 512
    kernel = C(1e-4) * DC(alpha=slowest_decay(order), beta=0.9)
    noise, powers = 1.0, [1.0]
    # against the noise alone the tail is negligible from a lag within the order ...
    assert orders.prior_tail_lag(kernel, powers, noise, 2 * order) < order
    # ... but the decay the data asked for is the slowest the order allows: the pilot's lag
    # reaches the order, and the default order doubles
    assert order_steps.pilot_lag(kernel, powers, noise, order) >= order
    # a decay well inside the bound is read as it is
    inside = C(1e-4) * DC(alpha=0.98, beta=0.9)
    assert order_steps.pilot_lag(inside, powers, noise, order) < order


def _pilots(memory, evidence):
    """``fit_at`` and ``tail_lag`` of pilots whose prior never decays before ``memory``."""
    fitted = []

    def fit_at(order):
        fitted.append(order)
        return SimpleNamespace(order=order, evidence=evidence(order))

    return fitted, fit_at, lambda fit: min(memory, 2 * fit.order)


def test_default_order_doubles_while_the_evidence_gains_and_stops_where_it_does_not():
    # the evidence grows by 50 nats per doubling up to 2048 lags, then by 0.5
    gains = {512: 0.0, 1024: 50.0, 2048: 100.0, 4096: 100.5, 8192: 101.0}
    fitted, fit_at, tail_lag = _pilots(10**6, gains.get)
    result = orders.default_order(fit_at, tail_lag, 10**5, 10**5,
                                  evidence=lambda fit: fit.evidence)
    assert fitted == [512, 1024, 2048, 4096]  # no pilot at 8192
    assert result.order == 4096 and result.fit.order == 4096  # the higher evidence, kept
    # a doubled order that explains the data worse: the shorter one is kept
    gains[4096] = 99.0
    fitted, fit_at, tail_lag = _pilots(10**6, gains.get)
    result = orders.default_order(fit_at, tail_lag, 10**5, 10**5,
                                  evidence=lambda fit: fit.evidence)
    assert fitted == [512, 1024, 2048, 4096]
    # (the pilots' fits are not held: the shorter order is fitted again)
    assert result.order == 2048 == result.table["best_order"] and result.fit is None
    # without evidence the doubling goes on to the record's length
    fitted, fit_at, tail_lag = _pilots(10**6, gains.get)
    result = orders.default_order(fit_at, tail_lag, 9000, 10**5)
    assert fitted == [512, 1024, 2048, 4096, 8192, 9000] and result.order == 9000


def test_a_response_that_decays_is_cut_as_before_whatever_the_evidence():
    fitted, fit_at, tail_lag = _pilots(700, lambda order: 0.0)
    result = orders.default_order(fit_at, tail_lag, 10**5, 33333,
                                  evidence=lambda fit: fit.evidence)
    # 512 is too short; at 1024 the prior has decayed: the rule stops there by the decay,
    # and a flat evidence does not send it back to 512
    assert fitted == [512, 1024] and result.order == 1024 and result.fit.order == 1024


def test_a_default_order_called_short_is_raised_and_never_warned_about(monkeypatch):
    # the record that makes an explicit order=40 warn "looks too short, try 80" (white
    # noise: a disturbance model would take the residuals' colour for its own)
    g = 0.97 ** np.arange(600) * np.cos(0.3 * np.arange(600))
    rng = np.random.default_rng(0)
    n = 1500
    u = rng.standard_normal(n)
    y_slow = np.convolve(u, g)[:n][::3].copy()
    y_slow += 1e-2 * np.std(y_slow) * rng.standard_normal(y_slow.shape[0])
    with pytest.warns(gm.OrderWarning, match=r"order=40 looks too short"):
        gm.FIRGaussianProcess(factor=3, order=40, noise_kernel="white").fit(u, y_slow)
    # a default rule that chose 40 (as the pilots' rule did on records where the fit at the
    # chosen order then called it short): the fit raises it instead of warning
    chosen = orders.DefaultOrder(order=40, table={"order": np.array([40]),
                                                  "score": np.array([40.0]),
                                                  "criterion": "prior_tail",
                                                  "best_order": 40}, fit=None)
    monkeypatch.setattr(order_steps, "default_order_rule",
                        lambda data, settings, fit_at: (chosen, None))
    with warnings.catch_warnings():
        warnings.simplefilter("error", gm.OrderWarning)
        model = gm.FIRGaussianProcess(factor=3, noise_kernel="white").fit(u, y_slow)
    order = model.coef_.shape[0]
    assert order >= 80 and model.order_selection_["best_order"] == order
    # the order kept is fitted as an explicit order is, and its check is quiet or the
    # doubled order gained too little evidence to be kept
    direct = gm.FIRGaussianProcess(factor=3, order=order, noise_kernel="white").fit(u, y_slow)
    np.testing.assert_allclose(model.coef_, direct.coef_, rtol=1e-10, atol=1e-12)


def test_default_order_cuts_a_last_pilot_whose_prior_is_negligible_well_within_it():
    # at TRIM_SHARE of the order or less the cut is fitted with the last pilot's
    # hyperparameters held; above it the pilot's fit is kept; trim None: fitted afterwards
    for memory, cut in ((600, 600), (800, None)):
        fitted, fit_at, tail_lag = _pilots(memory, lambda order: 0.0)
        trims = []
        result = orders.default_order(fit_at, tail_lag, 10**5, 33333,
                                      trim=lambda order: trims.append(order) or "cut")
        assert fitted == [512, 1024] and trims == ([] if cut is None else [cut])
        assert (result.order, result.fit) == ((600, "cut") if cut else (1024, result.fit))
    fitted, fit_at, tail_lag = _pilots(600, lambda order: 0.0)
    result = orders.default_order(fit_at, tail_lag, 10**5, 33333, trim=lambda order: None)
    assert result.order == 600 and result.fit is None


def test_a_cut_default_order_predicts_as_the_pilot_it_was_cut_from(monkeypatch):
    # a response whose prior the pilot at 1024 lags finds negligible from about 660
    t = np.arange(1500)
    g = 0.99 ** t * np.cos(0.3 * t)
    rng = np.random.default_rng(1)
    n = 6000
    u = rng.standard_normal(n)
    y_slow = np.convolve(u, g)[:n][::3].copy()
    noise = 0.02 * np.std(y_slow)
    y_slow += noise * rng.standard_normal(y_slow.shape[0])
    model = gm.FIRGaussianProcess(factor=3, noise_kernel="white").fit(u, y_slow)
    order = model.coef_.shape[0]
    assert model.order_selection_["order"].tolist() == [512, 1024]
    assert 512 < order <= orders.TRIM_SHARE * 1024 and model.order_selection_["best_order"] == order
    monkeypatch.setattr(orders, "TRIM_SHARE", 0.0)
    whole = gm.FIRGaussianProcess(factor=3, noise_kernel="white").fit(u, y_slow)
    assert whole.coef_.shape[0] == 1024
    # the pilot's tuned hyperparameters, held
    np.testing.assert_array_equal(model.kernel_.theta, whole.kernel_.theta)
    assert model.noise_level_ == whole.noise_level_
    # the prior beyond the cut adds under TAIL_TOLERANCE of the noise variance: the fast
    # output on a new input moves by a small part of the noise, the evidence by a
    # thousandth of a nat per slow sample (2 nats here)
    v = rng.standard_normal(3000)
    moved = model.predict(v) - whole.predict(v)
    assert np.sqrt(np.mean(moved**2)) < 0.1 * noise
    assert abs(model.log_marginal_likelihood_value_
               - whole.log_marginal_likelihood_value_) < 1e-3 * y_slow.shape[0]
    np.testing.assert_allclose(model.coef_, whole.coef_[:order], atol=5e-3 * np.abs(g).max())
    # kernel="auto" searches at the cut order from the pilot's tuned prior, as it is
    monkeypatch.setattr(orders, "TRIM_SHARE", 0.75)
    seen = []

    def search(observation, y, kernel, noise_level, noise_bounds, **kwargs):
        seen.append((observation.order, kernel.theta, noise_level, kwargs["tune_base"]))
        raise StopIteration  # the start is all this test reads

    monkeypatch.setattr(resonances, "search_resonances", search)
    with pytest.raises(StopIteration):
        gm.FIRGaussianProcess(factor=3, noise_kernel="white", kernel="auto").fit(u, y_slow)
    (searched_order, theta, noise_level, tune_base), = seen
    assert searched_order == order and tune_base is False
    # (the search works in normalized units: the scale differs, DC's decay and beta do not)
    np.testing.assert_allclose(theta[1:], model.kernel_.theta[1:], rtol=1e-12)


def test_auto_without_a_resonance_is_the_default_fit_from_the_kept_pilot():
    # the search starts from the pilot kept at the default order and does not tune it
    # again: where it keeps no term, the fit is the default kernel's, value for value
    rng = np.random.default_rng(1)
    n = 6000
    u = rng.standard_normal(n)
    y_slow = np.convolve(u, 0.99 ** np.arange(1500))[:n][::3].copy()
    y_slow += 0.02 * np.std(y_slow) * rng.standard_normal(y_slow.shape[0])
    plain = gm.FIRGaussianProcess(factor=3, noise_kernel="white").fit(u, y_slow)
    auto = gm.FIRGaussianProcess(factor=3, noise_kernel="white", kernel="auto").fit(u, y_slow)
    assert auto.resonances_ == [] and auto.order_selection_["order"].tolist() == [512]
    assert auto.kernel_ == plain.kernel_ and auto.noise_level_ == plain.noise_level_
    np.testing.assert_array_equal(auto.coef_, plain.coef_)
