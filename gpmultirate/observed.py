"""A lag kernel seen through the observation, as a scikit-learn kernel."""

from __future__ import annotations

import numpy as np
from sklearn.gaussian_process.kernels import GenericKernelMixin, Hyperparameter, Kernel

from gpmultirate.validation import as_real_array
from gpmultirate.observations import Observation

__all__ = ["ObservedKernel"]


class ObservedKernel(GenericKernelMixin, Kernel):
    """Covariance ``Phi K Phi^T`` of the slow-rate data, indexed by slow sample.

    The inputs ``X`` are slow-sample indices (``np.arange(M)[:, None]``); the
    value at ``(m, n)`` is ``(Phi K Phi^T)[m, n]`` where ``K`` is ``kernel``
    at lags ``0..P-1``.  Its hyperparameters are those of ``kernel`` (named
    ``kernel__<name>``), with analytic gradients, so that
    ``GaussianProcessRegressor(kernel=ObservedKernel(k, op) + WhiteKernel(gamma))``
    fits the slow data exactly as :class:`~gpmultirate.FIRGaussianProcess`.

    Parameters
    ----------
    kernel : sklearn Kernel
        Prior covariance of the impulse response over lag.
    observation : Observation
        The observation built from the training input, e.g. a
        :class:`~gpmultirate.DownsampledConvolution`.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process import GaussianProcessRegressor
    >>> from sklearn.gaussian_process.kernels import WhiteKernel
    >>> from gpmultirate import DownsampledConvolution, ObservedKernel
    >>> from gpmultirate.kernels import TC
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(60)
    >>> op = DownsampledConvolution(u, factor=3, order=30)
    >>> X = np.arange(op.n_outputs)[:, None]
    >>> y = op.matvec(0.8 ** np.arange(30))
    >>> kernel = ObservedKernel(TC(alpha=0.8), op) + WhiteKernel(1e-4, "fixed")
    >>> gpr = GaussianProcessRegressor(kernel, optimizer=None).fit(X, y)
    >>> bool(np.allclose(gpr.predict(X), y, atol=0.05))
    True
    """

    def __init__(self, kernel: Kernel, observation: Observation | None = None):
        self.kernel = kernel
        self.observation = observation

    def get_params(self, deep: bool = True) -> dict:
        """Get the parameters, including ``kernel__<name>`` with ``deep=True``."""
        params = dict(kernel=self.kernel, observation=self.observation)
        if deep:
            params.update(
                ("kernel__" + key, value) for key, value in self.kernel.get_params().items()
            )
        return params

    @property
    def hyperparameters(self) -> list:
        """The hyperparameters of the inner kernel, prefixed with ``kernel__``."""
        return [
            Hyperparameter(
                "kernel__" + h.name, h.value_type, h.bounds, h.n_elements, h.fixed
            )
            for h in self.kernel.hyperparameters
        ]

    @property
    def theta(self) -> np.ndarray:
        """The free hyperparameters of the inner kernel in their tuning coordinates (``theta``)."""
        return self.kernel.theta

    @theta.setter
    def theta(self, theta) -> None:
        self.kernel.theta = theta

    @property
    def bounds(self) -> np.ndarray:
        """The bounds of the inner kernel's ``theta``."""
        return self.kernel.bounds

    def __eq__(self, other) -> bool:
        if type(self) is not type(other):
            return False
        return self.kernel == other.kernel and self.observation == other.observation

    def _check_parts(self) -> None:
        if not isinstance(self.observation, Observation):
            raise ValueError(
                "observation must be an observation such as DownsampledConvolution; "
                f"got {type(self.observation).__name__}"
            )
        if not isinstance(self.kernel, Kernel):
            raise ValueError(f"kernel must be a scikit-learn Kernel; got {type(self.kernel).__name__}")

    def _indices(self, X, name: str) -> np.ndarray:
        self._check_parts()
        message = (
            f"{name} must hold slow-sample indices in 0..{self.observation.n_outputs - 1} "
            "with shape (n, 1)"
        )
        try:
            X = as_real_array(X, name)
        except ValueError as exc:
            raise ValueError(message) from exc
        if X.ndim == 2 and X.shape[1] == 1:
            X = X[:, 0]
        if X.ndim != 1 or X.size == 0 or not np.all(np.isfinite(X)):
            raise ValueError(message)
        index = X.astype(int)
        if not np.array_equal(index, X) or index.min() < 0 or index.max() >= self.observation.n_outputs:
            raise ValueError(message)
        return index

    def __call__(self, X, Y=None, eval_gradient: bool = False):
        """Return ``(Phi K Phi^T)[X, Y]`` and optionally its gradient."""
        rows = self._indices(X, "X")
        if eval_gradient:
            if Y is not None:
                raise ValueError("gradient can only be evaluated when Y is None")
            cov, grad = self.observation.covariance(self.kernel, eval_gradient=True)
            return cov[np.ix_(rows, rows)], grad[np.ix_(rows, rows)]
        cols = rows if Y is None else self._indices(Y, "Y")
        cov = self.observation.covariance(self.kernel)
        return cov[np.ix_(rows, cols)]

    def diag(self, X) -> np.ndarray:
        """Return the prior variance of the noise-free slow output at ``X``."""
        return np.diag(self(X)).copy()

    def is_stationary(self) -> bool:
        """Return False: the data covariance depends on the input record."""
        return False

    def __repr__(self) -> str:
        return f"ObservedKernel({self.kernel!r}, {self.observation!r})"
