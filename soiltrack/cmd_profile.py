"""``soiltrack profile``: a feasible speed/slip/torque profile on one terrain, by optimal control."""

from __future__ import annotations

import argparse
import json

from .argcheck import check_distance
from .cliutil import EXIT_OK, EXIT_SOLVER, floats_arg, output_path, vehicle_arg
from .cmd_margin import add_terrain_arguments, terrain_args
from .soilmodel import DataError


_DESCRIPTION = """\
A feasible speed/slip/torque profile from --v0 to --v1 on one terrain, by optimal control
(direct collocation, Radau IIA, IPOPT): the sprocket torque is held over each interval; the
slip, torque, power (and optional torque-rate and speed) limits hold at every mesh and
collocation point. The plan starts from a consistent state: the vehicle cruising at v0 with the
steady slip that carries its resistance (or --initial-slip; at rest when v0 = 0).

The report gives the peak speed, the limits that shape the plan (in how many intervals), and
any standstill (time windows below 0.01 m/s). Exit status: 0 feasible, 1 infeasible or solver
failed (the reason names the limit and the patch), 2 bad input."""


def add_objective_argument(p: argparse.ArgumentParser) -> None:
    """The ``--objective`` option of ``profile``."""
    p.add_argument(
        "--objective",
        choices=("time", "energy"),
        default="time",
        help="time: reach v1 at the distance as fast as the limits allow; energy: the least positive "
        "sprocket work (braking not recovered) - with --duration the distance is free and the plan "
        "may stand still (reported) (default: time)",
    )


def add_start_arguments(p: argparse.ArgumentParser) -> None:
    """The speed-limit and initial-slip options shared by ``profile`` and ``route``."""
    p.add_argument(
        "--max-speed",
        metavar="V",
        help="speed limit, m/s, at every mesh and collocation point "
        "(default none; the peak speed is reported either way)",
    )
    p.add_argument(
        "--initial-slip",
        metavar="S",
        help="slip when the plan starts, in (-1, 1) (default: the steady slip carrying the resistance at v0)",
    )


def _num(text: str | None, name: str):
    return None if text is None else floats_arg(text, name)[0]


def int_option(text: str | None, name: str, default: int) -> int:
    """An integer option (``default`` when not given; DataError naming ``name`` otherwise)."""
    if text is None:
        return default
    try:
        return int(text)
    except ValueError:
        raise DataError(f"argument {name} expects an integer, got {text!r}") from None


def print_result(res, a: argparse.Namespace, route: bool) -> int:
    """Print the JSON or the report, save the plot; exit 0 when feasible, 1 otherwise."""
    print(json.dumps(res.to_dict(route=route), indent=2, allow_nan=False) if a.json else res.report())
    if a.plot and res.success:
        from .planning.plots import plot_profile

        plot_profile(res, a.plot)
    return EXIT_OK if res.success else EXIT_SOLVER


def _cmd_profile(a: argparse.Namespace) -> int:
    from .planning import profile

    if a.plot:
        output_path(a.plot, "--plot", figure=True)
    vehicle = vehicle_arg(a.vehicle)
    terrain = terrain_args(a, vehicle)
    v0, v1 = _num(a.v0, "--v0"), _num(a.v1, "--v1")
    if v0 is None or v1 is None:
        raise DataError("arguments --v0 and --v1 are required")
    if v0 < 0:
        raise DataError(f"argument --v0 must be >= 0 m/s, got {v0:g}")
    if v1 < 0:
        raise DataError(f"argument --v1 must be >= 0 m/s, got {v1:g}")
    check_distance(_num(a.distance, "--distance"))  # beyond any route: refused
    res = profile(
        terrain,
        vehicle,
        v0=v0,
        v1=v1,
        distance=_num(a.distance, "--distance"),
        duration=_num(a.duration, "--duration"),
        grade_deg=_num(a.grade_deg, "--grade-deg") or 0.0,
        max_slip=_num(a.max_slip, "--max-slip"),
        objective=a.objective,
        intervals=int_option(a.intervals, "--intervals", 50),
        torque_rate=_num(a.torque_rate, "--torque-rate"),
        confidence=_num(a.confidence, "--confidence"),
        max_speed=_num(a.max_speed, "--max-speed"),
        slip0=_num(a.initial_slip, "--initial-slip"),
        radius_m=_num(a.turn_radius, "--turn-radius"),  # a turn over the whole profile (planning.route_turns)
    )
    return print_result(res, a, route=False)


def add_parser(sub) -> None:
    """Register the ``profile`` subcommand on an argparse subparsers object."""
    p = sub.add_parser(
        "profile",
        help="optimal speed/slip/torque profile on one terrain (exit 1: infeasible)",
        description=_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example:\n  soiltrack profile --vehicle heavy --terrain lete_sand --v0 0.5 --v1 3 --distance 30 "
        "--max-speed 4 --plot profile.png\n  soiltrack profile --vehicle light --fit FIT.json "
        "--v0 0.5 --v1 1.5 --duration 8 --objective energy --json",
    )
    p.add_argument("--vehicle", required=True, help="vehicle JSON file or preset name (heavy, light)")
    add_terrain_arguments(p)
    p.add_argument("--v0", required=True, metavar="V0", help="initial speed, m/s")
    p.add_argument("--v1", required=True, metavar="V1", help="target speed, m/s")
    p.add_argument("--distance", metavar="D", help="distance, m")
    p.add_argument("--duration", metavar="T", help="duration, s (instead of --distance; objective energy)")
    p.add_argument("--grade-deg", metavar="G", help="grade in degrees, positive uphill (default 0)")
    p.add_argument("--max-slip", metavar="S", help="slip limit in (0, 1) (default 0.2)")
    add_objective_argument(p)
    p.add_argument("--intervals", metavar="N", help="mesh intervals of the optimal control problem (default 50)")
    p.add_argument("--torque-rate", metavar="R", help="torque rate limit, N m/s (default none)")
    p.add_argument("--confidence", metavar="P", help="with --fit: probability that the slip limit holds (robust plan)")
    add_start_arguments(p)
    p.add_argument(
        "--turn-radius",
        metavar="R",
        help="turn of radius R m (signed: positive to the left) over the whole profile: left and right torques "
        "and slips by the steering model on the planned speeds (needs tread_m; flat only)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    p.add_argument(
        "--plot",
        metavar="PNG",
        help="save speed, slip, torque and traction reserve against distance (.png, .pdf, .svg)",
    )
    p.set_defaults(func=_cmd_profile)
