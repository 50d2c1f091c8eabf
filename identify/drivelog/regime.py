"""Gentle versus hard driving: what a drive log pins down, said in plain words.

At small slip ``F ~ F_max l i / (2 K)``: a log whose thrust stays well below ``F_max`` pins
down only this initial slope. :func:`classify_regime` calls a log ``"gentle"`` (correlation of
the F_max and K estimates >= 0.99, or F_max standard error >= 25 %, or F_max on a bound, or K on a bound
while F_max is not pinned within 5 %: F_max's interval is then the one of K held at the bound, not a valid
interval),
``"hard"`` (F_max within 5 % and K within 25 % standard error) or ``"intermediate"``, and
writes the warning that says which experiment would help.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...soilmodel.units import format_force
from .profile_check import PROFILE_MIN_RISE

__all__ = ["classify_regime", "GENTLE_CORRELATION", "GENTLE_REL_STDERR", "HARD_REL_STDERR", "K_REL_STDERR"]

#: Correlation of the F_max and K estimates above which a log is "gentle" (only the slope).
GENTLE_CORRELATION = 0.99
#: Relative standard error of F_max above which F_max is called undetermined.
GENTLE_REL_STDERR = 0.25
#: Relative standard error of F_max below which F_max counts as pinned down (a "hard" pull).
HARD_REL_STDERR = 0.05
#: Relative standard error of K below which K counts as pinned down (with F_max: a "hard" pull).
K_REL_STDERR = 0.25


def classify_regime(
    Fmax: float,
    K: float,
    l: float,
    cov2: np.ndarray | None,
    at_bound: list[str],
    thrust_peak: float,
    utilisation: float,
    n_high: int,
    *,
    profile_rise: tuple[float, float] | None = None,
) -> tuple[str, dict[str, Any], list[str]]:
    """Driving regime of a fitted log, the statistics behind it and its warnings.

    Parameters
    ----------
    Fmax, K, l
        Fitted thrust limit (N), shear modulus (m) and track length (m).
    cov2
        Covariance of ``(F_max, K)`` or ``None`` when it does not exist.
    at_bound
        Names (``"F_max"``, ``"K"``) of the estimates on a bound.
    thrust_peak, utilisation, n_high
        Largest thrust the log certainly reached (N), its ratio to ``Fmax``, and the number of
        samples above 70 % of ``Fmax``.
    profile_rise
        Rise of the profiled cost at ``F_max -+ 2 SE`` (:func:`~.profile_check.profile_flatness`; 4 where the
        standard error holds); below :data:`~.profile_check.PROFILE_MIN_RISE` on a side the log is "gentle":
        F_max's likelihood is far wider than its standard error (``extra["regime_reason"]`` says so).

    Returns
    -------
    regime, extra, warnings
        ``"gentle"``, ``"intermediate"`` or ``"hard"``; entries for ``FitResult.extra``
        (standard errors, correlation, slope standard error, ``regime``, and ``note`` for a
        hard log); warnings for the report.
    """
    extra: dict[str, Any] = {}
    warnings: list[str] = []
    corr, s_slope, relF, relK = float("nan"), float("nan"), float("inf"), float("inf")
    cov_ok = cov2 is not None
    if cov2 is not None:
        sF, sK = math.sqrt(cov2[0, 0]), math.sqrt(cov2[1, 1])
        corr = float(cov2[0, 1] / (sF * sK))
        gslope = np.array([l / (2 * K), -Fmax * l / (2 * K * K)])
        s_slope = float(math.sqrt(max(gslope @ cov2 @ gslope, 0.0)))
        relF, relK = sF / Fmax, sK / K
        extra.update(
            {
                "max_thrust_stderr_N": sF,
                "shear_modulus_stderr_m": sK,
                "corr_max_thrust_shear_modulus": corr,
                "initial_slope_stderr_N": s_slope,
            }
        )
    # K on a bound: F_max's interval is conditional on K held there; only a pinned-down F_max survives it
    k_held = "K" in at_bound and not relF <= HARD_REL_STDERR
    flat = profile_rise is not None and min(profile_rise) < PROFILE_MIN_RISE
    if profile_rise is not None:
        extra["profile_rise"] = [float(x) for x in profile_rise]
    if flat and profile_rise is not None:
        extra["regime_reason"] = (
            f"F_max's likelihood is far wider than its standard error: with K re-fitted the cost rises by only "
            f"{min(profile_rise):.2g} (4 expected) at F_max -+ 2 SE, so no interval of F_max is valid"
        )
    if (
        flat
        or not cov_ok
        or abs(corr) >= GENTLE_CORRELATION
        or relF >= GENTLE_REL_STDERR
        or "F_max" in at_bound
        or k_held
    ):
        regime = "gentle"
    elif relF <= HARD_REL_STDERR and relK <= K_REL_STDERR and "K" not in at_bound:
        regime = "hard"
    else:
        regime = "intermediate"
    extra["regime"] = regime

    stats = _RegimeStats(Fmax, K, l, corr, s_slope, relF, relK, thrust_peak, utilisation, n_high, at_bound)
    warnings.extend(_regime_warnings(regime, flat, stats, extra))
    if at_bound:
        warnings.append(
            f"{' and '.join(at_bound)} ended on the bound implied by the soil ranges: "
            f"the data or the bounds are questionable"
        )

    return regime, extra, warnings


@dataclass(frozen=True)
class _RegimeStats:
    """What the regime's warnings quote."""

    Fmax: float  #: fitted thrust limit, N
    K: float  #: fitted shear modulus, m
    l: float  #: track length, m
    corr: float  #: correlation of the F_max and K estimates
    s_slope: float  #: standard error of the initial slope, N
    relF: float  #: relative standard error of F_max
    relK: float  #: relative standard error of K
    thrust_peak: float  #: largest thrust the log certainly reached, N
    utilisation: float  #: thrust_peak / F_max
    n_high: int  #: samples above 70 % of F_max
    at_bound: list[str]  #: estimates on a bound


def _regime_warnings(regime: str, flat: bool, st: _RegimeStats, extra: dict[str, Any]) -> list[str]:
    """The report's warnings for a regime (and the hard pull's ``extra["note"]``)."""
    Fmax, K, l, corr, s_slope, relF, relK = st.Fmax, st.K, st.l, st.corr, st.s_slope, st.relF, st.relK
    thrust_peak, utilisation, n_high, at_bound = st.thrust_peak, st.utilisation, st.n_high, st.at_bound
    out: list[str] = []
    slope = Fmax * l / (2 * K)
    slope_se = f" (SE {format_force(s_slope)})" if math.isfinite(s_slope) else ""
    slope_txt = f"F_max l/(2K) = {format_force(slope)}{slope_se} (thrust per unit slip at small slip)"
    pct = _percent
    if flat:
        out.append(
            f"{extra['regime_reason']}; the largest thrust in this log is about {format_force(thrust_peak)} "
            f"(e.g. a start from rest: large thrust at speeds whose slip the log hardly measures). Only the initial "
            f"slope {slope_txt} is reported. To identify F_max, drive a hard pull near the traction limit"
        )
    elif regime == "gentle":
        out.append(
            f"gentle driving: the largest thrust in this log is about {format_force(thrust_peak)}, well "
            f"below the soil's thrust limit, so the log only shows the initial slope {slope_txt}; F_max and K "
            f"are not separable (correlation of their estimates {corr:.3f}, standard error of F_max {pct(relF)}). "
            f"To identify them, drive a hard pull near the traction limit (e.g. a hard acceleration from low "
            f"speed, a drawbar pull or a climb)"
        )
    elif regime == "intermediate" and relF <= HARD_REL_STDERR:
        i_lo, i_hi = K / l, 10 * K / l
        out.append(
            f"the log reaches the traction limit (F_max = {format_force(Fmax)}, SE {pct(relF)}), but K is "
            f"poorly determined (standard error {pct(relK)}{', on a bound' if 'K' in at_bound else ''}): the "
            f"samples sit either near zero slip or at full track spin, with few in between ({n_high} samples "
            f"above 70 % of F_max). The best determined small-slip quantity is the initial slope {slope_txt}. "
            f"A sustained pull at 50-90 % of the traction limit (slip about {i_lo:.3g} to {i_hi:.3g}) would pin K down"
        )
    elif regime == "intermediate":
        out.append(
            f"F_max and K are only partly separated (correlation {corr:.3f}, standard errors: F_max {pct(relF)}, "
            f"K {pct(relK)}); the largest thrust seen is about {format_force(thrust_peak)}. The best "
            f"determined quantity is the initial slope {slope_txt}. A harder pull, nearer the traction limit, "
            f"would pin F_max and K down"
        )
    else:
        extra["note"] = (
            f"hard pull: the thrust reached about {pct(utilisation)} of the fitted limit; F_max and K "
            f"are separated (correlation {corr:.3f}, standard errors: F_max {pct(relF)}, K {pct(relK)})"
        )
    return out


def _percent(x: float) -> str:
    """A share as a percentage in plain digits: ``"96 %"``, ``"102 %"``, ``"6.2 %"``, ``"0.76 %"``."""
    if not math.isfinite(x):
        return "undetermined"
    p = 100 * x
    return f"{p:.0f} %" if abs(p) >= 10 else f"{p:.2g} %"
