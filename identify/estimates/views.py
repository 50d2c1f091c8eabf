"""Estimates of a fit: per parameter (soil and effects), identifiable combinations, bounds, the soil.

A mixin of :class:`~soiltrack.identify.estimates.result.FitResult`.

* Parameters on a bound: the linearised standard error ignores the bound (it is the local
  curvature of the cost); the 95 % interval is clipped to the bounds and a note says so.
  :func:`~soiltrack.identify.profile_likelihood` gives the honest interval there.
* c and phi not separable (full model, one normal load): both are marked not identifiable,
  their ``value`` is ``None`` and their ``ci95`` is the range they take along the
  bounds-feasible ridge for ``F_max`` within its 95 % interval. ``soil`` is then ``None``; the
  optimiser's arbitrary ridge point is ``ridge_point`` (a :class:`Soil` whose name says it is
  not an estimate).
* A failed fit carries no estimate: values, standard errors and intervals are ``None``,
  ``combinations`` is empty and ``soil`` is ``None``; the last iterate stays visible as
  ``ridge_value`` / ``ridge_point``, labelled as such. Estimates of the unconstrained seed
  methods that fall outside the bounds are reported as ``outside_bounds`` (not clipped).
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np

from ...soilmodel.soil import PARAMETER_NAMES, Soil
from .least_squares import WEAK_VIF
from ...soilmodel.units import format_value
from .record_fields import RecordFields
from .records import EDGE_UNITS, Combination, ParameterEstimate
from .identifiability import BOUND_TOL
from ...soilmodel.ridge import soil_fmax_range as fmax_range


def _cut_note(lo: float, hi: float, b_lo: float, b_hi: float, factor: float, unit: str) -> list[str]:
    """Plain words for a 95 % interval ``[lo, hi]`` cut at the bounds ``[b_lo, b_hi]`` (edge units via factor)."""
    out = []
    unit = "" if unit in ("-", "") else " " + unit
    if lo < b_lo:
        out.append(
            f"the lower end of the 95 % interval is cut at the bound {b_lo * factor:.4g}{unit} (the "
            f"symmetric interval would reach {lo * factor:.4g}{unit})"
        )
    if hi > b_hi:
        out.append(
            f"the upper end of the 95 % interval is cut at the bound {b_hi * factor:.4g}{unit} (the "
            f"symmetric interval would reach {hi * factor:.4g}{unit})"
        )
    return out


__all__ = ["EstimateViews"]


def _profile_note(pi, factor: float, unit: str) -> str:
    """Plain words for a profile-likelihood (or hold-widened) interval that replaced the linearised one."""
    if pi.kind != "profile":
        return pi.note
    unit = "" if unit in ("-", "") else " " + unit
    a, b = pi.linear
    lin = (
        f"; the linearised interval [{a * factor:.4g}, {b * factor:.4g}]{unit} assumes a quadratic cost"
        if a is not None and b is not None
        else ""
    )
    s = (
        "95 % interval from the profile likelihood (this parameter held, all others refitted, up to the "
        f"likelihood-ratio threshold){lin}"
    )
    if pi.open_lower or pi.open_upper:
        side = "either side" if (pi.open_lower and pi.open_upper) else ("below" if pi.open_lower else "above")
        s += f"; the data do not bound it {side}: the interval reaches the physical bound there"
    if pi.note:
        s += "; " + pi.note
    return s


class EstimateViews(RecordFields):
    """Estimate views of a fit result (mixin)."""

    # ---------------------------------------------------------------------------- bounds
    @cached_property
    def _bound_flags(self) -> list[str | None]:
        lo, hi = self.bounds.lower, self.bounds.upper
        out: list[str | None] = []
        for j in range(3):
            if j not in self.free:
                out.append(None)
                continue
            tol = BOUND_TOL * (hi[j] - lo[j])
            if self.theta[j] < lo[j] - tol:
                out.append("below")
            elif self.theta[j] > hi[j] + tol:
                out.append("above")
            elif self.theta[j] <= lo[j] + tol:
                out.append("lower")
            elif self.theta[j] >= hi[j] - tol:
                out.append("upper")
            else:
                out.append(None)
        return out

    @property
    def active_bounds(self) -> dict[str, str]:
        """``{parameter name: "lower"|"upper"}`` for free parameters that ended on a bound (effect
        parameters as ``"effect.param"``)."""
        out = {n: p.bound_side for n, p in self.parameters.items() if p.at_bound and p.bound_side}
        for ps in self.effects.values():
            out.update({p.name: p.bound_side for p in ps.values() if p.at_bound and p.bound_side})
        return out

    @property
    def outside_bounds(self) -> dict[str, str]:
        """``{parameter name: "below"|"above"}`` for estimates outside the bounds (unconstrained methods)."""
        return {PARAMETER_NAMES[j]: s for j, s in enumerate(self._bound_flags) if s in ("below", "above")}

    # ---------------------------------------------------------------------------- views
    @cached_property
    def combinations(self) -> list[Combination]:
        """Identifiable combinations: ``F_max`` at each distinct load, ``K``, ``K/l``, initial slope.

        Empty when the fit failed (no estimate of anything).
        """
        if not self.success:
            return []
        K = float(self.theta[2])
        l = self.vehicle.track_length
        q = self.quantile
        idx = np.array(self.free)
        out: list[Combination] = []

        def add(name, value, g3, unit, desc, rng=None):
            """``rng``: the range the bounds allow; the interval is cut there, and the note says so."""
            se, est, weak = self._combo_stderr(self._full(g3)[idx])
            ci = (value - q * se, value + q * se) if (se is not None and q is not None) else (None, None)
            note = ""
            if rng is not None and ci[0] is not None and ci[1] is not None:  # both set together
                note = "; ".join(_cut_note(ci[0], ci[1], rng[0], rng[1], 1.0, unit))
                ci = (max(ci[0], rng[0]), min(ci[1], rng[1]))
            out.append(Combination(name, float(value), se, ci, unit, desc, est, weak, note))

        cf = self.model == "cohesion-free"
        actual = ""
        for W in self.normal_loads:
            W = float(W)
            fm, gF = self._fmax(W)
            if self.effect_labels:
                N_W = format_value(self._effective_load(W)[0], "N", 6)
                actual = f" (actual normal load N = {N_W} with the fitted effects)"
            add(
                f"F_max@W={W:.6g}N",
                fm,
                gF,
                "N",
                f"soil thrust limit {'N tan(phi)' if cf else 'A c + N tan(phi)'} at W = "
                f"{format_value(W, 'N', 6)}{actual}"
                if self.effect_labels
                else f"soil thrust limit {'W tan(phi)' if cf else 'A c + W tan(phi)'} at W = {format_value(W, 'N', 6)}",
                rng=fmax_range(
                    self.bounds, self.vehicle, self.model, self._effective_load(W)[0] if self.effect_labels else W
                ),
            )
        Kb = self.bounds.shear_modulus
        add("K", K, [0.0, 0.0, 1.0], "m", "shear deformation modulus K", rng=Kb)
        add(
            "K/l", K / l, [0.0, 0.0, 1.0 / l], "-", f"K over the track length l = {l:.6g} m", rng=(Kb[0] / l, Kb[1] / l)
        )
        for W in self.normal_loads:
            W = float(W)
            fm, gF = self._fmax(W)
            s0 = fm * l / (2.0 * K)
            g = gF * l / (2.0 * K) + self._full([0.0, 0.0, -fm * l / (2.0 * K * K)])
            srng = None
            if not self.effect_labels:
                f_lo, f_hi = fmax_range(self.bounds, self.vehicle, self.model, W)
                srng = (f_lo * l / (2.0 * Kb[1]), f_hi * l / (2.0 * Kb[0]))
            add(
                f"initial_slope@W={W:.6g}N",
                s0,
                g,
                "N/slip",
                f"small-slip slope dF/di = F_max l / (2 K) at W = {format_value(W, 'N', 6)}",
                rng=srng,
            )
        return out

    @cached_property
    def parameters(self) -> dict[str, ParameterEstimate]:
        """Per parameter (``cohesion``, ``friction_angle``, ``shear_modulus``): estimate and uncertainty."""
        ident = self._identifiable_free
        flags = self._bound_flags
        out: dict[str, ParameterEstimate] = {}
        ridge = None
        if self._cphi_ridge and self.success:
            fmax = self.combinations[0]
            ridge = self._ridge_intervals(fmax)
        for j, name in enumerate(PARAMETER_NAMES):
            val = float(self.theta[j])
            if j not in self.free:
                out[name] = ParameterEstimate(
                    name,
                    0.0,
                    None,
                    (0.0, 0.0),
                    identifiable=False,
                    fixed=True,
                    note="fixed at 0 by the cohesion-free model (not estimated)",
                )
                continue
            k = self.free.index(j)
            side = flags[j]
            notes = []
            if not self.success:
                out[name] = ParameterEstimate(
                    name,
                    None,
                    None,
                    (None, None),
                    bool(ident[k]),
                    False,
                    False,
                    None,
                    ridge_value=val if math.isfinite(val) else None,
                    note="the fit failed: no estimate (ridge_value is the last iterate, NOT an estimate)",
                )
                continue
            outside = side in ("below", "above")
            if outside:
                notes.append(f"{'below' if side == 'below' else 'above'} the bounds (unconstrained method)")
                side = None
            g = np.zeros(len(self.free))
            g[k] = 1.0
            g_s = g / self._D
            weak = bool(ident[k]) and self._vif(g_s) > WEAK_VIF
            partner = rho = None
            if weak and self.effect_labels:
                partner, rho = self._partner(k, True)
            if ident[k]:
                out[name] = self._identified_estimate(name, j, k, val, side, outside, notes, (weak, partner, rho))
            else:
                out[name] = self._unidentified_estimate(name, j, k, val, side, ridge)
        return out

    def _identified_estimate(self, name, j, k, val, side, outside, notes, weakness) -> ParameterEstimate:
        """An identifiable parameter: standard error, the interval (clipped, cut or profiled) and its notes."""
        weak, partner, rho = weakness
        q, C = self.quantile, self._cov_free
        lo, hi = self.bounds.lower, self.bounds.upper
        se = None
        if C is not None:
            v = C[k, k]
            se = math.sqrt(v) if (v >= 0 and math.isfinite(v)) else None
        if se is None:
            notes.append(
                "no standard error: "
                + ("no residual degrees of freedom (n = rank)" if self.dof <= 0 else "covariance not finite")
            )
        if se is not None and q is not None and outside:
            ci = (val - q * se, val + q * se)
        elif se is not None and q is not None:
            ci = (max(lo[j], val - q * se), min(hi[j], val + q * se))
            if side is None:
                notes.extend(
                    _cut_note(val - q * se, val + q * se, lo[j], hi[j], EDGE_UNITS[name][2], EDGE_UNITS[name][1])
                )
        else:
            ci = (None, None)
        if side is not None:
            notes.append(
                f"on the {side} bound: the standard error is the local curvature ignoring the "
                "bound and the interval is clipped to the bounds; use profile_likelihood for an "
                "honest interval"
            )
        if weak:
            notes.append(
                "weakly identifiable (correlation with other parameter directions > 0.99"
                + (f"; most with {partner}: {rho:+.4f})" if partner else ")")
            )
        pi = (self.replaced_intervals or {}).get(name)
        if pi is not None:
            ci = (pi.lower, pi.upper)
            notes = [n for n in notes if not n.startswith(("on the", "the lower end", "the upper end"))]
            if side is not None:
                notes.insert(0, f"on the {side} bound")
            notes.append(_profile_note(pi, EDGE_UNITS[name][2], EDGE_UNITS[name][1]))
        return ParameterEstimate(
            name,
            val,
            se,
            ci,
            True,
            weak,
            side is not None,
            side,
            note="; ".join(notes),
            correlated_with=partner,
            correlation=rho,
        )

    def _unidentified_estimate(self, name, j, k, val, side, ridge) -> ParameterEstimate:
        """A parameter the data do not identify: no value, the ridge's range or the bounds as its interval."""
        lo, hi = self.bounds.lower, self.bounds.upper
        partner = rho = None
        if ridge is not None and j in (0, 1):
            ci = ridge[j]
            note = (
                "not identifiable: c and phi enter only through F_max = A c + W tan(phi) at one "
                "normal load; interval = " + ridge[2]
            )
        else:
            ci = (float(lo[j]), float(hi[j]))
            note = "not identifiable from these data; interval = the bounds"
            if self.effect_labels:  # say what it is confounded with (an effect, or another parameter)
                partner, rho = self._partner(k, False)
                if partner:
                    note = f"not identifiable: the data cannot separate it from {partner}; interval = the bounds"
        # the optimiser's point on a ridge is arbitrary: "on a bound" only if the whole range is
        pinned = ci[0] is not None and ci[1] is not None and ci[1] - ci[0] <= BOUND_TOL * (hi[j] - lo[j])
        nb_side = side if (pinned and side in ("lower", "upper")) else None
        return ParameterEstimate(
            name,
            None,
            None,
            ci,
            False,
            False,
            nb_side is not None,
            nb_side,
            ridge_value=val,
            note=note,
            correlated_with=partner,
            correlation=rho,
        )

    @cached_property
    def effects(self) -> dict[str, dict[str, ParameterEstimate]]:
        """Per effect, per parameter: estimate and uncertainty, with the soil's honesty.

        ``{effect: {param: ParameterEstimate}}`` in SI (each parameter's own unit). A parameter
        the data cannot separate from the soil or another effect is not identifiable (value
        ``None``, interval = its bounds) and ``correlated_with`` / ``correlation`` name the
        parameter it is confounded with; a weakly identifiable one carries the same. Parameters
        held by ``fixed`` are marked ``fixed`` with their value. Empty without effects.
        """
        out: dict[str, dict[str, ParameterEstimate]] = {}
        if not self.effect_labels:
            return out
        q = self.quantile
        C = self._cov_free
        ident = self._identifiable_free
        for m, label in enumerate(self.effect_labels):
            name, pname = label.split(".", 1)
            j = 3 + m
            val = float(self.effect_values[m])
            lo, hi = (float(x) for x in self.effect_bounds[m])
            unit = self.effect_units[m] if m < len(self.effect_units) else ""
            d = out.setdefault(name, {})
            if label in self.fixed_labels:
                d[pname] = ParameterEstimate(
                    label,
                    val,
                    None,
                    (val, val),
                    identifiable=False,
                    fixed=True,
                    si_unit=unit,
                    note=f"held fixed at {val:g} {unit} (not estimated)",
                )
                continue
            k = self.free.index(j)
            if not self.success:
                d[pname] = ParameterEstimate(
                    label,
                    None,
                    None,
                    (None, None),
                    bool(ident[k]),
                    si_unit=unit,
                    ridge_value=val if math.isfinite(val) else None,
                    note="the fit failed: no estimate (ridge_value is the last iterate, NOT an estimate)",
                )
                continue
            tol = BOUND_TOL * (hi - lo)
            side = "lower" if val <= lo + tol else ("upper" if val >= hi - tol else None)
            partner, rho = self._partner(k, bool(ident[k]))
            if ident[k]:
                g_s = np.zeros(len(self.free))
                g_s[k] = 1.0 / self._D[k]
                vif = self._vif(g_s)
                weak = vif > WEAK_VIF
                se = None
                if C is not None:
                    v = C[k, k]
                    se = math.sqrt(v) if (v >= 0 and math.isfinite(v)) else None
                ci = (
                    (max(lo, val - q * se), min(hi, val + q * se))
                    if (se is not None and q is not None)
                    else (None, None)
                )
                notes = []
                if se is None:
                    notes.append(
                        "no standard error: "
                        + ("no residual degrees of freedom (n = rank)" if self.dof <= 0 else "covariance not finite")
                    )
                if side is not None:
                    notes.append(
                        f"on the {side} bound of its physical range [{lo:g}, {hi:g}] {unit}: the standard "
                        "error ignores the bound and the interval is clipped"
                    )
                if weak:
                    mult = math.sqrt(max(0.0, 1.0 - 1.0 / vif)) if math.isfinite(vif) else 1.0
                    notes.append(
                        f"weakly identifiable: multiple correlation {mult:.5f} with the other parameters"
                        + (f", most with {partner} ({rho:+.4f})" if partner else "")
                    )
                pi = (self.replaced_intervals or {}).get(label)
                if pi is not None:
                    ci = (pi.lower, pi.upper)
                    notes = [n for n in notes if not n.startswith("on the")]
                    if side is not None:
                        notes.insert(0, f"on the {side} bound of its physical range [{lo:g}, {hi:g}] {unit}")
                    notes.append(_profile_note(pi, 1.0, unit))
                d[pname] = ParameterEstimate(
                    label,
                    val,
                    se,
                    ci,
                    True,
                    bool(weak),
                    side is not None,
                    side,
                    note="; ".join(notes),
                    si_unit=unit,
                    correlated_with=partner,
                    correlation=rho,
                )
            else:
                with_ = f" from {partner}" if partner else ""
                d[pname] = ParameterEstimate(
                    label,
                    None,
                    None,
                    (lo, hi),
                    False,
                    ridge_value=val,
                    si_unit=unit,
                    correlated_with=partner,
                    correlation=rho,
                    note=f"not identifiable: the data cannot separate it{with_}; interval = its physical range",
                )
        return out

    @cached_property
    def effect_set(self):
        """The fitted effects as an :class:`~soiltrack.soilmodel.EffectSet` (fitted and fixed values),
        usable in ``simulate`` / ``tractive_force_with_effects``; ``None`` without effects or when
        the fit failed. Parameters the data do not identify keep the optimiser's value."""
        if not self.effect_labels or not self.success:
            return None
        from ...soilmodel.effects import EFFECTS, parse_effects

        vals: dict[str, dict[str, float]] = {}
        for label, v in zip(self.effect_labels, np.asarray(self.effect_values, np.float64)):
            name, pname = label.split(".", 1)
            vals.setdefault(name, {})[pname] = float(v)
        for name in self.effect_structure.names:
            for p in EFFECTS[name].params:
                if p.integer:
                    vals.setdefault(name, {})[p.name] = self.effect_structure.value(name, p.name, self.vehicle)
        try:
            return parse_effects(vals)
        except Exception:  # noqa: BLE001 - a non-finite or inadmissible point carries no effect set
            return None

    @cached_property
    def soil(self) -> Soil | None:
        """The identified soil, or ``None`` when the fit failed or a free parameter is not identifiable."""
        if not self.success or not all(self.parameters[PARAMETER_NAMES[j]].identifiable for j in self.free if j < 3):
            return None
        return self._soil_at(self.theta, f"identified ({self.model}, {self.method})")

    @cached_property
    def ridge_point(self) -> Soil | None:
        """The optimiser's point as a Soil, labelled; NOT an estimate when ``soil`` is None."""
        label = (
            "optimiser's point on an unidentifiable ridge - NOT an estimate"
            if self.soil is None
            else f"identified ({self.model}, {self.method})"
        )
        return self._soil_at(self.theta, label)

    def prediction_soil(self, normal_load) -> Soil:
        """A :class:`Soil` that reproduces the fitted curve at ``normal_load`` (N, scalar or array).

        Used by :func:`soiltrack.soilmodel.tractive_force` and ``max_thrust`` when they are given
        this result. With c and phi separable it is :attr:`soil`, valid at any load. At one
        normal load every point of the c-phi ridge gives the same curve at that load, so the
        optimiser's ridge point predicts it exactly there; any other load is refused.

        Raises
        ------
        DataError
            The fit failed, K is not identifiable, effects were fitted (use
            ``tractive_force_with_effects`` with :attr:`effect_set`), or ``normal_load``
            differs from the fitted load while c and phi were not separable.
        """
        from ...soilmodel.errors import DataError
        from .records import EDGE_UNITS

        if not self.success:
            raise DataError(f"the fit did not succeed ({self.status}): it gives no prediction")
        if self.effect_labels:
            raise DataError(
                "the fit includes effects: predict with soilmodel.tractive_force_with_effects(slip, "
                "result.ridge_point, vehicle, result.effect_set)"
            )
        if self.soil is not None:
            return self.soil
        ident = {n: pe.identifiable for n, pe in self.parameters.items() if not pe.fixed}
        if not (self._cphi_ridge and ident.get("shear_modulus", False)) or self.ridge_point is None:
            missing = [EDGE_UNITS[n][3] for n, ok in ident.items() if not ok]
            raise DataError(f"{', '.join(missing)} not identifiable from these data: no prediction")
        W0 = float(self.normal_loads[0])
        W = np.atleast_1d(np.asarray(normal_load, dtype=float))
        off = W[~(np.abs(W - W0) <= 1e-6 * W0)]
        if off.size:
            raise DataError(
                f"c and phi were not separable (all data at W = {W0:.6g} N): the fit predicts the "
                f"tractive force at that load only, not at W = {float(off[0]):.6g} N; fit data at "
                "two or more normal loads to predict at others"
            )
        th = self.theta
        return Soil(
            float(th[0]),
            float(th[1]),
            float(th[2]),
            name=f"fitted curve at W = {W0:.6g} N (ridge point: c and phi NOT separately identified)",
        )

    @staticmethod
    def _soil_at(theta, name: str) -> Soil | None:
        try:
            return Soil(float(theta[0]), float(theta[1]), float(theta[2]), name=name)
        except Exception:  # non-finite or outside the physical domain
            return None
