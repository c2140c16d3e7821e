r"""Slow samples of a sensor with a known first-order response.

The sensor does not read the fast output ``y`` itself but its first-order
low-pass, started at rest,

.. math::

    y_s(n) = a \, y_s(n - 1) + (1 - a) \, y(n), \qquad
    y(n) = \sum_{j < P} g(j) \, u(n - j),

with a known ``a`` in ``[0, 1)`` (unit gain at zero frequency; ``a = 0`` is
no filter), and reports ``y_s`` at the slow instants.  Both the sensor's
filter and the convolution are linear and time-invariant from rest, so they
commute: ``y_s(n) = sum_j g(j) v(n - j)`` with ``v`` the input through the
sensor's filter, ``v(n) = a v(n - 1) + (1 - a) u(n)``.  The regressor is
then the paper's eq. (8) with ``v`` in place of ``u``, and every structure
of a convolution's regressor (the diagonal recursion of shift-scaled
kernels on uniform samples, the FFT Gram of a long record) applies as it
is.  :class:`FilteredConvolution` is that observation.
"""

from __future__ import annotations

import numbers

import numpy as np
from scipy import signal

from gpmultirate.observations.base import Observation, UniformSampling
from gpmultirate.observations.sampled import SampledConvolution
from gpmultirate.validation import check_inputs

__all__ = ["FilteredConvolution", "check_pole", "sensor_filtered"]


def check_pole(value, name: str = "pole") -> float:
    """Return ``value`` as the pole of a stable first-order low-pass: a real in ``[0, 1)``.

    Examples
    --------
    >>> check_pole(0.5)
    0.5
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a real number in [0, 1); got {value!r}")
    value = float(value)
    if not (np.isfinite(value) and 0.0 <= value < 1.0):
        raise ValueError(
            f"{name} must be in [0, 1) (the sensor's response y_s(n) = a y_s(n - 1) "
            f"+ (1 - a) y(n) must be stable); got {value!r}"
        )
    return value


def sensor_filtered(x, pole: float) -> np.ndarray:
    """``x`` through the sensor's response from rest: ``v(n) = a v(n - 1) + (1 - a) x(n)``.

    Parameters
    ----------
    x : array-like of shape (N,) or (N, n)
        Filtered along the first axis.
    pole : float
        ``a``, in ``[0, 1)``.

    Returns
    -------
    ndarray, shaped as ``x`` (a new array)

    Examples
    --------
    >>> sensor_filtered([1.0, 0.0, 0.0], 0.5)
    array([0.5  , 0.25 , 0.125])
    """
    pole = check_pole(pole)
    return signal.lfilter([1.0 - pole], [1.0, -pole], np.asarray(x, dtype=float), axis=0)


class FilteredConvolution(Observation):
    """The slow samples of a sensor with a known first-order response (see the module).

    Sample ``m`` is ``y_s(n_m)``, ``y_s(n) = a y_s(n - 1) + (1 - a) y(n)``
    from rest, ``y`` the fast output of the input(s) ``u`` (zero before the
    record).

    Parameters
    ----------
    u : array-like of shape (N,) or (N, n_inputs)
        The fast-rate input(s).
    sample_indices : array-like of int
        Strictly increasing fast-sample indices in ``0..N-1``.
    order : int
        ``P``: the response is zero beyond lag ``P``.
    pole : float
        ``a`` in ``[0, 1)``, the sensor's pole per fast sample
        (``exp(-1 / tau)`` for a time constant of ``tau`` fast samples).

    Attributes
    ----------
    u : ndarray
        The input as given (read-only).
    filtered_input : ndarray
        ``v``: the input through the sensor's response (read-only).
    sample_indices : ndarray

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate.kernels import DC, observe
    >>> u = np.random.default_rng(0).standard_normal(30)
    >>> sensor = FilteredConvolution(u, [5, 11, 17, 23, 29], order=8, pole=0.6)
    >>> g = 0.7 ** np.arange(8.0)
    >>> y = np.convolve(u, g)[:30]
    >>> y_s = np.zeros(30)
    >>> for n in range(30):
    ...     y_s[n] = 0.6 * (y_s[n - 1] if n else 0.0) + 0.4 * y[n]
    >>> bool(np.allclose(sensor.matvec(g), y_s[[5, 11, 17, 23, 29]]))
    True
    >>> kernel = C(2.0) * DC(0.8, 0.6)
    >>> S = observe(kernel, sensor).covariance()
    >>> bool(np.allclose(S, sensor.matrix @ kernel(sensor.lags) @ sensor.matrix.T))
    True
    """

    def __init__(self, u, sample_indices, order: int, pole: float):
        inputs = check_inputs(u, "u")
        self.pole = check_pole(pole)
        filtered = sensor_filtered(inputs, self.pole)
        # the regressor of the filtered input is the whole structure: a convolution's
        self._convolution = SampledConvolution(filtered, sample_indices, order)
        inputs.setflags(write=False)
        self.u = inputs[:, 0] if inputs.shape[1] == 1 else inputs
        self.filtered_input = self._convolution.u
        self.order = self._convolution.order
        self.n_inputs = self._convolution.n_inputs
        self.sample_indices = self._convolution.sample_indices

    @property
    def n_samples(self) -> int:
        return self._convolution.n_samples

    @property
    def n_outputs(self) -> int:
        return self._convolution.n_outputs

    @property
    def slow_factor(self) -> int:
        """The median spacing of the instants."""
        return self._convolution.slow_factor

    @property
    def uniform_sampling(self) -> UniformSampling | None:
        """The uniform grid of the instants, with the filtered input (the diagonal recursion)."""
        return self._convolution.uniform_sampling

    @property
    def matrix(self) -> np.ndarray:
        """The regressor: the convolution regressor of the filtered input (read-only)."""
        return self._convolution.matrix

    def regressor_rows(self, start: int, stop: int) -> np.ndarray:
        return self._convolution.regressor_rows(start, stop)

    def regressor_view(self) -> np.ndarray:
        return self._convolution.regressor_view()

    def structured_gram(self, y=None):
        return self._convolution.structured_gram(y)

    def __repr__(self) -> str:
        return (f"FilteredConvolution(N={self.n_samples}, M={self.n_outputs}, "
                f"order={self.order}, pole={self.pole:g})")
