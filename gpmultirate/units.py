"""Scale-free numerics: the estimators work on data divided by exact powers of two.

A fit squares its data (variances, Gram matrices, the starting values and
bounds of the hyperparameters), so data of magnitude ``1e160`` or ``1e-160``
overflow or underflow although every result the user asks for is a
representable number.  :func:`normalize` divides each input ``u_k`` by
``2**e_k`` and the output by ``2**e_y``, with ``e`` the binary exponent of the
largest finite magnitude (after the division the largest magnitude lies in
``[0.5, 1)``).  A division by a power of two is exact, so the normalized
problem is the user's problem in other units, with no rounding at all, and
the model's numbers in the user's units follow exactly: the coefficients of
input ``k`` are ``2**(e_y - e_k)`` times the normalized ones, their variances
``4**(e_y - e_k)`` times, the noise variance ``4**e_y`` times, and the log
marginal likelihood is shifted by the Jacobian ``-M e_y log 2`` (``M`` used
slow samples).  Standard deviations are formed in normalized units and then
scaled, so they stay finite whenever they are representable, even where the
variance in the user's units is not.

Examples
--------
>>> import numpy as np
>>> u = np.array([3.0, -1.0, 2.0])
>>> u_n, y_n, scale = normalize(u, np.array([1e200, 2e200]))
>>> u_n, scale.input_exponents, scale.output_exponent
(array([ 0.75, -0.25,  0.5 ]), array([2]), 666)
>>> float(np.ldexp(y_n[1], scale.output_exponent)) == 2e200
True

Times are the other unit of the user's: with ``sample_time`` given, the
stamps of readings (``sample_times``), ``exposure`` and ``latency`` are in
its units (seconds), and :func:`in_fast_periods` and
:func:`duration_in_fast_periods` carry them into the fast sample periods the
observations work in (one place for every entry point: ``fit``,
``predict``, ``analyze_residuals``, the plots and the command line).
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from gpmultirate.exceptions import NumericalWarning
from gpmultirate.inference import (
    DataSpacePosterior,
    GaussianCoefficients,
    ParameterSpacePosterior,
    PrecisionPosterior,
)

__all__ = ["DataScale", "ScaledCoefficients", "duration_in_fast_periods", "in_fast_periods",
           "normalize"]

_TINY = np.finfo(float).tiny


@dataclasses.dataclass(frozen=True)
class DataScale:
    """The powers of two a fit divided its data by: ``u_k / 2**e_k`` and ``y / 2**e_y``.

    Attributes
    ----------
    input_exponents : ndarray of int, shape (n_inputs,)
    output_exponent : int
    """

    input_exponents: np.ndarray
    output_exponent: int

    @property
    def identity(self) -> bool:
        """True when nothing was divided (every exponent 0)."""
        return self.output_exponent == 0 and not np.any(self.input_exponents)

    @property
    def gain_exponents(self) -> np.ndarray:
        """``e_y - e_k``: the coefficients of input ``k`` are ``2**(e_y - e_k)`` times the normalized."""
        return self.output_exponent - self.input_exponents

    def coefficient_exponents(self, order: int) -> np.ndarray:
        """The exponent of each input-major coefficient ``(n_inputs * order,)``."""
        return np.repeat(self.gain_exponents, order)

    def kernel(self, kernel, to_data: bool = True):
        """``kernel`` in the data's units (``to_data``) or in normalized units, or None.

        None when an amplitude or a bound would not be a finite positive
        normal float in the target units.
        """
        from gpmultirate.kernels import input_kernels, like_inputs, rescaled

        sign = 2 if to_data else -2
        parts = []
        for part, e in zip(input_kernels(kernel), self.gain_exponents):
            with np.errstate(over="ignore"):
                factor = float(np.ldexp(1.0, sign * int(e)))
            if factor == 1.0:
                parts.append(part)
                continue
            if not _TINY <= factor < np.inf:
                return None
            parts.append(_rescaled(part, factor, rescaled))
        out = like_inputs(parts, kernel)
        try:
            theta, bounds = out.theta, out.bounds
        except ValueError:  # a value the fit's own checks refuse, with their message
            return out
        if not (np.all(np.isfinite(theta)) and np.all(np.isfinite(bounds))
                and np.all(np.exp(bounds) >= _TINY) and np.all(np.exp(theta) >= _TINY)):
            return None
        return out

    def variance(self, value: float, to_data: bool = True) -> float:
        """A noise variance in the data's units or in normalized units."""
        sign = 2 if to_data else -2
        with np.errstate(over="ignore"):
            return float(np.ldexp(value, sign * self.output_exponent))

    def log_density_shift(self, n_samples: int) -> float:
        """What converts a log density of ``n_samples`` normalized outputs to the data's units."""
        return -n_samples * self.output_exponent * math.log(2.0)


def _rescaled(kernel, factor: float, rescaled):
    """``rescaled(kernel, factor)``, folding the factor into a fixed constant in front.

    A kernel with no amplitude that scales it whole is wrapped as
    ``ConstantKernel(factor, "fixed") * kernel``; a kernel already so wrapped
    has its constant multiplied (exact for powers of two), so that going to
    the normalized units and back (a model file loaded) gives the same kernel.
    """
    from sklearn.base import clone
    from sklearn.gaussian_process.kernels import ConstantKernel, Product

    if (isinstance(kernel, Product) and isinstance(kernel.k1, ConstantKernel)
            and isinstance(kernel.k1.constant_value_bounds, str)
            and kernel.k1.constant_value_bounds == "fixed"):
        value = kernel.k1.constant_value * factor
        if value == 1.0:
            return clone(kernel.k2)
        return ConstantKernel(value, "fixed") * clone(kernel.k2)
    return rescaled(kernel, factor)


IDENTITY = DataScale(np.zeros(1, dtype=int), 0)

# binary exponents up to which a least-squares model is kept in the data's units
# (products of data, coefficients and covariances stay within 2**+-1000)
SAFE_EXPONENT = 240


def _exponent(values: np.ndarray, name: str) -> int:
    """The binary exponent of the largest finite magnitude of ``values`` (0 if none)."""
    finite = np.abs(values[np.isfinite(values)])
    largest = float(finite.max()) if finite.size else 0.0
    if largest == 0.0:
        return 0
    if largest < _TINY:
        raise ValueError(
            f"{name} is subnormal: its largest magnitude {largest:.3g} is below the smallest "
            f"normal float {_TINY:.3g}, where its digits are lost; express {name} in smaller units"
        )
    return int(np.frexp(largest)[1])


def _as_float(x):
    """``x`` as a float array, or None when it is no array of real numbers (checked later)."""
    if isinstance(x, (str, bytes, dict)) or x is None:
        return None
    try:
        arr = np.asarray(x)
    except (TypeError, ValueError):
        return None
    if arr.dtype.kind not in "iuf" or arr.size == 0:
        return None
    return np.array(arr, dtype=float)


def normalize(u, y_slow):
    """``(u, y_slow, scale)``: the data divided by exact powers of two of their magnitude.

    ``u`` (each input separately, over all records) and ``y_slow`` are
    divided by ``2**e`` with ``e`` the binary exponent of their largest
    finite magnitude.  Records stay records (the rule of
    :func:`~gpmultirate.observations.experiment.is_record_pair`); data that
    are not arrays of real numbers are returned unchanged with no scale, for
    the checks of the fit to name.

    Raises
    ------
    ValueError
        If ``u`` or ``y_slow`` is subnormal (its largest magnitude below
        ``2.2e-308``), or an input of ``u`` is zero at every sample.
    """
    from gpmultirate.observations.experiment import records_of

    several = records_of(u, y_slow)
    us = list(u) if several else [u]
    ys = list(y_slow) if several else [y_slow]
    u_arrays = [_as_float(x) for x in us]
    y_arrays = [_as_float(y) for y in ys]
    if any(x is None or x.ndim not in (1, 2) for x in u_arrays) or any(
        y is None for y in y_arrays
    ):
        return u, y_slow, IDENTITY
    columns = [x[:, None] if x.ndim == 1 else x for x in u_arrays]
    if len({c.shape[1] for c in columns}) != 1:
        return u, y_slow, IDENTITY
    stacked = np.vstack(columns)
    n_inputs = stacked.shape[1]
    if not np.all(np.isfinite(stacked)):
        return u, y_slow, IDENTITY  # refused by the checks of the fit
    input_exponents = []
    for k in range(n_inputs):
        label = "u" if n_inputs == 1 else f"u[:, {k}]"
        if not np.any(stacked[:, k]):
            raise ValueError(
                f"{label} is zero at every sample: an input that never moves carries no "
                "information about its impulse response; remove it or give a record that excites it"
            )
        input_exponents.append(_exponent(stacked[:, k], label))
    output_exponent = _exponent(np.concatenate([y.reshape(-1) for y in y_arrays]), "y_slow")
    scale = DataScale(np.array(input_exponents, dtype=int), output_exponent)
    if scale.identity:
        return u, y_slow, IDENTITY if n_inputs == 1 else scale
    exps = scale.input_exponents
    u_n = [np.ldexp(x, -exps if x.ndim == 2 else -int(exps[0])) for x in u_arrays]
    y_n = [np.ldexp(y, -output_exponent) for y in y_arrays]
    if several:
        return u_n, y_n, scale
    return u_n[0], y_n[0], scale


def _coefficients_in_data_units(coef: np.ndarray, exponents: np.ndarray) -> np.ndarray:
    """``coef * 2**exponents``; a ``ValueError`` where that is beyond the float range."""
    with np.errstate(over="ignore"):
        scaled = np.ldexp(coef, exponents)
    if np.all(np.isfinite(scaled)):
        return scaled
    with np.errstate(divide="ignore"):
        decades = np.log10(np.abs(coef)) + exponents * math.log10(2.0)
    raise ValueError(
        "the impulse response in the data's units is beyond the float range (coefficients "
        f"near 1e{int(np.floor(np.max(decades)))}, the largest float is 1.8e308): the units "
        "of y_slow per unit of u are too large; give u or y_slow in other units (for "
        "instance y_slow divided by a power of ten) and fit again")


class ScaledCoefficients(GaussianCoefficients):
    """The Gaussian coefficients of a normalized fit, in the data's units.

    :attr:`coef`, :meth:`linear_map`, :meth:`pair_variances` and
    :meth:`covariance` are in the data's units (variances that exceed the
    float range are ``inf``); :attr:`normalized` is the posterior of the
    normalized problem, which the estimators use to form standard
    deviations before scaling them.

    Parameters
    ----------
    normalized : GaussianCoefficients
    scale : DataScale
    order : int
    """

    def __init__(self, normalized, scale: DataScale, order: int):
        self.normalized = normalized
        self.scale = scale
        self.exponents = scale.coefficient_exponents(order)
        GaussianCoefficients.__init__(self, _coefficients_in_data_units(
            normalized.coef, self.exponents), None, None)
        self.log_marginal_likelihood = getattr(normalized, "log_marginal_likelihood", None)

    def _columns(self, A):
        return None if A is None else np.ldexp(A, self.exponents[None, :])

    def linear_map(self, A: np.ndarray, full_cov: bool = False):
        with np.errstate(over="ignore"):
            return self.normalized.linear_map(self._columns(A), full_cov)

    def pair_variances(self, A1: np.ndarray, A2: np.ndarray | None):
        with np.errstate(over="ignore"):
            return self.normalized.pair_variances(self._columns(A1), self._columns(A2))

    def covariance(self) -> np.ndarray:
        e = self.exponents
        with np.errstate(over="ignore"):
            return np.ldexp(self.normalized.covariance(), e[:, None] + e[None, :])

    def times_root(self, A: np.ndarray) -> np.ndarray:
        raise NotImplementedError("use linear_map or pair_variances")

    def innovations(self, y: np.ndarray) -> np.ndarray | None:
        """The normalized fit's innovations of ``y`` in the data's units: the same numbers
        (``y`` and the covariance's factor both scale by ``2**e_y``)."""
        return self.normalized.innovations(
            np.ldexp(np.asarray(y, dtype=float), -self.scale.output_exponent))

    def _lag_exponents(self, X: np.ndarray) -> np.ndarray:
        """The exponent of ``g`` at each kernel input (a lag, or an ``(input, lag)`` pair)."""
        gains = self.scale.gain_exponents
        if X.shape[1] > 1:
            return gains[X[:, 0].astype(int)]
        return np.full(X.shape[0], int(gains[0]))

    def mean_at_lags(self, X: np.ndarray) -> np.ndarray:
        """Posterior mean of ``g`` at the kernel inputs ``X``, in the data's units."""
        return np.ldexp(self.normalized.mean_at_lags(X), self._lag_exponents(X))

    def at_lags(self, X: np.ndarray, full_cov: bool = False):
        """Posterior mean and variance (or covariance) of ``g(X)`` in the data's units
        (``inf`` where a variance exceeds the float range)."""
        mean, second = self.normalized.at_lags(X, full_cov=full_cov)
        e = self._lag_exponents(X)
        with np.errstate(over="ignore"):
            if full_cov:
                return np.ldexp(mean, e), np.ldexp(second, e[:, None] + e[None, :])
            return np.ldexp(mean, e), np.ldexp(second, 2 * e)


class _ScaledDataSpace(ScaledCoefficients, DataSpacePosterior):
    """A :class:`ScaledCoefficients` of a :class:`~gpmultirate.inference.DataSpacePosterior`."""


class _ScaledParameterSpace(ScaledCoefficients, ParameterSpacePosterior):
    """A :class:`ScaledCoefficients` of a :class:`~gpmultirate.inference.ParameterSpacePosterior`."""


class _ScaledPrecision(ScaledCoefficients, PrecisionPosterior):
    """A :class:`ScaledCoefficients` of a :class:`~gpmultirate.inference.PrecisionPosterior`."""


def scaled(normalized, scale: DataScale, order: int) -> ScaledCoefficients:
    """``normalized`` in the data's units, still an instance of its route's class."""
    for route, cls in ((PrecisionPosterior, _ScaledPrecision),
                       (ParameterSpacePosterior, _ScaledParameterSpace),
                       (DataSpacePosterior, _ScaledDataSpace)):
        if isinstance(normalized, route):
            return cls(normalized, scale, order)
    return ScaledCoefficients(normalized, scale, order)


def split(posterior):
    """``(normalized posterior, DataScale)`` of a fitted model's ``posterior_``."""
    if isinstance(posterior, ScaledCoefficients):
        return posterior.normalized, posterior.scale
    return posterior, None


def scaled_moments(mean, second, exponents, kind):
    """Mean and std (``kind="std"``, from a variance) or covariance in the data's units."""
    mean = np.ldexp(mean, exponents)
    if kind == "std":
        return mean, np.ldexp(np.sqrt(np.maximum(second, 0.0)), exponents)
    with np.errstate(over="ignore"):
        return mean, np.ldexp(second, exponents[:, None] + exponents[None, :])


def scale_frequency_response(frf, exponent: int):
    """A :class:`~gpmultirate.responses.FrequencyResponse` of ``2**exponent`` times the FRF."""
    if exponent == 0:
        return frf
    mean = np.ldexp(frf.mean.real, exponent) + 1j * np.ldexp(frf.mean.imag, exponent)
    return dataclasses.replace(
        frf, mean=mean,
        magnitude_lower=np.ldexp(frf.magnitude_lower, exponent),
        magnitude_upper=np.ldexp(frf.magnitude_upper, exponent),
        real_std=np.ldexp(frf.real_std, exponent),
        imag_std=np.ldexp(frf.imag_std, exponent),
    )


def to_normalized(kernel, noise: float, noise_bounds, scale: DataScale):
    """A kernel, noise level and noise bounds given in the data's units, in normalized units."""
    if scale is None or scale.identity:
        return kernel, noise, noise_bounds
    converted = None if kernel is None else scale.kernel(kernel, to_data=False)
    if kernel is not None and converted is None:
        raise ValueError(
            "kernel: its amplitudes or their bounds, given in the data's units, leave the float "
            "range once the data are normalized; use normalize=True with an optimizer so that "
            "they are read in normalized units"
        )
    noise = scale.variance(noise, to_data=False)
    if not isinstance(noise_bounds, str):
        noise_bounds = tuple(scale.variance(b, to_data=False) for b in noise_bounds)
    if not (_TINY <= noise < np.inf):
        raise ValueError(
            "noise_level: given in the data's units, it leaves the float range once the data "
            "are normalized; use normalize=True so that it is read in normalized units"
        )
    return converted, noise, noise_bounds


def scaled_noise_kernel(kernel, factor: float):
    """A noise kernel over the instants whose covariance is ``factor`` times larger.

    The variances of its summands are multiplied, bounds included: a
    ``WhiteKernel``'s level, a ``ConstantKernel``'s value, or the constant of
    a product with one; any other summand is wrapped as
    ``ConstantKernel(factor, "fixed") * summand``.  Exact for powers of two.

    Examples
    --------
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C, Matern, WhiteKernel
    >>> scaled_noise_kernel(WhiteKernel(0.5) + C(2.0) * Matern(10.0, nu=1.5), 4.0)
    WhiteKernel(noise_level=2) + 2.83**2 * Matern(length_scale=10, nu=1.5)
    """
    from sklearn.base import clone
    from sklearn.gaussian_process.kernels import ConstantKernel, Product, Sum, WhiteKernel

    def times(value, bounds):
        if isinstance(bounds, str):
            return value * factor, bounds
        return value * factor, (bounds[0] * factor, bounds[1] * factor)

    if isinstance(kernel, Sum):
        return Sum(scaled_noise_kernel(kernel.k1, factor), scaled_noise_kernel(kernel.k2, factor))
    if isinstance(kernel, WhiteKernel):
        level, bounds = times(kernel.noise_level, kernel.noise_level_bounds)
        return WhiteKernel(level, bounds)
    if isinstance(kernel, ConstantKernel):
        value, bounds = times(kernel.constant_value, kernel.constant_value_bounds)
        return ConstantKernel(value, bounds)
    if isinstance(kernel, Product):
        if isinstance(kernel.k1, ConstantKernel):
            return Product(scaled_noise_kernel(kernel.k1, factor), clone(kernel.k2))
        if isinstance(kernel.k2, ConstantKernel):
            return Product(clone(kernel.k1), scaled_noise_kernel(kernel.k2, factor))
    return ConstantKernel(float(factor), "fixed") * clone(kernel)


def rescale_gaussian_process(model, scale: DataScale, rebuild) -> None:
    """Carry a fit on normalized data into the data's units (every public attribute).

    ``rebuild()`` gives the experiment of the user's data at the fitted
    order: ``observation_`` and ``y_slow_`` are those of the user's data.
    ``kernel_`` and ``noise_level_`` are in the data's units where they are
    finite positive normal floats; otherwise they stay in normalized units,
    ``hyperparameter_units_`` says ``"normalized"`` and a
    :class:`~gpmultirate.NumericalWarning` says why.
    """
    model.input_scale_ = np.ldexp(1.0, scale.input_exponents)
    model.output_scale_ = float(np.ldexp(1.0, scale.output_exponent))
    model.hyperparameter_units_ = "data"
    if scale.identity:
        return
    order = model.observation_.order
    model.posterior_ = scaled(model.posterior_, scale, order)
    model.coef_ = model._shaped(model.posterior_.coef)
    M = model.y_slow_.shape[0]
    shift = scale.log_density_shift(M)
    model.log_marginal_likelihood_value_ = model.log_marginal_likelihood_value_ + shift
    if hasattr(model, "cv_log_predictive_likelihood_"):
        model.cv_log_predictive_likelihood_ = model.cv_log_predictive_likelihood_ + shift
    selection = getattr(model, "order_selection_", None)
    if selection is not None and selection["criterion"] in ("log_evidence", "cv_log_predictive"):
        selection["score"] = selection["score"] + scale.log_density_shift(1)
    kernel = scale.kernel(model.kernel_)
    noise = scale.variance(model.noise_level_)
    bounds = model.noise_level_bounds_
    if not isinstance(bounds, str):
        bounds = tuple(scale.variance(b) for b in bounds)
    representable = kernel is not None and all(
        _TINY <= v < np.inf for v in ((noise,) + (() if isinstance(bounds, str) else bounds))
    )
    if representable:
        model.kernel_, model.noise_level_, model.noise_level_bounds_ = kernel, noise, bounds
        noise_kernel = getattr(model, "noise_kernel_", "white")
        if not isinstance(noise_kernel, str):  # a disturbance: its variances in the data's units
            model.noise_kernel_ = scaled_noise_kernel(noise_kernel, scale.variance(1.0))
    else:
        model.hyperparameter_units_ = "normalized"
        warnings.warn(
            "kernel_ and noise_level_ are in normalized units (u divided by input_scale_, "
            "y_slow by output_scale_): in the data's units an amplitude or the noise variance "
            "is beyond the float range. Every other result is in the data's units.",
            NumericalWarning,
            stacklevel=3,
        )
    experiment = rebuild()
    model.observation_ = experiment.observation
    model.y_slow_ = experiment.y


def rescale_least_squares(model, scale: DataScale, rebuild) -> None:
    """Carry a least-squares fit on normalized data into the data's units.

    Where every exponent is moderate (``|e| <= SAFE_EXPONENT``) the
    distribution is kept in the data's units as a plain
    :class:`~gpmultirate.inference.GaussianCoefficients` (its products are
    then the exact scalings of the normalized ones); beyond, it is a
    :class:`ScaledCoefficients`, and ``noise_variance_`` and
    ``coef_covariance_`` are ``inf`` where they exceed the float range while
    the standard deviations of ``impulse_response`` and ``predict``, formed
    before scaling, stay finite.
    """
    if scale.identity:
        return
    exponents = np.concatenate([scale.input_exponents, scale.gain_exponents,
                                [scale.output_exponent]])
    normalized = model.posterior_
    scaled = ScaledCoefficients(normalized, scale, model.observation_.order)
    model.coef_ = model._shaped(scaled.coef)
    with np.errstate(over="ignore"):
        model.noise_variance_ = scale.variance(model.noise_variance_)
    model.coef_covariance_ = scaled.covariance()
    if np.all(np.abs(exponents) <= SAFE_EXPONENT):
        model.posterior_ = GaussianCoefficients(
            scaled.coef, model.coef_covariance_, np.zeros((0, scaled.coef.shape[0])))
    else:
        model.posterior_ = scaled
    model.observation_ = rebuild().observation


def evidence_in_data_units(evidence, scale):
    """The normalized ``evidence`` at its kernel and noise level in the data's units, for the
    messages that name their values (the normalized one where they are not representable).
    A disturbance's variances (and their bounds) are scaled as the output's
    (:func:`scaled_noise_kernel`); its time scales do not depend on the units."""
    if scale is None or scale.identity:
        return evidence
    kernel = scale.kernel(evidence.kernel)
    if not evidence.noise.white:
        noise_kernel = getattr(evidence.noise, "kernel", None)
        if kernel is None or noise_kernel is None:
            return evidence
        from gpmultirate.noise import KernelNoise

        noise = KernelNoise(scaled_noise_kernel(noise_kernel, scale.variance(1.0)),
                            evidence.noise.instants)
        values = np.exp(np.append(kernel.bounds.ravel(), noise.bounds.ravel()))
        if not np.all((values >= _TINY) & (values < np.inf)):
            return evidence
        return evidence.moved_to(kernel, noise)
    noise = scale.variance(evidence.noise_level)
    bounds = evidence.noise_bounds
    if not isinstance(bounds, str):
        bounds = tuple(scale.variance(b) for b in bounds)
    values = (noise,) + (() if isinstance(bounds, str) else bounds)
    if kernel is None or not all(_TINY <= v < np.inf for v in values):
        return evidence
    from gpmultirate.noise import WhiteNoise

    moved = evidence.moved_to(kernel, noise)
    moved.noise = WhiteNoise(noise, bounds)
    return moved


def evidence_theta(model, theta):
    """``(normalized theta, shift)``: a ``theta`` in the data's units for the normalized evidence."""
    _, scale = split(model.posterior_)
    if scale is None or model.hyperparameter_units_ == "normalized":
        return theta, 0.0 if scale is None else scale.log_density_shift(model.y_slow_.shape[0])
    n_kernel = model.kernel_.theta.shape[0]
    kernel = scale.kernel(model.kernel_.clone_with_theta(theta[:n_kernel]), to_data=False)
    if kernel is None or kernel.theta.shape[0] != model._evidence.kernel.theta.shape[0]:
        raise ValueError("theta: its amplitudes leave the float range in normalized units")
    normalized = kernel.theta
    noise_kernel = getattr(model, "noise_kernel_", "white")
    if not isinstance(noise_kernel, str):  # a disturbance: its variances scale with the output
        noise = scaled_noise_kernel(noise_kernel.clone_with_theta(theta[n_kernel:]),
                                    scale.variance(1.0, to_data=False))
        normalized = np.append(normalized, noise.theta)
    elif theta.shape[0] > n_kernel:
        normalized = np.append(normalized, theta[-1] - 2 * scale.output_exponent * math.log(2.0))
    return normalized, scale.log_density_shift(model.y_slow_.shape[0])


# ------------------------------------------------------------------ times
#: a stamp within this relative distance of a tick after the division by
#: ``sample_time`` is the tick (the division's rounding, as in ``0.003 / 0.001``)
TICK_TOLERANCE = 1e-9
#: stamps all inside this share of the record's start, and more readings than
#: fast periods there, are taken for a unit mix-up
SQUEEZED_SHARE = 0.05


def duration_in_fast_periods(value: float, sample_time: float) -> float:
    """An ``exposure`` or ``latency`` in the units of ``sample_time``, in fast periods.

    Examples
    --------
    >>> duration_in_fast_periods(0.0025, 0.001)
    2.5
    """
    return value if sample_time == 1.0 else value / sample_time


def in_fast_periods(sample_times, sample_time: float, u=None, name: str = "sample_times",
                    readings: bool = True):
    """Stamps in the units of ``sample_time`` (seconds), in fast sample periods.

    ``stamps / sample_time``, a stamp within ``TICK_TOLERANCE`` (relative) of
    a tick being the tick (the division's rounding must not take a reading
    off its tick); a new array, the caller's is never touched.  A
    list of arrays is several records (a list back).  With the input ``u``
    of the records, stamps that cannot be in the units of ``sample_time`` are
    refused with a ``ValueError`` naming the likely mix-up: stamps squeezed
    into the first ``SQUEEZED_SHARE`` of the record with more readings than
    fast periods there (seconds given with ``sample_time`` 1; only for
    ``readings``: instants to predict at, ``readings=False``, may be a grid
    as fine as wanted), or past the record's end while they would fit it in
    fast periods.  Other checks are the observation's.

    Examples
    --------
    >>> import numpy as np
    >>> in_fast_periods([0.0025, 0.003, 0.0061], 0.001)
    array([2.5, 3. , 6.1])
    >>> in_fast_periods(np.arange(0, 0.6, 0.003), 1.0, u=np.ones(600))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: sample_times: all 200 stamps lie in [0, 0.597] fast sample periods, ... they look like seconds while sample_time is 1.0; ...
    """
    from gpmultirate.observations.experiment import is_record_list

    several = is_record_list(sample_times)
    records = list(sample_times) if several else [sample_times]
    lengths = _record_lengths(u, len(records))
    out = []
    for r, times in enumerate(records):
        raw = np.asarray(times)
        if raw.dtype.kind not in "iuf" or raw.ndim != 1 or raw.size == 0:
            out.append(times)  # the observation's checks name what is wrong
            continue
        stamps = raw.astype(float)
        periods = stamps / sample_time
        tick = np.round(periods)
        periods = np.where(np.abs(periods - tick) <= TICK_TOLERANCE * np.maximum(
            1.0, np.abs(tick)), tick, periods)
        if lengths is not None and np.all(np.isfinite(periods)):
            _check_units(stamps, periods, lengths[r], sample_time, name, readings)
        out.append(periods)
    return out if several else out[0]


def _record_lengths(u, n_records: int):
    """The fast samples of each record of ``u``, or None when they cannot be read."""
    if u is None:
        return None
    from gpmultirate.observations.experiment import is_record_list

    records = list(u) if is_record_list(u) else [u]
    if len(records) != n_records:
        return None
    try:
        lengths = [np.shape(record)[0] for record in records]
    except (IndexError, TypeError, ValueError):
        return None
    return lengths


def _check_units(stamps, periods, n_samples: int, sample_time: float, name: str,
                 readings: bool) -> None:
    """Refuse stamps that look like the other unit (seconds vs fast sample periods)."""
    last = float(periods.max())
    if (readings and n_samples > 0 and last < SQUEEZED_SHARE * n_samples
            and periods.size > max(last, 1.0)):
        raise ValueError(
            f"{name}: all {periods.size} stamps lie in [{periods.min():.3g}, {last:.3g}] fast "
            f"sample periods, the first {100 * last / n_samples:.2g} % of the record of "
            f"{n_samples} fast samples: they look like seconds while sample_time is "
            f"{sample_time!r}; give the fast sample time as sample_time (the stamps are in "
            "its units), or the stamps in fast sample periods" if sample_time == 1.0 else
            f"{name}: all {periods.size} stamps lie in [{periods.min():.3g}, {last:.3g}] fast "
            f"sample periods, the first {100 * last / n_samples:.2g} % of the record of "
            f"{n_samples} fast samples: they are not in the units of sample_time "
            f"({sample_time!r} s per fast sample); give them in seconds"
        )
    if sample_time != 1.0 and last >= n_samples and float(stamps.max()) < n_samples:
        raise ValueError(
            f"{name} are in the units of sample_time ({sample_time!r} s per fast sample): "
            f"the last stamp, {float(stamps.max()):g} s, lies past the record's end at "
            f"{n_samples * sample_time:g} s; stamps in fast sample periods are "
            "multiplied by sample_time to give seconds"
        )
