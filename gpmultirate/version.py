"""The version of gpmultirate."""

__version__ = "0.1.0"
