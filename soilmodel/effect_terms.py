"""The effects' terms outside the thrust: motion resistance, drivetrain torque loss, radius, mass, load.

Each is the nominal term when its effect is off, and written as ``nominal + parameter * term``
or ``nominal * (1 + parameter)`` or ``nominal * cos(parameter)`` when it is on (floats or
CasADi expressions; effects as in :mod:`.effect_registry`).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import casadi as ca

from .effect_registry import EffectSet, EffectValues, effect_structure, effect_symbols
from .vehicle import Vehicle

__all__ = [
    "DEFAULT_STANDSTILL_SPEED",
    "DEFAULT_SLIP_WIDTH",
    "smooth_sign",
    "smooth_abs",
    "effective_mass",
    "effective_weight",
    "effective_normal_load",
    "effective_radius",
    "motion_resistance",
    "torque_loss",
    "normal_load_function",
]

#: Below this speed (m/s) Coulomb-like terms (rolling resistance, Coulomb drivetrain friction)
#: are regularised smoothly through zero; at and above it they are exactly the textbook terms.
DEFAULT_STANDSTILL_SPEED = 0.01
#: Below this slip (-) the ``|i|`` of ``slip_sinkage`` is rounded off smoothly (C2) through zero; at and
#: above it the term is exactly the textbook ``mu_s |i|``. The kink of ``|i|`` at ``i = 0`` made the
#: joint drive-log fit non-smooth: a latent slip that settles at 0 (the hull balance's V-shaped minimum,
#: steep when ``mu_s`` is large) left IPOPT cycling in failed line searches until its iteration limit
#: (heavy log, 20 % extra mass, gentle driving: 500 iterations, 15 s). 1e-3 is below the slip a drive
#: log resolves (speed noise / speed) and changes the resistance by at most ``3/8 N mu_s 1e-3``.
DEFAULT_SLIP_WIDTH = 1e-3


def smooth_sign(x, width: float | None):
    """``sgn(x)`` for ``|x| >= width``, a C1 cubic ramp through 0 inside (``width`` None or 0: +1).

    With ``width`` ``None`` the term is the textbook constant (forward motion assumed).
    """
    if not width:
        return 1.0
    s = x / width
    ramp = s * (1.5 - 0.5 * s * s)
    return ca.if_else(x >= width, 1.0, ca.if_else(x <= -width, -1.0, ramp))


def smooth_abs(x, width: float | None):
    """``|x|`` for ``|x| >= width``, inside the even quartic ``3w/8 + 3x^2/(4w) - x^4/(8w^3)`` (value, slope
    and curvature continuous at ``+-width``: C2, smooth for Newton solvers). ``width`` None or 0: ``|x|``."""
    if not width:
        return ca.fabs(x)
    w = float(width)
    x2 = x * x
    inner = 3.0 * w / 8.0 + x2 * (3.0 / (4.0 * w) - x2 / (8.0 * w**3))
    return ca.if_else(ca.fabs(x) >= w, ca.fabs(x), inner)


def effective_mass(vehicle: Vehicle, effects: Any = None):
    """Actual mass ``m (1 + delta)`` (``m`` when ``mass_error`` is off), kg."""
    ev = effects if isinstance(effects, EffectValues) else EffectValues(effects, vehicle)
    m = vehicle.mass
    return m * (1 + ev["mass_error", "delta"]) if ev.on("mass_error") else m


def effective_weight(W, vehicle: Vehicle, effects: Any = None):
    """Actual weight ``W (1 + delta)`` from the nominal ``W`` (``mass_error``), N."""
    ev = effects if isinstance(effects, EffectValues) else EffectValues(effects, vehicle)
    return W * (1 + ev["mass_error", "delta"]) if ev.on("mass_error") else W


def effective_normal_load(W, vehicle: Vehicle, effects: Any = None):
    """Actual normal load ``W (1 + delta) cos(theta)`` from the nominal ``W`` (``mass_error``, ``grade``)."""
    ev = effects if isinstance(effects, EffectValues) else EffectValues(effects, vehicle)
    N = effective_weight(W, vehicle, ev)
    return N * ca.cos(ev["grade", "theta_rad"]) if ev.on("grade") else N


def effective_radius(vehicle: Vehicle, effects: Any = None):
    """Effective track radius ``r (1 + eps)`` (``r`` when ``radius_error`` is off), m."""
    ev = effects if isinstance(effects, EffectValues) else EffectValues(effects, vehicle)
    r = vehicle.sprocket_radius
    return r * (1 + ev["radius_error", "eps"]) if ev.on("radius_error") else r


def motion_resistance(
    v,
    slip,
    vehicle: Vehicle,
    effects: Any = None,
    W=None,
    standstill_speed: float | None = DEFAULT_STANDSTILL_SPEED,
    slip_width: float | None = DEFAULT_SLIP_WIDTH,
):
    """Longitudinal motion resistance, N: nominal ``W mu_r`` plus the resistance effects.

    ``R = N (mu_r + mu_s |i|) sgn(v) + N mu_v v + W_a sin(theta)`` with ``N`` the actual normal
    load (:func:`effective_normal_load`) and ``W_a`` the actual weight. ``sgn(v)`` is
    :func:`smooth_sign` with width ``standstill_speed`` (exactly 1 for ``v >= standstill_speed``;
    ``None``: the constant textbook term, forward motion assumed). ``|i|`` is :func:`smooth_abs` with
    width ``slip_width`` (exactly ``|i|`` for ``|i| >= slip_width``; ``None``: ``|i|`` with its kink at 0).

    Parameters
    ----------
    v, slip
        Vehicle speed (m/s) and track slip (-), floats or CasADi expressions.
    W
        Nominal weight, N (default the vehicle's).
    """
    ev = effects if isinstance(effects, EffectValues) else EffectValues(effects, vehicle)
    W = vehicle.weight if W is None else W
    N = effective_normal_load(W, vehicle, ev)
    coef = vehicle.rolling_resistance
    if ev.on("slip_sinkage"):
        coef = coef + ev["slip_sinkage", "mu_s"] * smooth_abs(slip, slip_width)
    R = N * coef
    if standstill_speed:
        R = R * smooth_sign(v, standstill_speed)
    if ev.on("speed_resistance"):
        R = R + N * ev["speed_resistance", "mu_v"] * v
    if ev.on("grade"):
        R = R + effective_weight(W, vehicle, ev) * ca.sin(ev["grade", "theta_rad"])
    return R


def torque_loss(w, vehicle: Vehicle, effects: Any = None, standstill_speed: float | None = DEFAULT_STANDSTILL_SPEED):
    """Drivetrain torque loss ``tau_c sgn(w) + tau_v w`` (0 when ``drivetrain_friction`` is off), N m.

    ``sgn(w)`` is :func:`smooth_sign` with width ``standstill_speed / r``.
    """
    ev = effects if isinstance(effects, EffectValues) else EffectValues(effects, vehicle)
    if not ev.on("drivetrain_friction"):
        return 0.0
    tc, tv = ev["drivetrain_friction", "tau_c"], ev["drivetrain_friction", "tau_v"]
    sgn = smooth_sign(w, standstill_speed / vehicle.sprocket_radius) if standstill_speed else 1.0
    return tc * sgn + tv * w


@lru_cache(maxsize=64)
def _normal_load_fn(vehicle: Vehicle, structure: EffectSet) -> ca.Function:
    mapping, vec, _ = effect_symbols(structure, ca.SX, vehicle)
    W = ca.SX.sym("W")
    N = effective_normal_load(W, vehicle, mapping)
    N = N if isinstance(N, ca.SX) else ca.SX(N)
    return ca.Function("normal_load", [W, vec], [N, ca.jacobian(N, vec)], ["W", "e"], ["N", "dN_de"])


def normal_load_function(vehicle: Vehicle, effects: Any = None) -> ca.Function:
    """Cached Function ``(W, e) -> (N, dN/de)``: actual normal load from the nominal ``W`` and the
    vector ``e`` of the identifiable effect parameters (order of :func:`effect_symbols`)."""
    return _normal_load_fn(vehicle, effect_structure(effects, vehicle))
