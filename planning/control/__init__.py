"""Closed-loop traction control on the soil identified while driving (docs/control.md).

Public names
------------
:func:`make_controller` / :class:`ControlSettings`
    ``pi``, ``slip``, ``mpc`` and ``fixed_slip`` controllers, each with ``command(measurement) -> torque``.
:class:`TrackPlant`, :class:`TerrainPatch`, :class:`PlantSettings`
    The library's straight-line dynamics over patches of true terrain, with sensor noise and delay.
:func:`run_closed_loop` / :class:`ClosedLoop`, :func:`metrics`
    A controller against any plant with ``step(torque) -> measurement``, and the metrics.
:func:`drive` / :class:`DriveResult`
    A controller and its baselines (``pi``, ``fixed_slip``, ``nominal_soil``, ``true_soil``) on one route.
:class:`EstimatedSoil`, :class:`PriorSoil`, :class:`TrueSoil`, :class:`SoilBelief`
    What a controller believes about the soil (the on-line estimator inside, or a prior, or the truth).
"""

from .belief import EstimatedSoil, PriorSoil, SoilBelief, TrueSoil
from .controllers import CONTROLLERS, ControlSettings, Controller, make_controller
from .drive import BASELINES, DriveResult, drive
from .loop import METRIC_KEYS, ClosedLoop, metrics, run_closed_loop
from .plant import PlantSettings, TerrainPatch, TrackPlant

__all__ = [
    "make_controller",
    "ControlSettings",
    "Controller",
    "CONTROLLERS",
    "TrackPlant",
    "TerrainPatch",
    "PlantSettings",
    "run_closed_loop",
    "ClosedLoop",
    "metrics",
    "METRIC_KEYS",
    "drive",
    "DriveResult",
    "BASELINES",
    "EstimatedSoil",
    "PriorSoil",
    "TrueSoil",
    "SoilBelief",
]
