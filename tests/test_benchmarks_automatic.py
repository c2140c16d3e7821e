"""The truth of the automatic-choices benchmark (``benchmarks/automatic.py``), checked
against an independent simulation: each mode's transfer function discretised and
simulated by :mod:`scipy.signal`."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.signal

PATH = Path(__file__).resolve().parent.parent / "benchmarks" / "automatic.py"
spec = importlib.util.spec_from_file_location("benchmark_automatic", PATH)
benchmark = importlib.util.module_from_spec(spec)
sys.modules[spec.name] = benchmark  # dataclasses look their module up by name
spec.loader.exec_module(benchmark)


def scipy_terms(system, k):
    """Zero-order-hold discretisations of input ``k``'s terms, one transfer function each."""
    terms = []
    for mode in system.modes[k]:
        w = 2 * np.pi * mode.frequency_hz
        terms.append(([mode.gain * w * w], [1.0, 2 * mode.damping * w, w * w]))
    if system.first_order[k] is not None:
        gain, tau = system.first_order[k]
        terms.append(([gain], [tau, 1.0]))
    return [scipy.signal.cont2discrete(term, system.sample_time, method="zoh")
            for term in terms]


@pytest.mark.filterwarnings("ignore::scipy.signal.BadCoefficients")
@pytest.mark.parametrize("family", ["alias", "no_resonance", "two_input", "long_memory"])
def test_true_impulse_response_and_validation_output_match_scipy(family):
    system = benchmark.draw_system(family, 11, quick=True)
    u_val = system.u_val.reshape(system.u_val.shape[0], -1)
    n = 300
    y_val = np.zeros(u_val.shape[0])
    for k in range(system.n_inputs):
        impulse = np.zeros(n)
        for num, den, dt in scipy_terms(system, k):
            (response,) = scipy.signal.dimpulse((num[0], den, dt), n=n)[1]
            impulse += response[:, 0]
            y_val += scipy.signal.dlsim((num[0], den, dt), u_val[:, k])[1][:, 0]
        np.testing.assert_allclose(system.impulse[k, :n], impulse, rtol=1e-7,
                                   atol=1e-10 * np.abs(impulse).max())
    np.testing.assert_allclose(system.y_val, y_val, rtol=1e-6,
                               atol=1e-9 * np.abs(y_val).max())
    assert system.y_slow.shape == (-(-system.u.shape[0] // system.factor),)


def test_alias_family_puts_the_upper_modes_alias_within_two_percent_of_the_lower():
    for seed in range(5):
        system = benchmark.draw_system("alias", seed)
        low, high = system.true_frequencies
        slow_rate = 1 / (system.factor * system.sample_time)
        assert low < slow_rate / 2 < high
        assert abs(abs(high - slow_rate) / low - 1) <= 0.02 + 1e-12


def test_ar1_disturbance_has_the_drawn_pole_and_variance():
    # the sample autocorrelation of a long draw against pole^lag (Monte Carlo)
    rng = np.random.default_rng(0)
    v = benchmark._ar1(200_000, 0.95, rng)
    assert abs(v.var() - 1) < 0.05
    for lag in (1, 5, 20):
        assert abs(np.mean(v[lag:] * v[:-lag]) - 0.95**lag) < 0.05


def test_oracle_pk_terms_sit_at_the_true_modes():
    system = benchmark.draw_system("two_mass", 2)
    kernel = benchmark.oracle_kernel(system)
    terms = [kernel.k2, kernel.k1.k2]
    for mode, term in zip(system.modes[0][::-1], terms):
        w = 2 * np.pi * mode.frequency_hz
        assert term.omega == pytest.approx(w * np.sqrt(1 - mode.damping**2) * system.sample_time)
        # PK's variance decays by alpha per lag: the squared envelope of the mode
        assert term.alpha == pytest.approx(np.exp(-mode.damping * w * system.sample_time) ** 2)


def test_judge_resonances_counts_aliases_as_true_and_others_as_false():
    system = benchmark.draw_system("alias", 4)
    low, high = system.true_frequencies
    slow_rate = 1 / (system.factor * system.sample_time)
    verdict = benchmark.judge_resonances(system, [low, abs(high - slow_rate), 0.5 * (low + high)])
    assert (verdict["found"], verdict["false"]) == (3, 1)
    assert benchmark.judge_resonances(system, [])["missed"] == 2
