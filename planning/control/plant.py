"""The simulated vehicle a controller drives: the library's straight-line dynamics over terrain patches.

State ``[v, w]`` (vehicle speed, sprocket speed), input the sprocket torque of both tracks, the
dynamics of :func:`soiltrack.soilmodel.dynamics.dynamics_expr` (Eqs. 1 and 4 with the thrust
balance ``I dw/dt = M_s - r F(i)``; the patch's grade as the ``grade`` effect: normal load
``W cos(theta)``, extra resistance ``W sin(theta)``; optionally soilmodel's ``slip_sinkage`` effect,
a resistance ``N mu_s |i|``: on such a patch more slip digs the tracks in, so the net pull
``F(i) - R(i)`` peaks at a moderate slip and falls beyond it). The dynamics are stiff (the slip settles in
milliseconds), so each control period is integrated by backward Euler sub-steps, each solved by
a CasADi Newton rootfinder built once per vehicle with the soil and grade as parameters.

The soil and grade are those of the patch under the vehicle's position (the true terrain). The
measurement carries Gaussian sensor noise and an optional delay (whole control periods).
A user plant is any object with ``step(torque) -> measurement``; this one also exposes
:attr:`TrackPlant.truth` (true distance, slip, thrust limit, patch) for the metrics.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from ...soilmodel import DataError, Soil, Vehicle
from ...soilmodel.dynamics import dynamics_expr
from ...soilmodel.effects import effective_normal_load
from ...soilmodel.traction import max_thrust_expr

__all__ = ["TerrainPatch", "PlantSettings", "TrackPlant", "step_function"]


@dataclass(frozen=True)
class TerrainPatch:
    """One stretch of the true terrain: length (m), soil, grade (deg, positive uphill), slip sinkage.

    ``slip_sinkage`` is the ``mu_s`` of soilmodel's ``slip_sinkage`` effect (-): the resistance grows
    by ``N mu_s |i|`` with the slip (0: none).
    """

    length_m: float
    soil: Soil
    grade_deg: float = 0.0
    slip_sinkage: float = 0.0

    def __post_init__(self) -> None:
        v = self.slip_sinkage
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not 0 <= v <= 2:
            raise DataError(f"terrain patch slip_sinkage (mu_s) must lie in [0, 2], got {v!r}")


@dataclass(frozen=True)
class PlantSettings:
    """Settings of :class:`TrackPlant` (SI).

    Attributes
    ----------
    dt
        Control period, s (one ``step`` call).
    substeps
        Backward-Euler sub-steps per period (the hull's dynamics are resolved by them; the slip's
        millisecond relaxation is damped, not resolved, which the implicit step allows).
    sigma_sprocket_speed, sigma_vehicle_speed, sigma_torque, sigma_accel
        Gaussian sensor noise standard deviations (rad/s, m/s, N m, m/s^2).
    delay_steps
        Measurement delay, whole control periods (0: the measurement of the state just reached).
    seed
        Seed of the noise generator.
    v0, slip0
        Start speed (m/s) and slip.
    """

    dt: float = 0.02
    substeps: int = 2
    sigma_sprocket_speed: float = 0.0
    sigma_vehicle_speed: float = 0.0
    sigma_torque: float = 0.0
    sigma_accel: float = 0.0
    delay_steps: int = 0
    seed: int | None = 0
    v0: float = 0.0
    slip0: float = 0.0

    def __post_init__(self) -> None:
        for name in ("dt", "sigma_sprocket_speed", "sigma_vehicle_speed", "sigma_torque", "sigma_accel", "v0"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise DataError(f"plant setting {name} must be a finite number >= 0, got {v!r}")
        if self.dt <= 0:
            raise DataError(f"plant setting dt must be > 0, got {self.dt!r}")
        for name in ("substeps", "delay_steps"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < (1 if name == "substeps" else 0):
                raise DataError(f"plant setting {name} must be an integer >= {1 if name == 'substeps' else 0}")
        if not 0 <= self.slip0 < 1:
            raise DataError(f"plant setting slip0 must lie in [0, 1), got {self.slip0!r}")


@lru_cache(maxsize=16)
def step_function(vehicle: Vehicle) -> ca.Function:
    """Backward-Euler step ``(x0, M, p=[c, phi, K, theta, mu_s], h) -> (x1, slip, thrust)``, built once per vehicle."""
    x1 = ca.SX.sym("x1", 2)
    x0 = ca.SX.sym("x0", 2)
    M = ca.SX.sym("M")
    p = ca.SX.sym("p", 5)
    h = ca.SX.sym("h")
    effects = {"grade": {"theta_rad": p[3]}, "slip_sinkage": {"mu_s": p[4]}}
    d = dynamics_expr(x1[0], x1[1], M, p[0], p[1], p[2], vehicle, effects)
    g = x1 - x0 - h * ca.vertcat(d["dv"], d["dw"])
    rf = ca.rootfinder(
        "plant_step_rf",
        "newton",
        {"x": x1, "p": ca.vertcat(x0, M, p, h), "g": g},
        {"abstol": 1e-9, "max_iter": 50, "error_on_fail": False},
    )
    X0, MM, P, H = ca.MX.sym("x0", 2), ca.MX.sym("M"), ca.MX.sym("p", 5), ca.MX.sym("h")
    sol = rf(X0, ca.vertcat(X0, MM, P, H))
    out = ca.Function("plant_signals", [x1, M, p], [d["slip"], d["thrust"]])(sol, MM, P)
    resid = ca.Function("plant_residual", [x1, x0, M, p, h], [ca.norm_inf(g)])(sol, X0, MM, P, H)
    return ca.Function(
        "plant_step",
        [X0, MM, P, H],
        [sol, out[0], out[1], resid],
        ["x0", "M", "p", "h"],
        ["x1", "slip", "thrust", "residual"],
    )


class TrackPlant:
    """Straight-line tracked vehicle over terrain patches (module docstring).

    Parameters
    ----------
    vehicle
        The true vehicle.
    patches
        The true terrain in driving order (:class:`TerrainPatch`); beyond the last, the last.
    settings
        :class:`PlantSettings`.
    """

    def __init__(
        self,
        vehicle: Vehicle,
        patches: list[TerrainPatch] | tuple[TerrainPatch, ...],
        settings: PlantSettings | None = None,
    ) -> None:
        if not patches:
            raise DataError("the plant needs at least one terrain patch")
        self.vehicle = vehicle
        self.patches = tuple(patches)
        self.settings = s = settings or PlantSettings()
        self._ends = np.cumsum([p.length_m for p in self.patches])
        self._p = [
            np.array(
                [
                    p.soil.cohesion,
                    p.soil.friction_angle,
                    p.soil.shear_modulus,
                    math.radians(p.grade_deg),
                    p.slip_sinkage,
                ]
            )
            for p in self.patches
        ]
        self._fn = step_function(vehicle)
        self._rng = np.random.default_rng(s.seed)
        r = vehicle.sprocket_radius
        self.time_s = 0.0
        self.distance_m = 0.0
        self.x = np.array([s.v0, s.v0 / (r * (1 - s.slip0))])
        self.slip = s.slip0
        self.thrust_N = 0.0
        self.accel = 0.0
        self.torque = 0.0
        self.failed_steps = 0
        self._queue: deque = deque()
        for _ in range(s.delay_steps):
            self._queue.append(self._measure())

    def patch_index(self, distance_m: float | None = None) -> int:
        """Index of the patch at ``distance_m`` (default the vehicle's position)."""
        x = self.distance_m if distance_m is None else distance_m
        return int(min(int(np.searchsorted(self._ends, x, side="right")), len(self.patches) - 1))

    @property
    def truth(self) -> dict[str, Any]:
        """True signals now: distance, speed, slip, thrust, the patch, its thrust limit and K."""
        k = self.patch_index()
        pt = self.patches[k]
        N = float(effective_normal_load(self.vehicle.weight, self.vehicle, {"grade": math.radians(pt.grade_deg)}))
        Fmax = float(max_thrust_expr(pt.soil.cohesion, pt.soil.friction_angle, N, self.vehicle.contact_area))
        return {
            "time_s": self.time_s,
            "distance_m": self.distance_m,
            "vehicle_speed_m_s": float(self.x[0]),
            "sprocket_speed_rad_s": float(self.x[1]),
            "slip": float(self.slip),
            "thrust_N": self.thrust_N,
            "patch": k,
            "max_thrust_N": Fmax,
            "shear_modulus_m": pt.soil.shear_modulus,
            "grade_deg": pt.grade_deg,
            "slip_sinkage": pt.slip_sinkage,
        }

    def _measure(self) -> dict[str, float]:
        s, rng = self.settings, self._rng
        return {
            "time_s": self.time_s,
            "sprocket_torque_Nm": self.torque + (rng.normal(0, s.sigma_torque) if s.sigma_torque else 0.0),
            "sprocket_speed_rad_s": float(self.x[1])
            + (rng.normal(0, s.sigma_sprocket_speed) if s.sigma_sprocket_speed else 0.0),
            "vehicle_speed_m_s": float(self.x[0])
            + (rng.normal(0, s.sigma_vehicle_speed) if s.sigma_vehicle_speed else 0.0),
            "vehicle_accel_m_s2": self.accel + (rng.normal(0, s.sigma_accel) if s.sigma_accel else 0.0),
        }

    def step(self, torque: float) -> dict[str, float]:
        """Hold ``torque`` (N m, both sprockets) over one control period; return the measurement."""
        M = float(torque)
        if not math.isfinite(M):
            raise DataError(f"plant: the torque must be finite, got {torque!r}")
        s = self.settings
        h = s.dt / s.substeps
        v_start = float(self.x[0])
        for _ in range(s.substeps):
            p = self._p[self.patch_index()]
            x_prev = self.x
            x1, slip, F, res = self._fn(x_prev, M, p, h)
            x1 = np.asarray(x1, dtype=float).ravel()
            if not (np.all(np.isfinite(x1)) and float(res) < 1e-6):
                self.failed_steps += 1
                x1 = self._fallback(x_prev, M, p, h)
                slip, F = self._fn(x1, M, p, 0.0)[1:3]
            self.x = np.array([max(x1[0], 0.0), max(x1[1], 0.0)])
            self.distance_m += 0.5 * (x_prev[0] + self.x[0]) * h
            self.slip, self.thrust_N = float(slip), float(F)
        self.time_s += s.dt
        self.torque = M
        self.accel = (float(self.x[0]) - v_start) / s.dt
        self._queue.append(self._measure())
        return self._queue.popleft()

    def _fallback(self, x0: np.ndarray, M: float, p: np.ndarray, h: float) -> np.ndarray:
        """Ten finer backward-Euler steps from ``x0`` (when one step's Newton solve did not converge)."""
        x = x0
        for _ in range(10):
            x = np.asarray(self._fn(x, M, p, h / 10)[0], dtype=float).ravel()
        if not np.all(np.isfinite(x)):
            raise DataError("plant: the implicit step failed (non-finite state); reduce dt")
        return x
