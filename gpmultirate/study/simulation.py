"""Data of one Monte Carlo run of the paper's study (Section 5.1), and its settings.

Every run draws a two-mass-spring-damper system with each parameter within
+-10 % of nominal, independent random-phase multisines of ``N`` samples for
training and validation, and white noise on the training output at a
signal-to-noise ratio drawn uniformly in [40, 60] dB; the slow output is
every ``F``-th noisy fast sample (eq. 3).

Random numbers come from :class:`numpy.random.SeedSequence`: within a run the
system, the two inputs and the noise each have their own child stream
(:func:`child_rng`), so that the data depend only on the run's seed.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np
from sklearn.gaussian_process.kernels import ConstantKernel, Kernel

from gpmultirate.kernels import DC, PK
from gpmultirate.simulation import DiscreteSystem, multisine, paper_system, simulate_experiment
from gpmultirate.validation import check_int, check_positive

__all__ = [
    "METHODS",
    "PAPER_NOISE_LEVEL",
    "PAPER_ORDERS",
    "RunData",
    "check_config",
    "check_methods",
    "check_orders",
    "child_rng",
    "child_seed",
    "paper_kernels",
    "seed_sequence",
    "simulate_run",
]

#: Estimators of the study: least squares (eq. 11), DC kernel, DC + two PK kernels.
METHODS = ("LS", "DC", "PK")
#: The paper's grid of FIR orders, ``P = 50, 100, ..., N = 600``.
PAPER_ORDERS = tuple(range(50, 601, 50))
#: The paper's regularisation parameter ``gamma`` (initial noise variance).
PAPER_NOISE_LEVEL = 1e-5
# resonances of the paper's prior-knowledge kernel, in Hz
_PK_FREQUENCIES = (0.4, 2.0)


# ------------------------------------------------------------------ kernels
def paper_kernels(sample_time: float = 0.1) -> dict[str, tuple[Kernel, float]]:
    """The DC and prior-knowledge kernels of the simulation example, with ``gamma``.

    ``"DC"`` is ``lambda * DC(alpha, beta)`` (eq. 16) and ``"PK"`` adds one
    prior-knowledge kernel (eq. 18-19) per resonance at 0.4 and 2 Hz
    (eq. 21), with the paper's values ``lambda = 1``,
    ``alpha = alpha_n = exp(-0.5 T)``, ``beta = exp(-0.1 T)``,
    ``sigma_1n = sigma_2n = 1`` and ``gamma = 1e-5``.  These are the starting
    point of the estimator's marginal-likelihood tuning, which adjusts all of
    them (the paper tunes ``gamma``, ``omega_n`` and ``alpha_n``).

    Parameters
    ----------
    sample_time : float, default=0.1
        Fast sample time ``T`` in seconds, below 0.25 s so that the 2 Hz
        resonance lies below the fast Nyquist frequency.

    Returns
    -------
    dict
        ``{"DC": (kernel, noise_level), "PK": (kernel, noise_level)}``.

    Examples
    --------
    >>> from gpmultirate.study import paper_kernels
    >>> kernels = paper_kernels(0.1)
    >>> sorted(kernels), kernels["PK"][1]
    (['DC', 'PK'], 1e-05)
    >>> kernels["PK"][0].k2.frequency_hz(0.1)  # the 2 Hz resonance
    2.0
    """
    sample_time = check_positive(sample_time, "sample_time")
    if max(_PK_FREQUENCIES) >= 0.5 / sample_time:
        raise ValueError(
            f"sample_time must be below {0.5 / max(_PK_FREQUENCIES):g} s so that the "
            f"{max(_PK_FREQUENCIES):g} Hz resonance lies below the fast Nyquist frequency; "
            f"got {sample_time!r}"
        )
    alpha = math.exp(-0.5 * sample_time)
    beta = math.exp(-0.1 * sample_time)
    # the amplitude may vanish: when the resonances explain the data, the DC
    # term of the PK kernel switches off instead of pressing on a bound
    dc = ConstantKernel(1.0, (1e-12, 1e5)) * DC(alpha=alpha, beta=beta)
    pk = dc
    for frequency in _PK_FREQUENCIES:  # eq. (21): k_DC + sum_n k_pk,n
        pk = pk + PK.from_hz(frequency, sample_time, alpha=alpha, sigma1=1.0, sigma2=1.0)
    return {"DC": (dc, PAPER_NOISE_LEVEL), "PK": (pk, PAPER_NOISE_LEVEL)}


# --------------------------------------------------------------- validation
def check_methods(methods) -> tuple[str, ...]:
    """Validate a selection of study methods, a name or a sequence of names.

    Examples
    --------
    >>> check_methods("LS"), check_methods(["PK", "DC"])
    (('LS',), ('PK', 'DC'))
    """
    if isinstance(methods, str):
        methods = (methods,)
    try:
        methods = tuple(methods)
    except TypeError as exc:
        raise ValueError(f"methods must be a sequence of names from {METHODS}") from exc
    if not methods:
        raise ValueError(f"methods must name at least one of {METHODS}")
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise ValueError(f"methods must be names from {METHODS}; got unknown {unknown}")
    if len(set(methods)) != len(methods):
        raise ValueError(f"methods must not repeat a name; got {methods}")
    return methods


def check_orders(orders, n_samples: int, name: str = "orders") -> np.ndarray:
    """Validate FIR orders in ``1..n_samples``, distinct; return them sorted.

    Examples
    --------
    >>> check_orders((30, 10), 60)
    array([10, 30])
    """
    if isinstance(orders, numbers.Integral) and not isinstance(orders, bool):
        orders = (orders,)
    try:
        items = list(orders)
    except TypeError as exc:
        raise ValueError(f"{name} must be a sequence of integers; got {orders!r}") from exc
    if not items:
        raise ValueError(f"{name} must contain at least one order")
    if any(isinstance(p, bool) or not isinstance(p, numbers.Integral) for p in items):
        raise ValueError(f"{name} must be integers; got {items!r}")
    values = np.array(items, dtype=int)
    if values.min() < 1 or values.max() > n_samples:
        raise ValueError(
            f"{name} must lie in 1..n_samples = 1..{n_samples}; got {values.tolist()}"
        )
    if np.unique(values).size != values.size:
        raise ValueError(f"{name} must not repeat a value; got {values.tolist()}")
    return np.sort(values)


def _check_snr(snr_db) -> tuple[float, float]:
    if isinstance(snr_db, numbers.Real) and not isinstance(snr_db, bool):
        snr_db = (snr_db, snr_db)
    try:
        low, high = (float(v) for v in snr_db)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"snr_db must be a number or a pair (low, high) in dB; got {snr_db!r}"
        ) from exc
    if not (np.isfinite(low) and np.isfinite(high) and low <= high):
        raise ValueError(f"snr_db must be finite with low <= high; got {snr_db!r}")
    return low, high


def _check_perturbation(perturbation) -> float:
    if isinstance(perturbation, bool) or not isinstance(perturbation, numbers.Real) \
            or not 0 <= perturbation < 1:
        raise ValueError(f"perturbation must lie in [0, 1); got {perturbation!r}")
    return float(perturbation)


def check_config(n_samples, factor, sample_time, snr_db, perturbation) -> dict:
    """The validated settings shared by a run, a study and the example.

    Returns
    -------
    dict
        ``n_samples``, ``factor``, ``sample_time``, ``snr_db`` (a pair) and
        ``perturbation``, the keyword arguments of :func:`simulate_run`.

    Examples
    --------
    >>> check_config(60, 3, 0.1, 50, 0.1)["snr_db"]
    (50.0, 50.0)
    """
    n_samples = check_int(n_samples, "n_samples", low=3)
    factor = check_int(factor, "factor", low=1, high=n_samples)
    paper_kernels(sample_time)  # validates sample_time
    return {
        "n_samples": n_samples,
        "factor": factor,
        "sample_time": float(sample_time),
        "snr_db": _check_snr(snr_db),
        "perturbation": _check_perturbation(perturbation),
    }


# ------------------------------------------------------------------ seeding
def seed_sequence(seed) -> np.random.SeedSequence:
    """``seed`` as a :class:`~numpy.random.SeedSequence` (None draws fresh entropy).

    Examples
    --------
    >>> seed_sequence(3).entropy
    3
    """
    if isinstance(seed, np.random.SeedSequence):
        return seed
    if seed is None or (isinstance(seed, numbers.Integral) and not isinstance(seed, bool)
                        and seed >= 0):
        return np.random.SeedSequence(seed)
    raise ValueError(
        f"random_state must be None, a non-negative integer or a SeedSequence; got {seed!r}"
    )


def child_seed(seed: np.random.SeedSequence, index: int) -> np.random.SeedSequence:
    """Child ``index`` of ``seed`` as ``seed.spawn`` makes it, without advancing ``seed``.

    ``spawn`` counts the children already made, so that spawning twice from
    one object gives different children; a study must give the same runs
    every time it is given the same seed object.

    Examples
    --------
    >>> import numpy as np
    >>> root = np.random.SeedSequence(5)
    >>> child_seed(root, 2).spawn_key == np.random.SeedSequence(5).spawn(3)[2].spawn_key
    True
    """
    return np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, index),
                                  pool_size=seed.pool_size)


def child_rng(seed: np.random.SeedSequence, index: int) -> np.random.Generator:
    """A generator on child ``index`` of ``seed``, see :func:`child_seed`.

    Examples
    --------
    >>> import numpy as np
    >>> first = child_rng(np.random.SeedSequence(0), 1).standard_normal()
    >>> first == child_rng(np.random.SeedSequence(0), 1).standard_normal()
    True
    """
    return np.random.default_rng(child_seed(seed, index))


# ---------------------------------------------------------------- one run
@dataclass
class RunData:
    """Training and validation data of one Monte Carlo run, see :func:`simulate_run`.

    Attributes
    ----------
    system : DiscreteSystem
        The perturbed fast-rate system ``G_0``.
    u, u_val : ndarray of shape (N,)
        Training and validation multisines (unit RMS).
    y_fast : ndarray of shape (N,)
        Noise-free fast training output ``y_h``.
    y_fast_noisy : ndarray of shape (N,)
        ``y_h + e_h``.
    y_slow : ndarray of shape (M,)
        ``(y_h + e_h)[0::F]``, the only output the estimators see.
    y_val : ndarray of shape (N,)
        Noise-free fast validation output, the reference of the GoF.
    snr_db : float
        Drawn signal-to-noise ratio of the training output, in dB.
    noise_std : float
        Standard deviation of ``e_h``.
    factor : int
    sample_time : float
    """

    system: DiscreteSystem
    u: np.ndarray
    y_fast: np.ndarray
    y_fast_noisy: np.ndarray
    y_slow: np.ndarray
    u_val: np.ndarray
    y_val: np.ndarray
    snr_db: float
    noise_std: float
    factor: int
    sample_time: float


def simulate_run(
    seed=None,
    *,
    n_samples: int = 600,
    factor: int = 3,
    sample_time: float = 0.1,
    snr_db=(40.0, 60.0),
    perturbation: float = 0.1,
) -> RunData:
    """Draw the system and the data of one Monte Carlo run (Section 5.1).

    Parameters
    ----------
    seed : int, SeedSequence or None
        The run's seed; :func:`~gpmultirate.study.run_paper_study` passes
        child ``i`` of ``SeedSequence(random_state)`` to run ``i``.  The
        system, the training input, the validation input and the noise (with
        the SNR) use the independent children 0, 1, 2 and 3 of it.
    n_samples : int, default=600
        Samples ``N`` of each multisine (one period, all bins excited).
    factor : int, default=3
        Downsampling factor ``F``.
    sample_time : float, default=0.1
        Fast sample time ``T`` in seconds.
    snr_db : float or (float, float), default=(40, 60)
        Range of the uniformly drawn SNR ``var(y_h) / var(e_h)`` in dB.
    perturbation : float, default=0.1
        Relative range of the system's parameters around nominal.

    Returns
    -------
    RunData

    Examples
    --------
    >>> from gpmultirate.study import simulate_run
    >>> data = simulate_run(0, n_samples=60)
    >>> data.u.shape, data.y_slow.shape, 40 <= data.snr_db <= 60
    ((60,), (20,), True)
    """
    config = check_config(n_samples, factor, sample_time, snr_db, perturbation)
    seed = seed_sequence(seed)
    n, t = config["n_samples"], config["sample_time"]
    system = paper_system(t, config["perturbation"], random_state=child_rng(seed, 0))
    u = multisine(n, t, random_state=child_rng(seed, 1))
    u_val = multisine(n, t, random_state=child_rng(seed, 2))
    noise = child_rng(seed, 3)
    snr = float(noise.uniform(*config["snr_db"]))
    train = simulate_experiment(system, u, config["factor"], snr_db=snr, random_state=noise)
    return RunData(system=system, u=u, y_fast=train.y_fast, y_fast_noisy=train.y_fast_noisy,
                   y_slow=train.y_slow, u_val=u_val, y_val=system.simulate(u_val), snr_db=snr,
                   noise_std=train.noise_std, factor=config["factor"], sample_time=t)
