"""Hold-out validation of slow-rate identification on a single-rate record.

A measured record sampled at one (fast) rate knows the output between the
slow samples, so it can judge what an estimator recovers from slow data:
:func:`holdout_split` keeps the first part of the record for estimation,
with every ``factor``-th output sample only, and the rest for validation at
every fast sample; :meth:`HoldoutSplit.evaluate` simulates a fitted model
over the *whole* record (so the validation part starts from the true past
input, not from rest) and scores it on the left-out fast samples with
:func:`~gpmultirate.metrics.fit_percent` and
:func:`~gpmultirate.metrics.goodness_of_fit`.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from gpmultirate.metrics import fit_percent, goodness_of_fit
from gpmultirate.validation import check_inputs, check_int, check_signal

__all__ = ["HoldoutScore", "HoldoutSplit", "holdout_split"]


@dataclass(frozen=True)
class HoldoutScore:
    """The fit of a model on the validation part of a :class:`HoldoutSplit`.

    Attributes
    ----------
    fit_percent : float
        ``100 (1 - ||y - y_hat|| / ||y - mean(y)||)`` on the validation
        samples, as MATLAB's ``compare`` reports it
        (:func:`~gpmultirate.metrics.fit_percent`).
    goodness_of_fit : float
        ``100 (1 - ||y - y_hat||^2 / ||y - mean(y)||^2)``, the paper's eq. (20)
        (:func:`~gpmultirate.metrics.goodness_of_fit`).
    y_pred : ndarray of shape (n_validation,)
        The model's output at the validation samples, in the units of the
        measured output (the estimation output mean added back).

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.holdout import HoldoutScore
    >>> HoldoutScore(fit_percent=50.0, goodness_of_fit=75.0, y_pred=np.zeros(3)).fit_percent
    50.0
    """

    fit_percent: float
    goodness_of_fit: float
    y_pred: np.ndarray


@dataclass(frozen=True)
class HoldoutSplit:
    """A single-rate record split into slow-rate estimation and fast-rate validation data.

    Made by :func:`holdout_split`; the arrays are read-only copies.

    Attributes
    ----------
    u : ndarray of shape (N,) or (N, n_inputs)
        The input of the whole record (minus the estimation mean when
        centred): the model is simulated from it.
    y_slow : ndarray of shape (M,)
        The slow estimation output ``y[0:n_estimation:factor]`` (minus its
        mean when centred), ``M = ceil(n_estimation / factor)``.
    y_validation : ndarray of shape (N - n_estimation,)
        The measured output ``y[n_estimation:]`` at every fast sample,
        unchanged.
    factor : int
        The downsampling factor ``F`` of the estimation output.
    n_estimation : int
        The number of fast estimation samples; validation starts there.
    u_mean : ndarray of shape (n_inputs,)
        What was subtracted from each input (zeros unless centred).
    y_mean : float
        What was subtracted from ``y_slow`` and is added to the model's
        output (0 unless centred).

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.holdout import holdout_split
    >>> split = holdout_split(np.arange(9.0), np.arange(9.0) ** 2, factor=2)
    >>> split.n_estimation, split.u_estimation.shape, split.y_slow, split.y_validation
    (6, (6,), array([ 0.,  4., 16.]), array([36., 49., 64.]))
    """

    u: np.ndarray
    y_slow: np.ndarray
    y_validation: np.ndarray
    factor: int
    n_estimation: int
    u_mean: np.ndarray
    y_mean: float

    @property
    def u_estimation(self) -> np.ndarray:
        """The estimation input ``u[:n_estimation]``, to fit a model with ``y_slow``."""
        return self.u[: self.n_estimation]

    def evaluate(self, model) -> HoldoutScore:
        """Score a fitted model on the left-out fast samples of the validation part.

        The model's output is ``model.predict(u)`` over the whole record, so
        at the validation samples it sees the estimation input as its past;
        ``y_mean`` is added back before the comparison with
        ``y_validation``.

        Parameters
        ----------
        model : fitted estimator
            Anything with ``predict(u)`` returning one output sample per
            input sample, fitted on ``u_estimation`` (e.g.
            :class:`~gpmultirate.FIRGaussianProcess` or
            :class:`~gpmultirate.LeastSquaresFIR`).

        Returns
        -------
        HoldoutScore

        Examples
        --------
        >>> import numpy as np
        >>> import gpmultirate as gm
        >>> from gpmultirate.holdout import holdout_split
        >>> rng = np.random.default_rng(0)
        >>> u = rng.standard_normal(300)
        >>> y = np.convolve(u, 0.8 ** np.arange(30))[:300]
        >>> split = holdout_split(u, y, factor=3)
        >>> model = gm.LeastSquaresFIR(factor=3, order=30).fit(split.u_estimation, split.y_slow)
        >>> round(split.evaluate(model).fit_percent, 6)
        100.0
        """
        y_pred = np.asarray(model.predict(self.u), dtype=float)
        if y_pred.shape != (self.u.shape[0],):
            raise ValueError(
                f"model.predict(u) must return one output per input sample, shape "
                f"({self.u.shape[0]},); got shape {y_pred.shape}"
            )
        y_pred = y_pred[self.n_estimation:] + self.y_mean
        return HoldoutScore(
            fit_percent=fit_percent(self.y_validation, y_pred),
            goodness_of_fit=goodness_of_fit(self.y_validation, y_pred),
            y_pred=y_pred,
        )


def holdout_split(u, y, factor: int, *, estimation_fraction: float = 2 / 3,
                  center: bool = False) -> HoldoutSplit:
    """Split a single-rate record into slow-rate estimation and fast-rate validation data.

    The first ``n_estimation = floor(estimation_fraction * N)`` samples are
    for estimation, with the output kept at fast indices ``0, F, 2F, ...``
    only; the remaining samples are for validation, at every fast sample.

    Parameters
    ----------
    u : array-like of shape (N,) or (N, n_inputs)
        The fast-rate input(s); not modified.
    y : array-like of shape (N,)
        The fast-rate output (one output); not modified.
    factor : int
        Downsampling factor ``F >= 1`` of the estimation output (1: every
        sample, the single-rate case).
    estimation_fraction : float, default=2/3
        The share of the record used for estimation, in ``(0, 1)``.
    center : bool, default=False
        Subtract the means of the estimation data -- each input's over its
        ``n_estimation`` fast samples, the output's over its slow samples --
        from the whole input and from ``y_slow``; :meth:`HoldoutSplit.evaluate`
        adds the output mean back.  An FIR model has no offset term, so
        records whose signals do not have zero mean need this.

    Returns
    -------
    HoldoutSplit

    Raises
    ------
    ValueError
        If ``u`` and ``y`` differ in length, ``factor`` is not a positive
        integer, ``estimation_fraction`` is outside ``(0, 1)``, or the split
        leaves fewer than one slow estimation sample or two validation
        samples.

    Examples
    --------
    The robot arm, two thirds for estimation with every third output sample:

    >>> from gpmultirate.datasets import load_robot_arm
    >>> from gpmultirate.holdout import holdout_split
    >>> data = load_robot_arm()
    >>> split = holdout_split(data.u, data.y, factor=3)
    >>> split.n_estimation, split.y_slow.shape, split.y_validation.shape
    (682, (228,), (342,))
    """
    x = check_inputs(u, "u")  # a new array of shape (N, n_inputs)
    one_input = np.ndim(u) == 1
    y = check_signal(y, "y", min_length=1)
    if y.shape[0] != x.shape[0]:
        raise ValueError(f"y must have the length of u ({x.shape[0]}); got {y.shape[0]}")
    factor = check_int(factor, "factor", low=1)
    if (isinstance(estimation_fraction, bool)
            or not isinstance(estimation_fraction, numbers.Real)
            or not 0.0 < float(estimation_fraction) < 1.0):
        raise ValueError(
            f"estimation_fraction must be a number in (0, 1); got {estimation_fraction!r}"
        )
    n_total = x.shape[0]
    # the tolerance keeps 2/3 of a multiple of 3 from rounding one sample down
    n_estimation = math.floor(float(estimation_fraction) * n_total + 1e-9)
    if n_estimation < 1 or n_total - n_estimation < 2:
        raise ValueError(
            f"estimation_fraction={estimation_fraction!r} of {n_total} samples leaves "
            f"{n_estimation} estimation and {n_total - n_estimation} validation samples; "
            "at least 1 and 2 are needed"
        )
    y_slow = y[:n_estimation:factor]
    if center:
        u_mean = x[:n_estimation].mean(axis=0)
        y_mean = float(np.mean(y_slow))
    else:
        u_mean = np.zeros(x.shape[1])
        y_mean = 0.0
    x = x - u_mean
    inputs = x[:, 0] if one_input else x
    return HoldoutSplit(
        u=_read_only(inputs),
        y_slow=_read_only(y_slow - y_mean),
        y_validation=_read_only(y[n_estimation:]),
        factor=factor,
        n_estimation=n_estimation,
        u_mean=_read_only(u_mean),
        y_mean=y_mean,
    )


def _read_only(x: np.ndarray) -> np.ndarray:
    x = np.array(x, dtype=float, copy=True)
    x.setflags(write=False)
    return x
