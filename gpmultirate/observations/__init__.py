"""Observation operators: how the slow data see the FIR coefficients.

See :mod:`gpmultirate.observations.base` for the interface shared by the
family; :class:`DownsampledConvolution` is the paper's eq. (8) and
:class:`ReducedObservation` the triangular factor of a long record.
"""

from gpmultirate.observations.base import Observation, UniformSampling
from gpmultirate.observations.convolution import (
    DownsampledConvolution,
    convolution_matrix,
    regressor_rows,
)
from gpmultirate.observations.reduced import ReducedObservation

__all__ = [
    "DownsampledConvolution",
    "Observation",
    "ReducedObservation",
    "UniformSampling",
    "convolution_matrix",
    "regressor_rows",
]
