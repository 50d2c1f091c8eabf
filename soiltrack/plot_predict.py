"""The figure of ``soiltrack predict --plot``: the four outputs against slip with their 95 % bounds."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_prediction"]

_PANELS = (
    ("drawbar_pull", "drawbar pull", "N", 1.0),
    ("thrust", "thrust", "N", 1.0),
    ("torque", "torque", "N m", 1.0),
    ("sinkage", "sinkage", "mm", 1e3),
)


def plot_prediction(pred, path: str) -> str:
    """Draw ``pred`` (a :class:`~soiltrack.planning.prediction.Prediction`) to ``path``; returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(9, 6.5), sharex=True)
    for ax, (key, label, unit, scale) in zip(axes.ravel(), _PANELS):
        y = np.asarray(pred.values[key]) * scale
        lo, hi = np.asarray(pred.lower[key]) * scale, np.asarray(pred.upper[key]) * scale
        ax.plot(pred.slip, y, color="C0", lw=2, label="prediction")
        if np.isfinite(lo).any():
            ax.fill_between(pred.slip, lo, hi, color="C0", alpha=0.25, lw=0, label="95 % from the soil")
        ax.set_ylabel(f"{label} ({unit})")
        ax.grid(alpha=0.3)
        if key == "drawbar_pull":
            ax.axhline(0.0, color="k", lw=0.8)
            ax.legend(loc="best", fontsize=8)
    for ax in axes[1]:
        ax.set_xlabel("slip")
    gear = "rigid wheel" if pred.to_dict()["running_gear"] == "rigid_wheel" else "tracked vehicle"
    fig.suptitle(f"{gear} at {pred.load:.4g} N on {', '.join(pred.estimate.sources)}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
