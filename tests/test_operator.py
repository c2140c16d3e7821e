"""DownsampledConvolution against the definition of the regressor (paper eq. 8).

Row ``m`` of ``Phi`` is ``[u(offset + mF), u(offset + mF - 1), ..., u(offset + mF - P + 1)]``
with ``u(n) = 0`` for ``n < 0`` (NOTES.md).  Every number here comes from an explicit
loop, ``np.convolve``, a closed-form kernel, finite differences or a Monte Carlo estimate.
"""

import copy
import pickle

import numpy as np
import pytest
from sklearn.gaussian_process.kernels import ConstantKernel as C

from gpmultirate import DownsampledConvolution
from gpmultirate.kernels import DC, PK
from gpmultirate.observations.convolution import convolution_matrix
from hold_reference import lagrange_rows

# (N, factor, order, offset)
CASES = [
    (12, 1, 5, 0),
    (13, 3, 4, 2),
    (20, 4, 20, 1),
    (7, 7, 3, 6),
    (30, 5, 1, 0),
    (10, 2, 10, 1),
    (9, 10, 4, 8),
    (61, 3, 25, 0),
]
CASE_IDS = [f"N{n}-F{f}-P{p}-o{o}" for n, f, p, o in CASES]


def explicit_regressor(u, factor, order, offset):
    rows = list(range(offset, len(u), factor))
    Phi = np.zeros((len(rows), order))
    for m in range(len(rows)):
        for i in range(order):
            n = offset + m * factor - i
            Phi[m, i] = u[n] if n >= 0 else 0.0
    return Phi


def dc_direct(t, s, alpha, beta, scale=1.0):
    return np.array([[scale * alpha ** ((a + b) / 2) * beta ** abs(a - b) for b in s] for a in t])


def make_input(n, seed=0):
    return np.random.default_rng(seed).standard_normal(n)


@pytest.fixture(params=CASES, ids=CASE_IDS)
def case(request):
    n, factor, order, offset = request.param
    u = make_input(n, seed=n + 7 * factor)
    return u, factor, order, offset


def test_matrix_equals_definition(case):
    u, factor, order, offset = case
    op = DownsampledConvolution(u, factor=factor, order=order, offset=offset)
    expected = explicit_regressor(u, factor, order, offset)
    np.testing.assert_array_equal(op.matrix, expected)
    assert op.shape == expected.shape
    assert op.n_samples == len(u)
    assert op.n_outputs == len(range(offset, len(u), factor))
    np.testing.assert_array_equal(op.sample_indices, list(range(offset, len(u), factor)))
    np.testing.assert_array_equal(op.lags[:, 0], np.arange(order))
    assert op.lags.shape == (order, 1)


def test_paper_example_by_hand():
    # u = 1..6, F = 2, P = 3: rows are fast samples 0, 2, 4
    op = DownsampledConvolution(np.arange(1.0, 7.0), factor=2, order=3)
    np.testing.assert_array_equal(op.matrix, [[1, 0, 0], [3, 2, 1], [5, 4, 3]])
    op = DownsampledConvolution(np.arange(1.0, 7.0), factor=2, order=3, offset=1)
    np.testing.assert_array_equal(op.matrix, [[2, 1, 0], [4, 3, 2], [6, 5, 4]])


def test_matvec_equals_downsampled_np_convolve(case):
    u, factor, order, offset = case
    op = DownsampledConvolution(u, factor=factor, order=order, offset=offset)
    rng = np.random.default_rng(1)
    g = rng.standard_normal(order)
    expected = np.convolve(u, g)[: len(u)][offset::factor]
    np.testing.assert_allclose(op.matvec(g), expected, rtol=1e-12, atol=1e-12)
    G = rng.standard_normal((order, 3))
    expected_cols = np.column_stack(
        [np.convolve(u, G[:, k])[: len(u)][offset::factor] for k in range(3)]
    )
    np.testing.assert_allclose(op.matvec(G), expected_cols, rtol=1e-12, atol=1e-12)


def test_rmatvec_equals_transpose(case):
    u, factor, order, offset = case
    op = DownsampledConvolution(u, factor=factor, order=order, offset=offset)
    Phi = explicit_regressor(u, factor, order, offset)
    rng = np.random.default_rng(2)
    y = rng.standard_normal(op.n_outputs)
    np.testing.assert_allclose(op.rmatvec(y), Phi.T @ y, rtol=1e-12, atol=1e-12)
    Y = rng.standard_normal((op.n_outputs, 2))
    np.testing.assert_allclose(op.rmatvec(Y), Phi.T @ Y, rtol=1e-12, atol=1e-12)
    # adjoint identity with the convolution of numpy
    g = rng.standard_normal(order)
    forward = np.convolve(u, g)[: len(u)][offset::factor]
    assert forward @ y == pytest.approx(g @ op.rmatvec(y), rel=1e-12, abs=1e-12)


def test_matvec_rmatvec_shape_errors():
    op = DownsampledConvolution(make_input(20), factor=2, order=5)
    with pytest.raises(ValueError, match="coef"):
        op.matvec(np.ones(4))
    with pytest.raises(ValueError, match="y"):
        op.rmatvec(np.ones(op.n_outputs + 1))


@pytest.mark.parametrize("case", [CASES[1], CASES[2], CASES[7]], ids=[CASE_IDS[1], CASE_IDS[2], CASE_IDS[7]])
def test_covariance_equals_dense_formula(case):
    n, factor, order, offset = case
    u = make_input(n, seed=3)
    op = DownsampledConvolution(u, factor=factor, order=order, offset=offset)
    Phi = explicit_regressor(u, factor, order, offset)
    kernel = C(1.7) * DC(alpha=0.85, beta=0.6)
    lags = np.arange(order)
    K = dc_direct(lags, lags, 0.85, 0.6, 1.7)
    np.testing.assert_allclose(op.kernel_matrix(kernel), K, rtol=1e-13)
    S = op.covariance(kernel)
    np.testing.assert_allclose(S, Phi @ K @ Phi.T, rtol=1e-10, atol=1e-12 * np.abs(S).max())
    np.testing.assert_array_equal(S, S.T)


@pytest.mark.parametrize("case", [CASES[1], CASES[7]], ids=[CASE_IDS[1], CASE_IDS[7]])
def test_covariance_gradient_matches_finite_differences(case):
    n, factor, order, offset = case
    u = make_input(n, seed=4)
    op = DownsampledConvolution(u, factor=factor, order=order, offset=offset)
    Phi = explicit_regressor(u, factor, order, offset)
    kernel = C(1.7) * DC(alpha=0.85, beta=0.6) + PK(alpha=0.9, omega=0.8, sigma1=0.5, sigma2=1.2)
    S, dS = op.covariance(kernel, eval_gradient=True)
    assert dS.shape == (op.n_outputs, op.n_outputs, kernel.theta.shape[0])
    np.testing.assert_allclose(S, op.covariance(kernel), rtol=1e-12, atol=1e-12)
    lags = np.arange(order)
    theta = kernel.theta
    step = 1e-5

    def dense_cov(theta_):
        # theta = log [constant, DC alpha, PK alpha, omega, sigma1, sigma2], artanh(DC beta)
        c, alpha, beta, a, w, s1, s2 = np.exp(theta_)
        beta = np.tanh(theta_[2])
        K = dc_direct(lags, lags, alpha, beta, c)
        env = a ** (lags / 2)
        K += s1**2 * np.outer(env * np.cos(w * lags), env * np.cos(w * lags))
        K += s2**2 * np.outer(env * np.sin(w * lags), env * np.sin(w * lags))
        return Phi @ K @ Phi.T

    np.testing.assert_allclose(dense_cov(theta), S, rtol=1e-10, atol=1e-12 * np.abs(S).max())
    for j in range(theta.shape[0]):
        e = np.zeros_like(theta)
        e[j] = step
        numeric = (dense_cov(theta + e) - dense_cov(theta - e)) / (2 * step)
        np.testing.assert_allclose(
            dS[..., j], numeric, rtol=1e-5, atol=1e-7 * np.abs(numeric).max()
        )


def test_cross_covariance_equals_formula():
    u = make_input(40, seed=5)
    op = DownsampledConvolution(u, factor=4, order=15, offset=3)
    Phi = explicit_regressor(u, 4, 15, 3)
    kernel = C(0.8) * DC(alpha=0.9, beta=0.7)
    lags = np.array([0.0, 0.25, 3.5, 7.0, 14.9, 20.3])
    # between integer lags the hold's prior: the Lagrange interpolation on the lags
    # n - 5 .. n + 6 (zero below lag 0) of the formula at integer lags; the bridge is
    # zero against the integer lags
    grid = np.arange(30)
    W = lagrange_rows(lags, grid.shape[0])
    expected = W @ dc_direct(grid, np.arange(15), 0.9, 0.7, 0.8) @ Phi.T
    np.testing.assert_allclose(
        op.cross_covariance(kernel, lags[:, None]), expected, rtol=1e-12, atol=1e-14
    )
    # at the integer lags the cross covariance is K Phi^T, a block of Cov([g; y])
    K = dc_direct(np.arange(15), np.arange(15), 0.9, 0.7, 0.8)
    np.testing.assert_allclose(
        op.cross_covariance(kernel, op.lags), K @ Phi.T, rtol=1e-12, atol=1e-14
    )


def test_covariance_matches_monte_carlo():
    # y = Phi g with g ~ N(0, K) has covariance Phi K Phi^T; check by sampling
    u = make_input(30, seed=6)
    op = DownsampledConvolution(u, factor=3, order=10, offset=1)
    K = dc_direct(np.arange(10), np.arange(10), 0.8, 0.6)
    rng = np.random.default_rng(7)
    n_draws = 40_000
    g = rng.multivariate_normal(np.zeros(10), K, size=n_draws)
    y = np.array([np.convolve(u, gi)[:30][1::3] for gi in g[:2000]])  # spot-check the map
    np.testing.assert_allclose(op.matvec(g[:2000].T).T, y, rtol=1e-12, atol=1e-12)
    samples = op.matvec(g.T).T
    empirical = samples.T @ samples / n_draws
    S = op.covariance(DC(alpha=0.8, beta=0.6))
    sd = np.sqrt(np.outer(np.diag(S), np.diag(S)) + S**2) / np.sqrt(n_draws)
    assert np.all(np.abs(empirical - S) < 5 * sd)


@pytest.mark.parametrize("order", [1, 3, 8, 15])
def test_convolution_matrix_equals_loop(order):
    u = make_input(8, seed=8)
    T = convolution_matrix(u, order)
    expected = np.array([[u[n - i] if n - i >= 0 else 0.0 for i in range(order)] for n in range(8)])
    np.testing.assert_array_equal(T, expected)
    g = np.random.default_rng(9).standard_normal(order)
    np.testing.assert_allclose(T @ g, np.convolve(u, g)[:8], rtol=1e-12, atol=1e-12)
    rows = np.array([7, 2, 0, 5])
    np.testing.assert_array_equal(convolution_matrix(u, order, rows), expected[rows])


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(factor=0, order=3), "factor"),
        (dict(factor=-1, order=3), "factor"),
        (dict(factor=2.5, order=3), "factor"),
        (dict(factor=2.0, order=3), "factor"),
        (dict(factor=True, order=3), "factor"),
        (dict(factor=None, order=3), "factor"),
        (dict(factor="2", order=3), "factor"),
        (dict(factor=2, order=0), "order"),
        (dict(factor=2, order=11), "order"),
        (dict(factor=2, order=3.0), "order"),
        (dict(factor=2, order=False), "order"),
        (dict(factor=2, order=3, offset=-1), "offset"),
        (dict(factor=2, order=3, offset=2), "offset"),
        (dict(factor=2, order=3, offset=0.5), "offset"),
        (dict(factor=20, order=3, offset=10), "offset"),  # offset >= N leaves no slow sample
    ],
)
def test_invalid_arguments_raise(kwargs, match):
    with pytest.raises(ValueError, match=match):
        DownsampledConvolution(make_input(10), **kwargs)


def test_numpy_integers_are_accepted():
    op = DownsampledConvolution(make_input(10), factor=np.int64(2), order=np.int32(3), offset=np.int8(1))
    assert (op.factor, op.order, op.offset) == (2, 3, 1)
    assert type(op.factor) is int


@pytest.mark.parametrize(
    "u",
    [
        np.array([1.0, np.nan, 2.0]),
        np.array([1.0, np.inf, 2.0]),
        np.array([-np.inf, 1.0]),
        np.ones((3, 4)),
        np.ones((2, 2, 2)),
        np.array([]),
        np.empty((0, 1)),
        None,
        "abc",
        [1.0, "x"],
    ],
    ids=["nan", "inf", "-inf", "2d", "3d", "empty", "empty2d", "none", "str", "mixed"],
)
def test_invalid_input_signal_raises(u):
    with pytest.raises(ValueError, match="u"):
        DownsampledConvolution(u, factor=1, order=1)


def test_input_is_copied_and_read_only():
    u = make_input(20, seed=10)
    before = u.copy()
    op = DownsampledConvolution(u, factor=3, order=6, offset=1)
    np.testing.assert_array_equal(u, before)
    assert u.flags.writeable
    assert not op.u.flags.writeable
    assert not np.shares_memory(op.u, u)
    with pytest.raises(ValueError):
        op.u[0] = 1.0
    with pytest.raises(ValueError):
        op.matrix[0, 0] = 1.0
    with pytest.raises(ValueError):
        op.sample_indices[0] = 1
    matrix = op.matrix.copy()
    u[:] = 0.0  # the caller changing its array afterwards changes nothing
    np.testing.assert_array_equal(op.u, before)
    np.testing.assert_array_equal(op.matrix, matrix)
    # a list is accepted and not modified
    values = [1.0, 2.0, 3.0]
    DownsampledConvolution(values, factor=1, order=2)
    assert values == [1.0, 2.0, 3.0]


def test_matvec_does_not_modify_arguments():
    op = DownsampledConvolution(make_input(20, seed=11), factor=2, order=4)
    g = np.arange(4.0)
    y = np.arange(op.n_outputs, dtype=float)
    op.matvec(g)
    op.rmatvec(y)
    np.testing.assert_array_equal(g, np.arange(4.0))
    np.testing.assert_array_equal(y, np.arange(op.n_outputs, dtype=float))


def test_equality():
    u = make_input(20, seed=12)
    op = DownsampledConvolution(u, factor=3, order=6, offset=1)
    assert op == DownsampledConvolution(u.copy(), factor=3, order=6, offset=1)
    assert op != DownsampledConvolution(u, factor=3, order=6, offset=2)
    assert op != DownsampledConvolution(u, factor=2, order=6, offset=1)
    assert op != DownsampledConvolution(u, factor=3, order=5, offset=1)
    other_u = u.copy()
    other_u[-1] += 1.0
    assert op != DownsampledConvolution(other_u, factor=3, order=6, offset=1)
    assert op != DownsampledConvolution(u[:-1], factor=3, order=6, offset=1)
    assert op != "not an operator"
    with pytest.raises(TypeError):
        hash(op)


@pytest.mark.parametrize("duplicate", [lambda op: pickle.loads(pickle.dumps(op)), copy.deepcopy])
def test_pickle_and_deepcopy_round_trip(duplicate):
    u = make_input(25, seed=13)
    op = DownsampledConvolution(u, factor=4, order=9, offset=2)
    _ = op.matrix  # a cached matrix must not get in the way
    loaded = duplicate(op)
    assert loaded == op
    np.testing.assert_array_equal(loaded.matrix, explicit_regressor(u, 4, 9, 2))
    np.testing.assert_array_equal(loaded.sample_indices, op.sample_indices)
    assert not loaded.u.flags.writeable
    assert not loaded.sample_indices.flags.writeable
    assert not loaded.matrix.flags.writeable
    assert repr(loaded) == repr(op)


def test_repr():
    op = DownsampledConvolution(make_input(25), factor=4, order=9, offset=2)
    text = repr(op)
    for part in ["DownsampledConvolution", "N=25", "factor=4", "order=9", "offset=2", "M=6"]:
        assert part in text
