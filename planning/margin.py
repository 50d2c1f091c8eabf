"""Traversability margin: the thrust the vehicle can get against the resistance it must overcome.

Available thrust (normal load N = W cos(theta) on a grade theta)::

    soil limit        F(i_max) = (A c + N tan(phi)) [1 - K/(i_max l) (1 - exp(-i_max l / K))]
    drivetrain limit  min(T_max / r, P_max / v)   (P_max / v only when a speed is given; the
                                                   track's power, slip losses not deducted)
    available         min(soil limit, drivetrain limit)

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
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..soilmodel import DataError, Soil, Vehicle, choose_scale, sensitivity_function, slip_from_thrust
from ..soilmodel.sinkage import has_bekker, static_sinkage
from .arguments import check_number
from .forces import resistances, soil_thrust
from .uncertainty import CHI2_95, SoilUncertainty, is_online_estimate, uncertainty_from_estimate, uncertainty_from_fit

__all__ = [
    "DEFAULT_MAX_SLIP",
    "DEFAULT_SAMPLES",
    "Margin",
    "margin",
    "resolve_terrain",
    "terrain_soil_vector",
    "drivetrain_limit",
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
            }
        )
        return {k: (_fnum(v) if isinstance(v, float) else v) for k, v in d.items()}

    def report(self) -> str:
        """Plain-words report with units by magnitude."""
        # one unit for the whole report, chosen by the magnitude of the thrusts compared (N or kN)
        kn = choose_scale([self.available_N, self.required_N, self.soil_limit_N], "N").format
        go = "TRAVERSABLE" if self.traversable else "NOT TRAVERSABLE"
        L = [
            f"{self.terrain}, grade {self.grade_deg:g} deg: {go}",
            f"  available thrust {kn(self.available_N)} (limited by the {self.limited_by}: soil at "
            f"{self.max_slip * 100:.3g} % slip {kn(self.soil_limit_N)}, drivetrain "
            f"{'unknown' if self.drivetrain_limit_N is None else kn(self.drivetrain_limit_N)})",
            f"  required thrust  {kn(self.required_N)} = rolling {kn(self.required['rolling_N'])} + compaction "
            f"{kn(self.required['compaction_N'])} + grade {kn(self.required['grade_N'])} + inertia "
            f"{kn(self.required['inertia_N'])} + drawbar {kn(self.required['drawbar_N'])}",
            f"  margin {kn(self.margin_N)} ({self.margin_ratio * 100:.3g} % of the available thrust)",
            "  steady slip needed: "
            + (
                "none delivers it (the soil cannot give this thrust)"
                if self.slip_required is None
                else f"{self.slip_required * 100:.3g} %"
            ),
            "  steepest grade: " + ("none" if self.max_grade_deg is None else f"{self.max_grade_deg:.3g} deg"),
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
) -> Margin:
    """Traversability margin of ``vehicle`` on ``terrain`` (see the module docstring).

    Parameters
    ----------
    terrain
        A :class:`~soiltrack.soilmodel.Soil` (a preset of ``TERRAINS`` carries its Bekker
        parameters), a ``FitResult``, or a :class:`~.uncertainty.SoilUncertainty` (from
        :func:`~.uncertainty.load_fit_json`).
    vehicle
        The vehicle (its torque and power limits, when given, bound the available thrust).
    grade_deg, accel, drawbar_N
        Grade (deg, positive uphill), acceleration (m/s^2) and drawbar pull (N) to sustain.
    speed
        Vehicle speed, m/s (for the power limit); ``None``: power not considered.
    max_slip
        Allowed slip in (0, 1); default :data:`DEFAULT_MAX_SLIP`.
    samples, seed
        Monte Carlo samples of an uncertain soil, and the generator's seed.

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
    th = math.radians(grade_deg)
    notes: list[str] = []
    N_arr, req = resistances(vehicle, soil, np.array([th]), accel, drawbar)
    N = float(N_arr[0])
    required = {k: float(v[0]) for k, v in req.items()}
    R = sum(required.values())
    if soil is None or not has_bekker(soil):
        notes.append(
            "no Bekker parameters (n, k_c, k_phi) for this terrain: compaction resistance not included"
            if soil is not None
            else "an identified soil has no Bekker parameters: compaction resistance "
            "not included (add it as drawbar_N if known)"
        )
    theta0 = terrain_soil_vector(soil, unc, N)
    soil_at = (
        soil if soil is not None else Soil(float(theta0[0]), float(theta0[1]), float(theta0[2]), name="fitted soil")
    )
    F_soil = float(soil_thrust(theta0, i_max, N, vehicle, model)[0])
    dt = drivetrain_limit(vehicle, speed)
    if dt is None:
        notes.append("the vehicle gives no torque or power limit: only the soil limits the thrust")
    elif speed is None and vehicle.max_power:
        notes.append("no speed given: the power limit is not considered")
    available = F_soil if dt is None else min(F_soil, dt)
    limited_by = "soil" if dt is None or F_soil <= dt else "drivetrain"
    m = available - R
    s_req, ok = slip_from_thrust(np.array([R]), soil_at, vehicle, model=model, normal_load=N, return_reachable=True)
    slip_required = float(s_req[0]) if bool(ok[0]) else None

    # steepest grade: margin(theta) falls with theta (the soil loses normal load, the grade adds)
    def m_of(t):
        Nt, rq = resistances(vehicle, soil, np.array([t]), accel, drawbar)
        th_t = terrain_soil_vector(soil, unc, float(Nt[0]))
        Fs = float(soil_thrust(th_t, i_max, Nt, vehicle, model)[0])
        av = Fs if dt is None else min(Fs, dt)
        return av - sum(float(v[0]) for v in rq.values())

    lim = 1.2  # the grade effect admits |theta| <= 1.2 rad (68.8 deg)
    lo: float | None
    hi: float | None
    if m_of(0.0) >= 0:
        lo, hi = 0.0, lim
        if m_of(hi) >= 0:
            lo = hi
    elif m_of(-lim) >= 0:
        lo, hi = -lim, 0.0
    else:
        lo = hi = None
    if lo is not None and hi is not None and lo != hi:
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            if m_of(mid) >= 0:
                lo = mid
            else:
                hi = mid
    max_grade = None if lo is None else math.degrees(lo)
    sink = float(static_sinkage(soil, vehicle, N)) if soil is not None and has_bekker(soil) else None

    p = p_d = p_mc = worst = None
    n_s = None
    words = None
    if unc is not None:
        words = unc.describe(N)
        J = unc.jacobian_at(N)
        g_theta = np.asarray(
            sensitivity_function(model)(i_max, *theta0, N, vehicle.track_length, vehicle.track_width), dtype=float
        ).ravel()
        g = g_theta @ J
        var = float(g @ unc.cov @ g)
        sd = math.sqrt(max(var, 0.0))
        m_soil = F_soil - R
        dt_ok = dt is None or dt >= R
        if not dt_ok:
            p_d = 0.0
        elif sd == 0.0:
            p_d = 1.0 if m_soil >= 0 else 0.0
        else:
            p_d = 0.5 * (1.0 + math.erf(m_soil / (sd * math.sqrt(2.0))))
        q = unc.sample(samples, seed)
        Fs = soil_thrust(unc.soils_at(q, N), i_max, N, vehicle, model)
        av_s = Fs if dt is None else np.minimum(Fs, dt)
        ms = av_s - R
        p_mc = float(np.mean(ms >= 0))
        n_s = samples
        r95 = math.sqrt(CHI2_95[unc.dim])
        cands = [m]
        if sd > 0:
            qw = unc.mean - r95 * (unc.cov @ g) / sd
            Fw = float(soil_thrust(unc.soils_at(qw, N), i_max, N, vehicle, model)[0])
            cands.append((Fw if dt is None else min(Fw, dt)) - R)
        Linv = np.linalg.pinv(unc.cov)
        d = q - unc.mean
        inside = np.einsum("ij,jk,ik->i", d, Linv, d) <= r95**2
        if np.any(inside):
            cands.append(float(np.min(ms[inside])))
        worst = float(min(cands))
        p = p_mc
        if abs(p_mc - p_d) > 0.02:
            notes.append(
                f"delta method ({p_d:.3f}) and Monte Carlo ({p_mc:.3f}) differ by more than 0.02: the "
                "soil limit is not close to Gaussian here; the Monte Carlo value is the answer"
            )
    label = soil.name if soil is not None and soil.name else ("identified soil (fit)" if unc is not None else "soil")
    return Margin(
        available_N=float(available),
        required_N=float(R),
        margin_N=float(m),
        margin_ratio=float(m / available) if available > 0 else -math.inf,
        traversable=bool(m >= 0),
        slip_required=slip_required,
        max_grade_deg=max_grade,
        limited_by=limited_by,
        soil_limit_N=F_soil,
        drivetrain_limit_N=None if dt is None else float(dt),
        required=required,
        normal_load_N=N,
        sinkage_m=sink,
        max_slip=float(i_max),
        grade_deg=float(grade_deg),
        speed_m_s=speed,
        accel_m_s2=float(accel),
        terrain=label,
        p_traversable=p,
        p_traversable_delta=p_d,
        p_traversable_mc=p_mc,
        worst_case_margin_N=worst,
        n_samples=n_s,
        uncertainty=words,
        notes=tuple(notes),
    )
