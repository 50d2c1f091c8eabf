"""Bounded least squares with IPOPT for the bevameter tests: the solver built once per model and size.

A model is a residual ``r(x, D, a)`` of scaled parameters ``x`` (a few), the data matrix ``D``
(one row per reading) and a vector ``a`` of scales; the solver minimises ``0.5 |r|^2`` within
box bounds on ``x``. Each (model, number of rows) gets one IPOPT instance and one Jacobian
Function, cached: every start and every later file of the same size reuses them.

The linearised covariance ``s^2 (J^T J)^-1`` (``s^2 = |r|^2 / (n - m)``) and Student-t
intervals are computed on the scaled parameters; directions the data leave flat (relative
singular value below :data:`RANK_RTOL`) are reported as not identifiable, never as numbers.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import lru_cache
from typing import Callable

import casadi as ca
import numpy as np

from ...soilmodel.threadsafe import call_solver, solver_status
from ..estimates.least_squares import NULL_TOL, RANK_TOL
from ..outcome import BOUND_TOL

__all__ = [
    "ResidualModel",
    "LsqSolution",
    "solve_bounded",
    "covariance",
    "RANK_RTOL",
    "BOUND_RTOL",
    "MAX_ITER",
    "IPOPT_TOL",
    "FLAT_COMPONENT_TOL",
]

#: Relative singular value of the scaled Jacobian below which a direction is not identifiable: the
#: library's one rank tolerance (:data:`soiltrack.identify.estimates.least_squares.RANK_TOL`).
RANK_RTOL = RANK_TOL
#: A parameter within this fraction of its box width from a bound is reported on that bound: the
#: library's one bound tolerance (:data:`soiltrack.identify.outcome.BOUND_TOL`).
BOUND_RTOL = BOUND_TOL
#: IPOPT iteration budget of one start.
MAX_ITER = 300
#: IPOPT's convergence tolerance (the scaled problems are of order one).
IPOPT_TOL = 1e-10
#: A parameter whose component in the flat directions of the fit exceeds this is not identifiable: the
#: library's one rule (:data:`soiltrack.identify.estimates.least_squares.NULL_TOL`).
FLAT_COMPONENT_TOL = NULL_TOL


@dataclass(frozen=True)
class ResidualModel:
    """A residual model: ``build(x, D, a) -> r`` (CasADi SX), with its sizes.

    Attributes
    ----------
    name
        Key of the cached solver (unique per model).
    n_params, n_columns, n_aux
        Sizes of ``x``, of a row of ``D`` and of ``a``.
    build
        Builds the residual vector (one entry per row) from SX symbols.
    """

    name: str
    n_params: int
    n_columns: int
    n_aux: int
    build: Callable


@dataclass(frozen=True)
class LsqSolution:
    """The best of the starts of a bounded least-squares fit (scaled parameters).

    Attributes
    ----------
    x
        Scaled parameters at the optimum.
    cost
        ``|r|^2`` at ``x``.
    residuals
        ``r`` at ``x`` (scaled, one per row).
    jacobian
        ``dr/dx`` at ``x``.
    converged
        IPOPT reported success for this start.
    status
        IPOPT's return status.
    iterations
        IPOPT iterations of this start.
    solve_time_s
        Wall time of all starts, s.
    starts
        Number of starts run.
    """

    x: np.ndarray
    cost: float
    residuals: np.ndarray
    jacobian: np.ndarray
    converged: bool
    status: str
    iterations: int
    solve_time_s: float
    starts: int


_MODELS: dict[str, ResidualModel] = {}


def _symbols(model: ResidualModel, n: int):
    x = ca.SX.sym("x", model.n_params)
    D = ca.SX.sym("D", n, model.n_columns)
    a = ca.SX.sym("a", model.n_aux)
    return x, D, a


@lru_cache(maxsize=64)
def _functions(name: str, n: int) -> tuple[ca.Function, ca.Function]:
    """The IPOPT solver and ``(x, p) -> (r, J)`` of model ``name`` for ``n`` rows (built once)."""
    model = _MODELS[name]
    x, D, a = _symbols(model, n)
    r = model.build(x, D, a)
    p = ca.vertcat(ca.vec(D), a)
    opts: dict = {
        "ipopt.print_level": 0,
        "print_time": False,
        "ipopt.sb": "yes",
        "ipopt.max_iter": MAX_ITER,
        "ipopt.tol": IPOPT_TOL,
    }
    solver = ca.nlpsol(f"lsq_{name}_{n}", "ipopt", {"x": x, "p": p, "f": 0.5 * ca.sumsqr(r)}, opts)
    rj = ca.Function(f"rj_{name}_{n}", [x, p], [r, ca.jacobian(r, x)])
    return solver, rj


def solve_bounded(
    model: ResidualModel,
    data: np.ndarray,
    aux: np.ndarray,
    starts: list[np.ndarray],
    lower: np.ndarray,
    upper: np.ndarray,
) -> LsqSolution:
    """Minimise ``0.5 |r(x)|^2`` within ``[lower, upper]`` from each start; the best start wins.

    Parameters
    ----------
    model
        The residual model (registered on first use).
    data
        ``(n, model.n_columns)`` data matrix.
    aux
        ``(model.n_aux,)`` scales.
    starts
        Start points (clipped into the box).
    lower, upper
        Box bounds on the scaled parameters.
    """
    _MODELS.setdefault(model.name, model)
    n = int(data.shape[0])
    solver, rj = _functions(model.name, n)
    p = np.concatenate([np.asarray(data, dtype=float).ravel(order="F"), np.asarray(aux, dtype=float)])
    t0 = time.perf_counter()
    best = None
    for x0 in starts:
        x0 = np.clip(np.asarray(x0, dtype=float), lower, upper)
        sol, stats = call_solver(solver, x0=x0, p=p, lbx=lower, ubx=upper)
        status, iters, converged = solver_status(stats)
        x = np.clip(np.asarray(sol["x"], dtype=float).ravel(), lower, upper)  # IPOPT relaxes bounds by ~1e-8
        f = float(sol["f"])
        if not (np.all(np.isfinite(x)) and np.isfinite(f)):
            continue
        if (
            best is None
            or f < best[1] - 1e-14 * max(abs(f), 1.0)
            or (not best[2] and converged and f <= best[1] * (1 + 1e-9))
        ):
            best = (x, f, converged, status, iters)
    elapsed = time.perf_counter() - t0
    if best is None:
        x = np.clip(np.asarray(starts[0], dtype=float), lower, upper)
        r, J = rj(x, p)
        return LsqSolution(
            x,
            float(np.sum(np.asarray(r) ** 2)),
            np.asarray(r, dtype=float).ravel(),
            np.asarray(J, dtype=float),
            False,
            "no start gave a finite answer",
            0,
            elapsed,
            len(starts),
        )
    x, f, ok, status, it = best
    r, J = rj(x, p)
    r = np.asarray(r, dtype=float).ravel()
    return LsqSolution(x, float(r @ r), r, np.asarray(J, dtype=float), ok, status, it, elapsed, len(starts))


def covariance(J: np.ndarray, cost: float, n: int) -> tuple[np.ndarray | None, np.ndarray, int]:
    """Linearised covariance of the scaled parameters, the identifiable mask and the residual dof.

    ``s^2 (J^T J)^+`` over the directions with relative singular value above :data:`RANK_RTOL`;
    a parameter with a component along a flat direction is not identifiable (mask False).
    ``None`` when the data have no residual degree of freedom (n <= m).
    """
    m = J.shape[1]
    dof = n - m
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    keep = s > RANK_RTOL * (s[0] if s.size and s[0] > 0 else 1.0)
    flat = Vt[~keep]
    ident = np.ones(m, dtype=bool) if flat.size == 0 else np.linalg.norm(flat, axis=0) < FLAT_COMPONENT_TOL
    if dof <= 0 or not np.any(keep):
        return None, ident, dof
    s2 = cost / dof
    Vk = Vt[keep]
    cov = s2 * (Vk.T / s[keep] ** 2) @ Vk
    return cov, ident, dof
