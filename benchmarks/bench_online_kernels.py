"""The on-line estimator's compiled kernels at each compiler flag set, and its noise re-estimate (issue 38 item 6).

On states of a 256-sample horizon taken from a replay of two logs of the independent simulator
(``tests/online_oracle.py``: the heavy vehicle with 4 s pulls and a change of terrain at 79.5 s, seed 7;
the light vehicle with 0.2 s pulls every 4.3 s, seed 9), per flag set (``jitcache.FLAGS``, ``-O2``;
``jitcache.FLAGS_O3``, the kernels' own, ``kernels.KERNEL_FLAGS``):

- the CPU time per call of the tracking step (``online_track_256``) and the full step (``online_step_256``),
  the best of ``--repeats`` x 100 calls per state, median over the states;
- whether the outputs are the same bit for bit as at ``-O2``.

Then the noise re-estimate of one horizon (``identify.drivelog.noise.noise_model`` on its three channels),
CPU time per call (best of 5 x 100)::

    python benchmarks/bench_online_kernels.py
    python benchmarks/bench_online_kernels.py --repeats 30
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
KEYS = ("time_s", "sprocket_torque_Nm", "sprocket_speed_rad_s", "vehicle_speed_m_s")
#: (log, vehicle, samples at which the horizon's state is taken)
STOPS = (("heavy", (1500, 2600, 4100, 5000)), ("light", (800, 2000)))


def _logs() -> dict:
    sys.path.insert(0, os.path.join(_ROOT, "tests"))
    from online_oracle import SOILS, simulate

    heavy_pulls = [(t, t + 4.0, 0.95) for t in (1, 20, 34, 48, 80, 94, 108)]
    light_pulls = [(t, t + 0.2, 0.95) for t in np.arange(1.0, 60.0, 4.3)]
    return {
        "heavy": simulate(
            "heavy", lambda t: SOILS["lete_sand"] if t < 79.5 else SOILS["weak"], 120.0, heavy_pulls, seed=7
        ),
        "light": simulate("light", lambda t: SOILS["lete_sand"], 60.0, light_pulls, seed=9),
    }


def states() -> tuple[list, dict]:
    """``(D, Z, P)`` of the horizon at the samples of :data:`STOPS`, and the last horizon's readings per log."""
    from soiltrack.identify import OnlineEstimator, OnlineSettings
    from soiltrack.soilmodel import VEHICLES

    out, hist = [], {}
    logs = _logs()
    for name, stops in STOPS:
        est = OnlineEstimator(VEHICLES[name], OnlineSettings())
        for k, row in enumerate(zip(*(logs[name][c] for c in KEYS))):
            est.update(*row)
            if k in stops:
                out.append((est._D.copy(), est._Z.copy(), est._P.copy()))
        hist[name] = np.array(est._hist, dtype=float)
    return out, hist


def _best_call(call, repeats: int, n: int = 100) -> float:
    best = np.inf
    for _ in range(repeats):
        c0 = time.process_time()
        for _ in range(n):
            call()
        best = min(best, (time.process_time() - c0) / n)
    return float(best)


def time_flags(sts: list, repeats: int) -> None:
    """Per flag set: the steps' CPU time per call and whether their outputs equal ``-O2``'s bit for bit."""
    from soiltrack.identify import jitcache
    from soiltrack.identify.online import kernels as K
    from soiltrack.identify.online.ccall import BufferCall

    cap = sts[0][0].shape[0]
    fns = K.kernel_functions(cap)[:2]  # step, track
    ref = None
    for label, flags in (("-O2 (jitcache.FLAGS)", jitcache.FLAGS), ("-O3 (jitcache.FLAGS_O3)", jitcache.FLAGS_O3)):
        comp = jitcache.load(fns, f"bench_online_kernels_{cap}", wait=True, flags=flags)
        if not comp.is_c:
            print(f"{label}: {comp.backend}; nothing to time")
            return
        outs, times = [], []
        for fn in fns:
            D, Z, P = np.zeros((cap, len(K.ROWS))), np.zeros(cap), np.zeros(len(K.PARAMS))
            res = [np.zeros(2), np.zeros(cap), np.zeros(len(K.SUMS))]
            call = BufferCall(fn, comp.path, [D, Z, P], res)
            per = []
            for D0, Z0, P0 in sts:
                D[:], Z[:], P[:] = D0, Z0, P0
                call()
                outs.append([r.copy() for r in res])
                per.append(_best_call(call, repeats))
            times.append(f"{fn.name()} {1e6 * float(np.median(per)):.1f} us")
        same = "" if ref is None else f"; outputs the same bit for bit as -O2: {_same(outs, ref)}"
        ref = ref or outs
        print(f"{label}: {', '.join(times)} per call (median over {len(sts)} states){same}")


def _same(a: list, b: list) -> bool:
    return all(all(np.array_equal(x, y) for x, y in zip(p, q)) for p, q in zip(a, b))


def time_noise(hist: dict) -> None:
    """CPU time of one noise re-estimate (the three channels of a horizon's readings)."""
    from soiltrack.identify.drivelog.noise import noise_model

    for name, arr in hist.items():
        t = _best_call(lambda: [noise_model(arr[:, j], None) for j in (1, 2, 3)], 5)
        print(f"noise re-estimate, {name} horizon ({arr.shape[0]} samples): {1e6 * t:.0f} us per call")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--repeats", type=int, default=15, help="timed batches of 100 calls per state (default 15)")
    a = p.parse_args()
    print("load:", open("/proc/loadavg").read().strip() if os.path.exists("/proc/loadavg") else "?")
    sts, hist = states()
    time_flags(sts, a.repeats)
    time_noise(hist)
    print("load:", open("/proc/loadavg").read().strip() if os.path.exists("/proc/loadavg") else "?")


if __name__ == "__main__":
    main()
