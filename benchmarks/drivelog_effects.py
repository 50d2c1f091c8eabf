"""Drive-log fits with effects: grade recovery on both reference vehicles, and fit times.

    python benchmarks/drivelog_effects.py            # light on dry sand, heavy on LETE sand, seed 0
    python benchmarks/drivelog_effects.py --seed 3 --grade-deg 5

For each vehicle: a 60 s log (3,001 samples at 50 Hz, default noise, IMU column) simulated with
a known grade, fitted with ``effects=["grade"]``; printed: the grade and the log's thrust limit
with their 95 % intervals and truths. Then fit times of the same log, nominal (no effects), with
the hull channel only, and with the grade: the first call in the process (builds the cached
IPOPT solver) and the second (cached), in the same run.
"""

from __future__ import annotations

import argparse
import math
import time

from soiltrack.identify.drivelog.fit import fit_drive_log
from soiltrack.soilmodel import TERRAINS, VEHICLES, max_thrust
from soiltrack.soilmodel.simulation import simulate_drive_log


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--grade-deg", type=float, default=3.0)
    a = ap.parse_args(argv)
    th = math.radians(a.grade_deg)
    for vname, tname in (("light", "dry_sand"), ("heavy", "lete_sand")):
        v, s = VEHICLES[vname], TERRAINS[tname]
        log = simulate_drive_log(v, s, seed=a.seed, effects={"grade": th})
        F_true = max_thrust(s, v, normal_load=v.weight * math.cos(th))
        times = {}
        for label, kw in (("nominal", {}), ("hull channel", {"hull_channel": True}), ("grade", {"effects": ["grade"]})):
            ts = []
            for _ in range(2):
                t0 = time.perf_counter()
                res = fit_drive_log(log, v, **kw)
                ts.append(time.perf_counter() - t0)
            times[label] = ts
        g = res.effects["grade"]["theta_rad"]
        f = next(c for c in res.combinations if c.name.startswith("F_max"))
        print(f"{vname} on {tname}, {log.n_samples} samples, seed {a.seed}: {res.extra['regime']} log")
        print(
            f"  grade  {g.value:.5f} rad, 95 % [{g.ci95[0]:.5f}, {g.ci95[1]:.5f}], truth {th:.5f} "
            f"({'inside' if g.ci95[0] <= th <= g.ci95[1] else 'OUTSIDE'})"
        )
        print(
            f"  F_max  {f.value:.6g} N, 95 % [{f.ci95[0]:.6g}, {f.ci95[1]:.6g}], truth {F_true:.6g} "
            f"(at W cos(theta); {'inside' if f.ci95[0] <= F_true <= f.ci95[1] else 'OUTSIDE'})"
        )
        k = res.parameters["shear_modulus"]
        print(
            f"  K      {1000 * k.value:.4g} mm, 95 % [{1000 * k.ci95[0]:.4g}, {1000 * k.ci95[1]:.4g}], truth "
            f"{1000 * s.shear_modulus:.4g} mm"
        )
        for label, ts in times.items():
            print(f"  fit time {label:13s} first {ts[0]:.2f} s, cached {ts[1]:.2f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
