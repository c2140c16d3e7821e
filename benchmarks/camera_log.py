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

``PYTHONPATH=. python benchmarks/camera_log.py --logs 3 [--kernel auto]
[--ticks] [--seconds 60]`` runs the command on held-out logs of this shape,
drawn afresh each run (:func:`draw_modes`: modes near 10-15 Hz and 70-90 Hz,
damping 0.015-0.03; ``--seed`` replays a run), and prints per log the wall
and CPU time, the peak memory, the validation fit, the band's share above
55 Hz and the resonances found (false: farther than 5 % from every true
mode).
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
# a resonance found farther than this share of every true mode's frequency is false
FALSE_TOLERANCE = 0.05


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


#: a progress line of the tuning: ``[  49.2 s] still on fit (49 s); ... about 88 s left``
_LEFT = re.compile(r"\[\s*([\d.]+) s\] still on fit .*about (\d+) s left")


def _time_left_lines(stderr: str):
    """``(at, left, start, end)`` of each time-left line of the tuning.

    An estimate is of the tuning under way; the pilot fits of the default
    order are each a tuning of their own, so a run starts where the last
    pilot (or the command's first line) ended and ends at the next line of
    a finished pilot (``default order: fitted order ...``) or the fit's end.
    Lines after the last such end are left out.
    """
    lines = stderr.replace("\r", "\n").splitlines()
    ends = [float(m.group(1)) for line in lines
            for m in [re.search(r"\[\s*([\d.]+) s\] (default order: fitted order|fit: )",
                                line)] if m]
    for line in lines:
        m = _LEFT.search(line)
        if not m:
            continue
        at, left = float(m.group(1)), float(m.group(2))
        later = [end for end in ends if end > at]
        if later:
            yield at, left, max([0.0] + [end for end in ends if end <= at]), later[0]


def estimate_ratios(stderr: str, shortest: float = 10.0) -> list:
    """Each estimate of the fit's time left over the time the fit then took, where that is at least ``shortest`` s.

    The time left is measured to the end of the run the line belongs to
    (:func:`_time_left_lines`).
    """
    return [left / (end - at) for at, left, _, end in _time_left_lines(stderr)
            if end - at >= shortest]


def run_time_ratios(stderr: str) -> list:
    """Each line's estimate of its tuning run's whole time over the time that run took.

    The estimate is the time the run had taken at the line plus the time
    left it announced (runs as in :func:`_time_left_lines`).  Every line
    counts, however close to the end.
    """
    return [(at - start + left) / (end - start)
            for at, left, start, end in _time_left_lines(stderr) if end > start]


def band_share(model, system, above=55.0):
    """The share of the DFT bins above ``above`` Hz where the true ``|G|`` is in the band."""
    freqs = np.fft.rfftfreq(model.observation_.n_samples, SAMPLE_TIME)
    freqs = freqs[freqs > above]
    frf = model.frequency_response(freqs)
    truth = np.abs(system.frequency_response(freqs))
    return float(np.mean((truth >= frf.magnitude_lower) & (truth <= frf.magnitude_upper)))


def draw_modes(rng):
    """Held-out modes of the log's shape: one near 10-15 Hz, one near 70-90 Hz (damping 0.015-0.03).

    The gains are those of :data:`MODES` (1 and 0.5).
    """
    return ((float(rng.uniform(10.0, 15.0)), float(rng.uniform(0.015, 0.03)), 1.0),
            (float(rng.uniform(70.0, 90.0)), float(rng.uniform(0.015, 0.03)), 0.5))


# ``python -m gpmultirate`` that prints its own peak resident memory last: the children's
# ``ru_maxrss`` of this process is the largest of every command run so far, not this one's,
# and a child's own ``ru_maxrss`` starts from the forking process's size (Linux keeps it
# across exec); the high-water mark of its memory map (``VmHWM``) is its own
_OWN_PEAK = (
    "import resource, runpy, sys\n"
    "def _peak_kb():\n"
    "    try:\n"
    "        with open('/proc/self/status') as status:\n"
    "            for line in status:\n"
    "                if line.startswith('VmHWM:'):\n"
    "                    return int(line.split()[1])\n"
    "    except OSError:\n"
    "        pass\n"
    "    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
    "try:\n"
    "    runpy.run_module('gpmultirate', run_name='__main__', alter_sys=True)\n"
    "finally:\n"
    "    print(f'peak-rss-kb {_peak_kb()}', file=sys.stderr)\n"
)


def run_command(seconds=20.0, ticks=False, seed=0, extra=(), timeout=3600, modes=MODES):
    """``gpmultirate fit`` on one camera log in a fresh process: times, memory and accuracy."""
    import gpmultirate as gm

    log = camera_log(seconds, ticks, seed, modes=modes)
    with tempfile.TemporaryDirectory() as folder:
        fast, camera = write_files(log, folder)
        out = Path(folder) / "res"
        command = [sys.executable, "-c", _OWN_PEAK, "fit", str(fast), "--input", "u",
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
        peak = re.findall(r"^peak-rss-kb (\d+)$", done.stderr, flags=re.MULTILINE)
    gof = gm.goodness_of_fit(log["y_val"], model.predict(log["u_val"]))
    found = [float(r.frequency_hz) for r in (getattr(model, "resonances_", None) or [])]
    return {"seconds": seconds_taken,
            "cpu_seconds": (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime),
            "command_peak_mb": int(peak[-1]) / 1024, "gof": gof,
            "band_share_above_55hz": band_share(model, log["system"]),
            "order": int(model.coef_.shape[-1]), "frames": int(log["y"].shape[0]),
            "steps": step_times(done.stderr), "progress": done.stderr[-4000:],
            "estimate_ratios": estimate_ratios(done.stderr),
            "run_time_ratios": run_time_ratios(done.stderr),
            "resonances_hz": found,
            "false_resonances_hz": [f for f in found if not any(
                abs(f - hz) <= FALSE_TOLERANCE * hz for hz, _, _ in modes)]}


def after_fit_share(steps: dict) -> float:
    """The time of the steps after the fit over the fit's (:func:`step_times`).

    Examples
    --------
    >>> after_fit_share({"fit": 40.0, "bands": 2.0, "state space": 6.0, "total": 48.0})
    0.2
    """
    return sum(t for name, t in steps.items() if name not in ("fit", "total")) / steps["fit"]


def _steps(steps: dict) -> str:
    return ", ".join(f"{name} {t:.1f} s" for name, t in steps.items()) or "-"


def _span(ratios) -> str:
    return f"{min(ratios):.2f}-{max(ratios):.2f} ({len(ratios)})" if ratios else "-"


def main(argv=None) -> int:
    """Held-out logs: ``--logs`` fresh draws of :func:`draw_modes`, the command on each."""
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--logs", type=int, default=3, help="held-out logs (default 3)")
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--ticks", action="store_true", help="frames on the ticks, no exposure")
    parser.add_argument("--seed", type=int, default=None, help="replay a run")
    parser.add_argument("--kernel", default=None, help="the command's --kernel (e.g. auto)")
    args = parser.parse_args(argv)
    seed = int(np.random.SeedSequence().entropy % 2**31) if args.seed is None else args.seed
    print(f"held-out camera logs: seed {seed} (replay with --seed {seed}), {args.seconds:g} s, "
          f"{'ticks' if args.ticks else 'own clock, exposure 2 ms'}, kernel "
          f"{args.kernel or 'default'}; load {os.getloadavg()[0]:.1f}", flush=True)
    rng = np.random.default_rng(seed)
    extra = () if args.kernel is None else ("--kernel", args.kernel)
    print("modes (Hz, damping) | wall s | CPU s | peak MB | order | fit % | band > 55 Hz | "
          "found Hz | false | time-left estimates / actual (10 s or more left) | "
          "estimated run times / actual", flush=True)
    rows = []
    for _ in range(args.logs):
        modes = draw_modes(rng)
        row = run_command(args.seconds, args.ticks, int(rng.integers(2**31)), extra,
                          modes=modes)
        rows.append(row)
        shown = ", ".join(f"{hz:.2f}/{zeta:.3f}" for hz, zeta, _ in modes)
        print(f"{shown} | {row['seconds']:.1f} | {row['cpu_seconds']:.1f} | "
              f"{row['command_peak_mb']:.0f} | {row['order']} | {row['gof']:.3f} | "
              f"{row['band_share_above_55hz']:.3f} | "
              f"{', '.join(f'{f:.2f}' for f in row['resonances_hz']) or '-'} | "
              f"{len(row['false_resonances_hz'])} | "
              f"{_span(row['estimate_ratios'])} | {_span(row['run_time_ratios'])}", flush=True)
        print(f"    steps: {_steps(row['steps'])}", flush=True)
    print(f"worst: wall {max(r['seconds'] for r in rows):.1f} s, peak "
          f"{max(r['command_peak_mb'] for r in rows):.0f} MB, fit "
          f"{min(r['gof'] for r in rows):.3f} %, band "
          f"{min(r['band_share_above_55hz'] for r in rows):.3f}, false resonances "
          f"{sum(len(r['false_resonances_hz']) for r in rows)}, time-left estimates / actual "
          f"{_span([x for r in rows for x in r['estimate_ratios']])}, estimated run times / "
          f"actual {_span([x for r in rows for x in r['run_time_ratios']])}, the steps after "
          f"the fit / the fit {_span([after_fit_share(r['steps']) for r in rows if r['steps']])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
