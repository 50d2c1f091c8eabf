"""Coverage of the 95 % intervals of c, phi and K from slip sweeps at two normal loads.

    python benchmarks/slip_coverage.py [--draws 2000]

Light vehicle on sandy loam (c = 1.72 kPa, phi = 29 deg, K = 0.01 m, K typical), 6 slips
from 0.01 to 0.5 at each of W = 300 N and 450 N, constant Gaussian noise of 0.2, 1 and 3 %
of the mean force; full model, IPOPT estimator through ``fit_many``. Prints, per noise
level, the fraction of 95 % intervals that hold the true value and the success rate.
"""

from __future__ import annotations

import argparse

import numpy as np

from soiltrack.identify import fit_many
from soiltrack.soilmodel import TERRAINS, VEHICLES, SlipData, tractive_force


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=11)
    a = ap.parse_args()
    v, s = VEHICLES["light"], TERRAINS["sandy_loam"]
    i1 = np.geomspace(0.01, 0.5, 6)
    slip = np.concatenate([i1, i1])
    W = np.repeat([300.0, 450.0], i1.size)
    F = tractive_force(slip, s, v, normal_load=W)
    truth = s.as_vector()
    print(
        f"{'noise':>6} {'success':>8} {'c':>6} {'phi':>6} {'K':>6}   (fraction of 95 % intervals holding the truth,"
        f" {a.draws} draws)"
    )
    for level in (0.002, 0.01, 0.03):
        rng = np.random.default_rng(a.seed)
        data = [
            SlipData(slip, F + level * F.mean() * rng.standard_normal(F.size), normal_load=W) for _ in range(a.draws)
        ]
        res = [r for r in fit_many(data, v, progress=False) if r.success]
        cover = []
        for name, t in zip(("cohesion", "friction_angle", "shear_modulus"), truth):
            hits = [(p := r.parameters[name]).identifiable and p.ci95[0] <= t <= p.ci95[1] for r in res]
            cover.append(np.mean(hits))
        print(f"{level:6.3f} {len(res) / a.draws:8.3f} {cover[0]:6.3f} {cover[1]:6.3f} {cover[2]:6.3f}")


if __name__ == "__main__":
    main()
