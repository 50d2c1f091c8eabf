"""Stuck prediction: when the tracks spin (slip runs away towards 1), and when the belly touches.

Spin. At a steady sprocket speed the thrust balance ``I dw/dt = M - r F(i)`` gives the thrust
``F = M / r``. The soil gives at most ``F_spin = F(i -> 1)`` (the thrust-slip curve of Eq. 2 is
rising: its top is at full slip). A torque above ``M_spin = r F_spin`` cannot be balanced by
any slip: the sprocket accelerates and the slip runs away towards 1 - the tracks spin. The
vehicle is stuck when the thrust it needs (the required thrust of :func:`~.margin.margin`)
exceeds ``F_spin``: no torque moves it, more torque only digs.

For a given torque M the steady slip is ``i(M / r)`` (``None`` beyond ``M_spin``). With a power
limit the drivetrain reaches ``M_spin`` while the sprocket speed is below ``P / M_spin``, i.e.
while the track speed ``r w`` is below ``P / F_spin``: a full-throttle vehicle whose track speed
falls below it (on entering a soft patch, on a grade) starts to spin; its vehicle speed is then
``r w (1 - i)`` with i running away towards 1.

Belly. With Bekker parameters and ``vehicle.ground_clearance``: static sinkage z0 (Bekker,
:mod:`soiltrack.soilmodel.sinkage`) grows with slip. The law used is Lyasko's slip-sinkage
relation (J. Terramechanics 47, 2010), ``z = z0 (1 + i) / (1 - 0.5 i)`` (z = 4 z0 at full
slip), an empirical fit; other slip-sinkage laws exist and give other numbers. The belly touches
when z reaches the ground clearance: at the slip ``i_belly`` (``None`` if never below full
slip; 0 if the static sinkage already reaches it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..soilmodel import Soil, Vehicle, format_force, format_torque, slip_from_thrust
from ..soilmodel.sinkage import has_bekker, slip_at_sinkage, slip_sinkage, static_sinkage
from .arguments import check_number
from .forces import resistances, soil_thrust
from .margin import DEFAULT_MAX_SLIP, resolve_terrain, terrain_soil_vector

__all__ = ["Stuck", "stuck"]

_FULL_SLIP = 0.999


@dataclass(frozen=True)
class Stuck:
    """Outcome of :func:`stuck` (SI; ``None`` where a value does not exist).

    Attributes
    ----------
    stuck
        True when the required thrust exceeds the soil's full-slip thrust (no torque moves the
        vehicle), or the sinkage at the operating slip reaches the belly.
    spin_thrust_N, spin_torque_Nm
        The soil's thrust at full slip and the torque beyond which the tracks spin.
    required_N, thrust_margin_N
        Thrust needed (as in :func:`~.margin.margin`) and ``spin_thrust_N - required_N``.
    torque_Nm, slip_at_torque, spins_at_torque, torque_margin_Nm
        The torque examined (default: the vehicle's limit), its steady slip (``None`` when it
        spins), whether it spins, ``spin_torque_Nm - torque_Nm``.
    spin_track_speed_m_s
        Track speed ``r w`` below which the drivetrain at full throttle produces the spin torque
        (``None``: never, or always - see ``notes``).
    static_sinkage_m, ground_clearance_m, belly_slip, sinkage_at_operating_slip_m
        Bekker static sinkage, the clearance, the slip at which the slip sinkage reaches the belly.
    notes
        Remarks in words.
    """

    stuck: bool
    spin_thrust_N: float
    spin_torque_Nm: float
    required_N: float
    thrust_margin_N: float
    torque_Nm: float | None
    slip_at_torque: float | None
    spins_at_torque: bool | None
    torque_margin_Nm: float | None
    spin_track_speed_m_s: float | None
    static_sinkage_m: float | None
    ground_clearance_m: float | None
    belly_slip: float | None
    sinkage_at_operating_slip_m: float | None
    notes: tuple[str, ...] = field(default=())

    def to_dict(self) -> dict:
        """JSON-ready dict (``None`` for non-finite values)."""
        out = {}
        for k, v in self.__dict__.items():
            if isinstance(v, float) and not math.isfinite(v):
                v = None
            out[k] = list(v) if isinstance(v, tuple) else v
        return out

    def report(self) -> str:
        """Plain-words summary."""
        kn = format_force
        L = [
            ("STUCK" if self.stuck else "not stuck") + f": the soil gives at most {kn(self.spin_thrust_N)} (full "
            f"slip), the vehicle needs {kn(self.required_N)} (reserve {kn(self.thrust_margin_N)})",
            f"  tracks spin above a sprocket torque of {format_torque(self.spin_torque_Nm)}",
        ]
        if self.torque_Nm is not None:
            slip = self.slip_at_torque  # None when the torque spins the tracks
            L.append(
                f"  at {format_torque(self.torque_Nm)}: "
                + (
                    "the tracks spin (slip runs away towards 1)"
                    if self.spins_at_torque or slip is None
                    else f"steady slip {slip * 100:.3g} %, {format_torque(self.torque_margin_Nm)} below spin"
                )
            )
        if self.spin_track_speed_m_s is not None:
            L.append(
                f"  at full throttle the tracks spin when the track speed r w falls below "
                f"{self.spin_track_speed_m_s:.3g} m/s"
            )
        if self.static_sinkage_m is not None:
            L.append(
                f"  static sinkage {self.static_sinkage_m * 100:.3g} cm"
                + (
                    ""
                    if self.ground_clearance_m is None
                    else f", belly at {self.ground_clearance_m * 100:.3g} cm: "
                    + (
                        "touches at rest"
                        if self.belly_slip == 0
                        else "never touches below full slip"
                        if self.belly_slip is None
                        else f"touches at {self.belly_slip * 100:.3g} % slip"
                    )
                )
            )
        L += [f"  note: {n}" for n in self.notes]
        return "\n".join(L)


def stuck(
    terrain: Any,
    vehicle: Vehicle,
    *,
    torque: float | None = None,
    grade_deg: float = 0.0,
    accel: float = 0.0,
    drawbar_N: float = 0.0,
    max_slip: float | None = None,
) -> Stuck:
    """When does the vehicle get stuck on ``terrain`` (see the module docstring)?

    Parameters
    ----------
    terrain
        ``Soil``, ``FitResult`` or ``SoilUncertainty`` (an identified soil: the fitted soil,
        worst ridge point).
    vehicle
        The vehicle (torque/power limits; ``ground_clearance`` for the belly check).
    torque
        Sprocket torque to examine, N m (default: the vehicle's torque limit, if any).
    grade_deg, accel, drawbar_N
        As in :func:`~.margin.margin`.
    max_slip
        Operating slip for the sinkage at the operating point (default 0.2).
    """
    grade_deg = check_number("grade_deg", grade_deg, -68.75, 68.75)
    i_op = DEFAULT_MAX_SLIP if max_slip is None else check_number("max_slip", max_slip, 0, 1, True, True)
    soil, unc, model = resolve_terrain(terrain, vehicle)
    th = math.radians(grade_deg)
    Narr, req = resistances(
        vehicle, soil, np.array([th]), check_number("accel", accel), check_number("drawbar_N", drawbar_N)
    )
    N = float(Narr[0])
    R = float(sum(v[0] for v in req.values()))
    theta = terrain_soil_vector(soil, unc, N)
    s = soil if soil is not None else Soil(float(theta[0]), float(theta[1]), float(theta[2]), name="fitted soil")
    F_spin = float(soil_thrust(theta, _FULL_SLIP, N, vehicle, model)[0])
    r = vehicle.sprocket_radius
    M_spin = r * F_spin
    notes = []
    if unc is not None:
        notes.append(unc.describe(N))
    M = torque if torque is not None else vehicle.max_sprocket_torque
    slip_M = spins = tm = None
    if M is not None:
        M = check_number("torque", M, 0.0)
        spins = M > M_spin
        tm = M_spin - M
        if not spins:
            slip_M = float(slip_from_thrust(np.array([M / r]), s, vehicle, model=model, normal_load=N)[0])
    v_spin = None
    Tmax, P = vehicle.max_sprocket_torque, vehicle.max_power
    if Tmax is not None and Tmax <= M_spin:
        notes.append(
            f"the torque limit ({format_torque(Tmax)}) is below the spin torque: full throttle does not spin the tracks"
        )
    elif P:
        v_spin = P / F_spin  # track speed r w at which P / w equals the spin torque
    else:
        notes.append("no power limit: a drivetrain that can reach the spin torque does so at any speed")
    z0 = float(static_sinkage(soil, vehicle, N)) if soil is not None and has_bekker(soil) else None
    gc = vehicle.ground_clearance
    belly = z_op = None
    if z0 is not None:
        z_op = float(slip_sinkage(z0, i_op))
        if gc is not None:
            if z0 >= gc:
                belly = 0.0
            else:
                ib = slip_at_sinkage(z0, gc)
                belly = ib if ib < 1 else None
        else:
            notes.append("the vehicle gives no ground_clearance_m: the belly check is not done")
    else:
        notes.append("no Bekker parameters: no sinkage estimate")
    is_stuck = R > F_spin or (belly is not None and belly <= i_op)
    return Stuck(
        bool(is_stuck), F_spin, M_spin, R, F_spin - R, M, slip_M, spins, tm, v_spin, z0, gc, belly, z_op, tuple(notes)
    )
