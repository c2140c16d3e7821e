r"""The lag kernels between integer lags: their semiseparable structure.

A slow sample taken between two fast ticks sees the impulse response at
the lags ``k + d`` (``k = 0..P-1``, ``0 <= d < 1`` the sample's offset
from its tick).  The shift-scaled kernels (TC, DC, SS) are covariances of
processes with a finite state (one state for TC and DC with ``beta >= 0``,
two for DC with ``beta < 0`` and for SS), so their covariance is
semiseparable: for integer lags ``k > l`` and offsets ``d, e`` in
``[0, 1)``,

.. math::

    k(k + d, l + e) = \sum_r A_r[k, l] \, f_r(d) \, h_r(e),
    \qquad A_r[k, l] = p_r[k] \, q_r[l] \, c_r^{k - l},

and on equal integer lags ``k(k + d, k + e) = c^k k(d, e)`` (``c`` the
shift scale).  :func:`offset_structure` returns these pieces; a timed
observation then forms the covariance of its samples from ``P x P``
matrices and vectors over the samples, never from the kernel on every pair
of real lags.

Every function here is written for complex hyperparameter values too, so
that the derivative with respect to a hyperparameter is exact to rounding by
the complex step, ``d F / d x = Im F(x + i h) / h``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import signal

__all__ = ["OffsetStructure", "lower_matrix", "offset_structure", "supports_offsets",
           "times_lower"]


class OffsetStructure(NamedTuple):
    """The pieces of a shift-scaled kernel between integer lags (see the module).

    Attributes
    ----------
    lower : list of (p, q, c, f, h)
        ``A_r[k, l] = p[k] q[l] c^(k - l)`` for ``k > l`` (``p``, ``q``
        vectors over the lags ``0..P-1``, ``|c| <= 1``), so that products
        with ``A_r`` are first-order recursions (:func:`times_lower`);
        ``f`` and ``h`` callables of the offsets.
    scale : complex or float
        ``c``: ``k(k + d, k + e) = c^k k(d, e)``.
    base : callable
        ``(d, e) -> k(d_i, e_j)``, the kernel at the offsets themselves.
    """

    lower: list
    scale: complex
    base: object


def supports_offsets(kernel) -> bool:
    """Whether :func:`offset_structure` knows ``kernel`` (TC, DC or SS, by its class)."""
    from gpmultirate.kernels.lag import DC, SS, TC

    return type(kernel) in (TC, DC, SS)


def lower_matrix(p, q, c) -> np.ndarray:
    """The strictly lower triangular ``A[k, l] = p[k] q[l] c^(k - l)`` (for tests and reading)."""
    k = np.arange(p.shape[0])
    gap = np.subtract.outer(k, k)
    return np.where(gap > 0, np.outer(p, q) * np.asarray(c) ** np.maximum(gap, 0), 0.0)


def times_lower(X, p, q, c, transpose: bool = False) -> np.ndarray:
    """``X @ A`` (or ``X @ A^T``) for ``A = lower_matrix(p, q, c)``, by a first-order recursion.

    ``(X A)[:, l] = q[l] sum_{k > l} X[:, k] p[k] c^(k - l)``: a recursion
    from the last lag down, ``O(M P)`` instead of ``O(M P^2)``; ``|c| <= 1``
    keeps it stable.
    """
    weights = q if transpose else p
    Z = X * weights
    if not transpose:
        Z = Z[:, ::-1]
    # s_j = c (s_{j-1} + Z_{j-1}): the sum over the earlier entries, weighted c^distance
    s = signal.lfilter([0.0, c], [1.0, -c], Z, axis=1)
    if not transpose:
        s = s[:, ::-1]
    return s * (p if transpose else q)


def _positive(x):
    """``|x|`` for a real or a complex-step value (the sign of its real part)."""
    return x if np.real(x) >= 0 else -x


def offset_structure(kernel, values: dict, order: int) -> OffsetStructure:
    """The semiseparable pieces of TC, DC or SS at the hyperparameter ``values``.

    Parameters
    ----------
    kernel : TC, DC or SS
        Only its class is read; the values come from ``values``.
    values : dict
        ``{name: value}``, real or complex (for the complex step).
    order : int
        ``P``: the pieces are on the lags ``0..P-1``.

    Returns
    -------
    OffsetStructure

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.kernels import DC
    >>> kernel = DC(alpha=0.8, beta=-0.6)
    >>> found = offset_structure(kernel, {"alpha": 0.8, "beta": -0.6}, 4)
    >>> d, e = np.array([0.3]), np.array([0.7])
    >>> value = sum(lower_matrix(p, q, c)[3, 1] * f(d) * h(e) for p, q, c, f, h in found.lower)
    >>> bool(np.isclose(value[0], kernel([[3.3]], [[1.7]])[0, 0]))
    True
    """
    from gpmultirate.kernels.lag import DC, SS, TC

    k = np.arange(order, dtype=float)
    ones = np.ones(order)
    if type(kernel) is TC:
        alpha = values["alpha"]
        return OffsetStructure(
            [(alpha**k, ones, 1.0, lambda d: alpha**d, lambda e: np.ones_like(e, dtype=float))],
            alpha,
            lambda d, e: alpha ** np.maximum.outer(d, e),
        )
    if type(kernel) is DC:
        alpha, beta = values["alpha"], values["beta"]
        b = _positive(beta)
        negative = np.real(beta) < 0
        # A[k, l] = alpha^((k + l) / 2) beta^(k - l): |beta|^(k - l) times (-1)^(k - l) for beta < 0
        half = alpha ** (k / 2.0)

        def base(d, e):
            distance = np.abs(np.subtract.outer(d, e))
            rho = b**distance
            if negative:
                rho = rho * np.cos(np.pi * distance)
            return alpha ** (np.add.outer(d, e) / 2.0) * rho

        def rising(d):
            return alpha ** (d / 2.0) * b**d

        def falling(e):
            return alpha ** (e / 2.0) * b ** (-e)

        if not negative:
            return OffsetStructure([(half, half, beta, rising, falling)], alpha, base)
        # cos(pi (n + d - e)) = (-1)^n (cos(pi d) cos(pi e) + sin(pi d) sin(pi e))
        return OffsetStructure(
            [
                (half, half, beta, lambda d: rising(d) * np.cos(np.pi * d),
                 lambda e: falling(e) * np.cos(np.pi * e)),
                (half, half, beta, lambda d: rising(d) * np.sin(np.pi * d),
                 lambda e: falling(e) * np.sin(np.pi * e)),
            ],
            alpha,
            base,
        )
    if type(kernel) is SS:
        alpha = values["alpha"]

        def base(d, e):
            longest = np.maximum.outer(d, e)
            return (alpha ** (np.add.outer(d, e) + longest) / 2.0
                    - alpha ** (3.0 * longest) / 6.0)

        # t > s: alpha^(2t + s) / 2 - alpha^(3t) / 6
        return OffsetStructure(
            [
                (alpha ** (2.0 * k), alpha**k / 2.0, 1.0,
                 lambda d: alpha ** (2.0 * d), lambda e: alpha**e),
                (alpha ** (3.0 * k), -ones / 6.0, 1.0,
                 lambda d: alpha ** (3.0 * d), lambda e: np.ones_like(e, dtype=float)),
            ],
            alpha**3,
            base,
        )
    raise TypeError(f"no offset structure for {type(kernel).__name__}")
