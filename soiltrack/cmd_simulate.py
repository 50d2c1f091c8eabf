"""``soiltrack simulate``: write a simulated drive log or slip sweep."""
from __future__ import annotations

import argparse
import sys

from .cliutil import EXIT_OK, floats_arg, soil_arg, vehicle_arg
from .soilmodel import TERRAINS

# --- simulate ---------------------------------------------------------------------------------
def _cmd_simulate(a: argparse.Namespace) -> int:
    from .soilmodel import write_csv
    from .soilmodel.effects import parse_effects
    from .soilmodel.simulation import simulate

    vehicle, soil = vehicle_arg(a.vehicle), soil_arg(a.terrain, a.soil)
    effects = parse_effects(a.effect or [])
    kwargs = dict(kind=a.kind, effects=effects, seed=a.seed, noise=a.noise, model=a.model)
    if a.kind == "drive":
        if a.duration is not None:
            kwargs["duration_s"] = a.duration
        if a.rate is not None:
            kwargs["sample_rate_hz"] = a.rate
    else:
        if a.slips:
            kwargs["slips"] = floats_arg(a.slips, "--slips")
        if a.loads:
            kwargs["normal_loads"] = floats_arg(a.loads, "--loads")
    data = simulate(vehicle, soil, **kwargs)
    if a.output == "-":
        write_csv(data, sys.stdout)
    else:
        write_csv(data, a.output)
        print(f"wrote {data.n_samples} rows ({'drive log' if a.kind == 'drive' else 'slip sweep'}) to {a.output}",
              file=sys.stderr)
    if a.plot:
        from .plots import plot_data

        plot_data(data, a.plot, title=f"{vehicle.name or a.vehicle} on {soil.name or 'soil'}")
    return EXIT_OK


def add_parser(sub) -> None:
    """Register the ``simulate`` subcommand on an argparse subparsers object."""
    s = sub.add_parser("simulate", help="write a simulated drive log or tractive force-slip sweep (CSV)")
    s.add_argument("--vehicle", default="heavy", help="preset name (heavy, light) or vehicle JSON file")
    g = s.add_mutually_exclusive_group()
    g.add_argument("--terrain", help=f"terrain preset ({', '.join(TERRAINS)}); default lete_sand")
    g.add_argument("--soil", help="soil as C_KPA,PHI_DEG,K_M, e.g. 1.3,31.1,0.012")
    s.add_argument("--kind", choices=("drive", "sweep"), default="drive", help="drive log (default) or slip sweep")
    s.add_argument("--effect", action="append", metavar="NAME=VALUE",
                   help="switch on an unmodelled effect, e.g. grade=0.03, drivetrain_friction.tau_v=2 (repeatable)")
    s.add_argument("--model", choices=("full", "cohesion-free"), default="full")
    s.add_argument("--noise", choices=("default", "none"), default="default", help="sensor noise")
    s.add_argument("--seed", type=int, default=None, help="random seed for the noise")
    s.add_argument("--duration", type=float, default=None, help="drive log length, s")
    s.add_argument("--rate", type=float, default=None, help="drive log sample rate, Hz")
    s.add_argument("--slips", help="sweep: comma-separated slips")
    s.add_argument("--loads", help="sweep: comma-separated normal loads, N (several make c and phi separable)")
    s.add_argument("-o", "--output", default="-", help="output CSV path ('-' for stdout)")
    s.add_argument("--plot", metavar="PNG", help="also save a figure of the data")
    s.set_defaults(func=_cmd_simulate)
