"""Cross-validation of the hyperparameters on held-out blocks of slow samples.

The marginal likelihood (eq. 19) trusts the model: when measured data are not
an FIR response plus white noise (drift, disturbances, a little
nonlinearity), it can prefer a worse predictor.  The paper names
cross-validation as the alternative.  Here the slow samples of each record
are cut into ``K`` contiguous blocks in time; fold ``k`` holds out the
``k``-th block of every record, and the objective is the log density of the
held-out samples under the prediction from the others,

.. math::

    \\mathrm{CV}(\\theta) = \\sum_k \\log p(y_{B_k} \\mid y_{\\bar B_k}, \\theta).

The regressor rows of held-out samples still use the whole input: only the
outputs are held out.  With ``A = (S + \\gamma I)^{-1}`` and ``a = A y`` for
*all* the data, the prediction of block ``B`` from the rest has residual
``r_B = A_{BB}^{-1} a_B`` and covariance ``A_{BB}^{-1}``, so one factor of the
full data covariance serves every fold (no refit per fold), and the gradient
is again a contraction ``tr(W dS/d theta)`` with one symmetric ``W``, which
every kernel term already computes for the evidence.
"""

from __future__ import annotations

import numbers

import numpy as np

from gpmultirate.covariance import DenseCovariance
from gpmultirate.inference import LogEvidence, TuningObjective
from gpmultirate.kernels import observe
from gpmultirate.noise import WhiteNoise
from gpmultirate.validation import check_int

#: the bounds that mark a noise level as a free hyperparameter where only that matters
_FREE = (0.0, np.inf)

__all__ = [
    "CrossValidation",
    "contiguous_folds",
    "held_out_predictions",
    "log_predictive_likelihood",
]


def contiguous_folds(record_sizes, n_folds: int) -> list[np.ndarray]:
    """Indices of the held-out samples of each fold: ``K`` contiguous blocks per record.

    Parameters
    ----------
    record_sizes : sequence of int
        The number of (used) slow samples of each record, in the order the
        records are concatenated.
    n_folds : int
        ``K >= 2``, at most the number of samples of the longest record.

    Returns
    -------
    list of ndarray of int
        Fold ``k`` holds the ``k``-th block of every record (blocks of
        nearly equal length, in time order).

    Examples
    --------
    >>> [f.tolist() for f in contiguous_folds([5, 3], 2)]
    [[0, 1, 2, 5, 6], [3, 4, 7]]
    """
    sizes = [int(s) for s in record_sizes]
    n_folds = check_int(n_folds, "cv", low=2, high=max(sizes))
    folds = [[] for _ in range(n_folds)]
    start = 0
    for size in sizes:
        for k, block in enumerate(np.array_split(np.arange(start, start + size), n_folds)):
            folds[k].append(block)
        start += size
    return [np.concatenate(f) for f in folds if sum(len(b) for b in f) > 0]


def _held_out(observation, kernel, noise, y, folds, eval_gradient):
    """The dense data covariance (every sample is used), ``Ky^{-1}``, ``Ky^{-1} y``, the blocks."""
    covariance = DenseCovariance.of_term(observe(kernel, observation), noise,
                                         noise.remainder(observation), gradient=eval_gradient)
    return (covariance, *covariance.held_out(y, folds))


def _noise_model(noise_level, noise_free: bool = True):
    """A noise model as it is, or white noise of the level (free or fixed)."""
    if isinstance(noise_level, numbers.Real):
        return WhiteNoise(noise_level, _FREE if noise_free else "fixed")
    return noise_level


def log_predictive_likelihood(
    observation, kernel, noise_level, y: np.ndarray, folds, eval_gradient: bool = False,
    noise_free: bool = True,
):
    """``sum_k log p(y_{B_k} | y_rest)`` and, optionally, its gradient in ``theta``.

    Parameters
    ----------
    observation : Observation
        The observation of all slow samples (not reduced).
    kernel : sklearn Kernel
    noise_level : float or noise model
        The white noise variance, or a noise model (:mod:`gpmultirate.noise`:
        a :class:`~gpmultirate.noise.KernelNoise` disturbance, whose
        covariance ``N`` then replaces ``noise_level * I`` in ``Ky = S + N``
        and links the folds: the held-out block is predicted from the rest
        with the disturbance's correlation across the block's edges).
    y : ndarray of shape (M,)
    folds : list of ndarray of int
        The held-out indices of each fold (:func:`contiguous_folds`).
    eval_gradient : bool, default=False
    noise_free : bool, default=True
        For a white noise level: whether the gradient ends with the
        derivative in ``log(noise_level)``.  A noise model's own free
        ``theta`` ends the gradient instead (``noise_free`` is not used).

    Returns
    -------
    float, or (float, ndarray) with ``eval_gradient``
        The gradient's entries are the kernel's ``theta``, then the noise
        model's free ``theta``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C, Matern, WhiteKernel
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import DC
    >>> from gpmultirate.noise import KernelNoise, noise_instants
    >>> rng = np.random.default_rng(0)
    >>> op = DownsampledConvolution(rng.standard_normal(90), factor=3, order=30)
    >>> y = op.matvec(0.8 ** np.arange(30)) + 0.01 * rng.standard_normal(op.n_outputs)
    >>> noise = KernelNoise(WhiteKernel(1e-4) + C(1e-4) * Matern(10.0, nu=1.5),
    ...                     noise_instants(op))
    >>> folds = contiguous_folds([op.n_outputs], 5)
    >>> value, gradient = log_predictive_likelihood(op, C(1.0) * DC(), noise, y, folds, True)
    >>> gradient.shape  # C, alpha, beta of the prior; white level, C, length scale of the noise
    (6,)
    """
    noise = _noise_model(noise_level, noise_free)
    covariance, A, alpha, blocks = _held_out(observation, kernel, noise, y, folds, eval_gradient)
    value = 0.0
    for block in blocks:
        value += block.log_density(alpha)
    if not eval_gradient:
        return value
    # d CV = tr(W dKy):  W = sym(a v^T) - 1/2 A (Q + C) A, v = A q, q_B = r_B,
    # Q = blockdiag(r_B r_B^T), C = blockdiag(A_BB^{-1})
    q = np.zeros_like(alpha)
    middle = np.zeros_like(A)
    for block in blocks:
        B, r_B = block.indices, block.residual
        q[B] = r_B
        middle[np.ix_(B, B)] = block.covariance() + np.outer(r_B, r_B)
    v = A @ q
    W = -0.5 * (A @ middle @ A)
    W += 0.5 * (np.outer(alpha, v) + np.outer(v, alpha))
    grad = covariance.contract(W)
    if noise.is_free:
        grad = np.append(grad, noise.contract(W))
    return value, grad


def held_out_predictions(observation, kernel, noise_level: float, y: np.ndarray, folds):
    """The mean and variance of each slow sample predicted from the other folds.

    Returns
    -------
    mean, variance : ndarray of shape (M,)
        For sample ``m`` in fold ``k``: the predictive mean and variance of
        ``y[m]`` given the samples outside fold ``k`` (noise included).
        ``noise_level`` may be a noise model (:mod:`gpmultirate.noise`), whose
        disturbance then links the folds.
    """
    noise = _noise_model(noise_level, noise_free=False)
    _, _, _, blocks = _held_out(observation, kernel, noise, y, folds, False)
    mean = np.empty_like(y)
    variance = np.empty_like(y)
    for block in blocks:
        B = block.indices
        mean[B] = y[B] - block.residual
        variance[B] = block.variances()
    return mean, variance


class CrossValidation(TuningObjective):
    """The cross-validated log predictive likelihood as a function of ``theta``.

    The objective :func:`~gpmultirate.tuning.maximize` works on when a fit
    is tuned with ``tuning="cross_validation"``: the same ``theta``, bounds
    and roles as :class:`~gpmultirate.inference.LogEvidence` (a
    :class:`~gpmultirate.inference.TuningObjective` as well), evaluated on
    all slow samples in data space, with the folds of
    :func:`contiguous_folds`.  It holds the evidence of the same data
    (:attr:`evidence`), whose cheap start tuning keeps: the scale prefit,
    the scale groups and the resonance grid answer from it.  It offers no
    Fisher information (``has_fisher`` is false).

    Parameters
    ----------
    observation : Observation
    y : ndarray of shape (M,)
    kernel : sklearn Kernel
    noise_level : float
    noise_bounds : pair of floats or "fixed"
    n_folds : int, default=5
    noise : noise model, optional
        A disturbance model (:func:`~gpmultirate.noise.make_noise`) in place
        of white noise of ``noise_level``: ``theta`` then ends with its free
        ``theta`` (as for :class:`~gpmultirate.inference.LogEvidence` with
        ``noise=``), and the held-out blocks are predicted under it.

    Attributes
    ----------
    evidence : LogEvidence
        The evidence of the same data at the same start.
    folds : list of ndarray of int

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import DC
    >>> rng = np.random.default_rng(0)
    >>> op = DownsampledConvolution(rng.standard_normal(90), factor=3, order=30)
    >>> y = op.matvec(0.8 ** np.arange(30)) + 0.01 * rng.standard_normal(op.n_outputs)
    >>> objective = CrossValidation(op, y, C(1.0) * DC(), 1e-3, (1e-6, 1.0), n_folds=5)
    >>> value, gradient = objective(objective.theta, eval_gradient=True)
    >>> gradient.shape
    (4,)
    """

    has_fisher = False

    def __init__(self, observation, y, kernel, noise_level, noise_bounds, n_folds: int = 5,
                 noise=None):
        super().__init__(kernel, noise_level, noise_bounds, noise)
        # the evidence-based start works on the reduced data; the folds need every sample
        self.evidence = LogEvidence(observation, y, kernel, noise_level, noise_bounds,
                                    noise=noise)
        self.observation, self.y = observation, y
        self.folds = contiguous_folds([r.n_outputs for r in observation.records], n_folds)

    def __call__(self, theta, eval_gradient: bool = False):
        """The cross-validated log predictive likelihood at ``theta`` (and its gradient)."""
        kernel, noise = self.split_models(theta, into=self._work)
        return log_predictive_likelihood(
            self.observation, kernel, noise, self.y, self.folds, eval_gradient,
        )

    def moved_to(self, kernel, noise_level: float) -> "CrossValidation":
        moved = super().moved_to(kernel, noise_level)
        moved.evidence = self.evidence.moved_to(kernel, noise_level)
        return moved

    def reusing_kernel(self) -> "CrossValidation":
        reusing = super().reusing_kernel()
        reusing.evidence = self.evidence.moved_to(self.kernel, self.noise)
        reusing.evidence._work = reusing._work  # one working kernel; evaluations never overlap
        return reusing

    # the evidence's answers, for tuning's evidence-based start
    @property
    def data(self):
        """The (reduced) observation of the evidence."""
        return self.evidence.data

    @property
    def z(self):
        """The (reduced) outputs of the evidence."""
        return self.evidence.z

    @property
    def n_outputs(self) -> int:
        """Outputs of the evidence's (reduced) data."""
        return self.evidence.n_outputs

    @property
    def by_precision(self) -> bool:
        """Whether the evidence goes through the prior's tridiagonal precision."""
        return self.evidence.by_precision

    def remainder(self):
        """The evidence's :class:`~gpmultirate.covariance.Remainder`."""
        return self.evidence.remainder()

    def covariance(self) -> np.ndarray:
        """``S`` of the evidence's data at the initial kernel."""
        return self.evidence.covariance()

    def scale_groups(self, theta):
        """The evidence's scale groups at ``theta``."""
        return self.evidence.scale_groups(theta)

    def along(self, theta, index: int, values):
        """The evidence for each value of ``theta[index]`` (the resonance grid), or None."""
        return self.evidence.along(theta, index, values)

    def posterior(self, kernel, noise_level: float):
        """The posterior of the coefficients for ``kernel`` and ``noise_level``."""
        return self.evidence.posterior(kernel, noise_level)

    def amplitude_couplings(self):
        """No couplings: the optimizer keeps plain coordinates for cross-validation.

        The valley ``c (1 - beta^2) = const`` that
        :class:`~gpmultirate.tuning.CorrelationScaleTransform` straightens is
        the evidence's (through the prior precision); on the measured CD arm
        (two inputs, ``y2``, ``F = 3``, ``order="auto"``) the coupled
        coordinates ended cross-validation at a lower optimum (464 against
        519 at 42 lags).
        """
        return []
