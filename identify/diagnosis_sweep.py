"""Sweep-only pieces of the diagnosis: usable fits, the blocked folds, in-sample evidence, imitation.

A tractive-force or drawbar-pull sweep has independent samples (one reading per slip), a few
dozen of them, and effects whose signatures bend the thrust-slip curve. Three consequences,
which :func:`~.diagnosis.diagnose` draws on sweeps:

- **Which effect is decided on all the data.** Comparing candidates by their predictions of
  held-out blocks fits each one on part of the sweep and asks it to extrapolate into the gaps
  (and, for the end blocks, beyond the slips it saw): that throws away evidence and adds the
  extrapolation error of the fit, which is largest for effects with a shape in slip. With
  independent samples and a known noise level the efficient comparison is the likelihood on
  all the data with a penalty for the parameters added (Akaike's information criterion),
  averaged over a Bayesian bootstrap of the samples (pseudo-BMA+, :func:`information_weights`).
  Held-out blocks still measure the gap, test the flexible term and give the shrink.
- **More folds** (:func:`sweep_folds`): each block held out once in five folds, so every fit
  sees 80 % of the sweep instead of half of it.
- **Imitation** (:func:`imitation_rms`): how closely effect B, refitted with the soil, can
  reproduce the curve fitted with effect A, in units of the noise. When that is small, no
  realisation of the noise can tell A from B with confidence; the pair is confusable.

A fit whose solver converged but whose answer fails the plausibility checks of
:mod:`.plausibility` (residuals far off, rows that look like outliers) is exactly what a
missing effect does to the nominal model: :func:`solver_converged` accepts it for the
diagnosis and :func:`plausibility_warnings` says why it was flagged.
"""
from __future__ import annotations

import math

import numpy as np

from ..soilmodel.data import SlipData

__all__ = ["NOT_USABLE", "solver_converged", "plausibility_warnings", "sweep_folds", "information_weights",
           "imitation_rms", "effect_start"]

#: Suffix :func:`~.result.build_result` appends to the status of a fit the plausibility checks refuse.
NOT_USABLE = "(answer not usable)"


def solver_converged(res) -> bool:
    """Whether the solver of ``res`` converged to finite numbers (plausibility aside).

    True for a successful fit, and for one whose only failure is the plausibility verdict
    (its status ends with :data:`NOT_USABLE`); False for a solver failure.
    """
    if getattr(res, "success", False):
        return True
    status = str(getattr(res, "status", ""))
    theta = np.asarray(getattr(res, "theta", [np.nan]), dtype=float)
    return status.endswith(NOT_USABLE) and bool(np.all(np.isfinite(theta)))


def plausibility_warnings(res) -> list[str]:
    """The plausibility warnings that made a converged fit 'not usable' (empty for a successful fit)."""
    if getattr(res, "success", False):
        return []
    try:
        ws = list(getattr(res, "warnings", ()) or ())
    except Exception:  # noqa: BLE001 - a lazily built view that fails says nothing more
        ws = []
    flagged = [w for w in ws if str(w).startswith("NOT USABLE")]
    return flagged or [w for w in ws if "outlier" in str(w) or "residual" in str(w)]


def sweep_folds(order: np.ndarray, n_blocks: int = 10, n_folds: int = 5) -> list[tuple[np.ndarray, np.ndarray]]:
    """Blocked folds of a sweep: ``n_blocks`` contiguous blocks in slip order, fold k holds out blocks k, k+f, ...

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


def information_weights(z: dict[str, np.ndarray], k: dict[str, int], n_boot: int = 400,
                        seed: int = 20261123) -> dict[str, float]:
    """Pseudo-BMA+ weights of in-sample fits: AIC on all the data, averaged over a Bayesian bootstrap.

    ``z[m]`` are model m's residuals over the noise level at every sample (the same samples for
    every model), ``k[m]`` the parameters it adds to the soil's. Each bootstrap replicate draws
    Dirichlet(1, ..., 1) weights ``a`` over the samples and scores every model by
    ``-0.5 n sum_t a_t z_t^2 - k`` (the log-likelihood minus Akaike's penalty); the weights are the
    softmax averaged over the replicates (Yao et al. 2018). A model with a non-finite residual
    gets weight 0. Deterministic (fixed ``seed``).
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
    L = -0.5 * Z[finite] ** 2  # (models, samples)
    pen = np.array([float(k.get(m, 0)) for m, f in zip(names, finite) if f])
    rng = np.random.default_rng(seed)
    A = rng.dirichlet(np.ones(n), size=n_boot)  # (boot, samples)
    E = n * A @ L.T - pen[None, :]
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


def imitation_rms(prediction: np.ndarray, data: SlipData, sigma: np.ndarray, fit_other) -> float:
    """RMS, over the noise, of the best imitation of a fitted curve by another model.

    Parameters
    ----------
    prediction
        The curve to imitate at the samples of ``data`` (what the data would be without noise
        if the first model were the truth), N.
    data
        The sweep (its slips, loads and what it measured).
    sigma
        Noise level per sample, N.
    fit_other
        ``fit_other(SlipData) -> (FitResult, residuals per sample)`` fitting the other model.

    Returns
    -------
    float
        ``sqrt(mean(((prediction - imitation) / sigma)^2))``; ``inf`` when the refit fails.
        The expected difference of the two models' sums of squared standardised residuals on
        such data is ``n`` times its square: below a few units the data cannot tell them apart.
    """
    key = "drawbar_pull" if data.measured == "drawbar_pull" else "tractive_force"
    synth = SlipData(slip=np.asarray(data.slip, float), normal_load=data.normal_load,
                     source=f"{data.source or 'sweep'} (noise-free curve of the verdict)",
                     **{key: np.asarray(prediction, float)})
    try:
        res, r = fit_other(synth)
    except Exception:  # noqa: BLE001 - a refit that cannot be made imitates nothing
        return math.inf
    if not solver_converged(res):
        return math.inf
    r = np.asarray(r, dtype=float)
    s = np.asarray(sigma, dtype=float)
    ok = np.isfinite(r) & (s > 0)
    if not np.any(ok):
        return math.inf
    return float(np.sqrt(np.mean((r[ok] / s[ok]) ** 2)))
