"""Physical ranges of the soil parameters: what no soil can have (a refusal, not a warning).

The practical range (:data:`~soiltrack.soilmodel.PRACTICAL_BOUNDS`, the seed's soils) and the
widened one (:data:`~soiltrack.soilmodel.WIDE_BOUNDS`) bound the fits. These are wider: a value
outside them is not an unusual soil but a wrong number (a unit slip, a corrupted file), and the
readers of identified soils (``--fit`` files) refuse it naming the field.
"""

from __future__ import annotations

import math

from .errors import DataError

__all__ = ["PHYSICAL_RANGES", "check_physical"]

#: ``name -> (low, high, unit, why)``, in the units of the fit JSON. Cohesion: the stiffest clays
#: reach a few hundred kPa (1,000 kPa is rock, not a soil for Eq. 2). Friction angle: above 0
#: (a frictionless soil has no Eq. 8) and below 70 deg (the densest gravels reach about 55 deg).
#: Shear deformation modulus K: 0.1 mm to 1 m (measured soils: about 1 mm to 0.25 m).
PHYSICAL_RANGES: dict[str, tuple[float, float, str, str]] = {
    "cohesion_kpa": (0.0, 1000.0, "kPa", "no soil's cohesion is negative or above 1,000 kPa (rock)"),
    "friction_angle_deg": (0.0, 70.0, "deg", "a friction angle lies in (0, 70) deg"),
    "shear_modulus_m": (1e-4, 1.0, "m", "K lies between 0.1 mm and 1 m (K in mm given as m?)"),
}


def check_physical(name: str, value: float, *, file: str | None = None, field: str | None = None) -> float:
    """``value`` of the soil parameter ``name`` (a key of :data:`PHYSICAL_RANGES`) if physical.

    Raises DataError naming ``file`` and ``field`` otherwise.
    """
    lo, hi, unit, why = PHYSICAL_RANGES[name]
    v = float(value)
    open_lo = name == "friction_angle_deg"
    if not math.isfinite(v) or v < lo or (open_lo and v <= lo) or v > hi:
        raise DataError(
            f"{name} = {v:g} {unit} is outside the physical range "
            f"{'(' if open_lo else '['}{lo:g}, {hi:g}] {unit}: {why}",
            file=file,
            column=field or name,
        )
    return v
