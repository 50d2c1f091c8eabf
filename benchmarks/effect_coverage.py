"""Joint soil-and-effect fits of slip sweeps: the grade/drawbar acceptance case and interval coverage.

    python benchmarks/effect_coverage.py [--draws 100]

Heavy vehicle on dry sand (c = 1.04 kPa, phi = 28 deg, K = 0.025 m, K typical), the simulator's
22 default slips (0.01 to 0.7) at W = 329 kN and 197.4 kN. First the acceptance case: a
drawbar-pull sweep and a tractive-force sweep with a grade of 0.1 rad (5.7 deg), force noise
1 kN, seed 1, fitted with ``effects=["grade"]``: the fitted grade and soil against the truth.
Then, per case and noise model, the fraction of 95 % intervals that hold the truth over
``--draws`` seeds: force noise only (1 kN), and the simulator's default noise (1 % of the
force AND 0.002 absolute on the slip: an error in the regressor that least squares does not
model). Last, the one-load case, where the grade is weakly identifiable (the slips start at
0.01, where the thrust is already 40 % of F_max, so a constant resistance is hard to tell from
F_max and K).
"""

from __future__ import annotations

import argparse

import numpy as np

from soiltrack.identify import fit
from soiltrack.soilmodel import TERRAINS, VEHICLES, SensorNoise, simulate_slip_sweep

V, S = VEHICLES["heavy"], TERRAINS["dry_sand"]
LOADS = [V.weight, 0.6 * V.weight]
TRUTH = {"cohesion": S.cohesion, "friction_angle": S.friction_angle, "shear_modulus": S.shear_modulus}
FORCE_ONLY = SensorNoise(force_rel=0.0, force_abs=1000.0, slip_abs=0.0)


def _inside(pe, t) -> bool:
    return pe.identifiable and pe.ci95[0] is not None and pe.ci95[0] <= t <= pe.ci95[1]


def acceptance() -> None:
    print("acceptance case: grade 0.1 rad, force noise 1 kN, seed 1, two loads")
    for measured in ("drawbar_pull", "tractive_force"):
        d = simulate_slip_sweep(
            V, S, effects={"grade": 0.1}, normal_loads=LOADS, seed=1, measure=measured, noise=FORCE_ONLY
        )
        r = fit(d, V, effects=["grade"])
        g = r.effects["grade"]["theta_rad"]
        print(
            f"  {measured:<15} {r.status}: grade {g.value:.5f} +- {g.stderr:.5f} rad, 95 % "
            f"[{g.ci95[0]:.5f}, {g.ci95[1]:.5f}] (truth 0.1: {'inside' if _inside(g, 0.1) else 'OUTSIDE'})"
        )
        p = r.parameters
        print(
            f"  {'':<15} c {p['cohesion'].edge_value:.3f} kPa [{p['cohesion'].edge_ci95[0]:.3f}, "
            f"{p['cohesion'].edge_ci95[1]:.3f}] (1.04), phi {p['friction_angle'].edge_value:.3f} deg "
            f"[{p['friction_angle'].edge_ci95[0]:.3f}, {p['friction_angle'].edge_ci95[1]:.3f}] (28), "
            f"K {p['shear_modulus'].value:.5f} m [{p['shear_modulus'].ci95[0]:.5f}, "
            f"{p['shear_modulus'].ci95[1]:.5f}] (0.025)"
        )


def coverage(draws: int) -> None:
    print(f"coverage of 95 % intervals over {draws} seeds (cohesion, phi, K, effect; success rate)")
    cases = [("grade", 0.1, "drawbar_pull"), ("grade", 0.1, "tractive_force"), ("slip_sinkage", 0.1, "drawbar_pull")]
    for noise_name, noise in (("force noise 1 kN", FORCE_ONLY), ("default noise (slip 0.002)", "default")):
        for eff, val, measured in cases:
            hits = np.zeros(4)
            ok = 0
            for seed in range(draws):
                d = simulate_slip_sweep(
                    V, S, effects={eff: val}, normal_loads=LOADS, seed=seed, measure=measured, noise=noise
                )
                r = fit(d, V, effects=[eff])
                if not r.success:
                    continue
                ok += 1
                hits[:3] += [_inside(r.parameters[k], t) for k, t in TRUTH.items()]
                hits[3] += _inside(next(iter(r.effects[eff].values())), val)
            cov = ", ".join(f"{h / draws:.2f}" for h in hits)
            print(f"  {noise_name:<27} {eff:<13} {measured:<15} {cov}; success {ok / draws:.2f}")


def one_load() -> None:
    d = simulate_slip_sweep(V, S, effects={"grade": 0.1}, seed=1, measure="drawbar_pull", noise=FORCE_ONLY)
    r = fit(d, V, effects=["grade"])
    g = r.effects["grade"]["theta_rad"]
    print("one load (329 kN), drawbar pull, grade 0.1 rad:")
    print(
        f"  grade {g.value:.4f} rad, 95 % [{g.ci95[0]:.4f}, {g.ci95[1]:.4f}], weakly identifiable: "
        f"{g.weakly_identifiable} ({g.note})"
    )
    k = r.parameters["shear_modulus"]
    print(
        f"  K {k.value:.5f} m [{k.ci95[0]:.5f}, {k.ci95[1]:.5f}] (truth 0.025); c and phi on their ridge: "
        f"{r.soil is None}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=100)
    a = ap.parse_args()
    acceptance()
    coverage(a.draws)
    one_load()


if __name__ == "__main__":
    main()
