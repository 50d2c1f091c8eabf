"""A fit result in words and in JSON: the report, warnings, the CLI JSON object.

A mixin of :class:`~soiltrack.identify.estimates.result.FitResult`. JSON (``to_json``) never carries NaN
or Infinity: unavailable numbers are ``null`` and the reason is in the ``note`` / ``warnings``
text. For drive logs ``rmse_N`` is ``null`` and ``rmse`` / ``residual_unit`` carry the residual
size in its own unit.
"""

from __future__ import annotations

import json
from functools import cached_property

import numpy as np

from ..jitcache import fallback_note
from ...soilmodel.ridge import MAX_LOAD_LEVELS, load_summary_points
from ...soilmodel.soil import PARAMETER_NAMES, PRACTICAL_BOUNDS, Soil, SoilBounds
from ...soilmodel.units import choose_scale, format_force
from ...soilmodel.vehicle import Vehicle
from ..outcome import (
    OUTCOMES,
    LackOfFitTest,
    Outcome,
    decide_outcome,
    identified,
    outcome_lines,
    running_gear_json,
    stated_noise_test,
)
from .record_fields import RecordFields
from .records import (
    EDGE_UNITS,
    NOT_USABLE,
    LoadSeparation,
    ParameterEstimate,
    combination_determined,
    finite_or_none,
    solver_converged,
)

__all__ = ["ReportViews", "OUTCOMES", "RESIDUAL_SIGN"]

#: The prefix of a plausibility check's refusal among the warnings.
_REFUSAL = "NOT USABLE: "
#: The sign of every residual a fit shows (report, JSON ``residuals``, figures), as in the diagnosis.
RESIDUAL_SIGN = "measured - model"


class ReportViews(RecordFields):
    """Report, warnings and JSON of a fit result (mixin)."""

    @property
    def outcome(self) -> str:
        """One of :data:`~soiltrack.identify.outcome.OUTCOMES` (the rules of :mod:`soiltrack.identify.outcome`)."""
        return self.fit_outcome.outcome

    @property
    def outcome_reason(self) -> str | None:
        """Why the outcome is not ``usable`` (a sentence), None when it is."""
        return self.fit_outcome.reason

    def identified_parameter(self, name: str) -> tuple[bool, str]:
        """Whether soil parameter ``name`` is identified by the outcome rules, and why not
        (:func:`~soiltrack.identify.outcome.identified`: not on a bound, interval narrower than most
        of the bound range)."""
        pe = self.parameters[name]
        if pe.fixed or pe.value is None:
            return False, "held fixed" if pe.fixed else "no estimate"
        j = PARAMETER_NAMES.index(name)
        return identified(
            identifiable=pe.identifiable,
            at_bound=pe.at_bound,
            ci95=pe.ci95,
            lower=float(self.bounds.lower[j]),
            upper=float(self.bounds.upper[j]),
        )

    @cached_property
    def determined(self) -> tuple[str, ...]:
        """What the data determine: identified soil parameters and estimable combinations with an interval."""
        out = [n for n in self.parameters if self.identified_parameter(n)[0]]
        if self._slope_only:  # a gentle drive log: K is not separated from F_max
            out = [n for n in out if n != "shear_modulus"]
        out += [cb.name for cb in self.combinations if cb.name not in self.undetermined_combinations]
        return tuple(out)

    @property
    def _slope_only(self) -> bool:
        """A gentle drive log: only the initial slope F_max l / (2 K) is determined, not F_max or K
        (:mod:`soiltrack.identify.drivelog.regime`)."""
        return self.data_kind == "drive" and isinstance(self.extra, dict) and self.extra.get("regime") == "gentle"

    @cached_property
    def undetermined_combinations(self) -> dict[str, str]:
        """``{combination name: why the data do not determine it}`` (never listed as determined)."""
        out: dict[str, str] = {}
        k_ok = self.identified_parameter("shear_modulus")[0] and not self._slope_only
        for cb in self.combinations:
            if not _combination_determined(cb):
                out[cb.name] = "not estimable or pinned at a bound"
            elif self._slope_only and (cb.name.startswith("F_max") or cb.name in _SCALED_K):
                out[cb.name] = self.extra.get("regime_reason") or (
                    "gentle driving: the log shows only the initial slope F_max l / (2 K)"
                )
            elif cb.name in _SCALED_K and not k_ok:
                out[cb.name] = "K itself is not identified"
        return out

    def _determined_labels(self) -> list[str]:
        """:attr:`determined` in the report's words (parameters by name, combinations as labelled)."""
        return [
            EDGE_UNITS[d][3] if d in EDGE_UNITS else _combo_label(d)
            for d in self.determined
            if not (d == "K" and "shear_modulus" in self.determined)  # K is said once
        ]

    @cached_property
    def fit_outcome(self) -> Outcome:
        """The fit's :class:`~soiltrack.identify.outcome.Outcome` (one rule for every kind of fit)."""
        solver_ok = solver_converged(self)
        refusals: list[str] = []
        if solver_ok and not self.success:
            refusals = [w[len(_REFUSAL) :] for w in self.warnings if w.startswith(_REFUSAL)] or [self.message]
        x = self.extra if isinstance(self.extra, dict) else {}
        lof = x.get("lack_of_fit")
        test: LackOfFitTest | None = None
        ratio = None
        if self.sigma_known and self.data_kind == "slip" and self.dof > 0:  # against the stated noise
            ssr = float(np.sum(np.asarray(self.weighted_residuals, dtype=np.float64) ** 2))
            test = stated_noise_test(ssr, self.dof)
            ratio = float(np.sqrt(ssr / self.dof))
        if isinstance(lof, dict) and lof.get("p_value") is not None:  # the repeats' pure error first
            test = LackOfFitTest(
                "the pure error of the repeats", float(lof["F"]), (lof["df_lack"], lof["df_pure"]), lof["p_value"]
            )
        return decide_outcome(
            solver_ok=solver_ok,
            failure=f"{self.solver_status}: {self.message}",
            refusals=refusals,
            determined=self.determined if self.success else (),
            lack_of_fit=test,
            noise_ratio=ratio,
        )

    @property
    def running_gear(self) -> dict:
        """The JSON ``running_gear`` of a tracked vehicle (``weight_N`` null when the loads are per row)."""
        v = self.vehicle
        loads = np.asarray(self.normal_loads, dtype=np.float64)
        own = loads.size == 0 or bool(np.allclose(loads, v.weight, rtol=1e-6))
        return running_gear_json(
            "track",
            name=v.name or None,
            weight_N=v.weight if own else None,
            contact_area_m2=v.contact_area,
            track_length_m=v.track_length,
        )

    @property
    def solver_status(self) -> str:
        """The solver's own status word: IPOPT's as it said it (``extra["solver_status"]``, kept when
        ``status`` is normalised to ``"converged"``), else ``status`` without the plausibility verdict."""
        own = self.extra.get("solver_status") if isinstance(self.extra, dict) else None
        if isinstance(own, str) and own:
            return own
        st = str(self.status)
        return st[: -len(NOT_USABLE)].rstrip() if st.endswith(NOT_USABLE) else st

    @property
    def residuals_measured_minus_model(self) -> np.ndarray:
        """The fit's residuals as every output shows them, :data:`RESIDUAL_SIGN` (``residual_unit``).

        ``residuals`` holds model - data (the solver's convention); this is its negative.
        """
        return -np.asarray(self.residuals, dtype=np.float64)

    @cached_property
    def warnings(self) -> tuple[str, ...]:
        """Warnings in plain words (input warnings first)."""
        w = list(self.input_warnings)
        if not solver_converged(self):  # "not usable" says why in its own warnings
            w.append(f"the fit failed (solver status {self.solver_status}): {self.message}")
        for name, d in self.outside_bounds.items():
            j = PARAMETER_NAMES.index(name)
            f, u = EDGE_UNITS[name][2], EDGE_UNITS[name][1]
            w.append(
                f"{EDGE_UNITS[name][3]} = {self.theta[j] * f:.5g} {u} lies {d} its bounds "
                f"[{self.bounds.lower[j] * f:.5g}, {self.bounds.upper[j] * f:.5g}] {u}: the {self.method} "
                "method is unconstrained"
            )
        for name, pe in self.parameters.items():
            if pe.at_bound and name == "cohesion" and pe.bound_side == "lower" and self.bounds.cohesion[0] == 0:
                w.append(
                    "cohesion c ended on its lower bound 0 kPa: the data show no cohesion (consistent with a "
                    "cohesionless soil; the cohesion-free model may be the better description)"
                )
            elif pe.at_bound:
                w.append(
                    f"{EDGE_UNITS[name][3]} ended on its {pe.bound_side} bound "
                    f"({pe.edge_value if pe.value is not None else (pe.ridge_value or 0) * EDGE_UNITS[name][2]:.6g} "
                    f"{pe.edge_unit}): a warning about the data or the bounds"
                )
        for s in self.identifiability["statements"]:
            if not s.startswith("all free"):
                w.append(s)
        for name, ps in self.effects.items():
            for pname, pe in ps.items():
                if pe.at_bound:
                    w.append(
                        f"effect parameter {name}.{pname} ended on its {pe.bound_side} bound "
                        f"({pe.value:.6g} {pe.si_unit}): a warning about the data or the range"
                    )
        sep = self.extra.get("load_separation") if isinstance(self.extra, dict) else None
        if isinstance(sep, dict) and sep.get("fragile") and self.success:
            w.append(LoadSeparation(**sep).statement(self))
        if self.dof <= 0 and not self.sigma_known:
            w.append(
                "no residual degrees of freedom (as many identifiable directions as samples): no standard "
                "errors, and an exact fit says nothing about the noise"
            )
        return tuple(w)

    # ---------------------------------------------------------------------------- output
    def to_dict(self) -> dict:
        """The CLI JSON object (edge units, never NaN; see the module docs)."""
        rmse = finite_or_none(self.rmse)
        # per combination: determined by the outcome rules (a gentle log's F_max, a K on a bound are not)
        und = (
            self.undetermined_combinations if self.success else {cb.name: "the fit failed" for cb in self.combinations}
        )
        d = {
            "model": self.model,
            "method": self.method,
            "status": self.status,
            "success": bool(self.success),
            **self.fit_outcome.to_dict(),
            "running_gear": self.running_gear,
            "n_samples": int(self.n_samples),
            "rmse_N": rmse if self.residual_unit == "N" else None,
            "solve_time_s": finite_or_none(self.solve_time),
            "parameters": {
                **{EDGE_UNITS[n][0]: self._parameter_json(pe) for n, pe in self.parameters.items()},
                **self.sinkage_parameters,
            },
            "combinations": [
                {**cb.to_dict(), "determined": cb.name not in und, "not_determined_reason": und.get(cb.name)}
                for cb in self.combinations
            ],
            "data_kind": self.data_kind,
            "rmse": rmse,
            "residual_unit": self.residual_unit,
            "cost": finite_or_none(self.cost),
            "iterations": int(self.iterations),
            "message": self.message,
            "dof": int(self.dof),
            "sigma_known": bool(self.sigma_known),
            "sigma_model": (
                self.extra.get("sigma_model")
                if self.data_kind == "slip" and isinstance(self.extra, dict)
                else "per-channel"
                if self.data_kind == "drive"
                else None
            ),
            "normal_loads_N": [float(w) for w in self.normal_loads],
            "identifiability": self.identifiability,
            "warnings": list(self.warnings),
            "active_bounds": self.active_bounds,
            "measured": self.measured,
            "parameter_names": list(self.parameter_names),
            "effects": {n: {k: pe.to_dict() for k, pe in ps.items()} for n, ps in self.effects.items()},
            "covariance": self._covariance_json(),
            "bounds": self._bounds_json(),
            "residuals": {
                "sign": RESIDUAL_SIGN,
                "unit": self.residual_unit,
                "values": [finite_or_none(x) for x in self.residuals_measured_minus_model],
            },
        }
        if self.extra:
            d["extra"] = json.loads(
                json.dumps(self.extra, default=json_default, allow_nan=True), parse_constant=lambda _: None
            )
        return d

    @property
    def sinkage_parameters(self) -> dict:
        """The sinkage laws' parameters fitted from a ``sinkage_m`` column, in the JSON's form and units:
        ``{"bekker_kc", "bekker_kphi", "bekker_n", "bekker_k_eq", "slip_sinkage_exponent"}``, each with
        ``value``, ``stderr``, ``ci95``, ``identifiable`` (:mod:`~soiltrack.identify.sweep.sinkage_channel`);
        empty without a sinkage column."""
        z = self.extra.get("sinkage_m") if isinstance(self.extra, dict) else None
        laws = z.get("laws") if isinstance(z, dict) else None
        params = laws.get("parameters") if isinstance(laws, dict) else None
        return dict(params) if isinstance(params, dict) else {}

    def _bounds_json(self) -> dict:
        """The soil bounds of the fit in edge units: ``{"cohesion_kpa": [lo, hi], ...}``."""
        return {
            EDGE_UNITS[n][0]: [
                finite_or_none(self.bounds.lower[j] * EDGE_UNITS[n][2]),
                finite_or_none(self.bounds.upper[j] * EDGE_UNITS[n][2]),
            ]
            for j, n in enumerate(PARAMETER_NAMES)
        }

    def _bounds_line(self) -> str | None:
        """A report line naming the bounds when they are not the practical range (else ``None``)."""
        if np.allclose(self.bounds.lower, PRACTICAL_BOUNDS.lower) and np.allclose(
            self.bounds.upper, PRACTICAL_BOUNDS.upper
        ):
            return None
        b = self._bounds_json()
        parts = [
            f"{EDGE_UNITS[n][3].split()[-1]} {b[EDGE_UNITS[n][0]][0]:.4g}-{b[EDGE_UNITS[n][0]][1]:.4g} "
            f"{EDGE_UNITS[n][1]}"
            for n in PARAMETER_NAMES
        ]
        return (
            "soil bounds: " + ", ".join(parts) + " (not the practical range c 0-69 kPa, phi 6-40 deg, K 0.006-0.05 m)"
        )

    def _covariance_json(self) -> dict:
        """``{"parameters", "matrix", "units"}``: the covariance over :attr:`parameter_names` in SI,
        ``matrix`` null when unavailable (rank deficient, no dof, failed fit), entries never NaN."""
        C = self.covariance if self.success else None
        return {
            "parameters": list(self.parameter_names),
            "matrix": None if C is None else [[finite_or_none(x) for x in row] for row in C],
            "units": "SI",
        }

    def _parameter_json(self, pe: ParameterEstimate) -> dict:
        """A parameter's JSON entry. The CLI contract wants a number in ``value``: for a successful fit
        whose parameter is not identifiable (c, phi at one load), that number is the centre of the
        feasible ridge, flagged ``identifiable: false`` and ``value_is_ridge_point: true``, with
        ``ci95`` the range the ridge allows - a marker, not an estimate. A failed fit keeps ``null``."""
        d = pe.to_dict()
        d["identified"] = bool(pe.name in self.determined)
        on_ridge = (
            self.success
            and d["value"] is None
            and not pe.identifiable
            and not pe.fixed
            and d["ridge_value"] is not None
        )
        if on_ridge:
            d["value"] = d["ridge_value"]
        d["value_is_ridge_point"] = bool(on_ridge)
        return d

    def to_json(self, indent: int | None = 2) -> str:
        """:meth:`to_dict` as JSON text (strict: no NaN/Infinity)."""
        return json.dumps(self.to_dict(), indent=indent, allow_nan=False)

    def _drive_log_lines(self) -> list[str]:
        """Report lines for drive-log fits: formulation, regime and any bias correction."""
        x = self.extra if isinstance(self.extra, dict) else {}
        L = []
        if "regime" in x or "formulation" in x:
            hold = {
                "zoh": "torque held between samples (zoh)",
                "sample": "torque sampled from a continuous signal",
            }.get(str(x.get("torque_hold")))
            L.append(
                f"drive log: {x.get('formulation', '?')} formulation, {x.get('samples_used', '?')} of "
                f"{x.get('samples_total', '?')} samples used, regime {x.get('regime', '?')}"
                + (f", {hold}" if hold else "")
                + (f" - {x['note']}" if x.get("note") else "")
            )
            alt = x.get("torque_hold_alternative")
            if isinstance(alt, dict):
                L.append(
                    f"torque hold not given: fitted again with torque_hold='{alt.get('torque_hold')}' ("
                    + (
                        "its intervals are covered by the ones below"
                        if alt.get("success")
                        else f"that fit did not succeed: {alt.get('status')}; intervals from this one only"
                    )
                    + ")"
                )
        bc = x.get("bias_correction")
        if isinstance(bc, dict):
            if bc.get("applied"):
                unc, cor = bc.get("uncorrected", {}), bc.get("correction", {})
                K0, dK = unc.get("shear_modulus_m"), cor.get("shear_modulus_m")
                F0, dF = unc.get("max_thrust_N"), cor.get("max_thrust_N")
                parts = []
                if F0 and dF is not None:
                    parts.append(f"F_max {F0:.5g} N {dF:+.3g} N")
                if K0 and dK is not None:
                    parts.append(f"K {K0:.5g} m {dK:+.3g} m")
                L.append(
                    f"bias correction: {bc.get('method', '?').upper()} applied ({bc.get('replicates', '?')} "
                    f"replicates; {', '.join(parts)}); intervals include its Monte Carlo variance"
                )
            else:
                L.append(
                    f"bias correction: {bc.get('method', '?').upper()} NOT applied"
                    + (f" - {bc['reason']}" if bc.get("reason") else "")
                )
        return L

    def _rig_lines(self) -> list[str]:
        """Report lines of a rig sweep: rows dropped, weights, sinkage, resistance, lack of fit, c-phi separation."""
        x = self.extra if isinstance(self.extra, dict) else {}
        L = []
        for d in x.get("dropped_rows", ()):
            L.append(f"rows dropped ({d['option']}): {d['count']} {d['reason']}")
        if x.get("weights_from"):
            L.append(
                f"weights: 1 / std^2 from the column {x['weights_from']} (relative weights: their level is "
                "estimated from the residuals)"
            )
        z = x.get("sinkage_m")
        if isinstance(z, dict):
            used = (x.get("resistance") or {}).get("mode") == "fit-sinkage"
            L.append(
                f"sinkage: measured per row, {1e3 * z['min']:.3g} to {1e3 * z['max']:.3g} mm (correlation with "
                f"the slip {z['slip_correlation']:+.2f}); "
                + (
                    "used by the resistance R = k_z z W"
                    if used
                    else "not in the track model's resistance (--resistance fit-sinkage uses it)"
                )
            )
            laws = z.get("laws")
            if isinstance(laws, dict):
                L.append("sinkage laws: " + laws["statement"])
                eff = laws.get("slip_sinkage_effect")
                if isinstance(eff, dict):
                    L.append(eff["statement"])
        res = x.get("resistance")
        if isinstance(res, dict):
            L.append("resistance: " + res["statement"])
        lof = x.get("lack_of_fit")
        if isinstance(lof, dict):
            L.append("lack of fit: " + lof["statement"])
        return L

    def _interval_tag(self, label: str) -> str:
        """`` (profile)`` or `` (both holds)`` when that parameter's interval replaced the linearised one."""
        pi = (self.replaced_intervals or {}).get(label)
        return "" if pi is None else (" (profile)" if pi.kind == "profile" else " (both holds)")

    def _noise_line(self) -> str:
        """What noise model the intervals rest on, in plain words (said once)."""
        x = self.extra if isinstance(self.extra, dict) else {}
        kind = x.get("sigma_model") if self.data_kind == "slip" else None
        q = self.quantile
        t = (
            f"95 % intervals use Student t ({self.dof} residual degrees of freedom, quantile {q:.4g})"
            if q is not None and not self.sigma_known
            else "95 % intervals use the normal quantile 1.96"
        )
        sn = x.get("slip_noise") if self.data_kind == "slip" else None
        if self.data_kind == "drive":
            head = "noise: per-channel levels " + ("given" if self.sigma_known else "estimated from the log")
        elif isinstance(sn, dict) and sn.get("adopted"):
            how = "estimated from the residuals" if sn.get("mode") == "auto" else "slip noise given"
            head = (
                f"noise: on the force and on the slip, weights 1 / (sigma_F^2 + (dF/di)^2 sigma_i^2) (effective "
                f"variance; {how}: sigma_i = {sn['slip_sigma']:.3g}, sigma_F = "
                f"{format_force(sn['force_sigma_N'])})"
            )
        elif kind == "relative":
            head = (
                "noise: proportional to the force (sigma='relative': weights 1/|F|, floored at 1 % of the "
                "largest force); its level estimated from the residuals"
            )
            if self.s2 is not None:
                head += f" at about {100 * self.s2**0.5:.3g} % of the force"
        elif kind == "given" or (kind is None and self.sigma_known):
            head = (
                "noise: sigma given per sample and taken as known"
                if self.sigma_known
                else "noise: sigma given as relative weights; level estimated from the residuals"
            )
        else:
            head = "noise: equal weights; level estimated from the residuals"
            if self.s2 is not None and self.residual_unit == "N":
                head += f" (s = {format_force(self.s2**0.5)})"
        if q is None and not self.sigma_known:
            return head + "; no residual degrees of freedom -> no standard errors"
        return f"{head}; {t}"

    def _soil_parameter_lines(self) -> list[str]:
        """The report's soil parameters: value, SE, 95 % interval and flags, or why there is no number."""
        L: list[str] = []
        L.append("parameters (95 % intervals):")
        notes = []
        for name, pe in self.parameters.items():
            lab = f"  {EDGE_UNITS[name][3]:<20}"
            u = pe.edge_unit
            lo, hi = pe.edge_ci95
            rng = f"[{lo:.4g}, {hi:.4g}] {u}" if lo is not None and hi is not None else "[unavailable]"
            if pe.fixed:
                L.append(f"{lab}0 {u} (fixed by the cohesion-free model)")
            elif pe.value is None and not self.success:
                L.append(f"{lab}no estimate (the fit failed)" + ("" if pe.identifiable else "; not identifiable"))
            elif not pe.identifiable and any(n.startswith("F_max") for n in self.undetermined_combinations):
                L.append(f"{lab}NOT IDENTIFIABLE (nor is F_max, which would bound it: no range)")
            elif not pe.identifiable:
                L.append(f"{lab}NOT IDENTIFIABLE; possible range {rng}")
            else:
                se = f" (SE {pe.edge_stderr:.3g} {u})" if pe.stderr is not None else " (no SE)"
                flag = " [ON " + (pe.bound_side or "").upper() + " BOUND]" if pe.at_bound else ""
                weak = " [weakly identifiable]" if pe.weakly_identifiable else ""
                cut = " [cut at a bound, see below]" if "is cut at the bound" in (pe.note or "") else ""
                ok, why_not = self.identified_parameter(name)
                tag = "" if ok or pe.at_bound else f" [NOT IDENTIFIED: {why_not}]"
                L.append(
                    f"{lab}{pe.edge_value:.5g} {u}{se}, 95 % {rng}{self._interval_tag(name)}{flag}{weak}{cut}{tag}"
                )
                if cut:
                    notes.append(
                        f"  {EDGE_UNITS[name][3]}: "
                        + "; ".join(n for n in pe.note.split("; ") if "is cut at the bound" in n)
                    )
        L.extend(notes)
        return L

    def _combination_lines(self, continuous: bool) -> list[str]:
        """What the data determine (with numbers) and, apart, what they do not (without)."""
        L: list[str] = []
        k_shown = self.parameters["shear_modulus"].identifiable and self.success
        combos = [cb for cb in self.combinations if not (cb.name == "K" and k_shown)]  # K is said above
        L.append("what the data determine (95 % intervals):" + ("" if combos else " nothing (the fit failed)"))
        shown = {f"{w:.6g}" for w in load_summary_points(self.normal_loads)} if continuous else None
        per_load = [cb for cb in combos if "@W=" in cb.name]
        if shown is not None and per_load:  # a measured load: the combinations at its median and extremes
            combos = [cb for cb in combos if "@W=" not in cb.name or _combo_load(cb.name) in shown]
        undetermined = [cb for cb in combos if cb.name in self.undetermined_combinations]
        combos = [cb for cb in combos if cb.name not in self.undetermined_combinations]
        for cb in combos:
            label = _combo_label(cb.name)
            ends = [e for e in ("lower", "upper") if f"the {e} end of the 95 % interval is cut" in cb.note]
            cut = f" [{' and '.join(ends)} end cut at the bound]" if ends else ""
            L.append(
                f"  {label:<28} {_combo_value(cb)}{cut}{' [weak]' if cb.weakly_identifiable else ''}  "
                f"({cb.description})"
            )
        if shown is not None and per_load:
            L.append(
                f"  (at the lowest, the median and the highest of the {len(self.normal_loads)} measured loads; "
                "every load's values are in --json under combinations)"
            )
        if undetermined:
            L.append("NOT determined by these data (no number is an estimate):")
            for cb in undetermined:
                L.append(f"  {_combo_label(cb.name):<28} {self.undetermined_combinations[cb.name]}")
        return L

    def report(self) -> str:
        """A human-readable multi-line report (units by magnitude: N or kN, kPa, deg, m)."""
        L: list[str] = []
        continuous = len(self.normal_loads) > MAX_LOAD_LEVELS
        if continuous:
            lo, med, hi = load_summary_points(self.normal_loads)
            loads = (
                f"measured per row, {len(self.normal_loads)} values from {format_force(lo)} to "
                f"{format_force(hi)} (median {format_force(med)})"
            )
        else:
            loads = ", ".join(format_force(w) for w in self.normal_loads)
        nid = [EDGE_UNITS[n][3] for n, pe in self.parameters.items() if not pe.fixed and n not in self.determined]
        L.extend(outcome_lines(self.fit_outcome, determined=self._determined_labels(), not_identified=nid))
        L.append(f"soiltrack identification - model {self.model}, method {self.method}")
        what = f" ({self.measured.replace('_', ' ')})" if self.measured else ""
        L.append(f"data: {self.data_kind}{what}, {self.n_samples} samples, normal load(s) W: {loads}")
        L.extend(self._rig_lines())
        L.append(
            f"vehicle: {self.vehicle.name or 'unnamed'} (l = {self.vehicle.track_length:.4g} m, "
            f"b = {self.vehicle.track_width:.4g} m, A = {self.vehicle.contact_area:.4g} m^2)"
        )
        if (bl := self._bounds_line()) is not None:
            L.append(bl)
        word = "converged" if solver_converged(self) else "FAILED - no estimate (see the warnings)"
        L.append(
            f"status: {word} (solver status {self.solver_status}, {self.iterations} "
            f"iterations, {_duration(self.solve_time)})"
        )
        fallback = fallback_note(self.extra.get("engine_backend")) if isinstance(self.extra, dict) else None
        if fallback:  # said once on stderr too (soiltrack.identify.jitcache)
            L.append(f"engine: {fallback}")
        unit = self.residual_unit
        rmse = format_force(self.rmse) if unit == "N" else f"{self.rmse:.4g} {unit}"
        L.append(f"fit: RMSE {rmse}, cost {self.cost:.6g}, residual dof {self.dof}")
        L.append(self._noise_line())
        L.extend(self._drive_log_lines())
        L.extend(self._soil_parameter_lines())
        if self.effects:
            L.append("effect parameters (95 % intervals, SI):")
        for name, ps in self.effects.items():
            for pname, pe in ps.items():
                lab = f"  {name + '.' + pname:<20} "
                u = pe.si_unit
                lo, hi = pe.ci95
                rng = f"[{lo:.4g}, {hi:.4g}] {u}" if lo is not None and hi is not None else "[unavailable]"
                if pe.fixed:
                    L.append(f"{lab}{pe.value:.5g} {u} (held fixed, not estimated)")
                elif pe.value is None and not self.success:
                    L.append(f"{lab}no estimate (the fit failed)")
                elif not pe.identifiable:
                    w = f" from {pe.correlated_with}" if pe.correlated_with else ""
                    L.append(f"{lab}NOT IDENTIFIABLE (not separable{w}); range {rng}")
                else:
                    se = f" (SE {pe.stderr:.3g} {u})" if pe.stderr is not None else " (no SE)"
                    flag = " [ON " + (pe.bound_side or "").upper() + " BOUND]" if pe.at_bound else ""
                    weak = (
                        f" [weakly identifiable: correlation {pe.correlation:+.4f} with {pe.correlated_with}]"
                        if pe.weakly_identifiable and pe.correlated_with
                        else (" [weakly identifiable]" if pe.weakly_identifiable else "")
                    )
                    L.append(
                        f"{lab}{pe.value:.5g} {u}{se}, 95 % {rng}{self._interval_tag(name + '.' + pname)}{flag}{weak}"
                    )
        kinds = {v.kind for v in (self.replaced_intervals or {}).values()}
        if "profile" in kinds:
            L.append(
                "  (profile: the 95 % interval from the profile likelihood, this parameter held and all others "
                "refitted; SE is the linearised standard error, which assumes a quadratic cost)"
            )
        if "hold" in kinds:
            L.append(
                "  (both holds: the interval covers the fits with the torque held and sampled; the torque hold "
                "was not given)"
            )
        L.extend(self._combination_lines(continuous))
        ident = self.identifiability
        L.append(
            f"identifiability: the data determine {ident['rank']} independent direction(s) of the "
            f"{ident['n_parameters']} parameters; sensitivity of the fit along each, relative to the strongest "
            "(scaled singular values; about 1e-8 or less = not determined): "
            + ", ".join(f"{s:.3g}" for s in ident["scaled_singular_values"])
        )
        for d in ident["null_space"]:
            L.append(
                "  undetermined direction: "
                + ", ".join(f"{k} {v:+.3g}" for k, v in d.items())
                + " (moving the parameters along it, in kPa / deg / m, leaves the fitted curve unchanged)"
            )
        for st in ident["statements"]:
            L.append("  - " + st)
        if self.ridge_point is not None and self.soil is None:
            rp = self.ridge_point
            what = "optimiser's ridge point" if self.success else "last iterate of the failed fit"
            L.append(
                f"  ({what}, NOT an estimate: c = {rp.cohesion_kpa:.4g} kPa, "
                f"phi = {rp.friction_angle_deg:.4g} deg, K = {rp.shear_modulus:.4g} m)"
            )
        if self.n_samples <= 20:
            res = self.residuals_measured_minus_model
            sc = choose_scale(res, "N") if unit == "N" else None
            u = sc.unit if sc is not None else unit
            f = sc.factor if sc is not None else 1.0
            L.append(f"residuals ({RESIDUAL_SIGN}, {u}): " + ", ".join(f"{r * f:+.4g}" for r in res))
        said = set(ident["statements"])  # the identifiability statements are said once, above
        warns = [w for w in self.warnings if w not in said]
        if warns:
            L.append("warnings:")
            for w in warns:
                L.append("  ! " + w)
        return "\n".join(L)

    def __str__(self) -> str:  # pragma: no cover - convenience
        return self.report()


def _duration(seconds: float) -> str:
    """A solve time in plain digits: ``"98.6 ms"``, ``"9.42 s"``, ``"312 s"`` (never ``9.42e+03 ms``)."""
    if not np.isfinite(seconds):
        return "time unknown"
    if seconds < 1.0:
        return f"{seconds * 1e3:.3g} ms"
    return f"{seconds:.3g} s" if seconds < 100.0 else f"{seconds:.0f} s"


def _combo_load(name: str) -> str:
    """The load of a per-load combination's name as written there: ``"F_max@W=4905N"`` -> ``"4905"``."""
    return name.split("@W=")[1][:-1]


def _combo_label(name: str) -> str:
    """``"F_max@W=4905N"`` -> ``"F_max at W = 4.905 kN"`` (the JSON keeps the machine name)."""
    if "@W=" in name and name.endswith("N"):
        base, w = name.split("@W=")
        return f"{base} at W = {format_force(float(w[:-1]))}"
    return name


#: Combinations that are K itself or K scaled by a constant: determined exactly when K is identified.
_SCALED_K = ("K", "K/l")


def _combination_determined(cb) -> bool:
    """A combination the data determine (:func:`~.records.combination_determined`, the one rule)."""
    return combination_determined(cb)[0]


def _combo_value(cb) -> str:
    """Value, standard error and 95 % interval of a combination in units by magnitude."""
    if cb.unit in ("N", "N/slip"):
        scale = choose_scale([cb.value], cb.unit)
        f, u = scale.factor, scale.unit
    else:
        f, u = 1.0, ("" if cb.unit == "-" else cb.unit)
    sp = f" {u}" if u else ""
    se = f" (SE {cb.stderr * f:.3g}{sp})" if cb.stderr is not None else " (no SE)"
    lo, hi = cb.ci95
    ci = f", 95 % [{lo * f:.4g}, {hi * f:.4g}]{sp}" if lo is not None and hi is not None else ""
    return f"{cb.value * f:.5g}{sp}{se}{ci}"


def json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, (Soil, Vehicle, SoilBounds)):
        return str(o)
    return repr(o)
