"""A fit that would not fit in memory is refused at once, with an estimate and the remedy."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

import gpmultirate as gm
from gpmultirate.inference import ParameterSpacePosterior, PrecisionPosterior
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


def _peak_of_fit(model, u, y) -> int:
    """The peak of numpy's allocations during ``model.fit(u, y)``, measured by tracemalloc."""
    import tracemalloc

    tracemalloc.start()
    try:
        model.fit(u, y)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.slow
@pytest.mark.parametrize("n, factor, order", [(600, 3, 600), (3000, 3, 300), (1200, 2, 1200)])
@pytest.mark.parametrize("optimizer", [None, "marginal_likelihood"])
def test_the_estimate_is_the_measured_peak(n, factor, order, optimizer):
    # the data space (M <= P), the long-record reduction (M > P) and a larger P
    rng = np.random.default_rng(1)
    u = rng.standard_normal(n)
    y = np.convolve(u, 0.9 ** np.arange(order))[:n:factor]
    y = y + 0.01 * rng.standard_normal(y.shape[0])
    model = gm.FIRGaussianProcess(factor=factor, order=order, optimizer=optimizer)
    peak = _peak_of_fit(model, u, y)
    estimate = fit_memory_estimate(y.shape[0], order, model.kernel_.theta.shape[0] + 1)
    assert peak < 1.5 * estimate
    if y.shape[0] > order:
        # long record: the default DC prior's posterior (and, tuned, its evidence)
        # goes through its tridiagonal precision and needs less than the estimate,
        # which covers the general route
        # (test_the_estimate_covers_the_general_long_record_posterior)
        assert isinstance(model.posterior_, PrecisionPosterior)
        if optimizer is None:
            assert peak < 0.5 * estimate
    else:
        # the estimate covers a kernel without structure, which forms the P x P prior
        # matrix (below); the default DC's data-space posterior never does
        assert 0.25 * estimate < peak


def _general_fit(kernel, n, factor, order, optimizer):
    """A fit of ``kernel`` (no structure the routes use), its measured peak and the estimate."""
    rng = np.random.default_rng(1)
    u = rng.standard_normal(n)
    y = np.convolve(u, 0.9 ** np.arange(order))[:n:factor]
    y = y + 0.01 * rng.standard_normal(y.shape[0])
    model = gm.FIRGaussianProcess(kernel, factor=factor, order=order, optimizer=optimizer)
    peak = _peak_of_fit(model, u, y)
    return model, y, peak, fit_memory_estimate(y.shape[0], order,
                                               model.kernel_.theta.shape[0] + 1)


@pytest.mark.slow
@pytest.mark.parametrize("optimizer", [None, "marginal_likelihood"])
def test_the_estimate_is_the_measured_peak_of_a_kernel_without_structure(optimizer):
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel

    _, _, peak, estimate = _general_fit(ConstantKernel(1.0) * RBF(20.0), 1200, 2, 1200,
                                        optimizer)
    assert 0.5 * estimate < peak < 1.5 * estimate


@pytest.mark.slow
@pytest.mark.parametrize("optimizer", [None, "marginal_likelihood"])
def test_the_estimate_covers_the_general_long_record_posterior(optimizer):
    # a prior without a tridiagonal precision: the eigendecomposition and QR route
    from sklearn.gaussian_process.kernels import ConstantKernel

    from gpmultirate.kernels import TC

    model, y, peak, estimate = _general_fit(ConstantKernel(1.0) * TC(), 3000, 3, 300,
                                            optimizer)
    assert isinstance(model.posterior_, ParameterSpacePosterior)
    # untuned, the checks after the fit (the M x M covariance and its factor) do not run
    lower = estimate - (0 if optimizer else 8 * 2 * y.shape[0] ** 2)
    assert 0.5 * lower < peak < 1.5 * estimate


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


@pytest.mark.slow
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
