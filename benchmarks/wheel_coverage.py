"""Coverage of the rigid-wheel fit's 95 % intervals on sweeps simulated by an independent implementation.

Run from the repository root (about 10 min on a shared 2-core machine)::

    python benchmarks/wheel_coverage.py --seeds 3

Two soils (c 1 kPa, phi 30 deg, K 12 mm, k 1.55 MN/m^(n+2), n 1.1; c 4 kPa, phi 22 deg, K 20 mm,
k 0.9 MN/m^(n+2), n 0.7) x one load (20 N) or three (15, 30, 45 N) x seeds; slips 0.1-0.9;
drawbar-pull noise 0.5 % of the mean load, sinkage noise --sinkage-sd (m). The sweeps come from
the plain-numpy oracle of the tests (tests/wheel_oracle.py). Prints, per case, for c, phi and K:
I (identifiable) or W (weakly) or N (not), + inside the interval or -, B on a bound; then the
count inside over the identifiable ones.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))
import wheel_oracle as oracle  # noqa: E402

from soiltrack.identify.wheel import fit_wheel  # noqa: E402
from soiltrack.soilmodel import RigidWheel, WheelSweep  # noqa: E402

R, B = 0.058, 0.05
SOILS = [(1000.0, math.radians(30), 0.012, 1.55e6, 1.1), (4000.0, math.radians(22), 0.02, 0.9e6, 0.7)]
SLIPS = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9]
KEYS = (("cohesion_kpa", 1e-3, 0), ("friction_angle_deg", 180 / math.pi, 1), ("shear_modulus_m", 1.0, 2))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--sinkage-sd", type=float, default=0.0002)
    a = ap.parse_args()
    wheel = RigidWheel(R, B)
    t0, inside, total = time.time(), 0, 0
    for si, soil in enumerate(SOILS):
        for loads in ([20.0], [15.0, 30.0, 45.0]):
            for seed in range(a.seeds):
                i, dp, W, z = oracle.sweep(
                    SLIPS, loads, *soil, R, B, sd_dp=0.005 * float(np.mean(loads)), sd_z=a.sinkage_sd, seed=seed
                )
                r = fit_wheel(WheelSweep(slip=i, drawbar_pull=dp, normal_load=W, sinkage=z), wheel)
                marks = []
                for key, fac, k in KEYS:
                    e = r.parameters[key]
                    if not e.identifiable:
                        marks.append("N")
                        continue
                    lo, hi = e.edge_ci95
                    ok = lo is not None and hi is not None and lo <= soil[k] * fac <= hi
                    inside, total = inside + ok, total + 1
                    marks.append(
                        ("W" if e.weakly_identifiable else "I") + ("+" if ok else "-") + ("B" if e.at_bound else "")
                    )
                print(f"soil {si} loads {len(loads)} seed {seed}: converged {r.success}, c/phi/K {marks}", flush=True)
    print(f"true value inside the 95 % interval: {inside} of {total} identifiable cases ({time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main()
