"""Fast-rate impulse-response identification from slow-rate output measurements.

The FIR impulse response is a Gaussian process over continuous lag, observed
through a downsampled convolution with the known fast-rate input.  See
:class:`FIRGaussianProcess` for the estimator and :mod:`gpmultirate.kernels`
for the prior covariances.
"""

from gpmultirate import datasets, holdout, kernels, simulation
from gpmultirate.version import __version__
from gpmultirate.estimators import FIRGaussianProcess, LeastSquaresFIR
from gpmultirate.exceptions import (
    FeedbackWarning,
    HeldOutWarning,
    IdentifiabilityError,
    ModelFileError,
    NumericalWarning,
    OrderWarning,
)
from gpmultirate.responses import FrequencyResponse
from gpmultirate.metrics import fit_percent, goodness_of_fit
from gpmultirate.multioutput import MultiOutputFIR
from gpmultirate.observed import ObservedKernel
from gpmultirate.observations import (
    DownsampledConvolution,
    InterpolatedConvolution,
    SampledConvolution,
    TimedConvolution,
)
from gpmultirate.persistence import load_model, save_model

__all__ = [
    "DownsampledConvolution",
    "FIRGaussianProcess",
    "FrequencyResponse",
    "IdentifiabilityError",
    "InterpolatedConvolution",
    "LeastSquaresFIR",
    "ModelFileError",
    "MultiOutputFIR",
    "NumericalWarning",
    "FeedbackWarning",
    "HeldOutWarning",
    "OrderWarning",
    "ObservedKernel",
    "SampledConvolution",
    "TimedConvolution",
    "__version__",
    "goodness_of_fit",
    "fit_percent",
    "load_model",
    "save_model",
]


def __getattr__(name):
    # gm.plotting without importing matplotlib with the package
    if name == "plotting":
        import importlib

        return importlib.import_module("gpmultirate.plotting")
    raise AttributeError(f"module 'gpmultirate' has no attribute {name!r}")
