"""Fisher-scoring tuning against dense computations and the L-BFGS-B path.

* ``observed_with_derivatives`` gives every ``dS_j = Phi dK_j Phi^T`` of the
  dense route (scikit-learn's ``kernel(X, eval_gradient=True)``);
* ``log_marginal_likelihood_fisher`` gives the evidence and gradient of the
  L-BFGS-B path and the Fisher information
  ``1/2 tr(Ky^{-1} dKy_j Ky^{-1} dKy_k)`` computed densely, which is also the
  covariance of the score under data drawn from the model (Monte Carlo);
* the fast resonance grid equals one evidence evaluation per candidate;
* Fisher scoring reaches the optimum L-BFGS-B reaches (or a better one).
"""

import warnings

import numpy as np
import pytest
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process.kernels import RBF
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate import simulation, study, tuning
from gpmultirate.inference import (
    log_marginal_likelihood,
    log_marginal_likelihood_fisher,
    resonance_grid_log_marginal_likelihood,
)
from gpmultirate.kernels import DC, PK, SS, TC, observe


def observed_with_derivatives(kernel, op):
    """``S`` and every derivative item ``dS_j`` (dense or factored)."""
    return observe(kernel, op).covariance_with_derivatives()


def observed_without(kernel, term, op):
    """``S`` with the summand ``term`` left out, or None."""
    return observe(kernel, op).covariance_without(term)

KERNELS = {
    "C*DC": C(2.0) * DC(alpha=0.8, beta=0.9),
    "C*DC-negative-beta+PK": C(2.0) * DC(alpha=0.8, beta=-0.7) + PK(alpha=0.9, omega=2.8),
    "DC+PK": DC(alpha=0.8, beta=0.7) + PK(alpha=0.9, omega=0.7, sigma1=0.5, sigma2=1.2),
    "C*TC+C": C(0.5) * TC(alpha=0.7) + C(1.3),
    "SS*Cfixed+RBF": SS(alpha=0.8) * C(0.3, "fixed") + RBF(3.0),
    "PK-alpha-fixed": PK(alpha=0.9, omega=0.7, sigma1=0.5, sigma2=1.2, alpha_bounds="fixed"),
    "DC-beta-fixed+PK": DC(alpha=0.85, beta=0.6, beta_bounds="fixed")
    + PK(alpha=0.95, omega=1.3, sigma1=0.7, sigma2=0.4, omega_bounds="fixed"),
}
kernel_params = [pytest.param(k, id=name) for name, k in KERNELS.items()]


def make_problem(seed=0, n=60, factor=3, order=25, offset=1):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    op = gm.DownsampledConvolution(u, factor, order, offset)
    return op, rng.standard_normal(op.n_outputs)


def dense_derivatives(kernel, op, noise, noise_free):
    S, dS = op.covariance(kernel, eval_gradient=True)
    Ky = S + noise * np.eye(op.n_outputs)
    if noise_free:
        dS = np.concatenate([dS, noise * np.eye(op.n_outputs)[:, :, None]], axis=2)
    return Ky, dS


@pytest.mark.parametrize("kernel", kernel_params)
def test_derivative_items_equal_dense(kernel):
    op, _ = make_problem()
    S, items = observed_with_derivatives(kernel, op)
    S_dense, dS = op.covariance(kernel, eval_gradient=True)
    np.testing.assert_allclose(S, S_dense, rtol=1e-10, atol=1e-12 * np.abs(S_dense).max())
    assert len(items) == kernel.theta.shape[0]
    for j, item in enumerate(items):
        full = item[0] @ item[1] @ item[0].T if isinstance(item, tuple) else item
        scale = np.abs(dS[:, :, j]).max()
        np.testing.assert_allclose(full, dS[:, :, j], rtol=1e-9, atol=1e-12 * scale)


@pytest.mark.parametrize("noise_free", [True, False])
@pytest.mark.parametrize("kernel", kernel_params)
def test_fisher_information_equals_dense(kernel, noise_free):
    op, y = make_problem(seed=1)
    noise = 0.3
    value, grad, fisher = log_marginal_likelihood_fisher(op, kernel, noise, y, noise_free)
    value_ref, grad_ref = log_marginal_likelihood(op, kernel, noise, y, True, noise_free)
    Ky, dS = dense_derivatives(kernel, op, noise, noise_free)
    inverse = np.linalg.inv(Ky)
    expected = 0.5 * np.einsum("ab,bcj,cd,dak->jk", inverse, dS, inverse, dS)
    assert value == pytest.approx(value_ref, rel=1e-12, abs=1e-10)
    np.testing.assert_allclose(grad, grad_ref, rtol=1e-9, atol=1e-12 * np.abs(grad_ref).max())
    np.testing.assert_allclose(fisher, expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())
    np.testing.assert_allclose(fisher, fisher.T, rtol=0, atol=0)


@pytest.mark.slow
def test_fisher_information_is_the_covariance_of_the_score():
    # data drawn from the model: Cov(gradient) = Fisher information
    kernel = KERNELS["DC+PK"]
    op, _ = make_problem(seed=2)
    noise = 0.2
    Ky, _ = dense_derivatives(kernel, op, noise, True)
    root = np.linalg.cholesky(Ky)
    rng = np.random.default_rng(5)
    scores = []
    for _ in range(3000):
        y = root @ rng.standard_normal(op.n_outputs)
        scores.append(log_marginal_likelihood(op, kernel, noise, y, True, True)[1])
    scores = np.array(scores)
    fisher = log_marginal_likelihood_fisher(op, kernel, noise, y, True)[2]
    sd = np.sqrt(np.diag(fisher))
    empirical = np.cov(scores.T) / np.outer(sd, sd)
    # standard error of a covariance estimate from 3000 draws is about 0.02-0.04
    np.testing.assert_allclose(empirical, fisher / np.outer(sd, sd), atol=0.12)
    np.testing.assert_allclose(scores.mean(axis=0) / sd, 0.0, atol=0.08)


def test_resonance_grid_equals_one_evaluation_per_candidate():
    kernel = C(1.5) * DC(alpha=0.85, beta=0.7) + PK(alpha=0.9, omega=0.6) + PK(
        alpha=0.85, omega=1.8, sigma1=0.4, sigma2=0.9
    )
    op, y = make_problem(seed=3, n=90, order=40)
    roles = observe(kernel).roles()
    for index in [i for i, role in enumerate(roles) if role.kind == "frequency"]:
        term = roles[index].owner
        assert isinstance(term, PK)
        omegas = np.exp(kernel.theta[index]) * np.geomspace(0.7, 1.4, 7)
        fast = resonance_grid_log_marginal_likelihood(
            op, kernel, term, "omega", 0.05, y, omegas
        )
        slow = []
        for omega in omegas:
            theta = kernel.theta.copy()
            theta[index] = np.log(omega)
            slow.append(
                log_marginal_likelihood(op, kernel.clone_with_theta(theta), 0.05, y, False, False)
            )
        np.testing.assert_allclose(fast, slow, rtol=1e-10, atol=1e-9)
    assert roles[0].kind == "amplitude"  # the constant is no resonance


def test_observed_without_is_none_inside_a_product():
    op, _ = make_problem()
    pk = PK(alpha=0.9, omega=0.7)
    assert observed_without(C(2.0) * pk, pk, op) is None
    rest = observed_without(DC() + pk + TC(), pk, op)
    np.testing.assert_allclose(rest, op.covariance(DC() + TC()), rtol=1e-10)


def paper_like_problem(seed):
    sim = simulation
    rng = np.random.default_rng(seed)
    system = sim.paper_system(0.1, perturbation=0.1, random_state=rng)
    u = sim.multisine(240, random_state=rng)
    data = sim.simulate_experiment(system, u, 3, snr_db=40.0, random_state=rng)
    return data.u, data.y_slow


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("name", ["DC", "PK"])
def test_fisher_scoring_reaches_the_lbfgs_optimum(name, seed, monkeypatch):
    u, y = paper_like_problem(seed)
    kernel = study.paper_kernels(0.1)[name][0]

    def fit(fisher_max_outputs):
        monkeypatch.setattr(tuning, "FISHER_MAX_OUTPUTS", fisher_max_outputs)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            return gm.FIRGaussianProcess(kernel, factor=3, order=240, noise_level=1e-5).fit(u, y)

    fisher, lbfgs = fit(10**6), fit(0)
    assert fisher.optimizer_result_.success
    assert fisher.log_marginal_likelihood_value_ >= lbfgs.log_marginal_likelihood_value_ - 1e-3
    # the optimum is stationary: the gain a Newton step on the interior
    # coordinates predicts, 1/2 g^T F^{-1} g, is negligible (in nats)
    _, grad, fisher_information = log_marginal_likelihood_fisher(
        fisher.observation_, fisher.kernel_, fisher.noise_level_, y, True
    )
    theta = np.append(fisher.kernel_.theta, np.log(fisher.noise_level_))
    bounds = np.vstack([fisher.kernel_.bounds, np.log(fisher.noise_level_bounds_)])
    interior = (theta > bounds[:, 0] + 1e-6) & (theta < bounds[:, 1] - 1e-6)
    g, F = grad[interior], fisher_information[np.ix_(interior, interior)]
    assert 0.5 * g @ np.linalg.lstsq(F, g, rcond=1e-12)[0] < 1e-3


def test_fisher_scoring_holds_coordinates_at_bounds():
    # bounds far from the data scale pin the amplitude at one of them
    u, y = paper_like_problem(0)
    kernel = C(1.0, (1e-3, 1e-2)) * DC(alpha=0.95, beta=0.99)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        # bounds read in the data's units, where they exclude the data's scale
        model = gm.FIRGaussianProcess(kernel, factor=3, order=240, normalize=False).fit(u * 1e-6, y)
    assert model.kernel_.k1.constant_value in (pytest.approx(1e-3), pytest.approx(1e-2))
    assert model.optimizer_result_.nit < 100
    assert np.all(np.isfinite(model.coef_))


@pytest.mark.parametrize("nu", [0.5, 1.5])
def test_disturbance_fisher_against_finite_differences(nu):
    """Evidence, gradient and Fisher information under a Matern disturbance (the dense
    route): ``1/2 tr(Ky^{-1} dKy_j Ky^{-1} dKy_k)`` with every ``dKy_j`` taken by central
    differences of the dense ``S + N`` in ``theta``, the gradient by differences of the
    dense log density."""
    from sklearn.gaussian_process.kernels import Matern, WhiteKernel

    from gpmultirate.inference import LogEvidence
    from gpmultirate.noise import KernelNoise, noise_instants

    op, y = make_problem(seed=4)
    kernel = C(1.5) * DC(alpha=0.8, beta=0.6) + PK(alpha=0.9, omega=0.9)
    noise_kernel = WhiteKernel(0.2) + C(0.5) * Matern(7.0, nu=nu)
    noise = KernelNoise(noise_kernel, noise_instants(op))
    evidence = LogEvidence(op, y, kernel, 0.2, (1e-5, 1e5), noise=noise)
    assert evidence.has_fisher
    theta = evidence.theta + 0.1
    value, grad, fisher = evidence.with_fisher(theta)
    n_kernel = kernel.theta.shape[0]

    def dense(theta):
        k = kernel.clone_with_theta(theta[:n_kernel])
        t = noise_instants(op)[0][:, None]
        return op.covariance(k) + noise_kernel.clone_with_theta(theta[n_kernel:])(t)

    def log_density(theta):
        Ky = dense(theta)
        sign, logdet = np.linalg.slogdet(Ky)
        return -0.5 * (y @ np.linalg.solve(Ky, y) + logdet + y.size * np.log(2 * np.pi))

    h = 1e-5
    steps = np.eye(theta.size) * h
    dK = [(dense(theta + e) - dense(theta - e)) / (2 * h) for e in steps]
    inverse = np.linalg.inv(dense(theta))
    expected = np.array([[0.5 * np.trace(inverse @ a @ inverse @ b) for b in dK] for a in dK])
    fd_grad = np.array([(log_density(theta + e) - log_density(theta - e)) / (2 * h)
                        for e in steps])
    assert value == pytest.approx(log_density(theta), rel=1e-10)
    np.testing.assert_allclose(grad, fd_grad, rtol=1e-5, atol=1e-6 * np.abs(fd_grad).max())
    np.testing.assert_allclose(fisher, expected, rtol=1e-5, atol=1e-7 * np.abs(expected).max())


def test_disturbance_tuned_by_fisher_scoring_reaches_the_lbfgs_optimum(monkeypatch):
    """A Matern 3/2 disturbance tuned by L-BFGS-B for at most
    ``COLOURED_LBFGS_EVALUATIONS`` and then Fisher scoring ends at the log evidence
    L-BFGS-B alone reaches (or higher), in no more evaluations."""
    from gpmultirate.noise import KernelNoise

    rng = np.random.default_rng(12)
    lags = np.arange(60)
    g = 0.9**lags * np.sin(0.4 * lags)
    u = rng.standard_normal(300)
    drift = np.convolve(rng.standard_normal(400), np.ones(25) / 5.0, "valid")[:300]
    y = np.convolve(u, g)[:300] + 0.05 * rng.standard_normal(300) + 0.3 * drift
    settings = dict(factor=3, order=60, noise_kernel="matern32")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fisher = gm.FIRGaussianProcess(**settings).fit(u, y[::3])
        monkeypatch.setattr(KernelNoise, "offers_fisher", lambda self, observation: False)
        lbfgs = gm.FIRGaussianProcess(**settings).fit(u, y[::3])
    assert fisher.log_marginal_likelihood_value_ >= lbfgs.log_marginal_likelihood_value_ - 1e-3
    assert fisher.optimizer_result_.nfev <= lbfgs.optimizer_result_.nfev


def test_fisher_scoring_stops_where_the_evidence_stopped_increasing():
    """A coordinate the evidence does not feel, with a gradient that says otherwise (a
    near-zero amplitude's, to rounding): its steps are accepted (the evidence does not
    decrease) and the predicted gain stays above the tolerance; the run stops after
    ``stall`` iterations without gain, at the maximum of the other coordinate."""
    from gpmultirate.tuning import FISHER_OPTIONS, DecayRateTransform, fisher_scoring

    def value_grad_fisher(theta):
        value = -(theta[0] - 1.0) ** 2
        return value, np.array([-2.0 * (theta[0] - 1.0), 0.1]), np.diag([2.0, 1.0])

    bounds = np.array([[-10.0, 10.0], [-1e6, 1e6]])
    result = fisher_scoring(value_grad_fisher, np.array([3.0, 0.0]), bounds,
                            DecayRateTransform([]))
    assert result.message == "the evidence stopped increasing"
    assert result.nit <= FISHER_OPTIONS["stall"] + 5
    assert result.x[0] == pytest.approx(1.0, abs=1e-6)
