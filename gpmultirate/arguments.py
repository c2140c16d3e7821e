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

__all__ = ["OneLineErrorParser", "argument_type", "available_cpus", "duration", "finite_float",
           "int_at_least", "nonzero_int", "order_or_auto", "sample_time"]


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


class OneLineErrorParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line: ``prog: error: message``."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {' '.join(str(message).split())}\n")
