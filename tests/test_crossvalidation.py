"""Cross-validation tuning, order selection and the held-out check after evidence tuning."""

import warnings

import numpy as np
import pytest
from scipy.stats import multivariate_normal
from sklearn.gaussian_process.kernels import (
    ConstantKernel as C,
    ExpSineSquared,
    Matern,
    WhiteKernel,
)

import gpmultirate as gm
from gpmultirate import simulation as sim
from gpmultirate.crossvalidation import (
    CrossValidation,
    contiguous_folds,
    held_out_predictions,
    log_predictive_likelihood,
)
from gpmultirate.kernels import DC, PK
from gpmultirate.noise import KernelNoise, noise_instants
from gpmultirate.observations import build_experiment


def refit_per_fold(Phi, K, noise, y, folds):
    """The plain K-refit: for each fold, condition on the other samples and score the block."""
    total, mean = 0.0, np.empty_like(y)
    for B in folds:
        T = np.setdiff1d(np.arange(y.shape[0]), B)
        Phi_T, Phi_B = Phi[T], Phi[B]
        # the posterior of the coefficients from the training samples only (eq. 15)
        Ky_T = Phi_T @ K @ Phi_T.T + noise * np.eye(T.shape[0])
        gain = np.linalg.solve(Ky_T, Phi_T @ K).T
        coef = gain @ y[T]
        cov = K - gain @ Phi_T @ K
        m = Phi_B @ coef
        c = Phi_B @ cov @ Phi_B.T + noise * np.eye(B.shape[0])
        total += multivariate_normal(m, c).logpdf(y[B])
        mean[B] = m
    return total, mean


@pytest.fixture(scope="module")
def small():
    rng = np.random.default_rng(3)
    u = rng.standard_normal(120)
    g = 0.85 ** np.arange(40) * np.cos(0.7 * np.arange(40))
    y = np.convolve(u, g)[:120][::3] + 0.05 * rng.standard_normal(40)
    return u, y


@pytest.mark.parametrize("order, n_folds", [(40, 5), (20, 3), (120, 7)])
def test_objective_matches_a_refit_per_fold(small, order, n_folds):
    u, y = small
    op = gm.DownsampledConvolution(u, 3, order)
    kernel = C(0.7) * DC(alpha=0.8, beta=0.6) + PK(alpha=0.9, omega=0.7)
    folds = contiguous_folds([op.n_outputs], n_folds)
    K = kernel(np.arange(order, dtype=float)[:, None])
    expected, expected_mean = refit_per_fold(op.matrix, K, 0.01, y, folds)
    value = log_predictive_likelihood(op, kernel, 0.01, y, folds)
    assert value == pytest.approx(expected, rel=1e-9)
    mean, variance = held_out_predictions(op, kernel, 0.01, y, folds)
    np.testing.assert_allclose(mean, expected_mean, rtol=1e-8, atol=1e-10)
    assert np.all(variance > 0.01)


def test_gradient_matches_finite_differences(small):
    u, y = small
    op = gm.DownsampledConvolution(u, 3, 40)
    objective = CrossValidation(
        op, y, C(0.7) * DC(alpha=0.8, beta=0.6) + PK(alpha=0.9, omega=0.7), 0.01,
        (1e-6, 1.0), n_folds=4,
    )
    theta = objective.theta
    value, grad = objective(theta, eval_gradient=True)
    # 1e-6 is at the rounding floor of this objective (an error of 1e-6 on the
    # PK frequency's derivative with numpy 2.4's BLAS); 1e-4 is 4e-9 from the limit
    step = 1e-4
    numeric = [
        (objective(theta + step * e) - objective(theta - step * e)) / (2 * step)
        for e in np.eye(theta.shape[0])
    ]
    np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-6)


def conditional_per_fold(Ky, y, folds):
    """sum_k log N(y_B | the rest) from the joint covariance ``Ky`` of all samples."""
    total = 0.0
    for B in folds:
        R = np.setdiff1d(np.arange(y.shape[0]), B)
        gain = np.linalg.solve(Ky[np.ix_(R, R)], Ky[np.ix_(R, B)]).T
        cov = Ky[np.ix_(B, B)] - gain @ Ky[np.ix_(R, B)]
        total += multivariate_normal(gain @ y[R], 0.5 * (cov + cov.T)).logpdf(y[B])
    return total


DISTURBANCES = [
    WhiteKernel(0.004) + C(0.02) * Matern(8.0, nu=1.5),
    WhiteKernel(0.004) + C(0.02) * Matern(5.0, nu=0.5),
    C(0.02) * Matern(5.0, nu=0.5),  # an AR(1) noise alone
    WhiteKernel(0.004) + C(0.01) * ExpSineSquared(2.0, 24.0, periodicity_bounds="fixed"),
]


@pytest.mark.parametrize("noise_kernel", DISTURBANCES)
def test_objective_under_a_disturbance_is_the_dense_conditional_density(small, noise_kernel):
    u, y = small
    op = gm.DownsampledConvolution(u, 3, 40)
    kernel = C(0.7) * DC(alpha=0.8, beta=0.6) + PK(alpha=0.9, omega=0.7)
    noise = KernelNoise(noise_kernel, noise_instants(op))
    folds = contiguous_folds([op.n_outputs], 4)
    K = kernel(op.lags)
    Ky = op.matrix @ K @ op.matrix.T + noise_kernel(np.arange(0, 120, 3.0)[:, None])
    expected = conditional_per_fold(Ky, y, folds)
    assert log_predictive_likelihood(op, kernel, noise, y, folds) == pytest.approx(
        expected, rel=1e-8)
    objective = CrossValidation(op, y, kernel, 0.01, (1e-6, 1.0), n_folds=4, noise=noise)
    assert objective.coloured
    assert objective.theta.shape[0] == kernel.theta.shape[0] + noise_kernel.theta.shape[0]
    assert objective(objective.theta) == pytest.approx(expected, rel=1e-8)
    # white noise as a model is the white objective
    white = WhiteKernel(0.01)
    assert log_predictive_likelihood(op, kernel, KernelNoise(white, noise_instants(op)), y,
                                     folds) == pytest.approx(
        log_predictive_likelihood(op, kernel, 0.01, y, folds), rel=1e-10)


@pytest.mark.parametrize("noise_kernel", DISTURBANCES)
def test_gradient_under_a_disturbance_matches_finite_differences(small, noise_kernel):
    u, y = small
    op = gm.DownsampledConvolution(u, 3, 40)
    noise = KernelNoise(noise_kernel, noise_instants(op))
    objective = CrossValidation(op, y, C(0.7) * DC(alpha=0.8, beta=0.6), 0.01, (1e-6, 1.0),
                                n_folds=4, noise=noise)
    theta = objective.theta + 0.05
    value, grad = objective(theta, eval_gradient=True)
    assert value == pytest.approx(objective(theta), rel=1e-12)
    step = 1e-5
    numeric = np.array([
        (objective(theta + step * e) - objective(theta - step * e)) / (2 * step)
        for e in np.eye(theta.shape[0])
    ])
    np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-6 * np.abs(numeric).max())
    # the noise model's entries move the objective: a gradient of zeros would pass nothing
    assert np.all(np.abs(grad[-noise.theta.shape[0]:]) > 1e-6)


def test_records_are_folded_each_in_time_order():
    folds = contiguous_folds([10, 4], 3)
    assert [f.tolist() for f in folds] == [[0, 1, 2, 3, 10, 11], [4, 5, 6, 12], [7, 8, 9, 13]]
    with pytest.raises(ValueError, match="cv"):
        contiguous_folds([4, 3], 5)
    with pytest.raises(ValueError, match="cv"):
        contiguous_folds([10], 1)


def test_several_records_and_inputs_match_a_refit(small):
    u, y = small
    rng = np.random.default_rng(5)
    u2 = rng.standard_normal((90, 2))
    y2 = rng.standard_normal(30)
    experiment = build_experiment([np.c_[u, u[::-1]], u2], [y, y2], factor=3, order=25)
    op = experiment.observation
    kernel = gm.kernels.PerInputKernel([C(1.0) * DC(alpha=0.8), C(0.5) * DC(alpha=0.7)])
    folds = contiguous_folds([r.n_outputs for r in op.records], 4)
    lags = np.arange(25, dtype=float)[:, None]
    K = np.zeros((50, 50))
    K[:25, :25] = kernel.kernels[0](lags)
    K[25:, 25:] = kernel.kernels[1](lags)
    expected, _ = refit_per_fold(op.matrix, K, 0.1, experiment.y, folds)
    assert log_predictive_likelihood(op, kernel, 0.1, experiment.y, folds) == pytest.approx(
        expected, rel=1e-9)


@pytest.fixture(scope="module")
def paper():
    system = sim.paper_system(0.1)
    u = sim.multisine(300, random_state=1)
    data = sim.simulate_experiment(system, u, 3, snr_db=30, random_state=3)
    u_val = sim.multisine(300, random_state=2)
    return data, u_val, system.simulate(u_val)


def test_cross_validation_tuning_maximizes_its_objective(paper):
    data, u_val, y_val = paper
    model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=150,
                                  tuning="cross_validation", cv=4).fit(data.u, data.y_slow)
    objective = CrossValidation(model.observation_, model.y_slow_, model.kernel_,
                                model.noise_level_, model.noise_level_bounds_, 4)
    theta = objective.theta
    best = objective(theta)
    assert best == pytest.approx(model.cv_log_predictive_likelihood_, rel=1e-10)
    rng = np.random.default_rng(0)
    bounds = objective.bounds
    for _ in range(5):  # no nearby point is better
        step = 0.05 * rng.standard_normal(theta.shape[0])
        assert objective(np.clip(theta + step, bounds[:, 0], bounds[:, 1])) <= best + 1e-6
    # and it identifies the system as well as the evidence does here
    evidence = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=150).fit(data.u, data.y_slow)
    assert model.score(u_val, y_val) > evidence.score(u_val, y_val) - 1.0


@pytest.mark.slow
def test_auto_order_is_the_best_of_a_brute_force_sweep(paper):
    data, _, _ = paper
    orders = [20, 40, 80, 160]
    for criterion in ("evidence", "cross_validation"):
        model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=orders, tuning=criterion,
                                      cv=4).fit(data.u, data.y_slow)
        sweep = []
        for order in orders:
            single = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=order,
                                           tuning=criterion, cv=4)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                single.fit(data.u, data.y_slow)
            sweep.append(single.log_marginal_likelihood_value_ if criterion == "evidence"
                         else single.cv_log_predictive_likelihood_)
        best = orders[int(np.argmax(sweep))]
        selection = model.order_selection_
        assert selection["best_order"] == best == model.observation_.order == model.coef_.shape[0]
        np.testing.assert_allclose(selection["score"], np.array(sweep) / data.y_slow.shape[0],
                                   rtol=1e-9)
        assert model.order == orders  # the parameter is left as given


def test_auto_order_grid():
    assert gm.estimators.auto_orders(683) == [21, 42, 85, 170, 341, 683]
    assert gm.estimators.auto_orders(15) == [15]


@pytest.mark.parametrize("bad, match", [
    (dict(tuning="loo"), "tuning"), (dict(cv=1), "cv"), (dict(cv=2.5), "cv"),
    (dict(order="best"), "order"), (dict(order=[]), "order"), (dict(order=[10, 0]), "order"),
    (dict(order=[10, 1000]), "order"),
])
def test_bad_arguments_name_themselves(small, bad, match):
    u, y = small
    with pytest.raises(ValueError, match=match):
        gm.FIRGaussianProcess(factor=3, **bad).fit(u, y)


def _too_long_prior():
    """A prior fixed far too long for a fast system in heavy noise: only the noise is
    tuned, and the coefficients at long lags fit noise that held-out blocks expose."""
    rng = np.random.default_rng(4)
    u = rng.standard_normal(600)
    y = np.convolve(u, 0.6 ** np.arange(20))[:600] + 0.5 * rng.standard_normal(600)
    kernel = C(1.0, "fixed") * DC(alpha=0.999, beta=0.5, alpha_bounds="fixed",
                                  beta_bounds="fixed")
    return u, y, kernel


def test_held_out_check_names_a_shorter_order_when_it_predicts_better():
    u, y, kernel = _too_long_prior()
    with pytest.warns(gm.HeldOutWarning, match=r"order=75 fits [\d.]+ % of them, order=600 -"):
        model = gm.FIRGaussianProcess(kernel, factor=3, order=600).fit(u, y[::3])
    assert model.coef_.shape == (600,)  # an explicit order is kept
    assert not hasattr(model, "order_selection_")
    # the warning's numbers are those of the held-out predictions at the two orders
    folds = contiguous_folds([200], 5)
    for order, sign in ((600, -1), (75, 1)):
        op = gm.DownsampledConvolution(u, 3, order)
        mean, _ = held_out_predictions(op, model.kernel_, model.noise_level_, y[::3], folds)
        assert np.sign(gm.fit_percent(y[::3], mean)) == sign


def test_default_order_is_cut_where_held_out_samples_are_predicted_better(tmp_path):
    u, y, kernel = _too_long_prior()
    with warnings.catch_warnings():
        warnings.simplefilter("error", gm.HeldOutWarning)  # acted on, not warned about
        model = gm.FIRGaussianProcess(kernel, factor=3).fit(u, y[::3])
    # independently: the fit at the default order N = 600 and the held-out fit of
    # every candidate order at its tuned values, by a dense refit per fold
    full = gm.FIRGaussianProcess(kernel, factor=3, order=600)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", gm.HeldOutWarning)
        full.fit(u, y[::3])
    folds = contiguous_folds([200], 5)
    orders = [18, 37, 75, 150, 300, 600]
    expected = []
    for order in orders:
        K = full.kernel_(np.arange(order, dtype=float)[:, None])
        Phi = gm.DownsampledConvolution(u, 3, order).matrix
        _, mean = refit_per_fold(Phi, K, full.noise_level_, y[::3], folds)
        expected.append(gm.fit_percent(y[::3], mean))
    selection = model.order_selection_
    assert selection["criterion"] == "held_out_fit"
    np.testing.assert_array_equal(selection["order"], orders)
    np.testing.assert_allclose(selection["score"], expected, rtol=1e-9, atol=1e-9)
    best = orders[int(np.argmax(expected))]
    assert expected[-1] + gm.estimators.ORDER_MARGIN < max(expected)
    assert selection["best_order"] == best == model.coef_.shape[0]
    # the kept model is the fit at that order
    explicit = gm.FIRGaussianProcess(kernel, factor=3, order=best).fit(u, y[::3])
    np.testing.assert_allclose(model.coef_, explicit.coef_, rtol=1e-10, atol=1e-12)
    assert model.noise_level_ == pytest.approx(explicit.noise_level_, rel=1e-10)
    gm.save_model(model, tmp_path / "m.npz")
    loaded = gm.load_model(tmp_path / "m.npz")
    assert loaded.get_params()["order"] is None
    np.testing.assert_array_equal(loaded.coef_, model.coef_)
    for key in ("order", "score"):
        np.testing.assert_array_equal(loaded.order_selection_[key], selection[key])
    assert loaded.order_selection_["criterion"] == "held_out_fit"


def test_default_order_stays_at_n_on_an_fir_system(paper):
    data, _, _ = paper
    model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3).fit(data.u, data.y_slow)
    n = data.u.shape[0]
    assert model.coef_.shape == (n,)
    assert model.order_selection_["best_order"] == n
    assert model.order_selection_["order"][-1] == n


def test_held_out_check_is_silent_on_an_fir_system(paper):
    data, _, _ = paper
    with warnings.catch_warnings():
        warnings.simplefilter("error", gm.HeldOutWarning)
        gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=300).fit(data.u, data.y_slow)


def test_selected_model_round_trips_through_a_file(paper, tmp_path):
    data, u_val, _ = paper
    model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=[40, 80],
                                  tuning="cross_validation", cv=4).fit(data.u, data.y_slow)
    gm.save_model(model, tmp_path / "m.npz")
    loaded = gm.load_model(tmp_path / "m.npz")
    assert loaded.get_params()["order"] == [40, 80]
    assert loaded.get_params()["tuning"] == "cross_validation"
    np.testing.assert_array_equal(loaded.predict(u_val), model.predict(u_val))
    assert loaded.cv_log_predictive_likelihood_ == model.cv_log_predictive_likelihood_
    for key in ("order", "score"):
        np.testing.assert_array_equal(loaded.order_selection_[key], model.order_selection_[key])
    assert loaded.order_selection_["best_order"] == model.order_selection_["best_order"]
    assert loaded.order_selection_["criterion"] == "cv_log_predictive"


@pytest.mark.slow
def test_default_order_on_measured_data_stops_a_wrong_model_from_extrapolating():
    # the CD arm's second output is driven by the second input: from the first alone
    # a long response fits disturbances and extrapolates far below 0 % on later data
    from gpmultirate.datasets import load_cd_player_arm
    from gpmultirate.holdout import holdout_split

    data = load_cd_player_arm()
    split = holdout_split(data.u[:, 0], data.y[:, 1], 3, center=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # white noise: a disturbance model (the default "auto") tempers the extrapolation
        full = gm.FIRGaussianProcess(factor=3, kernel="auto", order=split.n_estimation,
                                     noise_kernel="white")
        full.fit(split.u_estimation, split.y_slow)
        white = gm.FIRGaussianProcess(factor=3, kernel="auto", noise_kernel="white")
        white.fit(split.u_estimation, split.y_slow)
        default = gm.FIRGaussianProcess(factor=3, kernel="auto")
        default.fit(split.u_estimation, split.y_slow)
    assert split.evaluate(full).fit_percent < -10.0
    # under white noise the held-out check cuts the order
    assert white.order_selection_["best_order"] < split.n_estimation // 4
    assert abs(split.evaluate(white).fit_percent) < 2.0
    # the default's disturbance model keeps the long response from extrapolating too
    assert default.noise_kernel_ != "white"
    assert abs(split.evaluate(default).fit_percent) < 2.0


def test_a_refit_leaves_no_order_selection_of_an_earlier_fit(paper):
    data, _, _ = paper
    model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=[40, 80], cv=4)
    model.fit(data.u, data.y_slow)
    assert model.order_selection_["criterion"] == "log_evidence"
    # the held-out check runs after tuning only: nothing to report
    model.set_params(order=None, optimizer=None).fit(data.u, data.y_slow)
    assert not hasattr(model, "order_selection_")


def test_held_out_check_of_a_small_problem_runs_on_one_blas_thread(paper, monkeypatch):
    # as tuning does: on 2 cores a 200 x 200 factorization is 4-5 times slower
    # on two BLAS threads than on one
    from threadpoolctl import threadpool_info

    from gpmultirate import orders

    seen = []
    original = orders.held_out_predictions

    def spy(*args, **kwargs):
        seen.append([i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"])
        return original(*args, **kwargs)

    monkeypatch.setattr(orders, "held_out_predictions", spy)
    data, _, _ = paper
    gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=300).fit(data.u, data.y_slow)
    assert seen and all(threads == [1] * len(threads) and threads for threads in seen)


def test_held_out_order_check_at_own_instants():
    # the too-long prior read at instants inside the fast periods: the check runs on the
    # timed readings (the same folds, the readings' covariance at each shorter order)
    rng = np.random.default_rng(4)
    u = rng.standard_normal(600)
    times = np.arange(0, 600, 3) + rng.uniform(0, 1, 200)
    timed = gm.TimedConvolution(u, times, 600)
    y = timed.lag_functionals(lambda x: (0.6 ** x)[:, None])[:, 0]
    y = y + 0.5 * rng.standard_normal(200)
    _, _, kernel = _too_long_prior()
    with pytest.warns(gm.HeldOutWarning, match=r"order=75 fits 32.9 % of them, order=600 -6.5 %"):
        model = gm.FIRGaussianProcess(kernel, order=600).fit(u, y, sample_times=times)
    # the warning's numbers: the held-out predictions of the readings at the two orders
    folds = contiguous_folds([200], 5)
    for order, expected in ((600, -6.5), (75, 32.9)):
        readings = gm.TimedConvolution(u, times, order)
        mean, _ = held_out_predictions(readings, model.kernel_, model.noise_level_, y, folds)
        assert gm.fit_percent(y, mean) == pytest.approx(expected, abs=0.05)
    with warnings.catch_warnings():
        warnings.simplefilter("error", gm.HeldOutWarning)  # acted on, not warned about
        default = gm.FIRGaussianProcess(kernel).fit(u, y, sample_times=times)
    assert default.order_selection_["criterion"] == "held_out_fit"
    assert default.coef_.shape[0] == default.order_selection_["best_order"] < 600
