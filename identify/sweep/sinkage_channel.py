"""The measured sinkage of a track sweep (``sinkage_m``) fitted with the library's sinkage laws.

The laws have one home, :mod:`soiltrack.soilmodel.sinkage`: static Bekker sinkage of the track
``z0 = (p / k) ^ (1 / n)`` at the pressure ``p = W / A`` with ``k = k_c / b + k_phi`` at the
track's width b (:func:`~soiltrack.soilmodel.sinkage.sinkage_expr`), and the slip sinkage
``z = z0 L(i) ^ s`` with Lyasko's factor ``L(i) = (1 + i) / (1 - 0.5 i)`` and a free exponent s
(:func:`~soiltrack.soilmodel.sinkage.slip_sinkage_expr`: ``s = 1`` is Lyasko's law, ``s = 0`` a
sinkage that does not grow with the slip). This module builds the residual
``log z_model - log z_measured`` of each row from those CasADi expressions and solves it by
Gauss-Newton (multiplicative reading errors: a constant relative error of the sinkage). The
solver's parameters are ``a = log z0(W_ref)`` (the static sinkage at the rows' median load
``W_ref``), ``m = 1 / n`` and ``s``. In them the log-residual is linear (the laws are power
laws), so Gauss-Newton converges in one step and the Student-t intervals are exact for that
noise model; ``n = 1 / m`` takes the transformed interval of m and ``k`` a Fieller interval.

What the rows identify:

- always ``z0`` at ``W_ref`` (the level of the sinkage);
- ``n`` and ``k`` only when the load spreads (:data:`MIN_LOG_LOAD_SPREAD`) enough for the
  interval of 1 / n to exclude 0: at one load n and k enter only through z0;
- never k_c and k_phi apart: a track has one width, so only ``k_c / b + k_phi`` (the JSON's
  ``bekker_k_eq``); ``bekker_kc`` and ``bekker_kphi`` are reported not identifiable;
- the slip exponent s when the slip spreads, with the p-values of "no slip sinkage" (s = 0) and
  of "Lyasko's law" (s = 1): :func:`slip_sinkage_evidence` hands them to the diagnosis.

With the ``slip_sinkage`` effect in the thrust fit (a resistance ``W mu_s i``),
:func:`compare_slip_resistance` gives the slip coefficient that Bekker compaction of the measured
ruts implies (:func:`~soiltrack.soilmodel.sinkage.compaction_at_sinkage_expr` at the fitted
sinkage against the static one) beside the thrust fit's, with a test of their agreement.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from ...soilmodel.data import SlipData
from ...soilmodel.threadsafe import locked_cache
from ...soilmodel.sinkage import compaction_at_sinkage_expr, sinkage_expr, slip_sinkage_expr
from ...soilmodel.vehicle import Vehicle
from ..estimates.least_squares import RANK_TOL
from ..estimates.records import ParameterEstimate
from ..estimates.distributions import norm_cdf, t_cdf, t_ppf

__all__ = [
    "MIN_LOG_LOAD_SPREAD",
    "MIN_LOG_SLIP_SPREAD",
    "MIN_SINKAGE_ROWS",
    "RANK_TOL",
    "GN_MAX_ITER",
    "GN_STEP_TOL",
    "SLIP_SINKAGE_ALPHA",
    "SinkageChannelFit",
    "SlipSinkageEvidence",
    "fit_sinkage_channel",
    "slip_sinkage_evidence",
    "compare_slip_resistance",
]

#: Standard deviation of log(W) below which the rows carry no information on n (one load).
MIN_LOG_LOAD_SPREAD = 1e-6
#: Standard deviation of log L(i) (Lyasko's factor) below which the rows carry none on the slip
#: exponent (one slip); the exponent is then held at Lyasko's 1.
MIN_LOG_SLIP_SPREAD = 1e-6
#: Fewest rows with a positive sinkage and a driving slip for a fit (three coefficients and a dof).
MIN_SINKAGE_ROWS = 4
#: Smallest singular value of the column-scaled Jacobian, relative to the largest, of a full rank: the
#: library's one rank tolerance, imported from :mod:`soiltrack.identify.estimates.least_squares`.
#: Gauss-Newton iterations at most (the log-residual is linear in the solver's parameters: one suffices).
GN_MAX_ITER = 20
#: Gauss-Newton stops when the step is below this, relative to ``1 + |theta|``.
GN_STEP_TOL = 1e-10
#: Level of the tests (slip sinkage found, Lyasko's law refuted, channel and thrust fit disagree).
SLIP_SINKAGE_ALPHA = 0.05

_A, _M, _S = 0, 1, 2  # solver parameters: log z0(W_ref), 1 / n, slip exponent
_HELD = (0.0, 1.0, 1.0)  # values of a held parameter (m at one load: any; s at one slip: Lyasko's)


@locked_cache(maxsize=32)
def _row_function(track_length: float, track_width: float) -> ca.Function:
    """``(theta[3], W, i, W_ref) -> (log z_model, d log z_model / d theta)`` from soilmodel's laws."""
    th, W, i, W_ref = ca.SX.sym("theta", 3), ca.SX.sym("W"), ca.SX.sym("i"), ca.SX.sym("W_ref")
    n = 1 / th[_M]
    # sinkage at unit k: k enters the law as p / k, so the ratio to W_ref's carries n alone
    ratio = sinkage_expr(W, n, 0.0, 1.0, track_length, track_width) / sinkage_expr(
        W_ref, n, 0.0, 1.0, track_length, track_width
    )
    log_z = ca.log(slip_sinkage_expr(ca.exp(th[_A]) * ratio, i, th[_S]))
    return ca.Function("log_sinkage", [th, W, i, W_ref], [log_z, ca.jacobian(log_z, th)])


@locked_cache(maxsize=32)
def _k_function(track_length: float, track_width: float) -> ca.Function:
    """``(theta, W_ref) -> k`` (N/m^(n+2)): the k at which the law gives ``z0 = exp(a)`` at ``W_ref``."""
    th, W_ref = ca.SX.sym("theta", 3), ca.SX.sym("W_ref")
    n = 1 / th[_M]
    z_unit = sinkage_expr(W_ref, n, 0.0, 1.0, track_length, track_width)  # = (p / 1) ^ (1 / n)
    k = (z_unit / ca.exp(th[_A])) ** n  # (p / k) ^ (1 / n) = z0  <=>  k = (z_unit / z0) ^ n
    return ca.Function("k_eq", [th, W_ref], [k, ca.jacobian(k, th)])


def _num(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(float(x)) else float(x)


@dataclass(frozen=True)
class SinkageChannelFit:
    """The sinkage laws fitted to a sweep's ``sinkage_m`` (see the module docs).

    Attributes
    ----------
    converged, iterations
        Gauss-Newton's word: the step fell below :data:`GN_STEP_TOL` within :data:`GN_MAX_ITER`.
    n_rows, rows_left_out
        Rows fitted; rows without a positive sinkage (a log needs one) or at a skid slip.
    dof
        Residual degrees of freedom.
    reference_load
        ``W_ref``, N: the rows' median load (z0 is the static sinkage there).
    z0, z0_ci95
        Static sinkage at ``W_ref``, m, and its 95 % interval.
    relative_error
        The rows' relative scatter about the laws (rms of the log-residuals).
    parameters
        ``{key: ParameterEstimate}``: ``bekker_kc``, ``bekker_kphi``, ``bekker_n``, ``bekker_k_eq``,
        ``slip_sinkage_exponent``.
    p_no_slip_sinkage, p_lyasko
        p-values of ``s = 0`` and ``s = 1`` (Student t), ``None`` when s is not fitted.
    free
        Which of ``(a, m, s)`` were fitted (m held at one load, s at one slip).
    notes
        Plain words: what is identified and what not, and why.
    theta, covariance
        Solver parameters ``(log z0(W_ref), 1 / n, s)`` and their covariance (zeros where held).
    """

    converged: bool
    iterations: int
    n_rows: int
    rows_left_out: int
    dof: int
    reference_load: float
    track_length: float
    track_width: float
    z0: float
    z0_ci95: tuple[float | None, float | None]
    relative_error: float
    parameters: dict[str, ParameterEstimate]
    p_no_slip_sinkage: float | None
    p_lyasko: float | None
    free: tuple[bool, bool, bool]
    notes: tuple[str, ...]
    theta: np.ndarray = field(repr=False)
    covariance: np.ndarray | None = field(repr=False)

    @property
    def n_identifiable(self) -> bool:
        """Bekker n (and with it k = k_c / b + k_phi) is pinned down by the rows."""
        return self.parameters["bekker_n"].identifiable

    def predict(self, slip, normal_load) -> np.ndarray:
        """The fitted laws' sinkage (m) at the given slips and loads (soilmodel's expressions)."""
        i = np.asarray(slip, dtype=float).ravel()
        W = np.broadcast_to(np.asarray(normal_load, dtype=float), i.shape).ravel()
        log_z, _ = _evaluate((self.track_length, self.track_width), self.theta, W, i, self.reference_load)
        return np.exp(log_z)

    def statement(self) -> str:
        """One line of plain words with the numbers."""
        lo, hi = self.z0_ci95
        ci = f"95 % [{1e3 * lo:.3g}, {1e3 * hi:.3g}] mm" if lo is not None and hi is not None else "no interval"
        head = (
            "" if self.converged else f"Gauss-Newton did NOT converge ({self.iterations} iterations): "
        ) + f"static Bekker sinkage z0 = {1e3 * self.z0:.3g} mm at W = {self.reference_load:.4g} N, {ci}"
        n, k = self.parameters["bekker_n"], self.parameters["bekker_k_eq"]
        if n.identifiable and n.value is not None and k.edge_value is not None:
            k_lo, k_hi = k.edge_ci95
            head += (
                f"; n = {n.value:.3g} [{_fmt(n.ci95[0])}, {_fmt(n.ci95[1])}], k_c / b + k_phi = {k.edge_value:.4g} "
                f"[{_fmt(k_lo)}, {_fmt(k_hi)}] kN/m^(n+2) (k_c and k_phi do not separate at one track "
                "width)"
            )
        else:
            head += f"; n and k not identifiable ({n.note})"
        s = self.parameters["slip_sinkage_exponent"]
        if self.p_no_slip_sinkage is not None and self.p_lyasko is not None and s.value is not None:
            grows = "grows with the slip" if self.p_no_slip_sinkage < SLIP_SINKAGE_ALPHA else "shows no slip sinkage"
            law = "Lyasko's law refuted" if self.p_lyasko < SLIP_SINKAGE_ALPHA else "consistent with Lyasko's law"
            head += (
                f"; the sinkage {grows} (exponent of Lyasko's factor s = {s.value:.3g}, 95 % [{_fmt(s.ci95[0])}, "
                f"{_fmt(s.ci95[1])}]; p {_p(self.p_no_slip_sinkage)} for s = 0), {law} "
                f"(p {_p(self.p_lyasko)} for s = 1)"
            )
        else:
            head += f"; slip exponent not fitted ({s.note})"
        return head

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (``FitResult.extra["sinkage_m"]["laws"]``; its ``parameters`` join the fit's)."""
        return {
            "method": "gauss-newton on log sinkage (soilmodel.sinkage laws)",
            "converged": self.converged,
            "iterations": self.iterations,
            "n_rows": self.n_rows,
            "rows_left_out": self.rows_left_out,
            "dof": self.dof,
            "reference_load_N": self.reference_load,
            "z0_m": _num(self.z0),
            "z0_ci95_m": [_num(self.z0_ci95[0]), _num(self.z0_ci95[1])],
            "relative_error": _num(self.relative_error),
            "identifiable": ["z0"]
            + [k for k in ("bekker_n", "bekker_k_eq", "slip_sinkage_exponent") if self.parameters[k].identifiable],
            "parameters": {k: p.to_dict() for k, p in self.parameters.items()},
            "p_no_slip_sinkage": _num(self.p_no_slip_sinkage),
            "p_lyasko": _num(self.p_lyasko),
            "notes": list(self.notes),
            "statement": self.statement(),
        }


def _fmt(x: float | None) -> str:
    return "open" if x is None else f"{x:.4g}"


def _p(p: float) -> str:
    """A p-value as printed: below the double's resolution of 1 - cdf it is "< 1e-15"."""
    return "< 1e-15" if p < 1e-15 else f"= {p:.3g}"


@dataclass(frozen=True)
class SlipSinkageEvidence:
    """What a sweep's measured sinkage says about slip sinkage (for the diagnosis to weigh).

    Attributes
    ----------
    testable
        The test could be made (a ``sinkage_m`` column, enough rows, the slip spreads).
    exponent, stderr
        The fitted exponent s of Lyasko's factor ``z = z0(W) L(i) ^ s`` and its standard error.
    p_no_slip_sinkage
        p-value of "no slip sinkage" (``s = 0``: the sinkage independent of the slip at a given load).
    p_lyasko
        p-value of "Lyasko's law holds" (``s = 1``).
    n_rows, dof
        Rows used and the residual degrees of freedom.
    reason
        Why not testable (empty when testable).
    """

    testable: bool
    exponent: float | None
    stderr: float | None
    p_no_slip_sinkage: float | None
    p_lyasko: float | None
    n_rows: int
    dof: int
    reason: str = ""

    def found(self, alpha: float = SLIP_SINKAGE_ALPHA) -> bool:
        """Slip sinkage shown: testable, ``s > 0`` and "no slip sinkage" rejected at level ``alpha``."""
        return bool(
            self.testable
            and self.exponent is not None
            and self.exponent > 0
            and self.p_no_slip_sinkage is not None
            and self.p_no_slip_sinkage < alpha
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {
            "testable": self.testable,
            "exponent": _num(self.exponent),
            "stderr": _num(self.stderr),
            "p_no_slip_sinkage": _num(self.p_no_slip_sinkage),
            "p_lyasko": _num(self.p_lyasko),
            "n_rows": self.n_rows,
            "dof": self.dof,
            "found": self.found(),
            "reason": self.reason,
        }


@locked_cache(maxsize=64)
def _mapped_rows(track_length: float, track_width: float, n_rows: int) -> ca.Function:
    """:func:`_row_function` mapped over ``n_rows`` rows."""
    return _row_function(track_length, track_width).map(n_rows)


def _evaluate(geometry: tuple[float, float], theta: np.ndarray, W: np.ndarray, i: np.ndarray, W_ref: float):
    """Row values and Jacobian rows of :func:`_row_function` (one call over all rows)."""
    f = _mapped_rows(geometry[0], geometry[1], W.size)
    log_z, J = f(ca.DM(theta), W.reshape(1, -1), i.reshape(1, -1), W_ref)
    return np.asarray(log_z, dtype=float).ravel(), np.asarray(J, dtype=float).reshape(W.size, 3)


def _gauss_newton(geo, theta, free, W, i, lz, W_ref) -> tuple[np.ndarray, np.ndarray, int, bool]:
    """Gauss-Newton on the free parameters; returns theta, the last Jacobian, iterations, converged."""
    J = np.zeros((W.size, 3))
    for it in range(1, GN_MAX_ITER + 1):
        pred, J = _evaluate(geo, theta, W, i, W_ref)
        r = pred - lz
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(J))):
            return theta, J, it, False
        step = np.linalg.lstsq(J[:, free], -r, rcond=None)[0]
        theta = theta.copy()
        theta[free] += step
        if np.linalg.norm(step) <= GN_STEP_TOL * (1 + np.linalg.norm(theta)):
            _, J = _evaluate(geo, theta, W, i, W_ref)
            return theta, J, it, bool(np.all(np.isfinite(J)))
    return theta, J, GN_MAX_ITER, False


def _full_rank(J: np.ndarray) -> bool:
    norms = np.linalg.norm(J, axis=0)
    if np.any(norms == 0):
        return False
    sv = np.linalg.svd(J / norms, compute_uv=False)
    return bool(sv[-1] > RANK_TOL * sv[0])


def _p_two_sided(t: float, dof: int) -> float:
    """Two-sided p-value of Student's t with ``dof`` degrees of freedom (a Python float)."""
    return float(2.0 * (1.0 - t_cdf(float(t), dof)))


def _fieller(a: float, m: float, va: float, vm: float, cam: float, q: float) -> tuple[float, float] | None:
    """Interval of ``u = -a / m`` (``a + m u = 0``) at quantile q, or ``None`` when unbounded."""
    A2 = m * m - q * q * vm
    if A2 <= 0:
        return None
    B = a * m - q * q * cam
    C = a * a - q * q * va
    disc = B * B - A2 * C
    if disc < 0:
        return None
    root = math.sqrt(disc)
    return ((-B - root) / A2, (-B + root) / A2)


def fit_sinkage_channel(data: SlipData, vehicle: Vehicle) -> SinkageChannelFit | None:
    """Fit the Bekker and slip-sinkage laws to the sweep's measured sinkage.

    Parameters
    ----------
    data
        A track sweep with ``sinkage_m`` (the load per row, else the vehicle's weight).
    vehicle
        The track's geometry (length and width).

    Returns
    -------
    SinkageChannelFit or None
        ``None`` without a sinkage column or with fewer than :data:`MIN_SINKAGE_ROWS` rows at a
        positive sinkage and a driving slip.
    """
    if data.sinkage is None:
        return None
    z_all, i_all = np.asarray(data.sinkage, dtype=float), np.asarray(data.slip, dtype=float)
    W_all = np.asarray(data.loads(vehicle.weight), dtype=float)
    use = (z_all > 0) & (i_all >= 0)
    if np.count_nonzero(use) < MIN_SINKAGE_ROWS:
        return None
    z, i, W = z_all[use], i_all[use], W_all[use]
    W_ref = float(np.median(W))
    lz = np.log(z)
    l, b = float(vehicle.track_length), float(vehicle.track_width)
    geo = (l, b)
    notes: list[str] = []
    if int(np.count_nonzero(~use)):
        notes.append(f"{int(np.count_nonzero(~use))} rows without a positive sinkage or at a skid slip left out")
    load_spread = float(np.std(np.log(W / W_ref))) > MIN_LOG_LOAD_SPREAD
    slip_spread = float(np.std(np.log(np.asarray(slip_sinkage_expr(1.0, i), dtype=float)))) > MIN_LOG_SLIP_SPREAD
    free = np.array([True, load_spread, slip_spread])
    why_n = "" if load_spread else "one load: n and k enter only through the static sinkage z0 at that load"
    why_s = "" if slip_spread else "one slip: the exponent is held at Lyasko's 1 (z0 assumes Lyasko's law)"
    theta0 = np.array([float(np.mean(lz)), _HELD[_M], 0.0 if slip_spread else _HELD[_S]])
    _, J0 = _evaluate(geo, theta0, W, i, W_ref)
    if free[_M] and free[_S] and not _full_rank(J0[:, free]):
        # the load moves with the slip factor exactly: neither effect is identified; z0 then rests on
        # the held n = 1 and Lyasko's law
        free[_M] = free[_S] = False
        why_n = why_s = (
            "the load moves with the slip exactly: a load effect and a slip effect on the sinkage do not "
            "separate (z0 assumes n = 1 and Lyasko's law)"
        )
        theta0[_S] = _HELD[_S]
    theta, J, iters, converged = _gauss_newton(geo, theta0, free, W, i, lz, W_ref)
    dof = int(z.size - np.count_nonzero(free))
    pred, _ = _evaluate(geo, theta, W, i, W_ref)
    r = pred - lz
    rss = float(r @ r)
    cov: np.ndarray | None = None
    if converged and dof > 0 and _full_rank(J[:, free]):
        s2 = rss / dof
        cov = np.zeros((3, 3))
        cov[np.ix_(free, free)] = s2 * np.linalg.inv(J[:, free].T @ J[:, free])
    q = t_ppf(0.975, dof) if dof > 0 else math.nan
    a = float(theta[_A])
    se = np.sqrt(np.maximum(np.diag(cov), 0.0)) if cov is not None else np.full(3, math.nan)
    z0_ci = (math.exp(a - q * se[_A]), math.exp(a + q * se[_A])) if cov is not None else (None, None)
    params = _parameters(theta, cov, free, q, W_ref, l, b, why_n, why_s, notes)
    p0 = p1 = None
    if cov is not None and free[_S] and se[_S] > 0:
        s_hat = float(theta[_S])
        p0 = _p_two_sided(abs(s_hat) / se[_S], dof)
        p1 = _p_two_sided(abs(s_hat - 1.0) / se[_S], dof)
    if not converged:
        notes.append(f"Gauss-Newton did not converge in {iters} iterations: no intervals")
    return SinkageChannelFit(
        converged=converged,
        iterations=iters,
        n_rows=int(z.size),
        rows_left_out=int(np.count_nonzero(~use)),
        dof=dof,
        reference_load=W_ref,
        track_length=l,
        track_width=b,
        z0=math.exp(a),
        z0_ci95=z0_ci,
        relative_error=math.sqrt(rss / z.size),
        parameters=params,
        p_no_slip_sinkage=p0,
        p_lyasko=p1,
        free=(bool(free[0]), bool(free[1]), bool(free[2])),
        notes=tuple(notes),
        theta=theta,
        covariance=cov,
    )


def _sink(name: str, value, stderr, ci95, identifiable: bool, note: str = "") -> ParameterEstimate:
    """A sinkage-channel parameter record (SI; no bounds: a free Gauss-Newton fit)."""
    return ParameterEstimate(name, value, stderr, ci95, identifiable, note=note, source="sinkage_m")


def _parameters(theta, cov, free, q, W_ref, l, b, why_n, why_s, notes) -> dict[str, ParameterEstimate]:
    """The sinkage parameters (SI records; edge units in their JSON) from the solver's, with intervals."""
    a, m, s = (float(x) for x in theta)
    n_est = k_est = _sink("", None, None, (None, None), False)
    one_width = (
        f"k_c and k_phi never separate at one track width (b = {b:.4g} m): only k_c / b + k_phi (bekker_k_eq); "
        "plates or tracks of two widths separate them"
    )
    if free[_M]:
        if cov is None:
            why_n = "no intervals (see the notes)"
        else:
            va, vm, cam = cov[_A, _A], cov[_M, _M], cov[_A, _M]
            se_m = math.sqrt(max(vm, 0.0))
            lo, hi = m - q * se_m, m + q * se_m
            if m > 0 and lo > 0:
                kfn = _k_function(l, b)
                k_val, k_grad = (np.asarray(x, dtype=float).ravel() for x in kfn(ca.DM(theta), W_ref))
                k = float(k_val[0])
                g = k_grad.reshape(3)
                se_k = math.sqrt(max(float(g @ cov @ g), 0.0))
                p_ref = W_ref / (2 * b * l)
                iv = _fieller(a, m, va, vm, cam, q)  # u = log(k / p_ref) = -a / m
                k_ci = (p_ref * math.exp(iv[0]), p_ref * math.exp(iv[1])) if iv else (None, None)
                n_est = _sink(
                    "bekker_n",
                    1.0 / m,
                    se_m / m**2,
                    (1.0 / hi, 1.0 / lo),
                    True,
                    "from the measured sinkage's growth with the load (interval: that of 1 / n, inverted)",
                )
                k_est = _sink(
                    "bekker_k_eq",
                    k,
                    se_k,
                    k_ci,
                    iv is not None,
                    f"at the track width b = {b:.4g} m (Fieller interval: k extrapolates the law to z = 1 m, so it "
                    "moves with n)",
                )
                why_n = ""
            else:
                why_n = (
                    f"the loads' spread does not determine 1 / n: its 95 % interval [{lo:.3g}, {hi:.3g}] "
                    "does not lie above 0"
                )
    if why_n:
        n_est = _sink("bekker_n", None, None, (None, None), False, why_n)
        k_est = _sink("bekker_k_eq", None, None, (None, None), False, why_n)
        notes.append("n and k not identifiable: " + why_n)
    notes.append(one_width)
    if free[_S] and cov is not None:
        se_s = math.sqrt(max(cov[_S, _S], 0.0))
        s_est = _sink(
            "slip_sinkage_exponent",
            s,
            se_s,
            (s - q * se_s, s + q * se_s),
            True,
            "z = z0(W) [(1 + i) / (1 - 0.5 i)] ^ s: s = 1 is Lyasko's law, s = 0 no slip sinkage",
        )
    else:
        why = why_s or "no intervals (see the notes)"
        s_est = _sink(
            "slip_sinkage_exponent",
            None,
            None,
            (None, None),
            False,
            why,
        )
    kc = _sink("bekker_kc", None, None, (None, None), False, one_width)
    kphi = _sink("bekker_kphi", None, None, (None, None), False, one_width)
    return {
        "bekker_kc": kc,
        "bekker_kphi": kphi,
        "bekker_n": n_est,
        "bekker_k_eq": k_est,
        "slip_sinkage_exponent": s_est,
    }


def slip_sinkage_evidence(data: SlipData, vehicle: Vehicle) -> SlipSinkageEvidence:
    """Does the sweep's measured sinkage grow with the slip at a given load (slip sinkage)?

    The sinkage laws are fitted (:func:`fit_sinkage_channel`) with the exponent s of Lyasko's
    factor free; "no slip sinkage" is ``s = 0`` and "Lyasko's law" ``s = 1``, each tested with
    Student's t. The load is in the model (``z0(W)``), so a load that moves with the slip does
    not pass for slip sinkage while the loads separate from the slips.

    Parameters
    ----------
    data
        A track sweep (``sinkage_m`` needed for a test).
    vehicle
        The track's geometry and, without a load column, its weight.

    Returns
    -------
    SlipSinkageEvidence
        ``testable`` False, with the reason, when no test is possible (also for a rigid wheel's
        sweep: the textbook wheel's own sinkage grows with the slip at a given load).
    """
    if not isinstance(data, SlipData) or not isinstance(vehicle, Vehicle):
        return SlipSinkageEvidence(
            False,
            None,
            None,
            None,
            None,
            0,
            0,
            "not a track sweep: a rigid wheel's sinkage grows with the slip in the textbook wheel itself; its "
            "slip-sinkage signature is the wheel fit's sinkage residual",
        )
    if data.sinkage is None:
        return SlipSinkageEvidence(False, None, None, None, None, 0, 0, "no sinkage_m column")
    ch = fit_sinkage_channel(data, vehicle)
    if ch is None:
        n = int(np.count_nonzero((np.asarray(data.sinkage) > 0) & (np.asarray(data.slip) >= 0)))
        return SlipSinkageEvidence(
            False, None, None, None, None, n, 0, f"{n} rows with a positive sinkage (need {MIN_SINKAGE_ROWS})"
        )
    s = ch.parameters["slip_sinkage_exponent"]
    if not s.identifiable or ch.p_no_slip_sinkage is None:
        return SlipSinkageEvidence(False, None, None, None, None, ch.n_rows, ch.dof, s.note)
    return SlipSinkageEvidence(True, s.value, s.stderr, ch.p_no_slip_sinkage, ch.p_lyasko, ch.n_rows, ch.dof)


@locked_cache(maxsize=32)
def _slip_resistance_function(track_length: float, track_width: float, n_rows: int) -> ca.Function:
    """``(theta, W[n], i[n], W_ref) -> (mu_s, d mu_s / d theta)``: Bekker compaction's slip coefficient."""
    th, W, i = ca.SX.sym("theta", 3), ca.SX.sym("W", n_rows), ca.SX.sym("i", n_rows)
    W_ref = ca.SX.sym("W_ref")
    n = 1 / th[_M]
    k = _k_function(track_length, track_width)(th, W_ref)[0]
    ratio = sinkage_expr(W, n, 0.0, 1.0, track_length, track_width) / sinkage_expr(
        W_ref, n, 0.0, 1.0, track_length, track_width
    )
    z0 = ca.exp(th[_A]) * ratio
    z = slip_sinkage_expr(z0, i, th[_S])
    extra = (
        compaction_at_sinkage_expr(z, n, 0.0, k, track_width) - compaction_at_sinkage_expr(z0, n, 0.0, k, track_width)
    ) / W
    mu = ca.dot(i, extra) / ca.dot(i, i)  # least-squares slope of R_extra / W against i through 0
    return ca.Function("mu_s_sinkage", [th, W, i, W_ref], [mu, ca.jacobian(mu, th)])


def compare_slip_resistance(channel: SinkageChannelFit, data: SlipData, vehicle: Vehicle, mu_s) -> dict | None:
    """The slip coefficient that Bekker compaction of the measured ruts implies, beside the thrust fit's.

    The ``slip_sinkage`` effect's resistance is ``W mu_s i``. The fitted sinkage laws give the
    ruts' compaction resistance at each row's slip and at zero slip
    (:func:`~soiltrack.soilmodel.sinkage.compaction_at_sinkage_expr`); their difference over W,
    fitted as ``mu_s i`` by least squares over the rows, is the channel's mu_s (delta-method
    standard error). ``z = (mu_fit - mu_channel) / sqrt(se_fit^2 + se_channel^2)`` tests their
    agreement (normal p-value). Needs n (loads that spread); ``None`` without a thrust fit's mu_s.
    A disagreement has two readings, both said: a slip resistance beyond compaction (bulldozing),
    or the effect's linear form, which compaction's faster-than-linear growth does not follow and
    whose mu_s trades with the soil's parameters in the thrust fit (simulated compaction alone,
    n = 1.1, gave 0.07 from the thrust against 0.028 from the ruts).

    Parameters
    ----------
    channel
        The fitted sinkage laws.
    data, vehicle
        The sweep and its track.
    mu_s
        The thrust fit's ``slip_sinkage.mu_s`` estimate (``value``, ``stderr``), or ``None``.
    """
    if mu_s is None or getattr(mu_s, "value", None) is None:
        return None
    out: dict[str, Any] = {
        "mu_s_thrust_fit": _num(mu_s.value),
        "mu_s_thrust_fit_stderr": _num(mu_s.stderr),
        "mu_s_sinkage": None,
        "mu_s_sinkage_stderr": None,
        "p_agreement": None,
        "agree": None,
    }
    if not channel.n_identifiable or channel.covariance is None:
        out["statement"] = (
            f"slip_sinkage effect: mu_s = {mu_s.value:.3g} from the thrust; the sinkage cannot check it "
            "(Bekker compaction needs n, which these rows do not identify)"
        )
        return out
    i = np.asarray(data.slip, dtype=float)
    z = np.asarray(data.sinkage, dtype=float)
    W = np.asarray(data.loads(vehicle.weight), dtype=float)
    use = (z > 0) & (i >= 0)
    fn = _slip_resistance_function(channel.track_length, channel.track_width, int(np.count_nonzero(use)))
    mu, g = (
        np.asarray(x, dtype=float).ravel() for x in fn(ca.DM(channel.theta), W[use], i[use], channel.reference_load)
    )
    se = math.sqrt(max(float(g @ channel.covariance @ g), 0.0))
    out.update(mu_s_sinkage=_num(float(mu[0])), mu_s_sinkage_stderr=_num(se))
    se_fit = mu_s.stderr
    if se_fit is not None and math.isfinite(se_fit) and math.hypot(se_fit, se) > 0:
        zstat = (mu_s.value - float(mu[0])) / math.hypot(se_fit, se)
        p = 2.0 * (1.0 - norm_cdf(abs(zstat)))
        out.update(p_agreement=p, agree=bool(p >= SLIP_SINKAGE_ALPHA))
        corr = getattr(mu_s, "correlation", None)
        trade = (
            f" (in the thrust fit mu_s correlates {corr:+.2f} with {mu_s.correlated_with}: the linear form trades "
            "with the soil)"
            if corr is not None and getattr(mu_s, "correlated_with", None)
            else ""
        )
        verdict = (
            "they agree"
            if p >= SLIP_SINKAGE_ALPHA
            else "they differ: the slip resistance is not the ruts' compaction alone, or the effect's linear form "
            "W mu_s i (compaction grows faster than linearly with the slip) shifts it" + trade
        )
        tail = f"; p {_p(p)} for their agreement: {verdict}"
    else:
        tail = "; no standard error of the thrust fit's mu_s: no test of agreement"
    out["statement"] = (
        f"slip_sinkage effect: mu_s = {mu_s.value:.3g} from the thrust, {float(mu[0]):.3g} (SE {se:.2g}) from "
        f"Bekker compaction of the measured ruts{tail}"
    )
    return out
