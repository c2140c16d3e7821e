"""The reduced (parameter-space) observation of long records against dense formulas.

For ``M > P`` the evidence, its gradient and Fisher information, the
posterior and the estimator's tuning use the ``P x P`` factor ``(R, z, rho)``
of ``[Phi y]``.  Each is compared with the dense computation on the full
``M x M`` data covariance (``scipy.stats.multivariate_normal`` for the
evidence, explicit ``Phi`` for everything else).
"""

import numpy as np
import pytest
from scipy.stats import multivariate_normal
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate.inference import (
    DataSpacePosterior,
    log_marginal_likelihood,
    log_marginal_likelihood_fisher,
    posterior,
)
from gpmultirate.covariance import data_covariance
from gpmultirate.noise import WhiteNoise
from gpmultirate.observations import ReducedObservation, reduce_observation


def tuning_data(op, y):
    """The data the evidence is computed from: ``(op, y)``, or the reduction ``(R, z)``."""
    return reduce_observation(op, y)
from gpmultirate.kernels import DC, PK, TC


def make(seed=0, n=400, factor=3, order=30, offset=2, zoh=False):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    if zoh:
        u = np.repeat(u[::factor], factor)[:n]
    op = gm.DownsampledConvolution(u, factor, order, offset)
    return op, rng.standard_normal(op.n_outputs)


@pytest.mark.parametrize("block_rows", [7, 29, 31, 64, None])
@pytest.mark.parametrize("zoh", [False, True])
def test_factor_reproduces_the_normal_equations(block_rows, zoh):
    op, y = make(zoh=zoh)
    red = ReducedObservation(op, y, block_rows=block_rows)
    Phi = op.matrix
    np.testing.assert_allclose(red.matrix.T @ red.matrix, Phi.T @ Phi, rtol=1e-10, atol=1e-10 * np.abs(Phi.T @ Phi).max())
    np.testing.assert_allclose(red.matrix.T @ red.z, Phi.T @ y, rtol=1e-10, atol=1e-10 * np.abs(Phi.T @ y).max())
    assert red.z @ red.z + red.residual == pytest.approx(y @ y, rel=1e-12)
    if not zoh:  # full column rank: rho^2 is the least-squares residual
        coef = np.linalg.lstsq(Phi, y, rcond=None)[0]
        assert red.residual == pytest.approx(np.sum((y - Phi @ coef) ** 2), rel=1e-9)
    assert red.n_discarded == op.n_outputs - op.order
    assert np.allclose(np.tril(red.matrix, -1), 0.0)


def test_no_reduction_when_p_is_at_least_m():
    op, y = make(n=90, order=30)
    assert tuning_data(op, y)[0] is op


KERNELS = [C(1.3) * DC(0.8, 0.9) + PK(0.9, 0.5), TC(0.7), C(0.4) * DC(0.9, 0.5, beta_bounds="fixed")]


@pytest.mark.parametrize("zoh", [False, True])
@pytest.mark.parametrize("kernel", KERNELS)
def test_evidence_gradient_and_fisher_equal_the_data_space(kernel, zoh):
    # a zero-order-hold input makes Phi rank deficient: the reduction stays exact
    op, y = make(seed=1, zoh=zoh)
    noise = 0.2
    red, z = tuning_data(op, y)
    dense = multivariate_normal(np.zeros(op.n_outputs), op.covariance(kernel) + noise * np.eye(op.n_outputs))
    value, grad = log_marginal_likelihood(red, kernel, noise, z, True, True)
    value_full, grad_full = log_marginal_likelihood(op, kernel, noise, y, True, True)
    assert value == pytest.approx(dense.logpdf(y), rel=1e-12, abs=1e-9)
    np.testing.assert_allclose(grad, grad_full, rtol=1e-8, atol=1e-10 * np.abs(grad_full).max())
    f_value, f_grad, fisher = log_marginal_likelihood_fisher(red, kernel, noise, z, True)
    _, _, fisher_full = log_marginal_likelihood_fisher(op, kernel, noise, y, True)
    assert f_value == pytest.approx(value, rel=1e-12)
    np.testing.assert_allclose(f_grad, grad_full, rtol=1e-8, atol=1e-10 * np.abs(grad_full).max())
    np.testing.assert_allclose(fisher, fisher_full, rtol=1e-8, atol=1e-10 * np.abs(fisher_full).max())


def test_posterior_equals_the_dense_closed_form():
    op, y = make(seed=2)
    kernel = KERNELS[0]
    noise = 0.05
    result = posterior(op, kernel, noise, y)
    reference = DataSpacePosterior(data_covariance(kernel, op, WhiteNoise(noise)), y)
    Phi = op.matrix
    K = kernel(op.lags)
    mean = K @ Phi.T @ np.linalg.solve(Phi @ K @ Phi.T + noise * np.eye(len(y)), y)
    np.testing.assert_allclose(result.coef, mean, rtol=1e-8, atol=1e-10 * np.abs(mean).max())
    np.testing.assert_allclose(result.covariance(), reference.covariance(), rtol=1e-7, atol=1e-10)
    assert result.log_marginal_likelihood == pytest.approx(reference.log_marginal_likelihood, rel=1e-12)


def test_estimator_evidence_is_that_of_the_full_data():
    op, noise = make(seed=3, n=600, order=40)
    y = op.matvec(0.8 ** np.arange(40) * np.cos(0.5 * np.arange(40))) + 0.1 * noise
    model = gm.FIRGaussianProcess(C(1.0) * DC(0.9, 0.9), factor=3, order=40, offset=2).fit(op.u, y)
    theta = np.append(model.kernel_.theta, np.log(model.noise_level_))
    S = op.covariance(model.kernel_) + model.noise_level_ * np.eye(op.n_outputs)
    expected = multivariate_normal(np.zeros(op.n_outputs), S).logpdf(y)
    assert model.log_marginal_likelihood(theta) == pytest.approx(expected, rel=1e-10)
    assert model.log_marginal_likelihood_value_ == pytest.approx(expected, rel=1e-10)
