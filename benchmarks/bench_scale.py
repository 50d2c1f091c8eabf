"""Drive logs from 10^3 to 2x10^6 rows: wall time, peak memory and time per row of fit, track and --segments.

Each measurement runs in its own process (its peak resident memory from ``wait4``): the command-line
``soiltrack fit LOG --vehicle light --json`` (the default fit: latent slips profiled out above 10,000
rows, plus the discretisation check's second fit), ``soiltrack track`` (streamed replay), ``soiltrack
fit --segments 60s``, one profiled fit's solve time per sample and iteration (``iteration``), the
former fit with one IPOPT variable per latent slip (``latent_slips="ipopt"``, the same two fits; up to
``--ipopt-max`` rows) and scipy's ``least_squares`` on the same two-channel problem (latent slips as
variables, sparse Jacobian, ``trf``/``lsmr``; up to ``--scipy-max`` rows).
``fleet``: ``--fleet N:M`` logs of M minutes fitted by ``fit_many(paths, out=CSV)`` on a dask
``LocalCluster`` of 2 worker processes (1 thread each) and on a plain ``ProcessPoolExecutor`` of 2 (fork),
each in its own process: logs per minute, rows per second, peak RSS of each worker (dask: ``client.run``
of ``getrusage``; the pool: the largest child's, ``RUSAGE_CHILDREN``). The logs are the library's
simulator's (light vehicle, dry sand, 50 Hz, default driving, seed 1), made once into ``--dir``.

    python benchmarks/bench_scale.py                                   # 1,000 and 5,000 rows (minutes)
    python benchmarks/bench_scale.py --sizes 1e4,5e4,1.8e5 --ipopt-max 2e4
    python benchmarks/bench_scale.py --sizes 2e6 --tasks fit,track      # the 11-hour log (minutes; 2 GB)
    python benchmarks/bench_scale.py --tasks fleet --fleet 8:2           # 8 logs of 2 min, dask vs a pool
    python benchmarks/bench_scale.py --tasks fleet --fleet 200:10        # the issue's fleet (hours here)

The machine this project measures on has 2 cores shared with other engineers' jobs: the wall times are
those of a loaded machine (the CPU time is printed beside them); the memory is not affected.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

TASKS = ("fit", "track", "segments", "ipopt", "scipy", "iteration", "fleet")
#: The command line of this interpreter's soiltrack (not whichever ``soiltrack`` is first on PATH).
SOILTRACK = [sys.executable, "-m", "soiltrack"]

_FLEET_SNIPPET = """
import csv, resource, sys, time
from soiltrack.soilmodel import VEHICLES
from soiltrack.identify import fit_many
kind, out, paths = sys.argv[1], sys.argv[2], sys.argv[3:]
rows = sum(sum(1 for _ in open(p)) - 1 for p in paths)
def peak():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
if kind == "dask":
    from dask.distributed import Client, LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cl, Client(cl) as c:
        t0 = time.perf_counter()
        res = fit_many(paths, VEHICLES["light"], executor=c.get_executor(), chunk_size=1, out=out, progress=False)
        wall = time.perf_counter() - t0
        workers = sorted(c.run(peak).values())
else:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork")) as ex:
        t0 = time.perf_counter()
        res = fit_many(paths, VEHICLES["light"], executor=ex, chunk_size=1, out=out, progress=False)
        wall = time.perf_counter() - t0
    workers = [resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0]
written = len(list(csv.DictReader(open(out))))
ok = sum(bool(getattr(r, "success", False)) for r in res)
print(f"{len(paths)} logs ({rows:,} rows) in {wall:.1f} s: {60 * len(paths) / wall:.2f} logs/min, "
      f"{rows / wall:,.0f} rows/s; worker peak MB {[round(w) for w in workers]}; {ok} usable, {written} rows in {out}")
"""

_FIT_SNIPPET = """
import sys
from soiltrack.soilmodel import read_csv, VEHICLES
from soiltrack.identify import fit
r = fit(read_csv(sys.argv[1]), VEHICLES["light"], latent_slips=sys.argv[2], discretisation_check=True)
print(r.extra.get("max_thrust_N"), r.extra.get("max_thrust_stderr_N"), r.status)
"""

_ITERATION_SNIPPET = """
import sys, time
from soiltrack.soilmodel import read_csv, VEHICLES
from soiltrack.identify.drivelog import fit_drive_log
log = read_csv(sys.argv[1])
c0 = time.process_time()
r = fit_drive_log(log, VEHICLES["light"], latent_slips="profiled")
cpu = time.process_time() - c0
n, it, t = r.extra["samples_used"], max(r.iterations, 1), r.solve_time
print(f"one profiled fit: solve {t:.2f} s wall, whole fit {cpu:.2f} s CPU, {it} iterations: "
      f"{1e6 * cpu / (n * it):.2f} us CPU per sample per iteration")
"""

_SCIPY_SNIPPET = """
import sys, numpy as np, scipy.sparse as sp
from scipy.optimize import least_squares
from soiltrack.soilmodel import read_csv, VEHICLES
from soiltrack.identify.drivelog.prepare import prepare_drive_log
from soiltrack.identify.drivelog.nlp import eval_pointwise
v = VEHICLES["light"]
p = prepare_drive_log(read_csv(sys.argv[1]), v)
n, r, l = p.n_used, v.sprocket_radius, v.track_length
rw, ss, sc, rho = r * p.sprocket_speed, p.sigma_speed, p.sigma_thrust_cond, p.coupling
def res(x):
    F, dFs, dFF, dFK = eval_pointwise(x[2:], x[0], x[1], l)
    d_s = p.vehicle_speed - rw * (1 - x[2:])
    return np.concatenate([d_s / ss, (p.thrust - F - rho * d_s) / sc])
def jac(x):
    F, dFs, dFF, dFK = eval_pointwise(x[2:], x[0], x[1], l)
    k = np.arange(n)
    rows = np.concatenate([k, n + k, n + k, n + k])
    cols = np.concatenate([2 + k, np.zeros(n, int), np.ones(n, int), 2 + k])
    vals = np.concatenate([rw / ss, -dFF / sc, -dFK / sc, -(dFs + rho * rw) / sc])
    return sp.csr_matrix((vals, (rows, cols)), shape=(2 * n, n + 2))
x0 = np.concatenate([[1.2 * np.quantile(np.abs(p.thrust), 0.99), 0.0155], np.clip(p.slip_measured, -0.9, 0.9)])
lo = np.concatenate([[1.0, 0.006], np.full(n, -0.95)]); hi = np.concatenate([[1e4, 0.05], np.full(n, 0.98)])
s = least_squares(res, np.clip(x0, lo + 1e-9, hi - 1e-9), jac=jac, bounds=(lo, hi), method="trf", tr_solver="lsmr",
                  x_scale="jac", max_nfev=200)
print(s.x[0], None, f"least_squares status {s.status} nfev {s.nfev}")
"""


def _measure(cmd: list[str]) -> dict:
    """Like :func:`_run`, with the peak RSS of the child from ``wait4`` (the process is waited here)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    out_chunks = []
    # read stdout while it runs (a fit's JSON can be large); stderr is small
    while True:
        b = proc.stdout.read(1 << 16)
        if not b:
            break
        out_chunks.append(b[-4096:])
    _, status, ru = os.wait4(proc.pid, 0)
    err = proc.stderr.read().decode(errors="replace")
    proc.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - t0
    tail = b"".join(out_chunks)[-4096:].decode(errors="replace").strip().splitlines()
    return {
        "wall_s": wall,
        "cpu_s": ru.ru_utime + ru.ru_stime,
        "peak_rss_mb": ru.ru_maxrss / 1024.0,
        "rc": proc.returncode,
        "last": tail[-1][:200] if tail else "",
        "err": err.strip().splitlines()[-1][:300] if err.strip() else "",
    }


def _log(directory: str, rows: int) -> str:
    path = os.path.join(directory, f"light_{rows}.csv")
    if not os.path.exists(path):
        dur = (rows - 1) / 50.0
        cmd = [*SOILTRACK, "simulate", "--vehicle", "light", "--terrain", "dry_sand", "--duration", f"{dur:g}"]
        subprocess.run([*cmd, "--seed", "1", "-o", path], check=True, stderr=subprocess.DEVNULL)
    return path


def _fleet(a: argparse.Namespace, py: str) -> None:
    """The fleet measurement: the same N logs on a dask LocalCluster and on a process pool (module notes)."""
    n_logs, minutes = a.fleet.split(":")
    n, rows = int(n_logs), int(float(minutes) * 60 * 50) + 1
    paths = []
    for k in range(n):
        path = os.path.join(a.dir, f"fleet_{rows}_{k + 1}.csv")
        if not os.path.exists(path):
            cmd = [*SOILTRACK, "simulate", "--vehicle", "light", "--terrain", "dry_sand"]
            cmd += ["--duration", f"{(rows - 1) / 50.0:g}", "--seed", str(k + 1), "-o", path]
            subprocess.run(cmd, check=True, stderr=subprocess.DEVNULL)
        paths.append(path)
    for kind in ("dask", "pool"):
        m = _measure([py, "-c", _FLEET_SNIPPET, kind, os.path.join(a.dir, f"fleet_{kind}.csv"), *paths])
        m.update(task=f"fleet-{kind}", rows=n * rows, us_per_row=1e6 * m["wall_s"] / (n * rows))
        result = m["last"] if m["rc"] == 0 else f"rc {m['rc']}: {m['err']}"
        if a.json:
            print(json.dumps(m))
        else:
            print(f"fleet-{kind} ({n} x {rows} rows): {result} [whole run {m['wall_s']:.1f} s wall]", flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="1e3,5e3", help="rows of the logs, comma separated (default: 1e3,5e3)")
    ap.add_argument("--tasks", default="fit,track,segments,iteration,ipopt,scipy", help=f"some of {','.join(TASKS)}")
    ap.add_argument("--ipopt-max", type=float, default=2e4, help="largest log fitted the former way (rows)")
    ap.add_argument("--scipy-max", type=float, default=5e4, help="largest log given to least_squares (rows)")
    ap.add_argument("--dir", default=os.path.join("build", "bench_scale"), help="where the logs are made and kept")
    ap.add_argument("--json", action="store_true", help="one JSON object per measurement")
    ap.add_argument("--fleet", default="8:2", help="task fleet: N:M = N logs of M minutes (default 8:2)")
    a = ap.parse_args(argv)
    sizes = [int(float(s)) for s in a.sizes.split(",") if s.strip()]
    tasks = [t for t in a.tasks.split(",") if t]
    bad = sorted(set(tasks) - set(TASKS))
    if bad:
        ap.error(f"unknown tasks {bad}; expected some of {TASKS}")
    os.makedirs(a.dir, exist_ok=True)
    py = sys.executable
    print(f"# machine: {os.cpu_count()} cores (shared), python {sys.version.split()[0]}", file=sys.stderr)
    if not a.json:
        print(f"{'task':>9} {'rows':>9} {'wall_s':>8} {'cpu_s':>8} {'peak_MB':>8} {'us/row':>7}  result")
    if "fleet" in tasks:
        _fleet(a, py)
    for n in sizes:
        log = _log(a.dir, n) if set(tasks) - {"fleet"} else ""
        for task in tasks:
            if task == "fleet":
                continue
            if task == "ipopt" and n > a.ipopt_max or task == "scipy" and n > a.scipy_max:
                continue
            cmd = {
                "fit": [*SOILTRACK, "fit", log, "--vehicle", "light", "--json"],
                "track": [*SOILTRACK, "track", log, "--vehicle", "light", "--every", str(10**9), "--json"],
                "segments": [*SOILTRACK, "fit", log, "--vehicle", "light", "--segments", "60s", "--json"],
                "ipopt": [py, "-c", _FIT_SNIPPET, log, "ipopt"],
                "scipy": [py, "-c", _SCIPY_SNIPPET, log],
                "iteration": [py, "-c", _ITERATION_SNIPPET, log],
            }[task]
            m = _measure(cmd)
            m.update(task=task, rows=n, us_per_row=1e6 * m["wall_s"] / n)
            if task in ("fit", "segments"):  # (a fit's JSON ends with its residuals: the exit status says it)
                m["last"] = f"exit {m['rc']}"
            result = m["last"] if m["rc"] in (0, 1) else f"rc {m['rc']}: {m['err']}"
            if a.json:
                print(json.dumps(m))
            else:
                print(
                    f"{task:>9} {n:>9} {m['wall_s']:8.2f} {m['cpu_s']:8.2f} {m['peak_rss_mb']:8.0f} "
                    f"{m['us_per_row']:7.0f}  {result[:90]}",
                    flush=True,
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
