"""The version of gpmultirate."""

__version__ = "0.2.0"
