"""Marginal-likelihood tuning strategy (paper eq. 19, noise inside the determinant).

:func:`maximize` takes the objective, a
:class:`~gpmultirate.inference.LogEvidence`, and returns the optimum.  The
evidence of resonant kernels is multimodal in the resonance frequencies and
badly scaled in the overall amplitude, so a single gradient run from the
user's initial values is fragile.  The strategy is:

1. fit the overall scale of the kernel and the noise level with the kernel's
   shape fixed: with ``Phi K Phi^T = Q diag(s) Q^T`` the evidence of
   ``(c K, gamma)`` is a cheap sum over the eigenvalues, so this 2-D problem is
   solved from several starts at negligible cost; this makes the fit
   independent of the units of ``u`` and ``y``;
2. for each free resonance frequency (a hyperparameter whose
   :class:`~gpmultirate.kernels.Role` is ``"frequency"``, such as the
   ``omega`` of a :class:`~gpmultirate.kernels.PK` term), evaluate the
   evidence on a grid around its initial value, keep the best and restrict
   the frequency to a window around it;
3. maximize over all free hyperparameters, in decay-rate coordinates for
   the decays (role ``"decay"``) and in ``theta`` for the rest (the log of
   a positive value, ``artanh`` of a correlation), by Fisher scoring up to
   ``FISHER_MAX_OUTPUTS`` (reduced) slow samples and by L-BFGS-B with
   analytic gradients above, and above ``PRECISION_LBFGS_ABOVE`` where the
   evidence goes through the prior's tridiagonal precision (DC on square or
   reduced data), from that point and from optional random restarts.  The
   L-BFGS-B runs measure an amplitude that scales a correlation's term
   against it (:class:`CorrelationScaleTransform`), which straightens the
   valley of DC's evidence.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy import linalg, optimize
from sklearn.exceptions import ConvergenceWarning

from gpmultirate.covariance import SpectralCovariance, relative_spectrum
from gpmultirate.exceptions import NumericalWarning
from gpmultirate.progress import EVALUATIONS
from gpmultirate.validation import check_rng

__all__ = [
    "CorrelationScaleTransform",
    "DecayRateTransform",
    "fisher_scoring",
    "grid_search_resonances",
    "maximize",
    "minimize_lbfgs",
    "prefit_scale_and_noise",
    "warn_at_bounds",
]

# L-BFGS-B settings: tighter than scipy's defaults, which stop early on the
# flat, long valleys of the evidence.
LBFGS_OPTIONS = {"maxiter": 2000, "ftol": 1e-12, "gtol": 1e-7, "maxls": 50}
# A run that stops on a small relative reduction where its gradient still promises
# more than RESTART_GAIN nats (or has an entry above RESTART_GRADIENT) starts
# again from its end, at most LBFGS_RESTARTS times (see _promises_more).
LBFGS_RESTARTS = 3
RESTART_GAIN = 1e-3
RESTART_GRADIENT = 1.0
# A run also stops once an iteration gains less than STOP_GAIN nats: the relative
# ftol alone asks for 6e-9 nats at the 5,922 nats of a camera log's evidence, below
# what the evidence's own rounding resolves there, and the line searches of the last
# iterations then spent 19 of 34 evaluations (85 s at order 7,992) without a gain
# (tests/test_tuning_coordinates.py, benchmarks/camera_log.py).  1e-6 nats moves a
# hyperparameter by about 1e-3 of its posterior standard deviation.  Not for a
# disturbance's tuning, whose iterations along the amplitudes' ridge gain less.
STOP_GAIN = 1e-6
# A run also stops once its last iteration gained under EXPECTED_GAIN nats and its own
# quadratic model (the curvature pairs of its iterates, :class:`_ExpectedGainStop`)
# promises under EXPECTED_GAIN more: both small, the run sits at its optimum to about
# 0.05 posterior standard deviations of any hyperparameter (a gain of d^2 / 2 nats
# moves it d of them).  A small gain alone does not say so: on a flat stretch far
# from the optimum an iteration gains little where the curvature promises much (an
# amplitude at 74.6 whose optimum is its bound 2.69, tests/test_tuning_coordinates.py).
# Not for a disturbance's tuning (as STOP_GAIN).
EXPECTED_GAIN = 1e-3
# relative span and number of points of the resonance-frequency grid
RESONANCE_SPAN = 1.4
RESONANCE_POINTS = 41
# Up to this many (reduced) slow samples the hyperparameters are tuned by Fisher
# scoring (each iteration forms the M x M derivative of the data covariance per
# hyperparameter); above it by L-BFGS-B, whose iterations need only traces.
FISHER_MAX_OUTPUTS = 1000
# A disturbance model's tuning: L-BFGS-B for at most this many evaluations (it picks
# the basin: Fisher scoring from the white fit ended in a poorer one on a measured
# record, 537.5 against 673.9 nats), then Fisher scoring to the end (L-BFGS-B needs
# thousands of evaluations along the ridge of the amplitudes; within one nat of its
# end after 100-170 on the ar1 systems of benchmarks/automatic.py; with 100 one
# system of ten there chose the other Matern candidate)
COLOURED_LBFGS_EVALUATIONS = 200
# Through the prior's tridiagonal precision (DC on square or reduced data) an
# evaluation with its gradient costs a fraction of a Fisher information, and
# L-BFGS-B wins above this many coefficients despite its 2-4 times as many
# evaluations (reduced long record, DC: 0.24 s against 0.16 s at P = 150, 1.75 s
# against 0.29 s at P = 400, 18.8 s against 4.4 s at P = 1000).  Below it the gain
# is under 0.1 s a fit, and Fisher scoring keeps the results of earlier versions.
PRECISION_LBFGS_ABOVE = 200


def maximize(evidence, n_restarts: int = 0, random_state=None, max_evaluations=None):
    """Maximize the log evidence over its ``theta``; the whole tuning strategy.

    Parameters
    ----------
    evidence : LogEvidence
        The objective, with its initial point, bounds and roles.
    n_restarts : int, default=0
        Extra runs from points drawn uniformly within the bounds of ``theta``
        (log bounds of positive values, ``artanh`` bounds of correlations).
    random_state : int, RandomState, Generator or None
        Seed of the restarts.
    max_evaluations : int, optional
        A budget of evaluations per L-BFGS-B run (Fisher scoring, on small
        problems, is not limited): a run that spends it stops there without
        a :class:`~sklearn.exceptions.ConvergenceWarning` (a start already
        near the optimum, whose last steps are not worth their cost).

    Returns
    -------
    scipy.optimize.OptimizeResult or None
        The best run: ``x`` in ``theta`` coordinates, ``fun`` the negative
        log evidence.  None when nothing is free.

    Raises
    ------
    ValueError
        When the evidence cannot be evaluated at any optimizer point.
    """
    evidence = evidence.reusing_kernel()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        # a disturbance model starts from its white fit: no prefit of gamma alone
        coloured = getattr(evidence, "coloured", False)
        theta0, scale_message = (evidence.theta.copy(), None) if coloured else _prefit(
            evidence)
        if theta0.shape[0] == 0:
            return None
        bounds = evidence.bounds
        roles = evidence.roles()
        resonances = [i for i, role in enumerate(roles) if role.kind == "frequency"]
        if resonances and not coloured:
            theta0 = grid_search_resonances(evidence, theta0, bounds, resonances)
        if resonances:
            # a disturbance's tuning starts from the white fit's frequencies: it refines
            # them, it does not move a term onto another mode or the Nyquist frequency
            bounds = resonance_window(theta0, bounds, resonances)
        transform = DecayRateTransform(
            [i for i, role in enumerate(roles) if role.kind == "decay"]
        )
        # the progress expects a run to take as many evaluations as the last of its kind
        kind = (bool(coloured), int(theta0.shape[0]))
        fisher = evidence.has_fisher and evidence.n_outputs <= FISHER_MAX_OUTPUTS and not (
            evidence.n_outputs > PRECISION_LBFGS_ABOVE and evidence.by_precision)
        if fisher and coloured:
            coupled = CorrelationScaleTransform(transform.indices, evidence.amplitude_couplings())

            def run(start):
                # L-BFGS-B chooses the basin, Fisher scoring ends the crawl along its ridge
                with EVALUATIONS.run(kind):
                    # no gain floor for a disturbance: along the amplitudes' ridge each
                    # iteration gains little (a disturbance's amplitude stopped short of
                    # the bound the data push it to, tests/test_noise_units.py)
                    first = minimize_lbfgs(EVALUATIONS.timed(_negative(evidence)), start,
                                           bounds, coupled, COLOURED_LBFGS_EVALUATIONS,
                                           stop_gain=None)
                    if not np.isfinite(first.fun) or first.success:
                        return first
                    last = fisher_scoring(EVALUATIONS.timed(_value_grad_fisher(evidence)),
                                          first.x, bounds, transform)
                last.nfev += first.nfev
                last.nit += first.nit
                return last if last.fun <= first.fun else first
        elif fisher:

            def run(start):
                with EVALUATIONS.run(kind):  # the progress's measured cost of an evaluation
                    return fisher_scoring(EVALUATIONS.timed(_value_grad_fisher(evidence)),
                                          start, bounds, transform)
        else:
            coupled = CorrelationScaleTransform(transform.indices, evidence.amplitude_couplings())

            def run(start):
                with EVALUATIONS.run(kind):
                    return minimize_lbfgs(EVALUATIONS.timed(_negative(evidence)), start,
                                          bounds, coupled, max_evaluations,
                                          stop_gain=None if coloured else STOP_GAIN)

        runs = [run(theta0)]
        rng = check_rng(random_state)
        for _ in range(n_restarts):
            runs.append(run(rng.uniform(bounds[:, 0], bounds[:, 1])))
    finite = [r for r in runs if np.isfinite(r.fun)]
    if not finite:
        raise ValueError(
            "the marginal likelihood could not be evaluated at any optimizer point; "
            "check the kernel, its bounds and noise_level_bounds"
        )
    best = min(finite, key=lambda r: r.fun)
    if scale_message is not None and _amplitude_on_a_bound(evidence, best.x):
        # at the start's shape the data called for a scale the bounds do not admit, and
        # the tuned shape did not take it back: say why the amplitude sits on its bound
        warnings.warn(scale_message, ConvergenceWarning, stacklevel=3)
    if max_evaluations is None or best.nfev < max_evaluations:
        warn_if_not_converged(best)
    return best


def _amplitude_on_a_bound(evidence, theta) -> bool:
    """Whether an amplitude that scales the whole kernel ends on one of its bounds."""
    positions = evidence.scale_positions()
    bounds = evidence.bounds
    return positions is not None and any(
        min(abs(theta[i] - bounds[i, 0]), abs(theta[i] - bounds[i, 1])) < 1e-6
        for i, _ in positions)


def _negative(evidence):
    """``theta -> (-log evidence, -gradient)``, infinite where it cannot be evaluated."""

    def objective(theta):
        try:
            value, grad = evidence(theta, eval_gradient=True)
        except ValueError:
            return np.inf, np.zeros_like(theta)
        return -value, -grad

    return objective


def _value_grad_fisher(evidence):
    """``theta -> (log evidence, gradient, Fisher)``, ``-inf`` where it cannot be evaluated."""

    def value_grad_fisher(theta):
        try:
            return evidence.with_fisher(theta)
        except ValueError:
            return -np.inf, None, None

    return value_grad_fisher


def prefit_scale_and_noise(evidence) -> np.ndarray:
    """Fit the overall kernel scale and the noise level with the shape fixed.

    Returns the initial ``theta`` with the amplitudes that scale the whole
    kernel (``evidence.scale_positions()``) and the log noise level moved to
    their optimum; values are clipped to their bounds.  A
    :class:`~sklearn.exceptions.ConvergenceWarning` says so when the bounds
    of the amplitudes do not admit that scale.
    """
    theta, message = _prefit(evidence)
    if message is not None:
        warnings.warn(message, ConvergenceWarning, stacklevel=2)
    return theta


def _prefit(evidence):
    """:func:`prefit_scale_and_noise`'s ``theta``, and the message of bounds that do
    not admit the data's scale (or None)."""
    theta = evidence.theta.copy()
    scale_positions = evidence.scale_positions()
    fit_scale = scale_positions is not None
    fit_noise = evidence.noise_is_free
    if not (fit_scale or fit_noise):
        return theta, None
    y = evidence.z
    spectral = SpectralCovariance(evidence.covariance(), y)
    s = spectral.eigenvalues
    z2 = spectral.rotated_y**2
    power = float(np.mean(y**2)) or 1.0
    noise_level = evidence.noise_level

    # samples a reduced observation left out: independent N(0, g), sum of squares rho^2
    # (the remainder of the data covariance; its constant is left out of this objective)
    remainder = evidence.remainder()
    n_rest, rho2 = remainder.n, remainder.sum_of_squares

    def objective(x):
        log_c = x[0] if fit_scale else 0.0
        log_g = x[-1] if fit_noise else np.log(noise_level)
        c, g = np.exp(log_c), np.exp(log_g)
        d = spectral.diagonal(c, g)
        value = 0.5 * np.sum(z2 / d + np.log(d)) + 0.5 * (n_rest * log_g + rho2 / g)
        common = 0.5 * (1.0 / d - z2 / d**2)
        grad = []
        if fit_scale:
            grad.append(np.sum(common * c * s))
        if fit_noise:
            grad.append(np.sum(common * g) + 0.5 * (n_rest - rho2 / g))
        return value, np.array(grad)

    mean_s = float(np.mean(s)) or 1.0
    scale0 = np.log(power / mean_s)
    bounds = []
    if fit_scale:
        # the data's own scale is searched without the kernel's bounds, so that
        # bounds that do not admit it are reported instead of silently binding
        bounds.append((scale0 - 60.0, scale0 + 60.0))
    if fit_noise:
        bounds.append(tuple(np.log(evidence.noise_bounds)))
    starts = []
    for relative_noise in (1e-1, 1e-3, 1e-5, 1e-7):
        x = []
        if fit_scale:
            x.append(scale0)
        if fit_noise:
            x.append(np.log(relative_noise * power))
        starts.append(_clip(np.array(x), bounds))
    if fit_noise:
        x = [scale0] if fit_scale else []
        starts.append(_clip(np.array(x + [np.log(noise_level)]), bounds))
    best = None
    for x0 in starts:
        result = optimize.minimize(
            objective, x0, jac=True, method="L-BFGS-B", bounds=bounds, options=LBFGS_OPTIONS
        )
        if np.isfinite(result.fun) and (best is None or result.fun < best.fun):
            best = result
    if best is None:  # no start gave a finite evidence: the optimizer's runs report it
        return theta, None
    theta_bounds = evidence.bounds
    message = None
    if fit_scale:
        log_scale = float(best.x[0])
        message = _scale_out_of_bounds(evidence, theta, theta_bounds, scale_positions,
                                       log_scale)
        for i, p in scale_positions:
            theta[i] = np.clip(theta[i] + p * log_scale, *theta_bounds[i])
    if fit_noise:
        theta[-1] = best.x[-1]
    return _prefit_each_scale(evidence, theta, theta_bounds), message


def _prefit_each_scale(evidence, theta, bounds, sweeps: int = 2) -> np.ndarray:
    """Fit the scale of each independent part of ``S`` (each input) with the rest fixed.

    With ``R`` the covariance of the rest of the data and ``R = L L^T``, the
    part ``c S_k`` enters through the eigenvalues ``s`` of ``L^{-1} S_k L^{-T}``:
    the evidence of ``c`` is ``-1/2 sum(z^2 / (1 + c s) + log(1 + c s))`` with
    ``z = Q^T L^{-1} y``, a one-dimensional problem solved at negligible cost.
    The parts are computed once and rescaled in place (scaling a part's
    amplitudes scales it exactly); two sweeps over the parts.
    """
    groups = evidence.scale_groups(theta)
    if groups is None or len(groups) < 2:
        return theta
    noise = float(np.exp(theta[-1])) if evidence.noise_is_free else evidence.noise_level
    y = evidence.z
    parts = [S.copy() for _, _, S in groups]
    for _ in range(sweeps):
        for k, (positions, powers, _) in enumerate(groups):
            R = sum(S for j, S in enumerate(parts) if j != k)
            R[np.diag_indices_from(R)] += noise
            spectrum = relative_spectrum(R, parts[k], y)
            if spectrum is None:
                continue
            s, z2 = spectrum
            low = max((bounds[i, 0] - theta[i]) / p for i, p in zip(positions, powers))
            high = min((bounds[i, 1] - theta[i]) / p for i, p in zip(positions, powers))
            if not low <= 0.0 <= high:
                continue

            def objective(x):
                d = 1.0 + np.exp(x) * s
                return 0.5 * np.sum(z2 / d + np.log(d))

            result = optimize.minimize_scalar(
                objective, bounds=(max(low, -60.0), min(high, 60.0)), method="bounded",
                options={"xatol": 1e-3},
            )
            if result.success and result.fun < objective(0.0):
                for i, p in zip(positions, powers):
                    theta[i] = np.clip(theta[i] + p * result.x, *bounds[i])
                parts[k] *= np.exp(result.x)
    return theta


def _scale_out_of_bounds(evidence, theta, bounds, positions, log_scale) -> str | None:
    """The message when the bounds of the amplitudes do not admit the data's scale."""
    low = max((bounds[i, 0] - theta[i]) / p for i, p in positions)
    high = min((bounds[i, 1] - theta[i]) / p for i, p in positions)
    if low > high or low - np.log(10.0) <= log_scale <= high + np.log(10.0):
        return None
    roles = evidence.roles()
    names = ", ".join(roles[i].name for i, _ in positions)
    return (f"the data call for the kernel to be scaled by {np.exp(log_scale):.3g}, which the "
            f"bounds of its amplitude hyperparameters ({names}) do not allow; the fit will be "
            "poor. Widen those bounds to the units of u and y, or use kernel=None, whose "
            "bounds follow the data.")


def _clip(x, bounds):
    low = np.array([b[0] if b[0] is not None else -np.inf for b in bounds])
    high = np.array([b[1] if b[1] is not None else np.inf for b in bounds])
    return np.clip(x, low, high)


class DecayRateTransform:
    """Optimizer coordinates in which decay parameters are well scaled.

    A decay parameter ``a`` in (0, 1] (``alpha``) enters ``theta`` as
    ``log a``, which is tiny and badly scaled for the values near 1 that
    impulse responses need.  The optimizer works on ``z = log(-log a)``, the
    log of the decay rate per sample, instead; the other coordinates are
    unchanged.  A correlation in (-1, 1) (DC's ``beta``, role
    ``"correlation"``) needs no such change: its ``theta = artanh(beta)``
    is already close to ``-log(1 - |beta|) / 2`` near ``+-1``.

    Parameters
    ----------
    indices : sequence of int
        Positions in ``theta`` of the decay parameters (role ``"decay"``).
    """

    # decay rates below this are treated as zero (a = 1 within rounding)
    MIN_RATE = 1e-10
    # coordinates whose bounds are not a box in z (see CorrelationScaleTransform)
    couplings = ()

    def __init__(self, indices):
        self.indices = np.array(indices, dtype=int)

    def to_z(self, theta):
        z = np.array(theta, dtype=float)
        rate = np.maximum(-z[self.indices], self.MIN_RATE)
        z[self.indices] = np.log(rate)
        return z

    def to_theta(self, z):
        theta = np.array(z, dtype=float)
        theta[self.indices] = -np.exp(theta[self.indices])
        return theta

    def bounds(self, theta_bounds):
        b = np.array(theta_bounds, dtype=float)
        low = -b[self.indices, 1]  # smallest rate comes from the largest value
        high = -b[self.indices, 0]
        b[self.indices, 0] = np.log(np.maximum(low, self.MIN_RATE))
        b[self.indices, 1] = np.log(np.maximum(high, self.MIN_RATE))
        return b

    def gradient(self, grad_theta, theta):
        g = np.array(grad_theta, dtype=float)
        g[self.indices] *= theta[self.indices]  # d theta / d z = theta
        return g

    def plain(self) -> "DecayRateTransform":
        """These coordinates without couplings: the bounds of ``theta`` are a box in them."""
        return self


class CorrelationScaleTransform(DecayRateTransform):
    """Decay-rate coordinates, with each coupled amplitude measured against its correlation.

    DC's prior precision is ``K^{-1} = D^{-1} T^{-1} D^{-1} / c`` with the
    tridiagonal ``T^{-1}`` of entries ``O(1 / (1 - beta^2))``: the evidence
    changes little along ``c (1 - beta^2) = const`` and L-BFGS-B crawls along
    that valley in ``(log c, artanh beta)`` (a long record at P = 2000: 64
    evaluations, the amplitude moving by ``e^16``).  For each pair
    ``(j, a, p)`` of :meth:`~gpmultirate.inference.LogEvidence.amplitude_couplings`
    the optimizer works on ``z_a = theta_a + p log(1 - tanh(theta_j)^2)``
    (``p`` the amplitude's power) instead of ``theta_a``; every other
    coordinate is as in :class:`DecayRateTransform`.

    The bounds of ``theta_a`` are not a box in ``z``, so :meth:`bounds` leaves
    ``z_a`` free and :func:`minimize_lbfgs` polishes a result outside them in
    plain coordinates.  A free coordinate also makes L-BFGS-B scale its first
    step to unit length; with every coordinate bounded it takes the full
    gradient step, which on the evidence lands far off (a wasted line search).

    Parameters
    ----------
    indices : sequence of int
        Positions of the decay parameters.
    couplings : sequence of (int, int, float)
        ``(correlation position, amplitude position, power)``.

    Examples
    --------
    ``theta`` of ``C * DC`` with a free noise level: ``log c``, ``log alpha``,
    ``artanh beta``, ``log gamma``.  Points with the same ``c (1 - beta^2)``
    share the amplitude coordinate:

    >>> import numpy as np
    >>> t = CorrelationScaleTransform([1], [(2, 0, 1.0)])
    >>> for beta in (0.9, 0.99):
    ...     theta = np.array([-np.log(1 - beta**2), np.log(0.95), np.arctanh(beta), -4.0])
    ...     print(t.to_z(theta).round(4) + 0.0)
    [ 0.     -2.9702  1.4722 -4.    ]
    [ 0.     -2.9702  2.6467 -4.    ]
    >>> bool(np.allclose(t.to_theta(t.to_z(theta)), theta))
    True
    """

    def __init__(self, indices, couplings=()):
        super().__init__(indices)
        self.couplings = [(int(j), int(a), float(p)) for j, a, p in couplings]

    @staticmethod
    def _log_one_minus_square(x):
        """``log(1 - tanh(x)^2) = -2 log cosh(x)``, without overflow."""
        return -2.0 * (np.logaddexp(x, -x) - np.log(2.0))

    def to_z(self, theta):
        z = super().to_z(theta)
        for j, a, p in self.couplings:
            z[a] = theta[a] + p * self._log_one_minus_square(theta[j])
        return z

    def to_theta(self, z):
        theta = super().to_theta(z)
        for j, a, p in self.couplings:
            theta[a] = z[a] - p * self._log_one_minus_square(z[j])
        return theta

    def bounds(self, theta_bounds):
        b = super().bounds(theta_bounds)
        for _, a, _ in self.couplings:
            b[a] = [-np.inf, np.inf]
        return b

    def gradient(self, grad_theta, theta):
        g = super().gradient(grad_theta, theta)
        for j, a, p in self.couplings:
            # theta_a = z_a - p s(z_j), s'(x) = -2 tanh(x)
            g[j] += 2.0 * p * np.tanh(theta[j]) * grad_theta[a]
        return g

    def plain(self) -> DecayRateTransform:
        """The same decay-rate coordinates without the couplings."""
        return DecayRateTransform(self.indices)


def grid_search_resonances(evidence, theta, bounds, indices):
    """Coordinate-wise grid search of the resonance frequencies.

    For each position in ``indices`` (frequencies, whose ``theta`` is the
    log of the value), the log evidence is evaluated on a
    geometric grid of ``RESONANCE_POINTS`` values within a factor
    ``RESONANCE_SPAN`` of the current one, all at once where
    ``evidence.along`` can (a low-rank summand, by rank updates of one
    factorization), one by one otherwise.  Returns the improved ``theta``.
    """
    theta = theta.copy()
    offsets = np.log(np.geomspace(1.0 / RESONANCE_SPAN, RESONANCE_SPAN, RESONANCE_POINTS))
    roles = evidence.roles()
    for i in indices:
        candidates = np.unique(np.clip(theta[i] + offsets, bounds[i, 0], bounds[i, 1]))
        try:
            values = evidence.along(theta, i, roles[i].transform.from_theta(candidates))
        except ValueError:
            values = None
        if values is None:
            values = []
            for candidate in candidates:
                trial = theta.copy()
                trial[i] = candidate
                try:
                    values.append(evidence(trial))
                except ValueError:
                    values.append(-np.inf)
        theta[i] = candidates[int(np.nanargmax(values))]
    return theta


def resonance_window(theta, bounds, indices):
    """Restrict each resonance frequency to ``RESONANCE_SPAN`` around its grid optimum.

    The evidence has a local optimum at every resonance of the system (and a
    flat one at zero amplitude); without a window, a prior resonance can
    drift to another mode or die during the gradient refinement.
    """
    bounds = np.array(bounds, dtype=float)
    half = np.log(RESONANCE_SPAN)
    for i in indices:
        bounds[i, 0] = max(bounds[i, 0], theta[i] - half)
        bounds[i, 1] = min(bounds[i, 1], theta[i] + half)
    return bounds


def minimize_lbfgs(objective_and_gradient, theta0, bounds, transform=None,
                   max_evaluations=None, stop_gain=STOP_GAIN):
    """Bounded L-BFGS-B in ``transform`` coordinates; returns the result in theta.

    ``max_evaluations``: at most that many evaluations (``maxfun``) in all.
    ``stop_gain``: an iteration that gains less than this many nats ends a
    run (:func:`_gain_floor`); None for the relative ``ftol`` alone.

    L-BFGS-B also stops when one iteration gains less than ``ftol`` relative to
    the value, which a poor curvature pair (after line-search trials where the
    evidence cannot be evaluated) can cause far from the optimum: the run is
    then started again from its end with a fresh curvature memory, up to
    ``LBFGS_RESTARTS`` times, when the gradient there still promises more than
    ``RESTART_GAIN`` nats (see :func:`_promises_more`).
    """
    result = _lbfgs_run(objective_and_gradient, theta0, bounds, transform, max_evaluations,
                        stop_gain)
    for _ in range(LBFGS_RESTARTS):
        left = None if max_evaluations is None else int(max_evaluations) - result.nfev
        if (left is not None and left <= 0) or not _promises_more(result):
            break
        again = _lbfgs_run(objective_and_gradient, result.x, bounds, transform, left,
                           stop_gain)
        again.nfev += result.nfev
        again.nit += result.nit
        if not again.fun < result.fun:
            result.nfev, result.nit = again.nfev, again.nit
            break
        result = again
    return result


def _promises_more(result) -> bool:
    """Whether an L-BFGS-B run stopped on a small relative reduction with gain in sight.

    The gain in sight is the quadratic model's ``g^T H g / 2`` (``H`` the run's
    inverse-Hessian approximation, ``g`` its last gradient in the optimizer's
    coordinates), or a gradient entry above ``RESTART_GRADIENT`` nats per unit
    of a log or ``artanh`` coordinate, where a broken curvature memory
    understates that model.  At converged ends of the camera logs of
    ``benchmarks/camera_log.py`` the model promised 1e-9 nats or less; where a
    20 s log with exposure stopped short (5,543.0 nats, against 5,956.7 from
    there) it promised 1.6e10, with gradient entries up to 1,738.
    """
    message = _message(result).upper()
    relative = "REL" in message and "REDUCTION" in message
    if not relative or not np.isfinite(result.fun):
        return False
    g = np.where(result.free, np.asarray(result.jac, dtype=float), 0.0)
    if g.size == 0 or not np.all(np.isfinite(g)):
        return False
    if np.max(np.abs(g)) > RESTART_GRADIENT:
        return True
    hess_inv = getattr(result, "hess_inv", None)
    if hess_inv is None:
        return False
    return 0.5 * float(g @ hess_inv.matvec(g)) > RESTART_GAIN


def _lbfgs_run(objective_and_gradient, theta0, bounds, transform=None,
               max_evaluations=None, stop_gain=STOP_GAIN):
    """One bounded L-BFGS-B run in ``transform`` coordinates; returns the result in theta.

    The run stops once an iteration gains less than about ``stop_gain``
    nats (:func:`_gain_floor`; None: the relative ``ftol`` alone).
    """
    options = dict(LBFGS_OPTIONS)
    if max_evaluations is not None:
        options["maxfun"] = int(max_evaluations)
    if transform is None:
        limits = np.asarray(bounds, dtype=float)
        # where L-BFGS-B makes its first call: the start clipped into the bounds
        start = np.clip(np.asarray(theta0, dtype=float), limits[:, 0], limits[:, 1])
        shift, objective = _gain_floor(objective_and_gradient, start, options, stop_gain)
        result = _minimize_until_expected(objective, start, limits, options, stop_gain)
        result.fun = float(result.fun) + shift
        result.free = _free_directions(result.x, result.jac, limits)
        return result

    def in_z(z):
        theta = transform.to_theta(z)
        value, grad = objective_and_gradient(theta)
        return value, transform.gradient(grad, theta)

    z_bounds = transform.bounds(bounds)
    z0 = np.clip(transform.to_z(theta0), z_bounds[:, 0], z_bounds[:, 1])
    shift, objective = _gain_floor(in_z, z0, options, stop_gain)
    result = _minimize_until_expected(objective, z0, z_bounds, options, stop_gain)
    result.fun = float(result.fun) + shift
    result.free = _free_directions(result.x, result.jac, z_bounds)
    theta = transform.to_theta(result.x)
    result.x = np.clip(theta, bounds[:, 0], bounds[:, 1])
    if transform.couplings and not np.allclose(result.x, theta, 0.0, 1e-9):
        # a coupled amplitude left its bounds: polish the clipped point in plain coordinates
        polished = _lbfgs_run(objective_and_gradient, result.x, bounds, transform.plain(),
                              max_evaluations, stop_gain)
        polished.nfev += result.nfev
        polished.nit += result.nit
        return polished
    return result


def _minimize_until_expected(objective, x0, bounds, options=None, stop_gain=STOP_GAIN):
    """L-BFGS-B from ``x0``, ended early by :class:`_ExpectedGainStop` (unless ``stop_gain``
    is None: a disturbance's tuning, whose iterations along the amplitudes' ridge gain
    little each).

    ``objective(x) -> (value, gradient)`` is minimized (the negative log evidence);
    ``options``: L-BFGS-B's (scipy's defaults when None).  Returns scipy's result; a run
    ended by the rule reports success and says so in its message.
    """
    options = {} if options is None else options
    if stop_gain is None:
        return optimize.minimize(objective, x0, jac=True, method="L-BFGS-B", bounds=bounds,
                                 options=options)
    stop = _ExpectedGainStop(objective, bounds)
    result = optimize.minimize(stop.objective, x0, jac=True, method="L-BFGS-B",
                               bounds=bounds, options=options, callback=stop)
    if stop.stopped:
        # scipy reports a callback's stop as a failure: the run converged by this rule
        result.success, result.status = True, 0
        result.message = (f"CONVERGENCE: EXPECTED GAIN UNDER {EXPECTED_GAIN:g} NATS "
                          f"(LAST ITERATION {stop.last_gain:.2g}, MODEL {stop.promised:.2g})")
        result.x, result.fun, result.jac = stop.x, stop.value, stop.gradient
    return result


class _ExpectedGainStop:
    """The callback that ends an L-BFGS-B run whose remaining gain is negligible.

    After each iteration: the gain of that iteration, and the gain the run's
    own quadratic model promises from its end, ``g^T H g / 2``, with ``H``
    the inverse-Hessian approximation of the curvature pairs ``(s, y)`` of
    the last ``MEMORY`` iterates (the two-loop recursion, scaled by the last
    pair's ``s^T y / y^T y``) and ``g`` the gradient with the entries pushed
    against a bound they sit on zeroed.  Both under ``EXPECTED_GAIN``: stop
    (``StopIteration``).  The model is trusted only once it holds as many
    pairs of positive curvature as there are coordinates (or ``MEMORY``):
    before, it knows the curvature along the steps taken only and extends
    the last one's scale to every other direction (a first short step along
    a steep direction promised nothing where a term of the resonance search
    had far to go, and a true mode was dropped).  ``objective`` is wrapped
    (:meth:`objective`) to keep the gradient at each iterate: the callback
    is given the point and the value only.
    """

    MEMORY = 10

    def __init__(self, objective_and_gradient, bounds):
        self._call = objective_and_gradient
        self._bounds = np.asarray(bounds, dtype=float)
        self._seen = {}  # the last evaluations, by point
        self._pairs = []
        self.x = self.value = self.gradient = None
        self.stopped = False
        self.last_gain = self.promised = np.inf

    def objective(self, x):
        value, grad = self._call(x)
        grad = np.asarray(grad, dtype=float)
        if len(self._seen) > 64:
            self._seen.clear()
        self._seen[np.asarray(x, dtype=float).tobytes()] = (float(value), grad.copy())
        return value, grad

    def __call__(self, intermediate_result):
        x = np.array(intermediate_result.x, dtype=float)
        seen = self._seen.get(x.tobytes())
        if seen is None:  # an iterate not evaluated as such: no gradient to read
            return
        value, gradient = seen
        if self.x is not None:
            s, y = x - self.x, gradient - self.gradient
            if float(s @ y) > 1e-12 * float(np.linalg.norm(s) * np.linalg.norm(y)):
                self._pairs = (self._pairs + [(s, y)])[-self.MEMORY:]
            self.last_gain = self.value - value
        self.x, self.value, self.gradient = x, value, gradient
        if self.last_gain >= EXPECTED_GAIN or len(self._pairs) < min(x.size, self.MEMORY):
            return
        g = np.where(_free_directions(x, gradient, self._bounds), gradient, 0.0)
        self.promised = 0.5 * float(g @ self._inverse_hessian_times(g))
        if self.promised < EXPECTED_GAIN:
            self.stopped = True
            raise StopIteration

    def _inverse_hessian_times(self, g):
        q = g.copy()
        alphas = []
        for s, y in reversed(self._pairs):
            rho = 1.0 / float(s @ y)
            alpha = rho * float(s @ q)
            q -= alpha * y
            alphas.append((rho, alpha, s, y))
        s, y = self._pairs[-1]
        q *= float(s @ y) / float(y @ y)
        for rho, alpha, s, y in reversed(alphas):
            q += (alpha - rho * float(y @ q)) * s
        return q


def _gain_floor(objective_and_gradient, x0, options, stop_gain=STOP_GAIN):
    """The objective shifted so that an iteration gaining under ``stop_gain`` nats stops.

    L-BFGS-B's ``ftol`` test is relative to the value: ``f_k - f_{k+1} <=
    ftol * max(|f_k|, |f_{k+1}|, 1)``.  The objective returned is
    ``f - f(x0) - stop_gain / ftol``: its gains are ``f``'s, its value
    about ``stop_gain / ftol``, so the test stops at a gain of about
    ``stop_gain`` nats, the same in any units of the data (the evidence
    moves by a constant with them).  ``f(x0)`` is evaluated here and given
    back on the optimizer's first call there (no evaluation is added).
    Returns ``(shift, objective)``: the optimizer's values plus ``shift``
    are ``f``'s (``0.0`` and ``objective_and_gradient`` itself where
    ``f(x0)`` is not finite, or ``stop_gain`` None: ``ftol`` alone).
    """
    if stop_gain is None:
        return 0.0, objective_and_gradient
    first = objective_and_gradient(x0)
    value = float(first[0])
    if not np.isfinite(value):
        return 0.0, objective_and_gradient
    shift = value + stop_gain / float(options["ftol"])
    pending = [(value - shift, first[1])]

    def objective(x):
        if pending and np.array_equal(x, x0):
            return pending.pop()
        pending.clear()
        value, grad = objective_and_gradient(x)
        return value - shift, grad

    return shift, objective


def _free_directions(z, gradient, z_bounds) -> np.ndarray:
    """The coordinates a descent step can move: not pushed against a bound they sit on."""
    z = np.asarray(z, dtype=float)
    g = np.asarray(gradient, dtype=float)
    span = np.where(np.isfinite(z_bounds[:, 1] - z_bounds[:, 0]),
                    z_bounds[:, 1] - z_bounds[:, 0], 1.0)
    tol = 1e-10 * np.maximum(span, 1.0)
    at_lower = (z - z_bounds[:, 0] <= tol) & (g > 0)
    at_upper = (z_bounds[:, 1] - z <= tol) & (g < 0)
    return ~(at_lower | at_upper)


def _message(result) -> str:
    """The optimizer's stop message as text (older scipy gives bytes)."""
    message = result.message
    return message.decode() if isinstance(message, bytes) else str(message)


def warn_if_not_converged(result) -> None:
    """Emit a ConvergenceWarning for an L-BFGS-B run that did not converge."""
    if not result.success:
        message = _message(result)
        warnings.warn(
            "the marginal-likelihood optimizer did not converge "
            f"({message}, {result.nit} iterations); the hyperparameters may not be "
            "optimal. Try n_restarts_optimizer > 0 or other initial values.",
            ConvergenceWarning,
            stacklevel=4,
        )


# A tuned entry of theta this close to a finite bound (in theta units, relative
# to the bound's size) is reported as ending on it.
BOUND_TOLERANCE = 1e-4


def hyperparameters_at_bounds(evidence, theta=None) -> list[tuple[str, float, str, float]]:
    """The tuned hyperparameters that ended on a finite bound.

    Parameters
    ----------
    evidence : LogEvidence
        The objective; its ``bounds`` are the user's (not a search window).
    theta : ndarray, optional
        The tuned point; ``evidence.theta`` by default.

    Returns
    -------
    list of (name, value, side, bound)
        ``side`` is ``"lower"`` or ``"upper"``; ``value`` and ``bound`` in
        the hyperparameter's own units (not ``theta``).
    """
    theta = evidence.theta if theta is None else np.asarray(theta, dtype=float)
    bounds = evidence.bounds
    kernel, noise = evidence.split(theta)
    params = kernel.get_params()
    roles = evidence.roles()
    names = [role.name for role in roles]
    coloured = getattr(evidence, "coloured", False)
    if coloured:
        _, noise_model = evidence.split_models(theta)
        noise_kernel = noise_model.kernel
        noise_params = noise_kernel.get_params()
        for h in noise_kernel.hyperparameters:
            if not h.fixed:
                names.extend([f"noise_kernel__{h.name}"] * h.n_elements)
    elif evidence.noise_is_free:
        names.append("noise_level")
    found = []
    for i, name in enumerate(names):
        for side, column in (("lower", 0), ("upper", 1)):
            edge = bounds[i, column]
            if not np.isfinite(edge):
                continue
            if abs(theta[i] - edge) <= BOUND_TOLERANCE * max(1.0, abs(edge)):
                if side == "lower" and name.startswith("noise_kernel__") and \
                        name.endswith("noise_level"):
                    continue  # the disturbance explains all the noise: no white part needed
                if side == "lower" and i < len(roles) and _part_absent(roles[i], params, edge):
                    continue  # a resonance's cosine or sine part not needed: its phase is set
                if name == "noise_level":
                    value, bound = noise, evidence.noise_bounds[column]
                elif name.startswith("noise_kernel__"):
                    leaf = name[len("noise_kernel__"):]
                    value = noise_params[leaf]
                    bound = _value_bounds(noise_kernel, leaf)[column]
                else:
                    value = params[name]
                    bound = _value_bounds(kernel, name)[column]
                found.append((name, float(np.ravel(value)[0]), side, float(bound)))
    return found


#: a PK amplitude on a lower bound this far below the term's other amplitude is a part
#: the data do not need (its variance a millionth of the term's or less), not a bound
#: that decided: the search's terms start with bounds 1e-4 times the scanned amplitude,
#: and a term whose phase the data fix takes one part there (the robot arm with
#: ``kernel="auto"``)
ABSENT_PART = 1e-3


def _part_absent(role, params, log_edge: float) -> bool:
    """Whether ``role``'s lower bound (``log_edge``, in ``theta``) is below
    ``ABSENT_PART`` times its partner's value (:attr:`Role.partner`), at the tuned point."""
    if role.partner is None:
        return False
    owner_name = role.name[: len(role.name) - len(role.leaf_name)]
    partner = params[owner_name + role.partner]
    return bool(np.exp(log_edge) <= ABSENT_PART * float(partner))


def _value_bounds(kernel, name: str):
    """The bounds, in value units, of the parameter ``name`` of ``kernel``."""
    owner_name, _, leaf = name.rpartition("__")
    owner = kernel.get_params()[owner_name] if owner_name else kernel
    return np.ravel(getattr(owner, f"hyperparameter_{leaf}").bounds)


def warn_at_bounds(evidence, theta=None) -> None:
    """Emit one ConvergenceWarning naming every hyperparameter that ended on a finite bound.

    As scikit-learn's Gaussian processes do: a value on its bound usually
    means the bound, not the data, decided it.  The noise level is included.
    """
    found = hyperparameters_at_bounds(evidence, theta)
    if not found:
        return
    listed = "; ".join(
        f"{name} = {value:.4g} is on its {side} bound {bound:.4g}"
        for name, value, side, bound in found
    )
    warnings.warn(
        f"tuning ended on a bound: {listed}. The bound, not the data, decided "
        "these values; widen the bounds (the kernel's <name>_bounds or "
        "noise_level_bounds) and fit again, or fix them if that is intended.",
        ConvergenceWarning,
        stacklevel=3,
    )


# Fisher scoring settings: stop when the predicted gain of a full step is below
# "tol" nats (the evidence's own units, so independent of the data's units), or
# when "stall" iterations in a row together gained less than "tol" (accepted
# steps along a direction the evidence does not feel, a near-zero amplitude's:
# on one disturbance fit 950 of 1,015 evaluations gained nothing)
FISHER_OPTIONS = {"maxiter": 500, "tol": 1e-6, "stall": 20}


def fisher_scoring(value_grad_fisher, theta0, bounds, transform):
    """Maximise the log evidence by bounded, damped Fisher scoring.

    The curvature model is the Fisher information ``F`` (the expected
    negative Hessian) plus a symmetric rank-one secant correction ``C``,
    updated after every step from the change of the gradient.  ``F`` alone
    converges only linearly when the prior does not contain the system (the
    observed curvature then differs from the expected one); the correction
    restores fast convergence and is dropped whenever ``F + C`` is not
    positive definite.

    Each iteration solves ``(B + lambda diag F) step = g`` with
    ``B = F + C`` on the free coordinates (Levenberg-Marquardt damping), in
    the optimizer coordinates of ``transform``, projects the step on the box
    and accepts it when the evidence does not decrease; otherwise ``lambda``
    grows tenfold.  Coordinates at a bound whose gradient points outward are
    held.  Converged when the predicted gain ``g^T B^{-1} g / 2`` is below
    ``FISHER_OPTIONS["tol"]`` nats, or when the last
    ``FISHER_OPTIONS["stall"]`` iterations together gained less than that.

    ``value_grad_fisher(theta)`` returns the log evidence with its gradient
    and Fisher information in ``theta`` (``-inf`` and None where the evidence
    cannot be evaluated).  Returns a :class:`scipy.optimize.OptimizeResult`
    with ``fun`` the *negative* log evidence, like the L-BFGS-B runs.
    """
    z_bounds = transform.bounds(bounds)
    low, high = z_bounds[:, 0], z_bounds[:, 1]
    z = np.clip(transform.to_z(theta0), low, high)

    def evaluate(z):
        theta = transform.to_theta(z)
        f, g, F = value_grad_fisher(theta)
        if not np.isfinite(f):
            return theta, -np.inf, None, None
        J = np.ones_like(z)
        J[transform.indices] = theta[transform.indices]  # d theta / d z
        return theta, f, g * J, F * np.outer(J, J)

    theta, f, gz, Fz = evaluate(z)
    if not np.isfinite(f):
        return optimize.OptimizeResult(
            x=theta, fun=np.inf, jac=None, nit=0, nfev=1, njev=1, success=False,
            message="the evidence cannot be evaluated at the initial point",
        )
    correction = np.zeros_like(Fz)
    nfev = 1
    damping = 1e-3
    success, message = False, "maximum number of iterations reached"
    iteration = 0
    recent = [f]  # the evidence at the start of the last iterations
    for iteration in range(1, FISHER_OPTIONS["maxiter"] + 1):
        if len(recent) > FISHER_OPTIONS["stall"]:
            if f - recent.pop(0) < FISHER_OPTIONS["tol"]:
                success, message = True, "the evidence stopped increasing"
                break
        held = ((z <= low) & (gz < 0)) | ((z >= high) & (gz > 0))
        free = ~held
        if not np.any(free):
            success, message = True, "every coordinate held at a bound"
            break
        gf, Ff = gz[free], Fz[np.ix_(free, free)]
        scale = _diagonal_scale(Ff)
        Bf = Ff + correction[np.ix_(free, free)]
        if not _positive_definite(Bf, scale):
            correction[:] = 0.0
            Bf = Ff
        gain = 0.5 * gf @ _damped_solve(Bf, scale, 0.0, gf)
        if not np.isfinite(gain) or gain < FISHER_OPTIONS["tol"]:
            success, message = True, "predicted gain below tolerance"
            break
        while damping <= 1e12:
            step = np.zeros_like(z)
            step[free] = _damped_solve(Bf, scale, damping, gf)
            z_new = np.clip(z + step, low, high)
            trial = evaluate(z_new)
            nfev += 1
            if trial[1] >= f:
                break
            damping *= 10.0
        if damping > 1e12:
            success = gain < 1e3 * FISHER_OPTIONS["tol"]
            message = "no step increases the evidence"
            break
        step = z_new - z
        theta, f, gz_new, Fz = trial
        # secant condition (F + C) step = g_old - g_new, by a symmetric rank-one update
        residual = (gz - gz_new) - (Fz + correction) @ step
        denominator = residual @ step
        if abs(denominator) > 1e-8 * np.linalg.norm(residual) * np.linalg.norm(step):
            correction += np.outer(residual, residual) / denominator
        z, gz = z_new, gz_new
        damping = max(damping / 10.0, 1e-9)
        recent.append(f)
    return optimize.OptimizeResult(
        x=np.clip(theta, bounds[:, 0], bounds[:, 1]), fun=-f, jac=-gz, nit=iteration,
        nfev=nfev, njev=nfev, success=success, message=message,
    )


def _diagonal_scale(F):
    """Positive scaling of the coordinates: the diagonal of ``F``, floored.

    Coordinates the data carry (almost) no information on get the floor
    ``1e-12`` of the largest diagonal entry (``1`` when all vanish), so that
    scaling never overflows.
    """
    diagonal = np.diag(F)
    largest = float(diagonal.max()) if diagonal.size else 0.0
    floor = 1e-12 * largest if np.isfinite(largest) and largest > 0.0 else 1.0
    return np.maximum(diagonal, floor)


def _positive_definite(B, scale) -> bool:
    root = np.sqrt(scale)
    values = linalg.eigvalsh(B / np.outer(root, root), check_finite=False)
    return bool(values.min() > 1e-10 * max(values.max(), 1e-300))


def _damped_solve(F, scale, damping, g):
    """Solve ``(F + damping diag(scale)) x = g`` for a positive semi-definite ``F``.

    In coordinates scaled by ``sqrt(scale)`` the matrix is decomposed; its
    eigenvalues are floored at ``1e-10`` of the largest in magnitude (``1``
    when all vanish), so directions the data carry no information on get a
    bounded step instead of a warning, also when rounding in a nearly
    singular data covariance leaves ``F`` with no positive eigenvalue.
    """
    root = np.sqrt(scale)
    values, vectors = linalg.eigh(F / np.outer(root, root), check_finite=False)
    top = float(np.abs(values).max()) if values.size else 0.0
    floor = 1e-10 * top if np.isfinite(top) and top > 0.0 else 1.0
    values = np.maximum(values, floor) + damping
    return (vectors @ ((vectors.T @ (g / root)) / values)) / root
