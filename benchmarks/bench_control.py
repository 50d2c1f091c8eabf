"""Closed-loop traction control: each controller beside its baselines on routes of true terrain, and its step time.

Routes (planned everywhere as LETE sand, but ``dig``; the true terrain differs, as identification must find):

- ``soft``: flat, a patch of snow (soft, K = 25 mm) in the middle;
- ``change``: flat, LETE sand -> dry sand -> clayey soil (changes of terrain);
- ``climb``: flat, then a climb on dry sand (heavy: 20 deg; light: snow at 25 deg), then flat;
- ``steep``: a climb the true soil cannot carry within the slip limit (heavy: snow at 27 deg, beyond
  F_max at any slip; light: snow at 32 deg, beyond the 0.3 slip limit);
- ``dig``: starting at 1 m/s, to accelerate to the target on a soft rise that digs in (snow with
  soilmodel's ``slip_sinkage`` effect, :data:`DIG`: more slip loses net pull, so a high fixed slip
  ceiling digs in) and then a loose climb that needs a high slip (heavy: 40 m of dry sand at 24 deg,
  about 10 % slip; light: 15 m of snow at 20 deg, about 10 %), so that neither
  fixed ceiling (7 %, 20 %) gets through. Planned with the true soils, the slip sinkage unknown to the plan
  (``mu_s`` = 0): what the on-line estimate must find is that more slip digs in;
- ``mix`` and ``climbs``: the acceptance scenarios (changes of terrain mid-route, hard climbs), planned as LETE
  sand. Heavy ``mix``: LETE sand, snow, dry sand at 8 deg, clayey soil, LETE sand; heavy ``climbs``: dry sand at
  22 and 24 deg and LETE sand at 26 deg between flats. Light ``mix``: LETE sand, a user soil the library does not
  know (:data:`USER_SOILS` "wet loam": c 2 kPa, phi 22 deg, K 18 mm) flat and at 15 deg, snow, LETE sand; light
  ``climbs``: wet loam at 22 deg and snow at 24 deg between flats.

For each route, vehicle and controller (``slip``, ``mpc``), the baselines of the same run (``pi``,
``fixed_slip_7``, ``fixed_slip_20``, ``nominal_soil``, ``true_soil``) and the metrics of
:mod:`soiltrack.planning.control.loop`; per-step time (median, p99) of the controller with the
on-line estimator inside, of the controller alone (the estimator's update taken out), of the estimator's update
alone, and of the MPC's solve (with its IPOPT fall-backs and shifted-plan answers). ``--plant independent``
runs the independent numpy plant of tests/control_plant.py instead of the library's.

    python benchmarks/bench_control.py                       # light, climb, slip (about 30 s)
    python benchmarks/bench_control.py --split-time 1000     # the slip step: estimator vs own (replayed) time
    python benchmarks/bench_control.py --solve-time heavy/soft,light/climb,light/dig   # MPC solve: QRQP vs qpOASES
    python benchmarks/bench_control.py --vehicles heavy,light --routes soft,change,climb,steep \\
        --controllers slip,mpc --plant independent          # the full table (tens of minutes)
"""

from __future__ import annotations

import argparse
import os
import sys
import time

ROUTES = ("soft", "change", "climb", "steep", "dig", "mix", "climbs")
#: True soils of the routes that are not library terrains (``TERRAINS``): ``{name: (c kPa, phi deg, K m)}``.
USER_SOILS = {"wet_loam": (2.0, 22.0, 0.018)}
#: The ``dig`` route's slip-sinkage patch: (grade deg, mu_s) per vehicle (the net pull F(i) - N mu_s i peaks
#: 7 % (heavy) / 6 % (light) of F_max above the resistance at 5.7 % / 10 % slip, below it at 20 %).
DIG = {"heavy": (10.0, 1.0), "light": (6.0, 2.0)}


def routes(vehicle: str) -> dict:
    """``{name: (route dict, true terrain names, true slip-sinkage mu_s per patch)}`` for a vehicle."""
    v = 3.0 if vehicle == "heavy" else 1.5
    climb, climb_soil = (20, "dry_sand") if vehicle == "heavy" else (25, "snow")
    steep = 27 if vehicle == "heavy" else 32

    def R(patches, v0=0.3, planned=None):
        return {
            "v0_m_s": v0,
            "v_end_m_s": v,
            "max_slip": 0.3,
            "patches": [
                dict(length_m=L, terrain=planned[k] if planned else "lete_sand", grade_deg=g)
                for k, (L, g) in enumerate(patches)
            ],
        }

    dig_grade, dig_mu = DIG[vehicle]
    dig_climb, dig_soil = (24, "dry_sand") if vehicle == "heavy" else (20, "snow")
    dig_true = ["snow", "lete_sand", dig_soil, "lete_sand"]
    return {
        "soft": (R([(15, 0), (15, 0), (15, 0)]), ["lete_sand", "snow", "lete_sand"], [0.0] * 3),
        "change": (R([(15, 0), (15, 0), (15, 0)]), ["lete_sand", "dry_sand", "clayey_soil"], [0.0] * 3),
        "climb": (R([(15, 0), (25, climb), (10, 0)]), ["lete_sand", climb_soil, "lete_sand"], [0.0] * 3),
        "steep": (R([(12, 0), (20, steep)]), ["lete_sand", "snow"], [0.0] * 2),
        "dig": (
            R(
                [(15, dig_grade), (8, 0), (40 if vehicle == "heavy" else 15, dig_climb), (8, 0)],
                v0=1.0,
                planned=dig_true,
            ),
            dig_true,
            [dig_mu, 0.0, 0.0, 0.0],
        ),
        **_acceptance_routes(vehicle, R),
    }


def _acceptance_routes(vehicle: str, R) -> dict:
    """The ``mix`` and ``climbs`` routes (module docstring) of a vehicle, built with ``routes``' route maker."""
    if vehicle == "heavy":
        mix = ([(15, 0), (15, 0), (15, 8), (15, 0), (15, 0)], ["lete_sand", "snow", "dry_sand", "clayey_soil"])
        climbs = ([(10, 0), (15, 22), (10, 0), (15, 24), (10, 0), (10, 26)], ["lete_sand", "dry_sand"] * 2)
        mix[1].append("lete_sand")
        climbs[1].extend(["lete_sand", "lete_sand"])
    else:
        mix = ([(10, 0), (10, 0), (10, 15), (10, 0), (10, 0)], ["lete_sand", "wet_loam", "wet_loam", "snow"])
        climbs = ([(10, 0), (15, 22), (10, 0), (15, 24), (10, 0)], ["lete_sand", "wet_loam", "lete_sand", "snow"])
        mix[1].append("lete_sand")
        climbs[1].append("lete_sand")
    return {k: (R(p), t, [0.0] * len(p)) for k, (p, t) in (("mix", mix), ("climbs", climbs))}


def _true_soil(name: str):
    """A library terrain, or one of :data:`USER_SOILS`."""
    from soiltrack.soilmodel import TERRAINS, Soil

    if name in USER_SOILS:
        c, phi, K = USER_SOILS[name]
        return Soil.from_kpa_deg(c, phi, K, name=name.replace("_", " ") + " (user soil)")
    return TERRAINS[name]


def _row(name, r):
    m = r.metrics

    def f(x, d=3):
        return "-" if x is None else f"{x:.{d}g}"

    own = r.own_step_time_median_s, r.own_step_time_p99_s
    est = (
        f"{r.estimator_time_median_s * 1e6:.0f}/{r.estimator_time_p99_s * 1e6:.0f}"
        if r.estimator_time_median_s is not None
        else "-"
    )
    solve = (
        f"{r.solve_time_median_s * 1e3:.1f}/{r.solve_time_p99_s * 1e3:.1f} "
        f"(CPU {r.solve_cpu_median_s * 1e3:.1f}/{r.solve_cpu_p99_s * 1e3:.1f}; "
        f"{r.mpc_solves} solves, {r.mpc_fallbacks} IPOPT, {r.mpc_failures} failed: slip rule)"
        if r.solve_time_median_s
        else "-"
    )
    return (
        f"| {name} | {'yes' if r.arrived else 'no'} | {f(m['time_s'])} | {f(m['energy_J'])} | "
        f"{f(m['tracking_rmse_m_s'])} | {f(m['peak_slip'])} | {f(m['time_above_slip_limit_s'])} | "
        f"{m['stuck_events']} | {f(m['adapt_time_s'])} | {r.step_time_median_s * 1e6:.0f}/{r.step_time_p99_s * 1e6:.0f}"
        f" | {r.step_cpu_median_s * 1e6:.0f}/{r.step_cpu_p99_s * 1e6:.0f}"
        f" | {own[0] * 1e6:.0f}/{own[1] * 1e6:.0f} | {est} | {solve} |"
    )


def split_time(n: int, replays: int = 5) -> None:
    """The slip controller's step split into the estimator's update and its own part (library plant,
    light vehicle, ``climb``, ``n`` steps after 300 of warm-up; median and p99).

    First with the on-line estimator (its estimates recorded): the step in CPU (``process_time``) and wall
    clock, the estimator's update (wall clock) and ``step - update``. Then ``replays`` times with an
    estimator that answers the recorded estimates (the same inputs: the torques are checked to be the same),
    so the step is the controller's own: CPU median of each replay, and the median of the per-step minimum
    wall time over the replays (a loaded machine's waits filtered out)."""
    import numpy as np

    from soiltrack.identify.online import OnlineEstimator, OnlineSettings
    from soiltrack.planning import route_from_dict
    from soiltrack.planning.control import PlantSettings, TerrainPatch, TrackPlant, make_controller
    from soiltrack.soilmodel import VEHICLES

    V = VEHICLES["light"]
    spec, true, _ = routes("light")["climb"]
    route = route_from_dict(spec)
    recorded: list[list] = []

    class Recording:
        def __init__(self, vehicle, grade_rad):
            self.inner = OnlineEstimator(vehicle, OnlineSettings(grade_rad=grade_rad))
            recorded.append([])

        def update(self, *args):
            e = self.inner.update(*args)
            recorded[-1].append(e)
            return e

    class Replay:
        made = 0

        def __init__(self, vehicle, grade_rad):
            self.answers, self.k = iter(recorded[Replay.made]), 0
            Replay.made += 1

        def update(self, *args):
            return next(self.answers)

    def run(factory):
        ctl = make_controller("slip", V, route=route, estimator_factory=factory)
        ps = PlantSettings(v0=route.v0_m_s, sigma_vehicle_speed=0.005, sigma_sprocket_speed=0.02)
        pats = [TerrainPatch(p.length_m, _true_soil(t), p.grade_deg) for p, t in zip(route.patches, true)]
        pl = TrackPlant(V, pats, ps)
        meas, torques = pl.step(0.0), []
        for _ in range(300 + n):
            torques.append(ctl.command(meas))
            meas = pl.step(torques[-1])
        return ctl, torques

    def q(x):
        return f"median {np.median(x) * 1e6:.1f} us, p99 {np.percentile(x, 99) * 1e6:.1f} us"

    ctl, torques = run(Recording)
    st, sc = np.array(ctl.step_times_s[300:]), np.array(ctl.step_cpu_s[300:])
    ut = np.array(ctl.belief.update_times_s[300:])
    print(f"step with the estimator, CPU: {q(sc)}; wall: {q(st)}")
    print(f"estimator update (wall): {q(ut)}")
    print(f"own (step - estimator, wall): {q(st - ut)}")
    fastest = None
    for k in range(replays):
        Replay.made = 0
        ctl, again = run(Replay)
        if again != torques:
            raise RuntimeError("the replay gave other torques: the controller's inputs differ")
        w = np.array(ctl.step_times_s[300:])
        fastest = w if fastest is None else np.minimum(fastest, w)
        print(f"own (replayed estimates) {k + 1}: CPU {q(np.array(ctl.step_cpu_s[300:]))}")
    print(f"own, per-step minimum wall over {replays} replays: {q(fastest)}")


def solve_time(specs: str) -> None:
    """The MPC's step and solve, last round's SQP (exact Hessian, QRQP) beside this one's (convexified, qpOASES),
    in the same process: library plant, on-line estimate, each ``vehicle/route`` of ``specs`` (median, p99, max;
    CPU by ``process_time``, wall by ``perf_counter``; IPOPT fall-backs and failed solves)."""
    import numpy as np

    from soiltrack.planning import route_from_dict
    from soiltrack.planning.control import PlantSettings, TerrainPatch, TrackPlant, make_controller
    from soiltrack.soilmodel import VEHICLES

    print(
        "| run | QP | solves | IPOPT | failed | solve CPU ms med/p99/max | solve wall ms med/p99 | step CPU ms med/p99 "
        "| step wall ms med/p99 | time_s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for item in specs.split(","):
        vname, rname = item.split("/")
        V = VEHICLES[vname]
        spec, true, mus = routes(vname)[rname]
        route = route_from_dict(spec)
        for qp in ("qrqp", "qpoases"):
            ctl = make_controller("mpc", V, route=route, mpc_qp=qp)
            ps = PlantSettings(
                v0=route.v0_m_s,
                sigma_vehicle_speed=0.005,
                sigma_sprocket_speed=0.02,
                sigma_torque=0.005 * V.max_sprocket_torque,
            )
            pats = [
                TerrainPatch(p.length_m, _true_soil(t), p.grade_deg, m) for p, t, m in zip(route.patches, true, mus)
            ]
            pl = TrackPlant(V, pats, ps)
            meas = pl.step(0.0)
            while pl.truth["distance_m"] < route.length_m and pl.truth["time_s"] < 120:
                meas = pl.step(ctl.command(meas))
            P = ctl.problem
            sc, sw = np.array(ctl.solve_cpu_s) * 1e3, np.array(ctl.solve_times_s) * 1e3
            tc, tw = np.array(ctl.step_cpu_s) * 1e3, np.array(ctl.step_times_s) * 1e3

            def q(x):
                return f"{np.median(x):.2f}/{np.percentile(x, 99):.2f}"

            print(
                f"| {item} | {qp} | {len(sc)} | {P.fallbacks} | {P.failures} | {q(sc)}/{sc.max():.1f} | {q(sw)} | "
                f"{q(tc)} | {q(tw)} | {pl.truth['time_s']:.2f} |"
            )
            sys.stdout.flush()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__
    )
    p.add_argument("--vehicles", default="light", help="comma-separated: heavy, light (default light)")
    p.add_argument("--routes", default="climb", help=f"comma-separated of {', '.join(ROUTES)} (default climb)")
    p.add_argument("--controllers", default="slip", help="comma-separated: slip, mpc, pi (default slip)")
    p.add_argument("--plant", default="library", choices=("library", "independent"))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-probe", action="store_true", help="controllers without the traction probe (probe=False)")
    p.add_argument(
        "--mpc-disturbance", type=float, default=0.0, metavar="S", help="MPC's mpc_disturbance_s (default 0: off)"
    )
    p.add_argument(
        "--mpc-qp", default="qpoases", choices=("qpoases", "qrqp"), help="MPC's SQP setup (mpc_qp; default qpoases)"
    )
    p.add_argument("--split-time", type=int, metavar="N", help="only time the slip controller's step split (N steps)")
    p.add_argument(
        "--solve-time",
        metavar="V/R,...",
        help="only the MPC solve time, QRQP (exact Hessian) beside qpOASES (convexified): heavy/soft,light/climb",
    )
    a = p.parse_args(argv)
    if a.solve_time:
        solve_time(a.solve_time)
        return 0
    if a.split_time:
        split_time(a.split_time)
        return 0

    from soiltrack.planning import route_from_dict
    from soiltrack.planning.control import PlantSettings, drive
    from soiltrack.soilmodel import VEHICLES

    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))
    print(
        "| controller | arrived | time_s | energy_J | rmse_m_s | peak_slip | above_limit_s | stuck | adapt_s "
        "| step us med/p99 | step CPU us med/p99 | own us med/p99 | estimator us med/p99 | solve ms med/p99 |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for vname in a.vehicles.split(","):
        V = VEHICLES[vname]
        for rname in a.routes.split(","):
            spec, true, mus = routes(vname)[rname]
            route = route_from_dict(spec)
            soils = [_true_soil(k) for k in true]
            noise = dict(
                sigma_vehicle_speed=0.005, sigma_sprocket_speed=0.02, sigma_torque=0.005 * V.max_sprocket_torque
            )
            v0 = route.v0_m_s
            ps = PlantSettings(v0=v0, seed=a.seed, **noise)
            factory = None
            if a.plant == "independent":
                from control_plant import from_vehicle, with_truth

                def factory(patches, V=V, v0=v0):
                    pat = [
                        (
                            q.length_m,
                            q.soil.cohesion,
                            q.soil.friction_angle,
                            q.soil.shear_modulus,
                            q.grade_deg,
                            q.slip_sinkage,
                        )
                        for q in patches
                    ]
                    return with_truth(from_vehicle(V, pat, v0=v0, sigma_v=0.005, sigma_w=0.02, seed=a.seed))

            for kind in a.controllers.split(","):
                t0 = time.perf_counter()
                extra: dict = {"probe": False} if a.no_probe else {}
                if a.mpc_disturbance:
                    extra["mpc_disturbance_s"] = a.mpc_disturbance
                if a.mpc_qp != "qpoases":
                    extra["mpc_qp"] = a.mpc_qp
                res = drive(
                    kind, V, route, soils, true_slip_sinkage=mus, plant_settings=ps, plant_factory=factory, **extra
                )
                print(f"| **{vname} / {rname} / {kind}** ({time.perf_counter() - t0:.0f} s wall) |||||||||||||")
                print(_row(kind, res.run))
                for name, r in res.baselines.items():
                    print(_row(name, r))
                sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
