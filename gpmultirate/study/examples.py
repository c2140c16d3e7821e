"""Examples of the paper as data: one run of the study (Fig. 6) and Example 1 (Fig. 2).

* :func:`paper_example`: one Monte Carlo run's fitted LS, DC and PK models,
  for the Bode, impulse-response and intersample figures.
* :func:`nonidentifiable_example`: three fast-rate FIR models with identical
  slow-rate outputs (Example 1); :mod:`gpmultirate.plotting` draws both.
"""

from __future__ import annotations

from dataclasses import dataclass

import joblib
import numpy as np
import scipy.linalg

from gpmultirate import DownsampledConvolution
from gpmultirate.simulation import DiscreteSystem
from gpmultirate.study.runner import check_n_jobs, fit_and_score
from gpmultirate.study.simulation import (
    METHODS,
    RunData,
    check_config,
    check_methods,
    check_orders,
    child_seed,
    seed_sequence,
    simulate_run,
)
from gpmultirate.validation import check_int, check_positive, check_rng

__all__ = ["NonidentifiableExample", "PaperExample", "nonidentifiable_example", "paper_example"]


@dataclass
class PaperExample:
    """One Monte Carlo run with its fitted models, for the paper's Fig. 6.

    Attributes
    ----------
    data : RunData
        The run's system, inputs and outputs.
    models : dict of str to fitted estimator
        ``"LS"`` (at ``ls_order``), ``"DC"`` and ``"PK"`` (at ``order``), for
        the requested methods; no ``"LS"`` when no order of the grid is
        identifiable.
    gof : dict of str to float
        Validation goodness of fit of each model.
    order : int
        Order ``P`` of the kernel-regularised models.
    ls_order : int or None
        Order of the least-squares model.
    ls_orders, ls_gof : ndarray
        The least-squares orders tried (only ``ls_order`` when it was given)
        and their GoF, NaN where not identifiable.

    Examples
    --------
    >>> from gpmultirate.study import paper_example
    >>> example = paper_example(order=None, methods=("LS",), n_samples=60)
    >>> example.frequencies().shape, example.true_impulse_response(5).shape
    ((31,), (5,))
    """

    data: RunData
    models: dict
    gof: dict
    order: int
    ls_order: int | None
    ls_orders: np.ndarray
    ls_gof: np.ndarray

    @property
    def system(self) -> DiscreteSystem:
        """The true system ``G_0`` of the run."""
        return self.data.system

    def frequencies(self) -> np.ndarray:
        """DFT bins ``k / (N T)``, ``k = 0..N/2``, of the training record, in Hz."""
        return np.fft.rfftfreq(self.data.u.shape[0], d=self.data.sample_time)

    def true_frequency_response(self, freqs=None) -> np.ndarray:
        """FRF of the true system at ``freqs`` (default :meth:`frequencies`)."""
        return self.system.frequency_response(self.frequencies() if freqs is None else freqs)

    def true_impulse_response(self, n_lags: int | None = None) -> np.ndarray:
        """Markov parameters of the true system at lags ``0..n_lags-1`` (default ``order``)."""
        return self.system.impulse_response(self.order if n_lags is None else n_lags)


def paper_example(
    random_state=0,
    order: int | None = 600,
    ls_order: int | None = None,
    *,
    methods=METHODS,
    ls_orders=None,
    n_samples: int = 600,
    factor: int = 3,
    sample_time: float = 0.1,
    snr_db=(40.0, 60.0),
    perturbation: float = 0.1,
    n_jobs: int = 1,
) -> PaperExample:
    """Fit LS, DC and PK models on one run's data, as in the paper's Fig. 6.

    The data are those of the first run of ``run_paper_study(random_state=...)``
    with the same settings.  The DC and PK models have order ``order``
    (``P = N`` in the paper); least squares has ``ls_order``, or, by default,
    the identifiable order of ``ls_orders`` with the highest validation GoF
    (``P = 150`` in the paper).

    Parameters
    ----------
    random_state : int, SeedSequence or None, default=0
        Seed of the study whose first run is used.
    order : int or None, default=600
        Order of the DC and PK models, in ``1..n_samples``; None is ``n_samples``.
    ls_order : int, optional
        Order of the least-squares model, below ``M``.
    methods : sequence of {"LS", "DC", "PK"}, default=("LS", "DC", "PK")
    ls_orders : sequence of int, optional
        Candidate least-squares orders; default ``10, 20, ...`` below ``M``
        (``1..M-1`` when ``M <= 10``).
    n_samples, factor, sample_time, snr_db, perturbation
        As in :func:`~gpmultirate.study.run_paper_study`.
    n_jobs : int, default=1
        Fit the DC and PK models in parallel processes.

    Returns
    -------
    PaperExample

    Examples
    --------
    >>> from gpmultirate.study import paper_example
    >>> example = paper_example(order=None, methods=("LS", "DC"), n_samples=60)
    >>> example.order, example.ls_order < 20, sorted(example.models)
    (60, True, ['DC', 'LS'])
    """
    config = check_config(n_samples, factor, sample_time, snr_db, perturbation)
    n = config["n_samples"]
    order = n if order is None else check_int(order, "order", low=1, high=n)
    methods = check_methods(methods)
    n_jobs = check_n_jobs(n_jobs)
    data = simulate_run(child_seed(seed_sequence(random_state), 0), **config)
    n_slow = data.y_slow.shape[0]

    models, gof = {}, {}
    ls_tried, ls_scores, best = np.array([], dtype=int), np.array([]), None
    if "LS" in methods:
        if ls_order is not None:
            ls_tried = np.array([check_int(ls_order, "ls_order", low=1, high=n_slow - 1)])
        else:
            if ls_orders is None:
                ls_orders = range(10, n_slow, 10) if n_slow > 10 else range(1, max(n_slow, 2))
            ls_tried = check_orders(ls_orders, n, "ls_orders")
        fits = [fit_and_score("LS", int(p), data) for p in ls_tried]
        ls_scores = np.array([score for _, _, score in fits])
        if np.any(np.isfinite(ls_scores)):
            j = int(np.nanargmax(ls_scores))
            best, models["LS"], gof["LS"] = int(ls_tried[j]), fits[j][1], float(ls_scores[j])

    kernel_methods = [m for m in methods if m != "LS"]
    tasks = (joblib.delayed(fit_and_score)(m, order, data) for m in kernel_methods)
    for method, model, score in joblib.Parallel(n_jobs=n_jobs)(tasks):
        models[method], gof[method] = model, score
    return PaperExample(data=data, models={m: models[m] for m in methods if m in models},
                        gof={m: gof[m] for m in methods if m in gof}, order=order,
                        ls_order=best, ls_orders=ls_tried, ls_gof=ls_scores)


# ------------------------------------------------- non-identifiable example
@dataclass
class NonidentifiableExample:
    """Three fast-rate FIR models with identical slow-rate outputs (Example 1).

    Attributes
    ----------
    u : ndarray of shape (N,)
        The impulsive fast-rate input.
    models : ndarray of shape (3, P)
        Impulse responses ``theta``, ``theta*`` and ``theta'``, ``P = N``.
    y_slow : ndarray of shape (M,)
        The slow-rate output, the same for the three models.
    y_fast : ndarray of shape (3, N)
        The fast-rate outputs, which differ.
    factor : int
        Downsampling factor ``F``.

    Examples
    --------
    >>> from gpmultirate.study import nonidentifiable_example
    >>> example = nonidentifiable_example(40, factor=4, random_state=0)
    >>> freqs, spectra = example.slow_spectra(sample_time=0.5)
    >>> freqs.shape, spectra.shape, float(freqs[-1])  # up to the slow Nyquist frequency
    ((6,), (3, 6), 0.25)
    """

    u: np.ndarray
    models: np.ndarray
    y_slow: np.ndarray
    y_fast: np.ndarray
    factor: int

    @property
    def slow_outputs(self) -> np.ndarray:
        """Every ``factor``-th sample of each fast-rate output, shape ``(3, M)``."""
        return self.y_fast[:, :: self.factor]

    def slow_spectra(self, sample_time: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """DFT of each model's slow-rate output: ``(freqs in Hz, complex (3, K))``.

        The bins are ``k / (M F T)`` up to the slow Nyquist frequency; the
        three spectra are equal.
        """
        slow_time = self.factor * check_positive(sample_time, "sample_time")
        outputs = self.slow_outputs
        freqs = np.fft.rfftfreq(outputs.shape[1], d=slow_time)
        return freqs, np.array([np.fft.rfft(y) for y in outputs])

    def frequency_responses(self, sample_time: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """FRF of each model at the bins ``k / (N T)``: ``(freqs in Hz, complex (3, K))``.

        The DFT of the coefficients is the FRF at those bins; the three FRFs
        differ above the slow Nyquist frequency.
        """
        sample_time = check_positive(sample_time, "sample_time")
        freqs = np.fft.rfftfreq(self.u.shape[0], d=sample_time)
        return freqs, np.array([np.fft.rfft(model) for model in self.models])


def nonidentifiable_example(
    n_samples: int = 1000, factor: int = 4, random_state=None
) -> NonidentifiableExample:
    """Three FIR models with identical slow-rate outputs (the paper's Example 1).

    The input is an impulse at ``n = 0`` of ``N = n_samples`` fast samples and
    the order is ``P = N``, so the regressor ``Phi`` (eq. 8) of the
    ``M = ceil(N / F)`` slow samples has a null space of dimension ``P - M``.
    ``theta`` is a decaying oscillation below the slow Nyquist frequency;
    ``theta*`` and ``theta'`` add to it the orthogonal projection onto that
    null space (:func:`scipy.linalg.null_space`) of a decaying oscillation at
    a random frequency between the slow and the fast Nyquist frequency.  The
    three slow outputs ``Phi theta`` are equal, the fast-rate models are not.

    Parameters
    ----------
    n_samples : int, default=1000
        ``N = P``; at least ``2 * factor``.
    factor : int, default=4
        Downsampling factor ``F >= 2``.
    random_state : int, RandomState or None
        Seed of the added oscillations.

    Returns
    -------
    NonidentifiableExample

    Examples
    --------
    >>> import numpy as np
    >>> from gpmultirate.study import nonidentifiable_example
    >>> example = nonidentifiable_example(200, factor=4, random_state=0)
    >>> example.models.shape, example.y_slow.shape
    ((3, 200), (50,))
    >>> bool(np.allclose(example.y_fast[1, ::4], example.y_fast[0, ::4]))
    True
    """
    factor = check_int(factor, "factor", low=2)
    n_samples = check_int(n_samples, "n_samples", low=2 * factor)
    rng = check_rng(random_state)
    u = np.zeros(n_samples)
    u[0] = 1.0
    observation = DownsampledConvolution(u, factor, n_samples)
    null = scipy.linalg.null_space(observation.matrix)

    lags = np.arange(n_samples)
    decay = np.exp(-lags / (n_samples / 20.0))
    slow_nyquist, fast_nyquist = 0.5 / factor, 0.5  # cycles per fast sample
    base = decay * np.sin(2 * np.pi * 0.5 * slow_nyquist * lags)
    models = [base]
    for _ in range(2):
        frequency = rng.uniform(1.2 * slow_nyquist, 0.9 * fast_nyquist)
        phase = rng.uniform(0.0, 2 * np.pi)
        extra = 0.5 * decay * np.cos(2 * np.pi * frequency * lags + phase)
        models.append(base + null @ (null.T @ extra))
    models = np.array(models)
    y_fast = np.array([np.convolve(u, model)[:n_samples] for model in models])
    return NonidentifiableExample(u=u, models=models, y_slow=observation.matvec(models[0]),
                                  y_fast=y_fast, factor=factor)
