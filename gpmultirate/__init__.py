"""Fast-rate impulse-response identification from slow-rate output measurements.

The FIR impulse response is a Gaussian process over continuous lag, observed
through a downsampled convolution with the known fast-rate input.  See
:class:`FIRGaussianProcess` for the estimator and :mod:`gpmultirate.kernels`
for the prior covariances.

The package loads its parts when they are first used (``gm.FIRGaussianProcess``,
``from gpmultirate import kernels``), so that ``gpmultirate --help`` and a
Ctrl-C at the command's start do not wait for numpy, SciPy and scikit-learn.
"""

from importlib import import_module

from gpmultirate.version import __version__

# the public names, by the module that defines them
_EXPORTS = {
    "FIRGaussianProcess": "gpmultirate.estimators",
    "LeastSquaresFIR": "gpmultirate.estimators",
    "FeedbackWarning": "gpmultirate.exceptions",
    "HeldOutWarning": "gpmultirate.exceptions",
    "IdentifiabilityError": "gpmultirate.exceptions",
    "MisspecificationWarning": "gpmultirate.exceptions",
    "ModelFileError": "gpmultirate.exceptions",
    "NumericalWarning": "gpmultirate.exceptions",
    "OrderWarning": "gpmultirate.exceptions",
    "FrequencyResponse": "gpmultirate.responses",
    "fit_percent": "gpmultirate.metrics",
    "goodness_of_fit": "gpmultirate.metrics",
    "MultiOutputFIR": "gpmultirate.multioutput",
    "ObservedKernel": "gpmultirate.observed",
    "DownsampledConvolution": "gpmultirate.observations",
    "InterpolatedConvolution": "gpmultirate.observations",
    "SampledConvolution": "gpmultirate.observations",
    "TimedConvolution": "gpmultirate.observations",
    "load_model": "gpmultirate.persistence",
    "save_model": "gpmultirate.persistence",
}
# the subpackages and modules reached as attributes of the package
_SUBMODULES = ("datasets", "design", "holdout", "kernels", "simulation", "plotting")

__all__ = sorted([*_EXPORTS, "__version__"], key=str.lower)


def __getattr__(name):
    if name in _EXPORTS:
        value = getattr(import_module(_EXPORTS[name]), name)
    elif name in _SUBMODULES:
        value = import_module(f"gpmultirate.{name}")
    else:
        raise AttributeError(f"module 'gpmultirate' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__():
    return sorted({*globals(), *_EXPORTS, *_SUBMODULES})
