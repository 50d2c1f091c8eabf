"""Two-track drive logs with turns: the container, its CSV reader, and the turning simulator.

:class:`TwoTrackLog` keeps each track's channels (what :func:`~.data.read_csv` sums and averages
for the straight-line model). :func:`simulate_turning_log` drives the steering model
(:mod:`.steering`) along a prescribed motion: a forward-speed profile and turns of given radius
(``turns``: ``(t0, t1, radius_m)``, radius signed, positive to the left), the curvature ramped in
and out over ``ramp_s`` by a C1 cosine step. At every sample the plant is solved quasi-statically
(:func:`~.steering.motion_inverse_function`: the sprocket speeds and lateral speed that give the
hull its forward acceleration, centripetal force and yaw acceleration; the lateral speed's own rate
is neglected), the sprocket torques are ``r F_x,k + (I/2) dw_k/dt``. Sensor noise as
:class:`~.simulation.SensorNoise` (per track: the torque's full scale is half the drivetrain's
limit), the yaw rate with :data:`GYRO_NOISE` (none when all the other channels are noise-free).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any, Sequence

import casadi as ca
import numpy as np

from .csvread import read_columns, read_header
import csv

from .csvread import bad_rows_error
from .errors import DataError
from .simulation import add_noise, cruise_speed, drive_limits, sensor_noise
from .soil import Soil
from .steering import SteeringSettings, hull_forces_function, motion_inverse_function, vehicle_parameters
from .threadsafe import call_solver, locked_cache
from .tracks import TWO_TRACK_COLUMNS, YAW_COLUMN, turning_mask
from .vehicle import Vehicle

__all__ = [
    "TwoTrackLog",
    "Turn",
    "parse_turns",
    "read_two_track",
    "two_track_log_from_columns",
    "simulate_turning_log",
    "GYRO_NOISE",
]

#: Yaw-rate noise of the simulated gyroscope, rad/s (a MEMS gyro at 50 Hz).
GYRO_NOISE = 0.005
#: Optional lateral-speed column of a two-track log, m/s.
LATERAL_COLUMN = "lateral_speed_m_s"


@dataclass(frozen=True, eq=False)
class TwoTrackLog:
    """A drive log with each track's torque and sprocket speed (SI), optional yaw rate.

    Attributes
    ----------
    time, torque_left, torque_right, speed_left, speed_right, vehicle_speed
        ``time_s``, the four two-track columns, ``vehicle_speed_m_s`` (forward speed).
    yaw_rate
        ``yaw_rate_rad_s`` (+ left), or ``None``.
    vehicle_accel, lateral_speed
        ``vehicle_accel_m_s2``, ``lateral_speed_m_s``, or ``None``.
    source
        Where the data came from.
    """

    time: np.ndarray
    torque_left: np.ndarray
    torque_right: np.ndarray
    speed_left: np.ndarray
    speed_right: np.ndarray
    vehicle_speed: np.ndarray
    yaw_rate: np.ndarray | None = None
    vehicle_accel: np.ndarray | None = None
    lateral_speed: np.ndarray | None = None
    source: str = "<memory>"

    def __post_init__(self) -> None:
        for name in (
            "time",
            "torque_left",
            "torque_right",
            "speed_left",
            "speed_right",
            "vehicle_speed",
            "yaw_rate",
            "vehicle_accel",
            "lateral_speed",
        ):
            if getattr(self, name) is not None:
                arr = np.array(getattr(self, name), dtype=float).reshape(-1)
                arr.setflags(write=False)
                object.__setattr__(self, name, arr)
        cols = self.columns()
        sizes = {k: v.size for k, v in cols.items()}
        if len(set(sizes.values())) > 1:
            raise DataError(f"columns differ in length: {sizes}", file=self.source)
        for name, values in cols.items():
            bad = ~np.isfinite(values)
            if bad.any():
                raise bad_rows_error(bad, self.source, name, f"value {values[np.argmax(bad)]} is not a finite number")
        step = np.zeros(self.time.shape, dtype=bool)
        step[1:] = np.diff(self.time) <= 0
        if step.any():
            raise bad_rows_error(step, self.source, "time_s", "time must be strictly increasing")

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.time.size)

    def columns(self) -> dict[str, np.ndarray]:
        """The log as ``{column: values}`` in the CSV contract's names (given columns only)."""
        out = {"time_s": self.time}
        out.update(zip(TWO_TRACK_COLUMNS, (self.torque_left, self.torque_right, self.speed_left, self.speed_right)))
        out["vehicle_speed_m_s"] = self.vehicle_speed
        for name, col in (
            ("vehicle_accel", "vehicle_accel_m_s2"),
            ("yaw_rate", YAW_COLUMN),
            ("lateral_speed", LATERAL_COLUMN),
        ):
            if getattr(self, name) is not None:
                out[col] = getattr(self, name)
        return out

    def turning(self) -> np.ndarray:
        """The samples where the vehicle turns (:func:`~.tracks.turning_mask`)."""
        return turning_mask(self.speed_left, self.speed_right, self.yaw_rate)

    def write_csv(self, path) -> None:
        """Write the log as CSV (a path or an open text stream)."""
        if hasattr(path, "write"):
            self._write(path)
            return
        with open(os.fspath(path), "w", newline="", encoding="utf-8") as fh:
            self._write(fh)

    def _write(self, fh) -> None:
        cols = self.columns()
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(list(cols))
        for row in zip(*cols.values()):
            w.writerow([repr(float(v)) for v in row])


def read_two_track(path: str | os.PathLike, *, max_rows: int | None = None) -> TwoTrackLog:
    """Read a two-track drive log keeping each track's channels (DataError naming file and column)."""
    path = os.fspath(path)
    header = read_header(path)
    required = ("time_s", *TWO_TRACK_COLUMNS, "vehicle_speed_m_s")
    for col in required:
        if col not in header:
            raise DataError(f"missing column of a two-track drive log (header has {header})", file=path, column=col)
    optional = [c for c in ("vehicle_accel_m_s2", YAW_COLUMN, LATERAL_COLUMN) if c in header]
    d = read_columns(path, header, [*required, *optional], max_rows)
    return two_track_log_from_columns(d, source=path)


def two_track_log_from_columns(d: dict, *, source: str) -> TwoTrackLog:
    """A :class:`TwoTrackLog` from columns named as in a CSV (a CSV's or a bag's, read and checked)."""
    return TwoTrackLog(
        time=d["time_s"],
        torque_left=d[TWO_TRACK_COLUMNS[0]],
        torque_right=d[TWO_TRACK_COLUMNS[1]],
        speed_left=d[TWO_TRACK_COLUMNS[2]],
        speed_right=d[TWO_TRACK_COLUMNS[3]],
        vehicle_speed=d["vehicle_speed_m_s"],
        yaw_rate=d.get(YAW_COLUMN),
        vehicle_accel=d.get("vehicle_accel_m_s2"),
        lateral_speed=d.get(LATERAL_COLUMN),
        source=source,
    )


@dataclass(frozen=True)
class Turn:
    """A turn from ``start_s`` to ``end_s`` of radius ``radius_m`` (signed: + left)."""

    start_s: float
    end_s: float
    radius_m: float


def parse_turns(spec: str | Sequence, *, tread: float | None, duration_s: float, what: str = "--turns") -> tuple:
    """Turns from ``"T0:T1:R[,...]"`` (or ``(t0, t1, r)`` triples), checked; DataError naming ``what``.

    Refused: a malformed item, T1 <= T0, a turn outside ``[0, duration_s]`` or overlapping another,
    a radius that is zero, not finite or not larger than half the tread (a sprocket would have to
    stop or reverse: pivot turns are outside the model).
    """
    if tread is None:
        raise DataError(
            f"{what} needs the vehicle's tread_m (distance between the track centre lines)", column="tread_m"
        )
    items = [s for s in spec.split(",") if s.strip()] if isinstance(spec, str) else list(spec)
    if not items:
        raise DataError(f"{what}: no turn given")
    turns = []
    for item in items:
        try:
            t0, t1, r = (float(x) for x in (item.split(":") if isinstance(item, str) else item))
        except (TypeError, ValueError):
            raise DataError(f"{what}: {item!r} is not T0:T1:RADIUS_M (seconds, seconds, metres)") from None
        if not all(math.isfinite(x) for x in (t0, t1, r)) or not 0 <= t0 < t1 <= duration_s:
            raise DataError(f"{what}: {item!r} needs 0 <= T0 < T1 <= {duration_s:g} s (the log's duration)")
        if abs(r) <= 0.5 * tread:
            raise DataError(
                f"{what}: radius {r:g} m is not larger than half the tread ({0.5 * tread:g} m): the inner "
                "sprocket would stop or reverse (pivot turns are outside the model)"
            )
        turns.append(Turn(t0, t1, r))
    turns.sort(key=lambda t: t.start_s)
    for a, b in zip(turns, turns[1:]):
        if b.start_s < a.end_s:
            raise DataError(f"{what}: turns {a.start_s:g}-{a.end_s:g} s and {b.start_s:g}-{b.end_s:g} s overlap")
    return tuple(turns)


def _smooth_step(t: np.ndarray, t0: float, ramp: float) -> tuple[np.ndarray, np.ndarray]:
    """C1 cosine step from 0 (t <= t0) to 1 (t >= t0 + ramp) and its time derivative."""
    s = np.clip((t - t0) / ramp, 0.0, 1.0)
    inside = (s > 0) & (s < 1)
    return 0.5 - 0.5 * np.cos(np.pi * s), np.where(inside, 0.5 * np.pi / ramp * np.sin(np.pi * s), 0.0)


def _curvature(t: np.ndarray, turns: tuple, ramp_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Path curvature kappa(t) (1/m, + left) and its rate: each turn ramped in and out over ``ramp_s``."""
    k, dk = np.zeros_like(t), np.zeros_like(t)
    for tr in turns:
        ramp = min(ramp_s, 0.5 * (tr.end_s - tr.start_s))
        up, dup = _smooth_step(t, tr.start_s, ramp)
        down, ddown = _smooth_step(t, tr.end_s - ramp, ramp)
        k += (up - down) / tr.radius_m
        dk += (dup - ddown) / tr.radius_m
    return k, dk


def default_turn_speed(
    vehicle: Vehicle, t: np.ndarray, duration_s: float, cruise_m_s: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Forward speed u(t) and du/dt of the default profile: 0.3 v_c -> v_c in the first 10 %,
    a +30 % speed change at 45-60 %, v_c = ``cruise_m_s`` or :func:`~.simulation.cruise_speed`
    capped at 2 m/s."""
    vc = min(2.0, cruise_speed(vehicle)) if cruise_m_s is None else float(cruise_m_s)
    T = duration_s
    s1, d1 = _smooth_step(t, 0.0, 0.1 * T)
    s2, d2 = _smooth_step(t, 0.45 * T, 0.05 * T)
    s3, d3 = _smooth_step(t, 0.55 * T, 0.05 * T)
    u = vc * (0.3 + 0.7 * s1 + 0.3 * (s2 - s3))
    du = vc * (0.7 * d1 + 0.3 * (d2 - d3))
    return u, du


@locked_cache(maxsize=16)
def _plant_chain(settings: SteeringSettings, n: int) -> ca.Function:
    """The quasi-static plant over n samples, each solve started from the previous sample's solution."""
    rf = motion_inverse_function(settings)
    z = ca.MX.sym("z", 3)
    p = ca.MX.sym("p", rf.size1_in(1))
    u, Om, B, r = p[0], p[1], p[7 + 3], p[7 + 4]
    kin = ca.vertcat((u - Om * B / 2) / (0.97 * r), (u + Om * B / 2) / (0.97 * r), 0.0)
    ok = ca.logic_and(ca.fabs(z[0]) < 1e6, ca.logic_and(ca.fabs(z[1]) < 1e6, ca.fabs(z[2]) < 1e6))  # NaN: False
    return ca.Function("plant_step", [z, p], [rf(ca.if_else(ok, z, kin), p)]).mapaccum("plant_chain", n)


def _solve_plant(vehicle, soil, settings, u, du, Om, dOm):
    """Sprocket speeds, lateral speed, track forces and loads at every sample; the samples not solved."""
    n = u.size
    veh = vehicle_parameters(vehicle)
    r = vehicle.sprocket_radius
    sv = np.reshape([soil.cohesion, soil.friction_angle, soil.shear_modulus], (3, 1))
    P = np.vstack([u, Om, du, dOm, np.tile(sv, n), np.tile(veh.reshape(-1, 1), n)])
    Z, _ = call_solver(_plant_chain(settings, n), [u[0] / (0.97 * r)] * 2 + [0.0], P)
    Z = np.asarray(Z, dtype=float).reshape(3, n)
    hf = hull_forces_function(settings).map(n)
    Fx, net, W = (
        np.asarray(a, dtype=float)
        for a in hf(np.vstack([u, Z[2], Om]), Z[:2], np.tile(sv, n), u * Om, np.tile(veh.reshape(-1, 1), n))
    )
    m, Iz, Wt = vehicle.mass, veh[7], vehicle.weight
    err = np.vstack(
        [
            (net[0] - m * (du - Z[2] * Om)) / Wt,
            (net[1] - m * u * Om) / Wt,
            (net[2] - Iz * dOm) / (Wt * vehicle.track_length),
        ]
    )
    with np.errstate(invalid="ignore"):
        bad = ~np.all(np.isfinite(Z), axis=0) | ~(np.max(np.abs(err), axis=0) <= 1e-7)
        bad |= np.any(Z[:2] <= 0, axis=0) | np.any(W <= 0, axis=0)
    return Z, Fx, W, bad


def simulate_turning_log(
    vehicle: Vehicle,
    soil: Soil,
    *,
    turns: Any = (),
    seed: int | None = None,
    noise: Any = "default",
    duration_s: float = 60.0,
    sample_rate_hz: float = 50.0,
    ramp_s: float = 1.0,
    cruise_m_s: float | None = None,
    settings: SteeringSettings = SteeringSettings(),
    return_truth: bool = False,
):
    """Simulate a two-track drive log with turns (see the module docstring).

    Parameters
    ----------
    vehicle, soil
        The vehicle (needs ``tread``) and the true soil.
    turns
        ``"T0:T1:R,..."`` or ``(t0, t1, radius_m)`` triples (:func:`parse_turns`).
    seed, noise
        Noise generator seed; ``"default"``, ``"none"`` or a :class:`~.simulation.SensorNoise`.
    duration_s, sample_rate_hz
        Length and rate of the log.
    ramp_s
        Time over which a turn's curvature ramps in and out, s.
    cruise_m_s
        Cruise speed of the speed profile (:func:`default_turn_speed`), m/s; default
        min(2, :func:`~.simulation.cruise_speed`).
    settings
        Quadrature of the steering model.
    return_truth
        Also return ``{"time", "u", "v", "yaw_rate", "w_left", "w_right", "torque_left",
        "torque_right", "load_left", "load_right", "curvature", "limits"}``.

    Raises
    ------
    DataError
        Bad turns, a vehicle without tread, or a motion the soil cannot give (the samples named).
    """
    nz = sensor_noise(noise)
    checks = [("duration_s", duration_s), ("sample_rate_hz", sample_rate_hz), ("ramp_s", ramp_s)]
    for name, val in checks + ([("cruise_m_s", cruise_m_s)] if cruise_m_s is not None else []):
        if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val) or val <= 0:
            raise DataError(f"{name} must be a finite number > 0, got {val!r}")
    tr = parse_turns(turns, tread=vehicle.tread, duration_s=duration_s, what="turns") if turns else ()
    vehicle_parameters(vehicle)  # tread checked
    h = 1.0 / sample_rate_hz
    n = int(round(duration_s * sample_rate_hz)) + 1
    t = np.arange(n) * h
    u, du = default_turn_speed(vehicle, t, duration_s, cruise_m_s)
    kappa, dkappa = _curvature(t, tr, ramp_s)
    Om, dOm = u * kappa, du * kappa + u * dkappa
    Z, Fx, W, bad = _solve_plant(vehicle, soil, settings, u, du, Om, dOm)
    if bad.any():
        k = np.nonzero(bad)[0]
        raise DataError(
            f"the soil ({soil.name or 'given soil'}) cannot give this motion at {k.size} of {n} samples "
            f"(first at t = {t[k[0]]:g} s, curvature {kappa[k[0]]:.4g} 1/m at {u[k[0]]:.3g} m/s): a turn too "
            "tight for the soil, or a track would have to stop or tip"
        )
    wl, wr = Z[0], Z[1]
    I_half = 0.5 * vehicle.sprocket_inertia
    r = vehicle.sprocket_radius
    Tl = r * Fx[0] + I_half * np.gradient(wl, t)
    Tr = r * Fx[1] + I_half * np.gradient(wr, t)
    limits = drive_limits(vehicle)
    rng = np.random.default_rng(seed)
    fs = nz.torque_fs * 0.5 * limits.max_sprocket_torque
    log = TwoTrackLog(
        time=t,
        torque_left=add_noise(rng, Tl, fs, nz.torque_rel),
        torque_right=add_noise(rng, Tr, fs, nz.torque_rel),
        speed_left=add_noise(rng, wl, nz.encoder_abs, nz.encoder_rel),
        speed_right=add_noise(rng, wr, nz.encoder_abs, nz.encoder_rel),
        vehicle_speed=add_noise(rng, u, nz.gnss_speed, 0.0),
        yaw_rate=add_noise(rng, Om, GYRO_NOISE if any(vars(nz).values()) else 0.0, 0.0),
        source=f"simulated two-track log ({vehicle.name or 'vehicle'}, {soil.name or 'soil'}, {len(tr)} turns)",
    )
    if not return_truth:
        return log
    truth = {
        "time": t,
        "u": u,
        "v": Z[2],
        "yaw_rate": Om,
        "w_left": wl,
        "w_right": wr,
        "torque_left": Tl,
        "torque_right": Tr,
        "load_left": W[0],
        "load_right": W[1],
        "curvature": kappa,
        "limits": limits,
    }
    return log, truth
