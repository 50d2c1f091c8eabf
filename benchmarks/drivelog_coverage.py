"""Coverage of the drive-log fit's 95 % intervals and the bias of its estimates, over noise seeds.

Simulates the light vehicle on dry sand with the simulator's defaults (60 s at 50 Hz, default
speed profile and sensor noise; only the noise seed changes, so every log has the same true
trajectory) and fits each log with :func:`soiltrack.identify.drivelog.fit.fit_drive_log`::

    python benchmarks/drivelog_coverage.py                     # seeds 0..99, 2 worker processes
    python benchmarks/drivelog_coverage.py --seeds 200 --jobs 2 --json out.json
    python benchmarks/drivelog_coverage.py --vehicle heavy --terrain lete_sand --seeds 20
    python benchmarks/drivelog_coverage.py --seeds 200 --gauss-newton   # the former covariance
    python benchmarks/drivelog_coverage.py --seeds 60 --bias-correction simex   # opt-in SIMEX correction
    python benchmarks/drivelog_coverage.py --seeds 40 --hull                     # nominal fit + hull channel
    python benchmarks/drivelog_coverage.py --seeds 40 --effect grade=0.0524 --fit-effect grade

With ``--effect NAME=VALUE`` (repeatable) the logs carry that effect; ``--fit-effect NAME``
(repeatable) fits it jointly (hull channel on); F_max's truth is then the thrust limit at the
log's actual normal load ``W (1 + delta) cos(theta)``, and each fitted effect parameter with a
true value gets the same bias / coverage lines.

Reported: mean and standard deviation of the relative errors of F_max and K, the mean reported
relative standard errors, how often the reported 95 % intervals hold the truth (with the
binomial 95 % range of a calibrated interval for the same number of seeds), the mean of the
standardised errors z = (estimate - truth) / stderr, and the fit time. With ``--bias-correction``
the same numbers are printed for the uncorrected estimates of the same fits (kept in
``result.extra["bias_correction"]["uncorrected"]``, with the uncorrected sandwich standard errors)
and for the corrected ones.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np


def _one(args):
    vehicle_name, terrain_name, seed, kw, gauss_newton, bias_correction, simex_fixed, fit_kw = args
    from soiltrack.identify.drivelog import covariance as drivelog_covariance
    from soiltrack.identify.drivelog import simex as drivelog_simex
    from soiltrack.identify.drivelog.fit import fit_drive_log

    if gauss_newton:  # the former covariance: no sandwich (fit_drive_log falls back to Gauss-Newton)
        drivelog_covariance.profiled_covariance = lambda *a, **k: None
    if simex_fixed is not None:
        drivelog_simex._SIMEX_FIXED_SELECTION = simex_fixed
    from soiltrack.soilmodel import TERRAINS, VEHICLES, max_thrust
    from soiltrack.soilmodel.simulation import simulate_drive_log

    veh, soil = VEHICLES[vehicle_name], TERRAINS[terrain_name]
    from soiltrack.soilmodel.effects import effective_normal_load, parse_effects

    true_eff = parse_effects(kw.get("effects"))
    N_true = float(effective_normal_load(veh.weight, veh, true_eff))
    F_true, K_true = max_thrust(soil, veh, normal_load=N_true), soil.shear_modulus
    log = simulate_drive_log(veh, soil, seed=seed, **kw)
    t0 = time.perf_counter()
    res = fit_drive_log(log, veh, bias_correction=bias_correction, **fit_kw)
    dt = time.perf_counter() - t0
    fmax = next(c for c in res.combinations if c.name.startswith("F_max"))
    k = res.parameters["shear_modulus"]
    extra = {}
    bc = res.extra.get("bias_correction")
    if bc is not None:
        u = bc.get("uncorrected") or {
            "max_thrust_N": fmax.value,
            "shear_modulus_m": k.value,
            "max_thrust_stderr_N": fmax.stderr,
            "shear_modulus_stderr_m": k.stderr,
        }
        q = 1.959963984540054  # uncorrected intervals: normal quantile (the sandwich dof are large)
        extra = {
            "applied": bool(bc.get("applied")),
            "level_means": bc.get("level_means"),
            "mc_se_K": (bc.get("monte_carlo_stderr") or {}).get("shear_modulus_m"),
            "uncorrected": {
                "F": u["max_thrust_N"],
                "F_se": u["max_thrust_stderr_N"],
                "F_lo": u["max_thrust_N"] - q * u["max_thrust_stderr_N"],
                "F_hi": u["max_thrust_N"] + q * u["max_thrust_stderr_N"],
                "K": u["shear_modulus_m"],
                "K_se": u["shear_modulus_stderr_m"],
                "K_lo": u["shear_modulus_m"] - q * u["shear_modulus_stderr_m"],
                "K_hi": u["shear_modulus_m"] + q * u["shear_modulus_stderr_m"],
            },
        }
    for name, ps in (res.effects or {}).items():
        for pname, est in ps.items():
            if name in true_eff and est.stderr is not None:
                tv = true_eff.value(name, pname, veh)
                lab = f"{name}.{pname}"
                extra.update(
                    {
                        lab: est.value,
                        lab + "_se": est.stderr,
                        lab + "_lo": est.ci95[0],
                        lab + "_hi": est.ci95[1],
                        lab + "_true": tv,
                    }
                )
    return {
        **extra,
        "seed": seed,
        "success": bool(res.success),
        "time_s": dt,
        "F": fmax.value,
        "F_se": fmax.stderr,
        "F_lo": fmax.ci95[0],
        "F_hi": fmax.ci95[1],
        "K": k.value,
        "K_se": k.stderr,
        "K_lo": k.ci95[0],
        "K_hi": k.ci95[1],
        "F_true": F_true,
        "K_true": K_true,
        "regime": res.extra.get("regime"),
        "reduced_chi2": res.extra.get("reduced_chi2"),
    }


def _binom_range(n: int, p: float = 0.95) -> tuple[int, int]:
    """Central range holding at least 95 % of Binomial(n, p) (what a calibrated interval gives)."""
    pmf = [math.comb(n, j) * p**j * (1 - p) ** (n - j) for j in range(n + 1)]
    cdf = np.cumsum(pmf)
    lo = int(np.searchsorted(cdf, 0.025))
    hi = int(np.searchsorted(cdf, 0.975))
    return lo, hi


def _effect_labels(rows: list[dict]) -> list[str]:
    return sorted({k[:-5] for r in rows for k in r if k.endswith("_true") and "." in k})


def summarise(rows: list[dict]) -> dict:
    ok = [r for r in rows if r["success"]]
    n = len(ok)
    out = {"seeds": len(rows), "succeeded": n}
    for p in ["F", "K"] + _effect_labels(ok):
        if p not in ("F", "K"):  # effect parameters: absolute errors (their truth may be 0)
            have = [r for r in ok if p in r]
            err = np.array([r[p] - r[p + "_true"] for r in have])
            z = np.array([(r[p] - r[p + "_true"]) / r[p + "_se"] for r in have])
            inside = sum(r[p + "_lo"] <= r[p + "_true"] <= r[p + "_hi"] for r in have)
            out[p] = {
                "n": len(have),
                "mean_error": float(err.mean()),
                "sd_error": float(err.std(ddof=1)),
                "mean_stderr": float(np.mean([r[p + "_se"] for r in have])),
                "coverage": inside,
                "mean_z": float(z.mean()),
                "sd_z": float(z.std(ddof=1)),
                "true": have[0][p + "_true"],
            }
            continue
        err = np.array([r[p] / r[p + "_true"] - 1 for r in ok])
        se = np.array([r[p + "_se"] / r[p + "_true"] for r in ok])
        z = np.array([(r[p] - r[p + "_true"]) / r[p + "_se"] for r in ok])
        inside = sum(r[p + "_lo"] <= r[p + "_true"] <= r[p + "_hi"] for r in ok)
        out[p] = {
            "mean_rel_error": float(err.mean()),
            "sd_rel_error": float(err.std(ddof=1)),
            "stderr_of_mean": float(err.std(ddof=1) / math.sqrt(n)),
            "mean_rel_stderr": float(se.mean()),
            "coverage": inside,
            "coverage_rate": inside / n,
            "mean_z": float(z.mean()),
            "sd_z": float(z.std(ddof=1)),
        }
    out["calibrated_range_95"] = _binom_range(n)
    out["median_fit_time_s"] = float(np.median([r["time_s"] for r in ok]))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--vehicle", default="light")
    ap.add_argument("--terrain", default="dry_sand")
    ap.add_argument("--duration", type=float, default=None, help="log length, s (simulator default 60)")
    ap.add_argument("--rate", type=float, default=None, help="sample rate, Hz (simulator default 50)")
    ap.add_argument("--json", default=None, help="write per-seed rows and the summary here")
    ap.add_argument(
        "--gauss-newton",
        action="store_true",
        help="use the former Gauss-Newton covariance instead of the sandwich (for comparison)",
    )
    ap.add_argument(
        "--bias-correction",
        default=None,
        choices=["simex"],
        help="opt-in bias correction of fit_drive_log; also reports the uncorrected estimates",
    )
    ap.add_argument(
        "--simex-selection",
        default=None,
        choices=["fixed", "refit"],
        help="(diagnostic) SIMEX refits keep the uncorrected fit's samples (fixed, default) or reselect",
    )
    ap.add_argument("--effect", action="append", default=[], help="effect in the simulated logs, NAME=VALUE")
    ap.add_argument("--fit-effect", action="append", default=[], help="effect fitted jointly (hull channel on)")
    ap.add_argument("--hull", action="store_true", help="nominal fit with the hull channel")
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args(argv)
    kw = {}
    if a.effect:
        kw["effects"] = list(a.effect)
    fit_kw = {}
    if a.fit_effect:
        fit_kw["effects"] = list(a.fit_effect)
    if a.hull:
        fit_kw["hull_channel"] = True
    if a.duration:
        kw["duration_s"] = a.duration
    if a.rate:
        kw["sample_rate_hz"] = a.rate
    simex_fixed = None if a.simex_selection is None else a.simex_selection == "fixed"
    tasks = [
        (a.vehicle, a.terrain, s, kw, a.gauss_newton, a.bias_correction, simex_fixed, fit_kw)
        for s in range(a.first_seed, a.first_seed + a.seeds)
    ]
    t0 = time.time()
    rows = []
    with ProcessPoolExecutor(max_workers=max(a.jobs, 1)) as ex:
        for r in ex.map(_one, tasks):
            rows.append(r)
            if not a.quiet:
                print(
                    f"seed {r['seed']:4d}  F {100 * (r['F'] / r['F_true'] - 1):+6.2f} %  "
                    f"K {100 * (r['K'] / r['K_true'] - 1):+6.1f} %  (se {100 * r['K_se'] / r['K_true']:.1f} %)  "
                    f"in: F {r['F_lo'] <= r['F_true'] <= r['F_hi']:d} K {r['K_lo'] <= r['K_true'] <= r['K_hi']:d}  "
                    f"{r['time_s']:.2f} s",
                    flush=True,
                )
    s = summarise(rows)
    if a.bias_correction:
        s_unc = summarise([{**r, **r["uncorrected"]} for r in rows if r["success"]])
        s["uncorrected"] = s_unc
        s["correction_applied"] = sum(bool(r.get("applied")) for r in rows)
    lo, hi = s["calibrated_range_95"]
    print(
        f"\n{a.vehicle} on {a.terrain} ({'Gauss-Newton' if a.gauss_newton else 'default'} covariance; "
        f"effects in logs: {a.effect or 'none'}; fitted: {a.fit_effect or 'none'}"
        f"{'; hull channel' if a.hull else ''}), "
        f"{s['succeeded']}/{s['seeds']} fits succeeded, "
        f"{time.time() - t0:.0f} s wall, median fit {s['median_fit_time_s']:.2f} s"
    )
    blocks = [("", s)]
    if a.bias_correction:
        print(f"bias correction {a.bias_correction}: applied in {s['correction_applied']}/{s['succeeded']} fits")
        blocks = [("uncorrected ", s["uncorrected"]), (f"{a.bias_correction} ", s)]
    for label, blk in blocks:
        for p in ("F", "K"):
            q = blk[p]
            print(f"{label}", end="")
            print(
                f"{p:>2}: bias {100 * q['mean_rel_error']:+.2f} % (+- {100 * q['stderr_of_mean']:.2f}), "
                f"sd {100 * q['sd_rel_error']:.2f} %, reported se {100 * q['mean_rel_stderr']:.2f} %, "
                f"z mean {q['mean_z']:+.2f} sd {q['sd_z']:.2f}, 95 % interval holds truth "
                f"{q['coverage']}/{s['succeeded']} ({100 * q['coverage_rate']:.1f} %; calibrated: {lo}-{hi})"
            )
    for p in _effect_labels([r for r in rows if r["success"]]):
        q = s[p]
        print(
            f"{p}: true {q['true']:.5g}, bias {q['mean_error']:+.3g} (sd {q['sd_error']:.3g}), reported se "
            f"{q['mean_stderr']:.3g}, z mean {q['mean_z']:+.2f} sd {q['sd_z']:.2f}, 95 % interval holds truth "
            f"{q['coverage']}/{q['n']} (calibrated: {lo}-{hi})"
        )
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"rows": rows, "summary": s}, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
