"""The one decision rule: the verdict, its confidence, the cause, what cannot be told apart.

Given the weights of the admissible hypotheses (:mod:`.evidence`) and the gap tests
(:mod:`.gap_test`):

1. No gap: the verdict is ``none``.
2. A gap, and the heaviest hypothesis is a candidate effect that explains it: that effect. It
   explains the gap when it removes at least ``min_explained`` of the nominal model's excess error
   over the noise on the samples it changes (its support: the whole run for an effect, the window
   for a change of terrain); where the nominal model shows no excess there, it explains nothing.
   A group of confusable hypotheses with measured collinear sensitivities is tested as one, as it is
   weighed as one: it explains the gap when one of its members does.
3. A gap, and the heaviest is a candidate that does not explain it, the flexible term, or a cause
   outside the library (or an effect the user left out of the candidates): ``unexplained``, with
   the cause named when the heaviest is one and it explains the gap (the same test).
4. A gap, and the heaviest is the nominal model: ``none``.

The confidence is the verdict's weight as it stands in the ranking; for ``unexplained`` the summed
weight of the hypotheses outside the candidates (the flexible term and the outside causes); for
``none`` the weight of the no-gap hypothesis in the same comparison: the nominal model's together
with that of every hypothesis the evidence does not tell from it (their difference of evidence within
``confusable_separation`` of its standard errors: an effect fitted to no gap describes the data as
the nominal model does, and the weights spread over such nested hypotheses are the nominal
model's). Without that, an effect-free sweep whose nominal weight is shared with a dozen effects that
fit it as well would print ``none`` with a confidence near zero. Effects
whose weights are close and whose sensitivities are collinear are ``confusable``, each pair with the
experiment that separates them; such a group shares its summed weight evenly before the verdict is
drawn (:func:`share_confusable`: the data name the group, not a member), so the confidence is the
shared weight, as the ranking prints it, and no cap is needed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

from .gap_test import GapDecision
from .hypotheses import NOMINAL, Hypothesis
from .selection import confusable_groups, separating_experiment, shared_weights
from .settings import DiagnoseSettings

__all__ = [
    "ConfusablePair",
    "Decision",
    "SharedWeights",
    "decide",
    "share_confusable",
    "no_gap_weight",
    "UNEXPLAINED",
]

UNEXPLAINED = "unexplained"


class ConfusablePair(NamedTuple):
    """Two hypotheses the data cannot tell apart (:func:`share_confusable`).

    Attributes
    ----------
    effects
        The two names.
    correlation
        ``|corr|`` of their sensitivity directions (NaN when one is unknown: the flexible term).
    separation
        Their difference of evidence in its standard errors when that made them confusable (below
        ``confusable_separation``, whatever their weights); NaN when their close weights did.
    experiment
        The experiment that separates them.
    """

    effects: tuple[str, ...]
    correlation: float
    separation: float
    experiment: str


@dataclass(frozen=True)
class Decision:
    """The outcome of :func:`decide`.

    Attributes
    ----------
    verdict
        An effect name, ``"none"`` or ``"unexplained"``.
    confidence
        The verdict's weight (``unexplained``: the summed weight outside the candidates).
    heaviest
        The hypothesis with the largest weight.
    explained
        Share of the nominal excess error the heaviest removes (None when not computed).
    cause, cause_detail
        The outside cause that carries the gap (``unexplained`` only), and what names it.
    reason
        The rule that decided, with its numbers.
    confusable
        A :class:`ConfusablePair` per pair of effects the data cannot tell apart.
    """

    verdict: str
    confidence: float
    heaviest: str
    explained: float | None
    cause: str | None
    reason: str
    cause_detail: dict = field(default_factory=dict)
    confusable: tuple = ()


def _pairs(
    hyps: list[Hypothesis],
    weights: dict[str, float],
    directions: dict,
    s: DiagnoseSettings,
    separation: Callable[[Hypothesis, Hypothesis], float] | None,
) -> list[tuple[tuple[str, ...], float, float]]:
    """Pairs of hypotheses with a known sensitivity (and the flexible term: it can follow any smooth gap, its
    direction is unknown) that the evidence does not tell apart and whose sensitivities are collinear."""
    by_name = {h.name: h for h in hyps}
    lib = {h.name: weights[h.name] for h in hyps if h.name in directions or h.family == "flexible"}
    return confusable_groups(
        lib,
        directions,
        min_ratio=s.confusable_ratio,
        min_corr=s.confusable_corr,
        min_weight=s.confusable_weight,
        separation=None if separation is None else (lambda a, b: separation(by_name[a], by_name[b])),
        max_separation=s.confusable_separation,
    )


@dataclass(frozen=True)
class SharedWeights:
    """The weights after each group of confusable effects has shared its summed weight evenly.

    Attributes
    ----------
    weights
        The shared weights, heaviest first (see :func:`share_confusable`).
    confusable
        A :class:`ConfusablePair` per pair that shared: effects the data cannot tell apart, with
        the experiment that separates them.
    """

    weights: dict[str, float]
    confusable: tuple = ()


def share_confusable(
    hyps: list[Hypothesis],
    weights: dict[str, float],
    directions: dict,
    settings: DiagnoseSettings,
    separation: Callable[[Hypothesis, Hypothesis], float] | None = None,
) -> SharedWeights:
    """The weights with each group of confusable effects sharing its summed weight evenly, and the pairs.

    The data cannot tell the members of a group apart (collinear sensitivities, and close weights or a
    difference of evidence within ``confusable_separation`` of its standard errors, ``separation``, e.g.
    :meth:`.evidence.HeldOutEvidence.separation`; the flexible term with any effect the evidence does not
    tell from it), so the evidence names the group, not one member:
    a difference of weight inside it is the noise's coin flip. Ordered heaviest first; inside a
    group the user's candidates first, then the fewest parameters, then the larger weight before sharing
    (:func:`~.selection.shared_weights`). The pairs are found once, here, on the weights before
    sharing; the decision lists the same pairs.
    """
    pairs = _pairs(hyps, weights, directions, settings, separation)
    return SharedWeights(
        shared_weights(
            weights, pairs, {h.name: h.n_params for h in hyps}, [h.name for h in hyps if h.family == "candidate"]
        ),
        tuple(ConfusablePair(p, c, sep, separating_experiment(*p)) for p, c, sep in pairs),
    )


def _explains(exv: float | None, s: DiagnoseSettings) -> tuple[bool, str]:
    """Whether a hypothesis explains the gap: it removes at least ``min_explained`` of the nominal
    excess over the noise; and why not."""
    if exv is None:
        return False, (
            "the nominal model shows no excess error over the noise on the samples it changes, so it has "
            "nothing there to remove"
        )
    if exv < s.min_explained:
        return False, (
            f"removes only {max(exv, 0.0):.0%} of the nominal excess error over the noise (at least "
            f"{s.min_explained:.0%} is needed)"
        )
    return True, f"removes {exv:.0%} of the nominal excess error over the noise"


def _twins(name: str, confusable: tuple) -> list[str]:
    """The hypotheses linked to ``name`` through confusable pairs of measured collinear sensitivities (a
    known correlation; not the flexible term, which has no direction), nearest first."""
    seen, todo = [name], [name]
    while todo:
        k = todo.pop(0)
        for pair in confusable:
            a, b = pair.effects
            if k in (a, b) and math.isfinite(pair.correlation):
                other = b if k == a else a
                if other not in seen:
                    seen.append(other)
                    todo.append(other)
    return seen[1:]


def _group_explains(
    h: Hypothesis, by: dict[str, Hypothesis], exv: float | None, confusable: tuple, s: DiagnoseSettings
) -> tuple[bool, str]:
    """Whether the heaviest hypothesis, or a twin the data cannot tell from it, explains the gap.

    A group of hypotheses with the same signature whose evidence the data cannot tell apart is
    weighed as one (:func:`share_confusable`), and it is tested as one: the share of the gap each
    member's refit removes differs by more than the evidence does (a 2 % radius error's refit removed
    -457 % of a nominal excess of a few thousandths of the noise where the speed-sensor scale, within
    1.5 standard errors of it, removed all of it). The heaviest is named; the twin that explains is
    said."""
    ok, how = _explains(exv, s)
    if ok:
        return ok, how
    for twin in _twins(h.name, confusable):
        ex = by[twin].explained(by[NOMINAL]) if twin in by else math.nan
        if math.isfinite(ex) and _explains(float(ex), s)[0]:
            own = "nothing measurable" if exv is None else f"{exv:.0%}"
            return True, (
                f"{twin}, which these data cannot tell from it, removes {ex:.0%} of the nominal excess error "
                f"over the noise (its own refit removes {own})"
            )
    return ok, how


def no_gap_weight(
    hyps: list[Hypothesis],
    weights: dict[str, float],
    settings: DiagnoseSettings,
    separation: Callable[[Hypothesis, Hypothesis], float] | None,
) -> tuple[float, list[str]]:
    """The weight of the no-gap hypothesis and the hypotheses it holds besides the nominal model.

    The nominal model's weight plus that of every hypothesis whose difference of evidence from it is
    within ``confusable_separation`` of its standard errors (``separation``; none without it): the
    comparison cannot tell them from "no gap". At most 1 (the weights sum to one).
    """
    by = {h.name: h for h in hyps}
    if separation is None or NOMINAL not in by:
        return float(weights.get(NOMINAL, 0.0)), []
    nominal = by[NOMINAL]
    alike = []
    for h in hyps:
        if h.name == NOMINAL:
            continue
        z = separation(h, nominal)
        if math.isfinite(z) and z < settings.confusable_separation:
            alike.append(h.name)
    total = float(weights[NOMINAL]) + sum(float(weights[a]) for a in alike)
    return min(total, 1.0), alike


def decide(
    hyps: list[Hypothesis],
    weights: dict[str, float],
    gap: GapDecision,
    settings: DiagnoseSettings,
    *,
    confusable: tuple = (),
    separation: Callable[[Hypothesis, Hypothesis], float] | None = None,
) -> Decision:
    """Apply the rule of the module docstring.

    Parameters
    ----------
    hyps
        The admissible hypotheses (the nominal model among them).
    weights
        Their weights (:mod:`.evidence`), shared among confusable effects
        (:attr:`SharedWeights.weights`).
    gap
        The gap tests.
    settings
        ``min_explained``.
    confusable
        The pairs that shared their weight (:attr:`SharedWeights.confusable`), reported with the
        decision.
    separation
        The evidence's difference of two hypotheses in its standard errors (e.g.
        :meth:`.evidence.HeldOutEvidence.separation`): with it, the confidence of ``none`` is the
        no-gap hypothesis's weight (:func:`no_gap_weight`); without it, the nominal model's.
    """
    by = {h.name: h for h in hyps}
    top = max(weights, key=lambda k: weights[k])  # the first maximal: ties in the order of share_confusable
    h = by[top]
    w_out = float(sum(weights[x.name] for x in hyps if x.family in ("flexible", "outside")))
    ex = h.explained(by[NOMINAL]) if h.family != "nominal" else math.nan
    exv = float(ex) if math.isfinite(ex) else None
    w_top = f"{top} carries the largest weight ({weights[top]:.2f})"
    if not gap.present or h.family == "nominal":
        conf, alike = no_gap_weight(hyps, weights, settings, separation)
        why = (
            f"no gap test is significant (family level {settings.alpha:g}, shared among {len(gap.tests)} tests): "
            f"without a gap no explanation is named"
            if not gap.present
            else f"a gap test is significant, but {w_top}"
        )
        why += f"; the confidence is the weight of the no-gap hypothesis ({conf:.2f}): the nominal model's " + (
            f"({weights[NOMINAL]:.2f}) and that of the {len(alike)} hypotheses the evidence does not tell from "
            f"it (within {settings.confusable_separation:g} standard errors: {', '.join(alike)})"
            if alike
            else "alone (the evidence tells every other hypothesis from it)"
        )
        return Decision(NOMINAL, conf, top, None, None, why, confusable=confusable)
    ok, how = _group_explains(h, by, exv, confusable, settings)
    if h.family == "candidate" and ok:
        why = f"{w_top} and {how}" if how else w_top
        return Decision(top, weights[top], top, exv, None, why, confusable=confusable)
    cause = top if h.family == "outside" and ok else None
    if h.family == "flexible":
        why = f"the flexible discrepancy term carries the largest weight ({weights[top]:.2f})"
    else:
        why = f"{w_top}" + ("" if ok else f" but {how}")
    why += f"; the hypotheses outside the candidates weigh {w_out:.2f} together"
    return Decision(
        UNEXPLAINED,
        w_out,
        top,
        exv,
        cause,
        why,
        cause_detail=dict(h.detail) if cause else {},
        confusable=confusable,
    )
