"""The default kernel on lightly damped plants seen by a camera: DC against ``kernel="auto"``.

Every run draws new plants (the seed is printed; ``--seed`` replays a run):
a well-damped mode at 2-5 Hz (damping 0.2-0.5) and a lightly damped one at
60-90 Hz (damping 0.015-0.03), driven at 1 kHz by noise mostly below 30 Hz
(a fourth-order Butterworth filter) plus a weak white part (a tenth of its
std), seen by a 100 Hz camera on the fast ticks (factor 10, slow Nyquist
50 Hz, so the light mode is above it) for 40 s (``--seconds``), 40 dB.

Per plant and kernel: the median error of ``|G|`` below 20 Hz and above
55 Hz (relative to the true ``|G|``), the share of frequencies there whose
true ``|G|`` lies inside the 95 % magnitude band of
``frequency_response``, the validation fit (eq. 20) of the fast output on a
new record, the resonances kept, and the fit's CPU time with its ratio to
DC's.  Run from the repository root::

    PYTHONPATH=. python benchmarks/default_kernel.py --plants 3
    PYTHONPATH=. python benchmarks/default_kernel.py --quick          # 10 s records
    PYTHONPATH=. python benchmarks/default_kernel.py --kernels dc auto --seed 7

``--kernels`` takes ``dc``, ``auto`` and ``default`` (the estimator's
default, whatever it is).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from scipy import signal

sys.path.insert(0, str(Path(__file__).resolve().parent))

from automatic import Mode, discrete_system  # noqa: E402

SAMPLE_TIME = 1e-3
FACTOR = 10
SNR_DB = 40.0
LOW_BAND, HIGH_BAND = 20.0, 55.0


def draw_plant(seed: int, seconds: float) -> dict:
    """One plant, its training and validation records and its true FRF."""
    rng = np.random.default_rng(seed)
    modes = [Mode(float(rng.uniform(2.0, 5.0)), float(rng.uniform(0.2, 0.5)), 1.0),
             Mode(float(rng.uniform(60.0, 90.0)), float(rng.uniform(0.015, 0.03)),
                  float(rng.uniform(0.05, 0.2)))]
    system = discrete_system(modes, None, SAMPLE_TIME)
    n = int(round(seconds / SAMPLE_TIME))
    b, a = signal.butter(4, 30.0, fs=1.0 / SAMPLE_TIME)

    def excitation():
        low = signal.lfilter(b, a, rng.standard_normal(n + 500))[500:]
        low /= np.std(low)
        return low + 0.1 * rng.standard_normal(n)

    u, u_val = excitation(), excitation()
    y, y_val = system.simulate(u), system.simulate(u_val)
    noise = np.sqrt(np.var(y) / 10 ** (SNR_DB / 10))
    y_slow = (y + noise * rng.standard_normal(n))[::FACTOR]
    impulse = system.impulse_response(6000)
    return dict(seed=seed, modes=modes, u=u, y_slow=y_slow, u_val=u_val, y_val=y_val,
                impulse=impulse)


def true_frf(impulse: np.ndarray, freqs: np.ndarray) -> np.ndarray:
    lags = np.arange(impulse.size)
    return np.exp(-2j * np.pi * np.outer(freqs, lags) * SAMPLE_TIME) @ impulse


def fit_and_score(plant: dict, kernel: str) -> dict:
    from gpmultirate import FIRGaussianProcess

    params = dict(factor=FACTOR, sample_time=SAMPLE_TIME)
    if kernel != "default":
        params["kernel"] = kernel
    model = FIRGaussianProcess(**params)
    start = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.fit(plant["u"], plant["y_slow"])
    seconds = time.process_time() - start
    freqs = np.linspace(0.5, 0.5 / SAMPLE_TIME * 0.98, 800)
    response = model.frequency_response(freqs)
    truth = np.abs(true_frf(plant["impulse"], freqs))
    inside = (response.magnitude_lower <= truth) & (truth <= response.magnitude_upper)
    error = np.abs(response.magnitude - truth) / truth
    low, high = freqs < LOW_BAND, freqs > HIGH_BAND
    y_hat = model.predict(plant["u_val"])
    gof = 100.0 * (1.0 - np.linalg.norm(plant["y_val"] - y_hat)
                   / np.linalg.norm(plant["y_val"] - plant["y_val"].mean()))
    kept = getattr(model, "resonances_", None)
    return dict(kernel=kernel, seconds=seconds, order=model.observation_.order,
                error_low=float(np.median(error[low])), error_high=float(np.median(error[high])),
                inside_low=float(inside[low].mean()), inside_high=float(inside[high].mean()),
                gof=float(gof), resonances=[] if kept is None else list(kept))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=None, help="replay a run")
    parser.add_argument("--plants", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=40.0)
    parser.add_argument("--quick", action="store_true", help="10 s records, two plants")
    parser.add_argument("--kernels", nargs="+", default=["dc", "auto", "default"],
                        choices=["dc", "auto", "default"])
    args = parser.parse_args(argv)
    seed = args.seed if args.seed is not None else int(np.random.SeedSequence().entropy % 2**31)
    seconds, plants = (10.0, 2) if args.quick else (args.seconds, args.plants)
    print(f"seed {seed}; {plants} plants of {seconds:g} s; kernels {' '.join(args.kernels)}")
    rows = []
    for index in range(plants):
        plant = draw_plant(seed + index, seconds)
        modes = ", ".join(f"{m.frequency_hz:.2f} Hz ({m.damping:.3f})" for m in plant["modes"])
        print(f"plant {index} (seed {seed + index}): modes {modes}")
        base = None
        for kernel in args.kernels:
            row = fit_and_score(plant, kernel)
            base = row["seconds"] if kernel == "dc" else base
            ratio = f"{row['seconds'] / base:.2f}" if base else "-"
            print(f"  {kernel:8s} order {row['order']:5d}  |G| error <{LOW_BAND:g} Hz "
                  f"{row['error_low']:.3f}  >{HIGH_BAND:g} Hz {row['error_high']:.3f}  "
                  f"inside band {row['inside_low']:.2f} / {row['inside_high']:.2f}  "
                  f"GoF {row['gof']:.2f}  {row['seconds']:.1f} s CPU (x{ratio})  "
                  f"resonances {row['resonances']}")
            rows.append(row)
    print("\nmean over plants:")
    for kernel in args.kernels:
        mine = [r for r in rows if r["kernel"] == kernel]
        print(f"  {kernel:8s} |G| error {np.mean([r['error_low'] for r in mine]):.3f} / "
              f"{np.mean([r['error_high'] for r in mine]):.3f}  inside band "
              f"{np.mean([r['inside_low'] for r in mine]):.2f} / "
              f"{np.mean([r['inside_high'] for r in mine]):.2f}  GoF "
              f"{np.mean([r['gof'] for r in mine]):.2f}  CPU {np.mean([r['seconds'] for r in mine]):.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
