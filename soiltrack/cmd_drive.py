"""``soiltrack drive``: a closed-loop controller over a route of true terrain, beside its baselines."""

from __future__ import annotations

import argparse
import json
import math

from .cliutil import EXIT_OK, EXIT_SOLVER, floats_arg, output_path, vehicle_arg
from .soilmodel import DataError

_DESCRIPTION = """\
A closed-loop simulation: the controller (--controller mpc|slip|pi) drives the library's
straight-line dynamics (Eqs. 1, 4 with the thrust balance; implicit steps) over the route's
patches of TRUE terrain, with sensor noise, and the baselines run the same route: pi (no soil
knowledge), fixed slip ceilings of 7 % and 20 %, the same controller on the planned (nominal)
soil without the estimator, and the same controller given the true soil.
ROUTE.json: as for `soiltrack route` ({"v0_m_s", "v_end_m_s", "max_slip", "patches": [{"length_m",
"terrain" | "soil", "grade_deg"}]}); each patch may add "true_terrain": NAME or "true_soil":
{"cohesion_kpa", "friction_angle_deg", "shear_modulus_m"} (what the vehicle really drives on;
default the planned soil), and "true_slip_sinkage": MU_S (soilmodel's slip_sinkage effect, extra
resistance N mu_s |slip|, 0 to 2; default 0). The target speed is the larger of v0_m_s and v_end_m_s (or --speed).

Exit status: 0 the controller reached the end with no stuck event, 1 it did not (the reason in
the report and the JSON), 2 bad input."""

_MAX_POINTS = 2000


def read_drive_route(path: str):
    """ROUTE.json with ``true_terrain``/``true_soil`` (and ``true_slip_sinkage``, mu_s) per patch -> (Route, true
    soils, true slip-sinkage coefficients); DataError naming the field."""
    from .planning import route_from_dict
    from .soilmodel.jsonread import load_json_file

    obj = load_json_file(path, "route file")
    if not isinstance(obj, dict) or not isinstance(obj.get("patches"), list):
        return route_from_dict(obj, source=path), None, None  # its own error
    planned = dict(obj, patches=[])
    truths: list[dict | None] = []
    sinkage: list[float] = []
    for k, p in enumerate(obj["patches"]):
        if not isinstance(p, dict):
            planned["patches"].append(p)
            truths.append(None)
            sinkage.append(0.0)
            continue
        true = {key: p[key] for key in ("true_terrain", "true_soil") if key in p}
        if len(true) == 2:
            raise DataError(
                f"patches[{k}]: give 'true_terrain' or 'true_soil', not both", file=path, column=f"patches[{k}]"
            )
        mu = p.get("true_slip_sinkage", 0.0)
        if isinstance(mu, bool) or not isinstance(mu, (int, float)) or not 0 <= mu <= 2:
            raise DataError(
                f"patches[{k}].true_slip_sinkage must be a number in [0, 2] (mu_s), got {mu!r}",
                file=path,
                column=f"patches[{k}].true_slip_sinkage",
            )
        sinkage.append(float(mu))
        drop = ("true_terrain", "true_soil", "true_slip_sinkage")
        planned["patches"].append({key: v for key, v in p.items() if key not in drop})
        truths.append(true or None)
    route = route_from_dict(planned, source=path)
    soils = []
    for k, (t, patch) in enumerate(zip(truths, route.patches)):
        if t is None:
            soils.append(patch.terrain)
            continue
        key = next(iter(t))
        one = {"patches": [{"length_m": 1.0, ("terrain" if key == "true_terrain" else "soil"): t[key]}]}
        try:
            soils.append(route_from_dict(one, source=path).patches[0].terrain)
        except DataError as e:
            msg = e.reason.replace("patches[0].terrain", f"patches[{k}].{key}").replace(
                "patches[0].soil", f"patches[{k}].{key}"
            )
            raise DataError(msg, file=path, column=f"patches[{k}].{key}") from None
    return route, soils, sinkage


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, int):
        return str(v)
    return f"{v:.4g}"


def _table(res) -> str:
    rows = [(res.controller, res.run)] + list(res.baselines.items())
    from .planning.control.loop import METRIC_KEYS

    head = ["controller", "arrived"] + list(METRIC_KEYS)
    lines = [head] + [[n, "yes" if r.arrived else "no"] + [_fmt(r.metrics[k]) for k in METRIC_KEYS] for n, r in rows]
    widths = [max(len(str(x[j])) for x in lines) for j in range(len(head))]
    return "\n".join("  ".join(str(x[j]).rjust(widths[j]) for j in range(len(head))) for x in lines)


def _reason(run) -> str | None:
    if run.arrived and run.metrics["stuck_events"] == 0:
        return None
    stops = [e for e in run.events if e["kind"] == "stop"]
    if stops:
        return stops[-1]["reason"]
    if run.metrics["stuck_events"]:
        return f"{run.metrics['stuck_events']} stuck event(s): speed near zero at a slip above 0.5 for over 1 s"
    return f"did not reach the end in {run.series['time_s'][-1]:.4g} s (reached {run.series['distance_m'][-1]:.4g} m)"


def _series(run) -> dict:
    n = len(run.series["time_s"])
    step = max(1, math.ceil(n / _MAX_POINTS))
    idx = list(range(0, n, step))
    if idx[-1] != n - 1:
        idx.append(n - 1)
    return {k: [v[i] for i in idx] for k, v in run.series.items()}


def _json(res, reason) -> dict:
    def timing(r):
        return {
            "step_time_median_s": r.step_time_median_s,
            "step_time_p99_s": r.step_time_p99_s,
            "own_step_time_median_s": r.own_step_time_median_s,
            "own_step_time_p99_s": r.own_step_time_p99_s,
            "estimator_time_median_s": r.estimator_time_median_s,
            "solve_time_median_s": r.solve_time_median_s,
            "solve_time_p99_s": r.solve_time_p99_s,
        }

    base = {k: dict(r.metrics) for k, r in res.baselines.items()}
    best = res.fixed_slip_best
    base["fixed_slip"] = dict(res.baselines[best].metrics, slip_ceiling=float(best.rsplit("_", 1)[1]) / 100)
    return {
        "controller": res.controller,
        "arrived": res.run.arrived,
        "reason": reason,
        "metrics": res.run.metrics,
        "baselines": base,
        "events": res.run.events,
        "timing": timing(res.run),
        "notes": list(res.notes),
        "series": _series(res.run),
    }


def _cmd_drive(a: argparse.Namespace) -> int:
    from .planning.control import CONTROLLERS, PlantSettings, drive

    if a.controller not in ("mpc", "slip", "pi"):
        raise DataError(
            f"argument --controller: unknown controller {a.controller!r}; expected mpc, slip or pi "
            f"(the library also has {[c for c in CONTROLLERS if c not in ('mpc', 'slip', 'pi')]})"
        )
    if a.plot:
        output_path(a.plot, "--plot", figure=True)
    vehicle = vehicle_arg(a.vehicle)
    route, soils, sinkage = read_drive_route(a.route)
    speed = None if a.speed is None else floats_arg(a.speed, "--speed")[0]
    if speed is not None and not speed > 0:
        raise DataError(f"argument --speed must be > 0 m/s, got {speed:g}")
    if max(route.v0_m_s, route.v_end_m_s) <= 0 and speed is None:
        raise DataError(
            "v0_m_s and v_end_m_s are both 0: no speed to track (give --speed)", file=a.route, column="v_end_m_s"
        )
    dt = floats_arg(a.dt, "--dt")[0]
    if not 1e-3 <= dt <= 0.2:
        raise DataError(f"argument --dt must lie in [0.001, 0.2] s, got {dt:g}")
    noise = 0.0 if a.no_noise else 1.0
    Mmax = vehicle.max_sprocket_torque or vehicle.weight * vehicle.sprocket_radius
    ps = PlantSettings(
        dt=dt,
        v0=route.v0_m_s,
        seed=a.seed,
        sigma_vehicle_speed=0.005 * noise,
        sigma_sprocket_speed=0.02 * noise,
        sigma_torque=0.005 * Mmax * noise,
        sigma_accel=0.02 * noise,
        delay_steps=int(a.delay_steps),
    )
    res = drive(
        a.controller, vehicle, route, soils, true_slip_sinkage=sinkage, plant_settings=ps, target_speed_m_s=speed
    )
    reason = _reason(res.run)
    if a.json:
        print(json.dumps(_json(res, reason), indent=None, allow_nan=False, default=float))
    else:
        print(_table(res))
        for e in res.run.events:
            print(f"  event at {e['time_s']:.4g} s, {e['distance_m']:.4g} m: {e['kind']}: {e['reason']}")
        print(
            f"  step time of {res.controller}: median {res.run.step_time_median_s * 1e6:.0f} us, p99 "
            f"{res.run.step_time_p99_s * 1e6:.0f} us (estimator included)"
        )
        for n in res.notes:
            print(f"  note: {n}")
        if reason:
            print(f"{res.controller} did not get through: {reason}")
    if a.plot:
        from .plot_drive import plot_drive

        plot_drive(res, route, a.plot)
    return EXIT_OK if reason is None else EXIT_SOLVER


def add_parser(sub) -> None:
    """Register the ``drive`` subcommand on an argparse subparsers object."""
    p = sub.add_parser(
        "drive",
        help="closed-loop controller over a route of true terrain, beside its baselines (exit 1: not through)",
        description=_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example:\n  soiltrack drive ROUTE.json --vehicle light --controller slip --plot drive.png",
    )
    p.add_argument("route", help="ROUTE.json (patches may carry true_terrain or true_soil)")
    p.add_argument("--vehicle", required=True, help="vehicle JSON file or preset name (heavy, light)")
    p.add_argument("--controller", required=True, metavar="mpc|slip|pi", help="the controller to run")
    p.add_argument("--speed", metavar="M_S", help="target speed, m/s (default: the larger of v0_m_s and v_end_m_s)")
    p.add_argument("--dt", default="0.02", metavar="S", help="control period, s (default 0.02)")
    p.add_argument("--delay-steps", type=int, default=0, metavar="N", help="measurement delay, control periods")
    p.add_argument("--seed", type=int, default=0, help="seed of the sensor noise (default 0)")
    p.add_argument("--no-noise", action="store_true", help="noise-free sensors (default: realistic noise)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.add_argument("--plot", metavar="PNG", help="save speed, slip, torque, estimate vs true soil, patches")
    p.set_defaults(func=_cmd_drive)
