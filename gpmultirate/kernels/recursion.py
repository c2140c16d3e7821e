r"""Slow-rate covariance of shift-scaled kernels by a recursion along diagonals.

The lag kernels TC, DC and SS are *shift-scaled* on the integer lag grid:

.. math:: K(i + 1, j + 1) = a\, K(i, j),

with ``a = alpha`` for TC and DC and ``a = alpha**3`` for SS.  Let

.. math:: S_f(n, n') = \sum_{i,j=0}^{P-1} u(n - i)\, u(n' - j)\, K(i, j)

be the covariance of the noise-free fast-rate output (``u(k) = 0`` for
``k < 0``), so that the slow covariance is ``S[m, m'] = S_f(n_m, n_{m'})``
with ``n_m = offset + m F``.  Splitting off the terms with ``i = 0`` or
``j = 0`` and shifting the others by one lag gives, with

.. math::

    r(n) = \sum_{j} K(0, j)\, u(n - j), \qquad
    s(n) = \sum_{j} K(P-1, j)\, u(n - j),

the exact first-order recursion along each diagonal ``n' = n + d``:

.. math::

    S_f(n+1, n'+1) &= a \bigl(S_f(n, n') - u(n-P+1)\, s(n')
                      - s(n)\, u(n'-P+1) + K_{P-1,P-1}\, u(n-P+1)\, u(n'-P+1)\bigr) \\
                   &\quad + u(n+1)\, r(n'+1) + r(n+1)\, u(n'+1) - K_{0,0}\, u(n+1)\, u(n'+1),

started from ``S_f(-1, d - 1) = 0``.  The bracket is the sum over lags
``0..P-2`` (the lag ``P - 1`` drops out of the window), the second line the
terms entering at lag 0; when ``P = N`` the bracket terms vanish on the
record.  Every step multiplies the previous value by ``0 < a <= 1`` and
adds a forcing term, so rounding errors are never amplified.

Only the diagonals ``d = k F`` are needed, and only at ``n = n_m``.
Writing the recursion as ``x(n) = a x(n-1) + f(n)`` and unrolling one slow
period,

.. math:: x(n_m) = a^F x(n_{m-1}) + \sum_{l=0}^{F-1} a^l f(n_m - l).

Each forcing term is a product ``p(n) q(n + d)`` of two sequences, so on
the slow grid (``m' = m + k``) the period sum is

.. math:: Y[m, m'] = \sum_{p, q} \sum_{l=0}^{F-1} c_{pl}\, p(n_m - l)\, q(n_{m'} - l),

the product of two ``(4F, M)`` matrices (``2F`` rows when ``P = N``), and

.. math:: S[m, m'] = a^F S[m-1, m'-1] + Y[m, m'],  \qquad S[-1, \cdot] = 0,

is evaluated row by row on the upper triangle.  That is ``O(M^2 F) =
O(M N)`` operations, mostly one matrix product, against ``O(M^2 P)`` for
``Phi K Phi^T``.

Derivatives with respect to ``theta`` (the hyperparameters in tuning
coordinates: ``log(alpha)``, ``artanh(beta)`` for DC) follow by
differentiating this form (forward mode):

.. math::

    S'[m, m'] = a^F S'[m-1, m'-1] + F \rho\, a^F S[m-1, m'-1] + Y'[m, m'],

with ``rho = d log(a) / d theta`` (1 for ``log alpha`` of TC and DC, 3 for
SS, 0 for DC's ``beta``) and ``Y'`` the product rule applied to the two
factors; the factors depend on ``theta`` through ``a`` and through ``r``
and ``s``, i.e. only through the first and last kernel rows.

The kernel enters only through ``a`` (:meth:`ShiftScaledKernel.shift_scale
<gpmultirate.kernels.lag.ShiftScaledKernel.shift_scale>`) and its first and
last rows, which come from the kernel's own formula
(:meth:`~gpmultirate.kernels.lag.LagKernel.lag_covariance`), and the
observation only through its uniform sampling (``u``, ``F``, offset).
``Phi K`` costs ``O(M P)`` through the kernel's own ``right_multiply`` of the
observation's strided regressor view.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from gpmultirate.kernels.structure import ObservedTerm

__all__ = ["ShiftScaledTerm", "observed_recursion", "prefer_recursion"]


# ----------------------------------------------------------------------------
# the first and last kernel rows and their derivatives
# ----------------------------------------------------------------------------


class _Rows:
    """First and last rows of ``K`` on lags ``0..P-1``, the scale ``a`` and derivatives.

    ``d_first[name]`` and ``d_last[name]`` are the derivatives of the rows
    with respect to the ``theta`` entry of ``name``, ``rho[name]`` that of
    ``log(a)``; ``free``
    lists the free hyperparameters in ``theta`` order.
    """

    def __init__(self, kernel, order: int):
        j = np.arange(order, dtype=float)
        first, d_first = kernel.lag_covariance(np.zeros(1), j, eval_gradient=True)
        last, d_last = kernel.lag_covariance(np.array([order - 1.0]), j, eval_gradient=True)
        self.scale, self.rho = kernel.shift_scale()
        self.first, self.last = first[0], last[0]
        self.d_first = {name: d[0] for name, d in d_first.items()}
        self.d_last = {name: d[0] for name, d in d_last.items()}
        self.free = [h.name for h in kernel.hyperparameters if not h.fixed]


# ----------------------------------------------------------------------------
# S = Phi K Phi^T and its gradient contraction
# ----------------------------------------------------------------------------


def _convolve(u: np.ndarray, row: np.ndarray) -> np.ndarray:
    """``sum_j row[j] u(n - j)`` for ``n = 0..N-1``."""
    return signal.convolve(u, row, mode="full")[: u.shape[0]]


def _phases(sequence: np.ndarray, factor: int, offset: int, n_out: int) -> np.ndarray:
    """``out[l, m] = sequence(n_m - l)`` for ``l = 0..F-1`` (zero at negative indices)."""
    padded = np.concatenate([np.zeros(factor), sequence])
    index = (
        factor
        + offset
        + factor * np.arange(n_out)[None, :]
        - np.arange(factor)[:, None]
    )
    return padded[index]


class _Forcing:
    """Low-rank factors of the forcing summed over one slow period.

    Along the diagonal ``d`` the recursion is ``x(n) = a x(n-1) + f(n)``
    with ``f = a g + h``,

    * ``h(n) = u(n) Q(n + d) + r(n) u(n + d)``, ``Q = r - K00 u``,
    * ``g(n) = -(ul(n) T(n + d) + sl(n) ul(n + d))``, ``ul(n) = u(n - P)``,
      ``sl(n) = s(n - 1)``, ``T = sl - K_LL ul`` (zero when ``P = N``).

    Unrolled over one slow period, ``x(n_m) = a^F x(n_{m-1}) + Y``
    with ``Y = sum_{l<F} a^l f(n_m - l)``.  On the slow grid (``m' = m + k``,
    ``d = k F``) this is ``Y[m, m'] = sum_rows left[:, m] right[:, m']``,
    a product of ``(4F, M)`` factors built from the phases of the sequences.
    """

    def __init__(self, u, order, first, last, factor, offset, n_out):
        n = u.shape[0]
        self.boundary = order < n

        def phase(sequence):
            return _phases(sequence, factor, offset, n_out)

        r = _convolve(u, first)
        self.u = phase(u)
        self.r = phase(r)
        self.Q = phase(r - first[0] * u)
        if self.boundary:
            ul = np.concatenate([np.zeros(order), u[: n - order]])
            sl = np.concatenate([[0.0], _convolve(u, last)[:-1]])
            self.ul = phase(ul)
            self.sl = phase(sl)
            self.T = phase(sl - last[-1] * ul)


def _mirror_upper(S: np.ndarray, block: int = 64) -> None:
    """Copy the upper triangle of ``S`` to its lower triangle, in place."""
    size = S.shape[0]
    for i in range(0, size, block):
        j = min(i + block, size)
        S[j:, i:j] = S[i:j, j:].T
        diagonal_block = S[i:j, i:j]
        diagonal_block[...] = np.triu(diagonal_block) + np.triu(diagonal_block, 1).T


def _square(size: int) -> np.ndarray:
    """An uninitialised ``size x size`` array whose buffer has ``size`` zeros of slack.

    The slack lets :func:`_diagonals` view the array along its diagonals; it
    is zeroed so that the recursion never computes with leftover memory
    (a signalling NaN there raises "invalid value" warnings).
    """
    buffer = np.empty(size * (size + 1))
    buffer[size * size:] = 0.0
    return buffer[: size * size].reshape(size, size)


def _diagonals(X: np.ndarray) -> np.ndarray:
    """View ``D[d, m] = X[m, m + d]`` of a C-ordered square array made by :func:`_square`.

    Entries with ``m + d >= size`` alias the strict lower triangle of ``X``
    (rows below), never the upper one.
    """
    size = X.shape[0]
    step = X.strides[1]
    return np.lib.stride_tricks.as_strided(X, shape=(size, size), strides=(step, (size + 1) * step))


def _recurse_upper(left, right, scale, out, source=None, coupling=0.0):
    """Upper triangle of ``X[m, m'] = scale X[m-1, m'-1] + c X0[m-1, m'-1] + (left^T right)[m, m']``.

    ``X0`` is ``source`` (already computed) and ``c`` is ``coupling``; rows
    start from ``X[-1, :] = 0``.  ``out`` (and ``source``) must come from
    :func:`_square`; the lower triangle of ``out`` is left undefined.  Along
    each diagonal the recursion is a first-order filter, run on all
    diagonals at once; the product is one matrix multiplication (few, large
    BLAS calls behave best when BLAS threads compete for cores).
    """
    np.matmul(left.T, right, out=out)
    forcing = _diagonals(out)
    if coupling != 0.0:
        forcing = forcing.copy()
        forcing[:, 1:] += coupling * _diagonals(source)[:, :-1]
    # along diagonal d, the entries m >= size - d come last: garbage there
    # (the lower triangle) never reaches the upper triangle through the filter
    _diagonals(out)[...] = signal.lfilter([1.0], [1.0, -scale], forcing, axis=1)


def _observed(u, factor, offset, order, rows: _Rows, need_gradient, n_out):
    """``S`` and the list of ``dS_j`` (free hyperparameters) on the slow grid."""
    a = rows.scale
    period = a**factor
    phase_weight = a ** np.arange(factor, dtype=float)[:, None]  # a^l
    lags_in_period = np.arange(factor, dtype=float)[:, None]
    base = _Forcing(u, order, rows.first, rows.last, factor, offset, n_out)
    # h pairs carry a^l, g pairs -a^(l+1)
    h_weight, g_weight = phase_weight, -a * phase_weight
    left = [h_weight * base.u, h_weight * base.r]
    right = [base.Q, base.u]
    if base.boundary:
        left += [g_weight * base.ul, g_weight * base.sl]
        right += [base.T, base.ul]
    left, right = np.concatenate(left), np.concatenate(right)
    S = _square(n_out)
    _recurse_upper(left, right, period, S)
    gradients = []
    for name in rows.free if need_gradient else []:
        rho = rows.rho[name]  # d log(a) / d theta
        d = _Forcing(u, order, rows.d_first[name], rows.d_last[name], factor, offset, n_out)
        # derivative of the weights a^l and -a^(l+1) with respect to theta
        dh_weight = rho * lags_in_period * h_weight
        dg_weight = rho * (lags_in_period + 1.0) * g_weight
        # d(left^T right) = d(left)^T right + left^T d(right).  u and ul do not
        # depend on theta, so their rows of d(left) vanish when a does not either.
        d_left = [dh_weight * base.r + h_weight * d.r]
        d_right = [base.u]
        if rho != 0.0:
            d_left.append(dh_weight * base.u)
            d_right.append(base.Q)
        left_for_d_right = [h_weight * base.u]
        d_of_right = [d.Q]
        if base.boundary:
            d_left.append(dg_weight * base.sl + g_weight * d.sl)
            d_right.append(base.ul)
            if rho != 0.0:
                d_left.append(dg_weight * base.ul)
                d_right.append(base.T)
            left_for_d_right.append(g_weight * base.ul)
            d_of_right.append(d.T)
        dS = _square(n_out)
        _recurse_upper(
            np.concatenate(d_left + left_for_d_right),
            np.concatenate(d_right + d_of_right),
            period,
            dS,
            source=S,
            coupling=factor * rho * period,
        )
        gradients.append(dS)
    _mirror_upper(S)
    for dS in gradients:
        _mirror_upper(dS)
    return S, gradients


def observed_recursion(kernel, sampling, order: int, need_gradient: bool = True):
    """``S = Phi K Phi^T`` and the list of ``dS_j`` by the diagonal recursion.

    Neither ``K`` (``P x P``) nor ``Phi`` (``M x P``) is formed: ``S`` comes
    from the recursion of the module docstring in ``O(M N)`` operations, and
    with ``need_gradient`` every ``dS_j`` from its forward-mode derivative.

    Parameters
    ----------
    kernel : ShiftScaledKernel
        A TC, DC or SS kernel, or any kernel with ``shift_scale`` and
        ``lag_covariance``.
    sampling : UniformSampling
        The input ``u``, ``factor`` and ``offset`` of the observation.
    order : int
        The FIR order ``P``.
    need_gradient : bool, default=True

    Returns
    -------
    S : ndarray of shape (M, M)
        Exactly symmetric.
    derivatives : list of ndarray of shape (M, M)
        One per free hyperparameter in ``kernel.theta`` order; empty
        without ``need_gradient``.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import DC
    >>> op = DownsampledConvolution(np.arange(1.0, 9.0), factor=2, order=5, offset=1)
    >>> kernel = DC(alpha=0.8, beta=0.6)
    >>> S, dS = observed_recursion(kernel, op.uniform_sampling, op.order)
    >>> Phi, K = op.matrix, kernel(op.lags)
    >>> bool(np.allclose(S, Phi @ K @ Phi.T, rtol=1e-12, atol=0)), len(dS)
    (True, 2)
    """
    S, derivatives = _observed(
        np.asarray(sampling.u, dtype=float), sampling.factor, sampling.offset, order,
        _Rows(kernel, order), need_gradient, sampling.n_outputs,
    )
    if sampling.selection is None:
        return S, derivatives
    # the grid held samples that were not measured: keep the measured ones
    keep = np.ix_(sampling.selection, sampling.selection)
    return S[keep], [d[keep] for d in derivatives]


class ShiftScaledTerm(ObservedTerm):
    """A shift-scaled kernel: the recursion where it pays off, ``other`` elsewhere.

    The recursion needs uniformly spaced samples (``observation.uniform_sampling``
    is not None) and is taken where :func:`prefer_recursion` says it is
    faster than ``other``, the kernel's term without the recursion.
    """

    def __init__(self, kernel, observation, path: str, other: ObservedTerm):
        super().__init__(kernel, observation, path)
        self.other = other

    def _sampling(self, need_gradient: bool):
        sampling = self.observation.uniform_sampling
        if sampling is None or not prefer_recursion(
            sampling.n_outputs, sampling.u.shape[0], self.observation.order,
            need_gradient=need_gradient,
        ):
            return None
        return sampling

    def kernel_matrix(self):
        return self.other.kernel_matrix()

    def precision(self):
        return self.other.precision()

    def parameter_contractor(self):
        return self.other.parameter_contractor()

    def covariance(self):
        sampling = self._sampling(False)
        if sampling is None:
            return self.other.covariance()
        return observed_recursion(self.kernel, sampling, self.observation.order, False)[0]

    def covariance_with_contractor(self):
        sampling = self._sampling(True)
        if sampling is None:
            return self.other.covariance_with_contractor()
        S, derivatives = observed_recursion(self.kernel, sampling, self.observation.order)

        def contract(W):
            if W.shape != S.shape:
                raise ValueError(f"W must have shape {S.shape}; got {W.shape}")
            return np.array([np.vdot(W, d) for d in derivatives], dtype=float).reshape(-1)

        return S, contract

    def covariance_with_derivatives(self):
        sampling = self._sampling(True)
        if sampling is None:
            return self.other.covariance_with_derivatives()
        return observed_recursion(self.kernel, sampling, self.observation.order)

    def covariance_blocks(self, split):
        if self._sampling(False) is None:
            return self.other.covariance_blocks(split)
        return super().covariance_blocks(split)

    def regressor_times_kernel(self):
        # O(M P): the kernel's own product with the (strided) regressor
        return self.kernel.right_multiply(self.observation.regressor_view())


# ----------------------------------------------------------------------------
# cost model
# ----------------------------------------------------------------------------


def prefer_recursion(M: int, N: int, P: int, *, need_gradient: bool = True) -> bool:
    """Return True when the recursion is expected to beat the filter-and-BLAS route.

    That route is :class:`~gpmultirate.kernels.filters.DCFilterTerm` for DC.

    Both costs are modelled in seconds and compared.  With ``F = N / M``,

    * BLAS route (DC: ``Phi`` cached, ``H G^T`` and, for the gradient,
      ``W G`` and ``W H``): ``c0 + c1 M P + c2 M^2 P + c3 M^2 log2(M)``;
    * recursion: ``d0 + d1 M + d2 M^2 F + d3 N log2(N) + d4 M^2 log2(M)``
      (one product of ``(M, 4F)`` factors per matrix, a loop over the ``M``
      rows, FFT convolutions for ``r`` and ``s``).

    The ``M^2 log2(M)`` terms stand for the memory traffic of ``M x M``
    arrays, which grows faster than ``M^2`` once they leave the cache.  The
    constants were fitted to timings of a DC kernel (two free
    hyperparameters) with one BLAS thread on a two-core x86-64 machine, for
    ``M`` in 100..2000, ``F`` in 1..100 and ``P`` in 5..N; on those the rule
    loses at most about 40% against the better route (a millisecond or
    two), and it picks the recursion for every case where that is more
    than twice as fast.  The recursion needs neither ``Phi`` (``M x P``)
    nor ``K`` (``P x P``), which matters for memory when ``P`` is large.

    Parameters
    ----------
    M : int
        Number of slow samples.
    N : int
        Number of fast samples (input length).
    P : int
        FIR order.
    need_gradient : bool, default=True
        Whether the gradient contraction is needed as well as ``S``.

    Returns
    -------
    bool

    Examples
    --------
    >>> prefer_recursion(2000, 6000, 6000)
    True
    >>> prefer_recursion(500, 50_000, 10)
    False
    """
    M, N, P = float(M), float(N), float(P)
    F = N / M
    memory = M * M * np.log2(max(M, 2.0))
    if need_gradient:
        blas = 1.35e-4 + 3.86e-8 * M * P + 6.96e-11 * M * M * P + 6.56e-10 * memory
        recursion = (
            1.13e-3 + 7.61e-6 * M + 4.31e-10 * M * M * F
            + 2.40e-8 * N * np.log2(N) + 1.32e-9 * memory
        )
    else:
        blas = 5.2e-5 + 1.85e-8 * M * P + 3.67e-11 * M * M * P + 4.35e-10 * memory
        recursion = (
            3.0e-4 + 3.19e-6 * M + 1.0e-10 * M * M * F
            + 7.05e-9 * N * np.log2(N) + 1.16e-10 * memory
        )
    return bool(recursion < blas)
