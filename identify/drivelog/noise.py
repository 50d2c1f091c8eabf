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
    X, y, cnt = _bin_stats(d, xc, order, n_bins)
    wt = np.sqrt(cnt)
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


def _sorted_median(s: np.ndarray) -> np.ndarray:
    """Row medians of a row-sorted matrix, as :func:`numpy.median` computes them (the mean of the middle two)."""
    m = s.shape[1]
    if m % 2:
        return s[:, m // 2]
    return (s[:, m // 2 - 1] + s[:, m // 2]) / 2.0


_BinStats = tuple[np.ndarray, np.ndarray, np.ndarray]


def _bin_stats_loop(d: np.ndarray, xc: np.ndarray, order: np.ndarray, n_bins: int) -> _BinStats:
    """:func:`_bin_stats` bin by bin with ``np.median`` (NaN propagates)."""
    rows: list[list[float]] = []
    var: list[float] = []
    cnt: list[int] = []
    for chunk in np.array_split(order, n_bins):
        dd = d[chunk]
        mad = float(np.median(np.abs(dd - np.median(dd))))
        rows.append([1.0, float(np.mean(xc[chunk] ** 2))])
        var.append((MAD_TO_SIGMA * mad) ** 2 / 6.0)
        cnt.append(chunk.size)
    return np.array(rows), np.array(var), np.array(cnt, dtype=float)


def _bin_stats(d: np.ndarray, xc: np.ndarray, order: np.ndarray, n_bins: int) -> _BinStats:
    """Per bin of :func:`estimate_noise_profile`: the rows ``[1, mean(x^2)]``, the MAD variances and the counts.

    The bins are ``np.array_split(order, n_bins)``: at most two sizes, each size's bins contiguous in
    ``order``, so each size is one matrix and its medians come from one sort per row (the same numbers
    as ``np.median`` bin by bin: the middle element, or the mean of the middle two; the row means are
    numpy's pairwise sums of the same contiguous values). Non-finite second differences take the bin
    by bin route (:func:`_bin_stats_loop`: ``np.median`` propagates NaN; a sort does not).
    """
    if not np.all(np.isfinite(d)):
        return _bin_stats_loop(d, xc, order, n_bins)
    n = order.size
    q, r = divmod(n, n_bins)
    mads: list[np.ndarray] = []
    means: list[np.ndarray] = []
    counts: list[np.ndarray] = []
    for start, k, m in ((0, r, q + 1), (r * (q + 1), n_bins - r, q)):  # array_split: the r larger bins first
        if k == 0 or m == 0:
            continue
        idx = order[start : start + k * m].reshape(k, m)
        dd = np.sort(d[idx], axis=1)
        dev = np.sort(np.abs(dd - _sorted_median(dd)[:, None]), axis=1)
        mads.append(_sorted_median(dev))
        means.append(np.mean(xc[idx] ** 2, axis=1))
        counts.append(np.full(k, float(m)))
    mad_all = np.concatenate(mads)
    X = np.column_stack([np.ones(mad_all.size), np.concatenate(means)])
    # the variances in Python floats, as before (``float ** 2`` is C's pow, not numpy's square: the last bit
    # can differ)
    var_all = np.array([(MAD_TO_SIGMA * v) ** 2 / 6.0 for v in mad_all.tolist()])
    return X, var_all, np.concatenate(counts)


def noise_model(x: np.ndarray, given: float | None) -> tuple[float, float]:
    """``(a, b)`` of a channel: ``(given, 0)`` if given, else estimated, with a 0.01 % resolution floor."""
    if given is not None:
        return float(given), 0.0
    a, b = estimate_noise_profile(x)
    floor = 1e-4 * float(np.max(np.abs(x))) + 1e-12  # a 0.01 % resolution floor keeps noise-free data sane
    return max(a, floor), b
