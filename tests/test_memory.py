"""A fit that would not fit in memory is refused at once, with an estimate and the remedy."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

import gpmultirate as gm
from gpmultirate.memory import (
    LIMIT_VARIABLE,
    MemoryLimitError,
    available_memory,
    fit_memory_estimate,
)


@pytest.fixture
def problem():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(600)
    y = np.convolve(u, 0.9 ** np.arange(600))[:600:3] + 0.01 * rng.standard_normal(200)
    return u, y


def test_the_estimate_counts_the_matrices_of_the_data_and_parameter_spaces():
    # M <= P: data space (4 + n_theta) M^2, posterior 2 P^2 + 3 M P
    assert fit_memory_estimate(200, 600, 4) == 8 * (8 * 200**2 + 2 * 600**2 + 3 * 200 * 600)
    # M > P: the data reduce to P x P, plus the factor built block by block
    assert fit_memory_estimate(5000, 300, 3) == 8 * (7 * 300**2 + 2 * 300**2 + 3 * 300**2
                                                      + 3 * 300**2)


def test_the_limit_comes_from_the_environment(monkeypatch):
    monkeypatch.setenv(LIMIT_VARIABLE, "12345")
    assert available_memory() == 12345
    monkeypatch.setenv(LIMIT_VARIABLE, "lots")
    with pytest.raises(ValueError, match=LIMIT_VARIABLE):
        available_memory()
    monkeypatch.delenv(LIMIT_VARIABLE)
    assert available_memory() > 10**8


@pytest.mark.parametrize("estimator", [gm.FIRGaussianProcess(factor=3, order=600),
                                       gm.LeastSquaresFIR(factor=3, order=150)])
def test_a_fit_over_the_limit_fails_up_front(problem, estimator, monkeypatch):
    u, y = problem
    monkeypatch.setenv(LIMIT_VARIABLE, str(10**6))  # 1 MB
    with pytest.raises(MemoryLimitError, match="GB .* available: use a smaller order"):
        estimator.fit(u, y)
    monkeypatch.setenv(LIMIT_VARIABLE, str(10**10))
    estimator.fit(u, y)  # the same fit within the limit


def test_the_refusal_comes_before_the_allocation():
    # a process limited to 300 MB of address space fits the paper's size, and is
    # refused (not killed) for an order whose matrices need terabytes
    code = textwrap.dedent(f"""
        import resource, numpy as np, gpmultirate as gm
        from gpmultirate.memory import MemoryLimitError
        resource.setrlimit(resource.RLIMIT_AS, (2 * 10**9, 2 * 10**9))
        import os; os.environ["{LIMIT_VARIABLE}"] = str(3 * 10**8)
        rng = np.random.default_rng(0)
        u = rng.standard_normal(2 * 10**5)
        try:
            gm.FIRGaussianProcess(factor=10, order=10**5, optimizer=None).fit(u, u[::10])
        except MemoryLimitError as error:
            print("refused:", error)
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "refused: the fit needs about" in done.stdout
