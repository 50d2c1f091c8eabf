"""Joint drive-log fit: soil (thrust limit, K) and effect parameters with three residual channels.

The problem is stated in :mod:`.joint`; this module solves it, computes the sandwich
covariance from CasADi's exact per-sample derivatives, judges identifiability (eigenvalues of the
information, correlations) and builds the :class:`~..estimates.result.FitResult`. The soil part goes through
:func:`~..estimates.result.build_result` as for the nominal fit (marginal covariance of ``F_lim`` and K,
i.e. with the effect parameters' uncertainty included); the effect parameters are reported in
``extra["effects"]`` as ``{effect: {param: {value, stderr, ci95, identifiable, at_bound,
correlated_with}}}``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...soilmodel.data import DriveLog
from ...soilmodel.effects import EFFECTS, effect_structure, parse_effects
from ...soilmodel.errors import DataError
from ...soilmodel.soil import SoilBounds
from ...soilmodel.vehicle import Vehicle
from .joint import (
    CHANNELS,
    HULL_ROW,
    best_slips,
    effect_layout,
    joint_data,
    joint_solver,
    nlp_backend,
    padded_data,
    parse_fixed,
    residual_function,
    sample_outputs,
)
from .nlp import g_inverse, pad, run_starts, fmax_bounds, padded_size, ridge_point
from .prepare import SLIP_BOUNDS, PreparedLog
from .lm_start import profiled_start
from .regime import classify_regime
from .residuals import DriveLogResiduals
from ..estimates.result import WEAK_CORRELATION, FitResult, build_result

__all__ = ["fit_joint", "NULL_EIG_TOL", "CONFUSED_CORRELATION"]

#: Correlation beyond which an effect parameter is said to be confounded with another estimate.
CONFUSED_CORRELATION = 0.95
#: Relative eigenvalue of the (scaled) information below which a direction is not identifiable.
NULL_EIG_TOL = 1e-10


def _load_factor_range(labels: list[str], lo: np.ndarray, hi: np.ndarray) -> tuple[float, float]:
    """Smallest and largest ``N / W`` the effect bounds allow (grade's cos, mass_error's 1 + delta)."""
    fmin, fmax_ = 1.0, 1.0
    for lab, a, b in zip(labels, lo, hi):
        if lab == "grade.theta_rad":
            fmin *= math.cos(max(abs(a), abs(b)))
        elif lab == "mass_error.delta":
            fmin *= 1 + a
            fmax_ *= 1 + b
    return fmin, fmax_


def fit_joint(
    log: DriveLog,
    vehicle: Vehicle,
    prep: PreparedLog,
    model: str,
    bounds: SoilBounds,
    effects: Any,
    fixed: Any,
    starts: list[tuple[float, float]],
    c_hint: float | None,
    method: str,
    options: dict,
    base_extra: dict,
    base_warnings: list[str],
) -> tuple[FitResult, bool]:
    """Solve the joint problem and build the result; returns ``(result, success)``."""
    if str(options.get("sprocket_equation", "thrust")) != "thrust":
        raise DataError(
            "effects and the hull channel need sprocket_equation='thrust' (the seed's printed "
            "Eq. 3 mixes the resistance into the sprocket equation)"
        )
    jp = _joint_problem(log, vehicle, prep, model, bounds, effects, fixed, options)
    best, presolved, lbx, ubx = _solve_joint(vehicle, prep, jp, starts, options)
    labels, structure, n, W = jp.labels, jp.structure, jp.n, vehicle.weight
    xs = np.clip(best["x"], lbx, ubx)  # IPOPT may end a hair outside a bound (bound relaxation)
    pd = 2 + len(labels)
    theta = xs[:pd] * jp.scale
    slip = xs[pd : pd + n] * jp.i_ref
    Flim, K = float(theta[0]), float(theta[1])
    evals = dict(zip(labels, theta[2:].tolist()))

    # residuals and derivatives at the solution (CasADi AD, mapped over the samples)
    e, Jt, gi, H = sample_outputs(vehicle, structure, "derivative", theta, slip, jp.jd.D)
    e = e.T  # (n, 3)
    Jt = Jt.reshape(3, n, pd).transpose(1, 0, 2)  # (n, 3, pd)
    gi = gi.T  # (n, 3)
    H = H.reshape(pd + 1, n, pd + 1).transpose(1, 0, 2)
    raw = sample_outputs(vehicle, structure, "residual", theta, slip, jp.jd.D)[1].T

    free = ~np.concatenate([[False, False], jp.is_fixed])
    cov_full, ident, A = _sandwich(e, Jt, H, slip, free)
    finite = bool(np.all(np.isfinite(theta)) and np.all(np.isfinite(e)))
    success = bool(best["ok"] and finite)

    wres = -np.sign(e[:, 1] + e[:, 2]) * np.sqrt(np.sum(e**2, axis=1))
    res = -raw[:, 0]  # predicted minus encoder, rad/s: model - data, as the nominal fit's (and every fit's)
    Nload = _actual_load(W, evals)
    extra = _joint_extra(jp, base_extra, best, presolved, raw, (Flim, K, evals, Nload))
    units = [EFFECTS[lab.partition(".")[0]].param(lab.partition(".")[2]).unit for lab in labels]
    common = dict(
        data_kind="drive",
        model=model,
        method=method,
        residual_unit="rad/s",
        n_samples=n,
        vehicle=vehicle,
        bounds=bounds,
        status=best["status"],
        iterations=best["iterations"],
        solve_time=best["time"],
        sigma_known=prep.sigma_known,
        effect_labels=tuple(labels),
        effect_values=theta[2:],
        effect_bounds=tuple(zip(jp.elo.tolist(), jp.ehi.tolist())),
        effect_units=tuple(units),
        effect_structure=structure,
        fixed_labels=tuple(lab for lab in labels if lab in jp.fixed_vals),
        residual_model=DriveLogResiduals(hull_in_fit=jp.hull_used),
        normal_loads=np.full(n, W),
        extra=extra,
    )
    if not success:
        extra["covariance"] = "none"
        msg = f"drive-log fit with effects failed: IPOPT returned {best['status']}" + (
            "" if finite else " with non-finite values"
        )
        return build_result(
            theta=np.full(3, np.nan),
            jacobian=np.zeros((n, 3 + len(labels))),
            weighted_residuals=np.where(np.isfinite(wres), wres, 0.0),
            residuals=np.where(np.isfinite(res), res, 0.0),
            success=False,
            message=msg,
            warnings=tuple(base_warnings),
            **common,
        ), False
    sens = _Sensitivities(Jt, gi, free, ident, cov_full, A)
    return _converged_joint(
        vehicle,
        prep,
        jp,
        (model, bounds, c_hint),
        (Flim, K, evals, Nload, slip, wres, res),
        sens,
        list(base_warnings),
        common,
    ), True


@dataclass(frozen=True)
class _JointProblem:
    """The joint problem of one log, scaled for IPOPT (between :func:`_joint_problem` and the solve)."""

    structure: Any  #: the effects' structure (:func:`~soiltrack.soilmodel.effects.effect_structure`)
    labels: list[str]  #: effect parameter labels ``effect.param``
    fixed_vals: dict  #: held effect parameters and their values
    jd: Any  #: the joint data (three channels, noise, acceleration source)
    hull_used: bool  #: whether the hull channel is in the fit
    torque_hold: str  #: "zoh" or "sample"
    n: int  #: samples used
    N: int  #: padded size of the per-sample maps
    elo: np.ndarray  #: lower bounds of the effect parameters
    ehi: np.ndarray  #: upper bounds of the effect parameters
    esc: np.ndarray  #: scales of the effect parameters
    Fb: tuple  #: bounds of the thrust limit (N), widened by the load factor the effects allow
    Kb: tuple  #: bounds of K (m)
    F_ref: float  #: scale of the thrust limit
    K_ref: float  #: scale of K
    i_ref: float  #: scale of the latent slips (K_ref / l)
    scale: np.ndarray  #: scales of (F_lim, K, effects)
    e0: np.ndarray  #: start of the effect parameters (held ones at their values)
    is_fixed: np.ndarray  #: which effect parameters are held
    e_lo: np.ndarray  #: lower bounds of the effects, held ones pinned
    e_hi: np.ndarray  #: upper bounds of the effects, held ones pinned
    max_iter: int  #: IPOPT iterations
    tol: float  #: IPOPT tolerance
    print_level: int  #: IPOPT print level


@dataclass(frozen=True)
class _Sensitivities:
    """Per-sample derivatives and the sandwich covariance at the joint solution."""

    Jt: np.ndarray  #: (n, 3, p) residual derivatives in the parameters
    gi: np.ndarray  #: (n, 3) residual derivatives in the latent slip
    free: np.ndarray  #: which of (F_lim, K, effects) are free
    ident: np.ndarray  #: which free directions are identifiable
    cov_full: np.ndarray | None  #: sandwich covariance of the free parameters
    A: np.ndarray  #: the observed information


def _joint_problem(log, vehicle, prep, model, bounds, effects, fixed, options) -> _JointProblem:
    """State the joint problem: effects and their bounds, the data channels, scales and start of the effects."""
    fixed_vals = parse_fixed(fixed)
    names = set(_fixed_names(fixed_vals))
    es = parse_effects(effects)
    if names - set(es.names):
        es = parse_effects({**es.to_dict(), **{n: None for n in names - set(es.names)}})
    structure = effect_structure(es, vehicle)
    _, fn_labels = residual_function(vehicle, structure)
    labels = list(fn_labels)
    torque_hold = str(options.get("torque_hold", "zoh"))
    jd = joint_data(log, vehicle, prep, sigma_accel=options.get("sigma_accel"))
    hull_used = options.get("hull_channel", True) is not False
    if not hull_used:  # explicitly off: effects fitted from the speed and thrust channels only
        jd.D[HULL_ROW] = 0.0
    n = prep.n_used
    N = padded_size(n)
    l = vehicle.track_length
    max_iter = int(options.get("max_iter", 500))
    tol = float(options.get("tol", 1e-9))
    print_level = int(options.get("print_level", 0))

    elo, ehi, esc = effect_layout(labels, vehicle)
    lf_lo, lf_hi = _load_factor_range(labels, elo, ehi)
    Fb0 = fmax_bounds(bounds, vehicle, model)
    Fb = (Fb0[0] * lf_lo, Fb0[1] * lf_hi)
    Kb = tuple(bounds.shear_modulus)
    F_ref = 0.5 * (Fb[0] + Fb[1])
    K_ref = math.sqrt(Kb[0] * Kb[1])
    i_ref = K_ref / l
    scale = np.concatenate([[F_ref, K_ref], esc])
    # start of the effect parameters: given values (effects=...), else the off values; fixed ones pinned
    e0 = np.array([es.value(lab.split(".")[0], lab.split(".")[1], vehicle) for lab in labels], dtype=float)
    is_fixed = np.array([lab in fixed_vals for lab in labels], dtype=bool)
    for j, lab in enumerate(labels):
        if lab in fixed_vals:
            e0[j] = fixed_vals[lab]
    e_lo = np.where(is_fixed, e0, elo)
    e_hi = np.where(is_fixed, e0, ehi)
    e0 = np.clip(e0, np.where(np.isfinite(elo), elo, -1e300), np.where(np.isfinite(ehi), ehi, 1e300))
    return _JointProblem(
        structure,
        labels,
        fixed_vals,
        jd,
        hull_used,
        torque_hold,
        n,
        N,
        elo,
        ehi,
        esc,
        Fb,
        Kb,
        F_ref,
        K_ref,
        i_ref,
        scale,
        e0,
        is_fixed,
        e_lo,
        e_hi,
        max_iter,
        tol,
        print_level,
    )


def _solve_joint(vehicle: Vehicle, prep: PreparedLog, jp: _JointProblem, starts: list, options: dict):
    """Run IPOPT from the start points (profiled steps first unless switched off); ``(best, presolved, lbx, ubx)``."""
    structure, jd, n, N, l = jp.structure, jp.jd, jp.n, jp.N, vehicle.track_length
    Fb, Kb, F_ref, K_ref, i_ref, esc, scale, e0 = jp.Fb, jp.Kb, jp.F_ref, jp.K_ref, jp.i_ref, jp.esc, jp.scale, jp.e0
    e_lo, e_hi = jp.e_lo, jp.e_hi
    # the per-sample functions from C once the background compilation has them (the same numbers)
    solver = joint_solver(
        vehicle, structure, N, jp.max_iter, jp.tol, jp.print_level, nlp_backend(vehicle, structure, N)
    )
    Dp = padded_data(jd.D, N)
    p = np.concatenate([scale, [i_ref], Dp.reshape(-1, order="F"), pad(np.zeros(n), N, 1.0)])
    big = 1e20
    lbx = np.concatenate(
        [
            [Fb[0] / F_ref, Kb[0] / K_ref],
            np.where(np.isfinite(e_lo), e_lo / esc, -big),
            np.full(N, SLIP_BOUNDS[0] / i_ref),
        ]
    )
    ubx = np.concatenate(
        [
            [Fb[1] / F_ref, Kb[1] / K_ref],
            np.where(np.isfinite(e_hi), e_hi / esc, big),
            np.full(N, SLIP_BOUNDS[1] / i_ref),
        ]
    )

    lo_s, hi_s = SLIP_BOUNDS[0] + 1e-3, SLIP_BOUNDS[1] - 1e-3
    slip_meas = np.clip(prep.slip_measured, lo_s, hi_s)

    # the start: a few profiled Levenberg-Marquardt steps (drivelog_profiled); profiled_start=False (a warm start
    # from a nearby answer, e.g. the diagnosis's refits) or "_plain_start" (tests) skips them
    profiled = bool(options.get("profiled_start", True)) and not options.get("_plain_start", False)
    presolved: list = []
    th_lo = np.concatenate([[Fb[0], Kb[0]], np.where(np.isfinite(e_lo), e_lo, -big * esc)])
    th_hi = np.concatenate([[Fb[1], Kb[1]], np.where(np.isfinite(e_hi), e_hi, big * esc)])

    def start_maker(with_profile: bool):
        def make_x0(Fmax0: float, K0: float) -> np.ndarray:
            # latent slips from the inverse thrust-slip curve and from the measured slip (the per-sample cost
            # can have two minima); then the profiled steps, or 6 Newton steps of the slips at the start values
            y = np.clip(np.abs(prep.thrust) / Fmax0, 0.0, 0.98)
            slip_inv = np.clip(np.sign(prep.thrust) * g_inverse(y) * K0 / l, lo_s, hi_s)
            th0 = np.concatenate([[Fmax0, K0], e0])
            if with_profile:
                ps = profiled_start(vehicle, structure, jd.D, th0, th_lo, th_hi, scale, [slip_inv, slip_meas])
                presolved.append(ps)
                return np.concatenate([ps.theta / scale, pad(np.clip(ps.slip, lo_s, hi_s) / i_ref, N)])
            slip0 = np.clip(best_slips(vehicle, structure, th0, jd.D, [slip_inv, slip_meas], 6), lo_s, hi_s)
            return np.concatenate([[Fmax0 / F_ref, K0 / K_ref], e0 / esc, pad(slip0 / i_ref, N)])

        return make_x0

    starts = [(min(max(F0, Fb[0] * 1.001), Fb[1] * 0.999), K0) for F0, K0 in starts]
    best = run_starts(solver, start_maker(profiled), p, lbx, ubx, starts, Fb, Kb, F_ref, K_ref)
    if profiled and not best["ok"]:
        # IPOPT from the profiled start did not certify it (seen on noise-free logs: the search direction
        # "too small" at a point it could not improve): the plain starts, as without the profiled steps
        plain = run_starts(solver, start_maker(False), p, lbx, ubx, starts, Fb, Kb, F_ref, K_ref)
        plain["time"] += best["time"]
        plain["profiled_status"] = best["status"]
        best = plain if (plain["ok"], -plain["f"]) >= (best["ok"], -best["f"]) else best
    return best, presolved, lbx, ubx


def _joint_extra(jp: _JointProblem, base_extra: dict, best: dict, presolved: list, raw: np.ndarray, sol: tuple):
    """The result's ``extra``: the hull channel, the profiled start, channel rms, load and joint parameters."""
    Flim, K, evals, Nload = sol
    jd = jp.jd
    extra = dict(base_extra)
    extra["hull_channel"] = {
        "used": jp.hull_used,
        "accel_source": jd.accel_source,
        "accel_noise_m_s2": {"abs": jd.accel_noise[0], "rel": jd.accel_noise[1]},
        "sigma_hull_median_N": float(np.median(jd.sigma_hull[np.isfinite(jd.sigma_hull)]))
        if np.any(np.isfinite(jd.sigma_hull))
        else None,
    }
    if presolved:
        extra["profiled_start"] = {
            "steps": [{"iterations": ps.iterations, "converged": ps.converged} for ps in presolved],
            "ipopt_status_from_it": best.get("profiled_status", best["status"]),
        }
    extra["channel_rms"] = {ch: float(np.sqrt(np.mean(raw[:, j] ** 2))) for j, ch in enumerate(CHANNELS)}
    extra["normal_load_N"] = Nload
    extra["joint_parameters"] = {
        "max_thrust_N": Flim,
        "shear_modulus_m": K,
        "effects": evals,
        "structure": jp.structure.to_dict(),
        "torque_hold": jp.torque_hold,
    }
    return extra


def _converged_joint(
    vehicle: Vehicle,
    prep: PreparedLog,
    jp: _JointProblem,
    call: tuple,
    sol: tuple,
    sens: _Sensitivities,
    warnings: list[str],
    common: dict,
) -> FitResult:
    """The converged joint fit: covariance kind, (c, phi) on the ridge, confounding, the regime."""
    model, bounds, c_hint = call
    Flim, K, evals, Nload, slip, wres, res = sol
    labels, n, l, Fb, Kb, extra = jp.labels, jp.n, vehicle.track_length, jp.Fb, jp.Kb, common["extra"]
    dof = max(n - int(np.count_nonzero(sens.free)), 1)
    s2 = 1.0 if prep.sigma_known else float(np.sum(wres**2)) / dof
    Jr, cov2, kind = _result_jacobian(sens.Jt, sens.gi, sens.free, sens.ident, sens.cov_full, s2)
    extra["covariance"] = kind
    c, phi = ridge_point(Flim, vehicle, bounds, model, c_hint, normal_load=Nload)
    dFm_dc = vehicle.contact_area if model == "full" else 0.0
    jac = np.column_stack([Jr[:, 0] * dFm_dc, Jr[:, 0] * (Nload / math.cos(phi) ** 2), Jr[:, 1:]])

    warnings.extend(_confounding_warnings(labels, jp.is_fixed, sens.free, sens.ident, sens.cov_full, sens.A))

    # soil combinations and the regime (marginal over the effects)
    Fb_hit = [
        nm
        for nm, val, (lo, hi) in (("F_max", Flim, Fb), ("K", K, Kb))
        if val <= lo + 1e-6 * (hi - lo) or val >= hi - 1e-6 * (hi - lo)
    ]
    sT = prep.sigma_thrust
    thrust_peak = float(max(np.max(prep.thrust - 2.0 * sT), 0.0))
    utilisation = thrust_peak / Flim
    n_high = int(np.count_nonzero(prep.thrust - 2.0 * sT > 0.7 * Flim))
    extra.update(
        {
            "max_thrust_N": Flim,
            "shear_modulus_m": K,
            "initial_slope_N": Flim * l / (2 * K),
            "thrust_peak_N": thrust_peak,
            "thrust_utilisation": utilisation,
            "samples_above_70pct": n_high,
            "slip_max": float(np.max(slip)),
            "reduced_chi2": float(np.sum(wres**2)) / dof,
        }
    )
    regime, regime_extra, regime_warnings = classify_regime(Flim, K, l, cov2, Fb_hit, thrust_peak, utilisation, n_high)
    extra.update(regime_extra)
    warnings.extend(regime_warnings)
    eff_txt = ", ".join(f"{lab} = {evals[lab]:.4g}" for lab in labels) or "none"
    msg = (
        f"drive-log fit with effects converged: F_max = {Flim:.5g} N (at the log's normal load "
        f"{Nload:.5g} N), K = {1000 * K:.4g} mm, {eff_txt}; {regime} log, {n} samples, hull channel from "
        f"{jp.jd.accel_source}"
    )
    return build_result(
        theta=np.array([c, phi, K]),
        jacobian=jac,
        weighted_residuals=wres,
        residuals=res,
        success=True,
        message=msg,
        warnings=tuple(warnings),
        **common,
    )


def _result_jacobian(
    Jt: np.ndarray, gi: np.ndarray, free: np.ndarray, ident: np.ndarray, cov_full: np.ndarray | None, s2: float
) -> tuple[np.ndarray, np.ndarray | None, str]:
    """Jacobian in ``(F_lim, K, effects)`` for the shared result object, the (F_lim, K) covariance, its kind.

    A Gram-preserving stand-in ``Q S`` with ``S^T S`` the profiled Gauss-Newton information
    (only ``J^T J`` enters the statistics; the rows are not per-sample sensitivities), whose free
    block is then rescaled so that ``s2 (J^T J)^-1`` is the sandwich covariance (``"sandwich"``;
    ``"gauss-newton"`` when the sandwich does not exist for every free parameter).
    """
    Jp = Jt.copy()
    gn = np.sum(gi**2, axis=1)
    okg = gn > 1e-300
    Jp[okg] -= gi[okg, :, None] * (np.einsum("kc,kcp->kp", gi[okg], Jt[okg]) / gn[okg, None])[:, None, :]
    info = np.einsum("kcp,kcq->pq", Jp, Jp)
    wv, Uv = np.linalg.eigh(0.5 * (info + info.T))
    S = (Uv * np.sqrt(np.clip(wv, 0.0, None))) @ Uv.T
    Q, _ = np.linalg.qr(Jt[:, 1, :] + Jt[:, 2, :] + Jt[:, 0, :])
    Jr = Q @ S
    kind = "gauss-newton"
    fidx = np.nonzero(free)[0]
    if cov_full is not None and np.all(ident[fidx]):
        try:
            Jf = Jr[:, fidx]
            Lg = np.linalg.cholesky(Jf.T @ Jf)
            Lv = np.linalg.cholesky(s2 * np.linalg.inv(cov_full[np.ix_(fidx, fidx)]))
            Jr[:, fidx] = Jf @ np.linalg.solve(Lg.T, Lv.T)
            kind = "sandwich"
        except np.linalg.LinAlgError:
            pass
    if kind == "sandwich" and cov_full is not None:  # (the sandwich is set only with cov_full)
        return Jr, cov_full[:2, :2], kind
    try:
        return Jr, s2 * np.linalg.inv(Jr[:, :2].T @ Jr[:, :2]), kind
    except np.linalg.LinAlgError:
        return Jr, None, kind


def _confounding_warnings(
    labels: list[str],
    is_fixed: np.ndarray,
    free: np.ndarray,
    ident: np.ndarray,
    cov_full: np.ndarray | None,
    A: np.ndarray,
) -> list[str]:
    """Effect parameters confounded with the soil or another effect, in words, with the experiment.

    Correlations from the sandwich covariance, or, where a parameter is not estimable, the
    collinearity of the sensitivities (the information's ``A_ij / sqrt(A_ii A_jj)``).
    """
    warnings: list[str] = []
    all_labels = ["F_max", "K"] + list(labels)
    for j, lab in enumerate(labels):
        jj = 2 + j
        if is_fixed[j]:
            continue
        corr, kinds = {}, {}
        for k2, other in enumerate(all_labels):
            if k2 == jj or not free[k2]:
                continue
            if ident[jj] and ident[k2] and cov_full is not None and cov_full[jj, jj] > 0 and cov_full[k2, k2] > 0:
                rho, kind = float(cov_full[jj, k2] / math.sqrt(cov_full[jj, jj] * cov_full[k2, k2])), "correlation"
            elif A[jj, jj] > 0 and A[k2, k2] > 0:
                rho, kind = float(A[jj, k2] / math.sqrt(A[jj, jj] * A[k2, k2])), "collinearity of their effects"
            else:
                continue
            if abs(rho) >= CONFUSED_CORRELATION:
                corr[other], kinds[other] = rho, kind
        if ident[jj] and not corr:
            continue
        # (the result object states weak identifiability itself; this adds what separates them)
        txt = ", ".join(f"{o} ({kinds[o]} {r:+.3f})" for o, r in corr.items())
        hard = not ident[jj] or any(abs(r) >= WEAK_CORRELATION for r in corr.values())
        what = (
            f"{'cannot' if hard else 'can hardly'} be told apart from {txt}"
            if txt
            else "is not determined (the log carries no information on it)"
        )
        warnings.append(f"effect {lab} {what} on this log. {_separating_experiment(lab.partition('.')[0], corr)}")
    return warnings


def _fixed_names(fixed_vals: dict[str, float]) -> list[str]:
    """Effect names that appear in a parsed ``fixed`` mapping."""
    return sorted({lab.partition(".")[0] for lab in fixed_vals})


def _actual_load(W: float, evals: dict[str, float]) -> float:
    """``W (1 + delta) cos(theta)`` at the fitted effect values, N."""
    N = W * (1 + evals.get("mass_error.delta", 0.0))
    return N * math.cos(evals.get("grade.theta_rad", 0.0))


_SEPARATE = {
    frozenset({"grade", "mass_error"}): "A run at another payload, or with more acceleration and braking, separates "
    "mass_error (scales with dv/dt) from grade (constant).",
    frozenset({"grade", "drivetrain_friction"}): "Runs at different speeds and torque levels separate a constant "
    "resistance from a torque loss in the drivetrain.",
    frozenset({"speed_resistance", "drivetrain_friction"}): "A run with the torque sensor checked on a rig, or at "
    "constant speed with different payloads, separates them.",
}


def _separating_experiment(name: str, correlated: dict[str, float]) -> str:
    for other in correlated:
        oname = other.partition(".")[0]
        key = frozenset({name, oname})
        if key in _SEPARATE:
            return _SEPARATE[key]
    if any(o in ("F_max", "K") for o in correlated):
        return (
            "A tractive force-slip sweep (or a log with a wider range of slip and thrust) separates it from the soil."
        )
    return "A log with more varied speed, acceleration and thrust would help."


def _sandwich(
    e: np.ndarray, Jt: np.ndarray, H: np.ndarray, slip: np.ndarray, free: np.ndarray
) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
    """Sandwich covariance of the free parameters with the latent slips profiled out.

    ``A = sum_k (H_tt - H_ti H_it / H_ii)`` (exact per-sample Hessian), ``B = sum_k psi_k psi_k^T``
    with ``psi_k = J_theta^T e_k``. Directions of the column-scaled ``A`` with relative eigenvalue
    below :data:`NULL_EIG_TOL` are not identifiable; parameters with a component there are
    marked so. Returns ``(V (full size, zeros for fixed), identifiable flags, A)``.
    """
    pd = Jt.shape[2]
    lo, hi = SLIP_BOUNDS
    Hii = H[:, pd, pd]
    freek = (slip > lo + 1e-6) & (slip < hi - 1e-6) & (Hii > 1e-12 * np.max(np.abs(Hii)))
    Hs = np.where(freek, Hii, 1.0)
    Htt = H[:, :pd, :pd]
    Hti = H[:, :pd, pd]
    cross = np.where(freek[:, None, None], Hti[:, :, None] * Hti[:, None, :] / Hs[:, None, None], 0.0)
    A = np.sum(Htt - cross, axis=0)
    psi = np.einsum("kc,kcp->kp", e, Jt)
    B = psi.T @ psi
    idx = np.nonzero(free)[0]
    ident = np.zeros(pd, dtype=bool)
    Af, Bf = A[np.ix_(idx, idx)], B[np.ix_(idx, idx)]
    if not (np.all(np.isfinite(Af)) and np.all(np.isfinite(Bf))):
        return None, ident, A
    d = np.sqrt(np.maximum(np.abs(np.diag(Af)), 1e-300))
    As = Af / np.outer(d, d)
    w, U = np.linalg.eigh(0.5 * (As + As.T))
    if w[-1] <= 0:
        return None, ident, A
    null = w < NULL_EIG_TOL * w[-1]
    ok = np.ones(idx.size, dtype=bool)
    if np.any(null):
        ok = np.linalg.norm(U[:, null], axis=1) < 1e-6
    keep = idx[ok]
    ident[keep] = True
    if keep.size == 0:
        return None, ident, A
    Ak, Bk = A[np.ix_(keep, keep)], B[np.ix_(keep, keep)]
    try:
        Ai = np.linalg.inv(Ak)
    except np.linalg.LinAlgError:
        ident[:] = False
        return None, ident, A
    Vk = Ai @ Bk @ Ai
    Vk = 0.5 * (Vk + Vk.T)
    if not np.all(np.isfinite(Vk)) or np.any(np.linalg.eigvalsh(Vk) <= 0) or np.any(np.linalg.eigvalsh(Ak) <= 0):
        ident[:] = False
        return None, ident, A
    V = np.zeros((pd, pd))
    V[np.ix_(keep, keep)] = Vk
    return V, ident, A
