"""Opt-in SIMEX correction of the drive-log error-in-variables bias (vehicle-speed noise)."""

from __future__ import annotations

import dataclasses
from typing import Callable
import math
import time as _time

import numpy as np

from ...soilmodel.data import DriveLog
from ...soilmodel.errors import DataError
from ...soilmodel.soil import PRACTICAL_BOUNDS, SoilBounds
from ...soilmodel.vehicle import Vehicle
from .nlp import fmax_bounds, ridge_point
from .prepare import prepare_drive_log
from ..estimates.result import FitResult, build_result

__all__ = ["BIAS_CORRECTIONS", "SIMEX_LAMBDAS", "simex_fit"]

#: Bias corrections of :func:`fit_drive_log` (``None`` means none).
BIAS_CORRECTIONS = ("simex",)
#: Extra vehicle-speed noise levels of SIMEX, in units of the estimated noise variance.
SIMEX_LAMBDAS = (0.5, 1.0, 2.0)
#: SIMEX refits use the sample selection of the uncorrected fit.
_SIMEX_FIXED_SELECTION = True


def _simex_weights(lambdas=(0.0,) + SIMEX_LAMBDAS, at: float = -1.0) -> np.ndarray:
    """Weights ``c`` with ``sum c_j y_j`` = the least-squares quadratic in lambda through ``y_j``, at ``at``."""
    lam = np.asarray(lambdas, dtype=float)
    X = np.column_stack([np.ones_like(lam), lam, lam**2])
    return np.array([1.0, at, at * at]) @ np.linalg.pinv(X)


def simex_fit(
    fit_fn: Callable[..., FitResult],
    log: DriveLog,
    vehicle: Vehicle,
    model: str,
    bounds: SoilBounds | None,
    x0,
    strict: bool,
    method: str,
    formulation: str,
    bias_correction: str,
    options: dict,
) -> FitResult:
    """Uncorrected fit, then :func:`_simex_correct` (see there); entry of ``fit_drive_log(bias_correction=...)``.

    ``fit_fn`` is the uncorrected drive-log fit (``fit_drive_log``, passed in by its caller).
    """
    if bias_correction not in BIAS_CORRECTIONS:
        raise DataError(f"unknown bias_correction {bias_correction!r}; expected None or one of {BIAS_CORRECTIONS}")
    if formulation != "output-error":
        raise DataError("bias_correction is only available for the output-error formulation")
    options = dict(options)
    n_rep = options.pop("simex_replicates", 4)
    seed = options.pop("simex_seed", 0)
    if isinstance(n_rep, bool) or not isinstance(n_rep, int) or n_rep < 2 or n_rep % 2:
        raise DataError(f"simex_replicates must be an even integer >= 2, got {n_rep!r}")
    t0 = _time.perf_counter()
    base = fit_fn(log, vehicle, model, bounds, x0, strict, method=method, formulation=formulation, **options)
    if not base.success:
        return base
    return _simex_correct(
        fit_fn,
        base,
        log,
        vehicle,
        model,
        bounds if bounds is not None else PRACTICAL_BOUNDS,
        x0,
        method,
        options,
        n_rep,
        seed,
        t0,
    )


def _simex_correct(
    fit_fn: Callable[..., FitResult],
    base: FitResult,
    log: DriveLog,
    vehicle: Vehicle,
    model: str,
    bounds: SoilBounds,
    x0,
    method: str,
    options: dict,
    n_rep: int,
    seed: int,
    t0: float,
) -> FitResult:
    """SIMEX correction of F_max and K for the vehicle-speed (GNSS) noise.

    The bias of the output-error fit grows with the vehicle-speed noise variance (an
    error-in-variables effect of the latent per-sample slips; see the module docstring).
    SIMEX measures that growth on the log itself: white Gaussian noise of variance
    ``lambda sigma_v^2`` (``sigma_v`` the noise model estimated from the log, or the given
    ``sigma_vehicle_speed``) is added to the vehicle speed for ``lambda`` in
    :data:`SIMEX_LAMBDAS`, the log is refitted (``simex_replicates`` times per level, in
    antithetic pairs ``+-z`` sharing the draws across the levels), and a quadratic in
    ``lambda`` fitted by least squares to the estimate at ``lambda = 0`` and the replicate
    means is extrapolated to ``lambda = -1`` (no speed noise).

    Applied only to ``"hard"`` logs (F_max and K both pinned down, neither on a bound); for
    gentle and intermediate logs the result is the uncorrected fit with
    ``extra["bias_correction"]["applied"] = False``, the reason, and a warning.

    Covariance of the corrected estimate: the sandwich covariance of the uncorrected fit plus
    the Monte Carlo variance of the extrapolation (from the spread of the per-pair
    extrapolations); the reported standard errors and intervals of F_max and K are those of
    this sum, centred on the corrected estimate (Jacobian rescaled as for the sandwich). The
    residuals and the regime are those of the uncorrected fit.
    """
    if base.extra.get("regime") != "hard":
        # Gentle or intermediate log (K, or F_max and K together, poorly determined, or on a bound):
        # the refitted K wanders over its range or sits on a bound, the extrapolation is no bias
        # estimate (measured, heavy vehicle on LETE sand: it cost F_max coverage). Not applied.
        return _not_applied(
            base,
            {"replicates": 0, "reason": f"{base.extra.get('regime')} log: only applied to hard logs"},
            f"SIMEX bias correction not applied: {base.extra.get('regime')} log (F_max and K not both pinned "
            f"down, see above); estimates uncorrected",
            t0,
        )
    W = vehicle.weight
    c0, phi0, K0 = (float(z) for z in base.theta)
    jac0 = np.asarray(base.jacobian, dtype=float)
    dFm_dphi0 = W / math.cos(phi0) ** 2
    J2 = np.column_stack([jac0[:, 1] / dFm_dphi0, jac0[:, 2]])
    F0 = float(base.extra["max_thrust_N"])
    if base.s2 is None:  # impossible: a successful hard-log fit has its residual variance
        raise RuntimeError("SIMEX: the uncorrected fit has no residual variance s2")
    s2 = float(base.s2)
    cov0 = s2 * np.linalg.inv(J2.T @ J2)
    est, n_fail = _refits(fit_fn, base, log, vehicle, model, bounds, method, options, n_rep, seed)
    if n_fail:
        # a failed refit would bias the level means; keep the uncorrected fit and say so
        return _not_applied(
            base,
            {"replicates": n_rep, "failed_refits": n_fail},
            f"SIMEX bias correction not applied: {n_fail} of {3 * n_rep} refits failed; estimates uncorrected",
            t0,
        )
    pairs = n_rep // 2
    corrected, level_means, cov_mc = _extrapolate(est, np.array([F0, K0]), pairs)
    cov = cov0 + cov_mc
    Fb = fmax_bounds(bounds, vehicle, model)
    Kb = tuple(bounds.shear_modulus)
    Fc = min(max(float(corrected[0]), Fb[0]), Fb[1])
    Kc = min(max(float(corrected[1]), Kb[0]), Kb[1])

    # Jacobian in (F_max, K) rescaled so that s2 (J^T J)^-1 = cov, then the chain rule to (c, phi, K)
    R = np.linalg.solve(np.linalg.cholesky(J2.T @ J2).T, np.linalg.cholesky(s2 * np.linalg.inv(cov)).T)
    J2c = J2 @ R
    c_hint = None
    if x0 is not None and model == "full":
        c_hint = float(np.asarray(x0.as_vector() if hasattr(x0, "as_vector") else x0, dtype=float).reshape(-1)[0])
    c, phi = ridge_point(Fc, vehicle, bounds, model, c_hint)
    A = vehicle.contact_area
    jac = np.column_stack([J2c[:, 0] * (A if model == "full" else 0.0), J2c[:, 0] * W / math.cos(phi) ** 2, J2c[:, 1]])
    info = {
        "method": "simex",
        "applied": True,
        "lambdas": list(SIMEX_LAMBDAS),
        "replicates": n_rep,
        "antithetic_pairs": pairs,
        "seed": seed,
        "extrapolation": "quadratic in lambda, to -1",
        "uncorrected": {
            "max_thrust_N": F0,
            "shear_modulus_m": K0,
            "max_thrust_stderr_N": math.sqrt(cov0[0, 0]),
            "shear_modulus_stderr_m": math.sqrt(cov0[1, 1]),
        },
        "correction": {"max_thrust_N": Fc - F0, "shear_modulus_m": Kc - K0},
        "level_means": {
            "max_thrust_N": level_means[:, 0].tolist(),
            "shear_modulus_m": level_means[:, 1].tolist(),
        },
        "monte_carlo_stderr": {
            "max_thrust_N": math.sqrt(cov_mc[0, 0]),
            "shear_modulus_m": math.sqrt(cov_mc[1, 1]),
        },
        "covariance": "uncorrected sandwich + Monte Carlo variance of the extrapolation",
        "time_s": _time.perf_counter() - t0,
    }
    return _corrected_result(base, vehicle, model, bounds, method, (c, phi, Fc, Kc), cov, jac, info)


def _not_applied(base: FitResult, info: dict, warning: str, t0: float) -> FitResult:
    """The uncorrected fit, its ``extra["bias_correction"]`` saying why the correction was not applied."""
    extra = dict(base.extra)
    extra["bias_correction"] = {"method": "simex", "applied": False, **info, "time_s": _time.perf_counter() - t0}
    return dataclasses.replace(base, extra=extra, input_warnings=tuple(base.input_warnings) + (warning,))


def _refits(fit_fn, base, log, vehicle, model, bounds, method, options, n_rep, seed) -> tuple[np.ndarray, int]:
    """Refit the log with added speed noise at each level in antithetic pairs: ``(estimates, failed refits)``.

    The estimates are indexed (pair, sign, level, (F_max, K)).
    """
    nm = base.extra["noise_model"]["vehicle_speed_m_s"]
    v = np.asarray(log.vehicle_speed, dtype=float)
    given = options.get("sigma_vehicle_speed")
    sig_v = np.full(v.size, float(given)) if given is not None else np.sqrt(nm["abs"] ** 2 + (nm["rel"] * v) ** 2)
    keep = None
    if _SIMEX_FIXED_SELECTION:  # the uncorrected fit's samples (the speed floor would rise with the added noise)
        keep = prepare_drive_log(
            log,
            vehicle,
            sigma_torque=options.get("sigma_torque"),
            sigma_sprocket_speed=options.get("sigma_sprocket_speed"),
            sigma_vehicle_speed=given,
            torque_hold=str(options.get("torque_hold", "zoh")),
            min_speed=options.get("min_speed", 0.0),
            sprocket_equation=str(options.get("sprocket_equation", "thrust")),
        ).keep
    rng = np.random.default_rng(seed)
    pairs = n_rep // 2
    z = rng.standard_normal((pairs, v.size))
    est = np.full((pairs, 2, len(SIMEX_LAMBDAS), 2), np.nan)  # pair, sign, level, (F_max, K)
    n_fail = 0
    for p in range(pairs):
        for si, sign in enumerate((1.0, -1.0)):
            for j, lam in enumerate(SIMEX_LAMBDAS):
                opts = dict(options)
                if keep is not None:
                    opts["_fixed_keep"] = keep
                if given is not None:
                    opts["sigma_vehicle_speed"] = float(given) * math.sqrt(1.0 + lam)
                noisy = dataclasses.replace(log, vehicle_speed=v + sign * math.sqrt(lam) * sig_v * z[p])
                try:
                    r = fit_fn(noisy, vehicle, model, bounds, base.theta, False, method=method, **opts)
                except DataError:
                    r = None
                if r is None or not r.success:
                    n_fail += 1
                    continue
                est[p, si, j] = (r.extra["max_thrust_N"], r.extra["shear_modulus_m"])
    return est, n_fail


def _extrapolate(est: np.ndarray, theta0: np.ndarray, pairs: int):
    """The quadratic extrapolation to no noise, the level means and the Monte Carlo covariance."""
    w = _simex_weights()
    per_pair = est.mean(axis=1)  # pair, level, param (antithetic means)
    level_means = per_pair.mean(axis=0)  # level, param
    corrected = w[0] * theta0 + w[1:] @ level_means
    e_p = w[0] * theta0 + np.einsum("j,pjk->pk", w[1:], per_pair)
    cov_mc = (np.cov(e_p.T, ddof=1) / pairs) if pairs > 1 else np.zeros((2, 2))
    if pairs == 1:  # one pair: the antithetic halves give a (conservative) spread
        e_h = w[0] * theta0 + np.einsum("j,sjk->sk", w[1:], est[0])
        cov_mc = np.cov(e_h.T, ddof=1) / 2.0
    return corrected, level_means, cov_mc


def _corrected_result(base, vehicle, model, bounds, method, sol: tuple, cov, jac, info: dict) -> FitResult:
    """The corrected fit: its combinations, standard errors and ``extra["bias_correction"]``."""
    c, phi, Fc, Kc = sol
    W, l = vehicle.weight, vehicle.track_length
    sF, sK = math.sqrt(cov[0, 0]), math.sqrt(cov[1, 1])
    gslope = np.array([l / (2 * Kc), -Fc * l / (2 * Kc * Kc)])
    extra = dict(base.extra)
    extra.update(
        {
            "max_thrust_N": Fc,
            "shear_modulus_m": Kc,
            "initial_slope_N": Fc * l / (2 * Kc),
            "max_thrust_stderr_N": sF,
            "shear_modulus_stderr_m": sK,
            "corr_max_thrust_shear_modulus": float(cov[0, 1] / (sF * sK)),
            "initial_slope_stderr_N": float(math.sqrt(max(gslope @ cov @ gslope, 0.0))),
            "covariance": f"{base.extra['covariance']}+simex",
            "bias_correction": info,
        }
    )
    n_rep = info["replicates"]
    msg = f"{base.message}; SIMEX-corrected: F_max = {Fc:.5g} N, K = {1000 * Kc:.4g} mm ({3 * n_rep} refits)"
    return build_result(
        data_kind="drive",
        model=model,
        method=method,
        theta=np.array([c, phi, Kc]),
        jacobian=jac,
        weighted_residuals=base.weighted_residuals,
        residuals=base.residuals,
        residual_unit=base.residual_unit,
        n_samples=base.n_samples,
        normal_loads=np.full(base.n_samples, W),
        vehicle=vehicle,
        bounds=bounds,
        status=base.status,
        success=True,
        message=msg,
        iterations=base.iterations,
        solve_time=base.solve_time,
        sigma_known=base.sigma_known,
        warnings=tuple(base.input_warnings),
        extra=extra,
    )
