"""The calibration benchmark's floor (``benchmarks/calibration.py``), against its exact readings.

The floor reads the true response at the integer lags through the hold's
rows; the readings it is judged against come from the state-space model
carried over the partial period by matrix exponentials, independently of
the library.
"""

import importlib.util
import sys
from pathlib import Path

import numpy as np

PATH = Path(__file__).resolve().parent.parent / "benchmarks" / "calibration.py"
spec = importlib.util.spec_from_file_location("benchmark_calibration", PATH)
benchmark = importlib.util.module_from_spec(spec)
sys.modules[spec.name] = benchmark
spec.loader.exec_module(benchmark)


def _first_order(time_constant, delay=0.0):
    A, B, C = np.array([[-1 / time_constant]]), np.array([[1 / time_constant]]), np.array([[1.0]])
    return A, B, C, np.zeros((1, 1)), delay


def _mode(samples_per_period, damping=0.1):
    w = 2 * np.pi / samples_per_period
    A = np.array([[0.0, 1.0], [-w * w, -2 * damping * w]])
    return A, np.array([[0.0], [1.0]]), np.array([[w * w, 0.0]]), np.zeros((1, 1)), 0.0


def _floor(system, instants, exposure=0.0, order=200):
    u = np.random.default_rng(0).standard_normal(400)
    truth = benchmark.readings(system, u, instants, exposure)
    return benchmark.rule_floor(system, u, instants, exposure, order, truth)


def test_the_floor_on_the_ticks_is_exact():
    # on the ticks the hold's rows are the fast regressor rows: the true response at the
    # integer lags gives the exact readings (a delay between integer lags included)
    ticks = np.arange(220.0, 399.0)
    for system in (_first_order(12.0), _first_order(3.0, delay=1.6), _mode(4.0)):
        assert _floor(system, ticks) > 100 - 1e-8


def test_the_floor_between_the_ticks_measures_the_rule():
    # a smooth response (a mode at 20 fast samples per period, relative degree two) is read
    # between the ticks almost exactly; a delay's kinks between integer lags are not
    rng = np.random.default_rng(1)
    between = np.sort(rng.uniform(220.0, 398.0, 150))
    smooth = _floor(_mode(20.0), between)
    delayed = _floor(_first_order(2.0, delay=2.5), between)
    assert smooth > 99.99
    assert delayed < 99.9
    # the order's cut shows too: a leaky integrator cut at 40 lags of its 100-period memory
    leaky = (np.array([[-0.01]]), np.array([[1.0]]), np.array([[0.1]]), np.zeros((1, 1)), 0.0)
    assert _floor(leaky, between, order=40) < 90 < _floor(leaky, between, order=300)
