"""The data step for a drive log whose torque hold was not given: held, or sampled?

A logged command is held from each sample to the next (``"zoh"``); a transducer's continuous signal
is sampled (``"sample"``); the wrong one shifts the thrust by the torque's change over one sample,
which reads as a grade or a drivetrain loss. When the caller does not say, the nominal model is
fitted on the training blocks both ways, each with the flexible term on top (so that a gap the
nominal model leaves, which is slow in time, does not mask the hold's fast signature). The held torque
is the default (the library's drive-log contract: a logged command); the sampled one is taken when it
predicts the held-out blocks significantly better (Diebold-Mariano at ``alpha``): an effect that
works through the acceleration (a mass error) can make the sampled hold look a little better by
chance of timing, and a few percent is not evidence. Every hypothesis is then fitted with the hold
chosen; the report prints the shrink and the p-value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .fits import usable
from .hypotheses import Hypothesis
from .library import flexible_on, held_out
from .selection import dm_test
from .setup import Setup

__all__ = ["HoldChoice", "choose_hold"]


@dataclass(frozen=True)
class HoldChoice:
    """The torque hold of a drive log's fits.

    Attributes
    ----------
    hold
        ``"zoh"`` or ``"sample"``.
    given
        Whether the caller gave it.
    p_value, shrink, level
        When chosen: the Diebold-Mariano p-value that the sampled torque predicts the held-out
        blocks better than the held one, its held-out RMS shrink, and the level it was held to (None
        when given or not tried).
    """

    hold: str
    given: bool
    p_value: float | None = None
    shrink: float | None = None
    level: float | None = None

    def to_dict(self) -> dict:
        """JSON entry."""
        return {
            "hold": self.hold,
            "given": self.given,
            "p_value": self.p_value,
            "shrink": self.shrink,
            "level": self.level,
        }


def choose_hold(setup: Setup, nominal: Hypothesis, train_res: list) -> HoldChoice:
    """Compare the nominal model with the torque held (``nominal``, its training residuals ``train_res``) and
    sampled, each with the flexible term on top, on the held-out blocks; the sampled one is taken when it
    predicts them significantly better."""
    sampled, fits, sampled_train = held_out(setup, lambda tr: setup.runner.run_warm(tr, torque_hold="sample"))
    held = nominal.heldout()
    frame = setup.frame(held)
    if not all(usable(f, True) for f in fits):
        return HoldChoice("zoh", False, None, None)
    z0 = frame.z(flexible_on(setup, held, train_res))
    z1 = frame.z(flexible_on(setup, sampled, sampled_train), z0)
    shrink = 1.0 - float(np.sqrt((z1 @ z1) / max(float(z0 @ z0), 1e-300)))
    p = dm_test(z0, z1, setup.dm_lag)
    hold = "sample" if p < setup.settings.alpha else "zoh"
    return HoldChoice(hold, False, float(p), float(shrink), setup.settings.alpha)
