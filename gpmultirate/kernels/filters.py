r"""The DC kernel through an observation by recursive filters.

``K = D T D`` with the envelope ``D = diag(alpha^(t/2))`` and the Toeplitz
matrix ``T[i, j] = beta^|i - j|``, whose product with a row vector is a pair
of first-order recursive filters (causal and anticausal, the centre counted
once).  With ``G = Phi D`` and ``H = G T``:

* ``S = Phi K Phi^T = H G^T``, ``O(M P + M^2 P)`` instead of ``O(M P^2)``;
  formed as ``(G R)(G R)^T`` with ``T = R R^T`` the Cholesky factor of the
  AR(1) correlation (``G R`` is the anticausal filter of ``G``, scaled by
  ``sqrt(1 - beta^2)`` beyond its first column), a symmetric rank-k update
  of half the flops of the general product;
* the derivative in ``log alpha`` is ``E K + K E`` with ``E = diag(t / 2)``,
  so ``tr(W Phi dK Phi^T) = sum_{m, i} t_i H[m, i] (W G)[m, i]``;
* the derivative in ``beta`` replaces ``T`` by ``|i - j| beta^(|i - j| - 1)``,
  a second-order filter, times ``d beta / d theta`` (``1 - beta^2`` for
  ``theta = artanh(beta)``);
* ``Phi K = H D``.

All of it holds for any ``-1 < beta <= 1``: on the integer grid the
correlation of a negative ``beta`` is ``beta^|i - j|`` too.

The products of ``G`` (which has the sparsity of ``Phi``) with ``H`` and
with ``W`` are the observation's: a triangular regressor halves them.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from gpmultirate.kernels.precision import dc_precision
from gpmultirate.kernels.structure import ObservedTerm, outer_square, symmetrize

__all__ = ["DCFilterTerm", "suffix_after", "two_sided"]


def two_sided(X, causal_b, causal_a, include_center: bool) -> np.ndarray:
    """Filter every row of ``X`` with a symmetric two-sided recursive filter.

    The causal part has transfer function ``b(z)/a(z)``; the anticausal part
    is its mirror image.  With ``include_center`` the zero-lag tap (present in
    both halves) is counted once.

    Examples
    --------
    >>> two_sided(np.array([[0.0, 1.0, 0.0]]), [1.0], [1.0, -0.5], include_center=True)
    array([[0.5, 1. , 0.5]])
    """
    # in place: at M = 2,000 readings and P = 8,000 lags each array is 128 MB
    total = signal.lfilter(causal_b, causal_a, X, axis=1)
    total += signal.lfilter(causal_b, causal_a, X[:, ::-1], axis=1)[:, ::-1]
    if include_center:
        total -= X if causal_b[0] == 1.0 else causal_b[0] * X
    return total


def suffix_after(X: np.ndarray) -> np.ndarray:
    """``out[:, j] = sum_{i > j} X[:, i]`` (summed from the far end).

    Examples
    --------
    >>> suffix_after(np.array([[1.0, 2.0, 3.0]]))
    array([[5., 3., 0.]])
    """
    out = np.zeros_like(X)
    out[:, :-1] = np.cumsum(X[:, :0:-1], axis=1)[:, ::-1]
    return out


def _distance_filtered(G, beta):
    """``G T'`` with ``T'[i, j] = |i - j| beta^(|i - j| - 1)``, the derivative of ``T`` in ``beta``.

    The causal taps ``k beta^(k - 1)`` (``k >= 1``) are the impulse response
    of ``z^-1 / (1 - beta z^-1)^2``, which is defined at ``beta = 0`` too.

    Examples
    --------
    >>> _distance_filtered(np.array([[0.0, 0.0, 1.0, 0.0, 0.0]]), -0.5)
    array([[-1.,  1.,  0.,  1., -1.]])
    """
    return two_sided(G, [0.0, 1.0], [1.0, -2.0 * beta, beta**2], include_center=False)


class DCFilterTerm(ObservedTerm):
    """A DC kernel through any observation, by the filters of the module docstring."""

    def _filtered(self):
        """``beta``, the envelope ``d``, ``G = Phi D`` and ``H = G T``, computed once per term.

        The posterior asks a term for ``S`` and for ``Phi K``; both start from
        the same filtered regressor.
        """
        cached = getattr(self, "_filtered_parts", None)
        if cached is None:
            values = self.kernel.checked_values()
            beta = values["beta"]
            decay = values["alpha"] ** (self.lags / 2.0)
            G = self.observation.matrix * decay
            # H = G T: the causal and the anticausal filter, the centre counted once; the
            # anticausal one is also the root of T (:meth:`_root`)
            anticausal = signal.lfilter([1.0], [1.0, -beta], G[:, ::-1], axis=1)[:, ::-1]
            H = signal.lfilter([1.0], [1.0, -beta], G, axis=1)
            H += anticausal
            H -= G
            self._anticausal = anticausal
            cached = beta, decay, G, H
            self._filtered_parts = cached
        return cached

    def _root(self, alone: bool = False):
        """``G R`` with ``T = R R^T``: ``S = (G R)(G R)^T`` (the module docstring).

        ``R[i, j] = c_j beta^(i - j)`` for ``i >= j`` (``c_0 = 1``, else
        ``sqrt(1 - beta^2)``): the covariance of the AR(1) recursion
        ``x_i = beta x_(i-1) + sqrt(1 - beta^2) e_i`` started at ``x_0 = e_0``.
        Its columns are those of the anticausal filter of ``G``, scaled.
        ``alone``: nothing else of the filters is asked for (``H`` not formed).
        """
        if alone and getattr(self, "_filtered_parts", None) is None:
            # the root only: G and its anticausal filter, not H (which S's derivatives and
            # Phi K need)
            values = self.kernel.checked_values()
            beta, root = values["beta"], None
            G = self.observation.matrix * values["alpha"] ** (self.lags / 2.0)
        else:
            beta, _, G, _ = self._filtered()
            root = self._anticausal  # scaled in place below: taken once, then filtered again
            self._anticausal = None
        if root is None:
            root = signal.lfilter([1.0], [1.0, -beta], G[:, ::-1], axis=1)[:, ::-1]
        root = np.ascontiguousarray(root)
        root[:, 1:] *= np.sqrt(max(1.0 - beta * beta, 0.0))
        return root

    def kernel_matrix(self):
        # not kept: S and Phi K come from the filters, so K is asked for once, and at
        # the orders of long records a kept copy would double the largest array
        return self.kernel(self.observation.lags)

    def _free(self):
        return [h.name for h in self.kernel.hyperparameters if not h.fixed]

    def _beta_scale(self, beta):
        """``d beta / d theta`` of the kernel's ``beta`` coordinate."""
        return self.kernel.theta_transform("beta").derivative(beta)

    def parameter_contractor(self):
        lags = self.lags
        if not np.array_equal(lags, np.round(lags)):
            # between integer lags the values are the hold's, not the formula's
            return super().parameter_contractor()
        K = self.kernel_matrix()
        _, gradients = self.kernel.lag_covariance(lags, lags, eval_gradient=True)
        d_beta = gradients["beta"]
        free = self._free()

        def contract(A):
            AK = A * K
            # sum_ij A_ij K_ij (t_i + t_j) / 2 = t^T (A * K) 1 for symmetric A and K
            values = {"alpha": lags @ AK.sum(axis=1), "beta": np.sum(A * d_beta)}
            return np.array([values[name] for name in free])

        return K, contract

    def precision(self):
        """The tridiagonal ``K^{-1}`` (:func:`~gpmultirate.kernels.precision.dc_precision`), or None."""
        values = self.kernel.checked_values()
        return dc_precision(values["alpha"], values["beta"], self.kernel.beta_chain(),
                            self.observation.order, tuple(self._free()))

    def covariance(self):
        return outer_square(self._root())

    def covariance_blocks(self, split):
        root = self._root(alone=True)
        return root[split:] @ root[:split].T, np.einsum("ij,ij->i", root[split:], root[split:])

    def covariance_with_contractor(self):
        beta, _, G, H = self._filtered()
        S = outer_square(self._root())
        lags, free = self.lags, self._free()

        def contract(W):
            WG = self.observation.symmetric_times_regressor_shaped(W, G)
            values = {
                "alpha": np.einsum("mi,mi,i->", H, WG, lags),
                "beta": self._beta_scale(beta)
                * np.einsum("mi,mi->", _distance_filtered(G, beta), WG),
            }
            return np.array([values[name] for name in free])

        return S, contract

    def covariance_with_derivatives(self):
        beta, _, G, H = self._filtered()
        S = outer_square(self._root())
        items = []
        for name in self._free():
            if name == "alpha":
                # Phi (E K + K E) Phi^T = (G E) H^T + H (G E)^T
                half = (G * (self.lags / 2.0)) @ H.T
                items.append(half + half.T)
            else:
                items.append(
                    self._beta_scale(beta) * symmetrize(_distance_filtered(G, beta) @ G.T)
                )
        return S, items

    def regressor_times_kernel(self):
        _, decay, _, H = self._filtered()
        return H * decay
