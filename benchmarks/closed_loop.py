"""Closed-loop data: the direct fit, the fit with the excitation, and the open-loop experiment.

Each run simulates a 100 Hz camera closing a proportional loop (gain 1.5,
one frame of delay) around :func:`gpmultirate.simulation.camera_loop_plant`
(modes near 4 Hz and 76 Hz, fast rate 500 Hz, ``factor = 5``), excited by
white noise ``r`` (rms 0.3) added to the held controller output, with an
8-14 Hz vibration (rms 0.05) plus white noise (0.005) on the frames.  The
same excitation and disturbance drive an open-loop experiment (``u = r``).
Three default fits (``FIRGaussianProcess(factor=5, sample_time=T)``):

* ``open loop``: the open-loop experiment, ``fit(r, y_slow_open)``;
* ``direct``: the loop's record taken as open loop, ``fit(u, y_slow)``;
* ``excitation``: ``fit(u, y_slow, excitation=r)``.

Reported per fit, as the median over runs: the median ``| |G_hat| - |G_0| |``
over 300 frequencies below and above the slow Nyquist frequency (50 Hz, up
to the fast one, 250 Hz), the share of those frequencies whose 95 % band
holds ``|G_0|``, and the fit time; and the share of runs in which the fit
warned with a :class:`~gpmultirate.FeedbackWarning` (detection).  Run from
the repository root::

    PYTHONPATH=. python benchmarks/closed_loop.py [--runs R] [--seconds S] [--seed S0]
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import gpmultirate as gm
from gpmultirate import simulation as sim

SAMPLE_TIME, FACTOR = 1 / 500, 5


def _fit(u, y_slow, **extra):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        start = time.perf_counter()
        model = gm.FIRGaussianProcess(factor=FACTOR, sample_time=SAMPLE_TIME).fit(
            u, y_slow, **extra)
        seconds = time.perf_counter() - start
    warned = any(issubclass(w.category, gm.FeedbackWarning) for w in caught)
    return model, seconds, warned


def _scores(model, plant, freqs):
    frf = model.frequency_response(freqs)
    truth = np.abs(plant.frequency_response(freqs))
    error = np.abs(frf.magnitude - truth)
    inside = frf.contains(truth) if hasattr(frf, "contains") else (
        (truth >= frf.magnitude_lower) & (truth <= frf.magnitude_upper))
    below = freqs < 0.5 / (FACTOR * SAMPLE_TIME)
    return [np.median(error[below]), np.median(error[~below]),
            np.mean(inside[below]), np.mean(inside[~below])]


def run(runs: int, seconds: float, seed: int):
    plant = sim.camera_loop_plant(SAMPLE_TIME)
    n = int(round(seconds / SAMPLE_TIME))
    freqs = np.linspace(0.5, 249.5, 300)
    rows = {name: [] for name in ("open loop", "direct", "excitation")}
    for k in range(runs):
        rng = np.random.default_rng(seed + k)
        r = 0.3 * rng.standard_normal(n)
        v = sim.frame_disturbance(len(range(0, n, FACTOR)), FACTOR * SAMPLE_TIME,
                                  random_state=rng)
        closed = sim.simulate_camera_loop(plant, r, FACTOR, disturbance=v)
        open_loop = sim.simulate_camera_loop(plant, r, FACTOR, disturbance=v, feedback=False)
        for name, (u, y, extra) in {
            "open loop": (open_loop.u, open_loop.y_slow, {}),
            "direct": (closed.u, closed.y_slow, {}),
            "excitation": (closed.u, closed.y_slow, {"excitation": r}),
        }.items():
            model, elapsed, warned = _fit(u, y, **extra)
            rows[name].append(_scores(model, plant, freqs) + [elapsed, float(warned)])
        print(f"run {k + 1}/{runs}: " + "; ".join(
            f"{name} err {rows[name][-1][0]:.4f}/{rows[name][-1][1]:.4f} "
            f"cov {rows[name][-1][2]:.2f}/{rows[name][-1][3]:.2f} {rows[name][-1][4]:.2f} s"
            for name in rows), flush=True)
    return {name: np.array(values) for name, values in rows.items()}


def table(results) -> str:
    lines = ["| fit | median abs |G| error < 50 Hz | > 50 Hz | 95 % coverage < 50 Hz | > 50 Hz "
             "| fit time [s] | FeedbackWarning |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    for name, values in results.items():
        med = np.median(values, axis=0)
        lines.append(f"| {name} | {med[0]:.4f} | {med[1]:.4f} | {med[2]:.2f} | {med[3]:.2f} | "
                     f"{med[4]:.2f} | {np.mean(values[:, 5]):.0%} of runs |")
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=6)
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--seed", type=int, default=3700)
    args = parser.parse_args(argv)
    results = run(args.runs, args.seconds, args.seed)
    print(f"\n{args.runs} runs of {args.seconds:g} s, seeds {args.seed}..{args.seed + args.runs - 1}")
    print(table(results))
    ratio = np.median(results["excitation"][:, :2], axis=0) / np.median(
        results["open loop"][:, :2], axis=0)
    time_ratio = np.median(results["excitation"][:, 4] / results["direct"][:, 4])
    print(f"excitation / open-loop error: {ratio[0]:.2f} below, {ratio[1]:.2f} above the slow "
          f"Nyquist frequency; excitation fit time / direct fit time: {time_ratio:.2f}")


if __name__ == "__main__":
    main()
