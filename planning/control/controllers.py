"""Controllers with one call per sample, ``command(measurement) -> torque``: PI, slip and receding horizon.

Every controller tracks a target speed along a route (or on one patch), filters the measured
speeds, keeps its own odometry (the patch under it and ahead), and holds the drivetrain's limits:
``|M| <= M_max`` (braking to ``brake_fraction`` of it) and ``M w <= P_max``.

- ``pi``: PI speed control (feed-forward of the rolling and grade resistance), conditional
  integration (anti-windup); no soil knowledge.
- ``slip`` (and ``fixed_slip``): the torque is the smaller of a speed loop's and a slip loop's. The
  slip loop holds the slip at a ceiling: the believed soil's power-optimal slip (the traction
  study's optimum, :func:`~.optimum.optimal_slip`) capped by the slip limit, with the believed
  thrust there as feed-forward; ``fixed_slip`` holds a fixed ceiling (7 %, 20 %) by feedback alone.
- ``mpc``: the slip/torque problem of :mod:`.mpc` over a short horizon on the believed soil,
  re-solved every ``mpc_every`` samples; its first slip is the slip loop's target.

A speed governor (``slip``, ``mpc``) checks the patches ahead with the believed soil: where the
thrust at the slip limit (or the torque limit) is below the resistance (rolling and grade) the
controller stops before the patch (on it: at once); where the power limit cannot hold the target
speed it slows down; each decision is an entry of :attr:`events` with the reason in numbers. A stall (pulling
at rest with the slip past the limit for ``stall_s``) stops on the patch whatever the belief says, and while
the vehicle stands with no drive torque the belief learns nothing (``learn_min_speed``): a stop stays a stop.
"""

from __future__ import annotations

import math
import time
from bisect import bisect_right
from dataclasses import dataclass, fields, replace
from functools import lru_cache
from typing import Any, Sequence

import numpy as np

from ...soilmodel import TERRAINS, DataError, Soil, Vehicle
from ...soilmodel.traction import slip_factor_function
from ..margin import DEFAULT_MAX_SLIP
from .belief import EstimatedSoil, PriorSoil, SoilBelief, TrueSoil, patch_load, soil_of
from .mpc import MPC_METHODS, MpcProblem
from .optimum import optimal_slip_on_load

__all__ = ["ControlSettings", "RouteView", "Controller", "make_controller", "CONTROLLERS", "SOIL_SOURCES"]

CONTROLLERS = ("pi", "slip", "mpc", "fixed_slip")
SOIL_SOURCES = ("estimate", "nominal", "true")
#: Below this speed target (m/s) a controller stops (holds with no drive torque) rather than creeps.
_STOP_SPEED = 0.05
_UNIDENTIFIED = ("prior", "slope+prior")  # belief sources whose F_max is not identified on the patch


@dataclass(frozen=True)
class ControlSettings:
    """Settings of the controllers (SI; one line each on why).

    Attributes
    ----------
    max_slip
        Slip limit (``None``: the route's, else the planning default 0.2).
    fixed_slip
        ``fixed_slip`` controller: its fixed slip ceiling.
    speed_time_constant_s, speed_integral_s
        Speed loop: proportional gain ``r m / tau`` (an error corrected in about tau), integral time.
    slip_gain, slip_integral_s
        Slip loop: proportional gain as a fraction of the torque the believed curve's slope gives per
        unit slip, and integral time (corrects a wrong belief).
    filter_s
        Time constant of the first-order filter of the measured speeds (slip from noisy speeds).
    min_track_speed
        Regularisation of the measured slip, ``(r w - v) / max(r w, v_0)`` (as soilmodel's slip), m/s.
    brake_fraction
        Braking torque allowed, as a fraction of the torque limit.
    decel_m_s2
        Deceleration the governor plans a stop with.
    stop_margin_m
        Distance before an untraversable patch where the vehicle should stand.
    governor
        Whether the governor checks the ground ahead (``slip``, ``mpc``).
    mpc_horizon, mpc_interval_s, mpc_every
        Receding horizon: intervals, their length, and samples between two solves.
    mpc_qp
        The receding horizon's SQP setup (:data:`~.mpc.MPC_METHODS`): ``"qpoases"`` (default: the
        Hessian convexified, qpOASES) or ``"qrqp"`` (the exact Hessian with QRQP, last round's, whose
        slow solves set the step's p99; kept for comparison).
    mpc_speed_floor
        Whether the slip controller's rule (the speed loop, with its integral, under the believed optimal
        slip) is a floor under the plan's torque. The horizon problem has no integral action: a belief that
        overrates the soil (F_max not identified, the prior's kept) makes the plan's slips too small, it
        predicts an acceleration that never comes, and the vehicle stays below the target speed (independent
        plant, light vehicle, a snow climb planned as LETE sand: 35.9 s against 31.1 s with the true soil,
        +15 %, before the floor; docs/control.md).
    mpc_disturbance_s
        Offset-free MPC: time constant of the filtered hull-force residual ``m dv/dt - (F(i) - R - R_s i)``
        of the believed soil at the measured slip, added to the plan's resistance (a belief that overrates
        the soil otherwise leaves the MPC below the target speed: heavy ``climb`` +13 % time, +1.2 % with
        1 s); 0 (default): off, since with 1 s the heavy ``dig`` MPC spent 0.06 s above the slip limit
        (0 without; docs/control.md).
    sample_s
        Sample time assumed for the first sample (later: from the measurement's times).
    time_cpu
        Whether each command reads the process CPU clock (``step_cpu_s``, the benchmark's CPU columns): two
        system calls, about 6 of the slip controller's 21 us own step on the shared 2-core machine
        (``/work/notes/i43_scripts/own_micro.py``, docs/control.md); ``False`` for a vehicle (the wall
        clock ``step_times_s`` stays).
    learn_min_speed
        Standing with no drive: while both the filtered vehicle speed and the filtered track speed ``r w`` are
        below this (m/s) and the torque commanded for the last sample was not positive (a hold), the samples are
        not given to the belief (its estimator and the slip-sinkage estimate). Then the thrust is zero and the
        slip ``0/0`` is sensor noise: such samples say nothing of the thrust-slip curve, and fed to the estimator
        they moved the identified F_max and K of a patch the governor had stopped on, so that the governor
        resumed on the changed belief (independent plant, light vehicle, ``steep``, MPC: a resume 2.6 s after
        the stop, then 31.2 s above the slip limit; docs/control.md). A stall with a drive torque is kept: it
        shows the thrust at a high slip (there the estimator identified that climb's F_max).
    stall_s
        Stall: when the drive has pulled (torque > 0) with the filtered vehicle speed below ``learn_min_speed`` for
        this long (s) and the measured slip passed the slip limit meanwhile (the tracks spin; the runaway guard
        cuts the torque, so the slip swings), the governor stops on the patch (``"stall"``, logged with the
        reason) whatever the belief says, and does not resume there. The belief can miss a soil that
        cannot carry the climb (the estimator identifies F_max only from a converged horizon of enough samples,
        ``identify_min_samples``, and a vehicle spinning at rest gives few): on the heavy ``steep`` route the
        belief stayed on the planned soil and the ``slip`` controller spun at the limit for 30 s (docs/control.md).
    cut_factor, guard_margin
        Runaway guard (all but ``pi``): while the measured slip is above the slip limit (for a controller
        with a slip target: above the larger of 1.5 times the target and the target plus ``guard_margin``,
        capped by the limit, whichever loop sets the torque), the drive torque is cut to this fraction of
        the last one at every sample (a belief that overrates the soil would otherwise let the tracks spin
        up faster than the slip loop corrects it, and on a soil with slip sinkage a spinning track digs
        in within a few tenths of a second).
    probe, probe_s, probe_settle_s, probe_overspeed, probe_abort_drop, probe_need
        Traction probe (``slip``, ``mpc`` with the estimator): gentle driving shows only the start of
        the thrust-slip curve, so on a patch whose F_max is not identified yet and whose resistance needs
        at least ``probe_need`` times the believed pull at the slip limit (elsewhere the limit does not
        bind the drive, and a probe only spends energy on slip and overspeed: heavy ``soft`` +20 %)
        the controller pulls at the slip ceiling for ``probe_s`` (once per patch, and again after a
        detected change),
        ``probe_settle_s`` after entering it, ending early beyond ``1 + probe_overspeed`` times the
        speed target; and at once when the speed falls below ``1 - probe_abort_drop`` times the speed at its
        start (pulling harder slowed the vehicle: slip sinkage digs in, logged as ``probe_aborted``).
        The probe's slip is the ceiling but at most the slip limit less ``guard_margin``, and during it the
        runaway guard cuts at that slip (a belief that overrates F_max asks at the limit for more than the soil
        gives: the tracks spin up past it; independent plant, light snow climbs: 0.18-0.22 s above the limit
        before, 0-0.02 s after, docs/control.md).
    """

    max_slip: float | None = None
    fixed_slip: float = 0.07
    speed_time_constant_s: float = 1.0
    speed_integral_s: float = 3.0
    slip_gain: float = 0.5
    slip_integral_s: float = 0.3
    filter_s: float = 0.05
    min_track_speed: float = 0.01
    brake_fraction: float = 0.5
    decel_m_s2: float = 0.3
    stop_margin_m: float = 1.0
    governor: bool = True
    mpc_horizon: int = 10
    mpc_interval_s: float = 0.2
    mpc_every: int = 2
    mpc_qp: str = "qpoases"
    mpc_speed_floor: bool = True
    mpc_disturbance_s: float = 0.0
    sample_s: float = 0.02
    time_cpu: bool = True
    learn_min_speed: float = 0.05
    stall_s: float = 0.5
    cut_factor: float = 0.85
    guard_margin: float = 0.05
    probe: bool = True
    probe_s: float = 0.6
    probe_settle_s: float = 1.0
    probe_overspeed: float = 0.2
    probe_abort_drop: float = 0.2
    probe_need: float = 0.2

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in ("governor", "probe", "mpc_speed_floor", "time_cpu"):
                continue
            if f.name == "mpc_qp":
                if v not in MPC_METHODS:
                    raise DataError(f"controller setting mpc_qp must be one of {MPC_METHODS}, got {v!r}")
                continue
            if v is None:
                continue
            number = not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)
            if not number or not (v >= 0 if f.name == "mpc_disturbance_s" else v > 0):  # 0: offset-free MPC off
                bound = ">= 0" if f.name == "mpc_disturbance_s" else "> 0"
                raise DataError(f"controller setting {f.name} must be a finite number {bound}, got {v!r}")
        for name in ("max_slip", "fixed_slip"):
            v = getattr(self, name)
            if v is not None and not 0 < v < 1:
                raise DataError(f"controller setting {name} must lie in (0, 1), got {v!r}")
        if not isinstance(self.mpc_horizon, int) or not isinstance(self.mpc_every, int):
            raise DataError("controller settings mpc_horizon and mpc_every must be integers")


@dataclass(frozen=True)
class RouteView:
    """What a controller knows of its route: patch ends (m), grades (deg), planned soils, slip limit."""

    ends_m: tuple[float, ...]
    grades_deg: tuple[float, ...]
    soils: tuple[Soil, ...]
    max_slip: float | None
    length_m: float

    @classmethod
    def of(cls, route: Any, prior: Soil | None = None) -> "RouteView":
        """From a :class:`~soiltrack.planning.Route` (or ``None``: one endless flat patch of ``prior``)."""
        if route is None:
            return cls((math.inf,), (0.0,), (prior or TERRAINS["lete_sand"],), None, math.inf)
        ends = tuple(float(x) for x in np.cumsum([p.length_m for p in route.patches]))
        return cls(
            ends,
            tuple(float(p.grade_deg) for p in route.patches),
            tuple(soil_of(p.terrain) for p in route.patches),
            route.max_slip,
            ends[-1],
        )

    def patch_at(self, x: float) -> int:
        """Index of the patch at distance ``x``."""
        for k, e in enumerate(self.ends_m):
            if x < e:
                return k
        return len(self.ends_m) - 1

    def start_of(self, k: int) -> float:
        return 0.0 if k == 0 else self.ends_m[k - 1]


@lru_cache(maxsize=1)
def _bracket_table() -> tuple[np.ndarray, np.ndarray]:
    """``(g(x), x)``: soilmodel's shear bracket (the slip factor at l = K = 1) at x = 0 and 8,001 log-spaced
    points in [1e-8, 1e4], one mapped CasADi call; linear interpolation in it is exact to about 1e-5."""
    x = np.concatenate([[0.0], np.logspace(-8.0, 4.0, 8001)])
    g = slip_factor_function().map(x.size)(x.reshape(1, -1), 1.0, 1.0)
    return np.asarray(g, dtype=float).ravel(), x


def _lookup(x: float, xs: list[float], ys: list[float]) -> float:
    """Linear interpolation of ``ys`` at ``x`` over increasing ``xs`` (held at the ends), plain Python."""
    j = bisect_right(xs, x)
    if j <= 0:
        return ys[0]
    if j >= len(xs):
        return ys[-1]
    x0, x1 = xs[j - 1], xs[j]
    return ys[j - 1] + (ys[j] - ys[j - 1]) * (x - x0) / (x1 - x0)


def _measurement(meas: Any) -> tuple[float, float, float, float | None, float | None, bool]:
    """``(t, w, v, accel, torque, two_track)`` from a measurement dict (drive-log column names)."""
    if not isinstance(meas, dict):
        raise DataError(f"a measurement must be a dict with the drive-log column names, got {type(meas).__name__}")
    try:
        t = float(meas["time_s"])
        v = float(meas["vehicle_speed_m_s"])
        if "sprocket_speed_rad_s" in meas:
            w, two = float(meas["sprocket_speed_rad_s"]), False
        else:
            w, two = 0.5 * (float(meas["sprocket_speed_left_rad_s"]) + float(meas["sprocket_speed_right_rad_s"])), True
    except KeyError as e:
        raise DataError(
            f"the measurement has no {e.args[0]!r} (needs time_s, vehicle_speed_m_s and "
            "sprocket_speed_rad_s or the left and right speeds)",
            column=str(e.args[0]),
        ) from None
    a = meas.get("vehicle_accel_m_s2")
    M = meas.get("sprocket_torque_Nm")
    if M is None and "sprocket_torque_left_Nm" in meas:
        M = float(meas["sprocket_torque_left_Nm"]) + float(meas["sprocket_torque_right_Nm"])
    return t, w, v, (None if a is None else float(a)), (None if M is None else float(M)), two


class Controller:
    """Base of the controllers: measurement, filter, odometry, belief, governor, limits (module docstring)."""

    kind = "base"

    def __init__(
        self,
        vehicle: Vehicle,
        route: RouteView,
        target_speed_m_s: float,
        settings: ControlSettings,
        belief: PriorSoil | None,
    ) -> None:
        if not (math.isfinite(target_speed_m_s) and target_speed_m_s > 0):
            raise DataError(f"target speed must be a finite number > 0 m/s, got {target_speed_m_s!r}")
        self.vehicle, self.route, self.target, self.settings, self.belief = (
            vehicle,
            route,
            float(target_speed_m_s),
            settings,
            belief,
        )
        self.max_slip = settings.max_slip or route.max_slip or DEFAULT_MAX_SLIP
        self.events: list[dict] = []
        self.step_times_s: list[float] = []  # wall clock per command
        # CPU time per command (process_time: a loaded machine's waits left out; thread_time is a slow system
        # call here, 8 us to 1 ms, and would inflate what it measures)
        self.step_cpu_s: list[float] = []
        self.distance_m = 0.0
        self._t: float | None = None
        self._v = self._w = 0.0
        self._slip = 0.0
        self._last_M = 0.0
        self._Iv = 0.0
        self._Is = 0.0
        self._gov_state: tuple = ("go", -1)
        self._stall = (math.nan, -1, 0.0)  # the current stall: (time it began, its patch, its peak slip)
        self._stalled: set[int] = set()  # patches the vehicle stalled on (the governor stops there)
        self._judged: dict[int, tuple] = {}  # the governor's last judgement of each patch (:meth:`_judge`)
        self._ff: tuple = (None, (0.0, 0.0))  # the slip loop's last feed-forward ((F_max, K, slip), (M, gain))
        self._gy, self._gx = _bracket_table()
        self._gyl, self._gxl = self._gy.tolist(), self._gx.tolist()
        self._M_max = vehicle.max_sprocket_torque or math.inf
        self._P_max = vehicle.max_power or math.inf
        self._N = [patch_load(vehicle, g) for g in route.grades_deg]
        self._R0 = [
            vehicle.rolling_resistance * n + vehicle.weight * math.sin(math.radians(g))
            for n, g in zip(self._N, route.grades_deg)
        ]
        self._limit_grid = np.linspace(0.0, self.max_slip, 61)
        self.last: dict[str, Any] = {}
        self.limiting = "speed"  # which loop set the last torque: "speed", "slip", "probe" or "plan"

    # ------------------------------------------------------------------ helpers
    def resistance(self, patch: int) -> float:
        """Rolling and grade resistance on a patch, N (``mu_r W cos(theta) + W sin(theta)``)."""
        return self._R0[patch]

    def _sinkage_N(self, b: SoilBelief | None, patch: int) -> float:
        """The believed slip sinkage's resistance per unit slip on a patch, ``N mu_s``, N."""
        return 0.0 if b is None or not b.slip_sinkage else self._N[patch] * b.slip_sinkage

    def _pull_at_limit(self, b: SoilBelief, patch: int) -> tuple[float, float]:
        """``(slip, net pull)``: the slip (within the slip limit) of the largest believed ``F(i) - N mu_s i``."""
        Rs = self._sinkage_N(b, patch)
        if not Rs:
            return self.max_slip, self._thrust1(b, self.max_slip)
        grid = self._limit_grid
        net = self._thrust(b, grid) - Rs * grid
        j = int(np.argmax(net))
        return float(grid[j]), float(net[j])

    def _thrust(self, b: SoilBelief, slips: Sequence[float] | np.ndarray) -> np.ndarray:
        """Believed thrust (Eq. 2, ``F_max g(i l / K)``) at ``slips`` (non-negative), from a table of
        soilmodel's shear bracket ``g`` (:func:`_bracket_table`, exact to about 1e-5; a CasADi call per
        sample would cost more than the whole control step)."""
        x = np.abs(np.asarray(slips, dtype=float)) * (self.vehicle.track_length / b.shear_modulus_m)
        return b.max_thrust_N * np.interp(x, self._gx, self._gy)

    def _thrust1(self, b: SoilBelief, slip: float) -> float:
        """:meth:`_thrust` at one slip in plain Python (bisection in the same table: no numpy call per sample)."""
        return b.max_thrust_N * _lookup(abs(slip) * self.vehicle.track_length / b.shear_modulus_m, self._gxl, self._gyl)

    def _slip_for(self, b: SoilBelief, thrust: float) -> float:
        """Slip at which the believed soil gives ``thrust`` (inf beyond its F_max): the same table, inverted
        (``g`` rises monotonically; soilmodel's :func:`~soiltrack.soilmodel.traction.shear_bracket_inverse`
        agrees to about 1e-4 relative, tests/test_control.py)."""
        y = thrust / b.max_thrust_N
        if y >= 0.999:
            return math.inf
        return _lookup(max(y, 0.0), self._gyl, self._gxl) * b.shear_modulus_m / self.vehicle.track_length

    def _event(self, kind: str, patch: int, text: str, **numbers: float) -> None:
        self.events.append(
            {
                "time_s": self._t,
                "distance_m": self.distance_m,
                "kind": kind,
                "patch": patch,
                "reason": text,
                **{k: float(v) for k, v in numbers.items()},
            }
        )

    # ------------------------------------------------------------------ governor
    def _stalled_on(self, patch: int) -> bool:
        """Whether the vehicle has stalled on ``patch`` (``ControlSettings.stall_s``; logged once)."""
        s, t = self.settings, self._t or 0.0
        if patch in self._stalled:
            return True
        if not (self._last_M > 0 and self._v < s.learn_min_speed):
            self._stall = (math.nan, -1, 0.0)
            return False
        t0, k, peak = self._stall
        if k != patch:
            t0, peak = t, 0.0
        self._stall = (t0, patch, max(peak, self._slip))
        if t - t0 < s.stall_s or self._stall[2] <= self.max_slip:
            return False
        self._stalled.add(patch)
        return True

    def _governor(self, patch: int, v: float) -> float:
        """The speed target after checking the ground ahead with the belief (module docstring)."""
        s = self.settings
        v_ref = self.target
        state: tuple = ("go", -1)
        if self._stalled_on(patch):
            state = ("stop", patch, "stall", self._R0[patch], max(self._last_M, 0.0) / self.vehicle.sprocket_radius)
            if state[:2] != self._gov_state[:2]:
                self._log_state(state)
            self._gov_state = state
            return 0.0
        reach = v * v / (2 * s.decel_m_s2) + s.stop_margin_m + 5.0
        ends, R0, belief = self.route.ends_m, self._R0, self.belief
        for k in range(patch, len(ends)):
            start = ends[k - 1] if k else 0.0  # RouteView.start_of
            if k > patch and start - self.distance_m > reach:
                break
            b = belief.belief(k, patch) if belief is not None else None
            R = R0[k]  # self.resistance(k)
            i_R, limit, avail = self._judge(b, k)
            if limit is not None:
                gap = max(start - s.stop_margin_m - self.distance_m, 0.0) if k > patch else 0.0
                v_ref = min(v_ref, math.sqrt(2 * s.decel_m_s2 * gap))
                state = ("stop", k, limit, R, avail)
                break
            v_pow = 0.95 * self._P_max * (1 - i_R) / max(R, 1e-9)
            if v_pow < v_ref:
                gap = max(start - self.distance_m, 0.0)
                v_ref = min(v_ref, math.sqrt(v_pow**2 + 2 * s.decel_m_s2 * gap))
                if state[0] == "go":
                    state = ("slow", k, "power", R, self._P_max * (1 - i_R) / max(self.target, 1e-9))
        if state[:2] != self._gov_state[:2]:
            self._log_state(state)
        self._gov_state = state
        return v_ref

    def _judge(self, b: SoilBelief | None, k: int) -> tuple[float, str | None, float]:
        """``(slip needed, limit, available N)`` on patch ``k`` under belief ``b``: the slip at which the belief
        carries the patch's resistance (inf: beyond what it gives), and the limit that stops the vehicle there
        (``"torque"``, ``"slip"``, ``"soil"``; ``None``: traversable) with the thrust available within it.
        Remembered per patch for the last belief's values (the patches ahead keep their prior: asked at every
        sample)."""
        key = None if b is None else (b.max_thrust_N, b.shear_modulus_m, b.slip_sinkage)
        memo = self._judged.get(k)
        if memo is not None and memo[0] == key:
            return memo[1]
        R, r = self._R0[k], self.vehicle.sprocket_radius
        i_R = self._slip_for(b, R) if b is not None else 0.0
        limit, avail = None, 0.0
        if b is not None and b.slip_sinkage and i_R <= self.max_slip:  # sinkage: the net pull's peak decides
            pull = self._pull_at_limit(b, k)[1]
            i_R = i_R if pull >= R else math.inf
        if R > self._M_max / r:
            limit, avail = "torque", self._M_max / r
        elif i_R > self.max_slip:
            assert b is not None  # i_R is 0.0 without a belief
            avail = self._pull_at_limit(b, k)[1]
            limit = "soil" if math.isinf(i_R) else "slip"
        self._judged[k] = (key, (i_R, limit, avail))
        return i_R, limit, avail

    def _log_state(self, state: tuple) -> None:
        if state[0] == "go":
            self._event("resume", self._gov_state[1], "the ground ahead is traversable at the target speed")
            return
        kind, k, limit, R, avail = state
        src = self.belief.belief(k, self.route.patch_at(self.distance_m)).source if self.belief else "none"
        if limit == "stall":
            text = (
                f"the vehicle stalled on patch {k} (below {self.settings.learn_min_speed:g} m/s for "
                f"{self.settings.stall_s:g} s of pulling, the slip past the {self.max_slip:g} limit; the drive asked "
                f"for {avail:.4g} N of thrust, the patch "
                f"needs {R:.4g} N) though the {src} soil was believed to carry it: stopping now"
            )
        elif kind == "stop":
            text = (
                f"patch {k} needs {R:.4g} N of thrust; the {src} soil gives {avail:.4g} N within the "
                f"{limit} limit: stopping {'now' if k == self.route.patch_at(self.distance_m) else 'before it'}"
            )
        else:
            text = (
                f"patch {k} needs {R:.4g} N; the power limit holds it only below the target speed "
                f"({avail:.4g} N at {self.target:.3g} m/s): slowing down"
            )
        self._event(kind, k, text, required_N=R, available_N=avail)
        self.events[-1]["limit"] = limit  # "slip", "soil", "torque" or "power" (docs/control.md)

    # ------------------------------------------------------------------ one sample
    def command(self, measurement: dict) -> float | tuple[float, float]:
        """Torque (N m, both sprockets; a (left, right) pair for two-track measurements) for this sample."""
        s = self.settings
        c0 = time.process_time() if s.time_cpu else 0.0  # read outside the wall-clock interval (a system call)
        t0 = time.perf_counter()
        t, w, v, a, M_meas, two = _measurement(measurement)
        dt = s.sample_s if self._t is None else max(t - self._t, 1e-6)
        if not all(math.isfinite(x) for x in (t, w, v)):
            M = self._last_M  # a sample with a missing channel: hold the torque
        else:
            alpha = dt / (s.filter_s + dt) if self._t is not None else 1.0
            self._v += alpha * (v - self._v)
            self._w += alpha * (w - self._w)
            self._t = t
            self.distance_m += max(v, 0.0) * dt
            patch = self.route.patch_at(self.distance_m)
            rw = self.vehicle.sprocket_radius * self._w
            self._slip = min(max((rw - self._v) / max(rw, s.min_track_speed), -1.0), 1.0)  # Eq. 4, regularised
            if self.belief is not None:
                hold = self._last_M <= 0 and max(abs(self._v), abs(rw)) < s.learn_min_speed  # nothing to learn
                self.belief.update(t, self._last_M if M_meas is None else M_meas, w, v, a, patch, learn=not hold)
            v_ref = self._governor(patch, self._v) if (self.belief is not None and s.governor) else self.target
            M = self._limit(self._torque(patch, v_ref, dt), w)
            if self.kind != "pi" and self._slip > self._guard_slip() and M > 0:  # runaway guard: cut the torque
                M = min(M, max(self._last_M, 0.0) * s.cut_factor)
                self._Is = min(self._Is, 0.0)
            self.last = {"v_ref": v_ref, "patch": patch, "slip_filtered": self._slip, "limiting": self.limiting}
        self._last_M = M
        self.step_times_s.append(time.perf_counter() - t0)
        if s.time_cpu:
            self.step_cpu_s.append(time.process_time() - c0)
        return (0.5 * M, 0.5 * M) if two else M

    def _guard_slip(self) -> float:
        """Slip above which the runaway guard cuts the torque: the slip limit, or nearer the slip loop's target
        (``guard_margin``) for a controller with one (beyond it the tracks are spinning up, not settling)."""
        target = getattr(self, "slip_target", None)
        if target is None:
            return self.max_slip
        if self.limiting == "probe":  # a probe pulls at its target on purpose: beyond it the pull exceeds F_max
            return min(self.max_slip, target)
        return min(self.max_slip, max(1.5 * target, target + self.settings.guard_margin))

    def _limit(self, M: float, w_now: float) -> float:
        """Torque and power limits; the power on the largest of the filtered, raw and (while a slip loop
        drives) the sprocket speed its slip target will reach within the sample."""
        w_hi = max(self._w, w_now, 1e-3)
        if self.limiting in ("slip", "probe", "plan"):
            target = min(getattr(self, "slip_target", 0.0), 0.95)
            w_hi = max(w_hi, self._v / (self.vehicle.sprocket_radius * (1 - target)))
        M = min(M, self._M_max, self._P_max / w_hi)
        return max(M, -self.settings.brake_fraction * self._M_max) if math.isfinite(self._M_max) else M

    def _speed_loop(self, patch: int, v_ref: float, dt: float, cap: float) -> float:
        """PI speed torque with resistance feed-forward; integrates only while unsaturated (anti-windup)."""
        s, r, m = self.settings, self.vehicle.sprocket_radius, self.vehicle.mass
        kp = r * m / s.speed_time_constant_s
        e = v_ref - self._v
        if v_ref < _STOP_SPEED and self._v < _STOP_SPEED:  # stopped on purpose: hold (brakes), no torque
            self._Iv = 0.0
            return 0.0
        b = self.belief.belief(patch, patch) if self.belief is not None else None
        M = r * (self.resistance(patch) + self._sinkage_N(b, patch) * max(self._slip, 0.0)) + kp * e + self._Iv
        if v_ref < _STOP_SPEED:  # stopping: no drive torque (a climb stops the vehicle; downhill it brakes)
            self._Iv = 0.0
            return min(M, 0.0)
        near = abs(e) < 0.3 * max(self.target, 0.1)  # far from the target the proportional part acts alone
        if near and not (M >= cap and e > 0) and not (M <= -self.settings.brake_fraction * self._M_max and e < 0):
            self._Iv += kp / s.speed_integral_s * e * dt
        return M

    def _torque(self, patch: int, v_ref: float, dt: float) -> float:  # pragma: no cover - abstract
        raise NotImplementedError


class PIController(Controller):
    """PI speed control, no soil knowledge (module docstring)."""

    kind = "pi"

    def _torque(self, patch: int, v_ref: float, dt: float) -> float:
        cap = min(self._M_max, self._P_max / max(self._w, 1e-3))
        return self._speed_loop(patch, v_ref, dt, cap)


class SlipController(Controller):
    """Speed loop under a slip ceiling: the believed soil's power-optimal slip, or a fixed one (module docstring)."""

    kind = "slip"

    def __init__(self, *args: Any, fixed: float | None = None, **kw: Any) -> None:
        super().__init__(*args, **kw)
        self.fixed = fixed
        self.slip_ceiling = fixed if fixed is not None else self.max_slip
        self._probe_until: float | None = None
        self._probe_v0 = 0.0
        self._probed: set[int] = set()
        self._entered = (-1, 0.0)
        self._changes_seen = 0

    def _probing(self, patch: int, v_ref: float) -> bool:
        """Whether to pull at the slip ceiling now (the traction probe, :class:`ControlSettings`)."""
        s, t = self.settings, self._t or 0.0
        if not s.probe or not isinstance(self.belief, EstimatedSoil) or v_ref <= 0:
            return False
        if patch != self._entered[0]:
            self._entered = (patch, t)
        n = self.belief.changes
        if n != self._changes_seen:
            self._changes_seen = n
            self._probed.discard(patch)
            self._entered = (patch, t)
        if self._probe_until is not None:
            if self._v < (1 - s.probe_abort_drop) * self._probe_v0:  # pulling harder slowed it: the ground digs in
                self._probe_until = None
                self._event(
                    "probe_aborted",
                    patch,
                    f"the vehicle slowed from {self._probe_v0:.3g} to {self._v:.3g} m/s while pulling at the slip "
                    "ceiling: more slip loses pull here (slip sinkage); the probe ends",
                )
                return False
            if t < self._probe_until and self._v < (1 + s.probe_overspeed) * v_ref:
                return True
            self._probe_until = None
            return False
        b = self.belief.belief(patch, patch)
        if patch in self._probed or b.source not in _UNIDENTIFIED or t - self._entered[1] < s.probe_settle_s:
            return False
        self._probed.add(patch)
        need = self.resistance(patch) / max(self._pull_at_limit(b, patch)[1], 1e-9)
        if need < s.probe_need:  # the limit does not bind here: no probe (logged once per patch)
            self._event(
                "probe_skipped",
                patch,
                f"F_max of patch {patch} not identified ({b.source}), but its resistance needs only {need:.2f} of "
                f"the believed pull at the slip limit (< probe_need {s.probe_need:g}): no traction probe",
                need=need,
            )
            return False
        src = b.source
        self._probe_until, self._probe_v0 = t + s.probe_s, self._v
        self._event(
            "probe",
            patch,
            f"F_max of patch {patch} not identified yet ({src}): a traction probe of "
            f"{s.probe_s:g} s at the slip ceiling (the resistance needs {need:.2f} of the believed pull)",
            need=need,
        )
        return True

    def _probe_target(self, ceiling: float) -> float:
        """The probe's slip: the ceiling, at most the slip limit less ``guard_margin`` (a belief that overrates
        F_max asks at the limit for more than the soil gives: the tracks spin up past the limit)."""
        return min(ceiling, self.max_slip - self.settings.guard_margin)

    def _ceiling(self, patch: int) -> tuple[float, SoilBelief | None]:
        if self.fixed is not None or self.belief is None:
            return (self.fixed or self.max_slip), None
        b = self.belief.belief(patch, patch)
        opt = optimal_slip_on_load(
            self.vehicle.track_length,
            b.max_thrust_N,
            b.shear_modulus_m,
            self._R0[patch],
            self._N[patch],
            b.slip_sinkage,
        )
        return min(opt if opt is not None else self.max_slip, self.max_slip), b

    def _slip_loop(self, target: float, b: SoilBelief | None, dt: float, patch: int = 0) -> tuple[float, float]:
        """Torque holding the slip at ``target``: believed thrust there (feed-forward) plus PI on the slip."""
        s, r = self.settings, self.vehicle.sprocket_radius
        if b is not None:
            key = (b.max_thrust_N, b.shear_modulus_m, target)
            if self._ff[0] == key:  # the same belief and target as the last call
                ff, gain = self._ff[1]
            else:
                F0, F1 = self._thrust1(b, target), self._thrust1(b, target + 1e-3)
                gain = s.slip_gain * r * max((F1 - F0) / 1e-3, 1e-3 * b.max_thrust_N)
                ff = r * F0
                self._ff = (key, (ff, gain))
        else:  # no belief: the resistance torque (as the PI's feed-forward), the gain from the largest torque per slip
            gain, ff = s.slip_gain * min(self._M_max, r * self.vehicle.weight), r * self.resistance(patch)
        return ff + gain * (target - self._slip) + self._Is, gain

    def _integrate_slip(self, gain: float, target: float, dt: float) -> None:
        """The slip loop's integral (bounded by the torque limit)."""
        self._Is += gain / self.settings.slip_integral_s * (target - self._slip) * dt
        if math.isfinite(self._M_max):
            self._Is = min(max(self._Is, -self._M_max), self._M_max)

    def _torque(self, patch: int, v_ref: float, dt: float) -> float:
        ceiling, b = self._ceiling(patch)
        self.slip_ceiling = ceiling
        M_s, gain = self._slip_loop(ceiling, b, dt, patch)
        self.slip_target = ceiling
        if self._probing(patch, v_ref):
            self.limiting, self.slip_target = "probe", self._probe_target(ceiling)
            M_p, gain = self._slip_loop(self.slip_target, b, dt, patch)
            self._integrate_slip(gain, self.slip_target, dt)
            return M_p
        cap = min(self._M_max, self._P_max / max(self._w, 1e-3), M_s)
        M_v = self._speed_loop(patch, v_ref, dt, cap)
        self.limiting = "slip" if M_s < M_v else "speed"
        if M_s < M_v or self._slip > ceiling:  # the slip loop limits, or should: integrate its error
            self._integrate_slip(gain, ceiling, dt)
        return min(M_s, M_v)


class MpcController(SlipController):
    """Receding horizon on the believed soil; its first slip drives the slip loop (module docstring)."""

    kind = "mpc"

    def __init__(self, *args: Any, **kw: Any) -> None:
        super().__init__(*args, **kw)
        s = self.settings
        self.problem = MpcProblem(self.vehicle, horizon=s.mpc_horizon, h=s.mpc_interval_s, qp=s.mpc_qp)
        self._n = 0
        self._plan_slip = 0.0
        self._dist = (0.0, -1, math.nan)  # (filtered residual force N, its patch, last filtered speed)
        self.solve_times_s: list[float] = []  # wall clock per solve
        self.solve_cpu_s: list[float] = []  # CPU time per solve (IPOPT runs in this thread)

    def _disturbance(self, b: SoilBelief, patch: int, dt: float) -> float:
        """The filtered hull-force residual of the believed soil, N (``mpc_disturbance_s``; restarts per patch)."""
        tau = self.settings.mpc_disturbance_s
        d, k, v_prev = self._dist
        if tau <= 0 or k != patch or not math.isfinite(v_prev):
            self._dist = (0.0, patch, self._v)
            return 0.0
        i = max(self._slip, 0.0)
        model = self._thrust1(b, i) - self.resistance(patch) - self._sinkage_N(b, patch) * i
        res = self.vehicle.mass * (self._v - v_prev) / dt - model
        d += dt / (tau + dt) * (res - d)
        d = min(max(d, -0.5 * b.max_thrust_N), 0.5 * b.max_thrust_N)
        self._dist = (d, patch, self._v)
        return d

    def _torque(self, patch: int, v_ref: float, dt: float) -> float:
        b = self.belief.belief(patch, patch) if self.belief is not None else None
        if b is None:
            return super()._torque(patch, v_ref, dt)
        d = self._disturbance(b, patch, dt)
        if self._probing(patch, v_ref):
            ceiling, b = self._ceiling(patch)
            self.limiting, self.slip_target = "probe", self._probe_target(ceiling)
            M, gain = self._slip_loop(self.slip_target, b, dt, patch)
            self._integrate_slip(gain, self.slip_target, dt)
            return M
        self.limiting, self.slip_target = "plan", self._plan_slip
        if self._n % self.settings.mpc_every == 0 and v_ref >= _STOP_SPEED:  # stopping: the plan is not used
            t0, c0 = time.perf_counter(), time.process_time()
            M_max = self._M_max if math.isfinite(self._M_max) else 1e12
            P_max = self._P_max if math.isfinite(self._P_max) else 1e15
            plan = self.problem.solve(
                self._v,
                b.max_thrust_N,
                b.shear_modulus_m,
                self.resistance(patch) - d,
                self._sinkage_N(b, patch),
                v_ref,
                self._plan_slip,
                self.max_slip,
                M_max,
                P_max,
            )
            self.solve_times_s.append(time.perf_counter() - t0)
            self.solve_cpu_s.append(time.process_time() - c0)
            self._plan_slip = float(plan[0])
        self._n += 1
        if v_ref < _STOP_SPEED:  # stopping: the speed loop brakes (the plan's slips cannot be negative)
            self._Is = 0.0
            self.limiting = "speed"
            return self._speed_loop(patch, v_ref, dt, min(self._M_max, self._P_max / max(self._w, 1e-3)))
        if self.problem.failed_last:  # no plan: the slip controller's rule (speed loop under the optimal slip)
            return SlipController._torque(self, patch, v_ref, dt)
        M, gain = self._slip_loop(self._plan_slip, b, dt, patch)
        self._integrate_slip(gain, self._plan_slip, dt)
        if not self.settings.mpc_speed_floor:
            return M
        # the floor: the slip controller's rule (speed loop under the optimal-slip ceiling) when it asks for more
        ceiling, _ = self._ceiling(patch)
        M_c = self._slip_loop(ceiling, b, dt, patch)[0] - self._Is  # the plan loop's integral is not the ceiling's
        M_v = self._speed_loop(patch, v_ref, dt, min(self._M_max, self._P_max / max(self._w, 1e-3), M_c))
        floor = min(M_v, M_c)
        if floor > M:
            self.limiting, self.slip_target = ("slip" if M_c < M_v else "speed"), ceiling
            return floor
        return M


def make_controller(
    kind: str, vehicle: Vehicle, *, route: Any = None, target_speed_m_s: float | None = None, **settings: Any
) -> Controller:
    """A controller object with ``command(measurement) -> torque``.

    Parameters
    ----------
    kind
        ``"pi"``, ``"slip"``, ``"mpc"`` or ``"fixed_slip"`` (:data:`CONTROLLERS`).
    vehicle
        The vehicle (limits from ``max_sprocket_torque`` and ``max_power``).
    route
        A :class:`~soiltrack.planning.Route` (patches with planned soils and grades, slip limit), or
        ``None``: one flat patch of ``prior_soil``.
    target_speed_m_s
        Speed to track, m/s (default: the route's larger of ``v0_m_s`` and ``v_end_m_s``).
    **settings
        Fields of :class:`ControlSettings`, and ``soil`` (``"estimate"`` default, ``"nominal"``: the
        route's soils, no estimator, ``"true"``: ``true_soils``, one Soil per patch), ``true_soils``,
        ``true_slip_sinkage`` (with ``soil="true"``: each patch's ``mu_s``, default 0),
        ``prior_soil`` (without a route; default LETE sand), ``estimator_factory`` (see
        :class:`~.belief.EstimatedSoil`).
    """
    if kind not in CONTROLLERS:
        raise DataError(f"unknown controller {kind!r}; expected one of {CONTROLLERS}", column="--controller")
    source = settings.pop("soil", "estimate")
    true_soils = settings.pop("true_soils", None)
    prior = settings.pop("prior_soil", None)
    factory = settings.pop("estimator_factory", None)
    true_mu = settings.pop("true_slip_sinkage", None)
    unknown = sorted(set(settings) - {f.name for f in fields(ControlSettings)})
    if unknown:
        raise DataError(f"unknown controller setting(s) {unknown}")
    cs = replace(ControlSettings(), **settings)
    view = RouteView.of(route, prior)
    if target_speed_m_s is None:
        if route is None:
            raise DataError("make_controller needs target_speed_m_s (or a route)")
        target_speed_m_s = max(route.v0_m_s, route.v_end_m_s)
    if source not in SOIL_SOURCES:
        raise DataError(f"unknown soil source {source!r}; expected one of {SOIL_SOURCES}")
    belief: PriorSoil | None
    if kind in ("pi", "fixed_slip"):
        belief = None
    elif source == "estimate":
        belief = EstimatedSoil(vehicle, view.soils, view.grades_deg, factory)
    elif source == "nominal":
        belief = PriorSoil(vehicle, view.soils, view.grades_deg)
    else:
        if true_soils is None or len(true_soils) != len(view.soils):
            raise DataError("soil='true' needs true_soils, one Soil per patch of the route")
        belief = TrueSoil(vehicle, list(true_soils), view.grades_deg, true_mu)
    cls = {"pi": PIController, "slip": SlipController, "mpc": MpcController, "fixed_slip": SlipController}[kind]
    kw = {"fixed": cs.fixed_slip} if kind == "fixed_slip" else {}
    ctl = cls(vehicle, view, float(target_speed_m_s), cs, belief, **kw)
    if kind == "fixed_slip":
        ctl.kind = f"fixed_slip_{round(cs.fixed_slip * 100):g}"
    return ctl
