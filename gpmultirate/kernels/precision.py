r"""Tridiagonal prior precisions: the DC kernel's inverse.

The DC kernel at the lags ``0..P-1`` is ``K = D T D`` with
``D = diag(alpha^(t/2))`` and ``T[i, j] = beta^|i - j|``, the covariance of a
stationary first-order autoregression, whose inverse is tridiagonal for any
``-1 < beta < 1``:

.. math::

   T^{-1} = \frac{1}{1 - \beta^2}
   \begin{bmatrix} 1 & -\beta & & \\ -\beta & 1 + \beta^2 & \ddots & \\
   & \ddots & \ddots & -\beta \\ & & -\beta & 1 \end{bmatrix},
   \qquad \log\det K = \log\alpha \sum_t t + (P - 1) \log(1 - \beta^2).

So ``Q = K^{-1} = D^{-1} T^{-1} D^{-1}`` and its derivatives are
tridiagonal too.  A term whose prior has such a precision offers it
(:meth:`~gpmultirate.kernels.ObservedTerm.precision`), and the evidence of a
square or reduced observation can then be computed in the parameter space
with only the tridiagonal band of the posterior covariance
(:func:`gpmultirate.inference.log_marginal_likelihood`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["TridiagonalPrecision", "dc_precision"]

#: the largest ``log`` of the precision's dynamic range ``alpha^-(P-1)``
#: accepted (beyond it the entries would approach overflow)
MAX_LOG_RANGE = 500.0


class TridiagonalPrecision(NamedTuple):
    """``Q = K^{-1}`` tridiagonal, with its derivatives in the free ``theta`` entries.

    Attributes
    ----------
    diagonal : ndarray of shape (P,)
    off_diagonal : ndarray of shape (P - 1,)
        ``Q[t, t + 1]``.
    log_det_covariance : float
        ``log det K``.
    derivatives : list of (ndarray, ndarray)
        ``(diagonal, off_diagonal)`` of ``dQ / d theta_j``, one per free
        hyperparameter, in the order of ``theta``.
    log_det_gradient : ndarray
        ``d log det K / d theta_j``.
    """

    diagonal: np.ndarray
    off_diagonal: np.ndarray
    log_det_covariance: float
    derivatives: list
    log_det_gradient: np.ndarray

    def dense(self) -> np.ndarray:
        """``Q`` as a dense matrix (for checks)."""
        return tridiagonal_dense(self.diagonal, self.off_diagonal)

    def times(self, x: np.ndarray) -> np.ndarray:
        """``Q @ x`` for ``x`` of shape ``(P,)`` or ``(P, k)``, in ``O(P k)``.

        Examples
        --------
        >>> Q = dc_precision(0.8, 0.5, 0.5, 4)
        >>> x = np.arange(8.0).reshape(4, 2)
        >>> bool(np.allclose(Q.times(x), Q.dense() @ x))
        True
        """
        shape = (-1,) + (1,) * (np.ndim(x) - 1)
        off = self.off_diagonal.reshape(shape)
        out = self.diagonal.reshape(shape) * x
        out[:-1] += off * x[1:]
        out[1:] += off * x[:-1]
        return out

    def scaled(self, value: float, free: bool, first: bool) -> "TridiagonalPrecision":
        """The precision of ``value * K``; with ``free``, the derivative in ``log(value)`` joins.

        ``first``: the amplitude comes before the other entries of ``theta``.
        """
        scale = 1.0 / value
        derivatives = [(scale * d, scale * o) for d, o in self.derivatives]
        log_det_gradient = self.log_det_gradient
        if free:  # d(Q / c) / d log c = -Q / c;  d log det(c K) / d log c = P
            own = (-scale * self.diagonal, -scale * self.off_diagonal)
            derivatives = [own] + derivatives if first else derivatives + [own]
            size = np.array([float(self.diagonal.shape[0])])
            parts = [size, log_det_gradient] if first else [log_det_gradient, size]
            log_det_gradient = np.concatenate(parts)
        return TridiagonalPrecision(
            scale * self.diagonal, scale * self.off_diagonal,
            self.log_det_covariance + self.diagonal.shape[0] * np.log(value),
            derivatives, log_det_gradient,
        )


def tridiagonal_dense(diagonal: np.ndarray, off_diagonal: np.ndarray) -> np.ndarray:
    """The symmetric tridiagonal matrix with these diagonals.

    Examples
    --------
    >>> tridiagonal_dense(np.array([2.0, 3.0]), np.array([-1.0]))
    array([[ 2., -1.],
           [-1.,  3.]])
    """
    return np.diag(diagonal) + np.diag(off_diagonal, 1) + np.diag(off_diagonal, -1)


def dc_precision(alpha: float, beta: float, beta_chain: float, order: int,
                 free: tuple = ("alpha", "beta")) -> TridiagonalPrecision | None:
    """The tridiagonal precision of the DC kernel at the lags ``0..order-1``, or None.

    Parameters
    ----------
    alpha, beta : float
        ``0 < alpha <= 1``, ``|beta| < 1``.
    beta_chain : float
        ``d beta / d theta_beta``, from the kernel (the one place that knows
        how ``beta`` is parametrized).
    order : int
    free : tuple of str
        The free hyperparameters, in the order of ``theta``.

    Returns
    -------
    TridiagonalPrecision or None
        None where the inverse does not exist (``|beta| = 1``) or its
        entries ``alpha^-t`` would approach overflow.

    Examples
    --------
    >>> from gpmultirate.kernels import DC
    >>> Q = dc_precision(0.8, 0.5, 0.5, 4).dense()
    >>> K = DC(0.8, 0.5)(np.arange(4.0)[:, None])
    >>> bool(np.allclose(Q @ K, np.eye(4)))
    True
    """
    P = int(order)
    if not abs(beta) < 1.0 or (P - 1) * -np.log(alpha) > MAX_LOG_RANGE:
        return None
    t = np.arange(P, dtype=float)
    one_minus = 1.0 - beta * beta
    inner = np.full(P, (1.0 + beta * beta) / one_minus)
    inner[[0, -1]] = 1.0 / one_minus
    if P == 1:
        inner[:] = 1.0
    off = np.full(P - 1, -beta / one_minus)
    envelope = alpha ** -t                    # 1 / d_t^2
    off_envelope = alpha ** -(t[:-1] + 0.5)   # 1 / (d_t d_{t+1})
    diagonal = inner * envelope
    off_diagonal = off * off_envelope
    log_det = float(np.log(alpha) * t.sum() + (P - 1) * np.log(one_minus))
    derivatives, log_det_gradient = [], []
    for name in free:
        if name == "alpha":  # theta = log(alpha): alpha^-s -> -s alpha^-s
            derivatives.append((-t * diagonal, -(t[:-1] + 0.5) * off_diagonal))
            log_det_gradient.append(t.sum())
        elif name == "beta":  # d/d beta, times d beta / d theta
            d_inner = np.full(P, 4.0 * beta / one_minus**2)
            d_inner[[0, -1]] = 2.0 * beta / one_minus**2
            if P == 1:
                d_inner[:] = 0.0
            d_off = np.full(P - 1, -(1.0 + beta * beta) / one_minus**2)
            derivatives.append((beta_chain * d_inner * envelope, beta_chain * d_off * off_envelope))
            log_det_gradient.append(-(P - 1) * 2.0 * beta / one_minus * beta_chain)
        else:
            raise ValueError(f"free must name 'alpha' or 'beta'; got {name!r}")
    return TridiagonalPrecision(diagonal, off_diagonal, log_det, derivatives,
                                np.array(log_det_gradient, dtype=float))
