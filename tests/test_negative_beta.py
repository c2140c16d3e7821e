"""DC with a correlation ``-1 < beta < 1`` (the paper's range), tuned in ``theta = artanh(beta)``.

Every number is checked against an independent computation: the kernel
against its formula written out element by element (integer lags:
``alpha^((i+j)/2) beta^|i-j|`` in integer powers; real lags:
``|beta|^d cos(pi d)``), gradients against central finite differences of
``theta``, the fast paths (filters, diagonal recursion, long-record
reduction, several inputs) against ``Phi K Phi^T`` with ``Phi`` from an
explicit loop, the evidence against ``scipy.stats.multivariate_normal``.
"""

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import linalg
from scipy.stats import multivariate_normal
from sklearn.base import clone
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import ConstantKernel as C
from sklearn.gaussian_process.kernels import WhiteKernel

import gpmultirate as gm
from gpmultirate import DownsampledConvolution, FIRGaussianProcess, ObservedKernel
from gpmultirate.inference import LogEvidence
from gpmultirate.kernels import DC, PK, PerInputKernel, observe
from gpmultirate.kernels import recursion as recursion_module
from gpmultirate.kernels.filters import DCFilterTerm
from gpmultirate.kernels.recursion import ShiftScaledTerm, observed_recursion
from gpmultirate.kernels.structure import ObservedTerm
from gpmultirate.observations import ReducedObservation, build_experiment, reduce_observation
from gpmultirate.persistence import load_model, save_model
from hold_reference import lagrange_rows

DATA = Path(__file__).parent / "data"
INTEGER_LAGS = np.arange(12.0)
REAL_LAGS = np.array([0.0, 0.3, 1.0, 1.5, 2.25, 3.0, 4.7, 7.1, 10.0])
NEGATIVE = [-0.3, -0.75, -0.99]


def dc_elementwise(t, s, alpha, beta):
    """The DC kernel entry by entry; integer distances in integer powers of beta."""
    out = np.empty((len(t), len(s)))
    for i, ti in enumerate(t):
        for j, sj in enumerate(s):
            d = abs(float(ti) - float(sj))
            if d == int(d):
                correlation = beta ** int(d)
            elif beta >= 0:
                correlation = beta**d
            else:
                correlation = abs(beta) ** d * math.cos(math.pi * d)
            out[i, j] = alpha ** ((float(ti) + float(sj)) / 2.0) * correlation
    return out


def explicit_regressor(u, factor, order, offset=0):
    rows = range(offset, len(u), factor)
    return np.array([[u[n - i] if n - i >= 0 else 0.0 for i in range(order)] for n in rows])


def theta_derivatives(function, theta, step=1e-6):
    """Central differences of ``function(theta)`` (array-valued) in each entry of ``theta``."""
    out = []
    for j in range(theta.shape[0]):
        e = np.zeros_like(theta)
        e[j] = step
        out.append((function(theta + e) - function(theta - e)) / (2 * step))
    return np.stack(out, axis=-1)


def kernel_gradient_fd(kernel, X):
    return theta_derivatives(lambda th: kernel.clone_with_theta(th)(X), kernel.theta)


def random_symmetric(size, seed):
    A = np.random.default_rng(seed).standard_normal((size, size))
    return A + A.T


# ------------------------------------------------------------------ values
@pytest.mark.parametrize("beta", NEGATIVE + [0.0, 0.4])
def test_values_against_the_formula_on_integer_and_real_lags(beta):
    # the formula at integer lags; between them its interpolation by the hold: Lagrange
    # on the lags n - 5 .. n + 6 around n + d, zero below lag 0
    kernel = DC(alpha=0.85, beta=beta)
    X = INTEGER_LAGS[:, None]
    expected = dc_elementwise(INTEGER_LAGS, INTEGER_LAGS, 0.85, beta)
    np.testing.assert_allclose(kernel(X), expected, rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(kernel.diag(X), np.diag(expected), rtol=1e-13)
    grid = np.arange(40.0)
    formula = dc_elementwise(grid, grid, 0.85, beta)

    def bridge(t, s):  # independent on each cell: 0.1^2 sin(pi d) sin(pi e) k(n, n)
        n, m = np.floor(t)[:, None], np.floor(s)[None, :]
        return (0.1**2 * np.outer(np.sin(np.pi * t), np.sin(np.pi * s)) * (-1.0) ** (n + m)
                * (n == m) * 0.85**n)

    W = lagrange_rows(REAL_LAGS, 40)
    V = lagrange_rows([0.5, 2.0, 6.0], 40)
    expected = W @ formula @ W.T + bridge(REAL_LAGS, REAL_LAGS)
    np.testing.assert_allclose(kernel(REAL_LAGS[:, None]), expected, rtol=1e-11, atol=1e-14)
    np.testing.assert_allclose(kernel.diag(REAL_LAGS[:, None]), np.diag(expected), rtol=1e-11,
                               atol=1e-14)
    np.testing.assert_allclose(kernel(REAL_LAGS[:, None], np.array([[0.5], [2.0], [6.0]])),
                               W @ formula @ V.T + bridge(REAL_LAGS, np.array([0.5, 2.0, 6.0])),
                               rtol=1e-11, atol=1e-14)


def test_negative_beta_alternates_exactly_on_integer_lags():
    K = DC(alpha=1.0, beta=-0.5, alpha_bounds="fixed")(INTEGER_LAGS[:, None])
    assert K[0, 1] == -0.5 and K[0, 2] == 0.25 and K[3, 0] == -0.125
    assert np.array_equal(np.sign(K[0]), (-1.0) ** INTEGER_LAGS)


@pytest.mark.parametrize("beta", NEGATIVE)
def test_positive_semidefinite_on_real_lags(beta):
    lags = np.sort(np.random.default_rng(1).uniform(0.0, 15.0, 60))
    K = DC(alpha=0.95, beta=beta)(lags[:, None])
    values = linalg.eigvalsh(K)
    assert values.min() >= -1e-12 * values.max()
    # and the real-lag kernel is the integer one where the lags are integers
    np.testing.assert_allclose(
        DC(alpha=0.95, beta=beta)(INTEGER_LAGS[:, None]),
        0.95 ** (np.add.outer(INTEGER_LAGS, INTEGER_LAGS) / 2)
        * beta ** np.abs(np.subtract.outer(INTEGER_LAGS, INTEGER_LAGS)),
        rtol=1e-13,
    )


# ---------------------------------------------------------------- gradient
GRADIENT_KERNELS = {
    "DC": DC(alpha=0.8, beta=-0.6),
    "DC-beta-near--1": DC(alpha=0.9, beta=-0.995),
    "DC-beta-0": DC(alpha=0.9, beta=0.0),
    "C*DC+PK": C(2.0) * DC(alpha=0.85, beta=-0.7) + PK(alpha=0.9, omega=2.8, sigma1=0.6),
    "C*DC+PK+PK": C(0.5) * DC(0.9, -0.4) + PK(0.9, 0.5) + PK(0.8, 2.9, sigma2=0.3),
    "PK*DC": PK(alpha=0.95, omega=0.8) * DC(alpha=0.9, beta=-0.5),
    "DC**2": DC(alpha=0.9, beta=-0.6) ** 2,
    "DC*C": DC(alpha=0.9, beta=-0.2) * C(0.4),
}


@pytest.mark.parametrize("name", list(GRADIENT_KERNELS))
def test_gradient_in_theta_matches_finite_differences(name):
    kernel = GRADIENT_KERNELS[name]
    lag_sets = [INTEGER_LAGS]
    if name != "DC-beta-0":  # at beta = 0 the real-lag derivative is infinite
        lag_sets.append(REAL_LAGS)
    for lags in lag_sets:
        X = lags[:, None]
        _, dK = kernel(X, eval_gradient=True)
        numeric = kernel_gradient_fd(kernel, X)
        np.testing.assert_allclose(dK, numeric, rtol=1e-6, atol=1e-8 * np.abs(numeric).max())


def test_lag_covariance_gradient_off_the_diagonal_matches_finite_differences():
    # the recursion uses the first and last rows: t is not s
    kernel = DC(alpha=0.8, beta=-0.65)
    t, s = np.array([0.0, 9.0]), np.arange(10.0)
    _, gradients = kernel.lag_covariance(t, s, eval_gradient=True)
    for j, name in enumerate(["alpha", "beta"]):
        def value(theta):
            return kernel.clone_with_theta(theta).lag_covariance(t, s)

        numeric = theta_derivatives(value, kernel.theta)[:, :, j]
        np.testing.assert_allclose(gradients[name], numeric, rtol=1e-6, atol=1e-10)


def test_gradient_at_beta_zero_on_real_lags_is_finite():
    # between integer lags the values interpolate the integer ones: a finite derivative
    # in beta at beta = 0 (the formula's |beta|^d had an infinite one for 0 < d < 1)
    kernel = DC(alpha=0.9, beta=0.0)
    X = np.array([[0.0], [0.5], [3.25]])
    _, gradient = kernel(X, eval_gradient=True)
    step = 1e-6
    moved = [kernel.clone_with_theta(kernel.theta + sign * np.array([0.0, step]))(X)
             for sign in (1, -1)]
    np.testing.assert_allclose(gradient[..., 1], (moved[0] - moved[1]) / (2 * step),
                               rtol=1e-6, atol=1e-10)


# ----------------------------------------------- theta, bounds, the algebra
def test_theta_bounds_and_clone_with_theta_round_trip():
    kernel = DC(alpha=0.8, beta=-0.6, beta_bounds=(-0.95, 0.5))
    np.testing.assert_allclose(kernel.theta, [np.log(0.8), np.arctanh(-0.6)], rtol=1e-15)
    np.testing.assert_allclose(
        kernel.bounds, [np.log([1e-4, 1.0]), np.arctanh([-0.95, 0.5])], rtol=1e-15
    )
    assert [h.name for h in kernel.hyperparameters] == ["alpha", "beta"]
    assert kernel.n_dims == 2
    theta = np.array([np.log(0.7), np.arctanh(-0.9)])
    cloned = kernel.clone_with_theta(theta)
    assert cloned.alpha == pytest.approx(0.7, rel=1e-15)
    assert cloned.beta == pytest.approx(-0.9, rel=1e-15)
    assert kernel.beta == -0.6  # clone_with_theta does not change the original
    assert cloned.get_params()["beta_bounds"] == (-0.95, 0.5)
    np.testing.assert_allclose(cloned.theta, theta, rtol=1e-14)
    kernel.theta = theta
    assert kernel.beta == pytest.approx(-0.9, rel=1e-15)
    with pytest.raises(ValueError, match="theta"):
        kernel.theta = theta[:1]


def test_default_bounds_admit_both_signs():
    bounds = DC().bounds
    assert bounds[1, 0] == pytest.approx(np.arctanh(-0.9999)) and bounds[1, 0] < 0
    assert bounds[1, 1] == pytest.approx(np.arctanh(0.9999)) and np.all(np.isfinite(bounds))


def test_theta_in_composite_kernels():
    kernel = C(2.0) * DC(alpha=0.9, beta=-0.5) + PK(alpha=0.8, omega=1.0)
    expected = np.log([2.0, 0.9, 1.0, 0.8, 1.0, 1.0, 1.0])
    expected[2] = np.arctanh(-0.5)
    np.testing.assert_allclose(kernel.theta, expected, rtol=1e-15)
    theta = kernel.theta
    theta[2] = np.arctanh(-0.8)
    cloned = kernel.clone_with_theta(theta)
    assert cloned.k1.k2.beta == pytest.approx(-0.8, rel=1e-14)
    assert cloned.get_params()["k1__k2__beta"] == pytest.approx(-0.8, rel=1e-14)
    assert kernel.bounds.shape == (7, 2) and np.all(np.isfinite(kernel.bounds))
    assert repr(cloned.k1.k2) == "DC(alpha=0.9, beta=-0.8)"
    assert eval(repr(DC(0.9, -0.8)), {"DC": DC}) == DC(0.9, -0.8)


def test_bound_of_one_is_finite_and_theta_maps_back_below_one():
    kernel = DC(alpha=0.9, beta=0.5, beta_bounds=(0.1, 1.0))
    high = kernel.bounds[1, 1]
    assert np.isfinite(high) and high > 18.0
    cloned = kernel.clone_with_theta(np.array([0.0, high]))
    assert cloned.beta < 1.0
    assert np.isfinite(cloned.theta).all()
    far = kernel.clone_with_theta(np.array([0.0, 40.0]))
    assert far.beta < 1.0 and np.isfinite(far.theta).all()


def test_beta_one_works_fixed_and_is_refused_for_tuning():
    fixed = DC(alpha=0.9, beta=1.0, beta_bounds="fixed")
    X = INTEGER_LAGS[:, None]
    np.testing.assert_allclose(fixed(X), dc_elementwise(INTEGER_LAGS, INTEGER_LAGS, 0.9, 1.0))
    assert fixed.theta.shape == (1,)
    free = DC(alpha=0.9, beta=1.0)
    np.testing.assert_allclose(free(X), fixed(X), rtol=0)  # evaluating is fine
    assert free.n_dims == 2
    with pytest.raises(ValueError, match="beta"):
        free.theta
    rng = np.random.default_rng(0)
    u = rng.standard_normal(60)
    y = np.convolve(u, 0.8 ** np.arange(20))[:60][::3]
    # without tuning (as when a model file is loaded) a free beta = 1 is used as given
    model = FIRGaussianProcess(C(1.0) * DC(0.9, 1.0), factor=3, order=20, optimizer=None)
    model.fit(u, y)
    assert model.kernel_.k2.beta == 1.0
    with pytest.raises(ValueError, match="beta"):
        FIRGaussianProcess(C(1.0) * DC(0.9, 1.0), factor=3, order=20).fit(u, y)


@pytest.mark.parametrize("beta", [-1.0, -1.5, 1.0 + 1e-9, 2.0, np.nan, np.inf])
def test_bad_beta_raises_naming_beta(beta):
    kernel = DC(alpha=0.9, beta=beta)
    with pytest.raises(ValueError, match="beta"):
        kernel(INTEGER_LAGS[:, None])
    with pytest.raises(ValueError, match="beta"):
        kernel.theta
    with pytest.raises(ValueError, match="beta"):
        FIRGaussianProcess(C(1.0) * kernel, factor=3, order=5).fit(np.ones(12), np.ones(4))


@pytest.mark.parametrize("bounds", [(-1.0, 0.5), (-0.5, 1.2), (0.6, 0.2), (np.nan, 0.5), (0.5,)])
def test_bad_beta_bounds_raise_naming_them(bounds):
    kernel = DC(alpha=0.9, beta=0.5, beta_bounds=bounds)
    with pytest.raises(ValueError, match="beta_bounds"):
        kernel.bounds
    with pytest.raises(ValueError, match="beta_bounds"):
        FIRGaussianProcess(C(1.0) * kernel, factor=3, order=5).fit(np.ones(12), np.ones(4))


# -------------------------------------------------------------- fast paths
def operator(n=90, factor=3, order=40, offset=1, seed=0):
    u = np.random.default_rng(seed).standard_normal(n)
    return DownsampledConvolution(u, factor, order, offset), explicit_regressor(u, factor, order, offset)


def dense_contraction_fd(kernel, Phi, W):
    """Finite differences of ``tr(W Phi K(theta) Phi^T)`` in theta."""
    lags = np.arange(Phi.shape[1], dtype=float)[:, None]
    return theta_derivatives(
        lambda th: np.array(np.sum(W * (Phi @ kernel.clone_with_theta(th)(lags) @ Phi.T))),
        kernel.theta,
    )


def dense_derivatives_fd(kernel, Phi):
    lags = np.arange(Phi.shape[1], dtype=float)[:, None]
    return theta_derivatives(lambda th: Phi @ kernel.clone_with_theta(th)(lags) @ Phi.T, kernel.theta)


def forbid_dense(monkeypatch):
    """Make the dense route fail: the structured one must not need it."""
    def refuse(*args, **kwargs):
        raise AssertionError("the dense route was taken")

    monkeypatch.setattr(ObservedTerm, "kernel_with_gradient", refuse)
    monkeypatch.setattr(DownsampledConvolution, "sandwich", refuse)
    monkeypatch.setattr(DownsampledConvolution, "project", refuse)


@pytest.mark.parametrize("beta", NEGATIVE)
def test_filter_route_is_taken_and_equals_dense(beta, monkeypatch):
    kernel = DC(alpha=0.9, beta=beta)
    op, Phi = operator()
    term = observe(kernel, op)
    assert isinstance(term, ShiftScaledTerm) and isinstance(term.other, DCFilterTerm)
    assert term._sampling(True) is None  # the cost model keeps the filters at this size
    lags = np.arange(op.order, dtype=float)
    K = dc_elementwise(lags, lags, 0.9, beta)
    S_dense = Phi @ K @ Phi.T
    W = random_symmetric(op.n_outputs, 2)
    expected_contraction = dense_contraction_fd(kernel, Phi, W)
    expected_derivatives = dense_derivatives_fd(kernel, Phi)
    forbid_dense(monkeypatch)
    scale = np.abs(S_dense).max()
    np.testing.assert_allclose(term.covariance(), S_dense, rtol=1e-10, atol=1e-12 * scale)
    S, contract = term.covariance_with_contractor()
    np.testing.assert_allclose(S, S_dense, rtol=1e-10, atol=1e-12 * scale)
    np.testing.assert_allclose(contract(W), expected_contraction, rtol=1e-6,
                               atol=1e-7 * np.abs(expected_contraction).max())
    S, items = term.covariance_with_derivatives()
    for j, item in enumerate(items):
        np.testing.assert_allclose(item, expected_derivatives[:, :, j], rtol=1e-6,
                                   atol=1e-7 * np.abs(expected_derivatives[:, :, j]).max())
    np.testing.assert_allclose(term.regressor_times_kernel(), Phi @ K, rtol=1e-10,
                               atol=1e-12 * np.abs(Phi @ K).max())
    _, parameter_contract = term.parameter_contractor()
    A = random_symmetric(op.order, 3)
    np.testing.assert_allclose(parameter_contract(A), dense_contraction_fd(kernel, np.eye(op.order), A),
                               rtol=1e-6, atol=1e-8)


@pytest.mark.parametrize("beta", NEGATIVE)
@pytest.mark.parametrize("shape", [(90, 3, 40, 1), (57, 5, 57, 4), (60, 1, 20, 0)])
def test_recursion_route_is_taken_and_equals_dense(beta, shape, monkeypatch):
    kernel = C(1.5) * DC(alpha=0.9, beta=beta)
    op, Phi = operator(*shape)
    lags = np.arange(op.order, dtype=float)
    S_dense = 1.5 * Phi @ dc_elementwise(lags, lags, 0.9, beta) @ Phi.T
    W = random_symmetric(op.n_outputs, 4)
    expected = dense_contraction_fd(kernel, Phi, W)
    inner = kernel.k2
    _, d_inner = observed_recursion(inner, op.uniform_sampling, op.order)
    expected_inner = dense_derivatives_fd(inner, Phi)
    for j, d in enumerate(d_inner):
        np.testing.assert_allclose(d, expected_inner[:, :, j], rtol=1e-6,
                                   atol=1e-7 * np.abs(expected_inner[:, :, j]).max())
    # the recursion wherever it is offered, the filters and the dense route refused
    monkeypatch.setattr(recursion_module, "prefer_recursion", lambda *a, **k: True)
    forbid_dense(monkeypatch)
    for name in ("covariance", "covariance_with_contractor", "covariance_with_derivatives"):
        monkeypatch.setattr(DCFilterTerm, name, lambda self: pytest.fail("filters taken"))
    term = observe(kernel, op)
    S, contract = term.covariance_with_contractor()
    scale = np.abs(S_dense).max()
    np.testing.assert_allclose(S, S_dense, rtol=1e-10, atol=1e-12 * scale)
    np.testing.assert_allclose(term.covariance(), S_dense, rtol=1e-10, atol=1e-12 * scale)
    np.testing.assert_allclose(contract(W), expected, rtol=1e-6, atol=1e-7 * np.abs(expected).max())
    np.testing.assert_allclose(
        inner.right_multiply(Phi), Phi @ dc_elementwise(lags, lags, 0.9, beta), rtol=1e-10, atol=1e-12
    )


def test_long_record_reduction_equals_dense_evidence():
    kernel = C(2.0) * DC(alpha=0.85, beta=-0.7) + PK(alpha=0.9, omega=2.9, sigma1=0.5)
    op, Phi = operator(n=300, factor=3, order=20, offset=0, seed=5)
    y = np.random.default_rng(6).standard_normal(op.n_outputs)
    reduced, _ = reduce_observation(op, y)
    assert isinstance(reduced, ReducedObservation)
    lags = np.arange(op.order, dtype=float)[:, None]
    R = reduced.matrix
    np.testing.assert_allclose(observe(kernel, reduced).covariance(), R @ kernel(lags) @ R.T,
                               rtol=1e-9, atol=1e-12)
    noise = 0.3
    evidence = LogEvidence(op, y, kernel, noise, (1e-3, 10.0))
    assert isinstance(evidence.data, ReducedObservation)

    def dense(theta):
        K = kernel.clone_with_theta(theta[:-1])(lags)
        cov = Phi @ K @ Phi.T + np.exp(theta[-1]) * np.eye(op.n_outputs)
        return np.array(multivariate_normal(np.zeros(op.n_outputs), cov).logpdf(y))

    theta = evidence.theta
    value, grad = evidence(theta, eval_gradient=True)
    assert value == pytest.approx(float(dense(theta)), rel=1e-10)
    np.testing.assert_allclose(grad, theta_derivatives(dense, theta), rtol=1e-5, atol=1e-6)
    _, grad_fisher, _ = evidence.with_fisher(theta)
    np.testing.assert_allclose(grad_fisher, grad, rtol=1e-9, atol=1e-9)


def test_several_inputs_equal_dense():
    rng = np.random.default_rng(7)
    u = rng.standard_normal((90, 2))
    y = rng.standard_normal(30)
    experiment = build_experiment(u, y, factor=3, order=15)
    obs = experiment.observation
    kernel = PerInputKernel([C(1.3) * DC(0.9, -0.6), DC(0.8, 0.5)])
    lags = np.arange(15.0)
    K = linalg.block_diag(1.3 * dc_elementwise(lags, lags, 0.9, -0.6), dc_elementwise(lags, lags, 0.8, 0.5))
    Phi = np.hstack([explicit_regressor(u[:, 0], 3, 15), explicit_regressor(u[:, 1], 3, 15)])
    np.testing.assert_allclose(obs.matrix, Phi)
    term = observe(kernel, obs)
    S, contract = term.covariance_with_contractor()
    np.testing.assert_allclose(S, Phi @ K @ Phi.T, rtol=1e-10, atol=1e-12)
    W = random_symmetric(obs.n_outputs, 8)

    def trace(theta):
        fitted = kernel.clone_with_theta(theta)
        blocks = [k(lags[:, None]) for k in fitted.kernels]
        return np.array(np.sum(W * (Phi @ linalg.block_diag(*blocks) @ Phi.T)))

    numeric = theta_derivatives(trace, kernel.theta)
    np.testing.assert_allclose(contract(W), numeric, rtol=1e-6, atol=1e-7 * np.abs(numeric).max())


# ----------------------------------------------------------------- tuning
def alternating_problem(kind, seed=0, n=300, factor=3, order=40):
    rng = np.random.default_rng(seed)
    k = np.arange(order)
    if kind == "alternating":
        g = 0.9**k * (-0.6) ** k
    else:  # a resonance near the fast Nyquist frequency
        g = 0.9**k * np.cos(0.9 * np.pi * k)
    u, u_val = rng.standard_normal(n), rng.standard_normal(n)
    y = np.convolve(u, g)[:n][::factor]
    y = y + 0.1 * np.std(y) * rng.standard_normal(y.shape)
    return g, u, y, u_val, np.convolve(u_val, g)[:n]


@pytest.mark.parametrize("kind", ["alternating", "nyquist"])
def test_tuning_finds_a_negative_beta_and_beats_positive_only(kind):
    g, u, y, u_val, y_val = alternating_problem(kind)
    fits = {}
    for label, bounds in (("signed", (-0.9999, 0.9999)), ("positive", (1e-4, 0.9999))):
        model = FIRGaussianProcess(C(1.0) * DC(0.9, 0.5, beta_bounds=bounds), factor=3, order=40)
        fits[label] = model.fit(u, y)
    signed, positive = fits["signed"], fits["positive"]
    assert signed.kernel_.k2.beta < -0.5
    assert signed.log_marginal_likelihood_value_ > positive.log_marginal_likelihood_value_ + 5.0
    error = {k: np.linalg.norm(m.coef_ - g) / np.linalg.norm(g) for k, m in fits.items()}
    assert error["signed"] < error["positive"]
    gof = {k: gm.goodness_of_fit(y_val, m.predict(u_val)) for k, m in fits.items()}
    assert gof["signed"] > gof["positive"]
    # the evidence gradient at the optimum and away from it, against finite differences
    theta = signed._evidence.theta
    for point in (theta, theta + 0.1):
        _, grad = signed.log_marginal_likelihood(point, eval_gradient=True)
        numeric = theta_derivatives(lambda th: np.array(signed.log_marginal_likelihood(th)), point)
        np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-5 * max(1.0, np.abs(numeric).max()))


def test_sklearn_regressor_with_observed_kernel_tunes_negative_beta():
    _, u, y, _, _ = alternating_problem("nyquist", n=150, order=30)
    op = DownsampledConvolution(u, 3, 30)
    X = np.arange(op.n_outputs)[:, None]
    kernel = ObservedKernel(C(1.0) * DC(0.9, 0.3), op) + WhiteKernel(1e-2, (1e-6, 1.0))
    gpr = GaussianProcessRegressor(kernel, n_restarts_optimizer=2, random_state=0).fit(X, y)
    assert gpr.kernel_.k1.kernel.k2.beta < -0.5
    theta = gpr.kernel_.theta
    value, grad = gpr.log_marginal_likelihood(theta, eval_gradient=True)
    numeric = theta_derivatives(lambda th: np.array(gpr.log_marginal_likelihood(th)), theta)
    np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-5 * max(1.0, np.abs(numeric).max()))
    # the same theta means the same evidence in gpmultirate (noise last, in log)
    evidence = LogEvidence(op, y, clone(gpr.kernel_.k1.kernel), 1e-2, (1e-6, 1.0))
    assert evidence(theta) == pytest.approx(value, rel=1e-9)


# ------------------------------------------------------------ persistence
def test_negative_beta_model_round_trips(tmp_path):
    _, u, y, u_val, _ = alternating_problem("nyquist", n=150, order=30)
    model = FIRGaussianProcess(C(1.0) * DC(0.9, -0.5) + PK(0.9, 2.8), factor=3, order=30).fit(u, y)
    assert model.kernel_.k1.k2.beta < 0
    path = tmp_path / "negative.npz"
    save_model(model, path)
    loaded = load_model(path)
    assert loaded.kernel_.k1.k2.beta == model.kernel_.k1.k2.beta
    np.testing.assert_allclose(loaded.predict(u_val), model.predict(u_val), rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("name", ["tuned", "beta_1"])
def test_files_written_before_the_artanh_coordinate_load_and_predict_the_same(name):
    # written by gpmultirate 0.1.0 with beta in (0, 1] tuned in log(beta); "beta_1"
    # holds a free beta = 1
    stored = np.load(DATA / "model_dc_v0_1_predictions.npz")
    loaded = load_model(DATA / f"model_dc_{name}_v0_1.npz")
    beta = loaded.kernel_.k1.k2.beta if name == "tuned" else loaded.kernel_.k2.beta
    assert 0.0 < beta <= 1.0
    np.testing.assert_allclose(loaded.coef_, stored[name + "_coef"], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(loaded.predict(stored["u"]), stored[name], rtol=1e-12, atol=1e-15)
