"""Fitted models are safe to share: concurrent use gives the serial answers, bit for bit.

A fitted :class:`~gpmultirate.FIRGaussianProcess` (DC kernel, tuned) and a
:class:`~gpmultirate.LeastSquaresFIR` are queried from 8 threads at once
(``predict(u, return_std=True)``, ``impulse_response`` with
``return_std=True`` at non-integer lags for the Gaussian process and at
integer lags for least squares, ``frequency_response(level=0.9)``, each several
times; a barrier makes the threads start together).  Every answer must equal
the serial one exactly (``assert_array_equal``): prediction must not change
the model, and no cache filled lazily by one thread may be seen half-written
by another.

Models written with :func:`~gpmultirate.save_model` and read back with
:func:`~gpmultirate.load_model` in fresh processes (spawn context, so nothing
is inherited from this process but the file) must answer exactly as the
parent's loaded model does.

BLAS may use several threads inside one call; the serial reference is
computed under the same thread settings, so the comparison is exact.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import threading
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

import numpy as np
import pytest

from gpmultirate import FIRGaussianProcess, LeastSquaresFIR, load_model, save_model
from gpmultirate import simulation as sim
from gpmultirate.kernels import DC

N, FACTOR, ORDER, T = 300, 3, 150, 0.1
LS_ORDER = 60  # below M = N / FACTOR = 100 slow samples
N_THREADS = 8
REPEATS = 3
LEVEL = 0.9
LAGS = np.array([0.0, 0.25, 1.5, 7.75, 20.3, 64.5, 99.9, 148.6])  # continuous lag (GP)
LS_LAGS = np.array([0, 1, 2, 7, 20, 59])  # a least-squares FIR has integer lags only


def experiment():
    system = sim.paper_system(T)
    u = sim.multisine(N, sample_time=T, random_state=0)
    data = sim.simulate_experiment(system, u, FACTOR, snr_db=50.0, random_state=1)
    u_new = sim.multisine(N, sample_time=T, random_state=2)
    return data, u_new


@pytest.fixture(scope="module")
def problem():
    return experiment()


@pytest.fixture(scope="module")
def gp(problem):
    data, _ = problem
    return FIRGaussianProcess(DC(), factor=FACTOR, order=ORDER, sample_time=T).fit(
        data.u, data.y_slow)


@pytest.fixture(scope="module")
def ls(problem):
    data, _ = problem
    return LeastSquaresFIR(factor=FACTOR, order=LS_ORDER).fit(data.u, data.y_slow)


def answers(model, u):
    """Everything a user may ask a fitted model, as plain arrays."""
    out = {}
    out["predict"] = model.predict(u, return_std=True)
    lags = LAGS if isinstance(model, FIRGaussianProcess) else LS_LAGS
    out["impulse_response"] = model.impulse_response(lags, return_std=True)
    out["frequency_response"] = frequency_response_arrays(model.frequency_response(level=LEVEL))
    return out


def frequency_response_arrays(frf):
    return {f.name: getattr(frf, f.name) for f in dataclasses.fields(frf)}


def assert_same(actual, expected, where=""):
    if isinstance(expected, dict):
        assert actual.keys() == expected.keys(), where
        for key in expected:
            assert_same(actual[key], expected[key], f"{where}.{key}")
    elif isinstance(expected, tuple):
        assert isinstance(actual, tuple) and len(actual) == len(expected), where
        for i, (a, e) in enumerate(zip(actual, expected)):
            assert_same(a, e, f"{where}[{i}]")
    elif isinstance(expected, np.ndarray) or isinstance(actual, np.ndarray):
        np.testing.assert_array_equal(actual, expected, err_msg=where, strict=True)
    else:
        assert actual == expected, where


def state(model):
    """The fitted attributes that prediction must leave untouched."""
    return {k: (v.copy() if isinstance(v, np.ndarray) else v)
            for k, v in vars(model).items() if k.endswith("_") and not k.startswith("_")
            and isinstance(v, (np.ndarray, float, int, str))}


# ------------------------------------------------------------------ threads
@pytest.mark.slow
@pytest.mark.parametrize("name", ["gp", "ls"])
def test_threads_sharing_a_fitted_model_get_the_serial_answers(name, problem, request):
    _, u_new = problem
    model = request.getfixturevalue(name)
    before = state(model)
    expected = answers(model, u_new)
    barrier = threading.Barrier(N_THREADS)

    def work(_):
        barrier.wait(timeout=60)  # all threads start their queries together
        return [answers(model, u_new) for _ in range(REPEATS)]

    with ThreadPoolExecutor(N_THREADS) as pool:
        results = list(pool.map(work, range(N_THREADS)))

    assert len(results) == N_THREADS
    for t, runs in enumerate(results):
        for r, got in enumerate(runs):
            assert_same(got, expected, f"thread {t} repeat {r}")
    assert_same(state(model), before, "fitted state")
    assert_same(answers(model, u_new), expected, "serial after threads")


def test_threads_with_a_freshly_loaded_model_fill_its_caches_consistently(gp, problem, tmp_path):
    # A loaded model has computed nothing yet: the first queries race to fill
    # whatever the model computes on first use.
    _, u_new = problem
    path = tmp_path / "gp.npz"
    save_model(gp, path)
    expected = answers(load_model(path), u_new)
    fresh = load_model(path)
    barrier = threading.Barrier(N_THREADS)

    def work(_):
        barrier.wait(timeout=60)
        return answers(fresh, u_new)

    with ThreadPoolExecutor(N_THREADS) as pool:
        results = list(pool.map(work, range(N_THREADS)))
    for t, got in enumerate(results):
        assert_same(got, expected, f"thread {t}")


# ---------------------------------------------------------------- processes
def answers_of_saved_model(path: str):
    """Worker of the process pool: load ``path`` and answer on the test input."""
    _, u_new = experiment()
    return answers(load_model(path), u_new)


@pytest.mark.slow
def test_processes_loading_a_saved_model_get_the_parents_answers(gp, ls, problem, tmp_path):
    _, u_new = problem
    paths = []
    for name, model in (("gp", gp), ("ls", ls)):
        path = tmp_path / f"{name}.npz"
        save_model(model, path)
        paths.append(str(path))
    expected = [answers(load_model(p), u_new) for p in paths]
    # the loaded model answers as the one that was saved
    assert_same(expected[0]["predict"], gp.predict(u_new, return_std=True), "gp loaded")
    assert_same(expected[1]["predict"], ls.predict(u_new, return_std=True), "ls loaded")

    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(2, mp_context=context) as pool:
        results = list(pool.map(answers_of_saved_model, paths))
    for path, got, want in zip(paths, results, expected):
        assert_same(got, want, f"spawned process loading {path}")
