"""The vehicle and track-terrain model, written symbolically in CasADi, and its data.

Public names: :class:`Soil`, :class:`Vehicle`, :data:`TERRAINS`, :data:`VEHICLES`,
:data:`PRACTICAL_BOUNDS`, :data:`WIDE_BOUNDS`, :func:`tractive_force`, :func:`read_csv`, :func:`write_csv`,
:class:`SlipData` (tractive force or drawbar pull), :class:`DriveLog`, :class:`ShearTest` and
:class:`PlateTest` (bevameter tests), :class:`DataError`; the soil's stress laws (:func:`shear_stress_expr`,
:func:`plate_pressure_expr`: Janosi-Hanamoto shear, Bekker pressure-sinkage); the
unmodelled effects (:data:`EFFECTS`, :func:`parse_effects`, :func:`thrust_with_effects`,
:func:`sweep_measurement`: what a drawbar-pull rig reports), the dynamics
(:func:`dynamics_function`, :func:`slip_from_thrust`) and the simulator (:func:`simulate`); units
by magnitude for reports and figures (:func:`format_force`, :func:`format_torque`,
:func:`format_power`, :func:`format_energy`, :func:`choose_scale`).
Skid steering (Wong-Chiang): :func:`steady_turn`, :class:`SteadyTurn`, :class:`SteeringSettings`;
two-track logs with turns: :class:`TwoTrackLog`, :func:`read_two_track`, :func:`simulate_turning_log`.
The rigid wheel on a rig: :class:`RigidWheel`, :func:`read_running_gear` (track or wheel JSON),
:func:`wheel_expr` (the Wong-Reece stresses integrated), :class:`WheelSettings`,
:class:`WheelSweep`, :func:`read_wheel_sweep`, :func:`simulate_wheel_sweep`.
"""

from .data import DriveLog, PlateTest, ShearTest, SlipData, read_csv, write_csv
from .bevameter import (
    plate_pressure,
    plate_pressure_expr,
    plate_pressure_function,
    shear_stress,
    shear_stress_expr,
    shear_stress_function,
)
from .errors import DataError
from .soil import PARAMETER_NAMES, PRACTICAL_BOUNDS, SEED_ACTUAL, TERRAINS, WIDE_BOUNDS, Soil, SoilBounds
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
from .effects import (
    EFFECTS,
    EffectSet,
    EffectSpec,
    ParamSpec,
    effect_symbols,
    parse_effects,
    sweep_measurement,
    thrust_with_effects,
    tractive_force_with_effects,
)
from .dynamics import (
    SPROCKET_EQUATIONS,
    dynamics_expr,
    dynamics_function,
    slip_from_thrust,
    slip_from_thrust_function,
)
from .simulation import SensorNoise, simulate, simulate_drive_log, simulate_slip_sweep
from .steering import SteadyTurn, SteeringSettings, steady_turn
from .turning import TwoTrackLog, read_two_track, simulate_turning_log
from .units import Scale, choose_scale, format_energy, format_force, format_power, format_torque, format_value
from .rigid_wheel import RigidWheel, read_running_gear
from .wheel import WheelSettings, wheel_expr
from .wheel_sweep import WheelSweep, read_wheel_sweep, write_wheel_sweep
from .wheel_simulation import simulate_wheel_sweep

__all__ = [
    "SteadyTurn",
    "SteeringSettings",
    "steady_turn",
    "TwoTrackLog",
    "read_two_track",
    "simulate_turning_log",
    "DataError",
    "DriveLog",
    "SlipData",
    "ShearTest",
    "PlateTest",
    "read_csv",
    "write_csv",
    "shear_stress_expr",
    "plate_pressure_expr",
    "shear_stress_function",
    "plate_pressure_function",
    "shear_stress",
    "plate_pressure",
    "PARAMETER_NAMES",
    "PRACTICAL_BOUNDS",
    "WIDE_BOUNDS",
    "SEED_ACTUAL",
    "TERRAINS",
    "Soil",
    "SoilBounds",
    "MODELS",
    "max_thrust",
    "sensitivity_function",
    "thrust_expr",
    "thrust_function",
    "tractive_force",
    "tractive_force_sensitivities",
    "G",
    "VEHICLES",
    "Vehicle",
    "EFFECTS",
    "EffectSet",
    "EffectSpec",
    "ParamSpec",
    "effect_symbols",
    "parse_effects",
    "sweep_measurement",
    "thrust_with_effects",
    "tractive_force_with_effects",
    "SPROCKET_EQUATIONS",
    "dynamics_expr",
    "dynamics_function",
    "slip_from_thrust",
    "slip_from_thrust_function",
    "SensorNoise",
    "simulate",
    "simulate_drive_log",
    "simulate_slip_sweep",
    "Scale",
    "choose_scale",
    "format_value",
    "format_force",
    "format_torque",
    "format_power",
    "format_energy",
    "RigidWheel",
    "read_running_gear",
    "WheelSettings",
    "wheel_expr",
    "WheelSweep",
    "read_wheel_sweep",
    "write_wheel_sweep",
    "simulate_wheel_sweep",
]
