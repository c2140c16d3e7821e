"""Progress that is true: the time left from measured evaluations, the heartbeat, the steps' line."""

import io
import time
import types

import numpy as np
import pytest

import gpmultirate as gm
from gpmultirate import progress
from gpmultirate.progress import (
    EvaluationClock,
    StepTimes,
    show_progress,
    step,
    time_left,
)


def test_time_left_is_the_measured_cost_times_the_evaluations_to_come():
    # 4 evaluations measured, 10 expected: 6 more at the mean of the last five
    assert time_left([3.0, 1.0, 1.0, 2.0], 10) == pytest.approx(6 * 7.0 / 4)
    # the mean of the last five only: an early slow evaluation is forgotten
    assert time_left([100.0] + [1.0] * 5, 8) == pytest.approx(2.0)
    # a run past its expected count: half again as many
    assert time_left([2.0] * 20, 10) == pytest.approx(2.0 * 10)
    assert np.isnan(time_left([], 10))


def test_clock_expects_the_latest_run_of_its_kind_and_reports_the_current_one():
    clock = EvaluationClock()
    assert clock.expected() == progress.TYPICAL_EVALUATIONS and clock.summary() is None
    for count, kind in ((10, "a"), (40, "a"), (20, "a"), (12, "a"), (54, "b")):
        with clock.run(kind):
            f = clock.timed(lambda: None)
            for _ in range(count):
                f()
    # RUN_SHARE of the latest of its kind (the median of the earlier "a" runs would be 20)
    assert clock.runs == [10, 40, 20, 12, 54] and clock.expected("a") == round(0.7 * 12)
    assert clock.expected("b") == round(0.7 * 54)
    assert clock.expected("c") == round(0.7 * 54)  # a kind not seen yet: the latest run
    with clock.run("a"):
        slow = clock.timed(lambda: time.sleep(0.01))
        for _ in range(5):
            slow()
        text = clock.summary()
    assert text.startswith("tuning: 5 evaluation(s) of the evidence")
    # 3 more (0.7 x 12 = 8 expected) at about 0.01 s each
    left = float(text.rsplit("about ", 1)[1].split(" s")[0])
    assert 0.0 <= left <= 2.0
    assert clock.summary() is None  # the run is over


def test_an_estimate_fed_the_measured_costs_of_a_run_is_within_a_factor_two():
    # a run of 30 evaluations whose cost drifts by 30 % (as an optimizer's line
    # searches do): the estimate after each of the first 25 is within 2x of the rest
    rng = np.random.default_rng(0)
    costs = 1.0 + 0.3 * rng.uniform(-1, 1, 30)
    for done in range(3, 26):
        actual = costs[done:].sum()
        estimate = time_left(costs[:done], 30)
        assert actual / 2 <= estimate <= 2 * actual


@pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
def test_a_fit_times_its_evaluations():
    rng = np.random.default_rng(1)
    u = rng.standard_normal(300)
    y = np.convolve(u, 0.8 ** np.arange(20))[:300] + 0.01 * rng.standard_normal(300)
    before = len(progress.EVALUATIONS.runs)
    gm.FIRGaussianProcess(order=20, factor=3, noise_kernel="white").fit(u, y[::3])
    assert len(progress.EVALUATIONS.runs) > before and progress.EVALUATIONS.runs[-1] >= 1
    assert progress.EVALUATIONS.seconds is None  # no run left open


def test_no_step_runs_ten_seconds_without_a_line():
    stream = io.StringIO()
    with show_progress(stream, prefix="t", interval=0.2), StepTimes() as steps:
        with step("state space"):
            time.sleep(0.75)
    lines = stream.getvalue().splitlines()
    assert any("still on state space" in line for line in lines)
    times = [float(line.split("[", 1)[1].split(" s]")[0]) for line in lines]
    assert np.all(np.diff([0.0, *times]) < 0.2 + 0.5)  # never silent much beyond the interval
    assert "] state space: " in lines[-1]
    assert steps.times["state space"] >= 0.75
    assert steps.line().startswith("steps: state space ")


def test_steps_add_up_and_nothing_is_timed_without_active_steps():
    steps = StepTimes()
    with steps:
        for _ in range(2):
            with step("bands"):
                time.sleep(0.01)
    with step("bands"):
        pass
    assert list(steps.times) == ["bands"] and steps.times["bands"] >= 0.02
    assert steps.line().endswith(f"total {steps.times['bands']:.1f} s")


@pytest.mark.slow
def test_the_time_left_of_a_fit_is_within_a_factor_two_of_its_measured_time(monkeypatch):
    """End to end: the estimate after a few evaluations of a second fit against its rest.

    The first fit sets the expected number of evaluations (as the default
    order's pilot fits do for the fit at the chosen order); the second one
    is timed and estimated from its own measured evaluations (the process's
    clock starts without the runs of earlier tests).  The clock and
    the test count this process's CPU seconds (one BLAS thread, conftest.py):
    on a machine busy with other work the wall time of the same evaluations
    varies by more than the factor two asked here.
    """
    monkeypatch.setattr(progress, "time", types.SimpleNamespace(perf_counter=time.process_time))
    rng = np.random.default_rng(2)
    u = rng.standard_normal(6000)
    g = 0.995 ** np.arange(600) * np.sin(0.08 * np.arange(600))
    y = np.convolve(u, g)[:6000] + 0.05 * rng.standard_normal(6000)
    clock = progress.EVALUATIONS
    # the runs of earlier tests in this process would set the expected count otherwise
    monkeypatch.setattr(clock, "runs", [])
    model = gm.FIRGaussianProcess(order=600, factor=10, noise_kernel="white")
    model.fit(u, y[::10])
    marks = {}
    timed = clock.timed

    def watching(function):
        inner = timed(function)

        def wrapped(*args, **kwargs):
            out = inner(*args, **kwargs)
            marks["end"] = time.process_time()  # of the run's last evaluation, at the end
            if len(clock.seconds) == 4 and "estimate" not in marks:
                marks["estimate"] = time_left(clock.seconds, clock.expected())
                marks["at"] = marks["end"]
            return out

        return wrapped

    clock.timed = watching
    try:
        model.fit(u, y[::10])
    finally:
        clock.timed = timed
    # the estimate is of the tuning's evaluations still to come
    actual = marks["end"] - marks["at"]
    assert actual / 2 <= marks["estimate"] <= 2 * actual, (marks, actual)
