"""Is there a gap? The tests the decision uses, each with its p-value and level.

A gap is present when any of these is significant. They are one family of tests of one question,
so each is held to ``alpha`` divided by the number of tests made (Bonferroni): the chance that
effect-free data show a gap stays below ``alpha``. Each test's p-value and level are printed in the
report and the JSON, and no other number decides whether there is a gap.

- ``nominal error vs noise`` (drive logs): the nominal model's held-out error against the noise
  floor (:func:`~.selection.gap_p_value`, the chi-square corrected for correlated residuals). A
  sweep's noise floor, from second differences of a few dozen readings, is too rough for this.
- ``soil differs within a time window`` (drive logs): the score test of the nominal fit on all the
  data for one soil inside a window of time and another outside it, over every window of whole
  cells (:func:`~.log_parts.terrain_window`, its own Bonferroni over the windows and its
  correction for correlated residuals): a gap that the held-out blocks, each holding half of a
  window, can miss.
- ``flexible term beats nominal``: the flexible term predicts the held-out data better than the
  nominal model (Diebold-Mariano, :func:`~.selection.dm_test`);
- ``heaviest beats nominal``: the heaviest hypothesis predicts the held-out data better than the
  nominal model by a Diebold-Mariano test AND its held-out RMS shrinks by at least ``min_shrink``
  (a gain of a fraction of a percent over hundreds of samples is no gap);
- ``lack of fit`` (sweeps): a flexible term in slip on top of the nominal fit explains its residuals
  (F test, :func:`~.sweep_parts.lack_of_fit`; in-sample like a sweep's evidence, free of the noise level);
- ``pure-error lack of fit`` (sweeps whose rows repeat a slip level): the spread of the level
  means about the model against the spread within the levels (the rig fit's own test,
  :func:`~..sweep.rig.pure_error_test`), which measures the noise directly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


__all__ = ["GapTest", "GapDecision", "decide_gap"]


@dataclass(frozen=True)
class GapTest:
    """One test of the gap: what it asks, its p-value, the level it is held to."""

    name: str
    p_value: float
    level: float

    @property
    def significant(self) -> bool:
        """``p_value < level``."""
        return bool(self.p_value < self.level)

    def to_dict(self) -> dict:
        """JSON entry."""
        return {
            "test": self.name,
            "p_value": float(self.p_value),
            "level": float(self.level),
            "significant": self.significant,
        }


@dataclass(frozen=True)
class GapDecision:
    """The gap tests and whether any is significant.

    Attributes
    ----------
    tests
        The tests of the nominal model's gap, each with its (Bonferroni) level.
    """

    tests: tuple[GapTest, ...]

    @property
    def present(self) -> bool:
        """Whether a gap is present (any test significant)."""
        return any(t.significant for t in self.tests)

    def p_of(self, name: str) -> float:
        """p-value of the test ``name`` (1 when it was not made)."""
        return next((t.p_value for t in self.tests if t.name == name), 1.0)


def decide_gap(p_values: dict[str, float | None], alpha: float) -> GapDecision:
    """The :class:`GapDecision` from the p-values of the tests made (None: not made), each held to ``alpha``
    divided by the number of tests made."""
    made = {k: float(v) for k, v in p_values.items() if v is not None and math.isfinite(float(v))}
    level = alpha / max(1, len(made))
    return GapDecision(tuple(GapTest(k, v, level) for k, v in made.items()))
