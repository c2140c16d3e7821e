"""A crash-safe record of the finished runs of a study, so that it can resume.

:func:`~gpmultirate.study.run_paper_study` with ``journal=PATH`` appends one
JSON line per finished run to ``PATH`` (``gpmultirate demo`` uses
``runs.jsonl`` in its output folder).  The first line holds the settings of
the study; every other line holds one :class:`~gpmultirate.study.TrialResult`.

Each line is written by one ``os.write`` on a file opened with ``O_APPEND``
and then flushed to disk with ``os.fsync``, so an interruption (``SIGINT``,
``SIGKILL``, a crash of the machine) can at worst leave the last line
incomplete.  Reading ignores such a torn last line, and resuming cuts it off
before appending.  Floats are written with Python's shortest round-trip
``repr``, so a resumed study has bit for bit the numbers of an uninterrupted
one: run ``i`` is seeded by child ``i`` of the study's seed alone.

A file lock (where :mod:`fcntl` exists) stops two processes from writing
one journal at the same time.

Examples
--------
>>> import os, tempfile
>>> from gpmultirate.study import run_paper_study
>>> from gpmultirate.study.journal import read_journal
>>> path = os.path.join(tempfile.mkdtemp(), "runs.jsonl")
>>> result = run_paper_study(n_runs=2, orders=(10,), methods=("LS",), n_samples=60,
...                          progress=False, journal=path)
>>> settings, trials = read_journal(path)
>>> settings["n_runs"], sorted(trials)
(2, [0, 1])
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from gpmultirate.exceptions import JournalError
from gpmultirate.study.results import TrialResult
from gpmultirate.version import __version__

try:  # pragma: no cover - fcntl is missing on Windows only
    import fcntl
except ImportError:  # pragma: no cover
    fcntl = None

__all__ = ["JOURNAL_NAME", "JournalError", "StudyJournal", "describe_mismatch",
           "interrupted_message", "journal_progress", "prepare_journal", "read_journal",
           "study_settings"]

#: File name of the journal in the output folder of ``gpmultirate demo``.
JOURNAL_NAME = "runs.jsonl"
_FORMAT = "gpmultirate-study-journal"
_FORMAT_VERSION = 1
# per-method arrays of a TrialResult and the type of their entries
_ARRAYS = {"gof": float, "identifiable": bool, "fit_seconds": float, "n_warnings": int}
# settings that a resumed study must share with the journal, and how to show them
_SETTING_NAMES = {
    "random_state": "seed", "spawn_key": "seed spawn key", "n_runs": "runs",
    "orders": "orders", "methods": "methods", "n_samples": "n_samples", "factor": "factor",
    "sample_time": "sample_time", "snr_db": "SNR range", "perturbation": "perturbation",
    "version": "gpmultirate version",
}


def study_settings(n_runs, orders, methods, config, root) -> dict:
    """The settings of a study as a journal stores and compares them.

    Parameters
    ----------
    n_runs : int
    orders : ndarray of int
    methods : tuple of str
    config : dict
        The validated settings of :func:`~gpmultirate.study.simulation.check_config`.
    root : numpy.random.SeedSequence
        The study's seed.

    Returns
    -------
    dict
        JSON-compatible.
    """
    return {
        "random_state": int(root.entropy),
        "spawn_key": [int(k) for k in root.spawn_key],
        "n_runs": int(n_runs),
        "orders": [int(p) for p in orders],
        "methods": list(methods),
        "n_samples": int(config["n_samples"]),
        "factor": int(config["factor"]),
        "sample_time": float(config["sample_time"]),
        "snr_db": [float(v) for v in config["snr_db"]],
        "perturbation": float(config["perturbation"]),
        "version": __version__,
    }


# ----------------------------------------------------------------- encoding
def _encode_float(value: float):
    value = float(value)
    if math.isnan(value):
        return None
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return value


def _decode_float(value) -> float:
    if value is None:
        return math.nan
    if isinstance(value, str) and value in ("inf", "-inf"):
        return float(value)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"expected a number, got {value!r}")
    return float(value)


def _encode_trial(trial) -> bytes:
    record = {"run": int(trial.run), "snr_db": _encode_float(trial.snr_db),
              "seconds": _encode_float(trial.seconds)}
    for name, kind in _ARRAYS.items():
        record[name] = {
            m: [_encode_float(v) if kind is float else kind(v)
                for v in np.asarray(values).tolist()]
            for m, values in getattr(trial, name).items()
        }
    return (json.dumps(record, allow_nan=False, separators=(",", ":")) + "\n").encode("utf-8")


def _decode_trial(record, settings: dict):
    if not isinstance(record, dict):
        raise ValueError("a run record must be a JSON object")
    run = record["run"]
    if isinstance(run, bool) or not isinstance(run, int) or not 0 <= run < settings["n_runs"]:
        raise ValueError(f"run index {run!r} is not in 0..{settings['n_runs'] - 1}")
    n_orders = len(settings["orders"])
    arrays = {}
    for name, kind in _ARRAYS.items():
        per_method = record[name]
        if not isinstance(per_method, dict) or set(per_method) != set(settings["methods"]):
            raise ValueError(f"{name} must have one entry per method {settings['methods']}")
        arrays[name] = {}
        for m in settings["methods"]:
            values = per_method[m]
            if not isinstance(values, list) or len(values) != n_orders:
                raise ValueError(f"{name}[{m!r}] must hold {n_orders} values")
            if kind is float:
                arrays[name][m] = np.array([_decode_float(v) for v in values], dtype=float)
            elif kind is bool:
                if not all(isinstance(v, bool) for v in values):
                    raise ValueError(f"{name}[{m!r}] must hold true or false")
                arrays[name][m] = np.array(values, dtype=bool)
            else:
                if any(isinstance(v, bool) or not isinstance(v, int) for v in values):
                    raise ValueError(f"{name}[{m!r}] must hold integers")
                arrays[name][m] = np.array(values, dtype=int)
    return TrialResult(run=run, gof=arrays["gof"], identifiable=arrays["identifiable"],
                       fit_seconds=arrays["fit_seconds"], n_warnings=arrays["n_warnings"],
                       snr_db=_decode_float(record["snr_db"]),
                       seconds=_decode_float(record["seconds"]))


def _header(settings: dict) -> bytes:
    record = {"format": _FORMAT, "format_version": _FORMAT_VERSION, "settings": settings}
    return (json.dumps(record, allow_nan=False, separators=(",", ":")) + "\n").encode("utf-8")


# ------------------------------------------------------------------ reading
def _scan(path):
    """``(settings or None, trials by run, bytes of the valid prefix)`` of a journal file.

    A last line without its newline, or that is not valid JSON, is what an
    interrupted write leaves; it is left out.  Anything else that is wrong
    raises :class:`JournalError`.
    """
    data = Path(path).read_bytes()
    lines = data.split(b"\n")
    # the piece after the last newline is empty, or a torn line
    complete, offset = lines[:-1], 0
    settings, trials = None, {}
    for k, line in enumerate(complete):
        last = k == len(complete) - 1
        try:
            record = json.loads(line.decode("utf-8"))
        except (UnicodeDecodeError, ValueError) as exc:
            if last:
                break  # a torn last line
            raise JournalError(f"{path}: line {k + 1} is corrupt ({exc})") from None
        if k == 0:
            if (not isinstance(record, dict) or record.get("format") != _FORMAT
                    or not isinstance(record.get("settings"), dict)):
                raise JournalError(f"{path}: not a study journal (the first line holds no "
                                   f"{_FORMAT!r} header)")
            if record.get("format_version") != _FORMAT_VERSION:
                raise JournalError(f"{path}: journal format version "
                                   f"{record.get('format_version')!r} is not supported")
            settings = record["settings"]
            missing = sorted(set(_SETTING_NAMES) - set(settings))
            if missing:
                raise JournalError(f"{path}: the header lacks the settings {missing}")
        else:
            try:
                trial = _decode_trial(record, settings)
            except (KeyError, TypeError, ValueError) as exc:
                raise JournalError(f"{path}: line {k + 1} is not a valid run record "
                                   f"({exc})") from None
            trials.setdefault(trial.run, trial)
        offset += len(line) + 1
    return settings, trials, offset


def read_journal(path):
    """The settings and finished runs of a journal; a torn last line is ignored.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    settings : dict or None
        None when not even the header line was written completely.
    trials : dict of int to TrialResult
        The finished runs by index.

    Raises
    ------
    JournalError
        If the file is not a journal or a line other than the last is corrupt.
    """
    settings, trials, _ = _scan(path)
    return settings, trials


def journal_progress(path):
    """The finished runs of a journal and the runs of its study, or None if unreadable.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    tuple of (int, int or None), or None
        ``(finished, n_runs)``, ``n_runs`` None when the header line is
        missing; None when the file cannot be read or is not a journal.

    Examples
    --------
    >>> import os, tempfile
    >>> from gpmultirate.study import run_paper_study
    >>> from gpmultirate.study.journal import journal_progress
    >>> path = os.path.join(tempfile.mkdtemp(), "runs.jsonl")
    >>> _ = run_paper_study(n_runs=2, orders=(10,), methods=("LS",), n_samples=60,
    ...                     progress=False, journal=path)
    >>> journal_progress(path), journal_progress(path + ".missing")
    ((2, 2), None)
    """
    try:
        settings, trials = read_journal(path)
    except (OSError, JournalError):
        return None
    return len(trials), (None if settings is None else settings["n_runs"])


def prepare_journal(path, *, resume: bool = False, force: bool = False) -> str | None:
    """Make a study's journal ready to start (or resume) a study, or refuse.

    The saved runs of an interrupted study are kept for ``resume``,
    removed with ``force``; a journal without a finished run is removed
    (nothing is lost); any other journal is refused.

    Parameters
    ----------
    path : str or path-like
        The journal (``JOURNAL_NAME`` in the study's output folder).
    resume, force : bool, default=False
        Continue the saved runs, or discard them.

    Returns
    -------
    str or None
        A note when ``resume`` finds no journal (the study starts afresh).

    Raises
    ------
    ValueError
        If ``path`` is a directory, or holds finished runs (or cannot be
        read) and neither ``resume`` nor ``force`` is given.

    Examples
    --------
    >>> import os, tempfile
    >>> from gpmultirate.study.journal import prepare_journal
    >>> prepare_journal(os.path.join(tempfile.mkdtemp(), "runs.jsonl")) is None
    True
    """
    path = Path(path)
    if not (path.exists() or path.is_symlink()):
        if resume:
            return f"no {path.name} in {path.parent}: nothing to resume, starting the study"
        return None
    if path.is_dir():
        raise ValueError(f"{path} is a directory")
    if force:
        path.unlink()
        return None
    if resume:
        return None
    found = journal_progress(path)
    if found is not None and found[0] == 0:
        path.unlink()  # no run was finished: nothing to lose
        return None
    what = ("an unreadable journal" if found is None else
            f"{found[0]} of {found[1]} finished runs of an interrupted study")
    raise ValueError(f"{path} holds {what}; use --resume to continue it or --force to start "
                     f"over")


def interrupted_message(path) -> str:
    """What is saved of an interrupted study, and how to continue it.

    Parameters
    ----------
    path : str or path-like
        The study's journal.

    Returns
    -------
    str

    Examples
    --------
    >>> from gpmultirate.study.journal import interrupted_message
    >>> interrupted_message("missing/runs.jsonl")  # doctest: +ELLIPSIS
    'interrupted; the finished runs are saved in missing/runs.jsonl; run the same ...'
    """
    found = journal_progress(path) if Path(path).exists() else None
    saved = (f"{found[0]} of {found[1]} runs are saved in {path}" if found
             else f"the finished runs are saved in {path}")
    return f"interrupted; {saved}; run the same command with --resume to continue"


def describe_mismatch(found: dict, wanted: dict) -> str:
    """The settings in which a journal (``found``) and a study (``wanted``) differ.

    Examples
    --------
    >>> describe_mismatch({"n_runs": 5, "factor": 3}, {"n_runs": 6, "factor": 3})
    'runs 5 (journal) vs 6 (now)'
    """
    parts = []
    for key, value in wanted.items():
        if found.get(key) != value:
            show = _SETTING_NAMES.get(key, key)
            parts.append(f"{show} {_show(found.get(key))} (journal) vs {_show(value)} (now)")
    return "; ".join(parts)


def _show(value) -> str:
    if isinstance(value, list):
        return " ".join(map(str, value)) if value else "[]"
    return str(value)


# ------------------------------------------------------------------ writing
def _write_all(fd: int, data: bytes) -> None:
    # One write per line: a regular file takes it whole.  The loop only matters
    # for a short write (a full disk), where a torn line is the worst outcome.
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]
    os.fsync(fd)


def _sync_directory(path: Path) -> None:
    try:
        fd = os.open(path.parent if str(path.parent) else ".", os.O_RDONLY)
    except OSError:  # pragma: no cover - e.g. Windows
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover
        pass
    finally:
        os.close(fd)


class StudyJournal:
    """An open journal: the runs finished so far, and :meth:`append` for new ones.

    Use :meth:`open`; close it (or use it as a context manager) when done.

    Attributes
    ----------
    path : Path
    settings : dict
    trials : dict of int to TrialResult
        The runs found in the file when it was opened.
    """

    def __init__(self, path: Path, settings: dict, trials: dict, fd: int):
        self.path, self.settings, self.trials, self._fd = path, settings, trials, fd

    @classmethod
    def open(cls, path, settings: dict) -> "StudyJournal":
        """Create the journal ``path`` of a study, or reopen it to resume.

        An existing file must hold a study of the same ``settings``; its
        finished runs are in :attr:`trials` and a torn last line is cut off.
        A file without a complete header line is started afresh.

        Raises
        ------
        JournalError
            If the file holds another study, is corrupt, or another process
            has it open.
        """
        path = Path(path)
        fd = os.open(path, os.O_RDWR | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            if fcntl is not None:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except OSError:
                    raise JournalError(f"{path}: another process is writing this "
                                       f"journal") from None
            found, trials, valid = _scan(path)
            if found is None:
                os.ftruncate(fd, 0)
                _write_all(fd, _header(settings))
                _sync_directory(path)
                return cls(path, settings, {}, fd)
            if found != settings:
                raise JournalError(f"{path} holds a study with other settings: "
                                   f"{describe_mismatch(found, settings)}")
            if valid != os.fstat(fd).st_size:
                os.ftruncate(fd, valid)  # drop a torn last line before appending
                os.fsync(fd)
            return cls(path, settings, trials, fd)
        except BaseException:
            os.close(fd)
            raise

    def append(self, trial) -> None:
        """Append one finished run and flush it to disk."""
        if self._fd is None:
            raise ValueError("the journal is closed")
        _write_all(self._fd, _encode_trial(trial))

    def close(self) -> None:
        """Close the file (and release its lock)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> "StudyJournal":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
