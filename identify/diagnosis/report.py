"""The plain-words report of a diagnosis: what decided, with the numbers the decision used, and no others."""

from __future__ import annotations

import math
from typing import Any

__all__ = ["report_text", "fmt"]

#: Soil-summary entries that say something about the values rather than being one.
SOIL_META = ("identifiable", "converged", "at_bound", "outside_practical_range", "weakly_identifiable")

HEADS = {"none": "no gap beyond the noise", "unexplained": "a real gap that no candidate effect explains"}


def fmt(x: Any) -> str:
    """A number in four significant digits ("n/a" when missing or not finite)."""
    if x is None:
        return "n/a"
    x = float(x)
    if not math.isfinite(x):
        return "n/a"
    if x == 0:
        return "0"
    a = abs(x)
    if a >= 1e4 or a < 1e-3:
        return f"{x:.3g}" if 1e-3 <= a < 1e6 else f"{x:.3e}"
    return f"{x:.4g}"


def _value(v: Any) -> str:
    """A detail value in words: numbers formatted, lists of numbers as ranges."""
    if isinstance(v, (list, tuple)) and v and all(isinstance(x, (int, float)) for x in v):
        return " to ".join(fmt(x) for x in v)
    return fmt(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else str(v)


def _soil_flag(soil: dict, key: str) -> str:
    flags = []
    side = (soil.get("at_bound") or {}).get(key)
    if side:
        flags.append(f"on its {side} bound")
    elif key in (soil.get("outside_practical_range") or ()):
        flags.append("outside the practical range")
    if key in (soil.get("weakly_identifiable") or ()):
        flags.append("weakly determined")
    return f" ({'; '.join(flags)})" if flags else ""


def _gap_lines(d: Any) -> list[str]:
    kind = (
        "nominal model fitted on alternate blocks in time, predicting the others"
        if d.data_kind == "drive"
        else "each block of the sweep in slip held out once"
    )
    out = [f"The gap ({kind}; residuals are measured - model):"]
    for ch, v in d.holdout_rmse_before.items():
        nf = d.noise.get(ch, 0.0)
        ratio = f" = {v / nf:.2f} x the noise floor {fmt(nf)}" if nf and nf > 0 else ""
        out.append(f"  {ch}: held-out RMS {fmt(v)}{ratio}")
    for t in d.gap.tests:
        out.append(f"  {'*' if t.significant else ' '} {t.name}: p = {t.p_value:.2g} (level {t.level:.2g})")
    out.append(f"  gap present: {'yes' if d.gap.present else 'no'}")
    return out


def _ranking_lines(d: Any) -> list[str]:
    out = [f"The hypotheses, weighed together ({d.evidence}):"]
    for e in d.ranking:
        sh = "" if e.shrink is None else f", standardised held-out RMS shrinks by {e.shrink:.0%}"
        ex = "" if e.explained is None else f", explains {e.explained:.0%} of the excess"
        det = "".join(f", {k} {_value(v)}" for k, v in e.detail.items() if k in ("lag_s", "window_s", "level_N"))
        ew = e.evidence_weight
        shared = "" if ew is None or abs(ew - e.weight) < 5e-4 else f" (shared; {ew:.3f} from the evidence alone)"
        out.append(f"  {e.effect:<20s} {e.family:<9s} weight {e.weight:.3f}{shared} ({e.n_params} par){sh}{ex}{det}")
        for p, v in e.parameters.items():
            out.append(
                f"      {p} = {fmt(v.get('value'))} (standard error {fmt(v.get('stderr'))})"
                f"{'' if v.get('identifiable', True) else ' (not identifiable)'}"
                f"{' (on a bound of its range)' if v.get('at_bound') else ''}"
            )
    for x in d.excluded:
        out.append(f"  left out: {x.name} ({x.family}): {x.why}")
    for c in d.confusable:
        a, b = c.effects
        why = []
        if c.correlation is not None and math.isfinite(c.correlation):
            why.append(f"sensitivities correlated {c.correlation:.2f}")
        if c.separation is not None and math.isfinite(c.separation):
            why.append(f"evidence {c.separation:.1f} standard errors apart")
        cs = f" ({'; '.join(why)})" if why else ""
        out.append(
            f"  {a} and {b} cannot be told apart on these data{cs}: they share their weight; to separate them: "
            f"{c.experiment}"
        )
    return out


def _where_lines(d: Any) -> list[str]:
    if not d.gap.present:
        return ["Where the nominal misfit lies: no gap to localise."]
    out = ["Where the nominal misfit lies (share of the misfit above the noise):"]
    shown = [s for s in d.localisation if s.share >= 0.05][:8]
    for s in shown:
        rng = "whole channel" if s.range is None else f"{s.dimension} {fmt(s.range[0])} to {fmt(s.range[1])}"
        out.append(f"  {s.share:6.1%}  {s.channel:<24s} {rng}")
    if not shown:
        out.append("  nowhere above the noise")
    return out


def _sinkage_lines(d: Any) -> list[str]:
    """The measured sinkage against the slip (sweeps with a ``sinkage_m`` channel)."""
    ev = getattr(d, "sinkage", None)
    if ev is None:
        return []
    if not ev.testable:
        return [f"Measured sinkage: no test of its growth with the slip ({ev.reason})."]
    grows = "grows with the slip" if ev.found() else "shows no significant growth with the slip"
    return [
        f"Measured sinkage ({ev.n_rows} rows) {grows}: exponent of Lyasko's factor s = {ev.exponent:.3g} "
        f"(standard error {ev.stderr:.2g}; p = {ev.p_no_slip_sinkage:.2g} for no slip sinkage, "
        f"p = {ev.p_lyasko:.2g} for Lyasko's law s = 1). A sinkage that grows with the slip is the signature of "
        "slip sinkage; its resistance is weighed above on the force channel."
    ]


def _after_lines(d: Any) -> list[str]:
    if d.holdout_rmse_after is None or d.verdict == "none":
        return []
    what = d.verdict if d.cause is None and d.verdict != "unexplained" else (d.cause or "the flexible term")
    out = [f"How far the gap shrinks with {what} (fitted on the training blocks only):"]
    for ch, b in d.holdout_rmse_before.items():
        a = d.holdout_rmse_after.get(ch)
        fell = f" (held-out RMS {1 - a / b:.0%} lower)" if a is not None and b else ""
        out.append(f"  {ch}: {fmt(b)} -> {fmt(a)}{fell}")
    if d.shrink is not None:
        out.append(
            f"  shrink of the standardised held-out RMS {d.shrink:.2f} (residuals over their noise model, all "
            "channels: the measure the ranking quotes; the per-channel RMS above is in the channel's unit)"
        )
    return out


def _soil_lines(d: Any) -> list[str]:
    out = ["Soil of the nominal fit" + (f" -> with {d.verdict}:" if d.soil_after else ":")]
    for k, v in d.soil_before.items():
        if k in SOIL_META:
            continue
        after = "" if not d.soil_after else f" -> {fmt(d.soil_after.get(k))}{_soil_flag(d.soil_after, k)}"
        out.append(f"  {k}: {fmt(v)}{_soil_flag(d.soil_before, k)}{after}")
    return out


def report_text(d: Any) -> str:
    """The report of diagnosis ``d`` (a :class:`~.result.Diagnosis`)."""
    kind = "drive log" if d.data_kind == "drive" else "slip sweep"
    cause = ""
    if d.cause is not None:
        cause = f"; cause: {d.cause}" + "".join(
            f", {k} {_value(v)}" for k, v in d.cause_detail.items() if k in ("lag_s", "window_s", "level_N", "channels")
        )
    lines = [
        f"Sim-to-real gap diagnosis of a {kind} ({d.n_samples} samples)",
        "",
        f"Verdict: {d.verdict} ({HEADS.get(d.verdict, 'the effect that explains the gap')}{cause}), "
        f"confidence {d.confidence:.2f}",
        f"  why: {d.reason}",
    ]
    if d.torque_hold is not None:
        h = d.torque_hold
        what = "held from each sample to the next" if h.hold == "zoh" else "a sampled continuous signal"
        how = (
            "given"
            if h.given
            else (
                "chosen: held unless the sampled torque predicts the held-out blocks significantly better, "
                f"the flexible term on top of both (sampled: held-out error {abs(h.shrink or 0.0):.1%} "
                f"{'lower' if (h.shrink or 0.0) >= 0 else 'higher'}; p = "
                f"{h.p_value:.2g}, level {h.level or 0.0:.2g})"
                if h.p_value is not None
                else "not tested"
            )
        )
        lines.append(f"  torque: {what} ({how})")
    if not d.converged:
        lines.append("  CAUTION: a fit the verdict rests on did not converge")
    if not d.ranking:
        return "\n".join(lines + [f"Note: {n}" for n in d.notes])
    for part in (_gap_lines, _ranking_lines, _sinkage_lines, _where_lines, _after_lines, _soil_lines):
        block = part(d)
        if block:
            lines += [""] + block
    lines += [f"Note: {n}" for n in d.notes]
    lines.append(f"({d.elapsed_s:.1f} s)")
    return "\n".join(lines)
