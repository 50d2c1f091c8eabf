"""Joint fit of the soil and named effects to a slip sweep, with IPOPT.

The NLP is built ONCE per ``(vehicle, effects on, model, measured, rig speed, size class)`` and
cached (:func:`~soiltrack.soilmodel.threadsafe.locked_cache`); the data enter as parameters,
padded to the size class (:func:`padded_size`) with zero-weight samples, so that a diagnosis
refitting blocks of many lengths builds few solvers (a build costs 40-90 ms, a solve 10-20 ms). The
model is :func:`~soiltrack.identify.sweep.model.observation_function` (the soilmodel's
:func:`~soiltrack.soilmodel.effects.sweep_measurement`), mapped over the samples; residuals
and the Jacobian come from it by AD. Variables ``x = [c, phi, K, e...] / scale``, bounded by
the soil's practical ranges and each effect parameter's physical range
(:func:`~soiltrack.soilmodel.effects.parameter_bounds`). Held parameters (``fixed``, cohesion
of the cohesion-free model) have ``lbx = ubx`` and keep their Jacobian column in the result.
A pressure distribution keeps the pressure positive (``|e| + |alpha| <= 1`` as two linear
constraints). Start: the soil of the nominal variable-projection grid, the effects at the
values given (an ``EffectSet`` or dict) or their defaults (off; ``k_ratio`` 5).

At one normal load and without a non-uniform pressure (``hump_shear`` scales the whole shear
law, so it keeps the ridge), c and phi enter only through ``F_max = A c + N tan(phi)`` (N the
actual normal load). The NLP is then solved for ``F_max = N0 tan(phi_e)`` with c held at 0 and
phi_e spanning the F_max range of the bounds box (the same optimum, without the singular
Hessian along the ridge on which IPOPT otherwise wanders without certifying), and the
reported (c, phi) is the centre of the bounds-feasible ridge at the fitted F_max
(:func:`ridge_centre`), which leaves every prediction unchanged: the same marker as the
nominal fit's.
"""

from __future__ import annotations

import time
from typing import Any

import casadi as ca
import numpy as np

from ...soilmodel.effects import (
    EFFECTS,
    EffectSet,
    effect_symbols,
    normal_load_function,
    parameter_bounds,
    parameter_scale,
)
from ...soilmodel.ridge import fmax_range, one_load, ridge_centre
from ...soilmodel.threadsafe import call_solver, locked_cache, solver_status
from ...soilmodel.traction import max_thrust_expr
from ...soilmodel.vehicle import Vehicle
from .problem import SCALE, SlipProblem
from ..estimates.result import FitResult, build_result
from .start import start_point
from .model import SweepResiduals, observation_function, predict
from .plausibility import slip_checks

__all__ = ["fit_joint", "joint_layout", "padded_size"]

_DEFAULT_OPTS = {"ipopt.tol": 1e-12, "ipopt.acceptable_tol": 1e-8, "ipopt.max_iter": 500}


def padded_size(n: int) -> int:
    """Size class of ``n`` samples: a multiple of 8 up to 64, of 32 up to 512, then of 128."""
    step = 8 if n <= 64 else (32 if n <= 512 else 128)
    return -(-n // step) * step


def joint_layout(vehicle: Vehicle, structure: EffectSet) -> tuple[list[str], np.ndarray, np.ndarray, list[str]]:
    """Labels, bounds ``(m, 2)``, scales ``(m,)`` and units of the identifiable effect parameters."""
    labels = effect_symbols(structure, vehicle=vehicle)[2]
    bounds, scales, units = [], [], []
    for lab in labels:
        name, p = lab.split(".", 1)
        bounds.append(parameter_bounds(name, p, vehicle))
        scales.append(parameter_scale(name, p, vehicle))
        units.append(EFFECTS[name].param(p).unit)
    return labels, np.array(bounds, float).reshape(-1, 2), np.array(scales, float), units


@locked_cache(maxsize=64)
def _solver(
    vehicle: Vehicle, structure: EffectSet, model: str, measured: str, rig_speed: float, n: int, opts_key: tuple = ()
) -> ca.Function:
    labels, _, scales, _ = joint_layout(vehicle, structure)
    nx = 3 + len(labels)
    S = np.concatenate([SCALE, scales])
    X = ca.SX.sym("x", nx)
    P = ca.SX.sym("p", 4 * n + 1)
    slip, y, W, wt, scale = P[0:n], P[n : 2 * n], P[2 * n : 3 * n], P[3 * n : 4 * n], P[4 * n]
    obs = observation_function(vehicle, structure, model, measured, rig_speed)
    ym = obs.map(n)(slip.T, W.T, X * S)[0].T
    rw = (ym - y) * wt  # wt = 1 / sigma; 0 on padding
    f = 0.5 * ca.dot(rw, rw) / scale
    g = []
    if "pressure_distribution" in structure:
        ie, ia = 3 + labels.index("pressure_distribution.e"), 3 + labels.index("pressure_distribution.alpha")
        e, a = X[ie] * S[ie], X[ia] * S[ia]
        g = [e + a, e - a]
    nlp = {"x": X, "p": P, "f": f}
    if g:
        nlp["g"] = ca.vertcat(*g)
    opts: dict[str, Any] = {
        "expand": True,
        "print_time": False,
        "error_on_fail": False,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
    }
    opts.update(_DEFAULT_OPTS)
    opts.update(dict(opts_key))
    return ca.nlpsol(f"jointfit_{n}", "ipopt", nlp, opts)


def _separates_c_phi(structure: EffectSet, fixed: dict) -> bool:
    """Whether the effects let c and phi enter other than through F_max (only a non-uniform pressure does)."""
    if "pressure_distribution" not in structure:
        return False
    held = [fixed.get(f"pressure_distribution.{p}") for p in ("e", "alpha")]
    return not all(h is not None and h == 0.0 for h in held)


def fit_joint(
    pb: SlipProblem,
    x0=None,
    ipopt_options: dict | None = None,
    n_grid: int = 25,
    *,
    hold: dict | None = None,
    start_x=None,
) -> FitResult:
    """Fit the soil and the effects of ``pb`` jointly with IPOPT and build the result.

    ``hold``: ``{index in [c, phi, K, e...]: value (SI)}`` held during the solve (a profile
    point: :mod:`soiltrack.identify.estimates.joint_likelihood`); ``start_x``: a whole start vector
    ``[c, phi, K, e...]`` (SI), instead of the grid and the effects' defaults.
    """
    structure = pb.effects if pb.effects is not None else EffectSet()
    labels, eb, escale, units = joint_layout(pb.vehicle, structure)
    S = np.concatenate([SCALE, escale])
    key = tuple(sorted((ipopt_options or {}).items()))
    n_pad = padded_size(pb.n)
    solver = _solver(pb.vehicle, structure, pb.model, pb.measured, pb.rig_speed, n_pad, key)
    t0 = time.perf_counter()
    fixed = dict(pb.fixed)
    theta0, e0, start = _joint_start(pb, labels, eb, fixed, x0, n_grid, start_x)
    lo, hi, z0 = _joint_box(pb, labels, eb, S, fixed, np.concatenate([theta0, e0]), hold)
    args = {"x0": z0, "p": _joint_parameters(pb, n_pad), "lbx": lo, "ubx": hi}
    if "pressure_distribution" in structure:
        args.update(lbg=-1.0, ubg=1.0)
    W = pb.load
    A = pb.vehicle.contact_area
    ridge = (
        pb.model == "full" and one_load(W) and not _separates_c_phi(structure, fixed) and not {0, 1} & set(hold or ())
    )
    n_of = normal_load_function(pb.vehicle, structure) if labels else None

    def load_at(e_values) -> float:
        return float(n_of(float(W[0]), e_values)[0]) if n_of is not None else float(W[0])

    if ridge:
        sol, st, lo_c, hi_c = _ridge_solve(pb, solver, args, S, lo, hi, z0, load_at)
    else:
        sol, st = call_solver(solver, **args)
        lo_c, hi_c = lo, hi
    x, status, iters, ok, msgs = _checked_solution(sol, st, lo_c, hi_c, z0, S)
    theta, e = x[:3].copy(), x[3:].copy()
    note = ""
    if ridge and ok:
        N = load_at(e)
        F = max_thrust_expr(theta[0], theta[1], N, A)
        c, phi = ridge_centre(F, N, A, pb.bounds)
        theta[0], theta[1] = float(c), float(phi)
        note = "; one normal load: (c, phi) moved along the ridge to its centre (predictions unchanged)"
    total = time.perf_counter() - t0
    y = pb.measured_values
    ypred, J = predict(
        np.concatenate([theta, e]), pb.slip, pb.load, pb.vehicle, structure, pb.model, pb.measured, pb.rig_speed
    )
    r = ypred - y
    msg = "; ".join(msgs) or ("IPOPT converged" if ok else f"IPOPT: {status}")
    active, warnings = _pressure_constraint(structure, labels, e, pb.noise_warning(r))
    return build_result(
        data_kind="slip",
        model=pb.model,
        method="ipopt",
        theta=theta,
        jacobian=J / pb.sigma[:, None],
        weighted_residuals=r / pb.sigma,
        residuals=r,
        residual_unit="N",
        n_samples=pb.n,
        normal_loads=pb.load,
        vehicle=pb.vehicle,
        bounds=pb.bounds,
        status=status,
        success=ok,
        message=f"{msg} (joint soil and effects fit; {start}{note})",
        iterations=iters,
        solve_time=total,
        sigma_known=pb.sigma_known,
        warnings=warnings,
        extra={
            "engine": "ipopt",
            "start": [float(v) for v in np.concatenate([theta0, e0])],
            "active_constraints": active,
        },
        effect_labels=labels,
        effect_values=e,
        effect_bounds=[tuple(b) for b in eb],
        effect_units=units,
        effect_structure=structure,
        fixed_labels=tuple(fixed),
        measured=pb.measured,
        residual_model=SweepResiduals(pb.rig_speed),
        plausibility=slip_checks(None, r, theta, pb.load, pb.vehicle, pb.model, pb.bounds),
    )


def _joint_start(pb: SlipProblem, labels, eb, fixed: dict, x0, n_grid: int, start_x):
    """``(theta0, e0, words)``: the given start, or the nominal soil from the grid and the effects' defaults."""
    # start: nominal soil from the variable-projection grid (on the tractive-force equivalent), effects off
    if start_x is not None:
        sx = np.asarray(start_x, float).ravel()
        return sx[:3].copy(), [float(v) for v in sx[3:]], "given start"
    theta0, start = start_point(pb, x0, "grid", n_grid)
    start += ", effects at their given or default values"
    e0 = []
    given = dict(pb.effect_start)
    for lab, (lo, hi) in zip(labels, eb):
        name, pname = lab.split(".", 1)
        spec = EFFECTS[name].param(pname)
        v = fixed.get(lab, given.get(lab, spec.off_value if spec.default is None else spec.default))
        e0.append(min(max(v, lo), hi))
    return theta0, e0, start


def _joint_box(pb: SlipProblem, labels, eb, S, fixed: dict, x_start, hold):
    """Scaled bounds and start ``(lo, hi, z0)``: cohesion-free, held effects and profile points pinned."""
    lo = np.concatenate([pb.bounds.lower, eb[:, 0]]) / S
    hi = np.concatenate([pb.bounds.upper, eb[:, 1]]) / S
    z0 = x_start / S
    if pb.model == "cohesion-free":
        lo[0] = hi[0] = z0[0] = 0.0
    for k, lab in enumerate(labels):
        if lab in fixed:
            lo[3 + k] = hi[3 + k] = z0[3 + k] = fixed[lab] / S[3 + k]
    for j, v in (hold or {}).items():
        lo[j] = hi[j] = z0[j] = float(v) / S[j]
    return lo, hi, np.clip(z0, lo, hi)


def _joint_parameters(pb: SlipProblem, n_pad: int) -> np.ndarray:
    """The NLP's parameter vector: slips, measurements, loads, weights (padded), the cost scale."""
    y = pb.measured_values
    yw = y / pb.sigma
    scale = max(0.5 * float(yw @ yw), 1e-300)
    pad = n_pad - pb.n
    return np.concatenate(
        [
            pb.slip,
            np.zeros(pad),
            y,
            np.zeros(pad),
            pb.load,
            np.full(pad, pb.load[0]),
            1.0 / pb.sigma,
            np.zeros(pad),
            [scale],
        ]
    )


def _ridge_solve(pb: SlipProblem, solver, args: dict, S, lo, hi, z0, load_at):
    """One normal load: solve in (F_max, K, effects); the full problem if the effects move F_max off the box.

    c and phi enter only through F_max = A c + N tan(phi): solve for (F_max, K, effects) with
    F_max = N0 tan(phi_e) (c held at 0, phi_e over the F_max range of the box), exactly the
    optimum of the full problem without its singular Hessian (IPOPT wanders along the ridge
    otherwise and never certifies); the reported (c, phi) is the ridge centre.
    Returns ``(sol, stats, lo, hi)`` with the bounds of the problem solved last.
    """
    A = pb.vehicle.contact_area
    N0 = load_at(z0[3:] * S[3:])
    F_lo, F_hi = fmax_range(N0, A, pb.bounds)
    F0 = float(max_thrust_expr(z0[0] * S[0], z0[1] * S[1], N0, A))
    rlo, rhi = lo.copy(), hi.copy()
    rlo[0] = rhi[0] = 0.0
    rlo[1], rhi[1] = np.arctan(F_lo / N0) / S[1], np.arctan(F_hi / N0) / S[1]
    rz0 = z0.copy()
    rz0[0] = 0.0
    rz0[1] = min(max(np.arctan(F0 / N0) / S[1], rlo[1]), rhi[1])
    args.update(x0=rz0, lbx=rlo, ubx=rhi)
    sol, st = call_solver(solver, **args)
    xr = np.asarray(sol["x"], float).ravel() * S
    lo_c, hi_c = rlo, rhi
    if np.all(np.isfinite(xr)):
        Nr = load_at(xr[3:])
        Fr = float(max_thrust_expr(0.0, xr[1], Nr, A))
        f_lo, f_hi = fmax_range(Nr, A, pb.bounds)
        if not f_lo * (1 - 1e-9) <= Fr <= f_hi * (1 + 1e-9):
            # the fitted effects moved N so far that this F_max leaves the box: solve the full problem
            c_r, phi_r = ridge_centre(Fr, Nr, A, pb.bounds)
            z1 = np.concatenate([[float(c_r), float(phi_r)], xr[2:]]) / S
            args.update(x0=np.clip(z1, lo, hi), lbx=lo, ubx=hi)
            sol, st = call_solver(solver, **args)
            lo_c, hi_c = lo, hi
    return sol, st, lo_c, hi_c


def _checked_solution(sol, st, lo_c, hi_c, z0, S):
    """``(x, status, iterations, ok, messages)``: IPOPT's answer in SI, non-finite or out-of-bounds said."""
    x = np.asarray(sol["x"], float).ravel() * S
    status, iters, ok = solver_status(st)
    msgs = []
    if not np.all(np.isfinite(x)):
        ok = False
        msgs.append("IPOPT returned non-finite numbers")
    span = np.where(hi_c > lo_c, hi_c - lo_c, 1.0) * S
    viol = np.maximum(lo_c * S - x, x - hi_c * S) / span
    if np.any(viol > 1e-6):
        ok = False
        msgs.append("IPOPT's answer lies outside the bounds")
    x = np.clip(np.where(np.isfinite(x), x, z0 * S), lo_c * S, hi_c * S)
    return x, status, iters, ok, msgs


def _pressure_constraint(structure: EffectSet, labels, e, warnings: tuple):
    """The active constraint ``|e| + |alpha| <= 1`` of the pressure distribution, with its warning."""
    active = []
    if "pressure_distribution" in structure:
        pe, pa = e[labels.index("pressure_distribution.e")], e[labels.index("pressure_distribution.alpha")]
        if abs(pe) + abs(pa) >= 1.0 - 1e-6:
            active.append("pressure_distribution: |e| + |alpha| <= 1")
            warnings = warnings + (
                f"pressure_distribution ended on its constraint |e| + |alpha| = {abs(pe) + abs(pa):.6g} "
                "<= 1 (the pressure reaches zero somewhere on the track): e and alpha and their "
                "intervals are on that boundary, a warning about the data or the model",
            )
    return active, warnings
