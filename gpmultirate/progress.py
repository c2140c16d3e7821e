"""Progress of a fit as lines on a stream: the ``gpmultirate.fit`` logger made visible.

A fit that takes more than a few seconds (the default order's pilot fits on
a long record, the resonance search of ``kernel="auto"``, the fit at the
chosen order) reports each step on the :mod:`logging` logger
``gpmultirate.fit`` at level ``INFO``, with an estimate of the time left
where there is one.  Nothing is shown by default; :func:`show_progress`
attaches a :class:`ProgressHandler` that writes each step as one line with
the time elapsed (``gpmultirate fit`` does, unless ``--quiet``).

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
import time

__all__ = ["FIT_LOGGER", "ProgressHandler", "show_progress"]

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

    def emit(self, record: logging.LogRecord) -> None:  # noqa: D102 - logging.Handler's
        try:
            elapsed = time.perf_counter() - self.started
            stream = sys.stderr if self.stream is None else self.stream
            stream.write(f"{self.prefix}: [{elapsed:6.1f} s] {record.getMessage()}\n")
            stream.flush()
        except Exception:  # pragma: no cover - as logging.StreamHandler does
            self.handleError(record)


@contextlib.contextmanager
def show_progress(stream=None, prefix: str = "gpmultirate", logger: str = FIT_LOGGER):
    """Show the progress of fits within a ``with`` block.

    Attaches a :class:`ProgressHandler` to the logger (``INFO`` and above)
    for the block and restores the logger afterwards.

    Parameters
    ----------
    stream : file-like, optional
        Where the lines go (default: ``sys.stderr``).
    prefix : str, default="gpmultirate"
    logger : str, default=FIT_LOGGER

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
    handler = ProgressHandler(stream, prefix)
    target = logging.getLogger(logger)
    level = target.level
    if target.getEffectiveLevel() > logging.INFO:
        target.setLevel(logging.INFO)
    target.addHandler(handler)
    try:
        yield handler
    finally:
        target.removeHandler(handler)
        target.setLevel(level)
