"""Deprecated: the former home of :class:`~gpmultirate.responses.FrequencyResponse`.

The frequency response and its helpers live in :mod:`gpmultirate.responses`;
this module re-exports them, warns when it is imported and is removed in
gpmultirate 0.2.0.
"""

from gpmultirate.deprecation import deprecated_module
from gpmultirate.responses import (
    FrequencyResponse,
    check_frequencies,
    default_frequencies,
    dft_matrix,
)

__all__ = ["FrequencyResponse", "check_frequencies", "default_frequencies", "dft_matrix"]

deprecated_module("gpmultirate.frequency", "gpmultirate.responses")
