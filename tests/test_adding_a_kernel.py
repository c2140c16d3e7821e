"""The kernel of the "Adding a kernel" example gets its fast path and the right posterior.

``examples/adding_a_kernel.py`` defines ``FirstOrderPole`` in one class and
edits nothing else.  Its structured term must be used, must not evaluate the
kernel matrix for the data covariance, and every number must equal the dense
formulas of the paper (eq. 15 for the mean, the Gaussian-process conditional
at real lags, eq. 19 corrected for the evidence) and finite differences.
"""

from __future__ import annotations

import importlib.util
import pathlib

import numpy as np
import pytest
from scipy.stats import multivariate_normal
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate.kernels import DC, LowRankTerm, observe

PATH = pathlib.Path(__file__).resolve().parents[1] / "examples" / "adding_a_kernel.py"
spec = importlib.util.spec_from_file_location("adding_a_kernel", PATH)
example = importlib.util.module_from_spec(spec)
spec.loader.exec_module(example)
FirstOrderPole = example.FirstOrderPole


@pytest.fixture
def problem():
    rng = np.random.default_rng(3)
    u = rng.standard_normal(90)
    op = gm.DownsampledConvolution(u, factor=3, order=40, offset=1)
    g = 0.7 * 0.85 ** np.arange(40)
    y = op.matvec(g) + 0.02 * rng.standard_normal(op.n_outputs)
    return u, y, op


def test_values_and_gradient_follow_the_formula():
    kernel = FirstOrderPole(0.8)
    t = np.array([0.0, 0.5, 2.0, 3.25])
    K, dK = kernel(t[:, None], eval_gradient=True)
    np.testing.assert_allclose(K, 0.8 ** np.add.outer(t, t), rtol=1e-14)
    step = 1e-6
    up = kernel.clone_with_theta(kernel.theta + step)(t[:, None])
    down = kernel.clone_with_theta(kernel.theta - step)(t[:, None])
    np.testing.assert_allclose(dK[:, :, 0], (up - down) / (2 * step), rtol=1e-7, atol=1e-12)


def test_the_structured_term_is_used_and_matches_the_dense_route(problem, monkeypatch):
    _, _, op = problem
    kernel = FirstOrderPole(0.8)
    Phi = op.matrix
    K, dK = kernel(op.lags, eval_gradient=True)
    term = observe(kernel, op)
    assert isinstance(term, LowRankTerm)

    def forbidden(*args, **kwargs):
        raise AssertionError("the kernel matrix must not be evaluated")

    monkeypatch.setattr(FirstOrderPole, "__call__", forbidden)
    S, contract = term.covariance_with_contractor()
    _, items = term.covariance_with_derivatives()
    monkeypatch.undo()
    np.testing.assert_allclose(S, Phi @ K @ Phi.T, rtol=1e-12, atol=1e-12)
    W = np.random.default_rng(0).standard_normal((op.n_outputs,) * 2)
    W = W + W.T
    expected = np.einsum("mn,mi,ijk,nj->k", W, Phi, dK, Phi)
    np.testing.assert_allclose(contract(W), expected, rtol=1e-10)
    (U, D), = items
    np.testing.assert_allclose(U @ D @ U.T, Phi @ dK[:, :, 0] @ Phi.T, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(term.regressor_times_kernel(), Phi @ K, rtol=1e-12, atol=1e-13)


def test_posterior_and_evidence_equal_the_dense_formulas(problem):
    u, y, op = problem
    kernel = C(0.6) * FirstOrderPole(0.85) + C(0.01) * DC(0.9, 0.8)
    noise = 4e-4
    model = gm.FIRGaussianProcess(
        kernel, factor=3, order=40, offset=1, noise_level=noise, optimizer=None
    ).fit(u, y)
    Phi, K = op.matrix, kernel(op.lags)
    Ky = Phi @ K @ Phi.T + noise * np.eye(op.n_outputs)
    # eq. (15)
    np.testing.assert_allclose(model.coef_, K @ Phi.T @ np.linalg.solve(Ky, y), rtol=1e-8, atol=1e-10)
    # the Gaussian-process conditional at real lags
    lags = np.array([0.5, 3.3, 10.75])
    cross = kernel(lags[:, None], op.lags) @ Phi.T
    mean = cross @ np.linalg.solve(Ky, y)
    cov = kernel(lags[:, None]) - cross @ np.linalg.solve(Ky, cross.T)
    got_mean, got_std = model.impulse_response(lags, return_std=True)
    np.testing.assert_allclose(got_mean, mean, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(got_std, np.sqrt(np.diag(cov)), rtol=1e-6, atol=1e-10)
    # eq. (19), noise inside the determinant
    expected = multivariate_normal(np.zeros(op.n_outputs), Ky).logpdf(y)
    assert model.log_marginal_likelihood_value_ == pytest.approx(expected, rel=1e-10)


def test_tuning_uses_the_gradient_of_the_structured_term(problem):
    u, y, _ = problem
    kernel = C(1.0) * FirstOrderPole(0.6)
    model = gm.FIRGaussianProcess(kernel, factor=3, order=40, offset=1).fit(u, y)
    assert model.kernel_.k2.pole == pytest.approx(0.85, abs=0.02)
    theta = np.append(model.kernel_.theta, np.log(model.noise_level_))
    value, grad = model.log_marginal_likelihood(theta, eval_gradient=True)
    # the evidence is sharply curved in log(pole) (second derivative ~ 1e6):
    # a fourth-order difference with a small step
    step = 1e-6

    def f(x):
        return model.log_marginal_likelihood(x)

    numeric = [
        (-f(theta + 2 * step * e) + 8 * f(theta + step * e) - 8 * f(theta - step * e)
         + f(theta - 2 * step * e)) / (12 * step)
        for e in np.eye(theta.shape[0])
    ]
    np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-4)


def test_the_model_saves_and_loads_with_the_kernel_class(problem, tmp_path):
    u, y, op = problem
    kernel = C(0.6) * FirstOrderPole(0.85) + C(0.01) * DC(0.9, 0.8)
    model = gm.FIRGaussianProcess(kernel, factor=3, order=40, offset=1).fit(u, y)
    loaded = example.save_and_load(model, tmp_path / "pole.npz")
    assert type(loaded.kernel_.k1.k2) is FirstOrderPole
    assert repr(loaded.kernel_) == repr(model.kernel_)
    u_new = np.cos(0.4 * np.arange(120))
    for a, b in zip(loaded.predict(u_new, return_std=True), model.predict(u_new, return_std=True)):
        np.testing.assert_array_equal(a, b)
    lags = np.array([0.5, 3.3, 10.75])
    np.testing.assert_array_equal(loaded.impulse_response(lags), model.impulse_response(lags))
    assert loaded.log_marginal_likelihood_value_ == model.log_marginal_likelihood_value_
    with pytest.raises(gm.ModelFileError, match=r"'FirstOrderPole'.*kernels=\[FirstOrderPole\]"):
        gm.load_model(tmp_path / "pole.npz")
