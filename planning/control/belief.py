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
from functools import lru_cache
from typing import Any, Callable, Sequence

from ...soilmodel import DataError, Soil, Vehicle
from ...soilmodel.effects import effective_normal_load
from ...soilmodel.traction import max_thrust_expr

#: Slip sinkage on-line (:class:`SinkageEstimator`): samples per block (one point of the hull balance),
#: the standard error of ``mu_s`` below which it is used, and the fewest blocks.
SINKAGE_BLOCK, SINKAGE_MAX_SE, SINKAGE_MIN_BLOCKS = 5, 0.1, 4
#: Below this vehicle speed (m/s) a block is left out (the resistance is not fully mobilised at rest).
SINKAGE_MIN_SPEED = 0.05

#: An identified F_max is taken (and held) only with a standard error within this fraction of it: the
#: estimator calls F_max identified up to 25 %, too loose for a controller that acts on it.
MAX_REL_STDERR = 0.10

__all__ = [
    "MAX_REL_STDERR",
    "SinkageEstimator",
    "SoilBelief",
    "PriorSoil",
    "TrueSoil",
    "EstimatedSoil",
    "soil_of",
    "patch_load",
]


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
    slip_sinkage
        ``mu_s`` of soilmodel's ``slip_sinkage`` effect (extra resistance ``N mu_s |i|``), -.
    """

    max_thrust_N: float
    shear_modulus_m: float
    source: str
    slip_sinkage: float = 0.0


def soil_of(terrain: Any) -> Soil:
    """A :class:`Soil` from a route patch's terrain (a Soil, or an identified soil's mean)."""
    if isinstance(terrain, Soil):
        return terrain
    mean = getattr(terrain, "mean_soil", None)
    if callable(mean) and hasattr(terrain, "fitted_load"):
        return mean(terrain.fitted_load)
    raise DataError(f"a controller's prior needs a Soil for every patch, got {type(terrain).__name__}")


@lru_cache(maxsize=1024)
def patch_load(vehicle: Vehicle, grade_deg: float) -> float:
    """Normal load on a grade, N (soilmodel's one home of the grade's load; cached: asked at every sample)."""
    return float(effective_normal_load(vehicle.weight, vehicle, {"grade": math.radians(grade_deg)}))


def _belief(soil: Soil, vehicle: Vehicle, grade_deg: float, source: str, mu_s: float = 0.0) -> SoilBelief:
    N = patch_load(vehicle, grade_deg)
    F = float(max_thrust_expr(soil.cohesion, soil.friction_angle, N, vehicle.contact_area))
    return SoilBelief(F, float(soil.shear_modulus), source, float(mu_s))


class SinkageEstimator:
    """The slip-sinkage coefficient ``mu_s`` of the patch under the vehicle, from the hull balance.

    Per block of :data:`SINKAGE_BLOCK` samples: the thrust the sprocket torque transmits
    (``(M - I dw/dt) / r``) minus the hull's inertia ``m dv/dt`` and the known resistance
    (``mu_r N + W sin(theta)``, :func:`patch_load`) is the extra resistance ``N mu_s i``
    (soilmodel's ``slip_sinkage`` effect); ``mu_s`` by least squares through zero over the blocks.
    """

    def __init__(self, vehicle: Vehicle, grade_deg: float) -> None:
        self.vehicle = vehicle
        self.N = patch_load(vehicle, grade_deg)
        self.R0 = vehicle.rolling_resistance * self.N + vehicle.weight * math.sin(math.radians(grade_deg))
        self._buf: list[tuple[float, float, float, float]] = []
        self._sxx = self._sxy = self._syy = 0.0
        self.blocks = 0
        self._value: tuple[float, float] | None = None

    def update(self, time_s: float, torque: float, w: float, v: float) -> None:
        """Add one sample (time, sprocket torque of both tracks, sprocket speed, vehicle speed)."""
        self._buf.append((time_s, torque, w, v))
        if len(self._buf) < SINKAGE_BLOCK:
            return
        ts, Ms, ws, vs = zip(*self._buf)
        self._buf = []
        n = len(ts)
        h = n // 2
        t0, t1 = sum(ts[:h]) / h, sum(ts[h:]) / (n - h)
        w0, w1 = sum(ws[:h]) / h, sum(ws[h:]) / (n - h)
        v0, v1 = sum(vs[:h]) / h, sum(vs[h:]) / (n - h)
        V, r = self.vehicle, self.vehicle.sprocket_radius
        if t1 <= t0 or min(v0, v1) < SINKAGE_MIN_SPEED:
            return
        M = sum(Ms) / n
        F = (M - V.sprocket_inertia * (w1 - w0) / (t1 - t0)) / r
        rw = r * 0.5 * (w0 + w1)
        i = (rw - 0.5 * (v0 + v1)) / max(rw, 0.01)
        y = F - V.mass * (v1 - v0) / (t1 - t0) - self.R0
        x = self.N * abs(i)
        self._sxx += x * x
        self._sxy += x * y
        self._syy += y * y
        self.blocks += 1
        self._value = self._fit()

    @property
    def value(self) -> tuple[float, float] | None:
        """``(mu_s, standard error)`` once it is identified (:data:`SINKAGE_MAX_SE`), else ``None`` (the fit of
        the last block: asked at every sample, it changes once a block)."""
        return self._value

    def _fit(self) -> tuple[float, float] | None:
        """The least-squares ``mu_s`` through zero over the blocks and its standard error, or ``None``."""
        if self.blocks < SINKAGE_MIN_BLOCKS or self._sxx <= 0:
            return None
        mu = self._sxy / self._sxx
        var = max(self._syy - mu * self._sxy, 0.0) / (self.blocks - 1)
        se = math.sqrt(var / self._sxx)
        return (max(mu, 0.0), se) if se <= SINKAGE_MAX_SE else None


class PriorSoil:
    """The planned soil of each patch (``soils``, one per patch; ``grades_deg`` alike; ``slip_sinkage``:
    each patch's ``mu_s``, default 0)."""

    source = "prior"

    def __init__(
        self,
        vehicle: Vehicle,
        soils: Sequence[Soil],
        grades_deg: Sequence[float],
        slip_sinkage: Sequence[float] | None = None,
    ) -> None:
        mus = list(slip_sinkage) if slip_sinkage is not None else [0.0] * len(soils)
        self._b = [_belief(s, vehicle, g, self.source, m) for s, g, m in zip(soils, grades_deg, mus)]

    def update(
        self, time_s: float, torque: float, w: float, v: float, accel: float | None, patch: int, learn: bool = True
    ) -> None:
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
        a new estimator is made when the vehicle enters another patch of the route (see :meth:`update`).
    """

    source = "estimate"

    def __init__(
        self,
        vehicle: Vehicle,
        soils: Sequence[Soil],
        grades_deg: Sequence[float],
        estimator_factory: Callable[[Vehicle, float], Any] | None = None,
        slip_sinkage: Sequence[float] | None = None,
    ) -> None:
        super().__init__(vehicle, soils, grades_deg, slip_sinkage)
        self._prior = [SoilBelief(b.max_thrust_N, b.shear_modulus_m, "prior", b.slip_sinkage) for b in self._b]
        self.changes = 0  # changes of terrain the estimator detected
        self.vehicle = vehicle
        self._grades = list(grades_deg)
        self._soils = list(soils)
        self._factory = estimator_factory or _default_factory
        self._est = self._factory(vehicle, math.radians(self._grades[0]))
        self._key = (0, self._grades[0], self._soils[0])
        self._last: Any = None
        self._held: SoilBelief | None = None
        self._events: list[dict] = []
        self.update_times_s: list[float] = []
        self._sink = SinkageEstimator(vehicle, self._grades[0])
        self._sink_patch = 0
        self._cache: dict[tuple[int, int], SoilBelief] = {}  # beliefs asked since the last update

    def update(
        self, time_s: float, torque: float, w: float, v: float, accel: float | None, patch: int, learn: bool = True
    ) -> None:
        """Feed one sample (torque applied, sprocket speed, vehicle speed) to the estimator.

        Entering another patch of the route starts a new estimator and drops the held estimate: the old
        horizon describes the ground behind (even where the plan says the same soil and grade, the true
        ground may differ, and the change detector need not fire). ``learn=False`` (the controller stands
        with no drive torque, ``ControlSettings.learn_min_speed``): the sample is not given to the estimators
        and the belief stays as it is (its update time is recorded as 0).
        """
        k = min(patch, len(self._grades) - 1)
        key = (k, self._grades[k], self._soils[k])
        if key != self._key:
            self._est = self._factory(self.vehicle, math.radians(key[1]))
            self._key, self._last, self._held = key, None, None
            self._cache.clear()
        if k != self._sink_patch:
            self._sink, self._sink_patch = SinkageEstimator(self.vehicle, self._grades[k]), k
            self._cache.clear()
        if not learn:
            self.update_times_s.append(0.0)
            return
        self._cache.clear()
        self._sink.update(time_s, torque, w, v)
        t0 = time.perf_counter()
        e = self._est.update(time_s, torque, w, v, accel)
        self.update_times_s.append(time.perf_counter() - t0)
        self._last = e
        if getattr(e, "change_detected", False):
            self._held = None
            self.changes += 1
            self._sink = SinkageEstimator(self.vehicle, self._grades[k])
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
            self._held = SoilBelief(
                float(e.max_thrust_N), float(K or self._b[k].shear_modulus_m), "estimate", self._b[k].slip_sinkage
            )

    def belief(self, patch: int, current: int) -> SoilBelief:
        """The estimate for the patch under the vehicle, the prior for the others.

        F_max identified now: the estimate. Identified earlier on this patch (no change detected
        since): that estimate, held (``"held estimate"``). Only the small-slip slope: the prior's
        F_max with the K of that slope (``"slope+prior"``). Nothing: the prior. The slip sinkage:
        :class:`SinkageEstimator`'s once identified on the patch under the vehicle, else the prior's.
        """
        key = (patch, current)
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        b = self._thrust_belief(patch, current)
        mu = self._sink.value if patch == current and patch == self._sink_patch else None
        if mu is not None:
            b = SoilBelief(b.max_thrust_N, b.shear_modulus_m, b.source, mu[0])
        self._cache[key] = b
        return b

    def _thrust_belief(self, patch: int, current: int) -> SoilBelief:
        prior = self._prior[min(patch, len(self._prior) - 1)]
        e = self._last
        if patch != current or e is None or e.max_thrust_N is None:
            return prior
        ident = tuple(getattr(e, "identifiable", ()) or ())
        if self._held is not None:
            h = self._held
            return (
                h
                if "max_thrust" in ident
                else SoilBelief(h.max_thrust_N, h.shear_modulus_m, "held estimate", h.slip_sinkage)
            )
        if "slope" in ident and e.slope_N and e.slope_N > 0:
            K = prior.max_thrust_N * self.vehicle.track_length / (2.0 * e.slope_N)
            return SoilBelief(prior.max_thrust_N, float(min(max(K, 1e-3), 0.5)), "slope+prior", prior.slip_sinkage)
        return prior

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
