"""The frequencies' spread added after conditioning: kernels, posterior, fit, Laplace.

Every posterior is checked against the dense closed form of eq. (15) under
the kernel without the spread, plus the spread's covariance formed from the
kernel's own values (``k(X, X) - k0(X, X)``); the Laplace spreads against a
Hessian of the evidence's values by second differences.
"""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate import DownsampledConvolution, tuning
from gpmultirate.covariance import SpreadPosterior, dense_log_evidence, dense_posterior
from gpmultirate.fitting.spread import laplace_spreads, spread_of_fit
from gpmultirate.inference import LogEvidence, posterior
from gpmultirate.kernels import DC, PK, PerInputKernel
from gpmultirate.kernels.spread import (
    conditioning_kernel,
    posterior_spread_terms,
    spread_factor,
)
from gpmultirate.observations import TimedConvolution


def _kernel(hold=False, posterior_spread=True, omega_std=0.01, rate_std=0.004):
    return C(0.05) * DC(0.85, 0.6) + PK(
        0.9, 0.8, 0.3, 0.2, omega_std=omega_std, rate_std=rate_std, hold=hold,
        posterior_spread=posterior_spread) + PK(
        0.8, 2.1, 0.1, 0.15, omega_std=2 * omega_std, rate_std=rate_std, hold=hold,
        posterior_spread=posterior_spread)


def _data(n, factor, order, seed=0):
    rng = np.random.default_rng(seed)
    op = DownsampledConvolution(rng.standard_normal(n), factor=factor, order=order)
    t = np.arange(order)
    g = 0.3 * 0.95**t * np.sin(0.8 * t) + 0.1 * 0.9**t * np.cos(2.1 * t)
    y = op.matvec(g) + 0.02 * rng.standard_normal(op.n_outputs)
    return op, y


@pytest.mark.parametrize("hold", [False, True])
def test_spread_factor_is_the_kernels_difference_at_real_lags(hold):
    kernel = _kernel(hold)
    X = np.concatenate([np.arange(30.0), np.random.default_rng(1).uniform(0, 30, 25)])[:, None]
    V = spread_factor(kernel, X)
    assert V.shape == (X.shape[0], 4)
    np.testing.assert_allclose(V @ V.T, kernel(X) - conditioning_kernel(kernel)(X),
                               atol=1e-12 * np.max(kernel.diag(X)))
    assert np.max(np.abs(V)) > 1e-4  # a spread that is there


def test_spread_factor_of_several_inputs_is_zero_on_the_other_inputs_rows():
    kernel = PerInputKernel([C(0.1) * DC(0.8, 0.5), _kernel(True)])
    lags = np.arange(12.0)
    X = np.column_stack([np.repeat([0, 1], 12), np.tile(lags, 2)])
    V = spread_factor(kernel, X)
    np.testing.assert_allclose(V @ V.T, kernel(X) - conditioning_kernel(kernel)(X), atol=1e-13)
    assert not np.any(V[:12])
    assert [(k, path) for k, path, _ in posterior_spread_terms(kernel)] == [
        (1, "input1__k1__k2"), (1, "input1__k2")]


def test_conditioning_kernel_takes_out_the_posterior_spread_only():
    prior = PK(0.9, 0.5, omega_std=0.02)  # knowledge held before the data: kept
    kernel = C(0.1) * DC(0.8, 0.5) + prior + PK(0.9, 1.5, omega_std=0.02, rate_std=0.01,
                                                posterior_spread=True)
    conditioning = conditioning_kernel(kernel)
    assert conditioning.k1.k2.spread() == (0.02, 0.0)
    assert conditioning.k2.spread() == (0.0, 0.0)
    assert conditioning.k2.posterior_spread
    assert kernel.k2.spread() == (0.02, 0.01)  # the caller's kernel is not changed
    np.testing.assert_array_equal(conditioning.theta, kernel.theta)
    plain = C(0.1) * DC(0.8, 0.5) + prior
    assert conditioning_kernel(plain) is plain
    assert not posterior_spread_terms(plain)


def test_a_posterior_spread_inside_a_product_is_refused():
    kernel = C(0.1) * DC(0.8, 0.5) + C(2.0) * PK(0.9, 1.5, omega_std=0.02, posterior_spread=True)
    with pytest.raises(ValueError, match="posterior_spread=True must be a summand"):
        conditioning_kernel(kernel)
    with pytest.raises(ValueError, match="posterior_spread must be True or False"):
        PK(posterior_spread="yes").spread_after_conditioning()


@pytest.mark.parametrize("n, route", [(90, "DataSpacePosterior"), (900, "ParameterSpacePosterior")])
@pytest.mark.parametrize("hold", [False, True])
def test_spread_posterior_against_the_dense_closed_form(n, route, hold):
    order = 40
    op, y = _data(n, 3, order)
    kernel = _kernel(hold)
    k0 = conditioning_kernel(kernel)
    noise = 4e-4
    conditioned = posterior(op, k0, noise, y)
    assert type(conditioned).__name__ == route
    spread = SpreadPosterior(conditioned, kernel)
    lags = op.lags
    Phi = op.matrix
    mu, Sigma0 = dense_posterior(Phi, k0(lags), y, noise * np.eye(y.shape[0]))
    Sigma = Sigma0 + kernel(lags) - k0(lags)
    scale = np.max(np.diag(Sigma))
    np.testing.assert_allclose(spread.coef, mu, atol=1e-8 * np.max(np.abs(mu)))
    np.testing.assert_allclose(spread.covariance(), Sigma, atol=1e-8 * scale)
    np.testing.assert_allclose(spread.K, kernel(lags), atol=1e-10 * scale)
    A = np.random.default_rng(2).standard_normal((5, order))
    mean, cov = spread.linear_map(A, full_cov=True)
    np.testing.assert_allclose(mean, A @ mu, atol=1e-8 * np.max(np.abs(A @ mu)))
    np.testing.assert_allclose(cov, A @ Sigma @ A.T, atol=1e-7 * np.max(np.abs(cov)))
    np.testing.assert_allclose(spread.linear_map(A)[1], np.diag(A @ Sigma @ A.T),
                               rtol=1e-7, atol=1e-9 * scale)
    A2 = A[::-1] + 0.5
    var1, var2, cross = spread.pair_variances(A, A2)
    np.testing.assert_allclose(var1, np.diag(A @ Sigma @ A.T), rtol=1e-7, atol=1e-9 * scale)
    np.testing.assert_allclose(var2, np.diag(A2 @ Sigma @ A2.T), rtol=1e-7, atol=1e-9 * scale)
    np.testing.assert_allclose(cross, np.diag(A @ Sigma @ A2.T), rtol=1e-6, atol=1e-9 * scale)
    # real lags: the GP given the data under k0 (dense, data space), plus the spread there
    X = np.array([[0.25], [3.5], [17.75], [38.5]])
    Ky = Phi @ k0(lags) @ Phi.T + noise * np.eye(y.shape[0])
    cross_X = k0(X, lags) @ Phi.T
    mean_X = cross_X @ np.linalg.solve(Ky, y)
    cov_X = k0(X) - cross_X @ np.linalg.solve(Ky, cross_X.T) + kernel(X) - k0(X)
    got_mean, got_cov = spread.at_lags(X, full_cov=True)
    np.testing.assert_allclose(got_mean, mean_X, atol=1e-7 * np.max(np.abs(mean_X)))
    np.testing.assert_allclose(got_cov, cov_X, atol=1e-7 * np.max(np.diag(cov_X)))
    np.testing.assert_allclose(spread.at_lags(X)[1], np.diag(cov_X), rtol=1e-6)
    np.testing.assert_allclose(spread.mean_at_lags(X), mean_X, atol=1e-7 * np.max(np.abs(mean_X)))
    # the evidence and the innovations are those of the conditioning
    expected = dense_log_evidence(Phi, k0(lags), y, noise * np.eye(y.shape[0]))
    assert spread.log_marginal_likelihood == pytest.approx(expected, rel=1e-9)


def test_readings_spread_on_the_ticks_is_the_regressors_image_of_the_factor():
    rng = np.random.default_rng(4)
    u = rng.standard_normal(200)
    order = 30
    times = np.arange(40.0, 190.0, 7.0)
    readings = TimedConvolution(u, times, order)
    ticks = DownsampledConvolution(u, factor=1, order=order)
    rows = ticks.matrix[times.astype(int)]
    kernel = _kernel(True)
    op, y = _data(120, 3, order)
    spread = SpreadPosterior(posterior(op, conditioning_kernel(kernel), 1e-3, y), kernel)
    V = spread_factor(kernel, op.lags)
    np.testing.assert_allclose(spread.readings_spread(readings),
                               np.einsum("ij,ij->i", rows @ V, rows @ V), rtol=1e-8,
                               atol=1e-14)
    assert posterior(op, kernel, 1e-3, y).readings_spread(readings) == 0.0


def test_a_fit_conditions_without_the_spread_and_adds_it_to_the_bands():
    order = 40
    rng = np.random.default_rng(5)
    u = rng.standard_normal(300)
    op = DownsampledConvolution(u, factor=3, order=order)
    t = np.arange(order)
    y = op.matvec(0.3 * 0.95**t * np.sin(0.8 * t)) + 0.02 * rng.standard_normal(op.n_outputs)
    kernel = _kernel(True)
    noise = 4e-4
    model = gm.FIRGaussianProcess(factor=3, order=order, kernel=kernel, noise_level=noise,
                                  optimizer=None, normalize=False).fit(u, y)
    assert model.kernel_ == kernel
    assert "posterior_spread=True" in repr(model.kernel_)
    k0 = conditioning_kernel(kernel)
    lags, Phi, N = op.lags, op.matrix, noise * np.eye(op.n_outputs)
    mu, Sigma0 = dense_posterior(Phi, k0(lags), y, N)
    expected = dense_log_evidence(Phi, k0(lags), y, N)
    assert model.log_marginal_likelihood_value_ == pytest.approx(expected, rel=1e-9)
    mean, std = model.impulse_response(return_std=True)
    np.testing.assert_allclose(mean, mu, atol=1e-8 * np.max(np.abs(mu)))
    np.testing.assert_allclose(std**2, np.diag(Sigma0 + kernel(lags) - k0(lags)), rtol=1e-6)
    # the same spread in the prior is conditioned on: other evidence, narrower bands
    prior = gm.FIRGaussianProcess(factor=3, order=order, kernel=_kernel(True, False),
                                  noise_level=noise, optimizer=None, normalize=False).fit(u, y)
    assert abs(prior.log_marginal_likelihood_value_ - expected) > 1e-3
    assert np.sum(prior.impulse_response(return_std=True)[1][20:]) < np.sum(std[20:])
    # readings between the ticks carry it too
    times = np.arange(5.5, 290.0, 4.0)
    _, with_spread = model.predict(u, sample_times=times, return_std=True)
    plain = gm.FIRGaussianProcess(factor=3, order=order, kernel=k0, noise_level=noise,
                                  optimizer=None, normalize=False).fit(u, y)
    _, without = plain.predict(u, sample_times=times, return_std=True)
    assert np.all(with_spread >= without - 1e-12) and np.any(with_spread > 1.01 * without)


def test_laplace_spreads_against_second_differences_of_the_evidence():
    op, y = _data(240, 3, 40, seed=7)
    kernel = C(0.01, "fixed") * DC(0.85, 0.6, alpha_bounds="fixed", beta_bounds="fixed") + PK(
        0.9, 0.8, 0.3, 0.2, posterior_spread=True) + PK(0.8, 2.1, 0.1, 0.15, posterior_spread=True)
    start = LogEvidence(op, y, kernel, 4e-4, "fixed")
    evidence = start.moved_to(start.split(tuning.maximize(start, 0, 0).x)[0], 4e-4)
    spread = laplace_spreads(evidence)
    x = evidence.theta
    n = x.size
    h = 1e-3
    H = np.empty((n, n))
    for i in range(n):
        for j in range(i, n):
            e_i, e_j = np.eye(n)[i] * h, np.eye(n)[j] * h
            H[i, j] = H[j, i] = (evidence(x + e_i + e_j) - evidence(x + e_i - e_j)
                                 - evidence(x - e_i + e_j) + evidence(x - e_i - e_j)) / (4 * h * h)
    cov = np.linalg.inv(-H)
    names = [hp.name for hp in evidence.kernel.hyperparameters if not hp.fixed]
    for path, term in (("k1__k2", spread.k1.k2), ("k2", spread.k2)):
        omega = names.index(f"{path}__omega")
        alpha = names.index(f"{path}__alpha")
        assert term.omega_std == pytest.approx(term.omega * np.sqrt(cov[omega, omega]), rel=0.01)
        assert term.rate_std == pytest.approx(0.5 * np.sqrt(cov[alpha, alpha]), rel=0.01)
    assert spread.k1.k1 == evidence.kernel.k1.k1  # the base is untouched


def test_spread_of_fit_keeps_a_given_spread_unless_the_terms_were_tuned_again():
    op, y = _data(240, 3, 40, seed=8)
    template = _kernel(False)
    kernel = conditioning_kernel(template)
    evidence = LogEvidence(op, y, kernel, 4e-4, (1e-6, 1.0))
    assert spread_of_fit(None, kernel, evidence, False) is kernel
    kept = spread_of_fit(template, kernel, evidence, False)
    np.testing.assert_allclose(kept.theta, template.theta, rtol=1e-12)
    assert [t.spread() for _, _, t in posterior_spread_terms(kept)] == [
        t.spread() for _, _, t in posterior_spread_terms(template)]
    again = spread_of_fit(template, kernel, evidence, True)
    assert again.k2.omega_std != template.k2.omega_std and again.k2.omega_std > 0


def test_auto_fits_carry_the_spread_and_a_model_file_keeps_it(tmp_path):
    rng = np.random.default_rng(3)
    N, F, P = 900, 3, 150
    t = np.arange(P)
    g = 0.97**t * np.sin(0.5 * t) * 0.3 + 0.9**t * np.sin(2.2 * t) * 0.2
    u = rng.standard_normal(N)
    y = np.convolve(u, g)[:N][::F] + 0.01 * rng.standard_normal(N // F)
    model = gm.FIRGaussianProcess(factor=F, order=P, kernel="auto").fit(u, y)
    terms = posterior_spread_terms(model.kernel_)
    assert len(terms) == 2 and all(term.omega_std > 0 for _, _, term in terms)
    mean, std = model.impulse_response(return_std=True)
    path = tmp_path / "auto.npz"
    gm.save_model(model, path)
    loaded = gm.load_model(path)
    again, again_std = loaded.impulse_response(return_std=True)
    np.testing.assert_allclose(again, mean, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(again_std, std, rtol=1e-9, atol=1e-12)
    assert loaded.kernel_ == model.kernel_
    # the bands without the spread are narrower: the spread is in them
    plain = model.posterior_.normalized.conditioned
    assert np.sum(model.posterior_.normalized.covariance().diagonal()) > np.sum(
        plain.covariance().diagonal())
