"""Argument types of the ``gpmultirate`` command: checked numbers and one-line errors.

Each type converts one option's text or raises
:class:`argparse.ArgumentTypeError` with a message that names what was
expected; :class:`OneLineErrorParser` reports every error on one line.

Examples
--------
>>> from gpmultirate.arguments import int_at_least, order_or_auto
>>> int_at_least(2)("5"), order_or_auto("auto"), order_or_auto("40")
(5, 'auto', 40)
"""

from __future__ import annotations

import argparse
import math
import os

__all__ = ["FIT_KERNELS", "JOURNAL_NAME", "METHODS", "OneLineErrorParser", "add_sensor_arguments",
           "add_slow_arguments", "argument_type",
           "available_cpus", "check_out", "check_slow_log", "check_windows", "duration",
           "finite_float", "int_at_least", "nonzero_int", "one_line", "order_or_auto",
           "sample_time", "shorten", "without_abbreviations"]


#: Kernels of ``gpmultirate fit --kernel`` (:func:`gpmultirate.report.kernel_option`).
FIT_KERNELS = ("dc", "tc", "ss", "auto")
#: Estimators of ``gpmultirate demo --methods`` (:data:`gpmultirate.study.METHODS`), here
#: so that the parser is built without loading the study.
METHODS = ("LS", "DC", "PK")
#: The study's journal in ``gpmultirate demo --output``
#: (:data:`gpmultirate.study.journal.JOURNAL_NAME`).
JOURNAL_NAME = "runs.jsonl"


def available_cpus() -> int:
    """The CPUs this process may run on (at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def argument_type(name: str, convert, ok, problem, expected: str = "an integer"):
    """An argparse type: ``convert(text)`` if ``ok`` holds, else ``problem(text, value)``."""
    def parse(text: str):
        try:
            value = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
        if not ok(value):
            raise argparse.ArgumentTypeError(problem(text, value))
        return value

    parse.__name__ = name
    return parse


def int_at_least(low: int):
    """An argparse type: an integer of at least ``low``."""
    return argument_type(f"integer >= {low}", int, lambda value: value >= low,
                         lambda text, value: f"must be at least {low}, got {value}")


nonzero_int = argument_type("integer", int, lambda value: value != 0, lambda text, value:
                            "must not be 0 (use a positive count, or -1 for all CPUs)")
finite_float = argument_type("number", float, math.isfinite,
                             lambda text, value: f"must be finite, got {text!r}", "a number")
# a sample time whose reciprocal, a frequency, is a finite normal number too
sample_time = argument_type("seconds", float, lambda value: 1e-300 <= value <= 1e300,
                            lambda text, value: "must be a positive number between 1e-300 "
                                                f"and 1e300 seconds, got {text!r}", "a number")
duration = argument_type("seconds", float, lambda value: 0 <= value < math.inf,
                         lambda text, value: f"must be a non-negative number, got {text!r}",
                         "a number")
order_or_auto = argument_type(
    "order", lambda text: text if text == "auto" else int(text),
    lambda value: value == "auto" or value >= 1,
    lambda text, value: f"expected an integer >= 1 or 'auto', got {text!r}",
    "an integer >= 1 or 'auto'")


def without_abbreviations(add_parser):
    """``add_parser`` of a subparsers action whose parsers refuse abbreviated options
    (``--sample-tim`` is an error, not ``--sample-time``)."""
    def add(*args, **kwargs):
        kwargs.setdefault("allow_abbrev", False)
        return add_parser(*args, **kwargs)

    return add


class OneLineErrorParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line: ``prog: error: message``."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {' '.join(str(message).split())}\n")


# ------------------------------------------------------------------ errors
def check_out(parser, action) -> None:
    """Run ``action`` on ``--out``; a file that is in the way or an OS error ends the command."""
    try:
        action()
    except FileExistsError as error:
        hint = "; use --force to overwrite" if str(error).endswith(" exists") else ""
        parser.error(f"argument --out: {error}{hint}")
    except OSError as error:
        parser.error(f"argument --out: cannot write to {shorten(error.filename or '')!r} "
                     f"({error.strerror or error})")


def check_slow_log(parser, args) -> None:
    """Stop the command when ``--slow``/``--time`` come alone or with options they exclude."""
    if (args.slow is None) != (args.time is None):
        parser.error("argument --slow/--time: a slow log needs both: --slow FILE --time COL")
    wrong = ("--exposure/--latency", getattr(args, "exposure", 0) or getattr(args, "latency", 0))
    if args.slow is not None:
        wrong = ("--factor/--offset", getattr(args, "factor", None) is not None
                 or getattr(args, "offset", None) is not None)
    if wrong[1]:
        parser.error(f"argument {wrong[0]}: " + ("not with --slow (the stamps place the "
                     "readings)" if args.slow else "only with a slow log (--slow)"))


def check_windows(parser, args, n: int, sample_times) -> None:
    """Stop when ``--exposure``/``--latency`` leave no reading inside the record (in seconds).

    ``n``: the rows of the fast record; ``sample_times``: the slow log's
    stamps in fast sample periods.
    """
    record = n * args.sample_time
    latest = max(float(t) for t in sample_times) * args.sample_time
    if args.exposure > record:
        parser.error(f"argument --exposure: must not exceed the record, {record:g} s ({n} rows "
                     f"of {args.sample_time:g} s); got {args.exposure:g}")
    if args.latency > latest:
        parser.error(f"argument --latency: leaves no reading inside the record: every window "
                     f"would end before it starts (the latest stamp is {latest:g} s); got "
                     f"{args.latency:g}")


def add_sensor_arguments(parser, default) -> None:
    """Add ``--exposure`` and ``--latency`` (seconds) to a command's parser."""
    given = "0" if default == 0.0 else "the model's own"
    parser.add_argument("--exposure", type=duration, default=default, metavar="E",
                        help="with --slow: each reading is the mean output over the E seconds "
                             f"before its stamp (default: {given})")
    parser.add_argument("--latency", type=duration, default=default, metavar="L",
                        help="with --slow: a reading stamped t shows the output at t - L "
                             f"(seconds, default: {given})")


def add_slow_arguments(parser, holds: str) -> None:
    """Add ``--slow`` and ``--time`` (a slow log beside the fast record) to a command's parser."""
    parser.add_argument("--slow", metavar="FILE", default=None,
                        help=f"slow log (.csv, .npz, .mat) beside DATA: {holds}")
    parser.add_argument("--time", metavar="COL", default=None,
                        help="with --slow: its column of time stamps in seconds")


def shorten(text: str, limit: int = 80) -> str:
    """``text``, its middle cut out beyond ``limit`` characters."""
    return text if len(text) <= limit else f"{text[:limit // 2]}...{text[-limit // 2:]}"


def one_line(error: BaseException) -> str:
    """An exception as one line that names the file (shortened) for an OS error."""
    if isinstance(error, OSError) and error.strerror:
        names = [shorten(os.fsdecode(name)) for name in (error.filename, error.filename2)
                 if name is not None]
        return ": ".join([*names, error.strerror])
    text = " ".join(str(error).split())
    if isinstance(error, MemoryError):  # the memory guard's refusal says how much and why
        return text or "out of memory"
    return text if isinstance(error, ValueError) else f"{type(error).__name__}: {text}"
