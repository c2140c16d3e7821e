"""FIRGaussianProcess against dense closed forms of the paper's equations."""

import pickle
import warnings

import numpy as np
import pytest
from scipy import stats
from sklearn.base import clone
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate.kernels import DC, PK, TC

FACTOR, ORDER, OFFSET, NOISE = 3, 40, 1, 1e-2


def dense_regressor(u, factor, order, offset):
    """Phi of eq. (8), written from its definition."""
    rows = range(offset, len(u), factor)
    return np.array([[u[n - i] if n - i >= 0 else 0.0 for i in range(order)] for n in rows])


@pytest.fixture(scope="module")
def problem():
    rng = np.random.default_rng(3)
    u = rng.standard_normal(120)
    lags = np.arange(ORDER)
    g = 0.85**lags * np.cos(0.7 * lags)
    y_slow = np.convolve(u, g)[:120][OFFSET::FACTOR] + 0.1 * rng.standard_normal(40)
    kernel = C(2.0) * DC(alpha=0.85, beta=0.6) + PK(alpha=0.8, omega=0.7, sigma1=0.8, sigma2=0.5)
    model = gm.FIRGaussianProcess(
        kernel, factor=FACTOR, order=ORDER, offset=OFFSET, noise_level=NOISE, optimizer=None
    ).fit(u, y_slow)
    Phi = dense_regressor(u, FACTOR, ORDER, OFFSET)
    return dict(u=u, y=y_slow, kernel=kernel, model=model, Phi=Phi, g=g)


def dense_posterior(kernel, Phi, y, noise, lags):
    """GP posterior of g(lags) given y = Phi g(0..P-1) + e, by plain solves."""
    P = Phi.shape[1]
    grid = np.arange(P, dtype=float)[:, None]
    K = kernel(grid)
    Ky = Phi @ K @ Phi.T + noise * np.eye(Phi.shape[0])
    cross = kernel(np.asarray(lags, float)[:, None], grid) @ Phi.T
    mean = cross @ np.linalg.solve(Ky, y)
    cov = kernel(np.asarray(lags, float)[:, None]) - cross @ np.linalg.solve(Ky, cross.T)
    return mean, cov


def coef_covariance(kernel, Phi, noise):
    K = kernel(np.arange(Phi.shape[1], dtype=float)[:, None])
    Ky = Phi @ K @ Phi.T + noise * np.eye(Phi.shape[0])
    return K - K @ Phi.T @ np.linalg.solve(Ky, Phi @ K)


def test_coef_is_eq15(problem):
    Phi, kernel, y = problem["Phi"], problem["kernel"], problem["y"]
    K = kernel(np.arange(ORDER, dtype=float)[:, None])
    expected = K @ Phi.T @ np.linalg.solve(Phi @ K @ Phi.T + NOISE * np.eye(len(y)), y)
    np.testing.assert_allclose(problem["model"].coef_, expected, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("lags", [np.arange(ORDER), [0.5, 3.25, 10.9, 39.5, 55.0]])
def test_impulse_response_is_gp_posterior(problem, lags):
    model = problem["model"]
    mean, cov = dense_posterior(problem["kernel"], problem["Phi"], problem["y"], NOISE, lags)
    m1, std = model.impulse_response(lags, return_std=True)
    m2, cov2 = model.impulse_response(lags, return_cov=True)
    np.testing.assert_allclose(m1, mean, rtol=1e-8, atol=1e-11)
    np.testing.assert_allclose(m2, mean, rtol=1e-8, atol=1e-11)
    np.testing.assert_allclose(std, np.sqrt(np.clip(np.diag(cov), 0, None)), rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(cov2, cov, rtol=1e-6, atol=1e-10)
    np.testing.assert_allclose(model.impulse_response(lags), mean, rtol=1e-8, atol=1e-11)


def test_default_lags_equal_coef(problem):
    model = problem["model"]
    np.testing.assert_allclose(model.impulse_response(), model.coef_, rtol=1e-10, atol=1e-13)


def test_log_marginal_likelihood_is_dense_gaussian_density(problem):
    Phi, kernel, y = problem["Phi"], problem["kernel"], problem["y"]
    K = kernel(np.arange(ORDER, dtype=float)[:, None])
    cov = Phi @ K @ Phi.T + NOISE * np.eye(len(y))
    expected = stats.multivariate_normal(np.zeros(len(y)), cov).logpdf(y)
    model = problem["model"]
    assert model.log_marginal_likelihood_value_ == pytest.approx(expected, rel=1e-10)
    theta = np.append(model.kernel_.theta, np.log(NOISE))
    assert model.log_marginal_likelihood(theta) == pytest.approx(expected, rel=1e-10)


def test_log_marginal_likelihood_gradient_matches_finite_differences(problem):
    model = problem["model"]
    theta = np.append(model.kernel_.theta, np.log(NOISE)) + 0.05
    value, grad = model.log_marginal_likelihood(theta, eval_gradient=True)
    assert value == pytest.approx(model.log_marginal_likelihood(theta))
    step = 1e-6
    numeric = [
        (
            model.log_marginal_likelihood(theta + step * e)
            - model.log_marginal_likelihood(theta - step * e)
        )
        / (2 * step)
        for e in np.eye(theta.size)
    ]
    np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("block_entries", [2**22, 7 * ORDER])  # one block; blocks of 7 rows
def test_predict_mean_and_std_are_dense_convolution(problem, block_entries, monkeypatch):
    from gpmultirate import prediction

    monkeypatch.setattr(prediction, "_PREDICT_BLOCK_ENTRIES", block_entries)
    model, Phi = problem["model"], problem["Phi"]
    rng = np.random.default_rng(7)
    u_new = rng.standard_normal(70)
    T = dense_regressor(u_new, 1, ORDER, 0)
    Sigma = coef_covariance(problem["kernel"], Phi, NOISE)
    mean, std = model.predict(u_new, return_std=True)
    np.testing.assert_allclose(mean, T @ model.coef_, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(std, np.sqrt(np.diag(T @ Sigma @ T.T)), rtol=1e-6, atol=1e-10)
    np.testing.assert_allclose(model.predict(u_new), mean, rtol=1e-12, atol=1e-14)


def test_predict_shorter_than_order(problem):
    u_short = np.ones(5)
    expected = np.cumsum(problem["model"].coef_[:5])
    np.testing.assert_allclose(problem["model"].predict(u_short), expected, rtol=1e-10)


def test_score_is_eq20(problem):
    model = problem["model"]
    u = problem["u"]
    y_fast = np.convolve(u, problem["g"])[:120]
    y_hat = np.convolve(u, model.coef_)[:120]
    expected = 100 * (1 - np.sum((y_fast - y_hat) ** 2) / np.sum((y_fast - y_fast.mean()) ** 2))
    assert model.score(u, y_fast) == pytest.approx(expected, rel=1e-10)


def test_frequency_response_mean_and_covariance(problem):
    model = problem["model"]
    freqs = np.array([0.0, 0.5, 1.1, 2.0, 3.3, 4.99])
    frf = model.frequency_response(freqs, sample_time=0.1, level=0.9)
    i = np.arange(ORDER)
    direct = np.array([np.sum(model.coef_ * np.exp(-2j * np.pi * f * 0.1 * i)) for f in freqs])
    np.testing.assert_allclose(frf.mean, direct, rtol=1e-10, atol=1e-12)
    Sigma = coef_covariance(problem["kernel"], problem["Phi"], NOISE)
    E = np.exp(-2j * np.pi * 0.1 * np.outer(freqs, i))
    var_re = np.einsum("ki,ij,kj->k", E.real, Sigma, E.real)
    var_im = np.einsum("ki,ij,kj->k", E.imag, Sigma, E.imag)
    np.testing.assert_allclose(frf.real_std, np.sqrt(np.clip(var_re, 0, None)), rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(frf.imag_std, np.sqrt(np.clip(var_im, 0, None)), rtol=1e-5, atol=1e-9)
    assert frf.slow_nyquist == pytest.approx(1 / (2 * 0.3))
    assert frf.fast_nyquist == pytest.approx(5.0)
    assert frf.level == 0.9
    assert np.all(frf.magnitude_lower <= frf.magnitude_upper)
    assert np.all(frf.phase_lower <= frf.phase_upper)


def test_frequency_bands_are_projections_of_the_credible_region(problem):
    """Monte Carlo over exact posterior draws of g: the 2-D region holds ``level`` of the
    draws of G, the bands hold |G| and the phase of every draw in the region, and the
    draws in the region reach the edges of the bands."""
    model = problem["model"]
    freqs = np.array([0.7, 2.4])
    level = 0.8
    frf = model.frequency_response(freqs, sample_time=0.1, level=level)
    Sigma = coef_covariance(problem["kernel"], problem["Phi"], NOISE)
    rng = np.random.default_rng(11)
    draws = rng.multivariate_normal(model.coef_, Sigma, size=40000, method="eigh")
    E = np.exp(-2j * np.pi * 0.1 * np.outer(freqs, np.arange(ORDER)))
    G = draws @ E.T
    d = G - frf.mean
    var_r, var_i = frf.real_std ** 2, frf.imag_std ** 2
    cov = frf.real_imag_corr * frf.real_std * frf.imag_std
    distance = (var_i * d.real ** 2 - 2 * cov * d.real * d.imag + var_r * d.imag ** 2) / (
        var_r * var_i - cov ** 2)
    inside = distance <= stats.chi2.ppf(level, df=2)
    assert np.all(np.abs(inside.mean(axis=0) - level) < 0.01)
    assert np.all(frf.phase_defined)
    for k in range(freqs.size):
        mag = np.abs(G[inside[:, k], k])
        angle = np.angle(G[inside[:, k], k] * np.exp(-1j * frf.phase[k]))
        for values, low, high in ((mag, frf.magnitude_lower[k], frf.magnitude_upper[k]),
                                  (angle, frf.phase_lower[k] - frf.phase[k],
                                   frf.phase_upper[k] - frf.phase[k])):
            width = high - low
            assert low <= values.min() < low + 0.05 * width
            assert high - 0.05 * width < values.max() <= high


def test_default_frequencies_are_dft_bins(problem):
    frf = problem["model"].frequency_response(sample_time=0.1)
    np.testing.assert_allclose(frf.freqs, np.arange(61) / (120 * 0.1))


def test_samples_have_posterior_mean_and_covariance(problem):
    model = problem["model"]
    lags = [0.0, 1.5, 2.5, 7.25]
    draws = model.sample_impulse_responses(lags, n_samples=20000, random_state=0)
    mean, cov = dense_posterior(problem["kernel"], problem["Phi"], problem["y"], NOISE, lags)
    assert draws.shape == (4, 20000)
    std = np.sqrt(np.diag(cov))
    np.testing.assert_allclose(draws.mean(axis=1), mean, atol=5 * std.max() / np.sqrt(20000))
    np.testing.assert_allclose(np.cov(draws), cov, atol=0.05 * cov.max())
    again = model.sample_impulse_responses(lags, n_samples=3, random_state=5)
    np.testing.assert_array_equal(
        again, model.sample_impulse_responses(lags, n_samples=3, random_state=5)
    )


def test_optimizer_none_keeps_hyperparameters(problem):
    model = problem["model"]
    assert model.kernel_ == problem["kernel"]
    assert model.kernel_ is not model.kernel
    assert model.noise_level_ == NOISE


def test_fit_improves_evidence_and_recovers_response(problem):
    u, y = problem["u"], problem["y"]
    start = gm.FIRGaussianProcess(
        problem["kernel"], factor=FACTOR, order=ORDER, offset=OFFSET, noise_level=NOISE,
        optimizer=None,
    ).fit(u, y)
    # from the given start in the data's units (normalized units give another
    # start, whose resonance grid ends on the frequency window's edge)
    tuned = clone(start).set_params(optimizer="marginal_likelihood", normalize=False).fit(u, y)
    assert tuned.log_marginal_likelihood_value_ > start.log_marginal_likelihood_value_
    # the reported optimum is a stationary point of the evidence
    theta = np.append(tuned.kernel_.theta, np.log(tuned.noise_level_))
    bounds = np.vstack([tuned.kernel_.bounds, np.log(tuned.noise_level_bounds_)])
    _, grad = tuned.log_marginal_likelihood(theta, eval_gradient=True)
    interior = (theta > bounds[:, 0] + 1e-3) & (theta < bounds[:, 1] - 1e-3)
    assert np.all(np.abs(grad[interior]) < 1e-2)
    fast = np.convolve(u, problem["g"])[:120]
    assert tuned.score(u, fast) > 90


def test_restarts_are_reproducible_and_keep_the_best(problem):
    u, y = problem["u"], problem["y"]
    kernel = C(1.0) * TC(alpha=0.5)
    make = lambda r: gm.FIRGaussianProcess(  # noqa: E731
        kernel, factor=FACTOR, order=ORDER, offset=OFFSET, n_restarts_optimizer=r, random_state=4
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        a, b, single = make(3).fit(u, y), make(3).fit(u, y), make(0).fit(u, y)
    np.testing.assert_array_equal(a.coef_, b.coef_)
    assert a.log_marginal_likelihood_value_ >= single.log_marginal_likelihood_value_ - 1e-9


def test_non_convergence_warns(problem, monkeypatch):
    from gpmultirate import tuning

    monkeypatch.setitem(tuning.LBFGS_OPTIONS, "maxiter", 1)
    monkeypatch.setitem(tuning.FISHER_OPTIONS, "maxiter", 1)
    for fisher_max_outputs in (10**6, 0):  # Fisher scoring, then L-BFGS-B
        monkeypatch.setattr(tuning, "FISHER_MAX_OUTPUTS", fisher_max_outputs)
        with pytest.warns(ConvergenceWarning, match="did not converge"):
            gm.FIRGaussianProcess(
                C(1.0) * DC(), factor=FACTOR, order=ORDER, offset=OFFSET
            ).fit(problem["u"], problem["y"])


def test_tiny_noise_gives_finite_nonnegative_posterior(problem):
    model = gm.FIRGaussianProcess(
        problem["kernel"], factor=FACTOR, order=ORDER, offset=OFFSET, noise_level=1e-14,
        optimizer=None,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", gm.NumericalWarning)
        model.fit(problem["u"], problem["y"])
    mean, std = model.impulse_response(np.linspace(0, 45, 91), return_std=True)
    assert np.all(np.isfinite(mean)) and np.all(np.isfinite(std)) and np.all(std >= 0)
    y_mean, y_std = model.predict(problem["u"], return_std=True)
    assert np.all(np.isfinite(y_std)) and np.all(y_std >= 0)
    frf = model.frequency_response(sample_time=1.0)
    assert np.all(np.isfinite(frf.magnitude_upper))


def test_factor_one_order_below_m_small_noise_is_least_squares():
    rng = np.random.default_rng(5)
    u = rng.standard_normal(80)
    y = np.convolve(u, 0.7 ** np.arange(10))[:80] + 0.01 * rng.standard_normal(80)
    gp = gm.FIRGaussianProcess(
        C(1.0) * DC(0.9, 0.5), factor=1, order=10, noise_level=1e-12, optimizer=None
    ).fit(u, y)
    Phi = dense_regressor(u, 1, 10, 0)
    np.testing.assert_allclose(gp.coef_, np.linalg.lstsq(Phi, y, rcond=None)[0], rtol=1e-6)


def test_default_kernel_and_order(problem):
    model = gm.FIRGaussianProcess(factor=FACTOR, offset=OFFSET).fit(problem["u"], problem["y"])
    assert model.coef_.shape == (120,)
    assert isinstance(model.kernel_.k2, DC)


def test_inputs_are_not_modified(problem):
    u, y = problem["u"].copy(), problem["y"].copy()
    u0, y0 = u.copy(), y.copy()
    model = gm.FIRGaussianProcess(
        problem["kernel"], factor=FACTOR, order=ORDER, offset=OFFSET
    ).fit(u, y)
    lags = np.array([0.5, 1.0])
    model.impulse_response(lags, return_std=True)
    model.predict(u, return_std=True)
    np.testing.assert_array_equal(u, u0)
    np.testing.assert_array_equal(y, y0)
    np.testing.assert_array_equal(lags, [0.5, 1.0])
    assert problem["kernel"] == clone(problem["kernel"])  # user's kernel untouched
    assert problem["kernel"].get_params()["k1__k1__constant_value"] == 2.0


def test_pickle_round_trip(problem):
    model = problem["model"]
    again = pickle.loads(pickle.dumps(model))
    lags = np.array([0.3, 4.7])
    np.testing.assert_array_equal(again.impulse_response(lags), model.impulse_response(lags))
    np.testing.assert_array_equal(again.predict(problem["u"]), model.predict(problem["u"]))


def test_sklearn_conventions(problem):
    model = gm.FIRGaussianProcess(factor=2, order=5)
    assert model.get_params()["factor"] == 2
    assert clone(model).get_params() == model.get_params()
    with pytest.raises(ValueError, match="not fitted|fit"):
        model.predict(np.ones(3))


BAD_FIT = [
    (dict(factor=0), "factor"),
    (dict(factor=2.5), "factor"),
    (dict(factor=True), "factor"),
    (dict(order=0), "order"),
    (dict(order=121), "order"),
    (dict(offset=3), "offset"),
    (dict(offset=-1), "offset"),
    (dict(noise_level=-1.0), "noise_level"),
    (dict(noise_level=np.nan), "noise_level"),
    (dict(noise_level_bounds=(1.0, 0.1)), "noise_level_bounds"),
    (dict(optimizer="adam"), "optimizer"),
    (dict(n_restarts_optimizer=-1), "n_restarts_optimizer"),
    (dict(kernel="DC"), "kernel"),
]


@pytest.mark.parametrize("params, name", BAD_FIT)
def test_invalid_parameters_name_the_argument(problem, params, name):
    base = dict(factor=FACTOR, order=ORDER, offset=OFFSET)
    base.update(params)
    with pytest.raises(ValueError, match=name):
        gm.FIRGaussianProcess(**base).fit(problem["u"], problem["y"])


def test_invalid_data_name_the_argument(problem):
    model = gm.FIRGaussianProcess(factor=FACTOR, order=ORDER, offset=OFFSET, optimizer=None)
    u, y = problem["u"], problem["y"]
    bad_u = u.copy()
    bad_u[3] = np.nan
    with pytest.raises(ValueError, match="u"):
        model.fit(bad_u, y)
    with pytest.raises(ValueError, match="y_slow"):
        model.fit(u, y[:-1])
    with pytest.raises(ValueError, match="y_slow"):
        model.fit(u, np.append(y[:-1], np.inf))
    with pytest.raises(ValueError, match="u"):
        model.fit(np.ones((3, 4)), y)
    model.fit(u, y)
    with pytest.raises(ValueError, match="lags"):
        model.impulse_response([-1.0])
    with pytest.raises(ValueError, match="lags"):
        model.impulse_response([np.nan])
    with pytest.raises(ValueError, match="level"):
        model.frequency_response(level=1.5)
    with pytest.raises(ValueError, match="sample_time"):
        model.frequency_response(sample_time=0.0)
    with pytest.raises(ValueError, match="freqs"):
        model.frequency_response(freqs=[-1.0])
    with pytest.raises(ValueError, match="n_samples"):
        model.sample_impulse_responses(n_samples=0)
    with pytest.raises(ValueError, match="y_fast"):
        model.score(u, u[:-2])
    with pytest.raises(ValueError, match="theta"):
        model.log_marginal_likelihood(np.zeros(2))


@pytest.mark.parametrize("order", [15, 60])
def test_parameter_and_data_space_agree_with_dense_formulas(order):
    """M = 40 slow samples: order 15 uses the parameter space, order 60 the data space."""
    rng = np.random.default_rng(8)
    u = rng.standard_normal(120)
    y = np.convolve(u, 0.8 ** np.arange(order))[:120][::3] + 0.05 * rng.standard_normal(40)
    kernel = C(1.5) * DC(alpha=0.8, beta=0.7)
    model = gm.FIRGaussianProcess(kernel, factor=3, order=order, noise_level=0.01, optimizer=None)
    model.fit(u, y)
    Phi = dense_regressor(u, 3, order, 0)
    lags = np.array([0.0, 2.5, 7.0, order + 3.5])
    mean, cov = dense_posterior(kernel, Phi, y, 0.01, lags)
    m, c = model.impulse_response(lags, return_cov=True)
    np.testing.assert_allclose(m, mean, rtol=1e-8, atol=1e-11)
    np.testing.assert_allclose(model.impulse_response(lags), mean, rtol=1e-8, atol=1e-11)
    np.testing.assert_allclose(c, cov, rtol=1e-6, atol=1e-10)
    K = kernel(np.arange(order, dtype=float)[:, None])
    Ky = Phi @ K @ Phi.T + 0.01 * np.eye(40)
    expected = stats.multivariate_normal(np.zeros(40), Ky).logpdf(y)
    assert model.log_marginal_likelihood_value_ == pytest.approx(expected, rel=1e-10)
    Sigma = coef_covariance(kernel, Phi, 0.01)
    T = dense_regressor(u[:30], 1, order, 0)
    _, std = model.predict(u[:30], return_std=True)
    np.testing.assert_allclose(std, np.sqrt(np.diag(T @ Sigma @ T.T)), rtol=1e-6, atol=1e-10)
