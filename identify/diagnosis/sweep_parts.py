"""Sweep-only pieces of the diagnosis: the blocked folds, in-sample evidence, lack of fit, a plateau.

A tractive-force or drawbar-pull sweep has independent samples (one reading per slip), a few dozen
of them, and effects whose signatures bend the thrust-slip curve:

- **In-sample evidence** (:func:`information_weights`): the likelihood of each fit on all the
  data with Akaike's penalty, averaged over a Bayesian bootstrap (pseudo-BMA+); held-out blocks
  would make an effect with a shape in slip extrapolate into the gaps it did not see.
- **More folds** (:func:`sweep_folds`): each block held out once in five folds (the shrink).
- **Lack of fit** (:func:`lack_of_fit`): an F test of a flexible term (hat functions in slip) on
  top of a fit, its own parameters refitted with it.
- **A plateau** (:func:`find_plateau`): the largest readings flat at one level within the noise.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ...soilmodel.data import SlipData
from ..estimates.distributions import f_sf

__all__ = [
    "sweep_folds",
    "information_weights",
    "effect_start",
    "lack_of_fit",
    "fit_jacobian",
    "Plateau",
    "find_plateau",
    "PLATEAU_SHARE",
]


def sweep_folds(order: np.ndarray, n_blocks: int = 10, n_folds: int = 5) -> list[tuple[np.ndarray, np.ndarray]]:
    """Blocked folds of a sweep: ``n_blocks`` contiguous blocks in slip order; fold k holds out k, k+f, ...

    Parameters
    ----------
    order
        Sample indices sorted by slip.
    n_blocks
        Number of contiguous blocks (at least 2 samples each).
    n_folds
        Number of folds (``<= n_blocks``); every block is held out exactly once.

    Returns
    -------
    list of (train, test)
        Sample indices (sorted) of each fold.
    """
    order = np.asarray(order)
    n = order.size
    nb = int(max(2, min(n_blocks, n // 2)))
    nf = int(max(2, min(n_folds, nb)))
    chunks = np.array_split(order, nb)
    out = []
    for k in range(nf):
        te = np.sort(np.concatenate([c for j, c in enumerate(chunks) if j % nf == k]))
        tr = np.sort(np.concatenate([c for j, c in enumerate(chunks) if j % nf != k]))
        out.append((tr, te))
    return out


def information_weights(
    z: dict[str, np.ndarray], k: dict[str, int], n_boot: int = 400, seed: int = 20261123
) -> dict[str, float]:
    """Pseudo-BMA+ weights of in-sample fits: AIC on all the data, averaged over a Bayesian bootstrap.

    ``z[m]`` are model m's residuals over the noise level at every sample (the same samples for
    every model), ``k[m]`` the parameters it adds to the soil's. Each bootstrap replicate draws
    Dirichlet(1, ..., 1) weights ``a`` over the samples and scores every model by
    ``-0.5 n log(sum_t a_t z_t^2) - k`` (the Gaussian log-likelihood with the noise level profiled
    out, minus Akaike's penalty); the weights are the softmax averaged over the replicates (Yao et
    al. 2018). A model with a non-finite residual gets weight 0. Deterministic (fixed ``seed``).

    The noise floor gives only the shape of the noise along the sweep: its overall level, which
    second differences of a few dozen samples estimate to within 10-20 %, is profiled out per model
    and replicate, so a floor set too low does not multiply every likelihood gain (a chance feature
    of the noise fitted by the flexible term among them).
    """
    names = list(z)
    if not names:
        return {}
    Z = np.vstack([np.asarray(z[m], dtype=float) for m in names])
    n = Z.shape[1]
    finite = np.all(np.isfinite(Z), axis=1)
    out = np.zeros(len(names))
    if n == 0 or not np.any(finite):
        return {m: (1.0 / len(names) if n == 0 else 0.0) for m in names}
    Q = Z[finite] ** 2  # (models, samples)
    pen = np.array([float(k.get(m, 0)) for m, f in zip(names, finite) if f])
    rng = np.random.default_rng(seed)
    A = rng.dirichlet(np.ones(n), size=n_boot)  # (boot, samples)
    E = -0.5 * n * np.log(np.maximum(A @ Q.T, 1e-300)) - pen[None, :]  # the noise level profiled out
    E = E - E.max(axis=1, keepdims=True)
    W = np.exp(E)
    W /= W.sum(axis=1, keepdims=True)
    out[finite] = W.mean(axis=0)
    return {m: float(w) for m, w in zip(names, out)}


def effect_start(res) -> dict:
    """``{effect: {param: value}}`` of a fit with effects (the start of a refit from its answer)."""
    out: dict[str, dict[str, float]] = {}
    labels = tuple(getattr(res, "effect_labels", ()) or ())
    values = getattr(res, "effect_values", None)
    values = np.zeros(0) if values is None else np.asarray(values, dtype=float).ravel()
    for lab, v in zip(labels, values):
        name, p = lab.split(".", 1)
        out.setdefault(name, {})[p] = float(v)
    return out


# ----------------------------------------------------------------------------- lack of fit and the verdict
def lack_of_fit(
    residuals: np.ndarray,
    jacobian: np.ndarray,
    basis: np.ndarray,
    sigma: np.ndarray,
    held: Sequence[int] = (),
) -> float:
    """p-value that a flexible term ``basis`` on top of a fitted model still explains its residuals (F test).

    The model's own parameters are refitted with the flexible term (linearised: its Jacobian),
    so the test asks what the basis adds beyond them. Rows are weighted by ``1/sigma`` (the
    shape of the noise along the sweep); the F statistic does not depend on the noise level,
    which second differences estimate only roughly.

    A parameter that ended on a bound of its range cannot move on towards the residuals: its
    column (``held``) is left out of the refit. Linearised with it free, the test would move it
    past its bound and call the misfit that the bound leaves "explained by the model" (a 2 % radius
    error drives a heavy sweep's K onto its lower bound: p = 0.55 with K free, 0.0004 with K held).

    Parameters
    ----------
    residuals
        Measured minus predicted of the model fitted on all the data, per sample.
    jacobian
        Its prediction's Jacobian w.r.t. its parameters, ``(n, p)``.
    basis
        The flexible term's basis, ``(n, k)`` (e.g. :func:`~.selection.hat_basis` in slip).
    sigma
        Noise level per sample (only its shape matters).
    held
        Columns of ``jacobian`` whose parameters ended on a bound (held there in the refit).
    """
    s = np.asarray(sigma, dtype=float)
    z = np.asarray(residuals, dtype=float) / s
    J = np.delete(np.asarray(jacobian, dtype=float), list(held), axis=1) / s[:, None]
    B = np.asarray(basis, dtype=float) / s[:, None]
    ok = np.isfinite(z) & np.all(np.isfinite(J), axis=1) & np.all(np.isfinite(B), axis=1)
    z, J, B = z[ok], J[ok], B[ok]

    def span(M):
        M = M[:, np.linalg.norm(M, axis=0) > 0]
        if M.shape[1] == 0:
            return np.zeros((M.shape[0], 0))
        M = M / np.linalg.norm(M, axis=0)
        U, sv, _ = np.linalg.svd(M, full_matrices=False)
        return U[:, sv > 1e-9 * sv[0]]

    U0, U1 = span(J), span(np.hstack([J, B]))
    d1 = U1.shape[1] - U0.shape[1]
    d2 = z.size - U1.shape[1]
    if d1 <= 0 or d2 <= 0:
        return 1.0
    s0 = float(z @ z - np.sum((U0.T @ z) ** 2))
    s1 = float(z @ z - np.sum((U1.T @ z) ** 2))
    if s1 <= 0:
        return 0.0 if s0 > 0 else 1.0
    return f_sf(((s0 - s1) / d1) / (s1 / d2), d1, d2)


def fit_jacobian(res, data: SlipData) -> np.ndarray:
    """Jacobian ``(n, 3 + m)`` of a sweep fit's prediction at its answer, on the samples of ``data``."""
    from ..sweep.model import SweepResiduals, fit_vector, predict

    rm = res.residual_model if isinstance(getattr(res, "residual_model", None), SweepResiduals) else SweepResiduals()
    x = fit_vector(res)
    effects = res.effect_structure if res.effect_labels else None
    W = data.loads(res.vehicle.weight).astype(float)
    _, J = predict(x, data.slip, W, res.vehicle, effects, res.model, data.measured, rm.rig_speed)
    if res.model == "cohesion-free":
        J = J.copy()
        J[:, 0] = 0.0
    return J


# ----------------------------------------------------------------------------- a measured plateau
@dataclass(frozen=True)
class Plateau:
    """The sweep's largest readings flat at one level within the noise: a sensor or rig at its limit.

    The alternative it stands for is the nominal soil on the samples below the plateau and a
    constant ``level`` on the ``rows`` of the plateau: what a load cell clipped at its range (with
    noise added after the clip, so the readings do not repeat exactly) or a rig's force limit gives.

    Attributes
    ----------
    level : float
        The plateau's level (weighted mean of its readings), N.
    rows : tuple of int
        Its data rows (1-based, as in the file).
    slip_range : tuple of float
        Smallest and largest slip on it.
    z : numpy.ndarray
        Standardised residuals of the alternative at every sample.
    level_stderr : float
        Standard error of the level (its readings' noise floor over the square root of their count), N.
    """

    level: float
    rows: tuple[int, ...]
    slip_range: tuple[float, float]
    z: np.ndarray
    level_stderr: float = math.nan


#: Smallest share of a sweep's samples a plateau must hold to be considered.
PLATEAU_SHARE = 1.0 / 3.0


def find_plateau(
    values: np.ndarray, slip: np.ndarray, sigma: np.ndarray, fit_below, min_share: float = PLATEAU_SHARE
) -> Plateau | None:
    """The best model "nominal soil below, one flat level on the largest readings" of a sweep.

    For each count m of largest readings put on the level (at least ``min_share`` of the sweep),
    the level is their weighted mean and the nominal soil is fitted on the others; the m with
    the smallest total chi-square wins (searched in order of the level's own chi-square, which
    bounds the total from below, so few soil fits are made).

    Parameters
    ----------
    values
        Measured force per sample, N.
    slip
        Slip per sample.
    sigma
        Noise level per sample, N.
    fit_below
        ``fit_below(idx) -> (residuals on idx, predictions on the other samples)`` fitting the
        nominal soil on the samples ``idx`` only (None when the fit fails).
    min_share
        Fewest samples on the level, as a share of the sweep.

    Returns
    -------
    Plateau or None
        None for fewer than 9 samples or non-finite inputs, or when no m gives a soil below
        that rises to the level at the plateau's slips (then nothing is clipped). One or two
        readings below the level are passed exactly by the soil (F_max and K).
    """
    y = np.asarray(values, dtype=float)
    s = np.asarray(sigma, dtype=float)
    n = y.size
    if n < 9 or not np.all(np.isfinite(y) & np.isfinite(s) & (s > 0)):
        return None
    top = np.argsort(-y, kind="stable")
    w = 1.0 / s[top] ** 2
    sw, swy, swy2 = np.cumsum(w), np.cumsum(w * y[top]), np.cumsum(w * y[top] ** 2)
    chi_top = np.maximum(swy2 - swy**2 / sw, 0.0)  # spread of the top m readings about their mean, m = 1..n
    ms = np.arange(max(3, int(math.ceil(min_share * n))), n)
    best: tuple[float, int, np.ndarray] | None = None
    for m in sorted(ms, key=lambda m: chi_top[m - 1]):
        if best is not None and chi_top[m - 1] >= best[0]:
            break
        on, below = np.sort(top[:m]), np.sort(top[m:])
        lev = float(swy[m - 1] / sw[m - 1])
        if below.size >= 3:
            got = fit_below(below)
            if got is None:
                continue
            r_below, pred_on = got
            if not np.all(np.isfinite(r_below)) or not np.all(np.isfinite(pred_on)):
                continue
            if np.median((pred_on - lev) / s[on]) < 0.0:
                continue  # the soil below does not rise to the level there: nothing is clipped
        elif np.any(y[below] >= lev):
            continue
        else:  # one or two readings below: the soil (F_max and K at least) passes through them
            r_below = np.zeros(below.size)
        z = np.empty(n)
        z[below] = r_below / s[below]
        z[on] = (y[on] - lev) / s[on]
        total = float(z @ z)
        if best is None or total < best[0]:
            best = (total, int(m), z)
    if best is None:
        return None
    _, m_best, z = best
    on = np.sort(top[:m_best])
    return Plateau(
        float(swy[m_best - 1] / sw[m_best - 1]),
        tuple(int(k) + 1 for k in on),
        (float(np.min(slip[on])), float(np.max(slip[on]))),
        z,
        float(1.0 / math.sqrt(sw[m_best - 1])),
    )
