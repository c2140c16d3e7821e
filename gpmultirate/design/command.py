"""``gpmultirate design``: an input for a second experiment, from a pilot model.

``gpmultirate design MODEL --band F_LO F_HI`` reads a model written by
``gpmultirate fit`` (``model.npz``), designs a multisine whose predicted band
over the range is narrowest (:func:`~gpmultirate.design.design_multisine`)
and writes to ``--out`` the input (``input.csv``), the predicted bands before
(a flat random-phase multisine, or ``--compare`` a given input) and after
(``bands.png``) and a summary (``summary.md``, ``summary.json``), all at once
(:func:`gpmultirate.io.write_folder`).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from gpmultirate.arguments import check_out, finite_float, int_at_least

__all__ = ["DESIGN_OUT", "add_design_parser"]

DESIGN_OUT = "gpmultirate-design"


def add_design_parser(commands) -> None:
    """Add the ``design`` command to the ``gpmultirate`` subcommands."""
    design = commands.add_parser(
        "design", help="design the input of a second experiment from a pilot model",
        description="Design a multisine of the same rms whose predicted credible band of the "
                    "frequency response over --band is narrowest, from a model saved by "
                    "gpmultirate fit (its tuned kernel, noise and sample time held fixed). "
                    "Writes input.csv (index, time, u), bands.png (the predicted bands before "
                    "and after), summary.md and summary.json to --out.",
    )
    design.add_argument("model", metavar="MODEL", help="pilot model file written by "
                                                       "gpmultirate fit")
    design.add_argument("--band", type=finite_float, nargs=2, required=True,
                        metavar=("F_LO", "F_HI"), help="the frequency range in Hz")
    design.add_argument("--samples", type=int_at_least(3), default=None, metavar="N",
                        help="record length in fast samples (default: the pilot's)")
    design.add_argument("--factor", type=int_at_least(1), default=None, metavar="F",
                        help="downsampling factor (default: the pilot's)")
    design.add_argument("--offset", type=int_at_least(0), nargs="+", default=[0], metavar="O",
                        help="offset(s) of the slow sensor(s), 0..F-1 (default: 0)")
    design.add_argument("--rms", type=finite_float, default=None,
                        help="input rms in the pilot's input units (default: that of the "
                             "--compare input, else 1)")
    design.add_argument("--criterion", choices=("mean", "worst"), default="mean",
                        help="minimize the mean band over the range or the worst (default: mean)")
    design.add_argument("--floor", type=finite_float, default=0.5, metavar="SHARE",
                        help="every bin keeps at least this share of the flat amplitude, in "
                             "[0, 1) (default: 0.5)")
    design.add_argument("--relative", action="store_true",
                        help="minimize the band relative to the pilot's |G| (in dB)")
    design.add_argument("--compare", metavar="DATA", default=None,
                        help="data file (.csv, .npz, .mat) whose --input column is the input "
                             "to compare with (default: a flat random-phase multisine)")
    design.add_argument("--input", metavar="COL", default="u",
                        help="with --compare: its input column (default: u)")
    design.add_argument("--seed", type=int_at_least(0), default=0, metavar="S",
                        help="seed of the multisine phases (default: 0)")
    design.add_argument("--out", metavar="DIR", default=DESIGN_OUT,
                        help=f"folder of the results (default: {DESIGN_OUT})")
    design.add_argument("--force", action="store_true", help="overwrite an existing folder")
    design.add_argument("--quiet", "-q", action="store_true", help="no messages on stderr")
    design.set_defaults(handler=run_design, command_parser=design)


def _say(args, message: str) -> None:
    if not args.quiet:
        print(message, file=sys.stderr, flush=True)


def run_design(parser, args) -> int:
    """The handler of ``gpmultirate design``."""
    import numpy as np

    import gpmultirate as gm
    from gpmultirate.design.report import DESIGN_FILES, design_files
    from gpmultirate.io import check_folder, read_record, write_folder

    started = time.perf_counter()
    out = Path(args.out)
    check_out(parser, lambda: check_folder(out, DESIGN_FILES, overwrite=args.force))
    try:
        model = gm.load_model(args.model)
    except (ValueError, OSError) as error:
        reason = error.strerror if isinstance(error, OSError) and error.strerror else error
        parser.error(f"{args.model}: cannot load the model ({reason})")
    if not isinstance(model, gm.FIRGaussianProcess):
        parser.error(f"{args.model}: a design needs a FIRGaussianProcess model; got "
                     f"{type(model).__name__}")
    if args.rms is not None and args.rms <= 0:
        parser.error(f"argument --rms: must be positive; got {args.rms:g}")
    given, rms = None, args.rms or 1.0
    if args.compare is not None:
        given, _ = read_record(args.compare, [args.input])
        # the designed input has the power of the one it is compared with
        rms = args.rms or float(np.sqrt(np.mean(given ** 2)))
    n_samples = args.samples if given is None else given.shape[0]
    offset = args.offset[0] if len(args.offset) == 1 else tuple(args.offset)
    _say(args, f"gpmultirate design: {args.model}, {args.band[0]:g}..{args.band[1]:g} Hz ...")
    try:
        files, summary = design_files(
            model, tuple(args.band), n_samples=n_samples, factor=args.factor, offset=offset,
            rms=rms, criterion=args.criterion, relative=args.relative, floor=args.floor,
            random_state=args.seed, given_input=given, source=str(args.model))
    except ValueError as error:
        message = str(error)
        option = {"band_hz": "--band", "n_samples": "--samples", "factor": "--factor",
                  "offsets": "--offset", "offset": "--offset", "floor": "--floor"}.get(message.split(" ", 1)[0])
        parser.error(f"argument {option}: {message}" if option else f"{args.model}: {message}")
    check_out(parser, lambda: write_folder(out, files, overwrite=args.force,
                                            replaceable=DESIGN_FILES))
    for name in files:
        _say(args, f"wrote {out / name}")
    print(f"predicted mean band radius over {args.band[0]:g}..{args.band[1]:g} Hz: "
          f"{summary['before']['mean_band_radius']:.4g} before, "
          f"{summary['designed']['mean_band_radius']:.4g} designed "
          f"({summary['narrowing_mean']:.2f} times narrower)")
    _say(args, f"done in {time.perf_counter() - started:.1f} s")
    return 0
