"""Feasible speed/slip/torque profiles by optimal control, on one terrain or on a route of patches.

:func:`profile` plans from ``v0`` to ``v1`` over a distance (or a duration) on one terrain;
:func:`route_profile` over a :class:`~.route.Route`. Both

1. check every patch at steady state BEFORE the solver (necessary conditions, optimistic):
   the resistance ``mu_r N + R_c + W sin(theta)`` against the soil's thrust at the slip limit
   (``"slip"`` if a larger slip would give it, ``"soil"`` if no slip does) and the torque limit
   ``T_max / r`` (``"torque"``); the power limit ``P / v_end`` on the last patch
   (``"power"``); and whether the end speed can be reached at all with the largest thrust the
   limits allow (accelerating) or the largest braking thrust (slowing down). These checks are
   optimistic (necessary conditions), so a request they refuse is impossible: the solver is not
   run and the reason names the patch, the limit and the numbers;
2. solve the OCP of :mod:`.ocp` (direct collocation, IPOPT; the problem is built once per
   structure and re-solved with the data as parameters, warm-started from the previous solution);
3. check the solution after the solver: limits, end speed; a failed solve reports IPOPT's
   status and the patch where the plan is tightest.

The torque is held over each interval; the returned series hold one value per mesh point
(the torque's last entry repeats the one before). ``margin_N`` is the soil's thrust at the
slip limit minus the magnitude of the planned thrust (traction reserve; braking uses the same
limit, as ``F(-i) = -F(i)``). The initial sprocket speed is free within the slip limit (the
vehicle is already moving at ``v0``); the torque is the decision, held over each interval.

Robust profiles (``confidence`` with an identified soil): the plan is made on a soil backed
off along the linearised covariance - the soil whose thrust at the slip limit is the lower
one-sided ``confidence`` quantile (``q = mean - z Sigma g / sqrt(g' Sigma g)``, g the gradient
of that thrust) - and then checked by Monte Carlo: the fraction of sampled soils for which the
planned torque, replayed open-loop through the full dynamics (:func:`~.replay.replay`), breaks
the slip limit, beside the same fraction for the plan on the nominal soil.

Every plan keeps a traction reserve of :data:`THRUST_RESERVE` (its slip bound is where the soil
gives ``1 - THRUST_RESERVE`` of its thrust at the slip limit, and its power stays below
``(1 - THRUST_RESERVE) P_max``), so that the torque replayed open-loop keeps the limits between
the mesh points too. A duration instead of a distance gives equal time steps and a free
distance (energy objective only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import lru_cache
from statistics import NormalDist
from typing import Any

import casadi as ca
import numpy as np

from ..soilmodel import (
    DataError,
    Soil,
    Vehicle,
    format_energy,
    format_force,
    format_torque,
    sensitivity_function,
    slip_from_thrust,
    thrust_function,
)
from ..soilmodel.dynamics import slip_expr
from ..soilmodel.effect_terms import DEFAULT_STANDSTILL_SPEED
from ..soilmodel.simulation import drive_limits
from .arguments import check_number
from .fit_vehicle import headline_notes
from .forces import resistances, soil_thrust
from .margin import DEFAULT_MAX_SLIP, resolve_terrain, terrain_soil_vector
from .ocp import DEGREE, TURN_ROWS, OcpData, radau_collocation, solve_ocp
from .replay import replay
from .route import OBJECTIVES, Patch, Route
from .route_turns import MIN_TURN_SPEED, TURN_SERIES, TURN_SPEED_TOP, check_turns, plan_turns, turn_line, turn_terms

__all__ = [
    "SpeedPlan",
    "profile",
    "route_profile",
    "plan_patches",
    "DEFAULT_INTERVALS",
    "STANDSTILL_SPEED",
    "THRUST_RESERVE",
]

#: Traction reserve of a plan: its thrust stays below (1 - THRUST_RESERVE) times the soil's thrust
#: at the slip limit, and its power below (1 - THRUST_RESERVE) P_max. On the flat part of the
#: thrust-slip curve a thrust error of a fraction of a percent moves the slip by several percent
#: (measured: 0.07 % of thrust moved the slip of a braking plan on clayey soil from 19.8 % to
#: 21.4 % in the open-loop replay), so a plan right at i_max is not kept by its own torque.
THRUST_RESERVE = 0.005
#: Sampled soils of the Monte Carlo check of a robust profile.
ROBUST_SAMPLES = 100
#: Mesh intervals when none are given.
DEFAULT_INTERVALS = 50
#: Below this speed (m/s) the plan stands still: the model core's standstill regularisation speed
#: (:data:`soiltrack.soilmodel.effect_terms.DEFAULT_STANDSTILL_SPEED`), where slip loses its meaning.
STANDSTILL_SPEED = DEFAULT_STANDSTILL_SPEED
_SERIES = (
    "time_s",
    "distance_m",
    "speed_m_s",
    "sprocket_speed_rad_s",
    "slip",
    "sprocket_torque_Nm",
    "thrust_N",
    "margin_N",
    "patch",
)


def _dur(t) -> str:
    t = t or 0.0
    return f"{t * 1e3:.3g} ms" if t < 1 else f"{t:.3g} s"


def _f(x):
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


@dataclass(frozen=True)
class SpeedPlan:
    """A planned profile (or the reason there is none).

    Attributes
    ----------
    success, status, message
        Whether a feasible plan was found and checked; IPOPT's status (or ``"infeasible"``
        from the checks before the solver); words.
    objective, total_time_s, energy_J, solve_time_s, iterations, warm_start
        Objective, planned time and sprocket energy (positive work of the sprocket torque: braking
        energy is not recovered; ``None`` when there is no plan), solver time
        and iterations, whether the solve was warm-started.
    series
        Equal-length lists per mesh point: ``time_s``, ``distance_m``, ``speed_m_s``,
        ``sprocket_speed_rad_s``, ``slip``, ``sprocket_torque_Nm``, ``thrust_N``, ``margin_N``,
        ``patch`` (empty when there is no plan).
    reason
        When infeasible: ``{"patch", "limit", "required_N", "available_N", "short_by_N"}``.
    mesh
        Per-interval data for replays: ``c``, ``phi``, ``K`` (SI), ``grade_rad``,
        ``compaction_N``, ``dt``, ``torque``.
    active_limits
        Number of intervals in which each limit is active (``slip``: at the plan's slip bound,
        ``torque``, ``power``, ``torque_rate``): which limits shape the plan.
    patches
        Per patch: ``length_m``, ``grade_deg``, ``normal_load_N`` and the motion resistance the plan
        uses, itemised (``rolling_N``, ``compaction_N``, ``grade_N``): a replay must include them.
    limits, notes, robust
        Limits used (``max_torque_Nm``, ``max_power_W``, ``max_slip``, ``torque_rate_Nm_s``,
        ``max_speed_m_s``, and which were assumed), remarks, and the Monte Carlo check of a
        robust profile.
    peak_speed_m_s
        Largest planned speed over the mesh and collocation points (``None`` without a plan).
    standstills
        Time windows in which the plan stands still (speed below :data:`STANDSTILL_SPEED` at two
        or more consecutive mesh points): ``{"start_s", "end_s", "duration_s", "distance_m"}``.
    initial_slip, initial_slip_source
        The plan's first-point slip and where it comes from (``"given"``, ``"steady"``: the
        slip that carries the first patch's resistance at ``v0``, ``"rest"``: ``v0 = 0``).
    """

    success: bool
    status: str
    message: str
    objective: str
    total_time_s: float | None
    energy_J: float | None
    solve_time_s: float | None
    iterations: int | None
    warm_start: bool
    series: dict
    reason: dict | None
    mesh: dict
    limits: dict
    notes: tuple[str, ...] = field(default=())
    robust: dict | None = None
    n_patches: int = 1
    patches: tuple = ()
    active_limits: dict | None = None
    peak_speed_m_s: float | None = None
    standstills: tuple = ()
    initial_slip: float | None = None
    initial_slip_source: str | None = None
    #: what the first line says about the fit(s) planned with (outcome, other vehicle, effects left out)
    headline: tuple[str, ...] = ()
    #: per turning patch (:func:`~.route_turns.plan_turns`); empty: no turns, and the JSON has no turn keys
    turns: tuple = ()

    def to_dict(self, route: bool = False) -> dict:
        """The ``profile --json`` / ``route --json`` object (docs/data-formats.md); never NaN."""
        d = {
            "success": self.success,
            "status": self.status,
            "message": self.message,
            "objective": self.objective,
            "total_time_s": _f(self.total_time_s),
            "energy_J": _f(self.energy_J),
            "solve_time_s": _f(self.solve_time_s),
            "iterations": self.iterations,
            "warm_start": self.warm_start,
        }
        for k in _SERIES:
            if k == "patch" and not route:
                continue
            vals = self.series.get(k, [])
            d[k] = [int(x) for x in vals] if k == "patch" else [_f(x) for x in vals]
        if self.reason is not None:
            d["reason"] = {k: (_f(v) if isinstance(v, float) else v) for k, v in self.reason.items()}
        d["limits"] = {k: (_f(v) if isinstance(v, float) else v) for k, v in self.limits.items()}
        d["notes"] = list(self.notes)
        d["fit_notes"] = list(self.headline)
        d["active_limits"] = self.active_limits
        d["peak_speed_m_s"] = _f(self.peak_speed_m_s)
        d["standstills"] = [{k: _f(v) for k, v in w.items()} for w in self.standstills]
        d["initial_slip"] = _f(self.initial_slip)
        d["initial_slip_source"] = self.initial_slip_source
        d["patches"] = [{k: (_f(v) if isinstance(v, float) else v) for k, v in p.items()} for p in self.patches]
        if self.robust is not None:
            d["robust"] = {k: (_f(v) if isinstance(v, float) else v) for k, v in self.robust.items()}
        if self.turns:  # a route or profile with turns (planning.route_turns); absent otherwise
            for k in TURN_SERIES:
                d[k] = [_f(x) for x in self.series.get(k, [])]
            d["turns"] = [{k: (_f(v) if isinstance(v, float) else v) for k, v in t.items()} for t in self.turns]
        return d

    def report(self) -> str:
        """Plain-words summary."""
        if not self.success:
            L = [f"NO FEASIBLE PROFILE ({self.status}): {self.message}"]
        else:
            s = self.series
            vmax = self.limits.get("max_speed_m_s")
            L = [
                f"profile found ({self.objective} objective, IPOPT {self.status}, {self.iterations} iterations, "
                f"{_dur(self.solve_time_s)}{', warm start' if self.warm_start else ''})",
                f"  {s['distance_m'][-1]:.4g} m in {self.total_time_s:.4g} s, sprocket energy "
                f"{format_energy(self.energy_J)}; speed {s['speed_m_s'][0]:.3g} -> {s['speed_m_s'][-1]:.3g} m/s, "
                f"peak {self.peak_speed_m_s:.3g} m/s ("
                + (f"limit {vmax:.3g} m/s)" if vmax is not None else "no speed limit given)"),
                f"  initial slip {(self.initial_slip or 0.0) * 100:.3g} % "
                f"({_SLIP0_WORDS.get(self.initial_slip_source or '', 'unknown')})",
                "  "
                + _signed_extremes(s["slip"], "slip", lambda x: f"{x * 100:.3g} %")
                + f" (limit +-{self.limits['max_slip'] * 100:.3g} %)",
                "  "
                + _signed_extremes(s["sprocket_torque_Nm"], "torque", format_torque)
                + f" (limit +-{format_torque(self.limits['max_torque_Nm'])}), smallest traction reserve "
                f"{format_force(min(s['margin_N']))}",
            ]
            act = {k: n for k, n in (self.active_limits or {}).items() if n}
            n_int = len(s["time_s"]) - 1
            L.append(
                "  limits active: "
                + (
                    ", ".join(f"{k} in {n} of {n_int} intervals" for k, n in act.items())
                    if act
                    else "none (the objective alone shapes the plan)"
                )
            )
            for w in self.standstills:
                L.append(
                    f"  STANDS STILL (speed below {STANDSTILL_SPEED:g} m/s) from {w['start_s']:.4g} s to "
                    f"{w['end_s']:.4g} s ({w['duration_s']:.4g} s) at {w['distance_m']:.4g} m"
                )
        if self.robust is not None:
            L.append(
                f"  robust plan at confidence {self.robust['confidence']:.3g}: the slip limit is broken for "
                f"{self.robust['violation_fraction'] * 100:.3g} % of {self.robust['n_samples']} sampled soils "
                f"(nominal-soil plan: {self.robust['nominal_violation_fraction'] * 100:.3g} %)"
            )
        L += [turn_line(t) for t in self.turns]
        L += [f"  note: {n}" for n in self.notes]
        if self.headline:
            L[0] += " - " + "; ".join(self.headline)
        return "\n".join(L)


def _signed_extremes(values, what: str, fmt) -> str:
    """``largest driving slip 3 %, largest braking slip -13.7 %`` (a side without values: ``none``)."""
    v = np.asarray(values, dtype=float)
    pos, neg = v[v > 0], v[v < 0]
    a = fmt(float(pos.max())) if pos.size else "none"
    b = fmt(float(neg.min())) if neg.size else "none"
    return f"largest driving {what} {a}, largest braking {what} {b}"


#: The fitted effects a profile or route plans with (in the dynamics); the others are named as left out.
PLANNED_EFFECTS = ("slip_sinkage",)


def with_fit_headline(plan: SpeedPlan, terrains) -> SpeedPlan:
    """``plan`` with the first-line notes of the fits among ``terrains``.

    A fit's effects other than :data:`PLANNED_EFFECTS` are named as left out; an outcome that is not
    ``usable``, a fit of another vehicle and a fit without running gear are said
    (:func:`~.fit_vehicle.headline_notes`).
    """
    out: list[str] = []
    for t in terrains:
        ctx = getattr(t, "context", None)
        for n in headline_notes(ctx, PLANNED_EFFECTS):
            if n not in out:
                out.append(n)
    return replace(plan, headline=tuple(out)) if out else plan


# --------------------------------------------------------------------------------------------------
def _mesh(lengths: np.ndarray, n: int) -> np.ndarray:
    """Intervals per patch: proportional to length, at least 2 each (patch boundaries on the mesh)."""
    L = lengths.sum()
    k = np.maximum(2, np.round(n * lengths / L).astype(int))
    return k


def _infeasible(reason: dict, msg: str, objective: str, limits: dict, notes, n_patches: int) -> SpeedPlan:
    return SpeedPlan(
        False,
        "infeasible",
        msg,
        objective,
        None,
        None,
        None,
        None,
        False,
        {k: [] for k in _SERIES},
        reason,
        {},
        limits,
        tuple(notes),
        None,
        n_patches,
    )


def _reason(k, limit, req, avail):
    return {
        "patch": int(k),
        "limit": limit,
        "required_N": float(req),
        "available_N": float(avail),
        "short_by_N": float(req - avail),
    }


@dataclass(frozen=True)
class PatchData:
    """What the planner needs of one patch (SI).

    Attributes
    ----------
    theta
        Soil ``[c, phi, K]`` planned with (a robust plan's backed-off soil).
    N, R, Rc, grade
        Normal load, steady motion resistance (rolling, compaction, grade), compaction resistance (N)
        and grade (rad).
    Fs, Fpk
        The soil's thrust at the slip limit and near full slip (0.999), N.
    soil, unc
        The patch's soil, or its uncertainty (an identified soil).
    mu_s
        The fitted ``slip_sinkage`` coefficient planned with (0: none): the resistance
        ``mu_s N |i|`` adds to ``R`` along the plan (in the dynamics of the model core).
    """

    theta: np.ndarray
    N: float
    R: float
    Rc: float
    grade: float
    Fs: float
    Fpk: float
    soil: Any
    unc: Any
    mu_s: float = 0.0


def _fitted_mu_s(terrain: Any, unc: Any) -> float:
    """The ``slip_sinkage`` coefficient of a fit (its JSON or a FitResult; 0 without)."""
    ctx = getattr(unc, "context", None)
    return float((ctx.effects.get("slip_sinkage") or {}).get("mu_s", 0.0)) if ctx is not None else 0.0


def _patch_data(patches, vehicle, i_max) -> list[PatchData]:
    """Per patch: soil [c, phi, K], normal load, resistance items, soil limit, peak."""
    out = []
    for p in patches:
        soil, unc, _ = resolve_terrain(p.terrain, vehicle)
        th = math.radians(p.grade_deg)
        Narr, req = resistances(vehicle, soil, np.array([th]), 0.0, 0.0)
        N = float(Narr[0])
        theta = terrain_soil_vector(soil, unc, N)
        Fs = float(soil_thrust(theta, i_max, N, vehicle, "full")[0])
        Fpk = float(soil_thrust(theta, 0.999, N, vehicle, "full")[0])
        R = float(req["rolling_N"][0] + req["compaction_N"][0] + req["grade_N"][0])
        mu = _fitted_mu_s(p.terrain, unc)
        out.append(PatchData(theta, N, R, float(req["compaction_N"][0]), th, Fs, Fpk, soil, unc, mu))
    return out


def _precheck(pd, lengths, vehicle, v0, v1, i_max, Tmax, Pmax, r):
    """Steady-state and reachability checks (optimistic): a reason dict, or None."""
    T_thr = Tmax / r
    for k, d in enumerate(pd):
        avail = min(d.Fs, T_thr)
        if d.R > avail:
            if T_thr < d.Fs:
                lim = "torque"
            else:
                lim = "slip" if d.R <= d.Fpk else "soil"
            return _reason(k, lim, d.R, avail)
    last = len(pd) - 1
    if Pmax and v1 > 0 and pd[last].R > Pmax / v1:
        return _reason(last, "power", pd[last].R, Pmax / v1)
    m = vehicle.mass
    # fastest possible: largest thrust min(F_s, T/r, P/v), no inertia of the sprocket, sub-steps
    v2 = v0**2
    for k, d in enumerate(pd):
        hs = lengths[k] / 200.0
        for _ in range(200):
            v = math.sqrt(max(v2, 0.0))
            F = min(d.Fs, T_thr, Pmax / v if (Pmax and v > 0) else math.inf)
            v2 = v2 + 2 * hs * (F - d.R) / m
    if v1 > math.sqrt(max(v2, 0.0)) * (1 + 1e-9) + 1e-9:
        d = pd[last]
        L = float(sum(lengths))
        need = sum(p.R * lk for p, lk in zip(pd, lengths)) / L + m * (v1**2 - v0**2) / (2 * L)
        lim = (
            "power"
            if Pmax and Pmax / v1 <= min(d.Fs, T_thr)
            else "torque"
            if T_thr < d.Fs
            else "slip"
            if d.Fs < d.Fpk * 0.999
            else "soil"
        )
        avail = need - m * (v1**2 - math.sqrt(max(v2, 0)) ** 2) / (2 * L)
        return _reason(last, lim, need, avail)
    # slowest possible: largest braking thrust (skid at the slip limit, or the torque limit)
    v2 = v0**2
    for k, d in enumerate(pd):
        Fb = min(d.Fs, T_thr)
        v2 = max(v2 - 2 * lengths[k] * (Fb + d.R) / m, 0.0)
    if math.sqrt(v2) > v1 * (1 + 1e-9) + 1e-9:
        d = pd[last]
        L = float(sum(lengths))
        need = m * (v0**2 - v1**2) / (2 * L) - sum(p.R * lk for p, lk in zip(pd, lengths)) / L
        avail = min(d.Fs, T_thr)
        return _reason(last, "torque" if T_thr < d.Fs else "slip", need, avail)
    return None


@lru_cache(maxsize=256)
def _slip_bound(theta: tuple, N: float, Fs: float, i_max: float, vehicle: Vehicle) -> float:
    """Slip at which the soil gives (1 - THRUST_RESERVE) of its thrust at i_max (cached per soil and load)."""
    sb = slip_from_thrust(np.array([(1 - THRUST_RESERVE) * Fs]), Soil(*theta), vehicle, normal_load=N)
    return float(min(sb[0], i_max))


def _bang_bang(pd, idx, S, v0, v1, T_thr, Pmax, m, max_speed=None) -> np.ndarray:
    """Start guess of a minimum-time plan: 0.8 x (full thrust forward, full braking back from v1, the lower
    of the two) + 0.2 x (linear in distance); measured: 28-36 IPOPT iterations on the benchmark cases against
    31-98 for either guess alone."""
    h = np.diff(S)
    n = len(h)
    fwd = np.empty(n + 1)
    fwd[0] = v0
    for k in range(n):
        d = pd[idx[k]]
        F = min(0.95 * d.Fs, T_thr, Pmax / max(fwd[k], 1e-3))
        fwd[k + 1] = math.sqrt(max(fwd[k] ** 2 + 2 * h[k] * (F - d.R) / m, 0.01))
    bwd = np.empty(n + 1)
    bwd[n] = v1
    for k in range(n - 1, -1, -1):
        d = pd[idx[k]]
        F = min(0.95 * d.Fs, T_thr)
        bwd[k] = math.sqrt(max(bwd[k + 1] ** 2 + 2 * h[k] * (F + d.R) / m, 0.01))
    v = 0.8 * np.minimum(fwd, bwd) + 0.2 * (v0 + (v1 - v0) * S / S[-1])
    if max_speed is not None:
        v = np.minimum(v, max_speed)
    v[0], v[-1] = v0, v1
    return v


#: Words for where the first point's slip comes from.
_SLIP0_WORDS = {
    "given": "given",
    "steady": "steady slip carrying the resistance at v0",
    "steady_capped": "the steady slip at v0 is beyond the plan's slip bound: capped at it",
    "rest": "at rest",
}


def _slip(v: np.ndarray, w: np.ndarray, r: float) -> np.ndarray:
    """The model core's slip (:func:`~soiltrack.soilmodel.dynamics.slip_expr`, regularised at standstill)."""
    v = np.asarray(v, dtype=float)
    return np.asarray(slip_expr(ca.DM(v.ravel()), ca.DM(np.asarray(w, dtype=float).ravel()), r), dtype=float).reshape(
        v.shape
    )


def _initial_slip(d0: "PatchData", vehicle: Vehicle, v0: float, slip0: float | None, bound: float) -> tuple[float, str]:
    """The first point's slip: given (checked against the plan's slip bound), 0 at rest, else the steady slip
    that carries the first patch's resistance at ``v0`` (the vehicle is cruising when the plan starts)."""
    if v0 == 0.0:
        return 0.0, "rest"
    if slip0 is not None:
        if abs(slip0) > bound:
            raise DataError(
                f"argument slip0 = {slip0:g} is beyond the plan's slip bound {bound:.4g} on the first "
                f"patch (the slip limit less the traction reserve of {THRUST_RESERVE:g})"
            )
        return float(slip0), "given"
    c, phi, K = (float(x) for x in d0.theta)
    i_ss = float(slip_from_thrust(np.array([d0.R]), Soil(c, phi, K), vehicle, normal_load=d0.N)[0])
    for _ in range(50 if d0.mu_s else 0):  # F(i) = R + mu_s N |i|: a contraction (mu_s N << dF/di)
        i_new = float(
            slip_from_thrust(np.array([d0.R + d0.mu_s * d0.N * abs(i_ss)]), Soil(c, phi, K), vehicle, normal_load=d0.N)[
                0
            ]
        )
        if abs(i_new - i_ss) <= 1e-14:
            break
        i_ss = i_new
    if abs(i_ss) > bound:
        return float(np.sign(i_ss) * bound), "steady_capped"
    return i_ss, "steady"


def _standstills(t: np.ndarray, v: np.ndarray, s: np.ndarray) -> tuple[dict, ...]:
    """Windows of two or more consecutive mesh points below :data:`STANDSTILL_SPEED`."""
    still = np.asarray(v) < STANDSTILL_SPEED
    out = []
    k = 0
    while k < len(still):
        if still[k]:
            j = k
            while j + 1 < len(still) and still[j + 1]:
                j += 1
            if j > k:
                out.append(
                    {
                        "start_s": float(t[k]),
                        "end_s": float(t[j]),
                        "duration_s": float(t[j] - t[k]),
                        "distance_m": float(s[k]),
                    }
                )
            k = j + 1
        else:
            k += 1
    return tuple(out)


def plan_patches(patches: tuple[Patch, ...], vehicle: Vehicle, **kw: Any) -> SpeedPlan:
    """Plan over ``patches`` (the engine of :func:`profile`, :func:`route_profile` and the re-planner).

    Keyword arguments: ``v0``, ``v1``, ``distance``, ``duration``, ``max_slip``, ``objective``,
    ``intervals``, ``torque_rate``, and optionally ``confidence``, ``robust_samples``,
    ``max_speed``, ``slip0``, ``warm_store`` (the dict that keeps the solution for the next
    warm start; default: the process-wide one per problem structure).
    """
    res = _plan_core(patches, vehicle, **kw)
    info = []
    for p in patches:
        soil, _u, _m = resolve_terrain(p.terrain, vehicle)
        N, req = resistances(vehicle, soil, np.array([math.radians(p.grade_deg)]), 0.0, 0.0)
        length: float | None = float(p.length_m)
        if kw.get("duration") is not None:  # the distance is an outcome of the plan
            length = res.series["distance_m"][-1] if res.success else None
        info.append(
            {
                "length_m": length,
                "grade_deg": float(p.grade_deg),
                "terrain": p.label,
                "normal_load_N": float(N[0]),
                "rolling_N": float(req["rolling_N"][0]),
                "compaction_N": float(req["compaction_N"][0]),
                "grade_N": float(req["grade_N"][0]),
            }
        )
    return replace(res, patches=tuple(info))


@dataclass(frozen=True)
class _PlanArgs:
    """The checked arguments of a plan (internal)."""

    v0: float
    v1: float
    distance: float | None
    duration: float | None
    i_max: float
    objective: str
    intervals: int
    torque_rate: float | None
    confidence: float | None
    route: bool
    robust_samples: int
    max_speed: float | None
    slip0: float | None


def _check_args(
    *,
    v0: float,
    v1: float,
    distance: float | None,
    duration: float | None,
    max_slip: float | None,
    objective: str,
    intervals: int,
    torque_rate: float | None,
    confidence: float | None = None,
    route: bool = False,
    robust_samples: int = ROBUST_SAMPLES,
    max_speed: float | None = None,
    slip0: float | None = None,
) -> _PlanArgs:
    """Every argument of a plan checked (DataError naming the argument)."""
    v0 = check_number("v0", v0, 0.0)
    v1 = check_number("v1", v1, 0.0)
    if v0 + v1 <= 0:
        raise DataError("argument v0 or v1 must be > 0 (a profile from rest to rest has no speed to plan)")
    if max_speed is not None:
        max_speed = check_number("max_speed", max_speed, 0.0, lo_open=True)
        if max_speed < max(v0, v1):
            raise DataError(
                f"argument max_speed = {max_speed:g} m/s is below the initial or target speed "
                f"(v0 = {v0:g}, v1 = {v1:g} m/s)"
            )
    if slip0 is not None:
        slip0 = check_number("slip0", slip0, -1.0, 1.0, True, True)
        if v0 == 0.0:
            raise DataError("argument slip0 needs v0 > 0 (at rest the sprocket stands still: no slip to give)")
    if objective not in OBJECTIVES:
        raise DataError(f"argument objective must be one of {OBJECTIVES}, got {objective!r}")
    i_max = DEFAULT_MAX_SLIP if max_slip is None else check_number("max_slip", max_slip, 0, 1, True, True)
    if isinstance(intervals, bool) or not isinstance(intervals, (int, np.integer)) or not 2 <= intervals <= 2000:
        raise DataError(f"argument intervals must be an integer in [2, 2000], got {intervals!r}")
    if torque_rate is not None:
        torque_rate = check_number("torque_rate", torque_rate, 0.0, lo_open=True)
    if duration is not None:
        duration = check_number("duration", duration, 0.0, lo_open=True)
        if objective == "time":
            raise DataError("argument objective: with a duration the time is fixed; use objective 'energy'")
    if confidence is not None:
        confidence = check_number("confidence", confidence, 0.5, 1.0, hi_open=True)
    return _PlanArgs(
        v0, v1, distance, duration, i_max, objective, int(intervals), torque_rate, confidence, route,
        robust_samples, max_speed, slip0,
    )  # fmt: skip


def _limits(vehicle: Vehicle, a: _PlanArgs) -> tuple[Any, dict, list[str]]:
    """The drivetrain limits (``drive_limits``), the ``limits`` dict of the result and the notes on them."""
    lim = drive_limits(vehicle)
    limits = {
        "max_torque_Nm": float(lim.max_sprocket_torque),
        "max_power_W": float(lim.max_power),
        "max_slip": float(a.i_max),
        "torque_rate_Nm_s": a.torque_rate,
        "max_speed_m_s": a.max_speed,
        "torque_assumed": lim.torque_assumed,
        "power_assumed": lim.power_assumed,
    }
    notes = []
    if lim.torque_assumed or lim.power_assumed:
        notes.append(
            "the vehicle gives no "
            + " and no ".join(
                x
                for x, on in (
                    ("torque limit (0.8 W r assumed)", lim.torque_assumed),
                    ("power limit (15 W/kg assumed)", lim.power_assumed),
                )
                if on
            )
        )
    return lim, limits, notes


def _backed_off(pd: list[PatchData], vehicle: Vehicle, i_max: float, confidence: float) -> list[PatchData]:
    """A robust plan's soils: each identified soil backed off to the one-sided ``confidence`` quantile of its
    thrust at the slip limit (linearised covariance)."""
    if not any(d.unc is not None for d in pd):
        raise DataError(
            "argument confidence needs an identified soil (--fit / a FitResult): the soil given has no uncertainty"
        )
    z = NormalDist().inv_cdf(confidence)
    out = []
    for d in pd:
        u = d.unc
        if u is not None:
            g = np.asarray(
                sensitivity_function("full")(i_max, *d.theta, d.N, vehicle.track_length, vehicle.track_width),
                dtype=float,
            ).ravel() @ u.jacobian_at(d.N)
            sd = math.sqrt(max(float(g @ u.cov @ g), 0.0))
            if sd > 0:
                th = u.soils_at(u.mean - z * (u.cov @ g) / sd, d.N)[0]
                d = replace(
                    d,
                    theta=th,
                    Fs=float(soil_thrust(th, i_max, d.N, vehicle, "full")[0]),
                    Fpk=float(soil_thrust(th, 0.999, d.N, vehicle, "full")[0]),
                )
        out.append(d)
    return out


def _pre_solver_reason(pd, lengths, vehicle, a: _PlanArgs, Tmax, Pmax, r) -> dict | None:
    """Why the plan cannot exist, found at steady state before the solver (``None``: the solver decides)."""
    if a.duration is None:
        return _precheck(pd, lengths, vehicle, a.v0, a.v1, a.i_max, Tmax, Pmax, r)
    T_thr = Tmax / r
    for k, d in enumerate(pd):
        if d.R > min(d.Fs, T_thr):
            lim = "torque" if T_thr < d.Fs else ("slip" if d.R <= d.Fpk else "soil")
            return _reason(k, lim, d.R, min(d.Fs, T_thr))
    return None


def _capped(v: np.ndarray, idx: np.ndarray, terms: dict | None) -> np.ndarray:
    """Node speeds of a start guess within the turns' speed limits (the ends are kept: checked before)."""
    if not terms:
        return v
    cap = np.array([terms[k].speed_cap if k in terms else np.inf for k in idx])
    node = np.minimum(np.append(cap, np.inf), np.append(np.inf, cap))
    out = np.minimum(v, 0.98 * node)
    out[0], out[-1] = v[0], v[-1]
    return out


def _turn_terms(pd, patches, vehicle, a: _PlanArgs, lim) -> dict:
    """``{patch: TurnTerms}`` of the turning patches on the soils planned with (:func:`~.route_turns.turn_terms`)."""
    out = {}
    for k, p in enumerate(patches):
        if getattr(p, "radius_m", None) is not None:
            top = TURN_SPEED_TOP if a.max_speed is None else min(TURN_SPEED_TOP, a.max_speed)
            out[k] = turn_terms(pd[k].theta, p.radius_m, vehicle, max_slip=a.i_max, limits=lim, top=top)
    return out


def _turn_reason(terms: dict, patches, a: _PlanArgs) -> tuple[dict, str] | None:
    """A turn no speed profile can make (no speed at which its steady turn holds; v0 or v1 above its limit)."""
    last = len(patches) - 1
    for k, tt in terms.items():
        ends = [("v0", a.v0)] * (k == 0) + [("v1", a.v1)] * (k == last)
        over = [(name, v) for name, v in ends if v > tt.speed_cap * (1 + 1e-9)]
        if tt.speed_cap > 0 and not over:
            continue
        head = f"patch {k} ({patches[k].label}, turn of radius {tt.radius_m:g} m): "
        if tt.speed_cap <= 0:
            what = f"the steady turn breaks the {tt.cap_limit} limit even at {MIN_TURN_SPEED:g} m/s ({tt.cap_reason})"
        else:
            name, v = over[0]
            what = (
                f"{name} = {v:g} m/s is above the turn's steady speed limit {tt.speed_cap:.4g} m/s (above it: "
                f"{tt.cap_reason})"
            )
        reason = {"patch": k, "limit": tt.cap_limit, "turn_radius_m": tt.radius_m, "speed_cap_m_s": tt.speed_cap}
        return reason, head + what + "; found by the steering model before the solver"
    return None


def _ocp_data(pd, patches, vehicle, a: _PlanArgs, lengths, Tmax, Pmax, terms=None):
    """The mesh (in distance), the per-interval soil and limits, and the start: ``(OcpData, idx, i0 source)``."""
    r = vehicle.sprocket_radius
    counts = _mesh(lengths, a.intervals) if a.duration is None else np.array([a.intervals])
    n = int(counts.sum())
    idx = np.repeat(np.arange(len(patches)), counts)
    if a.duration is None:
        S = np.concatenate(
            [[0.0]]
            + [
                np.linspace(a0, a0 + lk, c + 1)[1:]
                for a0, lk, c in zip(np.concatenate([[0.0], np.cumsum(lengths)[:-1]]), lengths, counts)
            ]
        )
    else:
        S = np.linspace(0.0, 0.5 * (a.v0 + a.v1) * a.duration, n + 1)
    th = np.array([pd[k].theta for k in idx])
    bounds_p = [_slip_bound(tuple(map(float, d.theta)), d.N, d.Fs, a.i_max, vehicle) for d in pd]
    slip_bound = np.array([bounds_p[k] for k in idx])
    i0, i0_source = _initial_slip(pd[0], vehicle, a.v0, a.slip0, float(slip_bound[0]))
    data = OcpData(
        c=th[:, 0],
        phi=th[:, 1],
        K=th[:, 2],
        grade=np.array([pd[k].grade for k in idx]),
        Rc=np.array([pd[k].Rc for k in idx]),
        s=S,
        v0=a.v0,
        v1=a.v1,
        distance=None if a.duration is not None else float(lengths.sum()),
        duration=a.duration,
        slip_bound=slip_bound,
        max_torque=Tmax,
        max_power=Pmax * (1 - THRUST_RESERVE),
        max_slip=a.i_max,
        torque_rate=a.torque_rate,
        objective=a.objective,
        v_guess=_capped(_bang_bang(pd, idx, S, a.v0, a.v1, Tmax / r, Pmax, vehicle.mass, a.max_speed), idx, terms)
        if a.objective == "time" and a.duration is None
        else None,
        w0=0.0 if a.v0 == 0.0 else a.v0 / (r * (1.0 - i0)),
        max_speed=a.max_speed,
        mu_s=np.array([pd[k].mu_s for k in idx]) if any(d.mu_s for d in pd) else None,
        turn=np.column_stack([terms[k].column() if k in terms else np.zeros(TURN_ROWS) for k in idx])
        if terms
        else None,
        speed_cap=np.array([terms[k].speed_cap if k in terms else np.inf for k in idx]) if terms else None,
    )
    return data, idx, i0_source


def _slip_guesser(pd, idx, vehicle):
    """``F -> slip`` per interval (the inverse thrust-slip curve of each interval's soil): the solver's start."""

    def slip_guess(F):
        out = np.empty(idx.size)
        for k, d in enumerate(pd):
            sel = idx == k
            s_, _ok = slip_from_thrust(
                F[sel], Soil(*map(float, d.theta)), vehicle, normal_load=d.N, return_reachable=True
            )
            out[sel] = s_
        return out

    return slip_guess


def _node_thrust(i_nodes, th, Nn, n, vehicle) -> np.ndarray:
    """Eq. 2 at the mesh nodes (node k takes the soil of interval k; the end node the last)."""
    kk = np.minimum(np.arange(n + 1), n - 1)
    return np.asarray(
        thrust_function("full")(
            i_nodes.reshape(1, -1),
            th[kk, 0].reshape(1, -1),
            th[kk, 1].reshape(1, -1),
            th[kk, 2].reshape(1, -1),
            Nn[kk].reshape(1, -1),
            vehicle.track_length,
            vehicle.track_width,
        ),
        dtype=float,
    ).ravel()


def _violated(sol, i_nodes, i_col, a: _PlanArgs, Tmax, Pmax) -> tuple[list[str], float]:
    """The limits broken after the solve at the mesh and collocation points, and the peak speed."""
    v, w, M, Z = sol["v"], sol["w"], sol["M"], sol["Z"]
    viol = []
    if max(np.max(np.abs(i_nodes)), np.max(np.abs(i_col))) > a.i_max + 1e-6:
        viol.append("slip")
    if np.max(np.abs(M)) > Tmax * (1 + 1e-6):
        viol.append("torque")
    w_all = np.concatenate([w[:-1], w[1:], Z[1]])
    M_all = np.concatenate([M, M, np.repeat(M, DEGREE)])
    if Pmax and np.max(M_all * w_all) > Pmax * (1 + 1e-5):
        viol.append("power")
    peak = float(max(np.max(v), np.max(Z[0])))
    if a.max_speed is not None and peak > a.max_speed * (1 + 1e-6):
        viol.append("speed")
    return viol, peak


def _solver_failed(sol, viol, pd, idx, Fs_int, F_nodes, Tmax, r, a, limits, notes, n_patches) -> SpeedPlan:
    """The result of a solve that found no feasible profile: the patch where the plan is tightest."""
    k = int(idx[int(np.argmin(Fs_int - np.abs(F_nodes[:-1])))])
    d = pd[k]
    reason = _reason(k, "slip" if d.Fs < Tmax / r else "torque", d.R, float(min(d.Fs, Tmax / r)))
    msg = (
        f"the solver found no feasible profile (IPOPT: {sol['status']}"
        f"{'; violated after the solve: ' + ', '.join(viol) if viol else ''}); the plan is tightest on patch {k}"
    )
    return SpeedPlan(
        False, sol["status"], msg, a.objective, None, None, sol["solve_time"], sol["iterations"], sol["warm"],
        {k_: [] for k_ in _SERIES}, reason, {}, limits, tuple(notes), None, n_patches,
    )  # fmt: skip


def _active(sol, i_nodes, slip_bound, a: _PlanArgs, Tmax, Pmax) -> dict:
    """In how many intervals each limit is active."""
    v, w, M, dt, Z = sol["v"], sol["w"], sol["M"], sol["dt"], sol["Z"]
    n = M.size
    sb_nodes = np.concatenate([slip_bound, slip_bound[-1:]])
    at_slip = np.abs(i_nodes) >= sb_nodes * (1 - 1e-4)
    tr = a.torque_rate
    active = {
        "slip": int(np.sum(at_slip[:-1] | at_slip[1:])),
        "torque": int(np.sum(np.abs(M) >= Tmax * (1 - 1e-6))),
        "power": int(np.sum(np.maximum(M * w[:-1], M * w[1:]) >= Pmax * (1 - THRUST_RESERVE) * (1 - 1e-4))),
        "torque_rate": (int(np.sum(np.abs(np.diff(M)) >= tr * 0.5 * (dt[1:] + dt[:-1]) * (1 - 1e-4))) if tr else 0),
    }
    if a.max_speed is not None:
        v_int = np.maximum(np.maximum(v[:-1], v[1:]), Z[0].reshape(n, DEGREE).max(axis=1))
        active["speed"] = int(np.sum(v_int >= a.max_speed * (1 - 1e-4)))
    return active


def _series_and_mesh(sol, data, i_nodes, i_col, F_nodes, Fs_int, idx, th, Nn) -> tuple[dict, dict, float]:
    """The result's series, its mesh record (for replay and the robust check) and the positive sprocket work."""
    v, w, M, dt, Z = sol["v"], sol["w"], sol["M"], sol["dt"], sol["Z"]
    n = M.size
    t = np.concatenate([[0.0], np.cumsum(dt)])
    rep = lambda x: np.append(x, x[-1])  # noqa: E731 - interval value at its start node, last repeated
    series = {
        "time_s": t,
        "distance_m": sol["s"],
        "speed_m_s": v,
        "sprocket_speed_rad_s": w,
        "slip": i_nodes,
        "sprocket_torque_Nm": rep(M),
        "thrust_N": F_nodes,
        "margin_N": rep(Fs_int) - np.abs(F_nodes),
        "patch": rep(idx),
    }
    series = {k: [float(x) for x in vals] if k != "patch" else [int(x) for x in vals] for k, vals in series.items()}
    _tau, _C, B = radau_collocation(DEGREE)
    w_int = np.array([np.dot(B[1:], Z[1, k * DEGREE : (k + 1) * DEGREE]) for k in range(n)])
    energy = float(np.sum(np.maximum(M * dt * w_int, 0.0)))  # positive sprocket work (braking not recovered)
    mesh = {
        "c": th[:, 0],
        "phi": th[:, 1],
        "K": th[:, 2],
        "grade_rad": data.grade,
        "compaction_N": data.Rc,
        "dt": dt,
        "torque": M,
        "v": v,
        "w": w,
        "slip": i_nodes,
        "normal_load": Nn,
        "patch": idx,
        "slip_collocation": i_col,
    }
    if data.mu_s is not None:
        mesh["mu_s"] = data.mu_s
    return series, mesh, energy


def _plan_core(patches: tuple[Patch, ...], vehicle: Vehicle, *, warm_store: dict | None = None, **kw) -> SpeedPlan:
    """Check, pre-check at steady state, solve, check after the solve, record (the steps above)."""
    a = _check_args(**kw)
    lim, limits, notes = _limits(vehicle, a)
    Tmax, Pmax, r = lim.max_sprocket_torque, lim.max_power, vehicle.sprocket_radius
    pd = _patch_data(patches, vehicle, a.i_max)
    if a.confidence is not None:
        pd = _backed_off(pd, vehicle, a.i_max, a.confidence)
        notes.append(
            f"robust plan: soils backed off to the one-sided {a.confidence:.3g} quantile of their thrust at the "
            "slip limit (linearised covariance), checked by Monte Carlo"
        )
    lengths = np.array([p.length_m for p in patches], dtype=float)
    pre = _pre_solver_reason(pd, lengths, vehicle, a, Tmax, Pmax, r)
    if pre is not None:
        pk = patches[pre["patch"]]
        msg = (
            f"patch {pre['patch']} ({pk.label}, grade {pk.grade_deg:g} deg): needs {format_force(pre['required_N'])}, "
            f"the {pre['limit']} limit gives {format_force(pre['available_N'])} (short by "
            f"{format_force(pre['short_by_N'])}); found by the steady-state check before the solver"
        )
        return _infeasible(pre, msg, a.objective, limits, notes, len(patches))
    terms = _turn_terms(pd, patches, vehicle, a, lim)
    turn_pre = _turn_reason(terms, patches, a)
    if turn_pre is not None:
        return _infeasible(turn_pre[0], turn_pre[1], a.objective, limits, notes, len(patches))
    data, idx, i0_source = _ocp_data(pd, patches, vehicle, a, lengths, Tmax, Pmax, terms)
    n = idx.size
    sol = solve_ocp(data, vehicle, _slip_guesser(pd, idx, vehicle), warm_store)
    i_nodes, i_col = _slip(sol["v"], sol["w"], r), _slip(sol["Z"][0], sol["Z"][1], r)
    th = np.array([pd[k].theta for k in idx])
    Nn = np.array([pd[k].N for k in idx])
    F_nodes = _node_thrust(i_nodes, th, Nn, n, vehicle)
    Fs_int = np.array([pd[k].Fs for k in idx])
    viol, peak = _violated(sol, i_nodes, i_col, a, Tmax, Pmax)
    if not (sol["success"] and not viol and abs(sol["v"][-1] - a.v1) <= 1e-6 * max(1.0, a.v1)):
        return _solver_failed(sol, viol, pd, idx, Fs_int, F_nodes, Tmax, r, a, limits, notes, len(patches))
    series, mesh, energy = _series_and_mesh(sol, data, i_nodes, i_col, F_nodes, Fs_int, idx, th, Nn)
    t = series["time_s"]
    stand = _standstills(np.asarray(t), sol["v"], sol["s"])
    if stand and a.objective == "energy" and a.duration is not None:
        notes.append(
            "the energy objective counts the sprocket's positive work only and, with a duration, the "
            "distance is free: standing still costs nothing, so the plan waits (see the standstills)"
        )
    msg = (
        f"feasible profile: {sol['s'][-1]:.4g} m in {t[-1]:.4g} s; limits checked after the solve at the mesh "
        "and collocation points"
    )
    res = SpeedPlan(
        True, sol["status"], msg, a.objective, float(t[-1]), energy, sol["solve_time"], sol["iterations"],
        sol["warm"], series, None, mesh, limits, tuple(notes), None, len(patches),
        active_limits=_active(sol, i_nodes, data.slip_bound, a, Tmax, Pmax), peak_speed_m_s=peak,
        standstills=stand, initial_slip=float(i_nodes[0]), initial_slip_source=i0_source,
    )  # fmt: skip
    if a.confidence is None:
        return res
    rkw = dict(
        v0=a.v0, v1=a.v1, distance=a.distance, duration=a.duration, max_slip=a.i_max, objective=a.objective,
        intervals=a.intervals, torque_rate=a.torque_rate, route=a.route, max_speed=a.max_speed, slip0=a.slip0,
    )  # fmt: skip
    rs = a.robust_samples
    if isinstance(rs, bool) or not isinstance(rs, int) or rs < 10:
        raise DataError(f"argument robust_samples must be an integer >= 10, got {rs!r}")
    res = _with_mesh(res, mesh)
    return replace(res, robust=_robust_check(res, pd, idx, vehicle, a.i_max, a.confidence, patches, rkw, rs))


def _violations(result, pd, idx, vehicle, i_max, n_samples, seed=1) -> float:
    """Fraction of sampled soils for which the planned torque, replayed open-loop, breaks the slip limit."""
    qs = {k: d.unc.sample(n_samples, seed + k) for k, d in enumerate(pd) if d.unc is not None}
    broken = 0
    for j in range(n_samples):
        mesh = dict(result.mesh)
        th = np.column_stack([mesh["c"], mesh["phi"], mesh["K"]]).copy()
        for k, q in qs.items():
            sel = idx == k
            th[sel] = pd[k].unc.soils_at(q[j], pd[k].N)[0]
        mesh.update(c=th[:, 0], phi=th[:, 1], K=th[:, 2])
        rp = replay(_with_mesh(result, mesh), vehicle, substeps=4)
        broken += bool(np.max(np.abs(rp.slip)) > i_max * (1 + 1e-3))
    return broken / n_samples


def _with_mesh(result: "SpeedPlan", mesh: dict) -> "SpeedPlan":
    return replace(result, mesh=mesh)


def _robust_check(result, pd, idx, vehicle, i_max, confidence, patches, kw, n_samples) -> dict:
    frac = _violations(result, pd, idx, vehicle, i_max, n_samples)
    nominal = plan_patches(tuple(patches), vehicle, **dict(kw, confidence=None))
    frac_nom = _violations(nominal, pd, idx, vehicle, i_max, n_samples) if nominal.success else None
    return {
        "confidence": float(confidence),
        "method": "plan on the soil backed off along the linearised covariance; Monte Carlo replay check",
        "n_samples": n_samples,
        "violation_fraction": frac,
        "nominal_violation_fraction": frac_nom,
        "nominal_total_time_s": nominal.total_time_s,
    }


def profile(
    terrain: Any,
    vehicle: Vehicle,
    *,
    v0: float,
    v1: float,
    distance: float | None = None,
    duration: float | None = None,
    grade_deg: float = 0.0,
    max_slip: float | None = None,
    objective: str = "time",
    intervals: int = DEFAULT_INTERVALS,
    torque_rate: float | None = None,
    confidence: float | None = None,
    robust_samples: int = ROBUST_SAMPLES,
    max_speed: float | None = None,
    slip0: float | None = None,
    radius_m: float | None = None,
) -> SpeedPlan:
    """Plan a speed/slip/torque profile on one terrain (see the module docstring).

    Parameters
    ----------
    terrain
        A ``Soil``, a ``FitResult``, a ``SoilUncertainty`` or an on-line estimate (see
        :func:`~.uncertainty.uncertainty_from_estimate`).
    vehicle
        The vehicle (torque and power limits, or the simulator's documented defaults).
    v0, v1
        Initial and target speed, m/s (>= 0).
    distance, duration
        Exactly one: the distance (m) or the duration (s; objective ``"energy"`` only).
    grade_deg, max_slip, objective, intervals, torque_rate
        Grade (deg), slip limit (default 0.2), ``"time"`` or ``"energy"``, mesh intervals,
        optional torque-rate limit (N m/s).
    confidence
        With an identified soil: plan so that the slip limit holds with this probability
        (back-off, checked by Monte Carlo).
    robust_samples
        Sampled soils of that Monte Carlo check (each replays the plan and the nominal plan).
    max_speed
        Speed limit, m/s, at every mesh and collocation point (default none; the peak speed is
        reported either way).
    slip0
        The slip when the plan starts (default: the steady slip that carries the resistance at
        ``v0``; 0 at rest); within the plan's slip bound.
    radius_m
        A turn of this radius (m, signed, + left) over the whole profile: both sprockets' torques and
        slips by the steering model on the planned speeds (:func:`~.route_turns.plan_turns`; flat only).

    Returns
    -------
    SpeedPlan
    """
    if (distance is None) == (duration is None):
        raise DataError("give exactly one of the arguments distance and duration")
    if distance is not None:
        distance = check_number("distance", distance, 0.0, lo_open=True)
        length = distance
    else:
        length = 1.0
    grade_deg = check_number("grade_deg", grade_deg, -68.75, 68.75)
    if radius_m is not None:
        radius_m = check_number("radius_m", radius_m, -math.inf, math.inf)
    patches = (Patch(length, terrain, grade_deg, radius_m),)
    check_turns(patches, vehicle, argument="--turn-radius")
    plan = plan_patches(
        patches,
        vehicle,
        v0=v0,
        v1=v1,
        distance=distance,
        duration=duration,
        max_slip=max_slip,
        objective=objective,
        intervals=intervals,
        torque_rate=torque_rate,
        confidence=confidence,
        route=False,
        robust_samples=robust_samples,
        max_speed=max_speed,
        slip0=slip0,
    )
    plan = plan_turns(plan, patches, vehicle)  # unchanged without a turn
    return with_fit_headline(plan, (terrain,))


def route_profile(
    route: Route,
    vehicle: Vehicle,
    *,
    intervals: int | None = None,
    torque_rate: float | None = None,
    max_speed: float | None = None,
    slip0: float | None = None,
) -> SpeedPlan:
    """Plan over a :class:`~.route.Route`: mesh points on every patch boundary, at least 2 per patch.

    ``intervals`` defaults to 10 per patch, at least :data:`DEFAULT_INTERVALS`; ``max_speed`` and
    ``slip0`` as for :func:`profile`.
    """
    n = max(DEFAULT_INTERVALS, 10 * len(route.patches)) if intervals is None else intervals
    check_turns(route.patches, vehicle)  # patches with radius_m: before the solve (planning.route_turns)
    plan = plan_patches(
        route.patches,
        vehicle,
        v0=route.v0_m_s,
        v1=route.v_end_m_s,
        distance=route.length_m,
        duration=None,
        max_slip=route.max_slip,
        objective=route.objective,
        intervals=n,
        torque_rate=torque_rate,
        confidence=None,
        route=True,
        max_speed=max_speed,
        slip0=slip0,
    )
    plan = plan_turns(plan, route.patches, vehicle)  # unchanged without turns
    return with_fit_headline(plan, [p.terrain for p in route.patches])
