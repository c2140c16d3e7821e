"""The ``gpmultirate`` command: fit measured data, predict, and the paper's study.

``gpmultirate fit DATA --input COL --output COL`` identifies a fast-rate FIR
model from a CSV, ``.npz`` or ``.mat`` file (read by :mod:`gpmultirate.io`)
whose output column holds the slow samples, empty or ``NaN`` elsewhere, and
writes the model, its Bode, impulse-response and intersample figures with
credible bands and a summary to ``--out``, showing the fit's progress on
stderr (:func:`gpmultirate.progress.show_progress`; none with ``--quiet``).
``gpmultirate predict MODEL DATA``
writes the fast-rate prediction of a saved model with its standard deviation.
``gpmultirate demo`` runs the Monte Carlo study of the paper's Section 5
(reduced; ``--resume`` continues an interrupted one), ``gpmultirate
example1`` draws the paper's Example 1.  Figures are rendered with
matplotlib's Agg canvas, so the command never opens a window; numpy and the
other libraries load in the commands, not for ``--help``.

The commands parse their arguments and call the library: the files are read
by :func:`gpmultirate.io.read_record` and
:func:`gpmultirate.io.read_slow_samples`, the results of a fit are
:func:`gpmultirate.report.fit_files` written by
:func:`gpmultirate.io.write_folder` (all at once), a prediction is
:func:`gpmultirate.report.prediction_csv`, and the study's tables and figures
come from :func:`gpmultirate.report.write_study` and
:mod:`gpmultirate.plotting.report`.

Every failure ends the command with one line on stderr: exit status 2 for
an error (naming the option, file or column), 130 for Ctrl-C.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import textwrap
import time
from pathlib import Path

# the numerical libraries load in the commands: `--help` and parser errors come at once
from gpmultirate import __version__
from gpmultirate.arguments import (FIT_KERNELS, JOURNAL_NAME, METHODS, OneLineErrorParser,
                                   available_cpus, check_out, check_slow_log, check_windows,
                                   duration, finite_float, int_at_least, nonzero_int, one_line,
                                   order_or_auto, sample_time, without_abbreviations)
from gpmultirate.arguments import add_sensor_arguments, add_slow_arguments
from gpmultirate.design.command import add_design_parser
from gpmultirate.interrupts import NotedInterrupt

__all__ = ["build_parser", "main"]

#: Defaults of ``gpmultirate demo``: a few runs and orders, including ``P = N``.
DEMO_RUNS = 2
DEMO_ORDERS = (100, 200, 600)
SAMPLE_TIME = 0.1  # the paper's fast sample time, s
_DESCRIPTIONS = {"LS": "least squares", "DC": "DC kernel", "PK": "prior-knowledge kernel"}


# ------------------------------------------------------------------- parser
def _add_output(parser: argparse.ArgumentParser, default: str) -> None:
    parser.add_argument("--output", "-o", metavar="DIR", default=default,
                        help=f"directory for the results, created if needed (default: {default})")


#: Data sets of ``gpmultirate fit --example``: function of gpmultirate.datasets giving the
#: file, inputs, output.
EXAMPLES = {"robot-arm": ("robot_arm_csv", ("u",), "y_slow")}
#: Files written by ``gpmultirate fit`` into ``--out``.
FIT_FILES = ("model.npz", "bode.png", "impulse.png", "intersample.png", "residuals.png",
             "summary.json", "summary.md", "state_space.npz")
#: Choices of ``gpmultirate fit --noise`` (``FIRGaussianProcess(noise_kernel=...)``).
FIT_NOISES = ("white", "auto", "matern12", "matern32", "ar1")
FIT_OUT = "gpmultirate-fit"
PREDICT_OUT = "gpmultirate-prediction.csv"


def _add_fit_parser(commands) -> None:
    fit = commands.add_parser(
        "fit", help="identify a fast-rate FIR model from a data file (CSV, .npz, .mat)",
        description="Identify a fast-rate FIR model from a data file whose rows are fast "
                    "samples (CSV with a header row, .npz, or MATLAB .mat).  The output "
                    "column holds the slow samples, empty or NaN elsewhere; their instants "
                    "are read from that pattern.  Writes model.npz, bode.png, impulse.png, "
                    "intersample.png, residuals.png, summary.json, summary.md and "
                    "state_space.npz to --out.",
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
    fit.add_argument("--excitation", metavar="COL", default=None, help="closed-loop data: the "
                     "external signal added in the loop (one input; docs: closed_loop)")
    fit.add_argument("--output", metavar="COL", dest="output_column", default=None,
                     help="output column: the slow samples, empty or NaN elsewhere")
    fit.add_argument("--factor", type=int_at_least(1), default=None, metavar="F",
                     help="keep every F-th output sample (a fully measured output, for "
                          "testing); by default the measured samples are used as they are")
    fit.add_argument("--offset", type=int_at_least(0), default=None, metavar="O",
                     help="row of the first kept sample with --factor, 0..F-1 (default: 0)")
    fit.add_argument("--sample-time", type=sample_time, default=1.0, metavar="T",
                     help="fast sample time in seconds; frequencies are in Hz (default: 1, "
                          "cycles per sample)")
    fit.add_argument("--order", type=order_or_auto, default=None, metavar="P",
                     help="FIR order in 1..N, N the number of rows, or 'auto': the best of "
                          "N, N/2, ..., N/32 by the tuning criterion (default: N, or a "
                          "shorter N/2^k that predicts held-out slow samples clearly better)")
    fit.add_argument("--tuning", choices=("evidence", "cross_validation"), default="evidence",
                     help="criterion of the hyperparameters (and of --order auto): the "
                          "marginal likelihood, or the log density of held-out blocks of slow "
                          "samples (default: evidence)")
    fit.add_argument("--cv", type=int_at_least(2), default=5, metavar="K",
                     help="folds of cross-validation: contiguous blocks of slow samples "
                          "(default: 5)")
    fit.add_argument("--kernel", choices=FIT_KERNELS, default="dc",
                     help="prior of the impulse response: dc, tc or ss with a data-scaled "
                          "amplitude, or auto (resonances found from the data) "
                          "(default: dc)")
    fit.add_argument("--noise", choices=FIT_NOISES, default="auto",
                     help="noise of the slow samples: white, white plus a Matern 1/2 or "
                          "3/2 disturbance over time, or an AR(1) one alone (ar1), tuned by "
                          "the evidence; auto keeps a "
                          "disturbance only where the evidence clearly calls for it "
                          "(default: auto)")
    fit.add_argument("--initial-conditions", choices=("zero", "discard", "periodic"),
                     default="zero",
                     help="zero: at rest before the record; discard: use only outputs that "
                          "see recorded inputs; periodic: the record is one period "
                          "(default: zero)")
    add_slow_arguments(fit, "the output column (--output) and the time stamps in seconds on "
                             "the clock of DATA, whose row n is at n T")
    add_sensor_arguments(fit, 0.0)
    fit.add_argument("--xscale", choices=("auto", "linear", "log"), default="auto",
                     help="frequency axis of bode.png: log, linear, or auto (log when the band "
                          "spans more than two decades; default: auto)")
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
    add_slow_arguments(predict, "the time stamps (--time, seconds) of the readings to "
                                 "predict")
    add_sensor_arguments(predict, None)
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
    cpus = available_cpus()
    parser = OneLineErrorParser(
        prog="gpmultirate",
        description=textwrap.fill(
            "Identify fast-rate FIR models (impulse responses with Gaussian-process priors) "
            "from outputs measured at a slow rate.  'gpmultirate COMMAND --help' lists a "
            "command's options.", 78),
        formatter_class=argparse.RawDescriptionHelpFormatter, allow_abbrev=False,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True,
                                     parser_class=OneLineErrorParser)
    commands.add_parser = without_abbreviations(commands.add_parser)
    _add_fit_parser(commands)
    _add_predict_parser(commands)
    add_design_parser(commands)

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
    demo.add_argument("--runs", type=int_at_least(1), default=DEMO_RUNS, metavar="R",
                      help=f"Monte Carlo runs (default: {DEMO_RUNS}; the paper: 100)")
    demo.add_argument("--orders", type=int_at_least(1), nargs="+", default=list(DEMO_ORDERS),
                      metavar="P",
                      help="FIR orders, each in 1..N (default: "
                           f"{' '.join(map(str, DEMO_ORDERS))}; the paper: 50 100 ... 600)")
    demo.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS),
                      metavar="METHOD",
                      help=f"estimators among {', '.join(METHODS)} (default: all): "
                           + "; ".join(f"{m} = {d}" for m, d in _DESCRIPTIONS.items()))
    demo.add_argument("--n-jobs", type=nonzero_int, default=cpus, metavar="J",
                      help=f"parallel processes, -1 for all CPUs (default: the number of "
                           f"CPUs, {cpus} here)")
    demo.add_argument("--seed", type=int_at_least(0), default=0, metavar="S",
                      help="random seed of the study; the same seed gives the same numbers "
                           "for any --n-jobs (default: 0)")
    demo.set_defaults(handler=_demo, command_parser=demo)
    _add_output(demo, "gpmultirate-output")
    demo.add_argument("--no-figures", action="store_true",
                      help="write only the tables (skips fitting the example run)")
    demo.add_argument("--quiet", "-q", action="store_true",
                      help="no progress or file messages on stderr (the table is still "
                           "printed)")
    demo.add_argument("--n-samples", type=int_at_least(3), default=600, metavar="N",
                      help="samples per multisine (default: 600, the paper's); smaller "
                           "values, e.g. 60 with --orders 10 20, give quick test runs")
    demo.add_argument("--factor", type=int_at_least(1), default=3, metavar="F",
                      help="downsampling factor (default: 3, the paper's)")
    demo.add_argument("--snr", type=finite_float, nargs=2, default=[40.0, 60.0],
                      metavar=("LOW", "HIGH"),
                      help="range of the training signal-to-noise ratio in dB "
                           "(default: 40 60)")
    demo.add_argument("--example-order", type=int_at_least(1), default=None, metavar="P",
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
    example1.add_argument("--n-samples", type=int_at_least(2), default=1000, metavar="N",
                          help="samples of the impulse input and order of the models "
                               "(default: 1000)")
    example1.add_argument("--factor", type=int_at_least(2), default=4, metavar="F",
                          help="downsampling factor (default: 4)")
    example1.add_argument("--seed", type=int_at_least(0), default=0, metavar="S",
                          help="random seed of the added oscillations (default: 0)")
    example1.add_argument("--quiet", "-q", action="store_true",
                          help="no file messages on stderr")

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


def _save(args, fig, path: Path) -> None:
    fig.savefig(path, dpi=150)
    _say(args, f"wrote {path}")


def _demo(parser, args) -> int:
    from gpmultirate.study.journal import interrupted_message, prepare_journal
    from gpmultirate.study.simulation import check_config, check_methods, check_orders

    n = args.n_samples  # the library's checks, before anything is written
    if args.snr[0] > args.snr[1]:
        parser.error(f"argument --snr: LOW must not exceed HIGH; got {args.snr[0]:g} "
                     f"{args.snr[1]:g}")
    check_config(n, args.factor, SAMPLE_TIME, tuple(args.snr), 0.1)
    check_orders(args.orders, n)
    check_methods(args.methods)
    example_order = n if args.example_order is None else args.example_order
    check_orders([example_order], n, name="example_order")
    out = _output_dir(parser, args.output)
    journal = out / JOURNAL_NAME
    try:
        note = prepare_journal(journal, resume=args.resume, force=args.force)
    except ValueError as error:
        parser.error(f"argument --output: {error}")
    if note:
        _say(args, note)
    try:
        status = _run_demo(parser, args, out, journal, example_order)
    except KeyboardInterrupt:
        print(f"gpmultirate demo: {interrupted_message(journal)}", file=sys.stderr, flush=True)
        return 130
    return status


def _run_demo(parser, args, out: Path, journal: Path, example_order: int) -> int:
    import joblib

    from gpmultirate.study import paper_example, run_paper_study
    from gpmultirate.study.journal import JournalError

    n = args.n_samples
    config = {"n_samples": n, "factor": args.factor, "sample_time": SAMPLE_TIME,
              "snr_db": tuple(args.snr)}
    started = time.perf_counter()
    _say(args, f"gpmultirate demo: {args.runs} run(s), orders {' '.join(map(str, args.orders))}, "
               f"methods {' '.join(args.methods)}, N = {n}, n_jobs = {args.n_jobs}")
    try:
        result = run_paper_study(args.runs, args.orders, args.methods, n_jobs=args.n_jobs,
                                 random_state=args.seed, progress=not args.quiet,
                                 journal=journal, **config)
    except JournalError as error:
        parser.error(f"argument --resume: {error}" if args.resume else str(error))
    from gpmultirate.report import study_header, write_study

    for path in write_study(result, out):
        _say(args, f"wrote {path}")
    print(study_header(result))
    print()
    print(result.to_markdown(), end="")
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
    from gpmultirate.plotting.report import nonidentifiable_figure
    from gpmultirate.study import nonidentifiable_example

    if args.n_samples < 2 * args.factor:
        parser.error(f"argument --n-samples: must be at least 2 * factor = {2 * args.factor}, "
                     f"got {args.n_samples}")
    out = _output_dir(parser, args.output)
    example = nonidentifiable_example(args.n_samples, args.factor, random_state=args.seed)
    _save(args, nonidentifiable_figure(example), out / "example1.png")
    return 0


# ------------------------------------------------------------- fit, predict
def _fit_source(parser, args):
    """The data file, input columns and output column of ``gpmultirate fit``."""
    from gpmultirate import datasets

    if args.example is not None:
        if args.data is not None:
            parser.error(f"argument --example: give either DATA or --example, not both "
                         f"(got DATA {args.data!r})")
        _, inputs, output = EXAMPLES[args.example]
        path = Path(getattr(datasets, EXAMPLES[args.example][0])())
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


def _fit(parser, args) -> int:
    import warnings

    import numpy as np

    from gpmultirate import FIRGaussianProcess
    from gpmultirate.io import (
        check_folder, read_record, read_slow_log, read_slow_samples, write_folder,
    )
    from gpmultirate.progress import StepTimes, show_progress
    from gpmultirate.report import fit_files, kernel_option

    path, inputs, output = _fit_source(parser, args)
    _check_columns(parser, inputs, output)
    check_slow_log(parser, args)
    out = Path(args.out)
    check_out(parser, lambda: check_folder(out, FIT_FILES, overwrite=args.force))
    started = time.perf_counter()
    u, y = read_record(path, inputs, None if args.slow else output)
    n = u.shape[0]
    if args.excitation in [*inputs, output]:
        parser.error(f"argument --excitation: column {args.excitation!r} is an --input or --output")
    excitation = args.excitation and read_record(path, [args.excitation])[0]
    if isinstance(args.order, int) and args.order > n:
        parser.error(f"argument --order: must lie in 1..N = 1..{n} (the rows of {path}); "
                     f"got {args.order}")
    factor = args.factor or 1
    if args.offset is not None and args.offset >= factor:
        parser.error(f"argument --offset: must lie in 0..F-1 = 0..{factor - 1} with --factor "
                     f"{factor}; got {args.offset}")
    if args.offset is not None and args.offset >= n:
        parser.error(f"argument --offset: must be below the {n} rows of {path}; got "
                     f"{args.offset}")
    if args.slow is not None:  # its errors name the slow file
        samples = read_slow_log(args.slow, args.time, output, sample_time=args.sample_time,
                                n_samples=n, exposure=args.exposure, latency=args.latency)
        check_windows(parser, args, n, samples.sample_times)
    else:
        try:
            samples = read_slow_samples(y, factor=args.factor, offset=args.offset)
        except ValueError as error:
            parser.error(f"{path}: " + str(error).replace("column", f"output column {output!r}", 1))
    validation = None
    if args.validate is not None:
        validation = read_record(args.validate, inputs, output, complete=True)
        if np.ptp(validation[1]) == 0:
            parser.error(f"{args.validate}: output column {output!r} is constant, so the "
                         "goodness of fit is undefined")

    _say(args, f"gpmultirate fit: {path}, {n} fast samples, {samples.values.shape[0]} "
               f"{'readings' if args.slow else 'slow samples'} ({samples.description}), "
               f"{len(inputs)} input(s) ...")
    model = FIRGaussianProcess(
        kernel=kernel_option(args.kernel), order=args.order,
        initial_conditions=args.initial_conditions, sample_time=args.sample_time,
        tuning=args.tuning, cv=args.cv, noise_kernel=args.noise, **samples.estimator_params)
    def progress():
        return contextlib.nullcontext() if args.quiet else show_progress(
            prefix="gpmultirate fit", since=started)  # one clock for the whole command

    steps = StepTimes()
    with warnings.catch_warnings(record=True) as caught, progress(), steps, steps.step("fit"):
        warnings.simplefilter("always")
        try:
            loop = {} if excitation is None else {"excitation": excitation}
            model.fit(u, samples.y_slow, **samples.fit_params, **loop)
        except ValueError as error:
            parser.error(f"{path}: the model cannot be fitted: {error}")
    _say(args, f"gpmultirate fit: fitted in {time.perf_counter() - started:.1f} s; predictions, "
               "Bode and impulse-response bands, state-space model, figures ...")
    messages = list(dict.fromkeys(f"{w.category.__name__}: {w.message}" for w in caught))
    for message in messages:
        _say(args, f"warning: {message}")
    try:
        with progress(), steps:  # each step announced, none silent for ten seconds
            files, report = fit_files(model, u, samples, file=path, inputs=inputs, output=output,
                                      validation=validation, validation_file=args.validate,
                                      warnings=messages, kernel_option=args.kernel,
                                      xscale=args.xscale)
    except ValueError as error:
        parser.error(f"{path}: {error}")
    # the folder appears complete in one step (or not at all), see io.write_folder
    check_out(parser, lambda: write_folder(out, files, overwrite=args.force,
                                            replaceable=FIT_FILES))
    for name in files:
        _say(args, f"wrote {out / name}")
    print(report.headline())
    for note in report.notes:
        _say(args, f"note: {note}")
    _say(args, f"done in {time.perf_counter() - started:.1f} s; {steps.line()}")
    return 0


def _predict(parser, args) -> int:
    import gpmultirate as gm
    from gpmultirate.io import read_record, read_slow_log, write_file
    from gpmultirate.report import prediction_csv, prediction_messages

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
    check_slow_log(parser, args)
    u, _ = read_record(args.data, args.inputs)
    sample = getattr(model, "sample_time", None) or 1.0
    log = None if args.slow is None else read_slow_log(
        args.slow, args.time, sample_time=sample, n_samples=u.shape[0])
    # in seconds, the units of the model's sample_time (fast periods of a model without one)
    sensor = {name: getattr(args, name) for name in ("exposure", "latency")
              if getattr(args, name) is not None}
    try:
        table = prediction_csv(model, u, None if log is None else log.stamps, **sensor)
    except ValueError as error:
        parser.error(f"{args.model}: {error} for {args.data}; nothing was written")
    check_out(parser, lambda: write_file(out, table.encode("utf-8"), overwrite=args.force))
    for line in prediction_messages(model, out, table, log is not None, sensor):
        _say(args, line)
    return 0


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
    command = None
    noted = NotedInterrupt()
    try:
        with noted.installed():
            args = build_parser().parse_args(argv)
            command = args.command_parser
            return args.handler(command, args)
    except Exception as error:  # every error is one line, not a traceback
        if not noted.received:  # else a Ctrl-C surfaced as it (a C extension's import)
            message = one_line(error)
            if command is None:
                print(f"gpmultirate: error: {message}", file=sys.stderr, flush=True)
                return 2
            # a library message that starts with a parameter's name: name the option
            option = "--" + message.split(" ", 1)[0].replace("_", "-")
            known = any(option in action.option_strings for action in command._actions)
            command.error(f"argument {option}: {message}" if known and isinstance(
                error, ValueError) else message)
    except KeyboardInterrupt:
        pass
    print(f"{'gpmultirate' if command is None else command.prog}: interrupted",
          file=sys.stderr, flush=True)
    return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
