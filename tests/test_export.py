"""Realization (Ho-Kalman / ERA, balanced truncation) and the model exports.

Every number is checked against a computation that does not share the code
under test: Markov parameters by direct recursion of a known system, Hankel
singular values by the Gramians of the FIR's shift-register realization,
frequency responses by the DFT sum and by scipy's evaluation, the reduction
error against the bound on a dense frequency grid, and the band of the
reduced models against the posterior's exact standard deviations by Monte
Carlo.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest
from scipy import linalg, signal
from sklearn.base import BaseEstimator
from sklearn.exceptions import NotFittedError
from sklearn.gaussian_process.kernels import ConstantKernel

from gpmultirate import FIRGaussianProcess, LeastSquaresFIR, goodness_of_fit
from gpmultirate import simulation as sim
from gpmultirate.export import StateSpaceMixin, frequency_response_to_control
from gpmultirate.kernels import DC, PK
from gpmultirate.realization import (
    balanced_truncation,
    block_hankel,
    era,
    leading_era,
    select_order,
)


def _with_export(cls):
    """The estimator with the exports (a subclass until the estimators mix them in)."""
    if issubclass(cls, StateSpaceMixin):
        return cls
    return type(cls.__name__, (StateSpaceMixin, cls), {})


GP = _with_export(FIRGaussianProcess)
LS = _with_export(LeastSquaresFIR)


# ------------------------------------------------------------------ helpers
def markov_of(A, B, C, D, n_lags):
    """Markov parameters ``D, CB, CAB, ...`` by direct recursion."""
    out = [np.atleast_2d(D)]
    x = B
    for _ in range(1, n_lags):
        out.append(C @ x)
        x = A @ x
    return np.array(out)


def fir_response(g, freqs, sample_time):
    """``sum_i g_i exp(-j 2 pi f T i)``, the DFT sum of an impulse response (lags first)."""
    z = np.exp(-2j * np.pi * np.outer(freqs, np.arange(g.shape[0])) * sample_time)
    return np.tensordot(z, g, axes=(1, 0))


def state_space_response(system, freqs, sample_time):
    """``C (zI - A)^(-1) B + D`` of a state-space model, one solve per frequency, (n, p, m)."""
    z = np.exp(2j * np.pi * np.asarray(freqs) * sample_time)
    identity = np.eye(system.A.shape[0])
    return np.array([system.C @ linalg.solve(zk * identity - system.A, system.B) + system.D
                     for zk in z])


def random_stable(n, p, m, radius, seed):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    A *= radius / np.max(np.abs(np.linalg.eigvals(A)))
    return A, rng.standard_normal((n, m)), rng.standard_normal((p, n)), rng.standard_normal((p, m))


def shift_register(g):
    """The FIR ``g`` (lags first, one output and input) with ``P - 1`` states of past inputs."""
    P = g.shape[0]
    A = np.eye(P - 1, k=-1)
    B = np.zeros((P - 1, 1))
    B[0, 0] = 1.0
    return A, B, g[1:][None, :].copy(), np.array([[g[0]]])


def noisy_paper_fir(n_lags=300, noise=1e-4, seed=0):
    g = sim.paper_system(0.1).impulse_response(n_lags)
    return g + noise * np.random.default_rng(seed).standard_normal(n_lags)


# -------------------------------------------------------------- Ho-Kalman
def test_block_hankel_matches_the_definition():
    rng = np.random.default_rng(1)
    h = rng.standard_normal((7, 2, 3))
    H = block_hankel(h, n_block_rows=3, n_block_cols=4)
    assert H.shape == (6, 12)
    for i in range(3):
        for j in range(4):
            k = 1 + i + j
            expected = h[k] if k < 7 else np.zeros((2, 3))
            np.testing.assert_array_equal(H[2 * i:2 * i + 2, 3 * j:3 * j + 3], expected)


def test_ho_kalman_reproduces_a_low_order_system_exactly():
    A, B, C, D = random_stable(3, 2, 2, radius=0.9, seed=3)
    h = markov_of(A, B, C, D, 12)
    r = era(h, n_block_rows=5, n_block_cols=5)
    assert r.n_states == 3  # the rank of the Hankel matrix, found by the default rule
    assert r.hankel_singular_values[3] < 1e-12 * r.hankel_singular_values[0]
    # every Markov parameter, also far beyond the 11 lags in the Hankel matrices
    np.testing.assert_allclose(markov_of(r.A, r.B, r.C, r.D, 60), markov_of(A, B, C, D, 60),
                               rtol=0, atol=1e-10 * np.abs(h).max())
    # the same system up to a change of basis: the same poles
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(r.A)),
                               np.sort_complex(np.linalg.eigvals(A)), atol=1e-10)


def test_ho_kalman_on_a_single_input_single_output_system():
    system = sim.paper_system(0.1)  # 4 states
    h = system.impulse_response(40)
    r = era(h, 4, n_block_rows=15, n_block_cols=15)
    np.testing.assert_allclose(r.markov_parameters(400)[:, 0, 0], system.impulse_response(400),
                               atol=1e-9 * np.abs(h).max())


def test_era_of_a_fir_is_its_balanced_truncation():
    g = noisy_paper_fir(n_lags=80)
    exact = balanced_truncation(*shift_register(g), n_states=5)
    r = era(g, 5)
    # Hankel singular values from the Gramians of the shift register
    np.testing.assert_allclose(r.hankel_singular_values[:20], exact.hankel_singular_values[:20],
                               rtol=1e-8, atol=1e-12 * r.hankel_singular_values[0])
    freqs = np.linspace(0.0, 5.0, 301)
    np.testing.assert_allclose(r.frequency_response(freqs, 0.1),
                               exact.frequency_response(freqs, 0.1), rtol=1e-7, atol=1e-9)
    assert np.max(np.abs(np.linalg.eigvals(r.A))) < 1


def test_full_order_realization_is_the_fir():
    rng = np.random.default_rng(4)
    g = rng.standard_normal(12)
    r = era(g, 11)
    np.testing.assert_allclose(r.markov_parameters(20)[:, 0, 0], np.r_[g, np.zeros(8)],
                               atol=1e-10)


@pytest.mark.parametrize("n_states", [1, 2, 3, 4, 6, 10])
def test_fir_reduction_error_within_twice_the_discarded_hankel_singular_values(n_states):
    g = noisy_paper_fir()
    r = era(g, n_states)
    n_fft = 40000  # a grid of 20001 frequencies up to the Nyquist frequency of T = 0.1 s
    freqs = np.fft.rfftfreq(n_fft, d=0.1)
    error = np.abs(np.fft.rfft(g, n=n_fft) - r.frequency_response(freqs, 0.1)[:, 0, 0])
    s = r.hankel_singular_values
    assert r.error_bound == pytest.approx(2 * s[n_states:].sum())
    assert error.max() <= r.error_bound * (1 + 1e-9)
    # and no reduction of this order can do better than the next singular value
    assert error.max() >= 0.98 * s[n_states]


def test_balanced_truncation_error_bound_on_a_random_mimo_system():
    A, B, C, D = random_stable(8, 2, 3, radius=0.95, seed=5)
    full = balanced_truncation(A, B, C, D, n_states=8)
    freqs = np.linspace(0.0, 0.5, 4001)
    z = np.exp(2j * np.pi * freqs)
    G = np.array([C @ np.linalg.solve(zk * np.eye(8) - A, B) + D for zk in z])
    np.testing.assert_allclose(full.frequency_response(freqs), G, rtol=1e-8, atol=1e-10)
    for n in (2, 4, 6):
        r = balanced_truncation(A, B, C, D, n_states=n)
        gap = np.linalg.norm(G - r.frequency_response(freqs), ord=2, axis=(1, 2)).max()
        assert gap <= r.error_bound * (1 + 1e-9)
        assert gap >= 0.98 * r.hankel_singular_values[n]
        assert np.max(np.abs(np.linalg.eigvals(r.A))) < 1


def test_leading_era_equals_era():
    g = noisy_paper_fir()
    fast, full = leading_era(g, 4), era(g, 4)
    freqs = np.linspace(0.0, 5.0, 201)
    np.testing.assert_allclose(fast.frequency_response(freqs, 0.1),
                               full.frequency_response(freqs, 0.1), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(fast.hankel_singular_values, full.hankel_singular_values[:4],
                               rtol=1e-10)
    assert np.isnan(fast.error_bound)


def test_select_order_rule():
    assert select_order([1.0, 0.9, 0.1, 0.09, 0.003, 0.002, 1e-4, 9e-5]) == 4
    assert select_order([1.0, 0.5, 0.25]) == 3
    assert select_order([1.0, 0.5, 0.25], threshold=0.4) == 1
    assert select_order([2.0]) == 1
    # the paper system's FIR at the paper's order, with estimation-like noise: the
    # four states of the two modes
    assert era(noisy_paper_fir(n_lags=600, noise=1e-4)).n_states == 4


def test_realization_does_not_modify_its_input():
    g = noisy_paper_fir(n_lags=50)
    before = g.copy()
    era(g, 3)
    leading_era(g, 3)
    block_hankel(g)
    np.testing.assert_array_equal(g, before)


@pytest.mark.parametrize("bad, match", [
    (dict(markov=[1.0]), "markov"),
    (dict(markov=np.zeros((4, 2))), "markov"),
    (dict(markov=[0.0, 1.0, np.nan]), "markov"),
    (dict(markov=[1.0, 0.0, 0.0]), "static gain"),
    (dict(markov=[0.0, 1.0, 0.5], n_states=0), "n_states"),
    (dict(markov=[0.0, 1.0, 0.5], n_states=3), "n_states"),
    (dict(markov=[0.0, 1.0, 0.5], n_states=1.5), "n_states"),
    (dict(markov=[0.0, 1.0, 0.5], n_block_rows=0), "n_block_rows"),
    (dict(markov=[0.0, 1.0, 0.5], threshold=0.0), "threshold"),
    (dict(markov=[0.0, 1.0, 0.5], threshold=2.0), "threshold"),
])
def test_era_bad_input(bad, match):
    with pytest.raises(ValueError, match=match):
        era(**bad)


def test_other_bad_input():
    with pytest.raises(ValueError, match="hankel_singular_values"):
        select_order([0.1, 1.0])
    with pytest.raises(ValueError, match="A must be stable"):
        balanced_truncation([[1.5]], [[1.0]], [[1.0]], [[0.0]])
    with pytest.raises(ValueError, match="D must have shape"):
        balanced_truncation([[0.5]], [[1.0]], [[1.0]], [[0.0, 1.0]])
    with pytest.raises(ValueError, match="n_states"):
        leading_era(noisy_paper_fir(), 0)
    with pytest.raises(ValueError, match="frf"):
        frequency_response_to_control(np.ones(3))


# ------------------------------------------------------------- the exports
def three_state_fir(n_lags):
    """A third-order system's impulse response, decayed to 1e-4 of its peak in 40 lags."""
    A, B, C, D = random_stable(3, 1, 1, radius=0.78, seed=7)
    return markov_of(A, B, C, np.zeros((1, 1)), n_lags)[:, 0, 0]


@pytest.fixture(scope="module")
def ls_model():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(400)
    y_slow = np.convolve(u, three_state_fir(40))[:400][::2]
    return LS(factor=2, order=40, sample_time=0.1).fit(u, y_slow)


@pytest.fixture(scope="module")
def two_input_model():
    rng = np.random.default_rng(1)
    u = rng.standard_normal((200, 2))
    g1 = sim.paper_system(0.1).impulse_response(40)
    g2 = 0.05 * 0.8 ** np.arange(40) * (np.arange(40) > 0)
    y = np.convolve(u[:, 0], g1)[:200] + np.convolve(u[:, 1], g2)[:200]
    y_slow = y[::2] + 1e-4 * rng.standard_normal(100)
    kernel = ConstantKernel(1e-2, (1e-8, 1e2)) * DC(alpha=0.9, beta=0.99)
    return GP(kernel, factor=2, order=40, noise_level=1e-8, sample_time=0.1).fit(u, y_slow)


def test_to_dlti_impulse_response_is_coef(ls_model):
    system = ls_model.to_dlti()
    assert isinstance(system, signal.dlti)
    assert system.dt == 0.1
    _, (h,) = signal.dimpulse(system, n=50)
    np.testing.assert_allclose(h[:, 0], np.r_[ls_model.coef_, np.zeros(10)], rtol=0,
                               atol=1e-12)
    freqs = np.linspace(0.05, 4.95, 50)
    _, values = signal.dfreqresp(system, 2 * np.pi * freqs * 0.1)
    np.testing.assert_allclose(values, ls_model.frequency_response(freqs).mean, rtol=1e-9,
                               atol=1e-12)


def test_to_dlti_one_system_per_input(two_input_model):
    systems = two_input_model.to_dlti()
    assert isinstance(systems, list) and len(systems) == 2
    for k, system in enumerate(systems):
        _, (h,) = signal.dimpulse(system, n=40)
        np.testing.assert_allclose(h[:, 0], two_input_model.coef_[k], rtol=0, atol=1e-12)


def test_to_state_space_of_one_input(ls_model):
    system = ls_model.to_state_space()
    assert isinstance(system, signal.StateSpace) and system.dt == 0.1
    assert ls_model.state_space_order_ == 3 == system.A.shape[0]
    s = ls_model.hankel_singular_values_
    assert s.shape == (39,) and np.all(np.diff(s) <= 1e-12 * s[0])
    # Hankel singular values through the Gramians of the FIR's shift register
    exact = balanced_truncation(*shift_register(ls_model.coef_), n_states=3)
    np.testing.assert_allclose(s[:5], exact.hankel_singular_values[:5], rtol=1e-8)
    freqs = np.linspace(0.0, 5.0, 2001)
    error = np.abs(state_space_response(system, freqs, 0.1)[:, 0, 0]
                   - fir_response(ls_model.coef_, freqs, 0.1))
    assert error.max() <= 2 * s[3:].sum() * (1 + 1e-9)
    assert error.max() < 1e-3 * np.abs(ls_model.coef_).sum()


def test_to_state_space_of_two_inputs(two_input_model):
    model = two_input_model
    system = model.to_state_space(n_states=6)
    assert system.A.shape == (6, 6) and system.B.shape == (6, 2)
    assert system.C.shape == (1, 6) and system.D.shape == (1, 2)
    assert model.state_space_order_ == 6
    np.testing.assert_allclose(system.D[0], model.coef_[:, 0])
    # the impulse-response error is within the H2 norm, so within the H-infinity bound
    realized = markov_of(system.A, system.B, system.C, system.D, 40)[:, 0, :]
    error = np.linalg.norm(realized - model.coef_.T, axis=0)
    assert np.all(error <= 2 * model.hankel_singular_values_[6:].sum())
    freqs = np.linspace(0.0, 5.0, 1001)
    gap = np.linalg.norm(state_space_response(system, freqs, 0.1)
                         - fir_response(model.coef_.T[:, None, :], freqs, 0.1),
                         ord=2, axis=(1, 2)).max()
    assert gap <= 2 * model.hankel_singular_values_[6:].sum() * (1 + 1e-9)
    assert model.to_state_space().B.shape[1] == 2


def test_sample_state_spaces_reduce_the_posterior_draws(two_input_model):
    model = two_input_model
    systems = model.sample_state_spaces(n_states=5, n_samples=4, random_state=3)
    draws = model.sample_impulse_responses(n_samples=4, random_state=3)  # (2, 40, 4)
    assert len(systems) == 4
    freqs = np.linspace(0.0, 5.0, 501)
    for s, system in enumerate(systems):
        assert system.A.shape == (5, 5) and system.B.shape == (5, 2) and system.dt == 0.1
        draw = draws[:, :, s].T[:, None, :]
        bound = era(draw, 5).error_bound
        gap = np.linalg.norm(state_space_response(system, freqs, 0.1)
                             - fir_response(draw, freqs, 0.1), ord=2, axis=(1, 2)).max()
        assert gap <= bound * (1 + 1e-9)
    again = model.sample_state_spaces(n_states=5, n_samples=4, random_state=3)
    np.testing.assert_array_equal(again[2].A, systems[2].A)
    default = model.sample_state_spaces(n_samples=1, random_state=0)[0]
    assert default.A.shape[0] == era(model.coef_.T[:, None, :]).n_states


def test_exports_do_not_modify_the_model(ls_model):
    coef = ls_model.coef_.copy()
    ls_model.to_dlti()
    ls_model.to_state_space(3)
    ls_model.sample_state_spaces(3, n_samples=2, random_state=0)
    np.testing.assert_array_equal(ls_model.coef_, coef)


def test_exports_default_sample_time_is_one():
    class Bare(StateSpaceMixin, BaseEstimator):
        coef_ = np.r_[0.0, 1.0, 0.5]
        n_inputs_ = 1

        def fit(self):
            return self

    assert Bare().to_dlti().dt == 1.0
    assert Bare().to_state_space(1).dt == 1.0


@pytest.mark.parametrize("method, kwargs, match", [
    ("to_state_space", dict(n_states=0), "n_states"),
    ("to_state_space", dict(n_states=40), "n_states"),
    ("to_state_space", dict(n_states=2.0), "n_states"),
    ("to_state_space", dict(n_states=True), "n_states"),
    ("to_state_space", dict(threshold=-1.0), "threshold"),
    ("sample_state_spaces", dict(n_states=0), "n_states"),
    ("sample_state_spaces", dict(n_states=40), "n_states"),
    ("sample_state_spaces", dict(n_states=2, n_samples=0), "n_samples"),
])
def test_export_bad_input(ls_model, method, kwargs, match):
    with pytest.raises(ValueError, match=match):
        getattr(ls_model, method)(**kwargs)


@pytest.mark.parametrize("method", ["to_dlti", "to_state_space", "sample_state_spaces"])
def test_exports_need_a_fitted_model(method):
    with pytest.raises(NotFittedError):
        getattr(LS(order=3), method)()


# ----------------------------------------------------------- python-control
def test_to_control(ls_model):
    control = pytest.importorskip("control")
    system = ls_model.to_control(n_states=4)
    assert isinstance(system, control.StateSpace)
    assert system.dt == 0.1 and system.nstates == 4
    reference = ls_model.to_state_space(n_states=4)
    for name in "ABCD":
        np.testing.assert_array_equal(getattr(system, name), getattr(reference, name))
    freqs = np.linspace(0.05, 4.95, 100)
    values = system(np.exp(2j * np.pi * freqs * 0.1))
    np.testing.assert_allclose(np.ravel(values),
                               state_space_response(reference, freqs, 0.1)[:, 0, 0],
                               rtol=1e-9, atol=1e-12)


def test_frequency_response_to_control(ls_model):
    control = pytest.importorskip("control")
    freqs = np.linspace(0.0, 5.0, 60)
    frf = ls_model.frequency_response(freqs)
    data = frequency_response_to_control(frf)
    assert isinstance(data, control.FrequencyResponseData)
    assert data.dt == 0.1
    np.testing.assert_allclose(data.omega, 2 * np.pi * freqs)
    np.testing.assert_allclose(np.ravel(data.eval(2 * np.pi * freqs[1:])),
                               fir_response(ls_model.coef_, freqs[1:], 0.1), rtol=1e-10)


def test_control_missing_names_the_extra(ls_model, monkeypatch):
    monkeypatch.setitem(sys.modules, "control", None)  # import control now fails
    with pytest.raises(ImportError, match=r'pip install "gpmultirate\[control\]"'):
        ls_model.to_control()
    with pytest.raises(ImportError, match=r"gpmultirate\[control\]"):
        frequency_response_to_control(ls_model.frequency_response([0.5]))


# ------------------------------------------------------- the paper's system
def paper_kernel(T=0.1):
    a, b = np.exp(-0.5 * T), np.exp(-0.1 * T)
    return (ConstantKernel(1.0, (1e-12, 1e5)) * DC(alpha=a, beta=b)
            + PK.from_hz(0.4, T, alpha=a) + PK.from_hz(2.0, T, alpha=a))


@pytest.fixture(scope="module")
def paper_fit():
    rng = np.random.default_rng(0)
    system = sim.paper_system(0.1)
    u, u_val = sim.multisine(600, random_state=rng), sim.multisine(600, random_state=rng)
    data = sim.simulate_experiment(system, u, 3, snr_db=50, random_state=rng)
    model = GP(paper_kernel(), factor=3, order=600, noise_level=1e-5, sample_time=0.1)
    return model.fit(u, data.y_slow), u_val, system.simulate(u_val)


@pytest.mark.slow
def test_reduced_paper_model_keeps_the_validation_fit(paper_fit):
    model, u_val, y_val = paper_fit
    full = model.score(u_val, y_val)
    system = model.to_state_space(4)
    _, y, _ = signal.dlsim(system, u_val)
    reduced = goodness_of_fit(y_val, y[:, 0])
    assert full > 99.9
    assert reduced >= full - 0.5
    assert model.to_state_space().A.shape == (4, 4)  # the default rule finds the 4 states


@pytest.mark.slow
def test_reduced_draws_spread_as_the_posterior(paper_fit):
    model, _, _ = paper_fit
    # the modes and below: above the modes, the posterior spread is in the discarded
    # states, and four states keep only part of it (there, the draws are too narrow)
    freqs = np.array([0.1, 0.2, 0.43, 1.0, 2.29])  # slow Nyquist 1.67 Hz
    systems = model.sample_state_spaces(4, n_samples=100, random_state=0)
    G = np.array([state_space_response(s, freqs, 0.1)[:, 0, 0] for s in systems])
    frf = model.frequency_response(freqs)
    ratio_real = G.real.std(axis=0, ddof=1) / frf.real_std
    ratio_imag = G.imag.std(axis=0, ddof=1) / frf.imag_std
    assert np.all((ratio_real > 0.7) & (ratio_real < 1.4)), ratio_real
    assert np.all((ratio_imag > 0.7) & (ratio_imag < 1.4)), ratio_imag
