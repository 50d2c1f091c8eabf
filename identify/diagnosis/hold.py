"""A drive log whose torque hold was not given: held, or sampled? Part of the comparison.

A logged command is held from each sample to the next (``"zoh"``); a transducer's continuous signal
is sampled (``"sample"``); the wrong one shifts the thrust by the torque's change over one sample,
which reads as a grade, a drivetrain loss or a mass error. When the caller does not say, every
hypothesis is first fitted and weighed with the held torque (the library's drive-log contract: a
logged command). The best model of that comparison (the heaviest of the nominal model and the
library's effects; the nominal model when the flexible term is heaviest) is then fitted again on the
training blocks with the torque sampled, and both versions, each with the flexible term on top
(so that a slow gap neither masks nor imitates the hold's fast signature), predict the held-out
blocks. The sampled torque is taken when it predicts them significantly better (Diebold-Mariano at
``alpha`` on the held-out log density, each version standardised by its own noise level); then the
whole comparison is made again with it. Judging the hold under the best explanation, not under the
nominal model alone, matters where the effect itself works through the fast signals: a mass error
under a sampled torque made the nominal model's sampled version look worse, and the held torque
with a drivetrain loss was named (measured on the independent 50 Hz logs, docs/diagnosis.md).
The report prints the shrink and the p-value.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ...soilmodel.effects import EFFECTS
from .fits import usable
from .hypotheses import Frame, Hypothesis
from .library import flexible_on, held_out, simplest_form
from .selection import dm_loss_test
from .setup import Setup, noise_floors

__all__ = ["HoldChoice", "choose_hold", "hold_base"]


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
    judged_with
        When chosen: the model both holds were fitted with (``"none"``: the nominal model; else a
        library effect), each with the flexible term on top.
    """

    hold: str
    given: bool
    p_value: float | None = None
    shrink: float | None = None
    level: float | None = None
    judged_with: str | None = None

    def to_dict(self) -> dict:
        """JSON entry."""
        return {
            "hold": self.hold,
            "given": self.given,
            "p_value": self.p_value,
            "shrink": self.shrink,
            "level": self.level,
            "judged_with": self.judged_with,
        }


def hold_base(hyps: list[Hypothesis], weights: dict[str, float]) -> Hypothesis:
    """The model whose hold is judged: the heaviest of the nominal model and the library's effects among
    ``hyps`` (by ``weights``); the nominal model when the flexible term or an outside cause is heavier
    (the flexible term is put on top of it in :func:`choose_hold` anyway)."""
    models = [h for h in hyps if (h.family == "nominal" or h.name in EFFECTS) and h.held is not None]
    nominal = next(h for h in hyps if h.family == "nominal")
    best = max(models, key=lambda h: weights.get(h.name, 0.0), default=nominal)
    return best if best.train_residuals is not None else nominal


def _common_floor(setup: Setup, frame: Frame, held: tuple[dict[str, np.ndarray], ...]) -> Frame:
    """``frame`` with the noise floor per sample at most what the held-out residuals of either hold leave
    (their second differences, :func:`~.setup.noise_floors`): the wrong hold's fast misfit inflates the floor
    estimated from its own residuals, and would discount the very channel where the right hold does better."""
    window = setup.settings.noise_window(setup.n, True)
    sigma = {ch: np.array(sg, dtype=float, copy=True) for ch, sg in frame.sigma.items()}
    for r in held:
        fl, _ = noise_floors({ch: np.asarray(r[ch], dtype=float) for ch in frame.channels}, setup.order, window)
        for ch in frame.channels:
            sigma[ch] = np.fmin(sigma[ch], fl[ch])
    return Frame(sigma, frame.mask)


def choose_hold(setup: Setup, nominal: Hypothesis, base: Hypothesis) -> HoldChoice:
    """Compare ``base`` (fitted with the torque held: the nominal model or one library effect, see
    :func:`hold_base`) with the same model fitted with the torque sampled, each with the flexible term on
    top, on the held-out blocks of the nominal model's frame; the sampled torque is taken when it predicts
    them significantly better."""
    effects = () if base.family == "nominal" else (base.name,)
    fixed = simplest_form(base.name) if effects else {}
    extra = {"fixed": fixed} if fixed else {}
    noise: dict[str, np.ndarray] = {}
    sampled, fits, sampled_train = held_out(
        setup, lambda tr: setup.runner.run_warm(tr, effects, torque_hold="sample", **extra), noise
    )
    if not all(usable(f, True) for f in fits) or base.train_residuals is None:
        return HoldChoice("zoh", False, None, None)
    alt = replace(base, residuals=sampled, held=sampled, train_residuals=sampled_train, noise=noise or None)
    frame = _common_floor(setup, setup.frame(nominal.heldout()), (base.heldout(), sampled))
    z_nom = frame.z(nominal.heldout())
    # each with the flexible term on top, standardised by its own noise level: per sample, minus twice the
    # held-out log density up to a constant (z^2 + 2 log q), comparable across noise models
    tops = [
        replace(h, residuals=flexible_on(setup, h.heldout(), h.train_residuals)).scored(frame, z_nom, nominal)
        for h in (base, alt)
    ]
    d0, d1 = (h.z**2 + 2.0 * h.log_scale for h in tops)
    z0, z1 = (frame.z(h.residuals, z_nom) for h in tops)
    shrink = 1.0 - float(np.sqrt((z1 @ z1) / max(float(z0 @ z0), 1e-300)))
    p = dm_loss_test(d0 - d1, setup.dm_lag)
    hold = "sample" if p < setup.settings.alpha else "zoh"
    return HoldChoice(hold, False, float(p), float(shrink), setup.settings.alpha, base.name)
