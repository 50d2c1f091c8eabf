"""A clipped sensor: readings piled up exactly at a channel's largest or smallest value.

A saturated load cell or torque sensor, or a speed sensor at its range limit, reports the same
number for every sample beyond its range: the readings pile up *exactly* at the channel's
extreme, while a noisy signal almost never repeats a value. No effect in the library models
this; a flexible candidate (a softening soil, a resistance growing with slip) can imitate the
flattened curve, so a diagnosis that sees a pile-up says so and names no effect with confidence.

The test: at least ``MIN_ROWS`` rows (and ``MIN_SHARE`` of the channel) equal to its extreme,
and at least ``PILE_FACTOR`` times as many as hold the next value inward (a coarsely quantised
channel whose top bins are all well filled is not clipped, it is only quantised). Readings of
exactly zero (a vehicle at rest) are not a pile-up.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...soilmodel.data import DriveLog, SlipData

__all__ = ["Saturation", "find_saturation", "MIN_ROWS", "MIN_SHARE", "PILE_FACTOR"]

#: Fewest rows at the extreme for a pile-up.
MIN_ROWS = 3
#: Smallest share of the channel's rows at the extreme.
MIN_SHARE = 0.02
#: Rows at the extreme over rows at the next value inward.
PILE_FACTOR = 3


@dataclass(frozen=True)
class Saturation:
    """A channel whose readings pile up at one extreme.

    Attributes
    ----------
    channel : str
        Column name (``tractive_force_N``, ``sprocket_torque_Nm``, ...).
    side : {"largest", "smallest"}
    level : float
        The reading they pile up at (the channel's unit).
    rows : tuple of int
        Data rows (1-based, as in the file) at that reading.
    """

    channel: str
    side: str
    level: float
    rows: tuple[int, ...]

    def describe(self) -> str:
        """One plain sentence."""
        shown = ", ".join(str(r) for r in self.rows[:5]) + (", ..." if len(self.rows) > 5 else "")
        return (
            f"{len(self.rows)} rows of {self.channel} (rows {shown}) read exactly its {self.side} value "
            f"{self.level:.6g}: a sensor clipped at its range (saturation) looks like this, and no effect in "
            "the library models it"
        )


def _channels(data: SlipData | DriveLog) -> dict[str, np.ndarray]:
    if isinstance(data, SlipData):
        return {data.channel: np.asarray(data.values, dtype=float)}
    out = {
        "sprocket_torque_Nm": data.sprocket_torque,
        "sprocket_speed_rad_s": data.sprocket_speed,
        "vehicle_speed_m_s": data.vehicle_speed,
    }
    if data.vehicle_accel is not None:
        out["vehicle_accel_m_s2"] = data.vehicle_accel
    return {k: np.asarray(v, dtype=float) for k, v in out.items()}


def _pile(x: np.ndarray, side: str) -> float | None:
    """The reading at which ``x`` piles up on ``side`` (its largest or smallest value), or None."""
    x = x[np.isfinite(x)]
    if x.size < MIN_ROWS:
        return None
    level = float(np.max(x) if side == "largest" else np.min(x))
    if level == 0.0:  # exactly zero: a vehicle at rest, not a sensor at its range
        return None
    at = int(np.count_nonzero(x == level))
    if at < max(MIN_ROWS, MIN_SHARE * x.size):
        return None
    rest = x[x < level] if side == "largest" else x[x > level]
    if rest.size == 0:  # a constant channel: nothing to say here
        return None
    nxt = float(np.max(rest) if side == "largest" else np.min(rest))
    if at < PILE_FACTOR * int(np.count_nonzero(x == nxt)):
        return None
    return level


def find_saturation(data: SlipData | DriveLog) -> tuple[Saturation, ...]:
    """The channels of ``data`` whose readings pile up exactly at their largest or smallest value."""
    out = []
    for name, x in _channels(data).items():
        for side in ("largest", "smallest"):
            level = _pile(x, side)
            if level is not None:
                rows = tuple(int(k) + 1 for k in np.nonzero(x == level)[0])
                out.append(Saturation(name, side, level, rows))
    return tuple(out)
