"""Soil parameters, terrain presets and the seed's practical soil ranges (SI inside)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .errors import DataError

#: Names of the three identified soil parameters, in the order used by every vector.
PARAMETER_NAMES = ("cohesion", "friction_angle", "shear_modulus")


@dataclass(frozen=True)
class Soil:
    """Soil parameters of the Mohr-Coulomb / Janosi-Hanamoto model, SI units.

    Parameters
    ----------
    cohesion
        c in Pa (>= 0).
    friction_angle
        phi in rad, in (0, pi/2).
    shear_modulus
        Shear deformation modulus K in m (> 0).
    name
        Free text label.
    n, k_c, k_phi
        Optional Bekker pressure-sinkage parameters: exponent n (-), k_c in N/m^(n+1),
        k_phi in N/m^(n+2). Needed only for compaction resistance.
    shear_modulus_typical
        True when K is a typical value for the soil class rather than a measured one.

    Notes
    -----
    Use :meth:`from_kpa_deg` to build one from the units terramechanics tables use.
    """

    cohesion: float
    friction_angle: float
    shear_modulus: float
    name: str = ""
    n: float | None = None
    k_c: float | None = None
    k_phi: float | None = None
    shear_modulus_typical: bool = field(default=False)

    def __post_init__(self) -> None:
        for attr in ("cohesion", "friction_angle", "shear_modulus"):
            v = getattr(self, attr)
            if not isinstance(v, (int, float, np.floating, np.integer)) or not math.isfinite(float(v)):
                raise DataError(f"soil {attr} must be a finite number, got {v!r}")
        if self.cohesion < 0:
            raise DataError(f"soil cohesion must be >= 0 Pa, got {self.cohesion}")
        if not 0 < self.friction_angle < math.pi / 2:
            raise DataError(
                f"soil friction angle must lie in (0, 90) deg, got {math.degrees(self.friction_angle):.6g} deg"
            )
        if self.shear_modulus <= 0:
            raise DataError(f"soil shear deformation modulus K must be > 0 m, got {self.shear_modulus}")
        if self.n is not None and self.n <= 0:
            raise DataError(f"Bekker exponent n must be > 0, got {self.n}")

    @classmethod
    def from_kpa_deg(cls, cohesion_kpa: float, friction_angle_deg: float, shear_modulus_m: float, **kwargs) -> "Soil":
        """Build from c in kPa, phi in degrees and K in m (Bekker k_c, k_phi stay SI)."""
        return cls(
            cohesion=float(cohesion_kpa) * 1e3,
            friction_angle=math.radians(friction_angle_deg),
            shear_modulus=float(shear_modulus_m),
            **kwargs,
        )

    @property
    def cohesion_kpa(self) -> float:
        """c in kPa."""
        return self.cohesion / 1e3

    @property
    def friction_angle_deg(self) -> float:
        """phi in degrees."""
        return math.degrees(self.friction_angle)

    def as_vector(self) -> np.ndarray:
        """``[c (Pa), phi (rad), K (m)]``."""
        return np.array([self.cohesion, self.friction_angle, self.shear_modulus], dtype=float)

    def __str__(self) -> str:
        label = f"{self.name}: " if self.name else ""
        return (
            f"{label}c = {self.cohesion_kpa:.4g} kPa, phi = {self.friction_angle_deg:.4g} deg, "
            f"K = {self.shear_modulus:.4g} m"
        )


@dataclass(frozen=True)
class SoilBounds:
    """Box bounds on ``[c (Pa), phi (rad), K (m)]`` for identification."""

    cohesion: tuple[float, float]
    friction_angle: tuple[float, float]
    shear_modulus: tuple[float, float]

    def __post_init__(self) -> None:
        for attr in PARAMETER_NAMES:
            lo, hi = getattr(self, attr)
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise DataError(f"bounds on {attr} must be finite with lower < upper, got ({lo}, {hi})")

    @classmethod
    def from_kpa_deg(
        cls,
        cohesion_kpa: tuple[float, float],
        friction_angle_deg: tuple[float, float],
        shear_modulus_m: tuple[float, float],
    ) -> "SoilBounds":
        """Build from c in kPa, phi in degrees and K in m."""
        return cls(
            (cohesion_kpa[0] * 1e3, cohesion_kpa[1] * 1e3),
            (math.radians(friction_angle_deg[0]), math.radians(friction_angle_deg[1])),
            (float(shear_modulus_m[0]), float(shear_modulus_m[1])),
        )

    @property
    def lower(self) -> np.ndarray:
        """Lower bounds ``[c, phi, K]`` (SI)."""
        return np.array([self.cohesion[0], self.friction_angle[0], self.shear_modulus[0]])

    @property
    def upper(self) -> np.ndarray:
        """Upper bounds ``[c, phi, K]`` (SI)."""
        return np.array([self.cohesion[1], self.friction_angle[1], self.shear_modulus[1]])


#: The seed's "practical range": c 0-69 kPa, phi 6-40 deg, K 0.006-0.05 m. Note that the
#: seed's own "actual" phi (40.1 deg) lies just outside it; a fit that ends on a bound says so.
PRACTICAL_BOUNDS = SoilBounds.from_kpa_deg((0.0, 69.0), (6.0, 40.0), (0.006, 0.05))
#: Soils a measurement can still come from beyond the practical range: dense sands and gravels
#: (phi to 55 deg), stiff clays (c to 200 kPa), firm soils under small rig tracks (K from 2 mm:
#: below it a sweep whose readings all sit near one level, e.g. a load cell at its limit, would
#: read as a soil) and loose snow (K to 0.25 m). The diagnosis widens to them when the data want
#: a soil outside the practical range (:func:`soiltrack.identify.diagnose`).
WIDE_BOUNDS = SoilBounds.from_kpa_deg((0.0, 200.0), (1.0, 55.0), (0.002, 0.25))


def _terrain(
    key: str, name: str, n: float, k_c_kn: float, k_phi_kn: float, c_kpa: float, phi_deg: float, K: float, typical: bool
) -> Soil:
    return Soil.from_kpa_deg(
        c_kpa, phi_deg, K, name=name, n=n, k_c=k_c_kn * 1e3, k_phi=k_phi_kn * 1e3, shear_modulus_typical=typical
    )


#: Terrain presets (Wong, Theory of Ground Vehicles, as widely tabulated). Only LETE sand has a
#: measured K (0.012 m); every other K is a typical value for the soil class
#: (firm sand 0.01 m, compact clay 0.006 m, loose soil and fresh snow 0.025 m) and is flagged
#: ``shear_modulus_typical=True``.
TERRAINS: dict[str, Soil] = {
    "dry_sand": _terrain("dry_sand", "dry sand (Land Locomotion Lab)", 1.1, 0.99, 1528.43, 1.04, 28.0, 0.025, True),
    "sandy_loam": _terrain("sandy_loam", "sandy loam (LLL, 15 % moisture)", 0.7, 5.27, 1515.04, 1.72, 29.0, 0.01, True),
    "clayey_soil": _terrain("clayey_soil", "clayey soil (Thailand, 38 %)", 0.5, 13.19, 692.15, 4.14, 13.0, 0.006, True),
    "heavy_clay": _terrain("heavy_clay", "heavy clay (WES, 25 %)", 0.13, 12.70, 1555.95, 68.95, 34.0, 0.006, True),
    "lean_clay": _terrain("lean_clay", "lean clay (WES, 22 %)", 0.2, 16.43, 1724.69, 68.95, 20.0, 0.006, True),
    "lete_sand": _terrain("lete_sand", "LETE sand", 0.79, 102.0, 5301.0, 1.3, 31.1, 0.012, False),
    "snow": _terrain("snow", "snow (US)", 1.6, 4.37, 196.72, 1.03, 19.7, 0.025, True),
}

#: The seed's "actual" soil for Wong (2001) p. 176: c = 0.55 kPa, phi = 40.1 deg, K = 0.018 m.
SEED_ACTUAL = Soil.from_kpa_deg(0.55, 40.1, 0.018, name="seed's actual values (Wong 2001 p. 176)")
