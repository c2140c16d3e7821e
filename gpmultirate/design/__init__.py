"""Experiment design: the band before the measurement, and the input and sampling that narrow it.

For fixed hyperparameters the posterior covariance of the impulse response,
and so of the frequency response, depends on the input and on the sampling
instants, not on the output.  A prior (a pilot model, or a kernel with fixed
hyperparameters) therefore answers before any output is measured:

* :func:`predicted_frequency_response` and :func:`predicted_impulse_response`:
  the bands every record of a planned experiment will give;
* :func:`design_multisine`: multisine amplitudes that minimize the band over a
  frequency range (mean or worst case) at a given rms, and
  :func:`confounded_frequencies`: which excited frequencies the slow samples
  cannot tell apart;
* :func:`compare_sampling`: candidate sampling schemes (factor, offsets of
  several sensors, jittered instants, exposure) ranked by their bands;
* :func:`required_length`: the record length for a target band.

See :doc:`/design`.
"""

from gpmultirate.design.bands import band_decibels, band_radius
from gpmultirate.design.confounding import Confounding, alias_frequency, confounded_frequencies
from gpmultirate.design.predicted import (
    predicted_frequency_response,
    predicted_impulse_response,
    predicted_posterior,
)
from gpmultirate.design.criterion import BandCriterion
from gpmultirate.design.length import RecordLength, required_length
from gpmultirate.design.multisine import MultisineDesign, design_multisine, flat_multisine
from gpmultirate.design.prior import DesignPrior, design_prior
from gpmultirate.design.sampling import SamplingScheme
from gpmultirate.design.schemes import SamplingComparison, compare_sampling

__all__ = [
    "BandCriterion",
    "Confounding",
    "DesignPrior",
    "MultisineDesign",
    "RecordLength",
    "SamplingComparison",
    "SamplingScheme",
    "alias_frequency",
    "band_decibels",
    "band_radius",
    "compare_sampling",
    "confounded_frequencies",
    "design_multisine",
    "design_prior",
    "flat_multisine",
    "predicted_frequency_response",
    "predicted_impulse_response",
    "predicted_posterior",
    "required_length",
]
