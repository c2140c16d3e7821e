"""The example of a new noise model: ``HeteroscedasticNoise``, ``N = gamma diag(w)``.

One class, checked through the covariance layer against the dense closed
form (the Gaussian density of ``Phi K Phi^T + gamma diag(w)``, eq. 15 and 19
with ``N`` in place of ``gamma I``) and finite differences of the gradient.
"""

import numpy as np
import pytest
from scipy.stats import multivariate_normal
from sklearn.gaussian_process.kernels import ConstantKernel as C

from gpmultirate import DownsampledConvolution
from gpmultirate.covariance import DenseCovariance, data_covariance
from gpmultirate.crossvalidation import contiguous_folds, log_predictive_likelihood
from gpmultirate.inference import LogEvidence
from gpmultirate.kernels import DC, TC
from gpmultirate.noise import HeteroscedasticNoise, NoiseModel
from gpmultirate.observations import reduce_observation


def problem(seed=0, n=120, factor=3, order=15):
    rng = np.random.default_rng(seed)
    op = DownsampledConvolution(rng.standard_normal(n), factor, order)
    M = op.n_outputs
    weights = np.where(np.arange(M) < M // 2, 1.0, 9.0)  # a second, noisier half
    g = 0.8 ** np.arange(order)
    y = op.matvec(g) + np.sqrt(0.01 * weights) * rng.standard_normal(M)
    return op, weights, y


def dense_covariance(op, kernel, noise_level, weights):
    Phi = op.matrix
    return Phi @ kernel(op.lags) @ Phi.T + noise_level * np.diag(weights)


@pytest.mark.parametrize("kernel", [C(0.7) * DC(0.8, 0.4), TC(0.85)], ids=["DC", "TC"])
def test_evidence_and_posterior_equal_the_dense_closed_form(kernel):
    op, weights, y = problem()
    noise = HeteroscedasticNoise(weights, 0.02, (1e-4, 1.0))
    covariance = data_covariance(kernel, op, noise)
    assert isinstance(covariance, DenseCovariance)  # the route every model gets for free
    Ky = dense_covariance(op, kernel, 0.02, weights)
    reference = multivariate_normal(np.zeros(y.shape[0]), Ky).logpdf(y)
    assert covariance.log_likelihood(y) == pytest.approx(reference, rel=1e-10)
    np.testing.assert_allclose(covariance.solve(y), np.linalg.solve(Ky, y), rtol=1e-9)
    # eq. (15): mean K Phi^T Ky^-1 y, covariance K - K Phi^T Ky^-1 Phi K
    K, Phi = kernel(op.lags), op.matrix
    posterior = data_covariance(kernel, op, noise, space="posterior").posterior(y)
    np.testing.assert_allclose(posterior.coef, K @ Phi.T @ np.linalg.solve(Ky, y),
                               rtol=1e-8, atol=1e-12)
    Sigma = K - K @ Phi.T @ np.linalg.solve(Ky, Phi @ K)
    np.testing.assert_allclose(posterior.covariance(), Sigma, rtol=1e-7, atol=1e-12)


def test_gradient_equals_finite_differences():
    op, weights, y = problem(seed=1)
    kernel = C(0.7) * DC(0.8, 0.4)
    evidence = LogEvidence(op, y, kernel, 0.02, (1e-4, 1.0),
                           noise=HeteroscedasticNoise(weights, 0.02, (1e-4, 1.0)))
    theta = evidence.theta
    assert theta.shape == (4,)  # C, alpha, beta of the prior; log gamma of the noise
    value, grad = evidence(theta, eval_gradient=True)
    step = 1e-6
    numeric = np.array([
        (evidence(theta + step * e) - evidence(theta - step * e)) / (2 * step)
        for e in np.eye(theta.shape[0])
    ])
    np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-6)
    # the noise's entry against the closed form: d/d log gamma = 1/2 tr((a a^T - Ky^-1) gamma W)
    Ky = dense_covariance(op, kernel, 0.02, weights)
    a = np.linalg.solve(Ky, y)
    expected = 0.5 * 0.02 * np.sum((a**2 - np.diag(np.linalg.inv(Ky))) * weights)
    assert grad[-1] == pytest.approx(expected, rel=1e-8)


def test_unit_weights_are_white_noise():
    op, _, y = problem(seed=2)
    kernel = TC(0.85)
    ones = HeteroscedasticNoise(np.ones(op.n_outputs), 0.05, (1e-4, 1.0))
    value, grad = data_covariance(kernel, op, ones, "contraction").log_likelihood_gradient(y)
    from gpmultirate.noise import WhiteNoise

    white = WhiteNoise(0.05, (1e-4, 1.0))
    reference, reference_grad = data_covariance(kernel, op, white, "contraction") \
        .log_likelihood_gradient(y)
    assert value == pytest.approx(reference, rel=1e-12)
    np.testing.assert_allclose(grad, reference_grad, rtol=1e-10)


def test_cross_validation_takes_the_model_too():
    op, weights, y = problem(seed=3)
    kernel = C(0.7) * DC(0.8, 0.4)
    folds = contiguous_folds([op.n_outputs], 4)
    noise = HeteroscedasticNoise(weights, 0.02, (1e-4, 1.0))
    value, grad = log_predictive_likelihood(op, kernel, noise, y, folds, eval_gradient=True)
    # the held-out blocks' densities from the dense matrix
    Ky = dense_covariance(op, kernel, 0.02, weights)
    expected = 0.0
    for B in folds:
        rest = np.setdiff1d(np.arange(y.shape[0]), B)
        gain = Ky[np.ix_(B, rest)] @ np.linalg.inv(Ky[np.ix_(rest, rest)])
        mean = gain @ y[rest]
        cov = Ky[np.ix_(B, B)] - gain @ Ky[np.ix_(rest, B)]
        expected += multivariate_normal(mean, cov).logpdf(y[B])
    assert value == pytest.approx(expected, rel=1e-9)
    assert grad.shape == (4,)


def test_bad_input_is_refused_and_the_weights_are_copied():
    assert issubclass(HeteroscedasticNoise, NoiseModel)
    for weights in ([1.0, -1.0], [[1.0]], [], [1.0, np.nan]):
        with pytest.raises(ValueError, match="weights"):
            HeteroscedasticNoise(weights, 0.1)
    with pytest.raises(ValueError, match="noise_level"):
        HeteroscedasticNoise([1.0], 0.0)
    weights = np.ones(3)
    noise = HeteroscedasticNoise(weights, 0.1)
    weights[0] = 5.0
    assert noise.weights[0] == 1.0
    op, _, y = problem()
    with pytest.raises(ValueError, match="weights must give one weight per slow sample"):
        data_covariance(TC(0.8), op, HeteroscedasticNoise(np.ones(3), 0.1))
    fixed = HeteroscedasticNoise(np.ones(op.n_outputs), 0.1)
    assert fixed.theta.shape == (0,) and fixed.with_theta(np.empty(0)) is fixed
    # a reduction summarizes white noise only
    data, _ = reduce_observation(DownsampledConvolution(np.ones(300), 3, 10), np.ones(100))
    with pytest.raises(ValueError, match="reduced observation assumes white noise"):
        data_covariance(TC(0.8), data, HeteroscedasticNoise(np.ones(10), 0.1))


def test_one_variance_per_record_of_two_sensors():
    from gpmultirate.observations import RecordStack

    rng = np.random.default_rng(4)
    records = [DownsampledConvolution(rng.standard_normal(n), 3, 12) for n in (90, 60)]
    stack = RecordStack(records)
    noise = HeteroscedasticNoise.per_record(stack, [1.0, 25.0], 0.01)
    sizes = [r.n_outputs for r in records]
    np.testing.assert_array_equal(noise.weights, np.repeat([1.0, 25.0], sizes))
    y = stack.matvec(0.7 ** np.arange(12)) + np.sqrt(0.01 * noise.weights) \
        * rng.standard_normal(stack.n_outputs)
    kernel = C(0.5) * DC(0.7, 0.3)
    Ky = dense_covariance(stack, kernel, 0.01, noise.weights)
    reference = multivariate_normal(np.zeros(y.shape[0]), Ky).logpdf(y)
    assert data_covariance(kernel, stack, noise).log_likelihood(y) == pytest.approx(reference,
                                                                                   rel=1e-10)
    with pytest.raises(ValueError, match="one weight per record"):
        HeteroscedasticNoise.per_record(stack, [1.0, 2.0, 3.0], 0.01)
