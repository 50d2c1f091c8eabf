"""Vectorised numpy twin of Eq. 2 and its exact derivatives (for batched solvers and start points).

Same formula as :mod:`soiltrack.soilmodel.traction` (series of the shear bracket below
``x = 0.05``, ``F(i) = -F(|i|)`` for skid); the tests check both agree to rounding. Working
on stacked arrays (leading axes = many problems) avoids one CasADi call per problem, which
is what makes :func:`~soiltrack.identify.fit_many` fast.
"""
from __future__ import annotations

import numpy as np

SERIES_SWITCH = 0.05  # same switch as soilmodel.traction


def bracket(x: np.ndarray, derivative: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """``g(x) = 1 - (1 - exp(-x))/x`` and ``g'(x)`` (None if not asked) for x >= 0 (series near 0)."""
    x = np.asarray(x, dtype=float)
    small = x < SERIES_SWITCH
    xs = np.where(small, 1.0, x)
    e = np.expm1(-xs)
    g_exact = 1.0 + e / xs
    xz = np.where(small, x, 0.0)
    g_ser = xz * (1 / 2 + xz * (-1 / 6 + xz * (1 / 24 + xz * (-1 / 120 + xz * (1 / 720 + xz * (-1 / 5040 + xz / 40320))))))
    g = np.where(small, g_ser, g_exact)
    if not derivative:
        return g, None
    # g'(x) = (1 - (1 + x) exp(-x)) / x^2 = (-expm1(-x) - x exp(-x)) / x^2
    dg_exact = (-e - xs * (e + 1.0)) / (xs * xs)
    dg_ser = 1 / 2 + xz * (-2 / 6 + xz * (3 / 24 + xz * (-4 / 120 + xz * (5 / 720 + xz * (-6 / 5040 + xz * 7 / 40320)))))
    return g, np.where(small, dg_ser, dg_exact)


def thrust_and_jacobian(theta: np.ndarray, slip: np.ndarray, W: np.ndarray, l: float, b: float,
                        model: str = "full") -> tuple[np.ndarray, np.ndarray]:
    """Tractive force and ``dF/d[c, phi, K]`` for stacked problems.

    Parameters
    ----------
    theta : ndarray, shape (..., 3)
        ``[c (Pa), phi (rad), K (m)]`` per problem.
    slip, W : ndarray, shape (..., n)
        Slip and normal load per sample.
    l, b : float
        Track length and width of one track (m).
    model : {"full", "cohesion-free"}

    Returns
    -------
    F : ndarray, shape (..., n)
    J : ndarray, shape (..., n, 3)
    """
    c = theta[..., 0:1]
    phi = theta[..., 1:2]
    K = theta[..., 2:3]
    A = 2.0 * b * l
    s = np.sign(slip)
    x = np.abs(slip) * l / K
    g, dg = bracket(x)
    t = np.tan(phi)
    cf = model == "cohesion-free"
    fmax = W * t + (0.0 if cf else A * c)
    F = fmax * s * g
    dF_dc = np.zeros_like(F) if cf else A * s * g
    dF_dphi = W * (1.0 + t * t) * s * g
    dF_dK = fmax * s * dg * (-x / K)
    return F, np.stack([dF_dc, dF_dphi, dF_dK], axis=-1)
