"""Re-planning while driving: one speed-profile problem built for a vehicle and a mesh, re-solved warm.

A :class:`Replanner` fixes what does not change while the vehicle drives - the vehicle, the
distance (or duration) ahead, the mesh, the objective and the limits - and re-plans on the soil
known NOW (a ``Soil``, a ``FitResult``, a ``SoilUncertainty`` or an on-line estimate, see
:func:`~.uncertainty.uncertainty_from_estimate`) from the current speed and slip::

    rp = Replanner(vehicle, distance=30.0, v1=3.0, intervals=100)
    plan = rp.replan(TERRAINS["lete_sand"], v0=0.5)
    ...                                  # the estimator reports a new soil
    plan = rp.replan(estimate, v0=1.2, slip0=0.04)

The optimal-control problem (:mod:`.ocp`) takes the soil, grade, compaction and limits as
parameters, so it is built once per structure; each re-plan starts from this replanner's previous
solution (its own warm start, not shared with other plans in the process) and falls back to a
cold start when the warm one fails. Every plan is checked after the solve like any
:func:`~.profile.profile` (limits at the mesh and collocation points, end speed), and says
whether it was warm-started and how many iterations it took.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..soilmodel import DataError, Vehicle
from .arguments import check_number
from .margin import DEFAULT_MAX_SLIP
from .profile import DEFAULT_INTERVALS, SpeedPlan, plan_patches
from .route import OBJECTIVES, Patch

__all__ = ["Replanner", "ReplanSettings"]


@dataclass(frozen=True)
class ReplanSettings:
    """What a :class:`Replanner` keeps fixed (SI).

    Attributes
    ----------
    distance, duration
        Exactly one: the distance ahead (m) or the duration (s; objective ``"energy"``).
    v1
        Target speed at the end, m/s (a re-plan may give another).
    objective
        ``"time"`` or ``"energy"``.
    intervals
        Mesh intervals (the problem's size).
    max_slip, grade_deg, max_speed, torque_rate
        Slip limit, grade (deg), speed limit (m/s, ``None``: none), torque-rate limit
        (N m/s, ``None``: none).
    """

    distance: float | None
    duration: float | None
    v1: float
    objective: str = "time"
    intervals: int = DEFAULT_INTERVALS
    max_slip: float = DEFAULT_MAX_SLIP
    grade_deg: float = 0.0
    max_speed: float | None = None
    torque_rate: float | None = None


class Replanner:
    """A speed-profile problem built once for a vehicle and a mesh, re-solved warm on each new soil.

    Parameters
    ----------
    vehicle
        The vehicle.
    distance, duration
        Exactly one: the distance ahead (m) or the duration (s; objective ``"energy"``).
    v1
        Target speed, m/s.
    objective, intervals, max_slip, grade_deg, max_speed, torque_rate
        As for :func:`~.profile.profile`.

    Raises
    ------
    DataError
        An argument out of range (named).
    """

    def __init__(
        self,
        vehicle: Vehicle,
        *,
        v1: float,
        distance: float | None = None,
        duration: float | None = None,
        objective: str = "time",
        intervals: int = DEFAULT_INTERVALS,
        max_slip: float | None = None,
        grade_deg: float = 0.0,
        max_speed: float | None = None,
        torque_rate: float | None = None,
    ) -> None:
        if (distance is None) == (duration is None):
            raise DataError("give exactly one of the arguments distance and duration")
        if objective not in OBJECTIVES:
            raise DataError(f"argument objective must be one of {OBJECTIVES}, got {objective!r}")
        self.vehicle = vehicle
        self.settings = ReplanSettings(
            distance=None if distance is None else check_number("distance", distance, 0.0, lo_open=True),
            duration=None if duration is None else check_number("duration", duration, 0.0, lo_open=True),
            v1=check_number("v1", v1, 0.0),
            objective=objective,
            intervals=intervals,
            max_slip=DEFAULT_MAX_SLIP if max_slip is None else check_number("max_slip", max_slip, 0, 1, True, True),
            grade_deg=check_number("grade_deg", grade_deg, -68.75, 68.75),
            max_speed=None if max_speed is None else check_number("max_speed", max_speed, 0.0, lo_open=True),
            torque_rate=None if torque_rate is None else check_number("torque_rate", torque_rate, 0.0, lo_open=True),
        )
        self._store: dict = {}
        self.last: SpeedPlan | None = None
        self.count = 0

    def replan(self, terrain: Any, v0: float, *, slip0: float | None = None, v1: float | None = None) -> SpeedPlan:
        """Plan from the current state on ``terrain``, warm-started from this replanner's last solution.

        Parameters
        ----------
        terrain
            A ``Soil``, a ``FitResult``, a ``SoilUncertainty`` or an on-line estimate (the plan
            uses its mean soil; for F_max and K only, the weakest soil of the ridge at the load).
        v0
            Current speed, m/s.
        slip0
            Current slip (default: the steady slip that carries the resistance at ``v0``).
        v1
            Target speed, m/s (default: the replanner's).

        Returns
        -------
        SpeedPlan
            ``warm_start`` says whether the solve started from the previous solution.
        """
        s = self.settings
        length = s.distance if s.distance is not None else 1.0
        res = plan_patches(
            (Patch(length, terrain, s.grade_deg),),
            self.vehicle,
            v0=v0,
            v1=s.v1 if v1 is None else v1,
            distance=s.distance,
            duration=s.duration,
            max_slip=s.max_slip,
            objective=s.objective,
            intervals=s.intervals,
            torque_rate=s.torque_rate,
            max_speed=s.max_speed,
            slip0=slip0,
            warm_store=self._store,
        )
        self.count += 1
        if res.success:
            self.last = res
        return res

    def reset(self) -> None:
        """Forget the previous solution (the next re-plan starts cold)."""
        self._store.clear()
        self.last = None
