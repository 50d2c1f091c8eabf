"""``soiltrack simulate``: write a simulated drive log or slip sweep."""

from __future__ import annotations

import argparse
import math
import secrets
import sys

from .argcheck import check_seed
from .cliutil import EXIT_OK, MAX_SAMPLES, floats_arg, output_path, running_gear_arg, soil_arg
from .soilmodel import TERRAINS, DataError
from .soilmodel.rigid_wheel import RigidWheel
from .turn_cli import add_simulate_options, check_two_track_options, simulate_two_track_command

#: Bits of a seed drawn when ``--seed`` is not given (said on stderr, so that the run can be repeated).
SEED_BITS = 32
#: ``--sinkage`` of a track sweep: the exponent of Lyasko's slip factor in the simulated sinkage.
SINKAGE_LAWS = {"static": 0.0, "lyasko": 1.0}


# --- simulate ---------------------------------------------------------------------------------
def _check_options(a: argparse.Namespace) -> None:
    """Refuse options that do not apply to the chosen kind, effects without a value, absurd sizes."""
    drive_only = [o for o, v in (("--duration", a.duration), ("--rate", a.rate), ("--change", a.change)) if v]
    sweep_only = [o for o, v in (("--slips", a.slips), ("--loads", a.loads)) if v is not None]
    if a.kind == "drive" and sweep_only:
        raise DataError(
            f"{', '.join(sweep_only)} applies to slip sweeps only (--kind sweep); a drive log's slip "
            "and load follow from the simulated run"
        )
    if a.kind == "sweep" and drive_only:
        raise DataError(f"{', '.join(drive_only)} applies to drive logs only (--kind drive)")
    for spec in a.effect or []:
        if "=" not in spec:
            raise DataError(
                f"--effect {spec!r} needs a value (NAME=VALUE, e.g. grade=0.03): an effect switched on "
                "at its default parameters is the nominal model, i.e. no effect"
            )
    if a.kind == "drive":
        duration = 60.0 if a.duration is None else a.duration
        rate = 50.0 if a.rate is None else a.rate
        if duration > 0 and rate > 0 and duration * rate > MAX_SAMPLES:
            raise DataError(
                f"--duration {duration:g} s x --rate {rate:g} Hz = {duration * rate:.3g} samples; at most "
                f"{MAX_SAMPLES:,} (e.g. one hour at 500 Hz)"
            )
    check_seed(a.seed)
    if a.output != "-":
        output_path(a.output, "-o/--output")
    if a.plot:
        output_path(a.plot, "--plot", figure=True)


def _cmd_simulate(a: argparse.Namespace) -> int:
    from .soilmodel import write_csv
    from .soilmodel.effects import parse_effects
    from .soilmodel.simulation import simulate

    gear = running_gear_arg(a.vehicle)
    if a.seed is None:  # drawn here, for a vehicle's and a wheel's run alike, and said so it can be repeated
        a.seed = secrets.randbits(SEED_BITS)
        print(f"seed {a.seed} (not given: drawn; repeat this run with --seed {a.seed})", file=sys.stderr)
    if isinstance(gear, RigidWheel):
        from .wheel_cli import simulate_wheel_command

        if a.output != "-":
            output_path(a.output, "-o/--output")
        return simulate_wheel_command(a, gear, soil_arg(a.terrain, a.soil))
    if a.sinkage and a.kind != "sweep":
        raise DataError("--sinkage applies to slip sweeps only (--kind sweep)")
    if a.bekker and not a.sinkage:
        raise DataError("--bekker applies to a rigid wheel's sweep or to a track sweep with --sinkage only")
    _check_options(a)
    check_two_track_options(a)
    vehicle, soil = gear, soil_arg(a.terrain, a.soil)
    if a.two_track:
        return simulate_two_track_command(a, vehicle, soil)
    if a.bekker:
        soil = _with_bekker(soil, a.bekker)
    effects = parse_effects(a.effect or [])
    kwargs = dict(kind=a.kind, effects=effects, seed=a.seed, noise=a.noise, model=a.model)
    if a.kind == "drive":
        if a.duration is not None:
            kwargs["duration_s"] = a.duration
        if a.rate is not None:
            kwargs["sample_rate_hz"] = a.rate
        if a.change:
            kwargs["soil_changes"] = _changes(a.change, 60.0 if a.duration is None else a.duration)
    else:
        if a.slips:
            kwargs["slips"] = floats_arg(a.slips, "--slips")
        if a.loads:
            kwargs["normal_loads"] = floats_arg(a.loads, "--loads")
        if a.sinkage:
            kwargs["sinkage_slip_exponent"] = SINKAGE_LAWS[a.sinkage]
    data = simulate(vehicle, soil, **kwargs)
    what = "drive log" if a.kind == "drive" else "slip sweep"
    if a.output == "-":
        write_csv(data, sys.stdout)
    else:
        try:
            write_csv(data, a.output)
        except OSError as e:
            raise DataError(f"cannot write the CSV: {e.strerror or e}", file=a.output) from None
        print(f"wrote {data.n_samples} rows ({what}) to {a.output}", file=sys.stderr)
    if a.plot:
        from .plots import plot_data

        path = plot_data(data, a.plot, title=f"{vehicle.name or a.vehicle} on {soil.name or 'soil'}")
        print(f"wrote the figure to {path}", file=sys.stderr)
    return EXIT_OK


def _changes(specs: list[str], duration: float) -> list:
    """``--change T:TERRAIN`` or ``T:C_KPA,PHI_DEG,K_M`` (repeatable) -> ``[(t, Soil), ...]`` in time order."""
    out = []
    for spec in specs:
        t_text, sep, what = spec.partition(":")
        try:
            t = float(t_text)
        except ValueError:
            t = math.nan
        if not sep or not what or not math.isfinite(t):
            raise DataError(
                f"--change expects T:TERRAIN or T:C_KPA,PHI_DEG,K_M (T in s), got {spec!r}; "
                f"terrains: {', '.join(TERRAINS)}"
            )
        if not 0 < t < duration:
            raise DataError(f"--change {spec!r}: the time {t:g} s is outside the log (0 to {duration:g} s)")
        try:
            soil = soil_arg(None, what) if "," in what else soil_arg(what, None)
        except DataError as e:
            raise DataError(f"--change {spec!r}: {e}") from None
        out.append((t, soil))
    out.sort(key=lambda x: x[0])
    for (t0, _), (t1, _) in zip(out, out[1:]):
        if t1 == t0:
            raise DataError(f"--change: two changes at {t0:g} s")
    return out


def _with_bekker(soil, spec: str):
    """The soil with ``--bekker KC,KPHI,N`` (kN/m^(n+1), kN/m^(n+2), -)."""
    from .soilmodel import Soil

    vals = floats_arg(spec, "--bekker")
    if len(vals) != 3:
        raise DataError(f"--bekker expects KC,KPHI,N (kN/m^(n+1), kN/m^(n+2), -), got {spec!r}")
    kc, kphi, n = vals
    return Soil(
        cohesion=soil.cohesion,
        friction_angle=soil.friction_angle,
        shear_modulus=soil.shear_modulus,
        name=soil.name,
        n=n,
        k_c=kc * 1e3,
        k_phi=kphi * 1e3,
    )


def add_parser(sub) -> None:
    """Register the ``simulate`` subcommand on an argparse subparsers object."""
    s = sub.add_parser(
        "simulate",
        help="write a simulated drive log or tractive force-slip sweep (CSV)",
        description="Simulate a straight-line drive log (CVODES, speed-reference controller, sensor noise) or a "
        "tractive force-slip sweep, and write it as CSV in the columns 'soiltrack fit' reads.",
        epilog="example: soiltrack simulate --kind sweep --vehicle light --soil 1.7,29,0.01 --loads 300,450 "
        "--seed 1 -o sweep.csv",
    )
    s.add_argument(
        "--vehicle",
        default="heavy",
        help="preset name (heavy, light), vehicle JSON file, or a rigid wheel's JSON "
        '({"running_gear": "rigid_wheel", ...}: a rig sweep with --kind sweep --loads) '
        "(default: heavy)",
    )
    g = s.add_mutually_exclusive_group()
    g.add_argument("--terrain", help=f"terrain preset: {', '.join(TERRAINS)} (default: lete_sand)")
    g.add_argument(
        "--soil",
        metavar="C_KPA,PHI_DEG,K_M",
        help="soil as cohesion kPa, friction angle deg, shear modulus m, e.g. 1.3,31.1,0.012",
    )
    s.add_argument(
        "--kind", choices=("drive", "sweep"), default="drive", help="drive log or slip sweep (default: drive)"
    )
    s.add_argument(
        "--effect",
        action="append",
        metavar="NAME=VALUE",
        help="switch on an unmodelled effect with a value, e.g. grade=0.03 (rad), "
        "drivetrain_friction.tau_v=2 (repeatable; default: none)",
    )
    s.add_argument(
        "--model",
        choices=("full", "cohesion-free"),
        default="full",
        help="thrust model: full (Eq. 2, A c + W tan phi) or cohesion-free (Eq. 8, W tan phi) (default: full)",
    )
    s.add_argument(
        "--noise",
        choices=("default", "none"),
        default="default",
        help="sensor noise: realistic default levels, or none (default: default)",
    )
    s.add_argument(
        "--seed",
        type=int,
        default=None,
        help="random seed for the noise (default: drawn afresh and said on stderr, so that the run can be repeated)",
    )
    s.add_argument("--duration", type=float, default=None, help="drive log length in s (default: 60)")
    s.add_argument("--rate", type=float, default=None, help="drive log sample rate in Hz (default: 50)")
    s.add_argument(
        "--change",
        action="append",
        metavar="T:TERRAIN",
        help="drive log: a change of terrain at T s, to a preset (T:snow) or a soil (T:C_KPA,PHI_DEG,K_M); "
        "repeatable (default: one soil all along)",
    )
    s.add_argument("--slips", help="sweep: comma-separated slips in [0, 1) (default: 22 slips from 0.01 to 0.7)")
    s.add_argument(
        "--loads",
        help="sweep: comma-separated normal loads in N; several make c and phi separable "
        "(default: the vehicle's weight)",
    )
    s.add_argument(
        "--bekker",
        metavar="KC,KPHI,N",
        help="rigid wheel, or a track sweep with --sinkage: the soil's Bekker k_c (kN/m^(n+1)), k_phi "
        "(kN/m^(n+2)) and n, with --soil (a --terrain preset carries its own)",
    )
    s.add_argument(
        "--sinkage",
        choices=tuple(SINKAGE_LAWS),
        default=None,
        help="track sweep: also write sinkage_m, the soil's static Bekker sinkage at each row's load "
        "(static) or times Lyasko's slip factor (1 + i) / (1 - 0.5 i) (lyasko); 3 %% reading noise",
    )
    s.add_argument("-o", "--output", default="-", help="output CSV path, '-' for stdout (default: -)")
    s.add_argument("--plot", metavar="PNG", help="also save a figure of the data (.png, .pdf, .svg)")
    add_simulate_options(s)
    s.set_defaults(func=_cmd_simulate)
