"""Benchmarks of marginal-likelihood tuning, against plain reference implementations.

Run ``python benchmarks/run.py`` (every case but the camera logs, which take minutes each)
or ``--cases paper_dc paper_pk camera_log``.
The long-record cases also run ``previous``, the same fit with the reduction
reading the rows of ``Phi`` (QR) instead of the Gram matrix by FFT, and the
reduction alone is timed both ways (``reduction_50k``, ``reduction_1m``).
The cases: the paper's size (N = P = 600, factor 3) with the DC and the
DC + 2 PK kernels and ``kernel="auto"`` (timed against the DC fit), the paper's 100-run study (LS over the orders 50..600, DC
and PK at P = N), a long record (N = 50,000, P = 2,000) and P = N = 6,000;
the default fit (everything default, the paper's system at 40 dB, ``N`` of
3,000 to 1,000,000, ``defaults_*``, with the order it chose); a camera record
(N = 20,000, factor 10, modes at 30 and 120 Hz, ``camera_20k``: defaults with
``kernel="auto"``, the default kernel, and order 1,500) and ``gpmultirate fit``
on it end to end against the library fit it wraps (``cli_camera_20k``); the camera log of
``benchmarks/camera_log.py`` (``camera_log``: 20 s of a 1 kHz actuator, a 100 Hz camera on its
own clock with a 2 ms exposure, ``gpmultirate fit`` with the documented options, each step's
time, the command's peak memory, the validation fit and the share of the true ``|G|`` in the
band above 55 Hz; ``camera_log_quick``, 5 s; ``camera_log_ticks``, frames on the ticks;
``camera_log_60s``); and the experiments beyond the paper's, each against the uniform one-input
fit of the same size in the same run: two inputs at paper size, the paper
case with 20 % of the slow samples missing, four records of N = 600, and the
long record with irregular instants (mean spacing 3, jitter +-1); and a
structure with 2 inputs and 28 outputs (N = 8,523, F = 3, P = 200), one
default-kernel fit per output with :class:`gpmultirate.MultiOutputFIR`,
serially and in two processes (ratio against serial); frames of a camera
(``timed_*``: N = 600, P = 300, F = 3, 45 dB) at their own instants and with
an exposure of half a fast period, against the frames on the ticks, and a
long camera record (``timed_long_*``: N = 50,000, P = 2,000, about 16,700
frames) at their own instants (the interpolated route) against the ticks.
``--repeat 3`` runs
every case three times and prints the min/median/max time.
Each case runs in a fresh subprocess so that its peak memory (max RSS) is its own.
Printed: wall time, peak memory, validation goodness of fit, and the time ratio
against

* ``reference``: the paper's formulas written plainly -- the kernel matrix,
  ``Phi K Phi^T + gamma I`` and a Cholesky per evaluation, eq. (15) for the
  estimate, the corrected eq. (19) for the evidence, and
  ``scipy.optimize.minimize(method="L-BFGS-B")`` with finite-difference
  gradients, from the same initial hyperparameters;
* ``sklearn``: scikit-learn's ``GaussianProcessRegressor`` with
  ``ObservedKernel(kernel, observation) + WhiteKernel`` on slow-sample indices.

Results go to ``benchmarks/output/results.json``.  ``--scaling`` adds the fit
time against ``N`` and ``P`` in three regimes (``P = N``; a long record with
``P = 2000`` and growing ``N``; ``N = 50,000`` and growing ``P``), with the
exponent of a power law fitted to each, in ``benchmarks/output/scaling.json``
and ``scaling.png``; ``--draw-scaling scaling.json`` redraws the figure.
``--repeat k`` runs every case ``k`` times and prints min/median/max and the
load average.  Run it from the repository root with ``PYTHONPATH=.`` so that
the package under test is the working copy.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

OUTPUT = Path(__file__).resolve().parent / "output"


# ---------------------------------------------------------------- problems
def paper_problem(n_samples=600, factor=3, seed=0, snr_db=None):
    """One Monte Carlo run of the paper's simulation study at size ``n_samples``.

    The signal-to-noise ratio is drawn in 40..60 dB as in the study, unless
    ``snr_db`` is given.
    """
    from gpmultirate import simulation as sim

    rng = np.random.default_rng(seed)
    system = sim.paper_system(0.1, perturbation=0.1, random_state=rng)
    u = sim.multisine(n_samples, random_state=rng)
    u_val = sim.multisine(n_samples, random_state=rng)
    snr = rng.uniform(40, 60) if snr_db is None else snr_db
    data = sim.simulate_experiment(system, u, factor, snr_db=snr, random_state=rng)
    return data.u, data.y_slow, u_val, system.simulate(u_val)


def camera_problem(n_samples=20_000, factor=10, seed=0, snr_db=40.0):
    """A 1 kHz actuator watched by a 100 Hz camera: ``(u, y_slow, u_val, y_val, sample_time)``.

    Two lightly damped modes, at 30 Hz (damping 3 %) and at 120 Hz (2 %),
    one on each side of the camera's Nyquist frequency (50 Hz); 40 dB of
    fast-rate output noise before every tenth sample is kept; a multisine
    input and a noise-free validation record of the same length.
    """
    from scipy import signal

    from gpmultirate import simulation as sim

    sample_time = 1e-3
    rng = np.random.default_rng(seed)
    blocks = []
    for hz, zeta, gain in ((30.0, 0.03, 1.0), (120.0, 0.02, 0.5)):
        w = 2.0 * np.pi * hz
        blocks.append((np.array([[0.0, 1.0], [-w * w, -2.0 * zeta * w]]),
                       np.array([[0.0], [gain * w * w]])))
    A = np.block([[blocks[0][0], np.zeros((2, 2))], [np.zeros((2, 2)), blocks[1][0]]])
    B = np.vstack([blocks[0][1], blocks[1][1]])
    C = np.array([[1.0, 0.0, 1.0, 0.0]])
    Ad, Bd, Cd, Dd, _ = signal.cont2discrete((A, B, C, np.zeros((1, 1))), sample_time, "zoh")
    system = sim.DiscreteSystem(Ad, Bd, Cd, Dd, sample_time)
    u = sim.multisine(n_samples, sample_time, random_state=rng)
    u_val = sim.multisine(n_samples, sample_time, random_state=rng)
    data = sim.simulate_experiment(system, u, factor, snr_db=snr_db, random_state=rng)
    return data.u, data.y_slow, u_val, system.simulate(u_val), sample_time


def wide_problem(kind, n_samples=600, factor=3, seed=0):
    """``(u, y_slow, sample_indices, u_val, y_val)`` of an experiment beyond the paper's.

    ``kind``: ``"two_inputs"`` (a second, first-order system on a second
    input), ``"missing"`` (20 % of the slow samples NaN), ``"records"`` (four
    records of ``n_samples``), ``"irregular"`` (instants with mean spacing
    ``factor`` and jitter of one sample).
    """
    from gpmultirate import simulation as sim

    rng = np.random.default_rng(seed)
    system = sim.paper_system(0.1, perturbation=0.1, random_state=rng)
    if kind == "records":
        us = [sim.multisine(n_samples, random_state=rng) for _ in range(4)]
        ys = [sim.simulate_experiment(system, u, factor, snr_db=50, random_state=rng).y_slow
              for u in us]
        u_val = sim.multisine(n_samples, random_state=rng)
        return us, ys, None, u_val, system.simulate(u_val)
    u = sim.multisine(n_samples, random_state=rng)
    u_val = sim.multisine(n_samples, random_state=rng)
    y_fast, y_val = system.simulate(u), system.simulate(u_val)
    if kind == "two_inputs":
        second = 0.5 * 0.97 ** np.arange(n_samples)
        u2, u2_val = sim.multisine(n_samples, random_state=rng), sim.multisine(
            n_samples, random_state=rng)
        y_fast = y_fast + np.convolve(u2, second)[:n_samples]
        y_val = y_val + np.convolve(u2_val, second)[:n_samples]
        u, u_val = np.column_stack([u, u2]), np.column_stack([u_val, u2_val])
    if kind == "irregular":
        steps = factor + rng.integers(-1, 2, size=n_samples)
        index = np.cumsum(steps) - steps[0]
        index = index[index < n_samples]
    else:
        index = np.arange(0, n_samples, factor)
    y = y_fast[index]
    y = y + 10 ** (-50 / 20) * np.std(y) * rng.standard_normal(y.shape[0])
    if kind == "missing":
        y[rng.random(y.shape[0]) < 0.2] = np.nan
    sample_indices = index if kind == "irregular" else None
    return u, y, sample_indices, u_val, y_val


# modes (Hz, damping ratio) of the multi-output structure: fast rate 100 Hz, factor 3,
# so the slow Nyquist frequency is 16.7 Hz and the last mode lies above it; each
# mode decays to below 1e-3 within P = 200 samples
STRUCTURE_MODES = ((1.5, 0.4), (6.0, 0.1), (13.0, 0.05), (24.0, 0.03))


def structure_problem(n_samples=8523, n_outputs=28, factor=3, sample_time=0.01, seed=0):
    """A beam-like structure: two actuators, ``n_outputs`` sensors, shared modes.

    Every mode ``w^2 / (s^2 + 2 zeta w s + w^2)`` (zero-order-hold
    discretised) is driven by each actuator with the gain of its mode shape
    at the actuator (``sin((i + 1) pi x)``, actuators at ``x = 0.2, 0.7``)
    and seen by sensor ``j`` at ``x_j = (j + 1/2) / n_outputs`` with the
    same shape: the modes are shared, their shapes differ per output.
    Returns ``(u, y_slow, u_val, y_val)`` with ``u`` of shape ``(N, 2)``,
    ``y_slow`` of shape ``(M, n_outputs)`` (40 dB SNR per output) and the
    noise-free validation output ``y_val`` of shape ``(N, n_outputs)``.
    """
    from scipy import linalg

    from gpmultirate import simulation as sim

    rng = np.random.default_rng(seed)
    actuators, sensors = np.array([0.2, 0.7]), (np.arange(n_outputs) + 0.5) / n_outputs
    u = np.column_stack([sim.multisine(n_samples, sample_time, random_state=rng)
                         for _ in actuators])
    u_val = np.column_stack([sim.multisine(n_samples, sample_time, random_state=rng)
                             for _ in actuators])

    def output(inputs):
        y = np.zeros((n_samples, n_outputs))
        for i, (hz, zeta) in enumerate(STRUCTURE_MODES):
            w = 2 * np.pi * hz
            augmented = np.zeros((3, 3))
            augmented[:2, :2] = [[0.0, 1.0], [-w**2, -2 * zeta * w]]
            augmented[1, 2] = w**2
            transition = linalg.expm(augmented * sample_time)
            mode = sim.DiscreteSystem(transition[:2, :2], transition[:2, 2], [1.0, 0.0], 0.0,
                                      sample_time)
            drive = inputs @ np.sin((i + 1) * np.pi * actuators)
            y += np.outer(mode.simulate(drive), np.sin((i + 1) * np.pi * sensors))
        return y

    y_fast = output(u)
    y_slow = np.column_stack([
        sim.downsample(sim.add_output_noise(y_fast[:, j], 40.0, random_state=rng)[0], factor)
        for j in range(n_outputs)
    ])
    return u, y_slow, u_val, output(u_val)


def paper_kernel(name, T=0.1):
    if name == "auto":  # DC plus the resonances found from the data
        return "auto"
    if name == "default":  # the default kernel: C * DC(0.9, 0.9), scaled from the data
        return None
    from sklearn.gaussian_process.kernels import ConstantKernel as C

    from gpmultirate.kernels import DC, PK

    a, b = np.exp(-0.5 * T), np.exp(-0.1 * T)
    kernel = C(1.0, (1e-12, 1e5)) * DC(alpha=a, beta=b)
    if name == "PK":
        kernel = kernel + PK.from_hz(0.4, T, alpha=a) + PK.from_hz(2.0, T, alpha=a)
    return kernel


# -------------------------------------------------------------- estimators
def fit_ours(kernel, u, y, factor, order, noise=1e-5, noise_kernel="auto"):
    import gpmultirate as gm

    model = gm.FIRGaussianProcess(kernel, factor=factor, order=order, noise_level=noise,
                                  noise_kernel=noise_kernel)
    model.fit(u, y)
    return model.predict


def fit_reference(kernel, u, y, factor, order, noise=1e-5):
    """Eq. (15) and the corrected eq. (19), dense, finite-difference L-BFGS-B."""
    from scipy import linalg, optimize

    Phi = np.zeros((len(range(0, len(u), factor)), order))
    for m, n in enumerate(range(0, len(u), factor)):
        for i in range(min(order, n + 1)):
            Phi[m, i] = u[n - i]
    lags = np.arange(order, dtype=float)[:, None]
    bounds = np.vstack([kernel.bounds, [np.log(1e-12 * np.mean(y**2)), np.log(10 * np.mean(y**2))]])

    def negative_evidence(theta):
        K = kernel.clone_with_theta(theta[:-1])(lags)
        Ky = Phi @ K @ Phi.T + np.exp(theta[-1]) * np.eye(Phi.shape[0])
        try:
            L = linalg.cholesky(Ky, lower=True)
        except linalg.LinAlgError:
            return 1e25
        a = linalg.cho_solve((L, True), y)
        return 0.5 * y @ a + np.log(np.diag(L)).sum()

    theta0 = np.clip(np.append(kernel.theta, np.log(noise)), bounds[:, 0], bounds[:, 1])
    best = optimize.minimize(negative_evidence, theta0, method="L-BFGS-B", bounds=bounds)
    K = kernel.clone_with_theta(best.x[:-1])(lags)
    Ky = Phi @ K @ Phi.T + np.exp(best.x[-1]) * np.eye(Phi.shape[0])
    coef = K @ Phi.T @ np.linalg.solve(Ky, y)
    return lambda u_new: np.convolve(u_new, coef)[: len(u_new)]


def fit_sklearn(kernel, u, y, factor, order, noise=1e-5):
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import WhiteKernel

    import gpmultirate as gm

    operator = gm.DownsampledConvolution(u, factor, order)
    power = np.mean(y**2)
    gp_kernel = gm.ObservedKernel(kernel, operator) + WhiteKernel(
        noise, (1e-12 * power, 10 * power)
    )
    X = np.arange(operator.n_outputs)[:, None]
    gpr = GaussianProcessRegressor(gp_kernel, alpha=1e-12).fit(X, y)
    fitted = gpr.kernel_.k1
    K = fitted.kernel(operator.lags)
    coef = K @ operator.matrix.T @ gpr.alpha_
    return lambda u_new: np.convolve(u_new, coef)[: len(u_new)]


FITTERS = {"ours": fit_ours, "reference": fit_reference, "sklearn": fit_sklearn}


# ------------------------------------------------------------------- cases
def paper_case(kernel_name, implementation, n_samples=600, **options):
    from gpmultirate import goodness_of_fit

    u, y, u_val, y_val = paper_problem(n_samples)
    start = time.perf_counter()
    predict = FITTERS[implementation](paper_kernel(kernel_name), u, y, 3, n_samples, **options)
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "gof": goodness_of_fit(y_val, predict(u_val))}


def study_case(n_runs=100):
    """The paper's study: LS over the orders 50..600, DC and PK at P = N = 600."""
    from gpmultirate.study import PAPER_ORDERS, run_paper_study

    start = time.perf_counter()
    common = dict(n_runs=n_runs, n_jobs=2, random_state=0, progress=False)
    ls = run_paper_study(orders=PAPER_ORDERS, methods=("LS",), **common)
    kernels = run_paper_study(orders=(600,), methods=("DC", "PK"), **common)
    seconds = time.perf_counter() - start
    gof = {m: float(np.nanmean(kernels.gof[m][:, -1])) for m in ("DC", "PK")}
    gof["LS best"] = float(np.nanmean(np.nanmax(ls.gof["LS"], axis=1)))
    warnings_count = int(sum(kernels.n_warnings[m].sum() for m in ("DC", "PK")))
    return {"seconds": seconds, "gof": gof, "warnings": warnings_count}


def use_previous_reduction():
    """Make the long-record reduction read the rows of ``Phi`` (QR), as before the Gram by FFT."""
    from gpmultirate.observations import reduced

    original = reduced.ReducedObservation.__init__

    def qr_only(self, observation, y, block_rows=None, method="auto"):
        original(self, observation, y, block_rows, "qr")

    reduced.ReducedObservation.__init__ = qr_only


def long_record_case(implementation, n_samples=50_000, order=2000, factor=3):
    """A long record with fixed order: N = 50,000, F = 3, P = 2000 (M = 16,667).

    ``implementation="previous"``: the same fit with the QR reduction of the
    rows of ``Phi`` instead of the Gram matrix by FFT.
    """
    if implementation not in ("ours", "previous"):
        raise ValueError("the dense reference would need the M x M data covariance")
    from gpmultirate import goodness_of_fit

    if implementation == "previous":
        use_previous_reduction()
    u, y, u_val, y_val = paper_problem(n_samples, factor)
    start = time.perf_counter()
    predict = fit_ours(paper_kernel("DC"), u, y, factor, order)
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "gof": goodness_of_fit(y_val, predict(u_val))}


def defaults_case(n_samples, factor=3):
    """Everything default: one input, factor 3, the paper's system at 40 dB, ``n_samples`` long.

    The default order is chosen from the data (:func:`gpmultirate.orders.default_order`);
    the result reports it.
    """
    import gpmultirate as gm

    u, y, u_val, y_val = paper_problem(n_samples, factor, snr_db=40.0)
    start = time.perf_counter()
    model = gm.FIRGaussianProcess(factor=factor).fit(u, y)
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "gof": gm.goodness_of_fit(y_val, model.predict(u_val)),
            "order": int(model.coef_.shape[-1])}


def camera_case(implementation, n_samples=20_000, order=None):
    """The camera record (:func:`camera_problem`) fitted by the library.

    ``ours``: everything default with ``kernel="auto"``; ``default_kernel``:
    everything default; ``order_1500``: the default kernel at order 1,500
    (or ``order``), a well-chosen order to compare the goodness of fit with.
    """
    import gpmultirate as gm

    u, y, u_val, y_val, sample_time = camera_problem(n_samples)
    kernel = "auto" if implementation == "ours" else None
    if implementation == "order_1500":
        order = order or 1500
    start = time.perf_counter()
    model = gm.FIRGaussianProcess(kernel, factor=10, order=order,
                                  sample_time=sample_time).fit(u, y)
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "gof": gm.goodness_of_fit(y_val, model.predict(u_val)),
            "order": int(model.coef_.shape[-1]),
            "resonances": len(getattr(model, "resonances_", []))}


def cli_camera_case(implementation, n_samples=20_000):
    """``gpmultirate fit`` end to end on the camera record, against the library fit it wraps.

    The record is written as a CSV (the output column empty between the
    camera's frames); ``fit_seconds`` is the library fit with the
    command's settings (defaults) in the same process, ``seconds`` the
    command from reading the file to the last file written.
    """
    import contextlib
    import io
    import tempfile

    import gpmultirate as gm
    from gpmultirate.cli import main

    u, y, _, _, sample_time = camera_problem(n_samples)
    start = time.perf_counter()
    gm.FIRGaussianProcess(factor=10, sample_time=sample_time).fit(u, y)
    fit_seconds = time.perf_counter() - start
    with tempfile.TemporaryDirectory() as folder:
        data = Path(folder) / "camera.csv"
        rows = [f"{a:.17g},{y[k // 10]:.17g}" if k % 10 == 0 else f"{a:.17g},"
                for k, a in enumerate(u)]
        data.write_text("u,y\n" + "\n".join(rows) + "\n", encoding="utf-8")
        start = time.perf_counter()
        with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
            status = main(["fit", str(data), "--input", "u", "--output", "y", "--sample-time",
                           repr(sample_time), "--out", str(Path(folder) / "out")])
        seconds = time.perf_counter() - start
    if status != 0:
        raise RuntimeError(f"gpmultirate fit ended with status {status}")
    return {"seconds": seconds, "gof": float("nan"), "fit_seconds": fit_seconds,
            "ratio_to_fit": seconds / fit_seconds}


def evaluation_case(implementation, n_samples=50_000, order=2000, factor=3, repeat=3):
    """One evaluation of the evidence and its gradient on the reduced long record.

    ``ours``: through DC's tridiagonal precision; ``previous``: the data-space
    route on ``R K R^T + gamma I`` (the terms offer no precision).  The
    median of ``repeat`` evaluations in one process.
    """
    import gpmultirate as gm
    from gpmultirate.inference import LogEvidence

    if implementation == "previous":
        from gpmultirate.kernels import structure

        structure.ObservedTerm.precision = lambda self: None
        structure.ScaledTerm.precision = lambda self: None
    u, y, _, _ = paper_problem(n_samples, factor)
    observation = gm.DownsampledConvolution(u, factor, order)
    kernel = paper_kernel("DC")
    evidence = LogEvidence(observation, y, kernel, 1e-5 * np.var(y), (1e-12, 1e3))
    theta = evidence.theta
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        value, _ = evidence(theta, eval_gradient=True)
        times.append(time.perf_counter() - start)
    return {"seconds": float(np.median(times)), "min": min(times), "max": max(times),
            "gof": float("nan"), "value": value}


def reduction_case(implementation, n_samples=50_000, order=2000, factor=3):
    """The long-record reduction alone: the Gram matrix by FFT and Cholesky, or QR of the rows."""
    import gpmultirate as gm
    from gpmultirate.observations import ReducedObservation

    u, y, _, _ = paper_problem(n_samples, factor)
    observation = gm.DownsampledConvolution(u, factor, order)
    start = time.perf_counter()
    reduced = ReducedObservation(observation, y, method="auto" if implementation == "ours" else "qr")
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "gof": float("nan"), "route": reduced.route}


def wide_case(kind, implementation, n_samples=600, order=None):
    """An experiment beyond the paper's, DC kernel (one per input), ML-tuned."""
    if implementation != "ours":
        raise ValueError("only ours: the reference is the uniform one-input fit")
    import gpmultirate as gm
    from gpmultirate import goodness_of_fit

    u, y, index, u_val, y_val = wide_problem(kind, n_samples)
    kernel = paper_kernel("DC")
    factor = 3
    start = time.perf_counter()
    model = gm.FIRGaussianProcess(kernel, factor=factor, order=order or n_samples,
                                  noise_level=1e-5).fit(u, y, sample_indices=index)
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "gof": goodness_of_fit(y_val, model.predict(u_val))}


def camera_log_case(seconds, ticks, order=None):
    """``gpmultirate fit`` on a camera log (:mod:`camera_log`): steps, memory and accuracy.

    ``order`` (``--order`` of this script) is passed to the command; by
    default the command chooses it.
    """
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from camera_log import run_command

    result = run_command(seconds, ticks, extra=() if order is None else ("--order", str(order)))
    result.pop("progress")
    return result


def timed_case(kind, implementation, n_samples=600, order=300, exposure=0.5):
    """Frames of the paper's system (45 dB, factor 3, default kernel, ML-tuned).

    ``kind``: ``"ticks"`` (on the fast ticks, ``sample_indices``),
    ``"instants"`` (at an instant drawn inside each third fast period,
    ``sample_times``) or ``"exposure"`` (those instants with an exposure of
    half a fast period, modelled), simulated exactly between the ticks as in
    ``examples/camera_frames.py``.
    """
    if implementation != "ours":
        raise ValueError("only ours: the reference is the fit on the ticks")
    import importlib.util

    import gpmultirate as gm
    from gpmultirate import simulation

    path = Path(__file__).resolve().parent.parent / "examples" / "camera_frames.py"
    spec = importlib.util.spec_from_file_location("camera_frames", path)
    frames = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(frames)
    rng = np.random.default_rng(0)
    A, B, C = frames.continuous_system(rng)
    u = simulation.multisine(n_samples, random_state=rng)
    u_val = simulation.multisine(n_samples, random_state=rng)
    truth = frames.held_output(A, B, C, u_val, np.arange(n_samples, dtype=float))
    starts = np.arange(0, n_samples, 3)
    instants = starts + rng.uniform(0.0, 1.0, starts.shape[0])
    times = starts.astype(float) if kind == "ticks" else instants
    y = frames.held_output(A, B, C, u, times, exposure=exposure if kind == "exposure" else 0.0)
    y = y + np.sqrt(np.var(y) / 10**4.5) * rng.standard_normal(y.shape[0])
    start = time.perf_counter()
    if kind == "ticks":
        model = gm.FIRGaussianProcess(order=order).fit(u, y, sample_indices=starts)
    else:
        model = gm.FIRGaussianProcess(order=order, exposure=exposure if kind == "exposure"
                                      else 0.0).fit(u, y, sample_times=times)
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "gof": gm.goodness_of_fit(truth, model.predict(u_val))}


def multi_output_case(implementation, n_samples=8523, order=200):
    """2 inputs, 28 outputs, N = 8,523, F = 3, P = 200: one default-kernel fit per output.

    ``serial`` fits the outputs one after the other, ``n_jobs_2`` in two
    loky processes; the peak memory is the largest of this process and of
    the worker processes (shut down before it is read).
    """
    import gpmultirate as gm
    from gpmultirate import goodness_of_fit

    n_jobs = {"serial": 1, "n_jobs_2": 2}[implementation]
    u, y_slow, u_val, y_val = structure_problem(n_samples)
    estimator = gm.FIRGaussianProcess(factor=3, order=order, sample_time=0.01)
    start = time.perf_counter()
    model = gm.MultiOutputFIR(estimator, n_jobs=n_jobs).fit(u, y_slow)
    seconds = time.perf_counter() - start
    from joblib.externals.loky import get_reusable_executor

    get_reusable_executor().shutdown(wait=True)
    own, workers = (resource.getrusage(who)
                    for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    workers_mb = workers.ru_maxrss / 1024
    # CPU time of this process and its workers, simulation included: on a busy
    # machine it shows the work done where wall times only show the waiting
    cpu_seconds = own.ru_utime + own.ru_stime + workers.ru_utime + workers.ru_stime
    predicted = model.predict(u_val)
    gof = [goodness_of_fit(y_val[:, j], predicted[:, j]) for j in range(y_val.shape[1])]
    return {"seconds": seconds, "gof": float(np.mean(gof)), "gof_min": float(np.min(gof)),
            "workers_mb": workers_mb, "cpu_seconds": cpu_seconds}


CASES = {
    "paper_dc": ("paper size N = P = 600, F = 3, DC", ["ours", "reference", "sklearn"]),
    "paper_pk": ("paper size, DC + 2 PK", ["ours", "reference"]),
    "paper_default": ("paper size, default kernel (C * DC)", ["ours"]),
    "paper_auto": ("paper size, kernel='auto' (vs default)", ["ours"]),
    "paper_dc_white": ("paper size, DC, noise_kernel='white'", ["ours"]),
    "paper_dc_auto": ("paper size, DC, noise_kernel='auto' (vs white)", ["ours"]),
    "paper_default_white": ("paper size, default kernel, noise_kernel='white'", ["ours"]),
    "paper_default_auto": ("paper size, default kernel, noise_kernel='auto' (vs white)",
                           ["ours"]),
    "study_100": ("100-run Monte Carlo study", ["ours"]),
    "long_record": ("long record N = 50,000, P = 2,000, DC", ["ours", "previous"]),
    "reduction_50k": ("reduction alone, N = 50,000, P = 2,000", ["ours", "previous"]),
    "million": ("N = 1,000,000, P = 2,000, F = 10, DC", ["ours", "previous"]),
    "reduction_1m": ("reduction alone, N = 1,000,000, F = 10", ["ours", "previous"]),
    "evaluation_50k": ("one evidence + gradient, reduced N = 50,000", ["ours", "previous"]),
    "m_equals_p_2000": ("M = P = 2,000 (N = 6,000, F = 3), DC", ["ours"]),
    "p_equals_n_6000": ("P = N = 6000 (M = 2000), DC", ["ours"]),
    "two_inputs": ("two inputs, N = P = 600, F = 3, DC", ["ours"]),
    "missing_20": ("paper size, 20 % slow samples missing", ["ours"]),
    "uniform_2400": ("one record N = 2400, P = 600 (same size)", ["ours"]),
    "four_records": ("four records of N = 600, P = 600", ["ours"]),
    "long_irregular": ("long record, irregular instants", ["ours"]),
    "multi_output_28": ("2 inputs, 28 outputs, N = 8,523, P = 200", ["serial", "n_jobs_2"]),
    "timed_ticks": ("frames on the ticks, N = 600, P = 300, F = 3", ["ours"]),
    "timed_instants": ("frames at their own instants (vs ticks)", ["ours"]),
    "timed_exposure": ("own instants, exposure T/2 modelled (vs ticks)", ["ours"]),
    "timed_long_ticks": ("frames on the ticks, N = 50,000, P = 2,000, F = 3", ["ours"]),
    "timed_long_instants": ("the same at own instants, interpolated (vs ticks)", ["ours"]),
    "defaults_3k": ("defaults, 40 dB, N = 3,000, F = 3", ["ours"]),
    "defaults_30k": ("defaults, 40 dB, N = 30,000, F = 3", ["ours"]),
    "defaults_300k": ("defaults, 40 dB, N = 300,000, F = 3", ["ours"]),
    "defaults_1m": ("defaults, 40 dB, N = 1,000,000, F = 3", ["ours"]),
    "camera_20k": ("camera N = 20,000, F = 10, defaults, kernel='auto'",
                   ["ours", "default_kernel", "order_1500"]),
    "cli_camera_20k": ("gpmultirate fit on the camera record (vs its library fit)", ["ours"]),
    "camera_log": ("camera log 20 s, own clock, exposure 2 ms, command", ["ours"]),
    "camera_log_quick": ("camera log 5 s, own clock, exposure 2 ms, command", ["ours"]),
    "camera_log_ticks": ("camera log 20 s, frames on the ticks, command", ["ours"]),
    "camera_log_ticks_quick": ("camera log 5 s, frames on the ticks, command", ["ours"]),
    "camera_log_60s": ("camera log 60 s, own clock, exposure 2 ms, command", ["ours"]),
}
#: the record length (seconds) and frames on the ticks of each camera-log case
CAMERA_LOGS = {"camera_log": (20.0, False), "camera_log_quick": (5.0, False),
               "camera_log_ticks": (20.0, True), "camera_log_ticks_quick": (5.0, True),
               "camera_log_60s": (60.0, False)}
#: the record length of each case of the default fit
DEFAULTS_SIZES = {"defaults_3k": 3000, "defaults_30k": 30_000, "defaults_300k": 300_000,
                  "defaults_1m": 1_000_000}
# the implementation a case's ratios are against, when it is not "ours"
BASELINES = {"multi_output_28": "serial"}
# each experiment beyond the paper's and its uniform one-input reference of the same size
WIDE_REFERENCES = {
    "two_inputs": "paper_dc", "missing_20": "paper_dc", "four_records": "uniform_2400",
    "long_irregular": "long_record", "paper_auto": "paper_default",
    "paper_dc_auto": "paper_dc_white", "paper_default_auto": "paper_default_white",
    "timed_instants": "timed_ticks", "timed_exposure": "timed_ticks",
    "timed_long_instants": "timed_long_ticks",
}


def run_case(name, implementation, n_samples=None, order=None):
    if name == "paper_dc":
        return paper_case("DC", implementation, n_samples or 600)
    if name == "paper_auto":
        return paper_case("auto", implementation, n_samples or 600)
    if name == "paper_default":
        return paper_case("default", implementation, n_samples or 600)
    if name in ("paper_dc_white", "paper_dc_auto", "paper_default_white", "paper_default_auto"):
        kernel_name, _, noise_kernel = name[len("paper_"):].partition("_")
        return paper_case(kernel_name.upper() if kernel_name == "dc" else kernel_name,
                          implementation, n_samples or 600, noise_kernel=noise_kernel)
    if name == "paper_pk":
        return paper_case("PK", implementation, n_samples or 600)
    if name == "p_equals_n_6000":
        return paper_case("DC", implementation, n_samples or 6000)
    if name == "study_100":
        return study_case()
    if name == "long_record":
        return long_record_case(implementation, n_samples or 50_000, order or 2000)
    if name == "reduction_50k":
        return reduction_case(implementation, n_samples or 50_000, order or 2000)
    if name == "million":
        return long_record_case(implementation, n_samples or 1_000_000, order or 2000, 10)
    if name == "reduction_1m":
        return reduction_case(implementation, n_samples or 1_000_000, order or 2000, 10)
    if name == "evaluation_50k":
        return evaluation_case(implementation, n_samples or 50_000, order or 2000)
    if name == "m_equals_p_2000":
        return long_record_case(implementation, n_samples or 6000, order or 2000)
    if name == "two_inputs":
        return wide_case("two_inputs", implementation, n_samples or 600, order)
    if name == "missing_20":
        return wide_case("missing", implementation, n_samples or 600, order)
    if name == "four_records":
        return wide_case("records", implementation, n_samples or 600, order)
    if name == "uniform_2400":
        return long_record_case(implementation, n_samples or 2400, order or 600)
    if name == "long_irregular":
        return wide_case("irregular", implementation, n_samples or 50_000, order or 2000)
    if name == "multi_output_28":
        return multi_output_case(implementation, n_samples or 8523, order or 200)
    if name.startswith("timed_long_"):
        return timed_case(name[len("timed_long_"):], implementation, n_samples or 50_000,
                          order or 2000)
    if name.startswith("timed_"):
        return timed_case(name[len("timed_"):], implementation, n_samples or 600, order or 300)
    if name in DEFAULTS_SIZES:
        return defaults_case(n_samples or DEFAULTS_SIZES[name])
    if name == "defaults":  # the scaling figure's default fits, of any size
        return defaults_case(n_samples or 3000)
    if name == "camera_20k":
        return camera_case(implementation, n_samples or 20_000, order)
    if name == "cli_camera_20k":
        return cli_camera_case(implementation, n_samples or 20_000)
    if name in CAMERA_LOGS:
        return camera_log_case(*CAMERA_LOGS[name], order=order)
    raise ValueError(f"unknown case {name!r}")


def in_subprocess(name, implementation, n_samples=None, order=None, timeout=1800):
    command = [sys.executable, __file__, "--child", name, implementation]
    if n_samples:
        command += ["--n-samples", str(n_samples)]
    if order:
        command += ["--order", str(order)]
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout} s"}
    if done.returncode != 0:
        return {"error": done.stderr.strip().splitlines()[-1] if done.stderr else "failed"}
    return json.loads(done.stdout.strip().splitlines()[-1])


def repeated(name, implementation, repeat):
    """``repeat`` runs of a case in fresh processes: the median run, with the min, max and load."""
    runs, loads = [], []
    for _ in range(repeat):
        loads.append(os.getloadavg()[0])
        r = in_subprocess(name, implementation)
        if "error" in r:
            return r
        runs.append(r)
    runs.sort(key=lambda r: r["seconds"])
    median = dict(runs[len(runs) // 2])
    median.update(min=runs[0]["seconds"], max=runs[-1]["seconds"],
                  all=[r["seconds"] for r in runs], load=(min(loads), max(loads)),
                  peak_mb=max(r["peak_mb"] for r in runs))
    return median


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=[c for c in CASES if c not in CAMERA_LOGS],
                        choices=list(CASES),
                        help="by default every case but the camera logs (minutes each: "
                             "name them)")
    parser.add_argument("--scaling", action="store_true", help="also time against N")
    parser.add_argument("--repeat", type=int, default=1,
                        help="runs per case and implementation (min/median/max printed)")
    parser.add_argument("--implementations", nargs="+",
                        help="only these implementations (default: all of each case)")
    parser.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    parser.add_argument("--n-samples", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--order", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--scaling-only", nargs="+", metavar="CASE",
                        help="time only the scaling regimes of these cases (e.g. defaults) and "
                             "keep the others from docs/generated/scaling.json")
    parser.add_argument("--draw-scaling", metavar="JSON",
                        help="only redraw the scaling figure from its results file")
    args = parser.parse_args(argv)
    if args.draw_scaling:
        path = Path(args.draw_scaling)
        draw_scaling(json.loads(path.read_text()), path.with_suffix(".png"))
        return 0
    if args.scaling_only:
        earlier = Path(__file__).resolve().parent.parent / "docs" / "generated" / "scaling.json"
        regimes = [r for r in SCALING_REGIMES if r[1] in args.scaling_only]
        scaling(args.repeat, regimes, json.loads(earlier.read_text()))
        return 0
    if args.child:
        warnings.simplefilter("ignore")
        # the package loads its parts on first use: load them before any clock starts,
        # so that a case times its fit, not the imports
        import gpmultirate

        for name in gpmultirate.__all__:
            getattr(gpmultirate, name)
        result = run_case(*args.child, args.n_samples, args.order)
        result["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(json.dumps(result))
        return 0

    OUTPUT.mkdir(exist_ok=True)
    results = {"load_before": os.getloadavg()}
    print(f"load average before: {results['load_before']}")
    print(f"{'case':42s} {'impl':10s} {'time s':>9s} {'peak MB':>8s} {'GoF %':>9s} {'ratio':>7s}")
    for name in args.cases:
        title, implementations = CASES[name]
        if args.implementations:
            implementations = [i for i in implementations if i in args.implementations]
        results[name] = {}
        for implementation in implementations:
            r = repeated(name, implementation, args.repeat)
            results[name][implementation] = r
            ours = results[name].get(BASELINES.get(name, "ours"), {}).get("seconds")
            if "error" in r:
                print(f"{title:42s} {implementation:10s} {r['error']}")
                continue
            ratio = r["seconds"] / ours if ours else float("nan")  # x times slower than ours
            reference = results.get(WIDE_REFERENCES.get(name), {}).get("ours", {})
            if implementation == "ours" and reference.get("seconds"):
                # against the uniform one-input fit of the same size
                ratio = r["seconds"] / reference["seconds"]
            if isinstance(r["gof"], dict):
                print(f"{'':42s} {'':10s} GoF {r['gof']}")
            if "order" in r:
                print(f"{'':42s} {'':10s} default order {r['order']}")
            if "fit_seconds" in r:
                print(f"{'':42s} {'':10s} library fit {r['fit_seconds']:.2f} s; the command "
                      f"takes {r['ratio_to_fit']:.2f} x that")
            if "steps" in r:
                steps = ", ".join(f"{k} {v:.1f} s" for k, v in r["steps"].items())
                print(f"{'':42s} {'':10s} order {r['order']}, {r['frames']} frames; steps: "
                      f"{steps}; CPU {r['cpu_seconds']:.1f} s; the command's peak memory "
                      f"{r['command_peak_mb']:.0f} MB; true |G| in the band above 55 Hz "
                      f"{100 * r['band_share_above_55hz']:.1f} %")
            if "workers_mb" in r:
                print(f"{'':42s} {'':10s} peak MB of a worker process {r['workers_mb']:.0f}; "
                      f"lowest GoF of an output {r['gof_min']:.3f} %; CPU time of the "
                      f"median run {r['cpu_seconds']:.1f} s")
            gof = r["gof"] if isinstance(r["gof"], float) else np.mean(list(r["gof"].values()))
            print(
                f"{title:42s} {implementation:10s} {r['seconds']:9.2f} {r['peak_mb']:8.0f} "
                f"{gof:9.3f} {ratio:7.1f}"
                + (f"  (min/median/max {r['min']:.3g}/{r['seconds']:.3g}/{r['max']:.3g} s, "
                   f"load {r['load'][0]:.1f}..{r['load'][1]:.1f})" if args.repeat > 1 else ""),
                flush=True,
            )
    results["load_after"] = os.getloadavg()
    print(f"load average after: {results['load_after']}")
    if args.scaling:
        results["scaling"] = scaling(args.repeat)
    (OUTPUT / "results.json").write_text(json.dumps(results, indent=2))
    return 0


#: the regimes of the scaling figure: (label, case, [(N, P), ...])
SCALING_REGIMES = (
    ("P = N (M = N/3 <= P)", "paper_dc", [(n, n) for n in (300, 600, 1200, 2400)]),
    ("P = 500, N grows (long record)", "long_record",
     [(n, 500) for n in (12_500, 25_000, 50_000, 100_000, 200_000, 400_000)]),
    ("N = 50,000, P grows (long record)", "long_record",
     [(50_000, p) for p in (125, 250, 500, 1000)]),
    ("defaults, order from the data (F = 3, 40 dB)", "defaults",
     [(n, None) for n in (1000, 3000, 10_000, 30_000, 100_000, 300_000, 1_000_000)]),
)


def scaling(repeat=1, regimes=SCALING_REGIMES, keep=None):
    """Fit time and peak memory against N and P in each regime, with the exponent of a power law.

    Each point is the median of ``repeat`` fits in fresh processes (the peak
    memory is the largest of them; a default fit also records the order it
    chose, ``p``).  ``keep``: the results of an earlier run whose regimes not
    in ``regimes`` are kept as they are (``--scaling-only``).  Writes
    ``scaling.json`` and draws ``scaling.png`` in ``benchmarks/output``.
    """
    OUTPUT.mkdir(exist_ok=True)
    labels = [label for label, _, _ in regimes]
    kept = [r for r in (keep or {}).get("regimes", []) if r["label"] not in labels]
    result = {"load_before": os.getloadavg(), "regimes": kept}
    for label, case, sizes in regimes:
        points = []
        for n, p in sizes:
            times, peaks, chosen = [], [], p
            for _ in range(repeat):
                r = in_subprocess(case, "ours", n, p)
                if "error" in r:
                    break
                times.append(r["seconds"])
                peaks.append(r["peak_mb"])
                chosen = r.get("order", p)
            if not times:
                print(f"{label}: N = {n}, P = {p}: {r['error']}")
                continue
            points.append({"n": n, "p": chosen, "seconds": float(np.median(times)),
                           "min": min(times), "max": max(times), "peak_mb": max(peaks)})
            print(f"{label}: N = {n:7d}, P = {chosen:5d}: {np.median(times):8.2f} s "
                  f"({min(times):.2f}..{max(times):.2f}), {max(peaks):.0f} MB", flush=True)
            regime = {"label": label, "case": case, "points": points,
                      "exponent": power_law_exponent(label, points)}
            partial = dict(result, regimes=result["regimes"] + [regime])
            (OUTPUT / "scaling.json").write_text(json.dumps(partial, indent=2))  # so far
        result["regimes"].append({"label": label, "case": case, "points": points,
                                  "exponent": power_law_exponent(label, points)})
    result["load_after"] = os.getloadavg()
    (OUTPUT / "scaling.json").write_text(json.dumps(result, indent=2))
    draw_scaling(result, OUTPUT / "scaling.png")
    return result


def power_law_exponent(label, points):
    """The slope of ``log(time)`` against ``log(size)``, the size being the one that varies."""
    if len(points) < 2:
        return None
    key = "p" if "P grows" in label else "n"
    x = np.log([pt[key] for pt in points])
    y = np.log([pt["seconds"] for pt in points])
    return float(np.polyfit(x, y, 1)[0])


def draw_scaling(result, path):
    """The figure of :func:`scaling` from its results (``--draw-scaling scaling.json``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, memory) = plt.subplots(1, 2, figsize=(11.0, 4.2))
    for regime, marker in zip(result["regimes"], ("o-", "^-", "s-", "D-")):
        points = regime["points"]
        if not points:
            continue
        key = "p" if "P grows" in regime["label"] else "n"
        x = [pt[key] for pt in points]
        y = [pt["seconds"] for pt in points]
        errors = [[pt["seconds"] - pt["min"] for pt in points],
                  [pt["max"] - pt["seconds"] for pt in points]]
        exponent = regime["exponent"]
        label = regime["label"] + (f", slope {exponent:.2f}" if exponent is not None else "")
        line = ax.errorbar(x, y, yerr=errors, fmt=marker, capsize=2, label=label)
        measured = [(xi, pt["peak_mb"]) for xi, pt in zip(x, points) if "peak_mb" in pt]
        if measured:
            memory.plot(*zip(*measured), marker, color=line[0].get_color(),
                        label=regime["label"])
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("N (fast samples) or P (order), the size that varies")
    ax.set_ylabel("ML-tuned fit time (s)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    memory.set_xscale("log")
    memory.set_yscale("log")
    memory.set_xlabel("N (fast samples) or P (order), the size that varies")
    memory.set_ylabel("peak memory of the fitting process (MB)")
    memory.grid(True, which="both", alpha=0.3)
    if memory.lines:
        memory.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
