"""Slip-optimal traction: the slip that maximises drawbar power, and the one that maximises efficiency.

At steady state on a level or graded patch, with normal load N = W cos(theta)::

    drawbar pull    DP(i) = F(i) - R,   R = mu_r N + R_c (+ W sin(theta) on a grade)
    drawbar power   P_DP(i) = DP(i) v = DP(i) r w (1 - i)       (at a given sprocket speed w)
    efficiency      eta(i) = DP v / (M_s w) = DP(i) (1 - i) / F(i)   (M_s = r F at steady speed)

F is Eq. 2 from the model core. The drivetrain's limits are not applied to the curves (a note
says when the power optimum is beyond them). Both optima are found on a fine slip grid (0 to 0.99) refined
by golden-section search. Where eta peaks the efficiency is independent of w; the power optimum's
slip is too (w only scales P_DP). From a ``FitResult`` the uncertainty bands come from Monte Carlo
samples of the fit's Gaussian (percentiles 2.5 and 97.5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..soilmodel import Vehicle, format_power, format_torque, thrust_function
from ..soilmodel.search import golden_section
from .arguments import check_number
from .forces import resistances, soil_thrust
from .margin import resolve_terrain, terrain_soil_vector

__all__ = ["SlipOptimum", "slip_optimal"]

#: Golden-section steps refining a grid optimum: each shrinks the bracket of two grid cells by 0.618, so 60 steps
#: leave ~3e-13 of it (the optimum's slip to machine precision).
REFINE_STEPS = 60
_GRID = np.concatenate([np.linspace(1e-4, 0.05, 300), np.linspace(0.05, 0.99, 700)[1:]])


@dataclass(frozen=True)
class SlipOptimum:
    """Outcome of :func:`slip_optimal` (SI).

    Attributes
    ----------
    slip_max_power, max_drawbar_power_W
        Slip of the largest drawbar power at the sprocket speed, and that power.
    slip_max_efficiency, max_efficiency
        Slip of the largest tractive efficiency, and that efficiency.
    sprocket_speed_rad_s, normal_load_N, resistance_N
        Inputs used.
    slip, drawbar_pull_N, drawbar_power_W, efficiency
        The curves on the slip grid.
    bands
        From a fit: ``{"slip_max_power": [lo, hi], "slip_max_efficiency": [lo, hi],
        "drawbar_power_W": [lo-array, hi-array], "efficiency": [lo-array, hi-array]}`` (95 %),
        else ``None``.
    notes
        Remarks.
    """

    slip_max_power: float | None
    max_drawbar_power_W: float
    slip_max_efficiency: float | None
    max_efficiency: float
    sprocket_speed_rad_s: float
    normal_load_N: float
    resistance_N: float
    slip: np.ndarray
    drawbar_pull_N: np.ndarray
    drawbar_power_W: np.ndarray
    efficiency: np.ndarray
    bands: dict | None = None
    notes: tuple[str, ...] = field(default=())

    def report(self) -> str:
        """Plain-words summary."""
        sp, se = self.slip_max_power, self.slip_max_efficiency
        if sp is None or se is None:  # both None together (no positive drawbar pull)
            return "no positive drawbar pull at any slip: the soil cannot overcome the resistance"
        L = [
            f"largest drawbar power {format_power(self.max_drawbar_power_W)} at {sp * 100:.3g} % slip "
            f"(sprocket speed {self.sprocket_speed_rad_s:.3g} rad/s)",
            f"largest tractive efficiency {self.max_efficiency * 100:.3g} % at {se * 100:.3g} % slip",
        ]
        if self.bands:
            a, b = self.bands["slip_max_power"]
            c, d = self.bands["slip_max_efficiency"]
            L.append(
                f"  95 % bands from the fit: power-optimal slip {a * 100:.3g}-{b * 100:.3g} %, efficiency-optimal "
                f"slip {c * 100:.3g}-{d * 100:.3g} %"
            )
        L += [f"  note: {n}" for n in self.notes]
        return "\n".join(L)


def _thrust_on_grid(theta, vehicle, N, model):
    f = thrust_function(model)
    out = f(
        _GRID.reshape(1, -1),
        float(theta[0]),
        float(theta[1]),
        float(theta[2]),
        N,
        vehicle.track_length,
        vehicle.track_width,
    )
    return np.asarray(out, dtype=float).ravel()


def _curves(theta, vehicle, N, R, w, model):
    F = _thrust_on_grid(theta, vehicle, N, model)
    DP = F - R
    v = vehicle.sprocket_radius * w * (1 - _GRID)
    P = DP * v
    eta = np.where(F > 0, DP * (1 - _GRID) / np.where(F > 0, F, 1.0), 0.0)
    return DP, P, eta


def _refine(fun, k: int) -> tuple[float, float]:
    lo, hi = float(_GRID[max(k - 1, 0)]), float(_GRID[min(k + 1, len(_GRID) - 1)])
    s = golden_section(lambda x: -fun(x), lo, hi, steps=REFINE_STEPS).midpoint
    return s, fun(s)


def _optima(theta, vehicle, N, R, w, model, refine: bool = True):
    r = vehicle.sprocket_radius

    def F(s):
        return float(soil_thrust(theta, s, N, vehicle, model)[0])

    def power(s):
        return (F(s) - R) * r * w * (1 - s)

    def eff(s):
        f = F(s)
        return (f - R) * (1 - s) / f if f > 0 else 0.0

    DP, P, eta = _curves(theta, vehicle, N, R, w, model)
    if np.max(DP) <= 0:
        return None, float(np.max(P)), None, float(np.max(eta)), DP, P, eta
    kp, ke = int(np.argmax(P)), int(np.argmax(eta))
    if not refine:  # grid resolution: 1.7e-4 below 5 % slip, 1.3e-3 above (enough for bands)
        return float(_GRID[kp]), float(P[kp]), float(_GRID[ke]), float(eta[ke]), DP, P, eta
    sp, pp = _refine(power, kp)
    se, ee = _refine(eff, ke)
    return sp, pp, se, ee, DP, P, eta


def slip_optimal(
    terrain: Any,
    vehicle: Vehicle,
    *,
    sprocket_speed: float = 10.0,
    grade_deg: float = 0.0,
    samples: int = 200,
    seed: int | None = 0,
) -> SlipOptimum:
    """Slips of the largest drawbar power and of the largest tractive efficiency (module docstring).

    Parameters
    ----------
    terrain
        ``Soil``, ``FitResult`` or ``SoilUncertainty`` (bands from ``samples`` Monte Carlo soils).
    vehicle
        The vehicle.
    sprocket_speed
        Sprocket speed w, rad/s (scales the drawbar power only).
    grade_deg
        Grade, deg (its W sin(theta) counts as resistance).
    """
    w = check_number("sprocket_speed", sprocket_speed, 0.0, lo_open=True)
    th = math.radians(check_number("grade_deg", grade_deg, -68.75, 68.75))
    soil, unc, model = resolve_terrain(terrain, vehicle)
    Narr, req = resistances(vehicle, soil, np.array([th]), 0.0, 0.0)
    N = float(Narr[0])
    R = float(sum(v[0] for v in req.values()))
    theta = terrain_soil_vector(soil, unc, N)
    sp, pp, se, ee, DP, P, eta = _optima(theta, vehicle, N, R, w, model)
    notes = []
    if sp is not None:
        M = vehicle.sprocket_radius * (P[int(np.argmax(P))] / (vehicle.sprocket_radius * w * (1 - sp)) + R)
        if (vehicle.max_sprocket_torque and M > vehicle.max_sprocket_torque) or (
            vehicle.max_power and M * w > vehicle.max_power
        ):
            notes.append(
                f"the power-optimal slip needs a sprocket torque of {format_torque(M)} at {w:.3g} rad/s, beyond "
                "the vehicle's torque or power limit: the drivetrain cannot reach it at this sprocket speed"
            )
    bands = None
    if unc is not None:
        notes.append(unc.describe(N))
        th_s = unc.soils_at(unc.sample(samples, seed), N)
        res = [_optima(t, vehicle, N, R, w, model, refine=False) for t in th_s]
        ok = [x for x in res if x[0] is not None]
        if ok:
            arr = np.array([[x[0], x[2]] for x in ok])
            Ps = np.array([x[5] for x in ok])
            Es = np.array([x[6] for x in ok])
            bands = {
                "slip_max_power": list(np.percentile(arr[:, 0], [2.5, 97.5])),
                "slip_max_efficiency": list(np.percentile(arr[:, 1], [2.5, 97.5])),
                "drawbar_power_W": list(np.percentile(Ps, [2.5, 97.5], axis=0)),
                "efficiency": list(np.percentile(Es, [2.5, 97.5], axis=0)),
            }
    return SlipOptimum(sp, pp, se, ee, w, N, R, _GRID.copy(), DP, P, eta, bands, tuple(notes))
