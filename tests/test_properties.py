"""Properties of the estimators on random valid problems (hypothesis, tiny sizes).

Every number is checked against an independent dense computation written
here with numpy: the regressor Phi by an explicit loop over its definition
(eq. 8), the kernels from their formulas (eq. 16-19), the posterior by plain
solves.

Properties checked, with the examples each run draws (derandomized, no
example database, so every run draws the same problems):

==  ===========================================================  ========
#   property                                                     examples
==  ===========================================================  ========
1   posterior mean ``coef_`` = ``K Phi^T (Phi K Phi^T + gamma       100
    I)^-1 y`` (eq. 15), random factor, order, offset, noise,
    kernel (TC, DC or SS, scaled, maybe plus PK), both the
    ``M <= P`` and the ``M > P`` branch
2   posterior mean and variance of ``g(t)`` at random real lags       80
    = the dense Gaussian conditional
3   variances finite and non-negative: ``impulse_response`` std       80
    (and the diagonal of ``return_cov``) at random real lags up to
    1000, ``predict`` std, ``frequency_response`` ``real_std`` and
    ``imag_std`` and ordered finite bands, finite posterior samples;
    for FIRGaussianProcess (noise down to 1e-12) and
    LeastSquaresFIR
4   ``factor=1`` is ordinary kernel-regularised FIR estimation:       60
    ``coef_`` = the dense formula with the lower-triangular
    Toeplitz regressor, ``predict(u)`` = ``np.convolve(u, coef_)``,
    ``impulse_response`` at integer lags = ``coef_``
5   ``noise_level=1e-10`` with ``order < M`` gives least squares      60
    (``numpy.linalg.lstsq``) to the first-order bias bound;
    LeastSquaresFIR gives it to rounding
6   scaling ``u`` by ``c`` with the kernel amplitude divided by       60
    ``c**2`` (``optimizer=None``) scales ``coef_`` and the
    posterior std by ``1/c`` and leaves the predictions at ``c u``
    and the evidence unchanged
7   the same with the default tuned fit (``kernel=None``): ``coef_``  12
    scales by ``1/c``, the noise level and shape hyperparameters
    are unchanged, the amplitude scales by ``1/c**2``
8   no call modifies or keeps a reference to the caller's arrays:      40
    every public entry point (estimators, their methods, the
    operator, ObservedKernel, the lag kernels, goodness_of_fit,
    save/load, simulation) with contiguous, strided, float32 and
    list inputs; the caller's kernel object is not modified by
    ``fit``
9   same inputs and ``random_state`` give bit-identical ``coef_``,    12
    tuned hyperparameters, noise level, evidence, optimizer
    result, posterior samples and frequency-response bands
10  every noise model (white, Matern 1/2 and 3/2, AR(1), a user      25
    kernel ``WhiteKernel + C * Matern``) on the ticks (random
    factor and offset) and at the readings' own instants (random
    stamps, exposure, latency): ``coef_`` = the dense Gaussian
    conditional with the noise kernel over the instants and the
    readings as window means of the held input's output; the
    noise-inclusive ``predict`` std = ``sqrt(std**2 + k(t, t))``
==  ===========================================================  ========

10 properties, 529 examples per run (about 27 s; sizes are at most 30 fast
samples).
"""

from __future__ import annotations

import io
import warnings
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from sklearn.gaussian_process.kernels import ConstantKernel as C
from threadpoolctl import threadpool_limits

from gpmultirate import (
    DownsampledConvolution,
    FIRGaussianProcess,
    LeastSquaresFIR,
    ObservedKernel,
    goodness_of_fit,
    load_model,
    save_model,
)
from gpmultirate import simulation as sim
from gpmultirate.kernels import DC, PK, SS, TC


@pytest.fixture(scope="module", autouse=True)
def single_threaded_blas():
    # The matrices here are tiny; threaded BLAS only adds contention (and it
    # keeps the bit-for-bit determinism of property 9 independent of threads).
    with threadpool_limits(limits=1):
        yield


def examples(n: int):
    return settings(
        max_examples=n,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
    )


# ------------------------------------------------------------ dense maths
def regressor(u, factor, order, offset):
    """Phi of eq. (8): row m holds u[offset + m F - i], i = 0..P-1, zero before the record."""
    rows = []
    for n in range(offset, len(u), factor):
        rows.append([u[n - i] if n - i >= 0 else 0.0 for i in range(order)])
    return np.array(rows, dtype=float).reshape(-1, order)


@dataclass(frozen=True)
class KernelSpec:
    """A prior ``scale * (base + resonance)`` over lag, as sklearn kernel and dense formula."""

    family: str
    scale: float
    alpha: float
    beta: float
    resonance: tuple | None  # (alpha, omega, sigma1, sigma2) of a PK term

    def sklearn(self, scale: float | None = None):
        base = {"TC": lambda: TC(self.alpha), "DC": lambda: DC(self.alpha, self.beta),
                "SS": lambda: SS(self.alpha)}[self.family]()
        if self.resonance is not None:
            base = base + PK(*self.resonance)
        return C(self.scale if scale is None else scale) * base

    def dense(self, t, s):
        t = np.asarray(t, dtype=float)[:, None]
        s = np.asarray(s, dtype=float)[None, :]
        a, longest = self.alpha, np.maximum(t, s)
        if self.family == "TC":  # alpha^max(t, s)
            K = a**longest
        elif self.family == "DC":  # eq. (16)
            K = a ** ((t + s) / 2) * self.beta ** np.abs(t - s)
        else:  # eq. (17)
            K = a ** (t + s + longest) / 2 - a ** (3 * longest) / 6
        if self.resonance is not None:  # eq. (18)-(19)
            ra, w, s1, s2 = self.resonance
            K = K + ra ** ((t + s) / 2) * (
                s1**2 * np.cos(w * t) * np.cos(w * s) + s2**2 * np.sin(w * t) * np.sin(w * s))
        return self.scale * K


def log_uniform(low_exponent, high_exponent):
    return st.floats(low_exponent, high_exponent).map(lambda e: 10.0**e)


@st.composite
def kernel_specs(draw, min_alpha=0.3, resonance=True, edges=False):
    """Random priors; ``edges`` adds alpha = 1 and beta = 1 (rank-deficient TC and DC)."""
    unit = st.just(1.0) if edges else st.nothing()
    alpha = draw(st.floats(min_alpha, 0.98) | unit)
    beta = draw(st.floats(0.2, 0.98) | unit)
    if resonance and draw(st.booleans()):
        resonance = (draw(st.floats(0.5, 0.95)), draw(st.floats(0.2, 2.8)),
                     draw(st.floats(0.2, 1.5)), draw(st.floats(0.2, 1.5)))
    else:
        resonance = None
    return KernelSpec(
        family=draw(st.sampled_from(["TC", "DC", "SS"])),
        scale=draw(log_uniform(-1, 1)),
        alpha=alpha,
        beta=beta,
        resonance=resonance,
    )


@dataclass(frozen=True)
class Problem:
    u: np.ndarray
    y: np.ndarray
    factor: int
    order: int
    offset: int

    @property
    def Phi(self):
        return regressor(self.u, self.factor, self.order, self.offset)

    def layout(self):
        return dict(factor=self.factor, order=self.order, offset=self.offset)


@st.composite
def problems(draw, max_samples=14, factor=None, min_outputs_over_order=None):
    n = draw(st.integers(2, max_samples))
    factor = draw(st.integers(1, 4)) if factor is None else factor
    offset = draw(st.integers(0, min(factor, n) - 1))
    m = len(range(offset, n, factor))
    if min_outputs_over_order is None:
        order = draw(st.integers(1, n))
    else:
        assume(m - min_outputs_over_order >= 1)
        order = draw(st.integers(1, m - min_outputs_over_order))
    rng = np.random.default_rng(draw(st.integers(0, 2**20)))
    return Problem(rng.standard_normal(n), rng.standard_normal(m), factor, order, offset)


def dense_posterior(spec, Phi, y, noise, lags):
    """Mean and variance of g(lags) given y = Phi g(0..P-1) + e, by plain solves."""
    grid = np.arange(Phi.shape[1])
    Ky = Phi @ spec.dense(grid, grid) @ Phi.T + noise * np.eye(Phi.shape[0])
    cross = spec.dense(lags, grid) @ Phi.T
    mean = cross @ np.linalg.solve(Ky, y)
    var = np.diag(spec.dense(lags, lags)) - np.sum(cross * np.linalg.solve(Ky, cross.T).T, axis=1)
    return mean, var


def fit_gp(problem, spec, noise, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # NumericalWarning: jitter
        return FIRGaussianProcess(spec.sklearn(**kwargs), noise_level=noise, optimizer=None,
                                  **problem.layout()).fit(problem.u, problem.y)


def assert_close(actual, expected, relative, what):
    scale = np.max(np.abs(expected), initial=0.0)
    error = np.max(np.abs(np.asarray(actual) - expected), initial=0.0)
    assert error <= relative * scale + 1e-300, (
        f"{what}: max error {error:.3g} exceeds {relative:g} x {scale:.3g}")


# ------------------------------------------------------- 1. equation (15)
@examples(100)
@given(problems(), kernel_specs(), log_uniform(-3, 1))
@pytest.mark.slow
def test_posterior_mean_is_the_regularized_estimate_of_eq_15(problem, spec, noise):
    model = fit_gp(problem, spec, noise)
    Phi, y, P = problem.Phi, problem.y, problem.order
    K = spec.dense(np.arange(P), np.arange(P))
    dense = K @ Phi.T @ np.linalg.solve(Phi @ K @ Phi.T + noise * np.eye(len(y)), y)
    assert_close(model.coef_, dense, 1e-6, "coef_")


# ------------------------------------------ 2. the GP posterior at real lags
@examples(80)
@given(problems(), kernel_specs(), log_uniform(-3, 1),
       st.lists(st.floats(0.0, 30.0), min_size=1, max_size=6))
@pytest.mark.slow
def test_posterior_at_real_lags_is_the_dense_gaussian_conditional(problem, spec, noise, lags):
    # between the ticks the model's prior interpolates the lags of its order (its nodes
    # stop at P - 1), the kernel alone has no order: the two agree up to HOLD_POINTS / 2
    # lags before the order, where the reference below is the kernel's own
    # lags, where the reference below is the kernel's own values (the kernel's values
    # between integer lags are tested against the interpolation written out in
    # test_hold.py and test_kernels.py; here, the conditioning on the data)
    from gpmultirate.kernels.hold import HOLD_POINTS

    last = problem.order - 1 - HOLD_POINTS // 2
    lags = np.array([x for x in lags if x <= last] or [0.0])
    model = fit_gp(problem, spec, noise)
    mean, std = model.impulse_response(lags, return_std=True)
    kernel = spec.sklearn()
    grid = np.arange(problem.Phi.shape[1], dtype=float)
    K = kernel(grid[:, None])
    np.testing.assert_allclose(K, spec.dense(grid, grid), rtol=1e-10, atol=1e-14)  # eq. 16-19
    Ky = problem.Phi @ K @ problem.Phi.T + noise * np.eye(problem.Phi.shape[0])
    cross = kernel(lags[:, None], grid[:, None]) @ problem.Phi.T
    dense_mean = cross @ np.linalg.solve(Ky, problem.y)
    prior_var = np.diag(kernel(lags[:, None]))
    dense_var = prior_var - np.sum(cross * np.linalg.solve(Ky, cross.T).T, axis=1)
    assert_close(mean, dense_mean, 1e-6, "mean")
    assert np.all(np.abs(std**2 - np.maximum(dense_var, 0.0)) <= 1e-6 * np.max(prior_var) + 1e-15)


# ---------------------------------------------- 3. variances are variances
def assert_variances(std, what):
    std = np.asarray(std)
    assert np.all(np.isfinite(std)), f"{what}: non-finite std {std}"
    assert np.all(std >= 0), f"{what}: negative std {std}"


def assert_frequency_response(frf, what):
    assert_variances(frf.real_std, what + " real_std")
    assert_variances(frf.imag_std, what + " imag_std")
    for band in (frf.magnitude_lower, frf.magnitude_upper, frf.phase_lower, frf.phase_upper):
        assert np.all(np.isfinite(band)), f"{what}: non-finite band"
    assert np.all(frf.magnitude_lower >= 0)
    assert np.all(frf.magnitude_lower <= frf.magnitude_upper)
    assert np.all(frf.phase_lower <= frf.phase_upper)
    assert np.all(np.abs(frf.real_imag_corr) <= 1)


@pytest.mark.slow
@examples(80)
@given(problems(), kernel_specs(min_alpha=0.05, edges=True), log_uniform(-12, 1),
       st.lists(st.floats(0.0, 1000.0), min_size=1, max_size=6),
       st.lists(st.floats(0.0, 0.5), min_size=1, max_size=4))
def test_variances_are_finite_and_non_negative(problem, spec, noise, lags, freqs):
    lags, freqs = np.array(lags), np.array(freqs)
    model = fit_gp(problem, spec, noise)
    _, std = model.impulse_response(lags, return_std=True)
    assert_variances(std, "impulse_response")
    _, cov = model.impulse_response(lags, return_cov=True)
    prior = np.diag(spec.dense(lags, lags))
    assert np.all(np.isfinite(cov)) and np.all(np.diag(cov) >= -1e-12 * np.max(prior))
    _, std = model.predict(problem.u, return_std=True)
    assert_variances(std, "predict")
    assert_frequency_response(model.frequency_response(freqs), "frequency_response")
    assert_frequency_response(model.frequency_response(), "frequency_response (default grid)")
    assert np.all(np.isfinite(model.sample_impulse_responses(lags, 3, random_state=0)))

    Phi = problem.Phi
    if problem.order < Phi.shape[0] and np.linalg.matrix_rank(Phi) == problem.order:
        ls = LeastSquaresFIR(**problem.layout()).fit(problem.u, problem.y)
        _, std = ls.predict(problem.u, return_std=True)
        assert_variances(std, "LeastSquaresFIR.predict")
        assert_frequency_response(ls.frequency_response(freqs), "LeastSquaresFIR")


# ------------------------------------------------------ 4. factor = 1
@examples(60)
@given(problems(factor=1), kernel_specs(), log_uniform(-3, 1))
def test_factor_one_is_ordinary_kernel_regularized_fir(problem, spec, noise):
    u, y, P = problem.u, problem.y, problem.order
    # y(n) = sum_i g_i u(n - i): column i of the regressor is u delayed by i
    Phi = np.column_stack([np.convolve(u, np.eye(P)[i])[: len(u)] for i in range(P)])
    K = spec.dense(np.arange(P), np.arange(P))
    dense = K @ Phi.T @ np.linalg.solve(Phi @ K @ Phi.T + noise * np.eye(len(y)), y)
    model = fit_gp(problem, spec, noise)
    assert_close(model.coef_, dense, 1e-6, "coef_")
    assert_close(model.predict(u), np.convolve(u, model.coef_)[: len(u)], 1e-12, "predict")
    assert_close(model.impulse_response(np.arange(P)), model.coef_, 1e-9, "impulse_response")


# ------------------------------------------- 5. vanishing noise: least squares
@examples(60)
@given(problems(max_samples=30, min_outputs_over_order=2),
       kernel_specs(min_alpha=0.6, resonance=False))
def test_vanishing_noise_gives_least_squares(problem, spec):
    Phi, y, P = problem.Phi, problem.y, problem.order
    singular = np.linalg.svd(Phi, compute_uv=False)
    assume(singular[-1] > 1e-3 * singular[0])
    g_ls = np.linalg.lstsq(Phi, y, rcond=None)[0]
    noise = 1e-10
    # first-order bias of the regularised estimate: gamma (Phi^T Phi)^-1 K^-1 g
    K = spec.dense(np.arange(P), np.arange(P))
    bias = noise / singular[-1] ** 2 / np.linalg.eigvalsh(K)[0] * np.linalg.norm(g_ls)
    assume(bias <= 1e-4 * np.linalg.norm(g_ls))
    rounding = 1e-10 * singular[0] / singular[-1] * np.linalg.norm(g_ls)

    model = fit_gp(problem, spec, noise)
    assert np.linalg.norm(model.coef_ - g_ls) <= 2 * bias + rounding

    ls = LeastSquaresFIR(**problem.layout()).fit(problem.u, y)
    assert np.linalg.norm(ls.coef_ - g_ls) <= rounding


# ------------------------------------------------ 6-7. units of the input
@examples(60)
@given(problems(), kernel_specs(), log_uniform(-3, 1), log_uniform(-3, 3),
       st.lists(st.floats(0.0, 20.0), min_size=1, max_size=4))
@pytest.mark.slow
def test_input_scaling_with_matched_amplitude(problem, spec, noise, c, lags):
    lags = np.array(lags)
    model = fit_gp(problem, spec, noise)
    scaled_problem = Problem(c * problem.u, problem.y, problem.factor, problem.order,
                             problem.offset)
    scaled = fit_gp(scaled_problem, spec, noise, scale=spec.scale / c**2)
    assert_close(c * scaled.coef_, model.coef_, 1e-8, "c * coef_")
    _, std = model.impulse_response(lags, return_std=True)
    _, scaled_std = scaled.impulse_response(lags, return_std=True)
    prior_std = np.sqrt(np.diag(spec.dense(lags, lags)))
    assert np.all(np.abs(c * scaled_std - std) <= 1e-6 * np.max(prior_std)), "c * std"
    assert_close(scaled.predict(c * problem.u), model.predict(problem.u), 1e-8, "predict")
    assert np.isclose(scaled.log_marginal_likelihood_value_,
                      model.log_marginal_likelihood_value_, rtol=1e-8, atol=1e-8)


@st.composite
def identification_data(draw):
    n = draw(st.integers(12, 24))
    factor = draw(st.integers(1, 3))
    offset = draw(st.integers(0, factor - 1))
    order = draw(st.integers(3, n // 2))
    rng = np.random.default_rng(draw(st.integers(0, 2**20)))
    u = rng.standard_normal(n)
    lags = np.arange(order)
    Phi = regressor(u, factor, order, offset)
    y = Phi @ (0.8**lags * np.cos(0.6 * lags)) + 0.05 * rng.standard_normal(Phi.shape[0])
    return Problem(u, y, factor, order, offset)


@examples(12)
@given(identification_data(), log_uniform(-3, 3))
def test_input_scaling_with_tuned_default_kernel(problem, c):
    def tuned(u):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            return FIRGaussianProcess(**problem.layout()).fit(u, problem.y)

    model, scaled = tuned(problem.u), tuned(c * problem.u)
    assert_close(c * scaled.coef_, model.coef_, 1e-4, "c * coef_")
    assert np.isclose(scaled.noise_level_, model.noise_level_, rtol=1e-4)
    shift = scaled.kernel_.theta - model.kernel_.theta  # log(amplitude), log(alpha), artanh(beta)
    np.testing.assert_allclose(shift, [-2 * np.log(c), 0.0, 0.0], atol=1e-3)


# --------------------------------------------- 8. the caller's arrays
class Guard:
    """Copies of the caller's arrays, compared after every call."""

    def __init__(self, **arrays):
        self.arrays, self.copies = {}, {}
        self.add(**arrays)

    def add(self, **arrays):
        self.arrays.update(arrays)
        self.copies.update({name: self._copy(a) for name, a in arrays.items()})

    @staticmethod
    def _copy(a):
        return np.array(a, copy=True) if isinstance(a, np.ndarray) else list(a)

    def check(self, call: str):
        for name, a in self.arrays.items():
            now = self._copy(a)
            if isinstance(a, np.ndarray):
                same = now.dtype == self.copies[name].dtype and np.array_equal(
                    now, self.copies[name])
            else:
                same = now == self.copies[name]
            assert same, f"{call} modified the caller's {name}"


def presented(x: np.ndarray, how: str):
    """The same numbers as a caller might hold them, and the buffer to watch."""
    if how == "strided":  # a view into a larger array; the larger array must not change
        base = np.full(2 * len(x), -7.0)
        base[::2] = x
        return base[::2], base
    if how == "float32":
        return x.astype(np.float32), None
    if how == "list":
        return x.tolist(), None
    return x.copy(), None


@pytest.mark.slow
@examples(40)
@given(problems(max_samples=10), kernel_specs(),
       st.sampled_from(["contiguous", "strided", "float32", "list"]),
       st.sampled_from([None, "marginal_likelihood"]))
def test_caller_arrays_are_never_modified(problem, spec, how, optimizer):
    u, u_base = presented(problem.u, how)
    y, y_base = presented(problem.y, how)
    lags, _ = presented(np.array([0.0, 0.5, 3.25]), how)
    freqs, _ = presented(np.array([0.0, 0.1, 0.45]), how)
    X = np.arange(len(problem.y))[:, None]
    arrays = dict(u=u, y=y, lags=lags, freqs=freqs, X=X)
    arrays.update({k: v for k, v in (("u_base", u_base), ("y_base", y_base)) if v is not None})
    guard = Guard(**arrays)
    kernel = spec.sklearn()
    kernel_params = repr(sorted(kernel.get_params().items(), key=lambda kv: kv[0]))

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        model = FIRGaussianProcess(kernel, noise_level=0.1, optimizer=optimizer,
                                   n_restarts_optimizer=1, random_state=0,
                                   **problem.layout()).fit(u, y)
    guard.check("fit")
    assert repr(sorted(kernel.get_params().items(), key=lambda kv: kv[0])) == kernel_params, (
        "fit modified the caller's kernel")

    theta = np.append(model.kernel_.theta, np.log(model.noise_level_))
    coef = np.linspace(1.0, 0.1, problem.order)
    guard.add(theta=theta, coef=coef)
    calls = {
        "predict": lambda: model.predict(u, return_std=True),
        "score": lambda: model.score(u, np.asarray(u, dtype=float) + 1.0),
        "impulse_response": lambda: model.impulse_response(lags, return_std=True),
        "impulse_response(return_cov)": lambda: model.impulse_response(lags, return_cov=True),
        "sample_impulse_responses": lambda: model.sample_impulse_responses(lags, 2, 0),
        "frequency_response": lambda: model.frequency_response(freqs, sample_time=0.5),
        "log_marginal_likelihood": lambda: model.log_marginal_likelihood(
            theta, eval_gradient=True),
        "DownsampledConvolution": lambda: DownsampledConvolution(u, **problem.layout()),
        "matvec": lambda: model.observation_.matvec(coef),
        "rmatvec": lambda: model.observation_.rmatvec(y),
        "ObservedKernel": lambda: ObservedKernel(kernel, model.observation_)(X),
        "ObservedKernel.diag": lambda: ObservedKernel(kernel, model.observation_).diag(X),
        "kernel(lags)": lambda: kernel(np.asarray(lags, dtype=float)[:, None]),
        "goodness_of_fit": lambda: goodness_of_fit(u, np.zeros(len(problem.u))),
        "downsample": lambda: sim.downsample(u, problem.factor, problem.offset),
        "zero_order_hold": lambda: sim.zero_order_hold(y, 2),
        "add_output_noise": lambda: sim.add_output_noise(u, 20.0, random_state=0),
        "system.simulate": lambda: sim.paper_system().simulate(u),
        "system.frequency_response": lambda: sim.paper_system().frequency_response(freqs),
        "simulate_experiment": lambda: sim.simulate_experiment(
            sim.paper_system(), u, problem.factor, 30.0, problem.offset, random_state=0),
    }
    for name, call in calls.items():
        call()
        guard.check(name)
    for kind_, lag_kernel in (("TC", TC(0.8)), ("DC", DC(0.8, 0.5)), ("SS", SS(0.8)),
                              ("PK", PK(0.9, 0.5))):
        column = np.asarray(lags, dtype=float)[:, None]
        lag_kernel(column, eval_gradient=True)
        lag_kernel(column, column[::-1])
        lag_kernel.diag(column)
        guard.check(kind_)
    buffer = io.BytesIO()
    save_model(model, buffer)
    buffer.seek(0)
    load_model(buffer)
    guard.check("save_model/load_model")

    # the model keeps its own copies: changing the caller's arrays changes nothing
    def outputs():
        return (model.predict(problem.u), model.impulse_response(lags),
                model.log_marginal_likelihood(theta), model.observation_.matrix)

    before = outputs()
    for array in (u, y, u_base, y_base):
        if isinstance(array, np.ndarray):
            array[...] = 123.0
        elif isinstance(array, list):
            array[:] = [123.0] * len(array)
    assert all(np.array_equal(b, a) for b, a in zip(before, outputs())), (
        "the fitted model changed when the caller's arrays did")


# ------------------------------------------------------- 9. determinism
@pytest.mark.slow
@examples(12)
@given(identification_data(), st.integers(0, 2**16),
       st.sampled_from(["default", "TC", "DC+PK"]))
def test_fits_are_deterministic(problem, seed, kind):
    def fitted():
        kernel = {"default": None, "TC": C(1.0) * TC(0.7),
                  "DC+PK": C(1.0) * DC(0.7, 0.7) + PK(0.8, 0.6)}[kind]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            return FIRGaussianProcess(kernel, n_restarts_optimizer=1, random_state=seed,
                                      **problem.layout()).fit(problem.u, problem.y)

    first, second = fitted(), fitted()
    assert np.array_equal(first.coef_, second.coef_)
    assert np.array_equal(first.kernel_.theta, second.kernel_.theta)
    assert first.noise_level_ == second.noise_level_
    assert first.log_marginal_likelihood_value_ == second.log_marginal_likelihood_value_
    assert np.array_equal(first.optimizer_result_.x, second.optimizer_result_.x)
    lags = np.array([0.0, 1.5, 2.25, 7.0])
    samples = first.sample_impulse_responses(lags, 4, random_state=seed)
    assert np.array_equal(samples, second.sample_impulse_responses(lags, 4, random_state=seed))
    assert np.array_equal(samples, first.sample_impulse_responses(lags, 4, random_state=seed))
    a, b = first.frequency_response(), second.frequency_response()
    for name in ("mean", "magnitude_lower", "magnitude_upper", "phase_lower", "phase_upper",
                 "real_std", "imag_std"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


# -------------------------------- 10. every noise model, readings on and off the ticks
NOISE_MODELS = ["white", "matern12", "matern32", "ar1", "user"]


def _noise_choice(name):
    from sklearn.gaussian_process.kernels import Matern, WhiteKernel

    if name == "user":
        return WhiteKernel(0.05) + C(0.2) * Matern(3.0, nu=1.5)
    return name


def _reading_functionals(u, times, exposure, latency, order, nodes=48):
    """Each reading as ``sum_q c_q g(x_q)`` over lags in ``[0, P)``: the output of the held
    input at ``t - L`` (``E = 0``), or its mean over ``[t - L - E, t - L]`` by Gauss-Legendre
    on the pieces between ticks."""
    xi, w = np.polynomial.legendre.leggauss(nodes)
    out = []
    for t in times:
        end = t - latency
        if exposure == 0.0:
            instants, weights = np.array([end]), np.array([1.0])
        else:
            start = end - exposure
            edges = np.unique(np.concatenate(
                [[start, end], np.arange(np.ceil(start), np.ceil(end))]))
            edges = edges[(edges >= start) & (edges <= end)]
            instants = np.concatenate([a + (b - a) * (xi + 1) / 2
                                       for a, b in zip(edges[:-1], edges[1:])])
            weights = np.concatenate([w * (b - a) / 2 / exposure
                                      for a, b in zip(edges[:-1], edges[1:])])
        lags, coefs = [], []
        for s, weight in zip(instants, weights):
            for j in range(len(u)):
                if 0.0 <= s - j < order:
                    lags.append(s - j)
                    coefs.append(weight * u[j])
        out.append((np.array(lags), np.array(coefs)))
    return out


def _held_functional(lags, coefs, order, spec):
    """``sum c g(x)`` under the hold's prior: integer lags and their coefficients (Lagrange on
    ``n - 5 .. n + 6``, zero below 0, cut at ``order - 1`` unless None), and the bridge's
    part as a vector over the cells whose inner products give its covariance
    (``0.1^2 sin(pi d) sin(pi e) k(n, n)``)."""
    out, bridge = {}, np.zeros(32)  # lags below the order, at most 6
    for x, c in zip(lags, coefs):
        n = int(np.floor(x))
        nodes = [n] if x == n else [n + k for k in range(-5, 7)
                                    if order is None or n + k <= order - 1]
        for node in nodes:
            weight = np.prod([(x - o) / (node - o) for o in nodes if o != node])
            if node >= 0:
                out[node] = out.get(node, 0.0) + c * weight
        bridge[n] += c * np.sin(np.pi * (x - n)) * 0.1 * np.sqrt(
            spec.dense([float(n)], [float(n)])[0, 0])
    keys = sorted(out)
    return np.array(keys, dtype=float), np.array([out[k] for k in keys]), bridge


@st.composite
def noisy_problems(draw):
    n = draw(st.integers(8, 16))
    order = draw(st.integers(2, 6))
    rng = np.random.default_rng(draw(st.integers(0, 2**20)))
    u = rng.standard_normal(n)
    if draw(st.booleans()):  # on the ticks
        factor = draw(st.integers(1, 3))
        offset = draw(st.integers(0, factor - 1))
        times = np.arange(offset, n, factor, dtype=float)
        timing = dict(factor=factor, offset=offset)
        exposure = latency = 0.0
    else:  # at their own instants, with exposure and latency
        m = draw(st.integers(2, 6))
        times = np.sort(rng.choice(np.arange(1, 4 * n) / 4.0, size=m, replace=False))
        exposure = draw(st.sampled_from([0.0, 0.5, 1.25]))
        latency = draw(st.sampled_from([0.0, 0.3, 1.0]))
        timing = dict(exposure=exposure, latency=latency)
    y = rng.standard_normal(times.shape[0])
    return u, y, times, order, timing, exposure, latency


@pytest.mark.slow
@examples(25)
@given(noisy_problems(), st.sampled_from(NOISE_MODELS), kernel_specs(resonance=False))
def test_every_noise_model_and_timing_is_the_dense_gaussian_conditional(problem, noise_name,
                                                                       spec):
    u, y, times, order, timing, exposure, latency = problem
    on_ticks = "factor" in timing
    assume(on_ticks or times.max() - latency >= 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        model = FIRGaussianProcess(spec.sklearn(), order=order, optimizer=None, noise_level=0.1,
                                   noise_kernel=_noise_choice(noise_name), **timing)
        model.fit(u, y) if on_ticks else model.fit(u, y, sample_times=times)
    # the noise over the readings' instants: only their differences matter
    X = times[:, None]
    noise = (0.1 * np.eye(len(y)) if noise_name == "white" else model.noise_kernel_(X))
    funcs = _reading_functionals(u, times, exposure, latency, order)
    funcs = [(x, c, None) for x, c in funcs]
    if not on_ticks:
        funcs = [(x, c) for x, c, _ in funcs]
        # between integer lags the hold's prior: the readings as combinations of the
        # integer lags (nodes cut at order - 1; a record shorter than the twelve nodes
        # takes the kernel's own values, not cut) plus the bridge
        cut = order if len(u) >= 12 else None
        funcs = [_held_functional(x, c, cut, spec) for x, c in funcs]
    S = np.array([[ca @ spec.dense(xa, xb) @ cb for xb, cb, _ in funcs]
                   for xa, ca, _ in funcs])
    if not on_ticks:
        S = S + np.array([[ba @ bb for _, _, bb in funcs] for _, _, ba in funcs])
    lags = np.arange(order, dtype=float)
    cross = np.column_stack([spec.dense(lags, x) @ c if x.size else np.zeros(order)
                             for x, c, _ in funcs])
    dense = cross @ np.linalg.solve(S + noise, y)
    # quadrature of the kernel's kink inside a window: 1e-4; on the ticks, rounding
    assert_close(model.coef_, dense, 1e-6 if exposure == 0.0 else 1e-3, "coef_")
    mean, std = model.predict(u, return_std=True, include_noise=True)
    _, free = model.predict(u, return_std=True)
    white = 0.1 if noise_name == "white" else float(model.noise_kernel_.diag(X[:1])[0])
    np.testing.assert_allclose(std, np.sqrt(free**2 + white), rtol=1e-9)
