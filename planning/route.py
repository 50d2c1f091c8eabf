"""Routes of terrain patches (length, soil, grade) and the ROUTE.json reader (docs/data-formats.md)."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

from ..soilmodel import TERRAINS, DataError, Soil
from ..soilmodel.jsonread import load_json_file
from ..soilmodel.physical import check_physical

__all__ = ["Patch", "Route", "read_route", "route_from_dict", "OBJECTIVES", "MAX_PATCHES", "MAX_ROUTE_LENGTH_M"]

#: Objectives of a profile: minimum time, or minimum sprocket energy.
OBJECTIVES = ("time", "energy")
#: Most patches in a route: the plan's mesh takes 10 intervals a patch by default and at most 2,000
#: in all (merge neighbouring patches of the same terrain, or split the route).
MAX_PATCHES = 200
#: Longest route (and patch), m: 1,000 km is beyond any route planned in one optimal control problem.
MAX_ROUTE_LENGTH_M = 1e6


@dataclass(frozen=True)
class Patch:
    """One stretch of uniform terrain.

    Attributes
    ----------
    length_m
        Length along the path, m (> 0).
    terrain
        The soil (a :class:`~soiltrack.soilmodel.Soil`, e.g. a ``TERRAINS`` preset) or a
        :class:`~.uncertainty.SoilUncertainty` (an identified soil).
    grade_deg
        Grade, deg, positive uphill.
    radius_m
        Turning radius, m, signed (positive to the left); ``None``: straight (:mod:`.route_turns`).
    """

    length_m: float
    terrain: Any
    grade_deg: float = 0.0
    radius_m: float | None = None

    @property
    def label(self) -> str:
        """Short name of the terrain."""
        name = getattr(self.terrain, "name", "") or (
            "identified soil" if not isinstance(self.terrain, Soil) else "soil"
        )
        return name


@dataclass(frozen=True)
class Route:
    """A route: start and end speed, objective, slip limit and patches in driving order."""

    v0_m_s: float
    v_end_m_s: float
    patches: tuple[Patch, ...]
    objective: str = "time"
    max_slip: float | None = None

    @property
    def length_m(self) -> float:
        """Total length, m."""
        return float(sum(p.length_m for p in self.patches))


def _num(
    x: Any,
    field: str,
    src: str | None,
    *,
    lo: float = -math.inf,
    lo_open: bool = False,
    hi: float = math.inf,
    hi_open: bool = False,
) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(float(x)):
        raise DataError(f"field '{field}' must be a finite number, got {x!r}", file=src, column=field)
    x = float(x)
    if x < lo or (lo_open and x == lo) or x > hi or (hi_open and x == hi):
        rng = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
        raise DataError(f"field '{field}' = {x:g} is outside {rng}", file=src, column=field)
    return x


def route_from_dict(obj: Any, *, source: str | None = None, default_terrain: Any = None) -> Route:
    """Build a :class:`Route` from the ROUTE.json object; errors name the file and the field.

    ``default_terrain`` (e.g. the soil of ``--fit``) is used for patches that give neither
    ``terrain`` nor ``soil``.
    """
    src = source
    if not isinstance(obj, dict):
        raise DataError("route JSON must be an object", file=src)
    known = {"v0_m_s", "v_end_m_s", "objective", "max_slip", "patches"}
    unknown = sorted(set(obj) - known)
    if unknown:
        raise DataError(f"unknown field(s) {unknown}; expected {sorted(known)}", file=src)
    pats = obj.get("patches")
    if not isinstance(pats, list) or not pats:
        raise DataError("field 'patches' must be a non-empty list", file=src, column="patches")
    if len(pats) > MAX_PATCHES:
        raise DataError(
            f"{len(pats):,} patches; a route has at most {MAX_PATCHES} (the plan's mesh takes "
            "10 intervals a patch, at most 2,000): merge neighbouring patches of one terrain or "
            "split the route",
            file=src,
            column="patches",
        )
    patches = []
    for k, p in enumerate(pats):
        f = f"patches[{k}]"
        if not isinstance(p, dict):
            raise DataError(f"{f} must be an object", file=src, column=f)
        bad = sorted(set(p) - {"length_m", "terrain", "soil", "grade_deg", "radius_m"})
        if bad:
            raise DataError(f"unknown field(s) {bad} in {f}", file=src, column=f)
        if "length_m" not in p:
            raise DataError(f"missing field '{f}.length_m'", file=src, column=f"{f}.length_m")
        length = _num(p["length_m"], f"{f}.length_m", src, lo=0.0, lo_open=True, hi=MAX_ROUTE_LENGTH_M)
        grade = _num(p.get("grade_deg", 0.0), f"{f}.grade_deg", src, lo=-68.75, hi=68.75)
        if "terrain" in p and "soil" in p:
            raise DataError(f"{f}: give 'terrain' or 'soil', not both", file=src, column=f)
        if "terrain" in p:
            name = p["terrain"]
            if not isinstance(name, str) or name not in TERRAINS:
                raise DataError(
                    f"unknown terrain {name!r} in {f}.terrain; presets: {sorted(TERRAINS)}",
                    file=src,
                    column=f"{f}.terrain",
                )
            terrain = TERRAINS[name]
        elif "soil" in p:
            s = p["soil"]
            if not isinstance(s, dict):
                raise DataError(
                    f"{f}.soil must be an object with cohesion_kpa, friction_angle_deg, shear_modulus_m",
                    file=src,
                    column=f"{f}.soil",
                )
            vals = []
            for key in ("cohesion_kpa", "friction_angle_deg", "shear_modulus_m"):
                if key not in s:
                    raise DataError(f"missing field '{f}.soil.{key}'", file=src, column=f"{f}.soil.{key}")
                vals.append(
                    check_physical(key, _num(s[key], f"{f}.soil.{key}", src), file=src, field=f"{f}.soil.{key}")
                )
            try:
                terrain = Soil.from_kpa_deg(*vals, name=f"soil of patch {k}")
            except DataError as e:
                raise DataError(e.reason, file=src, column=f"{f}.soil") from None
        elif default_terrain is not None:
            terrain = default_terrain
        else:
            raise DataError(f"{f} needs 'terrain' (a preset name) or 'soil' (or pass --fit)", file=src, column=f)
        radius = None if p.get("radius_m") is None else _num(p["radius_m"], f"{f}.radius_m", src)
        if radius == 0.0:
            raise DataError(
                f"{f}.radius_m = 0: a turn's radius is signed (positive to the left) and not 0; leave radius_m out "
                "(or null) for a straight patch",
                file=src,
                column=f"{f}.radius_m",
            )
        patches.append(Patch(length, terrain, grade, radius))
    total = math.fsum(pt.length_m for pt in patches)
    if total > MAX_ROUTE_LENGTH_M:
        raise DataError(
            f"the route is {total:.6g} m long; at most {MAX_ROUTE_LENGTH_M:g} m are planned at once (split the route)",
            file=src,
            column="patches",
        )
    v0 = _num(obj.get("v0_m_s", 0.0), "v0_m_s", src, lo=0.0)
    v1 = _num(obj.get("v_end_m_s", v0), "v_end_m_s", src, lo=0.0)
    objective = obj.get("objective", "time")
    if objective not in OBJECTIVES:
        raise DataError(
            f"field 'objective' must be one of {OBJECTIVES}, got {objective!r}", file=src, column="objective"
        )
    ms = obj.get("max_slip")
    ms = None if ms is None else _num(ms, "max_slip", src, lo=0.0, lo_open=True, hi=1.0, hi_open=True)
    return Route(v0, v1, tuple(patches), objective, ms)


def read_route(path: str, default_terrain: Any = None) -> Route:
    """Read ROUTE.json (docs/data-formats.md); DataError naming the file and the field."""
    src = os.fspath(path)
    obj = load_json_file(src, "route file")  # encoding, depth, syntax (soilmodel.jsonread)
    return route_from_dict(obj, source=src, default_terrain=default_terrain)
