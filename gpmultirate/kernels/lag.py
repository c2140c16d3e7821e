"""Impulse-response kernels over continuous lag (paper eq. 16-19).

Each kernel is a :class:`sklearn.gaussian_process.kernels.Kernel` whose
inputs ``X`` are lags ``t >= 0`` in fast samples, of shape ``(n, 1)``.  The
formulas of the paper are the prior on the pulse response at integer lags.
Between them, TC, DC and SS take the interpolation of their integer-lag
values by the hold (:mod:`gpmultirate.kernels.hold`: the response to a held
pulse is smooth between the ticks); PK, one damped resonance, keeps its
formula, which from lag 1 on is the held response of a continuous-time mode
(with ``hold=True`` also on the first cell, zero at lag 0).  Either
way the FIR coefficients are samples of a Gaussian process ``g(t)`` over
continuous lag.

Hyperparameters follow scikit-learn's conventions: they are plain constructor
arguments, each has ``<name>_bounds`` (a pair or ``"fixed"``), ``theta``
holds the free values in tuning coordinates, and gradients
(``eval_gradient=True``) are taken with respect to ``theta``.  Each
hyperparameter declares its coordinate
(:mod:`gpmultirate.kernels.transforms`): the log of the value, as in
scikit-learn, except DC's correlation ``beta`` in ``(-1, 1)``, which enters
as ``artanh(beta)``.  The paper's overall scale ``lambda`` is
:class:`~sklearn.gaussian_process.kernels.ConstantKernel`, as in scikit-learn.
"""

from __future__ import annotations

import numbers

import numpy as np
from scipy import linalg
from sklearn.gaussian_process.kernels import Hyperparameter, Kernel, Sum

from gpmultirate.kernels.filters import DCFilterTerm, suffix_after, two_sided
from gpmultirate.kernels.hold import HoldTerm, hold_covariance, hold_diagonal, mode_start
from gpmultirate.kernels.instants import PKTimedTerm
from gpmultirate.kernels.recursion import ShiftScaledTerm
from gpmultirate.kernels.structure import LowRankTerm, ObservedTerm, StructuredKernel
from gpmultirate.kernels.transforms import ARTANH, LOG, ThetaTransform
from gpmultirate.validation import as_real_array, check_bounds, check_positive

__all__ = [
    "TC", "DC", "SS", "PK", "LagKernel", "ShiftScaledKernel", "check_lags", "correlation",
    "damped_sinusoids", "mode_basis", "resonance_summands", "without_resonances",
]

# what the tuning strategy should know of each hyperparameter (see Role)
_DECAY = ("decay", 1.0)
_CORRELATION = ("correlation", 1.0)


def damped_sinusoids(lags: np.ndarray, omega, envelope: np.ndarray):
    """PK's basis: ``e(t) cos(omega t)`` and ``e(t) sin(omega t)`` at the lags ``t``.

    The one place the resonance basis is computed: by :meth:`PK.basis`
    (``e(t) = alpha^(t/2)``) and by the resonance search, which scans many
    frequencies at once and parametrizes the decay by its rate
    (``e(t) = exp(-rate t)``).

    Parameters
    ----------
    lags : ndarray of shape (n,)
    omega : float or ndarray of shape (k,)
        Frequencies in radians per fast sample; an array gives one column each.
    envelope : ndarray of shape (n,)
        The decay ``e(t)`` at the lags.

    Returns
    -------
    (ndarray, ndarray)
        Of shape ``(n,)`` for a scalar ``omega``, else ``(n, k)``.

    Examples
    --------
    >>> import numpy as np
    >>> lags = np.arange(4.0)
    >>> c, s = damped_sinusoids(lags, np.array([0.5, 1.0]), 0.9 ** (lags / 2.0))
    >>> c.shape, bool(np.allclose(s[:, 1], 0.9 ** (lags / 2.0) * np.sin(lags)))
    ((4, 2), True)
    """
    phase = np.multiply.outer(lags, omega)
    if np.ndim(omega) == 0:
        return envelope * np.cos(phase), envelope * np.sin(phase)
    return envelope[:, None] * np.cos(phase), envelope[:, None] * np.sin(phase)


def mode_basis(lags: np.ndarray, rate, omega, derivatives: int = 0, hold: bool = False) -> list:
    """PK's basis at ``lags`` and its derivatives in ``lambda = -rate + i omega``.

    The one place the basis of a kept term is formed: by :meth:`PK.basis_derivatives`
    (``rate = -log(alpha) / 2``) and by the resonance search's joint model.  The
    ``k``-th pair is the real and imaginary parts of ``d^k b / d lambda^k`` for the
    complex basis ``b(t) = e^(lambda t)``, ``t^k (c, s)``; with ``hold`` the first
    cell, ``[0, 1)``, is the mode's step response
    (:func:`~gpmultirate.kernels.hold.mode_start`), zero at lag 0.

    Examples
    --------
    >>> import numpy as np
    >>> (c, s), (c1, s1) = mode_basis(np.array([0.0, 2.0]), 0.1, 1.0, 1, hold=True)
    >>> float(c[0]), bool(np.isclose(c1[1], 2.0 * np.exp(-0.2) * np.cos(2.0)))
    (0.0, True)
    """
    c, s = damped_sinusoids(lags, omega, np.exp(-rate * lags))
    out = [(c, s)]
    for _ in range(derivatives):
        out.append((lags * out[-1][0], lags * out[-1][1]))
    first = np.flatnonzero(lags < 1.0) if hold else np.empty(0, dtype=np.int64)
    if first.size:
        taken = mode_start(lags[first], rate, omega, derivatives)
        out = [(c.copy(), s.copy()) for c, s in out]
        for (c, s), (dc, ds) in zip(out, taken):
            c[first] -= dc
            s[first] -= ds
    return out


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


class LagKernel(StructuredKernel, Kernel):
    """Common machinery of the lag kernels: input checks, repr, range checks, ``theta``.

    A subclass lists its hyperparameters with their allowed ranges in
    ``_ranges`` as ``(name, lower, upper)`` (the range is ``(lower, upper]``),
    the ``theta`` coordinate of those not tuned in ``log(value)`` in
    ``_transforms`` (``{name: ThetaTransform}``), and implements
    :meth:`lag_covariance`.

    ``theta``, its setter and ``bounds`` are scikit-learn's, except that
    each entry goes through its hyperparameter's transform
    (:meth:`theta_transform`) instead of ``log``; ``clone_with_theta``, the
    kernel algebra (``+``, ``*``) and ``GaussianProcessRegressor`` use them
    unchanged.
    """

    # (name, lower, upper): the allowed range (lower, upper] of each value
    _ranges: tuple = ()
    # {name: ThetaTransform} of the hyperparameters whose theta is not log(value)
    _transforms: dict = {}

    def theta_transform(self, name: str) -> ThetaTransform:
        """The map between the value of hyperparameter ``name`` and its ``theta`` entry.

        Examples
        --------
        >>> DC().theta_transform("beta"), DC().theta_transform("alpha")
        (ArtanhTransform(), LogTransform())
        """
        return self._transforms.get(name, LOG)

    def _free(self) -> list:
        return [h for h in self.hyperparameters if not h.fixed]

    @property
    def n_dims(self) -> int:
        """Number of free hyperparameters (entries of ``theta``), without evaluating it."""
        return sum(h.n_elements for h in self._free())

    @property
    def theta(self) -> np.ndarray:
        """The free hyperparameters in tuning coordinates (the log of most; see :meth:`theta_transform`).

        Raises
        ------
        ValueError
            When a free value has no finite coordinate (e.g. ``beta = 1``
            with free bounds).
        """
        return np.array(
            [self.theta_transform(h.name).to_theta(getattr(self, h.name), h.name)
             for h in self._free()],
            dtype=float,
        )

    @theta.setter
    def theta(self, theta) -> None:
        theta = np.asarray(theta, dtype=float).reshape(-1)
        free = self._free()
        if theta.shape[0] != len(free):
            raise ValueError(
                f"theta has not the correct number of entries. Should be {len(free)}; "
                f"given are {theta.shape[0]}"
            )
        self.set_params(**{
            h.name: self.theta_transform(h.name).from_theta(value)
            for h, value in zip(free, theta)
        })

    @property
    def bounds(self) -> np.ndarray:
        """The bounds of ``theta``, of shape ``(n_dims, 2)``: each hyperparameter's bounds transformed.

        Raises
        ------
        ValueError
            When the bounds of a free hyperparameter are not an interval of
            allowed values; the message names them.
        """
        rows = [
            self.theta_transform(h.name).bounds_to_theta(h.bounds, f"{h.name}_bounds")
            for h in self._free()
        ]
        return np.vstack(rows) if rows else np.array([])

    def is_stationary(self) -> bool:
        """Return False: impulse-response kernels decay with the lag."""
        return False

    def checked_values(self) -> dict:
        """The hyperparameter values as floats, checked against their ranges.

        Returns
        -------
        dict
            ``{name: value}`` in the order of the constructor.

        Raises
        ------
        ValueError
            If a value is not a real number in its range.
        """
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

    def lag_covariance(self, t: np.ndarray, s: np.ndarray, eval_gradient: bool = False):
        """``k(t_i, s_j)`` for lag vectors ``t`` and ``s`` (no checks).

        Parameters
        ----------
        t, s : ndarray of shape (n,) and (m,)
            Non-negative lags; ``s`` may be ``t`` itself.
        eval_gradient : bool, default=False
            Also return the derivatives with respect to the ``theta``
            coordinate of every hyperparameter (:meth:`theta_transform`:
            ``log(name)`` for most, ``artanh(beta)`` for DC's ``beta``),
            fixed or not (unlike ``__call__``, also when ``s`` is not ``t``).

        Returns
        -------
        K : ndarray of shape (n, m)
        gradients : dict of ndarray of shape (n, m), only with ``eval_gradient``
            ``{name: dK / d theta_name}``.
        """
        raise NotImplementedError

    def __call__(self, X, Y=None, eval_gradient=False):
        """Return ``k(X, Y)`` and, if requested, its gradient with respect to ``theta``.

        Parameters
        ----------
        X : array-like of shape (n, 1)
            Lags in fast samples, finite and non-negative.
        Y : array-like of shape (m, 1), optional
            Second lags; ``X`` when None.
        eval_gradient : bool, default=False
            Also return the gradient with respect to ``theta``, the free
            hyperparameters in tuning coordinates (only when ``Y`` is None).

        Returns
        -------
        K : ndarray of shape (n, m)
        K_gradient : ndarray of shape (n, n, n_free), only with ``eval_gradient``
        """
        if eval_gradient and Y is not None:
            raise ValueError("gradient can only be evaluated when Y is None")
        t = check_lags(X, "X")
        s = t if Y is None else check_lags(Y, "Y")
        if not eval_gradient:
            return self.lag_covariance(t, s)
        K, gradients = self.lag_covariance(t, s, eval_gradient=True)
        free = [gradients[h.name] for h in self.hyperparameters if not h.fixed]
        if not free:
            return K, np.empty(K.shape + (0,))
        return K, np.stack(free, axis=-1)

    def __repr__(self) -> str:
        args = ", ".join(
            f"{name}={getattr(self, name):.3g}" for name, _, _ in self._ranges
        )
        return f"{type(self).__name__}({args})"


class ShiftScaledKernel(LagKernel):
    """A lag kernel with ``K(i + 1, j + 1) = a K(i, j)`` on the integer grid (TC, DC, SS).

    Such a kernel declares ``a`` (:meth:`shift_scale`) and its products
    with matrices (:meth:`right_multiply`); the diagonal recursion of
    :mod:`gpmultirate.kernels.recursion` then gives its observed covariance
    in ``O(M N)`` wherever the observation has uniformly spaced samples.
    """

    def shift_scale(self) -> tuple[float, dict]:
        """``a`` and ``{name: d log(a) / d theta_name}`` for every hyperparameter."""
        raise NotImplementedError

    def integer_covariance(self, t: np.ndarray, s: np.ndarray, eval_gradient: bool = False):
        """The kernel's formula (the paper's prior on the pulse response at integer lags).

        As :meth:`~LagKernel.lag_covariance`, for integer lag vectors.
        """
        raise NotImplementedError

    def lag_covariance(self, t, s, eval_gradient=False):
        """The formula at integer lags; between them its interpolation by the hold
        (:func:`~gpmultirate.kernels.hold.hold_covariance`)."""
        return hold_covariance(self, t, s, eval_gradient)

    def diag(self, X) -> np.ndarray:
        """Return ``k(X, X)`` on the diagonal only."""
        t = check_lags(X, "X")
        if np.all(t == np.round(t)):
            return self.integer_diagonal(t)
        return hold_diagonal(self, t)

    def integer_diagonal(self, t: np.ndarray, eval_gradient: bool = False):
        """``k(t_i, t_i)`` at integer lags by the formula (and ``{name: d/d theta_name}``)."""
        raise NotImplementedError

    def right_multiply(self, X: np.ndarray) -> np.ndarray:
        """``X @ K`` for ``X`` of shape ``(r, P)`` and ``K`` at lags ``0..P-1``, in ``O(r P)``."""
        raise NotImplementedError

    def unshifted_term(self, observation, path: str = "") -> ObservedTerm:
        """The term used where the recursion does not apply or does not pay off."""
        return ObservedTerm(self, observation, path)

    def observed(self, observation, path: str = "") -> ObservedTerm:
        """The recursion where it pays off, :meth:`unshifted_term` elsewhere."""
        return ShiftScaledTerm(self, observation, path, self.unshifted_term(observation, path))

    def observed_at_instants(self, observation, path: str = "") -> ObservedTerm:
        """Readings at their own instants: rows on the integer lags plus the bridge (one input).

        Between integer lags the kernel is the hold's interpolation of its
        integer-lag values plus an independent bridge on each cell
        (:mod:`gpmultirate.kernels.hold`), so a reading at any instant is a
        row on the integer lags (the observation's ``on_integer_lags``, with
        every route of the integer lags) plus the bridge's rows
        (:class:`~gpmultirate.kernels.hold.HoldTerm`).
        """
        rows = observation.on_integer_lags() if observation.n_inputs == 1 else None
        if rows is None:
            return observation.dense_term(self, path)
        return HoldTerm(self, self.observed(rows, path), observation, path)


class _DecayKernel(ShiftScaledKernel):
    """A lag kernel with the single hyperparameter ``alpha`` (TC, SS)."""

    _ranges = (("alpha", 0.0, 1.0),)
    tuning_roles = {"alpha": _DECAY}

    def __init__(self, alpha: float = 0.9, alpha_bounds=(1e-4, 1.0)):
        self.alpha = alpha
        self.alpha_bounds = alpha_bounds

    @property
    def hyperparameter_alpha(self) -> Hyperparameter:
        return Hyperparameter("alpha", "numeric", self.alpha_bounds)


def _is_grid(t: np.ndarray) -> bool:
    """True for the lags 0, 1, ..., n-1, where Toeplitz shortcuts apply."""
    return t.shape[0] > 0 and t[0] == 0 and np.array_equal(t, np.arange(t.shape[0]))


def correlation(distance, beta: float, eval_gradient: bool = False):
    r"""DC's correlation at lag distances ``d >= 0``, and its derivative in ``beta``.

    .. math::

        \rho(d) = \beta^d \quad (\beta \ge 0), \qquad
        \rho(d) = |\beta|^d \cos(\pi d) \quad (\beta < 0).

    On integer distances both are ``beta**d``, which is where DC reads it;
    between integer lags DC is the hold's interpolation
    (:mod:`gpmultirate.kernels.hold`).  For a negative ``beta`` the second
    form extends the correlation itself to real distances as the product of
    the exponential correlation ``|beta|^|d|`` and ``cos(pi d)``, both
    positive semidefinite.  The wave is ``cos(pi (d mod 2))``, exactly
    ``+-1`` on integers.

    Parameters
    ----------
    distance : ndarray
        Non-negative distances ``|t - s|``.
    beta : float
        In (-1, 1].
    eval_gradient : bool, default=False
        Also return ``d rho / d beta``.

    Returns
    -------
    rho : ndarray of the shape of ``distance``
    d_rho : ndarray, only with ``eval_gradient``

    Raises
    ------
    ValueError
        For the derivative at ``beta = 0`` when a distance lies strictly
        between 0 and 1, where it is infinite.

    Examples
    --------
    >>> correlation(np.array([0.0, 1.0, 2.0, 0.5]), -0.5).round(12)
    array([ 1.  , -0.5 ,  0.25,  0.  ])
    """
    magnitude = abs(beta)
    rho = magnitude**distance
    wave = np.cos(np.pi * np.remainder(distance, 2.0)) if beta < 0 else None
    if wave is not None:
        rho = rho * wave
    if not eval_gradient:
        return rho
    # d/d beta of |beta|^d (+-cos(pi d)) = d |beta|^(d - 1) (sign(beta) wave)
    if magnitude == 0.0 and np.any((distance > 0.0) & (distance < 1.0)):
        raise ValueError(
            "the derivative in beta is infinite at beta = 0 for lag distances between 0 and 1; "
            "use beta != 0 or integer lags"
        )
    exponent = np.where(distance > 0.0, distance - 1.0, 0.0)
    d_rho = distance * magnitude**exponent
    if wave is not None:
        d_rho = -d_rho * wave
    return rho, d_rho


def _power_of_distance(t, s, beta):
    """DC's correlation at ``|t_i - s_j|``; a Toeplitz matrix on the integer grid."""
    if t is s and _is_grid(t):
        return linalg.toeplitz(correlation(t, beta))
    return correlation(np.abs(np.subtract.outer(t, s)), beta)


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
    >>> TC(alpha=0.5)(np.array([[0.0], [1.0], [2.5]])).round(3)  # 2.5: between the ticks
    array([[1.   , 0.5  , 0.192],
           [0.5  , 0.5  , 0.17 ],
           [0.192, 0.17 , 0.178]])
    """

    def integer_covariance(self, t, s, eval_gradient=False):
        (alpha,) = self.checked_values().values()
        longest = np.maximum.outer(t, s)
        K = alpha**longest
        if not eval_gradient:
            return K
        return K, {"alpha": longest * K}

    def integer_diagonal(self, t, eval_gradient=False):
        (alpha,) = self.checked_values().values()
        values = alpha**t
        return (values, {"alpha": t * values}) if eval_gradient else values

    def shift_scale(self):
        return self.checked_values()["alpha"], {"alpha": 1.0}

    def right_multiply(self, X):
        # sum_i X_i alpha^max(i, j) = alpha^j sum_{i<=j} X_i + sum_{i>j} alpha^i X_i
        alpha = self.checked_values()["alpha"]
        w = alpha ** np.arange(X.shape[1], dtype=float)
        out = np.cumsum(X, axis=1)
        out *= w
        out += suffix_after(X * w)
        return out

    def unshifted_term(self, observation, path=""):
        return _TCTerm(self, observation, path)


class _TCTerm(ObservedTerm):
    """TC off the recursion: the gradient contraction without the gradient array."""

    def parameter_contractor(self):
        if not np.array_equal(self.lags, np.round(self.lags)):
            # between integer lags the values are the hold's, not the formula's
            return super().parameter_contractor()
        K = self.kernel_matrix()
        longest = np.maximum.outer(self.lags, self.lags)
        free = not self.kernel.hyperparameter_alpha.fixed

        def contract(A):
            return np.array([np.sum(A * K * longest)] if free else [])

        return K, contract

    def covariance_blocks(self, split):
        # Phi_r K by the kernel's O(M P) product, then one product with Phi_d^T
        Phi = self.observation.matrix
        PhiK = self.kernel.right_multiply(Phi[split:])
        return PhiK @ Phi[:split].T, np.einsum("ij,ij->i", PhiK, Phi[split:])


class DC(ShiftScaledKernel):
    r"""Diagonal-correlated kernel (paper eq. 16, without the scale ``lambda``).

    .. math:: k(t, s) = \alpha^{(t + s)/2}\, \rho(|t - s|), \qquad
              \rho(d) = \beta^d \ (\beta \ge 0), \quad
              \rho(d) = |\beta|^d \cos(\pi d) \ (\beta < 0)

    On integer lags this is the paper's ``alpha^((i+j)/2) beta^|i-j|`` with
    ``|beta| < 1``.  A negative ``beta`` makes neighbouring coefficients
    alternate in sign (resonances near the fast Nyquist frequency,
    acceleration outputs); on real lags the cosine, ``+-1`` on integers,
    keeps the kernel real and positive semidefinite (see
    :func:`correlation`).

    ``theta`` holds ``log(alpha)`` and ``artanh(beta)``, which maps
    ``(-1, 1)`` onto the real line; the gradient is with respect to them.
    ``beta = 1`` (a rank-one kernel, the pure decay ``alpha^((t+s)/2)``) is
    allowed when ``beta_bounds="fixed"``: it has no finite ``theta``, so
    asking the ``theta`` of a kernel with a free ``beta = 1`` (as tuning
    does) raises a ValueError.  A bound of 1 is accepted and read as the
    largest float below 1.

    Parameters
    ----------
    alpha : float, default=0.9
        Decay per fast sample, in (0, 1].
    beta : float, default=0.9
        Correlation between neighbouring lags, in (-1, 1] (1 only when
        fixed).
    alpha_bounds : pair of floats or "fixed", default=(1e-4, 1.0)
        Bounds on ``alpha`` for marginal-likelihood tuning.
    beta_bounds : pair of floats or "fixed", default=(-0.9999, 0.9999)
        Bounds on ``beta``, within (-1, 1].  The default is symmetric and
        admits correlation lengths ``-1 / log|beta|`` up to 10,000 samples of
        either sign, while keeping ``theta`` within ``+-4.95``.

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

    _ranges = (("alpha", 0.0, 1.0), ("beta", -1.0, 1.0))
    _transforms = {"beta": ARTANH}
    tuning_roles = {"alpha": _DECAY, "beta": _CORRELATION}

    def __init__(
        self,
        alpha: float = 0.9,
        beta: float = 0.9,
        alpha_bounds=(1e-4, 1.0),
        beta_bounds=(-0.9999, 0.9999),
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

    def integer_covariance(self, t, s, eval_gradient=False):
        alpha, beta = self.checked_values().values()
        if not eval_gradient:
            # scaled in place: one P x P array at a time at the orders of long records
            K = _power_of_distance(t, s, beta)
            K *= (alpha ** (t / 2.0))[:, None]
            K *= alpha ** (s / 2.0)
            return K
        mean_lag = np.add.outer(t, s) / 2.0
        envelope = alpha**mean_lag
        rho, d_rho = correlation(np.abs(np.subtract.outer(t, s)), beta, eval_gradient=True)
        K = envelope * rho
        d_beta = envelope * d_rho
        d_beta *= self.theta_transform("beta").derivative(beta)  # d beta / d theta
        return K, {"alpha": mean_lag * K, "beta": d_beta}

    def integer_diagonal(self, t, eval_gradient=False):
        alpha, _ = self.checked_values().values()
        values = alpha**t
        return (values, {"alpha": t * values, "beta": np.zeros_like(values)}) if (
            eval_gradient) else values

    def shift_scale(self):
        return self.checked_values()["alpha"], {"alpha": 1.0, "beta": 0.0}

    def beta_chain(self) -> float:
        """``d beta / d theta_beta`` (``1 - beta^2``, since ``theta_beta = artanh(beta)``).

        Derivatives in ``theta_beta`` written through this factor follow the
        declared transform of ``beta``.

        Examples
        --------
        >>> DC(0.8, 0.5).beta_chain()
        0.75
        """
        beta = self.checked_values()["beta"]
        return float(self.theta_transform("beta").derivative(beta))

    def right_multiply(self, X):
        # K = D T D, D = diag(alpha^(j/2)), T = beta^|i - j|: a two-sided AR(1) filter
        alpha, beta = self.checked_values().values()
        half = alpha ** (np.arange(X.shape[1], dtype=float) / 2.0)
        out = two_sided(X * half, [1.0], [1.0, -beta], include_center=True)
        out *= half
        return out

    def unshifted_term(self, observation, path=""):
        return DCFilterTerm(self, observation, path)


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

    def integer_covariance(self, t, s, eval_gradient=False):
        (alpha,) = self.checked_values().values()
        longest = np.maximum.outer(t, s)
        first_exponent = np.add.outer(t, s) + longest
        first = alpha**first_exponent / 2.0
        second = alpha ** (3.0 * longest) / 6.0
        K = first - second
        if not eval_gradient:
            return K
        # d/d(log alpha) of alpha**e is e * alpha**e
        return K, {"alpha": first_exponent * first - 3.0 * longest * second}

    def integer_diagonal(self, t, eval_gradient=False):
        (alpha,) = self.checked_values().values()
        values = alpha ** (3.0 * t) / 3.0
        return (values, {"alpha": 3.0 * t * values}) if eval_gradient else values


    def shift_scale(self):
        return self.checked_values()["alpha"] ** 3, {"alpha": 3.0}

    def right_multiply(self, X):
        # i <= j: alpha^(2j) alpha^i / 2 - alpha^(3j) / 6
        # i > j:  alpha^j alpha^(2i) / 2 - alpha^(3i) / 6
        alpha = self.checked_values()["alpha"]
        j = np.arange(X.shape[1], dtype=float)
        w1, w2, w3 = alpha**j, alpha ** (2.0 * j), alpha ** (3.0 * j)
        out = np.cumsum(X * w1, axis=1)
        out *= w2 / 2.0
        out += (w1 / 2.0) * suffix_after(X * w2)
        out -= (w3 / 6.0) * np.cumsum(X, axis=1)
        out -= suffix_after(X * (w3 / 6.0))
        return out


class PK(LagKernel):
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
    omega_std : float, default=0.0
        Standard deviation of the frequency (radians per fast sample) the
        prior carries: a resonance known to within ``omega_std``.  Not a
        hyperparameter (never tuned).  With ``omega_std`` or ``rate_std``
        positive the kernel adds the first-order change of the response
        with the frequency and the decay rate ``r = -log(alpha) / 2``,
        ``t s alpha^((t+s)/2) (A cos(omega t) cos(omega s) + B sin(omega t) sin(omega s))``
        with ``A = omega_std^2 sigma2^2 + rate_std^2 sigma1^2`` and
        ``B = omega_std^2 sigma1^2 + rate_std^2 sigma2^2``: the covariance
        of ``d g / d omega * d omega + d g / d r * d r`` for independent
        zero-mean ``d omega``, ``d r`` of those standard deviations, and
        rank four.  Without it a PK term knows the phase of its response at
        every lag, and a frequency slightly off leaves the truth outside its
        band at long lags.
    rate_std : float, default=0.0
        Standard deviation of the decay rate per fast sample (see
        ``omega_std``).
    hold : bool, default=False
        The resonance of a continuous-time plant behind the input's hold.
        Without it the basis is the paper's at every lag, ``alpha^(t/2)
        (cos, sin)(omega t)`` from lag 0.  With it the first cell ``[0, 1)``
        is the mode's response to the held input's first period (its step
        response, :func:`~gpmultirate.kernels.hold.mode_start`): zero at lag
        0 and smooth across lag 1, where it meets the paper's basis, which it
        keeps from lag 1 on.  That is the held pulse response of a mode
        exactly, at every real lag; readings between the ticks near the input's
        changes (a camera's exposure) see it.  Not a hyperparameter.
    posterior_spread : bool, default=False
        What ``omega_std`` and ``rate_std`` are.  False: knowledge of the
        frequency held before the data; the kernel's covariance carries the
        spread and a fit conditions on the data with it, which narrows it.
        True: the uncertainty of a frequency and decay tuned on the data (the
        terms of ``kernel="auto"``): a fit leaves the spread
        out of its evidence and its conditioning and adds it to the
        posterior covariance afterwards
        (:class:`~gpmultirate.covariance.SpreadPosterior`), so that the same
        data do not narrow it a second time.  Only read on a PK summand of
        the kernel (a term of a sum, per input), as ``kernel="auto"`` places
        them; the kernel's own covariance is the same either way.

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
    tuning_roles = {
        "alpha": _DECAY,
        "omega": ("frequency", 1.0),
        "sigma1": ("amplitude", 0.5),
        "sigma2": ("amplitude", 0.5),
    }
    #: the cosine and sine parts' amplitudes, each the other's partner (a part on a lower
    #: bound negligible against its partner is a part the data do not need)
    tuning_partners = {"sigma1": "sigma2", "sigma2": "sigma1"}

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
        omega_std: float = 0.0,
        rate_std: float = 0.0,
        hold: bool = False,
        posterior_spread: bool = False,
    ):
        self.alpha = alpha
        self.omega = omega
        self.sigma1 = sigma1
        self.sigma2 = sigma2
        self.alpha_bounds = alpha_bounds
        self.omega_bounds = omega_bounds
        self.sigma1_bounds = sigma1_bounds
        self.sigma2_bounds = sigma2_bounds
        self.omega_std = omega_std
        self.rate_std = rate_std
        self.hold = hold
        self.posterior_spread = posterior_spread

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

    def basis(self, lags: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The two basis functions ``alpha^(t/2) cos(omega t)`` and ``alpha^(t/2) sin(omega t)``.

        ``k(t, s) = sigma1^2 c(t) c(s) + sigma2^2 s(t) s(s)`` with ``(c, s)``
        these functions (on ``[0, 1)`` the mode's step response with ``hold``).

        Parameters
        ----------
        lags : ndarray of shape (n,)

        Returns
        -------
        (ndarray of shape (n,), ndarray of shape (n,))
        """
        return self.basis_derivatives(lags, 0)[0]

    def basis_derivatives(self, lags: np.ndarray, derivatives: int = 1) -> list:
        """The basis and its derivatives in ``lambda = log(alpha) / 2 + i omega``.

        With ``b(t) = c(t) + i s(t)`` the complex basis, the ``k``-th pair is
        the real and imaginary parts of ``d^k b / d lambda^k``:
        ``t^k (c, s)`` without ``hold``.  The derivatives in ``log(alpha)``
        and ``log(omega)`` are ``1/2`` and ``i omega`` times the first, and the
        spread's basis (``omega_std``, ``rate_std``) is the first pair itself.

        Parameters
        ----------
        lags : ndarray of shape (n,)
        derivatives : int, default=1
            The highest derivative (0, 1 or 2).

        Returns
        -------
        list of (ndarray, ndarray)

        Examples
        --------
        >>> import numpy as np
        >>> lags = np.array([0.0, 0.5, 2.0])
        >>> (c, s), (c1, s1) = PK(alpha=0.81, omega=1.0).basis_derivatives(lags)
        >>> bool(np.allclose(c1, lags * c)), bool(np.allclose(s1, lags * s))
        (True, True)
        >>> (c, s), = PK(alpha=0.81, omega=1.0, hold=True).basis_derivatives(lags, 0)
        >>> float(c[0]), bool(np.isclose(c[2], 0.81 * np.cos(2.0)))
        (0.0, True)
        """
        values = self.checked_values()
        return mode_basis(lags, -0.5 * np.log(values["alpha"]), values["omega"], derivatives,
                          self.held())

    def held(self) -> bool:
        """``hold`` checked: a bool.

        Examples
        --------
        >>> PK(hold=True).held()
        True
        """
        if not isinstance(self.hold, (bool, np.bool_)):
            raise ValueError(f"hold must be True or False; got {self.hold!r}")
        return bool(self.hold)

    def spread_after_conditioning(self) -> bool:
        """``posterior_spread`` checked: whether a fit adds the spread after conditioning.

        Examples
        --------
        >>> PK(omega_std=0.01, posterior_spread=True).spread_after_conditioning()
        True
        """
        if not isinstance(self.posterior_spread, (bool, np.bool_)):
            raise ValueError(
                f"posterior_spread must be True or False; got {self.posterior_spread!r}")
        return bool(self.posterior_spread)

    def spread_columns(self, lags: np.ndarray) -> np.ndarray:
        """``(n, 2)`` columns ``V`` of the spread's covariance: ``V V^T`` is the kernel's
        first-order part in the frequency and the decay (zero without ``omega_std`` and
        ``rate_std``), ``sqrt(A) c'`` and ``sqrt(B) s'``.

        Examples
        --------
        >>> import numpy as np
        >>> kernel = PK(alpha=0.81, omega=1.0, omega_std=0.02, rate_std=0.01)
        >>> lags = np.array([0.0, 1.5, 4.0])
        >>> V = kernel.spread_columns(lags)
        >>> plain = PK(alpha=0.81, omega=1.0)
        >>> bool(np.allclose(V @ V.T, kernel(lags[:, None]) - plain(lags[:, None])))
        True
        """
        values = self.checked_values()
        A, B = self._spread_weights(values)
        if not (A or B):
            return np.zeros((np.shape(lags)[0], 2))
        c1, s1 = self.basis_derivatives(np.asarray(lags, dtype=float), 1)[1]
        return np.column_stack([np.sqrt(A) * c1, np.sqrt(B) * s1])

    def spread(self) -> tuple[float, float]:
        """``(omega_std, rate_std)`` checked: finite and non-negative.

        Examples
        --------
        >>> PK(omega_std=0.01).spread()
        (0.01, 0.0)
        """
        values = []
        for name in ("omega_std", "rate_std"):
            value = getattr(self, name)
            if isinstance(value, (bool, str)) or not isinstance(value, numbers.Real):
                raise ValueError(f"{name} must be a real number; got {value!r}")
            value = float(value)
            if not np.isfinite(value) or value < 0.0:
                raise ValueError(f"{name} must be finite and non-negative; got {value!r}")
            values.append(value)
        return values[0], values[1]

    def _spread_weights(self, values) -> tuple[float, float]:
        """``(A, B)``, the variances of the spread's cosine and sine parts."""
        w_std, r_std = self.spread()
        var1, var2 = values["sigma1"] ** 2, values["sigma2"] ** 2
        return w_std**2 * var2 + r_std**2 * var1, w_std**2 * var1 + r_std**2 * var2

    def lag_covariance(self, t, s, eval_gradient=False):
        values = self.checked_values()
        omega, var1, var2 = values["omega"], values["sigma1"] ** 2, values["sigma2"] ** 2
        spread = any(self.spread())
        # the basis (and the spread's) with the derivatives the gradients take
        depth = (1 if spread else 0) + (1 if eval_gradient else 0)
        left, right = self.basis_derivatives(t, depth), self.basis_derivatives(s, depth)
        A, B = self._spread_weights(values) if spread else (0.0, 0.0)

        def outer(i, weights, j=None, rotate=(False, False)):
            """``sum_p weights_p x_p(t) y_p(s)`` over the cosine and sine parts of pairs i, j."""
            x, y = left[i], right[i if j is None else j]
            if rotate[0]:  # i times the pair: (c, s) -> (-s, c)
                x = (-x[1], x[0])
            if rotate[1]:
                y = (-y[1], y[0])
            return (np.column_stack(x) * weights) @ np.column_stack(y).T

        plain, spread_w = [var1, var2], [A, B]
        K = outer(0, plain)
        if spread:  # the first-order change with the frequency and the decay
            K = K + outer(1, spread_w)
        if s is t:  # symmetric to rounding, as a kernel on one set of lags is
            K = 0.5 * (K + K.T)
        if not eval_gradient:
            return K
        # d/dlog(alpha) = (1/2) d/dlambda; d/dlog(omega) = i omega d/dlambda, on each side
        d_alpha = 0.5 * (outer(1, plain, 0) + outer(0, plain, 1))
        d_omega = omega * (outer(1, plain, 0, (True, False)) + outer(0, plain, 1, (False, True)))
        cos_part = var1 * np.outer(left[0][0], right[0][0])
        sin_part = var2 * np.outer(left[0][1], right[0][1])
        d_sigma1, d_sigma2 = 2.0 * cos_part, 2.0 * sin_part
        if spread:
            w_std, r_std = self.spread()
            d_alpha = d_alpha + 0.5 * (outer(2, spread_w, 1) + outer(1, spread_w, 2))
            d_omega = d_omega + omega * (outer(2, spread_w, 1, (True, False))
                                         + outer(1, spread_w, 2, (False, True)))
            cc = np.outer(left[1][0], right[1][0])
            sn = np.outer(left[1][1], right[1][1])
            d_sigma1 = d_sigma1 + 2.0 * var1 * (r_std**2 * cc + w_std**2 * sn)
            d_sigma2 = d_sigma2 + 2.0 * var2 * (w_std**2 * cc + r_std**2 * sn)
        return K, {"alpha": d_alpha, "omega": d_omega, "sigma1": d_sigma1, "sigma2": d_sigma2}

    def observed(self, observation, path=""):
        """Rank two: ``K = V D V^T`` with ``V = [c, s]`` and ``D = diag(sigma1^2, sigma2^2)``."""
        values = self.checked_values()
        lags = observation.lags[:, 0]
        pairs = self.basis_derivatives(lags, 2 if any(self.spread()) else 1)
        (c, s), (c1, s1) = pairs[:2]
        var1, var2 = values["sigma1"] ** 2, values["sigma2"] ** 2
        omega = values["omega"]
        # extended basis [c, s, c', s'] (' the derivative in lambda, t times the basis
        # without hold): d/dlog(alpha) maps c -> c'/2 and s -> s'/2; d/dlog(omega) maps
        # c -> -omega s' and s -> omega c'
        candidates = {
            "alpha": _pair(0, 2, 0.5 * var1) + _pair(1, 3, 0.5 * var2),
            "omega": _pair(0, 3, -omega * var1) + _pair(1, 2, omega * var2),
            "sigma1": _single(0, 2.0 * var1),
            "sigma2": _single(1, 2.0 * var2),
        }
        if any(self.spread()):
            return self._observed_with_spread(observation, values, pairs, path)
        weights = [candidates[h.name] for h in self.hyperparameters if not h.fixed]
        return LowRankTerm(
            self, observation, np.column_stack([c, s]), np.diag([var1, var2]),
            np.column_stack([c1, s1]), weights, path,
        )

    def _observed_with_spread(self, observation, values, pairs, path):
        """Rank four: ``V = [c, s, c', s']``, ``D = diag(sigma1^2, sigma2^2, A, B)``.

        The derivatives act on the extended basis ``[V, c', s', c'', s'']``
        (columns 0-7; ``'`` the derivative in ``lambda``, ``t`` times the
        column without ``hold``): ``d/dlog(alpha)`` maps each column
        ``x -> x' / 2``, ``d/dlog(omega)`` maps ``c -> -omega s'``,
        ``s -> omega c'`` (and ``c'``, ``s'`` likewise one derivative up).
        """
        (c, s), (c1, s1), (c2, s2) = pairs
        var1, var2 = values["sigma1"] ** 2, values["sigma2"] ** 2
        omega = values["omega"]
        A, B = self._spread_weights(values)
        w2, r2 = (x**2 for x in self.spread())

        def pair(i, j, weight):
            D = np.zeros((8, 8))
            D[i, j] += weight
            D[j, i] += weight
            return D

        def single(*entries):
            D = np.zeros((8, 8))
            for i, weight in entries:
                D[i, i] += weight
            return D

        candidates = {
            "alpha": (pair(0, 4, 0.5 * var1) + pair(1, 5, 0.5 * var2)
                      + pair(2, 6, 0.5 * A) + pair(3, 7, 0.5 * B)),
            "omega": (pair(0, 5, -omega * var1) + pair(1, 4, omega * var2)
                      + pair(2, 7, -omega * A) + pair(3, 6, omega * B)),
            "sigma1": single((0, 2.0 * var1), (2, 2.0 * r2 * var1), (3, 2.0 * w2 * var1)),
            "sigma2": single((1, 2.0 * var2), (2, 2.0 * w2 * var2), (3, 2.0 * r2 * var2)),
        }
        weights = [candidates[h.name] for h in self.hyperparameters if not h.fixed]
        return LowRankTerm(
            self, observation, np.column_stack([c, s, c1, s1]), np.diag([var1, var2, A, B]),
            np.column_stack([c1, s1, c2, s2]), weights, path,
        )

    def observed_at_instants(self, observation, path=""):
        """Readings at their own instants by the low-rank basis at the real lags (one input)."""
        if observation.n_inputs != 1:
            return observation.dense_term(self, path)
        return PKTimedTerm(self, observation, path)

    def diag(self, X) -> np.ndarray:
        """Return ``k(X, X)`` on the diagonal only."""
        values = self.checked_values()
        t = check_lags(X, "X")
        spread = any(self.spread())
        pairs = self.basis_derivatives(t, 1 if spread else 0)
        c, s = pairs[0]
        out = values["sigma1"] ** 2 * c**2 + values["sigma2"] ** 2 * s**2
        if spread:
            A, B = self._spread_weights(values)
            c1, s1 = pairs[1]
            out = out + A * c1**2 + B * s1**2
        return out

    def __repr__(self) -> str:
        text = super().__repr__()
        w_std, r_std = self.spread()
        if w_std or r_std:
            text = f"{text[:-1]}, omega_std={w_std:.3g}, rate_std={r_std:.3g})"
        if self.held():
            text = f"{text[:-1]}, hold=True)"
        if self.spread_after_conditioning():
            text = f"{text[:-1]}, posterior_spread=True)"
        return text


def _pair(i: int, j: int, weight: float) -> np.ndarray:
    """A symmetric 4 x 4 weight with ``weight`` at ``(i, j)`` and ``(j, i)``."""
    D = np.zeros((4, 4))
    D[i, j] += weight
    D[j, i] += weight
    return D


def _single(i: int, weight: float) -> np.ndarray:
    """A 4 x 4 weight with ``weight`` at ``(i, i)``."""
    D = np.zeros((4, 4))
    D[i, i] = weight
    return D


def resonance_summands(kernel) -> list:
    """The PK summands of ``kernel`` reached through sums, in order.

    Examples
    --------
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> resonance_summands(C(1.0) * DC() + PK(omega=0.5) + PK(omega=1.0))
    [PK(alpha=0.9, omega=0.5, sigma1=1, sigma2=1), PK(alpha=0.9, omega=1, sigma1=1, sigma2=1)]
    """
    if isinstance(kernel, PK):
        return [kernel]
    if isinstance(kernel, Sum):
        return resonance_summands(kernel.k1) + resonance_summands(kernel.k2)
    return []


def without_resonances(kernel):
    """``kernel`` with its trailing PK summands removed (the part a resonance search starts from).

    Examples
    --------
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> without_resonances(C(1.0) * DC() + PK(omega=0.5))
    1**2 * DC(alpha=0.9, beta=0.9)
    """
    if isinstance(kernel, Sum):
        if isinstance(kernel.k2, PK):
            return without_resonances(kernel.k1)
        if isinstance(kernel.k1, PK):
            return without_resonances(kernel.k2)
    return kernel
