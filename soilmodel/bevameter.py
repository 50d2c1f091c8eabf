"""The soil's stress laws as a bevameter measures them: their one home (docs/measured-data.md).

Janosi-Hanamoto shear (a shear ring or shear box at normal pressure sigma, shear displacement j)::

    tau = (c + sigma tan(phi)) (1 - exp(-j / K))

Bekker pressure-sinkage (a plate of width b - the smaller dimension; the radius of a circular
plate - pressed to sinkage z)::

    p = (k_c / b + k_phi) z^n

Both are CasADi expressions (floats work too), built once into CasADi Functions; the numpy
helpers :func:`shear_stress` and :func:`plate_pressure` evaluate them. The track's thrust
(Eq. 2) is the shear law integrated over a track under uniform pressure; the static sinkage
of :mod:`.sinkage` is the pressure law solved for z. ``exp`` is written ``-expm1(-j / K)``
so that small displacements lose no digits.

A shear annulus (inner radius r_i, outer r_o) turned by theta records its torque; the shear
displacement grows with the radius, j = r theta, so the torque is the shear law integrated
across the ring (:func:`annulus_torque_expr`)::

    T = 2 pi int_{r_i}^{r_o} r^2 tau(r theta, sigma) dr

by :data:`ANNULUS_NODES`-point Gauss-Legendre quadrature (the integrand is smooth: against the
closed form of the integral the relative error is below 1e-12 for theta r_o / K up to 100,
checked in tests/test_bevameter_records.py).

Units: SI (Pa, m, rad); k_c in N/m^(n+1), k_phi in N/m^(n+2).
"""

from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

__all__ = [
    "shear_stress_expr",
    "plate_pressure_expr",
    "shear_stress_function",
    "plate_pressure_function",
    "shear_stress",
    "plate_pressure",
    "MIN_RELATIVE_SINKAGE",
    "ANNULUS_NODES",
    "annulus_torque_expr",
    "annulus_torque",
    "ring_torque_per_stress",
]

#: Gauss-Legendre nodes across a shear annulus's ring (see the module text for the error).
ANNULUS_NODES = 16

#: Floor of ``z / z_ref`` inside ``log`` in ``z^n = exp(n log z)``: keeps the branch CasADi also
#: evaluates at z = 0 finite (the pressure there is exactly 0, and so are its derivatives).
MIN_RELATIVE_SINKAGE = 1e-12


def shear_stress_expr(j, sigma, c, phi, K):
    """Janosi-Hanamoto shear stress ``(c + sigma tan(phi)) (1 - exp(-j / K))``, Pa.

    Parameters
    ----------
    j
        Shear displacement, m (>= 0).
    sigma
        Normal pressure, Pa.
    c, phi, K
        Cohesion (Pa), internal friction angle (rad), shear deformation modulus (m).
    """
    return (c + sigma * ca.tan(phi)) * -ca.expm1(-j / K)


def plate_pressure_expr(z, b, k_c, k_phi, n, z_ref=1.0):
    """Bekker plate pressure ``(k_c / b + k_phi) z^n``, Pa.

    Written as ``(k_c / b + k_phi) z_ref^n (z / z_ref)^n`` with ``(z / z_ref)^n = exp(n log(z / z_ref))``
    (``z_ref`` > 0, m; any value gives the same pressure - a fit picks the data's typical
    sinkage so that its parameters are weakly correlated).

    Parameters
    ----------
    z
        Sinkage, m (>= 0).
    b
        Plate width (smaller dimension; radius of a circular plate), m.
    k_c, k_phi, n
        Bekker moduli (N/m^(n+1), N/m^(n+2)) and exponent (-).
    """
    ratio = ca.fmax(z / z_ref, MIN_RELATIVE_SINKAGE)
    return ca.if_else(z > 0, (k_c / b + k_phi) * z_ref**n * ca.exp(n * ca.log(ratio)), 0)


def ring_torque_per_stress(r_i, r_o):
    """Torque of a uniform unit shear stress on the ring, ``2 pi (r_o^3 - r_i^3) / 3`` (m^3)."""
    return 2 * np.pi * (r_o**3 - r_i**3) / 3


def annulus_torque_expr(theta, sigma, c, phi, K, r_i, r_o, nodes: int = ANNULUS_NODES):
    """Torque of a shear annulus turned by ``theta`` (rad) at normal pressure ``sigma``, N m.

    ``T = 2 pi int_{r_i}^{r_o} r^2 tau(r theta, sigma) dr`` with the Janosi-Hanamoto
    :func:`shear_stress_expr` at ``nodes`` Gauss-Legendre points (symbolic or numeric; columns
    of equal length or scalars).
    """
    x, w = np.polynomial.legendre.leggauss(nodes)
    half = (r_o - r_i) / 2
    total = 0
    for xk, wk in zip(x, w):
        r = r_i + half * (xk + 1)
        total = total + wk * r**2 * shear_stress_expr(r * theta, sigma, c, phi, K)
    return 2 * np.pi * half * total


@lru_cache(maxsize=1)
def annulus_torque_function() -> ca.Function:
    """CasADi Function ``T(theta, sigma, c, phi, K, r_i, r_o)`` (SI), built once."""
    names = ("theta", "sigma", "c", "phi", "K", "r_i", "r_o")
    s = [ca.SX.sym(n) for n in names]
    return ca.Function(
        "annulus_torque", s, [annulus_torque_expr(s[0], s[1], s[2], s[3], s[4], s[5], s[6])], list(names), ["T"]
    )


def annulus_torque(theta, sigma, c: float, phi: float, K: float, r_i, r_o) -> np.ndarray:
    """:func:`annulus_torque_expr` at many points (numpy, broadcast), N m."""
    return _call(annulus_torque_function(), theta, sigma, c, phi, K, r_i, r_o)


@lru_cache(maxsize=1)
def shear_stress_function() -> ca.Function:
    """CasADi Function ``tau(j, sigma, c, phi, K)`` (SI), built once."""
    s = [ca.SX.sym(n) for n in ("j", "sigma", "c", "phi", "K")]
    return ca.Function("shear_stress", s, [shear_stress_expr(*s)], ["j", "sigma", "c", "phi", "K"], ["tau"])


@lru_cache(maxsize=1)
def plate_pressure_function() -> ca.Function:
    """CasADi Function ``p(z, b, k_c, k_phi, n)`` (SI), built once."""
    s = [ca.SX.sym(n) for n in ("z", "b", "k_c", "k_phi", "n")]
    return ca.Function("plate_pressure", s, [plate_pressure_expr(*s)], ["z", "b", "k_c", "k_phi", "n"], ["p"])


def _call(f: ca.Function, *args) -> np.ndarray:
    arrays = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in args))
    shape = arrays[0].shape
    if arrays[0].size == 0:
        return np.zeros(shape)
    rows = [a.reshape(1, -1) for a in arrays]
    return np.asarray(f.map(rows[0].shape[1])(*rows), dtype=float).reshape(shape)


def shear_stress(j, sigma, c: float, phi: float, K: float) -> np.ndarray:
    """:func:`shear_stress_expr` at many points (numpy, broadcast), Pa."""
    return _call(shear_stress_function(), j, sigma, c, phi, K)


def plate_pressure(z, b, k_c: float, k_phi: float, n: float) -> np.ndarray:
    """:func:`plate_pressure_expr` at many points (numpy, broadcast), Pa."""
    return _call(plate_pressure_function(), z, b, k_c, k_phi, n)
