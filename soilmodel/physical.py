"""The range of measured soils, per parameter, for the readers of identified soils (a refusal, not a warning).

The fits' default box is the seed's practical range (:data:`~soiltrack.soilmodel.PRACTICAL_BOUNDS`);
the range of measured soils is :data:`~soiltrack.soilmodel.WIDE_BOUNDS` (c 0-200 kPa, phi 1-55 deg,
K 2-250 mm), which ``--soil`` also enforces. A value outside it in a ``--fit`` file or a route's
patch soil is not an unusual soil but a wrong number (a unit slip, a corrupted file): it is refused
naming the field. This module only names those bounds per JSON field; it adds no range of its own.
"""

from __future__ import annotations

import math

from .errors import DataError
from .soil import WIDE_BOUNDS

__all__ = ["PHYSICAL_RANGES", "check_physical"]

_EDGE = {
    "cohesion_kpa": (0, 1e-3, "kPa", "c in Pa given as kPa?"),
    "friction_angle_deg": (1, 180.0 / math.pi, "deg", "phi in radians, or a typo?"),
    "shear_modulus_m": (2, 1.0, "m", "K in mm given as m?"),
}

#: ``field -> (low, high, unit, likely cause)`` in the units of the fit JSON, from :data:`WIDE_BOUNDS`.
PHYSICAL_RANGES: dict[str, tuple[float, float, str, str]] = {
    key: (float(WIDE_BOUNDS.lower[j] * f), float(WIDE_BOUNDS.upper[j] * f), unit, why)
    for key, (j, f, unit, why) in _EDGE.items()
}


def check_physical(name: str, value: float, *, file: str | None = None, field: str | None = None) -> float:
    """``value`` of the soil parameter ``name`` (a key of :data:`PHYSICAL_RANGES`) if within the range.

    Raises DataError naming ``file`` and ``field`` otherwise.
    """
    lo, hi, unit, why = PHYSICAL_RANGES[name]
    v = float(value)
    if not math.isfinite(v) or not lo - 1e-9 * abs(lo) <= v <= hi + 1e-9 * abs(hi):
        raise DataError(
            f"{name} = {v:g} {unit} is outside the range of measured soils [{lo:g}, {hi:g}] {unit} ({why})",
            file=file,
            column=field or name,
        )
    return v
