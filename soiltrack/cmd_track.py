"""``soiltrack track``: replay a drive log as a stream through the on-line estimator."""

from __future__ import annotations

import argparse
import json
from array import array
import math
import sys
import time

import numpy as np

from .cliutil import EXIT_OK, EXIT_SOLVER, output_path, vehicle_arg
from .soilmodel import DataError

#: The fields of every JSON line (docs/online.md), in this order.
STEP_FIELDS = (
    "time_s",
    "max_thrust_N",
    "max_thrust_stderr_N",
    "shear_modulus_m",
    "shear_modulus_stderr_m",
    "identifiable",
    "change_detected",
    "samples_used",
    "samples_skipped",
    "p_traversable",
    "slope_N",
    "slope_stderr_N",
    "change_time_s",
    "samples_turning",
    "slip",
    "converged",
    "status",
    "normal_load_N",
    "not_identifiable",
    "informed_at_s",
    "change_window_s",
    "held",
)
#: Largest grade accepted by --grade-deg, deg (the margin's own range).
MAX_GRADE_DEG = 68.75
#: Largest grade accepted by --log-grade-deg, deg (the ``grade`` effect's range, 1.2 rad).
MAX_LOG_GRADE_DEG = 68.75
#: Monte Carlo samples of each printed step's margin (a margin costs about 0.1 s: use --every).
MARGIN_SAMPLES = 1000


def _positive(text: str, option: str, integer: bool = False) -> float:
    try:
        val = int(text) if integer else float(text)
    except ValueError:
        raise DataError(f"{option} expects {'an integer' if integer else 'a number'} > 0, got {text!r}") from None
    if not math.isfinite(val) or val <= 0:
        raise DataError(f"{option} expects {'an integer' if integer else 'a number'} > 0, got {text!r}")
    return val


def _grade(text: str | None, option: str, limit: float) -> float | None:
    """A grade option in degrees (``None`` when not given), checked to be finite and within +-``limit``."""
    if text is None:
        return None
    try:
        val = float(text)
    except ValueError:
        raise DataError(f"{option} expects a number of degrees, got {text!r}") from None
    if not math.isfinite(val) or abs(val) > limit:
        raise DataError(f"{option} expects a finite grade within +-{limit:g} deg, got {text!r}")
    return val


def _samples(stream):
    """Rows of the stream as the estimator's update arguments: ``(method name, args)``."""
    return _chunk_samples(stream.columns, stream.two_track)


def _chunk_samples(c: dict, two_track: bool):
    """Rows of one chunk of columns (:class:`~soiltrack.soilmodel.drive_stream.DriveStreamReader`) as the
    estimator's update arguments: ``(method name, args)``."""
    n = int(c["time_s"].size)
    accel = c.get("vehicle_accel_m_s2")
    if two_track:
        yaw = c.get("yaw_rate_rad_s")
        cols = [
            c[k].tolist()
            for k in (
                "time_s",
                "sprocket_torque_left_Nm",
                "sprocket_torque_right_Nm",
                "sprocket_speed_left_rad_s",
                "sprocket_speed_right_rad_s",
                "vehicle_speed_m_s",
            )
        ]
        extra = [[None] * n if accel is None else accel.tolist(), [None] * n if yaw is None else yaw.tolist()]
        return "update_tracks", list(zip(*cols, *extra))
    cols = [c[k].tolist() for k in ("time_s", "sprocket_torque_Nm", "sprocket_speed_rad_s", "vehicle_speed_m_s")]
    return "update", list(zip(*cols, [None] * n if accel is None else accel.tolist()))


#: Output steps kept for the text report beyond which every other one is dropped (the report shows about 40;
#: the replay's memory stays bounded on a log of any length; fewer steps are kept as they are).
KEPT_STEPS = 4096
#: Estimates kept for --plot beyond which every other one is dropped (changes of terrain always kept).
KEPT_ESTIMATES = 200_000


def _thin(items: list, keep=lambda x: False) -> list:
    """Every other item (the last and those ``keep`` marks kept): a bounded record of a long replay."""
    return [x for j, x in enumerate(items) if j % 2 == 0 or j == len(items) - 1 or keep(x)]


def _p_traversable(estimate, vehicle, grade_deg: float | None):
    """Probability of traversing the grade from the estimate (``None`` without a grade or a covariance).

    Between excitations the estimate is the held one, its covariance grown by the random walk.
    """
    if grade_deg is None or estimate.covariance is None or not estimate.converged:
        return None
    from .planning import margin

    p = margin(estimate, vehicle, grade_deg=grade_deg, samples=MARGIN_SAMPLES).p_traversable
    return None if p is None else float(p)  # an estimate is uncertain: margin gives its probability


def _finite_or_none(x):
    return None if x is None or (isinstance(x, float) and not math.isfinite(x)) else x


def _step(estimate, p_trav) -> dict:
    d = estimate.as_dict()
    d["p_traversable"] = p_trav
    return {k: _finite_or_none(d[k]) for k in STEP_FIELDS}


def _cmd_track(a: argparse.Namespace) -> int:
    from .identify import OnlineEstimator, OnlineSettings
    from .identify.online import NOT_SEPARABLE
    from .soilmodel.drive_stream import DriveStreamReader

    if a.plot:
        output_path(a.plot, "--plot", figure=True)
    window = _positive(a.window, "--window")
    every = int(_positive(a.every, "--every", integer=True))
    grade = _grade(a.grade_deg, "--grade-deg", MAX_GRADE_DEG)
    log_grade = _grade(a.log_grade_deg, "--log-grade-deg", MAX_LOG_GRADE_DEG)
    vehicle = vehicle_arg(a.vehicle)
    from .columns_cli import column_notes, columns_arg

    reader = DriveStreamReader(a.log, columns=columns_arg(a))
    reader.check()  # the whole file checked first (constant memory): bad input refused before any output
    notes = column_notes(a.log, columns_arg(a))
    for line in notes:
        print(f"soiltrack track: columns: {line}", file=sys.stderr)
    est = OnlineEstimator(vehicle, OnlineSettings(window_s=window, grade_rad=math.radians(log_grade or 0.0)))
    times = array("d")
    steps: list[dict] = []
    history = []
    t_start, cpu_start = time.perf_counter(), time.process_time()
    last = None
    converged_since_change = False
    t_first = t_last = None
    k = -1
    pending = None
    for chunk in reader:
        tc = chunk["time_s"][np.isfinite(chunk["time_s"])]
        if tc.size:
            t_first = float(tc[0]) if t_first is None else t_first
            t_last = float(tc[-1])
        method, rows = _chunk_samples(chunk, reader.two_track)
        update = getattr(est, method)
        for row in rows:
            k += 1
            pending = None  # the previous update, not printed, is not the last
            t0 = time.perf_counter()
            e = update(*row)
            times.append(time.perf_counter() - t0)
            last = e
            # usable: the iteration converged at least once since the last change of terrain (its convergence
            # flag may flicker from one update to the next; the last step's own flag is in its JSON line)
            converged_since_change = bool(e.converged) if e.change_detected else (converged_since_change or e.converged)
            if a.plot:
                history.append(e)
                if len(history) > 2 * KEPT_ESTIMATES:
                    history = _thin(history, lambda x: x.change_detected)
            if k % every == every - 1 or e.change_detected:
                _emit(a, e, vehicle, grade, steps)
            else:
                pending = e
        if len(steps) > 2 * KEPT_STEPS:
            steps[:] = _thin(steps, lambda x: x["change_detected"])
    if pending is not None:  # the last update is always printed
        _emit(a, pending, vehicle, grade, steps)
    n_rows = k + 1
    wall = time.perf_counter() - t_start
    cpu = time.process_time() - cpu_start
    duration = float(t_last - t_first) if t_first is not None and t_last is not None else 0.0
    ok = last is not None and last.max_thrust_N is not None and converged_since_change
    if ok:
        reason = None
    elif last is None or last.max_thrust_N is None:
        reason = "no estimate: too few usable samples (standing, turning, skipped or slower than the noise)"
    else:
        reason = "the iteration has not converged since the start or the last change of terrain"
    times_a = np.frombuffer(times, dtype=float) if len(times) else np.zeros(0)
    summary = {
        "updates": n_rows,
        "update_time_median_s": float(np.median(times_a)) if n_rows else None,
        "update_time_p99_s": float(np.quantile(times_a, 0.99)) if n_rows else None,
        "changes": [_change_entry(c) for c in est.changes],
        "samples_turning": est.samples_turning,
        "samples_turning_not_fitted": dict(est.turning.not_fitted),  # i42: why turning samples were not fitted
        "samples_skipped": est.samples_skipped,
        "samples_seen": est.samples_seen,
        "log_duration_s": duration,
        "replay_time_s": wall,
        "real_time_factor": duration / wall if wall > 0 else None,
        "replay_cpu_time_s": cpu,
        "window_s": window,
        "log_grade_deg": log_grade or 0.0,
        "normal_load_N": est.normal_load_N,
        "not_identifiable": list(last.not_identifiable) if last is not None else list(NOT_SEPARABLE),
        "kernel_backend": est.backend,
        "converged": bool(ok),
        "reason": reason,
        "columns_read": notes,
        "final": steps[-1] if steps else None,
    }
    if a.json:
        print(json.dumps({"summary": summary}, allow_nan=False))
    else:
        print(_report(reader.source, steps, summary, every))
    if a.plot:
        from .plot_track import plot_track

        path = plot_track(history, a.plot, title=f"on-line estimate: {reader.source}")
        print(f"wrote the figure to {path}", file=sys.stderr)
    return EXIT_OK if ok else EXIT_SOLVER


def _change_entry(c: dict) -> dict:
    """A summary ``changes`` entry: ``time_s``, ``window_s`` [earliest, latest], ``detected_at_s``, ``test``
    (``"cusum"`` or ``"horizon"``: which test flagged it), the soil before."""
    return {
        k: ([float(x) for x in v] if isinstance(v, (list, tuple)) else (v if isinstance(v, str) else float(v)))
        for k, v in c.items()
    }


def _emit(a: argparse.Namespace, e, vehicle, grade, steps: list) -> None:
    """One output step: printed as a JSON line (--json; only the last is kept, for the summary), else kept."""
    step = _step(e, _p_traversable(e, vehicle, grade))
    if a.json:
        print(json.dumps(step, allow_nan=False))
        steps[:] = [step]
    else:
        steps.append(step)


def _fmt(x, scale=1.0, digits=4):
    return "-" if x is None else f"{x * scale:.{digits}g}"


def _report(source: str, steps: list[dict], summary: dict, every: int) -> str:
    L = [
        f"On-line estimate of {source}: {summary['updates']} samples, {summary['samples_skipped']} skipped "
        f"(missing or non-finite channel), {summary['samples_turning']} turning fitted by the steering model "
        f"({sum(summary['samples_turning_not_fitted'].values())} turning not fitted)",
        f"horizon {summary['window_s']:g} s; update time median "
        f"{1e6 * (summary['update_time_median_s'] or 0):.0f} us, p99 "
        f"{1e6 * (summary['update_time_p99_s'] or 0):.0f} us; "
        f"replay {summary['real_time_factor'] or 0:.0f} x "
        f"faster than real time ({summary['kernel_backend']})",
        "",
    ]
    L.append(
        f"normal load {summary['normal_load_N']:.5g} N (grade {summary['log_grade_deg']:g} deg); cohesion and "
        "friction angle are not separable at one normal load: only F_max = A c + N tan(phi) and K are estimated"
    )
    for c in summary["changes"]:
        L.append(
            f"change of terrain detected at {c['detected_at_s']:.3f} s, dated {c['time_s']:.3f} s "
            f"(between {c['window_s'][0]:.3f} and {c['window_s'][1]:.3f} s; "
            f"F_max before {c['max_thrust_before_N']:.4g} N)"
        )
    L.append("")
    ptrav = any(s["p_traversable"] is not None for s in steps)
    L.append(
        f"{'time_s':>9} {'F_max_N':>10} {'+-N':>8} {'K_mm':>7} {'+-mm':>6} {'used':>5}"
        + (f" {'p_trav':>6}" if ptrav else "")
        + "  identifiable"
    )
    shown = steps if len(steps) <= 40 else steps[:: max(1, len(steps) // 40)] + [steps[-1]]
    for s in shown:
        L.append(
            f"{s['time_s']:9.3f} {_fmt(s['max_thrust_N']):>10} {_fmt(s['max_thrust_stderr_N'], digits=2):>8} "
            f"{_fmt(s['shear_modulus_m'], 1e3, 3):>7} {_fmt(s['shear_modulus_stderr_m'], 1e3, 2):>6} "
            f"{s['samples_used']:>5}"
            + (f" {_fmt(s['p_traversable'], digits=3):>6}" if ptrav else "")
            + f"  {', '.join(s['identifiable']) or '-'}"
            + (" (held)" if s["held"] and s["identifiable"] else "")
            + ("  CHANGE" if s["change_detected"] else "")
        )
    if summary["reason"]:
        L += ["", f"not converged: {summary['reason']}"]
    return "\n".join(L)


_DESCRIPTION = """\
Replay a drive log as a stream, one sample at a time, through the on-line estimator (moving
horizon, one Newton step per sample, change-of-terrain detection). Columns as for `fit`, or a
two-track log (sprocket_torque_left_Nm, sprocket_torque_right_Nm, sprocket_speed_left_rad_s,
sprocket_speed_right_rad_s, optional yaw_rate_rad_s: summed torque, mean speed, turning
samples left out). An empty or non-finite reading skips its sample (counted), it is not
refused. With --json: one JSON object per output step, then {"summary": {...}}."""


def add_parser(sub) -> None:
    """Register the ``track`` subcommand on an argparse subparsers object."""
    f = sub.add_parser(
        "track",
        help="replay a drive log as a stream: on-line soil estimate, change of terrain",
        description=_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example: soiltrack track run.csv --vehicle light --every 25 --grade-deg 10 --json",
    )
    f.add_argument("log", help="drive-log CSV (combined or two-track columns)")
    f.add_argument("--vehicle", required=True, help="vehicle JSON file or preset name (heavy, light)")
    f.add_argument("--window", default="5", metavar="S", help="length of the moving horizon, s (default: 5)")
    f.add_argument(
        "--every",
        default="1",
        metavar="N",
        help="print every N-th update (and every update that detects a change; default: 1)",
    )
    f.add_argument(
        "--grade-deg",
        default=None,
        metavar="G",
        help="probability of traversing this grade from each estimate (planning margin; the held estimate "
        "between excitations), printed in the table and in --json, deg",
    )
    f.add_argument(
        "--log-grade-deg",
        default=None,
        metavar="G",
        help="known grade the log was driven on, deg, positive uphill: normal load W cos(G) (default: 0)",
    )
    from .columns_cli import add_columns_argument

    add_columns_argument(f)
    f.add_argument("--json", action="store_true", help="JSON lines and a final summary line")
    f.add_argument("--plot", metavar="PNG", help="write the estimates over time to this figure")
    f.set_defaults(func=_cmd_track)
