"""``c S + gamma I`` for every scale and noise level at once, from one eigendecomposition.

What the scale prefit of tuning (:func:`relative_spectrum`) and the
resonance search of ``kernel="auto"`` (:class:`SpectralCovariance`) scan.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from gpmultirate.covariance.base import cholesky_or_raise
from gpmultirate.exceptions import NotPositiveDefinite

__all__ = ["SpectralCovariance", "relative_spectrum"]


class SpectralCovariance:
    """``c S + gamma I``, and a low-rank update of it, for any ``c`` and ``gamma``.

    With ``S = Q diag(s) Q^T`` decomposed once (the eigenvalues clipped at
    zero), ``c S + gamma I = Q diag(c s + gamma) Q^T``: the quadratic form
    and the log-determinant cost ``O(M)`` for each scale ``c`` and noise
    level ``gamma``, with ``y`` rotated once (``Q^T y``).  A low-rank summand
    ``W W^T`` given in the rotated coordinates is added through the
    capacitance ``I + W^T diag(c s + gamma)^{-1} W`` (Woodbury and the
    matrix determinant lemma).

    Parameters
    ----------
    S : ndarray of shape (M, M)
        The kernel's data covariance without noise (symmetric, PSD).
    y : ndarray of shape (M,)
        The data.

    Examples
    --------
    >>> import numpy as np
    >>> A = np.array([[2.0, 1.0], [1.0, 2.0]])
    >>> spectral = SpectralCovariance(A, np.array([1.0, 0.0]))
    >>> d = spectral.diagonal(0.5, 0.1)
    >>> quad = float(np.sum(spectral.rotated_y**2 / d))
    >>> bool(np.isclose(quad, np.linalg.solve(0.5 * A + 0.1 * np.eye(2), [1.0, 0.0])[0]))
    True
    """

    def __init__(self, S: np.ndarray, y: np.ndarray):
        s, Q = linalg.eigh(S, check_finite=False)
        self.eigenvalues = np.maximum(s, 0.0)
        self.vectors = Q
        self.rotated_y = Q.T @ y

    def diagonal(self, scale: float, noise_level: float) -> np.ndarray:
        """The eigenvalues of ``scale * S + noise_level * I``."""
        return scale * self.eigenvalues + noise_level

    def rotate(self, A: np.ndarray) -> np.ndarray:
        """``Q^T A``: a matrix of the data space in the eigenvectors' coordinates."""
        return self.vectors.T @ A



def relative_spectrum(R: np.ndarray, S: np.ndarray, y: np.ndarray):
    """``c S + R`` for every ``c``: the eigenvalues ``s`` of ``L^{-1} S L^{-T}`` and ``z^2``.

    With ``R = L L^T`` (positive definite) and ``L^{-1} S L^{-T} = Q diag(s) Q^T``
    (``s`` clipped at zero), ``z = Q^T L^{-1} y``: the log evidence of ``c``
    is ``-1/2 sum(z^2 / (1 + c s) + log(1 + c s))`` up to a constant.
    Returns ``(s, z^2)``, or None when ``R`` is not positive definite.

    Examples
    --------
    >>> import numpy as np
    >>> R, S, y = np.diag([1.0, 4.0]), np.diag([2.0, 2.0]), np.array([1.0, 2.0])
    >>> s, z2 = relative_spectrum(R, S, y)
    >>> s.tolist(), z2.tolist()
    ([0.5, 2.0], [1.0, 1.0])
    """
    try:
        L = cholesky_or_raise(R)
    except NotPositiveDefinite:
        return None
    A = linalg.solve_triangular(L, S, lower=True, check_finite=False)
    A = linalg.solve_triangular(L, A.T, lower=True, check_finite=False)
    s, Q = linalg.eigh(0.5 * (A + A.T), check_finite=False)
    z2 = (Q.T @ linalg.solve_triangular(L, y, lower=True, check_finite=False)) ** 2
    return np.maximum(s, 0.0), z2
