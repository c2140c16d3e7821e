"""Feedback detection: does the input depend on past residuals?

In open loop the residuals ``e[m]`` of a fit are independent of the input,
in particular of the input *after* each slow sample.  In a loop the
controller acts on what the sensor saw, disturbance included, so the input
in the frames after sample ``m`` is correlated with ``e[m]``.  The test
here reads that correlation at negative lags, frame by frame:

* ``x_k[m]``, ``k = 1..frames``: the mean input over the ``k``-th frame of
  ``factor`` fast samples after ``n_m`` (fast samples ``n_m + (k-1) F + 1``
  to ``n_m + k F``); ``e`` and each ``x_k`` are centred;
* ``c_k = sum_m e[m] x_k[m] / M`` over the ``M`` samples with all their
  frames inside the record;
* under the hypothesis that ``e`` and the input are independent stationary
  series, ``sqrt(M) c`` is asymptotically normal with covariance
  ``V = sum_l w_l gamma_e(l) Gamma_x(l)`` (Bartlett's formula for the
  cross-correlation of independent series; ``gamma_e`` and ``Gamma_x`` the
  sample autocovariances, ``w_l = 1 - |l| / (L + 1)`` Bartlett weights
  up to ``L`` lags, which keep ``V`` positive semi-definite), so that
  ``Q = M c^T V^-1 c`` is chi-squared with ``frames`` degrees of freedom.
  The data look closed-loop when ``P(chi2 >= Q)`` is below the false-alarm
  level (``FALSE_ALARM``, 0.001 for the warning of a fit).

Coloured residuals and coloured inputs are both allowed: that is what the
autocovariances in ``V`` are for.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import signal, stats

from gpmultirate.exceptions import FeedbackWarning

__all__ = ["FALSE_ALARM", "FeedbackTest", "feedback_test", "check_feedback"]

#: False-alarm level of the warning a fit without an excitation gives.
FALSE_ALARM = 1e-3
#: Frames after each sample whose input is tested.
FRAMES = 3


@dataclass(frozen=True)
class FeedbackTest:
    """The statistic ``Q`` of the feedback test, its degrees of freedom and p-value.

    Attributes
    ----------
    statistic : float
        ``Q = M c^T V^-1 c``.
    dof : int
        The frames tested (chi-squared degrees of freedom).
    p_value : float
        ``P(chi2(dof) >= Q)``: small when the input depends on past residuals.
    correlation : ndarray of shape (dof,)
        ``c_k / sqrt(V_kk)``: the normalized correlation per frame (standard
        normal per frame under open loop).
    """

    statistic: float
    dof: int
    p_value: float
    correlation: np.ndarray


def _autocovariance(x: np.ndarray, lag: int) -> np.ndarray:
    """``sum_m x[m] x[m + lag]^T / M`` (biased, positive semi-definite as a sequence)."""
    M = x.shape[0]
    return x[: M - lag].T @ x[lag:] / M


def feedback_test(residuals, sample_indices, u, factor: int, frames: int = FRAMES,
                  max_lag: int | None = None) -> FeedbackTest | None:
    """Test whether the input after each slow sample is correlated with its residual.

    Parameters
    ----------
    residuals : array-like of shape (M,)
        Slow residuals; NaN where not measured (left out).
    sample_indices : array-like of int, shape (M,)
        Fast index of each residual.
    u : array-like of shape (N,)
        One fast-rate input.
    factor : int
        Fast samples per frame.
    frames : int, default=3
        Frames after each sample that are tested.
    max_lag : int, optional
        Lags ``L`` of the covariance ``V``; by default ``min(M // 5, 50)``.

    Returns
    -------
    FeedbackTest, or None when fewer than ``20 frames`` samples can be used.

    Examples
    --------
    A loop that feeds the residual back into the next frame's input:

    >>> import numpy as np
    >>> from gpmultirate.closedloop.detection import feedback_test
    >>> rng = np.random.default_rng(0)
    >>> e = rng.standard_normal(300)
    >>> u = rng.standard_normal(900)
    >>> u[3:] += 0.5 * np.repeat(e, 3)[:-3]  # e[m] enters u over the next frame
    >>> feedback_test(e, np.arange(0, 900, 3), u, factor=3).p_value < 1e-3
    True
    >>> feedback_test(e, np.arange(0, 900, 3), rng.standard_normal(900), factor=3).p_value > 1e-3
    True
    """
    e = np.asarray(residuals, dtype=float).reshape(-1)
    index = np.asarray(sample_indices, dtype=np.int64).reshape(-1)
    x = np.asarray(u, dtype=float).reshape(-1)
    N = x.shape[0]
    cumulative = np.concatenate([[0.0], np.cumsum(x)])
    usable = np.isfinite(e) & (index + frames * factor < N) & (index >= 0)
    if usable.sum() < 20 * frames:
        return None
    n = index[usable]
    future = np.column_stack([
        (cumulative[n + k * factor + 1] - cumulative[n + (k - 1) * factor + 1]) / factor
        for k in range(1, frames + 1)])
    e = e[usable] - e[usable].mean()
    future = future - future.mean(axis=0)
    M = e.shape[0]
    L = min(M // 5, 50) if max_lag is None else int(max_lag)
    c = future.T @ e / M
    V = np.var(e) * _autocovariance(future, 0)
    for lag in range(1, L + 1):
        weight = 1.0 - lag / (L + 1.0)
        gamma_e = float(e[: M - lag] @ e[lag:]) / M
        gamma_x = _autocovariance(future, lag)
        V += weight * gamma_e * (gamma_x + gamma_x.T)
    scale = np.sqrt(np.maximum(np.diag(V), np.finfo(float).tiny))
    try:
        statistic = float(M * c @ np.linalg.solve(V, c))
    except np.linalg.LinAlgError:
        return None
    if not np.isfinite(statistic) or statistic < 0:
        return None
    correlation = np.sqrt(M) * c / scale
    correlation.setflags(write=False)
    return FeedbackTest(statistic, frames, float(stats.chi2.sf(statistic, frames)), correlation)


def check_feedback(model, u, y_slow, sample_indices=None, sample_times=None) -> None:
    """After a fit without an excitation: warn when the data look closed-loop.

    Runs :func:`feedback_test` on the fit's residuals (one record, one
    input, samples on the fast ticks) and warns with a
    :class:`~gpmultirate.FeedbackWarning` naming ``excitation=`` when its
    p-value is below :data:`FALSE_ALARM`.  Other data are not tested.
    """
    if sample_times is not None or isinstance(u, (list, tuple)) and isinstance(y_slow, (list, tuple)):
        return
    x = np.asarray(u, dtype=float)
    if x.ndim == 2 and x.shape[1] == 1:
        x = x[:, 0]
    y = np.asarray(y_slow, dtype=float).reshape(-1)
    if x.ndim != 1:
        return
    if sample_indices is None:
        index = np.arange(model.offset, x.shape[0], model.factor)
        factor = int(model.factor)
    else:
        index = np.asarray(sample_indices, dtype=np.int64).reshape(-1)
        steps = np.diff(index)
        factor = int(np.median(steps)) if steps.size else 1
    if index.shape != y.shape or factor < 1:
        return
    if getattr(model, "initial_conditions", "zero") == "periodic":
        predicted = np.asarray(model.predict(x), dtype=float)
    else:  # from rest: one FFT convolution, whatever the order
        predicted = signal.fftconvolve(x, np.asarray(model.coef_, dtype=float))[: x.shape[0]]
    residuals = y - predicted[index]
    if getattr(model, "initial_conditions", "zero") == "discard":
        residuals[index < model.coef_.shape[-1] - 1] = np.nan
    test = feedback_test(residuals, index, x, factor)
    if test is not None and test.p_value < FALSE_ALARM:
        warnings.warn(
            f"the input depends on past residuals (feedback test p = {test.p_value:.1e} at a "
            f"false-alarm level of {FALSE_ALARM:g}): the data look closed-loop, and a fit that "
            "takes u as given is biased where the loop acts; pass the external signal added "
            "in the loop as excitation= (fit(u, y_slow, excitation=r))",
            FeedbackWarning, stacklevel=3)
