"""The drive-log engine's numbers and times on several simulated logs, against stored reference values.

Run:  python benchmarks/bench_drivelog_engine.py [--write-reference FILE] [--reference FILE] [--diagnose]
                                               [--kernels]

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

``--kernels`` times the engine's per-sample evaluations alone, each way checked equal first, on the
heavy log of ``bench_diagnose_speed.py`` (3,001 samples, 3,072 padded) with grade and drivetrain
friction: IPOPT's objective, gradient and Hessian of the Lagrangian from the virtual machine and from
the compiled kernels; the profiled start's sums as CasADi's summing map with the data as a ``DM``
(as before) and from the chunked kernel; the derivatives at a fit as ``fn.map(n)`` with its outputs
converted (as before) and through ``sample_outputs`` (the C libraries are compiled now if missing).

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

import casadi as ca
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


def _per_call(f, calls: int) -> float:
    f()
    t = time.perf_counter()
    for _ in range(calls):
        f()
    return (time.perf_counter() - t) / calls * 1e3


def _same(a, b) -> bool:
    """Outputs equal value for value (each flattened in column order, as CasADi stores them)."""
    a = a if isinstance(a, (list, tuple)) else [a]
    b = b if isinstance(b, (list, tuple)) else [b]

    def flat(x):
        return np.asarray(ca.DM(x).full() if isinstance(x, ca.DM) else np.asarray(x, dtype=float)).ravel(order="F")

    return len(a) == len(b) and all(np.array_equal(flat(x), flat(y)) for x, y in zip(a, b))


def kernels(calls: int = 20) -> None:
    """Milliseconds per evaluation of the engine's per-sample work, the former way and the current one."""
    from soiltrack.identify.drivelog import joint as J
    from soiltrack.identify.drivelog import lm_start as L
    from soiltrack.identify.drivelog.nlp import padded_size
    from soiltrack.identify.drivelog.prepare import prepare_drive_log
    from soiltrack.identify.jitcache import load
    from soiltrack.soilmodel.effects import effect_structure, parse_effects

    v = VEHICLES["heavy"]
    log = simulate(v, TERRAINS["lete_sand"], kind="drive", effects={"grade": 0.03}, seed=1, duration_s=60.0)
    prep = prepare_drive_log(log, v)
    jd = J.joint_data(log, v, prep)
    st = effect_structure(parse_effects(["grade", "drivetrain_friction"]), v)
    n, N = prep.n_used, padded_size(prep.n_used)
    fns = (J.residual_function(v, st)[0], J.derivative_function(v, st), J.sensitivity_function(v, st))
    libs = [
        load(J._nlp_kernel_functions(v, st), "drivelog_nlp", wait=True),
        load([L._sums_function(v, st).map(J.SLIP_CHUNK)], "drivelog_sums", wait=True),
        load([J._dense_outputs(f).map(J.SLIP_CHUNK) for f in fns], "drivelog_samples", wait=True),
    ]
    print(f"kernels on {n} samples ({N} padded), grade + drivetrain_friction: C libraries {[c.backend for c in libs]}")
    th = np.array([0.5 * v.weight, 0.015, 0.03, 100.0, 0.5])
    slip = np.clip(prep.slip_measured, 0.0, 0.9)
    vm, cc = (J.joint_solver(v, st, N, 500, 1e-9, 0, c) for c in (False, True))
    scale = np.array([0.5 * v.weight, 0.015, 0.05, 100.0, 0.5])
    i_ref = 0.015 / v.track_length
    p = np.concatenate(
        [scale, [i_ref], J.padded_data(jd.D, N).reshape(-1, order="F"), np.r_[np.zeros(n), np.ones(N - n)]]
    )
    x = np.concatenate([th / scale, slip / i_ref, np.zeros(N - n)])
    P, X = ca.DM(p), ca.DM(x)
    for name, args in (("nlp_f", (X, P)), ("nlp_grad_f", (X, P)), ("nlp_hess_l", (X, P, 1.0, ca.DM(0, 1)))):
        f0, f1 = vm.get_function(name), cc.get_function(name)
        same = _same(f0(*args), f1(*args))
        print(
            f"  IPOPT {name}: virtual machine {_per_call(lambda: f0(*args), calls):.2f} ms, "
            f"compiled kernels {_per_call(lambda: f1(*args), calls):.2f} ms; equal: {same}"
        )
    summing = L._sums_function(v, st).map("sums", "serial", n, [], [0, 1, 2, 3])
    Ddm = ca.DM(jd.D)
    sums = L._Sums(v, st, jd.D)
    old = lambda: [np.asarray(o, dtype=float) for o in summing(th.reshape(-1, 1), slip.reshape(1, -1), Ddm)]  # noqa: E731
    same = _same(old(), list(sums(th, slip)))
    print(
        f"  profiled sums: summing map with a DM {_per_call(old, calls):.2f} ms, chunked kernel "
        f"{_per_call(lambda: sums(th, slip), calls):.2f} ms; equal: {same}"
    )
    th_rep = np.repeat(th.reshape(-1, 1), n, axis=1)
    for which, fn in zip(J.SAMPLE_FUNCTIONS, fns):
        old = lambda: [np.asarray(o, dtype=float) for o in fn.map(n)(th_rep, slip.reshape(1, -1), jd.D)]  # noqa: E731
        new = lambda: J.sample_outputs(v, st, which, th, slip, jd.D)  # noqa: E731
        same = _same(old(), new())
        print(
            f"  {which} over the samples: map(n) built and called {_per_call(old, calls):.2f} ms, sample_outputs "
            f"{_per_call(new, calls):.2f} ms; equal: {same}"
        )


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-300))) if a.size else 0.0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--write-reference", default=None)
    ap.add_argument("--reference", default=None)
    ap.add_argument("--diagnose", action="store_true")
    ap.add_argument("--kernels", action="store_true")
    a = ap.parse_args(argv)
    print("load average before:", os.getloadavg())
    if a.kernels:
        kernels()
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
            line = f"diagnose {vname} (in this process, after the fits): {d.verdict} ({d.confidence!r}, "
            line += f"shrink {d.shrink!r})"
            line += f" in {dt:.2f} s"
            old = ref_diag.get(vname)
            if old is not None:
                same = (old["verdict"], old["confidence"], old["shrink"]) == (d.verdict, d.confidence, d.shrink)
                bad += not same
                line += f"; reference {old['verdict']} ({old['confidence']!r}, shrink {old['shrink']!r})"
                line += f" in {old['s']:.2f} s"
                line += f" [{'same' if same else 'DIFFERENT'}]"
            print(line, flush=True)
    if a.write_reference:
        with open(a.write_reference, "w") as fh:
            json.dump({"cases": rows, "diagnose": diag}, fh, indent=1)
            fh.write("\n")
    print("load average after:", os.getloadavg())
    if a.reference:
        print(
            f"{bad} difference(s); {len(rows)} cases compared (theta rel {THETA_RTOL:g}, iterations, status, "
            f"stats rel {STATS_RTOL:g}; diagnoses: verdict, confidence, shrink)"
        )
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
