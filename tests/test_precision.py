"""The DC kernel's tridiagonal precision and the evidence through it, against dense formulas.

The precision is checked against the inverse of the dense kernel matrix
(negative ``beta`` included, from the closed form of the kernel), its
derivatives and log determinant against finite differences; the evidence of
reduced and square observations through it against
``scipy.stats.multivariate_normal`` on the full data covariance, its
gradient against finite differences of that dense evidence.
"""

import numpy as np
import pytest
from scipy.stats import multivariate_normal
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate.inference import log_marginal_likelihood
from gpmultirate.kernels import DC, PK, TC, observe
from gpmultirate.kernels.precision import dc_precision
from gpmultirate.observations import reduce_observation


def dc_dense(alpha, beta, order):
    """``alpha^((t + s) / 2) beta^|t - s|`` written out (any sign of beta)."""
    t = np.arange(order, dtype=float)
    distance = np.abs(np.subtract.outer(t, t)).astype(int)
    return alpha ** (np.add.outer(t, t) / 2.0) * beta ** distance


PARAMETERS = [(0.9, 0.5), (0.97, -0.6), (0.8, 0.0), (1.0, 0.95), (0.95, -0.99)]


@pytest.mark.parametrize("alpha, beta", PARAMETERS)
@pytest.mark.parametrize("order", [1, 2, 5, 40])
def test_precision_is_the_inverse(alpha, beta, order):
    found = dc_precision(alpha, beta, 1.0, order)
    K = dc_dense(alpha, beta, order)
    np.testing.assert_allclose(found.dense() @ K, np.eye(order), atol=1e-8)
    sign, log_det = np.linalg.slogdet(K)
    assert sign == 1.0
    assert found.log_det_covariance == pytest.approx(log_det, rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("alpha, beta", PARAMETERS[:4])
@pytest.mark.parametrize("parametrization", ["log", "artanh"])
def test_derivatives_are_finite_differences(alpha, beta, parametrization):
    # theta_alpha = log(alpha); theta_beta = log(beta) or artanh(beta), each
    # through its chain factor d beta / d theta
    order, h = 12, 1e-6
    if parametrization == "log" and beta <= 0:
        pytest.skip("log(beta) needs beta > 0")
    to_beta = np.exp if parametrization == "log" else np.tanh
    theta_beta = np.log(beta) if parametrization == "log" else np.arctanh(beta)
    chain = beta if parametrization == "log" else 1.0 - beta**2

    def at(theta_alpha, theta_b):
        return dc_precision(np.exp(theta_alpha), to_beta(theta_b), 1.0, order)

    found = dc_precision(alpha, beta, chain, order)
    theta_alpha = np.log(alpha)
    shifts = {"alpha": (h, 0.0), "beta": (0.0, h)}
    for j, name in enumerate(("alpha", "beta")):
        da, db = shifts[name]
        up, down = at(theta_alpha + da, theta_beta + db), at(theta_alpha - da, theta_beta - db)
        if up is None or down is None:  # alpha = 1: the step in log alpha leaves the range
            continue
        numeric = (up.dense() - down.dense()) / (2 * h)
        d, o = found.derivatives[j]
        from gpmultirate.kernels.precision import tridiagonal_dense

        np.testing.assert_allclose(tridiagonal_dense(d, o), numeric,
                                   atol=1e-6 * np.abs(numeric).max() + 1e-9)
        numeric_log_det = (up.log_det_covariance - down.log_det_covariance) / (2 * h)
        assert found.log_det_gradient[j] == pytest.approx(numeric_log_det, rel=1e-6, abs=1e-6)


def test_no_precision_where_it_does_not_exist():
    assert dc_precision(0.9, 1.0, 1.0, 10) is None  # T of rank one
    assert dc_precision(0.5, 0.5, 0.5, 2000) is None  # alpha^-t near overflow
    assert observe(C(1.0) * DC(0.9, 0.5) + PK(0.9, 0.5)).precision() is None  # a sum
    assert observe(TC(0.9)).precision() is None


def test_a_scaled_kernel_has_the_scaled_precision():
    order, c = 8, 2.5
    kernel = C(c) * DC(0.9, 0.7)
    op = gm.DownsampledConvolution(np.ones(20), 1, order)
    found = observe(kernel, op).precision()
    K = kernel(op.lags)
    np.testing.assert_allclose(found.dense() @ K, np.eye(order), atol=1e-9)
    assert found.log_det_covariance == pytest.approx(np.linalg.slogdet(K)[1], rel=1e-10)
    # the order of theta: amplitude first, then alpha and beta
    h = 1e-6
    for j in range(3):
        step = np.zeros(3)
        step[j] = h
        up = observe(kernel.clone_with_theta(kernel.theta + step), op).precision()
        down = observe(kernel.clone_with_theta(kernel.theta - step), op).precision()
        numeric = (up.dense() - down.dense()) / (2 * h)
        d, o = found.derivatives[j]
        np.testing.assert_allclose(np.diag(d) + np.diag(o, 1) + np.diag(o, -1), numeric,
                                   atol=1e-6 * np.abs(numeric).max())
        assert found.log_det_gradient[j] == pytest.approx(
            (up.log_det_covariance - down.log_det_covariance) / (2 * h), rel=1e-6)
    # a fixed amplitude adds no entry; the amplitude second
    fixed = C(c, "fixed") * DC(0.9, 0.7)
    assert len(observe(fixed, op).precision().derivatives) == 2
    second = observe(DC(0.9, 0.7) * C(c), op).precision()
    np.testing.assert_allclose(second.derivatives[2][0], found.derivatives[0][0])


def problem(seed=0, n=400, factor=3, order=30, noise=0.05):
    rng = np.random.default_rng(seed)
    op = gm.DownsampledConvolution(rng.standard_normal(n), factor, order, 2)
    y = op.matvec(0.85 ** np.arange(order)) + np.sqrt(noise) * rng.standard_normal(op.n_outputs)
    return op, y


def dense_evidence(op, kernel, noise, y):
    covariance = op.covariance(kernel) + noise * np.eye(op.n_outputs)
    return multivariate_normal(np.zeros(op.n_outputs), covariance).logpdf(y)


KERNELS = [C(1.3) * DC(0.8, 0.9), DC(0.95, 0.3), C(0.4) * DC(0.9, 0.5, beta_bounds="fixed"),
           DC(0.99, 0.99)]


@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize("shape", ["reduced", "square"])
def test_evidence_through_the_precision_is_the_dense_evidence(kernel, shape):
    noise = 0.05
    if shape == "reduced":
        op, y = problem()
        data, z = reduce_observation(op, y)
    else:  # M = P: the data space, square regressor
        op, y = problem(n=90, order=30)
        data, z = op, y
    assert data.n_outputs == data.n_coefficients
    assert observe(kernel, data).precision() is not None
    value, grad = log_marginal_likelihood(data, kernel, noise, z, True, True)
    assert log_marginal_likelihood(data, kernel, noise, z, False, True) == value
    assert value == pytest.approx(dense_evidence(op, kernel, noise, y), rel=1e-10)
    # the gradient: finite differences of the dense evidence in theta and log(noise)
    theta = np.append(kernel.theta, np.log(noise))
    h = 1e-6
    numeric = []
    for j in range(theta.shape[0]):
        step = np.zeros_like(theta)
        step[j] = h
        values = [
            dense_evidence(op, kernel.clone_with_theta(t[:-1]), np.exp(t[-1]), y)
            for t in (theta + step, theta - step)
        ]
        numeric.append((values[0] - values[1]) / (2 * h))
    np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-5 * np.abs(numeric).max())
    # and the covariance route of the full observation (M > P: no precision route)
    if shape == "reduced":
        _, grad_full = log_marginal_likelihood(op, kernel, noise, y, True, True)
        np.testing.assert_allclose(grad, grad_full, rtol=1e-8, atol=1e-9 * np.abs(grad_full).max())


def test_without_a_precision_the_covariance_route_answers():
    op, y = problem(order=30)
    data, z = reduce_observation(op, y)
    kernel = C(1.0) * DC(1e-9, 0.5)  # alpha^-29 beyond the accepted range
    assert observe(kernel, data).precision() is None
    value = log_marginal_likelihood(data, kernel, 0.05, z, False, True)
    assert value == pytest.approx(dense_evidence(op, kernel, 0.05, y), rel=1e-10)


def test_the_precision_route_does_not_modify_its_inputs():
    op, y = problem()
    data, z = reduce_observation(op, y)
    before_z, before_gram = z.copy(), data.gram()[0].copy()
    log_marginal_likelihood(data, C(1.0) * DC(0.9, 0.8), 0.05, z, True, True)
    np.testing.assert_array_equal(z, before_z)
    np.testing.assert_array_equal(data.gram()[0], before_gram)


def test_tuning_through_the_precision_reaches_the_fisher_scoring_optimum(monkeypatch):
    # a reduced long record above PRECISION_LBFGS_ABOVE coefficients: L-BFGS-B through
    # DC's precision, against Fisher scoring in the data space of the reduction
    from gpmultirate import inference, tuning

    rng = np.random.default_rng(3)
    u = rng.standard_normal(3000)
    g = 0.97 ** np.arange(300) * np.cos(0.3 * np.arange(300))
    y = np.convolve(u, g)[:3000:3] + 0.05 * rng.standard_normal(1000)
    assert 300 > tuning.PRECISION_LBFGS_ABOVE

    def fit():
        return gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=300).fit(u, y)

    by_precision = fit()
    assert "hess_inv" in by_precision.optimizer_result_  # L-BFGS-B's result
    monkeypatch.setattr(inference.LogEvidence, "by_precision", property(lambda self: False))
    by_fisher = fit()
    assert "hess_inv" not in by_fisher.optimizer_result_
    assert by_precision.log_marginal_likelihood_value_ == pytest.approx(
        by_fisher.log_marginal_likelihood_value_, abs=1e-5)
    np.testing.assert_allclose(by_precision.coef_, by_fisher.coef_, rtol=1e-3,
                               atol=1e-4 * np.abs(by_fisher.coef_).max())
