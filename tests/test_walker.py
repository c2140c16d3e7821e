"""One walker over the kernel algebra: the observation decides what it asks of each leaf.

On the integer lags a structured kernel answers through ``observed``, for
readings at their own instants through ``observed_at_instants``; sums and
constant multiples are the walker's, for both.  Each check compares with the
dense formula (the kernel at the readings' real lags), not with the route
under test.
"""

from __future__ import annotations

import numpy as np
from sklearn.gaussian_process.kernels import Product, Sum, RBF, Hyperparameter, Kernel
from sklearn.gaussian_process.kernels import ConstantKernel as C

from gpmultirate.kernels import DC, PK, StructuredKernel, TC, observe
from gpmultirate.kernels.instants import DenseTimedTerm
from gpmultirate.kernels.lag import ShiftScaledKernel
from gpmultirate.observations import InterpolatedConvolution
from gpmultirate.kernels.structure import ProductTerm, ScaledTerm, SumTerm
from gpmultirate.observations import SampledConvolution, TimedConvolution

RNG = np.random.default_rng(7)
U = RNG.standard_normal(60)
TIMES = np.sort(RNG.uniform(10, 59, 15))


def dense_readings_covariance(kernel, u, times, order):
    """Without exposure: reading ``m`` is ``sum_j u[floor(t) - j] g(t - floor(t) + j)``."""
    if isinstance(kernel, Sum):
        return (dense_readings_covariance(kernel.k1, u, times, order)
                + dense_readings_covariance(kernel.k2, u, times, order))
    if isinstance(kernel, Product) and isinstance(kernel.k1, C):
        return kernel.k1.constant_value * dense_readings_covariance(kernel.k2, u, times, order)
    rows, lags = [], []
    for t in times:
        tick = int(np.floor(t))
        rows.append([u[tick - j] if tick - j >= 0 else 0.0 for j in range(order)])
        lags.append(np.arange(order) + (t - tick))
    rows, lags = np.array(rows), np.array(lags)
    M = len(times)
    S = np.empty((M, M))
    if isinstance(kernel, ShiftScaledKernel):
        # between integer lags the hold's prior: Lagrange on the lags n - 5 .. n + 6,
        # zero below lag 0, the nodes cut at order - 1
        maps = [_interpolation(lag, order) for lag in lags]
        K = kernel(np.arange(order, dtype=float)[:, None])
        # the bridge: independent on each cell, 0.1^2 sin(pi d)^2 k(n, n), the same d for
        # every lag of one reading
        bridge = [rows[a] * np.sin(np.pi * (lags[a][0] % 1.0)) for a in range(M)]
        v = 0.1**2 * np.diag(K)
        return np.array([[rows[a] @ maps[a] @ K @ maps[b].T @ rows[b]
                          + bridge[a] @ (v * bridge[b]) for b in range(M)] for a in range(M)])
    for a in range(M):
        for b in range(M):
            S[a, b] = rows[a] @ kernel(lags[a][:, None], lags[b][:, None]) @ rows[b]
    return S


def _interpolation(lags, order):
    """The map from ``g(0..order-1)`` to ``g(lags)`` of the hold's prior, term by term."""
    out = np.zeros((len(lags), order))
    for i, x in enumerate(lags):
        n = int(np.floor(x))
        nodes = [n + s for s in range(-5, 7) if n + s <= order - 1]
        for node in nodes:
            weight = np.prod([(x - o) / (node - o) for o in nodes if o != node])
            if node >= 0:
                out[i, node] += weight
    return out


class Exponential(StructuredKernel, Kernel):
    """``k(t, s) = pole^(t + s)``, rank one, with a timed term of its own (the example's)."""

    def __init__(self, pole=0.8, pole_bounds=(1e-3, 1.0)):
        self.pole = pole
        self.pole_bounds = pole_bounds

    @property
    def hyperparameter_pole(self):
        return Hyperparameter("pole", "numeric", self.pole_bounds)

    def __call__(self, X, Y=None, eval_gradient=False):
        x = np.asarray(X, dtype=float)[:, 0]
        y = x if Y is None else np.asarray(Y, dtype=float)[:, 0]
        K = self.pole ** np.add.outer(x, y)
        if eval_gradient:
            return K, (np.add.outer(x, y) * K)[:, :, None]
        return K

    def diag(self, X):
        return np.diag(self(X))

    def is_stationary(self):
        return False

    asked = []

    def observed_at_instants(self, observation, path=""):
        Exponential.asked.append(path)
        return DenseTimedTerm(self, observation, path)


def test_a_kernel_answers_for_timed_readings_with_one_method():
    Exponential.asked.clear()
    kernel = C(2.0) * Exponential(0.8) + C(0.5) * TC(0.9)
    timed = TimedConvolution(U, TIMES, order=12)
    S = timed.covariance(kernel)
    assert Exponential.asked == ["k1__k2__"]
    np.testing.assert_allclose(S, dense_readings_covariance(kernel, U, TIMES, 12),
                               rtol=1e-10, atol=1e-12)


def test_the_walker_keeps_sums_and_constants_and_asks_the_leaves():
    timed = TimedConvolution(U, TIMES, order=12)
    term = observe(C(2.0) * DC(0.8, 0.6) + RBF(2.0) * TC(0.9), timed)
    assert isinstance(term, SumTerm)
    assert isinstance(term.first, ScaledTerm)
    # DC answers on the integer lags: the readings' rows by the hold's interpolation
    assert isinstance(term.first.inner.inner.observation, InterpolatedConvolution)
    assert isinstance(term.second, DenseTimedTerm)  # a product needs a regressor
    ticks = SampledConvolution(U, np.arange(10, 59, 3), order=12)
    assert isinstance(observe(RBF(2.0) * TC(0.9), ticks), ProductTerm)


def test_a_subclass_of_a_lag_kernel_keeps_its_timed_term():
    class Mine(DC):
        pass

    timed = TimedConvolution(U, TIMES, order=12)
    kernel = Mine(0.8, -0.5)
    assert observe(kernel, timed).inner.observation is timed.on_integer_lags()
    np.testing.assert_allclose(timed.covariance(kernel),
                               dense_readings_covariance(kernel, U, TIMES, 12),
                               rtol=1e-10, atol=1e-12)


def test_the_cross_covariance_walks_the_same_terms():
    lags = np.array([0.25, 3.5, 7.75])
    kernel = C(1.7) * DC(0.85, 0.5) + PK(0.9, 0.7)
    # at the instants: Cov(g(l), y_m) = sum_j u[tick_m - j] k(l, j + offset_m), with the
    # readings' lags j + offset_m of DC seen through the order's interpolation (cut at 11)
    timed = TimedConvolution(U, TIMES, order=12)
    expected = np.empty((3, TIMES.shape[0]))
    integer = np.arange(12.0)[:, None]
    for m, t in enumerate(TIMES):
        tick = int(np.floor(t))
        row = np.array([U[tick - j] if tick >= j else 0.0 for j in range(12)])
        at = (np.arange(12) + t - tick)
        held = _interpolation(at, 12)
        dc, pk = kernel.k1, kernel.k2
        bridge = (0.1**2 * 1.7 * np.sin(np.pi * (lags[:, None] % 1.0))
                  * np.sin(np.pi * (t - tick)) * (np.floor(lags)[:, None] == integer[:, 0])
                  * 0.85 ** integer[:, 0])
        expected[:, m] = (dc(lags[:, None], integer) @ held.T + bridge
                          + pk(lags[:, None], at[:, None])) @ row
    np.testing.assert_allclose(timed.cross_covariance(kernel, lags), expected, rtol=1e-10,
                               atol=1e-12 * np.abs(expected).max())
    # with an exposure, each summand's term adds its own correction at the kink
    timed = TimedConvolution(U, TIMES, order=12, exposure=0.6)
    parts = (1.7 * timed.cross_covariance(DC(0.85, 0.5), lags)
             + timed.cross_covariance(PK(0.9, 0.7), lags))
    np.testing.assert_allclose(timed.cross_covariance(kernel, lags), parts, rtol=1e-13)
