"""``soiltrack margin``: traversability margin of a vehicle on a terrain, a soil or a fit."""

from __future__ import annotations

import argparse
import json

from .argcheck import check_drawbar
from .cliutil import EXIT_OK, EXIT_SOLVER, floats_arg, output_path, vehicle_arg
from .soilmodel import TERRAINS, DataError
from .turn_cli import add_margin_options, turn_margin_command


def terrain_args(a: argparse.Namespace, vehicle):
    """``--terrain`` / ``--soil`` / ``--fit`` -> Soil or SoilUncertainty (exactly one; default none is an error)."""
    from .cliutil import soil_arg
    from .planning import load_fit_json

    given = [x for x in (a.terrain, a.soil, a.fit) if x is not None]
    if len(given) != 1:
        raise DataError("give exactly one of --terrain NAME, --soil C_KPA,PHI_DEG,K_M or --fit FIT.json")
    if a.fit is not None:
        return load_fit_json(a.fit, vehicle, allow_other_vehicle=bool(getattr(a, "allow_other_vehicle", False)))
    if a.terrain is not None and a.terrain not in TERRAINS:
        raise DataError(f"argument --terrain: unknown terrain {a.terrain!r}; presets: {sorted(TERRAINS)}")
    return soil_arg(a.terrain, a.soil)


def add_terrain_arguments(p: argparse.ArgumentParser) -> None:
    """The shared ``--terrain | --soil | --fit`` arguments."""
    p.add_argument("--terrain", help=f"terrain preset ({', '.join(sorted(TERRAINS))})")
    p.add_argument("--soil", metavar="C_KPA,PHI_DEG,K_M", help="soil parameters (no Bekker parameters: no compaction)")
    p.add_argument("--fit", metavar="FIT.json", help="what `soiltrack fit --json` printed (soil with its uncertainty)")
    add_other_vehicle_argument(p)


def add_other_vehicle_argument(p: argparse.ArgumentParser) -> None:
    """``--allow-other-vehicle``: plan with a fit of another running gear on purpose."""
    from .planning.fit_vehicle import VEHICLE_TOLERANCE

    p.add_argument(
        "--allow-other-vehicle",
        action="store_true",
        help="with --fit: plan even when the fit's running gear differs from --vehicle by more than "
        f"{VEHICLE_TOLERANCE * 100:g} %% in weight, contact area or track length (the soil is mapped with the "
        "fit's own contact area and load, and the report says so); default: refused, exit 2",
    )


_DESCRIPTION = """\
Traversability margin of a vehicle on a terrain preset, a soil, or an identified soil.

Available thrust: the soil's thrust at the allowed slip (Eq. 2 at the normal load W cos(theta))
or the drivetrain limit min(T_max / r, P_max / v), whichever is smaller. Required thrust:
rolling, Bekker compaction (terrain presets with n, k_c, k_phi), grade, inertia, drawbar pull,
and a fit's slip_sinkage / speed_resistance. Downhill the required thrust is negative: the soil
must brake the vehicle, checked against its skid limit (F(i) = -F(|i|)). A vehicle JSON with
cg_height_m adds the static tipping limit; the soil's sliding limit always applies.
With --fit (what 'soiltrack fit --json' printed) the soil is uncertain: the probability of
being traversable (Monte Carlo and delta method) and the worst case over the 95 % region.

Exit status: 0 traversable, 1 not traversable (the report or JSON is printed), 2 bad input."""


def _num(text: str | None, name: str):
    return None if text is None else floats_arg(text, name)[0]


def _cmd_margin(a: argparse.Namespace) -> int:
    from .planning import margin

    if a.plot:
        output_path(a.plot, "--plot", figure=True)
    vehicle = vehicle_arg(a.vehicle)
    terrain = terrain_args(a, vehicle)
    check_drawbar(_num(a.drawbar_N, "--drawbar-N"), vehicle)  # a push at most W, a pull at most 10 W
    m = margin(
        terrain,
        vehicle,
        grade_deg=_num(a.grade_deg, "--grade-deg") or 0.0,
        accel=_num(a.accel, "--accel") or 0.0,
        drawbar_N=_num(a.drawbar_N, "--drawbar-N") or 0.0,
        speed=_num(a.speed, "--speed"),
        max_slip=_num(a.max_slip, "--max-slip"),
    )
    if a.turn_radius is not None:  # a steady turn with the steering model (soiltrack.planning.turning)
        return turn_margin_command(a, terrain, vehicle, m)
    print(json.dumps(m.to_dict(), indent=2, allow_nan=False) if a.json else m.report())
    if a.plot:
        from .planning.plots import plot_margin

        plot_margin(terrain, vehicle, m, a.plot)
    return EXIT_OK if m.traversable else EXIT_SOLVER


def add_parser(sub) -> None:
    """Register the ``margin`` subcommand on an argparse subparsers object."""
    p = sub.add_parser(
        "margin",
        help="traversability margin: available against required thrust (exit 1: not traversable)",
        description=_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example:\n  soiltrack margin --vehicle heavy --terrain lete_sand --grade-deg 15 --plot "
        "margin.png\n  soiltrack margin --vehicle light --fit FIT.json --grade-deg 10 --json",
    )
    p.add_argument("--vehicle", required=True, help="vehicle JSON file or preset name (heavy, light)")
    add_terrain_arguments(p)
    p.add_argument("--grade-deg", metavar="G", help="grade in degrees, positive uphill (default 0)")
    p.add_argument("--accel", metavar="A", help="acceleration to sustain, m/s^2 (default 0)")
    p.add_argument("--drawbar-N", dest="drawbar_N", metavar="D", help="drawbar pull to deliver, N (default 0)")
    p.add_argument("--speed", metavar="V", help="vehicle speed, m/s (brings in the power limit)")
    p.add_argument("--max-slip", metavar="S", help="allowed slip in (0, 1) (default 0.2)")
    add_margin_options(p)
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    p.add_argument(
        "--plot",
        metavar="PNG",
        help="save the thrust-slip curve against the limits and the requirement (.png, .pdf, .svg)",
    )
    p.set_defaults(func=_cmd_margin)
