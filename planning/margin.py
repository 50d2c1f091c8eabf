"""Traversability margin: the thrust the vehicle can get against the resistance it must overcome.

Available thrust (normal load N = W cos(theta) on a grade theta)::

    soil limit        F(i_max) = (A c + N tan(phi)) [1 - K/(i_max l) (1 - exp(-i_max l / K))]
    drivetrain limit  min(T_max / r, P_max / v)   (P_max / v only when a speed is given; the
                                                   track's power, slip losses not deducted)
    available         min(soil limit, drivetrain limit)

Both directions: the required thrust is signed (negative downhill: the soil must hold the vehicle
back). A braking thrust is checked against the soil's skid limit ``|F(-i_max)| = F(i_max)`` (the
library's skid law ``F(i) = -F(|i|)``, a first approximation) and the drivetrain's braking limit,
taken equal to its driving one; the margin is ``available - |required|`` and ``direction`` says
which (``"driving"`` or ``"braking"``). Slope stability (:mod:`.stability`): beyond the static
tipping limit (vehicles with ``cg_height``) or the soil's sliding limit a grade is not traversable
whatever the thrust, and the steepest grades respect both. Fitted effects of a fit JSON are
planned with: ``slip_sinkage`` and ``speed_resistance`` in the required thrust (item
``effects_N``, at the allowed slip and the given speed), ``hump_shear`` and
``pressure_distribution`` in the soil's thrust; the others are named as left out.

Required thrust, itemised: rolling resistance ``mu_r N``, Bekker compaction resistance
(terrain with n, k_c, k_phi; :mod:`soiltrack.soilmodel.sinkage`), grade ``W sin(theta)``,
inertia ``m a``, drawbar pull.

Margin ``available - required`` (N) and ``margin_ratio = margin / available`` (the fraction of
the available thrust left in reserve; negative when short). Go when the margin is >= 0. The
allowed slip ``i_max`` defaults to :data:`DEFAULT_MAX_SLIP` (20 %, a common operating limit of
tracked vehicles: beyond it the tracks dig in and wear).

With a ``FitResult`` (or its JSON) the soil is uncertain: ``p_traversable`` is the probability
of a margin >= 0, by the delta method (normal approximation of the soil limit, AD gradient)
and by Monte Carlo sampling of the fit's Gaussian (clipped to the bounds); Monte Carlo is the
answer (the two agree where the soil limit is close to Gaussian). The worst case over the 95 %
region is the smallest margin found on the 95 % ellipsoid (linearised worst direction) and
among the Monte Carlo samples inside it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..soilmodel import (
    DataError,
    Soil,
    Vehicle,
    choose_scale,
    format_force,
    sensitivity_function,
    slip_from_thrust,
)
from ..soilmodel.sinkage import has_bekker, static_sinkage
from .arguments import check_number
from .fit_vehicle import RESISTANCE_EFFECTS, SHEAR_EFFECTS, check_fit_vehicle, headline_notes
from .forces import resistances, soil_thrust
from .stability import slope_limits
from .uncertainty import CHI2_95, SoilUncertainty, is_online_estimate, uncertainty_from_estimate, uncertainty_from_fit

__all__ = [
    "DEFAULT_MAX_SLIP",
    "DEFAULT_SAMPLES",
    "Margin",
    "margin",
    "resolve_terrain",
    "terrain_soil_vector",
    "drivetrain_limit",
    "split_effects",
]

#: Allowed slip when none is given.
DEFAULT_MAX_SLIP = 0.2
#: Monte Carlo samples of the soil when the terrain is uncertain.
DEFAULT_SAMPLES = 10_000


def _fnum(x) -> float | None:
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


@dataclass(frozen=True)
class Margin:
    """Outcome of :func:`margin` (SI units; ``None`` where a value does not exist).

    Attributes
    ----------
    available_N, required_N, margin_N, margin_ratio
        Available and required thrust, their difference, and the difference over the available
        thrust.
    traversable
        ``margin_N >= 0`` (for an uncertain soil: at the fitted soil, worst ridge point).
    p_traversable, p_traversable_delta, p_traversable_mc
        Probability of a margin >= 0 (Monte Carlo), and both estimates; ``None`` without
        uncertainty.
    worst_case_margin_N
        Smallest margin over the 95 % region of the soil's uncertainty (``None`` without).
    slip_required
        Steady slip at which the soil gives the required thrust; ``None`` when no slip does.
    max_grade_deg
        Steepest grade with a margin >= 0 at the same speed, acceleration and drawbar (negative:
        only downhill works); ``None`` when not even a steep downhill does.
    limited_by, soil_limit_N, drivetrain_limit_N
        Which limit sets the available thrust; both limits (drivetrain ``None``: no limit known).
    required
        ``{"rolling_N", "compaction_N", "grade_N", "inertia_N", "drawbar_N"}``.
    normal_load_N, sinkage_m, max_slip, grade_deg, speed_m_s, accel_m_s2
        Inputs and intermediate values.
    terrain, uncertainty, notes
        Terrain label, how the uncertainty was used (words), remarks.
    """

    available_N: float
    required_N: float
    margin_N: float
    margin_ratio: float
    traversable: bool
    slip_required: float | None
    max_grade_deg: float | None
    limited_by: str
    soil_limit_N: float
    drivetrain_limit_N: float | None
    required: dict
    normal_load_N: float
    sinkage_m: float | None
    max_slip: float
    grade_deg: float
    speed_m_s: float | None
    accel_m_s2: float
    terrain: str
    p_traversable: float | None = None
    p_traversable_delta: float | None = None
    p_traversable_mc: float | None = None
    worst_case_margin_N: float | None = None
    n_samples: int | None = None
    uncertainty: str | None = None
    notes: tuple[str, ...] = field(default=())
    #: ``"driving"`` (the required thrust >= 0) or ``"braking"`` (downhill: the soil holds the vehicle back)
    direction: str = "driving"
    #: steepest downhill grade with a margin >= 0 (deg, negative), ``None`` when none
    min_grade_deg: float | None = None
    #: static tipping limit atan(l / (2 h)) (deg), ``None`` without ``cg_height``
    tipping_limit_deg: float | None = None
    #: grade the soil's full shear strength holds (deg)
    sliding_limit_deg: float | None = None
    #: fitted effects planned with, and fitted effects left out (names)
    effects_planned: tuple[str, ...] = ()
    effects_left_out: tuple[str, ...] = ()
    #: what the first line says about the fit (outcome not usable, other vehicle, effects left out)
    headline: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        """The ``margin --json`` object (docs/data-formats.md); never NaN (``null`` instead)."""
        d = {
            k: getattr(self, k)
            for k in (
                "available_N",
                "required_N",
                "margin_N",
                "margin_ratio",
                "traversable",
                "p_traversable",
                "slip_required",
                "max_grade_deg",
                "limited_by",
                "soil_limit_N",
                "drivetrain_limit_N",
            )
        }
        d["required"] = dict(self.required)
        d.update(
            {
                "p_traversable_delta": self.p_traversable_delta,
                "p_traversable_mc": self.p_traversable_mc,
                "worst_case_margin_N": self.worst_case_margin_N,
                "n_samples": self.n_samples,
                "normal_load_N": self.normal_load_N,
                "sinkage_m": self.sinkage_m,
                "max_slip": self.max_slip,
                "grade_deg": self.grade_deg,
                "speed_m_s": self.speed_m_s,
                "accel_m_s2": self.accel_m_s2,
                "terrain": self.terrain,
                "uncertainty": self.uncertainty,
                "notes": list(self.notes),
                "direction": self.direction,
                "min_grade_deg": self.min_grade_deg,
                "tipping_limit_deg": self.tipping_limit_deg,
                "sliding_limit_deg": self.sliding_limit_deg,
                "tipping_checked": self.tipping_limit_deg is not None,
                "effects_planned": list(self.effects_planned),
                "effects_left_out": list(self.effects_left_out),
                "fit_notes": list(self.headline),
            }
        )
        return {k: (_fnum(v) if isinstance(v, float) else v) for k, v in d.items()}

    def report(self) -> str:
        """Plain-words report with units by magnitude."""
        # one unit for the whole report, chosen by the magnitude of the thrusts compared (N or kN)
        kn = choose_scale([self.available_N, self.required_N, self.soil_limit_N], "N").format
        go = "TRAVERSABLE" if self.traversable else "NOT TRAVERSABLE"
        brake = self.direction == "braking"
        eff = self.required.get("effects_N", 0.0)
        head = f"{self.terrain}, grade {self.grade_deg:g} deg: {go}" + (" (downhill, braking)" if brake else "")
        if self.headline:
            head += " - " + "; ".join(self.headline)
        verb = "braking" if brake else "driving"
        L = [
            head,
            f"  available {verb} thrust {kn(self.available_N)} (limited by the {self.limited_by}: soil at "
            f"{'-' if brake else ''}{self.max_slip * 100:.3g} % slip {kn(self.soil_limit_N)}, drivetrain "
            f"{'unknown' if self.drivetrain_limit_N is None else kn(self.drivetrain_limit_N)})",
            f"  required thrust  {kn(self.required_N)} = rolling {kn(self.required['rolling_N'])} + compaction "
            f"{kn(self.required['compaction_N'])} + grade {kn(self.required['grade_N'])} + inertia "
            f"{kn(self.required['inertia_N'])} + drawbar {kn(self.required['drawbar_N'])}"
            + (f" + fitted effects {kn(eff)}" if self.effects_planned and "effects_N" in self.required else "")
            + (" (negative: a braking thrust)" if brake else ""),
            f"  margin {kn(self.margin_N)} ({self.margin_ratio * 100:.3g} % of the available thrust)",
            "  steady slip needed: "
            + (
                f"none delivers it (the soil cannot give this {verb} thrust)"
                if self.slip_required is None
                else f"{self.slip_required * 100:.3g} %"
            ),
            "  steepest grade: "
            + ("none" if self.max_grade_deg is None else f"{self.max_grade_deg:.3g} deg uphill")
            + ("" if self.min_grade_deg is None else f", {self.min_grade_deg:.3g} deg downhill")
            + (
                f" (static tipping limit {self.tipping_limit_deg:.3g} deg, sliding {self.sliding_limit_deg:.3g} deg)"
                if self.tipping_limit_deg is not None
                else f" (sliding limit {self.sliding_limit_deg:.3g} deg; tipping not checked: no cg_height_m)"
            ),
        ]
        if self.p_traversable is not None:
            L.append(
                f"  probability traversable {self.p_traversable:.3f} (Monte Carlo, {self.n_samples} soils; "
                f"delta method {self.p_traversable_delta:.3f}); worst case over the 95 % region: "
                f"{kn(self.worst_case_margin_N)}"
            )
            L.append(f"  {self.uncertainty}")
        L += [f"  note: {n}" for n in self.notes]
        return "\n".join(L)


def resolve_terrain(terrain: Any, vehicle: Vehicle | None = None) -> tuple[Soil | None, SoilUncertainty | None, str]:
    """``Soil`` -> (soil, None, model); a ``FitResult``, ``SoilUncertainty`` or on-line estimate -> (None,
    uncertainty, model).

    An on-line estimate (:func:`~.uncertainty.is_online_estimate`) needs the ``vehicle``.
    """
    if isinstance(terrain, Soil):
        return terrain, None, "full"
    if isinstance(terrain, SoilUncertainty):
        return None, terrain, terrain.model
    if hasattr(terrain, "theta") and hasattr(terrain, "combinations"):
        u = uncertainty_from_fit(terrain)
        if vehicle is not None and u.context is not None:  # another vehicle than the fit's: said, not refused
            u = replace(u, context=check_fit_vehicle(u.context, vehicle, allow_other=True))
        return None, u, u.model
    if is_online_estimate(terrain):
        if vehicle is None:
            raise DataError("an on-line estimate needs the vehicle to map F_max to the soil")
        u = uncertainty_from_estimate(terrain, vehicle)
        return None, u, u.model
    raise DataError(
        f"terrain must be a Soil (e.g. TERRAINS['dry_sand']), a FitResult, a SoilUncertainty or an "
        f"on-line estimate, got {type(terrain).__name__}"
    )


def terrain_soil_vector(soil: Soil | None, unc: SoilUncertainty | None, normal_load: float) -> np.ndarray:
    """``[c (Pa), phi (rad), K (m)]`` of what :func:`resolve_terrain` gave.

    The soil's own, or (an identified soil) the uncertainty's mean soil at ``normal_load``, N.
    """
    if soil is not None:
        return soil.as_vector()
    assert unc is not None  # resolve_terrain gives a soil or an uncertainty
    return unc.soils_at(unc.mean, normal_load)[0]


def drivetrain_limit(vehicle: Vehicle, speed: float | None) -> float | None:
    """``min(T_max / r, P_max / v)`` in N from what the vehicle gives (``None``: no limit known)."""
    lims = []
    if vehicle.max_sprocket_torque:
        lims.append(vehicle.max_sprocket_torque / vehicle.sprocket_radius)
    if vehicle.max_power and speed:
        lims.append(vehicle.max_power / speed)
    return min(lims) if lims else None


def split_effects(unc: SoilUncertainty | None, effects: dict | None) -> tuple[dict, dict, dict]:
    """``(resistance effects, shear-law effects, {left out: why})`` of an explicit ``effects`` or the fit's."""
    if effects is None:
        ctx = unc.context if unc is not None else None
        effects = dict(ctx.effects) if ctx is not None else {}
        left = ctx.left_out() if ctx is not None else {}
    else:
        left = {k: "not modelled by this planner" for k in effects if k not in RESISTANCE_EFFECTS + SHEAR_EFFECTS}
    res = {k: v for k, v in effects.items() if k in RESISTANCE_EFFECTS}
    shear = {k: v for k, v in effects.items() if k in SHEAR_EFFECTS}
    return res, shear, left


@dataclass(frozen=True)
class _Setting:
    """What a margin at one grade needs besides the grade (internal)."""

    vehicle: Vehicle
    soil: Soil | None
    unc: SoilUncertainty | None
    model: str
    i_max: float
    accel: float
    drawbar: float
    speed: float | None
    dt: float | None
    res_effects: dict
    shear_effects: dict

    def required(self, th: float) -> tuple[float, dict]:
        """Normal load and itemised required thrust at grade ``th`` (rad); signed (negative: braking)."""
        N_arr, req = resistances(
            self.vehicle,
            self.soil,
            np.array([th]),
            self.accel,
            self.drawbar,
            effects=self.res_effects or None,
            slip=self.i_max,
            speed=self.speed or 0.0,
        )
        items = {k: float(v[0]) for k, v in req.items()}
        return float(N_arr[0]), items

    def soil_limit(self, N: float, theta=None) -> float:
        """The soil's thrust at the allowed slip, N: the same driving and braking (skid law F(i) = -F(|i|))."""
        th = terrain_soil_vector(self.soil, self.unc, N) if theta is None else theta
        return float(soil_thrust(th, self.i_max, N, self.vehicle, self.model, effects=self.shear_effects or None)[0])

    def margin_at(self, th: float) -> float:
        """Available minus |required| at grade ``th`` (rad)."""
        N, items = self.required(th)
        F = self.soil_limit(N)
        av = F if self.dt is None else min(F, self.dt)
        return av - abs(sum(items.values()))


def _grade_range(st: _Setting, limit_deg: float) -> tuple[float | None, float | None]:
    """Steepest uphill and downhill grades (deg) with a margin >= 0 and within ``limit_deg``, around grade 0.

    The margin falls both ways from the grade of zero required thrust (uphill the grade adds; downhill the
    braking thrust grows while the soil loses normal load): the feasible grades are one interval, found
    by a 1-degree scan and bisection of its ends. ``(None, None)`` when no grade is feasible.
    """
    lim = min(math.radians(limit_deg), 1.2)  # the grade effect admits |theta| <= 1.2 rad (68.8 deg)
    grid = np.linspace(-lim, lim, 2 * int(math.ceil(math.degrees(lim))) + 1)
    ok = np.array([st.margin_at(float(t)) >= 0 for t in grid])
    if not ok.any():
        return None, None
    k0 = int(np.argmin(np.where(ok, np.abs(grid), np.inf)))  # the feasible grade nearest to flat
    a = b = k0
    while a > 0 and ok[a - 1]:
        a -= 1
    while b < grid.size - 1 and ok[b + 1]:
        b += 1

    def refine(t_in: float, t_out: float) -> float:
        for _ in range(40):
            mid = 0.5 * (t_in + t_out)
            if st.margin_at(mid) >= 0:
                t_in = mid
            else:
                t_out = mid
        return t_in

    up = float(grid[b]) if b == grid.size - 1 else refine(float(grid[b]), float(grid[b + 1]))
    down = float(grid[a]) if a == 0 else refine(float(grid[a]), float(grid[a - 1]))
    return math.degrees(up), math.degrees(down)


def margin(
    terrain: Any,
    vehicle: Vehicle,
    *,
    grade_deg: float = 0.0,
    accel: float = 0.0,
    drawbar_N: float = 0.0,
    speed: float | None = None,
    max_slip: float | None = None,
    samples: int = DEFAULT_SAMPLES,
    seed: int | None = 0,
    effects: dict | None = None,
) -> Margin:
    """Traversability margin of ``vehicle`` on ``terrain`` (see the module docstring).

    Parameters
    ----------
    terrain
        A :class:`~soiltrack.soilmodel.Soil` (a preset of ``TERRAINS`` carries its Bekker
        parameters), a ``FitResult``, or a :class:`~.uncertainty.SoilUncertainty` (from
        :func:`~.uncertainty.load_fit_json`: its fitted effects are planned with).
    vehicle
        The vehicle (its torque and power limits, when given, bound the available thrust; its
        ``cg_height``, when given, the grade by the static tipping limit).
    grade_deg, accel, drawbar_N
        Grade (deg, positive uphill), acceleration (m/s^2) and drawbar pull (N) to sustain.
    speed
        Vehicle speed, m/s (for the power limit); ``None``: power not considered.
    max_slip
        Allowed slip in (0, 1); default :data:`DEFAULT_MAX_SLIP` (braking: the skid -max_slip).
    samples, seed
        Monte Carlo samples of an uncertain soil, and the generator's seed.
    effects
        Effects to plan with, ``{effect: {parameter: value}}`` (default: those of a fit JSON).

    Returns
    -------
    Margin

    Raises
    ------
    DataError
        An argument out of range (named).
    """
    grade_deg = check_number("grade_deg", grade_deg, -68.75, 68.75)
    accel = check_number("accel", accel)
    drawbar = check_number("drawbar_N", drawbar_N)
    if speed is not None:
        speed = check_number("speed", speed, 0, math.inf, lo_open=True)
    i_max = DEFAULT_MAX_SLIP if max_slip is None else check_number("max_slip", max_slip, 0, 1, True, True)
    if not isinstance(samples, int) or samples < 100:
        raise DataError(f"argument samples must be an integer >= 100, got {samples!r}")
    soil, unc, model = resolve_terrain(terrain, vehicle)
    res_eff, shear_eff, left_out = split_effects(unc, effects)
    dt = drivetrain_limit(vehicle, speed)
    st = _Setting(vehicle, soil, unc, model, i_max, accel, drawbar, speed, dt, res_eff, shear_eff)
    N, required = st.required(math.radians(grade_deg))
    R = sum(required.values())
    theta0 = terrain_soil_vector(soil, unc, N)
    soil_at = (
        soil if soil is not None else Soil(float(theta0[0]), float(theta0[1]), float(theta0[2]), name="fitted soil")
    )
    F_soil = st.soil_limit(N, theta0)
    notes = _thrust_notes(st, R)
    available = F_soil if dt is None else min(F_soil, dt)
    m = available - abs(R)
    s_req, ok = slip_from_thrust(
        np.array([R]), soil_at, vehicle, effects=shear_eff or None, model=model, normal_load=N, return_reachable=True
    )
    stab = slope_limits(float(theta0[0]), float(theta0[1]), vehicle)
    limit = min(stab.sliding_deg, stab.tipping_deg if stab.tipping_deg is not None else 90.0)
    max_grade, min_grade = _grade_range(st, limit)
    stable = abs(grade_deg) <= limit
    head = _stability_notes(stab, grade_deg, limit)
    notes = head[:-1] + notes + head[-1:]  # the verdict first, how the limits were found last
    unc_out = _uncertain_margin(st, N, R, F_soil, m, theta0, samples, seed, notes) if unc is not None else {}
    if unc_out and not stable:
        unc_out.update(p_traversable=0.0, p_traversable_mc=0.0, p_traversable_delta=0.0)
    label = soil.name if soil is not None and soil.name else ("identified soil (fit)" if unc is not None else "soil")
    ctx = unc.context if unc is not None else None
    return Margin(
        available_N=float(available),
        required_N=float(R),
        margin_N=float(m),
        margin_ratio=float(m / available) if available > 0 else -math.inf,
        traversable=bool(m >= 0 and stable),
        slip_required=float(s_req[0]) if bool(ok[0]) else None,
        max_grade_deg=max_grade,
        limited_by="soil" if dt is None or F_soil <= dt else "drivetrain",
        soil_limit_N=F_soil,
        drivetrain_limit_N=None if dt is None else float(dt),
        required=required,
        normal_load_N=N,
        sinkage_m=float(static_sinkage(soil, vehicle, N)) if soil is not None and has_bekker(soil) else None,
        max_slip=float(i_max),
        grade_deg=float(grade_deg),
        speed_m_s=speed,
        accel_m_s2=float(accel),
        terrain=label,
        notes=tuple(notes),
        direction="braking" if R < 0 else "driving",
        min_grade_deg=min_grade,
        tipping_limit_deg=stab.tipping_deg,
        sliding_limit_deg=stab.sliding_deg,
        effects_planned=tuple(sorted({**res_eff, **shear_eff})),
        effects_left_out=tuple(sorted(left_out)),
        headline=tuple(headline_notes(ctx, RESISTANCE_EFFECTS + SHEAR_EFFECTS)) if ctx is not None else (),
        **unc_out,
    )


def _thrust_notes(st: _Setting, R: float) -> list[str]:
    """What the thrust comparison leaves out or assumes: compaction, drivetrain limits, braking, effects."""
    notes = []
    soil, vehicle = st.soil, st.vehicle
    if soil is None or not has_bekker(soil):
        notes.append(
            "no Bekker parameters (n, k_c, k_phi) for this terrain: compaction resistance not included"
            if soil is not None
            else "an identified soil has no Bekker parameters: compaction resistance "
            "not included (add it as drawbar_N if known)"
        )
    if st.dt is None:
        notes.append("the vehicle gives no torque or power limit: only the soil limits the thrust")
    elif st.speed is None and vehicle.max_power:
        notes.append("no speed given: the power limit is not considered")
    if R < 0:
        notes.append(
            f"downhill: the soil must hold the vehicle back with a braking thrust of {format_force(-R)} (skid "
            f"at slip -{st.i_max:g}: the library's skid law F(i) = -F(|i|), a first approximation), and the "
            "drivetrain must brake with it (its torque and power limits taken the same both ways)"
        )
    eff = {**st.res_effects, **st.shear_effects}
    if eff:
        notes.append(
            "planned with the fitted effect(s) "
            + ", ".join(f"{k} ({', '.join(f'{p} = {v:.4g}' for p, v in pv.items())})" for k, pv in eff.items())
            + (
                f"; the resistance effects at the allowed slip {st.i_max:g}"
                + (f" and the speed {st.speed:g} m/s" if st.speed else " (speed 0: no speed given)")
                if st.res_effects
                else ""
            )
        )
    return notes


def _stability_notes(stab, grade_deg: float, limit: float) -> list[str]:
    """The stability verdict first (when the grade is beyond a limit), then how the limits were found."""
    if abs(grade_deg) <= limit:
        return [stab.note]
    tips = stab.tipping_deg is not None and abs(grade_deg) > stab.tipping_deg
    why = (
        "the vehicle tips over"
        if tips
        else "a vehicle stopped on it slides: the soil's full shear strength A c + W cos(theta) tan(phi) "
        "does not hold W sin(theta)"
    )
    return [
        f"beyond the static {'tipping' if tips else 'sliding'} limit {limit:.3g} deg ({why}): not traversable "
        "whatever the thrust",
        stab.note,
    ]


def _uncertain_margin(
    st: _Setting, N: float, R: float, F_soil: float, m: float, theta0, samples: int, seed, notes: list
) -> dict:
    """``p_traversable`` (Monte Carlo and delta method) and the worst case over the 95 % region."""
    unc, vehicle, model, i_max, dt = st.unc, st.vehicle, st.model, st.i_max, st.dt
    assert unc is not None
    need = abs(R)
    words = unc.describe(N)
    J = unc.jacobian_at(N)
    g_theta = np.asarray(
        sensitivity_function(model)(i_max, *theta0, N, vehicle.track_length, vehicle.track_width), dtype=float
    ).ravel()
    g = g_theta @ J
    sd = math.sqrt(max(float(g @ unc.cov @ g), 0.0))
    m_soil = F_soil - need
    if not (dt is None or dt >= need):
        p_d = 0.0
    elif sd == 0.0:
        p_d = 1.0 if m_soil >= 0 else 0.0
    else:
        p_d = 0.5 * (1.0 + math.erf(m_soil / (sd * math.sqrt(2.0))))
    eff = st.shear_effects or None
    q = unc.sample(samples, seed)
    Fs = soil_thrust(unc.soils_at(q, N), i_max, N, vehicle, model, effects=eff)
    ms = (Fs if dt is None else np.minimum(Fs, dt)) - need
    p_mc = float(np.mean(ms >= 0))
    r95 = math.sqrt(CHI2_95[unc.dim])
    cands = [m]
    if sd > 0:
        qw = unc.mean - r95 * (unc.cov @ g) / sd
        Fw = float(soil_thrust(unc.soils_at(qw, N), i_max, N, vehicle, model, effects=eff)[0])
        cands.append((Fw if dt is None else min(Fw, dt)) - need)
    d = q - unc.mean
    inside = np.einsum("ij,jk,ik->i", d, np.linalg.pinv(unc.cov), d) <= r95**2
    if np.any(inside):
        cands.append(float(np.min(ms[inside])))
    if abs(p_mc - p_d) > 0.02:
        notes.append(
            f"delta method ({p_d:.3f}) and Monte Carlo ({p_mc:.3f}) differ by more than 0.02: the "
            "soil limit is not close to Gaussian here; the Monte Carlo value is the answer"
        )
    return {
        "p_traversable": p_mc,
        "p_traversable_delta": p_d,
        "p_traversable_mc": p_mc,
        "worst_case_margin_N": float(min(cands)),
        "n_samples": samples,
        "uncertainty": words,
    }
