"""``soiltrack fit``: identify the soil from a CSV."""
from __future__ import annotations

import argparse

from .cliutil import EXIT_OK, EXIT_SOLVER, floats_arg, vehicle_arg
from .soilmodel import DataError

# --- fit --------------------------------------------------------------------------------------
def _cmd_fit(a: argparse.Namespace) -> int:
    from .identify import fit
    from .soilmodel import DriveLog, read_csv

    data = read_csv(a.data)
    vehicle = vehicle_arg(a.vehicle)
    kw = {"engine": a.engine} if a.engine != "ipopt" else {}
    if a.sigma is not None and not isinstance(data, DriveLog):
        kw["sigma"] = a.sigma if a.sigma == "relative" else floats_arg(a.sigma, "--sigma")[0]
    if a.bias_correction != "none":
        if not isinstance(data, DriveLog):
            raise DataError("--bias-correction applies to drive logs only", file=a.data)
        kw["bias_correction"] = a.bias_correction
    if a.effect:
        kw["effects"] = [e.strip() for item in a.effect for e in item.split(",") if e.strip()]
    result = fit(data, vehicle, model=a.model, method=a.method, **kw)
    if a.json:
        print(result.to_json())
    else:
        print(result.report())
    if a.plot:
        from .plots import plot_fit

        plot_fit(data, vehicle, result, a.plot)
    return EXIT_OK if result.success else EXIT_SOLVER


def add_parser(sub) -> None:
    """Register the ``fit`` subcommand on an argparse subparsers object."""
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
    f.add_argument("--effect", action="append", metavar="NAME",
                   help="fit this unmodelled effect's parameters jointly with the soil (repeatable; e.g. grade, "
                        "slip_sinkage, speed_resistance, mass_error)")
    f.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    f.add_argument("--plot", metavar="PNG", help="save a figure of the data and the fit")
    f.set_defaults(func=_cmd_fit)
