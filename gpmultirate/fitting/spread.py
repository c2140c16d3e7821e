"""The spread of tuned frequencies, added to a fit's posterior after conditioning.

A fit conditions on the data with its kernel's posterior-spread PK terms
(``PK(posterior_spread=True)``: the terms of ``kernel="auto"``) without their
spread (:func:`~gpmultirate.kernels.spread.conditioning_kernel`), and adds
the spread to the posterior afterwards
(:class:`~gpmultirate.covariance.SpreadPosterior`).  :func:`spread_of_fit`
gives the kernel with the spread at the fit's values: the spread the kernel
came with (a model file's, or the resonance search's where the fit ended
with the search's own kernel and white noise), or, where the terms were
tuned again under the fit's final noise model (a disturbance), the Laplace
approximation of that evidence (:func:`laplace_spreads`).
"""

from __future__ import annotations

import numpy as np
from gpmultirate.kernels.spread import posterior_spread_terms, with_spreads

__all__ = ["gradient_hessian", "laplace_spreads", "marginal_variances", "spread_of_fit"]


def laplace_spreads(evidence, kernel=None, step: float = 1e-4):
    """``kernel`` with each posterior-spread PK term given the spread of the evidence's Laplace approximation.

    The Hessian of ``evidence`` (a :class:`~gpmultirate.inference.LogEvidence`
    under its noise model) over every free coordinate of its ``theta``, by
    central differences of the analytic gradient; ``-H^{-1}`` is the
    posterior covariance of the coordinates.  A term's ``omega_std`` is
    ``omega`` times the standard deviation of ``log(omega)``, its ``rate_std``
    half that of ``log(alpha)`` (the decay rate is ``-log(alpha) / 2``).
    The coordinates inside their bounds are taken jointly
    (:func:`marginal_variances`); one on a bound gets the standard deviation
    with the others held (``1 / sqrt(-H_ii)``), none where that curvature is
    not negative.

    Parameters
    ----------
    evidence : LogEvidence
    kernel : sklearn Kernel, optional
        The kernel at which to take the Hessian (default: ``evidence.kernel``).
    step : float, default=1e-4
        The relative step of the central differences.

    Returns
    -------
    sklearn Kernel
        ``kernel`` with ``omega_std`` and ``rate_std`` set on its
        posterior-spread PK summands.
    """
    kernel = evidence.kernel if kernel is None else kernel
    terms = posterior_spread_terms(kernel)
    if not terms:
        return kernel
    moved = evidence.moved_to(kernel, evidence.noise)
    x = moved.theta
    bounds = moved.bounds
    names = [h.name for h in kernel.hyperparameters if not h.fixed
             for _ in range(h.n_elements)]
    interior = (x > bounds[:, 0] + step) & (x < bounds[:, 1] - step)
    free = np.flatnonzero(bounds[:, 1] > bounds[:, 0])
    hessian = gradient_hessian(lambda z: moved(z, eval_gradient=True)[1], x, free, step)
    curvature = -np.diag(hessian)
    # a coordinate on its bound with the others held; the interior ones jointly
    variances = np.where(curvature > 0, 1.0 / np.where(curvature > 0, curvature, 1.0), 0.0)
    inside = np.flatnonzero(interior[free])
    variances[inside] = marginal_variances(hessian[np.ix_(inside, inside)])
    variance = dict(zip(free.tolist(), variances))

    def std(path, name):
        label = f"{path}__{name}"
        if label not in names:  # fixed: no spread from it
            return 0.0
        return float(np.sqrt(max(variance.get(names.index(label), 0.0), 0.0)))

    spreads = {id(term): (float(term.omega) * std(path, "omega"), 0.5 * std(path, "alpha"))
               for _, path, term in terms}
    return with_spreads(kernel, spreads)


def gradient_hessian(gradient, x: np.ndarray, free: np.ndarray, step: float = 1e-4):
    """The Hessian over the coordinates ``free`` of ``x`` by central differences of ``gradient``.

    ``gradient(z)`` is the analytic gradient at ``z`` (all coordinates);
    each coordinate is stepped by ``step * max(1, |x_i|)``; the result is
    symmetrized.

    Examples
    --------
    >>> import numpy as np
    >>> A = np.array([[2.0, 1.0], [1.0, 3.0]])
    >>> gradient_hessian(lambda z: -A @ z, np.zeros(2), np.arange(2)).round(9).tolist()
    [[-2.0, -1.0], [-1.0, -3.0]]
    """
    hessian = np.empty((free.size, free.size))
    for a, i in enumerate(free):
        h = step * max(1.0, abs(x[i]))
        up, down = x.copy(), x.copy()
        up[i] += h
        down[i] -= h
        hessian[a] = (gradient(up)[free] - gradient(down)[free]) / (2.0 * h)
    return 0.5 * (hessian + hessian.T)


def marginal_variances(hessian: np.ndarray) -> np.ndarray:
    """The variances of the Laplace approximation, ``diag((-H)^+)`` over its curved directions.

    ``-H`` is eigendecomposed; the directions of positive curvature give the
    covariance ``sum_k q_k q_k^T / w_k`` (``diag((-H)^{-1})`` where ``-H`` is
    positive definite).  A direction that is flat or bends up (an amplitude
    near zero whose evidence keeps rising slowly towards its bound) has no
    curvature to measure and is left out, so the coordinates it does not
    touch keep their joint variances.  Holding every other coordinate
    instead (``1 / (-H_ii)``) ignored the correlations of a frequency with
    its decay and amplitudes: on a two-input system with a flat amplitude
    that gave the frequency 0.6 of its joint standard deviation.

    Examples
    --------
    >>> import numpy as np
    >>> H = -np.array([[2.0, 1.0], [1.0, 2.0]])
    >>> bool(np.allclose(marginal_variances(H), np.diag(np.linalg.inv(-H))))
    True
    >>> marginal_variances(np.diag([-4.0, 1e-3])).round(6).tolist()
    [0.25, 0.0]
    """
    w, Q = np.linalg.eigh(-0.5 * (hessian + hessian.T))
    if w.size == 0 or w.max() <= 0.0:
        return np.zeros(w.size)
    keep = w > 1e-12 * w.max()
    return np.einsum("ik,k->i", Q[:, keep] ** 2, 1.0 / w[keep])


def spread_of_fit(template, kernel, evidence, tuned_again: bool):
    """The fit's kernel with its terms' spread: what the posterior adds after conditioning.

    Parameters
    ----------
    template : sklearn Kernel or None
        The kernel with the spread the fit started from (the user's, a
        model file's, or the resonance search's), or None (no
        posterior-spread term: ``kernel`` is returned).
    kernel : sklearn Kernel
        The fit's conditioning kernel at its final values.
    evidence : LogEvidence
        The fit's evidence at its final noise model.
    tuned_again : bool
        Whether the terms were tuned after ``template``'s spread was taken
        (under a disturbance, or with their set changed): the spread is then
        the Laplace approximation of ``evidence``.

    Returns
    -------
    sklearn Kernel
    """
    if template is None or not posterior_spread_terms(kernel):
        return kernel
    if tuned_again or template.theta.shape != kernel.theta.shape:
        return laplace_spreads(evidence, kernel)
    return template.clone_with_theta(kernel.theta)
