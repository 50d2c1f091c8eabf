"""Slip measured with noise: effective-variance weights for slip sweeps.

A rig measures the slip too, from a wheel encoder and the carriage speed, and a slip error
``delta i`` moves a sample by ``dy/di delta i``. On the steep start of the thrust-slip curve
(``dy/di -> F_max l / (2 K)`` as ``i -> 0``; about 2 MN per unit slip for a 33 t vehicle with
K = 1.2 cm) a slip error of 0.001 moves the force by kilonewtons, more than a load cell's
noise. A fit that takes the slip as exact then trusts the first few samples far too much, and
where a parameter is nearly confounded with another (a grade with phi in a drawbar sweep) it
can land confidently on the wrong side.

The cure used here is the effective-variance method (first order in the slip error): each
sample's variance is

    var_k = s^2 b_k^2 + sigma_i^2 (dy/di)_k^2,

with ``b`` the force weights of the fit (equal unless given), ``s`` the force-noise level
(estimated unless ``sigma_known``), ``sigma_i`` the slip-noise standard deviation and
``dy/di`` the slope of the model at the fitted parameters (by AD of the same sweep model:
:func:`~soiltrack.identify.sweep.model.slip_slope`). Weights and fit are iterated to a fixed
point.

``slip_noise="auto"`` (the default of joint soil-and-effect fits) estimates ``sigma_i`` by
maximum likelihood from the residuals of the exact-slip fit and adopts it only when a
likelihood-ratio test says the residual spread grows with ``(dy/di)^2`` (p < 0.01, against the
half-and-half chi-square mixture of a variance on its zero bound). A number is a known
``sigma_i``; ``"off"`` takes the slip as exact. What was done is in ``result.extra["slip_noise"]``
and said in the report. A misfit of the model at small slips (the wrong shear law, say) also
puts large residuals where the slope is steep, and this test cannot tell it from slip noise:
the report says so when it adopts the weights.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...soilmodel.errors import DataError
from ...soilmodel.search import golden_section
from ..estimates.result import FitResult
from .model import fit_vector, slip_slope
from .problem import SlipProblem

__all__ = [
    "SlipNoise",
    "estimate_slip_noise",
    "leverage",
    "serial_correlation",
    "check_slip_noise",
    "fit_with_slip_noise",
    "LR_CRITICAL",
]

#: Likelihood-ratio level above which slip noise is adopted: p = 0.01 under the mixture
#: 0.5 chi2(0) + 0.5 chi2(1) of a variance tested on its zero bound (P(chi2(1) > 5.412) = 0.02).
LR_CRITICAL = 5.412
#: Fewest samples on which a slip-noise level is estimated.
MIN_SAMPLES = 10
#: Fixed-point iterations of weights and fit, and the relative change of the weights that ends them.
MAX_ITER = 8
WEIGHT_RTOL = 1e-3


@dataclass(frozen=True)
class SlipNoise:
    """What the fit assumed about noise on the measured slip.

    Attributes
    ----------
    mode : {"auto", "given", "off"}
    adopted : bool
        Whether the weights include the slip noise.
    slip_sigma : float or None
        Standard deviation of the slip error (-), given or estimated.
    force_sigma : float or None
        Force-noise level ``s`` (N, for equal weights) the effective variance was combined with.
    likelihood_ratio : float or None
        ``2 (log L(sigma_i) - log L(0))`` on the exact-slip fit's residuals (``auto`` only).
    iterations : int
        Refits of the fixed point of weights and fit.
    converged : bool
        Whether the weights stopped changing (relative change below 1e-3).
    note : str
    """

    mode: str
    adopted: bool
    slip_sigma: float | None = None
    force_sigma: float | None = None
    likelihood_ratio: float | None = None
    iterations: int = 0
    converged: bool = True
    note: str = ""

    def to_dict(self) -> dict:
        """JSON-ready dict."""
        f = lambda x: None if x is None or not math.isfinite(x) else float(x)  # noqa: E731
        return {
            "mode": self.mode,
            "adopted": self.adopted,
            "slip_sigma": f(self.slip_sigma),
            "force_sigma_N": f(self.force_sigma),
            "likelihood_ratio": f(self.likelihood_ratio),
            "threshold": LR_CRITICAL if self.mode == "auto" else None,
            "iterations": self.iterations,
            "converged": self.converged,
            "note": self.note,
        }


def check_slip_noise(value) -> str | float:
    """Validate ``slip_noise``: ``"auto"``, ``"off"`` or a slip standard deviation in ``(0, 0.5)``."""
    if isinstance(value, str):
        if value in ("auto", "off"):
            return value
        try:
            value = float(value)
        except ValueError:
            raise DataError(
                f"slip_noise must be 'auto', 'off' or a slip standard deviation (a number in (0, 0.5)), got {value!r}"
            ) from None
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not (0.0 < float(value) < 0.5)
        or not math.isfinite(float(value))
    ):
        raise DataError(f"slip_noise must be 'auto', 'off' or a slip standard deviation in (0, 0.5), got {value!r}")
    return float(value)


def _loglik(r2: np.ndarray, v: np.ndarray, level_known: bool) -> float:
    """Gaussian log-likelihood (constants dropped) of residuals with variances ``s^2 v``, ``s^2`` profiled out
    (or ``s = 1`` when ``level_known``)."""
    if level_known:
        return -0.5 * float(np.sum(np.log(v)) + np.sum(r2 / v))
    s2 = float(np.mean(r2 / v))
    return -0.5 * float(np.sum(np.log(s2 * v))) - 0.5 * r2.size if s2 > 0 else math.inf


def estimate_slip_noise(
    residuals, slope, base_sigma, sigma_known: bool, slip_sigma: float | None = None
) -> tuple[float, float, float]:
    """Maximum-likelihood variance components ``(slip_sigma, s, likelihood ratio)``.

    Model: ``var_k = s^2 b_k^2 + slip_sigma^2 slope_k^2`` (``s = 1`` when ``sigma_known``). With
    ``slip_sigma`` given only ``s`` is estimated (and the ratio is ``nan``). Searched on a log
    grid of the ratio ``kappa = (slip_sigma / s)^2``, refined by golden section.
    """
    r2 = np.asarray(residuals, float) ** 2
    d2 = np.asarray(slope, float) ** 2
    b2 = np.asarray(base_sigma, float) ** 2
    if slip_sigma is not None:
        if sigma_known:
            return float(slip_sigma), 1.0, math.nan
        # s^2 with slip_sigma fixed: 1-D search on s^2 over a wide log range around the plain estimate
        plain = float(np.mean(r2 / b2))

        def nll(ls2):
            v = math.exp(ls2) * b2 + slip_sigma**2 * d2
            return 0.5 * float(np.sum(np.log(v)) + np.sum(r2 / v))

        ls2 = _minimise_1d(nll, math.log(max(plain, 1e-300)) - 20.0, math.log(max(plain, 1e-300)) + 2.0)
        return float(slip_sigma), math.sqrt(math.exp(ls2)), math.nan
    dmax = float(np.max(d2)) if d2.size else 0.0
    if dmax <= 0:
        return 0.0, math.sqrt(float(np.mean(r2 / b2))) if not sigma_known else 1.0, 0.0
    # kappa d^2 / b^2 from 1e-6 (invisible) to 1e6 (slip noise dominates everywhere)
    bmin = float(np.min(b2))
    lk_lo, lk_hi = math.log(1e-6 * bmin / dmax), math.log(1e6 * float(np.max(b2)) / float(np.min(d2[d2 > 0])))

    def nll_k(lk):
        return -_loglik(r2, b2 + math.exp(lk) * d2, sigma_known)

    grid = np.linspace(lk_lo, lk_hi, 121)
    vals = np.array([nll_k(g) for g in grid])
    k = int(np.argmin(vals))
    l0 = -_loglik(r2, b2, sigma_known)
    if vals[k] >= l0:  # no slope-driven spread
        return 0.0, math.sqrt(float(np.mean(r2 / b2))) if not sigma_known else 1.0, 0.0
    lk = _minimise_1d(nll_k, grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)])
    kappa = math.exp(lk)
    v = b2 + kappa * d2
    s2 = 1.0 if sigma_known else float(np.mean(r2 / v))
    lr = max(0.0, 2.0 * (l0 - nll_k(lk)))
    return math.sqrt(kappa * s2), math.sqrt(s2), lr


def _minimise_1d(f, a: float, b: float, tol: float = 1e-4) -> float:
    """Golden-section minimum of ``f`` on ``[a, b]`` (:func:`~soiltrack.soilmodel.search.golden_section`)."""
    return golden_section(f, a, b, tol=tol).midpoint


def serial_correlation(residuals, sigma, slip, load) -> float:
    """Lag-1 correlation of ``residuals / sigma`` in slip order within each normal load, as a z score.

    Noise on the slip leaves neighbouring samples independent; a model that misses the curve's
    shape leaves residuals that change smoothly with the slip. ``sqrt(n) rho_1`` is about
    standard normal under independence.
    """
    z = np.asarray(residuals, float) / np.asarray(sigma, float)
    num = den = 0.0
    n = 0
    keys = np.round(np.asarray(load, float), 3)
    for w in np.unique(keys):
        idx = np.nonzero(keys == w)[0]
        if idx.size < 3:
            continue
        zz = z[idx[np.argsort(np.asarray(slip, float)[idx], kind="stable")]]
        zz = zz - zz.mean()
        num += float(zz[1:] @ zz[:-1])
        den += float(zz @ zz)
        n += idx.size
    return num / den * math.sqrt(n) if den > 0 and n else 0.0


#: z score of :func:`serial_correlation` above which a slope-driven spread is read as misfit, not slip noise.
SERIAL_Z = 2.576


def leverage(res) -> np.ndarray:
    """Diagonal of the hat matrix of the weighted fit (free columns), capped at 0.95.

    A fitted residual has variance ``var_k (1 - h_k)``: the samples that pin the parameters
    (the steep start of the curve pins K) are fitted closely whatever their noise, so the
    variance components are estimated from ``r_k / sqrt(1 - h_k)``.
    """
    J = np.asarray(res.jacobian, float)[:, list(res.free)]
    if J.size == 0:
        return np.zeros(J.shape[0])
    Q, R = np.linalg.qr(J / np.maximum(np.linalg.norm(J, axis=0), 1e-300))
    keep = np.abs(np.diag(R)) > 1e-10 * max(float(np.max(np.abs(np.diag(R)))), 1e-300)
    h = np.sum(Q[:, keep] ** 2, axis=1)
    return np.minimum(h, 0.95)


def fit_with_slip_noise(pb, solve, mode) -> tuple[FitResult, SlipNoise, SlipProblem]:
    """Fit ``pb`` with ``solve(pb, start_x) -> FitResult`` under the slip-noise ``mode``.

    Returns the final result, what was assumed (:class:`SlipNoise`) and the problem with the
    weights of the final fit. ``"off"`` (or too few
    samples) is one plain solve. Otherwise the exact-slip fit comes first; ``"auto"`` keeps it
    unless the likelihood ratio exceeds :data:`LR_CRITICAL`; then weights and fit are iterated.
    """
    res = solve(pb, None)
    if mode == "off":
        return res, SlipNoise("off", False, note="slip taken as exact"), pb
    early = _exact_slip_only(res, pb, mode)
    if early is not None:
        return early
    base = pb.sigma
    given = None if mode == "auto" else float(mode)

    def components(r):
        d = slip_slope(fit_vector(r), pb.slip, pb.load, pb.vehicle, pb.effects, pb.model, pb.measured, pb.rig_speed)
        return d, estimate_slip_noise(r.residuals / np.sqrt(1.0 - leverage(r)), d, base, pb.sigma_known, given)

    d, (ss, s, lr) = components(res)
    if given is None and not lr > LR_CRITICAL:
        return (
            res,
            SlipNoise(
                "auto",
                False,
                ss,
                s,
                lr,
                note=f"the residual spread does not grow with the slope dF/di as slip noise would make "
                f"it (likelihood ratio {lr:.3g} <= {LR_CRITICAL}): slip taken as exact",
            ),
            pb,
        )
    sig = np.sqrt((s * base) ** 2 + (ss * d) ** 2)
    zs = serial_correlation(res.residuals, sig, pb.slip, pb.load)
    if given is None and zs > SERIAL_Z:
        return (
            res,
            SlipNoise(
                "auto",
                False,
                ss,
                s,
                lr,
                note=(
                    "the residual spread grows with the slope dF/di "
                    f"(likelihood ratio {lr:.3g} > {LR_CRITICAL}), but the residuals change smoothly with "
                    f"the slip (lag-1 correlation z = {zs:.3g} > {SERIAL_Z}): a misfit of "
                    "the model's shape, not noise on the slip, so the slip is taken as exact"
                ),
            ),
            pb,
        )
    it, converged, last, last_pb, ss, s = _iterate_weights(pb, solve, res, components, (sig, ss, s))
    if last is res:  # the first weighted fit failed: keep the exact-slip fit, say so
        return (
            res,
            SlipNoise(
                "auto" if given is None else "given",
                False,
                ss,
                s,
                lr if given is None else None,
                it,
                False,
                "the fit with slip-noise weights did not succeed: slip taken as exact",
            ),
            pb,
        )
    note = "" if converged else f"the slip-noise weights were still changing after {it} refits; "
    if given is None:
        note += (
            f"the residual spread grows with the slope dF/di as noise on the measured slip makes it "
            f"(likelihood ratio {lr:.3g} > {LR_CRITICAL}), so the fit weights the samples for it (see noise); "
            "a model misfit at small slips would look the same: if the slip is measured exactly, refit with "
            "slip_noise='off' (--slip-noise off) and compare"
        )
    return (
        last,
        SlipNoise(
            "auto" if given is None else "given",
            True,
            ss,
            s * float(np.median(base)),
            lr if given is None else None,
            it,
            converged,
            note,
        ),
        last_pb,
    )


def _exact_slip_only(res: FitResult, pb: SlipProblem, mode) -> tuple[FitResult, SlipNoise, SlipProblem] | None:
    """The exact-slip answer when there are too few samples or its fit failed; None to go on."""
    if pb.n < MIN_SAMPLES:
        return (
            res,
            SlipNoise(
                "auto" if mode == "auto" else "given",
                False,
                note=f"fewer than {MIN_SAMPLES} samples: slip taken as exact",
            ),
            pb,
        )
    if not res.success:
        return (
            res,
            SlipNoise(
                "auto" if mode == "auto" else "given",
                False,
                note="the exact-slip fit did not succeed: no slip-noise weights",
            ),
            pb,
        )
    return None


def _iterate_weights(pb: SlipProblem, solve, res: FitResult, components, start: tuple):
    """Refit with the slip-noise weights until they settle: ``(refits, converged, last, its problem, ss, s)``."""
    base = pb.sigma
    sig, ss, s = start
    it, converged, last, last_pb = 0, False, res, pb
    while it < MAX_ITER:
        it += 1
        q = replace(pb, sigma=sig / s)  # relative weights when the level is estimated (s = 1 when known)
        cur = solve(q, fit_vector(last))
        if not cur.success:
            break
        last, last_pb = cur, q
        d, (ss_new, s_new, _) = components(cur)
        sig_new = np.sqrt((s_new * base) ** 2 + (ss_new * d) ** 2)
        change = float(np.max(np.abs(sig_new - sig) / sig))
        sig, ss, s = sig_new, ss_new, s_new
        if change < WEIGHT_RTOL:
            converged = True
            break
    return it, converged, last, last_pb, ss, s
