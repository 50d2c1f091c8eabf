"""Can it turn here: a steady turn of given radius and speed with the steering model.

:func:`turn_margin` solves the steady motion at forward speed ``u = S`` and yaw rate
``Om = S / R`` (the path radius is ``sqrt(u^2 + v^2) / Om``, within the sideslip's cosine of R;
the sideslip is reported) with :func:`~soiltrack.soilmodel.steering.motion_inverse_function`,
and checks three limits:

- ``soil``: the soil holds the turn (the balances have a solution with both sprockets turning
  forwards and both tracks loaded), the sideslip is at most :data:`MAX_SIDESLIP_DEG` (else the
  vehicle slides out of its path) and the outer track's slip at most ``max_slip``;
- ``torque``: each sprocket's torque at most half the vehicle's ``max_sprocket_torque`` (which is
  of both tracks together; an equal split is assumed);
- ``power``: the sum of the driving sprockets' powers ``T_k w_k > 0`` at most ``max_power`` (the
  inner track's braking power is not recovered: a conservative assumption).

The smallest turning radius at the speed is found by bisection on ``log |R|`` between half the
tread and :data:`R_MAX`. Drivetrain limits the vehicle does not give are the simulator's
documented defaults (:func:`~soiltrack.soilmodel.simulation.drive_limits`), said in ``notes``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..soilmodel import DataError, Soil, Vehicle
from ..soilmodel.simulation import drive_limits
from ..soilmodel.steering import (
    SteeringSettings,
    hull_forces_function,
    motion_inverse_function,
    tread_of,
    vehicle_parameters,
)
from ..soilmodel.threadsafe import call_solver

__all__ = ["TurnMargin", "turn_margin", "turn_point", "min_turn_radius", "R_MAX"]

#: Largest radius searched for the smallest feasible one, m (beyond it a turn is straight driving).
R_MAX = 1e4
#: Largest sideslip of the centre (deg) at which the vehicle still follows its path; beyond it it slides out.
MAX_SIDESLIP_DEG = 10.0
#: Bisection steps on log |R| (a relative resolution of about 2e-4 between half the tread and R_MAX).
BISECTION_STEPS = 40


@dataclass(frozen=True)
class TurnMargin:
    """The turn's torques, slips and limits (JSON keys of DESIGN section 9 in :meth:`to_dict`)."""

    radius_m: float
    speed_m_s: float
    solved: bool
    torque_left_Nm: float | None
    torque_right_Nm: float | None
    slip_outer: float | None
    slip_inner: float | None
    sideslip_deg: float | None
    power_W: float | None
    turn_feasible: bool
    turn_limited_by: str | None
    min_turn_radius_m: float | None
    torque_limit_Nm: float
    power_limit_W: float
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        """The keys ``margin --json`` adds with ``--turn-radius``."""
        return {
            "turn_radius_m": self.radius_m,
            "turn_speed_m_s": self.speed_m_s,
            "torque_left_Nm": self.torque_left_Nm,
            "torque_right_Nm": self.torque_right_Nm,
            "slip_outer": self.slip_outer,
            "slip_inner": self.slip_inner,
            "sideslip_deg": self.sideslip_deg,
            "turn_power_W": self.power_W,
            "min_turn_radius_m": self.min_turn_radius_m,
            "turn_feasible": self.turn_feasible,
            "turn_limited_by": self.turn_limited_by,
            "turn_torque_limit_per_track_Nm": self.torque_limit_Nm,
            "turn_power_limit_W": self.power_limit_W,
            "p_turn_feasible": None,
            "turn_notes": list(self.notes),
        }

    def report(self) -> str:
        """A few lines for the margin report."""
        side = "left" if self.radius_m > 0 else "right"
        head = f"turn {abs(self.radius_m):g} m to the {side} at {self.speed_m_s:g} m/s: "
        tl, tr = self.torque_left_Nm, self.torque_right_Nm
        if not self.solved or tl is None or tr is None:
            body = "the soil cannot hold it (no steady motion)"
        else:
            body = (
                f"torques left {tl / 1e3:.3g} kN m, right {tr / 1e3:.3g} kN m; "
                f"slip outer {self.slip_outer:.3g}, inner {self.slip_inner:.3g}; sideslip {self.sideslip_deg:.2g} deg"
            )
        verdict = "feasible" if self.turn_feasible else f"NOT feasible (limited by {self.turn_limited_by})"
        rmin = "none" if self.min_turn_radius_m is None else f"{self.min_turn_radius_m:.3g} m"
        return "\n".join([head + body, f"  {verdict}; smallest turning radius at this speed: {rmin}", *self.notes])


def turn_point(
    vehicle: Vehicle, soil: Soil, radius_m: float, speed_m_s: float, settings: SteeringSettings = SteeringSettings()
):
    """``(solved, w_l, w_r, v, T_l, T_r)`` of the steady turn at radius R (+ left) and forward speed S."""
    veh = vehicle_parameters(vehicle)
    u, Om = float(speed_m_s), float(speed_m_s) / float(radius_m)
    r, B = vehicle.sprocket_radius, tread_of(vehicle)
    sv = [soil.cohesion, soil.friction_angle, soil.shear_modulus]
    p = np.concatenate([[u, Om, 0.0, 0.0], sv, veh])
    z0 = [(u - Om * B / 2) / (0.97 * r), (u + Om * B / 2) / (0.97 * r), 0.0]
    z, _ = call_solver(motion_inverse_function(settings), z0, p)
    z = np.asarray(z, dtype=float).ravel()
    Fx, net, W = (
        np.asarray(a, dtype=float).ravel()
        for a in hull_forces_function(settings)([u, z[2], Om], z[:2], sv, u * Om, veh)
    )
    err = [
        (net[0] + vehicle.mass * z[2] * Om) / vehicle.weight,
        (net[1] - vehicle.mass * u * Om) / vehicle.weight,
        net[2] / (vehicle.weight * vehicle.track_length),
    ]
    solved = bool(np.all(np.isfinite(z)) and max(abs(e) for e in err) < 1e-7 and np.all(z[:2] > 0) and np.all(W > 0))
    return solved, z[0], z[1], z[2], r * Fx[0], r * Fx[1]


def _check(vehicle, soil, radius_m, speed_m_s, max_slip, limits, settings):
    """``(limit or None, reason, details)`` of one turn: the first limit it breaks (soil, torque, power)."""
    solved, wl, wr, v, Tl, Tr = turn_point(vehicle, soil, radius_m, speed_m_s, settings)
    d = (solved, wl, wr, v, Tl, Tr)
    if not solved:
        if np.all(np.isfinite([wl, wr])) and min(wl, wr) <= 0:
            return "soil", "the inner sprocket would have to stop or reverse (a pivot turn: outside the model)", d
        return "soil", "the soil cannot hold the turn (no steady motion)", d
    r, B = vehicle.sprocket_radius, tread_of(vehicle)
    Om = speed_m_s / radius_m
    sl, sr = 1 - (speed_m_s - Om * B / 2) / (r * wl), 1 - (speed_m_s + Om * B / 2) / (r * wr)
    outer = sr if radius_m > 0 else sl
    beta = math.degrees(math.atan2(abs(v), speed_m_s))
    if beta > MAX_SIDESLIP_DEG:
        return "soil", f"the vehicle slides out of the turn (sideslip {beta:.3g} deg > {MAX_SIDESLIP_DEG:g})", d
    if outer > max_slip:
        return "soil", f"the outer track's slip {outer:.3g} exceeds the allowed {max_slip:g}", d
    if max(abs(Tl), abs(Tr)) > 0.5 * limits.max_sprocket_torque:
        return "torque", f"a sprocket torque exceeds {0.5 * limits.max_sprocket_torque:.4g} N m", d
    if max(Tl * wl, 0.0) + max(Tr * wr, 0.0) > limits.max_power:
        return "power", f"the driving sprockets' power exceeds {limits.max_power:.4g} W", d
    return None, None, d


def min_turn_radius(vehicle, soil, speed_m_s, *, max_slip=0.2, settings=SteeringSettings()) -> float | None:
    """Smallest feasible |R| (m) at the speed, by bisection on log |R| (left turn; the model is symmetric)."""
    limits = drive_limits(vehicle)
    lo, hi = 0.5 * tread_of(vehicle) * (1 + 1e-6), R_MAX
    if _check(vehicle, soil, hi, speed_m_s, max_slip, limits, settings)[0] is not None:
        return None
    if _check(vehicle, soil, lo, speed_m_s, max_slip, limits, settings)[0] is None:
        return lo
    for _ in range(BISECTION_STEPS):
        mid = math.sqrt(lo * hi)
        if _check(vehicle, soil, mid, speed_m_s, max_slip, limits, settings)[0] is None:
            hi = mid
        else:
            lo = mid
    return hi


def turn_margin(
    vehicle: Vehicle,
    soil: Soil,
    *,
    radius_m: float,
    speed_m_s: float,
    max_slip: float = 0.2,
    settings: SteeringSettings = SteeringSettings(),
) -> TurnMargin:
    """Can the vehicle turn at radius ``radius_m`` (signed, + left) and forward speed ``speed_m_s`` here.

    Raises
    ------
    DataError
        No tread, a radius not beyond half the tread, a speed not > 0, a slip limit outside (0, 1).
    """
    vehicle_parameters(vehicle)  # tread checked
    B = tread_of(vehicle)
    if not (math.isfinite(radius_m) and abs(radius_m) > 0.5 * B):
        raise DataError(f"--turn-radius {radius_m:g} m must be larger than half the tread ({0.5 * B:g} m)")
    if not (math.isfinite(speed_m_s) and speed_m_s > 0):
        raise DataError(f"--speed must be > 0 m/s with --turn-radius, got {speed_m_s:g}")
    if not 0 < max_slip < 1:
        raise DataError(f"max_slip must lie in (0, 1), got {max_slip:g}")
    limits = drive_limits(vehicle)
    limit, reason, (solved, wl, wr, v, Tl, Tr) = _check(vehicle, soil, radius_m, speed_m_s, max_slip, limits, settings)
    notes = [reason] if reason else []
    if limits.torque_assumed or limits.power_assumed:
        notes.append("the vehicle gives no torque or power limit: the library's defaults are used (0.8 W r, 15 W/kg)")
    r = vehicle.sprocket_radius
    Om = speed_m_s / radius_m
    sl, sr = (
        (1 - (speed_m_s - Om * B / 2) / (r * wl), 1 - (speed_m_s + Om * B / 2) / (r * wr)) if solved else (None, None)
    )
    outer, inner = (sr, sl) if radius_m > 0 else (sl, sr)
    return TurnMargin(
        radius_m=float(radius_m),
        speed_m_s=float(speed_m_s),
        solved=solved,
        torque_left_Nm=float(Tl) if solved else None,
        torque_right_Nm=float(Tr) if solved else None,
        slip_outer=None if outer is None else float(outer),
        slip_inner=None if inner is None else float(inner),
        sideslip_deg=math.degrees(math.atan2(v, speed_m_s)) if solved else None,
        power_W=float(max(Tl * wl, 0.0) + max(Tr * wr, 0.0)) if solved else None,
        turn_feasible=limit is None,
        turn_limited_by=limit,
        min_turn_radius_m=min_turn_radius(vehicle, soil, speed_m_s, max_slip=max_slip, settings=settings),
        torque_limit_Nm=0.5 * limits.max_sprocket_torque,
        power_limit_W=limits.max_power,
        notes=tuple(notes),
    )
