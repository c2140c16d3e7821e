"""Noise models: kernel disturbances against direct kernel evaluations and finite
differences, the AR(1) structure against the dense Matérn 1/2 matrices, the structured
evidence against the dense formulas, and the measurement band by Monte Carlo."""

import numpy as np
import pytest
from scipy import linalg, stats
from sklearn.gaussian_process.kernels import (
    RBF,
    ConstantKernel as C,
    ExpSineSquared,
    Matern,
    WhiteKernel,
)

from gpmultirate import DownsampledConvolution
from gpmultirate.kernels import DC
from gpmultirate.noise import (
    AR1Noise,
    AR1Statistics,
    KernelNoise,
    ar1_log_evidence,
    dense_log_evidence,
    dense_posterior,
    white_level,
)


def _fd(f, theta, step=1e-6):
    out = []
    for j in range(theta.shape[0]):
        e = np.zeros_like(theta)
        e[j] = step
        out.append((f(theta + e) - f(theta - e)) / (2 * step))
    return np.array(out)


# ------------------------------------------------------------ KernelNoise
def test_kernel_noise_matrix_is_the_kernel_at_the_instants_block_diagonal_per_record():
    kernel = WhiteKernel(0.2) + C(1.5) * Matern(7.0, nu=1.5)
    t1, t2 = np.arange(5) * 3.0 + 1, np.arange(4) * 3.0
    noise = KernelNoise(kernel, [t1, t2])
    N = noise.matrix()
    r = np.abs(t1[:, None] - t1[None, :]) * np.sqrt(3) / 7.0
    matern = 1.5 * (1 + r) * np.exp(-r)
    np.testing.assert_allclose(N[:5, :5], matern + 0.2 * np.eye(5), rtol=1e-12)
    assert np.all(N[:5, 5:] == 0) and np.all(N[5:, :5] == 0)
    assert noise.n_samples == 9 and noise.level == pytest.approx(0.2)
    assert noise.sample_variance() == pytest.approx(1.7)
    np.testing.assert_allclose(noise.theta, np.log([0.2, 1.5, 7.0]))
    assert noise.is_free and not noise.white
    moved = noise.with_theta(np.log([0.3, 2.0, 5.0]))
    assert moved.level == pytest.approx(0.3) and moved.kernel.k2.k2.length_scale == pytest.approx(5)
    assert noise.kernel.k1.noise_level == 0.2  # unchanged


def test_kernel_noise_derivatives_and_contraction_against_finite_differences():
    kernel = WhiteKernel(0.1) + C(2.0) * ExpSineSquared(3.0, 12.0) + C(0.5) * Matern(20.0,
                                                                                       nu=0.5)
    noise = KernelNoise(kernel, np.arange(0, 60, 3.0))
    theta = noise.theta
    N, dN = noise.matrix_with_gradient()
    for j in range(theta.shape[0]):
        e = np.zeros_like(theta)
        e[j] = 1e-6
        numeric = (noise.with_theta(theta + e).matrix() - noise.with_theta(theta - e).matrix())
        np.testing.assert_allclose(dN[:, :, j], numeric / 2e-6, atol=1e-7)
        np.testing.assert_array_equal(noise.derivatives()[j], dN[:, :, j])
    W = np.random.default_rng(0).standard_normal(N.shape)
    W = W + W.T
    np.testing.assert_allclose(noise.contract(W, 0.5),
                               [0.5 * np.trace(W @ dN[:, :, j]) for j in range(len(theta))],
                               rtol=1e-12)
    S = np.eye(N.shape[0])
    assert noise.add_to(S) is S
    np.testing.assert_allclose(S, np.eye(N.shape[0]) + N)
    assert noise.structure() is None  # periodic: the dense route


@pytest.mark.parametrize("nu", [0.5, 1.5])
@pytest.mark.parametrize("bounds", [((1e-5, 1.0), (1e-5, 1.0), (1.0, 1e4)),
                                    ("fixed", (1e-5, 1.0), (1.0, 1e4)),
                                    ((1e-5, 1.0), "fixed", "fixed"),
                                    ("fixed", "fixed", "fixed")])
@pytest.mark.parametrize("records", [1, 2])
def test_named_disturbances_in_closed_form_against_scikit_learn_and_finite_differences(
        nu, bounds, records, monkeypatch):
    """The named disturbances' form (white noise plus ``C * Matern(nu)``, nu 1/2 or 3/2) takes
    its matrix and gradient from the records' distances, and its moved kernel is built
    directly: the same values as scikit-learn's kernel, gradient and ``clone_with_theta``,
    and the gradient that of central differences of the dense formula."""
    rng = np.random.default_rng(records)
    instants = [np.sort(rng.uniform(0.0, 300.0, 40)), 3.0 * np.arange(25) + 1.0][:records]
    white, constant, scale = bounds
    kernel = WhiteKernel(0.1, white) + C(0.7, constant) * Matern(7.3, scale, nu=nu)
    theta = kernel.theta + rng.normal(size=kernel.theta.shape)
    noise = KernelNoise(kernel, instants).with_theta(theta)
    reference = kernel.clone_with_theta(theta)
    assert repr(noise.kernel) == repr(reference)
    np.testing.assert_array_equal(noise.kernel.theta, reference.theta)
    np.testing.assert_array_equal(noise.kernel.bounds, reference.bounds)
    import gpmultirate.noise.kernel

    def generic(*args):
        raise AssertionError("the named form went through scikit-learn's evaluation")

    monkeypatch.setattr(gpmultirate.noise.kernel, "kernel_blocks", generic)
    N, dN = noise.matrix_with_gradient()
    blocks = [reference(t[:, None], eval_gradient=True) for t in instants]
    np.testing.assert_allclose(N, linalg.block_diag(*(b for b, _ in blocks)), rtol=1e-13,
                               atol=1e-15)
    assert dN.shape == N.shape + (theta.shape[0],)

    def dense(theta):  # Matern from its formula, records independent
        values = dict(zip([h.name for h in kernel.hyperparameters if not h.fixed],
                          np.exp(theta)))
        w = values.get("k1__noise_level", 0.1)
        c = values.get("k2__k1__constant_value", 0.7)
        length = values.get("k2__k2__length_scale", 7.3)
        out = []
        for t in instants:
            r = np.abs(t[:, None] - t[None, :]) / length
            shape = np.exp(-r) if nu == 0.5 else (1 + np.sqrt(3) * r) * np.exp(-np.sqrt(3) * r)
            out.append(w * np.eye(t.shape[0]) + c * shape)
        return linalg.block_diag(*out)

    np.testing.assert_allclose(dense(theta), N, rtol=1e-12, atol=1e-15)
    for j in range(theta.shape[0]):
        e = np.zeros_like(theta)
        e[j] = 1e-6
        numeric = (dense(theta + e) - dense(theta - e)) / 2e-6
        np.testing.assert_allclose(dN[:, :, j], numeric, atol=1e-7)
        start = 0
        for t, (_, gradient) in zip(instants, blocks):
            stop = start + t.shape[0]
            np.testing.assert_allclose(dN[start:stop, start:stop, j], gradient[:, :, j],
                                       rtol=1e-12, atol=1e-15)
            start = stop
    with pytest.raises(ValueError, match="theta must have"):
        KernelNoise(kernel, instants).with_theta(np.zeros(theta.shape[0] + 1))


def test_kernel_noise_checks_its_arguments():
    with pytest.raises(ValueError, match="kernel"):
        KernelNoise("matern", np.arange(3.0))
    with pytest.raises(ValueError, match="instants"):
        KernelNoise(RBF(), np.array([[0.0, 1.0]]))
    with pytest.raises(ValueError, match="instants"):
        KernelNoise(RBF(), np.array([0.0, np.nan]))


def test_white_level_walks_sums_only():
    assert white_level(WhiteKernel(0.1) + WhiteKernel(0.2)) == pytest.approx(0.3)
    assert white_level(C(2.0) * Matern()) == 0.0


# -------------------------------------------------------------- AR(1)
def test_ar1_is_matern_half_on_a_uniform_grid():
    instants = [np.arange(7) * 3.0, np.arange(1) * 3.0, 30 + np.arange(4) * 3.0]
    kernel = C(1.7) * Matern(5.0, nu=0.5)
    ar1 = KernelNoise(kernel, instants).structure()
    assert isinstance(ar1, AR1Noise)
    N = KernelNoise(kernel, instants).matrix()
    np.testing.assert_allclose(ar1.matrix(), N, rtol=1e-12)
    Q = ar1.precision_matrix()
    np.testing.assert_allclose(Q, np.linalg.inv(N), rtol=1e-9, atol=1e-12)
    off = np.diag(Q, 1)
    assert np.count_nonzero(Q - np.diag(np.diag(Q)) - np.diag(off, 1) - np.diag(off, -1)) == 0
    assert ar1.log_det() == pytest.approx(np.linalg.slogdet(N)[1], rel=1e-12)
    W = ar1.whiten(np.eye(12))
    np.testing.assert_allclose(W @ N @ W.T, ar1.innovation_variance * np.eye(12), atol=1e-12)
    assert ar1.pole == pytest.approx(np.exp(-3.0 / 5.0))
    np.testing.assert_allclose(ar1.theta, kernel.theta)
    np.testing.assert_allclose(ar1.with_theta(np.log([2.0, 9.0])).matrix(),
                               KernelNoise(C(2.0) * Matern(9.0, nu=0.5), instants).matrix(),
                               rtol=1e-12)


@pytest.mark.parametrize("kernel, instants", [
    (C(1.0) * Matern(5.0, nu=1.5), np.arange(5) * 3.0),
    (WhiteKernel(0.1) + C(1.0) * Matern(5.0, nu=0.5), np.arange(5) * 3.0),
    (C(1.0) * Matern(5.0, nu=0.5), np.array([0.0, 3.0, 7.0])),
    (C(1.0) * Matern(5.0, nu=0.5), [np.arange(3) * 3.0, np.arange(3) * 2.0]),
])
def test_ar1_structure_only_where_it_is_exact(kernel, instants):
    assert AR1Noise.from_kernel(kernel, instants) is None


def test_ar1_plain_matern_and_fixed_parameters():
    ar1 = AR1Noise.from_kernel(Matern(4.0, (1.0, 100.0), nu=0.5), np.arange(6) * 2.0)
    assert ar1.variance == 1.0 and ar1.theta.tolist() == [np.log(4.0)]
    assert ar1.bounds.shape == (1, 2)
    with pytest.raises(ValueError, match="n_samples"):
        AR1Noise(1.0, 2.0, 1.0, [3, 0])


def _problem(rng, M_records=(80,), factor=3, order=25):
    """A regressor whose rows are split into records by the noise model only."""
    op = DownsampledConvolution(rng.standard_normal(sum(M_records) * factor), factor, order)
    return op.matrix, op.lags


@pytest.mark.parametrize("counts", [(80,), (50, 1, 30)])
def test_ar1_evidence_and_gradient_against_dense_formulas(counts):
    rng = np.random.default_rng(1)
    Phi, lags = _problem(rng, counts)
    kernel = C(0.8) * DC(0.85, 0.3)
    K, dK = kernel(lags, eval_gradient=True)
    instants = []
    for n in counts:
        instants.append(np.arange(n) * 3.0)
    noise_kernel = C(0.3) * Matern(8.0, nu=0.5)
    dense_noise = KernelNoise(noise_kernel, instants)
    N, dN = dense_noise.matrix_with_gradient()
    y = Phi @ (0.8 ** np.arange(25)) + rng.multivariate_normal(np.zeros(N.shape[0]), N)
    ar1 = dense_noise.structure()
    statistics = AR1Statistics(Phi, y, counts)
    value, grad = ar1_log_evidence(statistics, K, ar1, dK, eval_gradient=True)
    ref_value, ref_grad = dense_log_evidence(Phi, K, y, N, dK, dN, eval_gradient=True)
    assert value == pytest.approx(ref_value, rel=1e-10)
    np.testing.assert_allclose(grad, ref_grad, rtol=1e-7, atol=1e-8 * np.abs(ref_grad).max())
    assert ar1_log_evidence(statistics, K, ar1) == value


def test_prewhitening_is_exact():
    # log p(y) = white evidence of (W y, W Phi) at level sigma^2 (1 - a^2) + log |det W|
    rng = np.random.default_rng(2)
    Phi, lags = _problem(rng, (60,))
    K = (C(0.5) * DC(0.8, 0.2))(lags)
    ar1 = AR1Noise(0.2, 12.0, 3.0, 60)
    y = rng.standard_normal(60)
    Wy, WPhi = ar1.whiten(y), ar1.whiten(Phi)
    q = ar1.innovation_variance
    whitened = dense_log_evidence(WPhi, K, Wy, q * np.eye(60))
    log_det_W = 0.5 * np.log1p(-ar1.pole**2)
    assert whitened + log_det_W == pytest.approx(
        dense_log_evidence(Phi, K, y, ar1.matrix()), rel=1e-10)
    np.testing.assert_array_equal(Phi, _problem(np.random.default_rng(2), (60,))[0])


def test_ar1_statistics_check_the_counts():
    with pytest.raises(ValueError, match="counts"):
        AR1Statistics(np.ones((5, 2)), np.ones(5), [3])


# ------------------------------------------------------ dense reference
def test_dense_evidence_gradient_against_finite_differences():
    rng = np.random.default_rng(3)
    Phi, lags = _problem(rng, (40,), order=10)
    kernel = C(0.8) * DC(0.85, 0.3)
    noise = KernelNoise(WhiteKernel(0.05) + C(0.3) * Matern(10.0, nu=1.5), np.arange(40) * 3.0)
    y = rng.standard_normal(40)
    n_kernel = kernel.theta.shape[0]
    theta = np.concatenate([kernel.theta, noise.theta])

    def value(t):
        K = kernel.clone_with_theta(t[:n_kernel])(lags)
        return dense_log_evidence(Phi, K, y, noise.with_theta(t[n_kernel:]).matrix())

    K, dK = kernel(lags, eval_gradient=True)
    N, dN = noise.matrix_with_gradient()
    v, grad = dense_log_evidence(Phi, K, y, N, dK, dN, eval_gradient=True)
    assert v == pytest.approx(stats.multivariate_normal(np.zeros(40), Phi @ K @ Phi.T + N)
                              .logpdf(y), rel=1e-10)
    np.testing.assert_allclose(grad, _fd(value, theta), rtol=1e-5, atol=1e-6)


def test_dense_posterior_is_the_generalized_least_squares_posterior():
    rng = np.random.default_rng(4)
    Phi, lags = _problem(rng, (50,), order=12)
    K = (C(0.8) * DC(0.85, 0.3))(lags)
    N = KernelNoise(WhiteKernel(0.05) + C(0.3) * Matern(10.0, nu=1.5),
                    np.arange(50) * 3.0).matrix()
    y = rng.standard_normal(50)
    mu, Sigma = dense_posterior(Phi, K, y, N)
    Ninv = np.linalg.inv(N)
    information = np.linalg.inv(K) + Phi.T @ Ninv @ Phi
    np.testing.assert_allclose(Sigma, np.linalg.inv(information), rtol=1e-7, atol=1e-10)
    np.testing.assert_allclose(mu, np.linalg.solve(information, Phi.T @ Ninv @ y), rtol=1e-7)


def test_measurement_band_holds_its_level_with_coloured_disturbances():
    # g and a coloured disturbance drawn from the model; a new measured sample far
    # from the data (its disturbance independent of theirs) falls in the 95 % band
    # of the output plus N(t, t) in 95 % of the draws
    rng = np.random.default_rng(5)
    order, factor, M = 15, 3, 40
    u = rng.standard_normal(M * factor + 400)
    op = DownsampledConvolution(u[: M * factor], factor, order)
    K = (C(1.0) * DC(0.8, 0.5))(op.lags)
    noise = KernelNoise(WhiteKernel(0.02) + C(0.5) * Matern(9.0, nu=1.5),
                        np.arange(M) * factor * 1.0)
    N = noise.matrix()
    n_new = M * factor + 399
    row = u[n_new - np.arange(order)]
    Kroot = linalg.cholesky(K + 1e-12 * np.eye(order), lower=True)
    Nroot = linalg.cholesky(N, lower=True)
    z = stats.norm.ppf(0.975)
    draws = 4000
    # the posterior covariance does not depend on y, the mean is linear in it
    mu_map = np.column_stack([dense_posterior(op.matrix, K, e, N)[0] for e in np.eye(M)])
    Sigma = dense_posterior(op.matrix, K, np.zeros(M), N)[1]
    np.testing.assert_allclose(mu_map @ np.arange(M * 1.0),
                               dense_posterior(op.matrix, K, np.arange(M * 1.0), N)[0],
                               rtol=1e-8, atol=1e-12)
    G = Kroot @ rng.standard_normal((order, draws))
    Y = op.matrix @ G + Nroot @ rng.standard_normal((M, draws))
    y_new = row @ G + np.sqrt(noise.sample_variance()) * rng.standard_normal(draws)
    std = np.sqrt(row @ Sigma @ row + noise.sample_variance())
    inside = np.abs(y_new - row @ (mu_map @ Y)) <= z * std
    assert 0.94 < np.mean(inside) < 0.96  # binomial sd 0.0034


# ------------------------------------------- the data-covariance seam
def _seam_problem():
    rng = np.random.default_rng(6)
    op = DownsampledConvolution(rng.standard_normal(150), 3, 20)
    kernel = C(0.8) * DC(0.85, 0.3)
    y = op.matvec(0.8 ** np.arange(20)) + 0.1 * rng.standard_normal(op.n_outputs)
    return op, kernel, y


@pytest.mark.parametrize("make, route", [
    (lambda t: KernelNoise(WhiteKernel(0.05) + C(0.3) * Matern(10.0, nu=1.5), t), "Dense"),
    (lambda t: KernelNoise(WhiteKernel(0.05) + C(0.2) * ExpSineSquared(5.0, 24.0), t), "Dense"),
    (lambda t: AR1Noise(0.3, 8.0, 3.0, t.shape[0]), "AR1"),  # M = 50 > P = 20: its own route
], ids=["matern32", "periodic", "ar1"])
def test_noise_models_plug_into_the_data_covariance(make, route):
    from gpmultirate.covariance import data_covariance

    op, kernel, y = _seam_problem()
    noise = make(np.arange(op.n_outputs) * 3.0)
    dense = noise if isinstance(noise, KernelNoise) else KernelNoise.from_ar1(noise)
    N, dN = dense.matrix_with_gradient()
    np.testing.assert_allclose(noise.matrix(), N, rtol=1e-12)
    K, dK = kernel(op.lags, eval_gradient=True)
    covariance = data_covariance(kernel, op, noise, "contraction")
    assert type(covariance).__name__ == f"{route}Covariance"
    value, grad = covariance.log_likelihood_gradient(y)
    ref_value, ref_grad = dense_log_evidence(op.matrix, K, y, N, dK, dN, eval_gradient=True)
    assert value == pytest.approx(ref_value, rel=1e-10)
    np.testing.assert_allclose(grad, ref_grad, rtol=1e-8, atol=1e-10 * np.abs(ref_grad).max())
    posterior = data_covariance(kernel, op, noise, space="posterior").posterior(y)
    mu, Sigma = dense_posterior(op.matrix, K, y, N)
    np.testing.assert_allclose(posterior.coef, mu, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(posterior.covariance(), Sigma, rtol=1e-8, atol=1e-12)


def test_coloured_noise_refuses_a_reduced_observation():
    from gpmultirate.covariance import data_covariance
    from gpmultirate.observations import reduce_observation

    rng = np.random.default_rng(7)
    op = DownsampledConvolution(rng.standard_normal(300), 3, 10)
    data, _ = reduce_observation(op, rng.standard_normal(op.n_outputs))
    assert data.n_discarded > 0
    for noise in (KernelNoise(C(1.0) * Matern(5.0, nu=1.5), np.arange(10) * 3.0),
                  AR1Noise(1.0, 5.0, 3.0, 10)):
        with pytest.raises(ValueError, match="reduced observation assumes white noise"):
            data_covariance(C(1.0) * DC(0.8, 0.5), data, noise)


def test_make_noise_builds_each_choice():
    from gpmultirate.noise import WhiteNoise, make_noise

    t = np.arange(6) * 3.0
    white = make_noise("white", 0.2, (1e-3, 1.0), t)
    assert isinstance(white, WhiteNoise) and white.level == 0.2
    for name, nu in (("matern12", 0.5), ("matern32", 1.5)):
        noise = make_noise(name, 0.2, (1e-3, 1.0), t, length_scale=7.0)
        expected = WhiteKernel(0.2)(t[:, None]) + (C(0.2) * Matern(7.0, nu=nu))(t[:, None])
        np.testing.assert_allclose(noise.matrix(), expected, rtol=1e-12)
        assert noise.level == 0.2 and noise.theta.shape == (3,)
    fixed = make_noise("matern12", 0.2, "fixed", t)
    assert not fixed.is_free
    periodic = C(0.5) * ExpSineSquared(2.0, 12.0)
    added = make_noise(periodic, 0.2, "fixed", t)
    np.testing.assert_allclose(added.matrix(), 0.2 * np.eye(6) + periodic(t[:, None]),
                               rtol=1e-12)
    own = WhiteKernel(0.05) + C(1.0) * Matern(4.0, nu=1.5)
    assert make_noise(own, 0.2, "fixed", t).level == pytest.approx(0.05)
    with pytest.raises(ValueError, match="noise_kernel"):
        make_noise("matern52", 0.2, "fixed", t)
    with pytest.raises(ValueError, match="noise_kernel"):
        make_noise(3, 0.2, "fixed", t)
    with pytest.raises(ValueError, match="noise_level"):
        make_noise("white", -1.0, "fixed", t)


def test_disturbance_evidence_gain_is_the_best_grid_point_against_scipy_densities():
    from scipy.stats import multivariate_normal
    from sklearn.gaussian_process.kernels import Matern

    from gpmultirate.noise import (
        GAIN_LENGTH_SCALES,
        GAIN_SCALES,
        GAIN_SHARES,
        disturbance_evidence_gain,
    )

    rng = np.random.default_rng(7)
    blocks = [3.0 * np.arange(25), 3.0 * np.arange(15) + 1.0]  # two records
    M = 40
    A = rng.standard_normal((M, 3))
    S = A @ A.T
    y = rng.standard_normal(M) + np.repeat([0.8, -0.5], [25, 15])
    gamma = 0.7
    white = multivariate_normal(np.zeros(M), S + gamma * np.eye(M)).logpdf(y)
    best = -np.inf
    for ell in 3.0 * np.asarray(GAIN_LENGTH_SCALES):
        for nu in (0.5, 1.5):
            R = np.zeros((M, M))
            R[:25, :25] = Matern(ell, nu=nu)(blocks[0][:, None])
            R[25:, 25:] = Matern(ell, nu=nu)(blocks[1][:, None])
            for w in GAIN_SHARES:
                for s in GAIN_SCALES:
                    N = s * gamma * ((1 - w) * np.eye(M) + w * R)
                    best = max(best, multivariate_normal(np.zeros(M), S + N).logpdf(y) - white)
    S_before = S.copy()
    gain = disturbance_evidence_gain(S, y, gamma, blocks)
    assert gain == pytest.approx(best, rel=1e-10)
    np.testing.assert_array_equal(S, S_before)
    with pytest.raises(ValueError, match="S must"):
        disturbance_evidence_gain(S[:3, :3], y, gamma, blocks)
    with pytest.raises(ValueError, match="instants"):
        disturbance_evidence_gain(S, y, gamma, blocks[:1])


def test_ar1_evidence_gain_is_the_best_grid_point_against_scipy_densities():
    from scipy.stats import multivariate_normal

    from gpmultirate.noise import GAIN_LENGTH_SCALES, GAIN_SCALES, ar1_evidence_gain

    rng = np.random.default_rng(8)
    counts = [30, 1, 19]  # a lone sample is a record too
    blocks = [3.0 * np.arange(n) + 7.0 * i for i, n in enumerate(counts)]
    M, P = sum(counts), 5
    Phi = rng.standard_normal((M, P))
    A = rng.standard_normal((P, P))
    K = A @ A.T
    y = Phi @ rng.standard_normal(P) + rng.standard_normal(M)
    gamma = 0.8
    S = Phi @ K @ Phi.T
    white = multivariate_normal(np.zeros(M), S + gamma * np.eye(M)).logpdf(y)
    best = -np.inf
    for ell in 3.0 * np.asarray(GAIN_LENGTH_SCALES):
        for s in GAIN_SCALES:
            N = linalg.block_diag(*(s * gamma * np.exp(-np.abs(t[:, None] - t[None, :]) / ell)
                                    for t in blocks))
            best = max(best, multivariate_normal(np.zeros(M), S + N).logpdf(y) - white)
    Phi_before = Phi.copy()
    assert ar1_evidence_gain(Phi, K, y, gamma, blocks) == pytest.approx(best, rel=1e-9)
    np.testing.assert_array_equal(Phi, Phi_before)
    assert ar1_evidence_gain(Phi, K, y, gamma, [np.sort(rng.uniform(0, 200, M))]) is None


def test_ar1_evidence_gain_tells_a_drifting_long_record_from_a_white_one():
    from gpmultirate.noise import ar1_evidence_gain

    rng = np.random.default_rng(9)
    M, P = 1500, 4
    Phi = rng.standard_normal((M, P))
    g = rng.standard_normal(P)
    drift = np.zeros(M)
    for m in range(1, M):
        drift[m] = 0.95 * drift[m - 1] + 0.3 * rng.standard_normal()
    white = rng.standard_normal(M)
    t = 3.0 * np.arange(M)
    assert ar1_evidence_gain(Phi, np.eye(P), Phi @ g + white, 1.0, t) < 3.0
    coloured = Phi @ g + 0.3 * white + drift
    assert ar1_evidence_gain(Phi, np.eye(P), coloured, np.var(coloured - Phi @ g), t) > 50.0
