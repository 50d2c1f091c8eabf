"""``soiltrack route``: a feasible profile over a route of terrain patches (ROUTE.json)."""
from __future__ import annotations

import argparse

from .cliutil import vehicle_arg
from .cmd_profile import _int, print_result


def _cmd_route(a: argparse.Namespace) -> int:
    from .planning import load_fit_json, read_route, route_profile

    vehicle = vehicle_arg(a.vehicle)
    default = load_fit_json(a.fit, vehicle) if a.fit else None
    route = read_route(a.route, default_terrain=default)
    res = route_profile(route, vehicle, intervals=None if a.intervals is None else _int(a.intervals, "--intervals", 0))
    return print_result(res, a, route=True)


def add_parser(sub) -> None:
    """Register the ``route`` subcommand on an argparse subparsers object."""
    p = sub.add_parser("route", help="optimal profile over a route of terrain patches (exit 1: infeasible, patch named)")
    p.add_argument("route", help="ROUTE.json: v0_m_s, v_end_m_s, objective, max_slip, patches "
                                 "[{length_m, terrain | soil, grade_deg}]")
    p.add_argument("--vehicle", required=True, help="vehicle JSON file or preset name (heavy, light)")
    p.add_argument("--fit", metavar="FIT.json", help="identified soil for patches that name no terrain or soil")
    p.add_argument("--intervals", metavar="N", help="mesh intervals in total (default 10 per patch, at least 50)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    p.add_argument("--plot", metavar="PNG", help="save speed, slip, torque and traction reserve against distance")
    p.set_defaults(func=_cmd_route)
