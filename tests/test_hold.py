"""The prior between integer lags against independent computations.

* the held pulse response of continuous-time state-space models, integrated
  numerically (``scipy.integrate.quad``), against its interpolation from the
  integer lags;
* the two routes of readings between the ticks (exact and interpolated) against
  each other and the bridge written out;
* the prior's covariance at real lags against Monte Carlo draws of the
  construction (integer-lag values, interpolated, plus the bridge).
"""

import numpy as np
import pytest
from scipy import integrate, signal
from sklearn.gaussian_process.kernels import ConstantKernel as C

from gpmultirate.kernels import DC, PK, SS, TC, observe
from gpmultirate.kernels.hold import BRIDGE_SCALE, hold_weights
from gpmultirate.observations import InterpolatedConvolution, TimedConvolution
from test_kernels import finite_difference_gradient


def _mode(samples_per_period, damping=0.05):
    """A lightly damped continuous-time mode, time in fast periods: ``w^2 / (s^2 + 2 z w s + w^2)``."""
    w = 2 * np.pi / samples_per_period
    return signal.lti([w * w], [1.0, 2 * damping * w, w * w])


def _held(system, tau):
    """``g(tau) = integral over [tau - 1, tau] of h``, ``h`` zero before 0 (quadrature)."""
    ss = system.to_ss()
    values, vectors = np.linalg.eig(ss.A)
    left = (ss.C @ vectors)[0]
    right = np.linalg.solve(vectors, ss.B[:, 0])

    def h(r):  # C e^(A r) B by the modes
        return float(np.real(np.sum(left * np.exp(values * r) * right)))

    low = max(tau - 1.0, 0.0)
    return integrate.quad(h, low, tau, epsabs=1e-13, epsrel=1e-11, limit=200)[0]


@pytest.mark.parametrize("samples_per_period, bound", [(3, 0.04), (4, 0.02), (5, 0.012), (20, 0.002)])
def test_interpolation_of_the_held_response_of_a_mode(samples_per_period, bound):
    # away from lag 0 (where h starts and g has kinks at 0 and 1), the twelve-node
    # interpolation of g from its integer lags errs by at most ``bound`` of g's rms
    system = _mode(samples_per_period)
    lags = np.arange(0, 40)
    at_ticks = np.array([_held(system, float(n)) for n in lags])
    rng = np.random.default_rng(4)
    real = np.sort(rng.uniform(6.0, 30.0, 15))
    W, size = hold_weights(real)
    interpolated = W @ at_ticks[:size]
    truth = np.array([_held(system, t) for t in real])
    rms = np.sqrt(np.mean(at_ticks**2))
    error = np.sqrt(np.mean((interpolated - truth) ** 2)) / rms
    assert error < bound
    # with the start at lag 0 (where h starts) included, the bridge's size, BRIDGE_SCALE of
    # the prior's std at mid-cell, covers the error down to 3 fast samples per period
    everywhere = np.sort(rng.uniform(0.0, 30.0, 30))
    W, size = hold_weights(everywhere)
    truth = np.array([_held(system, t) for t in everywhere])
    assert np.sqrt(np.mean((W @ at_ticks[:size] - truth) ** 2)) / rms < BRIDGE_SCALE / 2


@pytest.mark.parametrize("time_constant", [1.5, 12.0])
def test_interpolation_of_a_first_order_response_with_its_kinks(time_constant):
    # h(0) != 0: g has kinks at lags 0 and 1 that no polynomial follows; the error (2-8 %
    # of the rms, mostly near the start) stays inside the bridge's size
    system = signal.lti([1 / time_constant], [1.0, 1 / time_constant])
    at_ticks = np.array([_held(system, float(n)) for n in range(60)])
    lags = np.sort(np.random.default_rng(6).uniform(0.0, 40.0, 30))
    W, size = hold_weights(lags)
    truth = np.array([_held(system, t) for t in lags])
    error = np.sqrt(np.mean((W @ at_ticks[:size] - truth) ** 2)) / np.sqrt(np.mean(at_ticks**2))
    assert error < BRIDGE_SCALE


def test_hold_weights_are_the_interpolated_route_rows():
    # the interpolated readings' regressor is the hold's weights (cut at order - 1) applied to
    # the fast regressor rows, point by point: the two routes share the prior on the lags
    rng = np.random.default_rng(1)
    u = rng.standard_normal(80)
    P = 20
    times = np.array([14.3, 30.0, 47.65, 61.2, 78.9])
    timed = TimedConvolution(u, times, P, exposure=0.7, latency=0.15)
    matrix = InterpolatedConvolution(timed).matrix
    xi, w = np.polynomial.legendre.leggauss(16)
    for m, t in enumerate(times):
        end, start = t - 0.15, t - 0.85
        edges = [start] + [k for k in range(int(np.ceil(start)), int(np.ceil(end)))
                           if start < k < end] + [end]
        row = np.zeros(P)
        for a, b in zip(edges[:-1], edges[1:]):
            for x, weight in zip(a + (b - a) * (xi + 1) / 2, w * (b - a) / 2 / 0.7):
                tick = int(np.floor(x))
                lags = x - np.arange(tick + 1)  # the input u[j], j <= tick, at lag x - j
                inside = lags < P
                W, _ = hold_weights(lags[inside], order=P)
                row += weight * (u[:tick + 1][inside] @ W.toarray())
        np.testing.assert_allclose(matrix[m], row, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("kernel", [C(2.0) * DC(0.85, 0.6), TC(0.8), SS(0.9)],
                         ids=["DC", "TC", "SS"])
def test_the_exact_route_is_the_interpolated_one_plus_the_bridge(kernel):
    rng = np.random.default_rng(2)
    u = rng.standard_normal(90)
    times = np.arange(20, 90, 3) + rng.uniform(0, 1, len(range(20, 90, 3)))
    P = 25
    timed = TimedConvolution(u, times, P, exposure=0.4)
    exact = observe(kernel, timed).covariance()
    interpolated = observe(kernel, InterpolatedConvolution(timed)).covariance()
    # the bridge: independent on each cell n, sin(pi d) shaped, BRIDGE_SCALE^2 k(n, n)
    xi, w = np.polynomial.legendre.leggauss(16)
    diagonal = np.diag(kernel(np.arange(P, dtype=float)[:, None]))
    Psi = np.zeros((times.shape[0], P))
    for m, t in enumerate(times):
        start, end = t - 0.4, t
        edges = [start] + [k for k in range(int(np.ceil(start)), int(np.ceil(end)))
                           if start < k < end] + [end]
        for a, b in zip(edges[:-1], edges[1:]):
            for x, weight in zip(a + (b - a) * (xi + 1) / 2, w * (b - a) / 2 / 0.4):
                tick = int(np.floor(x))
                for n in range(min(P, tick + 1)):
                    Psi[m, n] += weight * np.sin(np.pi * (x - tick)) * u[tick - n]
    bridge = Psi @ np.diag(BRIDGE_SCALE**2 * diagonal) @ Psi.T
    np.testing.assert_allclose(exact, interpolated + bridge, rtol=1e-10,
                               atol=1e-12 * np.abs(exact).max())


def test_real_lag_covariance_is_that_of_the_construction_monte_carlo():
    # draws of g at integer lags from K, interpolated, plus independent bridges: their
    # sample covariance at real lags is the kernel's (within its Monte Carlo error)
    kernel = DC(0.9, 0.7)
    rng = np.random.default_rng(3)
    lags = np.array([0.5, 2.25, 2.75, 6.4, 11.9])
    W, size = hold_weights(lags)
    K = kernel(np.arange(size, dtype=float)[:, None])
    root = np.linalg.cholesky(K + 1e-13 * np.eye(size))
    runs = 40000
    g = root @ rng.standard_normal((size, runs))
    whole = np.floor(lags).astype(int)
    bridge_std = BRIDGE_SCALE * np.sqrt(np.diag(K))
    cells = rng.standard_normal((size, runs)) * bridge_std[:, None]
    draws = W @ g + np.sin(np.pi * (lags - whole))[:, None] * cells[whole]
    empirical = draws @ draws.T / runs
    expected = kernel(lags[:, None])
    # the standard error of a sample covariance is about sqrt((K_ii K_jj + K_ij^2) / runs)
    error = np.sqrt((np.outer(np.diag(expected), np.diag(expected)) + expected**2) / runs)
    assert np.all(np.abs(empirical - expected) < 5 * error)


def test_pk_keeps_its_formula_between_integer_lags():
    # the held response of one damped mode is a damped sinusoid of the same frequency:
    # PK's basis at real lags is already the hold's, and it is not interpolated
    kernel = PK(alpha=0.9, omega=1.2, sigma1=0.7, sigma2=0.4)
    lags = np.array([0.3, 2.5, 7.75])
    c = 0.9 ** (lags / 2) * np.cos(1.2 * lags)
    s = 0.9 ** (lags / 2) * np.sin(1.2 * lags)
    np.testing.assert_allclose(kernel(lags[:, None]),
                               0.49 * np.outer(c, c) + 0.16 * np.outer(s, s), rtol=1e-12)


@pytest.mark.parametrize("samples_per_period, damping", [(3.0, 0.02), (12.0, 0.05), (80.0, 0.3)])
def test_pk_with_hold_is_the_held_response_of_a_mode_at_every_real_lag(samples_per_period,
                                                                        damping):
    # one mode of a continuous-time plant behind the hold, integrated numerically: from lag
    # 1 on a damped sinusoid (PK's basis), on [0, 1) its step response, zero at lag 0
    system = _mode(samples_per_period, damping)
    w = 2 * np.pi / samples_per_period
    rate, omega = damping * w, w * np.sqrt(1 - damping**2)
    lags = np.concatenate([[0.0, 1e-3, 0.2, 0.5, 0.8, 0.999], 1.0 + np.linspace(0.0, 9.0, 37)])
    held = np.array([_held(system, t) for t in lags])
    kernel = PK(alpha=np.exp(-2 * rate), omega=omega, hold=True)
    c, s = kernel.basis(lags)
    # the held response is a fixed combination of the two basis functions
    coef, *_ = np.linalg.lstsq(np.column_stack([c, s]), held, rcond=None)
    np.testing.assert_allclose(np.column_stack([c, s]) @ coef, held,
                               atol=1e-9 * np.abs(held).max())
    assert c[0] == 0.0 and s[0] == 0.0
    # the paper's basis does not hold on the first cell: nonzero at lag 0
    plain = PK(alpha=np.exp(-2 * rate), omega=omega).basis(lags)
    coef, *_ = np.linalg.lstsq(np.column_stack(plain), held, rcond=None)
    assert np.abs(np.column_stack(plain) @ coef - held).max() > 1e-3 * np.abs(held).max()


@pytest.mark.parametrize("spread", [(0.0, 0.0), (0.04, 0.01)])
def test_pk_with_hold_gradients_at_real_lags_by_central_differences(spread):
    kernel = PK(alpha=0.85, omega=1.3, sigma1=0.8, sigma2=1.4, omega_std=spread[0],
                rate_std=spread[1], hold=True)
    X = np.array([0.0, 0.1, 0.45, 0.9, 1.0, 1.3, 2.0, 4.75])[:, None]
    K, dK = kernel(X, eval_gradient=True)
    np.testing.assert_allclose(dK, finite_difference_gradient(kernel, X, step=1e-6), atol=1e-8)
    np.testing.assert_allclose(kernel.diag(X), np.diag(K), rtol=1e-12)
    # the spread is the first-order change of the held basis with the frequency and decay
    if any(spread):
        rate, omega = -0.5 * np.log(0.85), 1.3
        (c, s), (c1, s1) = kernel.basis_derivatives(X[:, 0], 1)
        h = 1e-6
        moved = [PK(alpha=np.exp(-2 * (rate - h * a)), omega=omega, hold=True).basis(X[:, 0])
                 for a in (1, -1)]
        # d/dlambda along the real axis: lambda = -rate + i omega
        np.testing.assert_allclose((moved[0][0] - moved[1][0]) / (2 * h), c1, atol=1e-7)
        np.testing.assert_allclose((moved[0][1] - moved[1][1]) / (2 * h), s1, atol=1e-7)


def test_pk_hold_is_checked_and_shown():
    assert repr(PK(alpha=0.5, omega=2.0, hold=True)) == (
        "PK(alpha=0.5, omega=2, sigma1=1, sigma2=1, hold=True)")
    with pytest.raises(ValueError, match="hold"):
        PK(hold="yes")(np.array([[0.0]]))


def test_impulse_response_between_the_ticks_interpolates_the_fitted_coefficients():
    # a fit on the ticks: the posterior mean at real lags is the interpolation of the
    # mean at integer lags (the bridge has mean zero), its variance at least the
    # interpolation's plus the bridge's
    import gpmultirate as gm

    rng = np.random.default_rng(5)
    u = rng.standard_normal(300)
    g = 0.85 ** np.arange(30) * np.cos(0.6 * np.arange(30))
    y = np.convolve(u, g)[:300][::3] + 0.01 * rng.standard_normal(100)
    model = gm.FIRGaussianProcess(C(1.0) * DC(0.85, 0.7), factor=3, order=30,
                                  optimizer=None, noise_level=1e-4).fit(u, y)
    lags = np.array([2.5, 7.3, 15.8])
    mean, std = model.impulse_response(lags, return_std=True)
    W, size = hold_weights(lags)
    on_ticks = model.impulse_response(np.arange(size, dtype=float))
    np.testing.assert_allclose(mean, W @ on_ticks, rtol=1e-8, atol=1e-10)
    bridge = BRIDGE_SCALE * np.sin(np.pi * (lags % 1.0)) * np.sqrt(
        np.diag(model.kernel_(np.floor(lags)[:, None])))
    assert np.all(std >= bridge * (1 - 1e-9))
