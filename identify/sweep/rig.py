"""Rig sweeps as rigs record them: row weights, the load as a covariate, repeats, what was dropped.

A single-track or single-wheel rig measures at set slips with a normal load that varies from
row to row, repeats each condition, and logs each reading's standard deviation and the
sinkage. This module turns those columns into what a fit reports:

- **weights**: a ``tractive_force_std_N`` / ``drawbar_pull_std_N`` column weighs each row by
  ``1 / std^2``. The std of a reading over its averaging window is a spread, not the error of
  the mean, so these are relative weights: their level is estimated from the residuals.
- **c-phi separation**: c and phi separate only through the load's spread
  (``F_max = A c + W tan(phi)``). When the spread is small (:data:`LOAD_SPREAD_SMALL`) or the
  load moves with the slip (:data:`LOAD_SLIP_CORRELATION`), the report says that the
  separation rests on it, and the intervals of c and phi come from the profile likelihood.
- **pure-error lack of fit**: rows at one slip (within :data:`SLIP_REPEAT_TOL`) are repeats of
  one condition. The scatter of their weighted residuals about their mean is the pure error
  (the model's load dependence is already in the residuals); the rest of the residual sum is
  lack of fit. ``F = (SS_lof / (g - p)) / (SS_pe / (n - g))`` with g slip levels and p
  identified directions, and its p-value.
- what was dropped when reading (``--driving-only``, ``--slip-angle 0``) and the measured
  sinkage: the Bekker and slip-sinkage laws fitted to it (:mod:`.sinkage_channel`: n and
  k_c / b + k_phi where the loads spread, the slip exponent and its tests), and, when the thrust
  fit has the ``slip_sinkage`` effect, the slip coefficient Bekker compaction of the measured ruts
  implies beside the fit's (the track model's resistance itself uses the sinkage only with
  ``resistance="fit-sinkage"``).
"""

from __future__ import annotations

from dataclasses import dataclass

import math

import numpy as np

from ...soilmodel.data import STD_COLUMNS, SlipData
from ...soilmodel.ridge import distinct_loads
from ..outcome import OUTCOME_SETTINGS, pure_error_f_test
from .sinkage_channel import compare_slip_resistance, fit_sinkage_channel
from ..estimates.records import LOAD_SLIP_CORRELATION, LOAD_SPREAD_SMALL, LoadSeparation

__all__ = [
    "LOAD_SPREAD_SMALL",
    "LOAD_SLIP_CORRELATION",
    "SLIP_REPEAT_TOL",
    "repeat_free",
    "LACK_OF_FIT_ALPHA",
    "LoadSeparation",
    "LackOfFit",
    "std_weights",
    "load_separation",
    "pure_error_test",
    "rig_extra",
]

#: Rows whose slips differ by at most this are repeats of one condition.
SLIP_REPEAT_TOL = 0.005
#: Level of the lack-of-fit test's verdict: the outcome rules' one level
#: (:attr:`soiltrack.identify.outcome.OutcomeSettings.lack_of_fit_level`; it was 5 % before).
LACK_OF_FIT_ALPHA = OUTCOME_SETTINGS.lack_of_fit_level


@dataclass(frozen=True)
class LackOfFit:
    """The pure-error lack-of-fit test of a sweep with repeated slips.

    Attributes
    ----------
    levels, repeats
        Slip levels and rows in them (repeats are rows beyond the first of a level).
    df_lack, df_pure
        Degrees of freedom ``g - p`` and ``n - g``.
    F, p_value
        The statistic and its p-value (F distribution).
    """

    levels: int
    repeats: int
    df_lack: int
    df_pure: int
    F: float
    p_value: float

    @property
    def significant(self) -> bool:
        """The model misses the level means by more than the repeats scatter (at :data:`LACK_OF_FIT_ALPHA`)."""
        return self.p_value < LACK_OF_FIT_ALPHA

    def statement(self) -> str:
        """Plain words."""
        verdict = (
            "the model misses the means of the slip levels by more than the repeats scatter"
            if self.significant
            else "no lack of fit beyond the repeats' scatter"
        )
        return (
            f"pure-error test over {self.levels} slip levels with repeats: F = {self.F:.3g} "
            f"({self.df_lack}, {self.df_pure} dof), p = {self.p_value:.3g}: {verdict}"
        )

    def to_dict(self) -> dict:
        """JSON-ready."""
        return {
            "levels": self.levels,
            "repeats": self.repeats,
            "df_lack": self.df_lack,
            "df_pure": self.df_pure,
            "F": self.F,
            "p_value": self.p_value,
            "significant": self.significant,
            "statement": self.statement(),
        }


def std_weights(data: SlipData) -> np.ndarray | None:
    """The per-row standard deviation column as the fit's sigma (relative weights), or ``None``."""
    return None if data.force_std is None else np.asarray(data.force_std, dtype=float)


def load_separation(data: SlipData) -> LoadSeparation | None:
    """The load's spread and its correlation with the slip, for sweeps at two or more loads."""
    if data.normal_load is None or distinct_loads(data.normal_load).size < 2:
        return None
    W, s = np.asarray(data.normal_load, dtype=float), np.asarray(data.slip, dtype=float)
    spread = float((W.max() - W.min()) / np.median(W))
    corr = float(np.corrcoef(W, s)[0, 1]) if np.std(s) > 0 else 0.0
    fragile = spread < LOAD_SPREAD_SMALL or abs(corr) > LOAD_SLIP_CORRELATION
    return LoadSeparation(spread, corr, fragile)


def slip_levels(slip) -> np.ndarray:
    """Level index of each row: slips within :data:`SLIP_REPEAT_TOL` of the level's first (sorted) slip."""
    s = np.asarray(slip, dtype=float)
    order = np.argsort(s, kind="stable")
    labels: list[int] = []
    k, start = -1, -math.inf
    for v in s[order].tolist():  # (Python floats: the same arithmetic as numpy's, without its per-item cost)
        if v - start > SLIP_REPEAT_TOL:
            k, start = k + 1, v
        labels.append(k)
    level = np.empty(s.size, dtype=int)
    level[order] = labels
    return level


def repeat_free(slips: np.ndarray) -> np.ndarray:
    """Per dataset (a row of ``slips``, datasets x samples): True when every sample is a slip level of its own
    (:func:`slip_levels`: each sorted slip more than :data:`SLIP_REPEAT_TOL` beyond the one before), so that
    :func:`pure_error_test` has no repeat to test; for many datasets at once."""
    s = np.sort(np.asarray(slips, dtype=float), axis=1)
    return np.all(s[:, 1:] - s[:, :-1] > SLIP_REPEAT_TOL, axis=1)


def pure_error_test(slip, weighted_residuals, n_params: int) -> LackOfFit | None:
    """The pure-error lack-of-fit test, or ``None`` without enough repeats and levels.

    Needs ``g > p`` slip levels and ``n > g`` rows (at least one repeat), and a non-zero pure error.
    """
    label = slip_levels(slip)
    if label.size == 0 or int(np.maximum.reduce(label)) + 1 >= np.size(weighted_residuals):  # no repeats
        return None
    t = pure_error_f_test(label, weighted_residuals, n_params, compact=True)
    if t is None:
        return None
    df_lack, df_pure = t.dof
    levels = df_lack + n_params
    return LackOfFit(levels, df_pure, df_lack, df_pure, t.statistic, t.p_value)


def rig_extra(data: SlipData, result, separation: LoadSeparation | None, *, no_repeats: bool = False) -> dict:
    """The entries a rig sweep adds to ``FitResult.extra`` (empty for a plain sweep).

    ``no_repeats``: the caller found (:func:`repeat_free`, for a batch at once) that no slip repeats, so the
    pure-error test has nothing to test and is not run.
    """
    out: dict = {}
    if data.dropped:
        out["dropped_rows"] = [
            {"reason": reason, "option": option, "count": len(rows), "rows": list(rows)}
            for reason, option, rows in data.dropped
        ]
    if data.force_std is not None:
        out["weights_from"] = STD_COLUMNS[data.measured]
    if data.sinkage is not None:
        z, s = np.asarray(data.sinkage, dtype=float), np.asarray(data.slip, dtype=float)
        corr = float(np.corrcoef(z, s)[0, 1]) if np.std(z) > 0 and np.std(s) > 0 else 0.0
        channel = fit_sinkage_channel(data, result.vehicle)
        laws = None if channel is None else channel.to_dict()
        mu_s = (result.effects.get("slip_sinkage") or {}).get("mu_s") if result.effects else None
        if channel is not None and laws is not None and mu_s is not None and not mu_s.fixed:
            laws["slip_sinkage_effect"] = compare_slip_resistance(channel, data, result.vehicle, mu_s)
        out["sinkage_m"] = {"min": float(z.min()), "max": float(z.max()), "slip_correlation": corr, "laws": laws}
    if separation is not None and result.model == "full":
        out["load_separation"] = separation.to_dict()
    if result.success and not no_repeats:  # (the free parameters' count: no statistic of the result is computed here)
        lof = pure_error_test(data.slip, result.weighted_residuals, len(result.free))
        if lof is not None:
            out["lack_of_fit"] = lof.to_dict()
    return out
