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

import math
from dataclasses import dataclass
from typing import Protocol, Sequence

import numpy as np

from .hypotheses import Hypothesis
from .selection import difference_z, stacking_weights
from .sweep_parts import information_weights

__all__ = ["Evidence", "HeldOutEvidence", "PenalisedEvidence", "log_density"]


class Evidence(Protocol):
    """What weighs the hypotheses: :meth:`weights` over the admissible ones."""

    #: Plain words for the report.
    describes: str

    def weights(self, hypotheses: Sequence[Hypothesis]) -> dict[str, float]:
        """Weight of each admissible hypothesis (summing to 1)."""

    def separation(self, a: Hypothesis, b: Hypothesis) -> float:
        """The difference of evidence between ``a`` and ``b`` in its standard errors (absolute)."""


def log_density(h: Hypothesis) -> np.ndarray:
    """A hypothesis's held-out log density per compared sample: ``-z^2 / 2 - log_scale`` (the log of its noise
    level relative to the nominal model's; 0 when it has none)."""
    z = np.asarray(h.z, dtype=float)
    return -0.5 * z**2 - (h.log_scale if h.log_scale.size == z.size else 0.0)


def _profiled(h: Hypothesis) -> np.ndarray:
    """A sweep fit's Gaussian log-likelihood per sample with the noise level profiled out: its terms sum to
    ``-n/2 log(mean z^2)`` and their spread gives the standard error of a difference (delta method)."""
    q = np.asarray(h.z, dtype=float) ** 2
    s2 = max(float(np.mean(q)), 1e-300) if q.size else 1.0
    return -0.5 * math.log(s2) - 0.5 * q / s2 + 0.5


@dataclass(frozen=True)
class HeldOutEvidence:
    """Pseudo-BMA+ weights of held-out log densities (blocks of ``block`` consecutive residuals)."""

    block: int
    n_bootstrap: int
    describes: str = "held-out evidence: each fit predicts the blocks it did not see (pseudo-BMA+)"

    def weights(self, hypotheses: Sequence[Hypothesis]) -> dict[str, float]:
        """Weights of ``hypotheses`` (all on the same held-out samples)."""
        return stacking_weights(
            {h.name: log_density(h) for h in hypotheses},
            block=self.block,
            n_boot=self.n_bootstrap,
        )

    def separation(self, a: Hypothesis, b: Hypothesis) -> float:
        """The held-out log-density difference of ``a`` and ``b`` in its standard errors, from the sums
        over the hold-out blocks (the units the bootstrap draws)."""
        d = log_density(a) - log_density(b)
        return difference_z(np.add.reduceat(d, np.arange(0, d.size, max(1, self.block))) if d.size else d)


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

    def separation(self, a: Hypothesis, b: Hypothesis) -> float:
        """The penalised log-likelihood difference of ``a`` and ``b`` in its standard errors, from the
        samples' terms (noise level profiled out) and Akaike's penalties."""
        return difference_z(_profiled(a) - _profiled(b), offset=float(b.n_params - a.n_params))
