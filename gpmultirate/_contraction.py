"""Kernel matrices with their gradient contracted against a symmetric matrix.

The gradient of the log evidence needs, for every free hyperparameter
``theta_j``, only the scalar ``sum(A * dK/dtheta_j)`` for one symmetric
``P x P`` matrix ``A`` (see :mod:`gpmultirate._inference`).  Forming the
``(P, P, n_theta)`` gradient array of scikit-learn's kernels and contracting
it is memory bound; here the contraction is pushed through the kernel
algebra instead:

* ``Sum``: the contractions of both terms, concatenated;
* ``Product``: ``d(K1 * K2) = dK1 * K2 + K1 * dK2``, so term 1 is contracted
  against ``A * K2`` and term 2 against ``A * K1``;
* ``ConstantKernel`` and the lag kernels: closed forms (a PK term has rank
  two, so its contractions are a few matrix-vector products);
* any other kernel: its dense gradient, contracted with one matrix product.

:func:`kernel_with_contractor` returns ``K`` and a function ``A -> gradient``.
"""

from __future__ import annotations

import numpy as np
from sklearn.gaussian_process.kernels import ConstantKernel, Product, Sum

from gpmultirate.kernels import DC, PK, SS, TC


def kernel_with_contractor(kernel, lags: np.ndarray):
    """Return ``K = kernel(lags)`` and ``contract(A) -> [sum(A * dK_j)]_j``.

    ``lags`` is a float vector; ``A`` passed to the contractor must be
    symmetric.  The order of the entries follows ``kernel.theta``.
    """
    if isinstance(kernel, Sum):
        K1, c1 = kernel_with_contractor(kernel.k1, lags)
        K2, c2 = kernel_with_contractor(kernel.k2, lags)
        return K1 + K2, lambda A: np.concatenate([c1(A), c2(A)])
    if isinstance(kernel, Product):
        scaled = _constant_times(kernel, lags)
        if scaled is not None:
            return scaled
        K1, c1 = kernel_with_contractor(kernel.k1, lags)
        K2, c2 = kernel_with_contractor(kernel.k2, lags)
        return K1 * K2, lambda A: np.concatenate([c1(A * K2), c2(A * K1)])
    if isinstance(kernel, ConstantKernel):
        value = float(kernel.constant_value)
        K = np.full((lags.shape[0], lags.shape[0]), value)
        if kernel.hyperparameter_constant_value.fixed:
            return K, _nothing
        return K, lambda A: np.array([value * A.sum()])
    for kind, builder in _LAG_BUILDERS.items():
        if type(kernel) is kind:
            return builder(kernel, lags)
    K, dK = kernel(lags[:, None], eval_gradient=True)
    n = dK.shape[2]
    if n == 0:
        return K, _nothing
    return K, lambda A: A.reshape(-1) @ dK.reshape(-1, n)


def kernel_matrix(kernel, lags: np.ndarray) -> np.ndarray:
    """``kernel(lags)`` with constant factors kept scalars (no ``P x P`` array of constants)."""
    if isinstance(kernel, Sum):
        return kernel_matrix(kernel.k1, lags) + kernel_matrix(kernel.k2, lags)
    if isinstance(kernel, Product):
        split = split_constant(kernel)
        if split is not None:
            return float(split[0].constant_value) * kernel_matrix(split[1], lags)
    return kernel(lags[:, None])


def split_constant(kernel: Product):
    """``(constant, other, constant_first)`` of ``ConstantKernel * k`` or ``k * ConstantKernel``, else None."""
    if isinstance(kernel.k1, ConstantKernel):
        return kernel.k1, kernel.k2, True
    if isinstance(kernel.k2, ConstantKernel):
        return kernel.k2, kernel.k1, False
    return None


def _constant_times(kernel: Product, lags):
    """``ConstantKernel * k`` (either order) with the constant kept a scalar."""
    split = split_constant(kernel)
    if split is None:
        return None
    constant, other, constant_first = split
    value = float(constant.constant_value)
    K_other, c_other = kernel_with_contractor(other, lags)
    K = value * K_other
    free = not constant.hyperparameter_constant_value.fixed

    def contract(A):
        own = np.array([np.sum(A * K)]) if free else np.empty(0)
        rest = c_other(value * A)
        return np.concatenate([own, rest] if constant_first else [rest, own])

    return K, contract


def _nothing(A):
    return np.empty(0)


def _select(kernel, names, values):
    """Keep the entries of the free hyperparameters, in ``theta`` order."""
    fixed = {h.name: h.fixed for h in kernel.hyperparameters}
    return np.array([v for name, v in zip(names, values) if not fixed[name]])


def _row_weighted(A, K, lags):
    # sum_ij A_ij K_ij (t_i + t_j) / 2 = t^T (A * K) 1 for symmetric A and K
    return lags @ (A * K).sum(axis=1)


def _tc(kernel: TC, lags):
    K = kernel(lags[:, None])
    longest = np.maximum.outer(lags, lags)

    def contract(A):
        return _select(kernel, ["alpha"], [np.sum(A * K * longest)])

    return K, contract


def _dc(kernel: DC, lags):
    K = kernel(lags[:, None])
    distance = np.abs(np.subtract.outer(lags, lags))

    def contract(A):
        AK = A * K
        return _select(
            kernel,
            ["alpha", "beta"],
            [lags @ AK.sum(axis=1), np.sum(AK * distance)],
        )

    return K, contract


def _ss(kernel: SS, lags):
    K, dK = kernel(lags[:, None], eval_gradient=True)
    if dK.shape[2] == 0:
        return K, _nothing
    gradient = dK[:, :, 0]
    return K, lambda A: np.array([np.sum(A * gradient)])


def _pk(kernel: PK, lags):
    values = kernel._check_hyperparameters()
    alpha, omega = values["alpha"], values["omega"]
    var1, var2 = values["sigma1"] ** 2, values["sigma2"] ** 2
    c, s = kernel._parts(lags, alpha, omega)
    K = var1 * np.outer(c, c) + var2 * np.outer(s, s)

    def contract(A):
        Ac, As = A @ c, A @ s
        tc, ts = lags * c, lags * s
        quad_c, quad_s = c @ Ac, s @ As
        return _select(
            kernel,
            ["alpha", "omega", "sigma1", "sigma2"],
            [
                var1 * (tc @ Ac) + var2 * (ts @ As),
                2.0 * omega * (-var1 * (ts @ Ac) + var2 * (tc @ As)),
                2.0 * var1 * quad_c,
                2.0 * var2 * quad_s,
            ],
        )

    return K, contract


_LAG_BUILDERS = {TC: _tc, DC: _dc, SS: _ss, PK: _pk}
