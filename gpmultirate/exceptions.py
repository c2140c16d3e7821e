"""Exceptions and warnings raised by gpmultirate.

Every exception and warning class of the package is defined here, as in
``sklearn.exceptions``.  The modules that raise them re-export them under
their former homes, so ``gpmultirate.io.DataFileError`` or
``gpmultirate.persistence.ModelFileError`` keep working.  Each error that
reports bad input is a :class:`ValueError`, so that ``except ValueError``
catches every refusal of the library.
"""

from __future__ import annotations

from numpy.linalg import LinAlgError

__all__ = [
    "DataFileError",
    "FeedbackWarning",
    "HeldOutWarning",
    "IdentifiabilityError",
    "JournalError",
    "MemoryLimitError",
    "MisspecificationWarning",
    "ModelFileError",
    "NotPositiveDefinite",
    "NumericalWarning",
    "OrderWarning",
]


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


class ModelFileError(ValueError):
    """A model file is not a valid gpmultirate model file for this version.

    Raised by :func:`~gpmultirate.load_model` for a file that is not a
    gpmultirate archive, is corrupted (checksum mismatch, truncated), was
    written by a different major version of the library or a newer file
    format, or names a kernel class that may not be loaded.

    Examples
    --------
    >>> from gpmultirate.exceptions import ModelFileError
    >>> issubclass(ModelFileError, ValueError)
    True
    """


class DataFileError(ValueError):
    """A data file cannot be read, or lacks what was asked of it.

    The message is one line that starts with the file name.

    Examples
    --------
    >>> from gpmultirate.exceptions import DataFileError
    >>> str(DataFileError("data.csv", "is empty"))
    'data.csv: is empty'
    """

    def __init__(self, path, problem: str):
        self.path = str(path)
        self.problem = " ".join(str(problem).split())  # one line
        super().__init__(f"{self.path}: {self.problem}")


class MemoryLimitError(ValueError, MemoryError):
    """A fit would need more memory than is available; the message says how much and why.

    A :class:`ValueError` (the size of the problem is the user's argument,
    and the refusal happens before any work) and a :class:`MemoryError`.

    Examples
    --------
    >>> from gpmultirate.exceptions import MemoryLimitError
    >>> issubclass(MemoryLimitError, ValueError), issubclass(MemoryLimitError, MemoryError)
    (True, True)
    """


class JournalError(ValueError):
    """A study journal that cannot be resumed: corrupt, locked, or of other settings.

    Examples
    --------
    >>> from gpmultirate.exceptions import JournalError
    >>> issubclass(JournalError, ValueError)
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


class MisspecificationWarning(UserWarning):
    """The fitted model leaves structure in the data: its bands may not hold their level.

    Emitted once after a fit whose innovations (the standardized one-step
    prediction errors of the slow samples under the fitted model) are
    correlated or of the wrong size, or whose noise estimate is at its
    lower bound (:mod:`gpmultirate.misspecification`); the message names
    what to try: ``kernel="auto"``, a longer order, a disturbance model.

    Examples
    --------
    >>> from gpmultirate.exceptions import MisspecificationWarning
    >>> issubclass(MisspecificationWarning, UserWarning)
    True
    """


class FeedbackWarning(UserWarning):
    """The data look closed-loop: the input depends on past residuals.

    Emitted after a fit without an ``excitation`` when the input in the
    frames after each slow sample is correlated with that sample's residual
    (:func:`gpmultirate.closedloop.detection.feedback_test`, at a stated
    false-alarm level); the message names ``excitation=``.

    Examples
    --------
    >>> from gpmultirate.exceptions import FeedbackWarning
    >>> issubclass(FeedbackWarning, UserWarning)
    True
    """


class NotPositiveDefinite(LinAlgError):
    """A posterior precision is not numerically positive definite.

    Raised inside :mod:`gpmultirate.covariance` by the precision route, which
    then falls back to the dense route; a :class:`numpy.linalg.LinAlgError`.
    """
