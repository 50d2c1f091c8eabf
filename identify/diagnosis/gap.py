"""Where a model and its measurements part: blocked hold-out, noise floor, localisation.

Pure numpy on residual arrays (measured minus predicted); no model and no fit in here. Used by
:func:`soiltrack.identify.diagnose`.

- :func:`blocked_folds`: contiguous blocks, alternately held out (two folds), never random rows
  (the residuals of a log are correlated; a random split leaks its neighbours).
- :func:`noise_floor`: white-noise level from the second differences of a residual series in
  its natural order (time for a log, slip for a sweep): a smooth gap cancels, the noise stays.
- :func:`localise`: share and significance of the misfit by range of one variable
  (slip, speed, time) or by channel.
- :func:`change_window`: the time window whose residual mean departs most from the rest
  (start and end), e.g. a softer patch of terrain in the middle of a run.
- :func:`whiteness`: autocorrelation and the Ljung-Box test of the residuals.
- :func:`lag_peak`: cross-correlation of the residuals with an input; a peak at a non-zero
  lag points to a delay between channels.
- :func:`chi2_sf`: chi-squared survival function (no scipy at run time).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...soilmodel.tracks import MAD_TO_SIGMA, mad_sigma
from ..estimates.distributions import chi2_isf, chi2_sf  # re-exported (their home is .stats)

__all__ = [
    "blocked_folds",
    "local_medians",
    "noise_floor",
    "noise_profile",
    "long_run_factor",
    "Segment",
    "localise",
    "ChangeWindow",
    "change_window",
    "whiteness",
    "lag_peak",
    "chi2_sf",
    "chi2_isf",
    "isolated_outliers",
    "OUTLIER_Z",
    "range_share",
]


# ----------------------------------------------------------------------------- splits and noise
def blocked_folds(n: int, n_blocks: int = 10) -> list[tuple[np.ndarray, np.ndarray]]:
    """Two folds of contiguous blocks: ``[(train, test), (test, train)]``.

    The ``n`` samples (in their natural order) are cut into ``n_blocks`` contiguous blocks;
    the even blocks form one part, the odd blocks the other. Each part is held out once while
    the model is fitted on the other, so every held-out block has training data on both sides
    (interpolation, not extrapolation) and no held-out sample has a training neighbour closer
    than the block edge.

    Parameters
    ----------
    n
        Number of samples.
    n_blocks
        Number of blocks (reduced for small ``n`` so that every block has at least 2 samples).
    """
    nb = int(max(2, min(n_blocks, n // 2)))
    labels = np.empty(n, dtype=int)
    for k, chunk in enumerate(np.array_split(np.arange(n), nb)):
        labels[chunk] = k % 2
    a, b = np.nonzero(labels == 0)[0], np.nonzero(labels == 1)[0]
    return [(a, b), (b, a)]


def noise_floor(residuals: np.ndarray, order: np.ndarray | None = None) -> float:
    """Root-mean-square level of the white noise in a residual series, from the data alone.

    Second differences ``d_k = r_{k+1} - 2 r_k + r_{k-1}`` in the natural order (``order``:
    indices that sort the samples, e.g. by slip for a sweep) have variance ``6 sigma^2`` for
    white noise, while a smooth gap between model and data nearly cancels. The estimate is the
    root mean square of ``d / sqrt(6)`` after clipping at 5 robust (MAD) standard deviations:
    an RMS, not a median, because it is compared with RMS errors and noise whose level varies
    along the data (relative noise) must count at its mean square; the clip keeps isolated
    steps harmless. Returns 0.0 for fewer than 5 samples.
    """
    r = np.asarray(residuals, dtype=float).ravel()
    if order is not None:
        r = r[np.asarray(order)]
    if r.size < 5:
        return 0.0
    d = r[2:] - 2.0 * r[1:-1] + r[:-2]
    med = float(np.median(d))
    mad = mad_sigma(d)
    if mad > 0:
        d = np.clip(d, med - 5 * mad, med + 5 * mad)
    return float(np.sqrt(np.mean(d**2) / 6.0))


def noise_profile(residuals: np.ndarray, order: np.ndarray | None = None, window: int | None = None) -> np.ndarray:
    """Per-sample noise level of a residual series whose noise varies along the data.

    Sweeps have noise that grows where the curve is steep (slip noise times dF/di at small
    slip) or with the reading (relative noise); logs, where the speed or torque is high. The
    squared second differences (see :func:`noise_floor`) are averaged over a moving window of
    ``window`` neighbours in the natural order (default: about a tenth of the samples, at
    least 7) and divided by 6; the result is floored at a fifth of the global level so that
    a quiet stretch does not make every residual there look significant.

    Returns
    -------
    ndarray
        sigma per sample, in the input's order (not the sorted one).
    """
    r = np.asarray(residuals, dtype=float).ravel()
    n = r.size
    idx = np.arange(n) if order is None else np.asarray(order)
    rs = r[idx]
    glob = noise_floor(rs)
    if n < 5:
        return np.full(n, glob)
    d2 = np.empty(n)
    d = rs[2:] - 2.0 * rs[1:-1] + rs[:-2]
    med = float(np.median(d))
    mad = mad_sigma(d)
    if mad > 0:
        d = np.clip(d, med - 8 * mad, med + 8 * mad)
    d2[1:-1] = d**2 / 6.0
    d2[0], d2[-1] = d2[1], d2[-2]
    w = int(window if window is not None else max(7, n // 10))
    w = max(1, min(w, n))
    cs = np.concatenate([[0.0], np.cumsum(d2)])
    lo = np.clip(np.arange(n) - w // 2, 0, n - w)  # the window slides to stay inside the data
    sm = (cs[lo + w] - cs[lo]) / w
    sig_sorted = np.maximum(np.sqrt(sm), 0.2 * glob)
    out = np.empty(n)
    out[idx] = sig_sorted
    return out


#: Robust z-score from which a lone reading is called an outlier (:func:`isolated_outliers`).
OUTLIER_Z = 5.5


def _row_medians(a: np.ndarray, full: np.ndarray) -> np.ndarray:
    """Median of each row of ``a`` over its non-NaN values (``full``: rows without NaN, the fast path)."""
    out = np.full(a.shape[0], np.nan)
    if np.any(full):
        out[full] = np.median(a[full], axis=1)
    if not np.all(full):
        out[~full] = np.nanmedian(a[~full], axis=1)
    return out


def local_medians(d: np.ndarray, n: int, half: int, split_sides: bool) -> np.ndarray:
    """Per reading ``k`` of ``n``, the median of the second differences ``d`` over ``half`` on each side.

    Leaves out the three that reading ``k`` enters (``d[j]`` is centred on reading ``j + 1``): the left
    side is ``d[k - 2 - half:k - 2]``, the right ``d[k + 1:k + 1 + half]`` (cut at the ends). A side with
    fewer than 3 values does not count; with ``split_sides`` each side's median is taken on its own and
    the larger kept. NaN where nothing counts. Vectorised over the readings in blocks (bounded memory).
    """
    pad = np.concatenate([np.full(half + 2, np.nan), d, np.full(half + 4, np.nan)])
    view = np.lib.stride_tricks.sliding_window_view(pad, half)
    # left window of reading k starts at d index k - 2 - half (pad index k), right one at d index k + 1
    out = np.full(n, np.nan)
    block = max(1, 2_000_000 // max(1, 2 * half))
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN rows: nothing counts there
        for a in range(0, n, block):
            k = np.arange(a, min(n, a + block))
            left, right = view[k], view[k + half + 3]
            nl, nr = np.sum(~np.isnan(left), axis=1), np.sum(~np.isnan(right), axis=1)
            if split_sides:
                ml = np.where(nl >= 3, _row_medians(left, nl == half), np.nan)
                mr = np.where(nr >= 3, _row_medians(right, nr == half), np.nan)
                out[k] = np.fmax(ml, mr)
            else:
                out[k] = np.where(nl + nr >= 3, _row_medians(np.hstack([left, right]), nl + nr == 2 * half), np.nan)
    return np.where(np.isnan(out), 0.0, out)


def isolated_outliers(
    residuals: np.ndarray,
    x: np.ndarray,
    z_min: float = OUTLIER_Z,
    window: int | None = None,
    split_sides: bool = False,
    trend: bool = False,
) -> list[tuple[int, float]]:
    """Lone readings far off their neighbours: a glitch, not a trend an effect could explain.

    In the order of ``x`` (slip or time), each reading is compared with the mean of its two
    neighbours on the left and with that on the right, and the nearer of the two counts: a glitch
    is far from both, a reading at the edge of a step is near one side. The difference is taken
    over a local robust noise level (median absolute deviation of the second differences over
    ``window // 2`` neighbours on each side, default a tenth of the samples and at least 21 in all,
    leaving out the three that the reading itself enters, and never below the level of the whole
    series: a few wild values do not inflate it, a noise that grows along the data is followed,
    and a quiet stretch does not make its readings look wild). With ``split_sides`` each side's
    level is estimated on its own and the larger counts (a signal whose noise changes at a step,
    as a measured signal at its limit does; less sensitive, since each side has half the samples).

    A reading is an outlier when that robust z-score exceeds ``z_min``, no reading within three
    on either side does, and its two neighbours agree within three times the noise of their
    difference: a ramp steeper than the noise, a step, or wild readings close together are not
    lone readings. With ``trend`` (a measured input that ramps fast, such as a torque) each side's
    reference is the straight line through its two readings carried on to this one, and the two
    neighbours need only agree with the local slope of the two outer ones,
    ``|(r[k+1] - r[k-1]) - (r[k+2] - r[k-2]) / 2| < 3 sqrt(2.5) sigma``: a glitch on a ramp is a lone
    reading, a step still is not. The first and last two readings are not judged (one side only).
    At most a tenth of the readings.

    Returns
    -------
    list of (index, z)
        Indices into ``residuals`` and the signed robust z-scores, largest first.
    """
    r = np.asarray(residuals, dtype=float).ravel()
    n = r.size
    if n < 9 or not np.all(np.isfinite(r)):
        return []
    order = np.argsort(np.asarray(x, dtype=float).ravel(), kind="stable")
    rs = r[order]
    d = np.abs(rs[2:] - 2.0 * rs[1:-1] + rs[:-2])
    w = int(window if window is not None else max(21, n // 10))
    w = max(3, min(w, d.size))
    glob = MAD_TO_SIGMA * float(np.median(d)) / math.sqrt(6.0)
    half = max(3, w // 2)
    sig = np.maximum(glob, MAD_TO_SIGMA * local_medians(d, n, half, split_sides) / math.sqrt(6.0))
    sig[:2] = sig[n - 2 :] = 0.0
    # the reading against the mean of its two neighbours on each side, the nearer of the two: a glitch is far
    # from both, a reading at the edge of a step is near one of them (each difference has variance
    # 1.5 sigma^2)
    z = np.zeros(n)
    k = np.arange(2, n - 2)
    if trend:  # each side's straight line through its two readings, carried on to this one (variance 6)
        left, right = 2.0 * rs[k - 1] - rs[k - 2], 2.0 * rs[k + 1] - rs[k + 2]
    else:
        left, right = 0.5 * (rs[k - 2] + rs[k - 1]), 0.5 * (rs[k + 1] + rs[k + 2])
    e = np.where(np.abs(rs[k] - left) < np.abs(rs[k] - right), rs[k] - left, rs[k] - right)
    pos = sig[k] > 0
    z[k[pos]] = e[pos] / (sig[k[pos]] * math.sqrt(6.0 if trend else 1.5))
    cand = np.abs(z) > z_min

    # and the signal continues across it: its two neighbours agree within the noise (not a pair, not a step)
    def continues(k: int) -> bool:
        if trend:
            return abs((rs[k + 1] - rs[k - 1]) - 0.5 * (rs[k + 2] - rs[k - 2])) < 3.0 * math.sqrt(2.5) * sig[k]
        return abs(rs[k + 1] - rs[k - 1]) < 3.0 * math.sqrt(2.0) * sig[k]

    hits = [
        k
        for k in range(2, n - 2)
        if cand[k] and not np.any(cand[max(0, k - 3) : k]) and not np.any(cand[k + 1 : k + 4]) and continues(k)
    ]
    if len(hits) > max(1, n // 10):
        return []
    return sorted(((int(order[k]), float(z[k])) for k in hits), key=lambda t: -abs(t[1]))


def long_run_factor(residuals: np.ndarray, max_lag: int | None = None) -> float:
    """Variance inflation of a mean of correlated residuals, ``1 + 2 sum_k w_k rho_k`` (Bartlett).

    1 for white residuals; larger when neighbouring residuals move together, which is by how
    much a sum of squared standardised residuals overstates the evidence. Floored at 1.
    """
    r = np.asarray(residuals, dtype=float).ravel()
    n = r.size
    if n < 8:
        return 1.0
    r = r - r.mean()
    den = float(r @ r)
    if den <= 0:
        return 1.0
    L = int(max_lag if max_lag is not None else min(n // 4, max(1, round(4 * (n / 100.0) ** (2.0 / 9.0)) * 4)))
    acc = 1.0
    for k in range(1, L + 1):
        rho = float(r[k:] @ r[:-k]) / den
        acc += 2.0 * (1.0 - k / (L + 1.0)) * rho
    return max(1.0, acc)


# ----------------------------------------------------------------------------- localisation
@dataclass(frozen=True)
class Segment:
    """The misfit in one range of one variable (or in one channel).

    Attributes
    ----------
    dimension
        ``"channel"``, ``"slip"``, ``"speed"`` or ``"time"``.
    range
        ``(lo, hi)`` of the variable, or ``None`` for a whole channel.
    channel
        The residual channel the misfit is measured in.
    share
        Fraction of the total misfit (sum of squared standardised residuals above the noise)
        that falls here, 0-1.
    significant
        True when the misfit here exceeds the noise floor (chi-squared test at ``alpha``,
        corrected for correlated residuals).
    mean, rms
        Mean and root-mean-square residual in the segment, in the channel's unit.
    n
        Number of samples.
    """

    dimension: str
    range: tuple[float, float] | None
    channel: str
    share: float
    significant: bool
    mean: float
    rms: float
    n: int

    def to_dict(self) -> dict:
        """The JSON entry of docs/data-formats.md."""
        return {
            "dimension": self.dimension,
            "range": None if self.range is None else [float(self.range[0]), float(self.range[1])],
            "channel": self.channel,
            "share": float(self.share),
            "significant": bool(self.significant),
            "mean": float(self.mean),
            "rms": float(self.rms),
            "n": int(self.n),
        }


def _excess(z: np.ndarray, inflation: float, alpha: float) -> tuple[float, bool]:
    """Misfit above the noise in standardised residuals ``z`` and whether it is significant."""
    n = z.size
    ss = float(z @ z)
    excess = max(0.0, ss - n)
    # chi-squared on the squared mean (most sensitive to offsets) and on the sum of squares (to shape)
    mean_stat = n * float(np.mean(z)) ** 2 / inflation
    ss_stat = n + (ss - n) / inflation
    sig = chi2_sf(mean_stat, 1) < alpha or chi2_sf(ss_stat, n) < alpha
    return excess, bool(sig)


def _standardised(residuals: dict[str, np.ndarray], sigma: dict) -> tuple[dict, dict]:
    """Standardised residuals per channel (0 where the noise level is not positive), long-run factors."""
    z_all, infl = {}, {}
    for ch, r in residuals.items():
        r = np.asarray(r, dtype=float)
        s = np.broadcast_to(np.asarray(sigma.get(ch, 0.0), dtype=float), r.shape)
        z = np.divide(r, s, out=np.zeros_like(r), where=s > 0)
        z_all[ch] = z
        infl[ch] = long_run_factor(z)
    return z_all, infl


def _bins(x: np.ndarray, n_bins: int) -> list[np.ndarray]:
    """Indices of ``n_bins`` ranges of ``x`` holding equal numbers of samples (contiguous in ``x``)."""
    order = np.argsort(x, kind="stable")
    return [c for c in np.array_split(order, min(n_bins, max(1, x.size // 3))) if c.size]


def range_share(
    residuals: dict[str, np.ndarray], sigma: dict, x: np.ndarray, lo: float, hi: float, n_bins: int = 6
) -> tuple[str, float]:
    """The channel with the most misfit above the noise in ``lo <= x <= hi``, and its share of it.

    On the scale of :func:`localise`'s segments of the variable ``x``: the misfit above the noise in
    the range over the total of the variable's ``n_bins`` ranges in every channel, so that an entry
    for a range that :func:`localise` did not cut (a change window, say) sits beside its bins.
    """
    x = np.asarray(x, dtype=float)
    z_all, _ = _standardised(residuals, sigma)
    inside = (x >= lo) & (x <= hi)
    ex = {ch: max(0.0, float(z[inside] @ z[inside]) - int(np.count_nonzero(inside))) for ch, z in z_all.items()}
    total = sum(max(0.0, float(z[c] @ z[c]) - c.size) for z in z_all.values() for c in _bins(x, n_bins))
    ch = max(ex, key=lambda c: ex[c])
    return ch, (min(1.0, ex[ch] / total) if total > 0 else 0.0)


def localise(
    residuals: dict[str, np.ndarray],
    sigma: dict[str, Any],
    variables: dict[str, np.ndarray],
    n_bins: int = 6,
    alpha: float = 0.01,
) -> list[Segment]:
    """Share and significance of the misfit by channel and by range of each variable.

    Parameters
    ----------
    residuals
        ``{channel: residuals}`` on the same samples, measured minus predicted.
    sigma
        ``{channel: noise level}`` in the channel's unit: a number, or one per sample
        (:func:`noise_profile`).
    variables
        ``{"slip" | "speed" | "time": values per sample}``; each is cut into ``n_bins`` ranges
        holding equal numbers of samples (contiguous in the variable).
    alpha
        Significance level of each test (Bonferroni-corrected over the segments of a dimension).

    Returns
    -------
    list of Segment
        Sorted by share, largest first; shares within one dimension sum to 1 (or 0 when there is
        no misfit above the noise).
    """
    out: list[Segment] = []
    z_all, infl = _standardised(residuals, sigma)
    # by channel
    ex = {ch: _excess(z, infl[ch], alpha / max(1, len(z_all))) for ch, z in z_all.items()}
    tot = sum(e for e, _ in ex.values())
    for ch, (e, sig) in ex.items():
        r = np.asarray(residuals[ch], dtype=float)
        out.append(
            Segment(
                "channel",
                None,
                ch,
                e / tot if tot > 0 else 0.0,
                sig,
                float(np.mean(r)),
                float(np.sqrt(np.mean(r**2))),
                int(r.size),
            )
        )
    # by range of each variable, in every channel
    for dim, x in variables.items():
        x = np.asarray(x, dtype=float)
        chunks = _bins(x, n_bins)
        segs = []
        for ch, z in z_all.items():
            r = np.asarray(residuals[ch], dtype=float)
            for c in chunks:
                e, sig = _excess(z[c], infl[ch], alpha / (len(chunks) * len(z_all)))
                segs.append(
                    (
                        e,
                        Segment(
                            dim,
                            (float(x[c].min()), float(x[c].max())),
                            ch,
                            0.0,
                            sig,
                            float(np.mean(r[c])),
                            float(np.sqrt(np.mean(r[c] ** 2))),
                            int(c.size),
                        ),
                    )
                )
        tot = sum(e for e, _ in segs)
        for e, sg in segs:
            out.append(
                Segment(
                    sg.dimension,
                    sg.range,
                    sg.channel,
                    e / tot if tot > 0 else 0.0,
                    sg.significant,
                    sg.mean,
                    sg.rms,
                    sg.n,
                )
            )
    out.sort(key=lambda s: -s.share)
    return out


@dataclass(frozen=True)
class ChangeWindow:
    """The window of a series whose residual mean departs most from the rest of it.

    Attributes
    ----------
    start, end
        Its first and last values of the ordering variable (e.g. time, s).
    shift
        Mean residual inside minus outside, in the channel's unit.
    statistic, p_value
        Chi-squared (1 dof) of the shift, corrected for correlated residuals and for the search
        over windows (Bonferroni over the candidate windows).
    significant
        ``p_value < alpha``.
    """

    channel: str
    start: float
    end: float
    shift: float
    statistic: float
    p_value: float
    significant: bool

    def to_dict(self) -> dict:
        """JSON-friendly dict."""
        return {
            "channel": self.channel,
            "start": float(self.start),
            "end": float(self.end),
            "shift": float(self.shift),
            "statistic": float(self.statistic),
            "p_value": float(self.p_value),
            "significant": bool(self.significant),
        }


def change_window(
    residuals: np.ndarray,
    x: np.ndarray,
    sigma: float,
    channel: str = "",
    n_cells: int = 100,
    alpha: float = 0.01,
) -> ChangeWindow | None:
    """Find the window ``[start, end]`` of ``x`` where the residual mean shifts most (two change points).

    The series is pooled into ``n_cells`` consecutive cells; every window of whole cells (not
    the whole series) is scored by the standardised difference of its mean from the mean
    outside (residuals standardised by ``sigma``, a number or one per sample). The long-run variance
    (:func:`long_run_factor`) of the residuals outside the best
    window corrects for correlation; the p-value is Bonferroni-corrected for the number of
    windows tried. ``None`` when the series is too short or ``sigma`` is not positive.
    """
    raw = np.asarray(residuals, dtype=float).ravel()
    x = np.asarray(x, dtype=float).ravel()
    n = raw.size
    sg = np.broadcast_to(np.asarray(sigma, dtype=float), raw.shape)
    if n < 12 or not np.all(sg > 0):
        return None
    order = np.argsort(x, kind="stable")
    raw, x, r = raw[order], x[order], (raw / sg)[order]  # r: standardised residuals
    cells = np.array_split(np.arange(n), min(n_cells, n // 3))
    m = len(cells)
    sums = np.array([r[c].sum() for c in cells])
    cnts = np.array([c.size for c in cells], dtype=float)
    S = np.concatenate([[0.0], np.cumsum(sums)])
    N = np.concatenate([[0.0], np.cumsum(cnts)])
    a_idx, b_idx = np.triu_indices(m + 1, k=1)  # window = cells a..b-1
    keep = ~((a_idx == 0) & (b_idx == m))
    a_idx, b_idx = a_idx[keep], b_idx[keep]
    n_in = N[b_idx] - N[a_idx]
    s_in = S[b_idx] - S[a_idx]
    n_out = n - n_in
    shift = s_in / n_in - (S[-1] - s_in) / n_out
    z2 = shift**2 / (1.0 / n_in + 1.0 / n_out)
    k = int(np.argmax(z2))
    a, b = int(a_idx[k]), int(b_idx[k])
    inside = np.concatenate([cells[j] for j in range(a, b)])
    mask = np.ones(n, dtype=bool)
    mask[inside] = False
    infl = max(long_run_factor(r[mask] - r[mask].mean()), long_run_factor(r[~mask] - r[~mask].mean()))
    stat = float(z2[k]) / infl
    p = min(1.0, chi2_sf(stat, 1) * a_idx.size)
    raw_shift = float(np.mean(raw[inside]) - np.mean(raw[mask]))
    return ChangeWindow(channel, float(x[inside].min()), float(x[inside].max()), raw_shift, stat, p, bool(p < alpha))


# ----------------------------------------------------------------------------- whiteness and lags
def whiteness(residuals: np.ndarray, max_lag: int = 20) -> dict:
    """Autocorrelation of the residuals and the Ljung-Box test of whiteness.

    Returns ``{"lag1": rho_1, "q": Q, "lags": L, "p_value": p, "white": p >= 0.01}``.
    """
    r = np.asarray(residuals, dtype=float).ravel()
    n = r.size
    L = int(min(max_lag, max(1, n // 5)))
    r = r - r.mean()
    den = float(r @ r)
    if n < 6 or den <= 0:
        return {"lag1": 0.0, "q": 0.0, "lags": L, "p_value": 1.0, "white": True}
    rho = np.array([float(r[k:] @ r[:-k]) / den for k in range(1, L + 1)])
    q = float(n * (n + 2) * np.sum(rho**2 / (n - np.arange(1, L + 1))))
    p = chi2_sf(q, L)
    return {"lag1": float(rho[0]), "q": q, "lags": L, "p_value": p, "white": bool(p >= 0.01)}


def lag_peak(residuals: np.ndarray, signal: np.ndarray, max_lag: int = 25) -> dict:
    """Cross-correlation of the residuals with an input signal, lags ``-max_lag..max_lag`` samples.

    Correlation at lag ``k`` is that of ``residuals[t]`` with ``signal[t - k]``. A peak away from
    lag 0 that stands well above the rest points to a delay between the channels.

    Returns ``{"lag": k at the peak, "corr": its correlation, "corr_at_0": ..., "bound": 2.58/sqrt(n)}``
    (``bound``: the 1 % band of a white series).
    """
    r = np.asarray(residuals, dtype=float).ravel()
    s = np.asarray(signal, dtype=float).ravel()
    n = r.size
    r = r - r.mean()
    s = s - s.mean()
    den = math.sqrt(float(r @ r) * float(s @ s))
    if n < 8 or den <= 0:
        return {"lag": 0, "corr": 0.0, "corr_at_0": 0.0, "bound": float("inf")}
    L = int(min(max_lag, n // 4))
    cc = {}
    for k in range(-L, L + 1):
        if k >= 0:
            cc[k] = float(r[k:] @ s[: n - k]) / den
        else:
            cc[k] = float(r[: n + k] @ s[-k:]) / den
    kbest = max(cc, key=lambda k: abs(cc[k]))
    return {"lag": int(kbest), "corr": cc[kbest], "corr_at_0": cc[0], "bound": 2.58 / math.sqrt(n)}
