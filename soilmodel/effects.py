"""Unmodelled physical effects (docs/physics.md): the public face of the effect modules.

The effects are split by concept; every name stays importable from here:

- :mod:`.effect_registry`: the registry (:data:`EFFECTS`, :class:`ParamSpec`, :class:`EffectSpec`),
  :class:`EffectSet`, :func:`parse_effects`, :func:`effect_symbols`, physical ranges and scales;
- :mod:`.effect_terms`: motion resistance, drivetrain torque loss, effective radius, mass, weight
  and normal load;
- :mod:`.thrust_effects`: the tractive force with effects (hump shear, pressure distribution);
- :mod:`.rig`: what a drawbar-pull rig reports (tractive force or drawbar pull).
"""

from .effect_registry import (
    EFFECTS,
    EffectSet,
    EffectSpec,
    ParamSpec,
    effect_spec,
    EffectValues,
    effect_structure,
    effect_symbols,
    parameter_bounds,
    parameter_scale,
    parse_effects,
)
from .effect_terms import (
    DEFAULT_SLIP_WIDTH,
    DEFAULT_STANDSTILL_SPEED,
    effective_mass,
    effective_normal_load,
    effective_radius,
    effective_weight,
    motion_resistance,
    normal_load_function,
    smooth_abs,
    smooth_sign,
    torque_loss,
)
from .rig import DEFAULT_RIG_SPEED, SWEEP_MEASURES, rig_true_slip, sweep_measurement
from .thrust_effects import (
    pressure_profile,
    softening_shear,
    thrust_with_effects,
    thrust_with_effects_function,
    tractive_force_with_effects,
    wong_type_b_shear,
)

__all__ = [
    "ParamSpec",
    "EffectValues",
    "effect_spec",
    "effect_structure",
    "EffectSpec",
    "EFFECTS",
    "EffectSet",
    "parse_effects",
    "effect_symbols",
    "DEFAULT_STANDSTILL_SPEED",
    "DEFAULT_SLIP_WIDTH",
    "smooth_sign",
    "smooth_abs",
    "effective_mass",
    "effective_weight",
    "effective_normal_load",
    "effective_radius",
    "motion_resistance",
    "torque_loss",
    "thrust_with_effects",
    "thrust_with_effects_function",
    "tractive_force_with_effects",
    "softening_shear",
    "wong_type_b_shear",
    "pressure_profile",
    "DEFAULT_RIG_SPEED",
    "SWEEP_MEASURES",
    "parameter_bounds",
    "parameter_scale",
    "effect_structure",
    "rig_true_slip",
    "sweep_measurement",
    "normal_load_function",
]
