"""The plant from an identified process sensitivity and a known controller.

In the paper's experiment the excitation ``r`` is added to the output of a
controller ``C`` that a fast loop sensor ``P_y`` closes; a fit of the slow
sensor's samples on ``r`` identifies the process sensitivity
``PS_z = P_z (1 + C P_y)^-1``, not the plant ``P_z``.  With the loop sensor's
process sensitivity ``PS_y = P_y (1 + C P_y)^-1`` (a fit of the fast loop
sensor on ``r``, where it is logged), ``1 + C P_y = 1 / (1 - C PS_y)``, so

``P_z = PS_z / (1 - C PS_y)``;

where the loop sensor is the slow sensor itself read at the fast rate
inside the loop (``P_y = P_z``), ``PS_y = PS_z``.  The band comes from
posterior draws of both fits (independent records of noise: independent
draws).
"""

from __future__ import annotations

import numpy as np

from gpmultirate.closedloop.controller import as_controller
from gpmultirate.closedloop.response import (
    LoopResponse, check_loop_frequencies, frequency_draws, loop_response,
)
from gpmultirate.validation import check_int, check_rng

__all__ = ["plant_from_process_sensitivity"]


def plant_from_process_sensitivity(process_sensitivity, controller, loop_sensor=None,
                                   freqs=None, level: float = 0.95, n_samples: int = 500,
                                   random_state=None) -> LoopResponse:
    """``P_z = PS_z / (1 - C PS_y)`` with its band, from fitted process sensitivities.

    Parameters
    ----------
    process_sensitivity : fitted FIRGaussianProcess
        ``PS_z``: the slow sensor fitted on the excitation ``r`` (one input).
    controller : float, array-like, scipy.signal.dlti or python-control system
        ``C`` at the fast rate (:func:`~gpmultirate.closedloop.as_controller`).
    loop_sensor : fitted FIRGaussianProcess, optional
        ``PS_y``: the fast loop sensor fitted on ``r`` (``factor=1``), where
        it is measured; by default ``PS_z`` (the loop is closed by the slow
        sensor's own signal at the fast rate).
    freqs : array-like, optional
        Frequencies in Hz; by default the DFT bins of the record.
    level : float, default=0.95
        Level of the pointwise band.
    n_samples : int, default=500
        Posterior draws.
    random_state : int, Generator or None

    Returns
    -------
    LoopResponse

    Examples
    --------
    A loop ``C = 0.5`` around ``P = 0.8 z^-1``: ``PS = 0.8 z^-1 / (1 + 0.4 z^-1)``.

    >>> import numpy as np
    >>> from scipy import signal
    >>> import gpmultirate as gm
    >>> from gpmultirate.closedloop import plant_from_process_sensitivity
    >>> rng = np.random.default_rng(0)
    >>> r = rng.standard_normal(600)
    >>> y = signal.lfilter([0.0, 0.8], [1.0, 0.4], r) + 0.01 * rng.standard_normal(600)
    >>> ps = gm.FIRGaussianProcess(order=30).fit(r, y)
    >>> plant = plant_from_process_sensitivity(ps, 0.5, freqs=[0.1, 0.3], random_state=0)
    >>> np.round(plant.magnitude, 2)
    array([0.8, 0.8])
    """
    n_samples = check_int(n_samples, "n_samples", low=2)
    rng = check_rng(random_state)
    freqs = check_loop_frequencies(process_sensitivity, freqs)
    sample_time = float(process_sensitivity.sample_time)
    if loop_sensor is not None and float(loop_sensor.sample_time) != sample_time:
        raise ValueError("loop_sensor must have the sample_time of process_sensitivity "
                         f"({sample_time}); got {loop_sensor.sample_time}")
    C = as_controller(controller).frequency_response(freqs, sample_time)
    mean_z, draws_z = frequency_draws(process_sensitivity, freqs, n_samples, rng)
    if loop_sensor is None:
        mean_y, draws_y = mean_z, draws_z
    else:
        mean_y, draws_y = frequency_draws(loop_sensor, freqs, n_samples, rng)
    mean = mean_z / (1.0 - C * mean_y)
    draws = draws_z / (1.0 - C * draws_y)
    return loop_response(freqs, mean, draws, level, sample_time, "plant")
