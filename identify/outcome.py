"""One outcome vocabulary and one set of honesty rules for every fit (DESIGN section 9).

Every fit - a track's slip sweep, a rig's drawbar sweep, a drive log, a rigid wheel's rig sweep, a
bevameter shear or plate test - ends in one :class:`Outcome`:

- ``usable``: the solver converged, something the user needs is determined, and the fit passes
  the lack-of-fit rules;
- ``poor_fit``: the model misses the data by more than their noise - lack of fit against the
  repeats' pure error (or, without repeats, against a stated noise) significant at
  :attr:`OutcomeSettings.lack_of_fit_level`, or a residual scale beyond the stated noise by
  :attr:`OutcomeSettings.noise_factor`;
- ``not_usable``: the solver converged but the answer fails the plausibility checks, or nothing
  the user needs (no parameter, no combination) is determined;
- ``failed``: the solver failed (no estimate).

Per parameter (:func:`identified`): a value on a bound (within :data:`BOUND_TOL` of the bound
range) is flagged and never called identified; a parameter whose 95 % interval spans more than
:attr:`OutcomeSettings.span_fraction` of its bound range is not identified. JSON carries
``outcome``, ``outcome_reason`` (null when usable) and ``running_gear`` (:func:`running_gear_json`);
the command line exits :func:`exit_code` (0 for ``usable``, 1 for the others). This module imports
no data kind and no result type (its distributions only when a test runs): each result type hands it
plain numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

__all__ = [
    "OUTCOMES",
    "OutcomeSettings",
    "OUTCOME_SETTINGS",
    "BOUND_TOL",
    "Outcome",
    "LackOfFitTest",
    "pure_error_f_test",
    "stated_noise_test",
    "decide_outcome",
    "identified",
    "interval_span_fraction",
    "on_bound",
    "running_gear_json",
    "outcome_lines",
    "exit_code",
]

#: The one vocabulary of a fit's outcome (JSON ``outcome``, the report's first line, the exit status).
OUTCOMES = ("usable", "poor_fit", "not_usable", "failed")

#: Distance to a bound, as a fraction of the bound range, within which a value is on the bound: the
#: library's one bound tolerance (track, wheel, bevameter; IPOPT's bound relaxation ends some 1e-8 of
#: the range inside a bound).
BOUND_TOL = 1e-5


@dataclass(frozen=True)
class OutcomeSettings:
    """The named settings of the outcome rules (one set for every kind of fit)."""

    lack_of_fit_level: float = 0.001
    """Level of the lack-of-fit tests (pure error, stated noise): a p-value below it is a poor fit.
    0.1 %, stricter than the textbook 5 %: a sweep's "repeats" are rows at nearly the same measured
    slip, and where the slip itself is noisy their scatter understates the noise on the steep part of
    the curve (a sweep simulated with the library's own model gave p = 0.008); the grousered wheel's
    p = 5e-5 and 4e-7 and a curve the model cannot follow (p < 1e-9) lie far below it."""
    noise_factor: float = 2.0
    """A residual scale beyond the stated noise by more than this factor is a poor fit, whatever the
    test says (a stated noise that far off is not the data's noise)."""
    span_fraction: float = 0.5
    """A parameter whose 95 % interval spans more than this fraction of its bound range is not
    identified ("most of its range": the data hardly narrow what the bounds already say)."""

    def __post_init__(self) -> None:
        if not 0.0 < self.lack_of_fit_level < 1.0:
            raise ValueError(f"lack_of_fit_level must lie in (0, 1), got {self.lack_of_fit_level!r}")
        if not self.noise_factor > 1.0:
            raise ValueError(f"noise_factor must exceed 1, got {self.noise_factor!r}")
        if not 0.0 < self.span_fraction <= 1.0:
            raise ValueError(f"span_fraction must lie in (0, 1], got {self.span_fraction!r}")


#: The settings every fit uses.
OUTCOME_SETTINGS = OutcomeSettings()


@dataclass(frozen=True)
class Outcome:
    """A fit's outcome (one of :data:`OUTCOMES`) and its reason (a sentence; None when usable)."""

    outcome: str
    reason: str | None = None

    def __post_init__(self) -> None:
        if self.outcome not in OUTCOMES:
            raise ValueError(f"outcome must be one of {OUTCOMES}, got {self.outcome!r}")

    @property
    def usable(self) -> bool:
        """Whether the outcome is ``usable``."""
        return self.outcome == "usable"

    def to_dict(self) -> dict[str, Any]:
        """``{"outcome", "outcome_reason"}`` for a fit's JSON."""
        return {"outcome": self.outcome, "outcome_reason": None if self.usable else self.reason}


@dataclass(frozen=True)
class LackOfFitTest:
    """A lack-of-fit test's result: what it tested against, the statistic, its p-value."""

    against: str
    statistic: float
    dof: tuple[int, ...]
    p_value: float

    def significant(self, settings: OutcomeSettings = OUTCOME_SETTINGS) -> bool:
        """p below the settings' :attr:`~OutcomeSettings.lack_of_fit_level`."""
        return self.p_value < settings.lack_of_fit_level


def pure_error_f_test(levels, residuals, n_params: int, *, compact: bool = False) -> LackOfFitTest | None:
    """The pure-error lack-of-fit F test of residuals grouped into repeated conditions.

    ``levels`` gives each row's condition (an integer label); the scatter of the residuals about
    their condition's mean is the pure error, the rest of the residual sum the lack of fit:
    ``F = (SS_lof / (g - p)) / (SS_pe / (n - g))``. ``None`` without ``g > p`` conditions, a
    repeat (``n > g``) and a non-zero pure error. ``compact``: the labels already are ``0 .. g - 1``,
    each used (as :func:`~soiltrack.identify.sweep.rig.slip_levels` gives them): not relabelled.
    """
    r = np.asarray(residuals, dtype=float).ravel()
    if compact:
        lab = np.asarray(levels).ravel()
    else:
        lab = np.unique(np.asarray(levels), return_inverse=True)[1].ravel()
    g, n = int(np.maximum.reduce(lab)) + 1 if lab.size else 0, r.size
    if g <= n_params or n <= g:
        return None
    counts = np.bincount(lab, minlength=g)
    means = np.bincount(lab, weights=r, minlength=g) / counts
    # (np.add.reduce: what np.sum runs, without its Python wrapper)
    ss_pure = float(np.add.reduce((r - means[lab]) ** 2))
    ss_lack = float(np.add.reduce(counts * means**2))
    if not ss_pure > 0:
        return None
    from .estimates.distributions import f_sf  # (imported here: the record's modules import this one)

    df_lack, df_pure = g - n_params, n - g
    F = (ss_lack / df_lack) / (ss_pure / df_pure)
    return LackOfFitTest("pure error of the repeats", F, (df_lack, df_pure), f_sf(F, df_lack, df_pure))


def stated_noise_test(weighted_ssr: float, dof: int) -> LackOfFitTest | None:
    """Chi-square test of the weighted residual sum (residuals over the stated noise) with ``dof``
    degrees of freedom; ``None`` without degrees of freedom or a finite sum."""
    if dof <= 0 or not math.isfinite(weighted_ssr):
        return None
    from .estimates.distributions import chi2_sf  # (imported here: the record's modules import this one)

    return LackOfFitTest("the stated noise", float(weighted_ssr), (int(dof),), chi2_sf(float(weighted_ssr), dof))


def decide_outcome(
    *,
    solver_ok: bool,
    failure: str = "",
    refusals: Sequence[str] = (),
    determined: Sequence[str] = (),
    lack_of_fit: LackOfFitTest | None = None,
    noise_ratio: float | None = None,
    settings: OutcomeSettings = OUTCOME_SETTINGS,
) -> Outcome:
    """The one rule from a fit's facts to its :class:`Outcome`.

    Parameters
    ----------
    solver_ok
        The solver converged to finite numbers.
    failure
        Why it did not (for ``failed``).
    refusals
        Plausibility checks the answer fails (each a sentence): ``not_usable``.
    determined
        Names of what the data determine (identified parameters and combinations): none is
        ``not_usable``.
    lack_of_fit
        The lack-of-fit test (pure error, else the stated noise), or None when not testable.
    noise_ratio
        Residual scale over the stated noise (None without a stated noise).
    settings
        The named levels.
    """
    if not solver_ok:
        return Outcome("failed", f"the solver failed: {failure or 'no estimate'}")
    if refusals:
        return Outcome("not_usable", "the answer fails the plausibility checks: " + "; ".join(refusals))
    if not determined:
        return Outcome("not_usable", "the data determine none of the parameters or their combinations")
    if lack_of_fit is not None and lack_of_fit.significant(settings):
        return Outcome(
            "poor_fit",
            f"lack of fit against {lack_of_fit.against}: p = {lack_of_fit.p_value:.2g} < "
            f"{settings.lack_of_fit_level:g} (statistic {lack_of_fit.statistic:.4g}, dof "
            f"{', '.join(str(d) for d in lack_of_fit.dof)}): the model misses the data by more than their noise",
        )
    if noise_ratio is not None and math.isfinite(noise_ratio) and noise_ratio > settings.noise_factor:
        return Outcome(
            "poor_fit",
            f"the residuals' scale is {noise_ratio:.3g} times the stated noise (more than "
            f"{settings.noise_factor:g} times): the model or the stated noise is wrong",
        )
    return Outcome("usable", None)


def on_bound(value: float, lower: float, upper: float) -> str | None:
    """``"lower"``/``"upper"`` when ``value`` lies within :data:`BOUND_TOL` of the bound range of a
    bound, else None (infinite ranges: an absolute tolerance of :data:`BOUND_TOL`)."""
    span = upper - lower
    tol = BOUND_TOL * span if math.isfinite(span) and span > 0 else BOUND_TOL
    if value - lower <= tol:
        return "lower"
    if upper - value <= tol:
        return "upper"
    return None


def interval_span_fraction(ci95, lower: float, upper: float) -> float | None:
    """Width of the 95 % interval over the bound range (None when either is unavailable)."""
    lo, hi = ci95
    span = upper - lower
    if lo is None or hi is None or not (math.isfinite(span) and span > 0):
        return None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return None
    return float((hi - lo) / span)


def identified(
    *,
    identifiable: bool,
    at_bound: bool,
    ci95,
    lower: float,
    upper: float,
    settings: OutcomeSettings = OUTCOME_SETTINGS,
) -> tuple[bool, str]:
    """Whether a parameter is identified, and why not (empty when it is).

    Identified: identifiable from the data, not on a bound, and its 95 % interval spans at most
    :attr:`OutcomeSettings.span_fraction` of its bound range (``ci95``, ``lower``, ``upper`` in one unit).
    """
    if not identifiable:
        return False, "not identifiable from these data"
    if at_bound:
        return False, "on a bound: its interval is not reliable"
    frac = interval_span_fraction(ci95, lower, upper)
    if frac is None:
        return False, "no interval"
    if frac > settings.span_fraction:
        return False, (
            f"its 95 % interval spans {100 * frac:.0f} % of its bound range "
            f"(more than {100 * settings.span_fraction:.0f} %)"
        )
    return True, ""


def running_gear_json(
    kind: str,
    *,
    name: str | None = None,
    weight_N: float | None = None,
    contact_area_m2: float | None = None,
    track_length_m: float | None = None,
    wheel_radius_m: float | None = None,
    wheel_width_m: float | None = None,
) -> dict[str, Any]:
    """The ``running_gear`` object of a fit's JSON: ``kind`` (``track``, ``rigid_wheel``,
    ``bevameter``), ``name``, ``weight_N`` (None for a rig: its load is per row) and the geometry keys
    that apply to the kind."""
    if kind not in ("track", "rigid_wheel", "bevameter"):
        raise ValueError(f"running gear kind must be track, rigid_wheel or bevameter, got {kind!r}")
    out: dict[str, Any] = {"kind": kind, "name": name, "weight_N": _num(weight_N)}
    if kind == "track":
        out.update(contact_area_m2=_num(contact_area_m2), track_length_m=_num(track_length_m))
    elif kind == "rigid_wheel":
        out.update(wheel_radius_m=_num(wheel_radius_m), wheel_width_m=_num(wheel_width_m))
    elif contact_area_m2 is not None:
        out["contact_area_m2"] = _num(contact_area_m2)
    return out


def outcome_lines(outcome: Outcome, *, determined: Sequence[str] = (), not_identified: Sequence[str] = ()) -> list[str]:
    """The first lines of every report: the outcome and its reason, then (when given) what the data
    determine and what they do not."""
    head = "outcome: usable" if outcome.usable else f"outcome: {outcome.outcome.upper()} - {outcome.reason}"
    out = [head]
    if determined:
        out.append("  determined: " + ", ".join(determined))
    if not_identified:
        out.append("  NOT identified: " + ", ".join(not_identified))
    return out


def exit_code(outcome: Outcome) -> int:
    """The command line's exit status: 0 for ``usable``, 1 for the others (the report is printed)."""
    return 0 if outcome.usable else 1


def _num(x) -> float | None:
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None
