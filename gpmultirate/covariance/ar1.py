"""AR(1) noise on long records: prewhitening by a tridiagonal precision, in the parameter space.

The data enter the evidence only through ``P x P`` products of the regressor
(:class:`AR1Statistics`, formed once in ``O(M P^2)``), so each evaluation
costs ``O(P^3)``: :class:`AR1Covariance` is the one home of the AR(1)
evidence and its gradient.
"""

from __future__ import annotations

import weakref

import numpy as np
from scipy import linalg

from gpmultirate.covariance.base import DataCovariance, Remainder, cholesky_or_raise, kernel_root
from gpmultirate.covariance.posteriors import ParameterSpacePosterior

__all__ = ["AR1Covariance", "AR1Statistics"]


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
    >>> from gpmultirate.noise import AR1Noise
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


_AR1_GRAMS: list = []


def _ar1_gram(observation, Phi, ar1):
    """The :class:`AR1Statistics` Gram of ``Phi``, formed once per observation."""
    counts = tuple(ar1.counts)
    for ref, matrix, sizes, gram in _AR1_GRAMS:
        if ref() is observation and matrix() is Phi and sizes == counts:
            return gram
    gram = ar1.statistics(Phi, np.zeros(Phi.shape[0])).gram
    _AR1_GRAMS.insert(0, (weakref.ref(observation), weakref.ref(Phi), counts, gram))
    del _AR1_GRAMS[4:]
    return gram


class AR1Covariance(DataCovariance):
    """``S + N`` for AR(1) noise ``N`` (a Matérn 1/2 disturbance on one uniform grid), ``M > P``.

    The noise's precision ``Q = T(a) / q`` is tridiagonal, so prewhitening
    the data and the regressor is exact: the problem is a white-noise one in
    the parameter space.  With ``G = Phi^T Q Phi``, ``b = Phi^T Q y``,
    ``c = y^T Q y`` (combinations of products formed once in ``O(M P^2)``,
    :class:`AR1Statistics`), ``K = F F^T`` and
    ``C = I + F^T G F = R^T R``:

    * ``y^T Ky^{-1} y = c - |R^{-T} F^T b|^2``;
    * ``log det Ky = log det N + log det C``;

    each evaluation costs ``O(P^3)``, none ``O(M^3)``.  The posterior of
    ``g = F z`` has mean ``F C^{-1} F^T b`` and covariance ``F C^{-1} F^T``:
    the attributes of :class:`ParameterSpaceCovariance` (``F``,
    ``inv_root``, ``R``, :meth:`whitened_coefficients`), so
    :class:`~gpmultirate.covariance.ParameterSpacePosterior` answers it.
    This is the one home of the AR(1) evidence and its gradient:
    :func:`~gpmultirate.noise.ar1_log_evidence` and
    :func:`~gpmultirate.noise.ar1_evidence_gain` evaluate it from the
    statistics alone (:meth:`of_statistics`).

    Parameters
    ----------
    term : ObservedTerm
    noise : noise model
        A :class:`~gpmultirate.noise.KernelNoise` whose ``structure()`` is
        ``ar1``, or ``ar1`` itself (its ``theta`` orders the gradient).
    remainder : Remainder
    ar1 : AR1Noise

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C, Matern
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import TC
    >>> from gpmultirate.covariance import data_covariance, dense_log_evidence
    >>> from gpmultirate.noise import KernelNoise, noise_instants
    >>> rng = np.random.default_rng(0)
    >>> op = DownsampledConvolution(rng.standard_normal(120), factor=3, order=10)
    >>> y = rng.standard_normal(op.n_outputs)
    >>> noise = KernelNoise(C(0.5) * Matern(6.0, nu=0.5), noise_instants(op))
    >>> covariance = data_covariance(TC(0.7), op, noise)
    >>> type(covariance).__name__
    'AR1Covariance'
    >>> reference = dense_log_evidence(op.matrix, TC(0.7)(op.lags), y, noise.matrix())
    >>> bool(np.isclose(covariance.log_likelihood(y), reference, rtol=1e-10))
    True
    """

    def __init__(self, term, noise, remainder, ar1):
        super().__init__(term, noise, remainder)
        observation = self.observation
        self.Phi = observation.matrix
        self._factor(term.kernel_matrix(), _ar1_gram(observation, self.Phi, ar1), ar1)
        self._given = None

    @classmethod
    def of_statistics(cls, statistics: AR1Statistics, ar1, K=None, root=None) -> "AR1Covariance":
        """The covariance of the data that ``statistics`` summarize, for the prior ``K``.

        No observation is needed: the kernel's gradient comes from
        :meth:`evidence` with a contraction of ``dK``.  ``root``, the
        :func:`~gpmultirate.covariance.kernel_root` of ``K``, may be given
        to reuse it over a grid of noise models.  Raises
        :class:`~gpmultirate.exceptions.NotPositiveDefinite` when
        ``I + F^T G F`` cannot be factored.
        """
        covariance = cls.__new__(cls)
        covariance.term, covariance.noise = None, ar1
        covariance.remainder = Remainder(0, 0.0, 1.0)
        covariance.size = statistics.M
        covariance.Phi = None
        covariance._factor(K, statistics.gram, ar1, root)
        covariance._given = statistics
        return covariance

    def _factor(self, K, gram, ar1, root=None):
        self.ar1 = ar1
        self.K = K
        self.F, self.inv_root = kernel_root(K) if root is None else root
        self.gram = gram
        a, q = ar1.pole, ar1.innovation_variance
        plain, interior, off = gram
        self.G = (plain + a * a * interior - a * off) / q
        C = self.F.T @ self.G @ self.F
        C[np.diag_indices_from(C)] += 1.0
        self.R = cholesky_or_raise(C, lower=False)
        self._solved = None

    def statistics(self, y: np.ndarray | None) -> AR1Statistics:
        """The :class:`AR1Statistics` of ``y`` (those given to :meth:`of_statistics` for None)."""
        if y is None:
            return self._given
        return self.ar1.statistics(self.Phi, y, self.gram)

    def _of(self, y: np.ndarray | None):
        """``(statistics, b, c, v, z)`` for ``y``, kept for the last ``y``."""
        if self._solved is None or self._solved[0] is not y:
            statistics = self.statistics(y)
            _, bt, ct = statistics.quadratic_forms(self.ar1.pole)
            q = self.ar1.innovation_variance
            b, c = bt / q, ct / q
            v = linalg.solve_triangular(self.R, self.F.T @ b, trans="T", check_finite=False)
            z = linalg.solve_triangular(self.R, v, check_finite=False)
            self._solved = (y, (statistics, b, c, v, z))
        return self._solved[1]

    def whitened_coefficients(self, y: np.ndarray) -> np.ndarray:
        """The posterior mean of ``z`` (``g = F z``)."""
        return self._of(y)[4]

    def _apply_precision(self, b: np.ndarray) -> np.ndarray:
        d, o = self.ar1.precision()
        out = d.reshape((-1,) + (1,) * (b.ndim - 1)) * b
        o = o.reshape((-1,) + (1,) * (b.ndim - 1))
        out[:-1] += o * b[1:]
        out[1:] += o * b[:-1]
        return out

    def solve(self, b):
        # Ky^{-1} b = Q b - Q Phi F C^{-1} F^T Phi^T Q b
        Qb = self._apply_precision(np.asarray(b, dtype=float))
        PhiF = self.Phi @ self.F
        inner = linalg.solve_triangular(self.R, PhiF.T @ Qb, trans="T", check_finite=False)
        inner = linalg.solve_triangular(self.R, inner, check_finite=False)
        return Qb - self._apply_precision(PhiF @ inner)

    def inv_quad_logdet(self, y):
        _, _, c, v, _ = self._of(y)
        log_det = self.ar1.log_det() + 2.0 * np.log(np.diag(self.R)).sum()
        return float(c - v @ v), float(log_det)

    def posterior(self, y):
        return ParameterSpacePosterior(self, y)

    def log_likelihood_gradient(self, y):
        """The log evidence and its gradient (the kernel's, then the noise's), in ``O(P^3)``."""
        _, contract = self.term.parameter_contractor()
        return self.evidence(y, contract)

    def evidence(self, y: np.ndarray | None, kernel_contract=None):
        """The log evidence and, with ``kernel_contract``, its gradient.

        ``kernel_contract`` maps a symmetric ``W`` of the parameter space to
        ``[tr(W dK_j)]_j``.  With ``mu``, ``Sigma`` the posterior: the
        kernel's entries are ``1/2 (beta^T dK_j beta - tr(H dK_j))``,
        ``beta = b - G mu`` (``= Phi^T Ky^{-1} y``), ``H = G - G Sigma G``;
        the noise's :meth:`~gpmultirate.noise.AR1Noise.evidence_gradient`.
        ``y=None``: the data of :meth:`of_statistics`.
        """
        value = self.log_likelihood(y)
        if kernel_contract is None:
            return value
        statistics, b, _, _, z = self._of(y)
        mu = self.F @ z
        root = linalg.solve_triangular(self.R, self.F.T, trans="T", check_finite=False)
        Sigma = root.T @ root
        beta = b - self.G @ mu
        GS = self.G @ Sigma
        H = self.G - GS @ self.G
        grad = 0.5 * np.asarray(kernel_contract(np.outer(beta, beta) - H), dtype=float)
        if self.noise.is_free:
            grad = np.append(grad, self.ar1.evidence_gradient(statistics, mu, Sigma))
        return value, grad
