"""Estimators of fast-rate FIR models from slow-rate output data.

* :class:`FIRGaussianProcess`: the kernel-regularised estimate of eq. (15)
  viewed as a Gaussian-process posterior over continuous lag, with
  marginal-likelihood tuning (eq. 19, noise inside the log-determinant).
* :class:`LeastSquaresFIR`: the least-squares baseline of eq. (11), which
  refuses non-unique problems (Lemma 1 and 2).

Both take one input or several (``u`` of shape ``(N, n_inputs)``), one record
or several (lists), slow samples at ``offset + m * factor`` or at any
``sample_indices``, missing samples as ``NaN``, and the initial conditions
``"zero"`` (at rest, the paper's case), ``"discard"`` or ``"periodic"``.
"""

from __future__ import annotations


import logging
import time
import warnings
from dataclasses import dataclass, replace

import numpy as np
from scipy import linalg
from sklearn.base import BaseEstimator, clone
from sklearn.gaussian_process.kernels import ConstantKernel, Kernel
from sklearn.utils.validation import check_is_fitted

from gpmultirate import orders, tuning, units
from gpmultirate.closedloop import check_feedback, loop_input
from gpmultirate.crossvalidation import CrossValidation, contiguous_folds
from gpmultirate.deprecation import warn_deprecated
from gpmultirate.exceptions import (
    HeldOutWarning, IdentifiabilityError, NumericalWarning, OrderWarning,
)
from gpmultirate.memory import check_fit_memory
from gpmultirate.export import StateSpaceMixin
from gpmultirate.inference import (
    GaussianCoefficients,
    LogEvidence,
    blas_threads_for,
    gaussian_samples,
)
from gpmultirate.kernels import (
    DC,
    PerInputKernel,
    check_lags,
    input_kernels,
    kernel_for_inputs,
    like_inputs,
    observe,
    rescaled,
)
from gpmultirate.metrics import goodness_of_fit
from gpmultirate.noise import (
    AR1_DISTURBANCE,
    NAMED_DISTURBANCES,
    ar1_evidence_gain,
    disturbance_evidence_gain,
    make_noise,
    noise_instants,
)
from gpmultirate.observations import build_experiment, regressor_rows
from gpmultirate.observations.experiment import Experiment, check_records, is_record_list
from gpmultirate.observations.interpolated import (
    DEFAULT_POINTS, InterpolatedConvolution, interpolation_error,
)
from gpmultirate.observations.sampled import check_initial_conditions
from gpmultirate.orders import MAX_CHECKED_SAMPLES, MIN_CHECKED_ORDER, auto_orders
from gpmultirate.observations.timed import (
    TimedConvolution,
    check_duration,
    build_timed_experiment,
    on_the_ticks,
    predict_readings,
)
from gpmultirate.resonances import slowest_decay
from gpmultirate.responses import (
    FrequencyResponse,
    check_frequencies,
    default_frequencies,
    dft_matrix,
)
from gpmultirate.validation import (
    check_bounds,
    check_int,
    check_level,
    check_positive,
    check_rng,
    check_sample_indices,
    check_sample_time,
    check_signal,
)

__all__ = ["FIRGaussianProcess", "LeastSquaresFIR"]


class _FIRModelMixin:
    """Prediction, scoring and frequency response shared by the FIR estimators.

    Subclasses set ``coef_``, ``observation_``, ``n_inputs_`` and ``posterior_``
    (a :class:`~gpmultirate.inference.GaussianCoefficients` of the
    input-major coefficient vector) in ``fit``, and implement
    ``impulse_response``.
    """

    #: whether the impulse response is defined between the integer lags
    continuous_lags = False

    @property
    def _order(self) -> int:
        return self.observation_.order

    @property
    def operator_(self):
        """Deprecated name of ``observation_``, removed in gpmultirate 0.2.0."""
        warn_deprecated(f"{type(self).__name__}.operator_", "observation_")
        if "observation_" not in vars(self) and "operator_" in vars(self):
            return vars(self)["operator_"]  # an estimator pickled before the rename
        return self.observation_

    @operator_.setter
    def operator_(self, value) -> None:
        warn_deprecated(f"{type(self).__name__}.operator_", "observation_")
        self.observation_ = value

    def _shaped(self, flat: np.ndarray) -> np.ndarray:
        """Coefficient-like values ``(n_inputs * n,)`` as ``(n_inputs, n)`` for several inputs."""
        if self.n_inputs_ > 1:
            return flat.reshape(self.n_inputs_, -1)
        return flat

    def _check_prediction_input(self, u, name: str = "u") -> np.ndarray:
        inputs, several_records = check_records(u, name)
        if several_records:
            raise ValueError(f"{name} must be one record here; got a list")
        x = inputs[0]
        if x.shape[1] != self.n_inputs_:
            raise ValueError(
                f"{name} must have {self.n_inputs_} input column(s), as in fit; got {x.shape[1]}"
            )
        return x

    def _fast_rows(self, x: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Rows of the fast-rate regressor of input(s) ``x`` (all inputs side by side)."""
        periodic = self.initial_conditions == "periodic"
        return np.hstack([
            regressor_rows(x[:, k], self._order, rows, periodic=periodic)
            for k in range(x.shape[1])
        ])

    def predict(self, u, return_std: bool = False, sample_times=None,
                include_noise: bool = False):
        """Fast-rate output of the model for input ``u``.

        ``y(n) = sum_k sum_i g_k(i) u_k(n - i)`` for ``n = 0..len(u)-1``,
        starting at rest (for ``initial_conditions="periodic"``, in periodic
        steady state: ``u`` is one period).  For the training input this is
        the intersample (fast-rate) response.

        Parameters
        ----------
        u : array-like of shape (n,) or (n, n_inputs), or a list of them
            Fast-rate input, shaped as in ``fit``; a list gives a list.
        return_std : bool, default=False
            Also return the posterior standard deviation of the noise-free
            output (``sqrt(diag(T Sigma T^T))`` with ``T`` the convolution
            matrix of ``u`` and ``Sigma`` the coefficient covariance).
        sample_times : array-like of float, or a list of them, optional
            Instead of the output at the fast ticks, the sensor's readings
            stamped at these instants (in fast sample periods, strictly
            increasing in ``[0, len(u))``), with the model's exposure and
            latency (:doc:`/cameras`); the standard deviation is that of the
            noise-free reading.
        include_noise : bool, default=False
            With ``return_std``: the standard deviation of a measured sample
            instead, the band a new measurement should fall in: the
            posterior variance of the output plus the variance of one
            sample of the fitted noise (the disturbance's and the white
            noise's, see :doc:`/disturbances`).

        Returns
        -------
        y : ndarray of shape (n,)
        std : ndarray of shape (n,), only if ``return_std``
        """
        check_is_fitted(self, "coef_")
        if include_noise and not return_std:
            raise ValueError("include_noise=True needs return_std=True")
        if include_noise:
            predicted = self.predict(u, True, sample_times)
            extra = self._measurement_noise_variance()
            if is_record_list(u):
                return [(m, np.sqrt(s**2 + extra)) for m, s in predicted]
            mean, std = predicted
            return mean, np.sqrt(std**2 + extra)
        if is_record_list(u):
            if sample_times is None:
                return [self.predict(u_r, return_std) for u_r in u]
            if not is_record_list(sample_times) or len(sample_times) != len(u):
                raise ValueError("sample_times must be a list with one entry per record of u")
            return [self.predict(u_r, return_std, t) for u_r, t in zip(u, sample_times)]
        x = self._check_prediction_input(u)
        if sample_times is not None:
            return self._predict_readings(x, sample_times, return_std)
        posterior, scale = units.split(self.posterior_)
        if scale is not None:  # in the units of the normalized fit, scaled at the end
            x = np.ldexp(x, -scale.input_exponents[None, :])
            out = self._predict_normalized(x, posterior, return_std)
            if return_std:
                return tuple(np.ldexp(v, scale.output_exponent) for v in out)
            return np.ldexp(out, scale.output_exponent)
        return self._predict_normalized(x, posterior, return_std)

    def _predict_normalized(self, x, posterior, return_std):
        n = x.shape[0]
        periodic = self.initial_conditions == "periodic"
        coef = posterior.coef.reshape(self.n_inputs_, -1)
        if not return_std and not periodic:
            return sum(np.convolve(x[:, k], coef[k])[:n] for k in range(x.shape[1]))
        # rows of the convolution matrix in blocks: memory O(block P), not O(n P)
        block = max(1, _PREDICT_BLOCK_ENTRIES // coef.size)
        mean, var = np.empty(n), np.empty(n)
        for start in range(0, n, block):
            rows = np.arange(start, min(start + block, n))
            A = self._fast_rows(x, rows)
            if return_std:
                mean[rows], var[rows] = posterior.linear_map(A)
            else:
                mean[rows] = A @ posterior.coef
        return (mean, np.sqrt(var)) if return_std else mean

    def _measurement_noise_variance(self) -> float:
        """The variance of one measured sample's noise (disturbance and white noise)."""
        model = getattr(self, "_noise_model", None)
        exponent = int(np.frexp(getattr(self, "output_scale_", 1.0))[1] - 1)
        with np.errstate(over="ignore"):
            if model is not None and not model.white:  # tuned on the normalized data
                return float(np.ldexp(model.sample_variance(), 2 * exponent))
            if hasattr(self, "noise_level_"):
                if getattr(self, "hyperparameter_units_", "data") == "normalized":
                    return float(np.ldexp(self.noise_level_, 2 * exponent))
                return float(self.noise_level_)
        return float(self.noise_variance_)

    def _predict_readings(self, x, sample_times, return_std):
        """Readings at ``sample_times``: here only on the fast ticks (no model between them)."""
        ticks = on_the_ticks(sample_times, 0.0, 0.0)
        if ticks is None:
            raise ValueError(
                f"{type(self).__name__} has no model between the integer lags: sample_times "
                "must be on the fast ticks (integers); use FIRGaussianProcess for instants "
                "between them"
            )
        ticks = check_sample_indices(ticks, x.shape[0], "sample_times")
        A = self._fast_rows(x, ticks)
        if not return_std:
            return A @ self.posterior_.coef
        mean, var = self.posterior_.linear_map(A)
        return mean, np.sqrt(var)

    def score(self, u, y_fast) -> float:
        """Goodness of fit in percent (eq. 20) of ``predict(u)`` against ``y_fast``.

        Parameters
        ----------
        u : array-like of shape (n,) or (n, n_inputs)
            Fast-rate validation input.
        y_fast : array-like of shape (n,)
            Fast-rate validation output.

        Returns
        -------
        float
        """
        check_is_fitted(self, "coef_")
        y_fast = check_signal(y_fast, "y_fast")
        x = self._check_prediction_input(u)
        if x.shape[0] != y_fast.shape[0]:
            raise ValueError(
                f"y_fast must have the length of u ({x.shape[0]}); got {y_fast.shape[0]}"
            )
        if np.ptp(y_fast) == 0:
            raise ValueError("y_fast must not be constant: the goodness of fit is undefined")
        return goodness_of_fit(y_fast, self.predict(u))

    def _input(self, input) -> int:
        if input is None:
            if self.n_inputs_ > 1:
                raise ValueError(
                    f"input must be given for a model of {self.n_inputs_} inputs "
                    f"(0..{self.n_inputs_ - 1})"
                )
            return 0
        return check_int(input, "input", low=0, high=self.n_inputs_ - 1)

    def frequency_response(
        self, freqs=None, sample_time: float | None = None, level: float = 0.95, input=None
    ) -> FrequencyResponse:
        """FRF of the identified model with a pointwise credible band.

        Valid at every frequency up to the fast Nyquist frequency, also
        beyond the slow Nyquist frequency ``1 / (2 F T)``.

        Parameters
        ----------
        freqs : array-like of shape (n,), optional
            Frequencies in Hz; by default the DFT bins of the training record.
        sample_time : float, optional
            Fast sample time ``T`` in seconds; by default the model's
            ``sample_time``.
        level : float, default=0.95
            Credible level of the band, in (0, 1).
        input : int, optional
            The input whose FRF is returned; needed for several inputs.

        Returns
        -------
        FrequencyResponse
        """
        check_is_fitted(self, "coef_")
        level = check_level(level)
        k = self._input(input)
        if sample_time is None:
            sample_time = self.sample_time
        if freqs is None:
            sample_time = check_sample_time(sample_time)
            freqs = default_frequencies(self.observation_.n_samples, sample_time)
        freqs, sample_time = check_frequencies(freqs, sample_time)
        P = self._order
        E = dft_matrix(freqs, sample_time, P)
        # the DFT of input k's block of the input-major coefficients
        A = np.zeros((E.shape[0], self.n_inputs_ * P), dtype=complex)
        A[:, k * P : (k + 1) * P] = E
        re, im = np.ascontiguousarray(A.real), np.ascontiguousarray(A.imag)
        posterior, scale = units.split(self.posterior_)
        var_re, var_im, cov = posterior.pair_variances(re, im)
        frf = FrequencyResponse.from_gaussian(
            freqs,
            A @ posterior.coef,
            var_re,
            var_im,
            cov,
            level=level,
            sample_time=sample_time,
            factor=self.observation_.slow_factor,
        )
        if scale is None:
            return frf
        return units.scale_frequency_response(frf, int(scale.gain_exponents[k]))

    def _scaled_impulse_response(self, lags, return_std, return_cov):
        """:meth:`impulse_response` from the normalized posterior, in the data's units."""
        kind = "cov" if return_cov else ("std" if return_std else None)
        mean, second, exponents = self._impulse_response_normalized(lags, kind)
        if exponents is not None:
            if kind is None:
                mean = np.ldexp(mean, exponents)
            else:
                mean, second = units.scaled_moments(mean, second, exponents, kind)
        elif kind == "std":
            second = np.sqrt(second)
        if kind is None:
            return self._shaped(mean)
        if kind == "cov":
            return self._shaped(mean), second
        return self._shaped(mean), self._shaped(second)

    def sample_impulse_responses(self, lags=None, n_samples: int = 1, random_state=None):
        """Draw impulse responses from the posterior (for least squares, the estimate's distribution).

        Parameters
        ----------
        lags : array-like of shape (n,), optional
            Lags in fast samples; default ``0..P-1``.
        n_samples : int, default=1
        random_state : int, RandomState or None

        Returns
        -------
        ndarray of shape (n, n_samples), or (n_inputs, n, n_samples) for several inputs
        """
        n_samples = check_int(n_samples, "n_samples", low=1)
        mean, cov, exponents = self._impulse_response_normalized(lags, "cov")
        draws = gaussian_samples(mean, cov, n_samples, check_rng(random_state))
        if exponents is not None:  # drawn in normalized units, each row scaled
            draws = np.ldexp(draws, exponents[:, None])
        if self.n_inputs_ > 1:
            return draws.reshape(self.n_inputs_, -1, n_samples)
        return draws


# entries of the convolution matrix formed at once by predict(..., return_std=True)
_PREDICT_BLOCK_ENTRIES = 2**22


def _unit_scales(experiment) -> list[float]:
    """Output power per unit input power, one per input: the data's units for the prior."""
    power_y = float(np.mean(experiment.y**2)) or 1.0
    return [power_y / power for power in _input_powers(experiment)]


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


#: the logger of a fit's progress (the default order's pilot fits, the resonance search)
_LOG = logging.getLogger("gpmultirate.fit")

#: residual lag-one autocorrelation above which a too-short order is reported
RESIDUAL_CORRELATION = 0.3


def _input_powers_of(inputs) -> list[float]:
    """``mean(u_k**2)`` of each input over all records (1 for an all-zero input)."""
    stacked = np.vstack([x[:, None] if x.ndim == 1 else x for x in inputs])
    return [float(np.mean(stacked[:, k] ** 2)) or 1.0 for k in range(stacked.shape[1])]


def _input_powers(experiment) -> list[float]:
    return _input_powers_of(_record_inputs(experiment))


# the margins in percentage points of held-out fit by which a shorter order
# must predict better to replace the default order N, and to be named in a
# warning for an explicit order
ORDER_MARGIN = 1.0
HELD_OUT_MARGIN = 5.0


#: nats of log evidence (of cross-validated log predictive likelihood with
#: ``tuning="cross_validation"``) a disturbance model must gain over white noise
#: for ``noise_kernel="auto"`` to choose it (it has two more hyperparameters)
AUTO_NOISE_MARGIN = 10.0
#: nats of log evidence a fixed disturbance must gain over the tuned white-noise
#: fit for ``noise_kernel="auto"`` to tune disturbances at all
AUTO_NOISE_GATE = 3.0
#: beyond this many slow samples ``noise_kernel="auto"`` tunes the AR(1) disturbance
#: of a long record (more samples than coefficients), and its check of samples off a
#: uniform grid keeps white noise instead of ``M x M`` factorizations
AUTO_NOISE_DENSE_GATE = 1000


def _check_noise_kernel(noise_kernel):
    """``noise_kernel`` checked: ``"white"``, a named disturbance or a scikit-learn kernel."""
    if isinstance(noise_kernel, Kernel):
        return noise_kernel
    if isinstance(noise_kernel, str) and (noise_kernel in ("auto", "white", AR1_DISTURBANCE)
                                          or noise_kernel in NAMED_DISTURBANCES):
        return noise_kernel
    names = ", ".join(repr(name) for name in ("auto", "white", *NAMED_DISTURBANCES,
                                              AR1_DISTURBANCE))
    raise ValueError(f"noise_kernel must be {names} or a scikit-learn kernel; "
                     f"got {noise_kernel!r}")


def _takes_ar1_route(operator) -> bool:
    """Whether ``noise_kernel="auto"`` tunes an AR(1) disturbance instead of dense Matérn ones.

    So it does for more than ``AUTO_NOISE_DENSE_GATE`` slow samples, more
    than the coefficients, on one uniform grid: there the AR(1) noise is
    tuned through its tridiagonal precision
    (:class:`~gpmultirate.covariance.AR1Covariance`) and the dense route's
    ``M x M`` factorizations would dominate the fit.
    """
    if operator.n_outputs <= max(AUTO_NOISE_DENSE_GATE, operator.n_coefficients):
        return False
    return _is_ar1(AR1_DISTURBANCE, operator)


def _is_ar1(choice, operator) -> bool:
    """Whether the noise ``choice`` takes the AR(1) route on ``operator``."""
    try:
        noise = make_noise(choice, 1.0, (1e-5, 1e5), noise_instants(operator))
    except ValueError:
        return False
    structure = getattr(noise, "structure", None)
    return (structure is not None and structure() is not None and operator.has_regressor
            and operator.n_outputs > operator.n_coefficients)


def _check_tuning(tuning_criterion) -> str:
    if not isinstance(tuning_criterion, str) or tuning_criterion not in (
        "evidence", "cross_validation"
    ):
        raise ValueError(
            f"tuning must be 'evidence' or 'cross_validation'; got {tuning_criterion!r}"
        )
    return tuning_criterion


def _record_inputs(experiment):
    """The inputs of every record, as ``(N, n_inputs)`` arrays."""
    out = []
    for record in experiment.observation.records:
        u = np.asarray(record.u, dtype=float)
        out.append(u[:, None] if u.ndim == 1 else u)
    return out


@dataclass(frozen=True)
class _Settings:
    """The estimator's parameters, checked before the data are touched."""

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


@dataclass
class _Fit:
    """The learned state of a fit at one order (the estimator's attributes of that name)."""

    experiment: object
    observation_: object
    y_slow_: np.ndarray
    noise_level_bounds_: object
    n_inputs_: int
    optimizer_result_: object
    kernel_: object
    noise_level_: float
    posterior_: object
    evidence: object
    coef_: np.ndarray
    log_marginal_likelihood_value_: float
    resonances_: object = None
    cv_log_predictive_likelihood_: float | None = None
    noise_kernel_: object = "white"
    noise_model: object = None


class FIRGaussianProcess(StateSpaceMixin, _FIRModelMixin, BaseEstimator):
    """Fast-rate FIR model as a Gaussian process over lag, from slow-rate data.

    The impulse response ``g(t)``, ``t >= 0`` real, has a zero-mean Gaussian
    process prior with covariance ``kernel``; the slow samples
    ``y_slow[m] = sum_{i<P} g(i) u[n_m - i] + e[m]``, ``n_m = offset + m F``
    (or ``sample_indices[m]``), observe it through a
    :class:`~gpmultirate.DownsampledConvolution` (or a
    :class:`~gpmultirate.SampledConvolution`) with white noise of variance
    ``noise_level`` (the ``gamma`` of eq. 15).  The posterior mean at lags
    ``0..P-1`` is the kernel-regularised estimate of eq. (15).

    With several inputs (``u`` of shape ``(N, n_inputs)``) each input has
    its own impulse response ``g_k``; the prior makes them independent, the
    posterior does not.  Several records (lists of ``u`` and ``y_slow``)
    share the hyperparameters and the noise level.

    Parameters
    ----------
    kernel : sklearn Kernel, list of them, or "auto", optional
        Prior covariance over lag; a list gives one kernel per input, and
        one kernel for several inputs is copied for each (each copy tuned
        separately).  Default ``ConstantKernel(c) * DC(alpha=0.9, beta=0.9)``
        per input, with ``c`` and its bounds set from the data, and ``alpha``
        bounded so that the prior's envelope ``alpha^(t/2)`` falls at least
        by ``e^-2`` by lag ``P`` (the FIR model's own assumption: the
        response has died out by then).  ``"auto"``:
        that default plus up to ``max_resonances`` PK terms whose frequencies
        are found from the data (see :mod:`gpmultirate.resonances`).
    factor : int, default=1
        Downsampling factor ``F`` (ignored when ``sample_indices`` are given).
    order : int, "auto" or sequence of int, optional
        FIR order ``P`` in ``1..N``, shared by all inputs.  Default: chosen
        from the data.  For a record of at most 2048 fast samples
        (``orders.SHORT_RECORD``, e.g. the paper's ``N = 600``): ``N``, the
        length of the (longest) record, unless the held-out check after
        evidence tuning finds that a shorter order ``N/2, ..., N/32`` (at
        least 10) predicts held-out slow samples more than one point of fit
        better at the tuned hyperparameters; the model is then fitted again
        at the best of them (see *Tuning that generalizes* in the user
        guide).  For a longer record: the lag beyond which the prior, tuned
        at a pilot order of 512 (doubled while it has not decayed within the
        order), is negligible against the noise
        (:func:`~gpmultirate.orders.default_order`); it costs the pilot
        fits and at most one refit, and a response that decays well within
        the record gets fewer coefficients than slow samples (the
        long-record route).  An integer is used as given (a too short one
        is reported with an :class:`~gpmultirate.OrderWarning`).  ``"auto"`` or a list of
        candidate orders: fit each candidate and keep the one the tuning
        criterion (``tuning``) prefers, per used slow sample; ``"auto"``
        tries ``N, N/2, N/4, ..., N/32`` (at least 10).  The candidates and
        their scores are reported in ``order_selection_``.
    offset : int, default=0
        Fast index of the first slow sample, ``0..F-1``.
    noise_level : float, default=1.0
        Noise variance ``gamma``; the initial value when it is tuned.
    noise_level_bounds : pair of floats, "fixed" or "auto", default="auto"
        Bounds for tuning ``noise_level``; ``"auto"`` is
        ``(1e-12, 10) * mean(y_slow**2)``.
    optimizer : "marginal_likelihood" or None, default="marginal_likelihood"
        Tune the free hyperparameters and the noise level by maximising the
        log marginal likelihood (Fisher scoring up to 1000 slow samples after
        the reduction of long records, L-BFGS-B above and, above 200
        coefficients, where the evidence goes through DC's precision; see
        the theory page and :mod:`gpmultirate.tuning`); ``None`` uses them
        exactly as given.
    tuning : {"evidence", "cross_validation"}, default="evidence"
        The criterion the hyperparameters (and an ``"auto"`` order)
        maximize: ``"evidence"``, the log marginal likelihood (eq. 19);
        ``"cross_validation"``, the log density of held-out blocks of slow
        samples predicted from the others (K-fold over time, ``cv`` folds;
        see :mod:`gpmultirate.crossvalidation`), which judges the model by
        what it predicts rather than by how well it explains the data.  It
        works in data space: ``O(M^3)`` per evaluation for ``M`` slow
        samples.  After evidence tuning, the held-out fit of the tuned model
        is compared with that of shorter orders (same folds, same
        hyperparameters): with the default order a clearly better shorter
        order replaces ``N``, with an explicit order a warning names it.
        A disturbance model (``noise_kernel``) is tuned by the same
        criterion: under ``"cross_validation"`` each held-out block is
        predicted with the disturbance's correlation across its edges.
    cv : int, default=5
        The number of folds of ``"cross_validation"`` (and of the held-out
        check after evidence tuning): contiguous blocks of slow samples of
        each record.
    exposure : float, default=0.0
        For readings at their own instants (``fit(..., sample_times=t)``):
        each reading is the mean output over the ``exposure`` before its
        instant, in fast sample periods (:doc:`/cameras`).
    latency : float, default=0.0
        For readings at their own instants: the reading stamped ``t`` shows
        the output at ``t - latency`` (fast sample periods).
    between_ticks : {"auto", "exact", "interpolated"}, default="auto"
        How readings between the fast ticks are observed.  ``"exact"``: the
        readings as linear functionals of the response over continuous lag
        (:class:`~gpmultirate.observations.TimedConvolution`), whose data
        covariance is ``M x M``.  ``"interpolated"``: the response between
        the integer lags interpolated (from twelve integer lags), so the
        readings are a regressor on the integer lags and a long record
        takes the ``P x P`` parameter space
        (:class:`~gpmultirate.observations.InterpolatedConvolution`); the
        interpolation error is absorbed by the tuned
        noise level, and ``interpolation_error_`` estimates it (:doc:`/cameras`).
        ``"auto"``: interpolated for a long record, with more readings than
        coefficients and than 1,000 (where the exact route's ``M x M``
        covariance costs many seconds per evaluation), exact otherwise; an
        interpolated fit whose estimated error is above
        ``INTERPOLATION_TOLERANCE`` (0.2) times the noise's standard
        deviation (a response with content near the fast Nyquist frequency)
        is fitted again exactly up to 3,000 readings (beyond, a
        :class:`~gpmultirate.NumericalWarning` gives the estimate).
    noise_kernel : "auto", "white", "matern12", "matern32", "ar1" or sklearn Kernel, default="auto"
        The noise of the slow samples.  ``"white"``: ``noise_level * I``.
        ``"matern12"``/``"matern32"``: white noise plus a disturbance
        ``C * Matern(length_scale, nu=1/2 or 3/2)`` over the samples'
        instants in fast samples (``Matern(length_scale=10)`` spans ten fast
        samples).  ``"ar1"``: ``C * Matern(length_scale, nu=1/2)`` alone, no
        white part (an AR(1) process on a uniform grid).  A kernel: a
        disturbance over the instants (a periodic one with
        ``ExpSineSquared``), added to white noise unless it holds a
        ``WhiteKernel`` or is ``[C *] Matern(nu=0.5)`` alone.  A disturbance
        is tuned with everything else by the evidence, starting from the
        white fit, on the samples themselves (the data-space route:
        ``O(M^3)`` per evaluation); an AR(1) one on one uniform grid with
        more samples than coefficients through its tridiagonal precision
        instead (:class:`~gpmultirate.covariance.AR1Covariance`: ``O(M P^2)``
        once, ``O(P^3)`` per evaluation).  ``"auto"`` fits
        white first and keeps it unless the data call for more: when the
        order covers the data's memory and a fixed Matérn disturbance at the
        tuned prior gains ``AUTO_NOISE_GATE`` (3) nats of evidence, it tunes
        Matérn 1/2 and 3/2 disturbances (beyond ``AUTO_NOISE_DENSE_GATE``
        (1000) slow samples on one uniform grid, more than the
        coefficients: the AR(1) disturbance ``"ar1"`` instead) and keeps the
        better one only when its log evidence exceeds white's by
        ``AUTO_NOISE_MARGIN`` (10) nats.  With
        ``tuning="cross_validation"`` the disturbance is tuned by the
        cross-validated log predictive likelihood from the white
        cross-validated fit (the data-space route, ``O(M^3)`` per
        evaluation, ``"ar1"`` included), and ``"auto"`` (same gate) keeps
        the better disturbance only when its cross-validated log predictive
        likelihood exceeds white's by ``AUTO_NOISE_MARGIN`` (10) nats.
        With ``optimizer=None``, where nothing is tuned, ``"auto"`` is
        white.  See :doc:`/disturbances`.
    n_restarts_optimizer : int, default=0
        Extra optimizer runs from random points drawn uniformly in the log
        bounds; the best optimum is kept.
    random_state : int, RandomState or None, default=None
        Seed of the restarts.
    initial_conditions : {"zero", "discard", "periodic"}, default="zero"
        ``"zero"``: the system is at rest before the record (the paper's
        case); ``"discard"``: the input before the record is unknown, so
        only slow samples at fast index ``>= order - 1`` are used;
        ``"periodic"``: ``u`` is one period of a periodic input in steady
        state (the regressor is circular).
    sample_time : float, default=1.0
        Fast sample time ``T`` in seconds, used by :meth:`frequency_response`
        (frequencies in Hz), the plots and the exports.  Left at 1.0,
        frequencies are in cycles per sample.
    max_resonances : int, default=4
        With ``kernel="auto"``, the most PK terms the search may add.
    normalize : bool, default=True
        When tuning, read the initial values and bounds of ``kernel``'s
        amplitudes, ``noise_level`` and explicit ``noise_level_bounds`` in
        normalized units: input(s) and output divided by their RMS (as
        scikit-learn's ``normalize_y`` does for the output).  The tuned fit
        then does not depend on the units of ``u`` and ``y``: an amplitude of
        1 (``ConstantKernel(1.0)``) is an impulse response of the size the
        data call for, and scikit-learn's default amplitude bounds
        ``(1e-5, 1e5)`` span that scale.  ``kernel_``, ``noise_level_``, the
        posterior, the bands and the evidence are in the data's units.  With
        ``optimizer=None``, or ``normalize=False``, the kernel and noise
        level are used in the data's units exactly as given.

    Attributes
    ----------
    coef_ : ndarray of shape (P,), or (n_inputs, P) for a 2-D ``u``
        Posterior mean of ``g`` at lags ``0..P-1`` (eq. 15).
    n_inputs_ : int
        The number of inputs.
    kernel_ : sklearn Kernel
        The kernel with the tuned hyperparameters.
    noise_level_ : float
        The tuned (or given) white noise variance (the ``WhiteKernel`` part
        of a disturbance model; for a disturbance without one, ``"ar1"``,
        the level of the white-noise fit it started from).
    noise_kernel_ : "white" or sklearn Kernel
        The fitted noise: ``"white"``, or the tuned noise kernel over the
        instants (white part included), such as
        ``WhiteKernel(0.01) + C(0.2) * Matern(40, nu=1.5)``.
    log_marginal_likelihood_value_ : float
        Log evidence of the slow data at ``kernel_`` and ``noise_level_``
        (scikit-learn's sign and constants: higher is better), a density of
        ``y_slow`` in its own units.
    interpolation_error_ : float
        Fits by the interpolated route only: the estimated rms error of the
        interpolated readings of ``coef_``, in standard deviations of the
        white noise (:func:`~gpmultirate.observations.interpolation_error`).
    input_scale_ : ndarray of shape (n_inputs,)
        The power of two each input was divided by for the fit.
    output_scale_ : float
        The power of two ``y_slow`` was divided by for the fit.
    hyperparameter_units_ : {"data", "normalized"}
        The units of ``kernel_``, ``noise_level_`` and
        ``noise_level_bounds_`` (see *Units* in :meth:`fit`).
    observation_ : Observation
        The observation operator of the training data: a
        :class:`~gpmultirate.DownsampledConvolution` in the paper's case, a
        :class:`~gpmultirate.SampledConvolution` or a stack of records
        otherwise.
    y_slow_ : ndarray of shape (M,)
        The slow samples the model was fitted to (the used ones: finite,
        and late enough for ``"discard"``; records concatenated).
    noise_level_bounds_ : pair of floats or "fixed"
        The bounds of ``noise_level`` used for tuning (``"auto"`` resolved).
    posterior_ : GaussianCoefficients
        The posterior of the coefficients at lags ``0..P-1``.
    optimizer_result_ : scipy.optimize.OptimizeResult or None
        The best optimizer run (``x`` in ``theta`` coordinates, ``fun`` the
        negative log evidence, or the negative cross-validated log
        predictive likelihood), or None when nothing was tuned.
    cv_log_predictive_likelihood_ : float
        With ``tuning="cross_validation"``: the sum over the folds of the
        log density of the held-out slow samples at the tuned values, under
        the chosen noise model (``noise_kernel_``).
    order_selection_ : dict
        With ``order="auto"`` or a list: ``"order"`` (the candidates),
        ``"score"`` (the criterion per used slow sample, higher is better),
        ``"criterion"`` (``"log_evidence"`` or ``"cv_log_predictive"``) and
        ``"best_order"`` (the fitted order).  With the default order, where
        the held-out check ran: the candidates ``N/32, ..., N``, their
        held-out fit in percent (``"criterion"`` ``"held_out_fit"``) and the
        fitted order; where the order was read from the tuned prior (a
        record longer than 2048 samples): the pilot orders, the lag read at
        each (``"score"``), ``"criterion"`` ``"prior_tail"`` and the order.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> import gpmultirate as gm
    >>> from gpmultirate.kernels import DC
    >>> rng = np.random.default_rng(0)
    >>> g = 0.9 ** np.arange(60) * np.cos(0.5 * np.arange(60))
    >>> u = rng.standard_normal(120)
    >>> y_slow = np.convolve(u, g)[:120][::3] + 0.05 * rng.standard_normal(40)
    >>> model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=60).fit(u, y_slow)
    >>> model.coef_.shape
    (60,)
    >>> mean, std = model.impulse_response([0.5, 1.5], return_std=True)
    >>> bool(np.all(std > 0))
    True

    Two inputs, and a slow sample that was not measured:

    >>> u2 = rng.standard_normal((120, 2))
    >>> y2 = (np.convolve(u2[:, 0], g)[:120] + np.convolve(u2[:, 1], -g)[:120])[::3]
    >>> y2 += 1e-2 * rng.standard_normal(40)
    >>> y2[5] = np.nan
    >>> model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=20).fit(u2, y2)
    >>> model.coef_.shape, model.frequency_response(input=1).magnitude.shape
    ((2, 20), (61,))
    """

    continuous_lags = True

    def __init__(
        self,
        kernel: Kernel | None = None,
        factor: int = 1,
        order: int | None = None,
        offset: int = 0,
        noise_level: float = 1.0,
        noise_level_bounds="auto",
        optimizer: str | None = "marginal_likelihood",
        n_restarts_optimizer: int = 0,
        random_state=None,
        initial_conditions: str = "zero",
        sample_time: float = 1.0,
        max_resonances: int = 4,
        normalize: bool = True,
        tuning: str = "evidence",
        cv: int = 5,
        exposure: float = 0.0,
        latency: float = 0.0,
        between_ticks: str = "auto",
        noise_kernel="auto",
    ):
        self.kernel = kernel
        self.factor = factor
        self.order = order
        self.offset = offset
        self.noise_level = noise_level
        self.noise_level_bounds = noise_level_bounds
        self.optimizer = optimizer
        self.n_restarts_optimizer = n_restarts_optimizer
        self.random_state = random_state
        self.initial_conditions = initial_conditions
        self.sample_time = sample_time
        self.max_resonances = max_resonances
        self.normalize = normalize
        self.tuning = tuning
        self.cv = cv
        self.exposure = exposure
        self.latency = latency
        self.between_ticks = between_ticks
        self.noise_kernel = noise_kernel

    # ------------------------------------------------------------------ fit
    def fit(self, u, y_slow, sample_indices=None, sample_times=None,
            excitation=None) -> "FIRGaussianProcess":
        """Condition the prior on slow data, tuning hyperparameters if asked.

        Parameters
        ----------
        u : array-like of shape (N,) or (N, n_inputs), or a list of them
            Fast-rate input(s); a list holds one record per entry.
        y_slow : array-like of shape (M,), or a list of them
            Slow output, ``y_slow[m] = y[offset + m * factor]`` (then
            ``M = len(range(offset, N, factor))``) or ``y[sample_indices[m]]``;
            ``NaN`` marks a sample that was not measured.
        sample_indices : array-like of int, or a list of them, optional
            The fast-sample index of each slow sample, strictly increasing
            in ``0..N-1``; ``factor`` and ``offset`` are then ignored.
        sample_times : array-like of float, or a list of them, optional
            The stamp of each reading in fast sample periods (real,
            strictly increasing, in ``[0, N)``), for readings off the fast
            ticks, with the model's ``exposure`` and ``latency`` (see
            :doc:`/cameras`); exclusive with ``sample_indices``.
        excitation : array-like of shape (N,), optional
            For closed-loop data: the external signal ``r`` added in the
            loop at the fast rate, independent of the disturbances, with
            ``u`` (one record, one input) the plant input the loop produced.
            The fit then runs on the part of ``u`` that ``r`` explains (the
            two-stage method, :mod:`gpmultirate.closedloop`), kept in
            ``excitation_model_``; ``excitation=u`` is the plain fit.
            Without it, a fit whose input depends on past residuals warns
            with a :class:`~gpmultirate.FeedbackWarning` (:doc:`/closed_loop`).

        Returns
        -------
        self

        Notes
        -----
        Lists: ``u`` and ``y_slow`` are several records only when both are
        lists (or tuples) of arrays; otherwise each is one array-like, as in
        scikit-learn (``u2.tolist()`` is the array ``u2``, and
        ``y[:, None].tolist()`` the column ``y[:, None]``).

        Units: the fit divides each input and the output by exact powers of
        two of their largest magnitude (``gpmultirate.units``), so any
        finite data in ``[1e-300, 1e300]`` fit alike, and a fit of
        ``u * 2**i``, ``y_slow * 2**j`` is the fit of ``u``, ``y_slow`` with
        every result scaled by ``2**(j - i)`` (outputs by ``2**j``) bit for
        bit.  ``input_scale_`` and ``output_scale_`` hold the powers.  All
        results are in the data's units; ``kernel_`` and ``noise_level_`` too
        unless an amplitude or the noise variance is outside the float range
        there (for instance ``u`` of size ``1e-300`` and ``y_slow`` of size
        1, an amplitude near ``1e600``): they then stay in the normalized
        units, ``hyperparameter_units_`` is ``"normalized"`` and a
        :class:`~gpmultirate.NumericalWarning` says so (such a model's file
        stores them in the normalized units with the powers of two, and
        :func:`~gpmultirate.load_model` fits it again in those units; the
        fit report gives the noise in the data's units).  ``optimizer_result_``
        is the optimizer's run on the normalized data.  Data whose largest
        magnitude is subnormal (below ``2.2e-308``), or an input that is zero
        at every sample, are refused with a ``ValueError`` naming them.
        """
        settings = self._check_params()
        given_input = u
        u, self.excitation_model_ = loop_input(u, excitation, type(self))
        sample_indices = _timed_samples(self, sample_indices, sample_times)
        timed = isinstance(sample_indices, _TimedSamples)
        for name in ("order_selection_", "cv_log_predictive_likelihood_", "resonances_",
                     "interpolation_error_"):
            self.__dict__.pop(name, None)  # made by some fits only: none left from a refit
        self._between_ticks_used = None  # the route of readings between ticks: the setting's
        # the fit works on the data divided by powers of two (exact), then rescales once
        given = (u, y_slow, sample_indices)
        u, y_slow, scale = units.normalize(u, y_slow)
        settings = replace(settings, scale=scale)
        self._fit_normalized((u, y_slow, sample_indices), settings, timed)
        if timed:
            self._check_interpolation((u, y_slow, sample_indices), settings)
        units.rescale_gaussian_process(
            self, scale, lambda: self._experiment(given, self.observation_.order))
        if self.excitation_model_ is None:
            check_feedback(self, given_input, given[1], given[2], sample_times)
        return self

    def _fit_normalized(self, data, settings: _Settings, timed: bool) -> None:
        """The fit on the normalized data, with the order checks."""
        if settings.candidates is not None:
            candidates = settings.candidates
            if candidates == "auto":
                candidates = orders.auto_orders(self._experiment(data, None).observation.order)
            selection = orders.select_order(
                lambda order: self._fit_at(data, order, settings), candidates, settings.criterion
            )
            self._adopt(selection.fit)
            self.order_selection_ = selection.table
            return
        order, fitted, rule, pilot = self.order, None, None, None
        if order is None:
            rule, pilot = self._default_order(data, settings)
            if rule is not None:
                order, fitted = rule.order, rule.fit
        if fitted is None:
            start = time.perf_counter()
            fitted = self._fit_at(data, order, settings if rule is None else replace(
                settings, order_from_data=True), start=pilot)
            if rule is not None:
                _LOG.info("fitted order %d in %.1f s", fitted.observation_.order,
                          time.perf_counter() - start)
        self._adopt(fitted)
        if rule is not None:
            self.order_selection_ = rule.table
        if settings.criterion == "evidence" and self.optimizer is not None:
            with blas_threads_for(fitted.experiment.observation):
                self._check_shorter_orders(data, fitted.experiment, settings)
        self._check_long_enough()
        return self

    def _check_interpolation(self, data, settings: _Settings) -> None:
        """Estimate an interpolated fit's error; with ``between_ticks="auto"``, act on it.

        The estimate (:func:`~gpmultirate.observations.interpolation_error`
        of the posterior mean) in standard deviations of the white noise is
        ``interpolation_error_``.  Above ``INTERPOLATION_TOLERANCE`` the
        default route fits the readings again, exactly, up to ``EXACT_UP_TO``
        readings; beyond, a ``NumericalWarning`` gives the estimate.
        """
        operator = self.observation_
        if not isinstance(operator, InterpolatedConvolution):
            return
        error = interpolation_error(operator, self.posterior_.coef)
        if error is None:
            return
        self.interpolation_error_ = error / np.sqrt(self.noise_level_)
        _LOG.info("interpolated readings (%d lags): estimated error %.3g noise std",
                  operator.points, self.interpolation_error_)
        if _between_ticks(self) != "auto" or self.interpolation_error_ <= INTERPOLATION_TOLERANCE:
            return
        if operator.n_outputs > EXACT_UP_TO:
            warnings.warn(
                f"the readings between the ticks are interpolated with an estimated error of "
                f"{self.interpolation_error_:.2g} noise standard deviations; "
                "between_ticks='exact' models them exactly (an M x M covariance)",
                NumericalWarning, stacklevel=3)
            return
        _LOG.info("fitting the readings again, exactly")
        self._between_ticks_used = "exact"
        del self.interpolation_error_
        self._fit_normalized(data, settings, True)

    def _default_order(self, data, settings: _Settings):
        """The default order of a record longer than ``SHORT_RECORD``: :func:`~gpmultirate.orders.default_order`.

        None for a shorter record (its default order is ``N``).  The pilot
        fits tune the plain prior (the user's kernel, or the default without
        the resonance search) by the evidence; the last one is kept as the
        fit when the rule keeps its order and the fit asks for nothing more.
        Their warnings are those of the kept fit only.  Returns the rule
        and, for the resonance search, the last pilot's tuned ``(kernel,
        noise level)``: the search starts from them instead of from the
        untuned prior (at the pilot's order they are already tuned).
        """
        whole = self._experiment(data, None)
        longest = whole.observation.order
        if longest <= orders.SHORT_RECORD:
            return None, None
        powers = _input_powers(whole)
        pilot = replace(settings, auto=False, criterion="evidence", noise_kernel="white")
        caught = {}

        last = []

        def fit_at(order):
            with warnings.catch_warnings(record=True) as record:
                warnings.simplefilter("always")
                fitted = self._fit_at(data, order, pilot)
            caught[order] = record
            last[:] = [fitted]
            return fitted

        def tail_lag(fitted):
            # over twice the order: a prior cut by the order has not decayed
            return orders.prior_tail_lag(fitted.kernel_, powers, fitted.noise_level_,
                                         2 * fitted.observation_.order)

        rule = orders.default_order(fit_at, tail_lag, longest, whole.y.shape[0],
                                    whole.n_inputs, log=_LOG.info)
        start = None
        if settings.auto and last[0].noise_model is None:
            start = (last[0].kernel_, last[0].noise_level_)
        if rule.fit is not None and (settings.auto or settings.criterion != "evidence"
                                     or settings.noise_kernel not in ("white", "auto")
                                     or (settings.noise_kernel == "auto"
                                         and self._calls_for_disturbance(
                                             rule.fit.experiment, rule.fit.kernel_,
                                             rule.fit.noise_level_, check_tail=False))):
            rule = replace(rule, fit=None)  # the fit at that order goes on from here
            _LOG.info("default order: %d, fitting it with the full settings", rule.order)
        if rule.fit is not None:
            for w in caught[rule.order]:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
            _LOG.info("default order: %d (the pilot fit at that order is kept)", rule.order)
        return rule, start

    def _check_long_enough(self) -> None:
        """Warn when the fitted order is too short for the data's memory.

        Where the fit has more slow samples than coefficients (the held-out
        check does not run there), two signs together: the tuned prior,
        continued beyond the order, is not negligible against the noise from
        the last lag on
        (:func:`~gpmultirate.orders.prior_tail_lag` reaches the order), and
        the residuals of the slow samples are correlated from one slow
        sample to the next (lag-one autocorrelation above
        ``RESIDUAL_CORRELATION`` and four standard errors).  The
        :class:`~gpmultirate.OrderWarning` names a longer order.
        """
        operator = self.observation_
        order = operator.order
        # under a disturbance model correlated residuals are the model's, not a short order's
        if (operator.n_outputs <= operator.n_coefficients
                or self.initial_conditions == "periodic" or self._noise_model is not None):
            return
        experiment_inputs = [np.asarray(r.u, dtype=float) for r in operator.records]
        longest = max(x.shape[0] for x in experiment_inputs)
        if order >= longest:
            return
        powers = _input_powers_of(experiment_inputs)
        if orders.prior_tail_lag(self.kernel_, powers, self.noise_level_, 2 * order) < order:
            return
        products = squares = 0.0
        start = 0
        for record, fitted in zip(operator.records, self._fitted_readings()):
            y = self.y_slow_[start : start + record.n_outputs]
            start += record.n_outputs
            residual = y - fitted
            products += float(residual[1:] @ residual[:-1])
            squares += float(residual @ residual)
        if squares == 0.0:
            return
        correlation = products / squares
        if correlation <= max(RESIDUAL_CORRELATION, 4.0 / np.sqrt(operator.n_outputs)):
            return
        longer = min(2 * order, longest)
        default = "" if self.order is None else " (or the default order=None, which reads it from the data)"
        warnings.warn(
            f"order={order} looks too short for the data's memory: the tuned prior has not "
            f"decayed against the noise by lag {order} and the residuals of the slow samples "
            f"are correlated from one to the next ({correlation:.2f} at lag one); the noise "
            f"level and the bands are then too large. Try order={longer}{default}.",
            OrderWarning,
            stacklevel=3,
        )

    def _fitted_readings(self) -> list:
        """The posterior mean of the used slow samples, one array per record.

        On the ticks, the fast output at their indices; readings at their own
        instants, by the interpolation of an interpolated fit or, fitted
        exactly (white noise, data space), as ``y - gamma S_y^{-1} y``.
        """
        operator = self.observation_
        coef = self.posterior_.coef
        if isinstance(operator, TimedConvolution):
            # white noise, in data space: the noise-free part of y is y - gamma S_y^{-1} y
            mean = self.y_slow_ - self.noise_level_ * self.posterior_.alpha
        elif isinstance(operator, InterpolatedConvolution):
            mean = operator.matvec(coef)
        else:
            coef = coef.reshape(self.n_inputs_, -1)
            out = []
            for record in operator.records:
                x = np.asarray(record.u, dtype=float)
                x = x[:, None] if x.ndim == 1 else x
                n = x.shape[0]
                fitted = sum(np.convolve(x[:, k], coef[k])[:n] for k in range(x.shape[1]))
                out.append(fitted[record.sample_indices])
            return out
        bounds = np.cumsum([0] + [record.n_outputs for record in operator.records])
        return [mean[a:b] for a, b in zip(bounds[:-1], bounds[1:])]

    def _check_params(self) -> _Settings:
        """Check every parameter, before the data are built (as scikit-learn does)."""
        criterion = _check_tuning(self.tuning)
        n_folds = check_int(self.cv, "cv", low=2)
        candidates = orders.order_candidates(self.order)
        if self.order is not None and candidates is None:
            check_int(self.order, "order", low=1)
        check_initial_conditions(self.initial_conditions)
        factor = check_int(self.factor, "factor", low=1)
        check_int(self.offset, "offset", low=0, high=factor - 1)
        if not (self.optimizer is None or (
            isinstance(self.optimizer, str) and self.optimizer == "marginal_likelihood"
        )):
            raise ValueError(
                f"optimizer must be 'marginal_likelihood' or None; got {self.optimizer!r}"
            )
        n_restarts = check_int(self.n_restarts_optimizer, "n_restarts_optimizer", low=0)
        check_rng(self.random_state)
        check_sample_time(self.sample_time)
        noise = check_positive(self.noise_level, "noise_level")
        if not (isinstance(self.noise_level_bounds, str) and self.noise_level_bounds == "auto"):
            check_bounds(self.noise_level_bounds, "noise_level_bounds")
        auto = isinstance(self.kernel, str) and self.kernel == "auto"
        if isinstance(self.kernel, str) and not auto:
            raise ValueError(f"kernel must be a scikit-learn kernel, a list of them or 'auto'; "
                             f"got {self.kernel!r}")
        max_resonances = check_int(self.max_resonances, "max_resonances", low=0)
        noise_kernel = _check_noise_kernel(self.noise_kernel)
        if noise_kernel == "auto" and self.optimizer is None:
            # without an optimizer the hyperparameters are the user's and nothing is tuned
            noise_kernel = "white"
        # normalized units are a start and bounds for tuning: without tuning
        # the kernel and the noise level are used exactly as given
        normalize = bool(self.normalize) and self.optimizer is not None
        return _Settings(criterion, n_folds, candidates, n_restarts, noise, auto,
                         max_resonances, normalize, self.optimizer is not None,
                         noise_kernel=noise_kernel)

    def _experiment(self, data, order):
        return _experiment(self, *data, order)

    def _adopt(self, fitted: _Fit) -> None:
        """Take the learned state of a fit at one order as the estimator's."""
        for name in ("observation_", "y_slow_", "noise_level_bounds_", "n_inputs_",
                     "optimizer_result_", "kernel_", "noise_level_", "posterior_", "coef_",
                     "log_marginal_likelihood_value_", "noise_kernel_"):
            setattr(self, name, getattr(fitted, name))
        self._noise_model = fitted.noise_model
        # kept for log_marginal_likelihood(theta) and the posterior at real lags
        self._evidence = fitted.evidence
        for name in ("resonances_", "cv_log_predictive_likelihood_"):
            if getattr(fitted, name) is not None:
                setattr(self, name, getattr(fitted, name))
            else:
                self.__dict__.pop(name, None)

    def _fit_at(self, data, order, settings: _Settings, start=None) -> _Fit:
        """Fit at one order; returns the learned state, leaves the estimator alone.

        ``start``: the ``(kernel, noise level)`` of a plain fit at that order
        (the default order's pilot), where ``kernel="auto"`` starts its search.
        """
        experiment = self._experiment(data, order)
        operator, y = experiment.observation, experiment.y
        kernel, noise, noise_bounds = prior_in_data_units(
            # "auto" starts from the default prior (also in the default order's pilots)
            None if isinstance(self.kernel, str) else self.kernel, experiment,
            settings.noise_level,
            self.noise_level_bounds, settings.normalize, settings.tuned,
        )
        if not settings.normalize and not getattr(self, "_prior_in_normalized_units", False):
            # given in the data's units: the fit works in the units of units.normalize
            # (a model file of hyperparameter_units_="normalized" gives them in those units)
            given = not isinstance(self.kernel, str) and self.kernel is not None
            explicit = not isinstance(self.noise_level_bounds, str) or (
                self.noise_level_bounds == "fixed")
            converted, noise, bounds = units.to_normalized(
                kernel if given else None, noise, noise_bounds if explicit else "fixed",
                settings.scale)
            kernel = converted if given else kernel
            noise_bounds = bounds if explicit else noise_bounds
        if start is not None and settings.auto:
            kernel, noise = clone(start[0]), float(start[1])
        # refuse now what would be killed for lack of memory halfway
        n_free = sum(h.n_elements for h in kernel.hyperparameters if not h.fixed)
        check_fit_memory(operator.n_outputs, operator.n_coefficients, n_free + 1,
                         n_inputs=experiment.n_inputs)
        optimizer_result = resonances_found = cv_value = None
        with blas_threads_for(operator):
            if settings.auto:
                from gpmultirate import resonances

                search = resonances.search_resonances(
                    operator, y, kernel, noise, noise_bounds,
                    max_resonances=settings.max_resonances,
                    sample_time=self.sample_time, random_state=self.random_state,
                    n_folds=settings.n_folds,
                )
                kernel, noise = search.kernel, search.noise_level
                optimizer_result = search.optimizer_result
                resonances_found = search.resonances
            evidence = LogEvidence(operator, y, kernel, noise, noise_bounds)
            objective = evidence
            if settings.criterion == "cross_validation":
                check_fit_memory(y.shape[0], y.shape[0], kernel.theta.shape[0] + 1)
                objective = CrossValidation(
                    operator, y, kernel, noise, noise_bounds, settings.n_folds
                )
            if self.optimizer is not None and (not settings.auto or objective is not evidence):
                # with "auto", the search tuned by the evidence: cross-validation goes on from there
                result = tuning.maximize(objective, settings.n_restarts, self.random_state)
                if result is not None:
                    optimizer_result = result
                    kernel, noise = evidence.split(result.x)
            posterior = evidence.posterior(kernel, noise)
            if objective is not evidence:
                moved = objective.moved_to(kernel, noise)
                cv_value = float(moved(moved.theta))
            noise_model = None
            if settings.noise_kernel != "white" and (
                    settings.noise_kernel != "auto" or self._calls_for_disturbance(
                        experiment, kernel, noise, check_tail=not settings.order_from_data)):
                # the disturbance is tuned with everything else, from the white fit
                if settings.noise_kernel != "auto":
                    choices = [self._noise_kernel_in_fit_units(settings)]
                elif _takes_ar1_route(operator):
                    # a long record on one uniform grid: the AR(1) disturbance keeps the
                    # long-record cost where the dense Matérn ones need M x M matrices
                    choices = [AR1_DISTURBANCE]
                else:
                    choices = list(NAMED_DISTURBANCES)
                # cross-validation works in data space whatever the noise's structure
                if cv_value is not None or not (len(choices) == 1
                                                and _is_ar1(choices[0], operator)):
                    check_fit_memory(y.shape[0], y.shape[0], kernel.theta.shape[0] + 3)
                # the criterion of the tuning judges: the evidence, or the cross-validated
                # log predictive likelihood (cv_value, the white fit's, is then set)
                white_score = posterior.log_marginal_likelihood if cv_value is None else cv_value
                best = None
                for choice in choices:
                    tried = self._fit_disturbance(operator, y, kernel, noise, noise_bounds,
                                                  choice, settings)
                    if best is None or tried[-1] > best[-1]:
                        best = tried
                if settings.noise_kernel != "auto" or best[-1] > white_score + AUTO_NOISE_MARGIN:
                    evidence, kernel, noise_model, posterior, result, score = best
                    optimizer_result = result if result is not None else optimizer_result
                    if cv_value is not None:
                        cv_value = score
                    # a disturbance without white noise (AR(1)) keeps the white fit's level
                    noise = noise_model.level or noise
                    if resonances_found:  # the search judged its terms with white noise
                        kept, reduced = resonances.resonances_under_disturbance(
                            operator, y, evidence, kernel, noise_model,
                            [r.input for r in resonances_found], settings.n_folds)
                        if len(kept) < len(resonances_found):
                            _LOG.info("resonance search: %d term(s) dropped, the disturbance "
                                      "explains them", len(resonances_found) - len(kept))
                            resonances_found = [resonances_found[r] for r in kept]
                            evidence, kernel, noise_model, posterior, result, score = (
                                self._fit_disturbance(operator, y, reduced, noise, noise_bounds,
                                                      None, settings, start=noise_model))
                            optimizer_result = result if result is not None else optimizer_result
                            if cv_value is not None:
                                cv_value = score
                            noise = noise_model.level or noise
        moved_evidence = evidence.moved_to(kernel, noise if noise_model is None else noise_model)
        if optimizer_result is not None:
            tuning.warn_at_bounds(units.evidence_in_data_units(moved_evidence, settings.scale))
        coef = posterior.coef
        return _Fit(
            experiment=experiment,
            observation_=operator,
            y_slow_=y,
            noise_level_bounds_=noise_bounds,
            n_inputs_=experiment.n_inputs,
            optimizer_result_=optimizer_result,
            kernel_=kernel,
            noise_level_=noise,
            posterior_=posterior,
            evidence=moved_evidence,
            coef_=coef.reshape(experiment.n_inputs, -1) if experiment.n_inputs > 1 else coef,
            log_marginal_likelihood_value_=posterior.log_marginal_likelihood,
            resonances_=resonances_found,
            cv_log_predictive_likelihood_=cv_value,
            noise_kernel_="white" if noise_model is None else noise_model.kernel,
            noise_model=noise_model,
        )

    def _calls_for_disturbance(self, experiment, kernel, noise_level: float,
                               check_tail: bool = True) -> bool:
        """Whether ``noise_kernel="auto"`` goes on to tune disturbances after the white fit.

        Three cheap checks on the tuned white-noise fit, in order:

        * the order covers the data's memory: it is the default order read
          from the data (``check_tail=False``), it reaches the longest record,
          or the output variance the tuned prior gives the lags from the
          order to twice the order is below ``TAIL_TOLERANCE`` (a hundredth)
          times the noise variance (:func:`~gpmultirate.orders.prior_tail_lag`,
          the measure of the order check).
          Otherwise the colour of the residuals may be the response's tail
          cut by the order, which a longer order explains, not a disturbance
          (the paper's study at orders below ``N``);
        * at most ``MAX_CHECKED_SAMPLES`` slow samples (a disturbance is tuned
          with the ``M x M`` data covariance);
        * a fixed Matérn disturbance, with the tuned prior held, gains at
          least ``AUTO_NOISE_GATE`` nats of log evidence over the white noise
          (:func:`~gpmultirate.noise.disturbance_evidence_gain`; with more
          slow samples than coefficients, where the fit has no ``M x M``
          matrix, an AR(1) one on a uniform grid,
          :func:`~gpmultirate.noise.ar1_evidence_gain`; off a uniform grid
          the dense one up to ``AUTO_NOISE_DENSE_GATE`` slow samples, and
          white noise beyond).
        """
        operator, y = experiment.observation, experiment.y
        order, n_samples = operator.order, y.shape[0]
        longest = max(np.asarray(r.u).shape[0] for r in operator.records)
        if check_tail and order < longest:
            powers = _input_powers(experiment)
            if orders.prior_tail_lag(kernel, powers, noise_level, 2 * order) >= order:
                _LOG.info("noise: white (the prior has not decayed against the noise by order "
                          "%d: the residuals' colour may be the cut tail)", order)
                return False
        if n_samples > MAX_CHECKED_SAMPLES:
            _LOG.info("noise: white (%d slow samples, beyond %d for a disturbance model)",
                      n_samples, MAX_CHECKED_SAMPLES)
            return False
        term = observe(kernel, operator)
        gain = None
        if n_samples > operator.n_coefficients and operator.has_regressor:
            # the AR(1) form, O(M P^2) once, then P x P per grid point: the long-record
            # route has no M x M matrix, and the check must not bring one
            gain = ar1_evidence_gain(operator.matrix, term.kernel_matrix(), y, noise_level,
                                     noise_instants(operator))
        if gain is None and n_samples <= AUTO_NOISE_DENSE_GATE:
            gain = disturbance_evidence_gain(term.covariance(), y, noise_level,
                                             noise_instants(operator))
        if gain is None:
            _LOG.info("noise: white (%d slow samples not on one uniform grid)", n_samples)
            return False
        _LOG.info("noise: a fixed disturbance gains %.1f nats over white", gain)
        return gain >= AUTO_NOISE_GATE

    def _noise_kernel_in_fit_units(self, settings: _Settings):
        """The noise choice in the units of the normalized data (a kernel is given in the data's)."""
        choice = settings.noise_kernel
        if (isinstance(choice, str) or settings.scale is None
                or getattr(self, "_prior_in_normalized_units", False)):
            return choice
        return units.scaled_noise_kernel(choice, settings.scale.variance(1.0, to_data=False))

    def _fit_disturbance(self, operator, y, kernel, noise_level, noise_bounds, choice,
                         settings: _Settings, start=None):
        """Tune a disturbance model with everything else, from the white fit's point.

        ``choice``: a noise choice (``make_noise``); ``start``: a noise model to go
        on from instead.

        By the criterion of ``settings``: the log evidence, or the
        cross-validated log predictive likelihood
        (:class:`~gpmultirate.crossvalidation.CrossValidation` with the noise
        model, on the same folds as the white fit).  Returns ``(evidence,
        kernel, noise_model, posterior, optimizer_result, score)``, ``score``
        the criterion's value at the tuned point.
        """
        noise_model = start if start is not None else make_noise(
            choice, noise_level, noise_bounds, noise_instants(operator))
        evidence = LogEvidence(operator, y, kernel, noise_level, noise_bounds, noise=noise_model)
        objective = evidence
        if settings.criterion == "cross_validation":
            objective = CrossValidation(operator, y, kernel, noise_level, noise_bounds,
                                        settings.n_folds, noise=noise_model)
        result = None
        if self.optimizer is not None:
            result = tuning.maximize(objective, settings.n_restarts, self.random_state)
            if result is not None:
                kernel, noise_model = objective.split_models(result.x)
        posterior = evidence.posterior(kernel, noise_model)
        if objective is evidence:
            score = posterior.log_marginal_likelihood
        else:
            moved = objective.moved_to(kernel, noise_model)
            score = float(moved(moved.theta))
        return evidence, kernel, noise_model, posterior, result, score

    def _check_shorter_orders(self, data, experiment, settings: _Settings):
        """Compare the held-out fit of the tuned model with that of shorter orders; act on it.

        The same hyperparameters, the same folds (as ``tuning="cross_validation"``);
        only the order is cut (:func:`~gpmultirate.orders.held_out_fits`).
        With the default order (``order=None``) the candidates are
        :func:`~gpmultirate.orders.auto_orders` of ``N``, and when one
        predicts the held-out slow samples more than ``ORDER_MARGIN`` points
        of fit better than ``N``, the model is fitted again at that order;
        ``order_selection_`` reports every candidate's held-out fit.  With an
        explicit order ``P`` the candidates are ``P/2, P/4, P/8`` and a
        :class:`~gpmultirate.HeldOutWarning` names one that predicts more than
        ``HELD_OUT_MARGIN`` points better.  Skipped where it would cost more
        than the fit (at least as many slow samples as coefficients, where
        the fit works on the ``P x P`` problem and the check would need
        ``M x M`` matrices; as many is checked for the default order, the
        single-rate case), beyond ``MAX_CHECKED_SAMPLES`` slow samples, or
        where it is not comparable (``"discard"`` uses other samples at other
        orders).
        """
        operator, y = experiment.observation, experiment.y
        order, n_samples = operator.order, y.shape[0]
        default_order = self.order is None
        n_folds = settings.n_folds
        # the fit works in data space for M < P; at M = P (single rate) only the
        # default order is checked, and never with M x M matrices beyond the limit
        data_space = n_samples < operator.n_coefficients or (
            default_order and n_samples == operator.n_coefficients)
        if (self.initial_conditions == "discard" or not data_space
                or n_samples > MAX_CHECKED_SAMPLES or order < 2 * MIN_CHECKED_ORDER
                or np.ptp(y) == 0):  # the fit in percent of a constant output is undefined
            return
        try:
            folds = contiguous_folds([r.n_outputs for r in operator.records], n_folds)
        except ValueError:
            return  # fewer samples than folds: nothing to hold out
        if default_order:
            candidates = orders.auto_orders(order)
        else:
            candidates = [order // d for d in (8, 4, 2) if order // d >= MIN_CHECKED_ORDER]
            candidates.append(order)
        fits = orders.held_out_fits(
            lambda p: operator if p == order else self._experiment(data, p).observation,
            candidates, self.kernel_,
            self.noise_level_ if self._noise_model is None else self._noise_model, y, folds,
        )
        if fits is None:
            return
        best = max(fits, key=fits.get)  # the shortest of equal fits
        if default_order:
            chosen = best if fits[best] > fits[order] + ORDER_MARGIN else order
            if chosen != order:
                self._adopt(self._fit_at(data, chosen, settings))
            self.order_selection_ = {
                "order": np.array(candidates),
                "score": np.array([fits[o] for o in candidates]),
                "criterion": "held_out_fit",
                "best_order": int(chosen),
            }
        elif fits[best] > fits[order] + HELD_OUT_MARGIN:
            warnings.warn(
                f"held-out slow samples are predicted clearly better at a shorter order: "
                f"order={best} fits {fits[best]:.1f} % of them, order={order} "
                f"{fits[order]:.1f} % ({n_folds}-fold cross-validation over time at the tuned "
                "hyperparameters). The marginal likelihood trusts the model, and measured data "
                "with drift, disturbances or a little nonlinearity can make it prefer a worse "
                f"predictor: try order={best}, or order='auto' with "
                "tuning='cross_validation'.",
                HeldOutWarning,
                stacklevel=3,
            )

    # ------------------------------------------------------------ evidence
    def log_marginal_likelihood(self, theta=None, eval_gradient: bool = False):
        """Log marginal likelihood of the training data (eq. 19, corrected).

        Parameters
        ----------
        theta : array-like, optional
            Hyperparameters in tuning coordinates: ``kernel_.theta`` (the
            log of each free value, ``artanh`` of DC's ``beta``) followed by
            ``log(noise_level)`` unless the noise level is fixed (with a
            disturbance model: the noise kernel's ``theta``).  By default
            the fitted value is returned.
        eval_gradient : bool, default=False
            Also return the gradient with respect to ``theta``.

        Returns
        -------
        float, or (float, ndarray) with ``eval_gradient``
        """
        check_is_fitted(self, "coef_")
        if theta is None:
            if eval_gradient:
                raise ValueError("eval_gradient requires theta")
            return self.log_marginal_likelihood_value_
        theta = check_signal(theta, "theta", min_length=0)
        evidence = self._evidence
        n_expected = evidence.theta.shape[0]
        if theta.shape[0] != n_expected:
            raise ValueError(f"theta must have {n_expected} entries; got {theta.shape[0]}")
        theta, shift = units.evidence_theta(self, theta)
        if eval_gradient:
            value, gradient = evidence(theta, eval_gradient=True)
            return value + shift, gradient
        return evidence(theta) + shift

    # ----------------------------------------------------------- posterior
    def impulse_response(self, lags=None, return_std: bool = False, return_cov: bool = False):
        """Posterior of the impulse response ``g(t)`` at real lags ``t >= 0``.

        Non-integer lags use the kernel on continuous lag (the Gaussian
        process / RKHS view of the estimate).

        Parameters
        ----------
        lags : array-like of shape (n,), optional
            Lags in fast samples; default ``0..P-1``.
        return_std : bool, default=False
            Also return the posterior standard deviation.
        return_cov : bool, default=False
            Also return the posterior covariance (exclusive with ``return_std``).

        Returns
        -------
        mean : ndarray of shape (n,), or (n_inputs, n) for several inputs
        std : ndarray of the shape of ``mean``, only with ``return_std``
        cov : ndarray of shape (n, n), only with ``return_cov``; for several
            inputs ``(n_inputs * n, n_inputs * n)``, of the input-major
            flattened ``mean``
        """
        check_is_fitted(self, "coef_")
        if return_std and return_cov:
            raise ValueError("return_std and return_cov cannot both be True")
        return self._scaled_impulse_response(lags, return_std, return_cov)

    def _impulse_response_normalized(self, lags, kind):
        """Flat mean, variance (``kind="std"``) or covariance (``"cov"``) or None, and the
        exponents that carry them into the data's units (None: already there)."""
        check_is_fitted(self, "coef_")
        X = self._points(lags)
        posterior, scale = units.split(self.posterior_)
        exponents = None
        if scale is not None:
            gains = scale.gain_exponents
            exponents = gains[X[:, 0].astype(int)] if self.n_inputs_ > 1 else np.full(
                X.shape[0], int(gains[0]))
        if kind is None:
            return posterior.mean_at_lags(X), None, exponents
        mean, second = posterior.at_lags(X, full_cov=kind == "cov")
        return mean, second, exponents

    def _predict_readings(self, x, sample_times, return_std):
        """The sensor's readings at ``sample_times`` (exposure and latency applied).

        A fit of interpolated readings predicts them by its interpolation;
        any other by the posterior at real lags.
        """
        posterior, scale = units.split(self.posterior_)
        kernel = self.kernel_
        if scale is not None:  # in the units of the normalized fit, scaled at the end
            x = np.ldexp(x, -scale.input_exponents[None, :])
            kernel = self._evidence.kernel
        readings = TimedConvolution(
            x, sample_times, self._order, self.exposure, self.latency, self.initial_conditions)
        fitted = self.observation_
        if isinstance(fitted, InterpolatedConvolution) and readings.n_samples >= fitted.points:
            # the readings as the fit modelled them: interpolated on the integer lags
            mean, var = posterior.linear_map(
                InterpolatedConvolution(readings, fitted.points).matrix)
        else:
            with blas_threads_for(readings):
                mean, var = predict_readings(posterior, self._evidence.data, kernel, readings)
        out = (mean, np.sqrt(var)) if return_std else mean
        if scale is None:
            return out
        if return_std:
            return tuple(np.ldexp(v, scale.output_exponent) for v in out)
        return np.ldexp(out, scale.output_exponent)

    def _points(self, lags) -> np.ndarray:
        """The kernel inputs of the lags: a column, or ``(input, lag)`` pairs input-major."""
        lags = np.arange(self._order, dtype=float) if lags is None else check_lags(lags, "lags")
        if self.n_inputs_ == 1:
            return lags[:, None]
        inputs = np.repeat(np.arange(self.n_inputs_, dtype=float), lags.shape[0])
        return np.column_stack([inputs, np.tile(lags, self.n_inputs_)])


class LeastSquaresFIR(StateSpaceMixin, _FIRModelMixin, BaseEstimator):
    """Least-squares FIR model from slow-rate data (paper eq. 11).

    The estimate is unique only when the order is below the number of slow
    samples (Lemma 1) and the regressor has full column rank, which fails
    for instance for zero-order-hold inputs (Lemma 2); otherwise ``fit``
    raises :class:`~gpmultirate.IdentifiabilityError`.

    Parameters
    ----------
    factor : int, default=1
        Downsampling factor ``F`` (ignored when ``sample_indices`` are given).
    order : int
        FIR order ``P``; ``n_inputs * P`` must be below the number of used
        slow samples ``M``.
    offset : int, default=0
        Fast index of the first slow sample, ``0..F-1``.
    initial_conditions : {"zero", "discard", "periodic"}, default="zero"
        As for :class:`FIRGaussianProcess`.
    sample_time : float, default=1.0
        Fast sample time in seconds, as for :class:`FIRGaussianProcess`.

    Attributes
    ----------
    coef_ : ndarray of shape (P,), or (n_inputs, P) for a 2-D ``u``
    n_inputs_ : int
    noise_variance_ : float
        Residual variance ``||y - Phi g||^2 / (M - P)`` (NaN when ``M = P + 0``).
    coef_covariance_ : ndarray of shape (n_inputs * P, n_inputs * P)
        ``noise_variance_ (Phi^T Phi)^{-1}``, used for the bands of
        :meth:`predict` and :meth:`frequency_response`.
    observation_ : Observation
    posterior_ : GaussianCoefficients
        The Gaussian distribution ``N(coef_, coef_covariance_)``.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import LeastSquaresFIR
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> g = 0.5 ** np.arange(10)
    >>> y_slow = np.convolve(u, g)[:300][::3]
    >>> LeastSquaresFIR(factor=3, order=10).fit(u, y_slow).coef_[:3].round(6)
    array([1.  , 0.5 , 0.25])
    """

    def __init__(self, factor: int = 1, order: int | None = None, offset: int = 0,
                 initial_conditions: str = "zero", sample_time: float = 1.0):
        self.factor = factor
        self.order = order
        self.offset = offset
        self.initial_conditions = initial_conditions
        self.sample_time = sample_time

    def fit(self, u, y_slow, sample_indices=None, sample_times=None) -> "LeastSquaresFIR":
        """Solve the least-squares problem of eq. (10)-(11).

        Parameters
        ----------
        u : array-like of shape (N,) or (N, n_inputs), or a list of them
        y_slow : array-like of shape (M,), or a list of them
            ``NaN`` marks a sample that was not measured.
        sample_indices : array-like of int, or a list of them, optional
            As for :meth:`FIRGaussianProcess.fit`.
        sample_times : array-like, or a list of them, optional
            Only on the fast ticks (integers): least squares has no model
            between the integer lags; exclusive with ``sample_indices``.

        Returns
        -------
        self

        Notes
        -----
        Lists and units as for :meth:`FIRGaussianProcess.fit`: records only
        when ``u`` and ``y_slow`` both are lists of arrays, and the data
        divided by exact powers of two before the least-squares problem is
        formed.  ``noise_variance_`` and ``coef_covariance_`` are ``inf``
        where they exceed the float range in the data's units; the standard
        deviations of :meth:`impulse_response` and :meth:`predict` are formed
        before scaling and stay finite.

        Raises
        ------
        IdentifiabilityError
            If ``n_inputs * order >= M`` (the used slow samples) or the
            regressor is rank deficient.
        """
        if sample_times is not None:
            if sample_indices is not None:
                raise ValueError("give sample_indices or sample_times, not both")
            sample_indices = on_the_ticks(sample_times, 0.0, 0.0)
            if sample_indices is None:
                raise ValueError(
                    "LeastSquaresFIR has no model between the integer lags: sample_times must "
                    "be on the fast ticks (integers); use FIRGaussianProcess for readings "
                    "between them"
                )
        if self.order is None:
            raise ValueError("order must be given: an integer below the number of slow samples")
        check_sample_time(self.sample_time)
        data_u, data_y = u, y_slow
        u, y_slow, scale = units.normalize(u, y_slow)  # exact powers of two, rescaled below
        experiment = build_experiment(
            u, y_slow, sample_indices, factor=self.factor, offset=self.offset,
            order=self.order, initial_conditions=self.initial_conditions,
        )
        operator, y = experiment.observation, experiment.y
        M, P = operator.n_outputs, operator.n_coefficients
        check_fit_memory(M, P, 0, n_inputs=operator.n_inputs)
        if P >= M:
            inputs = f" x {operator.n_inputs} inputs" if operator.n_inputs > 1 else ""
            raise IdentifiabilityError(
                f"order={operator.order}{inputs} is not below the number of used slow samples "
                f"M={M}: the least-squares FIR estimate is not unique (Lemma 1). Use a lower "
                "order, more data, or FIRGaussianProcess, whose prior makes any order unique."
            )
        U, s, Vt = linalg.svd(operator.matrix, full_matrices=False, check_finite=False)
        tolerance = max(M, P) * np.finfo(float).eps * (s[0] if s.size else 0.0)
        rank = int(np.sum(s > tolerance))
        if rank < P:
            hold = any(
                _is_zero_order_hold(x[:, k], operator.slow_factor)
                for x in _record_inputs(experiment) for k in range(x.shape[1])
            )
            hint = (
                "The input is constant between slow samples (zero-order hold, Lemma 2): "
                "excite the system at the fast rate. " if hold else ""
            )
            raise IdentifiabilityError(
                f"the regressor has rank {rank} < {P} coefficients, so the least-squares FIR "
                f"estimate is not unique. {hint}Use a fast-rate (e.g. multisine or random) "
                "input, a lower order, or FIRGaussianProcess."
            )
        coef = Vt.T @ ((U.T @ y) / s)
        residual = y - operator.matrix @ coef
        noise_variance = float(residual @ residual / (M - P))
        root = Vt.T / s  # coef covariance = noise_variance * root @ root.T
        self.observation_ = operator
        self.n_inputs_ = experiment.n_inputs
        self.coef_ = self._shaped(coef)
        self.noise_variance_ = noise_variance
        self.coef_covariance_ = noise_variance * (root @ root.T)
        self.posterior_ = GaussianCoefficients(coef, self.coef_covariance_, np.zeros((0, P)))
        units.rescale_least_squares(self, scale, lambda: build_experiment(
            data_u, data_y, sample_indices, factor=self.factor, offset=self.offset,
            order=self.order, initial_conditions=self.initial_conditions,
        ))
        return self

    def impulse_response(self, lags=None, return_std: bool = False, return_cov: bool = False):
        """The estimate at integer lags, with its standard deviation or covariance.

        Least squares estimates the coefficients only: ``lags`` must be
        integers in ``0..P-1``.  The covariance is :attr:`coef_covariance_`.

        Parameters
        ----------
        lags : array-like of int, optional
            Lags in ``0..P-1``; default all of them.
        return_std, return_cov : bool, default=False
            Also return the standard deviation or the covariance.

        Returns
        -------
        mean : ndarray of shape (n,), or (n_inputs, n) for several inputs
        std : ndarray of the shape of ``mean``, only with ``return_std``
        cov : ndarray, only with ``return_cov`` (input-major for several inputs)
        """
        check_is_fitted(self, "coef_")
        if return_std and return_cov:
            raise ValueError("return_std and return_cov cannot both be True")
        return self._scaled_impulse_response(lags, return_std, return_cov)

    def _impulse_response_normalized(self, lags, kind):
        """Flat mean, variance or covariance (as ``kind``), and the exponents to the data's units."""
        check_is_fitted(self, "coef_")
        order = self._order
        if lags is None:
            index = np.arange(order)
        else:
            lags = check_signal(lags, "lags")
            index = np.round(lags).astype(int)
            if np.any(np.abs(lags - index) > 1e-9) or np.any(index < 0) or np.any(index >= order):
                raise ValueError(
                    f"lags must be integers in 0..{order - 1} for a least-squares FIR model"
                )
        # the input-major positions of the lags of every input
        index = (np.arange(self.n_inputs_)[:, None] * order + index[None, :]).reshape(-1)
        posterior, scale = units.split(self.posterior_)
        exponents = None if scale is None else scale.coefficient_exponents(order)[index]
        covariance = self.coef_covariance_ if scale is None else posterior.K
        mean = posterior.coef[index]
        if kind is None:
            return mean, None, exponents
        cov = covariance[np.ix_(index, index)]
        if kind == "cov":
            return mean, cov, exponents
        return mean, np.maximum(np.diag(cov), 0.0), exponents


# ----------------------------------------------------- readings at their own instants
class _TimedSamples(list):
    """``[sample_times]`` of a fit whose readings are not all fast samples."""


def _timed_samples(model, sample_indices, sample_times):
    """What ``fit`` passes on as ``sample_indices``: the indices, or the timed samples.

    Readings on the fast ticks (no exposure, ``t - latency`` integers) are
    the fast samples of those indices, with every fast path of the ticks.
    """
    exposure = check_duration(model.exposure, "exposure")
    latency = check_duration(model.latency, "latency")
    _between_ticks(model)
    if sample_times is None:
        if exposure or latency:
            raise ValueError(
                "exposure and latency apply to readings at their own instants: give "
                "sample_times (in fast sample periods)"
            )
        return sample_indices
    if sample_indices is not None:
        raise ValueError("give sample_indices or sample_times, not both")
    ticks = on_the_ticks(sample_times, exposure, latency)
    if ticks is not None:
        return ticks
    return _TimedSamples([sample_times])


#: the routes of readings between the fast ticks (``between_ticks``)
BETWEEN_TICKS = ("auto", "exact", "interpolated")
#: ``between_ticks="auto"`` interpolates above this many readings (and more than coefficients)
INTERPOLATED_ABOVE = 1000
#: ``between_ticks="auto"``: the largest estimated interpolation error, in noise std
INTERPOLATION_TOLERANCE = 0.2
#: ``between_ticks="auto"``: readings fitted exactly where the interpolation is not enough
EXACT_UP_TO = 3000


def _between_ticks(model) -> str:
    route = getattr(model, "between_ticks", "auto")
    if not (isinstance(route, str) and route in BETWEEN_TICKS):
        raise ValueError(f"between_ticks must be one of {BETWEEN_TICKS}; got {route!r}")
    return route


def _experiment(model, u, y_slow, sample_indices, order):
    """The experiment of a fit: on the fast ticks, or the readings at their own instants.

    Readings at their own instants are the exact timed observation, or its
    interpolation on the integer lags (``between_ticks``; by default for a
    long record: more readings than coefficients and than ``INTERPOLATED_ABOVE``).
    """
    if isinstance(sample_indices, _TimedSamples):
        experiment = build_timed_experiment(
            u, y_slow, sample_indices[0], order=order, exposure=model.exposure,
            latency=model.latency, initial_conditions=model.initial_conditions,
        )
        timed = experiment.observation
        route = getattr(model, "_between_ticks_used", None) or _between_ticks(model)
        shortest = min(record.n_samples for record in timed.records)
        if route == "interpolated" or (route == "auto" and timed.n_outputs > max(
                timed.n_coefficients, INTERPOLATED_ABOVE) and shortest >= DEFAULT_POINTS):
            return Experiment(InterpolatedConvolution(timed), experiment.y, experiment.n_inputs)
        return experiment
    return build_experiment(
        u, y_slow, sample_indices, factor=model.factor, offset=model.offset,
        order=order, initial_conditions=model.initial_conditions,
    )


def _is_zero_order_hold(u: np.ndarray, factor: int) -> bool:
    """True when ``u`` is held constant on every block of ``factor`` samples, for some
    alignment, at values that change between blocks."""
    if factor < 2 or u.shape[0] < 2 * factor:
        return False
    for shift in range(factor):
        head = u[shift:]
        n_blocks = head.shape[0] // factor
        blocks = head[: n_blocks * factor].reshape(n_blocks, factor)
        # held values that change from block to block: an input that is zero (or constant)
        # after a few samples, such as an impulse, is not zero-order hold
        if np.allclose(blocks, blocks[:, :1], rtol=1e-12, atol=1e-14 * np.max(np.abs(u))) and (
                np.ptp(blocks[:, 0]) > 1e-14 * np.max(np.abs(u))):
            return True
    return False
