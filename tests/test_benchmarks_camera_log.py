"""The camera-log benchmark's reading of the progress lines (``benchmarks/camera_log.py``)."""

import importlib.util
import sys
from pathlib import Path

import pytest

PATH = Path(__file__).resolve().parent.parent / "benchmarks" / "camera_log.py"
spec = importlib.util.spec_from_file_location("benchmark_camera_log", PATH)
benchmark = importlib.util.module_from_spec(spec)
sys.modules[spec.name] = benchmark
spec.loader.exec_module(benchmark)

# a pilot ending at 10 s, then a run from 10 s to 50 s with two time-left lines, the fit's
# end at 50 s, and a line of the steps after it
STDERR = "\n".join([
    "gpmultirate fit: [   2.0 s] still on fit (2 s); tuning: 1 evaluation(s) of the evidence, "
    "1 s each, about 6 s left",
    "gpmultirate fit: [  10.0 s] default order: fitted order 512 in 10.0 s, the prior has "
    "not decayed by lag 512: next order 1024, about 40 s left",
    "gpmultirate fit: [  20.0 s] still on fit (20 s); tuning: 4 evaluation(s) of the "
    "evidence, 2.5 s each, about 60 s left",
    "gpmultirate fit: [  45.0 s] still on fit (45 s); tuning: 14 evaluation(s) of the "
    "evidence, 2.5 s each, about 10 s left",
    "gpmultirate fit: [  50.0 s] fit: 50.0 s",
    "gpmultirate fit: [  55.0 s] still on state space (5 s)",
])


def test_time_left_against_the_rest_of_its_run():
    # 20 s: 60 announced, 30 left (to 50 s); 45 s: 5 left, under 10 s: not counted;
    # 2 s: 6 announced, 8 left, under 10 s
    assert benchmark.estimate_ratios(STDERR) == pytest.approx([2.0])
    assert benchmark.estimate_ratios(STDERR, shortest=0.0) == pytest.approx(
        [6 / 8, 2.0, 10 / 5])


def test_run_time_against_the_time_its_run_took():
    # the run of a line starts at the last pilot's end: (2 + 6) / 10, (10 + 60) / 40,
    # (35 + 10) / 40
    assert benchmark.run_time_ratios(STDERR) == pytest.approx([0.8, 70 / 40, 45 / 40])


def test_each_command_reports_its_own_peak_memory():
    # the benchmark's children's ru_maxrss is the largest of every command so far; each
    # command prints its own peak instead: a command holding 200 MB more reports about that
    # much more, and the one after it its own again
    import subprocess

    def peak(prelude=""):
        done = subprocess.run([sys.executable, "-c", prelude + benchmark._OWN_PEAK, "--help"],
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 0
        return int(done.stderr.strip().splitlines()[-1].split()[-1]) / 1024

    small = peak()
    large = peak("import numpy\nheld = numpy.ones(25_000_000)\n")
    assert 0 < small < 1000
    assert large > small + 150
    assert peak() < large - 150
