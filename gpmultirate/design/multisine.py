"""Input design: the multisine whose amplitudes minimize the predicted band.

The input is one period of a multisine on the DFT bins of the record,

    u[n] = sum_k a_k sqrt(2) cos(2 pi k n / N + phi_k),

whose bins are orthogonal over the record, so that its rms is ``||a||``
exactly.  The phases are drawn once (``random_state``); the amplitudes
minimize the :class:`~gpmultirate.design.criterion.BandCriterion` on the
sphere ``||a|| = rms`` (L-BFGS on ``a = rms x / ||x||`` with the exact
gradient).

Bins that alias onto each other at the slow rate
(:func:`~gpmultirate.design.confounding.confounded_frequencies`) share what
the slow samples see of them, so where the power goes within such a group
matters most: besides the flat start (all bins at equal amplitude), the
design starts from the input that puts the designed power on one bin per
alias group (the one of largest prior band), and keeps the better optimum.
A ``floor`` of the power stays flat (:class:`PowerShares`), so that the
second experiment still excites the whole range.  The flat start with
the same phases is the reference the design is judged against.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from gpmultirate.design.confounding import Confounding, confounded_frequencies
from gpmultirate.design.criterion import BandCriterion, CriterionValue, check_criterion
from gpmultirate.design.prior import design_prior
from gpmultirate.design.sampling import SamplingScheme
from gpmultirate.inference import blas_threads_for
from gpmultirate.responses import check_frequencies
from gpmultirate.validation import as_real_array, check_int, check_positive, check_rng

_LOG = logging.getLogger("gpmultirate.design")

__all__ = ["MultisineDesign", "PowerShares", "design_multisine", "flat_multisine",
           "multisine_bins"]

#: iterations of each L-BFGS run of :func:`design_multisine`
MAX_ITERATIONS = 150
#: the share of the flat amplitude every bin keeps by default (a quarter of the power)
DEFAULT_FLOOR = 0.5


@dataclass(frozen=True)
class MultisineDesign:
    """A designed multisine and what it was designed for.

    Attributes
    ----------
    u : ndarray of shape (N,)
        The input, of rms ``rms``.
    freqs : ndarray of shape (K,)
        The candidate bins, in Hz.
    amplitudes, phases : ndarray of shape (K,)
        ``u[n] = sum_k amplitudes[k] sqrt(2) cos(2 pi freqs[k] T n + phases[k])``; an
        amplitude of zero is a bin the design leaves out.
    flat : ndarray of shape (N,)
        The flat multisine over the same bins with the same phases and rms.
    designed, reference : CriterionValue
        The criterion of ``u`` and of ``flat`` (value, band radius per
        evaluation frequency, mean and worst radius).
    eval_freqs : ndarray
        The frequencies the criterion counts.
    confounding : Confounding
        The alias groups among the bins ``u`` excites.
    criterion : str
    seconds : float
        The design's time.
    """

    u: np.ndarray
    freqs: np.ndarray
    amplitudes: np.ndarray
    phases: np.ndarray
    flat: np.ndarray
    designed: CriterionValue
    reference: CriterionValue
    eval_freqs: np.ndarray
    confounding: Confounding
    criterion: str
    seconds: float

    @property
    def narrowing(self) -> float:
        """The flat input's criterion over the designed one's (above 1: narrower bands)."""
        return self.reference.value / self.designed.value


def check_band(band_hz, sample_time: float, name: str = "band_hz") -> tuple[float, float]:
    """``(f_lo, f_hi)`` in ``[0, 1 / (2 T)]`` with ``f_lo < f_hi``."""
    band = as_real_array(band_hz, name).reshape(-1)
    fast_nyquist = 0.5 / sample_time
    if band.shape != (2,) or not np.all(np.isfinite(band)) or not (
            0 <= band[0] < band[1] <= fast_nyquist * (1 + 1e-12)):
        raise ValueError(f"{name} must be (f_lo, f_hi) in Hz with 0 <= f_lo < f_hi <= the "
                         f"fast Nyquist frequency {fast_nyquist:g}; got {band_hz!r}")
    return float(band[0]), float(band[1])


def multisine_bins(n_samples: int, sample_time: float, band_hz) -> np.ndarray:
    """The DFT bins ``k`` of ``n_samples``, strictly between 0 and Nyquist, in ``band_hz``.

    Examples
    --------
    >>> multisine_bins(20, 0.1, (1.0, 3.0))
    array([2, 3, 4, 5, 6])
    """
    low, high = check_band(band_hz, sample_time)
    bins = np.arange(1, (n_samples + 1) // 2)
    freqs = bins / (n_samples * sample_time)
    bins = bins[(freqs >= low - 1e-12) & (freqs <= high + 1e-12)]
    if bins.size == 0:
        raise ValueError(f"band_hz {band_hz!r} holds no DFT bin of a record of {n_samples} "
                         "samples: widen it or lengthen the record")
    return bins


def _basis(n_samples: int, bins: np.ndarray, phases: np.ndarray) -> np.ndarray:
    n = np.arange(n_samples)[:, None]
    return np.sqrt(2.0) * np.cos(2.0 * np.pi * n * bins[None, :] / n_samples + phases[None, :])


class PowerShares:
    """Amplitudes of rms ``rms`` from free coordinates ``x``, each bin keeping a floor.

    ``a_k = rms sqrt(floor^2 / K + (1 - floor^2) x_k^2 / ||x||^2)``: the power
    ``rms^2`` is split into a flat part (``floor^2`` of it, every bin at least
    ``floor`` times the flat amplitude) and a designed part.  With ``floor = 0``,
    ``a = rms x / ||x||`` (the sphere itself, signs as phase flips).
    :meth:`pullback` carries a gradient with respect to ``a`` to ``x``.

    Examples
    --------
    >>> shares = PowerShares(rms=2.0, floor=0.5, n_bins=4)
    >>> a = shares(np.array([1.0, 0.0, 0.0, 0.0]))
    >>> round(float(np.linalg.norm(a)), 12), (a >= 0.5 * 2.0 / 2 - 1e-12).all()
    (2.0, np.True_)
    """

    def __init__(self, rms: float, floor: float, n_bins: int):
        self.rms, self.floor, self.n_bins = rms, floor, n_bins

    def __call__(self, x: np.ndarray) -> np.ndarray:
        norm = np.linalg.norm(x)
        if self.floor == 0.0:
            return self.rms * x / norm
        shares = (x / norm) ** 2
        return self.rms * np.sqrt(self.floor ** 2 / self.n_bins + (1 - self.floor ** 2) * shares)

    def pullback(self, x: np.ndarray, grad_a: np.ndarray) -> np.ndarray:
        norm = np.linalg.norm(x)
        unit = x / norm
        if self.floor == 0.0:
            # the gradient through the projection onto the sphere ||a|| = rms
            return (self.rms / norm) * (grad_a - unit * (unit @ grad_a))
        shares = unit ** 2
        root = np.sqrt(self.floor ** 2 / self.n_bins + (1 - self.floor ** 2) * shares)
        grad_shares = grad_a * self.rms * (1 - self.floor ** 2) / (2.0 * root)
        return (2.0 / norm) * (unit * grad_shares - unit * (shares @ grad_shares))


def flat_multisine(n_samples: int, band_hz, rms: float = 1.0, sample_time: float = 1.0,
                   random_state=None) -> np.ndarray:
    """A random-phase multisine with equal amplitudes on the bins of ``band_hz``, at ``rms``.

    Examples
    --------
    >>> u = flat_multisine(600, (0.5, 3.0), rms=2.0, sample_time=0.1, random_state=0)
    >>> round(float(np.sqrt(np.mean(u ** 2))), 12)
    2.0
    """
    n_samples = check_int(n_samples, "n_samples", low=3)
    rms = check_positive(rms, "rms")
    bins = multisine_bins(n_samples, check_positive(sample_time, "sample_time"), band_hz)
    phases = check_rng(random_state).uniform(0.0, 2.0 * np.pi, size=bins.shape[0])
    return _basis(n_samples, bins, phases) @ np.full(bins.shape[0], rms / np.sqrt(bins.size))


def evaluation_frequencies(n_samples: int, sample_time: float, band_hz) -> np.ndarray:
    """The frequencies a design counts: the DFT bins of the record in ``band_hz``.

    The band between the bins follows them closely (the prior is smooth in
    frequency over a record's resolution), and half as many frequencies
    halve the cost of each evaluation.
    """
    low, high = band_hz
    freqs = np.fft.rfftfreq(n_samples, d=sample_time)
    return freqs[(freqs >= low - 1e-12) & (freqs <= high + 1e-12)]


def relative_weights(prior, freqs) -> np.ndarray:
    """``1 / |G(f)|`` of the prior's pilot model: weights of a band relative to the response."""
    if prior.reference is None:
        raise ValueError("relative bands need a pilot model as prior (its |G| is the "
                         "reference); got a kernel")
    magnitude = prior.reference.frequency_response(
        freqs, sample_time=prior.sample_time).magnitude
    floor = 1e-6 * float(np.max(magnitude)) or np.finfo(float).tiny
    return 1.0 / np.maximum(magnitude, floor)


def design_multisine(prior, n_samples, factor=3, band_hz=None, rms=1.0, noise_level=None,
                     sample_time=None, random_state=None, criterion="mean", *, order=None,
                     offset=0, excite_hz=None, relative=False, level=0.95, floor=DEFAULT_FLOOR,
                     max_iter=MAX_ITERATIONS, return_design=False):
    """A multisine of ``n_samples`` at ``rms`` whose amplitudes minimize the predicted band.

    Parameters
    ----------
    prior : FIRGaussianProcess (fitted), sklearn Kernel or DesignPrior
        As for :func:`~gpmultirate.design.predicted_frequency_response`.
    n_samples : int
        Record length ``N`` in fast samples (at least the order for
        initial conditions ``"zero"``).
    factor : int, default=3
        Downsampling factor ``F``.
    band_hz : (f_lo, f_hi), optional
        The frequencies, in Hz, whose band is minimized; default up to the
        fast Nyquist frequency.
    rms : float, default=1.0
        The input's rms, in the user's units.
    noise_level, sample_time, order : optional
        As for :func:`~gpmultirate.design.predicted_frequency_response`.
    random_state : int, RandomState or None
        Seed of the phases.
    criterion : {"mean", "worst"}, default="mean"
        Minimize the mean band radius over ``band_hz``, or (a smooth stand-in
        for) the largest.
    offset : int or sequence of int, default=0
        The slow sensors' offsets.
    excite_hz : (f_lo, f_hi), optional
        The bins the multisine may excite; default ``band_hz``.
    relative : bool, default=False
        Minimize the band relative to the pilot model's ``|G|`` (the band in
        dB) instead of the band itself.
    level : float, default=0.95
    floor : float, default=0.5
        Every candidate bin keeps at least ``floor`` times the flat
        amplitude (``floor^2`` of the power stays flat), in ``[0, 1)``: an
        input that still excites the whole range, so that hyperparameters
        tuned again on the second experiment stay determined (without it a
        design may starve frequencies the pilot's prior deems known, and a
        re-tuned fit can then widen its band there).  0 lets the design
        leave bins out.
    max_iter : int, default=150
        Iterations of each optimizer run.
    return_design : bool, default=False
        Also return the :class:`MultisineDesign`.

    Returns
    -------
    u : ndarray of shape (n_samples,)
    design : MultisineDesign, only with ``return_design``

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate.kernels import DC, PK
    >>> kernel = C(1.0) * DC(0.9, 0.5) + PK(alpha=0.95, omega=2.0, sigma1=0.3, sigma2=0.3)
    >>> u, design = design_multisine(kernel, 60, factor=3, band_hz=(0.1, 0.5), order=30,
    ...                              noise_level=1e-3, random_state=0, return_design=True)
    >>> round(float(np.sqrt(np.mean(u ** 2))), 12), bool(design.narrowing >= 1.0)
    (1.0, True)
    """
    start_time = time.perf_counter()
    prior = design_prior(prior, order=order, sample_time=sample_time, noise_level=noise_level)
    n_samples = check_int(n_samples, "n_samples", low=3)
    if prior.initial_conditions == "zero" and n_samples < prior.order:
        raise ValueError(f"n_samples must be at least order = {prior.order}; got {n_samples}")
    rms = check_positive(rms, "rms")
    T = prior.sample_time
    band = check_band((0.0, 0.5 / T) if band_hz is None else band_hz, T)
    excite = band if excite_hz is None else check_band(excite_hz, T, "excite_hz")
    criterion = check_criterion(criterion)
    max_iter = check_int(max_iter, "max_iter", low=1)
    floor = check_positive(floor, "floor", allow_zero=True)
    if not floor < 1.0:
        raise ValueError(f"floor must lie in [0, 1); got {floor}")
    scheme = SamplingScheme(factor=factor, offsets=offset)
    bins = multisine_bins(n_samples, T, excite)
    phases = check_rng(random_state).uniform(0.0, 2.0 * np.pi, size=bins.shape[0])
    basis = _basis(n_samples, bins, phases)
    eval_freqs, _ = check_frequencies(evaluation_frequencies(n_samples, T, band), T)
    weights = relative_weights(prior, eval_freqs) if relative else None
    objective = BandCriterion(prior, eval_freqs, criterion, weights, level)

    amplitudes = PowerShares(rms, floor, bins.shape[0])

    flat_x = np.ones(bins.shape[0])
    flat = basis @ amplitudes(flat_x)
    threads = blas_threads_for(scheme.observation(flat, prior.order, latency=prior.latency,
                                                  initial_conditions=prior.initial_conditions))
    with threads:
        reference = objective.value(flat, scheme)
    # the optimizer sees the criterion relative to the flat input's: its tolerances are absolute
    unit_value = reference.value or 1.0

    def fun(x):
        result, grad_u = objective.value_and_gradient(basis @ amplitudes(x), scheme)
        gradient = amplitudes.pullback(x, basis.T @ grad_u)
        return result.value / unit_value, gradient / unit_value

    starts = [flat_x]
    groups = confounded_frequencies(basis @ amplitudes(flat_x), scheme.factor, T).groups
    if groups:
        # one bin per alias group: the one whose prior band is widest
        prior_var = BandCriterion(prior, bins / (n_samples * T), "mean").value(
            np.zeros(n_samples), scheme).radius
        freqs = bins / (n_samples * T)
        one_each = np.ones(bins.shape[0])
        for group in groups:
            members = np.flatnonzero(np.isin(np.round(freqs / freqs[-1], 12),
                                             np.round(group / freqs[-1], 12)))
            one_each[members] = 0.0
            one_each[members[np.argmax(prior_var[members])]] = 1.0
        starts.append(one_each)
    best = None
    with threads:
        for number, x0 in enumerate(starts):
            run = optimize.minimize(fun, x0, jac=True, method="L-BFGS-B",
                                    options={"maxiter": max_iter})
            _LOG.debug("design start %d: %d evaluations, criterion %.4g of the flat input's "
                       "(%s)", number, run.nfev, run.fun, run.message)
            if best is None or run.fun < best.fun:
                best = run
        a = amplitudes(best.x)
        if floor == 0.0:
            # bins the optimum leaves (nearly) empty are left out
            a[np.abs(a) < 1e-3 * np.max(np.abs(a))] = 0.0
            a *= rms / np.linalg.norm(a)
        u = basis @ a
        designed = objective.value(u, scheme)
    if reference.value < designed.value:  # never worse than the reference
        u, a, designed = flat, amplitudes(flat_x), reference
    if not return_design:
        return u
    design = MultisineDesign(
        u=u, freqs=bins / (n_samples * T), amplitudes=np.abs(a),
        phases=np.mod(phases + np.pi * (a < 0), 2.0 * np.pi), flat=flat, designed=designed,
        reference=reference, eval_freqs=eval_freqs,
        confounding=confounded_frequencies(u, scheme.factor, T), criterion=criterion,
        seconds=time.perf_counter() - start_time)
    return u, design
