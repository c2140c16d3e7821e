"""A randomized benchmark of the automatic choices: ``kernel="auto"``, ``noise_kernel="auto"``
and the default order.

Every run draws new systems (the seed is printed; ``--seed`` replays a run)
from the families below, fits each with the automatic layer and compares it
with what knowing the truth would give:

* ``two_mass``: two modes per system, one below the slow Nyquist frequency
  (0.2-1.2 Hz) and one above it (1.8-4.5 Hz), damping 1-10 %, fast sample
  time 0.1 s, factor 3 (slow Nyquist 1.67 Hz), white noise at 20-60 dB;
* ``alias``: the same, with the upper mode placed so that its slow-rate
  alias falls within 2 % of the lower mode (the slow samples alone cannot
  tell them apart, the fast input can);
* ``no_resonance``: a first-order (DC-like) system, white noise;
* ``drift``: a two-mass system plus a random walk added at the slow samples;
* ``ar1``: a two-mass system plus an AR(1) disturbance at the fast rate
  (pole 0.9-0.995) at 20-60 dB, no white noise;
* ``two_input``: two inputs sharing two modes with their own gains, white noise;
* ``long_memory``: a lightly damped structure (fast sample time 1 ms, one
  well-damped and one lightly damped mode) at factors 10-40 whose response
  needs an order in the thousands (hundreds with ``--quick``), for the
  default order against the best of a small grid of orders by hand.

Per system, fits: ``kernel="auto"`` (everything else default), the plain
default (the DC kernel), and the oracle: DC plus one PK term at each true
mode with its true frequency and damping (fixed; amplitudes and DC tuned),
with the true disturbance model where there is one (its time scale fixed).
Reported: validation goodness of fit (eq. 20) on a noise-free fast-rate
validation record, the share of the true impulse response (lags of the
fitted order) inside the 95 % band of ``impulse_response(return_std=True)``,
the resonances found (false ones: in a system without resonance, or away
from every true mode and its slow-rate aliases), the disturbance
``noise_kernel="auto"`` chose, the fit time and its ratio to the default
fit.  A table per family (mean and worst case) and the targets of the
automatic layer beside them.  Results go to
``benchmarks/output/automatic.json``.  Run from the repository root::

    PYTHONPATH=. python benchmarks/automatic.py --quick
    PYTHONPATH=. python benchmarks/automatic.py --families alias ar1 --systems 6
    PYTHONPATH=. python benchmarks/automatic.py --seed 1234  # replay a run

The system generator (:func:`draw_system`) and the oracle
(:func:`oracle_kernel`, :func:`oracle_noise_kernel`) are importable.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.linalg

OUTPUT = Path(__file__).resolve().parent / "output"
Z95 = 1.959964
FAMILIES = ("two_mass", "alias", "no_resonance", "drift", "ar1", "two_input", "long_memory")
#: Families whose systems have resonances (the oracle-gap target is over these).
RESONANT = ("two_mass", "alias", "drift", "ar1", "two_input")
#: Relative distance of a found frequency to a true mode (or one of its
#: aliases) within which the resonance counts as found there.
MATCH_TOLERANCE = 0.05


# ------------------------------------------------------------------ systems
@dataclass
class Mode:
    """One continuous-time mode ``gain w^2 / (s^2 + 2 damping w s + w^2)``, ``w = 2 pi hz``."""

    frequency_hz: float
    damping: float
    gain: float


@dataclass
class BenchmarkSystem:
    """One drawn system, its records, and the truth the fits are scored against.

    ``modes[k]`` are the modes of input ``k``; ``first_order[k]`` is ``(gain,
    time constant in s)`` of a first-order term of input ``k`` or None.
    ``impulse`` holds the true fast-rate impulse response, shape
    ``(n_inputs, n_lags)``.  ``disturbance`` is None (white noise of std
    ``noise_std``), ``("ar1", pole, std)`` (AR(1) at the fast rate) or
    ``("drift", step_std)`` (a random walk at the slow samples, on top of
    white noise).
    """

    family: str
    seed: int
    sample_time: float
    factor: int
    modes: list
    first_order: list
    u: np.ndarray
    y_slow: np.ndarray
    u_val: np.ndarray
    y_val: np.ndarray
    impulse: np.ndarray
    snr_db: float
    noise_std: float
    disturbance: tuple | None = None
    memory: int = 0
    order_grid: tuple = ()
    details: dict = field(default_factory=dict)

    @property
    def n_inputs(self) -> int:
        return len(self.modes)

    @property
    def true_frequencies(self) -> list:
        return sorted({m.frequency_hz for modes in self.modes for m in modes})


def continuous_model(modes, first_order=None):
    """Continuous-time ``(A, B, C)`` of a sum of second-order modes and a first-order term."""
    blocks, inputs, outputs = [], [], []
    for mode in modes:
        w = 2.0 * np.pi * mode.frequency_hz
        blocks.append(np.array([[0.0, 1.0], [-w * w, -2.0 * mode.damping * w]]))
        inputs.append([0.0, mode.gain * w * w])
        outputs.append([1.0, 0.0])
    if first_order is not None:
        gain, tau = first_order
        blocks.append(np.array([[-1.0 / tau]]))
        inputs.append([gain / tau])
        outputs.append([1.0])
    A = scipy.linalg.block_diag(*blocks)
    B = np.concatenate(inputs)[:, None]
    C = np.concatenate(outputs)[None, :]
    return A, B, C


def discrete_system(modes, first_order, sample_time):
    """The zero-order-hold discretisation, a :class:`gpmultirate.simulation.DiscreteSystem`."""
    from gpmultirate.simulation import DiscreteSystem

    A, B, C = continuous_model(modes, first_order)
    n = A.shape[0]
    augmented = np.zeros((n + 1, n + 1))
    augmented[:n, :n], augmented[:n, n:] = A, B
    transition = scipy.linalg.expm(augmented * sample_time)
    return DiscreteSystem(transition[:n, :n], transition[:n, n:], C, 0.0, sample_time)


def _log_uniform(rng, low, high):
    return float(np.exp(rng.uniform(np.log(low), np.log(high))))


def _ar1(n, pole, rng):
    """A stationary AR(1) sequence of unit variance."""
    from scipy import signal

    e = rng.standard_normal(n) * np.sqrt(1.0 - pole**2)
    v, _ = signal.lfilter([1.0], [1.0, -pole], e, zi=[pole * rng.standard_normal()])
    return v


def _two_modes(rng, alias: bool, sample_time: float, factor: int) -> list:
    slow_rate = 1.0 / (factor * sample_time)
    low = rng.uniform(0.2, 1.2)
    if alias:
        # the upper mode's alias |f2 - k fs| within 2 % of the lower mode
        low = rng.uniform(0.3, 1.1)
        twin = low * (1.0 + rng.uniform(-0.02, 0.02))
        options = [f for f in (slow_rate - twin, slow_rate + twin) if 1.8 <= f <= 4.5]
        high = float(rng.choice(options))
    else:
        high = rng.uniform(1.8, 4.5)
    return [Mode(float(low), _log_uniform(rng, 0.02, 0.1), 1.0),
            Mode(float(high), _log_uniform(rng, 0.01, 0.05), _log_uniform(rng, 0.05, 0.3))]


def draw_system(family: str, seed: int, quick: bool = False,
                memory_range: tuple | None = None) -> BenchmarkSystem:
    """Draw one system of ``family`` from ``seed``, with its records and its truth.

    ``memory_range``: the range of the ``long_memory`` response's length in fast
    samples (default 2,000-4,000, or 300-500 with ``quick``).

    Examples
    --------
    >>> system = draw_system("alias", 3, quick=True)
    >>> system.u.shape, system.y_slow.shape, system.impulse.shape
    ((600,), (200,), (1, 600))
    """
    from gpmultirate.simulation import multisine

    if family not in FAMILIES:
        raise ValueError(f"family must be one of {FAMILIES}; got {family!r}")
    rng = np.random.default_rng(seed)
    sample_time, factor, n_samples, n_inputs = 0.1, 3, 600, 1
    first_order, disturbance, memory, grid = [None], None, 0, ()
    snr_db = float(rng.uniform(20.0, 60.0))
    if family in ("two_mass", "drift", "ar1"):
        modes = [_two_modes(rng, False, sample_time, factor)]
    elif family == "alias":
        modes = [_two_modes(rng, True, sample_time, factor)]
    elif family == "two_input":
        n_inputs = 2
        shared = _two_modes(rng, False, sample_time, factor)
        modes = [[Mode(m.frequency_hz, m.damping, float(m.gain * _log_uniform(rng, 0.3, 3.0)
                       * rng.choice([-1.0, 1.0]))) for m in shared] for _ in range(n_inputs)]
        first_order = [None, None]
    elif family == "no_resonance":
        modes = [[]]
        first_order = [(1.0, _log_uniform(rng, 0.2, 2.0))]
    else:  # long_memory
        sample_time = 1e-3
        factor = int(rng.integers(10, 41))
        memory = int(rng.uniform(*(memory_range or ((300, 500) if quick else (2000, 4000)))))
        n_samples = int(max(8 * memory, 150 * factor) if quick else max(10 * memory, 200 * factor))
        light = rng.uniform(20.0, 120.0)
        # the envelope exp(-damping w t) falls to 1e-3 within `memory` fast samples
        damping = np.log(1e3) / (memory * 2.0 * np.pi * light * sample_time)
        modes = [[Mode(float(rng.uniform(3.0, 8.0)), 0.3, 1.0),
                  Mode(float(light), float(damping), _log_uniform(rng, 0.05, 0.3))]]
        snr_db = float(rng.uniform(30.0, 50.0))
        grid = tuple(int(memory * r) for r in (0.25, 0.5, 1.0, 2.0))
    systems = [discrete_system(m, f, sample_time) for m, f in zip(modes, first_order)]
    u = np.column_stack([multisine(n_samples, sample_time, random_state=rng)
                         for _ in range(n_inputs)])
    u_val = np.column_stack([multisine(n_samples, sample_time, random_state=rng)
                             for _ in range(n_inputs)])
    y = sum(s.simulate(u[:, k]) for k, s in enumerate(systems))
    y_val = sum(s.simulate(u_val[:, k]) for k, s in enumerate(systems))
    n_lags = max(n_samples, 2 * memory)
    impulse = np.vstack([s.impulse_response(n_lags) for s in systems])
    scale = np.sqrt(np.var(y) / 10 ** (snr_db / 10))
    if family == "ar1":
        pole = float(rng.uniform(0.9, 0.995))
        y_noisy, noise_std = y + scale * _ar1(n_samples, pole, rng), 0.0
        disturbance = ("ar1", pole, float(scale))
        y_slow = y_noisy[::factor]
    else:
        noise_std = float(scale)
        y_slow = (y + scale * rng.standard_normal(n_samples))[::factor]
        if family == "drift":
            step = float(scale * rng.uniform(0.3, 1.0))
            y_slow = y_slow + np.cumsum(step * rng.standard_normal(y_slow.size))
            disturbance = ("drift", step)
    if n_inputs == 1:
        u, u_val = u[:, 0], u_val[:, 0]
    return BenchmarkSystem(family=family, seed=int(seed), sample_time=sample_time,
                           factor=factor, modes=modes, first_order=first_order, u=u,
                           y_slow=y_slow, u_val=u_val, y_val=y_val, impulse=impulse,
                           snr_db=snr_db, noise_std=noise_std, disturbance=disturbance,
                           memory=memory, order_grid=grid)


# ------------------------------------------------------------------- oracle
def pk_at(mode: Mode, sample_time: float):
    """A PK term at ``mode``'s damped frequency and decay, both fixed (amplitudes free).

    The response's envelope is ``exp(-damping w t)``; PK's ``alpha`` is the
    decay of its variance per fast sample, ``exp(-2 damping w T)``.
    """
    from gpmultirate.kernels import PK

    w = 2.0 * np.pi * mode.frequency_hz
    return PK(alpha=float(np.exp(-2.0 * mode.damping * w * sample_time)),
              omega=float(w * np.sqrt(1.0 - mode.damping**2) * sample_time),
              alpha_bounds="fixed", omega_bounds="fixed")


def oracle_kernel(system: BenchmarkSystem):
    """DC plus a PK term at each true mode (per input), or None (the default) without modes."""
    from sklearn.gaussian_process.kernels import ConstantKernel

    from gpmultirate.kernels import DC

    if not any(system.modes):
        return None
    kernels = []
    for modes in system.modes:
        kernel = ConstantKernel(1.0, (1e-8, 1e5)) * DC(alpha=0.9, beta=0.9)
        for mode in modes:
            kernel = kernel + pk_at(mode, system.sample_time)
        kernels.append(kernel)
    return kernels[0] if len(kernels) == 1 else kernels


def oracle_noise_kernel(system: BenchmarkSystem):
    """The true noise model: ``"white"``, AR(1) alone at its true time scale, or white plus
    a Matérn 1/2 of long time scale for a random walk."""
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

    if system.disturbance is None:
        return "white"
    if system.disturbance[0] == "ar1":
        length = -1.0 / np.log(system.disturbance[1])  # in fast samples
        return ConstantKernel(1.0, (1e-8, 1e5)) * Matern(length, "fixed", nu=0.5)
    return WhiteKernel(0.1) + ConstantKernel(1.0, (1e-8, 1e5)) * Matern(
        system.factor * len(system.y_slow), (system.factor, 1e7), nu=0.5)


# ------------------------------------------------------------------ scoring
def aliases(frequency: float, slow_rate: float, fast_nyquist: float) -> np.ndarray:
    """``frequency`` and its images ``|frequency - k slow_rate|`` below the fast Nyquist."""
    k = np.arange(0, int(2 * fast_nyquist / slow_rate) + 2)
    images = np.concatenate([frequency + k * slow_rate, np.abs(frequency - k * slow_rate)])
    return np.unique(images[images <= fast_nyquist])


def judge_resonances(system: BenchmarkSystem, found: list) -> dict:
    """Found, false (away from every true mode and its aliases) and missed (true modes with
    no term at them or an alias) resonances."""
    slow_rate = 1.0 / (system.factor * system.sample_time)
    nyquist = 0.5 / system.sample_time
    truth = system.true_frequencies

    def near(f, g):
        return abs(f - g) <= MATCH_TOLERANCE * max(g, slow_rate / 20)

    false = [f for f in found
             if not any(near(f, a) for t in truth for a in aliases(t, slow_rate, nyquist))]
    missed = [t for t in truth
              if not any(near(f, a) for f in found for a in aliases(t, slow_rate, nyquist))]
    return {"found": len(found), "false": len(false), "missed": len(missed),
            "frequencies": [round(f, 4) for f in found]}


def _noise_name(noise_kernel) -> str:
    if isinstance(noise_kernel, str):
        return noise_kernel
    text = repr(noise_kernel)
    if "nu=0.5" in text:
        return "matern12" + ("+white" if "WhiteKernel" in text else "")
    if "nu=1.5" in text:
        return "matern32" + ("+white" if "WhiteKernel" in text else "")
    return type(noise_kernel).__name__


def fit_and_score(system: BenchmarkSystem, kernel="default", order=None, noise_kernel="auto"):
    """Fit one model to ``system`` and score it against the truth."""
    import gpmultirate as gm

    kernel = None if kernel == "default" else kernel
    model = gm.FIRGaussianProcess(kernel, factor=system.factor, order=order,
                                  sample_time=system.sample_time, noise_kernel=noise_kernel)
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model.fit(system.u, system.y_slow)
    seconds = time.perf_counter() - start
    mean, std = model.impulse_response(return_std=True)
    mean, std = np.atleast_2d(mean), np.atleast_2d(std)
    P = mean.shape[1]
    truth = system.impulse[:, :P]
    if truth.shape[1] < P:  # the response has died out beyond the simulated lags
        truth = np.pad(truth, ((0, 0), (0, P - truth.shape[1])))
    # the lags where the response has not yet died out (above 1e-3 of its peak): the band's
    # coverage there, besides over all lags, so that a negligible tail does not dominate
    magnitude = np.abs(truth)
    support = np.zeros_like(magnitude, bool)
    for k in range(truth.shape[0]):
        alive = np.flatnonzero(magnitude[k] > 1e-3 * magnitude[k].max())
        support[k, :alive[-1] + 1 if alive.size else 0] = True
    inside = np.abs(truth - mean) <= Z95 * std
    found = [r.frequency_hz for r in (getattr(model, "resonances_", None) or [])]
    return {
        "gof": float(model.score(system.u_val, system.y_val)),
        "coverage": float(np.mean(inside)),
        "coverage_support": float(np.mean(inside[support])),
        "seconds": seconds,
        "order": int(P),
        "noise": _noise_name(model.noise_kernel_),
        "resonances": judge_resonances(system, found),
        "warnings": sorted({type(w.message).__name__ for w in caught}),
    }


def run_system(system: BenchmarkSystem, with_grid: bool = True) -> dict:
    """The fits of one system: default, auto, oracle (and the order grid)."""
    row = {"family": system.family, "seed": system.seed, "snr_db": round(system.snr_db, 1),
           "factor": system.factor,
           "modes": [[(round(m.frequency_hz, 4), round(m.damping, 4)) for m in modes]
                     for modes in system.modes],
           "disturbance": system.disturbance}
    oracle = oracle_kernel(system)
    fits = {"default": {}, "auto": {"kernel": "auto"},
            "oracle": {"kernel": "default" if oracle is None else oracle,
                       "noise_kernel": oracle_noise_kernel(system)}}
    for name, options in fits.items():
        row[name] = fit_and_score(system, **options)
        if system.order_grid:  # long fits: say where the run is
            print(f"    {name}: {row[name]['gof']:.2f} % in {row[name]['seconds']:.0f} s, "
                  f"order {row[name]['order']}", flush=True)
    row["auto"]["time_ratio"] = row["auto"]["seconds"] / row["default"]["seconds"]
    if system.order_grid and with_grid:
        row["memory"] = system.memory
        row["grid"] = {str(P): fit_and_score(system, order=P)["gof"] for P in system.order_grid}
    return row


# ---------------------------------------------------------------- reporting
def summarize(rows: list) -> dict:
    """Per family: mean and worst case of the reported quantities."""

    def stats(values, worst):
        values = np.asarray(values, float)
        return {"mean": float(values.mean()), "worst": float(worst(values))}

    summary = {}
    for family in dict.fromkeys(r["family"] for r in rows):
        group = [r for r in rows if r["family"] == family]
        s = {"systems": len(group)}
        for fit in ("auto", "default", "oracle"):
            s[f"{fit}_gof"] = stats([r[fit]["gof"] for r in group], np.min)
            s[f"{fit}_coverage"] = stats([r[fit]["coverage"] for r in group], np.min)
            s[f"{fit}_coverage_support"] = stats([r[fit]["coverage_support"] for r in group],
                                                 np.min)
            s[f"{fit}_seconds"] = stats([r[fit]["seconds"] for r in group], np.max)
            s[f"{fit}_noise_coloured"] = int(sum(r[fit]["noise"] != "white" for r in group))
        s["auto_minus_oracle"] = stats([r["auto"]["gof"] - r["oracle"]["gof"] for r in group],
                                       np.min)
        s["auto_minus_default"] = stats([r["auto"]["gof"] - r["default"]["gof"] for r in group],
                                        np.min)
        s["auto_time_ratio"] = stats([r["auto"]["time_ratio"] for r in group], np.max)
        for key in ("found", "false", "missed"):
            s[f"auto_{key}"] = stats([r["auto"]["resonances"][key] for r in group], np.max)
        if any("grid" in r for r in group):
            gaps = [max(r["grid"].values()) - r["default"]["gof"] for r in group if "grid" in r]
            s["best_order_minus_default"] = stats(gaps, np.max)
        summary[family] = s
    return summary


def targets(summary: dict, rows: list) -> list:
    """``(target, measured, met)`` for the automatic layer's targets that this run measured."""
    out = []
    resonant = [r for r in rows if r["family"] in RESONANT]
    if resonant:
        gaps = np.array([r["auto"]["gof"] - r["oracle"]["gof"] for r in resonant])
        out.append(("auto - oracle GoF, mean over two-mass families >= -0.05",
                    f"{gaps.mean():+.3f}", gaps.mean() >= -0.05))
        out.append(("auto - oracle GoF, every system >= -0.5", f"{gaps.min():+.3f}",
                    gaps.min() >= -0.5))
    if "no_resonance" in summary:
        n = sum(r["auto"]["resonances"]["found"] for r in rows if r["family"] == "no_resonance")
        out.append(("resonances found without resonance = 0", str(n), n == 0))
        equal = [r["auto"]["gof"] - r["default"]["gof"] for r in rows
                 if r["family"] == "no_resonance"]
        out.append(("auto - default GoF without resonance within 0.1 (auto as the default)",
                    f"{min(equal, key=abs):+.3f}..{max(equal, key=abs):+.3f}",
                    all(abs(e) <= 0.1 for e in equal)))
    for fit in ("auto", "default"):
        ar1 = [r[fit]["coverage"] for r in rows if r["family"] == "ar1"]
        if ar1:
            out.append((f"{fit}: impulse coverage under AR(1) in 0.92-0.98",
                        f"mean {np.mean(ar1):.3f}, min {np.min(ar1):.3f}, max {np.max(ar1):.3f}",
                        all(0.92 <= c <= 0.98 for c in ar1)))
    white = [r for r in rows if r["disturbance"] is None and r["family"] != "long_memory"]
    for fit in ("default", "auto") if white else ():
        kept = sum(r[fit]["noise"] == "white" for r in white)
        out.append((f"{fit}: noise auto keeps white on white data", f"{kept}/{len(white)}",
                    kept == len(white)))
    grid = [max(r["grid"].values()) - r["default"]["gof"] for r in rows if "grid" in r]
    if grid:
        out.append(("default order within 2 points of the best by hand",
                    f"worst gap {max(grid):.2f}", max(grid) <= 2.0))
    ratios = [r["auto"]["time_ratio"] for r in rows]
    out.append(("auto time / default time <= 2 (auto as the default)",
                f"mean {np.mean(ratios):.2f}, max {np.max(ratios):.2f}", max(ratios) <= 2.0))
    return out


def print_tables(summary: dict, checks: list) -> None:
    columns = ("family", "n", "GoF auto", "oracle", "default", "auto-oracle (mean, worst)",
               "cover auto", "oracle", "default", "cover (support) auto", "oracle", "default",
               "found/false/missed (mean; max)",
               "noise auto coloured", "s auto", "ratio (mean, max)", "best order - default")
    print(" | ".join(columns))
    for family, s in summary.items():
        def m(key, fmt=".2f"):
            return f"{s[key]['mean']:{fmt}}"

        cells = [family, str(s["systems"]),
                 f"{m('auto_gof')} ({s['auto_gof']['worst']:.2f})",
                 f"{m('oracle_gof')} ({s['oracle_gof']['worst']:.2f})",
                 f"{m('default_gof')} ({s['default_gof']['worst']:.2f})",
                 f"{s['auto_minus_oracle']['mean']:+.3f}, {s['auto_minus_oracle']['worst']:+.3f}",
                 f"{m('auto_coverage', '.3f')} ({s['auto_coverage']['worst']:.3f})",
                 f"{m('oracle_coverage', '.3f')} ({s['oracle_coverage']['worst']:.3f})",
                 f"{m('default_coverage', '.3f')} ({s['default_coverage']['worst']:.3f})",
                 *(f"{m(f + '_coverage_support', '.3f')} "
                   f"({s[f + '_coverage_support']['worst']:.3f})"
                   for f in ("auto", "oracle", "default")),
                 f"{m('auto_found', '.1f')}/{m('auto_false', '.1f')}/{m('auto_missed', '.1f')}; "
                 f"{s['auto_found']['worst']:.0f}/{s['auto_false']['worst']:.0f}/"
                 f"{s['auto_missed']['worst']:.0f}",
                 f"{s['auto_noise_coloured']}/{s['systems']}",
                 f"{m('auto_seconds', '.1f')}",
                 f"{m('auto_time_ratio')}, {s['auto_time_ratio']['worst']:.2f}",
                 (f"{s['best_order_minus_default']['mean']:.2f}, "
                  f"{s['best_order_minus_default']['worst']:.2f}"
                  if "best_order_minus_default" in s else "-")]
        print(" | ".join(cells))
    print("\ntarget | measured | met")
    for name, value, met in checks:
        print(f"{name} | {value} | {'yes' if met else 'NO'}")


def print_row(row: dict) -> None:
    a, o, d = row["auto"], row["oracle"], row["default"]
    extra = ""
    if "grid" in row:
        extra = (f" | order default {d['order']} (memory {row['memory']}), grid "
                 + ", ".join(f"{k}: {v:.2f}" for k, v in row["grid"].items()))
    print(f"  {row['family']} seed {row['seed']} modes {row['modes']} "
          f"{row['snr_db']} dB {row['disturbance'] or ''} | GoF auto {a['gof']:.2f} oracle "
          f"{o['gof']:.2f} default {d['gof']:.2f} | cover {a['coverage']:.3f}/"
          f"{o['coverage']:.3f}/{d['coverage']:.3f} (support {a['coverage_support']:.3f}/"
          f"{o['coverage_support']:.3f}/{d['coverage_support']:.3f}) | "
          f"found {a['resonances']['frequencies']} | "
          f"noise {a['noise']}/{d['noise']} | {a['seconds']:.1f} s x{a['time_ratio']:.2f}"
          + extra, flush=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=None, help="replay a run")
    parser.add_argument("--quick", action="store_true",
                        help="one system per family, short long-memory records")
    parser.add_argument("--systems", type=int, default=None,
                        help="systems per family (default 1 with --quick, 6 otherwise)")
    parser.add_argument("--memory", nargs=2, type=float, default=None, metavar=("LOW", "HIGH"),
                        help="range of the long-memory responses' length in fast samples")
    parser.add_argument("--families", nargs="+", default=list(FAMILIES), choices=FAMILIES)
    parser.add_argument("--output", type=Path, default=OUTPUT / "automatic.json")
    args = parser.parse_args(argv)
    import gpmultirate as gm

    seed = args.seed if args.seed is not None else int(np.random.SeedSequence().entropy % 2**31)
    n_systems = args.systems or (1 if args.quick else 6)
    print(f"gpmultirate {gm.__version__}; seed {seed} (replay with --seed {seed}); "
          f"{n_systems} system(s) per family; load {os.getloadavg()[0]:.1f}", flush=True)
    children = np.random.SeedSequence(seed).spawn(len(FAMILIES))
    rows, start = [], time.perf_counter()
    for family in args.families:
        child = children[FAMILIES.index(family)]
        seeds = child.generate_state(n_systems)
        for system_seed in seeds:
            system = draw_system(family, int(system_seed), quick=args.quick,
                                 memory_range=args.memory)
            row = run_system(system)
            print_row(row)
            rows.append(row)
    summary = summarize(rows)
    checks = targets(summary, rows)
    print()
    print_tables(summary, checks)
    print(f"\n{time.perf_counter() - start:.0f} s in all")
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(
        {"seed": seed, "quick": args.quick, "version": gm.__version__,
         "date": time.strftime("%Y-%m-%d"), "rows": rows, "summary": summary,
         "targets": [{"target": t, "measured": v, "met": bool(ok)} for t, v, ok in checks]},
        indent=1, default=str))
    print(f"results in {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
