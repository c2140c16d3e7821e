"""The paper's simulation study (Section 5, Fig. 5 and 6), reduced or in full.

Every Monte Carlo run draws the two-mass-spring-damper system with each
parameter within +-10 % of nominal, a training and a validation multisine of
N = 600 samples at T = 0.1 s, and output noise at an SNR between 40 and 60 dB;
only every third noisy output sample (M = 200) is measured.  For each FIR
order P it fits least squares (only P < M is identifiable), and the
Gaussian-process estimator with the DC kernel and with the DC kernel plus
prior-knowledge (PK) kernels at 0.4 and 2 Hz, and scores each by its
goodness of fit (eq. 20) on the noise-free fast-rate validation output.
The paper reports 99.50 % (PK) against 94.67 % (DC) at P = N = 600, with
least squares limited to P < M.

The work is done by :mod:`gpmultirate.study`; this script chooses the
size, prints the table and draws the figures:

* ``paper_study_gof.png``: GoF against order, mean +- 2 std over the runs (Fig. 5);
* ``paper_example_bode.png``: one run's FRF estimates with credible bands,
  the true FRF and 0.1 |G0 - G| (Fig. 6);
* ``paper_study.json``: every run's numbers, to reload with
  ``StudyResult.from_json``.

By default a reduced study (2 runs at P = 50, 150, 600) runs in under a
minute on two cores; ``--runs 100`` runs the paper's full study (100 runs at
P = 50, 100, ..., 600; hours on a laptop, use ``--jobs``).

Run ``python examples/paper_simulation.py [--output DIR] [--quick | --runs R]
[--orders P ...] [--jobs J]``.
"""

from __future__ import annotations

import argparse
import pathlib
import time

import matplotlib
import numpy as np

matplotlib.use("Agg")  # draw into files only

import matplotlib.pyplot as plt  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from gpmultirate import study  # noqa: E402
from gpmultirate.plotting import plot_bode, plot_study  # noqa: E402

DEFAULT_OUTPUT = pathlib.Path(__file__).resolve().parent / "output"
REDUCED_RUNS, REDUCED_ORDERS = 2, (50, 150, 600)
QUICK_RUNS, QUICK_ORDERS, QUICK_SAMPLES = 2, (50, 100, 300), 300
PAPER_GOF = {"DC": 94.67, "PK": 99.50}  # at P = N = 600, mean over 100 runs


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=pathlib.Path, default=DEFAULT_OUTPUT,
                        help="directory for the figures (default: examples/output)")
    size = parser.add_mutually_exclusive_group()
    size.add_argument("--quick", action="store_true",
                      help=f"a smoke test: {QUICK_RUNS} runs of half-length records "
                           f"(N = {QUICK_SAMPLES}) at P = {QUICK_ORDERS}")
    size.add_argument("--runs", type=int, default=None,
                      help="Monte Carlo runs; giving it switches the default orders to the "
                           "paper's grid 50, 100, ..., 600 (--runs 100: the full study)")
    parser.add_argument("--orders", type=int, nargs="+", default=None,
                        help="FIR orders P to evaluate (overrides the defaults above)")
    parser.add_argument("--jobs", type=int, default=-1,
                        help="parallel runs (joblib processes; default -1: all CPUs)")
    parser.add_argument("--seed", type=int, default=0, help="random_state of the study")
    return parser.parse_args()


def main() -> None:
    args = parse_args()
    args.output.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()

    n_samples = 600
    if args.quick:
        n_runs, orders, n_samples = QUICK_RUNS, QUICK_ORDERS, QUICK_SAMPLES
    elif args.runs is None:
        n_runs, orders = REDUCED_RUNS, REDUCED_ORDERS
    else:
        n_runs, orders = args.runs, study.PAPER_ORDERS
    if args.orders is not None:
        orders = tuple(args.orders)
    print(f"Monte Carlo study: {n_runs} runs, N = {n_samples}, orders P = {list(orders)}, "
          f"methods LS, DC, PK, random_state={args.seed}")

    # ------------------------------------------------------------------
    # The study.  Runs are independent, so they are spread over processes;
    # each run's data depend only on random_state and the run index, so the
    # numbers do not depend on --jobs.
    # ------------------------------------------------------------------
    result = study.run_paper_study(n_runs=n_runs, orders=orders, n_samples=n_samples,
                                         n_jobs=args.jobs, random_state=args.seed)
    print(f"\nvalidation GoF, mean ± std over {result.n_runs} runs "
          f"(M = {result.n_slow_samples} slow samples):\n")
    print(result.to_markdown())
    if n_samples == 600 and 600 in result.orders:
        column = list(result.orders).index(600)
        for method, paper in PAPER_GOF.items():
            print(f"{method} at P = N = 600: {result.gof[method][:, column].mean():.4f} % "
                  f"(paper: {paper:.2f} %)")
    warnings_total = {m: int(result.n_warnings[m].sum()) for m in result.methods}
    print(f"optimizer/jitter warnings per method: {warnings_total}")
    result.to_json(args.output / "paper_study.json")

    figure, ax = plt.subplots(figsize=(6.4, 4.2), layout="constrained")
    plot_study(result, ax=ax)
    ax.set_title(f"Monte Carlo study: {result.n_runs} runs, mean ± 2 std")
    path = args.output / "paper_study_gof.png"
    figure.savefig(path, dpi=120)
    plt.close(figure)
    print(f"saved {path}")

    # ------------------------------------------------------------------
    # The systems of the study (Fig. 4): the true FRF of every run's
    # perturbed system, three of them highlighted.  Each run's system comes
    # from the study's own seed stream, so these are the systems scored above.
    # ------------------------------------------------------------------
    family_freqs = np.linspace(0.01, 5.0, 1000)
    figure, ax = plt.subplots(figsize=(6.4, 3.8), layout="constrained")
    seeds = np.random.SeedSequence(args.seed).spawn(n_runs)
    for k, seed in enumerate(seeds):
        system = study.simulate_run(seed, n_samples=n_samples, factor=3,
                                          sample_time=0.1, snr_db=(40.0, 60.0),
                                          perturbation=0.1).system
        magnitude = 20 * np.log10(np.abs(system.frequency_response(family_freqs)))
        style = dict(color=("tab:blue", "tab:red", "goldenrod")[k], lw=1.2, ls="--", zorder=3) \
            if k < 3 else dict(color="0.75", lw=0.8)
        ax.plot(family_freqs, magnitude, **style)
    ax.axvline(0.5 / 0.3, color="0.3", ls="-.", lw=0.8)
    ax.text(0.5 / 0.3, 1.0, " slow Nyquist", transform=ax.get_xaxis_transform(),
            va="bottom", fontsize="small")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("magnitude [dB]")
    ax.set_title(f"true FRFs of the {n_runs} perturbed systems", pad=14)
    path = args.output / "paper_systems_frf.png"
    figure.savefig(path, dpi=120)
    plt.close(figure)
    print(f"saved {path}")

    # ------------------------------------------------------------------
    # One run in detail (Fig. 6): the first run of the study, LS at its best
    # order below M, DC and PK at P = N.
    # ------------------------------------------------------------------
    # (n_jobs=1: two fits do not repay starting worker processes)
    example = study.paper_example(random_state=args.seed, order=None,
                                        n_samples=n_samples, n_jobs=1)
    print(f"\nexample run (SNR {example.data.snr_db:.1f} dB): "
          + ", ".join(f"{name}{' (P=%d)' % example.ls_order if name == 'LS' else ''} "
                      f"{gof:.4f} %" for name, gof in example.gof.items()))
    freqs = example.frequencies()[1:]  # DFT bins of the record, without 0 Hz
    true_frf = example.true_frequency_response(freqs)
    colors = {"LS": "tab:red", "DC": "tab:blue", "PK": "tab:green"}
    figure, ax = plt.subplots(figsize=(9.0, 4.8), layout="constrained")
    for name, model in example.models.items():
        label = f"LS (P={example.ls_order})" if name == "LS" else f"{name} (P={example.order})"
        frf = model.frequency_response(freqs, sample_time=example.data.sample_time)
        # Magnitude only, as in the paper: above the slow Nyquist frequency the LS
        # and DC estimates are noisy, and their unwrapped phase drifts by
        # thousands of degrees, which says nothing the magnitude does not.  The
        # error is scaled by 0.1 (the paper's choice) to keep it apart from the FRFs.
        plot_bode(frf, axes=ax, phase=False, label=label, color=colors[name],
                  true_frf=true_frf, show_error=True, error_scale=0.1, legend=False)
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_xlabel("frequency [Hz]")
    ax.set_title(f"one run of the study (N = {n_samples}): FRF from slow-rate data (F = 3), "
                 "95 % bands", pad=16)  # room for the Nyquist labels above the axes
    path = args.output / "paper_example_bode.png"
    figure.savefig(path, dpi=120)
    plt.close(figure)
    print(f"saved {path}")
    print(f"\ndone in {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    # The matrices here have a few hundred rows: one BLAS thread is as fast as
    # several, and many times faster when other programs keep the cores busy.
    with threadpool_limits(limits=1, user_api="blas"):
        main()
