"""The disturbance option of the estimator on measured records: the table of the disturbances page.

For each record (DaISy robot arm; CD-player arm, outputs 1 and 2 with both
inputs), factor F = 3, the first two thirds for estimation (every third
output sample, means subtracted, :func:`gpmultirate.holdout.holdout_split`)
and the last third for validation at every fast sample, the defaults
(``kernel="auto"``, the default order) are fitted with each
``noise_kernel``; reported are the log evidence, the chosen noise, the
validation fit, the share of validation samples inside the 95 % measurement
band (``predict(u, return_std=True, include_noise=True)``), the share of the
fast samples between the slow ones inside the estimation span inside it,
and the fit time.  Run from the repository root::

    PYTHONPATH=. python benchmarks/disturbances_estimator.py [--noise white auto ...]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings

import numpy as np
from scipy import stats

import gpmultirate as gm
from gpmultirate.holdout import holdout_split
from gpmultirate.metrics import fit_percent

from disturbances import FACTOR, LEVEL, RECORDS, signals  # noqa: E402


def run(name: str, noise: str) -> dict:
    u, y = signals(name)
    split = holdout_split(u, y, FACTOR, center=True)
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = gm.FIRGaussianProcess(kernel="auto", factor=FACTOR, noise_kernel=noise).fit(
            split.u_estimation, split.y_slow)
    seconds = time.perf_counter() - start
    mean, std = model.predict(split.u, return_std=True, include_noise=True)
    z = stats.norm.ppf(0.5 + LEVEL / 2)
    n_est = split.n_estimation
    inside = np.abs(split.y_validation - split.y_mean - mean[n_est:]) <= z * std[n_est:]
    between = np.ones(n_est, bool)
    between[::FACTOR] = False
    y_est = y[:n_est] - split.y_mean
    inside_est = np.abs(y_est - mean[:n_est]) <= z * std[:n_est]
    return {"record": name, "noise": noise,
            "chosen": "white" if isinstance(model.noise_kernel_, str) else str(
                model.noise_kernel_),
            "log evidence": float(model.log_marginal_likelihood_value_),
            "fit": fit_percent(split.y_validation, mean[n_est:] + split.y_mean),
            "coverage validation": float(np.mean(inside)),
            "coverage between": float(np.mean(inside_est[between])),
            "seconds": seconds}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--records", nargs="+", default=list(RECORDS), choices=list(RECORDS),
                        metavar="NAME")
    parser.add_argument("--noise", nargs="+", default=["white", "auto"], metavar="NOISE")
    args = parser.parse_args(argv)
    header = ("record", "noise", "chosen", "log evidence", "fit", "coverage validation",
              "coverage between", "seconds")
    print(" | ".join(header))
    for name in args.records:
        for noise in args.noise:
            row = run(name, noise)
            print(" | ".join(f"{row[h]:.4g}" if isinstance(row[h], float) else str(row[h])
                             for h in header), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
