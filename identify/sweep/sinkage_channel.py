"""The measured sinkage of a track sweep against the library's sinkage laws (Bekker, Lyasko).

The library's laws (:mod:`soiltrack.soilmodel.sinkage`): static Bekker sinkage of the track
``z0 = (W / (A k)) ^ (1 / n)`` with ``k = k_c / b + k_phi`` at the track's width, and Lyasko's
slip sinkage ``z = z0 (1 + i) / (1 - 0.5 i)``. Taken together, with multiplicative reading
errors, ``log z - log L(i) = log z0(W_ref) + (1 / n) log(W / W_ref)`` (``L`` Lyasko's factor):
a straight line, fitted by least squares. What the rows identify:

- always ``z0`` at the median load (the level of the sinkage);
- ``n`` (and then ``k``) only when the load spreads (:data:`MIN_LOG_LOAD_SPREAD`); at one load
  they enter only through z0, and k_c and k_phi never separate at one track width;
- whether the sinkage grows with the slip as Lyasko's law says: the fit is repeated with the
  exponent ``s`` of ``L(i)`` free, and ``s = 1`` is tested (Student t, its p-value).

The fitted law's sinkage at each row is computed with the one home of each law
(:func:`~soiltrack.soilmodel.sinkage.sinkage_expr`, :func:`~soiltrack.soilmodel.sinkage.slip_sinkage`).
"""

from __future__ import annotations

import math

import numpy as np

from ...soilmodel.data import SlipData
from ...soilmodel.sinkage import sinkage_expr, slip_sinkage
from ...soilmodel.vehicle import Vehicle
from ..estimates.distributions import t_cdf, t_ppf

__all__ = ["fit_sinkage_channel", "MIN_LOG_LOAD_SPREAD", "MIN_SINKAGE_ROWS"]

#: Standard deviation of log(W) below which the rows carry no information on n (one load).
MIN_LOG_LOAD_SPREAD = 1e-6
#: Fewest rows with a positive sinkage for the slip-exponent test (three coefficients and a dof).
MIN_SINKAGE_ROWS = 4


def _ols(X: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Coefficients, their covariance, the residual variance and the residual dof."""
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    r = y - X @ coef
    dof = X.shape[0] - X.shape[1]
    s2 = float(r @ r) / dof if dof > 0 else math.nan
    return coef, s2 * np.linalg.pinv(X.T @ X), s2, dof


def fit_sinkage_channel(data: SlipData, vehicle: Vehicle) -> dict | None:
    """What the measured sinkage says about the Bekker and Lyasko laws (JSON-ready), or ``None``.

    ``None`` without a sinkage column or with too few rows at a positive sinkage and slip.
    """
    if data.sinkage is None:
        return None
    z, i = np.asarray(data.sinkage, dtype=float), np.asarray(data.slip, dtype=float)
    W = data.loads(vehicle.weight).astype(float)
    use = (z > 0) & (i >= 0)
    if np.count_nonzero(use) < MIN_SINKAGE_ROWS:
        return None
    z, i, W = z[use], i[use], W[use]
    W_ref = float(np.median(W))
    lz, lL, lW = np.log(z), np.log(slip_sinkage(1.0, i)), np.log(W / W_ref)
    spread = float(np.std(lW)) > MIN_LOG_LOAD_SPREAD
    X = np.column_stack([np.ones_like(lz), lW]) if spread else np.ones((lz.size, 1))
    coef, cov, s2, dof = _ols(X, lz - lL)
    if dof <= 0 or not math.isfinite(s2):
        return None
    q = t_ppf(0.975, dof)
    a, se_a = float(coef[0]), math.sqrt(max(cov[0, 0], 0.0))
    out: dict = {
        "reference_load_N": W_ref,
        "z0_m": math.exp(a),
        "z0_ci95_m": [math.exp(a - q * se_a), math.exp(a + q * se_a)],
        "n": None,
        "n_ci95": None,
        "k_eq_kn": None,
        "identifiable": ["z0"],
    }
    if spread:
        m, se_m = float(coef[1]), math.sqrt(max(cov[1, 1], 0.0))
        lo, hi = m - q * se_m, m + q * se_m
        if m > 0 and lo > 0:  # 1/n determined and positive: n and k follow
            n = 1.0 / m
            out.update(n=n, n_ci95=[1.0 / hi, 1.0 / lo], identifiable=["z0", "n", "k_eq"])
            A = vehicle.contact_area
            out["k_eq_kn"] = W_ref / (A * math.exp(a) ** n) / 1e3  # z0 = (W / (A k)) ^ (1 / n) solved for k
            z_fit = np.asarray(
                sinkage_expr(W, n, 0.0, out["k_eq_kn"] * 1e3, vehicle.track_length, vehicle.track_width), dtype=float
            ) * slip_sinkage(1.0, i)
            out["rms_m"] = float(np.sqrt(np.mean((z_fit - z) ** 2)))
    # Lyasko's slip factor with a free exponent s: s = 1 is the law
    Xs = np.column_stack([X, lL])
    cs, covs, _, dofs = _ols(Xs, lz)
    if dofs > 0:
        s, se_s = float(cs[-1]), math.sqrt(max(covs[-1, -1], 0.0))
        qs = t_ppf(0.975, dofs)
        p = 2.0 * (1.0 - t_cdf(abs(s - 1.0) / se_s, dofs)) if se_s > 0 else 0.0
        out["slip_exponent"] = {"value": s, "ci95": [s - qs * se_s, s + qs * se_s], "p_value_lyasko": p}
    out["statement"] = _statement(out, spread)
    return out


def _statement(o: dict, spread: bool) -> str:
    lo, hi = o["z0_ci95_m"]
    head = (
        f"static Bekker sinkage z0 = {1e3 * o['z0_m']:.3g} mm at W = {o['reference_load_N']:.4g} N, 95 % "
        f"[{1e3 * lo:.3g}, {1e3 * hi:.3g}] mm"
    )
    if o["n"] is not None:
        head += (
            f"; n = {o['n']:.3g} [{o['n_ci95'][0]:.3g}, {o['n_ci95'][1]:.3g}], k_c / b + k_phi = "
            f"{o['k_eq_kn']:.4g} kN/m^(n+2)"
        )
    else:
        head += (
            "; n and k not identifiable ("
            + ("one load" if not spread else "the load's spread does not determine 1/n")
            + ")"
        )
    se = o.get("slip_exponent")
    if se:
        verdict = (
            "grows with the slip as Lyasko's law"
            if se["p_value_lyasko"] >= 0.05
            else "does NOT grow with the slip as Lyasko's law"
        )
        head += (
            f"; the sinkage {verdict} (exponent of its factor {se['value']:.3g}, 95 % [{se['ci95'][0]:.3g}, "
            f"{se['ci95'][1]:.3g}], law 1, p = {se['p_value_lyasko']:.3g})"
        )
    return head
