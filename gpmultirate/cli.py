"""The ``gpmultirate`` command: fit measured data, predict, and the paper's study.

``gpmultirate fit DATA --input COL --output COL`` identifies a fast-rate FIR
model from a CSV, ``.npz`` or ``.mat`` file (read by :mod:`gpmultirate.io`)
whose output column holds the slow samples, empty or ``NaN`` elsewhere, and
writes the model, its Bode, impulse-response and intersample figures with
credible bands and a summary to ``--out``.  ``gpmultirate predict MODEL DATA``
writes the fast-rate prediction of a saved model with its standard deviation.
``gpmultirate demo`` runs a reduced version of the Monte Carlo study of the
paper's Section 5 (``--runs 100 --orders 50 100 ... 600`` is the full one),
prints the goodness-of-fit table and writes it, with the figures of one run,
to ``--output``; each finished run is saved at once to ``runs.jsonl`` there,
so that an interrupted study continues with ``--resume``.  ``gpmultirate
example1`` draws the non-identifiability example (the paper's Example 1,
Fig. 2).  Figures are rendered with
matplotlib's Agg canvas, without pyplot, so the command never opens a window.

Errors in the arguments or the files end the command with exit status 2 and
one line on stderr that names the option, file or column.
"""

from __future__ import annotations

import argparse
import io
import math
import os
import sys
import textwrap
import time
from pathlib import Path

import joblib
import numpy as np

from gpmultirate import __version__
from gpmultirate.study import METHODS, paper_example, run_paper_study
from gpmultirate.study.journal import JOURNAL_NAME, JournalError, read_journal

__all__ = ["build_parser", "main"]

#: Defaults of ``gpmultirate demo``: a few runs and orders, including ``P = N``.
DEMO_RUNS = 2
DEMO_ORDERS = (100, 200, 600)
SAMPLE_TIME = 0.1  # the paper's fast sample time, s
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


def _order_or_auto(text: str):
    if text == "auto":
        return "auto"
    try:
        return _int_at_least(1)(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"expected an integer >= 1 or 'auto', got {text!r}") from None


_order_or_auto.__name__ = "order"


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


class _OneLineErrorParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line: ``prog: error: message``."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {' '.join(str(message).split())}\n")


# ------------------------------------------------------------------- parser
def _add_output(parser: argparse.ArgumentParser, default: str) -> None:
    parser.add_argument("--output", "-o", metavar="DIR", default=default,
                        help=f"directory for the results, created if needed (default: {default})")


#: Kernels of ``gpmultirate fit --kernel``.
FIT_KERNELS = ("dc", "tc", "ss", "auto")
#: Data sets of ``gpmultirate fit --example``: file in ``gpmultirate/data``, inputs, output.
EXAMPLES = {"robot-arm": ("robot_arm_multirate.csv", ("u",), "y_slow")}
#: Files written by ``gpmultirate fit`` into ``--out``.
FIT_FILES = ("model.npz", "bode.png", "impulse.png", "intersample.png", "summary.json",
             "summary.md", "state_space.npz")
FIT_OUT = "gpmultirate-fit"
PREDICT_OUT = "gpmultirate-prediction.csv"


def _positive_float(text: str) -> float:
    value = _finite_float(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text!r}")
    return value


def _add_fit_parser(commands) -> None:
    fit = commands.add_parser(
        "fit", help="identify a fast-rate FIR model from a data file (CSV, .npz, .mat)",
        description="Identify a fast-rate FIR model (FIRGaussianProcess) from a data file "
                    "whose rows are fast samples: a CSV with a header row, an .npz or a "
                    "MATLAB .mat (v7 or older) file.  Name columns by header or variable "
                    "name, or NAME:INDEX for a column of a 2-D array.  The output column "
                    "holds the slow samples, empty or NaN where nothing was measured; the "
                    "sampling instants are taken from that pattern, so irregular and "
                    "missing samples need no option.  --factor/--offset instead downsample "
                    "a fully measured output.  Writes model.npz (gpmultirate.load_model), "
                    "bode.png, impulse.png and intersample.png with 95 % credible bands, "
                    "summary.json, summary.md and, when the model supports it, "
                    "state_space.npz to --out.  Errors are one line with exit status 2.",
    )
    fit.add_argument("data", metavar="DATA", nargs="?",
                     help="data file: .csv (header row, comma-separated, UTF-8), .npz or .mat")
    fit.add_argument("--example", choices=sorted(EXAMPLES), default=None,
                     help="fit a data set shipped with the package instead of DATA; "
                          "robot-arm is the DaISy flexible robot arm with every third output "
                          "sample kept (columns u and y_slow, the defaults of --input and "
                          "--output)")
    fit.add_argument("--input", nargs="+", metavar="COL", dest="inputs", default=None,
                     help="input column(s); several give a model of several inputs")
    fit.add_argument("--output", metavar="COL", dest="output_column", default=None,
                     help="output column: the slow samples, empty or NaN elsewhere")
    fit.add_argument("--factor", type=_int_at_least(1), default=None, metavar="F",
                     help="keep every F-th output sample (a fully measured output, for "
                          "testing); by default the measured samples are used as they are")
    fit.add_argument("--offset", type=_int_at_least(0), default=None, metavar="O",
                     help="row of the first kept sample with --factor, 0..F-1 (default: 0)")
    fit.add_argument("--sample-time", type=_positive_float, default=1.0, metavar="T",
                     help="fast sample time in seconds; frequencies are in Hz (default: 1, "
                          "cycles per sample)")
    fit.add_argument("--order", type=_order_or_auto, default=None, metavar="P",
                     help="FIR order in 1..N, N the number of rows, or 'auto': the best of "
                          "N, N/2, ..., N/32 by the tuning criterion (default: N, or a "
                          "shorter N/2^k that predicts held-out slow samples clearly better)")
    fit.add_argument("--tuning", choices=("evidence", "cross_validation"), default="evidence",
                     help="criterion of the hyperparameters (and of --order auto): the "
                          "marginal likelihood, or the log density of held-out blocks of slow "
                          "samples (default: evidence)")
    fit.add_argument("--cv", type=_int_at_least(2), default=5, metavar="K",
                     help="folds of cross-validation: contiguous blocks of slow samples "
                          "(default: 5)")
    fit.add_argument("--kernel", choices=FIT_KERNELS, default="dc",
                     help="prior of the impulse response: dc, tc or ss with a data-scaled "
                          "amplitude, or auto (resonances found from the data) "
                          "(default: dc)")
    fit.add_argument("--initial-conditions", choices=("zero", "discard", "periodic"),
                     default="zero",
                     help="zero: at rest before the record; discard: use only outputs that "
                          "see recorded inputs; periodic: the record is one period "
                          "(default: zero)")
    fit.add_argument("--validate", metavar="DATA2", default=None,
                     help="validation file with the same columns and the output measured at "
                          "every row; its goodness of fit goes into the summary")
    fit.add_argument("--out", metavar="DIR", default=FIT_OUT,
                     help=f"directory of the results, created if needed (default: {FIT_OUT})")
    fit.add_argument("--force", action="store_true", help="overwrite existing results")
    fit.add_argument("--quiet", "-q", action="store_true",
                     help="no progress or file messages on stderr")
    fit.set_defaults(handler=_fit, command_parser=fit)


def _add_predict_parser(commands) -> None:
    predict = commands.add_parser(
        "predict", help="fast-rate output of a saved model for the inputs of a data file",
        description="Predict the fast-rate output of a model saved by gpmultirate fit "
                    "(model.npz) for the input column(s) of a data file, from rest (or in "
                    "periodic steady state for a periodic model).  Writes a CSV with the "
                    "columns index, time, y and y_std (posterior standard deviation of the "
                    "noise-free output); for a many-output model (MultiOutputFIR), y_j and "
                    "y_std_j for every output j.",
    )
    predict.add_argument("model", metavar="MODEL", help="model file written by gpmultirate fit")
    predict.add_argument("data", metavar="DATA", help="data file: .csv, .npz or .mat")
    predict.add_argument("--input", nargs="+", metavar="COL", dest="inputs", required=True,
                         help="input column(s), as many as the model has inputs")
    predict.add_argument("--out", metavar="FILE", default=PREDICT_OUT,
                         help=f"CSV file of the prediction (default: {PREDICT_OUT})")
    predict.add_argument("--force", action="store_true", help="overwrite an existing file")
    predict.add_argument("--quiet", "-q", action="store_true",
                         help="no file messages on stderr")
    predict.set_defaults(handler=_predict, command_parser=predict)


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
    >>> args = build_parser().parse_args(["fit", "data.csv", "--input", "u", "--output", "y"])
    >>> args.data, args.inputs, args.output_column, args.kernel
    ('data.csv', ['u'], 'y', 'dc')
    """
    cpus = _available_cpus()
    parser = _OneLineErrorParser(
        prog="gpmultirate",
        description=textwrap.fill(
            "Identify fast-rate FIR models from slow-rate output data with Gaussian-process "
            "(kernel) priors: the simulation study of van Haren, Smith and Oomen (2025), "
            "reproduced on a simulated two-mass-spring-damper system; no data needed.", 78),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True,
                                     parser_class=_OneLineErrorParser)
    _add_fit_parser(commands)
    _add_predict_parser(commands)

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
                    "400 450 500 550 600.  Each finished run is saved at once to "
                    f"{JOURNAL_NAME} in --output, so that an interrupted study (Ctrl-C, a "
                    "killed process) continues with --resume; the file is removed when the "
                    "study is complete.",
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
    restart = demo.add_mutually_exclusive_group()
    restart.add_argument("--resume", action="store_true",
                         help=f"continue an interrupted study from the runs saved in "
                              f"--output/{JOURNAL_NAME}, running only the missing ones; the "
                              f"results equal those of an uninterrupted run.  The other "
                              f"options must be those of the interrupted command")
    restart.add_argument("--force", action="store_true",
                         help=f"discard the runs of an interrupted study saved in "
                              f"--output/{JOURNAL_NAME} and start over")

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


def _save(args, fig, path: Path) -> None:
    fig.savefig(path, dpi=150)
    _say(args, f"wrote {path}")


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
    journal = out / JOURNAL_NAME
    _check_journal(parser, args, journal)
    try:
        status = _run_demo(parser, args, out, journal, example_order)
    except KeyboardInterrupt:
        _interrupted(args, journal)
        return 130
    return status


def _journal_runs(journal: Path):
    """Finished runs in ``journal`` and the runs of its study, or None if unreadable."""
    try:
        settings, trials = read_journal(journal)
    except (OSError, JournalError):
        return None
    return len(trials), (None if settings is None else settings["n_runs"])


def _check_journal(parser, args, journal: Path) -> None:
    """Refuse to overwrite the saved runs of an interrupted study without --force."""
    if not (journal.exists() or journal.is_symlink()):
        if args.resume:
            _say(args, f"no {JOURNAL_NAME} in {journal.parent}: nothing to resume, starting "
                       f"the study")
        return
    if journal.is_dir():
        parser.error(f"argument --output: {journal} is a directory")
    if args.force:
        journal.unlink()
        return
    if args.resume:
        return
    found = _journal_runs(journal)
    if found is not None and found[0] == 0:
        journal.unlink()  # no run was finished: nothing to lose
        return
    what = ("an unreadable journal" if found is None else
            f"{found[0]} of {found[1]} finished runs of an interrupted study")
    parser.error(f"argument --output: {journal} holds {what}; use --resume to continue it "
                 f"or --force to start over")


def _interrupted(args, journal: Path) -> None:
    found = _journal_runs(journal) if journal.exists() else None
    saved = (f"{found[0]} of {found[1]} runs are saved in {journal}" if found
             else f"the finished runs are saved in {journal}")
    print(f"gpmultirate demo: interrupted; {saved}; run the same command with --resume to "
          f"continue", file=sys.stderr, flush=True)


def _run_demo(parser, args, out: Path, journal: Path, example_order: int) -> int:
    n = args.n_samples
    low, high = args.snr
    config = {"n_samples": n, "factor": args.factor, "sample_time": SAMPLE_TIME,
              "snr_db": (low, high)}
    started = time.perf_counter()
    _say(args, f"gpmultirate demo: {args.runs} run(s), orders {' '.join(map(str, args.orders))}, "
               f"methods {' '.join(args.methods)}, N = {n}, n_jobs = {args.n_jobs}")
    try:
        result = run_paper_study(args.runs, args.orders, args.methods, n_jobs=args.n_jobs,
                                 random_state=args.seed, progress=not args.quiet,
                                 journal=journal, **config)
    except JournalError as error:
        parser.error(f"argument --resume: {error}" if args.resume else str(error))
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
        from gpmultirate.plotting.report import example_figures, study_figure

        _save(args, study_figure(result), out / "gof_vs_order.png")
        _say(args, f"fitting one run's models for the figures (order {example_order}) ...")
        example = paper_example(args.seed, example_order, methods=args.methods,
                                n_jobs=min(joblib.effective_n_jobs(args.n_jobs), 2),
                                **config)
        for name, figure in (example_figures(example) if example.models else {}).items():
            _save(args, figure, out / name)
    journal.unlink(missing_ok=True)  # the study is complete: its runs are in study.json
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


# ------------------------------------------------------------- fit, predict
def _data_error(parser, error) -> None:
    parser.error(str(error))


def _example_path(name: str) -> Path:
    from importlib import resources

    return Path(str(resources.files("gpmultirate").joinpath("data", EXAMPLES[name][0])))


def _fit_source(parser, args):
    """The data file, input columns and output column of ``gpmultirate fit``."""
    if args.example is not None:
        if args.data is not None:
            parser.error(f"argument --example: give either DATA or --example, not both "
                         f"(got DATA {args.data!r})")
        _, inputs, output = EXAMPLES[args.example]
        path = _example_path(args.example)
        return (path, list(args.inputs or inputs),
                output if args.output_column is None else args.output_column)
    if args.data is None:
        parser.error("argument DATA: a data file is required (or --example robot-arm)")
    if args.inputs is None:
        parser.error("argument --input: the input column(s) are required")
    if args.output_column is None:
        parser.error("argument --output: the output column is required")
    return Path(args.data), list(args.inputs), args.output_column


def _check_columns(parser, inputs, output=None) -> None:
    for k, name in enumerate(inputs):
        if name in inputs[:k]:
            parser.error(f"argument --input: column {name!r} is given twice")
    if output is not None and output in inputs:
        parser.error(f"argument --output: column {output!r} is also an --input column")


def _read_inputs(parser, path, inputs, extra=()):
    """Float columns of ``path``: the inputs as ``(N,)`` or ``(N, k)``, and the extra ones."""
    from gpmultirate.io import DataFileError, read_columns

    try:
        columns = read_columns(path, [*inputs, *extra])
    except DataFileError as error:
        _data_error(parser, error)
    for name in inputs:
        missing = np.flatnonzero(np.isnan(columns[name]))
        if missing.size:
            parser.error(f"{path}: input column {name!r} has a missing value (empty or NaN) "
                         f"at row {missing[0]}; inputs must be measured at every row")
    u = np.column_stack([columns[name] for name in inputs])
    return (u[:, 0] if u.shape[1] == 1 else u), [columns[name] for name in extra]


def _fit_kernel(name: str):
    """The ``kernel`` argument of the estimator for ``--kernel name``.

    ``tc`` and ``ss`` are ``ConstantKernel(1) * TC()`` (``SS()``) in the
    estimator's normalized units, with the default kernel's amplitude bounds
    ``1e-8 .. 1e8``: the estimator scales them to each input's data, as it
    does its default ``dc`` kernel.
    """
    from sklearn.gaussian_process.kernels import ConstantKernel

    from gpmultirate.kernels import SS, TC

    if name == "dc":
        return None
    if name == "auto":
        return "auto"
    return ConstantKernel(1.0, (1e-8, 1e8)) * {"tc": TC, "ss": SS}[name]()


def _png(fig) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=150)
    return buffer.getvalue()


def _fit(parser, args) -> int:
    import warnings

    from gpmultirate import FIRGaussianProcess, save_model
    from gpmultirate.export import save_state_space
    from gpmultirate.io import read_slow_samples, write_folder
    from gpmultirate.plotting.report import fit_figures
    from gpmultirate.report import fit_report

    path, inputs, output = _fit_source(parser, args)
    _check_columns(parser, inputs, output)
    out = Path(args.out)
    _check_out_dir(parser, out, args.force)
    started = time.perf_counter()
    u, (y,) = _read_inputs(parser, path, inputs, [output])
    n = y.shape[0]
    if isinstance(args.order, int) and args.order > n:
        parser.error(f"argument --order: must lie in 1..N = 1..{n} (the rows of {path}); "
                     f"got {args.order}")
    if args.offset is not None and args.offset >= (args.factor or 1):
        parser.error(f"argument --offset: must lie in 0..F-1 = 0..{(args.factor or 1) - 1} "
                     f"with --factor {args.factor or 1}; got {args.offset}")
    if args.offset is not None and args.offset >= n:
        parser.error(f"argument --offset: must be below the {n} rows of {path}; "
                     f"got {args.offset}")
    try:
        samples = read_slow_samples(y, factor=args.factor, offset=args.offset)
    except ValueError as error:
        parser.error(f"{path}: {str(error).replace('column', f'output column {output!r}', 1)}")
    validation = None
    if args.validate is not None:
        u_val, (y_val,) = _read_inputs(parser, args.validate, inputs, [output])
        missing = np.flatnonzero(np.isnan(y_val))
        if missing.size:
            parser.error(f"{args.validate}: output column {output!r} must be measured at "
                         f"every row for validation; row {missing[0]} is missing")
        if np.ptp(y_val) == 0:
            parser.error(f"{args.validate}: output column {output!r} is constant, so the "
                         "goodness of fit is undefined")
        validation = (u_val, y_val)

    _say(args, f"gpmultirate fit: {path}, {n} fast samples, {samples.values.shape[0]} slow "
               f"samples ({samples.description}), {len(inputs)} input(s) ...")
    model = FIRGaussianProcess(
        kernel=_fit_kernel(args.kernel), order=args.order,
        initial_conditions=args.initial_conditions, sample_time=args.sample_time,
        tuning=args.tuning, cv=args.cv, **samples.estimator_params)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            model.fit(u, samples.y_slow, **samples.fit_params)
        except ValueError as error:
            parser.error(f"{path}: the model cannot be fitted: {error}")
    messages = list(dict.fromkeys(f"{w.category.__name__}: {w.message}" for w in caught))
    for message in messages:
        _say(args, f"warning: {message}")

    files, notes, system = {}, [], None
    buffer = io.BytesIO()
    try:
        save_model(model, buffer)
    except (ValueError, TypeError) as error:
        parser.error(f"{path}: the model cannot be saved: {error}")
    files["model.npz"] = buffer.getvalue()
    try:
        system = model.to_state_space()
    except ValueError as error:
        notes.append(f"state_space.npz was not written: {error}")
    if system is not None:
        buffer = io.BytesIO()
        save_state_space(system, buffer, sample_time=args.sample_time)
        files["state_space.npz"] = buffer.getvalue()
    report = fit_report(model, samples, file=path, inputs=inputs, output=output,
                        validation=validation, validation_file=args.validate,
                        state_space=system, notes=notes, warnings=messages,
                        kernel_option=args.kernel)
    for name, figure in fit_figures(model, u, samples, inputs).items():
        files[name] = _png(figure)
    files["summary.json"] = report.to_json().encode("utf-8")
    files["summary.md"] = report.to_markdown().encode("utf-8")
    try:
        write_folder(out, files, overwrite=args.force, replaceable=FIT_FILES)
    except FileExistsError as error:  # a file that appeared during the fit
        hint = "; use --force to overwrite" if str(error).endswith(" exists") else ""
        parser.error(f"argument --out: {error}{hint}")
    for name in files:
        _say(args, f"wrote {out / name}")
    summary = report.to_dict()
    line = (f"order {summary['model']['order']}, log evidence "
            f"{summary['model']['log_evidence']:.6g}, noise std "
            f"{math.sqrt(summary['model']['noise_level']):.4g}")
    if "validation" in summary:
        line += f", validation GoF {summary['validation']['gof_percent']:.2f} %"
    print(line)
    for note in notes:
        _say(args, f"note: {note}")
    _say(args, f"done in {time.perf_counter() - started:.1f} s")
    return 0


def _check_out_dir(parser, out: Path, force: bool) -> None:
    """Refuse an --out that cannot hold the results before anything is computed."""
    try:
        if out.is_symlink() or (out.exists() and not out.is_dir()):
            parser.error(f"argument --out: {str(out)!r} exists and is not a directory")
        entries = sorted(os.listdir(out)) if out.exists() else []
    except OSError as error:
        parser.error(f"argument --out: cannot use {_shorten(str(out))!r} "
                     f"({error.strerror or error})")
    foreign = [name for name in entries if name not in FIT_FILES]
    if foreign:
        parser.error(f"argument --out: {out / foreign[0]} is not a result of gpmultirate fit; "
                     "the folder is replaced as a whole, so choose an empty or new one")
    if entries and not force:
        existing = [name for name in FIT_FILES if name in entries]
        parser.error(f"argument --out: {out / existing[0]} exists; use --force to overwrite")


def _predict(parser, args) -> int:
    import gpmultirate as gm
    from gpmultirate.io import write_file

    _check_columns(parser, args.inputs)
    out = Path(args.out)
    if out.exists() and (out.is_dir() or not args.force):
        parser.error(f"argument --out: {str(out)!r} "
                     + ("is a directory" if out.is_dir() else "exists; use --force to overwrite"))
    try:
        model = gm.load_model(args.model)
    except (ValueError, OSError) as error:
        reason = error.strerror if isinstance(error, OSError) and error.strerror else error
        parser.error(f"{args.model}: cannot load the model ({reason})")
    if len(args.inputs) != model.n_inputs_:
        parser.error(f"argument --input: the model of {args.model} has {model.n_inputs_} "
                     f"input(s); got {len(args.inputs)} column(s)")
    u, _ = _read_inputs(parser, args.data, args.inputs)
    mean, std = model.predict(u, return_std=True)
    if not (np.isfinite(mean).all() and np.isfinite(std).all()):
        parser.error(f"{args.model}: the model's prediction for {args.data} is not finite "
                     "(the model or the inputs are out of range); nothing was written")
    # a many-output model (MultiOutputFIR) predicts one column per output
    several = mean.ndim == 2
    mean, std = mean.reshape(mean.shape[0], -1), std.reshape(std.shape[0], -1)
    models = getattr(model, "estimators_", [model])
    sample_time = float(getattr(models[0], "sample_time", 1.0))
    names = ([f"y_{j},y_std_{j}" for j in range(mean.shape[1])] if several else ["y,y_std"])
    text = io.StringIO()
    text.write(",".join(["index,time", *names]) + "\n")
    for k, (m, s) in enumerate(zip(mean, std)):
        values = ",".join(f"{a:.17g},{b:.17g}" for a, b in zip(m, s))
        text.write(f"{k},{k * sample_time:.17g},{values}\n")
    try:
        write_file(out, text.getvalue().encode("utf-8"), overwrite=args.force)
    except FileExistsError:
        parser.error(f"argument --out: {str(out)!r} appeared while writing; use --force to "
                     "overwrite")
    _say(args, f"wrote {out} ({mean.shape[0]} fast samples)")
    return 0


def _shorten(text: str, limit: int = 80) -> str:
    return text if len(text) <= limit else f"{text[:limit // 2]}...{text[-limit // 2:]}"


def _one_line(error: BaseException) -> str:
    """An exception as one line that names the file (shortened) for an OS error."""
    if isinstance(error, OSError) and error.strerror:
        names = [_shorten(os.fsdecode(name)) for name in (error.filename, error.filename2)
                 if name is not None]
        return ": ".join([*names, error.strerror])
    if isinstance(error, MemoryError):
        return f"out of memory: {error}" if str(error) else "out of memory"
    text = " ".join(str(error).split())
    return text if isinstance(error, ValueError) else f"{type(error).__name__}: {text}"


def main(argv=None) -> int:
    """Run the ``gpmultirate`` command.

    Every failure ends the command with one line on stderr: a Ctrl-C
    (``KeyboardInterrupt``) with exit status 130, any other error (invalid
    arguments or files, an operating-system error such as a full disk or a
    file name that is too long, the memory guard's refusal) with status 2.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name; default ``sys.argv[1:]``.

    Returns
    -------
    int
        The exit status, 0 on success, 130 after a Ctrl-C.  Errors raise
        :class:`SystemExit` with status 2, as argparse does.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    command = args.command_parser
    try:
        return args.handler(command, args)
    except KeyboardInterrupt:
        print(f"{command.prog}: interrupted", file=sys.stderr, flush=True)
        return 130
    except Exception as error:  # every error is one line, not a traceback
        command.error(_one_line(error))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
