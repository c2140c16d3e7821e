"""Simulated systems, excitation signals and slow-rate measurements.

This module generates the data of the paper's simulation example (Section 5) and of a
surrogate of its wafer-stage experiment (Section 6): a fast-rate discrete-time system
``G_0`` in state-space form, fast-rate inputs ``u_h``, output noise ``e_h`` and the
downsampler ``y_l(m) = y_h(offset + m * factor) + e_h(offset + m * factor)`` (eq. 3).
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from scipy import signal

from gpmultirate.validation import as_real_array, check_int, check_positive, check_signal

__all__ = [
    "DiscreteSystem", "two_mass_spring_damper", "PAPER_PARAMETERS", "perturb_parameters",
    "paper_system", "WAFER_STAGE_MODES", "wafer_stage_surrogate", "multisine",
    "random_binary_sequence", "zero_order_hold", "zoh_input", "add_output_noise",
    "downsample", "SimulatedExperiment", "simulate_experiment",
    "CAMERA_LOOP_MODES", "camera_loop_plant", "CameraLoopExperiment", "frame_disturbance",
    "simulate_camera_loop",
]

RandomStateLike = int | np.random.Generator | np.random.RandomState | None

#: Nominal parameters of the paper's two-mass-spring-damper system (Section 5.1), SI units.
PAPER_PARAMETERS = {"k1": 15.0, "k2": 100.0, "d1": 0.45, "d2": 0.06, "m1": 1.0, "m2": 1.0}

#: Modes ``(frequency in Hz, damping ratio, static gain)`` of :func:`wafer_stage_surrogate`.
WAFER_STAGE_MODES = (
    (80.0, 0.5, 1.0),  # well-damped, closed-loop-like low-frequency behaviour
    (490.0, 0.01, 0.006),  # closely spaced pair of structural chuck modes ...
    (510.0, 0.01, 0.005),  # ... same-sign gains give an anti-resonance in between
    (870.0, 0.015, 0.01),  # higher structural mode, above the slow-rate Nyquist frequency
)

#: Modes ``(frequency in Hz, damping ratio, static gain)`` of :func:`camera_loop_plant`.
CAMERA_LOOP_MODES = (
    (4.0, 0.3, 0.4),  # the low mode the camera's loop acts on
    (76.0, 0.03, 0.02),  # a structural mode above the 50 Hz Nyquist frequency of a 100 Hz camera
)


def _check_random_state(random_state: RandomStateLike) -> np.random.Generator:
    """Return a numpy Generator from an int, None, Generator or legacy RandomState."""
    if isinstance(random_state, numbers.Integral) and not isinstance(random_state, bool):
        if random_state < 0:
            raise ValueError(f"random_state must be a non-negative seed; got {random_state}")
        return np.random.default_rng(random_state)
    if random_state is None or isinstance(random_state, np.random.Generator):
        return np.random.default_rng(random_state)
    if isinstance(random_state, np.random.RandomState):
        # Draw a seed so that the caller's RandomState advances, as in scikit-learn.
        return np.random.default_rng(random_state.randint(np.iinfo(np.int32).max))
    raise ValueError(f"random_state must be None, an int or a numpy generator, "
                     f"got {random_state!r}")


def _check_signal(x, name: str) -> np.ndarray:
    """Return a float copy of a finite, non-empty 1-D signal."""
    return check_signal(x, name)


def _check_positive_int(value, name: str) -> int:
    return check_int(value, name, low=1)


def _check_positive(value, name: str) -> float:
    return check_positive(value, name)


class DiscreteSystem:
    """Fast-rate discrete-time LTI SISO system ``x(n+1) = A x(n) + B u(n)``, ``y = C x + D u``.

    Parameters
    ----------
    A : array-like of shape (order, order)
    B : array-like of shape (order,) or (order, 1)
    C : array-like of shape (order,) or (1, order)
    D : float or array-like of shape (1,) or (1, 1)
    sample_time : float
        Fast sampling time ``T_h`` in seconds.

    Attributes
    ----------
    A, B, C, D : ndarray
        Float copies with shapes ``(order, order)``, ``(order, 1)``, ``(1, order)``, ``(1, 1)``,
        as used by :mod:`scipy.signal`.

    Examples
    --------
    >>> system = DiscreteSystem([[0.5]], [1.0], [1.0], 0.0, sample_time=0.1)
    >>> system.impulse_response(4).tolist()
    [0.0, 1.0, 0.5, 0.25]
    >>> system.simulate([1.0, 0.0, 0.0]).tolist()
    [0.0, 1.0, 0.5]
    """

    def __init__(self, A, B, C, D, sample_time: float):
        A = as_real_array(A, "A")
        if A.ndim != 2 or A.shape[0] != A.shape[1] or A.shape[0] == 0:
            raise ValueError(f"A must be a non-empty square matrix, got shape {A.shape}")
        n = A.shape[0]
        shapes = {"B": ((n,), (n, 1)), "C": ((n,), (1, n)), "D": ((), (1,), (1, 1))}
        arrays = {"A": A}
        for name, value in zip("BCD", (B, C, D)):
            array = as_real_array(value, name)
            if array.shape not in shapes[name]:
                raise ValueError(f"{name} must have shape in {shapes[name]}, got {array.shape}")
            arrays[name] = array
        for name, array in arrays.items():
            if not np.all(np.isfinite(array)):
                raise ValueError(f"{name} must contain only finite values")
        self.A = A
        self.B = arrays["B"].reshape(n, 1)
        self.C = arrays["C"].reshape(1, n)
        self.D = arrays["D"].reshape(1, 1)
        self.sample_time = _check_positive(sample_time, "sample_time")

    def __repr__(self) -> str:
        return f"DiscreteSystem(order={self.order}, sample_time={self.sample_time!r})"

    @property
    def order(self) -> int:
        """Number of states."""
        return self.A.shape[0]

    @property
    def poles(self) -> np.ndarray:
        """Eigenvalues of ``A`` (discrete-time poles)."""
        return np.linalg.eigvals(self.A)

    @property
    def fast_nyquist(self) -> float:
        """Nyquist frequency ``1 / (2 T_h)`` of the fast rate, in Hz."""
        return 0.5 / self.sample_time

    def slow_nyquist(self, factor: int) -> float:
        """Nyquist frequency ``1 / (2 F T_h)`` of the output downsampled by ``factor``, in Hz."""
        return 0.5 / (_check_positive_int(factor, "factor") * self.sample_time)

    def _continuous_poles(self) -> np.ndarray:
        # One pole per conjugate pair (LAPACK returns real eigenvalues with zero imaginary
        # part); poles at the origin are pure delays without a continuous equivalent.
        z = self.poles
        z = z[(z.imag >= 0) & (z != 0)]
        s = np.log(z.astype(complex)) / self.sample_time
        return s[np.argsort(np.abs(s), kind="stable")]

    @property
    def natural_frequencies(self) -> np.ndarray:
        """Natural frequencies ``|log z| / (2 pi T_h)`` in Hz, one per pole pair, sorted."""
        return np.abs(self._continuous_poles()) / (2 * np.pi)

    @property
    def damping_ratios(self) -> np.ndarray:
        """Damping ratios ``-Re(s) / |s|`` of the poles, ordered as ``natural_frequencies``."""
        s = self._continuous_poles()
        return -s.real / np.abs(s)

    def simulate(self, u) -> np.ndarray:
        """Fast-rate output ``y_h`` for input ``u`` from zero initial state.

        Examples
        --------
        >>> system = paper_system()
        >>> system.simulate(np.ones(600)).shape
        (600,)
        """
        u = _check_signal(u, "u")
        x = np.zeros(self.order)
        states = np.empty((u.size, self.order))
        a, b = self.A, self.B[:, 0]
        for n, u_n in enumerate(u):
            states[n] = x
            x = a @ x + b * u_n
        return states @ self.C[0] + self.D[0, 0] * u

    def impulse_response(self, n_lags: int) -> np.ndarray:
        """Markov parameters ``[D, CB, CAB, CA^2B, ...]`` of length ``n_lags``.

        Examples
        --------
        >>> g = paper_system().impulse_response(600)
        >>> g.shape, float(g[0])
        ((600,), 0.0)
        """
        n_lags = _check_positive_int(n_lags, "n_lags")
        g = np.empty(n_lags)
        g[0] = self.D[0, 0]
        x = self.B[:, 0]
        for k in range(1, n_lags):
            g[k] = self.C[0] @ x
            x = self.A @ x
        return g

    def frequency_response(self, freqs) -> np.ndarray:
        """Frequency response ``C (zI - A)^{-1} B + D`` at ``z = exp(j 2 pi f T_h)``.

        Parameters
        ----------
        freqs : array-like of float
            Frequencies in Hz.

        Returns
        -------
        ndarray of complex, same shape as ``freqs``

        Examples
        --------
        >>> system = paper_system()
        >>> round(float(abs(system.frequency_response(0.0))), 4)  # static gain 1 / k1
        0.0667
        """
        freqs = as_real_array(freqs, "freqs")
        if not np.all(np.isfinite(freqs)):
            raise ValueError("freqs must be finite")
        z = np.exp(2j * np.pi * freqs.ravel() * self.sample_time)
        resolvent = z[:, None, None] * np.eye(self.order) - self.A
        rhs = np.broadcast_to(self.B, (z.size, self.order, 1))
        x = np.linalg.solve(resolvent, rhs)[:, :, 0]
        return (x @ self.C[0] + self.D[0, 0]).reshape(freqs.shape)


def two_mass_spring_damper(k1: float = 15.0, k2: float = 100.0, d1: float = 0.45,
                           d2: float = 0.06, m1: float = 1.0,
                           m2: float = 1.0) -> tuple[np.ndarray, ...]:
    """Continuous-time ``(A, B, C, D)`` of wall -(k1, d1)- m1 -(k2, d2)- m2.

    The force acts on ``m1``, the output is the position of ``m2``; the states are
    ``[x1, v1, x2, v2]``. Defaults are the paper's nominal values, :data:`PAPER_PARAMETERS`.

    Examples
    --------
    >>> A, B, C, D = two_mass_spring_damper()
    >>> A.shape, B.shape, C.shape, D.shape
    ((4, 4), (4, 1), (1, 4), (1, 1))
    """
    k1, k2, d1, d2, m1, m2 = (_check_positive(v, name) for v, name in zip(
        (k1, k2, d1, d2, m1, m2), ("k1", "k2", "d1", "d2", "m1", "m2")))
    A = np.array([
        [0.0, 1.0, 0.0, 0.0],
        [-(k1 + k2) / m1, -(d1 + d2) / m1, k2 / m1, d2 / m1],
        [0.0, 0.0, 0.0, 1.0],
        [k2 / m2, d2 / m2, -k2 / m2, -d2 / m2],
    ])
    B = np.array([[0.0], [1.0 / m1], [0.0], [0.0]])
    C = np.array([[0.0, 0.0, 1.0, 0.0]])
    return A, B, C, np.zeros((1, 1))


def _zoh(A, B, C, D, sample_time: float) -> DiscreteSystem:
    # Zero-order hold: expm([[A, B], [0, 0]] T) = [[A_d, B_d], [0, I]].
    n, m = B.shape
    augmented = np.zeros((n + m, n + m))
    augmented[:n, :n], augmented[:n, n:] = A, B
    transition = scipy.linalg.expm(augmented * sample_time)
    return DiscreteSystem(transition[:n, :n], transition[:n, n:], C, D, sample_time)


def perturb_parameters(nominal: dict, perturbation: float,
                       random_state: RandomStateLike = None) -> dict:
    """Draw each parameter uniformly within ``+- perturbation`` (relative) of its nominal value.

    Examples
    --------
    >>> params = perturb_parameters(PAPER_PARAMETERS, 0.1, random_state=0)
    >>> all(abs(params[k] / v - 1) <= 0.1 for k, v in PAPER_PARAMETERS.items())
    True
    """
    if (isinstance(perturbation, bool) or not isinstance(perturbation, numbers.Real)
            or not 0 <= perturbation < 1):
        raise ValueError(f"perturbation must lie in [0, 1), got {perturbation!r}")
    if not isinstance(nominal, dict) or not all(
        isinstance(v, numbers.Real) and not isinstance(v, bool) and np.isfinite(v) and v > 0
        for v in nominal.values()
    ):
        raise ValueError("nominal must be a dict of finite positive parameter values")
    rng = _check_random_state(random_state)
    factors = 1.0 + perturbation * rng.uniform(-1.0, 1.0, size=len(nominal))
    return {name: float(value) * f for (name, value), f in zip(nominal.items(), factors)}


def paper_system(sample_time: float = 0.1, perturbation: float = 0.0,
                 random_state: RandomStateLike = None) -> DiscreteSystem:
    """The paper's simulation system (Section 5), zero-order-hold discretised.

    Two-mass-spring-damper from :func:`two_mass_spring_damper` with :data:`PAPER_PARAMETERS`
    (modes near 0.43 Hz and 2.29 Hz); with ``perturbation=0.1`` each of the six parameters
    is drawn independently within +-10 % of nominal, as in every Monte Carlo run.

    Examples
    --------
    >>> system = paper_system()
    >>> np.round(system.natural_frequencies, 2)
    array([0.43, 2.29])
    >>> paper_system(perturbation=0.1, random_state=3).order
    4
    """
    params = perturb_parameters(PAPER_PARAMETERS, perturbation, random_state)
    return _zoh(*two_mass_spring_damper(**params), _check_positive(sample_time, "sample_time"))


def wafer_stage_surrogate(sample_time: float = 1 / 2000, random_state: RandomStateLike = None,
                          perturbation: float = 0.0) -> DiscreteSystem:
    """Lightly damped multi-mode surrogate of the paper's prototype wafer stage (Section 6).

    The continuous-time model is the modal sum
    ``G(s) = sum_i g_i w_i^2 / (s^2 + 2 zeta_i w_i s + w_i^2)`` over :data:`WAFER_STAGE_MODES`:
    a well-damped mode at 80 Hz (``zeta = 0.5``, unit static gain) standing in for the
    closed-loop process sensitivity, and structural resonances at 490, 510 and 870 Hz with
    ``zeta`` 0.01-0.015, the frequencies of the paper's prior-knowledge kernel. The small
    static gains (0.005-0.01) put the resonance peaks about 15-20 dB above the surrounding
    FRF; the same sign of the 490/510 Hz gains gives an anti-resonance that keeps the two
    peaks apart. The slowest decay rate ``zeta w`` is about 31 1/s, so the impulse response
    falls below 1e-4 of its peak within 600 samples at 2 kHz. Each mode is a strictly proper
    2-state block; the sum is zero-order-hold discretised. ``perturbation`` scales every
    frequency, damping ratio and gain independently within +- that relative amount.

    Examples
    --------
    >>> system = wafer_stage_surrogate()
    >>> system.order, system.slow_nyquist(3) == 1000 / 3
    (8, True)
    >>> np.round(system.natural_frequencies).tolist()
    [80.0, 490.0, 510.0, 870.0]
    """
    rng = _check_random_state(random_state)
    n = 2 * len(WAFER_STAGE_MODES)
    A, B, C = np.zeros((n, n)), np.zeros((n, 1)), np.zeros((1, n))
    for i, mode in enumerate(WAFER_STAGE_MODES):
        nominal = dict(zip(("frequency", "damping", "gain"), mode))
        frequency, damping, gain = perturb_parameters(nominal, perturbation, rng).values()
        w = 2 * np.pi * frequency
        A[2 * i:2 * i + 2, 2 * i:2 * i + 2] = [[0.0, 1.0], [-w**2, -2 * damping * w]]
        B[2 * i + 1, 0] = gain * w**2
        C[0, 2 * i] = 1.0
    return _zoh(A, B, C, np.zeros((1, 1)), _check_positive(sample_time, "sample_time"))


def multisine(n_samples: int, sample_time: float = 1.0, band=None, rms: float = 1.0,
              random_state: RandomStateLike = None) -> np.ndarray:
    """One period of a random-phase multisine with a flat amplitude spectrum.

    All DFT bins strictly between 0 and the Nyquist frequency, ``k = 1, ..., (n_samples - 1)
    // 2`` (``1, ..., N/2 - 1`` for even ``N``, the paper's setting), are excited by default;
    ``band=(f_low, f_high)`` in Hz keeps those whose frequency ``k / (n_samples T)`` lies in
    the closed band. Phases are uniform on ``[0, 2 pi)``; the result has zero mean
    and the requested RMS.

    Examples
    --------
    >>> u = multisine(600, random_state=0)
    >>> u.shape, round(float(np.sqrt(np.mean(u**2))), 6), abs(float(u.mean())) < 1e-12
    ((600,), 1.0, True)
    """
    n_samples = _check_positive_int(n_samples, "n_samples")
    if n_samples < 3:
        raise ValueError(f"n_samples must be at least 3 to excite a bin, got {n_samples}")
    sample_time = _check_positive(sample_time, "sample_time")
    rms = _check_positive(rms, "rms")
    bins = np.arange(1, (n_samples + 1) // 2)
    if band is not None:
        band = as_real_array(band, "band")
        if band.shape != (2,) or not np.all(np.isfinite(band)) or not 0 <= band[0] <= band[1]:
            raise ValueError(f"band must be (f_low, f_high) with 0 <= f_low <= f_high, got {band}")
        freqs = bins / (n_samples * sample_time)
        bins = bins[(freqs >= band[0]) & (freqs <= band[1])]
        if bins.size == 0:
            raise ValueError(f"band {tuple(band)} Hz contains no excitable DFT bin")
    rng = _check_random_state(random_state)
    spectrum = np.zeros(n_samples // 2 + 1, dtype=complex)
    spectrum[bins] = np.exp(2j * np.pi * rng.uniform(size=bins.size))
    u = np.fft.irfft(spectrum, n=n_samples)
    return u * (rms / np.sqrt(np.mean(u**2)))


def random_binary_sequence(n_samples: int, amplitude: float = 1.0,
                           random_state: RandomStateLike = None) -> np.ndarray:
    """I.i.d. sequence of ``+amplitude`` and ``-amplitude`` with equal probability.

    Examples
    --------
    >>> sorted(set(random_binary_sequence(100, amplitude=2.0, random_state=0).tolist()))
    [-2.0, 2.0]
    """
    n_samples = _check_positive_int(n_samples, "n_samples")
    amplitude = _check_positive(amplitude, "amplitude")
    rng = _check_random_state(random_state)
    return amplitude * (2.0 * rng.integers(0, 2, size=n_samples) - 1.0)


def zero_order_hold(u_slow, factor: int) -> np.ndarray:
    """Hold every slow sample for ``factor`` fast samples: ``u_h(mF + i) = u_l(m)`` (Lemma 2).

    Examples
    --------
    >>> zero_order_hold([1.0, 2.0], 3).tolist()
    [1.0, 1.0, 1.0, 2.0, 2.0, 2.0]
    """
    return np.repeat(_check_signal(u_slow, "u_slow"), _check_positive_int(factor, "factor"))


def zoh_input(n_samples: int, factor: int, random_state: RandomStateLike = None) -> np.ndarray:
    """Random zero-order-hold input: white standard-normal slow samples held ``factor`` times.

    Such inputs cannot identify fast-rate models of order above 2 (the paper's Lemma 2).

    Examples
    --------
    >>> u = zoh_input(7, 3, random_state=0)
    >>> u.shape, bool(u[0] == u[1] == u[2]), bool(u[6] != u[5])
    ((7,), True, True)
    """
    n_samples = _check_positive_int(n_samples, "n_samples")
    factor = _check_positive_int(factor, "factor")
    u_slow = _check_random_state(random_state).standard_normal(-(-n_samples // factor))
    return zero_order_hold(u_slow, factor)[:n_samples]


def add_output_noise(y, snr_db: float,
                     random_state: RandomStateLike = None) -> tuple[np.ndarray, float]:
    """Add white Gaussian noise with variance ``var(y) / 10**(snr_db / 10)``.

    The signal-to-noise ratio is the ratio of the variances of ``y_h`` and ``e_h`` in dB,
    as in the paper's simulation example.

    Returns
    -------
    y_noisy : ndarray
        A new array; ``y`` is not modified.
    noise_std : float

    Examples
    --------
    >>> y_noisy, noise_std = add_output_noise(np.sin(np.arange(100.0)), 40.0, random_state=0)
    >>> y_noisy.shape, round(noise_std, 4)
    ((100,), 0.0071)
    """
    y = _check_signal(y, "y")
    if isinstance(snr_db, bool) or not isinstance(snr_db, numbers.Real) or not np.isfinite(snr_db):
        raise ValueError(f"snr_db must be a finite number, got {snr_db!r}")
    noise_std = float(np.sqrt(np.var(y) / 10 ** (snr_db / 10)))
    rng = _check_random_state(random_state)
    return y + noise_std * rng.standard_normal(y.size), noise_std


def downsample(y, factor: int, offset: int = 0) -> np.ndarray:
    """Slow-rate samples ``y[offset::factor]``, the downsampler of eq. (3).

    Examples
    --------
    >>> downsample(np.arange(10.0), 3, offset=1).tolist()
    [1.0, 4.0, 7.0]
    """
    y = _check_signal(y, "y")
    factor = _check_positive_int(factor, "factor")
    if isinstance(offset, bool) or not isinstance(offset, numbers.Integral) \
            or not 0 <= offset < factor:
        raise ValueError(f"offset must be an integer with 0 <= offset < factor, got {offset!r}")
    return y[int(offset)::factor]


@dataclass
class SimulatedExperiment:
    """Data of one simulated slow-rate output experiment, see :func:`simulate_experiment`.

    Examples
    --------
    >>> data = simulate_experiment(paper_system(), np.zeros(6), factor=3)
    >>> data.y_slow.shape
    (2,)
    """

    u: np.ndarray
    y_fast: np.ndarray
    y_fast_noisy: np.ndarray
    y_slow: np.ndarray
    factor: int
    offset: int
    noise_std: float
    sample_time: float
    system: DiscreteSystem


def simulate_experiment(system: DiscreteSystem, u, factor: int, snr_db: float | None = None,
                        offset: int = 0,
                        random_state: RandomStateLike = None) -> SimulatedExperiment:
    """Simulate ``y_h``, add fast-rate noise ``e_h`` at ``snr_db`` and downsample (eq. 3).

    With ``snr_db=None`` the output is noise-free and ``noise_std`` is 0.

    Examples
    --------
    >>> u = multisine(600, sample_time=0.1, random_state=0)
    >>> data = simulate_experiment(paper_system(), u, factor=3, snr_db=50, random_state=1)
    >>> data.u.shape, data.y_fast.shape, data.y_slow.shape
    ((600,), (600,), (200,))
    """
    u = _check_signal(u, "u")
    if not isinstance(system, DiscreteSystem):
        raise ValueError(f"system must be a DiscreteSystem; got {type(system).__name__}")
    y_fast = system.simulate(u)
    if snr_db is None:
        y_fast_noisy, noise_std = y_fast.copy(), 0.0
    else:
        y_fast_noisy, noise_std = add_output_noise(y_fast, snr_db, random_state)
    y_slow = downsample(y_fast_noisy, factor, offset)
    return SimulatedExperiment(u=u, y_fast=y_fast, y_fast_noisy=y_fast_noisy, y_slow=y_slow,
                               factor=int(factor), offset=int(offset), noise_std=noise_std,
                               sample_time=system.sample_time, system=system)


def camera_loop_plant(sample_time: float = 1 / 500, modes=CAMERA_LOOP_MODES) -> DiscreteSystem:
    """A plant with modes near 4 Hz and 76 Hz for a 100 Hz camera's loop (:func:`simulate_camera_loop`).

    The modal sum ``G(s) = sum_i g_i w_i^2 / (s^2 + 2 zeta_i w_i s + w_i^2)``
    over ``modes`` (by default :data:`CAMERA_LOOP_MODES`), zero-order-hold
    discretised at ``sample_time``.  At 500 Hz and a camera every fifth
    sample, the 76 Hz mode lies above the camera's Nyquist frequency.

    Examples
    --------
    >>> plant = camera_loop_plant()
    >>> np.round(plant.natural_frequencies).tolist()
    [4.0, 76.0]
    """
    sample_time = _check_positive(sample_time, "sample_time")
    modes = [tuple(float(v) for v in mode) for mode in modes]
    if not modes or any(len(mode) != 3 or min(mode) <= 0 for mode in modes):
        raise ValueError("modes must be (frequency, damping, gain) triples of positive numbers")
    n = 2 * len(modes)
    A, B, C = np.zeros((n, n)), np.zeros((n, 1)), np.zeros((1, n))
    for i, (frequency, damping, gain) in enumerate(modes):
        w = 2 * np.pi * frequency
        A[2 * i:2 * i + 2, 2 * i:2 * i + 2] = [[0.0, 1.0], [-w**2, -2 * damping * w]]
        B[2 * i + 1, 0] = gain * w**2
        C[0, 2 * i] = 1.0
    return _zoh(A, B, C, np.zeros((1, 1)), sample_time)


@dataclass
class CameraLoopExperiment:
    """A record of a camera in the loop, see :func:`simulate_camera_loop`.

    Attributes
    ----------
    excitation : ndarray of shape (N,)
        ``r``, added to the held controller output at the fast rate.
    u : ndarray of shape (N,)
        The plant input ``r + hold(c)``.
    y_fast : ndarray of shape (N,)
        The plant output at the fast rate, noise-free.
    y_slow : ndarray of shape (M,)
        The frames: ``y_fast[offset + m factor]`` plus the disturbance.
    disturbance : ndarray of shape (M,)
        What was added to the frames (coloured vibration plus white noise).
    controller_output : ndarray of shape (M,)
        ``c[m]``, the controller's output computed from frame ``m``.
    factor, offset, delay : int
    sample_time : float
    feedback : bool
        Whether the loop was closed (False: ``u = r``, an open-loop experiment).
    system : DiscreteSystem
    """

    excitation: np.ndarray
    u: np.ndarray
    y_fast: np.ndarray
    y_slow: np.ndarray
    disturbance: np.ndarray
    controller_output: np.ndarray
    factor: int
    offset: int
    delay: int
    sample_time: float
    feedback: bool
    system: DiscreteSystem

    @property
    def sample_indices(self) -> np.ndarray:
        """The fast index of each frame."""
        return self.offset + self.factor * np.arange(self.y_slow.shape[0])


def frame_disturbance(n_frames: int, frame_time: float, band=(8.0, 14.0), rms: float = 0.05,
                      noise_std: float = 0.005,
                      random_state: RandomStateLike = None) -> np.ndarray:
    """A band-limited vibration plus white noise, one value per frame.

    Gaussian white noise through a fourth-order Butterworth band-pass over
    ``band`` (Hz, at the frame rate ``1 / frame_time``), scaled to ``rms``,
    plus white noise of standard deviation ``noise_std``; ``band=None``: the
    white noise alone.

    Examples
    --------
    >>> v = frame_disturbance(1000, 0.01, rms=0.1, noise_std=0.0, random_state=0)
    >>> round(float(np.sqrt(np.mean(v**2))), 6)
    0.1
    """
    n_frames = _check_positive_int(n_frames, "n_frames")
    frame_time = _check_positive(frame_time, "frame_time")
    noise_std = check_positive(noise_std, "noise_std", allow_zero=True)
    rng = _check_random_state(random_state)
    v = np.zeros(n_frames)
    if band is not None:
        low, high = (float(b) for b in band)
        if not 0 < low < high < 0.5 / frame_time:
            raise ValueError(f"band must be (low, high) with 0 < low < high < the frame rate's "
                             f"Nyquist frequency {0.5 / frame_time:g} Hz; got {band!r}")
        rms = check_positive(rms, "rms", allow_zero=True)
        sos = signal.butter(4, [low, high], btype="bandpass", fs=1.0 / frame_time, output="sos")
        burn_in = int(np.ceil(20.0 / (low * frame_time)))  # the filter's start forgotten
        vibration = signal.sosfilt(sos, rng.standard_normal(n_frames + burn_in))[burn_in:]
        v = rms * vibration / np.sqrt(np.mean(vibration**2))
    return v + noise_std * rng.standard_normal(n_frames)


def simulate_camera_loop(system: DiscreteSystem, excitation, factor: int, controller=1.5,
                         delay: int = 1, disturbance=None, offset: int = 0,
                         feedback: bool = True,
                         random_state: RandomStateLike = None) -> CameraLoopExperiment:
    """A camera closing a loop around a fast-rate plant, excited at the fast rate.

    Frame ``m`` is ``y_slow[m] = y(n_m) + v[m]`` at ``n_m = offset + m factor``;
    a controller at the frame rate reads the error ``-y_slow`` (regulation to
    zero) and its output ``c[m]`` is held over frame ``m + delay`` (a
    zero-order hold from ``n_{m+delay}`` to ``n_{m+delay+1} - 1``); the
    plant input is ``u = r + hold(c)``.  The disturbance ``v`` on the frames
    (vibration, drift, measurement noise) enters the input through the
    loop: ``u`` depends on past disturbance, and a fit that takes ``u`` as
    given is biased where the loop acts.  The excitation ``r`` is
    independent of ``v``.

    Parameters
    ----------
    system : DiscreteSystem
        The plant at the fast rate (e.g. :func:`camera_loop_plant`).
    excitation : array-like of shape (N,)
        ``r`` at the fast rate.
    factor : int
        Fast samples per frame.
    controller : float, array-like, scipy.signal.dlti or python-control system, default=1.5
        The controller at the frame rate (:func:`gpmultirate.closedloop.as_controller`).
    delay : int, default=1
        Frames between a frame and the hold of the output computed from it (at least 1).
    disturbance : array-like of shape (M,), optional
        ``v``; by default :func:`frame_disturbance` (an 8-14 Hz vibration of
        rms 0.05 plus white noise of 0.005) at the frame time ``factor T``.
    offset : int, default=0
        Fast index of the first frame.
    feedback : bool, default=True
        False: the same experiment with the loop open (``u = r``).
    random_state : int, Generator or None
        For the default disturbance.

    Returns
    -------
    CameraLoopExperiment

    Examples
    --------
    >>> plant = camera_loop_plant()
    >>> r = np.random.default_rng(0).standard_normal(2000)
    >>> loop = simulate_camera_loop(plant, r, factor=5, random_state=1)
    >>> loop.u.shape, loop.y_slow.shape
    ((2000,), (400,))
    >>> bool(np.allclose(loop.u[5:10], r[5:10] + loop.controller_output[0]))
    True
    """
    from gpmultirate.closedloop.controller import as_controller

    if not isinstance(system, DiscreteSystem):
        raise ValueError(f"system must be a DiscreteSystem; got {type(system).__name__}")
    r = _check_signal(excitation, "excitation")
    factor = _check_positive_int(factor, "factor")
    delay = _check_positive_int(delay, "delay")
    offset = check_int(offset, "offset", low=0, high=factor - 1)
    control = as_controller(controller).stepper()
    N = r.shape[0]
    n_frames = len(range(offset, N, factor))
    if disturbance is None:
        v = frame_disturbance(n_frames, factor * system.sample_time, random_state=random_state)
    else:
        v = _check_signal(disturbance, "disturbance")
        if v.shape[0] != n_frames:
            raise ValueError(f"disturbance must have one value per frame ({n_frames}); "
                             f"got {v.shape[0]}")
    a, b, c_row, d = system.A, system.B[:, 0], system.C[0], system.D[0, 0]
    x = np.zeros(system.order)
    u, y = np.empty(N), np.empty(N)
    y_slow, c = np.empty(n_frames), np.zeros(n_frames)
    held = 0.0
    for n in range(N):
        frame, phase = divmod(n - offset, factor)
        if n >= offset and phase == 0:
            held = c[frame - delay] if (feedback and frame >= delay) else 0.0
        u[n] = r[n] + held
        y[n] = c_row @ x + d * u[n]
        if n >= offset and phase == 0:
            y_slow[frame] = y[n] + v[frame]
            c[frame] = control(-y_slow[frame])
        x = a @ x + b * u[n]
    return CameraLoopExperiment(
        excitation=r, u=u, y_fast=y, y_slow=y_slow, disturbance=v.copy(),
        controller_output=c if feedback else np.zeros(n_frames), factor=factor,
        offset=offset, delay=delay, sample_time=system.sample_time, feedback=bool(feedback),
        system=system)
