"""Wheel sweeps with a measured torque (the numpy oracle, tests/wheel_oracle.py), fitted, intervals counted.

Each replicate: a smooth wheel r 0.058 m, b 0.05 m at loads 15 and 25 N and slips 0.1-0.9 (10 rows),
c 1 kPa, phi 30 deg, K 12 mm, Bekker k = 1.55 MN/m^(n+2), n = 1.1 (held in the fit); noise: pull
0.1 N, sinkage 0.02 mm, torque 0.004 N m. Prints how often the 95 % intervals of c, phi and K hold
the truth with the torque as a third channel.

    python benchmarks/wheel_torque_coverage.py [--reps 12]
"""

from __future__ import annotations

import argparse
import os
import sys


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reps", type=int, default=12, help="replicates (seeds 0..reps-1; default 12)")
    a = ap.parse_args(argv)
    import numpy as np

    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))
    from test_wheel_torque import SOIL, WHEEL, _sweep

    from soiltrack.identify.wheel import WheelFitOptions, fit_wheel
    from soiltrack.soilmodel.wheel_sweep import WheelSweep

    fixed = {"bekker_kc": 0.0, "bekker_kphi": SOIL[3], "bekker_n": SOIL[4]}
    truth = (("cohesion_kpa", 1.0), ("friction_angle_deg", 30.0), ("shear_modulus_m", 0.012))
    hits, ok = np.zeros(3), 0
    for seed in range(a.reps):
        i, dp, W, z, T = _sweep(seed=seed, sd_z=0.00002)
        f = fit_wheel(WheelSweep(i, dp, W, z, torque=T), WHEEL, WheelFitOptions(fixed=fixed))
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
