"""Figure of a rigid-wheel fit: drawbar pull against slip (coloured by load) and the sinkage channel."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_wheel_fit", "CURVE_POINTS"]

#: Points of the model curve.
CURVE_POINTS = 60
#: Smallest sinkage of the model curve, m (the trend line may cross zero when extrapolated).
MIN_CURVE_SINKAGE_M = 1e-4


def _curve_inputs(data) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, str]:
    """Slip grid of the model curve and the load and sinkage along it: the data's per-slip-level means,
    joined piecewise linearly (held beyond the end levels).

    The rows' model values use each row's load and measured sinkage, and the drawbar pull of a rigid wheel
    is steep in both: a curve at one median load with a straight-line sinkage trend strayed far from them
    (CMU trials: 17-26 mm of sinkage, 21.6-26.1 N of load). Along the level means it passes through the
    middle of each level's model points.
    """
    from .identify.wheel.result import slip_levels

    s = np.asarray(data.slip, dtype=float)
    lv = slip_levels(s)  # the rows of one condition (repeats) share a level
    groups = np.unique(lv)
    levels = np.array([s[lv == g].mean() for g in groups])
    W = np.asarray(data.normal_load, dtype=float)
    Wl = np.array([W[lv == g].mean() for g in groups])
    # the grid holds the levels themselves: the curve passes through each level's mean load and sinkage
    i = np.union1d(np.linspace(levels[0], levels[-1], CURVE_POINTS), levels) if levels.size > 1 else levels.copy()
    Wc = np.interp(i, levels, Wl)
    if data.has_sinkage:
        z_all = np.asarray(data.sinkage, dtype=float)
        zl = np.array([z_all[lv == g].mean() for g in groups])
        z = np.clip(np.interp(i, levels, zl), MIN_CURVE_SINKAGE_M, None)
        return i, Wc, z, f"the mean load and sinkage\nof each of the {levels.size} slip levels"
    return i, Wc, None, f"the mean load of each of the\n{levels.size} slip levels (sinkage from the load)"


def plot_wheel_fit(data, result, path: str) -> str:
    """Save the figure of ``result`` (a wheel fit) on ``data`` (a wheel sweep) to ``path``; returns the path.

    Left: measured drawbar pull (colour: normal load, with a colour bar), the model's value for
    each row (open circles) and its curve along the data's mean load and sinkage per slip level
    (:func:`_curve_inputs`; without sinkage, solved from the load). Right (sinkage measured): the
    measured sinkage against the one at which the fitted stresses carry each row's load.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .soilmodel.wheel_sweep import WheelSweep

    two = data.has_sinkage
    fig, axes = plt.subplots(1, 2 if two else 1, figsize=(11 if two else 6.5, 4.5), squeeze=False)
    ax = axes[0, 0]
    W = data.normal_load
    sc = ax.scatter(data.slip, data.drawbar_pull, c=W, cmap="viridis", s=30, zorder=3, label="measured")
    fig.colorbar(sc, ax=ax, label="normal load (N)")
    pred = result.predict(data)
    ax.scatter(data.slip, pred, facecolors="none", edgecolors="k", s=45, zorder=4, label="model at each row")
    i, Wc, z, how = _curve_inputs(data)
    curve = WheelSweep(slip=i, drawbar_pull=np.zeros_like(i), normal_load=Wc, sinkage=z)
    ax.plot(i, result.predict(curve), "k-", lw=1.2, label=f"model along {how}")
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.set_xlabel("slip i")
    ax.set_ylabel("drawbar pull (N)")
    status = "converged" if result.success else "FAILED"
    ax.set_title(f"rigid wheel fit ({status}), rmse {result.rmse_drawbar_pull:.3g} N", fontsize=10)
    ax.legend(fontsize=8, loc="best")
    if two:
        ax2 = axes[0, 1]
        ax2.scatter(data.slip, 1e3 * data.sinkage, c="C0", s=30, label="measured sinkage")
        ax2.scatter(
            data.slip,
            1e3 * result.predict_sinkage(data),
            facecolors="none",
            edgecolors="C3",
            s=45,
            label="sinkage at which the fitted stresses\ncarry the measured load",
        )
        ax2.set_xlabel("slip i")
        ax2.set_ylabel("sinkage (mm)")
        ax2.set_title(f"sinkage channel, rmse {1e3 * result.rmse_sinkage:.3g} mm", fontsize=10)
        ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
