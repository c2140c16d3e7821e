"""Order selection as a step of its own, and the parameters checked before the data."""

from __future__ import annotations

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
    ({"kernel": "dc"}, "kernel"),
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
