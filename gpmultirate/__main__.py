"""``python -m gpmultirate``: the ``gpmultirate`` command, see :mod:`gpmultirate.cli`."""

import sys

from gpmultirate.cli import main

if __name__ == "__main__":
    sys.exit(main())
