"""Observation operators: how the slow data see the FIR coefficients.

See :mod:`gpmultirate.observations.base` for the interface shared by the
family; :class:`DownsampledConvolution` is the paper's eq. (8) and
:class:`ReducedObservation` the triangular factor of a long record;
:class:`FilteredConvolution` reads the output through a sensor's known
first-order response;
:class:`SampledConvolution` observes any instants, several inputs and
periodic or unknown initial conditions, and :class:`RecordStack` stacks
several records; :class:`WhitenedObservation` is an observation seen through a
fixed noise covariance (white noise in its coordinates).
"""

from gpmultirate.observations.base import ColumnBlock, Observation, UniformSampling
from gpmultirate.observations.convolution import (
    DownsampledConvolution,
    convolution_matrix,
    regressor_rows,
)
from gpmultirate.observations.experiment import Experiment, build_experiment
from gpmultirate.observations.filtered import FilteredConvolution
from gpmultirate.observations.reduced import ReducedObservation, reduce_observation
from gpmultirate.observations.sampled import (
    INITIAL_CONDITIONS,
    RecordStack,
    SampledConvolution,
    check_initial_conditions,
)
from gpmultirate.observations.interpolated import InterpolatedConvolution, interpolation_error
from gpmultirate.observations.timed import TimedConvolution
from gpmultirate.observations.whitened import WhitenedObservation

__all__ = [
    "INITIAL_CONDITIONS",
    "ColumnBlock",
    "DownsampledConvolution",
    "Experiment",
    "FilteredConvolution",
    "InterpolatedConvolution",
    "Observation",
    "RecordStack",
    "ReducedObservation",
    "SampledConvolution",
    "TimedConvolution",
    "WhitenedObservation",
    "UniformSampling",
    "build_experiment",
    "check_initial_conditions",
    "reduce_observation",
    "convolution_matrix",
    "interpolation_error",
    "regressor_rows",
]
