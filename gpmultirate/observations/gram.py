"""The Gram matrix of a convolution sampled on a uniform grid, by FFT.

For slow samples at the fast instants ``n_m = n_0 + m F`` (``m < M``) the
regressor rows (paper eq. 8) are ``x_m(i) = e(n_m - i)``, with ``e`` the
input extended before the record (zero, or periodic).  Shifting both lags
by ``F`` shifts the rows by one sample,

    x_m(i + F) = x_{m-1}(i),

so the Gram matrix ``G = Phi_a^T Phi_b`` of two inputs' columns is block
Toeplitz up to a rank-two correction per block, one row entering at the
start of the record and one leaving at its end:

    G[i + F, j + F] = G[i, j] + x_{-1}(i) x_{-1}(j) - x_{M-1}(i) x_{M-1}(j).

The first ``F`` rows and columns are cross-correlations of the input with
its samples on the grid, ``sum_m e(n_m - r) e(n_m - j)``, one FFT each;
the rest follows from the recursion.  The cost is ``O(F N log N + P^2)``
instead of the ``O(M P^2)`` of ``Phi^T Phi``, and the memory ``O(N + P^2)``.
(Only entries ``x_{-1}(i)`` with ``i <= P - 1 - F`` enter, and those lie at
instants ``n_0 - F - i >= n_0 - P + 1``, inside the extended input.)
"""

from __future__ import annotations

import numpy as np
from scipy import fft

__all__ = ["extended_input", "grid_correlations", "uniform_gram"]

#: entries of the arrays one batch of FFTs works on (4 M: 32 MB of float64)
CHUNK_ENTRIES = 1 << 22


def extended_input(u: np.ndarray, order: int, periodic: bool = False) -> np.ndarray:
    """The input at the fast instants ``-(order - 1)`` to ``N - 1``: zero, or periodic, before the record.

    Entry ``n + order - 1`` is ``u(n)``.

    Examples
    --------
    >>> extended_input(np.array([1.0, 2.0, 3.0]), 3)
    array([0., 0., 1., 2., 3.])
    >>> extended_input(np.array([1.0, 2.0, 3.0]), 3, periodic=True)
    array([2., 3., 1., 2., 3.])
    """
    u = np.asarray(u, dtype=float)
    if periodic:
        return u[np.arange(-(order - 1), u.shape[0]) % u.shape[0]]
    return np.concatenate([np.zeros(order - 1), u])


def grid_correlations(weights: np.ndarray, positions: np.ndarray, signal_spectrum: np.ndarray,
                      n_fft: int, n_lags: int) -> np.ndarray:
    """``sum_m weights[k, m] s(positions[m] - j)`` for ``j < n_lags``, one row per ``k``.

    ``signal_spectrum`` is ``rfft(s, n_fft)`` with ``n_fft`` at least
    ``len(s) + n_lags - 1`` (no wrap-around).
    """
    result = np.empty((weights.shape[0], n_lags))
    conjugate = np.conj(signal_spectrum)
    chunk = max(1, CHUNK_ENTRIES // n_fft)  # rows per FFT: bounded memory for long records
    for start in range(0, weights.shape[0], chunk):
        rows = weights[start : start + chunk]
        sparse = np.zeros((rows.shape[0], n_fft))
        sparse[:, positions] = rows
        spectrum = fft.rfft(sparse, axis=1)
        spectrum *= conjugate
        result[start : start + chunk] = fft.irfft(spectrum, n_fft, axis=1)[:, :n_lags]
    return result


def uniform_gram(extended: np.ndarray, first: int, step: int, n_outputs: int, order: int,
                 y: np.ndarray | None = None, skip: np.ndarray | None = None):
    """``Phi^T Phi`` and ``Phi^T y`` of inputs sampled at ``first + m * step``, ``m < n_outputs``.

    Parameters
    ----------
    extended : ndarray of shape (n_inputs, N + order - 1)
        Each input at the instants ``-(order - 1) .. N - 1``
        (:func:`extended_input`).
    first, step, n_outputs : int
        The grid of fast instants ``first + m * step``, inside ``0 .. N - 1``.
    order : int
        ``P``, the lags per input.
    y : ndarray of shape (n_outputs,), optional
        The outputs on the grid (entries in ``skip`` are ignored).
    skip : ndarray of int, optional
        Grid entries that are not observed: their rows are subtracted from
        the grid's Gram (dense, ``O(len(skip) P^2)``).

    Returns
    -------
    gram : ndarray of shape (n_inputs * P, n_inputs * P)
        Exactly symmetric; the columns are input-major as in the regressor.
    projection : ndarray of shape (n_inputs * P,) or None
        ``Phi^T y`` when ``y`` is given.

    Examples
    --------
    >>> u = np.arange(1.0, 8.0)
    >>> G, _ = uniform_gram(extended_input(u, 3)[None], 1, 2, 3, 3)
    >>> Phi = np.array([[2.0, 1.0, 0.0], [4.0, 3.0, 2.0], [6.0, 5.0, 4.0]])
    >>> bool(np.allclose(G, Phi.T @ Phi))
    True
    """
    extended = np.atleast_2d(np.asarray(extended, dtype=float))
    n_inputs, length = extended.shape
    P, F = order, step
    positions = first + order - 1 + F * np.arange(n_outputs)  # indices into `extended`
    n_fft = fft.next_fast_len(length + P, real=True)
    spectra = fft.rfft(extended, n_fft, axis=1)
    head = min(F, P)  # the rows (and columns) computed directly
    # correlation rows: for input a and r < head, sum_m e_a(n_m - r) e_b(n_m - j)
    strips = {}
    for a in range(n_inputs):
        # the whole grid: the skipped rows are subtracted below
        weights = extended[a, positions[None, :] - np.arange(head)[:, None]]
        for b in range(n_inputs):
            strips[a, b] = grid_correlations(weights, positions, spectra[b], n_fft, P)
    # rows entering (instant first - F) and leaving (the last instant) with a shift by F
    lags = np.arange(max(P - F, 0))
    enters = extended[:, positions[0] - F - lags] if lags.size else np.zeros((n_inputs, 0))
    leaves = extended[:, positions[-1] - lags]
    gram = np.zeros((n_inputs * P, n_inputs * P))
    for a in range(n_inputs):
        for b in range(n_inputs):
            block = gram[a * P : (a + 1) * P, b * P : (b + 1) * P]
            block[:head] = strips[a, b]
            block[head:, :head] = strips[b, a][:, head:].T
            _fill_by_shifts(block, F, enters[a], enters[b], leaves[a], leaves[b])
    if skip is not None and skip.size:
        rows = np.concatenate(
            [extended[a, positions[skip][:, None] - np.arange(P)[None, :]] for a in range(n_inputs)],
            axis=1,
        )
        gram -= rows.T @ rows
    gram += gram.T
    gram *= 0.5
    projection = None
    if y is not None:
        weights = np.asarray(y, dtype=float).copy()[None, :]
        if skip is not None and skip.size:
            weights[:, skip] = 0.0
        projection = np.concatenate(
            [grid_correlations(weights, positions, spectra[a], n_fft, P)[0] for a in range(n_inputs)]
        )
    return gram, projection


def _fill_by_shifts(block, F, enters_a, enters_b, leaves_a, leaves_b) -> None:
    """Fill ``block`` beyond its first ``F`` rows and columns by the shift recursion."""
    P = block.shape[0]
    for low in range(F, P, F):
        high = min(low + F, P)
        # rows low..high-1 from column low on, then the columns low..high-1 below
        block[low:high, low:] = block[low - F : high - F, low - F : P - F]
        block[low:high, low:] += np.outer(enters_a[low - F : high - F], enters_b[low - F : P - F])
        block[low:high, low:] -= np.outer(leaves_a[low - F : high - F], leaves_b[low - F : P - F])
        if high < P:
            block[high:, low:high] = block[high - F : P - F, low - F : high - F]
            block[high:, low:high] += np.outer(enters_a[high - F : P - F], enters_b[low - F : high - F])
            block[high:, low:high] -= np.outer(leaves_a[high - F : P - F], leaves_b[low - F : high - F])
