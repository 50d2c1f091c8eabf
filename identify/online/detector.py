"""Change-of-terrain detector: a two-sided CUSUM of standardised one-step prediction residuals.

Each new sample is predicted from the current estimate before it enters the horizon: its
profiled residual (the latent slip chosen to fit the speeds and the thrust best, the
residual pair's length signed by the thrust residual, as in the batch fit) divided by the
horizon's residual scale is about standard normal while the soil stays the same. A change of
terrain moves the thrust-slip curve, and the residuals of the new soil lean to one side. The
CUSUM ``S+ = max(0, S+ + z - k)``, ``S- = max(0, S- - z - k)`` (``z`` clipped to
``+-clip``) accumulates that lean and raises an alarm when either side exceeds ``h``; the
change is dated at the last time the alarming side was zero (the maximum-likelihood change
point of a CUSUM).
"""

from __future__ import annotations

import math

__all__ = ["CusumDetector"]


class CusumDetector:
    """Two-sided CUSUM (Page 1954) on standardised residuals.

    Parameters
    ----------
    reference
        Drift ``k`` subtracted per sample, in standard deviations (half the smallest shift to
        catch quickly).
    threshold
        Alarm threshold ``h``.
    clip
        Each residual is clipped to ``[-clip, clip]`` first.
    """

    def __init__(self, reference: float, threshold: float, clip: float) -> None:
        self.reference, self.threshold, self.clip = float(reference), float(threshold), float(clip)
        self.reset(math.nan)

    def reset(self, time_s: float) -> None:
        """Forget everything (after an alarm, or at the start)."""
        self.up = 0.0
        self.down = 0.0
        self.up_start = time_s
        self.down_start = time_s

    @property
    def statistic(self) -> float:
        """The larger of the two sides, in standard deviations."""
        return max(self.up, self.down)

    def run_start(self, default: float) -> float:
        """Start of the side that leans most now (its last time at zero), or ``default`` when neither leans."""
        if self.up == 0.0 and self.down == 0.0:
            return default
        return self.up_start if self.up >= self.down else self.down_start

    def update(self, z: float, time_s: float) -> float | None:
        """Add one standardised residual taken at ``time_s``; the change time on an alarm, else ``None``."""
        if not math.isfinite(z):
            return None
        z = min(max(z, -self.clip), self.clip)
        if self.up == 0.0:
            self.up_start = time_s
        if self.down == 0.0:
            self.down_start = time_s
        self.up = max(0.0, self.up + z - self.reference)
        self.down = max(0.0, self.down - z - self.reference)
        if self.up > self.threshold:
            return self.up_start
        if self.down > self.threshold:
            return self.down_start
        return None
