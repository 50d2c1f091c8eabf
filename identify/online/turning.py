"""Turning samples in the on-line estimate: blocks of a turn fitted with the steering model.

The straight-line horizon (:mod:`.estimator`) cannot use a two-track log's turning samples (the
tracks pull and brake against the steering resistance). This module fits them with the steering
model instead (:func:`~soiltrack.soilmodel.steering.torque_inverse_function`, through
:class:`~soiltrack.identify.turning.fit.BlockModel`, the model of ``fit --motion turning``; its
CasADi Functions are built once per size and cached, the data enter as parameters):

1. Consecutive turning samples are collected into a block; a block is fitted when it reaches
   :attr:`TurningSettings.block_s` or when the turn ends (a straight sample, a gap); a shorter
   run than :attr:`TurningSettings.min_block_s` is not fitted (counted ``short``).
2. The block's channels are averaged over ``sub_block_s`` (as ``fit --motion turning``), and
   (F_max, K) are fitted by Levenberg-Marquardt on the block's residuals plus the held soil as
   the block's arrival cost ``(x - x_held)' P_held^-1 (x - x_held)``: information-form fusion
   (the arithmetic of :func:`~.memory.fuse`) done inside the fit, because one block alone often
   leaves F_max and K on a ridge, where its own estimate and linear covariance describe it badly
   (measured: fusing blocks' data-only estimates with ``fuse`` gave K 2.7-4.4 standard errors off
   on 2 of 6 seeds, and a first ridge block refused every later turn on another). With nothing
   held, the arrival cost is a weak prior at ``fit_turning``'s start (``seed_prior_rel`` = 100 %
   standard deviations). The left and right residuals are whitened by their 2 x 2 covariance
   pooled over the last ``noise_sub_blocks`` sub-blocks of fitted turns, this block's included
   (each block's residuals scaled by ``n / (n - 1)``; the first block is fitted twice, the second
   time with the covariance its own residuals gave). The block's information is ``J' J`` of the
   whitened residuals at the optimum, the posterior covariance ``(J' J + P_held^-1)^-1``.
3. **c/phi split.** The turn's load transfer moves ``m a_y h / B`` from the inner to the outer
   track, and how much that changes each track's ``F_max,k`` depends on the friction share
   ``kappa = W tan(phi) / F_max``, which the on-line estimate (F_max, K at one load) does not
   know. It is taken from :attr:`TurningSettings.friction_share` (default 1: a frictional soil;
   set it from a prior fit, e.g. ``1 - A c / F_max``). Its effect is small in ordinary turns
   (the load transfer is ``a_y h / (g B)`` of the weight: 2 % at 0.5 m/s^2, h 1 m, B 2.5 m).
4. **Fusion.** The posterior becomes the held soil at the block's last sample, unless

   - the block carries no information: ``trace(I_block P_held) < min_information`` (a gentle
     turn; nothing held: a parameter ended on its bound) (``no_information``);
   - it disagrees with the held soil: the fit's cost falls by more than
     :attr:`TurningSettings.gate_chi2` from the held value to the optimum (the innovation's
     chi-square, at most 2 degrees of freedom; ``disagrees``). It is counted and flagged, not
     fused, and it does NOT declare a change of terrain: the straight line's detector remains
     the one that does;
   - the steering model has no solution for it (``failed``), the vehicle has no ``tread_m``
     (``no_tread``), the sample has no yaw rate (``no_yaw``), or too few sub-blocks are above
     ``min_speed`` (``slow``).
5. **Arrival cost.** The horizon's prior is the held state at its oldest sample; the turning
   blocks fused after that are not in the horizon (turning samples never are), so
   :meth:`TurningUpdate.with_recent` adds their information (``J' J`` and the information vector,
   linearised where each was fitted) to the prior: no block is counted twice or lost.
   After a change of terrain the blocks before it are dropped with the horizon's start.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from ...soilmodel import SoilBounds, Vehicle
from ...soilmodel.steering import SteeringSettings
from ...soilmodel.turning import TwoTrackLog
from ..turning.fit import K_REF, BlockModel, TurnFitSettings, motion_blocks
from .memory import HeldSoil, Sym

__all__ = ["TurningSettings", "TurnBlock", "TurningUpdate", "NOT_FITTED_REASONS"]

#: Why a turning sample was not fitted (the keys of :attr:`TurningUpdate.not_fitted`).
NOT_FITTED_REASONS = ("no_tread", "no_yaw", "short", "slow", "failed", "no_information", "disagrees")


@dataclass(frozen=True)
class TurningSettings:
    """Settings of the on-line turning update (:class:`TurningUpdate`).

    Attributes
    ----------
    block_s
        Longest block, s: a long turn is fitted in pieces of this length (one model solve each).
    min_block_s
        Shortest run of turning samples that is fitted, s (shorter: too few sub-blocks).
    sub_block_s
        The channels are averaged over this, s (the quasi-static model is smooth over 0.2 s).
    min_speed
        Sub-blocks slower than this are left out, m/s (the model is of forward driving).
    friction_share
        kappa = W tan(phi) / F_max of the load transfer (the on-line estimate has no c/phi split).
    min_information
        Least ``trace(I_block P_held)`` of a fused block (below: a gentle turn, nothing learned).
    gate_chi2
        A block farther than this (chi-square, 2 dof; 99.9 %) from the held soil is not fused.
    noise_sub_blocks
        Sub-block residuals pooled for the left/right noise covariance (recent turns).
    min_noise_sub_blocks
        Fewest pooled residuals before a block is fused (the first short turn only sets the noise).
    max_iter
        Levenberg-Marquardt iterations per block (it starts at the held estimate).
    seed_prior_rel
        Relative standard deviation of the weak prior of the first block when nothing is held (100 %).
    steering
        Quadrature of the steering model (that of ``fit --motion turning``).
    """

    block_s: float = 2.0
    min_block_s: float = 0.6
    sub_block_s: float = 0.2
    min_speed: float = 0.2
    friction_share: float = 1.0
    min_information: float = 0.02
    gate_chi2: float = 13.815510557964274
    noise_sub_blocks: int = 60
    min_noise_sub_blocks: int = 8
    max_iter: int = 15
    seed_prior_rel: float = 1.0
    steering: SteeringSettings = field(default_factory=lambda: SteeringSettings(10, 2))

    def __post_init__(self) -> None:
        if not (0.0 <= self.friction_share <= 1.0):
            raise ValueError(f"friction_share must be in [0, 1], got {self.friction_share!r}")
        for name in ("block_s", "min_block_s", "sub_block_s", "gate_chi2"):
            if not (getattr(self, name) > 0):
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)!r}")


@dataclass(frozen=True)
class TurnBlock:
    """One fitted block: ``status`` ``fused`` or a reason of :data:`NOT_FITTED_REASONS`.

    ``x`` (F_max N, K m), ``V`` its covariance ``(v11, v12, v22)`` (data only), ``d2`` its squared
    Mahalanobis distance from the held soil (None when nothing was held), ``samples`` the block's.
    """

    time_s: float
    samples: int
    status: str
    x: tuple[float, float] | None = None
    V: Sym | None = None
    d2: float | None = None
    info: Sym | None = None  # the block's own information J'J (SI)
    prior: tuple | None = None  # ((F, K), P) the block was fitted against: the held soil or the weak seed prior


class TurningUpdate:
    """Collects turning samples into blocks, fits them, and fuses them into a :class:`~.memory.HeldSoil`.

    Parameters
    ----------
    vehicle
        The vehicle (needs ``tread_m``; without it every turning sample is ``no_tread``).
    bounds
        Soil bounds (K's, and F_max's through the c and phi bounds), as the straight estimate's.
    settings
        :class:`TurningSettings`.
    """

    def __init__(self, vehicle: Vehicle, bounds: SoilBounds, settings: TurningSettings | None = None) -> None:
        self.vehicle, self.settings = vehicle, settings or TurningSettings()
        self._ok = vehicle.tread is not None
        W, A = vehicle.weight, vehicle.contact_area
        self._lo = np.array([max(0.01, math.tan(bounds.friction_angle[0])), bounds.shear_modulus[0] / K_REF])
        self._hi = np.array(
            [(A * bounds.cohesion[1] + W * math.tan(bounds.friction_angle[1])) / W, bounds.shear_modulus[1] / K_REF]
        )
        self._buf: list[tuple[float, ...]] = []
        self._resid: deque = deque(maxlen=self.settings.noise_sub_blocks)
        self._recent: deque = deque(maxlen=256)  # (t, x, V) of the fused blocks
        self.samples_fitted = 0
        self.not_fitted = dict.fromkeys(NOT_FITTED_REASONS, 0)
        self.blocks: deque[TurnBlock] = deque(maxlen=64)

    @property
    def samples_not_fitted(self) -> int:
        """Turning samples not fitted by the steering model (all reasons)."""
        return sum(self.not_fitted.values())

    # ------------------------------------------------------------------ collecting
    def add(self, sample: tuple[float, ...], held: HeldSoil, window_s: float):
        """Take one turning sample ``(t, T_l, T_r, w_l, w_r, u, yaw)``; fits and fuses a full block.

        Returns the :class:`TurnBlock` when one was fitted, else None.
        """
        if not self._ok:
            self.not_fitted["no_tread"] += 1
            return None
        if sample[6] is None or not math.isfinite(sample[6]):  # no yaw rate: the steering model needs it
            blk = self.end(held, window_s)
            self.not_fitted["no_yaw"] += 1
            return blk
        if self._buf and sample[0] <= self._buf[-1][0]:
            self.end(held, window_s)
        self._buf.append(tuple(float(v) for v in sample))
        if self._buf[-1][0] - self._buf[0][0] >= self.settings.block_s:
            return self.end(held, window_s)
        return None

    def _count_short(self, n: int) -> None:
        self.not_fitted["short"] += n

    def end(self, held: HeldSoil, window_s: float) -> TurnBlock | None:
        """The turn (or the block) ended: fit and fuse what was collected (a short run is counted)."""
        buf, self._buf = self._buf, []
        if not buf:
            return None
        if buf[-1][0] - buf[0][0] < self.settings.min_block_s:
            self._count_short(len(buf))
            return None
        blk = self._fit(np.array(buf), held)
        blk = self._fuse(blk, held, window_s)
        self.blocks.append(blk)
        if blk.status == "fused":
            self.samples_fitted += blk.samples
        else:
            self.not_fitted[blk.status] += blk.samples
        return blk

    # ------------------------------------------------------------------ fitting
    def _fit(self, a: np.ndarray, held: HeldSoil) -> TurnBlock:
        """The block's data-only estimate and covariance (status ``fitted`` or a reason)."""
        s, t_end, n = self.settings, float(a[-1, 0]), int(a.shape[0])
        log = TwoTrackLog(
            time=a[:, 0], torque_left=a[:, 1], torque_right=a[:, 2], speed_left=a[:, 3], speed_right=a[:, 4],
            vehicle_speed=a[:, 5], yaw_rate=a[:, 6],
        )  # fmt: skip
        fs = TurnFitSettings(block_s=s.sub_block_s, min_speed=s.min_speed, steering=s.steering)
        b = motion_blocks(log, "all", fs)  # the estimator already classified the samples as turning
        if b["time"].size < 3:
            return TurnBlock(t_end, n, "slow")
        model = BlockModel(b, self.vehicle, fs)
        now = held.now(t_end)
        D = np.diag([model.W, K_REF])
        if now is not None:  # the held soil as the block's arrival cost (scaled parameters)
            th_h = np.clip(np.array([now[0][0] / model.W, now[0][1] / K_REF]), self._lo, self._hi)
            Pth = np.linalg.inv(D) @ _mat(now[1]) @ np.linalg.inv(D)
        else:  # nothing held: a weak prior at fit_turning's start (seed_prior_rel standard deviations)
            T_peak = max(np.max(np.abs(model.Tl)), np.max(np.abs(model.Tr)))
            f0 = max(0.6, 2.2 * T_peak / (self.vehicle.sprocket_radius * model.W))
            th_h = np.clip(np.array([f0, 1.5]), self._lo, self._hi)
            Pth = np.diag((s.seed_prior_rel * th_h) ** 2)
        prior = (th_h, np.linalg.cholesky(np.linalg.inv(Pth)).T)
        starts = [th_h]
        out, L = None, self._whitener()
        pooled = len(self._resid) >= s.min_noise_sub_blocks  # the noise covariance known before this block
        for th0 in starts:
            out = self._lm(model, np.clip(th0, self._lo, self._hi), L, prior)
            if out is not None:
                break
        if out is None:
            return TurnBlock(t_end, n, "failed")
        th, Z, Jw, d2 = out
        e = (model.y - Z[:2]).T
        m = e.shape[0]
        self._resid.extend(e * math.sqrt(m / max(m - 1, 1)))
        if len(self._resid) < s.min_noise_sub_blocks:
            return TurnBlock(t_end, n, "no_information")
        L_new = self._whitener()
        if pooled:  # one pass: the information re-whitened with the pool that now holds this block too
            M = L_new @ np.linalg.inv(L)
            Jw = np.einsum("ij,njk->nik", M, Jw.reshape(model.n, 2, 2)).reshape(2 * model.n, 2)
            d2 = None if d2 is None else d2  # (the gate's statistic of the first whitening)
        else:  # the first block: fitted again with the noise covariance its residuals gave
            out = self._lm(model, th, L_new, prior) if prior is None else self._lm(model, prior[0], L_new, prior)
            if out is None:
                return TurnBlock(t_end, n, "failed")
            th, Z, Jw, d2 = out
        Ib = Jw.T @ Jw
        on_bound = np.any(th <= self._lo * (1 + 1e-9)) or np.any(th >= self._hi * (1 - 1e-9))
        x = (float(model.W * th[0]), float(K_REF * th[1]))
        Dinv = np.linalg.inv(D)
        info = _sym(Dinv @ Ib @ Dinv)
        V = D @ np.linalg.inv(Ib + prior[1].T @ prior[1]) @ D  # the prior's term makes it positive definite
        if on_bound and now is None:
            return TurnBlock(t_end, n, "no_information", x, None, d2, info)
        pr = (float(model.W * th_h[0]), float(K_REF * th_h[1])), _sym(D @ Pth @ D)
        return TurnBlock(t_end, n, "fitted", x, _sym(V), d2, info, prior=pr)

    def _whitener(self) -> np.ndarray:
        """``L`` with ``L' L = S^-1``, S the pooled left/right residual covariance (100 I before any)."""
        if len(self._resid) < 3:
            return np.eye(2) * 100.0
        e = np.asarray(self._resid)
        S = e.T @ e / e.shape[0] + 1e-18 * np.eye(2)
        return np.linalg.inv(np.linalg.cholesky(S))

    def _lm(self, model: BlockModel, th0: np.ndarray, L: np.ndarray, prior=None):
        """Projected Levenberg-Marquardt on (F_max / W, K / K_REF), kappa fixed.

        ``prior = (th_h, C)`` adds the arrival cost ``|C (th - th_h)|^2`` (the held soil). Returns
        ``(th, Z, J_w of the data, d2)`` or None; ``d2`` (with a prior, started at ``th_h``) is the
        cost's fall from ``th_h`` to the optimum: the innovation's chi-square, 2 dof at most.
        """
        kap = self.settings.friction_share
        nd = 2 * model.n

        def ev(th):
            Z, Jt, ok = model.evaluate(np.array([th[0], th[1], kap]))
            if not ok:
                return None
            r = (L @ (model.y - Z[:2])).T.ravel()
            Jw = -np.einsum("ij,njk->nik", L, Jt.reshape(model.n, 2, 3)[:, :, :2]).reshape(nd, 2)
            if prior is not None:
                r, Jw = np.concatenate([r, prior[1] @ (th - prior[0])]), np.vstack([Jw, prior[1]])
            return Z, r, Jw

        th, cur = th0.copy(), ev(th0)
        if cur is None:
            return None
        model.z = cur[0]
        cost, lam = float(cur[1] @ cur[1]), 1e-3
        cost0 = cost
        for _ in range(self.settings.max_iter):
            H, g = cur[2].T @ cur[2], cur[2].T @ cur[1]
            accepted = done = False
            for _ in range(10):
                cand = np.clip(th + np.linalg.solve(H + lam * np.diag(np.diag(H) + 1e-12), -g), self._lo, self._hi)
                new = ev(cand)
                if new is not None and float(new[1] @ new[1]) < cost:
                    cc = float(new[1] @ new[1])
                    done = cost - cc < 1e-8 * cost or float(np.max(np.abs(cand - th))) < 1e-10
                    th, cur, cost, lam, accepted = cand, new, cc, max(lam / 5, 1e-9), True
                    model.z = new[0]
                    break
                lam *= 8
            if not accepted or done:
                break
        return th, cur[0], cur[2][:nd], (cost0 - cost if prior is not None else None)

    # ------------------------------------------------------------------ fusing
    def _fuse(self, blk: TurnBlock, held: HeldSoil, window_s: float) -> TurnBlock:
        """Gate the block against the held soil and fuse it (the rules of the module docstring)."""
        if blk.status != "fitted" or blk.x is None or blk.V is None or blk.info is None:
            return blk
        t, now = blk.time_s, held.now(blk.time_s)
        if now is not None:  # the gate and the information test against the held soil
            if _info_ratio(blk.info, now[1]) < self.settings.min_information:
                return dataclasses.replace(blk, status="no_information")
            if blk.d2 is None or blk.d2 > self.settings.gate_chi2:
                return dataclasses.replace(blk, status="disagrees")
        assert blk.prior is not None
        h = info_vector(blk.prior, blk)
        held.set(t, blk.x, blk.V)
        held.snapshot(t, t - window_s)
        self._recent.append((t, _mat(blk.info), h))
        return dataclasses.replace(blk, status="fused")

    def with_recent(self, prior, t_start: float):
        """The horizon's arrival cost ``(x, P)`` (or None) with the turning blocks fused after ``t_start``.

        Information form: ``P^-1 = P_prior^-1 + sum I_b``, ``P^-1 x = P_prior^-1 x_prior + sum h_b``
        (``h_b`` the block's information vector, linearised where it was fitted).
        """
        blocks = [(I, h) for t, I, h in self._recent if t > t_start]
        if not blocks:
            return prior
        I, h = np.zeros((2, 2)), np.zeros(2)
        if prior is not None:
            Ip = np.linalg.inv(_mat(prior[1]))
            I, h = Ip, Ip @ np.array(prior[0])
        for Ib, hb in blocks:
            I, h = I + Ib, h + hb
        try:
            P = np.linalg.inv(I)
        except np.linalg.LinAlgError:
            return prior
        if not (P[0, 0] > 0 and P[1, 1] > 0):
            return prior
        x = P @ h
        return (float(x[0]), float(x[1])), _sym(P)


def info_vector(prior, blk: TurnBlock) -> np.ndarray:
    """The block's information vector ``h_b = P_post^-1 x_post - P_prior^-1 x_prior`` (its share of the fusion)."""
    assert blk.V is not None and blk.x is not None
    return np.linalg.inv(_mat(blk.V)) @ np.array(blk.x) - np.linalg.inv(_mat(prior[1])) @ np.array(prior[0])


def _mat(m: Sym) -> np.ndarray:
    return np.array([[m[0], m[1]], [m[1], m[2]]], dtype=float)


def _sym(M: np.ndarray) -> Sym:
    return (float(M[0, 0]), float(0.5 * (M[0, 1] + M[1, 0])), float(M[1, 1]))


def _info_ratio(info: Sym, P: Sym) -> float:
    """``trace(I_block P_held)``: the block's information relative to the held uncertainty."""
    return info[0] * P[0] + 2 * info[1] * P[1] + info[2] * P[2]
