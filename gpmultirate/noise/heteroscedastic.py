"""White noise whose variance differs from sample to sample by known weights: ``N = gamma diag(w)``.

The example of a new noise model (``docs/adding_a_noise_model.rst``): one
subclass of :class:`~gpmultirate.noise.NoiseModel` that states ``N`` and
the derivative of ``N`` in its ``theta``, and gets the dense route of the
data covariance, its gradient and its posterior from the layer.
"""

from __future__ import annotations

import numpy as np

from gpmultirate.noise.base import NoiseModel

__all__ = ["HeteroscedasticNoise"]


class HeteroscedasticNoise(NoiseModel):
    """Independent noise of known relative variances: ``N = gamma diag(weights)``.

    Samples measured with different instruments, gains or averaging
    windows (a slow record of a noisier sensor, readings averaged over
    fewer frames) are independent with variances in known ratios;
    ``gamma`` scales them all and is tuned when ``bounds`` are given.

    Parameters
    ----------
    weights : array-like of shape (M,)
        The relative variance of each slow sample (positive, finite), in
        the order of the data.
    noise_level : float
        ``gamma > 0``: the variance of a sample of weight 1.
    bounds : pair of floats or "fixed", default="fixed"
        The bounds of ``gamma`` when it is tuned.

    Attributes
    ----------
    weights : ndarray of shape (M,)
        A copy of the weights.

    Examples
    --------
    >>> import numpy as np
    >>> noise = HeteroscedasticNoise([1.0, 4.0], 0.1, (1e-3, 1.0))
    >>> noise.add_to(np.zeros((2, 2)))
    array([[0.1, 0. ],
           [0. , 0.4]])
    >>> noise.theta.round(4).tolist(), noise.with_theta(np.log([0.2])).level
    ([-2.3026], 0.2)
    """

    def __init__(self, weights, noise_level: float, bounds="fixed"):
        weights = np.array(weights, dtype=float)  # a copy: the caller's array is kept
        if weights.ndim != 1 or weights.size == 0 or not np.all(np.isfinite(weights)) \
                or np.any(weights <= 0.0):
            raise ValueError("weights must be a non-empty 1-D array of positive finite "
                             "relative variances, one per slow sample")
        gamma = float(noise_level)
        if not (np.isfinite(gamma) and gamma > 0.0):
            raise ValueError(f"noise_level must be finite and positive; got {noise_level!r}")
        self.weights = weights
        self.noise_level = gamma
        self.noise_bounds = bounds

    @classmethod
    def per_record(cls, observation, weights, noise_level: float,
                   bounds="fixed") -> "HeteroscedasticNoise":
        """One relative variance per record of ``observation`` (each record's own sensor).

        Examples
        --------
        >>> import numpy as np
        >>> from gpmultirate import DownsampledConvolution
        >>> from gpmultirate.observations import RecordStack
        >>> stack = RecordStack([DownsampledConvolution(np.ones(6), 3, 2),
        ...                      DownsampledConvolution(np.ones(3), 3, 2)])
        >>> HeteroscedasticNoise.per_record(stack, [1.0, 4.0], 0.1).weights.tolist()
        [1.0, 1.0, 4.0]
        """
        sizes = [record.n_outputs for record in observation.records]
        weights = np.asarray(weights, dtype=float)
        if weights.shape != (len(sizes),):
            raise ValueError(f"weights must give one weight per record ({len(sizes)}); "
                             f"got shape {weights.shape}")
        return cls(np.repeat(weights, sizes), noise_level, bounds)

    @property
    def level(self) -> float:
        """``gamma``, the variance of a sample of weight 1."""
        return self.noise_level

    @property
    def theta(self) -> np.ndarray:
        """``[log(gamma)]`` when tuned, else empty."""
        if isinstance(self.noise_bounds, str):
            return np.empty(0)
        return np.array([np.log(self.noise_level)])

    @property
    def bounds(self) -> np.ndarray:
        """Bounds of :attr:`theta`, of shape ``(len(theta), 2)``."""
        if isinstance(self.noise_bounds, str):
            return np.empty((0, 2))
        return np.log(np.asarray(self.noise_bounds, dtype=float)).reshape(1, 2)

    def with_theta(self, theta) -> "HeteroscedasticNoise":
        if not self.is_free:
            return self
        return HeteroscedasticNoise(self.weights, float(np.exp(theta[0])), self.noise_bounds)

    def matrix(self) -> np.ndarray:
        """``N = gamma diag(weights)``, dense (for checks)."""
        return np.diag(self.noise_level * self.weights)

    def _check_size(self, n: int) -> None:
        if n != self.weights.shape[0]:
            raise ValueError(f"weights must give one weight per slow sample ({n}); "
                             f"got {self.weights.shape[0]}")

    def add_to(self, S: np.ndarray) -> np.ndarray:
        self._check_size(S.shape[0])
        S[np.diag_indices_from(S)] += self.noise_level * self.weights
        return S

    def contract(self, W: np.ndarray, weight: float = 1.0) -> np.ndarray:
        """``weight tr(W dN / d log gamma) = weight gamma sum_m W_mm w_m`` when tuned."""
        if not self.is_free:
            return np.empty(0)
        return np.array([weight * self.noise_level * (np.diag(W) @ self.weights)])
