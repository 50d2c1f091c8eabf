"""Hypotheses: every explanation of a gap, in one form the comparison weighs.

A :class:`Hypothesis` is the nominal model (``"none"``), a library effect, the flexible
discrepancy term (``"discrepancy"``: any smooth gap, naming no physics) or a cause outside the
library (:mod:`.outside`). Each states its parameter count, its standardised residuals on the
samples the evidence is taken on (:class:`Frame`), and whether it is admissible: its fits
converged and its parameters lie inside their range (an effect parameter on a bound is an effect
stretched to imitate something else). An inadmissible hypothesis leaves the comparison.

Residual convention: measured - model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

__all__ = ["Frame", "Hypothesis", "NOMINAL", "DISCREPANCY", "FAMILIES"]

NOMINAL = "none"
DISCREPANCY = "discrepancy"

#: ``nominal``: the model as it is; ``candidate``: a library effect among the candidates; ``flexible``: the
#: discrepancy term; ``outside``: a cause outside the library, or a library effect the user left out of the
#: candidates. The confidence of ``unexplained`` is the summed weight of ``flexible`` and ``outside``.
FAMILIES = ("nominal", "candidate", "flexible", "outside")


@dataclass(frozen=True, eq=False)
class Frame:
    """The samples the evidence is taken on, and the noise floor that standardises them.

    Attributes
    ----------
    sigma
        Noise level per channel and sample (full length; NaN where unknown): for a log's weights, the
        sensors' noise as the fit's noise model carries it into each channel; else the noise floor.
    mask
        Per channel, the samples compared (held out for a log, all usable ones for a sweep).
    expected
        Per channel and sample (full length), the expected squared standardised residual of a right model:
        a log's ``1 - h``, the share of the channel's noise its latent slip leaves
        (:func:`~soiltrack.identify.drivelog.sensitivity.latent_slip_expectation`); None: 1 (a sweep).
    """

    sigma: dict[str, np.ndarray]
    mask: dict[str, np.ndarray]
    expected: dict[str, np.ndarray] | None = None

    @property
    def channels(self) -> list[str]:
        """The residual channels."""
        return list(self.mask)

    @property
    def size(self) -> int:
        """Number of standardised residuals compared."""
        return int(sum(int(np.count_nonzero(m)) for m in self.mask.values()))

    def at_most_nominal(self, residuals: dict[str, np.ndarray]) -> "Frame":
        """This frame with each channel's noise level lowered, where needed, to the nominal model's own error.

        The noise on a channel is at most what the nominal model leaves there (``residuals``): where
        the nominal model's mean squared standardised residual is below its expected value
        (:attr:`expected`), the noise level is too high, and a hypothesis that only rescales a
        channel's noise (a mass error scales the hull balance's) would gain held-out density from
        the noise level's error, not from its predictions. Channels where the nominal error is above
        the expected value keep it.
        """
        sigma = dict(self.sigma)
        for ch, m in self.mask.items():
            z = np.asarray(residuals[ch], dtype=float)[m] / self.sigma[ch][m]
            e = self.expect_of(ch)[m]
            ok = np.isfinite(z)
            if np.any(ok):
                ratio = float(np.mean(z[ok] ** 2)) / max(float(np.mean(e[ok])), 1e-12)
                sigma[ch] = self.sigma[ch] * math.sqrt(min(1.0, max(ratio, 1e-12)))
        return Frame(sigma, self.mask, self.expected)

    def expect_of(self, ch: str) -> np.ndarray:
        """The expected squared standardised residual of channel ``ch`` (full length; ones without one)."""
        if self.expected is None or ch not in self.expected:
            return np.ones(self.mask[ch].size)
        return np.asarray(self.expected[ch], dtype=float)

    def z(
        self,
        residuals: dict[str, np.ndarray],
        fill: np.ndarray | None = None,
        scale: dict[str, np.ndarray] | None = None,
    ) -> np.ndarray:
        """Standardised residuals on the compared samples, channel after channel.

        ``fill`` (a z vector of the same layout, e.g. the nominal model's) replaces samples the
        hypothesis leaves unpredicted (NaN), so that every hypothesis is scored on the same samples.
        ``scale`` (per channel, full length): the hypothesis's own noise level relative to the nominal
        model's (:meth:`Hypothesis.noise_scale`); None: 1.
        """
        parts = []
        for ch, m in self.mask.items():
            sg = self.sigma[ch][m] if scale is None else self.sigma[ch][m] * np.asarray(scale[ch], dtype=float)[m]
            parts.append(np.asarray(residuals[ch], dtype=float)[m] / sg)
        out = np.concatenate(parts)
        if fill is not None:
            bad = np.isnan(out)
            out[bad] = fill[bad]
        return out


def _ratio(a: dict[str, np.ndarray] | None, b: dict[str, np.ndarray] | None) -> dict[str, np.ndarray] | None:
    """``a / b`` per channel of ``a`` (1 where ``b`` has no channel or the ratio is not a finite positive
    number), or None when either is None."""
    if a is None or b is None:
        return None
    out = {}
    for ch, x in a.items():
        y = b.get(ch)
        q = np.ones_like(x) if y is None else np.asarray(x, dtype=float) / np.asarray(y, dtype=float)
        out[ch] = np.where(np.isfinite(q) & (q > 0), q, 1.0)
    return out


@dataclass(frozen=True, eq=False)
class Hypothesis:
    """One explanation in the comparison.

    Attributes
    ----------
    name
        ``"none"``, an effect name, ``"discrepancy"`` or an outside cause (``"delay"``,
        ``"terrain_change"``, ``"clipped_sensor"``, ``"soil_beyond_range"``,
        ``"plateau"``).
    family
        One of :data:`FAMILIES`.
    n_params
        Parameters it adds to the nominal soil (the penalty of in-sample evidence).
    residuals
        Its residuals per channel (full length) on the samples the evidence uses: held out for a
        log, fitted on all the data for a sweep.
    z
        Standardised residuals on the frame's samples (set by :meth:`scored`).
    admissible, why
        Whether it enters the comparison, and why not (empty when it does).
    held
        Held-out residuals per channel (full length), for the shrink; None when not held out.
    parameters
        Its fitted parameters ``{param: {value, stderr, ci95, identifiable, at_bound}}``.
    detail
        What names an outside cause (``lag_s``, ``window_s``, ``level``, ...).
    fit
        Its fit on all the data, when made.
    train_residuals
        Per fold, its residuals on the training samples (full length), when held out.
    noise
        A log's: its own fits' noise level per channel at the held-out samples (full length), when it
        differs from the nominal model's by construction (an effect that scales a channel's noise).
    gain
        A log's: each residual's derivative with respect to the measured signal it is formed from, per
        channel (full length; :func:`~.fits.log_channels`), when ``noise`` is given.
    scale, log_scale
        Set by :meth:`scored`: its noise level relative to the nominal model's per channel (full
        length; None: 1), which standardises its residuals; and ``log`` of its noise level *in the
        measured signals' units* relative to the nominal model's, on the frame's samples (the held-out
        log density of the measurements is ``-z^2 / 2 - log_scale``). The two differ where a residual
        only rescales the same measured noise: a mass error's hull balance is the acceleration times
        the mass, so its noise and its residual grow together and the measured acceleration's density
        is unchanged (the Jacobian of the residual cancels the larger noise); the encoder's noise seen
        through a radius error's speed balance is a real change.
    direction
        Its sensitivity direction (the projected residual change it would make, beyond the soil) when it is no
        screened effect but one can be computed (the speed scale), for the confusable check.
    support
        Per channel (full length), the samples where its prediction can differ from the nominal
        model's (a change of terrain: its window); None: every sample (an effect of the whole run).
        The share of the gap it explains is measured there (:meth:`explained`).
    in_support
        Set by :meth:`scored`: ``support`` on the frame's samples, in the layout of ``z`` (None: all).
    z_gap
        Set by :meth:`with_gap`: its residuals standardised by the noise floor instead (a log's: the
        residuals' own noise level, as the gap tests take it), in the layout of ``z``; empty: ``z``. The
        share of the gap it explains (:meth:`explained`) is measured on them: a share of the excess over
        the noise needs that noise level calibrated on the residuals themselves.
    """

    name: str
    family: str
    n_params: int
    residuals: dict[str, np.ndarray]
    z: np.ndarray = field(default_factory=lambda: np.zeros(0))
    admissible: bool = True
    why: str = ""
    held: dict[str, np.ndarray] | None = None
    parameters: dict = field(default_factory=dict)
    detail: dict = field(default_factory=dict)
    fit: Any = None
    train_residuals: list | None = None
    noise: dict[str, np.ndarray] | None = None
    gain: dict[str, np.ndarray] | None = None
    direction: np.ndarray | None = None
    scale: dict[str, np.ndarray] | None = None
    log_scale: np.ndarray = field(default_factory=lambda: np.zeros(0))
    support: dict[str, np.ndarray] | None = None
    in_support: np.ndarray | None = None
    z_gap: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def heldout(self) -> dict[str, np.ndarray]:
        """Its held-out residuals (raises when it was not held out: the nominal model always is)."""
        if self.held is None:
            raise ValueError(f"hypothesis {self.name} was not held out")
        return self.held

    def noise_scale(self, nominal: "Hypothesis") -> dict[str, np.ndarray] | None:
        """Its noise level relative to ``nominal``'s per channel (1 where either is unknown), or None."""
        return _ratio(self.noise, nominal.noise)

    def gain_ratio(self, nominal: "Hypothesis") -> dict[str, np.ndarray] | None:
        """Its residuals' gains relative to ``nominal``'s per channel (1 where either is unknown), or None: the
        part of :meth:`noise_scale` that only rescales the same measured noise."""
        return _ratio(self.gain, nominal.gain)

    def scored(self, frame: Frame, fill: np.ndarray | None = None, nominal: "Hypothesis | None" = None) -> "Hypothesis":
        """This hypothesis with ``z`` on the frame's samples (see :meth:`Frame.z`), standardised by its own noise
        level relative to ``nominal``'s where it has one."""
        scale = None if nominal is None else self.noise_scale(nominal)
        z = frame.z(self.residuals, fill, scale)
        sel = (
            None
            if self.support is None
            else np.concatenate([np.asarray(self.support[ch], dtype=bool)[m] for ch, m in frame.mask.items()])
        )
        if scale is None:
            return replace(self, z=z, scale=None, log_scale=np.zeros(z.size), in_support=sel)
        gains = None if nominal is None else self.gain_ratio(nominal)
        ls = np.concatenate(
            [
                np.log(scale[ch][m] / (1.0 if gains is None or ch not in gains else gains[ch][m]))
                for ch, m in frame.mask.items()
            ]
        )
        ls[np.isnan(frame.z(self.residuals))] = 0.0  # filled with the nominal model's values
        return replace(self, z=z, scale=scale, log_scale=ls, in_support=sel)

    def with_gap(self, frame: Frame, fill: np.ndarray | None = None) -> "Hypothesis":
        """This scored hypothesis with :attr:`z_gap` on ``frame`` (the same samples as :meth:`scored`'s, another
        noise level), standardised by its own noise level relative to the nominal model's as :attr:`z` is."""
        return replace(self, z_gap=frame.z(self.residuals, fill, self.scale))

    def explained(self, nominal: "Hypothesis") -> float:
        """Share of the nominal model's excess error over the noise that this hypothesis removes.

        ``1 - max(E, 0) / E_nominal`` with ``E = S / n - 1`` (``S`` the sum of squared standardised
        residuals over the ``n`` compared samples in its :attr:`support`, on :attr:`z_gap` where set): at
        most 1, negative when it does worse, NaN when the nominal model shows no excess there (nothing for
        it to explain).
        """
        z0, z1 = nominal.gap_z, self.gap_z
        if self.in_support is not None and self.in_support.size == z1.size == z0.size:
            z0, z1 = z0[self.in_support], z1[self.in_support]
        n = z1.size
        s0 = float(z0 @ z0) if np.all(np.isfinite(z0)) else math.inf
        s1 = float(z1 @ z1) if np.all(np.isfinite(z1)) else math.inf
        if n == 0 or not (math.isfinite(s0) and math.isfinite(s1)) or s0 / n - 1.0 <= 0.0:
            return math.nan
        return 1.0 - max(s1 / n - 1.0, 0.0) / (s0 / n - 1.0)

    @property
    def gap_z(self) -> np.ndarray:
        """:attr:`z_gap` where set, else :attr:`z`."""
        return self.z_gap if self.z_gap.size == self.z.size and self.z.size else self.z
