"""Results of the paper's Monte Carlo study as data: tables, CSV, JSON.

* :class:`StudyResult`: the goodness of fit of every method, order and run,
  with its summary table (Markdown, reStructuredText, CSV) and a JSON form
  that reads back.
* :class:`GoFSummary`: mean and sample standard deviation of the goodness of
  fit per order over the runs, what the paper's Fig. 5 draws.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass

import numpy as np

from gpmultirate.validation import check_int, check_signal

__all__ = ["GoFSummary", "StudyResult", "TrialResult"]

_STUDY_FORMAT = "gpmultirate-study"
# per-method arrays of a StudyResult and their dtypes
_PER_RUN_FIELDS = {"gof": float, "identifiable": bool, "fit_seconds": float, "n_warnings": int}


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


@dataclass(frozen=True, eq=False, repr=False)
class GoFSummary:
    """Goodness of fit per model order over Monte Carlo runs: mean and sample std.

    Runs without a value at an order (NaN, or marked not identifiable) are
    left out of that order's statistics, as in the paper's Fig. 5.

    Attributes
    ----------
    orders : ndarray of shape (n_orders,)
        Model orders ``P``.
    mean : ndarray of shape (n_orders,)
        Mean over the runs with a value; NaN where no run has one.
    std : ndarray of shape (n_orders,)
        Sample standard deviation (``ddof=1``); NaN with fewer than two values.
    count : int ndarray of shape (n_orders,)
        Runs with a value at each order.
    n_runs : int
        Runs in the study.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.study import GoFSummary
    >>> summary = GoFSummary.from_runs([10, 20], [[90.0, np.nan], [94.0, 80.0]])
    >>> summary
    GoFSummary(2 orders in [10, 20], 2 runs)
    >>> summary.mean, summary.std, summary.count
    (array([92., 80.]), array([2.82842712,        nan]), array([2, 1]))
    """

    orders: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    count: np.ndarray
    n_runs: int

    def __repr__(self) -> str:
        span = (f" in [{self.orders.min():g}, {self.orders.max():g}]"
                if self.orders.size else "")
        return f"GoFSummary({self.orders.shape[0]} orders{span}, {self.n_runs} runs)"

    def band(self, n_std: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
        """``mean -+ n_std std``: the band of Fig. 5, NaN where ``std`` is.

        Examples
        --------
        >>> from gpmultirate.study import GoFSummary
        >>> GoFSummary.from_runs([10], [[90.0], [94.0]]).band(1.0)
        (array([89.17157288]), array([94.82842712]))
        """
        return self.mean - n_std * self.std, self.mean + n_std * self.std

    @classmethod
    def from_runs(cls, orders, gof, identifiable=None) -> "GoFSummary":
        """Statistics of a table of goodness-of-fit values, one row per run.

        Parameters
        ----------
        orders : array-like of shape (n_orders,)
            Model orders ``P``.
        gof : array-like of shape (n_runs, n_orders) or (n_orders,)
            Goodness of fit in percent (eq. 20), NaN where not computed.
        identifiable : bool array-like of shape (n_orders,) or gof's shape, optional
            Where the estimate exists; entries marked False are treated as NaN.

        Returns
        -------
        GoFSummary
        """
        orders = check_signal(orders, "orders")
        try:
            gof = np.array(gof, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError("gof must be an array of goodness-of-fit values") from exc
        if gof.ndim == 1:
            gof = gof[None, :]
        if gof.ndim != 2 or gof.shape[1] != orders.shape[0]:
            raise ValueError(
                f"gof must have shape (n_runs, {orders.shape[0]}) or ({orders.shape[0]},) to "
                f"match orders; got shape {np.shape(gof)}"
            )
        if np.any(np.isinf(gof)):
            raise ValueError("gof must not contain inf (use NaN for missing values)")
        if identifiable is not None:
            mask = np.asarray(identifiable)
            if mask.dtype != bool:
                raise ValueError(f"identifiable must be a boolean array; got dtype {mask.dtype}")
            if mask.shape not in (orders.shape, gof.shape):
                raise ValueError(
                    f"identifiable must have shape {orders.shape} or {gof.shape}; "
                    f"got {mask.shape}"
                )
            gof = np.where(mask, gof, np.nan)

        # nan-aware mean and sample std, written out to avoid warnings on empty columns
        finite = np.isfinite(gof)
        count = finite.sum(axis=0)
        total = np.where(finite, gof, 0.0).sum(axis=0)
        mean = np.full(count.shape, np.nan)
        mean[count > 0] = total[count > 0] / count[count > 0]
        deviation = np.where(finite, gof - mean, 0.0)
        std = np.full(count.shape, np.nan)
        several = count > 1
        std[several] = np.sqrt((deviation[:, several] ** 2).sum(axis=0) / (count[several] - 1))
        return cls(orders=orders, mean=mean, std=std, count=count, n_runs=int(gof.shape[0]))


@dataclass
class TrialResult:
    """Scores of one Monte Carlo run, see :func:`~gpmultirate.study.runner.run_trial`.

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
        Wall time of the whole study (of its last session, for a study
        resumed from a journal).

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.study import StudyResult
    >>> gof = {"LS": np.array([[90.0, np.nan], [92.0, np.nan]])}
    >>> result = StudyResult(
    ...     orders=np.array([10, 20]), methods=("LS",), gof=gof,
    ...     identifiable={"LS": np.isfinite(gof["LS"])}, fit_seconds={"LS": np.zeros((2, 2))},
    ...     n_warnings={"LS": np.zeros((2, 2), int)}, snr_db=np.array([45.0, 55.0]),
    ...     run_seconds=np.ones(2), random_state=0, n_samples=60)
    >>> print(result.to_markdown())
    | P | LS GoF [%] |
    |---:|---:|
    | 10 | 91.00 ± 1.41 |
    | 20 | not identifiable |
    <BLANKLINE>
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

    def gof_summary(self, method: str) -> GoFSummary:
        """Mean and sample standard deviation of ``method``'s GoF per order (Fig. 5).

        Runs where the model is not identifiable are left out.

        Parameters
        ----------
        method : str
            One of :attr:`methods`.

        Returns
        -------
        GoFSummary
        """
        if method not in self.methods:
            raise ValueError(f"method must be one of {tuple(self.methods)}; got {method!r}")
        return GoFSummary.from_runs(
            self.orders, self.gof[method],
            identifiable=np.asarray(self.identifiable[method], dtype=bool))

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

