"""Many outputs: one FIR model per measured output, fitted in parallel.

A structure measured at many points gives one slow output per sensor for the
same fast-rate input(s).  :class:`MultiOutputFIR` fits one copy
(:func:`sklearn.base.clone`) of a single-output estimator per column of
``y_slow``; each output gets its own hyperparameters, noise level and
posterior.  The fits run through :class:`joblib.Parallel`, so any joblib
backend runs them: processes (loky, the default), or a Dask cluster under
``joblib.parallel_config(backend="dask")``.
"""

from __future__ import annotations


import joblib
import numpy as np
from sklearn.base import BaseEstimator, clone
from sklearn.utils.validation import check_is_fitted
from gpmultirate.inference import one_blas_thread
from gpmultirate.observations.experiment import is_record_list
from gpmultirate.responses import FrequencyResponse
from gpmultirate.validation import as_real_array, check_int, check_n_jobs

__all__ = ["MultiOutputFIR", "stacked_coefficients"]


def stacked_coefficients(coefs) -> np.ndarray:
    """The outputs' coefficients on a common lag axis, zero beyond each one's order.

    Examples
    --------
    >>> stacked_coefficients([np.array([1.0, 2.0, 3.0]), np.array([4.0])])
    array([[1., 2., 3.],
           [4., 0., 0.]])
    """
    longest = max(c.shape[-1] for c in coefs)
    stacked = np.zeros((len(coefs), *coefs[0].shape[:-1], longest))
    for j, c in enumerate(coefs):
        stacked[j, ..., : c.shape[-1]] = c
    return stacked


class MultiOutputFIR(BaseEstimator):
    """One FIR model per output column of the slow data, fitted in parallel.

    ``fit(u, y_slow)`` with ``y_slow`` of shape ``(M, n_outputs)`` fits a
    clone of ``estimator`` to ``(u, y_slow[:, j])`` for every output ``j``:
    the model of output ``j`` is exactly the model a single estimator with
    the same parameters fits to that column alone (the same coefficients,
    hyperparameters and predictions, whatever ``n_jobs``).  The outputs
    share the input(s) and the sampling instants; a ``NaN`` marks a sample
    that was not measured for that output only.

    Parameters
    ----------
    estimator : FIRGaussianProcess or LeastSquaresFIR
        The unfitted single-output estimator whose parameters every output
        uses.  It is cloned, never fitted itself.
    n_jobs : int or None, default=None
        Outputs fitted at once, as in :class:`joblib.Parallel`: ``None`` is
        one unless a :func:`joblib.parallel_config` context says otherwise,
        ``-1`` uses every CPU.  Under
        ``joblib.parallel_config(backend="dask")`` the fits run on the Dask
        cluster of the active ``distributed.Client``.

    Attributes
    ----------
    estimators_ : list of estimators
        The fitted model of each output, in the order of the columns.
    n_outputs_ : int
    n_inputs_ : int
    coef_ : ndarray of shape (n_outputs, P), or (n_outputs, n_inputs, P)
        The estimators' ``coef_`` stacked along a first axis.  Where the
        outputs' orders differ (the default order may be cut per output by
        the held-out check), ``P`` is the longest and the shorter responses
        are padded with zeros: an FIR model of order ``P_j`` has no
        coefficient at lags ``P_j`` and beyond.

    Notes
    -----
    The parallelism is over outputs: every fit runs with one BLAS thread
    (as the fits of :func:`~gpmultirate.study.run_paper_study` do), serially
    as in parallel.  So ``n_jobs`` processes do not compete for the cores
    with BLAS threads of their own, and the result does not depend on
    ``n_jobs`` or on the backend, bit for bit.  Use ``n_jobs`` to use
    several cores.  A single estimator fitted alone follows its own rule
    (:func:`~gpmultirate.inference.blas_threads_for`: one thread for small
    problems, the BLAS default for large ones), so for large problems it
    can differ from the model of its output here in the last bits.

    Examples
    --------
    >>> import numpy as np
    >>> import gpmultirate as gm
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(240)
    >>> lags = np.arange(40)
    >>> g = np.column_stack([0.8**lags, -0.6**lags, 0.9**lags * np.cos(0.7 * lags)])
    >>> y = np.column_stack([np.convolve(u, g[:, j])[:240] for j in range(3)])
    >>> y_slow = y[::3] + 1e-3 * rng.standard_normal((80, 3))
    >>> y_slow[7, 1] = np.nan  # not measured at output 1 only
    >>> model = gm.MultiOutputFIR(gm.FIRGaussianProcess(factor=3, order=40))
    >>> model = model.fit(u, y_slow)
    >>> model.n_outputs_, model.coef_.shape, model.predict(u).shape
    (3, (3, 40), (240, 3))
    >>> model.frequency_response(output=2).magnitude.shape
    (121,)

    Each output is the single estimator fitted to its column:

    >>> alone = gm.FIRGaussianProcess(factor=3, order=40).fit(u, y_slow[:, 2])
    >>> bool(np.array_equal(alone.coef_, model.coef_[2]))
    True
    """

    def __init__(self, estimator, n_jobs: int | None = None):
        self.estimator = estimator
        self.n_jobs = n_jobs

    def fit(self, u, y_slow, sample_indices=None, sample_times=None) -> "MultiOutputFIR":
        """Fit one clone of the estimator per output column of ``y_slow``.

        Parameters
        ----------
        u : array-like of shape (N,) or (N, n_inputs), or a list of them
            Fast-rate input(s), shared by every output; a list holds one
            record per entry.
        y_slow : array-like of shape (M, n_outputs), or a list of them
            Slow output, one column per output (one such array per record);
            ``NaN`` marks a sample that was not measured at that output.
        sample_indices : array-like of int, or a list of them, optional
            The fast-sample index of each row of ``y_slow``, as for the
            estimator's ``fit``; shared by every output.
        sample_times : array-like of float, or a list of them, optional
            The instant of each row of ``y_slow`` in the units of the
            estimator's ``sample_time`` (readings at their own instants, with
            its exposure and latency), as for the estimator's ``fit``; shared
            by every output.

        Returns
        -------
        self

        Raises
        ------
        ValueError
            If ``y_slow`` is not 2-D (a 1-D ``y_slow`` is one output: fit
            the estimator itself, or pass ``y_slow[:, None]``), if
            ``estimator`` is not an estimator or ``n_jobs`` is invalid; and
            whatever the estimator raises for an output's data (the error
            notes which output).
        """
        estimator = self._check_estimator()
        n_jobs = check_n_jobs(self.n_jobs)
        columns = _output_columns(y_slow, several_records=is_record_list(u))
        tasks = (
            joblib.delayed(_fit_output)(clone(estimator), u, y_j, sample_indices, j,
                                        sample_times)
            for j, y_j in enumerate(columns)
        )
        self.estimators_ = list(joblib.Parallel(n_jobs=n_jobs)(tasks))
        self.n_outputs_ = len(self.estimators_)
        self.n_inputs_ = int(self.estimators_[0].n_inputs_)
        self.coef_ = stacked_coefficients([e.coef_ for e in self.estimators_])
        return self

    def _check_estimator(self):
        estimator = self.estimator
        if not all(hasattr(estimator, name) for name in ("fit", "predict", "get_params")):
            raise ValueError(
                "estimator must be an unfitted FIRGaussianProcess or LeastSquaresFIR (an "
                f"estimator with fit, predict and get_params); got {estimator!r}"
            )
        if isinstance(estimator, type):
            raise ValueError(
                f"estimator must be an estimator instance, not the class {estimator.__name__}"
            )
        return estimator

    def _output(self, output) -> int:
        if output is None:
            if self.n_outputs_ > 1:
                raise ValueError(
                    f"output must be given for a model of {self.n_outputs_} outputs "
                    f"(0..{self.n_outputs_ - 1})"
                )
            return 0
        return check_int(output, "output", low=0, high=self.n_outputs_ - 1)

    def predict(self, u, return_std: bool = False, sample_times=None,
                include_noise: bool = False):
        """Fast-rate output of every output's model for input ``u``.

        Parameters
        ----------
        u : array-like of shape (n,) or (n, n_inputs), or a list of them
            Fast-rate input, shaped as in ``fit``; a list gives a list.
        return_std : bool, default=False
            Also return the posterior standard deviation of each output (see
            the estimator's ``predict``).
        sample_times : array-like of float, or a list of them, optional
            Predict each output's readings at these instants (in the units
            of the estimator's ``sample_time``) instead of the fast samples, as the estimator's
            ``predict`` does; ``n`` is then their number.
        include_noise : bool, default=False
            With ``return_std``, the standard deviation of a new measurement
            of each output (its fitted noise included), as the estimator's
            ``predict`` gives it.

        Returns
        -------
        y : ndarray of shape (n, n_outputs)
        std : ndarray of shape (n, n_outputs), only if ``return_std``
        """
        check_is_fitted(self, "estimators_")
        if is_record_list(u):
            if sample_times is None:
                return [self.predict(u_r, return_std, None, include_noise) for u_r in u]
            if not is_record_list(sample_times) or len(sample_times) != len(u):
                raise ValueError("sample_times must be a list with one entry per record of u")
            return [self.predict(u_r, return_std, t, include_noise)
                    for u_r, t in zip(u, sample_times)]
        extra = {} if sample_times is None else {"sample_times": sample_times}
        if include_noise:
            extra["include_noise"] = True
        answers = [e.predict(u, return_std=return_std, **extra) for e in self.estimators_]
        if return_std:
            return (np.column_stack([a[0] for a in answers]),
                    np.column_stack([a[1] for a in answers]))
        return np.column_stack(answers)

    def frequency_response(self, freqs=None, sample_time: float | None = None,
                           level: float = 0.95, input=None, *,
                           output: int | None = None) -> FrequencyResponse:
        """FRF from ``input`` to ``output`` with its credible band.

        Parameters
        ----------
        freqs, sample_time, level, input
            As for the estimator's ``frequency_response``.
        output : int, optional
            The output, ``0..n_outputs-1``; needed for several outputs.

        Returns
        -------
        FrequencyResponse
        """
        check_is_fitted(self, "estimators_")
        j = self._output(output)
        return self.estimators_[j].frequency_response(freqs, sample_time, level, input)

    def impulse_response(self, lags=None, return_std: bool = False, return_cov: bool = False,
                         *, output: int | None = None):
        """Impulse response of the model of ``output`` (see the estimator's method).

        Parameters
        ----------
        lags, return_std, return_cov
            As for the estimator's ``impulse_response``.
        output : int, optional
            The output, ``0..n_outputs-1``; needed for several outputs.

        Returns
        -------
        mean : ndarray
        std or cov : ndarray, only with ``return_std`` or ``return_cov``
        """
        check_is_fitted(self, "estimators_")
        j = self._output(output)
        return self.estimators_[j].impulse_response(lags, return_std, return_cov)


def _fit_output(estimator, u, y_slow, sample_indices, output: int, sample_times=None):
    """Fit ``estimator`` to one output (a task of :meth:`MultiOutputFIR.fit`).

    One BLAS thread: the parallelism is over outputs, and the result must
    not depend on how many fits run at once.
    """
    try:
        with one_blas_thread():
            if sample_times is None:
                return estimator.fit(u, y_slow, sample_indices=sample_indices)
            return estimator.fit(u, y_slow, sample_indices=sample_indices,
                                 sample_times=sample_times)
    except Exception as exc:
        if hasattr(exc, "add_note"):  # Python >= 3.11
            exc.add_note(f"while fitting output {output} (column {output} of y_slow)")
        raise


def _output_columns(y_slow, several_records: bool) -> list:
    """The slow data of each output: a column, or a list of columns (one per record).

    ``y_slow`` holds records when ``u`` does (a nested list of numbers is
    then a list of records, not one 2-D array).
    """
    if several_records and is_record_list(y_slow):
        records = [_output_matrix(y_r, f"y_slow[{r}]") for r, y_r in enumerate(y_slow)]
        n_outputs = records[0].shape[1]
        for r, y_r in enumerate(records):
            if y_r.shape[1] != n_outputs:
                raise ValueError(
                    f"y_slow[{r}] has {y_r.shape[1]} outputs; y_slow[0] has {n_outputs}: "
                    "every record needs the same outputs"
                )
        _check_measured(np.vstack(records), "y_slow")
        return [[np.ascontiguousarray(y_r[:, j]) for y_r in records] for j in range(n_outputs)]
    y = _output_matrix(y_slow, "y_slow")
    _check_measured(y, "y_slow")
    return [np.ascontiguousarray(y[:, j]) for j in range(y.shape[1])]


def _check_measured(y: np.ndarray, name: str) -> None:
    """Refuse an output column with no finite sample, naming it."""
    empty = np.flatnonzero(~np.isfinite(y).any(axis=0))
    if empty.size:
        which = ", ".join(str(j) for j in empty[:10]) + (", ..." if empty.size > 10 else "")
        raise ValueError(
            f"{name} has no finite sample in column {which} (output {which}): nothing was "
            "measured at that output; drop the column or give its samples"
        )


def _output_matrix(y, name: str) -> np.ndarray:
    y = as_real_array(y, name)
    if y.ndim == 1:
        raise ValueError(
            f"{name} must be 2-D of shape (M, n_outputs), one column per output; got a 1-D "
            "array, which is one output: fit the estimator itself, or pass y_slow[:, None]"
        )
    if y.ndim != 2 or y.shape[0] == 0 or y.shape[1] == 0:
        raise ValueError(
            f"{name} must be 2-D of shape (M, n_outputs) with M, n_outputs >= 1; "
            f"got shape {y.shape}"
        )
    return y
