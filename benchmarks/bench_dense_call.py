"""The slip-step kernel of a drive-log fit: a plain CasADi call against ``call_dense`` (the buffer interface).

Run:  python benchmarks/bench_dense_call.py [--vehicle heavy] [--seconds 60] [--calls 200]

The kernel is the one the fit's per-sample Newton iterations call (``SLIP_CHUNK`` samples per
chunk, mapped over the log); both ways evaluate the same C code or virtual machine on the same
data, and the benchmark checks their outputs are equal before timing them. Prints milliseconds per
call for: the plain call with the data already a ``DM`` (as the library called it before), the
plain call plus the conversion of its outputs to numpy, and ``call_dense``.
"""

from __future__ import annotations

import argparse
import time

import casadi as ca
import numpy as np

from soiltrack.identify.drivelog.joint import SLIP_CHUNK, SlipSolver, joint_data, padded_data
from soiltrack.identify.drivelog.prepare import prepare_drive_log
from soiltrack.soilmodel import TERRAINS, VEHICLES, simulate
from soiltrack.soilmodel.dense_call import call_dense
from soiltrack.soilmodel.effects import effect_structure


def _per_call(f, calls: int) -> float:
    t = time.perf_counter()
    for _ in range(calls):
        f()
    return (time.perf_counter() - t) / calls * 1e3


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vehicle", default="heavy")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--calls", type=int, default=200)
    a = ap.parse_args(argv)
    v = VEHICLES[a.vehicle]
    log = simulate(v, TERRAINS["lete_sand"], kind="drive", seed=1, duration_s=a.seconds)
    prep = prepare_drive_log(log, v)
    jd = joint_data(log, v, prep)
    structure = effect_structure(None, v)
    solver = SlipSolver(v, structure, jd.D)
    chunked = solver.step_k
    n = prep.n_used
    k = -(-n // SLIP_CHUNK)
    size = k * SLIP_CHUNK
    fn = chunked.fn.map(k)
    th = np.zeros((fn.size1_in(0) // size if fn.size2_in(0) == 1 else fn.size1_in(0), 1))
    th[:2, 0] = (0.6 * v.mass * 9.81, 0.03)  # a thrust limit of 0.6 W and K = 3 cm
    s = np.full((1, size), 0.05)
    D = padded_data(jd.D, size)
    Ddm = ca.DM(D)
    plain = [np.asarray(o, dtype=float) for o in fn(th, s, Ddm)]
    fast = call_dense(fn, th, s, D)
    same = all(np.array_equal(p, q) for p, q in zip(plain, fast))
    print(f"{a.vehicle} log, {n} samples in {k} chunks of {SLIP_CHUNK}; outputs equal: {same}")
    t_plain = _per_call(lambda: fn(th, s, Ddm), a.calls)
    t_conv = _per_call(lambda: [np.asarray(o, dtype=float) for o in fn(th, s, Ddm)], a.calls)
    t_fast = _per_call(lambda: call_dense(fn, th, s, D), a.calls)
    print(f"plain call, data already a DM, outputs left as DM: {t_plain:.3f} ms per call")
    print(f"plain call + outputs to numpy (as the library called it): {t_conv:.3f} ms per call")
    print(f"call_dense (buffer interface, numpy in and out): {t_fast:.3f} ms per call")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
