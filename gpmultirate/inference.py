"""Inference: the posterior of the FIR coefficients and the log evidence.

With ``Ky = Phi K Phi^T + gamma I_M`` (the covariance of the slow data) and
its Cholesky factor ``L``:

* posterior mean of the coefficients, eq. (15): ``K Phi^T Ky^{-1} y``;
* posterior covariance: ``K - B^T B`` with ``B = L^{-1} Phi K``;
* log marginal likelihood, eq. (19) with the noise inside the determinant:
  ``-1/2 y^T Ky^{-1} y - 1/2 log det Ky - M/2 log(2 pi)``;
* its gradient by the trace identity
  ``d/dtheta_j = 1/2 tr((a a^T - Ky^{-1}) dKy/dtheta_j)`` with
  ``a = Ky^{-1} y``, evaluated as ``1/2 sum(A * dK_j)`` with
  ``A = Phi^T (a a^T - Ky^{-1}) Phi`` so that no ``Phi dK Phi^T`` product is
  formed per hyperparameter.

The data covariance ``Ky`` is an object
(:func:`gpmultirate.covariance.data_covariance`): its route (dense,
low-rank update, DC's precision, parameter space) owns the factor, the
evidence, its gradient and Fisher information, and the remainder of a reduced
long record; each route answers its posterior
(:mod:`gpmultirate.covariance.posteriors`), which holds the observation and
the kernel it answers for.  :class:`LogEvidence`
packages the evidence as a function of ``theta`` (the hyperparameters in their
tuning coordinates: the log of most, ``artanh`` of DC's ``beta``) for tuning.
"""

from __future__ import annotations

import contextlib
import numbers
import os
import time

import numpy as np
from sklearn.base import clone
from threadpoolctl import ThreadpoolController

from gpmultirate.covariance import (
    DataSpacePosterior,
    DenseCovariance,
    GaussianCoefficients,
    ParameterSpacePosterior,
    PrecisionPosterior,
    data_covariance,
    fisher_covariance,
    gaussian_samples,
    inverse_from_cholesky,
    log_gaussian,
    posterior_covariance,
    robust_cholesky,
    takes_precision_route,
)
from gpmultirate.kernels import observe
from gpmultirate.noise import WhiteNoise
from gpmultirate.observations import reduce_observation

__all__ = [
    "DataSpacePosterior",
    "GaussianCoefficients",
    "LogEvidence",
    "ParameterSpacePosterior",
    "PrecisionPosterior",
    "TuningObjective",
    "blas_threads_for",
    "gaussian_samples",
    "idle_cores",
    "own_load",
    "inverse_from_cholesky",
    "log_gaussian",
    "log_marginal_likelihood",
    "log_marginal_likelihood_fisher",
    "one_blas_thread",
    "posterior",
    "robust_cholesky",
]

# Below this size the matrices of a fit are too small for threaded BLAS to pay
# off, and on a busy machine its threads spin against each other: one thread.
SINGLE_THREAD_SIZE = 1500


_controller = None


def _blas_controller() -> ThreadpoolController:
    """One controller per process: finding the loaded libraries costs milliseconds.

    ``threadpool_limits`` scans every loaded shared library on each call
    (8 ms with scipy and scikit-learn loaded, twice per fit); the BLAS
    libraries a fit uses are loaded with numpy and scipy, before it.
    """
    global _controller
    if _controller is None:
        _controller = ThreadpoolController()
    return _controller


def one_blas_thread():
    """A context with one BLAS thread (the process's one thread controller).

    Examples
    --------
    >>> with one_blas_thread():
    ...     pass
    """
    return _blas_controller().limit(limits=1, user_api="blas")


def blas_threads_for(observation):
    """A context with one BLAS thread for small problems, as many as idle cores otherwise.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> with blas_threads_for(DownsampledConvolution(np.ones(90), 3, 30)):
    ...     pass
    """
    if max(observation.n_outputs, observation.n_coefficients) <= SINGLE_THREAD_SIZE:
        return one_blas_thread()
    idle = idle_cores()
    if idle < (os.cpu_count() or 1):
        return _blas_controller().limit(limits=idle, user_api="blas")
    return contextlib.nullcontext()


#: this process's own load is measured over at least this many seconds of wall time
OWN_LOAD_WINDOW = 5.0
# (wall, CPU) seconds of this process at the last measurement, and the load it gave
_OWN = {"wall": time.perf_counter(), "cpu": time.process_time(), "load": 1.0}


def own_load() -> float:
    """This process's recent load in cores: its CPU time over the wall time since the last measurement.

    Measured over at least ``OWN_LOAD_WINDOW`` seconds (every thread of
    the process counts: BLAS, joblib); 1 before a first window has passed.

    Examples
    --------
    >>> 0.0 <= own_load() <= 1.5 * (os.cpu_count() or 1)
    True
    """
    wall, cpu = time.perf_counter(), time.process_time()
    if wall - _OWN["wall"] >= OWN_LOAD_WINDOW:
        _OWN["load"] = (cpu - _OWN["cpu"]) / (wall - _OWN["wall"])
        _OWN["wall"], _OWN["cpu"] = wall, cpu
    return _OWN["load"]


def idle_cores() -> int:
    """The cores not busy with other work: ``cpu_count - round(load - own load)``, at least 1.

    The one-minute load average counts this process too, by what it used
    (:func:`own_load`: up to two cores while BLAS runs threaded): counting
    it as one core, a fit on a quiet two-core machine read its own load of
    1.5 as another process and went on with one thread (the 7,992-lag pilot
    of a camera log 43 s to 95 s).  On a busy machine threaded BLAS spins
    against the other work: with the other core of two busy, a 2000 x 2000
    Cholesky took 2.3 s on two threads and 0.47 s on one (median of 5).

    Examples
    --------
    >>> 1 <= idle_cores() <= (os.cpu_count() or 1)
    True
    """
    cores = os.cpu_count() or 1
    try:
        load = os.getloadavg()[0]
    except (OSError, AttributeError):
        return cores
    others = max(load - own_load(), 0.0)
    return max(1, min(cores, cores - round(others)))


def posterior(observation, kernel, noise_level: float, y: np.ndarray) -> GaussianCoefficients:
    """The posterior in whichever space is smaller: data (``M <= P``) or parameters.

    For ``M > P`` the data are first reduced to the ``P x P`` factor of
    :class:`~gpmultirate.observations.ReducedObservation` (never holding
    ``Phi``), whose least-squares form gives the same posterior; ``observation``
    may be such a reduction already (``y`` is then its ``z``).  The posterior
    of the reduction is :class:`PrecisionPosterior` where the prior has a
    tridiagonal precision, else :class:`ParameterSpacePosterior`: the route
    of :func:`~gpmultirate.covariance.data_covariance` decides.
    """
    data, z = reduce_observation(observation, y)
    return posterior_covariance(kernel, data, WhiteNoise(noise_level)).posterior(z)


def log_marginal_likelihood(
    observation, kernel, noise_level: float, y: np.ndarray, eval_gradient: bool, noise_free: bool
):
    """Log evidence of the slow data and its gradient with respect to ``theta``.

    The gradient has the kernel's ``theta`` first and, when ``noise_free`` is
    true, the derivative with respect to ``log(noise_level)`` last.
    """
    noise = WhiteNoise(noise_level, (0.0, np.inf) if noise_free else "fixed")
    if not eval_gradient:
        return data_covariance(kernel, observation, noise).log_likelihood(y)
    return data_covariance(kernel, observation, noise, "contraction").log_likelihood_gradient(y)


def log_marginal_likelihood_fisher(
    observation, kernel, noise_level: float, y: np.ndarray, noise_free: bool
):
    """Log evidence, its gradient and its Fisher information in ``theta``.

    :meth:`~gpmultirate.covariance.DenseCovariance.log_likelihood_fisher`:
    the entries follow the kernel's ``theta`` and, when ``noise_free``,
    ``log(noise_level)`` last.
    """
    noise = WhiteNoise(noise_level, (0.0, np.inf) if noise_free else "fixed")
    return fisher_covariance(kernel, observation, noise).log_likelihood_fisher(y)


def resonance_grid_log_marginal_likelihood(
    observation, kernel, term, name: str, noise_level: float, y: np.ndarray, values: np.ndarray
):
    """Log evidence for each value of the hyperparameter ``name`` of one low-rank summand.

    ``term`` must be a summand of ``kernel`` (not inside a product) whose
    structured term is low rank (:meth:`~gpmultirate.kernels.ObservedTerm.low_rank`),
    such as a PK resonance; returns None otherwise.  The rest of the data
    covariance is factored once and the summand enters each candidate as a
    :class:`~gpmultirate.covariance.WoodburyCovariance`: ``O(M^2)`` per
    candidate instead of ``O(M^3)``.
    """
    tree = observe(kernel, observation)
    S_rest = tree.covariance_without(term)
    found = None if S_rest is None else tree.candidate_factors(term, name, values)
    if found is None:
        return None
    U, weights = found
    rest = DenseCovariance(tree, WhiteNoise(noise_level), WhiteNoise(noise_level).remainder(observation),
                           S_rest, copy=False)
    return np.array([update.log_likelihood(y) for update in rest.plus_low_rank(U, weights)])


class TuningObjective:
    """What every objective of tuning shares: the kernel, the noise model and ``theta``.

    ``theta`` is the kernel's ``theta`` followed by the noise model's (the
    log noise level when it is tuned); :func:`~gpmultirate.tuning.maximize`
    treats every subclass alike: :class:`LogEvidence` and
    :class:`~gpmultirate.crossvalidation.CrossValidation`.  Subclasses are
    callable, ``objective(theta, eval_gradient=False)``, and say whether
    they offer :meth:`LogEvidence.with_fisher` (``has_fisher``).

    Parameters
    ----------
    kernel : sklearn Kernel
        The kernel at the initial hyperparameters (not modified).
    noise_level : float
        The noise variance; the initial value when it is tuned.
    noise_bounds : pair of floats or "fixed"
    """

    #: whether ``with_fisher`` is available (Fisher scoring may be used)
    has_fisher = False

    def __init__(self, kernel, noise_level: float, noise_bounds, noise=None):
        self.kernel = kernel
        self.noise = WhiteNoise(noise_level, noise_bounds) if noise is None else noise
        self._work = None

    @property
    def coloured(self) -> bool:
        """Whether the noise model is a disturbance over the instants (not ``gamma I``)."""
        return not self.noise.white

    @property
    def noise_level(self) -> float:
        """The (initial) noise variance."""
        return self.noise.level

    @property
    def noise_bounds(self):
        """The bounds of the noise variance, or ``"fixed"`` (None for a disturbance model)."""
        return self.noise.noise_bounds

    @property
    def noise_is_free(self) -> bool:
        """Whether the noise model's ``theta`` (``log(noise_level)``) ends ``theta``."""
        return self.noise.is_free

    @property
    def theta(self) -> np.ndarray:
        """The initial ``theta``: the kernel's and, if tuned, ``log(noise_level)``."""
        theta = self.kernel.theta
        return np.append(theta, self.noise.theta) if self.noise_is_free else theta

    @property
    def bounds(self) -> np.ndarray:
        """Bounds of ``theta`` (the kernel's ``bounds``, log noise bounds), of shape ``(n, 2)``."""
        bounds = self.kernel.bounds.reshape(-1, 2)
        if self.noise_is_free:
            bounds = np.vstack([bounds, self.noise.bounds])
        return bounds

    def roles(self) -> list:
        """One :class:`~gpmultirate.kernels.Role` per kernel entry of ``theta``."""
        return observe(self.kernel).roles()

    def scale_positions(self):
        """``[(position, power)]`` of the amplitudes that scale the whole kernel, or None."""
        term = observe(self.kernel)
        positions = term.scale_roles()
        if positions is None:
            return None
        roles = term.roles()
        return [(i, roles[i].power) for i in positions]

    def amplitude_couplings(self):
        """Correlations and the amplitudes scaling their terms, as positions in ``theta``.

        ``[(correlation, amplitude, power)]`` with the amplitude's power (see
        :meth:`~gpmultirate.kernels.ObservedTerm.amplitude_couplings`).
        """
        term = observe(self.kernel)
        roles = term.roles()
        return [(j, a, roles[a].power) for j, a in term.amplitude_couplings()]

    def split(self, theta, into=None):
        """The kernel and noise level of ``theta``.

        With ``into`` (a kernel of the same structure) its ``theta`` is set
        in place instead of cloning.
        """
        kernel, noise = self.split_models(theta, into)
        return kernel, noise.level

    def split_models(self, theta, into=None):
        """The kernel and the noise model of ``theta`` (``into`` as in :meth:`split`)."""
        n_kernel = self.kernel.theta.shape[0]
        if into is None:
            kernel = self.kernel.clone_with_theta(theta[:n_kernel])
        else:
            into.theta = theta[:n_kernel]
            kernel = into
        return kernel, self.noise.with_theta(theta[n_kernel:])

    def moved_to(self, kernel, noise_level) -> "TuningObjective":
        """The same objective, on the same data, started at ``kernel`` and ``noise_level``.

        ``noise_level`` is the white noise variance, or a noise model of the
        objective's kind (:mod:`gpmultirate.noise`) for a disturbance model.
        """
        moved = type(self).__new__(type(self))
        moved.__dict__.update(self.__dict__)
        if isinstance(noise_level, numbers.Real):
            if self.coloured:
                raise ValueError("a disturbance model moves to a noise model, not a noise level")
            noise = WhiteNoise(float(noise_level), self.noise.noise_bounds)
        else:
            noise = noise_level
        moved.kernel, moved.noise = kernel, noise
        return moved

    def reusing_kernel(self) -> "TuningObjective":
        """A copy whose evaluations set the hyperparameters of one working kernel in place.

        An optimizer evaluates hundreds of points, and a deep copy of the
        kernel per point is a large part of a small problem's cost.
        """
        reusing = self.moved_to(self.kernel, self.noise)
        reusing._work = clone(self.kernel)
        return reusing


class LogEvidence(TuningObjective):
    """The log marginal likelihood of the data as a function of ``theta``.

    The objective that tuning maximizes: ``theta`` is the kernel's ``theta``
    followed, when the noise level is tuned, by ``log(noise_level)``.  Long
    records are reduced once here (:meth:`~gpmultirate.observations.Observation.reduced`),
    so an evaluation never costs more than ``O(P^3)``.

    Parameters
    ----------
    observation : Observation
    y : ndarray of shape (M,)
    kernel : sklearn Kernel
        The kernel at the initial hyperparameters (not modified).
    noise_level : float
        The noise variance; the initial value when it is tuned.
    noise_bounds : pair of floats or "fixed"

    Attributes
    ----------
    data, z : Observation and ndarray
        The observation and outputs the evidence is computed from (reduced
        when ``M > P``).
    noise_is_free : bool
        Whether ``log(noise_level)`` is the last entry of ``theta``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate import DownsampledConvolution
    >>> from gpmultirate.kernels import DC
    >>> rng = np.random.default_rng(0)
    >>> op = DownsampledConvolution(rng.standard_normal(90), factor=3, order=30)
    >>> y = op.matvec(0.8 ** np.arange(30)) + 0.01 * rng.standard_normal(op.n_outputs)
    >>> evidence = LogEvidence(op, y, C(1.0) * DC(), 1e-3, (1e-6, 1.0))
    >>> value, gradient = evidence(evidence.theta, eval_gradient=True)
    >>> gradient.shape
    (4,)
    """

    has_fisher = True

    def __init__(self, observation, y, kernel, noise_level: float, noise_bounds, noise=None):
        super().__init__(kernel, noise_level, noise_bounds, noise)
        if self.coloured:
            # a reduction assumes white noise: the disturbance needs the samples themselves;
            # its Fisher information where the noise offers it (the dense route)
            self.data, self.z = observation, np.asarray(y, dtype=float)
            self.has_fisher = self.noise.offers_fisher(observation)
        else:
            self.data, self.z = reduce_observation(observation, y)

    @property
    def n_outputs(self) -> int:
        """Outputs of the (reduced) data: the size of every data-space matrix."""
        return self.data.n_outputs

    def scale_groups(self, theta):
        """``[(positions, powers, S_part)]`` of independently scaled parts of ``S`` at ``theta``, or None."""
        kernel, _ = self.split(theta)
        tree = observe(kernel, self.data)
        groups = tree.scale_groups()
        if groups is None:
            return None
        roles = tree.roles()
        return [(positions, [roles[i].power for i in positions], S) for positions, S in groups]

    @property
    def by_precision(self) -> bool:
        """Whether evaluations go through the prior's tridiagonal precision.

        So they do for square or reduced data (``M = P``) and a prior that
        offers one (DC, a constant times DC): each evaluation is then a
        ``P x P`` Cholesky factor and a triangular inverse, much cheaper than
        the data-space Fisher information.
        """
        return takes_precision_route(self.kernel, self.data, self.noise)

    def remainder(self):
        """The :class:`~gpmultirate.covariance.Remainder` of the reduced data at the initial noise."""
        return self.noise.remainder(self.data)

    def data_covariance(self, theta, gradient: bool = False):
        """The :class:`~gpmultirate.covariance.DataCovariance` of the (reduced) data at ``theta``.

        The route is the noise model's (``noise.data_covariance``); with
        ``gradient`` it is formed for ``log_likelihood_gradient``.
        """
        kernel, noise = self.split_models(theta, into=self._work)
        return noise.data_covariance(observe(kernel, self.data), gradient)

    def covariance(self) -> np.ndarray:
        """``S = Phi K Phi^T`` of the (reduced) data at the initial kernel."""
        return observe(self.kernel, self.data).covariance()

    def __call__(self, theta, eval_gradient: bool = False):
        """The log evidence at ``theta`` and, with ``eval_gradient``, its gradient."""
        if not eval_gradient:
            return self.data_covariance(theta).log_likelihood(self.z)
        return self.data_covariance(theta, gradient=True).log_likelihood_gradient(self.z)

    def with_fisher(self, theta):
        """The log evidence, its gradient and its Fisher information at ``theta``."""
        kernel, noise = self.split_models(theta, into=self._work)
        return fisher_covariance(kernel, self.data, noise).log_likelihood_fisher(self.z)

    def along(self, theta, index: int, values):
        """The log evidence for each value of ``theta[index]``, or None.

        ``values`` are hyperparameter values (not their ``theta`` coordinates).  None unless
        the entry belongs to a low-rank summand of the kernel.
        """
        role = self.roles()[index]
        kernel, noise = self.split(theta, into=self._work)
        prefix = role.name[: -len(role.leaf_name)].rstrip("_")
        owner = kernel.get_params()[prefix] if prefix else kernel
        return resonance_grid_log_marginal_likelihood(
            self.data, kernel, owner, role.leaf_name, noise, self.z, values
        )

    def posterior(self, kernel, noise_level):
        """The posterior of the coefficients for ``kernel`` and ``noise_level``.

        ``noise_level`` may be a noise model (:mod:`gpmultirate.noise`): the
        posterior is then the data-space one under that disturbance.
        """
        if isinstance(noise_level, numbers.Real):
            return posterior(self.data, kernel, float(noise_level), self.z)
        if noise_level.white:
            return posterior(self.data, kernel, noise_level.level, self.z)
        return posterior_covariance(kernel, self.data, noise_level).posterior(self.z)
