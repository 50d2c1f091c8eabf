"""Simulated measurements: straight-line drive logs and drawbar-pull slip sweeps.

Drive logs (:func:`simulate_drive_log`)
    The dynamics of :mod:`.dynamics` (Eqs. 1, 3/thrust balance, 4, with any effects on) are
    integrated by CVODES (implicit BDF, adaptive: slip settles in milliseconds at low speed)
    over one sample interval at a time, under a speed-reference PI controller whose torque is
    held constant over the interval (zero-order hold) and limited by the drivetrain's torque
    and power limits. The whole closed loop is one CasADi Function (``mapaccum`` of the
    controller and the integrator), built once and cached. Sensor noise is added afterwards;
    the controller acts on the noise-free speed.

Slip sweeps (:func:`simulate_slip_sweep`)
    A drawbar-pull rig at steady state: for each set slip and normal load, the tractive force.
    What the rig reports as tractive force is the measured drawbar pull plus the NOMINAL motion
    resistance ``W mu_r`` (the usual conversion), so resistance effects show as lost force:
    ``F_reported = F(i) - (R_actual - W mu_r)``; the slip is computed with the nominal radius
    (``radius_error`` offsets it); drivetrain friction does not enter (the force is measured by
    the drawbar load cell, not from the torque).

Noise (:class:`SensorNoise`) is white and Gaussian per channel, standard deviation
``sqrt(abs^2 + (rel * |signal|)^2)``, reproducible through ``seed``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Callable, Sequence

import casadi as ca
import numpy as np

from .threadsafe import call_solver, locked_cache
from .data import DriveLog, SlipData
from .dynamics import check_sprocket_equation, dynamics_function, slip_expr
from .effects import (
    DEFAULT_RIG_SPEED,
    DEFAULT_STANDSTILL_SPEED,
    SWEEP_MEASURES,
    EffectSet,
    EffectValues,
    parse_effects,
    smooth_sign,
    sweep_measurement,
)
from .errors import DataError
from .sinkage import has_bekker, slip_sinkage, static_sinkage
from .soil import Soil
from .traction import check_model
from .vehicle import Vehicle

__all__ = [
    "SensorNoise",
    "DriveLimits",
    "drive_limits",
    "default_speed_profile",
    "simulate",
    "simulate_drive_log",
    "simulate_slip_sweep",
    "DEFAULT_SLIPS",
    "cruise_speed",
    "hard_acceleration",
]

#: Power-to-mass ratio assumed when a vehicle gives no power limit, W/kg (typical of tracked
#: vehicles: 15 W/kg gives 500 kW for the 33.5 t heavy vehicle, 460 W for the 30.6 kg light one).
DEFAULT_POWER_PER_MASS = 15.0
#: Thrust-to-weight ratio of the torque limit assumed when a vehicle gives none (T = 0.8 W r).
DEFAULT_TORQUE_THRUST_RATIO = 0.8
#: Default set slips of a sweep (measured slip, as the rig computes it with the nominal radius).
DEFAULT_SLIPS = tuple(
    float(s) for s in np.round(np.concatenate([np.linspace(0.01, 0.1, 10), np.linspace(0.15, 0.7, 12)]), 6)
)


@dataclass(frozen=True)
class SensorNoise:
    """Standard deviations of white Gaussian sensor noise, per channel.

    Each channel's standard deviation is ``sqrt(abs^2 + (rel * |signal|)^2)``. The defaults are
    realistic for a field vehicle:

    Attributes
    ----------
    encoder_rel, encoder_abs
        Sprocket speed: 0.5 % and 0.01 rad/s (incremental encoder differentiated at 50 Hz).
    gnss_speed
        Vehicle speed: 0.05 m/s (RTK/Doppler GNSS speed).
    imu_accel
        Vehicle acceleration: 0.05 m/s^2 (MEMS IMU, gravity-compensated: the channel is dv/dt).
    torque_rel, torque_fs
        Sprocket torque: 1 % of reading and 0.1 % of the drivetrain's torque limit (full scale).
    force_rel, force_abs
        Sweep tractive force: 1 % of reading and 0 N.
    slip_abs
        Sweep slip: 0.002 (absolute).
    sinkage_rel, sinkage_abs
        Sweep sinkage (``sinkage_m``, when simulated): 3 % of reading (the rut's unevenness
        under a sinkage gauge) and 0 m.
    """

    encoder_rel: float = 0.005
    encoder_abs: float = 0.01
    gnss_speed: float = 0.05
    imu_accel: float = 0.05
    torque_rel: float = 0.01
    torque_fs: float = 0.001
    force_rel: float = 0.01
    force_abs: float = 0.0
    slip_abs: float = 0.002
    sinkage_rel: float = 0.03
    sinkage_abs: float = 0.0

    def __post_init__(self) -> None:
        for k, v in self.__dict__.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise DataError(f"SensorNoise.{k} must be a finite number >= 0, got {v!r}")

    @classmethod
    def none(cls) -> "SensorNoise":
        """All channels noise-free."""
        return cls(**{k: 0.0 for k in cls.__dataclass_fields__})


def _noise(noise: Any) -> SensorNoise:
    if isinstance(noise, SensorNoise):
        return noise
    if noise is None or noise == "none":
        return SensorNoise.none()
    if noise == "default":
        return SensorNoise()
    raise DataError(f"noise must be 'default', 'none' or a SensorNoise, got {noise!r}")


def _std(rng: np.random.Generator, x: np.ndarray, abs_: float, rel: float) -> np.ndarray:
    sd = np.sqrt(abs_**2 + (rel * np.abs(x)) ** 2)
    return x + sd * rng.standard_normal(x.shape)


def sensor_noise(noise: Any) -> SensorNoise:
    """``"default"``, ``"none"`` (or None) or a :class:`SensorNoise` -> that :class:`SensorNoise` (else DataError)."""
    return _noise(noise)


def add_noise(rng: np.random.Generator, x: np.ndarray, abs_: float, rel: float) -> np.ndarray:
    """``x`` plus white Gaussian noise of standard deviation ``sqrt(abs_^2 + (rel |x|)^2)`` per sample."""
    return _std(rng, x, abs_, rel)


@dataclass(frozen=True)
class DriveLimits:
    """Drivetrain limits used by the simulator's controller (both tracks).

    ``assumed`` is True where the vehicle gave no value and the library's default was used:
    torque ``0.8 W r`` (thrust 0.8 W), power 15 W/kg.
    """

    max_sprocket_torque: float
    max_power: float
    torque_assumed: bool
    power_assumed: bool


def drive_limits(vehicle: Vehicle) -> DriveLimits:
    """The vehicle's torque and power limits, or the documented defaults where it gives none."""
    t = vehicle.max_sprocket_torque
    p = vehicle.max_power
    return DriveLimits(
        float(t) if t else DEFAULT_TORQUE_THRUST_RATIO * vehicle.weight * vehicle.sprocket_radius,
        float(p) if p else DEFAULT_POWER_PER_MASS * vehicle.mass,
        not t,
        not p,
    )


def cruise_speed(vehicle: Vehicle) -> float:
    """Top speed of the default reference profile: ``min(3, 4 l)`` m/s (an arbitrary, moderate choice)."""
    return float(min(3.0, 4.0 * vehicle.track_length))


def hard_acceleration(vehicle: Vehicle) -> float:
    """Slope of the default profile's hard-acceleration ramps, m/s^2.

    1.5 times what the torque limit can give the rigid vehicle, ``T_max / (r (m + I/r^2))``:
    the controller saturates at the torque (then power) limit for the whole ramp, so the thrust
    is as high as the drivetrain allows - near the soil's traction limit whenever
    ``T_max / r`` approaches ``A c + W tan(phi)``, beyond it (track spin) when it exceeds it.
    """
    lim = drive_limits(vehicle)
    r = vehicle.sprocket_radius
    m_eq = vehicle.mass + vehicle.sprocket_inertia / r**2
    return 1.5 * lim.max_sprocket_torque / (r * m_eq)


def default_speed_profile(vehicle: Vehicle, duration_s: float = 60.0) -> Callable[[np.ndarray], np.ndarray]:
    """Default speed reference ``v_ref(t)``, m/s: mostly gentle driving, two hard starts.

    With ``v_c`` = :func:`cruise_speed`, ``a`` = :func:`hard_acceleration` and ``T`` the
    duration (times as fractions of T):

    - 0-0.04: standstill; at 0.04: HARD start, ramp 0 -> v_c at ``a`` (the controller saturates
      at the torque, then power, limit: thrust near the traction limit); hold to 0.15;
    - 0.15-0.25: gentle slow-down to 0.5 v_c; 0.28-0.43: gentle +-4 % speed changes (three
      sine periods); 0.43-0.5: gentle stop; standstill to 0.55;
    - 0.55: second HARD start to v_c; hold to 0.65; 0.65-0.75: gentle slow-down to 0.3 v_c
      (coasting/braking: negative torque, skid); hold; 0.8-0.9: gentle ramp to 0.7 v_c; hold.

    On flat ground a pull near the traction limit accelerates the vehicle at about
    ``g (tan(phi) - mu_r)``, so it lasts only ``v_c / a`` (a fraction of a second for a light
    vehicle): the hard phases are a few to a few tens of samples at 50 Hz.
    """
    vc = cruise_speed(vehicle)
    T = float(duration_s)
    a = hard_acceleration(vehicle)
    kt_list = [
        0.0,
        0.04 * T,
        0.04 * T + vc / a,
        0.15 * T,
        0.25 * T,
        0.43 * T,
        0.5 * T,
        0.55 * T,
        0.55 * T + vc / a,
        0.65 * T,
        0.75 * T,
        0.8 * T,
        0.9 * T,
        T,
    ]
    kv = np.array([0.0, 0.0, 1.0, 1.0, 0.5, 0.5, 0.0, 0.0, 1.0, 1.0, 0.3, 0.3, 0.7, 0.7]) * vc
    kt = np.maximum.accumulate(np.array(kt_list))

    def profile(t):
        t = np.asarray(t, dtype=float)
        base = np.interp(t, kt, kv)
        wiggle = np.where(
            (t > 0.28 * T) & (t < 0.43 * T), 0.04 * vc * np.sin(2 * np.pi * (t - 0.28 * T) / (0.05 * T)), 0.0
        )
        return base + wiggle

    return profile


def _reference(vehicle: Vehicle, duration_s: float, t: np.ndarray, speed_profile: Any) -> np.ndarray:
    if speed_profile is None:
        vref = default_speed_profile(vehicle, duration_s)(t)
    elif callable(speed_profile):
        vref = np.asarray(speed_profile(t), dtype=float) * np.ones_like(t)
    else:
        knots = np.asarray(speed_profile, dtype=float)
        if knots.ndim != 2 or knots.shape[1] != 2 or knots.shape[0] < 1:
            raise DataError("speed_profile must be a callable v_ref(t) or a sequence of (time_s, speed_m_s) pairs")
        if np.any(np.diff(knots[:, 0]) < 0):
            raise DataError("speed_profile knots must have non-decreasing time")
        vref = np.interp(t, knots[:, 0], knots[:, 1])
    if vref.shape != t.shape or not np.all(np.isfinite(vref)):
        raise DataError("speed_profile must give one finite speed per time step")
    return vref


@locked_cache(maxsize=32)
def _closed_loop(
    vehicle: Vehicle,
    soil: Soil,
    effects: EffectSet,
    model: str,
    sprocket_equation: str,
    h: float,
    n_steps: int,
    limits: DriveLimits,
    bandwidth: float,
) -> ca.Function:
    """Closed-loop simulation over n_steps sample intervals: ZOH PI speed control + CVODES plant."""
    dyn = dynamics_function(vehicle, soil, effects, model=model, sprocket_equation=sprocket_equation)
    x = ca.MX.sym("x", 2)
    u = ca.MX.sym("u")
    plant = ca.integrator(
        "plant",
        "cvodes",
        {"x": x, "p": u, "ode": dyn(x, u)[0]},
        0.0,
        h,
        {"abstol": 1e-9, "reltol": 1e-8, "max_num_steps": 200000, "show_eval_warnings": False},
    )
    r, I = vehicle.sprocket_radius, vehicle.sprocket_inertia
    m_eq = vehicle.mass + I / r**2
    kp = 2.0 * bandwidth * m_eq  # N per m/s (critically damped on the rigid-body plant)
    ki = bandwidth**2 * m_eq  # N per m
    xa = ca.MX.sym("xa", 3)  # v, w, integral of the speed error
    ref = ca.MX.sym("ref", 2)  # v_ref, dv_ref/dt
    v, w, z = xa[0], xa[1], xa[2]
    err = ref[0] - v
    ff = vehicle.weight * vehicle.rolling_resistance * smooth_sign(ref[0], DEFAULT_STANDSTILL_SPEED) + m_eq * ref[1]
    m_uns = r * (ff + kp * err + ki * z)
    w_floor = 0.05 * limits.max_power / limits.max_sprocket_torque
    m_lim = ca.fmin(limits.max_sprocket_torque, limits.max_power / ca.fmax(ca.fabs(w), w_floor))
    m_cmd = ca.fmin(ca.fmax(m_uns, -m_lim), m_lim)
    saturated = ca.fabs(m_uns) > m_lim
    z_next = ca.if_else(ca.logic_and(saturated, err * m_uns > 0), z, z + h * err)  # conditional integration
    x_next = plant(x0=xa[:2], p=m_cmd)["xf"]
    step = ca.Function("step", [xa, ref], [ca.vertcat(x_next, z_next), m_cmd])
    return step.mapaccum("closed_loop", n_steps)


def simulate_drive_log(
    vehicle: Vehicle,
    soil: Soil,
    *,
    effects: Any = None,
    seed: int | None = None,
    noise: Any = "default",
    model: str = "full",
    duration_s: float = 60.0,
    sample_rate_hz: float = 50.0,
    speed_profile: Any = None,
    sprocket_equation: str = "thrust",
    controller_bandwidth: float = 1.0,
    with_accel: bool = True,
    return_truth: bool = False,
    soil_changes: Sequence[tuple[float, Soil]] = (),
):
    """Simulate a straight-line drive log (the columns of docs/data-formats.md).

    Parameters
    ----------
    vehicle, soil
        The NOMINAL vehicle and the true soil.
    effects
        Unmodelled effects present in the "real" run (anything :func:`~.effects.parse_effects`
        takes); default none.
    seed
        Seed of the noise generator (same seed, same log).
    noise
        ``"default"`` (:class:`SensorNoise` defaults), ``"none"`` or a :class:`SensorNoise`.
    model
        Thrust law of the truth: ``"full"`` or ``"cohesion-free"``.
    duration_s, sample_rate_hz
        Length and rate of the log; the controller runs at the sample rate (zero-order hold).
    speed_profile
        ``None`` (:func:`default_speed_profile`), a callable ``v_ref(t)`` on a time array, or a
        sequence of ``(time_s, speed_m_s)`` knots (piecewise linear).
    sprocket_equation
        ``"thrust"`` (default) or ``"seed"`` (see :func:`~.dynamics.dynamics_expr`).
    controller_bandwidth
        Closed-loop bandwidth of the PI speed controller, rad/s (critically damped). Torque and
        power limits from the vehicle, or assumed (:func:`drive_limits`, reported in the truth).
    with_accel
        Include the IMU acceleration channel.
    return_truth
        Also return the noise-free signals.
    soil_changes
        Changes of terrain while driving: ``[(time_s, soil), ...]`` in increasing time; from
        each time on (rounded to a sample) the vehicle drives on that soil, its state carried
        over. The truth then also holds ``soil_index`` per sample (0: ``soil``).

    Returns
    -------
    DriveLog, or (DriveLog, dict)
        The truth dict holds arrays ``time``, ``v``, ``w``, ``slip`` (true, effective radius),
        ``slip_apparent`` (with the nominal radius, as computed from the log), ``thrust``,
        ``resistance``, ``torque`` (at the sensor, constant over each interval from the sample
        on), ``torque_loss``, ``accel`` (dv/dt), ``dw_dt`` (right limit at the sample),
        ``v_ref``, and ``limits`` (:class:`DriveLimits`).
    """
    check_model(model)
    check_sprocket_equation(sprocket_equation)
    eff = parse_effects(effects)
    nz = _noise(noise)
    h, n = _sampling(duration_s, sample_rate_hz, controller_bandwidth)
    t = np.arange(n) * h
    vref = _reference(vehicle, duration_s, t, speed_profile)
    dvref = np.append(np.diff(vref) / h, 0.0)
    limits = drive_limits(vehicle)
    soils, starts = _soil_segments(soil, soil_changes, h, n)
    X, M = _integrate(
        vehicle, soils, starts, eff, model, sprocket_equation, h, limits, float(controller_bandwidth), vref, dvref
    )
    v, w = X[0], X[1]
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(w)) and np.all(np.isfinite(M))):
        raise DataError("simulation produced non-finite values (integration failed)")
    soil_index = np.zeros(n, dtype=int)
    for j, k0 in enumerate(starts[1:-1], start=1):
        soil_index[k0 + 1 :] = j  # sample k0 + 1 is the first reached on soil j
    xdot, slip, thrust, res, loss = _outputs(vehicle, soils, soil_index, eff, model, sprocket_equation, X, M)
    r_nom = vehicle.sprocket_radius
    slip_app = np.asarray(_slip_fn()(v.reshape(1, -1), w.reshape(1, -1), r_nom), dtype=float).ravel()
    truth = {
        "time": t,
        "v": v,
        "w": w,
        "slip": slip[0],
        "slip_apparent": slip_app,
        "thrust": thrust[0],
        "resistance": res[0],
        "torque": M,
        "torque_loss": loss[0],
        "accel": xdot[0],
        "dw_dt": xdot[1],
        "v_ref": vref,
        "limits": limits,
    }
    if soil_changes:
        truth["soil_index"] = soil_index
    rng = np.random.default_rng(seed)
    log = DriveLog(
        time=t,
        sprocket_torque=_std(rng, M, nz.torque_fs * limits.max_sprocket_torque, nz.torque_rel),
        sprocket_speed=_std(rng, w, nz.encoder_abs, nz.encoder_rel),
        vehicle_speed=_std(rng, v, nz.gnss_speed, 0.0),
        vehicle_accel=_std(rng, xdot[0], nz.imu_accel, 0.0) if with_accel else None,
        source=f"simulated drive log ({vehicle.name or 'vehicle'}, {soil.name or 'soil'}, effects: {eff})",
    )
    return (log, truth) if return_truth else log


def _sampling(duration_s, sample_rate_hz, controller_bandwidth) -> tuple[float, int]:
    """The sample interval and the number of samples; DataError naming a bad argument."""
    for name, val in (
        ("duration_s", duration_s),
        ("sample_rate_hz", sample_rate_hz),
        ("controller_bandwidth", controller_bandwidth),
    ):
        if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val) or val <= 0:
            raise DataError(f"{name} must be a finite number > 0, got {val!r}")
    h = 1.0 / float(sample_rate_hz)
    n = int(round(duration_s * sample_rate_hz)) + 1
    if n < 3:
        raise DataError(f"duration_s x sample_rate_hz gives {n} samples; need at least 3")
    return h, n


def _integrate(vehicle, soils, starts, eff, model, sprocket_equation, h, limits, bandwidth, vref, dvref):
    """The closed loop integrated over each soil's segment (CVODES): states ``X`` (3 x n) and torques ``M`` (n)."""
    X_parts, M_parts = [np.zeros((3, 1))], []
    for j, (k0, k1) in enumerate(zip(starts, starts[1:])):
        sim = _closed_loop(vehicle, soils[j], eff, model, sprocket_equation, h, k1 - k0, limits, bandwidth)
        try:
            (Xj, Mj), _ = call_solver(sim, X_parts[-1][:, -1], np.vstack([vref[k0:k1], dvref[k0:k1]]))
        except RuntimeError as exc:  # CVODES gave up (e.g. an absurd speed profile)
            raise DataError(
                f"simulation failed: the integrator did not converge ({str(exc).splitlines()[-1]})"
            ) from None
        X_parts.append(np.asarray(Xj).reshape(3, -1))
        M_parts.append(np.asarray(Mj).ravel())
    X = np.hstack(X_parts)
    M = np.append(np.concatenate(M_parts), 0.0)
    M[-1] = M[-2]  # the last sample's torque: held from the previous interval
    return X, M


def _outputs(vehicle, soils, soil_index, eff, model, sprocket_equation, X, M):
    """``(xdot, slip, thrust, resistance, torque loss)`` at every sample, on the soil under it."""
    n = soil_index.size
    xdot, slip, thrust, res, loss = (
        np.empty((2, n)),
        np.empty((1, n)),
        np.empty((1, n)),
        np.empty((1, n)),
        np.empty((1, n)),
    )
    for j, sj in enumerate(soils):
        sel = np.nonzero(soil_index == j)[0]
        if sel.size == 0:
            continue
        dyn = dynamics_function(vehicle, sj, eff, model=model, sprocket_equation=sprocket_equation)
        outs = [np.asarray(a, dtype=float).reshape(-1, sel.size) for a in dyn(X[:2, sel], M[sel].reshape(1, -1))]
        for arr, o in zip((xdot, slip, thrust, res, loss), outs):
            arr[:, sel] = o
    return xdot, slip, thrust, res, loss


def _soil_segments(soil: Soil, changes, h: float, n: int) -> tuple[list[Soil], list[int]]:
    """The soils in order and the sample index where each segment's integration starts (+ the end)."""
    soils, starts = [soil], [0]
    last_t = -math.inf
    for item in changes:
        try:
            t_c, s_c = item
        except (TypeError, ValueError):
            raise DataError(f"soil_changes must be (time_s, Soil) pairs, got {item!r}") from None
        if (
            not isinstance(s_c, Soil)
            or isinstance(t_c, bool)
            or not isinstance(t_c, (int, float))
            or not math.isfinite(t_c)
            or t_c <= last_t
        ):
            raise DataError(f"soil_changes must be (time_s, Soil) pairs in increasing time, got {item!r}")
        k = int(round(t_c / h))
        if not 0 < k < n - 1:
            raise DataError(f"soil change at {t_c:g} s is outside the log (0 to {(n - 1) * h:g} s)")
        soils.append(s_c)
        starts.append(k)
        last_t = t_c
    return soils, starts + [n - 1]


def simulate_slip_sweep(
    vehicle: Vehicle,
    soil: Soil,
    *,
    slips: Sequence[float] | None = None,
    normal_loads: Sequence[float] | None = None,
    effects: Any = None,
    seed: int | None = None,
    noise: Any = "default",
    model: str = "full",
    rig_speed: float = DEFAULT_RIG_SPEED,
    measure: str = "tractive_force",
    return_truth: bool = False,
    sinkage_slip_exponent: float | None = None,
):
    """Simulate a drawbar-pull slip sweep: tractive force at set slips and normal loads.

    Parameters
    ----------
    vehicle, soil
        Nominal vehicle (geometry, radius, mu_r) and the true soil.
    slips
        Set slips in [0, 1) as the rig measures them (nominal radius); default
        :data:`DEFAULT_SLIPS` (0.01 to 0.7).
    normal_loads
        Nominal normal loads, N; every slip is run at every load. Default: the vehicle's weight,
        and then the data carry no ``normal_load_N`` column. Two or more loads make c and phi
        separable.
    effects
        Effects of the real run. ``hump_shear``, ``pressure_distribution`` change F(i);
        ``mass_error``, ``grade`` change the actual load; ``radius_error`` offsets the measured
        slip; resistance effects reduce the reported force (see the module docstring);
        ``drivetrain_friction`` has no effect on a rig.
    seed, noise
        Noise generator seed; ``"default"``, ``"none"`` or :class:`SensorNoise` (``force_rel``,
        ``force_abs``, ``slip_abs``). Noisy slips are clipped into [0, 0.999].
    model
        ``"full"`` or ``"cohesion-free"``.
    rig_speed
        Track speed ``r w`` of the rig, m/s (sets the vehicle speed for speed resistance).
    measure
        ``"tractive_force"`` (default: drawbar pull plus the nominal resistance ``W mu_r``) or
        ``"drawbar_pull"`` (the pull itself, ``F - R``); see
        :func:`~soiltrack.soilmodel.effects.sweep_measurement`.
    return_truth
        Also return ``{"slip": measured-noise-free, "slip_true", "tractive_force", "thrust",
        "normal_load"}`` (and ``"sinkage"`` when simulated).
    sinkage_slip_exponent
        ``None`` (default): no sinkage channel. A number ``s``: the data carry ``sinkage_m``, the
        soil's static Bekker sinkage at each row's load times the slip-sinkage factor
        (:func:`~soilmodel.sinkage.slip_sinkage_expr`) at the true slip with exponent ``s``
        (1: Lyasko's law; 0: no slip sinkage), with the noise ``sinkage_rel``/``sinkage_abs``.
        Needs the soil's Bekker n, k_c, k_phi. Independent of the ``slip_sinkage`` effect, whose
        resistance the thrust sees.

    Returns
    -------
    SlipData, or (SlipData, dict)
    """
    check_model(model)
    eff = parse_effects(effects)
    nz = _noise(noise)
    s = np.asarray(DEFAULT_SLIPS if slips is None else slips, dtype=float).ravel()
    if s.size == 0 or not np.all(np.isfinite(s)) or np.any(s < 0) or np.any(s >= 1):
        raise DataError("slips must be finite values in [0, 1)")
    loads_given = normal_loads is not None
    loads = np.asarray([vehicle.weight] if normal_loads is None else normal_loads, dtype=float).ravel()
    if loads.size == 0 or not np.all(np.isfinite(loads)) or np.any(loads <= 0):
        raise DataError("normal_loads must be finite values > 0 N")
    if not (isinstance(rig_speed, (int, float)) and math.isfinite(rig_speed) and rig_speed > 0):
        raise DataError(f"rig_speed must be a finite number > 0, got {rig_speed!r}")
    if measure not in SWEEP_MEASURES:
        raise DataError(f"measure must be one of {SWEEP_MEASURES}, got {measure!r}")
    if sinkage_slip_exponent is not None:
        if not has_bekker(soil):
            raise DataError(
                "a simulated sinkage channel needs the soil's Bekker n, k_c and k_phi: use a terrain preset "
                "(--terrain) or give them (--bekker)"
            )
        if not (
            isinstance(sinkage_slip_exponent, (int, float))
            and not isinstance(sinkage_slip_exponent, bool)
            and math.isfinite(sinkage_slip_exponent)
        ):
            raise DataError(f"sinkage_slip_exponent must be a finite number, got {sinkage_slip_exponent!r}")
    S, Wn = (a.ravel() for a in np.meshgrid(s, loads, indexing="xy"))
    fn = _sweep_fn(vehicle, eff, model, measure)
    slip_true, thrust, reported = (
        np.asarray(a, dtype=float).ravel()
        for a in fn(
            S.reshape(1, -1), Wn.reshape(1, -1), soil.cohesion, soil.friction_angle, soil.shear_modulus, rig_speed
        )
    )
    rng = np.random.default_rng(seed)
    F_meas = _std(rng, reported, nz.force_abs, nz.force_rel)
    s_meas = np.clip(_std(rng, S, nz.slip_abs, 0.0), 0.0, 0.999)
    z_true = z_meas = None
    if sinkage_slip_exponent is not None:  # drawn after the other channels: their noise stays as without it
        z0 = np.asarray(static_sinkage(soil, vehicle, Wn), dtype=float)
        z_true = np.asarray(slip_sinkage(z0, slip_true, float(sinkage_slip_exponent)), dtype=float)
        z_meas = _std(rng, z_true, nz.sinkage_abs, nz.sinkage_rel)
    src = f"simulated slip sweep ({vehicle.name or 'vehicle'}, {soil.name or 'soil'}, effects: {eff})"
    W_col = Wn if loads_given else None
    if measure == "drawbar_pull":
        data = SlipData(slip=s_meas, normal_load=W_col, source=src, drawbar_pull=F_meas, sinkage=z_meas)
    else:
        data = SlipData(slip=s_meas, tractive_force=F_meas, normal_load=W_col, source=src, sinkage=z_meas)
    if return_truth:
        truth = {"slip": S, "slip_true": slip_true, measure: reported, "thrust": thrust, "normal_load": Wn}
        if z_true is not None:
            truth["sinkage"] = z_true
        return data, truth
    return data


@lru_cache(maxsize=1)
def _slip_fn() -> ca.Function:
    v, w, r = ca.SX.sym("v"), ca.SX.sym("w"), ca.SX.sym("r")
    return ca.Function("slip", [v, w, r], [slip_expr(v, w, r)])


@lru_cache(maxsize=64)
def _sweep_fn(vehicle: Vehicle, effects: EffectSet, model: str, measured: str = "tractive_force") -> ca.Function:
    ev = EffectValues(effects, vehicle)
    i_app, W, c, phi, K, rig = (ca.SX.sym(n) for n in ("i", "W", "c", "phi", "K", "rig"))
    i_true, F, rep = sweep_measurement(i_app, W, c, phi, K, vehicle, ev, model, measured, rig)
    return ca.Function("sweep", [i_app, W, c, phi, K, rig], [i_true, F, rep])


def simulate(
    vehicle: Vehicle,
    soil: Soil,
    *,
    kind: str = "drive",
    effects: Any = None,
    seed: int | None = None,
    noise: Any = "default",
    model: str = "full",
    duration_s: float | None = None,
    sample_rate_hz: float | None = None,
    speed_profile: Any = None,
    slips: Sequence[float] | None = None,
    normal_loads: Sequence[float] | None = None,
    sprocket_equation: str = "thrust",
    measure: str = "tractive_force",
    return_truth: bool = False,
    sinkage_slip_exponent: float | None = None,
    soil_changes: Sequence[tuple[float, Soil]] = (),
):
    """Simulate a drive log (``kind="drive"``) or a drawbar-pull slip sweep (``kind="sweep"``).

    Dispatches to :func:`simulate_drive_log` (``duration_s`` default 60, ``sample_rate_hz``
    default 50, ``speed_profile``, ``sprocket_equation``) or :func:`simulate_slip_sweep`
    (``slips``, ``normal_loads``, ``measure``: ``"tractive_force"`` or ``"drawbar_pull"``,
    ``sinkage_slip_exponent``: a ``sinkage_m`` channel). ``soil_changes`` (drive logs only):
    changes of terrain, as in :func:`simulate_drive_log`.
    Arguments that belong to the other kind are refused.

    Returns
    -------
    DriveLog or SlipData (with a truth dict when ``return_truth``).
    """
    if kind == "drive":
        if (
            slips is not None
            or normal_loads is not None
            or measure != "tractive_force"
            or sinkage_slip_exponent is not None
        ):
            raise DataError(
                "slips, normal_loads, measure and sinkage_slip_exponent belong to kind='sweep', not to a drive log"
            )
        return simulate_drive_log(
            vehicle,
            soil,
            effects=effects,
            seed=seed,
            noise=noise,
            model=model,
            duration_s=60.0 if duration_s is None else duration_s,
            sample_rate_hz=50.0 if sample_rate_hz is None else sample_rate_hz,
            speed_profile=speed_profile,
            sprocket_equation=sprocket_equation,
            return_truth=return_truth,
            soil_changes=soil_changes,
        )
    if kind == "sweep":
        if soil_changes:
            raise DataError("soil_changes belongs to kind='drive', not to a sweep")
        if duration_s is not None or sample_rate_hz is not None or speed_profile is not None:
            raise DataError("duration_s, sample_rate_hz and speed_profile belong to kind='drive', not to a sweep")
        if sprocket_equation != "thrust":
            raise DataError("sprocket_equation belongs to kind='drive', not to a sweep")
        return simulate_slip_sweep(
            vehicle,
            soil,
            slips=slips,
            normal_loads=normal_loads,
            effects=effects,
            seed=seed,
            noise=noise,
            model=model,
            measure=measure,
            return_truth=return_truth,
            sinkage_slip_exponent=sinkage_slip_exponent,
        )
    raise DataError(f"unknown kind {kind!r}; expected 'drive' or 'sweep'")
