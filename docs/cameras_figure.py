"""Draw ``docs/generated/cameras_intersample.png``: a camera's frames and the band between ticks.

The paper's two-mass system (as in ``examples/camera_frames.py``), N = 300
fast samples, frames at an instant drawn inside each third fast period with
an exposure of half a period and a latency of a quarter, 45 dB; the default
kernel, tuned with the exposure and latency modelled.  The figure is
:func:`gpmultirate.plotting.plot_intersample` of the fitted model with the
frames at their stamps, and the true reading of the sensor between them.

Run ``PYTHONPATH=. python docs/cameras_figure.py`` from the repository root.
"""

from __future__ import annotations

import importlib.util
import pathlib

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import gpmultirate as gm  # noqa: E402
from gpmultirate import simulation  # noqa: E402
from gpmultirate.plotting import plot_intersample  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parent.parent
N, ORDER, EXPOSURE, LATENCY = 300, 150, 0.5, 0.25


def main():
    spec = importlib.util.spec_from_file_location(
        "camera_frames", ROOT / "examples" / "camera_frames.py")
    frames = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(frames)
    rng = np.random.default_rng(0)
    A, B, C = frames.continuous_system(rng)
    u = simulation.multisine(N, random_state=rng)
    stamps = np.arange(3, N, 3) + rng.uniform(0.0, 1.0, N // 3 - 1)
    # a frame stamped t is the mean output over [t - L - E, t - L]
    y = frames.held_output(A, B, C, u, stamps - LATENCY, exposure=EXPOSURE)
    y = y + np.sqrt(np.var(y) / 10**4.5) * rng.standard_normal(y.shape[0])
    T = frames.SAMPLE_TIME  # the model's times are in seconds
    model = gm.FIRGaussianProcess(order=ORDER, sample_time=T,
                                  exposure=EXPOSURE * T, latency=LATENCY * T)
    model.fit(u, y, sample_times=stamps * T)
    window = (120, 150)
    fig, ax = plt.subplots(figsize=(8, 3.6))
    drawn = plot_intersample(model, u, y_slow=y, sample_times=stamps * T, window=window,
                             between=8, ax=ax, label="predicted reading (95 % band)")
    grid = np.arange(window[0] * 8, window[1] * 8) / 8
    truth = frames.held_output(A, B, C, u, grid - LATENCY, exposure=EXPOSURE)
    ax.plot(grid * frames.SAMPLE_TIME, truth, color="k", linestyle="--", linewidth=1.0,
            label="true reading", zorder=2.5)
    for tick in range(*window):
        ax.axvline(tick * frames.SAMPLE_TIME, color="0.88", linewidth=0.5, zorder=0)
    drawn.ax.legend(fontsize="small", loc="upper left")
    ax.set_title(f"frames at their own instants, exposure {EXPOSURE:g} T, latency "
                 f"{LATENCY:g} T", fontsize="medium", loc="left")
    fig.tight_layout()
    out = ROOT / "docs" / "generated" / "cameras_intersample.png"
    fig.savefig(out, dpi=120)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
