"""A drive log whose torque hold the user did not state: the intervals cover both holds.

How the logged torque relates to the drive is a property of the logger the data cannot tell
reliably (a likelihood comparison preferred ``sample`` on held-torque logs): ``zoh`` (a
command held over each interval, as the library's simulator and most controllers do) or
``sample`` (a continuous signal sampled at each time, as a torque transducer gives). The wrong
one shifts the thrust by its change over one sample, which a joint fit reads as a grade or a
drivetrain loss: on independent 20 Hz logs on a 0.05 rad slope the grade came out 0.0494-0.0497
with ``zoh`` against 0.04995-0.05014 with ``sample``, intervals about +-0.0004.

So when effects are fitted and ``torque_hold`` is not given, the fit is made with ``zoh`` (its
point estimate is reported) and again with ``sample``; every interval that the second fit's
interval leaves is widened to cover both, and its note says so. Giving ``torque_hold`` gives
the one fit's interval. The diagnosis always states its hold and is not widened.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable

from ..estimates.joint_likelihood import ReplacedInterval
from ..estimates.result import FitResult

__all__ = ["fit_both_holds", "widen_for_hold"]


def _estimates(res) -> dict:
    """``{label: ParameterEstimate}`` of the soil and effect parameters of a result."""
    out = dict(res.parameters)
    for e, ps in res.effects.items():
        for p, pe in ps.items():
            out[f"{e}.{p}"] = pe
    return out


def _finite_ci(pe) -> bool:
    lo, hi = pe.ci95
    return (
        pe.identifiable
        and pe.value is not None
        and lo is not None
        and hi is not None
        and math.isfinite(lo)
        and math.isfinite(hi)
    )


def widen_for_hold(res, alt, alt_hold: str = "sample"):
    """``res`` with each interval widened to cover ``alt``'s (the fit with the other torque hold)."""
    extra = dict(res.extra)
    info = {"torque_hold": alt_hold, "success": bool(alt.success), "status": alt.status}
    if not (res.success and alt.success):
        extra["torque_hold_alternative"] = info
        return replace(res, extra=extra)
    mine, other = _estimates(res), _estimates(alt)
    overrides = dict(res.replaced_intervals or {})
    info["intervals"] = {}
    for label, pe in mine.items():
        pa = other.get(label)
        if pa is None or pe.fixed or not _finite_ci(pe) or not _finite_ci(pa):
            continue
        info["intervals"][label] = {"value": pa.value, "ci95": list(pa.ci95)}
        lo, hi = min(pe.ci95[0], pa.ci95[0]), max(pe.ci95[1], pa.ci95[1])
        if (lo, hi) == tuple(pe.ci95):
            continue
        prev = overrides.get(label)
        note = (
            f"the torque hold was not given: this interval also covers the fit with torque_hold='{alt_hold}' "
            f"({pa.value:.6g} [{pa.ci95[0]:.6g}, {pa.ci95[1]:.6g}] SI); give torque_hold for the interval of "
            "the one that describes the log"
        )
        if prev is not None:
            note = f"{prev.note}; {note}" if prev.note else note
        overrides[label] = ReplacedInterval(
            label, float(lo), float(hi), False, False, tuple(pe.ci95), 0, note, kind="hold"
        )
    extra["torque_hold_alternative"] = info
    return replace(res, replaced_intervals=overrides or None, extra=extra)


def fit_both_holds(fit_with: Callable[[str], FitResult]):
    """``fit_with("zoh")``, its intervals widened to cover ``fit_with("sample")`` (effects fitted only)."""
    res = fit_with("zoh")
    if not res.success or not res.effect_labels:
        return res
    return widen_for_hold(res, fit_with("sample"))
