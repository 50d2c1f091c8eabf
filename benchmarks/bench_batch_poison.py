#!/usr/bin/env python
"""A large poisoned batch through ``fit_many``: nothing lost, good results equal single fits, speed, memory.

Usage (from the repository root; scipy is a benchmark-only dependency, extra ``bench``)::

    python benchmarks/bench_batch_poison.py [--items 100000] [--poison 0.01] [--check all|N]
                                            [--scipy-subset 200] [--workers 0] [--json [FILE]]

The batch: ``--items`` two-load tractive force-slip sweeps of the heavy vehicle (20 samples each,
random soils in the practical range, 2 % force noise), made with plain numpy (the closed form of
Eq. 2 over the track, not soilmodel), of which a fraction ``--poison`` is replaced by ten kinds of
poison in turn:

  none          ``None`` instead of a sweep
  text          a file name (a string) instead of a sweep
  one_row       a one-row sweep (cannot identify three parameters)
  two_rows      a two-row sweep (neither)
  short_log     a three-sample drive log
  dict          a dict of columns instead of SlipData
  loads_kn      the normal loads in kN (a thousandth of the vehicle's weight)
  forces_kn     the forces in kN
  zero_force    a sweep whose force is zero everywhere
  repeated      every row twice (fitted, said as repeated rows)

What is checked and measured, in one run:

* one result per item, in order; every poisoned item has a reason: a failed result naming its
  batch index, or (``repeated``) the repeated-rows warning with the count;
* every good result equal to ``fit`` of the same sweep alone (theta bit for bit, same success and
  status), for all good items (``--check all``, the default) or the first N;
* throughput of ``fit_many`` (items per second, the whole batch, in this process or on a fork
  process pool of ``--workers``) against a loop of ``scipy.optimize.least_squares`` (bounded TRF,
  numerical Jacobian, what a user would script) on ``--scipy-subset`` good sweeps; and, because a
  shared machine's load drifts between the two, both on the same subset alternated three times;
* peak memory: the process's resident set before the batch and at its peak (``ru_maxrss``),
  and the growth per kept result.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import resource
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

try:
    from scipy.optimize import least_squares
except ImportError:  # --help answers without it; a run says what is missing
    if not {"-h", "--help"} & set(sys.argv[1:]):
        sys.exit("benchmarks need scipy: pip install 'soiltrack[bench]'")

from soiltrack.identify import fit, fit_many
from soiltrack.soilmodel import PRACTICAL_BOUNDS, VEHICLES, DriveLog, SlipData

HEAVY = VEHICLES["heavy"]
L, B = HEAVY.track_length, HEAVY.track_width
AREA = 2 * L * B
N_SAMPLES = 20
ROUNDS = 3  # alternations of fit_many and the scipy loop on the same sweeps
KINDS = (
    "none",
    "text",
    "one_row",
    "two_rows",
    "short_log",
    "dict",
    "loads_kn",
    "forces_kn",
    "zero_force",
    "repeated",
)


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def rss_mb() -> float:
    """Current resident set, MB (Linux /proc; the peak from getrusage where /proc is absent)."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except OSError:  # pragma: no cover
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def thrust(slip, W, c, phi, K):
    """Eq. 2 with the Janosi-Hanamoto shear law integrated over the track, closed form (plain numpy)."""
    X = np.maximum(slip, 1e-9) * L / K
    return (AREA * c + W * np.tan(phi)) * (1 - (1 - np.exp(-X)) / X)


def make_sweep(rng) -> SlipData:
    lo, hi = PRACTICAL_BOUNDS.lower, PRACTICAL_BOUNDS.upper
    c, phi, K = (rng.uniform(lo[j] + 0.1 * (hi[j] - lo[j]), hi[j] - 0.1 * (hi[j] - lo[j])) for j in range(3))
    slip = np.sort(rng.uniform(0.02, 0.6, N_SAMPLES))
    W = np.resize([0.5 * HEAVY.weight, HEAVY.weight], N_SAMPLES)
    F = thrust(slip, W, c, phi, K)
    return SlipData(slip, F * (1 + 0.02 * rng.standard_normal(N_SAMPLES)), W)


def poison(kind: str, d: SlipData):
    if kind == "none":
        return None
    if kind == "text":
        return "sweep_0042.csv"
    if kind == "one_row":
        return d.subset([0])
    if kind == "two_rows":
        return d.subset([0, 1])
    if kind == "short_log":
        return DriveLog([0.0, 0.1, 0.2], [1e3, 1e3, 1e3], [5.0, 5.0, 5.0], [1.0, 1.0, 1.0])
    if kind == "dict":
        return {"slip": d.slip, "tractive_force": d.values}
    if kind == "loads_kn":
        return SlipData(d.slip, d.values, d.normal_load / 1e3)
    if kind == "forces_kn":
        return SlipData(d.slip, d.values / 1e3, d.normal_load)
    if kind == "zero_force":
        return SlipData(d.slip, np.zeros(d.n_samples), d.normal_load)
    if kind == "repeated":
        return d.subset(np.repeat(np.arange(d.n_samples), 2))
    raise ValueError(kind)


def has_reason(kind: str, k: int, r) -> bool:
    """The result of a poisoned item says what is wrong (a failure naming the item, or the repeated rows)."""
    if kind == "repeated":
        found = {f["check"]: f for f in r.extra.get("consistency", {}).get("findings", [])}
        return "repeated_rows" in found and found["repeated_rows"]["count"] == N_SAMPLES
    if r.success:
        return False
    if r.status == "not fitted":
        return r.extra.get("batch_index") == k and r.message.startswith(f"batch item {k} ")
    return bool(r.warnings)  # fitted but refused: the consistency or plausibility warnings say why


def scipy_fit(d: SlipData) -> np.ndarray:
    lo, hi = np.asarray(PRACTICAL_BOUNDS.lower), np.asarray(PRACTICAL_BOUNDS.upper)
    scale = np.array([1e4, 1.0, 1e-2])

    def res(z):
        c, phi, K = z * scale
        return (thrust(d.slip, d.normal_load, c, phi, K) - d.values) / 1e3

    z0 = 0.5 * (lo + hi) / scale
    return least_squares(res, z0, bounds=(lo / scale, hi / scale), method="trf").x * scale


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--items", type=int, default=100_000)
    ap.add_argument("--poison", type=float, default=0.01)
    ap.add_argument("--check", default="all", help="good results compared with single fits: all or a number")
    ap.add_argument("--scipy-subset", type=int, default=200)
    ap.add_argument("--workers", type=int, default=0, help="fork process pool of this size (0: in this process)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", nargs="?", const="-", default=None)
    a = ap.parse_args(argv)
    rng = np.random.default_rng(a.seed)
    t0 = time.perf_counter()
    items: list = [make_sweep(rng) for _ in range(a.items)]
    n_bad = max(len(KINDS), int(round(a.poison * a.items)))
    where = np.sort(rng.choice(a.items, size=n_bad, replace=False))
    kinds = {int(k): KINDS[j % len(KINDS)] for j, k in enumerate(where)}
    for k, kind in kinds.items():
        items[k] = poison(kind, items[k])
    log(f"made {a.items:,} items ({n_bad} poisoned, {len(KINDS)} kinds) in {time.perf_counter() - t0:.1f} s")
    fit(items[next(k for k in range(a.items) if k not in kinds)], HEAVY)  # warm-up: kernels loaded/compiled
    rss0 = rss_mb()
    t0 = time.perf_counter()
    if a.workers:
        with ProcessPoolExecutor(a.workers, mp_context=mp.get_context("fork")) as ex:
            res = fit_many(items, HEAVY, progress=False, executor=ex)
    else:
        res = fit_many(items, HEAVY, progress=False)
    t_batch = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    rss1 = rss_mb()
    assert len(res) == a.items, "results lost"
    reasons = {kind: 0 for kind in KINDS}
    counts = {kind: 0 for kind in KINDS}
    for k, kind in kinds.items():
        counts[kind] += 1
        reasons[kind] += has_reason(kind, k, res[k])
    good = [k for k in range(a.items) if k not in kinds]
    n_check = len(good) if a.check == "all" else min(int(a.check), len(good))
    t0 = time.perf_counter()
    equal = sum(
        1
        for k in good[:n_check]
        if (lambda s, b: s.success == b.success and s.status == b.status and np.array_equal(s.theta, b.theta))(
            fit(items[k], HEAVY), res[k]
        )
    )
    t_single = time.perf_counter() - t0
    good_success = sum(res[k].success for k in good)
    sub = good[: a.scipy_subset]
    t0 = time.perf_counter()
    sp = [scipy_fit(items[k]) for k in sub]
    t_scipy = (time.perf_counter() - t0) / max(len(sub), 1)
    # the same sweeps through both, alternated (a shared machine's load drifts): the fairer ratio
    t_sp, t_fm = [], []
    for _ in range(ROUNDS):
        t0 = time.perf_counter()
        fit_many([items[k] for k in sub], HEAVY, progress=False)
        t_fm.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        for k in sub:
            scipy_fit(items[k])
        t_sp.append(time.perf_counter() - t0)
    same_subset = float(np.median(t_sp) / np.median(t_fm))
    agree = float(
        np.median(
            [
                np.max(np.abs(np.asarray(res[k].theta) - x) / np.maximum(np.abs(x), 1e-9) * (np.abs(x) > 1))
                if res[k].success
                else np.nan
                for k, x in zip(sub, sp)
            ]
        )
    )
    out = {
        "items": a.items,
        "poisoned": n_bad,
        "workers": a.workers,
        "results": len(res),
        "poison_with_reason": {k: f"{reasons[k]}/{counts[k]}" for k in KINDS},
        "all_poison_with_reason": sum(reasons.values()) == n_bad,
        "good_items": len(good),
        "good_success": good_success,
        "good_checked": n_check,
        "good_equal_to_single_fit": equal,
        "fit_many_s": t_batch,
        "fit_many_items_per_s": a.items / t_batch,
        "single_fit_items_per_s": n_check / t_single if t_single > 0 else None,
        "scipy_items_per_s": 1.0 / t_scipy,
        "scipy_subset": len(sub),
        "speedup_vs_scipy": t_scipy * a.items / t_batch,
        "speedup_vs_scipy_same_sweeps_alternated": same_subset,
        "median_rel_diff_vs_scipy_c_phi_K": agree,
        "rss_before_MB": rss0,
        "rss_after_MB": rss1,
        "peak_rss_MB": peak,
        "growth_per_result_kB": (rss1 - rss0) * 1024 / a.items,
    }
    log(
        f"fit_many: {a.items:,} items in {t_batch:.1f} s ({out['fit_many_items_per_s']:,.0f}/s), "
        f"{len(res):,} results; good {good_success:,}/{len(good):,} succeeded"
    )
    log("poison with a reason: " + ", ".join(f"{k} {v}" for k, v in out["poison_with_reason"].items()))
    log(
        f"good results equal to a single fit: {equal:,}/{n_check:,} "
        f"(single fits: {out['single_fit_items_per_s']:,.0f}/s)"
    )
    log(
        f"scipy least_squares loop: {out['scipy_items_per_s']:,.0f}/s on {len(sub)} sweeps -> fit_many "
        f"{out['speedup_vs_scipy']:.1f}x; median largest relative difference of c, phi, K vs scipy "
        f"{agree:.2g}"
    )
    log(
        f"the same {len(sub)} sweeps, fit_many and the scipy loop alternated {ROUNDS} times: fit_many "
        f"{same_subset:.1f}x faster (medians)"
    )
    log(
        f"memory: RSS {rss0:.0f} MB before the batch, {rss1:.0f} MB after, peak {peak:.0f} MB "
        f"({out['growth_per_result_kB']:.2f} kB per kept result)"
    )
    if a.json is not None:
        text = json.dumps(out, indent=2)
        if a.json == "-":
            print(text)
        else:
            with open(a.json, "w") as fh:
                fh.write(text + "\n")
    ok = out["all_poison_with_reason"] and equal == n_check
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
