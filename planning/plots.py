"""Figures of the planning results (matplotlib, Agg backend)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..soilmodel import Vehicle, choose_scale, format_energy, format_force
from .forces import resistances, soil_thrust
from .margin import Margin, split_effects, resolve_terrain, terrain_soil_vector
from .profile import THRUST_RESERVE, SpeedPlan
from .slip_optimal import SlipOptimum
from ..soilmodel.figures import save_figure

__all__ = ["plot_margin", "plot_profile", "plot_slip_optimal"]


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_margin(terrain: Any, vehicle: Vehicle, m: Margin, path: str) -> None:
    """Thrust-slip curve at the margin's normal load against the drivetrain limit and the requirement."""
    plt = _plt()
    soil, unc, model = resolve_terrain(terrain, vehicle)
    res_eff, shear_all, _left = split_effects(unc, None)
    shear = shear_all or None  # a fitted shear law is the soil's thrust the margin used
    theta = terrain_soil_vector(soil, unc, m.normal_load_N)
    s = np.linspace(0.0, 0.6, 301)
    F = np.array([soil_thrust(theta, float(x), m.normal_load_N, vehicle, model, effects=shear)[0] for x in s])
    need = abs(m.required_N)  # braking (downhill): the skid thrust |F(-i)| = F(i) must carry |required|
    ks = choose_scale([F.max(), need, m.drivetrain_limit_N or 0.0], "N")
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(s * 100, F * ks.factor, label=f"soil thrust at N = {format_force(m.normal_load_N)}")
    if unc is not None:
        q = unc.sample(200, 1)
        th = unc.soils_at(q, m.normal_load_N)
        Fs = np.array(
            [[soil_thrust(t, float(x), m.normal_load_N, vehicle, model, effects=shear)[0] for x in s[::10]] for t in th]
        )
        lo, hi = np.percentile(Fs, [2.5, 97.5], axis=0)
        ax.fill_between(s[::10] * 100, lo * ks.factor, hi * ks.factor, alpha=0.3, label="95 % band of the fitted soil")
    brake = m.direction == "braking"
    ax.axhline(
        need * ks.factor,
        color="C3",
        label=(f"required braking {ks.format(need)} (downhill)" if brake else f"required {ks.format(need)}")
        + (" at the allowed slip" if "effects_N" in m.required else ""),
    )
    if res_eff and "effects_N" in m.required:
        # a fitted slip-dependent resistance: the requirement at each slip (the margin takes it at the allowed slip)
        base = m.required_N - m.required["effects_N"]
        th_r = np.array([math.radians(m.grade_deg)])
        R_s = [
            base
            + float(
                resistances(vehicle, None, th_r, 0.0, 0.0, effects=res_eff, slip=float(x), speed=m.speed_m_s or 0.0)[1][
                    "effects_N"
                ][0]
            )
            for x in s[::10]
        ]
        ax.plot(
            s[::10] * 100,
            np.abs(R_s) * ks.factor,
            color="C3",
            ls="--",
            lw=1,
            label="required with the fitted effects, by slip",
        )
    if m.drivetrain_limit_N is not None:
        ax.axhline(
            m.drivetrain_limit_N * ks.factor,
            color="C2",
            ls="--",
            label=f"drivetrain limit {ks.format(m.drivetrain_limit_N)}",
        )
    ax.axvline(m.max_slip * 100, color="k", ls=":", label=f"allowed slip {m.max_slip * 100:.3g} %")
    ax.set_xlabel("skid |i| (%); the braking thrust is F(i) = -F(|i|)" if brake else "slip (%)")
    ax.set_ylabel(f"{'braking ' if brake else ''}thrust ({ks.unit})")
    go = "traversable" if m.traversable else "NOT traversable"
    ax.set_title(f"{m.terrain}, grade {m.grade_deg:g} deg: {go}, margin {ks.format(m.margin_N)}", fontsize=9)
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def plot_profile(result: SpeedPlan, path: str, title: str = "") -> None:
    """Speed, slip, torque and traction reserve of a planned profile against distance.

    The speed limit (when given) and the standstill windows are marked.
    """
    plt = _plt()
    s = result.series
    fig, axs = plt.subplots(4, 1, figsize=(7, 8), sharex=True)
    x = np.asarray(s["distance_m"])
    axs[0].plot(x, s["speed_m_s"], "-o", ms=2)
    vmax = result.limits.get("max_speed_m_s")
    if vmax is not None:
        axs[0].axhline(vmax, color="k", ls=":", label=f"speed limit {vmax:.3g} m/s")
        axs[0].legend(fontsize=8, loc="lower right")
    axs[0].set_ylabel("speed (m/s)")
    axs[1].plot(x, np.asarray(s["slip"]) * 100, "-o", ms=2)
    lim = result.limits["max_slip"] * 100
    for sgn in (1, -1):
        axs[1].axhline(sgn * lim, color="k", ls=":")
    axs[1].set_ylabel("slip (%)")
    M = np.asarray(s["sprocket_torque_Nm"])
    ts = choose_scale([np.abs(M).max(), result.limits["max_torque_Nm"]], "N m")
    axs[2].step(x, M * ts.factor, where="post")
    for sgn in (1, -1):
        axs[2].axhline(
            sgn * result.limits["max_torque_Nm"] * ts.factor,
            color="k",
            ls=":",
            label=f"torque limit +-{ts.format(result.limits['max_torque_Nm'])}" if sgn > 0 else None,
        )
    P = result.limits.get("max_power_W")
    if P and (result.active_limits or {}).get("power"):
        # the plan's power limit M w <= (1 - reserve) P_max as a torque bound, drawn where it is near the torque
        # limit; driving only (braking power is not bounded by the plan)
        w = np.abs(np.asarray(s["sprocket_speed_rad_s"], dtype=float))
        Pp = P * (1.0 - THRUST_RESERVE)
        Mp = np.where(w > 0, Pp / np.maximum(w, 1e-12), np.inf)
        Mp = np.where(Mp <= 1.5 * result.limits["max_torque_Nm"], Mp, np.nan)
        n_act = (result.active_limits or {})["power"]
        axs[2].plot(
            x,
            Mp * ts.factor,
            color="C3",
            ls="--",
            lw=1,
            label=f"power limit {(1 - THRUST_RESERVE) * 100:.3g} % of {P:.4g} W / w (active in {n_act} intervals)",
        )
    axs[2].legend(fontsize=7, loc="best")
    axs[2].set_ylabel(f"sprocket torque ({ts.unit})")
    R = np.asarray(s["margin_N"])
    fs = choose_scale(R, "N")
    axs[3].plot(x, R * fs.factor)
    axs[3].set_ylabel(f"traction reserve ({fs.unit})")
    axs[3].set_xlabel("distance (m)")
    if "patch" in s and len(set(s["patch"])) > 1:
        p = np.asarray(s["patch"])
        starts = np.concatenate([[0], np.nonzero(np.diff(p) != 0)[0] + 1])
        for k in starts:
            if k > 0:
                for ax in axs:
                    ax.axvline(x[k], color="0.6", lw=0.8)
            info = result.patches[int(p[k])] if int(p[k]) < len(result.patches) else {}
            g = info.get("grade_deg")
            axs[1].annotate(  # in the slip panel, below its limit line: the speed panel's curve runs at the top
                f"patch {int(p[k])}" + ("" if g is None else f", {g:g} deg"),
                (x[k], 0.9),
                xycoords=("data", "axes fraction"),
                xytext=(3, -3),
                textcoords="offset points",
                va="top",
                fontsize=7,
                color="0.35",
            )
    for w in result.standstills:  # a standstill is one point in distance: mark it with its time window
        axs[0].annotate(
            f"stands still {w['start_s']:.3g}-{w['end_s']:.3g} s",
            (w["distance_m"], 0.0),
            xytext=(5, 12),
            textcoords="offset points",
            fontsize=8,
            color="C3",
            arrowprops={"arrowstyle": "->", "color": "C3"},
        )
    for ax in axs:
        ax.grid(alpha=0.3)
    axs[0].set_title(
        title
        or f"{result.objective}-optimal profile: {result.total_time_s:.4g} s, "
        f"{format_energy(result.energy_J)}, peak speed {result.peak_speed_m_s:.3g} m/s",
        fontsize=9,
    )
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def plot_slip_optimal(opt: SlipOptimum, path: str, title: str = "") -> None:
    """Drawbar power and tractive efficiency against slip, the optima marked, with fit bands."""
    plt = _plt()
    fig, a1 = plt.subplots(figsize=(7, 4.5))
    s = opt.slip * 100
    ps = choose_scale(opt.drawbar_power_W, "W")
    a1.plot(s, opt.drawbar_power_W * ps.factor, color="C0", label="drawbar power")
    a2 = a1.twinx()
    a2.plot(s, opt.efficiency * 100, color="C1", label="tractive efficiency")
    if opt.bands:
        lo, hi = opt.bands["drawbar_power_W"]
        a1.fill_between(s, np.asarray(lo) * ps.factor, np.asarray(hi) * ps.factor, color="C0", alpha=0.25)
        lo, hi = opt.bands["efficiency"]
        a2.fill_between(s, np.asarray(lo) * 100, np.asarray(hi) * 100, color="C1", alpha=0.25)
    sp, se = opt.slip_max_power, opt.slip_max_efficiency  # both None together (no positive drawbar pull)
    if sp is not None and se is not None:
        a1.axvline(sp * 100, color="C0", ls=":")
        a2.axvline(se * 100, color="C1", ls=":")
    a1.set_xlabel("slip (%)")
    a1.set_ylabel(f"drawbar power ({ps.unit})", color="C0")
    a2.set_ylabel("tractive efficiency (%)", color="C1")
    a1.set_xlim(0, 40)
    a1.set_ylim(bottom=0)
    a2.set_ylim(0, 100)
    a1.grid(alpha=0.3)
    a1.set_title(
        title
        or (
            f"power-optimal slip {sp * 100:.3g} %, efficiency-optimal {se * 100:.3g} %"
            if sp is not None and se is not None
            else "no positive drawbar pull"
        ),
        fontsize=9,
    )
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
