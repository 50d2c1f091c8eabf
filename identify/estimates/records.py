"""Value types of an identification result: one parameter's estimate, one identifiable combination.

SI inside; :data:`EDGE_UNITS` maps the soil's parameters to the units of the edges (kPa, deg, m).
Effect parameters (``"effect.param"``) keep their SI unit at the edges too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ParameterEstimate", "Combination", "EDGE_UNITS", "finite_or_none", "NOT_USABLE", "solver_converged"]

EDGE_UNITS = {  # SI name -> (JSON key, edge unit, factor SI -> edge, label, SI unit)
    "cohesion": ("cohesion_kpa", "kPa", 1e-3, "cohesion c", "Pa"),
    "friction_angle": ("friction_angle_deg", "deg", 180.0 / math.pi, "friction angle phi", "rad"),
    "shear_modulus": ("shear_modulus_m", "m", 1.0, "shear modulus K", "m"),
}


#: Suffix :func:`~.result.build_result` appends to the status of a fit the plausibility checks refuse.
NOT_USABLE = "(answer not usable)"


def solver_converged(res) -> bool:
    """Whether the solver of ``res`` converged to finite numbers (plausibility aside).

    True for a successful fit, and for one whose only failure is the plausibility verdict
    (its status ends with :data:`NOT_USABLE`); False for a solver failure.
    """
    if getattr(res, "success", False):
        return True
    status = str(getattr(res, "status", ""))
    theta = np.asarray(getattr(res, "theta", [np.nan]), dtype=float)
    return status.endswith(NOT_USABLE) and bool(np.all(np.isfinite(theta)))


def finite_or_none(x) -> float | None:
    """float or None for anything non-finite (JSON never carries NaN/Infinity)."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


@dataclass(frozen=True)
class ParameterEstimate:
    """One soil parameter, SI units.

    Attributes
    ----------
    name : str
        ``"cohesion"``, ``"friction_angle"`` or ``"shear_modulus"``.
    value : float or None
        Estimate (Pa, rad, m); ``None`` when the data do not identify it.
    stderr : float or None
        Linearised standard error; ``None`` when unavailable (reason in ``note``).
    ci95 : tuple of (float or None)
        95 % interval (clipped to the bounds; for a non-identifiable parameter, the range it can
        take while the fit stays within its uncertainty, or the bounds).
    identifiable, weakly_identifiable : bool
        Whether the data pin it down; weakly: correlation with other directions > 0.99.
    at_bound : bool
        Whether the estimate lies on a bound; ``bound_side`` is ``"lower"``/``"upper"``.
    fixed : bool
        Held fixed by the model (cohesion in the cohesion-free model), not estimated.
    ridge_value : float or None
        The optimiser's point, for diagnostics only when not identifiable (NOT an estimate).
    note : str
        Plain-words remarks.
    """

    name: str
    value: float | None
    stderr: float | None
    ci95: tuple[float | None, float | None]
    identifiable: bool
    weakly_identifiable: bool = False
    at_bound: bool = False
    bound_side: str | None = None
    fixed: bool = False
    ridge_value: float | None = None
    note: str = ""
    si_unit: str = ""
    correlated_with: str | None = None
    correlation: float | None = None

    @property
    def unit(self) -> str:
        """SI unit (``"Pa"``, ``"rad"``, ``"m"``; an effect parameter's own unit)."""
        return EDGE_UNITS[self.name][4] if self.name in EDGE_UNITS else self.si_unit

    @property
    def edge_unit(self) -> str:
        """Unit at the edges (``"kPa"``, ``"deg"``, ``"m"``; effect parameters: SI)."""
        return EDGE_UNITS[self.name][1] if self.name in EDGE_UNITS else self.si_unit

    def _edge(self, x):
        return None if x is None else x * (EDGE_UNITS[self.name][2] if self.name in EDGE_UNITS else 1.0)

    @property
    def edge_value(self) -> float | None:
        """Value in kPa / deg / m."""
        return self._edge(self.value)

    @property
    def edge_stderr(self) -> float | None:
        """Standard error in kPa / deg / m."""
        return self._edge(self.stderr)

    @property
    def edge_ci95(self) -> tuple[float | None, float | None]:
        """95 % interval in kPa / deg / m."""
        return (self._edge(self.ci95[0]), self._edge(self.ci95[1]))

    # convenience names terramechanics users reach for
    @property
    def value_kpa(self) -> float | None:
        """Value in kPa (cohesion)."""
        return None if self.value is None else self.value * 1e-3

    @property
    def value_deg(self) -> float | None:
        """Value in degrees (friction angle)."""
        return None if self.value is None else math.degrees(self.value)

    def to_dict(self) -> dict:
        """JSON-ready dict in edge units (kPa, deg, m); never NaN."""
        lo, hi = self.edge_ci95
        return {
            "value": finite_or_none(self.edge_value),
            "stderr": finite_or_none(self.edge_stderr),
            "ci95": [finite_or_none(lo), finite_or_none(hi)],
            "identifiable": bool(self.identifiable),
            "at_bound": bool(self.at_bound),
            "bound_side": self.bound_side,
            "weakly_identifiable": bool(self.weakly_identifiable),
            "fixed": bool(self.fixed),
            "ridge_value": finite_or_none(self._edge(self.ridge_value)),
            "note": self.note,
            **({} if self.name in EDGE_UNITS else {"unit": self.si_unit}),
            **(
                {}
                if self.name in EDGE_UNITS and self.correlated_with is None
                else {"correlated_with": self.correlated_with, "correlation": finite_or_none(self.correlation)}
            ),
        }


@dataclass(frozen=True)
class Combination:
    """An identifiable combination of the parameters, e.g. ``F_max = A c + W tan(phi)``.

    Attributes
    ----------
    name : str
        Machine-friendly name, e.g. ``"F_max@W=329000N"``, ``"K"``, ``"K/l"``.
    value : float
        Value in ``unit`` (SI).
    stderr : float or None
        Linearised standard error; ``None`` when not estimable or no degrees of freedom.
    ci95 : tuple
        95 % interval (``None`` ends when unavailable).
    unit, description : str
        SI unit and plain-words meaning.
    estimable : bool
        Whether the data determine it (its gradient lies in the Jacobian's row space).
    weakly_identifiable : bool
        Variance inflation above the 0.99-correlation level.
    note : str
        Plain words about the interval, e.g. that a bound cut it (empty when nothing to say).
    """

    name: str
    value: float
    stderr: float | None
    ci95: tuple[float | None, float | None]
    unit: str
    description: str
    estimable: bool = True
    weakly_identifiable: bool = False
    note: str = ""

    def to_dict(self) -> dict:
        """JSON-ready dict (SI units as named); never NaN."""
        return {
            "name": self.name,
            "value": finite_or_none(self.value),
            "stderr": finite_or_none(self.stderr),
            "ci95": [finite_or_none(self.ci95[0]), finite_or_none(self.ci95[1])],
            "unit": self.unit,
            "description": self.description,
            "estimable": bool(self.estimable),
            "weakly_identifiable": bool(self.weakly_identifiable),
            "note": self.note,
        }
