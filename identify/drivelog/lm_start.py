"""Start of the joint drive-log fit near its optimum: Levenberg-Marquardt on the profiled cost.

The joint problem (:mod:`.joint`) has a few global parameters ``theta`` (thrust limit,
K, effect parameters) and one latent slip per sample, each in its own sample's residual only.
For fixed ``theta`` every slip is a one-dimensional problem (:meth:`.joint.SlipSolver.solve`);
what is left is the profiled cost ``phi(theta) = sum_k min_i |e_k(theta, i)|^2 / 2`` in 2 to 5
variables. Its gradient is ``sum_k J_k^T e_k`` at the per-sample optimum (the slip's own
derivative vanishes there) and its exact Hessian is the Schur complement of each sample's
``(theta, i)`` Hessian, ``H_tt - H_ti H_it / H_ii`` (CasADi AD, mapped over the samples).

IPOPT solves the full problem, slips included, and its status is the fit's. Started from the
nominal soil with the effect off, it spent 110-190 iterations on logs from foreign simulators
(ill-conditioned latent slips, K on its bound; 14 ms each on 1,500 samples); started at the
optimum, with no bound push and a capped barrier parameter, it needs 4-9. A few projected
Levenberg-Marquardt steps on ``phi`` bring the start there; IPOPT then polishes and certifies (its
KKT test, its bounds). Nothing here is reported as a result: a start that did not converge is
still a start.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ...soilmodel.effects import EffectSet
from ...soilmodel.threadsafe import locked_cache
from ...soilmodel.vehicle import Vehicle
from .joint import SLIP_CHUNK, SlipSolver, chunked_outputs, cse_function, derivative_function, padded_data
from .prepare import SLIP_BOUNDS

__all__ = ["ProfiledStart", "profiled_start"]

#: Newton iterations of the latent slips per trial step (warm-started: most samples settle in 3-4;
#: a cost from slips not fully settled is an upper bound of the profiled cost, so a step it accepts
#: does descend). The final check of every start runs the full 40.
TRIAL_SLIP_ITERATIONS = 8


@dataclass(frozen=True)
class ProfiledStart:
    """Parameters and latent slips after the profiled iterations.

    ``theta`` in physical units (``[F_lim, K, effects...]``), ``slip`` per used sample,
    ``cost`` the profiled cost there, ``iterations`` the accepted steps, ``converged`` whether
    the projected gradient, the decrease of the cost or the descent left became negligible before
    ``max_iter`` (the slips then rechecked from every start).
    """

    theta: np.ndarray
    slip: np.ndarray
    cost: float
    iterations: int
    converged: bool


@locked_cache(maxsize=32)
def _sums_function(vehicle: Vehicle, structure: EffectSet) -> ca.Function:
    """Per-sample ``(theta, i, d) -> (cost, gradient, profiled Hessian, Gauss-Newton profiled Hessian)`` in theta.

    The profiled Hessian is the Schur complement ``H_tt - H_ti H_it / H_ii`` where the slip is inside its
    bounds and its own curvature positive (else ``H_tt``: the slip does not move with theta); the
    Gauss-Newton one is ``Jp^T Jp`` with the sensitivities projected off the slip's own.
    """
    der = derivative_function(vehicle, structure)
    p = der.size1_in(0)
    theta = ca.SX.sym("theta", p)
    slip = ca.SX.sym("slip")
    d = ca.SX.sym("d", der.size1_in(2))
    e, Jt, gi, H = der(theta, slip, d)
    lo, hi = SLIP_BOUNDS
    hii = H[p, p]
    conv = ca.logic_and(ca.logic_and(slip > lo + 1e-9, slip < hi - 1e-9), hii > 1e-300)
    hti = H[:p, p]
    red = H[:p, :p] - ca.if_else(conv, ca.mtimes(hti, hti.T) / ca.if_else(conv, hii, 1.0), ca.SX.zeros(p, p))
    gn = ca.sumsqr(gi)
    proj = ca.logic_and(conv, gn > 1e-300)
    Jp = Jt - ca.if_else(proj, ca.mtimes(gi, ca.mtimes(gi.T, Jt)) / ca.if_else(proj, gn, 1.0), ca.SX.zeros(Jt.shape))
    outs = [0.5 * ca.sumsqr(e), ca.mtimes(Jt.T, e), red, ca.mtimes(Jp.T, Jp)]
    return ca.Function("drivelog_profiled_sums", [theta, slip, d], outs)


@locked_cache(maxsize=32)
def _sums_kernels(vehicle: Vehicle, structure: EffectSet):
    """:func:`_sums_function` mapped over :data:`~.joint.SLIP_CHUNK` samples (per-sample outputs), from C
    code when the per-user cache has it (:func:`~soiltrack.identify.jitcache.load` without waiting: the
    virtual machine answers until the library, compiled once per machine after the process that first needs
    it exits, is there)."""
    from ..jitcache import load

    sums = _sums_function(vehicle, structure)
    kernels = load([sums.map(SLIP_CHUNK)], "drivelog_sums", wait=False, defer=True)
    if not kernels.is_c:  # until the C code is there: common subexpressions merged (1,031 -> 837 instructions)
        kernels.functions = [cse_function(sums).map(SLIP_CHUNK)]
    return kernels


class _Sums:
    """The sums over the samples of :func:`_sums_function`, the data padded once.

    The per-sample outputs come from the chunked kernel (C code once compiled) through
    :func:`~soiltrack.soilmodel.dense_call.call_dense`; they are summed in sample order, one after the
    other (``numpy.cumsum``), as CasADi's summing map (``map(..., [0, 1, 2, 3])``) adds them: the same
    numbers as that map, at a fraction of its time (measured 22.9 ms -> 1.8 ms per call, 3,001 samples,
    three effect parameters).
    """

    def __init__(self, vehicle: Vehicle, structure: EffectSet, D: np.ndarray) -> None:
        kernels = _sums_kernels(vehicle, structure)
        kernels.upgrade()
        self.fn = kernels.functions[0]
        self.n = int(D.shape[1])
        size = -(-self.n // SLIP_CHUNK) * SLIP_CHUNK
        D = np.asarray(D, dtype=float)
        self.D = D if D.shape[1] == size else padded_data(D, size)  # already padded: shared, not copied

    def __call__(self, theta: np.ndarray, slip: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        n = self.n
        sums = []
        for o in chunked_outputs(self.fn, theta, np.asarray(slip, dtype=float).ravel()[:n], self.D):
            rows, cols = o.shape[0], o.shape[1] // max(n, 1)
            if n == 0:
                sums.append(np.zeros((rows, cols)))
                continue
            sums.append(_sequential_sum(o.reshape(rows, n, cols)).reshape(rows, cols))
        c, g, Hr, Hgn = sums
        return float(c[0, 0]), g.ravel(), Hr, Hgn


#: Samples summed per block by :func:`_sequential_sum` (its temporary memory; the sum does not depend on it).
SUM_BLOCK = 65_536


def _sequential_sum(o: np.ndarray) -> np.ndarray:
    """``o`` (``rows x n x cols``) summed over the samples one after the other, as ``numpy.cumsum``'s last row:
    block by block with the running sum carried in front, so the same additions in the same order (the same
    numbers) with temporaries of :data:`SUM_BLOCK` samples instead of the log's length."""
    rows, n, cols = o.shape
    carry: np.ndarray | None = None
    for a in range(0, n, SUM_BLOCK):
        block = o[:, a : a + SUM_BLOCK, :].transpose(1, 0, 2).reshape(-1, rows * cols)
        if carry is not None:
            block = np.vstack([carry, block])
        carry = np.cumsum(block, axis=0)[-1:]
    return np.zeros(rows * cols) if carry is None else carry[0]


def profiled_start(
    vehicle: Vehicle,
    structure: EffectSet,
    D: np.ndarray,
    theta0: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    scale: np.ndarray,
    slip_starts: list[np.ndarray],
    max_iter: int = 30,
    tol: float = 1e-7,
) -> ProfiledStart:
    """Projected Levenberg-Marquardt on the profiled cost from ``theta0`` inside ``[lower, upper]``.

    Parameters
    ----------
    vehicle, structure
        As for :func:`.joint.residual_function`.
    D
        Per-sample data (rows of :data:`.joint.DATA_ROWS`), used samples only.
    theta0, lower, upper, scale
        Start, bounds (equal for a fixed parameter) and typical sizes of ``[F_lim, K, effects...]``.
    slip_starts
        Starts of the latent slips (the per-sample cost can have two minima; the lowest is kept,
        at the start and again at the end).
    max_iter, tol
        Accepted steps at most; relative decrease of the cost deemed negligible.
    """
    lo, hi = SLIP_BOUNDS
    sc = np.asarray(scale, dtype=float)
    xl, xu = np.asarray(lower, dtype=float) / sc, np.asarray(upper, dtype=float) / sc
    x = np.clip(np.asarray(theta0, dtype=float) / sc, xl, xu)
    fixed = xu - xl <= 0.0
    slips = SlipSolver(vehicle, structure, D)
    sums = _Sums(vehicle, structure, D)
    slip = slips.best(x * sc, slip_starts, TRIAL_SLIP_ITERATIONS)
    cost, g, Hr, Hgn = sums(x * sc, slip)
    if not (math.isfinite(cost) and np.all(np.isfinite(g)) and np.all(np.isfinite(Hr)) and np.all(np.isfinite(Hgn))):
        # nothing to descend on (a non-finite residual somewhere): the start as given, IPOPT judges it
        return ProfiledStart(theta=x * sc, slip=np.clip(slip, lo, hi), cost=cost, iterations=0, converged=False)
    lam = 1e-3
    it = 0
    converged = False
    rechecked = False
    S = np.outer(sc, sc)
    while it < max_iter:
        gs = g * sc
        # active set: fixed, or on a bound with the gradient pushing outwards
        span = np.maximum(xu - xl, 1e-300)
        at_lo = (x - xl <= 1e-9 * span) & (gs > 0)
        at_hi = (xu - x <= 1e-9 * span) & (gs < 0)
        free = ~(fixed | at_lo | at_hi)
        pg = np.where(free, gs, 0.0)
        if not np.any(free) or np.max(np.abs(pg)) <= 1e-9 * max(cost, 1e-300):
            converged = True
        else:
            Hs = (Hr * S)[np.ix_(free, free)]
            w = np.linalg.eigvalsh(0.5 * (Hs + Hs.T))
            if w[0] <= 1e-12 * max(w[-1], 1e-300):  # the exact profiled Hessian is not convex here
                Hs = (Hgn * S)[np.ix_(free, free)]
            d = np.diag(Hs).copy()
            d = np.where(d > 0, d, 1.0)
            accepted = False
            for _ in range(12):
                try:
                    step = np.linalg.solve(Hs + lam * np.diag(d), -gs[free])
                except np.linalg.LinAlgError:
                    lam *= 10.0
                    continue
                xn = x.copy()
                xn[free] = np.clip(x[free] + step, xl[free], xu[free])
                sn = slips.solve(xn * sc, slip, TRIAL_SLIP_ITERATIONS)
                cn = float(np.sum(slips.costs(xn * sc, sn)))
                if np.isfinite(cn) and cn < cost:
                    rel = (cost - cn) / max(cost, 1e-300)
                    x, slip = xn, sn
                    lam = max(lam / 3.0, 1e-9)
                    accepted = True
                    it += 1
                    cost, g, Hr, Hgn = sums(x * sc, slip)
                    if not (np.all(np.isfinite(g)) and np.all(np.isfinite(Hr)) and np.all(np.isfinite(Hgn))):
                        return ProfiledStart(
                            theta=x * sc, slip=np.clip(slip, lo, hi), cost=cost, iterations=it, converged=False
                        )
                    if rel <= tol:
                        converged = True
                    break
                lam *= 4.0
            if not accepted:
                converged = True  # no descent left at this precision
        if converged:
            if rechecked:
                break
            # the per-sample minima again from every start: a slip may sit in a worse local minimum
            rechecked = True
            s2 = slips.best(x * sc, [slip] + list(slip_starts))
            c2 = float(np.sum(slips.costs(x * sc, s2)))
            if c2 < cost * (1 - 1e-12):
                slip = s2
                cost, g, Hr, Hgn = sums(x * sc, slip)
                converged = False
                continue
            break
    return ProfiledStart(theta=x * sc, slip=np.clip(slip, lo, hi), cost=cost, iterations=it, converged=converged)
