"""A slow sensor with a known first-order response, against the dense formulas of the paper.

The regressor is built by brute force from its definition (the output
through the sensor's recursion, one impulse response coefficient at a time);
the data covariance, the evidence (eq. 19, corrected), its gradient and the
posterior (eq. 15 and its covariance) are the dense formulas with that
regressor, evaluated here with NumPy and SciPy only.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import linalg
from scipy.stats import multivariate_normal
from sklearn.gaussian_process.kernels import RBF
from sklearn.gaussian_process.kernels import ConstantKernel as C

from gpmultirate.inference import LogEvidence, log_marginal_likelihood, posterior
from gpmultirate.kernels import DC, PK, SS, TC, observe
from gpmultirate.observations import FilteredConvolution
from gpmultirate.tuning import maximize

POLE = 0.7


def brute_force_regressor(u, indices, order, pole):
    """Column ``j``: the sensor's reading of the output of ``g = e_j``, by its recursion."""
    N = u.shape[0]
    Phi = np.zeros((len(indices), order))
    for j in range(order):
        y = np.array([u[n - j] if n >= j else 0.0 for n in range(N)])
        reading, previous = np.zeros(N), 0.0
        for n in range(N):
            previous = pole * previous + (1.0 - pole) * y[n]
            reading[n] = previous
        Phi[:, j] = reading[indices]
    return Phi


def problem(n_samples=90, factor=3, order=30, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n_samples)
    indices = np.arange(2, n_samples, factor)
    sensor = FilteredConvolution(u, indices, order, POLE)
    Phi = brute_force_regressor(u, indices, order, POLE)
    g = 0.8 ** np.arange(order) * np.cos(0.4 * np.arange(order))
    y = Phi @ g + 0.05 * rng.standard_normal(indices.shape[0])
    return u, indices, sensor, Phi, y


KERNELS = {
    "DC": C(1.5) * DC(0.85, 0.6),
    "TC": C(0.8) * TC(0.9),
    "SS": C(1.2) * SS(0.9),
    "PK": PK(0.9, 0.8, 1.1, 0.7),
    "DC+PK": C(1.5) * DC(0.85, -0.4) + PK(0.9, 0.8, 1.1, 0.7),
    "RBF": C(1.0) * RBF(3.0),
}


def test_the_regressor_is_the_sensor_reading_of_each_coefficient():
    _, _, sensor, Phi, _ = problem()
    np.testing.assert_allclose(sensor.matrix, Phi, rtol=1e-12, atol=1e-12)


def test_no_filter_is_the_sampled_convolution():
    from gpmultirate.observations import SampledConvolution

    u = np.random.default_rng(1).standard_normal(40)
    plain = SampledConvolution(u, [3, 9, 20, 39], 10)
    np.testing.assert_array_equal(FilteredConvolution(u, [3, 9, 20, 39], 10, 0.0).matrix,
                                  plain.matrix)


@pytest.mark.parametrize("name", sorted(KERNELS))
def test_data_covariance_and_evidence_follow_the_dense_formulas(name):
    _, _, sensor, Phi, y = problem()
    kernel = KERNELS[name]
    noise = 0.01
    K, dK = kernel(np.arange(30.0)[:, None], eval_gradient=True)
    S = Phi @ K @ Phi.T
    np.testing.assert_allclose(observe(kernel, sensor).covariance(), S,
                               rtol=1e-10, atol=1e-10 * np.abs(S).max())
    # eq. 19 (corrected): log N(y; 0, Phi K Phi^T + gamma I), and its gradient in theta
    Ky = S + noise * np.eye(S.shape[0])
    expected = multivariate_normal(np.zeros(S.shape[0]), Ky).logpdf(y)
    value, gradient = log_marginal_likelihood(sensor, kernel, noise, y, True, True)
    assert value == pytest.approx(expected, rel=1e-10)
    alpha = linalg.solve(Ky, y, assume_a="pos")
    Ky_inv = linalg.inv(Ky)
    dense_gradient = [
        0.5 * alpha @ dS @ alpha - 0.5 * np.sum(Ky_inv * dS)
        for dS in (Phi @ dK[:, :, j] @ Phi.T for j in range(dK.shape[2]))
    ]
    dense_gradient.append(noise * (0.5 * alpha @ alpha - 0.5 * np.trace(Ky_inv)))
    np.testing.assert_allclose(gradient, dense_gradient, rtol=1e-8, atol=1e-8)


def test_the_recursion_route_is_taken_and_agrees_with_the_dense_formula(monkeypatch):
    # a uniform record: the shift-scaled kernels take the diagonal recursion on the
    # filtered input (the observation offers its uniform sampling)
    import gpmultirate.kernels.recursion as recursion

    rng = np.random.default_rng(2)
    u = rng.standard_normal(300)
    indices = np.arange(1, 300, 2)
    order = 200
    sensor = FilteredConvolution(u, indices, order, POLE)
    calls = []
    original = recursion.observed_recursion
    monkeypatch.setattr(recursion, "observed_recursion",
                        lambda *args, **kwargs: calls.append(1) or original(*args, **kwargs))
    Phi = brute_force_regressor(u, indices, order, POLE)
    kernel = DC(0.95, 0.7)
    S = Phi @ kernel(np.arange(float(order))[:, None]) @ Phi.T
    np.testing.assert_allclose(observe(kernel, sensor).covariance(), S,
                               rtol=1e-9, atol=1e-9 * np.abs(S).max())
    assert calls, "the diagonal recursion was not taken"


@pytest.mark.parametrize("n_samples, order", [(60, 30), (300, 20)])
def test_posterior_follows_eq_15(n_samples, order):
    # M <= P: the data-space posterior; M > P: the long-record reduction of the regressor
    _, _, sensor, Phi, y = problem(n_samples=n_samples, order=order, seed=4)
    kernel = C(1.5) * DC(0.85, 0.6)
    noise = 0.02
    K = kernel(np.arange(float(order))[:, None])
    Ky = Phi @ K @ Phi.T + noise * np.eye(Phi.shape[0])
    mean = K @ Phi.T @ linalg.solve(Ky, y, assume_a="pos")
    covariance = K - K @ Phi.T @ linalg.solve(Ky, Phi @ K, assume_a="pos")
    found = posterior(sensor, kernel, noise, y)
    np.testing.assert_allclose(found.coef, mean, rtol=1e-8, atol=1e-8 * np.abs(mean).max())
    np.testing.assert_allclose(found.covariance(), covariance, rtol=1e-7,
                               atol=1e-8 * np.abs(K).max())


def test_a_kernel_is_tuned_on_the_sensor_readings():
    # tuning through the library's evidence and optimizer reaches the maximum of the
    # dense evidence: no direction improves it (checked against the dense formula)
    _, _, sensor, Phi, y = problem(n_samples=120, order=25, seed=6)
    evidence = LogEvidence(sensor, y, C(1.0) * DC(0.9, 0.8), 0.01, (1e-5, 1.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = maximize(evidence)
    theta = result.x
    kernel = evidence.kernel.clone_with_theta(theta[:-1])
    noise = float(np.exp(theta[-1]))

    def dense(kernel, noise):
        K = kernel(np.arange(25.0)[:, None])
        Ky = Phi @ K @ Phi.T + noise * np.eye(Phi.shape[0])
        return multivariate_normal(np.zeros(Ky.shape[0]), Ky).logpdf(y)

    best = dense(kernel, noise)
    assert -result.fun == pytest.approx(best, rel=1e-9)
    rng = np.random.default_rng(0)
    bounds = evidence.bounds
    for _ in range(10):
        moved = np.clip(theta + 0.05 * rng.standard_normal(theta.shape), bounds[:, 0], bounds[:, 1])
        assert dense(kernel.clone_with_theta(moved[:-1]), float(np.exp(moved[-1]))) <= best + 1e-6


@pytest.mark.parametrize("pole", [-0.1, 1.0, float("nan"), True, "0.5"])
def test_a_pole_outside_the_stable_range_is_refused(pole):
    with pytest.raises(ValueError, match="pole"):
        FilteredConvolution(np.ones(10), [2, 5], 3, pole)


def test_the_callers_input_is_not_modified():
    u = np.random.default_rng(0).standard_normal(20)
    kept = u.copy()
    FilteredConvolution(u, [4, 9, 19], 5, 0.5).matrix
    np.testing.assert_array_equal(u, kept)
