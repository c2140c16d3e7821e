"""The parameters of a :class:`~gpmultirate.FIRGaussianProcess` fit, checked once.

:func:`check_settings` reads the estimator's constructor parameters, checks
each (as scikit-learn does, before the data are touched) and returns them as
a frozen :class:`Settings`, which every step of the fit takes as an argument.
"""

from __future__ import annotations

from dataclasses import dataclass

from gpmultirate import orders
from gpmultirate.fitting.between_ticks import check_between_ticks
from gpmultirate.fitting.disturbance import check_noise_kernel
from gpmultirate.fitting.prior import kernel_from_name
from gpmultirate.observations.sampled import check_initial_conditions
from gpmultirate.observations.timed import check_duration
from gpmultirate.units import duration_in_fast_periods
from gpmultirate.validation import (
    check_bounds,
    check_int,
    check_positive,
    check_rng,
    check_sample_time,
)

__all__ = ["Settings", "check_settings", "check_tuning"]


@dataclass(frozen=True)
class Settings:
    """The estimator's parameters, checked before the data are touched.

    The first fields are values derived from the checked parameters; the
    others (from ``kernel`` on) are the parameters as given, checked.
    """

    criterion: str
    n_folds: int
    candidates: object  # None, "auto" or a sorted list of orders
    n_restarts: int
    noise_level: float
    auto: bool
    max_resonances: int
    normalize: bool
    tuned: bool
    scale: object = None  # the DataScale of the data (units.normalize), set by fit
    noise_kernel: object = "white"
    order_from_data: bool = False  # the order is the default order's: it covers the memory
    # the fit's start is the default order's last pilot, tuned at this order or cut to it
    # (its prior negligible beyond): kernel="auto"'s search does not tune that base again
    start_tuned: bool = False
    kernel: object = None
    order: object = None
    noise_level_bounds: object = "auto"
    random_state: object = None
    sample_time: float = 1.0
    factor: int = 1
    offset: int = 0
    initial_conditions: str = "zero"
    exposure: float = 0.0  # in fast sample periods (the parameter is in sample_time's units)
    latency: float = 0.0  # in fast sample periods
    between_ticks: str = "auto"  # the route of readings between the ticks
    #: the kernel and noise level are given in the units of the normalized data
    #: (a model file of ``hyperparameter_units_="normalized"``)
    prior_in_normalized_units: bool = False


def check_tuning(tuning_criterion) -> str:
    if not isinstance(tuning_criterion, str) or tuning_criterion not in (
        "evidence", "cross_validation"
    ):
        raise ValueError(
            f"tuning must be 'evidence' or 'cross_validation'; got {tuning_criterion!r}"
        )
    return tuning_criterion


def check_settings(model, prior_in_normalized_units: bool = False) -> Settings:
    """Check every parameter of the estimator ``model``; return them as :class:`Settings`.

    ``prior_in_normalized_units``: the kernel and the noise level are in the
    units of the normalized data (a model file fitted again in those units).

    Examples
    --------
    >>> from gpmultirate import FIRGaussianProcess
    >>> check_settings(FIRGaussianProcess(factor=3, order=20)).order
    20
    >>> check_settings(FIRGaussianProcess(tuning="loo"))
    Traceback (most recent call last):
    ...
    ValueError: tuning must be 'evidence' or 'cross_validation'; got 'loo'
    """
    criterion = check_tuning(model.tuning)
    n_folds = check_int(model.cv, "cv", low=2)
    candidates = orders.order_candidates(model.order)
    if model.order is not None and candidates is None:
        check_int(model.order, "order", low=1)
    check_initial_conditions(model.initial_conditions)
    factor = check_int(model.factor, "factor", low=1)
    check_int(model.offset, "offset", low=0, high=factor - 1)
    if not (model.optimizer is None or (
        isinstance(model.optimizer, str) and model.optimizer == "marginal_likelihood"
    )):
        raise ValueError(
            f"optimizer must be 'marginal_likelihood' or None; got {model.optimizer!r}"
        )
    n_restarts = check_int(model.n_restarts_optimizer, "n_restarts_optimizer", low=0)
    check_rng(model.random_state)
    sample_time = check_sample_time(model.sample_time)
    noise = check_positive(model.noise_level, "noise_level")
    if not (isinstance(model.noise_level_bounds, str) and model.noise_level_bounds == "auto"):
        check_bounds(model.noise_level_bounds, "noise_level_bounds")
    kernel = kernel_from_name(model.kernel) if isinstance(model.kernel, str) else model.kernel
    auto = isinstance(kernel, str)  # "auto"
    max_resonances = check_int(model.max_resonances, "max_resonances", low=0)
    noise_kernel = check_noise_kernel(model.noise_kernel)
    if noise_kernel == "auto" and model.optimizer is None:
        # without an optimizer the hyperparameters are the user's and nothing is tuned
        noise_kernel = "white"
    # normalized units are a start and bounds for tuning: without tuning
    # the kernel and the noise level are used exactly as given
    normalize = bool(model.normalize) and model.optimizer is not None
    # given in the units of sample_time, observed in fast sample periods
    exposure = duration_in_fast_periods(check_duration(model.exposure, "exposure"), sample_time)
    latency = duration_in_fast_periods(check_duration(model.latency, "latency"), sample_time)
    return Settings(
        criterion, n_folds, candidates, n_restarts, noise, auto, max_resonances, normalize,
        model.optimizer is not None, noise_kernel=noise_kernel, kernel=kernel,
        order=model.order, noise_level_bounds=model.noise_level_bounds,
        random_state=model.random_state, sample_time=model.sample_time, factor=model.factor,
        offset=model.offset, initial_conditions=model.initial_conditions,
        exposure=exposure, latency=latency,
        between_ticks=check_between_ticks(getattr(model, "between_ticks", "auto")),
        prior_in_normalized_units=prior_in_normalized_units,
    )
