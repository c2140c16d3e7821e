"""Diagonal recursion for TC, DC and SS against dense linear algebra.

``observed_shift_scaled`` must reproduce ``S = Phi K Phi^T`` with ``Phi``
from an explicit loop and ``K = kernel(lags)``, and its contractor must
reproduce ``sum((Phi^T W Phi) * dK_j)`` with ``dK`` from scikit-learn's
``kernel(lags, eval_gradient=True)`` and central finite differences of
``tr(W Phi K(theta) Phi^T)``.  ``cross_covariance_shift_scaled`` and
``kernel_matvec`` are checked against ``Phi @ K`` and ``K @ v``.
"""

import sys

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import RBF
from sklearn.gaussian_process.kernels import ConstantKernel as C

from gpmultirate import DownsampledConvolution
from gpmultirate.kernels import DC, PK, SS, TC, observe
from gpmultirate.kernels.recursion import ShiftScaledTerm, observed_recursion, prefer_recursion


def is_shift_scaled(kernel):
    """Whether the kernel's own term offers the diagonal recursion."""
    return isinstance(observe(kernel, DownsampledConvolution(np.ones(4), 1, 2)), ShiftScaledTerm)


def _check(kernel):
    if not is_shift_scaled(kernel):
        raise TypeError(f"expected a TC, DC or SS kernel; got {type(kernel).__name__}")


def observed_shift_scaled(kernel, op, need_gradient=True):
    """``S`` by the recursion and the contraction of its derivatives."""
    _check(kernel)
    S, derivatives = observed_recursion(kernel, op.uniform_sampling, op.order, need_gradient)
    if not need_gradient:
        return S, None
    term = ShiftScaledTerm(kernel, op, "", None)
    term._sampling = lambda need_gradient: op.uniform_sampling  # always the recursion
    return term.covariance_with_contractor()


def cross_covariance_shift_scaled(kernel, op):
    """``Phi K`` from the kernel's own product with the strided regressor."""
    _check(kernel)
    return kernel.right_multiply(op.regressor_view())


def kernel_matvec(kernel, order, v):
    """``K v`` from the kernel's own product (row vector times ``K``, ``K`` symmetric)."""
    v = np.asarray(v, dtype=float)
    if v.ndim == 1:
        return kernel.right_multiply(v[None, :])[0]
    return kernel.right_multiply(np.ascontiguousarray(v.T)).T

# (N, factor, order, offset): P < N and P = N, offsets > 0, factors 1..5
OPERATORS = {
    "N40-F1-P40-o0": (40, 1, 40, 0),
    "N61-F3-P20-o2": (61, 3, 20, 2),
    "N57-F5-P57-o4": (57, 5, 57, 4),
    "N50-F2-P17-o1": (50, 2, 17, 1),
    "N45-F3-P44-o0": (45, 3, 44, 0),
    "N64-F4-P30-o3": (64, 4, 30, 3),
    "N30-F4-P1-o3": (30, 4, 1, 3),
    "N9-F5-P2-o4": (9, 5, 2, 4),
}

KERNELS = {
    "TC": TC(alpha=0.85),
    "TC-alpha-near-1": TC(alpha=1.0 - 1e-6),
    "TC-alpha-1": TC(alpha=1.0),
    "TC-alpha-0.3": TC(alpha=0.3),
    "DC": DC(alpha=0.85, beta=0.7),
    "DC-alpha-near-1": DC(alpha=1.0 - 1e-6, beta=0.5),
    "DC-beta-near-1": DC(alpha=0.9, beta=1.0 - 1e-6),
    "DC-small-alpha": DC(alpha=0.3, beta=0.95),
    "DC-beta-fixed": DC(alpha=0.8, beta=0.6, beta_bounds="fixed"),
    "DC-alpha-fixed": DC(alpha=0.8, beta=0.6, alpha_bounds="fixed"),
    "SS": SS(alpha=0.9),
    "SS-alpha-near-1": SS(alpha=1.0 - 1e-6),
    "SS-alpha-0.3": SS(alpha=0.3),
    "SS-fixed": SS(alpha=0.7, alpha_bounds="fixed"),
    "SS-alpha-1e-4": SS(alpha=1e-4),
    "DC-both-extreme": DC(alpha=1e-4, beta=0.9999),
}

# kernels that stay valid at theta +- a finite-difference step
FD_KERNELS = ["TC", "TC-alpha-0.3", "DC", "DC-small-alpha", "DC-beta-fixed", "SS", "SS-alpha-0.3"]


def explicit_regressor(u, factor, order, offset):
    rows = list(range(offset, len(u), factor))
    return np.array(
        [[u[n - i] if n - i >= 0 else 0.0 for i in range(order)] for n in rows]
    ).reshape(len(rows), order)


def make_operator(key, seed=0, mean=0.3):
    n, factor, order, offset = OPERATORS[key]
    u = np.random.default_rng(seed + n).standard_normal(n) + mean
    return DownsampledConvolution(u, factor, order, offset), explicit_regressor(u, factor, order, offset)


def random_symmetric(size, seed):
    A = np.random.default_rng(seed).standard_normal((size, size))
    return A + A.T


def dense_lags(order):
    return np.arange(order, dtype=float)[:, None]


kernel_params = [pytest.param(k, id=name) for name, k in KERNELS.items()]
fd_kernel_params = [pytest.param(KERNELS[name], id=name) for name in FD_KERNELS]


# ----------------------------------------------------------------------------
# S = Phi K Phi^T and tr(W Phi dK_j Phi^T)
# ----------------------------------------------------------------------------


@pytest.mark.parametrize("op_key", list(OPERATORS))
@pytest.mark.parametrize("kernel", kernel_params)
def test_covariance_and_contraction_equal_dense(kernel, op_key):
    op, Phi = make_operator(op_key)
    K, dK = kernel(dense_lags(op.order), eval_gradient=True)
    S_dense = Phi @ K @ Phi.T
    S, contract = observed_shift_scaled(kernel, op)
    assert S.shape == (op.n_outputs, op.n_outputs)
    np.testing.assert_array_equal(S, S.T)
    scale = np.abs(S_dense).max()
    assert np.abs(S - S_dense).max() <= 1e-11 * scale
    np.testing.assert_allclose(S, S_dense, rtol=1e-9, atol=1e-13 * scale)
    S_only, none = observed_shift_scaled(kernel, op, need_gradient=False)
    assert none is None
    np.testing.assert_array_equal(S_only, S)
    for seed in (1, 2):
        W = random_symmetric(op.n_outputs, seed)
        A = Phi.T @ W @ Phi
        expected = np.einsum("ij,ijk->k", A, dK)
        magnitude = np.einsum("ij,ijk->k", np.abs(A), np.abs(dK))
        # an exactly zero derivative (TC and SS at P = 1) is met to rounding of tr(W S)
        floor = 1e-13 * np.sum(np.abs(W) * np.abs(S_dense))
        got = contract(W)
        assert got.shape == kernel.theta.shape
        assert np.all(np.abs(got - expected) <= 1e-10 * magnitude + floor)
        np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12 * magnitude.max(initial=0.0) + floor)


@pytest.mark.parametrize("op_key", ["N61-F3-P20-o2", "N57-F5-P57-o4", "N40-F1-P40-o0"])
@pytest.mark.parametrize("kernel", fd_kernel_params)
def test_contraction_matches_finite_differences(kernel, op_key):
    op, Phi = make_operator(op_key, seed=3)
    _, contract = observed_shift_scaled(kernel, op)
    W = random_symmetric(op.n_outputs, 4)
    theta, lags, step = kernel.theta, dense_lags(op.order), 1e-4

    def dense_value(theta_):
        return np.sum(W * (Phi @ kernel.clone_with_theta(theta_)(lags) @ Phi.T))

    def recursive_value(theta_):
        S, _ = observed_shift_scaled(kernel.clone_with_theta(theta_), op, need_gradient=False)
        return np.sum(W * S)

    got = contract(W)
    for value in (dense_value, recursive_value):
        numeric = []
        for j in range(theta.shape[0]):
            e = np.zeros_like(theta)
            e[j] = step
            numeric.append(
                (-value(theta + 2 * e) + 8 * value(theta + e) - 8 * value(theta - e) + value(theta - 2 * e))
                / (12 * step)
            )
        numeric = np.array(numeric)
        np.testing.assert_allclose(got, numeric, rtol=1e-7, atol=1e-9 * np.abs(numeric).max())


@pytest.mark.parametrize("kernel", kernel_params)
@pytest.mark.parametrize("order", [600, 150])
def test_long_record_accuracy(kernel, order):
    # M = 200 slow samples of a record of 600, input with a non-zero mean
    u = np.random.default_rng(5).standard_normal(600) + 1.0
    op = DownsampledConvolution(u, 3, order, 1)
    K = kernel(dense_lags(order))
    S_dense = op.matrix @ K @ op.matrix.T
    fresh = DownsampledConvolution(u, 3, order, 1)
    S, _ = observed_shift_scaled(kernel, fresh, need_gradient=False)
    assert np.abs(S - S_dense).max() <= 1e-11 * np.abs(S_dense).max()


def test_fixed_hyperparameters_are_skipped():
    op, _ = make_operator("N61-F3-P20-o2")
    W = random_symmetric(op.n_outputs, 6)
    _, full = observed_shift_scaled(DC(alpha=0.8, beta=0.6), op)
    _, no_beta = observed_shift_scaled(DC(alpha=0.8, beta=0.6, beta_bounds="fixed"), op)
    _, no_alpha = observed_shift_scaled(DC(alpha=0.8, beta=0.6, alpha_bounds="fixed"), op)
    _, none = observed_shift_scaled(DC(alpha=0.8, beta=0.6, alpha_bounds="fixed", beta_bounds="fixed"), op)
    both = full(W)
    np.testing.assert_array_equal(no_beta(W), both[:1])
    np.testing.assert_array_equal(no_alpha(W), both[1:])
    assert none(W).shape == (0,)
    _, tc_none = observed_shift_scaled(TC(alpha=0.8, alpha_bounds="fixed"), op)
    assert tc_none(W).shape == (0,)


def test_neither_regressor_nor_kernel_matrix_is_formed(monkeypatch):
    def forbidden(*args, **kwargs):
        raise AssertionError("the kernel matrix must not be evaluated")

    for kind in (TC, DC, SS):
        monkeypatch.setattr(kind, "__call__", forbidden)
    u = np.random.default_rng(7).standard_normal(80)
    for kernel in (TC(alpha=0.9), DC(alpha=0.9, beta=0.8), SS(alpha=0.9)):
        op = DownsampledConvolution(u, 3, 50, 2)
        S, contract = observed_shift_scaled(kernel, op)
        contract(np.eye(op.n_outputs))
        cross_covariance_shift_scaled(kernel, op)
        kernel_matvec(kernel, 50, np.ones(50))
        assert op._matrix is None


def test_contract_checks_the_shape_of_w():
    op, _ = make_operator("N61-F3-P20-o2")
    _, contract = observed_shift_scaled(TC(alpha=0.9), op)
    with pytest.raises(ValueError, match="shape"):
        contract(np.eye(op.n_outputs + 1))


@pytest.mark.parametrize(
    "kernel",
    [C(2.0) * DC(alpha=0.9, beta=0.5), PK(alpha=0.9), RBF(2.0), TC(0.9) + TC(0.8)],
    ids=["C*DC", "PK", "RBF", "TC+TC"],
)
def test_other_kernels_are_rejected(kernel):
    op, _ = make_operator("N61-F3-P20-o2")
    assert not is_shift_scaled(kernel)
    with pytest.raises(TypeError, match="TC, DC or SS"):
        observed_shift_scaled(kernel, op)
    with pytest.raises(TypeError, match="TC, DC or SS"):
        cross_covariance_shift_scaled(kernel, op)


def test_subclasses_keep_the_structure_of_their_parent():
    # a subclass inherits its parent's formula and so its fast path
    class MyDC(DC):
        pass

    assert is_shift_scaled(DC()) and is_shift_scaled(MyDC())
    op, Phi = make_operator("N61-F3-P20-o2")
    kernel = MyDC(alpha=0.8, beta=0.6)
    S, _ = observed_shift_scaled(kernel, op)
    S_dense = Phi @ kernel(dense_lags(op.order)) @ Phi.T
    np.testing.assert_allclose(S, S_dense, rtol=1e-9, atol=1e-12 * np.abs(S_dense).max())


def test_invalid_hyperparameters_are_reported():
    op, _ = make_operator("N61-F3-P20-o2")
    with pytest.raises(ValueError, match="alpha"):
        observed_shift_scaled(TC(alpha=1.5), op)


# ----------------------------------------------------------------------------
# Phi K and K v
# ----------------------------------------------------------------------------


@pytest.mark.parametrize("op_key", list(OPERATORS))
@pytest.mark.parametrize("kernel", kernel_params)
def test_cross_covariance_equals_dense(kernel, op_key):
    op, Phi = make_operator(op_key, seed=8)
    K = kernel(dense_lags(op.order))
    expected = Phi @ K
    got = cross_covariance_shift_scaled(kernel, op)
    assert got.shape == (op.n_outputs, op.order)
    scale = (np.abs(Phi) @ np.abs(K)).max()
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-13 * scale)
    # transpose of the operator's cross-covariance at the lags 0..P-1
    np.testing.assert_allclose(
        got.T, op.cross_covariance(kernel, op.lags), rtol=1e-9, atol=1e-13 * scale
    )


@pytest.mark.parametrize("order", [1, 2, 7, 120])
@pytest.mark.parametrize("kernel", kernel_params)
def test_kernel_matvec_equals_dense(kernel, order):
    rng = np.random.default_rng(order)
    K = kernel(dense_lags(order))
    v = rng.standard_normal(order)
    V = rng.standard_normal((order, 3))
    scale = np.abs(K).max() * (np.abs(V).sum(axis=0).max() + np.abs(v).sum())
    got = kernel_matvec(kernel, order, v)
    assert got.shape == (order,)
    np.testing.assert_allclose(got, K @ v, rtol=1e-9, atol=1e-14 * scale)
    got = kernel_matvec(kernel, order, V)
    assert got.shape == (order, 3)
    np.testing.assert_allclose(got, K @ V, rtol=1e-9, atol=1e-14 * scale)
    np.testing.assert_allclose(
        kernel_matvec(kernel, order, np.asfortranarray(V)), K @ V, rtol=1e-9, atol=1e-14 * scale
    )


# ----------------------------------------------------------------------------
# cost rule
# ----------------------------------------------------------------------------


def test_prefer_recursion_on_the_measured_cases():
    # the recursion was 5-50 times faster on these (timings of a DC kernel)
    for M, N, P in [(200, 600, 600), (500, 1500, 1500), (1000, 3000, 3000), (2000, 6000, 6000), (2000, 50_000, 2000)]:
        for need_gradient in (True, False):
            assert prefer_recursion(M, N, P, need_gradient=need_gradient) is True
    # short FIR and a long slow period, or a tiny problem: the matrix products win
    for M, N, P in [(500, 50_000, 50), (2000, 6000, 10), (100, 100, 20)]:
        assert prefer_recursion(M, N, P) is False
    # more lags only make the BLAS route dearer
    assert prefer_recursion(1000, 30_000, 2000) and not prefer_recursion(1000, 30_000, 50)


@pytest.mark.parametrize("kernel", [DC(alpha=0.8, beta=0.6), TC(alpha=0.9), SS(alpha=0.7)],
                         ids=["DC", "TC", "SS"])
def test_leftover_memory_never_reaches_the_result(kernel, monkeypatch):
    # np.empty may hand back memory that holds any bit pattern, NaN included: the
    # recursion must not compute with it (no floating-point warning) nor change its result
    op = DownsampledConvolution(np.random.default_rng(3).standard_normal(90), 3, 30, 1)
    clean_S, clean_dS = observed_recursion(kernel, op.uniform_sampling, op.order)
    recursion_module = sys.modules[observed_recursion.__module__]

    class PoisonedNumpy:
        def __getattr__(self, name):
            return getattr(np, name)

        @staticmethod
        def empty(shape):
            # a signalling NaN: any arithmetic on it raises "invalid value"
            return np.full(shape, 0x7FF4000000000000, dtype=np.uint64).view(np.float64)

    monkeypatch.setattr(recursion_module, "np", PoisonedNumpy())
    with np.errstate(all="raise"):
        S, dS = observed_recursion(kernel, op.uniform_sampling, op.order)
    np.testing.assert_array_equal(S, clean_S)
    for derivative, clean in zip(dS, clean_dS):
        np.testing.assert_array_equal(derivative, clean)
    dense = op.matrix @ kernel(op.lags) @ op.matrix.T
    np.testing.assert_allclose(S, dense, rtol=1e-10, atol=1e-12 * np.abs(dense).max())
