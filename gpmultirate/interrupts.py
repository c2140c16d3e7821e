"""Ctrl-C taken note of: an error raised after it is the interruption.

The command line (:func:`gpmultirate.cli.main`) reports a Ctrl-C as one line
and exit status 130.  Python raises ``KeyboardInterrupt`` for it, except
where the signal lands inside a C extension's initialization: that import
then fails with its own error.  :class:`NotedInterrupt` keeps Python's
behaviour and records that the signal came, so the command can tell the two
apart.
"""

from __future__ import annotations

import contextlib

__all__ = ["NotedInterrupt"]


class NotedInterrupt:
    """Python's own Ctrl-C handler, taking note that the signal came.

    A SIGINT that lands while a C extension initializes surfaces as that
    import's error (``ImportError: initialization failed``), not as
    ``KeyboardInterrupt``; with the note, :func:`gpmultirate.cli.main`
    reports it as the interruption it is.  Installed only in the main thread and only over
    Python's default handler.

    Examples
    --------
    >>> import signal
    >>> noted = NotedInterrupt()
    >>> with noted.installed():
    ...     signal.getsignal(signal.SIGINT) is noted
    True
    >>> noted.received, signal.getsignal(signal.SIGINT) is signal.default_int_handler
    (False, True)
    """

    def __init__(self):
        self.received = False

    def __call__(self, number, frame):
        self.received = True
        raise KeyboardInterrupt

    @contextlib.contextmanager
    def installed(self):
        import signal
        import threading

        if (threading.current_thread() is not threading.main_thread()
                or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
            yield self
            return
        signal.signal(signal.SIGINT, self)
        try:
            yield self
        finally:
            signal.signal(signal.SIGINT, signal.default_int_handler)
