"""A camera loop's response between the frames, from the identified fast-rate plant.

The loop of :func:`gpmultirate.simulation.simulate_camera_loop`: frames
``y(mF)``, a controller ``K`` at the frame rate, its output held over the
frame ``delay`` frames later, and the excitation (or an input disturbance)
``r`` added at the fast rate.  The loop is periodically time varying: a
fast-rate sinusoid ``r = exp(j w n)`` makes the fast output a sum of the
aliases ``w_j = w + 2 pi j / F``, ``j = 0..F-1``.  With
``theta = F w``, the hold's spectrum ``Z(w) = sum_{p<F} exp(-j w p)``, the
delayed controller ``K~ = K(exp(j theta)) exp(-j theta delay)`` and the
frame-rate plant ``L = (1/F) sum_j G(w_j) Z(w_j)``:

* the frames see ``Y_s = G(w) / (1 + K~ L)`` (what the camera measures);
* the fast output has ``Y_j = G(w_j) (delta_j0 - K~ Y_s Z(w_j) / F)`` at
  ``w_j``.

The *performance frequency gain* ``sqrt(sum_j |Y_j|^2)`` is the fast
output's rms per unit rms of ``r``: the response between the frames,
including what the frames alias away.  Bands come from posterior draws of
``G`` (:mod:`gpmultirate.closedloop.response`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gpmultirate.closedloop.controller import as_controller
from gpmultirate.closedloop.response import (
    LoopResponse, check_loop_frequencies, frequency_draws, loop_response,
)
from gpmultirate.validation import check_int, check_rng

__all__ = ["IntersamplePerformance", "camera_loop_response", "intersample_performance"]


@dataclass(frozen=True)
class IntersamplePerformance:
    """The loop's gain from ``r`` to the fast output and to the frames, with bands.

    Attributes
    ----------
    fast : LoopResponse
        The performance frequency gain ``sqrt(sum_j |Y_j|^2)`` (a magnitude).
    frames : LoopResponse
        ``Y_s``: the gain the frames see.
    factor, delay : int
    """

    fast: LoopResponse
    frames: LoopResponse
    factor: int
    delay: int


def camera_loop_response(G_aliases: np.ndarray, freqs, sample_time: float, factor: int,
                         controller, delay: int):
    """``(performance gain, Y_s)`` from the plant's FRF at the aliases (module docstring).

    ``G_aliases`` has shape ``(..., factor, n)``: ``G(f + j / (factor T))`` for
    ``j = 0..factor-1`` at each of the ``n`` frequencies ``f``.
    """
    freqs = np.asarray(freqs, dtype=float)
    w = 2 * np.pi * freqs * sample_time
    aliases = w[None, :] + 2 * np.pi * np.arange(factor)[:, None] / factor
    Z = np.sum(np.exp(-1j * aliases[None] * np.arange(factor)[:, None, None]), axis=0)
    theta = factor * w
    K = as_controller(controller).frequency_response(freqs, factor * sample_time)
    K = K * np.exp(-1j * theta * delay)
    L = np.sum(G_aliases * Z, axis=-2) / factor
    Ys = G_aliases[..., 0, :] / (1.0 + K * L)
    Y = -G_aliases * (K * Ys)[..., None, :] * Z / factor
    Y[..., 0, :] += G_aliases[..., 0, :]
    return np.sqrt(np.sum(np.abs(Y) ** 2, axis=-2)), Ys


def intersample_performance(plant, controller, factor: int | None = None, delay: int = 1,
                            freqs=None, level: float = 0.95, n_samples: int = 500,
                            random_state=None) -> IntersamplePerformance:
    """The camera loop's fast-rate response to ``r`` and what its frames see, with bands.

    Parameters
    ----------
    plant : fitted FIRGaussianProcess
        The fast-rate plant (for instance fitted with ``excitation=``).
    controller : float, array-like, scipy.signal.dlti or python-control system
        The controller at the frame rate.
    factor : int, optional
        Fast samples per frame; by default the plant's ``factor``.
    delay : int, default=1
        Frames from a frame to the hold of the controller's output from it.
    freqs : array-like, optional
        Frequencies of ``r`` in Hz, up to the slow Nyquist frequency
        ``1 / (2 factor T)`` (the aliases cover the fast band); by default
        200 of them.
    level : float, default=0.95
    n_samples : int, default=500
        Posterior draws of the plant.
    random_state : int, Generator or None

    Returns
    -------
    IntersamplePerformance

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> import gpmultirate as gm
    >>> from gpmultirate.closedloop import intersample_performance
    >>> from gpmultirate.kernels import TC
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(400)
    >>> g = 0.3 * 0.8 ** np.arange(40)
    >>> y_slow = np.convolve(u, g)[:400:4] + 0.01 * rng.standard_normal(100)
    >>> plant = gm.FIRGaussianProcess(C(1.0) * TC(), factor=4, order=40).fit(u, y_slow)
    >>> perf = intersample_performance(plant, 0.5, n_samples=50, random_state=0)
    >>> bool(np.all(perf.fast.magnitude >= perf.frames.magnitude - 1e-9))
    True
    """
    factor = check_int(plant.factor if factor is None else factor, "factor", low=1)
    delay = check_int(delay, "delay", low=0)
    n_samples = check_int(n_samples, "n_samples", low=2)
    sample_time = float(plant.sample_time)
    slow_nyquist = 0.5 / (factor * sample_time)
    if freqs is None:
        freqs = np.linspace(0.0, slow_nyquist, 201)[1:]
    freqs = check_loop_frequencies(plant, freqs)
    if np.any(freqs > slow_nyquist):
        raise ValueError(f"freqs must lie below the slow Nyquist frequency {slow_nyquist:g}: "
                         "their aliases cover the fast band")
    grid = (freqs[None, :] + np.arange(factor)[:, None] / (factor * sample_time)).ravel()
    mean, draws = frequency_draws(plant, grid, n_samples, check_rng(random_state))
    mean = mean.reshape(factor, -1)
    draws = draws.reshape(n_samples, factor, -1)
    gain, Ys = camera_loop_response(mean, freqs, sample_time, factor, controller, delay)
    gains, Yss = camera_loop_response(draws, freqs, sample_time, factor, controller, delay)
    return IntersamplePerformance(
        fast=loop_response(freqs, gain, gains, level, sample_time, "fast output"),
        frames=loop_response(freqs, Ys, Yss, level, sample_time, "frames"),
        factor=factor, delay=delay)
