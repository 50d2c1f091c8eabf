"""Causes outside the library, each a hypothesis fitted and scored like the effects.

Drive logs (held-out evidence: fitted on the training blocks, predicting the others):

- ``delay``: the vehicle-speed channel late (or early) against the sprocket speed. The lag comes from
  the nominal training residuals (:func:`~.log_parts.delay_scan`) and is refined by refits on the
  shifted log (:func:`~.log_parts.refine_delay`); the hypothesis is the nominal model on the log with
  the speed channel shifted back. Detail: ``lag_s``.
- ``terrain_change``: the soil differs within a time window. The window comes from the score test of
  the nominal fit on all the data (:func:`~.log_parts.terrain_window`); the hypothesis fits the soil
  on the training samples outside the window and its small-slip slope on those inside, each predicting
  the held-out samples on its side. It must beat the effects and the flexible term on held-out evidence like any other.
  Detail: ``window_s`` (where the data show it) and ``bracket_s`` (where its boundaries can lie).

Both kinds of data:

- ``soil_beyond_range``: the nominal model with the soil bounds widened, when the nominal soil
  ends on an edge of the practical range (admissible when the wider soil lies outside it).
- ``clipped_sensor``: readings piled up exactly at a channel's extreme (:func:`~.saturation.find_saturation`);
  the nominal model fitted without them, a censored reading contributing one noise unit.

Sweeps (penalised in-sample evidence): ``plateau``, the largest readings flat at one level within
the noise where the soil fitted below still rises (:func:`~.sweep_parts.find_plateau`).

A cause whose trace the data do not show (no significant lag, no significant window, nothing
clipped, no soil on a bound) is listed as not formed, with the reason; it is not weighed.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from ...soilmodel.errors import DataError
from ..estimates.distributions import chi2_sf
from ...soilmodel.soil import PRACTICAL_BOUNDS, WIDE_BOUNDS
from ..drivelog.sensitivity import drive_log_sensitivities
from .fits import SOIL_KEYS, channels, outside_practical, usable
from .hypotheses import Hypothesis
from .library import held_out
from .log_parts import (
    SPEED_CHANNEL,
    delay_scan,
    refine_delay,
    scale_speed,
    shift_speed,
    speed_scale_screen,
    terrain_window,
)
from .saturation import find_saturation
from .selection import dm_test
from .setup import Setup
from .sweep_parts import find_plateau

__all__ = ["outside_hypotheses"]


def _not_formed(name: str, why: str, n: int, channels_: list[str], detail: dict | None = None) -> Hypothesis:
    return Hypothesis(
        name,
        "outside",
        0,
        {ch: np.full(n, np.inf) for ch in channels_},
        admissible=False,
        why=why,
        detail=detail or {},
    )


def delay_hypothesis(setup: Setup, train_res: list) -> Hypothesis:
    """The vehicle-speed channel delayed against the sprocket speed (drive logs)."""
    s, data = setup.settings, setup.data
    tr, te = setup.folds[0]
    rtr = train_res[0].get(SPEED_CHANNEL)
    if rtr is None:
        return _not_formed("delay", "no speed channel", setup.n, setup.channels)
    scan = delay_scan(rtr, data.sprocket_speed, s.max_delay_samples, idx=tr)
    if not scan["p_value"] < s.alpha:
        return _not_formed(
            "delay",
            f"the delay scan finds no significant lag (p = {scan['p_value']:.2g})",
            setup.n,
            setup.channels,
        )
    k, fit_k = refine_delay(
        setup.nominal_fit, data, setup.runner.vehicle, tr, int(np.sign(scan["lag"])), s.max_delay_samples
    )
    if k == 0 or fit_k is None:
        return _not_formed(
            "delay", "no shift of the speed channel fits the training blocks better", setup.n, setup.channels
        )
    full = channels(fit_k, shift_speed(data, k))
    held = {ch: np.full(setup.n, np.nan) for ch in setup.channels}
    for ch in setup.channels:
        held[ch][te] = full[ch][te]
    h = float(np.median(np.diff(np.asarray(data.time, dtype=float))))
    detail = {"lag_samples": int(k), "lag_s": float(k * h), "scan_p_value": float(scan["p_value"])}
    return Hypothesis(
        "delay",
        "outside",
        1,
        held,
        held=held,
        detail=detail,
        parameters={"lag_s": {"value": float(k * h), "identifiable": True, "at_bound": False}},
    )


def _scaled_fit(setup: Setup, gain: float) -> tuple[float, Any]:
    """The nominal model refitted (warm) on the training blocks of the log with the vehicle speed divided by
    ``1 + gain``: its cost and fit (inf, None when it does not converge)."""
    tr = setup.folds[0][0]
    try:
        res = setup.runner.run_on(scale_speed(setup.data, gain), tr)
    except DataError:
        return math.inf, None
    return (float(res.cost), res) if usable(res, True) else (math.inf, None)


def speed_scale_hypothesis(setup: Setup, radius: Hypothesis | None) -> Hypothesis:
    """The vehicle-speed channel reading a constant factor high or low (drive logs).

    Its slip signature is a radius error's (both scale the apparent slip; only a radius error also
    changes the torque arm), so it is formed where the radius error was refitted, from its fitted
    ``eps``: the gain is the minimum of a parabola through the training costs at 0.5, 1 and 1.5 times
    ``eps``, then the nominal model refitted on the corrected log predicts the held-out blocks."""
    eps = None if radius is None else radius.parameters.get("eps", {}).get("value")
    if eps is None or not math.isfinite(float(eps)) or float(eps) == 0.0:
        return _not_formed("speed_scale", "no radius-like slip scale was fitted", setup.n, setup.channels)
    gains = np.array([0.5, 1.0, 1.5]) * float(eps)
    costs = np.array([_scaled_fit(setup, float(g))[0] for g in gains])
    if not np.all(np.isfinite(costs)):
        return _not_formed("speed_scale", "a fit with the speed rescaled did not converge", setup.n, setup.channels)
    a, b, _ = np.polyfit(gains, costs, 2)
    g = (
        float(np.clip(-b / (2 * a), gains[0] - 0.5 * float(eps), gains[-1] + 0.5 * float(eps)))
        if a > 0
        else float(gains[int(np.argmin(costs))])
    )
    cost, res = _scaled_fit(setup, g)
    if res is None:
        return _not_formed("speed_scale", "the fit with the speed rescaled did not converge", setup.n, setup.channels)
    te = setup.folds[0][1]
    full = channels(res, scale_speed(setup.data, g))
    held = {ch: np.full(setup.n, np.nan) for ch in setup.channels}
    for ch in setup.channels:
        held[ch][te] = full[ch][te]
    return Hypothesis(
        "speed_scale",
        "outside",
        1,
        held,
        held=held,
        detail={"gain": g},
        parameters={"gain": {"value": g, "identifiable": True, "at_bound": False}},
        direction=speed_scale_screen(
            setup.nominal_fit, setup.data, setup.runner.vehicle, sensitivities=setup.sensitivities
        ).direction,
    )


def _soil_of(res: Any) -> tuple[float, float]:
    """``(F_max, K)`` of a drive-log fit."""
    return float(res.extra["max_thrust_N"]), float(res.extra["shear_modulus_m"])


def _with_soil(res: Any, fmax: float, k: float) -> Any:
    """Fit result ``res`` with its thrust limit and shear modulus replaced (a drive-log model predicts
    from these two)."""
    extra = dict(res.extra)
    if extra.get("joint_parameters") is not None:
        extra["joint_parameters"] = dict(extra["joint_parameters"], max_thrust_N=fmax, shear_modulus_m=k)
    extra.update(max_thrust_N=fmax, shear_modulus_m=k)
    return replace(res, extra=extra)


def _slope_cost(setup: Setup, outside_fit: Any, span: np.ndarray, rows: np.ndarray, logk: float) -> float:
    """Sum of squared standardised residuals, on the samples ``rows`` of the contiguous stretch ``span``, of
    the outside soil with its shear modulus set to ``exp(logk)``."""
    f0, _ = _soil_of(outside_fit)
    try:
        r = channels(_with_soil(outside_fit, f0, math.exp(logk)), setup.data.subset(span))
    except DataError:
        return math.inf
    z = np.concatenate([r[ch][rows] / setup.sigma[ch][span[rows]] for ch in setup.channels])
    z = z[np.isfinite(z)]
    return float(z @ z) if z.size else math.inf


def _inside_modulus(setup: Setup, outside_fit: Any, span: np.ndarray, rows: np.ndarray) -> tuple[float, bool]:
    """The shear modulus inside the window, the thrust limit kept at the outside soil's: the least squares
    of the standardised residuals on the training samples ``rows`` of the window's stretch ``span``, over
    log K (a grid, then parabolic steps inside the grid's bracket). A soft patch driven gently shows only
    its small-slip slope ``F_max l / (2 K)``: one number, which K carries; the thrust limit stays the one
    the rest of the run supports, so the prediction inside never asks for more thrust than the soil can
    give. Returns K and whether it ends on an edge of the range searched."""
    s = setup.settings
    k0 = _soil_of(outside_fit)[1]
    lo, hi = math.log(k0 / s.terrain_slope_ratio), math.log(k0 * s.terrain_slope_ratio)
    grid = np.linspace(lo, hi, s.terrain_grid)
    costs = [_slope_cost(setup, outside_fit, span, rows, g) for g in grid]
    j = int(np.argmin(costs))
    if j in (0, grid.size - 1):  # the least cost on an edge: half way to the neighbour tells
        nb = 1 if j == 0 else grid.size - 2
        mid = 0.5 * (grid[j] + grid[nb])
        f_mid = _slope_cost(setup, outside_fit, span, rows, mid)
        if not f_mid < costs[j]:
            return math.exp(float(grid[j])), True
        pts = sorted([(float(grid[j]), costs[j]), (mid, f_mid), (float(grid[nb]), costs[nb])])
    else:
        pts = [(float(grid[i]), costs[i]) for i in (j - 1, j, j + 1)]
    (a, fa), (b, fb), (c, fc) = pts
    for _ in range(s.terrain_refine_steps):
        u = _parabola_vertex(a, fa, b, fb, c, fc)
        if u is None or not a < u < c or abs(u - b) < s.terrain_tol_log_k:
            break
        fu = _slope_cost(setup, outside_fit, span, rows, u)
        if fu < fb:  # u is the new centre; b bounds it on its side
            (a, fa, c, fc) = (b, fb, c, fc) if u > b else (a, fa, b, fb)
            b, fb = u, fu
        elif u < b:
            a, fa = u, fu
        else:
            c, fc = u, fu
    return math.exp(b), bool(min(b - lo, hi - b) < 1e-3 * (hi - lo))


def _parabola_vertex(a: float, fa: float, b: float, fb: float, c: float, fc: float) -> float | None:
    """The abscissa of the minimum of the parabola through three points (None when it has none)."""
    p = (b - a) * (fb - fc)
    q = (b - c) * (fb - fa)
    den = 2.0 * (p - q)
    if not (math.isfinite(den) and den != 0.0) or not all(map(math.isfinite, (fa, fb, fc))):
        return None
    u = b - ((b - a) * p - (b - c) * q) / den
    return u if (fb <= fa and fb <= fc) else None


def _window(setup: Setup) -> Any:
    """The soil's score-test window of the nominal fit on all the data (None when it cannot be made)."""
    try:
        sens = setup.sensitivities
        if sens is None:
            sens = drive_log_sensitivities(setup.nominal_fit, setup.data, setup.runner.vehicle)
        soil = sens.soil()
        return terrain_window(
            soil.residuals, soil.jacobian, soil.time_s, alpha=setup.settings.alpha, scale=_soil_of(setup.nominal_fit)
        )
    except DataError:
        return None


def terrain_hypothesis(setup: Setup, nominal_held: dict[str, np.ndarray], train_fit: Any) -> Hypothesis:
    """A different soil inside a time window (drive logs).

    The window is found like the effects are screened: by the score test of the nominal fit on all
    the data (:func:`~.log_parts.terrain_window`). The hypothesis is then fitted and judged like the
    others: the nominal model refitted on the training samples outside the window predicts the held-out
    samples outside; inside, its small-slip slope refitted on the training samples there
    (:func:`_inside_modulus`). When that refit fails or the samples outside cannot be fitted (a window over
    most of the run), the nominal training fit ``train_fit`` (which leans towards the window's soil) stands
    in for it. Parameters: the slope inside and the window's two ends.
    """
    win = _window(setup)
    if win is None or not win.significant:
        why = (
            "the soil's score test finds no window"
            if win is None
            else f"no time window where the soil differs significantly (p = {win.p_value:.2g})"
        )
        return _not_formed(
            "terrain_change", why, setup.n, setup.channels, None if win is None else {"score_p_value": win.p_value}
        )
    tr, te = setup.folds[0]
    t = np.asarray(setup.data.time, dtype=float)
    inside = (t >= win.evidence_start) & (t <= win.evidence_end)
    detail = {
        "window_s": [float(win.evidence_start), float(win.evidence_end)],
        "bracket_s": [float(win.start), float(win.end)],
        "score_p_value": float(win.p_value),
    }
    span = np.nonzero(inside)[0]
    span = np.arange(span[0], span[-1] + 1) if span.size else span
    rows = np.nonzero(np.isin(span, tr))[0]
    if rows.size < setup.settings.min_samples or not usable(train_fit, True):
        return _not_formed("terrain_change", "too few training samples inside the window", setup.n, setup.channels)
    # the soil outside: the nominal model refitted on the training samples outside the window (the nominal
    # training fit leans towards the window's soil); it predicts the held-out samples outside, and the slope
    # inside is searched from it
    try:
        outside = setup.runner.run_warm(tr[~np.isin(tr, span)])
    except DataError:  # too little outside the window to fit (a window over most of the run)
        outside = None
    base = outside if usable(outside, True) else train_fit
    f0, k0 = _soil_of(base)
    k1, on_edge = _inside_modulus(setup, base, span, rows)
    try:
        rin = channels(_with_soil(base, f0, k1), setup.data.subset(span))
        rout = channels(base, setup.data) if base is outside else nominal_held
    except DataError as e:
        return _not_formed("terrain_change", f"no prediction inside the window ({e})", setup.n, setup.channels)
    held = {ch: np.where(np.isin(np.arange(setup.n), te), rout[ch], np.nan) for ch in setup.channels}
    test_in = np.isin(span, te)
    for ch in setup.channels:
        held[ch][span[test_in]] = rin[ch][test_in]
    params = {"slope_change": {"value": k0 / k1 - 1.0, "identifiable": True, "at_bound": on_edge}}
    detail.update(max_thrust_N=f0, shear_modulus_inside_m=k1, shear_modulus_outside_m=k0)
    window = np.zeros(setup.n, dtype=bool)
    window[span] = True
    return Hypothesis(
        "terrain_change",
        "outside",
        3,
        held,
        held=held,
        detail=detail,
        parameters=params,
        support={ch: window for ch in setup.channels},
        admissible=not on_edge,
        why="the small-slip slope inside the window ends on an edge of the range searched" if on_edge else "",
    )


def _bound_edges(nominal: Any) -> dict[str, str]:
    """Soil parameters on a practical bound that the wide bounds move."""
    j_of = {name: j for j, name in enumerate(SOIL_KEYS)}
    out = {}
    for k, side in dict(getattr(nominal, "active_bounds", None) or {}).items():
        if k in j_of:
            pb = (PRACTICAL_BOUNDS.lower if side == "lower" else PRACTICAL_BOUNDS.upper)[j_of[k]]
            wb = (WIDE_BOUNDS.lower if side == "lower" else WIDE_BOUNDS.upper)[j_of[k]]
            if pb != wb:
                out[k] = side
    return out


def _beats_nominal(setup: Setup, nominal: Hypothesis, resid: dict[str, np.ndarray], extra_params: int) -> float:
    """p-value that residuals ``resid`` of a model nesting the nominal one fit better than the nominal's: a
    log's held-out (Diebold-Mariano), a sweep's in-sample (likelihood ratio, ``extra_params`` dof)."""
    base = nominal.heldout() if setup.is_log else nominal.residuals
    mask = {ch: np.isfinite(base[ch]) & (np.nan_to_num(setup.sigma[ch]) > 0) for ch in setup.channels}
    z0 = np.concatenate([base[ch][m] / setup.sigma[ch][m] for ch, m in mask.items()])
    z1 = np.concatenate([resid[ch][m] / setup.sigma[ch][m] for ch, m in mask.items()])
    if not np.all(np.isfinite(z1)):
        return 1.0
    if setup.is_log:
        return dm_test(z0, z1, setup.dm_lag)
    s0, s1 = float(z0 @ z0), float(z1 @ z1)
    if s1 <= 0 or s0 <= s1:
        return 1.0
    return chi2_sf(z0.size * math.log(s0 / s1), max(1, extra_params))


def wider_soil_hypothesis(setup: Setup, nominal: Hypothesis) -> Hypothesis:
    """The nominal model with the soil bounds widened (when the nominal soil ends on a practical edge).

    It nests the nominal model: it enters the comparison only when it fits significantly better (at
    ``alpha``); otherwise it is the nominal model again and would only split its weight."""
    run, nom = setup.runner, setup.nominal_fit
    edges = _bound_edges(nom)
    if not edges or setup.runner.options.get("bounds") is not PRACTICAL_BOUNDS:
        return _not_formed(
            "soil_beyond_range",
            "the nominal soil ends on no edge of the practical range" if not edges else "the soil bounds were given",
            setup.n,
            setup.channels,
        )
    x0 = np.asarray(nom.theta, dtype=float)
    held, fits, _ = held_out(
        setup,
        lambda tr: run.run_warm(tr, bounds=WIDE_BOUNDS) if setup.is_log else run.run(tr, bounds=WIDE_BOUNDS, x0=x0),
    )
    ref = fits[0] if setup.is_log else run.run(None, bounds=WIDE_BOUNDS, x0=x0)
    if not usable(ref, setup.is_log) or not outside_practical(ref) or any(k in edges for k in ref.active_bounds):
        return _not_formed(
            "soil_beyond_range",
            "the soil with the bounds widened stays in the practical range or ends on a wide bound",
            setup.n,
            setup.channels,
        )
    resid = held if setup.is_log else channels(ref, setup.data)
    p = _beats_nominal(setup, nominal, resid, len(edges))
    if not p < setup.settings.alpha:
        return _not_formed(
            "soil_beyond_range",
            f"the soil beyond the practical range fits no better than the one on its edge (p = {p:.2g})",
            setup.n,
            setup.channels,
        )
    detail = {
        "outside_practical_range": outside_practical(ref),
        "on_practical_bound": sorted(edges),
        "p_value": float(p),
    }
    return Hypothesis("soil_beyond_range", "outside", len(edges), resid, held=held, detail=detail, fit=ref)


def clipped_hypothesis(setup: Setup) -> Hypothesis:
    """The nominal model fitted without the clipped readings; a censored reading counts one noise unit."""
    sat = find_saturation(setup.data)
    if not sat:
        return _not_formed("clipped_sensor", "no channel piles up at its extreme", setup.n, setup.channels)
    clipped = np.zeros(setup.n, dtype=bool)
    for c in sat:
        clipped[np.asarray(c.rows) - 1] = True
    run = setup.runner
    keep = np.nonzero(~clipped)[0]
    try:
        if setup.is_log:
            held, _, _ = held_out(setup, lambda tr: run.run_warm(tr[~clipped[tr]]))
            resid = held
        else:
            f = run.run(keep)
            resid = channels(f, setup.data)
            held = None
    except DataError as e:
        return _not_formed("clipped_sensor", f"no fit without the clipped readings ({e})", setup.n, setup.channels)
    for ch in setup.channels:
        resid[ch][clipped] = setup.sigma[ch][clipped]
    detail = {
        "channels": sorted({c.channel for c in sat}),
        "rows": int(np.count_nonzero(clipped)),
        "levels": {c.channel: float(c.level) for c in sat},
    }
    return Hypothesis("clipped_sensor", "outside", 1, resid, held=held, detail=detail)


def plateau_hypothesis(setup: Setup) -> Hypothesis:
    """The soil below, one flat level on the largest readings (sweeps)."""
    data, run, ch = setup.data, setup.runner, setup.channels[0]
    values = np.asarray(data.values, dtype=float)

    def fit_below(idx: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        try:
            f = run.run(idx)
            r = channels(f, data)[ch] if usable(f, False) else None
        except DataError:
            return None
        if r is None:
            return None
        rest = np.setdiff1d(np.arange(setup.n), idx)
        return r[idx], values[rest] - r[rest]

    pl = find_plateau(values, setup.x, setup.sigma[ch], fit_below) if len(setup.channels) == 1 else None
    if pl is None:
        return _not_formed(
            "plateau", "no flat level on the largest readings above a rising soil", setup.n, setup.channels
        )
    detail = {"level_N": float(pl.level), "rows": len(pl.rows), "slip_range": list(pl.slip_range)}
    return Hypothesis(
        "plateau",
        "outside",
        2,
        {ch: pl.z * setup.sigma[ch]},
        detail=detail,
        parameters={
            "level_N": {
                "value": float(pl.level),
                "stderr": float(pl.level_stderr) if math.isfinite(pl.level_stderr) else None,
                "identifiable": True,
                "at_bound": False,
            }
        },
    )


def outside_hypotheses(
    setup: Setup, nominal: Hypothesis, train_res: list, train_fit: Any, effects: list[Hypothesis]
) -> list[Hypothesis]:
    """Every outside cause this kind of data can show (formed or not); ``effects``: the library effects
    refitted (a speed scale is formed from the radius error's fit)."""
    out = [wider_soil_hypothesis(setup, nominal), clipped_hypothesis(setup)]
    if setup.is_log:
        radius = next((h for h in effects if h.name == "radius_error" and h.admissible), None)
        out += [
            delay_hypothesis(setup, train_res),
            terrain_hypothesis(setup, nominal.heldout(), train_fit),
            speed_scale_hypothesis(setup, radius),
        ]
    else:
        out.append(plateau_hypothesis(setup))
    return out
