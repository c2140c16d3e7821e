"""Deprecated: the former home of the downsampled convolution of eq. (8).

Import :class:`~gpmultirate.observations.DownsampledConvolution` and
:func:`~gpmultirate.observations.convolution.convolution_matrix` from
:mod:`gpmultirate.observations`; this module warns when it is imported and is
removed in gpmultirate 0.2.0.
"""

from gpmultirate.deprecation import deprecated_module
from gpmultirate.observations.convolution import DownsampledConvolution, convolution_matrix

__all__ = ["DownsampledConvolution", "convolution_matrix"]

deprecated_module("gpmultirate.operator", "gpmultirate.observations")
