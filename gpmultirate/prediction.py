"""Prediction, scoring and the frequency response of a fitted FIR model.

:class:`FIRModelMixin` reads a fitted estimator's posterior of the
coefficients (a :class:`~gpmultirate.inference.GaussianCoefficients`): the
fast-rate output of an input (the convolution of eq. 8 at every fast tick),
readings on the fast ticks, the goodness of fit (eq. 20), the frequency
response with its credible band, and draws of the impulse response.  Both
estimators of :mod:`gpmultirate.estimators` share it.
"""

from __future__ import annotations

import weakref

import numpy as np
from sklearn.utils.validation import check_is_fitted

from gpmultirate import units
from gpmultirate.bands import (
    convolution_variance,
    dft_bins,
    dft_variances,
    frequency_variances,
)
from gpmultirate.inference import gaussian_samples
from gpmultirate.metrics import goodness_of_fit
from gpmultirate.observations import regressor_rows
from gpmultirate.observations.experiment import check_records, is_record_list
from gpmultirate.observations.timed import on_the_ticks
from gpmultirate.responses import (
    FrequencyResponse,
    check_frequencies,
    default_frequencies,
    dft_matrix,
)
from gpmultirate.validation import (
    check_int,
    check_level,
    check_rng,
    check_sample_indices,
    check_sample_time,
    check_signal,
)

__all__ = ["FIRModelMixin"]


class FIRModelMixin:
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
            stamped at these instants (in the units of ``sample_time``:
            seconds, fast sample periods when it is 1; strictly increasing
            in ``[0, len(u) T)``), with the model's exposure and
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
            predicted = self._predict_std_in_fit_units(u, sample_times)
            noise_std, exponent = self._measurement_noise_std()
            # combined in the fit's units, then scaled by a power of two: no
            # square of a data-unit value can overflow near the float range
            if is_record_list(u):
                return [(np.ldexp(m, exponent), np.ldexp(np.hypot(s, noise_std), exponent))
                        for m, s in predicted]
            mean, std = predicted
            return np.ldexp(mean, exponent), np.ldexp(np.hypot(std, noise_std), exponent)
        if is_record_list(u):
            if sample_times is None:
                return [self.predict(u_r, return_std) for u_r in u]
            if not is_record_list(sample_times) or len(sample_times) != len(u):
                raise ValueError("sample_times must be a list with one entry per record of u")
            return [self.predict(u_r, return_std, t) for u_r, t in zip(u, sample_times)]
        x = self._check_prediction_input(u)
        if sample_times is not None:
            return self._predict_readings(
                x, units.in_fast_periods(sample_times, self.sample_time, x, readings=False),
                return_std)
        return self._in_data_units(
            x, lambda x, posterior, scale: self._predict_normalized(x, posterior, return_std),
            return_std)

    def _in_data_units(self, x, predict, return_std: bool):
        """``predict(x, posterior, scale)`` in the units of the normalized fit, scaled at the end.

        ``x``: the input(s) in the data's units; ``predict`` gets them in the
        fit's units with the posterior there and the ``DataScale`` (None
        where the posterior is in the data's units already).
        """
        posterior, scale = units.split(self.posterior_)
        if scale is None:
            return predict(x, posterior, None)
        out = predict(np.ldexp(x, -scale.input_exponents[None, :]), posterior, scale)
        if return_std:
            return tuple(np.ldexp(v, scale.output_exponent) for v in out)
        return np.ldexp(out, scale.output_exponent)

    def _predict_normalized(self, x, posterior, return_std):
        n = x.shape[0]
        periodic = self.initial_conditions == "periodic"
        coef = posterior.coef.reshape(self.n_inputs_, -1)
        if not return_std and not periodic:
            return sum(np.convolve(x[:, k], coef[k])[:n] for k in range(x.shape[1]))
        if return_std and not periodic and coef.shape[1] >= _FFT_MIN_ORDER:
            # diag(T Sigma T^T) by FFT: O(P (N + P) log) instead of O(N P^2)
            mean = sum(np.convolve(x[:, k], coef[k])[:n] for k in range(x.shape[1]))
            return mean, np.sqrt(convolution_variance(x, _covariance(posterior)))
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

    def _output_exponent(self) -> int:
        """``e`` with ``output_scale_ = 2**e``: the fit's units are the data's over ``2**e``."""
        return int(np.frexp(getattr(self, "output_scale_", 1.0))[1] - 1)

    def _predict_std_in_fit_units(self, u, sample_times):
        """``predict(u, True, sample_times)`` divided by ``2**_output_exponent()``."""
        exponent = self._output_exponent()
        predicted = self.predict(u, True, sample_times)
        if is_record_list(u):
            return [(np.ldexp(m, -exponent), np.ldexp(s, -exponent)) for m, s in predicted]
        return tuple(np.ldexp(v, -exponent) for v in predicted)

    def _measurement_noise_std(self) -> tuple[float, int]:
        """The standard deviation of one measured sample's noise (disturbance and white noise).

        Returned as ``(std, e)``, the value in the data's units being
        ``std * 2**e``: a variance in the data's units may overflow where
        the standard deviation does not (data near ``1e300``).
        """
        model = getattr(self, "_noise_model", None)
        exponent = self._output_exponent()
        if model is not None and not model.white:  # tuned on the normalized data
            return float(np.sqrt(model.sample_variance())), exponent
        if hasattr(self, "noise_level_"):
            if getattr(self, "hyperparameter_units_", "data") == "normalized":
                return float(np.sqrt(self.noise_level_)), exponent
            variance = float(self.noise_level_)
        else:
            variance = float(self.noise_variance_)
        # a variance in the data's units: its square root in the fit's units
        return float(np.sqrt(np.ldexp(variance, -2 * exponent))), exponent

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

        This is the paper's measure, ``100 (1 - ||y - y_hat||^2 / ||y - mean(y)||^2)``
        (squared errors), not the normalized fit that other identification
        toolboxes report, ``100 (1 - ||y - y_hat|| / ||y - mean(y)||)``: that
        one is :func:`gpmultirate.fit_percent`, which the command line's
        summary gives beside it.  A score of 99.99 is a fit percent of 99.

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
        posterior, scale = units.split(self.posterior_)
        if P >= _FFT_MIN_ORDER:  # from the posterior covariance, E never formed
            block = slice(k * P, (k + 1) * P)
            mean, cov = posterior.coef[block], _covariance(posterior)[block, block]
            length = dft_bins(freqs, sample_time)
            # the DFT bins of a length: E Sigma by FFT; else the (anti-)diagonal sums
            mean, var_re, var_im, cov = (
                dft_variances(mean, cov, freqs.size, length) if length is not None
                else frequency_variances(mean, cov, 2.0 * np.pi * sample_time * freqs))
        else:
            E = dft_matrix(freqs, sample_time, P)
            # the DFT of input k's block of the input-major coefficients
            A = np.zeros((E.shape[0], self.n_inputs_ * P), dtype=complex)
            A[:, k * P : (k + 1) * P] = E
            re, im = np.ascontiguousarray(A.real), np.ascontiguousarray(A.imag)
            var_re, var_im, cov = posterior.pair_variances(re, im)
            mean = A @ posterior.coef
        frf = FrequencyResponse.from_gaussian(
            freqs,
            mean,
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


# the P x P covariance of the latest posterior whose bands were asked for: the command's
# predictions and Bode band share one (K - B^T B costs M P^2 flops, 3e10 at M = 2,000 and
# P = 4,000), and it goes with its posterior
_COVARIANCES: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _covariance(posterior) -> np.ndarray:
    """``posterior.covariance()``, kept while the posterior lives (the latest one only)."""
    try:
        return _COVARIANCES[posterior]
    except (KeyError, TypeError):
        pass
    cov = posterior.covariance()
    try:
        _COVARIANCES.clear()
        _COVARIANCES[posterior] = cov
    except TypeError:  # not weakly referable or not hashable: not kept
        pass
    return cov


# entries of the convolution matrix formed at once by predict(..., return_std=True)
_PREDICT_BLOCK_ENTRIES = 2**22
# from this order on, the bands of predict and frequency_response come from the
# P x P posterior covariance by FFT or its diagonal sums (gpmultirate.bands), not row by row
_FFT_MIN_ORDER = 128
