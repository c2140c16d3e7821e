"""Fast-rate impulse-response identification from slow-rate output measurements."""

from gpmultirate._version import __version__

__all__ = ["__version__"]
