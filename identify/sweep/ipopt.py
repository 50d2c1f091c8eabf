"""Bounded identification with IPOPT (the default method).

The NLP is built ONCE per ``(model, n_points)`` and cached; the data enter as NLP
parameters ``p = [slip (n), F (n), W (n), sigma (n), l, b, scale]``. Variables are scaled
for conditioning: ``x = [c / 1 kPa, phi / 1 rad, K / 1 cm]`` (``[phi, K / 1 cm]`` for the
cohesion-free model). The objective is the weighted sum of squares divided by
``scale = 0.5 * sum((F / sigma)^2)`` (a relative cost of order 1 at the start). The soil's
practical ranges are simple bounds on ``x``. The start point comes from the
variable-projection grid of :mod:`soiltrack.identify.sweep.start` (a global search over K with
``(c, tan(phi))`` solved linearly), unless ``x0`` is given.

IPOPT options (overridable with ``ipopt_options``): ``tol 1e-12``, ``acceptable_tol 1e-8``,
``max_iter 300``, and - because the grid start is already close - a small initial barrier
(``mu_init 1e-6``) and small bound push (``bound_push = bound_frac = 1e-6``). On the flat
c-phi ridge of one-load data the default barrier start made IPOPT walk ~100 iterations
towards the ridge's analytic centre; with these settings it stops after ~25 (the ridge
point is arbitrary either way and reported as such).
Success is IPOPT's ``success`` flag AND a return status of ``Solve_Succeeded`` or
``Solved_To_Acceptable_Level`` AND finite numbers inside the bounds (checked here, not taken
on trust).

Fixing a parameter (for profiles) reuses the same solver with ``lbx = ubx``.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import casadi as ca
import numpy as np

from ...soilmodel.soil import SoilBounds
from ...soilmodel.threadsafe import call_solver, locked_cache, solver_status
from ...soilmodel.ridge import fmax_range, one_load
from ...soilmodel.traction import max_thrust_expr, thrust_expr
from .problem import SCALE, SlipProblem, ridge_centre
from ..estimates.result import FitResult
from .start import start_point

__all__ = ["ipopt_solver", "fit_ipopt", "solve_ipopt"]

_DEFAULT_OPTS = {
    "ipopt.tol": 1e-12,
    "ipopt.acceptable_tol": 1e-8,
    "ipopt.max_iter": 300,
    # the grid start is good: start with a small barrier and close to the bounds
    "ipopt.mu_init": 1e-6,
    "ipopt.bound_push": 1e-6,
    "ipopt.bound_frac": 1e-6,
}


@locked_cache(maxsize=64)
def ipopt_solver(model: str, n: int, opts_key: tuple = ()) -> ca.Function:
    """The cached IPOPT ``nlpsol`` for ``model`` and ``n`` data points (quiet, expanded)."""
    nx = 3 if model == "full" else 2
    x = ca.SX.sym("x", nx)
    P = ca.SX.sym("p", 4 * n + 3)
    slip, F, W, sig = P[0:n], P[n : 2 * n], P[2 * n : 3 * n], P[3 * n : 4 * n]
    l, b, scale = P[4 * n], P[4 * n + 1], P[4 * n + 2]
    c = x[0] * SCALE[0] if model == "full" else 0
    phi, K = x[nx - 2], x[nx - 1] * SCALE[2]
    Fm = thrust_expr(slip, c, phi, K, W, l, b, model=model)
    rw = (Fm - F) / sig
    f = 0.5 * ca.dot(rw, rw) / scale
    opts: dict[str, Any] = {
        "expand": True,
        "print_time": False,
        "error_on_fail": False,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
    }
    opts.update(_DEFAULT_OPTS)
    opts.update(dict(opts_key))
    return ca.nlpsol(f"soilfit_{model.replace('-', '_')}_{n}", "ipopt", {"x": x, "p": P, "f": f}, opts)


def _params(pb: SlipProblem) -> np.ndarray:
    y = pb.force / pb.sigma
    scale = max(0.5 * float(y @ y), 1e-300)
    return np.concatenate(
        [pb.slip, pb.force, pb.load, pb.sigma, [pb.vehicle.track_length, pb.vehicle.track_width, scale]]
    )


def solve_ipopt(
    pb: SlipProblem, theta0: np.ndarray, fixed: dict[int, float] | None = None, ipopt_options: dict | None = None
) -> dict:
    """One IPOPT solve; returns theta (SI), checked status, iterations, time and raw stats.

    ``fixed`` maps parameter index (0 c, 1 phi, 2 K) to a value held fixed (profiles).
    """
    key = tuple(sorted((ipopt_options or {}).items()))
    solver = ipopt_solver(pb.model, pb.n, key)
    free = pb.free
    lo = pb.bounds.lower[free] / SCALE[free]
    hi = pb.bounds.upper[free] / SCALE[free]
    x0 = np.clip(np.asarray(theta0, float)[free] / SCALE[free], lo, hi)
    for j, v in (fixed or {}).items():
        k = free.index(j)
        lo[k] = hi[k] = x0[k] = v / SCALE[j]
    t0 = time.perf_counter()
    sol, st = call_solver(solver, x0=x0, p=_params(pb), lbx=lo, ubx=hi)
    dt = time.perf_counter() - t0
    x = np.asarray(sol["x"], float).ravel()
    theta = np.zeros(3)
    theta[free] = x * SCALE[free]
    status, iters, ok = solver_status(st)
    msgs = []
    if not np.all(np.isfinite(theta)):
        ok = False
        msgs.append("IPOPT returned non-finite numbers")
        theta = np.where(np.isfinite(theta), theta, np.asarray(theta0, float))
    span = pb.bounds.upper - pb.bounds.lower
    viol = np.maximum(pb.bounds.lower - theta, theta - pb.bounds.upper)[free] / span[free]
    if np.any(viol > 1e-6):
        ok = False
        msgs.append("IPOPT's answer lies outside the bounds")
    theta[free] = np.clip(theta[free], pb.bounds.lower[free], pb.bounds.upper[free])
    return {
        "theta": theta,
        "status": status,
        "success": ok,
        "iterations": iters,
        "time": dt,
        "message": "; ".join(msgs) or ("IPOPT converged" if ok else f"IPOPT: {status}"),
        "cost": float(sol["f"]) * _params(pb)[-1],
    }


def fit_ipopt(pb: SlipProblem, x0=None, ipopt_options: dict | None = None, n_grid: int = 25) -> FitResult:
    """Fit a :class:`SlipProblem` with the cached IPOPT solver and build the result."""
    one_load = pb.model == "full" and one_load_problem(pb)
    ipopt_solver(
        "cohesion-free" if one_load else pb.model, pb.n, tuple(sorted((ipopt_options or {}).items()))
    )  # one-off build, not timed
    t0 = time.perf_counter()
    theta0, start = start_point(pb, x0, "grid", n_grid)
    note = ""
    if one_load:
        out = _solve_one_load(pb, theta0, ipopt_options)
        note = (
            "; one normal load: solved in the identifiable parameters (F_max, K), exactly equivalent; "
            "(c, phi) is a point of the ridge"
        )
    else:
        out = solve_ipopt(pb, theta0, ipopt_options=ipopt_options)
    total = time.perf_counter() - t0
    return pb.result(
        out["theta"],
        method="ipopt",
        status=out["status"],
        success=out["success"],
        message=f"{out['message']} ({start}{note})",
        iterations=out["iterations"],
        solve_time=total,
        extra={"ipopt_time_s": out["time"], "start": [float(v) for v in theta0]},
    )


def one_load_problem(pb: SlipProblem) -> bool:
    """Whether the problem's samples are at one normal load (:func:`soilmodel.ridge.one_load`)."""
    return one_load(pb.load)


def _solve_one_load(pb: SlipProblem, theta0: np.ndarray, ipopt_options: dict | None) -> dict:
    """Full model at one load W: fit (F_max, K) with F_max = W tan(phi_e), then map to the ridge.

    The bounds box of (c, phi) maps onto ``F_max in [A c_lo + W tan(phi_lo), A c_hi + W tan(phi_hi)]``
    (F_max is increasing in both), so this bounded 2-parameter problem has exactly the optimum
    of the 3-parameter one, without its singular Hessian. The returned (c, phi) keeps the
    centre of the bounds-feasible ridge (:func:`ridge_centre`; a marker, reported as NOT an estimate).
    """
    W, A = float(pb.load[0]), pb.vehicle.contact_area
    F_lo, F_hi = fmax_range(W, A, pb.bounds)
    eb = SoilBounds((0.0, 1.0), (math.atan(F_lo / W), math.atan(F_hi / W)), pb.bounds.shear_modulus)
    red = replace(pb, model="cohesion-free", bounds=eb)
    F0 = max_thrust_expr(theta0[0], theta0[1], W, A)
    out = solve_ipopt(red, np.array([0.0, math.atan(F0 / W), theta0[2]]), ipopt_options=ipopt_options)
    F = max_thrust_expr(0.0, out["theta"][1], W, A, "cohesion-free")
    c, phi = ridge_centre(F, W, A, pb.bounds)
    out["theta"] = np.array([float(c), float(phi), out["theta"][2]])
    return out
