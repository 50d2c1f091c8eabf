"""Drive-log preparation: checks, noise levels, discrete sprocket-equation thrust, sample selection."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...soilmodel.data import DriveLog
from ...soilmodel.errors import DataError
from ...soilmodel.vehicle import Vehicle
from .noise import noise_model
from .relaxation import relaxation_weights, slip_trend

__all__ = ["PreparedLog", "prepare_drive_log", "MIN_USABLE_SAMPLES", "SLIP_BOUNDS"]

#: Fewest usable samples accepted (two identifiable combinations, a noise level, and margin).
MIN_USABLE_SAMPLES = 10

#: Latent slip bounds (skid down to -0.95, driving slip up to 0.98).
SLIP_BOUNDS = (-0.95, 0.98)
#: A change of the thrust (first difference; second difference with the slip-relaxation weights)
#: beyond this many noise standard deviations is a jump: half of it is added to the sample's thrust
#: standard deviation (the discretisation's error there). 5 = 4 standard deviations with 25 % margin.
JUMP_SIGMA = 5.0


@dataclass(frozen=True)
class PreparedLog:
    """The samples of a drive log that enter the fit, and their noise levels (SI).

    ``thrust`` is the thrust from the sprocket equation over the interval ending at each used
    sample (see :func:`prepare_drive_log`); ``slip_measured`` is ``1 - v/(r w)`` (for reference
    and for the equation-error comparison only). ``keep`` marks the used samples of the log.
    ``torque_used`` and ``dw_dt`` are the torque and sprocket acceleration behind ``thrust``
    (``thrust = (torque_used - I dw_dt) / r``, plus ``W mu_r`` with the seed's equation);
    ``relaxation`` the weight of the next interval in them (0 without ``relaxation_at``).
    ``noise`` holds the noise model ``(a, b)`` per channel: ``sigma = sqrt(a^2 + (b x)^2)``.
    The speed and thrust residuals of one sample share the encoder noise of ``w_k`` (with
    ``torque_hold="zoh"``); ``coupling`` and ``sigma_thrust_cond`` whiten that 2x2 covariance.
    """

    keep: np.ndarray
    torque_used: np.ndarray  # the torque behind each used sample's thrust, N m
    dw_dt: np.ndarray  # the sprocket acceleration behind it, rad/s^2
    relaxation: np.ndarray  # the slip-relaxation weight phi of each used sample (0: the end-point rule)
    relaxation_at: tuple[float, float] | None  # (F_lim N, K m) the weights were computed at
    vehicle_speed: np.ndarray
    sprocket_speed: np.ndarray
    thrust: np.ndarray
    slip_measured: np.ndarray
    sigma_speed: np.ndarray  # sigma_s: of v - r w (1 - i), m/s
    sigma_thrust: np.ndarray  # sigma_T, N
    coupling: np.ndarray  # rho = cov(speed, thrust residual noise) / sigma_s^2, N s/m
    sigma_thrust_cond: np.ndarray  # sigma_T given the speed residual, sqrt(sigma_T^2 - rho^2 sigma_s^2), N
    noise: dict
    sigma_known: bool
    dropped: dict

    @property
    def n_used(self) -> int:
        """Number of samples used."""
        return int(self.thrust.size)


def prepare_drive_log(
    log: DriveLog,
    vehicle: Vehicle,
    *,
    sigma_torque: float | None = None,
    sigma_sprocket_speed: float | None = None,
    sigma_vehicle_speed: float | None = None,
    torque_hold: str = "zoh",
    min_speed: float = 0.0,
    sprocket_equation: str = "thrust",
    fixed_keep: np.ndarray | None = None,
    noise_models: dict | None = None,
    relaxation_at: tuple[float, float] | None = None,
) -> PreparedLog:
    """Check a drive log, estimate its noise, compute the sprocket thrust and select samples.

    The sprocket equation ``I dw/dt = M_s - r F(i)`` is used in discrete form, without any
    smoothing of the encoder:

    - ``torque_hold="zoh"`` (default; the torque is a command held from each sample to the
      next, as a digital drive controller and the library's simulator do): implicit Euler over
      the interval ending at sample k, ``r F(i_k) = M_{k-1} - I (w_k - w_{k-1}) / h``. It is
      exact for the encoder part, and for the stiff slip dynamics (slip settles within
      milliseconds of a torque change, so over most of the interval the slip sits on its
      quasi-static value, the one sampled at t_k) it is the L-stable quasi-static limit.
    - ``torque_hold="sample"`` (torque measured at the sample instants of a continuous signal):
      ``r F(i_k) = M_k - I (w_{k+1} - w_{k-1}) / (2 h)``.

    With ``relaxation_at=(F_lim, K)`` (a pilot estimate) and the held torque, the thrust at sample k
    is ``(1 - phi_k) T_k + phi_k T_{k+1}`` of the two interval means around it, with the
    slip-relaxation weight ``phi_k`` of :mod:`.relaxation` (the slip does not settle at once after a
    torque step; the end-point rule above then lags). The torque and the sprocket acceleration rows
    (``torque_used``, ``dw_dt``) are mixed alike, and the thrust's noise and its covariance with the
    speed residual follow the mix.

    With the seed's printed sprocket equation (``sprocket_equation="seed"``) ``W mu_r`` is added.
    ``noise_models`` (``{"torque": (a, b), "sprocket_speed": ..., "vehicle_speed": ...}``)
    replaces the noise estimated from the log (a held-out block uses the fit's noise).

    Raises
    ------
    DataError
        Too few samples, no positive vehicle or sprocket speed, or fewer than
        :data:`MIN_USABLE_SAMPLES` usable samples; the message names the file and column.
    """
    _check_options(
        log, sprocket_equation, torque_hold, sigma_torque, sigma_sprocket_speed, sigma_vehicle_speed, min_speed
    )
    v = log.vehicle_speed
    w = log.sprocket_speed
    r, W = vehicle.sprocket_radius, vehicle.weight
    sigma_known = None not in (sigma_torque, sigma_sprocket_speed, sigma_vehicle_speed)
    nm, s_M, s_w, s_v = _noise_levels(log, noise_models, sigma_torque, sigma_sprocket_speed, sigma_vehicle_speed)
    if torque_hold == "zoh":
        th = _held_torque_thrust(log, vehicle, s_M, s_w, relaxation_at)
    else:
        th = _sampled_torque_thrust(log, vehicle, s_M, s_w)
    thrust, M_used, dwdt, cov_w, phi = th.thrust, th.torque_used, th.dw_dt, th.cov_w, th.relaxation
    if sprocket_equation == "seed":  # I dw/dt = M_s - (F - W mu_r) r, as printed in the seed
        thrust = thrust + W * vehicle.rolling_resistance
    sigma_T, n_jump = _jump_inflated(thrust, th.sigma_thrust)

    keep, slow, braking, edge, turning, floor = _select_samples(
        log, vehicle, thrust, sigma_T, s_v, s_w, min_speed, fixed_keep
    )
    vk, wk = v[keep], w[keep]
    slip_m = 1.0 - vk / (r * wk)
    one_minus_i = np.clip(1.0 - slip_m, 1.0 - SLIP_BOUNDS[1], 1.0 - SLIP_BOUNDS[0])
    sigma_s = np.sqrt(s_v[keep] ** 2 + (r * one_minus_i * s_w[keep]) ** 2)
    sT = sigma_T[keep]
    # w_k enters both residuals: -r (1 - i) dw_k and the thrust's encoder terms (zoh; the central
    # difference of torque_hold="sample" does not contain w_k)
    cov = one_minus_i * cov_w[keep]
    rho = cov / sigma_s**2
    sT_cond = np.sqrt(np.maximum(sT**2 - rho * cov, 0.0) + 1e-300)
    return PreparedLog(
        keep=keep,
        torque_used=M_used[keep],
        dw_dt=dwdt[keep],
        relaxation=phi[keep],
        relaxation_at=None
        if relaxation_at is None or torque_hold != "zoh"
        else (float(relaxation_at[0]), float(relaxation_at[1])),
        vehicle_speed=vk,
        sprocket_speed=wk,
        thrust=thrust[keep],
        slip_measured=slip_m,
        sigma_speed=sigma_s,
        sigma_thrust=sT,
        coupling=rho,
        sigma_thrust_cond=sT_cond,
        noise=nm,
        sigma_known=sigma_known,
        dropped={
            "slow": int(np.count_nonzero(slow)),
            "braking": int(np.count_nonzero(braking)),
            "edge": int(np.count_nonzero(edge)),
            "speed_floor_m_s": float(np.median(floor)),
            "thrust_jumps": n_jump,
            "turning": log.n_turning,
            "turning_left_out": int(np.count_nonzero(turning)),
        },
    )


@dataclass(frozen=True)
class _Thrust:
    """The thrust of every sample from the discrete sprocket equation, with what is behind it."""

    thrust: np.ndarray  #: thrust (N), NaN where the equation has no interval
    sigma_thrust: np.ndarray  #: its noise standard deviation (N), before the jump inflation
    torque_used: np.ndarray  #: the sprocket torque behind each thrust (N m)
    dw_dt: np.ndarray  #: the sprocket acceleration behind each thrust (rad/s^2)
    cov_w: np.ndarray  #: covariance with the speed residual per unit (1 - i) (through w_k)
    relaxation: np.ndarray  #: slip-relaxation weights (zero: the end-point rule)


def _check_options(
    log, sprocket_equation, torque_hold, sigma_torque, sigma_sprocket_speed, sigma_vehicle_speed, min_speed
) -> None:
    """The log's type, length and motion, and the options' values; DataError naming file and column."""
    if not isinstance(log, DriveLog):
        raise TypeError(f"fit_drive_log takes a DriveLog, got {type(log).__name__}")
    if sprocket_equation not in ("thrust", "seed"):
        raise DataError(f"unknown sprocket_equation {sprocket_equation!r}; expected 'thrust' or 'seed'")
    if torque_hold not in ("zoh", "sample"):
        raise DataError(f"unknown torque_hold {torque_hold!r}; expected 'zoh' or 'sample'")
    n = log.n_samples
    if n < MIN_USABLE_SAMPLES:
        raise DataError(
            f"a drive log needs at least {MIN_USABLE_SAMPLES} samples to identify F_max and K, got {n}",
            file=log.source,
            column="time_s",
        )
    if not np.any(log.vehicle_speed > 0):
        raise DataError(
            "no sample with a positive vehicle speed: a standing (or reversing) vehicle shows nothing of the soil",
            file=log.source,
            column="vehicle_speed_m_s",
        )
    if not np.any(log.sprocket_speed > 0):
        raise DataError(
            "no sample with a positive sprocket speed: the tracks never turned forwards",
            file=log.source,
            column="sprocket_speed_rad_s",
        )
    for name, val in (
        ("sigma_torque", sigma_torque),
        ("sigma_sprocket_speed", sigma_sprocket_speed),
        ("sigma_vehicle_speed", sigma_vehicle_speed),
        ("min_speed", min_speed),
    ):
        if val is not None and not (isinstance(val, (int, float)) and math.isfinite(val) and val >= 0):
            raise DataError(f"{name} must be a finite number >= 0, got {val!r}")


def _noise_levels(log: DriveLog, noise_models, sigma_torque, sigma_sprocket_speed, sigma_vehicle_speed):
    """Noise models ``sigma = sqrt(a^2 + (b x)^2)`` per channel and the per-sample levels ``(nm, s_M, s_w, s_v)``."""
    M, w, v = log.sprocket_torque, log.sprocket_speed, log.vehicle_speed
    # Noise models sigma = sqrt(a^2 + (b x)^2): given (constant), or estimated from the log.
    # (a model given in noise_models replaces the estimate, so that channel is not estimated at all)
    nm = {k: (float(a), float(b)) for k, (a, b) in (noise_models or {}).items()}
    for channel, reading, sigma_given in (
        ("torque", M, sigma_torque),
        ("sprocket_speed", w, sigma_sprocket_speed),
        ("vehicle_speed", v, sigma_vehicle_speed),
    ):
        if channel not in nm:
            nm[channel] = noise_model(reading, sigma_given)
    s_M = np.hypot(nm["torque"][0], nm["torque"][1] * M)
    s_w = np.hypot(nm["sprocket_speed"][0], nm["sprocket_speed"][1] * w)
    s_v = np.hypot(nm["vehicle_speed"][0], nm["vehicle_speed"][1] * v)
    return nm, s_M, s_w, s_v


def _held_torque_thrust(log: DriveLog, vehicle: Vehicle, s_M, s_w, relaxation_at) -> _Thrust:
    """``torque_hold="zoh"``: implicit Euler over each interval; mixed with the next by the relaxation weights."""
    n, t, v, w, M = log.n_samples, log.time, log.vehicle_speed, log.sprocket_speed, log.sprocket_torque
    r, I = vehicle.sprocket_radius, vehicle.sprocket_inertia
    M_used = np.full(n, np.nan)  # the torque and the sprocket acceleration behind each thrust
    dwdt = np.full(n, np.nan)
    # covariance of the thrust's noise with the speed residual's (through the encoder reading w_k),
    # per unit (1 - i) (that factor belongs to the speed residual)
    cov_w = np.zeros(n)
    phi = np.zeros(n)
    h = np.diff(t)
    M_used[1:] = M[:-1]
    dwdt[1:] = np.diff(w) / h
    var_T = np.full(n, np.inf)
    var_T[1:] = (s_M[:-1] ** 2 + (I / h) ** 2 * (s_w[1:] ** 2 + s_w[:-1] ** 2)) / r**2
    cov_w[1:] = I * s_w[1:] ** 2 / h
    if relaxation_at is not None and n > 2:
        k = np.arange(1, n - 1)  # samples with a next interval
        i_m = 1.0 - v / (r * np.where(w != 0, w, np.nan))
        phi[k] = relaxation_weights(vehicle, relaxation_at[0], relaxation_at[1], slip_trend(i_m)[k], w[k], h[k - 1])
        nxt = np.isfinite(M[k]) & np.isfinite(w[k + 1]) & np.isfinite(h[k])
        # the weight's premise is a steady trend of the interval means; where their second difference
        # exceeds the noise (a torque step at the traction limit) the end-point rule stays
        T_mean = (M_used - I * dwdt) / r
        Tm = np.where(np.isfinite(T_mean), T_mean, 0.0)
        d2 = np.abs(Tm[k + 1] - 2.0 * Tm[k] + Tm[k - 1])
        sd2 = np.sqrt(np.where(nxt, var_T[k + 1] + 4.0 * var_T[k] + var_T[k - 1], np.inf))
        steady = nxt & np.isfinite(T_mean[k - 1]) & (d2 <= JUMP_SIGMA * sd2)
        phi[k] = np.where(steady, phi[k], 0.0)
        nxt = steady
        a, b = 1.0 - phi[k], phi[k]
        M_used[k] = a * M[k - 1] + b * np.where(nxt, M[k], 0.0)
        dwdt[k] = a * dwdt[k] + b * np.where(nxt, (w[k + 1] - w[k]) / h[k], 0.0)
        # T_k holds -I w_k / (h_k r), T_{k+1} holds +I w_k / (h_{k+1} r): their covariance
        c_next = -(I**2) * s_w[k] ** 2 / (h[k - 1] * h[k] * r**2)
        var_next = np.where(nxt, (s_M[k] ** 2 + (I / h[k]) ** 2 * (s_w[k + 1] ** 2 + s_w[k] ** 2)) / r**2, 0.0)
        var_T[k] = a**2 * var_T[k] + b**2 * var_next + 2.0 * a * b * c_next
        cov_w[k] = I * s_w[k] ** 2 * (a / h[k - 1] - b / h[k])
    return _Thrust((M_used - I * dwdt) / r, np.sqrt(var_T), M_used, dwdt, cov_w, phi)


def _sampled_torque_thrust(log: DriveLog, vehicle: Vehicle, s_M, s_w) -> _Thrust:
    """``torque_hold="sample"``: the central difference of the encoder around each torque sample."""
    n, t, w, M = log.n_samples, log.time, log.sprocket_speed, log.sprocket_torque
    r, I = vehicle.sprocket_radius, vehicle.sprocket_inertia
    thrust = np.full(n, np.nan)
    sigma_T = np.full(n, np.inf)
    M_used = np.full(n, np.nan)
    dwdt = np.full(n, np.nan)
    h2 = t[2:] - t[:-2]
    M_used[1:-1] = M[1:-1]
    dwdt[1:-1] = (w[2:] - w[:-2]) / h2
    thrust[1:-1] = (M_used[1:-1] - I * dwdt[1:-1]) / r
    sigma_T[1:-1] = np.sqrt(s_M[1:-1] ** 2 + (I / h2) ** 2 * (s_w[2:] ** 2 + s_w[:-2] ** 2)) / r
    return _Thrust(thrust, sigma_T, M_used, dwdt, np.zeros(n), np.zeros(n))


def _jump_inflated(thrust: np.ndarray, sigma_T: np.ndarray) -> tuple[np.ndarray, int]:
    """The thrust's noise with half of each jump beyond the noise added, and the number of such samples.

    Discretisation error: the discrete sprocket equation gives the thrust averaged over the
    interval, the slip is sampled at its end. Where the thrust jumps within an interval (a
    spinning track that grips again, a torque step at the traction limit) the two differ by
    up to half the jump. Where the change to a neighbouring interval exceeds what the noise
    allows (4 standard deviations), that half jump is added to the sample's variance.
    """
    n = len(thrust)
    jump = np.zeros(n)
    fin = np.isfinite(thrust)
    d = np.where(fin[1:] & fin[:-1], np.abs(np.diff(np.where(fin, thrust, 0.0))), 0.0)
    sd = np.sqrt(np.where(fin[1:] & fin[:-1], sigma_T[1:] ** 2 + sigma_T[:-1] ** 2, np.inf))
    big = np.where(d > JUMP_SIGMA * sd, d, 0.0)
    jump[1:] = np.maximum(jump[1:], big)
    jump[:-1] = np.maximum(jump[:-1], big)
    return np.sqrt(sigma_T**2 + (0.5 * jump) ** 2), int(np.count_nonzero(jump > 0))


def _select_samples(log: DriveLog, vehicle: Vehicle, thrust, sigma_T, s_v, s_w, min_speed, fixed_keep):
    """The samples kept and those dropped (slow, braking, edge, turning), and the speed floor (m/s).

    Raises
    ------
    DataError
        Fewer than :data:`MIN_USABLE_SAMPLES` samples are left.
    """
    n, v, w, r = log.n_samples, log.vehicle_speed, log.sprocket_speed, vehicle.sprocket_radius
    edge = ~np.isfinite(thrust)
    floor = np.maximum(max(float(min_speed), 1e-3), 3.0 * np.maximum(s_v, r * s_w))
    slow = ~edge & ~((v >= floor) & (r * w >= floor))
    braking = ~edge & ~slow & (thrust < -3.0 * sigma_T)
    # a two-track log's turning samples, and the sample after each (its thrust spans the turn's last
    # interval), are outside the straight-line model
    turning = np.zeros(n, dtype=bool)
    if log.turning is not None:
        turn = log.turning.copy()
        turn[1:] |= log.turning[:-1]
        turning = ~(edge | slow | braking) & turn
    keep = ~(edge | slow | braking | turning)
    if fixed_keep is not None:  # SIMEX refits: the sample selection of the uncorrected fit
        keep = np.asarray(fixed_keep, dtype=bool).copy()
        slow, braking, edge = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), ~keep
    n_keep = int(np.count_nonzero(keep))
    if n_keep < MIN_USABLE_SAMPLES:
        raise DataError(
            f"only {n_keep} samples have vehicle and track speeds above 3 noise levels "
            f"(about {float(np.median(floor)):.3g} m/s) while driving; at least {MIN_USABLE_SAMPLES} "
            f"are needed",
            file=log.source,
            column="vehicle_speed_m_s",
        )
    return keep, slow, braking, edge, turning, floor
