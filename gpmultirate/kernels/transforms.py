"""How each hyperparameter's value maps to its entry of ``theta``.

scikit-learn tunes a kernel in ``theta``, the log of its free
hyperparameters, which suits a positive value (a scale, a decay, a
frequency).  A correlation in ``(-1, 1)``, the ``beta`` of
:class:`~gpmultirate.kernels.DC`, has no logarithm when it is negative; it
enters ``theta`` as ``artanh(beta)``, which maps ``(-1, 1)`` onto the real
line and, near ``beta = +-1``, behaves like the log of ``1 -+ beta``, as well
scaled there as the log of a decay rate.

A lag kernel declares the transform of each hyperparameter
(:meth:`~gpmultirate.kernels.LagKernel.theta_transform`); every other
kernel keeps scikit-learn's log.  :func:`theta_transforms` lists them for any
kernel, composite or not, in ``theta`` order, and :func:`check_kernel` checks
a kernel's values and bounds against them.
"""

from __future__ import annotations

import numpy as np
from sklearn.gaussian_process.kernels import Kernel

from gpmultirate.validation import as_real_array

__all__ = ["ArtanhTransform", "LogTransform", "ThetaTransform", "check_kernel", "theta_transforms",
           "LOG", "ARTANH"]


class ThetaTransform:
    """The map between a hyperparameter's value and its ``theta`` coordinate.

    Subclasses define :meth:`to_theta`, :meth:`from_theta`,
    :meth:`derivative` and the allowed values and bounds.
    """

    #: the formula, for messages and documentation
    formula = ""

    def to_theta(self, value, name: str = "value") -> np.ndarray:
        """``theta`` of ``value`` (a float or an array); ValueError where it is not finite."""
        raise NotImplementedError

    def from_theta(self, theta) -> np.ndarray:
        """The value of ``theta`` (a float or an array)."""
        raise NotImplementedError

    def derivative(self, value) -> np.ndarray:
        """``d value / d theta`` at ``value``."""
        raise NotImplementedError

    def bounds_to_theta(self, bounds, name: str = "bounds") -> np.ndarray:
        """Bounds ``(low, high)`` (any shape ending in 2) mapped to ``theta``.

        Raises
        ------
        ValueError
            When the bounds are not a valid interval of values.
        """
        raise NotImplementedError

    def check_bounds(self, bounds, name: str = "bounds") -> np.ndarray:
        """``bounds`` as a float array of shape ``(n, 2)``, checked; ValueError otherwise."""
        raise NotImplementedError

    def check_value(self, value, name: str = "value") -> None:
        """ValueError unless every entry of ``value`` is an allowed value (not only a tunable one)."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


def _as_bounds(bounds, name: str) -> np.ndarray:
    try:
        array = np.asarray(bounds, dtype=float).reshape(-1, 2)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a pair (low, high) or 'fixed'; got {bounds!r}") from None
    return array


class LogTransform(ThetaTransform):
    """``theta = log(value)`` for a positive value: scikit-learn's convention.

    Examples
    --------
    >>> LOG.to_theta(1.0), LOG.from_theta(0.0), LOG.derivative(2.0)
    (0.0, 1.0, 2.0)
    """

    formula = "log(value)"

    def to_theta(self, value, name="value"):
        array = np.asarray(value, dtype=float)
        if not (np.all(np.isfinite(array)) and np.all(array > 0)):
            raise ValueError(f"{name} must be finite and positive to be tuned in log(value); "
                             f"got {value!r}")
        out = np.log(array)
        return float(out) if out.ndim == 0 else out

    def from_theta(self, theta):
        out = np.exp(np.asarray(theta, dtype=float))
        return float(out) if out.ndim == 0 else out

    def derivative(self, value):
        return value

    def check_bounds(self, bounds, name="bounds"):
        array = _as_bounds(bounds, name)
        if not (np.all(np.isfinite(array)) and np.all(array[:, 0] > 0)
                and np.all(array[:, 0] <= array[:, 1])):
            raise ValueError(f"{name} must satisfy 0 < low <= high (finite); got {bounds!r}")
        return array

    def bounds_to_theta(self, bounds, name="bounds"):
        return np.log(self.check_bounds(bounds, name))

    def check_value(self, value, name="value"):
        array = np.asarray(value, dtype=float)
        if not (np.all(np.isfinite(array)) and np.all(array > 0)):
            raise ValueError(f"{name} must be finite and positive; got {value!r}")


# tanh(theta) rounds to 1 for theta above about 19; values stay at most this
_LARGEST_BELOW_ONE = float(np.nextafter(1.0, 0.0))


class ArtanhTransform(ThetaTransform):
    """``theta = artanh(value)`` for a correlation in ``(-1, 1)``.

    The value ``1`` (allowed for DC's ``beta`` when it is fixed) has no
    finite ``theta``: :meth:`to_theta` refuses it.  A bound of ``1`` means
    "up to the largest float below 1", whose ``theta`` is about 18.7, so
    that bounds stay finite for the optimizers; :meth:`from_theta` never
    returns more than that float, so every ``theta`` maps back to a value
    with a finite ``theta``.

    Examples
    --------
    >>> round(ARTANH.to_theta(-0.5), 6), round(ARTANH.from_theta(0.5493061443), 6)
    (-0.549306, 0.5)
    >>> ARTANH.derivative(0.5)
    0.75
    >>> ARTANH.bounds_to_theta((-0.5, 1.0)).round(3)
    array([[-0.549, 18.715]])
    """

    formula = "artanh(value)"

    def to_theta(self, value, name="value"):
        array = np.asarray(value, dtype=float)
        if not (np.all(np.isfinite(array)) and np.all(np.abs(array) < 1.0)):
            raise ValueError(
                f"{name} must lie in (-1, 1) to be tuned in theta = artanh({name}); got {value!r}"
                " (a value of 1 is allowed only when it is fixed: bounds 'fixed')"
            )
        out = np.arctanh(array)
        return float(out) if out.ndim == 0 else out

    def from_theta(self, theta):
        out = np.clip(np.tanh(np.asarray(theta, dtype=float)),
                      -_LARGEST_BELOW_ONE, _LARGEST_BELOW_ONE)
        return float(out) if out.ndim == 0 else out

    def derivative(self, value):
        out = 1.0 - np.square(value)
        return float(out) if np.ndim(out) == 0 else out

    def check_bounds(self, bounds, name="bounds"):
        array = _as_bounds(bounds, name)
        if not (np.all(np.isfinite(array)) and np.all(array[:, 0] > -1.0)
                and np.all(array[:, 1] <= 1.0) and np.all(array[:, 0] <= array[:, 1])):
            raise ValueError(f"{name} must satisfy -1 < low <= high <= 1; got {bounds!r}")
        return array

    def bounds_to_theta(self, bounds, name="bounds"):
        array = self.check_bounds(bounds, name)
        return np.arctanh(np.minimum(array, _LARGEST_BELOW_ONE))

    def check_value(self, value, name="value"):
        array = np.asarray(value, dtype=float)
        if not (np.all(np.isfinite(array)) and np.all(array > -1.0) and np.all(array <= 1.0)):
            raise ValueError(f"{name} must lie in (-1, 1]; got {value!r}")


LOG = LogTransform()
ARTANH = ArtanhTransform()


def transform_of(kernel, name: str) -> ThetaTransform:
    """The transform of the hyperparameter ``name`` (``k1__k2__beta``) of ``kernel``.

    The leaf kernel that owns it is found through ``get_params``; it answers
    through its ``theta_transform`` method if it has one, else it is
    scikit-learn's log.
    """
    prefix, _, leaf = name.rpartition("__")
    owner = kernel.get_params(deep=True)[prefix] if prefix else kernel
    declare = getattr(owner, "theta_transform", None)
    return LOG if declare is None else declare(leaf)


def theta_transforms(kernel) -> list:
    """One :class:`ThetaTransform` per entry of ``kernel.theta``, in order.

    Parameters
    ----------
    kernel : sklearn Kernel
        Any kernel, composite or not.

    Returns
    -------
    list of ThetaTransform

    Examples
    --------
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate.kernels import DC
    >>> theta_transforms(C(1.0) * DC(0.9, -0.5))
    [LogTransform(), LogTransform(), ArtanhTransform()]
    """
    out = []
    for h in kernel.hyperparameters:
        if not h.fixed:
            out += [transform_of(kernel, h.name)] * h.n_elements
    return out


def check_kernel(kernel, name: str = "kernel"):
    """Check a scikit-learn kernel's hyperparameter values and bounds.

    Each hyperparameter is checked against its ``theta`` coordinate
    (:func:`transform_of`): a value tuned in
    ``log`` must be real, finite and positive and its bounds a pair
    ``0 < low <= high``; a correlation tuned in ``artanh`` (DC's ``beta``)
    must lie in ``(-1, 1]`` and its bounds within it.  Lag kernels also
    check their own ranges (``alpha <= 1`` ...) on a test evaluation.
    """
    if not isinstance(kernel, Kernel):
        raise ValueError(f"{name} must be a scikit-learn Kernel over lags; got {type(kernel).__name__}")
    params = kernel.get_params()
    for h in kernel.hyperparameters:
        value = params.get(h.name)
        transform = transform_of(kernel, h.name)
        try:
            as_real_array(value, f"{name} hyperparameter {h.name}")
            transform.check_value(value, f"{name} hyperparameter {h.name}")
        except ValueError as exc:
            message = str(exc)
            if not message.startswith(name):
                message = f"{name} hyperparameter {h.name}: {message}"
            raise ValueError(message) from None
        if h.fixed:
            continue
        bounds_name = f"{h.name.rpartition('__')[2]}_bounds"
        transform.check_bounds(h.bounds, f"{name} {bounds_name}")
    try:
        kernel(np.zeros((1, 1)))
    except ValueError as exc:
        raise ValueError(f"{name}: {exc}") from None
    return kernel
