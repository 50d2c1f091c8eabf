"""On-line turning: the estimate from a two-track log with turns, with and without the steering model.

Log: heavy vehicle (tread 2.5 m, cg 1 m), LETE sand, 22 s at 25 Hz, turns ``4:10:15,13:19:-8``
(the log of tests/test_online_turning.py, seed 7). For each seed: F_max and K with their
standard errors and z against the truth, turning samples fitted / not fitted (by reason),
changes flagged, CPU of the replay, and the CPU of each turning block's fit.

    python benchmarks/bench_online_turning.py --seeds 7
    python benchmarks/bench_online_turning.py --seeds 1 2 3 4 5 6
"""

from __future__ import annotations

import argparse
import dataclasses
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[7], help="noise seeds of the simulated log")
    ap.add_argument("--without", action="store_true", help="also replay with the turns left out (no fit)")
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
    for seed in a.seeds:
        log = simulate_turning_log(heavy, soil, turns="4:10:15,13:19:-8", duration_s=22, sample_rate_hz=25, seed=seed)
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
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
