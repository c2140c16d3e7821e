"""Example 1 of the paper: slow-rate data cannot tell fast-rate models apart.

A fast-rate FIR model ``g`` of order ``P`` seen through a downsampler gives the
slow output ``y_slow = Phi g`` (eq. 8), with ``Phi`` of shape ``(M, P)``.  When
``P >= M`` the regressor has a null space: adding any vector of it to ``g``
changes the fast-rate response (its FRF above the slow Nyquist frequency, its
intersample output) but leaves every slow sample unchanged.  This script

1. reproduces Fig. 2 of the paper: three impulse responses with identical slow
   outputs and different fast-rate FRFs (:func:`gpmultirate.study.nonidentifiable_example`);
2. shows that :class:`gpmultirate.LeastSquaresFIR` refuses such problems with an
   :class:`gpmultirate.IdentifiabilityError` instead of returning one arbitrary
   solution: once for the impulsive input of Example 1 (``order >= M``, Lemma 1)
   and once for a zero-order-hold input (rank-deficient ``Phi`` even with
   ``order < M``, Lemma 2);
3. shows that a Gaussian-process prior makes the same impulsive-input problem
   well posed: :class:`gpmultirate.FIRGaussianProcess` returns a unique estimate.

Run ``python examples/example1_nonidentifiability.py [--output DIR]``.
"""

from __future__ import annotations

import argparse
import pathlib
import time

import matplotlib

matplotlib.use("Agg")  # draw into files only, also on machines without a display

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from sklearn.gaussian_process.kernels import ConstantKernel  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

import gpmultirate as gm  # noqa: E402
from gpmultirate import plotting, simulation, study  # noqa: E402
from gpmultirate.kernels import DC  # noqa: E402

DEFAULT_OUTPUT = pathlib.Path(__file__).resolve().parent / "output"


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=pathlib.Path, default=DEFAULT_OUTPUT,
                        help="directory for the figures (default: examples/output)")
    parser.add_argument("--quick", action="store_true",
                        help="accepted for symmetry with the other examples; this one is fast")
    return parser.parse_args()


def main() -> None:
    args = parse_args()
    args.output.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()

    # ------------------------------------------------------------------
    # 1. Three fast-rate models, one slow-rate output (Fig. 2).
    # ------------------------------------------------------------------
    # An impulse at n = 0 of N = 1000 fast samples, observed every F = 4 samples:
    # M = 250 slow samples for P = 1000 coefficients, so Phi has a null space of
    # dimension P - M = 750.  theta* and theta' add to theta (a slow oscillation)
    # the null-space part of an oscillation between the slow and the fast Nyquist
    # frequency.
    example = study.nonidentifiable_example(n_samples=1000, factor=4, random_state=0)
    n_models, order = example.models.shape
    n_slow = example.y_slow.shape[0]
    slow_outputs = example.y_fast[:, :: example.factor]
    print("Example 1 (Fig. 2): impulsive input, N = P =", order, " F =", example.factor,
          " M =", n_slow)
    print(f"  null space of Phi: dimension P - M = {order - n_slow}")
    print("  max |slow output of model j - slow output of theta|:",
          ", ".join(f"{np.max(np.abs(slow_outputs[j] - slow_outputs[0])):.1e}"
                    for j in range(1, n_models)))
    print("  max |fast output of model j - fast output of theta|:",
          ", ".join(f"{np.max(np.abs(example.y_fast[j] - example.y_fast[0])):.3f}"
                    for j in range(1, n_models)))

    # Time in seconds is arbitrary here; T = 1 s puts the slow Nyquist at 1/8 Hz.
    axes = plotting.plot_nonidentifiable_example(example, sample_time=1.0)
    figure = axes[0, 0].figure
    figure.suptitle("Three fast-rate models that give the same slow-rate output")
    path = args.output / "example1_nonidentifiability.png"
    figure.savefig(path, dpi=120)
    plt.close(figure)
    print(f"  saved {path}")

    # ------------------------------------------------------------------
    # 2. Least squares refuses to pick one of them.
    # ------------------------------------------------------------------
    # Lemma 1: with order >= M the least-squares problem has infinitely many
    # minimisers.  Returning the minimum-norm one would silently choose a model
    # with no fast-rate dynamics above the slow Nyquist frequency, so the
    # estimator raises instead, and says what to do.
    print("\nLeast squares on the impulsive input (order = N >= M, Lemma 1):")
    try:
        gm.LeastSquaresFIR(factor=example.factor, order=order).fit(example.u, example.y_slow)
    except gm.IdentifiabilityError as error:
        print("  IdentifiabilityError:", error)
    else:  # pragma: no cover - would be a bug in the library
        raise RuntimeError("LeastSquaresFIR accepted a non-identifiable problem")

    # Lemma 2: an input held constant between slow samples (zero-order hold)
    # makes the columns of Phi dependent even with few coefficients: the fast
    # inputs between two slow samples are all equal, so only sums of neighbouring
    # coefficients are seen.  Here order 30 < M = 200, and still Phi has rank < 30.
    factor, n_samples, ls_order = 3, 600, 30
    system = simulation.paper_system()
    u_zoh = simulation.zoh_input(n_samples, factor, random_state=1)
    y_slow = simulation.downsample(system.simulate(u_zoh), factor)
    print(f"\nLeast squares on a zero-order-hold input (order = {ls_order} < "
          f"M = {y_slow.shape[0]}, Lemma 2):")
    try:
        gm.LeastSquaresFIR(factor=factor, order=ls_order).fit(u_zoh, y_slow)
    except gm.IdentifiabilityError as error:
        print("  IdentifiabilityError:", error)
    else:  # pragma: no cover
        raise RuntimeError("LeastSquaresFIR accepted a zero-order-hold input")

    # The same order with a fast-rate (random) input is fine: every column of Phi
    # now sees different input samples.
    u_fast = np.random.default_rng(2).standard_normal(n_samples)
    y_slow_fast = simulation.downsample(system.simulate(u_fast), factor)
    ls = gm.LeastSquaresFIR(factor=factor, order=ls_order).fit(u_fast, y_slow_fast)
    rank = np.linalg.matrix_rank(ls.observation_.matrix)
    print(f"  the same order with a random fast-rate input: regressor rank {rank} = order, "
          "a unique least-squares estimate")

    # ------------------------------------------------------------------
    # 3. A prior makes the impulsive-input problem well posed.
    # ------------------------------------------------------------------
    # The posterior mean of eq. (15) exists for any order: among all models that
    # explain the slow samples it weighs each by the prior.  With hyperparameters
    # given (optimizer=None) this is a single linear solve.
    gp = gm.FIRGaussianProcess(ConstantKernel(1.0) * DC(alpha=0.99, beta=0.9),
                               factor=example.factor, order=order, noise_level=1e-8,
                               optimizer=None).fit(example.u, example.y_slow)
    residual = np.max(np.abs(gp.observation_.matvec(gp.coef_) - example.y_slow))
    print("\nFIRGaussianProcess on the impulsive input (order = N): a unique estimate,"
          f" max slow-sample residual {residual:.1e}")

    print(f"\ndone in {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    # The matrices here have a few hundred rows: one BLAS thread is as fast as
    # several, and many times faster when other programs keep the cores busy.
    with threadpool_limits(limits=1, user_api="blas"):
        main()
