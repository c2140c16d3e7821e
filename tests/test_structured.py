"""Fast paths of the evidence against dense linear algebra.

``observed_with_contractor`` (recursive filters for DC, rank two for PK, ...)
and ``kernel_with_contractor`` must give the same numbers as the dense route:
``S = Phi K Phi^T`` with ``Phi`` from an explicit loop, and the contraction
``sum_ij (Phi^T W Phi)_ij dK_ij[:, :, j]`` from scikit-learn's
``kernel(X, eval_gradient=True)``.  The contraction is also checked against
finite differences of ``tr(W Phi K(theta) Phi^T)``, and the log evidence of
:mod:`gpmultirate.inference` against ``scipy.stats.multivariate_normal``.
"""

import numpy as np
import pytest
from scipy.stats import multivariate_normal
from sklearn.gaussian_process.kernels import RBF
from sklearn.gaussian_process.kernels import ConstantKernel as C

from gpmultirate import DownsampledConvolution
from gpmultirate.inference import log_marginal_likelihood
from gpmultirate.kernels import DC, PK, SS, TC, observe
from gpmultirate.observations import Observation


class LagGrid(Observation):
    """The identity observation at arbitrary lags: its data-space answers are the
    parameter-space ones, so the contractors can be checked on real lags."""

    def __init__(self, lags):
        self._lags = np.asarray(lags, dtype=float)
        self.order = self.n_outputs = self._lags.shape[0]

    @property
    def lags(self):
        return self._lags[:, None]

    @property
    def matrix(self):
        return np.eye(self.order)


def kernel_with_contractor(kernel, lags):
    """``K`` at ``lags`` and its parameter-space gradient contractor."""
    return observe(kernel, LagGrid(lags)).parameter_contractor()


def observed_with_contractor(kernel, op, need_gradient=True):
    """``S`` and its data-space gradient contractor (None without the gradient)."""
    term = observe(kernel, op)
    if need_gradient:
        return term.covariance_with_contractor()
    return term.covariance(), None

# (N, factor, order, offset)
OPERATORS = {
    "N90-F3-P40-o1": (90, 3, 40, 1),
    "N60-F1-P20-o0": (60, 1, 20, 0),
    "N120-F5-P60-o2": (120, 5, 60, 2),
    "N50-F4-P1-o0": (50, 4, 1, 0),
    "N40-F7-P2-o3": (40, 7, 2, 3),
}

KERNELS = {
    "DC": DC(alpha=0.85, beta=0.7),
    "C*DC": C(2.5) * DC(alpha=0.9, beta=0.6),
    "DC*C": DC(alpha=0.9, beta=0.6) * C(0.4),
    "DC-beta-fixed": DC(alpha=0.8, beta=0.5, beta_bounds="fixed"),
    "C-fixed*DC": C(3.0, "fixed") * DC(alpha=0.9, beta=0.8),
    "DC-beta-near-1": DC(alpha=0.9, beta=0.999999),
    # beta = 1 has no finite theta = artanh(beta): allowed when fixed
    "DC-beta-1": DC(alpha=0.95, beta=1.0, beta_bounds="fixed"),
    "DC-alpha-small": DC(alpha=1e-3, beta=0.7),
    "DC-both-extreme": C(5.0) * DC(alpha=1e-4, beta=0.9999),
    "PK": PK(alpha=0.9, omega=0.7, sigma1=1.3, sigma2=0.6),
    "PK-some-fixed": PK(alpha=0.92, omega=1.1, sigma1=0.8, sigma2=1.4, omega_bounds="fixed", sigma2_bounds="fixed"),
    "PK+PK+PK": PK(alpha=0.9, omega=0.25, sigma1=0.4, sigma2=0.7)
    + PK(alpha=0.8, omega=1.4, sigma1=0.9, sigma2=0.2)
    + PK(alpha=0.95, omega=2.6, sigma1=1.5, sigma2=1.1),
    "C*DC+PK": C(2.0) * DC(alpha=0.85, beta=0.7) + PK(alpha=0.95, omega=1.2, sigma1=0.5, sigma2=0.8),
    "TC": TC(alpha=0.85),
    "SS": SS(alpha=0.9),
    "C*SS": C(4.0) * SS(alpha=0.8),
    "RBF": RBF(length_scale=3.0),
    "C*RBF+C": C(0.7) * RBF(length_scale=5.0, length_scale_bounds="fixed") + C(0.2),
    "DC*PK+TC*SS": DC(alpha=0.9, beta=0.7) * PK(alpha=0.95, omega=0.8) + TC(alpha=0.8) * SS(alpha=0.9),
    "C*(DC+PK)": C(1.3) * (DC(alpha=0.88, beta=0.4) + PK(alpha=0.9, omega=0.5, sigma1=2.0)),
    "C": C(1.7),
    "DC**2": DC(alpha=0.9, beta=0.6) ** 2,
}

# kernels that stay valid at theta +- a small step (alpha, beta strictly below 1)
FD_KERNELS = [
    name
    for name in KERNELS
    if name not in {"DC-beta-near-1", "DC-beta-1", "DC-both-extreme"}
]


def explicit_regressor(u, factor, order, offset):
    rows = list(range(offset, len(u), factor))
    return np.array(
        [[u[n - i] if n - i >= 0 else 0.0 for i in range(order)] for n in rows]
    ).reshape(len(rows), order)


def make_operator(key, seed=0):
    n, factor, order, offset = OPERATORS[key]
    u = np.random.default_rng(seed + n).standard_normal(n)
    return DownsampledConvolution(u, factor, order, offset), explicit_regressor(u, factor, order, offset)


def random_symmetric(size, seed):
    A = np.random.default_rng(seed).standard_normal((size, size))
    return A + A.T


def dense_contraction(kernel, lags, A):
    """``sum_ij A_ij dK_ij[:, :, j]`` and a magnitude scale for tolerances."""
    _, dK = kernel(lags[:, None], eval_gradient=True)
    flat = dK.reshape(-1, dK.shape[2])
    return A.reshape(-1) @ flat, np.abs(A).reshape(-1) @ np.abs(flat)


def trace_derivative(kernel, Phi, W, step=1e-4):
    """Five-point finite differences of ``tr(W Phi K(theta) Phi^T)`` in theta."""
    lags = np.arange(Phi.shape[1], dtype=float)[:, None]
    theta = kernel.theta

    def value(theta_):
        return np.sum(W * (Phi @ kernel.clone_with_theta(theta_)(lags) @ Phi.T))

    out = []
    for j in range(theta.shape[0]):
        e = np.zeros_like(theta)
        e[j] = step
        out.append(
            (-value(theta + 2 * e) + 8 * value(theta + e) - 8 * value(theta - e) + value(theta - 2 * e))
            / (12 * step)
        )
    return np.array(out)


kernel_params = [pytest.param(k, id=name) for name, k in KERNELS.items()]
fd_kernel_params = [pytest.param(KERNELS[name], id=name) for name in FD_KERNELS]
operator_keys = list(OPERATORS)


@pytest.mark.parametrize("op_key", operator_keys)
@pytest.mark.parametrize("kernel", kernel_params)
def test_observed_covariance_and_contraction_equal_dense(kernel, op_key):
    op, Phi = make_operator(op_key)
    lags = np.arange(op.order, dtype=float)
    K = kernel(lags[:, None])
    S_dense = Phi @ K @ Phi.T
    S, contract = observed_with_contractor(kernel, op)
    scale = np.abs(Phi) @ np.abs(K) @ np.abs(Phi).T
    np.testing.assert_allclose(S, S_dense, rtol=1e-9, atol=1e-12 * scale.max())
    np.testing.assert_allclose(S, S.T, rtol=1e-14, atol=1e-14 * scale.max())
    S_only, none = observed_with_contractor(kernel, op, need_gradient=False)
    np.testing.assert_allclose(S_only, S_dense, rtol=1e-9, atol=1e-12 * scale.max())
    for seed in (1, 2):
        W = random_symmetric(op.n_outputs, seed)
        expected, magnitude = dense_contraction(kernel, lags, Phi.T @ W @ Phi)
        got = contract(W)
        assert got.shape == kernel.theta.shape
        np.testing.assert_allclose(got, expected, rtol=1e-8, atol=1e-12 * magnitude.max())
        assert np.all(np.abs(got - expected) <= 1e-9 * magnitude + 1e-300)


@pytest.mark.parametrize("kernel", fd_kernel_params)
def test_observed_contraction_matches_finite_differences(kernel):
    op, Phi = make_operator("N90-F3-P40-o1")
    _, contract = observed_with_contractor(kernel, op)
    W = random_symmetric(op.n_outputs, 3)
    numeric = trace_derivative(kernel, Phi, W)
    np.testing.assert_allclose(contract(W), numeric, rtol=1e-6, atol=1e-8 * np.abs(numeric).max())


@pytest.mark.parametrize("kernel", kernel_params)
def test_kernel_contractor_equals_dense(kernel):
    lags = np.arange(30, dtype=float)
    K_expected, dK = kernel(lags[:, None], eval_gradient=True)
    K, contract = kernel_with_contractor(kernel, lags)
    np.testing.assert_allclose(K, K_expected, rtol=1e-12, atol=1e-14 * np.abs(K_expected).max())
    for seed in (4, 5):
        A = random_symmetric(30, seed)
        expected, magnitude = dense_contraction(kernel, lags, A)
        got = contract(A)
        assert got.shape == kernel.theta.shape
        assert np.all(np.abs(got - expected) <= 1e-10 * magnitude + 1e-300)


@pytest.mark.parametrize("kernel", fd_kernel_params)
def test_kernel_contractor_on_real_lags_matches_finite_differences(kernel):
    # the contractor takes any lag vector, not only the operator's grid
    lags = np.sort(np.random.default_rng(6).uniform(0.0, 25.0, 18))
    K, contract = kernel_with_contractor(kernel, lags)
    np.testing.assert_allclose(K, kernel(lags[:, None]), rtol=1e-12, atol=1e-15)
    A = random_symmetric(18, 7)
    theta = kernel.theta
    step = 1e-4

    def value(theta_):
        return np.sum(A * kernel.clone_with_theta(theta_)(lags[:, None]))

    numeric = []
    for j in range(theta.shape[0]):
        e = np.zeros_like(theta)
        e[j] = step
        numeric.append(
            (-value(theta + 2 * e) + 8 * value(theta + e) - 8 * value(theta - e) + value(theta - 2 * e))
            / (12 * step)
        )
    numeric = np.array(numeric)
    np.testing.assert_allclose(contract(A), numeric, rtol=1e-6, atol=1e-8 * np.abs(numeric).max())


# ----------------------------------------------------------------------------
# log marginal likelihood (eq. 19 with the noise inside the determinant)
# ----------------------------------------------------------------------------

LML_KERNELS = ["DC", "C*DC", "DC-beta-fixed", "PK-some-fixed", "C*DC+PK", "SS", "RBF", "DC*PK+TC*SS"]


def lml_data(op, Phi, seed=8):
    rng = np.random.default_rng(seed)
    lags = np.arange(op.order)
    g = 0.9**lags * np.cos(0.7 * lags)
    return Phi @ g + 0.1 * rng.standard_normal(op.n_outputs)


def dense_log_density(kernel, theta, log_noise, Phi, y):
    lags = np.arange(Phi.shape[1], dtype=float)[:, None]
    S = Phi @ kernel.clone_with_theta(theta)(lags) @ Phi.T
    cov = S + np.exp(log_noise) * np.eye(Phi.shape[0])
    return multivariate_normal(np.zeros(Phi.shape[0]), cov).logpdf(y)


@pytest.mark.parametrize("op_key", ["N90-F3-P40-o1", "N120-F5-P60-o2"])
@pytest.mark.parametrize("name", LML_KERNELS)
def test_log_marginal_likelihood_value_and_gradient(name, op_key):
    kernel = KERNELS[name]
    op, Phi = make_operator(op_key)
    y = lml_data(op, Phi)
    noise = 0.02
    theta = kernel.theta
    expected = dense_log_density(kernel, theta, np.log(noise), Phi, y)
    value = log_marginal_likelihood(op, kernel, noise, y, eval_gradient=False, noise_free=True)
    assert value == pytest.approx(expected, rel=1e-10, abs=1e-9)
    value, grad = log_marginal_likelihood(op, kernel, noise, y, eval_gradient=True, noise_free=True)
    assert value == pytest.approx(expected, rel=1e-10, abs=1e-9)
    assert grad.shape == (theta.shape[0] + 1,)

    full = np.append(theta, np.log(noise))
    step = 1e-4
    numeric = []
    for j in range(full.shape[0]):
        e = np.zeros_like(full)
        e[j] = step

        def f(x):
            return dense_log_density(kernel, x[:-1], x[-1], Phi, y)

        numeric.append(
            (-f(full + 2 * e) + 8 * f(full + e) - 8 * f(full - e) + f(full - 2 * e)) / (12 * step)
        )
    numeric = np.array(numeric)
    np.testing.assert_allclose(grad, numeric, rtol=1e-6, atol=1e-6 * max(1.0, np.abs(numeric).max()))

    _, grad_fixed_noise = log_marginal_likelihood(
        op, kernel, noise, y, eval_gradient=True, noise_free=False
    )
    np.testing.assert_allclose(grad_fixed_noise, grad[:-1], rtol=1e-12, atol=1e-12)


def test_log_marginal_likelihood_extreme_hyperparameters():
    # beta close to 1 and alpha small: value against the dense density only
    op, Phi = make_operator("N90-F3-P40-o1")
    y = lml_data(op, Phi)
    for name in ["DC-beta-near-1", "DC-beta-1", "DC-both-extreme", "DC-alpha-small"]:
        kernel = KERNELS[name]
        expected = dense_log_density(kernel, kernel.theta, np.log(0.05), Phi, y)
        value = log_marginal_likelihood(op, kernel, 0.05, y, eval_gradient=True, noise_free=True)[0]
        assert value == pytest.approx(expected, rel=1e-9), name


def test_fallback_kernel_with_all_hyperparameters_fixed():
    # a kernel without special handling and without free hyperparameters has an
    # empty gradient; its contraction must be an empty vector, not an error
    kernel = RBF(length_scale=3.0, length_scale_bounds="fixed")
    lags = np.arange(10, dtype=float)
    K, contract = kernel_with_contractor(kernel, lags)
    np.testing.assert_allclose(K, np.exp(-0.5 * np.subtract.outer(lags, lags) ** 2 / 9.0), rtol=1e-14)
    assert contract(random_symmetric(10, 9)).shape == (0,)
    op, Phi = make_operator("N60-F1-P20-o0")
    _, contract = observed_with_contractor(kernel, op)
    assert contract(random_symmetric(op.n_outputs, 10)).shape == (0,)


@pytest.mark.parametrize("op_key", operator_keys)
@pytest.mark.parametrize("kernel", kernel_params)
def test_regressor_times_kernel_equals_dense(kernel, op_key):
    def regressor_times_kernel(kernel, op):
        return observe(kernel, op).regressor_times_kernel()

    op, Phi = make_operator(op_key)
    K = kernel(np.arange(op.order, dtype=float)[:, None])
    expected = Phi @ K
    scale = (np.abs(Phi) @ np.abs(K)).max()
    np.testing.assert_allclose(
        regressor_times_kernel(kernel, op), expected, rtol=1e-9, atol=1e-12 * scale
    )
