"""What a drawbar-pull test rig reports: the slip-sweep measurement with effects (symbolic).

One home for the observation model of slip sweeps, used by the simulator
(:func:`~soiltrack.soilmodel.simulate_slip_sweep`) and by every slip fit.
"""

from __future__ import annotations

from typing import Any

from .effect_registry import EffectValues
from .effect_terms import motion_resistance
from .errors import DataError
from .thrust_effects import thrust_with_effects
from .vehicle import Vehicle

__all__ = ["DEFAULT_RIG_SPEED", "SWEEP_MEASURES", "rig_true_slip", "sweep_measurement"]

#: Track speed ``r w`` of a drawbar-pull rig when none is given, m/s (sets the vehicle speed).
DEFAULT_RIG_SPEED = 0.5
#: What a slip sweep may have measured (the CSV column is the name with ``_N``).
SWEEP_MEASURES = ("tractive_force", "drawbar_pull")


def rig_true_slip(i_app, vehicle: Vehicle, effects: Any = None):
    """True slip from the slip a rig computes with the nominal radius (``radius_error``).

    ``1 - v / (r_eff w) = (i + eps) / (1 + eps)``: ``eps = 0`` gives ``i`` exactly.
    """
    ev = effects if isinstance(effects, EffectValues) else EffectValues(effects, vehicle)
    if not ev.on("radius_error"):
        return i_app
    eps = ev["radius_error", "eps"]
    return (i_app + eps) / (1 + eps)


def sweep_measurement(
    i_app,
    W,
    c,
    phi,
    K,
    vehicle: Vehicle,
    effects: Any = None,
    model: str = "full",
    measured: str = "tractive_force",
    rig_speed: Any = DEFAULT_RIG_SPEED,
):
    """What a drawbar-pull rig reports at apparent slip ``i_app`` and nominal load ``W`` (symbolic).

    The rig runs the track at speed ``r w = rig_speed`` (so ``v = rig_speed (1 - i_app)``)
    and measures the drawbar pull ``DP = F(i) - R`` with ``F`` the thrust with effects
    (:func:`thrust_with_effects`, at the true slip :func:`rig_true_slip`) and ``R`` the actual
    motion resistance (:func:`motion_resistance`). A rig reporting "tractive force" adds the
    NOMINAL resistance back (the usual conversion): ``F_rep = DP + W mu_r``, so resistance
    effects show there as lost force. With no effect on, ``F_rep = F(i)`` exactly.

    Returns
    -------
    i_true, thrust, reported
        True slip, thrust (N) and the reported quantity (N).
    """
    if measured not in SWEEP_MEASURES:
        raise DataError(f"unknown measured quantity {measured!r}; expected one of {SWEEP_MEASURES}")
    ev = effects if isinstance(effects, EffectValues) else EffectValues(effects, vehicle)
    v = rig_speed * (1 - i_app)
    i_true = rig_true_slip(i_app, vehicle, ev)
    F = thrust_with_effects(i_true, c, phi, K, W, vehicle, ev, model)
    # a rig's carriage keeps moving forward (v = r w (1 - i) > 0 for i < 1): the resistance is the
    # textbook constant term, not faded out near standstill as in a drive (which made a step in the
    # curve near i = 0.98)
    R = motion_resistance(v, i_true, vehicle, ev, W=W, standstill_speed=None)
    if measured == "drawbar_pull":
        return i_true, F, F - R
    # F - (R - R_nominal): exactly F when no resistance effect is on
    return i_true, F, F - (R - motion_resistance(v, i_true, vehicle, None, W=W, standstill_speed=None))
