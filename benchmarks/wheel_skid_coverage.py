"""Wheel sweeps from a locked wheel to driving (skid rows), simulated in numpy, fitted, intervals counted.

Each replicate: ``tests/test_wheel_skid.py::skid_sweep`` (r 0.1 m, b 0.08 m, loads 60 and 90 N, slips -1 to
0.9, c 1.5 kPa, phi 30 deg, K 10 mm, Bekker held; noise: pull 0.1 N, sinkage 0.5 mm), fitted by
``fit_wheel``; prints how often the 95 % intervals of c, phi and K hold the truth.

    python benchmarks/wheel_skid_coverage.py [--reps 10]
"""

from __future__ import annotations

import argparse
import math
import os
import sys


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reps", type=int, default=10, help="replicates (seeds 0..reps-1; default 10)")
    a = ap.parse_args(argv)
    import numpy as np

    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))
    from test_wheel_skid import BEKKER_HELD, PHI, B, C, K, R, skid_sweep

    from soiltrack.identify.wheel import WheelFitOptions, fit_wheel
    from soiltrack.soilmodel.rigid_wheel import RigidWheel

    truth = (("cohesion_kpa", C / 1e3), ("friction_angle_deg", math.degrees(PHI)), ("shear_modulus_m", K))
    hits, ok = np.zeros(3), 0
    for seed in range(a.reps):
        f = fit_wheel(skid_sweep(seed), RigidWheel(R, B), WheelFitOptions(fixed=BEKKER_HELD))
        ok += f.success
        for k, (key, true) in enumerate(truth):
            lo, hi = f.parameters[key].edge_ci95
            hits[k] += lo is not None and lo <= true <= hi
    rates = {k: float(v) for k, v in zip(("c", "phi", "K"), (hits / a.reps).round(4))}
    out = {"reps": a.reps, "converged": ok, "coverage": rates}
    print(out)
    return out


if __name__ == "__main__":
    main()
