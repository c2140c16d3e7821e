"""Dropped frames: slow samples missing at random, and what they cost.

A slow sensor (a camera, a network link) loses measurements now and then.
``FIRGaussianProcess.fit`` takes a missing slow sample as ``NaN`` in
``y_slow``: the model simply has fewer observations, and its credible bands
say how much less it knows.  This script takes the paper's simulated system
(Section 5: :func:`gpmultirate.simulation.paper_system`, T = 0.1 s, a
multisine of N = 600 samples, every third output sample kept, M = 200) at an
SNR of 50 dB, drops 0 %, 10 %, 30 % and 50 % of the slow samples at random,
fits the paper's DC kernel of order P = N = 600 each time, and reports

* the goodness of fit (eq. 20) on a fresh validation multisine, noise-free
  output, from rest;
* the width of the 95 % credible band of the FRF relative to the true
  ``|G0|``, below and above the slow Nyquist frequency (1.67 Hz);
* the share of frequencies where the true ``G0`` lies inside the 95 %
  credible region of the complex FRF (an ellipse in the complex plane).

Each fraction is repeated over several records and several random patterns
of missing samples (``--quick``: one record, three patterns).  Figure
``dropped_frames.png``: the FRF with its band for 0 % and 30 % missing, and
the fit and band width against the missing fraction.

Run ``python examples/dropped_frames.py [--output DIR] [--quick]``.
"""

from __future__ import annotations

import argparse
import pathlib
import time

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")  # draw into files only

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

import gpmultirate as gm  # noqa: E402
from gpmultirate import simulation  # noqa: E402
from gpmultirate.plotting import plot_bode  # noqa: E402
from gpmultirate.study import paper_kernels  # noqa: E402

DEFAULT_OUTPUT = pathlib.Path(__file__).resolve().parent / "output"
SAMPLE_TIME = 0.1
N_SAMPLES = 600
FACTOR = 3
SNR_DB = 50.0
FRACTIONS = (0.0, 0.1, 0.3, 0.5)
SHOWN = (0.0, 0.3)  # the fractions drawn in the Bode plot
CHI2_2_95 = -2 * np.log(0.05)  # 95 % quantile of chi-square with 2 degrees of freedom


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=pathlib.Path, default=DEFAULT_OUTPUT,
                        help="directory for the figures (default: examples/output)")
    parser.add_argument("--quick", action="store_true",
                        help="one record and three patterns of missing samples per fraction")
    return parser.parse_args()


def band_summary(frf, true_frf, slow_nyquist):
    """Relative band width below / above the slow Nyquist frequency, and coverage.

    The width is the RMS half-width of the 95 % band of the complex FRF
    relative to the RMS of the true ``|G0|`` over the same frequencies (so the
    resonances, not the deep valleys of ``|G0|``, set the scale).  The
    coverage is the share of frequencies whose true ``G0`` lies inside the
    95 % credible ellipse of ``(Re G, Im G)``.
    """
    half_width = 1.96 * np.hypot(frf.real_std, frf.imag_std)
    below = frf.freqs < slow_nyquist
    widths = [float(np.linalg.norm(half_width[part]) / np.linalg.norm(true_frf[part]))
              for part in (below, ~below)]
    # squared Mahalanobis distance of G0 from the posterior mean of (Re G, Im G)
    error = true_frf - frf.mean
    d_re, d_im = error.real / frf.real_std, error.imag / frf.imag_std
    rho = frf.real_imag_corr
    distance = (d_re**2 - 2 * rho * d_re * d_im + d_im**2) / (1 - rho**2)
    inside = distance <= CHI2_2_95
    return widths[0], widths[1], float(np.mean(inside))


def main() -> None:
    args = parse_args()
    args.output.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    n_records, n_patterns = (1, 3) if args.quick else (5, 10)

    system = simulation.paper_system(SAMPLE_TIME)
    slow_nyquist = system.slow_nyquist(FACTOR)
    freqs = np.linspace(0.0, system.fast_nyquist, 401)[1:]
    true_frf = system.frequency_response(freqs)
    kernel, noise_level = paper_kernels(SAMPLE_TIME)["DC"]
    # Validation: a fresh multisine from rest and its noise-free fast output.
    u_val = simulation.multisine(N_SAMPLES, SAMPLE_TIME, random_state=1000)
    y_val = system.simulate(u_val)
    print(f"paper system, T = {SAMPLE_TIME} s, N = {N_SAMPLES}, F = {FACTOR} "
          f"(slow Nyquist {slow_nyquist:.2f} Hz), SNR {SNR_DB:g} dB, {kernel} of order "
          f"{N_SAMPLES}; {n_records} record(s) x {n_patterns} pattern(s) of missing samples")

    rng = np.random.default_rng(0)
    results = {fraction: [] for fraction in FRACTIONS}
    shown = {}
    for record in range(n_records):
        u = simulation.multisine(N_SAMPLES, SAMPLE_TIME, random_state=record)
        data = simulation.simulate_experiment(system, u, FACTOR, snr_db=SNR_DB,
                                              random_state=100 + record)
        n_slow = data.y_slow.shape[0]
        for fraction in FRACTIONS:
            # with nothing missing every pattern is the same: fit once
            for pattern in range(n_patterns if fraction > 0 else 1):
                y_slow = data.y_slow.copy()
                dropped = rng.choice(n_slow, size=round(fraction * n_slow), replace=False)
                y_slow[dropped] = np.nan  # a slow sample that was not measured
                model = gm.FIRGaussianProcess(kernel, factor=FACTOR, order=N_SAMPLES,
                                              noise_level=noise_level).fit(u, y_slow)
                frf = model.frequency_response(freqs, sample_time=SAMPLE_TIME)
                below, above, coverage = band_summary(frf, true_frf, slow_nyquist)
                results[fraction].append({
                    "M": model.y_slow_.shape[0], "gof": model.score(u_val, y_val),
                    "below": below, "above": above, "coverage": coverage,
                })
                if record == 0 and pattern == 0:
                    shown[fraction] = (frf, model.y_slow_.shape[0])

    # ------------------------------------------------------------------
    # Table: fit and band width against the missing fraction.
    # ------------------------------------------------------------------
    print("\ndropped frames: validation GoF [%] and 95 % FRF band against the share of "
          "missing slow samples")
    print(f"{'missing':>8}{'M used':>8}{'fits':>6}{'GoF mean':>10}{'std':>7}{'min':>8}"
          f"{'band < f_s':>12}{'band > f_s':>12}{'G0 inside':>11}")
    summary = {}
    for fraction, entries in results.items():
        gof = np.array([e["gof"] for e in entries])
        summary[fraction] = {key: float(np.mean([e[key] for e in entries]))
                             for key in ("M", "below", "above", "coverage")}
        summary[fraction].update(gof=float(gof.mean()), gof_std=float(gof.std()),
                                 gof_min=float(gof.min()))
        s = summary[fraction]
        print(f"{100 * fraction:>7.0f}%{s['M']:>8.0f}{len(entries):>6}{s['gof']:>10.2f}"
              f"{s['gof_std']:>7.2f}{s['gof_min']:>8.2f}{100 * s['below']:>11.1f}%"
              f"{100 * s['above']:>11.1f}%{100 * s['coverage']:>10.1f}%")
    print("(band < f_s, band > f_s: RMS half-width of the 95 % band of G relative to the RMS "
          f"of |G0|,\n below and above the slow Nyquist frequency f_s = {slow_nyquist:.2f} Hz; "
          "'G0 inside': share of\n frequencies where the true G0 lies in the 95 % credible "
          "ellipse of G; means over the fits)")

    # ------------------------------------------------------------------
    # Figure: FRF with bands for 0 % and 30 %, fit and band width against the
    # missing fraction.
    # ------------------------------------------------------------------
    figure = plt.figure(figsize=(11.0, 6.0), layout="constrained")
    grid = figure.add_gridspec(2, 2, width_ratios=(1.5, 1))
    ax_bode = figure.add_subplot(grid[:, 0])
    ax_gof = figure.add_subplot(grid[0, 1])
    ax_band = figure.add_subplot(grid[1, 1], sharex=ax_gof)
    colors = {0.0: "tab:blue", 0.3: "tab:red"}
    for fraction in SHOWN:
        frf, n_used = shown[fraction]
        plot_bode(frf, axes=ax_bode, phase=False, color=colors[fraction],
                  true_frf=true_frf if fraction == SHOWN[-1] else None,
                  label=f"{100 * fraction:.0f} % missing (M = {n_used})")
    ax_bode.set_title(f"FRF from every {FACTOR}rd output sample, 95 % bands", pad=16)
    ax_bode.legend(fontsize="small", loc="lower left")

    percent = 100 * np.array(FRACTIONS)
    for fraction, entries in results.items():
        ax_gof.plot(np.full(len(entries), 100 * fraction), [e["gof"] for e in entries],
                    linestyle="none", marker="o", markersize=3, color="0.6")
    ax_gof.plot(percent, [summary[f]["gof"] for f in FRACTIONS], marker="o", color="k",
                label="mean")
    ax_gof.set(ylabel="validation GoF [%]", title="fit and band against missing samples")
    ax_gof.legend(fontsize="small")
    ax_gof.grid(True, alpha=0.3)
    ax_band.plot(percent, [100 * summary[f]["below"] for f in FRACTIONS], marker="o",
                 label="below slow Nyquist")
    ax_band.plot(percent, [100 * summary[f]["above"] for f in FRACTIONS], marker="s",
                 label="above slow Nyquist")
    ax_band.set(xlabel="missing slow samples [%]", ylabel="RMS band half-width / RMS |G0| [%]",
                yscale="log")
    widths = [100 * summary[f][part] for f in FRACTIONS for part in ("below", "above")]
    ax_band.set_yticks([t for t in (5, 10, 20, 50, 100, 200, 500, 1000, 2000)
                        if min(widths) / 2 <= t <= max(widths) * 2])
    ax_band.yaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
    ax_band.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax_band.legend(fontsize="small")
    ax_band.grid(True, which="both", alpha=0.3)
    path = args.output / "dropped_frames.png"
    figure.savefig(path, dpi=120)
    plt.close(figure)
    print(f"\nsaved {path}")
    print(f"done in {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    # Matrices of a few hundred rows: one BLAS thread is as fast as several.
    with threadpool_limits(limits=1, user_api="blas"):
        main()
