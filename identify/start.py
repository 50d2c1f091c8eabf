"""Start points by variable projection: a grid on K, linear least squares for the rest.

For a fixed K the tractive force is LINEAR in ``(c, tan(phi))``:
``F_k = (A c + W_k tan(phi)) g(i_k l / K)``. So for each K on a geometric grid over its
bounds the best ``(c, tan(phi))`` follow from a 2x2 (or 1x1) weighted linear least-squares
problem, are projected onto the bounds, and the grid point of lowest cost is the start.
This is a global search over the only nonlinear parameter; the local solver then refines.
Vectorised over many problems at once (leading axis N).
"""
from __future__ import annotations

import numpy as np

from ..soilmodel.soil import SoilBounds
from .npmodel import bracket

__all__ = ["grid_start"]


def grid_start(slip: np.ndarray, force: np.ndarray, load: np.ndarray, sigma: np.ndarray, l: float, b: float,
               model: str, bounds: SoilBounds, n_grid: int = 25) -> np.ndarray:
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
    g = np.sign(slip)[:, None, :] * bracket(np.abs(slip)[:, None, :] * l / Ks[None, :, None], derivative=False)[0]
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
