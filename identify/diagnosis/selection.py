"""The comparison's tools: the flexible discrepancy term, pseudo-BMA+ weights, Diebold-Mariano tests.

- The flexible term (:func:`fit_discrepancy`) adds, to the nominal model's prediction, a low-order
  linear spline (hat functions on quantile knots, :func:`hat_basis`) fitted to the nominal training
  residuals: in slip for a sweep, in time for a log. It stands for any smooth gap and names no physics.
- :func:`stacking_weights`: pseudo-BMA+ weights of held-out log densities (Yao et al. 2018).
- :func:`dm_test`: one-sided Diebold-Mariano test that one model predicts the held-out data better.
- :func:`gap_p_value`: the held-out error against the noise floor (chi-square, corrected for
  correlated or over-dispersed residuals).
- :func:`confusable_groups` and :func:`separating_experiment`: effects the data cannot tell apart and
  the experiment that would.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection
import numpy as np

from ..estimates.distributions import chi2_sf

__all__ = [
    "SEPARATING_EXPERIMENTS",
    "LOOKALIKES",
    "separating_experiment",
    "hat_basis",
    "fit_discrepancy",
    "confusable_groups",
    "difference_z",
    "shared_weights",
    "dm_test",
    "gap_p_value",
    "stacking_weights",
]

from .hypotheses import DISCREPANCY, NOMINAL

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
    frozenset(
        {"radius_error", "grade"}
    ): "measure the track's effective radius (distance per sprocket turn at zero drawbar on firm ground)",
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
    frozenset({"radius_error", "speed_scale"}): "a speed reference independent of the vehicle-speed sensor (a "
    "measured distance over a timed run), or pulls against a known drawbar load: both scale the apparent "
    "slip, only a radius error changes the torque arm",
    frozenset({"drivetrain_friction", "radius_error"}): "a torque sensor at the track or a coast-down; "
    "and a measured distance per sprocket turn",
}


#: Causes outside the library that leave the same signature as an effect: a diagnosis that names the
#: effect says that these would look the same.
LOOKALIKES = {
    "grade": "any constant extra force on the vehicle (a towed load, a steady wind, compaction resistance) "
    "and a zero offset of the force sensor (a sweep) or of the accelerometer (a drive log)",
    "drivetrain_friction": "a zero offset of the torque sensor (it looks like the Coulomb part)",
    "radius_error": "a scale error of the vehicle-speed sensor (it shifts the apparent slip the same way; "
    "only the torque arm differs)",
    "mass_error": "a scale error of the accelerometer (in the hull balance; a mass error also changes the normal load)",
    "slip_sinkage": "any resistance that grows with the slip (bulldozing, a track digging in)",
    "speed_resistance": "any resistance that grows with speed (air drag, a viscous loss in the running gear)",
}


def separating_experiment(a: str, b: str) -> str:
    """The experiment that separates effects ``a`` and ``b`` (a generic advice when none is tabled)."""
    text = SEPARATING_EXPERIMENTS.get(frozenset({a, b}))
    if text:
        return text
    if DISCREPANCY in (a, b):
        e = b if a == DISCREPANCY else a
        return (
            f"data where {e} predicts something other than a smooth trend (other speeds, slips, loads or "
            "accelerations than these data cover): the flexible term follows any smooth gap"
        )
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


def difference_z(units: np.ndarray, offset: float = 0.0) -> float:
    """How many standard errors apart the evidence puts two hypotheses: ``|sum(units) + offset| / (sqrt(m) sd(units))``.

    ``units`` are the difference's contributions from the ``m`` units the data make independent (the
    hold-out blocks of a log, the samples of a sweep); ``offset`` a constant part (a difference of
    penalties). The standard error is the one of a sum of ``m`` independent draws (as in the
    comparison of held-out predictions of Vehtari, Gelman and Gabry 2017). ``inf`` when the units do
    not vary and the difference is not zero, or when a unit is not finite; 0 when there is no difference.
    """
    u = np.asarray(units, dtype=float).ravel()
    if u.size == 0:
        return 0.0
    if not np.all(np.isfinite(u)):
        return math.inf
    diff = abs(float(u.sum()) + offset)
    se = math.sqrt(u.size) * float(np.std(u))
    if se <= 0.0:
        return math.inf if diff > 0.0 else 0.0
    return diff / se


def confusable_groups(
    weights: dict[str, float],
    directions: dict[str, np.ndarray | None],
    min_ratio: float = 0.2,
    min_corr: float = 0.9,
    min_weight: float = 0.05,
    separation: Callable[[str, str], float] | None = None,
    max_separation: float = 2.0,
) -> list[tuple[tuple[str, ...], float, float]]:
    """Pairs of candidates the data cannot tell apart.

    A pair of named candidates is confusable when their projected sensitivity directions (what each
    would change in the residuals, beyond the soil) are collinear (``|corr| >= min_corr``, or unknown)
    and the evidence does not tell them apart: their weights are close (the smaller at least
    ``min_ratio`` of the larger and at least ``min_weight``: a difference of evidence too small to
    matter), or, for two known collinear directions, ``separation(a, b)``, their difference of
    evidence in its standard errors, is below ``max_separation`` and the larger weight at least
    ``min_weight`` (a difference the noise could make, however large: a pseudo-BMA+ weight is about
    the bootstrap's probability that one predicts better, 0.98 at 1.8 standard errors on a grid log,
    far beyond the weight ratio, not beyond a 5 % test). A pair with an unknown
    direction (the flexible term, which can follow any smooth gap) is judged by its weights alone: an
    effect that predicts as well as the flexible term with fewer parameters is what the held-out
    evidence rewards, and the flexible term is within the noise of the true effect by design.
    Collinear sensitivities alone are not enough: they are local (at "effect off"), and a refit that
    the held-out data clearly prefer has told the two apart.

    Returns ``[((a, b), corr, separation), ...]``: corr NaN when a direction is unknown; separation
    when it made the pair confusable (below ``max_separation``), else NaN (the weights did).
    """
    names = [k for k in weights if k != NOMINAL]
    out: list[tuple[tuple[str, ...], float, float]] = []
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            wa, wb = weights[a], weights[b]
            da, db = directions.get(a), directions.get(b)
            corr = float("nan")
            if da is not None and db is not None and np.linalg.norm(da) > 0 and np.linalg.norm(db) > 0:
                corr = float(abs(np.dot(da, db)) / (np.linalg.norm(da) * np.linalg.norm(db)))
            if math.isfinite(corr) and corr < min_corr:
                continue  # different signatures: the data can tell them apart
            close = min(wa, wb) >= max(min_ratio * max(wa, wb), min_weight)
            sep = separation(a, b) if separation is not None and math.isfinite(corr) else math.nan
            within = math.isfinite(corr) and max(wa, wb) >= min_weight and sep < max_separation
            if close or within:
                out.append(((a, b), corr, sep if within else math.nan))
    return out


#: Decimals a weight is given to: its Monte Carlo error is about 0.01 (400 bootstrap replicates), and
#: rounding keeps the last bit of a sum from making a half-share of 1 read as more than one half.
WEIGHT_DECIMALS = 12


def shared_weights(
    weights: dict[str, float],
    pairs: list[tuple[tuple[str, ...], float, float]],
    n_params: dict[str, int],
    candidates: Collection[str] = (),
) -> dict[str, float]:
    """The weights with each group of confusable hypotheses sharing its summed weight evenly.

    A group is the hypotheses linked through ``pairs`` (:func:`confusable_groups`): the data cannot
    tell its members apart, so the evidence is for the group, and a difference inside it (a coin
    flip of the noise) says nothing about which member it is. Each member gets the group's mean
    weight; the sum over all hypotheses is unchanged (to ``WEIGHT_DECIMALS``). The dict comes back
    heaviest first; inside a group the user's ``candidates`` first (naming a cause outside them, or
    the flexible term, says that the candidates cannot explain the gap, which these data do not show
    when a candidate explains it as well), then the fewest parameters (of explanations the data
    cannot tell apart, the simplest, as in the one-standard-error rule of model selection), then the
    larger weight before sharing. ``max`` and any stable sort by weight keep that order.
    """
    root = {k: k for k in weights}

    def find(k: str) -> str:
        while root[k] != k:
            k = root[k]
        return k

    for (a, b), *_ in pairs:
        if a in root and b in root:
            root[find(a)] = find(b)
    groups: dict[str, list[str]] = {}
    for k in weights:
        groups.setdefault(find(k), []).append(k)
    shared = dict(weights)
    for members in groups.values():
        if len(members) > 1:
            mean = float(sum(weights[k] for k in members)) / len(members)
            shared.update({k: mean for k in members})
    shared = {k: round(v, WEIGHT_DECIMALS) for k, v in shared.items()}
    chosen = set(candidates)
    order = sorted(weights, key=lambda k: (-shared[k], k not in chosen, n_params.get(k, 0), -weights[k]))
    return {k: shared[k] for k in order}


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


def gap_p_value(ss: float, n: int, inflation: float = 1.0) -> float:
    """p-value of ``ss`` (sum of ``n`` squared standardised residuals) against pure noise."""
    if n <= 0:
        return 1.0
    return chi2_sf(n + (ss - n) / max(1.0, inflation), n)
