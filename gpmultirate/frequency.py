"""Frequency response of an FIR model with credible bands (paper eq. 6).

The FRF ``G(f) = sum_i g_i exp(-j 2 pi f T i)`` is linear in the
coefficients, so a Gaussian posterior on ``g`` gives, at each frequency, a
bivariate Gaussian for ``(Re G, Im G)``.  The bands on magnitude and phase
are pointwise quantiles of that exact distribution, evaluated with a fixed
set of draws (magnitude and phase are non-linear functions of the Gaussian,
so their quantiles have no closed form).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gpmultirate.validation import check_level, check_positive, check_signal

__all__ = ["FrequencyResponse", "dft_matrix", "default_frequencies"]

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
    >>> from gpmultirate.frequency import FrequencyResponse
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
    """Validate a frequency grid in Hz and a sample time."""
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
