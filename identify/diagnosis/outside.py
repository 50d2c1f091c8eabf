"""Causes outside the library, each a hypothesis fitted and scored like the effects.

Drive logs (held-out evidence: fitted on the training blocks, predicting the others):

- ``delay``: the vehicle-speed channel late (or early) against the sprocket speed. The lag comes from
  the nominal training residuals (:func:`~.log_parts.delay_scan`) and is refined by refits on the
  shifted log (:func:`~.log_parts.refine_delay`); the hypothesis is the nominal model on the log with
  the speed channel shifted back. Detail: ``lag_s``.
- ``terrain_change``: the soil differs within a time window. The window comes from the score test of
  the nominal fit on all the data (:func:`~.log_parts.terrain_window`); the hypothesis moves the soil
  inside the window by one Gauss-Newton step on the training samples there and predicts the held-out
  samples. It must beat the effects and the flexible term on held-out evidence like any other.
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
from ...soilmodel.soil import PRACTICAL_BOUNDS, WIDE_BOUNDS
from ..drivelog.sensitivity import drive_log_sensitivities
from .fits import SOIL_KEYS, channels, outside_practical, usable
from .hypotheses import Hypothesis
from .library import held_out
from .log_parts import SPEED_CHANNEL, delay_scan, refine_delay, shift_speed, terrain_window
from .saturation import find_saturation
from .setup import Setup
from .sweep_parts import find_plateau

__all__ = ["outside_hypotheses"]


def _not_formed(name: str, why: str, n: int, channels_: list[str]) -> Hypothesis:
    return Hypothesis(name, "outside", 0, {ch: np.full(n, np.inf) for ch in channels_}, admissible=False, why=why)


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


def _with_soil(res: Any, fmax: float, k: float) -> Any:
    """Fit result ``res`` with its thrust limit and shear modulus replaced (a drive-log model predicts
    from these two)."""
    extra = dict(res.extra)
    if extra.get("joint_parameters") is not None:
        extra["joint_parameters"] = dict(extra["joint_parameters"], max_thrust_N=fmax, shear_modulus_m=k)
    extra.update(max_thrust_N=fmax, shear_modulus_m=k)
    return replace(res, extra=extra)


def _inside_soil(
    train_fit: Any, data: Any, vehicle: Any, tr: np.ndarray, inside: np.ndarray
) -> tuple[float, float] | None:
    """``(F_max, K)`` inside the window: one Gauss-Newton step from the training fit on its training samples
    inside the window (the soil outside stays the training fit's). None without information there."""
    sens = drive_log_sensitivities(train_fit, data, vehicle)
    used = np.nonzero(sens.keep)[0]
    rows = np.isin(used, tr) & inside[used]
    if np.count_nonzero(rows) < 2:
        return None
    J = sens.jacobian[rows][:, :, :2].reshape(-1, 2)
    e = sens.residuals[rows].reshape(-1)
    d = -np.linalg.pinv(J.T @ J) @ (J.T @ e)
    f0, k0 = float(train_fit.extra["max_thrust_N"]), float(train_fit.extra["shear_modulus_m"])
    return f0 + float(d[0]), k0 + float(d[1])


def terrain_hypothesis(setup: Setup, train_fit: Any, nominal_held: dict[str, np.ndarray]) -> Hypothesis:
    """A different soil inside a time window (drive logs).

    The window is found like the effects are screened: by the score test of the nominal fit on all
    the data (:func:`~.log_parts.terrain_window`). The hypothesis is then judged like the others on
    the held-out samples: outside the window the nominal training fit predicts them; inside, its
    soil (F_max, K) moved by one Gauss-Newton step on the training samples inside the window.
    """
    s, data, run = setup.settings, setup.data, setup.runner
    tr, te = setup.folds[0]
    try:
        sens = drive_log_sensitivities(setup.nominal_fit, data, run.vehicle)
        ex = setup.nominal_fit.extra
        win = terrain_window(
            sens.residuals,
            sens.jacobian,
            sens.time_s,
            alpha=s.alpha,
            scale=(float(ex.get("max_thrust_N", 1.0)), float(ex.get("shear_modulus_m", 1.0))),
        )
    except DataError:
        win = None
    if win is None or not win.significant:
        why = (
            "the soil's score test finds no window"
            if win is None
            else f"no time window where the soil differs significantly (p = {win.p_value:.2g})"
        )
        return _not_formed("terrain_change", why, setup.n, setup.channels)
    t = np.asarray(data.time, dtype=float)
    inside = (t >= win.evidence_start) & (t <= win.evidence_end)
    detail = {
        "window_s": [float(win.evidence_start), float(win.evidence_end)],
        "bracket_s": [float(win.start), float(win.end)],
        "score_p_value": float(win.p_value),
    }
    try:
        soil = _inside_soil(train_fit, data, run.vehicle, tr, inside)
        if soil is None or not (soil[0] > 0 and soil[1] > 0):
            return Hypothesis(
                "terrain_change",
                "outside",
                5,
                {ch: np.full(setup.n, np.inf) for ch in setup.channels},
                admissible=False,
                detail=detail,
                why="the training samples inside the window give no soil of physical sign",
            )
        rin = channels(_with_soil(train_fit, *soil), data)
    except DataError as e:
        return _not_formed("terrain_change", f"no soil inside the window ({e})", setup.n, setup.channels)
    held = {ch: np.full(setup.n, np.nan) for ch in setup.channels}
    for ch in setup.channels:
        held[ch][te] = np.where(inside[te], rin[ch][te], nominal_held[ch][te])
    f0, k0 = float(train_fit.extra["max_thrust_N"]), float(train_fit.extra["shear_modulus_m"])
    params = {
        "fmax_change": {"value": soil[0] / f0 - 1.0, "identifiable": True, "at_bound": False},
        "k_change": {"value": soil[1] / k0 - 1.0, "identifiable": True, "at_bound": False},
    }
    return Hypothesis("terrain_change", "outside", 4, held, held=held, detail=detail, parameters=params)


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


def wider_soil_hypothesis(setup: Setup) -> Hypothesis:
    """The nominal model with the soil bounds widened (when the nominal soil ends on a practical edge)."""
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
    detail = {"outside_practical_range": outside_practical(ref), "on_practical_bound": sorted(edges)}
    return Hypothesis("soil_beyond_range", "outside", 0, resid, held=held, detail=detail, fit=ref)


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


def outside_hypotheses(setup: Setup, nominal: Hypothesis, train_res: list, train_fit: Any) -> list[Hypothesis]:
    """Every outside cause this kind of data can show (formed or not)."""
    out = [wider_soil_hypothesis(setup), clipped_hypothesis(setup)]
    if setup.is_log:
        out += [delay_hypothesis(setup, train_res), terrain_hypothesis(setup, train_fit, nominal.heldout())]
    else:
        out.append(plateau_hypothesis(setup))
    return out
