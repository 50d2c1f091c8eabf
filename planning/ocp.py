"""The speed/slip/torque optimal-control problem: direct collocation, built once per size.

Formulation (time-domain direct collocation on a mesh fixed in DISTANCE, so that every patch
boundary is a mesh point):

- states ``x = [v, w]`` (vehicle speed, sprocket speed) at the mesh points and at ``d = 3``
  Radau IIA collocation points inside every interval (L-stable, order 5: the stiff slip
  dynamics are integrated implicitly, never with an explicit step);
- the sprocket torque ``M_k`` is held over each interval (zero-order hold);
- the interval durations ``dt_k`` are free; each interval's length is fixed,
  ``dt_k sum_j B_j v_kj = h_k`` (the collocation quadrature of ``ds/dt = v``, exact for the
  polynomial), so the patch boundaries are mesh points; the total time is ``sum(dt_k)``;
- dynamics: :func:`soiltrack.soilmodel.dynamics.dynamics_expr` itself (Eqs. 1, 4, the
  thrust-balance sprocket equation; grade as the ``grade`` effect) plus the patch's Bekker
  compaction resistance;
- limits at the mesh and collocation points: slip ``|i| <= i_b`` (per interval) written as the
  linear ``(1 - i_b) r w <= v <= (1 + i_b) r w``; ``|M| <= T_max``; ``M w <= P_max``; optional
  torque rate ``|M_{k+1} - M_k| <= rate (dt_k + dt_{k+1}) / 2``;
- objective: time ``sum(dt_k)`` or the sprocket's positive work ``sum(max(0, M_k integral(w dt)))``
  (braking energy is not recovered; slack variables ``e_k >= 0, e_k >= M_k integral(w dt)``
  keep it smooth; the quadrature is exact for the collocation polynomial);
- with a duration instead of a distance, the intervals are of equal time ``T / n`` and the
  distance is free;
- turning intervals (``OcpData.turn``, a patch with ``radius_m``; the problem is built with the
  turn rows only when some interval turns, so straight plans are the same NLP as before): the
  steering model's turn at that radius (:mod:`.route_turns`) enters as polynomials in the
  speed, ``dR(v) = a0 + a2 v^2 + a4 v^4`` (the extra longitudinal resistance of the steady turn:
  the centripetal force's sideslip and load transfer; added to the compaction resistance in the
  dynamics), and in the speed and the forward acceleration ``a`` (the dynamics' ``dv/dt`` at the
  point with the interval's torque), ``dT(v, a) = d(v) + a d1(v) + a^2 d2(v)`` (half the
  difference of the outer and inner sprocket torques, from the yaw moment balance; each ``d`` in
  ``[1, v^2, v^4]``) and the sideslip's tangent ``t(v, a)`` likewise: at every point
  ``|t| + err <= tan(MAX_SIDESLIP_DEG)`` (the accelerating turn's sideslip, its fit's largest error
  ``err`` to the safe side). The start node of the interval after a turn carries that turn's rows
  with this interval's acceleration (the after-solve check turns there). At every point the outer
  sprocket's torque ``M/2 + dT`` is at most ``T_max/2`` and the inner's ``M/2 - dT`` at least ``-T_max/2`` (each
  sprocket carries half the drivetrain's limit), the outer sprocket's power
  ``(M/2 + dT) w (1 + e)`` and the driving power of both ``M w + 2 dT e w`` at most ``P_max``
  (``e = B / (2 |R|)``, kinematic sprocket-speed ratio; the inner track's braking power is not
  recovered), the outer sprocket's torque at most ``o(v)`` and the inner's at least ``i(v)``
  (polynomials too: where the outer track's slip reaches the plan's limit accelerating and the
  inner's skid braking, by the steering model), and the speed at most the turn's steady speed
  limit (``OcpData.speed_cap``: above it the steady turn breaks a limit - sideslip, outer slip, no
  steady motion, a sprocket's torque or the power).

All data enter as parameters (soil, grade and compaction per interval, mesh distances,
limits, weights), so one ``nlpsol`` (IPOPT) is built per (vehicle, n, objective, torque-rate
limit on/off) and re-solved; the previous solution of the same structure warm-starts the next.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from ..soilmodel import Vehicle
from ..soilmodel.dynamics import dynamics_expr
from ..soilmodel.threadsafe import SOLVER_LOCK, call_solver, locked_cache, solver_status
from .turning import MAX_SIDESLIP_DEG

__all__ = [
    "OcpData",
    "solve_ocp",
    "ocp_solver",
    "ocp_nlp",
    "ocp_layout",
    "IPOPT_OPTIONS",
    "WARM_OPTIONS",
    "clear_warm_starts",
    "DEGREE",
    "radau_collocation",
    "TURN_ROWS",
]

#: Collocation points per interval (Radau IIA).
DEGREE = 3
#: Rows of ``OcpData.turn`` (:meth:`~.route_turns.TurnTerms.column`: the turn-resistance, torque-split,
#: slip-limited torque and sideslip coefficients, ``B / 2|R|`` and the sideslip fit's error).
TURN_ROWS = 29
#: Turn rows per point (outer and inner torque, outer and driving power, the two slip-limited torques, the
#: sideslip from above and from below).
TURN_POINT_ROWS = 8
#: Lower bound of the sprocket speed while moving, rad/s (the slip limit's linear form needs w > 0).
MIN_SPROCKET_SPEED = 1e-4
#: IPOPT options of every profile solve.
IPOPT_OPTIONS = {
    "print_level": 0,
    "sb": "yes",
    "max_iter": 1000,
    "tol": 1e-8,
    "acceptable_tol": 1e-6,
    "constr_viol_tol": 1e-8,
}
#: Warm-start options, tuned on the benchmark profile (IPOPT iterations for a new v1 / a new soil:
#: 13 / 22-65 with mu_init 1e-6 and pushes 1e-9; 5-6 / 20-24 with these).
WARM_OPTIONS = {
    "warm_start_init_point": "yes",
    "warm_start_bound_push": 1e-6,
    "warm_start_mult_bound_push": 1e-6,
    "warm_start_slack_bound_push": 1e-6,
    "mu_init": 1e-8,
}


@dataclass(frozen=True)
class OcpData:
    """Numbers of one OCP instance (SI; per-interval arrays of length n, ``s`` of length n + 1)."""

    c: np.ndarray
    phi: np.ndarray
    K: np.ndarray
    grade: np.ndarray  # rad
    Rc: np.ndarray  # compaction resistance, N
    slip_bound: np.ndarray  # |slip| bound used by the plan, per interval
    s: np.ndarray  # mesh distances (a start guess only when the distance is free)
    v0: float
    v1: float
    distance: float | None
    duration: float | None
    max_torque: float
    max_power: float | None
    max_slip: float
    torque_rate: float | None
    objective: str
    v_guess: np.ndarray | None = None  # start guess of the node speeds (None: linear in distance)
    w0: float | None = None  # initial sprocket speed, rad/s (None: free within the slip limit)
    max_speed: float | None = None  # speed limit at the mesh and collocation points, m/s
    mu_s: np.ndarray | None = None  # fitted slip_sinkage coefficient per interval (None: 0, the nominal model)
    turn: np.ndarray | None = None  # (TURN_ROWS, n): TurnTerms.column() per interval (None: no turn; zeros: straight)
    speed_cap: np.ndarray | None = None  # speed limit per interval, m/s (a turn's steady limit; None: none)


@locked_cache(maxsize=8)
def dynamics_fn(vehicle: Vehicle) -> ca.Function:
    """``f(x=[v, w], M, p=[c, phi, K, grade, R_c, mu_s]) -> (xdot, slip, thrust)`` from the model core
    (``mu_s``: the ``slip_sinkage`` effect's coefficient, 0 for the nominal model)."""
    x = ca.SX.sym("x", 2)
    M = ca.SX.sym("M")
    p = ca.SX.sym("p", 6)
    eff = {"grade": {"theta_rad": p[3]}, "slip_sinkage": {"mu_s": p[5]}}
    d = dynamics_expr(x[0], x[1], M, p[0], p[1], p[2], vehicle, eff)
    xdot = ca.vertcat(d["dv"] - p[4] / vehicle.mass, d["dw"])
    return ca.Function(
        "plan_dynamics", [x, M, p], [xdot, d["slip"], d["thrust"]], ["x", "M", "p"], ["xdot", "slip", "thrust"]
    )


@lru_cache(maxsize=8)
def radau_collocation(d: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Radau IIA collocation of degree ``d`` on [0, 1]: points ``tau`` (with 0 first), the derivative
    matrix ``C`` of the Lagrange basis at the points, and the quadrature weights ``B``."""
    tau = np.append(0.0, ca.collocation_points(d, "radau"))
    C = np.zeros((d + 1, d + 1))  # derivative of the Lagrange basis at the collocation points
    B = np.zeros(d + 1)  # quadrature weights
    for j in range(d + 1):
        coeff = np.poly1d([1.0])
        for r in range(d + 1):
            if r != j:
                coeff *= np.poly1d([1.0, -tau[r]]) / (tau[j] - tau[r])
        der = np.polyder(coeff)
        for r in range(d + 1):
            C[j, r] = der(tau[r])
        B[j] = np.polyint(coeff)(1.0)
    return tau, C, B


def ocp_layout(n: int, energy: bool) -> tuple[slice, slice, slice, slice, slice | None]:
    """Index blocks of the decision vector of :func:`ocp_nlp`: nodes X (2(n+1), column-major),
    collocation states Z (2 d n), held torques u, interval durations dt (n each) and, for the energy
    objective, the work slacks e (n; ``None`` otherwise)."""
    nx = 2 * (n + 1)
    nz = 2 * DEGREE * n
    a = nx + nz
    return (
        slice(0, nx),
        slice(nx, a),
        slice(a, a + n),
        slice(a + n, a + 2 * n),
        slice(a + 2 * n, a + 3 * n) if energy else None,
    )


@locked_cache(maxsize=16)
def ocp_nlp(vehicle: Vehicle, n: int, energy: bool = False, rate_limit: bool = False, turns: bool = False) -> dict:
    """The OCP with ``n`` intervals as an SX NLP ``{"x", "p", "f", "g"}`` (the layout of :func:`ocp_layout`).

    Cached: the cold and the warm-start solver of one structure share it (built once; do not modify it).

    ``energy``: energy objective (work slacks), else minimum time; ``rate_limit``: with the
    torque-rate rows; ``turns``: with the turn terms and rows (module docstring; :data:`TURN_ROWS`
    more parameter rows per interval, four rows per point after the power rows). Only the rows a
    problem needs are built; the last row of ``g`` is the total time.
    """
    f = dynamics_fn(vehicle)
    d = DEGREE
    tau, C, B = radau_collocation(d)
    r = vehicle.sprocket_radius
    X = ca.SX.sym("X", 2, n + 1)
    Z = ca.SX.sym("Z", 2, d * n)
    u = ca.SX.sym("u", n)
    dt = ca.SX.sym("dt", n)
    e = ca.SX.sym("e", n)  # positive work per interval (slack)
    P = ca.SX.sym("P", 8 + (TURN_ROWS if turns else 0), n)  # c, phi, K, grade, R_c, mu_s, slip bound, length, turn
    Ms, Pw, rate, wt, we, ts, es, vs, ws = (
        ca.SX.sym(s) for s in ("Ms", "Pw", "rate", "wt", "we", "ts", "es", "vs", "ws")
    )
    xs = ca.vertcat(vs, ws)  # state scales
    g_dyn, g_slip_lo, g_slip_hi, g_pow, g_dist, g_turn = [], [], [], [], [], []
    J_time = ca.sum1(dt)
    g_work = []
    for k in range(n):
        Mk = u[k] * Ms
        pts = [X[:, k]] + [Z[:, k * d + j] for j in range(d)]
        w_int = 0
        v_int = 0
        acc = [f(pts[0], Mk, _point_params(P, k, pts[0][0]))[0][0]] if turns else []  # dv/dt at the start
        for j in range(1, d + 1):
            xp = sum(C[q, j] * pts[q] for q in range(d + 1))
            pk = _point_params(P, k, pts[j][0]) if turns else P[:6, k]
            fj = f(pts[j], Mk, pk)[0]
            acc.append(fj[0])
            g_dyn.append((xp - dt[k] * fj) / xs)
            w_int += B[j] * pts[j][1]
            v_int += B[j] * pts[j][0]
        g_dyn.append((pts[d] - X[:, k + 1]) / xs)  # Radau: the last collocation point is the interval's end
        g_work.append((e[k] - Mk * dt[k] * w_int) / es)
        g_dist.append(dt[k] * v_int / P[7, k] - 1.0)
        for q in range(d + 1):
            v_, w_ = pts[q][0], pts[q][1]
            g_slip_lo.append((v_ - (1 - P[6, k]) * r * w_) / vs)
            g_slip_hi.append(((1 + P[6, k]) * r * w_ - v_) / vs)
            g_pow.append((Mk * w_) / Pw)
            if turns:  # the start node of an interval after a turn ends it: that turn's rows, this interval's dv/dt
                tk = P[8:, k] if q > 0 or k == 0 else ca.if_else(P[14, k] > 0, P[8:, k], P[8:, k - 1])
                g_turn += _turn_rows(tk, Mk, v_, w_, acc[q], Ms, Pw)
    dM = u[1:] - u[:-1]
    avg_dt = 0.5 * (dt[1:] + dt[:-1])
    rows = [*g_dyn, *g_dist] + (g_work if energy else []) + [*g_slip_lo, *g_slip_hi, *g_pow, *g_turn]
    if rate_limit:
        rows += [dM - rate * avg_dt / Ms, -dM - rate * avg_dt / Ms]
    g = ca.vertcat(*rows, J_time)
    J = we * ca.sum1(e) / es if energy else wt * J_time / ts
    x = ca.vertcat(ca.vec(X), ca.vec(Z), u, dt, e) if energy else ca.vertcat(ca.vec(X), ca.vec(Z), u, dt)
    p = ca.vertcat(ca.vec(P), Ms, Pw, rate, wt, we, ts, es, vs, ws)
    return {"x": x, "p": p, "f": J, "g": g}


def _poly(a, v):
    """``a0 + a2 v^2 + a4 v^4`` (the turn terms' polynomial in the speed)."""
    v2 = v * v
    return a[0] + v2 * (a[1] + v2 * a[2])


def _point_params(P, k: int, v):
    """Interval k's dynamics parameters at a point of speed v: the turn's extra resistance ``dR(v)`` added to
    the compaction resistance."""
    return ca.vertcat(P[:4, k], P[4, k] + _poly(P[8:11, k], v), P[5, k])


def _turn_rows(t, M, v, w, a, Ms, Pw) -> list:
    """The :data:`TURN_POINT_ROWS` turn rows at one point of speed v, sprocket speed w and acceleration a
    (``t``: the interval's turn column, :meth:`~.route_turns.TurnTerms.column`).

    ``dT(v, a)`` and the sideslip's ``tan`` ``t0(v) + a t1(v) + a^2 t2(v)`` (shifted by its fit's error
    both ways), scaled by ``tan`` of :data:`~.turning.MAX_SIDESLIP_DEG`; the acceleration is the dynamics'
    ``dv/dt`` at the point with the interval's torque.
    """
    dT = _poly(t[3:6], v) + a * (_poly(t[13:16], v) + a * _poly(t[16:19], v))
    e_ = t[6]
    tan_b = _poly(t[19:22], v) + a * (_poly(t[22:25], v) + a * _poly(t[25:28], v))
    tmax = math.tan(math.radians(MAX_SIDESLIP_DEG))
    return [
        (M + 2 * dT) / Ms,
        (M - 2 * dT) / Ms,
        (0.5 * M + dT) * w * (1 + e_) / Pw,
        (M + 2 * dT * e_) * w / Pw,
        (0.5 * M + dT - _poly(t[7:10], v)) / Ms,
        (0.5 * M - dT - _poly(t[10:13], v)) / Ms,
        (tan_b + t[28]) / tmax,
        (tan_b - t[28]) / tmax,
    ]


@locked_cache(maxsize=32)
def ocp_solver(
    vehicle: Vehicle, n: int, warm: bool, energy: bool = False, rate_limit: bool = False, turns: bool = False
) -> ca.Function:
    """The cached IPOPT solver of the OCP with ``n`` intervals (:func:`ocp_nlp`).

    ``warm``: warm-start options; ``energy``: energy objective (work slacks), else minimum time;
    ``rate_limit``: with the torque-rate rows; ``turns``: with the turn terms and rows.
    """
    opts: dict[str, Any] = {
        "ipopt": dict(IPOPT_OPTIONS, **(WARM_OPTIONS if warm else {})),
        "print_time": False,
        "error_on_fail": False,
    }
    return ca.nlpsol(f"speed_ocp_{n}", "ipopt", ocp_nlp(vehicle, n, energy, rate_limit, turns), opts)


_last: dict = {}


def _guess(d: OcpData, vehicle: Vehicle, n: int, slip_of_thrust) -> np.ndarray:
    """A consistent start: speed linear in distance, slip from the steady thrust, torque from the balance."""
    m, r, I = vehicle.mass, vehicle.sprocket_radius, vehicle.sprocket_inertia
    f = dynamics_fn(vehicle)
    S = d.s
    L = S[-1]
    vmid = max(d.v0, d.v1, 0.5)
    v = d.v0 + (d.v1 - d.v0) * S / L if d.v_guess is None else np.asarray(d.v_guess, dtype=float).copy()
    v = np.maximum(v, 0.3 * vmid)
    v[0], v[-1] = d.v0, d.v1
    h = np.diff(S)
    a = (v[1:] ** 2 - v[:-1] ** 2) / (2 * h)
    mu = np.zeros(n) if d.mu_s is None else np.asarray(d.mu_s, dtype=float)
    R = (
        np.array(
            [
                float(f(ca.DM([r, 1.0]), 0.0, [d.c[k], d.phi[k], d.K[k], d.grade[k], d.Rc[k], mu[k]])[0][0])
                for k in range(n)
            ]
        )
        * -m
    )  # resistance from the model core (rest of the slip: 0)
    Freq = m * a + R
    i = np.clip(slip_of_thrust(Freq), -0.9 * d.slip_bound, 0.9 * d.slip_bound)
    M = np.clip(r * Freq + I * a / (r * (1 - i)), -0.95 * d.max_torque, 0.95 * d.max_torque)
    inode = np.append(i, i[-1])
    w = np.maximum(v, 1e-3) / (r * (1 - inode))
    X = np.vstack([v, w])
    tau = np.append(0.0, ca.collocation_points(DEGREE, "radau"))
    Z = np.zeros((2, DEGREE * n))
    for k in range(n):
        for j in range(DEGREE):
            t = tau[j + 1]
            Z[:, k * DEGREE + j] = (1 - t) * X[:, k] + t * X[:, k + 1]
    dt = 2 * h / np.maximum(v[1:] + v[:-1], 1e-3) if d.duration is None else np.full(n, d.duration / n)
    out = [X.ravel(order="F"), Z.ravel(order="F"), M / d.max_torque, dt]
    if d.objective == "energy":
        out.append(np.maximum(M * h / (r * (1 - i)), 0.0))
    return np.concatenate(out)


def _cap_speeds(cap: np.ndarray, Xu: np.ndarray, Zu: np.ndarray) -> None:
    """Speed bounds (in place) from a per-interval limit: its collocation points and both its nodes."""
    Zu[0] = np.minimum(Zu[0], np.repeat(cap, DEGREE))
    Xu[0, :-1] = np.minimum(Xu[0, :-1], cap)
    Xu[0, 1:] = np.minimum(Xu[0, 1:], cap)


def _turn_row_bounds(d: OcpData, n: int, npt: int) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of the turn rows (:data:`TURN_POINT_ROWS` per point: outer torque, inner torque, outer power,
    driving power, the outer torque at its slip limit, the inner at its skid limit, the sideslip from above
    and from below); a straight interval's rows are free (they would repeat the torque bound and the power row)."""
    turning = np.asarray(d.turn, dtype=float)[6] > 0
    at = np.repeat(turning[:, None], DEGREE + 1, axis=1)
    at[1:, 0] |= turning[:-1]  # an interval's start node ends the turn before it (the after-solve check's node)
    on = np.repeat(at.ravel(), TURN_POINT_ROWS)
    pw = 1.0 if d.max_power else np.inf
    lo = np.tile([-np.inf, -1.0, -np.inf, -np.inf, -np.inf, 0.0, -np.inf, -1.0], npt)
    hi = np.tile([1.0, np.inf, pw, pw, 0.0, np.inf, 1.0, np.inf], npt)
    return np.where(on, lo, -np.inf), np.where(on, hi, np.inf)


def solve_ocp(d: OcpData, vehicle: Vehicle, slip_of_thrust, warm_store: dict | None = None) -> dict:
    """Solve one instance; the raw solution, IPOPT's status, iterations and wall time.

    ``slip_of_thrust(F_array) -> slip_array`` gives the start guess of the slip (cold starts).
    ``warm_store``: where the solution is kept for the next warm start (default: one store per
    problem structure, shared by every caller in the process; a :class:`~.replan.Replanner`
    keeps its own).
    """
    n = len(d.c)
    energy, rate_on, turns = d.objective == "energy", bool(d.torque_rate), d.turn is not None
    iX, iZ, iu, idt, ie = ocp_layout(n, energy)
    key = (vehicle, n, energy, rate_on, turns)
    store = _last if warm_store is None else warm_store
    prev = store.get(key)
    r = vehicle.sprocket_radius
    inf = np.inf
    Ms = d.max_torque
    Pw = d.max_power if d.max_power else 1.0
    L = float(d.s[-1])
    vmax = max(d.v0, d.v1, 0.1)
    ts = (L / vmax) if d.duration is None else d.duration
    es = vehicle.weight * L * 0.1 + 0.5 * vehicle.mass * vmax**2
    wt, we = (1.0, 0.0) if d.objective == "time" else (0.0, 1.0)
    mu_s = np.zeros(len(d.c)) if d.mu_s is None else np.asarray(d.mu_s, dtype=float)
    Pmat = np.vstack([d.c, d.phi, d.K, d.grade, d.Rc, mu_s, d.slip_bound, np.diff(d.s)])
    if turns:
        Pmat = np.vstack([Pmat, np.asarray(d.turn, dtype=float).reshape(TURN_ROWS, n)])
    p = np.concatenate([Pmat.ravel(order="F"), [Ms, Pw, d.torque_rate or 0.0, wt, we, ts, es, vmax, vmax / r]])
    nxv = 2 * (n + 1) + 2 * DEGREE * n + (3 if energy else 2) * n
    lbx, ubx = np.full(nxv, -inf), np.full(nxv, inf)
    Xl, Xu = np.full((2, n + 1), -inf), np.full((2, n + 1), inf)
    Xl[0], Xl[1] = 0.0, MIN_SPROCKET_SPEED
    Zl, Zu = np.full((2, DEGREE * n), -inf), np.full((2, DEGREE * n), inf)
    Zl[0], Zl[1] = 0.0, MIN_SPROCKET_SPEED
    if d.max_speed is not None:
        Xu[0], Zu[0] = d.max_speed, d.max_speed
    if d.speed_cap is not None:
        _cap_speeds(np.asarray(d.speed_cap, dtype=float), Xu, Zu)
    Xl[0, 0] = Xu[0, 0] = d.v0
    Xl[0, -1] = Xu[0, -1] = d.v1
    if d.w0 is not None:  # the initial state is given: speed and sprocket speed (its slip)
        Xl[1, 0] = Xu[1, 0] = d.w0
    if d.v1 == 0.0:  # stopping: the sprocket stops with the vehicle (slip limit at v = 0)
        Xl[1, -1] = Zl[1, -1] = 0.0
    free_dist = d.distance is None
    lbx[iX], ubx[iX] = Xl.ravel(order="F"), Xu.ravel(order="F")
    lbx[iZ], ubx[iZ] = Zl.ravel(order="F"), Zu.ravel(order="F")
    lbx[iu], ubx[iu] = -1.0, 1.0
    lbx[idt], ubx[idt] = 1e-5, inf
    if d.duration is not None:  # equal time steps, free distance
        lbx[idt] = ubx[idt] = d.duration / n
    if energy:
        lbx[ie], ubx[ie] = 0.0, inf
    npt = n * (DEGREE + 1)
    ndyn = n * 2 * (DEGREE + 1)
    dist_lo = np.full(n, -inf) if free_dist else np.zeros(n)
    dist_hi = np.full(n, inf) if free_dist else np.zeros(n)
    lbg_parts: list[Any] = (
        [np.zeros(ndyn), dist_lo] + ([np.zeros(n)] if energy else []) + [np.zeros(2 * npt), np.full(npt, -inf)]
    )
    ubg_parts: list[Any] = (
        [np.zeros(ndyn), dist_hi]
        + ([np.full(n, inf)] if energy else [])
        + [np.full(2 * npt, inf), np.full(npt, 1.0 if d.max_power else inf)]
    )
    if turns:
        lo_t, hi_t = _turn_row_bounds(d, n, npt)
        lbg_parts.append(lo_t)
        ubg_parts.append(hi_t)
    if rate_on:
        lbg_parts.append(np.full(2 * (n - 1), -inf))
        ubg_parts.append(np.zeros(2 * (n - 1)))
    lbg_parts.append([d.duration if d.duration is not None else -inf])
    ubg_parts.append([d.duration if d.duration is not None else inf])
    lbg, ubg = np.concatenate(lbg_parts), np.concatenate(ubg_parts)
    args = dict(p=p, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    warm = prev is not None
    solver = ocp_solver(vehicle, n, warm, energy, rate_on, turns)  # built once per structure; not solve time
    t0 = time.perf_counter()
    if prev is not None:  # warm
        args.update(x0=np.clip(prev["x"], lbx, ubx), lam_x0=prev["lam_x"], lam_g0=prev["lam_g"])
    else:
        args["x0"] = np.clip(_guess(d, vehicle, n, slip_of_thrust), lbx, ubx)
    out, stats = call_solver(solver, **args)
    status, iterations, ok = solver_status(stats)
    if not ok and warm:  # a poor warm start: retry cold once
        warm = False
        args = dict(
            p=p, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg, x0=np.clip(_guess(d, vehicle, n, slip_of_thrust), lbx, ubx)
        )
        t_b = time.perf_counter()
        cold = ocp_solver(vehicle, n, False, energy, rate_on, turns)
        t0 += time.perf_counter() - t_b  # the build (if any) is not solve time
        out, stats = call_solver(cold, **args)
        status, iterations, ok = solver_status(stats)
    elapsed = time.perf_counter() - t0
    x = np.asarray(out["x"], dtype=float).ravel()
    if ok and np.all(np.isfinite(x)):
        with SOLVER_LOCK:
            store[key] = {"x": x, "lam_x": np.asarray(out["lam_x"]).ravel(), "lam_g": np.asarray(out["lam_g"]).ravel()}
    X = x[iX].reshape((2, n + 1), order="F")
    Z = x[iZ].reshape((2, DEGREE * n), order="F")
    _tau, _C, B = radau_collocation(DEGREE)
    h = x[idt] * (Z[0].reshape(n, DEGREE) @ B[1:])
    return {
        "x": x,
        "v": X[0],
        "w": X[1],
        "s": np.concatenate([[0.0], np.cumsum(h)]),
        "Z": Z,
        "M": x[iu] * Ms,
        "dt": x[idt],
        "success": ok,
        "status": status,
        "iterations": iterations,
        "solve_time": elapsed,
        "warm": warm,
    }


def clear_warm_starts() -> None:
    """Forget the stored solutions (the next solve of each size starts cold)."""
    with SOLVER_LOCK:
        _last.clear()
