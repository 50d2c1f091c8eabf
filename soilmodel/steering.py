"""Skid steering of a tracked vehicle on deformable ground (Wong and Chiang's general theory).

Hull frame: x forward, y to the left, origin at the centre of the two contact patches (the
centre of gravity in plan), yaw rate ``Om`` positive to the left. The hull moves with forward
speed ``u`` and lateral speed ``v`` at the origin; track k (left: y_k = +B/2, right: -B/2) has
belt speed ``r w_k`` (the belt's ground run moves rearwards relative to the hull at that speed).

A point (x, y) of track k's contact patch slides over the ground with (hull frame)::

    V_x = u - Om y - r w_k,        V_y = v + Om x

It entered the contact at the front (x = l/2) ``T = (l/2 - x) / (r w_k)`` seconds ago. Its shear
displacement is the sliding velocity integrated along its path in the ground frame (the hull
turned by ``Om t`` meanwhile); for a steady motion this has a closed form::

    j_X = V_x C0 - b0 S0 + Om r w_k S1,     j_Y = V_x S0 + b0 C0 - Om r w_k C1,    b0 = v + Om l/2
    C0 = int_0^T cos(Om t) dt,  S0 = int_0^T sin(Om t) dt,  C1 = int_0^T t cos(Om t) dt,  S1 = int t sin

(series near ``Om T = 0``). The soil's shear stress, Janosi-Hanamoto, acts against the sliding
velocity::

    tau = (c + p tan(phi)) (1 - exp(-|j| / K)),      force on the hull  -tau V / |V| dA

with uniform pressure ``p_k = W_k / (b l)`` per track and the lateral load transfer of the
centripetal force, ``W_{left,right} = W/2 -+ m a_y h / B`` (``a_y = u Om``, h the centre of
gravity's height; none when the vehicle gives no ``cg_height_m``). The forces (longitudinal
``F_x``, lateral ``F_y``) and the yaw moment ``M_z = x dF_y - y dF_x`` of each patch are
integrated by Gauss-Legendre quadrature (:class:`SteeringSettings`), the motion resistance
``R_k = mu_r W_k`` acts along each track (its moment ``(R_l - R_r) B / 2``). The sprocket
torque of track k is ``r F_x,k`` (plus its share of the sprocket inertia times dw_k/dt).

Straight line (``Om = v = 0``, ``w_l = w_r``): ``j = i (l/2 - x)`` and the sum of both tracks
is exactly Eq. 2 (up to the quadrature error, stated in docs/physics.md).

Everything is a CasADi SX expression built once per quadrature size; the vehicle enters as a
parameter vector (:func:`vehicle_parameters`), so one Function serves every vehicle and soil.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from .effect_terms import DEFAULT_STANDSTILL_SPEED, smooth_sign
from .errors import DataError
from .soil import Soil
from .threadsafe import call_solver, locked_cache
from .vehicle import G, Vehicle

__all__ = [
    "SteeringSettings",
    "SteadyTurn",
    "vehicle_parameters",
    "track_forces_expr",
    "hull_forces_function",
    "steady_turn",
    "steady_turn_function",
    "motion_inverse_function",
    "slip_limited_motion_function",
    "torque_inverse_function",
    "torque_residual_function",
    "kinematic_radius",
    "check_steering_vehicle",
    "tread_of",
]

#: Below this |Om T| the path integrals C0, S0, C1, S1 are evaluated by their series (error < 1e-14).
PHI_SERIES = 0.1
#: Regularising speed of |V| in the sliding direction V/|V|, m/s (a point that does not slide has no direction).
SLIDE_EPS = 1e-6
#: Floor on the belt speed r w in the contact time (l/2 - x)/(r w), m/s (a stopped belt: the contact lasts).
BELT_FLOOR = 1e-3
#: Names of the vehicle parameter vector (:func:`vehicle_parameters`).
VEHICLE_PARAMS = ("m", "l", "b", "B", "r", "mu_r", "h", "Iz", "I")


@dataclass(frozen=True)
class SteeringSettings:
    """Quadrature of the contact patches.

    Attributes
    ----------
    n_along
        Gauss-Legendre nodes along each of the two panels along a track (the shear builds up from
        the front: the steep part).
    n_across
        Gauss-Legendre nodes across each of the two panels across a track.
    """

    n_along: int = 16
    n_across: int = 3

    def __post_init__(self) -> None:
        for k in ("n_along", "n_across"):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= 400:
                raise DataError(f"SteeringSettings.{k} must be an integer in [1, 400], got {v!r}")


def check_steering_vehicle(vehicle: Vehicle) -> Vehicle:
    """``vehicle`` if it has a ``tread`` (needed to steer), else a DataError naming ``tread_m``."""
    if vehicle.tread is None:
        raise DataError(
            "the steering model needs the vehicle's tread_m (distance between the track centre lines, m)",
            column="tread_m",
        )
    return vehicle


def tread_of(vehicle: Vehicle) -> float:
    """The vehicle's tread B, m (DataError naming ``tread_m`` when it has none)."""
    tread = check_steering_vehicle(vehicle).tread
    assert tread is not None  # checked above
    return float(tread)


def vehicle_parameters(vehicle: Vehicle) -> np.ndarray:
    """The parameter vector ``[m, l, b, B, r, mu_r, h, Iz, I]`` of the steering Functions (SI)."""
    check_steering_vehicle(vehicle)
    return np.array(
        [
            vehicle.mass,
            vehicle.track_length,
            vehicle.track_width,
            vehicle.tread,
            vehicle.sprocket_radius,
            vehicle.rolling_resistance,
            vehicle.cg_height or 0.0,
            vehicle.yaw_inertia_or_box,
            vehicle.sprocket_inertia,
        ],
        dtype=float,
    )


def kinematic_radius(w_left, w_right, tread: float):
    """Turning radius of the centre without slip, ``(B/2)(w_r + w_l)/(w_r - w_l)`` (signed: + left)."""
    wl, wr = np.asarray(w_left, dtype=float), np.asarray(w_right, dtype=float)
    with np.errstate(divide="ignore"):
        return 0.5 * tread * (wr + wl) / (wr - wl)


def _path_integrals(phi, T):
    """``C0, S0, C1, S1`` of the module docstring for ``phi = Om T`` (elementwise SX, series near 0)."""
    p2 = phi * phi
    small = ca.fabs(phi) < PHI_SERIES
    safe = ca.if_else(small, 1.0, phi)  # keeps the unused branch finite (and its derivative)
    sinc = ca.if_else(small, 1 - p2 / 6 * (1 - p2 / 20 * (1 - p2 / 42)), ca.sin(safe) / safe)
    cq = ca.if_else(
        small, phi * (0.5 - p2 * (1 / 24 - p2 * (1 / 720 - p2 / 40320))), (1 - ca.cos(safe)) / safe
    )  # (1 - cos)/phi
    pc = ca.if_else(
        small,
        0.5 - p2 * (1 / 8 - p2 * (1 / 144 - p2 / 5760)),
        ca.sin(safe) / safe + (ca.cos(safe) - 1) / (safe * safe),
    )
    qs = ca.if_else(
        small,
        phi * (1 / 3 - p2 * (1 / 30 - p2 / 840)),
        (ca.sin(safe) - safe * ca.cos(safe)) / (safe * safe),
    )
    return T * sinc, T * cq, T * T * pc, T * T * qs


@lru_cache(maxsize=8)
def _nodes(settings: SteeringSettings) -> tuple[np.ndarray, ...]:
    """Gauss-Legendre nodes on [0, 1] (along, across) with their weights, as flat tensor-grid columns."""
    xa, wa = np.polynomial.legendre.leggauss(settings.n_along)
    xc, wc = np.polynomial.legendre.leggauss(settings.n_across)
    XI, ETA = np.meshgrid(0.5 * (xa + 1), 0.5 * (xc + 1), indexing="ij")
    WA, WC = np.meshgrid(0.5 * wa, 0.5 * wc, indexing="ij")
    return XI.ravel(), ETA.ravel(), WA.ravel(), WC.ravel()


def _clip(x, lo, hi):
    return ca.fmin(ca.fmax(x, lo), hi)


def _panels(a, s, b_, t, w):
    """Nodes and weights of two panels [a, s] and [s, b_] from the [0, 1] rule (t, w): columns."""
    return ca.vertcat(a + (s - a) * t, s + (b_ - s) * t), ca.vertcat((s - a) * w, (b_ - s) * w)


def track_forces_expr(u, v, Om, belt, y_c, W_k, c, phi, K, l, b, settings: SteeringSettings):
    """``(F_x, F_y, M_z)`` of one track's shear on the hull (SX scalars), by quadrature.

    ``belt`` is the belt speed ``r w_k`` (m/s), ``y_c`` the track's centre line (m), ``W_k`` its
    normal load (N); the moment is about the origin (the patches' centre). The patch is split
    into four panels at the lines where the sliding velocity's components change sign (the
    instantaneous centre's longitudinal shift ``-v/Om`` and the track's own lateral one
    ``(u - r w_k)/Om``, each clipped into the patch): the sliding direction turns quickly there,
    and a Gauss rule converges slowly across such a kink. Each panel has the tensor
    Gauss-Legendre rule of :class:`SteeringSettings`.
    """
    xi, eta, wa, wc = (ca.DM(a) for a in _nodes(settings))
    tiny = 1e-12
    xs = _clip(-v * Om / (Om * Om + tiny), -0.5 * l, 0.5 * l)
    ys = _clip((u - belt) * Om / (Om * Om + tiny), y_c - 0.5 * b, y_c + 0.5 * b)
    x_col, wx = _panels(-0.5 * l, xs, 0.5 * l, xi, wa)
    y_col, wy = _panels(y_c - 0.5 * b, ys, y_c + 0.5 * b, eta, wc)
    n = xi.numel()
    x = ca.vertcat(x_col, x_col)  # the 4 panels: (x panel, y panel) = (1,1), (2,1), (1,2), (2,2)
    y = ca.vertcat(y_col[:n], y_col[:n], y_col[n:], y_col[n:])
    dA = ca.vertcat(wx * ca.repmat(wy[:n], 2, 1), wx * ca.repmat(wy[n:], 2, 1))
    p = W_k / (b * l)
    vx = u - Om * y - belt
    vy = v + Om * x
    T = (0.5 * l - x) / ca.fmax(belt, BELT_FLOOR)
    C0, S0, C1, S1 = _path_integrals(Om * T, T)
    b0 = v + Om * 0.5 * l
    jx = vx * C0 - b0 * S0 + Om * belt * S1
    jy = vx * S0 + b0 * C0 - Om * belt * C1
    j = ca.sqrt(jx * jx + jy * jy + 1e-30)
    tau = (c + p * ca.tan(phi)) * (-ca.expm1(-j / K))
    speed = ca.sqrt(vx * vx + vy * vy + SLIDE_EPS**2)
    fx = -tau * vx / speed * dA
    fy = -tau * vy / speed * dA
    return ca.sum1(fx), ca.sum1(fy), ca.sum1(x * fy - y * fx)


@lru_cache(maxsize=8)
def hull_forces_function(settings: SteeringSettings = SteeringSettings()) -> ca.Function:
    """CasADi Function of the forces on the hull, built once per quadrature.

    Inputs ``motion = [u, v, Om]``, ``w = [w_l, w_r]`` (rad/s), ``soil = [c, phi, K]`` (SI),
    ``a_y`` (lateral acceleration for the load transfer, m/s^2), ``veh`` (:func:`vehicle_parameters`).
    Outputs ``Fx = [F_x,l, F_x,r]`` (each track's shear along the track, N: the sprocket torque
    is ``r F_x``), ``net = [X, Y, N]`` (longitudinal force with the resistances, lateral force, yaw
    moment with the resistances' moment), ``W = [W_l, W_r]`` (the track loads, N).
    """
    mo, w, so, ay = ca.SX.sym("motion", 3), ca.SX.sym("w", 2), ca.SX.sym("soil", 3), ca.SX.sym("a_y")
    veh = ca.SX.sym("veh", len(VEHICLE_PARAMS))
    m, l, b, B, r, mu_r, h = (veh[k] for k in range(7))
    u, v, Om = mo[0], mo[1], mo[2]
    W = m * G
    dW = m * ay * h / B
    Wl, Wr = 0.5 * W - dW, 0.5 * W + dW
    fl = track_forces_expr(u, v, Om, r * w[0], 0.5 * B, Wl, so[0], so[1], so[2], l, b, settings)
    fr = track_forces_expr(u, v, Om, r * w[1], -0.5 * B, Wr, so[0], so[1], so[2], l, b, settings)
    sgn = smooth_sign(u, DEFAULT_STANDSTILL_SPEED)
    Rl, Rr = mu_r * Wl * sgn, mu_r * Wr * sgn
    X = fl[0] + fr[0] - Rl - Rr
    Y = fl[1] + fr[1]
    N = fl[2] + fr[2] + 0.5 * B * (Rl - Rr)
    return ca.Function(
        "hull_forces",
        [mo, w, so, ay, veh],
        [ca.vertcat(fl[0], fr[0]), ca.vertcat(X, Y, N), ca.vertcat(Wl, Wr)],
        ["motion", "w", "soil", "a_y", "veh"],
        ["Fx", "net", "W"],
    )


def _rootfinder(name: str, residual: ca.Function) -> ca.Function:
    return ca.rootfinder(
        name,
        "newton",
        residual,
        {"abstol": 1e-10, "max_iter": 60, "error_on_fail": False, "line_search": True, "show_eval_warnings": False},
    )


@locked_cache(maxsize=8)
def steady_turn_function(settings: SteeringSettings = SteeringSettings()) -> ca.Function:
    """Rootfinder ``(z0, [w_l, w_r, c, phi, K, veh...]) -> z = [u, v, Om]`` of the steady motion.

    Residuals (scaled by W and W l): ``X + m v Om = 0``, ``Y - m u Om = 0``, ``N = 0``.
    """
    hf = hull_forces_function(settings)
    z = ca.SX.sym("z", 3)
    p = ca.SX.sym("p", 5 + len(VEHICLE_PARAMS))
    w, so, veh = p[0:2], p[2:5], p[5:]
    m, l = veh[0], veh[1]
    W = m * G
    _, net, _ = hf(z, w, so, z[0] * z[2], veh)
    res = ca.vertcat((net[0] + m * z[1] * z[2]) / W, (net[1] - m * z[0] * z[2]) / W, net[2] / (W * l))
    return _rootfinder("steady_turn", ca.Function("steady_residual", [z, p], [res]))


@locked_cache(maxsize=8)
def motion_inverse_function(settings: SteeringSettings = SteeringSettings()) -> ca.Function:
    """Rootfinder ``(z0, [u, Om, du/dt, dOm/dt, c, phi, K, veh...]) -> z = [w_l, w_r, v]``.

    The sprocket speeds and lateral speed that give the hull a prescribed forward speed and yaw
    rate and their rates (quasi-static in v: dv/dt = 0): ``m (du/dt - v Om) = X``,
    ``m u Om = Y``, ``Iz dOm/dt = N``. The simulator's plant.
    """
    hf = hull_forces_function(settings)
    z = ca.SX.sym("z", 3)
    p = ca.SX.sym("p", 7 + len(VEHICLE_PARAMS))
    u, Om, du, dOm, so, veh = p[0], p[1], p[2], p[3], p[4:7], p[7:]
    m, l, Iz = veh[0], veh[1], veh[7]
    W = m * G
    _, net, _ = hf(ca.vertcat(u, z[2], Om), z[0:2], so, u * Om, veh)
    res = ca.vertcat((net[0] - m * (du - z[2] * Om)) / W, (net[1] - m * u * Om) / W, (net[2] - Iz * dOm) / (W * l))
    return _rootfinder("motion_inverse", ca.Function("motion_residual", [z, p], [res]))


@locked_cache(maxsize=8)
def slip_limited_motion_function(settings: SteeringSettings = SteeringSettings()) -> ca.Function:
    """Rootfinder ``(z0, [u, kappa, s, side, c, phi, K, veh...]) -> z = [w_free, v, a]``: a track at a given slip.

    The hull moves at forward speed ``u`` on a path of curvature ``kappa`` (1/R, + left) with the
    forward acceleration ``a`` (yaw rate ``Om = u kappa``, its rate ``a kappa``) such that track
    ``side`` (0 left, 1 right) runs at the longitudinal slip ``s`` of its centre line: its sprocket
    speed is fixed, ``w = (u - Om y_k) / (r (1 - s))``, and the balances of
    :func:`motion_inverse_function` are solved for the other sprocket's speed, the lateral speed and
    ``a``. With ``s`` the plan's slip limit on the outer track it gives the largest acceleration (and
    torque) at which the outer track stays within the limit; with ``-s`` on the inner track the
    hardest braking at which the inner's skid does. One solve per point instead of a scan over
    accelerations (whose points beyond traction have no solution and cost the rootfinder its
    iteration limit).
    """
    hf = hull_forces_function(settings)
    z = ca.SX.sym("z", 3)
    p = ca.SX.sym("p", 7 + len(VEHICLE_PARAMS))
    u, kappa, s, side, so, veh = p[0], p[1], p[2], p[3], p[4:7], p[7:]
    m, l, B, r, Iz = veh[0], veh[1], veh[3], veh[4], veh[7]
    W = m * G
    Om, a = u * kappa, z[2]
    y_k = 0.5 * B * (1 - 2 * side)  # the fixed track's centre line: +B/2 left, -B/2 right
    w_fixed = (u - Om * y_k) / (r * (1 - s))
    w = ca.vertcat(side * z[0] + (1 - side) * w_fixed, side * w_fixed + (1 - side) * z[0])
    _, net, _ = hf(ca.vertcat(u, z[1], Om), w, so, u * Om, veh)
    res = ca.vertcat((net[0] - m * (a - z[1] * Om)) / W, (net[1] - m * u * Om) / W, (net[2] - Iz * a * kappa) / (W * l))
    return _rootfinder("slip_limited_motion", ca.Function("slip_limited_residual", [z, p], [res]))


@lru_cache(maxsize=8)
def torque_residual_function(settings: SteeringSettings = SteeringSettings()) -> ca.Function:
    """Residuals ``(z = [w_l, w_r, v], p = [u, Om, T_l, T_r, c, phi, K, veh...])`` of :func:`torque_inverse_function`.

    ``[(r F_x,l - T_l) / (W r), (r F_x,r - T_r) / (W r), (Y - m u Om) / W]``.
    """
    hf = hull_forces_function(settings)
    z = ca.SX.sym("z", 3)
    p = ca.SX.sym("p", 7 + len(VEHICLE_PARAMS))
    u, Om, Tl, Tr, so, veh = p[0], p[1], p[2], p[3], p[4:7], p[7:]
    m, r = veh[0], veh[4]
    W = m * G
    Fx, net, _ = hf(ca.vertcat(u, z[2], Om), z[0:2], so, u * Om, veh)
    res = ca.vertcat((r * Fx[0] - Tl) / (W * r), (r * Fx[1] - Tr) / (W * r), (net[1] - m * u * Om) / W)
    return ca.Function("torque_residual", [z, p], [res])


@locked_cache(maxsize=8)
def torque_inverse_function(settings: SteeringSettings = SteeringSettings()) -> ca.Function:
    """Rootfinder ``(z0, [u, Om, T_l, T_r, c, phi, K, veh...]) -> z = [w_l, w_r, v]``.

    The sprocket speeds and lateral speed at which each track's shear gives the measured
    sprocket torque (``r F_x,k = T_k``, the sprocket inertia's share already taken off) and the
    lateral force balance holds (``m u Om = Y``, quasi-static in v): what a drive log's
    encoders should read, given its torques, vehicle speed and yaw rate. The fit's model.
    """
    return _rootfinder("torque_inverse", torque_residual_function(settings))


@dataclass(frozen=True)
class SteadyTurn:
    """A steady motion under constant sprocket speeds (:func:`steady_turn`), SI, signed (+ left).

    Attributes
    ----------
    converged
        The rootfinder's residual is below 1e-8 (scaled) and both tracks keep a positive load (no
        tipping); when False the numbers are not an answer.
    forward_speed, lateral_speed, yaw_rate
        u, v (m/s) at the centre, Om (rad/s).
    radius
        Turning radius of the centre's path ``sqrt(u^2 + v^2) / Om`` (m, signed; ``inf`` going straight).
    kinematic_radius
        Radius without slip ``(B/2)(w_r + w_l)/(w_r - w_l)``.
    slip_left, slip_right
        Longitudinal slip of each track's centre line, ``1 - (u -+ Om B/2) / (r w_k)`` (negative: skid).
    icr_shift_left, icr_shift_right
        Lateral position of each track's instantaneous centre of rotation relative to its centre
        line, m (``(u - r w_k)/Om - y_k``; None going straight).
    icr_longitudinal
        Longitudinal shift of the instantaneous centres ``-v / Om``, m (+ forward; None going straight).
    torque_left, torque_right
        Sprocket torques ``r F_x,k``, N m.
    load_left, load_right
        Normal loads of the tracks, N.
    sideslip_deg
        Sideslip angle of the centre ``atan2(v, u)``, deg: a few degrees in an ordinary turn; tens
        of degrees when the lateral acceleration approaches what the soil can hold (the vehicle
        slides out of the turn and its radius falls below the kinematic one).
    lateral_accel
        Centripetal acceleration ``u Om``, m/s^2 (the load transfer's).
    """

    converged: bool
    forward_speed: float
    lateral_speed: float
    yaw_rate: float
    radius: float
    kinematic_radius: float
    slip_left: float
    slip_right: float
    icr_shift_left: float | None
    icr_shift_right: float | None
    icr_longitudinal: float | None
    torque_left: float
    torque_right: float
    load_left: float
    load_right: float
    sideslip_deg: float
    lateral_accel: float


def _soil_vector(soil: Soil) -> list[float]:
    if not isinstance(soil, Soil):
        raise DataError(f"soil must be a Soil, got {type(soil).__name__}")
    return [soil.cohesion, soil.friction_angle, soil.shear_modulus]


def steady_turn(
    w_left: float, w_right: float, soil: Soil, vehicle: Vehicle, *, settings: SteeringSettings = SteeringSettings()
) -> SteadyTurn:
    """The steady motion under constant sprocket speeds ``w_left``, ``w_right`` (rad/s, both > 0).

    Solves the three steady balances (longitudinal, lateral, yaw) for u, v, Om with a cached
    CasADi Newton rootfinder; the start is the kinematic motion with a slip-reduced yaw rate.
    """
    veh = vehicle_parameters(vehicle)
    if not (math.isfinite(w_left) and math.isfinite(w_right)):
        raise DataError(f"sprocket speeds must be finite, got {w_left!r}, {w_right!r}")
    if w_left <= 0 or w_right <= 0:
        raise DataError(
            f"sprocket speeds {w_left:g}, {w_right:g} rad/s: a stopped or counter-rotating track (a pivot turn, "
            "radius at most half the tread) is outside the steering model (its contact time and shear "
            "displacement assume a belt running rearwards under the hull); both must be > 0"
        )
    r, B = vehicle.sprocket_radius, tread_of(vehicle)
    z0 = [0.5 * r * (w_left + w_right), 0.0, 0.6 * r * (w_right - w_left) / B]
    p = np.concatenate([[w_left, w_right], _soil_vector(soil), veh])
    z, _ = call_solver(steady_turn_function(settings), z0, p)
    z = np.asarray(z, dtype=float).ravel()
    return _steady_result(z, p, w_left, w_right, vehicle, settings)


def _steady_result(z, p, wl, wr, vehicle: Vehicle, settings: SteeringSettings) -> SteadyTurn:
    u, v, Om = (float(a) for a in z)
    hf = hull_forces_function(settings)
    Fx, net, W = (np.asarray(a, dtype=float).ravel() for a in hf(z, p[0:2], p[2:5], u * Om, p[5:]))
    scale = vehicle.weight
    res = np.array([(net[0] + vehicle.mass * v * Om) / scale, (net[1] - vehicle.mass * u * Om) / scale])
    res = np.append(res, net[2] / (scale * vehicle.track_length))
    ok = bool(np.all(np.isfinite(z)) and np.max(np.abs(res)) < 1e-8 and np.min(W) > 0)  # W <= 0: tipping
    r, B = vehicle.sprocket_radius, tread_of(vehicle)
    turning = abs(Om) > 1e-12
    return SteadyTurn(
        converged=ok,
        forward_speed=u,
        lateral_speed=v,
        yaw_rate=Om,
        radius=math.hypot(u, v) / Om if turning else math.inf,
        kinematic_radius=float(kinematic_radius(wl, wr, B)),
        slip_left=1 - (u - Om * B / 2) / (r * wl),
        slip_right=1 - (u + Om * B / 2) / (r * wr),
        icr_shift_left=(u - r * wl) / Om - B / 2 if turning else None,
        icr_shift_right=(u - r * wr) / Om + B / 2 if turning else None,
        icr_longitudinal=-v / Om if turning else None,
        torque_left=r * float(Fx[0]),
        torque_right=r * float(Fx[1]),
        load_left=float(W[0]),
        load_right=float(W[1]),
        sideslip_deg=math.degrees(math.atan2(v, u)),
        lateral_accel=u * Om,
    )
