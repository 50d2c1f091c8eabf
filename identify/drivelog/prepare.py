"""Drive-log preparation: checks, noise levels, discrete sprocket-equation thrust, sample selection."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...soilmodel.data import DriveLog
from ...soilmodel.errors import DataError
from ...soilmodel.vehicle import Vehicle
from .noise import noise_model

__all__ = ["PreparedLog", "prepare_drive_log", "MIN_USABLE_SAMPLES", "SLIP_BOUNDS"]

#: Fewest usable samples accepted (two identifiable combinations, a noise level, and margin).
MIN_USABLE_SAMPLES = 10

#: Latent slip bounds (skid down to -0.95, driving slip up to 0.98).
SLIP_BOUNDS = (-0.95, 0.98)


@dataclass(frozen=True)
class PreparedLog:
    """The samples of a drive log that enter the fit, and their noise levels (SI).

    ``thrust`` is the thrust from the sprocket equation over the interval ending at each used
    sample (see :func:`prepare_drive_log`); ``slip_measured`` is ``1 - v/(r w)`` (for reference
    and for the equation-error comparison only). ``keep`` marks the used samples of the log.
    ``noise`` holds the noise model ``(a, b)`` per channel: ``sigma = sqrt(a^2 + (b x)^2)``.
    The speed and thrust residuals of one sample share the encoder noise of ``w_k`` (with
    ``torque_hold="zoh"``); ``coupling`` and ``sigma_thrust_cond`` whiten that 2x2 covariance.
    """

    keep: np.ndarray
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

    With the seed's printed sprocket equation (``sprocket_equation="seed"``) ``W mu_r`` is added.
    ``noise_models`` (``{"torque": (a, b), "sprocket_speed": ..., "vehicle_speed": ...}``)
    replaces the noise estimated from the log (a held-out block uses the fit's noise).

    Raises
    ------
    DataError
        Too few samples, no positive vehicle or sprocket speed, or fewer than
        :data:`MIN_USABLE_SAMPLES` usable samples; the message names the file and column.
    """
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
    t = log.time
    v = log.vehicle_speed
    w = log.sprocket_speed
    M = log.sprocket_torque
    r, I, W = vehicle.sprocket_radius, vehicle.sprocket_inertia, vehicle.weight
    if not np.any(v > 0):
        raise DataError(
            "no sample with a positive vehicle speed: a standing (or reversing) vehicle shows nothing of the soil",
            file=log.source,
            column="vehicle_speed_m_s",
        )
    if not np.any(w > 0):
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
    sigma_known = None not in (sigma_torque, sigma_sprocket_speed, sigma_vehicle_speed)
    # Noise models sigma = sqrt(a^2 + (b x)^2): given (constant), or estimated from the log.
    nm = {
        "torque": noise_model(M, sigma_torque),
        "sprocket_speed": noise_model(w, sigma_sprocket_speed),
        "vehicle_speed": noise_model(v, sigma_vehicle_speed),
    }
    if noise_models is not None:
        nm.update({k: (float(a), float(b)) for k, (a, b) in noise_models.items()})
    s_M = np.hypot(nm["torque"][0], nm["torque"][1] * M)
    s_w = np.hypot(nm["sprocket_speed"][0], nm["sprocket_speed"][1] * w)
    s_v = np.hypot(nm["vehicle_speed"][0], nm["vehicle_speed"][1] * v)

    thrust = np.full(n, np.nan)
    sigma_T = np.full(n, np.inf)
    if torque_hold == "zoh":
        h = np.diff(t)
        thrust[1:] = (M[:-1] - I * np.diff(w) / h) / r
        sigma_T[1:] = np.sqrt(s_M[:-1] ** 2 + (I / h) ** 2 * (s_w[1:] ** 2 + s_w[:-1] ** 2)) / r
    else:
        h2 = t[2:] - t[:-2]
        thrust[1:-1] = (M[1:-1] - I * (w[2:] - w[:-2]) / h2) / r
        sigma_T[1:-1] = np.sqrt(s_M[1:-1] ** 2 + (I / h2) ** 2 * (s_w[2:] ** 2 + s_w[:-2] ** 2)) / r
    if sprocket_equation == "seed":  # I dw/dt = M_s - (F - W mu_r) r, as printed in the seed
        thrust = thrust + W * vehicle.rolling_resistance
    edge = ~np.isfinite(thrust)
    # Discretisation error: the discrete sprocket equation gives the thrust averaged over the
    # interval, the slip is sampled at its end. Where the thrust jumps within an interval (a
    # spinning track that grips again, a torque step at the traction limit) the two differ by
    # up to half the jump. Where the change to a neighbouring interval exceeds what the noise
    # allows (4 standard deviations), that half jump is added to the sample's variance.
    jump = np.zeros(n)
    fin = np.isfinite(thrust)
    d = np.where(fin[1:] & fin[:-1], np.abs(np.diff(np.where(fin, thrust, 0.0))), 0.0)
    sd = np.sqrt(np.where(fin[1:] & fin[:-1], sigma_T[1:] ** 2 + sigma_T[:-1] ** 2, np.inf))
    big = np.where(d > 4.0 * 1.25 * sd, d, 0.0)
    jump[1:] = np.maximum(jump[1:], big)
    jump[:-1] = np.maximum(jump[:-1], big)
    sigma_T = np.sqrt(sigma_T**2 + (0.5 * jump) ** 2)
    n_jump = int(np.count_nonzero(jump > 0))

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
    vk, wk = v[keep], w[keep]
    slip_m = 1.0 - vk / (r * wk)
    one_minus_i = np.clip(1.0 - slip_m, 1.0 - SLIP_BOUNDS[1], 1.0 - SLIP_BOUNDS[0])
    sigma_s = np.sqrt(s_v[keep] ** 2 + (r * one_minus_i * s_w[keep]) ** 2)
    sT = sigma_T[keep]
    if torque_hold == "zoh":  # w_k enters both residuals: -r (1 - i) dw_k and -I dw_k / (h r)
        hk = np.diff(t)[np.nonzero(keep)[0] - 1]
        cov = I * one_minus_i * s_w[keep] ** 2 / hk
    else:  # the central difference does not contain w_k
        cov = np.zeros_like(sT)
    rho = cov / sigma_s**2
    sT_cond = np.sqrt(np.maximum(sT**2 - rho * cov, 0.0) + 1e-300)
    return PreparedLog(
        keep=keep,
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
