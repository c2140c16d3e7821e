"""Exceptions and warnings raised by gpmultirate."""

from __future__ import annotations

__all__ = ["HeldOutWarning", "IdentifiabilityError", "NumericalWarning", "OrderWarning"]


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


class HeldOutWarning(UserWarning):
    """Held-out slow samples are predicted clearly better by another model.

    Emitted after marginal-likelihood tuning when a shorter order, at the same
    hyperparameters, predicts the held-out blocks of a K-fold
    cross-validation over time clearly better: the evidence can prefer a
    worse predictor on measured data.

    Examples
    --------
    >>> from gpmultirate.exceptions import HeldOutWarning
    >>> issubclass(HeldOutWarning, UserWarning)
    True
    """


class OrderWarning(UserWarning):
    """The FIR order looks too short for the data's memory.

    Emitted after a fit with more slow samples than coefficients when the
    tuned prior has not decayed against the noise by the last lag and the
    residuals of the slow samples are correlated from one to the next; the
    message names a longer order.

    Examples
    --------
    >>> from gpmultirate.exceptions import OrderWarning
    >>> issubclass(OrderWarning, UserWarning)
    True
    """
