"""Low-order state-space models from impulse responses (Ho-Kalman / ERA).

An identified FIR model of order ``P`` is a state-space model of ``P - 1``
states (a shift register of past inputs), too many for control design.  This
module realizes a low-order discrete-time model
``x(k+1) = A x(k) + B u(k)``, ``y(k) = C x(k) + D u(k)`` from the impulse
response (the Markov parameters ``h(0) = D``, ``h(k) = C A^(k-1) B``):

* :func:`block_hankel` stacks the Markov parameters into the (block) Hankel
  matrix ``H[i, j] = h(1 + i + j)``;
* :func:`era` is the Ho-Kalman algorithm in the form of the eigensystem
  realization algorithm: ``H = U S V^T``, the ``n`` leading singular triplets
  give the observability factor ``U_n S_n^(1/2)`` and the controllability
  factor ``S_n^(1/2) V_n^T``, and ``A`` comes from the Hankel matrix shifted
  by one lag;
* :func:`leading_era` is :func:`era` of a given order from the leading
  singular triplets only, for realizing many impulse responses quickly;
* :func:`balanced_truncation` reduces any stable discrete-time state-space
  model through its Gramians (square-root algorithm);
* :func:`select_order` is the rule that chooses the order from the Hankel
  singular values.

For a finite impulse response the default Hankel matrix of :func:`era` is the
whole Hankel operator of the FIR (zero beyond the last lag): its singular
values are then the exact Hankel singular values of the FIR and the
realization of order ``n`` is exactly the balanced truncation of the FIR to
``n`` states.  It is stable, and its frequency response is within twice the
sum of the discarded Hankel singular values of the FIR's, at every frequency.

Markov parameters are arrays of shape ``(n_lags, n_outputs, n_inputs)``; a
1-D array is a single-input, single-output impulse response.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import fft, linalg

from gpmultirate.validation import as_real_array, check_int, check_positive

__all__ = [
    "Realization",
    "as_markov",
    "balanced_truncation",
    "block_hankel",
    "era",
    "hankel_singular_values",
    "leading_era",
    "select_order",
]

#: default of ``threshold`` in :func:`select_order`
DEFAULT_THRESHOLD = 1e-3


@dataclass(frozen=True)
class Realization:
    """A discrete-time state-space model and the Hankel singular values it came from.

    Attributes
    ----------
    A : ndarray of shape (n_states, n_states)
    B : ndarray of shape (n_states, n_inputs)
    C : ndarray of shape (n_outputs, n_states)
    D : ndarray of shape (n_outputs, n_inputs)
    hankel_singular_values : ndarray
        The Hankel singular values of the system that was reduced, in
        decreasing order (the first ``n_states`` are kept): all of them, or
        for a long impulse response the leading ones down to below the
        order rule's threshold, with ``tail_bound`` for the rest.
    n_states : int
        The order of the realization.
    complete : bool, default=True
        False when ``hankel_singular_values`` holds only the leading values
        and nothing bounds the rest (:func:`leading_era`).
    tail_bound : float, default=0.0
        An upper bound of the sum of the Hankel singular values that
        ``hankel_singular_values`` does not hold (0 when it holds all).

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.realization import era
    >>> h = 0.5 ** np.arange(8) * (np.arange(8) > 0)  # h(k) = 0.5**k after h(0) = 0
    >>> r = era(h, n_block_rows=3, n_block_cols=3)
    >>> r.n_states, r.A.round(6).tolist()
    (1, [[0.5]])
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    hankel_singular_values: np.ndarray
    n_states: int
    complete: bool = True
    tail_bound: float = 0.0

    @property
    def error_bound(self) -> float:
        """Twice the sum of the discarded Hankel singular values (NaN unless ``complete``).

        With ``tail_bound`` for the values not held: then an upper bound of
        that sum.

        The H-infinity norm of the difference between the system that was
        reduced and this realization is at most this value when the
        realization is its balanced truncation (the default of :func:`era`
        for a finite impulse response, and :func:`balanced_truncation`).
        """
        if not self.complete:
            return float("nan")
        return float(2.0 * (np.sum(self.hankel_singular_values[self.n_states:])
                            + self.tail_bound))

    def markov_parameters(self, n_lags: int) -> np.ndarray:
        """Impulse response ``D, CB, CAB, ...`` of the realization.

        Parameters
        ----------
        n_lags : int
            Number of lags, at least 1.

        Returns
        -------
        ndarray of shape (n_lags, n_outputs, n_inputs)

        Examples
        --------
        >>> r = era([0.0, 1.0, 0.5, 0.25, 0.125], n_block_rows=2, n_block_cols=2)
        >>> r.markov_parameters(6)[:, 0, 0].round(6).tolist()
        [0.0, 1.0, 0.5, 0.25, 0.125, 0.0625]
        """
        n_lags = check_int(n_lags, "n_lags", low=1)
        out = np.empty((n_lags,) + self.D.shape)
        out[0] = self.D
        x = self.B
        for k in range(1, n_lags):
            out[k] = self.C @ x
            x = self.A @ x
        return out

    def frequency_response(self, freqs, sample_time: float = 1.0) -> np.ndarray:
        """``C (zI - A)^(-1) B + D`` at ``z = exp(j 2 pi f T)``.

        Parameters
        ----------
        freqs : array-like of shape (n,)
            Frequencies in Hz.
        sample_time : float, default=1.0
            Sample time ``T`` in seconds.

        Returns
        -------
        ndarray of shape (n, n_outputs, n_inputs), complex

        Examples
        --------
        >>> r = era([0.0, 1.0, 0.5, 0.25, 0.125], n_block_rows=2, n_block_cols=2)
        >>> r.frequency_response([0.0]).round(6)  # static gain 1 / (1 - 0.5)
        array([[[2.+0.j]]])
        """
        freqs = as_real_array(freqs, "freqs").reshape(-1)
        sample_time = check_positive(sample_time, "sample_time")
        z = np.exp(2j * np.pi * freqs * sample_time)
        n = self.n_states
        resolvent = z[:, None, None] * np.eye(n) - self.A
        x = np.linalg.solve(resolvent, np.broadcast_to(self.B, (z.size,) + self.B.shape))
        return self.C @ x + self.D


def as_markov(impulse_response, name: str = "impulse_response") -> np.ndarray:
    """Markov parameters as a new float array of shape ``(n_lags, n_outputs, n_inputs)``.

    A 1-D array is one input and one output.

    Examples
    --------
    >>> as_markov([0.0, 1.0, 0.5]).shape
    (3, 1, 1)
    """
    h = as_real_array(impulse_response, name)
    if h.ndim == 1:
        h = h[:, None, None]
    if h.ndim != 3 or 0 in h.shape:
        raise ValueError(
            f"{name} must have shape (n_lags,) or (n_lags, n_outputs, n_inputs); got {h.shape}"
        )
    if h.shape[0] < 2:
        raise ValueError(f"{name} must have at least 2 lags to realize a state; got {h.shape[0]}")
    if not np.all(np.isfinite(h)):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return h


def block_hankel(markov, n_block_rows: int | None = None, n_block_cols: int | None = None,
                 shift: int = 0) -> np.ndarray:
    """Block Hankel matrix ``H[i, j] = h(1 + shift + i + j)`` of Markov parameters.

    Markov parameters beyond the last lag are taken as zero, as for a finite
    impulse response.

    Parameters
    ----------
    markov : array-like of shape (n_lags,) or (n_lags, n_outputs, n_inputs)
        The impulse response ``h(0), h(1), ...``.
    n_block_rows, n_block_cols : int, optional
        Block rows and columns; default ``n_lags - 1`` each, which holds the
        whole impulse response after lag 0.
    shift : int, default=0
        Lags by which the Markov parameters are shifted.

    Returns
    -------
    ndarray of shape (n_block_rows * n_outputs, n_block_cols * n_inputs)

    Examples
    --------
    >>> block_hankel([0.0, 1.0, 2.0, 3.0])
    array([[1., 2., 3.],
           [2., 3., 0.],
           [3., 0., 0.]])
    >>> block_hankel([0.0, 1.0, 2.0, 3.0], shift=1)
    array([[2., 3., 0.],
           [3., 0., 0.],
           [0., 0., 0.]])
    """
    h = as_markov(markov, "markov")
    n_lags, p, m = h.shape
    rows = n_lags - 1 if n_block_rows is None else check_int(n_block_rows, "n_block_rows", low=1)
    cols = n_lags - 1 if n_block_cols is None else check_int(n_block_cols, "n_block_cols", low=1)
    shift = check_int(shift, "shift", low=0)
    index = 1 + shift + np.arange(rows)[:, None] + np.arange(cols)[None, :]
    padded = np.concatenate([h, np.zeros((1, p, m))])
    blocks = padded[np.minimum(index, n_lags)]  # (rows, cols, p, m); n_lags is the zero block
    return blocks.transpose(0, 2, 1, 3).reshape(rows * p, cols * m)


class _HankelProduct:
    """Products with the block Hankel matrix of :func:`block_hankel`, by FFT.

    ``H[(i, a), (j, b)] = h(1 + shift + i + j)[a, b]``: each product is a
    correlation of the Markov parameters with the vector, ``O((R + C) log(R + C))``
    per column and output-input pair instead of ``O(R C)``, and ``H`` is
    never formed.
    """

    def __init__(self, h: np.ndarray, rows: int, cols: int, shift: int = 0) -> None:
        n_lags, p, m = h.shape
        self.rows, self.cols, self.p, self.m = rows, cols, p, m
        self.shape = (rows * p, cols * m)
        c = np.zeros((rows + cols - 1, p, m))
        kept = h[1 + shift : 1 + shift + rows + cols - 1]
        c[: kept.shape[0]] = kept
        self.length = fft.next_fast_len(rows + cols - 1, real=True)
        self.spectrum = fft.rfft(c, self.length, axis=0)  # (L/2 + 1, p, m)

    def _correlate(self, spectrum, v, n_out, n_in):
        # (H v)[i] = sum_j c(i + j) v[j]: the convolution of c with v reversed, read from n_in - 1
        q = v.shape[1]
        v = v.reshape(n_in, -1, q)[::-1]
        w = fft.irfft(np.einsum("fab,fbq->faq", spectrum, fft.rfft(v, self.length, axis=0)),
                      self.length, axis=0)
        return w[n_in - 1 : n_in - 1 + n_out].reshape(-1, q)

    def matmat(self, v: np.ndarray) -> np.ndarray:
        """``H v`` for ``v`` of shape ``(C m, q)``."""
        return self._correlate(self.spectrum, v, self.rows, self.cols)

    def rmatmat(self, x: np.ndarray) -> np.ndarray:
        """``H^T x`` for ``x`` of shape ``(R p, q)``."""
        return self._correlate(self.spectrum.transpose(0, 2, 1), x, self.cols, self.rows)

    def operator(self):
        """As a :class:`scipy.sparse.linalg.LinearOperator` (for ``svds``)."""
        from scipy.sparse.linalg import LinearOperator

        return LinearOperator(
            self.shape, dtype=float,
            matvec=lambda v: self.matmat(np.reshape(v, (-1, 1)))[:, 0],
            rmatvec=lambda x: self.rmatmat(np.reshape(x, (-1, 1)))[:, 0],
            matmat=self.matmat, rmatmat=self.rmatmat)


def hankel_singular_values(markov, n_block_rows: int | None = None,
                           n_block_cols: int | None = None) -> np.ndarray:
    """All the singular values of the block Hankel matrix, in decreasing order.

    Only the values are computed (no singular vectors, several times
    cheaper); a square Hankel matrix of one input and one output is
    symmetric, and its singular values are the magnitudes of its
    eigenvalues (``eigvalsh``, cheaper still).

    Parameters
    ----------
    markov : array-like of shape (n_lags,) or (n_lags, n_outputs, n_inputs)
    n_block_rows, n_block_cols : int, optional
        As for :func:`block_hankel`.

    Returns
    -------
    ndarray

    Examples
    --------
    >>> import numpy as np
    >>> h = np.r_[0.0, 0.5 ** np.arange(40)]
    >>> s = hankel_singular_values(h)
    >>> bool(np.allclose(s, np.linalg.svd(block_hankel(h), compute_uv=False)))
    True
    """
    h = as_markov(markov, "markov")
    H = block_hankel(h, n_block_rows, n_block_cols)
    # numpy's LAPACK calls release the interpreter lock, so the progress's heartbeat
    # goes on during a long one (scipy's hold it)
    if H.shape[0] == H.shape[1] and h.shape[1:] == (1, 1):
        return np.sort(np.abs(np.linalg.eigvalsh(H)))[::-1]
    return np.linalg.svd(H, compute_uv=False)


def select_order(hankel_singular_values, threshold: float = DEFAULT_THRESHOLD,
                 zero_after: bool = True) -> int:
    """The order at the largest gap of the Hankel singular values.

    The order ``n`` maximises ``sigma_n / sigma_(n+1)`` over the orders
    whose last kept value ``sigma_n`` is at least ``threshold * sigma_1``,
    with ``sigma_(n+1) = 0`` after the last value: the model keeps the
    states up to the clearest drop in the singular values, and the drop must
    come before the values fall below the ``threshold`` (below it, the small
    values that noise in an estimated impulse response adds differ from
    each other by small ratios, with occasional large ones that mean
    nothing).  Among equal gaps the lowest order wins.

    Parameters
    ----------
    hankel_singular_values : array-like of shape (n,)
        Non-negative, in decreasing order; the values that are numerically
        non-zero (a zero after the last is implied).
    threshold : float, default=1e-3
        Relative size, in (0, 1], of the smallest singular value an order may keep.
    zero_after : bool, default=True
        Whether the values after the last are zero (a Hankel matrix of lower
        rank than its size: an exactly low-order response).  When False (a
        full-rank Hankel matrix of an estimated response, whose last values
        are noise), the drop after the last value is no candidate.

    Returns
    -------
    int
        The order, in ``1..n``.

    Examples
    --------
    >>> select_order([1.0, 0.9, 0.1, 0.09, 0.003, 0.002, 1e-4, 9e-5])
    4
    >>> select_order([1.0, 0.5, 0.25])  # all kept: the drop to zero after the last
    3
    >>> select_order([1.0, 0.5, 0.25], threshold=0.4)
    1
    >>> select_order([1.0, 0.98, 0.5, 0.48, 0.16, 0.159, 0.095], zero_after=False)
    4
    """
    s = as_real_array(hankel_singular_values, "hankel_singular_values").reshape(-1)
    if s.size == 0 or not np.all(np.isfinite(s)) or np.any(s < 0) or s[0] <= 0:
        raise ValueError(
            "hankel_singular_values must be finite, non-negative and not all zero; "
            f"got {s[:5]}{'...' if s.size > 5 else ''}"
        )
    if np.any(np.diff(s) > 1e-12 * s[0]):
        raise ValueError("hankel_singular_values must be in decreasing order")
    threshold = check_positive(threshold, "threshold")
    if threshold > 1:
        raise ValueError(f"threshold must be in (0, 1]; got {threshold!r}")
    n_kept = int(np.sum(s >= threshold * s[0]))  # at least 1: s[0] >= threshold * s[0]
    if not zero_after and n_kept == s.size and s.size > 1:
        n_kept -= 1  # no drop to zero after the last value to choose
    following = np.append(s, 0.0)[1 : n_kept + 1]
    with np.errstate(divide="ignore"):
        gaps = np.where(following > 0, s[:n_kept] / np.where(following > 0, following, 1.0),
                        np.inf)
    return int(np.argmax(gaps)) + 1


def _numerical_rank(s: np.ndarray, shape) -> int:
    if s.size == 0 or s[0] == 0:
        return 0
    return int(np.sum(s > max(shape) * np.finfo(float).eps * s[0]))


def _svd(matrix: np.ndarray):
    try:
        return linalg.svd(matrix, full_matrices=False, check_finite=False)
    except linalg.LinAlgError:  # the divide-and-conquer driver rarely fails to converge
        return linalg.svd(matrix, full_matrices=False, check_finite=False, lapack_driver="gesvd")


def _check_order(n_states, rank: int, singular_values: np.ndarray, threshold: float) -> int:
    if n_states is None:
        return select_order(singular_values[:rank], threshold,
                            zero_after=rank < singular_values.size)
    return check_int(n_states, "n_states", low=1, high=rank)


def era(markov, n_states: int | None = None, *, n_block_rows: int | None = None,
        n_block_cols: int | None = None, threshold: float = DEFAULT_THRESHOLD) -> Realization:
    """Realize a state-space model of an impulse response (Ho-Kalman, ERA).

    With ``H = U S V^T`` the block Hankel matrix of :func:`block_hankel` and
    ``H1`` the one shifted by one lag, the realization of order ``n`` is

    * ``A = S_n^(-1/2) U_n^T H1 V_n S_n^(-1/2)``,
    * ``B`` the first block column of ``S_n^(1/2) V_n^T``,
    * ``C`` the first block row of ``U_n S_n^(1/2)``,
    * ``D = h(0)``.

    If the impulse response comes from a system of order ``n`` and the
    Hankel matrix is large enough to hold ``n`` independent rows and
    columns, the realization of order ``n`` reproduces every Markov
    parameter, also beyond the lags in ``H``.  With the default size (the
    whole finite impulse response) it is the balanced truncation of the FIR
    to ``n`` states (see the module's notes).

    Parameters
    ----------
    markov : array-like of shape (n_lags,) or (n_lags, n_outputs, n_inputs)
        The impulse response ``h(0), h(1), ..., h(n_lags - 1)``, at least two lags.
    n_states : int, optional
        Order of the realization, in ``1..r`` with ``r`` the numerical rank
        of ``H``; by default chosen by :func:`select_order`.
    n_block_rows, n_block_cols : int, optional
        Size of ``H`` in blocks; default ``n_lags - 1`` each (the FIR's
        Hankel operator).  For the exact realization of a sequence that does
        not end, use sizes with ``n_block_rows + n_block_cols + 1 <= n_lags``.
    threshold : float, default=1e-3
        Passed to :func:`select_order` when ``n_states`` is None.

    Returns
    -------
    Realization
        With the singular values of ``H`` as ``hankel_singular_values``.

    Raises
    ------
    ValueError
        If ``n_states`` is out of range, or the impulse response after lag 0
        is zero (a static gain, with nothing to realize).

    Examples
    --------
    A second-order system from its first 8 Markov parameters:

    >>> import numpy as np
    >>> A = np.array([[0.9, 0.2], [-0.2, 0.9]])
    >>> B, C = np.array([[1.0], [0.0]]), np.array([[1.0, 1.0]])
    >>> h = [0.0] + [(C @ np.linalg.matrix_power(A, k) @ B).item() for k in range(7)]
    >>> r = era(h, n_block_rows=3, n_block_cols=3)
    >>> r.n_states
    2
    >>> bool(np.allclose(r.markov_parameters(12)[1:, 0, 0],
    ...     [(C @ np.linalg.matrix_power(A, k) @ B).item() for k in range(11)]))
    True
    """
    h = as_markov(markov, "markov")
    n_lags = h.shape[0]
    rows = n_lags - 1 if n_block_rows is None else check_int(n_block_rows, "n_block_rows", low=1)
    cols = n_lags - 1 if n_block_cols is None else check_int(n_block_cols, "n_block_cols", low=1)
    product = _HankelProduct(h, rows, cols)
    if min(product.shape) > DENSE_SPECTRUM_SIZE:
        leading = _leading_realization(h, product, n_states, threshold)
        if leading is not None:
            return leading
    # the values first (no vectors), then the leading triplets of the order chosen only
    s = hankel_singular_values(h, rows, cols)
    rank = _numerical_rank(s, product.shape)
    if rank == 0:
        raise ValueError(
            "markov is zero after lag 0 (a static gain): there is no state to realize"
        )
    n = _check_order(n_states, rank, s, threshold)
    U, leading, Vt = _leading_triplets(h, product, n)
    return _realize(h, product, U, leading, Vt, n, values=s)


#: above this many rows and columns, :func:`era` finds only the leading Hankel
#: singular values (ARPACK on FFT products) and bounds the rest, when the
#: ``LEADING_VALUES`` largest reach below the order rule's threshold
DENSE_SPECTRUM_SIZE = 1500
LEADING_VALUES = 64


def _frobenius_square(h: np.ndarray, product: _HankelProduct) -> float:
    """``||H||_F^2``: each Markov parameter ``h(1 + k)`` appears once per ``i + j = k``."""
    k = np.arange(product.rows + product.cols - 1)
    counts = np.minimum(k, product.rows - 1) - np.maximum(0, k - product.cols + 1) + 1
    kept = h[1 : 1 + k.size]
    return float(np.sum(counts[: kept.shape[0]] * np.sum(kept ** 2, axis=(1, 2))))


def _leading_realization(h, product: _HankelProduct, n_states, threshold):
    """:func:`era` from the leading singular triplets only, or None where they do not suffice.

    The ``LEADING_VALUES`` leading triplets are found (ARPACK on the FFT
    products; more when ``n_states`` is given); they suffice when the
    smallest is below ``threshold`` times the largest (the values
    :func:`select_order` reads) and beyond ``n_states``; the sum of the values not found is bounded through
    the Frobenius norm, ``sum_{i > k} s_i <= sqrt((r - k) (||H||_F^2 -
    sum_{i <= k} s_i^2))`` (Cauchy-Schwarz), ``r`` the smaller dimension.
    None when they do not suffice (the values-only dense spectrum is then
    the cheaper route).
    """
    from scipy.sparse.linalg import ArpackNoConvergence, svds

    size = min(product.shape)
    operator = product.operator()
    start = np.full(product.shape[1], 1.0 / np.sqrt(product.shape[1]))  # deterministic
    # one attempt: ARPACK's cost grows as k^2 per restart, and beyond some 64 values the
    # values-only dense spectrum is cheaper (an estimated FIR's values above the threshold
    # can number hundreds, from the noise in its tail)
    k = LEADING_VALUES if n_states is None else max(LEADING_VALUES, 2 * int(n_states) + 8)
    if k < size // 4:
        try:
            U, s, Vt = svds(operator, k=k, v0=start, solver="arpack")
        except ArpackNoConvergence:
            return None
        order = np.argsort(s)[::-1]
        U, s, Vt = U[:, order], s[order], Vt[order]
        if s[0] <= 0:
            return None
        enough = s[-1] < threshold * s[0] and s[-1] > size * np.finfo(float).eps * s[0]
        if enough and (n_states is None or int(n_states) < k):
            n = _check_order(n_states, k, s, threshold) if n_states is not None else \
                select_order(s, threshold, zero_after=False)
            rest = max(_frobenius_square(h, product) - float(np.sum(s ** 2)), 0.0)
            tail = float(np.sqrt((size - k) * rest))
            realization = _realize(h, product, U, s, Vt, n)
            return Realization(A=realization.A, B=realization.B, C=realization.C,
                               D=realization.D, hankel_singular_values=s, n_states=n,
                               tail_bound=tail)
    return None


def _leading_triplets(h, product: _HankelProduct, n: int):
    """``(U_n, s_n, V_n^T)`` of the Hankel matrix: iteratively, or by the full SVD.

    ARPACK on the FFT products (to machine precision) where ``n`` is small
    against the size; after the full SVD every triplet is returned.
    """
    from scipy.sparse.linalg import ArpackNoConvergence, svds

    size = min(product.shape)
    if size >= _ITERATIVE_MIN_SIZE and n < size // 4:
        start = np.full(product.shape[1], 1.0 / np.sqrt(product.shape[1]))  # deterministic
        try:
            U, s, Vt = svds(product.operator(), k=n, v0=start, solver="arpack")
        except ArpackNoConvergence:
            pass
        else:
            order = np.argsort(s)[::-1]
            return U[:, order], s[order], Vt[order]
    return _svd(block_hankel(h, product.rows, product.cols))


def _realize(h, product: _HankelProduct, U, s, Vt, n: int, values=None,
             complete: bool = True) -> Realization:
    """The order-``n`` realization from the leading singular triplets of ``H``.

    ``values``: the Hankel singular values the realization reports
    (default ``s``).
    """
    p, m = h.shape[1:]
    shifted = _HankelProduct(h, product.rows, product.cols, shift=1)
    root = np.sqrt(s[:n])
    left, right = U[:, :n] / root, Vt[:n].T / root
    A = left.T @ shifted.matmat(right)
    B = (root[:, None] * Vt[:n])[:, :m]
    C = (U[:, :n] * root)[:p, :]
    return Realization(A=A, B=B, C=C, D=h[0].copy(),
                       hankel_singular_values=s if values is None else values, n_states=n,
                       complete=complete)


# below this many rows or columns of H a full SVD is as fast as an iterative one
_ITERATIVE_MIN_SIZE = 100


def leading_era(markov, n_states: int) -> Realization:
    """:func:`era` of a given order from the leading singular triplets only.

    The ``n_states`` largest singular triplets of the default Hankel matrix
    are found iteratively (ARPACK, to machine precision), many times faster
    than the full SVD for a long impulse response and a low order: for
    realizing many impulse responses, such as posterior draws.  The
    realization is that of :func:`era`; its ``hankel_singular_values``
    hold the ``n_states`` leading values only, so its ``error_bound`` is
    not available (NaN).

    Parameters
    ----------
    markov : array-like of shape (n_lags,) or (n_lags, n_outputs, n_inputs)
    n_states : int
        At least 1 and below the numerical rank of the Hankel matrix.

    Returns
    -------
    Realization

    Examples
    --------
    >>> import numpy as np
    >>> h = np.r_[0.0, 0.9 ** np.arange(299)]
    >>> r, full = leading_era(h, 1), era(h, 1)
    >>> bool(np.allclose(r.A, full.A) and np.allclose(r.B * r.C, full.B * full.C))
    True
    >>> r.hankel_singular_values.shape, np.isnan(r.error_bound)
    ((1,), np.True_)
    """
    h = as_markov(markov, "markov")
    product = _HankelProduct(h, h.shape[0] - 1, h.shape[0] - 1)
    n = check_int(n_states, "n_states", low=1, high=min(product.shape))
    if min(product.shape) < _ITERATIVE_MIN_SIZE or n >= min(product.shape) // 4:
        full = era(h, n)
        return Realization(A=full.A, B=full.B, C=full.C, D=full.D,
                           hankel_singular_values=full.hankel_singular_values[:n], n_states=n)
    U, s, Vt = _leading_triplets(h, product, n)
    s = s[:n]
    if s[0] == 0 or s[-1] <= max(product.shape) * np.finfo(float).eps * s[0]:
        raise ValueError(
            f"n_states must be below the numerical rank of the Hankel matrix; got {n}"
        )
    return _realize(h, product, U, s, Vt, n, complete=False)


def _psd_root(gramian: np.ndarray) -> np.ndarray:
    """A factor ``L`` with ``L L^T = gramian`` (symmetric part, negative rounding clipped)."""
    w, Q = linalg.eigh(0.5 * (gramian + gramian.T))
    return Q * np.sqrt(np.maximum(w, 0.0))


def balanced_truncation(A, B, C, D, n_states: int | None = None, *,
                        threshold: float = DEFAULT_THRESHOLD) -> Realization:
    """Balanced truncation of a stable discrete-time state-space model.

    The Gramians solve ``Wc = A Wc A^T + B B^T`` and
    ``Wo = A^T Wo A + C^T C``; with ``Wc = Lc Lc^T``, ``Wo = Lo Lo^T`` and
    ``Lo^T Lc = U S V^T``, the Hankel singular values are ``S`` and the
    reduced model is ``(Ti A T, Ti B, C T, D)`` with
    ``T = Lc V_n S_n^(-1/2)`` and ``Ti = S_n^(-1/2) U_n^T Lo^T`` (the
    square-root algorithm).  Its frequency response differs from the
    original's by at most twice the sum of the discarded Hankel singular
    values (:attr:`Realization.error_bound`).

    Parameters
    ----------
    A : array-like of shape (n, n)
        Stable: every eigenvalue inside the unit circle.
    B : array-like of shape (n, n_inputs)
    C : array-like of shape (n_outputs, n)
    D : array-like of shape (n_outputs, n_inputs)
    n_states : int, optional
        Order of the reduced model, in ``1..r`` with ``r`` the number of
        numerically non-zero Hankel singular values; by default chosen by
        :func:`select_order`.
    threshold : float, default=1e-3
        Passed to :func:`select_order` when ``n_states`` is None.

    Returns
    -------
    Realization

    Examples
    --------
    >>> import numpy as np
    >>> A, B, C = np.diag([0.5, 0.01]), [[1.0], [0.1]], [[1.0, 0.1]]
    >>> r = balanced_truncation(A, B, C, [[0.0]], n_states=1)
    >>> r.hankel_singular_values.round(4)
    array([1.3409, 0.0024])
    >>> r.A.round(3).tolist(), round(r.error_bound, 4)
    ([[0.497]], 0.0048)
    """
    A = as_real_array(A, "A")
    if A.ndim != 2 or A.shape[0] != A.shape[1] or A.shape[0] == 0:
        raise ValueError(f"A must be a non-empty square matrix; got shape {A.shape}")
    n = A.shape[0]
    B, C, D = as_real_array(B, "B"), as_real_array(C, "C"), as_real_array(D, "D")
    if B.ndim != 2 or B.shape[0] != n:
        raise ValueError(f"B must have shape ({n}, n_inputs); got {B.shape}")
    if C.ndim != 2 or C.shape[1] != n:
        raise ValueError(f"C must have shape (n_outputs, {n}); got {C.shape}")
    if D.shape != (C.shape[0], B.shape[1]):
        raise ValueError(f"D must have shape {(C.shape[0], B.shape[1])}; got {D.shape}")
    for name, value in zip("ABCD", (A, B, C, D)):
        if not np.all(np.isfinite(value)):
            raise ValueError(f"{name} must be finite (no NaN or inf)")
    if np.max(np.abs(linalg.eigvals(A))) >= 1.0:
        raise ValueError("A must be stable (every eigenvalue strictly inside the unit circle)")
    Lc = _psd_root(linalg.solve_discrete_lyapunov(A, B @ B.T))
    Lo = _psd_root(linalg.solve_discrete_lyapunov(A.T, C.T @ C))
    U, s, Vt = _svd(Lo.T @ Lc)
    rank = _numerical_rank(s, A.shape)
    if rank == 0:
        raise ValueError("the system has no controllable and observable state to keep")
    k = _check_order(n_states, rank, s, threshold)
    root = np.sqrt(s[:k])
    T = Lc @ Vt[:k].T / root
    Ti = (U[:, :k] / root).T @ Lo.T
    return Realization(A=Ti @ A @ T, B=Ti @ B, C=C @ T, D=D.copy(),
                       hankel_singular_values=s, n_states=k)
