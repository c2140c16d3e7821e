"""``noise_kernel="auto"`` under AR(1) disturbances, its decision separated from the prior's.

The ``ar1`` family of ``benchmarks/automatic.py`` (two modes, an AR(1)
disturbance at the fast rate with pole 0.9-0.995, 20-60 dB, ``N = 600`` fast
samples, factor 3) and, for the false alarms, its white families, drawn
afresh each run (the seed is printed; ``--seed`` replays a run).  Per
system and order (the record's length, the default, and half of it), the
share of the true impulse response inside the 95 % band of
``impulse_response(return_std=True)`` for these fits:

* ``auto/auto``: ``kernel="auto"``, ``noise_kernel="auto"`` (the automatic layer);
* ``oracle/auto``, ``oracle/white``, ``oracle/oracle``: the true modes as PK
  terms (``automatic.oracle_kernel``) with the automatic, the white and the
  true noise model (``automatic.oracle_noise_kernel``): the noise decision
  judged where the prior is right;
* ``dc/oracle``: the default DC prior with the true noise model: what the
  band holds when the noise is known and the prior is not right.

Also: how often ``noise_kernel="auto"`` chose a disturbance (all and at
40-60 dB) and, on the white families (``--white``), how often it invented
one.  Run from the repository root::

    PYTHONPATH=. python benchmarks/disturbance_auto.py --systems 6
    PYTHONPATH=. python benchmarks/disturbance_auto.py --systems 4 --white 4 --seed 1234
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import automatic  # noqa: E402

#: The fits of each ar1 system: (name, kernel, noise) with "oracle" read per system.
FITS = (("auto/auto", "auto", "auto"), ("oracle/auto", "oracle", "auto"),
        ("oracle/white", "oracle", "white"), ("oracle/oracle", "oracle", "oracle"),
        ("dc/oracle", "default", "oracle"))
#: White families checked for disturbances ``noise_kernel="auto"`` invents.
WHITE_FAMILIES = ("two_mass", "alias", "no_resonance")


def fit(system, kernel, noise, order):
    kernel = automatic.oracle_kernel(system) if kernel == "oracle" else kernel
    noise = automatic.oracle_noise_kernel(system) if noise == "oracle" else noise
    start = time.process_time()
    row = automatic.fit_and_score(system, kernel=kernel, order=order, noise_kernel=noise)
    row["cpu"] = time.process_time() - start
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=None, help="replay a run")
    parser.add_argument("--systems", type=int, default=6, help="ar1 systems")
    parser.add_argument("--white", type=int, default=0, help="systems per white family")
    parser.add_argument("--orders", nargs="+", default=["default", "300"],
                        help="orders: 'default' (the record's length here) or a number")
    args = parser.parse_args(argv)
    seed = args.seed if args.seed is not None else int(np.random.SeedSequence().entropy % 2**31)
    print(f"seed {seed} (replay with --seed {seed}); load {os.getloadavg()[0]:.1f}", flush=True)
    children = np.random.SeedSequence(seed).spawn(1 + len(WHITE_FAMILIES))
    orders = [None if o == "default" else int(o) for o in args.orders]
    rows = []
    for system_seed in children[0].generate_state(args.systems):
        system = automatic.draw_system("ar1", int(system_seed), quick=True)
        for order in orders:
            row = {"seed": int(system_seed), "snr": system.snr_db,
                   "pole": system.disturbance[1], "order": order}
            for name, kernel, noise in FITS:
                row[name] = fit(system, kernel, noise, order)
            rows.append(row)
            print(f"  seed {row['seed']} {row['snr']:.1f} dB pole {row['pole']:.3f} order "
                  f"{row['auto/auto']['order']} | "
                  + " | ".join(f"{name} {row[name]['coverage']:.3f} {row[name]['noise']} "
                               f"{row[name]['cpu']:.1f}s" for name, _, _ in FITS), flush=True)
    print("\norder | fit | coverage mean (min, max) | disturbance chosen (40-60 dB) | CPU s mean")
    for order in orders:
        group = [r for r in rows if r["order"] == order]
        if not group:
            continue
        loud = [r for r in group if r["snr"] >= 40.0]
        for name, _, noise in FITS:
            cover = np.array([r[name]["coverage"] for r in group])
            chosen = sum(r[name]["noise"] != "white" for r in group)
            chosen_loud = sum(r[name]["noise"] != "white" for r in loud)
            print(f"{order or 'default'} | {name} | {cover.mean():.3f} ({cover.min():.3f}, "
                  f"{cover.max():.3f}) | {chosen}/{len(group)} ({chosen_loud}/{len(loud)}) | "
                  f"{np.mean([r[name]['cpu'] for r in group]):.1f}")
    if args.white:
        invented, total = 0, 0
        for family, child in zip(WHITE_FAMILIES, children[1:]):
            for system_seed in child.generate_state(args.white):
                system = automatic.draw_system(family, int(system_seed), quick=True)
                for kernel in ("default", "auto"):
                    row = automatic.fit_and_score(system, kernel=kernel)
                    invented += row["noise"] != "white"
                    total += 1
                    print(f"  white {family} seed {system_seed} {system.snr_db:.1f} dB kernel "
                          f"{kernel}: noise {row['noise']}", flush=True)
        print(f"\nwhite data: a disturbance chosen in {invented} of {total} fits")
    return 0


if __name__ == "__main__":
    sys.exit(main())
