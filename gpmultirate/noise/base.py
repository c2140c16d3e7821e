"""What a noise model is: ``N`` over the slow samples, its ``theta``, and the route it offers.

A noise model is one subclass of :class:`NoiseModel`.  The data covariance
layer (:mod:`gpmultirate.covariance`) asks it two things only: add ``N`` to
``S`` and contract ``dN / d theta`` (the dense route, which every model gets
for free), and, through :meth:`NoiseModel.data_covariance`, which route its
structure offers (white noise: DC's precision and the long-record
reduction; AR(1) noise: its tridiagonal precision).
"""

from __future__ import annotations

import numpy as np

from gpmultirate.covariance import DenseCovariance, Remainder

__all__ = ["NoiseModel", "instant_blocks", "kernel_blocks", "no_remainder"]


def instant_blocks(instants) -> list[np.ndarray]:
    """The instants as a list of 1-D float arrays, one per record.

    Examples
    --------
    >>> [t.tolist() for t in instant_blocks([[0, 3], [1]])]
    [[0.0, 3.0], [1.0]]
    """
    if isinstance(instants, (list, tuple)) and instants and np.ndim(instants[0]) == 1:
        blocks = [np.asarray(t, dtype=float) for t in instants]
    else:
        blocks = [np.asarray(instants, dtype=float)]
    for t in blocks:
        if t.ndim != 1 or t.size == 0 or not np.all(np.isfinite(t)):
            raise ValueError("instants must be a non-empty 1-D array of finite instants, or a "
                             "list of them (one per record)")
    return blocks


def kernel_blocks(kernel, instants: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """``N = blockdiag(k(t_r, t_r))`` and ``dN / d theta`` of a kernel over independent records.

    Returns arrays of shapes ``(M, M)`` and ``(M, M, len(kernel.theta))``.
    """
    M, n = sum(t.shape[0] for t in instants), kernel.theta.shape[0]
    N, dN = np.zeros((M, M)), np.zeros((M, M, n))
    start = 0
    for t in instants:
        block, gradient = kernel(t[:, None], eval_gradient=True)
        stop = start + t.shape[0]
        N[start:stop, start:stop] = block
        dN[start:stop, start:stop] = gradient
        start = stop
    return N, dN


def no_remainder(observation) -> Remainder:
    """No remainder; a reduced ``observation`` is refused (a reduction assumes white noise)."""
    if observation.n_discarded > 0:
        raise ValueError(
            "a reduced observation assumes white noise: a coloured noise model needs the "
            "observation itself (the AR(1) structure has its own reduction, AR1Statistics)"
        )
    return Remainder(0, 0.0, 1.0)


class NoiseModel:
    """The noise ``v ~ N(0, N)`` of the slow samples ``y = Phi g + v``: the base of every model.

    A subclass states ``N`` and its hyperparameters and gets the dense
    route of the data covariance for free; it overrides
    :meth:`data_covariance` when its structure offers a faster one
    (``docs/adding_a_noise_model.rst``).  It provides

    * :attr:`theta` (log hyperparameters that are tuned, after the
      kernel's in the ``theta`` of tuning), :attr:`bounds` and
      :meth:`with_theta`;
    * :meth:`add_to` (``S + N`` in place) and :meth:`contract`
      (``[weight tr(W dN / d theta_j)]_j``): what the dense route and its
      gradient need;
    * :attr:`level`: the white part of ``N`` (0 if none), which the
      estimator reports as ``noise_level_``.

    Attributes
    ----------
    white : bool
        Whether ``N`` is a multiple of the identity (what the long-record
        reduction assumes).
    """

    #: whether ``N`` is a multiple of the identity
    white = False
    #: the bounds of a noise level the model scales ``N`` by, or None
    noise_bounds = None

    @property
    def level(self) -> float:
        """The white part of ``N`` (0 if none)."""
        return 0.0

    @property
    def theta(self) -> np.ndarray:
        """The log hyperparameters that are tuned."""
        raise NotImplementedError

    @property
    def bounds(self) -> np.ndarray:
        """Bounds of :attr:`theta`, of shape ``(len(theta), 2)``."""
        raise NotImplementedError

    @property
    def is_free(self) -> bool:
        """Whether any hyperparameter is tuned."""
        return self.theta.shape[0] > 0

    def with_theta(self, theta) -> "NoiseModel":
        """The same noise model at ``theta`` (its own entries of the whole ``theta``)."""
        raise NotImplementedError

    def add_to(self, S: np.ndarray) -> np.ndarray:
        """``S + N`` in place (``S`` square, of the size of the data); returns ``S``."""
        raise NotImplementedError

    def contract(self, W: np.ndarray, weight: float = 1.0) -> np.ndarray:
        """``[weight tr(W dN / d theta_j)]_j`` for symmetric ``W``."""
        raise NotImplementedError

    def remainder(self, observation) -> Remainder:
        """The likelihood of what a reduction of ``observation`` summarized.

        Only white noise is summarized by the long-record reduction: any
        other model refuses a reduced ``observation``.
        """
        return no_remainder(observation)

    # ------------------------------------------------------------ routes
    def data_covariance(self, term, gradient: bool = False):
        """``S + N`` for the observed kernel ``term``: the route of the evidence.

        The dense route (:class:`~gpmultirate.covariance.DenseCovariance`)
        by default; with ``gradient`` it is formed for
        ``log_likelihood_gradient``.
        """
        return DenseCovariance.of_term(term, self, self.remainder(term.observation), gradient)

    def posterior_covariance(self, term):
        """``S + N`` for the observed kernel ``term``: the route of the posterior."""
        return self.data_covariance(term)

    def offers_fisher(self, observation) -> bool:
        """Whether tuning on ``observation`` may take Fisher scoring (:meth:`fisher_covariance`).

        A model that states its derivative matrices (:meth:`fisher_terms`)
        and takes the dense route on ``observation`` does; by default none.
        """
        return False

    def fisher_covariance(self, term):
        """``S + N`` with the derivative matrices of the Fisher information.

        The dense route with the term's derivative matrices, for a model that
        :meth:`offers_fisher`; the others refuse.
        """
        if not self.offers_fisher(term.observation):
            raise ValueError(f"the Fisher information is not offered for "
                             f"{type(self).__name__} here; tune with L-BFGS")
        return DenseCovariance.with_derivatives(term, self, self.remainder(term.observation))

    def fisher_terms(self, inverse: np.ndarray) -> list:
        """``("dense", dN_j, V_j, V_j^T)`` with ``V_j = Ky^{-1} dN_j`` for each tuned entry.

        ``inverse``: ``Ky^{-1}``.  What :meth:`DenseCovariance.log_likelihood_fisher
        <gpmultirate.covariance.DenseCovariance.log_likelihood_fisher>` needs of the noise.
        """
        raise NotImplementedError

    def offers_precision(self, term) -> bool:
        """Whether the evidence goes through the kernel term's tridiagonal precision."""
        return False
