"""AR(1) noise: a Matérn 1/2 process on a uniform grid, by its tridiagonal precision.

A Matérn 1/2 (exponential) process on a uniform grid of spacing ``F`` is an
AR(1) process with pole ``a = exp(-F / length_scale)``.  Its precision is
tridiagonal and prewhitening is exact: with ``w_0 = sqrt(1 - a^2) v_0``,
``w_m = v_m - a v_{m-1}`` the whitened samples are independent with
variance ``sigma^2 (1 - a^2)``, and the whitened data ``W y = W Phi g + W v``
are a white-noise problem for the whitened regressor.  The data enter only
through ``P x P`` products of the regressor
(:class:`~gpmultirate.covariance.AR1Statistics`, computed once), so the
long-record reduction is kept and each evaluation costs ``O(P^3)``: the
route :class:`~gpmultirate.covariance.AR1Covariance`, the one home of the
evidence, which :func:`ar1_log_evidence` and :func:`ar1_evidence_gain`
evaluate from the statistics alone.
"""

from __future__ import annotations

import numbers

import numpy as np
from scipy import linalg
from sklearn.gaussian_process.kernels import ConstantKernel, Matern, Product

from gpmultirate.covariance import AR1Covariance, AR1Statistics, DenseCovariance, kernel_root
from gpmultirate.exceptions import NotPositiveDefinite
from gpmultirate.noise.base import NoiseModel, instant_blocks, kernel_blocks

__all__ = ["AR1Noise", "ar1_evidence_gain", "ar1_log_evidence", "exponential_parts"]

#: The time scales of the disturbances the evidence gains try, in multiples
#: of the (median) spacing of the instants.
GAIN_LENGTH_SCALES = (1.0, 3.0, 10.0, 30.0, 100.0)
#: The factors of the total noise variance the evidence gains try.
GAIN_SCALES = (1.0, 3.0)


def exponential_parts(kernel):
    """``(constant, matern)``: the factors of ``[C *] Matern(nu=0.5)``, or None."""
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


class AR1Noise(NoiseModel):
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
        parts = exponential_parts(kernel)
        if parts is None:
            return None
        blocks = instant_blocks(instants)
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

    @classmethod
    def white(cls, variance: float, spacing: float, n_samples) -> "AR1Noise":
        """White noise of ``variance`` in the AR(1) form: the pole ``a = exp(-1000) = 0``.

        The reference an AR(1) noise is compared with through the same
        evidence (:func:`ar1_evidence_gain`).
        """
        return cls(variance, spacing / 1000.0, spacing, n_samples, "fixed", "fixed")

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

    @property
    def kernel(self):
        """``ConstantKernel(sigma^2) * Matern(length_scale, nu=0.5)``, over fast-sample instants."""
        return ConstantKernel(self.variance, self.variance_bounds) * Matern(
            self.length_scale, self.length_scale_bounds, nu=0.5)

    @property
    def instants(self) -> list[np.ndarray]:
        """The instants of the samples of each record (records are independent)."""
        return [self.spacing * np.arange(n) for n in self.counts]

    def add_to(self, S: np.ndarray) -> np.ndarray:
        """``S + N`` in place; returns ``S`` (the dense route)."""
        S += self.matrix()
        return S

    def contract(self, W: np.ndarray, weight: float = 1.0) -> np.ndarray:
        """``[weight tr(W dN / d theta_j)]_j`` for symmetric ``W`` (the dense route)."""
        _, dN = kernel_blocks(self.kernel, self.instants)
        return weight * np.einsum("ij,ijk->k", W, dN)

    # ------------------------------------------------------------ routes
    def fits(self, observation) -> bool:
        """Whether the AR(1) route serves ``observation``.

        So it does for data that are a regressor on the integer lags, not a
        reduction, with more samples than coefficients (the long-record
        case, where it keeps the cost ``O(M P^2)``), one sample per instant
        of this noise.
        """
        return (observation.n_discarded == 0 and observation.has_regressor
                and observation.n_outputs > observation.n_coefficients
                and self.n_samples == observation.n_outputs)

    def data_covariance(self, term, gradient: bool = False, owner=None):
        """:class:`~gpmultirate.covariance.AR1Covariance` where it :meth:`fits`, else dense.

        ``owner`` is the noise model this is the structure of (a
        :class:`~gpmultirate.noise.KernelNoise`, whose ``theta`` orders the
        gradient and whose dense route is the fallback); by default this one.
        """
        owner = self if owner is None else owner
        observation = term.observation
        remainder = owner.remainder(observation)
        if self.fits(observation):
            try:
                return AR1Covariance(term, owner, remainder, self)
            except NotPositiveDefinite:
                pass
        return DenseCovariance.of_term(term, owner, remainder, gradient)

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


def ar1_log_evidence(statistics: AR1Statistics, K: np.ndarray, noise: AR1Noise,
                     dK=None, eval_gradient: bool = False):
    """Log evidence of ``y = Phi g + v``, ``g ~ N(0, K)``, AR(1) noise, in ``O(P^3)``.

    :class:`~gpmultirate.covariance.AR1Covariance` of the data that
    ``statistics`` summarize: with ``Q = N^{-1}``, ``G = Phi^T Q Phi``,
    ``b = Phi^T Q y``, ``c = y^T Q y``, ``K = F F^T`` and
    ``C = I + F^T G F = R^T R``, ``y^T Ky^{-1} y = c - |R^{-T} F^T b|^2``
    and ``log det Ky = log det N + log det C``; the gradient by the trace
    identity (see :meth:`~gpmultirate.covariance.AR1Covariance.evidence`).

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
    >>> from gpmultirate.covariance import dense_log_evidence
    >>> rng = np.random.default_rng(1)
    >>> Phi, y = rng.standard_normal((40, 5)), rng.standard_normal(40)
    >>> K, noise = np.eye(5), AR1Noise(0.5, 4.0, 2.0, 40)
    >>> value = ar1_log_evidence(AR1Statistics(Phi, y, [40]), K, noise)
    >>> bool(np.isclose(value, dense_log_evidence(Phi, K, y, noise.matrix())))
    True
    """
    covariance = AR1Covariance.of_statistics(statistics, noise, K)
    if not eval_gradient:
        return covariance.evidence(None)

    def contract(W):
        return np.empty(0) if dK is None else np.einsum("ij,ijk->k", W, dK)

    return covariance.evidence(None, contract)


def ar1_evidence_gain(Phi, K, y, noise_level: float, instants) -> float | None:
    """The log evidence an AR(1) noise gains over white noise, the prior held: ``O(M P^2)``.

    The long-record form of :func:`~gpmultirate.noise.disturbance_evidence_gain`: the white
    noise ``gamma I`` is replaced by the AR(1) noise ``s gamma a^|m - n|``
    (:class:`AR1Noise`, a Matérn 1/2 process at uniformly spaced instants)
    for the time scales :data:`GAIN_LENGTH_SCALES` times the spacing and the
    scales :data:`GAIN_SCALES`.  The data enter through
    :class:`~gpmultirate.covariance.AR1Statistics` (once, ``O(M P^2)``) and ``K``'s
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
    blocks = instant_blocks(instants)
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
    root = kernel_root(K)  # once for the whole grid

    def log_evidence(ar1):
        try:
            return AR1Covariance.of_statistics(statistics, ar1, K, root).evidence(None)
        except NotPositiveDefinite:
            return -np.inf

    white = log_evidence(AR1Noise.white(gamma, spacing, counts))
    best = -np.inf
    for length_scale in spacing * np.asarray(GAIN_LENGTH_SCALES):
        for scale in GAIN_SCALES:
            ar1 = AR1Noise(scale * gamma, length_scale, spacing, counts)
            best = max(best, log_evidence(ar1) - white)
    return best
