"""Straight-line dynamics of a tracked vehicle (the seed's Eqs. 1, 3, 4) as a CasADi ODE.

State ``x = [v, w]`` (vehicle speed, m/s; sprocket speed, rad/s), input ``u = M_s`` (sprocket
torque of both tracks as measured, N m)::

    m dv/dt = F(i) - R(v, i)                  (Eq. 1; R = W mu_r nominally)
    I dw/dt = M_s - r F(i)                    (sprocket equation, default "thrust")
    I dw/dt = M_s - (F(i) - R) r              (Eq. 3 as printed in the seed, option "seed")
    i = 1 - v / (r w)                         (Eq. 4, for r w > 0)

with the effects of :mod:`.effects` applied (actual mass and load, resistance terms, torque
loss between sensor and track, effective radius, shear-changing effects in F).

Regularisation near standstill (the textbook terms are singular or discontinuous there):

- slip ``i = (r w - v) / max(r w, v_0)``, clipped to [-1, 1]: exactly Eq. 4,
  ``1 - v/(r w)``, whenever ``r w >= v_0`` (driving, and skid down to ``i = -1``, beyond
  which ``F(i) = -F(|i|)`` is saturated anyway); ``v_0`` (``standstill_speed``, default
  0.01 m/s) keeps it finite when the sprocket stops. Forward motion is the intended domain;
  reverse driving is only regularised, not modelled.
- rolling resistance and Coulomb drivetrain friction use ``sgn`` smoothed over
  ``|v| < v_0`` (:func:`~.effects.smooth_sign`); at and above ``v_0`` they are exactly the
  textbook terms. A vehicle at rest with no torque stays at rest.

The dynamics are stiff at low speed (slip settles in milliseconds): integrate them with an
implicit method (the simulator uses CVODES) or use the quasi-static limit,
:func:`slip_from_thrust`.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from .effects import (
    DEFAULT_STANDSTILL_SPEED,
    EffectSet,
    EffectValues,
    effective_mass,
    effective_radius,
    motion_resistance,
    parse_effects,
    thrust_with_effects,
    thrust_with_effects_function,
    torque_loss,
)
from .errors import DataError
from .soil import Soil
from .traction import check_model
from .vehicle import Vehicle

__all__ = [
    "SPROCKET_EQUATIONS",
    "slip_expr",
    "dynamics_expr",
    "dynamics_function",
    "slip_from_thrust",
    "slip_from_thrust_function",
    "slip_time_constant_expr",
    "held_torque_weight_expr",
    "held_torque_stencil_expr",
]

#: The two sprocket equations: ``"thrust"`` (default, ``I dw/dt = M_s - r F``) and ``"seed"``
#: (the seed's printed Eq. 3, ``I dw/dt = M_s - (F - W mu_r) r``).
SPROCKET_EQUATIONS = ("thrust", "seed")


def check_sprocket_equation(option: str) -> str:
    if option not in SPROCKET_EQUATIONS:
        raise DataError(f"unknown sprocket_equation {option!r}; expected one of {SPROCKET_EQUATIONS}")
    return option


def slip_expr(v, w, r, standstill_speed: float | None = DEFAULT_STANDSTILL_SPEED):
    """Track slip from the speeds, regularised: ``(r w - v) / max(r w, v_0)`` clipped to [-1, 1].

    Exactly Eq. 4, ``1 - v/(r w)`` (up to rounding), whenever ``r w >= v_0`` and the result lies
    in [-1, 1]; finite for every input, never NaN (``v_0 = standstill_speed``, a tiny floor when
    ``None``).
    """
    v0 = standstill_speed if standstill_speed else 1e-9
    rw = r * w
    return ca.fmin(ca.fmax((rw - v) / ca.fmax(rw, v0), -1.0), 1.0)


def dynamics_expr(
    v,
    w,
    M_s,
    c,
    phi,
    K,
    vehicle: Vehicle,
    effects: Any = None,
    *,
    model: str = "full",
    sprocket_equation: str = "thrust",
    standstill_speed: float | None = DEFAULT_STANDSTILL_SPEED,
) -> dict[str, Any]:
    """Symbolic right-hand side and intermediate signals of the dynamics.

    Parameters
    ----------
    v, w, M_s
        Vehicle speed (m/s), sprocket speed (rad/s), measured sprocket torque (N m).
    c, phi, K
        Soil parameters (SI), floats or CasADi symbols.
    vehicle
        The nominal vehicle.
    effects
        Effects (numeric :class:`~.effects.EffectSet` or a mapping with symbols, see
        :func:`~.effects.effect_symbols`).
    model
        ``"full"`` or ``"cohesion-free"`` thrust.
    sprocket_equation
        ``"thrust"`` (default): ``I dw/dt = M_s - tau_loss - r_eff F``: the torque at the
        sprocket balances the inertia and the thrust it transmits to the ground. ``"seed"``:
        the seed's Eq. 3 as printed, ``I dw/dt = M_s - tau_loss - (F - R) r_eff``. The printed
        form makes the sprocket torque at constant speed zero (``M_s = r m dv/dt + I dw/dt``),
        which no real vehicle does (docs/physics.md); it is kept only for comparison with
        the seed.
    standstill_speed
        Regularisation speed ``v_0``, m/s (see module docstring).

    Returns
    -------
    dict
        ``dv``, ``dw`` (derivatives), ``slip``, ``thrust`` (F), ``resistance`` (R),
        ``torque_loss``, ``radius`` (effective), ``mass`` (actual).
    """
    check_sprocket_equation(sprocket_equation)
    check_model(model)
    ev = effects if isinstance(effects, EffectValues) else EffectValues(effects, vehicle)
    r = effective_radius(vehicle, ev)
    m = effective_mass(vehicle, ev)
    i = slip_expr(v, w, r, standstill_speed)
    F = thrust_with_effects(i, c, phi, K, vehicle.weight, vehicle, ev, model)
    R = motion_resistance(v, i, vehicle, ev, standstill_speed=standstill_speed)
    loss = torque_loss(w, vehicle, ev, standstill_speed)
    M = M_s - loss if ev.on("drivetrain_friction") else M_s
    dv = (F - R) / m
    if sprocket_equation == "thrust":
        dw = (M - r * F) / vehicle.sprocket_inertia
    else:
        dw = (M - (F - R) * r) / vehicle.sprocket_inertia
    return {"dv": dv, "dw": dw, "slip": i, "thrust": F, "resistance": R, "torque_loss": loss, "radius": r, "mass": m}


@lru_cache(maxsize=128)
def _dyn_fn(
    vehicle: Vehicle,
    soil: Soil | None,
    effects: EffectSet,
    model: str,
    sprocket_equation: str,
    standstill_speed: float | None,
) -> ca.Function:
    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u")
    c: ca.SX | float  # symbols (soil to identify) or the given soil's numbers
    phi: ca.SX | float
    K: ca.SX | float
    if soil is None:
        p = ca.SX.sym("p", 3)
        c, phi, K = p[0], p[1], p[2]
    else:
        c, phi, K = soil.cohesion, soil.friction_angle, soil.shear_modulus
    d = dynamics_expr(
        x[0],
        x[1],
        u,
        c,
        phi,
        K,
        vehicle,
        effects,
        model=model,
        sprocket_equation=sprocket_equation,
        standstill_speed=standstill_speed,
    )
    outs = [
        ca.vertcat(d["dv"], d["dw"]),
        d["slip"],
        d["thrust"],
        d["resistance"],
        ca.SX(d["torque_loss"]) if not isinstance(d["torque_loss"], ca.SX) else d["torque_loss"],
    ]
    names_out = ["xdot", "slip", "thrust", "resistance", "torque_loss"]
    if soil is None:
        return ca.Function("track_dynamics", [x, u, p], outs, ["x", "u", "p"], names_out)
    return ca.Function("track_dynamics", [x, u], outs, ["x", "u"], names_out)


def dynamics_function(
    vehicle: Vehicle,
    soil: Soil | None = None,
    effects: Any = None,
    *,
    model: str = "full",
    sprocket_equation: str = "thrust",
    standstill_speed: float | None = DEFAULT_STANDSTILL_SPEED,
) -> ca.Function:
    """The dynamics as a cached CasADi Function.

    Inputs ``x = [v, w]``, ``u = M_s`` and, when ``soil`` is ``None``, ``p = [c, phi, K]`` (SI).
    Outputs ``xdot = [dv/dt, dw/dt]``, ``slip``, ``thrust``, ``resistance``, ``torque_loss``.
    Built once per (vehicle, soil-or-symbolic, effects, model, sprocket equation, standstill
    speed); see :func:`dynamics_expr` for the equations and the options.
    """
    check_model(model)
    check_sprocket_equation(sprocket_equation)
    return _dyn_fn(
        vehicle,
        soil,
        parse_effects(effects),
        model,
        sprocket_equation,
        None if not standstill_speed else float(standstill_speed),
    )


# --- quasi-static limit: slip as a function of thrust -------------------------------------------------

_SLIP_MAX = 0.999
#: Points per round of the peak search and of the inversion (one CasADi call per round for all loads/thrusts).
_SECTIONS = 8
_FRACTIONS = np.arange(1, _SECTIONS + 1) / (_SECTIONS + 1)
#: Rounds of the peak refinement: the bracket shrinks by 2 / (_SECTIONS + 1) per round, to 9e-14 of the grid
#: step after 20 (as the 60 golden-section steps this replaces, 3e-13).
_PEAK_ROUNDS = 20
#: Rounds of the inversion: the bracket shrinks by 1 / (_SECTIONS + 1) per round, to 7e-19 of the bracket after
#: 19 (below double precision, as the 60 halvings this replaces, 9e-19).
_INVERSE_ROUNDS = 19


def slip_time_constant_expr(slip, w, dthrust_dslip, vehicle: Vehicle):
    """Time constant (s) of the slip's relaxation under a held sprocket torque.

    The sprocket equation ``I dw/dt = M - r F(i)`` with ``w = v / (r (1 - i))``, linearised in the
    slip at a fixed vehicle speed (the hull is far heavier than the sprocket):
    ``tau = I w / ((1 - i) r dF/di)``. ``dthrust_dslip`` is ``dF/di`` of the thrust law (N), floored
    at a tiny positive value (on the flat of the curve the relaxation is slow, never negative).
    """
    dF = ca.fmax(dthrust_dslip, 1e-9)
    return vehicle.sprocket_inertia * ca.fabs(w) / (ca.fmax(1.0 - slip, 1e-3) * vehicle.sprocket_radius * dF)


def held_torque_weight_expr(x):
    """Weight ``phi(x)`` of the next interval's mean thrust in the thrust at a sample (``x = h / tau``).

    Under a torque held over each sample interval (zero-order hold), the thrust after each torque
    step relaxes exponentially with the slip's time constant ``tau`` (:func:`slip_time_constant_expr`).
    The mean thrust of an interval then differs from the thrust at its end by
    ``phi(x)`` times the change over the interval, with
    ``phi(x) = ((1 - e^-x) / x - e^-x) / (1 - e^-x)``; and ``(1 - phi) T_k + phi T_{k+1}`` of two
    consecutive interval means ``T`` equals the thrust at the sample between them to first order in
    the change (exact for a steady trend of equal steps). ``phi`` falls from 1/2 (``x -> 0``: slow
    relaxation, the thrust linear in time, the midpoint rule) to 0 (``x -> inf``: the slip settles at
    once, the interval's mean is its end value).
    """
    x = ca.fmax(x, 0.0)
    em = ca.exp(-x)
    exact = ((1.0 - em) / ca.fmax(x, 1e-300) - em) / ca.fmax(1.0 - em, 1e-300)
    return ca.if_else(x < 1e-4, 0.5 - x / 12.0, exact)


def held_torque_stencil_expr(x, curvature, spread: int = 1):
    """Weights of the interval means ``T_{k-s}, T_k, T_{k+1}, T_{k+1+s}`` (``s = spread``) in the thrust at k.

    The first-order rule of :func:`held_torque_weight_expr` takes ``(1 - phi) T_k + phi T_{k+1}``; its
    error is ``phi (1 - phi)`` times the second difference of the thrust at the samples (exact for a
    steady trend only). Near the traction limit the slip relaxes slowly (``phi`` about 1/2) and the
    thrust curves from sample to sample; there that error put F_max low. This rule subtracts
    ``curvature * phi (1 - phi)`` times the second difference estimated from interval means around the
    sample, ``((T_{k-s} + T_{k+1+s}) - (T_k + T_{k+1})) / (s (s + 1))`` (exact for a cubic; a wider
    ``spread`` reads the curvature of the trend with less of the encoder noise). With ``curvature = 2/3``
    and ``s = 1`` it is, in the slow limit (``phi -> 1/2``), the fourth-order reconstruction of a point
    value from cell means, ``(-T_{k-1} + 7 T_k + 7 T_{k+1} - T_{k+2}) / 12``; where the slip settles at
    once (``phi -> 0``) it is the end-point rule. The weights sum to one (a constant thrust is kept).

    Parameters
    ----------
    x
        ``h / tau`` of the sample (CasADi expression or number).
    curvature
        The factor of the curvature term (0: the first-order rule).
    spread
        ``s`` >= 1, the offset of the outer interval means.

    Returns
    -------
    tuple
        ``(c_outer_before, c_k, c_k+1, c_outer_after)``.
    """
    phi = held_torque_weight_expr(x)
    q = curvature * phi * (1.0 - phi) / (spread * (spread + 1))
    return -q, 1.0 - phi + q, phi + q, -q


def _thrust_at(fn: Any, soil: Any, pts: np.ndarray, W: np.ndarray) -> np.ndarray:
    """The thrust function ``fn`` at the slips ``pts`` (one row per load of ``W``, ``_SECTIONS`` columns), in
    one CasADi call."""
    F = fn(
        pts.reshape(1, -1), soil.cohesion, soil.friction_angle, soil.shear_modulus, np.repeat(W, pts.shape[1])[None, :]
    )
    return np.asarray(F, dtype=float).reshape(pts.shape)


def _peak(fn, soil: Soil, W: np.ndarray, n: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """Largest F on [0, _SLIP_MAX] and the smallest slip where it occurs, per load (grid + refine)."""
    grid = np.concatenate([[0.0], np.geomspace(1e-5, _SLIP_MAX, n - 1)])
    S, WW = np.meshgrid(grid, W, indexing="xy")
    F = np.asarray(
        fn(S.reshape(1, -1), soil.cohesion, soil.friction_angle, soil.shear_modulus, WW.reshape(1, -1)), dtype=float
    ).reshape(S.shape)
    k = np.argmax(F, axis=1)
    lo = grid[np.maximum(k - 1, 0)]
    hi = grid[np.minimum(k + 1, n - 1)]
    # refinement of the peak inside [lo, hi] (F is unimodal there): _SECTIONS points per round, one
    # CasADi call for all loads; the bracket shrinks to the points beside the largest value
    for _ in range(_PEAK_ROUNDS):
        pts = lo[:, None] + (hi - lo)[:, None] * _FRACTIONS[None, :]
        Fp = _thrust_at(fn, soil, pts, W)
        j = np.argmax(Fp, axis=1)
        rows = np.arange(len(W))
        lo, hi = (
            np.where(j > 0, pts[rows, np.maximum(j - 1, 0)], lo),
            np.where(j < _SECTIONS - 1, pts[rows, np.minimum(j + 1, _SECTIONS - 1)], hi),
        )
    s_peak = 0.5 * (lo + hi)
    F_peak = np.asarray(
        fn(s_peak.reshape(1, -1), soil.cohesion, soil.friction_angle, soil.shear_modulus, W.reshape(1, -1)), dtype=float
    ).ravel()
    F_grid_max = F[np.arange(F.shape[0]), k]
    better = F_grid_max > F_peak
    return np.where(better, grid[k], s_peak), np.maximum(F_peak, F_grid_max)


def slip_from_thrust(
    thrust,
    soil: Soil,
    vehicle: Vehicle,
    effects: Any = None,
    model: str = "full",
    normal_load=None,
    return_reachable: bool = False,
):
    """Slip at which the soil gives the thrust ``thrust`` (inverse of F(i)), numpy, vectorised.

    The rising branch of F(i) is inverted by bisection (60 halvings, then the slip is exact to
    ~1e-16 of the bracket); negative thrust gives the skid ``-i(|F|)``. Thrust beyond the soil's
    peak on [0, 0.999] is unreachable: the slip of the peak is returned (and flagged).

    Parameters
    ----------
    thrust
        Tractive force of both tracks, N (array-like).
    soil, vehicle, effects, model
        As in :func:`~.effects.tractive_force_with_effects`.
    normal_load
        Nominal normal load(s), N (default the vehicle's weight), broadcast with ``thrust``.
    return_reachable
        Also return a boolean array, False where ``|thrust|`` exceeds the soil's peak.

    Returns
    -------
    slip : ndarray, or (slip, reachable)
    """
    fn = thrust_with_effects_function(vehicle, effects, model)
    W = vehicle.weight if normal_load is None else normal_load
    T, Wb = np.broadcast_arrays(np.asarray(thrust, dtype=float), np.asarray(W, dtype=float))
    shape = T.shape
    T, Wb = T.ravel(), Wb.ravel()
    if not np.all(np.isfinite(T)) or not np.all(np.isfinite(Wb)):
        raise DataError("slip_from_thrust: thrust and normal load must be finite")
    if T.size == 0:
        out = np.zeros(shape)
        return (out, np.ones(shape, dtype=bool)) if return_reachable else out
    Wu, inv = np.unique(Wb, return_inverse=True)
    s_pk, F_pk = _peak(fn, soil, Wu)
    s_pk, F_pk = s_pk[inv], F_pk[inv]
    target = np.abs(T)
    reachable = target <= F_pk
    lo = np.zeros_like(target)
    hi = s_pk.copy()
    tgt = np.minimum(target, F_pk)
    # multisection of the rising branch: _SECTIONS points per round, one CasADi call for all thrusts
    for _ in range(_INVERSE_ROUNDS):
        pts = lo[:, None] + (hi - lo)[:, None] * _FRACTIONS[None, :]
        Fp = _thrust_at(fn, soil, pts, Wb)
        j = np.sum(Fp < tgt[:, None], axis=1)  # points below the target (F rises on the bracket)
        rows = np.arange(len(tgt))
        lo, hi = (
            np.where(j > 0, pts[rows, np.maximum(j - 1, 0)], lo),
            np.where(j < _SECTIONS, pts[rows, np.minimum(j, _SECTIONS - 1)], hi),
        )
    slip = np.where(reachable, 0.5 * (lo + hi), s_pk) * np.sign(T)
    slip = slip.reshape(shape)
    return (slip, reachable.reshape(shape)) if return_reachable else slip


@lru_cache(maxsize=64)
def _inv_fn(vehicle: Vehicle, effects: EffectSet, model: str) -> ca.Function:
    i = ca.SX.sym("i")
    p = ca.SX.sym("p", 5)  # F, c, phi, K, W
    one = ca.SX.sym("one")
    F_of = ca.Function("F_of", [one, p], [thrust_with_effects(one, p[1], p[2], p[3], p[4], vehicle, effects, model)])
    dF1 = ca.jacobian(F_of(one, p), one)
    dF1 = ca.substitute(dF1, one, 1.0)
    i_c = ca.fmin(ca.fmax(i, -1.0), 1.0)
    # F on [-1, 1], continued linearly beyond (keeps Newton finite when |F| exceeds F(1))
    g = F_of(i_c, p) + dF1 * (i - i_c) - p[0]
    rf = ca.rootfinder(
        "slip_inverse_rf",
        "newton",
        {"x": i, "p": p, "g": g},
        {"abstol": 1e-10, "max_iter": 200, "error_on_fail": False},
    )
    Ft, c, phi, K, W = (ca.MX.sym(n) for n in ("F", "c", "phi", "K", "W"))
    sol = rf(x0=0.0, p=ca.vertcat(Ft, c, phi, K, W))["x"]
    return ca.Function(
        "slip_from_thrust",
        [Ft, c, phi, K, W],
        [ca.fmin(ca.fmax(sol, -1.0), 1.0)],
        ["F", "c", "phi", "K", "W"],
        ["slip"],
    )


def slip_from_thrust_function(vehicle: Vehicle, effects: Any = None, model: str = "full") -> ca.Function:
    """Differentiable CasADi Function ``slip(F, c, phi, K, W)``: Newton rootfinder from slip 0.

    Newton from 0 converges monotonically on a concave rising branch (Janosi-Hanamoto with
    uniform or any non-negative pressure distribution); derivatives follow from the implicit
    function theorem, so it can sit inside an identification NLP. It assumes
    ``|F|`` below the soil's thrust limit: beyond it there is no solution and the result
    (clipped to [-1, 1]) is meaningless - check with the thrust function or use
    :func:`slip_from_thrust` (which flags it). With ``hump_shear`` on it targets the rising
    branch only.
    """
    check_model(model)
    return _inv_fn(vehicle, parse_effects(effects), model)
