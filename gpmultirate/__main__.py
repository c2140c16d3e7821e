"""``python -m gpmultirate`` and the ``gpmultirate`` command, see :mod:`gpmultirate.cli`.

This module imports nothing heavy, so a Ctrl-C while numpy, SciPy and
scikit-learn load is one line on stderr and exit status 130 too.
"""

import sys


def main(argv=None) -> int:
    """Run the command line; a Ctrl-C while it loads exits with status 130."""
    try:
        from gpmultirate.cli import main as run
    except KeyboardInterrupt:
        print("gpmultirate: interrupted", file=sys.stderr, flush=True)
        return 130
    return run(argv)


if __name__ == "__main__":
    sys.exit(main())
