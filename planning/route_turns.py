"""Turns on routes: left and right sprocket torques through patches with ``radius_m`` (the steering model).

A ROUTE.json patch may carry ``radius_m`` (signed, positive to the left; a turn of constant radius
over the patch's length). Before the solve, :func:`turn_terms` turns the steering model at that
radius into the optimiser's terms (:mod:`.ocp`): the turn's steady speed limit (the largest speed
at which it breaks no limit of :func:`~.turning.classify_turn`), its extra longitudinal resistance
as a polynomial in the speed, the outer and inner sprockets' slip-limited torques (accelerating and
braking, each solved directly by
:func:`~soiltrack.soilmodel.steering.slip_limited_motion_function`), and, from the accelerating
turns between those limits, half the outer-minus-inner torque (the yaw moment balance) and the
sideslip as polynomials in the speed and the forward acceleration. A turn that no speed holds, or
whose limit is below v0/v1 at the route's ends, is refused before the solver with the limit named.
After the solve :func:`plan_turns` solves, at every mesh
point of a turning patch, the hull motion the plan prescribes - forward speed ``u``, its rate
``du/dt`` (central differences of the plan's speeds over its times), yaw rate ``u / R`` and its rate
``(du/dt) / R`` - with the steering model (:func:`~.turning.motion_points`: both sprockets' speeds
and torques, the lateral speed) and checks it against the same limits: the optimiser's terms are
fits (their largest errors are stated and, for the sideslip and the slip-limited torques, shifted
to the safe side), so this check has the last word; a turn that breaks a limit makes the plan infeasible,
naming the patch, the limit and the mesh point.

Straight routes are the same problem as before (the turn rows are built only when a patch turns).
In a turn the plan's ``sprocket_torque_Nm`` is the optimiser's total (it carries the turn's extra
resistance); the turn's own torques are the ``torque_left_Nm``/``torque_right_Nm`` series of the
steering model, and ``turns`` summarises each turning patch. Flat turns only (the steering model
has no grade); the Bekker compaction resistance is not in the steering model (its motion
resistance is ``mu_r W`` per track).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..soilmodel import DataError, Vehicle
from ..soilmodel.steering import SteeringSettings, slip_limited_motion_function, tread_of, vehicle_parameters
from ..soilmodel.threadsafe import call_solver, locked_cache
from .margin import resolve_terrain, terrain_soil_vector
from .turning import classify_turn, motion_points

__all__ = [
    "check_turns",
    "plan_turns",
    "turn_line",
    "turn_terms",
    "TurnTerms",
    "TURN_SERIES",
    "MIN_TURN_SPEED",
    "TURN_SPEED_TOP",
]

#: Series a plan with turns adds (equal length to the others; straight points: half the plan's torque each).
TURN_SERIES = ("torque_left_Nm", "torque_right_Nm", "slip_left", "slip_right", "radius_m")
#: Below this speed (m/s) a mesh point of a turning patch is not turned (a turn at standstill is a pivot).
MIN_TURN_SPEED = 0.05
#: Highest speed (m/s) at which the turn terms of the optimiser are computed: a turn's speed limit
#: when the steady turn holds all the way (the polynomials are not extrapolated beyond it).
TURN_SPEED_TOP = 15.0
#: Speeds of the first scan for a turn's steady speed limit (geometric from MIN_TURN_SPEED to the top).
CAP_SCAN = 32
#: Rounds refining the speed limit between two scanned speeds, FIT_POINTS speeds each (the scan's step
#: of 20 % divided by 17 per round: a resolution of 0.07 % after two).
CAP_REFINE = 2
#: Steady turns the turn terms' polynomials are fitted to (evenly in speed up to the limit).
FIT_POINTS = 16
#: Fractions of the slip-limited acceleration (positive) and braking (negative) at which, at every fitted speed,
#: the accelerating turn is solved for the acceleration-dependent fits (the torque split and the sideslip).
ACCEL_FRACTIONS = (-1.0, -0.5, 0.0, 0.5, 1.0)


@dataclass(frozen=True)
class TurnTerms:
    """What the optimiser knows of one turning patch (:func:`turn_terms`), SI.

    Attributes
    ----------
    radius_m
        The patch's radius (signed, + left).
    speed_cap
        The steady turn's speed limit (the largest speed at which it breaks no limit), m/s; 0 when
        it breaks one even at :data:`MIN_TURN_SPEED`.
    cap_limit, cap_reason
        The limit the steady turn breaks just above ``speed_cap`` (``soil``, ``torque``, ``power``)
        and why; ``None`` when the cap is :data:`TURN_SPEED_TOP`.
    resistance, split
        Coefficients ``[a0, a2, a4]`` of the extra longitudinal resistance ``dR(v)`` (N) and
        ``[d0, d2, d4]`` of half the outer-minus-inner sprocket torque ``dT(v)`` (N m).
    fit_error_N, fit_error_Nm
        Largest error of the two polynomials at the fitted steady turns (N, N m).
    e
        ``B / (2 |R|)`` (the kinematic sprocket-speed ratio's half-difference).
    outer_cap, inner_cap
        Coefficients of the outer sprocket's largest torque (its slip at the plan's limit,
        accelerating) and the inner's smallest (its skid at the limit, braking), N m, in
        ``[1, v^2, v^4]``, shifted by their fits' largest error to the safe side.
    split_accel
        The torque split's dependence on the forward acceleration ``a`` (m/s^2):
        ``dT(v, a) = split(v) + a s1(v) + a^2 s2(v)``, ``[s1 (3), s2 (3)]`` in ``[1, v^2, v^4]``
        (fitted with ``split`` to the accelerating turns).
    sideslip
        ``tan`` of the sideslip, ``v_lat / u``, as ``t0(v) + a t1(v) + a^2 t2(v)`` (9 coefficients,
        ``[t0, t1, t2]`` each in ``[1, v^2, v^4]``), fitted to the accelerating turns.
    sideslip_error
        Largest error of the sideslip fit (in ``tan``): the optimiser's sideslip rows are shifted by
        it to the safe side.
    """

    radius_m: float
    speed_cap: float
    cap_limit: str | None
    cap_reason: str | None
    resistance: tuple[float, float, float]
    split: tuple[float, float, float]
    fit_error_N: float
    fit_error_Nm: float
    e: float
    outer_cap: tuple[float, float, float] = (math.inf, 0.0, 0.0)
    inner_cap: tuple[float, float, float] = (-math.inf, 0.0, 0.0)
    split_accel: tuple[float, ...] = (0.0,) * 6
    sideslip: tuple[float, ...] = (0.0,) * 9
    sideslip_error: float = 0.0

    def column(self) -> np.ndarray:
        """The patch's column of ``OcpData.turn`` (:data:`~.ocp.TURN_ROWS` rows): ``[a0, a2, a4, d0, d2, d4, e,
        o0, o2, o4, i0, i2, i4]``, ``split_accel`` (6), ``sideslip`` (9), ``sideslip_error``."""
        big = 1e12  # an unbounded cap (no steady turn to fit): a bound that never binds
        caps = [min(max(x, -big), big) for x in (*self.outer_cap, *self.inner_cap)]
        return np.array(
            [*self.resistance, *self.split, self.e, *caps, *self.split_accel, *self.sideslip, self.sideslip_error],
            dtype=float,
        )


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


def _steady_limits(vehicle, soil_vec, R, speeds, max_slip, lim, settings) -> tuple[list, tuple]:
    """``classify_turn`` of the steady turn at each speed (one mapped call), and the solved columns."""
    n = speeds.size
    cols = motion_points(vehicle, np.tile(soil_vec, (n, 1)), speeds, speeds / R, np.zeros(n), np.zeros(n), settings)
    return [
        classify_turn(vehicle, R, float(u), max_slip, lim, tuple(c[j] for c in cols)) for j, u in enumerate(speeds)
    ], cols


def _speed_cap(vehicle, soil_vec, R, top, max_slip, lim, settings) -> tuple[float, str | None, str | None]:
    """The largest speed (<= top) up to which the steady turn breaks no limit, and the limit broken above it."""
    grid = np.geomspace(MIN_TURN_SPEED, top, CAP_SCAN)
    res, _ = _steady_limits(vehicle, soil_vec, R, grid, max_slip, lim, settings)
    bad = [j for j, (limit, _w) in enumerate(res) if limit is not None]
    if not bad:
        return float(top), None, None
    if bad[0] == 0:
        return 0.0, res[0][0], res[0][1]
    lo, hi, why = float(grid[bad[0] - 1]), float(grid[bad[0]]), res[bad[0]]
    for _ in range(CAP_REFINE):  # each round: FIT_POINTS speeds between the last feasible and the first not
        sub = np.linspace(lo, hi, FIT_POINTS + 2)[1:-1]
        r_sub, _ = _steady_limits(vehicle, soil_vec, R, sub, max_slip, lim, settings)
        j = next((q for q, (limit, _w) in enumerate(r_sub) if limit is not None), None)
        if j is None:
            lo = float(sub[-1])
        else:
            lo, hi, why = (lo if j == 0 else float(sub[j - 1])), float(sub[j]), r_sub[j]
    return lo, why[0], why[1]


def turn_terms(
    soil_vec: np.ndarray,
    radius_m: float,
    vehicle: Vehicle,
    *,
    max_slip: float,
    limits: Any,
    top: float = TURN_SPEED_TOP,
    settings: SteeringSettings = SteeringSettings(),
) -> TurnTerms:
    """The steering model's turn at ``radius_m`` on soil ``[c, phi, K]`` as the optimiser's terms.

    The speed limit: a scan of :data:`CAP_SCAN` speeds and :data:`CAP_REFINE` finer scans, each steady turn checked by
    :func:`~.turning.classify_turn` (soil, per-sprocket torque, power). Then :data:`FIT_POINTS` steady
    turns evenly up to the limit give the extra resistance ``dR = (T_l + T_r)/r - mu_r W`` (the steady
    balance: ``-m v Om``, the sideslip's share of the centripetal force), fitted by least squares in
    ``[1, v^2, v^4]`` (the turn is symmetric in the direction of travel). At each of those speeds the
    outer track's slip limit accelerating and the inner's skid limit braking are solved for directly
    (:func:`_slip_limits`); the turns at :data:`ACCEL_FRACTIONS` of those accelerations give half the
    torque difference ``dT = (T_outer - T_inner)/2`` (the yaw moment balance) and the sideslip's
    ``tan`` as ``f0(v) + a f1(v) + a^2 f2(v)`` (:func:`_accel_fits`). The fits' largest errors are kept.
    """
    sv = tuple(float(x) for x in np.ravel(soil_vec))
    lim = _Limits(float(limits.max_sprocket_torque), float(limits.max_power))
    return _turn_terms(sv, float(radius_m), vehicle, float(max_slip), lim, float(top), settings)


@locked_cache(maxsize=64)
def _turn_terms(soil: tuple, R: float, vehicle: Vehicle, max_slip: float, limits, top: float, settings) -> TurnTerms:
    """:func:`turn_terms` (cached: a re-plan of the same turn on the same soil does not solve it again)."""
    sv = np.asarray(soil, dtype=float)
    cap, limit, why = _speed_cap(vehicle, sv, R, top, max_slip, limits, settings)
    e = 0.5 * tread_of(vehicle) / abs(R)
    if cap <= 0.0:
        return TurnTerms(R, 0.0, limit, why, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, 0.0, e)
    speeds = np.linspace(MIN_TURN_SPEED, cap, FIT_POINTS) if cap > MIN_TURN_SPEED else np.array([cap])
    _res, cols = _steady_limits(vehicle, sv, R, speeds, max_slip, limits, settings)
    solved, _wl, _wr, _v, Tl, Tr = cols
    r = vehicle.sprocket_radius
    dR = (Tl + Tr) / r - vehicle.rolling_resistance * vehicle.weight
    keep = np.asarray(solved, dtype=bool)
    nu = 3 if keep.sum() >= 3 else 1  # too few steady turns for the speed terms: constants only
    A = _basis(speeds[keep], np.zeros(int(keep.sum())), nu)[:, :nu]
    cR, *_ = np.linalg.lstsq(A, dR[keep], rcond=None)
    errR = float(np.max(np.abs(A @ cR - dR[keep])))
    pad = _three
    (to_cap, a_out, at_out), (ti_cap, a_in, at_in) = _slip_limits(
        vehicle, sv, R, speeds[keep], max_slip, settings, cols, keep
    )
    cO, *_ = np.linalg.lstsq(A, to_cap, rcond=None)
    cI, *_ = np.linalg.lstsq(A, ti_cap, rcond=None)
    # the torque caps' fits: conservative (shifted by their largest error towards the safe side)
    lo = float(np.max(A @ cO - to_cap))
    hi = float(np.max(ti_cap - A @ cI))
    cO[0] -= max(lo, 0.0)
    cI[0] += max(hi, 0.0)
    known = {0.0: tuple(np.asarray(c)[keep] for c in cols), 1.0: at_out, -1.0: at_in}
    cT, cB, errT, errB = _accel_fits(vehicle, sv, R, speeds[keep], a_out, a_in, known, settings, nu)
    return TurnTerms(
        R, cap, limit, why, pad(cR), cT[:3], errR, errT, e, pad(cO), pad(cI), cT[3:], cB, errB
    )  # fmt: skip


def _three(c: np.ndarray) -> tuple[float, float, float]:
    """Coefficients ``[c0, c2, c4]`` of a fit (the missing ones 0)."""
    x = [float(v) for v in np.ravel(c)] + [0.0, 0.0, 0.0]
    return x[0], x[1], x[2]


def _basis(u: np.ndarray, a: np.ndarray, nu: int = 3) -> np.ndarray:
    """Columns ``a^k u^(2j)`` for k = 0, 1, 2 and j < nu (the layout of ``split``/``split_accel`` and ``sideslip``)."""
    return np.column_stack([a**k * u ** (2 * j) for k in range(3) for j in range(nu)])


def _accel_fits(vehicle, sv, R, speeds, a_out, a_in, known, settings, nu) -> tuple[tuple, tuple, float, float]:
    """``dT`` and the sideslip's ``tan`` fitted in ``[1, v^2, v^4] x [1, a, a^2]`` to the turns at each speed and
    :data:`ACCEL_FRACTIONS` of its slip-limited acceleration (> 0) or braking (< 0): 9 coefficients each (``nu = 1``:
    the speed terms 0) and the largest errors (N m, tan). ``known``: the turns already solved, by fraction
    (``motion_points`` columns); the others are solved in one mapped call."""
    n = speeds.size
    new = [f for f in ACCEL_FRACTIONS if f not in known]
    acc_of = {f: (f * a_out if f >= 0 else -f * a_in) for f in ACCEL_FRACTIONS}
    if new:
        U, Acc = np.tile(speeds, len(new)), np.concatenate([acc_of[f] for f in new])
        cols = motion_points(vehicle, np.tile(sv, (U.size, 1)), U, U / R, Acc, Acc / R, settings)
        for q, f in enumerate(new):
            known = {**known, f: tuple(c[q * n : (q + 1) * n] for c in cols)}
    U = np.tile(speeds, len(ACCEL_FRACTIONS))
    Acc = np.concatenate([acc_of[f] for f in ACCEL_FRACTIONS])
    ok, _wl, _wr, v, Tl, Tr = (np.concatenate([known[f][j] for f in ACCEL_FRACTIONS]) for j in range(6))
    ok = ok.astype(bool)
    dT = 0.5 * (Tr - Tl) if R > 0 else 0.5 * (Tl - Tr)
    A = _basis(U[ok], Acc[ok], nu)
    out: list = []
    for y in (dT[ok], v[ok] / U[ok]):
        c, *_ = np.linalg.lstsq(A, y, rcond=None)
        full = np.zeros((3, 3))
        full[:, :nu] = c.reshape(3, nu)
        out += [tuple(float(x) for x in full.ravel()), float(np.max(np.abs(A @ c - y)))]
    return out[0], out[2], out[1], out[3]


@locked_cache(maxsize=16)
def _slip_limited_mapped(settings: SteeringSettings, n: int):
    """:func:`~soiltrack.soilmodel.steering.slip_limited_motion_function` mapped over n points (cached per size)."""
    return slip_limited_motion_function(settings).map(n)


def _slip_limits(vehicle, sv, R, speeds, max_slip, settings, steady, keep) -> list[tuple]:
    """``[(T_outer, a, turns), (T_inner, a, turns)]`` per speed: the outer sprocket's torque and the acceleration at
    which its slip reaches ``max_slip``, and the inner's torque and the braking at which its skid reaches
    ``-max_slip`` (:func:`~soiltrack.soilmodel.steering.slip_limited_motion_function`, one mapped solve from the
    steady turn, each answer solved again by :func:`~.turning.motion_points` and its slip checked; ``turns``:
    those ``motion_points`` columns). Where it has no answer (or one of the wrong sign), the steady turn's
    torque and no acceleration: the turn is not accelerated there.
    """
    n = speeds.size
    st = tuple(np.asarray(c)[keep] for c in steady)
    _ok, wl0, wr0, v0, Tl0, Tr0 = st
    r, B = vehicle.sprocket_radius, tread_of(vehicle)
    Om = speeds / R
    veh = np.tile(np.asarray(vehicle_parameters(vehicle), dtype=float)[:, None], (1, n))
    out = []
    for target, right in ((max_slip, R > 0), (-max_slip, R < 0)):  # the outer track, then the inner
        P = np.vstack(
            [
                speeds,
                np.full(n, 1.0 / R),
                np.full(n, target),
                np.full(n, float(right)),
                np.tile(sv[:, None], (1, n)),
                veh,
            ]
        )
        z, _ = call_solver(_slip_limited_mapped(settings, n), np.vstack([wl0 if right else wr0, v0, np.zeros(n)]), P)
        a = np.asarray(z, dtype=float).reshape(3, n)[2]
        a = np.where(np.isfinite(a), a, 0.0)
        ok, wl, wr, _v, Tl, Tr = motion_points(vehicle, np.tile(sv, (n, 1)), speeds, Om, a, a / R, settings)
        w, y = (wr, -0.5 * B) if right else (wl, 0.5 * B)
        with np.errstate(divide="ignore", invalid="ignore"):
            slip = 1 - (speeds - Om * y) / (r * w)
        good = ok & (np.abs(slip - target) < 1e-6) & (a * np.sign(target) >= 0)
        turns = tuple(np.where(good, c, c0) for c, c0 in zip((ok, wl, wr, _v, Tl, Tr), st))
        out.append((np.where(good, Tr if right else Tl, Tr0 if right else Tl0), np.where(good, a, 0.0), turns))
    return out


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
            "; a steady turn at this speed holds: the plan's acceleration in the turn breaks it (the optimiser "
            "bounds the accelerating turn by fits of the steering model between mesh points): a gentler plan "
            "(--max-speed, an energy objective) may pass"
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
