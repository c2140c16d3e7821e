"""White measurement noise ``N = gamma I``: what the long-record reduction and DC's precision need."""

from __future__ import annotations

import numpy as np

from gpmultirate.covariance import (
    DenseCovariance,
    ParameterSpaceCovariance,
    PrecisionCovariance,
    Remainder,
)
from gpmultirate.exceptions import NotPositiveDefinite
from gpmultirate.noise.base import NoiseModel

__all__ = ["WhiteNoise"]


class WhiteNoise(NoiseModel):
    """White measurement noise ``N = gamma I`` over the slow samples.

    Its hyperparameters enter ``theta`` through it: :attr:`theta` is
    ``[log(gamma)]`` when the level is tuned (``bounds`` not ``"fixed"``)
    and empty otherwise, after the kernel's entries.  White noise is what
    the long-record reduction summarizes (:meth:`remainder`) and what the
    precision route relies on: its routes (:meth:`data_covariance`) are

    * square or reduced data (``M = P``) and a kernel term with a
      tridiagonal precision (DC):
      :class:`~gpmultirate.covariance.PrecisionCovariance`;
    * the posterior of a reduced long record otherwise:
      :class:`~gpmultirate.covariance.ParameterSpaceCovariance`;
    * else the dense route.

    Parameters
    ----------
    noise_level : float
        ``gamma > 0``.
    bounds : pair of floats or "fixed", default="fixed"

    Examples
    --------
    >>> import numpy as np
    >>> noise = WhiteNoise(0.1, (1e-3, 1.0))
    >>> noise.theta, noise.with_theta(np.log([0.2])).level
    (array([-2.30258509]), 0.2)
    >>> noise.add_to(np.zeros((2, 2)))
    array([[0.1, 0. ],
           [0. , 0.1]])
    """

    white = True

    def __init__(self, noise_level: float, bounds="fixed"):
        self._level = float(noise_level)
        self.noise_bounds = bounds
        self._free = not isinstance(bounds, str)

    @property
    def level(self) -> float:
        """``gamma``."""
        return self._level

    @property
    def is_free(self) -> bool:
        """Whether ``gamma`` is tuned."""
        return self._free

    @property
    def theta(self) -> np.ndarray:
        """``[log(gamma)]`` when tuned, else empty."""
        return np.array([np.log(self.level)]) if self.is_free else np.empty(0)

    @property
    def bounds(self) -> np.ndarray:
        """Bounds of :attr:`theta`, of shape ``(len(theta), 2)``."""
        if not self.is_free:
            return np.empty((0, 2))
        return np.log(np.asarray(self.noise_bounds, dtype=float)).reshape(1, 2)

    def with_theta(self, theta) -> "WhiteNoise":
        if not self.is_free:
            return self
        return WhiteNoise(float(np.exp(theta[0])), self.noise_bounds)

    def add_to(self, S: np.ndarray) -> np.ndarray:
        S[np.diag_indices_from(S)] += self.level
        return S

    def contract(self, W: np.ndarray, weight: float = 1.0) -> np.ndarray:
        """``[weight tr(W dN / d theta_j)]_j`` for symmetric ``W``: ``weight tr(W) gamma``."""
        if not self.is_free:
            return np.empty(0)
        return np.array([weight * np.trace(W) * self.level])

    def remainder(self, observation) -> Remainder:
        """The likelihood of what a reduction of ``observation`` summarized (none otherwise)."""
        return Remainder(observation.n_discarded, observation.residual, self.level)

    # ------------------------------------------------------------ routes
    def _by_precision(self, term):
        """The precision route of ``term``, or None when the term or the factor declines."""
        precision = term.precision()
        if precision is None:
            return None
        try:
            return PrecisionCovariance(term, self, self.remainder(term.observation), precision)
        except NotPositiveDefinite:
            return None

    def data_covariance(self, term, gradient: bool = False):
        observation = term.observation
        if observation.n_outputs == observation.n_coefficients:
            route = self._by_precision(term)
            if route is not None:
                return route
        return DenseCovariance.of_term(term, self, self.remainder(observation), gradient)

    def offers_fisher(self, observation) -> bool:
        return True

    def fisher_terms(self, inverse: np.ndarray) -> list:
        """``dN = gamma I``: ``V = gamma Ky^{-1}``, symmetric (its own transpose); the
        derivative itself is left out (None), its quadratic form is ``gamma a^T a``."""
        if not self.is_free:
            return []
        scaled = self.level * inverse
        return [("dense", None, scaled, scaled)]

    def posterior_covariance(self, term):
        observation = term.observation
        if observation.n_discarded == 0:
            return DenseCovariance(term, self, self.remainder(observation))
        route = self._by_precision(term)
        if route is not None:
            return route
        return ParameterSpaceCovariance(term, self, self.remainder(observation))

    def offers_precision(self, term) -> bool:
        observation = term.observation
        return observation.n_outputs == observation.n_coefficients and term.precision() is not None
