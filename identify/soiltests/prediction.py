"""A track's drawbar pull predicted from bevameter tests, with the interval from the soil's uncertainty.

Drawbar pull of both tracks on flat ground, from the library's one home of each term::

    DP(i) = F(i; c, phi, K, W, l, b) - R_c(W; k_c, k_phi, n, l, b)

with F the thrust of Eq. 2 (:func:`soiltrack.soilmodel.traction.thrust_expr`) and R_c the Bekker
compaction resistance (:func:`soiltrack.soilmodel.sinkage.compaction_expr`). The running
gear's internal resistance is not part of it. The shear test and the plate test are
independent measurements, so the covariance of the six parameters is block-diagonal; the
interval propagates it linearly (gradient from CasADi's AD). It is the interval of the
model's prediction from the soil's uncertainty: a measured pull adds its own noise and the
model's error (uniform pressure, no slip sinkage).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from ...soilmodel import DataError, Vehicle
from ...soilmodel.sinkage import compaction_expr
from ...soilmodel.traction import thrust_expr
from ..estimates.distributions import norm_ppf
from ..estimates.estimate import Estimate

__all__ = ["DrawbarPrediction", "predict_drawbar_pull", "drawbar_pull_function"]


@dataclass(frozen=True)
class DrawbarPrediction:
    """Predicted drawbar pull of both tracks against slip, with its interval.

    Attributes
    ----------
    slip, normal_load
        Where it is predicted (slip, N).
    drawbar_pull, stderr
        Predicted pull and its standard error from the soil's uncertainty, N.
    lower, upper
        The interval at ``confidence``, N.
    thrust, compaction_resistance
        The two terms, N.
    confidence
        Level of the interval.
    """

    slip: np.ndarray
    normal_load: float
    drawbar_pull: np.ndarray
    stderr: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    thrust: np.ndarray
    compaction_resistance: float
    confidence: float


@lru_cache(maxsize=1)
def drawbar_pull_function() -> ca.Function:
    """``(slip, W, c, phi, K, k_c, k_phi, n, l, b) -> (DP, dDP/d[c, phi, K, k_c, k_phi, n], F, R_c)``, built once."""
    s = {k: ca.SX.sym(k) for k in ("slip", "W", "c", "phi", "K", "k_c", "k_phi", "n", "l", "b")}
    F = thrust_expr(s["slip"], s["c"], s["phi"], s["K"], s["W"], s["l"], s["b"])
    R = compaction_expr(s["W"], s["n"], s["k_c"], s["k_phi"], s["l"], s["b"])
    p = ca.vertcat(*(s[k] for k in ("c", "phi", "K", "k_c", "k_phi", "n")))
    DP = F - R
    return ca.Function(
        "drawbar_pull", list(s.values()), [DP, ca.jacobian(DP, p), F, R], list(s), ["DP", "dDP_dp", "F", "R_c"]
    )


def _require(fit: Estimate, kind: str, what: str) -> tuple[np.ndarray, np.ndarray]:
    if fit.kind != kind:
        raise DataError(f"expected a {kind.replace('_', ' ')} fit for {what}, got a {fit.kind.replace('_', ' ')} fit")
    if not fit.success:
        raise DataError(
            f"the {kind.replace('_', ' ')} fit ({fit.source}) did not succeed ({fit.status}): no prediction from it"
        )
    if fit.covariance is None:
        missing = [k for k, p in fit.parameters.items() if not p.identifiable]
        hint = "test at two or more normal pressures" if kind == "shear_test" else "test plates of two or more widths"
        raise DataError(
            f"the {kind.replace('_', ' ')} ({fit.source}) does not identify {', '.join(missing)}: the "
            f"track's {what} needs them ({hint})"
        )
    return np.array(fit.covariance.values, dtype=float), np.asarray(fit.covariance.matrix, dtype=float)


def predict_drawbar_pull(
    shear: Estimate,
    plate: Estimate,
    vehicle: Vehicle,
    slip,
    normal_load: float | None = None,
    confidence: float = 0.95,
) -> DrawbarPrediction:
    """Drawbar pull of the vehicle's tracks on the bevameter-identified soil, with its interval.

    Parameters
    ----------
    shear, plate
        Fits of a shear test at two or more pressures and of a plate test with two or more
        widths (:func:`~.fit_shear_test`, :func:`~.fit_plate_test`).
    vehicle
        The tracked vehicle (track length, width; its weight unless ``normal_load`` is given).
    slip
        Slips to predict at, in [0, 1).
    normal_load
        Normal load of both tracks, N (default the vehicle's weight).
    confidence
        Level of the interval (normal quantile).

    Raises
    ------
    DataError
        A fit failed or does not identify what the track needs (one pressure, one plate width).
    """
    (c, phi, K), cov_s = _require(shear, "shear_test", "thrust")
    (k_c, k_phi, n), cov_p = _require(plate, "plate_test", "compaction resistance")
    i = np.atleast_1d(np.asarray(slip, dtype=float))
    if not np.all(np.isfinite(i)) or np.any((i < 0) | (i >= 1)):
        raise DataError("slip must be finite and lie in [0, 1)")
    if not 0 < confidence < 1:
        raise DataError(f"confidence must lie in (0, 1), got {confidence}")
    W = float(vehicle.weight if normal_load is None else normal_load)
    cov = np.zeros((6, 6))
    cov[:3, :3], cov[3:, 3:] = cov_s, cov_p
    f = drawbar_pull_function().map(i.size)
    DP, G, F, R = f(i.reshape(1, -1), W, c, phi, K, k_c, k_phi, n, vehicle.track_length, vehicle.track_width)
    DP, F = np.asarray(DP, dtype=float).ravel(), np.asarray(F, dtype=float).ravel()
    G = np.asarray(G, dtype=float).reshape(6, -1, order="F").T  # one row per slip
    se = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", G, cov, G), 0.0))
    q = norm_ppf(0.5 + confidence / 2)
    return DrawbarPrediction(i, W, DP, se, DP - q * se, DP + q * se, F, float(np.asarray(R).ravel()[0]), confidence)
