"""``soiltrack diagnose``: the sim-to-real gap of a CSV against the nominal model (docs/data-formats.md)."""

from __future__ import annotations

import argparse

from .cliutil import EXIT_OK, EXIT_SOLVER, output_path, read_data_arg, running_gear_arg
from .columns_cli import add_columns_argument, column_notes, columns_arg, with_column_notes
from .soilmodel.rigid_wheel import RigidWheel


def _cmd_diagnose(a: argparse.Namespace) -> int:
    from .identify import diagnose

    if a.plot:  # checked before the work (a missing folder or an unknown extension: exit 2)
        output_path(a.plot, "--plot", figure=True)
    gear = running_gear_arg(a.vehicle)
    if isinstance(gear, RigidWheel):
        from .wheel_cli import diagnose_wheel_command

        return diagnose_wheel_command(a, gear)
    vehicle = gear
    if getattr(a, "fix", None):
        from .soilmodel import DataError

        raise DataError("--fix applies to a rigid wheel (--vehicle WHEEL.json) only")
    data = read_data_arg(a, a.data, driving_only=a.driving_only, slip_angle=a.slip_angle, columns=columns_arg(a))
    cands = None
    if a.candidates is not None:
        cands = [c.strip() for c in a.candidates.split(",") if c.strip()]
        if not cands:
            from .soilmodel import DataError

            raise DataError(f"--candidates expects comma-separated effect names, got {a.candidates!r}")
    from .soilmodel import DataError, DriveLog, SlipData

    if a.torque_hold not in (None, "auto") and not isinstance(data, DriveLog):
        raise DataError("--torque-hold applies to drive logs only", file=a.data)
    if not isinstance(data, (SlipData, DriveLog)):  # a bevameter test: diagnose refuses it (same words)
        raise DataError(f"diagnose takes SlipData or DriveLog, got {type(data).__name__}")
    import sys
    import time

    t0 = time.perf_counter()

    def progress(msg: str) -> None:
        print(f"[{time.perf_counter() - t0:5.1f} s] {msg}", file=sys.stderr, flush=True)

    from .soilmodel import PRACTICAL_BOUNDS, WIDE_BOUNDS

    bounds = {"auto": None, "practical": PRACTICAL_BOUNDS, "wide": WIDE_BOUNDS}[a.bounds]
    d = diagnose(
        data,
        vehicle,
        model=a.model,
        candidates=cands,
        torque_hold=None if a.torque_hold == "auto" else a.torque_hold,
        bounds=bounds,
        progress=None if a.quiet else progress,
    )
    print(with_column_notes(d.to_json() if a.json else d.report(), column_notes(a.data, columns_arg(a)), a.json))
    if a.plot:
        d.plot(a.plot)
    return EXIT_OK if d.converged else EXIT_SOLVER


_DESCRIPTION = """Diagnose the gap between the nominal model and measured data (a slip sweep or a drive log).

The data's channels are first checked against each other and the vehicle (a failed check: no
diagnosis, exit 1). Every explanation is a hypothesis in one comparison: the candidate effects, a
flexible "something else" term, the nominal model ("none") and causes outside the library (a delay
between channels, a change of terrain over a time window, a clipped sensor, a soil beyond the
practical range, a plateau). Each is fitted; the admissible ones are weighed once, on held-out
blocks for a log and by penalised in-sample evidence for a sweep. The verdict is the heaviest
hypothesis when there is a gap and it explains enough of it; its confidence is its weight.
Exit 0 when the diagnosis converged, 1 when it could not (the reason printed), 2 for bad input.
Method: docs/diagnosis.md."""


def add_parser(sub) -> None:
    """Register the ``diagnose`` subcommand on an argparse subparsers object."""
    p = sub.add_parser(
        "diagnose",
        help="where a model and measured data part, which unmodelled effect explains "
        "it, and how far the gap shrinks (slip sweep or drive log)",
        description=_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example:\n  soiltrack simulate --kind sweep --vehicle light --terrain sandy_loam --loads 300,450 "
        "--effect slip_sinkage=0.1 --seed 1 -o sweep.csv\n  soiltrack diagnose sweep.csv --vehicle light --plot "
        "diagnosis.png",
    )
    p.add_argument("data", help="CSV: slip,tractive_force_N|drawbar_pull_N[,normal_load_N] or a drive log")
    p.add_argument("--vehicle", required=True, help="vehicle JSON file or preset name (heavy, light)")
    p.add_argument(
        "--model",
        choices=("full", "cohesion-free"),
        default="full",
        help="soil model of the nominal fit and of every candidate: full (c, phi, K; Eq. 2) or cohesion-free "
        "(phi, K; Eq. 8) (default: full)",
    )
    p.add_argument(
        "--fix",
        action="append",
        metavar="NAME=VALUE",
        help="rigid wheel: hold a soil parameter in edge units (repeatable), e.g. friction_angle_deg=30 from a "
        "shear test (the grousers hypothesis needs phi, or c above 0, held); names as fit --fix",
    )
    p.add_argument(
        "--candidates",
        metavar="A,B,...",
        help="candidate effects (default: every effect that shows in this kind of data)",
    )
    p.add_argument(
        "--torque-hold",
        choices=("auto", "zoh", "sample"),
        default=None,
        help="drive logs: zoh: the torque is held from each sample to the next (a logged command); "
        "sample: a continuous torque signal sampled at each time (a transducer); auto (the "
        "default): the one with which the nominal model predicts held-out blocks better (held "
        "unless sampled is significantly better; the report says which)",
    )
    p.add_argument(
        "--bounds",
        choices=("auto", "practical", "wide"),
        default="auto",
        help="soil bounds of the fits: the practical range (c 0-69 kPa, phi 6-40 deg, K 6-50 mm), "
        "widened (c 0-200 kPa, phi 1-55 deg, K 2-250 mm), or auto (the default): practical, "
        "with a soil beyond it weighed as a cause outside the library",
    )
    p.add_argument(
        "--driving-only",
        action="store_true",
        help="slip sweeps: drop the rows at negative slip (skid: outside the driving model) "
        "instead of refusing the file",
    )
    p.add_argument(
        "--slip-angle",
        type=float,
        metavar="0",
        help="slip sweeps with a slip_angle_deg column: keep only the rows at slip angle 0 "
        "instead of refusing the file",
    )
    add_columns_argument(p)
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    p.add_argument("--plot", metavar="PNG", help="save a figure of the held-out residuals, weights and localisation")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=_cmd_diagnose)
