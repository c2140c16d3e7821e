"""Modes of the reduced model with credible intervals, and the peaks the data support.

The reduced model of a fit (:meth:`~gpmultirate.FIRGaussianProcess.to_state_space`,
``n`` states) has poles ``z_i``; each is a mode of the continuous-time
system with ``s_i = log(z_i) / T``:

* natural frequency ``f_i = |s_i| / (2 pi)`` in Hz (cycles per fast sample
  for ``T = 1``),
* damping ratio ``zeta_i = -Re(s_i) / |s_i|`` (1 for a real pole),
* gain: the mode's own contribution to ``|G|`` at its frequency,
  ``|r_i / (e^{j w_i} - z_i) + conj(r_i) / (e^{j w_i} - conj(z_i))|`` with
  ``w_i = angle(z_i)`` and the residue ``r_i = (C v_i)(w_i^T B)`` (``v_i``,
  ``w_i^T`` the right and left eigenvectors), the largest over the inputs:
  for a lightly damped mode, the height of its peak.

Their credible intervals come from posterior draws of the impulse response
(:meth:`~gpmultirate.FIRGaussianProcess.sample_impulse_responses`), each
reduced to the same order as in
:meth:`~gpmultirate.FIRGaussianProcess.sample_state_spaces`
(:func:`~gpmultirate.realization.leading_era`): each draw's modes are matched to the mean's (by
frequency on a log scale, :func:`scipy.optimize.linear_sum_assignment`) and
the intervals are the draws' central quantiles.

A peak of the frequency response of the posterior mean (a local maximum of
``|G|`` that stands at least ``PEAK_PROMINENCE_DB`` above the higher of the
valleys either side, within ``PEAK_RANGE_DB`` of the largest magnitude; the
``MAX_PEAKS`` highest) is *supported by the data* when, in at least ``level`` of the posterior
draws, ``|G|`` near the peak (within a tenth of its frequency) is above
``|G|`` at both valleys: the peak is then not an accident of the noise.  The
reduced model is consistent with the peaks when each supported peak that
stands above its higher valley by more than the reduction's error bound
(``2 sum`` of the discarded Hankel singular values, the most the reduced
model's ``|G|`` may differ from the FIR's) has a resonant mode
(``zeta < 1/sqrt(2)``) within a tenth of its frequency: a smaller peak the
reduced model may smooth away.

The intervals and the support are those of the posterior: they hold as far
as the fit's noise model does (white residuals,
:func:`gpmultirate.diagnosis.explain_residuals`); where the residuals are
coloured, they are too narrow.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.signal import find_peaks

from gpmultirate.realization import leading_era
from gpmultirate.validation import check_int, check_level

__all__ = ["FRFPeak", "ModalAnalysis", "Mode", "modal_analysis", "modes_of"]

#: How far a peak of ``|G|`` must stand above its higher valley to be called one, in dB
#: (a ripple of the FIR is not a peak).
PEAK_PROMINENCE_DB = 6.0
#: Peaks more than this far below the largest magnitude are not reported, in dB.
PEAK_RANGE_DB = 20.0
#: The most peaks reported: the highest.
MAX_PEAKS = 6
#: Damping ratios below this are resonant modes (a peak in ``|G|``).
RESONANT_DAMPING = 1 / np.sqrt(2)


@dataclass(frozen=True)
class Mode:
    """A mode of the reduced model, with credible intervals from posterior draws.

    Attributes
    ----------
    frequency : float
        Natural frequency in Hz.
    damping : float
        Damping ratio (1 for a real pole).
    gain : float
        The mode's own peak magnitude (see :mod:`gpmultirate.modes`).
    frequency_interval, damping_interval, gain_interval : tuple of float
        Central credible intervals at the analysis' level (NaN without draws).
    presence : float
        Share of the draws whose reduced model has this mode (matched within
        a factor 1.5 in frequency).
    """

    frequency: float
    damping: float
    gain: float
    frequency_interval: tuple
    damping_interval: tuple
    gain_interval: tuple
    presence: float

    @property
    def resonant(self) -> bool:
        """Whether the mode is lightly enough damped to make a peak."""
        return bool(self.damping < RESONANT_DAMPING)


@dataclass(frozen=True)
class FRFPeak:
    """A peak of the frequency response of the posterior mean.

    Attributes
    ----------
    frequency : float
        In Hz.
    magnitude : float
        ``|G|`` there.
    prominence : float
        ``|G|`` there minus ``|G|`` at the higher of its two valleys.
    probability : float
        Share of posterior draws in which the peak stands above both valleys.
    supported : bool
        ``probability >= level``.
    mode : int or None
        Index in :attr:`ModalAnalysis.modes` of the resonant mode within a
        tenth of its frequency, if any.
    """

    frequency: float
    magnitude: float
    prominence: float
    probability: float
    supported: bool
    mode: int | None


@dataclass(frozen=True)
class ModalAnalysis:
    """The reduced model's modes and the frequency response's peaks.

    Made by :func:`modal_analysis`.

    Attributes
    ----------
    n_states : int
        The order of the reduced model.
    modes : tuple of Mode
        By frequency.
    peaks : tuple of FRFPeak
        By frequency.
    level : float
        The level of the intervals and of the peaks' support.
    n_draws : int
        The posterior draws used.
    error_bound : float
        The reduction's bound on ``|G_reduced - G_FIR|`` at every frequency
        (NaN when unknown).
    """

    n_states: int
    modes: tuple
    peaks: tuple
    level: float
    n_draws: int
    error_bound: float = float("nan")

    @property
    def supported_peaks(self) -> tuple:
        """The peaks the data support."""
        return tuple(p for p in self.peaks if p.supported)

    @property
    def unmodelled_peaks(self) -> tuple:
        """Supported peaks above the reduction's error bound without a resonant mode."""
        bound = self.error_bound if np.isfinite(self.error_bound) else 0.0
        return tuple(p for p in self.supported_peaks if p.mode is None and p.prominence > bound)

    @property
    def consistent(self) -> bool:
        """Whether every supported peak above the reduction's error bound has a resonant
        mode of the reduced model."""
        return not self.unmodelled_peaks

    @property
    def text(self) -> str:
        """One sentence: how many peaks, which the data support, and the reduced order."""
        shown = ", ".join(f"{p.frequency:.4g} Hz" + ("" if p.supported else " (not supported, "
                                                         f"{100 * p.probability:.0f} % of draws)")
                          for p in self.peaks)
        resonant = sum(m.resonant for m in self.modes)
        line = (f"{len(self.peaks)} peak(s) in |G| ({shown or 'none'}); "
                f"{len(self.supported_peaks)} supported by the data at "
                f"{100 * self.level:g} %; the reduced model ({self.n_states} states) has "
                f"{resonant} resonant mode(s)")
        small = [p for p in self.supported_peaks if p.mode is None and p not in
                 self.unmodelled_peaks]
        if small:
            line += (f"; {len(small)} supported peak(s) stand less than the reduction's error "
                     f"bound ({self.error_bound:.3g}) above their valleys")
        if not self.consistent:
            line += ("; the peak(s) at " + ", ".join(f"{p.frequency:.4g} Hz" for p in
                                                     self.unmodelled_peaks)
                     + " have no mode: a higher n_states keeps them")
        return line


def modes_of(A, B, C, sample_time: float = 1.0) -> list[tuple[float, float, float]]:
    """``(frequency, damping, gain)`` of each mode of a discrete-time model, by frequency.

    A complex pair of poles is one mode.

    Parameters
    ----------
    A : array-like of shape (n, n)
    B : array-like of shape (n, n_inputs)
    C : array-like of shape (n_outputs, n)
    sample_time : float, default=1.0

    Returns
    -------
    list of (float, float, float)

    Examples
    --------
    A mode of 2 Hz with damping 0.05 sampled at 100 Hz:

    >>> import numpy as np
    >>> from gpmultirate.modes import modes_of
    >>> s = -0.05 * 2 * np.pi * 2 + 1j * 2 * np.pi * 2 * np.sqrt(1 - 0.05 ** 2)
    >>> z = np.exp(s * 0.01)
    >>> A = np.array([[z.real, -z.imag], [z.imag, z.real]])
    >>> [(round(f, 6), round(d, 6)) for f, d, _ in modes_of(A, np.eye(2)[:, :1],
    ...                                                     np.eye(2)[:1], 0.01)]
    [(2.0, 0.05)]
    """
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B = np.asarray(B, dtype=float).reshape(A.shape[0], -1)
    C = np.asarray(C, dtype=float).reshape(-1, A.shape[0])
    poles, right = np.linalg.eig(A)
    left = np.linalg.inv(right)
    found = []
    for i, z in enumerate(poles):
        if z.imag < -1e-12 * max(1.0, abs(z)) or z == 0:
            continue  # the pair's other half; a pole at 0 is a pure delay
        s = np.log(complex(z)) / sample_time
        frequency = abs(s) / (2 * np.pi)
        damping = float(-s.real / abs(s)) if abs(s) > 0 else 1.0
        residue = np.outer(C @ right[:, i], left[i] @ B)  # (n_outputs, n_inputs)
        at = np.exp(1j * np.angle(z))
        if abs(z.imag) > 1e-12 * max(1.0, abs(z)):
            contribution = residue / (at - z) + np.conj(residue) / (at - np.conj(z))
        else:
            at = np.sign(z.real) or 1.0
            contribution = residue.real / (at - z.real)
        found.append((float(frequency), damping, float(np.max(np.abs(contribution)))))
    return sorted(found)


def _frf(markov, nfft):
    """``|G|`` on the ``nfft // 2 + 1`` DFT frequencies, the largest over inputs."""
    return np.max(np.abs(np.fft.rfft(markov, n=nfft, axis=-1)), axis=0)


def modal_analysis(model, n_states: int | None = None, *, n_draws: int = 100,
                   level: float = 0.95, random_state=0, system=None) -> ModalAnalysis:
    """Modes of a fit's reduced model with credible intervals, and the supported peaks.

    Parameters
    ----------
    model : fitted FIRGaussianProcess
        With ``to_state_space`` and ``sample_impulse_responses``.
    n_states : int, optional
        The reduced order; by default that of ``model.to_state_space()``.
    n_draws : int, default=100
        Posterior draws of the impulse response.
    level : float, default=0.95
        Level of the intervals and of the peaks' support.
    random_state : int or None, default=0
        Seed of the draws.
    system : state-space model, optional
        The reduced model of the posterior mean (matrices ``A``, ``B``,
        ``C``), when it was made already (``model.to_state_space()``); its
        order is ``n_states``.

    Returns
    -------
    ModalAnalysis

    Examples
    --------
    One lightly damped mode at 0.1 cycles per sample:

    >>> import numpy as np
    >>> import gpmultirate as gm
    >>> from gpmultirate.modes import modal_analysis
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(600)
    >>> k = np.arange(80)
    >>> g = 0.93 ** k * np.sin(2 * np.pi * 0.1 * k)
    >>> y = np.convolve(u, g)[:600:2] + 0.05 * rng.standard_normal(300)
    >>> model = gm.FIRGaussianProcess(order=80, factor=2).fit(u, y)
    >>> modes = modal_analysis(model, n_draws=30)
    >>> mode = max(modes.modes, key=lambda m: m.gain)
    >>> true = abs(np.log(0.93 * np.exp(2j * np.pi * 0.1))) / (2 * np.pi)  # 0.1006
    >>> low, high = mode.frequency_interval
    >>> bool(low < true < high), round(mode.damping, 2), modes.n_states
    (True, 0.12, 2)
    >>> round(modes.peaks[0].frequency, 2), modes.peaks[0].supported, modes.consistent
    (0.1, True, True)
    """
    n_draws = check_int(n_draws, "n_draws", low=1)
    level = check_level(level, "level")
    sample_time = float(getattr(model, "sample_time", 1.0) or 1.0)
    if system is None:
        system = model.to_state_space(n_states)
    order = int(np.asarray(system.A).shape[0])
    singular = np.asarray(getattr(model, "hankel_singular_values_", []), dtype=float)
    error_bound = float(2 * singular[order:].sum()) if singular.size else float("nan")
    # the leading values of a long FIR's reduction: their tail is bounded, not summed
    if getattr(model, "state_space_order_", None) == order:
        error_bound = float(getattr(model, "state_space_error_bound_", error_bound))
    mean_modes = modes_of(system.A, system.B, system.C, sample_time)
    # one set of draws for the modes and the peaks: each reduced as the mean was
    # (the reduction of sample_state_spaces)
    coef = np.asarray(model.coef_, dtype=float).reshape(-1, np.shape(model.coef_)[-1])
    draws = np.asarray(model.sample_impulse_responses(n_samples=n_draws,
                                                      random_state=random_state))
    draws = draws.reshape(coef.shape[0], coef.shape[-1], n_draws)
    values = np.full((len(mean_modes), n_draws, 3), np.nan)
    if mean_modes:
        reference = np.log(np.maximum([m[0] for m in mean_modes], 1e-300))
        for d in range(n_draws):
            drawn = leading_era(draws[:, :, d].T[:, None, :], order)
            modes = modes_of(drawn.A, drawn.B, drawn.C, sample_time)
            if not modes:
                continue
            candidate = np.log(np.maximum([m[0] for m in modes], 1e-300))
            rows, cols = linear_sum_assignment(np.abs(reference[:, None] - candidate[None]))
            for i, j in zip(rows, cols):
                if abs(reference[i] - candidate[j]) <= np.log(1.5):
                    values[i, d] = modes[j]
    tails = (0.5 - level / 2, 0.5 + level / 2)

    def interval(x):
        x = x[np.isfinite(x)]
        return tuple(float(q) for q in np.quantile(x, tails)) if x.size else (np.nan, np.nan)

    result_modes = tuple(
        Mode(frequency=f, damping=z, gain=g, frequency_interval=interval(values[i, :, 0]),
             damping_interval=interval(values[i, :, 1]), gain_interval=interval(values[i, :, 2]),
             presence=float(np.mean(np.isfinite(values[i, :, 0]))))
        for i, (f, z, g) in enumerate(mean_modes))

    # the peaks of |G| of the posterior mean, and how often the draws keep them
    nfft = max(4096, 4 * coef.shape[-1])
    freqs = np.fft.rfftfreq(nfft, d=sample_time)
    gain = _frf(coef, nfft)
    drawn_gain = np.stack([_frf(draws[:, :, d], nfft) for d in range(n_draws)])
    with np.errstate(divide="ignore"):
        db = 20 * np.log10(np.maximum(gain, np.finfo(float).tiny))
    index, props = find_peaks(db, prominence=PEAK_PROMINENCE_DB,
                              height=float(np.max(db)) - PEAK_RANGE_DB)
    highest = np.sort(np.argsort(-gain[index], kind="stable")[:MAX_PEAKS])
    peaks = []
    for p, left, right in zip(index[highest], props["left_bases"][highest],
                              props["right_bases"][highest]):
        near = np.abs(freqs - freqs[p]) <= 0.1 * freqs[p]
        above = drawn_gain[:, near].max(axis=1) > np.maximum(drawn_gain[:, left],
                                                             drawn_gain[:, right])
        probability = float(np.mean(above))
        match = [i for i, m in enumerate(result_modes)
                 if m.resonant and abs(m.frequency - freqs[p]) <= 0.1 * freqs[p]]
        peaks.append(FRFPeak(frequency=float(freqs[p]), magnitude=float(gain[p]),
                             prominence=float(gain[p] - max(gain[left], gain[right])),
                             probability=probability, supported=probability >= level,
                             mode=match[0] if match else None))
    return ModalAnalysis(n_states=order, modes=result_modes, peaks=tuple(peaks), level=level,
                         n_draws=n_draws, error_bound=error_bound)
