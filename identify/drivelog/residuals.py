"""Per-channel residuals of a fitted drive-log model on a held-out log (block).

Three channels, each ``measured - predicted`` in its own unit (:data:`~.joint.CHANNELS`):

``sprocket_speed_rad_s``
    encoder reading minus ``v / (r_eff (1 - i))``;
``thrust_N``
    sprocket thrust ``(M - tau_loss - I dw/dt) / r_eff`` minus ``F(i)``;
``hull_N``
    hull balance ``m_eff a - (F(i) - R(v, i))`` (``a`` from the IMU column, else the central
    difference of the measured speed).

The latent slip of each held-out sample is solved for the FITTED parameters (the per-sample
minimum of the same whitened cost the fit profiles out, :meth:`~.joint.SlipSolver.solve`;
the hull channel takes part only if the fit used it). Because that slip is fitted to the sample,
the channels of one sample share one fitted degree of freedom: the sum over the channels of the
whitened squares has expectation about (channels used - 1) per sample, not the number of
channels. Per-channel noise sigmas (same units, per sample) come from the fit's noise model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ...soilmodel.data import DriveLog
from ...soilmodel.effects import effect_structure, parse_effects
from ...soilmodel.errors import DataError
from ...soilmodel.vehicle import Vehicle
from .joint import CHANNELS, HULL_ROW, best_slips, joint_data, residual_function, sample_outputs
from .nlp import g_inverse
from .prepare import SLIP_BOUNDS, prepare_drive_log

__all__ = ["DriveLogResiduals", "drive_log_residuals"]


@dataclass(frozen=True)
class DriveLogResiduals:
    """Residual model of drive-log fits, the hook of :meth:`FitResult.residuals_on` (picklable).

    ``hull_in_fit``: whether the fit used the hull channel (then the held-out latent slips use it too).
    """

    hull_in_fit: bool = False

    def residuals_on(self, result: Any, data: DriveLog) -> dict[str, np.ndarray]:
        """Raw residuals per channel on ``data`` (see :func:`drive_log_residuals`)."""
        out = drive_log_residuals(result, data, result.vehicle, model=result.model)
        return {ch: out["channels"][ch] for ch in CHANNELS}


def _params_from(
    result_or_params: Any, effects: Any
) -> tuple[float, float, dict[str, float], Any, dict | None, bool, str, tuple[float, float] | None, Any]:
    """``(F_lim, K, effect values, effects, noise models, hull used, torque_hold, accel noise, relaxation_at)``.

    ``relaxation_at`` is the pilot soil ``(F_lim, K)`` of the fit's held-torque discretisation (None:
    the end-point rule; see :mod:`.relaxation`), so that the residuals use the fit's own rows."""
    if isinstance(result_or_params, Mapping):
        p = result_or_params
        F, K = float(p["max_thrust_N"]), float(p["shear_modulus_m"])
        ev = dict(p.get("effects", {}))
        return (
            F,
            K,
            ev,
            effects if effects is not None else p.get("structure"),
            p.get("noise"),
            bool(p.get("hull_in_fit", bool(ev))),
            str(p.get("torque_hold", "zoh")),
            p.get("accel_noise"),
            p.get("relaxation_at"),
        )
    res = result_or_params
    if getattr(res, "data_kind", None) != "drive":
        raise DataError("drive_log_residuals needs a drive-log fit result or a parameter mapping")
    if not res.success:
        raise DataError("drive_log_residuals: the fit did not succeed; there is no fitted model to evaluate")
    ex = res.extra
    nm = {
        k: (ex["noise_model"][col]["abs"], ex["noise_model"][col]["rel"])
        for k, col in (
            ("torque", "torque_Nm"),
            ("sprocket_speed", "sprocket_speed_rad_s"),
            ("vehicle_speed", "vehicle_speed_m_s"),
        )
    }
    jp = ex.get("joint_parameters")
    hull = bool(ex.get("hull_channel", {}).get("used", False))
    an = None
    if "hull_channel" in ex:
        a = ex["hull_channel"]["accel_noise_m_s2"]
        an = (a["abs"], a["rel"]) if ex["hull_channel"]["accel_source"] == "imu" else None
    if jp is not None:
        return (
            float(jp["max_thrust_N"]),
            float(jp["shear_modulus_m"]),
            dict(jp["effects"]),
            effects if effects is not None else jp["structure"],
            nm,
            hull,
            jp["torque_hold"],
            an,
            ex.get("relaxation_at"),
        )
    return (
        float(ex["max_thrust_N"]),
        float(ex["shear_modulus_m"]),
        {},
        effects,
        nm,
        hull,
        str(ex.get("torque_hold", "zoh")),
        an,
        ex.get("relaxation_at"),
    )


def drive_log_residuals(
    result_or_params: Any, log: DriveLog, vehicle: Vehicle, effects: Any = None, model: str = "full"
) -> dict[str, Any]:
    """Residuals of a fitted drive-log model on a (held-out) log, per channel, with noise sigmas.

    Parameters
    ----------
    result_or_params
        A drive-log :class:`~..estimates.result.FitResult`, or a mapping with ``max_thrust_N`` (the log's
        thrust limit, N), ``shear_modulus_m`` and optionally ``effects`` (``{"effect.param":
        value}``), ``structure`` (which effects are on), ``noise`` (noise models per channel,
        ``{"torque": (a, b), ...}``), ``hull_in_fit``, ``torque_hold``, ``accel_noise``.
    log, vehicle
        The held-out log (at least 10 usable samples) and the nominal vehicle.
    effects
        Which effects are on (default: those of the fit).
    model
        Unused beyond the check (the thrust limit already carries the soil); kept for symmetry.

    Returns
    -------
    dict
        ``channels`` ``{channel: ndarray}`` (measured - predicted), ``sigma`` ``{channel:
        ndarray}`` (noise standard deviation per sample, same unit), ``gain`` ``{channel: ndarray}`` (the
        residual's derivative with respect to the measured signal it is formed from: 1 for the sprocket speed,
        ``1 / r_eff`` for the thrust from the torque, ``m_eff`` for the hull balance from the acceleration; a
        likelihood of the measured signals divides ``sigma`` by it), ``noise_sigma`` ``{channel:
        median sigma}``, ``time_s``, ``keep`` (used samples of ``log``), ``slip`` (latent slips),
        ``vehicle_speed_m_s``, ``accel_source``, ``hull_in_fit``.
    """
    out, _ = evaluate_residuals(result_or_params, log, vehicle, effects)
    return out


def evaluate_residuals(
    result_or_params: Any, log: DriveLog, vehicle: Vehicle, effects: Any
) -> tuple[dict[str, Any], dict]:
    """:func:`drive_log_residuals` and what it was computed from (``theta``, ``structure``, ``D`` as
    used to solve the latent slips, ``labels``) for :mod:`.sensitivity`."""
    F, K, ev, eff, nm, hull, torque_hold, an, rel = _params_from(result_or_params, effects)
    structure = effect_structure(parse_effects(eff) if eff is not None else None, vehicle)
    _, labels = residual_function(vehicle, structure)
    missing = [lab for lab in labels if lab not in ev]
    if missing:
        # effects switched on without a value: their given values (or off values)
        es = parse_effects(eff)
        for lab in missing:
            name, param = lab.split(".")
            ev[lab] = es.value(name, param, vehicle)
    theta = np.array([F, K] + [ev[lab] for lab in labels], dtype=float)
    if not np.all(np.isfinite(theta)):
        raise DataError("drive_log_residuals: the parameters are not finite")
    prep = prepare_drive_log(
        log, vehicle, torque_hold=torque_hold, noise_models=nm, relaxation_at=None if rel is None else tuple(rel)
    )
    jd = joint_data(log, vehicle, prep, accel_noise=an)
    l = vehicle.track_length
    y = np.clip(np.abs(prep.thrust) / F, 0.0, 0.98)
    slip0 = np.clip(np.sign(prep.thrust) * g_inverse(y) * K / l, SLIP_BOUNDS[0] + 1e-3, SLIP_BOUNDS[1] - 1e-3)
    D_solve = jd.D.copy()
    if not hull:
        D_solve[HULL_ROW] = 0.0
    slip_meas = np.clip(prep.slip_measured, SLIP_BOUNDS[0] + 1e-3, SLIP_BOUNDS[1] - 1e-3)
    slip = best_slips(vehicle, structure, theta, D_solve, [slip0, slip_meas])
    raw = sample_outputs(vehicle, structure, "residual", theta, slip, jd.D)[1]
    r_eff = vehicle.sprocket_radius * (1 + ev.get("radius_error.eps", 0.0))
    m_eff = vehicle.mass * (1 + ev.get("mass_error.delta", 0.0))
    ratio = r_eff / vehicle.sprocket_radius
    s_speed = np.sqrt(jd.D[5] ** 2 + (r_eff * jd.D[6]) ** 2)
    sig_w = s_speed / (r_eff * np.maximum(1 - slip, 1e-3))
    sig_H = jd.sigma_hull * m_eff / vehicle.mass
    sigma = {"sprocket_speed_rad_s": sig_w, "thrust_N": prep.sigma_thrust / ratio, "hull_N": sig_H}
    # each residual's derivative with respect to the measured signal it is formed from: the sprocket speed
    # itself, the torque over the effective radius, the acceleration times the effective mass
    ones = np.ones(slip.size)
    gain = {"sprocket_speed_rad_s": ones, "thrust_N": ones / r_eff, "hull_N": ones * m_eff}
    chans = {ch: raw[j] for j, ch in enumerate(CHANNELS)}
    chans["hull_N"] = np.where(np.isfinite(sig_H), chans["hull_N"], np.nan)
    out = {
        "channels": chans,
        "sigma": sigma,
        "gain": gain,
        "noise_sigma": {
            ch: float(np.median(s[np.isfinite(s)])) if np.any(np.isfinite(s)) else math.inf for ch, s in sigma.items()
        },
        "time_s": log.time[prep.keep],
        "keep": prep.keep,
        "slip": slip,
        "vehicle_speed_m_s": prep.vehicle_speed,
        "accel_source": jd.accel_source,
        "hull_in_fit": hull,
    }
    return out, {"theta": theta, "structure": structure, "D": D_solve, "labels": tuple(labels)}
