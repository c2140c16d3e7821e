"""A camera in the loop: the bias of the direct fit, and its absence with the excitation.

A 100 Hz camera closes a proportional loop (gain 1.5, one frame of delay)
around a plant with modes near 4 Hz and 76 Hz at a fast rate of 500 Hz
(:func:`gpmultirate.simulation.camera_loop_plant`); white noise ``r`` is
added to the held controller output, and an 8-14 Hz vibration disturbs the
frames (:func:`gpmultirate.simulation.simulate_camera_loop`).  The script
fits

* the same excitation and disturbance in an open-loop experiment (``u = r``);
* the loop's record as if it were open loop, ``fit(u, y_slow)``: the
  input depends on past disturbance, the fit is biased where the loop acts,
  and it warns with a ``FeedbackWarning``;
* the loop's record with the excitation, ``fit(u, y_slow, excitation=r)``;

prints the median ``| |G_hat| - |G_0| |`` and the share of frequencies whose
95 % band holds the true plant, below and above the camera's Nyquist
frequency, and draws ``closed_loop.png``: the three magnitude estimates
against the truth, and the loop's gain from ``r`` to the fast output and to
the frames (:func:`gpmultirate.closedloop.intersample_performance`).

Run ``python examples/closed_loop.py [--output DIR] [--quick]``.
"""

from __future__ import annotations

import argparse
import pathlib
import warnings

import matplotlib

matplotlib.use("Agg")  # draw into files only

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import gpmultirate as gm  # noqa: E402
from gpmultirate import simulation as sim  # noqa: E402
from gpmultirate.closedloop import intersample_performance  # noqa: E402
from gpmultirate.plotting import plot_intersample_performance  # noqa: E402
from gpmultirate.plotting.axes import to_db  # noqa: E402

SAMPLE_TIME, FACTOR, GAIN = 1 / 500, 5, 1.5


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--output", type=pathlib.Path, default=pathlib.Path("."))
    parser.add_argument("--quick", action="store_true", help="a 12 s record instead of 20 s")
    return parser.parse_args()


def main():
    args = parse_args()
    args.output.mkdir(parents=True, exist_ok=True)
    seconds = 12.0 if args.quick else 20.0
    n = int(round(seconds / SAMPLE_TIME))
    plant = sim.camera_loop_plant(SAMPLE_TIME)
    rng = np.random.default_rng(37)
    r = 0.3 * rng.standard_normal(n)
    v = sim.frame_disturbance(n // FACTOR, FACTOR * SAMPLE_TIME, random_state=rng)
    loop = sim.simulate_camera_loop(plant, r, FACTOR, controller=GAIN, disturbance=v)
    open_loop = sim.simulate_camera_loop(plant, r, FACTOR, disturbance=v, feedback=False)

    def fit(u, y, **extra):
        return gm.FIRGaussianProcess(factor=FACTOR, sample_time=SAMPLE_TIME).fit(u, y, **extra)

    models = {"open loop": fit(open_loop.u, open_loop.y_slow)}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        models["direct"] = fit(loop.u, loop.y_slow)
    warned = [w for w in caught if issubclass(w.category, gm.FeedbackWarning)]
    print(f"direct fit: FeedbackWarning {'raised' if warned else 'not raised'}")
    models["excitation"] = fit(loop.u, loop.y_slow, excitation=r)

    freqs = np.linspace(0.5, 249.5, 300)
    truth = np.abs(plant.frequency_response(freqs))
    below = freqs < 0.5 / (FACTOR * SAMPLE_TIME)
    print(f"{seconds:g} s at 500 Hz, a 100 Hz camera, loop gain {GAIN}")
    print("| fit | abs |G| error < 50 Hz | > 50 Hz | 95 % coverage < 50 Hz | > 50 Hz |")
    print("|---|---:|---:|---:|---:|")
    fig, (bode, perf_ax) = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
    bode.plot(freqs, to_db(truth), "k--", linewidth=1, label="true plant")
    for name, model in models.items():
        frf = model.frequency_response(freqs)
        error = np.abs(frf.magnitude - truth)
        inside = (truth >= frf.magnitude_lower) & (truth <= frf.magnitude_upper)
        print(f"| {name} | {np.median(error[below]):.4f} | {np.median(error[~below]):.4f} | "
              f"{np.mean(inside[below]):.2f} | {np.mean(inside[~below]):.2f} |")
        bode.plot(freqs, to_db(frf.magnitude), label=name)
    bode.axvline(50.0, color="0.5", linewidth=0.8)
    bode.set_xscale("log")
    bode.set_xlabel("frequency [Hz]")
    bode.set_ylabel("|G| [dB]")
    bode.legend(loc="lower left")
    bode.set_title("plant estimates (camera Nyquist 50 Hz)")

    perf = intersample_performance(models["excitation"], GAIN, n_samples=300, random_state=0)
    plot_intersample_performance(perf, ax=perf_ax)
    gap = np.max(perf.fast.magnitude / np.abs(perf.frames.magnitude))
    print(f"largest ratio of the fast output's gain to the frames' gain: {gap:.1f}")
    fig.savefig(args.output / "closed_loop.png", dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
