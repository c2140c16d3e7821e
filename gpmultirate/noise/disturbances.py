"""The choice of a noise model: the named disturbances, their instants, and cheap tests of need.

:func:`make_noise` turns the estimator's ``noise_kernel`` into a noise model
(:class:`~gpmultirate.noise.WhiteNoise`,
:class:`~gpmultirate.noise.KernelNoise`); :func:`noise_instants` gives the
instants of the slow samples; :func:`disturbance_evidence_gain` and
:func:`~gpmultirate.noise.ar1_evidence_gain` say whether the data call for a
disturbance at all.
"""

from __future__ import annotations

import numpy as np
from sklearn.gaussian_process.kernels import ConstantKernel, Kernel, Matern, WhiteKernel

from gpmultirate.covariance import matrix_log_density
from gpmultirate.noise.ar1 import GAIN_LENGTH_SCALES, GAIN_SCALES, exponential_parts
from gpmultirate.noise.base import instant_blocks
from gpmultirate.noise.kernel import KernelNoise, has_white
from gpmultirate.noise.white import WhiteNoise

__all__ = [
    "AR1_DISTURBANCE",
    "GAIN_ADDED_LEVELS",
    "GAIN_LENGTH_SCALES",
    "GAIN_SCALES",
    "GAIN_SHARES",
    "NAMED_DISTURBANCES",
    "disturbance_evidence_gain",
    "make_noise",
    "noise_instants",
]

#: The named disturbances of ``make_noise``: Matérn smoothness ``nu`` of each.
NAMED_DISTURBANCES = {"matern12": 0.5, "matern32": 1.5}
#: The named choice of a pure AR(1) noise ``C * Matern(nu=0.5)`` without white
#: noise: on one uniform grid with more samples than coefficients it is tuned
#: through its tridiagonal precision (:class:`gpmultirate.covariance.AR1Covariance`).
AR1_DISTURBANCE = "ar1"
#: The shares of the noise variance the disturbance takes that
#: :func:`disturbance_evidence_gain` tries (with :data:`GAIN_LENGTH_SCALES`
#: and :data:`GAIN_SCALES`).
GAIN_SHARES = (0.5, 0.9)
#: The variances, relative to the slow samples' power ``mean(y**2)``, of a
#: disturbance :func:`disturbance_evidence_gain` adds on top of the white noise
#: (those above three times the white noise's): where the prior has taken the
#: disturbance into the response, the white noise tuned to nearly nothing holds
#: none of it to share (AR(1) at 40-60 dB, docs/disturbances.rst).
GAIN_ADDED_LEVELS = (1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2)


def disturbance_evidence_gain(S, y, noise_level: float, instants) -> float:
    """The log evidence a fixed Matérn disturbance gains over white noise, the prior held.

    A cheap test of whether the slow samples call for a disturbance model:
    with the signal covariance ``S = Phi K Phi^T`` of a tuned white-noise fit
    held, the white noise ``gamma I`` is replaced by
    ``s gamma ((1 - w) I + w R)``, ``R`` the correlation of a Matérn 1/2 or
    3/2 process over the instants (records independent), for a small grid of
    time scales ``l`` (:data:`GAIN_LENGTH_SCALES` times the median spacing),
    shares ``w`` (:data:`GAIN_SHARES`) and scales ``s`` (:data:`GAIN_SCALES`);
    and ``gamma I + v R``, the disturbance added on top, for the variances
    ``v`` of :data:`GAIN_ADDED_LEVELS` times ``mean(y**2)`` above ``3 gamma``
    (a prior that took the disturbance into the response leaves ``gamma``
    tuned to nearly nothing, and nothing for a share of it to hold).
    Returns the largest ``log N(y; 0, S + N_disturbance) - log N(y; 0, S + gamma I)``
    (negative when no disturbance on the grid does better).  Each grid point
    costs one ``M x M`` Cholesky factorization.

    Parameters
    ----------
    S : ndarray of shape (M, M)
        The signal part of the data covariance (not modified).
    y : ndarray of shape (M,)
    noise_level : float
        The white noise variance ``gamma`` of the fit.
    instants : array-like of shape (M,), or a list of them
        The instant of each slow sample in fast samples, one array per record.

    Returns
    -------
    float

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> t = 3.0 * np.arange(200)
    >>> S = np.zeros((200, 200))
    >>> white = rng.standard_normal(200)
    >>> drift = np.cumsum(rng.standard_normal(200)) * 0.3 + 0.3 * white
    >>> bool(disturbance_evidence_gain(S, white, 1.0, t) < 2.0)
    True
    >>> bool(disturbance_evidence_gain(S, drift, np.var(drift), t) > 20.0)
    True
    """
    S = np.asarray(S, dtype=float)
    y = np.asarray(y, dtype=float)
    gamma = float(noise_level)
    M = y.shape[0]
    if S.shape != (M, M):
        raise ValueError(f"S must be of shape ({M}, {M}); got {S.shape}")
    blocks = instant_blocks(instants)
    if sum(t.shape[0] for t in blocks) != M:
        raise ValueError("instants must give one instant per sample of y")

    def log_evidence(N):
        return matrix_log_density(S + N, y)

    white = log_evidence(gamma * np.eye(M))
    distance = np.full((M, M), np.inf)
    start = 0
    steps = []
    for t in blocks:
        n = t.shape[0]
        distance[start : start + n, start : start + n] = np.abs(t[:, None] - t[None, :])
        steps.append(np.diff(t))
        start += n
    steps = np.abs(np.concatenate(steps))
    spacing = float(np.median(steps)) if steps.size and np.median(steps) > 0 else 1.0
    power = float(np.mean(y**2))
    added = [level * power for level in GAIN_ADDED_LEVELS if level * power > 3.0 * gamma]
    best = -np.inf
    for length_scale in spacing * np.asarray(GAIN_LENGTH_SCALES):
        d = distance / length_scale
        with np.errstate(invalid="ignore"):
            shapes = (np.exp(-d), (1.0 + np.sqrt(3.0) * d) * np.exp(-np.sqrt(3.0) * d))
        for R in shapes:
            R = np.nan_to_num(R, nan=0.0)  # inf * 0 across records
            for share in GAIN_SHARES:
                N = share * R
                N[np.diag_indices(M)] += 1.0 - share
                for scale in GAIN_SCALES:
                    best = max(best, log_evidence(scale * gamma * N) - white)
            for variance in added:
                N = variance * R
                N[np.diag_indices(M)] += gamma
                best = max(best, log_evidence(N) - white)
    return best


def noise_instants(observation) -> list[np.ndarray]:
    """The instant of every slow sample of each record, in fast samples.

    The fast-sample index of each sample (``sample_indices``), or the
    reading's stamp for readings at their own instants (``sample_times``);
    one array per record, as :class:`KernelNoise` takes them.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import DownsampledConvolution
    >>> noise_instants(DownsampledConvolution(np.ones(10), 3, 4, offset=1))[0].tolist()
    [1.0, 4.0, 7.0]
    """
    blocks = []
    for record in observation.records:
        instants = getattr(record, "sample_indices", None)
        if instants is None:
            instants = getattr(record, "sample_times", None)
        if instants is None:
            raise ValueError(
                f"a disturbance model needs the instant of every slow sample; "
                f"{type(record).__name__} does not give them"
            )
        blocks.append(np.asarray(instants, dtype=float))
    return blocks


def make_noise(noise_kernel, noise_level: float, noise_level_bounds, instants,
               length_scale: float = 10.0):
    """The noise model of a choice: ``"white"``, a named disturbance or a kernel.

    Parameters
    ----------
    noise_kernel : "white", "matern12", "matern32", "ar1" or sklearn Kernel
        ``"white"``: ``gamma I`` (:class:`~gpmultirate.noise.WhiteNoise`).
        ``"matern12"``/``"matern32"``: white noise plus
        ``C * Matern(length_scale, nu=1/2 or 3/2)`` over the instants, the
        constant started at ``noise_level`` with the noise level's bounds.
        ``"ar1"``: ``C * Matern(length_scale, nu=1/2)`` alone (no white
        noise), an AR(1) process on a uniform grid.
        A kernel: a disturbance over the instants, added to white noise of
        ``noise_level`` unless it holds a ``WhiteKernel`` summand itself or
        is the AR(1) form ``[C *] Matern(nu=0.5)``, used as it is.
    noise_level : float
        The white noise variance ``gamma`` (the start when it is tuned).
    noise_level_bounds : pair of floats or "fixed"
    instants : array-like of shape (M,), or a list of them
        The instant of each slow sample in fast samples, one array per record.
    length_scale : float, default=10.0
        The start of a named disturbance's time scale, in fast samples.

    Returns
    -------
    WhiteNoise or KernelNoise

    Examples
    --------
    >>> import numpy as np
    >>> noise = make_noise("matern32", 0.1, (1e-3, 1.0), np.arange(5) * 3.0)
    >>> noise.kernel
    WhiteKernel(noise_level=0.1) + 0.316**2 * Matern(length_scale=10, nu=1.5)
    >>> type(make_noise("white", 0.1, "fixed", np.arange(5))).__name__
    'WhiteNoise'
    >>> round(make_noise("ar1", 0.1, (1e-3, 1.0), np.arange(5) * 3.0).structure().pole, 4)
    0.7408
    """
    gamma = float(noise_level)
    if not (np.isfinite(gamma) and gamma > 0):
        raise ValueError(f"noise_level must be finite and positive; got {noise_level!r}")
    bounds = noise_level_bounds
    if isinstance(noise_kernel, str):
        if noise_kernel == "white":
            return WhiteNoise(gamma, bounds)
        if noise_kernel not in NAMED_DISTURBANCES and noise_kernel != AR1_DISTURBANCE:
            raise ValueError(
                f"noise_kernel must be 'white', {', '.join(map(repr, NAMED_DISTURBANCES))}, "
                f"{AR1_DISTURBANCE!r} or a scikit-learn kernel; got {noise_kernel!r}"
            )
        disturbance = ConstantKernel(gamma, bounds) * Matern(
            length_scale, "fixed" if isinstance(bounds, str) else (1.0, 1e4),
            nu=NAMED_DISTURBANCES.get(noise_kernel, 0.5))
        if noise_kernel == AR1_DISTURBANCE:
            return KernelNoise(disturbance, instants)
        return KernelNoise(WhiteKernel(gamma, bounds) + disturbance, instants)
    if not isinstance(noise_kernel, Kernel):
        raise ValueError(f"noise_kernel must be 'white', a named disturbance or a scikit-learn "
                         f"kernel; got {type(noise_kernel).__name__}")
    if has_white(noise_kernel) or exponential_parts(noise_kernel) is not None:
        return KernelNoise(noise_kernel, instants)
    return KernelNoise(WhiteKernel(gamma, bounds) + noise_kernel, instants)
