"""The data covariance ``Ky = S + N`` as an object: its factorization and what it answers.

``S = Phi K Phi^T`` is the kernel seen through the observation
(:func:`gpmultirate.kernels.observe`) and ``N`` the noise model
(:mod:`gpmultirate.noise`).  :func:`data_covariance` returns one
:class:`DataCovariance` that owns the factorization of ``S + N`` and answers,
from that one factor,

* :meth:`~DataCovariance.solve` (``Ky^{-1} b``) and
  :meth:`~DataCovariance.inv_quad_logdet` (``y^T Ky^{-1} y`` and
  ``log det Ky`` together);
* :meth:`~DataCovariance.log_likelihood`, the Gaussian log density of
  eq. (19) (with the noise inside the determinant) plus the :class:`Remainder`
  of a reduced long record;
* :meth:`~DataCovariance.log_likelihood_gradient`, the gradient in ``theta``
  (the kernel's, then the noise model's) by the trace identity, through the
  kernel term's gradient contraction, and, for the dense route,
  :meth:`~DenseCovariance.log_likelihood_fisher`;
* :meth:`~DataCovariance.posterior`, the posterior of the coefficients
  (eq. 15) from the same factor (:mod:`~gpmultirate.covariance.posteriors`).

The routes are subclasses, one module each; the noise model builds the one
its structure offers (``noise.data_covariance(term)``), so this layer asks
no object for its type:

* :class:`DenseCovariance` (:mod:`~gpmultirate.covariance.dense`): the
  Cholesky factor of ``S + N`` in the data space, the fallback of every
  noise model;
* :class:`WoodburyCovariance` (:mod:`~gpmultirate.covariance.lowrank`): a
  dense covariance plus a low-rank summand ``U D U^T`` (a PK resonance at
  one candidate of a grid), by the Woodbury identity and the matrix
  determinant lemma (:func:`woodbury_gain`, written once);
* :class:`PrecisionCovariance` (:mod:`~gpmultirate.covariance.precision`):
  square or reduced data (``M = P``), white noise and a kernel term that
  offers a tridiagonal precision ``Q = K^{-1}`` (DC): the posterior
  precision ``C = Q + Phi^T Phi / gamma`` is factored instead;
* :class:`ParameterSpaceCovariance`
  (:mod:`~gpmultirate.covariance.parameter_space`): a reduced long record
  seen from the parameter space, ``K = F F^T``, through a QR factor of
  ``[Phi F / sqrt(gamma); I]`` (the accuracy of least squares);
* :class:`AR1Covariance` (:mod:`~gpmultirate.covariance.ar1`): AR(1) noise
  on a long record, prewhitened through its tridiagonal precision.

Beside them, :class:`SpectralCovariance` is ``c S + gamma I (+ W W^T)`` for
every scale ``c`` and noise level ``gamma`` at once, from one
eigendecomposition of ``S``: what the scale prefit of tuning and the
resonance search of ``kernel="auto"`` scan.  :mod:`~gpmultirate.covariance.reference`
holds the plain dense formulas every route is tested against.

The Gaussian log density is written once, in :func:`log_gaussian`.
"""

from __future__ import annotations

from gpmultirate.covariance.ar1 import AR1Covariance, AR1Statistics
from gpmultirate.covariance.base import (
    LOG_2PI,
    DataCovariance,
    Remainder,
    cholesky_or_raise,
    inverse_from_cholesky,
    kernel_root,
    log_gaussian,
    robust_cholesky,
)
from gpmultirate.covariance.dense import DenseCovariance, HeldOutBlock, matrix_log_density
from gpmultirate.covariance.lowrank import (
    DiagonalPlusLowRank,
    WoodburyCovariance,
    woodbury_gain,
    woodbury_terms,
)
from gpmultirate.covariance.parameter_space import ParameterSpaceCovariance
from gpmultirate.covariance.posteriors import (
    DataSpacePosterior,
    GaussianCoefficients,
    ParameterSpacePosterior,
    PrecisionPosterior,
    SpreadPosterior,
    gaussian_samples,
)
from gpmultirate.covariance.precision import PrecisionCovariance
from gpmultirate.covariance.reference import dense_log_evidence, dense_posterior
from gpmultirate.covariance.spectral import SpectralCovariance, relative_spectrum
from gpmultirate.kernels import observe

__all__ = [
    "AR1Covariance",
    "AR1Statistics",
    "DataCovariance",
    "DataSpacePosterior",
    "DenseCovariance",
    "DiagonalPlusLowRank",
    "GaussianCoefficients",
    "HeldOutBlock",
    "LOG_2PI",
    "ParameterSpaceCovariance",
    "ParameterSpacePosterior",
    "PrecisionCovariance",
    "PrecisionPosterior",
    "Remainder",
    "SpectralCovariance",
    "SpreadPosterior",
    "WoodburyCovariance",
    "cholesky_or_raise",
    "data_covariance",
    "dense_log_evidence",
    "dense_posterior",
    "fisher_covariance",
    "gaussian_samples",
    "inverse_from_cholesky",
    "kernel_root",
    "log_gaussian",
    "matrix_log_density",
    "posterior_covariance",
    "relative_spectrum",
    "robust_cholesky",
    "takes_precision_route",
    "woodbury_gain",
    "woodbury_terms",
]

_SPACES = ("data", "posterior")
_DERIVATIVES = (None, "contraction", "matrices")


def data_covariance(kernel, observation, noise, derivatives: str | None = None,
                    space: str = "data") -> DataCovariance:
    """``S + N`` of ``observation`` under ``kernel`` and ``noise``, by the route the noise offers.

    The noise model chooses (``noise.data_covariance(term, gradient)``,
    :func:`posterior_covariance`, :func:`fisher_covariance`,
    :mod:`gpmultirate.noise`): it knows its own structure, and asks the
    observed kernel term for its own (a tridiagonal precision, a regressor
    on the integer lags).

    Parameters
    ----------
    kernel : sklearn Kernel
    observation : Observation
        Possibly a reduction (:func:`~gpmultirate.observations.reduce_observation`).
    noise : noise model
        :class:`~gpmultirate.noise.WhiteNoise`, :class:`~gpmultirate.noise.KernelNoise`, ...
    derivatives : {None, "contraction", "matrices"}
        What the gradient needs: the term's contraction
        (:meth:`DataCovariance.log_likelihood_gradient`) or its derivative
        matrices (:meth:`DenseCovariance.log_likelihood_fisher`, dense).
    space : {"data", "posterior"}
        ``"data"``: the route of the evidence.  ``"posterior"``: the route of
        the posterior (for white noise on a reduction, the parameter space
        where the prior offers no precision).

    Returns
    -------
    DataCovariance

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import DC, TC
    >>> from gpmultirate.noise import WhiteNoise
    >>> op = DownsampledConvolution(np.arange(1.0, 41.0), factor=2, order=20)
    >>> type(data_covariance(C(1.0) * DC(0.8, 0.5), op, WhiteNoise(0.1))).__name__
    'PrecisionCovariance'
    >>> type(data_covariance(TC(0.8), op, WhiteNoise(0.1))).__name__
    'DenseCovariance'
    """
    if space not in _SPACES:
        raise ValueError(f"space must be one of {_SPACES}; got {space!r}")
    if derivatives not in _DERIVATIVES:
        raise ValueError(f"derivatives must be one of {_DERIVATIVES}; got {derivatives!r}")
    if space == "posterior":
        return posterior_covariance(kernel, observation, noise)
    if derivatives == "matrices":
        return fisher_covariance(kernel, observation, noise)
    return noise.data_covariance(observe(kernel, observation), gradient=derivatives is not None)


def fisher_covariance(kernel, observation, noise) -> DenseCovariance:
    """``S + N`` with the derivative matrices the Fisher information needs (dense).

    The noise model answers (``noise.fisher_covariance(term)``): white noise
    offers :meth:`DenseCovariance.log_likelihood_fisher`, whose noise
    derivative is ``gamma I``, a disturbance over the instants on the dense
    route its kernel's derivative matrices; other models refuse.
    """
    return noise.fisher_covariance(observe(kernel, observation))


def posterior_covariance(kernel, observation, noise) -> DataCovariance:
    """``S + N`` by the route of the posterior the noise offers; its ``posterior(y)`` is eq. (15).

    For white noise on a reduced long record that is DC's precision or the
    parameter space (the accuracy of least squares); otherwise the route of
    the evidence.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import TC
    >>> from gpmultirate.noise import WhiteNoise
    >>> from gpmultirate.observations import reduce_observation
    >>> op = DownsampledConvolution(np.sin(np.arange(300.0)), factor=3, order=20)
    >>> data, z = reduce_observation(op, np.cos(np.arange(100.0)))
    >>> type(posterior_covariance(TC(0.8), data, WhiteNoise(0.1)).posterior(z)).__name__
    'ParameterSpacePosterior'
    """
    return noise.posterior_covariance(observe(kernel, observation))


def takes_precision_route(kernel, observation, noise) -> bool:
    """Whether :func:`data_covariance` goes through the kernel term's tridiagonal precision.

    So it does for square or reduced data (``M = P``), white noise and a
    term that offers one (DC, a constant times DC): the noise model answers
    (``noise.offers_precision(term)``); nothing is factored here.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import DC, TC
    >>> from gpmultirate.noise import WhiteNoise
    >>> op = DownsampledConvolution(np.arange(1.0, 41.0), factor=2, order=20)
    >>> takes_precision_route(DC(0.8, 0.5), op, WhiteNoise(0.1))
    True
    >>> takes_precision_route(TC(0.8), op, WhiteNoise(0.1))
    False
    """
    return noise.offers_precision(observe(kernel, observation))
