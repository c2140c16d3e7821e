"""The ``gpmultirate`` command: the paper's simulation study and figures, no data needed.

``gpmultirate demo`` runs a reduced version of the Monte Carlo study of the
paper's Section 5 (``--runs 100 --orders 50 100 ... 600`` is the full one),
prints the goodness-of-fit table and writes it, with the figures of one run,
to ``--output``.  ``gpmultirate example1`` draws the non-identifiability
example (the paper's Example 1, Fig. 2).  Figures are rendered with
matplotlib's Agg canvas, without pyplot, so the command never opens a window.
"""

from __future__ import annotations

import argparse
import os
import sys
import textwrap
import time
from pathlib import Path

import joblib
import numpy as np

from gpmultirate import __version__
from gpmultirate.study import METHODS, paper_example, run_paper_study

__all__ = ["build_parser", "main"]

#: Defaults of ``gpmultirate demo``: a few runs and orders, including ``P = N``.
DEMO_RUNS = 2
DEMO_ORDERS = (100, 200, 600)
SAMPLE_TIME = 0.1  # the paper's fast sample time, s
_STYLES = {"LS": "tab:red", "DC": "tab:blue", "PK": "tab:green"}
_DESCRIPTIONS = {"LS": "least squares", "DC": "DC kernel", "PK": "prior-knowledge kernel"}


def _available_cpus() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


# ------------------------------------------------------------ argument types
def _int_at_least(low: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be at least {low}, got {value}")
        return value

    parse.__name__ = f"integer >= {low}"
    return parse


def _nonzero_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value == 0:
        raise argparse.ArgumentTypeError("must not be 0 (use a positive count, or -1 for all "
                                         "CPUs)")
    return value


def _finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not np.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return value


# ------------------------------------------------------------------- parser
def _add_output(parser: argparse.ArgumentParser, default: str) -> None:
    parser.add_argument("--output", "-o", metavar="DIR", default=default,
                        help=f"directory for the results, created if needed (default: {default})")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``gpmultirate`` command.

    Returns
    -------
    argparse.ArgumentParser

    Examples
    --------
    >>> from gpmultirate.cli import build_parser
    >>> args = build_parser().parse_args(["demo", "--runs", "3", "--orders", "100", "600"])
    >>> args.command, args.runs, args.orders
    ('demo', 3, [100, 600])
    """
    cpus = _available_cpus()
    parser = argparse.ArgumentParser(
        prog="gpmultirate",
        description=textwrap.fill(
            "Identify fast-rate FIR models from slow-rate output data with Gaussian-process "
            "(kernel) priors: the simulation study of van Haren, Smith and Oomen (2025), "
            "reproduced on a simulated two-mass-spring-damper system; no data needed.", 78),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    demo = commands.add_parser(
        "demo", help="Monte Carlo study of LS, DC and PK estimators (paper Section 5)",
        description="Reduced Monte Carlo study of the paper's Section 5: per run a perturbed "
                    "system, training and validation multisines of N samples, training noise "
                    "at an SNR drawn in [40, 60] dB, every third output sample kept "
                    "(M = N / 3); least squares (LS), DC-kernel (DC) and prior-knowledge-"
                    "kernel (PK) FIR models of each order are scored by their goodness of fit "
                    "on noise-free validation data.  Prints the table and writes study.csv "
                    "(summary), study_runs.csv (every fit), study.md, study.rst, study.json and the "
                    "figures gof_vs_order.png, bode.png, impulse_response.png and "
                    "intersample.png (one run's models at order --example-order).  "
                    "The paper's full study is --runs 100 --orders 50 100 150 200 250 300 350 "
                    "400 450 500 550 600.",
    )
    demo.add_argument("--runs", type=_int_at_least(1), default=DEMO_RUNS, metavar="R",
                      help=f"Monte Carlo runs (default: {DEMO_RUNS}; the paper: 100)")
    demo.add_argument("--orders", type=_int_at_least(1), nargs="+", default=list(DEMO_ORDERS),
                      metavar="P",
                      help="FIR orders, each in 1..N (default: "
                           f"{' '.join(map(str, DEMO_ORDERS))}; the paper: 50 100 ... 600)")
    demo.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS),
                      metavar="METHOD",
                      help=f"estimators among {', '.join(METHODS)} (default: all): "
                           + "; ".join(f"{m} = {d}" for m, d in _DESCRIPTIONS.items()))
    demo.add_argument("--n-jobs", type=_nonzero_int, default=cpus, metavar="J",
                      help=f"parallel processes, -1 for all CPUs (default: the number of "
                           f"CPUs, {cpus} here)")
    demo.add_argument("--seed", type=_int_at_least(0), default=0, metavar="S",
                      help="random seed of the study; the same seed gives the same numbers "
                           "for any --n-jobs (default: 0)")
    demo.set_defaults(handler=_demo, command_parser=demo)
    _add_output(demo, "gpmultirate-output")
    demo.add_argument("--no-figures", action="store_true",
                      help="write only the tables (skips fitting the example run)")
    demo.add_argument("--quiet", "-q", action="store_true",
                      help="no progress or file messages on stderr (the table is still "
                           "printed)")
    demo.add_argument("--n-samples", type=_int_at_least(3), default=600, metavar="N",
                      help="samples per multisine (default: 600, the paper's); smaller "
                           "values, e.g. 60 with --orders 10 20, give quick test runs")
    demo.add_argument("--factor", type=_int_at_least(1), default=3, metavar="F",
                      help="downsampling factor (default: 3, the paper's)")
    demo.add_argument("--snr", type=_finite_float, nargs=2, default=[40.0, 60.0],
                      metavar=("LOW", "HIGH"),
                      help="range of the training signal-to-noise ratio in dB "
                           "(default: 40 60)")
    demo.add_argument("--example-order", type=_int_at_least(1), default=None, metavar="P",
                      help="order of the DC and PK models in the figures (default: N, as in "
                           "the paper's Fig. 6); LS uses its best identifiable order")

    example1 = commands.add_parser(
        "example1", help="non-identifiability example (paper Example 1, Fig. 2)",
        description="Three fast-rate FIR models with identical slow-rate outputs: an impulse "
                    "input, order P = N, and oscillations above the slow Nyquist frequency "
                    "added in the null space of the slow-rate regressor.  Writes "
                    "example1.png.",
    )
    example1.set_defaults(handler=_example1, command_parser=example1)
    _add_output(example1, "gpmultirate-output")
    example1.add_argument("--n-samples", type=_int_at_least(2), default=1000, metavar="N",
                          help="samples of the impulse input and order of the models "
                               "(default: 1000)")
    example1.add_argument("--factor", type=_int_at_least(2), default=4, metavar="F",
                          help="downsampling factor (default: 4)")
    example1.add_argument("--seed", type=_int_at_least(0), default=0, metavar="S",
                          help="random seed of the added oscillations (default: 0)")
    example1.add_argument("--quiet", "-q", action="store_true",
                          help="no file messages on stderr")

    # `gpmultirate --help` documents every option of every command
    parser.epilog = "\n".join(
        f"----- gpmultirate {name} -----\n{sub.format_help()}"
        for name, sub in commands.choices.items()
    )
    return parser


# ---------------------------------------------------------------- commands
def _say(args, message: str) -> None:
    if not args.quiet:
        print(message, file=sys.stderr, flush=True)


def _output_dir(parser, path: str) -> Path:
    out = Path(path)
    if out.exists() and not out.is_dir():
        parser.error(f"argument --output: {path!r} exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    return out


def _figure(**kwargs):
    # A bare Figure renders with the Agg canvas and never touches pyplot's state.
    from matplotlib.figure import Figure

    return Figure(layout="constrained", **kwargs)


def _format_gof(value: float) -> str:
    # enough decimals to tell 99.9990 % from 100 %
    return f"{value:.2f}" if value < 99.99 else f"{value:.4f}"


def _save(args, fig, path: Path) -> None:
    fig.savefig(path, dpi=150)
    _say(args, f"wrote {path}")


def _study_figure(args, result, out: Path) -> None:
    from gpmultirate.plotting import plot_study

    fig = _figure(figsize=(6.4, 4.2))
    ax = fig.subplots()
    plot_study(result, ax=ax)
    ax.set_title(f"GoF on validation data, mean ± 2 std over {result.n_runs} "
                 f"run{'s' if result.n_runs > 1 else ''}", fontsize="medium")
    _save(args, fig, out / "gof_vs_order.png")


def _example_figures(args, example, out: Path) -> None:
    from gpmultirate.plotting import plot_bode, plot_impulse_response, plot_intersample
    from gpmultirate.responses import ImpulseResponse, OutputPrediction

    methods = list(example.models)
    data = example.data
    n = data.u.shape[0]
    titles = {m: (f"{m} ({_DESCRIPTIONS[m]}), P = "
                  f"{example.ls_order if m == 'LS' else example.order}, "
                  f"GoF {_format_gof(example.gof[m])} %") for m in methods}

    # Bode magnitude per estimator with the true FRF and 0.1 |G0 - G| (paper Fig. 6), at
    # the DFT bins of the record, the frequencies the multisine excites
    freqs = example.frequencies()
    true_frf = example.true_frequency_response(freqs)
    fig = _figure(figsize=(8.5, 2.6 * len(methods) + 0.4))
    axes = fig.subplots(len(methods), 1, sharex=True, squeeze=False)[:, 0]
    for ax, method in zip(axes, methods):
        frf = example.models[method].frequency_response(freqs, sample_time=data.sample_time)
        plot_bode(frf, axes=ax, phase=False, label=method, color=_STYLES[method],
                  true_frf=true_frf, show_error=True, error_scale=0.1)
        ax.set_title(titles[method], fontsize="medium", loc="left", pad=14)
        ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
        if ax is not axes[-1]:
            ax.set_xlabel("")
    _save(args, fig, out / "bode.png")

    # impulse responses: posterior mean and 95 % band over the first lags, true markers
    n_lags = min(example.order, max(60, n // 4))
    true_g = example.true_impulse_response(n_lags)
    fig = _figure(figsize=(8.5, 2.4 * len(methods) + 0.4))
    axes = fig.subplots(len(methods), 1, sharex=True, squeeze=False)[:, 0]
    for ax, method in zip(axes, methods):
        model = example.models[method]
        order = model.coef_.shape[0]
        shown = min(order, n_lags)
        lags = (np.linspace(0.0, shown - 1.0, 4 * (shown - 1) + 1) if model.continuous_lags
                else np.arange(shown))
        plot_impulse_response(ImpulseResponse.from_model(model, lags), ax=ax, label=method,
                              color=_STYLES[method], true_response=true_g)
        ax.set_title(titles[method], fontsize="medium", loc="left", pad=14)
        ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
        if ax is not axes[-1]:
            ax.set_xlabel("")
    if n_lags < example.order:
        axes[-1].set_xlabel(f"lag [samples] (the first {n_lags} of P)")
    _save(args, fig, out / "impulse_response.png")

    # intersample output on the training input: 20 slow periods in the middle
    width = min(n, 20 * data.factor)
    start = max(0, (n - width) // 2)
    start -= start % data.factor
    fig = _figure(figsize=(8.5, 2.4 * len(methods) + 0.4))
    axes = fig.subplots(len(methods), 1, sharex=True, squeeze=False)[:, 0]
    for ax, method in zip(axes, methods):
        prediction = OutputPrediction.from_model(
            example.models[method], data.u, y_fast=data.y_fast, y_slow=data.y_slow,
            sample_time=data.sample_time)
        plot_intersample(prediction, ax=ax, window=(start, min(n, start + width)),
                         label=method, color=_STYLES[method])
        ax.set_title(titles[method], fontsize="medium", loc="left", pad=14)
        ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
        if ax is not axes[-1]:
            ax.set_xlabel("")
    _save(args, fig, out / "intersample.png")


def _demo(parser, args) -> int:
    n = args.n_samples
    if args.factor > n:
        parser.error(f"argument --factor: must not exceed --n-samples ({n}), got {args.factor}")
    bad = [p for p in args.orders if p > n]
    if bad:
        parser.error(f"argument --orders: orders must lie in 1..N = 1..{n}; got {bad}")
    if len(set(args.orders)) != len(args.orders):
        parser.error(f"argument --orders: orders must not repeat; got {args.orders}")
    if len(set(args.methods)) != len(args.methods):
        parser.error(f"argument --methods: methods must not repeat; got {args.methods}")
    low, high = args.snr
    if low > high:
        parser.error(f"argument --snr: LOW must not exceed HIGH; got {low:g} {high:g}")
    example_order = n if args.example_order is None else args.example_order
    if example_order > n:
        parser.error(f"argument --example-order: must lie in 1..N = 1..{n}; got {example_order}")
    out = _output_dir(parser, args.output)

    config = {"n_samples": n, "factor": args.factor, "sample_time": SAMPLE_TIME,
              "snr_db": (low, high)}
    started = time.perf_counter()
    _say(args, f"gpmultirate demo: {args.runs} run(s), orders {' '.join(map(str, args.orders))}, "
               f"methods {' '.join(args.methods)}, N = {n}, n_jobs = {args.n_jobs}")
    result = run_paper_study(args.runs, args.orders, args.methods, n_jobs=args.n_jobs,
                             random_state=args.seed, progress=not args.quiet, **config)
    result.to_csv(out / "study.csv")
    result.to_csv(out / "study_runs.csv", runs=True)
    result.to_json(out / "study.json")
    header = (f"Goodness of fit [%] of fast-rate FIR models on noise-free validation data: "
              f"mean ± sample std over {result.n_runs} run(s); N = {n} fast samples, "
              f"M = {result.n_slow_samples} slow samples (factor {args.factor}), SNR "
              f"{low:g}-{high:g} dB, seed {args.seed}."
              + (" LS is not identifiable for P >= M." if "LS" in args.methods else ""))
    table = result.to_markdown()
    (out / "study.md").write_text(f"# gpmultirate demo\n\n{header}\n\n{table}",
                                  encoding="utf-8")
    (out / "study.rst").write_text(f"{header}\n\n{result.to_rst()}", encoding="utf-8")
    for name in ("study.csv", "study_runs.csv", "study.json", "study.md", "study.rst"):
        _say(args, f"wrote {out / name}")
    print(header)
    print()
    print(table, end="")
    sys.stdout.flush()

    if not args.no_figures:
        _study_figure(args, result, out)
        _say(args, f"fitting one run's models for the figures (order {example_order}) ...")
        example = paper_example(args.seed, example_order, methods=args.methods,
                                n_jobs=min(joblib.effective_n_jobs(args.n_jobs), 2),
                                **config)
        if example.models:
            _example_figures(args, example, out)
    _say(args, f"done in {time.perf_counter() - started:.1f} s")
    return 0


def _example1(parser, args) -> int:
    from gpmultirate.plotting import plot_nonidentifiable_example
    from gpmultirate.study import nonidentifiable_example

    if args.n_samples < 2 * args.factor:
        parser.error(f"argument --n-samples: must be at least 2 * factor = {2 * args.factor}, "
                     f"got {args.n_samples}")
    out = _output_dir(parser, args.output)
    example = nonidentifiable_example(args.n_samples, args.factor, random_state=args.seed)
    fig = _figure(figsize=(9.0, 6.0))
    plot_nonidentifiable_example(example, axes=fig.subplots(2, 2))
    _save(args, fig, out / "example1.png")
    return 0


def main(argv=None) -> int:
    """Run the ``gpmultirate`` command.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name; default ``sys.argv[1:]``.

    Returns
    -------
    int
        The exit status, 0 on success.  Invalid arguments raise
        :class:`SystemExit` with status 2, as argparse does.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    return args.handler(args.command_parser, args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
