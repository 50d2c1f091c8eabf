"""The turning parts of ``soiltrack simulate`` (``--two-track --turns``) and ``soiltrack fit`` (``--motion``)."""

from __future__ import annotations

import argparse
import sys

from .cliutil import EXIT_OK, output_path
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
    kw = {"duration_s": 60.0 if a.duration is None else a.duration}
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
