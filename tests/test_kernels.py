"""Lag kernels TC, DC, SS, PK against the paper's formulas and scikit-learn's kernel contract.

The formulas are written out entry by entry from eq. (16)-(19) (with the
corrections of NOTES.md) and evaluated at real, non-integer lags; gradients are
checked against finite differences of the kernel matrix in ``theta`` (log) space.
The sklearn checks mirror ``sklearn/gaussian_process/tests/test_kernels.py``.
"""

import pickle
from inspect import signature

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.base import clone
from sklearn.gaussian_process.kernels import RBF, Product, Sum
from sklearn.gaussian_process.kernels import ConstantKernel as C
from sklearn.metrics.pairwise import pairwise_kernels

from gpmultirate.kernels import DC, PK, SS, TC, check_lags

RNG = np.random.default_rng(20250601)
# real, non-integer lags (plus lag 0), unsorted on purpose
LAGS = np.concatenate([[0.0], RNG.uniform(0.0, 14.0, 11)])
X = LAGS[:, None]
Y = RNG.uniform(0.0, 9.0, 7)[:, None]


# ----------------------------------------------------------------------------
# direct formulas, entry by entry (paper eq. 16-19)
# ----------------------------------------------------------------------------


def held(formula):
    """The formula at integer lags; between them its Lagrange interpolation on the twelve
    integer lags ``n - 5 .. n + 6`` around ``n + d``, zero below lag 0 (the hold's prior)."""

    def expand(x):
        n = int(np.floor(x))
        if x == n:
            return [(n, 1.0)]
        nodes = [n + k for k in range(-5, 7)]
        out = []
        for node in nodes:
            weight = np.prod([(x - o) / (node - o) for o in nodes if o != node])
            if node >= 0:
                out.append((node, weight))
        return out

    def bridge(a, b, *args, **kwargs):
        # independent on each cell: 0.1^2 sin(pi d) sin(pi e) k(n, n)
        n = np.floor(a)
        if np.floor(b) != n:
            return 0.0
        return (0.1**2 * np.sin(np.pi * (a - n)) * np.sin(np.pi * (b - n))
                * formula(n, n, *args, **kwargs))

    def kernel(t, s, *args, **kwargs):
        return np.array([[sum(wa * wb * formula(na, nb, *args, **kwargs)
                              for na, wa in expand(a) for nb, wb in expand(b))
                          + bridge(a, b, *args, **kwargs)
                          for b in s] for a in t])

    return kernel


@held
def tc_direct(a, b, alpha):
    return alpha ** max(a, b)


@held
def dc_direct(a, b, alpha, beta, scale=1.0):
    return scale * alpha ** ((a + b) / 2) * beta ** abs(a - b)


@held
def ss_direct(a, b, alpha):
    return alpha ** (a + b + max(a, b)) / 2 - alpha ** (3 * max(a, b)) / 6


def pk_paper(t, s, alpha, omega, sigma1, sigma2):
    """Eq. (18)-(19): alpha^((i+j)/2) (g1 cos(w(i-j)) + g2 cos(w(i+j)))."""
    g1 = (sigma1**2 + sigma2**2) / 2
    g2 = (sigma1**2 - sigma2**2) / 2
    return np.array(
        [
            [
                alpha ** ((a + b) / 2)
                * (g1 * np.cos(omega * (a - b)) + g2 * np.cos(omega * (a + b)))
                for b in s
            ]
            for a in t
        ]
    )


def finite_difference_gradient(kernel, X, step=1e-5):
    """Central differences of ``kernel(X)`` with respect to ``kernel.theta``."""
    theta = kernel.theta
    columns = []
    for j in range(theta.shape[0]):
        shift = np.zeros_like(theta)
        shift[j] = step
        plus = kernel.clone_with_theta(theta + shift)(X)
        minus = kernel.clone_with_theta(theta - shift)(X)
        columns.append((plus - minus) / (2 * step))
    return np.stack(columns, axis=-1) if columns else np.empty(X.shape[:1] * 2 + (0,))


# ----------------------------------------------------------------------------
# kernels under test (all hyperparameters strictly inside their ranges so
# that finite differences stay valid)
# ----------------------------------------------------------------------------

BASIC = {
    "TC": TC(alpha=0.8),
    "DC": DC(alpha=0.85, beta=0.6),
    "SS": SS(alpha=0.9),
    "PK": PK(alpha=0.9, omega=0.7, sigma1=1.3, sigma2=0.6),
    "PK-hold": PK(alpha=0.9, omega=0.7, sigma1=1.3, sigma2=0.6, hold=True),
}
COMPOSITE = {
    "C*DC+PK": C(2.0) * DC(alpha=0.8, beta=0.7) + PK(alpha=0.95, omega=1.2, sigma1=0.5, sigma2=0.8),
    "DC*C": DC(alpha=0.9, beta=0.5) * C(0.5),
    "TC+SS": TC(alpha=0.7) + SS(alpha=0.8),
    "PK*DC": PK(alpha=0.93, omega=0.4, sigma1=1.1, sigma2=0.9) * DC(alpha=0.9, beta=0.8),
    "C*DC+PK+PK": C(1.5) * DC(alpha=0.92, beta=0.75)
    + PK(alpha=0.9, omega=0.25, sigma1=0.4, sigma2=0.7)
    + PK(alpha=0.8, omega=1.4, sigma1=0.9, sigma2=0.2),
    "C*(TC+PK)": C(0.3) * (TC(alpha=0.85) + PK(alpha=0.9, omega=2.0)),
    "DC**2": DC(alpha=0.9, beta=0.6) ** 2,
}
ALL = {**BASIC, **COMPOSITE}


def kernel_params(mapping):
    return [pytest.param(k, id=name) for name, k in mapping.items()]


# ----------------------------------------------------------------------------
# formulas of the paper
# ----------------------------------------------------------------------------


@pytest.mark.parametrize("alpha", [0.3, 0.8, 0.99, 1.0])
def test_tc_matches_formula(alpha):
    kernel = TC(alpha=alpha)
    np.testing.assert_allclose(kernel(X), tc_direct(LAGS, LAGS, alpha), rtol=1e-13)
    np.testing.assert_allclose(kernel(X, Y), tc_direct(LAGS, Y[:, 0], alpha), rtol=1e-13)


@pytest.mark.parametrize("alpha, beta", [(0.8, 0.5), (0.95, 0.99), (0.4, 0.1), (1.0, 1.0)])
def test_dc_with_scale_matches_eq16(alpha, beta):
    kernel = C(2.5) * DC(alpha=alpha, beta=beta)
    np.testing.assert_allclose(kernel(X), dc_direct(LAGS, LAGS, alpha, beta, 2.5), rtol=1e-13)
    np.testing.assert_allclose(
        kernel(X, Y), dc_direct(LAGS, Y[:, 0], alpha, beta, 2.5), rtol=1e-13
    )


@pytest.mark.parametrize("alpha, beta", [(0.8, 0.5), (0.97, 0.999)])
def test_dc_on_integer_grid_matches_eq16(alpha, beta):
    # lags 0..P-1 take a Toeplitz shortcut inside DC; it must agree with the formula
    grid = np.arange(25.0)
    expected = dc_direct(grid, grid, alpha, beta)
    np.testing.assert_allclose(DC(alpha, beta)(grid[:, None]), expected, rtol=1e-13)
    np.testing.assert_allclose(DC(alpha, beta)(grid[:, None], grid[:, None]), expected, rtol=1e-13)
    # a grid that does not start at zero, and a permuted grid
    shifted = grid + 1.0
    np.testing.assert_allclose(
        DC(alpha, beta)(shifted[:, None]), dc_direct(shifted, shifted, alpha, beta), rtol=1e-13
    )
    permuted = RNG.permutation(grid)
    np.testing.assert_allclose(
        DC(alpha, beta)(permuted[:, None]), dc_direct(permuted, permuted, alpha, beta), rtol=1e-13
    )


@pytest.mark.parametrize("alpha", [0.5, 0.9, 1.0])
def test_ss_matches_eq17(alpha):
    kernel = SS(alpha=alpha)
    np.testing.assert_allclose(kernel(X), ss_direct(LAGS, LAGS, alpha), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(
        kernel(X, Y), ss_direct(LAGS, Y[:, 0], alpha), rtol=1e-12, atol=1e-15
    )


@pytest.mark.parametrize(
    "alpha, omega, sigma1, sigma2",
    [(0.9, 0.7, 1.3, 0.6), (0.95, 2.5132741228718345, 1.0, 1.0), (0.7, 0.05, 0.2, 3.0)],
)
def test_pk_matches_paper_form_at_real_lags(alpha, omega, sigma1, sigma2):
    kernel = PK(alpha=alpha, omega=omega, sigma1=sigma1, sigma2=sigma2)
    scale = sigma1**2 + sigma2**2
    np.testing.assert_allclose(
        kernel(X), pk_paper(LAGS, LAGS, alpha, omega, sigma1, sigma2), rtol=1e-10, atol=1e-13 * scale
    )
    np.testing.assert_allclose(
        kernel(X, Y),
        pk_paper(LAGS, Y[:, 0], alpha, omega, sigma1, sigma2),
        rtol=1e-10,
        atol=1e-13 * scale,
    )


def test_known_values():
    # worked by hand: DC(0.8, 0.5) at lags 0 and 1.5
    K = DC(alpha=0.8, beta=0.5)(np.array([[0.0], [2.0]]))
    off = 0.8**1.0 * 0.5**2
    np.testing.assert_allclose(K, [[1.0, off], [off, 0.8**2]], rtol=1e-14)
    # between the ticks the cubic weights of the midpoint, -1/16, 9/16, 9/16, -1/16, would
    # give lag 1.5 from 0..3 with four nodes; the twelve nodes' weights sum to one
    from gpmultirate.kernels.hold import hold_weights
    W, _ = hold_weights([7.5])
    assert W.sum() == pytest.approx(1.0, rel=1e-12)
    # SS at lag 0: 1/2 - 1/6 = 1/3
    assert SS(alpha=0.7)(np.array([[0.0]]))[0, 0] == pytest.approx(1.0 / 3.0, rel=1e-15)
    # PK at lag 0 is sigma1^2 (the sine part vanishes)
    assert PK(sigma1=1.7, sigma2=5.0)(np.array([[0.0]]))[0, 0] == pytest.approx(1.7**2)


# ----------------------------------------------------------------------------
# positive semidefiniteness and symmetry
# ----------------------------------------------------------------------------


def assert_psd(K):
    np.testing.assert_allclose(K, K.T, rtol=1e-13, atol=0)
    eig = np.linalg.eigvalsh(0.5 * (K + K.T))
    assert eig.max() > 0
    assert eig.min() >= -1e-10 * eig.max()


@pytest.mark.parametrize("kernel", kernel_params(ALL))
def test_positive_semidefinite_on_real_lags(kernel):
    lags = RNG.uniform(0.0, 40.0, 30)[:, None]
    assert_psd(kernel(lags))


unit_interval = st.floats(0.05, 1.0)
lag_lists = st.lists(st.floats(0.0, 30.0), min_size=2, max_size=12)


@settings(max_examples=40, deadline=None)
@given(alpha=unit_interval, beta=unit_interval, lags=lag_lists)
def test_dc_psd_and_symmetric_property(alpha, beta, lags):
    t = np.array(lags)
    K = DC(alpha=alpha, beta=beta)(t[:, None])
    assert_psd(K)
    # entries far below the largest come from sums of weighted kernel values that cancel:
    # their rounding is relative to the largest (4.6e-20 beside 2.5e-10, apart by 1.4e-11)
    np.testing.assert_allclose(K, dc_direct(t, t, alpha, beta), rtol=1e-12,
                               atol=1e-13 * np.abs(K).max())


@settings(max_examples=40, deadline=None)
@given(alpha=unit_interval, lags=lag_lists)
def test_tc_ss_psd_property(alpha, lags):
    t = np.array(lags)[:, None]
    assert_psd(TC(alpha=alpha)(t))
    assert_psd(SS(alpha=alpha)(t))


@settings(max_examples=40, deadline=None)
@given(
    alpha=unit_interval,
    omega=st.floats(0.01, 2 * np.pi),
    sigma1=st.floats(0.1, 10.0),
    sigma2=st.floats(0.1, 10.0),
    lags=lag_lists,
)
def test_pk_psd_property(alpha, omega, sigma1, sigma2, lags):
    t = np.array(lags)
    K = PK(alpha=alpha, omega=omega, sigma1=sigma1, sigma2=sigma2)(t[:, None])
    assert_psd(K)
    # rank two: at most two eigenvalues above rounding
    eig = np.linalg.eigvalsh(K)
    assert np.sum(eig > 1e-9 * eig.max()) <= 2


# ----------------------------------------------------------------------------
# scikit-learn's kernel contract
# ----------------------------------------------------------------------------


@pytest.mark.parametrize("kernel", kernel_params(ALL))
def test_gradient_matches_finite_differences(kernel):
    K, dK = kernel(X, eval_gradient=True)
    assert dK.shape == (X.shape[0], X.shape[0], kernel.theta.shape[0])
    np.testing.assert_allclose(K, kernel(X), rtol=1e-13, atol=1e-15)
    numeric = finite_difference_gradient(kernel, X)
    np.testing.assert_allclose(dK, numeric, rtol=1e-5, atol=1e-7 * np.abs(numeric).max())


@pytest.mark.parametrize("kernel", kernel_params(BASIC))
def test_gradient_on_integer_grid_matches_finite_differences(kernel):
    grid = np.arange(20.0)[:, None]
    _, dK = kernel(grid, eval_gradient=True)
    numeric = finite_difference_gradient(kernel, grid)
    np.testing.assert_allclose(dK, numeric, rtol=1e-5, atol=1e-7 * np.abs(numeric).max())


# theta = log(value) except DC's correlation, theta = artanh(beta)
CORRELATIONS = {("DC", "beta")}


@pytest.mark.parametrize("kernel", kernel_params(BASIC))
def test_theta_is_log_or_artanh_of_hyperparameters(kernel):
    kernel = clone(kernel)
    init_args = [p for p in signature(type(kernel).__init__).parameters if p != "self"]
    bound_names = {a[: -len("_bounds")] for a in init_args if a.endswith("_bounds")}
    assert {h.name for h in kernel.hyperparameters} == bound_names

    def coordinate(name):
        return np.arctanh if (type(kernel).__name__, name) in CORRELATIONS else np.log

    theta = kernel.theta
    for i, h in enumerate(kernel.hyperparameters):
        assert theta[i] == coordinate(h.name)(getattr(kernel, h.name))
        assert h.value_type == "numeric"
        np.testing.assert_array_equal(
            kernel.bounds[i], coordinate(h.name)(getattr(kernel, h.name + "_bounds"))
        )
    # the theta setter writes the values back, and attributes feed theta
    for i, h in enumerate(kernel.hyperparameters):
        theta = kernel.theta
        theta[i] = coordinate(h.name)(0.42)
        kernel.theta = theta
        assert getattr(kernel, h.name) == pytest.approx(0.42)
        setattr(kernel, h.name, 0.43)
        assert kernel.theta[i] == pytest.approx(coordinate(h.name)(0.43))


def test_hyperparameter_names_and_default_bounds():
    def listing(kernel):
        return [(h.name, tuple(np.ravel(h.bounds))) for h in kernel.hyperparameters]

    assert listing(TC()) == [("alpha", (1e-4, 1.0))]
    assert listing(SS()) == [("alpha", (1e-4, 1.0))]
    assert listing(DC()) == [("alpha", (1e-4, 1.0)), ("beta", (-0.9999, 0.9999))]
    assert listing(PK()) == [
        ("alpha", (1e-4, 1.0)),
        ("omega", (1e-3, np.pi)),
        ("sigma1", (1e-5, 1e5)),
        ("sigma2", (1e-5, 1e5)),
    ]
    composite = C(2.0) * DC() + PK()
    assert [h.name for h in composite.hyperparameters] == [
        "k1__k1__constant_value",
        "k1__k2__alpha",
        "k1__k2__beta",
        "k2__alpha",
        "k2__omega",
        "k2__sigma1",
        "k2__sigma2",
    ]
    expected = np.log([2.0, 0.9, 0.9, 0.9, 0.5, 1.0, 1.0])
    expected[2] = np.arctanh(0.9)  # DC's beta
    np.testing.assert_allclose(composite.theta, expected, rtol=1e-15)


@pytest.mark.parametrize("kernel", kernel_params(BASIC))
def test_fixed_bound_drops_hyperparameter(kernel):
    theta = kernel.theta
    _, dK = kernel(X, eval_gradient=True)
    names = [h.name for h in kernel.hyperparameters]
    for i, name in enumerate(names):
        params = kernel.get_params()
        params[name + "_bounds"] = "fixed"
        fixed = type(kernel)(**params)
        assert [h.fixed for h in fixed.hyperparameters] == [n == name for n in names]
        assert fixed.theta.shape == (theta.shape[0] - 1,)
        keep = [j for j in range(len(names)) if j != i]
        np.testing.assert_array_equal(fixed.theta, theta[keep])
        if keep:  # sklearn returns an empty 1-D array when nothing is free
            np.testing.assert_array_equal(fixed.bounds, kernel.bounds[keep])
        else:
            assert fixed.bounds.size == 0
        K_fixed, dK_fixed = fixed(X, eval_gradient=True)
        assert dK_fixed.shape == dK.shape[:2] + (len(keep),)
        np.testing.assert_array_equal(dK_fixed, dK[..., keep])
        np.testing.assert_allclose(K_fixed, kernel(X), rtol=1e-14, atol=1e-16)


def test_all_fixed_gives_empty_gradient():
    kernel = DC(alpha=0.8, beta=0.5, alpha_bounds="fixed", beta_bounds="fixed")
    K, dK = kernel(X, eval_gradient=True)
    assert kernel.theta.shape == (0,)
    assert dK.shape == (X.shape[0], X.shape[0], 0)
    np.testing.assert_allclose(K, dc_direct(LAGS, LAGS, 0.8, 0.5), rtol=1e-13)


def test_fixed_bounds_in_composite_kernel():
    free = C(2.0) * DC(alpha=0.8, beta=0.7) + PK(alpha=0.95, omega=1.2)
    fixed = C(2.0) * DC(alpha=0.8, beta=0.7, beta_bounds="fixed") + PK(
        alpha=0.95, omega=1.2, omega_bounds="fixed", sigma2_bounds="fixed"
    )
    keep = [0, 1, 3, 5]  # constant, DC alpha, PK alpha, PK sigma1
    np.testing.assert_array_equal(fixed.theta, free.theta[keep])
    np.testing.assert_array_equal(fixed.bounds, free.bounds[keep])
    _, dK_free = free(X, eval_gradient=True)
    _, dK_fixed = fixed(X, eval_gradient=True)
    np.testing.assert_array_equal(dK_fixed, dK_free[..., keep])
    numeric = finite_difference_gradient(fixed, X)
    np.testing.assert_allclose(dK_fixed, numeric, rtol=1e-5, atol=1e-7 * np.abs(numeric).max())


@pytest.mark.parametrize("kernel", kernel_params(ALL))
def test_auto_equals_cross(kernel):
    np.testing.assert_allclose(kernel(X), kernel(X, X), rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("kernel", kernel_params(ALL))
def test_diag_equals_diagonal_of_matrix(kernel):
    np.testing.assert_allclose(kernel.diag(X), np.diag(kernel(X)), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("kernel", kernel_params(BASIC))
def test_lags_as_vector_and_column_agree(kernel):
    np.testing.assert_array_equal(kernel(LAGS), kernel(X))
    np.testing.assert_array_equal(kernel.diag(LAGS), kernel.diag(X))


@pytest.mark.parametrize("kernel", kernel_params(ALL))
def test_versus_pairwise_kernels(kernel):
    np.testing.assert_allclose(pairwise_kernels(X, metric=kernel), kernel(X), rtol=1e-12)
    np.testing.assert_allclose(pairwise_kernels(X, Y, metric=kernel), kernel(X, Y), rtol=1e-12)


@pytest.mark.parametrize("kernel", kernel_params(ALL))
def test_clone(kernel):
    cloned = clone(kernel)
    assert cloned == kernel
    assert cloned is not kernel
    assert cloned.get_params() == kernel.get_params()
    for attr in dir(kernel):
        if attr.startswith("hyperparameter_"):
            assert getattr(cloned, attr) == getattr(kernel, attr)
    np.testing.assert_array_equal(cloned(X), kernel(X))


@pytest.mark.parametrize("kernel", kernel_params(ALL))
def test_clone_with_theta(kernel):
    original = kernel.theta.copy()
    new_theta = original + np.log(0.9)
    cloned = kernel.clone_with_theta(new_theta)
    np.testing.assert_allclose(cloned.theta, new_theta, rtol=1e-14, atol=1e-15)
    np.testing.assert_array_equal(kernel.theta, original)
    assert type(cloned) is type(kernel)
    assert not np.allclose(cloned(X), kernel(X))


@pytest.mark.parametrize("kernel", kernel_params(ALL))
def test_pickle_round_trip(kernel):
    loaded = pickle.loads(pickle.dumps(kernel))
    assert loaded == kernel
    np.testing.assert_array_equal(loaded.theta, kernel.theta)
    np.testing.assert_array_equal(loaded(X), kernel(X))
    np.testing.assert_array_equal(loaded(X, eval_gradient=True)[1], kernel(X, eval_gradient=True)[1])


@pytest.mark.parametrize(
    "kernel, text",
    [
        (TC(alpha=0.5), "TC(alpha=0.5)"),
        (DC(alpha=0.8, beta=0.25), "DC(alpha=0.8, beta=0.25)"),
        (SS(alpha=0.75), "SS(alpha=0.75)"),
        (PK(alpha=0.5, omega=2.0, sigma1=3.0, sigma2=0.5), "PK(alpha=0.5, omega=2, sigma1=3, sigma2=0.5)"),
    ],
)
def test_repr(kernel, text):
    assert repr(kernel) == text
    rebuilt = eval(text, {"TC": TC, "DC": DC, "SS": SS, "PK": PK})
    assert rebuilt == kernel
    combined = repr(C(2.0) * kernel + TC(alpha=0.5))
    assert text in combined and "TC(alpha=0.5)" in combined


@pytest.mark.parametrize("kernel", kernel_params(ALL))
def test_get_params_and_set_params_consistent_with_theta(kernel):
    kernel = clone(kernel)
    params = kernel.get_params()
    free = [h for h in kernel.hyperparameters if not h.fixed]

    def value(h, theta):  # every beta here is DC's, whose theta is artanh(beta)
        return np.tanh(theta) if h.name.endswith("beta") else np.exp(theta)

    for i, h in enumerate(free):
        assert value(h, kernel.theta[i]) == pytest.approx(params[h.name], rel=1e-14)
    for i, h in enumerate(free):
        kernel.set_params(**{h.name: 0.37})
        assert value(h, kernel.theta[i]) == pytest.approx(0.37, rel=1e-14)
        assert kernel.get_params()[h.name] == 0.37


def test_set_params_then_clone_and_bounds():
    kernel = DC(alpha=0.8, beta=0.5)
    kernel.set_params(alpha=0.6, beta_bounds=(0.1, 0.9))
    cloned = clone(kernel)
    assert cloned.get_params() == kernel.get_params()
    np.testing.assert_allclose(
        cloned.bounds, [np.log([1e-4, 1.0]), np.arctanh([0.1, 0.9])], rtol=1e-15
    )
    np.testing.assert_allclose(cloned(X), dc_direct(LAGS, LAGS, 0.6, 0.5), rtol=1e-13)
    with pytest.raises(ValueError):
        kernel.set_params(gamma=1.0)


@pytest.mark.parametrize("kernel", kernel_params(BASIC))
def test_kernel_algebra(kernel):
    K = kernel(X)
    np.testing.assert_allclose((kernel + 1.0)(X), K + 1.0, rtol=1e-14)
    np.testing.assert_allclose((1.0 + kernel)(X), K + 1.0, rtol=1e-14)
    np.testing.assert_allclose((3.0 * kernel)(X), 3.0 * K, rtol=1e-14)
    np.testing.assert_allclose((kernel * 3.0)(X), 3.0 * K, rtol=1e-14)
    other = DC(alpha=0.7, beta=0.3)
    K_other = dc_direct(LAGS, LAGS, 0.7, 0.3)
    assert isinstance(kernel + other, Sum) and isinstance(kernel * other, Product)
    np.testing.assert_allclose((kernel + other)(X), K + K_other, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose((kernel * other)(X), K * K_other, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose((kernel**2)(X), K**2, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose((kernel + RBF(2.0))(X), K + RBF(2.0)(X), rtol=1e-12)
    assert (kernel + other).theta.shape[0] == kernel.theta.shape[0] + 2


@pytest.mark.parametrize("kernel", kernel_params(BASIC))
def test_not_stationary_and_vector_input(kernel):
    assert not kernel.is_stationary()
    assert kernel.requires_vector_input
    assert kernel.n_dims == len(kernel.hyperparameters)


# ----------------------------------------------------------------------------
# validation
# ----------------------------------------------------------------------------


@pytest.mark.parametrize("kernel", kernel_params(BASIC))
@pytest.mark.parametrize(
    "bad, match",
    [
        (np.array([[1.0], [-0.5]]), "X must be non-negative"),
        (np.array([[1.0], [np.nan]]), "X must be finite"),
        (np.array([[np.inf], [1.0]]), "X must be finite"),
        (np.array([[-np.inf]]), "X must be finite"),
        (np.ones((3, 2)), "X must have shape"),
        (np.ones((2, 1, 1)), "X must have shape"),
        ("abc", "X must be"),
    ],
)
def test_invalid_lags_raise(kernel, bad, match):
    with pytest.raises(ValueError, match=match):
        kernel(bad)
    with pytest.raises(ValueError, match=match):
        kernel.diag(bad)
    with pytest.raises(ValueError, match=match.replace("X", "Y")):
        kernel(X, bad)


def test_check_lags():
    column = np.array([[0.0], [2.5]])
    out = check_lags(column)
    np.testing.assert_array_equal(out, [0.0, 2.5])
    out[0] = 9.0
    assert column[0, 0] == 0.0  # a copy, never a view
    with pytest.raises(ValueError, match="lags must be non-negative"):
        check_lags([-1.0], name="lags")


@pytest.mark.parametrize("kernel", kernel_params(BASIC))
def test_gradient_with_Y_raises(kernel):
    with pytest.raises(ValueError, match="gradient"):
        kernel(X, Y, eval_gradient=True)


@pytest.mark.parametrize(
    "kernel, match",
    [
        (TC(alpha=0.0), "alpha"),
        (TC(alpha=1.5), "alpha"),
        (SS(alpha=-0.2), "alpha"),
        (SS(alpha=np.nan), "alpha"),
        (DC(alpha=1.01, beta=0.5), "alpha"),
        (DC(alpha=0.5, beta=-1.0), "beta"),
        (DC(alpha=0.5, beta=-1.5), "beta"),
        (DC(alpha=0.5, beta=np.nan), "beta"),
        (DC(alpha=0.5, beta=1.2), "beta"),
        (DC(alpha=0.5, beta=1.0 + 1e-12), "beta"),
        (DC(alpha=0.5, beta="0.5"), "beta"),
        (PK(alpha=0.0), "alpha"),
        (PK(omega=-0.3), "omega"),
        (PK(omega=0.0), "omega"),
        (PK(omega=np.inf), "omega"),
        (PK(sigma1=-1.0), "sigma1"),
        (PK(sigma1=0.0), "sigma1"),
        (PK(sigma2=-2.0), "sigma2"),
        (PK(sigma2=np.inf), "sigma2"),
    ],
)
def test_invalid_hyperparameters_raise_naming_the_argument(kernel, match):
    with pytest.raises(ValueError, match=match):
        kernel(X)
    with pytest.raises(ValueError, match=match):
        kernel(X, eval_gradient=True)
    with pytest.raises(ValueError, match=match):
        kernel.diag(X)


def test_boundary_values_are_accepted():
    # alpha = beta = 1 is the closed end of (0, 1]
    # (from lag 5 on: below, the interpolation reads the zeros before lag 0)
    later = np.array([[5.0], [7.0], [9.0]])
    K = DC(alpha=1.0, beta=1.0)(later)
    np.testing.assert_array_equal(K, np.ones_like(K))
    np.testing.assert_array_equal(TC(alpha=1.0)(later), np.ones((3, 3)))
    # between the ticks, a constant interpolates to itself; the bridge adds 0.1^2 sin^2
    between = np.array([[5.5], [8.25]])
    expected = np.ones((2, 2)) + np.diag(0.1**2 * np.sin(np.pi * np.array([0.5, 0.25])) ** 2)
    np.testing.assert_allclose(DC(alpha=1.0, beta=1.0)(between), expected, rtol=1e-12)


# ----------------------------------------------------------------------------
# PK in Hz
# ----------------------------------------------------------------------------


def test_pk_from_hz_round_trip():
    kernel = PK.from_hz(0.4, sample_time=0.1, alpha=0.97, sigma1=2.0)
    assert kernel.omega == pytest.approx(2 * np.pi * 0.4 * 0.1, rel=1e-15)
    assert kernel.frequency_hz(0.1) == pytest.approx(0.4, rel=1e-15)
    assert kernel.alpha == 0.97 and kernel.sigma1 == 2.0
    # the resonance appears in the kernel: g(t) = cos(omega t) with period 1/f seconds
    period_in_samples = 1.0 / (0.4 * 0.1)
    lags = np.array([[0.0], [period_in_samples]])
    K = PK.from_hz(0.4, 0.1, alpha=1.0, sigma2=3.0)(lags)
    np.testing.assert_allclose(K, np.ones((2, 2)), rtol=1e-12)
    for f, T in [(2.0, 0.1), (0.013, 2.5), (50.0, 1e-3)]:
        assert PK.from_hz(f, T).frequency_hz(T) == pytest.approx(f, rel=1e-14)
        assert PK(omega=1.1).frequency_hz(T) == pytest.approx(1.1 / (2 * np.pi * T), rel=1e-14)


def test_pk_frequency_bounds_conversion():
    kernel = PK.from_hz(2.0, 0.1, frequency_bounds=(1.5, 2.5))
    np.testing.assert_allclose(
        kernel.omega_bounds, (2 * np.pi * 1.5 * 0.1, 2 * np.pi * 2.5 * 0.1), rtol=1e-15
    )
    np.testing.assert_allclose(
        kernel.bounds[1], np.log([2 * np.pi * 0.15, 2 * np.pi * 0.25]), rtol=1e-14
    )
    fixed = PK.from_hz(2.0, 0.1, frequency_bounds="fixed")
    assert fixed.omega_bounds == "fixed"
    assert fixed.theta.shape == (3,)
    # default: the constructor's omega bounds
    assert PK.from_hz(2.0, 0.1).omega_bounds == PK().omega_bounds


@pytest.mark.parametrize(
    "frequency, sample_time, match",
    [
        (0.4, 0.0, "sample_time"),
        (0.4, -0.1, "sample_time"),
        (0.4, np.nan, "sample_time"),
        (0.0, 0.1, "frequency"),
        (-1.0, 0.1, "frequency"),
        (np.inf, 0.1, "frequency"),
    ],
)
def test_pk_from_hz_validation(frequency, sample_time, match):
    with pytest.raises(ValueError, match=match):
        PK.from_hz(frequency, sample_time)
