"""The soil from a two-track drive log with yaw rate, fitted with the steering model.

Model (:func:`~soiltrack.soilmodel.steering.torque_inverse_function`): given each sample's
measured forward speed u, yaw rate Om and the two sprocket torques (the sprocket inertia's share
``(I/2) dw_k/dt`` taken off), the steering model gives the sprocket speeds at which each track's
shear delivers its torque while the lateral shear holds the centripetal force; the fit compares
them with the encoders (output error: the noisy speeds are not regressors of the slip, which
biases a torque-from-slip fit; DESIGN section 4). The channels are averaged over blocks of
``block_s`` (the quasi-static model is smooth over 0.2 s; the noise falls by the square root of
the block's samples and the model is solved once per block). Left and right residuals are
weighted by their 2 x 2 covariance estimated from the residuals (the vehicle-speed noise enters
both), in a second pass; each standard error is the larger of the model-based and the sandwich
one (:func:`_covariance`).

Parameters: ``F_max = A c + W tan(phi)`` (as ``F_max / W``), ``K``, and the friction share
``kappa = W tan(phi) / F_max`` in [0, 1] (c = (1 - kappa) F_max / A). Going straight both tracks
carry W/2 and only F_max and K enter; in a turn the load transfer moves ``m a_y h / B`` from the
inner to the outer track, which changes each track's ``A_k c + W_k tan(phi)`` by ``kappa``:
the only thing that separates c from phi here. c and phi are reported only when the standard
error of kappa is below :data:`KAPPA_SE_MAX`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from ...soilmodel import PRACTICAL_BOUNDS, DataError, SoilBounds, Vehicle
from ...soilmodel.steering import (
    SteeringSettings,
    check_steering_vehicle,
    torque_inverse_function,
    torque_residual_function,
    vehicle_parameters,
)
from ...soilmodel.threadsafe import call_solver, locked_cache
from ...soilmodel.turning import TwoTrackLog

__all__ = ["MOTIONS", "TurnFitSettings", "TurnFit", "BlockModel", "fit_turning", "fit_by_motion", "motion_blocks"]

MOTIONS = ("all", "straight", "turning")
#: Largest standard error of the friction share kappa at which c and phi are reported.
KAPPA_SE_MAX = 0.15
#: Largest relative standard error of F_max and of K at which the fit is usable.
REL_SE_MAX = 0.5
#: Reference scale of K in the fit's parameters, m.
K_REF = 0.01
#: Normal quantile of the 95 % intervals.
Z95 = 1.959963984540054


@dataclass(frozen=True)
class TurnFitSettings:
    """Settings of :func:`fit_turning`.

    Attributes
    ----------
    block_s
        Length of the blocks the channels are averaged over, s (noise down, one model solve each).
    min_speed
        Blocks slower than this (m/s) are left out (the model is of forward driving).
    max_iter
        Levenberg-Marquardt iterations per pass.
    steering
        Quadrature of the steering model (coarser than the simulator's default: within 4e-3 of a
        200 x 16 rule in radius and torques on the three test soils, docs/physics.md).
    """

    block_s: float = 0.2
    min_speed: float = 0.2
    max_iter: int = 25
    steering: SteeringSettings = field(default_factory=lambda: SteeringSettings(10, 2))


@dataclass(frozen=True)
class TurnFit:
    """The soil from the steering model (:func:`fit_turning`), SI inside, JSON at the edges.

    ``outcome`` is ``usable``, ``not_usable`` (F_max or K not determined: relative standard error
    above :data:`REL_SE_MAX`, e.g. gentle straight driving, which determines only the initial slope
    ``F_max l / (2 K)``, reported with its interval) or ``failed`` (no fit); ``separable``
    says whether the load transfer determined c and phi (then ``cohesion``, ``friction_angle``
    and their intervals are set, else ``None``).
    """

    motion: str
    rows: int
    blocks: int
    outcome: str
    outcome_reason: str | None
    max_thrust: float | None = None
    max_thrust_ci95: tuple[float, float] | None = None
    shear_modulus: float | None = None
    shear_modulus_ci95: tuple[float, float] | None = None
    friction_share: float | None = None
    friction_share_se: float | None = None
    separable: bool = False
    cohesion: float | None = None
    cohesion_ci95: tuple[float, float] | None = None
    friction_angle: float | None = None
    friction_angle_ci95: tuple[float, float] | None = None
    se: dict = field(default_factory=dict)
    correlation_fmax_k: float | None = None
    residual_rms_rad_s: tuple[float, float] | None = None
    initial_slope: float | None = None
    initial_slope_ci95: tuple[float, float] | None = None
    active_bounds: tuple[str, ...] = ()
    iterations: int = 0

    def to_dict(self) -> dict:
        """The S object of ``by_motion`` (DESIGN section 9) and the fit's details, kPa/deg at the edge."""

        def pair(x, scale=1.0):
            return None if x is None else [x[0] * scale, x[1] * scale]

        det = self.outcome == "usable"  # F_max and K of a fit that does not determine them: null, not a number
        out = {
            "rows": self.rows,
            "blocks": self.blocks,
            "outcome": self.outcome,
            "outcome_reason": self.outcome_reason,
            "max_thrust_N": self.max_thrust if det else None,
            "max_thrust_ci95": pair(self.max_thrust_ci95) if det else None,
            "shear_modulus_m": self.shear_modulus if det else None,
            "shear_modulus_ci95": pair(self.shear_modulus_ci95) if det else None,
            "initial_slope_N": self.initial_slope,
            "initial_slope_ci95": pair(self.initial_slope_ci95),
            "friction_share": self.friction_share,
            "friction_share_se": self.friction_share_se,
            "c_phi_separable": self.separable,
        }
        if self.separable and self.cohesion is not None and self.friction_angle is not None:
            out["cohesion_kpa"] = self.cohesion / 1e3
            out["cohesion_ci95"] = pair(self.cohesion_ci95, 1e-3)
            out["friction_angle_deg"] = math.degrees(self.friction_angle)
            out["friction_angle_ci95"] = pair(self.friction_angle_ci95, 180 / math.pi)
        out["correlation_max_thrust_shear_modulus"] = self.correlation_fmax_k
        out["residual_rms_rad_s"] = None if self.residual_rms_rad_s is None else list(self.residual_rms_rad_s)
        out["active_bounds"] = list(self.active_bounds)
        return out


def motion_blocks(log: TwoTrackLog, motion: str, settings: TurnFitSettings) -> dict[str, np.ndarray]:
    """Block means of the channels for the samples of ``motion`` (whole blocks of one kind only)."""
    if motion not in MOTIONS:
        raise DataError(f"motion must be one of {MOTIONS}, got {motion!r}")
    if log.yaw_rate is None:
        raise DataError(
            "the steering model needs the yaw rate (column yaw_rate_rad_s) of a two-track log",
            file=log.source,
            column="yaw_rate_rad_s",
        )
    t = log.time
    idx = np.floor((t - t[0]) / settings.block_s + 1e-9).astype(int)
    nb = int(idx[-1]) + 1
    count = np.bincount(idx, minlength=nb)
    turn = log.turning().astype(float)

    def mean(x):
        return np.bincount(idx, weights=x, minlength=nb) / np.maximum(count, 1)

    b = {
        k: mean(getattr(log, k))
        for k in ("torque_left", "torque_right", "speed_left", "speed_right", "vehicle_speed", "yaw_rate")
    }
    b["time"] = mean(t)
    share = mean(turn)
    full = count >= 0.8 * np.median(count)
    for k in ("speed_left", "speed_right"):  # the sprocket inertia's share: rate of the block means
        b["d" + k] = np.gradient(b[k], b["time"]) if nb > 1 else np.zeros(nb)
    keep = full & (b["vehicle_speed"] > settings.min_speed) & (b["speed_left"] > 0) & (b["speed_right"] > 0)
    keep &= {"all": share >= 0, "straight": share == 0, "turning": share == 1}[motion]
    out = {k: v[keep] for k, v in b.items()}
    out["rows"] = np.array(int(count[keep].sum()))
    return out


@lru_cache(maxsize=16)
def _predict_map(settings: SteeringSettings, n: int) -> ca.Function:
    return _predict_function(settings).map(n)


@locked_cache(maxsize=4)
def _predict_function(settings: SteeringSettings) -> ca.Function:
    """``(z0, p) -> (z, dz[0:2]/d[c, phi, K], residual at z)`` for one block (implicit sensitivities)."""
    rf = torque_inverse_function(settings)
    z0, a, so = ca.MX.sym("z0", 3), ca.MX.sym("motion", 4), ca.MX.sym("soil", 3)
    veh = ca.MX.sym("veh", rf.size1_in(1) - 7)
    p = ca.vertcat(a, so, veh)
    z = rf(z0, p)
    J = ca.jacobian(z[0:2], so)
    return ca.Function("turn_predict", [z0, a, so, veh], [z, J, torque_residual_function(settings)(z, p)])


class _Problem:
    """The blocks, the vehicle and the map from the fit's parameters to the model's predictions."""

    def __init__(self, blocks: dict, vehicle: Vehicle, settings: TurnFitSettings) -> None:
        self.b, self.vehicle, self.settings = blocks, vehicle, settings
        self.n = blocks["time"].size
        self.veh = vehicle_parameters(vehicle)
        half_I = 0.5 * vehicle.sprocket_inertia
        self.Tl = blocks["torque_left"] - half_I * blocks["dspeed_left"]
        self.Tr = blocks["torque_right"] - half_I * blocks["dspeed_right"]
        self.y = np.vstack([blocks["speed_left"], blocks["speed_right"]])
        self.z = np.vstack([self.y, np.zeros(self.n)])  # warm starts, updated on every accepted evaluation
        self.W, self.A = vehicle.weight, vehicle.contact_area

    def soil(self, th: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``[c, phi, K]`` and d[c, phi, K]/d[theta] for theta = [F_max / W, K / K_REF, kappa]."""
        f, k, kap = th
        den = 1 + (kap * f) ** 2
        s = np.array([(1 - kap) * self.W * f / self.A, math.atan(kap * f), K_REF * k])
        D = np.array([[(1 - kap) * self.W / self.A, 0, -self.W * f / self.A], [kap / den, 0, f / den], [0, K_REF, 0]])
        return s, D

    def evaluate(self, th: np.ndarray):
        """Predicted speeds (2 x n), their Jacobian (2n x 3) in theta, and whether every block solved."""
        s, D = self.soil(th)
        b = self.b
        P = np.vstack(
            [b["vehicle_speed"], b["yaw_rate"], self.Tl, self.Tr, np.tile(s.reshape(3, 1), self.n)]
            + [np.tile(self.veh.reshape(-1, 1), self.n)]
        )
        try:
            (Z, J, R), _ = call_solver(_predict_map(self.settings.steering, self.n), self.z, P[0:4], P[4:7], P[7:])
        except RuntimeError:  # a block's sensitivities failed (the model has no solution there)
            return None, None, False
        Z, R = np.asarray(Z).reshape(3, self.n), np.asarray(R).reshape(3, self.n)
        J = np.asarray(J).reshape(2, 3, self.n, order="F")  # mapped: 2 x (3 n), one 2 x 3 block each
        ok = bool(np.all(np.isfinite(Z)) and np.all(np.abs(R) < 1e-8) and np.all(Z[:2] > 0))
        Jt = np.einsum("ijn,jk->nik", J, D).reshape(2 * self.n, 3)  # rows: block-major, [left, right]
        return Z, Jt, ok


class BlockModel(_Problem):
    """The blocks' steering-model predictions and Jacobian (:meth:`evaluate`), for the on-line turning update.

    ``BlockModel(blocks, vehicle, settings)`` with ``blocks`` from :func:`motion_blocks`;
    ``evaluate([F_max / W, K / K_REF, kappa])`` gives the predicted speeds, their Jacobian and
    whether every block solved (the cached, mapped Function of :func:`fit_turning`).
    """


def _lm(prob: _Problem, th0: np.ndarray, lo: np.ndarray, hi: np.ndarray, L: np.ndarray, max_iter: int):
    """Projected Levenberg-Marquardt on the whitened residuals ``L (y - pred)`` (L: 2 x 2)."""

    def whitened(Z, Jt):
        r = (L @ (prob.y - Z[:2])).T.ravel()
        Jw = -np.einsum("ij,njk->nik", L, Jt.reshape(prob.n, 2, 3)).reshape(2 * prob.n, 3)
        return r, Jw

    th = th0.copy()
    Z, Jt, ok = prob.evaluate(th)
    if not ok:
        return None
    prob.z = Z
    r, Jw = whitened(Z, Jt)
    cost, lam, it = r @ r, 1e-3, 0
    for it in range(1, max_iter + 1):
        H, g = Jw.T @ Jw, Jw.T @ r
        accepted = done = False
        for _ in range(12):
            step = np.linalg.solve(H + lam * np.diag(np.diag(H) + 1e-12), -g)
            cand = np.clip(th + step, lo, hi)
            Zc, Jc, okc = prob.evaluate(cand)
            if okc:
                rc, Jwc = whitened(Zc, Jc)
                cc = float(rc @ rc)
                if cc < cost:
                    done = cost - cc < 1e-7 * cost or float(np.max(np.abs(cand - th))) < 1e-12
                    th, Z, r, Jw, accepted = cand, Zc, rc, Jwc, True
                    prob.z = Zc
                    cost, lam = cc, max(lam / 5, 1e-9)
                    break
            lam *= 8
        if not accepted or done:
            break
    return th, Z, Jw, r, it


def fit_turning(
    log: TwoTrackLog,
    vehicle: Vehicle,
    *,
    motion: str = "all",
    bounds: SoilBounds = PRACTICAL_BOUNDS,
    settings: TurnFitSettings = TurnFitSettings(),
) -> TurnFit:
    """Fit F_max, K (and c, phi where the load transfer separates them) with the steering model.

    Parameters
    ----------
    log
        A two-track log with ``yaw_rate_rad_s`` (:func:`~soiltrack.soilmodel.turning.read_two_track`).
    vehicle
        The vehicle; needs ``tread_m``.
    motion
        ``"all"``, ``"straight"`` or ``"turning"``: which samples (whole blocks) are fitted.
    bounds
        Soil bounds: K's bounds, and F_max between those the c and phi bounds give.
    settings
        :class:`TurnFitSettings`.
    """
    check_steering_vehicle(vehicle)
    blocks = motion_blocks(log, motion, settings)
    rows, n = int(blocks["rows"]), int(blocks["time"].size)
    if n < 6:
        return TurnFit(
            motion, rows, n, "failed", f"{n} blocks of {motion} driving above {settings.min_speed} m/s; need 6"
        )
    prob = _Problem(blocks, vehicle, settings)
    W, A = vehicle.weight, vehicle.contact_area
    f_lo = max(0.01, math.tan(bounds.friction_angle[0]))
    f_hi = (A * bounds.cohesion[1] + W * math.tan(bounds.friction_angle[1])) / W
    lo = np.array([f_lo, bounds.shear_modulus[0] / K_REF, 0.0])
    hi = np.array([f_hi, bounds.shear_modulus[1] / K_REF, 1.0])
    need = 2.2 * max(np.max(np.abs(prob.Tl)), np.max(np.abs(prob.Tr))) / (vehicle.sprocket_radius * W)
    th0 = np.clip(np.array([max(0.6, need), 1.5, 0.8]), lo, hi)
    out = _lm(prob, th0, lo, hi, np.eye(2) * 100.0, settings.max_iter)
    if out is None:
        return TurnFit(motion, rows, n, "failed", "the steering model has no solution at the start for some blocks")
    th, Z, _, _, it1 = out
    e = prob.y - Z[:2]
    S = np.cov(e) + 1e-18 * np.eye(2)
    L = np.linalg.inv(np.linalg.cholesky(S))
    out = _lm(prob, th, lo, hi, L, settings.max_iter)
    if out is None:
        return TurnFit(motion, rows, n, "failed", "the steering model lost its solution in the weighted pass")
    th, Z, Jw, r, it2 = out
    return _result(motion, rows, n, prob, th, Z, Jw, r, lo, hi, it1 + it2)


def _covariance(Jw: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The larger (per parameter, scaled as a whole) of the model-based and the sandwich covariance.

    Model-based: ``(J'J)^-1`` of the whitened residuals (their 2 x 2 covariance estimated).
    Sandwich (per block, HC0): ``(J'J)^-1 (sum_b J_b' r_b r_b' J_b) (J'J)^-1``: robust to the
    noise level changing along the log (the relative encoder noise is larger on the faster, outer
    track, which changes sides between left and right turns). The larger of the two is taken for
    each standard error (its correlations are the model-based ones).
    """
    H = np.linalg.pinv(Jw.T @ Jw, rcond=1e-13)
    n = r.size // 2
    g = np.einsum("bi,bij->bj", r.reshape(n, 2), Jw.reshape(n, 2, -1))  # per-block score
    S = H @ (g.T @ g) @ H
    scale = np.sqrt(np.maximum(np.diag(S), np.diag(H)) / np.maximum(np.diag(H), 1e-300))
    return H * np.outer(scale, scale)


def _ci(x: float, se: float) -> tuple[float, float]:
    return (float(x - Z95 * se), float(x + Z95 * se))


def _result(motion, rows, n, prob: _Problem, th, Z, Jw, r, lo, hi, iterations) -> TurnFit:
    """Covariance, intervals, identifiability and the outcome of a converged fit."""
    W = prob.W
    try:
        cov = _covariance(Jw, r)
    except np.linalg.LinAlgError:
        return TurnFit(motion, rows, n, "failed", "singular information matrix")
    se = np.sqrt(np.maximum(np.diag(cov), 0))
    Fmax, K = W * th[0], K_REF * th[1]
    se_F, se_K = W * se[0], K_REF * se[1]
    corr = float(cov[0, 1] / (se[0] * se[1])) if se[0] > 0 and se[1] > 0 else None
    names = ("max_thrust", "shear_modulus", "friction_share")
    active = tuple(nm for nm, v, a, b in zip(names, th, lo, hi) if v <= a + 1e-9 * max(1, abs(a)) or v >= b - 1e-9 * b)
    rms_lr = np.sqrt(np.mean((prob.y - Z[:2]) ** 2, axis=1))
    rms = (float(rms_lr[0]), float(rms_lr[1]))
    rel = max(se_F / Fmax, se_K / K)
    l = prob.vehicle.track_length
    slope = Fmax * l / (2 * K)  # dF/di at i = 0: what gentle driving determines
    grad = np.array([W * l / (2 * K), -Fmax * l / (2 * K * K) * K_REF, 0.0])
    se_slope = float(math.sqrt(max(grad @ cov @ grad, 0.0)))
    problems = []
    if rel > REL_SE_MAX:
        gentle = corr is not None and corr > 0.95  # F_max and K move together: only the initial slope is seen
        problems.append(
            f"F_max and K are not both determined (relative standard errors {se_F / Fmax:.2g} and {se_K / K:.2g}; "
            f"correlation {corr if corr is None else round(corr, 3)})"
            + (
                ": the log's thrust stays far below the soil's limit, so only the initial slope F_max l / (2 K) "
                "is pinned down"
                if gentle
                else ""
            )
        )
    act = [a for a in active if a != "friction_share"]
    if act:
        problems.append(f"{', '.join(act)} ended on a bound")
    separable = bool(se[2] < KAPPA_SE_MAX and "friction_share" not in active and not problems)
    kw: dict[str, Any] = {}
    if separable:
        s, D = prob.soil(th)
        cs = D @ cov @ D.T
        kw = dict(
            cohesion=float(s[0]),
            cohesion_ci95=_ci(float(s[0]), math.sqrt(cs[0, 0])),
            friction_angle=float(s[1]),
            friction_angle_ci95=_ci(float(s[1]), math.sqrt(cs[1, 1])),
        )
    return TurnFit(
        motion=motion,
        rows=rows,
        blocks=n,
        outcome="usable" if not problems else "not_usable",
        outcome_reason="; ".join(problems) or None,
        max_thrust=float(Fmax),
        max_thrust_ci95=_ci(Fmax, se_F),
        shear_modulus=float(K),
        shear_modulus_ci95=_ci(K, se_K),
        friction_share=float(th[2]),
        friction_share_se=float(se[2]),
        separable=separable,
        se={"max_thrust_N": float(se_F), "shear_modulus_m": float(se_K), "friction_share": float(se[2])},
        correlation_fmax_k=corr,
        residual_rms_rad_s=rms,
        initial_slope=float(slope),
        initial_slope_ci95=_ci(slope, se_slope),
        active_bounds=active,
        iterations=iterations,
        **kw,
    )


def fit_by_motion(
    log: TwoTrackLog,
    vehicle: Vehicle,
    *,
    bounds: SoilBounds = PRACTICAL_BOUNDS,
    settings: TurnFitSettings = TurnFitSettings(),
) -> tuple[dict, dict[str, TurnFit]]:
    """``by_motion`` of DESIGN section 9 and the three :class:`TurnFit` (``(dict, {motion: fit})``).

    ``agreement_se``: for F_max and K, ``(turning - straight) / sqrt(se_t^2 + se_s^2)`` (None when
    either fit is not usable).
    """
    fits = {m: fit_turning(log, vehicle, motion=m, bounds=bounds, settings=settings) for m in MOTIONS}
    agree: dict[str, float | None] = {}
    s, t = fits["straight"], fits["turning"]
    for key, attr in (("max_thrust_N", "max_thrust"), ("shear_modulus_m", "shear_modulus")):
        if s.outcome == "usable" and t.outcome == "usable":
            d = getattr(t, attr) - getattr(s, attr)
            agree[key] = float(d / math.hypot(s.se[key], t.se[key]))
        else:
            agree[key] = None
    out = {m: fits[m].to_dict() for m in ("straight", "turning", "all")}
    out["agreement_se"] = agree
    return out, fits
