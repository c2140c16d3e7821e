"""Estimators of fast-rate FIR models from slow-rate output data.

* :class:`FIRGaussianProcess`: the kernel-regularised estimate of eq. (15)
  viewed as a Gaussian-process posterior over continuous lag, with
  marginal-likelihood tuning (eq. 19, noise inside the log-determinant).
* :class:`LeastSquaresFIR`: the least-squares baseline of eq. (11), which
  refuses non-unique problems (Lemma 1 and 2).

Both take one input or several (``u`` of shape ``(N, n_inputs)``), one record
or several (lists), slow samples at ``offset + m * factor`` or at any
``sample_indices``, missing samples as ``NaN``, and the initial conditions
``"zero"`` (at rest, the paper's case), ``"discard"`` or ``"periodic"``.

``FIRGaussianProcess.fit`` is the list of its steps; each step is a module of
:mod:`gpmultirate.fitting` (settings, readings between the ticks, the order,
the fit at one order with its prior, resonance search and disturbance
choice) that returns what it chose for the estimator to adopt.  Prediction,
scoring and the frequency response are :mod:`gpmultirate.prediction`'s.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy import linalg
from sklearn.base import BaseEstimator
from sklearn.gaussian_process.kernels import Kernel
from sklearn.utils.validation import check_is_fitted

from gpmultirate import misspecification, units
from gpmultirate.closedloop import check_feedback, loop_input
from gpmultirate.exceptions import IdentifiabilityError
from gpmultirate.export import StateSpaceMixin
from gpmultirate.fitting import between_ticks, order as order_steps
from gpmultirate.fitting.between_ticks import (  # noqa: F401 (importable from here too)
    BETWEEN_TICKS,
    EXACT_UP_TO,
    INTERPOLATED_ABOVE,
    INTERPOLATION_TOLERANCE,
)
from gpmultirate.fitting.disturbance import (  # noqa: F401 (importable from here too)
    AUTO_NOISE_DENSE_GATE,
    AUTO_NOISE_GATE,
    AUTO_NOISE_MARGIN,
)
from gpmultirate.fitting.one_order import Fit, fit_at_order
from gpmultirate.fitting.order import (  # noqa: F401 (importable from here too)
    HELD_OUT_MARGIN,
    ORDER_MARGIN,
    RESIDUAL_CORRELATION,
)
from gpmultirate.fitting.prior import prior_in_data_units, record_inputs  # noqa: F401
from gpmultirate.fitting.settings import check_settings
from gpmultirate.inference import GaussianCoefficients, blas_threads_for
from gpmultirate.kernels import check_lags
from gpmultirate.memory import check_fit_memory
from gpmultirate.observations import build_experiment
from gpmultirate.observations.timed import TimedConvolution, on_the_ticks
from gpmultirate.orders import auto_orders  # noqa: F401 (importable from here too)
from gpmultirate.prediction import FIRModelMixin
from gpmultirate.validation import check_sample_time, check_signal

__all__ = ["FIRGaussianProcess", "LeastSquaresFIR"]

#: the name of :class:`~gpmultirate.prediction.FIRModelMixin` before it had a module
_FIRModelMixin = FIRModelMixin


class FIRGaussianProcess(StateSpaceMixin, FIRModelMixin, BaseEstimator):
    """Fast-rate FIR model as a Gaussian process over lag, from slow-rate data.

    The impulse response ``g(t)``, ``t >= 0`` real, has a zero-mean Gaussian
    process prior with covariance ``kernel``; the slow samples
    ``y_slow[m] = sum_{i<P} g(i) u[n_m - i] + e[m]``, ``n_m = offset + m F``
    (or ``sample_indices[m]``), observe it through a
    :class:`~gpmultirate.DownsampledConvolution` (or a
    :class:`~gpmultirate.SampledConvolution`) with white noise of variance
    ``noise_level`` (the ``gamma`` of eq. 15).  The posterior mean at lags
    ``0..P-1`` is the kernel-regularised estimate of eq. (15).

    With several inputs (``u`` of shape ``(N, n_inputs)``) each input has
    its own impulse response ``g_k``; the prior makes them independent, the
    posterior does not.  Several records (lists of ``u`` and ``y_slow``)
    share the hyperparameters and the noise level.

    Parameters
    ----------
    kernel : sklearn Kernel, list of them, or "dc", "tc", "ss", "auto", optional
        Prior covariance over lag; a list gives one kernel per input, and
        one kernel for several inputs is copied for each (each copy tuned
        separately).  Default (``None`` or ``"dc"``):
        ``ConstantKernel(c) * DC(alpha=0.9, beta=0.9)`` per input, with ``c``
        and its bounds set from the data, and ``alpha`` bounded so that the
        prior's envelope ``alpha^(t/2)`` falls at least by ``e^-2`` by lag
        ``P`` (the FIR model's own assumption: the response has died out by
        then).  ``"tc"``, ``"ss"``: TC or SS scaled the same way.  ``"auto"``:
        the DC prior plus up to ``max_resonances`` PK terms whose frequencies
        are found from the data (see :mod:`gpmultirate.resonances`).
    factor : int, default=1
        Downsampling factor ``F`` (ignored when ``sample_indices`` are given).
    order : int, "auto" or sequence of int, optional
        FIR order ``P`` in ``1..N``, shared by all inputs.  Default: chosen
        from the data: for a record of at most 2048 fast samples
        (``orders.SHORT_RECORD``) ``N``, or a shorter order ``N/2 .. N/32``
        that predicts held-out slow samples more than one point better; for
        a longer record, the lag beyond which the prior tuned at a pilot
        order (512, doubled while it has not decayed) is negligible against
        the noise (:func:`~gpmultirate.orders.default_order`; the user
        guide's *Tuning that generalizes*).  An integer is used as given (a
        too short one gets an :class:`~gpmultirate.OrderWarning`).
        ``"auto"`` or a list of candidates: each is fitted and the tuning
        criterion's choice kept (``order_selection_``).
    offset : int, default=0
        Fast index of the first slow sample, ``0..F-1``.
    noise_level : float, default=1.0
        Noise variance ``gamma``; the initial value when it is tuned.
    noise_level_bounds : pair of floats, "fixed" or "auto", default="auto"
        Bounds for tuning ``noise_level``; ``"auto"`` is
        ``(1e-12, 10) * mean(y_slow**2)``.
    optimizer : "marginal_likelihood" or None, default="marginal_likelihood"
        Tune the free hyperparameters and the noise level by maximising the
        log marginal likelihood (Fisher scoring up to 1000 slow samples after
        the reduction of long records, L-BFGS-B above and, above 200
        coefficients, where the evidence goes through DC's precision; see
        the theory page and :mod:`gpmultirate.tuning`); ``None`` uses them
        exactly as given.
    tuning : {"evidence", "cross_validation"}, default="evidence"
        The criterion the hyperparameters (and an ``"auto"`` order)
        maximize: ``"evidence"``, the log marginal likelihood (eq. 19);
        ``"cross_validation"``, the log density of held-out blocks of slow
        samples predicted from the others (K-fold over time, ``cv`` folds;
        see :mod:`gpmultirate.crossvalidation`), which judges the model by
        what it predicts rather than by how well it explains the data.  It
        works in data space: ``O(M^3)`` per evaluation for ``M`` slow
        samples.  After evidence tuning, the held-out fit of the tuned model
        is compared with that of shorter orders (same folds, same
        hyperparameters): with the default order a clearly better shorter
        order replaces ``N``, with an explicit order a warning names it.
        A disturbance model (``noise_kernel``) is tuned by the same
        criterion: under ``"cross_validation"`` each held-out block is
        predicted with the disturbance's correlation across its edges.
    cv : int, default=5
        The number of folds of ``"cross_validation"`` (and of the held-out
        check after evidence tuning): contiguous blocks of slow samples of
        each record.
    exposure : float, default=0.0
        For readings at their own instants (``fit(..., sample_times=t)``):
        each reading is the mean output over the ``exposure`` before its
        instant, in the units of ``sample_time`` (seconds; fast sample
        periods when it is 1) (:doc:`/cameras`).
    latency : float, default=0.0
        For readings at their own instants: the reading stamped ``t`` shows
        the output at ``t - latency`` (in the units of ``sample_time``).
    between_ticks : {"auto", "exact", "interpolated"}, default="auto"
        How readings between the fast ticks are observed: ``"exact"``, as
        linear functionals of the response over continuous lag
        (:class:`~gpmultirate.observations.TimedConvolution`, an ``M x M``
        covariance); ``"interpolated"``, from twelve integer lags
        (:class:`~gpmultirate.observations.InterpolatedConvolution`, the
        ``P x P`` route of long records; ``interpolation_error_`` estimates
        its error).  ``"auto"``: interpolated beyond 1,000 readings and more
        readings than coefficients, refitted exactly (up to 3,000 readings)
        where the estimated error exceeds ``INTERPOLATION_TOLERANCE`` (0.2)
        noise standard deviations (:doc:`/cameras`).
    noise_kernel : "auto", "white", "matern12", "matern32", "ar1" or sklearn Kernel, default="auto"
        The noise of the slow samples.  ``"white"``: ``noise_level * I``.
        ``"matern12"``/``"matern32"``: white noise plus a disturbance
        ``C * Matern(length_scale, nu=1/2 or 3/2)`` over the instants in fast
        samples; ``"ar1"``: ``C * Matern(length_scale, nu=1/2)`` alone (an
        AR(1) process, through its tridiagonal precision on one uniform
        grid).  A kernel: a disturbance over the instants, added to white
        noise unless it holds a ``WhiteKernel``; its variances and their
        bounds are read in normalized units (the output divided by its RMS),
        as ``kernel``'s amplitudes are, its time scales in fast samples.  A
        disturbance is tuned with everything else from the white fit.
        ``"auto"`` keeps white noise unless a fixed disturbance gains
        ``AUTO_NOISE_GATE`` (3) nats at the white fit and the tuned one
        beats white by ``AUTO_NOISE_MARGIN`` (10) nats of evidence (of
        cross-validated log predictive likelihood under
        ``tuning="cross_validation"``); with ``optimizer=None`` it is white.
        ``noise_kernel_`` is in the data's units.  See :doc:`/disturbances`.
    n_restarts_optimizer : int, default=0
        Extra optimizer runs from random points drawn uniformly in the log
        bounds; the best optimum is kept.
    random_state : int, RandomState or None, default=None
        Seed of the restarts.
    initial_conditions : {"zero", "discard", "periodic"}, default="zero"
        ``"zero"``: the system is at rest before the record (the paper's
        case); ``"discard"``: the input before the record is unknown, so
        only slow samples at fast index ``>= order - 1`` are used;
        ``"periodic"``: ``u`` is one period of a periodic input in steady
        state (the regressor is circular).
    sample_time : float, default=1.0
        Fast sample time ``T`` in seconds, used by :meth:`frequency_response`
        (frequencies in Hz), the plots and the exports, and the unit of
        ``sample_times``, ``exposure`` and ``latency`` (seconds).  Left at
        1.0, frequencies are in cycles per sample and times in fast sample
        periods.
    max_resonances : int, default=4
        With ``kernel="auto"``, the most PK terms the search may add.
    normalize : bool, default=True
        When tuning, read the initial values and bounds of ``kernel``'s
        amplitudes, ``noise_level`` and explicit ``noise_level_bounds`` in
        normalized units: input(s) and output divided by their RMS (as
        scikit-learn's ``normalize_y`` does for the output).  The tuned fit
        then does not depend on the units of ``u`` and ``y``: an amplitude of
        1 (``ConstantKernel(1.0)``) is an impulse response of the size the
        data call for, and scikit-learn's default amplitude bounds
        ``(1e-5, 1e5)`` span that scale.  ``kernel_``, ``noise_level_``, the
        posterior, the bands and the evidence are in the data's units.  With
        ``optimizer=None``, or ``normalize=False``, the kernel and noise
        level are used in the data's units exactly as given.

    Attributes
    ----------
    coef_ : ndarray of shape (P,), or (n_inputs, P) for a 2-D ``u``
        Posterior mean of ``g`` at lags ``0..P-1`` (eq. 15).
    n_inputs_ : int
        The number of inputs.
    kernel_ : sklearn Kernel
        The kernel with the tuned hyperparameters.
    noise_level_ : float
        The tuned (or given) white noise variance (the ``WhiteKernel`` part
        of a disturbance model; for a disturbance without one, ``"ar1"``,
        the level of the white-noise fit it started from).
    noise_kernel_ : "white" or sklearn Kernel
        The fitted noise: ``"white"``, or the tuned noise kernel over the
        instants (white part included), such as
        ``WhiteKernel(0.01) + C(0.2) * Matern(40, nu=1.5)``.
    log_marginal_likelihood_value_ : float
        Log evidence of the slow data at ``kernel_`` and ``noise_level_``
        (scikit-learn's sign and constants: higher is better), a density of
        ``y_slow`` in its own units.
    interpolation_error_ : float
        Fits by the interpolated route only: the estimated rms error of the
        interpolated readings of ``coef_``, in standard deviations of the
        white noise (:func:`~gpmultirate.observations.interpolation_error`).
    input_scale_ : ndarray of shape (n_inputs,)
        The power of two each input was divided by for the fit.
    output_scale_ : float
        The power of two ``y_slow`` was divided by for the fit.
    hyperparameter_units_ : {"data", "normalized"}
        The units of ``kernel_``, ``noise_level_`` and
        ``noise_level_bounds_`` (see *Units* in :meth:`fit`).
    observation_ : Observation
        The observation of the training data: a
        :class:`~gpmultirate.DownsampledConvolution` in the paper's case, a
        :class:`~gpmultirate.SampledConvolution` or a stack of records
        otherwise.
    y_slow_ : ndarray of shape (M,)
        The slow samples the model was fitted to (the used ones: finite,
        and late enough for ``"discard"``; records concatenated).
    noise_level_bounds_ : pair of floats or "fixed"
        The bounds of ``noise_level`` used for tuning (``"auto"`` resolved).
    posterior_ : GaussianCoefficients
        The posterior of the coefficients at lags ``0..P-1``.
    optimizer_result_ : scipy.optimize.OptimizeResult or None
        The best optimizer run (``x`` in ``theta`` coordinates, ``fun`` the
        negative log evidence, or the negative cross-validated log
        predictive likelihood), or None when nothing was tuned.
    cv_log_predictive_likelihood_ : float
        With ``tuning="cross_validation"``: the sum over the folds of the
        log density of the held-out slow samples at the tuned values, under
        the chosen noise model (``noise_kernel_``).
    order_selection_ : dict
        With ``order="auto"`` or a list: ``"order"`` (the candidates),
        ``"score"`` (the criterion per used slow sample, higher is better),
        ``"criterion"`` (``"log_evidence"`` or ``"cv_log_predictive"``) and
        ``"best_order"`` (the fitted order).  With the default order, where
        the held-out check ran: the candidates ``N/32, ..., N``, their
        held-out fit in percent (``"criterion"`` ``"held_out_fit"``) and the
        fitted order; where the order was read from the tuned prior (a
        record longer than 2048 samples): the pilot orders, the lag read at
        each (``"score"``), ``"criterion"`` ``"prior_tail"`` and the order.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> import gpmultirate as gm
    >>> from gpmultirate.kernels import DC
    >>> rng = np.random.default_rng(0)
    >>> g = 0.9 ** np.arange(60) * np.cos(0.5 * np.arange(60))
    >>> u = rng.standard_normal(120)
    >>> y_slow = np.convolve(u, g)[:120][::3] + 0.05 * rng.standard_normal(40)
    >>> model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=60).fit(u, y_slow)
    >>> model.coef_.shape
    (60,)
    >>> mean, std = model.impulse_response([0.5, 1.5], return_std=True)
    >>> bool(np.all(std > 0))
    True

    Two inputs, and a slow sample that was not measured:

    >>> u2 = rng.standard_normal((120, 2))
    >>> y2 = (np.convolve(u2[:, 0], g)[:120] + np.convolve(u2[:, 1], -g)[:120])[::3]
    >>> y2 += 1e-2 * rng.standard_normal(40)
    >>> y2[5] = np.nan
    >>> model = gm.FIRGaussianProcess(C(1.0) * DC(), factor=3, order=20).fit(u2, y2)
    >>> model.coef_.shape, model.frequency_response(input=1).magnitude.shape
    ((2, 20), (61,))
    """

    continuous_lags = True

    def __init__(
        self,
        kernel: Kernel | None = None,
        factor: int = 1,
        order: int | None = None,
        offset: int = 0,
        noise_level: float = 1.0,
        noise_level_bounds="auto",
        optimizer: str | None = "marginal_likelihood",
        n_restarts_optimizer: int = 0,
        random_state=None,
        initial_conditions: str = "zero",
        sample_time: float = 1.0,
        max_resonances: int = 4,
        normalize: bool = True,
        tuning: str = "evidence",
        cv: int = 5,
        exposure: float = 0.0,
        latency: float = 0.0,
        between_ticks: str = "auto",
        noise_kernel="auto",
    ):
        self.kernel = kernel
        self.factor = factor
        self.order = order
        self.offset = offset
        self.noise_level = noise_level
        self.noise_level_bounds = noise_level_bounds
        self.optimizer = optimizer
        self.n_restarts_optimizer = n_restarts_optimizer
        self.random_state = random_state
        self.initial_conditions = initial_conditions
        self.sample_time = sample_time
        self.max_resonances = max_resonances
        self.normalize = normalize
        self.tuning = tuning
        self.cv = cv
        self.exposure = exposure
        self.latency = latency
        self.between_ticks = between_ticks
        self.noise_kernel = noise_kernel

    # ------------------------------------------------------------------ fit
    def fit(self, u, y_slow, sample_indices=None, sample_times=None,
            excitation=None) -> "FIRGaussianProcess":
        """Condition the prior on slow data, tuning hyperparameters if asked.

        Parameters
        ----------
        u : array-like of shape (N,) or (N, n_inputs), or a list of them
            Fast-rate input(s); a list holds one record per entry.
        y_slow : array-like of shape (M,), or a list of them
            Slow output, ``y_slow[m] = y[offset + m * factor]`` (then
            ``M = len(range(offset, N, factor))``) or ``y[sample_indices[m]]``;
            ``NaN`` marks a sample that was not measured.
        sample_indices : array-like of int, or a list of them, optional
            The fast-sample index of each slow sample, strictly increasing
            in ``0..N-1``; ``factor`` and ``offset`` are then ignored.
        sample_times : array-like of float, or a list of them, optional
            The stamp of each reading in the units of ``sample_time``
            (seconds; fast sample periods when it is 1): real, strictly
            increasing, in ``[0, N T)``, for readings off the fast ticks,
            with the model's ``exposure`` and ``latency`` (see
            :doc:`/cameras`); exclusive with ``sample_indices``.  Stamps
            that look like the other unit (all in the record's first 5 %
            with more readings than fast periods there, or past its end
            while they would fit it in fast periods) raise a ``ValueError``.
        excitation : array-like of shape (N,), optional
            For closed-loop data: the external signal ``r`` added in the
            loop at the fast rate, independent of the disturbances, with
            ``u`` (one record, one input) the plant input the loop produced.
            The fit then runs on the part of ``u`` that ``r`` explains (the
            two-stage method, :mod:`gpmultirate.closedloop`), kept in
            ``excitation_model_``; ``excitation=u`` is the plain fit.
            Without it, a fit whose input depends on past residuals warns
            with a :class:`~gpmultirate.FeedbackWarning` (:doc:`/closed_loop`).

        Returns
        -------
        self

        Notes
        -----
        Lists: ``u`` and ``y_slow`` are several records only when both are
        lists (or tuples) of arrays; otherwise each is one array-like, as in
        scikit-learn (``u2.tolist()`` is the array ``u2``, and
        ``y[:, None].tolist()`` the column ``y[:, None]``).

        Units: the fit divides each input and the output by exact powers of
        two of their largest magnitude (``gpmultirate.units``), so any
        finite data in ``[1e-300, 1e300]`` fit alike, and a fit of
        ``u * 2**i``, ``y_slow * 2**j`` is the fit of ``u``, ``y_slow`` with
        every result scaled by ``2**(j - i)`` (outputs by ``2**j``) bit for
        bit.  ``input_scale_`` and ``output_scale_`` hold the powers.  All
        results are in the data's units; ``kernel_`` and ``noise_level_`` too
        unless an amplitude or the noise variance is outside the float range
        there (for instance ``u`` of size ``1e-300`` and ``y_slow`` of size
        1, an amplitude near ``1e600``): they then stay in the normalized
        units, ``hyperparameter_units_`` is ``"normalized"`` and a
        :class:`~gpmultirate.NumericalWarning` says so (such a model's file
        stores them in the normalized units with the powers of two, and
        :func:`~gpmultirate.load_model` fits it again in those units; the
        fit report gives the noise in the data's units).  ``optimizer_result_``
        is the optimizer's run on the normalized data.  Data whose largest
        magnitude is subnormal (below ``2.2e-308``), or an input that is zero
        at every sample, are refused with a ``ValueError`` naming them, as
        are units whose coefficients would be beyond the float range (for
        instance ``u * 1e-160`` and ``y_slow * 1e160``, coefficients near
        ``1e320``).
        """
        settings = check_settings(self, getattr(self, "_prior_in_normalized_units", False))
        given_input = u
        u, self.excitation_model_ = loop_input(u, excitation, type(self))
        if sample_times is not None:
            sample_times = units.in_fast_periods(sample_times, settings.sample_time, u)
        sample_indices = between_ticks.readings_of(sample_indices, sample_times,
                                                   settings.exposure, settings.latency, u)
        for name in ("order_selection_", "cv_log_predictive_likelihood_", "resonances_",
                     "interpolation_error_"):
            self.__dict__.pop(name, None)  # made by some fits only: none left from a refit
        # the fit works on the data divided by powers of two (exact), then rescales once
        given = (u, y_slow, sample_indices)
        u, y_slow, scale = units.normalize(u, y_slow)
        data, settings = (u, y_slow, sample_indices), replace(settings, scale=scale)
        self._adopt(*order_steps.fit_checked_order(data, settings, fit_at_order))
        check = between_ticks.check_interpolation(
            self.observation_, self.posterior_.coef, self.noise_level_, settings.between_ticks)
        if check is not None and check.refit:  # the readings again, exactly
            settings = replace(settings, between_ticks="exact")
            self._adopt(*order_steps.fit_checked_order(data, settings, fit_at_order))
        elif check is not None:
            self.interpolation_error_ = check.error
        # the innovations in the fit's own units, before the rescaling; a fit with the
        # user's hyperparameters (no tuning, as a model file is read) is not judged
        specified = misspecification.check_fit(
            self.observation_, self.y_slow_, self._evidence.kernel, self.noise_level_,
            self._noise_model, self.noise_level_bounds_,
            posterior=self.posterior_) if settings.tuned else None
        units.rescale_gaussian_process(self, scale, lambda: between_ticks.experiment_of(
            given, self.observation_.order, settings))
        if self.excitation_model_ is None:
            check_feedback(self, given_input, given[1], given[2], sample_times)
        self.misspecification_ = misspecification.check_misspecification(
            self, specified, given_input, given[1], given[2], sample_times)
        return self

    def _adopt(self, fitted: Fit, order_selection=None) -> None:
        """Take the learned state of a fit, and the table of its order's choice, as ours."""
        for name, value in fitted.attributes().items():
            if value is None and name in ("resonances_", "cv_log_predictive_likelihood_"):
                self.__dict__.pop(name, None)  # made by some fits only
            else:
                setattr(self, name, value)
        if order_selection is not None:
            self.order_selection_ = order_selection

    # ------------------------------------------------------------ evidence
    def log_marginal_likelihood(self, theta=None, eval_gradient: bool = False):
        """Log marginal likelihood of the training data (eq. 19, corrected).

        Parameters
        ----------
        theta : array-like, optional
            Hyperparameters in tuning coordinates: ``kernel_.theta`` (the
            log of each free value, ``artanh`` of DC's ``beta``) followed by
            ``log(noise_level)`` unless the noise level is fixed (with a
            disturbance model: the noise kernel's ``theta``).  By default
            the fitted value is returned.
        eval_gradient : bool, default=False
            Also return the gradient with respect to ``theta``.

        Returns
        -------
        float, or (float, ndarray) with ``eval_gradient``
        """
        check_is_fitted(self, "coef_")
        if theta is None:
            if eval_gradient:
                raise ValueError("eval_gradient requires theta")
            return self.log_marginal_likelihood_value_
        theta = check_signal(theta, "theta", min_length=0)
        evidence = self._evidence
        n_expected = evidence.theta.shape[0]
        if theta.shape[0] != n_expected:
            raise ValueError(f"theta must have {n_expected} entries; got {theta.shape[0]}")
        theta, shift = units.evidence_theta(self, theta)
        if eval_gradient:
            value, gradient = evidence(theta, eval_gradient=True)
            return value + shift, gradient
        return evidence(theta) + shift

    # ----------------------------------------------------------- posterior
    def impulse_response(self, lags=None, return_std: bool = False, return_cov: bool = False):
        """Posterior of the impulse response ``g(t)`` at real lags ``t >= 0``.

        Non-integer lags use the kernel on continuous lag (the Gaussian
        process / RKHS view of the estimate).

        Parameters
        ----------
        lags : array-like of shape (n,), optional
            Lags in fast samples; default ``0..P-1``.
        return_std : bool, default=False
            Also return the posterior standard deviation.
        return_cov : bool, default=False
            Also return the posterior covariance (exclusive with ``return_std``).

        Returns
        -------
        mean : ndarray of shape (n,), or (n_inputs, n) for several inputs
        std : ndarray of the shape of ``mean``, only with ``return_std``
        cov : ndarray of shape (n, n), only with ``return_cov``; for several
            inputs ``(n_inputs * n, n_inputs * n)``, of the input-major
            flattened ``mean``
        """
        check_is_fitted(self, "coef_")
        if return_std and return_cov:
            raise ValueError("return_std and return_cov cannot both be True")
        return self._scaled_impulse_response(lags, return_std, return_cov)

    def _impulse_response_normalized(self, lags, kind):
        """Flat mean, variance (``kind="std"``) or covariance (``"cov"``) or None, and the
        exponents that carry them into the data's units (None: already there)."""
        check_is_fitted(self, "coef_")
        X = self._points(lags)
        posterior, scale = units.split(self.posterior_)
        exponents = None
        if scale is not None:
            gains = scale.gain_exponents
            exponents = gains[X[:, 0].astype(int)] if self.n_inputs_ > 1 else np.full(
                X.shape[0], int(gains[0]))
        if kind is None:
            return posterior.mean_at_lags(X), None, exponents
        mean, second = posterior.at_lags(X, full_cov=kind == "cov")
        return mean, second, exponents

    def _predict_readings(self, x, sample_times, return_std):
        """The sensor's readings at ``sample_times`` (exposure and latency applied).

        As the fitted observation models them (its ``readings_model``)."""

        exposure = units.duration_in_fast_periods(self.exposure, self.sample_time)
        latency = units.duration_in_fast_periods(self.latency, self.sample_time)
        ticks = None if return_std or self.initial_conditions == "discard" else on_the_ticks(
            sample_times, exposure, latency)
        if ticks is not None and (ticks.size == 0 or ticks.min() < 0 or ticks.max() >= x.shape[0]):
            ticks = None

        def readings_at(x, posterior, scale):
            if ticks is not None:
                # readings on the ticks without exposure are fast samples of the output: its
                # mean there, without the readings' joint with the data (the residuals of
                # a camera log on the ticks: 4.1 s at order 3,998, 2,000 readings)
                return self._predict_normalized(x, posterior, False)[ticks]
            readings = TimedConvolution(
                x, sample_times, self._order, exposure, latency, self.initial_conditions)
            kernel = self._evidence.kernel  # what the posterior conditioned with
            readings = self.observation_.readings_model(readings)
            with blas_threads_for(readings):
                mean, var = readings.posterior_readings(posterior, self._evidence.data, kernel)
            return (mean, np.sqrt(var)) if return_std else mean

        return self._in_data_units(x, readings_at, return_std)

    def _points(self, lags) -> np.ndarray:
        """The kernel inputs of the lags: a column, or ``(input, lag)`` pairs input-major."""
        lags = np.arange(self._order, dtype=float) if lags is None else check_lags(lags, "lags")
        if self.n_inputs_ == 1:
            return lags[:, None]
        inputs = np.repeat(np.arange(self.n_inputs_, dtype=float), lags.shape[0])
        return np.column_stack([inputs, np.tile(lags, self.n_inputs_)])


class LeastSquaresFIR(StateSpaceMixin, FIRModelMixin, BaseEstimator):
    """Least-squares FIR model from slow-rate data (paper eq. 11).

    The estimate is unique only when the order is below the number of slow
    samples (Lemma 1) and the regressor has full column rank, which fails
    for instance for zero-order-hold inputs (Lemma 2); otherwise ``fit``
    raises :class:`~gpmultirate.IdentifiabilityError`.

    Parameters
    ----------
    factor : int, default=1
        Downsampling factor ``F`` (ignored when ``sample_indices`` are given).
    order : int
        FIR order ``P``; ``n_inputs * P`` must be below the number of used
        slow samples ``M``.
    offset : int, default=0
        Fast index of the first slow sample, ``0..F-1``.
    initial_conditions : {"zero", "discard", "periodic"}, default="zero"
        As for :class:`FIRGaussianProcess`.
    sample_time : float, default=1.0
        Fast sample time in seconds, as for :class:`FIRGaussianProcess`.

    Attributes
    ----------
    coef_ : ndarray of shape (P,), or (n_inputs, P) for a 2-D ``u``
    n_inputs_ : int
    noise_variance_ : float
        Residual variance ``||y - Phi g||^2 / (M - P)`` (NaN when ``M = P + 0``).
    coef_covariance_ : ndarray of shape (n_inputs * P, n_inputs * P)
        ``noise_variance_ (Phi^T Phi)^{-1}``, used for the bands of
        :meth:`predict` and :meth:`frequency_response`.
    observation_ : Observation
    posterior_ : GaussianCoefficients
        The Gaussian distribution ``N(coef_, coef_covariance_)``.

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate import LeastSquaresFIR
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> g = 0.5 ** np.arange(10)
    >>> y_slow = np.convolve(u, g)[:300][::3]
    >>> LeastSquaresFIR(factor=3, order=10).fit(u, y_slow).coef_[:3].round(6)
    array([1.  , 0.5 , 0.25])
    """

    def __init__(self, factor: int = 1, order: int | None = None, offset: int = 0,
                 initial_conditions: str = "zero", sample_time: float = 1.0):
        self.factor = factor
        self.order = order
        self.offset = offset
        self.initial_conditions = initial_conditions
        self.sample_time = sample_time

    def fit(self, u, y_slow, sample_indices=None, sample_times=None) -> "LeastSquaresFIR":
        """Solve the least-squares problem of eq. (10)-(11).

        Parameters
        ----------
        u : array-like of shape (N,) or (N, n_inputs), or a list of them
        y_slow : array-like of shape (M,), or a list of them
            ``NaN`` marks a sample that was not measured.
        sample_indices : array-like of int, or a list of them, optional
            As for :meth:`FIRGaussianProcess.fit`.
        sample_times : array-like, or a list of them, optional
            In the units of ``sample_time`` (seconds; fast sample periods
            when it is 1), only on the fast ticks: least squares has no
            model between the integer lags; exclusive with ``sample_indices``.

        Returns
        -------
        self

        Notes
        -----
        Lists and units as for :meth:`FIRGaussianProcess.fit`: records only
        when ``u`` and ``y_slow`` both are lists of arrays, and the data
        divided by exact powers of two before the least-squares problem is
        formed.  ``noise_variance_`` and ``coef_covariance_`` are ``inf``
        where they exceed the float range in the data's units; the standard
        deviations of :meth:`impulse_response` and :meth:`predict` are formed
        before scaling and stay finite.

        Raises
        ------
        IdentifiabilityError
            If ``n_inputs * order >= M`` (the used slow samples) or the
            regressor is rank deficient.
        """
        if sample_times is not None:
            if sample_indices is not None:
                raise ValueError("give sample_indices or sample_times, not both")
            sample_indices = on_the_ticks(units.in_fast_periods(
                sample_times, check_sample_time(self.sample_time), u), 0.0, 0.0)
            if sample_indices is None:
                raise ValueError(
                    "LeastSquaresFIR has no model between the integer lags: sample_times must "
                    "be on the fast ticks (integers); use FIRGaussianProcess for readings "
                    "between them"
                )
        if self.order is None:
            raise ValueError("order must be given: an integer below the number of slow samples")
        check_sample_time(self.sample_time)
        data_u, data_y = u, y_slow
        u, y_slow, scale = units.normalize(u, y_slow)  # exact powers of two, rescaled below
        experiment = build_experiment(
            u, y_slow, sample_indices, factor=self.factor, offset=self.offset,
            order=self.order, initial_conditions=self.initial_conditions,
        )
        observation, y = experiment.observation, experiment.y
        M, P = observation.n_outputs, observation.n_coefficients
        check_fit_memory(M, P, 0, n_inputs=observation.n_inputs)
        if P >= M:
            inputs = f" x {observation.n_inputs} inputs" if observation.n_inputs > 1 else ""
            raise IdentifiabilityError(
                f"order={observation.order}{inputs} is not below the number of used slow samples "
                f"M={M}: the least-squares FIR estimate is not unique (Lemma 1). Use a lower "
                "order, more data, or FIRGaussianProcess, whose prior makes any order unique."
            )
        U, s, Vt = linalg.svd(observation.matrix, full_matrices=False, check_finite=False)
        tolerance = max(M, P) * np.finfo(float).eps * (s[0] if s.size else 0.0)
        rank = int(np.sum(s > tolerance))
        if rank < P:
            hold = any(
                _is_zero_order_hold(x[:, k], observation.slow_factor)
                for x in record_inputs(experiment) for k in range(x.shape[1])
            )
            hint = (
                "The input is constant between slow samples (zero-order hold, Lemma 2): "
                "excite the system at the fast rate. " if hold else ""
            )
            raise IdentifiabilityError(
                f"the regressor has rank {rank} < {P} coefficients, so the least-squares FIR "
                f"estimate is not unique. {hint}Use a fast-rate (e.g. multisine or random) "
                "input, a lower order, or FIRGaussianProcess."
            )
        coef = Vt.T @ ((U.T @ y) / s)
        residual = y - observation.matrix @ coef
        noise_variance = float(residual @ residual / (M - P))
        root = Vt.T / s  # coef covariance = noise_variance * root @ root.T
        self.observation_ = observation
        self.n_inputs_ = experiment.n_inputs
        self.coef_ = self._shaped(coef)
        self.noise_variance_ = noise_variance
        self.coef_covariance_ = noise_variance * (root @ root.T)
        self.posterior_ = GaussianCoefficients(coef, self.coef_covariance_, np.zeros((0, P)))
        units.rescale_least_squares(self, scale, lambda: build_experiment(
            data_u, data_y, sample_indices, factor=self.factor, offset=self.offset,
            order=self.order, initial_conditions=self.initial_conditions,
        ))
        return self

    def impulse_response(self, lags=None, return_std: bool = False, return_cov: bool = False):
        """The estimate at integer lags, with its standard deviation or covariance.

        Least squares estimates the coefficients only: ``lags`` must be
        integers in ``0..P-1``.  The covariance is :attr:`coef_covariance_`.

        Parameters
        ----------
        lags : array-like of int, optional
            Lags in ``0..P-1``; default all of them.
        return_std, return_cov : bool, default=False
            Also return the standard deviation or the covariance.

        Returns
        -------
        mean : ndarray of shape (n,), or (n_inputs, n) for several inputs
        std : ndarray of the shape of ``mean``, only with ``return_std``
        cov : ndarray, only with ``return_cov`` (input-major for several inputs)
        """
        check_is_fitted(self, "coef_")
        if return_std and return_cov:
            raise ValueError("return_std and return_cov cannot both be True")
        return self._scaled_impulse_response(lags, return_std, return_cov)

    def _impulse_response_normalized(self, lags, kind):
        """Flat mean, variance or covariance (as ``kind``), and the exponents to the data's units."""
        check_is_fitted(self, "coef_")
        order = self._order
        if lags is None:
            index = np.arange(order)
        else:
            lags = check_signal(lags, "lags")
            index = np.round(lags).astype(int)
            if np.any(np.abs(lags - index) > 1e-9) or np.any(index < 0) or np.any(index >= order):
                raise ValueError(
                    f"lags must be integers in 0..{order - 1} for a least-squares FIR model"
                )
        # the input-major positions of the lags of every input
        index = (np.arange(self.n_inputs_)[:, None] * order + index[None, :]).reshape(-1)
        posterior, scale = units.split(self.posterior_)
        exponents = None if scale is None else scale.coefficient_exponents(order)[index]
        covariance = self.coef_covariance_ if scale is None else posterior.K
        mean = posterior.coef[index]
        if kind is None:
            return mean, None, exponents
        cov = covariance[np.ix_(index, index)]
        if kind == "cov":
            return mean, cov, exponents
        return mean, np.maximum(np.diag(cov), 0.0), exponents


def _is_zero_order_hold(u: np.ndarray, factor: int) -> bool:
    """True when ``u`` is held constant on every block of ``factor`` samples, for some
    alignment, at values that change between blocks."""
    if factor < 2 or u.shape[0] < 2 * factor:
        return False
    for shift in range(factor):
        head = u[shift:]
        n_blocks = head.shape[0] // factor
        blocks = head[: n_blocks * factor].reshape(n_blocks, factor)
        # held values that change from block to block: an input that is zero (or constant)
        # after a few samples, such as an impulse, is not zero-order hold
        if np.allclose(blocks, blocks[:, :1], rtol=1e-12, atol=1e-14 * np.max(np.abs(u))) and (
                np.ptp(blocks[:, 0]) > 1e-14 * np.max(np.abs(u))):
            return True
    return False
