"""What the residuals of a fit say is missing, and what to change.

:func:`~gpmultirate.residuals.analyze_residuals` answers *whether* the slow
residuals look white; :func:`explain_residuals` says *why not*: which
structure is left and which option of the estimator takes it up.

Three readings of a :class:`~gpmultirate.residuals.ResidualAnalysis`, each a
test at the analysis' level ``1 - confidence`` (Bonferroni over the three):

* **A peak in the residual spectrum.**  The periodogram ``I(f_k)`` of the
  standardized residuals over their slow samples, at the Fourier
  frequencies ``f_k = k / M`` (cycles per slow sample, ``0 < k < M / 2``),
  is exponentially distributed around its mean for white residuals; the
  largest ordinate over the mean, ``g = max I / mean I``, exceeds ``x``
  with probability at most ``n exp(-x)`` (``n`` ordinates; Fisher's test,
  first term).  A significant peak at slow frequency ``f`` comes from a
  fast-rate frequency that aliases onto it: ``|f_fast - j f_s| = f`` for
  an integer ``j``, ``f_s`` the slow rate; :attr:`ResidualFinding.aliases`
  lists them up to the fast Nyquist frequency.  A peak at the lowest
  frequencies (``k <= max(2, M / 100)``) is reported as a *drift*.
* **Correlation with the input.**  The standardized cross-correlations
  ``c_j(tau) / s_j(tau)`` (``s`` the band over ``z``) are about independent
  standard normal for residuals independent of the input; their squares
  summed over the lags ``tau >= 0`` are chi-squared.  Correlation at lags
  beyond the model's order means the order is too short; at shorter lags,
  dynamics the prior shrank away.

The remedies follow what the estimator's automatic layer does: a peak that
the input explains, or that falls where the model's own frequency response
has a peak, is a resonance the default kernel misses: ``kernel="auto"``
searches for it (``--kernel auto``), and after a fit that searched already, a
:class:`~gpmultirate.kernels.PK` term near it given by hand (the search
dropped it or did not reach it); correlation beyond the order asks for
a longer ``order``; a peak or a drift that the input does not explain is a
disturbance: ``noise_kernel="auto"`` (``--noise auto``) keeps one where the
evidence calls for it; where the fit's ``"auto"`` already kept white noise,
a named one, ``"matern32"`` (``"matern12"`` for a drift), which is fitted
whatever the evidence says.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

__all__ = ["ResidualExplanation", "ResidualFinding", "explain_residuals", "whiteness_p_value"]

#: Tests of :func:`explain_residuals`: the level is shared among them.
N_TESTS = 3


@dataclass(frozen=True)
class ResidualFinding:
    """One structure left in the residuals, and what takes it up.

    Attributes
    ----------
    kind : {"peak", "drift", "input"}
        A peak in the residual spectrum, a slow drift, or correlation with
        the input.
    frequency : float or None
        For a peak or a drift: its slow-rate frequency in Hz (cycles per
        fast sample period for ``sample_time=1``).
    aliases : tuple of float
        For a peak: the fast-rate frequencies (Hz, up to the fast Nyquist
        frequency) that alias onto ``frequency`` at the slow rate, the
        likeliest source first when a model was given.
    lag : int or None
        For correlation with the input: the fast lag of the largest
        standardized cross-correlation (``tau > 0``: the input earlier).
    input : int or None
        The input of that correlation.
    p_value : float
        The test's p-value (before the Bonferroni share).
    remedy : str
        The estimator option that takes the structure up, in Python's words
        (``kernel="auto"``, ``order=...``, ``noise_kernel="auto"``; after a
        fit with ``kernel="auto"``, a PK term by hand or a longer order).
    text : str
        One sentence for a report.
    """

    kind: str
    frequency: float | None
    aliases: tuple
    lag: int | None
    input: int | None
    p_value: float
    remedy: str
    text: str


@dataclass(frozen=True)
class ResidualExplanation:
    """The reasons a fit's residuals are not white (none when they are).

    Made by :func:`explain_residuals`.

    Attributes
    ----------
    white : bool
        Whether the residuals pass the Ljung-Box test at the analysis' level.
    p_value : float
        Its p-value: under the fitted model (:func:`whiteness_p_value`) where
        ``calibrated``, else the chi-squared one of the analysis.
    findings : tuple of ResidualFinding
        The structures found, strongest first; empty when the residuals are
        white or nothing specific was found.
    calibrated : bool
        Whether ``p_value`` is the one under the fitted model.
    """

    white: bool
    p_value: float
    findings: tuple = ()
    calibrated: bool = False

    @property
    def remedies(self) -> tuple:
        """The distinct remedies of the findings, in their order."""
        return tuple(dict.fromkeys(f.remedy for f in self.findings))

    @property
    def text(self) -> str:
        """The verdict and its reasons as one paragraph."""
        if self.white:
            return f"the residuals look white (Ljung-Box p = {self.p_value:.3g})"
        head = f"the residuals do not look white (Ljung-Box p = {self.p_value:.3g})"
        if not self.findings:
            return (head + "; no single peak, drift or input correlation stands out: try "
                    "noise_kernel=\"auto\" (a disturbance model)")
        return head + ": " + "; ".join(f.text for f in self.findings)


def _periodogram(analysis):
    e = np.asarray(analysis.residuals, dtype=float)
    e = e[np.isfinite(e)]
    e = e - e.mean()
    M = e.shape[0]
    spectrum = np.abs(np.fft.rfft(e)) ** 2
    k = np.arange(1, (M - 1) // 2 + 1)  # 0 < f_k < 1/2: exponential for white residuals
    return k / M, spectrum[k], M


def _aliases(slow_frequency, factor, sample_time):
    """Fast-rate frequencies (Hz) up to the fast Nyquist frequency that alias onto it."""
    fs_slow = 1.0 / (factor * sample_time)
    nyquist = 0.5 / sample_time
    found = []
    for j in range(factor + 1):
        for f in (j * fs_slow - slow_frequency, j * fs_slow + slow_frequency):
            if 0 <= f <= nyquist * (1 + 1e-12) and not any(np.isclose(f, g) for g in found):
                found.append(float(f))
    return sorted(found)


def _model_gain(model, frequencies, sample_time, n_input=0):
    coef = np.asarray(model.coef_, dtype=float)
    g = coef[n_input] if coef.ndim == 2 else coef
    lags = np.arange(g.shape[0])
    omega = 2 * np.pi * np.asarray(frequencies) * sample_time
    return np.abs(np.exp(-1j * np.outer(omega, lags)) @ g)


def _on_a_peak(model, frequency, sample_time) -> bool:
    """Whether ``frequency`` lies on a peak of the model's gain: within 10 % of a local
    maximum that stands 3 dB above the gain a decade around it."""
    nyquist = 0.5 / sample_time
    grid = np.linspace(0, nyquist, 2049)[1:]
    gain = _model_gain(model, grid, sample_time)
    peaks = np.flatnonzero((gain[1:-1] > gain[:-2]) & (gain[1:-1] >= gain[2:])) + 1
    for p in peaks:
        near = (grid > grid[p] / 3) & (grid < grid[p] * 3)
        if gain[p] > np.sqrt(2) * np.median(gain[near]) and abs(frequency - grid[p]) <= \
                0.1 * grid[p] + 2 * (grid[1] - grid[0]):
            return True
    return False


def _ljung_box(e, measured, max_lag):
    """The Ljung-Box statistic of each column of ``e`` (zero where not measured), with the
    pair counts of :func:`~gpmultirate.residuals.residual_correlations`."""
    M = e.shape[0]
    N = int(measured.sum())
    mask = measured.astype(float)
    energy = np.sum(e * e, axis=0)
    q = np.zeros(e.shape[1])
    for k in range(1, max_lag + 1):
        pairs = mask[: M - k] @ mask[k:]
        if pairs > 0:
            r = np.sum(e[: M - k] * e[k:], axis=0) / energy
            q += r * r / pairs
    return N * (N + 2) * q


def _regressor_products(x, index, order, periodic):
    """``Phi^T e`` and ``Phi g`` of the slow samples at ``index`` by FFT (one record)."""
    n, n_inputs = x.shape
    length = n if periodic else int(2 ** np.ceil(np.log2(n + order)))
    spectra = np.fft.rfft(x, n=length, axis=0)  # (freq, inputs)

    def transpose_times(e):  # (M, draws) -> (n_inputs * order, draws)
        placed = np.zeros((n, e.shape[1]))
        placed[index] = e
        z = np.fft.rfft(placed, n=length, axis=0)
        out = [np.fft.irfft(z * np.conj(spectra[:, j:j + 1]), n=length, axis=0)[:order]
               for j in range(n_inputs)]
        return np.concatenate(out, axis=0)

    def times(g):  # (n_inputs * order, draws) -> (M, draws)
        total = 0.0
        for j in range(n_inputs):
            gj = np.fft.rfft(g[j * order:(j + 1) * order], n=length, axis=0)
            total = total + np.fft.irfft(gj * spectra[:, j:j + 1], n=length, axis=0)[:n]
        return total[index]

    return transpose_times, times


def whiteness_p_value(analysis, model, u, *, n_draws: int = 400, random_state=0):
    """The p-value of the residuals' Ljung-Box statistic under the fitted model.

    The residuals of a fit are not white even when the model is right: they
    are ``e = (I - H) eps`` for white noise ``eps``, where the hat matrix
    ``H = Phi Sigma Phi^T / sigma^2`` (``Sigma`` the posterior covariance of the
    coefficients, ``sigma^2`` the noise variance; least squares: the
    projection on the regressor) couples neighbouring samples, so the
    chi-squared law of :func:`~gpmultirate.residuals.residual_correlations`
    calls well-specified fits coloured too often (5-10 % at its 1 % level on
    100 slow samples).  Here the statistic's null law is that of
    ``(I - H) eps`` under the fitted model: its mean and variance over
    ``n_draws`` draws give a scaled chi-squared law (Satterthwaite), whose
    tail is the p-value.

    Parameters
    ----------
    analysis : ResidualAnalysis
        Of ``model`` on the record ``u`` (:func:`~gpmultirate.residuals.analyze_residuals`).
    model : fitted FIRGaussianProcess or LeastSquaresFIR
        Fitted on the ticks (not readings at their own instants), with
        white noise.
    u : array-like of shape (N,) or (N, n_inputs)
        The record's input.
    n_draws : int, default=400
    random_state : int or None, default=0

    Returns
    -------
    float or None
        None where the model is outside this test's reach (a disturbance
        model, readings at their own instants, several records): the
        chi-squared p-value of the analysis is then the one to read.

    Examples
    --------
    >>> import numpy as np
    >>> import gpmultirate as gm
    >>> from gpmultirate.residuals import analyze_residuals
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> y = np.convolve(u, 0.7 ** np.arange(30))[:300:3] + 0.1 * rng.standard_normal(100)
    >>> model = gm.FIRGaussianProcess(order=30, factor=3).fit(u, y)
    >>> analysis = analyze_residuals(model, u, y)
    >>> p = whiteness_p_value(analysis, model, u)
    >>> 0 < p <= 1
    True
    """
    from gpmultirate.validation import check_inputs

    if getattr(model, "exposure", 0) or getattr(model, "latency", 0):
        return None
    if getattr(model, "observation_", None) is not None and \
            type(model.observation_).__name__ not in ("DownsampledConvolution",
                                                      "SampledConvolution"):
        return None
    noise = getattr(model, "noise_kernel_", "white")
    if not isinstance(noise, str) or noise != "white":
        return None
    x = check_inputs(u)
    e_obs = np.asarray(analysis.residuals, dtype=float)
    measured = np.isfinite(e_obs)
    index = np.asarray(analysis.sample_indices)[measured]
    coef = np.asarray(model.coef_, dtype=float)
    order = coef.shape[-1]
    n_inputs = x.shape[1]
    if coef.size != n_inputs * order:
        return None
    periodic = getattr(model, "initial_conditions", "zero") == "periodic"
    transpose_times, times = _regressor_products(x, index, order, periodic)
    rng = np.random.default_rng(random_state)
    eps = rng.standard_normal((index.shape[0], int(n_draws)))
    if hasattr(model, "noise_level_"):  # Bayesian: g_hat = Sigma Phi^T y / sigma^2
        _, cov = model.impulse_response(return_cov=True)
        with np.errstate(all="ignore"):
            variance = np.float64(model.noise_level_)
            if getattr(model, "hyperparameter_units_", "data") == "normalized":
                variance = variance * np.float64(model.output_scale_) ** 2
            ratio = np.asarray(cov, dtype=float) / variance
        if not (np.isfinite(variance) and variance > 0 and np.all(np.isfinite(ratio))):
            return None  # beyond the float range: the chi-squared verdict stands
        fitted = times(ratio @ transpose_times(eps))
    else:  # least squares: the projection on the regressor
        eye = np.eye(n_inputs * order)
        phi = times(eye)
        fitted = phi @ np.linalg.lstsq(phi, eps, rcond=None)[0]
    residuals = np.zeros((e_obs.shape[0], int(n_draws)))
    residuals[measured] = eps - fitted
    max_lag = int(analysis.lags[-1])
    null = _ljung_box(residuals, measured, max_lag)
    observed = _ljung_box(np.where(measured, e_obs, 0.0)[:, None], measured, max_lag)[0]
    mean, var = float(np.mean(null)), float(np.var(null))
    if not (mean > 0 and var > 0):
        return None
    scale, dof = var / (2 * mean), 2 * mean * mean / var
    return float(stats.chi2.sf(observed / scale, dof))


def _searched(model) -> bool:
    """Whether ``model`` was fitted with the resonance search (``kernel="auto"``)."""
    params = model.get_params(deep=False) if hasattr(model, "get_params") else {}
    return isinstance(params.get("kernel"), str) and params.get("kernel") == "auto"


def _resonance_remedy(model, frequency_hz: float, sample_time: float) -> tuple[str, str]:
    """The remedy of a resonance the prior misses, and its words: the search
    (``kernel="auto"``), or where the fit searched already and kept no term there, a
    :class:`~gpmultirate.kernels.PK` term at that frequency given by hand."""
    if not _searched(model):
        return ('kernel="auto"',
                'kernel="auto" searches for the resonance (--kernel auto)')
    omega = 2.0 * np.pi * frequency_hz * sample_time
    remedy = f"a PK term near {frequency_hz:.4g} Hz in the kernel (PK(omega={omega:.4g}))"
    return remedy, (f'kernel="auto" kept no term there (its search dropped or did not reach '
                    f'it): {remedy}, given by hand')


def _disturbance(model, named: str) -> str:
    """The disturbance remedy: ``noise_kernel="auto"``, or a named disturbance where the
    fit's automatic choice already kept white noise (the evidence did not call for one)."""
    params = model.get_params(deep=False) if hasattr(model, "get_params") else {}
    chosen = getattr(model, "noise_kernel_", None)
    if params.get("noise_kernel") == "auto" and isinstance(chosen, str) and chosen == "white":
        return f'noise_kernel="{named}"'
    return 'noise_kernel="auto"'


def explain_residuals(analysis, model=None, *, u=None, factor=None, sample_time=None):
    """The structure left in non-white residuals, and the option that takes it up.

    Parameters
    ----------
    analysis : ResidualAnalysis
        :func:`~gpmultirate.residuals.analyze_residuals` of a fit.
    model : fitted FIR estimator, optional
        The model: its frequency response tells which fast-rate alias of a
        peak is a resonance, its order whether input correlation lies
        beyond it, its ``factor`` and ``sample_time`` are the defaults.
    u : array-like, optional
        With ``model``: the record's input; the verdict then reads the
        statistic against its law under the fitted model
        (:func:`whiteness_p_value`), which holds its level on well-specified
        fits.  Without it, the chi-squared verdict of the analysis.
    factor : int, optional
        Fast samples per slow sample; default the model's, else the median
        spacing of ``analysis.sample_indices``.
    sample_time : float, optional
        The fast sample time in seconds (frequencies in Hz); default the
        model's, else 1 (cycles per fast sample).

    Returns
    -------
    ResidualExplanation

    Examples
    --------
    A lightly damped mode at 0.12 cycles per fast sample, fitted with too
    short an order: the residuals correlate with the input beyond the order,
    and oscillate at 0.12 cycles per sample, which 0.21 and 0.45 alias onto at
    the slow rate 1/3.

    >>> import numpy as np
    >>> import gpmultirate as gm
    >>> from gpmultirate.residuals import analyze_residuals
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(1500)
    >>> g = 0.98 ** np.arange(200) * np.sin(2 * np.pi * 0.12 * np.arange(200))
    >>> y = np.convolve(u, g)[:1500:3] + 0.05 * rng.standard_normal(500)
    >>> model = gm.LeastSquaresFIR(factor=3, order=15).fit(u, y)
    >>> why = explain_residuals(analyze_residuals(model, u, y), model)
    >>> why.white, [finding.kind for finding in why.findings]
    (False, ['input', 'peak'])
    >>> peak = why.findings[1]
    >>> round(peak.frequency, 2), [round(f, 2) for f in peak.aliases], peak.remedy
    (0.12, [0.12, 0.21, 0.46], 'kernel="auto"')
    """
    confidence = float(analysis.confidence)
    level = (1.0 - confidence) / N_TESTS
    index = np.asarray(analysis.sample_indices)
    if factor is None:
        factor = getattr(model, "factor", None) if model is not None else None
        if factor is None or not index.size > 1:
            steps = np.diff(index)
            factor = max(1, int(np.median(steps))) if steps.size else 1
    if sample_time is None:
        sample_time = (getattr(model, "sample_time", None) if model is not None else None) or 1.0
    factor, sample_time = int(factor), float(sample_time)
    p_value, calibrated = float(analysis.p_value), False
    if model is not None and u is not None:
        null_p = whiteness_p_value(analysis, model, u)
        if null_p is not None:
            p_value, calibrated = null_p, True
    white = bool(p_value >= 1.0 - confidence)
    if white:
        return ResidualExplanation(white=True, p_value=p_value, calibrated=calibrated)
    findings = []

    # correlation with the input: the standardized cross-correlations at lags >= 0
    z = stats.norm.ppf(0.5 + 0.5 * confidence)
    lags = np.asarray(analysis.input_lags)
    bound = np.asarray(analysis.cross_correlation_bound) / z
    with np.errstate(invalid="ignore", divide="ignore"):
        standard = np.where(bound > 0, np.asarray(analysis.cross_correlation) / bound, 0.0)
    forward = lags >= 0
    input_p, input_found = 1.0, None
    for j in range(standard.shape[0]):
        q = float(np.sum(standard[j, forward] ** 2))
        p = float(stats.chi2.sf(q, df=max(int(forward.sum()), 1)))
        if p < input_p:
            input_p = p
            k = int(np.argmax(np.abs(np.where(forward, standard[j], 0.0))))
            input_found = (j, int(lags[k]))
    input_correlated = input_p < level
    order = None
    if model is not None and hasattr(model, "coef_"):
        order = int(np.asarray(model.coef_).shape[-1])

    # a peak in the residual spectrum
    frequencies, spectrum, M = _periodogram(analysis)
    if spectrum.size >= 2 and np.mean(spectrum) > 0:
        n = spectrum.size
        k = int(np.argmax(spectrum))
        g = float(spectrum[k] / np.mean(spectrum))
        peak_p = float(min(1.0, n * np.exp(-g)))
        slow_hz = float(frequencies[k] / (factor * sample_time))
        if peak_p < level:
            if k + 1 <= max(2, M // 100):  # the lowest Fourier frequencies: a drift
                remedy = _disturbance(model, "matern12")
                text = (f"a slow drift (residual power at {slow_hz:.3g} Hz and below): a "
                        f"disturbance model, {remedy} (--noise)")
                findings.append(ResidualFinding("drift", slow_hz, (), None, None, peak_p,
                                                remedy, text))
            else:
                aliases = _aliases(slow_hz, factor, sample_time)
                resonant = []
                if model is not None and hasattr(model, "coef_"):
                    gains = _model_gain(model, aliases, sample_time)
                    aliases = [aliases[i] for i in np.argsort(-gains)]
                    resonant = [f for f in aliases if _on_a_peak(model, f, sample_time)]
                alias_text = ", ".join(f"{f:.4g}" for f in aliases[:6])
                more = ", ..." if len(aliases) > 6 else ""
                if input_correlated or resonant:
                    source = (f"the model's peak at {resonant[0]:.4g} Hz" if resonant
                              else "a response to the input")
                    remedy, how = _resonance_remedy(
                        model, resonant[0] if resonant else aliases[0] if aliases else slow_hz,
                        sample_time)
                    why = f"dynamics the prior misses ({source}): {how}"
                else:
                    remedy = _disturbance(model, "matern32")
                    why = f"not explained by the input: a disturbance, {remedy} (--noise)"
                text = (f"a peak in the residual spectrum at {slow_hz:.4g} Hz (aliased from "
                        f"{alias_text}{more} Hz at the fast rate): {why}")
                findings.append(ResidualFinding("peak", slow_hz, tuple(aliases), None, None,
                                                peak_p, remedy, text))
    if input_correlated and input_found is not None:
        j, lag = input_found
        beyond = order is not None and lag >= order - factor
        searched = _searched(model)
        remedy = "order=\"auto\"" if beyond or searched else "kernel=\"auto\""
        why = (f"at lag {lag}, near or beyond the order {order}: a longer order "
               "(order=\"auto\", --order auto)" if beyond else
               f"largest at lag {lag}: dynamics the prior shrank away, "
               + ("with the resonance search's terms already in the kernel: a longer "
                  "order, or a kernel given by hand" if searched else
                  "kernel=\"auto\" (--kernel auto) or a longer order"))
        findings.append(ResidualFinding("input", None, (), lag, j, input_p, remedy,
                                        f"correlation with input {j} ({why})"))
    findings.sort(key=lambda f: f.p_value)
    return ResidualExplanation(white=False, p_value=p_value, findings=tuple(findings),
                               calibrated=calibrated)
