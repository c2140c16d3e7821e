"""The prior an experiment is designed for: a kernel with fixed hyperparameters, in data units.

A design needs what a fit with fixed hyperparameters needs and nothing that
depends on the output: the kernel over lag, the FIR order ``P``, the white
noise variance ``gamma``, the fast sample time ``T`` and how the sensor reads
(exposure, latency, initial conditions).  :func:`design_prior` takes them
from a fitted :class:`~gpmultirate.FIRGaussianProcess` (its ``kernel_``,
``noise_level_``, ``noise_kernel_``, order and sample time: a pilot
experiment) or from a kernel with ``order=`` and ``sample_time=``.

Units: ``kernel_`` and ``noise_level_`` of a fit are in the data's units, so
the band predicted for an input ``u`` in the user's units is the band of
``FIRGaussianProcess(kernel_, noise_level=noise_level_, optimizer=None)``
fitted to ``u`` and any output, in the same units.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, replace

from sklearn.gaussian_process.kernels import Kernel

from gpmultirate.units import duration_in_fast_periods
from gpmultirate.validation import check_int, check_positive, check_sample_time

__all__ = ["DEFAULT_NOISE_LEVEL", "DesignPrior", "design_prior"]

#: the white noise variance of a design for a kernel prior, when none is given
DEFAULT_NOISE_LEVEL = 1e-4


@dataclass(frozen=True)
class DesignPrior:
    """A Gaussian-process prior with fixed hyperparameters, and the sensor it is read through.

    Attributes
    ----------
    kernel : sklearn Kernel
        Covariance of ``g(t)`` over lag in fast samples, in the data's units.
    order : int
        FIR order ``P``.
    noise_level : float
        White noise variance ``gamma`` of each slow sample, in the output's units squared.
    sample_time : float
        Fast sample time ``T`` in seconds (1.0: frequencies in cycles per sample).
    noise_kernel : "white" or sklearn Kernel
        The noise of the slow samples (a pilot fit's ``noise_kernel_``).
    exposure, latency : float
        How readings at their own instants are taken, in fast sample periods.
    initial_conditions : str
        ``"zero"`` (the paper's case), ``"discard"`` or ``"periodic"``.
    reference : FIRGaussianProcess or None
        The pilot model, whose FRF is the reference of relative (dB) targets.
    """

    kernel: Kernel
    order: int
    noise_level: float
    sample_time: float = 1.0
    noise_kernel: object = "white"
    exposure: float = 0.0
    latency: float = 0.0
    initial_conditions: str = "zero"
    reference: object = None

    def with_noise_level(self, noise_level) -> "DesignPrior":
        """This prior with another noise variance (None keeps it)."""
        if noise_level is None:
            return self
        return replace(self, noise_level=check_positive(noise_level, "noise_level"))


def design_prior(prior, *, order=None, sample_time=None, noise_level=None) -> DesignPrior:
    """The :class:`DesignPrior` of a fitted model or of a kernel with fixed hyperparameters.

    Parameters
    ----------
    prior : FIRGaussianProcess (fitted), sklearn Kernel or DesignPrior
        A fitted model gives its tuned kernel, order, noise (level and
        kernel), sample time, exposure, latency and initial conditions; a
        kernel needs ``order``.
    order : int, optional
        FIR order ``P``: required with a kernel; with a model, a different
        order than its own is refused.
    sample_time : float, optional
        Fast sample time in seconds; default the model's, or 1.0 for a kernel.
    noise_level : float, optional
        White noise variance of a slow sample in the output's units squared;
        default the model's ``noise_level_``, or :data:`DEFAULT_NOISE_LEVEL`
        (``1e-4``) for a kernel.

    Returns
    -------
    DesignPrior

    Examples
    --------
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate.kernels import DC
    >>> prior = design_prior(C(1.0) * DC(0.9, 0.5), order=40, sample_time=0.01)
    >>> prior.order, prior.noise_level, prior.sample_time
    (40, 0.0001, 0.01)
    """
    if isinstance(prior, DesignPrior):
        return prior.with_noise_level(noise_level)
    if isinstance(prior, Kernel):
        if order is None:
            raise ValueError("order must be given with a kernel prior (the FIR order P)")
        return DesignPrior(
            kernel=prior,
            order=check_int(order, "order", low=1),
            noise_level=check_positive(
                DEFAULT_NOISE_LEVEL if noise_level is None else noise_level, "noise_level"),
            sample_time=check_sample_time(1.0 if sample_time is None else sample_time),
        )
    if not (hasattr(prior, "kernel_") and hasattr(prior, "noise_level_")
            and hasattr(prior, "observation_")):
        raise ValueError(
            "prior must be a fitted FIRGaussianProcess or a scikit-learn kernel with fixed "
            f"hyperparameters; got {type(prior).__name__}")
    if getattr(prior, "n_inputs_", 1) != 1:
        raise ValueError(f"prior must be a model of one input; got {prior.n_inputs_} inputs")
    if getattr(prior, "hyperparameter_units_", "data") != "data":
        raise ValueError(
            "prior holds its hyperparameters in normalized units (hyperparameter_units_="
            "'normalized'): rescale the data to moderate magnitudes and fit it again")
    own_order = int(prior.observation_.order)
    if order is not None and check_int(order, "order", low=1) != own_order:
        raise ValueError(f"order must be the model's own ({own_order}) or None; got {order}")
    noise = prior.noise_level_ if noise_level is None else noise_level
    if isinstance(noise, bool) or not isinstance(noise, numbers.Real):
        raise ValueError(f"noise_level must be a positive number; got {noise!r}")
    return DesignPrior(
        kernel=prior.kernel_,
        order=own_order,
        noise_level=check_positive(noise, "noise_level"),
        sample_time=check_sample_time(prior.sample_time if sample_time is None else sample_time),
        noise_kernel=getattr(prior, "noise_kernel_", "white"),
        # the model's exposure and latency are in the units of its sample_time
        exposure=duration_in_fast_periods(float(getattr(prior, "exposure", 0.0)),
                                          prior.sample_time or 1.0),
        latency=duration_in_fast_periods(float(getattr(prior, "latency", 0.0)),
                                         prior.sample_time or 1.0),
        initial_conditions=getattr(prior, "initial_conditions", "zero"),
        reference=prior,
    )
