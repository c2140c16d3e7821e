"""Disturbance models on measured records: log evidence and 95 % measurement bands.

For each record, factor F = 3, order P = 200 per input, the first two thirds
for estimation (every third output sample, means subtracted) and the last
third for validation at every fast sample (:func:`gpmultirate.holdout.holdout_split`).
The prior is one ``C * DC`` per input, started at the optimum of
``FIRGaussianProcess(factor=3, order=200)`` (white noise) and then tuned
again, jointly with the noise model, by the dense formulas of
:mod:`gpmultirate.noise` (:func:`~gpmultirate.noise.dense_log_evidence`,
L-BFGS-B on the log hyperparameters from a few starts of the disturbance's
time scale).  Noise models compared:

* ``white``: ``WhiteKernel`` (today's model);
* ``white + matern12``: ``WhiteKernel() + C * Matern(nu=0.5)`` over the instants;
* ``white + matern32``: ``WhiteKernel() + C * Matern(nu=1.5)``;

each reported with its log evidence, its gain over white, the fitted
disturbance (level, time scale in fast samples), the validation fit, and the
share of measured samples inside the 95 % measurement band (posterior of the
output plus the variance of one noise sample, ``N(t, t)``): on the
validation third, and at the fast samples between the slow ones inside the
estimation span.  Run from the repository root::

    PYTHONPATH=. python benchmarks/disturbances.py [--records NAME ...]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings

import numpy as np
from scipy import optimize, stats
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

import gpmultirate as gm
from gpmultirate.datasets import load_cd_player_arm, load_robot_arm
from gpmultirate.holdout import holdout_split
from gpmultirate.metrics import fit_percent
from gpmultirate.noise import KernelNoise, dense_log_evidence, dense_posterior

FACTOR, ORDER, LEVEL = 3, 200, 0.95
RECORDS = {
    "robot arm": (load_robot_arm, None, None),
    "CD y1 <- u1, u2": (load_cd_player_arm, (0, 1), 0),
    "CD y2 <- u1, u2": (load_cd_player_arm, (0, 1), 1),
}
STARTS = (10.0, 100.0)  # time scales of the disturbance to start from, fast samples


def signals(name):
    load, inputs, output = RECORDS[name]
    data = load()
    u = data.u if inputs is None else data.u[:, list(inputs)]
    y = data.y if output is None else data.y[:, output]
    return u, y


def noise_kernel(choice: str, gamma: float, variance: float, length_scale: float):
    white = WhiteKernel(gamma, (1e-6 * variance, 10.0 * variance))
    if choice == "white":
        return white
    nu = {"white + matern12": 0.5, "white + matern32": 1.5}[choice]
    return white + ConstantKernel(0.1 * variance, (1e-6 * variance, 10.0 * variance)) * Matern(
        length_scale, (1.0, 1e4), nu=nu)


def tune(Phi, lags, y, kernel, noise: KernelNoise):
    """Maximize the dense log evidence over the kernel's and the noise's theta."""
    n_kernel = kernel.theta.shape[0]

    def objective(theta):
        k = kernel.clone_with_theta(theta[:n_kernel])
        n = noise.with_theta(theta[n_kernel:])
        K, dK = k(lags, eval_gradient=True)
        N, dN = n.matrix_with_gradient()
        try:
            value, grad = dense_log_evidence(Phi, K, y, N, dK, dN, eval_gradient=True)
        except np.linalg.LinAlgError:
            return np.inf, np.zeros_like(theta)
        return -value, -grad

    theta0 = np.concatenate([kernel.theta, noise.theta])
    bounds = np.vstack([kernel.bounds, noise.bounds])
    result = optimize.minimize(objective, np.clip(theta0, bounds[:, 0], bounds[:, 1]),
                               jac=True, method="L-BFGS-B", bounds=bounds,
                               options={"maxiter": 300})
    x = result.x
    return (-result.fun, kernel.clone_with_theta(x[:n_kernel]),
            noise.with_theta(x[n_kernel:]), result)


def coverage(model, split, K, mu, Sigma, noise_variance):
    """Validation fit, and band coverage on the validation third and between slow samples."""
    x = split.u if split.u.ndim == 2 else split.u[:, None]
    rows = np.arange(x.shape[0])
    T = model._fast_rows(x, rows)
    mean = T @ mu
    var = np.einsum("ij,jk,ik->i", T, Sigma, T) + noise_variance
    z = stats.norm.ppf(0.5 + LEVEL / 2)
    n_est = split.n_estimation
    # the full fast-rate record, centred as the estimation data
    y_all = np.concatenate([np.full(n_est, np.nan), split.y_validation - split.y_mean])
    inside = np.abs(y_all - mean) <= z * np.sqrt(var)
    validation = float(np.mean(inside[n_est:]))
    fit = fit_percent(split.y_validation, mean[n_est:] + split.y_mean)
    return fit, validation, mean, var, z


def run(name):
    u, y = signals(name)
    split = holdout_split(u, y, FACTOR, center=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        model = gm.FIRGaussianProcess(factor=FACTOR, order=ORDER).fit(split.u_estimation,
                                                                      split.y_slow)
    op = model.observation_
    Phi, lags, y_slow = op.matrix, op.lags, model.y_slow_
    K0 = model.kernel_(lags)
    if not np.allclose(K0, op.kernel_matrix(model.kernel_)):
        raise RuntimeError("the kernel over the lags differs from the observation's")
    instants = np.arange(0, split.n_estimation, FACTOR).astype(float)
    variance = float(np.var(y_slow))
    # between the slow samples inside the estimation span: the fast truth is known there
    y_fast_est = (y[: split.n_estimation] - split.y_mean)
    between = np.ones(split.n_estimation, bool)
    between[::FACTOR] = False
    rows = []
    for choice in ("white", "white + matern12", "white + matern32"):
        best = None
        starts = (None,) if choice == "white" else STARTS
        for scale in starts:
            noise = KernelNoise(noise_kernel(choice, model.noise_level_, variance, scale or 1.0),
                                instants)
            found = tune(Phi, lags, y_slow, model.kernel_, noise)
            print(f"    {name}, {choice}, start {scale}: {found[0]:.2f} after "
                  f"{found[3].nit} iterations", flush=True)
            if best is None or found[0] > best[0]:
                best = found
        value, kernel, noise, result = best
        K = kernel(lags)
        N = noise.matrix()
        mu, Sigma = dense_posterior(Phi, K, y_slow, N)
        fit, validation, mean, var, z = coverage(model, split, K, mu, Sigma,
                                                 noise.sample_variance())
        inside_between = np.abs(y_fast_est - mean[: split.n_estimation]) <= z * np.sqrt(
            var[: split.n_estimation])
        params = noise.kernel.get_params()
        disturbance = ""
        if choice != "white":
            disturbance = (f"sigma^2 = {params['k2__k1__constant_value']:.3g}, "
                           f"length {params['k2__k2__length_scale']:.3g}")
        rows.append({
            "record": name, "noise": choice, "log evidence": value,
            "estimator evidence": model.log_marginal_likelihood_value_,
            "white level": noise.level, "disturbance": disturbance,
            "fit": fit, "coverage validation": validation,
            "coverage between": float(np.mean(inside_between[between])),
            "converged": bool(result.success),
        })
    white = rows[0]["log evidence"]
    for row in rows:
        row["gain"] = row["log evidence"] - white
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--records", nargs="+", default=list(RECORDS), choices=list(RECORDS),
                        metavar="NAME")
    args = parser.parse_args(argv)
    print(f"gpmultirate {gm.__version__}; factor {FACTOR}, order {ORDER} per input, "
          f"{100 * LEVEL:g} % measurement band")
    header = ("record", "noise", "log evidence", "gain", "white level", "disturbance", "fit",
              "coverage validation", "coverage between", "converged")
    print(" | ".join(header))
    for name in args.records:
        start = time.perf_counter()
        for row in run(name):
            print(" | ".join(
                f"{row[h]:.4g}" if isinstance(row[h], float) else str(row[h]) for h in header))
        print(f"  ({name}: {time.perf_counter() - start:.0f} s; the estimator's own white "
              f"evidence {row['estimator evidence']:.1f})", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
