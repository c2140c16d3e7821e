"""Responses of identified FIR models as data objects, ready to be drawn.

The classes here hold what a figure shows and nothing about how it is drawn
(the functions of :mod:`gpmultirate.plotting` draw them):

* :class:`FrequencyResponse`: the FRF with pointwise credible bands on
  magnitude and phase, projections of the credible ellipse of
  ``(Re G, Im G)`` (paper eq. 6).
* :class:`ImpulseResponse`: the impulse response at given lags with its
  posterior standard deviation and posterior draws.
* :class:`OutputPrediction`: the fast-rate (intersample) output predicted from
  slow samples, with its band, the true output and the slow samples.

Each has a ``from_model`` constructor that uses only the public API of a
fitted estimator.

The FRF ``G(f) = sum_i g_i exp(-j 2 pi f T i)`` is linear in the
coefficients, so a Gaussian posterior on ``g`` gives, at each frequency, a
bivariate Gaussian for ``(Re G, Im G)``.  The bands on magnitude and phase
are the exact projections of its credible ellipse (chi-square with two
degrees of freedom), so that wherever the ellipse holds the true FRF both
bands hold its magnitude and its phase; where the ellipse contains 0 the
magnitude band reaches 0 and the phase is undefined.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.stats
from sklearn.exceptions import NotFittedError
from sklearn.utils.validation import check_is_fitted

from gpmultirate.optional import import_control
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

@dataclass(frozen=True, repr=False)
class FrequencyResponse:
    """Frequency response of an identified FIR model with pointwise credible bands.

    At each frequency the posterior of ``(Re G, Im G)`` is an exact bivariate
    Gaussian (:attr:`real_std`, :attr:`imag_std`, :attr:`real_imag_corr`).  Its
    credible region at :attr:`level` is the ellipse
    ``(z - mean)^T Sigma^{-1} (z - mean) <= chi2_2(level)`` (chi-square with two
    degrees of freedom), and the two bands are the projections of that
    ellipse:

    * magnitude band ``[magnitude_lower, magnitude_upper]``: the smallest and the
      largest ``|z|`` over the ellipse (``magnitude_lower`` is 0 where the
      ellipse contains 0);
    * phase band ``[phase_lower, phase_upper]``: the range of the angle of ``z``
      over the ellipse, around :attr:`phase`; where the ellipse contains 0 the
      phase is not defined (:attr:`phase_defined` is False) and the band is the
      whole circle, ``phase +- pi``.

    Wherever the ellipse contains the true FRF, both bands contain its
    magnitude and its phase (modulo a full turn), so each band holds the truth
    at least as often as the ellipse does: a band is a statement about the
    region, not an equal-tailed quantile of ``|G|``, which would exclude
    magnitudes near 0 whenever the mean is small.

    Attributes
    ----------
    freqs : ndarray of shape (n,)
        Frequencies in :attr:`frequency_unit` (Hz, or cycles per sample when
        ``sample_time`` is 1).
    mean : ndarray of shape (n,), complex
        FRF of the posterior-mean impulse response (equal to the posterior
        mean of the FRF).
    magnitude_lower, magnitude_upper : ndarray of shape (n,)
        Projection of the credible ellipse on ``|G|``.
    phase_lower, phase_upper : ndarray of shape (n,)
        Projection of the credible ellipse on the phase in radians, on the
        branch of :attr:`phase`.
    real_std, imag_std, real_imag_corr : ndarray of shape (n,)
        The exact bivariate Gaussian of ``(Re G, Im G)`` at each frequency.
    level : float
        Credible level of the ellipse.
    sample_time : float
        Fast sample time in seconds (1.0: none was given, frequencies are in
        cycles per sample).
    factor : int
        Downsampling factor of the data the model was identified from.
    phase_defined : bool ndarray of shape (n,)
        False where the credible ellipse contains 0.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.responses import FrequencyResponse
    >>> frf = FrequencyResponse.from_gaussian(
    ...     np.array([0.0, 1.0]), np.array([1.0 + 0j, 0.5j]),
    ...     np.array([0.01, 0.01]), np.array([0.01, 0.01]), np.zeros(2),
    ...     sample_time=0.5, factor=2)
    >>> frf
    FrequencyResponse(2 frequencies in [0, 1] Hz, level=0.95, factor=2, sample_time=0.5, phase defined at 2 of 2)
    >>> frf.fast_nyquist, frf.slow_nyquist
    (1.0, 0.5)

    Uncorrelated, equal variances: the ellipse is a circle of radius
    ``sqrt(chi2_2(0.95) 0.01) = 0.245``, so the magnitude band is ``|mean| +- 0.245``.

    >>> (frf.magnitude_upper - frf.magnitude).round(3)
    array([0.245, 0.245])
    >>> np.degrees(frf.phase_upper - frf.phase).round(1)  # asin(0.245 / |mean|)
    array([14.2, 29.3])

    A mean close to 0: the ellipse contains 0, the phase is undefined.

    >>> small = FrequencyResponse.from_gaussian([0.1], [0.1 + 0j], [0.01], [0.01], [0.0])
    >>> small.phase_defined, small.magnitude_lower, small.frequency_unit
    (array([False]), array([0.]), 'cycles/sample')
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
    phase_defined: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.phase_defined is None:
            # built without it: recompute it from the Gaussian, the one definition
            cov = self.real_imag_corr * self.real_std * self.imag_std
            defined = ~_region_contains_zero(self.mean, self.real_std ** 2,
                                             self.imag_std ** 2, cov, _chi2_2(self.level))
            object.__setattr__(self, "phase_defined", defined)
        else:
            object.__setattr__(self, "phase_defined",
                               np.asarray(self.phase_defined, dtype=bool))

    def __repr__(self) -> str:
        n = self.freqs.shape[0]
        return (f"FrequencyResponse({n} frequenc{'y' if n == 1 else 'ies'} in "
                f"{_span(self.freqs)} {self.frequency_unit}, level={self.level:g}, "
                f"factor={self.factor}, sample_time={self.sample_time:g}, "
                f"phase defined at {int(np.sum(self.phase_defined))} of {n})")

    @property
    def frequency_unit(self) -> str:
        """Unit of :attr:`freqs`: ``"Hz"``, or ``"cycles/sample"`` when ``sample_time == 1``.

        A sample time of exactly 1 is the estimators' default, used when no
        sample time was given: frequencies are then in cycles per sample.
        """
        return "cycles/sample" if self.sample_time == 1.0 else "Hz"

    def to_control(self):
        """This response as a ``control.FrequencyResponseData`` (python-control).

        Needs the optional extra: ``pip install "gpmultirate[control]"``.
        The frequencies are converted to radians per second.

        Returns
        -------
        control.FrequencyResponseData
        """
        control = import_control()
        freqs = np.asarray(self.freqs, dtype=float)
        mean = np.asarray(self.mean, dtype=complex)
        order = np.argsort(freqs, kind="stable")
        return control.FrequencyResponseData(mean[order].copy(), 2 * np.pi * freqs[order],
                                             dt=self.sample_time)

    @property
    def magnitude(self) -> np.ndarray:
        """``|G|`` of the posterior mean."""
        return np.abs(self.mean)

    @property
    def phase(self) -> np.ndarray:
        """Phase of the posterior mean in radians, unwrapped only where it is defined.

        Unwrapping runs along each stretch of frequencies where
        :attr:`phase_defined` is True and restarts after every stretch where
        it is not: the first value of a stretch is put on the branch nearest
        the last defined value before it (the principal value for the first
        stretch), so that wraps of a phase lost in noise never accumulate.
        Where the phase is undefined the value is the mean's angle continued
        from the last defined value; it is the centre of the whole-circle
        band there and has no meaning of its own.
        """
        return _unwrap_where_defined(np.angle(self.mean), self.phase_defined)

    @property
    def fast_nyquist(self) -> float:
        """Nyquist frequency of the fast rate, ``1 / (2 T)``, in :attr:`frequency_unit`."""
        return 0.5 / self.sample_time

    @property
    def slow_nyquist(self) -> float:
        """Nyquist frequency of the slow rate, ``1 / (2 F T)``, in :attr:`frequency_unit`."""
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

        The bands are the exact projections of the ``level`` credible ellipse
        on magnitude and phase (see :class:`FrequencyResponse`), computed per
        frequency in closed form (phase) and from the stationary points of the
        distance to the origin along the ellipse (magnitude).

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

        Examples
        --------
        >>> from gpmultirate.responses import FrequencyResponse
        >>> frf = FrequencyResponse.from_gaussian([0.2], [3.0 + 0j], [1.0], [0.25], [0.0],
        ...                                       level=0.5)
        >>> c = -2 * np.log(1 - 0.5)  # chi-square quantile, two degrees of freedom
        >>> bool(np.isclose(frf.magnitude_upper[0], 3 + np.sqrt(c)))
        True
        """
        level = check_level(level)
        mean = np.array(mean, dtype=complex).reshape(-1)
        var_real = np.maximum(np.asarray(var_real, dtype=float).reshape(-1), 0.0)
        var_imag = np.maximum(np.asarray(var_imag, dtype=float).reshape(-1), 0.0)
        cov = np.asarray(cov_real_imag, dtype=float).reshape(-1)
        std_r, std_i = np.sqrt(var_real), np.sqrt(var_imag)
        denom = std_r * std_i
        corr = np.divide(cov, denom, out=np.zeros_like(denom), where=denom > 0)
        corr = np.clip(corr, -1.0, 1.0)
        cov = corr * denom  # a positive semi-definite covariance
        c = _chi2_2(level)
        contains_zero = _region_contains_zero(mean, var_real, var_imag, cov, c)
        mag_lo, mag_hi = _magnitude_range(mean, var_real, var_imag, cov, c)
        mag_lo[contains_zero] = 0.0
        ph_lo, ph_hi = _relative_phase_range(mean, var_real, var_imag, cov, c)
        ph_lo[contains_zero], ph_hi[contains_zero] = -np.pi, np.pi
        defined = ~contains_zero
        phase = _unwrap_where_defined(np.angle(mean), defined)
        return cls(
            freqs=np.array(freqs, dtype=float).reshape(-1),
            mean=mean,
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
            phase_defined=defined,
        )


# ------------------------------------------------- projections of the ellipse
def _chi2_2(level: float) -> float:
    """Quantile of the chi-square distribution with 2 degrees of freedom."""
    return float(-2.0 * np.log1p(-level))


def _region_contains_zero(mean, var_real, var_imag, cov, c) -> np.ndarray:
    """Whether ``0`` lies in ``{z : (z - m)^T S^{-1} (z - m) <= c}``, also for singular ``S``.

    ``0`` is inside exactly when ``(n . m)^2 <= c n^T S n`` for every direction
    ``n``, that is when ``Q = m m^T - c S`` is negative semi-definite: trace
    ``<= 0`` and determinant ``>= 0``.
    """
    mean = np.asarray(mean, dtype=complex)
    q11 = mean.real ** 2 - c * var_real
    q22 = mean.imag ** 2 - c * var_imag
    q12 = mean.real * mean.imag - c * cov
    return (q11 + q22 <= 0.0) & (q11 * q22 - q12 ** 2 >= 0.0)


def _ellipse_axes(var_real, var_imag, cov, c):
    """Principal axes of the ellipse: angle of the major axis and semi-axes ``a >= b``."""
    angle = 0.5 * np.arctan2(2.0 * cov, var_real - var_imag)
    half_trace = 0.5 * (var_real + var_imag)
    radius = np.hypot(0.5 * (var_real - var_imag), cov)
    a = np.sqrt(c * (half_trace + radius))
    b = np.sqrt(c * np.maximum(half_trace - radius, 0.0))
    return angle, a, b


def _magnitude_range(mean, var_real, var_imag, cov, c) -> tuple[np.ndarray, np.ndarray]:
    """Smallest and largest ``|z|`` on the boundary of the ellipse, per frequency.

    In the principal axes the boundary is ``p + (a cos t, b sin t)`` with ``p``
    the mean, and ``|z|^2 = f(t)`` is stationary where
    ``h(t) = -a p1 sin t + b p2 cos t + (b^2 - a^2) sin t cos t = 0``.  With
    ``w = exp(j t)`` that is the quartic
    ``(b^2 - a^2) (w^4 - 1) - 2 a p1 (w^3 - w) + 2j b p2 (w^3 + w) = 0``, solved
    for all frequencies at once through the eigenvalues of its companion
    matrices.  The stationary points of the circle (``a = b``), the ends of
    the axes and a few Newton steps on ``h`` make it exact also when the
    quartic degenerates; the extremes are taken over all these candidates,
    each a point of the boundary.  (The smallest value is the answer only when
    the ellipse does not contain 0.)
    """
    mean = np.asarray(mean, dtype=complex)
    angle, a, b = _ellipse_axes(var_real, var_imag, cov, c)
    rotated = mean * np.exp(-1j * angle)
    p1, p2 = rotated.real, rotated.imag
    n = mean.shape[0]
    lead = b ** 2 - a ** 2
    scale = np.maximum(a ** 2 + np.abs(a * p1) + np.abs(b * p2), np.finfo(float).tiny)
    quartic = np.abs(lead) > 1e-10 * scale
    safe = np.where(quartic, lead, 1.0)
    # monic quartic w^4 + c3 w^3 + c2 w^2 + c1 w + c0
    c3 = (-2.0 * a * p1 + 2j * b * p2) / safe
    c1 = (2.0 * a * p1 + 2j * b * p2) / safe
    companion = np.zeros((n, 4, 4), dtype=complex)
    companion[:, 0, 0], companion[:, 0, 2], companion[:, 0, 3] = -c3, -c1, 1.0
    companion[:, 1, 0] = companion[:, 2, 1] = companion[:, 3, 2] = 1.0
    roots = np.linalg.eigvals(companion) if n else np.empty((0, 4), dtype=complex)
    root_angles = np.where(quartic[:, None], np.angle(roots), 0.0)
    circle = np.arctan2(p2, p1)[:, None] + np.array([0.0, np.pi])
    axis_ends = np.broadcast_to(np.arange(4) * (np.pi / 2), (n, 4))
    t = np.concatenate([root_angles, circle, axis_ends], axis=1)
    a_, b_, p1_, p2_, lead_ = (v[:, None] for v in (a, b, p1, p2, lead))
    candidates = [t]
    for _ in range(4):
        s, co = np.sin(t), np.cos(t)
        h = -a_ * p1_ * s + b_ * p2_ * co + lead_ * s * co
        dh = -a_ * p1_ * co - b_ * p2_ * s + lead_ * (co ** 2 - s ** 2)
        step = np.divide(h, dh, out=np.zeros_like(h), where=np.abs(dh) > 1e-300)
        t = t - np.clip(step, -0.5, 0.5)
        candidates.append(t)
    t = np.concatenate(candidates, axis=1)
    squared = (p1_ + a_ * np.cos(t)) ** 2 + (p2_ + b_ * np.sin(t)) ** 2
    return np.sqrt(squared.min(axis=1)), np.sqrt(squared.max(axis=1))


def _relative_phase_range(mean, var_real, var_imag, cov, c) -> tuple[np.ndarray, np.ndarray]:
    """Range of ``angle(z) - angle(mean)`` over the ellipse, where it does not contain 0.

    The extreme angles are those of the two tangent lines through the origin:
    a line with unit normal ``n`` is tangent when ``n^T (m m^T - c S) n = 0``
    (the null directions of that indefinite 2x2 matrix), and it touches the
    ellipse at ``m - (n . m) S n / (n^T S n)``.  The angles of the two points,
    relative to the mean's, lie in ``(-pi, pi)`` since the ellipse is convex
    and does not contain 0.  (Meaningless where it contains 0.)
    """
    mean = np.asarray(mean, dtype=complex)
    mr, mi = mean.real, mean.imag
    q11 = mr ** 2 - c * var_real
    q22 = mi ** 2 - c * var_imag
    q12 = mr * mi - c * cov
    phi = 0.5 * np.arctan2(2.0 * q12, q11 - q22)
    half_trace = 0.5 * (q11 + q22)
    radius = np.hypot(0.5 * (q11 - q22), q12)
    big, small = half_trace + radius, half_trace - radius
    e1 = np.stack([np.cos(phi), np.sin(phi)])
    e2 = np.stack([-np.sin(phi), np.cos(phi)])
    rotate_back = np.exp(-1j * np.angle(mean))
    angles = []
    for sign in (1.0, -1.0):
        normal = (np.sqrt(np.maximum(-small, 0.0)) * e1
                  + sign * np.sqrt(np.maximum(big, 0.0)) * e2)
        sn_r = var_real * normal[0] + cov * normal[1]
        sn_i = cov * normal[0] + var_imag * normal[1]
        nsn = normal[0] * sn_r + normal[1] * sn_i
        nm = normal[0] * mr + normal[1] * mi
        weight = np.divide(nm, nsn, out=np.zeros_like(nm), where=nsn > 1e-300)
        touch = (mr - weight * sn_r) + 1j * (mi - weight * sn_i)
        angles.append(np.angle(touch * rotate_back))
    lower = np.minimum(angles[0], angles[1])
    upper = np.maximum(angles[0], angles[1])
    return np.minimum(lower, 0.0), np.maximum(upper, 0.0)


def _unwrap_where_defined(angle: np.ndarray, defined: np.ndarray) -> np.ndarray:
    """Unwrap ``angle`` along each run of ``defined``, restarting after undefined runs.

    A defined run starts on the branch nearest the last defined value before
    it (the principal value for the first one); an undefined run continues
    from the last defined value.
    """
    angle = np.asarray(angle, dtype=float)
    out = np.empty_like(angle)
    n = angle.shape[0]
    if n == 0:
        return out
    edges = np.flatnonzero(np.diff(defined.astype(np.int8))) + 1
    starts = np.concatenate([[0], edges])
    stops = np.concatenate([edges, [n]])
    last = None  # the last defined value
    for start, stop in zip(starts, stops):
        run = np.unwrap(angle[start:stop])
        if last is not None:
            run = run + 2.0 * np.pi * np.round((last - run[0]) / (2.0 * np.pi))
        out[start:stop] = run
        if defined[start]:
            last = run[-1]
    return out


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
