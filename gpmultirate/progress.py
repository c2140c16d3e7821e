"""Progress of a fit as lines on a stream: the ``gpmultirate.fit`` logger made visible.

A fit that takes more than a few seconds (the default order's pilot fits on
a long record, the resonance search of ``kernel="auto"``, the fit at the
chosen order) reports each step on the :mod:`logging` logger
``gpmultirate.fit`` at level ``INFO``, with an estimate of the time left
where there is one.  Nothing is shown by default; :func:`show_progress`
attaches a :class:`ProgressHandler` that writes each step as one line with
the time elapsed (``gpmultirate fit`` does, unless ``--quiet``).

Within ``show_progress`` no step runs ten seconds without a line: a
heartbeat names the step under way and, while the hyperparameters are
tuned, the evaluations of the evidence done, their measured cost and the
time left that follows from it (:func:`time_left`), updated every ten
seconds.  :class:`StepTimes` times the steps of a command and gives the
final line, ``steps: fit 12.3 s, bands 0.8 s, ...``.

Examples
--------
>>> import io
>>> import numpy as np
>>> import gpmultirate as gm
>>> from gpmultirate.progress import show_progress
>>> rng = np.random.default_rng(0)
>>> u = rng.standard_normal(3000)
>>> y = np.convolve(u, 0.9 ** np.arange(40))[:3000] + 0.01 * rng.standard_normal(3000)
>>> stream = io.StringIO()
>>> with show_progress(stream):
...     model = gm.FIRGaussianProcess(factor=3).fit(u, y[::3])
>>> "default order" in stream.getvalue()
True
"""

from __future__ import annotations

import contextlib
import logging
import sys
import threading
import time

__all__ = ["EVALUATIONS", "FIT_LOGGER", "EvaluationClock", "ProgressHandler", "StepTimes",
           "show_progress", "step", "time_left"]

#: The name of the logger on which a fit reports its progress.
FIT_LOGGER = "gpmultirate.fit"


class ProgressHandler(logging.Handler):
    """A logging handler that writes each record as one line with the time elapsed.

    Parameters
    ----------
    stream : file-like, optional
        Where the lines go (default: ``sys.stderr`` at the time of each
        line).
    prefix : str, default="gpmultirate"
        The start of every line: ``"{prefix}: [  12.3 s] message"``.

    Examples
    --------
    >>> import io, logging
    >>> from gpmultirate.progress import ProgressHandler
    >>> stream = io.StringIO()
    >>> handler = ProgressHandler(stream, prefix="demo")
    >>> handler.emit(logging.makeLogRecord({"msg": "step %d", "args": (1,)}))
    >>> stream.getvalue().startswith("demo: [") and stream.getvalue().endswith("] step 1\\n")
    True
    """

    def __init__(self, stream=None, prefix: str = "gpmultirate") -> None:
        super().__init__(level=logging.INFO)
        self.stream = stream
        self.prefix = prefix
        self.started = time.perf_counter()
        self.last = self.started

    def emit(self, record: logging.LogRecord) -> None:  # noqa: D102 - logging.Handler's
        try:
            elapsed = time.perf_counter() - self.started
            stream = sys.stderr if self.stream is None else self.stream
            stream.write(f"{self.prefix}: [{elapsed:6.1f} s] {record.getMessage()}\n")
            stream.flush()
            self.last = time.perf_counter()
        except Exception:  # pragma: no cover - as logging.StreamHandler does
            self.handleError(record)


@contextlib.contextmanager
def show_progress(stream=None, prefix: str = "gpmultirate", logger: str = FIT_LOGGER,
                  interval: float | None = None, since: float | None = None):
    """Show the progress of fits within a ``with`` block.

    Attaches a :class:`ProgressHandler` to the logger (``INFO`` and above)
    for the block and restores the logger afterwards.  Whenever
    ``interval`` seconds pass without a line, a line says which step is
    under way and, while the evidence is tuned, its measured evaluations
    and the time left.

    Parameters
    ----------
    stream : file-like, optional
        Where the lines go (default: ``sys.stderr``).
    prefix : str, default="gpmultirate"
    logger : str, default=FIT_LOGGER
    interval : float, optional
        Seconds; default ``HEARTBEAT_SECONDS`` (10).
    since : float, optional
        The ``time.perf_counter()`` the elapsed times count from (default:
        now), so that two blocks of one command share one clock.

    Yields
    ------
    ProgressHandler

    Examples
    --------
    >>> import io, logging
    >>> from gpmultirate.progress import show_progress
    >>> stream = io.StringIO()
    >>> with show_progress(stream, prefix="fit"):
    ...     logging.getLogger("gpmultirate.fit").info("pilot fit done")
    >>> stream.getvalue().split("] ")[1]
    'pilot fit done\\n'
    """
    interval = HEARTBEAT_SECONDS if interval is None else float(interval)
    handler = ProgressHandler(stream, prefix)
    if since is not None:
        handler.started = float(since)
    target = logging.getLogger(logger)
    level = target.level
    if target.getEffectiveLevel() > logging.INFO:
        target.setLevel(logging.INFO)
    target.addHandler(handler)
    stop = threading.Event()
    beat = threading.Thread(target=_heartbeat, args=(handler, target, stop, interval),
                            name="gpmultirate-progress", daemon=True)
    beat.start()
    try:
        yield handler
    finally:
        stop.set()
        beat.join()
        target.removeHandler(handler)
        target.setLevel(level)


#: the longest a step runs without a line of progress, in seconds
HEARTBEAT_SECONDS = 10.0


def _heartbeat(handler, logger, stop, interval):
    """A line whenever ``interval`` seconds passed without one: the step and the time left."""
    while not stop.wait(min(1.0, interval / 4)):
        if time.perf_counter() - handler.last >= interval:
            logger.info("%s", _under_way())


def _under_way() -> str:
    step, since = _CURRENT.step, _CURRENT.since
    line = "still working" if step is None else (
        f"still on {step} ({time.perf_counter() - since:.0f} s)")
    tuning = EVALUATIONS.summary()
    return line if tuning is None else f"{line}; {tuning}"


class _Current:
    step: str | None = None
    since: float = 0.0
    steps: "StepTimes | None" = None


_CURRENT = _Current()


def time_left(evaluation_seconds, expected_evaluations: int) -> float:
    """Seconds left for a run of ``expected_evaluations`` from the measured evaluations.

    The evaluations still to come cost what the last ones measured cost
    (their mean over the last five: the cost of one evaluation is that of
    its route and order, steady within a run); a run that already made
    ``expected_evaluations`` is taken to need half again as many.

    Parameters
    ----------
    evaluation_seconds : sequence of float
        The measured time of each evaluation of the run so far.
    expected_evaluations : int
        The evaluations the run is expected to make (those of an earlier
        run of the same fit, or ``TYPICAL_EVALUATIONS``).

    Returns
    -------
    float

    Examples
    --------
    >>> time_left([2.0, 1.0, 1.0], 10)  # 7 more at 4/3 s
    9.333333333333332
    >>> time_left([1.0] * 12, 10)  # beyond the expected: 6 more
    6.0
    """
    done = len(evaluation_seconds)
    if done == 0:
        return float("nan")
    recent = list(evaluation_seconds)[-5:]
    each = sum(recent) / len(recent)
    expected = max(int(expected_evaluations), 1)
    if done >= expected:
        expected = done + max(1, done // 2)
    return each * (expected - done)


#: evaluations of an L-BFGS-B run of the evidence expected before any was measured
TYPICAL_EVALUATIONS = 30
#: a run is expected to take this share of the evaluations of the latest earlier run of
#: its kind: the default order's pilots each start where the last one ended and take
#: fewer evaluations one after the other, by a median factor of 0.71 over the pilots of
#: two held-out camera logs of ``benchmarks/camera_log.py`` (41, 34, 24, 10 and 38, 28,
#: 15, 16, 8 evaluations): expecting the latest count erred by up to 2.4 times there,
#: this share by at most 1.7 times; a run that repeats the latest one's count is
#: expected 0.7 of it, and the estimate grows once the run passes it (:func:`time_left`)
RUN_SHARE = 0.7


class EvaluationClock:
    """The measured time of each evaluation of the evidence, run by run.

    The tuning (:func:`gpmultirate.tuning.maximize`) opens a run
    (:meth:`run`, with the kind of problem it tunes) and times each
    evaluation (:meth:`timed`); the heartbeat of :func:`show_progress`
    reads :meth:`summary`.  A run is expected to take ``RUN_SHARE`` of the
    evaluations of the latest earlier run of its kind (:meth:`expected`):
    the default order's pilots each start where the last one ended, and
    take fewer evaluations one after the other (42, 37, 25 and 16 on a
    camera log of ``benchmarks/camera_log.py``), so the latest is the
    closer guess (the median of the earlier ones was more than twice the
    last run's count there), and less of it closer still.

    Examples
    --------
    >>> clock = EvaluationClock()
    >>> with clock.run():
    ...     f = clock.timed(lambda theta: theta * 2)
    ...     f(1.0), f(2.0)
    (2.0, 4.0)
    >>> clock.runs, clock.expected()  # 0.7 of the latest run's 2
    ([2], 1)
    """

    def __init__(self) -> None:
        self.runs: list[int] = []
        self.kinds: list = []
        self.kind = None  # of the run under way
        self.seconds: list[float] | None = None
        self.evaluating = time.perf_counter()  # the start of the latest evaluation
        self._lock = threading.Lock()

    @contextlib.contextmanager
    def run(self, kind=None):
        """One optimizer run: its evaluations are counted together.

        ``kind``: any hashable that tells runs of one problem from another
        (the tuning gives whether a disturbance is tuned and the number of
        hyperparameters); None by default.
        """
        outer, outer_kind = self.seconds, self.kind
        self.seconds, self.kind = [], kind
        try:
            yield self
        finally:
            with self._lock:
                if self.seconds:
                    self.runs.append(len(self.seconds))
                    self.kinds.append(kind)
                self.seconds, self.kind = outer, outer_kind

    def timed(self, function):
        """``function`` with each call's time recorded in the current run."""

        def timed_function(*args, **kwargs):
            start = self.evaluating = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                seconds = self.seconds
                if seconds is not None:
                    seconds.append(time.perf_counter() - start)

        return timed_function

    def expected(self, kind=None) -> int:
        """The evaluations a run of ``kind`` is expected to take.

        ``RUN_SHARE`` of those of the latest earlier run of that kind, else
        of the latest earlier run (at least one), else
        ``TYPICAL_EVALUATIONS``.
        """
        with self._lock:
            runs, kinds = list(self.runs), list(self.kinds)
        alike = [count for count, other in zip(runs, kinds) if other == kind]
        latest = alike[-1] if alike else runs[-1] if runs else None
        if latest is None:
            return TYPICAL_EVALUATIONS
        return max(1, int(round(RUN_SHARE * latest)))

    def summary(self) -> str | None:
        """``"tuning: 12 evaluation(s) of the evidence, 1.9 s each, about 34 s left"``.

        None outside a run.
        """
        seconds = self.seconds
        if seconds is None:
            return None
        if not seconds:
            return (f"tuning: the first evaluation of the evidence under way "
                    f"({time.perf_counter() - self.evaluating:.0f} s)")
        seconds = list(seconds)
        recent = seconds[-5:]
        return (f"tuning: {len(seconds)} evaluation(s) of the evidence, "
                f"{sum(recent) / len(recent):.2g} s each, about "
                f"{time_left(seconds, self.expected(self.kind)):.0f} s left")


#: the clock of the evidence's evaluations in this process
EVALUATIONS = EvaluationClock()


class StepTimes:
    """The time each step of a command takes, announced as it ends.

    A step under way for ten seconds is named by the heartbeat of
    :func:`show_progress`.

    Parameters
    ----------
    logger : str, default=FIT_LOGGER

    Examples
    --------
    >>> steps = StepTimes()
    >>> with steps.step("fit"):
    ...     pass
    >>> with steps.step("figures"):
    ...     pass
    >>> steps.line().startswith("steps: fit 0.0 s, figures 0.0 s")
    True
    """

    def __init__(self, logger: str = FIT_LOGGER) -> None:
        self.logger = logging.getLogger(logger)
        self.times: dict[str, float] = {}

    @contextlib.contextmanager
    def step(self, name: str):
        """Time the block as step ``name`` (added up if the step comes back)."""
        outer = (_CURRENT.step, _CURRENT.since)
        start = time.perf_counter()
        _CURRENT.step, _CURRENT.since = name, start
        try:
            yield
        finally:
            seconds = time.perf_counter() - start
            _CURRENT.step, _CURRENT.since = outer
            self.times[name] = self.times.get(name, 0.0) + seconds
            self.logger.info("%s: %.1f s", name, seconds)

    def __enter__(self) -> "StepTimes":
        """Make these the steps that :func:`step` times (within the ``with`` block)."""
        self._outer = _CURRENT.steps
        _CURRENT.steps = self
        return self

    def __exit__(self, *exc) -> None:
        _CURRENT.steps = self._outer

    def line(self) -> str:
        """``"steps: fit 12.3 s, bands 0.8 s, ..., total 15.0 s"``."""
        parts = [f"{name} {seconds:.1f} s" for name, seconds in self.times.items()]
        return "steps: " + ", ".join(parts + [f"total {sum(self.times.values()):.1f} s"])


def step(name: str):
    """Time the block as step ``name`` of the active :class:`StepTimes` (none: no effect).

    Examples
    --------
    >>> with StepTimes() as steps:
    ...     with step("state space"):
    ...         pass
    >>> list(steps.times)
    ['state space']
    >>> with step("alone"):  # no active steps
    ...     pass
    """
    steps = _CURRENT.steps
    return contextlib.nullcontext() if steps is None else steps.step(name)
