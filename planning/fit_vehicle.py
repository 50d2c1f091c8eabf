"""What a fit JSON says beyond the soil: its outcome, the running gear it was fitted with, its effects.

Every planning command given ``--fit`` reads these through :func:`read_fit_context` (called by
:func:`~soiltrack.planning.uncertainty.load_fit_json`) and

* checks the fit's ``running_gear`` against the vehicle it plans for
  (:func:`check_fit_vehicle`): weight, contact area and track length must agree within
  :data:`VEHICLE_TOLERANCE`; beyond it the plan is refused (``DataError``, exit 2) naming both
  vehicles, unless the caller allows another vehicle on purpose (``--allow-other-vehicle``):
  then the soil is mapped with the fit's own contact area and load (c, phi, K are soil
  properties; F_max is not) and the report says so;
* says on its first line when the fit's ``outcome`` is not ``usable``, when the fit records no
  running gear (the vehicle cannot be checked), and which fitted effects the plan leaves out
  (:func:`headline_notes`).

The effects are split by what a plan can do with them (:data:`RESISTANCE_EFFECTS` enter the
required thrust, :data:`SHEAR_EFFECTS` the soil's thrust law; the others describe the data's
sensors or setup and are left out, named).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from ..soilmodel import DataError, Vehicle, format_force

__all__ = [
    "FitContext",
    "VEHICLE_TOLERANCE",
    "OUTCOMES",
    "RESISTANCE_EFFECTS",
    "SHEAR_EFFECTS",
    "read_fit_context",
    "check_fit_vehicle",
    "headline_notes",
]

#: Largest relative difference of weight, contact area and track length between the fitted running gear
#: and the planned vehicle (5 %: a payload change of a few percent keeps the fit's F_max meaningful; beyond
#: it the soil limit at the other load rests on the c/phi split, which one load does not determine).
VEHICLE_TOLERANCE = 0.05
#: A fit's outcome (DESIGN section 9).
OUTCOMES = ("usable", "poor_fit", "not_usable", "failed")
#: The words of fit JSONs written before that vocabulary: "converged" is a fit whose answer stands.
_LEGACY_OUTCOMES = {"converged": "usable", "not usable": "not_usable"}
#: Effects that add to the motion resistance: planned with in the required thrust.
RESISTANCE_EFFECTS = ("slip_sinkage", "speed_resistance")
#: Effects that change the soil's thrust-slip law: planned with in the available thrust.
SHEAR_EFFECTS = ("hump_shear", "pressure_distribution")
#: Why each other effect is left out of a plan.
_LEFT_OUT_WHY = {
    "grade": "the slope of the measured data, not of the planned terrain",
    "drivetrain_friction": "a loss between the torque sensor and the track of the measured run",
    "radius_error": "a sensor calibration of the measured run",
    "mass_error": "the payload of the measured run (give the planned vehicle's mass instead)",
}


@dataclass(frozen=True)
class FitContext:
    """The fit JSON's outcome, running gear and effects.

    Attributes
    ----------
    source
        The file.
    outcome, outcome_reason
        ``usable`` | ``poor_fit`` | ``not_usable`` | ``failed`` (``None``: the JSON has none) and its reason.
    running_gear
        The ``running_gear`` object (``None``: the JSON records none).
    effects
        ``{effect: {parameter: value}}`` (SI) of the fitted effects.
    other_vehicle
        Set by :func:`check_fit_vehicle` when the fit is of another vehicle, allowed on purpose (words).
    """

    source: str
    outcome: str | None = None
    outcome_reason: str | None = None
    running_gear: dict | None = None
    effects: dict = field(default_factory=dict)
    other_vehicle: str | None = None

    def planned_effects(self) -> dict:
        """The fitted effects a plan uses (resistance and shear law), ``{effect: {parameter: value}}``."""
        return {k: v for k, v in self.effects.items() if k in RESISTANCE_EFFECTS + SHEAR_EFFECTS}

    def left_out(self, planned: tuple[str, ...] = RESISTANCE_EFFECTS + SHEAR_EFFECTS) -> dict:
        """``{effect: why}`` of the fitted effects a plan that uses ``planned`` leaves out."""
        out = {}
        for k in self.effects:
            if k in planned:
                continue
            if k in RESISTANCE_EFFECTS + SHEAR_EFFECTS:
                out[k] = "the profile and route planners do not model it yet; margin plans with it"
            else:
                out[k] = _LEFT_OUT_WHY.get(k, "not modelled by the planners")
        return out


def _value(p: Any) -> float | None:
    v = p.get("value") if isinstance(p, dict) else p
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
        return None
    return float(v)


def read_fit_context(obj: dict, src: str) -> FitContext:
    """Outcome, running gear and effects of a fit JSON object (DataError naming a malformed field)."""
    outcome = obj.get("outcome")
    outcome = _LEGACY_OUTCOMES.get(outcome, outcome) if isinstance(outcome, str) else outcome
    if outcome is not None and outcome not in OUTCOMES:
        raise DataError(f"outcome must be one of {', '.join(OUTCOMES)}, got {outcome!r}", file=src, column="outcome")
    gear = obj.get("running_gear")
    if gear is not None and not isinstance(gear, dict):
        raise DataError("running_gear must be an object", file=src, column="running_gear")
    effects: dict = {}
    raw = obj.get("effects") or {}
    if not isinstance(raw, dict):
        raise DataError("effects must be an object {effect: {parameter: {value, ...}}}", file=src, column="effects")
    for name, params in raw.items():
        if not isinstance(params, dict):
            raise DataError(f"effects.{name} must be an object", file=src, column=f"effects.{name}")
        vals = {}
        for pname, p in params.items():
            v = _value(p)
            if v is None:
                raise DataError(
                    f"effects.{name}.{pname}.value must be a finite number", file=src, column=f"effects.{name}.{pname}"
                )
            vals[pname] = v
        effects[str(name)] = vals
    return FitContext(src, outcome, obj.get("outcome_reason"), gear, effects)


def _rel(a: float, b: float) -> float:
    return abs(a - b) / max(abs(b), 1e-300)


def check_fit_vehicle(
    ctx: FitContext, vehicle: Vehicle, *, allow_other: bool = False, tolerance: float = VEHICLE_TOLERANCE
) -> FitContext:
    """Check the fit's running gear against ``vehicle``; returns ``ctx`` (with ``other_vehicle`` set when allowed).

    Raises
    ------
    DataError
        The fit is of a rig (a wheel or a bevameter) or of a vehicle whose weight, contact area or track
        length differs by more than ``tolerance`` (relative), and ``allow_other`` is false.
    """
    g = ctx.running_gear
    if g is None:
        return ctx
    kind = g.get("kind")
    gear_name = g.get("name") or kind or "?"
    diffs = []
    if kind != "track":
        diffs.append(f"it is a {kind} fit, not of a tracked vehicle")
    for key, mine, unit in (
        ("weight_N", vehicle.weight, "N"),
        ("contact_area_m2", vehicle.contact_area, "m^2"),
        ("track_length_m", vehicle.track_length, "m"),
    ):
        theirs = g.get(key)
        if kind == "track" and isinstance(theirs, (int, float)) and not isinstance(theirs, bool):
            if _rel(float(theirs), mine) > tolerance:
                fmt = format_force if unit == "N" else (lambda x, u=unit: f"{x:.4g} {u}")
                diffs.append(f"{key} {fmt(float(theirs))} against {fmt(mine)}")
    if not diffs:
        return ctx
    planned = vehicle.name or "the given vehicle"
    what = (
        f"the fit {ctx.source!r} is of another running gear ({gear_name}) than the planned vehicle ({planned}): "
        + "; ".join(diffs)
        + f" (tolerance {tolerance * 100:g} %)"
    )
    if not allow_other:
        raise DataError(
            what + "; fit data of this vehicle, or pass --allow-other-vehicle to map the soil to it on purpose",
            file=ctx.source,
            column="running_gear",
        )
    if kind != "track":
        raise DataError(what + "; a rig fit cannot be mapped to a tracked vehicle here", file=ctx.source)
    return FitContext(
        ctx.source,
        ctx.outcome,
        ctx.outcome_reason,
        ctx.running_gear,
        ctx.effects,
        what + "; allowed on purpose (--allow-other-vehicle): the soil (c, phi, K) is mapped with the fit's own "
        "contact area and load and used at this vehicle's load",
    )


def headline_notes(ctx: FitContext | None, planned: tuple[str, ...]) -> list[str]:
    """What the first line of a plan's report must say about its fit (empty when nothing)."""
    if ctx is None:
        return []
    out = []
    if ctx.outcome is not None and ctx.outcome != "usable":
        out.append(f"the fit's outcome is {ctx.outcome}" + (f" ({ctx.outcome_reason})" if ctx.outcome_reason else ""))
    if ctx.running_gear is None:
        out.append("the fit records no running gear: the vehicle cannot be checked against it")
    if ctx.other_vehicle:
        out.append("fit of another vehicle, scaled on purpose")
    lo = ctx.left_out(planned)
    if lo:
        out.append("fitted effect(s) left out: " + ", ".join(f"{k} ({why})" for k, why in lo.items()))
    return out
