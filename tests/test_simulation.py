"""Tests of gpmultirate.simulation against independent computations (scipy, dense formulas)."""

import numpy as np
import pytest
import scipy.signal
from hypothesis import given, settings
from hypothesis import strategies as st

from gpmultirate.simulation import (
    PAPER_PARAMETERS,
    WAFER_STAGE_MODES,
    DiscreteSystem,
    add_output_noise,
    downsample,
    multisine,
    paper_system,
    perturb_parameters,
    random_binary_sequence,
    simulate_experiment,
    two_mass_spring_damper,
    wafer_stage_surrogate,
    zero_order_hold,
    zoh_input,
)


def second_order_modes(k1, k2, d1, d2, m1, m2):
    """Continuous poles from the mass, damping and stiffness matrices, states [x1, x2, v1, v2]."""
    mass = np.diag([m1, m2])
    stiffness = np.array([[k1 + k2, -k2], [-k2, k2]])
    damping = np.array([[d1 + d2, -d2], [-d2, d2]])
    inv_mass = np.linalg.inv(mass)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-inv_mass @ stiffness, -inv_mass @ damping]])
    s = np.linalg.eigvals(A)
    s = s[s.imag > 0]
    return s[np.argsort(np.abs(s))]


def frf_on_grid(system, freqs):
    return 20 * np.log10(np.abs(system.frequency_response(freqs)))


# --------------------------------------------------------------------------- systems


def test_nominal_paper_modes_near_043_and_229_hz():
    s = second_order_modes(**PAPER_PARAMETERS)
    np.testing.assert_allclose(np.abs(s) / (2 * np.pi), [0.43, 2.29], atol=0.01)
    # undamped check from the stiffness alone: eig(K) = 107.5 -+ sqrt(107.5^2 - 1500)
    undamped = np.sqrt(107.5 + np.array([-1, 1]) * np.sqrt(107.5**2 - 1500)) / (2 * np.pi)
    np.testing.assert_allclose(np.abs(s) / (2 * np.pi), undamped, rtol=2e-3)

    A, *_ = two_mass_spring_damper()
    poles = np.linalg.eigvals(A)
    poles = poles[poles.imag > 0]
    np.testing.assert_allclose(np.sort_complex(poles), np.sort_complex(s), rtol=1e-10)

    system = paper_system()
    np.testing.assert_allclose(system.natural_frequencies, np.abs(s) / (2 * np.pi), rtol=1e-9)
    np.testing.assert_allclose(system.damping_ratios, -s.real / np.abs(s), rtol=1e-7)
    assert system.fast_nyquist == pytest.approx(5.0)
    assert system.slow_nyquist(3) == pytest.approx(1 / 0.6)


def test_static_gain_of_two_mass_system_is_compliance_of_first_spring():
    A, B, C, D = two_mass_spring_damper(k1=7.0, k2=30.0)
    assert (C @ np.linalg.solve(-A, B) + D).item() == pytest.approx(1 / 7.0)
    assert abs(paper_system(sample_time=0.05).frequency_response(0.0)) == pytest.approx(1 / 15)


@pytest.mark.parametrize("sample_time", [0.1, 0.02])
def test_zoh_matches_scipy_cont2discrete(sample_time):
    A, B, C, D = two_mass_spring_damper()
    Ad, Bd, Cd, Dd, _ = scipy.signal.cont2discrete((A, B, C, D), sample_time, method="zoh")
    system = paper_system(sample_time=sample_time)
    for ours, ref in zip((system.A, system.B, system.C, system.D), (Ad, Bd, Cd, Dd)):
        np.testing.assert_allclose(ours, ref, rtol=1e-10, atol=1e-13)
    assert system.sample_time == sample_time


def test_impulse_response_agrees_with_simulation_and_scipy():
    system = paper_system()
    n = 300
    g = system.impulse_response(n)
    impulse = np.zeros(n)
    impulse[0] = 1.0
    np.testing.assert_allclose(system.simulate(impulse), g, rtol=1e-12, atol=1e-15)

    dlti = (system.A, system.B, system.C, system.D, system.sample_time)
    _, (g_ref,) = scipy.signal.dimpulse(dlti, n=n)
    np.testing.assert_allclose(g, g_ref[:, 0], rtol=1e-10, atol=1e-14)

    u = multisine(n, random_state=4)
    _, y_ref, _ = scipy.signal.dlsim(dlti, u)
    np.testing.assert_allclose(system.simulate(u), y_ref[:, 0], rtol=1e-10, atol=1e-13)
    # a convolution with the full impulse response gives the same output (FIR of order N)
    np.testing.assert_allclose(np.convolve(u, g)[:n], y_ref[:, 0], rtol=1e-9, atol=1e-13)


def test_markov_parameters_with_direct_feedthrough():
    rng = np.random.default_rng(0)
    A = 0.5 * rng.standard_normal((3, 3)) / 3
    B, C = rng.standard_normal(3), rng.standard_normal(3)
    system = DiscreteSystem(A, B, C, 0.7, sample_time=1.0)
    expected = [0.7] + [C @ np.linalg.matrix_power(A, k - 1) @ B for k in range(1, 6)]
    np.testing.assert_allclose(system.impulse_response(6), expected, rtol=1e-12)


# scipy converts to a transfer function whose leading numerator coefficient is ~1e-18
# instead of 0 for this strictly proper system, and warns; the response is still exact.
@pytest.mark.filterwarnings("ignore::scipy.signal.BadCoefficients")
def test_frequency_response_matches_dft_of_impulse_response_and_dfreqresp():
    system = paper_system()
    g = system.impulse_response(6000)  # decayed to ~1e-20 of the peak
    freqs = np.array([0.0, 0.43, 1.0, 2.29, 4.9])
    w = 2 * np.pi * freqs * system.sample_time
    dtft = np.exp(-1j * np.outer(w, np.arange(g.size))) @ g
    H = system.frequency_response(freqs)
    np.testing.assert_allclose(H, dtft, rtol=1e-9)

    dlti = scipy.signal.dlti(system.A, system.B, system.C, system.D, dt=system.sample_time)
    _, H_ref = scipy.signal.dfreqresp(dlti, w=w)
    np.testing.assert_allclose(H, H_ref, rtol=1e-8)
    assert system.frequency_response(freqs.reshape(5, 1)).shape == (5, 1)


def test_discrete_system_validation():
    A, B, C = np.eye(2) * 0.5, np.ones(2), np.ones(2)
    with pytest.raises(ValueError, match="A"):
        DiscreteSystem(np.ones((2, 3)), B, C, 0.0, 1.0)
    with pytest.raises(ValueError, match="B"):
        DiscreteSystem(A, np.ones(3), C, 0.0, 1.0)
    with pytest.raises(ValueError, match="C"):
        DiscreteSystem(A, B, np.ones((2, 2)), 0.0, 1.0)
    with pytest.raises(ValueError, match="D"):
        DiscreteSystem(A, B, C, [0.0, 1.0], 1.0)
    with pytest.raises(ValueError, match="A"):
        DiscreteSystem(np.array([[np.nan, 0], [0, 0]]), B, C, 0.0, 1.0)
    with pytest.raises(ValueError, match="sample_time"):
        DiscreteSystem(A, B, C, 0.0, 0.0)
    system = DiscreteSystem(A, B, C, 0.0, 1.0)
    with pytest.raises(ValueError, match="u"):
        system.simulate(np.ones((3, 2)))
    with pytest.raises(ValueError, match="u"):
        system.simulate([1.0, np.inf])
    with pytest.raises(ValueError, match="n_lags"):
        system.impulse_response(0)
    with pytest.raises(ValueError, match="factor"):
        system.slow_nyquist(0)


def test_discrete_system_copies_its_inputs():
    A = np.array([[0.5]])
    system = DiscreteSystem(A, [1.0], [1.0], 0.0, 1.0)
    A[0, 0] = 0.9
    assert system.A[0, 0] == 0.5
    u = np.array([1.0, 2.0, 3.0])
    system.simulate(u)
    np.testing.assert_array_equal(u, [1.0, 2.0, 3.0])


# --------------------------------------------------------------------------- perturbation


def test_perturbation_stays_within_ten_percent_and_is_reproducible():
    draws = [perturb_parameters(PAPER_PARAMETERS, 0.1, random_state=seed) for seed in range(50)]
    ratios = np.array([[d[k] / v for k, v in PAPER_PARAMETERS.items()] for d in draws])
    assert np.all(np.abs(ratios - 1) <= 0.1)
    assert np.all(np.abs(ratios - 1).max(axis=0) > 0.08)  # the whole range is used
    same_seed = [perturb_parameters(PAPER_PARAMETERS, 0.1, random_state=7) for _ in range(2)]
    assert same_seed[0] == same_seed[1]
    assert perturb_parameters(PAPER_PARAMETERS, 0.0, 7) == PAPER_PARAMETERS

    params = perturb_parameters(PAPER_PARAMETERS, 0.1, random_state=7)
    A, B, C, D = two_mass_spring_damper(**params)
    Ad, Bd, *_ = scipy.signal.cont2discrete((A, B, C, D), 0.1, method="zoh")
    system = paper_system(perturbation=0.1, random_state=7)
    np.testing.assert_allclose(system.A, Ad, rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(system.B, Bd, rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(system.natural_frequencies,
                               np.abs(second_order_modes(**params)) / (2 * np.pi), rtol=1e-9)

    np.testing.assert_array_equal(paper_system(perturbation=0.1, random_state=7).A, system.A)
    assert not np.allclose(paper_system(perturbation=0.1, random_state=8).A, system.A)
    np.testing.assert_array_equal(
        paper_system(perturbation=0.1, random_state=np.random.default_rng(3)).A,
        paper_system(perturbation=0.1, random_state=3).A)
    with pytest.raises(ValueError, match="perturbation"):
        paper_system(perturbation=1.5)
    with pytest.raises(ValueError, match="random_state"):
        paper_system(perturbation=0.1, random_state="seed")


def test_legacy_random_state_is_accepted_and_advanced():
    rs = np.random.RandomState(0)
    first = paper_system(perturbation=0.1, random_state=rs)
    second = paper_system(perturbation=0.1, random_state=rs)
    assert not np.allclose(first.A, second.A)


# --------------------------------------------------------------------------- wafer stage


def test_wafer_surrogate_resonances_are_visible_peaks():
    system = wafer_stage_surrogate()
    assert system.sample_time == 1 / 2000
    assert system.slow_nyquist(3) == pytest.approx(1000 / 3)
    freqs = np.arange(400.0, 999.0, 0.1)
    mag = frf_on_grid(system, freqs)
    peaks = freqs[1:-1][(mag[1:-1] > mag[:-2]) & (mag[1:-1] > mag[2:])]
    for resonance, background in [(490, 450), (510, 550), (870, 800), (870, 950)]:
        nearest = peaks[np.argmin(np.abs(peaks - resonance))]
        assert abs(nearest - resonance) < 3
        height = mag[np.argmin(np.abs(freqs - nearest))] - frf_on_grid(system, background)
        assert 10 < height < 30


def test_wafer_surrogate_matches_independent_modal_transfer_function():
    system = wafer_stage_surrogate()
    freqs = np.array([10.0, 80.0, 300.0, 490.0, 505.0, 870.0, 990.0])
    z = np.exp(2j * np.pi * freqs * system.sample_time)
    expected = np.zeros(freqs.size, dtype=complex)
    for f, zeta, gain in WAFER_STAGE_MODES:
        wn = 2 * np.pi * f
        num, den, _ = scipy.signal.cont2discrete(
            ([gain * wn**2], [1.0, 2 * zeta * wn, wn**2]), system.sample_time, method="zoh")
        expected += np.polyval(num[0], z) / np.polyval(den, z)
    np.testing.assert_allclose(system.frequency_response(freqs), expected, rtol=1e-6)
    np.testing.assert_allclose(system.natural_frequencies, [m[0] for m in WAFER_STAGE_MODES])
    np.testing.assert_allclose(system.damping_ratios, [m[1] for m in WAFER_STAGE_MODES])
    np.testing.assert_allclose(system.D, 0.0)  # strictly proper


def test_wafer_surrogate_impulse_response_decays_within_600_samples():
    g = np.abs(wafer_stage_surrogate().impulse_response(1200))
    assert g[600:].max() < 1e-3 * g.max()
    perturbed = wafer_stage_surrogate(perturbation=0.1, random_state=1)
    ratios = perturbed.natural_frequencies / [m[0] for m in WAFER_STAGE_MODES]
    assert np.all(np.abs(ratios - 1) <= 0.1) and not np.allclose(ratios, 1)
    g = np.abs(perturbed.impulse_response(1200))
    assert g[600:].max() < 1e-3 * g.max()


# --------------------------------------------------------------------------- signals


def test_multisine_flat_spectrum_rms_and_zero_mean():
    n = 600
    u = multisine(n, rms=2.5, random_state=0)
    spectrum = np.abs(np.fft.rfft(u))
    excited = spectrum[1:n // 2]
    np.testing.assert_allclose(excited, excited[0], rtol=1e-9)
    assert spectrum[0] < 1e-9 * excited[0] and spectrum[n // 2] < 1e-9 * excited[0]
    assert np.sqrt(np.mean(u**2)) == pytest.approx(2.5, rel=1e-12)
    assert abs(u.mean()) < 1e-12
    # Parseval: the RMS is set by the excited bins alone
    assert np.sqrt(2 * np.sum(excited**2)) / n == pytest.approx(2.5, rel=1e-12)


def test_multisine_band_limits_energy():
    n, T = 601, 0.1  # odd length: rfft has no Nyquist bin
    u = multisine(n, sample_time=T, band=(0.3, 2.0), random_state=1)
    spectrum = np.abs(np.fft.rfft(u))
    freqs = np.fft.rfftfreq(n, d=T)
    inside = (freqs >= 0.3) & (freqs <= 2.0)
    np.testing.assert_allclose(spectrum[inside], spectrum[inside][0], rtol=1e-9)
    assert spectrum[~inside].max() < 1e-9 * spectrum[inside][0]
    assert np.sqrt(np.mean(u**2)) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="band"):
        multisine(n, sample_time=T, band=(0.001, 0.002))
    with pytest.raises(ValueError, match="band"):
        multisine(n, band=(2.0, 1.0))


def test_multisine_phases_depend_on_seed_only():
    np.testing.assert_array_equal(multisine(200, random_state=3), multisine(200, random_state=3))
    phase_a = np.angle(np.fft.rfft(multisine(200, random_state=3)))[1:100]
    phase_b = np.angle(np.fft.rfft(multisine(200, random_state=4)))[1:100]
    assert np.mean(np.abs(np.angle(np.exp(1j * (phase_a - phase_b)))) > 0.1) > 0.9
    with pytest.raises(ValueError, match="n_samples"):
        multisine(0)
    with pytest.raises(ValueError, match="rms"):
        multisine(100, rms=-1.0)
    with pytest.raises(ValueError, match="sample_time"):
        multisine(100, sample_time=0.0)


def test_random_binary_sequence():
    u = random_binary_sequence(10000, amplitude=0.5, random_state=0)
    assert set(np.unique(u)) == {-0.5, 0.5}
    assert abs(u.mean()) < 0.05
    np.testing.assert_array_equal(u, random_binary_sequence(10000, 0.5, random_state=0))
    with pytest.raises(ValueError, match="amplitude"):
        random_binary_sequence(10, amplitude=0.0)


def test_zero_order_hold_and_zoh_input():
    np.testing.assert_array_equal(zero_order_hold(np.array([1.0, -2.0]), 2), [1, 1, -2, -2])
    u = zoh_input(10, 3, random_state=0)
    assert u.shape == (10,)
    np.testing.assert_array_equal(u[:9].reshape(3, 3), np.repeat(u[:9:3, None], 3, axis=1))
    np.testing.assert_array_equal(u, zoh_input(10, 3, random_state=0))
    with pytest.raises(ValueError, match="factor"):
        zero_order_hold([1.0], 0)
    with pytest.raises(ValueError, match="u_slow"):
        zero_order_hold(np.ones((2, 2)), 2)
    with pytest.raises(ValueError, match="n_samples"):
        zoh_input(0, 3)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-1e6, 1e6), min_size=1, max_size=20), st.integers(1, 5), st.data())
def test_downsampling_a_held_signal_recovers_it(values, factor, data):
    offset = data.draw(st.integers(0, factor - 1))
    held = zero_order_hold(values, factor)
    assert held.shape == (len(values) * factor,)
    np.testing.assert_array_equal(downsample(held, factor, offset), values)


def test_downsample_validation():
    y = np.arange(10.0)
    assert downsample(y, 3).tolist() == [0.0, 3.0, 6.0, 9.0]
    assert downsample(y, 3, offset=2).shape == (3,)
    with pytest.raises(ValueError, match="factor"):
        downsample(y, 0)
    with pytest.raises(ValueError, match="factor"):
        downsample(y, 2.0)
    with pytest.raises(ValueError, match="offset"):
        downsample(y, 3, offset=3)
    with pytest.raises(ValueError, match="offset"):
        downsample(y, 3, offset=-1)
    with pytest.raises(ValueError, match="y"):
        downsample(np.ones((2, 5)), 2)


# --------------------------------------------------------------------------- noise and experiments


def test_add_output_noise_reaches_snr_and_keeps_input():
    rng = np.random.default_rng(0)
    y = 3.0 + 2.0 * rng.standard_normal(200_000)  # the mean must not count as signal
    y_before = y.copy()
    y_noisy, noise_std = add_output_noise(y, 40.0, random_state=1)
    np.testing.assert_array_equal(y, y_before)
    noise = y_noisy - y
    assert noise_std == pytest.approx(np.std(y) / 100)
    assert 10 * np.log10(np.var(y) / np.var(noise)) == pytest.approx(40.0, abs=0.05)
    assert abs(noise.mean()) < 5 * noise_std / np.sqrt(y.size)
    np.testing.assert_array_equal(y_noisy, add_output_noise(y, 40.0, random_state=1)[0])
    with pytest.raises(ValueError, match="snr_db"):
        add_output_noise(y, np.nan)


def test_simulate_experiment_paper_setting():
    system = paper_system()
    u = multisine(600, sample_time=system.sample_time, random_state=0)
    u_before = u.copy()
    data = simulate_experiment(system, u, factor=3, snr_db=50.0, offset=1, random_state=2)
    np.testing.assert_array_equal(u, u_before)
    np.testing.assert_allclose(data.y_fast, system.simulate(u))
    np.testing.assert_array_equal(data.y_slow, data.y_fast_noisy[1::3])
    assert data.y_slow.shape == (200,) and data.factor == 3 and data.offset == 1
    assert data.noise_std == pytest.approx(np.std(data.y_fast) * 10 ** (-50 / 20))
    assert data.sample_time == 0.1 and data.system is system

    clean = simulate_experiment(system, u, factor=3)
    assert clean.noise_std == 0.0
    np.testing.assert_array_equal(clean.y_slow, clean.y_fast[::3])
    with pytest.raises(ValueError, match="offset"):
        simulate_experiment(system, u, factor=3, offset=3)


def test_perturbation_must_not_be_a_bool():
    # found by the hostile-input search: False passed as 0
    with pytest.raises(ValueError, match="perturbation"):
        paper_system(perturbation=False)
