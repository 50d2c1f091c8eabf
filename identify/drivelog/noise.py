"""Drive-log sensor noise from the log itself: robust (MAD) levels of second differences.

Each channel has the noise model ``sigma = sqrt(a^2 + (b x)^2)`` (absolute plus relative part),
given by the caller or estimated here (:func:`estimate_noise_profile`).
"""

from __future__ import annotations

import math

import numpy as np

from ...soilmodel.tracks import MAD_TO_SIGMA, robust_noise

__all__ = ["estimate_noise", "estimate_noise_profile", "noise_model"]


def estimate_noise(x: np.ndarray) -> float:
    """Standard deviation of white measurement noise on a smooth signal, from the data alone.

    Uses the second differences ``d = x[k+1] - 2 x[k] + x[k-1]`` (variance ``6 sigma^2`` for
    white noise; a smooth signal contributes only ``h^2 x''``) and a median absolute deviation,
    so isolated steps in the signal do not inflate the estimate. Returns 0.0 for fewer than
    five samples or a noise-free signal.
    """
    x = np.asarray(x, dtype=float)
    if x.size < 5:
        return 0.0
    return robust_noise(x)


def estimate_noise_profile(x: np.ndarray, n_bins: int = 8) -> tuple[float, float]:
    """Noise model ``sigma(x) = sqrt(a^2 + (b x)^2)`` (absolute plus relative part) from the data alone.

    Sensors such as torque cells and encoders have noise that grows with the reading. The
    second differences (see :func:`estimate_noise`) are grouped into ``n_bins`` equally
    populated bins by the level ``|x|`` (taken two samples either side, so that binning does
    not select on the noise itself); a robust (MAD) variance per bin is fitted to
    ``a^2 + b^2 mean(x^2)`` by least squares (weights: square root of the bin count) with
    non-negative coefficients. Returns ``(a, b)``; ``b = 0`` for a constant noise level.
    The relative part is estimated mostly from the many moderate readings; a log with very few
    large readings gets a less certain ``b`` (the covariance is scaled by the residual
    variance anyway).
    """
    x = np.asarray(x, dtype=float)
    if x.size < 5 * n_bins:
        return estimate_noise(x), 0.0
    # level of the reading at k from x[k-2] and x[k+2]: independent of the noise in d[k]
    d = x[3:-1] - 2.0 * x[2:-2] + x[1:-3]
    xc = 0.5 * (np.abs(x[:-4]) + np.abs(x[4:]))
    order = np.argsort(xc)
    rows, var, cnt = [], [], []
    for chunk in np.array_split(order, n_bins):
        dd = d[chunk]
        mad = float(np.median(np.abs(dd - np.median(dd))))
        rows.append([1.0, float(np.mean(xc[chunk] ** 2))])
        var.append((MAD_TO_SIGMA * mad) ** 2 / 6.0)
        cnt.append(chunk.size)
    X, y, wt = np.array(rows), np.array(var), np.sqrt(np.array(cnt, dtype=float))
    fits = {}
    for cols in ((0,), (1,), (0, 1)):  # non-negative least squares on two coefficients
        A = X[:, cols] * wt[:, None]
        coef, *_ = np.linalg.lstsq(A, y * wt, rcond=None)
        if np.any(coef < 0):
            continue
        full = np.zeros(2)
        full[list(cols)] = coef
        fits[cols] = (float(np.sum(((X @ full - y) * wt) ** 2)), full)
    one = [fits[c] for c in ((0,), (1,)) if c in fits]
    if not one and (0, 1) not in fits:
        return estimate_noise(x), 0.0
    best = min(one, key=lambda f: f[0]) if one else fits[(0, 1)]
    if (0,) in fits and (1,) in fits and fits[(1,)][0] > 0.8 * fits[(0,)][0]:
        best = fits[(0,)]  # a purely relative model only when it fits clearly better
    # two coefficients only when they explain clearly more (readings spread enough to tell)
    if (0, 1) in fits and (not one or fits[(0, 1)][0] < 0.5 * best[0]):
        best = fits[(0, 1)]
    a2, b2 = best[1]
    return math.sqrt(a2), math.sqrt(b2)


def noise_model(x: np.ndarray, given: float | None) -> tuple[float, float]:
    """``(a, b)`` of a channel: ``(given, 0)`` if given, else estimated, with a 0.01 % resolution floor."""
    if given is not None:
        return float(given), 0.0
    a, b = estimate_noise_profile(x)
    floor = 1e-4 * float(np.max(np.abs(x))) + 1e-12  # a 0.01 % resolution floor keeps noise-free data sane
    return max(a, floor), b
