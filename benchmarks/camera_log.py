"""The camera log of a new user: ``gpmultirate fit`` end to end on a 1 kHz actuator and a 100 Hz camera.

The record: ``seconds`` of a 1 kHz actuator (band-limited noise, a
fourth-order Butterworth low-pass at 250 Hz), a plant with two lightly
damped modes (12 Hz and 80 Hz, damping 0.02; 80 Hz is above the camera's
50 Hz Nyquist frequency), a 100 Hz camera on its own clock (a period of
10 ms from a start of 0.3 ms, each frame late by up to 0.5 ms of jitter)
whose reading is the mean output over a 2 ms exposure ending at its stamp,
with 40 dB of white noise on the readings.  The output between the ticks is
the plant's under the held input, simulated exactly on a grid of 40 points
per fast period; the exposure's mean integrates it there (the trapezoid's
error is far below the noise).  ``ticks=True`` is the on-ticks variant:
a frame at every tenth tick, no exposure.

:func:`run_command` writes ``fast.csv`` and ``camera.csv`` to a temporary
folder and runs the command the documentation gives in a fresh process
(``python -m gpmultirate``), and reads back from ``res/``: the time of each
step (the command's last line of progress), the peak memory of the
command, the validation fit of the fast output on a held-out input
(eq. 20) and the share of frequencies above 55 Hz at which the true
``|G|`` lies inside the 95 % band of ``|G|``.

Run ``PYTHONPATH=. python benchmarks/run.py --cases camera_log`` (or
``camera_log_quick`` for 5 s of record, ``camera_log_ticks`` and
``camera_log_60s``).
"""

from __future__ import annotations

import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SAMPLE_TIME = 1e-3
FRAME_TIME = 1e-2
EXPOSURE = 2e-3
MODES = ((12.0, 0.02, 1.0), (80.0, 0.02, 0.5))
# points of the exact simulation per fast period
_FINE = 40


def plant(modes=MODES):
    """``(A, B, C)`` of the continuous plant: one second-order block per mode, unit DC gains."""
    blocks = []
    for hz, zeta, gain in modes:
        w = 2.0 * np.pi * hz
        blocks.append((np.array([[0.0, 1.0], [-w * w, -2.0 * zeta * w]]),
                       np.array([[0.0], [gain * w * w]])))
    n = 2 * len(blocks)
    A = np.zeros((n, n))
    for k, (a, _) in enumerate(blocks):
        A[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = a
    B = np.vstack([b for _, b in blocks])
    C = np.tile([1.0, 0.0], len(blocks))[None, :]
    return A, B, C


def actuator(n_samples, rng):
    """Band-limited noise: white noise through a fourth-order Butterworth low-pass at 250 Hz."""
    from scipy import signal

    sos = signal.butter(4, 250.0, fs=1.0 / SAMPLE_TIME, output="sos")
    u = signal.sosfilt(sos, rng.standard_normal(n_samples + 200))[200:]
    return u / np.std(u)


def fine_output(A, B, C, u):
    """The output on a grid of ``_FINE`` points per fast period (the held input), and the grid."""
    from scipy import linalg

    h = SAMPLE_TIME / _FINE
    n = A.shape[0]
    block = linalg.expm(np.block([[A, B], [np.zeros((1, n + 1))]]) * h)
    a, b = block[:n, :n], block[:n, n]
    # the states at the fine points of one period are linear in (x at the tick, u):
    # x(k T + j h) = a^j x(k T) + (sum_{i<j} a^i) b u(k)
    powers = [np.eye(n)]
    for _ in range(_FINE):
        powers.append(a @ powers[-1])
    sums = np.cumsum([np.zeros(n)] + [p @ b for p in powers[:-1]], axis=0)
    x = np.zeros(n)
    ticks = np.empty((u.shape[0] + 1, n))
    for k, value in enumerate(u):
        ticks[k] = x
        x = powers[_FINE] @ x + sums[_FINE] * value
    ticks[-1] = x
    # fine points j = 0.._FINE-1 of period k
    states = (np.einsum("jab,kb->kja", np.array(powers[:_FINE]), ticks[:-1])
              + sums[:_FINE][None, :, :] * u[:, None, None])
    y = (states @ C[0]).reshape(-1)
    y = np.append(y, C[0] @ ticks[-1])
    return y, np.arange(y.shape[0]) * h


def camera_log(seconds=20.0, ticks=False, seed=0, snr_db=40.0, modes=MODES):
    """One camera log and its held-out validation record.

    Returns
    -------
    dict
        ``u`` (fast input), ``t_cam`` and ``y`` (the frames' stamps in
        seconds and readings), ``u_val`` and ``y_val`` (a held-out input
        and its noise-free fast output), ``system`` (the plant held at the
        fast rate, a :class:`gpmultirate.simulation.DiscreteSystem`) and
        ``exposure``.
    """
    from scipy import signal

    from gpmultirate.simulation import DiscreteSystem

    rng = np.random.default_rng(seed)
    n = int(round(seconds / SAMPLE_TIME))
    A, B, C = plant(modes)
    u = actuator(n, rng)
    y_fine, t_fine = fine_output(A, B, C, u)
    if ticks:
        t_cam = np.arange(0, n, int(round(FRAME_TIME / SAMPLE_TIME))) * SAMPLE_TIME
        clean = np.interp(t_cam, t_fine, y_fine)
        exposure = 0.0
    else:
        starts = 3e-4 + np.arange(0.0, seconds, FRAME_TIME)
        t_cam = starts + rng.uniform(0.0, 5e-4, starts.shape[0])
        t_cam = t_cam[(t_cam >= EXPOSURE) & (t_cam < (n - 1) * SAMPLE_TIME)]
        # the mean over [t - E, t] from the integral of the fine output
        step = t_fine[1] - t_fine[0]
        integral = np.concatenate([[0.0], np.cumsum(0.5 * (y_fine[1:] + y_fine[:-1]) * step)])
        clean = (np.interp(t_cam, t_fine, integral)
                 - np.interp(t_cam - EXPOSURE, t_fine, integral)) / EXPOSURE
        exposure = EXPOSURE
    noise = np.sqrt(np.var(clean) / 10 ** (snr_db / 10.0))
    y = clean + noise * rng.standard_normal(clean.shape[0])
    Ad, Bd, Cd, Dd, _ = signal.cont2discrete((A, B, C, np.zeros((1, 1))), SAMPLE_TIME, "zoh")
    system = DiscreteSystem(Ad, Bd, Cd, Dd, SAMPLE_TIME)
    u_val = actuator(n, rng)
    return {"u": u, "t_cam": t_cam, "y": y, "u_val": u_val, "y_val": system.simulate(u_val),
            "system": system, "exposure": exposure}


def write_files(log, folder):
    """``fast.csv`` (column ``u``) and ``camera.csv`` (columns ``t_cam``, ``y``) in ``folder``."""
    folder = Path(folder)
    fast = folder / "fast.csv"
    camera = folder / "camera.csv"
    fast.write_text("u\n" + "\n".join(f"{v:.17g}" for v in log["u"]) + "\n", encoding="utf-8")
    camera.write_text("t_cam,y\n" + "\n".join(f"{t:.17g},{v:.17g}" for t, v in
                                              zip(log["t_cam"], log["y"])) + "\n",
                      encoding="utf-8")
    return fast, camera


#: the final line of the command's progress: ``steps: fit 12.3 s, bands 1.0 s, ...``
_STEPS = re.compile(r"steps: (.*)$", re.MULTILINE)


def step_times(stderr: str) -> dict:
    """The seconds of each step from the command's final line of progress (empty without one)."""
    found = _STEPS.findall(stderr)
    times = {}
    for part in (found[-1].split(",") if found else []):
        words = part.split()  # "state space 1.2 s"
        if len(words) >= 3 and words[-1] == "s":
            times[" ".join(words[:-2])] = float(words[-2])
    return times


def band_share(model, system, above=55.0):
    """The share of the DFT bins above ``above`` Hz where the true ``|G|`` is in the band."""
    freqs = np.fft.rfftfreq(model.observation_.n_samples, SAMPLE_TIME)
    freqs = freqs[freqs > above]
    frf = model.frequency_response(freqs)
    truth = np.abs(system.frequency_response(freqs))
    return float(np.mean((truth >= frf.magnitude_lower) & (truth <= frf.magnitude_upper)))


def run_command(seconds=20.0, ticks=False, seed=0, extra=(), timeout=3600):
    """``gpmultirate fit`` on one camera log in a fresh process: times, memory and accuracy."""
    import gpmultirate as gm

    log = camera_log(seconds, ticks, seed)
    with tempfile.TemporaryDirectory() as folder:
        fast, camera = write_files(log, folder)
        out = Path(folder) / "res"
        command = [sys.executable, "-m", "gpmultirate", "fit", str(fast), "--input", "u",
                   "--sample-time", "0.001", "--slow", str(camera), "--output", "y",
                   "--time", "t_cam", "--out", str(out)]
        if not ticks:
            command += ["--exposure", "0.002"]
        command += list(extra)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        # run from the temporary folder: the package is the one of PYTHONPATH, not of the cwd
        done = subprocess.run(command, capture_output=True, text=True, timeout=timeout,
                              env=dict(os.environ), cwd=folder)
        seconds_taken = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if done.returncode != 0:
            raise RuntimeError(f"gpmultirate fit ended with status {done.returncode}: "
                               f"{done.stderr.strip().splitlines()[-1:]}")
        model = gm.load_model(out / "model.npz")
    gof = gm.goodness_of_fit(log["y_val"], model.predict(log["u_val"]))
    return {"seconds": seconds_taken,
            "cpu_seconds": (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime),
            "command_peak_mb": after.ru_maxrss / 1024, "gof": gof,
            "band_share_above_55hz": band_share(model, log["system"]),
            "order": int(model.coef_.shape[-1]), "frames": int(log["y"].shape[0]),
            "steps": step_times(done.stderr), "progress": done.stderr[-4000:]}
