"""The default noise model on simulated records with a coloured disturbance.

Paper-like systems (:func:`gpmultirate.simulation.paper_system`, parameters
perturbed by 10 %, fast sample time 0.1 s), N = 600 fast samples of a
multisine, factor 3, plus an AR(1) disturbance with pole 0.99 at the fast
rate scaled to 20 dB below the output (``var(y) / var(v) = 100``), sampled
with the output.  Each run is fitted with the defaults (``kernel`` default,
the default order) and ``noise_kernel`` white and auto.  Reported per noise
model, over the runs: the share of the true impulse response (lags
``0..P-1``) inside the 95 % band of ``impulse_response(return_std=True)``,
and the goodness of fit on a noise-free validation multisine.  Run from the
repository root::

    PYTHONPATH=. python benchmarks/disturbance_simulation.py [--runs 20]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings

import numpy as np

import gpmultirate as gm
from gpmultirate.simulation import multisine, paper_system

N_SAMPLES, FACTOR, POLE, SNR_DB, SAMPLE_TIME = 600, 3, 0.99, 20.0, 0.1
Z95 = 1.959964


def ar1(n: int, pole: float, rng) -> np.ndarray:
    """A stationary AR(1) sequence of unit variance."""
    e = rng.standard_normal(n)
    v = np.empty(n)
    v[0] = e[0]
    scale = np.sqrt(1.0 - pole**2)
    for k in range(1, n):
        v[k] = pole * v[k - 1] + scale * e[k]
    return v


def simulated_run(seed: int):
    """``(u, y_slow, true impulse response of N lags, u_val, y_val)`` of one run."""
    rng = np.random.default_rng(seed)
    system = paper_system(SAMPLE_TIME, perturbation=0.1, random_state=rng)
    u = multisine(N_SAMPLES, SAMPLE_TIME, random_state=rng)
    u_val = multisine(N_SAMPLES, SAMPLE_TIME, random_state=rng)
    y = system.simulate(u)
    v = ar1(N_SAMPLES, POLE, rng) * np.sqrt(np.var(y) / 10 ** (SNR_DB / 10))
    impulse = np.zeros(N_SAMPLES)
    impulse[0] = 1.0
    return u, (y + v)[::FACTOR], system.simulate(impulse), u_val, system.simulate(u_val)


def score(seed: int, noise_kernel: str) -> dict:
    u, y_slow, g, u_val, y_val = simulated_run(seed)
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = gm.FIRGaussianProcess(factor=FACTOR, sample_time=SAMPLE_TIME,
                                      noise_kernel=noise_kernel).fit(u, y_slow)
    seconds = time.perf_counter() - start
    mean, std = model.impulse_response(return_std=True)
    truth = g[: mean.shape[0]]
    return {"coverage": float(np.mean(np.abs(truth - mean) <= Z95 * std)),
            "gof": float(model.score(u_val, y_val)), "seconds": seconds,
            "coloured": not isinstance(model.noise_kernel_, str)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--noise", nargs="+", default=["white", "auto"])
    args = parser.parse_args(argv)
    print("noise | runs | chose a disturbance | impulse-response band coverage (mean, min) | "
          "GoF % (mean) | seconds (mean)")
    for noise in args.noise:
        rows = [score(seed, noise) for seed in range(args.runs)]
        coverage = np.array([r["coverage"] for r in rows])
        print(f"{noise} | {args.runs} | {sum(r['coloured'] for r in rows)} | "
              f"{coverage.mean():.3f}, {coverage.min():.3f} | "
              f"{np.mean([r['gof'] for r in rows]):.2f} | "
              f"{np.mean([r['seconds'] for r in rows]):.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
