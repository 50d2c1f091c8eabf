"""Soil from turns: two-track drive logs with yaw rate fitted with the steering model (:mod:`.fit`)."""

from .fit import MOTIONS, TurnFit, TurnFitSettings, fit_by_motion, fit_turning, motion_blocks

__all__ = ["MOTIONS", "TurnFit", "TurnFitSettings", "fit_by_motion", "fit_turning", "motion_blocks"]
