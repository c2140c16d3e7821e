"""Identified models as discrete-time systems for control design.

:class:`StateSpaceMixin` gives the FIR estimators four exports of the
posterior-mean impulse response at the fast sample time ``T``
(the estimator's ``sample_time``):

* :meth:`~StateSpaceMixin.to_dlti`: the FIR itself as a
  ``scipy.signal.dlti`` transfer function, one per input;
* :meth:`~StateSpaceMixin.to_state_space`: a low-order
  ``scipy.signal.StateSpace``, the balanced truncation of the FIR
  (:func:`gpmultirate.realization.era`), one model for all inputs;
* :meth:`~StateSpaceMixin.sample_state_spaces`: the same reduction of
  posterior draws of the impulse response, for a band on the reduced model;
* :meth:`~StateSpaceMixin.to_control`: the reduced model as a
  ``control.StateSpace`` of python-control.

:func:`frequency_response_to_control` turns a
:class:`~gpmultirate.responses.FrequencyResponse` into a
``control.FrequencyResponseData``.  python-control is an optional
dependency: ``pip install "gpmultirate[control]"``.

The mixin uses only the public attributes of a fitted estimator:
``coef_``, ``n_inputs_``, ``sample_impulse_responses`` and ``sample_time``.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy import signal
from sklearn.utils.validation import check_is_fitted

from gpmultirate.optional import import_control
from gpmultirate.realization import DEFAULT_THRESHOLD, Realization, era, leading_era
from gpmultirate.responses import FrequencyResponse
from gpmultirate.validation import check_int, check_positive

__all__ = ["StateSpaceMixin", "frequency_response_to_control", "import_control"]


def _state_space(realization: Realization, sample_time: float) -> signal.StateSpace:
    r = realization
    return signal.StateSpace(r.A, r.B, r.C, r.D, dt=sample_time)


class StateSpaceMixin:
    """Exports of a fitted FIR estimator as discrete-time systems.

    Mixed into :class:`~gpmultirate.FIRGaussianProcess` and
    :class:`~gpmultirate.LeastSquaresFIR`.  The systems have the sample time
    ``sample_time`` of the estimator (1.0 when it has none) and the
    posterior-mean impulse response ``coef_`` as Markov parameters: the
    FIR ``G_k(z) = sum_i coef_[k, i] z^(-i)`` of input ``k``.

    Attributes
    ----------
    hankel_singular_values_ : ndarray
        Set by :meth:`to_state_space`: the Hankel singular values of the
        posterior-mean FIR (all its inputs together), decreasing.
    state_space_order_ : int
        Set by :meth:`to_state_space`: the order of the reduced model.
    state_space_error_bound_ : float
        Set by :meth:`to_state_space`: the bound of the difference between
        the FRFs of the reduced model and of the FIR
        (:attr:`gpmultirate.realization.Realization.error_bound`).
    """

    def _sample_time(self) -> float:
        return check_positive(getattr(self, "sample_time", 1.0), "sample_time")

    def _markov(self, coef: np.ndarray) -> np.ndarray:
        """Impulse responses ``(n_inputs, P)`` or ``(P,)`` as Markov parameters.

        The Markov parameters have shape ``(P, 1, n_inputs)``.
        """
        coef = np.asarray(coef, dtype=float).reshape(self.n_inputs_, -1)
        return coef.T[:, None, :].copy()

    def to_dlti(self):
        """The posterior-mean FIR as a discrete-time transfer function.

        ``G(z) = (g_0 z^(P-1) + g_1 z^(P-2) + ... + g_(P-1)) / z^(P-1)``
        with ``dt = sample_time``: its impulse response is ``coef_`` (a
        numerator coefficient below ``1e-14`` in front is taken as zero by
        ``scipy.signal``).

        Returns
        -------
        scipy.signal.dlti
            A ``TransferFunction`` for one input; a list of them, one per
            input, for several.

        Examples
        --------
        >>> import numpy as np
        >>> from scipy import signal
        >>> from gpmultirate import LeastSquaresFIR
        >>> rng = np.random.default_rng(0)
        >>> u = rng.standard_normal(300)
        >>> y_slow = np.convolve(u, [0.0, 1.0, 0.5, 0.25])[:300][::3]
        >>> model = LeastSquaresFIR(factor=3, order=4, sample_time=0.1).fit(u, y_slow)
        >>> system = model.to_dlti()
        >>> system.dt
        0.1
        >>> np.round(signal.dimpulse(system, n=5)[1][0].ravel(), 6)
        array([0.  , 1.  , 0.5 , 0.25, 0.  ])
        """
        check_is_fitted(self, "coef_")
        dt = self._sample_time()
        coef = np.asarray(self.coef_, dtype=float).reshape(self.n_inputs_, -1)
        den = np.zeros(coef.shape[1])
        den[0] = 1.0
        systems = []
        for g in coef:
            with warnings.catch_warnings():
                # scipy drops leading numerator coefficients below 1e-14 and says so
                warnings.simplefilter("ignore", signal.BadCoefficients)
                systems.append(signal.dlti(g.copy(), den.copy(), dt=dt))
        return systems[0] if self.n_inputs_ == 1 else systems

    def to_state_space(self, n_states: int | None = None, *,
                       threshold: float = DEFAULT_THRESHOLD) -> signal.StateSpace:
        """A low-order state-space model of the posterior-mean FIR.

        The balanced truncation of the FIR, realized from the Hankel matrix
        of its impulse response (:func:`gpmultirate.realization.era`); for
        several inputs one model with ``n_inputs`` inputs.  Its frequency
        response is within ``2 * sum(hankel_singular_values_[n_states:])``
        of the FIR's at every frequency (for a long FIR the leading values
        only are found: then within :attr:`state_space_error_bound_`).

        Sets :attr:`hankel_singular_values_`, :attr:`state_space_order_` and
        :attr:`state_space_error_bound_`.

        Parameters
        ----------
        n_states : int, optional
            Number of states, from 1 to the rank of the Hankel matrix (at
            most ``P - 1``).  By default the order at the largest drop of
            the Hankel singular values above ``threshold`` times the largest
            (:func:`gpmultirate.realization.select_order`).
        threshold : float, default=1e-3
            Used only when ``n_states`` is None.

        Returns
        -------
        scipy.signal.StateSpace
            Discrete-time, ``dt = sample_time``.

        Raises
        ------
        ValueError
            If ``n_states`` is out of range, or the impulse response is zero
            after lag 0.

        Examples
        --------
        >>> import numpy as np
        >>> from gpmultirate import LeastSquaresFIR
        >>> rng = np.random.default_rng(0)
        >>> u = rng.standard_normal(400)
        >>> g = 0.8 ** np.arange(30) - 0.5 ** np.arange(30)  # second order
        >>> model = LeastSquaresFIR(factor=2, order=30).fit(u, np.convolve(u, g)[:400][::2])
        >>> system = model.to_state_space()
        >>> model.state_space_order_, system.A.shape
        (2, (2, 2))
        >>> np.round(np.sort(np.linalg.eigvals(system.A).real), 2)  # the FIR ends at lag 29
        array([0.5, 0.8])
        """
        check_is_fitted(self, "coef_")
        dt = self._sample_time()
        realization = era(self._markov(self.coef_), n_states, threshold=threshold)
        self.hankel_singular_values_ = realization.hankel_singular_values
        self.state_space_order_ = realization.n_states
        self.state_space_error_bound_ = realization.error_bound
        return _state_space(realization, dt)

    def sample_state_spaces(self, n_states: int | None = None, n_samples: int = 10,
                            random_state=None) -> list:
        """Reduced models of posterior draws of the impulse response.

        Each draw of :meth:`sample_impulse_responses` at lags ``0..P-1`` is
        reduced as in :meth:`to_state_space`, to the same order
        (:func:`gpmultirate.realization.leading_era`): their frequency
        responses spread as the reduced model's uncertainty.

        Parameters
        ----------
        n_states : int, optional
            Order of every model; by default the order :meth:`to_state_space`
            chooses for the posterior mean.
        n_samples : int, default=10
            Number of draws.
        random_state : int, RandomState or None, default=None
            Seed of the draws.

        Returns
        -------
        list of scipy.signal.StateSpace
            ``n_samples`` discrete-time models, ``dt = sample_time``.

        Examples
        --------
        >>> import numpy as np
        >>> from gpmultirate import FIRGaussianProcess
        >>> rng = np.random.default_rng(0)
        >>> u = rng.standard_normal(120)
        >>> g = 0.8 ** np.arange(40) - 0.5 ** np.arange(40)
        >>> y_slow = np.convolve(u, g)[:120][::2] + 0.01 * rng.standard_normal(60)
        >>> model = FIRGaussianProcess(factor=2, order=40).fit(u, y_slow)
        >>> systems = model.sample_state_spaces(n_states=2, n_samples=3, random_state=0)
        >>> len(systems), systems[0].A.shape
        (3, (2, 2))
        """
        check_is_fitted(self, "coef_")
        n_samples = check_int(n_samples, "n_samples", low=1)
        dt = self._sample_time()
        if n_states is None:
            n_states = era(self._markov(self.coef_)).n_states
        else:
            n_states = check_int(n_states, "n_states", low=1)
        draws = np.asarray(self.sample_impulse_responses(n_samples=n_samples,
                                                         random_state=random_state))
        draws = draws.reshape(self.n_inputs_, -1, n_samples)
        return [_state_space(leading_era(self._markov(draws[:, :, s]), n_states), dt)
                for s in range(n_samples)]

    def to_control(self, n_states: int | None = None, *, threshold: float = DEFAULT_THRESHOLD):
        """The reduced model of :meth:`to_state_space` as a python-control system.

        Parameters
        ----------
        n_states : int, optional
            As for :meth:`to_state_space`.
        threshold : float, default=1e-3
            As for :meth:`to_state_space`.

        Returns
        -------
        control.StateSpace
            Discrete-time, ``dt = sample_time``, inputs named ``u[k]``.

        Raises
        ------
        ImportError
            If python-control is not installed
            (``pip install "gpmultirate[control]"``).

        Examples
        --------
        >>> import numpy as np
        >>> from gpmultirate import LeastSquaresFIR
        >>> rng = np.random.default_rng(0)
        >>> u = rng.standard_normal(400)
        >>> g = 0.8 ** np.arange(30) - 0.5 ** np.arange(30)
        >>> model = LeastSquaresFIR(factor=2, order=30, sample_time=0.01)
        >>> system = model.fit(u, np.convolve(u, g)[:400][::2]).to_control()
        >>> system.nstates, system.dt
        (2, 0.01)
        """
        control = import_control()
        system = self.to_state_space(n_states, threshold=threshold)
        return control.ss(system.A, system.B, system.C, system.D, system.dt)


def frequency_response_to_control(frf):
    """A :class:`~gpmultirate.responses.FrequencyResponse` as python-control frequency data.

    The posterior-mean FRF at the angular frequencies ``2 pi freqs``
    (rad/s), with ``dt = frf.sample_time``; the credible band is not carried.

    Parameters
    ----------
    frf : FrequencyResponse

    Returns
    -------
    control.FrequencyResponseData

    Raises
    ------
    ImportError
        If python-control is not installed
        (``pip install "gpmultirate[control]"``).

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.responses import FrequencyResponse
    >>> frf = FrequencyResponse.from_gaussian(
    ...     np.array([0.5, 1.0]), np.array([1.0 + 0j, 0.5j]), np.full(2, 1e-4),
    ...     np.full(2, 1e-4), np.zeros(2), sample_time=0.1)
    >>> data = frequency_response_to_control(frf)
    >>> data.omega.round(4), data.dt
    (array([3.1416, 6.2832]), 0.1)
    """
    if not isinstance(frf, FrequencyResponse):
        raise ValueError(f"frf must be a FrequencyResponse; got {type(frf).__name__}")
    return frf.to_control()


# ------------------------------------------------------------ state-space files
__all__ += ["load_state_space", "save_state_space"]


def save_state_space(system, file, *, sample_time: float | None = None,
                     overwrite: bool = True) -> None:
    """Write a discrete-time state-space model to an ``.npz`` file.

    The file holds the float arrays ``A``, ``B``, ``C``, ``D`` and the
    sample time ``dt`` (seconds), readable without gpmultirate
    (``numpy.load``) or with :func:`load_state_space`.  A file name is
    written all at once (:func:`gpmultirate.io.write_file`): an
    interruption leaves the earlier file or none.

    Parameters
    ----------
    system : scipy.signal.StateSpace, control.StateSpace or fitted estimator
        A model with matrices ``A``, ``B``, ``C``, ``D`` and a sample time
        ``dt``; an estimator (``FIRGaussianProcess``, ``LeastSquaresFIR``)
        is reduced by its ``to_state_space()``.
    file : str, path-like or binary file object
    sample_time : float, optional
        The sample time when ``system`` carries none: for ``dt=True``
        (default 1) or ``dt=None``.
    overwrite : bool, default True
        Replace an existing file of that name; otherwise
        :class:`FileExistsError`.

    Raises
    ------
    ValueError
        If ``system`` is not a discrete-time state-space model with finite
        matrices of matching shapes, or the sample time is not positive.

    Examples
    --------
    >>> import io
    >>> import numpy as np
    >>> from scipy import signal
    >>> from gpmultirate.export import load_state_space, save_state_space
    >>> system = signal.StateSpace([[0.5]], [[1.0]], [[2.0]], [[0.0]], dt=0.1)
    >>> buffer = io.BytesIO()
    >>> save_state_space(system, buffer)
    >>> loaded = load_state_space(io.BytesIO(buffer.getvalue()))
    >>> loaded.A, loaded.dt
    (array([[0.5]]), 0.1)
    """
    import io
    import os

    from gpmultirate.io import write_file

    if hasattr(system, "to_state_space") and not hasattr(system, "A"):
        system = system.to_state_space()
    try:
        A, B, C, D = (np.array(getattr(system, name), dtype=float) for name in "ABCD")
    except (AttributeError, TypeError, ValueError):
        raise ValueError("system must be a state-space model with matrices A, B, C and D; "
                         f"got {type(system).__name__}") from None
    A, B, C, D = (np.atleast_2d(matrix) for matrix in (A, B, C, D))
    n = A.shape[0]
    if (A.shape != (n, n) or B.shape[0] != n or C.shape[1] != n
            or D.shape != (C.shape[0], B.shape[1])):
        raise ValueError("system must have matrices A (n, n), B (n, m), C (p, n) and D (p, m); "
                         f"got shapes {A.shape}, {B.shape}, {C.shape}, {D.shape}")
    if not all(np.isfinite(matrix).all() for matrix in (A, B, C, D)):
        raise ValueError("system must have finite matrices")
    dt = getattr(system, "dt", None)
    if dt is True:  # discrete-time with an unspecified sample time
        dt = 1.0 if sample_time is None else sample_time
    elif dt is None and sample_time is not None:
        dt = sample_time
    if dt is None or dt is False or dt == 0:
        raise ValueError("system must be discrete-time (dt > 0 or True), or sample_time "
                         "given; got a model without a sample time")
    dt = check_positive(dt, "sample_time")
    buffer = io.BytesIO()
    np.savez(buffer, A=A, B=B, C=C, D=D, dt=np.asarray(dt, dtype=float))
    if hasattr(file, "write"):
        file.write(buffer.getvalue())
    else:
        write_file(os.fspath(file), buffer.getvalue(), overwrite=overwrite)


def load_state_space(file) -> signal.StateSpace:
    """Read a state-space model written by :func:`save_state_space`.

    Parameters
    ----------
    file : str, path-like or binary file object

    Returns
    -------
    scipy.signal.StateSpace
        Discrete-time, with ``dt`` from the file.

    Examples
    --------
    >>> import os, tempfile
    >>> from scipy import signal
    >>> from gpmultirate.export import load_state_space, save_state_space
    >>> path = os.path.join(tempfile.mkdtemp(), "state_space.npz")
    >>> save_state_space(signal.StateSpace([[0.0]], [[1.0]], [[1.0]], [[0.5]], dt=True),
    ...                  path, sample_time=0.01)
    >>> load_state_space(path).dt
    0.01
    """
    with np.load(file, allow_pickle=False) as arrays:
        A, B, C, D, dt = (np.array(arrays[name]) for name in ("A", "B", "C", "D", "dt"))
    return signal.StateSpace(A, B, C, D, dt=float(dt))
