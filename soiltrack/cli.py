"""The ``soiltrack`` command: one subcommand per job.

Exit status: 0 success; 1 the solver failed (results are still printed, with the reason);
2 bad input (the message names the file, the column and the row; no traceback).
"""
from __future__ import annotations

import argparse
import math
import os
import sys
from typing import Sequence

from .soilmodel import TERRAINS, VEHICLES, DataError, Soil, Vehicle

EXIT_OK, EXIT_SOLVER, EXIT_INPUT = 0, 1, 2


def _vehicle(arg: str) -> Vehicle:
    if arg in VEHICLES:
        return VEHICLES[arg]
    if not os.path.exists(arg):
        raise DataError(f"no such vehicle file, and not a preset name (presets: {sorted(VEHICLES)})", file=arg)
    return Vehicle.from_json(arg)


def _soil(terrain: str | None, soil: str | None) -> Soil:
    if soil:
        parts = soil.split(",")
        if len(parts) != 3:
            raise DataError(f"--soil expects C_KPA,PHI_DEG,K_M (three numbers), got {soil!r}")
        try:
            c, phi, K = (float(p) for p in parts)
        except ValueError:
            raise DataError(f"--soil expects three numbers C_KPA,PHI_DEG,K_M, got {soil!r}") from None
        return Soil.from_kpa_deg(c, phi, K, name="command line")
    key = terrain or "lete_sand"
    if key not in TERRAINS:
        raise DataError(f"unknown terrain {key!r}; presets: {sorted(TERRAINS)}")
    return TERRAINS[key]


def _floats(text: str, what: str) -> list[float]:
    try:
        vals = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise DataError(f"{what} expects comma-separated numbers, got {text!r}") from None
    if not vals or not all(math.isfinite(v) for v in vals):
        raise DataError(f"{what} expects finite numbers, got {text!r}")
    return vals


# --- simulate ---------------------------------------------------------------------------------
def _cmd_simulate(a: argparse.Namespace) -> int:
    from .soilmodel import write_csv
    from .soilmodel.effects import parse_effects
    from .soilmodel.simulation import simulate

    vehicle, soil = _vehicle(a.vehicle), _soil(a.terrain, a.soil)
    effects = parse_effects(a.effect or [])
    kwargs = dict(kind=a.kind, effects=effects, seed=a.seed, noise=a.noise, model=a.model)
    if a.kind == "drive":
        if a.duration is not None:
            kwargs["duration_s"] = a.duration
        if a.rate is not None:
            kwargs["sample_rate_hz"] = a.rate
    else:
        if a.slips:
            kwargs["slips"] = _floats(a.slips, "--slips")
        if a.loads:
            kwargs["normal_loads"] = _floats(a.loads, "--loads")
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


# --- fit --------------------------------------------------------------------------------------
def _cmd_fit(a: argparse.Namespace) -> int:
    from .identify import fit
    from .soilmodel import DriveLog, read_csv

    data = read_csv(a.data)
    vehicle = _vehicle(a.vehicle)
    kw = {"engine": a.engine} if a.engine != "ipopt" else {}
    if a.sigma is not None and not isinstance(data, DriveLog):
        kw["sigma"] = a.sigma if a.sigma == "relative" else _floats(a.sigma, "--sigma")[0]
    if a.bias_correction != "none":
        if not isinstance(data, DriveLog):
            raise DataError("--bias-correction applies to drive logs only", file=a.data)
        kw["bias_correction"] = a.bias_correction
    result = fit(data, vehicle, model=a.model, method=a.method, **kw)
    if a.json:
        print(result.to_json())
    else:
        print(result.report())
    if a.plot:
        from .plots import plot_fit

        plot_fit(data, vehicle, result, a.plot)
    return EXIT_OK if result.success else EXIT_SOLVER


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``soiltrack`` command."""
    p = argparse.ArgumentParser(prog="soiltrack", description="Soil-parameter identification and traversability for tracked vehicles.")
    from . import __version__

    p.add_argument("--version", action="version", version=f"soiltrack {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

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

    f = sub.add_parser("fit", help="identify soil parameters from a CSV (slip sweep or drive log)")
    f.add_argument("data", help="CSV file: slip,tractive_force_N[,normal_load_N] or a drive log")
    f.add_argument("--vehicle", required=True, help="vehicle JSON file or preset name (heavy, light)")
    f.add_argument("--model", choices=("full", "cohesion-free"), default="full")
    f.add_argument("--method", choices=("ipopt", "newton", "least-squares"), default="ipopt")
    f.add_argument("--engine", choices=("ipopt", "compiled", "auto"), default="ipopt",
                   help="solver engine for --method ipopt on slip data: IPOPT (default), or the compiled "
                        "projected Levenberg-Marquardt engine that hands anything it cannot certify to IPOPT")
    f.add_argument("--sigma", metavar="N|relative",
                   help="slip data: force noise standard deviation in N (taken as known), or 'relative' for noise "
                        "proportional to the force (level estimated); default: equal weights, level estimated")
    f.add_argument("--bias-correction", choices=("none", "simex"), default="none",
                   help="drive logs: SIMEX correction of the slip-noise bias of K on hard-pull logs (about 5 s)")
    f.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    f.add_argument("--plot", metavar="PNG", help="save a figure of the data and the fit")
    f.set_defaults(func=_cmd_fit)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except DataError as e:
        print(f"soiltrack {args.command}: error: {e}", file=sys.stderr)
        return EXIT_INPUT
    except BrokenPipeError:  # pragma: no cover
        return EXIT_OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
