"""Data covariance ``Phi K Phi^T`` and its gradient contraction, term by term.

The evidence and its gradient need ``S = Phi K Phi^T`` (``M x M``) and, for
a symmetric ``W``, the scalars ``tr(W Phi dK_j Phi^T)``.  Forming the
``P x P`` matrix ``K`` and ``A = Phi^T W Phi`` costs ``O(M P^2)`` per
evaluation; the structure of the kernels avoids it:

* DC: ``K = D T D`` with ``D = diag(alpha^(t/2))`` and the Toeplitz matrix
  ``T = beta^|i-j|``, whose product with a row vector is a pair of
  first-order recursive filters (causal and anticausal).  The derivative
  with respect to ``log beta`` is ``|i-j| beta^|i-j|``, a second-order
  filter.  Cost ``O(M P + M^2 P)`` instead of ``O(M P^2)``.
* PK: rank two, so ``S`` and every contraction come from four products
  ``Phi v``.
* ConstantKernel: rank one, or a scalar factor of a product.
* TC, DC and SS on long inputs: the diagonal recursion of
  :mod:`gpmultirate._recursive`, ``O(M N)``, where its cost model says so.
* anything else: the dense path of :mod:`gpmultirate._contraction`.

The operator's lags are always the integer grid ``0..P-1``.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import blas
from sklearn.gaussian_process.kernels import ConstantKernel, Product, Sum

from gpmultirate._contraction import _select, kernel_with_contractor, split_constant
from gpmultirate._recursive import (
    _two_sided,
    cross_covariance_shift_scaled,
    is_shift_scaled,
    observed_shift_scaled,
    observed_shift_scaled_derivatives,
    prefer_recursion,
)
from gpmultirate.kernels import DC, PK
from gpmultirate.operator import DownsampledConvolution


def observed_with_contractor(kernel, operator, need_gradient: bool = True):
    """Return ``S = Phi K Phi^T`` and ``contract(W) -> [tr(W Phi dK_j Phi^T)]_j``.

    ``W`` must be symmetric.  The entries follow ``kernel.theta``.  With
    ``need_gradient=False`` the contractor is None.
    """
    lags = operator.lags[:, 0]
    if isinstance(kernel, Sum):
        S1, c1 = observed_with_contractor(kernel.k1, operator, need_gradient)
        S2, c2 = observed_with_contractor(kernel.k2, operator, need_gradient)
        contract = (lambda W: np.concatenate([c1(W), c2(W)])) if need_gradient else None
        return S1 + S2, contract
    if isinstance(kernel, Product) and split_constant(kernel) is not None:
        return _constant_product(kernel, operator, need_gradient)
    if _use_recursion(kernel, operator, need_gradient):
        return observed_shift_scaled(kernel, operator, need_gradient)
    Phi = operator.matrix
    if isinstance(kernel, ConstantKernel):
        ones = Phi.sum(axis=1)
        value = float(kernel.constant_value)
        S = value * np.outer(ones, ones)
        if kernel.hyperparameter_constant_value.fixed:
            return S, (lambda W: np.empty(0))
        return S, (lambda W: np.array([value * ones @ W @ ones]))
    if type(kernel) is DC:
        return _dc(kernel, Phi, lags, need_gradient, getattr(operator, "upper_triangular", False))
    if type(kernel) is PK:
        return _pk(kernel, Phi, lags)
    return _dense(kernel, Phi, lags, need_gradient)


def _use_recursion(kernel, operator, need_gradient: bool) -> bool:
    """Whether ``S`` of a TC, DC or SS leaf comes from the diagonal recursion.

    Only a real downsampled convolution has the shift structure (a reduced
    observation does not), and the recursion is taken where its cost model
    says it is faster than the filter-and-BLAS route.
    """
    return (
        is_shift_scaled(kernel)
        and isinstance(operator, DownsampledConvolution)
        and prefer_recursion(
            operator.n_outputs, operator.n_samples, operator.order, need_gradient=need_gradient
        )
    )


def _constant_product(kernel, operator, need_gradient):
    constant, other, first = split_constant(kernel)
    value = float(constant.constant_value)
    S_other, c_other = observed_with_contractor(other, operator, need_gradient)
    S = value * S_other
    if not need_gradient:
        return S, None
    free = not constant.hyperparameter_constant_value.fixed

    def contract(W):
        own = np.array([np.sum(W * S)]) if free else np.empty(0)
        rest = c_other(value * W)
        return np.concatenate([own, rest] if first else [rest, own])

    return S, contract


def _dense(kernel, Phi, lags, need_gradient):
    if not need_gradient:
        K = kernel(lags[:, None])
        return _sym(Phi @ K @ Phi.T), None
    K, contract_p = kernel_with_contractor(kernel, lags)
    S = _sym(Phi @ K @ Phi.T)

    def contract(W):
        A = Phi.T @ W @ Phi
        return contract_p(_sym(A))

    return S, contract


def _dc_filtered(kernel: DC, Phi, lags):
    """``beta``, the envelope ``d = alpha^(t/2)``, ``G = Phi D`` and ``H = G T``.

    ``K = D T D`` with ``T[i, j] = beta^|i - j|``; a product with ``T`` is a
    causal plus an anticausal AR(1) filter, the centre counted once.
    """
    values = kernel._check_hyperparameters()
    beta = values["beta"]
    decay = values["alpha"] ** (lags / 2.0)
    G = Phi * decay
    return beta, decay, G, _two_sided(G, [1.0], [1.0, -beta], include_center=True)


def _dc_distance_filtered(G, beta):
    """``G T'`` with ``T'[i, j] = |i - j| beta^|i - j|`` (derivative in ``log beta``)."""
    return _two_sided(G, [0.0, beta], [1.0, -2.0 * beta, beta**2], include_center=False)


def _dc(kernel: DC, Phi, lags, need_gradient, upper_triangular=False):
    beta, _, G, H = _dc_filtered(kernel, Phi, lags)
    if upper_triangular:  # a reduced observation: products with G cost half
        # G^T is a Fortran-ordered lower-triangular view of G: no copies.
        # S^T = G H^T = op(G^T) H^T with op = transpose
        S = _sym(blas.dtrmm(1.0, G.T, H.T, side=0, lower=1, trans_a=1))
    else:
        S = _sym(H @ G.T)
    if not need_gradient:
        return S, None

    def contract(W):
        if upper_triangular:
            # W is symmetric, so its transpose is a Fortran-ordered view of W
            WG = blas.dtrmm(1.0, G.T, W.T, side=1, lower=1, trans_a=1)
        else:
            WG = W @ G
        # d/dlog(alpha): K * (t_i + t_j)/2, i.e. E K + K E with E = diag(t/2), so
        # tr(W Phi dK Phi^T) = 2 tr(H^T W G E) = sum over m, i of t_i H[m, i] (W G)[m, i]
        d_alpha = np.einsum("mi,mi,i->", H, WG, lags)
        # d/dlog(beta): K * |i - j| -> filter with taps k beta^k (zero at k = 0)
        d_beta = np.einsum("mi,mi->", _dc_distance_filtered(G, beta), WG)
        return _select(kernel, ["alpha", "beta"], [d_alpha, d_beta])

    return S, contract


def _pk_parts(kernel: PK, lags):
    """``omega``, the two variances and the cosine and sine parts at ``lags``."""
    values = kernel._check_hyperparameters()
    c, s = kernel._parts(lags, values["alpha"], values["omega"])
    return values["omega"], values["sigma1"] ** 2, values["sigma2"] ** 2, c, s


def _pk(kernel: PK, Phi, lags):
    omega, var1, var2, c, s = _pk_parts(kernel, lags)
    pc, ps = Phi @ c, Phi @ s
    S = var1 * np.outer(pc, pc) + var2 * np.outer(ps, ps)

    def contract(W):
        ptc, pts = Phi @ (lags * c), Phi @ (lags * s)
        Wc, Ws = W @ pc, W @ ps
        return _select(
            kernel,
            ["alpha", "omega", "sigma1", "sigma2"],
            [
                var1 * (ptc @ Wc) + var2 * (pts @ Ws),
                2.0 * omega * (-var1 * (pts @ Wc) + var2 * (ptc @ Ws)),
                2.0 * var1 * (pc @ Wc),
                2.0 * var2 * (ps @ Ws),
            ],
        )

    return S, contract


def _sym(A):
    return 0.5 * (A + A.T)


# ---------------------------------------------------------------------------
# Derivative matrices, for the Fisher information of the evidence.
#
# ``observed_with_derivatives`` returns ``S`` and one item per free
# hyperparameter (``kernel.theta`` order) describing ``dS_j = Phi dK_j Phi^T``
# either as a dense symmetric ``(M, M)`` array or, for low-rank terms, as a
# factor pair ``(U, D)`` with ``dS_j = U D U^T`` (``U`` of shape ``(M, r)``).


def observed_with_derivatives(kernel, operator):
    """Return ``S = Phi K Phi^T`` and the list of derivative items ``dS_j``."""
    return _derivatives(kernel, operator)


def _derivatives(kernel, operator):
    lags = operator.lags[:, 0]
    if isinstance(kernel, Sum):
        S1, d1 = _derivatives(kernel.k1, operator)
        S2, d2 = _derivatives(kernel.k2, operator)
        return S1 + S2, d1 + d2
    if isinstance(kernel, Product) and split_constant(kernel) is not None:
        constant, other, first = split_constant(kernel)
        value = float(constant.constant_value)
        S_other, d_other = _derivatives(other, operator)
        S = value * S_other
        rest = [_scaled(item, value) for item in d_other]
        own = [] if constant.hyperparameter_constant_value.fixed else [S]
        return S, (own + rest if first else rest + own)
    if _use_recursion(kernel, operator, True):
        return observed_shift_scaled_derivatives(kernel, operator)
    Phi = operator.matrix
    if isinstance(kernel, ConstantKernel):
        ones = Phi.sum(axis=1)[:, None]
        value = float(kernel.constant_value)
        S = value * (ones @ ones.T)
        if kernel.hyperparameter_constant_value.fixed:
            return S, []
        return S, [(ones, np.array([[value]]))]
    if type(kernel) is DC:
        return _dc_derivatives(kernel, Phi, lags)
    if type(kernel) is PK:
        return _pk_derivatives(kernel, Phi, lags)
    K, dK = kernel(lags[:, None], eval_gradient=True)
    S = _sym(Phi @ K @ Phi.T)
    return S, [_sym(Phi @ dK[:, :, j] @ Phi.T) for j in range(dK.shape[2])]


def _scaled(item, value):
    if isinstance(item, tuple):
        return item[0], value * item[1]
    return value * item


def _dc_derivatives(kernel: DC, Phi, lags):
    beta, _, G, H = _dc_filtered(kernel, Phi, lags)
    S = _sym(H @ G.T)
    items = []
    if not kernel.hyperparameter_alpha.fixed:
        # E K + K E with E = diag(t / 2): Phi (E K + K E) Phi^T = (G E) H^T + H (G E)^T
        half = (G * (lags / 2.0)) @ H.T
        items.append(half + half.T)
    if not kernel.hyperparameter_beta.fixed:
        items.append(_sym(_dc_distance_filtered(G, beta) @ G.T))
    return S, items


def _pk_derivatives(kernel: PK, Phi, lags):
    omega, var1, var2, c, s = _pk_parts(kernel, lags)
    # basis [Phi c, Phi s, Phi (t c), Phi (t s)]
    U = Phi @ np.column_stack([c, s, lags * c, lags * s])
    S = var1 * np.outer(U[:, 0], U[:, 0]) + var2 * np.outer(U[:, 1], U[:, 1])

    def pair(i, j, weight):
        D = np.zeros((4, 4))
        D[i, j] += weight
        D[j, i] += weight
        return D

    # d/dlog(alpha): c -> (t / 2) c, s -> (t / 2) s
    d_alpha = pair(0, 2, 0.5 * var1) + pair(1, 3, 0.5 * var2)
    # d/dlog(omega): c -> -omega t s, s -> omega t c
    d_omega = pair(0, 3, -omega * var1) + pair(1, 2, omega * var2)
    d_sigma1 = np.zeros((4, 4))
    d_sigma1[0, 0] = 2.0 * var1
    d_sigma2 = np.zeros((4, 4))
    d_sigma2[1, 1] = 2.0 * var2
    candidates = {"alpha": d_alpha, "omega": d_omega, "sigma1": d_sigma1, "sigma2": d_sigma2}
    fixed = {h.name: h.fixed for h in kernel.hyperparameters}
    items = [(U, D) for name, D in candidates.items() if not fixed[name]]
    return S, items


def observed_without(kernel, term, operator):
    """``Phi K Phi^T`` of ``kernel`` with the summand ``term`` left out.

    Returns None when ``term`` is not reached through sums alone.
    """
    if kernel is term:
        return np.zeros((operator.n_outputs, operator.n_outputs))
    if isinstance(kernel, Sum):
        for inside, other in ((kernel.k1, kernel.k2), (kernel.k2, kernel.k1)):
            rest = observed_without(inside, term, operator)
            if rest is not None:
                return rest + observed_with_contractor(other, operator, False)[0]
    return None


def regressor_times_kernel(kernel, operator, K=None):
    """``Phi K`` of shape ``(M, P)`` without the ``O(M P^2)`` product where possible.

    DC terms are filters of the rows of ``Phi`` (``Phi D T D``), PK terms
    rank two, constants rank one; other kernels use ``K`` (computed when not
    given).
    """
    lags = operator.lags[:, 0]
    if isinstance(kernel, Sum):
        return regressor_times_kernel(kernel.k1, operator) + regressor_times_kernel(
            kernel.k2, operator
        )
    if isinstance(kernel, Product) and split_constant(kernel) is not None:
        constant, other, _ = split_constant(kernel)
        return float(constant.constant_value) * regressor_times_kernel(other, operator)
    if is_shift_scaled(kernel) and isinstance(operator, DownsampledConvolution):
        return cross_covariance_shift_scaled(kernel, operator)
    Phi = operator.matrix
    if isinstance(kernel, ConstantKernel):
        ones = Phi.sum(axis=1)
        return float(kernel.constant_value) * np.repeat(ones[:, None], lags.shape[0], axis=1)
    if type(kernel) is DC:
        _, decay, _, H = _dc_filtered(kernel, Phi, lags)
        return H * decay
    if type(kernel) is PK:
        _, var1, var2, c, s = _pk_parts(kernel, lags)
        return var1 * np.outer(Phi @ c, c) + var2 * np.outer(Phi @ s, s)
    if K is None:
        K = kernel(lags[:, None])
    return Phi @ K
