"""Noise as a scikit-learn kernel over the instants of the slow samples: ``N = k(t, t)``."""

from __future__ import annotations

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

from gpmultirate.noise.ar1 import AR1Noise
from gpmultirate.noise.base import NoiseModel, instant_blocks, kernel_blocks

__all__ = ["KernelNoise", "white_level"]


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


class KernelNoise(NoiseModel):
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

    def __init__(self, kernel, instants):
        if not isinstance(kernel, Kernel):
            raise ValueError(f"kernel must be a scikit-learn kernel; got {type(kernel).__name__}")
        self.kernel = kernel
        self.instants = instant_blocks(instants)
        self._blocks = None  # (N, dN) at this kernel's theta, formed once
        self._distances = None  # |t_i - t_j| of each record, shared by with_theta's models

    @property
    def n_samples(self) -> int:
        """``M``, the number of slow samples."""
        return sum(t.shape[0] for t in self.instants)

    @property
    def level(self) -> float:
        """The white part of ``N``: the ``WhiteKernel`` summands' level (0 if none)."""
        return white_level(self.kernel)

    @property
    def theta(self) -> np.ndarray:
        """The kernel's ``theta`` (log hyperparameters that are not fixed)."""
        return self.kernel.theta

    @property
    def bounds(self) -> np.ndarray:
        """Bounds of :attr:`theta`, of shape ``(len(theta), 2)``."""
        return self.kernel.bounds.reshape(-1, 2)

    def with_theta(self, theta) -> "KernelNoise":
        """The same noise model at ``theta`` (its own entries of the whole ``theta``)."""
        theta = np.asarray(theta, dtype=float)
        parts = _named_parts(self.kernel)
        kernel = (self.kernel.clone_with_theta(theta) if parts is None
                  else _named_kernel(parts, theta))
        moved = KernelNoise(kernel, self.instants)
        moved._distances = self._distances = self._distances or self._named_distances()
        return moved

    def _named_distances(self):
        """The records' distances when the kernel is a named disturbance's form, else None."""
        if _named_parts(self.kernel) is None:
            return None
        return [np.abs(t[:, None] - t[None, :]) for t in self.instants]

    def matrix(self) -> np.ndarray:
        """``N``, of shape ``(M, M)``."""
        if self._blocks is not None:
            return self._blocks[0].copy()
        return linalg.block_diag(*(self.kernel(t[:, None]) for t in self.instants))

    def matrix_with_gradient(self) -> tuple[np.ndarray, np.ndarray]:
        """``N`` and ``dN / d theta``, of shapes ``(M, M)`` and ``(M, M, len(theta))``.

        Formed once per model (a model is one point of ``theta``): the evidence's
        gradient adds ``N`` and contracts ``dN`` at the same point.  Read only.
        """
        if self._blocks is None:
            parts = _named_parts(self.kernel)
            if parts is None:
                self._blocks = kernel_blocks(self.kernel, self.instants)
            else:
                self._distances = self._distances or self._named_distances()
                self._blocks = _named_blocks(parts, self._distances)
        return self._blocks

    def derivatives(self) -> list[np.ndarray]:
        """``dN / d theta_j`` for each entry of :attr:`theta`, dense ``(M, M)`` each."""
        _, dN = self.matrix_with_gradient()
        return [np.ascontiguousarray(dN[:, :, j]) for j in range(dN.shape[2])]

    def add_to(self, S: np.ndarray) -> np.ndarray:
        """``S + N`` in place (``S`` square, of the size of the data); returns ``S``."""
        # with its derivatives: the gradient's contraction at this point reuses them
        S += self.matrix_with_gradient()[0]
        return S

    def contract(self, W: np.ndarray, weight: float = 1.0) -> np.ndarray:
        """``[weight tr(W dN / d theta_j)]_j`` for symmetric ``W``."""
        _, dN = self.matrix_with_gradient()
        return weight * np.einsum("ij,ijk->k", W, dN)

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

    @classmethod
    def from_ar1(cls, ar1: AR1Noise) -> "KernelNoise":
        """The same noise as an :class:`AR1Noise`, as a kernel over its instants (dense)."""
        return cls(ar1.kernel, ar1.instants)

    def offers_fisher(self, observation) -> bool:
        """On the dense route (not the AR(1) one of a long record): ``dN`` is a few ``M x M``
        matrices, and Fisher scoring needs tens of evaluations where L-BFGS needs thousands
        (the amplitudes of the prior and of the disturbance trade off along a ridge)."""
        ar1 = self.structure()
        return ar1 is None or not ar1.fits(observation)

    def fisher_terms(self, inverse: np.ndarray) -> list:
        terms = []
        for dN in self.derivatives():
            product = inverse @ dN
            terms.append(("dense", dN, product, np.ascontiguousarray(product.T)))
        return terms

    def data_covariance(self, term, gradient: bool = False):
        """The AR(1) route where the model is one (:meth:`structure`), else the dense route."""
        ar1 = self.structure()
        if ar1 is not None:
            return ar1.data_covariance(term, gradient, owner=self)
        return super().data_covariance(term, gradient)


def _named_parts(kernel):
    """``(white, constant, matern)`` of ``WhiteKernel + ConstantKernel * Matern(nu)`` with
    ``nu`` 1/2 or 3/2 and one scalar length scale (the named disturbances' form, exactly
    these scikit-learn classes), else None."""
    if not (type(kernel) is Sum and type(kernel.k1) is WhiteKernel
            and type(kernel.k2) is Product and type(kernel.k2.k1) is ConstantKernel
            and type(kernel.k2.k2) is Matern):
        return None
    matern = kernel.k2.k2
    if matern.nu not in (0.5, 1.5) or np.ndim(matern.length_scale) != 0:
        return None
    return kernel.k1, kernel.k2.k1, matern


def _free(parts) -> list:
    """Which of ``(white, constant, matern)``'s hyperparameters are tuned."""
    white, constant, matern = parts
    return [not white.hyperparameter_noise_level.fixed,
            not constant.hyperparameter_constant_value.fixed,
            not matern.hyperparameter_length_scale.fixed]


def _named_kernel(parts, theta):
    """``clone_with_theta`` of a named disturbance's form, built directly (scikit-learn's
    clone copies and sets every parameter: a large share of an evaluation's overhead)."""
    white, constant, matern = parts
    values = [float(white.noise_level), float(constant.constant_value),
              float(np.squeeze(matern.length_scale))]
    free = _free(parts)
    if len(theta) != sum(free):
        raise ValueError(f"theta must have {sum(free)} entries; got {len(theta)}")
    entries = iter(np.exp(theta))
    values = [next(entries) if is_free else value for value, is_free in zip(values, free)]
    return WhiteKernel(values[0], white.noise_level_bounds) + ConstantKernel(
        values[1], constant.constant_value_bounds) * Matern(
            values[2], matern.length_scale_bounds, nu=matern.nu)


def _named_blocks(parts, distances) -> tuple[np.ndarray, np.ndarray]:
    """``N`` and ``dN / d theta`` of ``WhiteKernel(w) + C * Matern(l, nu)`` from the records'
    distances, the closed forms of scikit-learn's kernels and gradients (``theta`` the log
    values of the free ones, in the kernel's order: ``w``, ``C``, ``l``).  scikit-learn's
    evaluation of the sum with its gradients was a third of a disturbance's tuning on a few
    hundred slow samples."""
    white, constant, matern = parts
    free = _free(parts)
    w, c, scale = (float(white.noise_level), float(constant.constant_value),
                   float(np.squeeze(matern.length_scale)))
    blocks, gradients = [], []
    for d in distances:
        r = d / scale
        if matern.nu == 0.5:
            K = np.exp(-r)
            dK = r * K  # d/dlog(l) of exp(-d/l)
        else:
            e = np.exp(-np.sqrt(3.0) * r)
            K, dK = (1.0 + np.sqrt(3.0) * r) * e, 3.0 * r**2 * e
        signal = c * K
        block = signal.copy()
        block[np.diag_indices_from(block)] += w
        blocks.append(block)
        derivatives = [w * np.eye(d.shape[0]), signal, c * dK]
        gradients.append([g for g, is_free in zip(derivatives, free) if is_free])
    # dN is a view of (len(theta), M, M): each derivative contiguous, and the contraction
    # with W reads each one in order
    if len(blocks) == 1:
        N = blocks[0]
        stacked = (np.stack(gradients[0]) if gradients[0] else np.zeros((0,) + N.shape))
        return N, stacked.transpose(1, 2, 0)
    M = sum(d.shape[0] for d in distances)
    N, stacked = np.zeros((M, M)), np.zeros((sum(free), M, M))
    start = 0
    for block, grads in zip(blocks, gradients):
        stop = start + block.shape[0]
        N[start:stop, start:stop] = block
        for j, gradient in enumerate(grads):
            stacked[j, start:stop, start:stop] = gradient
        start = stop
    return N, stacked.transpose(1, 2, 0)


def has_white(kernel) -> bool:
    """Whether ``kernel`` has a ``WhiteKernel`` summand."""
    if isinstance(kernel, WhiteKernel):
        return True
    return isinstance(kernel, Sum) and (has_white(kernel.k1) or has_white(kernel.k2))
