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
  ``cos`` and ``-sin`` (:func:`dft_variances`);
* at any frequency ``w`` (radians per sample), with ``d_k`` the sums of the
  diagonals ``i - j = k`` of ``Sigma`` and ``a_k`` those of its
  anti-diagonals ``i + j = k``, ``cos(w i) cos(w j) = (cos(w (i - j)) +
  cos(w (i + j))) / 2`` and its like give
  ``Var(Re) = (sum_k d_k cos(w k) + sum_k a_k cos(w k)) / 2``,
  ``Var(Im) = (sum_k d_k cos(w k) - sum_k a_k cos(w k)) / 2`` and
  ``Cov(Re, Im) = -sum_k a_k sin(w k) / 2`` (``d`` is even): ``O(P)`` per
  frequency after ``O(P^2)`` once (:func:`frequency_variances`).

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

__all__ = ["convolution_variance", "dft_bins", "dft_variances", "frequency_variances"]

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


def _diagonal_sums(cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``d_k``, ``k = 0..P-1`` (the sums of the diagonals ``j - i = k``), and ``a_k``, ``k = 0..2P-2``.

    ``a_k`` is the sum of the anti-diagonal ``i + j = k``.
    """
    order = cov.shape[0]
    diagonal = np.array([np.trace(cov, offset=k) for k in range(order)])
    flipped = cov[::-1]  # row i of the flipped matrix is row P-1-i: i + j = k is offset k-P+1
    anti = np.array([np.trace(flipped, offset=k - order + 1) for k in range(2 * order - 1)])
    return diagonal, anti


def frequency_variances(mean: np.ndarray, cov: np.ndarray, angles: np.ndarray):
    """The DFT of ``g ~ N(mean, cov)`` at any ``angles`` ``w`` (radians per sample).

    With ``E[f, j] = exp(-i w_f j)``: the mean ``E mean`` and the variances of
    ``Re(E g)`` and ``Im(E g)`` and their covariance, from the sums of the
    diagonals and anti-diagonals of ``cov`` (see the module's notes).

    Parameters
    ----------
    mean : ndarray of shape (P,)
    cov : ndarray of shape (P, P)
        Symmetric.
    angles : ndarray of shape (n,)
        ``2 pi f T``.

    Returns
    -------
    frf : ndarray of shape (n,), complex
    var_re, var_im, cov_re_im : ndarray of shape (n,)

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.bands import frequency_variances
    >>> cov = np.array([[2.0, 0.5], [0.5, 1.0]])
    >>> frf, var_re, var_im, c = frequency_variances(np.zeros(2), cov, np.array([np.pi / 2]))
    >>> E = np.exp(-1j * np.pi / 2 * np.arange(2))  # (1, -i)
    >>> [round(float(v[0]), 12) for v in (var_re, var_im, c)]  # E.real cov E.real, ...
    [2.0, 1.0, -0.5]
    """
    order = cov.shape[0]
    diagonal, anti = _diagonal_sums(0.5 * (cov + cov.T))
    # sum over i - j = k of both signs: d_0 once, d_k (k > 0) twice
    two_sided = np.concatenate([[diagonal[0]], 2.0 * diagonal[1:]])
    frf = np.empty(angles.shape[0], dtype=complex)
    var_re, var_im, cov_re_im = (np.empty(angles.shape[0]) for _ in range(3))
    lags, wide = np.arange(order), np.arange(2 * order - 1)
    block = _columns_per_block(2 * order, angles.shape[0])
    for start in range(0, angles.shape[0], block):
        rows = slice(start, start + block)
        w = angles[rows, None]
        near = two_sided @ np.cos(w * lags).T
        cos_anti, sin_anti = np.cos(w * wide) @ anti, np.sin(w * wide) @ anti
        var_re[rows] = 0.5 * (near + cos_anti)
        var_im[rows] = 0.5 * (near - cos_anti)
        cov_re_im[rows] = -0.5 * sin_anti
        frf[rows] = np.exp(-1j * w * lags) @ mean
    return frf, np.maximum(var_re, 0.0), np.maximum(var_im, 0.0), cov_re_im
