"""Start points: the one home of where the solvers start.

:func:`start_point` gives the start of one problem: the user's ``x0``, the middle of the bounds
(the seed's methods) or the variable-projection grid (IPOPT, joint fits). :func:`grid_start`
is the grid, vectorised over many problems.

Variable projection: a grid on K, linear least squares for the rest.

For a fixed K the tractive force is LINEAR in ``(c, tan(phi))``:
``F_k = (A c + W_k tan(phi)) g(i_k l / K)``. So for each K on a geometric grid over its
bounds the best ``(c, tan(phi))`` follow from a 2x2 (or 1x1) weighted linear least-squares
problem, are projected onto the bounds, and the grid point of lowest cost is the start.
This is a global search over the only nonlinear parameter; the local solver then refines.
Vectorised over many problems at once (leading axis N). The slip factor ``g`` of every
(sample, K) pair comes from the soilmodel's CasADi Function in one mapped call.
"""

from __future__ import annotations

import math
from functools import lru_cache

import casadi as ca
import numpy as np

from ...soilmodel.errors import DataError
from ...soilmodel.soil import SoilBounds
from ...soilmodel.traction import slip_factor_function

__all__ = ["grid_start", "start_point", "middle_of_bounds", "x0_vector"]


def middle_of_bounds(bounds: SoilBounds, model: str) -> np.ndarray:
    """Middle of the bounds ``[c, phi, K]`` (c = 0 for the cohesion-free model)."""
    theta = 0.5 * (bounds.lower + bounds.upper)
    if model == "cohesion-free":
        theta[0] = 0.0
    return theta


def start_point(pb, x0=None, how: str = "grid", n_grid: int = 25) -> tuple[np.ndarray, str]:
    """Start ``[c, phi, K]`` (SI) of a slip problem and a label saying where it came from.

    Parameters
    ----------
    pb : SlipProblem
    x0 : Soil or array_like, optional
        The user's start point (wins over ``how``).
    how : {"grid", "middle"}
        Variable-projection grid (:func:`grid_start`) or the middle of the bounds.
    n_grid : int
        K values of the grid.
    """
    if x0 is not None:
        theta = x0_vector(x0).copy()
        if pb.model == "cohesion-free":
            theta[0] = 0.0
        return theta, "user start point"
    if how == "middle":
        return middle_of_bounds(pb.bounds, pb.model), "middle of the bounds"
    theta = grid_start(
        pb.slip[None],
        pb.force[None],
        pb.load[None],
        pb.sigma[None],
        pb.vehicle.track_length,
        pb.vehicle.track_width,
        pb.model,
        pb.bounds,
        n_grid=n_grid,
    )[0]
    return theta, "variable-projection grid start"


@lru_cache(maxsize=32)
def _mapped_slip_factor(m: int) -> ca.Function:
    return slip_factor_function().map(m)


def _slip_factors(slip: np.ndarray, l: float, Ks: np.ndarray) -> np.ndarray:
    """``g(slip l / K)`` for every problem, K and sample: shape (N, len(Ks), n), one mapped CasADi call."""
    N, n = slip.shape
    S = np.broadcast_to(slip[:, None, :], (N, Ks.size, n))
    K = np.broadcast_to(Ks[None, :, None], (N, Ks.size, n))
    g = _mapped_slip_factor(S.size)(S.reshape(1, -1), l, K.reshape(1, -1))
    return np.asarray(g, dtype=float).reshape(N, Ks.size, n)


def grid_start(
    slip: np.ndarray,
    force: np.ndarray,
    load: np.ndarray,
    sigma: np.ndarray,
    l: float,
    b: float,
    model: str,
    bounds: SoilBounds,
    n_grid: int = 25,
) -> np.ndarray:
    """Start points ``[c, phi, K]`` (SI) for stacked problems, shape (N, 3).

    Parameters
    ----------
    slip, force, load, sigma : ndarray, shape (N, n)
    l, b : float
        Track length and width (m).
    model : {"full", "cohesion-free"}
    bounds : SoilBounds
    n_grid : int
        Number of K values (geometric grid over the K bounds).
    """
    slip, force, load, sigma = (np.atleast_2d(np.asarray(a, float)) for a in (slip, force, load, sigma))
    N = slip.shape[0]
    A = 2.0 * b * l
    (c_lo, c_hi), (p_lo, p_hi), (K_lo, K_hi) = bounds.cohesion, bounds.friction_angle, bounds.shear_modulus
    t_lo, t_hi = np.tan(p_lo), np.tan(p_hi)
    Ks = np.geomspace(K_lo, K_hi, n_grid)
    # axes: (problem, K value, sample)
    y = (force / sigma)[:, None, :]
    g = _slip_factors(slip, l, Ks)
    a2 = (load / sigma)[:, None, :] * g
    m22 = np.einsum("kgi,kgi->kg", a2, a2)
    r2 = np.einsum("kgi,kgi->kg", a2, y)
    with np.errstate(all="ignore"):
        if model == "full":
            a1 = (A / sigma)[:, None, :] * g
            m11 = np.einsum("kgi,kgi->kg", a1, a1)
            m12 = np.einsum("kgi,kgi->kg", a1, a2)
            r1 = np.einsum("kgi,kgi->kg", a1, y)
            det = m11 * m22 - m12 * m12
            ok = det > 1e-10 * m11 * m22
            c = np.where(ok, (m22 * r1 - m12 * r2) / np.where(ok, det, 1.0), 0.0)
            c = np.clip(np.where(np.isfinite(c), c, 0.0), c_lo, c_hi)
            t = (r2 - c * m12) / np.where(m22 > 0, m22, 1.0)
            t = np.clip(np.where(np.isfinite(t), t, t_lo), t_lo, t_hi)
            # one load (or tan(phi) clipped): refit c given tan(phi)
            c2 = (r1 - t * m12) / np.where(m11 > 0, m11, 1.0)
            c = np.where(ok, c, np.clip(np.where(np.isfinite(c2), c2, 0.0), c_lo, c_hi))
            res = y - c[..., None] * a1 - t[..., None] * a2
        else:
            t = r2 / np.where(m22 > 0, m22, 1.0)
            t = np.clip(np.where(np.isfinite(t), t, t_lo), t_lo, t_hi)
            c = np.zeros_like(t)
            res = y - t[..., None] * a2
    cost = np.einsum("kgi,kgi->kg", res, res)
    cost = np.where(np.isfinite(cost), cost, np.inf)
    kbest = np.argmin(cost, axis=1)
    rows = np.arange(N)
    return np.stack([c[rows, kbest], np.arctan(t[rows, kbest]), Ks[kbest]], axis=1)


def x0_vector(x0) -> np.ndarray:
    """Accept a Soil or ``[c, phi, K]`` in SI."""
    if hasattr(x0, "as_vector"):
        return np.asarray(x0.as_vector(), float)
    v = np.asarray(x0, float).ravel()
    if v.size != 3 or not np.all(np.isfinite(v)):
        raise DataError(f"x0 must be a Soil or [c (Pa), phi (rad), K (m)], got {x0!r}")
    if v[1] > math.pi / 2:
        raise DataError(f"x0 friction angle {v[1]} rad > pi/2: x0 is in SI (rad), not degrees")
    return v
