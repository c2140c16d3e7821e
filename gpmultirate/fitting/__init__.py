"""The steps of :meth:`FIRGaussianProcess.fit <gpmultirate.FIRGaussianProcess.fit>`.

``fit`` reads as the list of these steps; each is a function of its own
module that takes what it needs as arguments and returns what it chose, and
the estimator adopts the result:

* :mod:`~gpmultirate.fitting.settings`: the parameters, checked once;
* :mod:`~gpmultirate.fitting.between_ticks`: what the readings are (on the
  ticks, or at their own instants: exact or interpolated), and the check of
  an interpolated fit, which may fit the readings again exactly;
* :mod:`~gpmultirate.fitting.order`: the order (candidates, the default
  order's pilot fits, or as given), the held-out check of shorter orders and
  the warning of a too-short order;
* :mod:`~gpmultirate.fitting.one_order`: the fit at one order, through
* :mod:`~gpmultirate.fitting.prior`: the default prior and the units of the
  prior;
* :mod:`~gpmultirate.fitting.auto_kernel`: the resonance search of
  ``kernel="auto"`` and its terms judged again under a disturbance;
* :mod:`~gpmultirate.fitting.disturbance`: the choice between white noise
  and a disturbance model;
* :mod:`~gpmultirate.fitting.spread`: the spread of tuned frequencies that
  the posterior adds after conditioning.
"""
