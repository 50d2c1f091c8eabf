"""Traversability margins and traction planning, built on the model core and on identified soils.

Public names
------------
:func:`margin` / :class:`Margin`
    Available against required thrust, go/no-go, gradeability; with an identified soil the
    probability of being traversable (delta method and Monte Carlo) and the worst case.
:func:`profile`, :func:`route_profile` / :class:`SpeedPlan`
    Feasible speed/slip/torque profiles by optimal control (direct collocation, IPOPT).
:class:`Replanner`
    One profile problem built for a vehicle and a mesh, re-solved warm on each new soil.
:func:`stuck` / :class:`Stuck`
    When the tracks spin (slip runs away), and Bekker sinkage reaching the belly.
:func:`slip_optimal` / :class:`SlipOptimum`
    Slips of the largest drawbar power and of the largest tractive efficiency.
:class:`Route`, :class:`Patch`, :func:`read_route`
    Routes of terrain patches (ROUTE.json).
:func:`replay` / :class:`Replay`
    Open-loop replay of a planned torque through the full dynamics (CVODES).
:class:`SoilUncertainty`, :func:`uncertainty_from_fit`, :func:`uncertainty_from_estimate`, :func:`load_fit_json`
    The soil's uncertainty from a ``FitResult``, an on-line estimate or ``soiltrack fit --json``.
"""

from .margin import DEFAULT_MAX_SLIP, Margin, margin
from .profile import SpeedPlan, profile, route_profile
from .replan import Replanner
from .replay import Replay, replay
from .route import Patch, Route, read_route, route_from_dict
from .slip_optimal import SlipOptimum, slip_optimal
from .stuck import Stuck, stuck
from .uncertainty import SoilUncertainty, load_fit_json, uncertainty_from_estimate, uncertainty_from_fit

__all__ = [
    "DEFAULT_MAX_SLIP",
    "Margin",
    "margin",
    "SpeedPlan",
    "profile",
    "route_profile",
    "Replanner",
    "Replay",
    "replay",
    "Patch",
    "Route",
    "read_route",
    "route_from_dict",
    "SlipOptimum",
    "slip_optimal",
    "Stuck",
    "stuck",
    "SoilUncertainty",
    "load_fit_json",
    "uncertainty_from_fit",
    "uncertainty_from_estimate",
]
