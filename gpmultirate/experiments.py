"""Deprecated: the paper's Monte Carlo simulation study, under its former module name.

The study lives in the :mod:`gpmultirate.study` package (simulation of the
runs, the runner, the results and the paper's examples).  This module
re-exports the same public names, warns when it is imported and is removed
in gpmultirate 0.2.0.
"""

from gpmultirate.deprecation import deprecated_module
from gpmultirate.study.examples import PaperExample, paper_example
from gpmultirate.study.results import StudyResult
from gpmultirate.study.runner import TrialResult, run_paper_study, run_trial
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

deprecated_module("gpmultirate.experiments", "gpmultirate.study")
