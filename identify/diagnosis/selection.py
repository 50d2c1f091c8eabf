"""Deciding which effect explains a gap: blocked cross-validation weights, the discrepancy term, the verdict.

Every model compared - the nominal one (``"none"``), each candidate effect kept by screening,
and a flexible discrepancy term standing for "something else" - is fitted on one part of the
data and scored on the other (the two folds of :func:`~.gap.blocked_folds`), as the sum of
squared held-out residuals standardised by each channel's noise floor. Held-out error is an
estimate of minus twice the predictive log-likelihood, so the weights

    w_m  proportional to  exp(-(S_m - S_min) / (2 f))

are Akaike-type weights computed on data the fit did not see; ``f`` (>= 1) is the long-run
variance factor of the residuals (:func:`~.gap.long_run_factor`): correlated residuals carry
less evidence than their count says.

The discrepancy term adds, to the nominal model's prediction, a low-order linear spline (hat
functions on quantile knots) fitted to the nominal training residuals - in slip for a sweep,
in time for a log. It is deliberately a two-stage fit (the soil is not refitted with it): it
stands for any smooth gap, which no named effect can claim.

The verdict (:func:`decide`):

- ``none`` when no candidate's score test is significant and the discrepancy term does not
  predict the held-out data significantly better than the nominal model (Diebold-Mariano
  test, :func:`dm_test`), or when the nominal model outweighs every candidate;
- ``unexplained`` when the discrepancy term predicts significantly better than the best
  candidate, or when the best candidate still leaves a significant gap on held-out data (its
  held-out RMS more than ``gap_ratio`` times the noise floor);
- otherwise the best candidate. ``confidence`` is the weight of the verdict (for
  ``unexplained``: the weight not carried by the best candidate).

Weights are flattened (``f`` larger) when the held-out squared residuals are more dispersed
than Gaussian noise makes them (``var(z^2) > 2``): a few large residuals are weak evidence.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..estimates.distributions import chi2_sf

__all__ = [
    "SEPARATING_EXPERIMENTS",
    "separating_experiment",
    "hat_basis",
    "fit_discrepancy",
    "cv_weights",
    "Verdict",
    "decide",
    "confusable_groups",
    "dm_test",
    "gap_p_value",
    "stacking_weights",
]

DISCREPANCY = "discrepancy"
NOMINAL = "none"

#: What experiment separates two effects that a given data set cannot tell apart (docs/physics.md,
#: "Unmodelled effects": where each effect leaves its signature).
SEPARATING_EXPERIMENTS: dict[frozenset, str] = {
    frozenset({"mass_error", "grade"}): "a run at another payload, or the same run with different "
    "accelerations (a mass error scales with dv/dt, a grade does not), or the same stretch driven in "
    "both directions (a grade changes sign)",
    frozenset({"speed_resistance", "drivetrain_friction"}): "a torque sensor at the track (or a coast-down "
    "with the drive disengaged): a viscous drivetrain loss is between sensor and track, speed resistance "
    "is outside",
    frozenset({"hump_shear", "slip_sinkage"}): "measure the sinkage, or the drawbar pull at high slip "
    "(beyond 30 %): strain softening lowers the thrust itself, slip sinkage only adds resistance",
    frozenset({"grade", "slip_sinkage"}): "a sweep down to very small slip (or a run at near-constant slip "
    "on level ground): a grade costs force at every slip, slip sinkage only as the slip grows",
    frozenset({"grade", "drivetrain_friction"}): "the same stretch driven in both directions (a grade changes "
    "sign, a drivetrain loss does not), a coast-down, or a torque sensor at the track: Coulomb drivetrain "
    "friction acts between sensor and track, a grade on the hull",
    frozenset({"mass_error", "radius_error"}): "a speed reference independent of the sprocket (e.g. a "
    "measured distance over a timed run): a radius error offsets the apparent slip by -eps, a mass "
    "error does not",
    frozenset({"radius_error", "grade"}): "measure the track's effective radius (distance per sprocket turn at "
    "zero drawbar on firm ground)",
    frozenset({"hump_shear", "pressure_distribution"}): "a sweep at two normal loads or two centre-of-gravity "
    "positions: the pressure distribution moves with the load transfer, strain softening does not",
    frozenset({"pressure_distribution", "radius_error"}): "measure the effective radius on firm ground; a "
    "radius error shifts the whole slip axis, a pressure distribution reshapes the curve",
    frozenset({"speed_resistance", "grade"}): "runs at two constant speeds: speed resistance grows with "
    "speed, a grade does not",
    frozenset({"speed_resistance", "slip_sinkage"}): "runs at the same slip and two speeds (or the same "
    "speed and two drawbar loads)",
    frozenset({"mass_error", "speed_resistance"}): "runs at two constant speeds and an acceleration run",
    frozenset({"mass_error", "slip_sinkage"}): "a run at constant speed with a different drawbar load (slip sinkage "
    "grows with the slip, a mass error only shows with acceleration), or a run at another payload",
    frozenset({"drivetrain_friction", "radius_error"}): "a torque sensor at the track or a coast-down; "
    "and a measured distance per sprocket turn",
}


#: Causes outside the library that leave the same signature as an effect: a diagnosis that names the
#: effect says that these would look the same.
LOOKALIKES = {
    "grade": "any constant extra force on the vehicle (a towed load, a steady wind, compaction resistance) "
    "and a zero offset of the force sensor (a sweep) or of the accelerometer (a drive log)",
    "drivetrain_friction": "a zero offset of the torque sensor (it looks like the Coulomb part)",
    "radius_error": "a scale error of the vehicle-speed sensor (it shifts the apparent slip the same way; only "
    "the torque arm differs)",
    "mass_error": "a scale error of the accelerometer (in the hull balance; a mass error also changes the normal load)",
    "slip_sinkage": "any resistance that grows with the slip (bulldozing, a track digging in)",
    "speed_resistance": "any resistance that grows with speed (air drag, a viscous loss in the running gear)",
}


def separating_experiment(a: str, b: str) -> str:
    """The experiment that separates effects ``a`` and ``b`` (a generic advice when none is tabled)."""
    text = SEPARATING_EXPERIMENTS.get(frozenset({a, b}))
    if text:
        return text
    return (
        f"data over a wider range of the variables where {a} and {b} differ (other slips, speeds, "
        "loads or accelerations), or a direct measurement of one of them"
    )


# ----------------------------------------------------------------------------- discrepancy term
def hat_basis(x: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """Linear B-splines (hat functions) on ``knots``: ``(n, len(knots))``; rows sum to 1.

    Outside the knot range the two end functions continue linearly (linear extrapolation of
    the spline, so a held-out block at either end of the data is predicted by the trend of
    its neighbour, not by a constant).
    """
    x = np.asarray(x, dtype=float).ravel()
    knots = np.asarray(knots, dtype=float)
    B = np.zeros((x.size, knots.size))
    xc = np.clip(x, knots[0], knots[-1])
    for j, kj in enumerate(knots):
        if j > 0:
            lo = knots[j - 1]
            m = (xc >= lo) & (xc <= kj)
            B[m, j] = (xc[m] - lo) / (kj - lo)
        if j < knots.size - 1:
            hi = knots[j + 1]
            m = (xc >= kj) & (xc <= hi)
            B[m, j] = np.maximum(B[m, j], (hi - xc[m]) / (hi - kj))
    for m, (a, b) in ((x < knots[0], (0, 1)), (x > knots[-1], (-1, -2))):
        if np.any(m):
            u = (x[m] - knots[a]) / (knots[b] - knots[a])  # negative beyond the end
            B[m, :] = 0.0
            B[m, a] = 1.0 - u
            B[m, b] = u
    return B


def fit_discrepancy(
    x_train: np.ndarray, r_train: np.ndarray, x_test: np.ndarray, n_knots: int, ridge: float = 1e-6
) -> tuple[np.ndarray, int]:
    """Fit a hat-function spline in ``x`` to training residuals and predict it at ``x_test``.

    Knots at quantiles of ``x_train``; a tiny ridge keeps empty knot intervals harmless.
    Returns the predicted residual at ``x_test`` and the number of spline coefficients.
    """
    x_train = np.asarray(x_train, dtype=float)
    k = int(max(2, min(n_knots, np.unique(x_train).size)))
    knots = np.unique(np.quantile(x_train, np.linspace(0.0, 1.0, k)))
    if knots.size < 2:
        return np.full(np.size(x_test), float(np.mean(r_train))), 1
    B = hat_basis(x_train, knots)
    scale = float(np.mean(B.T @ B).real) or 1.0
    beta = np.linalg.solve(B.T @ B + ridge * scale * np.eye(knots.size), B.T @ np.asarray(r_train, dtype=float))
    return hat_basis(x_test, knots) @ beta, int(knots.size)


# ----------------------------------------------------------------------------- weights and verdict
def cv_weights(scores: dict[str, float], inflation: float = 1.0) -> dict[str, float]:
    """Akaike-type weights from held-out scores (sum of squared standardised held-out residuals)."""
    finite = {k: v for k, v in scores.items() if v is not None and math.isfinite(v)}
    if not finite:
        return {k: 0.0 for k in scores}
    smin = min(finite.values())
    raw = {k: math.exp(-(v - smin) / (2.0 * max(1.0, inflation))) for k, v in finite.items()}
    tot = sum(raw.values())
    return {k: raw.get(k, 0.0) / tot for k in scores}


def stacking_weights(
    pointwise: dict[str, np.ndarray], block: int = 1, n_boot: int = 400, seed: int = 20261123
) -> dict[str, float]:
    """Pseudo-BMA+ weights: Akaike-type weights averaged over a Bayesian bootstrap of the held-out samples.

    ``pointwise[m]`` is the held-out log score of model ``m`` per sample (``-z^2/2`` for noise-
    standardised residuals ``z``), all on the same samples. The samples are grouped into
    consecutive blocks of ``block`` (correlated residuals of a log move together); each
    replicate draws Dirichlet(1, ..., 1) weights over the blocks, forms every model's total
    score under them, and takes the softmax. Averaging over replicates (Yao et al. 2018,
    "Using stacking to average Bayesian predictive distributions", pseudo-BMA+) keeps a gain that
    rests on a few samples from looking certain. A non-finite score gets weight 0.
    Deterministic (fixed ``seed``).
    """
    names = list(pointwise)
    if not names:
        return {}
    P = np.vstack([np.asarray(pointwise[m], dtype=float) for m in names])
    P = np.where(np.isnan(P), -np.inf, P)
    n = P.shape[1]
    if n == 0:
        return {m: 1.0 / len(names) for m in names}
    b = int(max(1, min(block, n)))
    edges = np.arange(0, n, b)
    S = np.add.reduceat(P, edges, axis=1)  # (models, blocks)
    nb = S.shape[1]
    rng = np.random.default_rng(seed)
    A = rng.dirichlet(np.ones(nb), size=n_boot)  # (boot, blocks)
    finite = np.all(np.isfinite(S), axis=1)
    out = np.zeros(len(names))
    if not np.any(finite):
        return {m: 0.0 for m in names}
    E = nb * A @ S[finite].T  # (boot, finite models)
    E = E - E.max(axis=1, keepdims=True)
    W = np.exp(E)
    W /= W.sum(axis=1, keepdims=True)
    out[finite] = W.mean(axis=0)
    return {m: float(w) for m, w in zip(names, out)}


def confusable_groups(
    weights: dict[str, float],
    directions: dict[str, np.ndarray | None],
    min_ratio: float = 0.2,
    min_corr: float = 0.9,
    min_weight: float = 0.05,
    verdict: str | None = None,
) -> list[tuple[tuple[str, ...], float]]:
    """Pairs of candidates the data cannot tell apart.

    A pair of named candidates is confusable when their weights are close (the smaller at least
    ``min_ratio`` of the larger and at least ``min_weight``) and their projected sensitivity
    directions (what each would change in the residuals, beyond the soil) are collinear
    (``|corr| >= min_corr``, or unknown). Collinear sensitivities alone are not enough: they
    are local (at "effect off"), and a refit that the held-out data clearly prefer has told the
    two apart. Returns ``[((a, b), corr), ...]`` (corr NaN when a direction is unknown).
    """
    names = [k for k in weights if k not in (NOMINAL, DISCREPANCY)]
    out = []
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            wa, wb = weights[a], weights[b]
            if max(wa, wb) < min_weight and verdict not in (a, b):
                continue
            da, db = directions.get(a), directions.get(b)
            ok = da is not None and db is not None and np.linalg.norm(da) > 0 and np.linalg.norm(db) > 0
            corr = float(abs(np.dot(da, db)) / (np.linalg.norm(da) * np.linalg.norm(db))) if ok else float("nan")
            close = min(wa, wb) >= max(min_ratio * max(wa, wb), min_weight)
            if close and (not math.isfinite(corr) or corr >= min_corr):
                out.append(((a, b), corr))
    return out


def dm_test(z_a: np.ndarray, z_b: np.ndarray, lag: int = 0) -> float:
    """One-sided Diebold-Mariano p-value that model b predicts the held-out data better than model a.

    ``d_t = z_a[t]^2 - z_b[t]^2`` (standardised held-out residuals of the same samples); the
    statistic is ``mean(d) / se(mean(d))`` with a Newey-West (Bartlett, ``lag``) variance, so a
    few large residuals or correlated ones do not make a small average gain look certain.
    """
    d = np.asarray(z_a, dtype=float) ** 2 - np.asarray(z_b, dtype=float) ** 2
    d = d[np.isfinite(d)] if np.all(np.isfinite(z_a)) or np.all(np.isfinite(z_b)) else d
    n = d.size
    if n < 3:
        return 1.0
    if not np.all(np.isfinite(d)):
        return 1.0
    m = float(np.mean(d))
    e = d - m
    v = float(e @ e) / n
    for k in range(1, min(lag, n - 1) + 1):
        v += 2.0 * (1.0 - k / (lag + 1.0)) * float(e[k:] @ e[:-k]) / n
    if v <= 0:
        return 0.0 if m > 0 else 1.0
    t = m / math.sqrt(v / n)
    return 0.5 * math.erfc(t / math.sqrt(2.0))


@dataclass(frozen=True)
class Verdict:
    """The decision: ``name`` (effect, ``"none"`` or ``"unexplained"``), ``confidence`` and why."""

    name: str
    confidence: float
    reason: str


def decide(
    weights: dict[str, float],
    significant: list[str],
    disc_beats: dict[str, float],
    after_ratio: dict[str, float],
    after_p: dict[str, float],
    alpha: float = 0.01,
    gap_ratio: float = 1.5,
    evidence: str = "predicts the held-out data",
    gap: bool | None = None,
) -> Verdict:
    """The verdict from the weights and tests (see the module docstring).

    Parameters
    ----------
    weights
        Weights of ``"none"``, ``"discrepancy"`` and the refitted candidates (cross-validation
        weights, or for a sweep information-criterion weights on all the data).
    significant
        Candidates whose score test was significant.
    disc_beats
        Per model (``"none"`` and each refitted candidate): p-value that the discrepancy term
        predicts the held-out data better (:func:`dm_test`).
    after_ratio, after_p
        Per refitted candidate: held-out RMS over the noise floor (worst channel; ``inf`` when a
        flexible term on top of the candidate still predicts significantly better) and the
        p-value of its held-out error against the noise floor.
    evidence
        What the weights measure, for the reasons (``"predicts the held-out data"`` or, on
        sweeps, ``"fits all the data"``).
    gap
        Whether a gap is seen; default: the discrepancy term predicts the held-out data
        significantly better than the nominal model (``disc_beats["none"] < alpha``).
    """
    w_none = weights.get(NOMINAL, 0.0)
    w_disc = weights.get(DISCREPANCY, 0.0)
    if gap is None:
        gap = disc_beats.get(NOMINAL, 1.0) < alpha
    named = {k: w for k, w in weights.items() if k not in (NOMINAL, DISCREPANCY)}
    if not significant and not gap:
        return Verdict(
            NOMINAL,
            max(w_none, 1.0 - w_disc),
            "no candidate's score is significant and a flexible term does not predict the held-out "
            "data significantly better than the nominal model",
        )
    if not named:
        if gap:
            return Verdict(
                "unexplained",
                w_disc,
                "the nominal model leaves a significant gap on the held-out data, "
                "and no candidate effect screens significant",
            )
        return Verdict(
            NOMINAL,
            w_none,
            "the candidates that screened significant do not predict the held-out data better than the nominal model",
        )
    best = max(named, key=lambda k: named[k])
    if w_none > named[best] and not gap:
        return Verdict(NOMINAL, w_none, f"the nominal model {evidence} best")
    if disc_beats.get(best, 1.0) < alpha:
        return Verdict(
            "unexplained",
            max(w_disc, 1.0 - named[best]),
            f"a flexible discrepancy term predicts the held-out data significantly better than the "
            f"best candidate, {best}",
        )
    if after_ratio.get(best, 0.0) > gap_ratio and after_p.get(best, 1.0) < alpha:
        how = (
            f"a held-out error {after_ratio[best]:.1f} times the noise floor"
            if math.isfinite(after_ratio[best])
            else "a smooth gap that a flexible term on top of it still predicts"
        )
        return Verdict("unexplained", 1.0 - named[best], f"the best candidate, {best}, still leaves {how}")
    if w_none > named[best]:
        return Verdict(NOMINAL, w_none, f"the nominal model {evidence} best")
    return Verdict(best, named[best], f"{best} {evidence} best")


def gap_p_value(ss: float, n: int, inflation: float = 1.0) -> float:
    """p-value of ``ss`` (sum of ``n`` squared standardised residuals) against pure noise."""
    if n <= 0:
        return 1.0
    return chi2_sf(n + (ss - n) / max(1.0, inflation), n)
