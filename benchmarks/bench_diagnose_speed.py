"""Time of one drive-log diagnosis on a 3,001-sample log (60 s at the simulator's 50 Hz), in a fresh process.

Run:  python benchmarks/bench_diagnose_speed.py [--vehicle light] [--runs 3] [--seconds 60] [--source sim|plain]
                                               [--fresh-cache]
Each run is a new Python process (solver builds included, as for the CLI); prints the verdict,
wall-clock and CPU time of each run and their medians, and the load average before and after.
``--fresh-cache``: the runs share a new, empty compiled-code cache folder (``SOILTRACK_CACHE_DIR``,
printed; left in place, background compilations may still be writing to it): the first run is the
first use on a new machine, the next ones what follows while the background compilations finish.

``--source plain``: instead of the library's simulator, the plain-numpy generator of
``benchmarks/independent_check.py`` (heavy vehicle, a sampled continuous torque at 20 Hz, grade
0.05 rad, and one effect-free log), stretched to 3,000 samples (150 s): logs the library did not
make, diagnosed with the default torque hold and with ``torque_hold="sample"`` (which describes them).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

ONE = r"""
import json, sys, time
sys.path.insert(0, {root!r})
from soiltrack.identify import diagnose
from soiltrack.soilmodel import TERRAINS, VEHICLES, simulate
v = VEHICLES[{vehicle!r}]
log = simulate(v, TERRAINS["lete_sand"], kind="drive", effects={{"grade": 0.03}}, seed=1, duration_s={seconds})
t, c = time.perf_counter(), time.process_time()
d = diagnose(log, v)
print(json.dumps({{"n": log.n_samples, "verdict": d.verdict, "confidence": d.confidence, "shrink": d.shrink,
                  "wall": time.perf_counter() - t, "cpu": time.process_time() - c}}))
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vehicle", default="light")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--source", choices=("sim", "plain"), default="sim")
    ap.add_argument("--fresh-cache", action="store_true")
    a = ap.parse_args(argv)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = dict(os.environ)
    if a.fresh_cache:
        import tempfile

        env["SOILTRACK_CACHE_DIR"] = tempfile.mkdtemp(prefix="soiltrack_bench_cache_")
        print("empty compiled-code cache:", env["SOILTRACK_CACHE_DIR"])
    if a.source == "plain":
        return plain(root, a.runs)
    print("load average before:", os.getloadavg())
    rows = []
    for _ in range(a.runs):
        out = (
            subprocess.run(
                [sys.executable, "-c", ONE.format(root=root, vehicle=a.vehicle, seconds=a.seconds)],
                capture_output=True,
                text=True,
                check=True,
                env=env,
            )
            .stdout.strip()
            .splitlines()[-1]
        )
        rows.append(json.loads(out))
        r = rows[-1]
        print(
            f"{a.vehicle}: {r['n']} samples -> {r['verdict']} ({r['confidence']:.2f}), shrink "
            f"{r['shrink'] if r['shrink'] is None else round(r['shrink'], 2)}: wall {r['wall']:.2f} s, "
            f"CPU {r['cpu']:.2f} s",
            flush=True,
        )
    med = lambda k: sorted(r[k] for r in rows)[len(rows) // 2]  # noqa: E731
    print(f"median of {len(rows)}: wall {med('wall'):.2f} s, CPU {med('cpu'):.2f} s")
    print("load average after:", os.getloadavg())
    return 0


PLAIN = r"""
import json, sys, time
sys.path.insert(0, {root!r}); sys.path.insert(0, {bench!r})
import independent_check as ic
from soiltrack.identify import diagnose
from soiltrack.soilmodel import Vehicle, read_csv
ic.log_csv({path!r}, 1, grade={grade}, duration=150.0)
log = read_csv({path!r})
v = Vehicle.from_json(ic.VEHICLE)
t, c = time.perf_counter(), time.process_time()
d = diagnose(log, v, torque_hold={hold!r})
print(json.dumps({{"n": log.n_samples, "verdict": d.verdict, "confidence": d.confidence,
                  "wall": time.perf_counter() - t, "cpu": time.process_time() - c}}))
"""


def plain(root: str, runs: int) -> int:
    """The plain-numpy logs of independent_check.py at 3,000 samples, each diagnosis in a fresh process."""
    import tempfile

    print("load average before:", os.getloadavg())
    with tempfile.TemporaryDirectory() as tmp:
        for grade in (0.05, 0.0):
            for hold in ("zoh", "sample"):
                walls = []
                for _ in range(runs):
                    code = PLAIN.format(
                        root=root,
                        bench=os.path.join(root, "benchmarks"),
                        grade=grade,
                        hold=hold,
                        path=os.path.join(tmp, "log.csv"),
                    )
                    out = (
                        subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
                        .stdout.strip()
                        .splitlines()[-1]
                    )
                    r = json.loads(out)
                    walls.append(r["wall"])
                    print(
                        f"plain log, grade {grade}, torque_hold={hold}: {r['n']} samples -> {r['verdict']} "
                        f"({r['confidence']:.2f}): wall {r['wall']:.2f} s, CPU {r['cpu']:.2f} s",
                        flush=True,
                    )
                print(f"  median of {runs}: wall {sorted(walls)[len(walls) // 2]:.2f} s")
    print("load average after:", os.getloadavg())
    return 0


if __name__ == "__main__":
    sys.exit(main())
