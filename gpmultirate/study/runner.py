"""Fits and scores of the paper's Monte Carlo study (Section 5), run in parallel.

For every order ``P`` of a grid, a run fits the least-squares FIR model
(eq. 11, only for ``P < M``) and the kernel-regularised models with the DC
and the prior-knowledge kernels (eq. 15-19, hyperparameters tuned by the
marginal likelihood), and scores each by its goodness of fit (eq. 20) on the
noise-free fast-rate validation output.

Run ``i`` of a study uses child ``i`` of ``SeedSequence(random_state)``, so
results depend only on ``random_state``, not on ``n_jobs``, the order in
which runs finish, or (for the system) on ``n_samples``.  Each fit uses one
BLAS thread (threadpoolctl, a scikit-learn dependency): the parallelism is
over runs.
"""

from __future__ import annotations

import math
import numbers
import os
import sys
import time
import warnings

import joblib
import numpy as np
from sklearn.exceptions import ConvergenceWarning

from gpmultirate.estimators import FIRGaussianProcess, LeastSquaresFIR
from gpmultirate.exceptions import (
    IdentifiabilityError,
    MisspecificationWarning,
    NumericalWarning,
    OrderWarning,
)
from gpmultirate.inference import one_blas_thread
from gpmultirate.study.journal import StudyJournal, read_journal, study_settings
from gpmultirate.study.results import StudyResult, TrialResult
from gpmultirate.study.simulation import (
    METHODS,
    PAPER_ORDERS,
    RunData,
    check_config,
    check_methods,
    check_orders,
    child_seed,
    paper_kernels,
    seed_sequence,
    simulate_run,
)
from gpmultirate.validation import check_int

__all__ = [
    "TrialResult",
    "check_n_jobs",
    "fit_and_score",
    "fit_method",
    "format_duration",
    "make_estimator",
    "run_paper_study",
    "run_trial",
    "time_left",
    "unordered_parallel",
]


# ------------------------------------------------------------------ one fit
def make_estimator(method: str, order: int, factor: int, sample_time: float):
    """The unfitted estimator of a study ``method`` at FIR order ``order``.

    ``"LS"`` is :class:`~gpmultirate.LeastSquaresFIR`; ``"DC"`` and ``"PK"``
    are :class:`~gpmultirate.FIRGaussianProcess` with the kernel and noise
    level of :func:`~gpmultirate.study.paper_kernels` and default tuning.

    Examples
    --------
    >>> make_estimator("LS", 10, 3, 0.1)
    LeastSquaresFIR(factor=3, order=10)
    """
    if method == "LS":
        return LeastSquaresFIR(factor=factor, order=order)
    kernel, noise_level = paper_kernels(sample_time)[method]
    return FIRGaussianProcess(kernel, factor=factor, order=order, noise_level=noise_level)


def fit_method(method: str, order: int, data: RunData):
    """Fit one model on a run's data; return ``(model or None, seconds, n_warnings)``.

    Convergence and jitter warnings of the tuning are counted rather than
    printed once per fit; an :class:`~gpmultirate.OrderWarning` and a
    :class:`~gpmultirate.MisspecificationWarning` are dropped (the study
    sweeps the order and compares priors on purpose: what a short order or a
    prior that misses the modes costs is what it measures); any other
    warning is passed on.  BLAS runs on one
    thread during the fit.  The model is None when least squares has no
    unique solution (Lemma 1, 2).

    Examples
    --------
    >>> from gpmultirate.study import simulate_run
    >>> model, seconds, n_warnings = fit_method("LS", 25, simulate_run(0, n_samples=60))
    >>> model is None, n_warnings  # P = 25 >= M = 20
    (True, 0)
    """
    model = make_estimator(method, order, data.factor, data.sample_time)
    start = time.perf_counter()
    # One BLAS thread: the study is parallel over runs, multithreaded BLAS on these small
    # matrices costs far more than it saves, and the result must not depend on n_jobs.
    with one_blas_thread(), \
            warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConvergenceWarning)
        warnings.simplefilter("always", NumericalWarning)
        try:
            model.fit(data.u, data.y_slow)
        except IdentifiabilityError:
            if method != "LS":
                raise
            model = None  # P >= M or a rank-deficient regressor (Lemma 1, 2)
    seconds = time.perf_counter() - start
    counted = (ConvergenceWarning, NumericalWarning)
    for w in caught:
        if not issubclass(w.category, counted + (OrderWarning, MisspecificationWarning)):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return model, seconds, sum(issubclass(w.category, counted) for w in caught)


def fit_and_score(method: str, order: int, data: RunData):
    """Fit one model and score it on the validation data: ``(method, model, gof)``.

    The GoF is NaN (and the model None) where least squares is not identifiable.

    Examples
    --------
    >>> from gpmultirate.study import simulate_run
    >>> data = simulate_run(0, n_samples=60)
    >>> method, model, gof = fit_and_score("LS", 10, data)
    >>> bool(gof == model.score(data.u_val, data.y_val))
    True
    >>> fit_and_score("LS", 25, data)[1:]  # P = 25 >= M = 20
    (None, nan)
    """
    model, _, _ = fit_method(method, order, data)
    return method, model, (math.nan if model is None else model.score(data.u_val, data.y_val))


# ------------------------------------------------------------------ one run
def run_trial(
    seed,
    orders=PAPER_ORDERS,
    methods=METHODS,
    *,
    run: int = 0,
    n_samples: int = 600,
    factor: int = 3,
    sample_time: float = 0.1,
    snr_db=(40.0, 60.0),
    perturbation: float = 0.1,
) -> TrialResult:
    """Fit and score every method at every order on one run's data.

    Parameters
    ----------
    seed : int, SeedSequence or None
        Seed of the run's data, see :func:`~gpmultirate.study.simulate_run`.
    orders : sequence of int, default=PAPER_ORDERS
        FIR orders ``P`` in ``1..n_samples``.
    methods : sequence of {"LS", "DC", "PK"}, default=METHODS
    run : int, default=0
        Index stored in the result.
    n_samples, factor, sample_time, snr_db, perturbation
        As in :func:`~gpmultirate.study.simulate_run`.

    Returns
    -------
    TrialResult

    Examples
    --------
    >>> from gpmultirate.study import run_trial
    >>> trial = run_trial(0, orders=(10, 20), methods=("LS",), n_samples=60)
    >>> trial.identifiable["LS"].tolist()  # M = 20 slow samples
    [True, False]
    """
    config = check_config(n_samples, factor, sample_time, snr_db, perturbation)
    orders = check_orders(orders, config["n_samples"])
    methods = check_methods(methods)
    start = time.perf_counter()
    data = simulate_run(seed, **config)
    shape = orders.shape
    gof = {m: np.full(shape, np.nan) for m in methods}
    identifiable = {m: np.zeros(shape, dtype=bool) for m in methods}
    fit_seconds = {m: np.zeros(shape) for m in methods}
    n_warnings = {m: np.zeros(shape, dtype=int) for m in methods}
    for method in methods:
        for j, order in enumerate(orders):
            model, seconds, n_warn = fit_method(method, int(order), data)
            fit_seconds[method][j], n_warnings[method][j] = seconds, n_warn
            if model is not None:
                identifiable[method][j] = True
                # eq. (20) against the noise-free fast validation output
                gof[method][j] = model.score(data.u_val, data.y_val)
    return TrialResult(run=int(run), gof=gof, identifiable=identifiable,
                       fit_seconds=fit_seconds, n_warnings=n_warnings, snr_db=data.snr_db,
                       seconds=time.perf_counter() - start)


# ----------------------------------------------------------------- progress
def time_left(elapsed: float, done: int, total: int) -> float:
    """Estimated seconds until ``total`` tasks are done, from ``done`` in ``elapsed`` s.

    The tasks finished so far set the rate: ``elapsed / done * (total - done)``.

    Examples
    --------
    >>> time_left(30.0, 3, 10)
    70.0
    """
    if done <= 0:
        return math.inf
    return max(0.0, elapsed / done * (total - done))


def format_duration(seconds: float) -> str:
    """``seconds`` as a short duration: ``"42 s"``, ``"3 min 5 s"``, ``"2 h 10 min"``.

    Examples
    --------
    >>> format_duration(42.4), format_duration(185), format_duration(7800)
    ('42 s', '3 min 5 s', '2 h 10 min')
    """
    if not math.isfinite(seconds):
        return "unknown time"
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds} s"
    if seconds < 3600:
        return f"{seconds // 60} min {seconds % 60} s"
    return f"{seconds // 3600} h {seconds % 3600 // 60} min"


# -------------------------------------------------------------------- study
def check_n_jobs(n_jobs) -> int:
    """Validate a joblib process count: a non-zero integer.

    Examples
    --------
    >>> check_n_jobs(-1)
    -1
    """
    if isinstance(n_jobs, bool) or not isinstance(n_jobs, numbers.Integral) or n_jobs == 0:
        raise ValueError(
            f"n_jobs must be a non-zero integer (negative counts back from all CPUs, "
            f"as in joblib); got {n_jobs!r}"
        )
    return int(n_jobs)


def unordered_parallel(n_jobs: int, tasks):
    """Results of joblib ``tasks`` as they finish (in order on joblib < 1.4).

    Examples
    --------
    >>> import joblib
    >>> sorted(unordered_parallel(1, (joblib.delayed(abs)(-k) for k in range(3))))
    [0, 1, 2]
    """
    try:
        return joblib.Parallel(n_jobs=n_jobs, return_as="generator_unordered")(tasks)
    except (TypeError, ValueError):  # pragma: no cover - joblib < 1.4
        return joblib.Parallel(n_jobs=n_jobs)(tasks)


def run_paper_study(
    n_runs: int = 100,
    orders=PAPER_ORDERS,
    methods=METHODS,
    *,
    n_samples: int = 600,
    factor: int = 3,
    sample_time: float = 0.1,
    snr_db=(40.0, 60.0),
    perturbation: float = 0.1,
    n_jobs: int = 1,
    random_state=0,
    progress: bool = True,
    journal=None,
) -> StudyResult:
    """Run the paper's Monte Carlo study (Section 5) and collect the GoF of every fit.

    Parameters
    ----------
    n_runs : int, default=100
        Monte Carlo runs.
    orders : int or sequence of int, default=(50, 100, ..., 600)
        FIR orders ``P`` in ``1..n_samples`` (sorted in the result); a single
        order, e.g. ``(600,)``, is allowed.
    methods : sequence of {"LS", "DC", "PK"}, default=("LS", "DC", "PK")
        Least squares (eq. 11), and :class:`~gpmultirate.FIRGaussianProcess`
        with the DC or the DC + prior-knowledge kernel of
        :func:`~gpmultirate.study.paper_kernels`.
    n_samples : int, default=600
        Samples ``N`` per multisine; ``M = ceil(N / factor)`` slow samples.
    factor : int, default=3
        Downsampling factor ``F``, in ``1..n_samples``.
    sample_time : float, default=0.1
        Fast sample time ``T`` in seconds, below 0.25 s (see
        :func:`~gpmultirate.study.paper_kernels`).
    snr_db : float or (float, float), default=(40, 60)
        Range of the uniformly drawn training SNR in dB.
    perturbation : float, default=0.1
        Relative range of the system's parameters around nominal.
    n_jobs : int, default=1
        Parallel runs (joblib processes); -1 uses every CPU.
    random_state : int, SeedSequence or None, default=0
        Seed of the study; run ``i`` uses child ``i`` of
        ``SeedSequence(random_state)`` (``SeedSequence(random_state).spawn(n_runs)[i]``).
        With None fresh entropy is drawn and stored in the result.
    progress : bool, default=True
        Print ``run k/n done (about ... left; this run t s)`` to stderr as
        runs finish, the time left estimated from the mean wall time per
        finished run.
    journal : str or path-like, optional
        A file to which each run is appended as it finishes (one JSON line,
        flushed to disk, see :mod:`gpmultirate.study.journal`).  If the file
        exists, it must hold a study with the same settings; its finished
        runs are reused and only the missing ones are run, which gives the
        same result as an uninterrupted study (except for the wall times).
        With ``random_state=None`` the journal's seed is used.

    Returns
    -------
    StudyResult

    Raises
    ------
    gpmultirate.study.journal.JournalError
        If ``journal`` holds a study with other settings, is corrupt, or is
        being written by another process.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.study import run_paper_study
    >>> result = run_paper_study(n_runs=2, orders=(10, 20), methods=("LS",),
    ...                          n_samples=60, progress=False)
    >>> result.gof["LS"].shape, result.n_slow_samples
    ((2, 2), 20)
    >>> bool(np.isnan(result.gof["LS"][:, 1]).all())  # P = 20 >= M: not identifiable
    True
    """
    n_runs = check_int(n_runs, "n_runs", low=1)
    config = check_config(n_samples, factor, sample_time, snr_db, perturbation)
    orders = check_orders(orders, config["n_samples"])
    methods = check_methods(methods)
    n_jobs = check_n_jobs(n_jobs)
    if not isinstance(progress, bool):
        raise ValueError(f"progress must be True or False; got {progress!r}")
    if journal is None:
        root = seed_sequence(random_state)
        return _collect(n_runs, orders, methods, config, n_jobs, root, progress, None)
    if random_state is None and os.path.exists(journal):
        # resume a study seeded from fresh entropy with the seed it drew
        found, _ = read_journal(journal)
        if found is not None:
            random_state = np.random.SeedSequence(found["random_state"],
                                                  spawn_key=tuple(found["spawn_key"]))
    root = seed_sequence(random_state)
    settings = study_settings(n_runs, orders, methods, config, root)
    with StudyJournal.open(journal, settings) as opened:
        return _collect(n_runs, orders, methods, config, n_jobs, root, progress, opened)


def _collect(n_runs, orders, methods, config, n_jobs, root, progress, journal):
    """The runs of :func:`run_paper_study` missing from ``journal``, and the result."""
    trials: list[TrialResult | None] = [None] * n_runs
    if journal is not None:
        for i, trial in journal.trials.items():
            trials[i] = trial
    n_done = sum(t is not None for t in trials)
    if progress and n_done:
        print(f"resuming from {journal.path}: {n_done} of {n_runs} runs done earlier",
              file=sys.stderr, flush=True)

    start = time.perf_counter()
    tasks = (joblib.delayed(run_trial)(child_seed(root, i), orders, methods, run=i, **config)
             for i in range(n_runs) if trials[i] is None)
    results = unordered_parallel(n_jobs, tasks) if n_done < n_runs else iter(())
    try:
        for new, trial in enumerate(results, start=1):
            if journal is not None:
                journal.append(trial)
            trials[trial.run] = trial
            if progress:
                done = n_done + new
                left = time_left(time.perf_counter() - start, new, n_runs - n_done)
                eta = "" if done == n_runs else f"about {format_duration(left)} left; this run "
                print(f"run {done}/{n_runs} done ({eta}{trial.seconds:.1f} s)",
                      file=sys.stderr, flush=True)
    finally:
        if hasattr(results, "close"):
            # stopped early (an interrupt): joblib warns that it cancels the pending
            # runs, which is the point; the finished ones are in the journal
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", message=r".*tasks which were still being "
                                        r"processed", category=UserWarning)
                results.close()

    def stack(name):
        return {m: np.array([getattr(t, name)[m] for t in trials]) for m in methods}

    return StudyResult(
        orders=orders, methods=methods, gof=stack("gof"), identifiable=stack("identifiable"),
        fit_seconds=stack("fit_seconds"), n_warnings=stack("n_warnings"),
        snr_db=np.array([t.snr_db for t in trials]),
        run_seconds=np.array([t.seconds for t in trials]), random_state=int(root.entropy),
        n_samples=config["n_samples"], factor=config["factor"],
        sample_time=config["sample_time"], snr_range=config["snr_db"],
        perturbation=config["perturbation"], total_seconds=time.perf_counter() - start,
    )
