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

from importlib import import_module

# the public names, by the module that defines them (loaded on first use, so that
# the command line's parser needs none of them)
_EXPORTS = {
    "band_decibels": "gpmultirate.design.bands",
    "band_radius": "gpmultirate.design.bands",
    "Confounding": "gpmultirate.design.confounding",
    "alias_frequency": "gpmultirate.design.confounding",
    "confounded_frequencies": "gpmultirate.design.confounding",
    "predicted_frequency_response": "gpmultirate.design.predicted",
    "predicted_impulse_response": "gpmultirate.design.predicted",
    "predicted_posterior": "gpmultirate.design.predicted",
    "BandCriterion": "gpmultirate.design.criterion",
    "RecordLength": "gpmultirate.design.length",
    "required_length": "gpmultirate.design.length",
    "MultisineDesign": "gpmultirate.design.multisine",
    "design_multisine": "gpmultirate.design.multisine",
    "flat_multisine": "gpmultirate.design.multisine",
    "DesignPrior": "gpmultirate.design.prior",
    "design_prior": "gpmultirate.design.prior",
    "SamplingScheme": "gpmultirate.design.sampling",
    "SamplingComparison": "gpmultirate.design.schemes",
    "compare_sampling": "gpmultirate.design.schemes",
}

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


def __getattr__(name):
    if name not in _EXPORTS:
        raise AttributeError(f"module 'gpmultirate.design' has no attribute {name!r}")
    value = getattr(import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted({*globals(), *_EXPORTS})
