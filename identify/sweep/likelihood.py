"""Profile likelihood: fix one parameter on a grid, re-optimise the others.

Uses the same cached IPOPT solver as :func:`~soiltrack.identify.fit` (the fixed parameter
gets ``lbx = ubx``), warm-started from the neighbouring grid point. The likelihood-ratio
95 % interval is the set of values whose profile cost stays within

* ``Delta SSR <= s^2 t_{0.975, n-r}^2`` when the noise level is estimated
  (``s^2 = SSR_min / (n - r)``, r = rank of the full fit; F(1, n - r) test), or
* ``Delta SSR <= 1.96^2`` (chi-square with one degree of freedom) when sigma is known,

with SSR the weighted sum of squares. The ends are found by linear interpolation between
grid points; an end that reaches the grid edge (usually a bound) is reported as such.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...soilmodel.data import SlipData
from ...soilmodel.errors import DataError
from ...soilmodel.soil import PARAMETER_NAMES, PRACTICAL_BOUNDS, SoilBounds
from ...soilmodel.vehicle import Vehicle
from .ipopt import solve_ipopt
from .problem import make_problem
from ..estimates.result import FitResult
from ..fitting import fit
from ..estimates.distributions import lr_threshold

__all__ = ["profile_likelihood", "ProfileResult"]

_ALIASES = {"c": "cohesion", "phi": "friction_angle", "K": "shear_modulus"}


@dataclass(frozen=True)
class ProfileResult:
    """A profile of the cost along one parameter.

    Attributes
    ----------
    parameter : str
        ``"cohesion"``, ``"friction_angle"`` or ``"shear_modulus"``.
    values : ndarray
        Grid of the fixed parameter (SI: Pa, rad, m).
    cost : ndarray
        Profile cost ``0.5 * SSR`` (weighted) at each grid value (``inf`` where the inner
        fit failed).
    others : ndarray, shape (len(values), 3)
        Re-optimised ``[c, phi, K]`` at each grid value.
    threshold : float
        Cost level that bounds the 95 % likelihood-ratio interval.
    interval : tuple of (float or None)
        95 % likelihood-ratio interval (SI); ``None`` ends when not available.
    open_lower, open_upper : bool
        True when the interval reaches the grid edge (the data do not bound it there).
    fit : FitResult
        The unconstrained-in-this-parameter fit the profile is referred to.
    note : str
    """

    parameter: str
    values: np.ndarray
    cost: np.ndarray
    others: np.ndarray
    threshold: float
    interval: tuple[float | None, float | None]
    open_lower: bool
    open_upper: bool
    fit: FitResult
    note: str = ""

    def to_dict(self) -> dict:
        """JSON-ready dict (SI units; non-finite numbers as ``None``)."""
        f = lambda x: None if x is None or not math.isfinite(x) else float(x)  # noqa: E731
        return {
            "parameter": self.parameter,
            "values": [f(v) for v in self.values],
            "cost": [f(c) for c in self.cost],
            "threshold": f(self.threshold),
            "interval": [f(self.interval[0]), f(self.interval[1])],
            "open_lower": self.open_lower,
            "open_upper": self.open_upper,
            "note": self.note,
        }


def profile_likelihood(
    data: SlipData,
    vehicle: Vehicle,
    parameter: str,
    values=None,
    *,
    model: str = "full",
    bounds: SoilBounds = PRACTICAL_BOUNDS,
    n_points: int = 41,
    fit_result: FitResult | None = None,
    sigma=None,
    sigma_known: bool | None = None,
) -> ProfileResult:
    """Profile the cost along one parameter and give the likelihood-ratio 95 % interval.

    Parameters
    ----------
    data : SlipData
    vehicle : Vehicle
    parameter : str
        ``"cohesion"``/``"c"``, ``"friction_angle"``/``"phi"``, ``"shear_modulus"``/``"K"``.
    values : array_like, optional
        Grid in SI (Pa, rad, m). Default: ``n_points`` values spanning the bounds.
    model : {"full", "cohesion-free"}
    bounds : SoilBounds
    n_points : int
        Size of the default grid.
    fit_result : FitResult, optional
        A fit of the same data (IPOPT); computed if not given.
    sigma, sigma_known
        As for :func:`~soiltrack.identify.fit`.

    Returns
    -------
    ProfileResult
    """
    name = _ALIASES.get(parameter, parameter)
    if name not in PARAMETER_NAMES:
        raise DataError(f"unknown parameter {parameter!r}; expected one of {PARAMETER_NAMES} (or c, phi, K)")
    j = PARAMETER_NAMES.index(name)
    if model == "cohesion-free" and j == 0:
        raise DataError("the cohesion-free model has no cohesion to profile")
    pb = make_problem(data, vehicle, model, bounds, sigma=sigma, sigma_known=sigma_known)
    if fit_result is None:
        fit_result = fit(data, vehicle, model=model, bounds=bounds, sigma=sigma, sigma_known=sigma_known)
    lo, hi = bounds.lower[j], bounds.upper[j]
    grid = np.linspace(lo, hi, n_points) if values is None else np.asarray(values, dtype=float).ravel()
    if grid.size < 2 or not np.all(np.isfinite(grid)):
        raise DataError("profile values must be at least two finite numbers")
    grid = np.sort(grid)
    cost = np.full(grid.size, np.inf)
    others = np.zeros((grid.size, 3))
    best = fit_result.theta.copy()
    # sweep outward from the grid point nearest the optimum, warm-starting each solve
    k0 = int(np.argmin(np.abs(grid - best[j])))
    for order in (range(k0, grid.size), range(k0 - 1, -1, -1)):
        start = best.copy()
        for k in order:
            out = solve_ipopt(pb, start, fixed={j: float(grid[k])})
            if out["success"]:
                _, rw, _ = pb.residuals(out["theta"])
                cost[k] = 0.5 * float(rw @ rw)
                others[k] = out["theta"]
                start = out["theta"]
            else:
                others[k] = np.nan
    cmin = min(float(fit_result.cost), float(np.min(cost)))
    thr, note = lr_threshold(cmin, fit_result.dof, pb.sigma_known)
    if not math.isfinite(thr):
        return ProfileResult(name, grid, cost, others, math.inf, (None, None), True, True, fit_result, note)
    inside = cost <= thr
    if not np.any(inside):
        return ProfileResult(
            name,
            grid,
            cost,
            others,
            thr,
            (None, None),
            False,
            False,
            fit_result,
            note + "; no grid point within the threshold (grid too coarse?)",
        )
    ks = np.nonzero(inside)[0]
    a, b = int(ks[0]), int(ks[-1])

    def cross(k_in, k_out):
        c1, c2 = cost[k_in], cost[k_out]
        if not math.isfinite(c2):
            return float(grid[k_in])
        t = (thr - c1) / (c2 - c1) if c2 != c1 else 0.0
        return float(grid[k_in] + t * (grid[k_out] - grid[k_in]))

    open_lo, open_hi = a == 0, b == grid.size - 1
    lo_v = float(grid[0]) if open_lo else cross(a, a - 1)
    hi_v = float(grid[-1]) if open_hi else cross(b, b + 1)
    if np.any(~inside[a : b + 1]):
        note += "; the set within the threshold is not connected (interval shown is its hull)"
    if open_lo or open_hi:
        note += "; the interval reaches the grid edge" + (" (the bounds)" if values is None else "")
    return ProfileResult(name, grid, cost, others, thr, (lo_v, hi_v), open_lo, open_hi, fit_result, note)
