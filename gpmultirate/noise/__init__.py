"""Noise models of the slow samples: white noise, and disturbances over the sample instants.

The data are ``y = Phi g + v`` with ``v ~ N(0, N)``.  Every noise model is
one subclass of :class:`NoiseModel` (:mod:`~gpmultirate.noise.base`) that
states ``N`` and its hyperparameters, and chooses the route of the data
covariance its structure offers (``noise.data_covariance(term)``, built
from :mod:`gpmultirate.covariance`):

* :class:`WhiteNoise` (:mod:`~gpmultirate.noise.white`): ``N = gamma I``,
  what the long-record reduction and DC's precision rely on;
* :class:`KernelNoise` (:mod:`~gpmultirate.noise.kernel`): ``N = k(t, t)``
  for a scikit-learn kernel ``k`` over the instants ``t`` of the slow
  samples, measured in fast samples -- typically
  ``WhiteKernel() + C * Matern(nu=1.5)``, or a sum with an
  ``ExpSineSquared`` for a periodic disturbance; independent records give a
  block-diagonal ``N``; dense, unless it is the AR(1) form below;
* :class:`AR1Noise` (:mod:`~gpmultirate.noise.ar1`): a Matérn 1/2 process
  on a uniform grid, an AR(1) process whose tridiagonal precision keeps the
  long-record cost (:class:`~gpmultirate.covariance.AR1Covariance`);
* :class:`HeteroscedasticNoise` (:mod:`~gpmultirate.noise.heteroscedastic`):
  independent samples of known relative variances, ``gamma diag(w)``: the
  example of a new model (one class and a test).

:mod:`~gpmultirate.noise.disturbances` turns the estimator's
``noise_kernel`` into a model (:func:`make_noise`) and says whether the
data call for a disturbance (:func:`disturbance_evidence_gain`,
:func:`ar1_evidence_gain`).  :func:`dense_log_evidence` and
:func:`dense_posterior` (:mod:`gpmultirate.covariance.reference`) are the
reference formulas for any noise model, against which the structured routes
are tested.
"""

from gpmultirate.covariance import AR1Statistics, dense_log_evidence, dense_posterior
from gpmultirate.noise.ar1 import AR1Noise, ar1_evidence_gain, ar1_log_evidence
from gpmultirate.noise.base import NoiseModel
from gpmultirate.noise.disturbances import (
    AR1_DISTURBANCE,
    GAIN_LENGTH_SCALES,
    GAIN_ADDED_LEVELS,
    GAIN_SCALES,
    GAIN_SHARES,
    NAMED_DISTURBANCES,
    disturbance_evidence_gain,
    make_noise,
    noise_instants,
)
from gpmultirate.noise.heteroscedastic import HeteroscedasticNoise
from gpmultirate.noise.kernel import KernelNoise, white_level
from gpmultirate.noise.white import WhiteNoise

__all__ = [
    "AR1_DISTURBANCE",
    "GAIN_LENGTH_SCALES",
    "GAIN_ADDED_LEVELS",
    "GAIN_SCALES",
    "GAIN_SHARES",
    "NAMED_DISTURBANCES",
    "AR1Noise",
    "AR1Statistics",
    "HeteroscedasticNoise",
    "KernelNoise",
    "NoiseModel",
    "WhiteNoise",
    "ar1_evidence_gain",
    "ar1_log_evidence",
    "dense_log_evidence",
    "dense_posterior",
    "disturbance_evidence_gain",
    "make_noise",
    "noise_instants",
    "white_level",
]
