"""Value types of an identification result: one parameter's estimate, one identifiable combination.

SI inside; :data:`EDGE_UNITS` maps the soil's parameters to the units of the edges (kPa, deg, m).
Effect parameters (``"effect.param"``) keep their SI unit at the edges too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from ...soilmodel.units import format_value
from ..outcome import identified

__all__ = [
    "ParameterEstimate",
    "Combination",
    "combination_determined",
    "CUT_END_RTOL",
    "EDGE_UNITS",
    "NAME_OF_KEY",
    "finite_or_none",
    "NOT_USABLE",
    "solver_converged",
    "LOAD_SPREAD_SMALL",
    "LOAD_SLIP_CORRELATION",
    "LoadSeparation",
    "fit_vector",
    "LOAD_FACTOR",
    "Finding",
    "check_loads",
]

#: The library's one table of a parameter's units: SI name -> (JSON key, edge unit, factor SI -> edge,
#: label, SI unit). Every kind's parameter record (:class:`ParameterEstimate`) converts through it.
EDGE_UNITS = {
    "cohesion": ("cohesion_kpa", "kPa", 1e-3, "cohesion c", "Pa"),
    "friction_angle": ("friction_angle_deg", "deg", 180.0 / math.pi, "friction angle phi", "rad"),
    "shear_modulus": ("shear_modulus_m", "m", 1.0, "shear modulus K", "m"),
    "shear_strength": ("shear_strength_kpa", "kPa", 1e-3, "shear strength", "Pa"),
    "bekker_kc": ("bekker_kc", "kN/m^(n+1)", 1e-3, "Bekker k_c", "N/m^(n+1)"),
    "bekker_kphi": ("bekker_kphi", "kN/m^(n+2)", 1e-3, "Bekker k_phi", "N/m^(n+2)"),
    "bekker_n": ("bekker_n", "-", 1.0, "Bekker exponent n", "-"),
    "bekker_k_eq": ("bekker_k_eq", "kN/m^(n+2)", 1e-3, "k_c / b + k_phi", "N/m^(n+2)"),
    "slip_sinkage": ("slip_sinkage", "-", 1.0, "slip-sinkage coefficient s", "-"),
    "grouser_height": ("grouser_height_m", "m", 1.0, "grouser height h", "m"),
    "slip_sinkage_exponent": (
        "slip_sinkage_exponent",
        "-",
        1.0,
        "exponent s of Lyasko's slip-sinkage factor",
        "-",
    ),
}
#: JSON key -> SI name of :data:`EDGE_UNITS`.
NAME_OF_KEY = {v[0]: n for n, v in EDGE_UNITS.items()}


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
    """One parameter of any fit (track, rig, wheel, bevameter test, sinkage channel), SI units inside.

    The library's one per-parameter record: every kind builds it, its edge units (kPa, deg, m,
    kN/m^(n+1), ...) come from :data:`EDGE_UNITS`, whether it is identified from
    :func:`~soiltrack.identify.outcome.identified`, and its JSON entry from :meth:`to_dict` (one layout).

    Attributes
    ----------
    name : str
        SI name: ``"cohesion"``, ``"friction_angle"``, ``"shear_modulus"``, ``"bekker_kc"``,
        ``"bekker_kphi"``, ``"bekker_n"``, ``"bekker_k_eq"``, ``"slip_sinkage"``,
        ``"slip_sinkage_exponent"`` (:data:`EDGE_UNITS`) or an effect's ``"effect.param"``.
    value : float or None
        Estimate (SI); ``None`` when the data do not identify it.
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
    si_unit : str
        The SI unit of a parameter outside :data:`EDGE_UNITS` (an effect's).
    correlated_with, correlation
        The parameter it correlates with most, and how much (when reported).
    lower, upper : float or None
        Its bounds (SI): the range :func:`~soiltrack.identify.outcome.identified` measures its interval
        against; ``None`` when the fit has none.
    label : str
        Plain name for a report (default: :data:`EDGE_UNITS`'s).
    source : str or None
        The data channel it comes from when not the fit's main one (``"sinkage_m"``).
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
    lower: float | None = None
    upper: float | None = None
    label: str = ""
    source: str | None = None

    @classmethod
    def from_edge(cls, name: str, value, stderr, ci95, identifiable: bool, **kw) -> ParameterEstimate:
        """A record from numbers in edge units (``value``, ``stderr``, ``ci95`` and the ``lower``,
        ``upper`` and ``ridge_value`` keywords): divided by :data:`EDGE_UNITS`'s factor into SI."""
        f = EDGE_UNITS[name][2] if name in EDGE_UNITS else 1.0

        def si(x):
            return None if x is None else float(x) / f

        for k in ("lower", "upper", "ridge_value"):
            if k in kw:
                kw[k] = si(kw[k])
        return cls(name, si(value), si(stderr), (si(ci95[0]), si(ci95[1])), bool(identifiable), **kw)

    @property
    def key(self) -> str:
        """JSON key (``"cohesion_kpa"``, ``"bekker_kc"``, ...; an effect parameter's own name)."""
        return EDGE_UNITS[self.name][0] if self.name in EDGE_UNITS else self.name

    @property
    def words(self) -> str:
        """Plain name for a report: :attr:`label`, else :data:`EDGE_UNITS`'s, else the name."""
        return self.label or (EDGE_UNITS[self.name][3] if self.name in EDGE_UNITS else self.name)

    @property
    def unit(self) -> str:
        """SI unit (``"Pa"``, ``"rad"``, ``"m"``; an effect parameter's own unit)."""
        return EDGE_UNITS[self.name][4] if self.name in EDGE_UNITS else self.si_unit

    @property
    def edge_unit(self) -> str:
        """Unit at the edges (``"kPa"``, ``"deg"``, ``"m"``, ``"kN/m^(n+1)"``; effect parameters: SI)."""
        return EDGE_UNITS[self.name][1] if self.name in EDGE_UNITS else self.si_unit

    def _edge(self, x):
        return None if x is None else x * (EDGE_UNITS[self.name][2] if self.name in EDGE_UNITS else 1.0)

    @property
    def edge_value(self) -> float | None:
        """Value in edge units."""
        return self._edge(self.value)

    @property
    def edge_stderr(self) -> float | None:
        """Standard error in edge units."""
        return self._edge(self.stderr)

    @property
    def edge_ci95(self) -> tuple[float | None, float | None]:
        """95 % interval in edge units."""
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

    @property
    def identified(self) -> tuple[bool, str]:
        """Identified by the outcome rules (:func:`~soiltrack.identify.outcome.identified`), and why not:
        held, not identifiable, on a bound, or an interval over most of its bound range are not."""
        if self.fixed:
            return False, "held fixed"
        if self.value is None or not self.identifiable:
            return False, "not identifiable from these data"
        if self.lower is None or self.upper is None:
            return (not self.at_bound), ("on a bound: its interval is not reliable" if self.at_bound else "")
        return identified(identifiable=True, at_bound=self.at_bound, ci95=self.ci95, lower=self.lower, upper=self.upper)

    def to_dict(self) -> dict:
        """The JSON entry, one layout for every kind, in edge units; never NaN.

        Keys: ``value``, ``stderr``, ``ci95``, ``identifiable``, ``identified``, ``at_bound``,
        ``bound_side``, ``weakly_identifiable``, ``fixed``, ``ridge_value``, ``value_is_ridge_point``
        (the track's sets it), ``unit`` (edge), ``note``, ``correlated_with``, ``correlation``, ``source``.
        """
        lo, hi = self.edge_ci95
        return {
            "value": finite_or_none(self.edge_value),
            "stderr": finite_or_none(self.edge_stderr),
            "ci95": [finite_or_none(lo), finite_or_none(hi)],
            "identifiable": bool(self.identifiable),
            "identified": bool(self.identified[0]),
            "at_bound": bool(self.at_bound),
            "bound_side": self.bound_side,
            "weakly_identifiable": bool(self.weakly_identifiable),
            "fixed": bool(self.fixed),
            "ridge_value": finite_or_none(self._edge(self.ridge_value)),
            "value_is_ridge_point": False,
            "unit": self.edge_unit,
            "note": self.note,
            "correlated_with": self.correlated_with,
            "correlation": finite_or_none(self.correlation),
            "source": self.source,
        }


@dataclass(frozen=True)
class Combination:
    """An identifiable combination of the parameters, e.g. ``F_max = A c + W tan(phi)``: the library's one
    combination record (track, rig, wheel, bevameter test), whether it is determined by
    :func:`combination_determined` (one rule).

    Attributes
    ----------
    name : str
        Machine-friendly name, e.g. ``"F_max@W=329000N"``, ``"K"``, ``"K/l"``, ``"bekker_k_eq"``.
    value : float
        Value in ``unit`` (SI for the track's; the edge unit it names for a wheel's or a bevameter test's).
    stderr : float or None
        Linearised standard error; ``None`` when not estimable or no degrees of freedom.
    ci95 : tuple
        95 % interval (``None`` ends when unavailable).
    unit, description : str
        Unit of ``value`` and plain-words meaning.
    estimable : bool
        Whether the data determine it (its gradient lies in the Jacobian's row space).
    weakly_identifiable : bool
        Variance inflation above the 0.99-correlation level.
    note : str
        Plain words about the interval, e.g. that a bound cut it (empty when nothing to say).
    expression : str
        Its formula where the name is not one (``"k_c / b + k_phi"``); empty otherwise.
    at : dict
        The condition it holds at, e.g. ``{"plate_width_m": 0.1}`` (in the JSON beside its other keys).
    range : tuple of float or None
        The range its terms' bounds allow (in ``unit``): an interval over most of it is not determined.
    terms_on_bounds : tuple of str
        The JSON keys of its terms that end on a bound; ``all_terms_on_bounds`` when every free one does.
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
    expression: str = ""
    at: Mapping[str, float] = field(default_factory=dict)
    range: tuple[float, float] | None = None
    terms_on_bounds: tuple[str, ...] = ()
    all_terms_on_bounds: bool = False

    @property
    def determined(self) -> tuple[bool, str]:
        """:func:`combination_determined` of this combination."""
        return combination_determined(self)

    def to_dict(self) -> dict:
        """JSON-ready dict (units as named), one layout for every kind; never NaN.

        Keys: ``name``, ``value``, ``stderr``, ``ci95``, ``unit``, ``description``, ``estimable``,
        ``weakly_identifiable``, ``note``, ``expression``, ``terms_on_bounds`` and the keys of ``at``;
        the record adds ``determined`` (its own rule may add to this one's, e.g. a gentle drive log's).
        """
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
            "expression": self.expression,
            "terms_on_bounds": list(self.terms_on_bounds),
            **{k: finite_or_none(v) for k, v in self.at.items()},
        }


#: Relative distance of a combination's value from an end of its interval that a bound cut, within
#: which the value is pinned at that end (a value on a bound is never called determined).
CUT_END_RTOL = 1e-6


def combination_determined(cb: Combination) -> tuple[bool, str]:
    """Whether the data determine a combination, and why not (empty when they do): the one rule.

    Determined: estimable, with a standard error and a whole interval; not pinned at an end of its
    interval a bound cut (:data:`CUT_END_RTOL`); not every free term on a bound; and its interval no wider
    than most of the range its terms' bounds allow (:func:`~soiltrack.identify.outcome.identified`).
    """
    if not (cb.estimable and cb.stderr is not None and None not in tuple(cb.ci95)):
        return False, "not estimable from these data"
    lo, hi = cb.ci95
    tol = CUT_END_RTOL * max(abs(cb.value), 1e-300)
    if ("lower end of the 95 % interval is cut" in cb.note and cb.value - lo <= tol) or (  # type: ignore[operator]
        "upper end of the 95 % interval is cut" in cb.note and hi - cb.value <= tol  # type: ignore[operator]
    ):
        return False, "pinned at a bound"
    if cb.all_terms_on_bounds:
        return False, f"its terms are on their bounds ({', '.join(cb.terms_on_bounds)})"
    if cb.range is not None:
        return identified(identifiable=True, at_bound=False, ci95=cb.ci95, lower=cb.range[0], upper=cb.range[1])
    return True, ""


#: Spread of the normal load, (max - min) / median, below which c and phi rest on little (a designed
#: test at 300 and 450 N spreads 0.4; measured rig loads of 21-26 N spread 0.18).
LOAD_SPREAD_SMALL = 0.3
#: |correlation| of the load with the slip above which a load effect and a slip effect mix.
LOAD_SLIP_CORRELATION = 0.5


@dataclass(frozen=True)
class LoadSeparation:
    """How the normal load separates c and phi in a sweep at several loads.

    Attributes
    ----------
    spread
        ``(max - min) / median`` of the rows' loads.
    slip_correlation
        Correlation of the load with the slip over the rows.
    fragile
        The spread is small or the load correlates with the slip: the separation rests on it.
    """

    spread: float
    slip_correlation: float
    fragile: bool

    def statement(self, result) -> str:
        """Plain words, with the fit's intervals of c and phi (profile likelihood when fragile)."""
        why = []
        if self.spread < LOAD_SPREAD_SMALL:
            why.append(f"the load spreads only {100 * self.spread:.0f} % of its median")
        if abs(self.slip_correlation) > LOAD_SLIP_CORRELATION:
            why.append(
                f"the load correlates with the slip (r = {self.slip_correlation:+.2f}): a slip effect can "
                "pass for a load effect"
            )
        if not self.fragile:
            return ""
        ivs = []
        for name, label in (("cohesion", "c"), ("friction_angle", "phi")):
            pe = result.parameters.get(name)
            if pe is None or pe.fixed:
                continue
            lo, hi = pe.edge_ci95
            tag = " (profile)" if name in (result.replaced_intervals or {}) else ""
            if lo is not None and hi is not None:
                ivs.append(f"{label} in [{lo:.3g}, {hi:.3g}] {pe.edge_unit}{tag}")
        tail = f"; 95 % intervals: {', '.join(ivs)}" if ivs else ""
        return (
            "c and phi are told apart only through the normal load's spread, and "
            + " and ".join(why)
            + f": the separation rests on it{tail}"
        )

    def to_dict(self) -> dict:
        """JSON-ready: the numbers and the verdict (the statement needs the fit: :meth:`statement`)."""
        return {"spread": self.spread, "slip_correlation": self.slip_correlation, "fragile": self.fragile}


def fit_vector(result) -> np.ndarray:
    """``x = [c, phi, K, e...]`` (SI) of a slip fit: its ``theta`` and its effect values (none without effects)."""
    ev = result.effect_values if result.effect_labels and result.effect_values is not None else []
    return np.concatenate([np.asarray(result.theta, dtype=float), np.asarray(ev, dtype=float).ravel()])


#: Normal loads (median over the rows) more than this factor below or above the vehicle's weight are
#: not this vehicle's: one track of it on a rig, a payload change or a slope stay well within it; a
#: light vehicle's 300 N sweep fitted with a 329 kN vehicle's file (0.1 %) does not.
LOAD_FACTOR = 10.0


@dataclass(frozen=True)
class Finding:
    """One plausibility finding.

    Attributes
    ----------
    code : str
        ``"force_scale_low"``, ``"force_above_any_soil"``, ``"negative_thrust"``,
        ``"limit_on_bound"``, ``"residuals_large"``, ``"outlier"``.
    message : str
        What is wrong and what to check, in plain words.
    usable : bool
        Whether the fit's answer can still be used (``False`` makes the fit unsuccessful).
    rows : tuple of int
        Data rows concerned (1-based), if any.
    """

    code: str
    message: str
    usable: bool
    rows: tuple[int, ...] = ()


def check_loads(load, vehicle) -> list[Finding]:
    """The rows' normal loads against the vehicle's weight (:data:`LOAD_FACTOR`); not usable beyond it.

    Parameters
    ----------
    load : array_like
        Normal load per row, N (the vehicle's weight where the data give none).
    vehicle
        The vehicle of the fit: its weight W = m g and contact area A.
    """
    load = np.asarray(load, dtype=float).ravel()
    W = float(vehicle.weight)
    if (
        not load.size
        or W <= 0
        or (float(np.minimum.reduce(load)) * LOAD_FACTOR >= W and float(np.maximum.reduce(load)) <= LOAD_FACTOR * W)
    ):
        return []  # every row within the factor (the common case: one comparison each way)
    if not np.all(np.isfinite(load)):
        return []
    med = float(np.median(load))
    ratio = med / W
    if 1.0 / LOAD_FACTOR <= ratio <= LOAD_FACTOR:
        return []
    size = f"{100 * ratio:.2g} % of" if ratio < 1 else f"{ratio:.3g} times"
    return [
        Finding(
            "load_not_this_vehicle",
            f"the data's normal loads (median {format_value(med, 'N', 3)}) are {size} this vehicle's weight "
            f"({format_value(W, 'N', 3)}): they are not this vehicle's, and its contact area "
            f"A = {vehicle.contact_area:.4g} m^2 makes the cohesion (A c in F_max) meaningless; check --vehicle "
            "(the file or preset of the vehicle that made the data) and the unit of the normal_load_N column",
            usable=False,
        )
    ]
