"""The result of a joint fit of several data sets: the shared soil, each data set's own fit, the
consistency test (:class:`JointFitResult`, :func:`build_joint_result`)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..estimates.distributions import chi2_sf
from ..estimates.least_squares import quantile
from ..outcome import OUTCOME_SETTINGS, Outcome, decide_outcome, on_bound, outcome_lines
from ..wheel.result import WHEEL_EDGE as _EDGE
from ..estimates.records import ParameterEstimate
from ..wheel.result import parameter_line
from .problem import N_SHARED, SHARED, box8

__all__ = ["JointFitResult", "build_joint_result", "consistency_test"]


@dataclass(frozen=True)
class JointFitResult:
    """One soil fitted to several data sets.

    Attributes
    ----------
    parameters
        The shared soil's estimates ``{JSON key: ParameterEstimate}`` (SI inside; edge units in the
        JSON, as a wheel fit's).
    specific
        Per data set its gear-specific estimates (``{"slip_sinkage": ParameterEstimate}`` or empty).
    datasets
        Per data set ``{"label", "kind", "rows", "gear", "outcome", "soil", ...}`` (its own fit).
    consistency
        The likelihood-ratio test of one soil against each data set's own (``p_value``, ``test``,
        ``statistic``, ``dof``, ``shifts_se``, ``contributions``, ``disagrees``).
    """

    labels: tuple[str, ...]
    parameters: dict[str, ParameterEstimate]
    specific: tuple[dict[str, ParameterEstimate], ...]
    datasets: tuple[dict[str, Any], ...]
    consistency: dict[str, Any]
    converged: bool
    status: str
    rank: int
    n_rows: int
    noise_sd: tuple[dict[str, float], ...]
    solve_time_s: float
    starts: int
    starts_converged: int
    notes: tuple[str, ...] = ()
    theta: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    covariance_si: np.ndarray | None = field(repr=False, default=None)
    free_names: tuple[str, ...] = ()

    @property
    def success(self) -> bool:
        """IPOPT converged with finite numbers."""
        return self.converged

    @property
    def determined(self) -> list[str]:
        """The shared parameters the data identify."""
        return [k for k, e in self.parameters.items() if e.identified[0]]

    @property
    def fit_outcome(self) -> Outcome:
        """The one outcome rules, then the consistency test: disagreeing data sets are a poor fit."""
        base = decide_outcome(
            solver_ok=self.success, failure=f"IPOPT {self.status}", determined=self.determined if self.success else ()
        )
        if base.outcome != "usable":
            return base
        c = self.consistency
        if c.get("poor_fit"):
            return Outcome("poor_fit", c["reason"])
        return base

    @property
    def outcome(self) -> str:
        """One of :data:`~soiltrack.identify.outcome.OUTCOMES`."""
        return self.fit_outcome.outcome

    def to_dict(self) -> dict[str, Any]:
        """The JSON object (``soiltrack fit A.csv B.csv ... --json``)."""
        return {
            **self.fit_outcome.to_dict(),
            "running_gear": {
                "kind": "several",
                "name": None,
                "weight_N": None,
                "per_dataset": [d["gear"] for d in self.datasets],
            },
            "kind": "joint",
            "model": "wong_reece",
            "method": "ipopt",
            "status": "converged" if self.success else "failed",
            "success": self.success,
            "n_samples": self.n_rows,
            "consistency": self.consistency,
            "parameters": {k: v.to_dict() for k, v in self.parameters.items()},
            "gear_parameters": [{k: v.to_dict() for k, v in s.items()} for s in self.specific],
            "datasets": list(self.datasets),
            "noise_sd": list(self.noise_sd),
            "identifiability": {"rank": self.rank, "parameters": list(self.free_names)},
            "solver": {"starts": self.starts, "starts_converged": self.starts_converged},
            "solve_time_s": self.solve_time_s,
            "notes": list(self.notes),
            "covariance": None
            if self.covariance_si is None or not np.all(np.isfinite(self.covariance_si))
            else {
                "parameters": list(self.free_names),
                "matrix": [[float(x) for x in row] for row in self.covariance_si],
                "units": "SI",
            },
        }

    def to_json(self) -> str:
        """:meth:`to_dict` as JSON text (a non-finite number, e.g. of a failed solve, as null)."""
        return json.dumps(_finite(self.to_dict()), indent=2)

    def report(self) -> str:
        """Plain text: the outcome, the consistency test first, the joint soil, each data set's own fit."""
        nid = [_EDGE[_name(k)][3] for k, e in self.parameters.items() if not e.fixed and not e.identified[0]]
        words = [_EDGE[_name(k)][3] for k in self.determined]
        lines = outcome_lines(self.fit_outcome, determined=words, not_identified=nid)
        lines += consistency_lines(self.consistency, self.labels)
        lines.append(
            f"joint fit of {len(self.labels)} data sets, {self.n_rows} residuals: "
            f"{'converged' if self.success else 'FAILED'} ({self.status}; {self.starts_converged} of {self.starts} "
            "starts converged)"
        )
        lines.append(f"{'shared soil':<30}{'value':>12}{'95 % interval':>28}  identifiable")
        for key, e in self.parameters.items():
            lines.append(parameter_line(key, e))
        for lab, sp in zip(self.labels, self.specific):
            for key, e in sp.items():
                lines.append(_specific_line(key, e) + f"  [{lab}]")
        lines.append("each data set's own fit:")
        for d in self.datasets:
            soil = ", ".join(f"{k} {_fmt(v)}" for k, v in d["soil"].items() if v is not None)
            lines.append(f"- {d['label']} ({d['kind']}, {d['rows']} rows): {d['outcome']}; {soil}")
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)


def _specific_line(key: str, e: ParameterEstimate) -> str:
    """A gear-specific parameter's report row (the wheel's table row; the grouser height written here)."""
    if key != "grouser_height_m":
        return parameter_line(key, e)
    lab = f"{'grouser height h (m)':<30}"
    value = e.edge_value if e.edge_value is not None else float("nan")
    lo, hi = e.edge_ci95
    if not e.identifiable or lo is None or hi is None:
        return f"{lab}{value:>12.4g}{'-':>28}  NOT IDENTIFIABLE"
    ident = f"no: ON {str(e.bound_side).upper()} BOUND" if e.at_bound else "yes"
    return f"{lab}{value:>12.4g}{f'[{lo:.4g}, {hi:.4g}]':>28}  {ident}"


def _finite(x: Any) -> Any:
    """``x`` with every non-finite float replaced by None (JSON has no NaN)."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    return x


def _fmt(v: Any) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def _name(key: str) -> str:
    return next(n for n, e in _EDGE.items() if e[0] == key)


def consistency_lines(c: dict[str, Any], labels) -> list[str]:
    """The report's consistency lines (first after the outcome)."""
    if c.get("p_value") is None:
        return [f"consistency: not testable ({c.get('reason_untestable', '')})"]
    out = [
        f"consistency of one soil across the {len(labels)} data sets: likelihood ratio {c['statistic']:.4g} on "
        f"{c['dof']} dof, p = {c['p_value']:.3g} ({'they disagree' if c['poor_fit'] else 'consistent'} at the "
        f"{OUTCOME_SETTINGS.lack_of_fit_level:g} level)"
    ]
    for lab, share in zip(labels, c["contributions"]):
        out.append(f"  {lab}: share of the statistic {share:.3g}")
    for key, shifts in c["shifts_se"].items():
        txt = ", ".join("n/a" if s is None else f"{s:+.2f}" for s in shifts)
        out.append(f"  {key} own - joint, in own standard errors: {txt}")
    return out


#: Edge units of the wheel's parameters and of the grouser height (a gear-specific parameter here).
EDGE = {**_EDGE, "grouser_height": ("grouser_height_m", 1.0, "m", "grouser height h")}
NAMES8 = tuple(_EDGE) + ("grouser_height",)


def _estimates(theta8, names_idx, spec, sol, bounds, fixed_names) -> dict[str, ParameterEstimate]:
    """Parameter records (SI) of the parameters ``names_idx`` (``(index into the 8-vector, variable column
    or None)``)."""
    cov, ident, q = sol["cov"], sol["ident"], quantile(int(sol["dof"]), False)
    lo, hi, _ = box8(spec, bounds)
    out = {}
    for k, col in names_idx:
        name = NAMES8[k]
        key = EDGE[name][0]
        v = float(np.clip(theta8[k], lo[k], hi[k]))
        side = on_bound(v, lo[k], hi[k])
        se = None
        if col is not None and ident[col] and math.isfinite(cov[col, col]):
            se = math.sqrt(max(float(cov[col, col]), 0.0))
        ci = (v - q * se, v + q * se) if se is not None and q is not None else (None, None)
        out[key] = ParameterEstimate(
            name,
            value=v,
            stderr=se,
            ci95=ci,
            identifiable=bool(col is not None and ident[col]),
            weakly_identifiable=False,
            at_bound=side is not None,
            bound_side=side,
            fixed=col is None,
            note="held" if name in fixed_names else ("" if col is not None else "not in these data"),
            lower=float(lo[k]),
            upper=float(hi[k]),
            label=EDGE[name][3],
        )
    return out


def _columns(specs, shared_free) -> tuple[list[int | None], list[list[tuple[int, int | None]]]]:
    """Variable column of each shared parameter (None if held) and each block's specific ``(index, column)``."""
    cols: list[int | None] = []
    q = 0
    for k in range(N_SHARED):
        cols.append(q if shared_free[k] else None)
        q += shared_free[k]
    spec_cols: list[list[tuple[int, int | None]]] = []
    for s in specs:
        mine: list[tuple[int, int | None]] = []
        for k, free in ((N_SHARED, s.specific_free), (N_SHARED + 1, s.grouser_free)):
            if free:
                mine.append((k, q))
                q += 1
        spec_cols.append(mine)
    return cols, spec_cols


def consistency_test(own, joint, labels, own_est, joint_est, leave_one_out=None) -> dict[str, Any]:
    """The likelihood-ratio test of one soil, each data set's share, the shifts in standard errors.

    ``leave_one_out``: per data set the p-value of the same test on the OTHER data sets (None where not
    testable); given, the disagreeing data set is the one without which the others agree best (else the
    largest share: a block whose noise level is estimated gives in to a precise one, so with three or more
    data sets the share alone can name the wrong one)."""
    f_joint = joint["f_blocks"]
    shares = [2 * (float(f_joint[d]) - float(o["solution"]["f_blocks"][0])) for d, o in enumerate(own)]
    shares = [max(0.0, x) if math.isfinite(x) else math.nan for x in shares]
    stat = float(sum(shares))
    dof = int(sum(o["solution"]["rank"] for o in own) - joint["rank"])
    shifts: dict[str, list[float | None]] = {}
    for key, je in joint_est.items():
        if je.fixed:
            continue
        row = []
        for oe in own_est:
            e = oe.get(key)
            ok = e is not None and e.identifiable and e.stderr and not e.at_bound
            row.append(None if not ok else float((e.value - je.value) / e.stderr))
        shifts[key] = row
    out: dict[str, Any] = {
        "test": "likelihood ratio: one soil for every data set against each data set's own fit (chi-square)",
        "statistic": stat,
        "dof": dof,
        "p_value": chi2_sf(stat, dof) if dof > 0 else None,
        "shifts_se": shifts,
        "contributions": shares,
        "disagrees": None,
        "poor_fit": False,
    }
    if not math.isfinite(stat):  # a failed solve: no statistic (never NaN in the JSON)
        out.update(statistic=None, p_value=None, contributions=[None] * len(shares))
        out["reason_untestable"] = "a fit did not give a finite likelihood"
        return out
    if dof <= 0:
        out["reason_untestable"] = "the data sets identify no parameter in common (degrees of freedom 0)"
        return out
    worst = int(np.argmax(shares))
    loo = None if leave_one_out is None else [(-1.0 if v is None else float(v)) for v in leave_one_out]
    if loo is not None and max(loo) >= 0:
        worst = int(np.argmax(loo))
        out["leave_one_out_p"] = list(leave_one_out)
    if out["p_value"] < OUTCOME_SETTINGS.lack_of_fit_level:
        big = [(abs(float(v)), k) for k, s in shifts.items() if (v := s[worst]) is not None]
        par = (
            f"; its {max(big)[1]} lies {shifts[max(big)[1]][worst]:+.2f} own standard errors from the joint value"
            if big
            else ""
        )
        out.update(
            poor_fit=True,
            disagrees=labels[worst],
            reason=(
                f"the data sets do not share one soil (likelihood ratio {stat:.4g} on {dof} dof, p = "
                f"{out['p_value']:.3g}): {labels[worst]} disagrees most ({shares[worst]:.3g} of the statistic"
                + (
                    f"; without it the others agree with p = {loo[worst]:.3g}"
                    if loo is not None and loo[worst] >= 0
                    else ""
                )
                + f"){par}"
            ),
        )
    return out


def _gear_json(gear) -> dict[str, Any] | None:
    if gear is None:
        return None
    if not hasattr(gear, "radius"):  # a tracked Vehicle (a track sweep or a drive log)
        return {
            "kind": "track",
            "name": gear.name or None,
            "weight_N": gear.weight,
            "contact_area_m2": gear.contact_area,
            "track_length_m": gear.track_length,
        }
    return {
        "kind": "rigid_wheel",
        "name": gear.name or None,
        "wheel_radius_m": gear.radius,
        "wheel_width_m": gear.width,
        "grouser_height_m": gear.grouser_height,
    }


def _own_entry(label, spec, gear, o, est) -> dict[str, Any]:
    off = o["official"]
    return {
        "label": label,
        "file": label,
        "kind": {
            "wheel": "wheel_sweep",
            "shear": "shear_test",
            "annulus": "shear_annulus",
            "plate": "plate_test",
            "track": "track_sweep",
            "drivelog": "drive_log",
        }[spec.kind],
        "rows": spec.n,
        "gear": _gear_json(gear),
        "outcome": off.outcome,
        "outcome_reason": off.fit_outcome.reason,
        "soil": {k: (e.edge_value if e.identifiable else None) for k, e in est.items() if not e.fixed},
        "soil_stderr": {k: e.edge_stderr for k, e in est.items() if not e.fixed},
        "converged": bool(o["solution"]["converged"]),
        "rank": int(o["solution"]["rank"]),
        "noise_sd": o["solution"]["noise_sd"][0],
    }


def build_joint_result(
    *, labels, datasets, gears, specs, own, joint, shared_free, theta8, fixed, bounds, solve_time_s, leave_one_out=None
) -> JointFitResult:
    """Assemble the :class:`JointFitResult` from the own solutions and the joint one (:mod:`.fit`)."""
    from .problem import block_touches

    cols, spec_cols = _columns(specs, shared_free)
    fixed_names = set(fixed)
    joint_est = _estimates(theta8[0], list(enumerate(cols)), specs[0], joint, bounds, fixed_names)
    specific = tuple(_estimates(theta8[d], spec_cols[d], s, joint, bounds, fixed_names) for d, s in enumerate(specs))
    own_est = []
    for o, s in zip(own, specs):
        oc, _ = _columns([s], o["shared_free"])
        touch = block_touches(s)
        idx = [(k, oc[k]) for k in range(N_SHARED) if touch[k]]
        own_est.append(_estimates(o["theta8"], idx, s, o["solution"], bounds, fixed_names))
    cons = consistency_test(own, joint, labels, own_est, joint_est, leave_one_out)
    notes = []
    if not all(o["solution"]["converged"] for o in own):
        bad = [lab for lab, o in zip(labels, own) if not o["solution"]["converged"]]
        notes.append(f"own fit did not converge: {', '.join(bad)} (its share of the statistic is not reliable)")
    on_b = [k for k, e in joint_est.items() if e.at_bound and not e.fixed]
    if on_b:
        notes.append(
            f"on a bound in the joint fit: {', '.join(on_b)}; the chi-square reference of the test is approximate "
            "there (a bound-pinned parameter does not count as a full degree of freedom)"
        )
    for lab, e in zip(labels, own):
        if e["official"].outcome != "usable":
            notes.append(f"{lab}'s own fit is {e['official'].outcome}: {e['official'].fit_outcome.reason}")
    names = [SHARED[k] for k in range(N_SHARED) if shared_free[k]]
    names += [f"{NAMES8[k]}[{labels[d]}]" for d in range(len(specs)) for k, _ in spec_cols[d]]
    return JointFitResult(
        labels=tuple(labels),
        parameters=joint_est,
        specific=specific,
        datasets=tuple(_own_entry(lab, s, g, o, e) for lab, s, g, o, e in zip(labels, specs, gears, own, own_est)),
        consistency=cons,
        converged=bool(joint["converged"] and joint["finite"]),
        status=joint["status"],
        rank=int(joint["rank"]),
        n_rows=int(joint["n_rows"]),
        noise_sd=tuple(joint["noise_sd"]),
        solve_time_s=solve_time_s,
        starts=int(joint["starts"]),
        starts_converged=int(joint["starts_converged"]),
        notes=tuple(notes),
        theta=np.asarray(joint["theta"], dtype=float),
        covariance_si=np.asarray(joint["cov"], dtype=float),
        free_names=tuple(names),
    )
