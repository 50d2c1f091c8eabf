"""The vehicle and track-terrain model, written symbolically in CasADi, and its data.

Public names: :class:`Soil`, :class:`Vehicle`, :data:`TERRAINS`, :data:`VEHICLES`,
:data:`PRACTICAL_BOUNDS`, :func:`tractive_force`, :func:`read_csv`, :func:`write_csv`,
:class:`SlipData`, :class:`DriveLog`, :class:`DataError`.
"""
from .data import DriveLog, SlipData, read_csv, write_csv
from .errors import DataError
from .soil import PARAMETER_NAMES, PRACTICAL_BOUNDS, SEED_ACTUAL, TERRAINS, Soil, SoilBounds
from .traction import (
    MODELS,
    max_thrust,
    sensitivity_function,
    thrust_expr,
    thrust_function,
    tractive_force,
    tractive_force_sensitivities,
)
from .vehicle import G, VEHICLES, Vehicle

__all__ = [
    "DataError", "DriveLog", "SlipData", "read_csv", "write_csv", "PARAMETER_NAMES", "PRACTICAL_BOUNDS",
    "SEED_ACTUAL", "TERRAINS", "Soil", "SoilBounds", "MODELS", "max_thrust", "sensitivity_function",
    "thrust_expr", "thrust_function", "tractive_force", "tractive_force_sensitivities", "G", "VEHICLES",
    "Vehicle",
]
