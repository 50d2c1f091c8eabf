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

``resistance="fit-sinkage"`` fits instead a resistance proportional to the measured sinkage,
``R = k_z z W`` (k_z in 1/m, the data's ``sinkage_m`` per row): at each trial k_z the readings
become tractive forces ``DP + k_z z W`` (what Eq. 2 predicts), and the result predicts drawbar
pulls of data that carry their sinkage (:class:`SinkageResistance`).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable

import numpy as np

from dataclasses import dataclass

from ...soilmodel.data import STD_COLUMNS, SlipData
from ...soilmodel.errors import DataError
from ...soilmodel.search import golden_section
from ...soilmodel.vehicle import Vehicle
from ..estimates.distributions import lr_threshold
from ..estimates.result import FitResult
from .model import SweepResiduals

__all__ = [
    "RESISTANCE_MODES",
    "MU_BOUNDS",
    "GRID_POINTS",
    "GOLDEN_TOL",
    "fit_resistance",
    "assumed_resistance",
    "SinkageResistance",
]

#: ``"assumed"``: the vehicle's rolling_resistance; ``"fit"``: mu_r fitted with the soil;
#: ``"fit-sinkage"``: ``R = k_z z W`` with k_z fitted (needs ``sinkage_m``).
RESISTANCE_MODES = ("assumed", "fit", "fit-sinkage")
#: Range of the fitted coefficient (the Vehicle accepts mu_r in [0, 1)).
MU_BOUNDS = (0.0, 0.6)
#: Points of the first grid over :data:`MU_BOUNDS`.
GRID_POINTS = 13
#: The golden-section search stops when the bracket is this narrow (in mu_r).
GOLDEN_TOL = 1e-4


def assumed_resistance(result: FitResult) -> dict:
    """The ``extra["resistance"]`` entry of a drawbar-pull fit with the vehicle's assumed coefficient."""
    mu = float(result.vehicle.rolling_resistance)
    return {
        "mode": "assumed",
        "coefficient": mu,
        "statement": f"assumed R = mu_r W with mu_r = {mu:g} (the vehicle's rolling_resistance), not fitted; "
        "--resistance fit estimates it with the soil",
    }


def _cost(res: FitResult) -> float:
    return float(res.cost) if res.success and math.isfinite(res.cost) else math.inf


@dataclass(frozen=True)
class SinkageResistance:
    """Residual model of a fit with ``R = k_z z W``: drawbar pulls of data carrying their sinkage.

    The fit itself is on the tractive forces ``DP + k_z z W``; this hook turns data of drawbar
    pull (with ``sinkage_m``) into those and hands them to ``base`` (the sweep's residual model).
    """

    k_z: float
    base: SweepResiduals

    def residuals_on(self, result, data) -> dict:
        """``{drawbar_pull_N: measured - predicted}`` of data with a sinkage column."""
        if not isinstance(data, SlipData) or data.measured != "drawbar_pull" or data.sinkage is None:
            raise DataError(
                "this fit's resistance is proportional to the sinkage: it predicts drawbar pulls "
                "of data with a sinkage_m column",
                file=getattr(data, "source", None),
            )
        tf = _as_tractive(data, self.k_z, result.vehicle.weight)
        return {data.channel: next(iter(self.base.residuals_on(result, tf).values()))}


def _as_tractive(data: SlipData, k_z: float, weight: float) -> SlipData:
    """The drawbar pulls as tractive forces ``DP + k_z z W`` (same rows, weights and loads; ``weight``
    where the data carry no load)."""
    W = data.loads(weight)
    if data.sinkage is None:
        raise DataError("a resistance proportional to the sinkage needs a sinkage_m column", file=data.source)
    return SlipData(
        slip=data.slip,
        tractive_force=data.values + k_z * data.sinkage * W,
        normal_load=data.normal_load,
        source=data.source,
        sinkage=data.sinkage,
        force_std=data.force_std,
        dropped=data.dropped,
    )


def fit_resistance(
    data: SlipData,
    vehicle: Vehicle,
    fit_at: Callable[[SlipData, Vehicle, bool], FitResult],
    form: str = "fit",
    base_residuals: SweepResiduals | None = None,
) -> FitResult:
    """Fit the resistance with the soil (see the module docs); returns the soil's fit at the best value.

    Parameters
    ----------
    data
        A drawbar-pull sweep (with ``sinkage_m`` for ``form="fit-sinkage"``).
    vehicle
        The vehicle (its rolling_resistance is replaced by each trial value for ``form="fit"``).
    fit_at
        ``fit_at(data, vehicle, final) -> FitResult``: the soil's fit; ``final`` is True for the
        reported fit (which may compute profile intervals), False inside the search.
    form
        ``"fit"`` (R = mu_r W) or ``"fit-sinkage"`` (R = k_z z W).
    base_residuals
        The sweep's residual model, wrapped by :class:`SinkageResistance` for ``"fit-sinkage"``.

    Raises
    ------
    DataError
        Tractive-force data (their resistance is already removed), no sinkage for
        ``"fit-sinkage"``, or no trial value fitted.
    """
    if data.measured != "drawbar_pull":
        raise DataError(
            f"resistance={form!r} applies to drawbar-pull data (tractive force already has the resistance added back)",
            file=data.source,
        )
    if form == "fit-sinkage":
        if data.sinkage is None:
            raise DataError("resistance='fit-sinkage' needs a sinkage_m column", file=data.source)
        z_max = float(max(data.sinkage.max(), 1e-12))
        hi = MU_BOUNDS[1] / z_max  # R / W at most MU_BOUNDS[1] at the deepest row

        def trial(v: float, final: bool) -> FitResult:
            return fit_at(_as_tractive(data, v, vehicle.weight), vehicle, final)
    else:
        hi = MU_BOUNDS[1]

        def trial(v: float, final: bool) -> FitResult:
            return fit_at(data, replace(vehicle, rolling_resistance=v), final)

    lo_b = MU_BOUNDS[0]
    tol = GOLDEN_TOL * (hi - lo_b) / (MU_BOUNDS[1] - MU_BOUNDS[0])
    cache: dict[float, float] = {}

    def cost(v: float) -> float:
        v = float(v)
        if v not in cache:
            cache[v] = _cost(trial(v, False))
        return cache[v]

    grid = np.linspace(lo_b, hi, GRID_POINTS)
    costs = np.array([cost(m) for m in grid])
    if not np.any(np.isfinite(costs)):
        raise DataError(f"no soil fitted the drawbar pull at any resistance in [{lo_b:g}, {hi:.4g}]", file=data.source)
    k = int(np.argmin(costs))
    golden_section(cost, float(grid[max(k - 1, 0)]), float(grid[min(k + 1, grid.size - 1)]), tol=tol)
    v = min(cache, key=lambda m: cache[m])
    best = trial(v, True)
    cmin = _cost(best)
    if not math.isfinite(cmin):
        cmin = cache[v]
    dof = int(best.dof) - 1  # one more free parameter than the soil's fit
    limit, how = lr_threshold(cmin, dof, bool(best.sigma_known))
    ends = [_end(cost, v, side, limit, tol) for side in (lo_b, hi)]
    soils = [trial(e, False) for e in ends if e is not None and e != v]
    entry = {
        "mode": form,
        "coefficient": v,
        "ci95": ends,
        "interval": how,
        "bounds": [lo_b, hi],
        "unit": "1/m" if form == "fit-sinkage" else "-",
        "at_bound": bool(v - lo_b <= tol or hi - v <= tol),
        "soil_over_interval": _soil_ranges([best, *soils]),
    }
    if form == "fit-sinkage":
        z = np.asarray(data.sinkage, dtype=float)
        entry["mu_r_range"] = [float(v * z.min()), float(v * z.max())]
    entry["statement"] = _statement(entry)
    extra = {**(best.extra if isinstance(best.extra, dict) else {}), "resistance": entry}
    if form == "fit-sinkage":
        if "weights_from" in extra:  # the fit saw the pulls as tractive forces; the column was the pull's
            extra["weights_from"] = STD_COLUMNS[data.measured]
        if base_residuals is None:
            raise ValueError("fit_resistance: form='fit-sinkage' needs base_residuals (the sweep's residual model)")
        return replace(best, extra=extra, measured="drawbar_pull", residual_model=SinkageResistance(v, base_residuals))
    return replace(best, extra=extra)


def _end(cost: Callable[[float], float], mu: float, side: float, limit: float, tol: float) -> float | None:
    """Where the profile crosses ``limit`` between ``mu`` and the bound ``side`` (the bound if it never does)."""
    if not math.isfinite(limit):
        return None
    if cost(side) <= limit:
        return float(side)
    lo, hi = mu, side  # cost(lo) <= limit < cost(hi)
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        if abs(hi - lo) <= tol:
            break
        lo, hi = (mid, hi) if cost(mid) <= limit else (lo, mid)
    return float(0.5 * (lo + hi))


def _soil_ranges(results: list[FitResult]) -> dict:
    """Range of each soil parameter (edge units) over the fits at mu_r's best value and interval ends."""
    out = {}
    ok = [r for r in results if r.success]
    for name, key, f in (
        ("cohesion", "cohesion_kpa", 1e-3),
        ("friction_angle", "friction_angle_deg", 180 / math.pi),
        ("shear_modulus", "shear_modulus_m", 1.0),
    ):
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
    if e["mode"] == "fit-sinkage":
        a, b = e["mu_r_range"]
        head = (
            f"fitted R = k_z z W: k_z = {e['coefficient']:.4g} 1/m, {ci} 1/m (profile likelihood)"
            f"{bound}, i.e. R / W from {a:.3g} to {b:.3g} over the rows' sinkage"
        )
    else:
        head = f"fitted R = mu_r W: mu_r = {e['coefficient']:.4g}, {ci} (profile likelihood){bound}"
    return f"{head}; the soil below is at this value; over its interval: {soil}"
