"""Credible bands of long convolutions and DFTs of Gaussian coefficients, by FFT.

The band of a prediction is the variance of ``T g`` row by row, ``T`` the
``N x P`` convolution (Toeplitz) matrix of the input and ``g ~ N(mu, Sigma)``
the coefficients; that of a frequency response is the variance of the real
and imaginary parts of ``E g``, ``E`` the DFT matrix.  Row by row
(``diag(T Sigma T^T)``) each costs ``O(N P^2)``: ``3e11`` flops for a 20 s
record at 1 kHz and ``P = 4,000``.  Both are products of ``Sigma`` with a
structured matrix, and the structure gives them by FFT:

* ``T Sigma`` is the convolution of the input with each column of
  ``Sigma``, so ``diag(T Sigma T^T)[n] = sum_j (T Sigma)[n, j] u(n - j)``
  costs ``P`` FFTs of length ``N + P`` (:func:`convolution_variance`);
* at the DFT bins ``k / (L T)`` of a length ``L``, ``E Sigma`` is the FFT of
  each column of ``Sigma`` (lags folded modulo ``L``), and the variances of
  ``Re`` and ``Im`` and their covariance are row sums of its products with
  ``cos`` and ``-sin`` (:func:`dft_variances`).

Memory stays ``O((N + P) B)`` with ``B`` columns of ``Sigma`` at a time.

Examples
--------
>>> import numpy as np
>>> from gpmultirate.bands import convolution_variance
>>> rng = np.random.default_rng(0)
>>> u, root = rng.standard_normal(50), rng.standard_normal((8, 8))
>>> cov = root @ root.T
>>> T = np.array([[u[n - j] if n >= j else 0.0 for j in range(8)] for n in range(50)])
>>> bool(np.allclose(convolution_variance(u[:, None], cov), np.diag(T @ cov @ T.T)))
True
"""

from __future__ import annotations

import numpy as np
from scipy import fft

__all__ = ["convolution_variance", "dft_bins", "dft_variances"]

# entries of an (FFT length x columns) block formed at once: memory O(2**22) floats
_BLOCK_ENTRIES = 2**22


def _columns_per_block(length: int, n_columns: int) -> int:
    return int(max(1, min(n_columns, _BLOCK_ENTRIES // max(1, length))))


def convolution_variance(inputs: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """``diag(T Sigma T^T)``: the variance of the convolution of the inputs with ``g``.

    ``T = [T_1 ... T_k]`` with ``T_i[n, j] = u_i(n - j)`` (zero before the
    record starts, the fit's ``initial_conditions="zero"``) and ``Sigma``
    the covariance of the input-major coefficients.

    Parameters
    ----------
    inputs : ndarray of shape (N, n_inputs)
    cov : ndarray of shape (n_inputs * P, n_inputs * P)
        Symmetric.

    Returns
    -------
    ndarray of shape (N,)
        Non-negative (rounding below zero clipped).
    """
    n, n_inputs = inputs.shape
    order = cov.shape[0] // n_inputs
    length = fft.next_fast_len(n + order - 1, real=True)
    spectra = fft.rfft(inputs, length, axis=0)  # (L/2 + 1, n_inputs)
    block = _columns_per_block(length, cov.shape[1])
    var = np.zeros(n)
    for start in range(0, cov.shape[1], block):
        columns = np.arange(start, min(start + block, cov.shape[1]))
        # (T Sigma)[:, columns] = sum_i u_i * Sigma[input i's lags, columns]
        products = sum(
            spectra[:, i : i + 1] * fft.rfft(cov[i * order : (i + 1) * order, columns],
                                             length, axis=0)
            for i in range(n_inputs)
        )
        Y = fft.irfft(products, length, axis=0)[:n]
        # times T[:, columns]: input columns // order shifted by columns % order
        for position, column in enumerate(columns):
            i, lag = divmod(int(column), order)
            if lag < n:
                var[lag:] += Y[lag:, position] * inputs[: n - lag, i]
    return np.maximum(var, 0.0)


def dft_bins(freqs: np.ndarray, sample_time: float) -> int | None:
    """``L`` when ``freqs`` are the DFT bins ``k / (L T)``, ``k = 0, 1, ...``, else None.

    Examples
    --------
    >>> dft_bins(np.fft.rfftfreq(10, 0.5), 0.5), dft_bins(np.array([0.0, 0.3]), 1.0)
    (10, None)
    """
    freqs = np.asarray(freqs, dtype=float)
    if freqs.size < 2 or freqs[0] != 0.0 or freqs[1] <= 0.0:
        return None
    length = 1.0 / (freqs[1] * sample_time)
    if abs(length - round(length)) > 1e-9 * length or round(length) < 2:
        return None
    length = int(round(length))
    expected = np.arange(freqs.size) / (length * sample_time)
    if freqs.size > length // 2 + 1 or not np.allclose(freqs, expected, rtol=1e-12,
                                                       atol=1e-12 * expected[-1]):
        return None
    return length


def _folded(values: np.ndarray, length: int) -> np.ndarray:
    """Rows (lags) summed modulo ``length``: ``exp(-2 pi i k j / L)`` is periodic in ``j``."""
    if values.shape[0] <= length:
        return values
    folded = np.zeros((length, *values.shape[1:]))
    for start in range(0, values.shape[0], length):
        part = values[start : start + length]
        folded[: part.shape[0]] += part
    return folded


def dft_variances(mean: np.ndarray, cov: np.ndarray, n_freqs: int, length: int):
    """The DFT of ``g ~ N(mean, cov)`` at the bins ``k / (L T)``, ``k < n_freqs``.

    With ``E[k, j] = exp(-2 pi i k j / L)``: the mean ``E mean`` and the
    variances of ``Re(E g)`` and ``Im(E g)`` and their covariance, bin by
    bin (as ``pair_variances`` of the real and imaginary parts of ``E``).

    Parameters
    ----------
    mean : ndarray of shape (P,)
    cov : ndarray of shape (P, P)
        Symmetric.
    n_freqs : int
        At most ``L // 2 + 1``.
    length : int
        ``L``.

    Returns
    -------
    frf : ndarray of shape (n_freqs,), complex
    var_re, var_im, cov_re_im : ndarray of shape (n_freqs,)
    """
    order = cov.shape[0]
    frf = fft.rfft(_folded(mean[:, None], length), length, axis=0)[:n_freqs, 0]
    var_re, var_im, cov_re_im = (np.zeros(n_freqs) for _ in range(3))
    block = _columns_per_block(length, order)
    bins = np.arange(n_freqs)
    for start in range(0, order, block):
        columns = np.arange(start, min(start + block, order))
        # (E Sigma)[:, columns]: Re = cos Sigma, Im = -sin Sigma (Sigma is real)
        Y = fft.rfft(_folded(cov[:, columns], length), length, axis=0)[:n_freqs]
        # the angle 2 pi k j / L with k j reduced modulo L first: exact for long records
        angle = (2.0 * np.pi / length) * np.mod(np.outer(bins, columns), length)
        c, s = np.cos(angle), -np.sin(angle)
        var_re += np.einsum("kj,kj->k", Y.real, c)
        var_im += np.einsum("kj,kj->k", Y.imag, s)
        cov_re_im += np.einsum("kj,kj->k", Y.real, s)
    return frf, np.maximum(var_re, 0.0), np.maximum(var_im, 0.0), cov_re_im
