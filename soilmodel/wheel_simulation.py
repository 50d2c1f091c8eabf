"""Simulated single-wheel rig sweeps from the one rigid-wheel model (:mod:`.wheel`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import DataError
from .rigid_wheel import RigidWheel
from .soil import Soil
from .wheel import (
    DEFAULT_WHEEL_SETTINGS,
    WheelSettings,
    evaluate,
    sinkage_from_load_function,
    wheel_forces_function,
)
from .wheel_sweep import WheelSweep

__all__ = ["WheelNoise", "DEFAULT_WHEEL_NOISE", "DEFAULT_WHEEL_SLIPS", "simulate_wheel_sweep"]

#: Smallest sinkage a simulated rig reports, m (noise cannot make it zero or negative).
MIN_SINKAGE_M = 1e-4
#: Slips of a simulated wheel sweep when none are given.
DEFAULT_WHEEL_SLIPS = (0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)


@dataclass(frozen=True)
class WheelNoise:
    """Measurement noise of a simulated wheel rig (independent, Gaussian).

    Parameters
    ----------
    drawbar_pull_rel
        Standard deviation of the drawbar pull as a fraction of the row's normal load
        (a force sensor's noise scales with its range, which is set by the load).
    sinkage_m
        Standard deviation of the sinkage reading, m.
    """

    drawbar_pull_rel: float = 0.005
    sinkage_m: float = 0.0005


DEFAULT_WHEEL_NOISE = WheelNoise()


def simulate_wheel_sweep(
    wheel: RigidWheel,
    soil: Soil,
    *,
    slips=DEFAULT_WHEEL_SLIPS,
    normal_loads=(20.0,),
    noise: WheelNoise | None = DEFAULT_WHEEL_NOISE,
    seed: int | None = None,
    settings: WheelSettings = DEFAULT_WHEEL_SETTINGS,
    slip_sinkage: float = 0.0,
) -> WheelSweep:
    """A drawbar pull-slip sweep of ``wheel`` on ``soil`` at every slip and load (sinkage included).

    The sinkage of each row solves the wheel's vertical balance for its load; the drawbar pull
    follows from the Wong-Reece stresses (:func:`~.wheel.wheel_expr`). ``noise=None``: exact;
    ``slip_sinkage`` the coefficient of that effect (0: none).
    The soil needs Bekker n, k_c and k_phi (a terrain preset has them).
    """
    if soil.n is None or soil.k_c is None or soil.k_phi is None:
        raise DataError(
            "a rigid wheel's sinkage needs the soil's Bekker n, k_c and k_phi: use a terrain preset "
            "(--terrain) or give them"
        )
    slips = np.asarray(slips, dtype=float)
    loads = np.asarray(normal_loads, dtype=float)
    if np.any((slips < 0) | (slips >= 1)) or np.any(loads <= 0):
        raise DataError("a wheel sweep needs slips in [0, 1) and loads > 0 N")
    i = np.tile(slips, loads.size)
    W = np.repeat(loads, slips.size)
    args = (
        soil.cohesion,
        soil.friction_angle,
        soil.shear_modulus,
        soil.k_c,
        soil.k_phi,
        soil.n,
        slip_sinkage,
    )
    r, b, h = wheel.radius, wheel.width, wheel.grouser_height
    (z,) = evaluate(sinkage_from_load_function(r, b, h, settings), i, W, *args)
    dp, wl, _ = evaluate(wheel_forces_function(r, b, h, settings), i, z, *args)
    if not np.allclose(wl, W, rtol=1e-8):
        raise DataError(
            f"the wheel's vertical balance has no solution for these loads (largest miss "
            f"{np.max(np.abs(wl - W)):.3g} N): the wheel would sink past its axle"
        )
    if noise is not None:
        rng = np.random.default_rng(seed)
        dp = dp + rng.normal(0.0, 1.0, dp.size) * noise.drawbar_pull_rel * W
        z = np.maximum(z + rng.normal(0.0, noise.sinkage_m, z.size), MIN_SINKAGE_M)
    return WheelSweep(
        slip=i,
        drawbar_pull=dp,
        normal_load=W,
        sinkage=z,
        source=f"simulated wheel sweep ({soil.name or 'soil'})",
    )
