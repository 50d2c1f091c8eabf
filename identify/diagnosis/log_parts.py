"""Drive-log parts of the diagnosis: a change of terrain in time, and a delay between channels.

Two things a drive log can show that no effect of the library explains; :mod:`.outside` makes
each a hypothesis of the comparison from these tools:

- :func:`terrain_window`: the time window in which the SOIL differs from the rest of the run
  (a softer patch). A change of soil does not shift the residual's mean: the thrust-slip curve
  moves, and where the vehicle pushes little (cruising, standing) the data cannot see it at all.
  The test is the score (Lagrange-multiplier) test of "the soil (thrust limit F_max and shear
  modulus K) differs inside the window": the per-sample scores ``g_k = J_k^T e_k`` of the nominal
  fit (:func:`~soiltrack.identify.drivelog.sensitivity.drive_log_sensitivities`) summed over the window, against
  their variance. The nominal fit sets the total score to zero, so the window's score is that of
  inside against outside (a bridge: ``V_in - V_in V_all^-1 V_in``). Every window of whole cells is
  tried (Bonferroni over the windows). The window with the largest statistic is where the
  evidence lies. Samples that carry no information about the soil (cruising, standing) can be
  inside or outside at no cost, so the boundaries are uncertain: every window whose statistic is
  within a 1 % chi-squared quantile (1 dof) of the best is as compatible with the data (windows
  inside the run preferred: a window that starts with the run is the same contrast as its
  complement, and a change in the middle of a run has the reference soil on both sides); the
  shortest of them is the evidence window (``evidence_start``, ``evidence_end``: where the data
  show the soil differs), and ``start``, ``end`` are the earliest start and the latest end among
  them (the bracket: the change lies inside it).
- :func:`delay_scan`: the speed channel's residuals regressed on the sprocket-speed change over
  ``k`` samples, ``w(t) - w(t - k)``, for ``k = -K..K``: a vehicle-speed sensor late by ``d``
  samples leaves ``r(t) ~ w(t) - w(t - d)`` (the encoder is not delayed and its noise is not the
  speed sensor's), so the lag with the largest t-statistic (Newey-West) estimates the delay.
  :func:`refine_delay` refits the nominal model on the log with the speed channel shifted.

Pure numpy on the fit's residuals and sensitivities; no physics here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .gap import long_run_factor
from ..estimates.distributions import chi2_isf, chi2_sf
from .screening import Screen, drive_log_score_pair, newey_west_lag, score_test

__all__ = [
    "TerrainWindow",
    "terrain_window",
    "delay_scan",
    "shift_speed",
    "refine_delay",
    "speed_scale_screen",
    "SPEED_CHANNEL",
]


@dataclass(frozen=True)
class TerrainWindow:
    """Where in time the soil differs from the rest of the run.

    Attributes
    ----------
    start, end
        The bracket (s): the earliest start and the latest end of the windows as compatible with
        the data as the best one (the change lies inside it).
    evidence_start, evidence_end
        The shortest window as compatible with the data as the best one (s): where the data show
        the soil differs; the boundaries of the change lie between these and ``start`` / ``end``.
    statistic, dof, p_value, significant
        Score statistic of "the soil differs inside the evidence window", its degrees of freedom,
        the p-value (Bonferroni over the windows tried) and ``p_value < alpha``.
    fmax_change, k_change
        Relative change of the thrust limit F_max and of K inside the window, linearised from the
        score (one Gauss-Newton step; negative: softer).
    channel
        ``"soil (F_max, K)"``: what the window is measured on.
    shift
        ``fmax_change`` (the number the generic report prints as the shift).
    """

    start: float
    end: float
    evidence_start: float
    evidence_end: float
    statistic: float
    dof: int
    p_value: float
    significant: bool
    fmax_change: float
    k_change: float
    channel: str = "soil (F_max, K)"

    @property
    def shift(self) -> float:
        return self.fmax_change


def _pinv_quads(S: np.ndarray, V: np.ndarray, atol: float = 1e-8) -> tuple[np.ndarray, np.ndarray]:
    """``S_j^T V_j^+ S_j`` and the rank of ``V_j`` for each of a stack of symmetric matrices ``V`` (``(w, p,
    p)``) and vectors ``S`` (``(w, p)``): eigenvalues below ``atol`` dropped; 0 and rank 0 where none is
    above it."""
    w, U = np.linalg.eigh(0.5 * (V + np.swapaxes(V, 1, 2)))
    keep = w > atol
    y = np.einsum("wpq,wp->wq", U, S)  # U^T S, one column per eigenvalue
    quad = np.where(keep, y**2 / np.where(keep, w, 1.0), 0.0).sum(axis=1)
    return quad, np.count_nonzero(keep, axis=1)


def terrain_window(
    residuals: np.ndarray,
    jacobian: np.ndarray,
    time_s: np.ndarray,
    scale=(1.0, 1.0),
    n_cells: int = 60,
    alpha: float = 0.01,
    min_info: float = 1e-3,
) -> TerrainWindow | None:
    """Find the time window in which the soil differs (see the module docstring).

    Parameters
    ----------
    residuals
        ``(n, c)`` whitened residuals of the nominal fit per used sample.
    jacobian
        ``(n, c, p)`` their profiled sensitivities; the first two columns are ``F_max`` and ``K``.
    time_s
        Time of each sample (s), increasing.
    scale
        ``(F_max, K)`` of the nominal fit: the changes are reported relative to them.
    n_cells
        The samples are pooled into this many consecutive cells; windows are whole cells.
    alpha
        Significance level (after the Bonferroni correction over the windows).
    min_info
        Directions of the soil in which the window or the rest of the run hold less than this share
        of the whole run's information are not tested (they cannot tell inside from outside).

    Returns
    -------
    TerrainWindow or None
        None with fewer than 24 samples or no information about the soil.
    """
    e = np.asarray(residuals, dtype=float)
    J = np.asarray(jacobian, dtype=float)[:, :, :2]
    t = np.asarray(time_s, dtype=float)
    if e.shape[0] < 24:
        return None
    cs = _cell_scores(e, J, n_cells)
    if cs is None:
        return None
    cells, G, I, infl = cs
    win = _window_statistics(G, I, infl, min_info)
    a_idx, b_idx, stats, ranks, S, Vin, Ia = win
    k = int(np.argmax(stats))
    dof = max(1, int(ranks[k]))
    stat = float(stats[k])
    p = min(1.0, chi2_sf(stat, dof) * a_idx.size)
    close, k = _compatible(a_idx, b_idx, stats, stat, alpha, len(cells))
    lo = cells[int(np.min(a_idx[close]))][0]
    hi = cells[int(np.max(b_idx[close])) - 1][-1]
    a, b = int(a_idx[k]), int(b_idx[k])
    # the soil change inside the evidence window (one Gauss-Newton step of a separate soil there)
    Vk = Vin[k] - Vin[k] @ Ia @ Vin[k]
    delta = -np.linalg.pinv(Vk) @ S[k] / np.asarray(scale, dtype=float)
    return TerrainWindow(
        start=float(t[lo]),
        end=float(t[hi]),
        evidence_start=float(t[cells[a][0]]),
        evidence_end=float(t[cells[b - 1][-1]]),
        statistic=stat,
        dof=dof,
        p_value=p,
        significant=bool(p < alpha),
        fmax_change=float(delta[0]),
        k_change=float(delta[1]),
    )


def _cell_scores(e: np.ndarray, J: np.ndarray, n_cells: int) -> tuple[list, np.ndarray, np.ndarray, float] | None:
    """The samples pooled into consecutive cells: the cells, their summed scores ``(m, 2)`` and information
    ``(m, 2, 2)``, and the long-run inflation of the scores' variance (None without information)."""
    n = e.shape[0]
    g = np.einsum("kcp,kc->kp", J, e)  # per-sample scores (n, 2)
    info = np.einsum("kcp,kcq->kpq", J, J)  # per-sample information (n, 2, 2)
    cells = np.array_split(np.arange(n), min(n_cells, n // 4))
    G = np.array([g[c].sum(axis=0) for c in cells])  # (m, 2)
    I = np.array([info[c].sum(axis=0) for c in cells])
    I_all = I.sum(axis=0)
    if not np.all(np.isfinite(I_all)) or np.max(np.abs(I_all)) <= 0:
        return None
    # residuals of a log are correlated in time: inflate the information by the long-run factor of the
    # per-sample scores (1 for white residuals), taken after removing their local mean over a cell, so
    # that a change of soil (a shift of the scores' mean over many samples) does not pass for correlation
    d = np.sqrt(np.maximum(np.diag(I_all), 1e-300))
    wlen = max(3, n // len(cells))
    ker = np.ones(wlen) / wlen
    hp = [g[:, j] / d[j] - np.convolve(g[:, j] / d[j], ker, mode="same") for j in range(2)]
    return cells, G, I, max(long_run_factor(hp[0]), long_run_factor(hp[1]))


def _window_statistics(G: np.ndarray, I: np.ndarray, infl: float, min_info: float) -> tuple:
    """Every window of whole cells except the whole run: its first and end cell, score statistic, rank, score
    ``S`` (inside against outside) and information ``Vin``, and the whole run's pseudo-inverse information."""
    m = G.shape[0]
    I_all = I.sum(axis=0)
    d = np.sqrt(np.maximum(np.diag(I_all), 1e-300))
    GS = np.concatenate([np.zeros((1, 2)), np.cumsum(G, axis=0)])
    IS = np.concatenate([np.zeros((1, 2, 2)), np.cumsum(I, axis=0)])
    a_idx, b_idx = np.triu_indices(m + 1, k=1)
    keep = ~((a_idx == 0) & (b_idx == m))
    a_idx, b_idx = a_idx[keep], b_idx[keep]
    Vin = IS[b_idx] - IS[a_idx]
    Ia = np.linalg.pinv(I_all)
    # inside against outside: the window's score less its share of the total (the total is zero at an
    # interior optimum, not where a soil parameter sits on a bound)
    S = (GS[b_idx] - GS[a_idx]) - np.einsum("wpq,q->wp", Vin @ Ia, GS[-1])
    Veff = infl * (Vin - Vin @ Ia @ Vin)
    # in units of the whole run's information: a direction in which the window (or the rest of the
    # run) holds less than min_info of it cannot tell inside from outside and is not tested
    Sn = S / d
    Vn = Veff / np.outer(d, d)
    stats, ranks = _pinv_quads(Sn, Vn, atol=min_info * infl)
    return a_idx, b_idx, stats, ranks, S, Vin, Ia


def _compatible(
    a_idx: np.ndarray, b_idx: np.ndarray, stats: np.ndarray, stat: float, alpha: float, m: int
) -> tuple[np.ndarray, int]:
    """The windows as compatible with the data as the best one, and the shortest of them (the evidence)."""
    # every window whose statistic is within a 1 % chi-squared (1 dof) quantile of the best one is as
    # compatible with the data (samples that carry no information about the soil, e.g. cruising or
    # standing, can be inside or outside at no cost)
    close = stats >= stat - chi2_isf(alpha, 1)
    # a window that starts with the run is the same contrast as its complement, which ends with the run;
    # a change "in the middle of a run" has the reference soil on both sides: the interior windows are
    # preferred when any of them is as compatible with the data
    interior = close & (a_idx > 0) & (b_idx < m)
    if np.any(interior):
        close = interior
    # the evidence: the shortest of those windows (the most specific statement the data support)
    cand = np.nonzero(close)[0]
    return close, int(cand[np.argmin(b_idx[cand] - a_idx[cand])])


def delay_scan(
    residual: np.ndarray, sprocket_speed: np.ndarray, max_lag: int = 25, idx: np.ndarray | None = None
) -> dict:
    """Regress the speed-channel residual on ``w(t) - w(t - k)`` for each lag ``k`` (module docstring).

    Parameters
    ----------
    residual
        Speed-channel residual per sample of the log (NaN where unused), rad/s.
    sprocket_speed
        Measured sprocket speed per sample, rad/s.
    max_lag
        Lags ``-max_lag..max_lag`` (samples) are tried.
    idx
        Samples to use (default: every finite one).

    Returns
    -------
    dict
        ``lag`` (samples, positive: the vehicle speed is late), ``t_stat`` (Newey-West), ``p_value``
        (Bonferroni over the lags), ``coef`` (residual per rad/s of sprocket-speed change, about 1
        for a pure delay), ``r2`` (share of the residual's variance the delay term explains),
        ``t_by_lag`` ({k: t}).
    """
    r = np.asarray(residual, dtype=float)
    w = np.asarray(sprocket_speed, dtype=float)
    n = r.size
    base = np.nonzero(np.isfinite(r))[0] if idx is None else np.asarray(idx)
    base = base[np.isfinite(r[base])]
    t_by_lag: dict[int, float] = {}
    out: dict[str, Any] = {
        "lag": 0,
        "t_stat": 0.0,
        "p_value": 1.0,
        "coef": 0.0,
        "r2": 0.0,
        "t_by_lag": t_by_lag,
    }
    if base.size < 30:
        return out
    L = int(min(max_lag, base.size // 10))
    # the encoder reading at t is in the residual at t (with its noise), and through the discrete
    # sprocket equation the one at t - 1 too: the regressor uses the leave-one-out interpolation
    # (w(t-1) + w(t+1)) / 2 for the present and lags of at least 2 samples, so that no noise it
    # carries is in the residual it explains
    wl = np.full(n, np.nan)
    wl[1:-1] = 0.5 * (w[:-2] + w[2:])
    best = None
    for k in range(-L, L + 1):
        if abs(k) < 2:
            continue
        sel = base[(base - k >= 1) & (base - k < n - 1) & (base >= 1) & (base < n - 1)]
        x = wl[sel] - w[sel - k]
        y = r[sel]
        xc, yc = x, y  # no intercept: a delay leaves no offset (the increments average out)
        sxx = float(xc @ xc)
        if sxx <= 0:
            continue
        b = float(xc @ yc) / sxx
        u = yc - b * xc
        gk = xc * u
        lag = newey_west_lag(sel.size)
        v = float(gk @ gk)
        for j in range(1, lag + 1):
            v += 2.0 * (1.0 - j / (lag + 1.0)) * float(gk[j:] @ gk[:-j])
        se = math.sqrt(max(v, 1e-300)) / sxx
        tk = b / se
        t_by_lag[k] = tk
        syy = float(yc @ yc)
        if best is None or tk > best[1]:  # a delay leaves a positive coefficient (module docstring)
            best = (k, tk, b, 1.0 - float(u @ u) / syy if syy > 0 else 0.0)
    if best is None:
        return out
    k, tk, b, r2 = best
    n_lags = max(1, len(t_by_lag))
    p = min(1.0, 0.5 * math.erfc(tk / math.sqrt(2.0)) * n_lags) if tk > 0 else 1.0
    out.update({"lag": int(k), "t_stat": float(tk), "p_value": float(p), "coef": float(b), "r2": float(r2)})
    return out


def shift_speed(data, k: int):
    """The log with its vehicle-speed channel moved ``k`` samples earlier (undoing a ``k``-sample delay).

    ``k > 0``: the speed sensor is late, ``v_corrected(t) = v(t + k)``; the last ``k`` samples repeat
    the last reading (negative ``k`` the first). The IMU column is left as it is.
    """
    from ...soilmodel.data import DriveLog

    v = np.asarray(data.vehicle_speed, dtype=float)
    if k > 0:
        vs = np.concatenate([v[k:], np.full(k, v[-1])])
    elif k < 0:
        vs = np.concatenate([np.full(-k, v[0]), v[:k]])
    else:
        vs = v.copy()
    return DriveLog(
        data.time,
        data.sprocket_torque,
        data.sprocket_speed,
        vs,
        data.vehicle_accel,
        source=f"{data.source} (vehicle speed shifted {k} samples)",
    )


def scale_speed(data, gain: float):
    """The log with its vehicle-speed channel divided by ``1 + gain`` (undoing a sensor that reads ``gain``
    high: a GNSS or odometry scale error). The IMU column is left as it is."""
    from ...soilmodel.data import DriveLog

    return DriveLog(
        data.time,
        data.sprocket_torque,
        data.sprocket_speed,
        np.asarray(data.vehicle_speed, dtype=float) / (1.0 + gain),
        data.vehicle_accel,
        source=f"{data.source} (vehicle speed divided by {1.0 + gain:.6g})",
    )


#: The speed channel of a drive-log fit's residuals (:data:`~.drivelog_joint.CHANNELS`).
SPEED_CHANNEL = "sprocket_speed_rad_s"


def refine_delay(nominal, data, vehicle, train: np.ndarray, k0: int, max_lag: int = 25):
    """The delay (whole samples) that the nominal model REFITTED on the shifted training part fits best.

    A profile with the nominal fit's parameters (no refit) is biased towards zero (the nominal fit
    has partly absorbed the delay: 3 samples for a 10-sample delay, measured); this searches the
    side of ``k0`` (its sign; ternary search on the integers ``1..max_lag``, each point a
    warm-started refit on the training part, their costs compared). Returns ``(k, fit)``
    (``(0, None)`` when no shift fits better than none).
    """
    from ..fitting import fit

    if k0 == 0:
        return 0, None
    sign = 1 if k0 > 0 else -1
    fits: dict[int, Any] = {}

    def cost(k):
        if k not in fits:
            try:
                # at most 60 iterations, one start: a shift far from the delay makes a hard problem (hundreds
                # of iterations) whose answer is only "worse"; unconverged counts as not fitting
                r = fit(
                    shift_speed(data, sign * k).subset(train),
                    vehicle,
                    model=nominal.model,
                    hull_channel=True,
                    x0=nominal.theta,
                    max_iter=60,
                    multistart=False,
                    bounds=nominal.bounds,
                    torque_hold=str(nominal.extra.get("torque_hold", "zoh")),
                    consistency=False,
                )
                fits[k] = r if r.success else None
            except Exception:  # noqa: BLE001 - a shift that leaves too few usable samples
                fits[k] = None
        r = fits[k]
        return math.inf if r is None else float(r.cost)

    lo, hi = 1, max_lag
    while hi - lo > 2:
        m1 = lo + (hi - lo) // 3
        m2 = hi - (hi - lo) // 3
        if cost(m1) <= cost(m2):
            hi = m2
        else:
            lo = m1
    best = min(range(lo, hi + 1), key=cost)
    if not math.isfinite(cost(best)) or cost(best) >= cost(0):
        return 0, None
    return sign * best, fits[best]


#: Relative step of the central difference of a drive log's residuals in the vehicle-speed scale: far above the
#: latent-slip solve's tolerance, far below any scale error the data show.
SPEED_SCALE_STEP = 1e-3


def speed_scale_screen(res, log, vehicle, hac_lag: int | None = None, sensitivities: Any = None) -> Screen:
    """Score test of a vehicle-speed sensor scale (``speed_scale``) from the nominal drive-log fit ``res``.

    A speed scale is no effect of the model, so its column of the Jacobian is the central difference of the
    fit's whitened residuals (latent slips solved again) in the scale of the speed channel, at the fitted
    soil. Its direction puts the speed scale into the same comparison of sensitivities as the library's
    effects (:func:`~.selection.confusable_groups`): it shares a radius error's slip signature. Not testable
    (``testable`` False) when the scaled log keeps other samples. ``sensitivities``: the fit's own on ``log``
    (:class:`~..drivelog.sensitivity.DriveLogSensitivities`, soil columns first), when already evaluated.
    """
    if sensitivities is None:
        J, r, _, c = drive_log_score_pair(res, log, vehicle)
    else:
        (J, r), c = sensitivities.soil().stacked(), sensitivities.n_channels
    up = drive_log_score_pair(res, scale_speed(log, SPEED_SCALE_STEP), vehicle)[1]
    down = drive_log_score_pair(res, scale_speed(log, -SPEED_SCALE_STEP), vehicle)[1]
    if not (up.size == down.size == r.size):
        return Screen("speed_scale", (), 0.0, 0.0, 0, 1.0, False, None)
    Z = ((up - down) / (2.0 * SPEED_SCALE_STEP)).reshape(-1, 1)
    lag = c * newey_west_lag(r.size // max(c, 1)) if hac_lag is None else hac_lag
    # projected off the same soil columns as the effects' directions (:func:`~.screening.screen`)
    return score_test("speed_scale", J, Z, r, ("speed_scale.gain",), hac_lag=lag)
