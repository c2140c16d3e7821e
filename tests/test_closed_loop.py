"""Closed-loop identification: the two-stage fit, feedback detection, the loop's responses."""

import warnings

import numpy as np
import pytest
from numpy.lib.stride_tricks import sliding_window_view
from scipy import signal

import gpmultirate as gm
from gpmultirate import simulation as sim
from gpmultirate.closedloop import (
    as_controller, feedback_test, fit_excitation_model, intersample_performance,
    plant_from_process_sensitivity,
)
from gpmultirate.closedloop.performance import camera_loop_response
from gpmultirate.residuals import analyze_residuals

T, F = 1 / 500, 5


def _loop(n, seed, feedback=True, rms=0.05):
    plant = sim.camera_loop_plant(T)
    r = 0.3 * np.random.default_rng(seed).standard_normal(n)
    v = sim.frame_disturbance(len(range(0, n, F)), F * T, rms=rms, random_state=seed + 1000)
    return sim.simulate_camera_loop(plant, r, F, disturbance=v, feedback=feedback)


def _quick(order):
    """A fit at a given order with white noise: quick on records of thousands of samples."""
    return gm.FIRGaussianProcess(factor=F, order=order, noise_kernel="white", sample_time=T)


def _regressor(x, order):
    return sliding_window_view(np.concatenate([np.zeros(order - 1), x]), order)[:, ::-1]


# ------------------------------------------------------------------ simulation
def test_camera_loop_matches_an_independent_lifted_simulation():
    """The loop, recomputed from the plant's impulse response and the held controller output."""
    loop = _loop(1500, 0)
    g = loop.system.impulse_response(1500)
    y_fast = np.convolve(loop.u, g)[:1500]
    assert np.allclose(loop.y_fast, y_fast, atol=1e-10)
    assert np.allclose(loop.y_slow, y_fast[::F] + loop.disturbance)
    c = -1.5 * loop.y_slow  # the proportional controller on the frames
    held = np.concatenate([np.zeros(F), np.repeat(c, F)])[:1500]  # one frame of delay
    assert np.allclose(loop.u, loop.excitation + held)


def test_open_camera_loop_is_the_plant_driven_by_the_excitation():
    loop = _loop(1000, 1, feedback=False)
    assert np.array_equal(loop.u, loop.excitation)


@pytest.mark.parametrize("controller", [0.5, [0.5, 0.0], signal.dlti([0.5], [1.0], dt=0.01)])
def test_controller_forms_agree(controller):
    c = as_controller(controller)
    assert np.allclose(c.frequency_response([0.0, 10.0], 0.01), 0.5)


def test_python_control_system_is_read_as_its_transfer_function():
    control = pytest.importorskip("control")
    lag = control.tf([0.5, 0.0], [1.0, -0.5], 0.01)  # 0.5 z / (z - 0.5) = 0.5 / (1 - 0.5 z^-1)
    c = as_controller(lag)
    assert np.allclose(c.numerator, [0.5, 0.0]) and np.allclose(c.denominator, [1.0, -0.5])
    assert np.allclose(c.filter([1.0, 0.0, 0.0]), [0.5, 0.25, 0.125])
    assert np.allclose(as_controller(control.ss(lag)).frequency_response([3.0], 0.01),
                       c.frequency_response([3.0], 0.01))


def test_controller_refuses_continuous_and_improper_systems():
    with pytest.raises(ValueError, match="discrete"):
        as_controller(signal.lti([1.0], [1.0, 1.0]))
    with pytest.raises(ValueError, match="proper"):
        as_controller(signal.dlti([1.0, 0.0, 0.0], [1.0, 0.5], dt=0.1))
    with pytest.raises(ValueError, match="controller"):
        as_controller("pid")


# ------------------------------------------------------------------ the two-stage fit
def test_excitation_equal_to_the_input_is_the_plain_fit():
    loop = _loop(2000, 2, feedback=False)
    plain = _quick(120).fit(loop.u, loop.y_slow)
    model = _quick(120).fit(
        loop.u, loop.y_slow, excitation=loop.u.copy())
    assert np.array_equal(plain.coef_, model.coef_)
    assert plain.log_marginal_likelihood_value_ == model.log_marginal_likelihood_value_
    assert model.excitation_model_.identity and plain.excitation_model_ is None


@pytest.mark.parametrize("bad, message", [
    (np.zeros(10), "length of u"),
    (np.full(2000, np.nan), "finite"),
    (np.zeros(2000), "zero"),
    (np.ones((2000, 2)), "1-D"),
])
def test_bad_excitation_is_refused_naming_it(bad, message):
    loop = _loop(2000, 3)
    with pytest.raises(ValueError, match="excitation") as info:
        gm.FIRGaussianProcess(factor=F).fit(loop.u, loop.y_slow, excitation=bad)
    assert message in str(info.value)


def test_excitation_is_not_modified():
    loop = _loop(2000, 4)
    r = loop.excitation.copy()
    _quick(100).fit(loop.u, loop.y_slow, excitation=r)
    assert np.array_equal(r, loop.excitation)


def test_first_stage_recovers_a_known_filter_per_phase():
    rng = np.random.default_rng(5)
    r = rng.standard_normal(3000)
    h = np.array([[1.0, 0.5, 0.0], [1.0, -0.5, 0.25]])  # phase-dependent: n mod 2
    reg = _regressor(r, 3)
    u = np.empty(3000)
    u[0::2], u[1::2] = reg[0::2] @ h[0], reg[1::2] @ h[1]
    u += 0.05 * rng.standard_normal(3000)
    first = fit_excitation_model(u, r, gm.FIRGaussianProcess, period=2, order=6)
    assert np.allclose(first.coef[:, :3], h, atol=0.01)
    assert np.allclose(first.coef[:, 3:], 0.0, atol=0.01)
    draws = first.sample_inputs(r, 200, random_state=0)
    spread = draws.std(axis=0)
    assert np.all(spread > 0) and np.mean(spread) < 0.01  # about sqrt(6 / 1500) * 0.05


def _two_stage_bias(n, seeds, order=400, first_order=300):
    """Least squares of both stages (an independent computation of the two-stage method)."""
    g0 = sim.camera_loop_plant(T).impulse_response(order)
    direct, projected = [], []
    for seed in seeds:
        loop = _loop(n, seed, rms=0.1)
        R = _regressor(loop.excitation, first_order)
        u_r = R @ np.linalg.lstsq(R, loop.u, rcond=None)[0]
        for u, out in ((loop.u, direct), (u_r, projected)):
            g = np.linalg.lstsq(_regressor(u, order)[::F], loop.y_slow, rcond=None)[0]
            out.append(g - g0)
    return (np.linalg.norm(np.mean(direct, axis=0)), np.linalg.norm(np.mean(projected, axis=0)))


@pytest.mark.slow
def test_two_stage_bias_shrinks_with_the_record_and_the_direct_bias_does_not():
    short = _two_stage_bias(20_000, range(3))
    long = _two_stage_bias(80_000, range(3))
    assert long[0] > 0.8 * short[0]  # the direct fit's bias stays
    assert long[1] < 0.6 * short[1]  # the two-stage error shrinks
    assert long[1] < 0.3 * long[0]


@pytest.mark.slow
def test_kernel_two_stage_fit_is_consistent_where_the_direct_fit_is_biased():
    """The library's fit against the true plant, where the loop acts, at two record lengths.

    Order 400 covers the plant's memory; white noise keeps the fits quick.
    Measured (seeds 7 and 8): with the excitation 0.032 and 0.024 at 5,000
    samples, 0.0074 and 0.0092 at 20,000; the direct fit 0.10-0.16 at both.
    """
    plant = sim.camera_loop_plant(T)
    freqs = np.linspace(1.0, 45.0, 60)
    G = np.abs(plant.frequency_response(freqs))
    errors = {}
    for n in (5_000, 20_000):
        for seed in (7, 8):
            loop = _loop(n, seed, rms=0.1)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", gm.FeedbackWarning)
                direct = _quick(400).fit(loop.u, loop.y_slow)
            model = _quick(400).fit(loop.u, loop.y_slow, excitation=loop.excitation)
            errors.setdefault(n, []).append(
                [np.median(np.abs(np.abs(m.frequency_response(freqs).mean) - G))
                 for m in (direct, model)])
    short, long = np.mean(errors[5_000], axis=0), np.mean(errors[20_000], axis=0)
    assert long[1] < 0.6 * short[1]  # the two-stage error shrinks with the record
    assert long[0] > 0.7 * short[0]  # the direct fit's bias does not
    assert long[1] < 0.2 * long[0]


# ------------------------------------------------------------------ detection
def test_feedback_warning_fires_on_a_camera_loop_and_names_the_excitation():
    loop = _loop(5000, 8)
    with pytest.warns(gm.FeedbackWarning, match="excitation="):
        _quick(150).fit(loop.u, loop.y_slow)


def test_no_feedback_warning_on_the_same_experiment_in_open_loop_or_with_the_excitation():
    for seed in (9, 10):
        open_loop = _loop(5000, seed, feedback=False)
        with warnings.catch_warnings():
            warnings.simplefilter("error", gm.FeedbackWarning)
            _quick(150).fit(open_loop.u, open_loop.y_slow)
            closed = _loop(5000, seed)
            _quick(150).fit(
                closed.u, closed.y_slow, excitation=closed.excitation)


def test_feedback_test_false_alarm_rate_under_coloured_residuals_and_inputs():
    """Monte Carlo: independent AR(1) residuals and a coloured input, level 0.05."""
    rng = np.random.default_rng(11)
    p_values = []
    for _ in range(300):
        e = signal.lfilter([1.0], [1.0, -0.7], rng.standard_normal(400))
        u = signal.lfilter([1.0], [1.0, -0.9], rng.standard_normal(1200))
        p_values.append(feedback_test(e, np.arange(0, 1200, 3), u, factor=3).p_value)
    rate = np.mean(np.array(p_values) < 0.05)
    assert 0.02 < rate < 0.09  # 0.05 +- 3 binomial standard deviations (0.013)


def test_analyze_residuals_reports_feedback():
    loop = _loop(5000, 12)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", gm.FeedbackWarning)
        model = _quick(150).fit(loop.u, loop.y_slow)
    analysis = analyze_residuals(model, loop.u, loop.y_slow)
    assert analysis.closed_loop and analysis.feedback_p_value[0] < 1e-6
    assert np.any(analysis.input_lags < 0)
    open_loop = _loop(5000, 12, feedback=False)
    model = _quick(150).fit(open_loop.u, open_loop.y_slow)
    assert not analyze_residuals(model, open_loop.u, open_loop.y_slow).closed_loop


# ------------------------------------------------------------------ the loop's responses
def test_camera_loop_response_matches_the_simulated_loop():
    """Alias amplitudes of the fast output for a complex sinusoid, against the simulation."""
    plant = sim.camera_loop_plant(T)
    n_tail, k0, n = 1000, 37, 6000
    f0 = k0 / (n_tail * T)
    t = np.arange(n)
    outputs = []
    for r in (np.cos(2 * np.pi * f0 * T * t), np.sin(2 * np.pi * f0 * T * t)):
        loop = sim.simulate_camera_loop(plant, r, F, disturbance=np.zeros(n // F))
        outputs.append(loop.y_fast[-n_tail:])
    y = outputs[0] + 1j * outputs[1]  # the response to exp(j w n)
    spectrum = np.fft.fft(y) / n_tail * np.exp(2j * np.pi * k0 * (n - n_tail) / n_tail)
    aliases = k0 + np.arange(F) * n_tail // F
    G = plant.frequency_response(f0 + np.arange(F) / (F * T))[:, None]
    gain, Ys = camera_loop_response(G, [f0], T, F, 1.5, 1)
    assert np.isclose(gain[0], np.sqrt(np.sum(np.abs(spectrum[aliases]) ** 2)), rtol=1e-6)
    assert np.isclose(np.abs(Ys[0]), np.abs(np.sum(spectrum[aliases])), rtol=1e-6)


@pytest.mark.slow
def test_intersample_performance_band_holds_the_true_gain():
    loop = _loop(10_000, 13)
    model = gm.FIRGaussianProcess(factor=F, sample_time=T).fit(
        loop.u, loop.y_slow, excitation=loop.excitation)
    perf = intersample_performance(model, 1.5, n_samples=300, random_state=0)
    G = loop.system.frequency_response(
        perf.fast.freqs[None, :] + np.arange(F)[:, None] / (F * T))
    true_gain, _ = camera_loop_response(G, perf.fast.freqs, T, F, 1.5, 1)
    # one record: the frequencies' errors are correlated, so the share varies (0.815 measured)
    assert np.mean(perf.fast.contains(true_gain)) > 0.7


def test_plant_from_process_sensitivity_of_a_fast_loop():
    """A fast loop C around P; r added to the controller output; the slow sensor is P's output."""
    rng = np.random.default_rng(14)
    n, factor = 3000, 3
    b, a = [0.0, 0.2, 0.1], [1.0, -1.2, 0.5]  # P(z)
    k = 0.8
    r = rng.standard_normal(n)
    # y = P u, u = r - k y  =>  y = P / (1 + k P) r
    y = signal.lfilter(b, np.polyadd(a, k * np.array(b)), r)
    noise = 1e-3 * rng.standard_normal((2, n))
    ps = gm.FIRGaussianProcess(factor=factor, order=60, noise_kernel="white").fit(
        r, (y + noise[0])[::factor])
    sensor = gm.FIRGaussianProcess(order=60, noise_kernel="white").fit(r, y + noise[1])
    freqs = np.linspace(0.01, 0.45, 40)
    true = signal.freqz(b, a, worN=2 * np.pi * freqs)[1]
    for loop_sensor in (None, sensor):
        plant = plant_from_process_sensitivity(ps, k, loop_sensor=loop_sensor, freqs=freqs,
                                               random_state=0)
        assert np.allclose(plant.mean, true, rtol=0.05, atol=0.01)
        assert np.mean(plant.contains(np.abs(true))) > 0.8


@pytest.mark.slow
def test_command_line_fit_with_an_excitation_column(tmp_path):
    from gpmultirate.cli import main

    loop = _loop(3000, 15)
    y = np.full(3000, np.nan)
    y[::F] = loop.y_slow
    data = tmp_path / "loop.csv"
    rows = np.column_stack([loop.u, loop.excitation, y])
    with open(data, "w") as f:
        f.write("u,r,y\n")
        for row in rows:
            f.write(",".join("" if np.isnan(x) else repr(float(x)) for x in row) + "\n")
    out = tmp_path / "out"
    assert main(["fit", str(data), "--input", "u", "--excitation", "r",
                 "--output", "y", "--factor", str(F), "--order", "100", "--noise", "white", "--quiet",
                 "--out", str(out)]) == 0
    assert (out / "model.npz").is_file()
    with pytest.raises(SystemExit):
        main(["fit", str(data), "--input", "u", "--excitation", "u", "--output", "y",
              "--factor", str(F), "--quiet", "--out", str(tmp_path / "again")])


@pytest.mark.slow
def test_first_stage_spread_is_small_against_the_posterior():
    """Law of total variance: refits on first-stage draws move the FRF little against its band."""
    from sklearn.base import clone

    loop = _loop(6000, 16)
    model = gm.FIRGaussianProcess(factor=F, sample_time=T).fit(
        loop.u, loop.y_slow, excitation=loop.excitation)
    freqs = np.linspace(0.5, 249.5, 100)
    frf = model.frequency_response(freqs)
    posterior = frf.real_std**2 + frf.imag_std**2
    fixed = gm.FIRGaussianProcess(model.kernel_, factor=F, sample_time=T,
                                  order=model.coef_.shape[0], optimizer=None,
                                  noise_level=model.noise_level_, noise_kernel=model.noise_kernel_)
    means = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for u_r in model.excitation_model_.sample_inputs(loop.excitation, 8, random_state=0):
            means.append(clone(fixed).fit(u_r, loop.y_slow).frequency_response(freqs).mean)
    spread = np.var(np.array(means), axis=0, ddof=1)
    assert np.all(spread > 0)  # the draws differ
    assert np.median(spread / posterior) < 0.05
