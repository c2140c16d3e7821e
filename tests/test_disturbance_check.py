"""The disturbance check of noise_kernel="auto" at any order: an AR(1) disturbance seen at an
order below the record's length and at it, white noise kept on white data (the cut tail is
not a disturbance), and the band's coverage under AR(1) disturbances by Monte Carlo."""

import warnings

import numpy as np
import pytest
from scipy import signal

from gpmultirate import FIRGaussianProcess
from gpmultirate.simulation import multisine, paper_system

N, FACTOR = 600, 3


def _paper_record(seed, pole=None, snr_db=20.0):
    """A paper-like system (Section 5, parameters within 10 %), a multisine, and an AR(1)
    disturbance of ``pole`` at the fast rate (white noise when None) at ``snr_db``."""
    rng = np.random.default_rng(seed)
    system = paper_system(perturbation=0.1, random_state=rng)
    u = multisine(N, 0.1, random_state=rng)
    y = system.simulate(u)
    if pole is None:
        v = rng.standard_normal(N)
    else:
        e = rng.standard_normal(N) * np.sqrt(1.0 - pole**2)
        v, _ = signal.lfilter([1.0], [1.0, -pole], e, zi=[pole * rng.standard_normal()])
    y_slow = (y + v * np.sqrt(np.var(y) / 10 ** (snr_db / 10)))[::FACTOR]
    return system, u, y_slow


def _fit(u, y_slow, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return FIRGaussianProcess(factor=FACTOR, sample_time=0.1, **options).fit(u, y_slow)


@pytest.mark.slow  # a disturbance tuned: about 1.5 s of CPU each, more on a loaded machine
@pytest.mark.parametrize("order", [300, N])
def test_auto_chooses_a_disturbance_under_an_ar1_one_below_and_at_the_record_length(order):
    _, u, y_slow = _paper_record(1, pole=0.99)
    assert _fit(u, y_slow, order=order).noise_kernel_ != "white"


@pytest.mark.parametrize("order, seed", [(100, 0), (300, 1), (None, 2)])
def test_auto_keeps_white_noise_on_white_data_at_a_cut_order_and_by_default(order, seed):
    _, u, y_slow = _paper_record(seed, snr_db=50.0)
    assert _fit(u, y_slow, order=order).noise_kernel_ == "white"


@pytest.mark.slow
def test_the_cut_tail_alone_would_win_a_disturbance_the_check_looks_past_it():
    """At order 50 the paper system's tail colours the residuals: tuned, a disturbance wins
    by the evidence; the check, which looks at all the record's lags, keeps white noise."""
    _, u, y_slow = _paper_record(3, snr_db=50.0)
    coloured = _fit(u, y_slow, order=50, noise_kernel="matern32")
    white = _fit(u, y_slow, order=50, noise_kernel="white")
    assert coloured.log_marginal_likelihood_value_ > white.log_marginal_likelihood_value_ + 10
    assert _fit(u, y_slow, order=50).noise_kernel_ == "white"


@pytest.mark.slow
@pytest.mark.parametrize("order", [300, N])
def test_impulse_band_coverage_under_ar1_disturbances_by_monte_carlo(order):
    """Paper-like systems, AR(1) at the fast rate (pole 0.99, 20 dB): the 95 % band of the
    default fit holds 0.92-0.98 of the true impulse response on average over eight runs."""
    coverage, chosen = [], 0
    for seed in range(8):
        system, u, y_slow = _paper_record(seed, pole=0.99)
        model = _fit(u, y_slow, order=order)
        chosen += model.noise_kernel_ != "white"
        mean, std = model.impulse_response(return_std=True)
        truth = system.impulse_response(order)
        coverage.append(np.mean(np.abs(truth - mean) <= 1.959964 * std))
    assert chosen == 8
    assert 0.92 <= np.mean(coverage) <= 0.98
