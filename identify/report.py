"""A fit result in words and in JSON: the report, warnings, the CLI JSON object.

A mixin of :class:`~soiltrack.identify.result.FitResult`. JSON (``to_json``) never carries NaN
or Infinity: unavailable numbers are ``null`` and the reason is in the ``note`` / ``warnings``
text. For drive logs ``rmse_N`` is ``null`` and ``rmse`` / ``residual_unit`` carry the residual
size in its own unit.
"""
from __future__ import annotations

import json
from functools import cached_property

import numpy as np

from ..soilmodel.soil import PARAMETER_NAMES, Soil, SoilBounds
from ..soilmodel.vehicle import Vehicle
from .estimate_types import _EDGE, ParameterEstimate, _f

__all__ = ["ReportViews"]


class ReportViews:
    """Report, warnings and JSON of a fit result (mixin)."""

    @cached_property
    def warnings(self) -> tuple[str, ...]:
        """Warnings in plain words (input warnings first)."""
        w = list(self.input_warnings)
        if not self.success:
            w.append(f"the fit did not succeed ({self.status}): {self.message}")
        for name, d in self.outside_bounds.items():
            j = PARAMETER_NAMES.index(name)
            f, u = _EDGE[name][2], _EDGE[name][1]
            w.append(f"{_EDGE[name][3]} = {self.theta[j] * f:.5g} {u} lies {d} its bounds "
                     f"[{self.bounds.lower[j] * f:.5g}, {self.bounds.upper[j] * f:.5g}] {u}: the {self.method} "
                     "method is unconstrained")
        for name, pe in self.parameters.items():
            if pe.at_bound and name == "cohesion" and pe.bound_side == "lower" and self.bounds.cohesion[0] == 0:
                w.append("cohesion c ended on its lower bound 0 kPa: the data show no cohesion (consistent with a "
                         "cohesionless soil; the cohesion-free model may be the better description)")
            elif pe.at_bound:
                w.append(f"{_EDGE[name][3]} ended on its {pe.bound_side} bound "
                         f"({pe.edge_value if pe.value is not None else (pe.ridge_value or 0) * _EDGE[name][2]:.6g} "
                         f"{pe.edge_unit}): a warning about the data or the bounds")
        for s in self.identifiability["statements"]:
            if not s.startswith("all free"):
                w.append(s)
        for name, ps in self.effects.items():
            for pname, pe in ps.items():
                if pe.at_bound:
                    w.append(f"effect parameter {name}.{pname} ended on its {pe.bound_side} bound "
                             f"({pe.value:.6g} {pe.si_unit}): a warning about the data or the range")
        if self.dof <= 0 and not self.sigma_known:
            w.append("no residual degrees of freedom (as many identifiable directions as samples): no standard "
                     "errors, and an exact fit says nothing about the noise")
        return tuple(w)


    # ---------------------------------------------------------------------------- output
    def to_dict(self) -> dict:
        """The CLI JSON object (edge units, never NaN; see the module docs)."""
        rmse = _f(self.rmse)
        d = {
            "model": self.model, "method": self.method, "status": self.status, "success": bool(self.success),
            "n_samples": int(self.n_samples),
            "rmse_N": rmse if self.residual_unit == "N" else None,
            "solve_time_s": _f(self.solve_time),
            "parameters": {_EDGE[n][0]: self._parameter_json(pe) for n, pe in self.parameters.items()},
            "combinations": [cb.to_dict() for cb in self.combinations],
            "data_kind": self.data_kind, "rmse": rmse, "residual_unit": self.residual_unit,
            "cost": _f(self.cost), "iterations": int(self.iterations), "message": self.message,
            "dof": int(self.dof), "sigma_known": bool(self.sigma_known),
            "normal_loads_N": [float(w) for w in self.normal_loads],
            "identifiability": self.identifiability, "warnings": list(self.warnings),
            "active_bounds": self.active_bounds,
            "measured": self.measured,
            "parameter_names": list(self.parameter_names),
            "effects": {n: {k: pe.to_dict() for k, pe in ps.items()} for n, ps in self.effects.items()},
            "covariance": self._covariance_json(),
        }
        if self.extra:
            d["extra"] = json.loads(json.dumps(self.extra, default=_json_default, allow_nan=True),
                                    parse_constant=lambda _: None)
        return d

    def _covariance_json(self) -> dict:
        """``{"parameters", "matrix", "units"}``: the covariance over :attr:`parameter_names` in SI,
        ``matrix`` null when unavailable (rank deficient, no dof, failed fit), entries never NaN."""
        C = self.covariance if self.success else None
        return {"parameters": list(self.parameter_names),
                "matrix": None if C is None else [[_f(x) for x in row] for row in C], "units": "SI"}

    def _parameter_json(self, pe: ParameterEstimate) -> dict:
        """A parameter's JSON entry. The CLI contract wants a number in ``value``: for a successful fit
        whose parameter is not identifiable (c, phi at one load), that number is the centre of the
        feasible ridge, flagged ``identifiable: false`` and ``value_is_ridge_point: true``, with
        ``ci95`` the range the ridge allows - a marker, not an estimate. A failed fit keeps ``null``."""
        d = pe.to_dict()
        on_ridge = (self.success and d["value"] is None and not pe.identifiable and not pe.fixed
                    and d["ridge_value"] is not None)
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
            L.append(f"drive log: {x.get('formulation', '?')} formulation, {x.get('samples_used', '?')} of "
                     f"{x.get('samples_total', '?')} samples used, regime {x.get('regime', '?')}"
                     + (f" - {x['note']}" if x.get("note") else ""))
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
                L.append(f"bias correction: {bc.get('method', '?').upper()} applied ({bc.get('replicates', '?')} "
                         f"replicates; {', '.join(parts)}); intervals include its Monte Carlo variance")
            else:
                L.append(f"bias correction: {bc.get('method', '?').upper()} NOT applied"
                         + (f" - {bc['reason']}" if bc.get("reason") else ""))
        return L

    def report(self) -> str:
        """A human-readable multi-line report (kPa, deg, m, kN)."""
        L: list[str] = []
        loads = ", ".join(f"{w / 1e3:.6g} kN" for w in self.normal_loads)
        L.append(f"soiltrack identification - model {self.model}, method {self.method}")
        what = f" ({self.measured.replace('_', ' ')})" if self.measured else ""
        L.append(f"data: {self.data_kind}{what}, {self.n_samples} samples, normal load(s): {loads}")
        L.append(f"vehicle: {self.vehicle.name or 'unnamed'} (l = {self.vehicle.track_length:.4g} m, "
                 f"b = {self.vehicle.track_width:.4g} m, A = {self.vehicle.contact_area:.4g} m^2)")
        L.append(f"status: {self.status} ({'success' if self.success else 'FAILED'}), {self.iterations} iterations, "
                 f"{self.solve_time * 1e3:.3g} ms")
        unit = self.residual_unit
        if unit == "N":
            L.append(f"fit: RMSE {self.rmse / 1e3:.4g} kN, cost {self.cost:.6g}, residual dof {self.dof}")
        else:
            L.append(f"fit: RMSE {self.rmse:.4g} {unit}, cost {self.cost:.6g}, residual dof {self.dof}")
        q = self.quantile
        if self.sigma_known:
            L.append("noise: sigma given; 95 % intervals use the normal quantile 1.96")
        elif q is not None:
            L.append(f"noise: sigma estimated from the residuals; 95 % intervals use Student t ({self.dof} dof, "
                     f"quantile {q:.4g})")
        else:
            L.append("noise: unknown and no residual degrees of freedom -> no standard errors")
        L.extend(self._drive_log_lines())
        L.append("parameters (95 % intervals):")
        for name, pe in self.parameters.items():
            lab = f"  {_EDGE[name][3]:<20}"
            u = pe.edge_unit
            lo, hi = pe.edge_ci95
            rng = f"[{lo:.4g}, {hi:.4g}] {u}" if lo is not None and hi is not None else "[unavailable]"
            if pe.fixed:
                L.append(f"{lab}0 {u} (fixed by the cohesion-free model)")
            elif pe.value is None and not self.success:
                L.append(f"{lab}no estimate (the fit failed)" + ("" if pe.identifiable else "; not identifiable"))
            elif not pe.identifiable:
                L.append(f"{lab}NOT IDENTIFIABLE; possible range {rng}")
            else:
                se = f" +- {pe.edge_stderr:.3g}" if pe.stderr is not None else " (no stderr)"
                flag = " [ON " + pe.bound_side.upper() + " BOUND]" if pe.at_bound else ""
                weak = " [weakly identifiable]" if pe.weakly_identifiable else ""
                L.append(f"{lab}{pe.edge_value:.5g}{se} {u}, 95 % {rng}{flag}{weak}")
        if self.effects:
            L.append("effect parameters (95 % intervals, SI):")
        for name, ps in self.effects.items():
            for pname, pe in ps.items():
                lab = f"  {name + '.' + pname:<20}"
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
                    se = f" +- {pe.stderr:.3g}" if pe.stderr is not None else " (no stderr)"
                    flag = " [ON " + pe.bound_side.upper() + " BOUND]" if pe.at_bound else ""
                    weak = (f" [weakly identifiable: correlation {pe.correlation:+.4f} with {pe.correlated_with}]"
                            if pe.weakly_identifiable and pe.correlated_with else
                            (" [weakly identifiable]" if pe.weakly_identifiable else ""))
                    L.append(f"{lab}{pe.value:.5g}{se} {u}, 95 % {rng}{flag}{weak}")
        L.append("identifiable combinations:" + ("" if self.combinations else " none (the fit failed)"))
        for cb in self.combinations:
            if cb.unit.startswith("N"):
                v, se, u = cb.value / 1e3, (None if cb.stderr is None else cb.stderr / 1e3), "k" + cb.unit
            else:
                v, se, u = cb.value, cb.stderr, cb.unit
            if not cb.estimable:
                L.append(f"  {cb.name:<26} not estimable from these data")
                continue
            s = f" +- {se:.3g}" if se is not None else " (no stderr)"
            L.append(f"  {cb.name:<26} {v:.5g}{s} {u}{' [weak]' if cb.weakly_identifiable else ''}  ({cb.description})")
        ident = self.identifiability
        L.append(f"identifiability: rank {ident['rank']} of {ident['n_parameters']}; scaled singular values "
                 + ", ".join(f"{s:.3g}" for s in ident["scaled_singular_values"]))
        for d in ident["null_space"]:
            L.append("  null direction: " + ", ".join(f"{k} {v:+.3g}" for k, v in d.items())
                     + " (unit vector in kPa / deg / m: moving along it leaves the fit unchanged)")
        for s in ident["statements"]:
            L.append("  - " + s)
        if self.ridge_point is not None and self.soil is None:
            rp = self.ridge_point
            what = "optimiser's ridge point" if self.success else "last iterate of the failed fit"
            L.append(f"  ({what}, NOT an estimate: c = {rp.cohesion_kpa:.4g} kPa, "
                     f"phi = {rp.friction_angle_deg:.4g} deg, K = {rp.shear_modulus:.4g} m)")
        if self.n_samples <= 20:
            sc, u = (1e-3, "kN") if unit == "N" else (1.0, unit)
            L.append(f"residuals (model - data, {u}): " + ", ".join(f"{r * sc:+.4g}" for r in self.residuals))
        if self.warnings:
            L.append("warnings:")
            for w in self.warnings:
                L.append("  ! " + w)
        return "\n".join(L)

    def __str__(self) -> str:  # pragma: no cover - convenience
        return self.report()



def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, (Soil, Vehicle, SoilBounds)):
        return str(o)
    return repr(o)
