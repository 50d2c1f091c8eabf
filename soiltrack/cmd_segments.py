"""``soiltrack fit LOG.csv --segments 60s|auto`` (a soil map along a long log) and the fit's memory budget."""

from __future__ import annotations

import argparse
import csv
import io
import json
import sys

from .cliutil import EXIT_OK, EXIT_SOLVER
from .soilmodel import DataError
from .soilmodel.csvread import read_header
from .soilmodel.data import DRIVE_COLUMNS
from .soilmodel.tracks import TWO_TRACK_COLUMNS

__all__ = ["add_arguments", "check_budget", "memory_limit_arg", "segments_command"]


def add_arguments(f: argparse.ArgumentParser) -> None:
    """The ``fit`` options of this module: ``--segments``, ``--max-memory``."""
    f.add_argument(
        "--segments",
        metavar="DURATION|auto",
        default=None,
        help="drive logs: a soil map along the run - fit each segment (e.g. 60s, 5min; auto: cut where the "
        "on-line change detector dates a change of terrain, and every 60 s between), merge neighbours whose "
        "soils agree within their intervals; one row per segment (CSV, or --json: a 'segments' list)",
    )
    f.add_argument(
        "--max-memory",
        metavar="BYTES|auto",
        default="auto",
        help="drive logs: refuse (exit 2) before the work a fit whose estimated peak memory exceeds this "
        "(e.g. 2G, 500M); auto (default): half the memory the machine has available",
    )


def _is_drive_log(header: list[str]) -> bool:
    return any(c in header for c in (*DRIVE_COLUMNS, *TWO_TRACK_COLUMNS)) and "slip" not in header


def memory_limit_arg(a: argparse.Namespace) -> float | None:
    """``--max-memory`` in bytes (None: auto, the fit's default limit)."""
    from .identify.drivelog.budget import parse_memory

    return parse_memory(a.max_memory)


def check_budget(a: argparse.Namespace) -> None:
    """Refuse a drive-log fit the memory limit cannot hold (DataError, exit 2), before the file is read."""
    from .identify.drivelog.budget import check_fit_budget, count_rows, parse_memory

    from .soilmodel.logread import is_bag

    limit = parse_memory(a.max_memory)
    if is_bag(a.data):
        return  # a ROS bag: its rows are known only once read (not estimated before the work)
    if not _is_drive_log(read_header(a.data)):
        if a.segments is not None:
            raise DataError("--segments applies to drive logs only", file=a.data)
        return
    rows = count_rows(a.data)
    if a.segments is None:
        check_fit_budget(rows, source=a.data, max_memory=limit, effects=bool(a.effect))
        return
    from .identify.segments import MERGE_REFIT_ROWS

    # --segments: the log held in memory (its columns, 48 bytes a row measured as 120 with the reader's growth)
    # and the largest fit, a merged run of at most MERGE_REFIT_ROWS rows
    check_fit_budget(
        min(rows, MERGE_REFIT_ROWS),
        source=a.data,
        max_memory=limit,
        latent_slips="profiled",
        extra_bytes=120.0 * rows,
        what=f"a segment map of {rows:,} rows",
    )


def segments_command(a: argparse.Namespace, data, vehicle, bounds) -> int:
    """Fit the drive log segment by segment; print the map (CSV or JSON); exit 0 when every segment is usable."""
    from .identify.segments import SEGMENT_FIELDS, fit_segments
    from .soilmodel import DriveLog

    if not isinstance(data, DriveLog):
        raise DataError("--segments applies to drive logs only", file=a.data)
    for opt, val in (("--effect", a.effect), ("--bias-correction", a.bias_correction != "none")):
        if val:
            raise DataError(f"{opt} is not available with --segments (each segment gets the nominal fit)")
    kw = {"bounds": bounds, "model": a.model}
    if a.torque_hold is not None:
        kw["torque_hold"] = a.torque_hold
    if a.discretisation is not None:
        kw["discretisation"] = a.discretisation
    smap = fit_segments(data, vehicle, a.segments, **kw)
    if a.json:
        print(json.dumps(smap.to_dict(), allow_nan=False))
    else:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(
            [
                *SEGMENT_FIELDS[:4],
                "max_thrust_ci95_lo",
                "max_thrust_ci95_hi",
                "shear_modulus_m",
                "shear_modulus_ci95_lo",
                "shear_modulus_ci95_hi",
                *SEGMENT_FIELDS[7:],
                "rows",
                "pieces",
                "discretisation",
            ]
        )
        for s in smap.segments:
            d = s.to_dict()
            fci = d["max_thrust_ci95"] or [None, None]
            kci = d["shear_modulus_ci95"] or [None, None]
            row = [
                d["start_s"],
                d["end_s"],
                d["distance_m"],
                d["max_thrust_N"],
                *fci,
                d["shear_modulus_m"],
                *kci,
                d["cohesion_kpa"],
                d["friction_angle_deg"],
                d["outcome"],
                d["rows"],
                d["pieces"],
                d["discretisation"],
            ]
            w.writerow(["" if x is None else (f"{x:.6g}" if isinstance(x, float) else x) for x in row])
        sys.stdout.write(buf.getvalue())
        for s in smap.segments:
            if s.reason:
                print(f"segment {s.start_s:.3f}-{s.end_s:.3f} s: {s.outcome}: {s.reason}", file=sys.stderr)
    if a.plot:
        from .plot_segments import plot_segments

        print(f"wrote the figure to {plot_segments(smap, a.plot)}", file=sys.stderr)
    return EXIT_OK if all(s.reason is None for s in smap.segments) else EXIT_SOLVER
