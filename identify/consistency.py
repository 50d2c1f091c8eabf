"""Are the data what their labels say? Cross-channel physics checks that catch mislabelled files.

A file can be valid (numbers, right columns, right ranges) and still be mislabelled: the torque
of one sprocket instead of both, the time in milliseconds, the speed in km/h, the normal load in
kN. Every such file fitted "with success" before these checks (issue 23). The checks compare
channels that the physics ties together, so a wrong unit or a missing factor shows as a ratio far
from 1, and the likely cause is said in words:

Drive logs (the straight-line dynamics of :mod:`soiltrack.soilmodel.dynamics`, integrated over
the log so that sensor noise averages out instead of being differentiated):

* **torque scale** ``rho``: the hull balance ``m dv/dt = F - R(v) - delta`` (``R`` the nominal
  motion resistance, :func:`~soiltrack.soilmodel.effect_terms.motion_resistance`; ``delta`` an
  unknown constant resistance such as a grade, fitted) against the thrust the sprocket equation
  gives, ``F = (M_s - I dw/dt) / r``. Integrated from the start to every sample,
  ``m (v - v_0) = rho [int M_s/r dt - I (w - w_0)/r] - int R dt - delta t`` is linear in
  ``rho`` and ``delta``; least squares gives both. ``rho = 1``: consistent; ``rho = 2``: the
  torque is half what moves the hull (one sprocket of two); ``rho = 0.001``: the time stamps are
  in milliseconds (every integral is 1,000 times too large). Not checked when the log has too
  little speed change to separate ``rho`` from ``delta`` (said).
* **IMU**: ``int a_IMU dt`` against ``v - v_0``: slope 1 consistent, -1 a flipped sign, 1,000
  milliseconds. The nominal drive-log fit does not use the IMU column (fits with effects do):
  this check is what reads it there, and the finding says so.
* **speed ratio** ``v / (r w)`` while moving (1 - slip): between about 0.5 and 1 when driving;
  about 3.6 x that when the vehicle speed is in km/h, about 0.1 x when the sprocket speed is in
  rpm.

Slip sweeps:

* **load scale**: the ``normal_load_N`` column against the vehicle's weight (a thousandth:
  kN for N);
* **force scale**: the largest force over the normal load, against what any soil can give
  (below 1 %: a force in kN or a load too large; above Eq. 2's maximum over the range of measured
  soils, :data:`~soiltrack.soilmodel.WIDE_BOUNDS`: impossible);
* **repeated rows**: rows that repeat an earlier row exactly are counted and named (fitted as
  independent evidence, copies shrink the standard errors).

Each finding is ``ok``, ``unchecked``, ``warning`` (said in the result's warnings) or ``fatal``
(the answer cannot stand: ``success`` is set False with the reason). :func:`with_consistency`
applies a report to a :class:`~soiltrack.identify.FitResult`; ``fit`` and ``fit_many`` call it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import casadi as ca
import numpy as np

from ..soilmodel.data import DriveLog, SlipData
from ..soilmodel.effects import motion_resistance
from ..soilmodel.soil import WIDE_BOUNDS
from ..soilmodel.threadsafe import locked_cache
from ..soilmodel.vehicle import Vehicle
from .estimates.records import NOT_USABLE

__all__ = [
    "ConsistencySettings",
    "Finding",
    "ConsistencyReport",
    "check_consistency",
    "check_consistency_many",
    "with_consistency",
    "repeated_rows",
    "SEVERITIES",
]

#: Severity of a finding, mildest first.
SEVERITIES = ("ok", "unchecked", "warning", "fatal")


@dataclass(frozen=True)
class ConsistencySettings:
    """Thresholds of the consistency checks (ratios; 1 is consistent).

    Attributes
    ----------
    warn_factor : float
        A ratio off 1 by more than this factor (either way) is a warning (1.25: a 25 % scale
        error shows in the soil's answer at least as much).
    fatal_factor : float
        Off by more than this factor the answer cannot stand (1.5: a factor 2 is a missing
        sprocket or track, 1,000 a unit prefix).
    max_rel_stderr : float
        A ratio estimated with a larger relative standard error is ``unchecked`` (the log has
        too little speed change to tell).
    moving_speed : float
        Samples with ``r w`` and ``v`` above this (m/s) enter the speed ratio.
    speed_ratio_range : tuple of float
        Plausible median ``v / (r w)`` while moving (1 - slip): slips from -10 % to 60 %.
    min_force_ratio : float
        A sweep whose largest force is below this fraction of its normal load at every slip
        above ``min_force_slip`` cannot come from any soil with phi >= 1 deg (tan 1 deg = 0.017).
    min_force_slip : float
        Slips above which a soil's thrust is well developed.
    load_ratio_range : tuple of float
        Plausible median normal load over the vehicle's weight in a sweep made for this vehicle
        (a rig may load one track segment, or add ballast).
    gap_factor : float
        A time step longer than this many median steps splits a log into segments (the rows of a
        subset, a logger pause); the integrals restart at each.
    max_segment_s : float
        The integrals also restart after this long, s: over an hour the integrated noise and
        drift swamp the balance (measured: ratio 0.19 on a simulated 1-hour light-vehicle log,
        0.93 with restarts every 120 s, IMU check 1.33 -> 1.02; logs up to 120 s are unchanged).
    sign_speed : float
        Below this measured speed, m/s, the resistance's sign is taken from the track's speed ``r w``
        (three GNSS noise levels of 0.05 m/s: a standing hull reads above it in 0.3 % of samples).
    error_block_s : float
        The torque scale's standard error is also taken from the fit's increments over blocks this long, s
        (the larger one counts): the integrated balance's residual is a random walk, whose increments over
        1 s (50 samples at 50 Hz) are about independent; with the per-sample error alone, gentle 60 s
        pieces of a consistent log read "fatal".
    """

    warn_factor: float = 1.25
    fatal_factor: float = 1.5
    max_rel_stderr: float = 0.2
    moving_speed: float = 0.05
    speed_ratio_range: tuple[float, float] = (0.4, 1.1)
    min_force_ratio: float = 0.01
    min_force_slip: float = 0.1
    load_ratio_range: tuple[float, float] = (0.05, 20.0)
    gap_factor: float = 3.0
    max_segment_s: float = 120.0
    sign_speed: float = 0.15
    error_block_s: float = 1.0


@dataclass(frozen=True)
class Finding:
    """One check: its name, the measured ratio, the severity and what it means in words."""

    check: str
    severity: str
    message: str
    ratio: float | None = None
    rows: tuple[int, ...] = ()
    count: int = 0

    def to_dict(self) -> dict:
        """JSON-ready dict."""
        return {
            "check": self.check,
            "severity": self.severity,
            "message": self.message,
            "ratio": None if self.ratio is None or not math.isfinite(self.ratio) else float(self.ratio),
            "rows": list(self.rows),
            "count": int(self.count),
        }


@dataclass(frozen=True)
class ConsistencyReport:
    """Every finding of :func:`check_consistency` on one dataset."""

    findings: tuple[Finding, ...] = field(default_factory=tuple)

    @property
    def passed(self) -> bool:
        """False when a finding is fatal (the fit's answer cannot stand)."""
        return not any(f.severity == "fatal" for f in self.findings)

    @property
    def failed_checks(self) -> tuple[str, ...]:
        """Names of the checks that warn or are fatal."""
        return tuple(f.check for f in self.findings if f.severity in ("warning", "fatal"))

    def warnings(self) -> tuple[str, ...]:
        """The warnings and fatal findings, in words (for the result's warnings)."""
        return tuple(
            f"data consistency ({f.check}): {f.message}" for f in self.findings if f.severity in ("warning", "fatal")
        )

    def to_dict(self) -> dict:
        """JSON-ready dict: ``passed`` and the findings."""
        return {"passed": self.passed, "findings": [f.to_dict() for f in self.findings]}


def _severity(ratio: float, st: ConsistencySettings) -> str:
    if not math.isfinite(ratio) or ratio <= 0:
        return "fatal"
    off = max(ratio, 1.0 / ratio)
    return "fatal" if off > st.fatal_factor else "warning" if off > st.warn_factor else "ok"


def _segments(t: np.ndarray, gap_factor: float, max_segment_s: float = math.inf) -> np.ndarray:
    """Index of each sample's segment start: a time step over ``gap_factor`` x the median step (the rows
    of a subset, a logger pause) starts a new segment, over which nothing is integrated; so does every
    ``max_segment_s`` of the log (counted from its start)."""
    dt = np.diff(t)
    new = np.zeros(t.size, dtype=bool)
    new[0] = True
    if dt.size:
        new[1:] = dt > gap_factor * float(np.median(dt))
    if math.isfinite(max_segment_s) and t.size > 1:
        block = np.floor((t - t[0]) / max_segment_s)
        new[1:] |= block[1:] != block[:-1]
    starts = np.nonzero(new)[0]
    return starts[np.searchsorted(starts, np.arange(t.size), side="right") - 1]


def _cumtrapz(y: np.ndarray, t: np.ndarray, start: np.ndarray) -> np.ndarray:
    """The trapezoid integral of ``y`` from each sample's segment start."""
    inc = np.zeros(y.size, dtype=float)
    inc[1:] = 0.5 * (y[1:] + y[:-1]) * np.diff(t)
    inc[start == np.arange(y.size)] = 0.0
    cum = np.cumsum(inc)
    return cum - cum[start]


@locked_cache(maxsize=16)
def _resistance_function(vehicle: Vehicle) -> ca.Function:
    vs = ca.SX.sym("v")
    return ca.Function("R", [vs], [motion_resistance(vs, 0.0, vehicle, None)])


def _resistance(v: np.ndarray, vehicle: Vehicle) -> np.ndarray:
    """Nominal motion resistance at speeds ``v`` from its one home (soilmodel.effect_terms)."""
    return np.asarray(_resistance_function(vehicle).map(v.size)(v.reshape(1, -1)), dtype=float).ravel()


def _cause_torque(rho: float) -> str:
    if 1.6 < rho < 2.5:
        return "the torque is about half what moves the hull: the torque of one sprocket of two?"
    if 0.4 < rho < 0.625:
        return "the torque is about twice what moves the hull: both sprockets counted twice, or a gear ratio?"
    if 3e-4 < rho < 3e-3:
        return "every integral over time is about 1,000 times too large: the time stamps in milliseconds?"
    if 300 < rho < 3000:
        return (
            "every integral over time is about 1,000 times too small: the time in kiloseconds, or the torque in kN m?"
        )
    return "the torque channel's scale or unit does not match the vehicle's mass and the measured speeds"


def _sign_speed(v: np.ndarray, rw: np.ndarray, st: ConsistencySettings) -> np.ndarray:
    """The speed the nominal resistance is evaluated at: the measured ``v`` where ``|v| >= sign_speed``, the
    track's ``r w`` below. Only the sign of the speed matters there (``smooth_sign``, 0.01 m/s wide), and a
    GNSS speed's noise (0.05 m/s) flips it sample by sample at a standstill and in a start: the resistance
    column then integrates +-W mu_r noise, which the regression shares with the torque column (an 11-hour
    log's ratio read 0.012). The encoder gives the sign without that noise (the track stands when the hull
    does); a locked track sliding faster than ``sign_speed`` keeps the hull's speed."""
    return np.where(np.abs(v) < st.sign_speed, rw, v)


def _increment_stderr(
    res: np.ndarray, Xs: np.ndarray, seg: np.ndarray, t: np.ndarray, st: ConsistencySettings
) -> float:
    """Standard error of the first coefficient from the fit's increments over blocks of ``st.error_block_s``.

    The balance is regressed on integrals from each segment's start, so its residual is a random walk
    (integrated torque noise, the nominal resistance's error), not white: the least-squares error, which
    counts the 3,000 samples of a 60 s piece as independent, is too small where the columns are nearly
    collinear (gentle 60 s pieces of a light log: 0.012-0.35 for ratios scattered from -2.1 to 1.6). A random walk's
    increments are independent: the same coefficients' residual and columns differenced over blocks (within
    a segment) give the error the samples really carry."""
    n = res.size
    dt = float(np.median(np.diff(t))) if n > 1 else 0.0
    k = max(int(round(st.error_block_s / dt)), 1) if dt > 0 else 1
    ends = np.unique(np.concatenate([np.arange(0, n, k), np.unique(seg), [n - 1]]))
    a, b = ends[:-1], ends[1:]
    a, b = a[seg[a] == seg[b]], b[seg[a] == seg[b]]  # no block across a segment's start
    if a.size <= Xs.shape[1]:
        return math.inf
    dr, dX = res[b] - res[a], Xs[b] - Xs[a]
    s2 = float(dr @ dr) / (a.size - Xs.shape[1])
    return math.sqrt(max(s2 * float(np.linalg.pinv(dX.T @ dX)[0, 0]), 0.0))


def _drive_findings(log: DriveLog, vehicle: Vehicle, st: ConsistencySettings) -> list[Finding]:
    t = log.time - log.time[0]
    seg = _segments(t, st.gap_factor, st.max_segment_s)
    found = (_torque_scale_finding(log, vehicle, st, t, seg), _imu_finding(log, st, t, seg))
    return [f for f in found if f is not None] + [_speed_ratio_finding(log, vehicle, st)]


def _torque_scale_finding(log: DriveLog, vehicle: Vehicle, st: ConsistencySettings, t, seg) -> Finding | None:
    """The sprocket torque against the hull balance (None: fewer than 10 samples or non-finite numbers)."""
    v, w, M = log.vehicle_speed, log.sprocket_speed, log.sprocket_torque
    m, I, r = vehicle.mass, vehicle.sprocket_inertia, vehicle.sprocket_radius
    # torque scale: m (v - v0) + I (w - w0) / r = rho int M/r dt - a int R dt - b int v dt - g t
    y = m * (v - v[seg]) + I * (w - w[seg]) / r
    X = np.column_stack(
        [
            _cumtrapz(M / r, t, seg),
            -_cumtrapz(_resistance(_sign_speed(v, r * w, st), vehicle), t, seg),
            -_cumtrapz(v, t, seg),
            -(t - t[seg]),
        ]
    )
    scale = np.abs(X).max(axis=0)
    scale[scale == 0] = 1.0
    ok = bool(np.all(np.isfinite(X)) and np.all(np.isfinite(y)) and np.abs(X[:, 0]).max() > 0)
    if ok and log.n_samples >= 10:
        Xs = X / scale
        coef, *_ = np.linalg.lstsq(Xs, y, rcond=None)
        res = y - Xs @ coef
        dof = max(log.n_samples - X.shape[1], 1)
        s2 = float(res @ res) / dof
        try:
            se = math.sqrt(s2 * max(float(np.linalg.pinv(Xs.T @ Xs)[0, 0]), 0.0)) / scale[0]
            se = max(se, _increment_stderr(res, Xs, seg, t, st) / scale[0])
        except np.linalg.LinAlgError:  # pragma: no cover - pinv of a finite matrix converges
            se = math.inf
        rho = float(coef[0] / scale[0])
        if rho > 0 and se / rho <= st.max_rel_stderr:
            sev = _severity(rho, st)
            msg = (
                f"the hull balance needs {rho:.3g} times the thrust the sprocket torque gives "
                f"(standard error {se:.2g})" + ("" if sev == "ok" else f": {_cause_torque(rho)}")
            )
            return Finding("torque_scale", sev, msg, rho)
        if rho <= 0 and se < abs(rho):
            return Finding(
                "torque_scale",
                "fatal",
                f"the hull accelerates against the torque (ratio {rho:.3g}): "
                "the torque's sign is flipped, or the columns are swapped",
                rho,
            )
        return Finding(
            "torque_scale",
            "unchecked",
            f"not checked: the log has too little speed change to "
            f"compare the torque with the hull balance (ratio {rho:.3g} +- {se:.2g})",
            rho,
        )
    return None


def _imu_finding(log: DriveLog, st: ConsistencySettings, t, seg) -> Finding | None:
    """The IMU acceleration against the measured speed's change (None: no speed change to compare with)."""
    if log.vehicle_accel is None:
        return Finding("imu", "unchecked", "no IMU column (vehicle_accel_m_s2): not checked")
    v = log.vehicle_speed
    dv = v - v[seg]
    ia = _cumtrapz(log.vehicle_accel, t, seg)
    den = float(ia @ ia)
    if not (den > 0 and float(dv @ dv) > 0):
        return None
    s = float(ia @ dv) / den  # dv ~ s * int(a) -> the IMU is 1/s times what the speed says
    k = 1.0 / s if s != 0 else math.inf
    note = " (the nominal drive-log fit does not use the IMU column; fits with effects do)"
    if k < 0:
        return Finding(
            "imu",
            "warning",
            f"the IMU acceleration has the opposite sign of the speed's change "
            f"(ratio {k:.3g}): its sign is flipped" + note,
            k,
        )
    sev = _severity(k, st)
    cause = (
        ""
        if sev == "ok"
        else (
            ": the time stamps in milliseconds?"
            if 300 < k < 3000
            else ": the IMU in g instead of m/s^2?"
            if 0.07 < k < 0.13
            else ": a scale or unit error in the IMU column"
        )
    )
    return Finding(
        "imu",
        "ok" if sev == "ok" else "warning",
        f"the IMU acceleration is {k:.3g} times what the speed's change gives{cause}" + note,
        k,
    )


def _speed_ratio_finding(log: DriveLog, vehicle: Vehicle, st: ConsistencySettings) -> Finding:
    """The median of v / (r w) while moving against the driving range."""
    v, w, r = log.vehicle_speed, log.sprocket_speed, vehicle.sprocket_radius
    # speed ratio while moving
    rw = r * w
    moving = (rw > st.moving_speed) & (v > st.moving_speed)
    if moving.sum() >= 5:
        q = _median(v[moving] / rw[moving])
        lo, hi = st.speed_ratio_range
        if lo <= q <= hi:
            return Finding("speed_ratio", "ok", f"v / (r w) while moving is {q:.3g} (slip {1 - q:.2g})", q)
        else:
            if q > hi:
                cause = (
                    "about 3.6 times a driving value: the vehicle speed in km/h?"
                    if 1.4 < q < 4.0
                    else "the vehicle is faster than its tracks all the time: a unit error, a wrong sprocket "
                    "radius, "
                    "or the speed columns swapped?"
                )
            else:
                cause = (
                    "about a tenth of a driving value: the sprocket speed in rpm (x 9.55)?"
                    if 0.04 < q < 0.12
                    else "the tracks turn much faster than the vehicle moves: a unit error or a wrong sprocket radius?"
                )
            return Finding(
                "speed_ratio",
                "fatal",
                f"v / (r w) while moving is {q:.3g}, outside the driving range [{lo:g}, {hi:g}]: {cause}",
                q,
            )
    return Finding("speed_ratio", "unchecked", "fewer than 5 moving samples: v / (r w) not checked")


_LOOP_ROWS = 16  # repeated_rows: up to this many rows a set of tuples, beyond it a sort


def repeated_rows(data: SlipData) -> tuple[int, tuple[int, ...]]:
    """``(count, first rows)`` of rows that repeat an earlier row exactly (1-based data rows)."""
    cols = [data.slip, data.values] + ([data.normal_load] if data.normal_load is not None else [])
    if len(data.slip) <= _LOOP_ROWS:  # a few rows: the plain loop is the quicker (the same answer)
        seen: set = set()
        dup: list[int] = []
        for r, row in enumerate(zip(*(c.tolist() for c in cols)), start=1):
            if row in seen:
                dup.append(r)
            else:
                seen.add(row)
        return len(dup), tuple(dup[:5])
    ss = np.sort(np.asarray(data.slip, dtype=float))
    if not np.count_nonzero(ss[1:] == ss[:-1]):  # no two rows share a slip: none repeats another (the same answer)
        return 0, ()
    X = np.column_stack([np.asarray(c, dtype=float) for c in cols])
    order = np.lexsort(X.T[::-1])  # stable: among equal rows the earliest first
    Xs = X[order]
    same = np.all(Xs[1:] == Xs[:-1], axis=1)  # NaN never equals: a row with a NaN repeats nothing
    later = np.sort(order[1:][same])  # every row equal to an earlier one
    return int(later.size), tuple(int(r) + 1 for r in later[:5])


def _median(x: np.ndarray) -> float:
    s = np.sort(x)
    n = s.size
    return float(s[n // 2]) if n % 2 else float(0.5 * (s[n // 2 - 1] + s[n // 2]))


def _sweep_findings(data: SlipData, vehicle: Vehicle, st: ConsistencySettings) -> list[Finding]:
    out: list[Finding] = []
    W = vehicle.weight
    if data.normal_load is not None:
        q = _median(data.normal_load) / W
        lo, hi = st.load_ratio_range
        if lo <= q <= hi:
            out.append(Finding("load_scale", "ok", f"the median normal load is {q:.3g} times the vehicle's weight", q))
        else:
            cause = (
                "a thousandth: the load in kN instead of N?"
                if 3e-4 < q < 3e-3
                else "a thousand times: the vehicle's weight in kN, or a file of another vehicle?"
                if 300 < q < 3000
                else "a file of another vehicle, or a unit error?"
            )
            out.append(
                Finding(
                    "load_scale",
                    "fatal",
                    f"the median normal load is {q:.3g} times this vehicle's weight ({W:.6g} N): {cause}",
                    q,
                )
            )
    developed = data.slip >= st.min_force_slip
    if np.count_nonzero(developed) and data.normal_load is None and W > 0:  # every load W: exact as below,
        ratio = float(np.maximum.reduce(data.values[developed])) / W  # (the largest quotient is the largest's)
        c_hi, phi_hi = float(WIDE_BOUNDS.upper[0]), float(WIDE_BOUNDS.upper[1])
        out.append(_force_scale_finding(ratio, (vehicle.contact_area * c_hi + W * math.tan(phi_hi)) / W, st))
    elif np.count_nonzero(developed):
        loads = data.loads(W)
        ratio = float(np.max(data.values[developed] / loads[developed]))
        out.append(_force_scale_finding(ratio, _top_ratio(vehicle, loads), st))
    n_rep, rows = repeated_rows(data)
    if n_rep:
        out.append(_repeated_finding(n_rep, rows))
    return out


def _top_ratio(vehicle: Vehicle, loads) -> float:
    """The largest force over the normal load any soil of the measured range gives at these loads."""
    c_hi, phi_hi = float(WIDE_BOUNDS.upper[0]), float(WIDE_BOUNDS.upper[1])  # the range of measured soils
    return float(np.max((vehicle.contact_area * c_hi + loads * math.tan(phi_hi)) / loads))


def _force_scale_finding(ratio: float, top: float, st: ConsistencySettings) -> Finding:
    """The force-scale check: the largest developed force over the normal load, ``ratio``, against what soils give."""
    if ratio < st.min_force_ratio:
        return Finding(
            "force_scale",
            "fatal",
            f"the largest force at slips >= {st.min_force_slip:g} is "
            f"{ratio:.3g} of the normal load: no soil gives so little (phi >= 1 deg gives 0.017); "
            "the force in kN instead of N, or the data of a lighter vehicle?",
            ratio,
        )
    if ratio > top:
        return Finding(
            "force_scale",
            "fatal",
            f"the largest force is {ratio:.3g} times the normal load, more "
            f"than any soil gives this vehicle ({top:.3g}): the force in N where the load is in kN, "
            "or the data of a heavier vehicle?",
            ratio,
        )
    return Finding("force_scale", "ok", f"the largest force is {ratio:.3g} of the normal load", ratio)


def _repeated_finding(n_rep: int, rows: tuple[int, ...]) -> Finding:
    """The repeated-rows warning: ``n_rep`` rows repeat an earlier one (the first ``rows``, 1-based)."""
    return Finding(
        "repeated_rows",
        "warning",
        f"{n_rep} row(s) repeat an earlier row exactly (rows "
        f"{', '.join(map(str, rows))}{' ...' if n_rep > len(rows) else ''}): each is fitted as "
        "independent evidence, which shrinks the standard errors; remove copies, keep true "
        "replicates",
        float(n_rep),
        rows,
        n_rep,
    )


def _plain_sweep_findings(datasets: list, vehicle: Vehicle, st: ConsistencySettings) -> list[tuple[Finding, ...]]:
    """:func:`_sweep_findings` of sweeps of one length without a normal-load column, decided at once: every
    load is the vehicle's weight, so the force scale is one stacked maximum; a sweep with no two equal slips
    has no repeated row (any other goes through :func:`repeated_rows`)."""
    W = vehicle.weight
    S = np.array([d.slip for d in datasets], dtype=float)
    loads = datasets[0].loads(W)  # (the same for every sweep of this length)
    developed_rows = S >= st.min_force_slip
    developed = (np.count_nonzero(developed_rows, axis=1) > 0).tolist()
    ratios = np.where(developed_rows, np.array([d.values for d in datasets]) / loads, -np.inf).max(axis=1).tolist()
    Ss = np.sort(S, axis=1)
    maybe_repeats = (Ss[:, 1:] == Ss[:, :-1]).any(axis=1).tolist()
    top = _top_ratio(vehicle, loads)
    out: list[tuple[Finding, ...]] = []
    for d, dev, ratio, maybe in zip(datasets, developed, ratios, maybe_repeats):
        found: tuple[Finding, ...] = (_force_scale_finding(ratio, top, st),) if dev else ()
        if maybe:
            n_rep, rows = repeated_rows(d)
            if n_rep:
                found += (_repeated_finding(n_rep, rows),)
        out.append(found)
    return out


def check_consistency_many(datasets: list, vehicle: Vehicle) -> list[ConsistencyReport]:
    """:func:`check_consistency` (default settings) of many datasets (``fit_many``): the same reports; the
    slip sweeps of one length without a normal-load column checked at once (:func:`_plain_sweep_findings`)."""
    out: list[ConsistencyReport | None] = [None] * len(datasets)
    groups: dict[int, list[int]] = {}
    for k, d in enumerate(datasets):
        if type(d) is SlipData and d.normal_load is None and d.slip.size:
            groups.setdefault(d.slip.size, []).append(k)
    for idx in groups.values():
        for k, found in zip(idx, _plain_sweep_findings([datasets[k] for k in idx], vehicle, _DEFAULT_SETTINGS)):
            out[k] = ConsistencyReport(found)
    return [r if r is not None else check_consistency(d, vehicle) for r, d in zip(out, datasets)]


_DEFAULT_SETTINGS = ConsistencySettings()  # (frozen: one instance serves every call without settings)


def check_consistency(data: Any, vehicle: Vehicle, settings: ConsistencySettings | None = None) -> ConsistencyReport:
    """Run the checks of the module notes on a drive log or a slip sweep.

    Parameters
    ----------
    data : DriveLog or SlipData
    vehicle : Vehicle
    settings : ConsistencySettings, optional

    Returns
    -------
    ConsistencyReport
    """
    st = settings or _DEFAULT_SETTINGS
    if isinstance(data, DriveLog):
        return ConsistencyReport(tuple(_drive_findings(data, vehicle, st)))
    if isinstance(data, SlipData):
        return ConsistencyReport(tuple(_sweep_findings(data, vehicle, st)))
    return ConsistencyReport()


def with_consistency(result: Any, report: ConsistencyReport) -> Any:
    """``result`` with the report's warnings and ``extra["consistency"]``; failed if a finding is fatal."""
    warns = tuple(w for w in report.warnings() if w not in result.input_warnings)  # a nested fit said them
    if not warns:  # the common case: recorded in the result's own extra dict (no copy of the result)
        result.extra["consistency"] = report.to_dict()
        return result
    extra = dict(result.extra)
    extra["consistency"] = report.to_dict()
    kw: dict[str, Any] = {"extra": extra, "input_warnings": tuple(result.input_warnings) + warns}
    if not report.passed and result.success:
        fatal = [f.check for f in report.findings if f.severity == "fatal"]
        kw["success"] = False
        kw["status"] = result.status if NOT_USABLE in result.status else f"{result.status} {NOT_USABLE}"
        kw["message"] = (
            f"{result.message}; the data fail the consistency check(s) {', '.join(fatal)}: the answer "
            "cannot stand (see the warnings)"
        )
    return replace(result, **kw)
