"""The figure of a :class:`~.result.Diagnosis` (matplotlib, Agg)."""

from __future__ import annotations

from typing import Any

import numpy as np
from ...soilmodel.figures import save_figure

__all__ = ["plot_diagnosis"]


def plot_diagnosis(diag: Any, path: str) -> str:
    """Save a figure of the diagnosis to ``path`` (PNG) and return the path.

    Top: held-out residuals of the main channel against time (log) or slip (sweep), nominal
    model and with the verdict's effect, with the +-2 noise-floor band and the change window.
    Bottom left: the weights of the one comparison. Bottom right: the largest localisation shares.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cv = diag.curves
    if not cv or not cv.get("before"):  # nothing was held out (too few samples, or no nominal fit)
        fig, ax = plt.subplots(figsize=(8, 3))
        ax.axis("off")
        ax.text(
            0.02,
            0.5,
            f"verdict: {diag.verdict} (confidence {diag.confidence:.2f})\n\n"
            + "\n".join(diag.reason[i : i + 100] for i in range(0, len(diag.reason), 100)),
            va="center",
            fontsize=9,
            family="monospace",
        )
        save_figure(fig, path, dpi=110)
        return path
    chans = list(cv["before"])
    fig = plt.figure(figsize=(11, 7.5))
    gs = fig.add_gridspec(2, 2, height_ratios=[1.2, 1.0])
    ax = fig.add_subplot(gs[0, :])
    main = max(chans, key=lambda ch: float(np.mean((cv["before"][ch] / diag.noise[ch]) ** 2)))
    x = cv["held_x"][main]
    o = np.argsort(x, kind="stable")
    ax.plot(x[o], cv["before"][main][o], ".", ms=3, color="tab:red", alpha=0.6, label="nominal model")
    if cv.get("after") is not None:
        lab = diag.verdict if diag.verdict != "unexplained" else (diag.cause or "flexible discrepancy term")
        ax.plot(x[o], cv["after"][main][o], ".", ms=3, color="tab:blue", alpha=0.6, label=f"with {lab}")
    s = diag.noise[main]
    ax.axhspan(-2 * s, 2 * s, color="0.85", zorder=0, label="+-2 x noise floor")
    win = diag.cause_detail.get("window_s")
    if win is not None:
        ax.axvspan(
            win[0],
            win[1],
            color="tab:orange",
            alpha=0.15,
            label=f"terrain-change window {win[0]:.3g}-{win[1]:.3g} s",
        )
    ax.axhline(0, color="k", lw=0.6)
    ax.set_xlabel("time, s" if cv["x_label"] == "time" else "slip, -")
    ax.set_ylabel(f"held-out residual, {main}\n(measured - model)")
    ax.set_title(
        f"verdict: {diag.verdict} ({'' if diag.cause is None else f'cause {diag.cause}, '}"
        f"confidence {diag.confidence:.2f})"
        + ("" if diag.shrink is None else f", standardised held-out RMS shrinks by {diag.shrink:.0%}")
    )
    ax.legend(fontsize=8, loc="best")
    ax2 = fig.add_subplot(gs[1, 0])
    names = [e.effect for e in diag.ranking]
    ax2.barh(range(len(names)), [e.weight for e in diag.ranking], color="tab:green")
    ax2.set_yticks(range(len(names)), names, fontsize=8)
    ax2.invert_yaxis()
    ax2.set_xlim(0, 1)
    ax2.set_xlabel(
        "weight (held-out evidence)" if diag.data_kind == "drive" else "weight (in-sample evidence, Akaike's penalty)"
    )
    ax3 = fig.add_subplot(gs[1, 1])
    segs = [sg for sg in diag.localisation if sg.dimension != "channel"][:8]
    # "lo to hi": a dash between signed numbers reads as a minus ("slip -0.387--0.0335")
    labels = [f"{sg.dimension} {sg.range[0]:.3g} to {sg.range[1]:.3g}\n{sg.channel}" for sg in segs]
    gap = diag.verdict != "none"  # no gap beyond the noise: no localisation is significant, whatever its share
    ax3.barh(
        range(len(segs)),
        [sg.share for sg in segs],
        color=["tab:red" if sg.significant and gap else "0.6" for sg in segs],
    )
    ax3.set_yticks(range(len(segs)), labels, fontsize=7)
    ax3.invert_yaxis()
    ax3.set_xlabel(
        "share of the misfit (red: significant)"
        if gap
        else "share of the misfit (verdict none: no gap beyond the noise)"
    )
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    return path
