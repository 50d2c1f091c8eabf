"""Sim-to-real diagnosis of a wheel sweep: does the textbook wheel explain it, and if not, which effect.

Hypotheses: ``none`` (the nominal Wong-Reece wheel), each wheel effect (``slip_sinkage``: at a
given sinkage a slipping wheel's soil carries less, so the measured sinkage grows with slip at a
constant load; its signature is a sinkage residual - measured minus the sinkage that carries the
load - that rises with slip), and
``unexplained`` (the drawbar pull misses the repeats' scatter and no effect helps).

Every hypothesis is fitted to all rows (its Akaike weight, from the concentrated likelihood) and
checked on held-out data: each slip level in turn is left out, the fit made on the others, and
the left-out rows predicted (drawbar pull and sinkage, each channel scaled by the nominal fit's
noise level). An effect is the verdict when its likelihood-ratio test against the nominal
has ``p < ALPHA`` and it predicts the held-out levels better; ``unexplained`` when the nominal's
drawbar pull fails the pure-error lack-of-fit test (``p < ALPHA``) and no effect is the verdict.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ...soilmodel.errors import DataError
from ...soilmodel.rigid_wheel import RigidWheel
from ...soilmodel.wheel_sweep import WheelSweep
from ..estimates.distributions import chi2_sf, t_cdf
from .fitting import WHEEL_EFFECTS, WheelFitOptions, fit_wheel
from .grouser_hypothesis import GROUSER_HYPOTHESIS, grouser_hypothesis, grousers_weighable
from .problem import channel_floors
from .result import WheelFitResult, slip_levels, wheel_rows

__all__ = ["WheelDiagnosis", "diagnose_wheel", "ALPHA"]

#: Significance level of the likelihood-ratio, lack-of-fit and trend tests.
ALPHA = 0.01
#: Why the grouser hypothesis is not weighed with c and phi both free.
GROUSER_CONFOUNDED = (
    "grousers: not weighed - with c and phi both fitted the grouser height is confounded with them (Bekker's "
    "factors multiply c and tan(phi); c held at 0 does not tell them apart); hold phi or a c above 0 (a shear test, "
    "a terrain; CLI --fix friction_angle_deg=...) to weigh grousers"
)
#: What the grouser hypothesis' held-out error is.
GROUSER_HOLDOUT = (
    "grousers: Bekker's grouser term with the height fitted, h = {h:.3g} mm (the wheel's JSON: {h0:.3g} mm); "
    "its held-out error holds h at this all-rows value in each left-out fold (one parameter's optimism)"
)
#: Every hypothesis the wheel diagnosis can weigh: the wheel's effects and the grousers.
KNOWN_HYPOTHESES = (*WHEEL_EFFECTS, GROUSER_HYPOTHESIS)
#: A slip level whose share of the held-out misfit exceeds this many equal shares is flagged significant.
LOCALISATION_SHARE = 2.0


@dataclass(frozen=True, eq=False)
class WheelDiagnosis:
    """Verdict, ranking and held-out errors of a wheel diagnosis (``to_json``: ``diagnose --json``)."""

    verdict: str
    confidence: float
    ranking: tuple[dict[str, Any], ...]
    localisation: tuple[dict[str, Any], ...]
    shrink: float | None
    nominal: WheelFitResult
    after: WheelFitResult | None
    signature: dict[str, Any]
    converged: bool
    notes: tuple[str, ...]

    def to_dict(self) -> dict[str, Any]:
        """The JSON object (the keys of the track's diagnosis, plus the wheel's signature and notes)."""

        def soil(r: WheelFitResult | None) -> dict | None:
            return None if r is None else {k: v.edge_value for k, v in r.parameters.items()}

        return {
            "running_gear": "rigid_wheel",
            "verdict": self.verdict,
            "confidence": self.confidence,
            "ranking": list(self.ranking),
            "confusable": [],
            "localisation": list(self.localisation),
            "shrink": self.shrink,
            "soil_before": soil(self.nominal),
            "soil_after": soil(self.after) if self.verdict in KNOWN_HYPOTHESES else None,
            "slip_sinkage_signature": self.signature,
            "lack_of_fit": self.nominal.lack_of_fit,
            "converged": self.converged,
            "notes": list(self.notes),
        }

    def to_json(self) -> str:
        """:meth:`to_dict` as JSON text."""
        return json.dumps(self.to_dict(), indent=2)

    def report(self) -> str:
        """A plain-text report."""
        lines = [
            f"verdict: {self.verdict} (confidence {self.confidence:.2f})"
            + ("" if self.converged else " - the nominal fit did not converge")
        ]
        lines.append(f"{'hypothesis':<16}{'weight':>8}{'held-out before':>17}{'after':>8}{'shrink':>8}")
        for r in self.ranking:
            sh = "-" if r["shrink"] is None else f"{r['shrink']:.2f}"
            after = "-" if r["holdout_rmse_after"] is None else f"{r['holdout_rmse_after']:.3g}"
            lines.append(f"{r['effect']:<16}{r['weight']:>8.2f}{r['holdout_rmse_before']:>17.3g}{after:>8}{sh:>8}")
        sig = self.signature
        if sig.get("correlation") is not None:
            lines.append(
                f"slip-sinkage signature: the sinkage residual against slip r = {sig['correlation']:+.2f} "
                f"(p = {sig['p_value']:.2g}); measured sinkage against slip r = {sig['sinkage_slip_r']:+.2f}"
            )
        lf = self.nominal.lack_of_fit
        if lf.get("testable"):
            lines.append(f"drawbar pull against the repeats' scatter: F = {lf['F']:.3g}, p = {lf['p_value']:.2g}")
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)


def _objective(r: WheelFitResult, data: WheelSweep) -> float:
    """Concentrated negative log-likelihood of a fit (per-channel unknown noise), the fit's own objective."""
    n = data.n_samples
    f_dp, f_z = channel_floors(float(np.mean(data.normal_load)))
    f = n / 2 * math.log(r.rmse_drawbar_pull**2 + f_dp**2)
    if r.rmse_sinkage is not None:
        f += n / 2 * math.log(r.rmse_sinkage**2 + f_z**2)
    return f


def _holdout(
    data: WheelSweep, wheel: RigidWheel, opts: WheelFitOptions, scale: tuple[float, float | None]
) -> tuple[float, dict[int, float], bool]:
    """Leave-one-slip-level-out: scaled rms of the held-out residuals, the share per level, all converged."""
    lev = slip_levels(data.slip)
    sq: dict[int, float] = {}
    ok = True
    for g in np.unique(lev):
        train, test = data.subset(lev != g), data.subset(lev == g)
        r = fit_wheel(train, wheel, opts)
        ok &= r.success
        dp, _, _, z_w = wheel_rows(wheel, opts.settings, r.theta, test)[:4]
        s = float((((dp - test.drawbar_pull) / scale[0]) ** 2).sum())
        if scale[1] is not None:
            s += float((((z_w - test.sinkage) / scale[1]) ** 2).sum())
        sq[int(g)] = s
    n_res = data.n_samples * (2 if scale[1] is not None else 1)
    total = sum(sq.values())
    return math.sqrt(total / n_res), {g: v / total if total > 0 else 0.0 for g, v in sq.items()}, ok


@dataclass(frozen=True, eq=False)
class _Hypothesis:
    """One explanation tried by :func:`diagnose_wheel`: its fit, held-out error and evidence."""

    effect: str  #: "none" (the nominal wheel) or one of :data:`WHEEL_EFFECTS`
    fit: WheelFitResult  #: the fit on all slip levels
    holdout: float  #: scaled rms of the held-out residuals (each slip level left out in turn)
    k: int  #: free parameters
    weight: float = 0.0  #: Akaike weight among the hypotheses
    p_value: float | None = None  #: likelihood-ratio test against the nominal fit (None for "none")
    admissible: bool = True  #: False when the effect (or the grouser height) ends on a bound
    bound_note: str | None = None  #: why it is inadmissible, for the diagnosis' notes
    height: float | None = None  #: the fitted grouser height (m), for the grousers hypothesis


def diagnose_wheel(
    data: WheelSweep,
    wheel: RigidWheel,
    options: WheelFitOptions = WheelFitOptions(),
    candidates: tuple[str, ...] | None = None,
) -> WheelDiagnosis:
    """Diagnose a wheel sweep against the nominal rigid wheel (see the module text)."""
    cands = _checked_candidates(data, candidates)
    nominal = fit_wheel(data, wheel, replace(options, effects=()))
    notes = []
    f_dp, f_z = channel_floors(float(np.mean(data.normal_load)))
    scale = (
        math.hypot(nominal.rmse_drawbar_pull, f_dp),
        None if nominal.rmse_sinkage is None else math.hypot(nominal.rmse_sinkage, f_z),
    )
    # each left-out level's fit starts from the fit on all levels (the grid when that solve fails)
    before, shares, ok_nom = _holdout(data, wheel, replace(options, effects=(), start=tuple(nominal.theta)), scale)
    hyps = [_Hypothesis("none", nominal, before, sum(not e.fixed for e in nominal.parameters.values()))]
    for eff in cands:
        if eff == "slip_sinkage" and not data.has_sinkage:
            notes.append("slip_sinkage needs a measured sinkage (sinkage_m) to show: not tried")
            continue
        if eff == GROUSER_HYPOTHESIS:  # Bekker's grouser term, the height fitted (grouser_hypothesis.py)
            if not grousers_weighable(options):
                notes.append(GROUSER_CONFOUNDED)
                continue
            h, ok = _grouser_row(data, wheel, options, nominal, scale)
            ok_nom &= ok
            hyps.append(h)
            notes.append(GROUSER_HOLDOUT.format(h=1e3 * (h.height or 0.0), h0=1e3 * wheel.grouser_height))
            continue
        r = fit_wheel(data, wheel, replace(options, effects=(eff,)))
        ho, _, ok = _holdout(data, wheel, replace(options, effects=(eff,), start=tuple(r.theta)), scale)
        ok_nom &= ok
        hyps.append(_effect_row(eff, r, ho))
    hyps, verdict = _weighed(hyps, data, nominal, before)
    notes.extend(h.bound_note for h in hyps if h.bound_note)
    lf = nominal.lack_of_fit
    unexplained = verdict == "none" and lf.get("testable") and lf["p_value"] < ALPHA
    if unexplained:
        verdict = "unexplained"
    ranking = _ranking(hyps, before)
    if verdict == "unexplained":
        confidence = 1.0 - float(lf["p_value"])
    else:
        confidence = next(r["weight"] for r in ranking if r["effect"] == verdict)
    after = next((h.fit for h in hyps if h.effect == verdict), None)
    shrink = None
    if verdict in KNOWN_HYPOTHESES:
        shrink = next((r["shrink"] for r in ranking if r["effect"] == verdict), None)
    notes.append(
        "held-out errors are root mean squares of residuals scaled by the nominal fit's noise level per "
        "channel (1 = as good as the fit in-sample), each slip level left out in turn"
    )
    return WheelDiagnosis(
        verdict=verdict,
        confidence=float(confidence),
        ranking=tuple(ranking),
        localisation=tuple(_localisation(data, shares)),
        shrink=shrink,
        nominal=nominal,
        after=after,
        signature=_sinkage_signature(data, nominal),
        converged=bool(nominal.success and ok_nom),
        notes=tuple(notes),
    )


def _checked_candidates(data: WheelSweep, candidates: tuple[str, ...] | None) -> tuple[str, ...]:
    """The candidate effects (default all the wheel's); DataError for an unknown one or fewer than 3 slip levels."""
    cands = KNOWN_HYPOTHESES if candidates is None else tuple(candidates)
    bad = [c for c in cands if c not in KNOWN_HYPOTHESES]
    if bad:
        raise DataError(f"unknown candidate {bad[0]!r} for a rigid wheel; it has {list(KNOWN_HYPOTHESES)}")
    if np.unique(slip_levels(data.slip)).size < 3:
        raise DataError(
            "a wheel diagnosis leaves each slip level out in turn: it needs at least 3 slip levels",
            file=data.source,
            column="slip",
        )
    return cands


def _effect_row(eff: str, r: WheelFitResult, holdout: float) -> _Hypothesis:
    """An effect's hypothesis; an effect that ends on its bound is inadmissible as a verdict (the track's rule)."""
    e = r.parameters.get(eff)
    note = None
    if e is not None and e.at_bound:
        note = (
            f"{eff} ends on its {e.bound_side} bound ({e.edge_value:.4g}): inadmissible as a verdict (a value "
            "the bounds choose is not an estimate of the effect; its weight and p-value are shown, not used)"
        )
    k = sum(not p.fixed for p in r.parameters.values())
    return _Hypothesis(eff, r, holdout, k, admissible=note is None, bound_note=note)


def _grouser_row(
    data: WheelSweep, wheel: RigidWheel, options: WheelFitOptions, nominal: WheelFitResult, scale: tuple
) -> tuple[_Hypothesis, bool]:
    """The grousers hypothesis (height profiled, :mod:`.grouser_hypothesis`) with its held-out error."""
    g = grouser_hypothesis(data, wheel, options, nominal, _objective)
    ho, _, ok = _holdout(data, g["wheel"], replace(g["options"], start=tuple(g["fit"].theta)), scale)
    note = None
    if not g["admissible"]:
        note = (
            f"grousers: the fitted height ends on its {g['bound_side']} bound ({1e3 * g['bound_value']:.4g} mm): "
            "inadmissible as a verdict (a height the bounds choose is not an estimate of the grousers)"
        )
    row = _Hypothesis(GROUSER_HYPOTHESIS, g["fit"], ho, int(g["k"]), admissible=note is None, bound_note=note)
    return replace(row, height=float(g["height"])), ok


def _weighed(
    hyps: list[_Hypothesis], data: WheelSweep, nominal: WheelFitResult, before: float
) -> tuple[list[_Hypothesis], str]:
    """The hypotheses with their Akaike weights and p-values, and the verdict among the effects.

    An effect wins when its likelihood-ratio test is significant at :data:`ALPHA`, it lowers the held-out
    error, its fit succeeded, it is admissible (not on a bound), and it outweighs the effect chosen so far; else
    the verdict is "none".
    """
    aic = np.array([2 * _objective(h.fit, data) + 2 * h.k for h in hyps])
    w = np.exp(-(aic - aic.min()) / 2)
    w = w / w.sum()
    f0 = _objective(nominal, data)
    verdict, best = "none", 0.0  # best: the weight of the verdict's hypothesis
    out = []
    for h, wk in zip(hyps, w):
        if h.effect == "none":
            out.append(replace(h, weight=float(wk), p_value=None))
            continue
        p = chi2_sf(max(2 * (f0 - _objective(h.fit, data)), 0.0), 1)
        out.append(replace(h, weight=float(wk), p_value=p))
        win = p < ALPHA and h.holdout < before and h.fit.success and h.admissible
        if win and (verdict == "none" or float(wk) > best):
            verdict, best = h.effect, float(wk)
    return out, verdict


def _sinkage_signature(data: WheelSweep, nominal: WheelFitResult) -> dict[str, Any]:
    """The slip-sinkage signature: the nominal fit's sinkage residual's correlation with the slip."""
    sig: dict[str, Any] = {"correlation": None, "p_value": None, "sinkage_slip_r": None}
    if data.has_sinkage and data.n_samples > 3 and data.sinkage is not None:
        res = data.sinkage - nominal.predict_sinkage(data)
        rho = float(np.corrcoef(res, data.slip)[0, 1])
        dof = data.n_samples - 2
        t = rho * math.sqrt(dof / max(1 - rho**2, 1e-300))
        sig = {
            "correlation": rho,
            "p_value": 2 * (1 - t_cdf(abs(t), dof)),
            "sinkage_slip_r": float(np.corrcoef(data.sinkage, data.slip)[0, 1]),
        }
    return sig


def _ranking(hyps: list[_Hypothesis], before: float) -> list[dict[str, Any]]:
    """The hypotheses by weight, as the JSON's ranking (held-out errors before and after, shrink, p-value)."""
    ranking = []
    for h in sorted(hyps, key=lambda x: -x.weight):
        sh = None if h.effect == "none" else 1 - h.holdout / before
        ranking.append(
            {
                "effect": h.effect,
                "weight": h.weight,
                "holdout_rmse_before": before,
                "holdout_rmse_after": None if h.effect == "none" else h.holdout,
                "shrink": sh,
                "p_value": h.p_value,
                "admissible": h.admissible,
                "parameters": _row_parameters(h),
            }
        )
    return ranking


def _row_parameters(h: _Hypothesis) -> dict[str, float]:
    """The hypothesis' own fitted parameter for the ranking (the slip-sinkage coefficient, the grouser height)."""
    if h.effect == "slip_sinkage":
        v = h.fit.parameters["slip_sinkage"].value
        return {} if v is None else {"slip_sinkage": float(v)}
    if h.effect == GROUSER_HYPOTHESIS and h.height is not None:
        return {"grouser_height_m": h.height}
    return {}


def _localisation(data: WheelSweep, shares: dict[int, float]) -> list[dict[str, Any]]:
    """Where the held-out error sits: each slip level's share, largest first."""
    lev = slip_levels(data.slip)
    loc = []
    for g, share in sorted(shares.items(), key=lambda kv: -kv[1]):
        s = data.slip[lev == g]
        loc.append(
            {
                "dimension": "slip",
                "range": [float(s.min()), float(s.max())],
                "channel": "drawbar_pull_N" + (" and sinkage_m" if data.has_sinkage else ""),
                "share": share,
                "significant": bool(share > LOCALISATION_SHARE / len(shares)),
            }
        )
    return loc
