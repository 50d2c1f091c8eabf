"""Small distribution helpers (Student t, normal) without scipy.

scipy is not a runtime dependency of soiltrack, so the quantiles used for confidence
intervals are computed here: the Student t CDF through the regularised incomplete beta
function (Lentz continued fraction, as in Numerical Recipes ``betacf``) and its quantile by
bisection. Accuracy is about 1e-12 relative, far below what an interval needs.
"""

from __future__ import annotations

import math
from functools import lru_cache

__all__ = ["betainc", "f_sf", "t_cdf", "t_ppf", "norm_cdf", "norm_ppf", "chi2_sf", "chi2_isf", "lr_threshold"]


def _betacf(a: float, b: float, x: float) -> float:
    tiny, eps = 1e-300, 1e-15
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c, d = 1.0, 1.0 - qab * x / qap
    if -tiny < d < tiny:
        d = tiny
    d = 1.0 / d
    h = d
    for m in range(1, 10_000):
        m2 = 2 * m
        aa = m * (b - m) * x / ((qam + m2) * (a + m2))
        d = 1.0 + aa * d
        if -tiny < d < tiny:  # (abs(d) < tiny without the call: the same for every float, NaN too)
            d = tiny
        c = 1.0 + aa / c
        if -tiny < c < tiny:  # (abs(c) < tiny without the call: the same for every float, NaN too)
            c = tiny
        d = 1.0 / d
        h *= d * c
        aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))
        d = 1.0 + aa * d
        if -tiny < d < tiny:  # (abs(d) < tiny without the call: the same for every float, NaN too)
            d = tiny
        c = 1.0 + aa / c
        if -tiny < c < tiny:  # (abs(c) < tiny without the call: the same for every float, NaN too)
            c = tiny
        d = 1.0 / d
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < eps:
            break
    return h


def betainc(a: float, b: float, x: float) -> float:
    """Regularised incomplete beta function I_x(a, b) for a, b > 0 and 0 <= x <= 1."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    lbt = math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x) + b * math.log1p(-x)
    bt = math.exp(lbt)
    if x < (a + 1.0) / (a + b + 2.0):
        return bt * _betacf(a, b, x) / a
    return 1.0 - bt * _betacf(b, a, 1.0 - x) / b


def f_sf(f: float, d1: float, d2: float) -> float:
    """P(X > f) for X with an F(d1, d2) distribution."""
    if not math.isfinite(f):
        return 0.0 if f > 0 else 1.0
    if f <= 0 or d1 <= 0 or d2 <= 0:
        return 1.0
    return betainc(0.5 * d2, 0.5 * d1, d2 / (d2 + d1 * f))


def t_cdf(t: float, dof: float) -> float:
    """CDF of Student's t distribution with ``dof`` degrees of freedom."""
    if dof <= 0:
        raise ValueError(f"degrees of freedom must be > 0, got {dof}")
    if math.isinf(dof):
        return norm_cdf(t)
    x = dof / (dof + t * t)
    tail = 0.5 * betainc(0.5 * dof, 0.5, x)
    return 1.0 - tail if t > 0 else tail


def norm_cdf(z: float) -> float:
    """Standard normal CDF."""
    return 0.5 * math.erfc(-z / math.sqrt(2.0))


def _bisect(f, target: float, lo: float, hi: float) -> float:
    while f(hi) < target:
        hi *= 2.0
        if hi > 1e300:
            return math.inf
    for _ in range(300):
        mid = 0.5 * (lo + hi)
        if f(mid) < target:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-14 * max(1.0, hi):
            break
    return 0.5 * (lo + hi)


@lru_cache(maxsize=4096)
def t_ppf(q: float, dof: float) -> float:
    """Quantile of Student's t distribution (e.g. ``t_ppf(0.975, 1) = 12.706...``)."""
    if not 0.0 < q < 1.0:
        raise ValueError(f"probability must lie in (0, 1), got {q}")
    if dof <= 0:
        raise ValueError(f"degrees of freedom must be > 0, got {dof}")
    if math.isinf(dof):
        return norm_ppf(q)
    if q == 0.5:
        return 0.0
    if q < 0.5:
        return -t_ppf(1.0 - q, dof)
    if dof == 1:
        return math.tan(math.pi * (q - 0.5))
    return _bisect(lambda t: t_cdf(t, dof), q, 0.0, 16.0)


@lru_cache(maxsize=256)
def norm_ppf(q: float) -> float:
    """Quantile of the standard normal distribution."""
    if not 0.0 < q < 1.0:
        raise ValueError(f"probability must lie in (0, 1), got {q}")
    if q == 0.5:
        return 0.0
    if q < 0.5:
        return -norm_ppf(1.0 - q)
    return _bisect(norm_cdf, q, 0.0, 8.0)


def _gamma_prefactor(a: float, x: float) -> float:
    """``x^a e^-x / Gamma(a)``, the factor both expansions of the incomplete gamma share."""
    return math.exp(-x + a * math.log(x) - math.lgamma(a))


def _gammainc_lower_series(a: float, x: float) -> float:
    term = total = 1.0 / a
    ap = a
    for _ in range(1000):
        ap += 1.0
        term *= x / ap
        total += term
        if abs(term) < abs(total) * 1e-15:
            break
    return total * _gamma_prefactor(a, x)


def _gammainc_upper_cf(a: float, x: float) -> float:
    tiny = 1e-300
    b = x + 1.0 - a
    c = 1.0 / tiny
    d = 1.0 / b
    h = d
    for i in range(1, 1000):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = tiny if abs(d) < tiny else d
        c = b + an / c
        c = tiny if abs(c) < tiny else c
        d = 1.0 / d
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < 1e-15:
            break
    return _gamma_prefactor(a, x) * h


def chi2_sf(x: float, dof: float) -> float:
    """P(X > x) for X chi-squared with ``dof`` degrees of freedom (regularised upper gamma)."""
    if not math.isfinite(x):
        return 0.0 if x > 0 else 1.0
    if x <= 0 or dof <= 0:
        return 1.0
    a, y = 0.5 * dof, 0.5 * x
    if y < a + 1.0:
        return max(0.0, 1.0 - _gammainc_lower_series(a, y))
    return min(1.0, _gammainc_upper_cf(a, y))


def chi2_isf(p: float, dof: float) -> float:
    """The x with ``chi2_sf(x, dof) = p`` (bisection on the monotone survival function)."""
    lo, hi = 0.0, max(10.0, 10.0 * dof)
    while chi2_sf(hi, dof) > p:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if chi2_sf(mid, dof) > p:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-10 * max(1.0, hi):
            break
    return 0.5 * (lo + hi)


def lr_threshold(cmin: float, dof: int, sigma_known: bool) -> tuple[float, str]:
    """Profile cost that bounds the 95 % likelihood-ratio interval, and how it was set.

    ``cmin + 1.96^2 / 2`` when sigma is known; ``cmin + s^2 t_{0.975, dof}^2 / 2`` with
    ``s^2 = 2 cmin / dof`` when it is estimated; ``inf`` without residual degrees of freedom.
    """
    if sigma_known:
        return cmin + 0.5 * norm_ppf(0.975) ** 2, "sigma known: Delta(SSR) <= 1.96^2 (chi-square, 1 dof)"
    if dof <= 0:
        return math.inf, "no residual degrees of freedom: the noise level, hence the interval, is unknown"
    s2 = 2.0 * cmin / dof
    return cmin + 0.5 * s2 * t_ppf(0.975, float(dof)) ** 2, f"sigma estimated: Delta(SSR) <= s^2 t^2 (t with {dof} dof)"
