"""Noise models of the slow samples: white noise, and disturbances over the sample instants.

The data are ``y = Phi g + v`` with ``v ~ N(0, N)``.  Today's model is white,
``N = gamma I``.  Measured records carry more: drift, floor vibration, a
periodic disturbance, a sensor's own filtering.  Such a disturbance is a
Gaussian process over the *instants* of the slow samples, measured in fast
samples (``Matern(length_scale=10)`` spans ten fast samples), so:

* :class:`KernelNoise`: ``N = k(t, t)`` for a scikit-learn kernel ``k`` over
  the instants ``t`` -- typically ``WhiteKernel() + C * Matern(nu=1.5)``, or a
  sum with an ``ExpSineSquared`` for a periodic disturbance.  Independent
  records give a block-diagonal ``N``.  Dense: ``N`` and its derivatives in
  the log hyperparameters are ``M x M``.
* :class:`AR1Noise`: a Matérn 1/2 (exponential) process on a uniform grid of
  spacing ``F`` is an AR(1) process with pole ``a = exp(-F / length_scale)``.
  Its precision is tridiagonal and prewhitening is exact: with
  ``w_0 = sqrt(1 - a^2) v_0``, ``w_m = v_m - a v_{m-1}`` the whitened
  samples are independent with variance ``sigma^2 (1 - a^2)``, and the
  whitened data ``W y = W Phi g + W v`` are a white-noise problem for the
  whitened regressor.  :func:`ar1_log_evidence` uses this: the data enter only
  through ``P x P`` products of the regressor (:class:`AR1Statistics`,
  computed once), so the long-record reduction is kept and each evaluation
  costs ``O(P^3)``.

:func:`dense_log_evidence` and :func:`dense_posterior` are the reference
formulas for any noise model (the data-space route, eq. 15 and 19 with
``N`` in place of ``gamma I``), against which the structured route is
tested.
"""

from __future__ import annotations

import numbers

import numpy as np
from scipy import linalg
from sklearn.gaussian_process.kernels import (
    ConstantKernel,
    Kernel,
    Matern,
    Product,
    Sum,
    WhiteKernel,
)

__all__ = [
    "AR1_DISTURBANCE",
    "NAMED_DISTURBANCES",
    "AR1Noise",
    "AR1Statistics",
    "KernelNoise",
    "ar1_evidence_gain",
    "ar1_log_evidence",
    "dense_log_evidence",
    "dense_posterior",
    "disturbance_evidence_gain",
    "make_noise",
    "noise_instants",
    "white_level",
]

#: The named disturbances of ``make_noise``: Matérn smoothness ``nu`` of each.
NAMED_DISTURBANCES = {"matern12": 0.5, "matern32": 1.5}
#: The named choice of a pure AR(1) noise ``C * Matern(nu=0.5)`` without white
#: noise: on one uniform grid with more samples than coefficients it is tuned
#: through its tridiagonal precision (:class:`gpmultirate.covariance.AR1Covariance`).
AR1_DISTURBANCE = "ar1"

LOG_2PI = np.log(2.0 * np.pi)


def _instant_blocks(instants) -> list[np.ndarray]:
    """The instants as a list of 1-D float arrays, one per record."""
    if isinstance(instants, (list, tuple)) and instants and np.ndim(instants[0]) == 1:
        blocks = [np.asarray(t, dtype=float) for t in instants]
    else:
        blocks = [np.asarray(instants, dtype=float)]
    for t in blocks:
        if t.ndim != 1 or t.size == 0 or not np.all(np.isfinite(t)):
            raise ValueError("instants must be a non-empty 1-D array of finite instants, or a "
                             "list of them (one per record)")
    return blocks


def white_level(kernel) -> float:
    """The sum of the ``WhiteKernel`` levels among the summands of ``kernel`` (0 if none).

    Examples
    --------
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C, Matern, WhiteKernel
    >>> white_level(WhiteKernel(0.3) + C(2.0) * Matern(10.0, nu=1.5))
    0.3
    """
    if isinstance(kernel, WhiteKernel):
        return float(kernel.noise_level)
    if isinstance(kernel, Sum):
        return white_level(kernel.k1) + white_level(kernel.k2)
    return 0.0


class KernelNoise:
    """A noise model ``N = k(t, t)``: a scikit-learn kernel over the sample instants.

    The instants are in fast samples: the slow sample ``m`` of a uniform
    sampling is at ``t_m = offset + m F``.  Samples of different records
    are independent (``N`` is block diagonal).  The hyperparameters are the
    kernel's, in its ``theta`` (log values), so they are tuned with the
    prior's.  A ``WhiteKernel`` summand is the white measurement noise; the
    other summands are the disturbance.

    Parameters
    ----------
    kernel : sklearn Kernel
        Stationary kernel over one feature, the instant.
    instants : array-like of shape (M,), or a list of them
        The instant of each slow sample, one array per record.

    Attributes
    ----------
    white : bool
        False: ``N`` is not a multiple of the identity.
    level : float
        The white part of ``N`` (the ``WhiteKernel`` summands' level, 0 if none).
    is_free : bool
        Whether any hyperparameter is tuned.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C, Matern, WhiteKernel
    >>> noise = KernelNoise(WhiteKernel(0.1) + C(1.0) * Matern(6.0, nu=0.5), np.arange(4) * 3)
    >>> N = noise.matrix()
    >>> N[0, :2].round(6).tolist(), bool(np.isclose(N[0, 1], np.exp(-3.0 / 6.0)))
    ([1.1, 0.606531], True)
    >>> noise.theta.round(3).tolist(), noise.level
    ([-2.303, 0.0, 1.792], 0.1)
    """

    white = False

    def __init__(self, kernel, instants):
        if not isinstance(kernel, Kernel):
            raise ValueError(f"kernel must be a scikit-learn kernel; got {type(kernel).__name__}")
        self.kernel = kernel
        self.instants = _instant_blocks(instants)

    @property
    def n_samples(self) -> int:
        """``M``, the number of slow samples."""
        return sum(t.shape[0] for t in self.instants)

    @property
    def level(self) -> float:
        return white_level(self.kernel)

    @property
    def theta(self) -> np.ndarray:
        """The kernel's ``theta`` (log hyperparameters that are not fixed)."""
        return self.kernel.theta

    @property
    def bounds(self) -> np.ndarray:
        """Bounds of :attr:`theta`, of shape ``(len(theta), 2)``."""
        return self.kernel.bounds.reshape(-1, 2)

    @property
    def is_free(self) -> bool:
        return self.theta.shape[0] > 0

    def with_theta(self, theta) -> "KernelNoise":
        """The same noise model at ``theta`` (its own entries of the whole ``theta``)."""
        return KernelNoise(self.kernel.clone_with_theta(np.asarray(theta, dtype=float)),
                           self.instants)

    def matrix(self) -> np.ndarray:
        """``N``, of shape ``(M, M)``."""
        return linalg.block_diag(*(self.kernel(t[:, None]) for t in self.instants))

    def matrix_with_gradient(self) -> tuple[np.ndarray, np.ndarray]:
        """``N`` and ``dN / d theta``, of shapes ``(M, M)`` and ``(M, M, len(theta))``."""
        M, n = self.n_samples, self.theta.shape[0]
        N, dN = np.zeros((M, M)), np.zeros((M, M, n))
        start = 0
        for t in self.instants:
            block, gradient = self.kernel(t[:, None], eval_gradient=True)
            stop = start + t.shape[0]
            N[start:stop, start:stop] = block
            dN[start:stop, start:stop] = gradient
            start = stop
        return N, dN

    def derivatives(self) -> list[np.ndarray]:
        """``dN / d theta_j`` for each entry of :attr:`theta`, dense ``(M, M)`` each."""
        _, dN = self.matrix_with_gradient()
        return [np.ascontiguousarray(dN[:, :, j]) for j in range(dN.shape[2])]

    def add_to(self, S: np.ndarray) -> np.ndarray:
        """``S + N`` in place (``S`` square, of the size of the data); returns ``S``."""
        S += self.matrix()
        return S

    def contract(self, W: np.ndarray, weight: float = 1.0) -> np.ndarray:
        """``[weight tr(W dN / d theta_j)]_j`` for symmetric ``W``."""
        _, dN = self.matrix_with_gradient()
        return weight * np.einsum("ij,ijk->k", W, dN)

    def remainder(self, observation):
        """No remainder: coloured noise is not summarized by the white-noise reduction.

        The data-covariance seam (:func:`gpmultirate.covariance.data_covariance`)
        asks each noise model for the likelihood of what a long-record
        reduction left out; a reduction assumes white noise, so a reduced
        ``observation`` is refused.
        """
        return _no_remainder(observation)

    def sample_variance(self) -> float:
        """The variance of one measured sample, ``k(t, t)`` (stationary kernels)."""
        return float(self.kernel.diag(np.zeros((1, 1)))[0])

    def structure(self):
        """The :class:`AR1Noise` this model is, or None.

        So it is when the kernel is ``Matern(nu=0.5)``, optionally times a
        constant, and the instants of every record are uniformly spaced with
        one spacing.
        """
        return AR1Noise.from_kernel(self.kernel, self.instants)


def _no_remainder(observation):
    from gpmultirate.covariance import Remainder

    if getattr(observation, "n_discarded", 0) > 0:
        raise ValueError(
            "a reduced observation assumes white noise: a coloured noise model needs the "
            "observation itself (the AR(1) structure has its own reduction, AR1Statistics)"
        )
    return Remainder(0, 0.0, 1.0)


def _exponential_parts(kernel):
    """``(variance, length_scale, bounds)`` of ``[C *] Matern(nu=0.5)``, or None."""
    constant, matern = ConstantKernel(1.0, "fixed"), kernel
    if isinstance(kernel, Product):
        for a, b in ((kernel.k1, kernel.k2), (kernel.k2, kernel.k1)):
            if isinstance(a, ConstantKernel) and isinstance(b, Matern):
                constant, matern = a, b
                break
        else:
            return None
    if not isinstance(matern, Matern) or matern.nu != 0.5 or np.ndim(matern.length_scale) != 0:
        return None
    return constant, matern


class AR1Noise:
    """Matérn 1/2 noise on a uniform grid: an AR(1) process, by its tridiagonal precision.

    ``N[m, n] = sigma^2 a^|m - n|`` with ``a = exp(-spacing / length_scale)``
    (``sigma^2 exp(-|t_m - t_n| / length_scale)`` at instants ``spacing``
    apart).  The precision is ``Q = T / (sigma^2 (1 - a^2))`` with ``T``
    tridiagonal: diagonal ``1, 1 + a^2, ..., 1 + a^2, 1``, off-diagonal ``-a``.

    ``theta`` is ``[log sigma^2, log length_scale]`` (the free ones), the
    ``theta`` of ``ConstantKernel(sigma^2) * Matern(length_scale, nu=0.5)``.

    Parameters
    ----------
    variance : float
        ``sigma^2``.
    length_scale : float
        In fast samples.
    spacing : float
        The distance of consecutive instants, in fast samples (the factor ``F``).
    n_samples : int or sequence of int
        Samples per record (independent records).
    variance_bounds, length_scale_bounds : pair of floats or "fixed"

    Examples
    --------
    >>> import numpy as np
    >>> noise = AR1Noise(2.0, 6.0, spacing=3, n_samples=5)
    >>> Q = noise.precision_matrix()
    >>> bool(np.allclose(Q @ noise.matrix(), np.eye(5)))
    True
    >>> w = noise.whiten(np.eye(5))
    >>> bool(np.allclose(w.T @ w / noise.innovation_variance, Q))
    True
    """

    white = False

    def __init__(self, variance: float, length_scale: float, spacing: float, n_samples,
                 variance_bounds=(1e-5, 1e5), length_scale_bounds=(1e-5, 1e5)):
        self.variance = float(variance)
        self.length_scale = float(length_scale)
        self.spacing = float(spacing)
        counts = [n_samples] if isinstance(n_samples, numbers.Integral) else list(n_samples)
        if not counts or any(int(n) < 1 for n in counts):
            raise ValueError(f"n_samples must be positive; got {n_samples!r}")
        self.counts = [int(n) for n in counts]
        if not (self.variance > 0 and self.length_scale > 0 and self.spacing > 0):
            raise ValueError("variance, length_scale and spacing must be positive")
        self.variance_bounds = variance_bounds
        self.length_scale_bounds = length_scale_bounds
        #: whether the variance comes before the length scale in ``theta``
        #: (``C * Matern``; ``Matern * C`` puts the length scale first)
        self.variance_first = True

    @classmethod
    def from_kernel(cls, kernel, instants) -> "AR1Noise | None":
        """The AR(1) form of ``[C *] Matern(nu=0.5)`` at uniformly spaced instants, or None."""
        parts = _exponential_parts(kernel)
        blocks = _instant_blocks(instants)
        if parts is None:
            return None
        steps = np.concatenate([np.diff(t) for t in blocks])
        if steps.size == 0 or np.ptp(steps) > 1e-9 * abs(steps[0]) or steps[0] <= 0:
            return None
        constant, matern = parts
        noise = cls(constant.constant_value, matern.length_scale, steps[0],
                    [t.shape[0] for t in blocks], constant.constant_value_bounds,
                    matern.length_scale_bounds)
        noise.variance_first = not (isinstance(kernel, Product) and kernel.k1 is matern)
        return noise

    # ---------------------------------------------------------- parameters
    @property
    def pole(self) -> float:
        """``a = exp(-spacing / length_scale)``."""
        return float(np.exp(-self.spacing / self.length_scale))

    @property
    def innovation_variance(self) -> float:
        """``sigma^2 (1 - a^2)``: the variance of the whitened samples."""
        return self.variance * (1.0 - self.pole**2)

    @property
    def level(self) -> float:
        return 0.0

    @property
    def n_samples(self) -> int:
        return sum(self.counts)

    def _free(self):
        return [not isinstance(self.variance_bounds, str),
                not isinstance(self.length_scale_bounds, str)]

    @property
    def theta(self) -> np.ndarray:
        return np.log(np.array(self.in_theta_order(self.variance, self.length_scale), dtype=float))

    @property
    def bounds(self) -> np.ndarray:
        rows = [np.log(b) for b in self.in_theta_order(self.variance_bounds,
                                                        self.length_scale_bounds)]
        return np.array(rows, dtype=float).reshape(-1, 2)

    @property
    def is_free(self) -> bool:
        return any(self._free())

    def with_theta(self, theta) -> "AR1Noise":
        values = [self.variance, self.length_scale]
        entries = iter(np.asarray(theta, dtype=float))
        order = (0, 1) if self.variance_first else (1, 0)
        free = self._free()
        for i in order:
            if free[i]:
                values[i] = float(np.exp(next(entries)))
        moved = AR1Noise(values[0], values[1], self.spacing, self.counts, self.variance_bounds,
                         self.length_scale_bounds)
        moved.variance_first = self.variance_first
        return moved

    def statistics(self, Phi: np.ndarray, y: np.ndarray, gram=None) -> "AR1Statistics":
        """The :class:`AR1Statistics` of ``Phi`` and ``y`` on this noise's records."""
        return AR1Statistics(Phi, y, self.counts, gram)

    def evidence_gradient(self, statistics: "AR1Statistics", mu: np.ndarray,
                          Sigma: np.ndarray) -> list:
        """The log evidence's derivatives in this noise's ``theta``, in ``O(P^2)``.

        With ``Q = T(a) / q``, ``q = sigma^2 (1 - a^2)``, and ``mu``, ``Sigma``
        the posterior of the coefficients under this noise: each entry is
        ``-1/2 (r^T dQ r + tr(Sigma Phi^T dQ Phi) + d log det N)`` with
        ``r = y - Phi mu`` (``dN = -N dQ N``), every term a combination of
        the ``statistics`` (:class:`AR1Statistics` of ``Phi`` and ``y``).
        """
        a, q = self.pole, self.innovation_variance
        Gt, bt, ct = statistics.quadratic_forms(a)
        G, b, c = Gt / q, bt / q, ct / q

        def entry(dG, db, dc, dlogdet):
            # r^T dQ r = dc - 2 mu^T db + mu^T dG mu ; tr(Sigma Phi^T dQ Phi) = sum(Sigma * dG)
            quad = dc - 2.0 * mu @ db + mu @ dG @ mu
            return -0.5 * (quad + np.sum(Sigma * dG) + dlogdet)

        free = self._free()
        variance = length_scale = None
        if free[0]:  # d/d log sigma^2: dQ = -Q
            variance = entry(-G, -b, -c, float(self.n_samples))
        if free[1]:  # d/d log length_scale = (d a / d log l) d/da, d a / d log l = -a log a
            dT = statistics.quadratic_forms(a, derivative=True)
            n_pairs = sum(n - 1 for n in self.counts)
            da = -a * np.log(a)
            dq = -2.0 * a * self.variance  # d q / d a
            dG = (dT[0] - Gt * dq / q) / q
            db = (dT[1] - bt * dq / q) / q
            dc = (dT[2] - ct * dq / q) / q
            dlogdet = -2.0 * a * n_pairs / (1.0 - a * a)
            length_scale = da * entry(dG, db, dc, dlogdet)
        return self.in_theta_order(variance, length_scale)

    def in_theta_order(self, variance_entry, length_scale_entry) -> list:
        """The free ones of the two entries, in the order of the kernel's ``theta``."""
        free = self._free()
        entries = [(variance_entry, free[0]), (length_scale_entry, free[1])]
        if not self.variance_first:
            entries.reverse()
        return [value for value, is_free in entries if is_free]

    # ------------------------------------------------------------ matrices
    def matrix(self) -> np.ndarray:
        """``N`` (dense, for checks and small problems)."""
        a = self.pole
        blocks = []
        for n in self.counts:
            k = np.arange(n)
            blocks.append(self.variance * a ** np.abs(k[:, None] - k[None, :]))
        return linalg.block_diag(*blocks)

    def as_kernel_noise(self) -> KernelNoise:
        """The same noise as a :class:`KernelNoise` (``C * Matern(nu=0.5)`` at the instants)."""
        instants = [self.spacing * np.arange(n) for n in self.counts]  # independent blocks
        kernel = ConstantKernel(self.variance, self.variance_bounds) * Matern(
            self.length_scale, self.length_scale_bounds, nu=0.5)
        return KernelNoise(kernel, instants)

    def add_to(self, S: np.ndarray) -> np.ndarray:
        """``S + N`` in place; returns ``S`` (the dense route of the data-covariance seam)."""
        S += self.matrix()
        return S

    def contract(self, W: np.ndarray, weight: float = 1.0) -> np.ndarray:
        """``[weight tr(W dN / d theta_j)]_j`` for symmetric ``W``."""
        return self.as_kernel_noise().contract(W, weight)

    def remainder(self, observation):
        """No remainder; a reduced ``observation`` is refused (see :class:`KernelNoise`)."""
        return _no_remainder(observation)

    def _band(self, a: float):
        """Diagonal and off-diagonal of ``T`` (records joined by zero off-diagonals)."""
        diagonal, off = [], []
        for n in self.counts:
            d = np.full(n, 1.0 + a * a)
            d[0] = d[-1] = 1.0
            if n == 1:
                d[0] = 1.0 - a * a  # a lone sample: T = 1 - a^2, Q = 1 / sigma^2
            diagonal.append(d)
            off.append(np.append(np.full(n - 1, -a), 0.0))
        return np.concatenate(diagonal), np.concatenate(off)[:-1]

    def precision(self) -> tuple[np.ndarray, np.ndarray]:
        """Diagonal and off-diagonal of ``Q = N^{-1}``."""
        d, o = self._band(self.pole)
        q = self.innovation_variance
        return d / q, o / q

    def precision_matrix(self) -> np.ndarray:
        d, o = self.precision()
        return np.diag(d) + np.diag(o, 1) + np.diag(o, -1)

    def log_det(self) -> float:
        """``log det N = M log sigma^2 + sum_records (n - 1) log(1 - a^2)``."""
        a = self.pole
        return float(self.n_samples * np.log(self.variance)
                     + sum(n - 1 for n in self.counts) * np.log1p(-a * a))

    def whiten(self, b: np.ndarray) -> np.ndarray:
        """``W b`` (rows are samples): ``W^T W = (1 - a^2) T``, ``W N W^T = sigma^2 (1 - a^2) I``.

        The prewhitening filter ``w_0 = sqrt(1 - a^2) b_0``,
        ``w_m = b_m - a b_{m-1}`` per record; ``b`` is not modified.
        """
        b = np.asarray(b, dtype=float)
        a = self.pole
        out = np.empty_like(b)
        start = 0
        for n in self.counts:
            block = b[start : start + n]
            out[start] = np.sqrt(1.0 - a * a) * block[0]
            out[start + 1 : start + n] = block[1:] - a * block[:-1]
            start += n
        return out


class AR1Statistics:
    """The products of the data that the AR(1) evidence needs, computed once: ``O(M P^2)``.

    ``T = I + a^2 D - a E`` with ``D = diag(0, 1, ..., 1, 0)`` and ``E`` the
    symmetric off-diagonal ones (per record), so ``X^T T Z`` for any ``a`` is
    a combination of ``X^T Z``, ``X^T D Z`` and ``X^T E Z``: these three for
    ``X, Z`` in ``(Phi, y)`` are kept.

    Parameters
    ----------
    Phi : ndarray of shape (M, P)
    y : ndarray of shape (M,)
    counts : sequence of int
        Samples per record (rows of ``Phi`` in record order).
    gram : tuple of three ndarrays, optional
        The :attr:`gram` of an earlier instance on the same ``Phi`` and
        ``counts`` (its ``O(M P^2)`` products reused; only those with ``y``
        are formed).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> Phi, y = rng.standard_normal((6, 2)), rng.standard_normal(6)
    >>> stats = AR1Statistics(Phi, y, [6])
    >>> noise = AR1Noise(1.0, 2.0, 1.0, 6)
    >>> G, b, c = stats.quadratic_forms(noise.pole)
    >>> T = noise.precision_matrix() * noise.innovation_variance
    >>> bool(np.allclose(G, Phi.T @ T @ Phi)), bool(np.allclose(c, y @ T @ y))
    (True, True)
    """

    def __init__(self, Phi: np.ndarray, y: np.ndarray, counts, gram=None):
        Phi = np.asarray(Phi, dtype=float)
        y = np.asarray(y, dtype=float)
        interior = np.ones(Phi.shape[0])
        pairs = []  # (row, previous row) within a record
        start = 0
        for n in counts:
            interior[start] = interior[start + n - 1] = 0.0
            pairs.extend(range(start + 1, start + n))
            start += n
        if start != Phi.shape[0]:
            raise ValueError(f"counts must add up to the rows of Phi ({Phi.shape[0]}); got {start}")
        pairs = np.asarray(pairs, dtype=int)
        self.M = Phi.shape[0]
        self.counts = list(counts)
        singles = np.array([n == 1 for n in counts])
        # a lone sample has T = 1 - a^2: it belongs to D with weight -1 (1 + a^2 D)
        start = 0
        for n, single in zip(counts, singles):
            if single:
                interior[start] = -1.0
            start += n

        self._interior, self._pairs = interior, pairs
        self.gram = self.band_products(Phi, Phi) if gram is None else gram
        self.cross = self.band_products(Phi, y)
        self.energy = self.band_products(y, y)

    def band_products(self, X: np.ndarray, Z: np.ndarray):
        """``(X^T Z, X^T D Z, X^T E Z)``: ``X^T T(a) Z`` is ``first + a^2 second - a third``."""
        interior, pairs = self._interior, self._pairs
        XZ = X.T @ Z
        XDZ = (X.T * interior) @ Z
        XEZ = X[pairs].T @ Z[pairs - 1] + X[pairs - 1].T @ Z[pairs]
        return XZ, XDZ, XEZ

    @staticmethod
    def _combine(parts, a: float, derivative: bool = False):
        plain, interior, off = parts
        if derivative:  # d/da of plain + a^2 interior - a off
            return 2.0 * a * interior - off
        return plain + a * a * interior - a * off

    def quadratic_forms(self, a: float, derivative: bool = False):
        """``Phi^T T Phi``, ``Phi^T T y``, ``y^T T y`` at pole ``a`` (or their ``d/da``)."""
        return (self._combine(self.gram, a, derivative), self._combine(self.cross, a, derivative),
                float(self._combine(self.energy, a, derivative)))


def ar1_log_evidence(statistics: AR1Statistics, K: np.ndarray, noise: AR1Noise,
                     dK=None, eval_gradient: bool = False):
    """Log evidence of ``y = Phi g + v``, ``g ~ N(0, K)``, AR(1) noise, in ``O(P^3)``.

    With ``Q = N^{-1}``, ``G = Phi^T Q Phi``, ``b = Phi^T Q y``,
    ``c = y^T Q y``, ``K = F F^T`` and ``C = I + F^T G F = R^T R``:

    * ``y^T Ky^{-1} y = c - |R^{-T} F^T b|^2``;
    * ``log det Ky = log det N + log det C``.

    The gradient, by the trace identity with ``Ky^{-1} = Q - Q Phi
    Sigma Phi^T Q`` (``Sigma`` the posterior covariance, ``mu`` the mean):

    * kernel entry ``j``: ``1/2 (beta^T dK_j beta - tr(H dK_j))`` with
      ``beta = b - G mu`` (``= Phi^T Ky^{-1} y``) and ``H = G - G Sigma G``;
    * noise entry ``j`` (``dN = -N dQ N``): ``-1/2 (r^T dQ r + tr(Sigma Phi^T dQ Phi)
      + d log det N)`` with ``r = y - Phi mu``, every term a combination of
      the :class:`AR1Statistics`.

    Parameters
    ----------
    statistics : AR1Statistics
    K : ndarray of shape (P, P)
        Prior covariance of the coefficients.
    noise : AR1Noise
    dK : ndarray of shape (P, P, n_kernel), optional
        ``dK / d theta_kernel``; needed with ``eval_gradient``.
    eval_gradient : bool, default=False

    Returns
    -------
    value : float
    gradient : ndarray, only with ``eval_gradient``
        The kernel's entries, then the noise's (``noise.theta``).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> Phi, y = rng.standard_normal((40, 5)), rng.standard_normal(40)
    >>> K, noise = np.eye(5), AR1Noise(0.5, 4.0, 2.0, 40)
    >>> value = ar1_log_evidence(AR1Statistics(Phi, y, [40]), K, noise)
    >>> bool(np.isclose(value, dense_log_evidence(Phi, K, y, noise.matrix())))
    True
    """
    a, q = noise.pole, noise.innovation_variance
    Gt, bt, ct = statistics.quadratic_forms(a)
    G, b, c = Gt / q, bt / q, ct / q
    values, vectors = linalg.eigh(0.5 * (K + K.T), check_finite=False)
    keep = values > max(values.max(), 0.0) * 1e-14
    F = vectors[:, keep] * np.sqrt(values[keep])
    C = F.T @ G @ F
    C[np.diag_indices_from(C)] += 1.0
    R = linalg.cholesky(C, lower=False, check_finite=False)
    Fb = F.T @ b
    v = linalg.solve_triangular(R, Fb, trans="T", check_finite=False)
    quadratic = c - v @ v
    log_det = noise.log_det() + 2.0 * np.log(np.diag(R)).sum()
    M = statistics.M
    value = float(-0.5 * quadratic - 0.5 * log_det - 0.5 * M * LOG_2PI)
    if not eval_gradient:
        return value
    # posterior: Sigma = F C^{-1} F^T, mu = Sigma b
    Rinv_FT = linalg.solve_triangular(R, F.T, trans="T", check_finite=False)
    Sigma = Rinv_FT.T @ Rinv_FT
    mu = Sigma @ b
    grad = []
    if dK is not None:
        beta = b - G @ mu
        H = G - G @ Sigma @ G
        for j in range(dK.shape[2]):
            dKj = dK[:, :, j]
            grad.append(0.5 * (beta @ dKj @ beta - np.sum(H * dKj)))
    grad.extend(noise.evidence_gradient(statistics, mu, Sigma))
    return value, np.array(grad)


def dense_log_evidence(Phi, K, y, N, dK=None, dN=None, eval_gradient: bool = False):
    """The reference log evidence ``log N(y; 0, Phi K Phi^T + N)`` and its gradient.

    Eq. (19) with the noise covariance ``N`` in place of ``gamma I``; the
    gradient by the trace identity, ``1/2 tr((alpha alpha^T - Ky^{-1}) dKy_j)``,
    for the kernel's entries (``Phi dK_j Phi^T``) then the noise's (``dN_j``).

    Parameters
    ----------
    Phi : ndarray of shape (M, P)
    K : ndarray of shape (P, P)
    y : ndarray of shape (M,)
    N : ndarray of shape (M, M)
    dK : ndarray of shape (P, P, n_kernel), optional
    dN : ndarray of shape (M, M, n_noise), optional
    eval_gradient : bool, default=False

    Returns
    -------
    value : float
    gradient : ndarray, only with ``eval_gradient``

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.stats import multivariate_normal
    >>> Phi, K, N, y = np.eye(2), np.eye(2), 0.5 * np.eye(2), np.array([0.3, -1.0])
    >>> bool(np.isclose(dense_log_evidence(Phi, K, y, N),
    ...                 multivariate_normal(np.zeros(2), 1.5 * np.eye(2)).logpdf(y)))
    True
    """
    Ky = Phi @ K @ Phi.T + N
    L = linalg.cholesky(Ky, lower=True, check_finite=False)
    alpha = linalg.cho_solve((L, True), y, check_finite=False)
    M = y.shape[0]
    value = float(-0.5 * y @ alpha - np.log(np.diag(L)).sum() - 0.5 * M * LOG_2PI)
    if not eval_gradient:
        return value
    W = np.outer(alpha, alpha) - linalg.cho_solve((L, True), np.eye(M), check_finite=False)
    grad = []
    if dK is not None:
        A = Phi.T @ W @ Phi
        grad.extend(0.5 * (A.reshape(1, -1) @ dK.reshape(A.size, -1))[0])
    if dN is not None:
        grad.extend(0.5 * (W.reshape(1, -1) @ dN.reshape(W.size, -1))[0])
    return value, np.array(grad)


def dense_posterior(Phi, K, y, N):
    """Posterior mean and covariance of ``g`` given ``y = Phi g + v``, ``v ~ N(0, N)``.

    Eq. (15) with ``N`` in place of ``gamma I``: ``mu = K Phi^T Ky^{-1} y`` and
    ``Sigma = K - K Phi^T Ky^{-1} Phi K``.

    Examples
    --------
    >>> import numpy as np
    >>> mu, Sigma = dense_posterior(np.eye(1), np.eye(1), np.array([2.0]), np.eye(1))
    >>> mu.round(12).tolist(), Sigma.round(12).tolist()
    ([1.0], [[0.5]])
    """
    Ky = Phi @ K @ Phi.T + N
    L = linalg.cholesky(Ky, lower=True, check_finite=False)
    PhiK = Phi @ K
    B = linalg.solve_triangular(L, PhiK, lower=True, check_finite=False)
    mu = PhiK.T @ linalg.cho_solve((L, True), y, check_finite=False)
    Sigma = K - B.T @ B
    return mu, 0.5 * (Sigma + Sigma.T)


#: The time scales of the disturbances :func:`disturbance_evidence_gain` tries,
#: in multiples of the median spacing of the instants.
GAIN_LENGTH_SCALES = (1.0, 3.0, 10.0, 30.0, 100.0)
#: The shares of the noise variance the disturbance takes, and the factors of
#: the total noise variance, that :func:`disturbance_evidence_gain` tries.
GAIN_SHARES = (0.5, 0.9)
GAIN_SCALES = (1.0, 3.0)


def disturbance_evidence_gain(S, y, noise_level: float, instants) -> float:
    """The log evidence a fixed Matérn disturbance gains over white noise, the prior held.

    A cheap test of whether the slow samples call for a disturbance model:
    with the signal covariance ``S = Phi K Phi^T`` of a tuned white-noise fit
    held, the white noise ``gamma I`` is replaced by
    ``s gamma ((1 - w) I + w R)``, ``R`` the correlation of a Matérn 1/2 or
    3/2 process over the instants (records independent), for a small grid of
    time scales ``l`` (:data:`GAIN_LENGTH_SCALES` times the median spacing),
    shares ``w`` (:data:`GAIN_SHARES`) and scales ``s`` (:data:`GAIN_SCALES`).
    Returns the largest ``log N(y; 0, S + N_disturbance) - log N(y; 0, S + gamma I)``
    (negative when no disturbance on the grid does better).  Each grid point
    costs one ``M x M`` Cholesky factorization.

    Parameters
    ----------
    S : ndarray of shape (M, M)
        The signal part of the data covariance (not modified).
    y : ndarray of shape (M,)
    noise_level : float
        The white noise variance ``gamma`` of the fit.
    instants : array-like of shape (M,), or a list of them
        The instant of each slow sample in fast samples, one array per record.

    Returns
    -------
    float

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> t = 3.0 * np.arange(200)
    >>> S = np.zeros((200, 200))
    >>> white = rng.standard_normal(200)
    >>> drift = np.cumsum(rng.standard_normal(200)) * 0.3 + 0.3 * white
    >>> bool(disturbance_evidence_gain(S, white, 1.0, t) < 2.0)
    True
    >>> bool(disturbance_evidence_gain(S, drift, np.var(drift), t) > 20.0)
    True
    """
    S = np.asarray(S, dtype=float)
    y = np.asarray(y, dtype=float)
    gamma = float(noise_level)
    M = y.shape[0]
    if S.shape != (M, M):
        raise ValueError(f"S must be of shape ({M}, {M}); got {S.shape}")
    blocks = _instant_blocks(instants)
    if sum(t.shape[0] for t in blocks) != M:
        raise ValueError("instants must give one instant per sample of y")

    def log_evidence(N):
        try:
            L = linalg.cholesky(S + N, lower=True, check_finite=False)
        except linalg.LinAlgError:
            return -np.inf
        z = linalg.solve_triangular(L, y, lower=True, check_finite=False)
        return float(-0.5 * z @ z - np.log(np.diag(L)).sum())

    white = log_evidence(gamma * np.eye(M))
    distance = np.full((M, M), np.inf)
    start = 0
    steps = []
    for t in blocks:
        n = t.shape[0]
        distance[start : start + n, start : start + n] = np.abs(t[:, None] - t[None, :])
        steps.append(np.diff(t))
        start += n
    steps = np.abs(np.concatenate(steps))
    spacing = float(np.median(steps)) if steps.size and np.median(steps) > 0 else 1.0
    best = -np.inf
    for length_scale in spacing * np.asarray(GAIN_LENGTH_SCALES):
        d = distance / length_scale
        with np.errstate(invalid="ignore"):
            shapes = (np.exp(-d), (1.0 + np.sqrt(3.0) * d) * np.exp(-np.sqrt(3.0) * d))
        for R in shapes:
            R = np.nan_to_num(R, nan=0.0)  # inf * 0 across records
            for share in GAIN_SHARES:
                N = share * R
                N[np.diag_indices(M)] += 1.0 - share
                for scale in GAIN_SCALES:
                    best = max(best, log_evidence(scale * gamma * N) - white)
    return best


def ar1_evidence_gain(Phi, K, y, noise_level: float, instants) -> float | None:
    """The log evidence an AR(1) noise gains over white noise, the prior held: ``O(M P^2)``.

    The long-record form of :func:`disturbance_evidence_gain`: the white
    noise ``gamma I`` is replaced by the AR(1) noise ``s gamma a^|m - n|``
    (:class:`AR1Noise`, a Matérn 1/2 process at uniformly spaced instants)
    for the time scales :data:`GAIN_LENGTH_SCALES` times the spacing and the
    scales :data:`GAIN_SCALES`.  The data enter through
    :class:`AR1Statistics` (once, ``O(M P^2)``) and ``K``'s
    eigendecomposition (once); each grid point then costs a ``P x P``
    Cholesky factorization.  Returns the largest gain, or None when the
    instants are not uniformly spaced with one spacing.

    Parameters
    ----------
    Phi : ndarray of shape (M, P)
    K : ndarray of shape (P, P)
        The prior covariance of the coefficients.
    y : ndarray of shape (M,)
    noise_level : float
        The white noise variance ``gamma`` of the fit.
    instants : array-like of shape (M,), or a list of them

    Returns
    -------
    float or None

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> Phi, K = rng.standard_normal((300, 4)), np.eye(4)
    >>> y = Phi @ rng.standard_normal(4) + rng.standard_normal(300)
    >>> bool(ar1_evidence_gain(Phi, K, y, 1.0, 3.0 * np.arange(300)) < 2.0)
    True
    >>> ar1_evidence_gain(Phi, K, y, 1.0, np.sort(rng.uniform(0, 900, 300))) is None
    True
    """
    blocks = _instant_blocks(instants)
    steps = np.concatenate([np.diff(t) for t in blocks])
    if steps.size == 0 or steps[0] <= 0 or np.ptp(steps) > 1e-9 * abs(steps[0]):
        return None
    spacing = float(steps[0])
    counts = [t.shape[0] for t in blocks]
    Phi = np.asarray(Phi, dtype=float)
    y = np.asarray(y, dtype=float)
    M = y.shape[0]
    if Phi.shape[0] != M or sum(counts) != M:
        raise ValueError("Phi, y and instants must have one row per sample")
    gamma = float(noise_level)
    statistics = AR1Statistics(Phi, y, counts)
    values, vectors = linalg.eigh(0.5 * (K + K.T), check_finite=False)
    keep = values > max(values.max(), 0.0) * 1e-14
    F = vectors[:, keep] * np.sqrt(values[keep])
    n_pairs = sum(n - 1 for n in counts)

    def log_evidence(a, variance):
        q = variance * (1.0 - a * a)
        G, b, c = statistics.quadratic_forms(a)
        C = F.T @ (G / q) @ F
        C[np.diag_indices_from(C)] += 1.0
        try:
            R = linalg.cholesky(C, lower=False, check_finite=False)
        except linalg.LinAlgError:
            return -np.inf
        v = linalg.solve_triangular(R, F.T @ (b / q), trans="T", check_finite=False)
        log_det = (M * np.log(variance) + n_pairs * np.log1p(-a * a)
                   + 2.0 * np.log(np.diag(R)).sum())
        return float(-0.5 * (c / q - v @ v) - 0.5 * log_det)

    white = log_evidence(0.0, gamma)
    best = -np.inf
    for length_scale in spacing * np.asarray(GAIN_LENGTH_SCALES):
        a = float(np.exp(-spacing / length_scale))
        for scale in GAIN_SCALES:
            best = max(best, log_evidence(a, scale * gamma) - white)
    return best


def _has_white(kernel) -> bool:
    if isinstance(kernel, WhiteKernel):
        return True
    return isinstance(kernel, Sum) and (_has_white(kernel.k1) or _has_white(kernel.k2))


def noise_instants(observation) -> list[np.ndarray]:
    """The instant of every slow sample of each record, in fast samples.

    The fast-sample index of each sample (``sample_indices``), or the
    reading's stamp for readings at their own instants (``sample_times``);
    one array per record, as :class:`KernelNoise` takes them.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> noise_instants(DownsampledConvolution(np.ones(10), 3, 4, offset=1))[0].tolist()
    [1.0, 4.0, 7.0]
    """
    blocks = []
    for record in observation.records:
        instants = getattr(record, "sample_indices", None)
        if instants is None:
            instants = getattr(record, "sample_times", None)
        if instants is None:
            raise ValueError(
                f"a disturbance model needs the instant of every slow sample; "
                f"{type(record).__name__} does not give them"
            )
        blocks.append(np.asarray(instants, dtype=float))
    return blocks


def make_noise(noise_kernel, noise_level: float, noise_level_bounds, instants,
               length_scale: float = 10.0):
    """The noise model of a choice: ``"white"``, a named disturbance or a kernel.

    Parameters
    ----------
    noise_kernel : "white", "matern12", "matern32", "ar1" or sklearn Kernel
        ``"white"``: ``gamma I`` (:class:`gpmultirate.covariance.WhiteNoise`).
        ``"matern12"``/``"matern32"``: white noise plus
        ``C * Matern(length_scale, nu=1/2 or 3/2)`` over the instants, the
        constant started at ``noise_level`` with the noise level's bounds.
        ``"ar1"``: ``C * Matern(length_scale, nu=1/2)`` alone (no white
        noise), an AR(1) process on a uniform grid.
        A kernel: a disturbance over the instants, added to white noise of
        ``noise_level`` unless it holds a ``WhiteKernel`` summand itself or
        is the AR(1) form ``[C *] Matern(nu=0.5)``, used as it is.
    noise_level : float
        The white noise variance ``gamma`` (the start when it is tuned).
    noise_level_bounds : pair of floats or "fixed"
    instants : array-like of shape (M,), or a list of them
        The instant of each slow sample in fast samples, one array per record.
    length_scale : float, default=10.0
        The start of a named disturbance's time scale, in fast samples.

    Returns
    -------
    WhiteNoise or KernelNoise

    Examples
    --------
    >>> import numpy as np
    >>> noise = make_noise("matern32", 0.1, (1e-3, 1.0), np.arange(5) * 3.0)
    >>> noise.kernel
    WhiteKernel(noise_level=0.1) + 0.316**2 * Matern(length_scale=10, nu=1.5)
    >>> type(make_noise("white", 0.1, "fixed", np.arange(5))).__name__
    'WhiteNoise'
    >>> round(make_noise("ar1", 0.1, (1e-3, 1.0), np.arange(5) * 3.0).structure().pole, 4)
    0.7408
    """
    from gpmultirate.covariance import WhiteNoise

    gamma = float(noise_level)
    if not (np.isfinite(gamma) and gamma > 0):
        raise ValueError(f"noise_level must be finite and positive; got {noise_level!r}")
    bounds = noise_level_bounds
    if isinstance(noise_kernel, str):
        if noise_kernel == "white":
            return WhiteNoise(gamma, bounds)
        if noise_kernel not in NAMED_DISTURBANCES and noise_kernel != AR1_DISTURBANCE:
            raise ValueError(
                f"noise_kernel must be 'white', {', '.join(map(repr, NAMED_DISTURBANCES))}, "
                f"{AR1_DISTURBANCE!r} or a scikit-learn kernel; got {noise_kernel!r}"
            )
        disturbance = ConstantKernel(gamma, bounds) * Matern(
            length_scale, "fixed" if isinstance(bounds, str) else (1.0, 1e4),
            nu=NAMED_DISTURBANCES.get(noise_kernel, 0.5))
        if noise_kernel == AR1_DISTURBANCE:
            return KernelNoise(disturbance, instants)
        return KernelNoise(WhiteKernel(gamma, bounds) + disturbance, instants)
    if not isinstance(noise_kernel, Kernel):
        raise ValueError(f"noise_kernel must be 'white', a named disturbance or a scikit-learn "
                         f"kernel; got {type(noise_kernel).__name__}")
    if _has_white(noise_kernel) or _exponential_parts(noise_kernel) is not None:
        return KernelNoise(noise_kernel, instants)
    return KernelNoise(WhiteKernel(gamma, bounds) + noise_kernel, instants)
