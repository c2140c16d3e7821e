"""The downsampled convolution of eq. (8); kept so that existing imports keep working.

The observation operators live in :mod:`gpmultirate.observations`.
"""

from gpmultirate.observations.convolution import DownsampledConvolution, convolution_matrix

__all__ = ["DownsampledConvolution", "convolution_matrix"]
