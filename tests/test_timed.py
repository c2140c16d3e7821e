"""Slow samples at their own instants: every number against a brute-force dense computation.

The reference readings are built here from the model alone: the output at
real time ``t`` is ``sum_j u[j] g(t - j)``; a reading with exposure is the
window average, by Gauss-Legendre quadrature on the pieces between ticks
with many more nodes than the library uses; the covariance is the explicit
double sum of the kernel over every pair of (node, lag).
"""

import numpy as np
import pytest
from scipy import linalg
from scipy.stats import multivariate_normal
from sklearn.gaussian_process.kernels import RBF, ConstantKernel as C, Product, Sum

import gpmultirate as gm

from gpmultirate.inference import DataSpacePosterior, log_marginal_likelihood, posterior
from gpmultirate.kernels import DC, PK, SS, TC, observe
from gpmultirate.observations import SampledConvolution, TimedConvolution
from gpmultirate.observations import timed as timed_module
from gpmultirate.observations.timed import check_sample_times

P = 7
N = 24
TIMES = np.array([3.3, 6.05, 8.5, 11.0, 13.71, 17.2, 20.95])
KERNELS = {
    "DC": C(1.5) * DC(alpha=0.75, beta=0.6),
    "DC-negative": DC(alpha=0.8, beta=-0.5),
    "TC": TC(alpha=0.7),
    "SS": C(3.0) * SS(alpha=0.8),
    "PK": PK(alpha=0.8, omega=1.1, sigma1=1.0, sigma2=0.6),
    # with the spread of kernel="auto"'s kept terms: rank four, the lag-weighted basis too
    "PK-spread": PK(alpha=0.8, omega=1.1, sigma1=1.0, sigma2=0.6, omega_std=0.05,
                    rate_std=0.02),
    # the search's terms: the first cell the mode's step response (zero at lag 0)
    "PK-hold": PK(alpha=0.8, omega=1.1, sigma1=1.0, sigma2=0.6, hold=True),
    "PK-hold-spread": PK(alpha=0.8, omega=1.1, sigma1=1.0, sigma2=0.6, omega_std=0.05,
                         rate_std=0.02, hold=True),
    "sum": C(1.0) * DC(alpha=0.7, beta=0.4) + PK(alpha=0.85, omega=0.9),
    "RBF": C(0.5) * RBF(length_scale=1.5),
}


def _input():
    return np.random.default_rng(3).standard_normal(N)


def _nodes(times, exposure, latency, n):
    """Per reading: instants and weights of its window (Gauss-Legendre, split at the ticks)."""
    xi, w = np.polynomial.legendre.leggauss(n)
    out = []
    for t in times:
        end = t - latency
        if exposure == 0:
            out.append((np.array([end]), np.array([1.0])))
            continue
        start = end - exposure
        ticks = range(int(np.ceil(start)), int(np.ceil(end)))
        edges = [start] + [k for k in ticks if start < k < end]
        edges.append(end)
        instants, weights = [], []
        for a, b in zip(edges[:-1], edges[1:]):
            instants.append(a + (b - a) * (xi + 1) / 2)
            weights.append(w * (b - a) / 2 / exposure)
        out.append((np.concatenate(instants), np.concatenate(weights)))
    return out


def _functionals(u, times, exposure, latency, n, order=P):
    """Each reading as ``sum_q c_q g(x_q)``: lags ``x`` and coefficients ``c`` (lags < P)."""
    out = []
    for instants, weights in _nodes(times, exposure, latency, n):
        lags, coefs = [], []
        for s, w in zip(instants, weights):
            for j in range(len(u)):
                if 0 <= s - j < order:
                    lags.append(s - j)
                    coefs.append(w * u[j])
        out.append((np.array(lags), np.array(coefs)))
    return out


def _on_integer_lags(lags, coefs, order=None):
    """``sum_q c_q g(x_q)`` as a combination of ``g`` at integer lags: the hold's prior.

    Between integer lags TC, DC and SS are the Lagrange interpolation of the
    twelve integer lags ``n - 5 .. n + 6`` around ``x = n + d``, zero below
    lag 0, the nodes cut at ``order - 1`` (written out here term by term).
    """
    out = {}
    for x, c in zip(lags, coefs):
        n = int(np.floor(x))
        if x == n:
            out[n] = out.get(n, 0.0) + c
            continue
        nodes = [n + s for s in range(-5, 7) if order is None or n + s <= order - 1]
        for node in nodes:
            weight = 1.0
            for other in nodes:
                if other != node:
                    weight *= (x - other) / (node - other)
            if node >= 0:
                out[node] = out.get(node, 0.0) + c * weight
    keys = np.array(sorted(out), dtype=float)
    return keys, np.array([out[k] for k in sorted(out)])


def _pair(kernel, a, b, order=P):
    """``Cov(sum a_c g(a_x), sum b_c g(b_x))`` under ``kernel``, by its leaves.

    ``a`` or ``b`` with ``order=None`` is ``g`` at real lags outside the readings: the
    nodes of the kernel itself, not cut."""
    (xa, ca, cut_a), (xb, cb, cut_b) = a, b
    if isinstance(kernel, Sum):
        return _pair(kernel.k1, a, b, order) + _pair(kernel.k2, a, b, order)
    if isinstance(kernel, Product) and isinstance(kernel.k1, C):
        return kernel.k1.constant_value * _pair(kernel.k2, a, b, order)
    if isinstance(kernel, (DC, TC, SS)):
        bridge = _bridge(kernel, xa, ca, xb, cb)
        xa, ca = _on_integer_lags(xa, ca, order if cut_a else None)
        xb, cb = _on_integer_lags(xb, cb, order if cut_b else None)
        return ca @ kernel(xa[:, None], xb[:, None]) @ cb + bridge
    return ca @ kernel(xa[:, None], xb[:, None]) @ cb


def _bridge(kernel, xa, ca, xb, cb):
    """The bridge of the hold's prior: ``0.1^2 sin(pi d) sin(pi e) k(n, n)`` on a shared cell."""
    na, nb = np.floor(xa), np.floor(xb)
    shared = na[:, None] == nb[None, :]
    left = ca * np.sin(np.pi * (xa - na)) * kernel.diag(na[:, None])
    right = cb * np.sin(np.pi * (xb - nb))
    return float(0.1**2 * np.sum(shared * np.outer(left, right)))


def _dense_reference(kernel, u, times, exposure=0.0, latency=0.0, n=48, at=None, order=P):
    """The covariance of the readings (and with ``g(at)``) by explicit double sums."""
    funcs = _functionals(u, times, exposure, latency, n, order)
    M = len(funcs)
    S = np.empty((M, M))
    for a in range(M):
        for b in range(a, M):  # a covariance: the other triangle by symmetry
            S[a, b] = S[b, a] = _pair(kernel, (*funcs[a], True), (*funcs[b], True), order)
    if at is None:
        return S
    cross = np.array([[_pair(kernel, (np.array([x]), np.ones(1), False), (*f, True))
                       for f in funcs] for x in at])
    return S, cross


def _data(S, noise):
    rng = np.random.default_rng(7)
    root = linalg.cholesky(S + noise * np.eye(S.shape[0]), lower=True)
    return root @ rng.standard_normal(S.shape[0])


@pytest.mark.parametrize("name", list(KERNELS))
def test_covariance_matches_dense_sums_without_exposure(name):
    kernel, u = KERNELS[name], _input()
    op = TimedConvolution(u, TIMES, order=P, latency=0.4)
    S = observe(kernel, op).covariance()
    reference = _dense_reference(kernel, u, TIMES, latency=0.4)
    assert np.allclose(S, reference, rtol=1e-6, atol=1e-9 * np.abs(reference).max())


@pytest.mark.parametrize("name", ["PK", "PK-spread", "constant"])
@pytest.mark.parametrize("exposure", [0.0, 0.7])
def test_low_rank_cross_covariance_is_the_dense_one(name, exposure):
    # Cov(g(lags), y) of PK (with and without its spread) and a constant from their
    # readings' basis, against the kernel at the real lags of every point
    kernel = C(0.7) if name == "constant" else KERNELS[name]
    op = TimedConvolution(_input(), TIMES, order=P, exposure=exposure, latency=0.3)
    lags = np.array([[0.0], [0.3], [2.5], [5.75], [6.0]])
    found = observe(kernel, op).cross_covariance(lags)
    expected = op.dense_cross_covariance(kernel, lags)
    assert found.shape == expected.shape == (5, TIMES.shape[0])
    np.testing.assert_allclose(found, expected, rtol=1e-10, atol=1e-12 * np.abs(expected).max())
    # the regressor times the kernel on the integer lags: the same at lags 0..P-1
    np.testing.assert_allclose(observe(kernel, op).regressor_times_kernel(),
                               op.dense_cross_covariance(kernel, op.lags).T, rtol=1e-10,
                               atol=1e-12 * np.abs(expected).max())


@pytest.mark.slow
@pytest.mark.parametrize("name", list(KERNELS))
def test_covariance_matches_fine_quadrature_with_exposure(name):
    kernel, u = KERNELS[name], _input()
    op = TimedConvolution(u, TIMES, order=P, exposure=0.6, latency=0.3)
    S = observe(kernel, op).covariance()
    reference = _dense_reference(kernel, u, TIMES, 0.6, 0.3, n=96)
    assert np.max(np.abs(S - reference)) <= 1e-4 * np.abs(reference).max()


@pytest.mark.parametrize("name", list(KERNELS))
def test_posterior_and_evidence_match_dense(name):
    _check_posterior(name, 0.0, 1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(KERNELS))
def test_posterior_and_evidence_match_dense_with_exposure(name):
    _check_posterior(name, 0.5, 1e-4)


def test_posterior_with_exposure_matches_dense_sum():
    _check_posterior("sum", 0.5, 1e-4, n=64, times=TIMES[:4])


def _check_posterior(name, exposure, tol, n=96, times=TIMES):
    kernel, u = KERNELS[name], _input()
    lags = np.array([0.0, 0.35, 1.5, 2.9, 4.25, 6.5])
    op = TimedConvolution(u, times, order=P, exposure=exposure, latency=0.2)
    S, cross = _dense_reference(kernel, u, times, exposure, 0.2, n=n, at=lags)
    noise = 1e-3 * np.trace(S) / S.shape[0]
    y = _data(S, noise)
    Ky = S + noise * np.eye(S.shape[0])
    mean_ref = cross @ linalg.solve(Ky, y)
    var_ref = np.diag(kernel(lags[:, None]) - cross @ linalg.solve(Ky, cross.T))
    evidence_ref = multivariate_normal(np.zeros(y.shape[0]), Ky).logpdf(y)
    post = posterior(op, kernel, noise, y)
    assert isinstance(post, DataSpacePosterior)
    mean, var = post.at_lags(lags[:, None], full_cov=False)
    scale = np.abs(mean_ref).max()
    assert np.max(np.abs(mean - mean_ref)) <= tol * scale
    assert np.allclose(np.sqrt(var), np.sqrt(var_ref), rtol=tol, atol=tol * np.sqrt(var_ref).max())
    value = log_marginal_likelihood(op, kernel, noise, y, False, False)
    assert abs(value - evidence_ref) <= tol * abs(evidence_ref)
    assert abs(post.log_marginal_likelihood - evidence_ref) <= tol * abs(evidence_ref)


@pytest.mark.parametrize("name", list(KERNELS))
@pytest.mark.parametrize("exposure", [
    0.0, pytest.param(0.7, marks=pytest.mark.slow),
])
def test_gradient_matches_finite_differences(name, exposure):
    if name == "RBF" and exposure:
        pytest.skip("the dense route under exposure is covered by test_dense_gradient_exposure")
    _check_gradient(name, exposure)


def test_gradient_with_exposure_matches_finite_differences():
    _check_gradient("sum", 0.7)


def _check_gradient(name, exposure):
    kernel, u = KERNELS[name], _input()
    op = TimedConvolution(u, TIMES, order=P, exposure=exposure, latency=0.1)
    S = observe(kernel, op).covariance()
    noise = 1e-2 * np.trace(S) / S.shape[0]
    y = _data(S, noise)
    value, grad = log_marginal_likelihood(op, kernel, noise, y, True, True)
    theta = np.append(kernel.theta, np.log(noise))
    step = 1e-6
    for j in range(theta.shape[0]):
        moved = []
        for sign in (1, -1):
            t = theta.copy()
            t[j] += sign * step
            moved.append(log_marginal_likelihood(
                op, kernel.clone_with_theta(t[:-1]), np.exp(t[-1]), y, False, False))
        numeric = (moved[0] - moved[1]) / (2 * step)
        assert np.isclose(grad[j], numeric, rtol=1e-5, atol=1e-6 * abs(value))


def test_on_the_ticks_equals_the_sampled_convolution():
    u = _input()
    kernel = KERNELS["sum"]
    timed = TimedConvolution(u, [2.0, 5.0, 9.0, 14.0, 20.0], order=P)
    ticks = SampledConvolution(u, [2, 5, 9, 14, 20], order=P)
    assert np.allclose(observe(kernel, timed).covariance(), observe(kernel, ticks).covariance())
    assert np.allclose(timed.cross_covariance(kernel, timed.lags),
                       kernel(ticks.lags) @ ticks.matrix.T)


def test_records_stack_shares_the_response():
    u, kernel = _input(), KERNELS["DC"]
    first = TimedConvolution(u[:12], [2.5, 7.25], order=P)
    second = TimedConvolution(u[12:], [1.5, 9.75], order=P, exposure=0.0)
    stacked = TimedConvolution.stack([first, second])
    S = observe(kernel, stacked).covariance()
    # the records' readings as one experiment: explicit sums over both inputs
    funcs = _functionals(u[:12].tolist() + [0.0] * 12, [2.5, 7.25], 0, 0, 1)
    funcs += _functionals(u[12:].tolist() + [0.0] * 12, [1.5, 9.75], 0, 0, 1)
    reference = np.array([[_pair(kernel, (*f1, True), (*f2, True)) for f2 in funcs]
                          for f1 in funcs])
    assert np.allclose(S, reference, rtol=1e-10)
    assert stacked.n_outputs == 4 and len(stacked.records) == 2


def test_structured_exposure_is_exact_at_any_node_count():
    # the kink of TC/DC/SS is integrated exactly: 8 and 16 nodes agree to rounding
    u = _input()
    for name in ("DC", "DC-negative", "TC", "SS", "PK", "PK-spread"):
        found = []
        for nodes in (8, 16):
            op = TimedConvolution(u, TIMES, order=P, exposure=0.8, latency=0.2, nodes=nodes)
            found.append(observe(KERNELS[name], op).covariance())
            found.append(op.cross_covariance(KERNELS[name], np.array([0.3, 2.5, 5.75])))
        assert np.allclose(found[0], found[2], rtol=1e-10, atol=1e-12)
        assert np.allclose(found[1], found[3], rtol=1e-10, atol=1e-12)


@pytest.mark.slow
def test_dense_route_quadrature_error_below_1e4():
    # the dense route integrates by the points: smooth kernels converge fast
    u, kernel = _input(), KERNELS["RBF"]
    times = TIMES[:4]
    reference = _dense_reference(kernel, u, times, 0.8, 0.0, n=64)
    op = TimedConvolution(u, times, order=P, exposure=0.8)
    S = observe(kernel, op).covariance()
    assert np.max(np.abs(S - reference)) <= 1e-8 * np.abs(reference).max()


def test_checks_name_the_argument():
    u = _input()
    with pytest.raises(ValueError, match="strictly increasing"):
        check_sample_times([1.0, 1.0], N)
    with pytest.raises(ValueError, match=r"sample_times must lie in \[0, 24\)"):
        TimedConvolution(u, [1.0, 24.0], order=P)
    with pytest.raises(ValueError, match="exposure"):
        TimedConvolution(u, [1.0, 2.0], order=P, exposure=-1.0)
    with pytest.raises(ValueError, match="latency"):
        TimedConvolution(u, [1.0, 2.0], order=P, latency=float("nan"))
    with pytest.raises(TypeError, match="no regressor"):
        TimedConvolution(u, [1.0, 2.0], order=P).matrix


def test_discard_keeps_late_windows_only():
    u = _input()
    op = TimedConvolution(u, [2.5, 6.5, 9.5], order=P, exposure=0.5,
                          initial_conditions="discard")
    assert op.used.tolist() == [False, True, True]
    assert np.array_equal(op.sample_times, [6.5, 9.5])


@pytest.mark.slow
def test_dense_gradient_exposure():
    kernel, u = KERNELS["RBF"], _input()
    op = TimedConvolution(u, TIMES[:4], order=P, exposure=0.7, nodes=4)
    S = observe(kernel, op).covariance()
    noise = 1e-2 * np.trace(S) / S.shape[0]
    y = _data(S, noise)
    _, grad = log_marginal_likelihood(op, kernel, noise, y, True, False)
    for j in range(kernel.theta.shape[0]):
        values = []
        for sign in (1, -1):
            t = kernel.theta.copy()
            t[j] += sign * 1e-6
            values.append(log_marginal_likelihood(op, kernel.clone_with_theta(t), noise, y,
                                                  False, False))
        assert np.isclose(grad[j], (values[0] - values[1]) / 2e-6, rtol=1e-5)


# ------------------------------------------------------------- the estimators
N_FIT, F_FIT, P_FIT = 90, 3, 12


def _fit_data(seed=0):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(N_FIT)
    g = 0.8 ** np.arange(P_FIT) * np.cos(0.6 * np.arange(P_FIT))
    ticks = np.arange(0, N_FIT, F_FIT)
    y = np.convolve(u, g)[:N_FIT][ticks] + 1e-2 * rng.standard_normal(ticks.shape[0])
    times = ticks + rng.uniform(0, 1, ticks.shape[0])
    return u, y, ticks, times


def test_times_on_the_ticks_give_the_fit_of_the_indices():
    u, y, ticks, _ = _fit_data()
    a = gm.FIRGaussianProcess(C(1.0) * DC(), order=P_FIT).fit(u, y, sample_indices=ticks)
    b = gm.FIRGaussianProcess(C(1.0) * DC(), order=P_FIT).fit(u, y, sample_times=ticks * 1.0)
    assert np.allclose(a.coef_, b.coef_)
    assert np.isclose(a.log_marginal_likelihood_value_, b.log_marginal_likelihood_value_)
    # a latency of whole periods: the stamps are late by it
    c = gm.FIRGaussianProcess(C(1.0) * DC(), order=P_FIT, latency=2.0).fit(
        u, y[:-1], sample_times=ticks[:-1] + 2.0)
    d = gm.FIRGaussianProcess(C(1.0) * DC(), order=P_FIT).fit(u, y[:-1], sample_indices=ticks[:-1])
    assert np.allclose(c.coef_, d.coef_)


def test_prediction_at_the_ticks_is_predict():
    u, y, ticks, times = _fit_data()
    for model in (
        gm.FIRGaussianProcess(C(1.0) * DC(), order=P_FIT).fit(u, y, sample_indices=ticks),
        gm.FIRGaussianProcess(C(1.0) * DC(), order=P_FIT).fit(u, y, sample_times=times),
    ):
        mean, std = model.predict(u, return_std=True)
        every = np.arange(N_FIT, dtype=float)
        at_ticks, at_std = model.predict(u, sample_times=every, return_std=True)
        assert np.allclose(at_ticks, mean, rtol=1e-6, atol=1e-7 * np.abs(mean).max())
        assert np.allclose(at_std, std, rtol=1e-5, atol=1e-6 * std.max())


@pytest.mark.parametrize("initial_conditions", ["zero", "periodic"])
def test_readings_on_the_ticks_without_bands_are_the_output_there(initial_conditions):
    # the mean alone at whole-period stamps comes from the fast output (no joint with the
    # data): the same as the readings' conditional mean, latency included
    u, y, ticks, times = _fit_data()
    model = gm.FIRGaussianProcess(C(1.0) * DC(), order=P_FIT, latency=2.0,
                                  initial_conditions=initial_conditions).fit(
        u, y, sample_times=times + 2.0)
    stamps = np.arange(2.0, N_FIT, 3.0)
    alone = model.predict(u, sample_times=stamps)
    joint, _ = model.predict(u, sample_times=stamps, return_std=True)
    np.testing.assert_allclose(alone, joint, rtol=1e-7, atol=1e-9 * np.abs(joint).max())
    np.testing.assert_allclose(alone, model.predict(u)[(stamps - 2.0).astype(int)],
                               rtol=1e-12, atol=0)
    # a stamp whose instant falls before the record: the readings' own model
    early = np.concatenate([[1.0], stamps])
    np.testing.assert_allclose(model.predict(u, sample_times=early),
                               model.predict(u, sample_times=early, return_std=True)[0],
                               rtol=1e-7, atol=1e-9 * np.abs(joint).max())


def test_readings_predicted_as_a_dense_gaussian_conditional():
    _check_readings(0.0, 1e-6, 1)


@pytest.mark.slow
def test_readings_with_exposure_predicted_as_a_dense_gaussian_conditional():
    _check_readings(0.4, 1e-4, 96)


def _check_readings(exposure, tol, n):
    # fixed hyperparameters: the readings' mean and std are S (S + g I)^{-1} y and its variance
    u, y, ticks, times = _fit_data(1)
    kernel = C(0.8) * DC(0.75, 0.7)
    noise = 1e-3
    # the record of the reference: N = 24 fast samples, order P = 7
    u, y, times = u[:24], y[:7], times[:7]
    model = gm.FIRGaussianProcess(kernel, order=7, noise_level=noise, optimizer=None,
                                  normalize=False, exposure=exposure, latency=0.3)
    model.fit(u, y, sample_times=times)
    new = np.array([5.5, 17.25, 22.0])
    both = np.concatenate([times, new])
    both_u = u
    S_all = _dense_reference(kernel, both_u, np.sort(both), exposure, 0.3, n=n)
    order = np.argsort(both)
    rank = np.empty_like(order)
    rank[order] = np.arange(order.shape[0])
    S_all = S_all[np.ix_(rank, rank)]
    M = times.shape[0]
    Ky = S_all[:M, :M] + noise * np.eye(M)
    mean_ref = S_all[M:, :M] @ linalg.solve(Ky, y)
    var_ref = np.diag(S_all[M:, M:] - S_all[M:, :M] @ linalg.solve(Ky, S_all[:M, M:]))
    mean, std = model.predict(u, sample_times=new, return_std=True)
    assert np.allclose(mean, mean_ref, rtol=tol, atol=tol * np.abs(mean_ref).max())
    assert np.allclose(std, np.sqrt(var_ref), rtol=tol)


def test_records_and_missing_readings():
    u, y, _, times = _fit_data()
    y = y.copy()
    y[4] = np.nan
    model = gm.FIRGaussianProcess(C(1.0) * DC(), order=P_FIT).fit(
        [u[:45], u[45:]], [y[:15], y[15:]], sample_times=[times[:15], times[15:] - 45])
    assert model.y_slow_.shape == (29,)
    assert isinstance(model.observation_, gm.TimedConvolution)


@pytest.mark.slow
def test_two_inputs():
    # several inputs: each input's kernel on its own readings (PerInputKernel)
    u, y, _, times = _fit_data()
    u2 = np.column_stack([u, np.roll(u, 7)])
    model = gm.FIRGaussianProcess(order=6).fit(u2[:45], y[:15],
                                                sample_times=times[:15])
    assert model.coef_.shape == (2, 6)


def test_least_squares_on_the_ticks_only():
    u, y, ticks, times = _fit_data()
    a = gm.LeastSquaresFIR(order=P_FIT).fit(u, y, sample_indices=ticks)
    b = gm.LeastSquaresFIR(order=P_FIT).fit(u, y, sample_times=ticks * 1.0)
    assert np.allclose(a.coef_, b.coef_)
    with pytest.raises(ValueError, match="no model between the integer lags"):
        gm.LeastSquaresFIR(order=P_FIT).fit(u, y, sample_times=times)
    with pytest.raises(ValueError, match="no model between the integer lags"):
        a.predict(u, sample_times=[1.5])


def test_checks():
    u, y, ticks, times = _fit_data()
    with pytest.raises(ValueError, match="not both"):
        gm.FIRGaussianProcess(order=P_FIT).fit(u, y, sample_indices=ticks, sample_times=times)
    with pytest.raises(ValueError, match="give sample_times"):
        gm.FIRGaussianProcess(order=P_FIT, exposure=0.5).fit(u, y, sample_indices=ticks)
    with pytest.raises(ValueError, match="exposure must be a non-negative"):
        gm.FIRGaussianProcess(order=P_FIT, exposure=-0.5).fit(u, y, sample_times=times)
    with pytest.raises(ValueError, match="strictly increasing"):
        gm.FIRGaussianProcess(order=P_FIT).fit(u, y, sample_times=times[::-1])
    model = gm.FIRGaussianProcess(exposure=0.5)
    assert model.get_params()["exposure"] == 0.5


# ------------------------------------------------------- the band between the ticks
def test_plot_intersample_draws_the_band_between_the_ticks():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from gpmultirate.plotting import IntersamplePlot, plot_intersample
    from gpmultirate.responses import normal_quantile

    u, y, _, times = _fit_data()
    model = gm.FIRGaussianProcess(C(1.0) * DC(), order=P_FIT, exposure=0.5, latency=0.2,
                                  optimizer=None, noise_level=1e-4).fit(u, y, sample_times=times)
    fig, ax = plt.subplots()
    shown = plt.show
    try:
        plt.show = lambda *a, **k: pytest.fail("plot_intersample must not show")
        before = plt.get_fignums()
        drawn = plot_intersample(model, u, y_slow=y, sample_times=times, sample_time=0.01,
                                 window=(30, 45), between=4, ax=ax)
    finally:
        plt.show = shown
    assert isinstance(drawn, IntersamplePlot) and drawn.ax is ax
    assert plt.get_fignums() == before
    grid = np.arange(120, 180) / 4
    np.testing.assert_allclose(drawn.mean_line.get_xdata(), grid * 0.01)
    # the band is the model's readings on the grid, an independent call of predict
    mean, std = model.predict(u, sample_times=grid, return_std=True)
    np.testing.assert_allclose(drawn.mean_line.get_ydata(), mean)
    vertices = drawn.band.get_paths()[0].vertices
    z = normal_quantile(0.95)
    assert np.isclose(vertices[:, 1].max(), (mean + z * std).max())
    assert np.isclose(vertices[:, 1].min(), (mean - z * std).min())
    inside = (times >= 30) & (times < 45)
    np.testing.assert_allclose(drawn.slow_markers.get_xdata(), times[inside] * 0.01)
    np.testing.assert_array_equal(drawn.slow_markers.get_ydata(), y[inside])
    # a model fitted between the ticks draws between them by default (8 per period)
    default = plot_intersample(model, u, window=(30, 32))
    assert default.mean_line.get_xdata().shape == (16,) and default.slow_markers is None
    plt.close("all")


def test_plot_intersample_between_checks():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from gpmultirate.plotting import plot_intersample

    u, y, ticks, times = _fit_data()
    model = gm.FIRGaussianProcess(C(1.0) * DC(), order=P_FIT, optimizer=None,
                                  noise_level=1e-4).fit(u, y, sample_times=times)
    with pytest.raises(ValueError, match="sample_times"):
        plot_intersample(model, u, y_slow=y)
    with pytest.raises(ValueError, match="y_slow"):
        plot_intersample(model, u, y_slow=y[:-1], sample_times=times)
    with pytest.raises(ValueError, match="between"):
        plot_intersample(model, u, between=0)
    with pytest.raises(ValueError, match="factor and offset"):
        plot_intersample(model, u, factor=3)
    least = gm.LeastSquaresFIR(order=P_FIT).fit(u, y, sample_indices=ticks)
    with pytest.raises(ValueError, match="FIRGaussianProcess"):
        plot_intersample(least, u, between=4)
    plt.close("all")


def test_multioutput_passes_the_instants_through():
    u, y, _, times = _fit_data()
    y2 = np.column_stack([y, 0.5 * y + 0.01])
    base = gm.FIRGaussianProcess(C(1.0) * DC(), order=P_FIT, exposure=0.3, latency=0.1,
                                 optimizer=None, noise_level=1e-4)
    several = gm.MultiOutputFIR(base, n_jobs=1).fit(u, y2, sample_times=times)
    new = np.array([5.5, 17.25, 40.1])
    mean, std = several.predict(u, return_std=True, sample_times=new)
    assert mean.shape == (3, 2)
    for j in range(2):
        alone = gm.FIRGaussianProcess(C(1.0) * DC(), order=P_FIT, exposure=0.3, latency=0.1,
                                      optimizer=None, noise_level=1e-4).fit(
            u, y2[:, j], sample_times=times)
        assert isinstance(several.estimators_[j].observation_, gm.TimedConvolution)
        np.testing.assert_allclose(several.estimators_[j].coef_, alone.coef_, rtol=1e-10)
        m, s = alone.predict(u, return_std=True, sample_times=new)
        np.testing.assert_allclose(mean[:, j], m, rtol=1e-10)
        np.testing.assert_allclose(std[:, j], s, rtol=1e-10)
    listed = several.predict([u, u], sample_times=[new, new])
    np.testing.assert_allclose(listed[1], mean)
    with pytest.raises(ValueError, match="one entry per record"):
        several.predict([u, u], sample_times=new)


# ------------------------------------------- exposure windows in closed form
def test_independent_inputs_sum_each_inputs_structured_readings():
    # PerInputKernel: the readings' covariance is the sum of each input's, each by its own
    # structure (semiseparable DC and TC, exact with an exposure) instead of the dense
    # route; checked against each input's single-input observation and, without an
    # exposure, against the dense route
    from gpmultirate.kernels import PerInputKernel
    from gpmultirate.kernels.instants import DenseTimedTerm

    rng = np.random.default_rng(5)
    u = rng.standard_normal((60, 2))
    t = np.arange(0, 60, 3) + rng.uniform(0, 1, 20)
    kernels = [C(1.3) * DC(0.9, 0.7), C(0.7) * TC(0.8)]
    kernel = PerInputKernel(kernels)
    for exposure in (0.0, 0.5):
        op = TimedConvolution(u, t, 12, exposure=exposure, latency=0.2)
        S, items = observe(kernel, op).covariance_with_derivatives()
        singles = [observe(k, TimedConvolution(u[:, i], t, 12, exposure=exposure, latency=0.2))
                   for i, k in enumerate(kernels)]
        parts = [single.covariance_with_derivatives() for single in singles]
        assert np.allclose(S, sum(p[0] for p in parts), rtol=1e-12, atol=0)
        expected = [d for p in parts for d in p[1]]
        assert len(items) == len(expected) == kernel.theta.shape[0]
        for d, e in zip(items, expected):
            assert np.allclose(d, e, rtol=1e-12, atol=1e-14 * np.abs(e).max())
        cross = observe(kernel, op).regressor_times_kernel()
        assert np.allclose(cross, np.hstack([s.regressor_times_kernel() for s in singles]))
        if exposure == 0.0:  # each input's readings by explicit sums, added
            reference = sum(_dense_reference(k, u[:, i], t, 0.0, 0.2, order=12)
                            for i, k in enumerate(kernels))
            assert np.allclose(S, reference, rtol=1e-10)
    # a fit of two inputs at its own instants, evidence against the dense route
    y = rng.standard_normal(20)
    model = gm.FIRGaussianProcess(kernel, optimizer=None, noise_level=0.1, order=12).fit(
        u, y, sample_times=t)
    S = sum(_dense_reference(k, u[:, i], t, order=12) for i, k in enumerate(kernels))
    S = S + 0.1 * np.eye(20)
    reference = multivariate_normal(np.zeros(20), S).logpdf(y)
    assert model.log_marginal_likelihood_value_ == pytest.approx(reference, rel=1e-9)


@pytest.mark.slow
def test_order_too_short_is_named_at_own_instants():
    # more readings than coefficients, a response far longer than the order: the residuals
    # of the readings (the interpolated fit's rows, or y - gamma S^{-1} y of the exact one)
    # are correlated and the OrderWarning names a longer order
    rng = np.random.default_rng(2)
    u = rng.standard_normal(900)
    t = np.arange(0, 900, 3) + rng.uniform(0, 1, 300)
    y = TimedConvolution(u, t, 400).lag_functionals(
        lambda x: (0.99 ** x * np.cos(0.3 * x))[:, None])[:, 0]
    y = y + 0.01 * rng.standard_normal(300)
    for route in ("exact", "interpolated"):
        with pytest.warns(gm.OrderWarning, match="order=40 looks too short"):
            model = gm.FIRGaussianProcess(order=40, between_ticks=route).fit(
                u, y, sample_times=t)
    # the identity the exact route's check reads: y - gamma S_y^{-1} y is the posterior
    # mean of the readings (predict at their instants), S_y formed densely here
    from gpmultirate.kernels.instants import DenseTimedTerm

    u, y, t = u[:180], y[:60], t[:60]  # still more readings than coefficients
    model = gm.FIRGaussianProcess(DC(0.9, 0.8), optimizer=None, noise_level=0.01,
                                  order=40, between_ticks="exact").fit(u, y, sample_times=t)
    S = _dense_reference(model.kernel_, u, t, order=40)
    fitted = y - 0.01 * np.linalg.solve(S + 0.01 * np.eye(60), y)
    mean = model.predict(u, sample_times=t)
    assert np.allclose(fitted, mean, rtol=1e-7, atol=1e-9 * np.abs(mean).max())


@pytest.mark.parametrize("noise_kernel", ["auto", "ar1", "matern12"])
def test_disturbances_with_more_readings_than_coefficients_off_the_ticks(noise_kernel):
    # readings on a uniform grid between the ticks, more of them than coefficients: the
    # AR(1) routes need a regressor on the integer lags, so the readings take the dense one
    rng = np.random.default_rng(9)
    u = rng.standard_normal(300)
    t = np.arange(100) * 3.0 + 0.5
    y = TimedConvolution(u, t, 20).lag_functionals(lambda x: (0.8 ** x)[:, None])[:, 0]
    y = y + np.cumsum(0.05 * rng.standard_normal(100)) + 0.01 * rng.standard_normal(100)
    model = gm.FIRGaussianProcess(order=20, noise_kernel=noise_kernel).fit(u, y, sample_times=t)
    assert model.observation_.n_outputs > model.observation_.n_coefficients
    assert np.isfinite(model.log_marginal_likelihood_value_)
    if noise_kernel != "auto":
        assert model.noise_kernel_ != "white"


def test_independent_inputs_over_several_records():
    from gpmultirate.kernels import PerInputKernel
    from gpmultirate.kernels.instants import DenseTimedTerm

    rng = np.random.default_rng(6)
    kernel = PerInputKernel([C(1.3) * DC(0.9, 0.7), C(0.7) * TC(0.8)])
    records = [TimedConvolution(rng.standard_normal((n, 2)),
                                np.arange(1, n, 3) + rng.uniform(0, 1, len(range(1, n, 3))), 10)
               for n in (40, 31)]
    op = TimedConvolution.stack(records)
    S = observe(kernel, op).covariance()
    # the readings of both records, of each input, by explicit sums (one response)
    reference = 0.0
    for i, k in enumerate(kernel.kernels):
        funcs = [f for r in records
                 for f in _functionals(r._inputs[:, i], r.sample_times, 0, 0, 1, order=10)]
        reference = reference + np.array(
            [[_pair(k, (*f1, True), (*f2, True), 10) for f2 in funcs] for f1 in funcs])
    assert np.allclose(S, reference, rtol=1e-10, atol=1e-12)
    assert op.input_block(1).input_block(0) is op.input_block(1)  # one input: itself


def _record(n=150):
    rng = np.random.default_rng(1)
    u = rng.standard_normal(n)
    y = np.convolve(u, 0.8 ** np.arange(20))[:n] + 0.05 * rng.standard_normal(n)
    return u, y[::3], np.arange(0.0, n, 3.0)


@pytest.mark.parametrize("params, name", [
    ({"latency": 1000}, "latency"), ({"latency": 1000.5}, "latency"), ({"latency": 148.0}, "latency"),
    ({"exposure": 0.5, "latency": 160}, "latency"), ({"exposure": 1000}, "exposure"),
    ({"exposure": 1e12}, "exposure"), ({"exposure": 150.5}, "exposure"),
    ({"exposure": 1e300, "latency": 1e300}, "exposure"),
])
def test_time_parameters_beyond_the_record_are_refused_at_once(params, name):
    import time
    import tracemalloc

    u, y_slow, times = _record()
    tracemalloc.start()
    started = time.process_time()  # CPU seconds: a busy machine does not slow a refusal
    try:
        with pytest.raises(ValueError, match=f"^{name} must"):
            gm.FIRGaussianProcess(order=20, **params).fit(u, y_slow, sample_times=times)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert time.process_time() - started < 2.0 and peak < 20e6
    # the readings of a prediction are checked against its record too
    with pytest.raises(ValueError, match=f"^{name} must"):
        TimedConvolution(u, times, 20, exposure=params.get("exposure", 0.0),
                         latency=params.get("latency", 0.0))


@pytest.mark.parametrize("value", ["0.5", b"1", True, np.array(0.5), None, [0.5]])
@pytest.mark.parametrize("name", ["exposure", "latency"])
def test_time_parameters_must_be_real_numbers(name, value):
    u, y_slow, times = _record()
    with pytest.raises(ValueError, match=f"^{name} must be a"):
        gm.FIRGaussianProcess(order=20, **{name: value}).fit(u, y_slow, sample_times=times)


def test_a_latency_that_moves_early_readings_before_the_record_is_a_fit_at_rest():
    # readings whose instant t - L falls before the record see the output at
    # rest (zero for any response): the fit of the others alone, on the ticks
    u, y_slow, times = _record(60)
    params = dict(kernel=C(1.0) * DC(0.8, 0.5), order=10, optimizer=None, noise_level=1e-2)
    model = gm.FIRGaussianProcess(latency=5.0, **params).fit(u, y_slow, sample_times=times)
    late = times >= 5.0
    reference = gm.FIRGaussianProcess(**params).fit(
        u, y_slow[late], sample_indices=(times[late] - 5.0).astype(int))
    np.testing.assert_allclose(model.coef_, reference.coef_, rtol=1e-9, atol=1e-12)


def test_integer_sample_times_out_of_range_are_named_with_the_given_values():
    u, y_slow, times = _record()
    for bad, shown in ((np.arange(-3, 147, 3), "from -3 to 144"),
                       (np.append(np.arange(0.0, 147.0, 3.0), 1e20), "from 0 to 1e+20")):
        with pytest.raises(ValueError, match="^sample_times must lie in") as error:
            gm.FIRGaussianProcess(order=20).fit(u, y_slow, sample_times=bad)
        assert shown in str(error.value)


def test_exposure_windows_beyond_the_memory_are_refused_before_forming_them(monkeypatch):
    from gpmultirate.exceptions import MemoryLimitError

    u, y_slow, times = _record()
    monkeypatch.setenv("GPMULTIRATE_MEMORY_LIMIT", str(10**7))
    # 50 readings of 100 periods: 5050 pieces between ticks, 16 points each, 41 MB
    with pytest.raises(MemoryLimitError, match="^exposure 100 over 50 readings .* 5050 pieces"):
        gm.FIRGaussianProcess(order=20, exposure=100.0).fit(u, y_slow, sample_times=times + 0.5)


class _FallingBridge(DC):
    """DC whose bridge variance is written to fall with ``alpha`` on odd cells: both signs of
    ``dv`` for the bridge's rank-k updates (the integer-lag kernel is DC's)."""

    def integer_diagonal(self, t, eval_gradient=False):
        found = super().integer_diagonal(t, eval_gradient)
        if not eval_gradient:
            return found
        values, gradients = found
        sign = np.where(np.asarray(t) % 2 == 1, -1.0, 1.0)
        return values, {name: sign * d for name, d in gradients.items()}


@pytest.mark.parametrize("kernel", [DC(0.9, 0.6), TC(0.85), _FallingBridge(0.9, -0.4)],
                         ids=["DC", "TC", "both signs"])
def test_the_bridge_derivatives_and_contraction_against_psi_written_out(kernel):
    """``S``, ``dS_j`` and ``tr(W dS_j)`` of the exact route: the rows on the integer lags'
    (every route of the integer lags) plus ``Psi diag(v) Psi^T`` and ``Psi diag(dv_j) Psi^T``
    formed densely from the observation's bridge rows and the kernel's diagonal."""
    from gpmultirate.kernels.hold import BRIDGE_SCALE

    rng = np.random.default_rng(5)
    u = rng.standard_normal(120)
    times = np.arange(15, 120, 2) + rng.uniform(0, 1, len(range(15, 120, 2)))
    P = 40
    timed = TimedConvolution(u, times, P, exposure=0.7)
    term = observe(kernel, timed)
    inner = observe(kernel, timed.on_integer_lags())
    Psi = np.array(timed.bridge_rows())
    v, dv = kernel.integer_diagonal(np.arange(P, dtype=float), eval_gradient=True)
    free = [h.name for h in kernel.hyperparameters if not h.fixed]
    bridge = Psi @ np.diag(BRIDGE_SCALE**2 * v) @ Psi.T
    d_bridge = [Psi @ np.diag(BRIDGE_SCALE**2 * dv[name]) @ Psi.T for name in free]
    S_inner, d_inner = inner.covariance_with_derivatives()
    scale = np.abs(S_inner + bridge).max()
    np.testing.assert_allclose(term.covariance(), S_inner + bridge, rtol=1e-10,
                               atol=1e-12 * scale)
    S, items = term.covariance_with_derivatives()
    np.testing.assert_allclose(S, S_inner + bridge, rtol=1e-10, atol=1e-12 * scale)
    for item, d, e in zip(items, d_inner, d_bridge):
        np.testing.assert_allclose(item, d + e, rtol=1e-10, atol=1e-12 * np.abs(d + e).max())
    W = rng.standard_normal((timed.n_outputs, timed.n_outputs))
    W = W + W.T
    S, contract = term.covariance_with_contractor()
    expected = np.array([np.sum(W * (d + e)) for d, e in zip(d_inner, d_bridge)])
    np.testing.assert_allclose(S, S_inner + bridge, rtol=1e-10, atol=1e-12 * scale)
    np.testing.assert_allclose(contract(W), expected, rtol=1e-9,
                               atol=1e-11 * np.abs(expected).max())


@pytest.mark.parametrize("name", ["DC", "DC-negative", "TC", "SS", "PK", "PK-spread", "sum",
                                  pytest.param("RBF", marks=pytest.mark.slow),  # dense: 5 s
                                  "per input", "constant"])
def test_covariance_blocks_are_the_joint_covariances_blocks(name):
    """The readings' covariance with the data they are stacked after, and their variances,
    formed alone (each structured route, the bridge, sums and constants) equal the blocks of
    the joint ``S``."""
    from gpmultirate.kernels import PerInputKernel

    rng = np.random.default_rng(11)
    inputs = 2 if name == "per input" else 1
    u = rng.standard_normal((120, inputs)) if inputs > 1 else rng.standard_normal(120)
    times = np.arange(15, 119, 3) + rng.uniform(0, 1, 35)
    new_times = np.sort(rng.uniform(10, 119, 9))
    if name == "RBF":  # the dense route, a double integral per pair of readings: fewer of them
        times, new_times = times[::3], new_times[::2]
    data = TimedConvolution(u, times, 40, exposure=0.7, latency=0.2)
    new = TimedConvolution(u, new_times, 40, exposure=0.7, latency=0.2)
    joint = TimedConvolution.stack([data, new])
    kernel = {"per input": PerInputKernel([C(1.5) * DC(0.9, 0.6), TC(0.85)]),
              "constant": C(0.3)}.get(name, KERNELS.get(name))
    term = observe(kernel, joint)
    M = data.n_outputs
    cross, var = term.covariance_blocks(M)
    S = observe(kernel, joint).covariance()
    scale = np.abs(S).max()
    np.testing.assert_allclose(cross, S[M:, :M], rtol=1e-10, atol=1e-12 * scale)
    np.testing.assert_allclose(var, np.diag(S)[M:], rtol=1e-10, atol=1e-12 * scale)
    _, every = observe(kernel, new).covariance_blocks(0)
    np.testing.assert_allclose(every, np.diag(observe(kernel, new).covariance()), rtol=1e-10,
                               atol=1e-12 * scale)


def _two_input_readings(initial_conditions, n_stamps, seed):
    """Two inputs, readings near both ends with exposure and latency (ticks before the first
    sample), and an order beyond the record for zero initial conditions."""
    rng = np.random.default_rng(seed)
    n = 700
    u = rng.standard_normal((n, 2))
    stamps = np.sort(rng.uniform(0.2, n - 0.5, n_stamps))
    order = 900 if initial_conditions == "zero" else 650
    return u, order, TimedConvolution(u, stamps, order=order, exposure=1.7, latency=0.4,
                                      initial_conditions=initial_conditions)


@pytest.mark.parametrize("initial_conditions", ["zero", "periodic"])
def test_unique_rows_are_the_input_at_each_tick_minus_each_lag(initial_conditions):
    u, order, timed = _two_input_readings(initial_conditions, 400, 3)
    n = u.shape[0]
    _, ticks = timed._unique
    assert ticks.min() < 0 and ticks.shape[0] > timed_module._ROW_CHUNK
    rows = timed.unique_rows()
    # u[tick - j] written out: every (tick, lag) pair at once
    t = ticks[:, None] - np.arange(order)[None, :]
    if initial_conditions == "periodic":
        block = u[t % n]
    else:
        block = np.where(((t >= 0) & (t < n))[..., None], u[np.clip(t, 0, n - 1)], 0.0)
    expected = np.hstack([block[:, :, 0], block[:, :, 1]])
    np.testing.assert_array_equal(rows, expected)
    assert not rows.flags.writeable


@pytest.mark.parametrize("initial_conditions", ["zero", "periodic"])
@pytest.mark.parametrize("rate", [2.0 / 650, 0.05, 1.5])
def test_damped_sinusoids_by_recursion_are_the_rows_times_the_bases(initial_conditions, rate):
    # the recursion over the input against the regressor rows times the sampled bases
    _, order, timed = _two_input_readings(initial_conditions, 300, 4)
    j = np.arange(order, dtype=float)
    omega = 0.9
    ec, es = np.exp(-rate * j) * np.cos(omega * j), np.exp(-rate * j) * np.sin(omega * j)
    for k in range(2):
        rows = timed.unique_rows()[:, k * order:(k + 1) * order]
        expected = rows @ np.column_stack([ec, es, j * ec, j * es])
        found = timed._damped_at_ticks(rate, omega, k, with_lag=True)
        scale = np.abs(expected).max(axis=0)
        np.testing.assert_allclose(found / scale, expected / scale, rtol=0, atol=1e-11)
        np.testing.assert_allclose(timed._damped_at_ticks(rate, omega, k, with_lag=False),
                                   found[:, :2])


@pytest.mark.parametrize("initial_conditions", ["zero", "periodic"])
def test_inputs_at_ticks_are_the_rows_at_lag_zero(initial_conditions):
    # the held basis's first cell reads the input at each point's own tick: the rows' lag 0
    _, order, timed = _two_input_readings(initial_conditions, 300, 4)
    for k in range(2):
        np.testing.assert_array_equal(timed._inputs_at_ticks(k),
                                      timed.unique_rows()[:, k * order])
