"""The result of a diagnosis: :class:`Diagnosis` (report, JSON, figure) and its :class:`RankEntry` rows.

The JSON object is the command line's contract (``soiltrack diagnose --json``): ``verdict``,
``confidence`` (the verdict's ``weight`` in ``ranking``; for ``unexplained`` the summed weight of the
hypotheses outside the candidates), ``cause`` with what names it (``lag_s``, ``window_s``, ...),
``ranking``, ``confusable``, ``localisation``, ``shrink``, ``soil_before``, ``soil_after``, and the
gap tests the decision used. Never NaN: null instead.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

from .fits import finite
from .gap import Segment
from .gap_test import GapDecision
from .hold import HoldChoice
from .plot import plot_diagnosis
from .report import report_text
from .screening import Screen

__all__ = ["RankEntry", "Excluded", "Diagnosis"]


@dataclass(frozen=True)
class RankEntry:
    """One admissible hypothesis in the comparison.

    Attributes
    ----------
    effect
        ``"none"``, an effect, ``"discrepancy"`` or an outside cause.
    family
        ``nominal``, ``candidate``, ``flexible`` or ``outside``.
    weight
        Its weight in the one comparison (the weights sum to 1); effects the data cannot tell apart
        (``confusable``) share their summed weight evenly.
    evidence_weight
        Its weight from the evidence alone, before a confusable group shares it (None when not
        computed).
    n_params
        Parameters it adds to the nominal soil.
    holdout_rmse_before, holdout_rmse_after
        Held-out RMS per channel of the nominal model and of this hypothesis (channel's unit).
    shrink
        ``1 - after/before`` of the noise-standardised held-out RMS over the channels (None for
        ``none`` and where it was not held out).
    explained
        Share of the nominal excess error over the noise it removes on the evidence's samples.
    parameters, detail
        Its fitted parameters; what names an outside cause.
    """

    effect: str
    family: str
    weight: float
    n_params: int
    holdout_rmse_before: dict[str, float]
    holdout_rmse_after: dict[str, float]
    shrink: float | None
    explained: float | None
    parameters: dict
    detail: dict = field(default_factory=dict)
    evidence_weight: float | None = None

    def to_dict(self) -> dict:
        """The JSON entry."""
        return {
            "effect": self.effect,
            "family": self.family,
            "weight": float(self.weight),
            "evidence_weight": finite(self.evidence_weight),
            "n_params": int(self.n_params),
            "holdout_rmse_before": {k: finite(v) for k, v in self.holdout_rmse_before.items()},
            "holdout_rmse_after": {k: finite(v) for k, v in self.holdout_rmse_after.items()},
            "shrink": finite(self.shrink),
            "explained": finite(self.explained),
            "parameters": self.parameters,
            "detail": self.detail,
        }


@dataclass(frozen=True)
class Excluded:
    """A hypothesis that left the comparison (inadmissible or not formed), and why."""

    name: str
    family: str
    why: str

    def to_dict(self) -> dict:
        """The JSON entry."""
        return {"effect": self.name, "family": self.family, "why": self.why}


@dataclass(frozen=True, eq=False)
class Diagnosis:
    """Outcome of :func:`~.diagnose.diagnose`. Read :meth:`report`; :meth:`to_json` is the CLI contract.

    Attributes
    ----------
    verdict, confidence, reason
        An effect name, ``"none"`` or ``"unexplained"``; its weight in ``ranking`` (``unexplained``:
        the summed weight outside the candidates); the rule that decided, with its numbers.
    cause, cause_detail
        The outside cause named by an ``unexplained`` verdict (``"delay"``, ``"terrain_change"``, ...)
        and what names it (``lag_s``, ``window_s``, ...); None and ``{}`` otherwise.
    ranking, excluded
        The admissible hypotheses, heaviest first; those that left the comparison, with why.
    evidence
        How the weights were computed.
    gap
        The gap tests with their p-values and levels.
    screens
        The score test of every library effect (which were refitted).
    confusable
        A :class:`~.decision.ConfusablePair` per pair the data cannot tell apart.
    localisation
        Where the nominal misfit lies (:class:`~.gap.Segment`, by share).
    noise
        Noise floor per channel.
    holdout_rmse_before, holdout_rmse_after, shrink, explained
        Held-out RMS before and after the verdict's hypothesis; its shrink; its share of the excess.
    soil_before, soil_after
        The nominal soil and the soil with the verdict's effect (None for ``none`` and ``unexplained``).
    converged
        Whether the fits the verdict rests on converged.
    torque_hold
        A drive log's torque hold: given, or chosen on the held-out blocks (:mod:`.hold`); None for
        a sweep.
    lone_readings
        Per residual channel, the rows left out of the evidence and the gap tests as lone readings
        far off both neighbours (a glitch; :func:`~.gap.isolated_outliers`). On a drive log the
        residual at row k is the step from row k - 1: a torque glitch at row k shows at k + 1.
    """

    data_kind: str
    n_samples: int
    candidates: tuple[str, ...]
    verdict: str
    confidence: float
    reason: str
    cause: str | None
    cause_detail: dict
    ranking: tuple[RankEntry, ...]
    excluded: tuple[Excluded, ...]
    evidence: str
    gap: GapDecision
    screens: tuple[Screen, ...]
    confusable: tuple
    localisation: tuple[Segment, ...]
    noise: dict
    holdout_rmse_before: dict
    holdout_rmse_after: dict | None
    shrink: float | None
    explained: float | None
    soil_before: dict
    soil_after: dict | None
    converged: bool
    notes: tuple[str, ...] = ()
    torque_hold: HoldChoice | None = None
    elapsed_s: float = 0.0
    curves: dict = field(default_factory=dict, repr=False)
    sinkage: Any = None
    lone_readings: dict = field(default_factory=dict)

    def weight_of(self, name: str) -> float:
        """Weight of hypothesis ``name`` in the ranking (0 when absent)."""
        return next((e.weight for e in self.ranking if e.effect == name), 0.0)

    def to_dict(self) -> dict:
        """The JSON object (never NaN: null instead)."""
        out: dict[str, Any] = {
            "verdict": self.verdict,
            "confidence": float(self.confidence),
            "cause": self.cause,
        }
        out.update(self.cause_detail)
        out.update(
            {
                "reason": self.reason,
                "ranking": [e.to_dict() for e in self.ranking],
                "excluded": [e.to_dict() for e in self.excluded],
                "evidence": self.evidence,
                "gap_tests": [t.to_dict() for t in self.gap.tests],
                "gap": bool(self.gap.present),
                "confusable": [list(c.effects) for c in self.confusable],
                "confusable_detail": [
                    {
                        "effects": list(c.effects),
                        "correlation": finite(c.correlation),
                        "separation_se": finite(c.separation),
                        "experiment": c.experiment,
                    }
                    for c in self.confusable
                ],
                "localisation": [s.to_dict() for s in self.localisation],
                "lone_readings": {ch: [int(r) for r in rows] for ch, rows in self.lone_readings.items()},
                "shrink": finite(self.shrink),
                "explained": finite(self.explained),
                "holdout_rmse_before": {k: finite(v) for k, v in self.holdout_rmse_before.items()},
                "holdout_rmse_after": None
                if self.holdout_rmse_after is None
                else {k: finite(v) for k, v in self.holdout_rmse_after.items()},
                "noise_floor": {k: finite(v) for k, v in self.noise.items()},
                "soil_before": self.soil_before,
                "soil_after": self.soil_after,
                "screening": [s.to_dict() for s in self.screens],
                "data_kind": self.data_kind,
                "n_samples": int(self.n_samples),
                "candidates": list(self.candidates),
                "residual_sign": "measured - model",
                "torque_hold": None if self.torque_hold is None else self.torque_hold.hold,
                "torque_hold_choice": None if self.torque_hold is None else self.torque_hold.to_dict(),
                "converged": bool(self.converged),
                "sinkage_evidence": None if self.sinkage is None else self.sinkage.to_dict(),
                "notes": list(self.notes),
                "elapsed_s": finite(self.elapsed_s),
            }
        )
        return out

    def to_json(self, indent: int | None = 2) -> str:
        """:meth:`to_dict` as JSON."""
        return json.dumps(self.to_dict(), indent=indent, allow_nan=False)

    def report(self) -> str:
        """A plain-words report (:func:`~.report.report_text`)."""
        return report_text(self)

    def plot(self, path: str) -> str:
        """Save the figure (:func:`~.plot.plot_diagnosis`) and return its path."""
        return plot_diagnosis(self, path)
