"""Resonances found from the data: the search behind ``kernel="auto"``.

:func:`search_resonances` starts from the base kernel (``C * DC`` per input)
tuned by marginal likelihood and adds :class:`~gpmultirate.kernels.PK`
terms one at a time, greedily:

1. **scan** (:func:`resonance_scan`): with the current kernel and noise
   level fixed, the log evidence gain of one more PK term is computed for
   every frequency of a grid over ``(0, pi]`` radians per fast sample (the
   whole band up to the fast Nyquist frequency, so resonances above the
   slow Nyquist frequency, which the slow samples alias, are found too),
   for a few decay rates and, for each, the best amplitude.  The current
   data covariance is factored once; a candidate enters as a rank-two
   update (matrix determinant lemma, Woodbury identity);
2. **joint refinement**: the best candidate is added as a mode behind the
   input's hold (``PK(hold=True)``: zero at lag 0, its step response on the
   first cell; the scan reads the paper's basis, one lag of ``P`` apart)
   and all PK terms, the
   overall scale of the base kernel and the noise level are tuned together
   on a diagonal-plus-low-rank form of the data covariance, ``O(M P r)``
   per evaluation for ``r`` terms, on the base kernel's tuned shape; the
   term is kept when the log evidence grew by more than
   :data:`SEARCH_THRESHOLD` nats and the term is resonant (damping ratio
   below :data:`MAX_DAMPING`), otherwise the search stops; it also stops
   after ``max_resonances`` terms.  The terms keep these values: the
   base kernel's shape is not tuned again with them (that tuning cost as
   much as the rest of the search, moved the fit by hundredths of a point
   and left bands at a point that is not the evidence's optimum of the
   terms);
3. **pruning by evidence**: each term's evidence gain is the log evidence
   minus that of the model without it, **the other terms**, the scale and
   the noise re-tuned: a term whose work another term can take over
   (a slow-rate twin the input does not separate from its mode) gains
   little, a mode the input separates from its twin keeps its gain; while
   a term gains at most :data:`EVIDENCE_THRESHOLD` nats or is not
   resonant, the weakest is removed and the rest re-tuned;
4. **persistent images** (:func:`persistent_aliases`): a nearly undamped
   term whose folded frequency is near DC (within
   :data:`PERSISTENT_CYCLES` cycles over the record of ``k / F``) is
   dropped: in the slow samples it is a slowly wandering signal on which a
   slow disturbance regresses, in held-out blocks too;
5. **held-out check** (:func:`held_out_resonances`): the evidence trusts the
   model, and on measured data a term can raise it by fitting a
   disturbance that does not repeat.  The slow samples are cut into
   contiguous blocks over time (as for ``tuning="cross_validation"``) and
   each block is predicted from the others
   (:func:`~gpmultirate.crossvalidation.held_out_predictions`).  The check
   judges **sets** of terms: a term is removed only when the others,
   re-tuned without it (as in step 3), predict the held-out samples as
   well (within :data:`HELD_OUT_GAIN` points, or a twentieth of the base
   kernel's held-out error where that is less), both the outputs and the
   outputs whitened by an AR model of the base kernel's held-out
   residuals; the terms left together must beat the tuned base kernel by
   as much, or the search returns the tuned base kernel.  A survivor is
   never judged with the values it had beside a partner that is gone (the
   failure of a rule by frequencies: it dropped one of a mode and its
   slow-rate alias, and the held-out check then dropped the survivor, which
   alone predicts worse than no term).  The whitened fit is the
   one that matters against slow disturbances (drift, level steps): a
   slow, nearly undamped term turns the input's history into a slowly
   wandering signal that follows such a disturbance within the record,
   even in held-out blocks (a spurious regression of one persistent
   signal on another), but not its changes from one sample to the next,
   nor on a new record;
6. **the frequencies' spread**: the kept terms get ``omega_std`` and
   ``rate_std`` (:class:`~gpmultirate.kernels.PK`), the standard
   deviations of their frequency and decay rate in the Laplace
   approximation of the evidence at the tuned values (its Hessian by
   central differences of the analytic gradient), as a posterior spread
   (``posterior_spread=True``): the fit conditions on the data without it
   and adds it to the posterior afterwards
   (:mod:`gpmultirate.kernels.spread`; in the prior, the same data narrowed
   it to a tenth to a third of its effect at long lags).  Without it a PK
   term of rank two knows the phase of its response at every lag, and a
   tuned frequency off by a fraction of a percent leaves the truth outside
   the 95 % band at long lags;
7. **under the disturbance** (:func:`resonances_under_disturbance`): the
   search works with white noise; where the fit then chooses a coloured
   disturbance (``noise_kernel``), each term is judged again with it, by
   its evidence gain and the held-out check, for a term may have done
   what the disturbance now does; and the base kernel of each input with
   terms, by its evidence gain beside them (:data:`EVIDENCE_THRESHOLD`),
   for a base the terms leave idle takes up the disturbance's slow part
   that the input happens to share.  Where the data call for a
   disturbance before any term is found, a fit runs the whole search on
   the samples whitened by that disturbance's covariance
   (:func:`gpmultirate.fitting.auto_kernel.search_under_disturbance`,
   :class:`~gpmultirate.observations.WhitenedObservation`): white noise
   there, so every step above applies unchanged, and the held-out check
   is left to this step, under the disturbance itself.

A search step refines the scan's best candidate and, when that one fails
(:data:`SEARCH_THRESHOLD`, or not resonant), the scan's best outside
:data:`RUNNER_UP_SPAN` of it when the scan gave that one more than
:data:`EVIDENCE_THRESHOLD` nats: the scan holds
the base kernel's shape, and its order of two modes is not always the
order their refinements give.

Failure modes: a mode whose slow-rate alias falls on another mode and that
the input does not separate from it (no power at one of the two
frequencies, or the same content at both) is represented by one term, the
better-supported of the two, whose frequency may be the alias: the slow
samples predict as well, the response between them is wrong at the
other frequency; the data cannot say more.  Under a slow drift that a
fit takes for white noise (no disturbance chosen before the search), the
drift dominates the scans: terms near the slow-rate images of zero
frequency follow it, and weak modes go unseen.  The spread is first order in
the frequency: at a high signal-to-noise ratio with a frequency the data
resolve poorly, the band is still too narrow (a Monte Carlo of
``tests/test_resonances.py`` measures it).  The held-out check does not
run beyond :data:`~gpmultirate.orders.MAX_CHECKED_SAMPLES` slow samples;
there the evidence alone decides.

The threshold is an approximate Bayes factor: a PK term brings four
hyperparameters and its frequency is chosen among a few hundred
candidates.  Without a resonance the best gain over the grid is the largest
of many ``chi^2_2 / 2`` draws, about ``log(n_candidates) ~ 7`` nats; 12
nats is an evidence ratio of ``e^12 ~ 1.6e5``, which also pays a BIC-like
Occam penalty ``2 log M`` for the four hyperparameters up to ``M ~ 400``
slow samples.  The search stage asks a new term for twice as much: on the
base kernel's shape tuned without resonances, terms that only make up for
that shape gained 15-18 nats when it was tuned again with them; the
pruning, against the other terms re-tuned, asks for the 12 nats.

Cost: one tuning of the base kernel and one eigendecomposition of its data
covariance, shared by the scans and the refinements (the regressor rotated
into its eigenvectors once per input, ``O(M^2 P)``); per found resonance
one scan (``O(M P log P)`` per decay rate: the data whitened by that
decomposition, the terms found so far as a low-rank update, no
factorization of its own) and one joint refinement; the last,
unsuccessful scan and refinement; one re-tuning per subset of terms judged
(``O(M P r)`` per evaluation); the held-out check, one ``M x M``
factorization per kernel compared (skipped beyond
:data:`~gpmultirate.orders.MAX_CHECKED_SAMPLES` slow samples); the
spreads, ``2 (2 + 4 r)`` gradient evaluations.  Without resonances, one
tuning of the base kernel (the default fit), a scan and a refinement.
"""

from __future__ import annotations

import logging

import numbers
import warnings
from dataclasses import dataclass, field

import numpy as np
from sklearn.base import clone
from sklearn.gaussian_process.kernels import Kernel

from gpmultirate import tuning
from gpmultirate.covariance import (
    DenseCovariance,
    DiagonalPlusLowRank,
    SpectralCovariance,
    log_gaussian,
    woodbury_gain,
)
from gpmultirate.crossvalidation import contiguous_folds, held_out_predictions
from gpmultirate.exceptions import NumericalWarning
from gpmultirate.fitting.spread import gradient_hessian, marginal_variances
from gpmultirate.inference import LogEvidence, blas_threads_for
from gpmultirate.kernels import (
    PK,
    input_kernels,
    like_inputs,
    observe,
    resonance_summands,
    without_resonances,
)
from gpmultirate.kernels.lag import damped_sinusoids, mode_basis
from gpmultirate.kernels.spread import with_spreads
from gpmultirate.metrics import fit_percent
from gpmultirate.noise import WhiteNoise
from gpmultirate.orders import MAX_CHECKED_SAMPLES
from gpmultirate.validation import check_positive

__all__ = [
    "EVIDENCE_THRESHOLD", "HELD_OUT_GAIN", "MAX_DAMPING", "MIN_EXCITATION",
    "PERSISTENT_CYCLES", "PERSISTENT_DAMPING", "PREWHITENING_ORDER", "RUNNER_UP_SPAN",
    "SEARCH_THRESHOLD",
    "SPECTRA_BYTES",
    "Resonance", "ResonanceSearch", "alias_twins", "damping_ratio", "excitation",
    "held_out_resonances", "persistent_aliases", "resonance_scan", "resonances_under_disturbance",
    "search_resonances", "slowest_decay",
]

#: the logger of a fit's progress (see :mod:`gpmultirate.progress`)
_LOG = logging.getLogger("gpmultirate.fit")

#: log evidence gain (nats) a PK term must bring to be kept
EVIDENCE_THRESHOLD = 12.0
#: gain (nats) a new term must bring in the search, with the base kernel's shape fixed
SEARCH_THRESHOLD = 2.0 * EVIDENCE_THRESHOLD
#: bytes of the readings' damped spectra a search keeps from one scan to the next
#: (readings at their own instants: the four decays of 2,000 readings by 1,500 scanned
#: frequencies are about 190 MB, each 1.7 s of CPU to form)
SPECTRA_BYTES = 2**29
#: the factor either way about a failed candidate's frequency within which a search
#: step tries no other candidate of the same input (:func:`_scan_candidates`)
RUNNER_UP_SPAN = 1.4
#: damping ratio above which a tuned PK term is not a resonance (no peak)
MAX_DAMPING = 0.5
#: held-out fit (points of fit percent) a term must add to be kept
HELD_OUT_GAIN = 0.1
#: the factor either way within which the search scales the tuned base kernel
#: (``benchmarks/automatic.py``: the whole range of its amplitudes came 0.002 points
#: nearer the oracle on two-mass families and dropped real modes on drifting and
#: long-memory records)
SCALE_RANGE = 1e3
#: the order of the AR model of the base kernel's held-out residuals that whitens
#: them before the held-out fits are compared
PREWHITENING_ORDER = 4
#: cycles over the record below which a nearly undamped term's slow-rate image is a
#: persistent signal that a slow disturbance regresses on (:func:`persistent_aliases`)
PERSISTENT_CYCLES = 16
#: damping ratio below which a term near a slow-rate alias of DC is nearly undamped
PERSISTENT_DAMPING = 0.01
#: excitation (relative to its mean over the band) below which no resonance is searched
MIN_EXCITATION = 1e-2
# decay rates of the scan's candidates, in units of 1 / P (the envelope
# alpha^(t/2) falls by e^-r at lag P), and the amplitude grid (standard
# deviations relative to the data's scale)
_SCAN_DECAYS = (2.0, 6.0, 20.0, 60.0)
_SCAN_AMPLITUDES = np.geomspace(1e-4, 1e2, 31)


def slowest_decay(order: int) -> float:
    """The largest ``alpha`` of a resonance the search adds: it must decay within the order.

    An FIR model of order ``P`` says the response has died out by lag ``P``;
    a PK term whose envelope ``alpha^(t/2)`` has not (``alpha`` near 1) is no
    longer an impulse response but a persistent oscillation, which on
    measured data fits disturbances within the record and fails beyond it.
    The envelope must fall at least by ``e^-2`` (the slowest decay the scan
    tries) by lag ``P``: ``alpha <= exp(-4 / P)``.

    Examples
    --------
    >>> round(slowest_decay(600), 5)
    0.99336
    """
    return float(np.exp(-2.0 * _SCAN_DECAYS[0] / order))


@dataclass(frozen=True)
class Resonance:
    """One resonance found from the data.

    Attributes
    ----------
    frequency_hz : float
        Frequency of the PK term, ``omega / (2 pi T)`` with ``T`` the
        model's ``sample_time`` (cycles per fast sample when ``T = 1``).
    damping : float
        Damping ratio of the resonance: with the decay rate
        ``r = -log(alpha) / 2`` per fast sample of the response envelope,
        ``r / sqrt(r^2 + omega^2)``.
    evidence_gain : float
        Gain of the log evidence (nats) of the kept kernel over the kernel
        without the term, the other terms, the base kernel's scale and the
        noise tuned again without it.
    input : int
        The input whose kernel holds the term.
    """

    frequency_hz: float
    damping: float
    evidence_gain: float
    input: int = 0


@dataclass
class ResonanceSearch:
    """The outcome of :func:`search_resonances`.

    Attributes
    ----------
    kernel : sklearn Kernel
        The tuned kernel: the base kernel plus one PK term per resonance,
        each with the spread of its frequency and decay
        (``PK(posterior_spread=True)``).
    noise_level : float
        The tuned noise variance.
    optimizer_result : scipy.optimize.OptimizeResult or None
        The optimizer run of the base kernel (None when nothing is free);
        the terms are tuned by the search's joint refinement.
    resonances : list of Resonance
        The resonances in the order they were found, with their tuned
        frequencies and damping ratios.
    log_marginal_likelihood : float
        The log evidence of the kept kernel.
    history : list of float
        The log evidence of the tuned base kernel, after each term the
        search added and, when a term was added, of the kernel the
        pruning kept (and of the kernel the held-out check kept, when it
        dropped some terms but not all) and, last, of the kept terms tuned
        together once more with the scale and the noise (the kernel kept).
    held_out : dict or None
        The held-out check (:func:`held_out_resonances`) when it ran:
        ``"base"`` and ``"found"``, the held-out fit in percent (of the
        whitened outputs) of the tuned base kernel and of the kernel with
        every term the evidence kept, ``"kept"``, that of the kernel with
        the terms that earned their place (``"base"`` when none did), the
        same of the outputs themselves (``"raw_base"``, ``"raw_found"``,
        ``"raw_kept"``) and ``"dropped"``, the number of terms it removed.
    evidence : LogEvidence or None
        The log evidence of the data at ``kernel`` without the spread
        (:func:`~gpmultirate.kernels.spread.conditioning_kernel`) and
        ``noise_level``: the search's reduction of the data, which the fit
        goes on with instead of reducing the data again.
    """

    kernel: Kernel
    noise_level: float
    optimizer_result: object
    resonances: list = field(default_factory=list)
    log_marginal_likelihood: float = float("nan")
    history: list = field(default_factory=list)
    held_out: dict | None = None
    evidence: object = None


def _check_max_resonances(value) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
        raise ValueError(f"max_resonances must be a non-negative integer; got {value!r}")
    return int(value)


def damping_ratio(alpha: float, omega: float) -> float:
    """Damping ratio of a PK term: ``r / sqrt(r^2 + omega^2)``, ``r = -log(alpha) / 2``.

    Examples
    --------
    >>> round(damping_ratio(1.0, 0.5), 3)
    0.0
    >>> r = 0.05
    >>> bool(np.isclose(damping_ratio(np.exp(-2 * r), 0.5), r / np.hypot(r, 0.5)))
    True
    """
    rate = abs(0.5 * np.log(alpha))  # alpha in (0, 1]
    return float(rate / np.hypot(rate, omega))


def resonance_scan(observation, y, kernel, noise_level: float, input: int = 0,
                   omegas=None, alphas=None, amplitudes=None):
    """Log evidence gain of one more PK term, for each frequency and decay of a grid.

    With the data covariance ``Ky = Phi K Phi^T + gamma I = L L^T`` of the
    current ``kernel`` factored once, a PK term of frequency ``omega``,
    decay ``alpha`` and standard deviations ``sigma1 = sigma2 = s`` on input
    ``input`` adds ``s^2 U U^T`` with ``U = Phi_k [c, s]`` (the observed
    basis of :meth:`~gpmultirate.kernels.PK.basis`).  With
    ``G = U^T Ky^{-1} U = Q diag(lambda) Q^T`` and ``beta = Q^T U^T Ky^{-1} y``,
    the determinant lemma and the Woodbury identity give the gain

        ``1/2 sum_j (s^2 beta_j^2 / (1 + s^2 lambda_j) - log(1 + s^2 lambda_j))``,

    (:func:`~gpmultirate.covariance.woodbury_gain`), maximised here over ``s``
    on a grid.

    Parameters
    ----------
    observation : Observation
        The (reduced) observation the evidence is computed from.  For
        readings at their own instants (a
        :class:`~gpmultirate.TimedConvolution`) the bases are observed at
        real lags through the readings' functionals
        (:meth:`~gpmultirate.TimedConvolution.damped_spectrum`), and the
        excitation is judged from the regressor of the readings' ticks.
    y : ndarray of shape (M,)
        Its outputs.
    kernel : sklearn Kernel
        The current kernel (a :class:`~gpmultirate.kernels.PerInputKernel`
        for several inputs).
    noise_level : float
        The current noise variance.
    input : int, default=0
        The input whose impulse response gets the term.
    omegas : array-like, optional
        Frequencies in radians per fast sample; default a uniform grid over
        ``(0, pi]`` with spacing about ``pi / max(P, 256)``, at least two
        periods within the ``P`` lags.
    alphas : array-like, optional
        Decays per fast sample in (0, 1]; default four decays whose
        envelope falls by ``e^-2`` to ``e^-60`` over ``P`` lags.
    amplitudes : array-like, optional
        Candidate ``s``; default a geometric grid scaled by the data.

    Returns
    -------
    gain : ndarray of shape (n_alphas, n_omegas)
        The best gain (nats) over the amplitudes, at least 0; 0 at the
        frequencies the input does not excite (:func:`excitation`).
    sigma : ndarray of shape (n_alphas, n_omegas)
        The amplitude of the best gain.  Readings at their own instants are
        not scanned at the frequencies the input does not excite (but the
        first): there the smallest candidate amplitude.
    omegas, alphas : ndarray
        The grid.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import DC
    >>> rng = np.random.default_rng(0)
    >>> op = DownsampledConvolution(rng.standard_normal(300), factor=3, order=100)
    >>> g = 0.97 ** np.arange(100) * np.cos(2.0 * np.arange(100))
    >>> y = op.matvec(g) + 0.01 * rng.standard_normal(op.n_outputs)
    >>> gain, _, omegas, _ = resonance_scan(op, y, C(0.1) * DC(), 1e-4)
    >>> round(float(omegas[np.argmax(gain.max(axis=0))]), 1)
    2.0
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        covariance = DenseCovariance.of(kernel, observation, WhiteNoise(noise_level))
    return _scan(observation, y, input, covariance.whiten, omegas, alphas, amplitudes)


def _scan(observation, y, input, whiten, omegas=None, alphas=None, amplitudes=None,
          white_regressor=None, seen=None):
    """:func:`resonance_scan` with the data covariance given by ``whiten``.

    ``whiten(B)``: ``F B`` for any ``F`` with ``F^T F = Ky^{-1}`` (the gain
    depends on ``Ky^{-1}`` only).  ``white_regressor``: ``F Phi`` when it is
    at hand; ``seen``: a dict of the :func:`excitation` on the default grid
    per input, filled here: it does not change from one scan to the next.
    """
    # readings at their own instants see the bases between the integer lags: observed
    # through the readings' functionals; their regressor at the ticks gauges the excitation
    timed = hasattr(observation, "damped_spectrum")
    Phi = _tick_regressor(observation, input) if timed else observation.input_block(input).matrix
    P = Phi.shape[1]
    lags = np.arange(P, dtype=float)
    n_fft = index = None
    if omegas is None:
        # the grid pi j / n, j = 1..n: the products of every row with the
        # bases are then one real FFT of length 2 n
        n_fft = max(P, 256)
        index = np.arange(1, n_fft + 1)
        index = index[index * P >= 4 * n_fft]  # at least two periods over the lags
        omegas = np.pi * index / n_fft
    else:
        seen = None  # the cache holds the default grid's
    if alphas is None:
        alphas = np.exp(-2.0 * np.asarray(_SCAN_DECAYS) / P)
    omegas = np.asarray(omegas, dtype=float)
    alphas = np.asarray(alphas, dtype=float)
    w = whiten(y)
    if timed:
        white = None
    elif white_regressor is not None:
        white = white_regressor
    else:
        white = whiten(Phi)  # L^{-1} Phi
    if amplitudes is None:
        # the size of an impulse response that explains the data's power
        power_u = float(np.mean(Phi**2)) * P or 1.0
        amplitudes = _SCAN_AMPLITUDES * np.sqrt(float(np.mean(y**2)) / power_u)
    s2 = np.asarray(amplitudes, dtype=float) ** 2
    # where the input has (almost) no power the data cannot locate a resonance:
    # a large amplitude there only fits noise, and the response beyond the record
    if seen is None or input not in seen:
        seen_here = (excitation(Phi, omegas) if n_fft is None
                     else _excitation_on_grid(Phi, n_fft, index))
        if seen is not None:
            seen[input] = seen_here
    else:
        seen_here = seen[input]
    unseen = seen_here < MIN_EXCITATION
    gain = np.zeros((alphas.size, omegas.size))
    sigma = np.full_like(gain, np.sqrt(s2.min()))
    scanned = np.arange(omegas.size)
    if timed:
        # the readings' bases cost O(readings x frequencies) each: formed only where the
        # gain can be other than 0, and at the first frequency, whose amplitude a scan that
        # gains nowhere returns
        scanned = np.flatnonzero(~unseen | (scanned == 0))
    for a, alpha in enumerate(alphas):
        envelope = alpha ** (0.5 * lags)
        if timed:
            Ac, As = _timed_sinusoids(observation, whiten, input, alpha, omegas[scanned], n_fft,
                                      None if index is None else index[scanned], seen)
        elif n_fft is None:
            cos, sin = damped_sinusoids(lags, omegas, envelope)  # PK's basis, per frequency
            Ac, As = white @ cos, white @ sin
        else:
            # sum_t x_t e^{-i omega t}: real part the cosine, minus imaginary the sine
            spectrum = np.fft.rfft(white * envelope, n=2 * n_fft, axis=1)[:, index]
            Ac, As = spectrum.real, -spectrum.imag
        g11 = np.einsum("ij,ij->j", Ac, Ac)
        g22 = np.einsum("ij,ij->j", As, As)
        g12 = np.einsum("ij,ij->j", Ac, As)
        b1, b2 = Ac.T @ w, As.T @ w
        # eigen-decomposition of each 2 x 2 G
        mean, half = 0.5 * (g11 + g22), np.hypot(0.5 * (g11 - g22), g12)
        lam = np.stack([mean + half, np.maximum(mean - half, 0.0)], axis=1)
        angle = 0.5 * np.arctan2(2.0 * g12, g11 - g22)
        q1 = np.cos(angle) * b1 + np.sin(angle) * b2
        q2 = -np.sin(angle) * b1 + np.cos(angle) * b2
        beta2 = np.stack([q1**2, q2**2], axis=1)
        # the capacitance of s U: eigenvalues s^2 lambda, projections s beta
        values = woodbury_gain(s2[None, :, None] * lam[:, None, :],
                               s2[None, :, None] * beta2[:, None, :])  # (omega, amplitude)
        best = np.argmax(values, axis=1)
        gain[a, scanned] = np.maximum(values[np.arange(scanned.size), best], 0.0)
        sigma[a, scanned] = np.sqrt(s2[best])
    gain[:, unseen] = 0.0
    return gain, sigma, omegas, alphas


def _tick_regressor(observation, input: int) -> np.ndarray:
    """Timed readings: the regressor of a response constant between integer lags, ``(M, P)``."""
    P = observation.order
    return observation.weighted_rows()[:, input * P:(input + 1) * P]


def _timed_sinusoids(observation, whiten, input, alpha, omegas, n_fft, index, seen=None):
    """Whitened readings of PK's cosine and sine bases at every frequency (timed readings).

    ``seen``: the scan's cache (the same grid and decays in every scan of a
    search); the readings of the bases on the default grid are kept there
    while they fit in ``SPECTRA_BYTES``, and only whitened in later scans.
    """
    if index is not None:
        key = ("spectrum", input, float(alpha))
        spectrum = None if seen is None else seen.get(key)
        if spectrum is None:
            spectrum = observation.damped_spectrum(alpha, n_fft, index, input)
            kept = 0 if seen is None else seen.get("spectra_bytes", 0) + spectrum.nbytes
            if seen is not None and kept <= SPECTRA_BYTES:
                seen[key], seen["spectra_bytes"] = spectrum, kept
        return whiten(spectrum.real), whiten(-spectrum.imag)
    cos, sin = [], []
    for part in np.array_split(omegas, max(1, omegas.size // 8)):  # bounded memory
        observed = observation.lag_functionals(
            lambda x: np.hstack(damped_sinusoids(x, part, alpha ** (0.5 * x))), input)
        cos.append(observed[:, :part.size])
        sin.append(observed[:, part.size:])
    return whiten(np.hstack(cos)), whiten(np.hstack(sin))


def excitation(Phi: np.ndarray, omegas) -> np.ndarray:
    """How strongly the data see a sinusoidal response at each frequency, relative to the mean.

    ``||Phi w cos(omega t)||^2 + ||Phi w sin(omega t)||^2`` over the lags
    ``t`` of the regressor ``Phi``, with ``w(t)`` a Hann taper over the lags
    (against leakage from strong bands), divided by its mean over
    ``omegas``: the power
    of the input near ``omega`` as the slow samples receive it (aliased or
    not).  A resonance is only searched where this is at least
    :data:`MIN_EXCITATION`.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> u = np.cos(0.3 * np.arange(300))  # one frequency only
    >>> e = excitation(DownsampledConvolution(u, 3, 60).matrix, [0.3, 2.0])
    >>> bool(e[0] > 1.9 and e[1] < 0.1)
    True
    """
    omegas = np.asarray(omegas, dtype=float)
    P = Phi.shape[1]
    lags = np.arange(P, dtype=float)
    # a Hann taper over the lags keeps the leakage of strong bands low (below 1e-4)
    taper = _hann_over_lags(P)[:, None]
    phase = np.outer(lags, omegas)
    seen = (np.sum((Phi @ (taper * np.cos(phase))) ** 2, axis=0)
            + np.sum((Phi @ (taper * np.sin(phase))) ** 2, axis=0))
    mean = float(np.mean(seen))
    return seen / mean if mean > 0 else np.zeros_like(seen)


def _hann_over_lags(P: int) -> np.ndarray:
    """The Hann taper of :func:`excitation` over ``P`` lags."""
    return 0.5 - 0.5 * np.cos(2.0 * np.pi * (np.arange(P) + 0.5) / P)


def _excitation_on_grid(Phi: np.ndarray, n_fft: int, index: np.ndarray) -> np.ndarray:
    """:func:`excitation` at the frequencies ``pi * index / n_fft``: one real FFT per row.

    ``sum_t x_t cos(omega t)`` and ``sum_t x_t sin(omega t)`` of the tapered
    rows ``x`` are the real part and minus the imaginary part of their
    transform of length ``2 n_fft`` at bin ``index``; ``O(M P log P)``
    instead of ``O(M P n_omegas)``.
    """
    spectrum = np.fft.rfft(Phi * _hann_over_lags(Phi.shape[1]), n=2 * n_fft, axis=1)[:, index]
    seen = np.sum(spectrum.real**2 + spectrum.imag**2, axis=0)
    mean = float(np.mean(seen))
    return seen / mean if mean > 0 else np.zeros_like(seen)


def search_resonances(observation, y, base_kernel, noise_level: float, noise_bounds, *,
                      max_resonances: int = 4, sample_time: float = 1.0,
                      random_state=None, n_folds: int = 5,
                      tune_base: bool = True, held_out: bool = True) -> ResonanceSearch:
    """Add PK terms to ``base_kernel`` by marginal likelihood, with no frequency guesses.

    The greedy forward search of the module docstring: tune the base
    kernel; repeatedly scan one more PK term over the whole band on every
    input, refine it jointly with the terms found so far, and keep it when
    the log evidence grows by more than :data:`SEARCH_THRESHOLD` nats and
    it is resonant; then prune the terms whose evidence gain against the
    others re-tuned without them is at most :data:`EVIDENCE_THRESHOLD`
    nats, keep only the set of terms that improves the fit of held-out slow
    samples (:func:`held_out_resonances`), and give the kept terms the
    spread of their frequency and decay.  With several
    inputs the terms go into the input kernels of the
    :class:`~gpmultirate.kernels.PerInputKernel`, each to the input whose
    scan gains most.

    Parameters
    ----------
    observation : Observation
        How the slow samples observe the coefficients.
    y : ndarray of shape (M,)
        The slow samples.
    base_kernel : sklearn Kernel
        The kernel to start from (``C * DC``, or a
        :class:`~gpmultirate.kernels.PerInputKernel` of them); not modified.
    noise_level : float
        The initial noise variance.
    noise_bounds : pair of floats or "fixed"
        Its tuning bounds.
    max_resonances : int, default=4
        The most PK terms to add (in all); 0 gives the tuned base kernel.
    sample_time : float, default=1.0
        Fast sample time in seconds, for :attr:`Resonance.frequency_hz`.
    random_state : int, RandomState, Generator or None
        Passed to the tuning.
    n_folds : int, default=5
        Contiguous blocks of slow samples of the held-out check.
    tune_base : bool, default=True
        False: ``base_kernel`` and ``noise_level`` are tuned already on
        these data (a default order's pilot at this order, or cut to it),
        and the search starts from them as they are.
    held_out : bool, default=True
        False: no held-out check (step 5); the caller judges the terms
        held out under its own noise model (the search under a disturbance,
        :func:`gpmultirate.fitting.auto_kernel.search_under_disturbance`,
        whose terms :func:`resonances_under_disturbance` judges).

    Returns
    -------
    ResonanceSearch

    Raises
    ------
    ValueError
        If ``max_resonances`` is not a non-negative integer or
        ``sample_time`` is not positive.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import DC
    >>> rng = np.random.default_rng(1)
    >>> op = DownsampledConvolution(rng.standard_normal(600), factor=3, order=200)
    >>> t = np.arange(200)
    >>> g = 0.9 ** t + 0.98 ** t * np.sin(2.4 * t)
    >>> y = op.matvec(g) + 0.01 * rng.standard_normal(op.n_outputs)
    >>> found = search_resonances(op, y, C(1.0) * DC(), 1e-4, (1e-8, 1.0))
    >>> [round(r.frequency_hz * 2 * np.pi, 2) for r in found.resonances]
    [2.4]
    """
    max_resonances = _check_max_resonances(max_resonances)
    sample_time = check_positive(sample_time, "sample_time")
    with blas_threads_for(observation):
        return _search(observation, y, base_kernel, noise_level, noise_bounds,
                       max_resonances, sample_time, random_state, n_folds, tune_base,
                       held_out)


def _search(observation, y, base_kernel, noise_level, noise_bounds, max_resonances,
            sample_time, random_state, n_folds=5, tune_base=True,
            held_out=True) -> ResonanceSearch:
    _LOG.info("resonance search: order %d, up to %d resonance(s)%s", observation.order,
              max_resonances, "" if tune_base else ", from the tuned pilot's prior")
    evidence = LogEvidence(observation, y, base_kernel, noise_level, noise_bounds)
    if tune_base:
        base, noise, result, value = _tune(evidence, base_kernel, noise_level, random_state)
    else:
        base, noise, result, value = (base_kernel, noise_level, None,
                                      float(evidence(evidence.theta)))
    model_noise0, result0 = noise, result
    history = [value]
    model = _ResonantModel(evidence.moved_to(base, noise))
    n_inputs = len(input_kernels(base_kernel))
    kernel = base
    timed = hasattr(evidence.data, "damped_spectrum")
    seen = {}  # the excitation per input, the same for every scan
    for _ in range(max_resonances):
        best = None
        # the scan whitens by the model's own decomposition: the base kernel's
        # eigenvectors, and the terms as a low-rank update (no new factorization)
        rotated_whiten = model.whitener()

        def whiten(B):
            return rotated_whiten(model.rotate(B))

        scans = [_scan(evidence.data, evidence.z, k, whiten, seen=seen,
                       white_regressor=None if timed
                       else rotated_whiten(model.rotated_regressor(k)))
                 for k in range(n_inputs)]
        candidates = _scan_candidates(scans)
        if not candidates:
            break  # no signal left to scan (zero data): no term, no zero-width bounds
        for _, k, alpha, omega, sigma in candidates:
            trial = model.with_term(k, PK(
                alpha=alpha, omega=omega, sigma1=sigma, sigma2=sigma,
                alpha_bounds=(1e-4, slowest_decay(evidence.data.order)),
                sigma1_bounds=(sigma * 1e-4, sigma * 1e4),
                sigma2_bounds=(sigma * 1e-4, sigma * 1e4), hold=True,
            ))
            gain = trial.value - model.value
            if gain > SEARCH_THRESHOLD and trial.terms[-1][1] is not None:
                break
        else:
            break
        model = trial
        kernel = model.kernel()
        history.append(model.value)
        _LOG.info("resonance search: a term at %.4g Hz on input %d (evidence gain %.1f nats)",
                  float(omega) / (2.0 * np.pi * sample_time), k, gain)
    gains, check = [], None
    if model.terms:
        kernel, noise, value, gains, retuned = _prune(evidence, model)
        found = _terms_of(kernel, [g.input for g in gains]) if gains else []
        persistent = set(persistent_aliases(found, observation.slow_factor, y.shape[0]))
        if persistent:
            _LOG.info("resonance search: %d term(s) dropped, persistent slow-rate images",
                      len(persistent))
            kept = [r for r in range(len(gains)) if r not in persistent]
            gains = [gains[r] for r in kept]
            if gains:
                kernel, noise, value = retuned(kept)
        else:
            kept = list(range(len(gains)))
        final = kept
        if gains and held_out:
            check = held_out_resonances(
                observation, y, kernel, noise, [g.input for g in gains], base, model_noise0,
                n_folds, refit=lambda subset: retuned([kept[i] for i in subset])[:2])
            if check is not None and len(check["kept_terms"]) < len(gains):
                _LOG.info("resonance search: %d term(s) dropped, they do not improve the fit of "
                          "held-out slow samples (%.2f %% with them, %.2f %% without)",
                          check["dropped"], check["found"], check["kept"])
                gains = [gains[r] for r in check["kept_terms"]]
                final = [kept[i] for i in check["kept_terms"]]
                if gains:
                    history.append(value)  # the set the evidence kept, before the check
        while gains:
            # the kept terms, the scale and the noise tuned together once more, from the
            # scaled base kernel (the held-out check's and the spreads' model): the search's
            # scale is bounded about the pilot's, and where the terms explain the data the
            # evidence takes the base kernel further down; each term's gain is then taken
            # against the others re-tuned without it from the same point, and a term this
            # tuning leaves weak or without a peak (its amplitudes taken to nothing where a
            # drift took its place) goes as in the pruning, the rest tuned again
            kernel, noise, value = retuned(final)
            tuned = dict(zip(sorted(final), retuned.model(final).terms))
            values = [value - retuned.model([i for i in final if i != r]).value for r in final]
            weak = [i for i, r in enumerate(final) if values[i] <= EVIDENCE_THRESHOLD
                    or damping_ratio(tuned[r][1].alpha, tuned[r][1].omega) >= MAX_DAMPING]
            if not weak:
                gains = [_Gain(g.input, v) for g, v in zip(gains, values)]
                break
            drop = min(weak, key=lambda i: values[i])
            _LOG.info("resonance search: a term dropped, %.1f nats after the last tuning",
                      values[drop])
            gains = gains[:drop] + gains[drop + 1:]
            final = final[:drop] + final[drop + 1:]
        if not gains:  # every term pruned: the tuned base kernel
            kernel, noise, result, value = base, model_noise0, result0, history[0]
        history.append(value)
    terms = _terms_of(kernel, [r.input for r in gains]) if gains else []
    conditioning = kernel
    if terms:  # what the data leave uncertain of each frequency and decay, for the posterior
        # the Laplace spreads at the tuned values, for the fit to add after conditioning
        spreads = retuned.model(final).term_spreads()
        kernel = with_spreads(kernel, {id(term): spread
                                       for (_, term), spread in zip(terms, spreads)})
    return ResonanceSearch(
        kernel=kernel, noise_level=noise, optimizer_result=result,
        resonances=[
            Resonance(
                frequency_hz=float(term.omega) / (2.0 * np.pi * sample_time),
                damping=damping_ratio(term.alpha, term.omega),
                evidence_gain=float(gain.value), input=k,
            )
            for (k, term), gain in zip(terms, gains)
        ],
        log_marginal_likelihood=value, history=history,
        evidence=evidence.moved_to(conditioning, noise),
        held_out=None if check is None else {
            name: check[name] for name in ("base", "found", "kept", "raw_base", "raw_found",
                                           "raw_kept", "dropped")},
    )


def _scan_candidates(scans) -> list:
    """The terms a search step refines, best first: ``[(scan gain, input, alpha, omega, sigma)]``.

    ``scans``: :func:`_scan`'s ``(gain, sigma, omegas, alphas)`` per input.
    The scan's best candidate, and where it fails (its refinement gains at
    most :data:`SEARCH_THRESHOLD` nats, or ends not resonant) the best one
    on any input outside :data:`RUNNER_UP_SPAN` of its frequency on its
    input, when the scan gave that one more than :data:`EVIDENCE_THRESHOLD`
    nats itself (above the ``log(n_candidates) ~ 7`` nats of the best of a
    scan without a resonance): the scan holds the base kernel's shape, and
    its order of two modes is not always the refined one (under a drift, a
    weak mode came first at 17.5 nats and refined to 22.6; the strong mode
    behind it, at 14.6, refined to 128 and was never tried).  Empty when
    the best has no amplitude.
    """
    found = []
    for k, (gain, sigma, omegas, alphas) in enumerate(scans):
        a, j = np.unravel_index(np.argmax(gain), gain.shape)
        found.append((float(gain[a, j]), k, alphas[a], omegas[j], sigma[a, j]))
    best = max(found, key=lambda c: c[0])
    if not (np.isfinite(best[4]) and best[4] > 0.0):
        return []
    runner = None
    for k, (gain, sigma, omegas, alphas) in enumerate(scans):
        distinct = np.ones(omegas.shape[0], dtype=bool)
        if k == best[1]:
            # frequencies below the grid's first step count as that step (no ratio to zero)
            floor = np.min(omegas[omegas > 0.0], initial=np.inf)
            floor = floor if np.isfinite(floor) else 1.0
            ratio = np.abs(np.log(np.maximum(omegas, floor) / max(best[3], floor)))
            distinct = ratio > np.log(RUNNER_UP_SPAN)
        if not distinct.any():
            continue
        masked = np.where(distinct[None, :], gain, -np.inf)
        a, j = np.unravel_index(np.argmax(masked), masked.shape)
        if masked[a, j] > EVIDENCE_THRESHOLD and (runner is None or masked[a, j] > runner[0]):
            runner = (float(masked[a, j]), k, alphas[a], omegas[j], sigma[a, j])
    if runner is not None and np.isfinite(runner[4]) and runner[4] > 0.0:
        return [best, runner]
    return [best]


def alias_twins(terms, gains, factor: int, n_slow: int) -> list[int]:
    """The terms that are slow-rate aliases of a stronger term on the same input.

    A diagnostic, not a decision: the search no longer drops a term by its
    frequency (the module docstring, steps 3 and 5).  Sampled every
    ``factor`` fast samples, a resonance at ``f`` cycles per fast sample
    and one at ``k / factor +- f`` show at the same slow-rate frequency;
    only the fast input can tell them apart, and where it does both are
    modes (a rule that dropped the weaker one lost a true mode on random
    two-mass systems whose upper alias falls on the lower mode).  Two
    terms are twins when
    their folded slow-rate frequencies differ by less than the narrower of
    their half-power bandwidths (``2 zeta f``), or than the record's
    frequency resolution ``1 / (factor * n_slow)`` where that is wider
    (two distinct modes of a random two-mass system 0.007 cycles per
    sample apart after folding stay); of each pair the one of smaller
    evidence gain is returned (by index).

    Parameters
    ----------
    terms : list of (int, PK)
        The input and the PK term of each resonance.
    gains : list of float
        Their evidence gains, in the same order.
    factor : int
        Fast samples per slow sample.
    n_slow : int
        The number of slow samples.

    Returns
    -------
    list of int

    Examples
    --------
    >>> from gpmultirate.kernels import PK
    >>> mode = PK(alpha=0.99, omega=2 * np.pi * 0.127)
    >>> twin = PK(alpha=0.99, omega=2 * np.pi * (1 / 3 - 0.127))
    >>> other = PK(alpha=0.99, omega=2 * np.pi * 0.05)
    >>> alias_twins([(0, mode), (0, twin), (0, other)], [500.0, 90.0, 200.0], 3, 200)
    [1]
    >>> alias_twins([(0, mode), (1, twin)], [500.0, 90.0], 3, 200)  # other inputs
    []
    """
    if factor <= 1:
        return []
    period = 1.0 / factor

    def folded(f):
        f = f % period
        return min(f, period - f)

    frequencies = [float(term.omega) / (2.0 * np.pi) for _, term in terms]
    widths = [2.0 * damping_ratio(term.alpha, term.omega) * f
              for (_, term), f in zip(terms, frequencies)]
    resolution = 1.0 / (factor * max(int(n_slow), 1))
    twins = set()
    order = sorted(range(len(terms)), key=lambda i: -gains[i])
    for a, i in enumerate(order):
        if i in twins:
            continue
        for j in order[a + 1:]:
            if j in twins or terms[i][0] != terms[j][0]:
                continue
            within = max(min(widths[i], widths[j]), resolution)
            if (abs(folded(frequencies[i]) - folded(frequencies[j])) < within
                    and abs(frequencies[i] - frequencies[j]) > within):
                twins.add(j)
    return sorted(twins)


def persistent_aliases(terms, factor: int, n_slow: int,
                       cycles: float = PERSISTENT_CYCLES) -> list[int]:
    """The nearly undamped terms whose slow-rate image is a slowly wandering signal.

    Sampled every ``factor`` fast samples, a term at ``f`` cycles per fast
    sample shows at its folded frequency ``f mod 1 / factor`` (folded to
    ``[0, 1 / (2 factor)]``).  Near ``k / factor`` (``k = 0`` included) that
    is near DC: the term turns the input's history into a signal that
    completes only a few cycles over the record, a persistent signal on
    which a slow disturbance (drift, level steps, low-frequency noise)
    regresses, in held-out blocks as well as in the evidence (a spurious
    regression of one persistent signal on another), but not on a new
    record.  A term is returned (by index) when it is nearly undamped
    (damping ratio below :data:`PERSISTENT_DAMPING`) and its folded
    frequency is below ``cycles`` times the record's frequency resolution
    ``1 / (factor * n_slow)``: its image completes fewer than ``cycles``
    cycles over the record.  Such a resonance cannot be told from a slow
    disturbance by the slow samples; one further from the alias, or more
    damped, is kept.

    Parameters
    ----------
    terms : list of (int, PK)
        The input and the PK term of each resonance.
    factor : int
        Fast samples per slow sample.
    n_slow : int
        The number of slow samples.
    cycles : float, default=PERSISTENT_CYCLES

    Returns
    -------
    list of int

    Examples
    --------
    >>> from gpmultirate.kernels import PK
    >>> lure = PK(alpha=0.99, omega=2 * np.pi * 0.331)  # 0.0023 from 1/3
    >>> mode = PK(alpha=0.99, omega=2 * np.pi * 0.30)
    >>> persistent_aliases([(0, lure), (0, mode)], 3, 300)
    [0]
    """
    factor = max(int(factor), 1)
    period = 1.0 / factor
    band = cycles / (factor * max(int(n_slow), 1))
    persistent = []
    for i, (_, term) in enumerate(terms):
        f = float(term.omega) / (2.0 * np.pi)
        folded = f % period
        folded = min(folded, period - folded)
        if folded < band and damping_ratio(term.alpha, term.omega) < PERSISTENT_DAMPING:
            persistent.append(i)
    return persistent


def held_out_resonances(observation, y, kernel, noise_level: float, inputs, base_kernel,
                        base_noise: float, n_folds: int = 5, margin: float = HELD_OUT_GAIN,
                        refit=None):
    """Which PK terms of ``kernel`` improve the fit of held-out slow samples.

    The slow samples are cut into ``n_folds`` contiguous blocks per record
    (:func:`~gpmultirate.crossvalidation.contiguous_folds`), each predicted
    from the others at fixed hyperparameters
    (:func:`~gpmultirate.crossvalidation.held_out_predictions`), and scored
    by :func:`~gpmultirate.metrics.fit_percent` twice: on the outputs, and
    on the outputs and predictions filtered by ``A(q)``, the AR model
    (order :data:`PREWHITENING_ORDER`, least squares, per record) of the
    held-out residuals of ``base_kernel``, which whitens them.  A term's
    gain is the smaller of its two gains, each in units of the gain
    needed: ``margin`` points, or a twentieth of the base kernel's held-out
    error (``100`` minus its fit) where that is less.  Backward elimination
    over sets: while removing some term, the others as ``refit`` gives them
    without it, costs at most the gain needed, the term whose removal
    costs least is dropped.  The set left must gain more than that over
    ``base_kernel`` (the tuned kernel without terms), or none is kept; it
    is not cut into a lone survivor that predicts worse than the set.

    Parameters
    ----------
    observation : Observation
        The observation of every used slow sample (not reduced).
    y : ndarray of shape (M,)
    kernel : sklearn Kernel
        The tuned kernel with its PK terms.
    noise_level : float
    inputs : list of int
        The input of each PK term, in the order they were added.
    base_kernel : sklearn Kernel
        The tuned kernel without PK terms.
    base_noise : float
        Its noise variance.
    n_folds : int, default=5
    margin : float, default=HELD_OUT_GAIN
        Points of fit percent a term must add (at most; see above).
    refit : callable, optional
        ``refit(indices) -> (kernel, noise_level)``: the model with only
        the terms ``indices`` (the search passes the terms re-tuned
        without the others); default ``kernel`` with the other terms
        removed, every hyperparameter held.

    Returns
    -------
    dict or None
        None where the check does not run (more than
        :data:`~gpmultirate.orders.MAX_CHECKED_SAMPLES` slow samples, fewer
        samples than folds, a constant output).  Otherwise ``"kept_terms"``
        (the indices of the terms kept, in order), ``"kernel"`` (the model
        of those terms by ``refit``; ``base_kernel`` when none is kept),
        ``"base"``, ``"found"`` and ``"kept"`` (held-out fits in percent of
        the whitened outputs, of ``base_kernel``, ``kernel`` and
        the kept kernel), ``"raw_base"``, ``"raw_found"`` and ``"raw_kept"``
        (the same of the outputs) and ``"dropped"`` (the number of terms
        dropped).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import DC, PK
    >>> rng = np.random.default_rng(0)
    >>> op = DownsampledConvolution(rng.standard_normal(600), factor=3, order=100)
    >>> y = op.matvec(0.9 ** np.arange(100)) + 0.01 * rng.standard_normal(op.n_outputs)
    >>> base = C(5.0) * DC(0.9, 0.9)
    >>> spurious = base + PK(alpha=0.98, omega=2.0, sigma1=0.3, sigma2=0.3)
    >>> held_out_resonances(op, y, spurious, 1e-4, [0], base, 1e-4)["kept_terms"]
    []
    """
    y = np.asarray(y, dtype=float)
    if y.shape[0] > MAX_CHECKED_SAMPLES or np.ptp(y) == 0:
        return None
    sizes = [r.n_outputs for r in observation.records]
    try:
        folds = contiguous_folds(sizes, n_folds)
    except ValueError:
        return None

    def held_out_mean(candidate, noise):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NumericalWarning)
            try:
                return held_out_predictions(observation, candidate, noise, y, folds)[0]
            except (ValueError, np.linalg.LinAlgError):
                return None

    base_mean = held_out_mean(base_kernel, base_noise)
    if base_mean is None:
        return None
    whiten = _prewhitening(y - base_mean, sizes)
    white_y = whiten(y)
    if np.ptp(white_y) == 0:
        return None

    def held_out_fits(candidate, noise):
        """(fit of the whitened outputs, fit of the outputs) in percent."""
        mean = held_out_mean(candidate, noise)
        if mean is None:
            return -np.inf, -np.inf
        return fit_percent(white_y, whiten(mean)), fit_percent(y, mean)

    terms = _terms_of(kernel, list(inputs))
    if refit is None:
        def refit(subset):
            return _assembled(kernel, [terms[i] for i in subset]), noise_level
    kept = list(range(len(terms)))
    found = current = held_out_fits(kernel, noise_level)
    base = fit_percent(white_y, whiten(base_mean)), fit_percent(y, base_mean)
    # near a perfect fit ``margin`` points may be more than the base kernel leaves to
    # gain: there a gain counts from a twentieth of the base's held-out error
    needed = [max(min(margin, 0.05 * (100.0 - b)), 1e-9) for b in base]

    def cost(with_term, without_term):
        # what removing a term costs: the smaller of its two gains, in units of `needed`
        return min((w - o) / n for w, o, n in zip(with_term, without_term, needed))

    while len(kept) > 1:
        without = {r: held_out_fits(*refit([i for i in kept if i != r])) for r in kept}
        weakest = min(kept, key=lambda r: cost(current, without[r]))
        if cost(current, without[weakest]) > 1.0:
            break
        kept.remove(weakest)
        current = without[weakest]
    # the set left must beat the kernel without terms; it is not cut further into
    # a single survivor that predicts worse than the set
    if kept and cost(current, base) <= 1.0:
        kept = []
    if not kept:
        current = base
    return {
        "kept_terms": kept,
        "kernel": refit(kept)[0] if kept else base_kernel,
        "base": base[0],
        "found": found[0],
        "kept": current[0],
        "raw_base": base[1],
        "raw_found": found[1],
        "raw_kept": current[1],
        "dropped": len(terms) - len(kept),
    }


def resonances_under_disturbance(observation, y, evidence, kernel, noise, inputs,
                                 n_folds: int = 5) -> tuple[list[int], Kernel]:
    """The PK terms of ``kernel`` a fit with a disturbance model still calls for.

    The resonance search judges its terms with white noise; a coloured
    disturbance chosen after it may explain what a term did (a slow drift,
    a periodic disturbance).  Each term is judged again with the
    disturbance, every hyperparameter held: it is kept when the log
    evidence without it falls by more than :data:`EVIDENCE_THRESHOLD`
    nats, and the terms kept must pass :func:`held_out_resonances` with the
    disturbance (against the kernel without PK terms, hyperparameters
    held).  Then the base kernel of each input with kept terms is judged
    the same way against those terms alone, and dropped where it gains no
    more than :data:`EVIDENCE_THRESHOLD` nats.

    Parameters
    ----------
    observation : Observation
        The observation of every used slow sample (not reduced).
    y : ndarray of shape (M,)
    evidence : LogEvidence
        The evidence of the fit, with its noise model.
    kernel : sklearn Kernel
        The tuned kernel with its PK terms.
    noise : noise model
        The tuned disturbance model (:mod:`gpmultirate.noise`).
    inputs : list of int
        The input of each PK term, in the order they were added.
    n_folds : int, default=5

    Returns
    -------
    kept : list of int
        The indices of the terms kept, in order.
    kernel : sklearn Kernel
        ``kernel`` with only those terms and the bases kept (hyperparameters
        unchanged); ``kernel`` itself when every term and base stays.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.inference import LogEvidence
    >>> from gpmultirate.kernels import DC, PK
    >>> from gpmultirate.noise import make_noise
    >>> rng = np.random.default_rng(0)
    >>> op = DownsampledConvolution(rng.standard_normal(600), factor=3, order=100)
    >>> y = op.matvec(0.9 ** np.arange(100)) + 0.01 * rng.standard_normal(op.n_outputs)
    >>> spurious = C(5.0) * DC(0.9, 0.9) + PK(alpha=0.98, omega=2.0, sigma1=0.3, sigma2=0.3)
    >>> noise = make_noise("matern12", 1e-4, "fixed", np.arange(op.n_outputs) * 3.0)
    >>> evidence = LogEvidence(op, y, spurious, 1e-4, "fixed", noise=noise)
    >>> kept, kernel = resonances_under_disturbance(op, y, evidence, spurious, noise, [0])
    >>> kept, kernel
    ([], 2.24**2 * DC(alpha=0.9, beta=0.9))
    """
    terms = _terms_of(kernel, list(inputs))
    if not terms:
        return [], kernel

    def value(candidate):
        moved = evidence.moved_to(candidate, noise)
        return float(moved(moved.theta))

    full = value(kernel)
    kept = [r for r in range(len(terms))
            if full - value(_assembled(kernel, terms[:r] + terms[r + 1:])) > EVIDENCE_THRESHOLD]
    if kept:
        check = held_out_resonances(
            observation, y, _assembled(kernel, [terms[r] for r in kept]), noise,
            [inputs[r] for r in kept], _without_pk(kernel), noise, n_folds)
        if check is not None:
            kept = [kept[i] for i in check["kept_terms"]]
    if not kept:
        return kept, _without_pk(kernel)
    reduced = kernel if len(kept) == len(terms) else _assembled(kernel,
                                                                [terms[r] for r in kept])
    # the base of an input with terms, judged as a term is: with the disturbance it may
    # take up the disturbance's slow part that the input happens to share
    full = value(reduced)
    for k in sorted({inputs[r] for r in kept}):
        without = _without_base(reduced, k)
        left = value(without)
        if full - left <= EVIDENCE_THRESHOLD:
            reduced, full = without, left
    return kept, reduced


def _prewhitening(residual, sizes, order: int = PREWHITENING_ORDER):
    """The filter ``A(q)`` of an AR model of ``residual``, per record: ``series -> A(q) series``.

    The coefficients are fitted by least squares to the residual of every
    record at once; the filtered records, each without its first ``order``
    samples, are concatenated.  The identity where a record is too short.
    """
    bounds = np.cumsum([0, *sizes])
    rows, targets = [], []
    for start, stop in zip(bounds[:-1], bounds[1:]):
        e = residual[start:stop]
        if e.shape[0] > 4 * order:
            rows.append(np.column_stack([e[order - k - 1 : e.shape[0] - k - 1]
                                         for k in range(order)]))
            targets.append(e[order:])
    if not rows:
        return lambda series: np.asarray(series, dtype=float)
    a = np.linalg.lstsq(np.vstack(rows), np.concatenate(targets), rcond=None)[0]
    taps = np.concatenate([[1.0], -a])

    def whiten(series):
        parts = []
        for start, stop in zip(bounds[:-1], bounds[1:]):
            x = series[start:stop]
            parts.append(np.convolve(x, taps)[order : x.shape[0]] if x.shape[0] > 4 * order
                         else x)
        return np.concatenate(parts)

    return whiten


class _Retuned:
    """Subsets of the found terms, each re-tuned: ``retuned(indices) -> (kernel, noise, value)``.

    The kernel without its PK terms (its tuned shape) is decomposed once; a
    subset's terms, the overall scale and the noise level are then tuned
    jointly on the diagonal-plus-low-rank form (:class:`_ResonantModel`),
    from the values the terms have in ``kernel``.  So a term's partner
    takes over what the two did together when it can (a slow-rate twin
    the input does not separate from its mode), and a subset is judged at
    its best, not with the values it had beside the terms removed.
    Results are kept per subset.
    """

    def __init__(self, evidence, kernel, noise, terms):
        self._model = _ResonantModel(evidence.moved_to(_without_pk(kernel), noise))
        self._terms = list(terms)
        self._done = {}

    def model(self, indices):
        """The tuned :class:`_ResonantModel` of the terms ``indices``."""
        key = tuple(sorted(indices))
        if key not in self._done:
            trial = self._model._copy()
            trial.terms = [self._terms[i] for i in key]
            self._done[key] = trial.optimized()
        return self._done[key]

    def __call__(self, indices):
        model = self.model(indices)
        return model.kernel(), model.noise_level, model.value


@dataclass
class _Gain:
    input: int
    value: float


def _terms_of(kernel, inputs):
    """``[(input, PK)]`` of ``kernel``'s PK terms, for terms added to ``inputs`` in order."""
    per_input = [resonance_summands(each) for each in input_kernels(kernel)]
    seen = [0] * len(per_input)
    terms = []
    for k in inputs:
        terms.append((k, per_input[k][seen[k]]))
        seen[k] += 1
    return terms


def _assembled(kernel, terms):
    """The non-PK part of each input kernel of ``kernel`` plus ``terms``, in order."""
    kernels = input_kernels(_without_pk(kernel))
    kernels = [clone(each) for each in kernels]
    for k, term in terms:
        kernels[k] = kernels[k] + clone(term)
    return like_inputs(kernels, kernel)


def _prune(evidence, model):
    """Drop the weakest term while one is not worth keeping; the others re-tuned each time.

    ``model``: the search's :class:`_ResonantModel`, its terms, scale and
    noise tuned jointly on the base kernel's tuned shape.  A term is kept
    when the log evidence exceeds that of the model without it, the other
    terms, the scale and the noise re-tuned (:class:`_Retuned`), by more
    than :data:`EVIDENCE_THRESHOLD` nats, and it is resonant.  Returns the
    kernel, noise level, log evidence, the gains (empty when no term is
    left) and the :class:`_Retuned` of the kept terms (None without terms),
    whose subsets the held-out check reuses.
    """
    inputs = [k for k, _ in model.terms]
    while inputs:
        kernel, noise, value = model.kernel(), model.noise_level, model.value
        terms = list(model.terms)
        retuned = _Retuned(evidence, kernel, noise, terms)
        everything = range(len(terms))
        gains = [value - retuned.model([i for i in everything if i != r]).value
                 for r in everything]
        weak = [r for r, (_, term) in enumerate(terms)
                if gains[r] <= EVIDENCE_THRESHOLD
                or damping_ratio(term.alpha, term.omega) >= MAX_DAMPING]
        if not weak:
            return kernel, noise, value, [_Gain(k, g) for k, g in zip(inputs, gains)], retuned
        drop = min(weak, key=lambda r: gains[r])
        model = retuned.model([i for i in everything if i != drop])
        inputs = inputs[:drop] + inputs[drop + 1:]
    return None, None, None, [], None


class _ResonantModel:
    """The tuned base kernel, scaled by ``c``, plus PK terms: the state of the search.

    With the base kernel's data covariance decomposed once,
    ``S = Q diag(s) Q^T``, the model's data covariance
    ``c S + gamma I + sum_r U_r D_r U_r^T`` (``U_r`` the observed basis of
    PK term ``r``, ``D_r = diag(sigma1^2, sigma2^2)``) is
    ``Q (diag(c s + gamma) + V D V^T) Q^T`` with ``V = Q^T U``: a diagonal
    plus a rank-``2 n_terms`` update, so the log evidence costs
    ``O(M P n_terms)`` for any values of the terms, ``c`` and ``gamma``, and
    all of them are tuned jointly each time a term is added, by Fisher
    scoring (:func:`gpmultirate.tuning.fisher_scoring`) with the model's
    own Fisher information (:meth:`_fisher`), also ``O(M P n_terms)``.
    """

    def __init__(self, evidence):
        self.evidence = evidence
        self.base = evidence.kernel
        self.noise_level = evidence.noise_level
        self.log_scale = 0.0
        self.terms = []  # (input, PK) in the order added
        data = evidence.data
        self._spectral = SpectralCovariance(observe(self.base, data).covariance(), evidence.z)
        self._s = self._spectral.eigenvalues
        self._y = self._spectral.rotated_y
        self._blocks = {}
        self.value = self._log_evidence(self._pack())

    # ---------------------------------------------------------- parameters
    def _pack(self):
        x = [self.log_scale, np.log(self.noise_level)]
        for _, term in self.terms:
            x += [np.log(max(-0.5 * np.log(term.alpha), 1e-10)), term.omega,
                  np.log(term.sigma1), np.log(term.sigma2)]
        return np.array(x)

    def _bounds(self):
        evidence = self.evidence
        log_noise = np.log(self.noise_level)
        bounds = [(-np.log(SCALE_RANGE), np.log(SCALE_RANGE)),
                  tuple(np.log(evidence.noise_bounds)) if evidence.noise_is_free
                  else (log_noise, log_noise)]
        for _, term in self.terms:
            rates = sorted(-0.5 * np.log(b) for b in term.alpha_bounds)
            bounds += [(np.log(max(rates[0], 1e-10)), np.log(max(rates[1], 1e-10))),
                       tuple(term.omega_bounds), tuple(np.log(term.sigma1_bounds)),
                       tuple(np.log(term.sigma2_bounds))]
        return np.array(bounds, dtype=float)

    def rotate(self, B):
        """``Q^T B``: a matrix of the data space in the base kernel's eigenvectors."""
        return self._spectral.rotate(B)

    def rotated_regressor(self, k):
        """``Q^T Phi_k``, computed once per input and shared by the model's copies."""
        return self._rotated_regressor(k)

    def whitener(self):
        """``X -> F X`` for rotated ``X``, with ``F^T F`` the inverse of the model's covariance.

        The rotated covariance is ``D + W W^T`` (``D = diag(c s + gamma)``,
        ``W`` the terms' observed bases times their amplitudes).  With
        ``Z = D^{-1/2} W = U S V^T`` (thin SVD),
        ``F = (I + Z Z^T)^{-1/2} D^{-1/2} = (I + U ((1 + S^2)^{-1/2} - 1) U^T) D^{-1/2}``:
        ``O(M r)`` per column instead of a factorization of the ``M x M``
        data covariance.
        """
        x = self._pack()
        root = np.sqrt(self._spectral.diagonal(np.exp(x[0]), np.exp(x[1])))
        if not self.terms:
            return lambda X: X / root.reshape((-1,) + (1,) * (np.ndim(X) - 1))
        lags = np.arange(self.evidence.data.order, dtype=float)
        W = np.empty((root.size, 2 * len(self.terms)))
        for r, (k, term) in enumerate(self.terms):
            rate, omega = np.exp(x[2 + 4 * r]), x[3 + 4 * r]
            rotated = self._observed_basis(k, lags, rate, omega, False, term.held())
            W[:, 2 * r] = np.exp(x[4 + 4 * r]) * rotated[:, 0]
            W[:, 2 * r + 1] = np.exp(x[5 + 4 * r]) * rotated[:, 1]
        U, S, _ = np.linalg.svd(W / root[:, None], full_matrices=False)
        shrink = 1.0 / np.sqrt(1.0 + S**2) - 1.0

        def whiten(X):
            X = X / root.reshape((-1,) + (1,) * (np.ndim(X) - 1))
            return X + U @ (shrink.reshape((-1,) + (1,) * (np.ndim(X) - 1)) * (U.T @ X))

        return whiten

    def _rotated_regressor(self, k):
        if k not in self._blocks:
            self._blocks[k] = self._spectral.rotate(self.evidence.data.input_block(k).matrix)
        return self._blocks[k]

    def _observed_basis(self, k, lags, rate, omega, eval_gradient, hold):
        """The rotated data of the term's basis ``[e cos, e sin]`` (and ``t e cos, t e sin``).

        With ``hold`` (the search's terms: PK's ``hold``) the basis is that of
        a mode behind the hold, zero at lag 0 and the mode's step response on
        the first cell.
        Readings at their own instants see the basis at real lags, through
        their functionals; other data through the regressor on ``lags``.
        """
        data = self.evidence.data
        if hasattr(data, "damped_sinusoids"):
            return self._spectral.rotate(
                data.damped_sinusoids(rate, omega, k, eval_gradient, hold=hold))
        pairs = mode_basis(lags, rate, omega, 1 if eval_gradient else 0, hold)
        return self._rotated_regressor(k) @ np.column_stack([x for pair in pairs for x in pair])

    def _log_evidence(self, x, eval_gradient: bool = False, eval_fisher: bool = False):
        """The log evidence at ``x`` and, with ``eval_gradient``, its gradient.

        With ``K = diag(d) + W W^T`` (``W`` the observed, rotated bases
        times the standard deviations), ``A = K^{-1}`` (Woodbury) and
        ``a = A y``: ``d f = 1/2 a^T dK a - 1/2 tr(A dK)``, where
        ``dK = dW W^T + W dW^T`` for the parameters of a term.  With
        ``eval_fisher`` also the Fisher information
        ``F_ij = 1/2 tr(A dK_i A dK_j)`` (:meth:`_fisher`).
        """
        c, gamma = np.exp(x[0]), np.exp(x[1])
        d = self._spectral.diagonal(c, gamma)
        inv_d = 1.0 / d
        y = self._y
        r_terms = len(self.terms)
        lags = np.arange(self.evidence.data.order, dtype=float)
        W = np.empty((y.shape[0], 2 * r_terms))
        raw = []  # per term: rotated [e cos, e sin, t e cos, t e sin] and parameters
        for r, (k, term) in enumerate(self.terms):
            rate, omega = np.exp(x[2 + 4 * r]), x[3 + 4 * r]
            s1, s2 = np.exp(x[4 + 4 * r]), np.exp(x[5 + 4 * r])
            rotated = self._observed_basis(k, lags, rate, omega, eval_gradient, term.held())
            W[:, 2 * r], W[:, 2 * r + 1] = s1 * rotated[:, 0], s2 * rotated[:, 1]
            raw.append((rotated, rate, s1, s2))
        if r_terms:
            update = DiagonalPlusLowRank(d, W)
            quad, log_det = update.inv_quad_logdet(y)
        else:
            quad, log_det = y @ (inv_d * y), np.sum(np.log(d))
        remainder = WhiteNoise(float(gamma)).remainder(self.evidence.data)
        rest, rest_grad, rest_fisher = remainder.log_likelihood()
        value = log_gaussian(quad, log_det, y.shape[0]) + rest
        if not eval_gradient:
            return value
        if r_terms:
            a, diag_A = update.solve(y), update.inverse_diagonal()
            AW = update.inverse_times_low_rank()
        else:
            a, diag_A = inv_d * y, inv_d
        grad = np.empty_like(x, dtype=float)
        grad[0] = 0.5 * np.sum((a**2 - diag_A) * c * self._s)
        grad[1] = 0.5 * np.sum(a**2 - diag_A) * gamma + rest_grad
        dWs = []  # per term: dW of its two columns for (log rate, omega, log s1, log s2)
        for r, (rotated, rate, s1, s2) in enumerate(raw):
            wa = W[:, 2 * r : 2 * r + 2].T @ a  # W^T a for the term's two columns
            aw = AW[:, 2 * r : 2 * r + 2]
            c_, s_, tc, ts = rotated.T
            zero = np.zeros_like(c_)
            dW = np.stack([np.column_stack([-rate * s1 * tc, -rate * s2 * ts]),
                           np.column_stack([-s1 * ts, s2 * tc]),
                           np.column_stack([s1 * c_, zero]),
                           np.column_stack([zero, s2 * s_])])  # (4, M, 2)
            # d f = (W^T a) . (dW^T a) - sum(A W * dW), over the two columns
            grad[2 + 4 * r : 6 + 4 * r] = (np.einsum("pmc,m,c->p", dW, a, wa)
                                           - np.einsum("pmc,mc->p", dW, aw))
            dWs.append(dW)
        if not eval_fisher:
            return value, grad
        fisher = self._fisher(c * self._s, gamma, d, W, dWs,
                              update if r_terms else None, AW if r_terms else None)
        fisher[1, 1] += rest_fisher
        return value, grad, fisher

    @staticmethod
    def _fisher(v_scale, gamma, d, W, dWs, update, AW):
        """``F_ij = 1/2 tr(A dK_i A dK_j)`` of the parameters ``(log c, log gamma, terms...)``.

        ``dK`` is ``diag(v)`` for ``log c`` (``v = c s``) and ``log gamma``
        (``v = gamma``), and ``dW W^T + W dW^T`` for a term's parameter, with
        ``dW`` nonzero in the term's two columns of ``W``.  With
        ``A = D^{-1} - P P^T`` (Woodbury, ``P = D^{-1} W G^{-T}``):

        * ``tr(A diag(v) A diag(w)) = sum v w (1/d^2 - 2 diag(P P^T) / d)
          + <P^T diag(v) P, P^T diag(w) P>``;
        * ``tr(A diag(v) A dK_j) = 2 sum_m v_m (A W)_m . (A dW_j)_m`` over
          the term's columns;
        * ``tr(A dK_i A dK_j) = 2 tr(Q_i Q_j) + 2 tr(G H_ij)`` with
          ``Q_i = W^T A dW_i``, ``G = W^T A W`` and ``H_ij = dW_i^T A dW_j``.

        ``O(M r^2)`` for ``r`` terms, like the gradient.
        """
        n_terms = len(dWs)
        n = 2 + 4 * n_terms
        fisher = np.empty((n, n))
        diagonals = np.stack([v_scale, np.full_like(d, gamma)])  # (2, M)
        if update is None:
            fisher[:2, :2] = 0.5 * (diagonals / d) @ (diagonals / d).T
            return fisher
        P = update.E
        pp = np.einsum("mk,mk->m", P, P)
        inner = (diagonals * (1.0 / d**2 - 2.0 * pp / d)) @ diagonals.T
        projected = np.einsum("vm,mk,ml->vkl", diagonals, P, P)
        fisher[:2, :2] = 0.5 * (inner + np.einsum("vkl,wkl->vw", projected, projected))
        if not n_terms:
            return fisher
        M = d.shape[0]
        stacked = np.concatenate(dWs, axis=0)  # (4 n_terms, M, 2)
        A_dW = update.solve(stacked.transpose(1, 0, 2).reshape(M, -1)).reshape(M, -1, 2)
        A_dW = A_dW.transpose(1, 0, 2)  # (4 n_terms, M, 2): A dW_i
        columns = np.repeat(np.arange(n_terms), 4)  # the term of each parameter
        AW_i = np.stack([AW[:, 2 * t : 2 * t + 2] for t in columns])  # (p, M, 2)
        # diagonal against a term's parameter: 2 sum_m v_m (A W)_m . (A dW_j)_m
        fisher[:2, 2:] = np.einsum("vm,pmc,pmc->vp", diagonals, AW_i, A_dW)
        fisher[2:, :2] = fisher[:2, 2:].T
        G = W.T @ AW  # (2R, 2R)
        Q = np.einsum("mk,pmc->pkc", AW, stacked)  # W^T A dW_i: (p, 2R, 2)
        H = np.einsum("pmc,qmd->pqcd", stacked, A_dW)  # dW_i^T A dW_j: (p, q, 2, 2)
        # by 2 x 2 blocks of the terms' columns: X[i, j] = Q_i's block of term j's columns,
        # Y[i, j] = G's block (term j's rows, term i's columns)
        X = Q.reshape(Q.shape[0], n_terms, 2, 2)[:, columns]
        blocks = G.reshape(n_terms, 2, n_terms, 2).transpose(0, 2, 1, 3)
        Y = blocks[columns[None, :], columns[:, None]]
        fisher[2:, 2:] = (np.einsum("ijab,jiba->ij", X, X)
                          + np.einsum("ijab,ijba->ij", Y, H))
        return fisher

    def _unpack(self, x):
        self.log_scale, self.noise_level = float(x[0]), float(np.exp(x[1]))
        terms = []
        for r, (k, term) in enumerate(self.terms):
            rate, omega, log_s1, log_s2 = x[2 + 4 * r : 6 + 4 * r]
            terms.append((k, clone(term).set_params(
                alpha=float(np.exp(-2.0 * np.exp(rate))), omega=float(omega),
                sigma1=float(np.exp(log_s1)), sigma2=float(np.exp(log_s2)),
            )))
        self.terms = terms

    def _copy(self):
        copy = _ResonantModel.__new__(_ResonantModel)
        copy.__dict__.update(self.__dict__)
        copy.terms = list(self.terms)
        return copy

    # ------------------------------------------------------------- search
    def optimized(self):
        """A copy with the terms, ``c`` and ``gamma`` tuned jointly (Fisher scoring).

        :func:`gpmultirate.tuning.fisher_scoring` with this model's Fisher
        information (:meth:`_fisher`), in the coordinates of :meth:`_pack`.
        """
        trial = self._copy()
        bounds = trial._bounds()
        x0 = np.clip(trial._pack(), bounds[:, 0], bounds[:, 1])

        def value_grad_fisher(x):
            try:
                return trial._log_evidence(x, eval_gradient=True, eval_fisher=True)
            except (np.linalg.LinAlgError, ValueError):
                return -np.inf, None, None

        start = -value_grad_fisher(x0)[0]
        if not np.all(np.isfinite(bounds)):  # no box to search in: the start, untuned
            trial.value = -start
            return trial
        best = tuning.fisher_scoring(value_grad_fisher, x0, bounds, _IDENTITY)
        x, fun = (best.x, best.fun) if np.isfinite(best.fun) and best.fun <= start else (x0, start)
        trial._unpack(x)
        trial.value = -float(fun)
        return trial

    def term_spreads(self, step: float = 1e-4):
        """``[(omega_std, rate_std)]`` per term: the Laplace approximation at the current values.

        The Hessian of the log evidence over every free coordinate (the
        overall scale, the noise level where tuned, each term's log decay
        rate, frequency and log amplitudes) by central differences of its
        gradient; its negative inverse is the posterior covariance of the
        coordinates, whose frequency and decay-rate entries give the
        standard deviations (the rate's through its log).  Directions
        without negative curvature are left out
        (:func:`~gpmultirate.fitting.spread.marginal_variances`).
        """
        x = self._pack()
        bounds = self._bounds()
        free = np.flatnonzero(bounds[:, 1] > bounds[:, 0])
        hessian = gradient_hessian(lambda z: self._log_evidence(z, True)[1], x, free, step)
        variance = dict(zip(free.tolist(), marginal_variances(hessian)))
        spreads = []
        for r in range(len(self.terms)):
            rate = np.exp(x[2 + 4 * r])
            spreads.append((float(np.sqrt(max(variance.get(3 + 4 * r, 0.0), 0.0))),
                            float(rate * np.sqrt(max(variance.get(2 + 4 * r, 0.0), 0.0)))))
        return spreads

    def with_term(self, k, term):
        """A copy with ``term`` added to input ``k`` and everything re-tuned jointly.

        The new term is replaced by None when it ends not resonant.
        """
        trial = self._copy()
        trial.terms.append((k, term))
        trial = trial.optimized()
        added = trial.terms[-1][1]
        if damping_ratio(added.alpha, added.omega) >= MAX_DAMPING:
            trial.terms[-1] = (k, None)
        return trial

    def kernel(self):
        """The base kernel scaled by ``c`` plus the terms, one input kernel each."""
        kernels = [clone(each) for each in input_kernels(_scaled(self.evidence, self.log_scale))]
        for k, term in self.terms:
            kernels[k] = kernels[k] + term
        return like_inputs(kernels, self.base)


#: the search's own coordinates are the optimizer's (:meth:`_ResonantModel._pack`)
_IDENTITY = tuning.DecayRateTransform([])


def _without_base(kernel, k: int):
    """``kernel`` with input ``k``'s kernel its PK summands alone (its base dropped)."""
    kernels = [clone(each) for each in input_kernels(kernel)]
    terms = resonance_summands(kernels[k])
    alone = clone(terms[0])
    for term in terms[1:]:
        alone = alone + clone(term)
    kernels[k] = alone
    return like_inputs(kernels, kernel)


def _without_pk(kernel):
    """The kernel with its PK summands removed (each input's base part)."""
    return like_inputs([without_resonances(each) for each in input_kernels(kernel)], kernel)


def _tune(evidence, kernel, noise, random_state, max_evaluations=None):
    """Tuned ``(kernel, noise, optimizer result, log evidence)`` from ``evidence``'s start."""
    result = tuning.maximize(evidence, 0, random_state, max_evaluations)
    if result is None:
        return kernel, noise, None, float(evidence(evidence.theta))
    kernel, noise = evidence.split(result.x)
    return kernel, noise, result, float(-result.fun)


def _scaled(evidence, log_scale: float):
    """The kernel of ``evidence`` scaled by ``exp(log_scale)`` through its amplitudes."""
    kernel = evidence.kernel
    positions = evidence.scale_positions()
    if positions is None or log_scale == 0.0:
        return clone(kernel)
    theta = kernel.theta.copy()
    bounds = kernel.bounds.reshape(-1, 2)
    for i, power in positions:
        theta[i] = np.clip(theta[i] + power * log_scale, *bounds[i])
    return kernel.clone_with_theta(theta)
