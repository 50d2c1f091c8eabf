"""The one record of a fit whatever the data (bevameter tests today; the other kinds move onto it), and the
free functions over it: what it determines, its outcome, its report and its JSON.

:class:`Estimate` stores the parameter table (:class:`~.records.ParameterEstimate`), the combinations
(:class:`~.records.Combination`), the solver's word (:class:`SolverRun`), the data's provenance
(:class:`DataProvenance`: file, rows used and dropped, the running gear), the residuals per channel
(:class:`ResidualChannel`, measured minus model), the covariance (:class:`CovarianceBlock`, SI) and the
lack-of-fit test. Everything a reader sees is computed from what is stored by the functions below
(:func:`determined`, :func:`estimate_outcome`, :func:`estimate_report`, :func:`estimate_dict`), with the
one set of rules (:mod:`soiltrack.identify.outcome`, :func:`~.records.combination_determined`). The record
is frozen and is never changed after it is built; it knows no data kind (the kind's fit builds it).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from ..outcome import LackOfFitTest, Outcome, decide_outcome, outcome_lines
from .records import Combination, ParameterEstimate, finite_or_none
from .report import RESIDUAL_SIGN

__all__ = [
    "Estimate",
    "SolverRun",
    "DataProvenance",
    "ResidualChannel",
    "CovarianceBlock",
    "determined",
    "estimate_outcome",
    "estimate_report",
    "estimate_dict",
    "estimate_json",
    "rms",
]


@dataclass(frozen=True)
class SolverRun:
    """What the solver said, never hidden.

    Attributes
    ----------
    method : str
        The solver (``"ipopt"``).
    converged : bool
        It reported success (for the best of its starts).
    status : str
        Its return status, as it gives it.
    finite : bool
        Every number the fit reports is finite (checked by the kind's fit).
    message : str
        Why the fit failed, in plain words (empty when it did not).
    iterations : int
        Its iterations (of the best start).
    solve_time_s : float
        Wall time of every start, s.
    starts : int
        Starts run.
    """

    method: str
    converged: bool
    status: str
    finite: bool = True
    message: str = ""
    iterations: int = 0
    solve_time_s: float = 0.0
    starts: int = 1


@dataclass(frozen=True)
class DataProvenance:
    """Where the fitted numbers come from.

    Attributes
    ----------
    source : str
        The file (or label) fitted.
    title : str
        What the data are, in words (``"bevameter shear test"``): the report's name for them.
    n_samples : int
        Rows fitted.
    rows_dropped : int
        Rows of the file not fitted.
    running_gear : dict
        The JSON ``running_gear`` (:func:`~soiltrack.identify.outcome.running_gear_json`).
    conditions : dict
        The test's conditions, e.g. ``{"normal_pressures_kpa": [...]}`` (JSON ``levels``).
    condition_labels : dict
        Words for the report per condition key (``"normal pressures (kPa)"``).
    """

    source: str
    title: str
    n_samples: int
    rows_dropped: int = 0
    running_gear: Mapping[str, Any] = field(default_factory=dict)
    conditions: Mapping[str, list[float]] = field(default_factory=dict)
    condition_labels: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class ResidualChannel:
    """One measured channel's residuals at the optimum, measured minus model (:data:`~.report.RESIDUAL_SIGN`).

    Attributes
    ----------
    name : str
        The channel (``"shear_stress"``, ``"pressure"``, ``"drawbar_pull"``).
    unit : str
        Unit of ``values`` (``"kPa"``, ``"N"``).
    values : ndarray
        One per row.
    """

    name: str
    unit: str
    values: np.ndarray = field(repr=False)


@dataclass(frozen=True, eq=False)
class CovarianceBlock:
    """The linearised covariance of the identified parameters, in SI, for propagating into predictions.

    Attributes
    ----------
    names : tuple of str
        SI names of the parameters (``cohesion``, ``friction_angle``, ...), the matrix's order.
    values : tuple of float
        Their values (SI).
    matrix : ndarray
        The covariance (SI).
    null_space : tuple of tuple of float
        Directions over ``names`` the data do not see (empty when none).
    """

    names: tuple[str, ...]
    values: tuple[float, ...]
    matrix: np.ndarray = field(repr=False)
    null_space: tuple[tuple[float, ...], ...] = ()

    def to_dict(self) -> dict | None:
        """``{"parameters", "values", "matrix", "units": "SI", "null_space"}``; ``None`` if not finite."""
        C = np.asarray(self.matrix, dtype=float)
        if not np.all(np.isfinite(C)) or not all(math.isfinite(v) for v in self.values):
            return None
        return {
            "parameters": list(self.names),
            "values": [float(v) for v in self.values],
            "matrix": [[float(x) for x in row] for row in C],
            "units": "SI",
            "null_space": [list(v) for v in self.null_space],
        }


@dataclass(frozen=True, eq=False)
class Estimate:
    """The record of one fit: parameters, combinations, solver, data, residuals, covariance (module docs).

    Attributes
    ----------
    kind : str
        The data kind's JSON name (``"shear_test"``, ``"plate_test"``).
    parameters : dict
        ``{JSON key: ParameterEstimate}`` (SI inside; edge units in the JSON and report), in the JSON order.
    combinations : dict
        ``{name: Combination}``: what the data identify where the parameters themselves are not.
    solver : SolverRun
    data : DataProvenance
    residuals : tuple of ResidualChannel
        Measured minus model, per channel (the first is the fit's main channel).
    covariance : CovarianceBlock or None
        Of the identified parameters (``None`` when not every parameter it would cover is identified).
    dof : int
        Residual degrees of freedom.
    lack_of_fit : LackOfFitTest or None
        Against the repeats' pure error or the stated noise; ``None`` when not tested.
    model_limit : str or None
        Why the model cannot be trusted on these data whatever the statistics say (a poor fit), decided
        by the kind's fit from its data; ``None`` when nothing is known against it.
    notes : tuple of str
        Plain-words statements (identifiability, bounds, the model).
    """

    kind: str
    parameters: Mapping[str, ParameterEstimate]
    combinations: Mapping[str, Combination]
    solver: SolverRun
    data: DataProvenance
    residuals: tuple[ResidualChannel, ...]
    covariance: CovarianceBlock | None
    dof: int
    lack_of_fit: LackOfFitTest | None = None
    model_limit: str | None = None
    notes: tuple[str, ...] = ()

    # views by the free functions below (so that ``fit.report()`` reads as every other fit's)
    @property
    def success(self) -> bool:
        """The solver converged to finite numbers and the data identify at least one parameter."""
        return solver_ok(self)

    @property
    def converged(self) -> bool:
        """The solver's word (:attr:`SolverRun.converged`)."""
        return self.solver.converged

    @property
    def status(self) -> str:
        """The solver's return status."""
        return self.solver.status

    @property
    def source(self) -> str:
        """The file fitted."""
        return self.data.source

    @property
    def n_samples(self) -> int:
        """Rows fitted."""
        return self.data.n_samples

    @property
    def running_gear(self) -> Mapping[str, Any]:
        """The JSON ``running_gear``."""
        return self.data.running_gear

    @property
    def determined(self) -> list[str]:
        """:func:`determined`."""
        return determined(self)

    @property
    def fit_outcome(self) -> Outcome:
        """:func:`estimate_outcome`."""
        return estimate_outcome(self)

    @property
    def outcome(self) -> str:
        """One of :data:`~soiltrack.identify.outcome.OUTCOMES`."""
        return estimate_outcome(self).outcome

    @property
    def identifiable(self) -> list[str]:
        """Keys of the parameters the data identify (held ones excluded)."""
        return [k for k, p in self.parameters.items() if p.identifiable and not p.fixed]

    @property
    def active_bounds(self) -> list[str]:
        """Keys of the parameters that end on a bound."""
        return [k for k, p in self.parameters.items() if p.at_bound]

    def rmse(self, channel: int = 0) -> float:
        """Root mean square of a channel's residuals (:func:`rms`)."""
        return rms(self.residuals[channel].values)

    def report(self) -> str:
        """:func:`estimate_report`."""
        return estimate_report(self)

    def to_dict(self) -> dict:
        """:func:`estimate_dict`."""
        return estimate_dict(self)

    def to_json(self, indent: int | None = 2) -> str:
        """:func:`estimate_json`."""
        return estimate_json(self, indent)


def rms(values: np.ndarray) -> float:
    """Root mean square (nan for no values)."""
    v = np.asarray(values, dtype=float).ravel()
    return math.sqrt(float(v @ v) / v.size) if v.size else math.nan


def solver_ok(est: Estimate) -> bool:
    """The solver converged, its numbers are finite, and the data identify at least one parameter, with a
    finite value."""
    vals = [p.value for p in est.parameters.values() if p.identifiable and not p.fixed]
    return bool(
        est.solver.converged and est.solver.finite and vals and all(v is not None and math.isfinite(v) for v in vals)
    )


def determined(est: Estimate) -> list[str]:
    """What the data determine (JSON keys and combination names): identified parameters
    (:attr:`~.records.ParameterEstimate.identified`) and determined combinations
    (:func:`~.records.combination_determined`); nothing when the fit failed."""
    if not solver_ok(est):
        return []
    out = [k for k, p in est.parameters.items() if p.identified[0]]
    return out + [k for k, c in est.combinations.items() if c.determined[0]]


def estimate_outcome(est: Estimate) -> Outcome:
    """The fit's outcome by the one set of rules (:func:`~soiltrack.identify.outcome.decide_outcome`): a
    failed solve, nothing determined, lack of fit, then the kind's :attr:`Estimate.model_limit`."""
    s = est.solver
    failure = s.message or (
        f"{s.method.upper()} {s.status}"
        if not s.converged
        else "non-finite numbers"
        if not s.finite
        else "the data identify no parameter"
    )
    base = decide_outcome(
        solver_ok=solver_ok(est), failure=failure, determined=determined(est), lack_of_fit=est.lack_of_fit
    )
    if base.usable and est.model_limit:
        return Outcome("poor_fit", est.model_limit)
    return base


def _words(est: Estimate, key: str) -> str:
    if key in est.parameters:
        return est.parameters[key].words
    c = est.combinations[key]
    return c.expression or c.name


def estimate_report(est: Estimate) -> str:
    """Plain-text report: the outcome and its reason first, the data, the solver's word, each parameter with its
    interval (nothing on a bound called identified), the combinations, the notes and the result."""
    o = estimate_outcome(est)
    nid = [p.words for p in est.parameters.values() if not p.fixed and not p.identified[0]]
    d, s = est.data, est.solver
    lvl = "; ".join(
        f"{d.condition_labels.get(k, k)}: {', '.join(f'{v:.4g}' for v in vals)}" for k, vals in d.conditions.items()
    )
    dropped = f", {d.rows_dropped} rows of the file dropped" if d.rows_dropped else ""
    res = est.residuals[0] if est.residuals else None
    misfit = f"; rms misfit {rms(res.values):.4g} {res.unit}" if res is not None else ""
    lines = outcome_lines(o, determined=[_words(est, k) for k in determined(est)], not_identified=nid) + [
        f"{d.title}: {d.source} ({d.n_samples} rows{dropped}{'; ' + lvl if lvl else ''})",
        f"solver: {s.method.upper()} {'converged' if s.converged else 'DID NOT CONVERGE'} ({s.status}), "
        f"{s.iterations} iterations, {s.solve_time_s:.3f} s{misfit}",
    ]
    lines += [_parameter_line(p) for p in est.parameters.values()]
    lines += [_combination_line(c) for c in est.combinations.values()]
    if est.lack_of_fit is not None:
        t = est.lack_of_fit
        lines.append(f"lack of fit against {t.against}: F = {t.statistic:.3g}, p = {t.p_value:.3g}")
    lines += [f"note: {n}" for n in est.notes]
    lines.append("result: " + ("usable" if o.usable else f"{o.outcome.upper()} ({o.reason})"))
    return "\n".join(lines)


def _parameter_line(p: ParameterEstimate) -> str:
    """One parameter of the report: no number where the data do not identify it; a bound flagged."""
    if p.fixed:
        return f"  {p.words:<28} {p.edge_value:>10.4g} {p.edge_unit:<12} held fixed"
    if not p.identifiable or p.edge_value is None:
        return f"  {p.words:<28} not identifiable (see the note)"
    lo, hi = p.edge_ci95
    ci = f"[{lo:.4g}, {hi:.4g}]" if lo is not None and hi is not None else "[n/a]"
    ok, why = p.identified
    flag = "  ON A BOUND (not identified; interval not reliable)" if p.at_bound else ""
    flag += "" if ok or p.at_bound else f"  NOT IDENTIFIED ({why})"
    return f"  {p.words:<28} {p.edge_value:>10.4g} {p.edge_unit:<12} 95 % {ci}{flag}"


def _combination_line(c: Combination) -> str:
    """One combination of the report: a number only where the data determine it."""
    at = ", ".join(f"{k} = {v:.4g}" for k, v in c.at.items())
    label = (c.expression or c.name) + (f" ({at})" if at else "")
    ok, why = c.determined
    if not ok:
        return f"  {label:<40} NOT DETERMINED ({why})"
    ci = f"[{c.ci95[0]:.4g}, {c.ci95[1]:.4g}]"
    return f"  {label:<40} {c.value:.4g} {c.unit}  95 % {ci}"


def estimate_dict(est: Estimate) -> dict:
    """The JSON object of a fit (``soiltrack fit --json``), one layout for every kind on the record; never NaN.

    Keys: ``kind``, ``source``, ``method``, ``status``, ``success``, ``outcome``, ``outcome_reason``,
    ``running_gear``, ``converged``, ``iterations``, ``n_samples``, ``rows_dropped``, ``rmse_<unit>`` (the main
    channel's), ``solve_time_s``, ``levels``, ``parameters``, ``combinations`` (each with ``determined`` and
    ``not_determined_reason``), ``identifiable``, ``active_bounds``, ``determined``, ``dof``, ``lack_of_fit``,
    ``notes``, ``covariance``, ``residuals`` (``{"sign", "unit", "values", "channels"}``).
    """
    o = estimate_outcome(est)
    s, d = est.solver, est.data
    main = est.residuals[0] if est.residuals else None
    t = est.lack_of_fit
    ok = solver_ok(est)
    combos = []
    for c in est.combinations.values():
        det, why = c.determined if ok else (False, "the fit failed")
        combos.append({**c.to_dict(), "determined": det, "not_determined_reason": why or None})
    return {
        "kind": est.kind,
        "source": d.source,
        "method": s.method,
        "status": s.status,
        "success": ok,
        **o.to_dict(),
        "running_gear": dict(d.running_gear),
        "converged": bool(s.converged),
        "iterations": int(s.iterations),
        "n_samples": int(d.n_samples),
        "rows_dropped": int(d.rows_dropped),
        **({f"rmse_{main.unit}": finite_or_none(rms(main.values))} if main is not None else {}),
        "solve_time_s": finite_or_none(s.solve_time_s),
        "levels": {k: list(v) for k, v in d.conditions.items()},
        "parameters": {k: p.to_dict() for k, p in est.parameters.items()},
        "combinations": combos,
        "identifiable": est.identifiable,
        "active_bounds": est.active_bounds,
        "determined": determined(est),
        "dof": int(est.dof),
        "lack_of_fit": None
        if t is None
        else {"against": t.against, "F": finite_or_none(t.statistic), "dof": list(t.dof), "p_value": t.p_value},
        "notes": list(est.notes),
        "covariance": None if est.covariance is None else est.covariance.to_dict(),
        "residuals": {
            "sign": RESIDUAL_SIGN,
            "unit": None if main is None else main.unit,
            "values": [] if main is None else [finite_or_none(x) for x in main.values],
            "channels": {
                r.name: {"unit": r.unit, "values": [finite_or_none(x) for x in r.values]} for r in est.residuals
            },
        },
    }


def estimate_json(est: Estimate, indent: int | None = 2) -> str:
    """:func:`estimate_dict` as JSON text."""
    return json.dumps(estimate_dict(est), indent=indent, allow_nan=False)
