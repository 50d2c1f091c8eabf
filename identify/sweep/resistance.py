"""The motion resistance of a drawbar-pull sweep, fitted with the soil (``resistance="fit"``).

A rig measures the drawbar pull ``DP = F(i) - R``; the resistance ``R = mu_r W`` of the
running gear on that soil is rarely known. With ``resistance="fit"`` the coefficient mu_r is
estimated with the soil: the cost is profiled over mu_r (at each value the soil is fitted
with the vehicle's ``rolling_resistance`` set to it, so the fitted model is the library's one
drawbar-pull model), minimised on a grid refined by golden-section search within
:data:`MU_BOUNDS`, and its 95 % interval is the likelihood-ratio interval of that profile
(:func:`~soiltrack.identify.estimates.distributions.lr_threshold`, one more free parameter
than the soil fit). The soil is reported at the best mu_r, with its range over mu_r's
interval (the soil refitted at the interval's ends). Without the option the report says which
resistance was assumed.

Only the constant coefficient is fitted; a resistance proportional to the measured sinkage is
not (yet) a model of the library.
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable

import numpy as np

from ...soilmodel.data import SlipData
from ...soilmodel.errors import DataError
from ...soilmodel.vehicle import Vehicle
from ..estimates.distributions import lr_threshold
from ..estimates.result import FitResult

__all__ = ["RESISTANCE_MODES", "MU_BOUNDS", "GRID_POINTS", "GOLDEN_TOL", "fit_resistance", "assumed_resistance"]

#: ``"assumed"``: the vehicle's rolling_resistance; ``"fit"``: mu_r fitted with the soil.
RESISTANCE_MODES = ("assumed", "fit")
#: Range of the fitted coefficient (the Vehicle accepts mu_r in [0, 1)).
MU_BOUNDS = (0.0, 0.6)
#: Points of the first grid over :data:`MU_BOUNDS`.
GRID_POINTS = 13
#: The golden-section search stops when the bracket is this narrow (in mu_r).
GOLDEN_TOL = 1e-4
_PHI = (math.sqrt(5.0) - 1.0) / 2.0


def assumed_resistance(result: FitResult) -> dict:
    """The ``extra["resistance"]`` entry of a drawbar-pull fit with the vehicle's assumed coefficient."""
    mu = float(result.vehicle.rolling_resistance)
    return {"mode": "assumed", "coefficient": mu,
            "statement": f"assumed R = mu_r W with mu_r = {mu:g} (the vehicle's rolling_resistance), not fitted; "
                         "--resistance fit estimates it with the soil"}


def _cost(res: FitResult) -> float:
    return float(res.cost) if res.success and math.isfinite(res.cost) else math.inf


def fit_resistance(data: SlipData, vehicle: Vehicle, fit_at: Callable[[Vehicle, bool], FitResult]) -> FitResult:
    """Fit mu_r with the soil (see the module docs); returns the soil's fit at the best mu_r.

    Parameters
    ----------
    data
        A drawbar-pull sweep.
    vehicle
        The vehicle (its rolling_resistance is replaced by each trial value).
    fit_at
        ``fit_at(vehicle, final) -> FitResult``: the soil's fit with that vehicle; ``final`` is
        True for the reported fit (which may compute profile intervals), False inside the search.

    Raises
    ------
    DataError
        Tractive-force data (their resistance is already removed), or no trial value fitted.
    """
    if data.measured != "drawbar_pull":
        raise DataError("resistance='fit' applies to drawbar-pull data (tractive force already has the resistance "
                        "added back)", file=data.source)
    cache: dict[float, float] = {}

    def cost(mu: float) -> float:
        mu = float(mu)
        if mu not in cache:
            cache[mu] = _cost(fit_at(replace(vehicle, rolling_resistance=mu), False))
        return cache[mu]

    grid = np.linspace(*MU_BOUNDS, GRID_POINTS)
    costs = np.array([cost(m) for m in grid])
    if not np.any(np.isfinite(costs)):
        raise DataError(f"no soil fitted the drawbar pull at any resistance coefficient in {MU_BOUNDS}",
                        file=data.source)
    k = int(np.argmin(costs))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    c, d = b - _PHI * (b - a), a + _PHI * (b - a)
    while b - a > GOLDEN_TOL:
        if cost(c) <= cost(d):
            b, d = d, c
            c = b - _PHI * (b - a)
        else:
            a, c = c, d
            d = a + _PHI * (b - a)
    mu = min(cache, key=cache.get)
    best = fit_at(replace(vehicle, rolling_resistance=mu), True)
    cmin = _cost(best)
    if not math.isfinite(cmin):
        cmin = cache[mu]
    dof = int(best.dof) - 1  # one more free parameter than the soil's fit
    limit, how = lr_threshold(cmin, dof, bool(best.sigma_known))
    ends = [_end(cost, mu, side, limit) for side in (MU_BOUNDS[0], MU_BOUNDS[1])]
    soils = [fit_at(replace(vehicle, rolling_resistance=e), False) for e in ends if e is not None and e != mu]
    entry = {"mode": "fit", "coefficient": mu, "ci95": ends, "interval": how, "bounds": list(MU_BOUNDS),
             "at_bound": bool(mu - MU_BOUNDS[0] <= GOLDEN_TOL or MU_BOUNDS[1] - mu <= GOLDEN_TOL),
             "soil_over_interval": _soil_ranges([best, *soils])}
    entry["statement"] = _statement(entry)
    extra = {**(best.extra if isinstance(best.extra, dict) else {}), "resistance": entry}
    return replace(best, extra=extra)


def _end(cost: Callable[[float], float], mu: float, side: float, limit: float) -> float | None:
    """Where the profile crosses ``limit`` between ``mu`` and the bound ``side`` (the bound if it never does)."""
    if not math.isfinite(limit):
        return None
    if cost(side) <= limit:
        return float(side)
    lo, hi = mu, side  # cost(lo) <= limit < cost(hi)
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        if abs(hi - lo) <= GOLDEN_TOL:
            break
        lo, hi = (mid, hi) if cost(mid) <= limit else (lo, mid)
    return float(0.5 * (lo + hi))


def _soil_ranges(results: list[FitResult]) -> dict:
    """Range of each soil parameter (edge units) over the fits at mu_r's best value and interval ends."""
    out = {}
    ok = [r for r in results if r.success]
    for name, key, f in (("cohesion", "cohesion_kpa", 1e-3), ("friction_angle", "friction_angle_deg", 180 / math.pi),
                         ("shear_modulus", "shear_modulus_m", 1.0)):
        j = ("cohesion", "friction_angle", "shear_modulus").index(name)
        vals = [float(r.theta[j]) * f for r in ok if math.isfinite(r.theta[j])]
        if vals:
            out[key] = [min(vals), max(vals)]
    return out


def _statement(e: dict) -> str:
    lo, hi = e["ci95"]
    ci = f"95 % [{lo:.3g}, {hi:.3g}]" if lo is not None and hi is not None else "no interval (no residual dof)"
    bound = " [ON A BOUND of its range]" if e["at_bound"] else ""
    rng = e["soil_over_interval"]
    names = {"cohesion_kpa": ("c", "kPa"), "friction_angle_deg": ("phi", "deg"), "shear_modulus_m": ("K", "m")}
    soil = ", ".join(f"{names[k][0]} {v[0]:.3g} to {v[1]:.3g} {names[k][1]}" for k, v in rng.items())
    return (f"fitted R = mu_r W: mu_r = {e['coefficient']:.4g}, {ci} (profile likelihood){bound}; the soil below "
            f"is at this mu_r; over mu_r's interval: {soil}")
