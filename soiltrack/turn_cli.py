"""The turning parts of ``soiltrack simulate`` (``--two-track --turns``) and ``soiltrack fit`` (``--motion``)."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from .cliutil import EXIT_OK, EXIT_SOLVER, output_path
from .soilmodel import DataError

#: Drive-log options the two-track turning simulator does not take (the steering model has no effects yet).
_NOT_TWO_TRACK = (("--effect", "effect"), ("--bekker", "bekker"), ("--sinkage", "sinkage"))


def check_two_track_options(a: argparse.Namespace) -> None:
    """``--turns`` needs ``--two-track``; ``--two-track`` needs a drive log, the full model, no effects."""
    if a.turns is not None and not a.two_track:
        raise DataError("--turns applies to a two-track drive log only (add --two-track)")
    if not a.two_track:
        return
    if a.kind != "drive":
        raise DataError("--two-track applies to drive logs only (--kind drive)")
    if a.model != "full":
        raise DataError("--two-track simulates the full steering model (A c + W tan phi per track); --model full")
    given = [opt for opt, attr in _NOT_TWO_TRACK if getattr(a, attr, None)]
    if given:
        raise DataError(f"{', '.join(given)} does not apply to --two-track (the steering model has no effects yet)")


def simulate_two_track_command(a: argparse.Namespace, vehicle, soil) -> int:
    """Write a two-track log with turns (:func:`~soiltrack.soilmodel.turning.simulate_turning_log`)."""
    from .soilmodel.turning import simulate_turning_log

    if vehicle.tread is None:
        raise DataError(
            "--two-track needs the vehicle's tread_m (distance between the track centre lines) in its JSON",
            file=a.vehicle,
            column="tread_m",
        )
    if a.output != "-":
        output_path(a.output, "-o/--output")
    kw: dict[str, Any] = {"duration_s": 60.0 if a.duration is None else a.duration}
    if a.rate is not None:
        kw["sample_rate_hz"] = a.rate
    log = simulate_turning_log(vehicle, soil, turns=a.turns or (), seed=a.seed, noise=a.noise, **kw)
    if a.output == "-":
        log.write_csv(sys.stdout)
    else:
        try:
            log.write_csv(a.output)
        except OSError as e:
            raise DataError(f"cannot write the CSV: {e.strerror or e}", file=a.output) from None
        print(f"wrote {log.n_samples} rows (two-track drive log) to {a.output}", file=sys.stderr)
    if a.plot:
        print(f"wrote the figure to {plot_two_track(log, a.plot)}", file=sys.stderr)
    return EXIT_OK


def plot_two_track(log, path: str) -> str:
    """Sprocket speeds, torques (left, right) and yaw rate of a two-track log against time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for k, (lab, left, right, unit) in enumerate(
        (
            ("sprocket speed", log.speed_left, log.speed_right, "rad/s"),
            ("sprocket torque", log.torque_left / 1e3, log.torque_right / 1e3, "kN m"),
        )
    ):
        ax[k].plot(log.time, left, lw=0.7, label="left")
        ax[k].plot(log.time, right, lw=0.7, label="right")
        ax[k].set_ylabel(f"{lab} ({unit})")
        ax[k].legend(loc="best")
    if log.yaw_rate is not None:
        ax[2].plot(log.time, log.yaw_rate, lw=0.7, color="k")
    ax[2].set_ylabel("yaw rate (rad/s, + left)")
    ax[2].set_xlabel("time (s)")
    ax[0].set_title(log.source)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def add_simulate_options(s) -> None:
    """``--two-track`` and ``--turns`` on the ``simulate`` parser."""
    s.add_argument(
        "--two-track",
        action="store_true",
        help="drive log with each track's torque and sprocket speed and the yaw rate, from the skid-steer "
        "model (needs tread_m in the vehicle JSON)",
    )
    s.add_argument(
        "--turns",
        metavar="T0:T1:RADIUS_M[,...]",
        help="with --two-track: turns from T0 to T1 s of the given radius (m, signed: positive to the left, "
        "larger than half the tread), e.g. 10:20:15,30:38:-8",
    )


# --- fit --motion -------------------------------------------------------------------------------
def fit_motion_command(a: argparse.Namespace, data, vehicle, options: dict) -> int | None:
    """``fit`` of a two-track log with yaw rate by the steering model; None: not this path.

    Taken when the log has the two-track columns and ``yaw_rate_rad_s`` and the vehicle has
    ``tread_m`` (``--motion`` default ``all``), or when ``--motion`` is given (then anything
    missing is refused, exit 2). ``options``: the fit's options and their defaults (those given
    other than ``--bounds`` are refused: the steering fit does not take them).
    """
    from .soilmodel import DriveLog
    from .soilmodel.logread import data_columns
    from .soilmodel.tracks import YAW_COLUMN

    given = a.motion is not None
    two_track = isinstance(data, DriveLog) and data.turning is not None
    has_yaw = isinstance(data, DriveLog) and YAW_COLUMN in data_columns(a.data, topics=getattr(a, "topics", None))
    if isinstance(data, DriveLog) and has_yaw and not two_track:
        raise DataError(
            "a yaw rate without the two-track columns (sprocket_torque_left_Nm, sprocket_torque_right_Nm, "
            "sprocket_speed_left_rad_s, sprocket_speed_right_rad_s): turns need each track's channels",
            file=a.data,
            column=YAW_COLUMN,
        )
    if not given and not (two_track and has_yaw and vehicle.tread is not None):
        return None
    if not two_track:
        raise DataError("--motion applies to two-track drive logs (each track's torque and speed)", file=a.data)
    if not has_yaw:
        raise DataError("--motion needs the yaw rate of a two-track log", file=a.data, column=YAW_COLUMN)
    if vehicle.tread is None:
        raise DataError(
            "--motion (the steering model) needs the vehicle's tread_m (distance between the track centre lines)",
            file=a.vehicle,
            column="tread_m",
        )
    taken = {"vehicle", "bounds"}  # the steering fit takes --bounds (K's, and F_max's from c's and phi's)
    extra = [f"--{k.replace('_', '-')}" for k, v in options.items() if k not in taken and getattr(a, k) != v]
    extra += ["--plot"] if a.plot else []
    if extra:
        raise DataError(
            f"{', '.join(extra)} do{'es' if len(extra) == 1 else ''} not apply to the steering model's fit of a "
            "two-track log with yaw rate (leave it out, or fit the straight samples with the straight-line model: "
            "drop the yaw_rate_rad_s column)",
            file=a.data,
        )
    motion = a.motion or "all"
    return _fit_and_print(a, vehicle, motion)


def _fit_and_print(a: argparse.Namespace, vehicle, motion: str) -> int:
    from .identify.turning import fit_by_motion
    from .soilmodel.logread import read_two_track_data

    log = read_two_track_data(a.data, topics=getattr(a, "topics", None))  # a CSV or a ROS bag
    by_motion, fits = fit_by_motion(log, vehicle, bounds=a.bounds_obj)
    main = fits[motion]
    out = {"model": "steering", "motion": motion, **main.to_dict()}
    out["running_gear"] = {
        "kind": "track",
        "name": vehicle.name,
        "weight_N": vehicle.weight,
        "contact_area_m2": vehicle.contact_area,
        "track_length_m": vehicle.track_length,
        "tread_m": vehicle.tread,
    }
    out["by_motion"] = by_motion
    if a.json:
        print(json.dumps(out, indent=2))
    else:
        print(_report(out, fits))
    return EXIT_OK if main.outcome == "usable" else EXIT_SOLVER


def _fmt_ci(x, ci, scale=1.0, unit=""):
    if x is None:
        return "-"
    return f"{x * scale:.4g} {unit} [{ci[0] * scale:.4g}, {ci[1] * scale:.4g}]"


def _report(out: dict, fits: dict) -> str:
    lines = [
        f"soil from the steering model (skid-steer, Wong-Chiang), main result: {out['motion']} samples",
        f"outcome: {out['outcome']}" + (f" - {out['outcome_reason']}" if out["outcome_reason"] else ""),
        "",
        f"{'samples':<10}{'rows':>7}  {'outcome':<11}{'F_max (kN) [95 %]':<32}{'K (m) [95 %]':<30}",
    ]
    for m in ("straight", "turning", "all"):
        f = fits[m]
        if f.outcome != "usable":
            what = (
                f"not determined; initial slope F_max l/(2K) {_fmt_ci(f.initial_slope, f.initial_slope_ci95, 1e-3)} kN"
                if f.initial_slope is not None
                else (f.outcome_reason or "")
            )
            lines.append(f"{m:<10}{f.rows:>7}  {f.outcome:<11}{what}")
            continue
        lines.append(
            f"{m:<10}{f.rows:>7}  {f.outcome:<11}{_fmt_ci(f.max_thrust, f.max_thrust_ci95, 1e-3):<32}"
            f"{_fmt_ci(f.shear_modulus, f.shear_modulus_ci95):<30}"
        )
    ag = out["by_motion"]["agreement_se"]
    if ag.get("max_thrust_N") is not None:
        lines.append(
            f"turning - straight: F_max {ag['max_thrust_N']:+.2f} SE, K {ag['shear_modulus_m']:+.2f} SE "
            "(|x| < 2: they agree)"
        )
    else:
        lines.append("turning and straight not compared: one of them is not usable (see its outcome)")
    main = fits[out["motion"]]
    if main.separable:
        lines.append(
            f"c {_fmt_ci(main.cohesion, main.cohesion_ci95, 1e-3, 'kPa')}, "
            f"phi {_fmt_ci(main.friction_angle, main.friction_angle_ci95, 180 / 3.141592653589793, 'deg')} "
            "(separated by the turns' load transfer)"
        )
    else:
        se = main.friction_share_se
        lines.append(
            "c and phi not separable: the turns' lateral load transfer leaves the friction share "
            f"W tan(phi) / F_max undetermined (SE {se:.2g}, needs < 0.15)"
            if se is not None
            else "c and phi not separable"
        )
    return "\n".join(lines)


def add_fit_options(f) -> None:
    """``--motion`` on the ``fit`` parser."""
    f.add_argument(
        "--motion",
        choices=("all", "straight", "turning"),
        default=None,
        help="two-track log with yaw_rate_rad_s and a vehicle with tread_m: fit the steering model to all, "
        "the straight or the turning samples (default: all); the JSON adds by_motion with the three side by side",
    )


# --- margin --turn-radius -----------------------------------------------------------------------
def turn_margin_command(a: argparse.Namespace, terrain, vehicle, m) -> int:
    """``margin ... --turn-radius R --speed S``: the straight-line margin's JSON plus the turn's keys."""
    from .cliutil import floats_arg
    from .planning.turning import turn_margin
    from .planning.uncertainty import SoilUncertainty
    from .soilmodel.traction import resolve_soil

    radius = floats_arg(a.turn_radius, "--turn-radius")[0]
    if a.speed is None:
        raise DataError("--turn-radius needs --speed S (the forward speed of the turn, m/s)")
    if vehicle.tread is None:
        raise DataError(
            "--turn-radius needs the vehicle's tread_m (distance between the track centre lines)",
            file=a.vehicle,
            column="tread_m",
        )
    for opt, val in (("--grade-deg", a.grade_deg), ("--accel", a.accel), ("--drawbar-N", a.drawbar_N)):
        if val is not None and floats_arg(val, opt)[0] != 0.0:
            raise DataError(
                f"{opt} {val} with --turn-radius: the steering model's steady turn is flat, unaccelerated and "
                "without drawbar pull (a turn on a grade or under a pull is outside the model); give it without "
                f"{opt}, or check the straight-line margin alone"
            )
    speed = floats_arg(a.speed, "--speed")[0]
    uncertain = isinstance(terrain, SoilUncertainty)  # --fit: the fit's mean soil, and p_turn_feasible by sampling
    soil = terrain.mean_soil(vehicle.weight) if uncertain else resolve_soil(terrain, vehicle)[0]
    max_slip = floats_arg(a.max_slip, "--max-slip")[0] if a.max_slip is not None else 0.2
    t = turn_margin(
        vehicle, soil, radius_m=radius, speed_m_s=speed, max_slip=max_slip, uncertainty=terrain if uncertain else None
    )
    if a.json:
        print(json.dumps({**m.to_dict(), **t.to_dict()}, indent=2, allow_nan=False))
    else:
        print(m.report())
        print(t.report())
    if a.plot:
        from .planning.plots import plot_margin

        plot_margin(terrain, vehicle, m, a.plot)
    return EXIT_OK if (m.traversable and t.turn_feasible) else EXIT_SOLVER


def add_margin_options(p) -> None:
    """``--turn-radius`` on the ``margin`` parser."""
    p.add_argument(
        "--turn-radius",
        metavar="R",
        help="steady turn of radius R m (signed: positive to the left) at --speed: both sprockets' torques, the "
        "outer and inner slips, the smallest radius at that speed, turn_feasible (needs tread_m)",
    )
