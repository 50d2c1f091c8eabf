"""The weights of the comparison: one interface, two implementations.

- :class:`HeldOutEvidence` (drive logs): each hypothesis is fitted on alternate blocks of the run
  and predicts the others (the bootstrap draws whole hold-out blocks: the unit the design makes
  independent; shorter blocks would let a gain that a model's form wins on every sample of a
  correlated stretch look certain); its held-out log density ``-z^2 / 2 - log q`` per sample
  (``q`` its own noise level relative to the nominal model's: a mass error scales the hull
  balance's noise with the mass) is averaged over a
  Bayesian bootstrap of blocks of consecutive samples (pseudo-BMA+, Yao et al. 2018,
  :func:`~.selection.stacking_weights`): correlated residuals move together, and a gain that rests
  on a few samples does not look certain. No penalty: held-out prediction pays for flexibility.
- :class:`PenalisedEvidence` (sweeps: independent samples, a few dozen): each hypothesis is
  fitted on all the data; the Gaussian likelihood with the noise level profiled out, minus
  Akaike's penalty of one per parameter, averaged over a Bayesian bootstrap of the samples
  (:func:`~.sweep_parts.information_weights`). Held-out prediction would make a sweep's effects
  extrapolate into the blocks they did not see.

The weights are computed once, over the admissible hypotheses; they sum to one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, Sequence

import numpy as np

from .hypotheses import Hypothesis
from .selection import stacking_weights
from .sweep_parts import information_weights

__all__ = ["Evidence", "HeldOutEvidence", "PenalisedEvidence"]


class Evidence(Protocol):
    """What weighs the hypotheses: :meth:`weights` over the admissible ones."""

    #: Plain words for the report.
    describes: str

    def weights(self, hypotheses: Sequence[Hypothesis]) -> dict[str, float]:
        """Weight of each admissible hypothesis (summing to 1)."""


def _log_scale(h: Hypothesis) -> np.ndarray | float:
    """``log`` of a hypothesis's noise level relative to the nominal model's per sample (0 when it has none)."""
    return h.log_scale if h.log_scale.size == np.asarray(h.z).size else 0.0


@dataclass(frozen=True)
class HeldOutEvidence:
    """Pseudo-BMA+ weights of held-out log densities (blocks of ``block`` consecutive residuals)."""

    block: int
    n_bootstrap: int
    describes: str = "held-out evidence: each fit predicts the blocks it did not see (pseudo-BMA+)"

    def weights(self, hypotheses: Sequence[Hypothesis]) -> dict[str, float]:
        """Weights of ``hypotheses`` (all on the same held-out samples)."""
        return stacking_weights(
            {h.name: -0.5 * np.asarray(h.z) ** 2 - _log_scale(h) for h in hypotheses},
            block=self.block,
            n_boot=self.n_bootstrap,
        )


@dataclass(frozen=True)
class PenalisedEvidence:
    """Pseudo-BMA+ weights of in-sample likelihoods with Akaike's penalty."""

    n_bootstrap: int
    describes: str = (
        "penalised in-sample evidence: each fit on all the data, Akaike's penalty per parameter (pseudo-BMA+)"
    )

    def weights(self, hypotheses: Sequence[Hypothesis]) -> dict[str, float]:
        """Weights of ``hypotheses`` (all on the same samples)."""
        return information_weights(
            {h.name: h.z for h in hypotheses},
            {h.name: h.n_params for h in hypotheses},
            n_boot=self.n_bootstrap,
        )
