"""Figure of an on-line estimate over time (``soiltrack track --plot``)."""

from __future__ import annotations

import numpy as np

from .plots import plt, save_figure

#: Two-sided 95 % normal quantile of the bands.
Z95 = 1.959963984540054


def _series(history, name: str) -> np.ndarray:
    return np.array([np.nan if getattr(e, name) is None else float(getattr(e, name)) for e in history])


def plot_track(history, path: str, title: str = "on-line estimate") -> str:
    """F_max and K with their 95 % bands over time, detected changes and their windows, samples used.

    Saved to ``path``; the held estimate between excitations is drawn dotted.

    ``history`` is the :class:`~soiltrack.identify.OnlineEstimate` of every update. Where a
    quantity is not identifiable its estimate is drawn thin and grey (the value the horizon's
    fit holds, not a determined one).
    """
    t = _series(history, "time_s")
    F, sF = _series(history, "max_thrust_N"), _series(history, "max_thrust_stderr_N")
    K, sK = _series(history, "shear_modulus_m"), _series(history, "shear_modulus_stderr_m")
    used = _series(history, "samples_used")
    skipped = _series(history, "samples_skipped")
    turning = _series(history, "samples_turning")
    changes = [(e.time_s, e.change_time_s) for e in history if e.change_detected]
    windows = [getattr(e, "change_window_s", None) for e in history if e.change_detected]
    held = np.array([bool(getattr(e, "held", False)) for e in history])
    fig, ax = plt.subplots(3, 1, figsize=(9, 8), sharex=True, gridspec_kw={"height_ratios": [3, 3, 2]})
    for a, y, s, scale, label in ((ax[0], F, sF, 1e-3, "F_max (kN)"), (ax[1], K, sK, 1e3, "K (mm)")):
        a.plot(t, y * scale, color="0.6", lw=0.8, label="estimate (not identifiable: grey)")
        ident = np.isfinite(s)
        a.plot(t, np.where(ident & ~held, y, np.nan) * scale, color="C0", lw=1.5, label="identified")
        if held.any():
            a.plot(t, np.where(ident & held, y, np.nan) * scale, color="C0", lw=1.5, ls=":", label="held")
        a.fill_between(
            t,
            (y - Z95 * s) * scale,
            (y + Z95 * s) * scale,
            where=ident,
            color="C0",
            alpha=0.25,
            label="95 % band",
        )
        a.set_ylabel(label)
        a.grid(alpha=0.3)
    ax[2].plot(t, used, color="C2", label="samples in the estimate")
    ax[2].plot(t, skipped, color="C3", label="skipped (missing channel), total")
    if np.nanmax(turning, initial=0) > 0:
        ax[2].plot(t, turning, color="C4", label="turning (left out), total")
    ax[2].set_ylabel("samples")
    ax[2].set_xlabel("time (s)")
    ax[2].grid(alpha=0.3)
    for a in ax:
        for j, (td, tc) in enumerate(changes):
            a.axvline(td, color="C1", lw=1.2, label="change detected" if j == 0 else None)
            a.axvline(tc, color="C1", lw=1.0, ls="--", label="change dated" if j == 0 else None)
            w = windows[j]
            if w is not None:
                a.axvspan(w[0], w[1], color="C1", alpha=0.12, label="change window" if j == 0 else None)
    for a in ax:
        a.legend(loc="best", fontsize=7)
    ax[0].set_title(title, fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path)
