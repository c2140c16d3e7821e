"""The design criterion: the band radius over a frequency range, as a function of the input.

With ``e_f`` the row of the DFT matrix at ``f`` and ``Sigma`` the predicted
posterior covariance (:mod:`gpmultirate.design.predicted`), the band radius
is ``r_f = w_f sqrt(chi2_2(level) v_f / 2)`` with ``v_f = e_f^H Sigma e_f``
(:mod:`gpmultirate.design.bands`), weighted by ``w_f`` (1, or ``1 / |G|`` of
a pilot model for a relative band).  The criterion is

* ``"mean"``: ``J = mean_f r_f``;
* ``"worst"``: ``J = (mean_f r_f^p)^(1/p)`` with ``p = WORST_CASE_POWER``, a
  smooth stand-in for ``max_f r_f`` (``value.worst`` reports the max itself).

Its gradient with respect to the input follows from
``d Sigma = -(Sigma dPhi^T Phi Sigma + Sigma Phi^T dPhi Sigma) / gamma``
(white noise, for any prior, singular ones included, since
``Sigma Phi^T / gamma = K Phi^T (Phi K Phi^T + gamma I)^{-1}``):

    dJ / dPhi = -(2 / gamma) Phi Sigma W Sigma,   W = Re(sum_f (dJ/dv_f) e_f e_f^H),

and ``Phi[m, i] = u[n_m - i]`` (eq. 8) carries it to ``u``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gpmultirate.design.bands import chi2_2
from gpmultirate.design.predicted import posterior_of
from gpmultirate.observations import DownsampledConvolution, SampledConvolution
from gpmultirate.responses import dft_matrix
from gpmultirate.validation import check_level

__all__ = ["CRITERIA", "WORST_CASE_POWER", "BandCriterion", "CriterionValue"]

#: the criteria a design minimizes
CRITERIA = ("mean", "worst")
#: the power of the smooth maximum of the ``"worst"`` criterion
WORST_CASE_POWER = 16


def check_criterion(criterion) -> str:
    if not (isinstance(criterion, str) and criterion in CRITERIA):
        raise ValueError(f"criterion must be one of {CRITERIA}; got {criterion!r}")
    return criterion


@dataclass(frozen=True)
class CriterionValue:
    """The criterion of one input: its value and the band radii it summarizes."""

    value: float
    radius: np.ndarray
    mean: float
    worst: float


class BandCriterion:
    """The mean or worst-case band radius over ``freqs`` of an experiment.

    Parameters
    ----------
    prior : DesignPrior
    freqs : ndarray of shape (n,)
        Frequencies in Hz (or cycles per sample) where the band counts.
    criterion : {"mean", "worst"}
    weights : ndarray of shape (n,), optional
        ``w_f``; default 1.
    level : float, default=0.95

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate.kernels import DC
    >>> from gpmultirate.design import SamplingScheme, design_prior
    >>> prior = design_prior(C(1.0) * DC(0.8, 0.5), order=20)
    >>> crit = BandCriterion(prior, np.linspace(0.0, 0.5, 11))
    >>> u = np.random.default_rng(0).standard_normal(60)
    >>> value, gradient = crit.value_and_gradient(u, SamplingScheme(factor=3))
    >>> gradient.shape
    (60,)
    """

    def __init__(self, prior, freqs, criterion: str = "mean", weights=None,
                 level: float = 0.95):
        self.prior = prior
        self.freqs = np.asarray(freqs, dtype=float)
        self.criterion = check_criterion(criterion)
        self.level = check_level(level)
        self.weights = (np.ones(self.freqs.shape[0]) if weights is None
                        else np.asarray(weights, dtype=float))
        E = dft_matrix(self.freqs, prior.sample_time, prior.order)
        self._re, self._im = np.ascontiguousarray(E.real), np.ascontiguousarray(E.imag)
        self._parts = np.vstack([self._re, self._im])
        self._scale = np.sqrt(chi2_2(self.level) / 2.0) * self.weights

    def _observation(self, u, scheme):
        prior = self.prior
        return scheme.observation(u, prior.order, latency=prior.latency,
                                  initial_conditions=prior.initial_conditions)

    def _summary(self, variances):
        radius = self._scale * np.sqrt(np.maximum(variances, 0.0))
        mean, worst = float(radius.mean()), float(radius.max())
        if self.criterion == "mean":
            value, d_radius = mean, np.full(radius.shape[0], 1.0 / radius.shape[0])
        else:
            p = WORST_CASE_POWER
            top = max(worst, np.finfo(float).tiny)
            ratio = radius / top  # scaled against overflow
            moment = float(np.mean(ratio ** p))
            value = top * moment ** (1.0 / p)
            d_radius = moment ** (1.0 / p - 1.0) * ratio ** (p - 1) / radius.shape[0]
        return CriterionValue(value, radius, mean, worst), d_radius

    def value(self, u, scheme) -> CriterionValue:
        """The criterion of input ``u`` read through ``scheme`` (any scheme, any noise)."""
        post = posterior_of(self.prior, self._observation(u, scheme))
        var_re, var_im, _ = post.pair_variances(self._re, self._im)
        return self._summary(var_re + var_im)[0]

    def value_and_gradient(self, u, scheme):
        """The criterion and its gradient with respect to ``u``.

        For white noise and readings on the fast ticks (no exposure), with
        zero or periodic initial conditions.
        """
        prior = self.prior
        if not (isinstance(prior.noise_kernel, str) and prior.noise_kernel == "white"):
            raise ValueError("the criterion's gradient needs white noise: the prior's noise "
                             f"kernel is {prior.noise_kernel!r}")
        if prior.initial_conditions not in ("zero", "periodic"):
            raise ValueError("the criterion's gradient needs initial_conditions 'zero' or "
                             f"'periodic'; got {prior.initial_conditions!r}")
        u = np.asarray(u, dtype=float)
        observation = self._observation(u, scheme)
        if not isinstance(observation, (DownsampledConvolution, SampledConvolution)):
            raise ValueError("the criterion's gradient needs readings on the fast ticks "
                             "without exposure")
        post = posterior_of(prior, observation)
        n = self.freqs.shape[0]
        # Sigma [Re E; Im E]^T in one product: (P, 2n)
        sigma_e = post.covariance() @ self._parts.T
        variances = np.einsum("fi,if->f", self._parts, sigma_e)
        variances = variances[:n] + variances[n:]
        result, d_radius = self._summary(variances)
        # dJ/dv_f = dJ/dr_f * r_f / (2 v_f), the same for the real and the imaginary part
        d_var = np.divide(d_radius * result.radius, 2.0 * variances,
                          out=np.zeros_like(variances), where=variances > 0)
        phi = observation.matrix
        d_phi = -(2.0 / prior.noise_level) * (
            ((phi @ sigma_e) * np.concatenate([d_var, d_var])) @ sigma_e.T)
        return result, _regressor_adjoint(d_phi, observation.sample_indices, u.shape[0],
                                          prior.initial_conditions == "periodic")


def _regressor_adjoint(d_phi, sample_indices, n_samples: int, periodic: bool) -> np.ndarray:
    """``d/du`` of ``sum(d_phi * Phi(u))`` for ``Phi[m, i] = u[n_m - i]`` (eq. 8)."""
    order = d_phi.shape[1]
    index = np.asarray(sample_indices)[:, None] - np.arange(order)[None, :]
    if periodic:
        return np.bincount((index % n_samples).ravel(), weights=d_phi.ravel(),
                           minlength=n_samples)
    inside = index >= 0
    return np.bincount(index[inside], weights=d_phi[inside], minlength=n_samples)
