"""The slip-optimal point of a believed thrust law: the traction study's drawbar-power optimum, fast.

:func:`~soiltrack.planning.slip_optimal` (the traction study) maximises the drawbar power
``(F(i) - R) r w (1 - i)`` on a slip grid refined by golden section; one call takes tens of ms.
A controller asks at every sample, so :func:`optimal_slip` evaluates the same objective on the
same slip grid from a table of the slip factor ``g(i l / K)`` (Eq. 2's bracket, soilmodel's
:func:`~soiltrack.soilmodel.traction.slip_factor_function`, one mapped call per vehicle) over
200 log-spaced K in [2 mm, 0.25 m]: ``P(i) ∝ (g(i l / K) - R / F_max) (1 - i)``, K interpolated
between rows. With slip sinkage (soilmodel's ``slip_sinkage`` effect, extra resistance ``N mu_s i``) the
objective is ``(g(i l / K) - R / F_max - N mu_s i / F_max) (1 - i)``. It agrees with ``slip_optimal``
(tests/test_control.py checks it) to the grid's resolution; :func:`optimal_slip_reference` is the
traction study's own answer.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ...soilmodel import Soil, Vehicle
from ...soilmodel.traction import slip_factor_function
from ..slip_optimal import slip_optimal
from .belief import patch_load

__all__ = ["optimal_slip", "optimal_slip_on_load", "optimal_slip_reference"]

_K = np.geomspace(0.002, 0.25, 200)


@lru_cache(maxsize=1)
def _grid() -> np.ndarray:
    """The traction study's slip grid (``SlipOptimum.slip``: 1e-4 to 0.99, finer below 5 %)."""
    return np.asarray(slip_optimal(Soil(0.0, 0.5, 0.01), Vehicle(1.0, 1.0, 0.1, 0.1, 0.0, 0.05)).slip, dtype=float)


@lru_cache(maxsize=16)
def _table(track_length: float) -> np.ndarray:
    """``g(i l / K)`` on (K rows, slip grid columns), one mapped CasADi call."""
    S, KK = np.meshgrid(_grid(), _K)
    f = slip_factor_function().map(S.size)
    return np.asarray(f(S.reshape(1, -1), track_length, KK.reshape(1, -1)), dtype=float).reshape(S.shape)


def _resistance(vehicle: Vehicle, grade_deg: float) -> float:
    g = math.radians(grade_deg)
    return vehicle.rolling_resistance * patch_load(vehicle, grade_deg) + vehicle.weight * math.sin(g)


def optimal_slip(
    vehicle: Vehicle, max_thrust_N: float, shear_modulus_m: float, grade_deg: float, slip_sinkage: float = 0.0
) -> float | None:
    """Slip of the largest drawbar power for the thrust law ``(F_max, K)`` on the grade (``slip_sinkage``: the
    ``mu_s`` of the extra resistance ``N mu_s i``); ``None``: no drawbar pull.

    Cached on a grid of 0.2 % in ``R / F_max`` and ``N mu_s / F_max`` and 0.5 % in K (the answer moves far
    less in between).
    """
    return optimal_slip_on_load(
        vehicle.track_length,
        max_thrust_N,
        shear_modulus_m,
        _resistance(vehicle, grade_deg),
        patch_load(vehicle, grade_deg),
        slip_sinkage,
    )


def optimal_slip_on_load(
    track_length: float,
    max_thrust_N: float,
    shear_modulus_m: float,
    resistance_N: float,
    normal_load_N: float,
    slip_sinkage: float = 0.0,
) -> float | None:
    """:func:`optimal_slip` with the patch's rolling and grade resistance and normal load given (N): a
    controller that holds them per patch asks this at every sample (the vehicle's hash for the cached load
    and the resistance's sine cost more than the answer's cached look-up)."""
    F = max(max_thrust_N, 1e-9)
    return _optimal(
        track_length,
        round(resistance_N / F / 0.002),
        round(math.log(max(shear_modulus_m, 1e-6)) / 0.005),
        round(normal_load_N * slip_sinkage / F / 0.002),
    )


@lru_cache(maxsize=65536)
def _optimal(track_length: float, k_rho: int, k_K: int, k_sigma: int = 0) -> float | None:
    G = _table(track_length)
    rho = k_rho * 0.002
    u = float(np.interp(k_K * 0.005, np.log(_K), np.arange(_K.size)))
    j = int(u)
    f = u - j
    g = G[j] if f == 0 or j + 1 >= _K.size else (1 - f) * G[j] + f * G[j + 1]
    grid = _grid()
    P = (g - rho - k_sigma * 0.002 * grid) * (1 - grid)
    k = int(np.argmax(P))
    return None if P[k] <= 0 else float(grid[k])


def optimal_slip_reference(
    vehicle: Vehicle, max_thrust_N: float, shear_modulus_m: float, grade_deg: float
) -> float | None:
    """The traction study's power-optimal slip for the same law (the cohesion-free soil of that F_max)."""
    N = patch_load(vehicle, grade_deg)
    phi = min(max(math.atan(max_thrust_N / N), 1e-3), math.pi / 2 - 1e-3)
    return slip_optimal(Soil(0.0, phi, shear_modulus_m), vehicle, grade_deg=grade_deg).slip_max_power
