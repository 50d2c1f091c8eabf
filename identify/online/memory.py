"""What the on-line estimate remembers: the held (F_max, K) with a covariance that grows as a random walk.

The moving horizon's fit sees only its last ``window_s`` seconds. The memory carries what older
samples said, as an arrival cost: the state (estimate and covariance) at the time the horizon's
oldest sample arrived. While the horizon identifies F_max, the estimate is that prior fused with
the horizon's own (data-only) estimate in information form,

    P^-1 = P_prior^-1 + V_win^-1,    x = P (P_prior^-1 x_prior + V_win^-1 x_win),

which is the horizon's fit with a quadratic arrival cost, linearised at its optimum; the prior
holds only samples older than the horizon, so no sample is counted twice. While the horizon does
not identify F_max (gentle driving, no pull in the last ``window_s`` s), the last fused estimate
is held, and its covariance grows by ``Q (t - t_fused)`` with
``Q = diag((q_F F)^2, (q_K K)^2)`` per second: a random walk, how fast the soil may drift while
the vehicle drives on it (:class:`~.settings.OnlineSettings` ``drift_max_thrust_rel``,
``drift_shear_modulus_rel``). After a change of terrain everything is dropped.
"""

from __future__ import annotations

import math
from collections import deque

__all__ = ["HeldSoil", "fuse"]

Sym = tuple[float, float, float]  # a symmetric 2x2 matrix as (a11, a12, a22)


def _inv(m: Sym) -> Sym | None:
    a, b, d = m
    det = a * d - b * b
    if not (a > 0 and d > 0 and det > 1e-12 * a * d):
        return None
    return d / det, -b / det, a / det


def fuse(x_p: tuple[float, float], P_p: Sym, x_w: tuple[float, float], V_w: Sym):
    """Information-form fusion of a prior and a horizon estimate; ``(x, P, d2)`` or ``None`` if singular.

    ``d2`` is the squared Mahalanobis distance of the two, ``(x_w - x_p)' (P_p + V_w)^-1 (x_w - x_p)``
    (chi-square with 2 degrees of freedom when both describe the same soil).
    """
    Ip, Iw = _inv(P_p), _inv(V_w)
    S = _inv((P_p[0] + V_w[0], P_p[1] + V_w[1], P_p[2] + V_w[2]))
    if Ip is None or Iw is None or S is None:
        return None
    I = (Ip[0] + Iw[0], Ip[1] + Iw[1], Ip[2] + Iw[2])
    P = _inv(I)
    if P is None:
        return None
    h0 = Ip[0] * x_p[0] + Ip[1] * x_p[1] + Iw[0] * x_w[0] + Iw[1] * x_w[1]
    h1 = Ip[1] * x_p[0] + Ip[2] * x_p[1] + Iw[1] * x_w[0] + Iw[2] * x_w[1]
    x = (P[0] * h0 + P[1] * h1, P[1] * h0 + P[2] * h1)
    d0, d1 = x_w[0] - x_p[0], x_w[1] - x_p[1]
    d2 = S[0] * d0 * d0 + 2 * S[1] * d0 * d1 + S[2] * d1 * d1
    return x, P, d2


class HeldSoil:
    """The held estimate over (F_max, K) in SI, its covariance and the arrival-cost snapshots.

    Parameters
    ----------
    drift_F_rel, drift_K_rel
        Random-walk rates: standard deviation of the drift over one second, relative to the held
        value (per sqrt(s)).
    """

    def __init__(self, drift_F_rel: float, drift_K_rel: float) -> None:
        self.qF, self.qK = float(drift_F_rel), float(drift_K_rel)
        self.reset()

    def reset(self) -> None:
        """Forget everything (the start, a change of terrain)."""
        self.x: tuple[float, float] | None = None
        self.P: Sym | None = None
        self.t_ref = math.nan  # when x, P were last fused
        # (t, x, P, t_ref) of the held state after each update: the arrival cost of later horizons
        self._snaps: deque = deque()

    @property
    def known(self) -> bool:
        """Whether anything is held."""
        return self.x is not None

    def grown(self, x: tuple[float, float], P: Sym, dt: float) -> Sym:
        """``P + Q dt`` at the value ``x`` (the random walk over ``dt`` seconds)."""
        dt = max(dt, 0.0)
        return P[0] + (self.qF * x[0]) ** 2 * dt, P[1], P[2] + (self.qK * x[1]) ** 2 * dt

    def now(self, t: float) -> tuple[tuple[float, float], Sym] | None:
        """The held estimate and its covariance grown to time ``t`` (``None`` before anything is known)."""
        if self.x is None or self.P is None:
            return None
        return self.x, self.grown(self.x, self.P, t - self.t_ref)

    def prior(self, t_start: float, t: float) -> tuple[tuple[float, float], Sym] | None:
        """The arrival cost of a horizon whose samples start after ``t_start``: the state then, grown to ``t``."""
        snaps = self._snaps
        while len(snaps) >= 2 and snaps[1][0] <= t_start:
            snaps.popleft()
        if not snaps or snaps[0][0] > t_start:
            return None
        _, x, P, t_ref = snaps[0]
        return x, self.grown(x, P, t - t_ref)

    def set(self, t: float, x: tuple[float, float], P: Sym) -> None:
        """The state fused at time ``t``."""
        self.x, self.P, self.t_ref = x, P, t

    def snapshot(self, t: float, t_oldest: float) -> None:
        """Record the state after the update at ``t`` (the arrival cost of horizons starting after ``t_oldest``).

        A state unchanged since the last snapshot is not recorded again (the last one stands for it),
        and snapshots no horizon can ask for any more are dropped: a constant-size deque.
        """
        if self.x is None:
            return
        snaps = self._snaps
        if not snaps or snaps[-1][3] != self.t_ref:
            snaps.append((t, self.x, self.P, self.t_ref))
        while len(snaps) >= 2 and snaps[1][0] <= t_oldest:
            snaps.popleft()
