"""``soiltrack profile``: a feasible speed/slip/torque profile on one terrain, by optimal control."""
from __future__ import annotations

import argparse
import json

from .argcheck import check_distance
from .cliutil import EXIT_OK, EXIT_SOLVER, floats_arg, vehicle_arg
from .cmd_margin import add_terrain_arguments, terrain_args
from .soilmodel import DataError


def _num(text: str | None, name: str):
    return None if text is None else floats_arg(text, name)[0]


def _int(text: str | None, name: str, default: int) -> int:
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
    res = profile(terrain, vehicle, v0=v0, v1=v1, distance=_num(a.distance, "--distance"),
                  duration=_num(a.duration, "--duration"), grade_deg=_num(a.grade_deg, "--grade-deg") or 0.0,
                  max_slip=_num(a.max_slip, "--max-slip"), objective=a.objective,
                  intervals=_int(a.intervals, "--intervals", 50), torque_rate=_num(a.torque_rate, "--torque-rate"),
                  confidence=_num(a.confidence, "--confidence"))
    return print_result(res, a, route=False)


def add_parser(sub) -> None:
    """Register the ``profile`` subcommand on an argparse subparsers object."""
    p = sub.add_parser("profile", help="optimal speed/slip/torque profile on one terrain (exit 1: infeasible)")
    p.add_argument("--vehicle", required=True, help="vehicle JSON file or preset name (heavy, light)")
    add_terrain_arguments(p)
    p.add_argument("--v0", required=True, metavar="V0", help="initial speed, m/s")
    p.add_argument("--v1", required=True, metavar="V1", help="target speed, m/s")
    p.add_argument("--distance", metavar="D", help="distance, m")
    p.add_argument("--duration", metavar="T", help="duration, s (instead of --distance; objective energy)")
    p.add_argument("--grade-deg", metavar="G", help="grade in degrees, positive uphill (default 0)")
    p.add_argument("--max-slip", metavar="S", help="slip limit in (0, 1) (default 0.2)")
    p.add_argument("--objective", choices=("time", "energy"), default="time")
    p.add_argument("--intervals", metavar="N", help="mesh intervals (default 50)")
    p.add_argument("--torque-rate", metavar="R", help="torque rate limit, N m/s (default none)")
    p.add_argument("--confidence", metavar="P", help="with --fit: probability that the slip limit holds (robust plan)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    p.add_argument("--plot", metavar="PNG", help="save speed, slip, torque and traction reserve against distance")
    p.set_defaults(func=_cmd_profile)
