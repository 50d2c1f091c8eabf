"""The compiled LM engine: a bounded Levenberg-Marquardt solve as ONE CasADi call.

``fit(data, vehicle)`` (default ``engine="auto"``, or ``engine="compiled"``) and
``fit_many`` solve the same bounded weighted least-squares problem as the IPOPT path,

    minimise  0.5 * sum_k (w_k (F(i_k; c, phi, K, W_k) - F_k))^2   within the bounds,  w_k = 1/sigma_k,

with a solver whose whole run is one pre-built CasADi ``Function``. Every residual, gradient,
Hessian and Jacobian in it is derived by CasADi's automatic differentiation from
:func:`soiltrack.soilmodel.traction.thrust_expr` (Eq. 2 / Eq. 8, the one home of the physics);
nothing here writes the shear bracket or its derivatives by hand. Each per-sample expression
is split by CasADi's ``extract_parametric`` into what depends on the parameters alone
(``tan(phi)``, ``cos(phi)^2``, ...), computed once per evaluation, and the per-sample rest: the
same operations on the same numbers as one expression per sample, without the repeated
transcendental calls.

1. **Start**: variable projection on a grid of K (as :mod:`soiltrack.identify.sweep.start`: for each
   K the force is linear in ``(c, tan(phi))``; its coefficients are the derivatives of Eq. 2
   with respect to them, solved by weighted linear least squares and projected onto the
   bounds; the grid point of lowest cost wins). The ``n_grid`` values of K are uniform in
   1/K. On problems of more than ``GRID_ROWS`` (16) samples the grid is evaluated on 16 of
   them spread evenly over the slip range (it only picks the start basin; the iteration and
   the certificate use every sample), which halves the cost of a 100-point fit. A given
   ``x0`` replaces it.
2. **Iteration**: up to ``N_ITER`` projected, damped Newton steps in the scaled variables of
   the IPOPT path (``c / 1 kPa``, ``phi / 1 rad``, ``K / 1 cm``): exact Hessian of the cost
   (AD) plus Levenberg-Marquardt damping ``lam * diag(J^T J)``; variables on a bound whose
   gradient points outwards are held (active set); the trial point is projected onto the box
   and accepted if the cost does not increase (``lam / 10``), else rejected (``lam * 10``); at
   the rounding floor of the cost (relative change below 1e-13) a step is also accepted when
   it shrinks the free part of the gradient (Newton's endgame). Each block of iterations is a
   conditional call skipped once the first-order test below holds.
3. **Certification**, computed by the same Function from its final state (not a solver's
   word): finite numbers, inside the bounds, and the first-order (KKT) conditions for the box:
   the projected gradient ``|| g_free ||`` at most ``KKT_TOL`` times
   ``sqrt(trace(J^T J) * 2 cost)``, or a cost that is zero to rounding - the very test that
   stops the iteration (one home). ``KKT_TOL`` and ``ZERO_COST`` are inputs of the call, not
   compiled-in constants. A fit the engine cannot certify is handed to the cached IPOPT
   solver, the authority (said in the message; ``extra["engine"] == "ipopt"``,
   ``extra["handed_over_from"] == "compiled"``).

**Size classes.** A problem of ``n`` samples is padded to ``size_class(n)`` rows (powers of
two, at least 4) with zero slip, zero force and zero weight: padded rows add exactly nothing
to the cost, its derivatives or the start grid. Twenty datasets of twenty lengths therefore
share a handful of Functions instead of building twenty.

**C code.** Each Function is generated to C and compiled with the system compiler into a
per-user on-disk cache keyed by a hash of the source (:mod:`soiltrack.identify.jitcache`), so
a second process loads the library instead of compiling. ``jit="wait"`` compiles now when
the library is missing (``engine="compiled"``); ``jit="background"`` (``engine="auto"``)
never waits: it evaluates the same Function in CasADi's virtual machine while a detached
compiler fills the cache; ``jit="off"`` (or ``SOILTRACK_NO_JIT``) uses the virtual machine.
``extra["engine"]`` is ``"compiled"`` for C code and ``"compiled-vm"`` for the virtual
machine, and ``extra["engine_backend"]`` says why (e.g. "virtual machine (no C compiler)").

The full model at ONE normal load is solved exactly as the IPOPT path does it: in the
identifiable parameters ``(F_max, K)`` (``F_max = W tan(phi_e)``, the cohesion-free Eq. 8,
with the bounds box of ``(c, phi)`` mapped onto bounds of ``phi_e``), then mapped onto the
centre of the bounds-feasible ridge (:func:`~soiltrack.identify.sweep.problem.ridge_centre`, an
arbitrary ridge point, reported as such by :class:`~soiltrack.identify.FitResult`).

Thread safety: each cached kernel is called through a zero-copy buffer guarded by its own
lock (a C call of microseconds; the lock is held only across it); each kernel is built (and
compiled) once under its own lock, so a compilation does not block fits that use other
kernels; after ``fork`` the locks are renewed in the child.
"""

from __future__ import annotations

import math
import os
import threading
import time
from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from ...soilmodel.traction import max_thrust_expr, thrust_expr
from .. import jitcache
from .ipopt import one_load_problem  # the one test of "a single normal load"
from .plausibility import corner_soils, limit_screen_expr, screen_expr
from .problem import SCALE, SlipProblem, heteroscedasticity_screen_expr, ridge_centre
from ..estimates.result import FitResult, build_result

__all__ = [
    "compiled_solver",
    "fit_compiled",
    "solve",
    "solve_many",
    "kernel",
    "size_class",
    "Solution",
    "N_ITER",
    "KKT_TOL",
    "JIT_MODES",
]

#: Most damped-Newton iterations per call (skipped once converged; typically 2-6 are run).
N_ITER = 40
#: Relative first-order tolerance (projected gradient vs sqrt(trace(J^T J) * 2 cost)).
KKT_TOL = 1e-9
#: A cost below this fraction of 0.5 * sum((w F)^2) is a zero-residual (global) optimum.
ZERO_COST = 1e-24
#: How the C code is obtained: compile now if missing / in the background / never.
JIT_MODES = ("wait", "background", "off")
_BLOCK = 5  # iterations per skippable block
_EPS_B = 1e-12  # relative distance to a bound counted as "on it" (of the bound range)
_MIN_CLASS = 4
#: Samples the start grid is evaluated on (problems with more rows: a spread subsample, see ``grid_rows``).
GRID_ROWS = 16


def size_class(n: int) -> int:
    """Rows a problem of ``n`` samples is padded to: the next power of two, at least 4."""
    n = max(int(n), 1)
    return max(_MIN_CLASS, 1 << (n - 1).bit_length())


def _theta_of_z(z, p: int):
    """``(c, phi, K, model)`` of the scaled variables (p = 3: full; p = 2: cohesion-free / phi_e)."""
    if p == 3:
        return z[0] * SCALE[0], z[1], z[2] * SCALE[2], "full"
    return 0.0, z[0], z[1] * SCALE[2], "cohesion-free"


def _data_symbols():
    return [ca.SX.sym(k) for k in ("s", "F", "W", "w", "l", "b")]


def _row_map(name: str, inputs: list, outputs: list, repeated: list, n: int, reduce_out=(), opts: dict | None = None):
    """``Function(name, inputs, outputs).map(name, "serial", n, repeated, reduce_out)``, evaluated in less time.

    ``repeated``: indices of the inputs that are the same for every sample (the parameters,
    ``l``, ``b``, ...). CasADi's ``extract_parametric`` splits ``outputs`` into what depends on
    them alone (``tan(phi)``, ``cos(phi)^2``, ``A c``, ...), computed once per call by a ``pre``
    Function, and the per-sample rest, which takes those numbers as an extra first input
    instead of computing them once per sample: the same operations on the same numbers, so the
    same results to the last bit, with fewer transcendental calls. Inputs the per-sample rest no
    longer reads are left out of the map (a serial map copies a repeated input once per sample).
    Returns a callable with the arguments of the plain mapped Function.
    """
    rep = list(repeated)
    ret, syms, pars = ca.extract_parametric(outputs, ca.vertcat(*[inputs[i] for i in rep]))
    body = ca.vertcat(*ret)
    used = [k for k, x in enumerate(inputs) if x.numel() and ca.depends_on(body, x)]
    row_in = ([ca.vertcat(*syms)] if syms else []) + [inputs[k] for k in used]
    row = ca.Function(name, row_in, list(ret), opts or {})
    first = 1 if syms else 0
    mapped = row.map(
        name + "_map",
        "serial",
        n,
        ([0] if syms else []) + [first + j for j, k in enumerate(used) if k in rep],
        list(reduce_out),
    )
    pre = ca.Function(name + "_pre", [inputs[i] for i in rep], [ca.vertcat(*pars)], {"cse": True}) if syms else None

    def call(*args):
        kept = [args[k] for k in used]
        return mapped(pre(*[args[i] for i in rep]), *kept) if syms else mapped(*kept)

    return call


def _point_functions(p: int, n_grid: int, n: int, m: int):
    """Per-sample functions mapped over the samples, all derived from ``thrust_expr`` by AD.

    ``grid`` (over ``m`` samples): the sums of the variable-projection grid (coefficients of
    the linear parameters ``(c, tan(phi))`` at each grid K); ``ev`` (over ``n`` samples): the
    sums of the sample's cost ``0.5 r^2``, its gradient ``r dr/dz``, exact Hessian and squared
    Jacobian row in the scaled variables ``z``, with ``r = w (F(z) - F_data)``. Both are
    called as the mapped Functions they stand for (:func:`_row_map`).
    """
    s, F, W, w, l, b = _data_symbols()
    model = "full" if p == 3 else "cohesion-free"
    cs, ts, Kk = ca.SX.sym("c"), ca.SX.sym("t"), ca.SX.sym("K")
    lin = ca.vertcat(cs, ts) if p == 3 else ts
    F_lin = thrust_expr(s, cs, ca.atan(ts), Kk, W, l, b, model=model)  # linear in (c, tan(phi))
    coef = ca.substitute(ca.jacobian(F_lin, lin), lin, ca.DM.zeros(lin.numel()))
    coef_f = ca.Function("coef", [s, W, l, b, Kk], [coef])
    Ks = ca.SX.sym("Ks", n_grid)
    y = F * w
    rows = [coef_f(s, W, l, b, Ks[j]) * w for j in range(n_grid)]
    a2 = ca.vertcat(*[r[r.numel() - 1] for r in rows])
    if p == 3:
        a1 = ca.vertcat(*[r[0] for r in rows])
        sums = ca.vertcat(a1 * a1, a1 * a2, a2 * a2, a1 * y, a2 * y)
    else:
        sums = ca.vertcat(a2 * a2, a2 * y)
    grid = _row_map("pt_grid", [s, F, W, w, l, b, Ks], [sums, y * y], [4, 5, 6], m, [0, 1], {"cse": True})
    z = ca.SX.sym("z", p)
    c, phi, K, model = _theta_of_z(z, p)
    r = w * (thrust_expr(s, c, phi, K, W, l, b, model=model) - F)
    gr = ca.jacobian(r, z).T
    cost = 0.5 * r * r
    H = ca.hessian(cost, z)[0]
    ev = _row_map(
        "pt_ev", [z, s, F, W, w, l, b], [ca.vertcat(cost, r * gr, ca.vec(H), gr * gr)], [0, 5, 6], n, [0], {"cse": True}
    )
    return grid, ev


def _resjac_point(model: str, n: int):
    """Per sample (mapped over ``n``): raw residual ``F(theta) - F_data`` (N) and ``w dF/d[c, phi, K]`` (SI), by AD."""
    s, F, W, w, l, b = _data_symbols()
    th = ca.SX.sym("theta", 3)
    Fm = thrust_expr(s, th[0], th[1], th[2], W, l, b, model=model)
    J = ca.jacobian(Fm, th)
    return _row_map("pt_resjac", [th, s, F, W, w, l, b], [ca.vertcat(Fm - F, w * J.T)], [0, 5, 6], n, (), {"cse": True})


def _thrust_map(model: str, n: int):
    """``thrust_expr`` at ``n`` samples of one soil: ``(slip, c, phi, K, W, l, b)`` with c, phi, K, l, b shared."""
    a = [ca.SX.sym(k) for k in ("slip", "c", "phi", "K", "W", "l", "b")]
    F = thrust_expr(a[0], a[1], a[2], a[3], a[4], a[5], a[6], model=model)
    return _row_map("corner_curves", a, [F], [1, 2, 3, 5, 6], n)


def compiled_solver(p: int, n: int, n_grid: int = 25, n_iter: int = N_ITER) -> ca.Function:
    """The solver Function for ``p`` free parameters (2 or 3) and ``n`` rows (virtual-machine form).

    Takes ONE vector ``x = [d, lbz, ubz, z0, use_z0, g]`` and returns ONE vector ``y`` (so that it
    can be called through a zero-copy buffer). Inputs: ``d = [slip (n), F (n), W (n), w (n), l, b]``
    with ``w = 1/sigma`` (0 on padding rows), ``lbz, ubz`` (scaled bounds), ``z0`` (scaled
    start, used when ``use_z0 = 1``) and, for ``n > GRID_ROWS``, ``g = [slip, F, W, w]`` of the
    ``GRID_ROWS`` samples the start grid is evaluated on (:func:`grid_rows`). Output:
    ``[z (p), cost, g (p), trJJ, iters, zstart (p), scale]``: the scaled optimum,
    ``0.5 sum r^2``, the gradient of the cost in ``z``, the trace of ``J^T J``, the iterations
    run until the first-order test held, the start used and ``0.5 sum (w F)^2``. :func:`kernel`
    compiles it to C (cached on disk).
    """
    n_grid = max(int(n_grid), 1)
    d = ca.MX.sym("d", 4 * n + 2)
    lbz, ubz, z0, use0 = ca.MX.sym("lbz", p), ca.MX.sym("ubz", p), ca.MX.sym("z0", p), ca.MX.sym("use_z0")
    slip, force, W, wt = (d[k * n : (k + 1) * n].T for k in range(4))
    l, b = d[4 * n], d[4 * n + 1]
    m = min(n, GRID_ROWS)  # rows of the start grid: all, or a subsample given as its own input
    grid_sums, evm = _point_functions(p, n_grid, n, m)
    gd = ca.MX.sym("grid_data", 4 * m if n > GRID_ROWS else 0)
    g_rows = [gd[k * m : (k + 1) * m].T for k in range(4)] if n > GRID_ROWS else [slip, force, W, wt]

    pick = _grid_pick(p, n_grid)
    K_lo, K_hi = lbz[p - 1] * SCALE[2], ubz[p - 1] * SCALE[2]
    frac = np.linspace(0.0, 1.0, n_grid) if n_grid > 1 else np.zeros(1)
    Kgrid = 1 / (1 / K_hi + ca.DM(frac) * (1 / K_lo - 1 / K_hi))  # uniform in 1/K
    # mapped over the samples with the sums accumulated in the loop (reduce_out)
    gm, yy = grid_sums(*g_rows, l, b, Kgrid)
    zgrid = pick(gm, yy, lbz, ubz, Kgrid)
    zs = ca.if_else(use0 > 0.5, z0, zgrid)
    zs = ca.fmin(ca.fmax(zs, lbz), ubz)
    scale = 0.5 * ca.sumsqr(force * wt)

    # ---- 2. damped projected Newton iterations (state: z, lam, f, g, H, D, iters)

    def evaluate(z):
        s = evm(z, slip, force, W, wt, l, b)
        return s[0], s[1 : 1 + p], ca.reshape(s[1 + p : 1 + p + p * p], p, p), s[1 + p + p * p :]

    kkt, certify, trial, accept = _lm_tests(p)
    nst, cond_b, parts, converged, tol = _lm_blocks(p, n, evm, kkt, trial, accept)
    f0, g0, H0, D0 = evaluate(zs)
    state = ca.vertcat(zs, 1e-3, f0, g0, ca.vec(H0), D0, 0)
    for _ in range(-(-n_iter // _BLOCK)):
        state = cond_b(converged(state, lbz, ubz, scale, tol), state, d, lbz, ubz, scale, tol)
    out = ca.vertcat(
        state[0:p],
        state[p + 1],
        state[p + 2 : 2 * p + 2],
        ca.sum1(state[2 * p + 2 + p * p : 3 * p + 2 + p * p]),
        state[nst - 1],
        zs,
        scale,
        certify(*parts(state), lbz, ubz, scale, tol),
    )
    o = 4 * n + 2
    xin = ca.MX.sym("x", o + 3 * p + 3 + gd.numel())
    f = ca.Function("lm", [d, lbz, ubz, z0, use0, tol, gd], [out])
    return ca.Function(
        f"soilfit_clm_{p}_{n}_{n_grid}_{n_iter}",
        [xin],
        [
            ca.densify(
                f(
                    xin[0:o],
                    xin[o : o + p],
                    xin[o + p : o + 2 * p],
                    xin[o + 2 * p : o + 3 * p],
                    xin[o + 3 * p],
                    xin[o + 3 * p + 1 : o + 3 * p + 3],
                    xin[o + 3 * p + 3 :],
                )
            )
        ],
        ["x"],
        ["y"],
    )


def _grid_pick(p: int, n_grid: int) -> ca.Function:
    """The start grid's pick: the best (c, tan phi) of each K from the sums, then the best K (scaled ``z``)."""
    # ---- 1. variable-projection grid start (residual cost of each K from the sums:
    # |y|^2 - 2 c r1 - 2 t r2 + c^2 m11 + 2 c t m12 + t^2 m22, with t = tan(phi))
    sc = ca.SX.sym("sums", (5 if p == 3 else 2) * n_grid)
    yy_s = ca.SX.sym("yy")
    lz, uz, Kg = ca.SX.sym("lz", p), ca.SX.sym("uz", p), ca.SX.sym("Kg", n_grid)
    if p == 3:
        m11, m12, m22, r1, r2 = (sc[k * n_grid : (k + 1) * n_grid] for k in range(5))
    else:
        m22, r2 = sc[0:n_grid], sc[n_grid : 2 * n_grid]
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
    best: tuple[ca.SX, ...] = (cost[0], c[0], t[0], Kg[0])
    for j in range(1, n_grid):
        better = cost[j] < best[0]  # NaN never wins
        best = tuple(ca.if_else(better, new, old) for new, old in zip((cost[j], c[j], t[j], Kg[j]), best))
    _, c_b, t_b, K_b = best
    zg = (
        ca.vertcat(c_b / SCALE[0], ca.atan(t_b), K_b / SCALE[2]) if p == 3 else ca.vertcat(ca.atan(t_b), K_b / SCALE[2])
    )
    return ca.Function("pick", [sc, yy_s, lz, uz, Kg], [zg])


def _lm_tests(p: int) -> tuple[ca.Function, ca.Function, ca.Function, ca.Function]:
    """The first-order test with bounds, its certificate, the damped projected Newton trial, the acceptance."""
    lz, uz = ca.SX.sym("lz", p), ca.SX.sym("uz", p)
    # the first-order (KKT) test with bounds: the stopping test AND the certificate (one home);
    # tolS = [KKT_TOL, ZERO_COST] are inputs, not compiled-in constants
    zS, gS, DS, fS, scS = ca.SX.sym("z", p), ca.SX.sym("g", p), ca.SX.sym("D", p), ca.SX.sym("f"), ca.SX.sym("sc")
    tolS = ca.SX.sym("tol", 2)
    epsS = _EPS_B * (uz - lz)
    act = ca.logic_or(ca.logic_and(zS <= lz + epsS, gS > 0), ca.logic_and(zS >= uz - epsS, gS < 0))
    gp = ca.if_else(act, ca.SX.zeros(p), gS)
    done = ca.logic_or(ca.norm_2(gp) <= tolS[0] * ca.sqrt(ca.sum1(DS) * 2 * fS), fS <= tolS[1] * scS)
    kkt = ca.Function("kkt", [zS, fS, gS, DS, lz, uz, scS, tolS], [done, act])
    # certificate: the KKT test on finite numbers inside the box (NaN fails every comparison)
    vals = ca.vertcat(zS, fS, gS, DS)
    finite = ca.logic_and(
        ca.sum1(ca.fabs(vals) < ca.inf) == vals.numel(), ca.sum1(ca.logic_and(zS >= lz, zS <= uz)) == p
    )
    certify = ca.Function("certify", [zS, fS, gS, DS, lz, uz, scS, tolS], [ca.logic_and(finite, done)])
    HS, lamS = ca.SX.sym("H", p, p), ca.SX.sym("lam")
    mfree = 1 - act
    Hd = HS + lamS * ca.diag(ca.fmax(DS, 1e-300))
    Hr = (mfree @ mfree.T) * Hd + ca.diag(1 - mfree)
    zt = ca.fmin(ca.fmax(zS + ca.solve(Hr, -mfree * gS), lz), uz)
    trial = ca.Function("trial", [zS, lamS, gS, HS, DS, lz, uz], [zt, mfree])
    ftS, gtS, mS = ca.SX.sym("ft"), ca.SX.sym("gt", p), ca.SX.sym("m", p)
    accept = ca.Function(
        "accept",
        [ftS, fS, gtS, gS, mS],
        [
            ca.logic_or(
                ftS <= fS, ca.logic_and(ftS <= fS + 1e-13 * ca.fabs(fS), ca.norm_2(mS * gtS) < ca.norm_2(mS * gS))
            )
        ],
    )

    return kkt, certify, trial, accept


def _lm_blocks(p: int, n: int, evm, kkt, trial, accept):
    """The iteration state's layout and the Function of one block of conditional iterations.

    Returns ``(nst, cond_b, parts, converged, tol)``: the state's length, the conditional block (index 0:
    iterate, else keep), the accessor of ``(z, f, g, D)`` in a state, the first-order test of a state and
    the solver's tolerance input ``[KKT_TOL, ZERO_COST]``.
    """
    nst = 3 * p + p * p + 3
    st = ca.MX.sym("state", nst)
    sz, slam, sf, sg_ = st[0:p], st[p], st[p + 1], st[p + 2 : 2 * p + 2]
    sH = ca.reshape(st[2 * p + 2 : 2 * p + 2 + p * p], p, p)
    sD, sit = st[2 * p + 2 + p * p : 3 * p + 2 + p * p], st[nst - 1]
    d_, lbz_, ubz_ = ca.MX.sym("d", 4 * n + 2), ca.MX.sym("lbz", p), ca.MX.sym("ubz", p)
    slip_, force_, W_, w_ = (d_[k * n : (k + 1) * n].T for k in range(4))
    l_, b_ = d_[4 * n], d_[4 * n + 1]
    zt_, m_ = trial(sz, slam, sg_, sH, sD, lbz_, ubz_)
    s_ = evm(zt_, slip_, force_, W_, w_, l_, b_)
    ft, gt, Ht, Dt = s_[0], s_[1 : 1 + p], s_[1 + p : 1 + p + p * p], s_[1 + p + p * p :]
    acc = accept(ft, sf, gt, sg_, m_)  # NaN is rejected
    new = ca.vertcat(
        ca.if_else(acc, zt_, sz),
        ca.if_else(acc, ca.fmax(slam * 0.1, 1e-15), ca.fmin(slam * 10, 1e20)),
        ca.if_else(acc, ft, sf),
        ca.if_else(acc, gt, sg_),
        ca.if_else(acc, Ht, ca.vec(sH)),
        ca.if_else(acc, Dt, sD),
        sit + 1,
    )
    step_f = ca.Function("lm_step", [st, d_, lbz_, ubz_], [new])
    keep_f = ca.Function("lm_keep", [st, d_, lbz_, ubz_], [st])
    cond = ca.Function.conditional("lm_iter", [step_f], keep_f)  # index 0: iterate; else: keep
    sc_, tol_, tol = ca.MX.sym("scale"), ca.MX.sym("tol", 2), ca.MX.sym("tol", 2)

    def parts(s):
        return s[0:p], s[p + 1], s[p + 2 : 2 * p + 2], s[2 * p + 2 + p * p : 3 * p + 2 + p * p]

    def converged(s, lo, hi, scl, tl):
        return kkt(*parts(s), lo, hi, scl, tl)[0]

    sb = st  # blocks of _BLOCK conditional iterations, each block skipped as a whole once converged
    for _ in range(_BLOCK):
        sb = cond(converged(sb, lbz_, ubz_, sc_, tol_), sb, d_, lbz_, ubz_)
    block_f = ca.Function("lm_block", [st, d_, lbz_, ubz_, sc_, tol_], [sb])
    keep_b = ca.Function("lm_keep_block", [st, d_, lbz_, ubz_, sc_, tol_], [st])
    cond_b = ca.Function.conditional("lm_blocks", [block_f], keep_b)

    return nst, cond_b, parts, converged, tol


def resjac_function(model: str, n: int) -> ca.Function:
    """``[theta (3), d (4n+2), corners (6)] -> [r (n), J (n x 3, column-major), F_weak (n), F_strong (n), screen, bp,
    limit]``.

    Residuals and ``J = w dF/dtheta`` of Eq. 2/8 by AD, and the thrust of the weakest and the
    strongest soil within the bounds (``corners = [c, phi, K]`` of each,
    :func:`~soiltrack.identify.sweep.plausibility.corner_soils`) at every sample: the curves the
    plausibility checks compare the data with (:func:`~soiltrack.identify.sweep.plausibility.assess`);
    ``screen`` is :func:`~soiltrack.identify.sweep.plausibility.screen_expr` of these numbers (0: the
    numpy checks have nothing to find but F_max on a bound) and ``bp``
    :func:`~soiltrack.identify.sweep.problem.heteroscedasticity_screen_expr` (0: no noise warning),
    ``limit`` :func:`~soiltrack.identify.sweep.plausibility.limit_screen_expr` at ``theta`` (0: F_max is
    on no bound either, so no numpy check runs).
    """
    pt = _resjac_point(model, n)
    thr = _thrust_map(model, n)
    xin = ca.MX.sym("x", 3 + 4 * n + 2 + 6)
    th, d, cr = xin[0:3], xin[3 : 3 + 4 * n + 2], xin[3 + 4 * n + 2 :]
    rows = [d[k * n : (k + 1) * n].T for k in range(4)]
    l, b = d[4 * n], d[4 * n + 1]
    out = pt(th, *rows, l, b)  # 4 x n
    weak = thr(rows[0], cr[0], cr[1], cr[2], rows[2], l, b)
    strong = thr(rows[0], cr[3], cr[4], cr[5], rows[2], l, b)
    screen = screen_expr(rows[0], rows[1], out[0, :], weak, strong, rows[3])
    bp = heteroscedasticity_screen_expr(rows[1], out[0, :], rows[3])
    limit = limit_screen_expr(th[0], th[1], rows[2], cr[0:3], cr[3:6], 2.0 * b * l, model, rows[3])
    return ca.Function(
        f"soilfit_resjac_{model.replace('-', '_')}_{n}",
        [xin],
        [ca.densify(ca.vertcat(out[0, :].T, ca.vec(out[1:4, :].T), weak.T, strong.T, screen, bp, limit))],
        ["x"],
        ["y"],
    )


class _Caller:
    """Zero-copy caller of a flat Function (one input vector, one output vector); thread-safe."""

    #: what evaluates this caller (set by :class:`Kernel`)
    engine: str
    backend: str
    #: views of the solver caller's input buffer (set by :class:`Kernel`): data, data + box + start, grid rows
    head: np.ndarray
    front: np.ndarray
    grid: np.ndarray | None

    def __init__(self, f: ca.Function) -> None:
        self.f = f
        self.n_in, self.n_out = f.size1_in(0), f.size1_out(0)
        self.lock = threading.Lock()
        self.x = np.zeros(self.n_in)
        self.y = np.zeros(self.n_out)
        try:
            self.buf, self.trigger = f.buffer()
            # the stub wants a byte size, the binding takes it from the memoryview (3 arguments are refused);
            # numpy's buffer protocol is typed from Python 3.12 only
            self.buf.set_arg(0, memoryview(self.x))  # type: ignore[call-arg, arg-type]
            self.buf.set_res(0, memoryview(self.y))  # type: ignore[call-arg, arg-type]
        except Exception:  # pragma: no cover - CasADi without buffers: ordinary (slower) calls
            self.trigger = None

    def __call__(self, x: np.ndarray) -> np.ndarray:
        if self.trigger is None:  # pragma: no cover
            return np.asarray(self.f(np.asarray(x, float)), float).ravel()
        with self.lock:
            self.x[:] = x
            self.trigger()
            return self.y.copy()


class Kernel:
    """The solver and residual/Jacobian Functions of one ``(p, model, size class, n_grid)``.

    ``backend`` says what evaluates them (C from the disk cache, C compiled now, or the
    virtual machine and why); ``engine`` is ``"compiled"`` (C) or ``"compiled-vm"``.
    """

    def __init__(self, p: int, model: str, n: int, n_grid: int, jit: str) -> None:
        self.p, self.model, self.n, self.n_grid = p, model, n, n_grid
        self.vm = [compiled_solver(p, n, n_grid), resjac_function(model, n)]
        self._load(jit)

    def _load(self, jit: str) -> None:
        if jit == "off":
            self.compiled = jitcache.Compiled(tuple(f.name() for f in self.vm), list(self.vm), jitcache.VM_OFF)
        else:
            self.compiled = jitcache.load(self.vm, f"soiltrack_clm_{self.p}_{self.n}", wait=(jit == "wait"))
        self._callers()

    def _callers(self) -> None:
        callers = [_Caller(f) for f in self.compiled.functions]
        for c in callers:  # what evaluates this very caller (read with it, never stale)
            c.engine, c.backend = self.engine, self.backend
        cs, cr = callers
        nc, p = self.n, self.p
        o = 4 * nc + 2
        # views of the solver's input buffer: the data [slip, F, W, w, l, b] (+ the box and start), the
        # start grid's samples as 4 x GRID_ROWS; (read with the caller, under its lock)
        cs.head, cs.front = cs.x[0:o], cs.x[0 : o + 3 * p + 3]
        cs.grid = cs.x[o + 3 * p + 3 :].reshape(4, GRID_ROWS) if nc > GRID_ROWS else None
        self.solver, self.resjac = cs, cr

    @property
    def backend(self) -> str:
        return self.compiled.backend

    @property
    def engine(self) -> str:
        return "compiled" if self.compiled.is_c else "compiled-vm"

    def refresh(self, jit: str) -> None:
        """Pick up a finished background compilation, or compile now when ``jit == "wait"``."""
        if self.compiled.is_c:
            return
        if self.compiled.upgrade():
            self._callers()
        elif jit == "wait" and self.compiled.backend in (jitcache.VM_PENDING, jitcache.VM_OFF):
            self._load("wait")

    def renew_locks(self) -> None:
        for c in (self.solver, self.resjac):
            c.lock = threading.Lock()


_KERNELS: dict[tuple, Kernel] = {}
_KERNELS_LOCK = threading.Lock()  # guards the two dicts
_BUILD_LOCKS: dict[tuple, threading.Lock] = {}  # one per kernel: builds and compiles do not block other kernels
_BY_SIZE: dict[tuple, tuple] = {}  # (p, model, n, n_grid) as called -> (its kernel, _KERNELS): a shortcut


def _after_fork() -> None:  # a lock held by another thread at fork time would never be released
    global _KERNELS_LOCK
    _KERNELS_LOCK = threading.Lock()
    _BUILD_LOCKS.clear()
    for k in _KERNELS.values():
        k.renew_locks()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork)


def _jit_mode(jit: str) -> str:
    if os.environ.get("SOILTRACK_NO_JIT"):
        return "off"
    if jit not in JIT_MODES:
        raise ValueError(f"jit must be one of {JIT_MODES}, got {jit!r}")
    return jit


def kernel(p: int, model: str, n: int, n_grid: int = 25, jit: str = "wait") -> Kernel:
    """The cached :class:`Kernel` for ``p`` free parameters, residual ``model`` and ``n`` samples.

    ``n`` is rounded up to its :func:`size_class`. ``jit`` is one of :data:`JIT_MODES`.
    """
    hit = _BY_SIZE.get((p, model, n, n_grid))
    if hit is not None and hit[1] is _KERNELS and hit[0].compiled.is_c and jit in JIT_MODES:
        return hit[0]  # the common case: C code loaded, no lock
    key = (int(p), model, size_class(n), max(int(n_grid), 1))
    k = _KERNELS.get(key)
    if k is not None and k.compiled.is_c and jit in JIT_MODES:
        _remember(p, model, n, n_grid, k)
        return k
    jit = _jit_mode(jit)
    with _KERNELS_LOCK:
        lock = _BUILD_LOCKS.setdefault(key, threading.Lock())
    with lock:
        k = _KERNELS.get(key)
        if k is None:
            k = Kernel(*key, jit=jit)
            with _KERNELS_LOCK:
                _KERNELS[key] = k
        else:
            k.refresh(jit)
        _remember(p, model, n, n_grid, k)
        return k


def _remember(p, model: str, n, n_grid, k: Kernel) -> None:
    """Find ``k`` for these exact arguments without computing its key next time (kernels are never replaced;
    the entry holds the cache it came from, and counts only while that is still the cache)."""
    if len(_BY_SIZE) > 4096:
        _BY_SIZE.clear()
    _BY_SIZE[(p, model, n, n_grid)] = (k, _KERNELS)


@dataclass(frozen=True, eq=False)
class Solution:
    """What one compiled solve returns (SI), before the result is built or handed over.

    ``certified``: the first-order conditions with bounds hold (checked here from the
    Function's outputs). ``residuals`` (N) and ``jacobian`` (``w dF/dtheta``, n x 3) are at
    ``theta`` (the reported point; for one-load full data the ridge marker); ``curves`` are the
    weakest and strongest soil's thrust at each sample (N) for the plausibility checks;
    ``screen``, ``bp_screen`` and ``limit_screen`` the residual Function's screens of them
    (:func:`resjac_function`).
    """

    theta: np.ndarray
    certified: bool
    iterations: int
    start: list
    residuals: np.ndarray
    jacobian: np.ndarray
    z: np.ndarray
    p: int
    one_load: bool
    engine: str
    backend: str
    call_time: float
    curves: tuple | None = None
    screen: float | None = None
    bp_screen: float | None = None
    limit_screen: float | None = None


def _variant(pb: SlipProblem) -> tuple[int, bool, str]:
    """``(p, one_load, residual model)`` of a problem."""
    one = pb.model == "full" and one_load_problem(pb)
    p = 3 if (pb.model == "full" and not one) else 2
    return p, one, pb.model


def _scaled_box(pb: SlipProblem, p: int, one_load: bool) -> tuple[list, list]:
    if one_load:  # F_max = W tan(phi_e) spans what the (c, phi) box allows
        (c_lo, c_hi), (p_lo, p_hi), (K_lo, K_hi) = pb.bounds.cohesion, pb.bounds.friction_angle, pb.bounds.shear_modulus
        W0, A = float(pb.load[0]), pb.vehicle.contact_area
        F_lo, F_hi = max_thrust_expr(c_lo, p_lo, W0, A), max_thrust_expr(c_hi, p_hi, W0, A)
        return [math.atan(F_lo / W0), K_lo / _S2], [math.atan(F_hi / W0), K_hi / _S2]
    return _box(pb.bounds, p)


def _box(bounds, p: int) -> tuple[list, list]:
    """Scaled bounds of the variables (not the one-load case, whose box depends on the load)."""
    (c_lo, c_hi), (p_lo, p_hi), (K_lo, K_hi) = bounds.cohesion, bounds.friction_angle, bounds.shear_modulus
    if p == 3:
        return [c_lo / _S0, p_lo, K_lo / _S2], [c_hi / _S0, p_hi, K_hi / _S2]
    return [p_lo, K_lo / _S2], [p_hi, K_hi / _S2]


def _scaled_start(pb: SlipProblem, x0, p: int, one_load: bool) -> tuple[list, float]:
    if x0 is None:
        return [0.0] * p, 0.0
    x0 = np.asarray(x0, float)
    return [float(v) for v in _scaled_start_given(pb, x0, p, one_load)], 1.0


def _scaled_start_given(pb: SlipProblem, x0: np.ndarray, p: int, one_load: bool) -> list:
    if one_load:
        W0 = float(pb.load[0])
        return [math.atan(max_thrust_expr(x0[0], x0[1], W0, pb.vehicle.contact_area) / W0), x0[2] / SCALE[2]]
    if p == 3:
        return [x0[0] / SCALE[0], x0[1], x0[2] / SCALE[2]]
    return [x0[1], x0[2] / SCALE[2]]


def _data_vector(pb: SlipProblem, nc: int, out: np.ndarray | None = None) -> np.ndarray:
    """``[slip, F, W, w, l, b]`` padded to ``nc`` rows (zero slip, force and weight), into ``out`` if given."""
    n = pb.n
    if out is None:
        d = np.zeros(4 * nc + 2)
    else:
        d = out
        d[:] = 0.0
    d[0:n] = pb.slip
    d[nc : nc + n] = pb.force
    d[2 * nc : 2 * nc + n] = pb.load
    d[2 * nc + n : 3 * nc] = pb.load[0]
    np.divide(1.0, pb.sigma, out=d[3 * nc : 3 * nc + n])
    d[4 * nc], d[4 * nc + 1] = pb.vehicle.track_length, pb.vehicle.track_width
    return d


def grid_rows(pb: SlipProblem) -> np.ndarray:
    """Indices of the ``GRID_ROWS`` samples the start grid uses when a problem has more.

    Evenly spread over the samples sorted by slip (smallest and largest slip included): the
    grid only chooses the start basin, the iteration and its certificate use every sample.
    """
    return pb.slip.argsort(kind="stable")[_spread(pb.n)]


@lru_cache(maxsize=1024)
def _spread(n: int) -> np.ndarray:
    return np.round(np.linspace(0, n - 1, GRID_ROWS)).astype(np.intp)


def _grid_vector(pb: SlipProblem, out: np.ndarray) -> None:
    idx = grid_rows(pb)
    m = GRID_ROWS
    pb.slip.take(idx, out=out[0:m])
    pb.force.take(idx, out=out[m : 2 * m])
    pb.load.take(idx, out=out[2 * m : 3 * m])
    w = out[3 * m : 4 * m]
    pb.sigma.take(idx, out=w)
    np.divide(1.0, w, out=w)


_S0, _S2 = float(SCALE[0]), float(SCALE[2])


def _theta_si(z, p: int) -> list[float]:
    """Start/optimum in SI ``[c, phi, K]`` (one-load full: ``c = 0`` and the equivalent friction angle)."""
    if p == 3:
        return [float(z[0]) * _S0, float(z[1]), float(z[2]) * _S2]
    return [0.0, float(z[0]), float(z[1]) * _S2]


def input_vector(pb: SlipProblem, x0=None, nc: int | None = None) -> np.ndarray:
    """The solver Function's input ``[d, lbz, ubz, z0, use_z0, tol, g]`` for ``pb`` (``nc`` rows)."""
    p, one_load, _ = _variant(pb)
    nc = size_class(pb.n) if nc is None else nc
    z0, use0 = _scaled_start(pb, x0, p, one_load)
    g = np.zeros(4 * GRID_ROWS if nc > GRID_ROWS else 0)
    if g.size:
        _grid_vector(pb, g)
    return np.concatenate((_data_vector(pb, nc), *_scaled_box(pb, p, one_load), z0, [use0], [KKT_TOL, ZERO_COST], g))


def solve(pb: SlipProblem, x0=None, n_grid: int = 25, jit: str = "wait") -> Solution:
    """Run the compiled solver on a :class:`SlipProblem` and certify its answer (no hand-over here)."""
    p, one_load, model = _variant(pb)
    k = kernel(p, model, pb.n, n_grid, jit)
    nc, n = k.n, pb.n
    cs, cr = k.solver, k.resjac
    if cs.trigger is None or cr.trigger is None:  # pragma: no cover - CasADi without buffers
        return _solve_unbuffered(pb, x0, p, one_load, k)
    tail = _tail(pb, p, one_load, x0)
    w = np.divide(1.0, pb.sigma)
    grid = None if cs.grid is None else _block_offsets(nc) + pb.slip.argsort(kind="stable")[_spread(n)]
    pad = _zeros(nc - n)
    with cs.lock:  # fill the zero-copy input buffer in place, call, read the output
        # [slip, F, W, w] each padded to nc rows (zero slip, force and weight; W = the first load), l, b,
        # the scaled box and start (what input_vector gives), in one copy; then the start grid's samples
        # (grid_rows) taken from the blocks just written
        np.concatenate((pb.slip, pad, pb.force, pad, pb.load, pb.load[0:1].repeat(nc - n), w, pad, tail), out=cs.front)
        if grid is not None:
            cs.x.take(grid, out=cs.grid)
        t1 = time.perf_counter()
        cs.trigger()
        t_call = time.perf_counter() - t1
        yl = cs.y.tolist()
        z, iters, ok, theta = _decode(pb, yl, p, one_load)
        if ok:  # residuals and Jacobian at the reported point (AD of Eq. 2/8), the plausibility curves
            with cr.lock:  # (always taken after the solver's lock: no deadlock)
                np.concatenate((theta, cs.head, _corners(pb.bounds, pb.model)), out=cr.x)
                cr.trigger()
                rj = cr.y.copy()
    return _solution_of(theta, ok, iters, yl, p, z, one_load, cs, t_call, rj if ok else None, n, nc)


def _solve_unbuffered(pb: SlipProblem, x0, p: int, one_load: bool, k: "Kernel") -> "Solution":  # pragma: no cover
    """:func:`solve` through ordinary Function calls (CasADi without buffers)."""
    nc, n = k.n, pb.n
    cs, cr = k.solver, k.resjac
    o = 4 * nc + 2
    weak, strong = corner_soils(pb.bounds, pb.model)
    xin = input_vector(pb, x0, nc)
    t1 = time.perf_counter()
    yl = cs(xin).tolist()
    t_call = time.perf_counter() - t1
    z, iters, ok, theta = _decode(pb, yl, p, one_load)
    rj = cr(np.concatenate((theta, xin[0:o], weak, strong))) if ok else None
    return _solution_of(theta, ok, iters, yl, p, z, one_load, cs, t_call, rj, n, nc)


def _solution_of(
    theta,
    ok: bool,
    iters: int,
    yl: list,
    p: int,
    z: list,
    one_load: bool,
    cs: "_Caller",
    t_call: float,
    rj: np.ndarray | None,
    n: int,
    nc: int,
) -> "Solution":
    """The :class:`Solution` of one solve: the solver's output list ``yl`` and the residual Function's ``rj``."""
    if rj is None:
        r = J = np.empty(0)
        curves = screen = bp = limit = None
    else:
        r = rj[0:n]
        J = rj[nc : 4 * nc].reshape(3, nc)[:, 0:n].T
        curves = (rj[4 * nc : 4 * nc + n], rj[5 * nc : 5 * nc + n])
        screen, bp, limit = rj[6 * nc : 6 * nc + 3].tolist()
    obj = object.__new__(Solution)  # Solution(...) without the frozen dataclass's per-field setattr
    obj.__dict__.update(
        theta=theta,
        certified=ok,
        iterations=iters,
        start=_theta_si(yl[2 * p + 3 : 3 * p + 3], p),
        residuals=r,
        jacobian=J,
        z=np.array(z),
        p=p,
        one_load=one_load,
        engine=cs.engine,
        backend=cs.backend,
        call_time=t_call,
        curves=curves,
        screen=screen,
        bp_screen=bp,
        limit_screen=limit,
    )
    return obj


def _tail(pb: SlipProblem, p: int, one_load: bool, x0) -> np.ndarray:
    """``[l, b, lbz, ubz, z0, use_z0, KKT_TOL, ZERO_COST]``: what follows the data blocks in the solver's input."""
    v = pb.vehicle
    if x0 is None and not one_load:  # the same numbers for every problem with these bounds and this vehicle
        try:
            return _tail_cached(v.track_length, v.track_width, pb.bounds, p, KKT_TOL, ZERO_COST)
        except TypeError:  # unhashable bounds: not cached
            pass
    lbz, ubz = _scaled_box(pb, p, one_load)
    z0, use0 = _scaled_start(pb, x0, p, one_load)
    return np.array([v.track_length, v.track_width, *lbz, *ubz, *z0, use0, KKT_TOL, ZERO_COST])


@lru_cache(maxsize=256)
def _tail_cached(l: float, b: float, bounds, p: int, kkt: float, zero: float) -> np.ndarray:
    lbz, ubz = _box(bounds, p)
    t = np.array([l, b, *lbz, *ubz, *([0.0] * p), 0.0, kkt, zero])
    t.flags.writeable = False
    return t


@lru_cache(maxsize=64)
def _zeros(n: int) -> np.ndarray:
    """``n`` zeros (read only): the padding rows of a size class."""
    z = np.zeros(n)
    z.flags.writeable = False
    return z


@lru_cache(maxsize=64)
def _corners_cached(bounds, model: str) -> np.ndarray:
    weak, strong = corner_soils(bounds, model)
    c = np.array(weak + strong, dtype=float)
    c.flags.writeable = False
    return c


def _corners(bounds, model: str) -> np.ndarray:
    """``[weak (c, phi, K), strong (c, phi, K)]`` of :func:`corner_soils` as one array.

    The residual Function's last input.
    """
    try:
        return _corners_cached(bounds, model)
    except TypeError:  # unhashable bounds: not cached
        return _corners_cached.__wrapped__(bounds, model)


@lru_cache(maxsize=1024)
def _block_offsets(nc: int) -> np.ndarray:
    return np.arange(4, dtype=np.intp).reshape(4, 1) * nc


def _decode(pb: SlipProblem, yl: list, p: int, one_load: bool) -> tuple[list, int, bool, np.ndarray]:
    """``(z, iterations, certified, theta)`` of the solver's output list.

    ``yl = [z (p), cost, g (p), trJJ, iters, zstart (p), scale, certified]``; the certificate
    (finite numbers inside the box meeting the first-order test) is computed by the Function
    itself from its final state, with the same KKT test that stops the iteration.
    """
    z = yl[0:p]
    iters = int(yl[2 * p + 2]) if math.isfinite(yl[2 * p + 2]) else -1
    ok = yl[3 * p + 4] > 0.5
    theta = np.array(_theta_si(z, p) if all(map(math.isfinite, z)) else [math.nan] * 3)
    if ok and one_load:  # the ridge marker, as the IPOPT path reports it
        W0 = float(pb.load[0])
        c, phi = ridge_centre(
            max_thrust_expr(0.0, theta[1], W0, pb.vehicle.contact_area, "cohesion-free"),
            W0,
            pb.vehicle.contact_area,
            pb.bounds,
        )
        theta[0], theta[1] = float(c), float(phi)
    return z, iters, ok, theta


def solve_many(pbs: list, n_grid: int = 25, jit: str = "wait") -> list[Solution]:
    """:func:`solve` for many problems: the same Function and inputs, packed and decoded as arrays.

    Problems of one kind and one length are stacked; the compiled solver and the residual
    Function are called once per problem through their zero-copy buffers (no Python work per
    call beyond a row copy), so the per-problem cost is a few microseconds plus the C call.
    Gives exactly what :func:`solve` gives for each problem.
    """
    out: list[Solution | None] = [None] * len(pbs)
    groups: dict[tuple, list[int]] = {}
    for i, pb in enumerate(pbs):
        groups.setdefault((*_variant(pb), pb.n), []).append(i)
    for (p, one_load, model, n), idx in groups.items():
        k = kernel(p, model, n, n_grid, jit)
        cs, cr = k.solver, k.resjac
        nc, N = k.n, len(idx)
        P = [pbs[i] for i in idx]
        o = 4 * nc + 2
        X = np.zeros((N, cs.n_in))
        load = np.stack([pb.load for pb in P])
        X[:, 0:n] = np.stack([pb.slip for pb in P])
        X[:, nc : nc + n] = np.stack([pb.force for pb in P])
        X[:, 2 * nc : 2 * nc + n] = load
        X[:, 2 * nc + n : 3 * nc] = load[:, 0:1]
        X[:, 3 * nc : 3 * nc + n] = 1.0 / np.stack([pb.sigma for pb in P])
        X[:, 4 * nc] = [pb.vehicle.track_length for pb in P]
        X[:, 4 * nc + 1] = [pb.vehicle.track_width for pb in P]
        if one_load:  # the box depends on the load
            for r, pb in enumerate(P):
                lbz, ubz = _scaled_box(pb, p, one_load)
                X[r, o : o + 2 * p] = lbz + ubz
        else:  # one box per bounds (most batches share one)
            for b, rows_b in _by_bounds(P):
                lbz, ubz = _box(b, p)
                X[rows_b, o : o + 2 * p] = lbz + ubz
        X[:, o + 3 * p + 1] = KKT_TOL
        X[:, o + 3 * p + 2] = ZERO_COST
        if nc > GRID_ROWS:
            m = GRID_ROWS
            rows = np.take_along_axis(
                np.argsort(X[:, 0:n], axis=1, kind="stable"), _spread(n)[None, :].repeat(N, 0), axis=1
            )
            g = o + 3 * p + 3
            for j, blk in enumerate((0, nc, 2 * nc, 3 * nc)):
                X[:, g + j * m : g + (j + 1) * m] = np.take_along_axis(X[:, blk : blk + n], rows, axis=1)
        Y = _run_rows(cs, X)
        Z = Y[:, 0:p]
        cert = Y[:, 3 * p + 4] > 0.5
        theta = np.zeros((N, 3))
        if p == 3:
            theta[:, 0] = Z[:, 0] * _S0
        theta[:, 1] = Z[:, p - 2]
        theta[:, 2] = Z[:, p - 1] * _S2
        theta[~np.all(np.isfinite(Z), axis=1)] = np.nan
        if one_load:  # the ridge marker, as the IPOPT path reports it
            for r in np.nonzero(cert)[0].tolist():
                pb = P[r]
                W0, A = float(pb.load[0]), pb.vehicle.contact_area
                c, phi = ridge_centre(max_thrust_expr(0.0, theta[r, 1], W0, A, "cohesion-free"), W0, A, pb.bounds)
                theta[r, 0], theta[r, 1] = float(c), float(phi)
        corners = np.empty((N, 6))
        for b, rows_b in _by_bounds(P):  # one per bounds (the model is the group's)
            corners[rows_b] = _corners(b, model)
        RJ = _run_rows(cr, np.concatenate((theta, X[:, 0:o], corners), axis=1))
        J = RJ[:, nc : 4 * nc].reshape(N, 3, nc)[:, :, 0:n].transpose(0, 2, 1)
        _fill_solutions(out, idx, Y, RJ, theta, J, cert, (p, n, nc, one_load, cs.engine, cs.backend))
    return out  # type: ignore[return-value]


def _fill_solutions(out: list, idx: list, Y, RJ, theta, J, cert, kind: tuple) -> None:
    """The :class:`Solution` of each row of a stacked solve into ``out[idx[row]]``: its arrays are rows of the
    stacked outputs (``Y`` the solver's, ``RJ`` the residual Function's; ``theta``, ``J`` decoded from them)."""
    p, n, nc, one_load, engine, backend = kind
    iters = [int(v) if math.isfinite(v) else -1 for v in Y[:, 2 * p + 2].tolist()]
    st = Y[:, 2 * p + 3 : 3 * p + 3]  # the start (_theta_si of each row, the same products)
    start = st * [_S0, 1.0, _S2] if p == 3 else np.column_stack((np.zeros(len(idx)), st[:, 0], st[:, 1] * _S2))
    screens = RJ[:, 6 * nc : 6 * nc + 3].tolist()
    empty = np.empty(0)
    new = object.__new__
    rows = zip(idx, cert.tolist(), iters, start.tolist(), screens, list(theta), list(Y[:, 0:p]), list(RJ), list(J))
    for i, ok, it, st_r, sc, th, z, rj, Jr in rows:
        sol = out[i] = new(Solution)  # Solution(...) without the frozen dataclass's per-field setattr
        sol.__dict__.update(
            theta=th,
            certified=ok,
            iterations=it,
            start=st_r,
            residuals=rj[0:n] if ok else empty,
            jacobian=Jr if ok else empty,
            z=z,
            p=p,
            one_load=one_load,
            engine=engine,
            backend=backend,
            call_time=math.nan,
            curves=(rj[4 * nc : 4 * nc + n], rj[5 * nc : 5 * nc + n]) if ok else None,
            screen=sc[0] if ok else None,
            bp_screen=sc[1] if ok else None,
            limit_screen=sc[2] if ok else None,
        )


def _by_bounds(P: list) -> list[tuple]:
    """``[(bounds, rows of P)]``: the problems ``P`` by their bounds object (a batch of one bounds: one entry)."""
    first = P[0].bounds
    if all(pb.bounds is first for pb in P):
        return [(first, slice(None))]
    out: dict = {}
    for r, pb in enumerate(P):
        out.setdefault(id(pb.bounds), (pb.bounds, []))[1].append(r)
    return list(out.values())


def _run_rows(c: "_Caller", X: np.ndarray) -> np.ndarray:
    """Call a flat Function on each row of ``X`` through its zero-copy buffer."""
    Y = np.empty((X.shape[0], c.n_out))
    if c.trigger is None:  # pragma: no cover - CasADi without buffers
        for r in range(X.shape[0]):
            Y[r] = c(X[r])
        return Y
    with c.lock:
        xb, yb, trig = c.x, c.y, c.trigger
        for xr, yr in zip(X, Y):  # (rows as views: iterating an array makes them in C)
            xb[:] = xr
            trig()
            yr[:] = yb
    return Y


def fit_compiled(
    pb: SlipProblem, x0=None, n_grid: int = 25, ipopt_options: dict | None = None, jit: str = "wait"
) -> FitResult:
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
    jit : {"wait", "background", "off"}
        How the C code is obtained (module notes).
    """
    t0 = time.perf_counter()
    sol = solve(pb, x0, n_grid, jit)
    if not sol.certified:
        return hand_over(pb, sol, x0, n_grid, ipopt_options, t0)
    return result_of(pb, sol, x0, time.perf_counter() - t0)


def _note(sol: Solution, x0) -> str:
    src = "user start point" if x0 is not None else "variable-projection grid start"
    ridge = (
        (
            "; one normal load: solved in the identifiable parameters (F_max, K), exactly equivalent; "
            "(c, phi) is a point of the ridge"
        )
        if sol.one_load
        else ""
    )
    return f"{src}{ridge}"


def message_of(sol: Solution, x0) -> str:
    """The result message of a certified compiled solve."""
    return f"converged (compiled projected Levenberg-Marquardt, first-order conditions met; {_note(sol, x0)})"


def extra_of(sol: Solution) -> dict:
    """``extra`` of a certified compiled solve: which engine and backend, call time, start point."""
    return {
        "engine": sol.engine,
        "engine_backend": sol.backend,
        "engine_call_time_s": sol.call_time,
        "start": sol.start,
        "solver_status": "first-order conditions certified",
    }


def result_of(pb: SlipProblem, sol: Solution, x0, solve_time: float) -> FitResult:
    """The :class:`FitResult` of a certified solve (shared statistics via ``build_result``)."""
    samples = pb.result_kwargs(sol.curves, sol.screen)["samples"]
    if sol.screen is not None and sol.limit_screen is not None:  # (slip, F, W, curves, screen, limit screen)
        samples += (sol.limit_screen,)
    kw = pb.checked_kwargs(sol.residuals, sol.theta, samples)
    return build_result(
        data_kind="slip",
        model=pb.model,
        method="ipopt",
        theta=sol.theta,
        jacobian=sol.jacobian,
        weighted_residuals=sol.residuals / pb.sigma,
        residuals=sol.residuals,
        residual_unit="N",
        n_samples=pb.n,
        normal_loads=pb.load,
        vehicle=pb.vehicle,
        bounds=pb.bounds,
        status="converged",
        success=True,
        message=message_of(sol, x0),
        iterations=sol.iterations,
        solve_time=solve_time,
        sigma_known=pb.sigma_known,
        warnings=pb.noise_warning(sol.residuals, sol.bp_screen),
        extra={**extra_of(sol), "sigma_model": pb.noise_model},
        **kw,
    )


def hand_over(
    pb: SlipProblem, sol: Solution, x0, n_grid: int, ipopt_options: dict | None, t0: float, source: str = "compiled"
) -> FitResult:
    """Re-solve with the cached IPOPT path (from the last iterate if finite, else as asked)."""
    from .ipopt import fit_ipopt

    x = None
    if np.all(np.isfinite(sol.z)):
        x = np.array(_theta_si(sol.z, sol.p))
        if sol.one_load:  # a point of the same F_max inside the box
            W0 = float(pb.load[0])
            c, phi = ridge_centre(
                max_thrust_expr(0.0, x[1], W0, 0.0, "cohesion-free"), W0, pb.vehicle.contact_area, pb.bounds
            )
            x[0], x[1] = float(c), float(phi)
    elif x0 is not None:
        x = np.asarray(x0, float)
    res = fit_ipopt(pb, x, ipopt_options=ipopt_options, n_grid=n_grid)
    object.__setattr__(
        res, "message", f"{source} engine did not certify convergence; re-solved with IPOPT: " + res.message
    )
    object.__setattr__(res, "solve_time", time.perf_counter() - t0)
    res.extra["engine"] = "ipopt"
    res.extra["handed_over_from"] = sol.engine
    return res
