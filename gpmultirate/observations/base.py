"""The observation family: how the slow data see the impulse response.

Every observation is linear in the FIR coefficients ``g`` at the lags
``0..P-1``: ``y = Phi g + e``.  :class:`Observation` is the interface that
inference and the kernels' structured terms use; its members own the
structure of ``Phi``:

* :class:`~gpmultirate.observations.convolution.DownsampledConvolution`,
  the paper's eq. (8): uniformly spaced slow samples of a convolution, whose
  rows are a strided view of the input and which offers its uniform
  sampling to the diagonal recursion of shift-scaled kernels;
* :class:`~gpmultirate.observations.reduced.ReducedObservation`, the
  ``P x P`` triangular factor that summarizes a long record, whose products
  use triangular BLAS.

The base class implements everything from :attr:`Observation.matrix`, so a
new member needs only that (and ``order``, ``n_outputs``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from gpmultirate.kernels import ObservedTerm, observe
from gpmultirate.kernels.structure import ConstantTerm, cross_kernel
from gpmultirate.validation import check_array

__all__ = ["ColumnBlock", "Observation", "UniformSampling"]


class UniformSampling(NamedTuple):
    """Slow samples ``offset + m * factor``, ``m < n_outputs``, of the response to ``u`` from rest.

    ``offset < factor``: the sample before the first lies before the record.
    With ``selection``, the observed samples are the grid's entries
    ``selection`` (the others were not measured).
    """

    u: np.ndarray
    factor: int
    offset: int
    n_outputs: int
    selection: np.ndarray | None = None


class Observation:
    """A linear observation ``y = Phi g`` of the FIR coefficients at lags ``0..P-1``.

    Subclasses set ``order`` (``P``) and ``n_outputs`` (``M``) and provide
    :attr:`matrix`; the products below may be overridden where the
    structure of ``Phi`` makes them cheaper.  With several inputs
    (``n_inputs > 1``) the coefficients are stacked input-major, ``Phi`` has
    ``n_inputs * P`` columns and :attr:`lags` has the columns
    ``(input, lag)``.
    """

    order: int
    n_outputs: int
    n_inputs: int = 1
    #: samples a reduction has summarized (their likelihood is the noise model's
    #: :meth:`~gpmultirate.noise.WhiteNoise.remainder`)
    n_discarded: int = 0
    #: the sum of squares ``rho^2`` of those samples
    residual: float = 0.0
    #: the uniform sampling the diagonal recursion needs, if any
    uniform_sampling: UniformSampling | None = None
    #: whether the data are a regressor on the integer lags (:attr:`matrix`); readings
    #: between the ticks are not, and the routes that need ``Phi`` pass them by
    has_regressor: bool = True
    #: whether the readings see the response between the integer lags (a model of it
    #: is then fitted and drawn there)
    between_ticks: bool = False
    #: the layout of the observation in a model file (:mod:`gpmultirate.persistence`):
    #: ``"records"`` (each record's input and sample indices), ``"downsampled"``
    #: (one input, factor and offset) or ``"timed"`` (each record's input and instants)
    file_layout: str = "records"

    @property
    def shape(self) -> tuple[int, int]:
        """``(M, P)``, the shape of the regressor."""
        return (self.n_outputs, self.order)

    @property
    def records(self) -> list:
        """The records this observation stacks: itself, unless it is a stack."""
        return [self]

    @property
    def n_coefficients(self) -> int:
        """``n_inputs * P``, the number of columns of the regressor."""
        return self.n_inputs * self.order

    @property
    def lags(self) -> np.ndarray:
        """The kernel input of the coefficients.

        Lags ``0..P-1`` of shape ``(P, 1)`` for one input; for several, the
        pairs ``(input, lag)`` input-major, of shape ``(n_inputs * P, 2)``.
        """
        lags = np.arange(self.order, dtype=float)
        if self.n_inputs == 1:
            return lags[:, None]
        inputs = np.repeat(np.arange(self.n_inputs, dtype=float), self.order)
        return np.column_stack([inputs, np.tile(lags, self.n_inputs)])

    def input_block(self, k: int) -> "Observation":
        """The observation of the coefficients of input ``k`` alone (its columns of ``Phi``)."""
        if self.n_inputs == 1:
            return self
        return ColumnBlock(self, k)

    @property
    def matrix(self) -> np.ndarray:
        """The regressor ``Phi`` of shape ``(M, P)``."""
        raise NotImplementedError

    def regressor_view(self) -> np.ndarray:
        """``Phi`` in its cheapest read-only form (a view where possible)."""
        return self.matrix

    def __getstate__(self):
        # the regressor and the per-input blocks are rebuilt on demand: a
        # pickle holds only the data that define the observation
        state = self.__dict__.copy()
        if "_matrix" in state:
            state["_matrix"] = None
        if "_blocks" in state:
            state["_blocks"] = {}
        if "_gram" in state:
            state["_gram"] = None
        return state

    # ------------------------------------------------------------- products
    def matvec(self, coef) -> np.ndarray:
        """Return ``Phi @ coef``: the observed output of FIR coefficients ``coef``.

        ``coef`` has shape ``(P,)`` or ``(P, k)``.
        """
        coef = check_array(coef, "coef", rows=self.n_coefficients)
        return self.matrix @ coef

    def rmatvec(self, y) -> np.ndarray:
        """Return ``Phi.T @ y`` for ``y`` of shape ``(M,)`` or ``(M, k)``."""
        y = check_array(y, "y", rows=self.n_outputs)
        return self.matrix.T @ y

    def sandwich(self, K: np.ndarray) -> np.ndarray:
        """``Phi K Phi^T`` for a symmetric ``P x P`` matrix ``K``, exactly symmetric."""
        Phi = self.matrix
        A = Phi @ K @ Phi.T
        return 0.5 * (A + A.T)

    def project(self, W: np.ndarray) -> np.ndarray:
        """``Phi^T W Phi`` for a symmetric ``M x M`` matrix ``W``, exactly symmetric."""
        Phi = self.matrix
        A = Phi.T @ W @ Phi
        return 0.5 * (A + A.T)

    def regressor_shaped_outer(self, H: np.ndarray, G: np.ndarray) -> np.ndarray:
        """``H @ G.T`` where ``G`` has the sparsity of ``Phi`` (e.g. ``Phi D``)."""
        return H @ G.T

    def symmetric_times_regressor_shaped(self, W: np.ndarray, G: np.ndarray) -> np.ndarray:
        """``W @ G`` for a symmetric ``W``, where ``G`` has the sparsity of ``Phi``."""
        return W @ G

    # ------------------------------------------------------------- reduction
    def regressor_rows(self, start: int, stop: int) -> np.ndarray:
        """Rows ``start..stop-1`` of ``Phi`` (the reduction reads them block by block)."""
        return self.matrix[start:stop]

    def structured_gram(self, y=None):
        """``(Phi^T Phi, Phi^T y)`` from the structure of ``Phi``, or None without one.

        Members whose regressor has a structure that makes the Gram matrix
        cheaper than ``O(M P^2)`` override this (a convolution on a uniform
        grid: FFTs, :mod:`~gpmultirate.observations.gram`); the second entry
        is None without ``y``.
        """
        return None

    def gram(self, y=None, block_rows: int | None = None):
        """``Phi^T Phi`` and ``Phi^T y`` (None without ``y``), exactly symmetric.

        By the structure of ``Phi`` where its member has one
        (:meth:`structured_gram`), else by blocks of ``block_rows`` rows of
        ``Phi`` (never the whole regressor at once).

        Examples
        --------
        >>> import numpy as np
        >>> from gpmultirate import DownsampledConvolution
        >>> op = DownsampledConvolution(np.arange(1.0, 7.0), factor=2, order=2)
        >>> op.gram(np.ones(3))
        (array([[35., 26.],
               [26., 20.]]), array([9., 6.]))
        """
        if y is not None:
            y = check_array(y, "y", rows=self.n_outputs)
            if y.ndim != 1:
                raise ValueError(f"y must be one-dimensional; got shape {y.shape}")
        if y is None and getattr(self, "_gram", None) is not None:
            return self._gram, None
        found = self.structured_gram(y)
        if found is None:
            found = self._dense_gram(y, block_rows)
        if y is None:  # kept: the evidence by the prior precision asks for it repeatedly
            found[0].setflags(write=False)
            self._gram = found[0]
        return found

    def _dense_gram(self, y, block_rows):
        P = self.n_coefficients
        block = block_rows or max(2 * P, 1024)
        gram = np.zeros((P, P))
        projection = None if y is None else np.zeros(P)
        for start in range(0, self.n_outputs, block):
            rows = self.regressor_rows(start, start + block)
            gram += rows.T @ rows
            if y is not None:
                projection += rows.T @ y[start : start + block]
        gram += gram.T
        gram *= 0.5
        return gram, projection

    # ------------------------------------------------------ the kernel's terms
    def structured_term(self, kernel, path: str = "") -> ObservedTerm:
        """A :class:`~gpmultirate.kernels.StructuredKernel` leaf seen through this observation.

        What the walker (:func:`~gpmultirate.kernels.observe`) asks for each
        leaf that answers for its own structure: on the integer lags, the
        kernel's :meth:`~gpmultirate.kernels.StructuredKernel.observed`.
        """
        return kernel.observed(self, path)

    def constant_term(self, kernel, path: str = "") -> ObservedTerm:
        """A ``ConstantKernel`` leaf seen through this observation: rank one."""
        return ConstantTerm(kernel, self, path)

    def dense_term(self, kernel, path: str = "") -> ObservedTerm:
        """Any kernel seen through this observation, densely from ``K`` and ``Phi``."""
        return ObservedTerm(kernel, self, path)

    # ------------------------------------------------- with a kernel (dense)
    def kernel_matrix(self, kernel, eval_gradient: bool = False):
        """Return the prior covariance ``K`` of the coefficients at lags ``0..P-1``."""
        if not eval_gradient:
            return observe(kernel, self).kernel_matrix()
        return kernel(self.lags, eval_gradient=True)

    def covariance(self, kernel, eval_gradient: bool = False):
        """Return the prior covariance ``Phi K Phi^T`` of the noise-free observed output.

        With ``eval_gradient=True`` also return its gradient with respect to
        ``kernel.theta``, of shape ``(M, M, n_theta)``.
        """
        if not eval_gradient:
            return self.sandwich(self.kernel_matrix(kernel))
        Phi = self.matrix
        K, dK = self.kernel_matrix(kernel, eval_gradient=True)
        grad = np.einsum("mi,ijk,nj->mnk", Phi, dK, Phi, optimize=True)
        return self.sandwich(K), grad

    def cross_covariance(self, kernel, lags) -> np.ndarray:
        """Return ``Cov(g(lags), y) = k(lags, 0..P-1) Phi^T``, shape ``(n, M)``."""
        return self.dense_cross_covariance(kernel, lags)

    def dense_cross_covariance(self, kernel, lags) -> np.ndarray:
        """``Cov(g(lags), y)`` from the kernel between ``lags`` and the observation's own lags."""
        return cross_kernel(kernel, lags, self.lags) @ self.matrix.T

    # ------------------------------------------------- what a fit of these data reads
    def fitted_readings(self, posterior, y: np.ndarray, noise_level: float) -> list:
        """The posterior mean of the noise-free data, one array per record.

        Here the fast output at each record's sample indices, the convolution
        of the record's input(s) with the posterior mean of the coefficients
        (input-major).  ``y`` and the white ``noise_level`` are those of the
        fit (readings off the ticks need them).
        """
        coef = posterior.coef.reshape(self.n_inputs, -1)
        out = []
        for record in self.records:
            x = np.asarray(record.u, dtype=float)
            x = x[:, None] if x.ndim == 1 else x
            n = x.shape[0]
            fitted = sum(np.convolve(x[:, k], coef[k])[:n] for k in range(x.shape[1]))
            out.append(fitted[record.sample_indices])
        return out

    def split_by_record(self, values: np.ndarray) -> list:
        """``values`` of the stacked data as one array per record."""
        bounds = np.cumsum([0] + [record.n_outputs for record in self.records])
        return [values[a:b] for a, b in zip(bounds[:-1], bounds[1:])]

    def readings_model(self, readings):
        """How a fit of these data models new ``readings`` (a timed observation).

        Here as they are: linear functionals of the response at real lags.
        """
        return readings

    def posterior_readings(self, posterior, data, kernel):
        """Mean and variance of these noise-free data under the posterior of a fit.

        ``posterior``: the fit's :class:`~gpmultirate.inference.GaussianCoefficients`
        of the coefficients; ``data``, ``kernel``: the observation it
        conditioned on and its kernel.  Here ``Phi g`` for the regressor
        ``Phi`` (:attr:`matrix`).
        """
        return posterior.linear_map(self.matrix)

    def interpolation_check(self, coef) -> float | None:
        """The estimated rms error of the data's interpolation between the ticks, or None.

        None here: these data are read without interpolation.
        """
        return None


class ColumnBlock(Observation):
    """The columns of one input of a several-input observation, as an observation.

    Parameters
    ----------
    parent : Observation
    k : int
        The input.
    """

    def __init__(self, parent: Observation, k: int):
        self.parent = parent
        self.input = k
        self.order = parent.order
        self.n_outputs = parent.n_outputs
        self._matrix = None

    @property
    def matrix(self) -> np.ndarray:
        if self._matrix is None:
            P, k = self.order, self.input
            block = np.ascontiguousarray(self.parent.matrix[:, k * P : (k + 1) * P])
            block.setflags(write=False)
            self._matrix = block
        return self._matrix

    def __repr__(self) -> str:
        return f"ColumnBlock({self.parent!r}, input={self.input})"
