"""Camera frames at their own instants: off the fast ticks, with exposure and latency.

A camera in the loop takes its frames on its own clock: frame ``m`` is taken
at an instant inside a fast sample period, integrates the light over an
exposure, and may be stamped late.  This script simulates the paper's
two-mass system (Section 5: :func:`gpmultirate.simulation.paper_system`
with +-10 % parameters, T = 0.1 s, a multisine of N = 600 samples, factor 3,
order P = 300, 45 dB) with frames at an instant drawn uniformly inside each
third fast period, and fits

* the ideal the paper assumes: frames on the fast ticks;
* the frames rounded to the nearest tick (the best without ``sample_times``);
* the frames at their own instants, ``fit(u, y, sample_times=t)``, with the
  hyperparameters of the rounded fit (not re-tuned) and tuned;
* frames with an exposure of half a fast period: ignored (instants only)
  and modelled (``exposure=0.5``), both tuned.

It prints the goodness of fit (eq. 20) on a fresh validation multisine for
each, the time of a fit at own instants against one on the ticks, and draws
``camera_frames.png``: the continuous intersample output with its 95 %
band between the ticks (``predict(u, sample_times=t, return_std=True)``)
and the frames at their instants.

Run ``python examples/camera_frames.py [--output DIR] [--quick] [--systems N]``.
"""

from __future__ import annotations

import argparse
import pathlib
import time

import matplotlib

matplotlib.use("Agg")  # draw into files only

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy import linalg  # noqa: E402

import gpmultirate as gm  # noqa: E402
from gpmultirate import simulation  # noqa: E402

DEFAULT_OUTPUT = pathlib.Path(__file__).resolve().parent / "output"
SAMPLE_TIME = 0.1
N_SAMPLES = 600
FACTOR = 3
ORDER = 300
SNR_DB = 45.0
EXPOSURE = 0.5  # fast sample periods


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=pathlib.Path, default=DEFAULT_OUTPUT,
                        help="directory for the figure (default: examples/output)")
    parser.add_argument("--quick", action="store_true", help="one short system")
    parser.add_argument("--systems", type=int, default=4, help="systems to average over")
    return parser.parse_args()


def continuous_system(rng):
    """The perturbed two-mass system in continuous time, and its zero-order-hold discretization."""
    params = simulation.perturb_parameters(simulation.PAPER_PARAMETERS, 0.1, rng)
    A, B, C, _ = simulation.two_mass_spring_damper(**params)
    return A, B, C


def held_output(A, B, C, u, times, exposure=0.0, nodes=32):
    """The output of the held input at real ``times`` (in fast periods), window-averaged.

    ``u[n]`` acts over ``[n T, (n + 1) T)``; inside a period the state moves by
    the exact zero-order-hold solution over the part of the period elapsed.
    """
    n = A.shape[0]

    def step(duration):
        augmented = np.zeros((n + 1, n + 1))
        augmented[:n, :n], augmented[:n, n:] = A, B
        transition = linalg.expm(augmented * duration * SAMPLE_TIME)
        return transition[:n, :n], transition[:n, n]

    Ad, Bd = step(1.0)
    states = np.zeros((u.shape[0] + 1, n))
    for k in range(u.shape[0]):
        states[k + 1] = Ad @ states[k] + Bd * u[k]

    def at(t):
        tick = int(np.floor(t))
        Ap, Bp = step(t - tick)
        return float(C[0] @ (Ap @ states[tick] + Bp * u[tick]))

    if exposure == 0.0:
        return np.array([at(t) for t in times])
    xi, w = np.polynomial.legendre.leggauss(nodes)
    out = []
    for t in times:
        edges = [t - exposure] + [k for k in range(int(np.ceil(t - exposure)), int(np.ceil(t)))
                                  if t - exposure < k < t] + [t]
        total = 0.0
        for a, b in zip(edges[:-1], edges[1:]):
            x = a + (b - a) * (xi + 1) / 2
            total += (b - a) / 2 * sum(wi * at(xj) for wi, xj in zip(w, x) if xj >= 0)
        out.append(total / exposure)
    return np.array(out)


def one_system(seed, n_samples, order, timings):
    rng = np.random.default_rng(seed)
    A, B, C = continuous_system(rng)
    u = simulation.multisine(n_samples, random_state=rng)
    u_val = simulation.multisine(n_samples, random_state=rng)
    truth = held_output(A, B, C, u_val, np.arange(n_samples, dtype=float))
    starts = np.arange(0, n_samples, FACTOR)
    instants = starts + rng.uniform(0.0, 1.0, starts.shape[0])
    on_ticks = held_output(A, B, C, u, starts.astype(float))
    between = held_output(A, B, C, u, instants)
    # an exposure of half a period ending at the instant (the first frames start at rest)
    exposed = held_output(A, B, C, u, instants, exposure=EXPOSURE)
    noise_std = np.sqrt(np.var(between) / 10 ** (SNR_DB / 10))

    def noisy(y):
        return y + noise_std * rng.standard_normal(y.shape[0])

    y_ticks, y_between, y_exposed = noisy(on_ticks), noisy(between), noisy(exposed)

    def gof(model):
        return gm.goodness_of_fit(truth, model.predict(u_val))

    results = {}
    start = time.perf_counter()
    model = gm.FIRGaussianProcess(order=order).fit(u, y_ticks, sample_indices=starts)
    timings["ticks"].append(time.perf_counter() - start)
    results["on the fast ticks"] = gof(model)
    rounded = np.minimum(np.round(instants).astype(int), n_samples - 1)
    rounded_model = gm.FIRGaussianProcess(order=order).fit(u, y_between, sample_indices=rounded)
    results["own instants, rounded to the nearest tick"] = gof(rounded_model)
    fixed = gm.FIRGaussianProcess(
        rounded_model.kernel_, order=order, noise_level=rounded_model.noise_level_,
        optimizer=None, normalize=False,
    ).fit(u, y_between, sample_times=instants)
    results["own instants, exact (hyperparameters of the rounded fit)"] = gof(fixed)
    start = time.perf_counter()
    timed = gm.FIRGaussianProcess(order=order).fit(u, y_between, sample_times=instants)
    timings["own instants"].append(time.perf_counter() - start)
    results["own instants, exact (tuned)"] = gof(timed)
    ignored = gm.FIRGaussianProcess(order=order).fit(u, y_exposed, sample_times=instants)
    results[f"exposure {EXPOSURE:g} T, ignored (tuned)"] = gof(ignored)
    modelled = gm.FIRGaussianProcess(order=order, exposure=EXPOSURE).fit(
        u, y_exposed, sample_times=instants)
    results[f"exposure {EXPOSURE:g} T, modelled (tuned)"] = gof(modelled)
    return results, (timed, u, instants, y_between, A, B, C)


def draw(fitted, path):
    model, u, instants, y, A, B, C = fitted
    window = (60.0, 75.0)
    grid = np.linspace(*window, 301)
    mean, std = model.predict(u, sample_times=grid, return_std=True)
    truth = held_output(A, B, C, u, grid)
    shown = (instants >= window[0]) & (instants <= window[1])
    fig, ax = plt.subplots(figsize=(8, 3.6))
    ax.fill_between(grid * SAMPLE_TIME, mean - 1.96 * std, mean + 1.96 * std, alpha=0.3,
                    label="95 % band")
    ax.plot(grid * SAMPLE_TIME, truth, "k", lw=1, label="true output")
    ax.plot(grid * SAMPLE_TIME, mean, "C0--", lw=1, label="posterior mean")
    ax.plot(instants[shown] * SAMPLE_TIME, y[shown], "C3o", ms=4, label="frames")
    for tick in np.arange(np.ceil(window[0]), window[1] + 1):
        ax.axvline(tick * SAMPLE_TIME, color="0.85", lw=0.5, zorder=0)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("output")
    ax.legend(loc="upper right", fontsize=8, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main():
    args = parse_args()
    args.output.mkdir(parents=True, exist_ok=True)
    n_samples, order, n_systems = (N_SAMPLES, ORDER, args.systems)
    if args.quick:
        n_samples, order, n_systems = 240, 120, 1
    timings = {"ticks": [], "own instants": []}
    table, fitted = {}, None
    for seed in range(n_systems):
        results, fit = one_system(seed, n_samples, order, timings)
        fitted = fitted or fit
        for name, value in results.items():
            table.setdefault(name, []).append(value)
    print(f"N = {n_samples}, factor {FACTOR}, order {order}, {SNR_DB:g} dB, "
          f"{n_systems} system(s): validation GoF")
    print("| slow samples | validation GoF |")
    print("|---|---:|")
    for name, values in table.items():
        print(f"| {name} | {np.mean(values):.2f} |")
    print(f"fit time, on the ticks: {np.median(timings['ticks']):.2f} s; at own instants: "
          f"{np.median(timings['own instants']):.2f} s (median of {n_systems})")
    draw(fitted, args.output / "camera_frames.png")


if __name__ == "__main__":
    main()
