"""The posterior of long records through DC's tridiagonal precision, against dense formulas.

With more slow samples than coefficients (``M > P``) and a prior whose
precision is tridiagonal (a constant times DC), the posterior is
:class:`~gpmultirate.inference.PrecisionPosterior`.  Every number is checked
against the paper's equations written out densely in the ``M``-sample data
space: ``Phi`` from its definition, the kernel from its closed form
(``|beta|^d cos(pi d)`` for a negative ``beta`` on real lags), the mean of
eq. (15), the covariance ``K - K Phi^T Ky^{-1} Phi K``, the evidence by
``scipy.stats.multivariate_normal``, and ``g`` at real lags from the joint
Gaussian of ``(g(X), y)``.  Kernels without a precision keep
:class:`~gpmultirate.inference.ParameterSpacePosterior`, checked the same way.
"""

import pickle
import warnings

import numpy as np
import pytest
from scipy.stats import multivariate_normal
from sklearn.gaussian_process.kernels import ConstantKernel as C

import gpmultirate as gm
from gpmultirate import covariance, inference
from gpmultirate.exceptions import NotPositiveDefinite
from gpmultirate.inference import ParameterSpacePosterior, PrecisionPosterior, posterior
from gpmultirate.kernels import DC, PK, TC
from gpmultirate.observations import reduce_observation
from gpmultirate.responses import FrequencyResponse
from hold_reference import lagrange_rows

N, FACTOR, ORDER, OFFSET, NOISE = 600, 2, 40, 1, 0.05**2
LAGS = np.arange(ORDER, dtype=float)
REAL_LAGS = np.array([0.0, 0.4, 1.0, 2.5, 7.25, 13.9, 25.5, 39.0, 41.3])


def regressor(u, factor, order, offset):
    """``Phi[m, i] = u[n_m - i]`` with ``n_m = offset + m F``, zero before the record."""
    rows = range(offset, len(u), factor)
    return np.array([[u[n - i] if n - i >= 0 else 0.0 for i in range(order)] for n in rows])


def convolution(u, order):
    """The fast-rate convolution matrix ``T[n, i] = u[n - i]``."""
    return regressor(u, 1, order, 0)


def dc(constant, alpha, beta):
    """``c alpha^((t+s)/2) beta^|t-s|`` at integer lags; between them the hold's prior.

    The Lagrange interpolation on the lags ``n - 5 .. n + 6`` around ``n + d`` (zero
    below lag 0) plus the bridge ``0.1^2 sin(pi d) sin(pi e) k(n, n)`` on a shared cell.
    """

    def formula(t, s):
        return (constant * alpha ** (np.add.outer(t, s) / 2.0)
                * beta ** np.abs(np.subtract.outer(t, s)))

    def k(t, s):
        t, s = np.asarray(t, float), np.asarray(s, float)
        size = int(max(t.max(), s.max())) + 8
        grid = np.arange(size, dtype=float)
        Wt = lagrange_rows(t, size)
        Ws = lagrange_rows(s, size)
        n, m = np.floor(t)[:, None], np.floor(s)[None, :]
        bridge = (0.1**2 * np.outer(np.sin(np.pi * t), np.sin(np.pi * s)) * (-1.0) ** (n + m)
                  * (n == m) * constant * alpha**n)
        return Wt @ formula(grid, grid) @ Ws.T + bridge

    return k


def library(kernel):
    """A kernel without a closed form here, evaluated on lags ``t`` and ``s``."""
    return lambda t, s: kernel(np.asarray(t, float)[:, None], np.asarray(s, float)[:, None])


def dense(k, Phi, y, noise):
    """The posterior and evidence of ``y = Phi g(0..P-1) + e`` in the data space."""
    K = k(LAGS, LAGS)
    Ky = Phi @ K @ Phi.T + noise * np.eye(Phi.shape[0])
    gain = np.linalg.solve(Ky, Phi @ K).T  # K Phi^T Ky^{-1}
    mean = gain @ y  # eq. (15)
    cov = K - gain @ Phi @ K
    evidence = multivariate_normal(np.zeros(Phi.shape[0]), Ky).logpdf(y)

    def at(X):
        """Mean and covariance of g(X) given y: the joint Gaussian of (g(X), y)."""
        cross = k(X, LAGS) @ Phi.T
        return cross @ np.linalg.solve(Ky, y), k(X, X) - cross @ np.linalg.solve(Ky, cross.T)

    return mean, cov, evidence, at


@pytest.fixture(scope="module")
def record():
    rng = np.random.default_rng(7)
    u = rng.standard_normal(N)
    g = 0.8**LAGS * np.cos(2.5 * LAGS)
    Phi = regressor(u, FACTOR, ORDER, OFFSET)
    y = Phi @ g + np.sqrt(NOISE) * rng.standard_normal(Phi.shape[0])
    op = gm.DownsampledConvolution(u, FACTOR, ORDER, OFFSET)
    assert op.n_outputs == Phi.shape[0] > ORDER
    return dict(u=u, Phi=Phi, y=y, op=op, rng=rng)


def close(found, expected, rtol=1e-8):
    np.testing.assert_allclose(found, expected, rtol=rtol, atol=rtol * np.abs(expected).max())


def check_posterior(result, kernel, k, record, noise):
    """Every quantity of ``result`` against the dense posterior of ``kernel``, written as ``k``."""
    Phi, y, rng = record["Phi"], record["y"], record["rng"]
    mean, cov, evidence, at = dense(k, Phi, y, noise)
    close(result.coef, mean)
    close(result.covariance(), cov)
    assert result.log_marginal_likelihood == pytest.approx(evidence, rel=1e-10)
    A1, A2 = rng.standard_normal((2, 6, ORDER))
    found_mean, found_cov = result.linear_map(A1, full_cov=True)
    close(found_mean, A1 @ mean)
    close(found_cov, A1 @ cov @ A1.T)
    close(result.linear_map(A1)[1], np.diag(A1 @ cov @ A1.T))
    var1, var2, cross = result.pair_variances(A1, A2)
    close(var1, np.diag(A1 @ cov @ A1.T))
    close(var2, np.diag(A2 @ cov @ A2.T))
    close(cross, np.diag(A1 @ cov @ A2.T))
    data, _ = reduce_observation(record["op"], y)
    X = REAL_LAGS[:, None]
    lag_mean, lag_cov = at(REAL_LAGS)
    assert result.observation.n_outputs == data.n_outputs and result.kernel is kernel
    close(result.mean_at_lags(X), lag_mean)
    found_mean, found_var = result.at_lags(X, full_cov=False)
    close(found_mean, lag_mean)
    close(found_var, np.diag(lag_cov), rtol=1e-7)
    close(result.at_lags(X, full_cov=True)[1], lag_cov, rtol=1e-7)


@pytest.mark.parametrize("constant, alpha, beta",
                         [(1.0, 0.85, 0.6), (2.5, 0.9, -0.6), (0.7, 0.8, -0.95), (1.0, 1.0, 0.3)])
def test_long_record_posterior_through_the_precision_is_the_dense_posterior(
        record, constant, alpha, beta):
    kernel = C(constant) * DC(alpha, beta)
    result = posterior(record["op"], kernel, NOISE, record["y"])
    assert isinstance(result, PrecisionPosterior)
    check_posterior(result, kernel, dc(constant, alpha, beta), record, NOISE)


@pytest.mark.parametrize("kernel", [
    C(1.3) * DC(0.85, -0.5) + PK(0.9, 2.5, 0.8, 0.5),
    TC(0.8),
    C(1.0) * DC(1e-9, 0.5),  # alpha^-(P-1) beyond the precision's range
], ids=["DC+PK", "TC", "DC-without-precision"])
def test_kernels_without_a_precision_keep_the_parameter_space(record, kernel):
    result = posterior(record["op"], kernel, NOISE, record["y"])
    assert type(result) is ParameterSpacePosterior
    check_posterior(result, kernel, library(kernel), record, NOISE)


def test_a_failed_factorization_falls_back_to_the_parameter_space(record, monkeypatch):
    kernel = C(1.0) * DC(0.9, -0.6)
    def fails(C, **options):
        raise NotPositiveDefinite("C")

    monkeypatch.setattr(covariance.precision, "cholesky_or_raise", fails)
    result = posterior(record["op"], kernel, NOISE, record["y"])
    assert type(result) is ParameterSpacePosterior
    check_posterior(result, kernel, dc(1.0, 0.9, -0.6), record, NOISE)


@pytest.mark.parametrize("tuned", [False, True], ids=["fixed", "tuned"])
def test_estimator_of_a_long_record_matches_the_dense_posterior(record, tuned):
    u, Phi, y, rng = record["u"], record["Phi"], record["y"], record["rng"]
    model = gm.FIRGaussianProcess(
        C(1.5) * DC(0.9, -0.6), factor=FACTOR, order=ORDER, offset=OFFSET, noise_level=NOISE,
        optimizer="marginal_likelihood" if tuned else None,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # bound warnings of the tuning are not the subject
        model.fit(u, y)
    assert isinstance(model.posterior_, PrecisionPosterior)
    params = model.kernel_.get_params()
    k = dc(params["k1__constant_value"], params["k2__alpha"], params["k2__beta"])
    noise = model.noise_level_
    if not tuned:
        assert (params["k2__beta"], noise) == (-0.6, NOISE)
    mean, cov, evidence, at = dense(k, Phi, y, noise)
    close(model.coef_, mean)
    assert model.log_marginal_likelihood_value_ == pytest.approx(evidence, rel=1e-10)
    # g at real lags
    lag_mean, lag_cov = at(REAL_LAGS)
    found_mean, lag_std = model.impulse_response(REAL_LAGS, return_std=True)
    close(found_mean, lag_mean)
    close(lag_std, np.sqrt(np.diag(lag_cov)), rtol=1e-7)
    close(model.impulse_response(REAL_LAGS, return_cov=True)[1], lag_cov, rtol=1e-7)
    # the noise-free fast output of a new input
    u_new = rng.standard_normal(150)
    T = convolution(u_new, ORDER)
    found_mean, found_std = model.predict(u_new, return_std=True)
    close(found_mean, T @ mean)
    close(found_std, np.sqrt(np.diag(T @ cov @ T.T)), rtol=1e-7)
    # the FRF and its bands (off 0 and Nyquist, where the imaginary part vanishes)
    freqs = np.linspace(0.01, 0.49, 25)
    E = np.exp(-2j * np.pi * np.outer(freqs, LAGS))
    re, im = E.real, E.imag
    expected = FrequencyResponse.from_gaussian(
        freqs, E @ mean, np.diag(re @ cov @ re.T), np.diag(im @ cov @ im.T),
        np.diag(re @ cov @ im.T), level=0.9)
    frf = model.frequency_response(freqs, sample_time=1.0, level=0.9)
    close(frf.mean, expected.mean)
    for name in ("real_std", "imag_std", "real_imag_corr", "magnitude_lower",
                 "magnitude_upper", "phase_lower", "phase_upper"):
        close(getattr(frf, name), getattr(expected, name), rtol=1e-6)
    # a pickled model keeps its posterior
    again = pickle.loads(pickle.dumps(model))
    np.testing.assert_array_equal(again.impulse_response(REAL_LAGS, return_std=True)[1], lag_std)
