"""``soiltrack route``: a feasible profile over a route of terrain patches (ROUTE.json)."""

from __future__ import annotations

import argparse

from .cliutil import floats_arg, output_path, vehicle_arg
from .cmd_margin import add_other_vehicle_argument
from .cmd_profile import add_start_arguments, int_option, print_result

_DESCRIPTION = """\
A feasible speed/slip/torque profile over a route of terrain patches (ROUTE.json), by optimal
control: a mesh point on every patch boundary, each patch with its soil, grade and compaction.
ROUTE.json: {"v0_m_s", "v_end_m_s", "objective": "time" | "energy", "max_slip",
"patches": [{"length_m", "terrain": NAME | "soil": {"cohesion_kpa", "friction_angle_deg",
"shear_modulus_m"}, "grade_deg", "radius_m"}]}; patches naming neither take the soil of --fit.
radius_m (signed, positive to the left; optional): the patch is a turn of that radius, planned
with the steering model on the planned speeds (left and right torques and slips; needs tread_m).

Exit status: 0 feasible, 1 infeasible (the patch and the limit named) or solver failed, 2 bad input."""


def _num(text: str | None, name: str):
    return None if text is None else floats_arg(text, name)[0]


def _cmd_route(a: argparse.Namespace) -> int:
    from .planning import load_fit_json, read_route, route_profile
    from .planning.route_turns import check_turns

    if a.plot:
        output_path(a.plot, "--plot", figure=True)
    vehicle = vehicle_arg(a.vehicle)
    default = load_fit_json(a.fit, vehicle, allow_other_vehicle=a.allow_other_vehicle) if a.fit else None
    route = read_route(a.route, default_terrain=default)
    check_turns(route.patches, vehicle, a.route)  # radius_m: tread, half the tread, flat (planning.route_turns)
    res = route_profile(
        route,
        vehicle,
        intervals=None if a.intervals is None else int_option(a.intervals, "--intervals", 0),
        max_speed=_num(a.max_speed, "--max-speed"),
        slip0=_num(a.initial_slip, "--initial-slip"),
    )
    return print_result(res, a, route=True)


def add_parser(sub) -> None:
    """Register the ``route`` subcommand on an argparse subparsers object."""
    p = sub.add_parser(
        "route",
        help="optimal profile over a route of terrain patches (exit 1: infeasible, patch named)",
        description=_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example:\n  soiltrack route ROUTE.json --vehicle heavy --max-speed 4 --plot route.png",
    )
    p.add_argument(
        "route",
        help="ROUTE.json: v0_m_s, v_end_m_s, objective, max_slip, patches [{length_m, terrain | soil, grade_deg, "
        "radius_m}]",
    )
    p.add_argument("--vehicle", required=True, help="vehicle JSON file or preset name (heavy, light)")
    p.add_argument("--fit", metavar="FIT.json", help="identified soil for patches that name no terrain or soil")
    add_other_vehicle_argument(p)
    p.add_argument("--intervals", metavar="N", help="mesh intervals in total (default 10 per patch, at least 50)")
    add_start_arguments(p)
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    p.add_argument(
        "--plot",
        metavar="PNG",
        help="save speed, slip, torque and traction reserve against distance (.png, .pdf, .svg)",
    )
    p.set_defaults(func=_cmd_route)
