"""Independent priors for the impulse responses of several inputs.

With ``n`` inputs the coefficients are stacked input-major,
``g = [g_0; g_1; ...]``, and the prior makes the inputs' responses
independent: ``K = blockdiag(K_0, K_1, ...)``.  As a scikit-learn kernel
over pairs ``X = (input, lag)`` this is
``k((i, t), (j, s)) = [i = j] k_i(t, s)``.  Through an observation
``Phi = [Phi_0, Phi_1, ...]`` the data covariance is the sum
``sum_i Phi_i K_i Phi_i^T``, so each input's kernel keeps its own fast
path on its own columns (:meth:`Observation.input_block`).
"""

from __future__ import annotations

import numpy as np
from scipy import linalg
from sklearn.base import clone
from sklearn.gaussian_process.kernels import Hyperparameter, Kernel

from gpmultirate.kernels.structure import (
    ObservedTerm, StructuredKernel, concatenated_couplings, observe,
)
from gpmultirate.kernels.transforms import check_kernel
from gpmultirate.validation import as_real_array

__all__ = ["BlockTerm", "PerInputKernel", "input_kernels", "kernel_for_inputs", "like_inputs"]


class PerInputKernel(StructuredKernel, Kernel):
    """One kernel per input, independent across inputs: ``k((i, t), (j, s)) = [i = j] k_i(t, s)``.

    Its hyperparameters are those of the input kernels, named
    ``input<i>__<name>``, so that each input's kernel is tuned separately.

    Parameters
    ----------
    kernels : sequence of sklearn Kernel
        The prior of each input's impulse response over lag.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.kernels import DC, TC, PerInputKernel
    >>> kernel = PerInputKernel([TC(0.5), DC(0.8, 0.9)])
    >>> X = np.array([[0, 0.0], [0, 1.0], [1, 0.0]])
    >>> kernel(X).round(3)
    array([[1. , 0.5, 0. ],
           [0.5, 0.5, 0. ],
           [0. , 0. , 1. ]])
    >>> kernel.theta.shape
    (3,)
    """

    def __init__(self, kernels):
        self.kernels = kernels

    @property
    def n_inputs(self) -> int:
        return len(self.kernels)

    def get_params(self, deep: bool = True) -> dict:
        """The kernels and, with ``deep=True``, ``input<i>`` and ``input<i>__<name>``."""
        params = {"kernels": self.kernels}
        if deep:
            for i, kernel in enumerate(self.kernels):
                params[f"input{i}"] = kernel
                params.update(
                    (f"input{i}__{key}", value) for key, value in kernel.get_params().items()
                )
        return params

    @property
    def hyperparameters(self) -> list:
        return [
            Hyperparameter(f"input{i}__" + h.name, h.value_type, h.bounds, h.n_elements, h.fixed)
            for i, kernel in enumerate(self.kernels)
            for h in kernel.hyperparameters
        ]

    @property
    def theta(self) -> np.ndarray:
        parts = [kernel.theta for kernel in self.kernels]
        return np.concatenate(parts) if parts else np.empty(0)

    @theta.setter
    def theta(self, theta) -> None:
        start = 0
        for kernel in self.kernels:
            n = kernel.n_dims
            kernel.theta = theta[start : start + n]
            start += n

    @property
    def bounds(self) -> np.ndarray:
        parts = [kernel.bounds.reshape(-1, 2) for kernel in self.kernels]
        return np.vstack(parts) if parts else np.empty((0, 2))

    def _split(self, X, name):
        X = as_real_array(X, name)
        if X.ndim != 2 or X.shape[1] != 2:
            raise ValueError(f"{name} must have shape (n, 2): columns input and lag; got {X.shape}")
        inputs = X[:, 0].astype(int)
        if np.any(inputs != X[:, 0]) or np.any(inputs < 0) or np.any(inputs >= self.n_inputs):
            raise ValueError(f"{name}[:, 0] must hold input indices in 0..{self.n_inputs - 1}")
        return inputs, X[:, 1:]

    def __call__(self, X, Y=None, eval_gradient=False):
        """``k(X, Y)`` over ``(input, lag)`` pairs and, for ``Y=None``, the gradient."""
        if eval_gradient and Y is not None:
            raise ValueError("gradient can only be evaluated when Y is None")
        rows, t = self._split(X, "X")
        cols, s = (rows, t) if Y is None else self._split(Y, "Y")
        K = np.zeros((rows.shape[0], cols.shape[0]))
        gradient = np.zeros((rows.shape[0], cols.shape[0], self.n_dims))
        start = 0
        for i, kernel in enumerate(self.kernels):
            a, b = np.flatnonzero(rows == i), np.flatnonzero(cols == i)
            n = kernel.n_dims
            if a.size and b.size:
                if eval_gradient:
                    block, d_block = kernel(t[a], eval_gradient=True)
                    gradient[np.ix_(a, a, np.arange(start, start + n))] = d_block
                else:
                    block = kernel(t[a], None if Y is None else s[b])
                K[np.ix_(a, b)] = block
            start += n
        return (K, gradient) if eval_gradient else K

    def diag(self, X) -> np.ndarray:
        rows, t = self._split(X, "X")
        out = np.zeros(rows.shape[0])
        for i, kernel in enumerate(self.kernels):
            a = np.flatnonzero(rows == i)
            if a.size:
                out[a] = kernel.diag(t[a])
        return out

    def is_stationary(self) -> bool:
        return False

    def __eq__(self, other) -> bool:
        return (
            type(self) is type(other)
            and len(self.kernels) == len(other.kernels)
            and all(a == b for a, b in zip(self.kernels, other.kernels))
        )

    def __repr__(self) -> str:
        return f"PerInputKernel([{', '.join(repr(k) for k in self.kernels)}])"

    def observed(self, observation, path: str = ""):
        """A :class:`BlockTerm`: each input's kernel through that input's columns."""
        return BlockTerm(
            self,
            [
                observe(kernel, observation.input_block(i), f"{path}input{i}__")
                for i, kernel in enumerate(self.kernels)
            ],
            observation,
            path,
        )

    def observed_at_instants(self, observation, path: str = ""):
        """Each input's kernel through that input's readings (:meth:`observed`), if they match."""
        if self.n_inputs != observation.n_inputs:
            return observation.dense_term(self, path)
        return self.observed(observation, path)

    def roles_term(self, path: str = "") -> ObservedTerm:
        """The term used for questions about the hyperparameters only."""
        return BlockTerm(
            self, [observe(k, None, f"{path}input{i}__") for i, k in enumerate(self.kernels)],
            None, path,
        )


def input_kernels(kernel) -> list:
    """The kernel of each input: those of a :class:`PerInputKernel`, else ``[kernel]``.

    Examples
    --------
    >>> from gpmultirate.kernels import DC, TC
    >>> input_kernels(PerInputKernel([TC(0.5), DC(0.8, 0.9)]))
    [TC(alpha=0.5), DC(alpha=0.8, beta=0.9)]
    >>> input_kernels(TC(0.5))
    [TC(alpha=0.5)]
    """
    return list(kernel.kernels) if isinstance(kernel, PerInputKernel) else [kernel]


def like_inputs(kernels: list, template) -> Kernel:
    """``kernels`` joined as ``template`` is: a :class:`PerInputKernel` or a single kernel."""
    return PerInputKernel(list(kernels)) if isinstance(template, PerInputKernel) else kernels[0]


def kernel_for_inputs(kernel, n_inputs: int) -> Kernel:
    """The prior of ``n_inputs`` inputs from what a user gives.

    Parameters
    ----------
    kernel : sklearn Kernel, list of them, or PerInputKernel
        One kernel (copied for every input, each copy tuned separately), a
        list with one kernel per input, or a :class:`PerInputKernel`.
    n_inputs : int

    Returns
    -------
    sklearn Kernel
        A checked copy: the kernel itself for one input, else a
        :class:`PerInputKernel`.

    Examples
    --------
    >>> from gpmultirate.kernels import DC
    >>> kernel_for_inputs(DC(0.8, 0.9), 2)
    PerInputKernel([DC(alpha=0.8, beta=0.9), DC(alpha=0.8, beta=0.9)])
    """
    if isinstance(kernel, PerInputKernel):
        kernels = list(kernel.kernels)
    elif isinstance(kernel, (list, tuple)):
        kernels = list(kernel)
    else:
        kernels = [check_kernel(kernel)] * n_inputs
    if len(kernels) != n_inputs:
        raise ValueError(
            f"kernel must be one kernel or a list with one kernel per input ({n_inputs}); "
            f"got a list of {len(kernels)}"
        )
    kernels = [clone(check_kernel(k, f"kernel[{i}]")) for i, k in enumerate(kernels)]
    return kernels[0] if n_inputs == 1 else PerInputKernel(kernels)


class BlockTerm(ObservedTerm):
    """Independent inputs: ``K = blockdiag(K_i)`` and ``S = sum_i Phi_i K_i Phi_i^T``."""

    def __init__(self, kernel, blocks, observation, path: str = ""):
        super().__init__(kernel, observation, path)
        self.blocks = blocks

    def kernel_matrix(self):
        return linalg.block_diag(*[block.kernel_matrix() for block in self.blocks])

    def parameter_contractor(self):
        parts = [block.parameter_contractor() for block in self.blocks]
        P = self.observation.order

        def contract(A):
            return np.concatenate(
                [c(A[i * P : (i + 1) * P, i * P : (i + 1) * P]) for i, (_, c) in enumerate(parts)]
            )

        return linalg.block_diag(*[K for K, _ in parts]), contract

    def covariance(self):
        return sum(block.covariance() for block in self.blocks)

    def covariance_blocks(self, split):
        parts = [block.covariance_blocks(split) for block in self.blocks]
        return sum(cross for cross, _ in parts), sum(var for _, var in parts)

    def covariance_with_contractor(self):
        parts = [block.covariance_with_contractor() for block in self.blocks]
        S = sum(S_i for S_i, _ in parts)
        return S, lambda W: np.concatenate([c(W) for _, c in parts])

    def covariance_with_derivatives(self):
        S, items = 0.0, []
        for block in self.blocks:
            S_i, items_i = block.covariance_with_derivatives()
            S = S + S_i
            items += items_i
        return S, items

    def regressor_times_kernel(self):
        return np.hstack([block.regressor_times_kernel() for block in self.blocks])

    def covariance_without(self, kernel):
        if self.kernel is kernel:
            return super().covariance_without(kernel)
        for i, block in enumerate(self.blocks):
            rest = block.covariance_without(kernel)
            if rest is not None:
                return rest + sum(
                    other.covariance() for j, other in enumerate(self.blocks) if j != i
                )
        return None

    def candidate_factors(self, kernel, name, values):
        for block in self.blocks:
            found = block.candidate_factors(kernel, name, values)
            if found is not None:
                return found
        return None

    def roles(self):
        return [role for block in self.blocks for role in block.roles()]

    def amplitude_couplings(self):
        return concatenated_couplings(self.blocks)

    def scale_groups(self):
        groups, start = [], 0
        for block in self.blocks:
            inner = block.scale_roles()
            if inner is None:
                return None
            groups.append(([start + i for i in inner], block.covariance()))
            start += len(block.roles())
        return groups

    def scale_roles(self):
        positions, start = [], 0
        for block in self.blocks:
            inner = block.scale_roles()
            if inner is None:
                return None
            positions += [start + i for i in inner]
            start += len(block.roles())
        return positions
