"""Drive-log preparation: checks, noise levels, discrete sprocket-equation thrust, sample selection."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...soilmodel.data import DriveLog
from ...soilmodel.errors import DataError
from ...soilmodel.vehicle import Vehicle
from .noise import noise_model
from .relaxation import slip_trend

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
    """``torque_hold="zoh"``: implicit Euler over each interval; with ``relaxation_at``, the relaxation rule.

    The thrust at sample k is ``sum_j c_j T_{k+j}`` (j = -1..2) of the interval means ``T``
    (:func:`_relaxation_coefficients`; the end-point rule ``c = (0, 1, 0, 0)``). The torque and the
    sprocket acceleration rows are mixed alike, and the noise of the mix follows from the raw
    readings' coefficients (each ``w_n`` enters ``T_n`` and ``T_{n+1}``).
    """
    n, t, w, M = log.n_samples, log.time, log.sprocket_speed, log.sprocket_torque
    r, I = vehicle.sprocket_radius, vehicle.sprocket_inertia
    h = np.diff(t)
    M_iv = np.full(n, np.nan)  # the interval ending at m: its torque, acceleration and thrust
    a_iv = np.full(n, np.nan)
    M_iv[1:] = M[:-1]
    a_iv[1:] = np.diff(w) / h
    T_iv = (M_iv - I * a_iv) / r
    var_iv = np.full(n, np.inf)
    var_iv[1:] = (s_M[:-1] ** 2 + (I / h) ** 2 * (s_w[1:] ** 2 + s_w[:-1] ** 2)) / r**2
    C, phi, lo = _relaxation_coefficients(log, vehicle, relaxation_at, T_iv, var_iv)
    offsets = range(-lo, C.shape[1] - lo)  # C[:, j + lo] is the weight of T_{k+j}
    k = np.arange(n)

    def at(x, j, fill=np.nan):
        idx = k + j
        ok = (idx >= 0) & (idx < n)
        return np.where(ok, x[np.clip(idx, 0, n - 1)], fill)

    def mix(x):
        out = np.zeros(n)
        for j in offsets:
            out += np.where(C[:, j + lo] != 0, C[:, j + lo] * at(x, j), 0.0)
        return out

    M_used, dwdt = mix(M_iv), mix(a_iv)
    M_used[0] = dwdt[0] = np.nan
    hh = np.full(n + 1, np.inf)  # hh[m] = t_m - t_{m-1}
    hh[1:n] = h
    var_T = np.zeros(n)
    for j in offsets:
        var_T += np.where(C[:, j + lo] != 0, (C[:, j + lo] / r) ** 2 * at(s_M, j - 1, 0.0) ** 2, 0.0)
    coef_wk = np.zeros(n)
    for q in range(-lo - 1, C.shape[1] - lo):  # the reading w_{k+q}: in T_{k+q} (minus) and in T_{k+q+1} (plus)
        cq = np.zeros(n)
        for j, sign in ((q, -1.0), (q + 1, 1.0)):
            if j in offsets:
                cq = cq + np.where(C[:, j + lo] != 0, sign * C[:, j + lo] * I / (r * at(hh, j, np.inf)), 0.0)
        var_T = var_T + np.where(cq != 0, cq**2 * at(s_w, q, 0.0) ** 2, 0.0)
        if q == 0:
            coef_wk = cq
    var_T[0] = np.inf
    # covariance with the speed residual per unit (1 - i), through w_k (that factor belongs to the speed residual)
    cov_w = -r * coef_wk * s_w**2
    cov_w[0] = 0.0
    return _Thrust((M_used - I * dwdt) / r, np.sqrt(var_T), M_used, dwdt, cov_w, phi)


def _relaxation_coefficients(log: DriveLog, vehicle: Vehicle, relaxation_at, T_iv, var_iv):
    """The weights of the interval means per sample, the relaxation weight ``phi`` and the stencil's reach back.

    Returns ``(C, phi, s)``: ``C[k, j + s]`` is the weight of ``T_{k+j}`` (``j = -s .. s + 1``, ``s`` =
    :data:`~.relaxation.RELAXATION_SPREAD`). The end-point rule (``T_k`` alone) without ``relaxation_at``.
    With it: the weights of :func:`~.relaxation.relaxation_stencil` where the interval means around the
    sample follow a steady trend (every second difference of ``T`` inside the stencil within
    :data:`JUMP_SIGMA` noise levels: no torque step at the traction limit), the first-order rule where only
    the one at k holds, the end-point rule where that one does not.
    """
    from . import relaxation as rx

    n, sp = log.n_samples, int(rx.RELAXATION_SPREAD)
    C = np.zeros((n, 2 * sp + 2))
    C[:, sp] = 1.0
    phi = np.zeros(n)
    if relaxation_at is None or n <= 2:
        return C, phi, sp
    t, v, w = log.time, log.vehicle_speed, log.sprocket_speed
    h = np.diff(t)
    k = np.arange(1, n - 1)  # samples with a next interval
    i_m = 1.0 - v / (vehicle.sprocket_radius * np.where(w != 0, w, np.nan))
    p, c = rx.relaxation_stencil(
        vehicle, relaxation_at[0], relaxation_at[1], slip_trend(i_m)[k], w[k], h[k - 1], rx.RELAXATION_CURVATURE, sp
    )
    fin = np.isfinite(T_iv)
    Tm = np.where(fin, T_iv, 0.0)

    def steady_at(j):  # the second difference of T around sample j (T_{j-1}, T_j, T_{j+1}) within the noise
        ok = (j + 1 < n) & (j - 1 >= 1)
        jj = np.clip(j, 1, n - 2)
        d2 = np.abs(Tm[jj + 1] - 2.0 * Tm[jj] + Tm[jj - 1])
        sd2 = np.sqrt(var_iv[jj + 1] + 4.0 * var_iv[jj] + var_iv[jj - 1])
        return ok & fin[jj + 1] & fin[jj] & fin[jj - 1] & (d2 <= JUMP_SIGMA * sd2)

    first = steady_at(k)
    whole = first.copy()
    for j in range(-sp + 1, sp + 1):  # the windows T_{k+j-1..k+j+1} inside T_{k-s}..T_{k+1+s}
        if j != 0:
            whole &= steady_at(k + j)
    full = np.zeros((k.size, 2 * sp + 2))
    full[:, [0, sp, sp + 1, 2 * sp + 1]] = c
    one = np.zeros_like(full)
    one[:, sp], one[:, sp + 1] = 1.0 - p, p
    phi[k] = np.where(first, p, 0.0)
    C[k] = np.where(whole[:, None], full, np.where(first[:, None], one, C[k]))
    return C, phi, sp


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
