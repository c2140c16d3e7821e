"""Impulse-response kernels over continuous lag (paper eq. 16-19).

Each kernel is a :class:`sklearn.gaussian_process.kernels.Kernel` whose
inputs ``X`` are lags ``t >= 0`` in fast samples, of shape ``(n, 1)``.  The
formulas of the paper are written for integer lags; they hold unchanged for
real lags and stay positive semidefinite there, which turns the FIR
coefficients into samples of a Gaussian process ``g(t)`` over continuous lag.

Hyperparameters follow scikit-learn's conventions: they are plain constructor
arguments, each has ``<name>_bounds`` (a pair or ``"fixed"``), ``theta`` is
the log of the free values, and gradients (``eval_gradient=True``) are taken
with respect to ``theta``.  The paper's overall scale ``lambda`` is
:class:`~sklearn.gaussian_process.kernels.ConstantKernel`, as in scikit-learn.
"""

from __future__ import annotations

import numbers

import numpy as np
from scipy import linalg
from sklearn.gaussian_process.kernels import Hyperparameter, Kernel

from gpmultirate.validation import as_real_array, check_bounds, check_positive

__all__ = ["TC", "DC", "SS", "PK", "check_lags"]


def check_lags(X, name: str = "X") -> np.ndarray:
    """Validate lags and return them as a float vector.

    Parameters
    ----------
    X : array-like of shape (n,) or (n, 1)
        Lags in fast samples; finite and non-negative.
    name : str, default="X"
        Argument name used in error messages.

    Returns
    -------
    ndarray of shape (n,)
        A new float array (the caller's array is never modified).

    Examples
    --------
    >>> check_lags([[0.0], [1.5]])
    array([0. , 1.5])
    """
    lags = as_real_array(X, name)
    if lags.ndim == 2 and lags.shape[1] == 1:
        lags = lags[:, 0]
    if lags.ndim != 1:
        raise ValueError(
            f"{name} must have shape (n_lags, 1) or (n_lags,); got shape {np.shape(X)}"
        )
    if not np.all(np.isfinite(lags)):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    if np.any(lags < 0):
        raise ValueError(f"{name} must be non-negative lags; got minimum {lags.min():g}")
    return lags


class _LagKernel(Kernel):
    """Common machinery of the lag kernels: input checks, repr, range checks."""

    # (name, lower, upper, upper_inclusive) allowed ranges of the values
    _ranges: tuple = ()

    def is_stationary(self) -> bool:
        """Return False: impulse-response kernels decay with the lag."""
        return False

    def _check_hyperparameters(self) -> dict:
        values = {}
        for name, low, high in self._ranges:
            value = getattr(self, name)
            if isinstance(value, (bool, str)) or not isinstance(value, numbers.Real):
                raise ValueError(f"{name} must be a real number; got {value!r}")
            value = float(value)
            if not np.isfinite(value) or not (low < value <= high):
                raise ValueError(
                    f"{name} must lie in ({low:g}, {high:g}]; got {value!r}"
                )
            values[name] = value
        return values

    def _lags(self, X, Y):
        t = check_lags(X, "X")
        if Y is None:
            return t, t, True
        return t, check_lags(Y, "Y"), False

    def __repr__(self) -> str:
        args = ", ".join(
            f"{name}={getattr(self, name):.3g}" for name, _, _ in self._ranges
        )
        return f"{type(self).__name__}({args})"


class _DecayKernel(_LagKernel):
    """A lag kernel with the single hyperparameter ``alpha`` (TC, SS)."""

    _ranges = (("alpha", 0.0, 1.0),)

    def __init__(self, alpha: float = 0.9, alpha_bounds=(1e-4, 1.0)):
        self.alpha = alpha
        self.alpha_bounds = alpha_bounds

    @property
    def hyperparameter_alpha(self) -> Hyperparameter:
        return Hyperparameter("alpha", "numeric", self.alpha_bounds)


def _is_grid(t: np.ndarray) -> bool:
    """True for the lags 0, 1, ..., n-1, where Toeplitz shortcuts apply."""
    return t.shape[0] > 0 and t[0] == 0 and np.array_equal(t, np.arange(t.shape[0]))


def _envelope_outer(t, s, alpha):
    """``alpha**((t_i + s_j)/2)`` as an outer product of two vectors."""
    return np.outer(alpha ** (t / 2.0), alpha ** (s / 2.0))


def _power_of_distance(t, s, beta):
    """``beta**|t_i - s_j|``; a Toeplitz matrix on the integer grid."""
    if t is s and _is_grid(t):
        return linalg.toeplitz(beta**t)
    return beta ** np.abs(np.subtract.outer(t, s))


def _no_gradient_for_cross(Y, eval_gradient):
    if eval_gradient and Y is not None:
        raise ValueError("gradient can only be evaluated when Y is None")


def _stack(gradients, fixed_flags):
    """Stack the gradients of the free hyperparameters along the last axis."""
    free = [g for g, fixed in zip(gradients, fixed_flags) if not fixed]
    if not free:
        shape = gradients[0].shape if gradients else (0, 0)
        return np.empty(shape + (0,))
    return np.stack(free, axis=-1)


class TC(_DecayKernel):
    r"""Tuned-correlated (first-order stable spline) kernel.

    .. math:: k(t, s) = \alpha^{\max(t, s)}

    Parameters
    ----------
    alpha : float, default=0.9
        Decay per fast sample, in (0, 1].
    alpha_bounds : pair of floats or "fixed", default=(1e-4, 1.0)
        Bounds on ``alpha`` for marginal-likelihood tuning.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.kernels import TC
    >>> TC(alpha=0.5)(np.array([[0.0], [1.0], [2.5]])).round(3)
    array([[1.   , 0.5  , 0.177],
           [0.5  , 0.5  , 0.177],
           [0.177, 0.177, 0.177]])
    """

    def __call__(self, X, Y=None, eval_gradient=False):
        """Return ``k(X, Y)`` and, if requested, its gradient with respect to ``theta``."""
        _no_gradient_for_cross(Y, eval_gradient)
        (alpha,) = self._check_hyperparameters().values()
        t, s, _ = self._lags(X, Y)
        longest = np.maximum.outer(t, s)
        K = alpha**longest
        if not eval_gradient:
            return K
        return K, _stack([longest * K], [self.hyperparameter_alpha.fixed])

    def diag(self, X) -> np.ndarray:
        """Return ``k(X, X)`` on the diagonal only."""
        (alpha,) = self._check_hyperparameters().values()
        return alpha ** check_lags(X, "X")


class DC(_LagKernel):
    r"""Diagonal-correlated kernel (paper eq. 16, without the scale ``lambda``).

    .. math:: k(t, s) = \alpha^{(t + s)/2}\, \beta^{|t - s|}

    Parameters
    ----------
    alpha : float, default=0.9
        Decay per fast sample, in (0, 1].
    beta : float, default=0.9
        Correlation between neighbouring lags, in (0, 1] (the paper's
        ``|beta| < 1``; negative values are not positive definite on
        continuous lags and are not offered).
    alpha_bounds, beta_bounds : pair of floats or "fixed", default=(1e-4, 1.0)
        Bounds for marginal-likelihood tuning.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel
    >>> from gpmultirate.kernels import DC
    >>> kernel = ConstantKernel(2.0) * DC(alpha=0.8, beta=0.5)
    >>> kernel(np.array([[0.0], [1.0]])).round(3)
    array([[2.   , 0.894],
           [0.894, 1.6  ]])
    """

    _ranges = (("alpha", 0.0, 1.0), ("beta", 0.0, 1.0))

    def __init__(
        self,
        alpha: float = 0.9,
        beta: float = 0.9,
        alpha_bounds=(1e-4, 1.0),
        beta_bounds=(1e-4, 1.0),
    ):
        self.alpha = alpha
        self.beta = beta
        self.alpha_bounds = alpha_bounds
        self.beta_bounds = beta_bounds

    @property
    def hyperparameter_alpha(self) -> Hyperparameter:
        return Hyperparameter("alpha", "numeric", self.alpha_bounds)

    @property
    def hyperparameter_beta(self) -> Hyperparameter:
        return Hyperparameter("beta", "numeric", self.beta_bounds)

    def __call__(self, X, Y=None, eval_gradient=False):
        """Return ``k(X, Y)`` and, if requested, its gradient with respect to ``theta``."""
        _no_gradient_for_cross(Y, eval_gradient)
        alpha, beta = self._check_hyperparameters().values()
        t, s, _ = self._lags(X, Y)
        if not eval_gradient:
            return _envelope_outer(t, s, alpha) * _power_of_distance(t, s, beta)
        mean_lag = np.add.outer(t, s) / 2.0
        distance = np.abs(np.subtract.outer(t, s))
        K = alpha**mean_lag * beta**distance
        return K, _stack(
            [mean_lag * K, distance * K],
            [self.hyperparameter_alpha.fixed, self.hyperparameter_beta.fixed],
        )

    def diag(self, X) -> np.ndarray:
        """Return ``k(X, X)`` on the diagonal only."""
        alpha, _ = self._check_hyperparameters().values()
        return alpha ** check_lags(X, "X")


class SS(_DecayKernel):
    r"""Second-order stable-spline kernel (paper eq. 17, without ``lambda``).

    .. math:: k(t, s) = \frac{\alpha^{t + s + \max(t, s)}}{2} - \frac{\alpha^{3\max(t, s)}}{6}

    Parameters
    ----------
    alpha : float, default=0.9
        Decay per fast sample, in (0, 1].
    alpha_bounds : pair of floats or "fixed", default=(1e-4, 1.0)
        Bounds for marginal-likelihood tuning.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.kernels import SS
    >>> SS(alpha=0.5).diag(np.array([[0.0], [1.0]])).round(4)
    array([0.3333, 0.0417])
    """

    def __call__(self, X, Y=None, eval_gradient=False):
        """Return ``k(X, Y)`` and, if requested, its gradient with respect to ``theta``."""
        _no_gradient_for_cross(Y, eval_gradient)
        (alpha,) = self._check_hyperparameters().values()
        t, s, _ = self._lags(X, Y)
        longest = np.maximum.outer(t, s)
        first_exponent = np.add.outer(t, s) + longest
        first = alpha**first_exponent / 2.0
        second = alpha ** (3.0 * longest) / 6.0
        K = first - second
        if not eval_gradient:
            return K
        # d/d(log alpha) of alpha**e is e * alpha**e
        gradient = first_exponent * first - 3.0 * longest * second
        return K, _stack([gradient], [self.hyperparameter_alpha.fixed])

    def diag(self, X) -> np.ndarray:
        """Return ``k(X, X)`` on the diagonal only."""
        (alpha,) = self._check_hyperparameters().values()
        return alpha ** (3.0 * check_lags(X, "X")) / 3.0


class PK(_LagKernel):
    r"""Prior-knowledge kernel of one damped resonance (paper eq. 18-19).

    .. math::

        k(t, s) = \alpha^{(t+s)/2}\left(\sigma_1^2 \cos(\omega t)\cos(\omega s)
                  + \sigma_2^2 \sin(\omega t)\sin(\omega s)\right)

    which equals the paper's form
    ``alpha^((t+s)/2) (gamma1 cos(omega (t-s)) + gamma2 cos(omega (t+s)))``
    with ``gamma1 = (sigma1^2 + sigma2^2)/2`` and
    ``gamma2 = (sigma1^2 - sigma2^2)/2``.  It has rank two, is positive
    semidefinite, and is defined for real lags.  Sum several to encode
    several resonances.

    Parameters
    ----------
    alpha : float, default=0.9
        Decay per fast sample of the resonance's variance, in (0, 1].
    omega : float, default=0.5
        Resonance frequency in radians per fast sample, in (0, pi] for a
        resonance below the fast Nyquist frequency (values up to ``2 pi`` are
        accepted).  Use :meth:`from_hz` to give it in Hz.
    sigma1, sigma2 : float, default=1.0
        Standard deviations of the cosine and sine parts of the response.
    alpha_bounds : pair of floats or "fixed", default=(1e-4, 1.0)
    omega_bounds : pair of floats or "fixed", default=(1e-3, pi)
    sigma1_bounds, sigma2_bounds : pair of floats or "fixed", default=(1e-5, 1e5)
        Bounds for marginal-likelihood tuning.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.kernels import PK
    >>> kernel = PK.from_hz(2.0, sample_time=0.1, alpha=0.95)
    >>> round(kernel.omega, 4), round(kernel.frequency_hz(0.1), 4)
    (1.2566, 2.0)
    >>> kernel(np.array([[0.0], [0.5]])).round(3)
    array([[1.   , 0.799],
           [0.799, 0.975]])
    """

    _ranges = (
        ("alpha", 0.0, 1.0),
        ("omega", 0.0, 2.0 * np.pi),
        ("sigma1", 0.0, np.inf),
        ("sigma2", 0.0, np.inf),
    )

    def __init__(
        self,
        alpha: float = 0.9,
        omega: float = 0.5,
        sigma1: float = 1.0,
        sigma2: float = 1.0,
        alpha_bounds=(1e-4, 1.0),
        omega_bounds=(1e-3, np.pi),
        sigma1_bounds=(1e-5, 1e5),
        sigma2_bounds=(1e-5, 1e5),
    ):
        self.alpha = alpha
        self.omega = omega
        self.sigma1 = sigma1
        self.sigma2 = sigma2
        self.alpha_bounds = alpha_bounds
        self.omega_bounds = omega_bounds
        self.sigma1_bounds = sigma1_bounds
        self.sigma2_bounds = sigma2_bounds

    @classmethod
    def from_hz(
        cls,
        frequency: float,
        sample_time: float,
        *,
        frequency_bounds=None,
        **kwargs,
    ) -> "PK":
        """Create a PK kernel whose resonance is given in Hz.

        Parameters
        ----------
        frequency : float
            Resonance frequency in Hz, in (0, 1 / (2 sample_time)].
        sample_time : float
            Fast sample time in seconds.
        frequency_bounds : pair of floats or "fixed", optional
            Bounds on the frequency in Hz; converted to ``omega_bounds``.
        **kwargs
            Other constructor arguments (``alpha``, ``sigma1``, ...).

        Returns
        -------
        PK
        """
        sample_time = check_positive(sample_time, "sample_time")
        frequency = check_positive(frequency, "frequency")
        if frequency > 0.5 / sample_time:
            raise ValueError(
                f"frequency must not exceed the fast Nyquist frequency {0.5 / sample_time:g} Hz; "
                f"got {frequency:g}"
            )
        scale = 2.0 * np.pi * sample_time
        if frequency_bounds is not None:
            bounds = check_bounds(frequency_bounds, "frequency_bounds")
            kwargs["omega_bounds"] = (
                bounds if isinstance(bounds, str) else (bounds[0] * scale, bounds[1] * scale)
            )
        return cls(omega=frequency * scale, **kwargs)

    def frequency_hz(self, sample_time: float) -> float:
        """Return the resonance frequency in Hz for the given fast sample time."""
        return float(self.omega) / (2.0 * np.pi * sample_time)

    @property
    def hyperparameter_alpha(self) -> Hyperparameter:
        return Hyperparameter("alpha", "numeric", self.alpha_bounds)

    @property
    def hyperparameter_omega(self) -> Hyperparameter:
        return Hyperparameter("omega", "numeric", self.omega_bounds)

    @property
    def hyperparameter_sigma1(self) -> Hyperparameter:
        return Hyperparameter("sigma1", "numeric", self.sigma1_bounds)

    @property
    def hyperparameter_sigma2(self) -> Hyperparameter:
        return Hyperparameter("sigma2", "numeric", self.sigma2_bounds)

    def _parts(self, lags, alpha, omega):
        envelope = alpha ** (lags / 2.0)
        return envelope * np.cos(omega * lags), envelope * np.sin(omega * lags)

    def __call__(self, X, Y=None, eval_gradient=False):
        """Return ``k(X, Y)`` and, if requested, its gradient with respect to ``theta``."""
        _no_gradient_for_cross(Y, eval_gradient)
        alpha, omega, sigma1, sigma2 = self._check_hyperparameters().values()
        t, s, _ = self._lags(X, Y)
        ct, st = self._parts(t, alpha, omega)
        cs, ss = self._parts(s, alpha, omega)
        cos_part = sigma1**2 * np.outer(ct, cs)
        sin_part = sigma2**2 * np.outer(st, ss)
        K = cos_part + sin_part
        if not eval_gradient:
            return K
        mean_lag = np.add.outer(t, s) / 2.0
        # d/d(log omega): omega * dK/domega, using d cos(w t)/dw = -t sin(w t)
        d_omega = omega * (
            sigma1**2 * (-np.outer(t * st, cs) - np.outer(ct, s * ss))
            + sigma2**2 * (np.outer(t * ct, ss) + np.outer(st, s * cs))
        )
        gradients = [mean_lag * K, d_omega, 2.0 * cos_part, 2.0 * sin_part]
        fixed = [
            self.hyperparameter_alpha.fixed,
            self.hyperparameter_omega.fixed,
            self.hyperparameter_sigma1.fixed,
            self.hyperparameter_sigma2.fixed,
        ]
        return K, _stack(gradients, fixed)

    def diag(self, X) -> np.ndarray:
        """Return ``k(X, X)`` on the diagonal only."""
        alpha, omega, sigma1, sigma2 = self._check_hyperparameters().values()
        c, s = self._parts(check_lags(X, "X"), alpha, omega)
        return sigma1**2 * c**2 + sigma2**2 * s**2
