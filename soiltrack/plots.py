"""Figures for the command-line tool and the examples (matplotlib, Agg backend, PNG)."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .soilmodel import DataError, DriveLog, SlipData  # noqa: E402


def save_figure(fig, path: str) -> str:
    """Save ``fig`` to ``path`` (format from the extension) and close it; OSError -> DataError."""
    try:
        fig.savefig(path, dpi=120)
    except OSError as e:
        raise DataError(f"cannot write the figure: {e.strerror or e}", file=path) from None
    finally:
        plt.close(fig)
    return path


def plot_data(data: SlipData | DriveLog, path: str, title: str = "") -> str:
    """Save a figure of tractive force-slip data or of a drive log's four channels."""
    if isinstance(data, SlipData):
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        loads = data.normal_load if data.normal_load is not None else np.zeros(data.n_samples)
        for W in np.unique(loads):
            sel = loads == W
            label = f"W = {W / 1e3:.4g} kN" if W > 0 else "data"
            ax.plot(data.slip[sel], data.tractive_force[sel] / 1e3, "o", ms=4, label=label)
        ax.set_xlabel("slip i (-)")
        ax.set_ylabel("tractive force F (kN)")
        ax.set_ylim(bottom=min(0.0, float(np.min(data.tractive_force)) / 1e3 * 1.05))
        ax.set_xlim(left=0.0)
        ax.grid(alpha=0.3)
        ax.legend()
    else:
        fig, axs = plt.subplots(4 if data.vehicle_accel is not None else 3, 1, figsize=(7, 8), sharex=True)
        t = data.time
        big = float(np.max(np.abs(data.sprocket_torque))) >= 1e3
        axs[0].plot(t, data.sprocket_torque / (1e3 if big else 1.0), lw=0.8)
        axs[0].set_ylabel("sprocket torque (kN m)" if big else "sprocket torque (N m)")
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


def plot_fit(data: SlipData | DriveLog, vehicle, result, path: str) -> str:
    """Save a figure of a fit: data, fitted curve and residuals (slip data), or residuals (drive log).

    The fitted curve is drawn from the optimiser's point ``result.theta``; on a c-phi ridge every
    point gives the same curve, so the curve is meaningful even where c and phi are not.
    """
    from .soilmodel import Soil, tractive_force

    status = f"{result.model}, {result.method}: {result.status}" + ("" if result.success else " (FAILED)")
    theta = np.asarray(result.theta, dtype=float)
    soil = None
    if np.all(np.isfinite(theta)) and 0 < theta[1] < np.pi / 2 and theta[2] > 0 and theta[0] >= 0:
        soil = Soil(*theta)
    if isinstance(data, SlipData):
        fig, (ax, axr) = plt.subplots(2, 1, figsize=(6.4, 6.0), sharex=True, gridspec_kw={"height_ratios": [3, 1.3]})
        loads = data.loads(vehicle.weight)
        imax = max(float(np.max(data.slip)) * 1.15, 0.05)
        grid = np.linspace(0, imax, 300)
        for k, W in enumerate(np.unique(loads)):
            sel = loads == W
            col = f"C{k}"
            ax.plot(data.slip[sel], data.tractive_force[sel] / 1e3, "o", color=col, ms=5,
                    label=f"measured, W = {W / 1e3:.4g} kN")
            if soil is not None:
                ax.plot(grid, tractive_force(grid, soil, vehicle, result.model, normal_load=W) / 1e3, "-",
                        color=col, lw=1.2, label=f"fitted ({result.model})")
            rel = 100 * result.residuals[sel] / np.where(data.tractive_force[sel] != 0, data.tractive_force[sel], 1)
            axr.plot(data.slip[sel], rel, "o", color=col, ms=5)
        axr.axhline(0, color="k", lw=0.6)
        ax.set_ylabel("tractive force F (kN)")
        ax.legend(fontsize=8)
        ax.set_title(status, fontsize=9)
        axr.set_ylabel("model - data (%)")
        axr.set_xlabel("slip i (-)")
        for a in (ax, axr):
            a.grid(alpha=0.3)
    else:
        fig, (ax, axr) = plt.subplots(2, 1, figsize=(7, 7))
        # thrust from the sprocket equation against the slip computed from the speeds (noisy: shown
        # for orientation only - the fit never uses this slip as a regressor)
        r_s, inertia = vehicle.sprocket_radius, vehicle.sprocket_inertia
        thrust = (data.sprocket_torque[:-1] - inertia * np.diff(data.sprocket_speed) / np.diff(data.time)) / r_s
        rw = r_s * data.sprocket_speed[1:]
        ok = rw > 0.15 * max(float(np.max(rw)), 1e-9)
        slip = 1 - data.vehicle_speed[1:][ok] / rw[ok]
        i_hi = min(1.0, max(0.3, float(np.quantile(slip, 0.99)) if slip.size else 0.3))
        ax.plot(slip, thrust[ok], ".", ms=2, alpha=0.4, color="0.4", label="sprocket thrust vs slip from speeds")
        if soil is not None:
            grid = np.linspace(0, i_hi, 300)
            ax.plot(grid, tractive_force(grid, soil, vehicle, result.model), "C3-", lw=1.6, label="fitted F(i)")
        ax.set_xlim(-0.1, i_hi)
        ax.set_xlabel("slip i (-)")
        ax.set_ylabel("thrust (N)")
        regime = result.extra.get("regime") if isinstance(result.extra, dict) else None
        ax.set_title(status + (f" - regime: {regime}" if regime else ""), fontsize=9)
        ax.legend(fontsize=8)
        res = np.asarray(result.residuals, dtype=float)
        axr.plot(np.arange(res.size), res, ".", ms=2)
        axr.axhline(0, color="k", lw=0.6)
        axr.set_xlabel("sample used in the fit")
        axr.set_ylabel(f"model - data ({result.residual_unit})")
        for a in (ax, axr):
            a.grid(alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path)
