"""Validation of the sim-to-real diagnosis on withheld effects (issue 9), on the simulator's data.

Three ways:

(a) effect in the data, withheld from the nominal model: each effect at two magnitudes, noise
    levels, terrains, both reference vehicles, seeds, plus effect-free data;
(b) the true effect withheld from the candidates (leave-one-out): the honest answers are
    ``unexplained`` or a confidence <= 0.5;
(c) effects outside the library, on drive logs: a speed-sensor delay (the vehicle-speed channel
    shifted by a few samples) and a softer patch of terrain in the middle of a run (the log
    spliced from runs on two soils with the same speed reference; the window must be found).

Each case also gets its detectability: the RMS misfit the effect leaves after the NOMINAL model
is fitted to the noise-free data (what the soil cannot absorb), over the noise level. Accuracy
targets are checked where that ratio exceeds 3; below it, ``none`` is a correct answer too.

Run:  python benchmarks/bench_diagnose.py [--quick] [--kinds sweep,drive] [--effects radius_error] [--png confusion.png]
(the figure goes to benchmarks/out/, which git ignores, unless --png names another path)
Timings are wall-clock on whatever machine runs it (say how loaded it was).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections import defaultdict

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from soiltrack.identify import diagnose, fit  # noqa: E402
from soiltrack.identify.estimates.records import solver_converged  # noqa: E402
from soiltrack.identify.sweep.model import SweepResiduals  # noqa: E402
from soiltrack.soilmodel import EFFECTS, TERRAINS, VEHICLES, DataError, DriveLog, SensorNoise, simulate  # noqa: E402

NOISE = {
    "sweep": {"low": SensorNoise(force_rel=0.005, slip_abs=0.0005), "default": SensorNoise()},
    "drive": {
        "default": SensorNoise(),
        "double": SensorNoise(
            encoder_rel=0.01, encoder_abs=0.02, gnss_speed=0.1, imu_accel=0.1, torque_rel=0.02, torque_fs=0.002
        ),
    },
}
SLIPS = tuple(np.round(np.linspace(0.01, 0.7, 60), 4))
#: The grid's vehicles and terrains (``--quick``: the first of each).
GRID_VEHICLES = ("light", "heavy")
GRID_TERRAINS = ("lete_sand", "dry_sand")


def magnitudes(name: str, vehicle) -> list:
    """Two magnitudes per effect (small, large), in the parse_effects form."""
    Wr = vehicle.weight * vehicle.sprocket_radius
    return {
        "grade": [0.02, 0.06],
        "speed_resistance": [0.02, 0.06],
        "slip_sinkage": [0.05, 0.15],
        "drivetrain_friction": [0.01 * Wr, 0.03 * Wr],
        "radius_error": [0.02, 0.05],
        "hump_shear": [0.15, 0.3],
        "pressure_distribution": [0.2, 0.4],
        "mass_error": [0.1, 0.25],
    }[name]


def make(kind, vehicle, soil, effects, seed, noise, duration=60.0, slips=SLIPS):
    if kind == "sweep":
        return simulate(vehicle, soil, kind="sweep", effects=effects, seed=seed, slips=slips, noise=noise)
    return simulate(vehicle, soil, kind="drive", effects=effects, seed=seed, noise=noise, duration_s=duration)


def detectability(kind, vehicle, soil, effects, seed, noise_level_data, duration=60.0) -> float:
    """RMS nominal misfit on the noise-free data over the RMS noise of the noisy data (per channel, max)."""
    if not effects:
        return 0.0
    clean = make(kind, vehicle, soil, effects, seed, "none", duration)
    try:
        r = fit(clean, vehicle)
        if kind == "sweep" and not r.success and solver_converged(r):
            # converged, only flagged implausible: the misfit an effect leaves is what it measures
            res = SweepResiduals().residuals_on(r, clean, accept_implausible=True)
        else:
            res = r.residuals_on(clean)
    except (DataError, RuntimeError):
        return float("nan")
    out = 0.0
    for ch, v in res.items():
        v = np.asarray(v, float)
        v = v[np.isfinite(v)]
        s = noise_level_data.get(ch)
        if s and v.size:
            out = max(out, float(np.sqrt(np.mean(v**2))) / s)
    return out


def drive_effects_supported(vehicle) -> bool:
    log = simulate(vehicle, TERRAINS["lete_sand"], kind="drive", seed=0, duration_s=5.0)
    try:
        fit(log, vehicle, effects=["grade"])
        return True
    except (DataError, TypeError) as e:
        print(f"drive logs skipped: fits of drive logs with effects are not available here ({e})")
        return False


def run_case(kind, vname, tname, eff_name, mag, nname, seed, candidates=None, duration=60.0, weigh_outside=True):
    """Simulate one case, diagnose it, and measure its detectability."""
    vehicle, soil = VEHICLES[vname], TERRAINS[tname]
    effects = {eff_name: mag} if eff_name != "none" else None
    data = make(kind, vehicle, soil, effects, seed, NOISE[kind][nname], duration)
    t0 = time.perf_counter()
    d = diagnose(data, vehicle, candidates=candidates, weigh_outside=weigh_outside)
    dt = time.perf_counter() - t0
    # sweeps: the noise level is the simulator's, not the diagnosis' estimate (which would move the goalposts
    # whenever the estimate changes): RMS of the data minus the noise-free truth at the reported slips
    noise_level = d.noise
    if kind == "sweep":
        truth = make(kind, vehicle, soil, effects, seed, "none", duration, slips=np.clip(data.slip, 0.0, 0.999))
        noise_level = {data.channel: float(np.sqrt(np.mean((np.asarray(data.values) - truth.values) ** 2)))}
    det = detectability(kind, vehicle, soil, effects, seed, noise_level, duration)
    return {
        "kind": kind,
        "vehicle": vname,
        "terrain": tname,
        "effect": eff_name,
        "mag": mag,
        "noise": nname,
        "seed": seed,
        "verdict": d.verdict,
        "confidence": d.confidence,
        "shrink": d.shrink,
        "explained": d.explained,
        "cause": d.cause,
        "time": dt,
        "det": det,
        "n": data.n_samples,
        "outside": weigh_outside,
        "confusable": [c.effects for c in d.confusable],
        "diag": d,
    }


# ----------------------------------------------------------------------------- out of library
def delayed_speed_log(vehicle, soil, seed, lag=10, duration=60.0):
    log = simulate(vehicle, soil, kind="drive", seed=seed, duration_s=duration)
    v = np.asarray(log.vehicle_speed)
    vs = np.concatenate([np.full(lag, v[0]), v[:-lag]])  # the speed sensor reports lag samples late
    return DriveLog(
        log.time,
        log.sprocket_torque,
        log.sprocket_speed,
        vs,
        log.vehicle_accel,
        source=f"drive log with a {lag}-sample speed-sensor delay",
    )


def soft_patch_log(vehicle, soil, soft, seed, t1=25.0, t2=40.0, duration=60.0):
    a = simulate(vehicle, soil, kind="drive", seed=seed, duration_s=duration)
    b = simulate(vehicle, soft, kind="drive", seed=seed, duration_s=duration)
    m = (a.time >= t1) & (a.time < t2)
    cols = {}
    for name in ("sprocket_torque", "sprocket_speed", "vehicle_speed", "vehicle_accel"):
        x, y = getattr(a, name), getattr(b, name)
        cols[name] = None if x is None else np.where(m, y, x)
    return DriveLog(
        a.time,
        cols["sprocket_torque"],
        cols["sprocket_speed"],
        cols["vehicle_speed"],
        cols["vehicle_accel"],
        source=f"drive log with a softer patch from {t1} s to {t2} s",
    )


# ----------------------------------------------------------------------------- reporting
def confusion_png(rows, labels, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = labels + ["unexplained"]
    M = np.zeros((len(labels), len(cols)))
    for r in rows:
        if r["effect"] in labels:
            M[labels.index(r["effect"]), cols.index(r["verdict"]) if r["verdict"] in cols else -1] += 1
    fig, ax = plt.subplots(figsize=(9, 7))
    Mn = M / np.maximum(1, M.sum(axis=1, keepdims=True))
    ax.imshow(Mn, cmap="Blues", vmin=0, vmax=1)
    for i in range(M.shape[0]):
        for j in range(M.shape[1]):
            if M[i, j]:
                ax.text(j, i, int(M[i, j]), ha="center", va="center", color="k" if Mn[i, j] < 0.6 else "w")
    ax.set_xticks(range(len(cols)), cols, rotation=45, ha="right")
    ax.set_yticks(range(len(labels)), labels)
    ax.set_xlabel("verdict")
    ax.set_ylabel("effect in the data")
    ax.set_title("diagnosis confusion matrix (counts; colour = row share)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def print_confusion(rows, labels):
    cols = labels + ["unexplained"]
    w = max(len(c) for c in cols)
    print(" " * (w + 2) + " ".join(f"{c[:6]:>6s}" for c in cols))
    for lab in labels:
        cnt = defaultdict(int)
        for r in rows:
            if r["effect"] == lab:
                cnt[r["verdict"]] += 1
        print(f"{lab:>{w}s}  " + " ".join(f"{cnt.get(c, 0):6d}" for c in cols))


def summarise(rows, title):
    print(f"\n=== {title}: {len(rows)} diagnoses ===")
    if not rows:
        return
    labels = ["none"] + [e for e in EFFECTS if any(r["effect"] == e for r in rows)]
    print_confusion(rows, labels)
    print("\ntop-1 accuracy where detectable (nominal misfit > 3 x noise), by effect and noise level:")
    for e in labels[1:]:
        for nz in sorted({r["noise"] for r in rows}):
            sel = [r for r in rows if r["effect"] == e and r["noise"] == nz]
            det = [r for r in sel if r["det"] > 3]
            ok = sum(r["verdict"] == e for r in det)
            allok = sum(r["verdict"] == e for r in sel)
            wrong = sum(r["verdict"] not in (e, "none", "unexplained") and r["confidence"] > 0.5 for r in sel)
            print(
                f"  {e:<22s} {nz:<8s} detectable {ok}/{len(det)}"
                f"{'' if not det else f' = {ok / len(det):.0%}'}   all cases {allok}/{len(sel)}   "
                f"confident wrong (>0.5): {wrong}"
            )
    det_all = [r for r in rows if r["effect"] != "none" and r["det"] > 3]
    if det_all:
        ok = sum(r["verdict"] == r["effect"] for r in det_all)
        print(
            f"  all detectable cases: {ok}/{len(det_all)} = {ok / len(det_all):.0%}; misses (verdict, confidence, "
            "confusable pairs named):"
        )
        for r in det_all:
            if r["verdict"] != r["effect"]:
                print(f"    {_line(r)}  confusable {r['confusable'] or '-'}")
        twin = [
            r
            for r in det_all
            if r["verdict"] != r["effect"] and {r["verdict"], r["effect"]} in [set(p) for p in r["confusable"]]
        ]
        print(
            f"  of the {len(det_all) - ok} misses, {len(twin)} name the effect's confusable twin (the pair shares its "
            "weight: these data cannot tell the two apart, and the tie-break names one of them)"
        )
    free = [r for r in rows if r["effect"] == "none"]
    if free:
        fa = sum(r["verdict"] != "none" for r in free)
        print(f"false alarms on effect-free data: {fa}/{len(free)} = {fa / len(free):.0%}")
    if rows and rows[0]["kind"] == "drive":
        terr = [r for r in rows if r["cause"] == "terrain_change"]
        print(
            f"uniform-soil logs that claim a change of terrain: {len(terr)}/{len(rows)}"
            + "".join(f"\n    {_line(r)}" for r in terr[:5])
        )
    right = [
        r["shrink"]
        for r in rows
        if r["effect"] not in ("none",) and r["verdict"] == r["effect"] and r["shrink"] is not None
    ]
    if right:
        print(f"median held-out shrink when right: {np.median(right):.2f} (n = {len(right)})")
    gaps = [
        r["explained"]
        for r in rows
        if r["effect"] not in ("none",) and r["verdict"] == r["effect"] and r.get("explained") is not None
    ]
    if gaps:
        print(
            f"median share of the excess error over the noise explained when right: {np.median(gaps):.2f} "
            f"(n = {len(gaps)})"
        )
    ts = [r["time"] for r in rows]
    print(
        f"time per diagnosis: median {np.median(ts):.2f} s, max {max(ts):.2f} s (n = {len(ts)}; samples "
        f"{sorted({r['n'] for r in rows})})"
    )


#: Where the confusion matrix goes by default (a folder git ignores: no figure lands in the repository).
DEFAULT_PNG = os.path.join(os.path.dirname(os.path.abspath(__file__)), "out", "bench_diagnose_confusion.png")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a small grid (a few minutes)")
    ap.add_argument("--kinds", default="sweep,drive")
    ap.add_argument("--png", default=DEFAULT_PNG, help="confusion-matrix figure (default in benchmarks/out/)")
    ap.add_argument("--log-seconds", type=float, default=60.0, help="duration of the simulated drive logs")
    ap.add_argument("--vehicles", default=None, help="subset, e.g. light,heavy (default: the grid's)")
    ap.add_argument("--terrains", default=None, help="subset, e.g. lete_sand (default: the grid's)")
    ap.add_argument("--noises", default=None, help="subset of noise levels, e.g. default (default: the grid's)")
    ap.add_argument("--seeds", default=None, help="subset of seeds, e.g. 1 (default: 1,2,3; --quick 1)")
    ap.add_argument(
        "--effects",
        default=None,
        help="subset of effects, e.g. radius_error or none,grade (default: all that show, the effect-free logs "
        "and the out-of-library logs; a subset runs only the effects named)",
    )
    ap.add_argument("--max-loo", type=int, default=None, help="leave-one-out cases per kind (default 40; quick 2/8)")
    a = ap.parse_args(argv)
    kinds = [k for k in a.kinds.split(",") if k]
    chosen = set(a.effects.split(",")) if a.effects else None  # --effects: only these (and "none" if named)
    if "drive" in kinds and not drive_effects_supported(VEHICLES["light"]):
        kinds.remove("drive")
    rows, loo, ool = [], [], []
    seeds = (1,) if a.quick else (1, 2, 3)
    if a.seeds:
        seeds = tuple(int(x) for x in a.seeds.split(","))
    for kind in kinds:
        vehicles = GRID_VEHICLES[:1] if a.quick else GRID_VEHICLES
        terrains = GRID_TERRAINS[:1] if a.quick else GRID_TERRAINS
        noises = list(NOISE[kind])[:1] if a.quick else list(NOISE[kind])
        vehicles = tuple(a.vehicles.split(",")) if a.vehicles else vehicles
        terrains = tuple(a.terrains.split(",")) if a.terrains else terrains
        noises = [x for x in a.noises.split(",") if x in NOISE[kind]] if a.noises else noises
        names = [e for e, s in EFFECTS.items() if kind in s.shows_in]
        if chosen is not None:
            names = [e for e in names if e in chosen]
        # a drive-log diagnosis costs about a minute on a loaded 2-core machine: a smaller grid
        dur = a.log_seconds
        mags = (lambda e, v: magnitudes(e, v)[-1:]) if kind == "drive" and a.quick else magnitudes
        free_seeds = (
            (seeds + (2, 3)) if a.quick and kind == "sweep" else ((1, 2) if kind == "drive" and a.quick else seeds)
        )
        free_seeds = tuple(dict.fromkeys(free_seeds))
        for vname in vehicles:
            for tname in terrains:
                for nname in noises:
                    for seed in free_seeds if chosen is None or "none" in chosen else ():
                        rows.append(run_case(kind, vname, tname, "none", None, nname, seed, duration=dur))
                        print(_line(rows[-1]), flush=True)
                    for e in names:
                        for mag in mags(e, VEHICLES[vname]):
                            for seed in seeds:
                                rows.append(run_case(kind, vname, tname, e, mag, nname, seed, duration=dur))
                                print(_line(rows[-1]), flush=True)
        # (b) leave-one-out on the detectable cases of the first vehicle/terrain/noise
        n_loo = a.max_loo if a.max_loo is not None else (2 if kind == "drive" else 8) if a.quick else 40
        for r in [r for r in rows if r["kind"] == kind and r["effect"] != "none" and r["det"] > 3][:n_loo]:
            cands = [e for e, s in EFFECTS.items() if kind in s.shows_in and e != r["effect"]]
            loo.append(
                run_case(
                    kind,
                    r["vehicle"],
                    r["terrain"],
                    r["effect"],
                    r["mag"],
                    r["noise"],
                    r["seed"],
                    candidates=cands,
                    duration=dur,
                )
            )
            print("LOO " + _line(loo[-1]), flush=True)
            if kind == "sweep":  # the same without weighing the left-out library effects: the flexible term and
                # the lack-of-fit test alone must keep the confidence honest
                loo.append(
                    run_case(
                        kind,
                        r["vehicle"],
                        r["terrain"],
                        r["effect"],
                        r["mag"],
                        r["noise"],
                        r["seed"],
                        candidates=cands,
                        duration=dur,
                        weigh_outside=False,
                    )
                )
                print("LOO-blind " + _line(loo[-1]), flush=True)
    if "drive" in kinds and chosen is None:
        v, s = VEHICLES["light"], TERRAINS["lete_sand"]
        soft = TERRAINS["dry_sand"]
        T = a.log_seconds
        t1, t2 = round(0.4 * T), round(0.65 * T)
        for seed in seeds:
            for label, log in (
                ("speed-sensor delay 10 samples", delayed_speed_log(v, s, seed, duration=T)),
                (f"softer patch {t1}-{t2} s", soft_patch_log(v, s, soft, seed, t1, t2, duration=T)),
            ):
                t0 = time.perf_counter()
                d = diagnose(log, v)
                ool.append((label, d, time.perf_counter() - t0))
                det = d.cause_detail
                win = f"cause {d.cause}"
                if "window_s" in det:
                    w0, w1 = det["window_s"]
                    win += f" window {w0:.1f}-{w1:.1f} s (patch {t1}-{t2} s)"
                if "lag_s" in det:
                    win += f" lag {det['lag_s']:.3g} s ({det['lag_samples']} samples)"
                print(
                    f"OOL {label} seed {seed}: {d.verdict} ({d.confidence:.2f}); {win}; {d.elapsed_s:.1f} s", flush=True
                )
    for kind in kinds:
        summarise([r for r in rows if r["kind"] == kind], f"(a) effect withheld from the model, {kind}")
        for blind in (False, True):
            L = [r for r in loo if r["kind"] == kind and r["outside"] != blind]
            if L:
                bad = sum(r["verdict"] not in ("unexplained", "none") and r["confidence"] > 0.5 for r in L)
                what = (
                    "without weighing the left-out library effects (weigh_outside=False)"
                    if blind
                    else "as diagnosed (the left-out effects weighed)"
                )
                print(
                    f"(b) leave-one-out, {kind}, {what}: {len(L)} cases, confident (>0.5) wrong names {bad}; "
                    "verdicts: " + ", ".join(f"{k} {v}" for k, v in sorted(_count(r["verdict"] for r in L).items()))
                )
    if ool:
        bad = sum(d.verdict not in ("unexplained", "none") and d.confidence > 0.5 for _, d, _ in ool)
        print(f"(c) out of library: {len(ool)} cases, confident (>0.5) names {bad}")
    if rows:
        labels = ["none"] + [e for e in EFFECTS if any(r["effect"] == e for r in rows)]
        os.makedirs(os.path.dirname(os.path.abspath(a.png)), exist_ok=True)
        confusion_png(rows, labels, a.png)
        print(f"confusion matrix saved to {a.png}")
    return 0


def _count(it):
    out = defaultdict(int)
    for x in it:
        out[x] += 1
    return out


def _line(r):
    return (
        f"{r['kind']:<5s} {r['vehicle']:<5s} {r['terrain']:<10s} {r['noise']:<7s} {r['effect']:<21s} "
        f"{'' if r['mag'] is None else format(r['mag'], '.3g'):>7s} s{r['seed']} det {r['det']:6.1f} -> "
        f"{r['verdict']:<21s} {r['confidence']:.2f} shrink {'-' if r['shrink'] is None else format(r['shrink'], '.2f')}"
        f" {r['time']:.2f}s"
    )


if __name__ == "__main__":
    sys.exit(main())
