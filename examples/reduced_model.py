"""A low-order model for control design, from slow-rate data, and a controller.

The paper's simulated two-mass-spring-damper (T = 0.1 s, modes at 0.43 and
2.29 Hz) is identified from N = 600 fast input samples and every third noisy
output sample (F = 3, SNR 50 dB) with the paper's prior, DC plus PK kernels
at 0.4 and 2 Hz, as an FIR model of order 600.  Six hundred coefficients are
no model to design a controller with, so the script

1. reduces the posterior-mean FIR to a state-space model
   (``model.to_state_space()``: the balanced truncation of the FIR, with the
   order read from the Hankel singular values) and compares its validation
   fit with the FIR's;
2. reduces posterior draws of the impulse response to the same order
   (``model.sample_state_spaces``), so that the reduced model has a band
   too, and draws its Bode plot inside the FIR's 95 % band;
3. designs a PID controller on the reduced model with python-control
   (``model.to_control()``), and checks the closed loop on the true system
   and on every reduced posterior draw: stability, margins, step response.

Figure: ``reduced_model.png`` (Bode magnitude and phase; open-loop step
responses; closed-loop step responses).  Needs python-control
(``pip install "gpmultirate[control]"``).

Run ``python examples/reduced_model.py [--output DIR] [--quick]``.
"""

from __future__ import annotations

import argparse
import pathlib
import time
import warnings

import matplotlib
import numpy as np

matplotlib.use("Agg")  # draw into files only

import control  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
from scipy import signal  # noqa: E402
from sklearn.gaussian_process.kernels import ConstantKernel  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from gpmultirate import FIRGaussianProcess, goodness_of_fit, simulation  # noqa: E402
from gpmultirate.kernels import DC, PK  # noqa: E402
from gpmultirate.plotting import plot_bode  # noqa: E402

DEFAULT_OUTPUT = pathlib.Path(__file__).resolve().parent / "output"
T, N, FACTOR, SNR_DB = 0.1, 600, 3, 50.0


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=pathlib.Path, default=DEFAULT_OUTPUT,
                        help="directory for the figure (default: examples/output)")
    parser.add_argument("--quick", action="store_true",
                        help="fewer posterior draws (20 instead of 100)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the data and the draws")
    return parser.parse_args()


def paper_kernel():
    """The paper's prior: C * DC plus PK kernels at the two modes' rough frequencies."""
    a, b = np.exp(-0.5 * T), np.exp(-0.1 * T)
    return (ConstantKernel(1.0, (1e-12, 1e5)) * DC(alpha=a, beta=b)
            + PK.from_hz(0.4, T, alpha=a) + PK.from_hz(2.0, T, alpha=a))


def pid(kp: float, ki: float, kd: float, filter_time: float) -> control.TransferFunction:
    """Discrete PID ``kp + ki T z / (z - 1) + kd (z - 1) / ((tf + T) z - tf)`` (backward Euler)."""
    z = control.tf([1.0, 0.0], [1.0], T)
    return kp + ki * T * z / (z - 1) + kd * (z - 1) / ((filter_time + T) * z - filter_time)


def margins(loop):
    """Gain margin, phase margin (deg) and their crossover frequencies (rad/s) of ``loop``."""
    with warnings.catch_warnings():
        # python-control says when it evaluates the margins on a frequency grid
        warnings.filterwarnings("ignore", message="stability_margins", category=UserWarning)
        return control.margin(loop)


def response(system, freqs) -> np.ndarray:
    """Frequency response of a one-input, one-output python-control system at ``freqs`` Hz."""
    return np.ravel(system(np.exp(2j * np.pi * freqs * T)))


def main() -> None:
    args = parse_args()
    args.output.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    rng = np.random.default_rng(args.seed)
    n_draws = 20 if args.quick else 100

    # ------------------------------------------------------------------
    # Identification: fast multisine input, every third noisy output sample.
    # ------------------------------------------------------------------
    system = simulation.paper_system(T)
    u, u_val = (simulation.multisine(N, random_state=rng) for _ in range(2))
    data = simulation.simulate_experiment(system, u, FACTOR, snr_db=SNR_DB, random_state=rng)
    y_val = system.simulate(u_val)  # noise-free fast-rate validation output
    model = FIRGaussianProcess(paper_kernel(), factor=FACTOR, order=N, noise_level=1e-5,
                               sample_time=T).fit(u, data.y_slow)
    gof_fir = model.score(u_val, y_val)
    print(f"FIR of order {N} from {data.y_slow.size} slow samples: validation GoF {gof_fir:.5f} %")

    # ------------------------------------------------------------------
    # Reduction.  The Hankel singular values of the FIR drop by a factor of
    # about 30 after the fourth: two modes, four states.  The default order
    # is the one at that largest drop; the balanced truncation's frequency
    # response is within twice the sum of the discarded values of the FIR's.
    # ------------------------------------------------------------------
    reduced = model.to_state_space()
    order = model.state_space_order_
    hsv = model.hankel_singular_values_
    print("Hankel singular values (relative):",
          " ".join(f"{v:.2g}" for v in hsv[:8] / hsv[0]), "...")
    print(f"chosen order {order}, at the largest drop")
    _, y_reduced, _ = signal.dlsim(reduced, u_val)
    gof_reduced = goodness_of_fit(y_val, y_reduced[:, 0])
    print(f"reduced model ({order} states): validation GoF {gof_reduced:.5f} % "
          f"(FIR {gof_fir:.5f} %)")
    print("reduced poles (natural frequency Hz, damping):", ", ".join(
        f"({abs(np.log(p)) / (2 * np.pi * T):.3f}, {-np.log(p).real / abs(np.log(p)):.3f})"
        for p in np.linalg.eigvals(reduced.A) if p.imag > 0))

    # posterior draws of the impulse response, each reduced to the same order
    draws = [control.ss(s.A, s.B, s.C, s.D, T)
             for s in model.sample_state_spaces(order, n_samples=n_draws, random_state=args.seed)]

    # ------------------------------------------------------------------
    # Control design on the reduced model.  The output is the position of
    # the second mass, the force acts on the first: a non-collocated loop
    # whose phase falls by 180 degrees at each mode.  The PID gains below
    # were chosen on the reduced model (four states: quick to evaluate) from
    # a small grid, for a small time-weighted absolute error of the step
    # response with at least 30 degrees of phase margin and 6 dB of gain
    # margin; the derivative action's lead carries the crossover past the
    # first mode.
    # ------------------------------------------------------------------
    plant = model.to_control()
    controller = pid(kp=1.0, ki=10.0, kd=2.0, filter_time=0.05)
    gain_margin, phase_margin, _, crossover = margins(plant * controller)
    print(f"PID on the reduced model: gain margin {20 * np.log10(gain_margin):.1f} dB, "
          f"phase margin {phase_margin:.1f} deg, crossover {crossover / (2 * np.pi):.3f} Hz")
    true_plant = control.ss(system.A, system.B, system.C, system.D, T)
    loops = {"designed (reduced model)": control.feedback(plant * controller, 1),
             "true system": control.feedback(true_plant * controller, 1)}
    for name, loop in loops.items():
        info = control.step_info(loop)
        print(f"closed loop, {name}: largest pole |z| = {np.abs(loop.poles()).max():.4f}, "
              f"overshoot {info['Overshoot']:.1f} %, 2 % settling time "
              f"{info['SettlingTime']:.1f} s")
    stable_true = np.abs(loops["true system"].poles()).max() < 1
    draw_loops = [control.feedback(d * controller, 1) for d in draws]
    n_stable = sum(np.abs(loop.poles()).max() < 1 for loop in draw_loops)
    draw_margins = np.array([margins(d * controller)[:2] for d in draws])
    print(f"closed loop stable on the true system: {stable_true}; on {n_stable} of "
          f"{n_draws} reduced posterior draws; their gain margins "
          f"{20 * np.log10(draw_margins[:, 0].min()):.1f}.."
          f"{20 * np.log10(draw_margins[:, 0].max()):.1f} dB, "
          f"phase margins {draw_margins[:, 1].min():.1f}..{draw_margins[:, 1].max():.1f} deg")

    # ------------------------------------------------------------------
    # The figure.
    # ------------------------------------------------------------------
    freqs = np.geomspace(0.01, 0.5 / T, 500)
    frf = model.frequency_response(freqs)
    reduced_frf = response(plant, freqs)
    draw_frfs = np.array([response(d, freqs) for d in draws])
    true_frf = system.frequency_response(freqs)
    print(f"max |G_FIR - G_reduced| over 0-{0.5 / T:g} Hz: "
          f"{np.abs(frf.mean - reduced_frf).max():.2g} (bound {2 * hsv[order:].sum():.2g}, "
          f"peak |G| {frf.magnitude.max():.2g}); max error to the true FRF: FIR "
          f"{np.abs(frf.mean - true_frf).max():.2g}, "
          f"reduced {np.abs(reduced_frf - true_frf).max():.2g}")
    # The band is narrow at low frequencies, where the FIR of 60 s misses the
    # last of the slowly decaying response: the true FRF leaves it there too.
    print(f"|G| inside the FIR's 95 % band at {100 * inside_band(reduced_frf, frf).mean():.0f} % "
          f"of the frequencies for the reduced model, "
          f"{100 * inside_band(true_frf, frf).mean():.0f} % for the true system")

    figure = plt.figure(figsize=(9.0, 8.4), layout="constrained")
    grid = figure.add_gridspec(3, 2, height_ratios=(1.3, 1.0, 1.1))
    ax_mag = figure.add_subplot(grid[0, :])
    ax_phase = figure.add_subplot(grid[1, :], sharex=ax_mag)
    plot_bode(frf, axes=(ax_mag, ax_phase), label=f"FIR (P = {N})", color="tab:blue",
              true_frf=true_frf, xscale="log", legend=False)
    for k, values in enumerate(draw_frfs):
        label = f"{order}-state reductions of {n_draws} posterior draws" if k == 0 else None
        ax_mag.plot(freqs, 20 * np.log10(np.abs(values)), color="tab:orange", lw=0.5,
                    alpha=0.4, label=label)
        ax_phase.plot(freqs, np.degrees(_near(np.unwrap(np.angle(values)), frf.phase)),
                      color="tab:orange", lw=0.5, alpha=0.4)
    ax_mag.plot(freqs, 20 * np.log10(np.abs(reduced_frf)), color="tab:red", lw=1.4,
                label=f"{order}-state reduced model")
    ax_phase.plot(freqs, np.degrees(_near(np.unwrap(np.angle(reduced_frf)), frf.phase)),
                  color="tab:red", lw=1.4)
    ax_mag.legend(fontsize="small", loc="lower left")
    ax_mag.set_title(f"FIR with 95 % band, its {order}-state reduction and the reductions of "
                     "posterior draws", pad=16)

    ax_step = figure.add_subplot(grid[2, 0])
    steps = np.ones(300)
    time_axis = np.arange(steps.size) * T
    ax_step.plot(time_axis, system.simulate(steps), "k--", lw=1.2, label="true system")
    ax_step.plot(time_axis, model.predict(steps), color="tab:blue", lw=1.2, label="FIR")
    ax_step.plot(time_axis, signal.dlsim(reduced, steps)[1][:, 0], color="tab:red", lw=1.0,
                 label=f"{order}-state model")
    ax_step.set_xlabel("time [s]")
    ax_step.set_ylabel("position of mass 2")
    ax_step.set_title("open-loop step response")
    ax_step.legend(fontsize="small")

    ax_loop = figure.add_subplot(grid[2, 1])
    loop_time = np.arange(300) * T
    for k, loop in enumerate(draw_loops):
        ax_loop.plot(loop_time, control.step_response(loop, T=loop_time).outputs,
                     color="tab:orange", lw=0.5, alpha=0.4,
                     label="on the reduced draws" if k == 0 else None)
    ax_loop.plot(loop_time, control.step_response(loops["designed (reduced model)"],
                                                  T=loop_time).outputs,
                 color="tab:red", lw=1.4, label="designed (reduced model)")
    ax_loop.plot(loop_time, control.step_response(loops["true system"], T=loop_time).outputs,
                 "k--", lw=1.2, label="on the true system")
    ax_loop.set_xlabel("time [s]")
    ax_loop.set_title("closed-loop step response, PID")
    ax_loop.legend(fontsize="small")
    path = args.output / "reduced_model.png"
    figure.savefig(path, dpi=110)
    plt.close(figure)
    print(f"saved {path}")
    print(f"done in {time.perf_counter() - start:.1f} s")


def inside_band(values, frf) -> np.ndarray:
    """Where ``|values|`` lies inside the magnitude band of ``frf``."""
    magnitude = np.abs(values)
    return (magnitude >= frf.magnitude_lower) & (magnitude <= frf.magnitude_upper)


def _near(phase, reference):
    """``phase`` shifted by a multiple of 2 pi to start next to ``reference``."""
    return phase - 2 * np.pi * np.round((phase[0] - reference[0]) / (2 * np.pi))


if __name__ == "__main__":
    # One BLAS thread: the matrices have a few hundred rows.
    with threadpool_limits(limits=1, user_api="blas"):
        main()
