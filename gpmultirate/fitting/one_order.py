"""A fit at one order: prior, resonance search, tuning, posterior, disturbance.

:func:`fit_at_order` is the fit of :class:`~gpmultirate.FIRGaussianProcess`
at one FIR order, on the data in the units of
:func:`~gpmultirate.units.normalize`.  It returns the learned state as a
:class:`Fit` and leaves the estimator alone; the order steps
(:mod:`gpmultirate.fitting.order`) call it at the orders they try, and the
estimator adopts the fit they keep.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gpmultirate import tuning, units
from gpmultirate.covariance import SpreadPosterior
from gpmultirate.crossvalidation import CrossValidation
from gpmultirate.fitting import auto_kernel
from gpmultirate.fitting.between_ticks import experiment_of
from gpmultirate.fitting.disturbance import choose_disturbance
from gpmultirate.fitting.prior import starting_prior
from gpmultirate.fitting.spread import spread_of_fit
from gpmultirate.inference import LogEvidence, blas_threads_for
from gpmultirate.kernels.spread import conditioning_kernel
from gpmultirate.memory import check_fit_memory

__all__ = ["Fit", "fit_at_order"]


@dataclass
class Fit:
    """The learned state of a fit at one order (the estimator's attributes of that name)."""

    experiment: object
    observation_: object
    y_slow_: np.ndarray
    noise_level_bounds_: object
    n_inputs_: int
    optimizer_result_: object
    kernel_: object
    noise_level_: float
    posterior_: object
    evidence: object
    coef_: np.ndarray
    log_marginal_likelihood_value_: float
    resonances_: object = None
    cv_log_predictive_likelihood_: float | None = None
    noise_kernel_: object = "white"
    noise_model: object = None
    spread_kernel: object = None

    def attributes(self) -> dict:
        """The estimator's attributes of this fit (``_noise_model`` and ``_evidence`` private:
        the evidence is kept for ``log_marginal_likelihood(theta)`` and the posterior at
        real lags)."""
        names = ("observation_", "y_slow_", "noise_level_bounds_", "n_inputs_",
                 "optimizer_result_", "kernel_", "noise_level_", "posterior_", "coef_",
                 "log_marginal_likelihood_value_", "noise_kernel_", "resonances_",
                 "cv_log_predictive_likelihood_")
        out = {name: getattr(self, name) for name in names}
        out["_noise_model"], out["_evidence"] = self.noise_model, self.evidence
        if self.spread_kernel is not None:  # the kernel with its terms' spread
            out["kernel_"] = self.spread_kernel
        return out


def fit_at_order(data, order, settings, start=None) -> Fit:
    """Fit at one order; returns the learned state.

    ``data``: ``(u, y_slow, sample_indices)``, normalized
    (:func:`~gpmultirate.fitting.between_ticks.readings_of` gives the last);
    ``order``: the FIR order (None: the longest record's length);
    ``settings``: the fit's :class:`~gpmultirate.fitting.settings.Settings`;
    ``start``: the ``(kernel, noise level)`` of a plain fit at that order
    (the default order's pilot), where the tuning or ``kernel="auto"``'s
    search starts.

    The steps: the experiment and the starting prior, the memory guard, the
    resonance search (``kernel="auto"``: under the disturbance the data call
    for, where they call for one before any term is found,
    :func:`~gpmultirate.fitting.auto_kernel.search_under_disturbance`), the
    tuning by the criterion, the posterior, the disturbance choice
    (``noise_kernel``, made with the search when it ran under one) and, when a
    disturbance is kept after a search, the search's terms judged again;
    last, the spread of the terms' frequencies added to the posterior
    (:mod:`gpmultirate.fitting.spread`).  Every step before conditions on
    the kernel without that spread: ``kernel_`` is the kernel with it, the
    evidence and the order steps hold the kernel without it.
    """
    experiment = experiment_of(data, order, settings)
    observation, y = experiment.observation, experiment.y
    kernel, noise, noise_bounds = starting_prior(experiment, settings, start)
    template = kernel  # the kernel with its terms' posterior spread, if it has any
    kernel = conditioning_kernel(kernel)
    # refuse now what would be killed for lack of memory halfway
    n_free = sum(h.n_elements for h in kernel.hyperparameters if not h.fixed)
    check_fit_memory(observation.n_outputs, observation.n_coefficients, n_free + 1,
                     n_inputs=experiment.n_inputs)
    optimizer_result = found = cv_value = noise_model = searched_kernel = decided = under = None

    def experiment_at(longer):  # the experiment at another order, for the disturbance check
        return experiment_of(data, longer, settings)

    with blas_threads_for(observation):
        if settings.auto:
            under = auto_kernel.search_under_disturbance(experiment, kernel, noise,
                                                         noise_bounds, settings, experiment_at)
            if under is not None and under.decided is not None:
                # the search ran under the disturbance the data call for
                searched, decided = under.searched, under.decided
                optimizer_result = under.start[2]
                noise = decided.noise_model.level or under.start[1]
                evidence = decided.evidence
            else:
                start, tuned = (under.start, True) if under is not None else (
                    (kernel, noise, None), False)
                searched = auto_kernel.search(observation, y, start[0], start[1],
                                              noise_bounds, settings, tuned=tuned)
                template, noise = searched.kernel, searched.noise_level
                kernel = searched_kernel = conditioning_kernel(template)
                optimizer_result = (start[2] if searched.optimizer_result is None
                                    else searched.optimizer_result)
                evidence = searched.evidence  # the search's reduction of the data, if any
                if evidence is None:
                    evidence = LogEvidence(observation, y, kernel, noise, noise_bounds)
            found = searched.resonances
        else:
            evidence = LogEvidence(observation, y, kernel, noise, noise_bounds)
        objective = evidence
        if settings.criterion == "cross_validation":
            check_fit_memory(y.shape[0], y.shape[0], kernel.theta.shape[0] + 1)
            objective = CrossValidation(
                observation, y, kernel, noise, noise_bounds, settings.n_folds
            )
        if settings.tuned and (not settings.auto or objective is not evidence):
            # with "auto", the search tuned by the evidence: cross-validation goes on from there
            result = tuning.maximize(objective, settings.n_restarts, settings.random_state)
            if result is not None:
                optimizer_result = result
                kernel, noise = evidence.split(result.x)
        if decided is not None:  # chosen with the search, under its disturbance
            template, kernel, disturbance = searched.kernel, decided.kernel, decided
        elif under is not None and under.white and not found:
            # no term on the prior the disturbance check kept white noise for: it stays
            posterior, disturbance = evidence.posterior(kernel, noise), None
        else:
            posterior = evidence.posterior(kernel, noise)
            if objective is not evidence:
                moved = objective.moved_to(kernel, noise)
                cv_value = float(moved(moved.theta))
            # the criterion of the tuning judges: the evidence, or the cross-validated
            # log predictive likelihood (cv_value, the white fit's, is then set)
            disturbance = choose_disturbance(
                experiment, kernel, noise, noise_bounds,
                posterior.log_marginal_likelihood if cv_value is None else cv_value, settings,
                cross_validated=cv_value is not None, experiment_at=experiment_at)
        if disturbance is not None and disturbance.noise_model is None:
            # white noise after all, tuned again from the disturbance's better prior
            if disturbance.optimizer_result is not None:
                optimizer_result = disturbance.optimizer_result
            evidence, kernel, noise = (disturbance.evidence, disturbance.kernel,
                                       disturbance.noise_level)
            posterior = disturbance.posterior
            if cv_value is not None:
                cv_value = disturbance.score
        elif disturbance is not None:
            steps = [disturbance]
            # a disturbance without white noise (AR(1)) keeps the white fit's level
            noise = disturbance.noise_model.level or noise
            if found:  # the search judged its terms with white noise: again, with the disturbance
                found, refitted = auto_kernel.rejudge(observation, y, disturbance, found, noise,
                                                      noise_bounds, settings)
                if refitted is not None:
                    steps.append(refitted)
                    noise = refitted.noise_model.level or noise
            for step in steps:
                if step.optimizer_result is not None:
                    optimizer_result = step.optimizer_result
            evidence, kernel, noise_model = (steps[-1].evidence, steps[-1].kernel,
                                             steps[-1].noise_model)
            posterior = steps[-1].posterior
            if cv_value is not None:
                cv_value = steps[-1].score
    moved_evidence = evidence.moved_to(kernel, noise if noise_model is None else noise_model)
    if optimizer_result is not None:
        tuning.warn_at_bounds(units.evidence_in_data_units(moved_evidence, settings.scale))
    # the search's spread holds where its kernel and white noise are the fit's
    spread_kernel = spread_of_fit(
        None if template is kernel else template, kernel, moved_evidence,
        tuned_again=settings.auto and not (noise_model is None and kernel is searched_kernel))
    if spread_kernel is not kernel:
        posterior = SpreadPosterior(posterior, spread_kernel)
    coef = posterior.coef
    return Fit(
        experiment=experiment,
        observation_=observation,
        y_slow_=y,
        noise_level_bounds_=noise_bounds,
        n_inputs_=experiment.n_inputs,
        optimizer_result_=optimizer_result,
        kernel_=kernel,
        noise_level_=noise,
        posterior_=posterior,
        evidence=moved_evidence,
        coef_=coef.reshape(experiment.n_inputs, -1) if experiment.n_inputs > 1 else coef,
        log_marginal_likelihood_value_=posterior.log_marginal_likelihood,
        resonances_=found,
        cv_log_predictive_likelihood_=cv_value,
        noise_kernel_="white" if noise_model is None else noise_model.kernel,
        noise_model=noise_model,
        spread_kernel=None if spread_kernel is kernel else spread_kernel,
    )
