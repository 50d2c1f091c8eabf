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

__all__ = ["CusumDetector", "ExcitationTest", "score_distance"]


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


Sym = tuple[float, float, float]  # a symmetric 2x2 matrix as (a11, a12, a22)


def _solve_sym(M: Sym, g: tuple[float, float]) -> float:
    """``g' M^-1 g`` for a symmetric positive semi-definite ``M`` (0 along a null direction of ``M``)."""
    a, b, d = M
    det = a * d - b * b
    tr = a + d
    if not (tr > 0):
        return 0.0
    if det <= 1e-12 * tr * tr:  # rank one (or none): the component of g along M's range
        return (g[0] * g[0] + g[1] * g[1]) / tr if tr > 0 else 0.0
    return (d * g[0] * g[0] - 2.0 * b * g[0] * g[1] + a * g[1] * g[1]) / det


def score_distance(g: tuple[float, float], A: Sym, P: Sym, inflate: float = 1.0) -> float:
    """Score test of samples against a held estimate of covariance ``P``: ``g' (c A + A P A)^-1 g``, ``c = inflate``.

    ``g`` is the samples' score at the held estimate (``sum r_i d_i``, ``r_i`` the standardised
    residual, ``d_i`` its gradient in the parameters), ``A = sum d_i d_i'`` their information. The
    samples' own one-step estimate of the difference is ``A^-1 g`` with covariance ``A^-1``, the held
    estimate's error adds ``P``; ``(A^-1 g)' (A^-1 + P)^-1 (A^-1 g) = g' (A + A P A)^-1 g``,
    chi-square with 2 degrees of freedom while the soil is the held one. Defined where ``A`` is
    singular too (samples of a pull's ramp only: nothing along the ridge they do not see).
    ``inflate`` (``c``) scales the noise part: ``1 + n b^2`` for ``n`` samples sharing a model error of
    ``b`` noise standard deviations (see :class:`ExcitationTest`).
    """
    a, b, d = A
    p, q, r = P
    # A P A for symmetric A, P
    ap = (a * p + b * q, a * q + b * r, b * p + d * q, b * q + d * r)  # rows of A P: (11, 12, 21, 22)
    apa = (ap[0] * a + ap[1] * b, ap[0] * b + ap[1] * d, ap[2] * b + ap[3] * d)
    c = inflate
    return _solve_sym((c * a + apa[0], c * b + apa[1], c * d + apa[2]), g)


#: The excitation test looks for a change inside the excitation too: every this many samples the
#: statistic of the samples after each candidate split (every this many samples) is computed, and
#: the largest is the statistic (a generalised likelihood ratio over the change time, on a grid).
SPLIT_STRIDE = 5


class ExcitationTest:
    """The samples of one excitation (a pull) against the estimate held when it began: a score test.

    Each sample's profiled residual ``r`` at the reference (the held estimate at the excitation's
    first sample) and its gradient ``d`` in the scaled (F_max, K) are added up as the score
    ``g = sum r d`` and the information ``A = sum d d'``; :func:`score_distance` with the reference's
    covariance (grown by the random walk) is the statistic. It needs no fit of the excitation's
    samples, so it tests a pull's ramp as it comes (a horizon of a ramp alone identifies nothing).

    Parameters
    ----------
    clip
        Each standardised residual is clipped to ``[-clip, clip]`` first (one wild sample cannot
        raise an alarm alone).
    bias
        A model error shared by the samples of one excitation, in noise standard deviations: ``n``
        samples' noise part of the statistic is inflated by ``1 + n bias^2`` (a random effect: many
        samples at one operating point cannot tell a change of soil from a small lean of the model
        there).
    """

    def __init__(self, clip: float, bias: float = 0.0) -> None:
        self.clip, self.bias2 = float(clip), float(bias) ** 2
        self.reset()

    def reset(self) -> None:
        """Forget the excitation (a gap ends it; a change of terrain)."""
        self.ref: tuple[float, float] | None = None
        self.P: Sym = (0.0, 0.0, 0.0)
        self.t_last = -math.inf
        self.times: list[float] = []
        self._rows: list[tuple[float, float, float, float, float]] = []  # (r d0, r d1, d0 d0, d0 d1, d1 d1)
        self._prefix: list[tuple[float, float, float, float, float]] = []  # sums of the rows before each split
        self.g = (0.0, 0.0)
        self.A: Sym = (0.0, 0.0, 0.0)

    @property
    def active(self) -> bool:
        """Whether an excitation is being tested."""
        return self.ref is not None

    def begin(self, t: float, ref: tuple[float, float]) -> None:
        """A new excitation whose first sample arrives at ``t``, tested against ``ref`` (scaled F_max, K)."""
        self.reset()
        self.ref = ref
        self.t_last = t

    def add(self, t: float, r: float, d: tuple[float, float], P: Sym) -> float:
        """Add one sample (residual ``r``, gradient ``d``); ``P`` the reference's covariance now. The statistic."""
        r = min(max(r, -self.clip), self.clip)
        d0, d1 = d
        row = (r * d0, r * d1, d0 * d0, d0 * d1, d1 * d1)
        n = len(self._rows)
        if n % SPLIT_STRIDE == 0:  # a candidate split before this sample: the sums before it
            self._prefix.append((*self.g, *self.A))
        self._rows.append(row)
        self.times.append(t)
        self.t_last = t
        g = self.g = (self.g[0] + row[0], self.g[1] + row[1])
        A = self.A = (self.A[0] + row[2], self.A[1] + row[3], self.A[2] + row[4])
        self.P = P
        b2 = self.bias2
        best = score_distance(g, A, P, 1.0 + (n + 1) * b2)
        if (n + 1) % SPLIT_STRIDE == 0:  # the samples after each candidate split (the first is all of them)
            for j, q in enumerate(self._prefix[1:], 1):
                gq, Aq = (g[0] - q[0], g[1] - q[1]), (A[0] - q[2], A[1] - q[3], A[2] - q[4])
                best = max(best, score_distance(gq, Aq, P, 1.0 + (n + 1 - j * SPLIT_STRIDE) * b2))
        return best

    def change_points(self, margin: float) -> tuple[int, int, int]:
        """The most likely first sample on the new soil, and the range of those within ``margin`` of it.

        For each split ``k`` the statistic of the samples from ``k`` on (those before it on the
        reference's soil) is twice the log-likelihood ratio of a change just before sample ``k``;
        ``(k_best, k_lo, k_hi)`` with ``k_lo..k_hi`` the splits whose statistic is within ``margin``
        of the best (a likelihood interval of the change point).
        """
        g0 = g1 = a = b = d = 0.0
        stats = []
        for m, row in enumerate(reversed(self._rows), 1):
            g0, g1 = g0 + row[0], g1 + row[1]
            a, b, d = a + row[2], b + row[3], d + row[4]
            stats.append(score_distance((g0, g1), (a, b, d), self.P, 1.0 + m * self.bias2))
        stats.reverse()
        best = max(range(len(stats)), key=stats.__getitem__)
        near = [k for k, v in enumerate(stats) if v >= stats[best] - margin]
        return best, near[0], near[-1]
