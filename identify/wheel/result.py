"""The result of a rigid-wheel fit: estimates, what the data identify, lack of fit, report and JSON.

Channels: the drawbar pull (N) and, with a measured sinkage, the sinkage (m) against the one at
which the fitted stresses carry the measured load (:mod:`.problem`). Statistics (as for the track,
:mod:`soiltrack.identify.estimates.least_squares`): each channel's residuals are
weighted by its own noise level (the root mean square of its residuals at the optimum); the
column-scaled Jacobian of the weighted residuals gives the rank (singular values below
``RANK_TOL`` are structural zeros), the null space (directions the data do not see), the
covariance ``s^2 (J^T J)^+`` and Student-t 95 % intervals with ``N - rank`` degrees of freedom
(intersected with the bounds).
A parameter with a component in the null space is *not identifiable*; one whose variance
inflation exceeds ``1 / (1 - 0.99^2)`` is *weakly identifiable*. Combinations get an interval
when their gradient lies in the row space (estimable).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...soilmodel.rigid_wheel import RigidWheel
from ...soilmodel.wheel import entry_angle
from ...soilmodel.wheel_sweep import WheelSweep
from ..estimates.least_squares import (
    RANK_TOL,
    WEAK_CORRELATION,
    WEAK_VIF,
    core_stats_one,
    estimable,
    identified_columns,
    quantile,
)
from ..estimates.distributions import f_sf
from ..estimates.report import RESIDUAL_SIGN
from ..estimates.records import EDGE_UNITS, Combination, ParameterEstimate
from ..outcome import BOUND_TOL, LackOfFitTest, Outcome, decide_outcome, outcome_lines, running_gear_json
from .problem import WHEEL_PARAMETERS, bekker_modulus, channel_floors, residual_function, torque_floor

__all__ = [
    "WheelFitResult",
    "build_wheel_result",
    "BOUND_REL_TOL",
    "wheel_rows",
    "pure_error",
    "slip_levels",
    "conditions",
    "LOAD_REPEAT_TOL",
    "SLIP_LEVEL_TOL",
    "LOAD_SLIP_CORRELATION_WARN",
    "LOAD_SPREAD_MIN",
    "grousers_separable",
    "grouser_spacing_reason",
]

#: Distance to a bound, as a fraction of the bound range, below which a parameter is on it (the one
#: bound tolerance of the outcome rules).
BOUND_REL_TOL = BOUND_TOL
#: Rows whose slips differ by less than this are repeats of one slip level (pure-error test).
SLIP_LEVEL_TOL = 0.02
#: Rows of one slip level whose loads lie within this fraction of their mean are repeats of one condition
#: (a rig that does not servo the load scatters it by some 10 %).
LOAD_REPEAT_TOL = 0.2
#: |correlation| of load and slip above which the report warns that the load tracks the slip.
LOAD_SLIP_CORRELATION_WARN = 0.5
#: Relative spread of the loads ((max - min) / mean) below which the sweep counts as one load.
LOAD_SPREAD_MIN = 0.25

#: The wheel's report words where they differ from :data:`~soiltrack.identify.estimates.records.EDGE_UNITS`'s.
_WORDS = {"shear_modulus": "shear deformation modulus K"}
# name -> (JSON key, factor SI -> edge unit, unit, words), from the library's one unit table
_EDGE = {
    n: (EDGE_UNITS[n][0], EDGE_UNITS[n][2], EDGE_UNITS[n][1], _WORDS.get(n, EDGE_UNITS[n][3]))
    for n in ("cohesion", "friction_angle", "shear_modulus", "bekker_kc", "bekker_kphi", "bekker_n", "slip_sinkage")
}


def _num(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def grousers_separable(fixed: dict[str, float]) -> bool:
    """Whether one grousered wheel's fit can tell the grousers from the soil: phi held, or c held above 0.

    Bekker's grouser factors multiply c and tan(phi) (:mod:`soiltrack.soilmodel.grousers`), so with both
    fitted any grouser effect the model misses is booked as soil strength. ``fixed``: the held parameters
    ``{name: SI value}`` (c held at 0, the cohesion-free model, does not count: its factor multiplies nothing).
    """
    return "friction_angle" in fixed or fixed.get("cohesion", 0.0) > 0


def grouser_spacing_reason(height: float) -> str:
    """Why a grousered wheel's own fit with c and phi both fitted is a ``poor_fit`` (docs/physics.md)."""
    return (
        f"a grousered wheel (h = {1e3 * height:.3g} mm) with c and phi both fitted on it alone: the model's grouser "
        "term is Bekker's side shear, which assumes grousers close enough that the soil between them moves with "
        "the wheel; the grouser spacing is not modelled (sparse grousers push soil ahead of the wheel: more "
        "resistance, Skonieczny, Moreland and Wettergreen, IROS 2012), so whatever the grousers do beyond Bekker's "
        "term is booked as soil strength. Hold phi (a shear test: --fix) or fit this wheel beside a smooth wheel "
        "on the same soil (a joint fit, whose consistency test checks the grouser term)"
    )


@dataclass(frozen=True, eq=False)
class WheelFitResult:
    """What a rigid-wheel fit found and how far the data support it.

    ``theta`` holds the six parameters in SI (:data:`WHEEL_PARAMETERS` order); ``parameters`` the
    library's parameter records (SI inside, edge units in the JSON and report) keyed by JSON name;
    ``statements`` says in words what is identified.
    """

    wheel: RigidWheel
    success: bool
    status: str
    message: str
    theta: np.ndarray
    parameters: dict[str, ParameterEstimate]
    combinations: tuple[Combination, ...]
    statements: tuple[str, ...]
    warnings: tuple[str, ...]
    rank: int
    scaled_singular_values: tuple[float, ...]
    null_space: tuple[dict[str, float], ...]
    noise_sd: dict[str, float | None]
    rmse_drawbar_pull: float
    rmse_sinkage: float | None
    lack_of_fit: dict[str, Any]
    n_samples: int
    sinkage_measured: bool
    settings: Any
    iterations: int
    starts: int
    starts_converged: int
    solve_time_s: float
    dof: int
    residuals: np.ndarray | None = field(repr=False, default=None)
    rows_dropped: int = 0
    #: The torque channel's rms (weighted) residual, N m (``None``: the torque was not measured).
    rmse_torque: float | None = None
    #: Covariance of the free parameters in SI (order of :attr:`free_names`), ``None`` without one.
    covariance_si: np.ndarray | None = field(repr=False, default=None)
    #: The free parameters' names (``WHEEL_PARAMETERS`` order) of :attr:`covariance_si`.
    free_names: tuple[str, ...] = ()
    #: Directions (SI, over :attr:`free_names`) the data do not see: a prediction is estimable only
    #: when its gradient is orthogonal to every one.
    null_space_si: tuple[tuple[float, ...], ...] = ()

    def covariance_dict(self) -> dict[str, Any] | None:
        """The ``"covariance"`` block of the JSON (SI, linearised), or ``None``."""
        if self.covariance_si is None or not np.all(np.isfinite(self.covariance_si)):
            return None
        return {
            "parameters": list(self.free_names),
            "matrix": [[float(x) for x in row] for row in self.covariance_si],
            "units": "SI",
            "null_space": [list(v) for v in self.null_space_si],
        }

    def predict(self, data: WheelSweep) -> np.ndarray:
        """The model's drawbar pull (N) for each row of ``data`` (its sinkage, or solved from its load)."""
        return self._rows(data)[0]

    def predict_load(self, data: WheelSweep) -> np.ndarray:
        """The vertical force (N) of the fitted stresses at each row's sinkage (its load if solved)."""
        return self._rows(data)[1]

    def predict_torque(self, data: WheelSweep) -> np.ndarray:
        """The model's driving torque (N m) for each row of ``data`` (at the sinkage the pull uses)."""
        return self._rows(data)[4]

    def predict_sinkage(self, data: WheelSweep) -> np.ndarray:
        """The sinkage (m) at which the fitted stresses carry each row's load (the sinkage channel)."""
        return self._rows(data)[3]

    def _rows(self, data: WheelSweep) -> tuple[np.ndarray, ...]:
        return wheel_rows(self.wheel, self.settings, self.theta, data)

    @property
    def determined(self) -> list[str]:
        """What the data determine: identified parameters and determined combinations (JSON names)."""
        out = [k for k, e in self.parameters.items() if e.identified[0]]
        return out + [c.name for c in self.combinations if c.determined[0]]

    @property
    def fit_outcome(self) -> Outcome:
        """The fit's outcome by the one set of rules (:mod:`soiltrack.identify.outcome`): with repeats,
        lack of fit of the drawbar pull against their pure error is a poor fit."""
        lf = self.lack_of_fit
        test = None
        if lf.get("testable"):
            test = LackOfFitTest(
                "the pure error of the repeats (drawbar pull)",
                float(lf["F"]),
                (int(lf["lack_of_fit_dof"]), int(lf["pure_error_dof"])),
                float(lf["p_value"]),
            )
        base = decide_outcome(
            solver_ok=self.success,
            failure=self.message or self.status,
            determined=self.determined if self.success else (),
            lack_of_fit=test,
        )
        held = {e.name: float(e.value) for e in self.parameters.values() if e.fixed and e.value is not None}
        if base.outcome == "usable" and self.wheel.grouser_height > 0 and not grousers_separable(held):
            return Outcome("poor_fit", grouser_spacing_reason(self.wheel.grouser_height))
        return base

    @property
    def outcome(self) -> str:
        """One of :data:`~soiltrack.identify.outcome.OUTCOMES`."""
        return self.fit_outcome.outcome

    @property
    def running_gear(self) -> dict[str, Any]:
        """The JSON ``running_gear`` of a rigid wheel (``weight_N`` null: a rig's load is per row)."""
        w = self.wheel
        return running_gear_json(
            "rigid_wheel", name=w.name or None, weight_N=None, wheel_radius_m=w.radius, wheel_width_m=w.width
        )

    def to_dict(self) -> dict[str, Any]:
        """The JSON object (``soiltrack fit --json`` on a wheel sweep)."""
        return {
            "kind": "rigid_wheel",
            **self.fit_outcome.to_dict(),
            "running_gear": self.running_gear,
            "model": "wong_reece",
            "method": "ipopt",
            "status": "converged" if self.success else "failed",
            "success": self.success,
            "message": self.message,
            "n_samples": self.n_samples,
            "rows_dropped": self.rows_dropped,
            "sinkage": "measured" if self.sinkage_measured else "solved from the load (Bekker stresses)",
            "rmse_N": self.rmse_drawbar_pull,
            "sinkage_rmse_m": _num(self.rmse_sinkage),
            "noise_sd": {k: _num(v) for k, v in self.noise_sd.items()},
            "solve_time_s": self.solve_time_s,
            "parameters": {k: v.to_dict() for k, v in self.parameters.items()},
            "combinations": [_combination_json(c, self.success) for c in self.combinations],
            "identifiability": {
                "rank": self.rank,
                "n_parameters": sum(not e.fixed for e in self.parameters.values()),
                "parameters": [k for k, e in self.parameters.items() if not e.fixed],
                "scaled_singular_values": list(self.scaled_singular_values),
                "null_space": list(self.null_space),
                "statements": list(self.statements),
                "rank_tolerance": RANK_TOL,
            },
            "lack_of_fit": self.lack_of_fit,
            "warnings": list(self.warnings),
            "wheel": self.wheel.to_dict(),
            "settings": {
                "c1": self.settings.c1,
                "c2": self.settings.c2,
                "nodes": self.settings.nodes,
                "grouser_model": self.settings.grouser_model,
            },
            "solver": {
                "iterations": self.iterations,
                "starts": self.starts,
                "starts_converged": self.starts_converged,
            },
            "covariance": self.covariance_dict(),
            "torque_rmse_Nm": _num(self.rmse_torque) if self.rmse_torque is not None else None,
            "determined": self.determined if self.success else [],
            "dof": int(self.dof),
            "residuals": {
                "sign": RESIDUAL_SIGN,
                "unit": "N",
                "values": [_num(float(x)) for x in (self.residuals if self.residuals is not None else ())],
            },
            "channels": ["drawbar_pull_N"]
            + (["sinkage_m"] if self.sinkage_measured else [])
            + (["wheel_torque_Nm"] if self.rmse_torque is not None else []),
        }

    def to_json(self) -> str:
        """:meth:`to_dict` as JSON text."""
        return json.dumps(self.to_dict(), indent=2)

    def _determined_words(self) -> list[str]:
        return [_EDGE[_NAME_OF[d]][3] if d in _NAME_OF else d for d in self.determined]

    def report(self) -> str:
        """A plain-text report (at most about 40 lines)."""
        w = self.wheel
        nid = [_EDGE[_NAME_OF[k]][3] for k, e in self.parameters.items() if not e.fixed and not e.identified[0]]
        head = outcome_lines(self.fit_outcome, determined=self._determined_words(), not_identified=nid)
        lines = head + [
            f"rigid wheel (Wong-Reece), r = {w.radius:g} m, b = {w.width:g} m, h = {w.grouser_height:g} m; "
            f"{self.n_samples} rows"
            + (f" ({self.rows_dropped} rows of the file dropped)" if self.rows_dropped else "")
            + "; sinkage "
            + ("measured" if self.sinkage_measured else "solved from the load"),
            f"status: {'converged' if self.success else 'FAILED'} ({self.status}; {self.starts_converged} of "
            f"{self.starts} starts converged){'' if self.success else ': ' + self.message}",
            f"drawbar pull rmse {self.rmse_drawbar_pull:.4g} N"
            + (
                f", sinkage rmse {1e3 * self.rmse_sinkage:.3g} mm (against the sinkage that carries the load)"
                if self.rmse_sinkage is not None
                else ""
            )
            + (f", wheel torque rmse {self.rmse_torque:.4g} N m" if self.rmse_torque is not None else ""),
            "",
        ]
        lines.append(f"{'parameter':<30}{'value':>12}{'95 % interval':>28}  identifiable")
        for key, e in self.parameters.items():
            lines.append(_parameter_line(key, e))
        if self.combinations:
            lines.append("")
            for c in self.combinations:
                lines.append(_combination_line(c))
        lines.append("")
        lines.append("what the data identify:")
        lines += [f"- {s}" for s in self.statements]
        lf = self.lack_of_fit
        if lf.get("testable"):
            lines.append(
                f"lack of fit against the repeats' scatter (pure error sd {lf['pure_error_sd_N']:.3g} N, "
                f"{lf['conditions']} slip and load levels): F = {lf['F']:.3g}, p = {lf['p_value']:.3g}"
            )
        elif lf:
            lines.append(f"lack of fit: not testable ({lf.get('reason', '')})")
        for wmsg in self.warnings:
            lines.append(f"warning: {wmsg}")
        return "\n".join(lines)


_NAME_OF = {v[0]: n for n, v in _EDGE.items()}


def _parameter_line(key: str, e: ParameterEstimate) -> str:
    """One row of the report's parameter table; no number for a parameter the data do not identify,
    and nothing on a bound (or with an interval over most of its range) called identified."""
    lab = f"{e.words + ' (' + e.edge_unit + ')':<30}"
    value = e.edge_value if e.edge_value is not None else float("nan")
    if e.fixed:
        return f"{lab}{value:>12.4g}{'fixed':>28}  fixed"
    if not e.identifiable:
        return f"{lab}{'-':>12}{'-':>28}  NOT IDENTIFIABLE (the optimiser's point is no estimate)"
    lo, hi = e.edge_ci95
    ci = "-" if lo is None or hi is None else f"[{lo:.4g}, {hi:.4g}]"
    ok, why = e.identified
    if e.at_bound:
        ident = f"no: ON {str(e.bound_side).upper()} BOUND (interval not reliable)"
    elif not ok:
        ident = f"no: {why}"
    else:
        ident = "weakly" if e.weakly_identifiable else "yes"
    return f"{lab}{value:>12.4g}{ci:>28}  {ident}"


def _combination_json(c: Combination, success: bool) -> dict[str, Any]:
    """A combination's JSON entry (the one layout) with ``determined`` by the one rule."""
    ok, why = c.determined if success else (False, "the fit failed")
    return {**c.to_dict(), "determined": ok, "not_determined_reason": why or None}


def _combination_line(c: Combination) -> str:
    """A combination in the report: a number only where the data determine it."""
    ok, why = c.determined
    if not ok:
        return f"{c.name}: NOT DETERMINED ({why})"
    ci = "-" if c.ci95[0] is None else f"[{c.ci95[0]:.4g}, {c.ci95[1]:.4g}]"
    tail = f" (terms on a bound: {', '.join(c.terms_on_bounds)}; conditional on them)" if c.terms_on_bounds else ""
    return (
        f"{c.name} = {c.value:.4g} {c.unit}, 95 % {ci}"
        + (" (weakly identified)" if c.weakly_identifiable else "")
        + tail
    )


def wheel_rows(wheel: RigidWheel, settings, theta: np.ndarray, data: WheelSweep) -> tuple[np.ndarray, ...]:
    """Per row at parameters ``theta`` (SI): drawbar pull (N), vertical force (N), the sinkage used (m)
    and the sinkage that carries the row's load (m)."""
    fn = residual_function(wheel, settings, data.has_sinkage).map(data.n_samples)
    z = data.sinkage if data.sinkage is not None else np.zeros(data.n_samples)
    th = np.tile(np.asarray(theta, dtype=float).reshape(-1, 1), (1, data.n_samples))
    out = fn(data.slip.reshape(1, -1), z.reshape(1, -1), data.normal_load.reshape(1, -1), th)
    return tuple(np.asarray(v, dtype=float).ravel() for v in out)


def _split(x: np.ndarray, gap) -> np.ndarray:
    """Group label per value: sorted values split where the step exceeds ``gap(previous value)``."""
    order = np.argsort(x)
    labels = np.empty(x.size, dtype=int)
    g = 0
    for a, b in zip(order[:-1], order[1:]):
        labels[a] = g
        if x[b] - x[a] > gap(x[a]):
            g += 1
    labels[order[-1]] = g
    return labels


def slip_levels(slip: np.ndarray) -> np.ndarray:
    """Slip level of each row (sorted slips split where the step exceeds :data:`SLIP_LEVEL_TOL`)."""
    return _split(slip, lambda _: SLIP_LEVEL_TOL)


def conditions(slip: np.ndarray, load: np.ndarray) -> np.ndarray:
    """Condition of each row: its slip level and, within it, its load level (:data:`LOAD_REPEAT_TOL`)."""
    lev = slip_levels(slip)
    out = np.empty(slip.size, dtype=int)
    n = 0
    for g in np.unique(lev):
        idx = np.nonzero(lev == g)[0]
        sub = _split(load[idx], lambda w: LOAD_REPEAT_TOL * w)
        out[idx] = sub + n
        n += int(sub.max()) + 1
    return out


def pure_error(values: np.ndarray, slip: np.ndarray, load: np.ndarray) -> tuple[float, int, int]:
    """(pure-error sum of squares, its dof, number of conditions) of repeats at one slip and load level."""
    lab = conditions(slip, load)
    ss, dof = 0.0, 0
    for g in np.unique(lab):
        v = values[lab == g]
        ss += float(((v - v.mean()) ** 2).sum())
        dof += v.size - 1
    return ss, dof, int(np.unique(lab).size)


def _lack_of_fit(data: WheelSweep, r_dp: np.ndarray, rank_dp: int) -> dict[str, Any]:
    ss_pe, dof_pe, levels = pure_error(data.drawbar_pull, data.slip, data.normal_load)
    out: dict[str, Any] = {"conditions": levels, "pure_error_dof": dof_pe}
    dof_lof = levels - rank_dp
    ss_res = float(r_dp @ r_dp)
    if dof_pe <= 0 or dof_lof <= 0 or ss_pe <= 0:
        out.update(
            testable=False,
            reason=(
                f"{levels} conditions (slip and load levels) for {rank_dp} identified directions of the drawbar pull"
                if dof_lof <= 0
                else "no repeated condition"
            ),
        )
        return out
    ss_lof = max(ss_res - ss_pe, 0.0)
    F = (ss_lof / dof_lof) / (ss_pe / dof_pe)
    out.update(
        testable=True,
        pure_error_sd_N=math.sqrt(ss_pe / dof_pe),
        lack_of_fit_dof=dof_lof,
        F=F,
        p_value=f_sf(F, dof_lof, dof_pe),
        note="repeats of a condition differ a little in load and sinkage: their scatter includes that of "
        "the covariates",
    )
    return out


def _wheel_parameters(theta, free, lo, hi, ident, Pinv, C, q) -> tuple[dict[str, ParameterEstimate], list, list]:
    """Each parameter's record (SI; held ones as given), and the names not identifiable and weakly
    identifiable."""
    params: dict[str, ParameterEstimate] = {}
    kf = 0
    weak_names, nonid = [], []
    for k, name in enumerate(WHEEL_PARAMETERS):
        key, words = _EDGE[name][0], _EDGE[name][3]
        if not free[k]:
            params[key] = ParameterEstimate(
                name, float(theta[k]), None, (None, None), True, fixed=True, note="held fixed", label=words
            )
            continue
        span = hi[k] - lo[k]
        side = (
            "lower"
            if theta[k] - lo[k] < BOUND_REL_TOL * span
            else "upper"
            if hi[k] - theta[k] < BOUND_REL_TOL * span
            else None
        )
        vif = float(Pinv[kf, kf])
        weak = bool(ident[kf] and vif > WEAK_VIF)
        se = math.sqrt(C[kf, kf]) if C is not None and ident[kf] and C[kf, kf] >= 0 else None
        # linearised interval, intersected with the bounds (no negative cohesion or friction angle)
        ci = (
            (max(theta[k] - q * se, lo[k]), min(theta[k] + q * se, hi[k]))
            if se is not None and q is not None
            else (None, None)
        )
        note = "" if side is None else f"on its {side} bound: the data or the bounds want a value beyond it"
        params[key] = ParameterEstimate(
            name,
            float(theta[k]),
            se,
            (None if ci[0] is None else float(ci[0]), None if ci[1] is None else float(ci[1])),
            bool(ident[kf]),
            weakly_identifiable=weak,
            at_bound=side is not None,
            bound_side=side,
            note=note,
            lower=float(lo[k]),
            upper=float(hi[k]),
            label=words,
        )
        if not ident[kf]:
            nonid.append(name)
        elif weak:
            weak_names.append(name)
        kf += 1

    return params, nonid, weak_names


def _null_statements(null, D, names, statements: list) -> list[dict[str, float]]:
    """The null directions in edge units (largest component positive); a statement per direction."""
    null_dirs = []
    for col in null.T:
        d = col / D * np.array([_EDGE[nm][1] for nm in names])
        d = d / np.linalg.norm(d)
        if d[np.argmax(np.abs(d))] < 0:
            d = -d
        null_dirs.append({_EDGE[nm][0]: float(d[j]) for j, nm in enumerate(names)})
        involved = [_EDGE[nm][3] for j, nm in enumerate(names) if abs(col[j]) > 0.1]
        statements.append(
            f"the data do not separate {' and '.join(involved)}: they see no change along one "
            "combination of them (a null direction of the Jacobian)."
        )
    return null_dirs


def _parameter_statements(names, nonid, weak_names, combos, params, ident) -> list[str]:
    """What the data identify, in words: parameters not identifiable, weakly identifiable, not identified by
    the outcome rules (on a bound, an interval over most of the range), the combinations."""
    statements: list[str] = []
    for name in nonid:
        statements.append(f"{_EDGE[name][3]} is not identifiable from these data.")
    for name in weak_names:
        statements.append(
            f"{_EDGE[name][3]} is only weakly identifiable (its estimate correlates above "
            f"{WEAK_CORRELATION} with the other parameters'): its interval is wide."
        )
    for c in combos:
        if c.determined[0] and not c.weakly_identifiable and c.stderr is not None:
            statements.append(f"{c.name} ({c.description}) is identified: {c.value:.4g} {c.unit} +- {c.stderr:.2g}.")
        elif c.estimable and not c.determined[0]:
            statements.append(f"{c.name} ({c.description}) is not determined: {c.determined[1]}.")
    good = [
        _EDGE[nm][3]
        for j, nm in enumerate(names)
        if ident[j] and nm not in weak_names and params[_EDGE[nm][0]].identified[0]
    ]
    if good:
        statements.append(f"identified on their own: {', '.join(good)}.")
    for nm in names:
        e = params[_EDGE[nm][0]]
        if e.identifiable and not e.identified[0]:
            statements.append(f"{_EDGE[nm][3]} is not identified: {e.identified[1]}.")
    return statements


def _wheel_combinations(data, wheel, options, theta, free, lo, hi, params, D, null, Pinv, C, q) -> list:
    """The combinations the wheel's data can pin down: the shear strength at the mean contact pressure and
    the Bekker stiffness of this width (edge units), with the range their terms' bounds allow."""
    sink = data.has_sinkage

    def combo(grad_full: np.ndarray) -> tuple[float | None, bool, bool]:
        g = grad_full[free]
        gs = g / D
        nrm = float(np.linalg.norm(gs))
        est = estimable(gs, null)
        weak = bool(est and nrm > 0 and float(gs @ Pinv @ gs) / nrm**2 > WEAK_VIF)
        if not est or C is None:
            return None, est, weak
        var = float(g @ C @ g)
        return (math.sqrt(var) if var >= 0 else None), est, weak

    combos = []
    # shear strength at the mean contact pressure
    z_used = data.sinkage if sink else None
    if z_used is None:
        z_used = wheel_rows(wheel, options.settings, theta, data)[2]
    th1 = np.asarray(entry_angle(np.clip(z_used, 1e-12, wheel.radius), wheel.radius), dtype=float).ravel()
    p_bar = float(np.mean(data.normal_load / (wheel.width * wheel.radius * th1)))

    def on_bounds(*ks: int) -> tuple[tuple[str, ...], bool]:
        names_on = tuple(
            _EDGE[WHEEL_PARAMETERS[k]][0] for k in ks if free[k] and params[_EDGE[WHEEL_PARAMETERS[k]][0]].at_bound
        )
        return names_on, len(names_on) == sum(bool(free[k]) for k in ks)

    if free[0] or free[1]:
        tau = theta[0] + p_bar * math.tan(theta[1])
        tau_rng = (lo[0] + p_bar * math.tan(lo[1]), hi[0] + p_bar * math.tan(hi[1]))
        tau_on, tau_all = on_bounds(0, 1)
        se, est, weak = combo(np.array([1.0, p_bar / math.cos(theta[1]) ** 2, 0, 0, 0, 0, 0]))
        ci = (max(tau - q * se, 0.0), tau + q * se) if se is not None and q is not None else (None, None)
        combos.append(
            Combination(
                "c + p tan(phi)",
                tau / 1e3,
                None if se is None else se / 1e3,
                (None if ci[0] is None else ci[0] / 1e3, None if ci[1] is None else ci[1] / 1e3),
                "kPa",
                f"shear strength at the mean contact pressure p = {p_bar / 1e3:.3g} kPa "
                "(load over the arc's projected area b r theta_1)",
                estimable=est,
                weakly_identifiable=weak,
                range=(tau_rng[0] / 1e3, tau_rng[1] / 1e3),
                terms_on_bounds=tau_on,
                all_terms_on_bounds=tau_all,
            )
        )
    if free[3] and free[4]:
        kval = bekker_modulus(theta[3], theta[4], wheel.width)
        k_rng = (bekker_modulus(lo[3], lo[4], wheel.width), bekker_modulus(hi[3], hi[4], wheel.width))
        k_on, k_all = on_bounds(3, 4)
        se, est, weak = combo(np.array([0, 0, 0, 1.0 / wheel.width, 1.0, 0, 0]))
        ci = (max(kval - q * se, 0.0), kval + q * se) if se is not None and q is not None else (None, None)
        combos.append(
            Combination(
                "k_c / b + k_phi",
                kval / 1e3,
                None if se is None else se / 1e3,
                (None if ci[0] is None else ci[0] / 1e3, None if ci[1] is None else ci[1] / 1e3),
                "kN/m^(n+2)",
                f"Bekker stiffness of this wheel's width b = {wheel.width:g} m",
                estimable=est,
                weakly_identifiable=weak,
                range=(float(k_rng[0]) / 1e3, float(k_rng[1]) / 1e3),
                terms_on_bounds=k_on,
                all_terms_on_bounds=k_all,
            )
        )

    return combos


def build_wheel_result(
    *,
    data: WheelSweep,
    wheel: RigidWheel,
    options,
    free: np.ndarray,
    theta: np.ndarray,
    residual_dp: np.ndarray,
    residual_z: np.ndarray,
    jac_dp: np.ndarray,
    jac_z: np.ndarray,
    converged: bool,
    status: str,
    iterations: int,
    starts: int,
    starts_converged: int,
    solve_time_s: float,
    residual_torque: np.ndarray | None = None,
    jac_torque: np.ndarray | None = None,
) -> WheelFitResult:
    """Assemble a :class:`WheelFitResult` from the optimum's residuals and Jacobians (SI).

    ``residual_torque`` / ``jac_torque``: the measured torque's channel (weighted by its rows'
    relative standard deviations), stacked with its own noise level like the sinkage's.
    """
    n = data.n_samples
    sink = data.has_sinkage
    lo, hi = np.array(options.bounds.lower), np.array(options.bounds.upper)
    theta = np.clip(theta, lo, hi)  # IPOPT may end a hair outside a bound (its bound relaxation)
    rw, J, (s_dp, s_z, s_t) = _weighted_channels(
        data, wheel, (residual_dp, jac_dp), (residual_z, jac_z), (residual_torque, jac_torque)
    )
    finite = bool(np.all(np.isfinite(J)) and np.all(np.isfinite(rw)) and np.all(np.isfinite(theta)))
    names = [WHEEL_PARAMETERS[k] for k in range(len(WHEEL_PARAMETERS)) if free[k]]
    st = core_stats_one(np.where(np.isfinite(J), J, 0.0), np.where(np.isfinite(rw), rw, 0.0), False)
    D, V, Srel, Pinv = st["D"][0], st["V"][0], st["S"][0], st["Pinv"][0]
    nonnull, rank, dof, s2 = st["nonnull"][0], int(st["rank"][0]), int(st["dof"][0]), float(st["s2"][0])
    null = V[:, ~nonnull]
    ident = identified_columns(null, st["Dok"][0])
    q = quantile(dof, False)
    C = s2 * Pinv / np.outer(D, D) if math.isfinite(s2) else None

    params, nonid, weak_names = _wheel_parameters(theta, free, lo, hi, ident, Pinv, C, q)

    combos = _wheel_combinations(data, wheel, options, theta, free, lo, hi, params, D, null, Pinv, C, q)
    statements: list[str] = []
    null_dirs = _null_statements(null, D, names, statements)
    statements += _parameter_statements(names, nonid, weak_names, combos, params, ident)
    warnings = _load_notes(data, params, statements)
    rank_dp = int(core_stats_one(np.where(np.isfinite(jac_dp), jac_dp, 0.0), residual_dp, False)["rank"][0])
    lof = _lack_of_fit(data, residual_dp, rank_dp)
    ok = converged and finite
    message = (
        ""
        if ok
        else (
            "IPOPT did not converge from any start"
            if not converged
            else "non-finite residuals or Jacobian at the optimum"
        )
    )
    return WheelFitResult(
        wheel=wheel,
        success=ok,
        status=status,
        message=message,
        theta=np.array(theta, dtype=float),
        parameters=params,
        combinations=tuple(combos),
        statements=tuple(statements),
        warnings=tuple(warnings),
        rank=rank,
        scaled_singular_values=tuple(float(s) for s in Srel),
        null_space=tuple(null_dirs),
        noise_sd={"drawbar_pull_N": s_dp, "sinkage_m": s_z, **({"wheel_torque_Nm": s_t} if s_t is not None else {})},
        rmse_drawbar_pull=s_dp,
        rmse_sinkage=s_z,
        lack_of_fit=lof,
        n_samples=n,
        sinkage_measured=sink,
        settings=options.settings,
        iterations=iterations,
        starts=starts,
        starts_converged=starts_converged,
        solve_time_s=solve_time_s,
        dof=dof,
        residuals=np.asarray(residual_dp, dtype=float),
        rows_dropped=int(data.dropped),
        rmse_torque=s_t,
        covariance_si=None if C is None else np.array(C, dtype=float),
        free_names=tuple(names),
        null_space_si=tuple(tuple(float(x) for x in (col / D) / np.linalg.norm(col / D)) for col in null.T),
    )


def _weighted_channels(data: WheelSweep, wheel: RigidWheel, dp: tuple, z: tuple, torque: tuple):
    """Stack the channels weighted as the objective's optimum weighted them: ``(rw, J, (s_dp, s_z, s_t))``.

    Each channel is ``(residuals, Jacobian)``; the sinkage's counts when measured, the torque's when given.
    The weights are ``1 / sqrt(SSR_k / n + floor_k^2)`` per channel.
    """
    (residual_dp, jac_dp), (residual_z, jac_z), (residual_torque, jac_torque) = dp, z, torque
    n, sink = data.n_samples, data.has_sinkage
    s_dp = math.sqrt(float(residual_dp @ residual_dp) / n)
    s_z = math.sqrt(float(residual_z @ residual_z) / n) if sink else None
    # the weights the objective's optimum used: 1 / (SSR_k / n + floor_k^2) per channel
    f_dp, f_z = channel_floors(float(np.mean(data.normal_load)))
    s_dp_eff = math.sqrt(s_dp**2 + f_dp**2)
    rw = residual_dp / s_dp_eff
    J = jac_dp / s_dp_eff
    if s_z is not None:
        s_z_eff = math.sqrt(s_z**2 + f_z**2)
        rw = np.concatenate([rw, residual_z / s_z_eff])
        J = np.vstack([J, jac_z / s_z_eff])
    s_t = None
    if residual_torque is not None and jac_torque is not None:
        s_t = math.sqrt(float(residual_torque @ residual_torque) / n)
        s_t_eff = math.hypot(s_t, torque_floor(float(np.mean(data.normal_load)), wheel.radius))
        rw = np.concatenate([rw, residual_torque / s_t_eff])
        J = np.vstack([J, jac_torque / s_t_eff])
    return rw, J, (s_dp, s_z, s_t)


def _load_notes(data: WheelSweep, params: dict, statements: list[str]) -> list[str]:
    """Append what the loads' spread says to ``statements``; the warnings of load-slip correlation and bounds."""
    n = data.n_samples
    W = data.normal_load
    spread = float((W.max() - W.min()) / W.mean())
    warnings: list[str] = []
    if spread < LOAD_SPREAD_MIN:
        statements.append(
            f"the loads span only {100 * spread:.0f} % of their mean ({W.min():.4g}-{W.max():.4g} N): "
            "c and phi separate only through the pressure's variation along the arc and with the "
            "sinkage, not through the load."
        )
    if n > 2 and np.std(W) > 0 and np.std(data.slip) > 0:
        rho = float(np.corrcoef(W, data.slip)[0, 1])
        if abs(rho) > LOAD_SLIP_CORRELATION_WARN:
            warnings.append(
                f"the load correlates with the slip (r = {rho:+.2f}): what the fit attributes to the load "
                "may be the slip's doing and vice versa; c and phi rest on it."
            )
    at_bound = [k for k, e in params.items() if e.at_bound]
    if at_bound:
        warnings.append(f"on a bound: {', '.join(at_bound)} (the interval of a bound-pinned value is not reliable).")
    return warnings


#: Public names of the wheel's edge units and words, and of the report line (the joint fit of several
#: data sets uses them).
WHEEL_EDGE = _EDGE
parameter_line = _parameter_line
