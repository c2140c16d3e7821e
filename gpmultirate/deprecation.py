"""Deprecated names: each warns once used, naming its new home and the version that removes it.

The policy: a public name that moves or is renamed keeps working for one
minor version with a :class:`DeprecationWarning`, and is removed in the next
minor version (:data:`REMOVED_IN`).  A deprecated module warns when it is
imported; a deprecated attribute of a module warns through the module's
``__getattr__`` (as numpy and scipy do); a deprecated attribute of an
estimator is a property that warns.
"""

from __future__ import annotations

import warnings

from gpmultirate.version import __version__

__all__ = ["REMOVED_IN", "deprecated_module", "warn_deprecated"]

#: the version that removes the names deprecated in this one (the next minor)
REMOVED_IN = "0.3.0"


def warn_deprecated(old: str, new: str, stacklevel: int = 2) -> None:
    """Warn that ``old`` is deprecated in favour of ``new``.

    Examples
    --------
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     warn_deprecated("gpmultirate.old_name", "gpmultirate.new_name")
    >>> print(caught[0].message)  # doctest: +ELLIPSIS
    gpmultirate.old_name is deprecated since gpmultirate 0.2... and will be removed in 0.3.0: use gpmultirate.new_name instead
    """
    warnings.warn(
        f"{old} is deprecated since gpmultirate {__version__} and will be removed in "
        f"{REMOVED_IN}: use {new} instead",
        DeprecationWarning,
        stacklevel=stacklevel + 1,
    )


def deprecated_module(old: str, new: str) -> None:
    """Warn, from the body of the deprecated module ``old``, that it is imported.

    The warning points at the statement that imports the module (Python
    skips the frames of the import machinery), so that Python's default
    filters show it where ``__main__`` imports the module.
    """
    # 1 warn_deprecated, 2 here, 3 the module's body, 4 the importing statement
    warn_deprecated(f"the module {old}", new, stacklevel=3)
