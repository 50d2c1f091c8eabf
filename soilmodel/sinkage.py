"""Bekker sinkage and compaction resistance (docs/physics.md): their one home.

Static sinkage of a track of width b under uniform pressure p = N / A (N the normal load,
A = 2 b l both tracks)::

    z0 = (p / (k_c / b + k_phi)) ** (1 / n)

and the compaction resistance of both tracks (the work of pressing a rut of depth z0 per
metre travelled)::

    R_c = 2 b (k_c / b + k_phi) z0 ** (n + 1) / (n + 1)

Written once as CasADi expressions (floats work too); :func:`static_sinkage` and
:func:`compaction_resistance` are the numpy helpers. Slip-induced sinkage (for stuck
prediction) follows Lyasko's empirical relation (J. Terramechanics 47, 2010)::

    z = z0 (1 + i) / (1 - 0.5 i)          (z = 4 z0 at full slip)

one law among several (others give other numbers); :func:`slip_sinkage_expr` writes it with a
free exponent ``s`` of its factor, ``z = z0 [(1 + i) / (1 - 0.5 i)] ** s`` (``s = 1`` the law,
``s = 0`` no slip sinkage), the form a measured sinkage channel is tested against;
:func:`slip_sinkage` is the numpy helper and :func:`slip_at_sinkage` its inverse. The compaction
resistance at a given sinkage z (the rut's work per metre, both tracks) is
:func:`compaction_at_sinkage_expr`; :func:`compaction_expr` is its value at z0. A soil without
Bekker parameters (``n``, ``k_c``, ``k_phi`` of :class:`~.soil.Soil` unset) has no compaction
term: the helpers return 0 and :func:`has_bekker` says so.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from .soil import Soil
from .vehicle import Vehicle

__all__ = [
    "has_bekker",
    "sinkage_expr",
    "compaction_expr",
    "compaction_at_sinkage_expr",
    "slip_sinkage_expr",
    "static_sinkage",
    "compaction_resistance",
    "slip_sinkage",
    "slip_at_sinkage",
]


def has_bekker(soil: Soil) -> bool:
    """True when the soil carries Bekker n, k_c and k_phi."""
    return soil.n is not None and soil.k_c is not None and soil.k_phi is not None


def sinkage_expr(N, n, k_c, k_phi, track_length, track_width):
    """Static Bekker sinkage ``z0`` in m (symbolic or float); ``N`` the normal load of both tracks, N."""
    p = N / (2 * track_width * track_length)
    return (ca.fmax(p, 0) / (k_c / track_width + k_phi)) ** (1.0 / n)


def compaction_at_sinkage_expr(z, n, k_c, k_phi, track_width):
    """Bekker compaction resistance of both tracks at sinkage ``z`` (m): ``2 b k z^(n+1) / (n+1)``, N."""
    return 2 * track_width * (k_c / track_width + k_phi) * z ** (n + 1) / (n + 1)


def compaction_expr(N, n, k_c, k_phi, track_length, track_width):
    """Bekker compaction resistance of both tracks ``R_c``, N (symbolic or float)."""
    z0 = sinkage_expr(N, n, k_c, k_phi, track_length, track_width)
    return compaction_at_sinkage_expr(z0, n, k_c, k_phi, track_width)


def _eval(expr_fn, soil: Soil, vehicle: Vehicle, normal_load) -> float | np.ndarray:
    N = vehicle.weight if normal_load is None else normal_load
    N = np.asarray(N, dtype=float)
    if not has_bekker(soil):
        out = np.zeros_like(N)
    else:
        out = np.asarray(
            ca.evalf(
                expr_fn(
                    ca.DM(N.reshape(-1, 1)), soil.n, soil.k_c, soil.k_phi, vehicle.track_length, vehicle.track_width
                )
            ),
            dtype=float,
        ).reshape(N.shape)
    return out if out.ndim else float(out)


def static_sinkage(soil: Soil, vehicle: Vehicle, normal_load=None) -> float | np.ndarray:
    """Static sinkage z0 in m (0 without Bekker parameters); ``normal_load`` default W = m g."""
    return _eval(sinkage_expr, soil, vehicle, normal_load)


def compaction_resistance(soil: Soil, vehicle: Vehicle, normal_load=None) -> float | np.ndarray:
    """Compaction resistance R_c of both tracks in N (0 without Bekker parameters)."""
    return _eval(compaction_expr, soil, vehicle, normal_load)


def slip_sinkage_expr(z0, slip, exponent=1.0):
    """Slip sinkage ``z0 [(1 + |i|) / (1 - 0.5 |i|)] ** exponent``, m (symbolic or numpy).

    ``exponent`` 1 is Lyasko's law, 0 a sinkage that does not grow with the slip.
    """
    symbolic = isinstance(slip, (ca.SX, ca.MX, ca.DM))
    i = ca.fabs(slip) if symbolic else np.abs(slip)
    return z0 * ((1 + i) / (1 - 0.5 * i)) ** exponent


def slip_sinkage(z0, slip, exponent: float = 1.0):
    """Lyasko's slip sinkage ``z0 (1 + |i|) / (1 - 0.5 |i|)``, m (numpy; :func:`slip_sinkage_expr`)."""
    return slip_sinkage_expr(np.asarray(z0, dtype=float), np.asarray(slip, dtype=float), exponent)


def slip_at_sinkage(z0: float, z: float) -> float:
    """Slip at which :func:`slip_sinkage` reaches ``z`` (>= 1 when only beyond full slip)."""
    q = z / z0
    return (q - 1) / (1 + 0.5 * q)
