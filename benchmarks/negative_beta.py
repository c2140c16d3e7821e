"""DC with a negative correlation beta: speed of the fast paths and fits to measured data.

Run ``python benchmarks/negative_beta.py``.  Two parts:

1. The evidence gradient's expensive step, ``S = Phi K Phi^T`` with the
   contraction ``tr(W Phi dK_j Phi^T)``, for ``C * DC(alpha, beta)`` with
   ``beta = +0.6`` and ``-0.6`` on the route the library picks (diagonal
   recursion at the paper's size and at P = N = 3000, filters for a short
   FIR on a long record), against the plain dense reference (``K`` and
   scikit-learn's gradient array, ``Phi`` from the observation) in the same
   run.  Printed: min / median / max seconds of ``REPEATS`` runs and the
   ratio of the medians.  A negative ``beta`` must take the same route at
   the same cost as a positive one.
2. The robot arm and CD-player arm (DaISy), slow outputs every third
   sample: ``C * DC`` tuned with ``beta`` in ``(-1, 1)`` against ``(1e-4, 1)``
   (the former range), with the tuned ``beta``, the log evidence and the
   validation goodness of fit on the last quarter of each record.
"""

from __future__ import annotations

import os
import time
import warnings

import numpy as np

REPEATS = 5


def timed(function):
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return np.array(times)


def route_timings(n_samples, factor, order, seed=0):
    from sklearn.gaussian_process.kernels import ConstantKernel as C

    from gpmultirate import DownsampledConvolution
    from gpmultirate.kernels import DC, observe

    rng = np.random.default_rng(seed)
    op = DownsampledConvolution(rng.standard_normal(n_samples), factor, order)
    W = rng.standard_normal((op.n_outputs, op.n_outputs))
    W += W.T
    Phi = op.matrix
    lags = op.lags
    rows = []
    for beta in (0.6, -0.6):
        kernel = C(1.3) * DC(alpha=0.99, beta=beta)
        term = observe(kernel, op)
        route = "filters" if term.inner._sampling(True) is None else "recursion"

        def fast():
            S, contract = term.covariance_with_contractor()
            return S, contract(W)

        def dense():
            K, dK = kernel(lags, eval_gradient=True)
            S = Phi @ K @ Phi.T
            A = Phi.T @ W @ Phi
            return S, A.reshape(-1) @ dK.reshape(-1, dK.shape[2])

        S_fast, g_fast = fast()
        S_dense, g_dense = dense()
        error = max(
            np.abs(S_fast - S_dense).max() / np.abs(S_dense).max(),
            np.abs(g_fast - g_dense).max() / np.abs(g_dense).max(),
        )
        rows.append((beta, route, timed(fast), timed(dense), error))
    return rows


def measured_fits():
    from sklearn.gaussian_process.kernels import ConstantKernel as C

    import gpmultirate as gm
    from gpmultirate.datasets import load_cd_player_arm, load_robot_arm
    from gpmultirate.kernels import DC

    factor, order = 3, 100
    robot, cd = load_robot_arm(), load_cd_player_arm()
    cases = [
        ("robot arm", np.asarray(robot.u), np.asarray(robot.y), 768),
        ("CD arm y1", np.asarray(cd.u), np.asarray(cd.y[:, 0]), 1536),
        ("CD arm y2", np.asarray(cd.u), np.asarray(cd.y[:, 1]), 1536),
    ]
    for name, u, y, n_est in cases:
        u_est, y_est, u_val, y_val = u[:n_est], y[:n_est], u[n_est:], y[n_est:]
        u_mean, y_mean = u_est.mean(axis=0), y_est.mean()
        for label, bounds in (("(-0.9999, 0.9999)", (-0.9999, 0.9999)), ("(1e-4, 1)", (1e-4, 1.0))):
            kernel = C(1.0) * DC(0.9, 0.5, beta_bounds=bounds)
            if u.ndim > 1:
                kernel = [kernel, kernel]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                model = gm.FIRGaussianProcess(
                    kernel, factor=factor, order=order, initial_conditions="discard"
                ).fit(u_est - u_mean, (y_est - y_mean)[::factor])
            fitted = model.kernel_
            leaves = fitted.kernels if hasattr(fitted, "kernels") else [fitted]
            betas = ", ".join(f"{leaf.k2.beta:+.4f}" for leaf in leaves)
            predicted = model.predict(u_val - u_mean) + y_mean
            gof = gm.goodness_of_fit(y_val[order:], predicted[order:])
            print(f"{name:10s} beta_bounds {label:18s} beta {betas:18s} "
                  f"log evidence {model.log_marginal_likelihood_value_:9.2f}  GoF {gof:7.3f} %")


def main():
    print(f"load average {os.getloadavg()[0]:.2f} (1 min) on {os.cpu_count()} cores; "
          f"{REPEATS} repeats, seconds min / median / max")
    print(f"{'N':>5} {'F':>2} {'P':>5} {'beta':>5} {'route':>9}   {'fast':>22}   {'dense':>22}  "
          f"{'ratio':>6}  rel. error")
    for n, factor, order in ((600, 3, 600), (6000, 20, 200), (3000, 3, 3000)):
        for beta, route, fast, dense, error in route_timings(n, factor, order):
            def show(t):
                return f"{t.min():6.3f} /{np.median(t):6.3f} /{t.max():6.3f}"

            print(f"{n:5d} {factor:2d} {order:5d} {beta:+5.1f} {route:>9}   {show(fast)}   "
                  f"{show(dense)}  {np.median(dense) / np.median(fast):6.1f}  {error:.1e}")
    print()
    measured_fits()
    print(f"load average {os.getloadavg()[0]:.2f} (1 min)")


if __name__ == "__main__":
    main()
