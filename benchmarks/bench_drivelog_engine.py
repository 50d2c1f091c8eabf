"""The drive-log engine's numbers and times on several simulated logs, against stored reference values.

Run:  python benchmarks/bench_drivelog_engine.py [--write-reference FILE] [--reference FILE] [--diagnose]

For each simulated log (light/heavy vehicle, lete_sand/dry_sand, with and without effects, two or
three seeds) it fits the joint drive-log problem (``fit(log, vehicle, effects=[...])``), evaluates
the residuals and profiled sensitivities of that fit on the log (``drive_log_residuals``,
``drive_log_sensitivities``: the held-out path of a diagnosis), and prints the fitted
``theta = (F_lim, K, effect parameters)``, IPOPT's iterations and the times (the first fit, with
its solver builds, and a second one). ``--reference`` compares with values stored by
``--write-reference`` (the reference file of this repository,
``benchmarks/drivelog_engine_reference.json``, was written on commit 7b291f1, before the engine
changes it checks): the largest relative difference in theta, in the residual and sensitivity
sums, and in the fit's cost and sums of its Jacobian (the sandwich covariance's stand-in) and
weighted residuals; whether the iteration counts and statuses are the same. ``--diagnose`` also
diagnoses the heavy and light logs of ``bench_diagnose_speed.py`` in this process (verdict,
confidence, shrink and time; the fresh-process times are that benchmark's). Exit status 1 if
theta differs by more than 1e-10 relative, the other numbers by more than 1e-9, or an iteration
count, status or diagnosis differs.

Reference on another commit (here 7b291f1), from a source tree of it (the script puts its own
tree first on ``sys.path``)::

    mkdir /tmp/ref && git archive 7b291f1 | tar -x -C /tmp/ref
    cp benchmarks/bench_drivelog_engine.py /tmp/ref/benchmarks/
    python /tmp/ref/benchmarks/bench_drivelog_engine.py --diagnose \
        --write-reference benchmarks/drivelog_engine_reference.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from soiltrack.identify import diagnose, fit  # noqa: E402
from soiltrack.identify.drivelog.residuals import drive_log_residuals  # noqa: E402
from soiltrack.identify.drivelog.sensitivity import drive_log_sensitivities  # noqa: E402
from soiltrack.soilmodel import TERRAINS, VEHICLES, simulate  # noqa: E402

#: (name, vehicle, terrain, simulated effects, fitted effects, seed)
CASES = (
    ("light-lete-nominal-s1", "light", "lete_sand", None, None, 1),
    ("light-lete-nominal-s2", "light", "lete_sand", None, None, 2),
    ("heavy-lete-grade-s1", "heavy", "lete_sand", {"grade": 0.03}, ["grade"], 1),
    ("heavy-lete-grade-s3", "heavy", "lete_sand", {"grade": 0.03}, ["grade"], 3),
    ("light-dry-friction-s1", "light", "dry_sand", {"drivetrain_friction": 0.05}, ["drivetrain_friction"], 1),
    ("light-dry-friction-s2", "light", "dry_sand", {"drivetrain_friction": 0.05}, ["drivetrain_friction"], 2),
    ("heavy-dry-nominal-grade-s2", "heavy", "dry_sand", None, ["grade"], 2),
    ("heavy-dry-two-s1", "heavy", "dry_sand", {"grade": 0.02}, ["grade", "drivetrain_friction"], 1),
)
THETA_RTOL = 1e-10
#: Largest relative difference of the cost and of the sums of |Jacobian| and |weighted residuals| accepted.
STATS_RTOL = 1e-9


def run_case(name: str, vname: str, terrain: str, sim_eff, fit_eff, seed: int, seconds: float) -> dict:
    """Fit, residuals and sensitivities of one simulated log; numbers and times."""
    v = VEHICLES[vname]
    log = simulate(v, TERRAINS[terrain], kind="drive", effects=sim_eff, seed=seed, duration_s=seconds)
    t0 = time.perf_counter()
    r = fit(log, v, effects=fit_eff)
    t_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    fit(log, v, effects=fit_eff)
    t_second = time.perf_counter() - t0
    jp = r.extra.get("joint_parameters")
    if jp is not None:
        theta = [jp["max_thrust_N"], jp["shear_modulus_m"]] + [jp["effects"][k] for k in sorted(jp["effects"])]
    else:
        theta = [r.extra["max_thrust_N"], r.extra["shear_modulus_m"]]
    t0 = time.perf_counter()
    res = drive_log_residuals(r, log, v)
    sens = drive_log_sensitivities(r, log, v, effects=["grade", "drivetrain_friction", "speed_resistance"])
    t_eval = time.perf_counter() - t0
    chans = res["channels"]
    sums = [float(np.nansum(np.abs(chans[c]))) for c in sorted(chans)]
    sums += [float(np.sum(np.abs(sens.residuals))), float(np.sum(np.abs(sens.jacobian)))]
    return {
        "name": name,
        "n": int(log.n_samples),
        "status": r.status,
        "success": bool(r.success),
        "iterations": int(r.iterations),
        "theta": [float(x) for x in theta],
        "sums": sums,
        "stats": [float(r.cost), float(np.nansum(np.abs(r.jacobian))), float(np.nansum(np.abs(r.weighted_residuals)))],
        "fit_s": t_first,
        "fit_again_s": t_second,
        "residuals_and_sensitivities_s": t_eval,
    }


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-300))) if a.size else 0.0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--write-reference", default=None)
    ap.add_argument("--reference", default=None)
    ap.add_argument("--diagnose", action="store_true")
    a = ap.parse_args(argv)
    print("load average before:", os.getloadavg())
    ref, ref_diag = {}, {}
    if a.reference:
        with open(a.reference) as fh:
            stored = json.load(fh)
        ref = {row["name"]: row for row in stored["cases"]}
        ref_diag = {row["vehicle"]: row for row in stored.get("diagnose", [])}
    rows, bad = [], 0
    for case in CASES:
        row = run_case(*case, seconds=a.seconds)
        rows.append(row)
        th = ", ".join(f"{x:.12g}" for x in row["theta"])
        line = (
            f"{row['name']}: {row['n']} samples, {row['status']}, {row['iterations']} it, theta [{th}]; "
            f"fit {row['fit_s']:.2f} s (again {row['fit_again_s']:.2f} s), residuals+sensitivities "
            f"{row['residuals_and_sensitivities_s']:.2f} s"
        )
        if row["name"] in ref:
            rr = ref[row["name"]]
            dth, dsum = _rel(row["theta"], rr["theta"]), _rel(row["sums"], rr["sums"])
            dst = _rel(row["stats"], rr["stats"])
            same_it = row["iterations"] == rr["iterations"]
            ok = dth <= THETA_RTOL and same_it and row["status"] == rr["status"] and dst <= STATS_RTOL
            bad += not ok
            line += (
                f"\n    vs reference: theta rel diff {dth:.1e}, residual/sensitivity sums rel diff {dsum:.1e}, "
                f"cost/jacobian/residual sums rel diff {dst:.1e}, "
                f"iterations {rr['iterations']} -> {row['iterations']}, fit {rr['fit_s']:.2f} -> {row['fit_s']:.2f} s,"
                f" again {rr['fit_again_s']:.2f} -> {row['fit_again_s']:.2f} s, residuals+sensitivities "
                f"{rr['residuals_and_sensitivities_s']:.2f} -> {row['residuals_and_sensitivities_s']:.2f} s"
                f" [{'same' if ok else 'DIFFERENT'}]"
            )
        print(line, flush=True)
    diag = []
    if a.diagnose:
        for vname in ("heavy", "light"):
            v = VEHICLES[vname]
            log = simulate(v, TERRAINS["lete_sand"], kind="drive", effects={"grade": 0.03}, seed=1, duration_s=60.0)
            t0 = time.perf_counter()
            d = diagnose(log, v)
            dt = time.perf_counter() - t0
            row = {"vehicle": vname, "verdict": d.verdict, "confidence": d.confidence, "shrink": d.shrink, "s": dt}
            diag.append(row)
            line = f"diagnose {vname} (in this process, after the fits): {d.verdict} ({d.confidence!r}, shrink {d.shrink!r})"
            line += f" in {dt:.2f} s"
            old = ref_diag.get(vname)
            if old is not None:
                same = (old["verdict"], old["confidence"], old["shrink"]) == (d.verdict, d.confidence, d.shrink)
                bad += not same
                line += f"; reference {old['verdict']} ({old['confidence']!r}, shrink {old['shrink']!r}) in {old['s']:.2f} s"
                line += f" [{'same' if same else 'DIFFERENT'}]"
            print(line, flush=True)
    if a.write_reference:
        with open(a.write_reference, "w") as fh:
            json.dump({"cases": rows, "diagnose": diag}, fh, indent=1)
            fh.write("\n")
    print("load average after:", os.getloadavg())
    if a.reference:
        print(f"{bad} difference(s); {len(rows)} cases compared (theta rel {THETA_RTOL:g}, iterations, status, stats rel {STATS_RTOL:g}; diagnoses: verdict, confidence, shrink)")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
