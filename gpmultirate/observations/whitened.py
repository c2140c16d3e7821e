"""An observation seen through a fixed noise covariance: the generalized least-squares view.

With slow samples ``y = Phi g + d + e`` whose noise ``N = cov(d + e)`` is
known up to a factor (a disturbance model's shape, tuned once), the
Cholesky factor ``N = L L^T`` turns them into ``L^{-1} y = (L^{-1} Phi) g +
w`` with ``cov(w)`` a multiple of the identity: a problem with white noise
and the regressor ``L^{-1} Phi``.  Every tool that assumes white noise (the
resonance search of :mod:`gpmultirate.resonances`, its scans, refinements
and pruning) then works under the disturbance unchanged.  ``L`` is lower
triangular, so the ``m``-th whitened sample is the innovation of ``y_m``
given the samples before it: the samples keep their order, and contiguous
blocks of them stay contiguous in time.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from gpmultirate.observations.base import Observation
from gpmultirate.validation import check_array

__all__ = ["WhitenedObservation"]


class WhitenedObservation(Observation):
    """``L^{-1} Phi`` for ``N = L L^T``: ``observation`` under the fixed noise covariance ``N``.

    A dense observation (``M x P`` regressor): for records of up to a few
    thousand slow samples with a regressor on the integer lags
    (``observation.has_regressor``).

    Parameters
    ----------
    observation : Observation
        The observation of the slow samples (not modified).
    noise_covariance : ndarray of shape (M, M)
        The covariance ``N`` of the samples' noise, symmetric positive definite.

    Raises
    ------
    ValueError
        If ``observation`` has no regressor, ``noise_covariance`` is not
        ``M x M``, not finite or not positive definite.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> rng = np.random.default_rng(0)
    >>> op = DownsampledConvolution(rng.standard_normal(60), factor=3, order=5)
    >>> t = np.arange(op.n_outputs)
    >>> N = 0.5 * np.exp(-np.abs(t[:, None] - t[None, :]) / 4.0) + 0.1 * np.eye(op.n_outputs)
    >>> whitened = WhitenedObservation(op, N)
    >>> L = np.linalg.cholesky(N)
    >>> bool(np.allclose(L @ whitened.matrix, op.matrix))
    True
    >>> y = rng.standard_normal(op.n_outputs)
    >>> bool(np.allclose(L @ whitened.whiten(y), y))
    True
    """

    def __init__(self, observation: Observation, noise_covariance):
        if not observation.has_regressor:
            raise ValueError("observation must have a regressor on the integer lags to be "
                             "whitened; readings between the ticks have none")
        M = observation.n_outputs
        N = check_array(noise_covariance, "noise_covariance", rows=M, ndims=(2,))
        if N.shape != (M, M):
            raise ValueError(f"noise_covariance must be of shape ({M}, {M}), the slow "
                             f"samples'; got {N.shape}")
        try:
            self._factor = linalg.cholesky(N, lower=True, check_finite=False)
        except linalg.LinAlgError as error:
            raise ValueError("noise_covariance must be positive definite") from error
        self._parent = observation
        self.order = observation.order
        self.n_inputs = observation.n_inputs
        self.n_outputs = M
        self.uniform_sampling = None  # the diagonal recursion needs a convolution's rows
        matrix = self.whiten(observation.matrix)
        matrix.setflags(write=False)
        self._matrix = matrix

    @property
    def lags(self) -> np.ndarray:
        """The lags (and inputs) of the parent observation's coefficients."""
        return self._parent.lags

    @property
    def slow_factor(self) -> int:
        """The parent observation's slow-rate factor (fast samples per slow sample)."""
        return self._parent.slow_factor

    @property
    def matrix(self) -> np.ndarray:
        """``L^{-1} Phi`` (read-only)."""
        return self._matrix

    def whiten(self, values) -> np.ndarray:
        """``L^{-1} values`` for ``values`` of shape ``(M,)`` or ``(M, k)`` (a new array)."""
        return linalg.solve_triangular(self._factor, np.asarray(values, dtype=float),
                                       lower=True, check_finite=False)

    def __repr__(self) -> str:
        return f"WhitenedObservation({self._parent!r})"
