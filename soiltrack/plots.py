"""Figures for the command-line tool and the examples (matplotlib, Agg backend, PNG)."""

from __future__ import annotations

from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .identify.estimates.report import RESIDUAL_SIGN  # noqa: E402
from .soilmodel import DataError, DriveLog, SlipData, choose_scale  # noqa: E402
from .soilmodel.figures import save_figure  # noqa: E402  (the one helper; callers use plots.save_figure)
from .soilmodel.ridge import MAX_LOAD_LEVELS  # noqa: E402  (more distinct loads: drawn by load range)


_QUANTITY = {"tractive_force": "tractive force F", "drawbar_pull": "drawbar pull DP"}
#: The fitted curve is drawn to this factor times the largest measured slip ...
CURVE_SLIP_MARGIN = 1.15
#: ... but never beyond this slip (the model holds for slip in [0, 1)).
CURVE_SLIP_END = 0.99


def slip_grid_end(slip) -> float:
    """Largest slip of a fitted curve's grid: a margin beyond the data, inside [0, 1)."""
    return min(max(float(np.max(slip)) * CURVE_SLIP_MARGIN, 0.05), CURVE_SLIP_END)


def plot_data(data: SlipData | DriveLog, path: str, title: str = "") -> str:
    """Save a figure of tractive force-slip data or of a drive log's four channels."""
    if isinstance(data, SlipData):
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        loads = data.normal_load if data.normal_load is not None else np.zeros(data.n_samples)
        sc, u = force_unit(data.values)
        if np.unique(loads).size <= MAX_LOAD_LEVELS:
            for W in np.unique(loads):
                sel = loads == W
                label = f"W = {W / sc:.4g} {u}" if W > 0 else "data"
                ax.plot(data.slip[sel], data.values[sel] / sc, "o", ms=4, label=label)
        else:
            sca = ax.scatter(
                data.slip,
                data.values / sc,
                c=loads / sc,
                cmap="viridis",
                s=24,
                edgecolors="k",
                linewidths=0.4,
                label="measured (colour: normal load)",
            )
            fig.colorbar(sca, ax=ax, label=f"normal load W ({u})")
        ax.set_xlabel("slip i (-)")
        ax.set_ylabel(f"{_QUANTITY[data.measured]} ({u})")
        ax.set_ylim(bottom=min(0.0, float(np.min(data.values)) / sc * 1.05))
        ax.set_xlim(left=0.0)
        ax.grid(alpha=0.3)
        ax.legend()
    else:
        fig, axs = plt.subplots(4 if data.vehicle_accel is not None else 3, 1, figsize=(7, 8), sharex=True)
        t = data.time
        torque = choose_scale(data.sprocket_torque, "N m")
        axs[0].plot(t, data.sprocket_torque * torque.factor, lw=0.8)
        axs[0].set_ylabel(f"sprocket torque ({torque.unit})")
        axs[1].plot(t, data.sprocket_speed, lw=0.8)
        axs[1].set_ylabel("sprocket speed (rad/s)")
        axs[2].plot(t, data.vehicle_speed, lw=0.8)
        axs[2].set_ylabel("vehicle speed (m/s)")
        if data.vehicle_accel is not None:
            axs[3].plot(t, data.vehicle_accel, lw=0.8)
            axs[3].set_ylabel("accel (m/s$^2$)")
        axs[-1].set_xlabel("time (s)")
        for ax in axs:
            ax.grid(alpha=0.3)
    if title:
        import textwrap

        fig.suptitle(textwrap.fill(title, 90), fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path)


def force_unit(values) -> tuple[float, str]:
    """``(divisor, unit)`` for forces of this magnitude (:func:`soilmodel.choose_scale`, as the reports)."""
    scale = choose_scale(values, "N")
    return 1.0 / scale.factor, scale.unit


def _curve_band(grid, result, vehicle, W: float) -> np.ndarray | None:
    """Half-width of the 95 % band of the fitted curve at load ``W`` (delta method on F_max and K).

    F = F_max g(i l / K); the sensitivities come from the soilmodel's AD Function (dF/dphi =
    W sec^2(phi) g gives g, dF/dK the K column); F_max's and K's standard errors and their
    correlation come from the result. ``None`` when the result has no interval for them.
    """
    from .soilmodel import Soil, tractive_force_sensitivities

    cbs = {cb.name: cb for cb in result.combinations}
    fm = cbs.get(f"F_max@W={W:.6g}N")  # the name as the result writes it (6 significant digits)
    kk = cbs.get("K")
    corr = (result.identifiability.get("fmax_K_correlation") or {}).get(f"{W:.6g}")
    q = result.quantile
    if fm is None or kk is None or fm.stderr is None or kk.stderr is None or corr is None or q is None:
        return None
    th = result.theta  # [c, phi, K]
    sens = tractive_force_sensitivities(
        grid, Soil(float(th[0]), float(th[1]), float(th[2])), vehicle, result.model, normal_load=W
    )
    g = sens[:, 1] / (W / np.cos(result.theta[1]) ** 2)
    dK = sens[:, 2]
    var = (g * fm.stderr) ** 2 + (dK * kk.stderr) ** 2 + 2 * g * dK * corr * fm.stderr * kk.stderr
    return q * np.sqrt(np.maximum(var, 0.0))


def _status_title(result) -> tuple[str, str]:
    """The figure's title and its colour: the fit's outcome in the report's words."""
    if result.success:
        return f"{result.model} model, {result.method}: {result.outcome}", "k"
    if result.outcome == "not_usable":
        return (
            f"ANSWER NOT USABLE ({result.model} model, {result.method}: the plausibility checks refuse "
            "it; see the report)",
            "C3",
        )
    return f"FIT FAILED ({result.model} model, {result.method}: {result.solver_status}) - no estimate", "C3"


def plot_fit(data: SlipData | DriveLog, vehicle, result, path: str) -> str:
    """Save a figure of a fit: data, fitted curve with its 95 % band, and residuals.

    Slip data: the measurements per normal load, the fitted curve (through the fit result, so
    it is the same at every point of an unidentifiable c-phi ridge) and the residuals in N or
    kN. Drive log: the samples the fit used - thrust from the sprocket equation against the
    slip from the speeds, coloured by their weight in the fit (slow samples carry little slip
    information), thrust-binned weighted means of the slip - with the fitted curve and band,
    and the speed residuals over time. A failed fit is drawn as such: its last iterate dashed
    and labelled, never as "fitted".
    """
    from .soilmodel import Soil, tractive_force, tractive_force_with_effects

    title, tcol = _status_title(result)
    theta = np.asarray(result.theta, dtype=float)
    last = None  # the optimiser's last point, drawn only for a failed fit
    if (
        not result.success
        and np.all(np.isfinite(theta))
        and 0 < theta[1] < np.pi / 2
        and theta[2] > 0
        and theta[0] >= 0
    ):
        last = Soil(*theta)

    measured = getattr(data, "measured", "tractive_force")
    effects = bool(getattr(result, "effects", None))

    def curve(grid, W):
        if result.success:
            if isinstance(data, SlipData):  # what the rig reports (tractive force or drawbar pull, with effects)
                return result.predict(grid, normal_load=W)
            if effects:  # the soil's thrust with the fitted effects (normal load, shear law), from soilmodel
                return tractive_force_with_effects(
                    grid, result.ridge_point, vehicle, result.effect_set, result.model, normal_load=W
                )
            return tractive_force(grid, result, vehicle, normal_load=W)
        return tractive_force(grid, last, vehicle, result.model, normal_load=W)

    # a failed fit's last iterate is a soil only: draw it where the data are the soil's thrust
    drawable = result.success or (last is not None and measured == "tractive_force" and not effects)
    if isinstance(data, SlipData):
        fig, (ax, axr) = plt.subplots(
            2, 1, figsize=(6.6, 6.2), sharex=True, gridspec_kw={"height_ratios": [3, 1.3]}, layout="constrained"
        )
        axes = _sweep_panels(fig, ax, axr, data, vehicle, result, curve, drawable)
    else:
        fig, (ax, axr) = plt.subplots(2, 1, figsize=(7, 7.4), gridspec_kw={"height_ratios": [3, 1.4]})
        _drive_log_panels(fig, ax, axr, data, vehicle, result, curve if drawable else None)
        axes = (ax, axr)
    ax.set_title(title, fontsize=9, color=tcol)
    for a in axes:
        a.grid(alpha=0.3)
    fig.align_ylabels(list(axes))
    if fig.get_layout_engine() is None:
        fig.tight_layout()
    return save_figure(fig, path)


def _sweep_panels(fig, ax, axr, data: SlipData, vehicle, result, curve, drawable: bool) -> tuple:
    """A sweep's panels: the measurements per load, the fitted curves with their bands, the residuals."""
    effects = bool(getattr(result, "effects", None))
    measured = getattr(data, "measured", "tractive_force")
    loads = data.loads(vehicle.weight)
    sc, u = force_unit(data.values)
    grid = np.linspace(0.0, slip_grid_end(data.slip), 300)
    res = result.residuals_measured_minus_model
    levels, shown, curve_loads = _sweep_points(fig, ax, axr, data, loads, res, result.model)
    for col, W, sel in shown:
        ax.plot(data.slip[sel], data.values[sel] / sc, "o", color=col, ms=5, label=f"measured, W = {W / sc:.4g} {u}")
        if np.all(np.isfinite(res[sel])):
            axr.plot(data.slip[sel], res[sel] / sc, "o", color=col, ms=5)
    lows = [float(np.min(data.values)) / sc]
    try:
        if drawable:
            curve(grid[:2], curve_loads[0][1])
    except DataError:  # a resistance from each row's sinkage: the model exists at the rows only
        drawable = False
        at_rows = result.predict(data)
        ax.plot(data.slip, at_rows / sc, "x", color="k", ms=6, label="model at each row (its own sinkage)")
        lows.append(float(np.min(at_rows)) / sc)
    for k, (col, W, label) in enumerate(curve_loads):
        if not drawable:
            break
        F = curve(grid, W)
        lows.append(float(np.min(F)) / sc)
        if not result.success:
            ax.plot(grid, F / sc, "--", color="0.5", lw=1.0, label=_unusable_label(result) if k == 0 else None)
            continue
        extreme = levels.size > MAX_LOAD_LEVELS and k > 0
        ax.plot(grid, F / sc, ":" if extreme else "-", color=col, lw=1.0 if extreme else 1.4, label=label)
        band = None if effects or extreme else _curve_band(grid, result, vehicle, float(W))
        if band is not None:
            ax.fill_between(
                grid,
                (F - band) / sc,
                (F + band) / sc,
                color=col,
                alpha=0.18,
                lw=0,
                label=None if k else "95 % band of the fitted curve",
            )
    axr.axhline(0, color="k", lw=0.6)
    ax.set_ylabel(f"{_QUANTITY[measured]} ({u})")
    lo = min(0.0, *lows)
    ax.set_ylim(bottom=lo - 0.05 * abs(lo) if lo < 0 else 0.0)
    if lo < 0:
        ax.axhline(0, color="k", lw=0.6)
    ax.set_xlim(0.0, max(grid[-1], float(np.max(data.slip))) * 1.02)
    ax.legend(fontsize=8)
    axr.set_ylabel(f"{_residual_label(result)} ({u})")
    axr.set_xlabel("slip i (-)")
    axes = (ax, axr)
    return axes


def _sweep_points(fig, ax, axr, data: SlipData, loads, res, model: str) -> tuple:
    """The load levels, the points drawn per level, and the curves' loads: ``(levels, shown, curve_loads)``.

    Up to :data:`MAX_LOAD_LEVELS` levels: one colour each; more (a measured, varying load): points coloured by
    load (drawn here), curves at the median load and the extremes.
    """
    sc, u = force_unit(data.values)
    levels = np.unique(loads)
    curve_loads: list[tuple[Any, float, str | None]]  # colour, load, legend label
    if levels.size <= MAX_LOAD_LEVELS:
        shown = [(f"C{k}", W, sel) for k, (W, sel) in enumerate((W, loads == W) for W in levels)]
        curve_loads = [(f"C{k}", W, f"fitted ({model} model)") for k, W in enumerate(levels)]
    else:  # a measured, continuously varying load: colour by load, curves at its typical value and extremes
        norm = plt.Normalize(float(levels[0]) / sc, float(levels[-1]) / sc)
        cmap = plt.get_cmap("viridis")
        sca = ax.scatter(
            data.slip,
            data.values / sc,
            c=loads / sc,
            cmap=cmap,
            norm=norm,
            s=28,
            edgecolors="k",
            linewidths=0.4,
            zorder=3,
            label="measured (colour: normal load)",
        )
        axr.scatter(data.slip, res / sc, c=loads / sc, cmap=cmap, norm=norm, s=22, edgecolors="k", linewidths=0.4)
        fig.colorbar(sca, ax=[ax, axr], label=f"normal load W ({u})", pad=0.02)
        rep = float(loads[np.argsort(loads)[loads.size // 2]])  # the median row's measured load
        shown = []
        curve_loads = [
            (cmap(norm(rep / sc)), rep, f"fitted at the median load {rep / sc:.4g} {u}"),
            (
                cmap(norm(levels[0] / sc)),
                float(levels[0]),
                f"at the extremes {levels[0] / sc:.4g} and {levels[-1] / sc:.4g} {u}",
            ),
            (cmap(norm(levels[-1] / sc)), float(levels[-1]), None),
        ]
    return levels, shown, curve_loads


def _residual_label(result) -> str:
    """``measured - model`` (:data:`RESIDUAL_SIGN`); ``measured - last iterate`` for a failed fit."""
    if result.outcome == "failed":
        return RESIDUAL_SIGN.replace("model", "last iterate")
    return RESIDUAL_SIGN + (" (not usable)" if result.outcome == "not_usable" else "")


def _unusable_label(result) -> str:
    """The legend of a curve that is not an answer: a converged but refused fit, or a failed one's last iterate."""
    if result.outcome == "not_usable":
        return "the fit's curve: answer NOT USABLE (see the report)"
    return "last iterate of the FAILED fit"


def _effect_corrected(prep, vehicle, result) -> tuple[np.ndarray, np.ndarray, str]:
    """The samples' thrust and slip with the fitted drivetrain loss and track radius, and a label.

    ``T = (M - loss(w) - I dw/dt) / r_eff`` and ``i = 1 - v / (r_eff w)``, from soilmodel's
    :func:`~.soilmodel.effect_terms.torque_loss` and
    :func:`~.soilmodel.effect_terms.effective_radius` (the nominal sprocket thrust and slip when neither
    effect was fitted): the points then lie where the fitted model puts the soil's thrust.
    """
    import casadi as ca

    from .soilmodel.effects import effective_radius, torque_loss

    es = result.effect_set
    names = set(getattr(es, "names", ()) or ())
    used = sorted(names & {"drivetrain_friction", "radius_error"})
    if not used:
        return prep.thrust, prep.slip_measured, "sprocket thrust vs slip from speeds"
    r, r_eff = vehicle.sprocket_radius, float(effective_radius(vehicle, es))
    w = ca.SX.sym("w")
    loss_fn = ca.Function("torque_loss", [w], [torque_loss(w, vehicle, es)]).map(prep.sprocket_speed.size)
    loss = np.asarray(loss_fn(prep.sprocket_speed.reshape(1, -1)), dtype=float).ravel()
    thrust = (r * prep.thrust - loss) / r_eff
    slip = 1.0 - prep.vehicle_speed / (r_eff * prep.sprocket_speed)
    return thrust, slip, f"thrust vs slip with the fitted {' and '.join(used)}"


def _drive_log_panels(fig, ax, axr, data: DriveLog, vehicle, result, curve) -> None:
    """The two panels of a drive-log fit (see :func:`plot_fit`)."""
    from .identify.drivelog.fit import prepare_drive_log

    rel = (getattr(result, "extra", None) or {}).get("relaxation_at")  # the fit's own thrust rows
    prep = prepare_drive_log(data, vehicle, relaxation_at=None if rel is None else tuple(rel))
    r_s = vehicle.sprocket_radius
    rw = r_s * prep.sprocket_speed
    effects = bool(getattr(result, "effects", None)) and result.success
    thrust, slip, what = (
        _effect_corrected(prep, vehicle, result)
        if effects
        else (prep.thrust, prep.slip_measured, "sprocket thrust vs slip from speeds")
    )
    weight = (rw / prep.sigma_speed) ** 2  # slip information of a sample: 1 / sigma_i^2
    sc, u = force_unit(thrust)
    order = np.argsort(weight)  # heavy samples drawn last, on top
    wrel = weight / float(np.max(weight))
    pts = ax.scatter(
        np.clip(slip[order], -1, 1),
        thrust[order] / sc,
        c=np.log10(np.maximum(wrel[order], 1e-4)),
        s=5,
        cmap="viridis",
        vmin=-4,
        vmax=0,
        alpha=0.6,
        lw=0,
        label=f"{slip.size} samples used: {what}",
    )
    cb = fig.colorbar(pts, ax=ax, pad=0.01)
    cb.set_label("weight in the fit (log10, relative)", fontsize=8)
    # thrust bins (the thrust is the precise variable): weighted mean slip of each, with its standard error
    edges = np.linspace(float(np.min(thrust)), float(np.max(thrust)), 13)
    idx = np.clip(np.searchsorted(edges, thrust, side="right") - 1, 0, edges.size - 2)
    bx_l: list[float] = []
    by_l: list[float] = []
    be_l: list[float] = []
    for b in range(edges.size - 1):
        sel = idx == b
        if sel.sum() < 3:
            continue
        w = weight[sel]
        bx_l.append(float(np.sum(w * slip[sel]) / np.sum(w)))
        be_l.append(float(np.sqrt(1.0 / np.sum(w))))  # standard error of the weighted mean
        by_l.append(float(np.mean(thrust[sel])))
    bx, by, be = np.array(bx_l), np.array(by_l), np.array(be_l)
    ax.errorbar(
        bx,
        by / sc,
        xerr=1.96 * be,
        fmt="s",
        color="k",
        ms=4,
        capsize=2,
        lw=1,
        label="weighted mean slip per thrust bin (95 %)",
    )
    # the axis shows every sample that pulls hard (they fix F_max) and the bulk of the rest
    strong = slip[thrust > 0.25 * float(np.max(thrust))]
    i_hi = min(
        0.99,
        1.05
        * max(
            0.05,
            float(np.quantile(slip, 0.99)),
            float(np.max(strong)) if strong.size else 0.0,
            float(np.max(bx + 2 * be)) if bx.size else 0.0,
        ),
    )
    i_lo = max(-0.3, min(-0.02, float(np.quantile(slip, 0.01))))
    if curve is not None:
        grid = np.linspace(0, i_hi, 300)
        W = float(result.normal_loads[0]) if len(result.normal_loads) else vehicle.weight
        F = curve(grid, W)
        if result.success:
            ax.plot(grid, F / sc, "C3-", lw=1.6, label="fitted F(i)" + (" with the fitted effects" if effects else ""))
            band = None if effects else _curve_band(grid, result, vehicle, W)
            if band is not None:
                ax.fill_between(
                    grid,
                    (F - band) / sc,
                    (F + band) / sc,
                    color="C3",
                    alpha=0.2,
                    lw=0,
                    label="95 % band of the fitted curve",
                )
        else:
            ax.plot(grid, F / sc, "--", color="0.5", lw=1.2, label=_unusable_label(result))
    outside = int(np.sum((slip < i_lo) | (slip > i_hi)))
    ax.set_xlim(i_lo, i_hi)
    ax.set_ylim(min(0.0, float(np.min(thrust)) / sc), float(np.max(thrust)) / sc * 1.08)
    ax.set_xlabel("slip i (-)" + (f"; {outside} low-weight samples beyond the axis" if outside else ""))
    ax.set_ylabel(f"thrust ({u})")
    ax.legend(fontsize=7, loc="lower right")
    x = result.extra if isinstance(result.extra, dict) else {}
    if x.get("regime"):
        ax.text(0.01, 0.98, f"regime: {x['regime']}", transform=ax.transAxes, va="top", fontsize=8)
    res = result.residuals_measured_minus_model
    t_used = data.time[prep.keep] if prep.keep.sum() == res.size else np.arange(res.size)
    axr.plot(t_used, res, ".", ms=2)
    axr.axhline(0, color="k", lw=0.6)
    axr.set_xlabel("time (s)" if prep.keep.sum() == res.size else "sample used in the fit")
    axr.set_ylabel(f"{_residual_label(result)} ({result.residual_unit})")
