"""Figure of ``soiltrack drive``: speed, slip, torque, believed against true F_max, and the patches, over distance."""

from __future__ import annotations

import numpy as np


def plot_drive(res, route, path: str) -> None:
    """Save the figure of a :class:`~soiltrack.planning.control.DriveResult` to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(4, 1, figsize=(9, 10), sharex=True)
    big = max(abs(x) for x in res.run.series["sprocket_torque_Nm"]) >= 1e3
    scale, tunit = (1e3, "kN m") if big else (1.0, "N m")
    fscale, funit = (1e3, "kN") if big else (1.0, "N")
    runs = [(res.controller, res.run, "C0", 1.6)] + [
        (n, r, c, 0.9)
        for (n, c) in (("true_soil", "C2"), ("pi", "C3"), (res.fixed_slip_best, "C4"))
        if (r := res.baselines.get(n)) is not None
    ]
    for name, run, col, lw in runs:
        S = run.series
        d = np.asarray(S["distance_m"])
        ax[0].plot(d, S["speed_m_s"], color=col, lw=lw, label=name)
        ax[1].plot(d, S["slip"], color=col, lw=lw)
        ax[2].plot(d, np.asarray(S["sprocket_torque_Nm"]) / scale, color=col, lw=lw)
    S = res.run.series
    d = np.asarray(S["distance_m"])
    ax[0].plot(d, S["target_speed_m_s"], "k--", lw=0.8, label=f"{res.controller}'s speed target")
    lim = route.max_slip or 0.2
    ax[1].axhline(lim, color="k", ls="--", lw=0.8, label=f"slip limit {lim:g}")
    bF = np.array([np.nan if x is None else x for x in S["belief_max_thrust_N"]], dtype=float)
    tF = np.array([np.nan if x is None else x for x in S["true_max_thrust_N"]], dtype=float)
    ax[3].plot(d, tF / fscale, "k", lw=1.4, label="true F_max")
    ax[3].plot(d, bF / fscale, "C0", lw=1.2, label=f"{res.controller}'s believed F_max")
    nom = res.baselines.get("nominal_soil")
    if nom is not None:
        nd = np.asarray(nom.series["distance_m"])
        nF = np.array([np.nan if x is None else x for x in nom.series["belief_max_thrust_N"]], dtype=float)
        ax[3].plot(nd, nF / fscale, "C1:", lw=1.2, label="planned (nominal) F_max")
    ends = np.cumsum([p.length_m for p in route.patches])
    for a in ax:
        for k, e in enumerate(ends):
            a.axvline(e, color="0.6", lw=0.6)
            if k % 2 == 0:
                a.axvspan(ends[k - 1] if k else 0.0, e, color="0.93", zorder=0)
    for k, p in enumerate(route.patches):
        x0 = ends[k - 1] if k else 0.0
        ax[0].text(
            x0 + 0.02 * p.length_m,
            1.0,
            f"{k}: {p.grade_deg:g} deg",
            transform=ax[0].get_xaxis_transform(),
            va="bottom",
            fontsize=7,
        )
    for e in res.run.events:
        if e["kind"] in ("stop", "slow"):
            ax[0].axvline(e["distance_m"], color="C3" if e["kind"] == "stop" else "C1", lw=1.0, ls=":")
    ax[0].set_ylabel("speed (m/s)")
    ax[1].set_ylabel("slip (-)")
    ax[2].set_ylabel(f"sprocket torque ({tunit})")
    ax[3].set_ylabel(f"thrust limit F_max ({funit})")
    ax[3].set_xlabel("distance (m)")
    ax[0].legend(fontsize=7, loc="lower right")
    ax[1].legend(fontsize=7, loc="upper right")
    ax[3].legend(fontsize=7, loc="lower right")
    m = res.run.metrics
    fig.suptitle(
        f"soiltrack drive: {res.controller}, {'arrived' if res.run.arrived else 'did not arrive'}, "
        f"stuck events {m['stuck_events']}, peak slip {m['peak_slip']:.3g}",
        fontsize=10,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
