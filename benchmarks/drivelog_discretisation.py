#!/usr/bin/env python
"""The held-torque sprocket equation: the end-point rule against the slip-relaxation weights, side by side.

Usage (from the repository root)::

    python benchmarks/drivelog_discretisation.py              # 20 seeds per case (about 5 min)
    python benchmarks/drivelog_discretisation.py --seeds 5
    python benchmarks/drivelog_discretisation.py --case default --seeds 60   # one case (label prefix)
    python benchmarks/drivelog_discretisation.py --check 12   # the check's shifts on ordinary logs

What is measured
----------------
Drive logs simulated by the library (CVODES, torque held from sample to sample, the light vehicle on
LETE sand, 30 s, default sensor noise), each fitted twice by ``fit``: ``discretisation="end-point"``
(the interval's mean thrust put on the slip at its end) and ``"relaxation"`` (the default: the thrust
at the sample from the two interval means around it, weighted by the slip's relaxation; see
``soiltrack.identify.drivelog.relaxation``). Per case and rule: the mean error of F_max (percent of
the truth at the log's load), the mean standardised error (error / standard error), and how many of
the 95 % intervals of F_max and K hold the truth. Cases: hard pulls (1 -> 2.5 m/s every 4 s) on flat
ground and on an 8 deg grade at 50 Hz, the same pulls at 100 Hz, and the default (gentle) profile at
50 Hz. Plus one noise-free log of the pulls at 25, 50, 100 and 200 Hz per rule (the discretisation
error alone). ``--check N``: instead, the shift of F_max between the two rules in standard errors
(``fit(..., discretisation_check=True)``) on N default-profile logs each of the light vehicle on LETE
sand and dry sand and the heavy vehicle on LETE sand (how often the check warns on ordinary logs).
"""

from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if _ROOT not in sys.path:
    sys.path.insert(0, _ROOT)

from soiltrack.identify import fit  # noqa: E402
from soiltrack.identify.drivelog.fit import DISCRETISATION_SHIFT_SE  # noqa: E402
from soiltrack.soilmodel import TERRAINS, VEHICLES, max_thrust, simulate_drive_log  # noqa: E402

VEHICLE, SOIL = VEHICLES["light"], TERRAINS["lete_sand"]
RULES = ("end-point", "relaxation")
Z95 = 1.959963984540054


def pulls(t):
    """1 m/s, stepped to 2.5 m/s every 4 s for 2 s (pulls near the traction limit)."""
    return np.where(t < 0.5, 0.0, np.where(np.mod(t, 4.0) < 2.0, 1.0, 2.5))


CASES = {
    "pulls, flat, 50 Hz": dict(speed_profile=pulls, sample_rate_hz=50.0, grade_deg=0.0),
    "pulls, 8 deg, 50 Hz": dict(speed_profile=pulls, sample_rate_hz=50.0, grade_deg=8.0),
    "pulls, flat, 100 Hz": dict(speed_profile=pulls, sample_rate_hz=100.0, grade_deg=0.0),
    "default profile, flat, 50 Hz": dict(speed_profile=None, sample_rate_hz=50.0, grade_deg=0.0),
}


def simulate(case: dict, seed: int, noise: str = "default"):
    th = math.radians(case["grade_deg"])
    log = simulate_drive_log(
        VEHICLE,
        SOIL,
        seed=seed,
        duration_s=30.0,
        sample_rate_hz=case["sample_rate_hz"],
        speed_profile=case["speed_profile"],
        effects={"grade": th} if th else None,
        controller_bandwidth=2.0,
        noise=noise,
    )
    return log, max_thrust(SOIL, VEHICLE, normal_load=VEHICLE.weight * math.cos(th))


def study(seeds: int, only: str | None = None) -> None:
    K_true = SOIL.shear_modulus
    for label, case in CASES.items():
        if only is not None and not label.startswith(only):
            continue
        rows = {rule: [] for rule in RULES}
        for seed in range(seeds):
            log, F_true = simulate(case, 100 + seed)
            for rule in RULES:
                e = fit(log, VEHICLE, discretisation=rule).extra
                F, sF = e["max_thrust_N"], e["max_thrust_stderr_N"]
                K, sK = e["shear_modulus_m"], e["shear_modulus_stderr_m"]
                rows[rule].append(
                    (
                        100 * (F / F_true - 1),
                        (F - F_true) / sF,
                        abs(F - F_true) <= Z95 * sF,
                        abs(K - K_true) <= Z95 * sK,
                    )
                )
            print(f"  {label}: seed {seed + 1} of {seeds}", file=sys.stderr)
        print(f"{label} ({seeds} seeds):")
        for rule in RULES:
            a = np.array(rows[rule], dtype=float)
            print(
                f"  {rule:10s}: F_max error mean {a[:, 0].mean():+.2f} % (sd {a[:, 0].std(ddof=1):.2f}), "
                f"standardised mean {a[:, 1].mean():+.2f} (sd {a[:, 1].std(ddof=1):.2f}); "
                f"95 % intervals hold F_max {int(a[:, 2].sum())}/{seeds}, K {int(a[:, 3].sum())}/{seeds}"
            )


def noise_free() -> None:
    print("noise-free pulls, flat (the discretisation error alone):")
    for hz in (25.0, 50.0, 100.0, 200.0):
        log, F_true = simulate(dict(CASES["pulls, flat, 50 Hz"], sample_rate_hz=hz), 5, noise="none")
        parts = []
        for rule in RULES:
            e = fit(log, VEHICLE, discretisation=rule).extra
            F, sF = e["max_thrust_N"], e["max_thrust_stderr_N"]
            parts.append(f"{rule} {100 * (F / F_true - 1):+.2f} % ({(F - F_true) / sF:+.1f} SE)")
        print(f"  {hz:5.0f} Hz: " + ", ".join(parts))


def check_shifts(seeds: int, limit: float) -> None:
    """The discretisation check on ordinary (default-profile) logs: its F_max shifts, in standard errors."""
    for vehicle, soil in ((VEHICLE, SOIL), (VEHICLE, TERRAINS["dry_sand"]), (VEHICLES["heavy"], SOIL)):
        shifts = []
        for seed in range(seeds):
            log = simulate_drive_log(vehicle, soil, seed=200 + seed)
            c = fit(log, vehicle, discretisation_check=True).extra.get("discretisation_check", {})
            if c.get("max_thrust_shift_se") is not None:
                shifts.append(c["max_thrust_shift_se"])
        a = np.abs(np.array(shifts))
        print(
            f"{vehicle.name.split(' (')[0]} vehicle, {soil.name}: {a.size} logs compared, "
            f"|shift| max {a.max():.2f} SE, beyond 1 SE {int(np.sum(a > 1))}, "
            f"beyond {limit:g} SE (a warning) {int(np.sum(a > limit))}"
        )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=20, help="seeds per case (default 20)")
    ap.add_argument("--case", default=None, help="only the cases whose label starts with this")
    ap.add_argument("--check", type=int, default=None, metavar="N", help="the check's shifts on N logs per vehicle")
    a = ap.parse_args(argv)
    if a.seeds < 2:
        ap.error("--seeds must be at least 2")
    if a.check is not None:
        if a.check < 1:
            ap.error("--check must be at least 1")
        check_shifts(a.check, DISCRETISATION_SHIFT_SE)
        return 0
    if a.case is None:
        noise_free()
    study(a.seeds, a.case)
    return 0


if __name__ == "__main__":
    sys.exit(main())
