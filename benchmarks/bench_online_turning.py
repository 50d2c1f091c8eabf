"""On-line turning: the estimate from a two-track log with turns, with and without the steering model.

Log: heavy vehicle (tread 2.5 m, cg 1 m), LETE sand, 22 s at 25 Hz, turns ``4:10:15,13:19:-8``
(the log of tests/test_online_turning.py, seed 7). For each seed: F_max and K with their
standard errors and z against the truth, turning samples fitted / not fitted (by reason),
changes flagged, CPU of the replay, and the CPU of each turning block's fit.

    python benchmarks/bench_online_turning.py --seeds 7
    python benchmarks/bench_online_turning.py --seeds 1 2 3 4 5 6
    python benchmarks/bench_online_turning.py --independent --seeds 1 2 3 4 --without

``--independent``: the logs of benchmarks/turning_independent.py instead (45 s at 25 Hz, four
turns of 8-25 m, straight hard pulls, the shear accumulated from entry; its vehicle), and the
batch ``fit_turning`` of each log's turning samples beside the on-line end state.
"""

from __future__ import annotations

import argparse
import dataclasses
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[7], help="noise seeds of the simulated log")
    ap.add_argument("--without", action="store_true", help="also replay with the turns left out (no fit)")
    ap.add_argument("--independent", action="store_true", help="logs of benchmarks/turning_independent.py")
    ap.add_argument("--blocks", action="store_true", help="print each turning block: time, status, F_max, K")
    a = ap.parse_args(argv)

    from soiltrack.identify.online import OnlineEstimator
    from soiltrack.identify.online import turning as tm
    from soiltrack.soilmodel import TERRAINS, VEHICLES
    from soiltrack.soilmodel.traction import max_thrust
    from soiltrack.soilmodel.turning import simulate_turning_log

    heavy = dataclasses.replace(VEHICLES["heavy"], tread=2.5, cg_height=1.0)
    soil = TERRAINS["lete_sand"]
    F, K = max_thrust(soil, heavy), soil.shear_modulus
    print(f"truth: F_max {F / 1e3:.1f} kN, K {K:.4f} m")
    block_cpu: list[float] = []
    end = tm.TurningUpdate.end

    def timed(self, *args):
        t0 = time.process_time()
        out = end(self, *args)
        if out is not None:
            block_cpu.append(time.process_time() - t0)
        return out

    tm.TurningUpdate.end = timed  # type: ignore[method-assign]
    logs = _independent_logs(a.seeds) if a.independent else {}
    if a.independent:
        heavy = next(iter(logs.values()))[1]
        F, K = next(iter(logs.values()))[2]
        print(f"independent logs: truth F_max {F / 1e3:.1f} kN, K {K:.4f} m")
    for seed in a.seeds:
        if a.independent:
            from soiltrack.identify.turning import fit_turning

            log = logs[seed][0]
            bf = fit_turning(log, heavy, motion="turning")
            print(f"seed {seed}, batch fit of the turning samples: {bf.outcome}, F_max {bf.max_thrust}, "
                  f"K {bf.shear_modulus} (SE {bf.se.get('shear_modulus_m')})")  # fmt: skip
        else:
            log = simulate_turning_log(
                heavy, soil, turns="4:10:15,13:19:-8", duration_s=22, sample_rate_hz=25, seed=seed
            )
        for label, ts in (("turns fitted", None), ("turns left out", tm.TurningSettings(min_block_s=1e9)))[
            : 2 if a.without else 1
        ]:
            block_cpu.clear()
            est = OnlineEstimator(heavy, turning=ts)
            t0 = time.process_time()
            for k in range(log.n_samples):
                e = est.update_tracks(
                    log.time[k], log.torque_left[k], log.torque_right[k], log.speed_left[k], log.speed_right[k],
                    log.vehicle_speed[k], yaw_rate=log.yaw_rate[k],
                )  # fmt: skip
            cpu = time.process_time() - t0

            def z(x, se, truth):
                return "not identified" if se is None else f"{x:.4g} +- {se:.2g} (z {(x - truth) / se:+.2f})"

            print(
                f"seed {seed}, {label}: F_max {z(e.max_thrust_N, e.max_thrust_stderr_N, F)}, "
                f"K {z(e.shear_modulus_m, e.shear_modulus_stderr_m, K)}; turning fitted {e.samples_turning}, "
                f"not fitted {est.turning.not_fitted}; changes {len(est.changes)}; CPU {cpu:.2f} s; "
                f"block CPU {[round(c, 3) for c in block_cpu]} s"
            )
            if a.blocks:
                for b in est.turning.blocks:
                    x = "" if b.x is None else f" F_max {b.x[0] / 1e3:.1f} kN, K {1e3 * b.x[1]:.2f} mm"
                    print(f"   block at {b.time_s:6.2f} s, {b.samples} samples, {b.status}{x}")
    return 0


def _independent_logs(seeds) -> dict:
    """``{seed: (TwoTrackLog, Vehicle, (F_max, K))}`` from benchmarks/turning_independent.py."""
    import os
    import sys
    import tempfile

    from soiltrack.soilmodel import Vehicle
    from soiltrack.soilmodel.turning import two_track_log_from_columns

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import turning_independent as ti

    veh = ti.Vehicle()
    path = os.path.join(tempfile.mkdtemp(prefix="online_turn_"), "vehicle.json")
    ti.write_vehicle(veh, path)
    vehicle = Vehicle.from_json(path)
    soil = ti.SOILS["lete_sand"]
    out = {}
    for seed, lg in zip(seeds, ti.simulate(list(seeds), 45.0, soil, veh, grid=ti.Grid(40, 3, 0.01))):
        cols = {c: lg[c] for c in ti.COLUMNS}
        out[seed] = (two_track_log_from_columns(cols, source=f"independent seed {seed}"), vehicle,
                     (soil.max_thrust(veh), soil.K))  # fmt: skip
    return out


if __name__ == "__main__":
    raise SystemExit(main())
