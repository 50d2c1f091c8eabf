"""Where the nominal misfit lies: by channel and by range of slip, speed and time (:func:`~.gap.localise`)."""

from __future__ import annotations

import numpy as np

from .gap import Segment, localise
from .setup import Setup

__all__ = ["localisation", "variables"]

#: Sprocket rim speeds below this share of the run's largest give no usable apparent slip (set to 0).
MIN_RIM_SHARE = 0.05


def variables(setup: Setup) -> dict[str, np.ndarray]:
    """Localisation variables per sample: slip (apparent, from the speeds, for a log), speed, time."""
    data = setup.data
    if not setup.is_log:
        return {"slip": np.asarray(data.slip, dtype=float)}
    v = np.asarray(data.vehicle_speed, dtype=float)
    rw = setup.runner.vehicle.sprocket_radius * np.asarray(data.sprocket_speed, dtype=float)
    big = rw > MIN_RIM_SHARE * max(1e-9, float(np.max(np.abs(rw))))
    slip = np.where(big, 1.0 - v / np.where(rw == 0, 1.0, rw), 0.0)
    return {"time": np.asarray(data.time, dtype=float), "speed": v, "slip": np.clip(slip, -1.0, 1.0)}


def localisation(setup: Setup) -> list[Segment]:
    """Segments of the nominal model's full-data residuals, by share of the misfit above the noise."""
    R, sg = setup.residuals, setup.sigma
    common = np.logical_and.reduce([np.isfinite(R[ch]) & np.isfinite(sg[ch]) for ch in setup.channels])
    return localise(
        {ch: R[ch][common] for ch in setup.channels},
        {ch: sg[ch][common] for ch in setup.channels},
        {k: v[common] for k, v in variables(setup).items()},
        alpha=setup.settings.alpha,
    )
