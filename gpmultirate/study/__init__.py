"""The paper's Monte Carlo simulation study (Section 5) and its examples.

* :mod:`gpmultirate.study.simulation`: the data of one run
  (:func:`simulate_run`), the paper's kernels (:func:`paper_kernels`), the
  settings checks and the seeding.
* :mod:`gpmultirate.study.runner`: the fits and scores of a run
  (:func:`run_trial`) and of a whole study, in parallel
  (:func:`run_paper_study`).
* :mod:`gpmultirate.study.results`: :class:`StudyResult` with its tables,
  CSV and JSON, and :class:`GoFSummary`, the statistics of Fig. 5.
* :mod:`gpmultirate.study.examples`: one run's fitted models for Fig. 6
  (:func:`paper_example`) and the non-identifiable models of Example 1
  (:func:`nonidentifiable_example`, Fig. 2).

Random numbers come from :class:`numpy.random.SeedSequence`: run ``i`` of a
study uses child ``i`` of ``SeedSequence(random_state)``, and within a run the
system, the two inputs and the noise each have their own stream, so results
depend only on ``random_state``, not on ``n_jobs``, the order in which runs
finish, or (for the system) on ``n_samples``.

Examples
--------
>>> from gpmultirate.study import run_paper_study
>>> result = run_paper_study(n_runs=2, orders=(5, 10), methods=("LS",), n_samples=60,
...                          progress=False)
>>> result.n_runs, result.orders.tolist(), result.n_slow_samples
(2, [5, 10], 20)
"""

from gpmultirate.study.examples import (
    NonidentifiableExample,
    PaperExample,
    nonidentifiable_example,
    paper_example,
)
from gpmultirate.study.results import GoFSummary, StudyResult, TrialResult
from gpmultirate.study.runner import run_paper_study, run_trial
from gpmultirate.study.simulation import (
    METHODS,
    PAPER_NOISE_LEVEL,
    PAPER_ORDERS,
    RunData,
    paper_kernels,
    simulate_run,
)

__all__ = [
    "METHODS",
    "PAPER_NOISE_LEVEL",
    "PAPER_ORDERS",
    "GoFSummary",
    "NonidentifiableExample",
    "PaperExample",
    "RunData",
    "StudyResult",
    "TrialResult",
    "nonidentifiable_example",
    "paper_example",
    "paper_kernels",
    "run_paper_study",
    "run_trial",
    "simulate_run",
]
