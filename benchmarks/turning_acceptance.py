"""Issue 42's acceptance on logs the library did not make: the soil from turning samples alone.

Logs: benchmarks/turning_independent.py (plain numpy, imports nothing of soiltrack: the shear
displacement accumulated from each belt node's entry, the sliding direction at every node, PI
sprocket servos, noise), heavy vehicle (tread 2.5 m, cg 1 m), 45 s at 25 Hz, four turns of
kinematic radius 8-25 m alternating left and right, straight hard pulls, per seed. Each log is
written as a two-track CSV with its vehicle JSON, read back with ``read_two_track`` and fitted with
``fit_turning`` (the code of ``soiltrack fit --motion turning``; ``--cli N`` also runs the command on
the first N seeds and checks it reports the same numbers). Reported per seed: F_max and K with
their 95 % intervals, the outcome; over the seeds: how often each interval holds the truth (of the
usable fits), with its 95 % Clopper-Pearson interval; with ``--straight`` also the straight samples'
fit of the same log and the agreement in standard errors.

Seeds: 1-10 were used while writing the simulator (development); 101 and up are held out.

    python benchmarks/turning_acceptance.py --seeds 101-110
    python benchmarks/turning_acceptance.py --seeds 1-4 --straight --cli 1
    python benchmarks/turning_acceptance.py --seeds 101-110 --soil clayey_soil
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import turning_independent as ti  # noqa: E402


def seed_list(spec: str) -> list[int]:
    """``"1-10"`` or ``"1,2,5"`` -> seeds."""
    out: list[int] = []
    for part in spec.split(","):
        a, _, b = part.partition("-")
        out.extend(range(int(a), int(b or a) + 1))
    return out


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Exact binomial interval of k successes in n trials."""
    from scipy.stats import beta

    a = 1 - level
    lo = 0.0 if k == 0 else float(beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a / 2, k + 1, n - k))
    return lo, hi


def _fit(path: str, vpath: str, motion: str):
    from soiltrack.identify.turning import fit_turning
    from soiltrack.soilmodel import Vehicle
    from soiltrack.soilmodel.turning import read_two_track

    return fit_turning(read_two_track(path), Vehicle.from_json(vpath), motion=motion)


def _row(fit, F: float, K: float) -> dict:
    ok = fit.outcome == "usable"
    d = {"outcome": fit.outcome, "reason": fit.outcome_reason, "F": fit.max_thrust, "K": fit.shear_modulus}
    d["F_ci"], d["K_ci"] = fit.max_thrust_ci95, fit.shear_modulus_ci95
    d["se"] = fit.se
    d["F_in"] = ok and fit.max_thrust_ci95[0] <= F <= fit.max_thrust_ci95[1]
    d["K_in"] = ok and fit.shear_modulus_ci95[0] <= K <= fit.shear_modulus_ci95[1]
    return d


def _summary(rows: list[dict], label: str) -> None:
    use = [r for r in rows if r["outcome"] == "usable"]
    n = len(use)
    print(f"{label}: {n} of {len(rows)} fits usable")
    if not n:
        return
    for key in ("F_in", "K_in"):
        k = sum(r[key] for r in use)
        lo, hi = clopper_pearson(k, n)
        print(f"   truth inside the {key[0]} interval: {k} of {n} = {k / n:.3f} (95 % CI {lo:.3f}-{hi:.3f})")
    k = sum(r["F_in"] and r["K_in"] for r in use)
    print(f"   inside both: {k} of {n}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="101-104", help="e.g. 101-130 or 1,2,3 (1-10: development; 101-: held out)")
    ap.add_argument("--soil", choices=sorted(ti.SOILS), default="lete_sand")
    ap.add_argument("--duration", type=float, default=45.0)
    ap.add_argument("--batch", type=int, default=5, help="seeds simulated together (vectorised)")
    ap.add_argument("--straight", action="store_true", help="also fit the straight samples of each log")
    ap.add_argument("--cli", type=int, default=0, help="run `soiltrack fit --motion turning --json` on N seeds")
    ap.add_argument("--keep", help="directory to keep the logs and the vehicle JSON in")
    ap.add_argument("--json", help="write the per-seed rows here")
    a = ap.parse_args(argv)
    seeds = seed_list(a.seeds)
    soil, veh = ti.SOILS[a.soil], ti.Vehicle()
    F, K = soil.max_thrust(veh), soil.K
    print(f"{a.soil}: truth F_max {F:.1f} N, K {K} m; seeds {seeds}")
    d = a.keep or tempfile.mkdtemp(prefix="turning_acc_")
    os.makedirs(d, exist_ok=True)
    vpath = os.path.join(d, "vehicle.json")
    ti.write_vehicle(veh, vpath)
    rows: dict[str, list[dict]] = {"turning": [], "straight": []}
    sim_cpu = fit_cpu = 0.0
    for b0 in range(0, len(seeds), a.batch):
        batch = seeds[b0 : b0 + a.batch]
        t0 = time.process_time()
        logs = ti.simulate(batch, a.duration, soil, veh, grid=ti.Grid(40, 3, 0.01))
        sim_cpu += time.process_time() - t0
        for seed, log in zip(batch, logs):
            path = os.path.join(d, f"log_{a.soil}_{seed}.csv")
            ti.write_csv(log, path)
            for motion in ("turning", "straight") if a.straight else ("turning",):
                t0 = time.process_time()
                r = _row(_fit(path, vpath, motion), F, K)
                fit_cpu += time.process_time() - t0
                r["seed"] = seed
                rows[motion].append(r)
                fmt = (
                    f"F {r['F'] / 1e3:.1f} kN [{r['F_ci'][0] / 1e3:.1f}, {r['F_ci'][1] / 1e3:.1f}] "
                    f"K {1e3 * r['K']:.2f} mm [{1e3 * r['K_ci'][0]:.2f}, {1e3 * r['K_ci'][1]:.2f}]"
                    if r["F"] is not None
                    else ""
                )
                print(f"seed {seed} {motion:8s} {r['outcome']:10s} {fmt} in: F {r['F_in']} K {r['K_in']}"
                      + ("" if r["outcome"] == "usable" else f" ({r['reason']})"), flush=True)  # fmt: skip
            if a.straight:
                t_, s_ = rows["turning"][-1], rows["straight"][-1]
                if t_["outcome"] == s_["outcome"] == "usable":
                    zF = (t_["F"] - s_["F"]) / np.hypot(t_["se"]["max_thrust_N"], s_["se"]["max_thrust_N"])
                    zK = (t_["K"] - s_["K"]) / np.hypot(t_["se"]["shear_modulus_m"], s_["se"]["shear_modulus_m"])
                    print(f"   turning - straight: F {zF:+.2f} SE, K {zK:+.2f} SE")
            if a.cli > 0 and seed in seeds[: a.cli]:
                _check_cli(path, vpath, rows["turning"][-1])
    _summary(rows["turning"], "turning samples")
    if a.straight:
        _summary(rows["straight"], "straight samples")
    print(f"CPU: simulation {sim_cpu:.1f} s, fits {fit_cpu:.1f} s")
    if a.json:
        with open(a.json, "w", encoding="utf-8") as fh:
            json.dump(rows, fh, indent=1, default=str)
    return 0


def _check_cli(path: str, vpath: str, row: dict) -> None:
    cmd = [sys.executable, "-m", "soiltrack", "fit", path, "--vehicle", vpath, "--motion", "turning", "--json"]
    p = subprocess.run(cmd, capture_output=True, text=True)
    out = json.loads(p.stdout)
    same = out["outcome"] == row["outcome"] and (
        row["F"] is None or abs(out["max_thrust_N"] - row["F"]) <= 1e-6 * row["F"]
    )
    print(f"   CLI exit {p.returncode}, outcome {out['outcome']}, F_max {out['max_thrust_N']}: "
          f"{'same as the API' if same else 'DIFFERS from the API'}")  # fmt: skip


if __name__ == "__main__":
    raise SystemExit(main())
