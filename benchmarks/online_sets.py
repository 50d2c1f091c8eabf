"""Two fixed log sets for the on-line detector: a TUNING set and a HELD-OUT set (``bench_online.py --set``).

Both come from the independent simulator ``tests/online_oracle.py`` (plain Python, not the library) with
the same design and different seeds (so different pull timings, change times and sizes):

- change logs: heavy and light vehicles x flat and 10 deg x pulls every 4-6, 12-18 and 25-35 s
  (heavy pulls 2-4 s, light 0.1-0.3 s, to 90-97 % of F_max) x F_max down 20-40 %, F_max up 20-40 %
  and K alone x2 = 36 logs of ``CHANGE_LOG_S`` seconds, one change each in the log's second half:
  three of every four between two pulls (a random point of a gap), one inside a pull;
- uniform soil: four 15-minute logs (heavy and light, flat and 10 deg, pulls every 5-30 s) = one hour,
  where every alarm is false.

The tuning set (seed base :data:`SETS` ``["tuning"]``) is the one thresholds may be looked at on; the
held-out set (``["heldout"]``) is run for the report only, never while choosing a setting.
"""

from __future__ import annotations

import math
import time

import numpy as np

import online_compare as oc
import online_oracle as oracle

#: Seed base of each set (the logs of a set are fixed by it).
SETS = {"tuning": 3000, "heldout": 7000}
#: Length of each change log, s.
CHANGE_LOG_S = 150.0
#: Length of each uniform-soil log, s (four of them: one hour).
UNIFORM_LOG_S = 900.0
#: Pull intervals of the change logs, s.
EVERIES = ((4.0, 6.0), (12.0, 18.0), (25.0, 35.0))
KINDS = ("F_down", "F_up", "K_x2")


def cases(name: str) -> list[dict]:
    """The set's scenarios (change logs first, then the uniform-soil logs)."""
    base = SETS[name]
    rnd = np.random.default_rng(base)
    out, k = [], 0
    for veh in ("heavy", "light"):
        for gr in (0.0, 10.0):
            for ev in EVERIES:
                for kind in KINDS:
                    k += 1
                    out.append(
                        dict(
                            vehicle=veh,
                            grade=gr,
                            every=ev,
                            kind=kind,
                            seed=base + k,
                            frac=float(rnd.uniform(0.2, 0.4)),
                            where="pull" if k % 4 == 0 else "gap",
                            pos=float(rnd.uniform(0.2, 0.8)),
                            duration=CHANGE_LOG_S,
                        )
                    )
    for veh in ("heavy", "light"):
        for gr in (0.0, 10.0):
            k += 1
            out.append(
                dict(
                    vehicle=veh,
                    grade=gr,
                    every=(5.0, 30.0),
                    kind="uniform",
                    seed=base + k,
                    frac=0.0,
                    where="-",
                    pos=0.0,
                    duration=UNIFORM_LOG_S,
                )
            )
    return out


def make_log(sc: dict):
    """Simulate one scenario: columns, change times."""
    veh = oracle.VEHICLES[sc["vehicle"]]
    g = math.radians(sc["grade"])
    dur = sc["duration"]
    if sc["kind"] == "uniform":
        old = new = oracle.SOILS["lete_sand"]
    else:
        old, new = oc.soils_for(sc["kind"], sc["frac"], veh, g)
    length = (2.0, 4.0) if sc["vehicle"] == "heavy" else (0.1, 0.3)
    pulls = oracle.random_pulls(dur, sc["every"], length, (0.9, 0.97), sc["seed"])
    changes: list[float] = []
    if sc["kind"] != "uniform":
        late = [j for j, p in enumerate(pulls[:-1]) if p[1] > 0.45 * dur]
        j = late[0]
        a, b, _ = pulls[j]
        if sc["where"] == "gap":
            a, b = b, pulls[j + 1][0]
        changes = [a + sc["pos"] * (b - a)]
    tc = changes[0] if changes else math.inf
    cols = oracle.simulate(
        sc["vehicle"], lambda t: old if t < tc else new, dur, pulls, grade_deg=sc["grade"], seed=sc["seed"]
    )
    return cols, changes


def label(sc: dict) -> str:
    """One scenario in a line."""
    ev = sc["every"]
    return (
        f"{sc['vehicle']} {sc['grade']:g} deg every {ev[0]:g}-{ev[1]:g} s {sc['kind']}"
        + (f" {sc['frac']:.2f} in a {sc['where']}" if sc["kind"] != "uniform" else "")
        + f" seed {sc['seed']}"
    )


def run_set(name: str, estimators=("held",), out=print, only: str | None = None, overrides=None) -> dict:
    """Replay the set through the estimators and print per-log lines and one table; the totals.

    ``overrides``: ``{setting: value}`` given to every ``OnlineSettings`` of the held and window
    estimators (to compare a setting's values on the tuning set).
    """
    if overrides:
        import functools

        from soiltrack.identify import OnlineSettings

        oc.OnlineSettings = functools.partial(OnlineSettings, **overrides)  # type: ignore[assignment]
    tot = {
        n: dict(dF=[], dK=[], mF=0, mK=0, nF=0, nK=0, false=0, false_uni=0, hours=0.0, err=[], cover=[], cpu=[], win=[])
        for n in estimators
    }
    for sc in cases(name):
        if only and only not in label(sc):
            continue
        cols, changes = make_log(sc)
        parts = [label(sc) + ":"]
        for n in estimators:
            c0 = time.process_time()
            run = oc.run_estimator(n, sc["vehicle"], cols, sc["grade"])
            cpu = time.process_time() - c0
            r = oc.score(run, cols, changes)
            T = tot[n]
            key = "K" if sc["kind"] == "K_x2" else "F"
            if changes:
                T["d" + key] += r["delays"]
                T["m" + key] += r["missed"]
                T["n" + key] += len(changes)
            T["false"] += r["false"]
            if sc["kind"] == "uniform":
                T["hours"] += r["hours"]
                T["false_uni"] += r["false"]
            T["err"].append(r["err"])
            T["cover"].append(r["cover"])
            T["cpu"].append(cpu / len(run["t"]))
            T["win"] += r["windows_ok"]
            parts.append(
                f"{n}: delay {[round(d, 2) for d in r['delays']]} missed {r['missed']} false {r['false']}"
                f" alarms {[round(a, 2) for a in run['alarms']]} change {[round(c, 2) for c in changes]}"
            )
        out(" ".join(parts), flush=True)
    out(f"\nset {name} (seed base {SETS[name]}), settings changed: {overrides or 'none'}:")
    out(
        "| estimator | F_max changes detected <= 1 s | K x2 detected <= 1 s | missed (F / K) | "
        "false alarms (all logs) | per uniform hour | F_max error median / p95 | 95 % coverage | "
        "window holds the truth | CPU per sample (mean over logs) |"
    )
    out("|---|---|---|---|---|---|---|---|---|---|")
    for n in estimators:
        T = tot[n]
        err = np.concatenate(T["err"]) if T["err"] else np.array([np.nan])
        cov = np.concatenate(T["cover"]) if T["cover"] else np.array([np.nan])
        f1 = sum(d <= 1.0 for d in T["dF"])
        k1 = sum(d <= 1.0 for d in T["dK"])
        out(
            f"| {n} | {f1} of {T['nF']} | {k1} of {T['nK']} | {T['mF']} / {T['mK']} | {T['false']} | "
            f"{_uniform_rate(T)} | {100 * np.nanmedian(err):.1f} % / {100 * np.nanquantile(err, 0.95):.1f} % | "
            f"{100 * np.nanmean(cov):.1f} % | {sum(T['win'])} of {len(T['win'])} | "
            f"{1e6 * np.mean(T['cpu']):.0f} us |"
        )
    return tot


def _uniform_rate(T: dict) -> str:
    """False alarms per hour of the uniform-soil logs."""
    if T["hours"] <= 0:
        return "-"
    return f"{T['false_uni'] / T['hours']:.2f} ({T['false_uni']} in {T['hours']:.2f} h)"


def main(argv=None) -> None:
    """List a set's logs (the scenarios, not simulated); ``bench_online.py --set`` runs them."""
    import argparse

    ap = argparse.ArgumentParser(
        description="The on-line detector's fixed log sets: list the scenarios of one "
        "(run them with bench_online.py --set NAME)."
    )
    ap.add_argument("--set", choices=sorted(SETS), default="tuning", help="which set to list (default: tuning)")
    args = ap.parse_args(argv)
    for sc in cases(args.set):
        print(label(sc))


if __name__ == "__main__":
    main()
