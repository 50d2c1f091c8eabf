"""What the data pin down: null space, estimability, the c-phi ridge, confounded parameters.

A mixin of :class:`~soiltrack.identify.estimates.result.FitResult` (it reads the result's core statistics).

* A parameter is *identifiable* when it has no component in the null space of the column-scaled
  Jacobian; it is *weakly identifiable* when its variance inflation in the column-scaled problem
  exceeds ``1 / (1 - 0.99^2)`` (multiple correlation with the other directions above 0.99).
* Identifiable combinations get a standard error when their gradient lies in the row space of
  the Jacobian (estimable).
* c and phi not separable (full model, one normal load): the bounds-feasible ridge
  ``A c + N tan(phi) = F_max`` gives their possible ranges.
* An effect parameter the data cannot separate from the soil or another effect names the
  parameter it is confounded with (:meth:`IdentifiabilityViews._partner`).
"""

from __future__ import annotations

import math
from functools import cached_property
from typing import Any

import numpy as np

from ...soilmodel.ridge import ridge_ranges
from ..outcome import BOUND_TOL
from .least_squares import NULL_TOL, RANK_TOL, WEAK_CORRELATION, WEAK_VIF, estimable, identified_columns
from ...soilmodel.units import format_value
from .record_fields import RecordFields
from .records import EDGE_UNITS, Combination, finite_or_none

__all__ = ["IdentifiabilityViews", "BOUND_TOL"]


class IdentifiabilityViews(RecordFields):
    """Identifiability views of a fit result (mixin; needs the result's core statistics)."""

    def _ridge_pinned(self) -> str:
        """What of F_max and K the data pin down, in words (the outcome rules' ``determined``)."""
        det = self.determined
        fm = any(d.startswith("F_max") for d in det)
        k = "shear_modulus" in det
        if fm and k:
            return "The data pin down F_max and K."
        if fm:
            return "The data pin down F_max (K is not identified: see above)."
        if k:
            return "The data pin down K, not F_max."
        return "The data pin down neither F_max nor K."

    @cached_property
    def _null(self) -> np.ndarray:
        """Null-space basis (scaled coordinates of the free parameters), shape (p, k)."""
        return self._V[:, ~self._nonnull]

    @cached_property
    def _identifiable_free(self) -> np.ndarray:
        return identified_columns(self._null, self._Dok)

    @cached_property
    def _cov_free(self) -> np.ndarray | None:
        """Covariance of the free parameters in SI (pseudo-inverse), None without s^2."""
        if self.s2 is None or not math.isfinite(self.s2):
            return None
        D = self._D
        return self.s2 * self._Pinv / np.outer(D, D)

    @cached_property
    def covariance(self) -> np.ndarray | None:
        """Covariance of ``[c, phi, K]`` (SI); ``None`` if rank deficient or no dof."""
        C = self._cov_free
        if C is None or self.rank < len(self.free) or not np.all(np.isfinite(C)):
            return None
        out = np.zeros((self._n_all, self._n_all))
        idx = np.array(self.free)
        out[np.ix_(idx, idx)] = C
        return out

    @cached_property
    def correlation(self) -> np.ndarray | None:
        """Correlation matrix of ``[c, phi, K]`` (fixed parameters: zero rows, unit diagonal)."""
        C = self.covariance
        if C is None:
            return None
        d = np.sqrt(np.diag(C))
        with np.errstate(invalid="ignore", divide="ignore"):
            R = C / np.outer(np.where(d > 0, d, 1.0), np.where(d > 0, d, 1.0))
        np.fill_diagonal(R, 1.0)
        return R

    def _vif(self, g_scaled: np.ndarray) -> float:
        nrm = float(g_scaled @ g_scaled)
        return float(g_scaled @ self._Pinv @ g_scaled) / nrm if nrm > 0 else math.inf

    def _estimable(self, g_scaled: np.ndarray) -> bool:
        return estimable(g_scaled, self._null)

    def _combo_stderr(self, g_free: np.ndarray) -> tuple[float | None, bool, bool]:
        """(stderr, estimable, weak) of a linear functional with SI gradient g over free params."""
        g_s = g_free / self._D
        est = self._estimable(g_s)
        weak = est and self._vif(g_s) > WEAK_VIF
        C = self._cov_free
        if not est or C is None:
            return None, est, weak
        var = float(g_free @ C @ g_free)
        return (math.sqrt(var) if var >= 0 and math.isfinite(var) else None), est, weak

    # ---------------------------------------------------------------------------- ridge
    @cached_property
    def _cphi_ridge(self) -> bool:
        """Full model, c and phi both unidentifiable, one normal load: the classic ridge."""
        if self.model != "full" or len(self.normal_loads) != 1:
            return False
        ident = self._identifiable_free
        return not ident[0] and not ident[1]

    def _ridge_intervals(self, fmax: "Combination") -> tuple[tuple, tuple, str]:
        A = self.vehicle.contact_area
        W = self._effective_load(float(self.normal_loads[0]))[0]
        F_lo = fmax.ci95[0] if fmax.ci95[0] is not None else fmax.value
        F_hi = fmax.ci95[1] if fmax.ci95[1] is not None else fmax.value
        rr = ridge_ranges(F_lo, F_hi, W, A, self.bounds)
        how = (
            "F_max within its 95 % interval"
            if fmax.ci95[0] is not None
            else "F_max at its estimate (no interval: no residual degrees of freedom)"
        )
        if rr is None:
            return (
                (None, None),
                (None, None),
                (f"no point of the ridge A c + W tan(phi) = F_max with {how} lies within the bounds"),
            )
        return (
            rr[0],
            rr[1],
            (
                f"range along the ridge A c + W tan(phi) = F_max "
                f"(W = {format_value(W, 'N', 6)}) with {how}, within the bounds"
            ),
        )

    def _partner(self, k: int, identifiable: bool) -> tuple[str | None, float | None]:
        """The free parameter most correlated with free parameter ``k`` and that correlation.

        Identifiable: the largest pairwise correlation of the estimates. Not identifiable: the
        parameter moving most with it along the null space (correlation +-1, sign of the
        estimates' co-movement)."""
        names = [self.parameter_names[j] for j in self.free]
        if len(names) < 2:
            return None, None
        if identifiable:
            P = self._Pinv
            d = np.sqrt(np.clip(np.diag(P), 0.0, None))
            if d[k] <= 0:
                return None, None
            with np.errstate(all="ignore"):
                row = P[k] / (d[k] * np.where(d > 0, d, np.inf))
            row[k] = 0.0
            row = np.where(np.isfinite(row) & self._identifiable_free, row, 0.0)
            m = int(np.argmax(np.abs(row)))
            return names[m], float(np.clip(row[m], -1.0, 1.0))
        null = self._null
        if null.shape[1] == 0:
            return None, None
        v = null @ null[k]  # null-space direction closest to this parameter's axis (scaled coordinates)
        w = np.abs(v)
        w[k] = 0.0
        m = int(np.argmax(w))
        if w[m] < NULL_TOL:
            return None, None
        return names[m], float(np.sign(v[k] * v[m]))

    def _fmax_K_correlation(self) -> dict[str, float | None]:
        """Correlation of the F_max estimate at each load with the K estimate (scale-free)."""
        out: dict[str, float | None] = {}
        if not self.success:
            return out
        idx = np.array(self.free)
        Pinv = self._Pinv / np.outer(self._D, self._D)  # (J^T J)^+ in SI; s^2 cancels in a correlation
        gK = self._full([0.0, 0.0, 1.0])[idx]
        for W in self.normal_loads:
            gF = self._fmax(float(W))[1][idx]
            if not (self._estimable(gF / self._D) and self._estimable(gK / self._D)):
                out[f"{float(W):.6g}"] = None
                continue
            v1, v2, c12 = gF @ Pinv @ gF, gK @ Pinv @ gK, gF @ Pinv @ gK
            out[f"{float(W):.6g}"] = float(c12 / math.sqrt(v1 * v2)) if v1 > 0 and v2 > 0 else None
        return out

    @cached_property
    def identifiability(self) -> dict[str, Any]:
        """Rank, scaled singular values, null-space directions and plain-words statements."""
        p = len(self.free)
        names = [self.parameter_names[j] for j in self.free]
        null_dirs = []
        for col in self._null.T:
            d = col / self._D  # back to SI parameter space
            d = d * np.array([EDGE_UNITS[n][2] if n in EDGE_UNITS else 1.0 for n in names])  # edge units: kPa, deg, m
            d = d / np.linalg.norm(d)
            if d[np.argmax(np.abs(d))] < 0:
                d = -d
            null_dirs.append(
                {(EDGE_UNITS[names[k]][0] if names[k] in EDGE_UNITS else names[k]): float(d[k]) for k in range(p)}
            )
        statements: list[str] = []
        params = self.parameters
        if self._cphi_ridge:  # (what of F_max and K the data pin down: the outcome rules' ``determined``)
            W = float(self.normal_loads[0])
            statements.append(
                f"c and phi are not separable: all data are at one normal load (W = {format_value(W, 'N', 6)}), "
                "where they enter only through F_max = A c + W tan(phi); infinitely many (c, phi) give the same curve. "
                f"{self._ridge_pinned()} Data at two or more normal loads (payload change, slope) or a "
                "prior are needed to separate c and phi."
            )
        for name, pe in params.items():
            if pe.fixed:
                continue
            if not pe.identifiable and not (self._cphi_ridge and name in ("cohesion", "friction_angle")):
                statements.append(
                    f"{EDGE_UNITS[name][3]} is not identifiable from these data"
                    + (f": they cannot separate it from {pe.correlated_with}." if pe.correlated_with else ".")
                )
            elif pe.weakly_identifiable:
                statements.append(
                    f"{EDGE_UNITS[name][3]} is only weakly identifiable (correlated above "
                    f"{WEAK_CORRELATION} with other parameter directions)."
                )
        for name, ps in self.effects.items():
            for pname, pe in ps.items():
                if pe.fixed or not self.success:
                    continue
                partner = f" from {pe.correlated_with}" if pe.correlated_with else ""
                rho = f" (correlation {pe.correlation:+.4f})" if pe.correlation is not None else ""
                if not pe.identifiable:
                    statements.append(
                        f"effect parameter {name}.{pname} is not identifiable from these data: they "
                        f"cannot separate it{partner}{rho}."
                    )
                elif pe.weakly_identifiable:
                    statements.append(
                        f"effect parameter {name}.{pname} is only weakly identifiable: the data hardly "
                        f"separate it from the soil and the other effects ({pe.note.split(': ', 1)[-1]}). "
                        "Its interval assumes the model of the data is exact: along so narrow a ridge a "
                        "small unmodelled error (slip measured with noise, a sensor offset) can move the "
                        "estimate far outside it; an experiment that separates it is safer than the "
                        "interval."
                    )
        fk_corr = self._fmax_K_correlation()
        weak_combos = [
            cb
            for cb in self.combinations
            if cb.weakly_identifiable and cb.name.startswith("F_max") and not self.effect_labels
        ]  # with effects, F_max may be weak through an effect
        high = {w: r for w, r in fk_corr.items() if r is not None and abs(r) > WEAK_CORRELATION}
        if weak_combos or high or (params["shear_modulus"].weakly_identifiable and not self.effect_labels):
            rtxt = (
                (
                    " (correlation "
                    + ", ".join(f"{r:+.4f} at W = {format_value(float(w), 'N', 6)}" for w, r in high.items())
                    + ")"
                )
                if high
                else ""
            )
            statements.append(
                f"F_max and K are strongly correlated{rtxt}: the data show mainly the start of the thrust-slip curve, "
                "whose slope F_max l / (2 K) is determined but not F_max and K separately; data at larger slip "
                "(near the traction limit) separate them."
            )
        if not statements:
            statements.append("all free parameters are identifiable from these data.")
        corr = None
        if self.correlation is not None:
            corr = [[finite_or_none(x) for x in row] for row in self.correlation]
        return {
            "rank": int(self.rank),
            "n_parameters": p,
            "parameters": names,
            "fmax_K_correlation": fk_corr,
            "scaled_singular_values": [float(s) for s in self.scaled_singular_values],
            "null_space": null_dirs,
            "correlation": corr,
            "statements": statements,
            "rank_tolerance": RANK_TOL,
        }
