"""A study and a many-output fit on a real Dask cluster give the local numbers.

Under ``joblib.parallel_config(backend="dask")`` the joblib tasks of
:func:`~gpmultirate.study.run_paper_study` and of
:class:`~gpmultirate.MultiOutputFIR` run on the workers of a
``distributed.LocalCluster`` (two worker processes, one thread each).  The
results must equal those of the local run with the same seeds exactly, and
the tasks must have run on the workers: the scheduler's task stream and the
workers' own counters of executed tasks both see them.

Needs the ``distributed`` extra (``pip install ".[test,distributed]"``);
skipped without it.  Slow because a cluster of two processes takes a few
seconds to start.
"""

import joblib
import numpy as np
import pytest

import gpmultirate as gm
from gpmultirate.study import run_paper_study

distributed = pytest.importorskip("distributed")

pytestmark = pytest.mark.slow

STUDY = dict(n_runs=4, orders=(10, 20), methods=("LS", "DC"), n_samples=60, random_state=7,
             progress=False)


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as client:
        yield client


def executed(client) -> dict:
    """Tasks each worker has executed so far, counted by the worker itself."""
    return client.run(lambda dask_worker: dask_worker.state.executed_count)


def on_cluster(client, function):
    """``function()`` under the Dask backend, with the tasks the workers ran for it."""
    before = executed(client)
    with distributed.get_task_stream(client) as stream, \
            joblib.parallel_config(backend="dask"):
        result = function()
    after = executed(client)
    ran = {worker: after[worker] - before.get(worker, 0) for worker in after}
    return result, stream.data, ran


def assert_ran_on_workers(client, stream, ran):
    # the workers as the client reaches them (the scheduler's summary of workers can be
    # empty for a moment after a run)
    workers = set(client.run(lambda: None))
    assert len(stream) >= 2 and {task["worker"] for task in stream} <= workers
    assert sum(ran.values()) == len(stream)  # the workers saw what the scheduler logged


def test_study_on_the_cluster_equals_the_local_run(client):
    local = run_paper_study(n_jobs=1, **STUDY)
    remote, stream, ran = on_cluster(client, lambda: run_paper_study(n_jobs=-1, **STUDY))
    assert_ran_on_workers(client, stream, ran)
    for method in STUDY["methods"]:
        np.testing.assert_array_equal(remote.gof[method], local.gof[method])
        np.testing.assert_array_equal(remote.identifiable[method], local.identifiable[method])
        np.testing.assert_array_equal(remote.n_warnings[method], local.n_warnings[method])
    np.testing.assert_array_equal(remote.snr_db, local.snr_db)
    assert np.isnan(remote.gof["LS"][:, 1]).all()  # P = 20 = M: not identifiable
    assert np.isfinite(remote.gof["DC"]).all()


def test_many_output_fit_on_the_cluster_equals_the_local_fit(client):
    rng = np.random.default_rng(3)
    u = rng.standard_normal((150, 2))
    lags = np.arange(30)
    y = np.column_stack([
        np.convolve(u[:, 0], a**lags)[:150] - np.convolve(u[:, 1], b**lags)[:150]
        for a, b in ((0.5, 0.8), (0.7, 0.6), (0.9, 0.3), (0.6, 0.6))
    ])
    y_slow = y[::3] + 1e-3 * rng.standard_normal((50, 4))
    y_slow[10, 2] = np.nan
    estimator = gm.FIRGaussianProcess(factor=3, order=30)
    local = gm.MultiOutputFIR(estimator).fit(u, y_slow)
    remote, stream, ran = on_cluster(client, lambda: gm.MultiOutputFIR(estimator).fit(u, y_slow))
    assert_ran_on_workers(client, stream, ran)
    np.testing.assert_array_equal(remote.coef_, local.coef_)
    for a, b in zip(remote.estimators_, local.estimators_):
        np.testing.assert_array_equal(a.kernel_.theta, b.kernel_.theta)
        assert a.noise_level_ == b.noise_level_
    np.testing.assert_array_equal(remote.predict(u), local.predict(u))
