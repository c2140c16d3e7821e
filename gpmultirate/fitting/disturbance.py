"""The disturbance choice of a fit: white noise, or a disturbance model tuned with the rest.

After the white-noise fit at one order, :func:`choose_disturbance` tunes the
disturbance ``noise_kernel`` asks for (a named one or a kernel), or, for
``"auto"``, decides from cheap checks whether the data call for one
(:func:`calls_for_disturbance`), tunes the candidates and keeps the best only
when it beats white noise by ``AUTO_NOISE_MARGIN``.  The noise models, their
evidence and their routes are :mod:`gpmultirate.noise`'s; this module only
chooses among them, and returns what it chose.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy import linalg
from sklearn.gaussian_process.kernels import Kernel

from gpmultirate import orders, tuning, units
from gpmultirate.crossvalidation import CrossValidation, contiguous_folds
from gpmultirate.fitting.prior import input_powers, starting_prior
from gpmultirate.inference import LogEvidence
from gpmultirate.kernels import observe
from gpmultirate.memory import check_fit_memory
from gpmultirate.noise import (
    AR1_DISTURBANCE,
    NAMED_DISTURBANCES,
    ar1_evidence_gain,
    disturbance_evidence_gain,
    make_noise,
    noise_instants,
)
from gpmultirate.orders import MAX_CHECKED_SAMPLES

__all__ = [
    "AUTO_NOISE_DENSE_GATE",
    "AUTO_NOISE_GATE",
    "AUTO_NOISE_HELD_OUT",
    "AUTO_NOISE_MARGIN",
    "DisturbanceFit",
    "calls_for_disturbance",
    "check_noise_kernel",
    "choose_disturbance",
    "disturbance_gain",
    "fit_disturbance",
    "held_out_loss",
    "is_ar1",
    "takes_ar1_route",
    "white_from",
]

_LOG = logging.getLogger("gpmultirate.fit")

#: nats of log evidence (of cross-validated log predictive likelihood with
#: ``tuning="cross_validation"``) a disturbance model must gain over white noise
#: for ``noise_kernel="auto"`` to choose it (it has two more hyperparameters)
AUTO_NOISE_MARGIN = 10.0
#: nats of log evidence a fixed disturbance must gain over the tuned white-noise
#: fit for ``noise_kernel="auto"`` to tune disturbances at all
AUTO_NOISE_GATE = 3.0
#: beyond this many slow samples ``noise_kernel="auto"`` tunes the AR(1) disturbance
#: of a long record (more samples than coefficients), and its check of samples off a
#: uniform grid keeps white noise instead of ``M x M`` factorizations
AUTO_NOISE_DENSE_GATE = 1000
#: points of held-out fit (fit percent) the response under a disturbance may lose
#: against white noise's for ``noise_kernel="auto"`` to keep it (:func:`held_out_loss`):
#: the one point a disturbance may cost on a measured record (docs/disturbances.rst:
#: true AR(1) disturbances and drifts gain, disturbances that absorb model error lose
#: tens of points)
AUTO_NOISE_HELD_OUT = 1.0
#: contiguous blocks of :func:`held_out_loss`
HELD_OUT_FOLDS = 5


def check_noise_kernel(noise_kernel):
    """``noise_kernel`` checked: ``"white"``, a named disturbance or a scikit-learn kernel.

    Examples
    --------
    >>> check_noise_kernel("matern32")
    'matern32'
    >>> check_noise_kernel("pink")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: noise_kernel must be 'auto', 'white', ... or a scikit-learn kernel; got 'pink'
    """
    if isinstance(noise_kernel, Kernel):
        _check_one_dimension(noise_kernel)
        return noise_kernel
    if isinstance(noise_kernel, str) and (noise_kernel in ("auto", "white", AR1_DISTURBANCE)
                                          or noise_kernel in NAMED_DISTURBANCES):
        return noise_kernel
    names = ", ".join(repr(name) for name in ("auto", "white", *NAMED_DISTURBANCES,
                                              AR1_DISTURBANCE))
    raise ValueError(f"noise_kernel must be {names} or a scikit-learn kernel; "
                     f"got {noise_kernel!r}")


def _check_one_dimension(kernel) -> None:
    """A noise kernel acts on the readings' instants: one column of times."""
    instants = np.array([[0.0], [1.0]])
    try:
        with np.errstate(all="ignore"):
            values = np.asarray(kernel(instants), dtype=float)
        fits = values.shape == (2, 2)
    except Exception as error:  # a kernel of several dimensions refuses one column
        fits, reason = False, f" ({' '.join(str(error).split())})"
    else:
        reason = f" (it gave shape {values.shape} on two instants)"
    if not fits:
        raise ValueError(
            "noise_kernel must act on one dimension, the instants of the readings (a column "
            f"of times); got {kernel!r}{reason}")


def takes_ar1_route(observation) -> bool:
    """Whether ``noise_kernel="auto"`` tunes an AR(1) disturbance instead of dense Matérn ones.

    So it does for more than ``AUTO_NOISE_DENSE_GATE`` slow samples, more
    than the coefficients, on one uniform grid: there the AR(1) noise is
    tuned through its tridiagonal precision
    (:class:`~gpmultirate.covariance.AR1Covariance`) and the dense route's
    ``M x M`` factorizations would dominate the fit.
    """
    if observation.n_outputs <= max(AUTO_NOISE_DENSE_GATE, observation.n_coefficients):
        return False
    return is_ar1(AR1_DISTURBANCE, observation)


def is_ar1(choice, observation) -> bool:
    """Whether the noise ``choice`` takes the AR(1) route on ``observation``."""
    try:
        noise = make_noise(choice, 1.0, (1e-5, 1e5), noise_instants(observation))
    except ValueError:
        return False
    structure = getattr(noise, "structure", None)
    return (structure is not None and structure() is not None and observation.has_regressor
            and observation.n_outputs > observation.n_coefficients)


def calls_for_disturbance(experiment, kernel, noise_level: float,
                          check_tail: bool = True, experiment_at=None, noise_bounds=None,
                          settings=None) -> bool:
    """Whether ``noise_kernel="auto"`` goes on to tune disturbances after the white fit.

    Two cheap checks on the tuned white-noise fit (``kernel`` and
    ``noise_level`` on ``experiment``), in order:

    * at most ``MAX_CHECKED_SAMPLES`` slow samples (a disturbance is tuned
      with the ``M x M`` data covariance);
    * a fixed Matérn disturbance, with the tuned prior held, gains at
      least ``AUTO_NOISE_GATE`` nats of log evidence over the white noise
      (:func:`disturbance_gain`).

    Below the longest record's length, unless the order is the default
    order read from the data (``check_tail=False``), the colour of the
    residuals may be the response's tail cut by the order, which a longer
    order explains, not a disturbance (the paper's study at orders below
    ``N``).  Up to ``AUTO_NOISE_DENSE_GATE`` slow samples a gain found
    there is measured again on a white fit tuned at the record's length
    (``experiment_at(order)`` builds the experiment at another order;
    ``noise_bounds`` and ``settings`` tune it): the cut tail is signal
    there, a disturbance is not.  Beyond, without ``experiment_at`` or
    where ``initial_conditions="discard"`` (no reading is left at that order),
    white noise is kept where the tuned prior has not decayed against the
    noise by twice the order (the output variance it gives the lags from
    the order to twice the order above ``TAIL_TOLERANCE`` times the noise
    variance, :func:`~gpmultirate.orders.prior_tail_lag`, the measure of
    the order check).
    """
    observation, y = experiment.observation, experiment.y
    order, n_samples = observation.order, y.shape[0]
    longest = max(np.asarray(r.u).shape[0] for r in observation.records)
    if n_samples > MAX_CHECKED_SAMPLES:
        _LOG.info("noise: white (%d slow samples, beyond %d for a disturbance model)",
                  n_samples, MAX_CHECKED_SAMPLES)
        return False
    # with initial_conditions="discard" an order of the record's length leaves no reading
    discards = settings is not None and settings.initial_conditions == "discard"
    look_past = (check_tail and order < longest and experiment_at is not None
                 and n_samples <= AUTO_NOISE_DENSE_GATE and not discards)
    if check_tail and order < longest and not look_past and orders.prior_tail_lag(
            kernel, input_powers(experiment), noise_level, 2 * order) >= order:
        _LOG.info("noise: white (the prior has not decayed against the noise by "
                  "order %d: the residuals' colour may be the cut tail)", order)
        return False
    gain = disturbance_gain(experiment, kernel, noise_level)
    if gain is None:
        return False
    _LOG.info("noise: a fixed disturbance gains %.1f nats over white (order %d)", gain, order)
    if gain >= AUTO_NOISE_GATE and look_past:
        # the colour may be the tail the order cuts: look again with the prior and the
        # noise tuned on all the lags of the record, where the tail is signal
        experiment = experiment_at(longest)
        kernel, noise_level = _tuned_white(experiment, kernel, noise_level, noise_bounds,
                                           settings)
        gain = disturbance_gain(experiment, kernel, noise_level)
        if gain is None:
            return False
        _LOG.info("noise: at order %d, where the cut tail is signal, it gains %.1f nats",
                  longest, gain)
    return gain >= AUTO_NOISE_GATE


def _tuned_white(experiment, kernel, noise_level, noise_bounds, settings):
    """The prior and white noise level tuned on ``experiment``: the better of the runs from
    ``kernel`` and ``noise_level`` and from the fit's starting point there (a noise level
    tuned at a short order holds the cut tail, a local optimum at the longer one)."""
    if settings is None or not settings.tuned:
        return kernel, noise_level
    starts = [(kernel, noise_level)]
    first, noise, _ = starting_prior(experiment, settings)
    starts.append((kernel if settings.auto else first, noise))
    best, best_value = (kernel, noise_level), -np.inf
    for start_kernel, start_noise in starts:
        evidence = LogEvidence(experiment.observation, experiment.y, start_kernel, start_noise,
                               noise_bounds)
        result = tuning.maximize(evidence, 0, settings.random_state)
        if result is not None and -result.fun > best_value:
            best, best_value = evidence.split(result.x), -result.fun
    return best


def disturbance_gain(experiment, kernel, noise_level: float) -> float | None:
    """The log evidence a fixed disturbance gains over the white noise, the prior held.

    With more slow samples than coefficients, where the fit has no ``M x M``
    matrix, an AR(1) one on a uniform grid
    (:func:`~gpmultirate.noise.ar1_evidence_gain`, ``O(M P^2)`` once);
    otherwise, up to ``AUTO_NOISE_DENSE_GATE`` slow samples, the dense
    Matérn ones (:func:`~gpmultirate.noise.disturbance_evidence_gain`).
    None (logged) when neither applies.
    """
    observation, y = experiment.observation, experiment.y
    n_samples = y.shape[0]
    term = observe(kernel, observation)
    gain = None
    if n_samples > observation.n_coefficients and observation.has_regressor:
        # the AR(1) form, O(M P^2) once, then P x P per grid point: the long-record
        # route has no M x M matrix, and the check must not bring one
        gain = ar1_evidence_gain(observation.matrix, term.kernel_matrix(), y, noise_level,
                                 noise_instants(observation))
    if gain is None and n_samples <= AUTO_NOISE_DENSE_GATE:
        gain = disturbance_evidence_gain(term.covariance(), y, noise_level,
                                         noise_instants(observation))
    if gain is None:  # say which check could not run, and why
        if not observation.has_regressor:
            why = (f"readings off the ticks have no regressor for the AR(1) check, and more "
                   f"than {AUTO_NOISE_DENSE_GATE} for the dense one")
        elif n_samples <= observation.n_coefficients:
            why = (f"not more than the {observation.n_coefficients} coefficients for the AR(1) "
                   f"check, and more than {AUTO_NOISE_DENSE_GATE} for the dense one")
        else:
            why = "not on one uniform grid"
        _LOG.info("noise: white (%d slow samples: %s)", n_samples, why)
    return gain


def held_out_loss(observation, y, kernel, noise_level: float, disturbance,
                  n_folds: int = HELD_OUT_FOLDS) -> float | None:
    """Points of held-out fit the disturbance's response loses against white noise's.

    The record's slow samples are cut into ``n_folds`` contiguous blocks
    (:func:`~gpmultirate.crossvalidation.contiguous_folds`); each block is
    predicted by the response alone, ``S_BR (S_RR + N_RR)^{-1} y_R`` with
    ``S = Phi K Phi^T`` (the posterior mean of the coefficients given the
    other blocks, through the regressor of the block: a simulation, without
    the disturbance's own prediction), once with the white fit (``kernel``,
    ``noise_level``) and once with the ``disturbance``
    (:class:`DisturbanceFit`).  The errors of each block are taken about
    their mean (a level per block is no response's to predict: a drift
    moves it).  Returns ``100 (|e_disturbance| - |e_white|) / |y - mean(y)|``
    over all blocks, the loss in points of the fit percent; None beyond
    ``AUTO_NOISE_DENSE_GATE`` slow samples (dense ``M x M`` algebra).
    """
    M = y.shape[0]
    if M > AUTO_NOISE_DENSE_GATE or M < 2 * n_folds:
        return None
    sizes = [t.shape[0] for t in noise_instants(observation)]
    folds = contiguous_folds(sizes, min(n_folds, min(sizes)))

    def errors(S, N):
        out = np.empty(M)
        for block in folds:
            rest = np.setdiff1d(np.arange(M), block)
            weights = linalg.cho_solve(linalg.cho_factor(S[np.ix_(rest, rest)]
                                                         + N[np.ix_(rest, rest)]), y[rest])
            error = y[block] - S[np.ix_(block, rest)] @ weights
            # a level per block is no response's to predict: a drift moves it
            out[block] = error - error.mean()
        return float(np.linalg.norm(out))

    S_white = np.asarray(observe(kernel, observation).covariance(), dtype=float)
    S_disturbed = np.asarray(observe(disturbance.kernel, observation).covariance(), dtype=float)
    noise = disturbance.noise_model.add_to(np.zeros((M, M)))
    try:
        white = errors(S_white, float(noise_level) * np.eye(M))
        disturbed = errors(S_disturbed, noise)
    except linalg.LinAlgError:
        return None
    spread = float(np.linalg.norm(y - y.mean())) or 1.0
    return 100.0 * (disturbed - white) / spread


def noise_kernel_in_fit_units(settings, y):
    """The noise choice in the units of the data the fit works on (``y``, its slow samples).

    A kernel given with ``normalize=True`` is read as ``kernel`` and
    ``noise_level`` are, in normalized units (the output divided by its
    RMS): its variances and their bounds are multiplied by ``mean(y**2)``.
    Otherwise (no tuning, or ``normalize=False``) it is in the data's units
    and divided by the output's power of two squared; a model file of
    normalized hyperparameters gives it in the fit's units already.
    """
    choice = settings.noise_kernel
    if isinstance(choice, str) or settings.scale is None or settings.prior_in_normalized_units:
        return choice
    if settings.normalize:
        return units.scaled_noise_kernel(choice, float(np.mean(y**2)) or 1.0)
    return units.scaled_noise_kernel(choice, settings.scale.variance(1.0, to_data=False))


@dataclass(frozen=True)
class DisturbanceFit:
    """A disturbance model tuned with everything else.

    ``evidence``: the :class:`~gpmultirate.inference.LogEvidence` with the
    noise model; ``kernel``, ``noise_model``: the tuned prior and noise;
    ``posterior``: the posterior of the coefficients there;
    ``optimizer_result``: the optimizer's run (None when nothing was
    tuned); ``score``: the tuning criterion at the tuned point.  With
    ``noise_model`` None, white noise of variance ``noise_level`` (a white
    fit tuned again, :func:`white_from`).
    """

    evidence: object
    kernel: object
    noise_model: object
    posterior: object
    optimizer_result: object
    score: float
    noise_level: float | None = None


def fit_disturbance(observation, y, kernel, noise_level, noise_bounds, choice, settings,
                    start=None) -> DisturbanceFit:
    """Tune a disturbance model with everything else, from the white fit's point.

    ``choice``: a noise choice (:func:`~gpmultirate.noise.make_noise`);
    ``start``: a noise model to go on from instead.  By the criterion of
    ``settings``: the log evidence, or the cross-validated log predictive
    likelihood (:class:`~gpmultirate.crossvalidation.CrossValidation` with
    the noise model, on the same folds as the white fit).
    """
    noise_model = start if start is not None else make_noise(
        choice, noise_level, noise_bounds, noise_instants(observation))
    evidence = LogEvidence(observation, y, kernel, noise_level, noise_bounds, noise=noise_model)
    objective = evidence
    if settings.criterion == "cross_validation":
        objective = CrossValidation(observation, y, kernel, noise_level, noise_bounds,
                                    settings.n_folds, noise=noise_model)
    result = None
    if settings.tuned:
        result = tuning.maximize(objective, settings.n_restarts, settings.random_state)
        if result is not None:
            kernel, noise_model = objective.split_models(result.x)
    posterior, score = _scored(evidence, objective, kernel, noise_model)
    return DisturbanceFit(evidence, kernel, noise_model, posterior, result, score)


def _scored(evidence, objective, kernel, noise):
    """The posterior at ``(kernel, noise)`` and the tuning criterion there: its log
    evidence, or ``objective``'s value (cross-validation) where it is not the evidence."""
    posterior = evidence.posterior(kernel, noise)
    if objective is evidence:
        return posterior, posterior.log_marginal_likelihood
    moved = objective.moved_to(kernel, noise)
    return posterior, float(moved(moved.theta))


def choose_disturbance(experiment, kernel, noise_level: float, noise_bounds, white_score,
                       settings, cross_validated: bool = False,
                       experiment_at=None) -> DisturbanceFit | None:
    """The disturbance the fit keeps after the white-noise fit, or None for white noise.

    ``kernel``, ``noise_level``: the tuned white-noise fit on ``experiment``;
    ``white_score``: its criterion (the log evidence, or with
    ``cross_validated`` the cross-validated log predictive likelihood).  A
    named disturbance or kernel in ``settings.noise_kernel`` is tuned and
    kept; ``"auto"`` tunes candidates only when :func:`calls_for_disturbance`
    (the Matérn ones, or beyond ``AUTO_NOISE_DENSE_GATE`` slow samples on one
    uniform grid the AR(1) one, :func:`takes_ar1_route`) and keeps the best
    only when it gains ``AUTO_NOISE_MARGIN`` over white noise and loses at
    most ``AUTO_NOISE_HELD_OUT`` points of held-out fit (:func:`held_out_loss`).
    ``experiment_at(order)``: the experiment at another order, where the
    check looks past the order (:func:`calls_for_disturbance`).
    """
    choice = settings.noise_kernel
    if choice == "white" or (choice == "auto" and not calls_for_disturbance(
            experiment, kernel, noise_level, check_tail=not settings.order_from_data,
            experiment_at=experiment_at, noise_bounds=noise_bounds, settings=settings)):
        return None
    observation, y = experiment.observation, experiment.y
    # the disturbance is tuned with everything else, from the white fit
    if choice != "auto":
        choices = [noise_kernel_in_fit_units(settings, y)]
    elif takes_ar1_route(observation):
        # a long record on one uniform grid: the AR(1) disturbance keeps the
        # long-record cost where the dense Matérn ones need M x M matrices
        choices = [AR1_DISTURBANCE]
    else:
        choices = list(NAMED_DISTURBANCES)
    # cross-validation works in data space whatever the noise's structure
    if cross_validated or not (len(choices) == 1 and is_ar1(choices[0], observation)):
        check_fit_memory(y.shape[0], y.shape[0], kernel.theta.shape[0] + 3)
    best = None
    for candidate in choices:
        tried = fit_disturbance(observation, y, kernel, noise_level, noise_bounds, candidate,
                                settings)
        if best is None or tried.score > best.score:
            best = tried
    if choice != "auto":
        return best
    if best.score <= white_score + AUTO_NOISE_MARGIN:
        return None
    lost = held_out_loss(observation, y, kernel, noise_level, best)
    if lost is not None and lost > AUTO_NOISE_HELD_OUT:
        _LOG.info("noise: white (the disturbance gains %.1f nats but its response predicts "
                  "the held-out blocks %.2f points worse)", best.score - white_score, lost)
        return None
    again = white_from(best, observation, y, noise_bounds, settings, cross_validated)
    if again is not None and best.score <= again.score + AUTO_NOISE_MARGIN:
        # the disturbance's tuning found a better prior, not a disturbance: white from there
        _LOG.info("noise: white (tuned again from the disturbance's prior, white noise comes "
                  "within %.1f nats of it)", best.score - again.score)
        return again
    return best


def white_from(disturbed: DisturbanceFit, observation, y, noise_bounds, settings,
               cross_validated: bool = False) -> DisturbanceFit | None:
    """White noise tuned again from a disturbance fit's prior: a :class:`DisturbanceFit`
    whose ``noise_model`` is None.

    The disturbance is tuned with the prior, from the white fit: where the white fit's
    tuning ended at a poorer optimum of the prior, the disturbance's gain over it is the
    better prior's, not its own (a two-mass system of ``benchmarks/automatic.py``: 10
    nats over white, with a disturbance of 1e-6 of the noise's std).  White noise of the
    disturbed fit's variance per sample, tuned with the prior from there, is the fair
    comparison.  None where nothing is tuned, or the noise has no variance per sample.
    """
    if not settings.tuned:
        return None
    try:
        level = float(disturbed.noise_model.sample_variance())
    except (AttributeError, NotImplementedError, TypeError, ValueError):
        return None
    low, high = np.asarray(noise_bounds, dtype=float).ravel()[:2]
    level = float(np.clip(level, low, high))
    evidence = LogEvidence(observation, y, disturbed.kernel, level, noise_bounds)
    objective = evidence
    if cross_validated:
        objective = CrossValidation(observation, y, disturbed.kernel, level, noise_bounds,
                                    settings.n_folds)
    result = tuning.maximize(objective, 0, settings.random_state)
    kernel, level = (disturbed.kernel, level) if result is None else evidence.split(result.x)
    posterior, score = _scored(evidence, objective, kernel, level)
    return DisturbanceFit(evidence, kernel, None, posterior, result, score, level)
