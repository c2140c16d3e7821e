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


__all__ = ["OffsetStructure", "dc_pieces", "exp_divided_difference", "lower_matrix",
           "offset_structure", "ordered_exponential_integral", "ss_pieces", "tc_pieces",
           "times_lower"]

#: below this spread of the points the divided differences of exp are Taylor series
_SERIES_SPREAD = 0.5
_SERIES_TERMS = 24


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
    rates : list of (complex, complex) or None
        ``f_r(d) = exp(lambda_r d)`` and ``h_r(e) = exp(mu_r e)``: the rates
        ``(lambda_r, mu_r)`` of each lower piece, when every piece is one
        exponential (TC, DC with ``beta > 0``, SS), for the closed-form
        integrals over exposure windows (:func:`ordered_exponential_integral`);
        None otherwise.
    """

    lower: list
    scale: complex
    base: object
    rates: list | None = None


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
    """The semiseparable pieces of a shift-scaled kernel at the hyperparameter ``values``.

    The kernel answers for its pieces (its method ``offset_structure``:
    :func:`tc_pieces` for TC, :func:`dc_pieces` for DC, :func:`ss_pieces`
    for SS).

    Parameters
    ----------
    kernel : TC, DC or SS
        Only its kind is read; the values come from ``values``.
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
    return kernel.offset_structure(values, order)


def tc_pieces(values: dict, order: int) -> OffsetStructure:
    """TC's pieces: ``k(t, s) = alpha^max(t, s)``, one exponential."""
    k = np.arange(order, dtype=float)
    ones = np.ones(order)
    alpha = values["alpha"]
    return OffsetStructure(
        [(alpha**k, ones, 1.0, lambda d: alpha**d, lambda e: np.ones_like(e, dtype=float))],
        alpha,
        lambda d, e: alpha ** np.maximum.outer(d, e),
        [(np.log(alpha), 0.0)],
    )


def dc_pieces(values: dict, order: int) -> OffsetStructure:
    """DC's pieces: one exponential for ``beta > 0``, two for ``beta < 0`` (the cosine's)."""
    k = np.arange(order, dtype=float)
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
        log_a, log_b = np.log(alpha) / 2.0, np.log(b)
        return OffsetStructure([(half, half, beta, rising, falling)], alpha, base,
                               [(log_a + log_b, log_a - log_b)])
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


def ss_pieces(values: dict, order: int) -> OffsetStructure:
    """SS's pieces: two exponentials (see :func:`offset_structure`)."""
    k = np.arange(order, dtype=float)
    ones = np.ones(order)
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
        [(2.0 * np.log(alpha), np.log(alpha)), (3.0 * np.log(alpha), 0.0)],
    )


def exp_divided_difference(z0, z1, z2):
    """The second divided difference ``exp[z0, z1, z2]``, elementwise, for real or complex points.

    It is the integral of ``exp`` of the affine function taking the values
    ``z0, z1, z2`` at the corners of the triangle ``0 <= v <= u <= 1``
    (Hermite-Genocchi).  Points that spread by less than ``1/2`` take a
    Taylor series about ``z0``; otherwise the recursion divides by the
    largest spread.  Both are analytic in the points, so the complex step
    differentiates them.

    Examples
    --------
    >>> import numpy as np
    >>> z = np.array([0.1]), np.array([0.7]), np.array([2.0])
    >>> exact = ((np.exp(2.0) - np.exp(0.7)) / 1.3 - (np.exp(0.7) - np.exp(0.1)) / 0.6) / 1.9
    >>> bool(np.isclose(exp_divided_difference(*z)[0], exact, rtol=1e-13))
    True
    >>> float(exp_divided_difference(np.zeros(1), np.zeros(1), np.zeros(1))[0])
    0.5
    """
    z0, z1, z2 = np.broadcast_arrays(*(np.asarray(z) for z in (z0, z1, z2)))
    dtype = np.result_type(z0, z1, z2, float)
    out = np.empty(z0.shape, dtype=dtype)
    w1, w2 = z1 - z0, z2 - z0
    spread = np.maximum(np.maximum(np.abs(w1), np.abs(w2)), np.abs(z2 - z1))
    near = spread < _SERIES_SPREAD
    if np.any(near):
        a, b = w1[near], w2[near]
        # sum_k h_k(a, b) / (k + 2)!, h_k the complete homogeneous polynomial of degree k
        # (|h_k| <= (k + 1) spread^k): as many terms as the largest spread needs
        largest = float(np.max(spread[near]))
        terms, bound, k = 1, 0.5, 0
        while k < _SERIES_TERMS and bound > 1e-18 * 0.5:
            k += 1
            bound = bound * largest * (k + 1) / k / (k + 2)
            terms = k + 1
        h = np.ones_like(a)
        power = np.ones_like(a)
        total = h / 2.0
        factorial = 2.0
        for k in range(1, terms):
            power = power * a
            h = b * h + power
            factorial *= k + 2
            total = total + h / factorial
        out[near] = np.exp(z0[near]) * total
    far = ~near
    if np.any(far):
        x = np.stack([z0[far], z1[far], z2[far]])
        # the two points farthest apart go first and last
        gaps = np.abs(np.stack([x[1] - x[0], x[2] - x[0], x[2] - x[1]]))
        pick = np.argmax(gaps, axis=0)
        first = np.choose(pick, [x[0], x[0], x[1]])
        middle = np.choose(pick, [x[2], x[1], x[0]])
        last = np.choose(pick, [x[1], x[2], x[2]])
        out[far] = (_exp_first(middle, last) - _exp_first(first, middle)) / (last - first)
    return out


def _exprel(z):
    """``(exp(z) - 1) / z``, analytic: ``expm1(z) / z``, a Taylor series very near 0.

    NumPy's ``expm1`` of a complex number is accurate in both parts, so the
    complex step differentiates it.
    """
    z = np.asarray(z)
    out = np.empty(z.shape, dtype=np.result_type(z, float))
    near = np.abs(z) < 1e-5
    a = z[near]
    out[near] = 1.0 + a * (0.5 + a * (1.0 / 6.0 + a / 24.0))
    b = z[~near]
    out[~near] = np.expm1(b) / b
    return out


def _exp_first(z0, z1):
    """``exp[z0, z1] = exp(z0) (exp(z1 - z0) - 1) / (z1 - z0)``."""
    return np.exp(z0) * _exprel(z1 - z0)


def _exp_integral(rate, start, stop):
    """``int_start^stop exp(rate x) dx`` for ``stop >= start``."""
    return (stop - start) * _exp_first(rate * start, rate * stop)


def ordered_exponential_integral(lam, mu, a1, b1, a2, b2):
    """``int_{x in [a1, b1]} int_{y in [a2, b2], y < x} exp(lam x + mu y) dy dx``, elementwise.

    In closed form (:func:`exp_divided_difference`): the part of ``[a1, b1]``
    beyond ``b2`` sees the whole of ``[a2, b2]``; the overlap ``[s, t]`` of
    the two intervals sees ``[a2, s]`` and the triangle ``s <= y < x <= t``.
    Real or complex rates (the complex step).

    Examples
    --------
    >>> import numpy as np
    >>> from scipy import integrate
    >>> value = ordered_exponential_integral(-0.3, 0.2, 0.1, 0.9, 0.0, 0.6)
    >>> reference = integrate.dblquad(lambda y, x: np.exp(-0.3 * x + 0.2 * y), 0.1, 0.9,
    ...                               0.0, lambda x: min(x, 0.6), epsabs=1e-13)[0]
    >>> bool(np.isclose(value, reference, rtol=1e-10))
    True
    """
    lam, mu, a1, b1, a2, b2 = np.broadcast_arrays(
        *(np.asarray(v) for v in (lam, mu, a1, b1, a2, b2)))
    beyond = np.clip(b2, a1, b1)
    whole = _exp_integral(lam, beyond, b1) * _exp_integral(mu, a2, b2)
    s = np.maximum(a1, a2)
    t = np.maximum(np.minimum(b1, b2), s)
    length = t - s
    before = _exp_integral(mu, a2, s) * _exp_integral(lam, s, t)
    total = lam + mu
    triangle = (np.exp(total * s) * length**2
                * exp_divided_difference(np.zeros_like(total * s), lam * length,
                                         total * length))
    return whole + before + triangle
