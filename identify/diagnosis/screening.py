"""Cheap screening of candidate effects: the score (Lagrange-multiplier) test at the nominal fit.

At the nominal fit, an effect's parameters sit at their off values. If the effect were in the
data, moving its parameter would lower the cost: the score ``Z^T r`` is the gradient of the
half sum of squared weighted residuals ``r`` along the effect's Jacobian columns ``Z``,
after projecting ``Z`` off the columns of the freely fitted (soil) parameters, so that what the
soil can absorb does not count. The statistic

    LM = s^T V^{-1} s,   s = Z_perp^T r,   V = Var(s)

is chi-squared with as many degrees of freedom as the effect has columns when the effect is
absent. ``V`` is the heteroscedasticity-and-autocorrelation-consistent (Newey-West, Bartlett
weights) variance of ``sum_t Z_perp[t] r[t]``: drive-log residuals are correlated in time, and
the plain ``sigma^2 Z^T Z`` would overstate the evidence. With lag 0 (independent samples, a
sweep) it is White's heteroscedasticity-robust variance: noise that grows with the reading, or
one outlier, does not make every candidate look significant. No refit is needed; the Jacobian
comes from one fit with the candidate effects held at their off values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...soilmodel.effects import EFFECTS
from ..estimates.distributions import chi2_sf

__all__ = ["Screen", "project_off", "score_test", "newey_west_lag", "screen", "stationarity"]


@dataclass(frozen=True)
class Screen:
    """Score-test outcome for one candidate effect.

    Attributes
    ----------
    effect
        Candidate name.
    columns
        Labels of the effect's Jacobian columns used (those with a sensitivity on these data).
    score
        Norm of the projected score ``Z_perp^T r`` relative to ``|Z_perp| |r|`` (0-1: the cosine
        between the residuals and the effect's sensitivity; 0 at a perfect nominal fit).
    statistic, dof, p_value
        LM statistic, its degrees of freedom, and the chi-squared p-value.
    screenable
        False when the effect leaves no sensitivity on these data beyond the soil's (e.g.
        ``drivetrain_friction`` on a rig sweep); then statistic 0 and p-value 1.
    direction
        The projected sensitivity along which the score points (unit vector over the samples),
        used to tell confusable candidates; ``None`` when not screenable.
    gain
        ``|B^T r|^2`` with ``B`` an orthonormal basis of the projected sensitivity: the drop of
        the sum of squared weighted residuals a linearised refit with the effect would give.
        It ranks the candidates for refitting (the LM statistic's robust variance makes it a
        significance, not a size).
    """

    effect: str
    columns: tuple[str, ...]
    score: float
    statistic: float
    dof: int
    p_value: float
    screenable: bool
    direction: np.ndarray | None = None
    gain: float = 0.0

    def to_dict(self) -> dict:
        """JSON-friendly dict (no direction)."""
        return {
            "effect": self.effect,
            "columns": list(self.columns),
            "score": float(self.score),
            "statistic": float(self.statistic),
            "dof": int(self.dof),
            "p_value": float(self.p_value),
            "screenable": bool(self.screenable),
            "gain": float(self.gain),
        }


def project_off(Z: np.ndarray, J: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    """The part of the columns of ``Z`` orthogonal to the column space of ``J`` (SVD, rank-revealing)."""
    Z = np.asarray(Z, dtype=float)
    J = np.asarray(J, dtype=float)
    if J.size == 0 or J.shape[1] == 0:
        return Z.copy()
    norms = np.linalg.norm(J, axis=0)
    Js = J[:, norms > 0] / norms[norms > 0]
    if Js.shape[1] == 0:
        return Z.copy()
    U, s, _ = np.linalg.svd(Js, full_matrices=False)
    U = U[:, s > rtol * s[0]]
    return Z - U @ (U.T @ Z)


def newey_west_lag(n: int) -> int:
    """Bartlett bandwidth ``floor(4 (n/100)^(2/9))`` (Newey-West's rule)."""
    return int(math.floor(4.0 * (n / 100.0) ** (2.0 / 9.0)))


def _hac(G: np.ndarray, lag: int) -> np.ndarray:
    """Newey-West long-run covariance of the rows of ``G`` (n x k), times n."""
    V = G.T @ G
    for k in range(1, lag + 1):
        w = 1.0 - k / (lag + 1.0)
        C = G[k:].T @ G[:-k]
        V = V + w * (C + C.T)
    return V


def score_test(
    effect: str,
    J_free: np.ndarray,
    Z: np.ndarray,
    r: np.ndarray,
    labels: tuple[str, ...] = (),
    hac_lag: int | None = 0,
    rel_tol: float = 1e-6,
) -> Screen:
    """Score test of one candidate from the nominal fit's weighted residuals and Jacobian.

    Parameters
    ----------
    effect
        Candidate name.
    J_free
        Jacobian of the weighted residuals w.r.t. the freely fitted parameters (n x p).
    Z
        Jacobian columns of the candidate's parameters at their off values (n x k).
    r
        Weighted residuals at the nominal fit (n).
    labels
        Labels of the columns of ``Z``.
    hac_lag
        Newey-West bandwidth for correlated residuals; 0 for independent samples (White's
        heteroscedasticity-robust variance ``sum_t g_t g_t^T``, ``g_t = Z_perp[t] r[t]``: one
        large residual cannot make every candidate look significant); ``None`` chooses
        :func:`newey_west_lag`.
    rel_tol
        Columns whose projected norm is below ``rel_tol`` times their norm carry no information
        beyond the soil's and are dropped.
    """
    r = np.asarray(r, dtype=float).ravel()
    Z = np.asarray(Z, dtype=float).reshape(r.size, -1)
    labels = tuple(labels) or tuple(f"{effect}[{j}]" for j in range(Z.shape[1]))
    Zp = project_off(Z, J_free)
    nz = np.linalg.norm(Z, axis=0)
    npz = np.linalg.norm(Zp, axis=0)
    keep = (nz > 0) & (npz > rel_tol * np.where(nz > 0, nz, 1.0)) & np.all(np.isfinite(Zp), axis=0)
    if not np.any(keep):
        return Screen(effect, (), 0.0, 0.0, 0, 1.0, False, None)
    Zp = Zp[:, keep]
    # drop columns (nearly) dependent on the others, keep a well-conditioned basis
    Un, sv, Vt = np.linalg.svd(Zp / np.linalg.norm(Zp, axis=0), full_matrices=False)
    rank = int(np.sum(sv > 1e-6 * sv[0]))
    B = Un[:, :rank]  # orthonormal basis of the projected sensitivity
    s = B.T @ r
    n = r.size
    rn = float(np.linalg.norm(r))
    cosine = float(np.linalg.norm(s)) / rn if rn > 0 else 0.0
    lag = newey_west_lag(n) if hac_lag is None else max(0, int(hac_lag))
    V = _hac(B * r[:, None], lag)
    try:
        stat = float(s @ np.linalg.solve(V, s)) if np.all(np.isfinite(V)) else 0.0
    except np.linalg.LinAlgError:
        stat = 0.0
    if not math.isfinite(stat) or stat < 0:
        stat = 0.0
    d = B @ s
    dn = float(np.linalg.norm(d))
    direction = d / dn if dn > 0 else B[:, 0]
    return Screen(
        effect,
        tuple(l for l, k in zip(labels, keep) if k),
        cosine,
        stat,
        rank,
        chi2_sf(stat, rank),
        True,
        direction,
        float(s @ s),
    )


def stationarity(J_free: np.ndarray, r: np.ndarray) -> float:
    """Largest cosine between the residuals and a free parameter's Jacobian column.

    At a least-squares optimum inside the bounds ``J_free^T r = 0``: the value is at the level
    of the solver tolerance. A large value means the Jacobian and residuals handed over are not
    the pair the fit minimised (or a parameter sits on a bound), and score tests built on them
    are not to be trusted.
    """
    J = np.asarray(J_free, dtype=float)
    r = np.asarray(r, dtype=float).ravel()
    nr = float(np.linalg.norm(r))
    if J.size == 0 or nr == 0:
        return 0.0
    nj = np.linalg.norm(J, axis=0)
    ok = nj > 0
    if not np.any(ok):
        return 0.0
    return float(np.max(np.abs(J[:, ok].T @ r) / (nj[ok] * nr)))


def drive_log_score_pair(res, log, vehicle, effects=None) -> tuple[np.ndarray, np.ndarray, list[str], int]:
    """A consistent (Jacobian, residual) pair of a drive-log fit, for score tests.

    A drive-log fit profiles out one latent slip per sample, and the Jacobian it reports is a
    stand-in with the right ``J^T J`` only. The score needs the real thing: the per-sample
    whitened residuals and their profiled sensitivities from
    :func:`~soiltrack.identify.drivelog.sensitivity.drive_log_sensitivities`, stacked sample by sample.
    ``effects`` (names) evaluates the derivatives with those effects switched on at their off
    values, so that a nominal fit gives the candidates' columns without carrying them in its NLP.

    Returns
    -------
    J, r, labels, c
        ``(c n, p)``, ``(c n,)``, the column labels ``["F_max", "K", "effect.param", ...]`` and the
        number of channels ``c`` (rows per sample).
    """
    from ..drivelog.sensitivity import drive_log_sensitivities

    sens = drive_log_sensitivities(res, log, vehicle, effects=effects)
    J, r = sens.stacked()
    return J, r, list(sens.labels), sens.n_channels


def screen(data, vehicle, candidates, model: str = "full", hac_lag: int | None = 0, fit_options: dict | None = None):
    """Score-test every candidate from ONE fit: the nominal model with the candidates held off.

    For a sweep the fit (:func:`~soiltrack.identify.fitting.fit` with ``effects=candidates`` and ``fixed`` = every
    parameter at its off value) is the nominal fit, and its Jacobian carries the candidates'
    columns. For a drive log it is the nominal fit with the hull channel, and the columns come
    from :func:`drive_log_score_pair` (cheaper: the candidates stay out of the NLP).
    ``fit_options`` are passed to that fit (e.g. ``{"torque_hold": "sample"}`` for a drive log).

    Returns
    -------
    (FitResult, list of Screen, DriveLogSensitivities or None)
        The fit, the candidates' score tests and, for a drive log whose fit succeeded, the per-sample
        sensitivities they came from (soil columns first: the later steps' score tests reuse them).
    """
    from ..fitting import fit

    cands = list(candidates)
    if not cands:
        return fit(data, vehicle, model=model, **(fit_options or {})), [], None
    from ...soilmodel.data import DriveLog
    from ..drivelog.sensitivity import drive_log_sensitivities

    rows_per_sample = 1
    sens = None
    if isinstance(data, DriveLog):
        # the nominal fit with the hull channel (the estimator of the candidates' fits); the candidates'
        # columns come from the drive-log model's derivatives with them switched on at "off"
        res = fit(data, vehicle, model=model, hull_channel=True, **(fit_options or {}))
        names = list(res.parameter_names)
        J = np.zeros((1, len(names)))
        r = np.zeros(1)
        if res.success:
            sens = drive_log_sensitivities(res, data, vehicle, effects=cands)
            (J, r), names, rows_per_sample = sens.stacked(), list(sens.labels), sens.n_channels
    else:
        fixed = {f"{c}.{p.name}": p.off_value for c in cands for p in EFFECTS[c].params if not p.integer}
        res = fit(
            data,
            vehicle,
            model=model,
            effects=cands,
            fixed=fixed,
            slip_noise="off",
            intervals="linear",
            **(fit_options or {}),
        )
        names = list(res.parameter_names)
        J = np.asarray(res.jacobian, dtype=float)
        r = np.asarray(res.weighted_residuals, dtype=float).ravel()
    if hac_lag is None:
        hac_lag = rows_per_sample * newey_west_lag(r.size // rows_per_sample)
    cols = {c: [j for j, nm in enumerate(names) if nm.startswith(c + ".")] for c in cands}
    taken = {j for js in cols.values() for j in js}
    free = [j for j in range(len(names)) if j not in taken]
    out = [
        score_test(c, J[:, free], J[:, cols[c]], r, tuple(names[j] for j in cols[c]), hac_lag=hac_lag) for c in cands
    ]
    if res.success:
        bound = set(getattr(res, "active_bounds", {}) or {})
        fj = [j for j in free if names[j] not in bound]
        res.extra["screening_stationarity"] = stationarity(J[:, fj], r)
    return res, out, sens
