"""ObservedKernel against the dense data covariance Phi K Phi^T and a dense Gaussian density.

``Phi`` is built by an explicit loop (paper eq. 8), ``K`` by the paper's DC
formula, the evidence by ``scipy.stats.multivariate_normal`` and the posterior
mean by a dense linear solve; gradients are checked by finite differences.
"""

import pickle

import numpy as np
import pytest
from scipy.stats import multivariate_normal
from sklearn.base import clone
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import ConstantKernel as C
from sklearn.gaussian_process.kernels import WhiteKernel

from gpmultirate import DownsampledConvolution, ObservedKernel
from gpmultirate.kernels import DC, PK, TC

N, FACTOR, ORDER, OFFSET = 90, 3, 30, 1


def explicit_regressor(u, factor, order, offset):
    rows = list(range(offset, len(u), factor))
    return np.array(
        [[u[n - i] if n - i >= 0 else 0.0 for i in range(order)] for n in rows]
    )


def dc_direct(t, s, alpha, beta, scale=1.0):
    return np.array([[scale * alpha ** ((a + b) / 2) * beta ** abs(a - b) for b in s] for a in t])


@pytest.fixture(scope="module")
def setup():
    rng = np.random.default_rng(11)
    u = rng.standard_normal(N)
    op = DownsampledConvolution(u, factor=FACTOR, order=ORDER, offset=OFFSET)
    Phi = explicit_regressor(u, FACTOR, ORDER, OFFSET)
    lags = np.arange(ORDER)
    g_true = 0.85 ** lags * np.cos(0.6 * lags)
    y = Phi @ g_true + 0.05 * rng.standard_normal(Phi.shape[0])
    return op, Phi, y


def dense_S(Phi, scale, alpha, beta):
    lags = np.arange(Phi.shape[1])
    return Phi @ dc_direct(lags, lags, alpha, beta, scale) @ Phi.T


def indices(values):
    return np.asarray(values)[:, None]


def test_value_equals_dense_covariance_at_index_subsets(setup):
    op, Phi, _ = setup
    ok = ObservedKernel(C(1.5) * DC(alpha=0.8, beta=0.6), op)
    S = dense_S(Phi, 1.5, 0.8, 0.6)
    tol = dict(rtol=1e-10, atol=1e-12 * np.abs(S).max())
    M = op.n_outputs
    np.testing.assert_allclose(ok(indices(np.arange(M))), S, **tol)
    rows = [3, 0, 7, 7, M - 1]
    cols = [1, 29, 4]
    np.testing.assert_allclose(ok(indices(rows)), S[np.ix_(rows, rows)], **tol)
    np.testing.assert_allclose(ok(indices(rows), indices(cols)), S[np.ix_(rows, cols)], **tol)
    np.testing.assert_allclose(ok(indices(rows)), ok(indices(rows), indices(rows)), rtol=1e-14)
    np.testing.assert_allclose(ok.diag(indices(rows)), np.diag(S)[rows], **tol)
    # 1-D index vectors are also accepted
    np.testing.assert_allclose(ok(np.array(rows)), S[np.ix_(rows, rows)], **tol)


@pytest.mark.parametrize(
    "kernel",
    [
        pytest.param(DC(alpha=0.85, beta=0.7), id="DC"),
        pytest.param(C(1.5) * DC(alpha=0.8, beta=0.6) + PK(alpha=0.9, omega=0.9), id="C*DC+PK"),
        pytest.param(TC(alpha=0.9) + DC(alpha=0.7, beta=0.5, beta_bounds="fixed"), id="TC+DCfixed"),
    ],
)
def test_gradient_matches_finite_differences(setup, kernel):
    op, _, _ = setup
    ok = ObservedKernel(kernel, op)
    X = indices([0, 5, 2, 11, 20, 28])
    K, dK = ok(X, eval_gradient=True)
    theta = ok.theta
    assert dK.shape == (6, 6, theta.shape[0])
    np.testing.assert_allclose(K, ok(X), rtol=1e-12, atol=1e-14)
    step = 1e-5
    for j in range(theta.shape[0]):
        e = np.zeros_like(theta)
        e[j] = step
        numeric = (ok.clone_with_theta(theta + e)(X) - ok.clone_with_theta(theta - e)(X)) / (
            2 * step
        )
        np.testing.assert_allclose(dK[..., j], numeric, rtol=1e-5, atol=1e-7 * np.abs(numeric).max())
    with pytest.raises(ValueError, match="gradient"):
        ok(X, X, eval_gradient=True)


def test_gradient_equals_dense_closed_form(setup):
    # d/dlog(alpha) of Phi K Phi^T is Phi (K * (t_i + t_j)/2) Phi^T; theta of beta is
    # artanh(beta), d/dtheta = (1 - beta^2) d/dbeta, d/dbeta K = K |t_i - t_j| / beta
    op, Phi, _ = setup
    ok = ObservedKernel(DC(alpha=0.8, beta=0.6), op)
    M = op.n_outputs
    _, dS = ok(indices(np.arange(M)), eval_gradient=True)
    lags = np.arange(ORDER)
    K = dc_direct(lags, lags, 0.8, 0.6)
    d_alpha = Phi @ (K * np.add.outer(lags, lags) / 2) @ Phi.T
    d_beta = Phi @ (K * np.abs(np.subtract.outer(lags, lags)) * (1 - 0.6**2) / 0.6) @ Phi.T
    np.testing.assert_allclose(dS[..., 0], d_alpha, rtol=1e-9, atol=1e-11 * np.abs(d_alpha).max())
    np.testing.assert_allclose(dS[..., 1], d_beta, rtol=1e-9, atol=1e-11 * np.abs(d_beta).max())


def test_hyperparameters_delegate_with_prefix(setup):
    op, _, _ = setup
    inner = C(2.0) * DC(alpha=0.8, beta=0.6, beta_bounds="fixed") + PK(omega_bounds=(0.1, 2.0))
    ok = ObservedKernel(inner, op)
    assert [h.name for h in ok.hyperparameters] == [
        "kernel__" + h.name for h in inner.hyperparameters
    ]
    assert [h.fixed for h in ok.hyperparameters] == [h.fixed for h in inner.hyperparameters]
    assert ok.hyperparameters[2].name == "kernel__k1__k2__beta"
    assert ok.hyperparameters[2].fixed
    np.testing.assert_array_equal(ok.theta, inner.theta)
    np.testing.assert_array_equal(ok.bounds, inner.bounds)
    np.testing.assert_allclose(ok.bounds[3], np.log([0.1, 2.0]))  # PK omega, after fixed beta
    assert ok.theta.shape == (6,)
    _, dK = ok(indices([0, 1, 2]), eval_gradient=True)
    assert dK.shape == (3, 3, 6)
    # the gradient equals the free kernel's gradient without the fixed column
    free = ObservedKernel(C(2.0) * DC(alpha=0.8, beta=0.6) + PK(omega_bounds=(0.1, 2.0)), op)
    _, dK_free = free(indices([0, 1, 2]), eval_gradient=True)
    np.testing.assert_allclose(dK, dK_free[..., [0, 1, 3, 4, 5, 6]], rtol=1e-12, atol=1e-15)


def test_theta_setter_and_params(setup):
    op, _, _ = setup
    ok = ObservedKernel(DC(alpha=0.8, beta=0.6), op)
    ok.theta = [np.log(0.5), np.arctanh(0.3)]
    assert ok.kernel.alpha == pytest.approx(0.5)
    assert ok.kernel.beta == pytest.approx(0.3)
    params = ok.get_params()
    assert params["kernel__alpha"] == pytest.approx(0.5)
    assert params["observation"] is op
    assert set(ok.get_params(deep=False)) == {"kernel", "observation"}
    ok.set_params(kernel__alpha=0.7)
    assert ok.kernel.alpha == 0.7
    np.testing.assert_allclose(ok.theta, [np.log(0.7), np.arctanh(0.3)])


def test_clone_and_clone_with_theta(setup):
    op, Phi, _ = setup
    ok = ObservedKernel(C(1.5) * DC(alpha=0.8, beta=0.6), op)
    cloned = clone(ok)
    assert cloned == ok
    assert cloned is not ok
    assert cloned.kernel is not ok.kernel
    assert cloned.observation == op
    theta = ok.theta.copy()
    new_theta = [np.log(2.0), np.log(0.5), np.arctanh(0.4)]
    other = ok.clone_with_theta(new_theta)
    np.testing.assert_array_equal(ok.theta, theta)  # the original is untouched
    np.testing.assert_allclose(other.theta, new_theta)
    M = op.n_outputs
    S = dense_S(Phi, 2.0, 0.5, 0.4)
    np.testing.assert_allclose(
        other(indices(np.arange(M))), S, rtol=1e-10, atol=1e-12 * np.abs(S).max()
    )
    assert other != ok
    assert ok != ObservedKernel(C(1.5) * DC(alpha=0.8, beta=0.6), DownsampledConvolution(op.u, 3, 29, 1))
    assert "ObservedKernel" in repr(ok) and "DC(alpha=0.8, beta=0.6)" in repr(ok)
    assert not ok.is_stationary()


def test_pickle_round_trip(setup):
    op, _, _ = setup
    ok = ObservedKernel(C(1.5) * DC(alpha=0.8, beta=0.6), op) + WhiteKernel(0.01)
    loaded = pickle.loads(pickle.dumps(ok))
    assert loaded == ok
    X = indices([0, 4, 9])
    np.testing.assert_array_equal(loaded(X), ok(X))


@pytest.fixture(scope="module")
def noise():
    return 0.05**2


def test_gpr_log_marginal_likelihood_equals_dense_density(setup, noise):
    op, Phi, y = setup
    M = op.n_outputs
    X = indices(np.arange(M))
    kernel = ObservedKernel(C(1.5) * DC(alpha=0.8, beta=0.6), op) + WhiteKernel(noise, "fixed")
    gpr = GaussianProcessRegressor(kernel=kernel, optimizer=None, alpha=0.0).fit(X, y)
    S = dense_S(Phi, 1.5, 0.8, 0.6)
    expected = multivariate_normal(np.zeros(M), S + noise * np.eye(M)).logpdf(y)
    assert gpr.log_marginal_likelihood_value_ == pytest.approx(expected, rel=1e-9)
    # and its gradient, against finite differences of the dense density
    theta = gpr.kernel_.theta
    value, grad = gpr.log_marginal_likelihood(theta, eval_gradient=True)
    assert value == pytest.approx(expected, rel=1e-9)

    def dense(theta_):
        c, a, b = np.exp(theta_[0]), np.exp(theta_[1]), np.tanh(theta_[2])
        return multivariate_normal(np.zeros(M), dense_S(Phi, c, a, b) + noise * np.eye(M)).logpdf(y)

    step = 1e-5
    for j in range(theta.shape[0]):
        e = np.zeros_like(theta)
        e[j] = step
        numeric = (dense(theta + e) - dense(theta - e)) / (2 * step)
        assert grad[j] == pytest.approx(numeric, rel=1e-5, abs=1e-6)


def test_gpr_predictions_equal_dense_posterior(setup, noise):
    op, Phi, y = setup
    M = op.n_outputs
    X = indices(np.arange(M))
    kernel = ObservedKernel(C(1.5) * DC(alpha=0.8, beta=0.6), op) + WhiteKernel(noise, "fixed")
    gpr = GaussianProcessRegressor(kernel=kernel, optimizer=None, alpha=1e-12).fit(X, y)
    S = dense_S(Phi, 1.5, 0.8, 0.6)
    Ky = S + (noise + 1e-12) * np.eye(M)
    mean = S @ np.linalg.solve(Ky, y)
    # WhiteKernel adds the noise on the diagonal of k(X) but not to k(X, X_train)
    var = np.diag(S) + noise - np.einsum("ij,ji->i", S, np.linalg.solve(Ky, S))
    pred, std = gpr.predict(X, return_std=True)
    np.testing.assert_allclose(pred, mean, rtol=1e-7, atol=1e-9 * np.abs(y).max())
    np.testing.assert_allclose(std, np.sqrt(var), rtol=1e-6)
    subset = indices([2, 9, 17])
    np.testing.assert_allclose(gpr.predict(subset), mean[[2, 9, 17]], rtol=1e-7, atol=1e-10)


def test_gpr_optimizer_improves_log_marginal_likelihood(setup, noise):
    op, Phi, y = setup
    M = op.n_outputs
    X = indices(np.arange(M))
    start = ObservedKernel(C(0.05) * DC(alpha=0.5, beta=0.2), op) + WhiteKernel(noise, "fixed")
    gpr = GaussianProcessRegressor(kernel=start, alpha=1e-10, random_state=0).fit(X, y)
    initial = gpr.log_marginal_likelihood(start.theta)
    assert gpr.log_marginal_likelihood_value_ > initial + 10.0
    fitted = gpr.kernel_.k1.kernel
    c, a, b = fitted.k1.constant_value, fitted.k2.alpha, fitted.k2.beta
    assert 0 < a <= 1 and 0 < b <= 1
    expected = multivariate_normal(np.zeros(M), dense_S(Phi, c, a, b) + (noise + 1e-10) * np.eye(M)).logpdf(y)
    assert gpr.log_marginal_likelihood_value_ == pytest.approx(expected, rel=1e-8)
    # the user's kernel is not modified by fitting
    assert start.k1.kernel.k2.alpha == 0.5


@pytest.mark.parametrize(
    "bad",
    [
        pytest.param(np.array([[1.5]]), id="non-integer"),
        pytest.param(np.array([[-1]]), id="negative"),
        pytest.param(np.array([[30]]), id="M"),
        pytest.param(np.array([[100]]), id="too-large"),
        pytest.param(np.empty((0, 1)), id="empty"),
        pytest.param(np.array([[np.nan]]), id="nan"),
        pytest.param(np.array([[np.inf]]), id="inf"),
        pytest.param(np.zeros((3, 2), dtype=int), id="two-columns"),
        pytest.param(np.zeros((2, 1, 1), dtype=int), id="3d"),
    ],
)
def test_invalid_indices_raise(setup, bad):
    op, _, _ = setup
    assert op.n_outputs == 30
    ok = ObservedKernel(DC(alpha=0.8, beta=0.6), op)
    with pytest.raises(ValueError, match="X must hold slow-sample indices"):
        ok(bad)
    with pytest.raises(ValueError, match="X must hold slow-sample indices"):
        ok(bad, eval_gradient=True)
    with pytest.raises(ValueError, match="Y must hold slow-sample indices"):
        ok(indices([0, 1]), bad)
