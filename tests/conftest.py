"""Shared test settings: one BLAS thread per test process.

The suite runs many small factorizations.  Threaded BLAS gains nothing on
them and, on a machine with other work (or with ``pytest -n`` workers side
by side), spins against it: a 400 x 400 ``eigh`` took 2-4 s on two threads
of a busy 2-core machine and 0.05 s on one.  Child processes started by the
tests inherit the same limit through the environment.  Tests that exercise
the library's own thread choice set their limits explicitly.
"""
import os

import pytest
from threadpoolctl import threadpool_limits

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")


@pytest.fixture(autouse=True, scope="session")
def _one_blas_thread():
    with threadpool_limits(limits=1, user_api="blas"):
        yield
