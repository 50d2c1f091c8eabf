"""Coverage of the joint fit of several data sets on one soil, on data simulated here in plain numpy.

Each replicate simulates, from one soil, a tracked vehicle's slip sweep at two loads (Janosi-Hanamoto
thrust, Eq. 2, written out below, Gaussian force noise) and a bevameter shear test at three normal
pressures (Janosi-Hanamoto shear stress, Gaussian stress noise), fits them jointly with
``soiltrack.identify.fit([sweep, shear], [vehicle, None])`` and counts how often each shared soil
parameter's 95 % interval holds the truth, with the Wilson 95 % interval of that rate; it also counts
how often the consistency test refuses one soil (nominally 0.1 %, the lack-of-fit level).

``--case weighted``: the sweep is a rig's instead - 8 slips, each repeated 3 times, at the two loads, with
noise that grows with the force (sd 1 N + 3 % of F) logged per row in ``tractive_force_std_N`` - so the
intervals hold the truth at the nominal rate only if the joint fit weighs each row by its std as the single
fit does; ``--case ignored`` fits the same rows with the std column dropped (equal weights), for contrast.

    python benchmarks/joint_coverage.py [--reps 100] [--seed 0] [--case plain|weighted|ignored]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

#: The soil simulated (dry sand of Wong's table, K a typical value), SI.
SOIL = {"c": 1040.0, "phi": math.radians(28.0), "K": 0.025}
#: The library's light vehicle (W = 300 N, l = 0.5 m, b = 0.1 m per track).
LIGHT = {"W": 300.0, "l": 0.5, "b": 0.1}
#: Sweep: slips, loads (fractions of W), force noise (N); shear test: pressures (Pa), displacements (m), noise (Pa).
SLIPS = np.linspace(0.03, 0.6, 12)
LOAD_FRACTIONS = (0.5, 1.5)
FORCE_SD = 3.0
PRESSURES = (5e3, 10e3, 15e3)
DISPLACEMENTS = np.linspace(0.002, 0.1, 10)
STRESS_SD = 60.0
#: The rig sweep of ``--case weighted``: slip levels, repeats per level, noise sd = a + b F (N).
RIG_SLIPS = np.linspace(0.03, 0.6, 8)
RIG_REPEATS = 3
RIG_SD = (1.0, 0.03)
CASES = ("plain", "weighted", "ignored")


def sweep_rows(rng: np.random.Generator, soil: dict = SOIL) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(slip, load, tractive force)`` of a track sweep: (A c + W tan phi)(1 - K/(il)(1 - e^(-il/K))) + noise."""
    i = np.tile(SLIPS, len(LOAD_FRACTIONS))
    W = np.repeat(np.array(LOAD_FRACTIONS) * LIGHT["W"], SLIPS.size)
    F = thrust(i, W, soil)
    return i, W, F + rng.normal(0.0, FORCE_SD, F.size)


def thrust(i: np.ndarray, W: np.ndarray, soil: dict = SOIL) -> np.ndarray:
    """Eq. 2 of the light vehicle: (A c + W tan phi)(1 - K/(il)(1 - e^(-il/K)))."""
    A, l = 2 * LIGHT["b"] * LIGHT["l"], LIGHT["l"]
    x = i * l / soil["K"]
    return (A * soil["c"] + W * math.tan(soil["phi"])) * (1 - (1 - np.exp(-x)) / x)


def rig_rows(rng: np.random.Generator, soil: dict = SOIL) -> tuple[np.ndarray, ...]:
    """``(slip, load, tractive force, std)`` of a rig sweep: repeated slips, noise sd a + b F, logged per row."""
    i = np.tile(np.repeat(RIG_SLIPS, RIG_REPEATS), len(LOAD_FRACTIONS))
    W = np.repeat(np.array(LOAD_FRACTIONS) * LIGHT["W"], RIG_SLIPS.size * RIG_REPEATS)
    F = thrust(i, W, soil)
    sd = RIG_SD[0] + RIG_SD[1] * F
    return i, W, F + rng.normal(0.0, sd), sd


def shear_rows(rng: np.random.Generator, soil: dict = SOIL) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(sigma, j, tau)`` of a shear test: (c + sigma tan phi)(1 - e^(-j/K)) + noise."""
    sig = np.repeat(PRESSURES, DISPLACEMENTS.size)
    j = np.tile(DISPLACEMENTS, len(PRESSURES))
    tau = (soil["c"] + sig * math.tan(soil["phi"])) * (1 - np.exp(-j / soil["K"]))
    return sig, j, tau + rng.normal(0.0, STRESS_SD, tau.size)


def wilson(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion k / n."""
    p = k / n
    d = 1 + z**2 / n
    m = (p + z**2 / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z**2 / (4 * n**2)) / d
    return m - h, m + h


def one(seed: int, case: str = "plain") -> dict:
    """One replicate of ``case`` (:data:`CASES`): the joint fit's verdicts (truth inside each interval, test
    refused, outcome)."""
    from soiltrack.identify import fit
    from soiltrack.soilmodel import VEHICLES, ShearTest, SlipData

    rng = np.random.default_rng(seed)
    if case == "plain":
        i, W, F = sweep_rows(rng)
        sweep = SlipData(slip=i, tractive_force=F, normal_load=W, source=f"sweep {seed}")
    else:
        i, W, F, sd = rig_rows(rng)
        std = sd if case == "weighted" else None
        sweep = SlipData(slip=i, tractive_force=F, normal_load=W, force_std=std, source=f"rig sweep {seed}")
    sig, j, tau = shear_rows(rng)
    shear = ShearTest(normal_pressure=sig, shear_displacement=j, shear_stress=tau, source=f"shear {seed}")
    r = fit([sweep, shear], [VEHICLES["light"], None], labels=["sweep", "shear"])
    truth = {
        "cohesion_kpa": SOIL["c"] / 1e3,
        "friction_angle_deg": math.degrees(SOIL["phi"]),
        "shear_modulus_m": SOIL["K"],
    }
    inside, width = {}, {}
    for key, v in truth.items():
        e = r.parameters[key]
        ok = bool(e.identifiable and e.edge_ci95[0] is not None)
        inside[key] = ok and e.edge_ci95[0] <= v <= e.edge_ci95[1]
        width[key] = e.edge_ci95[1] - e.edge_ci95[0] if ok else math.nan
    return {"inside": inside, "width": width, "refused": bool(r.consistency["poor_fit"]), "outcome": r.outcome}


def run(reps: int, seed0: int = 0, case: str = "plain") -> dict:
    """Coverage counts over ``reps`` replicates of ``case`` (seeds seed0 ... seed0 + reps - 1)."""
    if case not in CASES:
        raise ValueError(f"case must be one of {CASES}, got {case!r}")
    res = [one(seed0 + k, case) for k in range(reps)]
    keys = list(res[0]["inside"])
    return {
        "reps": reps,
        "covered": {k: sum(r["inside"][k] for r in res) for k in keys},
        "median_width": {k: float(np.nanmedian([r["width"][k] for r in res])) for k in keys},
        "refused": sum(r["refused"] for r in res),
        "usable": sum(r["outcome"] == "usable" for r in res),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reps", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--case", choices=CASES, default="plain")
    a = ap.parse_args()
    t0 = time.process_time()
    out = run(a.reps, a.seed, a.case)
    n = out["reps"]
    what = {
        "plain": "a track sweep (2 loads)",
        "weighted": "a rig sweep (2 loads, 3 repeats, per-row std column)",
        "ignored": "a rig sweep (2 loads, 3 repeats, std column dropped: equal weights)",
    }[a.case]
    print(f"joint fit of {what} and a shear test, {n} replicates (numpy simulator, seeds {a.seed}-{a.seed + n - 1})")
    for k, c in out["covered"].items():
        lo, hi = wilson(c, n)
        print(
            f"  {k:<20} 95 % interval holds the truth {c}/{n} = {100 * c / n:.1f} % "
            f"(Wilson [{100 * lo:.1f}, {100 * hi:.1f}] %); median width {out['median_width'][k]:.4g}"
        )
    print(f"  consistency test refused one soil: {out['refused']}/{n}; outcome usable: {out['usable']}/{n}")
    print(f"  CPU time {time.process_time() - t0:.1f} s")


if __name__ == "__main__":
    main()
