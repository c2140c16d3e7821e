r"""The structure layer: a kernel seen through an observation.

Tuning and inference ask the same few questions of the prior covariance
``K`` (``P x P``, the kernel at the lags ``0..P-1`` of an observation) and of
the covariance of the noise-free observed data ``S = Phi K Phi^T``:

=============================================  ===============================
question                                       method of :class:`ObservedTerm`
=============================================  ===============================
``K``                                          ``kernel_matrix``
``K`` and ``A -> [sum(A * dK_j)]_j``           ``parameter_contractor``
``S``                                          ``covariance``
``S`` and ``W -> [tr(W Phi dK_j Phi^T)]_j``    ``covariance_with_contractor``
``S`` and every ``dS_j = Phi dK_j Phi^T``      ``covariance_with_derivatives``
``Phi K``                                      ``regressor_times_kernel``
``S`` with one summand left out                ``covariance_without``
``Cov(g(lags), y)`` at any lags                ``cross_covariance``
=============================================  ===============================

(``dK_j`` is the derivative with respect to the ``j``-th entry of
``kernel.theta``, a free hyperparameter in its tuning coordinate -- its log,
or ``artanh`` of a correlation, see :mod:`gpmultirate.kernels.transforms`;
``A`` and ``W`` are symmetric.)  :class:`ObservedTerm` answers all of them densely, from the
kernel matrix and scikit-learn's gradient, so any scikit-learn kernel works.
A kernel with structure subclasses :class:`StructuredKernel` and returns,
from :meth:`StructuredKernel.observed`, a term class that answers faster: a
:class:`LowRankTerm` for ``K = V D V^T`` (PK, constants), the filter form of
DC (:mod:`gpmultirate.kernels.filters`), or the diagonal recursion of
shift-scaled kernels (:mod:`gpmultirate.kernels.recursion`).  How the data
enter (a triangular factor, a strided view of the input) is the
observation's business: terms call its products and never ask its type.

:func:`observe` is the one walker over the kernel algebra: ``Sum`` adds
terms, ``ConstantKernel * k`` keeps the constant a scalar factor, any other
``Product`` is formed densely with the product rule (in parameter space,
which needs the observation's regressor; readings without one take their
dense term of the product), and every leaf is asked of the observation,
which decides what it asks of the kernel:

* :meth:`~gpmultirate.observations.Observation.structured_term` for a
  :class:`StructuredKernel`: on the integer lags the kernel's
  :meth:`StructuredKernel.observed`, for readings at their own instants its
  :meth:`StructuredKernel.observed_at_instants`
  (:mod:`gpmultirate.kernels.instants`);
* :meth:`~gpmultirate.observations.Observation.constant_term` for
  ``ConstantKernel`` (rank one);
* :meth:`~gpmultirate.observations.Observation.dense_term` for any other
  scikit-learn kernel.

Tuning also asks what each free hyperparameter *is* (:class:`Role`): a decay
in (0, 1] (``"decay"``, tuned in decay-rate coordinates), a correlation in
(-1, 1) (``"correlation"``, tuned in ``artanh``), a resonance frequency
(``"frequency"``, searched on a grid), an amplitude (``"amplitude"``; the set
that scales the whole kernel is :meth:`ObservedTerm.scale_roles`), or
anything else (``"other"``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import blas
from sklearn.base import clone
from sklearn.gaussian_process.kernels import ConstantKernel, Kernel, Product, Sum

from gpmultirate.kernels.transforms import LOG, ThetaTransform

__all__ = ["LowRankTerm", "ObservedTerm", "Role", "StructuredKernel", "observe", "rescaled"]


@dataclass(frozen=True)
class Role:
    """What one free entry of ``kernel.theta`` means to the tuning strategy.

    Attributes
    ----------
    name : str
        The parameter's full name in the kernel (``k1__k2__alpha``), as
        :meth:`~sklearn.base.BaseEstimator.set_params` takes it.
    kind : {"decay", "correlation", "frequency", "amplitude", "other"}
        ``"decay"``: a value in (0, 1] such as ``alpha``, with
        ``theta = log(value)``;
        ``"correlation"``: a value in (-1, 1) such as DC's ``beta``, with
        ``theta = artanh(value)``;
        ``"frequency"``: a resonance frequency in radians per sample;
        ``"amplitude"``: the kernel scales with ``value ** (1 / power)``.
    owner : sklearn Kernel
        The leaf kernel the parameter belongs to.
    leaf_name : str
        The parameter's name within ``owner``.
    power : float
        For amplitudes: scaling the owner by ``c`` multiplies the value by
        ``c ** power`` (1 for a constant, 1/2 for a standard deviation).
    transform : ThetaTransform
        How the value maps to its ``theta`` entry (``log`` unless the owner
        declares otherwise).
    partner : str or None
        For an amplitude of one part of a term (PK's ``sigma1``, the cosine
        part): the owner's parameter of the other part (``sigma2``), against
        which a lower bound is negligible or not
        (:func:`gpmultirate.tuning.hyperparameters_at_bounds`); the owner
        declares it in ``tuning_partners``.
    """

    name: str
    kind: str
    owner: Kernel
    leaf_name: str
    power: float = 1.0
    transform: ThetaTransform = LOG
    partner: str | None = None


def no_gradient(A) -> np.ndarray:
    """The contraction of a term without free hyperparameters: an empty vector."""
    return np.empty(0)


def symmetrize(A: np.ndarray) -> np.ndarray:
    """``(A + A^T) / 2``: removes the rounding asymmetry of a product."""
    return 0.5 * (A + A.T)


def outer_square(X: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """``X X^T`` (added to ``out`` when given), exactly symmetric, by a symmetric rank-k update.

    Half the flops of the general product ``X @ X.T``: a covariance
    ``A K A^T`` whose ``K = R R^T`` has a cheap root is ``outer_square(A R)``.

    Examples
    --------
    >>> X = np.array([[1.0, 2.0], [3.0, 4.0], [0.5, 0.0]])
    >>> bool(np.array_equal(outer_square(X), outer_square(X).T))
    True
    >>> bool(np.allclose(outer_square(X, np.eye(3)), X @ X.T + np.eye(3)))
    True
    """
    X = np.asarray(X, dtype=float)
    size = X.shape[0]
    if X.shape[1] == 0:  # no columns: nothing to add (BLAS refuses an empty update)
        return np.zeros((size, size)) if out is None else np.array(out, dtype=float)
    # X^T is a Fortran-ordered view of a C-ordered X: no copy; the update fills the lower
    # triangle of a zero matrix, mirrored by one addition (no masks of M x M)
    lower = blas.dsyrk(1.0, X.T, c=np.zeros((size, size), order="F"), trans=1, lower=1,
                       overwrite_c=1)
    square = lower + lower.T
    square.flat[:: size + 1] = np.diag(lower)
    if out is not None:
        square += out
    return square


class ObservedTerm:
    """A kernel seen through an observation; every question answered densely.

    This is the fallback for any scikit-learn kernel and the base class of
    the structured terms, which override what their structure makes
    cheaper.

    Parameters
    ----------
    kernel : sklearn Kernel
        Prior covariance over lag.
    observation : Observation or None
        The observation (see :mod:`gpmultirate.observations`);
        None for questions about the hyperparameters only (:meth:`roles`).
    path : str, default=""
        Prefix of this kernel's parameter names within the whole kernel
        (``"k1__"``), for :class:`Role`.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import RBF
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import observe
    >>> op = DownsampledConvolution(np.arange(1.0, 7.0), factor=2, order=3)
    >>> term = observe(RBF(1.0), op)
    >>> S = term.covariance()
    >>> K = RBF(1.0)(op.lags)
    >>> bool(np.allclose(S, op.matrix @ K @ op.matrix.T))
    True
    """

    def __init__(self, kernel: Kernel, observation=None, path: str = ""):
        self.kernel = kernel
        self.observation = observation
        self.path = path

    @property
    def lags(self) -> np.ndarray:
        """The lags ``0..P-1`` of the observation as a float vector."""
        return self.observation.lags[:, 0]

    # ------------------------------------------------------ parameter space
    def kernel_matrix(self) -> np.ndarray:
        """``K`` at the lags ``0..P-1`` (evaluated once per term; not to be modified).

        The posterior asks a term for ``K`` and for ``Phi K``; a dense kernel
        is evaluated once for both.
        """
        if getattr(self, "_kernel_matrix", None) is None:
            self._kernel_matrix = self.kernel(self.observation.lags)
        return self._kernel_matrix

    def kernel_with_gradient(self) -> tuple[np.ndarray, np.ndarray]:
        """``K`` and its gradient, of shape ``(P, P, n_theta)``."""
        return self.kernel(self.observation.lags, eval_gradient=True)

    def parameter_contractor(self):
        """``K`` and ``contract(A) -> [sum(A * dK_j)]_j`` for symmetric ``A``."""
        K, dK = self.kernel_with_gradient()
        n = dK.shape[2]
        if n == 0:
            return K, no_gradient
        return K, lambda A: A.reshape(-1) @ dK.reshape(-1, n)

    # ----------------------------------------------------------- data space
    def covariance(self) -> np.ndarray:
        """``S = Phi K Phi^T``, of shape ``(M, M)``."""
        return self.observation.sandwich(self.kernel_matrix())

    def covariance_with_contractor(self):
        """``S`` and ``contract(W) -> [tr(W Phi dK_j Phi^T)]_j`` for symmetric ``W``."""
        K, contract = self.parameter_contractor()
        observation = self.observation
        return observation.sandwich(K), lambda W: contract(observation.project(W))

    def covariance_with_derivatives(self):
        """``S`` and the list of ``dS_j``, one per free hyperparameter.

        Each item is a dense symmetric ``(M, M)`` array or, for low-rank
        derivatives, a pair ``(U, D)`` with ``dS_j = U D U^T``.
        """
        K, dK = self.kernel_with_gradient()
        sandwich = self.observation.sandwich
        return sandwich(K), [sandwich(dK[:, :, j]) for j in range(dK.shape[2])]

    def regressor_times_kernel(self) -> np.ndarray:
        """``Phi K``, of shape ``(M, P)``: the covariance of the data with the coefficients."""
        return self.observation.matrix @ self.kernel_matrix()

    def covariance_blocks(self, split: int) -> tuple[np.ndarray, np.ndarray]:
        """``S[split:, :split]`` and ``diag(S)[split:]``, without the rest of ``S``.

        A prediction of readings stacked after the data they are conditioned
        on needs their covariance with the data and their own variances
        only; the structured terms form just these (half the products of
        the joint ``S`` and none of its memory).  Here, from ``S``.
        """
        S = self.covariance()
        return S[split:, :split], np.diag(S)[split:].copy()

    def cross_covariance(self, lags: np.ndarray) -> np.ndarray:
        """``Cov(g(lags), y)`` for the lags of shape ``(n, d)``: shape ``(n, M)``.

        From the kernel between ``lags`` and the observation's own lags
        (:meth:`~gpmultirate.observations.Observation.dense_cross_covariance`).
        """
        return self.observation.dense_cross_covariance(self.kernel, lags)

    def covariance_without(self, kernel: Kernel) -> np.ndarray | None:
        """``S`` with the summand ``kernel`` left out, or None if it is not a summand."""
        if self.kernel is kernel:
            size = self.observation.n_outputs
            return np.zeros((size, size))
        return None

    def low_rank(self):
        """``(V, D)`` with ``K = V D V^T`` (``V`` of shape ``(P, r)``), or None."""
        return None

    def precision(self):
        """``K^{-1}`` when it is tridiagonal, with its derivatives, or None.

        A :class:`~gpmultirate.kernels.precision.TridiagonalPrecision`;
        the evidence of a square or reduced observation then needs only the
        band of the posterior covariance.
        """
        return None

    def candidate_factors(self, kernel: Kernel, name: str, values):
        """Low-rank factors of the summand ``kernel`` with ``name`` set to each of ``values``.

        Returns ``(U, weights)``: ``U`` of shape ``(M, sum r_k)`` holds the
        observed bases ``Phi V_k`` side by side and ``weights`` the ``D_k``,
        so that the summand's data covariance at ``values[k]`` is
        ``U_k D_k U_k^T``.  None when ``kernel`` is not a summand reached
        through sums, or is not low rank.
        """
        if self.kernel is not kernel:
            return None
        factors = []
        for value in values:
            candidate = clone(kernel).set_params(**{name: float(value)})
            factor = observe(candidate, self.observation).low_rank()
            if factor is None:
                return None
            factors.append(factor)
        U = self.observation.matrix @ np.column_stack([basis for basis, _ in factors])
        return U, [weight for _, weight in factors]

    # -------------------------------------------------------------- roles
    def roles(self) -> list[Role]:
        """One :class:`Role` per free entry of ``kernel.theta``, in order."""
        declared = getattr(self.kernel, "tuning_roles", {})
        partners = getattr(self.kernel, "tuning_partners", {})
        transform_of = getattr(self.kernel, "theta_transform", None)
        roles = []
        for h in self.kernel.hyperparameters:
            if h.fixed:
                continue
            kind, power = declared.get(h.name, ("other", 1.0))
            transform = LOG if transform_of is None else transform_of(h.name)
            role = Role(self.path + h.name, kind, self.kernel, h.name, power, transform,
                        partners.get(h.name))
            roles += [role] * h.n_elements
        return roles

    def scale_groups(self):
        """Independent additive parts of ``S``, each with its own amplitudes, or None.

        A list of ``(positions, S_part)`` with ``S = sum S_part``: scaling the
        amplitudes at ``positions`` (in :meth:`roles`) scales ``S_part``
        alone.  Only several inputs offer it; tuning then fits each input's
        scale before the gradient steps.
        """
        return None

    def scale_roles(self) -> list[int] | None:
        """Positions (in :meth:`roles`) of amplitudes that together scale all of ``K``.

        None when no set of free amplitudes scales the whole kernel.
        """
        roles = self.roles()
        amplitudes = [i for i, role in enumerate(roles) if role.kind == "amplitude"]
        owned = [h.name for h in self.kernel.hyperparameters]
        declared = getattr(self.kernel, "tuning_roles", {})
        every_amplitude = [n for n in owned if declared.get(n, ("other",))[0] == "amplitude"]
        if not amplitudes or len(amplitudes) != len(every_amplitude):
            return None
        return amplitudes

    def amplitude_couplings(self) -> list[tuple[int, int]]:
        """Positions (in :meth:`roles`) of correlations and of the amplitudes scaling their terms.

        ``[(correlation, amplitude)]``, one amplitude per correlation.  DC's
        prior precision scales with ``1 / (c (1 - beta^2))``, so along the
        evidence's valleys ``c`` and ``beta`` move together; tuning measures
        such an amplitude against its correlation.  Empty unless a free
        constant multiplies a term with exactly one correlation.
        """
        return []


class StructuredKernel:
    """Mixin of kernels that answer for their own structure: the extension point.

    A subclass (also a scikit-learn ``Kernel``) may

    * override :meth:`observed` to return a term whose methods use its
      structure (subclass :class:`ObservedTerm`, or use :class:`LowRankTerm`);
    * override :meth:`observed_at_instants` likewise for readings at their
      own instants (see :mod:`gpmultirate.kernels.instants` and
      :mod:`gpmultirate.kernels.hold`);
    * declare ``tuning_roles``, a dict from hyperparameter name to
      ``(kind, power)`` (see :class:`Role`), so that tuning treats decays,
      frequencies and amplitudes well.

    Everything not overridden falls back to the dense answers of
    :class:`ObservedTerm`.
    """

    #: ``{name: (kind, power)}``, see :class:`Role`
    tuning_roles: dict = {}

    def observed(self, observation, path: str = "") -> ObservedTerm:
        """This kernel seen through ``observation``; dense unless overridden."""
        return ObservedTerm(self, observation, path)

    def observed_at_instants(self, observation, path: str = "") -> ObservedTerm:
        """This kernel seen through readings at their own instants; dense unless overridden.

        ``observation`` has no regressor on the integer lags (a
        :class:`~gpmultirate.observations.TimedConvolution`); its
        :meth:`~gpmultirate.observations.Observation.dense_term` forms the
        covariance from the kernel at the readings' real lags.
        """
        return observation.dense_term(self, path)

    def roles_term(self, path: str = "") -> ObservedTerm:
        """The term that answers questions about the hyperparameters only (no observation)."""
        return ObservedTerm(self, None, path)


class SumTerm(ObservedTerm):
    """``k1 + k2``: every answer is the sum (or concatenation) of the terms' answers."""

    def __init__(self, kernel, first: ObservedTerm, second: ObservedTerm, observation, path):
        super().__init__(kernel, observation, path)
        self.first, self.second = first, second

    def kernel_matrix(self):
        return self.first.kernel_matrix() + self.second.kernel_matrix()

    def parameter_contractor(self):
        K1, c1 = self.first.parameter_contractor()
        K2, c2 = self.second.parameter_contractor()
        return K1 + K2, lambda A: np.concatenate([c1(A), c2(A)])

    def covariance(self):
        return self.first.covariance() + self.second.covariance()

    def covariance_with_contractor(self):
        S1, c1 = self.first.covariance_with_contractor()
        S2, c2 = self.second.covariance_with_contractor()
        return S1 + S2, lambda W: np.concatenate([c1(W), c2(W)])

    def covariance_with_derivatives(self):
        S1, d1 = self.first.covariance_with_derivatives()
        S2, d2 = self.second.covariance_with_derivatives()
        return S1 + S2, d1 + d2

    def regressor_times_kernel(self):
        return self.first.regressor_times_kernel() + self.second.regressor_times_kernel()

    def covariance_blocks(self, split):
        cross, var = self.first.covariance_blocks(split)
        cross2, var2 = self.second.covariance_blocks(split)
        return cross + cross2, var + var2

    def cross_covariance(self, lags):
        return self.first.cross_covariance(lags) + self.second.cross_covariance(lags)

    def covariance_without(self, kernel):
        if self.kernel is kernel:
            return super().covariance_without(kernel)
        for inside, other in ((self.first, self.second), (self.second, self.first)):
            rest = inside.covariance_without(kernel)
            if rest is not None:
                return rest + other.covariance()
        return None

    def candidate_factors(self, kernel, name, values):
        found = self.first.candidate_factors(kernel, name, values)
        if found is None:
            found = self.second.candidate_factors(kernel, name, values)
        return found

    def roles(self):
        return self.first.roles() + self.second.roles()

    def scale_roles(self):
        first, second = self.first.scale_roles(), self.second.scale_roles()
        if first is None or second is None:
            return None
        return first + [len(self.first.roles()) + i for i in second]

    def amplitude_couplings(self):
        return concatenated_couplings([self.first, self.second])


def concatenated_couplings(terms) -> list[tuple[int, int]]:
    """The amplitude couplings of terms whose roles are concatenated in order."""
    found, start = [], 0
    for term in terms:
        found += [(j + start, a + start) for j, a in term.amplitude_couplings()]
        start += len(term.roles())
    return found


class ScaledTerm(ObservedTerm):
    """``c * k`` (either order) with the constant kept a scalar.

    The derivative with respect to ``log c`` of ``c X`` is ``c X`` itself,
    and every other derivative is ``c`` times that of ``k``.
    """

    def __init__(self, kernel, constant, inner: ObservedTerm, constant_first, observation, path):
        super().__init__(kernel, observation, path)
        self.value = float(constant.constant_value)
        self.free = not constant.hyperparameter_constant_value.fixed
        self.constant = constant
        self.inner = inner
        self.constant_first = constant_first

    def _join(self, own, rest):
        return np.concatenate([own, rest] if self.constant_first else [rest, own])

    def kernel_matrix(self):
        return self.value * self.inner.kernel_matrix()

    def parameter_contractor(self):
        K_inner, c_inner = self.inner.parameter_contractor()
        K = self.value * K_inner

        def contract(A):
            own = np.array([np.sum(A * K)]) if self.free else np.empty(0)
            return self._join(own, c_inner(self.value * A))

        return K, contract

    def covariance(self):
        return self.value * self.inner.covariance()

    def precision(self):
        inner = self.inner.precision()
        if inner is None or not self.value > 0.0:
            return None
        return inner.scaled(self.value, self.free, self.constant_first)

    def covariance_with_contractor(self):
        S_inner, c_inner = self.inner.covariance_with_contractor()
        S = self.value * S_inner

        def contract(W):
            own = np.array([np.sum(W * S)]) if self.free else np.empty(0)
            return self._join(own, c_inner(self.value * W))

        return S, contract

    def covariance_with_derivatives(self):
        S_inner, d_inner = self.inner.covariance_with_derivatives()
        S = self.value * S_inner
        rest = [
            (item[0], self.value * item[1]) if isinstance(item, tuple) else self.value * item
            for item in d_inner
        ]
        own = [S] if self.free else []
        return S, (own + rest if self.constant_first else rest + own)

    def regressor_times_kernel(self):
        return self.value * self.inner.regressor_times_kernel()

    def covariance_blocks(self, split):
        cross, var = self.inner.covariance_blocks(split)
        return self.value * cross, self.value * var

    def cross_covariance(self, lags):
        return self.value * self.inner.cross_covariance(lags)

    def _own_roles(self):
        if not self.free:
            return []
        prefix = self.path + ("k1__" if self.constant_first else "k2__")
        return [Role(prefix + "constant_value", "amplitude", self.constant, "constant_value")]

    def roles(self):
        own, rest = self._own_roles(), self.inner.roles()
        return own + rest if self.constant_first else rest + own

    def scale_roles(self):
        # the first factor's amplitudes if it has any, else the second's
        # (a fixed constant has no role, so the inner positions are unchanged)
        own = [0 if self.constant_first else len(self.inner.roles())] if self.free else None
        inner = self.inner.scale_roles()
        if self.constant_first:
            return own if own is not None else inner
        return inner if inner is not None else own

    def amplitude_couplings(self):
        inner_roles = self.inner.roles()
        shift = 1 if (self.free and self.constant_first) else 0
        found = [(j + shift, a + shift) for j, a in self.inner.amplitude_couplings()]
        correlations = [j for j, role in enumerate(inner_roles) if role.kind == "correlation"]
        if self.free and not found and len(correlations) == 1:
            own = 0 if self.constant_first else len(inner_roles)
            found = [(correlations[0] + shift, own)]
        return found


class ProductTerm(ObservedTerm):
    """A general product ``k1 * k2``: dense, with the product rule in parameter space.

    ``d(K1 * K2) = dK1 * K2 + K1 * dK2`` (elementwise), so the first factor
    is contracted against ``A * K2`` and the second against ``A * K1``.
    """

    def __init__(self, kernel, first: ObservedTerm, second: ObservedTerm, observation, path):
        super().__init__(kernel, observation, path)
        self.first, self.second = first, second

    def kernel_matrix(self):
        return self.first.kernel_matrix() * self.second.kernel_matrix()

    def parameter_contractor(self):
        K1, c1 = self.first.parameter_contractor()
        K2, c2 = self.second.parameter_contractor()
        return K1 * K2, lambda A: np.concatenate([c1(A * K2), c2(A * K1)])

    def roles(self):
        return self.first.roles() + self.second.roles()

    def scale_roles(self):
        first = self.first.scale_roles()
        if first is not None:
            return first
        second = self.second.scale_roles()
        if second is None:
            return None
        return [len(self.first.roles()) + i for i in second]

    def amplitude_couplings(self):
        return concatenated_couplings([self.first, self.second])


class LowRankTerm(ObservedTerm):
    """A term with ``K = V D V^T`` of low rank ``r``, e.g. PK (``r = 2``) or a constant.

    The data covariance is ``S = U D U^T`` with ``U = Phi V``, so nothing of
    size ``P x P`` or ``M x M x n_theta`` is formed: ``S`` costs one product
    ``Phi V``, its gradient contraction ``O(M^2 q)`` and its derivatives stay
    factored, ``dS_j = U_x D_j U_x^T`` on the extended basis
    ``V_x = [V, V']``.

    Parameters
    ----------
    kernel : sklearn Kernel
    observation : Observation
    basis : ndarray of shape (P, r)
        ``V``.
    weight : ndarray of shape (r, r)
        ``D``, symmetric positive semidefinite.
    derivative_basis : ndarray of shape (P, q - r), optional
        ``V'``, the extra columns the derivatives need.
    derivative_weights : sequence of ndarray of shape (q, q)
        ``D_j`` with ``dK_j = V_x D_j V_x^T``, one per free hyperparameter
        in ``theta`` order.
    path : str, default=""

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import PK, observe
    >>> op = DownsampledConvolution(np.arange(1.0, 9.0), factor=2, order=6)
    >>> kernel = PK(alpha=0.8, omega=0.7)
    >>> term = observe(kernel, op)
    >>> type(term).__name__
    'LowRankTerm'
    >>> Phi, K = op.matrix, kernel(op.lags)
    >>> bool(np.allclose(term.covariance(), Phi @ K @ Phi.T))
    True
    """

    def __init__(self, kernel, observation, basis, weight, derivative_basis=None,
                 derivative_weights=(), path: str = ""):
        super().__init__(kernel, observation, path)
        self.basis = basis
        self.weight = weight
        self.derivative_basis = derivative_basis
        self.derivative_weights = list(derivative_weights)
        self._observed_basis = None

    def low_rank(self):
        return self.basis, self.weight

    def _extended(self):
        if self.derivative_basis is None:
            return self.basis
        return np.hstack([self.basis, self.derivative_basis])

    def observed_basis(self) -> np.ndarray:
        """``U_x = Phi V_x``, of shape ``(M, q)`` (computed once)."""
        if self._observed_basis is None:
            self._observed_basis = self.observation.matrix @ self._extended()
        return self._observed_basis

    def parameter_contractor(self):
        V = self._extended()
        K = self.kernel_matrix()
        weights = self.derivative_weights

        def contract(A):
            projected = V.T @ A @ V
            return np.array([np.sum(D * projected) for D in weights])

        return K, contract

    def covariance(self):
        U = self.observed_basis()[:, : self.basis.shape[1]]
        return (U @ self.weight) @ U.T

    def covariance_with_contractor(self):
        U = self.observed_basis()
        S = self.covariance()
        weights = self.derivative_weights

        def contract(W):
            projected = U.T @ (W @ U)
            return np.array([np.sum(D * projected) for D in weights])

        return S, contract

    def covariance_with_derivatives(self):
        U = self.observed_basis()
        return self.covariance(), [(U, D) for D in self.derivative_weights]

    def regressor_times_kernel(self):
        r = self.basis.shape[1]
        return (self.observed_basis()[:, :r] @ self.weight) @ self.basis.T

    def covariance_blocks(self, split):
        U = self.observed_basis()[:, : self.basis.shape[1]]
        UD = U[split:] @ self.weight
        return UD @ U[:split].T, np.einsum("ij,ij->i", UD, U[split:])


def split_constant(kernel: Product):
    """``(constant, other, constant_first)`` of ``c * k`` or ``k * c``, else None."""
    if isinstance(kernel.k1, ConstantKernel):
        return kernel.k1, kernel.k2, True
    if isinstance(kernel.k2, ConstantKernel):
        return kernel.k2, kernel.k1, False
    return None


class ConstantTerm(LowRankTerm):
    """A constant alone, of rank one: ``K = c 1 1^T``; its value is an amplitude."""

    def __init__(self, kernel: ConstantKernel, observation, path: str = ""):
        value = float(kernel.constant_value)
        weight = np.array([[value]])
        self.free = not kernel.hyperparameter_constant_value.fixed
        basis = None if observation is None else np.ones((observation.order, 1))
        super().__init__(kernel, observation, basis, weight, None,
                         [weight] if self.free else [], path)

    def roles(self):
        if not self.free:
            return []
        return [Role(self.path + "constant_value", "amplitude", self.kernel, "constant_value")]

    def scale_roles(self):
        return [0] if self.free else None


def observe(kernel: Kernel, observation=None, path: str = "") -> ObservedTerm:
    """The one walker: ``kernel`` seen through ``observation``, as a tree of terms.

    Parameters
    ----------
    kernel : sklearn Kernel
        Prior covariance over lag: a lag kernel, any scikit-learn kernel,
        or sums and products of them.
    observation : Observation, optional
        The observation; None for questions about roles only.
    path : str, default=""
        Prefix of the parameter names (used by the recursion).

    Returns
    -------
    ObservedTerm

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import DC, PK, observe
    >>> op = DownsampledConvolution(np.arange(1.0, 13.0), factor=3, order=12)
    >>> kernel = C(2.0) * DC(alpha=0.8, beta=0.7) + PK(alpha=0.8, omega=1.0)
    >>> term = observe(kernel, op)
    >>> S, contract = term.covariance_with_contractor()
    >>> bool(np.allclose(S, op.matrix @ kernel(op.lags) @ op.matrix.T))
    True
    >>> [role.kind for role in term.roles()]
    ['amplitude', 'decay', 'correlation', 'decay', 'frequency', 'amplitude', 'amplitude']
    """
    if isinstance(kernel, Sum):
        return SumTerm(
            kernel,
            observe(kernel.k1, observation, path + "k1__"),
            observe(kernel.k2, observation, path + "k2__"),
            observation,
            path,
        )
    if isinstance(kernel, Product):
        split = split_constant(kernel)
        if split is not None:
            constant, other, first = split
            inner = observe(other, observation, path + ("k2__" if first else "k1__"))
            return ScaledTerm(kernel, constant, inner, first, observation, path)
        if observation is not None and not observation.has_regressor:
            # the product rule is applied in parameter space, through the regressor
            return observation.dense_term(kernel, path)
        return ProductTerm(
            kernel,
            observe(kernel.k1, observation, path + "k1__"),
            observe(kernel.k2, observation, path + "k2__"),
            observation,
            path,
        )
    if observation is None:  # the hyperparameters only
        if isinstance(kernel, ConstantKernel):
            return ConstantTerm(kernel, None, path)
        if isinstance(kernel, StructuredKernel):
            return kernel.roles_term(path)
        return ObservedTerm(kernel, None, path)
    if isinstance(kernel, ConstantKernel):
        return observation.constant_term(kernel, path)
    if isinstance(kernel, StructuredKernel):
        return observation.structured_term(kernel, path)
    return observation.dense_term(kernel, path)


def rescaled(kernel: Kernel, factor: float) -> Kernel:
    """A copy of ``kernel`` whose covariance is ``factor`` times larger, bounds included.

    The amplitudes that together scale the whole kernel
    (:meth:`ObservedTerm.scale_roles`) are multiplied by
    ``factor ** power``, and so are their bounds, so that tuning explores
    the same shapes.  A kernel without such amplitudes is wrapped as
    ``ConstantKernel(factor, "fixed") * kernel``.

    Parameters
    ----------
    kernel : sklearn Kernel
    factor : float
        Positive.

    Returns
    -------
    sklearn Kernel

    Examples
    --------
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate.kernels import DC
    >>> kernel = rescaled(C(2.0, (1e-3, 1e3)) * DC(0.8, 0.9), 100.0)
    >>> kernel.k1.constant_value, kernel.k1.constant_value_bounds
    (200.0, (0.1, 100000.0))
    >>> rescaled(DC(0.8, 0.9), 100.0)
    10**2 * DC(alpha=0.8, beta=0.9)
    """
    term = observe(kernel)
    positions = term.scale_roles()
    if positions is None:
        return ConstantKernel(float(factor), "fixed") * clone(kernel)
    copy = clone(kernel)
    params = copy.get_params()
    roles = term.roles()
    changes = {}
    for i in positions:
        role = roles[i]
        scale = float(factor) ** role.power
        changes[role.name] = params[role.name] * scale
        bounds = params.get(role.name + "_bounds")
        if bounds is not None and not isinstance(bounds, str):
            changes[role.name + "_bounds"] = (bounds[0] * scale, bounds[1] * scale)
    copy.set_params(**changes)
    return copy


def cross_kernel(kernel: Kernel, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """``k(X, Y)`` as a function of the lags: ``k(x, x)`` wherever a row of ``X`` equals one of ``Y``.

    scikit-learn's ``WhiteKernel`` (alone or in a sum or product) gives
    ``k(X, Y) = 0`` whenever ``Y`` is passed, even at equal points, while
    ``k(X)`` has its variance on the diagonal: the posterior at the integer
    lags (``coef_``, from ``k(X)``) and at any lag (from ``k(X, Y)``) would
    then disagree.  Such a kernel (found on a few of the points: ``k(X)``
    and ``k(X, Y=X)`` differ) gets the diagonal value ``k(x, x)`` at every
    coinciding pair; any other kernel is evaluated as it is.

    Examples
    --------
    >>> from sklearn.gaussian_process.kernels import WhiteKernel
    >>> cross_kernel(WhiteKernel(2.0), np.array([[0.0], [0.5]]), np.array([[0.0], [1.0]]))
    array([[2., 0.],
           [0., 0.]])
    """
    K = kernel(X, Y)
    probe = X[: min(8, X.shape[0])]
    if probe.shape[0] == 0 or np.array_equal(kernel(probe), kernel(probe, probe.copy())):
        return K
    a, b = np.nonzero(np.all(X[:, None, :] == Y[None, :, :], axis=2))
    if a.size:
        K = np.array(K, dtype=float)
        K[a, b] = kernel.diag(X)[a]
    return K
