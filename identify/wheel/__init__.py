"""Identification of the soil from single-wheel rig sweeps with the rigid-wheel model.

Public names: :func:`fit_wheel`, :class:`WheelFitOptions`, :class:`WheelFitResult`,
:class:`WheelBounds`, :data:`DEFAULT_WHEEL_BOUNDS`, :data:`WHEEL_PARAMETERS`,
:func:`soil_from_wheel_fit`, :func:`pure_error` (the repeats' scatter per slip level).
"""

from .fitting import WheelFitOptions, fit_wheel, soil_from_wheel_fit
from .problem import DEFAULT_WHEEL_BOUNDS, WHEEL_PARAMETERS, WheelBounds
from .result import WheelFitResult, pure_error

__all__ = [
    "fit_wheel",
    "WheelFitOptions",
    "WheelFitResult",
    "WheelBounds",
    "DEFAULT_WHEEL_BOUNDS",
    "WHEEL_PARAMETERS",
    "soil_from_wheel_fit",
    "pure_error",
]
