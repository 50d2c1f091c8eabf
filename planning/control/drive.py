"""A controller and its baselines on one route over the true terrain (what ``soiltrack drive`` runs).

Baselines of the same run: ``pi`` (no soil knowledge), ``fixed_slip_7`` and ``fixed_slip_20``
(a fixed slip ceiling held by feedback; ``fixed_slip`` is the better of the two: arrived first,
else fewer stuck events), ``nominal_soil`` (the same controller on the route's planned soil, no
estimator) and ``true_soil`` (the same controller given the true soil). For ``pi``, which uses no
soil, ``nominal_soil`` and ``true_soil`` are the ``slip`` controller's (said in ``notes``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

from ...soilmodel import DataError, Soil, Vehicle
from ..margin import DEFAULT_MAX_SLIP
from .belief import soil_of
from .controllers import CONTROLLERS, make_controller
from .loop import ClosedLoop, run_closed_loop
from .plant import PlantSettings, TerrainPatch, TrackPlant

__all__ = ["drive", "DriveResult", "BASELINES"]

BASELINES = ("pi", "fixed_slip_7", "fixed_slip_20", "nominal_soil", "true_soil")


@dataclass(frozen=True)
class DriveResult:
    """The chosen controller's run and the baselines' (``{name: ClosedLoop}``)."""

    controller: str
    run: ClosedLoop
    baselines: dict[str, ClosedLoop]
    notes: tuple[str, ...] = field(default=())

    @property
    def fixed_slip_best(self) -> str:
        """The better fixed-slip baseline's name."""
        a, b = self.baselines["fixed_slip_7"], self.baselines["fixed_slip_20"]

        def key(r: ClosedLoop) -> tuple:
            return (not r.arrived, r.metrics["time_s"] or math.inf, r.metrics["stuck_events"])

        return "fixed_slip_7" if key(a) <= key(b) else "fixed_slip_20"


def drive(
    kind: str,
    vehicle: Vehicle,
    route: Any,
    true_soils: Sequence[Soil] | None = None,
    *,
    true_slip_sinkage: Sequence[float] | None = None,
    plant_settings: PlantSettings | None = None,
    target_speed_m_s: float | None = None,
    max_time_s: float | None = None,
    baselines: Sequence[str] = BASELINES,
    record_every: int = 1,
    plant_factory: Callable[[list[TerrainPatch]], Any] | None = None,
    **settings: Any,
) -> DriveResult:
    """Run controller ``kind`` and the ``baselines`` over ``route`` on the true soils (module docstring).

    Parameters
    ----------
    kind
        ``"pi"``, ``"slip"`` or ``"mpc"``.
    vehicle, route
        The vehicle and a :class:`~soiltrack.planning.Route` (its patches' soils are the planned ones).
    true_soils
        The true soil of each patch (default: the planned ones).
    true_slip_sinkage
        The true ``mu_s`` of each patch (soilmodel's ``slip_sinkage`` effect; default 0 everywhere).
    plant_settings
        Noise, delay, sample time (default: :class:`~.plant.PlantSettings` starting at the route's ``v0_m_s``).
    target_speed_m_s
        Speed to track (default the larger of ``v0_m_s`` and ``v_end_m_s``).
    max_time_s
        Time allowed (default: 3 times the route at the target speed, plus 30 s).
    plant_factory
        ``factory(true_patches) -> plant`` (any object with ``step(torque) -> measurement``; a fresh
        one per run); default the library's :class:`~.plant.TrackPlant` with ``plant_settings``.
    """
    if kind not in CONTROLLERS:
        raise DataError(f"unknown controller {kind!r}; expected one of {CONTROLLERS}", column="--controller")
    planned = [soil_of(p.terrain) for p in route.patches]
    truth = list(true_soils) if true_soils is not None else planned
    if len(truth) != len(planned):
        raise DataError(f"{len(truth)} true soils for {len(planned)} patches")
    v_t = float(target_speed_m_s if target_speed_m_s is not None else max(route.v0_m_s, route.v_end_m_s))
    if not (math.isfinite(v_t) and v_t > 0):
        raise DataError("the target speed (the larger of v0_m_s and v_end_m_s) must be > 0", column="v_end_m_s")
    ps = plant_settings or PlantSettings(v0=route.v0_m_s, slip0=0.0)
    t_max = max_time_s or 3.0 * route.length_m / v_t + 30.0
    lim = route.max_slip or settings.get("max_slip") or DEFAULT_MAX_SLIP
    mus = [float(x) for x in true_slip_sinkage] if true_slip_sinkage is not None else [0.0] * len(truth)
    if len(mus) != len(truth):
        raise DataError(f"{len(mus)} slip-sinkage coefficients for {len(truth)} patches")
    patches = [TerrainPatch(p.length_m, s, p.grade_deg, m) for p, s, m in zip(route.patches, truth, mus)]
    notes = []
    same = "slip" if kind == "pi" else kind
    if kind == "pi":
        notes.append("pi uses no soil: nominal_soil and true_soil are the slip controller's")
    plan: dict[str, tuple[str, dict[str, Any]]] = {kind: (kind, {})}
    for b in baselines:
        if b == "pi":
            plan[b] = ("pi", {})
        elif b.startswith("fixed_slip_"):
            plan[b] = ("fixed_slip", {"fixed_slip": int(b.rsplit("_", 1)[1]) / 100})
        elif b == "nominal_soil":
            plan[b] = (same, {"soil": "nominal"})
        elif b == "true_soil":
            plan[b] = (same, {"soil": "true", "true_soils": truth, "true_slip_sinkage": mus})
        else:
            raise DataError(f"unknown baseline {b!r}; expected some of {BASELINES}")
    runs = {}
    for name, (k, extra) in plan.items():
        ctl = make_controller(k, vehicle, route=route, target_speed_m_s=v_t, sample_s=ps.dt, **settings, **extra)
        runs[name] = run_closed_loop(
            ctl,
            plant_factory(patches) if plant_factory is not None else TrackPlant(vehicle, patches, ps),
            distance_m=route.length_m,
            target_speed_m_s=v_t,
            max_slip=lim,
            max_time_s=t_max,
            record_every=record_every,
        )
    main = runs.pop(kind)
    return DriveResult(kind, main, runs, tuple(notes))
