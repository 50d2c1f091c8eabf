#!/usr/bin/env python
"""F_max bias of the drive-log fit on logs of the independent simulator, over seeds, one change at a time.

Usage (from the repository root)::

    python benchmarks/drivelog_independent_bias.py                         # case "base", 8 seeds x 10 min
    python benchmarks/drivelog_independent_bias.py --case "no noise" --seeds 2
    python benchmarks/drivelog_independent_bias.py --case "dt 0.1 ms" --seeds 2 --minutes 3

What is measured
----------------
Logs of ``benchmarks/drivelog_independent.py`` (plain numpy, implicit Euler, torque held between samples,
light vehicle on dry sand, random hard pulls, different pulls and noise per seed), written as CSV and
fitted as ``soiltrack fit LOG.csv --vehicle light --json`` does (``fit(read_csv(LOG), VEHICLES["light"],
discretisation_check=True)``; ``--rule relaxation`` fits with ``discretisation="relaxation"`` instead).
Per seed: the error of F_max (percent of the truth) and of K, and the truth's z-score against the
interval (error / standard error); over seeds: the mean error with its standard error over seeds, the
mean and standard deviation of the z-scores, and how many 95 % intervals hold the truth. The cases change
one thing at a time: the simulator's sub-step, the noise of each channel, the rate.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time

import numpy as np

_HERE = os.path.dirname(os.path.abspath(__file__))
for _p in (_HERE, os.path.dirname(_HERE)):
    if _p not in sys.path:
        sys.path.insert(0, _p)

import drivelog_independent as sim  # noqa: E402

from soiltrack.identify import fit  # noqa: E402
from soiltrack.soilmodel import VEHICLES, read_csv  # noqa: E402

Z95 = 1.959963984540054
CASES = {
    "base": {},
    "no noise": dict(noise=None),
    "dt 0.1 ms": dict(dt=1e-4),
    "dt 0.1 ms, no noise": dict(dt=1e-4, noise=None),
    "speed noise only": dict(noise=sim.Noise().scaled(torque=0, encoder=0, imu=0)),
    "encoder noise only": dict(noise=sim.Noise().scaled(torque=0, gnss=0, imu=0)),
    "torque noise only": dict(noise=sim.Noise().scaled(encoder=0, gnss=0, imu=0)),
    "no speed noise": dict(noise=sim.Noise().scaled(gnss=0)),
    "100 Hz": dict(rate_hz=100.0),
}


def fit_one(log: dict, rule: str) -> dict:
    """The log fitted as the command line does; errors and z-scores against its truth."""
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "log.csv")
        sim.write_csv(log, path)
        data = read_csv(path)
    kw = {"discretisation_check": True} if rule == "cli" else {"discretisation": rule}
    t0 = time.process_time()
    res = fit(data, VEHICLES["light"], **kw)
    ex = res.extra
    F_t, K_t = log["truth"]["F_max"], log["truth"]["K"]
    out = {
        "F": ex["max_thrust_N"],
        "errF": 100.0 * (ex["max_thrust_N"] / F_t - 1.0),
        "zF": (ex["max_thrust_N"] - F_t) / ex["max_thrust_stderr_N"],
        "errK": 100.0 * (ex["shear_modulus_m"] / K_t - 1.0),
        "zK": (ex["shear_modulus_m"] - K_t) / ex["shear_modulus_stderr_m"],
        "cpu": time.process_time() - t0,
        "success": bool(res.success),
    }
    chk = ex.get("discretisation_check") or {}
    if chk.get("compared"):
        out["errF_relaxation"] = 100.0 * (chk["relaxation_max_thrust_N"] / F_t - 1.0)
    return out


def summary(rows: list[dict]) -> str:
    """Mean error +- its standard error over seeds, z-score mean and sd, intervals holding the truth."""
    n = len(rows)

    def col(k):
        return np.array([r[k] for r in rows if k in r], dtype=float)

    def mse(a):
        return f"{a.mean():+.2f} % +- {a.std(ddof=1) / math.sqrt(a.size):.2f}" if a.size > 1 else f"{a.mean():+.2f} %"

    zF, zK = col("zF"), col("zK")
    s = (
        f"{n} seeds: F_max error {mse(col('errF'))}, z mean {zF.mean():+.2f} sd {zF.std(ddof=1) if n > 1 else 0:.2f},"
        f" {int(np.sum(np.abs(zF) < Z95))}/{n} intervals hold it; K error {mse(col('errK'))},"
        f" {int(np.sum(np.abs(zK) < Z95))}/{n}"
    )
    rel = col("errF_relaxation")
    if rel.size:
        s += f"; relaxation-rule F_max error {mse(rel)}"
    return s


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default="base", choices=sorted(CASES))
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--rule", default="cli", choices=("cli", "end-point", "relaxation"))
    a = ap.parse_args(argv)
    seeds = range(a.first_seed, a.first_seed + a.seeds)
    t0 = time.process_time()
    logs = sim.simulate(seeds, duration_s=60.0 * a.minutes, **CASES[a.case])
    print(f"case {a.case!r}: {a.seeds} logs of {a.minutes:g} min simulated in {time.process_time() - t0:.0f} s CPU")
    rows = []
    for seed, log in zip(seeds, logs):
        r = fit_one(log, a.rule)
        rows.append(r)
        print(
            f"  seed {seed}: F_max {r['F']:.2f} N ({r['errF']:+.2f} %, z {r['zF']:+.2f}), "
            f"K {r['errK']:+.1f} % (z {r['zK']:+.2f}), {r['cpu']:.1f} s CPU"
            + (f", relaxation rule {r['errF_relaxation']:+.2f} %" if "errF_relaxation" in r else ""),
            flush=True,
        )
    print(summary(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
