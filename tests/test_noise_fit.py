"""The disturbance model inside the estimator: evidence, gradient and posterior of a fit
against the dense formulas with the disturbance covariance, finite differences, the
measurement band by Monte Carlo with disturbances drawn from the model, and the checks."""

import warnings

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import (
    ConstantKernel as C,
    ExpSineSquared,
    Matern,
    WhiteKernel,
)

from gpmultirate import FIRGaussianProcess
from gpmultirate.kernels import DC
from gpmultirate.noise import KernelNoise, dense_log_evidence, dense_posterior, noise_instants

FACTOR, ORDER = 3, 30

pytestmark = pytest.mark.filterwarnings("ignore:tuning ended on a bound",
                                    "ignore:order=30 looks too short")


def _data(seed=0, n=240):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    y = np.convolve(u, 0.85 ** np.arange(ORDER))[:n]
    drift = np.cumsum(0.05 * rng.standard_normal(n))
    return u, (y + drift + 0.05 * rng.standard_normal(n))[::FACTOR]


def _fd(f, theta, step=1e-6):
    out = []
    for j in range(theta.shape[0]):
        e = np.zeros_like(theta)
        e[j] = step
        out.append((f(theta + e) - f(theta - e)) / (2 * step))
    return np.array(out)


def _dense_parts(model, theta):
    """Phi, K, dK, N, dN of a fitted model at ``theta`` (kernel's entries, then the noise's)."""
    op = model.observation_
    n_kernel = model.kernel_.theta.shape[0]
    kernel = model.kernel_.clone_with_theta(theta[:n_kernel])
    noise = KernelNoise(model.noise_kernel_.clone_with_theta(theta[n_kernel:]),
                        noise_instants(op))
    K, dK = kernel(op.lags, eval_gradient=True)
    N, dN = noise.matrix_with_gradient()
    return op.matrix, K, dK, N, dN


@pytest.mark.parametrize("noise_kernel", [
    "matern12",
    "matern32",
    C(0.1) * ExpSineSquared(2.0, 24.0, periodicity_bounds="fixed"),
    "ar1",  # M = 80 > P = 30 on one uniform grid: the AR(1) route
    Matern(9.0, nu=0.5) * C(0.1),  # the same, its theta in the other order
])
def test_fitted_evidence_gradient_and_posterior_against_dense_formulas(noise_kernel):
    u, y = _data()
    model = FIRGaussianProcess(C(1.0) * DC(0.8, 0.5), factor=FACTOR, order=ORDER,
                               noise_level=1e-2, noise_kernel=noise_kernel).fit(u, y)
    # in the data's units: the kernel's, then the noise kernel's
    theta = np.concatenate([model.kernel_.theta, model.noise_kernel_.theta])
    n_kernel = model.kernel_.theta.shape[0]
    assert model._evidence.theta.shape[0] == n_kernel + model.noise_kernel_.theta.shape[0]
    Phi, K, dK, N, dN = _dense_parts(model, theta)
    ref, ref_grad = dense_log_evidence(Phi, K, y, N, dK, dN, eval_gradient=True)
    assert model.log_marginal_likelihood_value_ == pytest.approx(ref, rel=1e-8)
    moved = theta + 0.1
    value, grad = model.log_marginal_likelihood(moved, eval_gradient=True)
    Phi, K, dK, N, dN = _dense_parts(model, moved)
    ref, ref_grad = dense_log_evidence(Phi, K, y, N, dK, dN, eval_gradient=True)
    assert value == pytest.approx(ref, rel=1e-8)
    np.testing.assert_allclose(grad, ref_grad, rtol=1e-8, atol=1e-8 * np.abs(ref_grad).max())
    numeric = _fd(lambda t: model.log_marginal_likelihood(t), moved)
    np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-6 * np.abs(numeric).max())
    Phi, K, _, N, _ = _dense_parts(model, theta)
    mu, Sigma = dense_posterior(Phi, K, y, N)
    np.testing.assert_allclose(model.coef_, mu, rtol=1e-8, atol=1e-10 * np.abs(mu).max())
    np.testing.assert_allclose(model.posterior_.covariance(), Sigma, rtol=1e-8,
                               atol=1e-10 * np.abs(Sigma).max())
    # the fast-rate output band is that of the dense posterior
    mean, std = model.predict(u, return_std=True)
    rows = np.array([np.concatenate([u[n::-1], np.zeros(ORDER)])[:ORDER] for n in range(len(u))])
    np.testing.assert_allclose(mean, rows @ mu, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(std**2, np.einsum("ij,jk,ik->i", rows, Sigma, rows), rtol=1e-8,
                               atol=1e-12)


def test_tuning_raises_the_evidence_over_white_on_a_drifting_record():
    u, y = _data(1)
    white = FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel="white").fit(u, y)
    coloured = FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel="matern12").fit(u, y)
    assert white.noise_kernel_ == "white"
    assert isinstance(coloured.noise_kernel_, type(WhiteKernel() + Matern()))
    assert coloured.log_marginal_likelihood_value_ > white.log_marginal_likelihood_value_ + 5
    assert coloured.noise_level_ == pytest.approx(coloured.noise_kernel_.k1.noise_level)


def test_noise_kernel_is_checked():
    u, y = _data()
    for bad in ("matern52", 3, None):
        with pytest.raises(ValueError, match="noise_kernel"):
            FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel=bad).fit(u, y)
    model = FIRGaussianProcess(noise_kernel="matern32")
    assert model.get_params()["noise_kernel"] == "matern32"
    assert FIRGaussianProcess().get_params()["noise_kernel"] == "auto"
    with pytest.raises(ValueError, match="return_std"):
        FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel="white").fit(u, y).predict(
            u, include_noise=True)


@pytest.mark.slow
def test_measurement_band_is_calibrated_with_disturbances_drawn_from_the_model():
    """Systems drawn from the prior, disturbances from the noise kernel: a new record's
    measured samples fall in the 95 % measurement band 95 % of the time, and the
    standardized errors have unit variance; the band of the output alone is too narrow."""
    rng = np.random.default_rng(11)
    kernel = C(1.0, "fixed") * DC(0.8, 0.5, "fixed", "fixed")
    noise_kernel = WhiteKernel(0.02, "fixed") + C(0.3, "fixed") * Matern(12.0, "fixed", nu=1.5)
    n, n_new = 150, 90
    t_new = np.arange(n_new, dtype=float)[:, None]
    L_new = np.linalg.cholesky(noise_kernel(t_new) + 1e-12 * np.eye(n_new))
    z_band, z_output = [], []
    for _ in range(200):
        u = rng.standard_normal(n)
        model = FIRGaussianProcess(kernel, factor=FACTOR, order=ORDER, optimizer=None,
                                   noise_kernel=noise_kernel)
        op_lags = np.arange(ORDER, dtype=float)[:, None]
        g = np.linalg.cholesky(kernel(op_lags) + 1e-12 * np.eye(ORDER)) @ rng.standard_normal(
            ORDER)
        t = np.arange(0, n, FACTOR, dtype=float)[:, None]
        L = np.linalg.cholesky(noise_kernel(t) + 1e-12 * np.eye(t.shape[0]))
        y = np.convolve(u, g)[:n][::FACTOR] + L @ rng.standard_normal(t.shape[0])
        model.fit(u, y)
        u_new = rng.standard_normal(n_new)
        measured = np.convolve(u_new, g)[:n_new] + L_new @ rng.standard_normal(n_new)
        mean, std = model.predict(u_new, return_std=True, include_noise=True)
        _, std_output = model.predict(u_new, return_std=True)
        z_band.append((measured - mean) / std)
        z_output.append((measured - mean) / std_output)
    z_band, z_output = np.concatenate(z_band), np.concatenate(z_output)
    coverage = np.mean(np.abs(z_band) < 1.959964)
    assert 0.93 < coverage < 0.97
    assert np.mean(z_band**2) == pytest.approx(1.0, abs=0.08)
    assert np.mean(np.abs(z_output) < 1.959964) < 0.8


@pytest.mark.slow
def test_auto_keeps_white_noise_where_the_data_do_not_call_for_more():
    rng = np.random.default_rng(3)
    u = rng.standard_normal(300)
    y = np.convolve(u, 0.85 ** np.arange(ORDER))[:300][::FACTOR]
    y = y + 0.05 * rng.standard_normal(y.shape[0])
    auto = FIRGaussianProcess(factor=FACTOR, order=ORDER).fit(u, y)
    white = FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel="white").fit(u, y)
    assert auto.noise_kernel_ == "white"
    np.testing.assert_array_equal(auto.coef_, white.coef_)
    assert auto.log_marginal_likelihood_value_ == white.log_marginal_likelihood_value_


def test_auto_chooses_the_disturbance_of_a_drifting_record_by_the_evidence():
    from gpmultirate.estimators import AUTO_NOISE_MARGIN

    u, y = _data(0)  # the prior decays within the order: a disturbance is considered
    auto = FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel="auto").fit(u, y)
    white = FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel="white").fit(u, y)
    fits = {name: FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel=name).fit(u, y)
            for name in ("matern12", "matern32")}
    best = max(fits, key=lambda name: fits[name].log_marginal_likelihood_value_)
    assert (fits[best].log_marginal_likelihood_value_
            > white.log_marginal_likelihood_value_ + AUTO_NOISE_MARGIN)
    assert auto.noise_kernel_ == fits[best].noise_kernel_
    assert auto.log_marginal_likelihood_value_ == pytest.approx(
        fits[best].log_marginal_likelihood_value_, rel=1e-12)


@pytest.mark.parametrize("noise_kernel", ["matern32", C(0.1) * ExpSineSquared(2.0, 24.0), "ar1"])
def test_a_disturbance_model_is_saved_and_loaded(tmp_path, noise_kernel):
    from gpmultirate import load_model, save_model

    u, y = _data(1)
    model = FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel=noise_kernel).fit(u, y)
    save_model(model, tmp_path / "model.gpm")
    loaded = load_model(tmp_path / "model.gpm")
    assert repr(loaded.noise_kernel_) == repr(model.noise_kernel_)
    assert repr(loaded.get_params()["noise_kernel"]) == repr(noise_kernel)
    np.testing.assert_allclose(loaded.coef_, model.coef_, rtol=1e-8, atol=1e-12)
    _, std = model.predict(u, return_std=True, include_noise=True)
    _, loaded_std = loaded.predict(u, return_std=True, include_noise=True)
    np.testing.assert_allclose(loaded_std, std, rtol=1e-8)


def test_multi_output_passes_the_noise_kernel_through():
    from gpmultirate import MultiOutputFIR

    u, y = _data(1)
    _, y2 = _data(2)
    model = MultiOutputFIR(FIRGaussianProcess(factor=FACTOR, order=ORDER,
                                              noise_kernel="matern12")).fit(
        u, np.column_stack([y, y2]))
    for estimator in model.estimators_:
        assert not isinstance(estimator.noise_kernel_, str)


@pytest.mark.slow
def test_command_line_noise_option_summary_and_residual_figure(tmp_path, capsys):
    import json

    from gpmultirate.cli import main

    u, y = _data(1)
    column = np.full(u.shape[0], np.nan)
    column[::FACTOR] = y
    data = tmp_path / "data.csv"
    np.savetxt(data, np.column_stack([u, column]), delimiter=",", header="u,y", comments="")
    out = tmp_path / "fit"
    assert main(["fit", str(data), "--input", "u", "--output", "y", "--order", str(ORDER),
                 "--noise", "matern12", "--out", str(out), "--quiet"]) == 0
    assert "disturbance std" in capsys.readouterr().out
    assert (out / "residuals.png").read_bytes()[:4] == b"\x89PNG"
    noise = json.loads((out / "summary.json").read_text())["model"]["noise"]
    model = FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel="matern12").fit(u, y)
    assert noise["model"] == str(model.noise_kernel_)
    assert noise["white_level"] == pytest.approx(model.noise_level_, rel=1e-6)
    total = model.noise_kernel_.k1.noise_level + model.noise_kernel_.k2.k1.constant_value
    assert noise["white_level"] + noise["disturbance_level"] == pytest.approx(total, rel=1e-6)
    assert noise["time_scale"]["k2__k2__length_scale"] == pytest.approx(
        model.noise_kernel_.k2.k2.length_scale, rel=1e-6)
    assert isinstance(noise["residuals_white"], bool)
    assert "noise model" in (out / "summary.md").read_text()
    with pytest.raises(SystemExit):
        main(["fit", str(data), "--input", "u", "--output", "y", "--noise", "matern52",
              "--out", str(out)])


def _dense_cv(model, noise_kernel, n_folds=5):
    """sum_k log N(y_Bk | the rest) with ``Ky = Phi K Phi^T + N`` at a model's values, dense."""
    from scipy.stats import multivariate_normal

    from gpmultirate.crossvalidation import contiguous_folds

    op, y = model.observation_, model.y_slow_
    if isinstance(noise_kernel, str):
        N = model.noise_level_ * np.eye(y.shape[0])
    else:
        N = KernelNoise(noise_kernel, noise_instants(op)).matrix()
    Ky = op.matrix @ model.kernel_(op.lags) @ op.matrix.T + N
    total = 0.0
    for B in contiguous_folds([op.n_outputs], n_folds):
        R = np.setdiff1d(np.arange(y.shape[0]), B)
        gain = np.linalg.solve(Ky[np.ix_(R, R)], Ky[np.ix_(R, B)]).T
        cov = Ky[np.ix_(B, B)] - gain @ Ky[np.ix_(R, B)]
        total += multivariate_normal(gain @ y[R], 0.5 * (cov + cov.T)).logpdf(y[B])
    return total


@pytest.fixture(scope="module")
def cv_fits():
    u, y = _data(1, n=300)
    return u, y, {name: FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel=name,
                                           tuning="cross_validation").fit(u, y)
                  for name in ("white", "matern12", "matern32", "ar1", "auto")}


def test_cross_validation_tunes_an_explicit_disturbance_by_its_own_objective(cv_fits):
    u, y, fits = cv_fits
    white = fits["white"]
    assert white.cv_log_predictive_likelihood_ == pytest.approx(_dense_cv(white, "white"),
                                                                rel=1e-8)
    # "ar1": the AR(1) noise alone, which the evidence takes through its precision for
    # M > P; cross-validation works in data space anyway
    for name in ("matern12", "matern32", "ar1"):
        model = fits[name]
        assert model.noise_kernel_ != "white"
        # the reported value is the chosen model's, in the data's units
        assert model.cv_log_predictive_likelihood_ == pytest.approx(
            _dense_cv(model, model.noise_kernel_), rel=1e-8)
        # on a drifting record the disturbance predicts the held-out blocks far better
        assert model.cv_log_predictive_likelihood_ > white.cv_log_predictive_likelihood_ + 50
        # tuned by cross-validation, not by the evidence: at least the held-out density
        # of the evidence's tuned disturbance
        by_evidence = FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel=name).fit(u, y)
        assert model.cv_log_predictive_likelihood_ >= _dense_cv(
            by_evidence, by_evidence.noise_kernel_) - 1e-6
        # the posterior is the one under the tuned disturbance
        Phi, K, _, N, _ = _dense_parts(model, np.concatenate([model.kernel_.theta,
                                                              model.noise_kernel_.theta]))
        mu, _ = dense_posterior(Phi, K, y, N)
        np.testing.assert_allclose(model.coef_, mu, rtol=1e-8, atol=1e-10 * np.abs(mu).max())


def test_auto_under_cross_validation_keeps_the_better_disturbance_by_a_margin(cv_fits):
    _, _, fits = cv_fits
    best = max(("matern12", "matern32"), key=lambda n: fits[n].cv_log_predictive_likelihood_)
    auto = fits["auto"]
    assert auto.cv_log_predictive_likelihood_ == pytest.approx(
        fits[best].cv_log_predictive_likelihood_, rel=1e-10)
    assert repr(auto.noise_kernel_) == repr(fits[best].noise_kernel_)


def test_auto_under_cross_validation_keeps_white_noise_where_the_record_is_white():
    rng = np.random.default_rng(4)
    u = rng.standard_normal(300)
    y = (np.convolve(u, 0.85 ** np.arange(ORDER))[:300] + 0.05 * rng.standard_normal(300))[::3]
    fits = {name: FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel=name,
                                     tuning="cross_validation").fit(u, y)
            for name in ("auto", "white")}
    assert fits["auto"].noise_kernel_ == "white"
    assert fits["auto"].cv_log_predictive_likelihood_ == pytest.approx(
        fits["white"].cv_log_predictive_likelihood_, rel=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("order", [100, 600])
def test_auto_keeps_the_paper_study_white_at_a_cut_order_and_at_n(order):
    from gpmultirate.study import paper_kernels, simulate_run

    data = simulate_run(3)
    kernel, noise = paper_kernels(0.1)["DC"]
    fits = {name: FIRGaussianProcess(kernel, factor=3, order=order, noise_level=noise,
                                     noise_kernel=name).fit(data.u, data.y_slow)
            for name in ("auto", "white")}
    assert fits["auto"].noise_kernel_ == "white"
    np.testing.assert_array_equal(fits["auto"].coef_, fits["white"].coef_)
    if order == 100:
        # the cut tail colours the residuals: a disturbance would win, the tail rule keeps white
        coloured = FIRGaussianProcess(kernel, factor=3, order=order, noise_level=noise,
                                      noise_kernel="matern32").fit(data.u, data.y_slow)
        assert (coloured.log_marginal_likelihood_value_
                > fits["white"].log_marginal_likelihood_value_ + 10)


def test_held_out_predictions_under_a_disturbance_against_dense_conditioning():
    from gpmultirate import DownsampledConvolution
    from gpmultirate.crossvalidation import contiguous_folds, held_out_predictions

    u, y = _data(4)
    op = DownsampledConvolution(u, FACTOR, ORDER)
    kernel = C(0.8) * DC(0.85, 0.3)
    noise = KernelNoise(WhiteKernel(1e-3) + C(0.05) * Matern(20.0, nu=1.5), noise_instants(op))
    folds = contiguous_folds([op.n_outputs], 4)
    mean, variance = held_out_predictions(op, kernel, noise, y, folds)
    Phi = op.matrix
    Ky = Phi @ kernel(op.lags) @ Phi.T + noise.matrix()
    for B in folds:
        R = np.setdiff1d(np.arange(y.shape[0]), B)
        weights = np.linalg.solve(Ky[np.ix_(R, R)], Ky[np.ix_(R, B)])
        np.testing.assert_allclose(mean[B], weights.T @ y[R], rtol=1e-8, atol=1e-10)
        expected = np.diag(Ky[np.ix_(B, B)] - Ky[np.ix_(B, R)] @ weights)
        np.testing.assert_allclose(variance[B], expected, rtol=1e-8)


@pytest.mark.slow
def test_default_band_of_the_impulse_response_holds_under_an_ar1_disturbance():
    """Monte Carlo over paper-like systems with an AR(1) disturbance (pole 0.99, 20 dB)."""
    from gpmultirate.simulation import multisine, paper_system

    n, factor, pole = 600, 3, 0.99
    coverage, gof = {"auto": [], "white": []}, {"auto": [], "white": []}
    for seed in range(6):
        rng = np.random.default_rng(seed)
        system = paper_system(0.1, perturbation=0.1, random_state=rng)
        u = multisine(n, 0.1, random_state=rng)
        u_val = multisine(n, 0.1, random_state=rng)
        y = system.simulate(u)
        e = rng.standard_normal(n)
        v = np.empty(n)
        v[0] = e[0]
        for k in range(1, n):
            v[k] = pole * v[k - 1] + np.sqrt(1 - pole**2) * e[k]
        y_slow = (y + v * np.sqrt(np.var(y) / 100.0))[::factor]
        impulse = np.zeros(n)
        impulse[0] = 1.0
        g = system.simulate(impulse)
        for name in coverage:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                model = FIRGaussianProcess(factor=factor, noise_kernel=name).fit(u, y_slow)
            mean, std = model.impulse_response(return_std=True)
            coverage[name].append(np.mean(np.abs(g[: mean.shape[0]] - mean) <= 1.959964 * std))
            gof[name].append(model.score(u_val, system.simulate(u_val)))
    assert 0.9 <= np.mean(coverage["auto"]) <= 0.99
    assert np.mean(coverage["auto"]) > np.mean(coverage["white"]) + 0.05
    assert np.mean(gof["auto"]) >= np.mean(gof["white"])


def test_auto_on_a_long_white_record_takes_the_ar1_check_and_keeps_white(monkeypatch):
    from gpmultirate.fitting import disturbance

    rng = np.random.default_rng(11)
    n = 3 * 1100  # M = 1100 slow samples: beyond the dense check
    u = rng.standard_normal(n)
    y = np.convolve(u, 0.6 ** np.arange(20))[:n][::FACTOR] + 0.05 * rng.standard_normal(1100)
    seen = []
    original = disturbance.ar1_evidence_gain
    monkeypatch.setattr(disturbance, "ar1_evidence_gain",
                        lambda *args: seen.append(original(*args)) or seen[-1])
    auto = FIRGaussianProcess(factor=FACTOR, order=40).fit(u, y)
    white = FIRGaussianProcess(factor=FACTOR, order=40, noise_kernel="white").fit(u, y)
    assert len(seen) == 1 and seen[0] < disturbance.AUTO_NOISE_GATE
    assert auto.noise_kernel_ == "white"
    np.testing.assert_array_equal(auto.coef_, white.coef_)


def _dense_route_only(monkeypatch):
    """Every disturbance takes the dense M x M route (no AR(1) structure is seen), tuned by
    L-BFGS as the AR(1) route is (the dense route alone offers Fisher scoring, which stops
    elsewhere on the evidence's flat top, within its tolerance)."""
    monkeypatch.setattr(KernelNoise, "structure", lambda self: None)
    monkeypatch.setattr(KernelNoise, "offers_fisher", lambda self, observation: False)


def test_ar1_route_is_taken_and_gives_the_dense_route_fit(monkeypatch):
    """The same AR(1) noise model tuned through its tridiagonal precision and densely."""
    from gpmultirate.covariance import AR1Covariance, DenseCovariance

    u, y = _data(1)
    structured = FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel="ar1").fit(u, y)
    assert type(structured._evidence.data_covariance(structured._evidence.theta)) is \
        AR1Covariance
    assert repr(structured.noise_kernel_).count("WhiteKernel") == 0
    _dense_route_only(monkeypatch)
    dense = FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel="ar1").fit(u, y)
    assert type(dense._evidence.data_covariance(dense._evidence.theta)) is DenseCovariance
    np.testing.assert_allclose(structured.noise_kernel_.theta, dense.noise_kernel_.theta,
                               rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(structured.kernel_.theta, dense.kernel_.theta, rtol=1e-6,
                               atol=1e-6)
    assert structured.log_marginal_likelihood_value_ == pytest.approx(
        dense.log_marginal_likelihood_value_, rel=1e-6)
    np.testing.assert_allclose(structured.coef_, dense.coef_, rtol=1e-6,
                               atol=1e-6 * np.abs(dense.coef_).max())
    mean, std = structured.impulse_response(np.linspace(0, ORDER - 1, 7), return_std=True)
    ref_mean, ref_std = dense.impulse_response(np.linspace(0, ORDER - 1, 7), return_std=True)
    np.testing.assert_allclose(mean, ref_mean, rtol=1e-6, atol=1e-6 * np.abs(ref_mean).max())
    np.testing.assert_allclose(std, ref_std, rtol=1e-6)
    # the white-noise level of the fit is kept (an AR(1) noise has no white part)
    assert structured.noise_level_ > 0


def test_ar1_posterior_at_real_lags_against_the_dense_route(monkeypatch):
    """Evidence, gradient and posterior at fractional lags: AR(1) route vs dense, same model."""
    u, y = _data(2)
    kernel = C(0.8) * DC(0.85, 0.3)
    noise_kernel = C(0.02) * Matern(7.0, nu=0.5)
    model = FIRGaussianProcess(kernel, factor=FACTOR, order=ORDER, optimizer=None,
                               noise_kernel=noise_kernel).fit(u, y)
    theta = np.concatenate([model.kernel_.theta + 0.05, model.noise_kernel_.theta + 0.2])
    value, grad = model.log_marginal_likelihood(theta, eval_gradient=True)
    lags = np.array([0.0, 0.5, 2.25, 11.7, ORDER - 1.5])
    mean, std = model.impulse_response(lags, return_std=True)
    _dense_route_only(monkeypatch)
    dense = FIRGaussianProcess(kernel, factor=FACTOR, order=ORDER, optimizer=None,
                               noise_kernel=noise_kernel).fit(u, y)
    ref, ref_grad = dense.log_marginal_likelihood(theta, eval_gradient=True)
    assert value == pytest.approx(ref, rel=1e-8)
    np.testing.assert_allclose(grad, ref_grad, rtol=1e-8, atol=1e-8 * np.abs(ref_grad).max())
    ref_mean, ref_std = dense.impulse_response(lags, return_std=True)
    np.testing.assert_allclose(mean, ref_mean, rtol=1e-8, atol=1e-10 * np.abs(ref_mean).max())
    np.testing.assert_allclose(std, ref_std, rtol=1e-8)


def test_summary_of_an_ar1_noise_has_no_white_part():
    from gpmultirate.report import noise_summary

    u, y = _data(1)
    model = FIRGaussianProcess(factor=FACTOR, order=ORDER, noise_kernel="ar1").fit(u, y)
    noise = noise_summary(model)
    assert noise["white_level"] == 0.0
    assert noise["disturbance_level"] == pytest.approx(model.noise_kernel_.k1.constant_value,
                                                       rel=1e-12)
    assert noise["time_scale"]["k2__length_scale"] == model.noise_kernel_.k2.length_scale


def test_auto_on_a_long_drifting_record_tunes_the_ar1_disturbance(monkeypatch):
    """Beyond 1000 slow samples on one grid: "ar1", never an M x M factorization."""
    import gpmultirate.covariance as covariance

    rng = np.random.default_rng(12)
    n = 3 * 1100
    u = rng.standard_normal(n)
    drift = np.cumsum(0.05 * rng.standard_normal(n))
    y = (np.convolve(u, 0.6 ** np.arange(20))[:n] + drift + 0.05 * rng.standard_normal(n))[::3]
    original = covariance.robust_cholesky

    def small_only(A, *args, **kwargs):
        assert A.shape[0] < 1100, "a dense M x M factorization"
        return original(A, *args, **kwargs)

    monkeypatch.setattr(covariance, "robust_cholesky", small_only)
    auto = FIRGaussianProcess(factor=FACTOR, order=40).fit(u, y)
    white = FIRGaussianProcess(factor=FACTOR, order=40, noise_kernel="white").fit(u, y)
    ar1 = FIRGaussianProcess(factor=FACTOR, order=40, noise_kernel="ar1").fit(u, y)
    assert repr(auto.noise_kernel_) == repr(ar1.noise_kernel_)
    assert "WhiteKernel" not in repr(auto.noise_kernel_)
    assert auto.log_marginal_likelihood_value_ == pytest.approx(
        ar1.log_marginal_likelihood_value_, rel=1e-12)
    assert auto.log_marginal_likelihood_value_ > white.log_marginal_likelihood_value_ + 10


@pytest.mark.slow
def test_resonances_found_under_white_noise_are_judged_again_with_the_disturbance(monkeypatch):
    # the search (here made to return a spurious term) judged with white noise; the
    # disturbance the fit then chooses takes it out, and the fit is tuned again without it
    from gpmultirate import resonances
    from gpmultirate.kernels import PK, resonance_summands

    search = resonances.search_resonances

    def with_a_spurious_term(observation, y, kernel, noise, noise_bounds, **settings):
        found = search(observation, y, kernel, noise, noise_bounds, **settings)
        spurious = PK(alpha=0.98, omega=2.0, sigma1=1e-3, sigma2=1e-3)
        return resonances.ResonanceSearch(
            kernel=found.kernel + spurious, noise_level=found.noise_level,
            optimizer_result=found.optimizer_result,
            resonances=[resonances.Resonance(frequency_hz=2.0 / (2 * np.pi), damping=0.01,
                                             evidence_gain=30.0, input=0)],
            log_marginal_likelihood=found.log_marginal_likelihood, history=found.history)

    monkeypatch.setattr(resonances, "search_resonances", with_a_spurious_term)
    u, y = _data(0)
    model = FIRGaussianProcess(kernel="auto", factor=FACTOR, order=ORDER,
                               noise_kernel="matern12").fit(u, y)
    assert model.resonances_ == []
    assert resonance_summands(model.kernel_) == []
    # with white noise the (spurious) term stays: the search's word is final there
    model = FIRGaussianProcess(kernel="auto", factor=FACTOR, order=ORDER,
                               noise_kernel="white").fit(u, y)
    assert len(model.resonances_) == 1


@pytest.mark.slow
def test_a_true_resonance_is_kept_with_the_disturbance():
    rng = np.random.default_rng(1)
    u = rng.standard_normal(900)
    lags = np.arange(100)
    g = 0.9 ** lags + 0.97 ** lags * np.sin(2.4 * lags)
    y = np.convolve(u, g)[:900:3]
    y = y + np.cumsum(0.05 * rng.standard_normal(300)) + 0.02 * rng.standard_normal(300)
    model = FIRGaussianProcess(kernel="auto", factor=3, order=100,
                               noise_kernel="matern12").fit(u, y)
    assert [round(2 * np.pi * r.frequency_hz, 1) for r in model.resonances_] == [2.4]
