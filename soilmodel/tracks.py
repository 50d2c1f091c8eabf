"""Two-track drive logs: one track's channels each side, turning samples recognised.

A tracked vehicle logs each track: ``sprocket_torque_left_Nm, sprocket_torque_right_Nm,
sprocket_speed_left_rad_s, sprocket_speed_right_rad_s`` and optionally ``yaw_rate_rad_s``.
The straight-line model (Eqs. 1-4) is of the whole vehicle going straight: its torque is the
SUM of the two sprocket torques, its sprocket speed the MEAN of the two. While the vehicle
turns (skid steering) the tracks slip sideways and differently, which the straight-line model
does not describe; such samples are recognised and left out (counted, never fitted).

A sample turns when the left and right sprocket speeds are apart by more than
:data:`TURN_THRESHOLD_SIGMA` standard deviations of their difference's noise, or the yaw rate
is more than that many standard deviations of its noise away from zero. The noise levels come
from the data themselves (:func:`robust_noise`: second differences, median absolute deviation,
so the smooth turns do not inflate them) unless given. A turn's edges, where the difference is
still inside the noise band, are covered by marking :data:`TURN_MARGIN_SAMPLES` samples either
side of every detected turning sample.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "mad_sigma",
    "TWO_TRACK_COLUMNS",
    "YAW_COLUMN",
    "TURN_THRESHOLD_SIGMA",
    "TURN_MARGIN_SAMPLES",
    "NOISE_FLOOR_REL",
    "robust_noise",
    "combine_tracks",
    "turning_mask",
]

#: The two-track columns of a drive log (instead of ``sprocket_torque_Nm, sprocket_speed_rad_s``).
TWO_TRACK_COLUMNS = (
    "sprocket_torque_left_Nm",
    "sprocket_torque_right_Nm",
    "sprocket_speed_left_rad_s",
    "sprocket_speed_right_rad_s",
)
#: Optional yaw-rate column of a two-track log (rad/s).
YAW_COLUMN = "yaw_rate_rad_s"
#: A sample turns when the track-speed difference (or the yaw rate) exceeds this many noise
#: standard deviations. Four keeps straight driving with Gaussian noise almost never flagged
#: (6e-5 of the samples per channel).
TURN_THRESHOLD_SIGMA = 4.0
#: Samples marked as turning on each side of every sample beyond the threshold (a turn's edges).
TURN_MARGIN_SAMPLES = 1
#: Noise floor relative to the largest reading (a resolution floor: noise-free data stay sane).
NOISE_FLOOR_REL = 1e-4

#: Factor from the median absolute deviation to the standard deviation of a normal distribution.
MAD_TO_SIGMA = 1.482602218505602


def mad_sigma(x) -> float:
    """The robust standard deviation: :data:`MAD_TO_SIGMA` times the median absolute deviation of ``x``
    from its median (the one home of the robust noise formula; a normal sample's sigma)."""
    x = np.asarray(x, dtype=float)
    return MAD_TO_SIGMA * float(np.median(np.abs(x - np.median(x))))


def robust_noise(x: np.ndarray) -> float:
    """Standard deviation of white noise on a smooth signal, from second differences (MAD).

    ``d = x[k+1] - 2 x[k] + x[k-1]`` has variance ``6 sigma^2`` for white noise; a smooth
    signal (a turn, an acceleration) contributes only ``h^2 x''``. Non-finite values are left
    out; fewer than five finite samples give 0.0.
    """
    x = np.asarray(x, dtype=float)
    d = x[2:] - 2.0 * x[1:-1] + x[:-2]
    d = d[np.isfinite(d)]
    if d.size < 3:
        return 0.0
    return mad_sigma(d) / math.sqrt(6.0)


def combine_tracks(torque_left, torque_right, speed_left, speed_right) -> tuple[np.ndarray, np.ndarray]:
    """The straight-line model's channels: summed sprocket torque (N m) and mean sprocket speed (rad/s)."""
    tl, tr, sl, sr = (np.asarray(a, dtype=float) for a in (torque_left, torque_right, speed_left, speed_right))
    return tl + tr, 0.5 * (sl + sr)


def _floor(x: np.ndarray) -> float:
    fin = np.abs(x[np.isfinite(x)])
    return NOISE_FLOOR_REL * float(np.max(fin)) + 1e-12 if fin.size else 1e-12


def turning_mask(
    speed_left,
    speed_right,
    yaw_rate=None,
    *,
    sigma_difference: float | None = None,
    sigma_yaw: float | None = None,
    threshold: float = TURN_THRESHOLD_SIGMA,
    margin: int = TURN_MARGIN_SAMPLES,
) -> np.ndarray:
    """Boolean mask of the samples where the vehicle turns.

    Parameters
    ----------
    speed_left, speed_right
        Sprocket speeds of the two tracks, rad/s.
    yaw_rate
        Yaw rate, rad/s, or ``None``.
    sigma_difference, sigma_yaw
        Noise standard deviations of ``speed_left - speed_right`` and of the yaw rate; ``None``:
        estimated from the data (:func:`robust_noise`, with a floor of
        :data:`NOISE_FLOOR_REL` of the largest reading).
    threshold
        Noise standard deviations beyond which a sample turns.
    margin
        Samples marked on each side of a turning sample.

    Returns
    -------
    numpy.ndarray
        ``True`` where the vehicle turns (non-finite readings never count as turning).
    """
    d = np.asarray(speed_left, dtype=float) - np.asarray(speed_right, dtype=float)
    if sigma_difference is None:
        sigma_difference = max(robust_noise(d), _floor(np.concatenate([np.ravel(speed_left), np.ravel(speed_right)])))
    with np.errstate(invalid="ignore"):
        turn = np.abs(d) > threshold * sigma_difference
        if yaw_rate is not None:
            y = np.asarray(yaw_rate, dtype=float)
            if sigma_yaw is None:
                sigma_yaw = max(robust_noise(y), _floor(y))
            turn |= np.abs(y) > threshold * sigma_yaw
    turn &= np.isfinite(d)
    if margin > 0 and np.any(turn):
        idx = np.nonzero(turn)[0]
        grown = np.zeros_like(turn)
        for k in range(-margin, margin + 1):
            j = np.clip(idx + k, 0, turn.size - 1)
            grown[j] = True
        turn = grown
    return turn
