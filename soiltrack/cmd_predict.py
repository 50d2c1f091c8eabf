"""``soiltrack predict``: pull, thrust, torque and sinkage of a wheel or track against slip, for design."""

from __future__ import annotations

import argparse
import json
import math
import sys

from .cliutil import EXIT_OK, EXIT_SOLVER, check_soil, floats_arg, output_path, running_gear_arg
from .soilmodel import TERRAINS, DataError, Soil

#: Most slips one prediction evaluates.
MAX_SLIPS = 10_001

_DESCRIPTION = """\
Forward prediction for design: the drawbar pull, thrust, torque and sinkage a running gear gives on
a soil, against slip, with 95 % bounds from the soil's uncertainty (a fit's covariance; none for a
preset or given numbers).

  rigid wheel (--vehicle WHEEL.json):  Wong-Reece; the sinkage carries --load N (required), so the
      soil needs its Bekker parameters (--soil C_KPA,PHI_DEG,K_M,KC,KPHI,N, a terrain preset, a wheel
      fit, or a bevameter plate fit beside a shear fit: --fit shear.json --fit plate.json)
  tracked vehicle (--vehicle V):       Eq. 2 at the vehicle's weight (or --load); drawbar pull =
      thrust - mu_r W - Bekker compaction; torque = r x thrust (both sprockets, steady speed)

Exit status: 0 predicted at every slip, 1 the gear cannot carry the load at some slips (printed,
with the reason), 2 bad input."""


def slip_arg(text: str) -> list[float]:
    """``A:B:STEP`` -> the slips A, A + STEP, ... up to B (inclusive within rounding), or a list ``S1,S2,...``
    (the slips of a measured sweep, in increasing order); DataError otherwise."""
    if "," in text or ":" not in text:
        return _slip_list(text)
    parts = text.split(":")
    if len(parts) != 3:
        raise DataError(f"--slip expects A:B:STEP (e.g. 0:0.9:0.05), got {text!r}")
    try:
        a, b, step = (float(p) for p in parts)
    except ValueError:
        raise DataError(f"--slip expects three numbers A:B:STEP, got {text!r}") from None
    if not all(math.isfinite(v) for v in (a, b, step)):
        raise DataError(f"--slip expects finite numbers, got {text!r}")
    if step <= 0:
        raise DataError(f"--slip: STEP must be > 0, got {step:g}")
    if b < a:
        raise DataError(f"--slip {text}: the range is reversed (B = {b:g} < A = {a:g}); give A:B:STEP with A <= B")
    if a < -1 or b >= 1:
        raise DataError(f"--slip {text}: slips must lie in [-1, 1) (a wheel: -1 locked, < 0 skid; a track: [0, 1))")
    n = int(math.floor((b - a) / step + 1e-9)) + 1
    if n > MAX_SLIPS:
        raise DataError(f"--slip {text}: {n} slips, more than {MAX_SLIPS}; use a larger STEP")
    return [round(a + k * step, 12) for k in range(n)]


def _slip_list(text: str) -> list[float]:
    """``S1,S2,...`` -> those slips (finite, increasing, in [-1, 1), at most MAX_SLIPS)."""
    try:
        vals = [float(p) for p in text.split(",")]
    except ValueError:
        raise DataError(f"--slip expects A:B:STEP or a list S1,S2,... of numbers, got {text!r}") from None
    if not all(math.isfinite(v) for v in vals):
        raise DataError(f"--slip expects finite numbers, got {text!r}")
    if any(b <= a for a, b in zip(vals, vals[1:])):
        raise DataError(f"--slip {text}: a list of slips must increase")
    if vals[0] < -1 or vals[-1] >= 1:
        raise DataError(f"--slip {text}: slips must lie in [-1, 1) (a wheel: -1 locked, < 0 skid; a track: [0, 1))")
    if len(vals) > MAX_SLIPS:
        raise DataError(f"--slip {text}: {len(vals)} slips, more than {MAX_SLIPS}")
    return vals


def _soil(text: str) -> Soil:
    vals = floats_arg(text, "--soil")
    if len(vals) not in (3, 6):
        raise DataError(f"--soil expects C_KPA,PHI_DEG,K_M or C_KPA,PHI_DEG,K_M,KC,KPHI,N, got {text!r}")
    for w in check_soil(vals[0], vals[1], vals[2], "--soil"):
        print(f"soiltrack: warning: {w}", file=sys.stderr)
    kw = {}
    if len(vals) == 6:
        kc, kphi, n = vals[3:]
        if not (kphi > 0 and n > 0):
            raise DataError(f"--soil: Bekker k_phi and n must be > 0, got k_phi = {kphi:g}, n = {n:g}")
        kw = {"k_c": kc * 1e3, "k_phi": kphi * 1e3, "n": n}
    return Soil.from_kpa_deg(*vals[:3], name=f"--soil {text}", **kw)


def _estimate(a: argparse.Namespace, gear, load):
    from .planning.prediction import fits_estimate, soil_estimate

    given = [x for x in (a.terrain, a.soil, a.fit) if x]
    if len(given) != 1:
        raise DataError("give exactly one of --terrain NAME, --soil C_KPA,PHI_DEG,K_M[,KC,KPHI,N] or --fit FIT.json")
    if a.fit:
        return fits_estimate(list(a.fit), gear, load)
    if a.terrain is not None:
        if a.terrain not in TERRAINS:
            raise DataError(f"argument --terrain: unknown terrain {a.terrain!r}; presets: {sorted(TERRAINS)}")
        return soil_estimate(TERRAINS[a.terrain])
    return soil_estimate(_soil(a.soil))


def _cmd_predict(a: argparse.Namespace) -> int:
    from .planning.prediction import predict

    if a.plot:
        output_path(a.plot, "--plot", figure=True)
    gear = running_gear_arg(a.vehicle)
    slips = slip_arg(a.slip)
    load = None if a.load is None else floats_arg(a.load, "--load")[0]
    if load is not None and not load > 0:
        raise DataError(f"--load must be a normal load > 0 N, got {load:g}")
    est = _estimate(a, gear, load)
    pred = predict(gear, est, slips, load)
    print(json.dumps(pred.to_dict(), indent=2, allow_nan=False) if a.json else pred.report())
    if a.plot:
        from .plot_predict import plot_prediction

        print(f"wrote the figure to {plot_prediction(pred, a.plot)}", file=sys.stderr)
    carried = all(math.isfinite(v) for v in pred.values["drawbar_pull"])
    return EXIT_OK if carried else EXIT_SOLVER


def add_parser(sub) -> None:
    """Register the ``predict`` subcommand on an argparse subparsers object."""
    p = sub.add_parser(
        "predict",
        help="forward prediction: drawbar pull, thrust, torque and sinkage against slip (wheel or track)",
        description=_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example:\n  soiltrack predict --vehicle examples/data/cmu-3dterra/smooth_wheel.json "
        "--terrain lete_sand --load 20 --slip 0:0.9:0.1\n"
        "  soiltrack predict --vehicle light --fit FIT.json --slip 0:0.5:0.05 --json",
    )
    p.add_argument("--vehicle", required=True, help="vehicle JSON, preset name (heavy, light) or rigid-wheel JSON")
    p.add_argument("--terrain", help=f"terrain preset ({', '.join(sorted(TERRAINS))})")
    p.add_argument(
        "--soil",
        metavar="C_KPA,PHI_DEG,K_M[,KC,KPHI,N]",
        help="soil parameters; a wheel needs Bekker k_c (kN/m^(n+1)), k_phi (kN/m^(n+2)) and n too",
    )
    p.add_argument(
        "--fit",
        metavar="FIT.json",
        action="append",
        help="what `soiltrack fit --json` printed (track, wheel, bevameter shear or plate test); repeatable: "
        "a shear test and a plate test together",
    )
    p.add_argument(
        "--slip",
        required=True,
        metavar="A:B:STEP",
        help="slips from A to B (inclusive) by STEP, or a list S1,S2,... (e.g. a measured sweep's): a wheel in "
        "[-1, 1) (skid down to locked: --slip=-1:0.9:0.1), "
        "a track in [0, 1)",
    )
    p.add_argument("--load", metavar="N", help="normal load, N (required for a wheel; a track: default its weight)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.add_argument("--plot", metavar="PNG", help="save the four outputs against slip with their bounds")
    p.set_defaults(func=_cmd_predict)
