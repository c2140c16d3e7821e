r"""Kernels seen through readings at their own instants: the terms of timed readings.

Readings between the fast ticks, with an exposure and a latency
(:class:`~gpmultirate.observations.TimedConvolution`), are no matrix on the
integer lags, so the terms of :mod:`gpmultirate.kernels.structure` that
start from ``Phi`` do not apply.  The walker
(:func:`~gpmultirate.kernels.structure.observe`) keeps sums and constant
multiples; each leaf answers through
:meth:`~gpmultirate.kernels.StructuredKernel.observed_at_instants`, and
these are the terms the kernels return there:

* TC, DC (``beta != 0``) and SS of one input: :class:`ShiftScaledTimedTerm`,
  by their semiseparable structure between integer lags
  (:mod:`gpmultirate.kernels.offsets`), ``O(M P + M^2 P)``;
* PK of one input: :class:`PKTimedTerm`, and a constant:
  :class:`ConstantTimedTerm`, of rank two and one at any lag, by their bases;
* any other kernel (products, inputs coupled, any scikit-learn kernel):
  :class:`DenseTimedTerm`, from the kernel at the real lags grouped by the
  distinct offsets, ``O(G^2 P^2)`` kernel entries for ``G`` distinct offsets
  (as cheap as on the ticks for ``G = 1``, meant for small problems
  otherwise).

The derivatives of the structured terms are exact to rounding: the complex
step on the hyperparameter values.  Where the exposure windows of TC, DC
and SS meet on one integer lag, their double integral is in closed form for
single exponentials
(:func:`~gpmultirate.kernels.offsets.ordered_exponential_integral`) and
split at the kink otherwise (:func:`_ordered_integral`).

The terms read the readings' points (their regressor rows, offsets from
their ticks, quadrature weights and window pieces: ``unique_rows``,
``point_offsets``, ``point_readings``, ``point_weights``, ``point_row_ids``,
``pieces``) from the observation; how those are formed is the observation's
business.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

from gpmultirate.kernels.offsets import (
    _exp_integral, offset_structure, ordered_exponential_integral, times_lower,
)
from gpmultirate.kernels.structure import ConstantTerm, ObservedTerm

__all__ = ["BLOCK_ENTRIES", "ConstantTimedTerm", "DenseTimedTerm", "PKTimedTerm",
           "ShiftScaledTimedTerm", "semiseparable_term"]

#: the complex step of the derivatives (relative to the value)
_STEP = 1e-30
#: kernel entries formed at once by the dense route and the cross-covariance
BLOCK_ENTRIES = 2**22


def _ordered_integral(f, h, a1, b1, a2, b2, xi, w):
    """``int_{x in [a1, b1]} int_{y in [a2, b2], y < x} f(x) h(y) dy dx``, elementwise.

    The region's edge ``y = x`` is where the kernel has its kink; on each
    side of ``x = b2`` the integrand is smooth, so nested Gauss-Legendre
    rules on the two parts are exact to rounding for the exponentials and
    cosines of the lag kernels.
    """
    low = np.maximum(a1, a2)
    high = np.maximum(b1, low)
    split = np.clip(b2, low, high)
    total = 0.0
    for start, stop, follows_x in ((low, split, True), (split, high, False)):
        half = 0.5 * (stop - start)
        x = start[..., None] + half[..., None] * (xi + 1.0)
        upper = x if follows_x else np.broadcast_to(b2[..., None], x.shape)
        inner_half = 0.5 * (upper - a2[..., None])
        y = a2[..., None, None] + inner_half[..., None] * (xi + 1.0)
        inner = (h(y) @ w) * inner_half
        total = total + ((f(x) * inner) @ w) * half
    return total


def _cell_integrals(found, r, f, h, a, b, nodes):
    """Over each cell ``[a, b]``: the integrals of ``f_r`` and ``h_r``, and of ``f_r(x) h_r(y)``
    over its triangle ``y < x`` (closed form for exponentials, else Gauss-Legendre)."""
    if found.rates is not None:
        lam, mu = found.rates[r]
        return (_exp_integral(lam, a, b), _exp_integral(mu, a, b),
                ordered_exponential_integral(lam, mu, a, b, a, b))
    xi, w = np.polynomial.legendre.leggauss(nodes)
    half = 0.5 * (b - a)
    x = a[:, None] + half[:, None] * (xi + 1.0)
    return ((f(x) @ w) * half, (h(x) @ w) * half, _ordered_integral(f, h, a, b, a, b, xi, w))


def _step_product(A, B):
    """``A @ B`` for real or complex-step matrices, in real products.

    A complex-step value is ``x + i h x'`` with ``h`` far below rounding, so
    the product of the two imaginary parts (``O(h^2)``) is dropped, as the
    complex step drops it from the real part: three real products where
    the complex one takes four, two where one factor is real.
    """
    a_complex, b_complex = np.iscomplexobj(A), np.iscomplexobj(B)
    if not (a_complex or b_complex):
        return A @ B
    if not b_complex:
        return (A.real @ B) + 1j * (A.imag @ B)
    if not a_complex:
        return (A @ B.real) + 1j * (A @ B.imag)
    return (A.real @ B.real) + 1j * (A.imag @ B.real + A.real @ B.imag)


def _base_at_points(found, d):
    """``k(d_i, d_j)`` at the offsets, from the lower pieces (``k(x, y) = sum_r A_r[0, 0]
    f_r(x) h_r(y)`` for ``x >= y``): ``O(M)`` exponentials instead of ``O(M^2)`` powers."""
    later = d[:, None] >= d[None, :]
    out = 0.0
    for p_r, q_r, _, f, h in found.lower:
        outer = np.multiply.outer(f(d), h(d))
        out = out + p_r[0] * q_r[0] * np.where(later, outer, outer.T)
    return out


class _TimedTerm(ObservedTerm):
    """A leaf kernel seen through timed readings; subclasses provide :meth:`_build`.

    ``_build(values)`` returns the covariance of the readings for the
    hyperparameter ``values`` (real, or complex for the complex step); the
    derivative with respect to a free ``theta`` entry is
    ``Im build(value + i h) / h`` times ``d value / d theta``.
    """

    def _values(self) -> dict:
        return {h.name: float(getattr(self.kernel, h.name)) for h in self.kernel.hyperparameters}

    def _free(self):
        return [h for h in self.kernel.hyperparameters if not h.fixed]

    def _build(self, values):
        raise NotImplementedError

    def covariance(self):
        if getattr(self, "_covariance", None) is None:
            S = np.real(self._build(self._values()))
            self._covariance = 0.5 * (S + S.T)
        return self._covariance

    def _derivatives(self):
        values = self._values()
        items = []
        for h in self._free():
            step = _STEP * max(abs(values[h.name]), 1.0)
            moved = dict(values)
            moved[h.name] = values[h.name] + 1j * step
            built = self._build(moved)
            if getattr(self, "_covariance", None) is None:
                # the real part of the complex step is the value to O(step^2): no build of its own
                S = np.real(built)
                self._covariance = 0.5 * (S + S.T)
            dS = np.imag(built) / step
            transform = getattr(self.kernel, "theta_transform", None)
            chain = (values[h.name] if transform is None
                     else float(transform(h.name).derivative(values[h.name])))
            dS = chain * 0.5 * (dS + dS.T)
            items.append(dS)
        return items

    def covariance_with_derivatives(self):
        items = self._derivatives()
        return self.covariance(), items

    def covariance_with_contractor(self):
        items = self._derivatives()
        return self.covariance(), lambda W: np.array([np.sum(W * dS) for dS in items])

    def regressor_times_kernel(self):
        return self.cross_covariance(self.observation.lags).T

    def low_rank(self):
        return None

    def precision(self):
        return None


class ShiftScaledTimedTerm(_TimedTerm):
    """TC, DC or SS through timed readings, by the semiseparable structure.

    The kernel gives its pieces (``kernel.offset_structure(values, order)``,
    see :mod:`gpmultirate.kernels.offsets`).

    With the strictly lower pieces ``A_r, f_r, h_r`` and the shift scale
    ``c`` (:func:`~gpmultirate.kernels.offsets.offset_structure`), the
    readings' covariance is

    ``S = sum_r (X_r A_r Y_r^T + Y_r A_r^T X_r^T) + Q ((R C R^T) o H) Q^T``

    with ``X_r = Q diag(f_r) R`` and ``Y_r = Q diag(h_r) R`` (``R`` the
    points' regressor rows, ``Q`` the quadrature sums), ``C = diag(c^k)``
    and ``H = k(d_i, d_j)`` at the points' offsets.
    """

    def _build(self, values):
        obs = self.observation
        P = obs.order
        found = offset_structure(self.kernel, values, P)
        d = obs.point_offsets
        S = 0.0
        for p, q, c, f, h in found.lower:
            X = obs.weighted_rows(f(d))
            Y = obs.weighted_rows(h(d))
            part = _step_product(times_lower(X, p, q, c), Y.T)
            S = S + part + part.T
        rows = obs.unique_rows()
        scale = found.scale ** np.arange(P, dtype=float)
        G = _step_product(rows * scale, rows.T)
        if obs.exposure == 0.0:
            ids = obs.point_row_ids
            return S + G[np.ix_(ids, ids)] * _base_at_points(found, d)
        return S + self._windows_on_equal_lags(found, G)

    def _windows_on_equal_lags(self, found, G):
        """``sum_k c^k`` times the kernel at the offsets, integrated over pairs of window pieces.

        ``k(k + x, k + y) = c^k k(x, y)`` has its kink at ``x = y``, with
        ``k(x, y) = sum_r A_r[0, 0] f_r(x) h_r(y)`` for ``x > y``.  The ends
        of all the pieces cut ``[0, 1]`` into cells; a piece is a run of
        cells, and the integral over ``y < x`` of two pieces is the sum of
        ``F_a H_b`` over their cells ``a > b`` (``F``, ``H`` the integrals of
        ``f_r``, ``h_r`` over a cell) plus, over their common cells, the
        integral ``T_a`` over the triangle ``y < x`` of the cell.  These are
        in closed form where ``f_r`` and ``h_r`` are exponentials
        (:func:`~gpmultirate.kernels.offsets.ordered_exponential_integral`),
        otherwise by Gauss-Legendre quadrature on the cell (nested on the
        triangle, :func:`_ordered_integral`), where the integrands are
        smooth.  The sums over runs of cells are differences of cumulative
        sums: ``O(n E)`` for ``n`` pieces and ``E <= 2 n`` cells.
        """
        obs = self.observation
        piece, start, stop = obs.pieces
        n_pieces = start.shape[0]
        first_point = np.searchsorted(piece, np.arange(n_pieces))
        reading = obs.point_readings[first_point]
        row = obs.point_row_ids[first_point]
        edges = np.unique(np.concatenate([start, stop]))
        low, high = np.searchsorted(edges, start), np.searchsorted(edges, stop)
        a, b = edges[:-1], edges[1:]
        cells = np.arange(a.shape[0] + 1)
        # common cells of two pieces: from max(low) to max(min(high), max(low))
        common_low = np.maximum.outer(low, low)
        common_high = np.maximum(np.minimum.outer(high, high), common_low)
        block = max(1, BLOCK_ENTRIES // (4 * cells.shape[0]))
        value = 0.0
        for r, (p_r, q_r, _, f, h) in enumerate(found.lower):
            F, H, T = _cell_integrals(found, r, f, h, a, b, obs.nodes)
            zero = np.zeros(1, dtype=F.dtype)
            cum_H = np.concatenate([zero, np.cumsum(H)])
            cum_T = np.concatenate([zero, np.cumsum(T)])
            # I[i, j] = int_{x in piece i} int_{y in piece j, y < x} f_r(x) h_r(y)
            I = np.empty((n_pieces, n_pieces), dtype=F.dtype)
            for j0 in range(0, n_pieces, block):
                j = slice(j0, min(j0 + block, n_pieces))
                # V[j, x]: the integral of h_r over the cells of piece j before cell x
                before = np.clip(cells[None, :-1], low[j, None], high[j, None])
                V = cum_H[before] - cum_H[low[j], None]
                W = np.concatenate([np.zeros((V.shape[0], 1), dtype=V.dtype),
                                    np.cumsum(V * F, axis=1)], axis=1)
                I[:, j] = (W[:, high] - W[:, low]).T
            I += cum_T[common_high] - cum_T[common_low]
            value = value + p_r[0] * q_r[0] * (I + I.T)
        pieces = value * G[np.ix_(row, row)] / obs.exposure**2
        Q = sparse.csr_matrix(
            (np.ones(n_pieces), (reading, np.arange(n_pieces))),
            shape=(obs.n_outputs, n_pieces),
        )
        return np.asarray(Q @ np.asarray(Q @ pieces).T).T

    def cross_covariance(self, lags):
        # the quadrature of the window that meets ``lags`` misses the kernel's kink there:
        # its integral split at the kink replaces it (exact to rounding)
        out = super().cross_covariance(lags)
        if self.observation.exposure > 0.0:
            out += self.observation.kink_correction(self.kernel, lags[:, 0])
        return out

    def regressor_times_kernel(self):
        # Cov(y_i, g(l)): k > l from f_r(d) h_r(0), k < l from f_r(0) h_r(d), k = l from c^k k(d, 0)
        obs = self.observation
        P = obs.order
        found = offset_structure(self.kernel, self._values(), P)
        d = obs.point_offsets
        zero = np.zeros(1)
        out = 0.0
        for p, q, c, f, h in found.lower:
            out = out + times_lower(obs.weighted_rows(f(d)), p, q, c) * float(np.real(h(zero)[0]))
            out = out + float(np.real(f(zero)[0])) * times_lower(
                obs.weighted_rows(h(d)), p, q, c, transpose=True)
        scale = found.scale ** np.arange(P, dtype=float)
        out = out + obs.weighted_rows(found.base(d, zero)[:, 0]) * scale
        return np.real(out)


class ConstantTimedTerm(_TimedTerm):
    """A constant through timed readings: ``S = c U U^T``, ``U`` the readings of the constant 1."""

    def _build(self, values):
        U = self.observation.weighted_rows().sum(axis=1, keepdims=True)
        D = np.array([[values["constant_value"]]])
        return (U @ D) @ U.T

    def roles(self):
        return ConstantTerm(self.kernel, None, self.path).roles()

    def scale_roles(self):
        return [0] if self._free() else None


class PKTimedTerm(_TimedTerm):
    """PK through timed readings: ``S = U D U^T``, ``U`` the readings of its rank-two basis."""

    def _build(self, values):
        obs = self.observation
        P = obs.order
        alpha, omega = values["alpha"], values["omega"]
        rows = obs.point_rows()
        lags = np.arange(P)[None, :] + obs.point_offsets[:, None]
        envelope = alpha ** (lags / 2.0)
        cos_part = np.einsum("ij,ij->i", rows, envelope * np.cos(omega * lags))
        sin_part = np.einsum("ij,ij->i", rows, envelope * np.sin(omega * lags))
        Q = sparse.csr_matrix(
            (obs.point_weights, (obs.point_readings, np.arange(obs.n_points))),
            shape=(obs.n_outputs, obs.n_points),
        )
        U = np.column_stack([Q @ cos_part, Q @ sin_part])
        D = np.diag([values["sigma1"] ** 2, values["sigma2"] ** 2])
        return (U @ D) @ U.T


class DenseTimedTerm(_TimedTerm):
    """Any kernel through timed readings, from the kernel at the real lags, by distinct offsets."""

    def _pairs(self, eval_gradient: bool):
        obs = self.observation
        rows = obs.point_rows()
        offsets, group = np.unique(obs.point_offsets, return_inverse=True)
        group = group.reshape(-1)
        n = obs.n_points
        n_theta = self.kernel.n_dims if eval_gradient else 0
        S = np.zeros((n, n))
        dS = np.zeros((n_theta, n, n))
        members = [np.flatnonzero(group == g) for g in range(offsets.shape[0])]
        lags = [obs.point_lags(o) for o in offsets]
        for a in range(offsets.shape[0]):
            for b in range(a, offsets.shape[0]):
                ia, ib = members[a], members[b]
                if eval_gradient:
                    # scikit-learn's gradients are of k(X, X): both offsets' lags stacked
                    both = lags[a] if a == b else np.vstack([lags[a], lags[b]])
                    K, dK = self.kernel(both, eval_gradient=True)
                    size = lags[a].shape[0]
                    K, dK = K[:size, -size:], dK[:size, -size:]
                else:
                    K = self.kernel(lags[a], lags[b])
                block = rows[ia] @ K @ rows[ib].T
                S[np.ix_(ia, ib)] = block
                S[np.ix_(ib, ia)] = block.T
                for j in range(n_theta):
                    block = rows[ia] @ dK[:, :, j] @ rows[ib].T
                    dS[j][np.ix_(ia, ib)] = block
                    dS[j][np.ix_(ib, ia)] = block.T
        return S, dS

    def covariance(self):
        if getattr(self, "_covariance", None) is None:
            S, _ = self._pairs(False)
            S = self.observation.point_sum(S)
            self._covariance = 0.5 * (S + S.T)
        return self._covariance

    def _derivatives(self):
        S, dS = self._pairs(True)
        point_sum = self.observation.point_sum
        if getattr(self, "_covariance", None) is None:
            S = point_sum(S)
            self._covariance = 0.5 * (S + S.T)
        return [point_sum(d) for d in dS]


def semiseparable_term(kernel, observation, path: str = "") -> ObservedTerm:
    """A kernel with semiseparable pieces between integer lags through timed readings.

    ``kernel`` declares ``offset_structure(values, order)``
    (:mod:`gpmultirate.kernels.offsets`); its term is
    :class:`ShiftScaledTimedTerm` for one input, and the observation's dense
    term for several (the pieces are of one lag axis).
    """
    if observation.n_inputs != 1:
        return observation.dense_term(kernel, path)
    return ShiftScaledTimedTerm(kernel, observation, path)
