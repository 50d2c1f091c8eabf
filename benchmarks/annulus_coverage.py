"""Shear annulus records simulated with the closed form of the ring integral (not soilmodel), fitted, intervals counted.

Each replicate: a ring r_i 0.15 m, r_o 0.20 m at three normal loads (300, 600, 900 N), 12 rotations
0.5-15 deg and 4 steady-state rows 25-60 deg per load, c 2.5 kPa, phi 24 deg, K 12 mm, Gaussian
torque noise 0.5 N m; the torque from ``2 pi (c + sigma tan phi) int r^2 (1 - exp(-r theta / K)) dr``
by its antiderivative. Fitted by ``fit_soil_test`` (the annulus model integrates by quadrature);
prints how often the 95 % intervals of c, phi and K hold the truth.

    python benchmarks/annulus_coverage.py [--reps 300] [--seed 11]
"""

from __future__ import annotations

import argparse
import math


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reps", type=int, default=300, help="replicates (default 300)")
    ap.add_argument("--seed", type=int, default=11)
    a = ap.parse_args(argv)
    import numpy as np

    from soiltrack.identify.soiltests import fit_soil_test
    from soiltrack.soilmodel.bevameter_records import AnnulusTest

    ri, ro, c, phi, K = 0.15, 0.20, 2.5e3, math.radians(24.0), 0.012
    area = math.pi * (ro**2 - ri**2)
    rng = np.random.default_rng(a.seed)
    hits, conv = np.zeros(3), 0
    for _ in range(a.reps):
        loads = np.repeat([300.0, 600.0, 900.0], 16)
        th = np.radians(np.tile(np.concatenate([np.linspace(0.5, 15, 12), [25, 35, 45, 60]]), 3))
        k = th / K

        def F(r):
            return r**3 / 3 + np.exp(-k * r) * (r**2 / k + 2 * r / k**2 + 2 / k**3)

        T = 2 * math.pi * (c + loads / area * math.tan(phi)) * (F(ro) - F(ri)) + rng.normal(0, 0.5, th.size)
        fit = fit_soil_test(AnnulusTest(loads / area, th, T, np.full(th.size, ri), np.full(th.size, ro)))
        conv += fit.converged
        for j, (key, true) in enumerate(
            (("cohesion_kpa", c / 1e3), ("friction_angle_deg", math.degrees(phi)), ("shear_modulus_m", K))
        ):
            lo, hi = fit.parameters[key].edge_ci95
            hits[j] += lo is not None and lo <= true <= hi
    rates = {k: float(v) for k, v in zip(("c", "phi", "K"), (hits / a.reps).round(4))}
    out = {"reps": a.reps, "converged": conv, "coverage": rates}
    print(out)
    return out


if __name__ == "__main__":
    main()
