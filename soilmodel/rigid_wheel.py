"""A single rigid wheel on a test rig (the running gear ``rigid_wheel``), its JSON, and the choice
between it and a tracked vehicle.

JSON (docs/data-formats.md): ``{"running_gear": "rigid_wheel", "wheel_radius_m", "wheel_width_m",
"grouser_height_m"}`` (grouser height optional, 0 for a smooth wheel). A rig has no mass: the
normal load is measured per row and required in its data.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass

from .errors import DataError
from .jsonread import load_json_file, loads_json
from .vehicle import Vehicle

__all__ = ["RigidWheel", "RUNNING_GEARS", "read_running_gear", "WHEEL_LIMITS"]

#: The running gears a JSON file may describe (``"running_gear"``; absent means ``"track"``).
RUNNING_GEARS = ("track", "rigid_wheel")

_JSON_FIELDS = {"wheel_radius_m": "radius", "wheel_width_m": "width", "grouser_height_m": "grouser_height"}
_REQUIRED = ("wheel_radius_m", "wheel_width_m")
#: Plausible ranges (m) of a test wheel's numbers; outside them the input is refused as a likely unit error.
WHEEL_LIMITS = {"radius": (1e-3, 10.0), "width": (1e-3, 10.0), "grouser_height": (0.0, 1.0)}


@dataclass(frozen=True)
class RigidWheel:
    """A rigid wheel on a single-wheel rig, SI units.

    Parameters
    ----------
    radius, width
        Wheel radius r and width b, m.
    grouser_height
        Grouser height h, m (0: smooth); the shear radius is ``r + h``.
    name
        Free text label.
    """

    radius: float
    width: float
    grouser_height: float = 0.0
    name: str = ""

    def __post_init__(self) -> None:
        for attr, (lo, hi) in WHEEL_LIMITS.items():
            v = getattr(self, attr)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise DataError(f"wheel {attr} must be a finite number, got {v!r}")
            if not lo <= v <= hi:
                raise DataError(
                    f"wheel {attr} = {v:.6g} m is outside the plausible range [{lo:g}, {hi:g}] m: "
                    "check the number and its unit"
                )
        if self.grouser_height >= self.radius:
            raise DataError(
                f"wheel grouser_height ({self.grouser_height:g} m) must be below the radius ({self.radius:g} m)"
            )

    @property
    def shear_radius(self) -> float:
        """Radius of the shear surface r + h, m."""
        return self.radius + self.grouser_height

    def to_dict(self) -> dict:
        """The JSON object of docs/data-formats.md."""
        out = {"name": self.name} if self.name else {}
        out["running_gear"] = "rigid_wheel"
        out.update({key: getattr(self, attr) for key, attr in _JSON_FIELDS.items()})
        return out

    def to_json(self) -> str:
        """The wheel as JSON text."""
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_dict(cls, obj: dict, *, source: str | None = None, name: str = "") -> "RigidWheel":
        """Build from a JSON-like dict; errors name ``source`` and the offending field."""
        for key in _REQUIRED:
            if key not in obj:
                raise DataError(f"missing required field '{key}' of a rigid wheel", file=source, column=key)
        allowed = set(_JSON_FIELDS) | {"name", "running_gear"}
        unknown = sorted(set(obj) - allowed)
        if unknown:
            raise DataError(
                f"unknown field(s) {unknown} for a rigid wheel (a rig has no mass: the load is per row "
                f"in the data); expected {sorted(allowed)}",
                file=source,
                column=unknown[0],
            )
        kwargs = {}
        for key, attr in _JSON_FIELDS.items():
            v = obj.get(key)
            if v is None:
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise DataError(f"field '{key}' must be a number, got {v!r}", file=source, column=key)
            kwargs[attr] = float(v)
        try:
            return cls(name=str(obj.get("name", name)), **kwargs)
        except DataError as e:
            col = next((k for k, a in _JSON_FIELDS.items() if f"wheel {a} " in str(e)), None)
            raise DataError(e.reason, file=source, column=col) from None


def read_running_gear(path_or_text: str | os.PathLike) -> Vehicle | RigidWheel:
    """Read a vehicle JSON (track, the default) or a rigid-wheel JSON (``"running_gear": "rigid_wheel"``).

    A path or JSON text starting with ``{``; errors name the file and the field.
    """
    text = os.fspath(path_or_text)
    if text.lstrip().startswith("{"):
        source, obj = "<json text>", loads_json(text, "<json text>", "vehicle JSON")
    else:  # encoding, depth and syntax checked (soilmodel.jsonread)
        source, obj = text, load_json_file(text, "vehicle JSON")
    if not isinstance(obj, dict):
        raise DataError("vehicle JSON must be an object", file=source)
    gear = obj.get("running_gear", "track")
    if gear not in RUNNING_GEARS:
        raise DataError(
            f"unknown running_gear {gear!r}; expected one of {list(RUNNING_GEARS)}",
            file=source,
            column="running_gear",
        )
    label = os.path.splitext(os.path.basename(source))[0] if source != "<json text>" else ""
    if gear == "rigid_wheel":
        return RigidWheel.from_dict(obj, source=source, name=label)
    return Vehicle.from_dict({k: v for k, v in obj.items() if k != "running_gear"}, source=source, name=label)
