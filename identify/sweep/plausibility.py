"""Plausibility of tractive force-slip data and of a fit to them: wrong data must not pass as success.

A bounded fit always "converges" to something. These checks say, in plain words, when the data
or the answer cannot be right, so that a fit to them is not reported as a success:

At input (independent of the fit):

- **loads of another vehicle**: the rows' normal loads are far below or above the weight of the
  vehicle given (a light vehicle's sweep fitted with a heavy vehicle's file): the contact area
  A of that vehicle then puts a wrong A c into every F_max;
- **force scale**: the forces are far below what the weakest soil within the bounds gives at
  these slips and this load (typically kN written in an N column), or a row lies far above
  what the strongest soil gives (a typo, a unit error, the wrong normal load);
- **negative thrust while driving**: a negative tractive force at positive slip.

After the fit:

- **thrust limit on a bound**: the identifiable combination F_max = A c + W tan(phi) sits at the
  smallest or largest value the bounds allow, so the bounds, not the data, fixed it;
- **residuals as large as the data**: the model does not describe them;
- **gross outliers**: a row whose residual is many robust standard deviations out (robust
  z-score: residual over 1.4826 times the median absolute deviation), named by row.

Each finding says whether the answer is still usable; :func:`assess` returns the warnings and
the verdict that the result builder turns into ``warnings`` and ``success``. Rows are numbered
like :class:`~soiltrack.soilmodel.DataError`'s: row 1 is the first data row of the file.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from ...soilmodel.ridge import continuous_load, corner_soils
from ..estimates.records import LOAD_FACTOR, Finding, check_loads
from ...soilmodel.ridge import soil_fmax_range as fmax_range
from ...soilmodel.soil import SoilBounds
from ...soilmodel.traction import max_thrust_expr, thrust_at
from ...soilmodel.vehicle import Vehicle
from ...soilmodel.tracks import MAD_TO_SIGMA
from ...soilmodel.units import format_value

__all__ = [
    "Finding",
    "slip_checks",
    "fmax_range",
    "corner_soils",
    "corner_curves",
    "check_loads",
    "check_slip_data",
    "check_slip_fit",
    "assess",
    "screen_expr",
    "limit_screen_expr",
    "LIMIT_BAND",
    "assess_many",
    "SCALE_FACTOR",
    "OUTLIER_Z",
    "OUTLIER_SHARE",
    "GROSS_Z",
    "GROSS_SHARE",
    "RESIDUAL_RATIO",
    "BOUND_FACTOR",
    "LOAD_FACTOR",
]

#: Data this many times below the weakest soil (median over the samples) or a row this many times
#: above the strongest are not a soil within the bounds.
SCALE_FACTOR = 5.0
#: Robust z-score and share of the force scale (90th percentile of |F|) of a residual from which a
#: row is named as a likely outlier, and from which it spoils the fit.
OUTLIER_Z, OUTLIER_SHARE = 8.0, 0.1
GROSS_Z, GROSS_SHARE = 10.0, 0.25
#: RMSE over the root-mean-square force above which the model does not describe the data.
RESIDUAL_RATIO = 0.5
#: F_max on a bound is unusable when the data ask for more than this factor beyond it.
BOUND_FACTOR = 2.0
#: F_max within this share of the range the bounds allow from either end counts as on that bound.
LIMIT_BAND = 1e-3
#: Fewest samples for a robust residual scale (median absolute deviation).
MIN_ROBUST = 6
#: Relative slack of :func:`screen_expr`: rounding never lets the screen pass data a check would flag.
SCREEN_SLACK = 1e-9


def _fmt_force(x: float) -> str:
    return format_value(x, "N", 3)


def _rows(idx, limit: int = 5) -> str:
    rows = [int(k) + 1 for k in idx]
    text = ", ".join(str(r) for r in rows[:limit])
    return text + (f" and {len(rows) - limit} more" if len(rows) > limit else "")


def corner_curves(slip, load, vehicle: Vehicle, model: str, bounds: SoilBounds) -> tuple[np.ndarray, np.ndarray]:
    """Thrust (N) of the weakest and of the strongest soil within the bounds at each sample (one CasADi call).

    The compiled engine computes the same curves in its residual Function and passes them to
    :func:`assess` (``curves``), which then skips this call.
    """
    slip, load = np.asarray(slip, dtype=float).ravel(), np.asarray(load, dtype=float).ravel()
    n = slip.size
    weak, strong = corner_soils(bounds, model)
    both = thrust_at(
        np.tile(slip, 2),
        np.repeat([weak[0], strong[0]], n),
        np.repeat([weak[1], strong[1]], n),
        np.repeat([weak[2], strong[2]], n),
        np.tile(load, 2),
        vehicle,
        model,
    )
    return both[:n], both[n:]


def _median(x: np.ndarray, finite: bool = False) -> float:
    """``np.median`` of a 1-D array, the same number without its generic machinery (NaN if any is NaN;
    ``finite=True``: the caller knows there is none)."""
    n = x.size
    h = n // 2
    part = x.copy()  # np.partition without its wrapper
    if n % 2:
        part.partition(h)
        m = float(part[h])
    else:
        part.partition((h - 1, h))
        m = (float(part[h - 1]) + float(part[h])) / 2.0
    return m if finite or not np.logical_or.reduce(np.isnan(x)) else math.nan


def _quantile(x: np.ndarray, q: float) -> float:
    """``np.quantile(x, q)`` (linear interpolation) of a finite 1-D array, the same arithmetic as numpy's."""
    n = x.size
    virtual = (n - 1) * q
    if virtual >= n - 1:
        return float(np.max(x))
    lo = int(math.floor(virtual))
    t = virtual - lo
    part = x.copy()
    part.partition((lo, lo + 1))
    a, b = part[lo], part[lo + 1]
    d = b - a
    return float(b - d * (1 - t)) if t >= 0.5 else float(a + d * t)


_MIN, _MAX = np.minimum.reduce, np.maximum.reduce  # x.min(), x.max() without their Python wrappers


def _vec(a) -> np.ndarray:
    """``np.asarray(a, dtype=float).ravel()`` (the array itself when it already is one)."""
    if type(a) is np.ndarray and a.ndim == 1 and a.dtype == np.float64:
        return a
    return np.asarray(a, dtype=float).ravel()


def _all_finite(x: np.ndarray) -> bool:
    """Whether every entry is finite (``np.isfinite(x).all()`` in two ufunc calls)."""
    return bool(np.logical_and.reduce(np.isfinite(x), axis=None))


def _mean_square(x: np.ndarray) -> float:
    """``np.mean(x ** 2)`` (the same sum and division)."""
    return float(np.add.reduce(x * x)) / x.size


def screen_expr(slip, force, residuals, weak, strong, real):
    """CasADi expression: 1 when :func:`assess` may find more than an F_max on a bound, else 0.

    A necessary condition of each check, written so that it can run where the residuals are
    computed (the compiled engine's residual Function), and a clean fit then skips the numpy
    checks; a 1 runs them all, so what is found and said is decided by the checks below alone.
    0 needs every number finite and: every force at positive slip above ``1/SCALE_FACTOR`` of
    the weakest soil's (so their median is too), none above ``SCALE_FACTOR`` times the
    strongest's, none negative, ``sum r^2 <= RESIDUAL_RATIO^2 sum F^2``, and a residual range
    ``max r - min r`` (a bound of every ``|r - median(r)|``) within the smaller outlier share of
    a lower bound of the force scale (enough rows with ``|F|`` above it to put the 90th
    percentile there). All with :data:`SCREEN_SLACK` against rounding.

    Parameters
    ----------
    slip, force, residuals, weak, strong : casadi.MX or SX, row vectors
        Per row: slip, measured force (N), model minus data (N), the weakest and strongest
        soil's thrust (N) (:func:`corner_curves`).
    real : same shape
        Positive for a data row (e.g. its weight ``1/sigma``), 0 for a padding row (ignored).
    """
    e = SCREEN_SLACK
    big = ca.inf
    on = real > 0
    pos = ca.logic_and(on, slip > 0)
    vals = ca.vertcat(force, residuals, weak, strong)
    finite = ca.sum2(ca.if_else(on, 4 - ca.sum1(ca.fabs(vals) < big), 0)) == 0  # NaN fails every comparison
    low = ca.mmin(ca.if_else(pos, SCALE_FACTOR * force - weak * (1 + e), big)) < 0
    above = ca.mmax(ca.if_else(pos, force - SCALE_FACTOR * strong, -big)) > 0
    negative = ca.mmin(ca.if_else(on, force, big)) < 0
    large = ca.sum2(ca.if_else(on, residuals * residuals, 0)) > RESIDUAL_RATIO**2 * (1 - e) * ca.sum2(
        ca.if_else(on, force * force, 0)
    )
    n = ca.sum2(ca.if_else(on, 1, 0))
    spread = ca.mmax(ca.if_else(on, residuals, -big)) - ca.mmin(ca.if_else(on, residuals, big))
    level = spread * (1 + e) / min(OUTLIER_SHARE, GROSS_SHARE)
    high = ca.sum2(ca.if_else(ca.logic_and(on, ca.fabs(force) >= level), 1, 0))
    outlier = ca.logic_and(n >= MIN_ROBUST, high < n - ca.floor(0.9 * (n - 1)))
    return ca.logic_or(
        ca.logic_not(finite), ca.logic_or(ca.logic_or(low, above), ca.logic_or(negative, ca.logic_or(large, outlier)))
    )


def limit_screen_expr(c, phi, load, weak, strong, area, model: str, real):
    """CasADi expression: 0 when the F_max-on-a-bound check of :func:`assess` surely finds nothing, else 1.

    The necessary condition of that check, to run where the residuals are computed (the
    compiled engine's residual Function) next to :func:`screen_expr`: with both 0 a clean fit
    skips every numpy check. 0 needs, at every data row's load ``W``, the fitted soil's
    ``F_max = max_thrust_expr(c, phi, W)`` finite and farther than the band of
    :data:`LIMIT_BAND` (plus :data:`SCREEN_SLACK` of the magnitudes, against rounding) from both
    ends of the range ``[F_max(weak), F_max(strong)]`` the bounds allow (:func:`fmax_range`).

    Parameters
    ----------
    c, phi : casadi.MX or SX scalars
        The reported soil (SI).
    load, real : row vectors
        Normal load per row (N); positive ``real`` for a data row, 0 for a padding row.
    weak, strong : sequences ``(c, phi, ...)``
        The weakest and strongest soil within the bounds (:func:`corner_soils`).
    area : float or expression
        Contact area ``A`` (m^2); ``model``: ``"full"`` or ``"cohesion-free"``.
    """
    fm = max_thrust_expr(c, phi, load, area, model)
    lo = max_thrust_expr(weak[0], weak[1], load, area, model)
    hi = max_thrust_expr(strong[0], strong[1], load, area, model)
    tol = LIMIT_BAND * (hi - lo)
    slack = SCREEN_SLACK * (ca.fabs(fm) + ca.fabs(lo) + ca.fabs(hi))
    clear = ca.logic_and(fm > lo + tol + slack, fm < hi - tol - slack)  # NaN: not clear
    return ca.sum2(ca.if_else(real > 0, 1 - clear, 0)) > 0


def check_slip_data(
    slip, force, load, vehicle: Vehicle, model: str, bounds: SoilBounds, curves: tuple | None = None
) -> list[Finding]:
    """Checks that need no fit: the force scale against the bounds, and negative thrust.

    Parameters
    ----------
    slip, force, load : array_like
        Slip (-), tractive force (N) and normal load (N) per sample.
    vehicle, model, bounds
        As in the fit; the bounds define "any soil".
    curves : (ndarray, ndarray), optional
        :func:`corner_curves` at every sample, if already computed.
    """
    slip, force, load = _vec(slip), _vec(force), _vec(load)
    out: list[Finding] = []
    pos = slip > 0
    n_pos = int(np.count_nonzero(pos))
    if not n_pos:
        return out
    every = n_pos == slip.size
    if curves is None:
        lo, hi = corner_curves(slip if every else slip[pos], load if every else load[pos], vehicle, model, bounds)
    else:
        lo, hi = _vec(curves[0]), _vec(curves[1])
        if not every:
            lo, hi = lo[pos], hi[pos]
    f = force if every else force[pos]
    ratio = _median(f / lo)
    if ratio < 1.0 / SCALE_FACTOR:
        W = _median(load)
        out.append(
            Finding(
                "force_scale_low",
                f"the forces are about {1 / max(ratio, 1e-12):.3g} times smaller than the weakest soil "
                "within the bounds "
                f"gives at these slips (W = {_fmt_force(W)}; largest measured {_fmt_force(float(np.max(force)))}, the "
                f"weakest soil reaches {_fmt_force(float(np.max(lo)))}): are they in kN in an N column, or is the "
                "normal load or the vehicle wrong?",
                usable=False,
            )
        )
    above = np.nonzero(pos)[0][f > SCALE_FACTOR * hi] if not every else np.nonzero(f > SCALE_FACTOR * hi)[0]
    if above.size:
        k = int(above[0])
        hi_k = float(hi[np.nonzero(pos)[0] == k][0])
        out.append(
            Finding(
                "force_above_any_soil",
                f"row(s) {_rows(above)}: the tractive force ({_fmt_force(float(force[k]))} in row {k + 1}) "
                f"is more than {SCALE_FACTOR:g} times what the strongest soil within the bounds gives at "
                f"that slip and load ({_fmt_force(hi_k)}): a typo, a unit error or the wrong normal load?",
                usable=False,
                rows=tuple(int(r) + 1 for r in above),
            )
        )
    neg = np.nonzero(pos & (force < 0))[0] if _MIN(force) < 0 else np.zeros(0, dtype=np.intp)
    if len(neg):
        k = int(neg[0])
        out.append(
            Finding(
                "negative_thrust",
                f"row(s) {_rows(neg)}: negative tractive force at positive slip ({_fmt_force(float(force[k]))} at "
                f"i = {slip[k]:.3g} in row {k + 1}); a driving track pushes forward: a sign error or a braking sample?",
                usable=True,
                rows=tuple(int(r) + 1 for r in neg),
            )
        )
    return out


def _limit_on_bound(
    force: np.ndarray,
    load: np.ndarray,
    r: np.ndarray,
    c: float,
    phi: float,
    K: float,
    vehicle: Vehicle,
    model: str,
    bounds: SoilBounds,
) -> list[Finding]:
    """The F_max-on-a-bound finding of :func:`check_slip_fit` (finite ``theta`` and residuals)."""
    out: list[Finding] = []
    if not (c >= 0 and 0 < phi < math.pi / 2 and K > 0):  # not a soil (what :class:`Soil` accepts)
        return out
    single = _MIN(load) == _MAX(load)
    if not single and continuous_load(load):  # a measured load: one check over all rows, said once
        return _limit_on_bound_range(force, load, r, c, phi, vehicle, model, bounds)
    for W in load[:1] if single else np.unique(load):
        fm = float(max_thrust_expr(c, phi, float(W), vehicle.contact_area, model))
        fm_lo, fm_hi = fmax_range(bounds, vehicle, model, float(W))
        tol = LIMIT_BAND * (fm_hi - fm_lo)
        side = "smallest" if fm <= fm_lo + tol else "largest" if fm >= fm_hi - tol else None
        if not side or fm <= 0:
            continue
        sel = load == W
        # the F_max these data ask for with the fitted curve's shape: F = F_max g(i), g = model / F_max,
        # so the unbounded best F_max is the least-squares scale sum(g F) / sum(g^2)
        fs = force if single else force[sel]
        g = (fs + (r if single else r[sel])) / fm
        gg = np.add.reduce(g * g)  # (np.sum's reduction without its wrapper)
        wanted = float(np.add.reduce(g * fs) / gg) if gg > 0 else fm
        out.append(_limit_finding(fm, float(W), side, wanted))
    return out


def _limit_finding(fm: float, W: float, side: str, wanted: float, W_text: str | None = None) -> Finding:
    """The F_max-on-a-bound finding: F_max ``fm`` at load ``W`` on the ``side`` ("smallest"/"largest") the
    bounds allow, where the data ask for ``wanted``; not usable beyond :data:`BOUND_FACTOR`. ``W_text``:
    ``W`` written already (``_fmt_force(W)``, for many findings at one load)."""
    far = wanted < fm / BOUND_FACTOR if side == "smallest" else wanted > fm * BOUND_FACTOR
    return Finding(
        "limit_on_bound",
        f"the thrust limit F_max = {_fmt_force(fm)} at W = {W_text or _fmt_force(W)} is the {side} value the "
        f"bounds allow (c and phi at their {'lower' if side == 'smallest' else 'upper'} bounds); the data ask "
        f"for about {_fmt_force(wanted)}"
        + (
            ": the bounds, not the data, fixed the answer; check the units of the force and the normal load"
            if far
            else ": the soil lies at or just beyond the bounds; widen them if that is physically reasonable"
        ),
        usable=not far,
    )


def assess_many(
    problems: list,
    solutions: list,
    vehicle: Vehicle,
    model: str,
    bounds: SoilBounds,
    stacked: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> list[tuple]:
    """:func:`assess` of many certified compiled solves of one length (``fit_many``'s batch): the same verdicts.

    The rows the solver's screens clear (``screen`` 0, finite ``theta``), with every load within
    :data:`LOAD_FACTOR` of the vehicle's weight and one load per dataset, are decided for all at once: no
    finding where the limit screen is 0 too, else F_max against the bounds (:func:`_limit_on_bound`'s
    numbers, stacked); every other row goes through :func:`assess`. ``stacked``: ``(theta, load,
    residuals)`` of the solutions and problems as stacked arrays, when the caller has them.
    """
    N = len(problems)
    if stacked is None:
        theta, L, R_all = np.stack([s.theta for s in solutions]), np.stack([pb.load for pb in problems]), None
    else:
        theta, L, R_all = stacked
    W = float(vehicle.weight)
    lo, hi = np.minimum.reduce(L, axis=1), np.maximum.reduce(L, axis=1)
    c, phi, K = theta[:, 0], theta[:, 1], theta[:, 2]
    fast = np.array([s.screen is not None and s.screen < 0.5 for s in solutions]) & np.isfinite(theta).all(axis=1)
    fast &= (lo == hi) & ((lo * LOAD_FACTOR >= W) & (hi <= LOAD_FACTOR * W) if W > 0 else True)  # check_loads: none
    clear = np.array([s.limit_screen is not None and s.limit_screen < 0.5 for s in solutions]) & fast
    soil = (c >= 0) & (0 < phi) & (phi < math.pi / 2) & (K > 0)  # what _limit_on_bound checks (a soil)
    out: list[tuple | None] = [((), True) if ok else None for ok in clear.tolist()]
    todo = np.nonzero(fast & ~clear & soil)[0]
    if todo.size:
        fm = max_thrust_expr(c[todo], phi[todo], lo[todo], vehicle.contact_area, model)
        rng = np.array([fmax_range(bounds, vehicle, model, w) for w in lo[todo].tolist()]).reshape(-1, 2)
        tol = LIMIT_BAND * (rng[:, 1] - rng[:, 0])
        low, high = fm <= rng[:, 0] + tol, fm >= rng[:, 1] - tol
        F = np.stack([problems[k].force for k in todo.tolist()])
        R = R_all[todo] if R_all is not None else np.stack([solutions[k].residuals for k in todo.tolist()])
        with np.errstate(all="ignore"):
            g = (F + R) / fm[:, None]
            gg = np.add.reduce(g * g, axis=1)
            wanted = np.where(gg > 0, np.add.reduce(g * F, axis=1) / gg, fm)
        texts: dict[float, str] = {}  # each load written once (one vehicle: one load)
        for j, k in enumerate(todo.tolist()):
            side = "smallest" if low[j] else "largest" if high[j] else None
            if not side or fm[j] <= 0:
                out[k] = ((), True)
                continue
            W_k = float(lo[k])
            W_text = texts.get(W_k)
            if W_text is None:
                W_text = texts[W_k] = _fmt_force(W_k)
            f = _limit_finding(float(fm[j]), W_k, side, float(wanted[j]), W_text)
            out[k] = ((("NOT USABLE: " if not f.usable else "") + f.message,), f.usable)
    for k in np.nonzero(fast & ~clear & ~soil)[0].tolist():
        out[k] = ((), True)  # not a soil: _limit_on_bound finds nothing, and the screens found nothing else
    for k in range(N):
        if out[k] is None:
            pb, s = problems[k], solutions[k]
            out[k] = assess(
                pb.slip,
                pb.force,
                pb.load,
                s.residuals,
                s.theta,
                vehicle,
                model,
                bounds,
                s.curves,
                s.screen,
                s.limit_screen,
            )
    return out  # type: ignore[return-value]


def _limit_on_bound_range(
    force: np.ndarray,
    load: np.ndarray,
    r: np.ndarray,
    c: float,
    phi: float,
    vehicle: Vehicle,
    model: str,
    bounds: SoilBounds,
) -> list[Finding]:
    """The F_max-on-a-bound check for a load varying row to row: one finding for all rows.

    F_max is on a bound at every load when it is at one (c and phi both at their lower or both
    at their upper bounds); the scale the data ask for is fitted over all rows at once (one row
    alone carries the noise of one reading, not a verdict).
    """
    W = _vec(load)
    fm = np.asarray(max_thrust_expr(c, phi, W, vehicle.contact_area, model), dtype=float)
    lo_hi = np.array([fmax_range(bounds, vehicle, model, float(w)) for w in (W.min(), W.max())])
    lo = np.interp(W, [W.min(), W.max()], lo_hi[:, 0])  # F_max is affine in W: exact between the ends
    hi = np.interp(W, [W.min(), W.max()], lo_hi[:, 1])
    tol = LIMIT_BAND * (hi - lo)
    side = "smallest" if np.all(fm <= lo + tol) else "largest" if np.all(fm >= hi - tol) else None
    if not side or np.any(fm <= 0):
        return []
    m = force + r  # the fitted curve at each row; the data ask for it scaled by sum(m F) / sum(m^2)
    scale = float(np.sum(m * force) / np.sum(m * m)) if np.sum(m * m) > 0 else 1.0
    far = scale < 1 / BOUND_FACTOR if side == "smallest" else scale > BOUND_FACTOR
    return [
        Finding(
            "limit_on_bound",
            f"the thrust limit F_max = {_fmt_force(float(fm.min()))} to {_fmt_force(float(fm.max()))} over the loads "
            f"W = {_fmt_force(float(W.min()))} to {_fmt_force(float(W.max()))} is the {side} value the bounds allow (c "
            f"and phi at their {'lower' if side == 'smallest' else 'upper'} bounds); the data, all rows together, ask "
            f"for about {scale:.3g} times that"
            + (
                ": the bounds, not the data, fixed the answer; check the units of the force and the normal load"
                if far
                else ": the soil lies at or just beyond the bounds; widen them if that is physically reasonable"
            ),
            usable=not far,
        )
    ]


def check_slip_fit(
    slip, force, load, residuals, theta, vehicle: Vehicle, model: str, bounds: SoilBounds
) -> list[Finding]:
    """Checks of a fit's answer: F_max on a bound, residuals as large as the data, gross outliers.

    ``residuals`` are model minus data (N) at the fitted ``theta = [c (Pa), phi (rad), K (m)]``.
    """
    slip, force, load, r = _vec(slip), _vec(force), _vec(load), _vec(residuals)
    c, phi, K = np.asarray(theta, dtype=float).ravel().tolist()
    if not (math.isfinite(c) and math.isfinite(phi) and math.isfinite(K) and _all_finite(r)):
        return []
    out = _limit_on_bound(force, load, r, c, phi, K, vehicle, model, bounds)
    # residuals as large as the data
    scale = math.sqrt(_mean_square(force)) if force.size else 0.0
    rmse = math.sqrt(_mean_square(r)) if r.size else 0.0
    if scale > 0 and rmse > RESIDUAL_RATIO * scale:
        out.append(
            Finding(
                "residuals_large",
                f"the residuals are as large as the data (RMSE {_fmt_force(rmse)}, data {_fmt_force(scale)} root mean "
                "square): the model does not describe these data",
                usable=False,
            )
        )
    # gross outliers: far out in robust z-score AND a sizeable share of the force scale (the noise
    # of a thrust-slip sweep is not constant - slip noise on the steep part of the curve gives
    # large force residuals - so a z-score alone flags clean data)
    if r.size >= MIN_ROBUST:
        med = _median(r, finite=True)
        dev = np.abs(r - med)
        mad = MAD_TO_SIGMA * _median(dev, finite=True)
        size = _quantile(np.abs(force), 0.9)  # the data's force scale, robust to a few wild rows
        az = dev / max(mad, 1e-6 * size, 1e-300)  # |robust z-score|
        if _MAX(az) > min(OUTLIER_Z, GROSS_Z):  # else no row is an outlier of either kind
            share = dev / max(size, 1e-300)
            is_gross = (az > GROSS_Z) & (share > GROSS_SHARE)
            gross = np.nonzero(is_gross)[0]
            odd = np.nonzero((az > OUTLIER_Z) & (share > OUTLIER_SHARE) & ~is_gross)[0]  # the rest, in row order
        else:
            gross = odd = np.empty(0, dtype=np.intp)
        if gross.size and gross.size <= max(1, r.size // 4):
            k = int(gross[np.argmax(az[gross])])
            out.append(
                Finding(
                    "outlier",
                    f"row(s) {_rows(gross)} lie far off the rest (row {k + 1}: {_fmt_force(float(force[k]))} at "
                    f"i = {slip[k]:.3g}, off the fitted curve by {_fmt_force(abs(float(r[k])))}, {az[k]:.3g} robust "
                    "standard deviations): the fit is pulled by it; correct or remove the row and fit again",
                    usable=False,
                    rows=tuple(int(g) + 1 for g in gross),
                )
            )
        if odd.size and odd.size <= max(1, r.size // 4):
            out.append(
                Finding(
                    "outlier",
                    f"row(s) {_rows(odd)} look like outliers (off the fitted curve by more than {OUTLIER_Z:g} robust "
                    f"standard deviations and {OUTLIER_SHARE:.0%} of the force scale)",
                    usable=True,
                    rows=tuple(int(g) + 1 for g in odd),
                )
            )
    return out


def assess(
    slip,
    force,
    load,
    residuals,
    theta,
    vehicle: Vehicle,
    model: str,
    bounds: SoilBounds,
    curves: tuple | None = None,
    screen: float | None = None,
    limit_screen: float | None = None,
) -> tuple[tuple[str, ...], bool]:
    """All checks: ``(warnings, usable)``; ``usable`` is False when any finding makes the answer unusable.

    Each cause is said once: rows already refused at input are not named again as outliers, and
    "residuals as large as the data" is left out when an input finding or an outlier explains it.
    ``curves``: :func:`corner_curves` at every sample, if the caller has them (the compiled engine).
    ``screen``: :func:`screen_expr` of these very numbers, if the caller has it (the compiled
    engine); 0 means no check but F_max on a bound can find anything, and only that one runs.
    ``limit_screen``: :func:`limit_screen_expr` at ``theta``, if the caller has it; 0 (with
    ``screen`` 0) means that one has nothing to find either: no finding, usable.
    """
    loads = check_loads(load, vehicle)  # not part of the screens: cheap, and always run
    if screen is not None and screen < 0.5:
        c, phi, K = np.asarray(theta, dtype=float).ravel().tolist()
        if math.isfinite(c) and math.isfinite(phi) and math.isfinite(K):  # (the screen saw finite residuals)
            if limit_screen is not None and limit_screen < 0.5 and not loads:
                return (), True
            slip, force, load = _vec(slip), _vec(force), _vec(load)
            found = loads + (
                []
                if limit_screen is not None and limit_screen < 0.5
                else _limit_on_bound(force, load, _vec(residuals), c, phi, K, vehicle, model, bounds)
            )
            return tuple(("NOT USABLE: " if not f.usable else "") + f.message for f in found), all(
                f.usable for f in found
            )
    slip, force, load = _vec(slip), _vec(force), _vec(load)
    found = loads + check_slip_data(slip, force, load, vehicle, model, bounds, curves)
    named = {r for f in found if not f.usable for r in f.rows}
    after = check_slip_fit(slip, force, load, residuals, theta, vehicle, model, bounds)
    for f in sorted(after, key=lambda f: f.code == "residuals_large") if after else ():
        if f.code == "outlier" and set(f.rows) <= named:
            continue
        if f.code == "residuals_large" and any(not g.usable for g in found if g.code != "limit_on_bound"):
            continue
        found.append(f)
        if not f.usable:
            named |= set(f.rows)
    usable = all(f.usable for f in found)
    return tuple(("NOT USABLE: " if not f.usable else "") + f.message for f in found), usable


def slip_checks(samples, residuals, theta, normal_loads, vehicle: Vehicle, model: str, bounds: SoilBounds):
    """The plausibility checks' verdict on a slip fit, ``(warnings, usable)``, for ``build_result(plausibility=...)``.

    ``samples``: ``(slip, thrust_N, load_N)`` per sample, optionally followed by the weakest and strongest
    soil's thrust at each sample ``(F_weak, F_strong)`` when the solver has them (:func:`corner_curves`) and
    the solver's screen of them (:func:`screen_expr`) and of F_max on a bound (:func:`limit_screen_expr`):
    then :func:`assess` runs. None (a fit without the checks of the data: joint fits, a failed batch item):
    the loads against the vehicle all the same (:func:`check_loads`).
    """
    if samples is not None:
        slip, thrust, load, *curves = samples
        return assess(slip, thrust, load, residuals, theta, vehicle, model, bounds, *curves)
    loads = check_loads(normal_loads, vehicle)
    return tuple("NOT USABLE: " + f.message for f in loads), not loads
