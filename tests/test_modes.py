"""Modes of the reduced model with credible intervals, and the peaks the data support."""

import warnings

import numpy as np
import pytest
from scipy import linalg

import gpmultirate as gm
from gpmultirate.modes import modal_analysis, modes_of


def _discrete(modes, sample_time):
    """A sum of second-order modes (frequency Hz, damping, numerator), zero-order hold."""
    blocks, inputs, outputs = [], [], []
    for f, zeta, k in modes:
        w = 2 * np.pi * f
        blocks.append(np.array([[0.0, 1.0], [-w * w, -2 * zeta * w]]))
        inputs.append([0.0, 1.0])
        outputs.append([k, 0.0])
    A = linalg.block_diag(*blocks)
    B = np.concatenate(inputs)[:, None]
    C = np.concatenate(outputs)[None, :]
    n = A.shape[0]
    big = np.zeros((n + 1, n + 1))
    big[:n, :n], big[:n, n:] = A, B
    step = linalg.expm(big * sample_time)
    return step[:n, :n], step[:n, n:], C


def test_modes_of_gives_the_continuous_modes_and_the_peak_of_a_single_mode():
    A, B, C = _discrete([(2.0, 0.03, 1.0), (7.5, 0.2, 3.0)], 0.01)
    found = modes_of(A, B, C, 0.01)
    np.testing.assert_allclose([f for f, _, _ in found], [2.0, 7.5], rtol=1e-9)
    np.testing.assert_allclose([z for _, z, _ in found], [0.03, 0.2], rtol=1e-9)
    # one mode alone: its gain is |G| at its damped frequency, from the transfer function
    A1, B1, C1 = _discrete([(2.0, 0.03, 1.0)], 0.01)
    (f, zeta, gain), = modes_of(A1, B1, C1, 0.01)
    z = np.exp(1j * np.angle(np.linalg.eigvals(A1)).max())
    G = (C1 @ np.linalg.solve(z * np.eye(2) - A1, B1))[0, 0]
    assert gain == pytest.approx(abs(G), rel=1e-9)
    # a real pole: damping 1, frequency |log z| / (2 pi T)
    (f, zeta, gain), = modes_of([[0.5]], [[1.0]], [[1.0]], 0.1)
    assert zeta == 1.0 and f == pytest.approx(np.log(2) / (2 * np.pi * 0.1))
    assert gain == pytest.approx(1.0 / (1 - 0.5))


def _fit(seed, n=1200, factor=2, sample_time=0.01):
    rng = np.random.default_rng(seed)
    A, B, C = _discrete([(3.0, 0.05, 40.0), (12.0, 0.05, 600.0)], sample_time)
    u = rng.standard_normal(n)
    x = np.zeros(A.shape[0])
    y = np.zeros(n)
    for k in range(n):
        y[k] = C[0] @ x
        x = A @ x + B[:, 0] * u[k]
    y = y / np.std(y)
    y_slow = y[::factor] + 0.02 * rng.standard_normal(n // factor)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return gm.FIRGaussianProcess(order=300, factor=factor,
                                     sample_time=sample_time).fit(u, y_slow)


@pytest.fixture(scope="module")
def two_modes():
    return _fit(0)


@pytest.mark.slow  # the fit of the two modes: 7 s of CPU
def test_two_modes_found_with_intervals_and_both_peaks_supported(two_modes):
    analysis = modal_analysis(two_modes, 4, n_draws=40)
    resonant = [m for m in analysis.modes if m.resonant]
    assert [round(m.frequency) for m in resonant] == [3, 12]
    for m, truth in zip(resonant, (3.0, 12.0)):
        low, high = m.frequency_interval
        assert low <= m.frequency <= high and abs(m.frequency - truth) < 0.05 * truth
        assert m.damping_interval[0] < m.damping_interval[1] and m.presence > 0.9
    assert [round(p.frequency) for p in analysis.supported_peaks] == [3, 12]
    assert analysis.consistent and "2 supported" in analysis.text
    # two states cannot keep both resonances: a peak without a mode is named, unless it
    # stands less than the reduction's error bound above its valleys
    two = modal_analysis(two_modes, 2, n_draws=20)
    missing = [p for p in two.supported_peaks if p.mode is None]
    assert two.n_states == 2 and missing
    assert two.unmodelled_peaks == tuple(p for p in missing if p.prominence > two.error_bound)
    assert two.consistent == (not two.unmodelled_peaks)
    if not two.consistent:
        assert "a higher n_states keeps them" in two.text


def test_arguments_are_checked():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(120)
    y = np.convolve(u, 0.8 ** np.arange(20))[:120:2] + 0.01 * rng.standard_normal(60)
    model = gm.FIRGaussianProcess(order=20, factor=2, sample_time=0.01, optimizer=None,
                                  noise_level=1e-4, noise_kernel="white").fit(u, y)
    with pytest.raises(ValueError, match="n_draws"):
        modal_analysis(model, n_draws=0)
    with pytest.raises(ValueError, match="level"):
        modal_analysis(model, level=1.5)


@pytest.mark.slow  # the fit of the two modes: 7 s of CPU
def test_the_intervals_are_those_of_the_reduced_posterior_draws(two_modes):
    analysis = modal_analysis(two_modes, 4, n_draws=30, random_state=3)
    systems = two_modes.sample_state_spaces(4, n_samples=30, random_state=3)
    for mode in (m for m in analysis.modes if m.resonant):
        # the nearest mode of each reduced draw, independently of the matching
        drawn = [min((f for f, _, _ in modes_of(s.A, s.B, s.C, 0.01)),
                     key=lambda f: abs(np.log(f / mode.frequency))) for s in systems]
        np.testing.assert_allclose(mode.frequency_interval, np.quantile(drawn, [0.025, 0.975]),
                                   rtol=1e-6)
