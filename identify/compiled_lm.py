"""The compiled single-fit engine: a bounded Levenberg-Marquardt solve as ONE CasADi call.

``fit(data, vehicle, engine="compiled")`` (and small groups in ``fit_many``) solve the same
bounded weighted least-squares problem as the IPOPT path,

    minimise  0.5 * sum_k ((F(i_k; c, phi, K, W_k) - F_k) / sigma_k)^2   within the bounds,

with a solver whose whole run is one pre-built CasADi ``Function``, built once per
``(p, n_points, n_grid)`` (p = 2 or 3 free parameters) and cached, called once per fit
through a zero-copy buffer (no per-call conversion of the arguments):

1. **Start**: variable projection on a grid of K (as :mod:`soiltrack.identify.start`: for each
   K the linear parameters ``(c, tan(phi))`` from weighted linear least squares, projected
   onto the bounds; the grid point of lowest cost), evaluated inside the Function. Here the
   ``n_grid`` values of K are uniform in 1/K rather than geometric (``exp(-|i| l / K)`` then
   follows from one K to the next by one multiplication; the local iteration converges to
   the same optimum from either start). A given ``x0`` replaces it.
2. **Iteration**: up to ``N_ITER`` projected, damped Newton steps in the scaled variables of
   the IPOPT path (``c / 1 kPa``, ``phi / 1 rad``, ``K / 1 cm``): exact Hessian of the cost
   (closed-form derivatives of Eq. 2, checked against CasADi AD in the tests) plus
   Levenberg-Marquardt damping ``lam * diag(J^T J)``; variables on a bound whose gradient
   points outwards are held (active set); the trial point is projected onto the box and
   accepted if the cost does not increase (``lam / 10``), else rejected (``lam * 10``); at
   the rounding floor of the cost (relative change below 1e-13) a step is also accepted when
   it shrinks the free part of the gradient (Newton's endgame, where cost decreases are below
   rounding). The exact Hessian converges quadratically also on large-residual data (e.g.
   Wong's three points, where Gauss-Newton converges only linearly). Each iteration is a
   conditional call that is skipped once the first-order test below holds.
3. **Certification** (in Python, from the Function's outputs, not on trust): finite numbers,
   inside the bounds, and the first-order (KKT) conditions for the box: the projected
   gradient ``|| g_free ||`` at most ``KKT_TOL`` times ``sqrt(trace(J^T J) * 2 cost)`` (the
   same relative test as the vectorised batch engine), or a cost that is zero to rounding.
   A fit the engine cannot certify is handed to the cached IPOPT solver (said in the message;
   ``extra["engine"] == "ipopt"``).

The per-sample work is mapped (a loop in the generated code), and the Function is compiled
to C with the system C compiler (CasADi's ``shell`` JIT, ``-O2``, in a private temporary
folder removed at exit) - about 2 s once per ``(p, n_points, n_grid)``. Without a compiler
(or with the environment variable ``SOILTRACK_NO_JIT`` set) CasADi's virtual machine
evaluates the same Function, a few times slower.

The full model at ONE normal load is solved exactly as the IPOPT path does it: in the
identifiable parameters ``(F_max, K)`` (``F_max = W tan(phi_e)``, with the bounds box of
``(c, phi)`` mapped onto bounds of ``phi_e``), then mapped onto the centre of the
bounds-feasible ridge ``A c + W tan(phi) = F_max`` (an arbitrary ridge point, reported as
such by :class:`~soiltrack.identify.FitResult`).

Results are labelled ``method="ipopt"`` (the estimator: bounded least squares within the
practical ranges, the same optimum) with ``extra["engine"]`` = ``"compiled-lm"`` (or
``"ipopt"`` after a hand-over), status ``"Compiled_LM_Converged"``. The FitResult is built by
the shared :func:`~soiltrack.identify.build_result` from the residuals and the Jacobian at
the optimum (from the Function's outputs), so uncertainty, identifiability and warnings are
those of any other path.
"""
from __future__ import annotations

import atexit
import math
import os
import shutil
import tempfile
import threading
import time
from functools import lru_cache

import casadi as ca
import numpy as np

from ..soilmodel.traction import SERIES_SWITCH, shear_bracket
from .problem import SCALE, SlipProblem, ridge_centre
from .result import FitResult, build_result

__all__ = ["compiled_solver", "fit_compiled", "N_ITER", "KKT_TOL"]

#: Most damped-Newton iterations per call (skipped once converged; typically 2-6 are run).
N_ITER = 40
#: Relative first-order tolerance (projected gradient vs sqrt(trace(J^T J) * 2 cost)).
KKT_TOL = 1e-9
#: A cost below this fraction of 0.5 * sum((F / sigma)^2) is a zero-residual (global) optimum.
ZERO_COST = 1e-24
_BLOCK = 5  # iterations per skippable block
_EPS_B = 1e-12  # relative distance to a bound counted as "on it" (of the bound range)


def _fit_residuals(z, d, n: int, p: int):
    """Weighted residuals (n) as SX of the scaled variables ``z`` and the data vector ``d``."""
    slip, force, W, sig = d[0:n], d[n:2 * n], d[2 * n:3 * n], d[3 * n:4 * n]
    l, b = d[4 * n], d[4 * n + 1]
    if p == 3:
        c, phi, K = z[0] * SCALE[0], z[1], z[2] * SCALE[2]
        fmax = 2 * b * l * c + W * ca.tan(phi)
    else:
        phi, K = z[0], z[1] * SCALE[2]
        fmax = W * ca.tan(phi)
    return (fmax * shear_bracket(slip * l / K) - force) / sig


def _bracket_d2(x):
    """``g(x) = 1 - (1 - exp(-x))/x`` and its first two derivatives for x >= 0 (SX).

    Exact form above ``SERIES_SWITCH`` (0.05, as in :mod:`soiltrack.soilmodel.traction`), the
    Taylor series below (truncation < 1e-14 relative): no division by zero, F(0) = 0.
    Closed forms: ``g' = (1 - e - x e) / x^2``, ``g'' = (e - 2 g') / x`` with ``e = exp(-x)``.
    """
    small = x < SERIES_SWITCH
    xs = ca.if_else(small, 1.0, x)
    E = ca.expm1(-xs)
    g_ex = 1 + E / xs
    d1_ex = (-E - xs * (E + 1)) / (xs * xs)
    d2_ex = (E + 1 - 2 * d1_ex) / xs
    # series: g = sum_{k>=1} (-1)^(k+1) x^k / (k+1)!
    cs = [(-1) ** (k + 1) / math.factorial(k + 1) for k in range(1, 10)]
    g_s = 0
    for k in range(9, 0, -1):
        g_s = (g_s + cs[k - 1]) * x
    d1_s = 0
    for k in range(9, 0, -1):
        d1_s = d1_s * x + k * cs[k - 1]
    d2_s = 0
    for k in range(9, 1, -1):
        d2_s = d2_s * x + k * (k - 1) * cs[k - 1]
    return (ca.if_else(small, g_s, g_ex), ca.if_else(small, d1_s, d1_ex), ca.if_else(small, d2_s, d2_ex))


def _point_functions(p: int, n_grid: int):
    """Per-sample SX Functions (mapped over the samples; compact generated code for any n).

    ``pt_ev`` gives the sample's cost, gradient, exact Hessian and squared Jacobian row in the
    scaled variables from closed-form derivatives of Eq. 2 (checked against CasADi AD in the
    tests); ``pt_grid`` the sums of the variable-projection grid (start point only, so the
    bracket is evaluated with a short series below x = 1e-4).
    """
    s, F, W, sig, l, b = (ca.SX.sym(k) for k in ("s", "F", "W", "sig", "l", "b"))
    Ks = ca.SX.sym("Ks", n_grid)  # grid of K, uniform in 1/K: x_j = |i| l / K_j is uniform in j
    Ki = ca.SX.sym("Ki", n_grid)  # 1 / Ks (no division per sample and K)
    y = F / sig
    a = ca.fabs(s) * l
    ainv = 1 / ca.fmax(a, 1e-300)
    e = ca.exp(-a * Ki[0])
    q = ca.exp(-a * (Ki[1] - Ki[0])) if n_grid > 1 else 1
    gs = []
    for j in range(n_grid):  # exp(-x_j) by recurrence: one exp per sample instead of one per K
        xj = a * Ki[j]
        gs.append(ca.if_else(xj < 1e-4, xj * (0.5 - xj * (1 / 6)), 1 - (1 - e) * (Ks[j] * ainv)))
        e = e * q
    g = ca.vertcat(*gs)
    sgn_sig = ca.sign(s) / sig
    a2 = (W * sgn_sig) * g
    if p == 3:
        a1 = (2 * b * l * sgn_sig) * g
        sums = ca.vertcat(a1 * a1, a1 * a2, a2 * a2, a1 * y, a2 * y)
    else:
        sums = ca.vertcat(a2 * a2, a2 * y)
    grid = ca.Function("pt_grid", [s, F, W, sig, l, b, Ks, Ki], [sums, y * y], {"cse": True})
    z = ca.SX.sym("z", p)
    phi, u = z[p - 2], z[p - 1]
    K = u * SCALE[2]
    sgn = ca.sign(s)
    x = ca.fabs(s) * l / K
    g0, g1, g2 = _bracket_d2(x)
    sg = sgn * g0
    dsg = sgn * g1 * (-x / u)                      # d sg / du
    d2sg = sgn * (g2 * x * x + 2 * g1 * x) / (u * u)  # d2 sg / du2
    t = ca.tan(phi)
    sec2 = 1 + t * t
    fm = W * t + (2 * b * l * SCALE[0] * z[0] if p == 3 else 0)
    r = (fm * sg - F) / sig
    dphi = W * sec2 / sig
    gr = [dphi * sg, fm / sig * dsg]  # dr/dphi, dr/du
    H2 = [[2 * t * dphi * sg, dphi * dsg], [dphi * dsg, fm / sig * d2sg]]
    if p == 3:
        ac = 2 * b * l * SCALE[0] / sig
        gr = [ac * sg] + gr
        H2 = [[0, 0, ac * dsg], [0] + H2[0], [ac * dsg] + H2[1]]
    gr = ca.vertcat(*gr)
    Hr = ca.blockcat([[ca.SX(v) if not isinstance(v, ca.SX) else v for v in row] for row in H2])
    Hf = ca.mtimes(gr, gr.T) + r * Hr
    ev = ca.Function("pt_ev", [z, s, F, W, sig, l, b], [ca.vertcat(0.5 * r * r, r * gr, ca.vec(Hf), gr * gr)], {"cse": True})
    # at the optimum: raw residual r, sg / sigma (dF/dF_max / sigma) and dF/dK / sigma (SI)
    sgf = ca.Function("pt_res", [z, s, F, W, sig, l, b], [ca.vertcat(fm * sg - F, sg / sig, fm / sig * dsg / SCALE[2])],
                      {"cse": True})
    return grid, ev, sgf


@lru_cache(maxsize=64)
def compiled_solver(p: int, n: int, n_grid: int = 25, n_iter: int = N_ITER, jit: bool | None = None) -> ca.Function:
    """The cached solver Function for ``p`` free parameters (2 or 3) and ``n`` samples.

    The returned Function takes ONE vector ``x = [d, lbz, ubz, z0, use_z0]`` and returns ONE
    vector ``y``, the concatenation of the outputs below (so that it can be called through a
    zero-copy buffer). Inputs: ``d = [slip (n), F (n), W (n), sigma (n), l, b]``, ``lbz, ubz``
    (scaled bounds), ``z0`` (scaled start, used when ``use_z0 = 1``), ``use_z0``.
    Outputs: ``z`` (scaled optimum), ``cost`` (0.5 sum of squared weighted residuals),
    ``g`` (gradient of the cost in z), ``trJJ`` (trace of J^T J in z), ``iters`` (iterations
    run until the first-order test held), ``zstart`` (start used), ``scale``
    (0.5 sum (F / sigma)^2), and at the optimum ``r`` (n, model minus data, N), ``sgw``
    (n, ``sign(i) g(|i| l / K) / sigma``) and ``JK`` (n, ``dF/dK / sigma``, SI).
    The start grid has ``n_grid`` K values uniform in 1/K (so that ``exp(-|i| l / K)``
    follows by one multiplication from one K to the next).

    The per-sample work is mapped (a loop in the generated code) and each iteration is a
    conditional call that is skipped once the first-order test holds, so the cost is that of
    the grid plus the iterations actually needed. Compiled to C with the system compiler
    (CasADi's ``shell`` JIT) when one is available (``jit=None``: unless the environment
    variable ``SOILTRACK_NO_JIT`` is set), else evaluated by CasADi's virtual machine.
    """
    n_grid = max(int(n_grid), 1)
    pt_grid, pt_ev, pt_sg = _point_functions(p, n_grid)
    d = ca.MX.sym("d", 4 * n + 2)
    lbz, ubz, z0, use0 = ca.MX.sym("lbz", p), ca.MX.sym("ubz", p), ca.MX.sym("z0", p), ca.MX.sym("use_z0")
    slip, force, W, sig = (d[k * n:(k + 1) * n].T for k in range(4))
    l, b = d[4 * n], d[4 * n + 1]

    # ---- 1. variable-projection grid start (same construction as start.grid_start; the
    # residual cost of each K from the sums: |y|^2 - 2 c r1 - 2 t r2 + c^2 m11 + 2 c t m12 + t^2 m22)
    sc = ca.SX.sym("sums", (5 if p == 3 else 2) * n_grid)
    yy_s = ca.SX.sym("yy")
    lz, uz, Kg = ca.SX.sym("lz", p), ca.SX.sym("uz", p), ca.SX.sym("Kg", n_grid)
    if p == 3:
        m11, m12, m22, r1, r2 = (sc[k * n_grid:(k + 1) * n_grid] for k in range(5))
    else:
        m22, r2 = sc[0:n_grid], sc[n_grid:2 * n_grid]
    t_lo, t_hi = ca.tan(lz[p - 2]), ca.tan(uz[p - 2])
    if p == 3:
        c_lo, c_hi = lz[0] * SCALE[0], uz[0] * SCALE[0]
        det = m11 * m22 - m12 * m12
        ok = det > 1e-10 * m11 * m22
        c = ca.if_else(ok, (m22 * r1 - m12 * r2) / ca.if_else(ok, det, 1.0), 0.0)
        c = ca.fmin(ca.fmax(c, c_lo), c_hi)
        t = (r2 - c * m12) / ca.if_else(m22 > 0, m22, 1.0)
        t = ca.fmin(ca.fmax(t, t_lo), t_hi)
        c2 = (r1 - t * m12) / ca.if_else(m11 > 0, m11, 1.0)
        c = ca.if_else(ok, c, ca.fmin(ca.fmax(c2, c_lo), c_hi))
        cost = yy_s - 2 * c * r1 - 2 * t * r2 + c * c * m11 + 2 * c * t * m12 + t * t * m22
    else:
        t = ca.fmin(ca.fmax(r2 / ca.if_else(m22 > 0, m22, 1.0), t_lo), t_hi)
        c = ca.SX.zeros(n_grid)
        cost = yy_s - 2 * t * r2 + t * t * m22
    best = (cost[0], c[0], t[0], Kg[0])
    for j in range(1, n_grid):
        better = cost[j] < best[0]  # NaN never wins
        best = tuple(ca.if_else(better, new, old) for new, old in zip((cost[j], c[j], t[j], Kg[j]), best))
    _, c_b, t_b, K_b = best
    zg = ca.vertcat(c_b / SCALE[0], ca.atan(t_b), K_b / SCALE[2]) if p == 3 else \
        ca.vertcat(ca.atan(t_b), K_b / SCALE[2])
    pick = ca.Function("pick", [sc, yy_s, lz, uz, Kg], [zg])
    K_lo, K_hi = lbz[p - 1] * SCALE[2], ubz[p - 1] * SCALE[2]
    frac = np.linspace(0.0, 1.0, n_grid) if n_grid > 1 else np.zeros(1)
    Kinv = 1 / K_hi + ca.DM(frac) * (1 / K_lo - 1 / K_hi)  # uniform in 1/K
    Kgrid = 1 / Kinv
    # mapped over the samples with the sums accumulated in the loop (reduce_out)
    gm, yy = pt_grid.map("grid_sums", "serial", n, [4, 5, 6, 7], [0, 1])(slip, force, W, sig, l, b, Kgrid, Kinv)
    zgrid = pick(gm, yy, lbz, ubz, Kgrid)
    zs = ca.if_else(use0 > 0.5, z0, zgrid)
    zs = ca.fmin(ca.fmax(zs, lbz), ubz)
    scale = 0.5 * yy

    # ---- 2. damped projected Newton iterations (state: z, lam, f, g, H, D, done, iters)
    evm = pt_ev.map("ev_sums", "serial", n, [0, 5, 6], [0])

    def evaluate(z):
        s = evm(z, slip, force, W, sig, l, b)
        return s[0], s[1:1 + p], ca.reshape(s[1 + p:1 + p + p * p], p, p), s[1 + p + p * p:]

    zS, gS, DS, fS, scS = ca.SX.sym("z", p), ca.SX.sym("g", p), ca.SX.sym("D", p), ca.SX.sym("f"), ca.SX.sym("sc")
    epsS = _EPS_B * (uz - lz)
    act = ca.logic_or(ca.logic_and(zS <= lz + epsS, gS > 0), ca.logic_and(zS >= uz - epsS, gS < 0))
    gp = ca.if_else(act, ca.SX.zeros(p), gS)
    done = ca.logic_or(ca.norm_2(gp) <= KKT_TOL * ca.sqrt(ca.sum1(DS) * 2 * fS), fS <= ZERO_COST * scS)
    kkt = ca.Function("kkt", [zS, fS, gS, DS, lz, uz, scS], [done, act])
    HS, lamS = ca.SX.sym("H", p, p), ca.SX.sym("lam")
    m = 1 - act
    Hd = HS + lamS * ca.diag(ca.fmax(DS, 1e-300))
    Hr = (m @ m.T) * Hd + ca.diag(1 - m)
    zt = ca.fmin(ca.fmax(zS + ca.solve(Hr, -m * gS), lz), uz)
    trial = ca.Function("trial", [zS, lamS, gS, HS, DS, lz, uz], [zt, m])
    # acceptance: the cost does not increase; or, at the rounding floor of the cost (relative
    # change below 1e-13), the free part of the gradient shrinks (Newton's endgame)
    ftS, gtS, mS = ca.SX.sym("ft"), ca.SX.sym("gt", p), ca.SX.sym("m", p)
    accept = ca.Function("accept", [ftS, fS, gtS, gS, mS], [ca.logic_or(
        ftS <= fS, ca.logic_and(ftS <= fS + 1e-13 * ca.fabs(fS), ca.norm_2(mS * gtS) < ca.norm_2(mS * gS)))])

    nst = 3 * p + p * p + 3
    st = ca.MX.sym("state", nst)
    sz, slam, sf, sg_ = st[0:p], st[p], st[p + 1], st[p + 2:2 * p + 2]
    sH = ca.reshape(st[2 * p + 2:2 * p + 2 + p * p], p, p)
    sD, sit = st[2 * p + 2 + p * p:3 * p + 2 + p * p], st[nst - 1]
    d_, lbz_, ubz_ = ca.MX.sym("d", 4 * n + 2), ca.MX.sym("lbz", p), ca.MX.sym("ubz", p)
    # the iteration needs the data: rebuild the data views on its own symbols
    slip_, force_, W_, sig_ = (d_[k * n:(k + 1) * n].T for k in range(4))
    l_, b_ = d_[4 * n], d_[4 * n + 1]
    zt_, m_ = trial(sz, slam, sg_, sH, sD, lbz_, ubz_)
    s_ = evm(zt_, slip_, force_, W_, sig_, l_, b_)
    ft, gt, Ht, Dt = s_[0], s_[1:1 + p], s_[1 + p:1 + p + p * p], s_[1 + p + p * p:]
    acc = accept(ft, sf, gt, sg_, m_)  # NaN is rejected
    new_z = ca.if_else(acc, zt_, sz)
    new = ca.vertcat(new_z, ca.if_else(acc, ca.fmax(slam * 0.1, 1e-15), ca.fmin(slam * 10, 1e20)),
                     ca.if_else(acc, ft, sf), ca.if_else(acc, gt, sg_), ca.if_else(acc, Ht, ca.vec(sH)),
                     ca.if_else(acc, Dt, sD), sit + 1)
    step_f = ca.Function("lm_step", [st, d_, lbz_, ubz_], [new])
    keep_f = ca.Function("lm_keep", [st, d_, lbz_, ubz_], [st])
    cond = ca.Function.conditional("lm_iter", [step_f], keep_f)  # index 0: iterate; else: keep
    sc_ = ca.MX.sym("scale")

    def converged(s, lo, hi, scl):
        return kkt(s[0:p], s[p + 1], s[p + 2:2 * p + 2], s[2 * p + 2 + p * p:3 * p + 2 + p * p], lo, hi, scl)[0]

    # blocks of BLOCK conditional iterations, each block skipped as a whole once converged
    sb = st
    for _ in range(_BLOCK):
        sb = cond(converged(sb, lbz_, ubz_, sc_), sb, d_, lbz_, ubz_)
    block_f = ca.Function("lm_block", [st, d_, lbz_, ubz_, sc_], [sb])
    keep_b = ca.Function("lm_keep_block", [st, d_, lbz_, ubz_, sc_], [st])
    cond_b = ca.Function.conditional("lm_blocks", [block_f], keep_b)

    f0, g0, H0, D0 = evaluate(zs)
    state = ca.vertcat(zs, 1e-3, f0, g0, ca.vec(H0), D0, 0)
    for _ in range(-(-n_iter // _BLOCK)):
        state = cond_b(converged(state, lbz, ubz, scale), state, d, lbz, ubz, scale)
    zf = state[0:p]
    # ---- 3. what the result needs at the optimum: sign(i) g and its K derivative
    sgd = pt_sg.map(n, "serial")(zf, slip, force, W, sig, l, b)
    f = ca.Function(f"soilfit_clm_{p}_{n}_{n_grid}_{n_iter}", [d, lbz, ubz, z0, use0],
                    [zf, state[p + 1], state[p + 2:2 * p + 2], ca.sum1(state[2 * p + 2 + p * p:3 * p + 2 + p * p]),
                     state[nst - 1], zs, scale, sgd[0, :].T, sgd[1, :].T, sgd[2, :].T],
                    ["d", "lbz", "ubz", "z0", "use_z0"],
                    ["z", "cost", "g", "trJJ", "iters", "zstart", "scale", "r", "sgw", "JK"])
    # one flat input and one flat output: called through a zero-copy buffer (no conversions)
    xin = ca.MX.sym("x", 4 * n + 3 + 3 * p)
    o = 4 * n + 2
    flat = ca.Function(f"soilfit_clm_{p}_{n}_{n_grid}_{n_iter}_flat", [xin],
                       [ca.vertcat(*f(xin[0:o], xin[o:o + p], xin[o + p:o + 2 * p], xin[o + 2 * p:o + 3 * p],
                                      xin[o + 3 * p]))], ["x"], ["y"])
    if jit is None:
        jit = not os.environ.get("SOILTRACK_NO_JIT")
    return _jit(flat) if jit else flat


class _Caller:
    """Zero-copy caller of a flat Function (one input vector, one output vector); thread-safe."""

    def __init__(self, f: ca.Function) -> None:
        self.f = f
        self.n_in, self.n_out = f.size1_in(0), f.size1_out(0)
        self.lock = threading.Lock()
        self.x = np.zeros(self.n_in)
        self.y = np.zeros(self.n_out)
        try:
            self.buf, self.trigger = f.buffer()
            self.buf.set_arg(0, memoryview(self.x))
            self.buf.set_res(0, memoryview(self.y))
        except Exception:  # pragma: no cover - CasADi without buffers: ordinary (slower) calls
            self.trigger = None

    def __call__(self, x: np.ndarray) -> np.ndarray:
        if self.trigger is None:  # pragma: no cover
            return np.asarray(self.f(np.asarray(x, float)), float).ravel()
        with self.lock:
            self.x[:] = x
            self.trigger()
            return self.y.copy()


@lru_cache(maxsize=64)
def _caller(p: int, n: int, n_grid: int) -> _Caller:
    """The cached zero-copy caller of :func:`compiled_solver` ``(p, n, n_grid)``."""
    return _Caller(compiled_solver(p, n, n_grid))


_JIT_DIR: list[str] = []
_JIT_LOCK = threading.Lock()


def _jit(f: ca.Function) -> ca.Function:
    """Compile ``f`` to C with the system compiler in a private temporary folder; ``f`` on failure."""
    with _JIT_LOCK:
        return _jit_locked(f)


def _jit_locked(f: ca.Function) -> ca.Function:
    try:
        if not _JIT_DIR:
            _JIT_DIR.append(tempfile.mkdtemp(prefix="soiltrack_clm_"))
            atexit.register(shutil.rmtree, _JIT_DIR[0], True)
        folder = _JIT_DIR[0] + os.sep
        name = f.name()
        cg = ca.CodeGenerator(name + ".c", {"with_header": False})
        cg.add(f)
        cg.generate(folder)
        imp = ca.Importer(folder + name + ".c", "shell", {"directory": folder, "flags": ["-O2"], "cleanup": False})
        g = ca.external(name, imp)
        return g
    except Exception:  # no compiler, or it failed: the virtual machine evaluates the same Function
        return f


def fit_compiled(pb: SlipProblem, x0=None, n_grid: int = 25, ipopt_options: dict | None = None) -> FitResult:
    """Fit a :class:`SlipProblem` with the compiled engine; hand over to IPOPT if not certified.

    Parameters
    ----------
    pb : SlipProblem
    x0 : ndarray, optional
        Start ``[c, phi, K]`` (SI); default: the variable-projection grid.
    n_grid : int
        K values of the start grid.
    ipopt_options : dict, optional
        Options for the IPOPT hand-over.
    """
    t0 = time.perf_counter()
    W = pb.load
    W0 = float(W[0])
    one_load = pb.model == "full" and bool(np.all(np.abs(W - W0) <= 1e-9 * abs(W0)))
    p = 3 if (pb.model == "full" and not one_load) else 2
    n = pb.n
    call = _caller(p, n, int(n_grid))  # built (and compiled) once per (p, n, n_grid), then cached
    bnd = pb.bounds
    l, b = pb.vehicle.track_length, pb.vehicle.track_width
    A = 2.0 * b * l
    (c_lo, c_hi), (p_lo, p_hi), (K_lo, K_hi) = bnd.cohesion, bnd.friction_angle, bnd.shear_modulus
    sK = SCALE[2]
    if one_load:
        F_lo, F_hi = A * c_lo + W0 * math.tan(p_lo), A * c_hi + W0 * math.tan(p_hi)
        lbz = [math.atan(F_lo / W0), K_lo / sK]
        ubz = [math.atan(F_hi / W0), K_hi / sK]
    elif p == 3:
        lbz = [c_lo / SCALE[0], p_lo, K_lo / sK]
        ubz = [c_hi / SCALE[0], p_hi, K_hi / sK]
    else:
        lbz = [p_lo, K_lo / sK]
        ubz = [p_hi, K_hi / sK]
    if x0 is None:
        z0, use0 = [0.0] * p, 0.0
    else:
        x0 = np.asarray(x0, float)
        if one_load:
            z0 = [math.atan((A * x0[0] + W0 * math.tan(x0[1])) / W0), x0[2] / sK]
        elif p == 3:
            z0 = [x0[0] / SCALE[0], x0[1], x0[2] / sK]
        else:
            z0 = [x0[1], x0[2] / sK]
        use0 = 1.0
    t1 = time.perf_counter()
    y = call(np.concatenate((pb.slip, pb.force, W, pb.sigma, [l, b], lbz, ubz, z0, [use0])))
    t_call = time.perf_counter() - t1
    # y = [z (p), cost, g (p), trJJ, iters, zstart (p), scale, r (n), sg / sigma (n), dF/dK / sigma (n)]
    z = y[0:p]
    cost = float(y[p])
    g = y[p + 1:2 * p + 1]
    trJJ, iters = float(y[2 * p + 1]), y[2 * p + 2]
    zs = y[2 * p + 3:3 * p + 3]
    scale = float(y[3 * p + 3])
    o = 3 * p + 4
    # ---- certify: finite, inside the bounds, first-order conditions with bounds
    ok = math.isfinite(cost) and math.isfinite(trJJ)
    gp2 = 0.0
    for j in range(p):
        zj, gj, lo, hi = float(z[j]), float(g[j]), lbz[j], ubz[j]
        if not (math.isfinite(zj) and math.isfinite(gj) and lo <= zj <= hi):
            ok = False
            break
        eps = _EPS_B * (hi - lo)
        if not ((zj <= lo + eps and gj > 0) or (zj >= hi - eps and gj < 0)):
            gp2 += gj * gj
    if ok:
        ok = math.sqrt(gp2) <= KKT_TOL * math.sqrt(trJJ * 2.0 * cost) or cost <= ZERO_COST * scale
    if not ok:
        return _hand_over(pb, z, p, one_load, x0, n_grid, ipopt_options, t0)
    # ---- theta (SI), the ridge point for one-load full data (as the IPOPT path does it)
    K = float(z[-1]) * sK
    if one_load:
        c, phi = ridge_centre(W0 * math.tan(float(z[0])), W0, A, pb.bounds)
        theta = np.array([float(c), float(phi), K])
    elif p == 3:
        theta = np.array([float(z[0]) * SCALE[0], float(z[1]), K])
    else:
        theta = np.array([0.0, float(z[0]), K])
    # ---- residuals and Jacobian at theta from the Function's outputs (F_max is the same at
    # every point of the one-load ridge, so r and dF/dK are too)
    r = y[o:o + n]
    sgw = y[o + n:o + 2 * n]
    tphi = math.tan(theta[1])
    J = np.empty((n, 3))
    if pb.model == "cohesion-free":
        J[:, 0] = 0.0
    else:
        J[:, 0] = A * sgw
    J[:, 1] = W * (1.0 + tphi * tphi) * sgw
    J[:, 2] = y[o + 2 * n:o + 3 * n]
    note = ("; one normal load: solved in the identifiable parameters (F_max, K), exactly equivalent; "
            "(c, phi) is a point of the ridge") if one_load else ""
    src = "user start point" if x0 is not None else "variable-projection grid start"
    return build_result(data_kind="slip", model=pb.model, method="ipopt", theta=theta, jacobian=J,
                        weighted_residuals=r / pb.sigma, residuals=r, residual_unit="N", n_samples=n,
                        normal_loads=W, vehicle=pb.vehicle, bounds=bnd, status="Compiled_LM_Converged",
                        success=True, message="converged (compiled projected Levenberg-Marquardt, first-order "
                                              f"conditions met; {src}{note})",
                        iterations=int(iters), solve_time=time.perf_counter() - t0, sigma_known=pb.sigma_known,
                        warnings=pb.noise_warning(r), samples=(pb.slip, pb.force, pb.load),
                        extra={"engine": "compiled-lm", "sigma_model": pb.noise_model, "engine_call_time_s": t_call,
                               "start": _theta_of(zs, p)})


def _theta_of(z: np.ndarray, p: int) -> list[float]:
    """Start point in SI ``[c, phi, K]`` (one-load full: ``c = 0`` and the equivalent friction angle)."""
    if p == 3:
        return [float(z[0] * SCALE[0]), float(z[1]), float(z[2] * SCALE[2])]
    return [0.0, float(z[0]), float(z[1] * SCALE[2])]


def _hand_over(pb: SlipProblem, z, p, one_load, x0, n_grid, ipopt_options, t0) -> FitResult:
    """Re-solve with the cached IPOPT path (from the last iterate if finite, else as asked)."""
    from .ipopt_fit import fit_ipopt
    x = None
    if np.all(np.isfinite(z)):
        x = np.array(_theta_of(z, p))
    elif x0 is not None:
        x = np.asarray(x0, float)
    res = fit_ipopt(pb, x, ipopt_options=ipopt_options, n_grid=n_grid)
    object.__setattr__(res, "message", "compiled engine did not certify convergence; re-solved with IPOPT: "
                       + res.message)
    object.__setattr__(res, "solve_time", time.perf_counter() - t0)
    res.extra["engine"] = "ipopt"
    return res
