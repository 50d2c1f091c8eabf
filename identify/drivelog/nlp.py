"""Drive-log NLPs (output-error with latent slips; equation-error for comparison) and their solves.

Each solver is built once per formulation and padded log length (data as parameters), cached
with :func:`~soiltrack.soilmodel.threadsafe.locked_cache` and called through
:func:`~soiltrack.soilmodel.threadsafe.call_solver`.
"""

from __future__ import annotations

import math
import time as _time
from typing import Any

import casadi as ca
import numpy as np

from ...soilmodel.ridge import ridge_centre, ridge_ranges
from ...soilmodel.soil import SoilBounds
from ...soilmodel.threadsafe import call_solver, locked_cache, solver_status
from ...soilmodel.traction import shear_bracket, shear_bracket_inverse
from ...soilmodel.vehicle import Vehicle
from .prepare import SLIP_BOUNDS, PreparedLog

__all__ = ["padded_size", "fmax_bounds", "ridge_point", "solve_output_error", "solve_equation_error", "eval_pointwise"]


def bracket_signed(slip, lk):
    """``sign(i) g(|i| l / K)`` with ``lk = l / K``."""
    return ca.sign(slip) * shear_bracket(ca.fabs(slip) * lk)


_QUIET: dict[str, bool | int | float | str] = {
    "expand": True,
    "print_time": False,
    "ipopt.sb": "yes",
    "ipopt.print_level": 0,
}


def padded_size(n: int) -> int:
    """Problem size the NLP is built for: the next of 64, 96, 128, 192, 256, ... (2^k or 1.5 2^k).

    Logs of similar length share one cached solver; the extra samples get zero weight.
    """
    size = 64
    while True:
        if n <= size:
            return size
        if n <= size * 3 // 2:
            return size * 3 // 2
        size *= 2


@locked_cache(maxsize=16)
def _output_error_solver(n: int, max_iter: int, tol: float, print_level: int) -> ca.Function:
    """IPOPT solver for the output-error (latent slip) problem with ``n`` (padded) samples.

    Variables ``[F_max / F_ref, K / K_ref, i_1 / i_ref, ..., i_n / i_ref]``; parameters
    ``[F_ref, K_ref, i_ref, r, l, v(n), w(n), T(n), 1/sigma_s(n), 1/sigma_T|s(n), rho(n), pad(n)]``.
    The residual pair of each sample is whitened (its speed and thrust noise are correlated
    through the encoder): ``e_w = d_s / sigma_s``, ``e_T = (d_T - rho d_s) / sigma_T|s``.
    Padding samples have zero weights and ``pad = 1`` (a unit penalty pins their latent slip).
    """
    x = ca.SX.sym("x", 2 + n)
    p = ca.SX.sym("p", 5 + 7 * n)
    F_ref, K_ref, i_ref, r, l = (p[j] for j in range(5))
    v, w, T, iss, isT, rho, pad = (p[5 + j * n : 5 + (j + 1) * n] for j in range(7))
    Fmax, K = x[0] * F_ref, x[1] * K_ref
    z = x[2:]
    slip = z * i_ref
    d_s = v - r * w * (1 - slip)
    e_w = d_s * iss
    e_T = (T - Fmax * bracket_signed(slip, l / K) - rho * d_s) * isT
    f = 0.5 * (ca.sumsqr(e_w) + ca.sumsqr(e_T) + ca.sumsqr(pad * z))
    opts = dict(_QUIET, **{"ipopt.max_iter": max_iter, "ipopt.tol": tol, "ipopt.print_level": print_level})
    return ca.nlpsol(f"drivelog_oe_{n}", "ipopt", {"x": x, "p": p, "f": f}, opts)


@locked_cache(maxsize=16)
def _equation_error_solver(n: int, max_iter: int, tol: float, print_level: int) -> ca.Function:
    """IPOPT solver for the naive equation-error problem (slip from the measured speeds)."""
    x = ca.SX.sym("x", 2)
    p = ca.SX.sym("p", 3 + 3 * n)
    F_ref, K_ref, l = p[0], p[1], p[2]
    slip, T, isT = (p[3 + j * n : 3 + (j + 1) * n] for j in range(3))
    e_T = (T - x[0] * F_ref * bracket_signed(slip, l / (x[1] * K_ref))) * isT
    f = 0.5 * ca.sumsqr(e_T)
    opts = dict(_QUIET, **{"ipopt.max_iter": max_iter, "ipopt.tol": tol, "ipopt.print_level": print_level})
    return ca.nlpsol(f"drivelog_ee_{n}", "ipopt", {"x": x, "p": p, "f": f}, opts)


@locked_cache(maxsize=1)
def _pointwise() -> ca.Function:
    """``(slip, F_max, K, l) -> (F, dF/dslip, dF/dF_max, dF/dK)`` by AD (vectorises over rows)."""
    s, Fm, K, l = (ca.SX.sym(k) for k in ("slip", "Fmax", "K", "l"))
    F = Fm * bracket_signed(s, l / K)
    return ca.Function(
        "drivelog_pointwise",
        [s, Fm, K, l],
        [F, ca.jacobian(F, s), ca.jacobian(F, Fm), ca.jacobian(F, K)],
        ["slip", "Fmax", "K", "l"],
        ["F", "dF_ds", "dF_dFmax", "dF_dK"],
    )


def eval_pointwise(slip: np.ndarray, Fmax: float, K: float, l: float) -> tuple[np.ndarray, ...]:
    out = _pointwise()(slip.reshape(1, -1), Fmax, K, l)
    return tuple(np.asarray(o, dtype=float).reshape(-1) for o in out)


def g_inverse(y: np.ndarray) -> np.ndarray:
    """x >= 0 with ``1 - (1 - exp(-x))/x = y`` for y in [0, 1): the soilmodel's inverse of the one bracket."""
    return shear_bracket_inverse(y)


def fmax_bounds(bounds: SoilBounds, vehicle: Vehicle, model: str) -> tuple[float, float]:
    """Range of ``F_max = A c + W tan(phi)`` over the soil bounds, N (cohesion-free: no ``A c``)."""
    W, A = vehicle.weight, vehicle.contact_area
    lo = W * math.tan(bounds.friction_angle[0])
    hi = W * math.tan(bounds.friction_angle[1])
    if model == "full":
        lo += A * max(bounds.cohesion[0], 0.0)
        hi += A * bounds.cohesion[1]
    return lo, hi


def ridge_point(
    Fmax: float,
    vehicle: Vehicle,
    bounds: SoilBounds,
    model: str,
    c_hint: float | None,
    normal_load: float | None = None,
) -> np.ndarray:
    """A ``(c, phi)`` on the ridge ``A c + W tan(phi) = F_max`` inside the bounds.

    The point is NOT an estimate of c and phi (only their combination is identifiable; the
    result object says so and reports the ridge's extent). It keeps ``c_hint`` (the initial
    guess's cohesion) when that is feasible, clamped into the feasible cohesion range, else it is
    the library's one ridge marker (:func:`~soiltrack.soilmodel.ridge.ridge_centre`: the middle of
    the feasible range, or the nearest point of the box when F_max lies beyond it). For the
    cohesion-free model c = 0 and ``phi = atan(F_max / W)``. ``normal_load`` (default the
    vehicle's weight) is the log's actual normal load W.
    """
    W, A = (vehicle.weight if normal_load is None else normal_load), vehicle.contact_area
    plo, phi_hi = bounds.friction_angle
    if model == "cohesion-free":
        return np.array([0.0, min(max(math.atan(Fmax / W), plo), phi_hi)])
    seg = ridge_ranges(Fmax, Fmax, W, A, bounds) if c_hint is not None else None
    if seg is None or c_hint is None:  # (seg is None whenever c_hint is)
        c, phi = ridge_centre(Fmax, W, A, bounds)
        return np.array([float(c), float(phi)])
    (c_a, c_b), _ = seg
    c = min(max(float(c_hint), c_a), c_b)
    return np.array([c, min(max(math.atan(max(Fmax - A * c, 0.0) / W), plo), phi_hi)])


def pad(a: np.ndarray, size: int, value: float = 0.0) -> np.ndarray:
    return np.concatenate([a, np.full(size - a.size, value)])


def run_starts(solver: ca.Function, make_x0, p, lbx, ubx, starts, Fb, Kb, F_ref, K_ref) -> dict:
    """Solve from the first start; try the next ones only if it failed or ended on a bound."""
    best: dict[str, Any] | None = None
    total = 0.0
    for j, (Fmax0, K0) in enumerate(starts):
        t0 = _time.perf_counter()
        sol, st = call_solver(solver, x0=make_x0(Fmax0, K0), p=p, lbx=lbx, ubx=ubx)
        total += _time.perf_counter() - t0
        xs = np.asarray(sol["x"], dtype=float).reshape(-1)
        fval = float(sol["f"])
        status, iters, converged = solver_status(st)
        ok = converged and bool(np.all(np.isfinite(xs))) and math.isfinite(fval)
        cand: dict[str, Any] = {
            "x": xs,
            "f": fval,
            "ok": ok,
            "status": status,
            "iterations": iters,
            "starts_tried": j + 1,
        }
        if best is None or (cand["ok"], -cand["f"]) > (best["ok"], -best["f"]):
            best = cand
        best["starts_tried"] = j + 1
        F, K = best["x"][0] * F_ref, best["x"][1] * K_ref
        on_bound = any(abs(val - b) <= 1e-6 * (hi - lo) for val, (lo, hi) in ((F, Fb), (K, Kb)) for b in (lo, hi))
        if best["ok"] and not on_bound:
            break
    if best is None:
        raise ValueError("run_starts: no start points given")
    best["time"] = total
    return best


def solve_output_error(
    prep: PreparedLog,
    vehicle: Vehicle,
    F_ref: float,
    K_ref: float,
    Fb,
    Kb,
    starts,
    max_iter: int,
    tol: float,
    print_level: int,
):
    n = prep.n_used
    N = padded_size(n)
    l, r = vehicle.track_length, vehicle.sprocket_radius
    i_ref = K_ref / l
    solver = _output_error_solver(N, max_iter, tol, print_level)
    p = np.concatenate(
        [
            [F_ref, K_ref, i_ref, r, l],
            pad(prep.vehicle_speed, N),
            pad(prep.sprocket_speed, N),
            pad(prep.thrust, N),
            pad(1.0 / prep.sigma_speed, N),
            pad(1.0 / prep.sigma_thrust_cond, N),
            pad(prep.coupling, N),
            pad(np.zeros(n), N, 1.0),
        ]
    )
    lbx = np.concatenate([[Fb[0] / F_ref, Kb[0] / K_ref], np.full(N, SLIP_BOUNDS[0] / i_ref)])
    ubx = np.concatenate([[Fb[1] / F_ref, Kb[1] / K_ref], np.full(N, SLIP_BOUNDS[1] / i_ref)])

    def make_x0(Fmax0: float, K0: float) -> np.ndarray:
        # latent slips from the inverse thrust-slip curve at the start values
        y = np.clip(np.abs(prep.thrust) / Fmax0, 0.0, 0.98)
        slip0 = np.clip(np.sign(prep.thrust) * g_inverse(y) * K0 / l, SLIP_BOUNDS[0] + 1e-3, SLIP_BOUNDS[1] - 1e-3)
        return np.concatenate([[Fmax0 / F_ref, K0 / K_ref], pad(slip0 / i_ref, N)])

    best = run_starts(solver, make_x0, p, lbx, ubx, starts, Fb, Kb, F_ref, K_ref)
    xs = best["x"]
    return best, xs[0] * F_ref, xs[1] * K_ref, xs[2 : 2 + n] * i_ref


def solve_equation_error(
    prep: PreparedLog,
    vehicle: Vehicle,
    F_ref: float,
    K_ref: float,
    Fb,
    Kb,
    starts,
    max_iter: int,
    tol: float,
    print_level: int,
):
    n = prep.n_used
    N = padded_size(n)
    l = vehicle.track_length
    solver = _equation_error_solver(N, max_iter, tol, print_level)
    slip = np.clip(prep.slip_measured, SLIP_BOUNDS[0], SLIP_BOUNDS[1])
    p = np.concatenate([[F_ref, K_ref, l], pad(slip, N), pad(prep.thrust, N), pad(1.0 / prep.sigma_thrust, N)])
    lbx = [Fb[0] / F_ref, Kb[0] / K_ref]
    ubx = [Fb[1] / F_ref, Kb[1] / K_ref]
    best = run_starts(
        solver, lambda F0, K0: np.array([F0 / F_ref, K0 / K_ref]), p, lbx, ubx, starts, Fb, Kb, F_ref, K_ref
    )
    return best, best["x"][0] * F_ref, best["x"][1] * K_ref, slip
