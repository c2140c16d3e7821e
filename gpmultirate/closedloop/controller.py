"""A known loop controller, as a ratio of polynomials in ``z^-1``.

The closed-loop tools take the controller in the forms users hold it in: a
number (a static gain), an FIR array ``[b_0, b_1, ...]``, a discrete
:class:`scipy.signal.dlti` (transfer function, zeros-poles-gain or state
space) or a discrete python-control system.  :func:`as_controller` turns
each into one :class:`Controller`: ``C(z) = B(z^-1) / A(z^-1)`` with
``A(0) = 1``, which filters a signal sample by sample (the loop simulation
needs that) and gives its frequency response.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np
from scipy import signal

__all__ = ["Controller", "as_controller"]


@dataclass(frozen=True)
class Controller:
    """``C(z) = sum_k numerator[k] z^-k / sum_k denominator[k] z^-k``, ``denominator[0] = 1``.

    Attributes
    ----------
    numerator, denominator : ndarray
        Coefficients of ``z^-k``, ``k = 0, 1, ...``.
    sample_time : float or None
        The controller's own sample time in seconds, where the system stated one.

    Examples
    --------
    >>> from gpmultirate.closedloop import as_controller
    >>> c = as_controller([0.5, 0.25])
    >>> c.filter([1.0, 0.0, 0.0]).tolist()
    [0.5, 0.25, 0.0]
    >>> complex(c.frequency_response([0.0], 1.0)[0])
    (0.75+0j)
    """

    numerator: np.ndarray
    denominator: np.ndarray
    sample_time: float | None = None

    def frequency_response(self, freqs, sample_time: float) -> np.ndarray:
        """``C(exp(j 2 pi f T))`` at ``freqs`` (Hz) for the sample time ``T`` it runs at."""
        z_inv = np.exp(-2j * np.pi * np.asarray(freqs, dtype=float) * sample_time)
        num = np.polynomial.polynomial.polyval(z_inv, self.numerator)
        den = np.polynomial.polynomial.polyval(z_inv, self.denominator)
        return num / den

    def filter(self, x) -> np.ndarray:
        """The controller's output for input ``x``, from rest."""
        return signal.lfilter(self.numerator, self.denominator, np.asarray(x, dtype=float))

    def stepper(self) -> "_Stepper":
        """A filter that takes one sample at a time (for a loop simulated frame by frame)."""
        return _Stepper(self.numerator, self.denominator)


class _Stepper:
    """Direct form of ``B / A``: ``c[m] = sum b_k e[m-k] - sum_{k>=1} a_k c[m-k]``."""

    def __init__(self, numerator, denominator):
        self.b, self.a = numerator, denominator
        self.e = np.zeros(len(numerator))
        self.c = np.zeros(max(len(denominator) - 1, 0))

    def __call__(self, e: float) -> float:
        self.e = np.roll(self.e, 1)
        self.e[0] = e
        c = float(self.b @ self.e - self.a[1:] @ self.c)
        if self.c.size:
            self.c = np.roll(self.c, 1)
            self.c[0] = c
        return c


def _from_polynomials(num, den, sample_time) -> Controller:
    """``num / den`` given in powers of ``z`` (highest first), as polynomials in ``z^-1``."""
    num = np.atleast_1d(np.asarray(num, dtype=float)).ravel()
    den = np.atleast_1d(np.asarray(den, dtype=float)).ravel()
    den = np.trim_zeros(den, "f")
    num = np.trim_zeros(num, "f") if np.any(num) else np.zeros(1)
    if den.size == 0:
        raise ValueError("controller must have a non-zero denominator")
    if num.size > den.size:
        raise ValueError("controller must be proper (a causal discrete-time system)")
    # multiply by z^-(len(den) - 1): coefficients of z^-k, numerator padded for its relative degree
    numerator = np.concatenate([np.zeros(den.size - num.size), num]) / den[0]
    return Controller(numerator, den / den[0], sample_time)


def as_controller(controller, name: str = "controller") -> Controller:
    """A :class:`Controller` from a gain, an FIR array, a ``scipy.signal.dlti`` or a python-control system.

    Parameters
    ----------
    controller : float, array-like, scipy.signal.dlti, control.LTI or Controller
        A number is a static gain; a 1-D array the FIR coefficients of
        ``z^0, z^-1, ...``; a system must be discrete-time, single input and
        single output, and proper.
    name : str
        The argument's name in error messages.

    Returns
    -------
    Controller

    Examples
    --------
    >>> from scipy import signal
    >>> from gpmultirate.closedloop import as_controller
    >>> c = as_controller(signal.dlti([1.0], [1.0, -0.5], dt=0.01))  # 1 / (z - 0.5)
    >>> c.numerator.tolist(), c.denominator.tolist(), c.sample_time
    ([0.0, 1.0], [1.0, -0.5], 0.01)
    """
    if isinstance(controller, Controller):
        return controller
    if isinstance(controller, numbers.Real) and not isinstance(controller, bool):
        if not np.isfinite(controller):
            raise ValueError(f"{name} must be finite; got {controller!r}")
        return Controller(np.array([float(controller)]), np.array([1.0]))
    if isinstance(controller, signal.dlti):
        dt = controller.dt
        if dt is None or dt is False:
            raise ValueError(f"{name} must be a discrete-time system")
        tf = controller.to_tf()
        if np.ndim(tf.num) > 1 and np.shape(tf.num)[0] != 1:
            raise ValueError(f"{name} must be single input, single output")
        return _from_polynomials(tf.num, tf.den, None if dt is True else float(dt))
    if isinstance(controller, signal.lti):
        raise ValueError(f"{name} must be discrete-time; got a continuous-time system")
    module = type(controller).__module__ or ""
    if module.startswith("control"):
        return _from_control(controller, name)
    try:
        fir = np.asarray(controller, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(
            f"{name} must be a gain, an FIR array, a scipy.signal.dlti or a python-control "
            f"system; got {type(controller).__name__}") from None
    if fir.ndim != 1 or fir.size == 0 or not np.all(np.isfinite(fir)):
        raise ValueError(f"{name} as an array must be a non-empty finite 1-D FIR")
    return Controller(fir.copy(), np.array([1.0]))


def _from_control(system, name: str) -> Controller:
    """A python-control ``TransferFunction`` or ``StateSpace`` (discrete, SISO)."""
    from gpmultirate.optional import import_control

    control = import_control()
    if not system.isdtime():
        raise ValueError(f"{name} must be a discrete-time system")
    if system.ninputs != 1 or system.noutputs != 1:
        raise ValueError(f"{name} must be single input, single output")
    tf = control.tf(system)
    dt = None if system.dt is True else float(system.dt)
    return _from_polynomials(tf.num[0][0], tf.den[0][0], dt)
