"""The closed loop: a controller against a plant, its series and metrics, and the baselines of the same run.

A plant is any object with ``step(torque) -> measurement`` (a dict with the drive-log column
names). When it also has ``truth`` (a dict with ``distance_m``, ``slip``, ``patch``,
``max_thrust_N``, ``shear_modulus_m``; :class:`~.plant.TrackPlant` has it) the metrics use the
true slip and distance, else the measured ones.

Metrics (:func:`metrics`): time to the destination (``None`` when not reached in the time
allowed), sprocket energy (positive work, ``sum max(M w, 0) dt``), speed-tracking RMSE against
the requested speed, peak slip and time above the slip limit (samples with a track speed above
0.05 m/s), stuck events (vehicle speed below 0.05 m/s at a slip above 0.5 for more than 1 s, each
episode once), and the adapt time: after each change of the true soil, the time until the
controller's believed F_max is within 10 % of the true one and stays so for 1 s (the largest over
the changes; ``None`` without a belief or a change, or when it never adapts).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...soilmodel import DataError

__all__ = ["ClosedLoop", "run_closed_loop", "metrics", "STUCK_SPEED", "STUCK_SLIP", "STUCK_TIME_S"]

STUCK_SPEED, STUCK_SLIP, STUCK_TIME_S = 0.05, 0.5, 1.0
ADAPT_REL, ADAPT_HOLD_S = 0.10, 1.0
METRIC_KEYS = (
    "time_s",
    "energy_J",
    "tracking_rmse_m_s",
    "peak_slip",
    "time_above_slip_limit_s",
    "stuck_events",
    "adapt_time_s",
)


@dataclass(frozen=True)
class ClosedLoop:
    """One closed-loop run: ``series`` (equal-length lists), ``metrics``, ``events``, ``arrived``, per-step times."""

    controller: str
    series: dict[str, list]
    metrics: dict[str, Any]
    events: list[dict]
    arrived: bool
    step_time_median_s: float
    step_time_p99_s: float
    solve_time_median_s: float | None = None
    solve_time_p99_s: float | None = None
    estimator_time_median_s: float | None = None
    own_step_time_median_s: float | None = None
    own_step_time_p99_s: float | None = None
    step_cpu_median_s: float | None = None
    step_cpu_p99_s: float | None = None
    solve_cpu_median_s: float | None = None
    solve_cpu_p99_s: float | None = None
    notes: tuple[str, ...] = field(default=())
    estimator_time_p99_s: float | None = None
    mpc_solves: int = 0  # receding-horizon solves, of them answered by IPOPT (SQP failed) and by the shifted plan
    mpc_fallbacks: int = 0
    mpc_failures: int = 0


def run_closed_loop(
    controller: Any,
    plant: Any,
    *,
    distance_m: float,
    target_speed_m_s: float,
    max_slip: float,
    max_time_s: float,
    record_every: int = 1,
) -> ClosedLoop:
    """Drive ``plant`` with ``controller`` until ``distance_m`` is covered or ``max_time_s`` has passed.

    The first measurement is the plant's answer to a zero torque. ``controller`` needs
    ``command(measurement)``; ``plant`` needs ``step(torque)`` (module docstring).
    """
    if not callable(getattr(plant, "step", None)):
        raise DataError(f"the plant must have a step(torque) method, got {type(plant).__name__}")
    if not callable(getattr(controller, "command", None)):
        raise DataError(f"the controller must have a command(measurement) method, got {type(controller).__name__}")
    S: dict[str, list] = {
        k: []
        for k in (
            "time_s",
            "distance_m",
            "speed_m_s",
            "target_speed_m_s",
            "slip",
            "sprocket_torque_Nm",
            "sprocket_speed_rad_s",
            "patch",
            "belief_max_thrust_N",
            "belief_shear_modulus_m",
            "true_max_thrust_N",
            "true_shear_modulus_m",
        )
    }
    meas = plant.step(0.0)
    odo, t_prev, n, arrived = 0.0, None, 0, False
    while True:
        M = controller.command(meas)
        Msum = float(sum(M)) if isinstance(M, (tuple, list)) else float(M)
        if not math.isfinite(Msum):
            raise DataError(f"the controller returned a non-finite torque {M!r}")
        meas = plant.step(M)
        t = float(meas["time_s"])
        truth = getattr(plant, "truth", None)
        v = float(meas["vehicle_speed_m_s"])
        odo += max(v, 0.0) * (0.0 if t_prev is None else t - t_prev)
        t_prev = t
        d = float(truth["distance_m"]) if truth else odo
        if n % record_every == 0:
            _record(S, controller, truth, meas, t, d, Msum)
        n += 1
        if d >= distance_m:
            arrived = True
            break
        if t >= max_time_s:
            break
    if (n - 1) % record_every:
        _record(S, controller, truth, meas, t, d, Msum)
    m = metrics(S, target_speed_m_s=target_speed_m_s, max_slip=max_slip, arrived=arrived)
    st = np.asarray(getattr(controller, "step_times_s", []) or [math.nan])
    sv = getattr(controller, "solve_times_s", None)
    sc = getattr(controller, "solve_cpu_s", None)
    events = list(getattr(controller, "events", []))
    belief = getattr(controller, "belief", None)
    events += list(getattr(belief, "events", []) or [])
    events.sort(key=lambda e: e.get("time_s") or 0.0)
    ut = np.asarray(getattr(belief, "update_times_s", []) or [], dtype=float)
    cpu = np.asarray(getattr(controller, "step_cpu_s", []) or [], dtype=float)
    own = st - ut if ut.size == st.size else st  # the controller's own time, the estimator's update taken out
    return ClosedLoop(
        getattr(controller, "kind", type(controller).__name__),
        S,
        m,
        events,
        arrived,
        float(np.median(st)),
        float(np.percentile(st, 99)),
        float(np.median(sv)) if sv else None,
        float(np.percentile(sv, 99)) if sv else None,
        float(np.median(ut)) if ut.size else None,
        float(np.median(own)),
        float(np.percentile(own, 99)),
        float(np.median(cpu)) if cpu.size else None,
        float(np.percentile(cpu, 99)) if cpu.size else None,
        float(np.median(sc)) if sc else None,
        float(np.percentile(sc, 99)) if sc else None,
        estimator_time_p99_s=float(np.percentile(ut, 99)) if ut.size else None,
        mpc_solves=len(sv or []),
        mpc_fallbacks=int(getattr(getattr(controller, "problem", None), "fallbacks", 0)),
        mpc_failures=int(getattr(getattr(controller, "problem", None), "failures", 0)),
    )


def _record(S: dict, controller: Any, truth: dict | None, meas: dict, t: float, d: float, M: float) -> None:
    last = getattr(controller, "last", {}) or {}
    b = getattr(controller, "belief", None)
    patch = int(truth["patch"]) if truth else int(last.get("patch", 0))
    bel = b.belief(last.get("patch", 0), last.get("patch", 0)) if b is not None else None
    w = float(truth["sprocket_speed_rad_s"]) if truth else float(meas.get("sprocket_speed_rad_s", math.nan))
    S["time_s"].append(t)
    S["distance_m"].append(d)
    S["speed_m_s"].append(float(truth["vehicle_speed_m_s"]) if truth else float(meas["vehicle_speed_m_s"]))
    S["target_speed_m_s"].append(float(last.get("v_ref", math.nan)))
    S["slip"].append(float(truth["slip"]) if truth else float(last.get("slip_filtered", math.nan)))
    S["sprocket_torque_Nm"].append(M)
    S["sprocket_speed_rad_s"].append(w)
    S["patch"].append(patch)
    S["belief_max_thrust_N"].append(None if bel is None else bel.max_thrust_N)
    S["belief_shear_modulus_m"].append(None if bel is None else bel.shear_modulus_m)
    S["true_max_thrust_N"].append(None if not truth else float(truth["max_thrust_N"]))
    S["true_shear_modulus_m"].append(None if not truth else float(truth["shear_modulus_m"]))


def metrics(S: dict, *, target_speed_m_s: float, max_slip: float, arrived: bool) -> dict[str, Any]:
    """The metrics of a run's series (module docstring)."""
    t = np.asarray(S["time_s"], dtype=float)
    dt = np.diff(t, prepend=t[0] - (t[1] - t[0] if t.size > 1 else 0.0))
    v = np.asarray(S["speed_m_s"], dtype=float)
    i = np.asarray(S["slip"], dtype=float)
    M = np.asarray(S["sprocket_torque_Nm"], dtype=float)
    w = np.asarray(S["sprocket_speed_rad_s"], dtype=float)
    moving = np.isfinite(i) & (np.nan_to_num(w) * 1.0 > 0)
    energy = float(np.sum(np.maximum(np.nan_to_num(M * w), 0.0) * dt))
    stuck = v < STUCK_SPEED
    stuck &= np.nan_to_num(i) > STUCK_SLIP
    events, run = 0, 0.0
    for k in range(t.size):
        run = run + dt[k] if stuck[k] else 0.0
        if stuck[k] and run > STUCK_TIME_S and (run - dt[k]) <= STUCK_TIME_S:
            events += 1
    above = moving & (i > max_slip + 1e-9)
    return {
        "time_s": float(t[-1]) if arrived else None,
        "arrived": bool(arrived),
        "energy_J": energy,
        "tracking_rmse_m_s": float(np.sqrt(np.mean((v - target_speed_m_s) ** 2))),
        "peak_slip": float(np.max(i[moving])) if np.any(moving) else 0.0,
        "time_above_slip_limit_s": float(np.sum(dt[above])),
        "stuck_events": int(events),
        "adapt_time_s": _adapt(S, t),
    }


def _adapt(S: dict, t: np.ndarray) -> float | None:
    bF, tF = S["belief_max_thrust_N"], S["true_max_thrust_N"]
    if not bF or bF[0] is None or tF[0] is None:
        return None
    b, tr = np.asarray(bF, dtype=float), np.asarray(tF, dtype=float)
    changes = [k for k in range(1, tr.size) if abs(tr[k] - tr[k - 1]) > 1e-6 * abs(tr[k - 1])]
    if not changes:
        return None
    ok = np.abs(b - tr) <= ADAPT_REL * np.abs(tr)
    worst = 0.0
    for j, k in enumerate(changes):
        end = changes[j + 1] if j + 1 < len(changes) else t.size
        found = None
        for q in range(k, end):
            if not ok[q]:
                continue
            hold = (t[q:end] - t[q]) <= ADAPT_HOLD_S
            if np.all(ok[q:end][hold]) and t[end - 1] - t[q] >= min(ADAPT_HOLD_S, t[end - 1] - t[k]):
                found = t[q] - t[k]
                break
        if found is None:
            return None
        worst = max(worst, found)
    return float(worst)
