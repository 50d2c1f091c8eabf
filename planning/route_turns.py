"""Turns on routes: left and right sprocket torques through patches with ``radius_m`` (the steering model).

A ROUTE.json patch may carry ``radius_m`` (signed, positive to the left; a turn of constant radius
over the patch's length). The speed profile is planned as before (:mod:`.profile`, the straight-line
optimal control problem); :func:`plan_turns` then solves, at every mesh point of a turning patch,
the hull motion the plan prescribes - forward speed ``u``, its rate ``du/dt`` (central differences
of the plan's speeds over its times), yaw rate ``u / R`` and its rate ``(du/dt) / R`` - with the
steering model (:func:`~.turning.motion_points`: both sprockets' speeds and torques, the lateral
speed) and checks it against the limits of ``margin --turn-radius`` (:func:`~.turning.classify_turn`:
soil - steady motion, inner sprocket forwards, sideslip, outer slip at most the plan's slip
limit -, torque per sprocket at most half the plan's ``max_torque_Nm``, power). A turn that breaks
a limit makes the plan infeasible, naming the patch, the limit and the mesh point.

Straight patches and routes without turns are unchanged (the same numbers). In a turn the plan's
``sprocket_torque_Nm``, ``thrust_N``, ``margin_N`` and ``energy_J`` remain those of the
straight-line problem (the optimiser does not see the turning resistance); the turn's own
torques are the ``torque_left_Nm``/``torque_right_Nm`` series, and ``turns`` summarises each
turning patch. Flat turns only (the steering model has no grade); the Bekker compaction
resistance is not in the steering model (its motion resistance is ``mu_r W`` per track).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..soilmodel import DataError, Vehicle
from ..soilmodel.steering import SteeringSettings, tread_of
from .margin import resolve_terrain, terrain_soil_vector
from .turning import classify_turn, motion_points

__all__ = ["check_turns", "plan_turns", "turn_line", "TURN_SERIES", "MIN_TURN_SPEED"]

#: Series a plan with turns adds (equal length to the others; straight points: half the plan's torque each).
TURN_SERIES = ("torque_left_Nm", "torque_right_Nm", "slip_left", "slip_right", "radius_m")
#: Below this speed (m/s) a mesh point of a turning patch is not turned (a turn at standstill is a pivot).
MIN_TURN_SPEED = 0.05


@dataclass(frozen=True)
class _Limits:
    """The plan's drivetrain limits in the attribute names :func:`~.turning.classify_turn` reads."""

    max_sprocket_torque: float
    max_power: float


def check_turns(patches, vehicle: Vehicle, source: str | None = None, *, argument: str | None = None) -> None:
    """Refuse turning patches the steering model cannot plan (DataError naming the patch and field).

    A radius not beyond half the tread, a turn on a grade, a vehicle without ``tread_m``. ``argument``
    (e.g. ``"--turn-radius"``) names the option instead of the ROUTE.json field (``profile``).
    """
    turning = [k for k, p in enumerate(patches) if getattr(p, "radius_m", None) is not None]
    if not turning:
        return
    if vehicle.tread is None:
        what = argument or f"patches[{turning[0]}].radius_m"
        raise DataError(
            f"{what}: a turn needs the vehicle's tread_m (distance between the track centre lines)", column="tread_m"
        )
    B = tread_of(vehicle)
    for k in turning:
        p = patches[k]
        field = argument or f"patches[{k}].radius_m"
        if abs(p.radius_m) <= 0.5 * B:
            raise DataError(
                f"{field} = {p.radius_m:g} m: a turn's radius must be larger than half the tread "
                f"({0.5 * B:g} m; a pivot turn is outside the steering model)",
                file=source,
                column=None if argument else field,
            )
        if p.grade_deg != 0.0:
            raise DataError(
                f"{field}: a turn on a grade ({p.grade_deg:g} deg) is outside the steering model (flat turns "
                "only): split the patch or set the grade to 0",
                file=source,
                column=None if argument else f"patches[{k}].grade_deg",
            )


def _turn_of_node(idx: np.ndarray, radii: list) -> np.ndarray:
    """Patch whose radius each mesh point turns with (its interval's; the end point of a turn: that turn's)."""
    k = idx.copy()
    for j in range(1, idx.size):
        if radii[idx[j]] is None and radii[idx[j - 1]] is not None:
            k[j] = idx[j - 1]
    return k


def plan_turns(plan, patches, vehicle: Vehicle, settings: SteeringSettings = SteeringSettings()):
    """``plan`` (a :class:`~.profile.SpeedPlan`) with its turning patches solved by the steering model.

    Unchanged when no patch turns or the plan has no solution. Otherwise adds the
    :data:`TURN_SERIES` series and ``turns`` (per turning patch), and makes the plan infeasible
    when a turn breaks a limit (``reason``: the patch, the limit, the point).
    """
    radii = [getattr(p, "radius_m", None) for p in patches]
    if all(r is None for r in radii) or not plan.success:
        return plan
    check_turns(patches, vehicle)
    s = plan.series
    t, v = np.asarray(s["time_s"]), np.asarray(s["speed_m_s"])
    k_node = _turn_of_node(np.asarray(s["patch"], dtype=int), radii)
    R = np.array([math.inf if radii[k] is None else radii[k] for k in k_node])
    du = np.gradient(v, t) if t.size > 1 else np.zeros_like(v)
    on = np.isfinite(R) & (v >= MIN_TURN_SPEED)
    half = 0.5 * np.asarray(s["sprocket_torque_Nm"])
    out = {
        "torque_left_Nm": half.copy(),
        "torque_right_Nm": half.copy(),
        "slip_left": np.asarray(s["slip"], dtype=float).copy(),
        "slip_right": np.asarray(s["slip"], dtype=float).copy(),
    }
    lim = _Limits(plan.limits["max_torque_Nm"], plan.limits["max_power_W"])
    first_bad = None
    if on.any():
        j = np.flatnonzero(on)
        soils = np.array([_soil_vector(patches[k].terrain, vehicle) for k in k_node[j]])
        u, Om, dOm = v[j], v[j] / R[j], du[j] / R[j]
        cols = motion_points(vehicle, soils, u, Om, du[j], dOm, settings)
        r, B = vehicle.sprocket_radius, tread_of(vehicle)
        solved, wl, wr, lat, Tl, Tr = cols
        out["torque_left_Nm"][j] = np.where(solved, Tl, np.nan)  # no steady motion: no torques to report
        out["torque_right_Nm"][j] = np.where(solved, Tr, np.nan)
        with np.errstate(divide="ignore", invalid="ignore"):
            out["slip_left"][j] = np.where(solved, 1 - (u - Om * B / 2) / (r * wl), np.nan)
            out["slip_right"][j] = np.where(solved, 1 - (u + Om * B / 2) / (r * wr), np.nan)
        for n, jj in enumerate(j):
            limit, why = classify_turn(vehicle, R[jj], v[jj], plan.limits["max_slip"], lim, tuple(c[n] for c in cols))
            if limit is not None:
                first_bad = (int(jj), limit, why)
                break
    if first_bad is None:
        return _with_turns(plan, out, R, k_node, on, radii, first_bad, patches)
    jb = first_bad[0]
    sv = _soil_vector(patches[k_node[jb]].terrain, vehicle)[None, :]
    zero = np.zeros(1)  # the same point without acceleration: does the steady turn hold?
    steady = motion_points(vehicle, sv, v[jb : jb + 1], v[jb : jb + 1] / R[jb], zero, zero, settings)
    ok = classify_turn(vehicle, R[jb], v[jb], plan.limits["max_slip"], lim, tuple(c[0] for c in steady))[0] is None
    return _with_turns(plan, out, R, k_node, on, radii, first_bad, patches, float(du[jb]), ok)


def _soil_vector(terrain: Any, vehicle: Vehicle) -> np.ndarray:
    """``[c, phi, K]`` the plan uses for a flat patch (an identified soil: its mean at the vehicle's weight)."""
    soil, unc, _ = resolve_terrain(terrain, vehicle)
    return terrain_soil_vector(soil, unc, vehicle.weight)


def _with_turns(plan, out, R, k_node, on, radii, first_bad, patches, du_at=0.0, steady_ok=False):
    """The plan with the turn series, the per-turn summary and, when a turn breaks a limit, infeasible."""
    series = dict(plan.series)
    for key, vals in out.items():
        series[key] = [float(x) for x in vals]
    series["radius_m"] = [float(x) if math.isfinite(x) else None for x in R]
    turns = []
    for k, rad in enumerate(radii):
        if rad is None:
            continue
        sel = (k_node == k) & on
        tl, tr = np.asarray(out["torque_left_Nm"])[sel], np.asarray(out["torque_right_Nm"])[sel]
        outer = np.asarray(out["slip_right" if rad > 0 else "slip_left"])[sel]
        bad = first_bad is not None and k_node[first_bad[0]] == k
        turns.append(
            {
                "patch": k,
                "radius_m": float(rad),
                "points": int(sel.sum()),
                "feasible": not bad,
                "limited_by": first_bad[1] if bad else None,
                "max_torque_left_Nm": _fmax(tl),
                "max_torque_right_Nm": _fmax(tr),
                "max_slip_outer": _fmax(outer),
            }
        )
    plan = replace(plan, series=series, turns=tuple(turns))
    if first_bad is None:
        return plan
    jj, limit, why = first_bad
    k = int(k_node[jj])
    msg = (
        f"patch {k} ({patches[k].label}, turn of radius {radii[k]:g} m): {why} at {series['distance_m'][jj]:.4g} m, "
        f"speed {series['speed_m_s'][jj]:.3g} m/s, acceleration {du_at:.3g} m/s^2 (the steering model on the planned "
        "speeds)"
    )
    if steady_ok:
        msg += (
            "; a steady turn at this speed holds: the straight-line plan's acceleration breaks it (the speed "
            "profile is planned without the turn): a gentler plan (--max-speed, an energy objective) may pass"
        )
    reason = {"patch": k, "limit": limit, "turn_radius_m": float(radii[k]), "distance_m": series["distance_m"][jj]}
    return replace(plan, success=False, status="infeasible", message=msg, reason=reason)


def _fmax(x: np.ndarray) -> float | None:
    x = x[np.isfinite(x)]
    return float(np.max(x)) if x.size else None


def turn_line(t: dict) -> str:
    """One report line of a turning patch (an entry of ``turns``)."""
    side = "left" if t["radius_m"] > 0 else "right"
    head = f"  turn on patch {t['patch']}: {abs(t['radius_m']):g} m to the {side}, {t['points']} mesh points: "
    if not t["feasible"]:
        return head + f"NOT feasible (limited by {t['limited_by']})"
    tl, tr, so = t["max_torque_left_Nm"], t["max_torque_right_Nm"], t["max_slip_outer"]
    if tl is None or tr is None or so is None:
        return head + "feasible (no point fast enough to turn)"
    return head + f"feasible; largest torques left {tl / 1e3:.3g} kN m, right {tr / 1e3:.3g} kN m, outer slip {so:.3g}"
