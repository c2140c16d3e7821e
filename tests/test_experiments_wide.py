"""Several inputs, several records, any instants, missing samples, initial conditions.

Every case is checked against the paper's formulas written densely here:
the regressor built by loops (eq. 8 with the initial conditions), the prior
``K = blockdiag(K_k)``, the posterior mean of eq. (15), the Gaussian-process
conditional at real lags, the evidence of eq. (19, corrected), the FRF and
the prediction variances as linear maps of the coefficient covariance.
"""

from __future__ import annotations

import pickle
import warnings

import numpy as np
import pytest
from scipy import linalg
from scipy.stats import multivariate_normal, norm
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import ConstantKernel as C
from sklearn.gaussian_process.kernels import WhiteKernel

import gpmultirate as gm
from gpmultirate.kernels import DC, PK, SS, TC
from gpmultirate.persistence import load_model, save_model


# ------------------------------------------------------------ dense reference
def dense_regressor(u, indices, order, initial_conditions="zero"):
    """``Phi[m, k P + i] = u_k(n_m - i)``, by loops."""
    u = np.asarray(u, dtype=float)
    u = u[:, None] if u.ndim == 1 else u
    N, n_inputs = u.shape
    Phi = np.zeros((len(indices), n_inputs * order))
    for m, n in enumerate(indices):
        for k in range(n_inputs):
            for i in range(order):
                j = n - i
                if j >= 0:
                    Phi[m, k * order + i] = u[j, k]
                elif initial_conditions == "periodic":
                    Phi[m, k * order + i] = u[j % N, k]
    return Phi


def dense_prior(kernels, lags):
    return linalg.block_diag(*[k(lags[:, None]) for k in kernels])


def dense_cross_prior(kernels, lags, order):
    grid = np.arange(order, dtype=float)[:, None]
    return linalg.block_diag(*[k(lags[:, None], grid) for k in kernels])


def dense_posterior(Phi, K, y, noise):
    Ky = Phi @ K @ Phi.T + noise * np.eye(Phi.shape[0])
    mean = K @ Phi.T @ np.linalg.solve(Ky, y)
    cov = K - K @ Phi.T @ np.linalg.solve(Ky, Phi @ K)
    evidence = multivariate_normal(np.zeros(Phi.shape[0]), Ky).logpdf(y)
    return mean, cov, Ky, evidence


def used_instants(indices, y, order, initial_conditions):
    keep = np.isfinite(y)
    if initial_conditions == "discard":
        keep &= np.asarray(indices) >= order - 1
    return np.asarray(indices)[keep], np.asarray(y)[keep]


# ------------------------------------------------------------------ problems
def record(rng, n, n_inputs, spacing=3, missing=0.0, irregular=False):
    u = rng.standard_normal((n, n_inputs)) if n_inputs > 1 else rng.standard_normal(n)
    if irregular:
        steps = rng.integers(spacing - 1, spacing + 2, size=n)
        indices = np.cumsum(steps)
        indices = indices[indices < n]
    else:
        indices = np.arange(1, n, spacing)
    y = rng.standard_normal(indices.shape[0])
    if missing:
        y[rng.random(indices.shape[0]) < missing] = np.nan
        y[0] = 0.3  # at least one measured sample
    return u, indices, y


KERNELS = [C(0.8) * DC(0.85, 0.9), C(0.5) * TC(0.8) + PK(0.9, 0.9, 0.4, 0.3)]

CASES = {
    "two inputs, kernel list": dict(n_inputs=2, records=1, ic="zero", kernels=KERNELS),
    "two inputs, one kernel": dict(n_inputs=2, records=1, ic="zero", kernels=[KERNELS[0]]),
    "two records of different lengths": dict(n_inputs=1, records=2, ic="zero", kernels=[KERNELS[1]]),
    "irregular instants": dict(n_inputs=1, records=1, ic="zero", irregular=True,
                               kernels=[KERNELS[0]]),
    "missing samples": dict(n_inputs=1, records=1, ic="zero", missing=0.3, kernels=[KERNELS[1]]),
    "discard": dict(n_inputs=1, records=1, ic="discard", kernels=[KERNELS[0]]),
    "periodic": dict(n_inputs=1, records=1, ic="periodic", kernels=[KERNELS[1]]),
    "all at once": dict(n_inputs=2, records=2, ic="discard", irregular=True, missing=0.2,
                        kernels=KERNELS),
    "periodic, two inputs, records, missing": dict(n_inputs=2, records=2, ic="periodic",
                                                   missing=0.2, kernels=[SS(0.8), TC(0.7)]),
}


def make_case(name, order=18, seed=0):
    spec = CASES[name]
    rng = np.random.default_rng(seed)
    lengths = [60, 45][: spec["records"]]
    data = [record(rng, n, spec["n_inputs"], missing=spec.get("missing", 0.0),
                   irregular=spec.get("irregular", False)) for n in lengths]
    us, indices, ys = zip(*data)
    if spec["records"] == 1:
        us, indices, ys = us[0], indices[0], ys[0]
    else:
        us, indices, ys = list(us), list(indices), list(ys)
    kernel = spec["kernels"] if len(spec["kernels"]) > 1 else spec["kernels"][0]
    model = gm.FIRGaussianProcess(
        kernel, order=order, noise_level=0.05, optimizer=None,
        initial_conditions=spec["ic"],
    ).fit(us, ys, sample_indices=indices)
    # the dense reference of the same data
    records = data
    Phis, y_used = [], []
    for u, index, y in records:
        index_used, y_r = used_instants(index, y, order, spec["ic"])
        Phis.append(dense_regressor(u, index_used, order, spec["ic"]))
        y_used.append(y_r)
    Phi, y = np.vstack(Phis), np.concatenate(y_used)
    kernels = spec["kernels"] * (spec["n_inputs"] if len(spec["kernels"]) == 1 else 1)
    return model, Phi, y, kernels, spec


@pytest.mark.parametrize("name", list(CASES))
def test_posterior_evidence_and_bands_equal_the_dense_formulas(name):
    model, Phi, y, kernels, spec = make_case(name)
    order, n_inputs = 18, spec["n_inputs"]
    lags = np.arange(order, dtype=float)
    K = dense_prior(kernels, lags)
    mean, cov, Ky, evidence = dense_posterior(Phi, K, y, 0.05)
    scale = np.abs(mean).max()
    np.testing.assert_allclose(model.y_slow_, y)
    np.testing.assert_allclose(np.ravel(model.coef_), mean, rtol=1e-7, atol=1e-9 * scale)
    assert model.log_marginal_likelihood_value_ == pytest.approx(evidence, rel=1e-9)
    expected_shape = (n_inputs, order) if n_inputs > 1 else (order,)
    assert model.coef_.shape == expected_shape
    # real lags: the Gaussian-process conditional
    t = np.array([0.5, 2.25, 7.0, 11.6])
    cross = dense_cross_prior(kernels, t, order) @ Phi.T
    gp_mean = cross @ np.linalg.solve(Ky, y)
    gp_cov = dense_prior(kernels, t) - cross @ np.linalg.solve(Ky, cross.T)
    got_mean, got_std = model.impulse_response(t, return_std=True)
    np.testing.assert_allclose(np.ravel(got_mean), gp_mean, rtol=1e-7, atol=1e-9 * scale)
    np.testing.assert_allclose(np.ravel(got_std), np.sqrt(np.diag(gp_cov)), rtol=1e-6,
                               atol=1e-9)
    _, got_cov = model.impulse_response(t, return_cov=True)
    np.testing.assert_allclose(got_cov, gp_cov, rtol=1e-6, atol=1e-9)
    # FRF of each input: a linear map of the coefficients
    for k in range(n_inputs):
        frf = model.frequency_response([0.05, 0.2, 0.45], level=0.9,
                                       input=k if n_inputs > 1 else None)
        E = np.exp(-2j * np.pi * np.outer([0.05, 0.2, 0.45], lags))
        A = np.zeros((3, n_inputs * order), dtype=complex)
        A[:, k * order : (k + 1) * order] = E
        np.testing.assert_allclose(frf.mean, A @ mean, rtol=1e-7, atol=1e-9 * scale)
        var_re = np.einsum("ij,jk,ik->i", A.real, cov, A.real)
        np.testing.assert_allclose(frf.real_std, np.sqrt(var_re), rtol=1e-5, atol=1e-9)
    # prediction from rest (or periodic) with its standard deviation
    u_new = np.random.default_rng(9).standard_normal((25, n_inputs))
    u_arg = u_new if n_inputs > 1 else u_new[:, 0]
    T = dense_regressor(u_new, np.arange(25), order,
                        "periodic" if spec["ic"] == "periodic" else "zero")
    y_mean, y_std = model.predict(u_arg, return_std=True)
    np.testing.assert_allclose(y_mean, T @ mean, rtol=1e-7, atol=1e-9 * scale)
    np.testing.assert_allclose(y_std, np.sqrt(np.diag(T @ cov @ T.T)), rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(model.predict(u_arg), T @ mean, rtol=1e-7, atol=1e-9 * scale)


@pytest.mark.parametrize("name", ["two inputs, kernel list", "two records of different lengths",
                                  "missing samples"])
def test_long_records_through_the_reduction_equal_the_dense_formulas(name):
    # order 6: M > n_inputs * P, so the evidence and posterior run in the parameter space
    model, Phi, y, kernels, spec = make_case(name, order=6, seed=3)
    assert model.observation_.n_outputs > model.observation_.n_coefficients
    K = dense_prior(kernels, np.arange(6, dtype=float))
    mean, cov, _, evidence = dense_posterior(Phi, K, y, 0.05)
    np.testing.assert_allclose(np.ravel(model.coef_), mean, rtol=1e-7, atol=1e-10)
    assert model.log_marginal_likelihood_value_ == pytest.approx(evidence, rel=1e-9)
    t = np.array([0.5, 3.5])
    cross = dense_cross_prior(kernels, t, 6)
    # g(t) | g(0..P-1): the prior conditional, averaged over the posterior of g
    Kgrid = K
    J = cross @ np.linalg.pinv(Kgrid)
    expected = dense_prior(kernels, t) - J @ Kgrid @ J.T + J @ cov @ J.T
    _, std = model.impulse_response(t, return_std=True)
    np.testing.assert_allclose(np.ravel(std), np.sqrt(np.diag(expected)), rtol=1e-5, atol=1e-8)


def test_gradient_of_the_evidence_with_two_inputs_and_records_matches_finite_differences():
    model, _, _, _, _ = make_case("all at once")
    theta = np.append(model.kernel_.theta, np.log(0.05))
    tuned = gm.FIRGaussianProcess(model.kernel_, order=18, initial_conditions="discard")
    model = tuned.set_params(optimizer=None, noise_level=0.05, noise_level_bounds=(1e-4, 1.0))
    model.fit(*make_data("all at once"))
    value, grad = model.log_marginal_likelihood(theta, eval_gradient=True)
    step = 1e-5
    numeric = [
        (model.log_marginal_likelihood(theta + step * e)
         - model.log_marginal_likelihood(theta - step * e)) / (2 * step)
        for e in np.eye(theta.shape[0])
    ]
    np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-6)


def make_data(name, seed=0):
    spec = CASES[name]
    rng = np.random.default_rng(seed)
    lengths = [60, 45][: spec["records"]]
    data = [record(rng, n, spec["n_inputs"], missing=spec.get("missing", 0.0),
                   irregular=spec.get("irregular", False)) for n in lengths]
    us, indices, ys = (list(x) for x in zip(*data))
    return us, ys, indices


def test_given_uniform_instants_equal_factor_and_offset():
    rng = np.random.default_rng(4)
    u = rng.standard_normal(90)
    y = np.convolve(u, 0.8 ** np.arange(40))[2:90:3] + 0.01 * rng.standard_normal(30)
    plain = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, offset=2, order=40).fit(u, y)
    given = gm.FIRGaussianProcess(C(1.0) * DC(), order=40).fit(
        u, y, sample_indices=np.arange(2, 90, 3))
    np.testing.assert_allclose(given.coef_, plain.coef_, rtol=1e-6, atol=1e-9)
    assert given.log_marginal_likelihood_value_ == pytest.approx(
        plain.log_marginal_likelihood_value_, rel=1e-8)


def test_a_missing_sample_is_as_if_left_out():
    rng = np.random.default_rng(5)
    u = rng.standard_normal(60)
    y = np.convolve(u, 0.8 ** np.arange(30))[:60:3] + 0.01 * rng.standard_normal(20)
    y_nan = y.copy()
    y_nan[[3, 11]] = np.nan
    keep = np.isfinite(y_nan)
    kernel = C(1.0) * DC(0.9, 0.8)
    with_nan = gm.FIRGaussianProcess(kernel, factor=3, order=30).fit(u, y_nan)
    left_out = gm.FIRGaussianProcess(kernel, order=30).fit(
        u, y[keep], sample_indices=np.arange(0, 60, 3)[keep])
    np.testing.assert_array_equal(with_nan.coef_, left_out.coef_)
    assert with_nan.log_marginal_likelihood_value_ == left_out.log_marginal_likelihood_value_


@pytest.mark.slow
def test_two_inputs_are_identified_where_one_input_fails():
    # the slow output of a two-input system: a one-input model cannot explain it
    rng = np.random.default_rng(6)
    n, F = 600, 3
    system = gm.simulation.paper_system(0.1)
    g = system.impulse_response(n)
    u = rng.standard_normal((n, 2))
    y_fast = np.convolve(u[:, 0], g)[:n] + np.convolve(u[:, 1], 0.9 ** np.arange(n))[:n]
    y = y_fast[::F] + 0.01 * rng.standard_normal(n // F)
    two = gm.FIRGaussianProcess(factor=F, order=200).fit(u, y)
    with warnings.catch_warnings():
        # the input left out makes the data look like noise to a one-input model
        warnings.simplefilter("ignore", ConvergenceWarning)
        one = gm.FIRGaussianProcess(factor=F, order=200).fit(u[:, 0], y)
    u_val = rng.standard_normal((n, 2))
    y_val = np.convolve(u_val[:, 0], g)[:n] + np.convolve(u_val[:, 1], 0.9 ** np.arange(n))[:n]
    assert two.score(u_val, y_val) > 95.0
    assert one.score(u_val[:, 0], y_val) < two.score(u_val, y_val) - 20.0
    assert two.kernel_.kernels[0] != two.kernel_.kernels[1]  # each input tuned on its own


@pytest.mark.slow
def test_two_input_bands_are_calibrated_by_monte_carlo():
    # g_k drawn from the prior, data from the model: the 95 % band of each
    # coefficient must cover the truth at 95 % of the coefficients and draws
    rng = np.random.default_rng(7)
    order, n, noise = 20, 60, 0.05
    kernels = [C(1.0) * DC(0.85, 0.8), C(0.5) * TC(0.8)]
    K = dense_prior(kernels, np.arange(order, dtype=float))
    root = np.linalg.cholesky(K + 1e-12 * np.eye(2 * order))
    z = norm.ppf(0.975)
    hits = []
    for _ in range(300):
        u = rng.standard_normal((n, 2))
        index = np.sort(rng.choice(n, size=25, replace=False))
        g = root @ rng.standard_normal(2 * order)
        y = dense_regressor(u, index, order) @ g + np.sqrt(noise) * rng.standard_normal(25)
        model = gm.FIRGaussianProcess(kernels, order=order, noise_level=noise,
                                      optimizer=None).fit(u, y, sample_indices=index)
        mean, std = model.impulse_response(return_std=True)
        hits.append(np.abs(np.ravel(mean) - g) <= z * np.ravel(std))
    coverage = np.mean(hits)
    # 12,000 correlated indicators: a few tenths of a percent of spread
    assert 0.935 <= coverage <= 0.965


# ------------------------------------------------------------- least squares
def test_least_squares_with_two_inputs_and_missing_samples_equals_lstsq():
    rng = np.random.default_rng(8)
    u = rng.standard_normal((300, 2))
    y = rng.standard_normal(100)
    y[[4, 50]] = np.nan
    model = gm.LeastSquaresFIR(factor=3, order=10).fit(u, y)
    index, y_used = used_instants(np.arange(0, 300, 3), y, 10, "zero")
    Phi = dense_regressor(u, index, 10)
    expected = np.linalg.lstsq(Phi, y_used, rcond=None)[0]
    np.testing.assert_allclose(np.ravel(model.coef_), expected, rtol=1e-9, atol=1e-12)
    assert model.coef_.shape == (2, 10)
    mean, std = model.impulse_response([0, 3], return_std=True)
    assert mean.shape == std.shape == (2, 2)


def test_least_squares_counts_the_used_samples():
    rng = np.random.default_rng(9)
    u = rng.standard_normal((60, 2))
    y = rng.standard_normal(20)
    # 2 inputs x order 10 = 20 coefficients: not below the 20 slow samples
    with pytest.raises(gm.IdentifiabilityError, match="M=20"):
        gm.LeastSquaresFIR(factor=3, order=10).fit(u, y)
    y[:5] = np.nan
    with pytest.raises(gm.IdentifiabilityError, match="M=15"):
        gm.LeastSquaresFIR(factor=3, order=8).fit(u, y)
    # "discard" drops the instants 0, 3 and 6, before order - 1 = 8
    with pytest.raises(gm.IdentifiabilityError, match="M=17"):
        gm.LeastSquaresFIR(factor=3, order=9, initial_conditions="discard").fit(
            u, rng.standard_normal(20))


# --------------------------------------------------------- scikit-learn GPR
def test_sampled_convolution_inside_gaussian_process_regressor():
    rng = np.random.default_rng(10)
    u = rng.standard_normal(50)
    index = np.array([1, 4, 5, 9, 13, 20, 22, 30, 31, 40, 47])
    op = gm.SampledConvolution(u, index, order=15)
    y = op.matvec(0.8 ** np.arange(15)) + 0.01 * rng.standard_normal(index.shape[0])
    kernel = C(1.0) * DC(0.8, 0.9)
    X = np.arange(op.n_outputs)[:, None]
    gpr = GaussianProcessRegressor(
        gm.ObservedKernel(kernel, op) + WhiteKernel(1e-4, "fixed"), optimizer=None, alpha=0.0
    ).fit(X, y)
    model = gm.FIRGaussianProcess(kernel, order=15, noise_level=1e-4, optimizer=None).fit(
        u, y, sample_indices=index)
    assert gpr.log_marginal_likelihood_value_ == pytest.approx(
        model.log_marginal_likelihood_value_, rel=1e-9)
    Phi = dense_regressor(u, index, 15)
    np.testing.assert_allclose(op.matrix, Phi)


# ---------------------------------------------------------------- persistence
@pytest.mark.parametrize("name", ["all at once", "periodic, two inputs, records, missing",
                                  "irregular instants"])
def test_saved_and_pickled_models_predict_identically(name, tmp_path):
    model, *_ = make_case(name)
    u_new = np.random.default_rng(11).standard_normal((30, CASES[name]["n_inputs"]))
    u_arg = u_new if CASES[name]["n_inputs"] > 1 else u_new[:, 0]
    path = tmp_path / "model.npz"
    save_model(model, path)
    for loaded in (load_model(path), pickle.loads(pickle.dumps(model))):
        for a, b in zip(loaded.predict(u_arg, return_std=True), model.predict(u_arg, return_std=True)):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(loaded.coef_, model.coef_)
        np.testing.assert_array_equal(loaded.impulse_response([0.5, 2.5]),
                                      model.impulse_response([0.5, 2.5]))


def test_saved_least_squares_with_two_inputs_and_records(tmp_path):
    rng = np.random.default_rng(12)
    us = [rng.standard_normal((150, 2)), rng.standard_normal((120, 2))]
    ys = [rng.standard_normal(50), rng.standard_normal(40)]
    model = gm.LeastSquaresFIR(factor=3, order=12).fit(us, ys)
    save_model(model, tmp_path / "ls.npz")
    loaded = load_model(tmp_path / "ls.npz")
    np.testing.assert_array_equal(loaded.coef_, model.coef_)
    preds = loaded.predict([us[0][:20], us[1][:10]])
    assert isinstance(preds, list) and preds[0].shape == (20,) and preds[1].shape == (10,)
    np.testing.assert_array_equal(preds[0], model.predict(us[0][:20]))


# ---------------------------------------------------------------- bad input
def bad(match, **kwargs):
    return pytest.param(kwargs, match, id=match)


RNG = np.random.default_rng(13)
U1, U2 = RNG.standard_normal(30), RNG.standard_normal((30, 2))
Y10 = RNG.standard_normal(10)


@pytest.mark.parametrize(
    "arguments, match",
    [
        bad("y_slow must be a list", u=[U1, U1], y_slow=Y10),
        bad("y_slow must be a list", u=[U1, U1], y_slow=[Y10]),
        bad("u\\[1\\] has 2 inputs", u=[U1, U2], y_slow=[Y10, Y10]),
        bad("sample_indices must be strictly increasing", u=U1, y_slow=Y10[:3],
            sample_indices=[3, 3, 5]),
        bad("sample_indices must lie in 0..29", u=U1, y_slow=Y10[:3], sample_indices=[3, 5, 30]),
        bad("sample_indices must have one entry per sample", u=U1, y_slow=Y10[:4],
            sample_indices=[3, 5, 7]),
        bad("sample_indices must be a list", u=[U1, U1], y_slow=[Y10, Y10],
            sample_indices=[0, 3]),
        bad("sample_indices must hold integers", u=U1, y_slow=Y10[:2], sample_indices=[0.5, 2.0]),
        bad("y_slow has no finite sample", u=U1, y_slow=np.full(10, np.nan)),
        bad("y_slow\\[1\\] has no finite sample", u=[U1, U1], y_slow=[Y10, np.full(10, np.nan)]),
        bad("must not contain inf", u=U1, y_slow=np.r_[Y10[:9], np.inf]),
        bad("u must be 1-D .* or 2-D", u=np.zeros((30, 2, 2)), y_slow=Y10),
        bad("u must be finite", u=np.r_[U1[:29], np.nan], y_slow=Y10),
    ],
)
@pytest.mark.parametrize("estimator", ["gp", "ls"])
def test_bad_data_is_reported_with_its_name(arguments, match, estimator):
    model = (gm.FIRGaussianProcess(factor=3, order=5, optimizer=None) if estimator == "gp"
             else gm.LeastSquaresFIR(factor=3, order=2))
    with pytest.raises(ValueError, match=match):
        model.fit(**arguments)


def test_bad_parameters_are_reported_with_their_name():
    with pytest.raises(ValueError, match="initial_conditions must be one of"):
        gm.FIRGaussianProcess(initial_conditions="rest", factor=3).fit(U1, Y10)
    with pytest.raises(ValueError, match="initial_conditions must be one of"):
        gm.LeastSquaresFIR(order=2, initial_conditions=None, factor=3).fit(U1, Y10)
    with pytest.raises(ValueError, match="discard.*leaves no slow sample"):
        gm.FIRGaussianProcess(order=29, initial_conditions="discard").fit(
            U1, Y10[:3], sample_indices=[1, 5, 9])
    with pytest.raises(ValueError, match="kernel must be one kernel or a list with one kernel "
                                         "per input \\(2\\); got a list of 3"):
        gm.FIRGaussianProcess([DC(), DC(), DC()], factor=3, order=5).fit(U2, Y10)
    with pytest.raises(ValueError, match="kernel\\[1\\]"):
        gm.FIRGaussianProcess([DC(), "DC"], factor=3, order=5).fit(U2, Y10)
    model = gm.FIRGaussianProcess(factor=3, order=5, optimizer=None).fit(U2, Y10)
    with pytest.raises(ValueError, match="input must be given"):
        model.frequency_response()
    with pytest.raises(ValueError, match="input must be in 0..1"):
        model.frequency_response(input=2)
    with pytest.raises(ValueError, match="u must have 2 input"):
        model.predict(U1)


def test_caller_arrays_are_not_modified():
    u, y = U2.copy(), Y10.copy()
    y[2] = np.nan
    index = np.arange(0, 30, 3)
    copies = [u.copy(), y.copy(), index.copy()]
    gm.FIRGaussianProcess(factor=3, order=5).fit([u], [y], sample_indices=[index])
    for original, copy in zip((u, y, index), copies):
        np.testing.assert_array_equal(original, copy)
