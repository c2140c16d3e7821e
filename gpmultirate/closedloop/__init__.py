"""Identification from closed-loop data: a plant in a loop that a (slow) sensor closes.

* :mod:`~gpmultirate.closedloop.controller`: the known loop controller.
* :mod:`~gpmultirate.closedloop.projection`: the first stage of the
  two-stage method, ``u`` from the excitation ``r``
  (``FIRGaussianProcess.fit(u, y_slow, excitation=r)``).
* :mod:`~gpmultirate.closedloop.detection`: does the input depend on past
  residuals (the warning of a fit without an excitation)?
* :mod:`~gpmultirate.closedloop.plant`: the plant from an identified process
  sensitivity and a known controller, with its band.
* :mod:`~gpmultirate.closedloop.performance`: the camera loop's response
  between the frames, with its band.
* :mod:`~gpmultirate.closedloop.response`: loop quantities with bands from
  posterior draws.
"""

from gpmultirate.closedloop.controller import Controller, as_controller
from gpmultirate.closedloop.detection import FeedbackTest, check_feedback, feedback_test
from gpmultirate.closedloop.performance import IntersamplePerformance, intersample_performance
from gpmultirate.closedloop.plant import plant_from_process_sensitivity
from gpmultirate.closedloop.response import LoopResponse
from gpmultirate.closedloop.projection import (
    ExcitationModel, fit_excitation_model, loop_input, project_input,
)

__all__ = ["Controller", "as_controller", "ExcitationModel", "fit_excitation_model",
           "project_input", "loop_input", "FeedbackTest", "feedback_test", "check_feedback", "LoopResponse",
           "plant_from_process_sensitivity", "IntersamplePerformance", "intersample_performance"]
