"""Drive-log parts of the diagnosis: a change of terrain in time, and a delay between channels.

Two things a drive log can show that no effect of the library explains, and that must not be
named as one (docs/physics.md, "Unmodelled effects"; :func:`~.diagnosis.diagnose` calls these for logs):

- :func:`terrain_window`: the time window in which the SOIL differs from the rest of the run
  (a softer patch). A change of soil does not shift the residual's mean: the thrust-slip curve
  moves, and where the vehicle pushes little (cruising, standing) the data cannot see it at all.
  The test is the score (Lagrange-multiplier) test of "the soil (thrust limit F_max and shear
  modulus K) differs inside the window": the per-sample scores ``g_k = J_k^T e_k`` of the nominal
  fit (:func:`~.drivelog_sensitivity.drive_log_sensitivities`) summed over the window, against
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
  :func:`delay_holdout` fits that term on the training part and predicts the held-out part, so
  that the delay competes with the candidate effects on the same held-out data.

Pure numpy on the fit's residuals and sensitivities; no physics here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .gap import long_run_factor
from ..estimates.distributions import chi2_isf, chi2_sf
from .screening import newey_west_lag

__all__ = [
    "TerrainWindow",
    "terrain_window",
    "delay_scan",
    "delay_holdout",
    "DelayCheck",
    "delay_check",
    "review_drive_log",
    "shift_speed",
    "refine_delay",
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

    def to_dict(self) -> dict:
        """JSON-friendly dict (the ``change_window`` entry of a drive-log diagnosis)."""

        def f(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        return {
            "channel": self.channel,
            "start": float(self.start),
            "end": float(self.end),
            "evidence_start": float(self.evidence_start),
            "evidence_end": float(self.evidence_end),
            "shift": f(self.fmax_change),
            "fmax_change": f(self.fmax_change),
            "k_change": f(self.k_change),
            "statistic": float(self.statistic),
            "dof": int(self.dof),
            "p_value": float(self.p_value),
            "significant": bool(self.significant),
        }

    def describe(self) -> str:
        """One line for the report."""
        if not self.significant:
            return (
                f"no significant change of soil in time (strongest window {self.evidence_start:.4g} to "
                f"{self.evidence_end:.4g} s, p = {self.p_value:.2g})"
            )
        how = ", ".join(f"{name} {_pct(x)}" for name, x in (("thrust limit", self.fmax_change), ("K", self.k_change)))
        return (
            f"the soil differs from the rest of the run within {self.start:.4g} to {self.end:.4g} s: it shows "
            f"between {self.evidence_start:.4g} and {self.evidence_end:.4g} s (linearised change there: {how}; "
            f"p = {self.p_value:.2g}); the samples outside that but inside the bracket carry too little "
            f"information about the soil (little thrust) to place the boundaries closer"
        )


def _pct(x: float) -> str:
    """A relative change in words (a linearised step beyond +-100 % says only its direction)."""
    if not math.isfinite(x):
        return "unknown"
    if abs(x) > 1.0:
        return "much lower" if x < 0 else "much higher"
    return f"{x:+.0%}"


def _pinv_quad(S: np.ndarray, V: np.ndarray, atol: float = 1e-8) -> tuple[float, int]:
    """``S^T V^+ S`` and the rank of ``V`` (symmetric, eigen-decomposed; eigenvalues below ``atol`` dropped)."""
    w, U = np.linalg.eigh(0.5 * (V + V.T))
    if w[-1] <= atol:
        return 0.0, 0
    keep = w > atol
    y = U[:, keep].T @ S
    return float(np.sum(y**2 / w[keep])), int(np.count_nonzero(keep))


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
    n = e.shape[0]
    if n < 24:
        return None
    g = np.einsum("kcp,kc->kp", J, e)  # per-sample scores (n, 2)
    info = np.einsum("kcp,kcq->kpq", J, J)  # per-sample information (n, 2, 2)
    cells = np.array_split(np.arange(n), min(n_cells, n // 4))
    m = len(cells)
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
    infl = max(long_run_factor(hp[0]), long_run_factor(hp[1]))
    GS = np.concatenate([np.zeros((1, 2)), np.cumsum(G, axis=0)])
    IS = np.concatenate([np.zeros((1, 2, 2)), np.cumsum(I, axis=0)])
    # every window of whole cells, except the whole run
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
    stats = np.empty(a_idx.size)
    ranks = np.empty(a_idx.size, dtype=int)
    for j in range(a_idx.size):
        stats[j], ranks[j] = _pinv_quad(Sn[j], Vn[j], atol=min_info * infl)
    k = int(np.argmax(stats))
    a, b = int(a_idx[k]), int(b_idx[k])
    dof = max(1, int(ranks[k]))
    stat = float(stats[k])
    p = min(1.0, chi2_sf(stat, dof) * a_idx.size)
    # where the boundaries can lie: every window whose statistic is within a 1 % chi-squared (1 dof)
    # quantile of the best one is as compatible with the data (samples that carry no information
    # about the soil, e.g. cruising or standing, can be inside or outside at no cost)
    close = stats >= stat - chi2_isf(alpha, 1)
    # a window that starts with the run is the same contrast as its complement, which ends with the run;
    # a change "in the middle of a run" has the reference soil on both sides: the interior windows are
    # preferred when any of them is as compatible with the data
    interior = close & (a_idx > 0) & (b_idx < m)
    if np.any(interior):
        close = interior
    lo = cells[int(np.min(a_idx[close]))][0]
    hi = cells[int(np.max(b_idx[close])) - 1][-1]
    # the evidence: the shortest of those windows (the most specific statement the data support)
    cand = np.nonzero(close)[0]
    k = int(cand[np.argmin(b_idx[cand] - a_idx[cand])])
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
    out = {"lag": 0, "t_stat": 0.0, "p_value": 1.0, "coef": 0.0, "r2": 0.0, "t_by_lag": {}}
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
        out["t_by_lag"][k] = tk
        syy = float(yc @ yc)
        if best is None or tk > best[1]:  # a delay leaves a positive coefficient (module docstring)
            best = (k, tk, b, 1.0 - float(u @ u) / syy if syy > 0 else 0.0)
    if best is None:
        return out
    k, tk, b, r2 = best
    n_lags = max(1, len(out["t_by_lag"]))
    p = min(1.0, 0.5 * math.erfc(tk / math.sqrt(2.0)) * n_lags) if tk > 0 else 1.0
    out.update({"lag": int(k), "t_stat": float(tk), "p_value": float(p), "coef": float(b), "r2": float(r2)})
    return out


def _lag_matrix(w: np.ndarray, idx: np.ndarray, lags: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Rows ``idx`` (those with every lag inside the log) of ``[wl(t) - w(t - k) for k in lags]``."""
    n = w.size
    wl = np.full(n, np.nan)
    wl[1:-1] = 0.5 * (w[:-2] + w[2:])
    kmin, kmax = min(lags), max(lags)
    idx = idx[(idx - kmax >= 0) & (idx - kmin < n) & (idx >= 1) & (idx < n - 1)]
    X = np.column_stack([wl[idx] - w[idx - k] for k in lags])
    return X, idx


def delay_holdout(
    residual_train: np.ndarray,
    residual_held: np.ndarray,
    sprocket_speed: np.ndarray,
    train: np.ndarray,
    test: np.ndarray,
    max_lag: int = 25,
) -> tuple[np.ndarray, dict]:
    """The delay term fitted on the training samples, subtracted from the held-out residuals.

    The term is a distributed lag: the speed residual regressed jointly on the sprocket-speed
    changes over every lag ``2 <= |k| <= max_lag`` (a delay that is not a whole number of samples,
    or that the latent slip partly absorbs, leaves a blend of lags). :func:`delay_scan` on the
    training part names the dominant lag for the report.

    Parameters
    ----------
    residual_train
        Speed-channel residual of the training fit at every sample of the log (NaN where unused).
    residual_held
        The held-out residuals to correct (full length; only ``test`` is changed).
    sprocket_speed
        Measured sprocket speed per sample.
    train, test
        Sample indices of the two parts.

    Returns
    -------
    (corrected, scan)
        Full-length residuals with the training part's delay term removed on ``test``, and the
        training part's :func:`delay_scan`.
    """
    scan = delay_scan(residual_train, sprocket_speed, max_lag, idx=np.asarray(train))
    out = np.array(residual_held, dtype=float, copy=True)
    w = np.asarray(sprocket_speed, dtype=float)
    rt = np.asarray(residual_train, dtype=float)
    L = int(min(max_lag, max(2, np.asarray(train).size // 40)))
    lags = [k for k in range(-L, L + 1) if abs(k) >= 2]
    tr = np.asarray(train)
    tr = tr[np.isfinite(rt[tr])]
    X, tr = _lag_matrix(w, tr, lags)
    if tr.size < 4 * len(lags):
        return out, scan
    coef, *_ = np.linalg.lstsq(X, rt[tr], rcond=None)
    Xt, te = _lag_matrix(w, np.asarray(test), lags)
    ok = np.isfinite(out[te])
    out[te[ok]] = out[te[ok]] - Xt[ok] @ coef
    return out, scan


@dataclass(frozen=True)
class DelayCheck:
    """The delay term as a competitor of the verdict on the held-out data.

    Attributes
    ----------
    scan
        :func:`delay_scan` on the training part (``lag`` in samples, ``seconds``, ``t_stat``, ...).
    significant
        The delay term predicts the held-out speed residuals significantly better than nothing
        (Diebold-Mariano at ``alpha``) and its lag is significant on the training part.
    gain
        Drop of the held-out sum of squared standardised residuals the delay term gives.
    """

    scan: dict
    significant: bool
    gain: float

    def summary(self) -> dict:
        """JSON-friendly summary (the ``lags`` entry of a drive-log diagnosis)."""
        s = self.scan
        return {
            "lag": int(s["lag"]),
            "seconds": float(s.get("seconds", 0.0)),
            "t_stat": float(s["t_stat"]),
            "p_value": float(s["p_value"]),
            "coef": float(s["coef"]),
            "r2": float(s["r2"]),
            "holdout_gain": float(self.gain) if math.isfinite(self.gain) else None,
            "significant": bool(self.significant),
        }


def delay_check(
    train_residual: np.ndarray,
    held_residual: np.ndarray,
    sigma: np.ndarray,
    mask: np.ndarray,
    sprocket_speed: np.ndarray,
    time_s: np.ndarray,
    train: np.ndarray,
    test: np.ndarray,
    dm_lag: int,
    alpha: float = 0.01,
) -> DelayCheck:
    """Fit the delay term on the training part, score it on the held-out part (speed channel).

    ``train_residual`` / ``held_residual``: the nominal model's speed-channel residuals at every sample
    (NaN elsewhere) from the training fit, on the training and the held-out samples; ``sigma`` the
    noise level per sample; ``mask`` the held-out samples compared.
    """
    from .selection import dm_test

    corrected, scan = delay_holdout(train_residual, held_residual, sprocket_speed, train, test)
    h = float(np.median(np.diff(np.asarray(time_s, dtype=float)))) if len(time_s) > 1 else 0.0
    scan = dict(scan, seconds=scan["lag"] * h)
    scan.pop("t_by_lag", None)
    z0 = held_residual[mask] / sigma[mask]
    z1 = corrected[mask] / sigma[mask]
    ok = np.isfinite(z0) & np.isfinite(z1)
    if scan["lag"] == 0 or np.count_nonzero(ok) < 10:
        return DelayCheck(scan, False, 0.0)
    gain = float(np.sum(z0[ok] ** 2) - np.sum(z1[ok] ** 2))
    sig = bool(scan["p_value"] < alpha and dm_test(z0[ok], z1[ok], dm_lag) < alpha)
    return DelayCheck(scan, sig, gain)


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


#: The speed channel of a drive-log fit's residuals (:data:`~.drivelog_joint.CHANNELS`).
SPEED_CHANNEL = "sprocket_speed_rad_s"


def review_drive_log(
    verdict,
    data,
    vehicle,
    nominal,
    H: dict,
    sigma: dict,
    mask: dict,
    folds,
    train_res: dict,
    scores: dict,
    dm_lag: int,
    alpha: float = 0.01,
    alternatives=(),
):
    """The drive-log checks of :func:`~.diagnosis.diagnose` after the held-out comparison.

    1. The change of terrain in time (:func:`terrain_window` on the nominal fit's per-sample scores).
    2. The delay term (:func:`delay_check`) as a competitor of the verdict's effect: when it explains
       more of the held-out misfit than the effect, the verdict is ``unexplained`` (a delay between the
       channels is no effect of the library); when it explains part of it, the effect's confidence is
       at most its share of the two gains.
    3. A verdict ``none`` with a significant change of soil in time becomes ``unexplained`` - unless
       one of ``alternatives``, ``(effect, fit)`` pairs of candidates fitted on the training part, best
       first (``fit`` may be a callable that fits on demand: the candidates that screening did not keep
       are fitted only here), removes that change when the window is sought on its own fit: then the
       "change" is the effect's signature in time (a radius error offsets the slip by about -eps, which
       weighs differently as the speed varies; a resistance growing with slip weighs on the windows of
       hard acceleration), and the first such effect is named with confidence 0.5 (its held-out gain
       alone was within the noise).

    Returns
    -------
    (verdict, change, lags, notes)
        The (possibly revised) :class:`~.selection.Verdict`, the :class:`TerrainWindow` (or None), the
        ``{"delay scan ...": summary}`` entry for the diagnosis' ``lags`` and notes for the report.
    """
    from ...soilmodel.errors import DataError
    from ..drivelog.sensitivity import drive_log_sensitivities
    from .selection import NOMINAL, Verdict

    notes: list[str] = []
    lags: dict = {}
    change = None
    try:
        sens = drive_log_sensitivities(nominal, data, vehicle)
        scale = (float(nominal.extra.get("max_thrust_N", 1.0)), float(nominal.extra.get("shear_modulus_m", 1.0)))
        change = terrain_window(sens.residuals, sens.jacobian, sens.time_s, scale=scale, alpha=alpha)
    except DataError:
        change = None
    # the delay term, fitted on the first training part, scored on its held-out part
    check = None
    if SPEED_CHANNEL in H.get(NOMINAL, {}) and folds and train_res.get(NOMINAL):
        tr, te = folds[0]
        n = data.n_samples
        rtr = np.full(n, np.nan)
        rtr[tr] = train_res[NOMINAL][0][SPEED_CHANNEL]
        held = np.full(n, np.nan)
        held[te] = H[NOMINAL][SPEED_CHANNEL][te]
        m = mask[SPEED_CHANNEL].copy()
        m[tr] = False
        check = delay_check(rtr, held, sigma[SPEED_CHANNEL], m, data.sprocket_speed, data.time, tr, te, dm_lag, alpha)
        lags["delay scan: speed residual vs sprocket-speed change over k samples"] = check.summary()
    name = verdict.name
    if check is not None and check.significant and check.gain > 0:
        # the exact delay model: the vehicle-speed channel shifted by the best whole number of samples,
        # the nominal model refitted on the training part, scored on the held-out part like the candidates
        # the side of the delay: the sign of the dominant lag of the scan on the training part
        k, fit_k = refine_delay(nominal, data, vehicle, folds[0][0], int(np.sign(check.scan["lag"])))
        exact = _delay_gain(k, fit_k, data, vehicle, H, sigma, mask, folds) if k != 0 else 0.0
        h = float(np.median(np.diff(np.asarray(data.time, dtype=float))))
        check = DelayCheck(dict(check.scan, lag=int(k), seconds=k * h, fir_gain=check.gain), k != 0, exact)
        lags["delay scan: speed residual vs sprocket-speed change over k samples"] = check.summary()
    if check is not None and check.significant and check.gain > 0:
        lag_txt = f"{abs(check.scan['lag'])} samples ({abs(check.scan['seconds']):.3g} s)"
        late = "late" if check.scan["lag"] > 0 else "early"
        if name not in (NOMINAL, "unexplained", "discrepancy"):
            g_eff = float(scores[NOMINAL] - scores[name]) if math.isfinite(scores.get(name, math.inf)) else 0.0
            share = max(0.0, g_eff) / (max(0.0, g_eff) + check.gain)
            if check.gain > g_eff:
                verdict = Verdict(
                    "unexplained",
                    1.0 - share,
                    f"the vehicle-speed channel looks {lag_txt} {late} against the sprocket speed: the "
                    f"nominal model refitted with that channel shifted back explains more of the held-out "
                    f"misfit than the best candidate, {name} (gain in the sum of squared standardised "
                    f"held-out residuals {check.gain:.0f} against {g_eff:.0f}); no library effect is a delay",
                )
                notes.append(
                    f"{name} was the best candidate, but a {lag_txt} delay of the vehicle-speed channel "
                    f"explains the held-out data better: check the time stamps of the speed sensor"
                )
            elif share < verdict.confidence:
                verdict = Verdict(name, share, verdict.reason)
                notes.append(
                    f"a {lag_txt} delay of the vehicle-speed channel explains part of the held-out misfit "
                    f"(gain {check.gain:.0f} against {g_eff:.0f} for {name}): {name} is named with "
                    f"confidence {share:.2f} only"
                )
        elif name == NOMINAL:
            verdict = Verdict(
                "unexplained",
                max(0.0, 1.0 - float(check.scan["p_value"])),
                f"the vehicle-speed channel looks {lag_txt} {late} against the sprocket speed (the "
                f"nominal model refitted with it shifted back predicts the held-out data better); no "
                f"library effect is a delay",
            )
    if verdict.name == NOMINAL and change is not None and change.significant:
        kept: list[tuple[str, Any]] = []  # (effect, its window): the effects that do not remove the change
        for a_name, a_fit in alternatives:
            try:
                a_fit = a_fit() if callable(a_fit) else a_fit
                if a_fit is None or not a_fit.success:
                    continue
                sa = drive_log_sensitivities(a_fit, data, vehicle)
                ch_a = terrain_window(sa.residuals, sa.jacobian, sa.time_s, scale=scale, alpha=alpha)
            except DataError:
                continue
            if ch_a is not None and ch_a.significant:
                kept.append((a_name, ch_a))
                continue
            notes.append(
                f"the nominal model's soil seems to differ at {change.evidence_start:.4g}-"
                f"{change.evidence_end:.4g} s (p = {change.p_value:.2g}), but with {a_name} (fitted on the "
                f"training part) no time window differs "
                f"({'p = ' + format(ch_a.p_value, '.2g') if ch_a is not None else 'nothing to test'}): "
                f"it is {a_name}'s signature in time, not a change of terrain"
            )
            verdict = Verdict(
                a_name,
                0.5,
                f"{a_name} removes the change of soil in time that the nominal model "
                "shows, while its held-out gain alone is within the noise: named with confidence 0.5",
            )
            break
        if verdict.name == NOMINAL and kept:
            notes.append(
                "the change of soil in time stays significant with "
                + ", ".join(f"{a} (p = {w.p_value:.2g})" for a, w in kept)
                + " fitted on the training part"
            )
    if verdict.name == NOMINAL and change is not None and change.significant:
        verdict = Verdict(
            "unexplained",
            max(0.0, 1.0 - change.p_value),
            f"the soil differs in a time window ({change.evidence_start:.4g} to {change.evidence_end:.4g} s, "
            f"within {change.start:.4g} to {change.end:.4g} s; p = {change.p_value:.2g}): a change of "
            "terrain during the run, which no candidate effect describes",
        )
    return verdict, change, lags, notes


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
                # at most 60 iterations, one start: a shift far from the delay makes a hard problem (hundreds of
                # iterations) whose answer is only "worse"; unconverged counts as not fitting
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


def _delay_gain(k, res, data, vehicle, H, sigma, mask, folds) -> float:
    """Held-out gain (all channels, standardised) of the training fit ``res`` on the log shifted by ``k``."""
    from .selection import NOMINAL

    tr, te = folds[0]
    shifted = shift_speed(data, k)
    try:
        if res is None or not res.success:
            return 0.0
        from ..drivelog.residuals import drive_log_residuals

        out = drive_log_residuals(res, shifted, vehicle)
    except Exception:  # noqa: BLE001 - no delay model: no gain
        return 0.0
    keep = np.asarray(out["keep"])
    idx = np.nonzero(keep)[0] if keep.dtype == bool else keep.astype(int)
    gain = 0.0
    n = data.n_samples
    for ch, r in out["channels"].items():
        if ch not in H[NOMINAL]:
            continue
        full = np.full(n, np.nan)
        full[idx] = np.asarray(r, dtype=float)
        m = mask[ch].copy()
        m[tr] = False
        z0 = H[NOMINAL][ch][m] / sigma[ch][m]
        z1 = full[m] / sigma[ch][m]
        ok = np.isfinite(z0) & np.isfinite(z1)
        gain += float(np.sum(z0[ok] ** 2) - np.sum(z1[ok] ** 2))
    return gain


@dataclass(frozen=True)
class ArmCheck:
    """Does the torque arm follow a radius error's slip offset? (:func:`torque_arm_check`)

    A radius error ``r (1 + eps)`` shifts the apparent slip and divides the sprocket thrust by
    ``1 + eps``; a scale error of the vehicle-speed sensor shifts the slip the same way and leaves the
    thrust alone. With a thrust scale ``1 + kappa`` fitted on top (jointly with the soil and eps,
    linearised at the radius-error fit), a radius error has ``kappa = 0`` and a speed-sensor scale
    error ``kappa = eps``.

    Attributes
    ----------
    kappa, stderr
        The thrust scale's estimate and standard error (widened for correlated residuals).
    eps
        The radius error's fitted eps.
    z_radius, z_speed_scale
        ``|kappa| / stderr`` and ``|kappa - eps| / stderr``: how far each explanation is off.
    """

    kappa: float
    stderr: float
    eps: float
    z_radius: float
    z_speed_scale: float


def torque_arm_check(fit, data, vehicle, eps: float, h: float = 1e-4) -> ArmCheck | None:
    """The thrust scale ``kappa`` on top of a radius-error fit of a drive log (see :class:`ArmCheck`).

    Its profiled sensitivity is a difference quotient: the residuals with the logged torque and the
    sprocket inertia scaled by ``1 + h`` (the sprocket thrust ``(M - I dw/dt) / r`` scaled), the
    latent slips solved again, against those of the fit. None when the residuals cannot be evaluated.
    """
    from dataclasses import replace

    from ...soilmodel.errors import DataError
    from ..drivelog.sensitivity import drive_log_sensitivities

    try:
        s0 = drive_log_sensitivities(fit, data, vehicle)
        s1 = drive_log_sensitivities(
            fit,
            replace(data, sprocket_torque=np.asarray(data.sprocket_torque, float) * (1 + h)),
            replace(vehicle, sprocket_inertia=vehicle.sprocket_inertia * (1 + h)),
        )
    except DataError:
        return None
    if s0.residuals.shape != s1.residuals.shape or not np.array_equal(s0.keep, s1.keep):
        return None
    J, r = s0.stacked()
    zk = ((s1.residuals - s0.residuals) / h).reshape(-1, 1)
    A = np.hstack([J, zk])
    ok = np.all(np.isfinite(A), axis=1) & np.isfinite(r)
    A, r = A[ok], r[ok]
    G = A.T @ A
    try:
        Gi = np.linalg.inv(G)
    except np.linalg.LinAlgError:
        return None
    kappa = float(-(Gi @ (A.T @ r))[-1])
    s2 = max(1.0, float(np.mean(r**2)))
    infl = max(long_run_factor(s0.residuals[:, j]) for j in range(s0.residuals.shape[1]))
    var = float(Gi[-1, -1]) * s2 * infl
    if not (math.isfinite(kappa) and math.isfinite(var) and var > 0):
        return None
    se = math.sqrt(var)
    return ArmCheck(kappa, se, float(eps), abs(kappa) / se, abs(kappa - eps) / se)
