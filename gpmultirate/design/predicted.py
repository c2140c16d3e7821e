"""The band before the measurement: the posterior of an experiment that has not been run.

For fixed hyperparameters the posterior covariance of the FIR coefficients,

    Sigma = K - K Phi^T (Phi K Phi^T + gamma I)^{-1} Phi K,

depends on the input (through the regressor ``Phi``, eq. 8) and on the
sampling instants, never on the output.  :func:`predicted_posterior` builds the
observation of the planned experiment as a fit builds it and takes the
library's posterior of it (:mod:`gpmultirate.inference`) with outputs that
are all zero: its mean is the prior mean (zero) and its covariance is the
one every record of that experiment will give.  The FRF's band and the
impulse response's band follow from it as a fitted model's do.
"""

from __future__ import annotations

import numpy as np

from gpmultirate.design.prior import design_prior
from gpmultirate.design.sampling import as_scheme
from gpmultirate.inference import LogEvidence, blas_threads_for, posterior
from gpmultirate.noise import make_noise, noise_instants
from gpmultirate.responses import (
    FrequencyResponse,
    check_frequencies,
    default_frequencies,
    dft_matrix,
)
from gpmultirate.kernels import check_lags
from gpmultirate.observations.timed import check_duration
from gpmultirate.units import duration_in_fast_periods, in_fast_periods
from gpmultirate.validation import check_level, check_signal

__all__ = [
    "posterior_of",
    "predicted_frequency_response",
    "predicted_impulse_response",
    "predicted_posterior",
]


def _experiment(prior, u, factor, offset, sample_times, exposure, noise_level, order,
                sample_time, scheme):
    """The prior, the scheme and the observation of a planned experiment."""
    prior = design_prior(prior, order=order, sample_time=sample_time, noise_level=noise_level)
    u = check_signal(u, "u")
    if u.ndim != 1:
        raise ValueError(f"u must be one input, a 1-D array; got shape {u.shape}")
    if prior.initial_conditions == "zero" and u.shape[0] < prior.order:
        raise ValueError(f"u must have at least order = {prior.order} samples; "
                         f"got {u.shape[0]}")
    # stamps and an exposure in the units of the prior's sample_time, as fit takes them
    if sample_times is not None:
        sample_times = in_fast_periods(sample_times, prior.sample_time, u)
    if exposure is not None:
        exposure = duration_in_fast_periods(check_duration(exposure, "exposure"),
                                            prior.sample_time)
    scheme = as_scheme(scheme, factor=factor, offset=offset, sample_times=sample_times,
                       exposure=prior.exposure if exposure is None else exposure)
    observation = scheme.observation(u, prior.order, latency=prior.latency,
                                     initial_conditions=prior.initial_conditions)
    return prior, scheme, observation


def posterior_of(prior, observation):
    """The library's posterior of ``observation`` under ``prior``, from outputs all zero."""
    zeros = np.zeros(observation.n_outputs)
    with blas_threads_for(observation):
        if isinstance(prior.noise_kernel, str) and prior.noise_kernel == "white":
            return posterior(observation, prior.kernel, prior.noise_level, zeros)
        noise = make_noise(prior.noise_kernel, prior.noise_level, "fixed",
                           noise_instants(observation))
        evidence = LogEvidence(observation, zeros, prior.kernel, prior.noise_level, "fixed",
                               noise=noise)
        return evidence.posterior(prior.kernel, noise)


def predicted_posterior(prior, u, factor=3, offset=0, sample_times=None, exposure=None,
                        noise_level=None, *, order=None, sample_time=None, scheme=None):
    """The posterior of the FIR coefficients that any record of this experiment gives.

    Parameters are those of :func:`predicted_frequency_response`.

    Returns
    -------
    GaussianCoefficients
        Mean zero (the prior's); ``covariance()`` is the ``P x P`` posterior
        covariance, ``pair_variances`` and ``linear_map`` give those of linear
        functionals without it.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate.kernels import DC
    >>> u = np.random.default_rng(0).standard_normal(60)
    >>> post = predicted_posterior(C(1.0) * DC(0.8, 0.5), u, factor=3, order=20)
    >>> post.covariance().shape, float(np.abs(post.coef).max())
    ((20, 20), 0.0)
    """
    prior, _, observation = _experiment(prior, u, factor, offset, sample_times, exposure,
                                        noise_level, order, sample_time, scheme)
    return posterior_of(prior, observation)


def predicted_frequency_response(prior, u, factor=3, offset=0, sample_times=None,
                                 exposure=None, noise_level=None, freqs=None,
                                 level: float = 0.95, *, order=None, sample_time=None,
                                 scheme=None) -> FrequencyResponse:
    """The frequency response's band of an experiment, before it is run.

    For fixed hyperparameters the posterior covariance does not depend on
    the output: the returned bands are those of every record of this
    experiment, fitted with the prior's hyperparameters held fixed
    (``FIRGaussianProcess(kernel, noise_level=..., optimizer=None)``), at the
    cost of one such fit's posterior.  Its mean is the prior mean, zero.

    Parameters
    ----------
    prior : FIRGaussianProcess (fitted), sklearn Kernel or DesignPrior
        A pilot model (its tuned kernel, order, noise, sample time, exposure
        and latency), or a kernel with fixed hyperparameters in the data's
        units (then ``order=`` is required).
    u : array-like of shape (N,)
        The planned input, in the user's units.
    factor : int, default=3
        Downsampling factor ``F``.
    offset : int or sequence of int, default=0
        Fast index of the first slow sample, ``0..F-1``; several offsets are
        several slow sensors reading the same output.
    sample_times : array-like of shape (M,), optional
        Readings at their own instants, in the units of the prior's
        ``sample_time`` (seconds; fast sample periods when it is 1), as
        ``fit`` takes them (``factor`` and ``offset`` are then ignored).
    exposure : float, optional
        Each reading's exposure, in the same units; default the pilot
        model's, or 0 for a kernel.
    noise_level : float, optional
        White noise variance of a slow sample, in the output's units squared;
        default the pilot model's ``noise_level_``, or ``1e-4`` for a kernel.
    freqs : array-like, optional
        Frequencies in Hz (cycles per sample when ``sample_time`` is 1);
        default the DFT bins of ``u``.
    level : float, default=0.95
        Credible level of the bands.
    order : int, optional
        FIR order ``P``, required with a kernel prior.
    sample_time : float, optional
        Fast sample time ``T`` in seconds; default the model's, or 1.0.
    scheme : SamplingScheme, optional
        The sampling outright (replaces ``factor``, ``offset``,
        ``sample_times`` and ``exposure``).

    Returns
    -------
    FrequencyResponse
        ``real_std``, ``imag_std``, ``real_imag_corr`` and the bands are the
        posterior's for any output record; ``mean`` is zero.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate.kernels import DC
    >>> u = np.random.default_rng(0).standard_normal(120)
    >>> kernel = C(1.0) * DC(0.9, 0.5)
    >>> frf = predicted_frequency_response(kernel, u, factor=3, order=40, sample_time=0.01)
    >>> frf.slow_nyquist, bool(np.all(frf.mean == 0))
    (16.666666666666668, True)

    The band of a fit with the same hyperparameters held fixed, for any output:

    >>> import gpmultirate as gm
    >>> y_slow = np.random.default_rng(1).standard_normal(40)
    >>> fit = gm.FIRGaussianProcess(kernel, factor=3, order=40, noise_level=1e-4,
    ...                             optimizer=None, sample_time=0.01).fit(u, y_slow)
    >>> bool(np.allclose(fit.frequency_response().real_std, frf.real_std))
    True
    """
    level = check_level(level)
    prior, scheme, observation = _experiment(prior, u, factor, offset, sample_times, exposure,
                                             noise_level, order, sample_time, scheme)
    post = posterior_of(prior, observation)
    n_samples = np.asarray(u).shape[0]
    if freqs is None:
        freqs = default_frequencies(n_samples, prior.sample_time)
    freqs, _ = check_frequencies(freqs, prior.sample_time)
    E = dft_matrix(freqs, prior.sample_time, prior.order)
    with blas_threads_for(observation):
        var_re, var_im, cov = post.pair_variances(np.ascontiguousarray(E.real),
                                                  np.ascontiguousarray(E.imag))
    return FrequencyResponse.from_gaussian(
        freqs, np.zeros(freqs.shape[0], dtype=complex), var_re, var_im, cov, level=level,
        sample_time=prior.sample_time, factor=scheme.factor)


def predicted_impulse_response(prior, u, factor=3, offset=0, sample_times=None,
                               exposure=None, noise_level=None, lags=None, *, order=None,
                               sample_time=None, scheme=None):
    """The impulse response's posterior standard deviation of an experiment, before it is run.

    Parameters are those of :func:`predicted_frequency_response`, with
    ``lags`` (real, in fast samples; default ``0..P-1``) in place of ``freqs``.

    Returns
    -------
    lags : ndarray of shape (n,)
    std : ndarray of shape (n,)
        The posterior standard deviation of ``g`` at each lag, for any output
        record (the mean is the prior's, zero).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate.kernels import DC
    >>> u = np.random.default_rng(0).standard_normal(60)
    >>> lags, std = predicted_impulse_response(C(1.0) * DC(0.8, 0.5), u, order=20,
    ...                                        lags=[0.0, 0.5, 1.0])
    >>> lags.tolist(), bool(np.all(std > 0))
    ([0.0, 0.5, 1.0], True)
    """
    prior, _, observation = _experiment(prior, u, factor, offset, sample_times, exposure,
                                        noise_level, order, sample_time, scheme)
    lags = (np.arange(prior.order, dtype=float) if lags is None
            else check_lags(lags, "lags"))
    post = posterior_of(prior, observation)
    _, var = post.at_lags(lags[:, None])
    return lags, np.sqrt(np.maximum(var, 0.0))
