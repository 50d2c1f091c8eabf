"""Static slope stability of a tracked vehicle on a longitudinal grade: tipping and sliding.

Tipping (needs ``cg_height_m`` in the vehicle JSON). The vehicle tips over the downhill end of
its ground contact when the weight's line of action passes that end::

    tan(theta_tip) = (l / 2) / h

with l the contact length of the track and h the height of the centre of gravity above the
ground contact. Assumptions, said in every report that uses it: the centre of gravity lies
midway along the contact length (no longitudinal offset), the vehicle is static (no
acceleration, no drawbar pull at a hitch height, no dynamic load transfer), the contact ends are
the tipping edges (a sprocket or idler beyond them, which would widen the base, is ignored), the
ground is rigid under the edge (sinkage would tilt the vehicle further: the limit is not
conservative on soft soil), and the grade is longitudinal (no side slope: lateral tipping is not
checked). The same angle holds uphill (tipping backwards) and downhill (forwards).

Sliding. The soil's full shear strength ``F_max = A c + W cos(theta) tan(phi)`` (Eq. 2 at full
shear displacement, both tracks locked or driven) must hold the grade's ``W sin(theta)``; the
steepest grade it holds solves ``W sin(theta) = A c + W cos(theta) tan(phi)``, i.e.
``theta_slide = phi + asin(A c cos(phi) / W)`` (90 deg when the argument reaches 1). It is an
upper bound of what the thrust margin allows at a slip limit (F(i_max) < F_max); it is reported
because a parked or crawling vehicle is held by the full strength, not by the slip limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..soilmodel import Vehicle

__all__ = ["SlopeLimits", "slope_limits", "tipping_limit_deg", "sliding_limit_deg"]


@dataclass(frozen=True)
class SlopeLimits:
    """Static slope limits (deg, magnitudes: the same uphill and downhill).

    Attributes
    ----------
    tipping_deg
        ``atan(l / (2 h))``; ``None`` without a centre-of-gravity height.
    sliding_deg
        ``phi + asin(A c cos(phi) / W)`` of the soil used (at most 90).
    note
        How the limits were found, or that tipping is not checked.
    """

    tipping_deg: float | None
    sliding_deg: float
    note: str

    def to_dict(self) -> dict:
        """JSON-ready dict."""
        return {"tipping_limit_deg": self.tipping_deg, "sliding_limit_deg": self.sliding_deg}


def tipping_limit_deg(vehicle: Vehicle) -> float | None:
    """Static tipping grade ``atan(l / (2 h))`` in degrees (``None`` without ``cg_height``)."""
    h = vehicle.cg_height
    if h is None:
        return None
    return math.degrees(math.atan2(0.5 * vehicle.track_length, h))


def sliding_limit_deg(c: float, phi: float, vehicle: Vehicle) -> float:
    """Steepest grade (deg) the soil's full shear strength holds: ``phi + asin(A c cos(phi) / W)``.

    ``c`` in Pa, ``phi`` in rad (SI).
    """
    arg = vehicle.contact_area * max(c, 0.0) * math.cos(phi) / vehicle.weight
    return 90.0 if arg >= 1.0 else min(90.0, math.degrees(phi + math.asin(arg)))


def slope_limits(c: float, phi: float, vehicle: Vehicle) -> SlopeLimits:
    """Tipping and sliding limits of ``vehicle`` on a soil with cohesion ``c`` (Pa) and friction angle ``phi`` (rad)."""
    tip = tipping_limit_deg(vehicle)
    slide = sliding_limit_deg(c, phi, vehicle)
    if tip is None:
        note = (
            "tipping not checked: the vehicle gives no cg_height_m (add it to the vehicle JSON for the static "
            "tipping limit atan(l / (2 h)))"
        )
    else:
        note = (
            f"static tipping limit {tip:.3g} deg = atan(l / (2 h)), l = {vehicle.track_length:g} m, "
            f"h = {vehicle.cg_height:g} m (centre of gravity midway along the contact, static, rigid edge, "
            "no side slope)"
        )
    return SlopeLimits(tip, slide, note)
