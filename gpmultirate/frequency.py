"""Former home of :class:`~gpmultirate.responses.FrequencyResponse`.

The frequency response and its helpers now live in
:mod:`gpmultirate.responses`; this module re-exports them so that existing
imports keep working.
"""

from gpmultirate.responses import (
    FrequencyResponse,
    check_frequencies,
    default_frequencies,
    dft_matrix,
)

__all__ = ["FrequencyResponse", "check_frequencies", "default_frequencies", "dft_matrix"]
