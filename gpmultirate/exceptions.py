"""Exceptions and warnings raised by gpmultirate."""

from __future__ import annotations

__all__ = ["IdentifiabilityError", "NumericalWarning"]


class IdentifiabilityError(ValueError):
    """The least-squares FIR estimate is not unique (paper Lemma 1 and 2).

    Raised when the order is at least the number of slow samples, or when
    the regressor is rank deficient, for instance for a zero-order-hold input.

    Examples
    --------
    >>> from gpmultirate import IdentifiabilityError
    >>> issubclass(IdentifiabilityError, ValueError)
    True
    """


class NumericalWarning(UserWarning):
    """A factorisation needed extra diagonal jitter to succeed."""
