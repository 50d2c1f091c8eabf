"""Figures for the command-line tool and the examples (matplotlib, Agg backend, PNG)."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .soilmodel import DriveLog, SlipData  # noqa: E402


def plot_data(data: SlipData | DriveLog, path: str, title: str = "") -> None:
    """Save a figure of tractive force-slip data or of a drive log's four channels."""
    if isinstance(data, SlipData):
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        loads = data.normal_load if data.normal_load is not None else np.zeros(data.n_samples)
        for W in np.unique(loads):
            sel = loads == W
            label = f"W = {W / 1e3:.4g} kN" if W > 0 else "measured"
            ax.plot(data.slip[sel], data.tractive_force[sel] / 1e3, "o", ms=4, label=label)
        ax.set_xlabel("slip i (-)")
        ax.set_ylabel("tractive force F (kN)")
        ax.grid(alpha=0.3)
        ax.legend()
    else:
        fig, axs = plt.subplots(4 if data.vehicle_accel is not None else 3, 1, figsize=(7, 8), sharex=True)
        t = data.time
        axs[0].plot(t, data.sprocket_torque / 1e3, lw=0.8)
        axs[0].set_ylabel("sprocket torque (kN m)")
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
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
