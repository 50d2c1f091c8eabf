"""Figure of a segment map: the soil's thrust limit and shear modulus along the run, with their intervals."""

from __future__ import annotations

import os

__all__ = ["plot_segments"]


def plot_segments(smap, path: str) -> str:
    """Draw ``F_max`` and ``K`` per segment (value and 95 % interval) against the log's time; returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_f, ax_k) = plt.subplots(2, 1, sharex=True, figsize=(9, 5.5), constrained_layout=True)
    for s in smap.segments:
        x = (s.start_s, s.end_s)
        usable = s.reason is None and s.max_thrust_N is not None
        if not usable:
            for ax in (ax_f, ax_k):
                ax.axvspan(*x, color="0.85", lw=0)
            # a usable fit whose F_max is not determined (gentle driving) is labelled so, not just "usable"
            label = s.outcome if s.outcome != "usable" or not s.not_identified else "F_max, K\nnot identified"
            ax_f.text(0.5 * sum(x), 0.02, label, transform=ax_f.get_xaxis_transform(), ha="center", fontsize=7)
            continue
        for ax, val, ci, scale in (
            (ax_f, s.max_thrust_N, s.max_thrust_ci95, 1.0),
            (ax_k, s.shear_modulus_m, s.shear_modulus_ci95, 1e3),
        ):
            if val is None:
                continue
            if ci is not None:
                ax.fill_between(x, ci[0] * scale, ci[1] * scale, color="tab:blue", alpha=0.25, lw=0)
            ax.plot(x, (val * scale, val * scale), color="tab:blue", lw=2)
    for c in smap.cuts:
        for ax in (ax_f, ax_k):
            ax.axvline(c, color="0.6", lw=0.6, ls=":")
    ax_f.set_ylabel("F_max, N")
    ax_k.set_ylabel("K, mm")
    ax_k.set_xlabel("time, s")
    n = len(smap.segments)
    ax_f.set_title(
        f"soil along the run: {n} segment{'s' if n != 1 else ''} ({smap.spec}; dotted: cuts before merging; "
        "band: 95 % interval)",
        fontsize=9,
    )
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return os.fspath(path)
