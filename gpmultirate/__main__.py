"""``python -m gpmultirate``: the ``gpmultirate`` command, see :mod:`gpmultirate.cli`."""

import sys

if __name__ == "__main__":
    try:  # a Ctrl-C while the libraries load is one line too
        from gpmultirate.cli import main
    except KeyboardInterrupt:
        print("gpmultirate: interrupted", file=sys.stderr, flush=True)
        sys.exit(130)
    sys.exit(main())
