r"""The impulse response between integer lags: the interpolation of a held input.

The input is held over each fast period, so the response at a real lag
``t`` to one held pulse is the continuous-time impulse response ``h``
integrated over the hold,

.. math:: g(t) = \int_{t - 1}^{t} h(r) \, dr,

smooth between the ticks (``C^1`` for a continuous ``h``) and band-limited by
the hold.  The lag kernels TC, DC and SS are priors on the discrete pulse
response ``g(0), g(1), ...`` (the paper's eq. 16-17); between integer lags
their values are those of that sequence interpolated by a smooth stencil,

.. math::

    g(n + d) = \sum_s w_s(d) \, g(n + s), \qquad
    k(n + d, m + e) = w(n + d)^T K \, w(m + e),

with ``w_s`` the Lagrange weights of the :data:`HOLD_POINTS` nodes
``s = -5 .. 6`` around ``n`` (:func:`stencil`), zeros below lag 0 (the
response is causal) and, for an observation of order ``P``, the nodes cut at
``P - 1`` (the order cuts the response; across the cut the zeros would make
the interpolation ring).  At integer lags ``w`` is a unit vector: the kernels'
values there are their formulas, unchanged.  The construction is a Gaussian
process over real lags (a linear map of the integer-lag one), and a reading
between the ticks is a row on the integer lags: every route of the integer-lag
observations applies to it.

What the interpolation from integer lags cannot see (content of ``h`` near and
above the fast Nyquist frequency, aliased at the integer lags, and the kinks
of ``g`` at lags 0 and 1 where ``h`` starts) is the bridge: independent on
each cell ``[n, n + 1)``, of the shape ``s(d) = sin(pi d)`` (zero on the
ticks),

.. math::

    g(n + d) = \sum_s w_s(d)\, g(n + s) + s(d)\, b_n, \qquad
    b_n \sim N(0, \kappa^2 k(n, n)),

    k(n + d, m + e) = w(n + d)^T K\, w(m + e) + [n = m]\, \kappa^2 s(d) s(e) k(n, n),

with ``kappa =`` :data:`BRIDGE_SCALE`.  The twelve-node interpolation of the
held pulse response of a continuous-time mode, away from lag 0, errs by 3 %
of its rms at 3 fast samples per period, 1 % at 5 and 0.1 % at 20; with the
start included by 4.4 % at 3; a first-order response, whose kinks at lags
0 and 1 no polynomial follows, by 2-8 % (time constants of 12 and 1.5 fast
periods; ``tests/test_hold.py``).  ``kappa = 0.1`` covers these, and modes
nearer the fast Nyquist frequency in part (a resonance there is PK's, exact at real lags): on the
calibration benchmark 0.05 left the band between the ticks of fits on the
ticks too narrow for the two-mass systems (modes at 2-5 fast samples per
period), 0.1 did not, and neither changed the tuned noise of fits between
the ticks.  A reading
sees the bridge through its regressor rows weighted by ``s(d)``
(:class:`HoldTerm`): an observation on the integer lags too, with no
quadrature over pairs of readings.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

from gpmultirate.kernels.structure import ObservedTerm, outer_square

__all__ = ["BRIDGE_SCALE", "HOLD_POINTS", "HoldTerm", "bridge_shape", "bridge_variances",
           "hold_covariance", "hold_diagonal", "hold_weights", "lagrange_weights",
           "mode_start", "stencil"]

#: the integer lags each value between them is interpolated from (a polynomial of degree 11)
HOLD_POINTS = 12
#: ``kappa``: the bridge's standard deviation at mid-cell, relative to the prior's at its lag
#: (twice the interpolation error of a held mode at 3 fast samples per period)
BRIDGE_SCALE = 0.1


def stencil(points: int) -> np.ndarray:
    """The ``points`` interpolation nodes, relative to the tick before the instant.

    Examples
    --------
    >>> stencil(4)
    array([-1,  0,  1,  2])
    >>> stencil(2)
    array([0, 1])
    """
    if isinstance(points, bool) or not isinstance(points, (int, np.integer)) or (
            points < 2 or points % 2):
        raise ValueError(f"points must be an even integer of at least 2; got {points!r}")
    return np.arange(1 - points // 2, points // 2 + 1)


#: points whose Lagrange weights are formed at a time
_WEIGHT_CHUNK = 2**16


def lagrange_weights(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The Lagrange weights of integer ``nodes`` at the points ``x``: ``(len(x), len(nodes))``.

    Examples
    --------
    >>> w = lagrange_weights(np.array([-1, 0, 1, 2]), np.array([0.5]))
    >>> w * 16
    array([[-1.,  9.,  9., -1.]])
    """
    nodes = np.asarray(nodes, dtype=float)
    x = np.asarray(x, dtype=float)
    gaps = nodes[:, None] - nodes[None, :]
    np.fill_diagonal(gaps, 1.0)
    denominators = np.prod(gaps, axis=1)
    out = np.empty((x.shape[0], nodes.shape[0]))
    # w_j(x) = prod_(i != j) (x - s_i) / (s_j - s_i): the products of the differences
    # before and after j, O(S) passes over x where the pairs took O(S^2); a few points at
    # a time, so that the temporaries stay small beside the result
    for start in range(0, x.shape[0], _WEIGHT_CHUNK):
        differences = x[start:start + _WEIGHT_CHUNK, None] - nodes[None, :]
        block = out[start:start + _WEIGHT_CHUNK]
        block[:, 0] = 1.0
        np.cumprod(differences[:, :-1], axis=1, out=block[:, 1:])
        block[:, :-1] *= np.cumprod(differences[:, :0:-1], axis=1)[:, ::-1]
        block /= denominators
    return out


def hold_weights(lags, order: int | None = None, points: int = HOLD_POINTS):
    """The interpolation weights ``w(t)`` of real ``lags`` on the integer lags.

    Parameters
    ----------
    lags : array-like of shape (n,)
        Non-negative real lags (below ``order`` when it is given).
    order : int, optional
        ``P``: the nodes are cut at ``P - 1``.  Without it, the nodes beyond
        reach the integer lags there (the prior of a response not cut).
    points : int, default=HOLD_POINTS

    Returns
    -------
    W : scipy.sparse.csr_matrix of shape (n, L)
        Row ``i``: ``g(lags[i]) = W[i] @ g(0..L-1)``; a unit row at an
        integer lag.
    L : int
        The number of integer lags the rows reach.

    Examples
    --------
    >>> W, L = hold_weights([2.0, 2.5], points=4)
    >>> L, (W.toarray() * 16).round(6).tolist()
    (5, [[0.0, 0.0, 16.0, 0.0, 0.0], [0.0, -1.0, 9.0, 9.0, -1.0]])
    >>> hold_weights([0.5, 3.5], order=4, points=4)[0].toarray().round(4)
    array([[ 0.5625,  0.5625, -0.0625,  0.    ],
           [ 0.    ,  0.    , -0.5   ,  1.5   ]])
    """
    t = np.asarray(lags, dtype=float).reshape(-1)
    nodes = stencil(points)
    whole = np.floor(t).astype(np.int64)
    offset = t - whole
    if order is not None and t.size and whole.max() > order - 1:
        raise ValueError(f"lags must lie below order = {order}; got {t.max():g}")
    columns = whole[:, None] + nodes[None, :]
    values = np.zeros(columns.shape)
    cut = np.zeros(t.shape[0], dtype=np.int64) if order is None else np.maximum(
        columns[:, -1] - (order - 1), 0)
    for c in np.unique(cut):
        mine = cut == c
        values[mine, :points - c] = lagrange_weights(nodes[:points - c], offset[mine])
    values[columns < 0] = 0.0  # the response is zero before lag 0
    on_tick = offset == 0.0
    values[on_tick] = (nodes == 0)[None, :]  # exactly the integer lag's value
    size = int(columns.max()) + 1 if t.size else 0
    if order is not None:
        size = order
    keep = (values != 0.0) & (columns >= 0)
    rows = np.broadcast_to(np.arange(t.shape[0])[:, None], columns.shape)
    W = sparse.csr_matrix((values[keep], (rows[keep], columns[keep])), shape=(t.shape[0], size))
    return W, size


def _times(a, b):
    """``a b`` for complex numbers held as ``(real part, imaginary part)`` pairs."""
    return a[0] * b[0] - a[1] * b[1], a[0] * b[1] + a[1] * b[0]


def _over(a, b):
    """``a / b`` for ``(real part, imaginary part)`` pairs."""
    size = b[0] * b[0] + b[1] * b[1]
    return (a[0] * b[0] + a[1] * b[1]) / size, (a[1] * b[0] - a[0] * b[1]) / size


def _exp(a):
    """``e^a`` for a ``(real part, imaginary part)`` pair."""
    scale = np.exp(a[0])
    return scale * np.cos(a[1]), scale * np.sin(a[1])


def mode_start(offsets, rate, omega, derivatives: int = 0) -> list:
    r"""What the hold takes off a mode's response on its first cell, ``[0, 1)``.

    A continuous-time mode ``h(r) = e^(lambda r)``, ``lambda = -rate + i omega``,
    behind a hold has the pulse response ``g(t) = int_(max(t - 1, 0))^t h``:
    ``e^(lambda t) (1 - e^(-lambda)) / lambda`` from lag 1 on, PK's basis up to
    a constant factor, and on the first cell the mode's step response,

    .. math::

        b(d) = \frac{e^{\lambda d} - 1}{1 - e^{-\lambda}}, \qquad 0 \le d < 1,

    scaled to meet ``e^(lambda d)`` at ``d = 1``: zero at lag 0 (a reading on
    the tick where the input changes does not see the change yet), smooth
    across lag 1.  Returned is ``e^(lambda d) - b(d)`` and its derivatives in
    ``lambda`` up to ``derivatives``, as ``(real part, imaginary part)`` pairs
    (the cosine and sine bases' parts).  The parts are formed from real
    functions of ``rate`` and ``omega``, so complex values of these (the
    complex step of the derivatives) pass through.

    Parameters
    ----------
    offsets : ndarray
        Lags in ``[0, 1)``.
    rate, omega : float
        The decay rate and frequency per fast sample.
    derivatives : int, default=0
        The highest derivative in ``lambda`` (0, 1 or 2).

    Returns
    -------
    list of (ndarray, ndarray)
        ``derivatives + 1`` pairs, each of the shape of ``offsets``.

    Examples
    --------
    >>> import numpy as np
    >>> d = np.array([0.0, 0.5])
    >>> (cos, sin), = mode_start(d, 0.1, 2.0)
    >>> lam = -0.1 + 2.0j
    >>> held = (np.exp(lam * d) - 1) / (1 - np.exp(-lam))
    >>> bool(np.allclose(cos + 1j * sin, np.exp(lam * d) - held)), float(cos[0])
    (True, 1.0)
    """
    d = np.asarray(offsets)
    q = _exp((-rate * d, omega * d))                            # e^(lambda d)
    shift = _exp((rate + 0.0 * d, -omega + 0.0 * d))           # e^(-lambda)
    denominator = (1.0 - shift[0], -shift[1])                   # 1 - e^(-lambda)
    numerator = (q[0] - 1.0, q[1])                              # e^(lambda d) - 1
    held = _over(numerator, denominator)
    out = [(q[0] - held[0], q[1] - held[1])]
    if derivatives >= 1:
        # b' = (N' - b D') / D with N' = d q and D' = e^(-lambda)
        dq = (d * q[0], d * q[1])
        once = _times(held, shift)
        first = _over((dq[0] - once[0], dq[1] - once[1]), denominator)
        out.append((dq[0] - first[0], dq[1] - first[1]))
    if derivatives >= 2:
        # b'' = (N'' - 2 b' D' - b D'') / D with N'' = d^2 q and D'' = -e^(-lambda)
        twice = _times(first, shift)
        second = _over((d * dq[0] - 2.0 * twice[0] + once[0],
                        d * dq[1] - 2.0 * twice[1] + once[1]), denominator)
        out.append((d * dq[0] - second[0], d * dq[1] - second[1]))
    return out


def bridge_shape(offsets) -> np.ndarray:
    """``s(d) = sin(pi d)``: the shape of the bridge between two ticks, zero on them.

    Examples
    --------
    >>> bridge_shape(np.array([0.0, 0.5])).round(12)
    array([0., 1.])
    """
    return np.sin(np.pi * np.asarray(offsets, dtype=float))


def bridge_variances(kernel, order: int, eval_gradient: bool = False):
    """``v_n = BRIDGE_SCALE^2 k(n, n)``, ``n = 0..order-1`` (and ``{name: dv}``)."""
    lags = np.arange(order, dtype=float)
    if not eval_gradient:
        return BRIDGE_SCALE**2 * kernel.integer_diagonal(lags)
    v, gradients = kernel.integer_diagonal(lags, eval_gradient=True)
    return BRIDGE_SCALE**2 * v, {name: BRIDGE_SCALE**2 * d for name, d in gradients.items()}


def _cells(lags):
    """The bridge's rows: ``s(d)`` at ``(i, cell)`` for the lags between ticks, and the cells."""
    whole = np.floor(lags)
    between = np.flatnonzero(lags != whole)
    cells, index = np.unique(whole[between], return_inverse=True)
    rows = sparse.csr_matrix(
        (bridge_shape(lags[between] - whole[between]), (between, index.reshape(-1))),
        shape=(lags.shape[0], cells.shape[0]))
    return rows, cells


def _add_bridge(out, kernel, t, s, gradients=None):
    """Add ``k_b(t, s)`` (and its derivatives) in place: ``s(d) s(e) v_n`` on a shared cell ``n``.

    Only the pairs of lags between ticks in the same cell are touched (sparse
    products), so lags on the ticks cost nothing.
    """
    Bt, cells_t = _cells(t)
    Bs, cells_s = (Bt, cells_t) if s is t else _cells(s)
    cells = np.intersect1d(cells_t, cells_s)
    if cells.size == 0:
        return
    Bt = Bt[:, np.searchsorted(cells_t, cells)]
    Bs = Bs[:, np.searchsorted(cells_s, cells)]
    if gradients is None:
        found = (kernel.integer_diagonal(cells), {})
    else:
        found = kernel.integer_diagonal(cells, eval_gradient=True)
    for target, v in [(out, found[0])] + [(gradients[name], d) for name, d in found[1].items()]:
        pairs = (Bt @ sparse.diags(BRIDGE_SCALE**2 * v) @ Bs.T).tocoo()
        target[pairs.row, pairs.col] += pairs.data


def _sandwich(Wt, K, Ws):
    out = np.asarray(Ws @ np.asarray(Wt @ K).T).T
    if Ws is Wt:  # symmetric to rounding, as the kernel on the lags themselves
        out = 0.5 * (out + out.T)
    return out


def hold_covariance(kernel, t, s, eval_gradient: bool = False):
    """``k(t, s) = w(t)^T K w(s) + k_b(t, s)`` from the kernel at integer lags (see the module).

    Parameters
    ----------
    kernel : ShiftScaledKernel
        Its formula at integer lags, ``integer_covariance(a, b,
        eval_gradient)`` (and ``{name: dK}``), and its diagonal there,
        ``integer_diagonal(a, eval_gradient)``.
    t, s : ndarray of shape (n,) and (m,)
        Real lags; ``s`` may be ``t`` itself.
    eval_gradient : bool, default=False

    Returns
    -------
    K : ndarray of shape (n, m)
    gradients : dict of ndarray, only with ``eval_gradient``

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.kernels import TC
    >>> hold_covariance(TC(0.8), np.array([1.0, 2.0]), np.array([1.0]))  # the formula
    array([[0.8 ],
           [0.64]])
    """
    integer_covariance = kernel.integer_covariance
    integer = (np.all(t == np.round(t)) and (s is t or np.all(s == np.round(s))))
    if integer:
        return integer_covariance(t, s, eval_gradient=eval_gradient)
    Wt, _ = hold_weights(t)
    Ws = Wt if s is t else hold_weights(s)[0]
    # only the integer lags the rows reach
    used_t = np.unique(Wt.indices)
    used_s = used_t if s is t else np.unique(Ws.indices)
    grid_t = used_t.astype(float)
    grid_s = grid_t if s is t else used_s.astype(float)
    Wt = Wt[:, used_t]
    Ws = Wt if s is t else Ws[:, used_s]
    if not eval_gradient:
        out = _sandwich(Wt, integer_covariance(grid_t, grid_s), Ws)
        _add_bridge(out, kernel, t, s)
        return out
    K, gradients = integer_covariance(grid_t, grid_s, eval_gradient=True)
    out = _sandwich(Wt, K, Ws)
    gradients = {name: _sandwich(Wt, dK, Ws) for name, dK in gradients.items()}
    _add_bridge(out, kernel, t, s, gradients)
    return out, gradients


def hold_diagonal(kernel, t) -> np.ndarray:
    """``k(t_i, t_i)`` for a shift-scaled kernel (``K(i + 1, j + 1) = a K(i, j)``).

    The nodes of a lag ``n + d`` with ``n`` at least the stencil's reach
    below are ``n + s``, all non-negative: its interpolated value is
    ``a^(n - r)`` times that of ``r + d`` (``r`` the reach), from one local
    block of the kernel; the bridge adds ``s(d)^2 v_n``.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.kernels import TC
    >>> t = np.array([0.5, 7.25, 30.0])
    >>> bool(np.allclose(hold_diagonal(TC(0.8), t), np.diag(hold_covariance(TC(0.8), t, t))))
    True
    """
    t = np.asarray(t, dtype=float)
    out = np.empty(t.shape[0])
    nodes = stencil(HOLD_POINTS)
    reach = -int(nodes[0])
    whole = np.floor(t)
    far = whole >= reach
    near = np.flatnonzero(~far)
    if near.size:
        out[near] = np.diag(hold_covariance(kernel, t[near], t[near]))
    if np.any(far):
        local = np.arange(reach + nodes[0], reach + nodes[-1] + 1, dtype=float)
        block = kernel.integer_covariance(local, local)
        w = lagrange_weights(nodes, t[far] - whole[far])
        with np.errstate(under="ignore"):
            scale = kernel.shift_scale()[0] ** (whole[far] - reach)
        bridge = BRIDGE_SCALE**2 * bridge_shape(t[far] - whole[far]) ** 2 * (
            kernel.integer_diagonal(whole[far]))
        out[far] = scale * np.einsum("ij,jk,ik->i", w, block, w) + bridge
    return out


class HoldTerm(ObservedTerm):
    """A shift-scaled kernel through readings at their own instants: rows plus the bridge.

    The readings are ``Phi_w g(0..P-1) + Psi b`` with ``Phi_w`` their rows on
    the integer lags by the interpolation (``inner``: the kernel's own term
    through them, with every route of the integer lags) and ``Psi`` the
    same rows with each point weighted by the bridge's shape ``s(d)``
    (``readings.bridge_rows()``); ``b`` independent across cells with
    variances ``v_n`` (:func:`bridge_variances`).  So
    ``S = Phi_w K Phi_w^T + Psi diag(v) Psi^T``: the bridge costs
    ``O(M^2 P)`` (a symmetric rank-k update; its gradient one product
    ``W Psi``, the derivative matrices never formed) and the covariance is
    formed in the data space, the cheaper form while ``M`` is below the
    ``2 P`` coefficients of ``g`` and the bridge.

    Parameters
    ----------
    kernel : ShiftScaledKernel
    inner : ObservedTerm
        The kernel through the readings' rows on the integer lags.
    readings : TimedConvolution
    path : str
    """

    def __init__(self, kernel, inner, readings, path: str = ""):
        super().__init__(kernel, readings, path)
        self.inner, self.readings = inner, readings

    def _free(self):
        return [h.name for h in self.kernel.hyperparameters if not h.fixed]

    def _bridge_derivatives(self):
        """``Psi diag(dv_j) Psi^T`` per free hyperparameter; None where ``dv_j`` is zero.

        Each by symmetric rank-k updates of the columns where ``dv_j`` is
        positive and where it is negative.
        """
        Psi = self.readings.bridge_rows()
        _, dv = bridge_variances(self.kernel, self.readings.order, eval_gradient=True)
        out = []
        for name in self._free():
            d = dv[name]
            if not np.any(d):
                out.append(None)
                continue
            up, down = np.flatnonzero(d > 0), np.flatnonzero(d < 0)
            matrix = outer_square(Psi[:, up] * np.sqrt(d[up]))
            if down.size:
                matrix -= outer_square(Psi[:, down] * np.sqrt(-d[down]))
            out.append(matrix)
        return out

    def _with_bridge(self, S):
        """``S + Psi diag(v) Psi^T`` by a symmetric rank-k update of ``Psi sqrt(v)``."""
        Psi = self.readings.bridge_rows()
        v = bridge_variances(self.kernel, self.readings.order)
        return outer_square(Psi * np.sqrt(v), out=S)

    # the parameter space and the roles are the inner term's: the bridge is zero at integer lags
    def kernel_matrix(self):
        return self.inner.kernel_matrix()

    def kernel_with_gradient(self):
        return self.inner.kernel_with_gradient()

    def parameter_contractor(self):
        return self.inner.parameter_contractor()

    def regressor_times_kernel(self):
        return self.inner.regressor_times_kernel()

    def roles(self):
        return self.inner.roles()

    def scale_roles(self):
        return self.inner.scale_roles()

    def amplitude_couplings(self):
        return self.inner.amplitude_couplings()

    def low_rank(self):
        return None

    def precision(self):
        return None

    def covariance(self):
        if getattr(self, "_covariance", None) is None:
            self._covariance = self._with_bridge(self.inner.covariance())
        return self._covariance

    def covariance_blocks(self, split):
        # the bridge's blocks: Psi_r diag(v) Psi_d^T and the rows' sums of Psi_r^2 v
        cross, var = self.inner.covariance_blocks(split)
        Psi = self.readings.bridge_rows()
        v = bridge_variances(self.kernel, self.readings.order)
        weighted = Psi[split:] * v
        return cross + weighted @ Psi[:split].T, var + np.einsum("ij,ij->i", weighted, Psi[split:])

    def covariance_with_derivatives(self):
        S, items = self.inner.covariance_with_derivatives()
        dense = [item[0] @ item[1] @ item[0].T if isinstance(item, tuple) else item
                 for item in items]
        return self._with_bridge(S), [d if e is None else d + e
                                      for d, e in zip(dense, self._bridge_derivatives())]

    def covariance_with_contractor(self):
        # tr(W Psi diag(dv) Psi^T) = dv . diag(Psi^T W Psi): one product W Psi for every
        # derivative, none of the M x M derivative matrices formed
        S, contract = self.inner.covariance_with_contractor()
        Psi = self.readings.bridge_rows()
        _, dv = bridge_variances(self.kernel, self.readings.order, eval_gradient=True)
        derivatives = np.array([dv[name] for name in self._free()])

        def with_bridge(W):
            seen = np.einsum("mj,mj->j", Psi, W @ Psi)  # diag(Psi^T W Psi)
            return contract(W) + derivatives @ seen

        return self._with_bridge(S), with_bridge

    def cross_covariance(self, lags):
        # the bridge of g(n + d) meets the readings' bridge on the cell n
        out = self.inner.cross_covariance(lags)
        x = np.asarray(lags, dtype=float)[:, -1]
        whole = np.floor(x).astype(np.int64)
        inside = np.flatnonzero((whole < self.readings.order) & (x != whole))
        if inside.size:
            v = bridge_variances(self.kernel, self.readings.order)
            Psi = self.readings.bridge_rows()
            shape = bridge_shape(x[inside] - whole[inside])
            out[inside] += (shape * v[whole[inside]])[:, None] * Psi[:, whole[inside]].T
        return out
