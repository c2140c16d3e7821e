"""Residual analysis of a fitted FIR model, as identification users know it from ``resid``.

A model that explains the slow samples up to white measurement noise leaves
residuals ``e[m] = y_slow[m] - y_hat(n_m)`` that are

* uncorrelated with themselves at every lag ``k >= 1`` (otherwise the noise
  is coloured -- drift, vibration, a sensor's filtering -- and the model's
  bands are too narrow), and
* uncorrelated with past and future inputs (otherwise dynamics are missing:
  too short an order, or a prior that shrank a real response away).

:func:`analyze_residuals` computes both correlations with their confidence
bands and a whiteness verdict, as a frozen :class:`ResidualAnalysis`;
:func:`gpmultirate.plotting.plot_residuals` draws it.

Conventions (documented once, here):

* ``e`` is not centred: an offset left in the residuals is a misfit and shows
  as correlation at every lag.  Centre the data before fitting
  (:func:`~gpmultirate.holdout.holdout_split` with ``center=True``) when the
  signals do not have zero mean.
* Autocorrelation at lag ``k`` (in slow samples, i.e. consecutive entries of
  ``y_slow``): ``r(k) = sum_m e[m] e[m+k] / sum_m e[m]^2`` over the measured
  pairs (the biased estimator of ``resid``; ``r(0) = 1``).  Under the
  hypothesis that ``e`` is white, ``r(k)`` is asymptotically normal with
  variance ``N_k / N^2`` (``N`` measured residuals, ``N_k`` measured pairs at
  lag ``k``; ``N_k = N - k`` without gaps, which gives Bartlett's familiar
  ``1 / N`` for small ``k``).  The band is ``+- z sqrt(N_k) / N`` with ``z``
  the two-sided normal quantile of ``confidence``.
* Cross-correlation with input ``j`` at lag ``tau`` (in fast samples):
  ``c_j(tau) = sum_m e[m] u_j(n_m - tau) / (N rms(e) rms(u_j))``, where
  ``rms(u_j)`` is over the whole input; positive ``tau`` pairs a residual
  with an earlier input (what a missing impulse-response coefficient at lag
  ``tau`` leaves), negative ``tau`` with a later one (feedback).  Under the
  hypothesis that ``e`` is white and independent of the input, its variance
  given the input is ``sum_m u_j(n_m - tau)^2 / (N rms(u_j))^2``, and the band
  is ``z`` times its root.
* Whiteness verdict: the Ljung-Box statistic
  ``Q = N (N + 2) sum_{k=1}^{h} r(k)^2 / N_k`` over the lags ``1..h``
  (``h = max_lag``), which is chi-squared with ``h`` degrees of freedom for
  white residuals; the residuals are called white when its p-value is at
  least ``1 - confidence`` (0.01 by default).  :attr:`ResidualAnalysis.share_outside`
  gives the share of lags outside the band as a second reading: about
  ``1 - confidence`` of them fall outside by chance.
* Feedback: the cross-correlations at negative lags read whether the input
  depends on past residuals (a loop); the joint test of the mean input over
  the three frames after each sample
  (:func:`gpmultirate.closedloop.detection.feedback_test`, chi-squared with
  coloured residuals and inputs allowed) gives ``feedback_p_value`` per
  input, and :attr:`ResidualAnalysis.closed_loop` calls the data closed-loop
  when it is below ``1 - confidence``.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np
from scipy import stats

from gpmultirate.closedloop.detection import feedback_test
from gpmultirate.units import in_fast_periods
from gpmultirate.validation import check_inputs, check_int, check_level, check_sample_indices

__all__ = ["ResidualAnalysis", "analyze_residuals", "residual_correlations"]


@dataclass(frozen=True)
class ResidualAnalysis:
    """Autocorrelation and input cross-correlations of a model's slow residuals.

    Made by :func:`analyze_residuals`; the arrays are read-only.  The module
    docstring of :mod:`gpmultirate.residuals` gives the formulas.

    Attributes
    ----------
    residuals : ndarray of shape (M,)
        ``y_slow - y_hat`` at the slow samples; NaN where no sample was
        measured (or where it was not used in the fit).
    sample_indices : ndarray of shape (M,)
        The fast-sample index ``n_m`` of each slow sample.
    lags : ndarray of shape (max_lag + 1,)
        Autocorrelation lags ``0..max_lag``, in slow samples.
    autocorrelation : ndarray of shape (max_lag + 1,)
        ``r(k)``; ``r(0) = 1``.
    autocorrelation_bound : ndarray of shape (max_lag + 1,)
        Half width of the band of ``r(k)`` for white residuals.
    input_lags : ndarray of shape (n_input_lags,)
        Cross-correlation lags ``tau``, in fast samples.
    cross_correlation : ndarray of shape (n_inputs, n_input_lags)
        ``c_j(tau)``, one row per input.
    cross_correlation_bound : ndarray of shape (n_inputs, n_input_lags)
        Half width of the band of ``c_j(tau)``.
    confidence : float
        The level of the bands and of the test (0.99 by default).
    ljung_box : float
        The Ljung-Box statistic ``Q`` over lags ``1..max_lag``.
    p_value : float
        ``P(chi2(max_lag) >= Q)``.
    feedback_statistic : ndarray of shape (n_inputs,)
        Per input, the feedback test's statistic (chi-squared with 3
        degrees of freedom in open loop); NaN where the record is too short.
    feedback_p_value : ndarray of shape (n_inputs,)
        Per input, its p-value: small when the input depends on past residuals.

    Examples
    --------
    >>> import numpy as np
    >>> import gpmultirate as gm
    >>> from gpmultirate.residuals import analyze_residuals
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(900)
    >>> y = np.convolve(u, 0.7 ** np.arange(20))[:900] + 0.1 * rng.standard_normal(900)
    >>> model = gm.LeastSquaresFIR(factor=3, order=20).fit(u, y[::3])
    >>> analysis = analyze_residuals(model, u, y[::3])
    >>> analysis.white, analysis.autocorrelation.shape, analysis.cross_correlation.shape
    (True, (26,), (1, 151))
    """

    residuals: np.ndarray
    sample_indices: np.ndarray
    lags: np.ndarray
    autocorrelation: np.ndarray
    autocorrelation_bound: np.ndarray
    input_lags: np.ndarray
    cross_correlation: np.ndarray
    cross_correlation_bound: np.ndarray
    confidence: float
    ljung_box: float
    p_value: float
    feedback_statistic: np.ndarray | None = None
    feedback_p_value: np.ndarray | None = None

    @property
    def n_residuals(self) -> int:
        """``N``: the measured residuals the correlations are computed from."""
        return int(np.sum(np.isfinite(self.residuals)))

    @property
    def standardized(self) -> np.ndarray:
        """The residuals divided by their root mean square (NaN kept)."""
        e = self.residuals
        return e / np.sqrt(np.nanmean(e * e))

    @property
    def white(self) -> bool:
        """Whether the Ljung-Box test accepts whiteness at level ``1 - confidence``."""
        return bool(self.p_value >= 1.0 - self.confidence)

    @property
    def share_outside(self) -> float:
        """Share of the lags ``1..max_lag`` whose autocorrelation is outside the band."""
        outside = np.abs(self.autocorrelation[1:]) > self.autocorrelation_bound[1:]
        return float(np.mean(outside)) if outside.size else 0.0

    @property
    def closed_loop(self) -> bool:
        """Whether an input depends on past residuals at level ``1 - confidence``.

        The data then look closed-loop: fit with ``excitation=`` (:doc:`/closed_loop`).
        """
        if self.feedback_p_value is None:
            return False
        p = np.asarray(self.feedback_p_value)
        return bool(np.any(p[np.isfinite(p)] < 1.0 - self.confidence))

    @property
    def input_share_outside(self) -> np.ndarray:
        """Per input, the share of input lags whose cross-correlation is outside the band."""
        return np.mean(np.abs(self.cross_correlation) > self.cross_correlation_bound, axis=1)


def _normal_quantile(confidence: float) -> float:
    return float(stats.norm.ppf(0.5 + 0.5 * confidence))


def residual_correlations(residuals, sample_indices, u, *, max_lag: int, input_lags,
                          confidence: float) -> ResidualAnalysis:
    """The :class:`ResidualAnalysis` of given residuals (NaN: not measured).

    The model-free part of :func:`analyze_residuals`, for residuals computed
    elsewhere.

    Parameters
    ----------
    residuals : array-like of shape (M,)
        Residuals at the slow samples; NaN where none.
    sample_indices : array-like of int, shape (M,)
        Strictly increasing fast-sample index of each residual, in ``0..N-1``.
    u : array-like of shape (N,) or (N, n_inputs)
        The fast-rate input(s).
    max_lag : int
        Autocorrelation lags ``0..max_lag`` (slow samples), ``max_lag >= 1``.
    input_lags : array-like of int
        Cross-correlation lags in fast samples.
    confidence : float
        Level of the bands and of the test, in (0, 1).

    Returns
    -------
    ResidualAnalysis

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.residuals import residual_correlations
    >>> e = np.random.default_rng(1).standard_normal(400)
    >>> analysis = residual_correlations(e, np.arange(400), np.ones(400), max_lag=10,
    ...                                  input_lags=[0], confidence=0.99)
    >>> bool(np.isclose(analysis.autocorrelation_bound[1], 2.5758 * np.sqrt(399) / 400,
    ...                 rtol=1e-4))
    True
    """
    e = np.array(residuals, dtype=float).reshape(-1)
    x = check_inputs(u)
    index = check_sample_indices(sample_indices, x.shape[0])
    if index.shape != e.shape:
        raise ValueError(
            f"sample_indices must have one entry per residual ({e.shape[0]}); got {index.shape[0]}"
        )
    if np.any(np.isinf(e)):
        raise ValueError("residuals must be finite or NaN (not measured)")
    confidence = check_level(confidence, "confidence")
    measured = np.isfinite(e)
    N = int(measured.sum())
    max_lag = check_int(max_lag, "max_lag", low=1)
    if N < 3:
        raise ValueError(
            f"the residuals have {N} measured (finite) samples; their correlation needs at "
            "least 3 (is y_slow all NaN?)"
        )
    if N < max_lag + 2:
        raise ValueError(
            f"max_lag must be below the number of measured residuals minus one ({N - 1}); "
            f"got {max_lag}"
        )
    lags_in = np.asarray(input_lags)
    if lags_in.ndim != 1 or lags_in.size == 0 or lags_in.dtype.kind not in "iu":
        raise ValueError("input_lags must be a non-empty 1-D array of integers")
    input_lags = lags_in.astype(np.int64)
    z = _normal_quantile(confidence)
    # the correlations are scale-free: read them on residuals and inputs scaled to a
    # largest magnitude of one, so that data near the float range do not overflow
    peak_e = max(float(np.max(np.abs(np.where(measured, e, 0.0)))), np.finfo(float).tiny)
    filled = np.where(measured, e / peak_e, 0.0)
    peak_u = np.max(np.abs(x), axis=0)
    x = x / np.where(peak_u > 0, peak_u, 1.0)
    mask = measured.astype(float)
    energy = float(filled @ filled)
    if energy == 0.0:
        raise ValueError("the residuals are all zero: their correlation is undefined")

    lags = np.arange(max_lag + 1)
    M = e.shape[0]
    auto = np.array([filled[: M - k] @ filled[k:] for k in lags]) / energy
    pairs = np.array([mask[: M - k] @ mask[k:] for k in lags])
    auto_bound = z * np.sqrt(pairs) / N
    # Ljung-Box with the pair counts N_k in place of N - k (gaps allowed)
    used = pairs[1:] > 0
    q = float(N * (N + 2) * np.sum(auto[1:][used] ** 2 / pairs[1:][used]))
    p_value = float(stats.chi2.sf(q, df=max_lag))

    rms_e = np.sqrt(energy / N)
    n_inputs = x.shape[1]
    cross = np.zeros((n_inputs, input_lags.shape[0]))
    cross_bound = np.zeros_like(cross)
    rms_u = np.sqrt(np.mean(x * x, axis=0))
    for t, tau in enumerate(input_lags):
        source = index - tau
        inside = (source >= 0) & (source < x.shape[0]) & measured
        values = x[source[inside]]  # (pairs, n_inputs)
        cross[:, t] = filled[inside] @ values
        cross_bound[:, t] = np.sqrt(np.sum(values * values, axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(rms_u > 0, 1.0 / (N * rms_u), 0.0)[:, None]
    cross = cross * scale / rms_e
    cross_bound = z * cross_bound * scale
    steps = np.diff(index)
    frame = max(1, int(np.median(steps))) if steps.size else 1
    tests = [feedback_test(e / peak_e, index, x[:, j], frame) for j in range(n_inputs)]
    feedback = np.array([[np.nan, np.nan] if t is None else [t.statistic, t.p_value]
                         for t in tests])

    def frozen(a):
        a = np.array(a)
        a.setflags(write=False)
        return a

    return ResidualAnalysis(
        residuals=frozen(e), sample_indices=frozen(index), lags=frozen(lags),
        autocorrelation=frozen(auto), autocorrelation_bound=frozen(auto_bound),
        input_lags=frozen(input_lags), cross_correlation=frozen(cross),
        cross_correlation_bound=frozen(cross_bound), confidence=confidence,
        ljung_box=q, p_value=p_value, feedback_statistic=frozen(feedback[:, 0]),
        feedback_p_value=frozen(feedback[:, 1]),
    )


def analyze_residuals(model, u, y_slow, sample_indices=None, *, sample_times=None,
                      max_lag: int = 25, input_lags=None,
                      confidence: float = 0.99) -> ResidualAnalysis:
    """Autocorrelation and input cross-correlations of a fitted model's slow residuals.

    The residuals are ``y_slow[m] - model.predict(u)[n_m]`` with
    ``n_m = offset + m * factor`` (the model's own ``factor`` and
    ``offset``) or ``sample_indices[m]``; for readings at their own
    instants, ``y_slow[m] - model.predict(u, sample_times=t)[m]`` (the
    model's reading, exposure and latency applied), with ``n_m`` the tick
    of ``t[m]`` for the cross-correlations.  With
    ``initial_conditions="discard"`` the samples the fit did not use (fast
    index below ``order - 1``) are left out, as are ``NaN`` samples.

    Parameters
    ----------
    model : fitted FIRGaussianProcess or LeastSquaresFIR
        Anything with ``predict(u)`` and the attributes ``factor``,
        ``offset`` and ``initial_conditions`` of the FIR estimators.
    u : array-like of shape (N,) or (N, n_inputs)
        Fast-rate input, one record, as in ``fit``.
    y_slow : array-like of shape (M,)
        Slow output, as in ``fit``; ``NaN`` marks a sample not measured.
    sample_indices : array-like of int, optional
        Fast-sample index of each slow sample; ``factor`` and ``offset`` are
        then not used.
    sample_times : array-like of float, optional
        The instant of each slow sample in the units of the model's
        ``sample_time`` (seconds; fast sample periods when it is 1), as in
        ``fit(..., sample_times=t)``; not with ``sample_indices``.
    max_lag : int, default=25
        Largest autocorrelation lag, in slow samples (also the number of
        lags of the Ljung-Box test).
    input_lags : array-like of int, optional
        Cross-correlation lags in fast samples; by default
        ``-max_lag * factor .. max_lag * factor``.
    confidence : float, default=0.99
        Level of the bands and of the whiteness test.

    Returns
    -------
    ResidualAnalysis

    Raises
    ------
    ValueError
        If ``y_slow`` does not match the slow samples of ``u``, or an argument
        is out of range.

    Examples
    --------
    An FIR model fitted to data with coloured (AR(1)) noise: its residuals
    are not white.

    >>> import numpy as np
    >>> import gpmultirate as gm
    >>> from gpmultirate.residuals import analyze_residuals
    >>> rng = np.random.default_rng(3)
    >>> u = rng.standard_normal(1500)
    >>> noise = np.zeros(500)
    >>> for m in range(1, 500):
    ...     noise[m] = 0.8 * noise[m - 1] + 0.1 * rng.standard_normal()
    >>> y_slow = np.convolve(u, 0.7 ** np.arange(20))[:1500:3] + noise
    >>> model = gm.LeastSquaresFIR(factor=3, order=20).fit(u, y_slow)
    >>> analysis = analyze_residuals(model, u, y_slow)
    >>> analysis.white, analysis.share_outside > 0.2
    (False, True)
    """
    x = check_inputs(u)
    N = x.shape[0]
    y = np.array(y_slow, dtype=float)
    if y.ndim == 2 and 1 in y.shape:
        y = y.reshape(-1)
    if y.ndim != 1:
        raise ValueError(f"y_slow must be 1-D (one record); got shape {y.shape}")
    if np.any(np.isinf(y)):
        raise ValueError("y_slow must be finite or NaN (not measured)")
    if sample_times is not None:
        if sample_indices is not None:
            raise ValueError("give sample_indices or sample_times, not both")
        stamps = np.array(sample_times, dtype=float).reshape(-1)  # in sample_time's units
        if stamps.shape[0] != y.shape[0] or not np.all(np.isfinite(stamps)):
            raise ValueError(f"sample_times must hold one finite instant per slow sample "
                             f"({y.shape[0]}); got {np.shape(sample_times)}")
        times = in_fast_periods(stamps, getattr(model, "sample_time", 1.0), x)
        index = np.floor(times).astype(np.int64)
        factor = max(1, int(round(float(np.median(np.diff(times)))))) if times.size > 1 else 1
    elif sample_indices is None:
        factor, offset = model.factor, model.offset
        index = np.arange(offset, N, factor)
        if index.shape[0] != y.shape[0]:
            raise ValueError(
                f"y_slow must have len(range(offset, N, factor)) = {index.shape[0]} samples for "
                f"N = {N}, factor = {factor}, offset = {offset}; got {y.shape[0]}"
            )
    else:
        factor = 1
        index = check_sample_indices(sample_indices, N)
        if index.shape[0] != y.shape[0]:
            raise ValueError(
                f"sample_indices must have one entry per slow sample ({y.shape[0]}); "
                f"got {index.shape[0]}"
            )
        steps = np.diff(index)
        if steps.size:
            factor = int(np.median(steps))
    inputs = x if x.shape[1] > 1 else x[:, 0]
    if sample_times is not None:
        residuals = y - np.asarray(model.predict(inputs, sample_times=stamps), dtype=float)
    else:
        residuals = y - np.asarray(model.predict(inputs), dtype=float)[index]
    if getattr(model, "initial_conditions", "zero") == "discard":
        order = int(np.asarray(model.coef_).shape[-1])
        residuals[index < order - 1] = np.nan
    if input_lags is None:
        reach = check_int(max_lag, "max_lag", low=1) * factor
        input_lags = np.arange(-reach, reach + 1)
    elif isinstance(input_lags, numbers.Integral):
        raise ValueError("input_lags must be an array of integer lags, not a single number")
    return residual_correlations(residuals, index, x, max_lag=max_lag, input_lags=input_lags,
                                 confidence=confidence)
