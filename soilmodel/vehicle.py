"""Vehicle description (SI), JSON I/O per docs/data-formats.md, and the reference vehicles."""

from __future__ import annotations

import difflib
import json
import math
import os
from dataclasses import dataclass, fields

from .errors import DataError
from .jsonread import load_json_file, loads_json

#: Standard gravity, m/s^2.
G = 9.81

_JSON_FIELDS = {  # JSON key -> dataclass field
    "mass_kg": "mass",
    "track_length_m": "track_length",
    "track_width_m": "track_width",
    "sprocket_radius_m": "sprocket_radius",
    "sprocket_inertia_kg_m2": "sprocket_inertia",
    "rolling_resistance": "rolling_resistance",
    "max_sprocket_torque_Nm": "max_sprocket_torque",
    "max_power_W": "max_power",
    "road_wheels": "road_wheels",
    "ground_clearance_m": "ground_clearance",
    "tread_m": "tread",
    "yaw_inertia_kg_m2": "yaw_inertia",
    "cg_height_m": "cg_height",
}
#: Plausible ranges (SI) of the vehicle's numbers; anything outside is refused at input, because a
#: typo (a mass of 1e300 kg, a track 500 m long) would otherwise surface as overflow deep in a solver.
#: Generous on purpose: the largest tracked machines (bucket-wheel excavators) weigh about 1.4e7 kg.
LIMITS = {
    "mass": (1e-3, 1e8, "kg"),
    "track_length": (1e-3, 100.0, "m"),
    "track_width": (1e-3, 20.0, "m"),
    "sprocket_radius": (1e-3, 10.0, "m"),
    "sprocket_inertia": (0.0, 1e8, "kg m^2"),
    "max_sprocket_torque": (0.0, 1e9, "N m"),
    "max_power": (0.0, 1e9, "W"),
    "tread": (1e-3, 100.0, "m"),
    "yaw_inertia": (0.0, 1e12, "kg m^2"),
    "cg_height": (0.0, 50.0, "m"),
}

_REQUIRED = (
    "mass_kg",
    "track_length_m",
    "track_width_m",
    "sprocket_radius_m",
    "sprocket_inertia_kg_m2",
    "rolling_resistance",
)


@dataclass(frozen=True)
class Vehicle:
    """A tracked vehicle in straight-line motion, SI units.

    Parameters
    ----------
    mass
        m in kg; the normal load is ``W = m g`` with g = 9.81 m/s^2.
    track_length, track_width
        Contact length l and width b of ONE track, m. Contact area of both tracks A = 2 b l.
    sprocket_radius
        r in m.
    sprocket_inertia
        I of both sprockets and what turns with them, kg m^2.
    rolling_resistance
        Coefficient of longitudinal (motion) resistance mu_r (-).
    max_sprocket_torque, max_power
        Drivetrain limits of both tracks together (N m, W); ``None`` when unknown.
    road_wheels
        Road wheels per side (used by the pressure-distribution effect); ``None`` when unknown.
    ground_clearance
        Height of the belly above the track's ground contact, m (stuck prediction: sinkage
        reaching the belly); ``None`` when unknown.
    tread
        Distance B between the two tracks' centre lines, m (the steering model); ``None`` when
        unknown (then nothing can turn).
    yaw_inertia
        Yaw moment of inertia Iz of the whole vehicle about its centre of gravity, kg m^2; ``None``:
        the steering model assumes a uniform box over the tracks, ``m (l^2 + (B + b)^2) / 12``.
    cg_height
        Height of the centre of gravity above the track's ground contact, m (static tipping limit
        on a grade, :func:`soiltrack.planning.stability.slope_limits`; lateral load transfer in a
        turn); ``None`` when unknown (tipping not checked, no load transfer).
    name
        Free text label.
    """

    mass: float
    track_length: float
    track_width: float
    sprocket_radius: float
    sprocket_inertia: float
    rolling_resistance: float
    max_sprocket_torque: float | None = None
    max_power: float | None = None
    road_wheels: int | None = None
    name: str = ""
    ground_clearance: float | None = None
    tread: float | None = None
    yaw_inertia: float | None = None
    cg_height: float | None = None

    def __post_init__(self) -> None:
        positive = ("mass", "track_length", "track_width", "sprocket_radius")
        for f in fields(self):
            if f.name in ("name", "road_wheels"):
                continue
            v = getattr(self, f.name)
            if v is None:
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise DataError(f"vehicle {f.name} must be a finite number, got {v!r}")
            if f.name in positive and v <= 0:
                raise DataError(f"vehicle {f.name} must be > 0, got {v}")
            if v < 0:
                raise DataError(f"vehicle {f.name} must be >= 0, got {v}")
            if f.name in (
                "max_sprocket_torque",
                "max_power",
                "ground_clearance",
                "tread",
                "yaw_inertia",
                "cg_height",
            ) and (v == 0):
                raise DataError(f"vehicle {f.name} must be > 0 (or absent), got {v}")
        for name, (lo, hi, unit) in LIMITS.items():
            v = getattr(self, name)
            if v is not None and not (v == 0 and lo == 0) and not lo <= v <= hi:
                raise DataError(
                    f"vehicle {name} = {v:.6g} {unit} is outside the plausible range [{lo:g}, {hi:g}] "
                    f"{unit}: check the number and its unit"
                )
        if self.rolling_resistance >= 1:
            raise DataError(f"vehicle rolling_resistance must be < 1, got {self.rolling_resistance}")
        if self.tread is not None and self.tread <= self.track_width:
            raise DataError(
                f"vehicle tread {self.tread:g} m (between the track centre lines) must exceed the track width "
                f"{self.track_width:g} m: the two tracks would overlap"
            )
        rw = self.road_wheels
        if rw is not None and (isinstance(rw, bool) or not isinstance(rw, int) or not 1 <= rw <= 100):
            raise DataError(f"vehicle road_wheels must be a positive integer (at most 100), got {rw!r}")

    @property
    def weight(self) -> float:
        """Normal load W = m g, N."""
        return self.mass * G

    @property
    def contact_area(self) -> float:
        """Contact area of both tracks A = 2 b l, m^2."""
        return 2.0 * self.track_width * self.track_length

    @property
    def yaw_inertia_or_box(self) -> float:
        """Iz, kg m^2: the given ``yaw_inertia``, else a uniform box over the tracks (needs ``tread``)."""
        if self.yaw_inertia is not None:
            return self.yaw_inertia
        if self.tread is None:
            raise DataError("the vehicle has no tread_m (distance between the track centre lines)", column="tread_m")
        return self.mass * (self.track_length**2 + (self.tread + self.track_width) ** 2) / 12.0

    @property
    def mean_pressure(self) -> float:
        """Mean ground pressure p = W / A, Pa."""
        return self.weight / self.contact_area

    # --- JSON -------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The JSON object of docs/data-formats.md (optional fields and ``name`` only when set)."""
        out = {"name": self.name} if self.name else {}
        for key, attr in _JSON_FIELDS.items():
            v = getattr(self, attr)
            if v is not None:
                out[key] = v
        return out

    def to_json(self) -> str:
        """The vehicle as JSON text (the fields of docs/data-formats.md)."""
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_dict(cls, obj: dict, *, source: str | None = None, name: str = "") -> "Vehicle":
        """Build from a JSON-like dict; errors name ``source`` and the offending field."""
        if not isinstance(obj, dict):
            raise DataError("vehicle JSON must be an object", file=source)
        known = set(_JSON_FIELDS) | {"name"}
        unknown = sorted(k for k in obj if k not in known)  # first: a typo also "misses" the field it meant
        if unknown:
            hints = []
            for k in unknown:
                close = difflib.get_close_matches(str(k), known, 1)
                hints.append(f"'{k}'" + (f" (did you mean '{close[0]}'?)" if close else ""))
            raise DataError(
                f"unknown field{'s' if len(unknown) > 1 else ''} {', '.join(hints)}; the fields "
                f"are {', '.join(sorted(_JSON_FIELDS))} and name",
                file=source,
                column=str(unknown[0]),
            )
        for key in _REQUIRED:
            if key not in obj:
                raise DataError(f"missing required field '{key}'", file=source, column=key)
        kwargs = {}
        for key, attr in _JSON_FIELDS.items():
            if key not in obj or obj[key] is None:
                continue
            v = obj[key]
            if key == "road_wheels":
                if isinstance(v, float) and v.is_integer():
                    v = int(v)
            elif isinstance(v, bool) or not isinstance(v, (int, float)):
                raise DataError(f"field '{key}' must be a number, got {v!r}", file=source, column=key)
            else:
                v = float(v)
            kwargs[attr] = v
        try:
            return cls(name=str(obj.get("name", name)), **kwargs)
        except DataError as e:
            attr_to_key = {a: k for k, a in _JSON_FIELDS.items()}
            col = next((attr_to_key[a] for a in attr_to_key if f"vehicle {a} " in str(e)), None)
            raise DataError(e.reason, file=source, column=col) from None

    @classmethod
    def from_json(cls, path_or_text: str | os.PathLike) -> "Vehicle":
        """Read a vehicle from a JSON file path (or from JSON text starting with ``{``)."""
        text = os.fspath(path_or_text)
        if text.lstrip().startswith("{"):
            source, obj = "<json text>", loads_json(text, "<json text>", "vehicle JSON")
        else:  # encoding, depth and syntax checked (soilmodel.jsonread)
            source, obj = text, load_json_file(text, "vehicle JSON")
        return cls.from_dict(
            obj, source=source, name=os.path.splitext(os.path.basename(source))[0] if source != "<json text>" else ""
        )


#: Reference vehicles. The heavy vehicle's W = 329 kN is Wong's (2001, p. 176); its geometry
#: (l = 2.8 m, b = 0.5 m, r = 0.3 m, I = 500 kg m^2, 5 road wheels a side) and drivetrain limits
#: are ASSUMPTIONS of this library - the seed gives none of them. The light vehicle
#: (W = 300 N) is the seed's cohesion-study vehicle with assumed geometry and limits.
VEHICLES: dict[str, Vehicle] = {
    "heavy": Vehicle(
        mass=329_000.0 / G,
        track_length=2.8,
        track_width=0.5,
        sprocket_radius=0.3,
        sprocket_inertia=500.0,
        rolling_resistance=0.05,
        max_sprocket_torque=80_000.0,
        max_power=600_000.0,
        road_wheels=5,
        name="heavy (W = 329 kN, Wong 2001 p. 176; geometry assumed)",
    ),
    "light": Vehicle(
        mass=300.0 / G,
        track_length=0.5,
        track_width=0.1,
        sprocket_radius=0.08,
        sprocket_inertia=0.05,
        rolling_resistance=0.05,
        max_sprocket_torque=40.0,
        max_power=500.0,
        road_wheels=4,
        name="light (W = 300 N, seed's cohesion study; geometry assumed)",
    ),
}
