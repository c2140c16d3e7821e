"""Optional dependencies, imported when first needed.

A missing optional package raises an :class:`ImportError` that names the
extra to install, e.g. ``pip install "gpmultirate[control]"``.
"""

from __future__ import annotations

__all__ = ["import_control"]

_CONTROL_HINT = 'python-control is needed here: pip install "gpmultirate[control]"'


def import_control():
    """The ``control`` package (python-control), or an ImportError that names the extra.

    Returns
    -------
    module

    Raises
    ------
    ImportError
        If python-control is not installed.

    Examples
    --------
    >>> control = import_control()
    """
    try:
        import control
    except ImportError as exc:
        raise ImportError(_CONTROL_HINT) from exc
    return control
