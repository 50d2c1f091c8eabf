"""Profile-likelihood intervals of a joint soil-and-effect slip fit.

The linearised 95 % interval ``value +- q stderr`` assumes the cost is quadratic over the
interval. Along a near-confounded direction it is not: a grade and phi in a drawbar sweep
trade along a long curved valley, and the linearised interval can exclude the truth that the
data do not reject (a likelihood-ratio test at the truth well inside its 95 % level). The
profile interval does not assume it: each end is where the cost, with this parameter held and
every other one refitted, rises by the likelihood-ratio threshold
(:func:`~soiltrack.identify.estimates.distributions.lr_threshold`: ``1.96^2 / 2`` with a known sigma, else
``s^2 t^2 / 2``).

Each end is found by stepping out from the estimate (first step: the linearised half-width,
doubling) until the threshold is crossed or the physical bound is reached (then the end is
the bound and the interval is open there), then by regula falsi on the profile cost.

The profile is continuous and starts at the fit's minimum: before each side is searched, a
probe a small step from the estimate (:data:`_PROBE_STEP` of the linearised half-width) must
come back within :data:`_PROBE_RTOL` of the threshold's rise of the minimum. When it does not,
the held solves do not follow the profile's valley (the solver left the warm start for another
local minimum; an end "found" that way sits at the estimate): that side takes the linearised
end and the interval's note says so, rather than a one-sided interval ending at the estimate. Every
profile point is a solve of the same cached NLP as the fit, warm-started from its neighbour
(:func:`~soiltrack.identify.sweep.joint.fit_joint` with ``hold``).

``intervals="auto"`` (the default of joint fits) profiles the parameters flagged weakly
identifiable or ended on a bound, where the linearised interval is least trustworthy;
``"profile"`` every identifiable one; ``"linear"`` none.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ...soilmodel.errors import DataError
from ...soilmodel.soil import PARAMETER_NAMES
from .distributions import lr_threshold
from .records import ParameterEstimate, fit_vector

__all__ = [
    "PROFILE_IPOPT_OPTIONS",
    "ReplacedInterval",
    "profile_intervals",
    "with_profile_intervals",
    "check_intervals",
    "INTERVAL_MODES",
]

INTERVAL_MODES = ("auto", "linear", "profile")
_MAX_EXPAND = 7
_MAX_REFINE = 8
#: The end is located when the profile cost is within this share of (threshold - minimum) of the threshold.
_COST_RTOL = 0.02
#: IPOPT options of a profile solve: each starts at a neighbouring optimum, so the barrier starts small; with
#: IPOPT's default (mu_init 0.1) the start is pushed into the interior and the solve can land in another local
#: minimum (the hump-shear sweep of examples/diagnose_story.py: cost 77.0 at the estimate against the fit's 27.0).
PROFILE_IPOPT_OPTIONS = {"ipopt.mu_init": 1e-6}
#: Step of the continuity probe, as a share of the linearised half-width (small: the profile there is the minimum's).
_PROBE_STEP = 1e-3
#: The probe's cost may rise at most this share of (threshold - minimum) above the minimum (it rises ~1e-6).
_PROBE_RTOL = 0.05


@dataclass(frozen=True)
class ReplacedInterval:
    """A 95 % interval that replaced a parameter's linearised one (SI): the profile likelihood's, or
    (``kind="hold"``) one widened to cover a drive log's two torque holds.

    ``open_lower`` / ``open_upper``: the threshold is not crossed before the physical bound
    (the data do not bound the parameter on that side); ``linear``: the linearised interval it
    replaces; ``evaluations``: profile solves; ``note``: anything that went wrong.
    """

    label: str
    lower: float
    upper: float
    open_lower: bool
    open_upper: bool
    linear: tuple
    evaluations: int
    note: str = ""
    #: ``"profile"`` (the profile likelihood) or ``"hold"`` (widened to cover the other torque hold of a
    #: drive log, :mod:`soiltrack.identify.drivelog.torque_hold`)
    kind: str = "profile"

    def to_dict(self) -> dict:
        """JSON-ready dict."""
        f = lambda x: None if x is None or not math.isfinite(x) else float(x)  # noqa: E731
        return {
            "ci95": [f(self.lower), f(self.upper)],
            "open_lower": self.open_lower,
            "open_upper": self.open_upper,
            "linear_ci95": [f(v) for v in self.linear],
            "evaluations": self.evaluations,
            "note": self.note,
            "kind": self.kind,
        }


def check_intervals(value) -> str:
    """Validate the ``intervals`` option."""
    if value not in INTERVAL_MODES:
        raise DataError(f"intervals must be one of {INTERVAL_MODES}, got {value!r}")
    return value


def _candidates(res, mode: str) -> list[tuple[int, str, ParameterEstimate]]:
    """``(index in [c, phi, K, e...], label, ParameterEstimate)`` of the parameters to profile."""
    out = []
    for j, name in enumerate(PARAMETER_NAMES):
        pe = res.parameters[name]
        if j in res.free and pe.identifiable and pe.value is not None:
            out.append((j, name, pe))
    for m, label in enumerate(res.effect_labels):
        e, p = label.split(".", 1)
        pe = res.effects[e][p]
        if 3 + m in res.free and pe.identifiable and pe.value is not None and not pe.fixed:
            out.append((3 + m, label, pe))
    if mode == "auto":
        out = [t for t in out if t[2].weakly_identifiable or t[2].at_bound]
    return out


def profile_intervals(pb, res, solve, mode: str = "auto") -> tuple[dict, tuple[str, ...]]:
    """Profile intervals of ``res`` (a successful joint fit of ``pb``).

    ``solve(pb, hold, start_x) -> FitResult`` solves with ``{index: value}`` held. Returns
    ``({label: ReplacedInterval}, warnings)``.
    """
    if mode == "linear" or not res.success:
        return {}, ()
    cmin = float(res.cost)
    thr, how = lr_threshold(cmin, res.dof, pb.sigma_known)
    if not math.isfinite(thr):
        return {}, ()
    xhat = fit_vector(res)
    lo_b = np.concatenate([pb.bounds.lower, [b[0] for b in res.effect_bounds]])
    hi_b = np.concatenate([pb.bounds.upper, [b[1] for b in res.effect_bounds]])
    out, warnings = {}, []
    best: list[Any] = [cmin, None]  # the lowest cost seen and its vector (None: the fit's own)

    def cost_at(j, v, start):
        r = solve(pb, {j: v}, start)
        if not r.success:
            return None, None
        c = 0.5 * float(np.dot(r.weighted_residuals, r.weighted_residuals))
        x = fit_vector(r)
        if c < best[0] - 1e-9 * max(abs(best[0]), 1e-300) - 1e-12:
            best[0], best[1] = c, x
        return c, x

    for j, label, pe in _candidates(res, mode):
        val, b_lo, b_hi = float(xhat[j]), float(lo_b[j]), float(hi_b[j])
        tol = 1e-9 * (b_hi - b_lo)
        half = (pe.ci95[1] - pe.ci95[0]) / 2 if pe.ci95[0] is not None and pe.ci95[1] is not None else 0.0
        if not half > 0:
            half = 0.05 * (b_hi - b_lo)
        n_eval, notes, ends, opens = 0, [], [], []
        for sign, bound in ((-1.0, b_lo), (1.0, b_hi)):
            if abs(val - bound) <= max(tol, 1e-6 * (b_hi - b_lo)):
                ends.append(bound)
                opens.append(True)
                continue
            side = "lower" if sign < 0 else "upper"
            v_probe = val + sign * min(_PROBE_STEP * half, 0.5 * abs(bound - val))
            c_probe, _ = cost_at(j, v_probe, xhat)
            n_eval += 1
            if c_probe is None or c_probe - cmin > _PROBE_RTOL * (thr - cmin):
                lin_end = pe.ci95[0] if sign < 0 else pe.ci95[1]
                ends.append(float(lin_end) if lin_end is not None else bound)
                opens.append(lin_end is None)
                notes.append(
                    f"the {side} end is the linearised one: a profile solve a small step from the estimate "
                    + (
                        "failed"
                        if c_probe is None
                        else f"came back at cost {c_probe:.6g} against the minimum {cmin:.6g}"
                    )
                    + " (the solve left the profile's valley), so the profile could not be followed on that side"
                )
                continue
            in_v, in_c, in_x = val, cmin, xhat
            out_v: float | None = None
            out_c: float | None = None
            step = half
            failed = False
            for _ in range(_MAX_EXPAND):
                v = in_v + sign * step
                v = bound if sign * (v - bound) >= 0 else v
                c, x = cost_at(j, v, in_x)
                n_eval += 1
                if c is None:
                    failed = True
                    break
                if c > thr:
                    out_v, out_c = v, c
                    break
                in_v, in_c, in_x = v, c, x
                if v == bound:
                    break
                step *= 2.0
            if out_v is None or out_c is None:  # (both are set together)
                ends.append(bound if (not failed and in_v == bound) else in_v)
                opens.append(not failed and in_v == bound)
                if failed:
                    notes.append(
                        f"a profile solve failed on the {side} side: that end "
                        "is the last value the profile reached, a lower limit of the interval's width"
                    )
                elif in_v != bound:
                    notes.append(f"the {side} end was not reached in {_MAX_EXPAND} steps")
                continue
            for _ in range(_MAX_REFINE):
                if abs(out_c - thr) <= _COST_RTOL * (thr - cmin) or abs(in_c - thr) <= _COST_RTOL * (thr - cmin):
                    break
                t = (thr - in_c) / (out_c - in_c)
                t = min(max(t, 0.1), 0.9)  # safeguarded regula falsi
                v = in_v + t * (out_v - in_v)
                c, x = cost_at(j, v, in_x)
                n_eval += 1
                if c is None:
                    break
                if c <= thr:
                    in_v, in_c, in_x = v, c, x
                else:
                    out_v, out_c = v, c
            t = (thr - in_c) / (out_c - in_c) if out_c != in_c else 0.0
            ends.append(in_v + t * (out_v - in_v))
            opens.append(False)
        out[label] = ReplacedInterval(
            label, float(min(ends)), float(max(ends)), opens[0], opens[1], tuple(pe.ci95), n_eval, "; ".join(notes)
        )
    if best[1] is not None:
        warnings.append(
            f"the profile found a lower cost ({best[0]:.6g} against the fit's {cmin:.6g}) at "
            f"{np.array2string(best[1], precision=5)}: the fit's optimum is local, and its intervals "
            "are referred to it"
        )
    return out, tuple(warnings)


def with_profile_intervals(pb, res, solve, mode: str = "auto"):
    """``res`` with the profile intervals of ``mode`` in ``profile_intervals`` (and ``extra``)."""
    if mode == "linear":
        return res
    prof, warns = profile_intervals(pb, res, solve, mode)
    if not prof and not warns:
        return res
    extra = dict(res.extra)
    extra["profile_intervals"] = {k: v.to_dict() for k, v in prof.items()}
    return replace(res, replaced_intervals=prof, extra=extra, input_warnings=tuple(res.input_warnings) + warns)
