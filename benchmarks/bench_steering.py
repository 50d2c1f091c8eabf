"""Steering model: quadrature error, steady-turn time, soil from turns against straight driving.

Usage::

    python benchmarks/bench_steering.py [--seeds N] [--duration S] [--rate HZ] [--quick | --separation]

Parts (sizes printed with each result):

1. Quadrature: the steady turn (radius, both torques) at the default rule and the fit's rule
   against a 200 x 16 rule, heavy vehicle (tread 2.5 m, cg 1 m), three soils, inner sprocket
   3 rad/s and speed ratios 1.1, 1.5, 2.5.
2. Steady-turn evaluation time (cached rootfinder, warm process), median of 50 calls.
3. Identification: logs of ``--duration`` s at ``--rate`` Hz on ``--terrain`` (LETE sand), one with three turns
   (15 m left, 8 m right, 25 m left), one of the same duration with none; F_max and K from the
   turning samples, the straight samples of the turning log, and the straight log; their error,
   95 % interval width, coverage over ``--seeds`` seeds, the friction share's standard error
   (c-phi separation by the load transfer), and the fit time.
4. ``--separation``: c and phi from the turns' load transfer (cg 1.5 m, turns of 10-14 m at
   3.5 m/s), the friction share and its standard error per seed.
5. ``--plan`` (also in every run but ``--separation``): turning-plan solve times on LETE sand at
   2 m/s: ``turn_margin`` at 10 m (incl. the smallest radius by bisection), ``p_turn_feasible`` over
   ``--samples`` soils (15 % relative errors), and a 55 m route with a 15 m patch turning at 10 m
   (planned, then the turn solved), against the same route straight: the first plan of each (its
   solver built, a cold start; the turn's terms solved) and the re-plans (warm; the same turn on the
   same soil is not solved again). ``--route-only``: the routes only.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time

import numpy as np


def _quadrature(vehicle, soils) -> None:
    from soiltrack.soilmodel.steering import SteeringSettings, steady_turn

    print("1. quadrature error against a 200 x 16 Gauss-Legendre rule (per panel), max |rel| of R, T_l, T_r")
    for label, s in (("default 16 x 3", SteeringSettings()), ("fit 10 x 2", SteeringSettings(10, 2))):
        worst = 0.0
        for soil in soils:
            for ratio in (1.1, 1.5, 2.5):
                ref = steady_turn(3.0, 3.0 * ratio, soil, vehicle, settings=SteeringSettings(200, 16))
                st = steady_turn(3.0, 3.0 * ratio, soil, vehicle, settings=s)
                e = max(
                    abs(st.radius / ref.radius - 1),
                    abs(st.torque_left / ref.torque_left - 1),
                    abs(st.torque_right / ref.torque_right - 1),
                )
                worst = max(worst, e)
        print(f"   {label}: {worst:.2e} (3 soils x 3 ratios)")


def _timing(vehicle, soil) -> None:
    from soiltrack.soilmodel.steering import steady_turn

    steady_turn(3.0, 4.5, soil, vehicle)
    ts, cs = [], []
    for k in range(50):
        t, c = time.perf_counter(), time.process_time()
        steady_turn(3.0, 4.5 + 0.01 * k, soil, vehicle)
        ts.append(time.perf_counter() - t)
        cs.append(time.process_time() - c)
    print(
        f"2. steady turn: {1e3 * statistics.median(ts):.2f} ms wall, {1e3 * statistics.median(cs):.2f} ms CPU, "
        "median of 50 (default rule, started from the kinematic motion each time)"
    )


def _identification(vehicle, soil, seeds: int, duration: float, rate: float) -> None:
    from soiltrack.identify.turning import fit_turning
    from soiltrack.soilmodel.turning import simulate_turning_log

    Ft = vehicle.contact_area * soil.cohesion + vehicle.weight * np.tan(soil.friction_angle)
    Kt = soil.shear_modulus
    f = duration / 30.0
    turns = f"{4 * f:g}:{10 * f:g}:15,{13 * f:g}:{19 * f:g}:-8,{22 * f:g}:{27 * f:g}:25"
    print(
        f"3. identification, {duration:g} s at {rate:g} Hz, {seeds} seeds, turns {turns}; truth F_max "
        f"{Ft / 1e3:.1f} kN, K {Kt:g} m"
    )
    rows = {k: [] for k in ("turning samples", "straight samples", "straight log")}
    for seed in range(1, seeds + 1):
        log = simulate_turning_log(vehicle, soil, turns=turns, duration_s=duration, sample_rate_hz=rate, seed=seed)
        straight = simulate_turning_log(vehicle, soil, turns=(), duration_s=duration, sample_rate_hz=rate, seed=seed)
        for key, lg, motion in (
            ("turning samples", log, "turning"),
            ("straight samples", log, "straight"),
            ("straight log", straight, "straight"),
        ):
            t = time.perf_counter()
            fit = fit_turning(lg, vehicle, motion=motion)
            rows[key].append((fit, time.perf_counter() - t))
    for key, fits in rows.items():
        ok = [f for f, _ in fits if f.outcome == "usable"]
        tm = statistics.median(t for _, t in fits)
        if not ok:
            sl = [f.initial_slope_ci95 for f, _ in fits if f.initial_slope_ci95]
            slope = Ft * vehicle.track_length / (2 * Kt)
            cov = sum(lo <= slope <= hi for lo, hi in sl)
            print(
                f"   {key}: not usable in {len(fits)}/{len(fits)} (F_max, K not determined); initial slope "
                f"inside its 95 % interval {cov}/{len(sl)}; fit {tm:.1f} s median"
            )
            continue
        eF = [abs(f.max_thrust / Ft - 1) for f in ok]
        eK = [abs(f.shear_modulus / Kt - 1) for f in ok]
        wF = [(f.max_thrust_ci95[1] - f.max_thrust_ci95[0]) / Ft for f in ok]
        wK = [(f.shear_modulus_ci95[1] - f.shear_modulus_ci95[0]) / Kt for f in ok]
        cF = sum(f.max_thrust_ci95[0] <= Ft <= f.max_thrust_ci95[1] for f in ok)
        cK = sum(f.shear_modulus_ci95[0] <= Kt <= f.shear_modulus_ci95[1] for f in ok)
        kse = statistics.median(f.friction_share_se for f in ok)
        print(
            f"   {key}: usable {len(ok)}/{len(fits)}; |error| F_max {100 * statistics.median(eF):.2f} %, "
            f"K {100 * statistics.median(eK):.1f} % (median); 95 % width F_max {100 * statistics.median(wF):.1f} %, "
            f"K {100 * statistics.median(wK):.0f} % of the truth; inside F_max {cF}/{len(ok)}, K {cK}/{len(ok)}; "
            f"friction-share SE {kse:.2f}; fit {tm:.1f} s median"
        )


def _separation(soil, seeds: int, duration: float, rate: float) -> None:
    """c and phi from the load transfer: cg 1.5 m, turns of 10-14 m at 3.5 m/s."""
    from soiltrack.identify.turning import fit_turning
    from soiltrack.soilmodel import VEHICLES
    from soiltrack.soilmodel.turning import simulate_turning_log

    vehicle = dataclasses.replace(VEHICLES["heavy"], tread=2.5, cg_height=1.5)
    f = duration / 30.0
    turns = f"{4 * f:g}:{10 * f:g}:12,{13 * f:g}:{19 * f:g}:-10,{22 * f:g}:{27 * f:g}:14"
    W = vehicle.weight
    Ft = vehicle.contact_area * soil.cohesion + W * np.tan(soil.friction_angle)
    print(
        f"4. c-phi separation: cg 1.5 m, 3.5 m/s, turns {turns}, {duration:g} s at {rate:g} Hz; true friction "
        f"share {W * np.tan(soil.friction_angle) / Ft:.3f}, F_max {Ft / 1e3:.1f} kN, K {soil.shear_modulus:g} m"
    )
    for seed in range(1, seeds + 1):
        log = simulate_turning_log(
            vehicle, soil, turns=turns, duration_s=duration, sample_rate_hz=rate, seed=seed, cruise_m_s=3.5
        )
        fit = fit_turning(log, vehicle, motion="turning")
        phi = "-" if fit.friction_angle is None else f"{np.degrees(fit.friction_angle):.1f} deg"
        print(
            f"   seed {seed}: share {fit.friction_share:.3f} (SE {fit.friction_share_se:.3f}), separable "
            f"{fit.separable}, phi {phi}; F_max {fit.max_thrust / 1e3:.1f} kN {fit.max_thrust_ci95[0] / 1e3:.1f}-"
            f"{fit.max_thrust_ci95[1] / 1e3:.1f}, K {fit.shear_modulus:.4f} m {fit.shear_modulus_ci95[0]:.4f}-"
            f"{fit.shear_modulus_ci95[1]:.4f}"
        )


def _planning(vehicle, soil, samples: int, route_only: bool = False) -> None:
    def clock(f):
        t, c = time.perf_counter(), time.process_time()
        out = f()
        return out, time.perf_counter() - t, time.process_time() - c

    if not route_only:
        _margin_times(vehicle, soil, samples, clock)
    _route_times(vehicle, clock)


def _margin_times(vehicle, soil, samples: int, clock) -> None:
    from soiltrack.planning.turning import turn_margin, turn_probability
    from soiltrack.planning.uncertainty import SoilUncertainty
    from soiltrack.soilmodel import PRACTICAL_BOUNDS

    turn_margin(vehicle, soil, radius_m=10.0, speed_m_s=2.0)  # build the solvers once
    m, tw, tc = clock(lambda: turn_margin(vehicle, soil, radius_m=10.0, speed_m_s=2.0))
    print(
        f"5. turn_margin at 10 m, 2 m/s (with the smallest radius {m.min_turn_radius_m:.3g} m): "
        f"{tw:.3g} s wall, {tc:.3g} s CPU"
    )
    mean = soil.as_vector()
    unc = SoilUncertainty(
        "parameters", "full", ("cohesion", "friction_angle", "shear_modulus"), mean, np.diag((0.15 * mean) ** 2),
        vehicle.weight, PRACTICAL_BOUNDS, "bench: 15 % relative errors", vehicle.contact_area,
    )  # fmt: skip
    turn_probability(vehicle, unc, radius_m=10.0, speed_m_s=2.0, n_samples=samples)  # build the map once
    for R in (1.0, 1.1):
        r = R * m.min_turn_radius_m
        p, tw, tc = clock(lambda: turn_probability(vehicle, unc, radius_m=r, speed_m_s=2.0, n_samples=samples))
        print(
            f"   p_turn_feasible at {r:.3g} m = {p.p:.3g} +- {p.stderr:.2g} ({samples} soils): "
            f"{tw:.3g} s wall, {tc:.3g} s CPU"
        )


def _route_times(vehicle, clock) -> None:
    from soiltrack.planning import route_profile
    from soiltrack.planning.route import route_from_dict

    pats = [{"length_m": 20, "terrain": "lete_sand"}, {"length_m": 15, "terrain": "lete_sand", "radius_m": 10},
            {"length_m": 20, "terrain": "lete_sand"}]  # fmt: skip
    route = route_from_dict({"v0_m_s": 2.0, "v_end_m_s": 2.0, "patches": pats})
    straight = route_from_dict(
        {"v0_m_s": 2.0, "v_end_m_s": 2.0, "patches": [{k: v for k, v in q.items() if k != "radius_m"} for q in pats]}
    )
    for label, rt in (("straight", straight), ("with the turn", route)):
        runs = [clock(lambda: route_profile(rt, vehicle, max_speed=2.0)) for _ in range(3)]
        plan = runs[0][0]
        print(
            f"   route 55 m, {len(plan.series['time_s'])} mesh points, {label}, first plan (the solver built, "
            f"cold): success {plan.success}, {runs[0][1]:.3g} s wall, {runs[0][2]:.3g} s CPU; IPOPT "
            f"{plan.iterations} iterations, {plan.solve_time_s:.3g} s wall in the solver"
        )
        plan = runs[-1][0]
        tw, tc = statistics.median(x[1] for x in runs[1:]), statistics.median(x[2] for x in runs[1:])
        print(
            f"     re-planned (median of 2): {tw:.3g} s wall, {tc:.3g} s CPU; IPOPT {plan.iterations} iterations, "
            f"warm {plan.warm_start}"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3, help="seeds of the identification part (default 3)")
    ap.add_argument("--duration", type=float, default=30.0, help="log length, s (default 30)")
    ap.add_argument("--rate", type=float, default=25.0, help="sample rate, Hz (default 25)")
    ap.add_argument("--terrain", default="lete_sand", help="terrain of parts 3 and 4 (default lete_sand)")
    ap.add_argument("--quick", action="store_true", help="parts 1 and 2 only")
    ap.add_argument("--separation", action="store_true", help="part 4 only (c-phi separation, --seeds seeds)")
    ap.add_argument("--plan", action="store_true", help="part 5 only (turning-plan solve times)")
    ap.add_argument("--samples", type=int, default=800, help="soils of p_turn_feasible in part 5 (default 800)")
    ap.add_argument("--route-only", action="store_true", help="part 5's route plans only (straight and with the turn)")
    a = ap.parse_args()
    from soiltrack.soilmodel import TERRAINS, VEHICLES

    vehicle = dataclasses.replace(VEHICLES["heavy"], tread=2.5, cg_height=1.0)
    soils = [TERRAINS[k] for k in ("lete_sand", "clayey_soil", "dry_sand")]
    soil = TERRAINS[a.terrain]
    if a.separation:
        _separation(soil, a.seeds, a.duration, a.rate)
        return
    if a.plan or a.route_only:
        _planning(vehicle, TERRAINS["lete_sand"], a.samples, a.route_only)
        return
    _quadrature(vehicle, soils)
    _timing(vehicle, soils[0])
    _planning(vehicle, TERRAINS["lete_sand"], a.samples)
    if not a.quick:
        _identification(vehicle, soil, a.seeds, a.duration, a.rate)


if __name__ == "__main__":
    main()
