"""Responses of identified FIR models as data objects, ready to be drawn.

The classes here hold what a figure shows and nothing about how it is drawn
(the functions of :mod:`gpmultirate.plotting` draw them):

* :class:`FrequencyResponse`: the FRF with pointwise credible bands on
  magnitude and phase (paper eq. 6).
* :class:`ImpulseResponse`: the impulse response at given lags with its
  posterior standard deviation and posterior draws.
* :class:`OutputPrediction`: the fast-rate (intersample) output predicted from
  slow samples, with its band, the true output and the slow samples.

Each has a ``from_model`` constructor that uses only the public API of a
fitted estimator.

The FRF ``G(f) = sum_i g_i exp(-j 2 pi f T i)`` is linear in the
coefficients, so a Gaussian posterior on ``g`` gives, at each frequency, a
bivariate Gaussian for ``(Re G, Im G)``.  The bands on magnitude and phase
are pointwise quantiles of that exact distribution, evaluated with a fixed
set of draws (magnitude and phase are non-linear functions of the Gaussian,
so their quantiles have no closed form).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.stats
from sklearn.exceptions import NotFittedError
from sklearn.utils.validation import check_is_fitted

from gpmultirate.validation import (
    as_real_array,
    check_array,
    check_inputs,
    check_int,
    check_level,
    check_positive,
    check_sample_indices,
    check_signal,
)

__all__ = [
    "FrequencyResponse",
    "ImpulseResponse",
    "OutputPrediction",
    "check_frequencies",
    "default_frequencies",
    "dft_matrix",
    "normal_quantile",
]

# Draws per frequency for the band quantiles; the quantile of a 95 % band is
# then accurate to about 0.3 % in probability.  Fixed seed: bands are
# deterministic.
_BAND_DRAWS = 8192
_BAND_SEED = 20250425
_CHUNK = 128


@dataclass(frozen=True)
class FrequencyResponse:
    """Frequency response of an identified FIR model with a pointwise band.

    Attributes
    ----------
    freqs : ndarray of shape (n,)
        Frequencies in Hz.
    mean : ndarray of shape (n,), complex
        FRF of the posterior-mean impulse response (equal to the posterior
        mean of the FRF).
    magnitude_lower, magnitude_upper : ndarray of shape (n,)
        Pointwise credible band of ``|G|`` at ``level``.
    phase_lower, phase_upper : ndarray of shape (n,)
        Pointwise credible band of the phase in radians, around
        :attr:`phase`.
    real_std, imag_std, real_imag_corr : ndarray of shape (n,)
        The exact bivariate Gaussian of ``(Re G, Im G)`` at each frequency.
    level : float
        Credible level of the bands.
    sample_time : float
        Fast sample time in seconds.
    factor : int
        Downsampling factor of the data the model was identified from.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.responses import FrequencyResponse
    >>> frf = FrequencyResponse.from_gaussian(
    ...     np.array([0.0, 1.0]), np.array([1.0 + 0j, 0.5j]),
    ...     np.array([0.01, 0.01]), np.array([0.01, 0.01]), np.zeros(2),
    ...     sample_time=0.5, factor=2)
    >>> frf.fast_nyquist, frf.slow_nyquist
    (1.0, 0.5)
    >>> bool(np.all(frf.magnitude_lower < frf.magnitude) and np.all(frf.magnitude < frf.magnitude_upper))
    True
    """

    freqs: np.ndarray
    mean: np.ndarray
    magnitude_lower: np.ndarray
    magnitude_upper: np.ndarray
    phase_lower: np.ndarray
    phase_upper: np.ndarray
    real_std: np.ndarray
    imag_std: np.ndarray
    real_imag_corr: np.ndarray
    level: float
    sample_time: float
    factor: int

    @property
    def magnitude(self) -> np.ndarray:
        """``|G|`` of the posterior mean."""
        return np.abs(self.mean)

    @property
    def phase(self) -> np.ndarray:
        """Unwrapped phase of the posterior mean in radians."""
        return np.unwrap(np.angle(self.mean))

    @property
    def fast_nyquist(self) -> float:
        """Nyquist frequency of the fast rate, ``1 / (2 T)`` in Hz."""
        return 0.5 / self.sample_time

    @property
    def slow_nyquist(self) -> float:
        """Nyquist frequency of the slow rate, ``1 / (2 F T)`` in Hz."""
        return 0.5 / (self.sample_time * self.factor)

    @classmethod
    def from_gaussian(
        cls,
        freqs,
        mean,
        var_real,
        var_imag,
        cov_real_imag,
        *,
        level: float = 0.95,
        sample_time: float = 1.0,
        factor: int = 1,
    ) -> "FrequencyResponse":
        """Build the bands from the bivariate Gaussian of ``(Re G, Im G)``.

        Parameters
        ----------
        freqs : ndarray of shape (n,)
        mean : complex ndarray of shape (n,)
        var_real, var_imag, cov_real_imag : ndarray of shape (n,)
            Covariance entries of ``(Re G, Im G)`` at each frequency.
        level : float, default=0.95
        sample_time : float, default=1.0
        factor : int, default=1

        Returns
        -------
        FrequencyResponse
        """
        level = check_level(level)
        mean = np.asarray(mean, dtype=complex)
        var_real = np.maximum(var_real, 0.0)
        var_imag = np.maximum(var_imag, 0.0)
        std_r, std_i = np.sqrt(var_real), np.sqrt(var_imag)
        denom = std_r * std_i
        corr = np.divide(cov_real_imag, denom, out=np.zeros_like(denom), where=denom > 0)
        corr = np.clip(corr, -1.0, 1.0)

        tails = [(1.0 - level) / 2.0, (1.0 + level) / 2.0]
        z = np.random.default_rng(_BAND_SEED).standard_normal((2, _BAND_DRAWS))
        n = mean.shape[0]
        mag_lo, mag_hi, ph_lo, ph_hi = (np.empty(n) for _ in range(4))
        for start in range(0, n, _CHUNK):
            part = slice(start, min(start + _CHUNK, n))
            # draws of (Re, Im) through the 2x2 Cholesky factor at each frequency
            re = mean[part].real[:, None] + std_r[part, None] * z[0]
            im = mean[part].imag[:, None] + std_i[part, None] * (
                corr[part, None] * z[0] + np.sqrt(1.0 - corr[part] ** 2)[:, None] * z[1]
            )
            draws = re + 1j * im
            mag_lo[part], mag_hi[part] = np.quantile(np.abs(draws), tails, axis=1)
            # phase relative to the mean's phase, so that the band never wraps
            relative = np.angle(draws * np.exp(-1j * np.angle(mean[part]))[:, None])
            ph_lo[part], ph_hi[part] = np.quantile(relative, tails, axis=1)
        phase = np.unwrap(np.angle(mean))
        return cls(
            freqs=np.asarray(freqs, dtype=float),
            mean=np.asarray(mean, dtype=complex),
            magnitude_lower=mag_lo,
            magnitude_upper=mag_hi,
            phase_lower=phase + ph_lo,
            phase_upper=phase + ph_hi,
            real_std=std_r,
            imag_std=std_i,
            real_imag_corr=corr,
            level=level,
            sample_time=float(sample_time),
            factor=int(factor),
        )


def default_frequencies(n_samples: int, sample_time: float) -> np.ndarray:
    """DFT bins ``k / (N T)``, ``k = 0..N/2``, of a record of ``N`` fast samples.

    Examples
    --------
    >>> default_frequencies(4, 0.5)
    array([0. , 0.5, 1. ])
    """
    return np.fft.rfftfreq(int(n_samples), d=float(sample_time))


def check_frequencies(freqs, sample_time) -> tuple[np.ndarray, float]:
    """Validate a frequency grid in Hz and a sample time.

    Examples
    --------
    >>> check_frequencies([0.0, 1.5], 0.1)
    (array([0. , 1.5]), 0.1)
    """
    sample_time = check_positive(sample_time, "sample_time")
    freqs = check_signal(freqs, "freqs")
    if np.any(freqs < 0):
        raise ValueError("freqs must be non-negative (Hz)")
    return freqs, sample_time


def dft_matrix(freqs, sample_time: float, order: int) -> np.ndarray:
    """Matrix ``E[k, i] = exp(-j 2 pi f_k T i)`` mapping FIR coefficients to the FRF.

    Examples
    --------
    >>> E = dft_matrix([0.0, 0.25], sample_time=1.0, order=2)
    >>> E.round(3)
    array([[1.+0.j, 1.+0.j],
           [1.+0.j, 0.-1.j]])
    """
    freqs = np.asarray(freqs, dtype=float)
    return np.exp(-2j * np.pi * sample_time * np.outer(freqs, np.arange(order)))


# ------------------------------------------------------------- shared pieces
def normal_quantile(level: float) -> float:
    """Two-sided standard normal quantile ``z`` of a credible ``level``.

    ``P(|Z| <= z) = level`` for a standard normal ``Z``, so that
    ``mean +- z std`` is the central Gaussian interval at ``level``.

    Parameters
    ----------
    level : float
        Credible level in (0, 1).

    Returns
    -------
    float

    Examples
    --------
    >>> round(normal_quantile(0.95), 6)
    1.959964
    """
    return float(scipy.stats.norm.ppf(0.5 + check_level(level) / 2.0))


def _frozen(array: np.ndarray) -> np.ndarray:
    """``array`` (already a private copy) made read-only, as the dataclasses are frozen."""
    array.setflags(write=False)
    return array


def _check_fitted(model) -> None:
    """Refuse anything but a fitted scikit-learn style estimator, naming ``model``."""
    try:
        check_is_fitted(model)
    except (NotFittedError, TypeError) as exc:
        raise ValueError(
            f"model must be a fitted FIR estimator; got {type(model).__name__} ({exc})"
        ) from None


def _span(values: np.ndarray) -> str:
    return f"[{values.min():g}, {values.max():g}]" if values.size else "[]"


# ----------------------------------------------------------- impulse response
@dataclass(frozen=True, eq=False, repr=False)
class ImpulseResponse:
    """Impulse response of an identified FIR model at given lags, with a band.

    Attributes
    ----------
    lags : ndarray of shape (n,)
        Lags in fast samples.
    mean : ndarray of shape (n,)
        Posterior mean (or least-squares estimate) of ``g`` at ``lags``.
    std : ndarray of shape (n,) or None
        Posterior standard deviation of ``g`` at ``lags``; None without one.
    level : float
        Credible level of the band :attr:`lower`, :attr:`upper`.
    samples : ndarray of shape (n, k)
        ``k`` posterior draws of ``g`` at ``lags``, one per column (``k`` may be 0).
    continuous : bool
        True for a Gaussian process over real lags (drawn as a curve), False
        for coefficients at integer lags (drawn with markers).

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.responses import ImpulseResponse
    >>> response = ImpulseResponse(lags=np.arange(3.0), mean=np.array([1.0, 0.5, 0.25]),
    ...                            std=np.full(3, 0.1), level=0.95, continuous=False)
    >>> response
    ImpulseResponse(3 lags in [0, 2], integer lags, level=0.95, std, 0 samples)
    >>> response.upper.round(3)
    array([1.196, 0.696, 0.446])
    """

    lags: np.ndarray
    mean: np.ndarray
    std: np.ndarray | None = None
    level: float = 0.95
    samples: np.ndarray | None = None
    continuous: bool = True

    def __post_init__(self) -> None:
        lags = check_signal(self.lags, "lags")
        n = lags.shape[0]
        mean = check_signal(self.mean, "mean")
        if mean.shape != (n,):
            raise ValueError(f"mean must have one value per lag ({n}); got {mean.shape[0]}")
        std = None
        if self.std is not None:
            std = check_signal(self.std, "std")
            if std.shape != (n,) or np.any(std < 0):
                raise ValueError(f"std must hold {n} non-negative values, one per lag")
        if self.samples is None:
            samples = np.empty((n, 0))
        else:
            samples = check_array(self.samples, "samples", ndims=(2,))
            if samples.shape[0] != n:
                raise ValueError(
                    f"samples must have shape ({n}, k), one row per lag; got {samples.shape}"
                )
        if not isinstance(self.continuous, (bool, np.bool_)):
            raise ValueError(f"continuous must be True or False; got {self.continuous!r}")
        set_ = object.__setattr__  # the dataclass is frozen: normalise once, here
        set_(self, "lags", _frozen(lags))
        set_(self, "mean", _frozen(mean))
        set_(self, "std", None if std is None else _frozen(std))
        set_(self, "level", check_level(self.level))
        set_(self, "samples", _frozen(samples))
        set_(self, "continuous", bool(self.continuous))

    @property
    def lower(self) -> np.ndarray | None:
        """``mean - z std`` with ``z`` the two-sided normal quantile of ``level``."""
        if self.std is None:
            return None
        return self.mean - normal_quantile(self.level) * self.std

    @property
    def upper(self) -> np.ndarray | None:
        """``mean + z std`` with ``z`` the two-sided normal quantile of ``level``."""
        if self.std is None:
            return None
        return self.mean + normal_quantile(self.level) * self.std

    @property
    def n_samples(self) -> int:
        """Number of posterior draws in :attr:`samples`."""
        return int(self.samples.shape[1])

    def __repr__(self) -> str:
        kind = "continuous lags" if self.continuous else "integer lags"
        std = "std" if self.std is not None else "no std"
        return (f"ImpulseResponse({self.lags.shape[0]} lags in {_span(self.lags)}, {kind}, "
                f"level={self.level:g}, {std}, {self.n_samples} samples)")

    @classmethod
    def from_model(
        cls,
        model,
        lags=None,
        *,
        level: float = 0.95,
        n_samples: int = 0,
        random_state=None,
    ) -> "ImpulseResponse":
        """Impulse response of a fitted estimator, through its public API.

        The mean and standard deviation come from
        ``model.impulse_response(lags, return_std=True)`` and the draws from
        ``model.sample_impulse_responses(lags, n_samples=..., random_state=...)``;
        ``model.continuous_lags`` tells whether the model is defined at real
        lags (:class:`~gpmultirate.FIRGaussianProcess`) or only at integer
        lags ``0..P-1`` (:class:`~gpmultirate.LeastSquaresFIR`).

        Parameters
        ----------
        model : fitted FIRGaussianProcess or LeastSquaresFIR
        lags : array-like of shape (n,), optional
            Lags in fast samples.  By default 4 points per sample over
            ``0..P-1`` for a model over continuous lag, else ``0..P-1``.
        level : float, default=0.95
            Credible level of the band, in (0, 1).
        n_samples : int, default=0
            Number of posterior draws.
        random_state : int, RandomState or None
            Seed of the draws.

        Returns
        -------
        ImpulseResponse

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
        >>> import gpmultirate as gm
        >>> from gpmultirate.kernels import DC
        >>> from gpmultirate.responses import ImpulseResponse
        >>> rng = np.random.default_rng(0)
        >>> g = 0.9 ** np.arange(40) * np.cos(0.8 * np.arange(40))
        >>> u = rng.standard_normal(120)
        >>> model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=40, noise_level=1e-4,
        ...                               optimizer=None).fit(u, np.convolve(u, g)[:120:3])
        >>> ImpulseResponse.from_model(model, n_samples=3, random_state=0)
        ImpulseResponse(157 lags in [0, 39], continuous lags, level=0.95, std, 3 samples)
        """
        _check_fitted(model)
        level = check_level(level)
        n_samples = check_int(n_samples, "n_samples", low=0)
        try:
            continuous = model.continuous_lags
        except AttributeError:
            raise ValueError(
                f"model must have a continuous_lags attribute (a gpmultirate estimator); "
                f"got {type(model).__name__}"
            ) from None
        if lags is None:
            order = model.coef_.shape[0]
            lags = (np.linspace(0.0, order - 1.0, 4 * (order - 1) + 1) if continuous
                    else np.arange(order))
        mean, std = model.impulse_response(lags, return_std=True)
        lags = np.asarray(lags, dtype=float).reshape(-1)
        samples = (model.sample_impulse_responses(lags, n_samples=n_samples,
                                                  random_state=random_state)
                   if n_samples else None)
        return cls(lags=lags, mean=mean, std=std, level=level, samples=samples,
                   continuous=bool(continuous))


# ----------------------------------------------------------- output prediction
@dataclass(frozen=True, eq=False, repr=False)
class OutputPrediction:
    """Fast-rate output predicted from slow samples, with its credible band.

    Attributes
    ----------
    time : ndarray of shape (N,)
        Fast-rate instants ``n T`` in seconds.
    mean : ndarray of shape (N,)
        Predicted noise-free fast-rate output.
    std : ndarray of shape (N,)
        Its posterior standard deviation.
    level : float
        Credible level of the band :attr:`lower`, :attr:`upper`.
    slow_index : int ndarray of shape (M,)
        Fast-sample indices ``offset + m F`` of the slow samples.
    y_fast : ndarray of shape (N,) or None
        True fast-rate output.
    y_slow : ndarray of shape (M,) or None
        The slow samples.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.responses import OutputPrediction
    >>> prediction = OutputPrediction(time=0.1 * np.arange(6), mean=np.ones(6),
    ...                               std=np.full(6, 0.5), level=0.5,
    ...                               slow_index=np.arange(0, 6, 3), y_slow=np.ones(2))
    >>> prediction
    OutputPrediction(6 fast samples over [0, 0.5] s, 2 slow samples, level=0.5, y_slow)
    >>> prediction.slow_time, prediction.upper[:2].round(4)
    (array([0. , 0.3]), array([1.3372, 1.3372]))
    """

    time: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    level: float = 0.95
    slow_index: np.ndarray | None = None
    y_fast: np.ndarray | None = None
    y_slow: np.ndarray | None = None

    def __post_init__(self) -> None:
        time = check_signal(self.time, "time")
        n = time.shape[0]

        def per_instant(value, name):
            value = check_signal(value, name)
            if value.shape != (n,):
                raise ValueError(f"{name} must have one value per instant of time ({n}); "
                                 f"got {value.shape[0]}")
            return _frozen(value)

        std = per_instant(self.std, "std")
        if np.any(std < 0):
            raise ValueError("std must be non-negative")
        index = np.empty(0, dtype=int)
        if self.slow_index is not None:
            raw = np.asarray(self.slow_index)
            if raw.ndim != 1 or raw.dtype.kind not in "iu" or np.any(raw < 0) \
                    or np.any(raw >= n):
                raise ValueError(f"slow_index must be a 1-D array of integers in 0..{n - 1}")
            index = raw.astype(int)
        y_slow = None
        if self.y_slow is not None:
            y_slow = check_signal(self.y_slow, "y_slow")
            if y_slow.shape != index.shape:
                raise ValueError(f"y_slow must have one value per slow_index "
                                 f"({index.shape[0]}); got {y_slow.shape[0]}")
        set_ = object.__setattr__  # the dataclass is frozen: normalise once, here
        set_(self, "time", _frozen(time))
        set_(self, "mean", per_instant(self.mean, "mean"))
        set_(self, "std", std)
        set_(self, "level", check_level(self.level))
        set_(self, "slow_index", _frozen(index))
        set_(self, "y_fast", None if self.y_fast is None else per_instant(self.y_fast, "y_fast"))
        set_(self, "y_slow", None if y_slow is None else _frozen(y_slow))

    @property
    def slow_time(self) -> np.ndarray:
        """Instants of the slow samples in seconds, ``time[slow_index]``."""
        return self.time[self.slow_index]

    @property
    def lower(self) -> np.ndarray:
        """``mean - z std`` with ``z`` the two-sided normal quantile of ``level``."""
        return self.mean - normal_quantile(self.level) * self.std

    @property
    def upper(self) -> np.ndarray:
        """``mean + z std`` with ``z`` the two-sided normal quantile of ``level``."""
        return self.mean + normal_quantile(self.level) * self.std

    def __repr__(self) -> str:
        given = [name for name in ("y_fast", "y_slow") if getattr(self, name) is not None]
        return (f"OutputPrediction({self.time.shape[0]} fast samples over {_span(self.time)} s, "
                f"{self.slow_index.shape[0]} slow samples, level={self.level:g}"
                + "".join(f", {name}" for name in given) + ")")

    def select(self, window) -> "OutputPrediction":
        """The prediction on the fast samples ``start..stop-1`` of ``window``.

        Parameters
        ----------
        window : pair of int
            ``(start, stop)`` with ``0 <= start < stop <= N``.

        Returns
        -------
        OutputPrediction
            With the slow samples inside the window, re-indexed.

        Examples
        --------
        >>> import numpy as np
        >>> from gpmultirate.responses import OutputPrediction
        >>> full = OutputPrediction(time=np.arange(9.0), mean=np.zeros(9), std=np.ones(9),
        ...                         slow_index=np.arange(0, 9, 3))
        >>> part = full.select((2, 8))
        >>> part.time, part.slow_time
        (array([2., 3., 4., 5., 6., 7.]), array([3., 6.]))
        """
        n = self.time.shape[0]
        if not isinstance(window, (Sequence, np.ndarray)) or len(window) != 2:
            raise ValueError(f"window must be a pair (start, stop); got {window!r}")
        start, stop = (check_int(w, "window", low=0, high=n) for w in window)
        if start >= stop:
            raise ValueError(f"window must satisfy start < stop; got {window!r}")
        inside = (self.slow_index >= start) & (self.slow_index < stop)
        part = slice(start, stop)
        return OutputPrediction(
            time=self.time[part], mean=self.mean[part], std=self.std[part], level=self.level,
            slow_index=self.slow_index[inside] - start,
            y_fast=None if self.y_fast is None else self.y_fast[part],
            y_slow=None if self.y_slow is None else self.y_slow[inside],
        )

    @classmethod
    def from_model(
        cls,
        model,
        u,
        *,
        y_fast=None,
        y_slow=None,
        factor: int | None = None,
        offset: int | None = None,
        sample_time: float | None = None,
        level: float = 0.95,
        sample_indices=None,
    ) -> "OutputPrediction":
        """Fast-rate output of a fitted estimator for input ``u``, with its band.

        The mean and standard deviation of the noise-free output come from
        ``model.predict(u, return_std=True)``; the slow samples lie at the
        fast indices ``offset + m factor``, or at ``sample_indices``.

        Parameters
        ----------
        model : fitted FIRGaussianProcess or LeastSquaresFIR
        u : array-like of shape (N,) or (N, n_inputs)
            Fast-rate input(s), shaped as in the model's ``fit``.
        y_fast : array-like of shape (N,), optional
            True fast-rate output.
        y_slow : array-like of shape (M,), optional
            Slow samples, ``M = len(range(offset, N, factor))`` or
            ``len(sample_indices)``; ``NaN`` marks one that was not measured
            (it is not drawn).
        factor, offset : int, optional
            Placement of the slow samples; by default the model's
            (``model.factor`` and ``model.offset``).
        sample_time : float, optional
            Fast sample time ``T`` in seconds (``time`` is ``n T``); by
            default the model's ``sample_time`` (1.0 if it has none).
        level : float, default=0.95
            Credible level of the band, in (0, 1).
        sample_indices : array-like of int, optional
            The fast index of each slow sample, instead of ``factor`` and
            ``offset``.

        Returns
        -------
        OutputPrediction

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
        >>> import gpmultirate as gm
        >>> from gpmultirate.kernels import DC
        >>> from gpmultirate.responses import OutputPrediction
        >>> rng = np.random.default_rng(0)
        >>> g = 0.9 ** np.arange(40) * np.cos(0.8 * np.arange(40))
        >>> u = rng.standard_normal(120)
        >>> y_fast = np.convolve(u, g)[:120]
        >>> model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=40, noise_level=1e-4,
        ...                               optimizer=None).fit(u, y_fast[::3])
        >>> prediction = OutputPrediction.from_model(model, u, y_fast=y_fast,
        ...                                          y_slow=y_fast[::3], sample_time=0.1)
        >>> float(prediction.time[-1]), prediction.slow_time[:3]
        (11.9, array([0. , 0.3, 0.6]))
        """
        _check_fitted(model)
        n = check_inputs(u, "u").shape[0]
        if sample_indices is not None:
            slow_index = check_sample_indices(sample_indices, n, "sample_indices")
        else:
            factor = model.factor if factor is None else factor
            offset = model.offset if offset is None else offset
            factor = check_int(factor, "factor", low=1)
            offset = check_int(offset, "offset", low=0, high=factor - 1)
            slow_index = np.arange(offset, n, factor)
        if sample_time is None:
            sample_time = getattr(model, "sample_time", 1.0)
        sample_time = check_positive(sample_time, "sample_time")
        level = check_level(level)
        if y_fast is not None:
            y_fast = check_signal(y_fast, "y_fast")
            if y_fast.shape[0] != n:
                raise ValueError(f"y_fast must have len(u) = {n} samples; got {y_fast.shape[0]}")
        if y_slow is not None:
            y_slow = as_real_array(y_slow, "y_slow").reshape(-1)
            if np.any(np.isinf(y_slow)):
                raise ValueError("y_slow must not contain inf (NaN marks a missing sample)")
            if y_slow.shape[0] != slow_index.shape[0]:
                raise ValueError(
                    f"y_slow must have one sample per slow instant "
                    f"({slow_index.shape[0]}); got {y_slow.shape[0]}"
                )
            measured = np.isfinite(y_slow)
            slow_index, y_slow = slow_index[measured], y_slow[measured]
        mean, std = model.predict(u, return_std=True)
        return cls(time=np.arange(n) * sample_time, mean=mean, std=std, level=level,
                   slow_index=slow_index, y_fast=y_fast, y_slow=y_slow)
