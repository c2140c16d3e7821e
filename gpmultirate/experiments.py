"""The paper's Monte Carlo simulation study (Section 5) and its example run (Fig. 5-6).

Every run draws a two-mass-spring-damper system with each parameter within
+-10 % of nominal, independent random-phase multisines of ``N`` samples for
training and validation, and white noise on the training output at a
signal-to-noise ratio drawn uniformly in [40, 60] dB; the slow output is
every ``F``-th noisy fast sample (eq. 3).  For every order ``P`` of a grid it
fits the least-squares FIR model (eq. 11, only for ``P < M``) and the
kernel-regularised models with the DC and the prior-knowledge kernels
(eq. 15-19, hyperparameters tuned by the marginal likelihood), and scores
each by its goodness of fit (eq. 20) on the noise-free fast-rate validation
output.

* :func:`paper_kernels`: the DC and PK priors with the paper's initial values.
* :func:`simulate_run`, :func:`run_trial`: the data and the fits of one run.
* :func:`run_paper_study`: all runs, in parallel, as a :class:`StudyResult`.
* :func:`paper_example`: one run's fitted models for the Bode, impulse-response
  and intersample figures.

Random numbers come from :class:`numpy.random.SeedSequence`: run ``i`` of a
study uses child ``i`` of ``SeedSequence(random_state)``, and within a run the
system, the two inputs and the noise each have their own stream, so results
depend only on ``random_state``, not on ``n_jobs``, the order in which runs
finish, or (for the system) on ``n_samples``.  Each fit uses one BLAS thread
(threadpoolctl, a scikit-learn dependency): the parallelism is over runs.
"""

from __future__ import annotations

import csv
import json
import math
import numbers
import sys
import time
import warnings
from dataclasses import dataclass

import joblib
import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process.kernels import ConstantKernel, Kernel
from threadpoolctl import threadpool_limits

from gpmultirate.validation import check_int, check_positive
from gpmultirate.estimators import FIRGaussianProcess, LeastSquaresFIR
from gpmultirate.exceptions import IdentifiabilityError, NumericalWarning
from gpmultirate.kernels import DC, PK
from gpmultirate.simulation import DiscreteSystem, multisine, paper_system, simulate_experiment

__all__ = [
    "METHODS",
    "PAPER_ORDERS",
    "PaperExample",
    "RunData",
    "StudyResult",
    "TrialResult",
    "paper_example",
    "paper_kernels",
    "run_paper_study",
    "run_trial",
    "simulate_run",
]

#: Estimators of the study: least squares (eq. 11), DC kernel, DC + two PK kernels.
METHODS = ("LS", "DC", "PK")
#: The paper's grid of FIR orders, ``P = 50, 100, ..., N = 600``.
PAPER_ORDERS = tuple(range(50, 601, 50))
#: The paper's regularisation parameter ``gamma`` (initial noise variance).
PAPER_NOISE_LEVEL = 1e-5
# resonances of the paper's prior-knowledge kernel, in Hz
_PK_FREQUENCIES = (0.4, 2.0)
_STUDY_FORMAT = "gpmultirate-study"
# per-method arrays of a StudyResult and their dtypes
_PER_RUN_FIELDS = {"gof": float, "identifiable": bool, "fit_seconds": float, "n_warnings": int}


# ------------------------------------------------------------------ kernels
def paper_kernels(sample_time: float = 0.1) -> dict[str, tuple[Kernel, float]]:
    """The DC and prior-knowledge kernels of the simulation example, with ``gamma``.

    ``"DC"`` is ``lambda * DC(alpha, beta)`` (eq. 16) and ``"PK"`` adds one
    prior-knowledge kernel (eq. 18-19) per resonance at 0.4 and 2 Hz
    (eq. 21), with the paper's values ``lambda = 1``,
    ``alpha = alpha_n = exp(-0.5 T)``, ``beta = exp(-0.1 T)``,
    ``sigma_1n = sigma_2n = 1`` and ``gamma = 1e-5``.  These are the starting
    point of the estimator's marginal-likelihood tuning, which adjusts all of
    them (the paper tunes ``gamma``, ``omega_n`` and ``alpha_n``).

    Parameters
    ----------
    sample_time : float, default=0.1
        Fast sample time ``T`` in seconds, below 0.25 s so that the 2 Hz
        resonance lies below the fast Nyquist frequency.

    Returns
    -------
    dict
        ``{"DC": (kernel, noise_level), "PK": (kernel, noise_level)}``.

    Examples
    --------
    >>> from gpmultirate.experiments import paper_kernels
    >>> kernels = paper_kernels(0.1)
    >>> sorted(kernels), kernels["PK"][1]
    (['DC', 'PK'], 1e-05)
    >>> kernels["PK"][0].k2.frequency_hz(0.1)  # the 2 Hz resonance
    2.0
    """
    sample_time = check_positive(sample_time, "sample_time")
    if max(_PK_FREQUENCIES) >= 0.5 / sample_time:
        raise ValueError(
            f"sample_time must be below {0.5 / max(_PK_FREQUENCIES):g} s so that the "
            f"{max(_PK_FREQUENCIES):g} Hz resonance lies below the fast Nyquist frequency; "
            f"got {sample_time!r}"
        )
    alpha = math.exp(-0.5 * sample_time)
    beta = math.exp(-0.1 * sample_time)
    # the amplitude may vanish: when the resonances explain the data, the DC
    # term of the PK kernel switches off instead of pressing on a bound
    dc = ConstantKernel(1.0, (1e-12, 1e5)) * DC(alpha=alpha, beta=beta)
    pk = dc
    for frequency in _PK_FREQUENCIES:  # eq. (21): k_DC + sum_n k_pk,n
        pk = pk + PK.from_hz(frequency, sample_time, alpha=alpha, sigma1=1.0, sigma2=1.0)
    return {"DC": (dc, PAPER_NOISE_LEVEL), "PK": (pk, PAPER_NOISE_LEVEL)}


# --------------------------------------------------------------- validation
def _check_methods(methods) -> tuple[str, ...]:
    if isinstance(methods, str):
        methods = (methods,)
    try:
        methods = tuple(methods)
    except TypeError as exc:
        raise ValueError(f"methods must be a sequence of names from {METHODS}") from exc
    if not methods:
        raise ValueError(f"methods must name at least one of {METHODS}")
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise ValueError(f"methods must be names from {METHODS}; got unknown {unknown}")
    if len(set(methods)) != len(methods):
        raise ValueError(f"methods must not repeat a name; got {methods}")
    return methods


def _check_orders(orders, n_samples: int, name: str = "orders") -> np.ndarray:
    if isinstance(orders, numbers.Integral) and not isinstance(orders, bool):
        orders = (orders,)
    try:
        items = list(orders)
    except TypeError as exc:
        raise ValueError(f"{name} must be a sequence of integers; got {orders!r}") from exc
    if not items:
        raise ValueError(f"{name} must contain at least one order")
    if any(isinstance(p, bool) or not isinstance(p, numbers.Integral) for p in items):
        raise ValueError(f"{name} must be integers; got {items!r}")
    values = np.array(items, dtype=int)
    if values.min() < 1 or values.max() > n_samples:
        raise ValueError(
            f"{name} must lie in 1..n_samples = 1..{n_samples}; got {values.tolist()}"
        )
    if np.unique(values).size != values.size:
        raise ValueError(f"{name} must not repeat a value; got {values.tolist()}")
    return np.sort(values)


def _check_snr(snr_db) -> tuple[float, float]:
    if isinstance(snr_db, numbers.Real) and not isinstance(snr_db, bool):
        snr_db = (snr_db, snr_db)
    try:
        low, high = (float(v) for v in snr_db)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"snr_db must be a number or a pair (low, high) in dB; got {snr_db!r}"
        ) from exc
    if not (np.isfinite(low) and np.isfinite(high) and low <= high):
        raise ValueError(f"snr_db must be finite with low <= high; got {snr_db!r}")
    return low, high


def _check_perturbation(perturbation) -> float:
    if isinstance(perturbation, bool) or not isinstance(perturbation, numbers.Real) \
            or not 0 <= perturbation < 1:
        raise ValueError(f"perturbation must lie in [0, 1); got {perturbation!r}")
    return float(perturbation)


def _check_config(n_samples, factor, sample_time, snr_db, perturbation) -> dict:
    """The validated settings shared by a run, a study and the example."""
    n_samples = check_int(n_samples, "n_samples", low=3)
    factor = check_int(factor, "factor", low=1, high=n_samples)
    paper_kernels(sample_time)  # validates sample_time
    return {
        "n_samples": n_samples,
        "factor": factor,
        "sample_time": float(sample_time),
        "snr_db": _check_snr(snr_db),
        "perturbation": _check_perturbation(perturbation),
    }


def _seed_sequence(seed) -> np.random.SeedSequence:
    if isinstance(seed, np.random.SeedSequence):
        return seed
    if seed is None or (isinstance(seed, numbers.Integral) and not isinstance(seed, bool)
                        and seed >= 0):
        return np.random.SeedSequence(seed)
    raise ValueError(
        f"random_state must be None, a non-negative integer or a SeedSequence; got {seed!r}"
    )


def _child(seed: np.random.SeedSequence, index: int) -> np.random.SeedSequence:
    """Child ``index`` of ``seed`` as ``seed.spawn`` makes it, without advancing ``seed``.

    ``spawn`` counts the children already made, so that spawning twice from
    one object gives different children; a study must give the same runs
    every time it is given the same seed object.
    """
    return np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, index),
                                  pool_size=seed.pool_size)


def _rng(seed: np.random.SeedSequence, index: int) -> np.random.Generator:
    return np.random.default_rng(_child(seed, index))


# ---------------------------------------------------------------- one run
@dataclass
class RunData:
    """Training and validation data of one Monte Carlo run, see :func:`simulate_run`.

    Attributes
    ----------
    system : DiscreteSystem
        The perturbed fast-rate system ``G_0``.
    u, u_val : ndarray of shape (N,)
        Training and validation multisines (unit RMS).
    y_fast : ndarray of shape (N,)
        Noise-free fast training output ``y_h``.
    y_fast_noisy : ndarray of shape (N,)
        ``y_h + e_h``.
    y_slow : ndarray of shape (M,)
        ``(y_h + e_h)[0::F]``, the only output the estimators see.
    y_val : ndarray of shape (N,)
        Noise-free fast validation output, the reference of the GoF.
    snr_db : float
        Drawn signal-to-noise ratio of the training output, in dB.
    noise_std : float
        Standard deviation of ``e_h``.
    factor : int
    sample_time : float
    """

    system: DiscreteSystem
    u: np.ndarray
    y_fast: np.ndarray
    y_fast_noisy: np.ndarray
    y_slow: np.ndarray
    u_val: np.ndarray
    y_val: np.ndarray
    snr_db: float
    noise_std: float
    factor: int
    sample_time: float


def simulate_run(
    seed=None,
    *,
    n_samples: int = 600,
    factor: int = 3,
    sample_time: float = 0.1,
    snr_db=(40.0, 60.0),
    perturbation: float = 0.1,
) -> RunData:
    """Draw the system and the data of one Monte Carlo run (Section 5.1).

    Parameters
    ----------
    seed : int, SeedSequence or None
        The run's seed; :func:`run_paper_study` passes child ``i`` of
        ``SeedSequence(random_state)`` to run ``i``.  The system, the training
        input, the validation input and the noise (with the SNR) use the
        independent children 0, 1, 2 and 3 of it.
    n_samples : int, default=600
        Samples ``N`` of each multisine (one period, all bins excited).
    factor : int, default=3
        Downsampling factor ``F``.
    sample_time : float, default=0.1
        Fast sample time ``T`` in seconds.
    snr_db : float or (float, float), default=(40, 60)
        Range of the uniformly drawn SNR ``var(y_h) / var(e_h)`` in dB.
    perturbation : float, default=0.1
        Relative range of the system's parameters around nominal.

    Returns
    -------
    RunData

    Examples
    --------
    >>> from gpmultirate.experiments import simulate_run
    >>> data = simulate_run(0, n_samples=60)
    >>> data.u.shape, data.y_slow.shape, 40 <= data.snr_db <= 60
    ((60,), (20,), True)
    """
    config = _check_config(n_samples, factor, sample_time, snr_db, perturbation)
    seed = _seed_sequence(seed)
    n, t = config["n_samples"], config["sample_time"]
    system = paper_system(t, config["perturbation"], random_state=_rng(seed, 0))
    u = multisine(n, t, random_state=_rng(seed, 1))
    u_val = multisine(n, t, random_state=_rng(seed, 2))
    noise = _rng(seed, 3)
    snr = float(noise.uniform(*config["snr_db"]))
    train = simulate_experiment(system, u, config["factor"], snr_db=snr, random_state=noise)
    return RunData(system=system, u=u, y_fast=train.y_fast, y_fast_noisy=train.y_fast_noisy,
                   y_slow=train.y_slow, u_val=u_val, y_val=system.simulate(u_val), snr_db=snr,
                   noise_std=train.noise_std, factor=config["factor"], sample_time=t)


def _estimator(method: str, order: int, factor: int, sample_time: float):
    if method == "LS":
        return LeastSquaresFIR(factor=factor, order=order)
    kernel, noise_level = paper_kernels(sample_time)[method]
    return FIRGaussianProcess(kernel, factor=factor, order=order, noise_level=noise_level)


def _fit(method: str, order: int, data: RunData):
    """Fit one model; return ``(model or None, seconds, n_warnings)``.

    Convergence and jitter warnings of the tuning are counted rather than
    printed once per fit; any other warning is passed on.  BLAS runs on one
    thread during the fit.
    """
    model = _estimator(method, order, data.factor, data.sample_time)
    start = time.perf_counter()
    # One BLAS thread: the study is parallel over runs, multithreaded BLAS on these small
    # matrices costs far more than it saves, and the result must not depend on n_jobs.
    with threadpool_limits(limits=1, user_api="blas"), \
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
        if not issubclass(w.category, counted):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return model, seconds, sum(issubclass(w.category, counted) for w in caught)


@dataclass
class TrialResult:
    """Scores of one Monte Carlo run, see :func:`run_trial`.

    Attributes
    ----------
    run : int
        Index of the run in its study.
    gof : dict of str to ndarray of shape (n_orders,)
        Validation goodness of fit in percent per method; NaN where the
        model does not exist (least squares with ``P >= M``).
    identifiable : dict of str to bool ndarray of shape (n_orders,)
    fit_seconds : dict of str to ndarray of shape (n_orders,)
        Wall time of each ``fit``.
    n_warnings : dict of str to int ndarray of shape (n_orders,)
        Convergence or jitter warnings raised by each fit.
    snr_db : float
        The run's training SNR.
    seconds : float
        Wall time of the whole run.
    """

    run: int
    gof: dict
    identifiable: dict
    fit_seconds: dict
    n_warnings: dict
    snr_db: float
    seconds: float


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
        Seed of the run's data, see :func:`simulate_run`.
    orders : sequence of int, default=PAPER_ORDERS
        FIR orders ``P`` in ``1..n_samples``.
    methods : sequence of {"LS", "DC", "PK"}, default=METHODS
    run : int, default=0
        Index stored in the result.
    n_samples, factor, sample_time, snr_db, perturbation
        As in :func:`simulate_run`.

    Returns
    -------
    TrialResult

    Examples
    --------
    >>> from gpmultirate.experiments import run_trial
    >>> trial = run_trial(0, orders=(10, 20), methods=("LS",), n_samples=60)
    >>> trial.identifiable["LS"].tolist()  # M = 20 slow samples
    [True, False]
    """
    config = _check_config(n_samples, factor, sample_time, snr_db, perturbation)
    orders = _check_orders(orders, config["n_samples"])
    methods = _check_methods(methods)
    start = time.perf_counter()
    data = simulate_run(seed, **config)
    shape = orders.shape
    gof = {m: np.full(shape, np.nan) for m in methods}
    identifiable = {m: np.zeros(shape, dtype=bool) for m in methods}
    fit_seconds = {m: np.zeros(shape) for m in methods}
    n_warnings = {m: np.zeros(shape, dtype=int) for m in methods}
    for method in methods:
        for j, order in enumerate(orders):
            model, seconds, n_warn = _fit(method, int(order), data)
            fit_seconds[method][j], n_warnings[method][j] = seconds, n_warn
            if model is not None:
                identifiable[method][j] = True
                # eq. (20) against the noise-free fast validation output
                gof[method][j] = model.score(data.u_val, data.y_val)
    return TrialResult(run=int(run), gof=gof, identifiable=identifiable,
                       fit_seconds=fit_seconds, n_warnings=n_warnings, snr_db=data.snr_db,
                       seconds=time.perf_counter() - start)


# ------------------------------------------------------------------ results
def _column_stats(values: np.ndarray) -> tuple[float, float, int]:
    """Mean, sample standard deviation (ddof=1) and count of the finite values."""
    finite = values[np.isfinite(values)]
    n_ok = int(finite.size)
    mean = float(finite.mean()) if n_ok else math.nan
    std = float(finite.std(ddof=1)) if n_ok > 1 else math.nan
    return mean, std, n_ok


def _format_cell(row: dict, digits: int | None) -> str:
    """``mean ± std`` of a summary row, with ``(k/n runs)`` when some runs have no value."""
    std = row["std"]
    if digits is None:
        digits = 2
        if np.isfinite(std) and std > 0:
            digits = int(np.clip(1 - math.floor(math.log10(std)), 2, 4))
    cell = f"{row['mean']:.{digits}f}"
    if not math.isnan(std):
        cell += f" ± {std:.{digits}f}"
    if row["n_ok"] < row["n_runs"]:
        cell += f" ({row['n_ok']}/{row['n_runs']} runs)"
    return cell


def _nan_to_none(value):
    return None if isinstance(value, float) and math.isnan(value) else value


@dataclass
class StudyResult:
    """Goodness of fit of every method, order and run of a study (paper Fig. 5).

    Attributes
    ----------
    orders : ndarray of int, shape (n_orders,)
        FIR orders ``P``, increasing.
    methods : tuple of str
    gof : dict of str to ndarray of shape (n_runs, n_orders)
        Validation goodness of fit in percent (eq. 20); NaN where the model
        does not exist.
    identifiable : dict of str to bool ndarray of shape (n_runs, n_orders)
        False where least squares has no unique solution (``P >= M``, Lemma 1).
    fit_seconds : dict of str to ndarray of shape (n_runs, n_orders)
        Wall time of each fit.
    n_warnings : dict of str to int ndarray of shape (n_runs, n_orders)
        Optimizer-convergence and jitter warnings of each fit.
    snr_db : ndarray of shape (n_runs,)
        Training SNR of each run.
    run_seconds : ndarray of shape (n_runs,)
        Wall time of each run.
    random_state : int
        Entropy of the study's :class:`~numpy.random.SeedSequence`; passing
        it again reproduces the study.
    n_samples, factor, sample_time, snr_range, perturbation
        The settings of the study.
    total_seconds : float
        Wall time of the whole study.
    """

    orders: np.ndarray
    methods: tuple
    gof: dict
    identifiable: dict
    fit_seconds: dict
    n_warnings: dict
    snr_db: np.ndarray
    run_seconds: np.ndarray
    random_state: int
    n_samples: int = 600
    factor: int = 3
    sample_time: float = 0.1
    snr_range: tuple = (40.0, 60.0)
    perturbation: float = 0.1
    total_seconds: float = math.nan

    @property
    def n_runs(self) -> int:
        """Number of Monte Carlo runs."""
        return int(self.snr_db.shape[0])

    @property
    def n_slow_samples(self) -> int:
        """Slow samples ``M = ceil(N / F)`` of each training record."""
        return len(range(0, self.n_samples, self.factor))

    # ------------------------------------------------------------ tables
    def summary(self) -> list[dict]:
        """Mean and sample standard deviation of the GoF per method and order.

        Returns
        -------
        list of dict
            One row per method (in ``methods`` order) and order, with keys
            ``method``, ``order``, ``mean``, ``std`` (``ddof=1``; NaN with fewer
            than two values), ``n_ok`` (runs with a value), ``n_runs``,
            ``identifiable`` (in every run), ``mean_fit_seconds`` and
            ``n_warnings`` (summed over the runs).
        """
        rows = []
        for method in self.methods:
            for j, order in enumerate(self.orders):
                mean, std, n_ok = _column_stats(self.gof[method][:, j])
                rows.append({
                    "method": method,
                    "order": int(order),
                    "mean": mean,
                    "std": std,
                    "n_ok": n_ok,
                    "n_runs": self.n_runs,
                    "identifiable": bool(np.all(self.identifiable[method][:, j])),
                    "mean_fit_seconds": float(np.mean(self.fit_seconds[method][:, j])),
                    "n_warnings": int(np.sum(self.n_warnings[method][:, j])),
                })
        return rows

    def to_markdown(self, digits: int | None = None) -> str:
        """GoF table in Markdown: one row per order, ``mean ± std`` per method.

        Least squares reads ``not identifiable`` where no run has a unique
        estimate (``P >= M``); a cell averaged over fewer than all runs says
        how many.

        Parameters
        ----------
        digits : int, optional
            Decimals of the mean and standard deviation.  By default 2, or up
            to 4 when the standard deviation needs them to show two
            significant digits (a PK fit near 100 % reads ``99.9996 ± 0.0005``).

        Returns
        -------
        str
        """
        header, rows = self._table(digits)
        lines = ["| " + " | ".join(header) + " |", "|---:|" + "---:|" * len(self.methods)]
        lines += ["| " + " | ".join(row) + " |" for row in rows]
        return "\n".join(lines) + "\n"

    def to_rst(self, digits: int | None = None) -> str:
        """The table of :meth:`to_markdown` as a reStructuredText list table.

        Parameters
        ----------
        digits : int, optional
            As in :meth:`to_markdown`.

        Returns
        -------
        str
        """
        header, rows = self._table(digits)
        lines = [".. list-table::", "   :header-rows: 1", ""]
        for row in [header, *rows]:
            lines.append("   * - " + row[0])
            lines += [f"     - {cell}" for cell in row[1:]]
        return "\n".join(lines) + "\n"

    def _table(self, digits):
        """Header and rows (lists of strings) of the GoF table."""
        if digits is not None:
            digits = check_int(digits, "digits", low=0)
        by_key = {(r["method"], r["order"]): r for r in self.summary()}
        header = ["P"] + [f"{m} GoF [%]" for m in self.methods]
        rows = []
        for j, order in enumerate(self.orders):
            cells = [str(int(order))]
            for method in self.methods:
                row = by_key[(method, int(order))]
                if row["n_ok"] == 0:
                    none = not np.any(self.identifiable[method][:, j])
                    cells.append("not identifiable" if none else "n/a")
                    continue
                cells.append(_format_cell(row, digits))
            rows.append(cells)
        return header, rows

    def to_csv(self, path, *, runs: bool = False) -> None:
        """Write :meth:`summary` (or, with ``runs=True``, every run) as CSV.

        Parameters
        ----------
        path : str or path-like
        runs : bool, default=False
            One row per run, method and order with ``gof``, ``identifiable``,
            ``fit_seconds``, ``n_warnings`` and ``snr_db`` instead of the summary.
        """
        with open(path, "w", newline="", encoding="utf-8") as stream:
            if not runs:
                rows = self.summary()
                writer = csv.DictWriter(stream, fieldnames=list(rows[0]))
                writer.writeheader()
                writer.writerows(rows)
                return
            writer = csv.writer(stream)
            writer.writerow(["run", "method", "order", "gof", "identifiable", "fit_seconds",
                             "n_warnings", "snr_db"])
            for method in self.methods:
                for i in range(self.n_runs):
                    for j, order in enumerate(self.orders):
                        writer.writerow([
                            i, method, int(order), float(self.gof[method][i, j]),
                            bool(self.identifiable[method][i, j]),
                            float(self.fit_seconds[method][i, j]),
                            int(self.n_warnings[method][i, j]), float(self.snr_db[i]),
                        ])

    # ------------------------------------------------------- persistence
    def to_dict(self) -> dict:
        """Plain-Python (JSON-compatible) form; NaN is stored as None."""
        def nested(array):
            return [[_nan_to_none(v) for v in row] for row in np.asarray(array).tolist()]

        return {
            "format": _STUDY_FORMAT,
            "format_version": 1,
            "orders": self.orders.tolist(),
            "methods": list(self.methods),
            **{name: {m: nested(getattr(self, name)[m]) for m in self.methods}
               for name in _PER_RUN_FIELDS},
            "snr_db": self.snr_db.tolist(),
            "run_seconds": self.run_seconds.tolist(),
            "random_state": int(self.random_state),
            "n_samples": self.n_samples,
            "factor": self.factor,
            "sample_time": self.sample_time,
            "snr_range": list(self.snr_range),
            "perturbation": self.perturbation,
            "total_seconds": _nan_to_none(float(self.total_seconds)),
        }

    @classmethod
    def from_dict(cls, data: dict) -> "StudyResult":
        """Inverse of :meth:`to_dict`."""
        if not isinstance(data, dict) or data.get("format") != _STUDY_FORMAT:
            raise ValueError(f"data must be a dict written by StudyResult.to_dict "
                             f"(format {_STUDY_FORMAT!r})")
        methods = tuple(data["methods"])

        def array(values, dtype):
            if dtype is float:
                return np.array([[math.nan if v is None else v for v in row] for row in values],
                                 dtype=float).reshape(len(values), len(data["orders"]))
            return np.array(values, dtype=dtype).reshape(len(values), len(data["orders"]))

        total = data.get("total_seconds")
        return cls(
            orders=np.array(data["orders"], dtype=int),
            methods=methods,
            **{name: {m: array(data[name][m], dtype) for m in methods}
               for name, dtype in _PER_RUN_FIELDS.items()},
            snr_db=np.array(data["snr_db"], dtype=float),
            run_seconds=np.array(data["run_seconds"], dtype=float),
            random_state=int(data["random_state"]),
            n_samples=int(data["n_samples"]),
            factor=int(data["factor"]),
            sample_time=float(data["sample_time"]),
            snr_range=tuple(float(v) for v in data["snr_range"]),
            perturbation=float(data["perturbation"]),
            total_seconds=math.nan if total is None else float(total),
        )

    def to_json(self, path) -> None:
        """Write the result to a JSON file that :meth:`from_json` reads back."""
        with open(path, "w", encoding="utf-8") as stream:
            json.dump(self.to_dict(), stream, allow_nan=False)
            stream.write("\n")

    @classmethod
    def from_json(cls, path) -> "StudyResult":
        """Read a result written by :meth:`to_json`."""
        with open(path, encoding="utf-8") as stream:
            return cls.from_dict(json.load(stream))


# -------------------------------------------------------------------- study
def _check_n_jobs(n_jobs) -> int:
    if isinstance(n_jobs, bool) or not isinstance(n_jobs, numbers.Integral) or n_jobs == 0:
        raise ValueError(
            f"n_jobs must be a non-zero integer (negative counts back from all CPUs, "
            f"as in joblib); got {n_jobs!r}"
        )
    return int(n_jobs)


def _unordered(n_jobs: int, tasks):
    """Results of joblib ``tasks`` as they finish (in order on joblib < 1.4)."""
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
        with the DC or the DC + prior-knowledge kernel of :func:`paper_kernels`.
    n_samples : int, default=600
        Samples ``N`` per multisine; ``M = ceil(N / factor)`` slow samples.
    factor : int, default=3
        Downsampling factor ``F``, in ``1..n_samples``.
    sample_time : float, default=0.1
        Fast sample time ``T`` in seconds, below 0.25 s (see :func:`paper_kernels`).
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
        Print ``run k/n done (t s)`` to stderr as runs finish.

    Returns
    -------
    StudyResult

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.experiments import run_paper_study
    >>> result = run_paper_study(n_runs=2, orders=(10, 20), methods=("LS",),
    ...                          n_samples=60, progress=False)
    >>> result.gof["LS"].shape, result.n_slow_samples
    ((2, 2), 20)
    >>> bool(np.isnan(result.gof["LS"][:, 1]).all())  # P = 20 >= M: not identifiable
    True
    """
    n_runs = check_int(n_runs, "n_runs", low=1)
    config = _check_config(n_samples, factor, sample_time, snr_db, perturbation)
    orders = _check_orders(orders, config["n_samples"])
    methods = _check_methods(methods)
    n_jobs = _check_n_jobs(n_jobs)
    if not isinstance(progress, bool):
        raise ValueError(f"progress must be True or False; got {progress!r}")
    root = _seed_sequence(random_state)
    seeds = [_child(root, i) for i in range(n_runs)]

    start = time.perf_counter()
    tasks = (joblib.delayed(run_trial)(seed, orders, methods, run=i, **config)
             for i, seed in enumerate(seeds))
    trials: list[TrialResult | None] = [None] * n_runs
    for done, trial in enumerate(_unordered(n_jobs, tasks), start=1):
        trials[trial.run] = trial
        if progress:
            print(f"run {done}/{n_runs} done ({trial.seconds:.1f} s)", file=sys.stderr,
                  flush=True)

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


# ------------------------------------------------------------------ example
@dataclass
class PaperExample:
    """One Monte Carlo run with its fitted models, for the paper's Fig. 6.

    Attributes
    ----------
    data : RunData
        The run's system, inputs and outputs.
    models : dict of str to fitted estimator
        ``"LS"`` (at ``ls_order``), ``"DC"`` and ``"PK"`` (at ``order``), for
        the requested methods; no ``"LS"`` when no order of the grid is
        identifiable.
    gof : dict of str to float
        Validation goodness of fit of each model.
    order : int
        Order ``P`` of the kernel-regularised models.
    ls_order : int or None
        Order of the least-squares model.
    ls_orders, ls_gof : ndarray
        The least-squares orders tried (only ``ls_order`` when it was given)
        and their GoF, NaN where not identifiable.
    """

    data: RunData
    models: dict
    gof: dict
    order: int
    ls_order: int | None
    ls_orders: np.ndarray
    ls_gof: np.ndarray

    @property
    def system(self) -> DiscreteSystem:
        """The true system ``G_0`` of the run."""
        return self.data.system

    def frequencies(self) -> np.ndarray:
        """DFT bins ``k / (N T)``, ``k = 0..N/2``, of the training record, in Hz."""
        return np.fft.rfftfreq(self.data.u.shape[0], d=self.data.sample_time)

    def true_frequency_response(self, freqs=None) -> np.ndarray:
        """FRF of the true system at ``freqs`` (default :meth:`frequencies`)."""
        return self.system.frequency_response(self.frequencies() if freqs is None else freqs)

    def true_impulse_response(self, n_lags: int | None = None) -> np.ndarray:
        """Markov parameters of the true system at lags ``0..n_lags-1`` (default ``order``)."""
        return self.system.impulse_response(self.order if n_lags is None else n_lags)


def _fit_and_score(method: str, order: int, data: RunData):
    model, _, _ = _fit(method, order, data)
    return method, model, (math.nan if model is None else model.score(data.u_val, data.y_val))


def paper_example(
    random_state=0,
    order: int | None = 600,
    ls_order: int | None = None,
    *,
    methods=METHODS,
    ls_orders=None,
    n_samples: int = 600,
    factor: int = 3,
    sample_time: float = 0.1,
    snr_db=(40.0, 60.0),
    perturbation: float = 0.1,
    n_jobs: int = 1,
) -> PaperExample:
    """Fit LS, DC and PK models on one run's data, as in the paper's Fig. 6.

    The data are those of the first run of ``run_paper_study(random_state=...)``
    with the same settings.  The DC and PK models have order ``order``
    (``P = N`` in the paper); least squares has ``ls_order``, or, by default,
    the identifiable order of ``ls_orders`` with the highest validation GoF
    (``P = 150`` in the paper).

    Parameters
    ----------
    random_state : int, SeedSequence or None, default=0
        Seed of the study whose first run is used.
    order : int or None, default=600
        Order of the DC and PK models, in ``1..n_samples``; None is ``n_samples``.
    ls_order : int, optional
        Order of the least-squares model, below ``M``.
    methods : sequence of {"LS", "DC", "PK"}, default=("LS", "DC", "PK")
    ls_orders : sequence of int, optional
        Candidate least-squares orders; default ``10, 20, ...`` below ``M``
        (``1..M-1`` when ``M <= 10``).
    n_samples, factor, sample_time, snr_db, perturbation
        As in :func:`run_paper_study`.
    n_jobs : int, default=1
        Fit the DC and PK models in parallel processes.

    Returns
    -------
    PaperExample

    Examples
    --------
    >>> from gpmultirate.experiments import paper_example
    >>> example = paper_example(order=None, methods=("LS", "DC"), n_samples=60)
    >>> example.order, example.ls_order < 20, sorted(example.models)
    (60, True, ['DC', 'LS'])
    """
    config = _check_config(n_samples, factor, sample_time, snr_db, perturbation)
    n = config["n_samples"]
    order = n if order is None else check_int(order, "order", low=1, high=n)
    methods = _check_methods(methods)
    n_jobs = _check_n_jobs(n_jobs)
    data = simulate_run(_child(_seed_sequence(random_state), 0), **config)
    n_slow = data.y_slow.shape[0]

    models, gof = {}, {}
    ls_tried, ls_scores, best = np.array([], dtype=int), np.array([]), None
    if "LS" in methods:
        if ls_order is not None:
            ls_tried = np.array([check_int(ls_order, "ls_order", low=1, high=n_slow - 1)])
        else:
            if ls_orders is None:
                ls_orders = range(10, n_slow, 10) if n_slow > 10 else range(1, max(n_slow, 2))
            ls_tried = _check_orders(ls_orders, n, "ls_orders")
        fits = [_fit_and_score("LS", int(p), data) for p in ls_tried]
        ls_scores = np.array([score for _, _, score in fits])
        if np.any(np.isfinite(ls_scores)):
            j = int(np.nanargmax(ls_scores))
            best, models["LS"], gof["LS"] = int(ls_tried[j]), fits[j][1], float(ls_scores[j])

    kernel_methods = [m for m in methods if m != "LS"]
    tasks = (joblib.delayed(_fit_and_score)(m, order, data) for m in kernel_methods)
    for method, model, score in joblib.Parallel(n_jobs=n_jobs)(tasks):
        models[method], gof[method] = model, score
    return PaperExample(data=data, models={m: models[m] for m in methods if m in models},
                        gof={m: gof[m] for m in methods if m in gof}, order=order,
                        ls_order=best, ls_orders=ls_tried, ls_gof=ls_scores)
