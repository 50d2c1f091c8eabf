"""What a controller believes about the soil under and ahead of it: prior, on-line estimate or the truth.

A :class:`SoilBelief` is the thrust law a controller uses: the thrust limit ``F_max`` at the
patch's normal load and the shear modulus ``K`` (Eq. 2 is ``F = F_max g(i l / K)``; c and phi
enter only through F_max at one load). Three sources:

- :class:`PriorSoil`: the route's planned soil of each patch (no estimator: the ``nominal_soil``
  baseline);
- :class:`TrueSoil`: the plant's true soil (the ``true_soil`` bound);
- :class:`EstimatedSoil`: the on-line estimator inside (:class:`soiltrack.identify.online.OnlineEstimator`
  by default; any object with the same ``update`` and an estimate with ``max_thrust_N``,
  ``shear_modulus_m``, ``identifiable``, ``slope_N``, ``change_detected`` drops in). Before the
  estimate identifies F_max it is fused with the prior: the identified small-slip slope
  ``F_max l / (2 K)`` with the prior's F_max gives K; with nothing identified, the prior.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Callable, Sequence

from ...soilmodel import DataError, Soil, Vehicle
from ...soilmodel.effects import effective_normal_load
from ...soilmodel.traction import max_thrust_expr

#: An identified F_max is taken (and held) only with a standard error within this fraction of it: the
#: estimator calls F_max identified up to 25 %, too loose for a controller that acts on it.
MAX_REL_STDERR = 0.10

__all__ = ["MAX_REL_STDERR", "SoilBelief", "PriorSoil", "TrueSoil", "EstimatedSoil", "soil_of", "patch_load"]


@dataclass(frozen=True)
class SoilBelief:
    """The thrust law a controller uses now (SI).

    Attributes
    ----------
    max_thrust_N, shear_modulus_m
        F_max at the patch's normal load, and K.
    source
        ``"prior"``, ``"true"``, ``"estimate"`` (F_max identified), ``"slope+prior"`` (only the
        small-slip slope identified: the prior's F_max, K from the slope).
    """

    max_thrust_N: float
    shear_modulus_m: float
    source: str


def soil_of(terrain: Any) -> Soil:
    """A :class:`Soil` from a route patch's terrain (a Soil, or an identified soil's mean)."""
    if isinstance(terrain, Soil):
        return terrain
    mean = getattr(terrain, "mean_soil", None)
    if callable(mean) and hasattr(terrain, "fitted_load"):
        return mean(terrain.fitted_load)
    raise DataError(f"a controller's prior needs a Soil for every patch, got {type(terrain).__name__}")


def patch_load(vehicle: Vehicle, grade_deg: float) -> float:
    """Normal load on a grade, N (soilmodel's one home of the grade's load)."""
    return float(effective_normal_load(vehicle.weight, vehicle, {"grade": math.radians(grade_deg)}))


def _belief(soil: Soil, vehicle: Vehicle, grade_deg: float, source: str) -> SoilBelief:
    N = patch_load(vehicle, grade_deg)
    F = float(max_thrust_expr(soil.cohesion, soil.friction_angle, N, vehicle.contact_area))
    return SoilBelief(F, float(soil.shear_modulus), source)


class PriorSoil:
    """The planned soil of each patch (``soils``, one per patch; ``grades_deg`` alike)."""

    source = "prior"

    def __init__(self, vehicle: Vehicle, soils: Sequence[Soil], grades_deg: Sequence[float]) -> None:
        self._b = [_belief(s, vehicle, g, self.source) for s, g in zip(soils, grades_deg)]

    def update(self, time_s: float, torque: float, w: float, v: float, accel: float | None, patch: int) -> None:
        """Nothing to learn."""

    def belief(self, patch: int, current: int) -> SoilBelief:
        """Belief about ``patch`` while the vehicle is on ``current``."""
        return self._b[min(patch, len(self._b) - 1)]

    @property
    def events(self) -> list[dict]:
        return []


class TrueSoil(PriorSoil):
    """The plant's true soil of each patch (the bound of what identification can give)."""

    source = "true"


class EstimatedSoil(PriorSoil):
    """The on-line estimate of the soil under the vehicle, fused with the prior (module docstring).

    Parameters
    ----------
    vehicle, soils, grades_deg
        As :class:`PriorSoil` (the prior).
    estimator_factory
        ``factory(vehicle, grade_rad) -> estimator`` (default
        :class:`~soiltrack.identify.online.OnlineEstimator` with ``OnlineSettings(grade_rad=...)``);
        a new estimator is made when the vehicle enters a patch of another grade (its normal load
        changes, and with it F_max).
    """

    source = "estimate"

    def __init__(
        self,
        vehicle: Vehicle,
        soils: Sequence[Soil],
        grades_deg: Sequence[float],
        estimator_factory: Callable[[Vehicle, float], Any] | None = None,
    ) -> None:
        super().__init__(vehicle, soils, grades_deg)
        self.vehicle = vehicle
        self._grades = list(grades_deg)
        self._soils = list(soils)
        self._factory = estimator_factory or _default_factory
        self._est = self._factory(vehicle, math.radians(self._grades[0]))
        self._key = (self._grades[0], self._soils[0])
        self._last: Any = None
        self._held: SoilBelief | None = None
        self._events: list[dict] = []
        self.update_times_s: list[float] = []

    def update(self, time_s: float, torque: float, w: float, v: float, accel: float | None, patch: int) -> None:
        """Feed one sample (torque applied, sprocket speed, vehicle speed) to the estimator.

        Entering a patch of another grade (another normal load, so another F_max) or another planned
        soil starts a new estimator: the old horizon describes the ground behind.
        """
        k = min(patch, len(self._grades) - 1)
        key = (self._grades[k], self._soils[k])
        if key != self._key:
            self._est = self._factory(self.vehicle, math.radians(key[0]))
            self._key, self._last, self._held = key, None, None
        t0 = time.perf_counter()
        e = self._est.update(time_s, torque, w, v, accel)
        self.update_times_s.append(time.perf_counter() - t0)
        self._last = e
        if getattr(e, "change_detected", False):
            self._held = None
            self._events.append(
                {
                    "time_s": float(time_s),
                    "kind": "change_detected",
                    "change_time_s": getattr(e, "change_time_s", None),
                    "reason": "the estimator detected a change of terrain",
                }
            )
        ident = tuple(getattr(e, "identifiable", ()) or ())
        se = getattr(e, "max_thrust_stderr_N", None)
        precise = se is not None and e.max_thrust_N and se <= MAX_REL_STDERR * e.max_thrust_N
        if "max_thrust" in ident and e.max_thrust_N is not None and precise:
            K = e.shear_modulus_m if "shear_modulus" in ident else None
            if K is None and e.slope_N:
                K = e.max_thrust_N * self.vehicle.track_length / (2.0 * e.slope_N)
            self._held = SoilBelief(float(e.max_thrust_N), float(K or self._b[k].shear_modulus_m), "estimate")

    def belief(self, patch: int, current: int) -> SoilBelief:
        """The estimate for the patch under the vehicle, the prior for the others.

        F_max identified now: the estimate. Identified earlier on this patch (no change detected
        since): that estimate, held (``"held estimate"``). Only the small-slip slope: the prior's
        F_max with the K of that slope (``"slope+prior"``). Nothing: the prior.
        """
        prior = super().belief(patch, current)
        e = self._last
        if patch != current or e is None or e.max_thrust_N is None:
            return SoilBelief(prior.max_thrust_N, prior.shear_modulus_m, "prior")
        ident = tuple(getattr(e, "identifiable", ()) or ())
        if self._held is not None:
            return (
                self._held
                if "max_thrust" in ident
                else SoilBelief(self._held.max_thrust_N, self._held.shear_modulus_m, "held estimate")
            )
        if "slope" in ident and e.slope_N and e.slope_N > 0:
            K = prior.max_thrust_N * self.vehicle.track_length / (2.0 * e.slope_N)
            return SoilBelief(prior.max_thrust_N, float(min(max(K, 1e-3), 0.5)), "slope+prior")
        return SoilBelief(prior.max_thrust_N, prior.shear_modulus_m, "prior")

    @property
    def estimate(self) -> Any:
        """The estimator's last estimate (``None`` before the first update)."""
        return self._last

    @property
    def events(self) -> list[dict]:
        return self._events


def _default_factory(vehicle: Vehicle, grade_rad: float) -> Any:
    from ...identify.online import OnlineEstimator, OnlineSettings

    return OnlineEstimator(vehicle, OnlineSettings(grade_rad=float(grade_rad)))
