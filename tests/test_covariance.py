"""The data covariance objects against dense closed forms.

Every route of :func:`gpmultirate.covariance.data_covariance` (dense,
Woodbury update, DC's precision, the parameter space of a reduced record) is
checked against ``Phi K Phi^T + gamma I`` formed and solved densely:
``solve``, the quadratic form and the log-determinant, the log density
(scipy's), the gradient by central differences, the Fisher information by its
trace formula, and the remainder of a reduced record against the likelihood
of the full record.
"""

import numpy as np
import pytest
from scipy.stats import multivariate_normal
from sklearn.gaussian_process.kernels import RBF
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate.covariance import (
    DenseCovariance,
    DiagonalPlusLowRank,
    ParameterSpaceCovariance,
    PrecisionCovariance,
    Remainder,
    SpectralCovariance,
    WoodburyCovariance,
    data_covariance,
    takes_precision_route,
)
from gpmultirate.inference import DataSpacePosterior, LogEvidence
from gpmultirate.noise import WhiteNoise
from gpmultirate.kernels import DC, PK, TC, observe
from gpmultirate.observations import reduce_observation

NOISE = 0.05


def problem(n, factor, order, seed=0):
    rng = np.random.default_rng(seed)
    op = gm.DownsampledConvolution(rng.standard_normal(n), factor, order)
    g = 0.85 ** np.arange(order) * np.cos(0.6 * np.arange(order))
    return op, op.matvec(g) + 0.2 * rng.standard_normal(op.n_outputs), rng


def dense_ky(op, kernel, noise=NOISE):
    Phi = op.matrix
    return Phi @ kernel(op.lags) @ Phi.T + noise * np.eye(op.n_outputs)


def close(found, expected, rtol=1e-8):
    expected = np.asarray(expected)
    np.testing.assert_allclose(found, expected, rtol=rtol,
                               atol=rtol * max(np.abs(expected).max(), 1e-300))


def check_answers(covariance, op, kernel, y, rng, noise=NOISE, rtol=1e-8):
    """solve, inv_quad_logdet and the log density against ``Ky`` formed densely."""
    Ky = dense_ky(op, kernel, noise)
    b = rng.standard_normal((op.n_outputs, 3))
    close(covariance.solve(b), np.linalg.solve(Ky, b), rtol)
    close(covariance.solve(y), np.linalg.solve(Ky, y), rtol)
    quadratic, log_det = covariance.inv_quad_logdet(y)
    assert quadratic == pytest.approx(y @ np.linalg.solve(Ky, y), rel=rtol)
    assert log_det == pytest.approx(np.linalg.slogdet(Ky)[1], rel=rtol, abs=rtol)
    expected = multivariate_normal(np.zeros(op.n_outputs), Ky).logpdf(y)
    assert covariance.log_likelihood(y) == pytest.approx(expected, rel=rtol)


def numeric_gradient(kernel, op, y, noise, step=1e-6):
    """Central differences of the dense log density in the kernel's theta and log(noise)."""
    def value(theta):
        Ky = dense_ky(op, kernel.clone_with_theta(theta[:-1]), np.exp(theta[-1]))
        return -0.5 * (y @ np.linalg.solve(Ky, y) + np.linalg.slogdet(Ky)[1]
                       + y.shape[0] * np.log(2.0 * np.pi))

    theta = np.append(kernel.theta, np.log(noise))
    return np.array([(value(theta + step * e) - value(theta - step * e)) / (2 * step)
                     for e in np.eye(theta.shape[0])])


@pytest.mark.parametrize("kernel", [RBF(3.0), TC(0.8), C(1.3) * DC(0.8, 0.9) + PK(0.9, 0.5)],
                         ids=["RBF", "TC", "DC+PK"])
def test_dense_route_against_the_closed_form(kernel):
    op, y, rng = problem(60, 3, 30)  # M = 20 < P
    covariance = data_covariance(kernel, op, WhiteNoise(NOISE))
    assert type(covariance) is DenseCovariance
    check_answers(covariance, op, kernel, y, rng)
    close(covariance.inverse(), np.linalg.inv(dense_ky(op, kernel)))
    assert covariance.observation is op and covariance.kernel is kernel


@pytest.mark.parametrize("kernel", [TC(0.8), C(1.3) * DC(0.8, 0.9) + PK(0.9, 0.5)],
                         ids=["TC", "DC+PK"])
def test_dense_gradient_and_fisher(kernel):
    op, y, _ = problem(60, 3, 30)
    noise = WhiteNoise(NOISE, (1e-6, 1.0))
    value, grad = data_covariance(kernel, op, noise, "contraction").log_likelihood_gradient(y)
    expected = multivariate_normal(np.zeros(op.n_outputs), dense_ky(op, kernel)).logpdf(y)
    assert value == pytest.approx(expected, rel=1e-10)
    numeric = numeric_gradient(kernel, op, y, NOISE)
    close(grad, numeric, rtol=1e-5)
    f_value, f_grad, fisher = data_covariance(kernel, op, noise, "matrices").log_likelihood_fisher(y)
    assert f_value == pytest.approx(value, rel=1e-12)
    close(f_grad, grad)
    # F_jk = 1/2 tr(Ky^{-1} dKy_j Ky^{-1} dKy_k), dKy by differences of the dense matrix
    theta = np.append(kernel.theta, np.log(NOISE))
    step = 1e-6

    def ky(t):
        return dense_ky(op, kernel.clone_with_theta(t[:-1]), np.exp(t[-1]))

    inverse = np.linalg.inv(ky(theta))
    V = [inverse @ (ky(theta + step * e) - ky(theta - step * e)) / (2 * step)
         for e in np.eye(theta.shape[0])]
    expected_fisher = np.array([[0.5 * np.trace(a @ b) for b in V] for a in V])
    close(fisher, expected_fisher, rtol=1e-5)


def test_a_fixed_noise_level_has_no_gradient_entry():
    op, y, _ = problem(60, 3, 30)
    kernel = TC(0.8)
    _, grad = data_covariance(kernel, op, WhiteNoise(NOISE), "contraction").log_likelihood_gradient(y)
    assert grad.shape == kernel.theta.shape


def test_woodbury_update_is_the_dense_covariance_with_the_summand():
    op, y, rng = problem(90, 3, 30)
    base_kernel = C(1.3) * DC(0.8, 0.9)
    base = data_covariance(base_kernel, op, WhiteNoise(NOISE), space="posterior")
    assert type(base) is DenseCovariance  # M = 30 = P but not a reduction
    candidates = [PK(0.9, omega) for omega in (0.4, 1.1, 2.3)]
    factors = [observe(k, op).low_rank() for k in candidates]
    U = op.matrix @ np.column_stack([basis for basis, _ in factors])
    updates = base.plus_low_rank(U, [weight for _, weight in factors])
    for update, candidate in zip(updates, candidates):
        assert isinstance(update, WoodburyCovariance)
        check_answers(update, op, base_kernel + candidate, y, rng)


@pytest.mark.parametrize("constant, alpha, beta", [(1.0, 0.85, 0.6), (2.5, 0.9, -0.6)])
def test_precision_route_of_square_data(constant, alpha, beta):
    op, y, rng = problem(60, 2, 30)  # M = P = 30
    kernel = C(constant) * DC(alpha, beta)
    assert takes_precision_route(kernel, op, WhiteNoise(NOISE))
    covariance = data_covariance(kernel, op, WhiteNoise(NOISE, (1e-6, 1.0)), "contraction")
    assert type(covariance) is PrecisionCovariance
    check_answers(covariance, op, kernel, y, rng, rtol=1e-7)
    value, grad = covariance.log_likelihood_gradient(y)
    assert value == pytest.approx(covariance.log_likelihood(y), rel=1e-12)
    close(grad, numeric_gradient(kernel, op, y, NOISE), rtol=1e-5)
    # the dense route gives the same gradient
    dense = DenseCovariance.of(kernel, op, WhiteNoise(NOISE, (1e-6, 1.0)), "contraction")
    close(grad, dense.log_likelihood_gradient(y)[1], rtol=1e-7)


def test_precision_route_needs_a_precision_and_falls_back_when_not_definite(monkeypatch):
    from gpmultirate.covariance import precision as module
    from gpmultirate.exceptions import NotPositiveDefinite

    op, y, rng = problem(60, 2, 30)
    assert not takes_precision_route(TC(0.8), op, WhiteNoise(NOISE))
    assert type(data_covariance(TC(0.8), op, WhiteNoise(NOISE))) is DenseCovariance

    def fails(C, **options):
        raise NotPositiveDefinite("C")

    monkeypatch.setattr(module, "cholesky_or_raise", fails)
    kernel = C(1.0) * DC(0.85, 0.6)
    covariance = data_covariance(kernel, op, WhiteNoise(NOISE))
    assert type(covariance) is DenseCovariance
    check_answers(covariance, op, kernel, y, rng)


@pytest.mark.parametrize("kernel, data_route, posterior_route", [
    (C(1.0) * DC(0.85, 0.6), PrecisionCovariance, PrecisionCovariance),
    (TC(0.8), DenseCovariance, ParameterSpaceCovariance),
    (C(1.3) * DC(0.8, 0.9) + PK(0.9, 0.5), DenseCovariance, ParameterSpaceCovariance),
], ids=["DC", "TC", "DC+PK"])
def test_reduced_record_with_its_remainder_is_the_full_record(kernel, data_route,
                                                              posterior_route):
    op, y, rng = problem(180, 3, 20)  # M = 60 > P = 20
    data, z = reduce_observation(op, y)
    full = multivariate_normal(np.zeros(op.n_outputs), dense_ky(op, kernel)).logpdf(y)
    noise = WhiteNoise(NOISE, (1e-6, 1.0))
    assert noise.remainder(data).n == op.n_outputs - op.order
    # the reduced part alone: z ~ N(0, R K R^T + gamma I)
    R = data.matrix
    Kz = R @ kernel(op.lags) @ R.T + NOISE * np.eye(op.order)
    for space, route in (("data", data_route), ("posterior", posterior_route)):
        covariance = data_covariance(kernel, data, noise, space=space)
        assert type(covariance) is route
        assert covariance.log_likelihood(z) == pytest.approx(full, rel=1e-10)
        quadratic, log_det = covariance.inv_quad_logdet(z)
        assert quadratic == pytest.approx(z @ np.linalg.solve(Kz, z), rel=1e-8)
        assert log_det == pytest.approx(np.linalg.slogdet(Kz)[1], rel=1e-8)
        close(covariance.solve(z), np.linalg.solve(Kz, z), rtol=1e-7)
    # the gradient of the reduced evidence with its remainder is the full record's
    value, grad = data_covariance(kernel, data, noise, "contraction").log_likelihood_gradient(z)
    assert value == pytest.approx(full, rel=1e-10)
    close(grad, numeric_gradient(kernel, op, y, NOISE), rtol=1e-5)


def test_remainder_against_independent_gaussians():
    rng = np.random.default_rng(1)
    e = rng.standard_normal(7)
    gamma = 0.3
    value, grad, fisher = Remainder(7, e @ e, gamma).log_likelihood()
    assert value == pytest.approx(multivariate_normal(np.zeros(7), gamma * np.eye(7)).logpdf(e))
    step = 1e-6
    up = Remainder(7, e @ e, gamma * np.exp(step)).log_likelihood()[0]
    down = Remainder(7, e @ e, gamma * np.exp(-step)).log_likelihood()[0]
    assert grad == pytest.approx((up - down) / (2 * step), rel=1e-6)
    assert fisher == 3.5  # n / 2: the expected negative second derivative in log(gamma)
    assert Remainder(0, 0.0, gamma).log_likelihood() == (0.0, 0.0, 0.0)


def test_white_noise_enters_theta_through_itself():
    noise = WhiteNoise(0.1, (1e-4, 1.0))
    assert noise.is_free and noise.white
    np.testing.assert_allclose(noise.theta, [np.log(0.1)])
    np.testing.assert_allclose(noise.bounds, [[np.log(1e-4), 0.0]])
    assert noise.with_theta(np.log([0.5])).level == pytest.approx(0.5)
    fixed = WhiteNoise(0.1)
    assert fixed.theta.shape == (0,) and fixed.bounds.shape == (0, 2)
    assert fixed.with_theta(np.empty(0)) is fixed
    W = np.random.default_rng(2).standard_normal((4, 4))
    np.testing.assert_allclose(noise.contract(W, 0.5), [0.5 * np.trace(W) * 0.1])
    assert fixed.contract(W).shape == (0,)
    S = np.ones((3, 3))
    noise.add_to(S)
    np.testing.assert_allclose(S, np.ones((3, 3)) + 0.1 * np.eye(3))


def test_evidence_theta_carries_the_noise_model():
    op, y, _ = problem(60, 3, 30)
    evidence = LogEvidence(op, y, TC(0.8), 0.05, (1e-4, 1.0))
    np.testing.assert_allclose(evidence.theta, np.append(TC(0.8).theta, np.log(0.05)))
    np.testing.assert_allclose(evidence.bounds[-1], np.log([1e-4, 1.0]))
    kernel, noise_level = evidence.split(np.append(TC(0.7).theta, np.log(0.2)))
    assert noise_level == pytest.approx(0.2) and kernel.alpha == pytest.approx(0.7)
    moved = evidence.moved_to(TC(0.6), 0.3)
    assert moved.noise_level == 0.3 and moved.noise_bounds == (1e-4, 1.0)


def test_posterior_answers_from_what_it_holds():
    op, y, _ = problem(60, 3, 30)
    kernel = TC(0.8)
    result = DataSpacePosterior(data_covariance(kernel, op, WhiteNoise(NOISE)), y)
    assert result.observation is op and result.kernel is kernel
    X = np.array([[0.5], [3.25], [10.0]])
    Phi, K = op.matrix, kernel(op.lags)
    Ky = dense_ky(op, kernel)
    cross = kernel(X, op.lags) @ Phi.T
    mean = cross @ np.linalg.solve(Ky, y)
    cov = kernel(X) - cross @ np.linalg.solve(Ky, cross.T)
    close(result.mean_at_lags(X), mean)
    found_mean, found_cov = result.at_lags(X, full_cov=True)
    close(found_mean, mean)
    close(found_cov, cov, rtol=1e-7)
    close(result.at_lags(X)[1], np.diag(cov), rtol=1e-7)


def test_the_data_space_posterior_makes_the_priors_matrix_when_asked_for_it():
    # the mean needs Phi K alone: a pilot fit never holds the P x P K
    op, y, _ = problem(60, 3, 30)
    kernel = TC(0.8)
    made = []
    covariance = data_covariance(kernel, op, WhiteNoise(NOISE))
    making = covariance.term.kernel_matrix
    covariance.term.kernel_matrix = lambda: made.append(1) or making()
    result = DataSpacePosterior(covariance, y)
    Ky = dense_ky(op, kernel)
    close(result.coef, kernel(op.lags) @ op.matrix.T @ np.linalg.solve(Ky, y))
    assert made == []
    K = kernel(op.lags)
    close(result.K, K)
    close(result.covariance(), K - K @ op.matrix.T @ np.linalg.solve(Ky, op.matrix @ K),
          rtol=1e-7)
    assert made == [1]  # made once


def test_spectral_covariance_matches_the_dense_matrix_for_any_scale_and_noise():
    rng = np.random.default_rng(11)
    A = rng.standard_normal((12, 5))
    S = A @ A.T  # rank 5: eigenvalues at zero are clipped, not negative
    y = rng.standard_normal(12)
    W = rng.standard_normal((12, 2))
    spectral = SpectralCovariance(S, y)
    assert np.all(spectral.eigenvalues >= 0.0)
    for scale, noise in [(1.0, 0.1), (3.7, 1e-3), (0.02, 2.0)]:
        dense = scale * S + noise * np.eye(12)
        d = spectral.diagonal(scale, noise)
        np.testing.assert_allclose(np.sum(spectral.rotated_y**2 / d),
                                   y @ np.linalg.solve(dense, y), rtol=1e-10)
        np.testing.assert_allclose(np.sum(np.log(d)), np.linalg.slogdet(dense)[1], rtol=1e-10)
        # a low-rank summand in the rotated coordinates: Woodbury and the determinant lemma
        V = spectral.rotate(W)
        updated = dense + W @ W.T
        quad, log_det = DiagonalPlusLowRank(d, V).inv_quad_logdet(spectral.rotated_y)
        np.testing.assert_allclose(log_det, np.linalg.slogdet(updated)[1], rtol=1e-10)
        np.testing.assert_allclose(quad, y @ np.linalg.solve(updated, y), rtol=1e-10)


@pytest.mark.parametrize("identity", [False, True], ids=["diagonal", "identity"])
def test_diagonal_plus_low_rank_answers_as_the_dense_matrix(identity):
    from gpmultirate.covariance import woodbury_gain

    rng = np.random.default_rng(5)
    M, r = 9, 3
    d = None if identity else rng.uniform(0.5, 2.0, M)
    W, y, B = rng.standard_normal((M, r)), rng.standard_normal(M), rng.standard_normal((M, 2))
    D = np.eye(M) if identity else np.diag(d)
    A = D + W @ W.T
    update = DiagonalPlusLowRank(d, W)
    quad, log_det = update.inv_quad_logdet(y)
    assert quad == pytest.approx(y @ np.linalg.solve(A, y), rel=1e-12)
    assert log_det == pytest.approx(np.linalg.slogdet(A)[1], rel=1e-12, abs=1e-12)
    np.testing.assert_allclose(update.solve(B), np.linalg.solve(A, B), rtol=1e-10)
    inverse = np.linalg.inv(A)
    np.testing.assert_allclose(update.inverse_diagonal(), np.diag(inverse), rtol=1e-10)
    np.testing.assert_allclose(update.inverse_times_low_rank(), inverse @ W, rtol=1e-9,
                               atol=1e-12)
    # the evidence gain of the summand, from its capacitance's spectrum
    DW = np.linalg.solve(D, W)
    eigenvalues, vectors = np.linalg.eigh(W.T @ DW)
    gain = woodbury_gain(eigenvalues, (vectors.T @ (DW.T @ y)) ** 2)
    reference = (multivariate_normal(np.zeros(M), A).logpdf(y)
                 - multivariate_normal(np.zeros(M), D).logpdf(y))
    assert gain == pytest.approx(reference, rel=1e-10)


def test_the_layer_asks_no_object_for_its_type():
    """The routes are chosen by the noise models: no probes or type checks in the layer."""
    import inspect
    import pathlib
    import re

    import gpmultirate.covariance as layer

    for path in pathlib.Path(layer.__file__).parent.glob("*.py"):
        source = path.read_text(encoding="utf-8")
        assert not re.search(r"\b(hasattr|getattr)\(|\btype\([^)]*\) is\b", source), path.name
    for name in ("DenseCovariance", "PrecisionCovariance", "ParameterSpaceCovariance",
                 "AR1Covariance"):
        assert "def posterior" in inspect.getsource(getattr(layer, name))


def test_bad_route_requests_are_refused():
    from gpmultirate.covariance import fisher_covariance
    from gpmultirate.noise import HeteroscedasticNoise

    op, y, _ = problem(60, 2, 30)
    with pytest.raises(ValueError, match="space"):
        data_covariance(TC(0.8), op, WhiteNoise(NOISE), space="parameters")
    with pytest.raises(ValueError, match="derivatives"):
        data_covariance(TC(0.8), op, WhiteNoise(NOISE), derivatives="hessian")
    # the Fisher information needs the noise's derivative matrices: white noise and a
    # kernel over the instants give them, the heteroscedastic model does not
    with pytest.raises(ValueError, match="Fisher information is not offered"):
        fisher_covariance(TC(0.8), op, HeteroscedasticNoise(np.ones(op.n_outputs), NOISE))
    assert type(fisher_covariance(C(1.0) * DC(0.8, 0.5), op, WhiteNoise(NOISE))) \
        is DenseCovariance
