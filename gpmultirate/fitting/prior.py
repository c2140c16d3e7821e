"""The prior a fit starts from: the default prior, and the prior in the fit's units.

The default prior is ``ConstantKernel(c) * DC()`` per input, ``c`` the
output power per unit input power (the data's units), and ``DC``'s decay
bounded so that its envelope has fallen by lag ``P`` (the FIR model's own
assumption).  A user's kernel, amplitudes and noise level are read in
normalized units when tuning (``normalize=True``), in the data's units
otherwise; :func:`starting_prior` brings either into the units of the
normalized data the fit works on (:mod:`gpmultirate.units`).
"""

from __future__ import annotations

import numpy as np
from sklearn.base import clone
from sklearn.gaussian_process.kernels import ConstantKernel

from gpmultirate import units
from gpmultirate.kernels import (
    DC,
    SS,
    TC,
    PerInputKernel,
    input_kernels,
    kernel_for_inputs,
    like_inputs,
    rescaled,
)
from gpmultirate.resonances import slowest_decay
from gpmultirate.validation import check_bounds

__all__ = ["KERNEL_NAMES", "input_powers", "kernel_from_name", "input_powers_of", "prior_in_data_units", "record_inputs",
           "starting_prior"]


def _unit_scales(experiment) -> list[float]:
    """Output power per unit input power, one per input: the data's units for the prior."""
    power_y = float(np.mean(experiment.y**2)) or 1.0
    return [power_y / power for power in input_powers(experiment)]


def _initial_kernel(kernel, experiment, normalize: bool = True):
    """The prior of the fit in the data's units: the user's kernel(s), or the default.

    With ``normalize`` the user's kernel is a prior in normalized units
    (input and output divided by their RMS): each input's amplitudes and
    their bounds are multiplied by that input's unit scale
    (:func:`~gpmultirate.kernels.rescaled`).  The default kernel is
    ``ConstantKernel(c) * DC()`` with ``c`` that scale, bounds ``c * 1e-8 ..
    c * 1e8``, and ``alpha`` at most
    :func:`~gpmultirate.resonances.slowest_decay` of the order: its envelope
    falls at least by ``e^-2`` by lag ``P``.
    """
    n = experiment.n_inputs
    scales = _unit_scales(experiment)
    if kernel is not None:
        kernel = kernel_for_inputs(kernel, n)
        if not normalize:
            return kernel
        kernels = [rescaled(k, c) for k, c in zip(input_kernels(kernel), scales)]
        return like_inputs(kernels, kernel)
    # the FIR model says the response has died out by lag P: the default prior agrees
    slowest = slowest_decay(experiment.observation.order)
    kernels = [
        ConstantKernel(c, (c * 1e-8, c * 1e8))
        * DC(alpha=min(0.9, slowest), alpha_bounds=(1e-4, slowest))
        for c in scales
    ]
    return kernels[0] if n == 1 else PerInputKernel(kernels)


def _noise_bounds(noise_level_bounds, y: np.ndarray, normalize: bool):
    """The bounds of the noise variance in the data's units (``"auto"`` resolved)."""
    power = float(np.mean(y**2)) or 1.0
    if isinstance(noise_level_bounds, str) and noise_level_bounds == "auto":
        return (1e-12 * power, 10.0 * power)
    bounds = check_bounds(noise_level_bounds, "noise_level_bounds")
    if normalize and not isinstance(bounds, str):
        return (bounds[0] * power, bounds[1] * power)  # given in normalized units
    return bounds


def prior_in_data_units(kernel, experiment, noise_level: float, noise_level_bounds,
                        normalize: bool, tuned: bool):
    """The fit's starting prior and noise: the default prior and the unit normalization.

    Parameters
    ----------
    kernel : sklearn Kernel, list of them, or None
        The user's prior (None: the default ``ConstantKernel(c) * DC()`` per
        input, see :func:`_initial_kernel`).
    experiment : Experiment
        The data (observation and used slow samples).
    noise_level : float
        The noise variance as given.
    noise_level_bounds : pair of floats, "fixed" or "auto"
    normalize : bool
        Read the kernel's amplitudes, ``noise_level`` and explicit bounds in
        normalized units (input(s) and output divided by their RMS).
    tuned : bool
        Whether the noise level will be tuned (then clipped into its bounds).

    Returns
    -------
    kernel, noise_level, noise_level_bounds
        In the data's units.
    """
    y = experiment.y
    kernel = _initial_kernel(kernel, experiment, normalize)
    bounds = _noise_bounds(noise_level_bounds, y, normalize)
    if normalize:
        noise_level *= float(np.mean(y**2)) or 1.0  # given in normalized units
    if tuned and not isinstance(bounds, str):
        noise_level = float(np.clip(noise_level, *bounds))
    return kernel, noise_level, bounds


def input_powers_of(inputs) -> list[float]:
    """``mean(u_k**2)`` of each input over all records (1 for an all-zero input)."""
    stacked = np.vstack([x[:, None] if x.ndim == 1 else x for x in inputs])
    return [float(np.mean(stacked[:, k] ** 2)) or 1.0 for k in range(stacked.shape[1])]


#: the kernels named by a string: ``kernel="dc"`` (the default DC prior), ``"tc"``,
#: ``"ss"`` and ``"auto"`` (the DC prior plus the resonances found in the data)
KERNEL_NAMES = ("dc", "tc", "ss", "auto")


def kernel_from_name(name: str):
    """The kernel a name stands for, as the estimator reads it.

    ``"dc"`` is the default DC prior (``None``: its amplitude and decay
    bounds are set from the data), ``"auto"`` the resonance search
    (``"auto"``); ``"tc"`` and ``"ss"`` are ``ConstantKernel(1) * TC()``
    (``SS()``) in the estimator's normalized units, with the default
    kernel's amplitude bounds ``1e-8 .. 1e8``: the estimator scales them to
    each input's data, as it does its default DC kernel.

    Examples
    --------
    >>> kernel_from_name("dc") is None, kernel_from_name("auto")
    (True, 'auto')
    >>> kernel_from_name("tc")
    1**2 * TC(alpha=0.9)
    >>> kernel_from_name("rbf")
    Traceback (most recent call last):
    ...
    ValueError: kernel must be a scikit-learn kernel, a list of them or one of 'dc', 'tc', 'ss', 'auto'; got 'rbf'
    """
    if not isinstance(name, str) or name not in KERNEL_NAMES:
        raise ValueError("kernel must be a scikit-learn kernel, a list of them or one of "
                         f"{', '.join(repr(n) for n in KERNEL_NAMES)}; got {name!r}")
    if name in ("dc", "auto"):
        return None if name == "dc" else "auto"
    return ConstantKernel(1.0, (1e-8, 1e8)) * {"tc": TC, "ss": SS}[name]()


def input_powers(experiment) -> list[float]:
    return input_powers_of(record_inputs(experiment))


def record_inputs(experiment):
    """The inputs of every record, as ``(N, n_inputs)`` arrays."""
    out = []
    for record in experiment.observation.records:
        u = np.asarray(record.u, dtype=float)
        out.append(u[:, None] if u.ndim == 1 else u)
    return out


def starting_prior(experiment, settings, start=None):
    """The fit's starting kernel, noise level and noise bounds, in the normalized data's units.

    :func:`prior_in_data_units` of the user's kernel (``kernel="auto"``
    starts from the default prior), and a prior given in the data's units
    (no tuning, or ``normalize=False``) converted into the units of
    :func:`~gpmultirate.units.normalize` (a model file of
    ``hyperparameter_units_="normalized"`` gives it in those units already).
    ``start``: the tuned ``(kernel, noise level)`` of a plain fit at that
    order, where the tuning (or ``kernel="auto"``'s search) starts instead.
    """
    user_kernel = None if isinstance(settings.kernel, str) else settings.kernel
    kernel, noise, noise_bounds = prior_in_data_units(
        user_kernel, experiment, settings.noise_level, settings.noise_level_bounds,
        settings.normalize, settings.tuned,
    )
    if not settings.normalize and not settings.prior_in_normalized_units:
        given = user_kernel is not None
        explicit = not isinstance(settings.noise_level_bounds, str) or (
            settings.noise_level_bounds == "fixed")
        converted, noise, bounds = units.to_normalized(
            kernel if given else None, noise, noise_bounds if explicit else "fixed",
            settings.scale)
        kernel = converted if given else kernel
        noise_bounds = bounds if explicit else noise_bounds
    if start is not None:
        kernel, noise = _moved_to(kernel, start[0]), float(start[1])
    return kernel, noise, noise_bounds


def _moved_to(prior, tuned):
    """``prior`` with the values of ``tuned`` (a kernel of the same structure), keeping its bounds.

    The bounds are those of this order's prior: a start tuned at another order
    (a shorter pilot's) carries that order's bound on DC's decay, which would
    hold the tuning below the decay the longer order admits.  A kernel of
    another structure is taken as it is.
    """
    if prior.theta.shape != tuned.theta.shape:
        return clone(tuned)
    bounds = prior.bounds
    return prior.clone_with_theta(np.clip(tuned.theta, bounds[:, 0], bounds[:, 1]))
