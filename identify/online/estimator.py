"""On-line soil identification while driving: a moving-horizon estimator with real-time iterations.

Method
------
The estimate is the batch drive-log fit (:mod:`soiltrack.identify.drivelog`, output-error
formulation with latent slips) of the samples inside a moving horizon of ``window_s`` seconds,
tracked by real-time iteration: every new sample enters the horizon with its latent slip
predicted from the current estimate, samples older than the horizon (or older than the last
detected change of terrain) leave it, and ONE Gauss-Newton step on (F_max, K, all latent
slips) is taken (:class:`~.kernels.Kernels`: the slips are eliminated exactly, one pass
over the horizon in a compiled CasADi kernel). While the Newton decrement says the iterate is
not converged (start, after a change) up to ``max_steps_per_update`` steps are taken. When
nothing changes, the iterate sits on the batch fit's optimum of the same window.

Covariance: the batch fit's sandwich ``A^-1 B A^-1`` (exact per-sample Hessian, empirical score
variance), from the same pass. What is identifiable follows the batch fit's regime rules
(:mod:`soiltrack.identify.drivelog.regime`): gentle driving (F_max and K correlated beyond
0.99, or F_max's standard error beyond 25 %, or F_max on a bound) identifies only the
small-slip slope ``F_max l / (2 K)``.

Change of terrain: :class:`~.detector.CusumDetector` on the standardised one-step prediction
residuals of new samples; on an alarm the horizon drops every sample before the estimated
change time (the old soil is forgotten) and the iteration restarts from the current iterate.

Input: samples with a missing or non-finite channel are skipped and counted (the sample after
a gap starts a new chain: the sprocket equation needs two consecutive samples); irregular time
steps enter the sprocket equation as they are, and a step longer than ``max_step_ratio`` times
the running median breaks the chain. Two-track samples (:meth:`OnlineEstimator.update_tracks`)
are combined (summed torque, mean speed) and turning samples are recognised with the same rule
as a two-track log file (:func:`soiltrack.soilmodel.tracks.turning_mask`, noise levels from the
recent samples) and left out. The acceleration channel is accepted and not used (the nominal
batch fit does not use it either).
"""

from __future__ import annotations

import math
import statistics
from collections import deque

import numpy as np

from ...soilmodel.tracks import MAD_TO_SIGMA, NOISE_FLOOR_REL, combine_tracks, robust_noise, turning_mask
from ...soilmodel.effects import effective_normal_load
from ...soilmodel.traction import max_thrust_expr
from ...soilmodel.vehicle import Vehicle
from ..drivelog.noise import noise_model
from ..drivelog.relaxation import TREND_SAMPLES
from ..drivelog.regime import GENTLE_CORRELATION, GENTLE_REL_STDERR, K_REL_STDERR
from .detector import CusumDetector, ExcitationTest
from .ccall import BufferCall
from .kernels import JUMP_SIGMA, NOISE, PARAMS, RAW, ROWS, SUMS, kernels
from .memory import HeldSoil, fuse
from .result import IDENTIFIABLE_NAMES, NOT_SEPARABLE, OnlineEstimate
from .settings import OnlineSettings
from .turning import TurningSettings, TurningUpdate  # i42 hook

__all__ = ["OnlineEstimator", "INITIAL_CAPACITY", "START_THRUST_FACTOR", "MIN_NOISE_SAMPLES"]

#: Horizon capacity the estimator starts with (grown by doubling when the horizon needs more).
INITIAL_CAPACITY = 64
#: Start value of F_max: this factor times the largest thrust seen (the batch fit's start rule), applied
#: until the iteration has converged once, whenever a thrust (less two standard deviations) exceeds the iterate.
START_THRUST_FACTOR = 1.2
#: Fewest readings the noise levels are estimated from (before that: the first estimate stays).
MIN_NOISE_SAMPLES = 8
#: Informative samples closer than this belong to one excitation (a pull), s (change windows).
EXCITATION_GAP_S = 0.5
#: Relative step of the finite differences of a residual in (F_max, K) (:meth:`OnlineEstimator._reference_residual`).
_FD_REL = 1e-4
#: Newton steps on K at the larger F_max of :meth:`OnlineEstimator._rejects_larger`.
_REJECT_K_STEPS = 6
#: Turning-noise levels are re-estimated this often while fewer than ``turn_history`` are known.
_TURN_REESTIMATE_EARLY = 8

_P = {name: j for j, name in enumerate(PARAMS)}
_S = {name: j for j, name in enumerate(SUMS)}
_R = {name: j for j, name in enumerate(ROWS)}
_RAW_JUMP = RAW.index("jump")
_RAW_RELAX = [RAW.index(k) for k in ("M", "w_next", "h_next", "slip_trend", "F_pilot", "K_pilot", "relax")]
#: The relaxation readings are the last entries of a sample's readings, in this order (written as a slice).
_RAW_RELAX_AT = _RAW_RELAX[0]
assert _RAW_RELAX == list(range(_RAW_RELAX_AT, len(RAW)))
# per-update indices as plain ints (no dict look-up on the hot path)
_RM, _RT, _RISC = ROWS.index("m"), ROWS.index("T"), ROWS.index("inv_sc")
_PXF, _PXK = PARAMS.index("xF"), PARAMS.index("xK")
_SN, _SCOST = SUMS.index("n_used"), SUMS.index("cost")
_N = {name: j for j, name in enumerate(NOISE)}
#: Benign readings for empty slots (finite everything; never used: outside the horizon).
_EMPTY_RAW = np.array([1.0, 1.0, 1.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 1.0, 1.0, 0.0])
_EMPTY_RAW_TAIL = tuple(_EMPTY_RAW[6:].tolist())  # a new sample's readings after its first six
_MESSAGES = {
    "ok": "converged",
    "warming_up": "too few samples for an estimate yet",
    "not_converged": "the Gauss-Newton iteration has not converged yet",
}
#: What an estimate does not identify, given what it does (c and phi never: one normal load).
_NOT_IDENTIFIED: dict[tuple[str, ...], tuple[str, ...]] = {
    ident: tuple(n for n in IDENTIFIABLE_NAMES if n not in ident) + NOT_SEPARABLE
    for ident in ((), ("slope",), ("slope", "max_thrust"), ("slope", "max_thrust", "shear_modulus"))
}


class OnlineEstimator:
    """Streaming identification of F_max and K with change-of-terrain detection.

    Parameters
    ----------
    vehicle
        The vehicle (geometry, inertia, weight).
    settings
        :class:`~.settings.OnlineSettings` (defaults if ``None``).

    Examples
    --------
    >>> est = OnlineEstimator(VEHICLES["light"])                        # doctest: +SKIP
    >>> for row in rows:                                               # doctest: +SKIP
    ...     e = est.update(row.t, row.torque, row.sprocket_speed, row.speed)
    ...     if e.change_detected: print("new terrain since", e.change_time_s)
    """

    def __init__(
        self, vehicle: Vehicle, settings: OnlineSettings | None = None, *, turning: TurningSettings | None = None
    ) -> None:
        self.vehicle = vehicle
        self.settings = settings or OnlineSettings()
        s = self.settings
        # the normal load on the known grade (soilmodel's one home of the grade's load), and the
        # range of F_max = A c + N tan(phi) over the soil box at that load
        self._normal_load = (
            float(effective_normal_load(vehicle.weight, vehicle, {"grade": s.grade_rad}))
            if s.grade_rad
            else float(vehicle.weight)
        )
        self._grade = float(s.grade_rad)
        N, A, b = self._normal_load, vehicle.contact_area, s.bounds
        Fb = (
            float(max_thrust_expr(max(b.cohesion[0], 0.0), b.friction_angle[0], N, A, s.model)),
            float(max_thrust_expr(b.cohesion[1], b.friction_angle[1], N, A, s.model)),
        )
        Kb = tuple(s.bounds.shear_modulus)
        self._F_ref = 0.5 * (Fb[0] + Fb[1])
        self._K_ref = math.sqrt(Kb[0] * Kb[1])
        self._bounds_scaled = (
            (Fb[0] / self._F_ref, Fb[1] / self._F_ref),
            (Kb[0] / self._K_ref, Kb[1] / self._K_ref),
        )
        self._P = np.zeros(len(PARAMS))
        for name, val in (
            ("F_ref", self._F_ref),
            ("K_ref", self._K_ref),
            ("l", vehicle.track_length),
            ("max_step", s.max_step_scaled),
            ("xF_lo", self._bounds_scaled[0][0]),
            ("xF_hi", self._bounds_scaled[0][1]),
            ("xK_lo", self._bounds_scaled[1][0]),
            ("xK_hi", self._bounds_scaled[1][1]),
            ("xF", self._bounds_scaled[0][0]),
            ("xK", 1.0),
        ):
            self._P[_P[name]] = val
        self._noise = np.zeros(len(NOISE))
        self._noise[[_N["r"], _N["I"], _N["min_speed"], _N["l"]]] = (
            vehicle.sprocket_radius,
            vehicle.sprocket_inertia,
            s.min_speed,
            vehicle.track_length,
        )
        self._Ph = np.zeros(len(PARAMS))  # the parameters at the held estimate (for the detector)
        self._Vh = np.zeros(3)  # the held covariance over the scaled (xF, xK)
        self._held_out = np.zeros(3)
        self._held = HeldSoil(s.drift_max_thrust_rel, s.drift_shear_modulus_rel)
        self._informed_at: float | None = None
        self._info_times: deque = deque(maxlen=4096)  # times of the informative samples (change windows)
        self._loaded_times: deque = deque(maxlen=4096)  # ... of the samples loaded to detect_min_load
        self._t_first = math.nan
        self._have_noise = False
        self._noise_known = None not in (s.sigma_torque, s.sigma_sprocket_speed, s.sigma_vehicle_speed)
        self._since_noise = 0
        self._alloc(INITIAL_CAPACITY)
        # the horizon's slots in time order, (t, slot), and the running maximum of the used slots'
        # peak thrust (a deque of (t, slot, peak) with decreasing peaks: the maximum is its front)
        self._live: deque[tuple[float, int]] = deque()
        self._peaks: deque[tuple[float, int, float]] = deque()
        self._hist: deque = deque()  # (t, M, w, v) of valid straight samples, time order
        self._dts: deque = deque(maxlen=31)
        self._dt_med: float | None = None
        self._dt_count = 0
        self._prev: tuple[float, float, float, int] | None = None  # t, M, w, slot (-1: not in horizon)
        self._last_thrust: tuple[float, float] | None = None  # T and sigma_T of the previous sample
        self._thrust_before: tuple[float, float] | None = None  # ... and of the one before it (relaxation)
        self._slips: deque = deque(maxlen=TREND_SAMPLES)  # measured slips of the latest samples (slip trend)
        self._n_slips = 0  # slips appended so far (the index of the next)
        self._pending: deque = deque()  # samples waiting for their slip trend: (index, slot, t, M, w_next, h_next)
        self._t_reset = -math.inf
        self._detector = CusumDetector(s.detect_reference, s.detect_threshold, s.detect_clip)
        self._detect_since = -math.inf
        # the excitation test (detector.ExcitationTest): its own prediction buffers at the reference
        self._xtest = ExcitationTest(s.detect_clip, s.detect_excitation_bias)
        self._xref: tuple[tuple[float, float], tuple[float, float, float], float] | None = None  # x, P, t_ref
        self._xalarm: tuple[float, tuple[float, float], float] | None = None
        self._xrow, self._xP, self._xout = np.zeros(len(ROWS)), np.zeros(len(PARAMS)), np.zeros(2)
        k0 = kernels(INITIAL_CAPACITY)
        self._c_predict_ref = BufferCall(k0.predict, k0.library, [self._xrow, self._xP], [self._xout])
        self._recent_z: deque = deque(maxlen=s.detect_scale_samples)
        self._F_known: float | None = None  # last F_max the horizon determined (since the last change)
        self._known_since = math.inf  # when it was first determined
        self._last_time = -math.inf
        self._z_scale = 1.0
        self._z_count = 0
        self._turn_d: deque = deque(maxlen=s.turn_history)
        self._turn_y: deque = deque(maxlen=s.turn_history)
        self._turn_sigma: tuple[float | None, float | None] = (None, None)
        self._turn_count = 0
        self._w_max = 0.0
        self._thrust_max = 0.0
        self._started = False
        self.changes: list[dict] = []
        self.samples_seen = 0
        self.samples_skipped = 0
        self.samples_turning = 0
        # i42 hook: turning samples fitted by the steering model (identify/online/turning.py)
        self.turning = TurningUpdate(vehicle, s.bounds, turning)
        self._converged = False
        self._gentle_win: dict | None = None  # the last fit of a gentle horizon (see _solve)
        self._since_solve = 0
        self._last: OnlineEstimate | None = None

    # ------------------------------------------------------------------ buffers
    def _alloc(self, cap: int) -> None:
        k = kernels(cap)
        self._cap = cap
        self._backend = k.backend
        self._RAW = np.tile(_EMPTY_RAW, (cap, 1))
        self._D = np.zeros((cap, len(ROWS)))
        self._ok = np.zeros(cap)
        self._Z = np.zeros(cap)
        self._tslot = np.full(cap, -math.inf)
        self._slot = 0
        self._x_out = np.zeros(2)
        self._Z_out = np.zeros(cap)
        self._sums = np.zeros(len(SUMS))
        self._sl: list[float] = self._sums.tolist()  # the sums as Python floats (read per update)
        self._scale_of: tuple[list[float] | None, float] = (None, 1.0)  # _scale's value for the sums ``_sl``
        self._peak = np.zeros(cap)  # per slot: thrust two standard deviations below its value
        self._row = np.zeros(len(ROWS))
        self._raw1 = np.zeros(len(RAW))
        self._raw_relax = np.zeros(len(RAW))
        self._row_relax = np.zeros(len(ROWS))
        self._relax_T = np.zeros(1)
        self._relax_sT = np.zeros(1)
        self._pred_out = np.zeros(2)
        self._T_out = np.zeros(1)
        self._sT_out = np.zeros(1)
        self._rows_all = np.zeros((cap, len(ROWS)))
        self._T_all = np.zeros(cap)
        self._sT_all = np.zeros(cap)
        lib = k.library
        self._c_step = BufferCall(k.step, lib, [self._D, self._Z, self._P], [self._x_out, self._Z_out, self._sums])
        self._c_track = BufferCall(k.track, lib, [self._D, self._Z, self._P], [self._x_out, self._Z_out, self._sums])
        self._c_predict = BufferCall(k.predict, lib, [self._row, self._P], [self._pred_out])
        self._c_predict_held = BufferCall(k.predict_held, lib, [self._row, self._Ph, self._Vh], [self._held_out])
        self._c_prepare = BufferCall(k.prepare, lib, [self._raw1, self._noise], [self._row, self._T_out, self._sT_out])
        self._c_relax = BufferCall(
            k.prepare, lib, [self._raw_relax, self._noise], [self._row_relax, self._relax_T, self._relax_sT]
        )
        self._relax_pred = np.zeros(2)
        self._c_relax_predict = BufferCall(k.predict, lib, [self._row_relax, self._P], [self._relax_pred])
        self._c_prepare_all = BufferCall(
            k.prepare_all, lib, [self._RAW, self._noise], [self._rows_all, self._T_all, self._sT_all]
        )

    def _grow(self) -> None:
        self._finish_relax(flush=True)  # the queue holds slot numbers: settled before they move
        old = (self._RAW, self._D, self._ok, self._Z, self._tslot, self._sums.copy(), self._peak)
        cap = self._cap
        new = min(2 * cap, self.settings.max_capacity)
        if new == cap:
            return
        order = np.argsort(old[4])  # oldest first
        self._alloc(new)
        self._RAW[:cap] = old[0][order]
        self._D[:cap] = old[1][order]
        self._ok[:cap] = old[2][order]
        self._Z[:cap] = old[3][order]
        self._tslot[:cap] = old[4][order]
        self._sums[:] = old[5]
        self._sl = self._sums.tolist()
        self._peak[:cap] = old[6][order]
        self._slot = cap
        new_slot = np.empty(cap, dtype=int)
        new_slot[order] = np.arange(cap)
        self._live = deque((t, int(new_slot[j])) for t, j in self._live)
        self._peaks = deque((t, int(new_slot[j]), val) for t, j, val in self._peaks)
        if self._prev is not None and self._prev[3] >= 0:
            p = self._prev
            self._prev = (p[0], p[1], p[2], int(new_slot[p[3]]))

    # ------------------------------------------------------------------ public
    @property
    def estimate(self) -> OnlineEstimate | None:
        """The estimate after the last update (``None`` before the first)."""
        return self._last

    @property
    def normal_load_N(self) -> float:
        """Normal load of the estimates, N: ``W cos(theta)`` on the known grade (``settings.grade_rad``)."""
        return self._normal_load

    @property
    def backend(self) -> str:
        """What evaluates the kernels (C code, or CasADi's virtual machine)."""
        return self._backend

    def update(
        self,
        time_s: float,
        sprocket_torque: float,
        sprocket_speed: float,
        vehicle_speed: float,
        vehicle_accel: float | None = None,
    ) -> OnlineEstimate:
        """Take one sample and return the estimate.

        Parameters
        ----------
        time_s, sprocket_torque, sprocket_speed, vehicle_speed
            Time (s), torque of both tracks (N m), sprocket speed (rad/s), vehicle speed (m/s).
            A missing (``None``) or non-finite reading skips the sample (counted).
        vehicle_accel
            IMU acceleration, m/s^2: accepted and not used (the nominal fit does not use it).
        """
        self.samples_seen += 1
        try:
            t, M, w, v = float(time_s), float(sprocket_torque), float(sprocket_speed), float(vehicle_speed)
        except (TypeError, ValueError):
            return self._skip(time_s, "a channel is missing or not finite")
        if not (math.isfinite(t) and math.isfinite(M) and math.isfinite(w) and math.isfinite(v)):
            return self._skip(time_s, "a channel is missing or not finite")
        return self._straight(t, M, w, v)

    def update_tracks(
        self,
        time_s: float,
        torque_left: float,
        torque_right: float,
        speed_left: float,
        speed_right: float,
        vehicle_speed: float,
        vehicle_accel: float | None = None,
        yaw_rate: float | None = None,
    ) -> OnlineEstimate:
        """Take one two-track sample and return the estimate.

        Per-track torque (N m) and sprocket speed (rad/s), vehicle speed (m/s), optional
        acceleration (not used) and yaw rate (rad/s). The channels are combined (summed
        torque, mean speed); a turning sample (left and right speeds apart, or a yaw rate,
        beyond ``turn_threshold`` noise levels) is left out and counted, with the sample
        before it (a turn's edge), and it breaks the sample chain.
        """
        self.samples_seen += 1
        vals = (time_s, torque_left, torque_right, speed_left, speed_right, vehicle_speed)
        if not all(_finite(x) for x in vals):
            return self._skip(time_s, "a channel is missing or not finite")
        yaw = float(yaw_rate) if yaw_rate is not None and _finite(yaw_rate) else None
        if self._is_turning(float(speed_left), float(speed_right), yaw):
            self._turn_hook((time_s, torque_left, torque_right, speed_left, speed_right, vehicle_speed, yaw))
            if self._prev is not None and self._prev[3] >= 0:  # a turn's edge: the sample before it
                j = self._prev[3]
                self._tslot[j] = -math.inf
                self._D[j, _RM] = 0.0
                if self._live and self._live[-1][1] == j:
                    self._live.pop()
                self._rebuild_peaks()
            self._end_chain()
            return self._report(float(time_s), None, False, None, "skipped", "turning sample left out")
        self._turn_hook(None)  # i42 hook: a straight sample ends the turn's block
        M, w = combine_tracks(torque_left, torque_right, speed_left, speed_right)
        return self._straight(float(time_s), float(M), float(w), float(vehicle_speed))

    # ------------------------------------------------------------------ internals
    def _turn_hook(self, sample) -> None:
        """i42 hook: a turning sample to the steering-model blocks (None: the turn ended); fused when fitted."""
        T, w = self.turning, self.settings.window_s
        blk = T.add(sample, self._held, w) if sample else T.end(self._held, w)
        self.samples_turning = T.samples_fitted
        if blk is not None and blk.status == "fused":
            self._informed_at = blk.time_s

    def _skip(self, time_s, why: str) -> OnlineEstimate:
        self.samples_skipped += 1
        self._turn_hook(None)  # i42 hook: a gap ends the turn's block
        self._end_chain()
        t = float(time_s) if _finite(time_s) else (self._last.time_s if self._last else math.nan)
        return self._report(t, None, False, None, "skipped", f"sample skipped: {why}")

    def _is_turning(self, wl: float, wr: float, yaw: float | None) -> bool:
        s = self.settings
        self._turn_d.append(wl - wr)
        if yaw is not None:
            self._turn_y.append(yaw)
        self._w_max = max(self._w_max, abs(wl), abs(wr))
        self._turn_count += 1
        n = len(self._turn_d)
        every = _TURN_REESTIMATE_EARLY if n < s.turn_history else s.noise_every
        if n >= MIN_NOISE_SAMPLES and (self._turn_sigma[0] is None or self._turn_count % every == 0):
            floor = NOISE_FLOOR_REL * self._w_max + 1e-12
            sd: float | None = max(robust_noise(np.fromiter(self._turn_d, float)), floor)
            sy = None
            if len(self._turn_y) >= MIN_NOISE_SAMPLES:
                y = np.fromiter(self._turn_y, float)
                sy = max(robust_noise(y), NOISE_FLOOR_REL * float(np.max(np.abs(y))) + 1e-12)
            self._turn_sigma = (sd, sy)
        sd, sy = self._turn_sigma
        if sd is None:
            return False
        return bool(
            turning_mask(
                [wl],
                [wr],
                None if (yaw is None or sy is None) else [yaw],
                sigma_difference=sd,
                sigma_yaw=sy,
                threshold=s.turn_threshold,
                margin=0,
            )[0]
        )

    def _straight(self, t: float, M: float, w: float, v: float) -> OnlineEstimate:
        s = self.settings
        prev = self._prev
        if prev is not None and t <= prev[0]:
            return self._skip(t, f"time {t:.6g} s does not increase (previous {prev[0]:.6g} s)")
        self._hist.append((t, M, w, v))
        if self._t_first != self._t_first:
            self._t_first = t
        cutoff = max(t - s.window_s, self._t_reset)
        while self._hist and self._hist[0][0] < cutoff:
            self._hist.popleft()
        if prev is None:
            self._prev = (t, M, w, -1)
            return self._report(t, None, False, None, None, "first sample of a chain (no sprocket-speed difference)")
        h = t - prev[0]
        if len(self._dts) >= 3 and h > s.max_step_ratio * self._median_dt():
            self._end_chain()
            self._prev = (t, M, w, -1)
            return self._report(t, None, False, None, None, f"time step {h:.3g} s too long: a new chain starts")
        self._dts.append(h)
        self._refresh_noise()
        raw = self._raw1
        raw[:] = (v, w, prev[2], prev[1], h, 0.0, *_EMPTY_RAW_TAIL)
        self._c_prepare()
        T, sT = float(self._T_out[0]), float(self._sT_out[0])
        self._slips.append(1.0 - v / (self.vehicle.sprocket_radius * w) if w != 0.0 else math.nan)
        self._n_slips += 1
        # thrust jumps (the batch fit's allowance): this sample and the one before it
        if self._last_thrust is not None:
            T0, sT0 = self._last_thrust
            dT = abs(T - T0)
            if dT > JUMP_SIGMA * math.hypot(sT, sT0):
                raw[_RAW_JUMP] = dT
                self._c_prepare()
                if prev[3] >= 0:
                    j = prev[3]
                    self._RAW[j, _RAW_JUMP] = max(self._RAW[j, _RAW_JUMP], dT)
                    self._reprepare(j)
        if s.relaxation and prev[3] >= 0:
            queued = (
                self._last_thrust is not None
                and self._thrust_before is not None
                and self._queue_relax(prev[3], prev[0], T, sT, M=prev[1], w_next=w, h_next=h)
            )
            if not queued:  # the end-point rule stays: the sample is used as it is
                self._release(prev[3], cutoff)
        self._finish_relax(cutoff=cutoff)
        self._thrust_before = self._last_thrust
        self._last_thrust = (T, sT)
        row = self._row.tolist()  # the new sample's data column as floats (read below)
        used = row[_RM] > 0
        if used and not self._started:  # start value of F_max (the batch fit's rule), until converged once
            # raised only where a thrust (two standard deviations below its value) exceeds the iterate:
            # a floor at START_THRUST_FACTOR x the largest thrust held an iteration that had not yet
            # converged on a pull's plateau (0.9-0.97 F_max) above the truth, update after update
            self._thrust_max = max(self._thrust_max, T - 2.0 * sT)
            if self._thrust_max > self._P[_PXF] * self._F_ref:
                self._P[_PXF] = min(START_THRUST_FACTOR * self._thrust_max / self._F_ref, self._bounds_scaled[0][1])
        # change detection on the one-step prediction, before the sample enters the horizon
        change, slip0 = self._detect(t, T, sT) if used else (None, None)
        # the sample enters the ring buffer
        slot = self._slot
        if self._tslot[slot] >= cutoff and self._cap < s.max_capacity:
            self._grow()
            slot = self._slot
        if self._live and self._live[0][1] == slot:  # at max_capacity: the oldest sample leaves early
            self._live.popleft()
            if self._peaks and self._peaks[0][1] == slot:
                self._peaks.popleft()
        self._RAW[slot] = raw
        D = self._D
        D[slot] = self._row
        self._ok[slot] = row[_RM]
        if s.relaxation:  # held back until its discretisation is decided (see _release, _finish_relax)
            D[slot, _RM] = 0.0
        isc = row[_RISC]
        pk = self._peak[slot] = row[_RT] - 2.0 / isc if isc > 0 else -math.inf  # as _peak
        self._Z[slot] = 0.0 if slip0 is None else slip0
        self._tslot[slot] = t
        self._live.append((t, slot))
        if row[_RM] > 0:
            self._push_peak(t, slot, pk)
        self._slot = (slot + 1) % self._cap
        self._prev = (t, M, w, slot)
        return self._finish(t, slip0, change, cutoff)

    def _end_chain(self) -> None:
        """The sample chain breaks (a skipped or turning sample, a long gap): held-back samples are used as they are."""
        if self._prev is not None and self._prev[3] >= 0:
            self._release(self._prev[3], max(self._last_time - self.settings.window_s, self._t_reset))
        self._finish_relax(flush=True)
        self._prev = None
        self._last_thrust = None

    def _release(self, j: int, cutoff: float) -> None:
        """Slot ``j`` enters the fit (its use flag) unless it has left the horizon."""
        if self._tslot[j] >= cutoff:
            self._D[j, _RM] = self._ok[j]

    def held_back(self) -> list[int]:
        """Slots not in the fit yet: waiting for the next sample or their slip trend (the relaxation rule)."""
        out = [e[1] for e in self._pending]
        if self.settings.relaxation and self._prev is not None and self._prev[3] >= 0:
            out.append(self._prev[3])
        return out

    def _queue_relax(self, j: int, t: float, T1: float, sT1: float, *, M: float, w_next: float, h_next: float) -> bool:
        """Queue slot ``j`` (the sample before the new one) for the slip-relaxation rule (its next interval is known).

        The batch fit's ``discretisation="relaxation"`` (:mod:`~soiltrack.identify.drivelog.relaxation`):
        the thrust at the sample is ``(1 - phi) T_k + phi T_{k+1}``. Where the interval means are not
        a steady trend (second difference beyond :data:`JUMP_SIGMA` noise levels: a torque step at
        the traction limit) the end-point rule stays, as in the batch fit. The weight waits for the
        slip trend (:meth:`_finish_relax`).
        """
        (T0, sT0), (Tm, sTm) = self._last_thrust, self._thrust_before  # type: ignore[misc]
        if abs(T1 - 2.0 * T0 + Tm) > JUMP_SIGMA * math.sqrt(sT1 * sT1 + 4.0 * sT0 * sT0 + sTm * sTm):
            return False
        self._pending.append((self._n_slips - 2, j, t, M, w_next, h_next))
        return True

    def _finish_relax(self, flush: bool = False, cutoff: float | None = None) -> None:
        """Apply the relaxation rule to the queued samples whose slip trend is complete.

        ``phi`` comes from the slip's time constant at the slip trend (the median of the
        :data:`TREND_SAMPLES` measured slips centred on the sample, as the batch fit: the sample
        waits ``TREND_SAMPLES // 2`` samples for it; ``flush``: at a chain's end, what there is)
        and the pilot soil (the held estimate, else the iterate). The slot's peak (the
        informative-sample test) stays the end-point one; its latent slip starts again from the new
        row's optimum at the iterate (the row moved under it). ``cutoff``: the horizon's start (a
        slot before it is not used).
        """
        half = TREND_SAMPLES // 2
        pending = self._pending
        if not pending or not (flush or pending[0][0] + half <= self._n_slips - 1):
            return
        if cutoff is None:
            cutoff = max(self._last_time - self.settings.window_s, self._t_reset)
        while pending and (flush or pending[0][0] + half <= self._n_slips - 1):
            k, j, t, M, w_next, h_next = pending.popleft()
            if self._tslot[j] != t:  # the slot was reused or moved meanwhile
                continue
            base = self._n_slips - len(self._slips)  # the index of the oldest slip kept
            first = max(k - half, base)
            sl = [x for x in list(self._slips)[first - base :] if x == x]
            trend = statistics.median(sl) if sl else 0.0
            held = self._held.x
            F, K = held if held is not None else (self._P[_PXF] * self._F_ref, self._P[_PXK] * self._K_ref)
            RAWj = self._RAW[j]
            RAWj[_RAW_RELAX_AT:] = (M, w_next, h_next, trend, F, K, 1.0)
            self._raw_relax[:] = RAWj
            self._c_relax()
            row = self._row_relax
            self._D[j] = row
            m = self._ok[j] = row[_RM]
            if t < cutoff:
                self._D[j, _RM] = 0.0
            elif m > 0:
                self._c_relax_predict()
                self._Z[j] = self._relax_pred[0]

    def _detect(self, t: float, T: float, sT: float) -> tuple[float | None, float]:
        """The new sample's prediction: the CUSUM's change time (or ``None``) and its latent slip."""
        s = self.settings
        self._c_predict()
        slip0, wres = float(self._pred_out[0]), float(self._pred_out[1])
        z = wres / self._scale()
        self._note_informative(t, T, sT)
        if s.memory:
            z = self._held_residual(t, z)
        # a change is judged against a soil whose F_max was determined, on samples loaded against it
        # with the memory on, only what is held is tested (nothing held: nothing known to contradict; the
        # horizon's own iterate between pulls is not known, measured: a false alarm against it on the light vehicle)
        loaded = (
            (self._held.known or not s.memory)
            and self._F_known is not None
            and T >= s.detect_min_load * self._F_known
            and t - self._known_since >= s.detect_settle_s
        )
        change = None
        if (
            loaded
            and self._started
            and self._sl[_SN] >= s.detect_min_samples
            and t - self._detect_since >= s.detect_min_s
        ):
            change = self._detector.update(z / self._robust_scale(), t)
            if self._detector.statistic == 0.0:  # the residual spread is learnt from quiet samples only
                self._recent_z.append(z)
            if s.memory and change is None:
                self._xalarm = self._test_excitation(t)
        return change, slip0

    def _test_excitation(self, t: float) -> tuple[float, tuple[float, float], float] | None:
        """Add the new (loaded) sample to the excitation test; ``(t_change, window, keep_from)`` on an alarm.

        An excitation is a run of loaded samples (gaps below :data:`EXCITATION_GAP_S`, at most
        ``detect_excitation_max_s`` long); its reference is the held estimate at its first sample, with
        the covariance grown by the random walk since.
        """
        s, X, H = self.settings, self._xtest, self._held
        if H.x is None or H.P is None:
            return None
        if not X.active or t - X.t_last > EXCITATION_GAP_S or t - X.times[0] > s.detect_excitation_max_s:
            self._xref = (H.x, H.P, H.t_ref)
            X.begin(t, (H.x[0] / self._F_ref, H.x[1] / self._K_ref))
        assert self._xref is not None  # set with the excitation's reference
        x, P, t_ref = self._xref
        p11, p12, p22 = H.grown(x, P, t - t_ref)
        fr, kr = self._F_ref, self._K_ref
        r, d = self._reference_residual(x[0] / fr, x[1] / kr)
        d2 = X.add(t, r, d, (p11 / (fr * fr), p12 / (fr * kr), p22 / (kr * kr)))
        if d2 <= s.detect_excitation_chi2:
            return None
        best, lo, hi = X.change_points(s.detect_date_margin)
        times = X.times
        if lo == 0:  # the excitation may have begun on the new soil: dated at its start (as the other tests)
            return times[0], (self._change_window(times[0])[0], times[hi]), times[0]
        # inside the excitation: its samples from the earliest likely split on stay (the new horizon's ramp); the
        # window reaches back to the last informative sample before that split's excitation (the samples between,
        # a climb's, may be on the new soil without showing it)
        return times[best], (self._change_window(times[lo])[0], times[hi]), times[lo]

    def _reference_residual(self, xF: float, xK: float) -> tuple[float, tuple[float, float]]:
        """The new sample's standardised profiled residual at the scaled ``(xF, xK)`` and its gradient there.

        The gradient by forward differences (step :data:`_FD_REL` of each value), each point's latent
        slip profiled anew (the prediction kernel): the profiled residual's total derivative.
        """
        np.copyto(self._xrow, self._row)
        P, out, call = self._xP, self._xout, self._c_predict_ref
        np.copyto(P, self._P)
        P[_PXF], P[_PXK] = xF, xK
        call()
        r0 = float(out[1])
        hF, hK = _FD_REL * xF, _FD_REL * xK
        P[_PXF] = xF + hF
        call()
        dF = (float(out[1]) - r0) / hF
        P[_PXF], P[_PXK] = xF, xK + hK
        call()
        dK = (float(out[1]) - r0) / hK
        sc = self._scale()
        return r0 / sc, (dF / sc, dK / sc)

    def _finish(self, t: float, slip0, change, cutoff: float) -> OnlineEstimate:
        """After the sample entered: forget on a change, iterate, update the memory, report."""
        s = self.settings
        window, test, keep_from = None, "cusum", None
        t_rests = change  # what is held is judged by the excitations before this time
        if change is None and self._xalarm is not None:  # the excitation test's alarm, dated by it
            (change, window, keep_from), test = self._xalarm, "excitation"
            t_rests = self._xtest.times[0]  # the reference: held before the excitation began
        self._xalarm = None
        if change is not None and s.memory and self._excitations_before(t_rests) < s.detect_min_excitations:
            # what is held rests on one excitation (see detect_min_excitations): start it again
            self._held.reset()
            self._detector.reset(t)
            self._xtest.reset()
            change = window = None
        if change is not None:
            if window is None:
                window = self._change_window(change)
                change = self._excitation_start(change, window[0])
            self._forget(t, change, window, test=test, keep_from=keep_from)
            cutoff = max(t - s.window_s, self._t_reset)
        win = self._solve(t, cutoff, change is None)
        if s.memory:
            late = self._remember(t, win)
            if late is not None and change is None:  # the horizon contradicts what is known: a change
                change, window = late
                change = self._excitation_start(change, window[0])
                self._forget(t, change, window, test="horizon")
                self._iterate(max(t - s.window_s, self._t_reset))
                win = self._window(t)
                self._remember(t, win)
        return self._report(t, slip0, change is not None, change, None, "", win=win, window=window)

    def _solve(self, t: float, cutoff: float, may_skip: bool) -> dict:
        """The horizon's iteration and its fit (:meth:`_window`), or the last fit while driving is gentle.

        With the memory on, a horizon holding no sample loaded to ``detect_min_load`` of the held
        F_max (gentle driving) identifies at most the slope and the held estimate is what is
        reported; there the converged iteration is solved only every ``gentle_solve_every`` samples
        (the samples leaving the horizon still leave it at once, and the detector still tests each
        new sample). The last fit stands in between only if its horizon was gentle too.
        """
        s = self.settings
        gentle = (
            may_skip
            and s.memory
            and self._converged
            and self._held.known
            and not (self._loaded_times and self._loaded_times[-1] >= cutoff)
        )
        if gentle and self._gentle_win is not None and self._since_solve < s.gentle_solve_every - 1:
            self._since_solve += 1
            self._advance(cutoff)
            return self._gentle_win
        self._iterate(cutoff)
        win = self._window(t)
        self._since_solve = 0
        self._gentle_win = win if gentle and self._converged else None
        return win

    def _advance(self, cutoff: float) -> None:
        """Samples older than ``cutoff`` leave the horizon (their ``m`` set to 0)."""
        live, m = self._live, _RM
        while live and live[0][0] < cutoff:
            self._D[live.popleft()[1], m] = 0.0
        peaks = self._peaks
        while peaks and peaks[0][0] < cutoff:
            peaks.popleft()

    def _push_peak(self, t: float, slot: int, value: float) -> None:
        peaks = self._peaks
        while peaks and peaks[-1][2] <= value:
            peaks.pop()
        peaks.append((t, slot, value))

    def _rebuild_peaks(self) -> None:
        """The running maximum from scratch (after a slot's weight or use changed).

        What :meth:`_push_peak` leaves after pushing the used live slots in time order, at once: the
        slots whose peak exceeds every later one, and the last one.
        """
        self._peaks.clear()
        if not self._live:
            return
        ts, js = zip(*self._live)
        slots = np.fromiter(js, dtype=np.intp, count=len(js))
        used = np.flatnonzero(self._ok[slots] > 0)
        if used.size == 0:
            return
        vals = self._peak[slots[used]]
        if np.isnan(vals).any():  # NaN compares false: the one-at-a-time rule, as it is
            for k, val in zip(used.tolist(), vals.tolist()):
                self._push_peak(ts[k], js[k], val)
            return
        later = np.empty_like(vals)  # the largest peak after each slot (-inf after the last)
        later[-1] = -math.inf
        if vals.size > 1:
            np.maximum.accumulate(vals[:0:-1], out=later[-2::-1])
        keep = vals > later
        keep[-1] = True
        self._peaks.extend((ts[k], js[k], val) for k, val in zip(used[keep].tolist(), vals[keep].tolist()))

    def _median_dt(self) -> float:
        """Running median of the recent time steps (recomputed every few samples)."""
        self._dt_count += 1
        if self._dt_med is None or self._dt_count % _TURN_REESTIMATE_EARLY == 0:
            self._dt_med = statistics.median(self._dts)
        return self._dt_med

    def _reprepare(self, j: int) -> None:
        """Recompute slot ``j``'s data column from its readings (after its jump allowance grew)."""
        keep_row = self._row.copy()
        keep = (self._T_out.copy(), self._sT_out.copy(), self._raw1.copy())
        self._raw1[:] = self._RAW[j]
        self._c_prepare()
        self._D[j] = self._row
        self._ok[j] = self._row[_RM]
        if self.settings.relaxation:  # the sample before the new one: still held back (its rule is decided next)
            self._D[j, _RM] = 0.0
        self._peak[j] = _peak(self._row)
        self._rebuild_peaks()
        self._row[:] = keep_row
        self._T_out[:], self._sT_out[:], self._raw1[:] = keep

    def _forget(
        self,
        t: float,
        t_change: float,
        window: tuple[float, float] | None = None,
        test: str = "cusum",
        keep_from: float | None = None,
    ) -> None:
        """A change of terrain at ``t_change``: drop the older samples and what is held, restart the detector.

        ``keep_from``: the samples from this time on stay (default ``t_change``).
        """
        held = self._held.now(t)
        before = (float(self._P[_PXF] * self._F_ref), float(self._P[_PXK] * self._K_ref)) if held is None else held[0]
        self.changes.append(
            {
                "time_s": t_change,
                "window_s": list(window) if window is not None else [t_change, t_change],
                "detected_at_s": t,
                "test": test,
                "max_thrust_before_N": before[0],
                "shear_modulus_before_m": before[1],
            }
        )
        self._held.reset()
        self._informed_at = None
        cut = t_change if keep_from is None else keep_from
        for dq in (self._info_times, self._loaded_times):  # the new soil's samples only
            keep = [x for x in dq if x >= cut]
            dq.clear()
            dq.extend(keep)
        self._t_reset = cut
        self._gentle_win = None
        self._detector.reset(t)
        self._xtest.reset()
        self._detect_since = t
        self._converged = False
        self._since_noise = self.settings.noise_every  # re-estimate the noise on the new soil
        self._P[_P["w_prior"]] = 0.0  # the old soil's F_max no longer holds
        self._F_known = None
        self._known_since = math.inf

    def _refresh_noise(self) -> None:
        s = self.settings
        self._since_noise += 1
        if self._have_noise and (self._since_noise < s.noise_every or len(self._hist) < MIN_NOISE_SAMPLES):
            return
        arr = np.array(self._hist, dtype=float)
        if arr.shape[0] < 3:
            arr = np.vstack([arr] * 3)
        nm = (
            noise_model(arr[:, 1], s.sigma_torque),
            noise_model(arr[:, 2], s.sigma_sprocket_speed),
            noise_model(arr[:, 3], s.sigma_vehicle_speed),
        )
        self._noise[[_N["aM"], _N["bM"], _N["aw"], _N["bw"], _N["av"], _N["bv"]]] = [z for pair in nm for z in pair]
        if len(self._hist) >= MIN_NOISE_SAMPLES:
            self._since_noise = 0
        if self._have_noise:  # the horizon's weights follow the new noise levels
            self._c_prepare_all()
            self._D[:] = self._rows_all
            self._ok[:] = self._rows_all[:, _RM]
            with np.errstate(divide="ignore"):
                np.subtract(self._rows_all[:, _RT], 2.0 / self._rows_all[:, _RISC], out=self._peak)
            live = np.zeros(self._cap)
            for _, j in self._live:
                live[j] = 1.0
            np.multiply(self._ok, live, out=self._D[:, _RM])
            for j in self.held_back():
                self._D[j, _RM] = 0.0
            self._rebuild_peaks()
        self._have_noise = True

    def _scale(self) -> float:
        """Residual scale: 1 with known noise, else sqrt of the reduced chi-square of the horizon."""
        if self._noise_known:
            return 1.0
        sl = self._sl
        cached = self._scale_of
        if cached[0] is sl:  # the sums have not changed since it was computed (``_sl`` is replaced, never edited)
            return cached[1]
        n = sl[_SN]
        sc = math.sqrt(max(2.0 * sl[_SCOST] / max(n - 2.0, 1.0), 1e-12))
        self._scale_of = (sl, sc)
        return sc

    def _robust_scale(self) -> float:
        """Spread of the recent prediction residuals (MAD, never below 1), re-estimated every few samples.

        Where the model fits worse than the noise (transients, coasting) the residuals spread
        wider than the horizon's chi-square says; the detector then asks for a lean beyond that
        spread, not beyond the noise alone.
        """
        self._z_count += 1
        n = len(self._recent_z)
        if n >= MIN_NOISE_SAMPLES and self._z_count % _TURN_REESTIMATE_EARLY == 0:
            med = statistics.median(self._recent_z)
            self._z_scale = max(1.0, MAD_TO_SIGMA * statistics.median([abs(x - med) for x in self._recent_z]))
        return self._z_scale

    def _iterate(self, cutoff: float) -> None:
        """Newton steps on the horizon: one when converged, else up to ``max_steps_per_update``.

        A converged iteration takes the tracking step (:data:`~.kernels.TRACK_SLIP_ITERATIONS`
        slip iterations); one that has not, the full step. Within one update (fixed data) a step
        that raised the cost is taken back and retried with a quarter of the trust region
        (backtracking across kernel calls).
        """
        s = self.settings
        self._advance(cutoff)
        steps = 1 if self._converged else s.max_steps_per_update
        P = self._P
        before: tuple[float, float, float] | None = None  # (xF, xK, cost) before the last step
        tr = s.max_step_scaled
        for _ in range(steps + 1):
            P[_P["max_step"]] = tr
            x_old = (P[_PXF], P[_PXK])
            (self._c_track if self._converged else self._c_step)()
            sl = self._sums.tolist()
            x_new = self._x_out.tolist()
            if not math.isfinite(math.fsum(sl) + x_new[0] + x_new[1]):
                self._converged = False  # keep the last good iterate; say so
                P[_P["max_step"]] = s.max_step_scaled
                self._sl = sl
                return
            self._sl = sl
            cost = sl[_SCOST]
            if before is not None and cost > before[2] * (1 + 1e-9) + 1e-12:
                P[_PXF], P[_PXK] = before[0], before[1]  # take the step back, shorter
                tr *= 0.25
                before = None
                self._converged = False
                continue
            before = (x_old[0], x_old[1], cost)
            P[_PXF], P[_PXK] = x_new
            np.copyto(self._Z, self._Z_out)
            dec = abs(sl[_S["decrement"]]) / self._scale() ** 2
            self._converged = bool(sl[_SN] >= 3 and dec < s.converged_decrement)
            if self._converged or steps == 1:
                break
        P[_P["max_step"]] = s.max_step_scaled
        if self._converged:
            self._started = True

    def _covariance(self) -> tuple[float, float, float] | None:
        """Sandwich covariance over (F_max, K) in SI as ``(V_FF, V_FK, V_KK)``, or ``None`` when it does not exist."""
        S = self._sl
        a11, a12, a22 = S[_S["A11"]], S[_S["A12"]], S[_S["A22"]]
        b11, b12, b22 = S[_S["B11"]], S[_S["B12"]], S[_S["B22"]]
        if not (S[_SN] >= 3 and math.isfinite(a11 + a12 + a22 + b11 + b12 + b22)):
            return None
        det = a11 * a22 - a12 * a12
        if not (a11 > 0 and det > 1e-12 * a11 * a22):
            return None
        # A^-1 B A^-1 with A^-1 = [[a22, -a12], [-a12, a11]] / det
        i11, i12, i22 = a22 / det, -a12 / det, a11 / det
        m11, m12 = i11 * b11 + i12 * b12, i11 * b12 + i12 * b22  # rows of A^-1 B
        m21, m22 = i12 * b11 + i22 * b12, i12 * b12 + i22 * b22
        v11 = m11 * i11 + m12 * i12
        v12 = 0.5 * ((m11 * i12 + m12 * i22) + (m21 * i11 + m22 * i12))
        v22 = m21 * i12 + m22 * i22
        fr, kr = self._F_ref, self._K_ref
        v11, v12, v22 = v11 * fr * fr, v12 * fr * kr, v22 * kr * kr
        if not (math.isfinite(v11 + v12 + v22) and v11 > 0 and v22 > 0 and v11 * v22 > v12 * v12):
            return None
        return v11, v12, v22

    def _window(self, t: float) -> dict:
        """The horizon's own fit: values, data-only covariance and what it identifies (``ident``).

        Once the horizon determines F_max, a weak prior (``hold_rel``) holds the iterate there
        while later horizons do not determine it.
        """
        l = self.vehicle.track_length
        n_raw = self._sl[_SN]
        n_used = int(round(n_raw)) if math.isfinite(n_raw) else 0
        # identification needs the iteration to have converged once (since the start); before that
        # the iterate is shown, not identified
        have = self._started or (n_used >= 3 and self._converged)
        xF, xK = float(self._P[_PXF]), float(self._P[_PXK])
        w: dict = dict(F=None, K=None, sF=None, sK=None, cov=None, slope=None, s_slope=None, V=None)
        w.update(ident=(), n_used=n_used, have=have, K_bound=False)
        if not (have or n_used >= 3):
            return w
        F, K = xF * self._F_ref, xK * self._K_ref
        w.update(F=F, K=K, slope=F * l / (2 * K))
        V = self._covariance() if have and n_used >= 3 else None
        if V is None:
            return w
        v11, v12, v22 = V
        w["V"] = V
        g1, g2 = l / (2 * K), -F * l / (2 * K * K)
        w["s_slope"] = math.sqrt(max(g1 * g1 * v11 + 2 * g1 * g2 * v12 + g2 * g2 * v22, 0.0))
        if w["s_slope"] < GENTLE_REL_STDERR * w["slope"]:  # even the slope needs slips above the noise
            w["ident"] = ("slope",)
        sF_, sK_ = math.sqrt(v11), math.sqrt(v22)
        corr = v12 / (sF_ * sK_)
        (Flo, Fhi), (Klo, Khi) = self._bounds_scaled
        tol = 1e-6
        F_bound = not (Flo + tol < xF < Fhi - tol)
        K_bound = not (Klo + tol < xK < Khi - tol)
        w["K_bound"] = K_bound
        # samples to estimate its sandwich; and, while nothing is held, a converged fit (the first estimate
        # of a soil is held with no arrival cost to check it against: an iterate between steps is no fit)
        enough = n_used >= self.settings.identify_min_samples and (self._converged or self._held.known)
        if enough and abs(corr) < GENTLE_CORRELATION and sF_ / F < GENTLE_REL_STDERR and not F_bound:
            # the horizon's largest thrust, two standard deviations below its value
            peak = max(self._peaks[0][2], 0.0) if self._peaks else 0.0
            first = self.settings.memory and not self._held.known  # the first estimate of a soil
            if peak >= self.settings.identify_min_utilisation * F and (not first or self._rejects_larger(xF, xK)):
                w.update(ident=("slope", "max_thrust"), sF=sF_)
                # F_max is determined: hold it there (weakly) while later horizons do not determine it
                self._P[_P["xF_prior"]] = xF
                self._P[_P["w_prior"]] = 1.0 / (self.settings.hold_rel * xF) ** 2
                if self._F_known is None:
                    self._known_since = t
                self._F_known = F
                if sK_ / K <= K_REL_STDERR and not K_bound:
                    w.update(ident=("slope", "max_thrust", "shear_modulus"), sK=sK_)
                    w["cov"] = np.array([[v11, v12], [v12, v22]])
        return w

    def _rejects_larger(self, xF: float, xK: float) -> bool:
        """Whether the horizon's data reject ``identify_reject_factor`` times its F_max (K refitted).

        The profiled cost at F_max x factor, minimised over K by :data:`_REJECT_K_STEPS` Newton
        steps (the slips at their optimum in each kernel pass), against the cost at the estimate:
        twice the rise, in noise variances, must exceed ``identify_reject_chi2``. A likelihood-ratio
        check that does not rest on the estimate's own covariance or F_max (a gentle horizon's
        F_max along the ridge passes a utilisation test relative to itself). The horizon's state
        is restored.
        """
        s, P = self.settings, self._P
        keep = (P.copy(), self._Z.copy(), self._sums.copy(), self._x_out.copy(), self._Z_out.copy())
        cost0 = self._sl[_SCOST]
        (Flo, Fhi), (Klo, Khi) = self._bounds_scaled
        P[_PXF] = min(s.identify_reject_factor * xF, Fhi)
        P[_PXK] = min(s.identify_reject_factor * xK, Khi)  # the same small-slip slope to start from
        P[_P["w_prior"]] = 0.0
        P[_P["max_step"]] = 0.0  # the kernel's own step is not taken: its slips stay at their optimum
        best = math.inf
        try:
            for _ in range(_REJECT_K_STEPS):
                self._c_step()
                sl = self._sums
                best = min(best, float(sl[_SCOST]))
                np.copyto(self._Z, self._Z_out)
                g2, a22 = float(sl[_S["g2"]]), float(sl[_S["A22"]])
                if a22 <= 0:
                    a22 = float(sl[_S["S22"]])
                xk = P[_PXK]
                step = -g2 / a22 if a22 > 0 else 0.0
                P[_PXK] = min(max(xk + max(min(step, 0.25 * xk), -0.25 * xk), Klo), Khi)
        finally:
            P[:], self._Z[:], self._sums[:], self._x_out[:], self._Z_out[:] = keep
        sc = self._scale()
        return bool(math.isfinite(best) and 2.0 * (best - cost0) / (sc * sc) > s.identify_reject_chi2)

    def _used_peaks(self) -> np.ndarray:
        """The peaks (thrust two standard deviations below its value) of the horizon's used samples."""
        return self._peak[self._D[:, _RM] > 0]

    def _count_loaded(self, level: float, peaks: np.ndarray | None = None) -> int:
        """Used samples of the horizon loaded to ``level`` (their thrust two standard deviations below it).

        ``peaks``: :meth:`_used_peaks`, when the caller has them for the same data.
        """
        return int(np.count_nonzero((self._used_peaks() if peaks is None else peaks) >= level))

    def _window_threshold(self, n_plateau: int) -> float:
        """The horizon test's threshold on d2 for a horizon holding ``n_plateau`` samples on its plateau.

        ``detect_window_chi2`` from ``detect_window_plateau_samples`` plateau samples on, scaled up by
        ``detect_window_plateau_samples / n_plateau`` below (never passed without a plateau sample).
        """
        s = self.settings
        if not s.memory:
            return s.detect_window_chi2
        if n_plateau < 1:
            return math.inf
        return s.detect_window_chi2 * max(1.0, s.detect_window_plateau_samples / n_plateau)

    def _enough_informative(self, level: float, peaks: np.ndarray | None = None) -> bool:
        """Whether the horizon holds ``identify_min_informative`` used samples loaded to ``level`` (memory on)."""
        if not self.settings.memory:
            return True  # the window estimator of before has no such rule
        return self._count_loaded(level, peaks) >= self.settings.identify_min_informative

    # ------------------------------------------------------------------ memory
    def _remember(self, t: float, win: dict) -> tuple[float, tuple[float, float]] | None:
        """Fuse an informative horizon with its arrival cost; a contradiction gives ``(t_change, window)``."""
        H, s = self._held, self.settings
        t_start = max(t - s.window_s, self._t_reset)
        # a horizon is fused when it identifies F_max from enough loaded samples, K off its bounds (on a
        # bound its covariance describes the box, not the data, and F_max's variance is the one given K
        # there: measured, 174 +- 4 kN against a truth of 146 kN on a pull's plateau)
        informative = "max_thrust" in win["ident"] and not win["K_bound"]
        peaks = self._used_peaks() if informative else None  # the same data for both counts below
        if informative and self._enough_informative(s.identify_min_utilisation * win["F"], peaks):
            xw, Vw = (win["F"], win["K"]), win["V"]
            pr = self.turning.with_recent(H.prior(t_start, t), t_start)  # i42 hook: turns after t_start
            # tested only where the horizon reaches its plateau (else its F_max is an extrapolation along the
            # ridge that the sandwich does not describe: the uniform-soil false alarms); fused if it agrees
            n_plateau = self._count_loaded(s.detect_window_min_load * xw[0], peaks)
            near = not s.memory or n_plateau >= s.identify_min_informative
            if pr is None:
                H.set(t, xw, Vw)
            else:
                res = fuse(pr[0], pr[1], xw, Vw)
                settled = t - self._known_since >= s.detect_settle_s
                if res is not None and res[2] > self._window_threshold(n_plateau) and settled:
                    first = next((x for x in self._info_times if x >= t_start), t)
                    t_change = self._detector.run_start(first)
                    window = self._change_window(t_change)
                    t_ex = self._excitation_start(t_change, window[0])
                    revealed = bool(self.changes) and t_ex <= self.changes[-1]["window_s"][1] + EXCITATION_GAP_S
                    if revealed or self._excitations_before(t_start) < s.detect_min_excitations:
                        # the excitation that revealed the last change (its first estimate of the new soil
                        # was held too early), or a held estimate resting on a single excitation (one
                        # operating point of the curve: F_max an extrapolation along the ridge whose sandwich
                        # covariance understates it): not a change; start the held estimate again
                        H.reset()
                        H.set(t, xw, Vw)
                        H.snapshot(t, t - s.window_s)
                        return None
                    return t_change, window
                if res is not None and (res[2] <= s.detect_window_chi2 or (near and not settled)):
                    H.set(t, res[0], res[1])
        if H.known:
            assert H.x is not None  # known: an estimate is held
            if self._informed_at is None:  # the horizon that first identified F_max: its latest loaded sample
                self._informed_at = next((x for x in reversed(self._info_times) if x >= t_start), t)
            self._F_known = H.x[0]
            if self._known_since == math.inf:
                self._known_since = t
            self._P[_P["xF_prior"]] = H.x[0] / self._F_ref
        H.snapshot(t, t - s.window_s)
        return None

    def _excitations_before(self, t_start: float) -> int:
        """Excitations before ``t_start``: runs of informative samples (gaps below :data:`EXCITATION_GAP_S`)
        holding at least ``identify_min_informative`` of them (the fusion rule's count; a lone sample is none).

        What the arrival cost of a horizon starting at ``t_start`` rests on (since the last change).
        """
        need = self.settings.identify_min_informative
        n, last, run = 0, -math.inf, 0
        for x in self._info_times:
            if x >= t_start:
                break
            if x - last > EXCITATION_GAP_S:
                n += run >= need
                run = 0
            run += 1
            last = x
        return n + (run >= need)

    def _held_residual(self, t: float, z: float) -> float:
        """The new sample's standardised residual against the held estimate (``z`` unchanged without one)."""
        now = self._held.now(t)
        if now is None:
            return z
        (F, K), (p11, p12, p22) = now
        fr, kr = self._F_ref, self._K_ref
        Ph = self._Ph
        Ph[:] = self._P
        Ph[_PXF], Ph[_PXK] = F / fr, K / kr
        self._Vh[:] = (p11 / (fr * fr), p12 / (fr * kr), p22 / (kr * kr))
        self._c_predict_held()
        wres, var = float(self._held_out[1]), max(float(self._held_out[2]), 0.0)
        sc = self._scale()
        return wres / math.sqrt(sc * sc + self.settings.detect_held_sigmas**2 * var)

    def _note_informative(self, t: float, T: float, sT: float) -> None:
        """Keep the time of a sample loaded enough to inform F_max (relative to what is known)."""
        ref = self._held.x[0] if self._held.x is not None else (self._F_known or float(self._P[_PXF] * self._F_ref))
        if T >= self.settings.detect_min_load * ref:
            self._loaded_times.append(t)
        if T - 2.0 * sT >= self.settings.identify_min_utilisation * ref:
            self._informed_at = t
            self._info_times.append(t)

    def _excitation_start(self, t_seen: float, earliest: float) -> float:
        """Start of the excitation in which a change was seen at ``t_seen``: the date of the change.

        The first sample of that excitation loaded to ``detect_min_load`` of F_max (samples closer
        than :data:`EXCITATION_GAP_S`), never before ``earliest`` (the last informative sample on
        the old soil). The horizon restarts there: the excitation's first samples are on the new
        soil too (when the change came between two excitations), and without them the new horizon
        can hold one operating point of the curve only (F_max and K on a ridge; measured: 174 +- 4
        kN against a truth of 146 kN after a restart on a pull's plateau).
        """
        block = t_seen
        for x in reversed(self._loaded_times):
            if x >= t_seen:
                continue
            if block - x > EXCITATION_GAP_S:
                break
            block = x
        return max(block, min(earliest, t_seen))

    def _change_window(self, latest: float) -> tuple[float, float]:
        """``(earliest, latest)`` of a change first seen at ``latest``.

        ``earliest`` is the last informative sample before the excitation (the run of informative
        samples, gaps below :data:`EXCITATION_GAP_S`) in which the change was seen: that
        excitation's first samples may already have been on the new soil without leaning enough.
        """
        earliest = None
        block = latest
        for x in reversed(self._info_times):
            if x >= latest:
                continue
            if block - x <= EXCITATION_GAP_S:
                block = x
                continue
            earliest = x
            break
        if earliest is None:
            earliest = self._t_reset if math.isfinite(self._t_reset) else self._t_first
        return float(min(earliest, latest)), float(latest)

    def _held_fields(self, t: float, win: dict) -> dict:
        """The reported values: the held estimate grown to ``t`` (the window's values before anything is held)."""
        now = self._held.now(t)
        if now is None:
            return dict(win, held=False)
        (F, K), (p11, p12, p22) = now
        l = self.vehicle.track_length
        slope = F * l / (2 * K)
        sF_, sK_ = math.sqrt(p11), math.sqrt(p22)
        g1, g2 = l / (2 * K), -F * l / (2 * K * K)
        s_slope = math.sqrt(max(g1 * g1 * p11 + 2 * g1 * g2 * p12 + g2 * g2 * p22, 0.0))
        ident: tuple[str, ...] = ("slope",) if s_slope < GENTLE_REL_STDERR * slope else ()
        sF = sK = cov = None
        if sF_ / F < GENTLE_REL_STDERR:
            # the held covariance is given with F_max (K's variance in it large while K is not
            # identified): traversability between excitations propagates both
            ident, sF, cov = ("slope", "max_thrust"), sF_, np.array([[p11, p12], [p12, p22]])
            if sK_ / K <= K_REL_STDERR:
                ident, sK = ("slope", "max_thrust", "shear_modulus"), sK_
        held = "max_thrust" not in win["ident"]
        return dict(F=F, K=K, slope=slope, held=held, s_slope=s_slope, sF=sF, sK=sK, cov=cov, ident=ident)

    def _report(self, t: float, slip, change: bool, t_change, status, message, win=None, window=None) -> OnlineEstimate:
        self._last_time = t
        if win is None:
            win = self._window(t)
        n_used, have = win["n_used"], win["have"]
        v = self._held_fields(t, win) if self.settings.memory else dict(win, held=False)
        ident = v["ident"]
        if status is None:
            status = (
                "ok" if (have and self._converged) else ("not_converged" if (have or n_used >= 3) else "warming_up")
            )
        if not message:
            message = _MESSAGES.get(status, status)
            if change:
                message = f"change of terrain detected, dated {t_change:.6g} s: older samples forgotten"
            elif v["held"] and ident and self._informed_at is not None:
                message = f"held estimate (last informed at {self._informed_at:.6g} s), covariance grown since"
        est = OnlineEstimate.from_fields(
            {
                "time_s": float(t),
                "max_thrust_N": v["F"],
                "max_thrust_stderr_N": v["sF"],
                "shear_modulus_m": v["K"],
                "shear_modulus_stderr_m": v["sK"],
                "covariance": v["cov"],
                "slope_N": v["slope"],
                "slope_stderr_N": v["s_slope"],
                "normal_load_N": self._normal_load,
                "grade_rad": self._grade,
                "identifiable": ident,
                "not_identifiable": _NOT_IDENTIFIED[ident],
                "slip": None if slip is None else float(slip),
                "change_detected": bool(change),
                "change_time_s": None if t_change is None else float(t_change),
                "samples_used": n_used,
                "samples_skipped": self.samples_skipped,
                "samples_turning": self.samples_turning,
                "samples_seen": self.samples_seen,
                # the held estimate is a definite value (fused at a converged horizon, then carried)
                "converged": bool(self._converged and have) or bool(self._held.known and "max_thrust" in ident),
                "status": status,
                "message": message,
                "detector": self._detector.statistic,
                "informed_at_s": self._informed_at if self._held.known else None,
                "change_window_s": None if window is None else (float(window[0]), float(window[1])),
                "held": bool(v["held"]),
            }
        )
        self._last = est
        return est


def _peak(row: np.ndarray) -> float:
    """A data column's thrust two standard deviations below its value (-inf without a weight)."""
    isc = float(row[_RISC])
    return float(row[_RT]) - 2.0 / isc if isc > 0 else -math.inf


def _finite(x) -> bool:
    try:
        return x is not None and math.isfinite(float(x))
    except (TypeError, ValueError):
        return False
