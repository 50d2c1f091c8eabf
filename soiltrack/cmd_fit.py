"""``soiltrack fit``: identify the soil from a CSV."""

from __future__ import annotations

import argparse
import sys

from .cliutil import floats_arg, output_path, read_data_arg, running_gear_arg
from .cmd_segments import add_arguments as add_segment_arguments
from .cmd_segments import check_budget, memory_limit_arg, segments_command
from .columns_cli import add_columns_argument, column_notes, columns_arg, with_column_notes
from .identify.drivelog import DISCRETISATIONS
from .identify.engines import DEFAULT_ENGINE, ENGINES
from .identify.outcome import exit_code
from .soilmodel import PRACTICAL_BOUNDS, WIDE_BOUNDS, DataError, SoilBounds
from .soilmodel.rigid_wheel import RigidWheel
from .turn_cli import add_fit_options, fit_motion_command

#: Named soil bounds of ``--bounds`` (the same names as ``diagnose --bounds``).
NAMED_BOUNDS = {"practical": PRACTICAL_BOUNDS, "wide": WIDE_BOUNDS}


def bounds_arg(text: str) -> SoilBounds:
    """``--bounds``: a name of :data:`NAMED_BOUNDS` or six numbers ``C_LO,C_HI,PHI_LO,PHI_HI,K_LO,K_HI``
    (kPa, deg, m) within the physical domain (c >= 0, 0 < phi < 90 deg, K > 0); DataError otherwise."""
    if text in NAMED_BOUNDS:
        return NAMED_BOUNDS[text]
    what = (
        f"--bounds expects {' or '.join(NAMED_BOUNDS)} or six numbers C_LO,C_HI,PHI_LO,PHI_HI,K_LO,K_HI (kPa, deg, m)"
    )
    vals = floats_arg(text, "--bounds") if any(ch.isdigit() for ch in text) else []
    if len(vals) != 6:
        raise DataError(f"{what}, got {text!r}")
    c, phi, K = vals[0:2], vals[2:4], vals[4:6]
    for name, (lo, hi), ok in (("c", c, c[0] >= 0), ("phi", phi, 0 < phi[0] and phi[1] < 90), ("K", K, K[0] > 0)):
        if not ok or not lo < hi:
            raise DataError(
                f"{what}: the {name} bounds [{lo:g}, {hi:g}] are not a range within c >= 0 kPa, "
                f"0 < phi < 90 deg, K > 0 m (lower < upper)"
            )
    return SoilBounds.from_kpa_deg((c[0], c[1]), (phi[0], phi[1]), (K[0], K[1]))


# --- fit --------------------------------------------------------------------------------------
def _check_options(a: argparse.Namespace, drive_log: bool) -> None:
    """Refuse options that do not apply to these data or this method (nothing is silently ignored)."""
    if a.engine != DEFAULT_ENGINE and (a.method != "ipopt" or drive_log):
        raise DataError(
            f"--engine {a.engine} applies to --method ipopt on slip data only"
            + (" (this file is a drive log)" if drive_log else f", not to --method {a.method}"),
            file=a.data if drive_log else None,
        )
    if a.sigma is not None and drive_log:
        raise DataError("--sigma applies to slip data only; a drive-log fit estimates its noise levels", file=a.data)
    if a.bias_correction != "none" and not drive_log:
        raise DataError("--bias-correction applies to drive logs only", file=a.data)
    if a.torque_hold is not None and not drive_log:
        raise DataError("--torque-hold applies to drive logs only", file=a.data)
    if a.discretisation is not None and not drive_log:
        raise DataError("--discretisation applies to drive logs only", file=a.data)
    if a.resistance is not None and drive_log:
        raise DataError(
            "--resistance applies to drawbar-pull sweeps; a drive log's resistance is the vehicle's (or an --effect)",
            file=a.data,
        )
    for opt, val in (("--slip-noise", a.slip_noise), ("--interval-method", a.interval_method)):
        if val is not None and drive_log:
            raise DataError(
                f"{opt} applies to slip sweeps only (a drive log's slip is a latent variable of its fit)", file=a.data
            )
        if val is not None and a.method != "ipopt":
            raise DataError(f"{opt} applies to --method ipopt, not to --method {a.method}")


#: Options of slip sweeps and drive logs and their defaults (a bevameter fit takes none of them).
_VEHICLE_OPTIONS = {
    "vehicle": None,
    "model": "full",
    "method": "ipopt",
    "engine": DEFAULT_ENGINE,
    "sigma": None,
    "bias_correction": "none",
    "torque_hold": None,
    "discretisation": None,
    "slip_noise": None,
    "intervals": None,
    "interval_method": None,
    "bounds": "practical",
    "effect": None,
    "resistance": None,
}


def _bevameter_record(a: argparse.Namespace):
    """The file as a bevameter record (annulus torque, plate force or radius), or ``None`` if it is not one."""
    from .soilmodel.bevameter_records import RECORD_COLUMNS, is_bevameter_record, read_bevameter_record
    from .soilmodel.columns import plan_columns
    from .soilmodel.csvread import read_header

    try:
        head = read_header(a.data)
    except DataError:
        return None  # read_csv names the problem
    plan = plan_columns(head, known=RECORD_COLUMNS, mapping=columns_arg(a), source=a.data)
    if not is_bevameter_record(list(plan.header)):
        return None
    return read_bevameter_record(
        a.data, inner_radius_m=a.inner_radius_m, outer_radius_m=a.outer_radius_m, columns=columns_arg(a)
    )


def _cmd_soil_test(a: argparse.Namespace, data) -> int:
    """Fit a bevameter test (no vehicle: the soil itself was measured)."""
    from .identify.soiltests import fit_soil_test

    given = [f"--{k.replace('_', '-')}" for k, v in _VEHICLE_OPTIONS.items() if getattr(a, k) != v]
    if given:
        raise DataError(
            f"{', '.join(given)} appl{'ies' if len(given) == 1 else 'y'} to slip sweeps and drive logs; "
            "a bevameter test is fitted on its own (leave it out)",
            file=a.data,
        )
    from .soilmodel.bevameter_records import RECORD_COLUMNS, AnnulusTest

    if a.plot and isinstance(data, AnnulusTest):
        raise DataError("--plot is not available for a shear annulus's record yet (the fit's report and JSON are)")
    result = fit_soil_test(data, negative_kc=a.negative_kc)
    notes = column_notes(a.data, columns_arg(a), RECORD_COLUMNS)
    print(with_column_notes(result.to_json() if a.json else result.report(), notes, a.json))
    if a.plot:
        from .plot_soiltest import plot_soil_test

        print(f"wrote the figure to {plot_soil_test(data, result, a.plot)}", file=sys.stderr)
    return exit_code(result.fit_outcome)


def _cmd_fit(a: argparse.Namespace) -> int:
    from .identify import fit
    from .soilmodel import DriveLog, PlateTest, ShearTest
    from .cmd_fit_joint import joint_fit_command, single_file_args

    if not single_file_args(a):  # several files: one soil for all (cmd_fit_joint)
        return joint_fit_command(a, _bevameter_record)
    gear = running_gear_arg(a.vehicle) if a.vehicle is not None else None
    if isinstance(gear, RigidWheel):
        from .wheel_cli import fit_wheel_command

        return fit_wheel_command(a, gear)
    if a.fix:
        raise DataError("--fix applies to a rigid wheel's fit (--vehicle WHEEL.json) only")
    if a.bulldozing_density is not None:
        raise DataError("--bulldozing-density applies to a rigid wheel's fit (--vehicle WHEEL.json) only")
    if a.plot:
        output_path(a.plot, "--plot", figure=True)
    bounds = bounds_arg(a.bounds)
    record = _bevameter_record(a)  # a shear annulus's torque or a plate's force, as recorded
    if record is not None:
        return _cmd_soil_test(a, record)
    if a.inner_radius_m is not None or a.outer_radius_m is not None:
        raise DataError("--inner-radius-m / --outer-radius-m apply to a shear annulus (torque_Nm) only", file=a.data)
    check_budget(a)  # a drive log's fit estimated from its row count: refused before the work when too large
    data = read_data_arg(a, a.data, driving_only=a.driving_only, slip_angle=a.slip_angle, columns=columns_arg(a))
    if isinstance(data, (ShearTest, PlateTest)):
        return _cmd_soil_test(a, data)
    if a.negative_kc:
        raise DataError("--negative-kc applies to plate tests only", file=a.data)
    if gear is None:
        raise DataError(
            "--vehicle is required for slip sweeps and drive logs (a vehicle JSON file or a preset name: heavy, light)",
            file=a.data,
        )
    vehicle = gear
    a.bounds_obj = bounds
    motion_rc = fit_motion_command(
        a, data, vehicle, _VEHICLE_OPTIONS
    )  # two-track log with yaw rate: the steering model
    if motion_rc is not None:
        return motion_rc
    drive_log = isinstance(data, DriveLog)
    if a.segments is not None:
        return segments_command(a, data, vehicle, bounds)
    if a.intervals is not None:  # the old name (profile's --intervals is a mesh size)
        print("soiltrack fit: --intervals is now --interval-method (the old name will go)", file=sys.stderr)
        a.interval_method = a.interval_method or a.intervals
    _check_options(a, drive_log)
    kw = {"engine": a.engine} if a.method == "ipopt" and not drive_log else {}
    kw["bounds"] = bounds
    if a.sigma is not None:
        kw["sigma"] = a.sigma if a.sigma == "relative" else floats_arg(a.sigma, "--sigma")[0]
    if a.bias_correction != "none":
        kw["bias_correction"] = a.bias_correction
    if a.torque_hold is not None:
        kw["torque_hold"] = a.torque_hold
    if a.discretisation is not None:  # else the fit's own check (identify.drivelog.fit)
        kw["discretisation"] = a.discretisation
    if a.slip_noise is not None:
        kw["slip_noise"] = (
            a.slip_noise if a.slip_noise in ("auto", "off") else floats_arg(a.slip_noise, "--slip-noise")[0]
        )
    if a.interval_method is not None:
        kw["intervals"] = a.interval_method
    if a.resistance is not None:
        kw["resistance"] = a.resistance
    if a.effect:
        kw["effects"] = [e.strip() for item in a.effect for e in item.split(",") if e.strip()]
    if drive_log:  # checked again on the data read (a ROS bag's rows are known only now)
        kw["max_memory"] = memory_limit_arg(a)
    result = fit(data, vehicle, model=a.model, method=a.method, **kw)
    notes = column_notes(a.data, columns_arg(a))
    print(with_column_notes(result.to_json() if a.json else result.report(), notes, a.json))
    if a.plot:
        from .plots import plot_fit

        path = plot_fit(data, vehicle, result, a.plot)
        print(f"wrote the figure to {path}", file=sys.stderr)
    return exit_code(result.fit_outcome)


_DESCRIPTION = """\
Identify the soil (cohesion c, friction angle phi, shear modulus K) from a CSV file, with
bounded fits (default bounds: c 0-69 kPa, phi 6-40 deg, K 0.006-0.05 m; see --bounds). The file kind is
recognised by its header (comma separated, SI units, any column order):

  tractive force-slip data:  slip,tractive_force_N[,normal_load_N]
      slip in [0, 1); rows at two or more normal loads make c and phi separable
  drawbar pull-slip data:    slip,drawbar_pull_N[,normal_load_N]
      what a test rig measures: drawbar pull = thrust - motion resistance (mu_r W nominal; a
      resistance growing with slip is the slip_sinkage effect, a constant extra one looks like grade)
  drive log:                 time_s,sprocket_torque_Nm,sprocket_speed_rad_s,vehicle_speed_m_s
                             [,vehicle_accel_m_s2]
      time strictly increasing; torque and speed of both sprockets together
  bevameter shear test:      normal_pressure_Pa,shear_displacement_m,shear_stress_Pa
      c, phi, K (two or more normal pressures separate c and phi); no --vehicle
  plate sinkage test:        plate_width_m,pressure_Pa,sinkage_m
      Bekker k_c, k_phi, n (one plate width gives only k_c / b + k_phi); no --vehicle
  single-wheel rig sweep:    slip,drawbar_pull_N,normal_load_N[,sinkage_m]
      with --vehicle WHEEL.json ({"running_gear": "rigid_wheel", "wheel_radius_m", "wheel_width_m",
      "grouser_height_m"}): the Wong-Reece rigid wheel; the load is required per row; a measured
      sinkage sets the entry angle and its load balance identifies the Bekker stiffness

Prints a report (or --json): first the outcome (usable, poor_fit, not_usable or failed, with its
reason; the solver's own status beside it), each parameter with its standard error (SE) and 95 %
interval, what the data determine, and residuals as measured - model. Exit 0 when the outcome is
usable, 1 otherwise (poor fit, not usable, failed: the report is printed), 2 for bad input."""


def add_parser(sub) -> None:
    """Register the ``fit`` subcommand on an argparse subparsers object."""
    f = sub.add_parser(
        "fit",
        help="identify soil parameters from a CSV (slip sweep or drive log)",
        description=_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example: soiltrack fit examples/data/wong2001_p176.csv "
        "--vehicle examples/data/heavy_vehicle.json --plot fit.png",
    )
    f.add_argument(
        "data",
        nargs="+",
        help="CSV file: a slip sweep (tractive force or drawbar pull), a drive log or a bevameter test (columns "
        "above); several files (wheel sweeps, bevameter tests): one soil fitted to all, with a consistency test",
    )
    f.add_argument(
        "--vehicle",
        action="append",
        help="vehicle JSON file or preset name (heavy, light); required for slip sweeps and "
        "drive logs, refused for bevameter tests; with several files once for all or once per file in order",
    )
    _add_model_options(f)
    _add_data_options(f)
    _add_kind_options(f)
    add_segment_arguments(f)  # --segments, --max-memory (soiltrack.cmd_segments)
    f.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    add_fit_options(f)
    f.add_argument("--plot", metavar="PNG", help="save a figure of the data and the fit (.png, .pdf, .svg)")
    f.set_defaults(func=_cmd_fit)


def _add_model_options(f: argparse.ArgumentParser) -> None:
    """The model, the solver and the bounds: ``--model`` to ``--resistance``."""
    f.add_argument(
        "--model",
        choices=("full", "cohesion-free"),
        default="full",
        help="full: F_max = A c + W tan(phi) (Eq. 2); cohesion-free: F_max = W tan(phi), c = 0 (Eq. 8) (default: full)",
    )
    f.add_argument(
        "--method",
        choices=("ipopt", "newton", "least-squares"),
        default="ipopt",
        help="ipopt: bounded weighted least squares (recommended); newton, least-squares: the seed "
        "paper's unbounded methods, for comparison (default: ipopt)",
    )
    f.add_argument(
        "--engine",
        choices=ENGINES,
        default=DEFAULT_ENGINE,
        help="what solves --method ipopt on slip data (same optimum): auto (default: compiled "
        "Levenberg-Marquardt, C code from the per-user cache or, while it compiles in the "
        "background, CasADi's virtual machine), ipopt, compiled (compile the C code now if not "
        "cached) or vectorized; anything not certified, and every fit with --effect, is solved "
        "by IPOPT",
    )
    f.add_argument(
        "--sigma",
        metavar="N|relative",
        help="slip data: force noise standard deviation in N (taken as known), or 'relative' for noise "
        "proportional to the force (level estimated); default: equal weights, level estimated",
    )
    f.add_argument(
        "--bias-correction",
        choices=("none", "simex"),
        default="none",
        help="drive logs: SIMEX correction of the slip-noise bias of K on hard-pull logs, about 5 s (default: none)",
    )
    f.add_argument(
        "--torque-hold",
        choices=("zoh", "sample"),
        default=None,
        help="drive logs: how the logged torque relates to the drive (default: zoh; with --effect and "
        "no --torque-hold the fit is made with both and its intervals cover both). zoh: the torque "
        "is held from each sample to the next (a controller updating it at the log rate); sample: "
        "a continuous torque signal sampled at each time (a torque transducer, or a controller "
        "much faster than the log). The wrong one biases a fitted grade by about the thrust "
        "change over one sample",
    )
    f.add_argument(
        "--discretisation",
        choices=DISCRETISATIONS,
        default=None,
        help="drive logs with a held torque: how the sprocket equation's interval means meet the slip at "
        "the samples (default: both fitted; the relaxation fit is reported where the two disagree beyond 2 "
        "standard errors, else the end-point fit). end-point: the interval's mean on the slip at its end (the "
        "quasi-static limit; on hard pulls at 50 Hz F_max comes out a few percent high); relaxation: the "
        "thrust at each sample from the four interval means around it, weighted by the slip's relaxation "
        "after each torque step (right on hard pulls, intervals a little narrow on gentle driving); see "
        "docs/drivelogs.md",
    )
    f.add_argument(
        "--slip-noise",
        metavar="auto|off|SIGMA",
        help="slip sweeps: noise on the measured slip. auto (default with --effect): weights for it "
        "when the residuals show it (likelihood-ratio test); off: slip exact (default without "
        "--effect); a number: the slip's standard deviation",
    )
    f.add_argument(
        "--bounds",
        default="practical",
        metavar="practical|wide|C_LO,C_HI,PHI_LO,PHI_HI,K_LO,K_HI",
        help="soil bounds of the fit: practical (default: c 0-69 kPa, phi 6-40 deg, K 6-50 mm), "
        "wide (c 0-200 kPa, phi 1-55 deg, K 2-250 mm), or six numbers in kPa, deg, m, e.g. "
        "0,69,2,40,0.006,0.05 for a smooth track or a slippery soil (phi below 6 deg)",
    )
    f.add_argument("--intervals", choices=("auto", "linear", "profile"), default=None, help=argparse.SUPPRESS)
    f.add_argument(
        "--interval-method",
        choices=("auto", "linear", "profile"),
        default=None,
        help="slip sweeps: 95 %% intervals from the profile likelihood for the weakly identifiable and "
        "at-bound parameters (auto, default with --effect), for all (profile), or linearised "
        "for all (linear, default without --effect)",
    )
    f.add_argument(
        "--effect",
        action="append",
        metavar="NAME",
        help="fit this unmodelled effect's parameters jointly with the soil (repeatable; e.g. grade, "
        "slip_sinkage, speed_resistance, mass_error)",
    )
    f.add_argument(
        "--resistance",
        choices=("assumed", "fit", "fit-sinkage"),
        default=None,
        help="drawbar-pull sweeps: the motion resistance is the vehicle's R = mu_r W (assumed, "
        "the default; the report says so), R = mu_r W with mu_r fitted with the soil (fit), "
        "or R = k_z z W with k_z fitted from the sinkage_m column (fit-sinkage); with its "
        "profile-likelihood interval",
    )


def _add_data_options(f: argparse.ArgumentParser) -> None:
    """Which rows of the data are used: ``--driving-only``, ``--slip-angle``."""
    f.add_argument(
        "--driving-only",
        action="store_true",
        help="slip sweeps: drop the rows at negative slip (skid, a locked wheel: outside the driving "
        "model) instead of refusing the file; the count is reported",
    )
    f.add_argument(
        "--slip-angle",
        type=float,
        metavar="0",
        help="slip sweeps with a slip_angle_deg column: keep only the rows at this slip angle (only 0: "
        "the model is straight-line) instead of refusing the file; the count is reported",
    )


def _add_kind_options(f: argparse.ArgumentParser) -> None:
    """Options of one data kind: the rigid wheel's, the column mapping, the bevameters'."""
    f.add_argument(
        "--fix",
        action="append",
        metavar="NAME=VALUE",
        help="rigid wheel: hold a parameter at a value in edge units (repeatable), e.g. bekker_n=1; names "
        "cohesion_kpa, friction_angle_deg, shear_modulus_m, bekker_kc, bekker_kphi, bekker_n",
    )
    f.add_argument(
        "--bulldozing-density",
        type=float,
        default=None,
        metavar="KG_M3",
        help="rigid wheel: add Bekker's bulldozing resistance of the sinking wheel with this soil bulk density "
        "(held; docs/physics.md)",
    )
    f.add_argument(
        "--fit-grouser-height",
        action="store_true",
        help="several files: fit the grouser height of every wheel whose JSON has grouser_height_m > 0 (its own "
        "parameter, started there), beside the shared soil (docs/physics.md, grousers)",
    )
    add_columns_argument(f)
    f.add_argument(
        "--inner-radius-m",
        type=float,
        default=None,
        metavar="R",
        help="a shear annulus's inner radius, m (when the file has no inner_radius_m column)",
    )
    f.add_argument(
        "--outer-radius-m",
        type=float,
        default=None,
        metavar="R",
        help="a shear annulus's outer radius, m (when the file has no outer_radius_m column)",
    )
    f.add_argument(
        "--negative-kc",
        action="store_true",
        help="plate tests: fit Bekker k_c freely (flagged when negative) instead of holding it >= 0 (where it ends "
        "on 0 the report gives the unconstrained value either way)",
    )
