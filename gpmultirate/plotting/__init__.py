"""Figures of identified fast-rate FIR models, in the style of the paper.

The functions draw data objects: a
:class:`~gpmultirate.responses.FrequencyResponse`, an
:class:`~gpmultirate.responses.ImpulseResponse`, an
:class:`~gpmultirate.responses.OutputPrediction`, a
:class:`~gpmultirate.study.StudyResult` or a
:class:`~gpmultirate.study.NonidentifiableExample`.  They compute nothing
about the model: the data objects hold the means, bands and draws.

Every function draws on axes it is given (``ax=`` or, for the Bode plot,
``axes=(magnitude, phase)``), creates a figure only when none is given,
returns the axes and the artists it drew, and never calls ``plt.show()``.
Calling a function again on the same axes overlays, so that several
estimates (least squares, DC kernel, PK kernel) share one figure.

* :func:`plot_bode`: FRF magnitude and phase with credible bands, the true
  FRF, the FRF error and the slow and fast Nyquist frequencies (Fig. 6, 10, 11).
* :func:`plot_impulse_response`: impulse response over lag with a band and
  posterior draws.
* :func:`plot_intersample`: fast-rate (intersample) output predicted from
  slow samples.
* :func:`plot_gof_vs_order` and :func:`plot_study`: goodness of fit against
  model order over Monte Carlo runs (Fig. 5, 9).
* :func:`plot_residuals`: autocorrelation of the slow residuals and their
  cross-correlation with each input, with the bands for white residuals.
* :func:`plot_loop_response` and :func:`plot_intersample_performance`:
  closed-loop quantities with their bands (:doc:`/closed_loop`).
* :func:`plot_nonidentifiable_example`: three fast-rate models with
  identical slow-rate outputs (Example 1, Fig. 2).

The modules: :mod:`gpmultirate.plotting.frequency` (Bode plot),
:mod:`gpmultirate.plotting.time` (time-domain figures),
:mod:`gpmultirate.plotting.study` (study figures) and
:mod:`gpmultirate.plotting.axes` (helpers shared by them).

Examples
--------
>>> import matplotlib
>>> matplotlib.use("Agg")
>>> import numpy as np
>>> from gpmultirate.plotting import plot_impulse_response
>>> from gpmultirate.responses import ImpulseResponse
>>> response = ImpulseResponse(lags=np.arange(4.0), mean=0.5 ** np.arange(4),
...                            std=np.full(4, 0.1), continuous=False)
>>> drawn = plot_impulse_response(response, label="estimate")
>>> drawn.mean_line.get_ydata().tolist()
[1.0, 0.5, 0.25, 0.125]
>>> import matplotlib.pyplot as plt
>>> plt.close("all")
"""

from gpmultirate.plotting.frequency import BodePlot, plot_bode
from gpmultirate.plotting.loop import (
    LoopResponsePlot, plot_intersample_performance, plot_loop_response,
)
from gpmultirate.plotting.residuals import ResidualPlot, plot_residuals
from gpmultirate.plotting.study import GoFPlot, StudyPlot, plot_gof_vs_order, plot_study
from gpmultirate.plotting.time import (
    ImpulseResponsePlot,
    IntersamplePlot,
    plot_impulse_response,
    plot_intersample,
    plot_nonidentifiable_example,
)

__all__ = [
    "BodePlot",
    "GoFPlot",
    "ImpulseResponsePlot",
    "IntersamplePlot",
    "LoopResponsePlot",
    "ResidualPlot",
    "StudyPlot",
    "plot_bode",
    "plot_gof_vs_order",
    "plot_impulse_response",
    "plot_intersample",
    "plot_intersample_performance",
    "plot_loop_response",
    "plot_nonidentifiable_example",
    "plot_residuals",
    "plot_study",
]
