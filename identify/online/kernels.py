"""The estimator's CasADi kernels: built once per horizon capacity, compiled to C once per machine.

The horizon's samples are the columns of a data matrix ``D`` (rows :data:`ROWS`); their order
does not matter (every quantity is a sum over samples), so the horizon is a ring buffer. The
thrust law is the one of :mod:`soiltrack.soilmodel.traction` (``F = F_max g(i l / K)``,
:func:`~soiltrack.soilmodel.traction.slip_factor`), never a copy. Per sample ``k`` (the batch
fit's output-error formulation, :mod:`soiltrack.identify.drivelog`)::

    T_k   = (M_{k-1} - I (w_k - w_{k-1}) / h_k) / r          discrete sprocket equation (zoh)
    d_s   = v_k - r w_k (1 - i_k)
    e_w   = d_s / sigma_s                                     speed residual
    e_T   = (T_k - F_max g(i_k l / K) - rho d_s) / sigma_T|s  thrust residual (whitened pair)

with the latent slip ``i_k`` a per-sample unknown and the noise model ``sigma = sqrt(a^2 +
(b x)^2)`` per channel (:func:`prepare_kernel`: the weights depend only on the readings and
the noise levels, so they are computed when a sample enters and when the noise levels are
re-estimated). One Gauss-Newton step on ``(F_max, K, i_1..i_n)`` eliminates the slips exactly
(block-arrow structure: the Schur complement is a 2x2 system), so a step costs one pass over
the horizon (:class:`Kernels`). The same pass gives the sandwich covariance of the profiled
estimator (exact per-sample Hessian, empirical score variance), as the batch fit computes it.
"""

from __future__ import annotations

from types import SimpleNamespace

import casadi as ca

from ...soilmodel.dynamics import held_torque_weight_expr, slip_time_constant_expr
from ...soilmodel.threadsafe import locked_cache
from ...soilmodel.traction import slip_factor
from ..drivelog.prepare import SLIP_BOUNDS
from ..drivelog.relaxation import RELAXATION_SLIP_RANGE
from .. import jitcache

__all__ = [
    "RAW",
    "ROWS",
    "NOISE",
    "PARAMS",
    "SUMS",
    "Kernels",
    "kernels",
    "kernel_functions",
    "library_name",
    "KERNEL_FLAGS",
    "prepare_kernel",
    "predict_kernel",
    "predict_held_kernel",
    "JUMP_SIGMA",
    "RELAX_SLIP_RANGE",
    "SPEED_FLOOR_SIGMA",
    "BRAKING_SIGMA",
    "PREDICT_ITERATIONS",
    "PREDICT_START_U",
    "SLIP_ITERATIONS",
    "TRACK_SLIP_ITERATIONS",
    "SLIP_STEP_FRACTIONS",
    "TRACK_STEP_FRACTIONS",
]

#: A sample's readings: vehicle speed, sprocket speed and the previous one, the previous
#: torque, the time step, the thrust jump allowance (N); then what the slip-relaxation rule
#: (:mod:`soiltrack.identify.drivelog.relaxation`) needs once the next sample has arrived: the
#: sample's own torque, the next sprocket speed and time step, the slip trend the weight is
#: computed at, the pilot (F_max, K) and ``relax`` (1: mix in the next interval's mean, 0: the
#: end-point rule).
RAW = ("v", "w", "w_prev", "M_prev", "h", "jump", "M", "w_next", "h_next", "slip_trend", "F_pilot", "K_pilot", "relax")
#: Noise and vehicle constants of :func:`prepare_kernel`.
NOISE = ("aM", "bM", "aw", "bw", "av", "bv", "r", "I", "min_speed", "l")
#: Rows of the horizon's data matrix (what :func:`prepare_kernel` gives per sample; ``m`` is
#: 1 for a sample used in the fit, set to 0 outside the horizon).
ROWS = ("v", "rw", "T", "inv_sc", "inv_ss", "rho", "m")
#: Entries of the step's parameter vector: the scaled iterate, its scales, the track length,
#: the trust region, the scaled bounds, and a prior on F_max (value, weight) that holds F_max
#: where the horizon does not determine it.
PARAMS = (
    "xF",
    "xK",
    "F_ref",
    "K_ref",
    "l",
    "max_step",
    "xF_lo",
    "xF_hi",
    "xK_lo",
    "xK_hi",
    "xF_prior",
    "w_prior",
)
#: Entries of the step's sum vector (at the point before the step).
SUMS = (
    "S11",
    "S12",
    "S22",
    "g1",
    "g2",
    "cost",
    "A11",
    "A12",
    "A22",
    "B11",
    "B12",
    "B22",
    "n_used",
    "decrement",
)
#: Samples with vehicle or track speed below this many noise levels are not used (slip undefined).
SPEED_FLOOR_SIGMA = 3.0
#: Samples with thrust below minus this many thrust standard deviations are braking: not used.
BRAKING_SIGMA = 3.0
#: A thrust change beyond this many standard deviations of the difference is a jump; half of it
#: is added to the sample's thrust standard deviation (the batch fit's discretisation allowance).
JUMP_SIGMA = 5.0
#: Gauss-Newton iterations on the latent slip of a new sample before it is predicted.
PREDICT_ITERATIONS = 4
#: Start candidates of a new sample's latent slip besides the measured one, as ``u = i l / K``
#: (the slip factor's argument; its curve rises over u = 0.1 to 10). At low speed the measured
#: slip is mostly noise and can sit on the wrong plateau of the curve (thrust positive, slip
#: negative), where a Gauss-Newton step jumps to the other plateau and never reaches the steep
#: part; the batch fit starts from the thrust's slip for the same reason.
PREDICT_START_U = (0.0, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0)
#: Slip trends are clipped to this range for the relaxation weight (the batch fit's range, one home).
RELAX_SLIP_RANGE = RELAXATION_SLIP_RANGE
#: Smallest speed floor, m/s (as the batch fit).
_MIN_FLOOR = 1e-3


def _relaxation_weight(R, N, w):
    """The slip-relaxation weight ``phi`` of the next interval (the batch fit's rule, soilmodel's expressions).

    ``tau = I w / ((1 - i) r dF/di)`` at the slip trend and the pilot soil, with the estimator's own
    thrust law ``F = F_max g(i l / K)``; ``phi = phi(h / tau)`` in [0, 1/2]; 0 unless ``relax``.
    """
    lo, hi = RELAX_SLIP_RANGE
    i = ca.fmin(ca.fmax(R["slip_trend"], lo), hi)
    z = ca.SX.sym("z")
    dF = ca.substitute(ca.jacobian(R["F_pilot"] * slip_factor(z, N["l"], R["K_pilot"]), z), z, i)
    tau = slip_time_constant_expr(i, w, dF, SimpleNamespace(sprocket_inertia=N["I"], sprocket_radius=N["r"]))
    phi = ca.fmin(ca.fmax(held_torque_weight_expr(R["h"] / tau), 0.0), 0.5)
    return ca.if_else(R["relax"] > 0, phi, 0.0)


def _prepare(raw, noise):
    """Per-sample weights from the readings and the noise levels (SX).

    The thrust is the interval mean ``T_k`` (the end-point rule), or with ``relax`` the mix
    ``(1 - phi) T_k + phi T_{k+1}`` of the two interval means around the sample, its variance and
    its covariance with the speed residual mixed as :func:`~soiltrack.identify.drivelog.prepare.prepare_drive_log`
    mixes them. The outputs ``T`` and ``sT`` are the end-point mean and its noise (the jump tests).
    """
    R = {name: raw[j] for j, name in enumerate(RAW)}
    v, w, wp, Mp, h, jump = (R[k] for k in ("v", "w", "w_prev", "M_prev", "h", "jump"))
    N = {name: noise[j] for j, name in enumerate(NOISE)}
    r, I = N["r"], N["I"]
    sM = ca.sqrt(N["aM"] ** 2 + (N["bM"] * Mp) ** 2)
    sw = ca.sqrt(N["aw"] ** 2 + (N["bw"] * w) ** 2)
    swp = ca.sqrt(N["aw"] ** 2 + (N["bw"] * wp) ** 2)
    sv = ca.sqrt(N["av"] ** 2 + (N["bv"] * v) ** 2)
    T = (Mp - I * (w - wp) / h) / r
    sT2_raw = (sM**2 + (I / h) ** 2 * (sw**2 + swp**2)) / r**2
    # the slip-relaxation mix with the next interval (b = 0: the end-point rule, unchanged)
    b = _relaxation_weight(R, N, w)
    a = 1.0 - b
    hn, wn, Mk = R["h_next"], R["w_next"], R["M"]
    swn = ca.sqrt(N["aw"] ** 2 + (N["bw"] * wn) ** 2)
    sMk = ca.sqrt(N["aM"] ** 2 + (N["bM"] * Mk) ** 2)
    T_next = (Mk - I * (wn - w) / hn) / r
    var_next = (sMk**2 + (I / hn) ** 2 * (swn**2 + sw**2)) / r**2
    c_next = -(I**2) * sw**2 / (h * hn * r**2)
    T_mix = a * T + b * T_next
    sT2 = a**2 * sT2_raw + b**2 * var_next + 2.0 * a * b * c_next + (0.5 * jump) ** 2
    floor = ca.fmax(ca.fmax(N["min_speed"], _MIN_FLOOR), SPEED_FLOOR_SIGMA * ca.fmax(sv, r * sw))
    ok = ca.logic_and(ca.logic_and(v >= floor, r * w >= floor), T_mix >= -BRAKING_SIGMA * ca.sqrt(sT2))
    rw = r * w
    one_minus_i = ca.fmin(ca.fmax(v / ca.fmax(rw, _MIN_FLOOR), 1.0 - SLIP_BOUNDS[1]), 1.0 - SLIP_BOUNDS[0])
    ss2 = sv**2 + (r * one_minus_i * sw) ** 2
    cov = I * one_minus_i * sw**2 * (a / h - b / hn)
    rho = cov / ss2
    sc = ca.sqrt(ca.fmax(sT2 - rho * cov, 0.0) + 1e-300)
    row = ca.vertcat(v, rw, T_mix, 1.0 / sc, 1.0 / ca.sqrt(ss2), rho, ca.if_else(ok, 1.0, 0.0))
    return row, T, ca.sqrt(sT2_raw)


def _residuals(row, i, xF, xK, F_ref, K_ref, l, shape=slip_factor):
    """The speed and thrust residuals of one sample; ``shape(i, l, K)`` is the slip factor (soilmodel's)."""
    v, rw, T, isc, iss, rho = (row[j] for j in range(6))
    d_s = v - rw * (1 - i)
    e_w = d_s * iss
    e_T = (T - xF * F_ref * shape(i, l, xK * K_ref) - rho * d_s) * isc
    return e_w, e_T


@locked_cache(maxsize=1)
def prepare_kernel() -> ca.Function:
    """``(raw, noise) -> (row, T, sigma_T)``: a sample's data column (:data:`ROWS`, ``m`` = usable)."""
    raw = ca.SX.sym("raw", len(RAW))
    noise = ca.SX.sym("noise", len(NOISE))
    row, T, sT = _prepare(raw, noise)
    return ca.Function("online_prepare", [raw, noise], [row, T, sT], ["raw", "noise"], ["row", "T", "sT"])


#: Gauss-Newton iterations on each latent slip (at the current F_max, K) within one step.
SLIP_ITERATIONS = 2
#: ... and within a tracking step (the iteration converged: each slip starts from its optimum
#: of the previous update, moved by the step's first-order follow), with the step fractions
#: of :data:`TRACK_STEP_FRACTIONS`: a full Gauss-Newton step, kept only where it lowers the cost.
TRACK_SLIP_ITERATIONS = 1


#: Step fractions tried by each safeguarded Gauss-Newton step on a latent slip (the cheapest
#: cost wins; 0 keeps the slip): the thrust-slip curve is steep at small slip, and a full step
#: from a poor start can jump to the other side of the optimum and back.
SLIP_STEP_FRACTIONS = (1.0, 0.5, 0.25, 0.0)
#: Step fractions of a tracking step's slip iteration.
TRACK_STEP_FRACTIONS = (1.0, 0.0)


def _slip_gn(row, i, xF, xK, F_ref, K_ref, l, iterations: int, fractions: tuple[float, ...] = SLIP_STEP_FRACTIONS):
    """``iterations`` safeguarded Gauss-Newton steps on one sample's latent slip at fixed (F_max, K).

    Each step tries the ``fractions`` of the Gauss-Newton step and keeps the cheapest.
    """
    lo, hi = SLIP_BOUNDS
    z = ca.SX.sym("z")
    e = ca.vertcat(*_residuals(row, z, xF, xK, F_ref, K_ref, l))
    J = ca.jacobian(e, z)
    step = -ca.dot(J, e) / ca.fmax(ca.dot(J, J), 1e-300)
    cost = ca.sumsqr(e)
    for _ in range(iterations):
        st = ca.substitute(step, z, i)
        best_i, best_c = None, None
        for frac in fractions:
            # the fraction 0 keeps the slip (inside the bounds already): its cost shares the step's residuals
            cand = i if frac == 0.0 else ca.fmin(ca.fmax(i + frac * st, lo), hi)
            c = ca.substitute(cost, z, cand)
            if best_i is None:
                best_i, best_c = cand, c
            else:
                assert best_c is not None  # set with best_i on the first fraction
                better = c < best_c
                best_i, best_c = ca.if_else(better, cand, best_i), ca.if_else(better, c, best_c)
        i = best_i
    return i


@locked_cache(maxsize=1)
def _bracket_derivatives() -> ca.Function:
    """``u -> (g, g', g'')``: the slip factor ``g(u)`` of soilmodel (``u = i l / K``) and its derivatives (AD)."""
    u = ca.SX.sym("u")
    g = slip_factor(u, 1.0, 1.0)
    return ca.Function("online_bracket", [u], [g, ca.jacobian(g, u), ca.hessian(g, u)[0]])


def _thrust_residual_derivatives(row, i_s, xs, P, z):
    """The thrust residual ``e_T`` at ``(xs, i_s)`` with its gradient and Hessian in ``z = (xF, xK, i)``.

    Differentiated (AD) through the slip factor's local second-order model at the point,
    ``g(u0) + g'(u0) (u - u0) + g''(u0) (u - u0)^2 / 2`` with ``u0 = u``: the same value, gradient
    and Hessian as differentiating :func:`_residuals` directly (to rounding), in fewer
    operations (the slip factor's two branches are differentiated once, in ``u`` alone).
    """
    u0 = ca.SX.sym("u0")
    g0, g1, g2 = _bracket_derivatives()(u0)

    def local(i, l, K):
        du = i * l / K - u0
        return g0 + g1 * du + 0.5 * g2 * du**2

    _, e_T = _residuals(row, i_s, xs[0], xs[1], P["F_ref"], P["K_ref"], P["l"], shape=local)
    u = i_s * P["l"] / (xs[1] * P["K_ref"])
    out = ca.substitute([e_T, ca.gradient(e_T, z), ca.hessian(e_T, z)[0]], [u0], [u])
    return out[0], out[1], out[2]


def _sample_sums(iterations: int, fractions: tuple[float, ...]):
    """Per-sample contributions to the sums, the optimal slip, and its follow of a step (SX Function).

    Each latent slip is first moved to its optimum at the current (F_max, K) (``iterations``
    safeguarded Gauss-Newton steps trying the step ``fractions``, warm-started), so the sums are those of the
    profiled cost: its gradient ``g = e_T de_T/dx``, its exact Hessian ``A`` (Schur
    complement of the per-sample Hessian in (xF, xK, i), residual curvature included), the
    Gauss-Newton matrix ``S`` (a fallback where ``A`` is not positive definite) and the score
    products ``B`` of the sandwich covariance. ``follow`` is the slip's first-order change per
    unit parameter step (``i_next = i - follow . dx``), so the slips follow the step without a
    second pass over the horizon.
    """
    row = ca.SX.sym("row", len(ROWS))
    i0 = ca.SX.sym("i")
    p = ca.SX.sym("p", len(PARAMS))
    P = {name: p[j] for j, name in enumerate(PARAMS)}
    m = row[6]
    lo, hi = SLIP_BOUNDS
    xs = ca.SX.sym("xs", 2)
    i_s = ca.SX.sym("i_s")
    e_w, _ = _residuals(row, i_s, xs[0], xs[1], P["F_ref"], P["K_ref"], P["l"])
    z = ca.vertcat(xs, i_s)
    e_T, gT, hT = _thrust_residual_derivatives(row, i_s, xs, P, z)
    a, bT = gT[:2], gT[2]
    bw = row[1] * row[4]  # d e_w / d i
    Hii_gn = bw**2 + bT**2
    S = (bw**2 / Hii_gn) * (a @ a.T)  # Gauss-Newton Schur complement of the slip
    g = a * e_T  # profiled gradient (the slip's own gradient is ~0)
    H = gT @ gT.T + e_T * hT  # exact Hessian of (e_w^2 + e_T^2) / 2 in (xF, xK, i)
    H[2, 2] = H[2, 2] + bw**2
    free = ca.if_else(ca.logic_and(i_s > lo + 1e-6, i_s < hi - 1e-6), 1.0, 0.0)
    Hi = ca.if_else(H[2, 2] > 0, H[2, 2], Hii_gn)
    Hc = H[:2, :2] - free * (H[:2, 2] @ H[2, :2]) / Hi
    # an unused column (m = 0: outside the horizon, an empty slot of zeros) contributes exactly 0,
    # never 0 x NaN (its Gauss-Newton Schur term is 0 / 0)
    per = ca.vertcat(
        S[0, 0],
        S[0, 1],
        S[1, 1],
        g[0],
        g[1],
        0.5 * (e_w**2 + e_T**2),
        Hc[0, 0],
        Hc[0, 1],
        Hc[1, 1],
        g[0] ** 2,
        g[0] * g[1],
        g[1] ** 2,
        1.0,
    )
    per = ca.if_else(m > 0, per, ca.DM.zeros(per.shape[0]))
    # first-order follow of a parameter step dx: i_next = clip(i - follow . dx)
    follow = ca.if_else(m > 0, bT * a / Hii_gn, ca.DM.zeros(2))
    core = ca.Function("online_sample_core", [row, i_s, xs, p], [per, follow])
    x = ca.vertcat(P["xF"], P["xK"])
    i_opt = _slip_gn(row, i0, P["xF"], P["xK"], P["F_ref"], P["K_ref"], P["l"], iterations, fractions)
    i_opt = ca.if_else(m > 0, i_opt, i0)
    per_s, follow_s = core(row, i_opt, x, p)
    return ca.Function("online_sample_sums", [row, i0, p], [per_s, i_opt, follow_s], {"cse": True})


def _step(n: int, iterations: int, fractions: tuple[float, ...], name: str) -> ca.Function:
    """One Newton step on a horizon of capacity ``n`` (slips: ``iterations`` steps over ``fractions``)."""
    sums_f = _sample_sums(iterations, fractions)
    D = ca.MX.sym("D", len(ROWS), n)
    Z = ca.MX.sym("Z", 1, n)
    P = ca.MX.sym("P", len(PARAMS))
    tot, Zopt, follow = sums_f.map(f"{name}_sums_map", "serial", n, [2], [0])(D, Z, P)
    Q = {name: P[j] for j, name in enumerate(PARAMS)}
    xF, xK = Q["xF"], Q["xK"]
    g1 = tot[3] + Q["w_prior"] * (xF - Q["xF_prior"])
    g2 = tot[4]
    # Newton on the profiled cost (exact Hessian A) where A is positive definite, else Gauss-Newton
    A11, A12, A22 = tot[6] + Q["w_prior"], tot[7], tot[8]
    S11, S12, S22 = tot[0] + Q["w_prior"], tot[1], tot[2]
    pd = ca.logic_and(A11 > 0, A11 * A22 - A12 * A12 > 1e-9 * A11 * A22)
    H11, H12, H22 = ca.if_else(pd, A11, S11), ca.if_else(pd, A12, S12), ca.if_else(pd, A22, S22)
    mu = 1e-12 * (H11 + H22) + 1e-300
    a11, a22 = H11 + mu, H22 + mu
    det = a11 * a22 - H12 * H12
    st1 = -(a22 * g1 - H12 * g2) / det
    st2 = -(a11 * g2 - H12 * g1) / det
    ms = Q["max_step"]

    def cap(step, x):  # trust region: no parameter changes by more than max_step of its value per step
        return ca.fmin(ca.fmax(step, -ms * x), ms * x)

    lo1, hi1, lo2, hi2 = Q["xF_lo"], Q["xF_hi"], Q["xK_lo"], Q["xK_hi"]
    scale = ca.fmin(1.0, ms / ca.fmax(ca.fmax(ca.fabs(st1) / xF, ca.fabs(st2) / xK), 1e-300))
    x1, x2 = xF + scale * st1, xK + scale * st2
    out1 = ca.logic_or(x1 < lo1, x1 > hi1)
    out2 = ca.logic_or(x2 < lo2, x2 > hi2)
    # active set: a parameter stopped at its bound, the other takes its Newton step given that change
    x2b = ca.fmin(ca.fmax(x2, lo2), hi2)
    x1_given2 = ca.fmin(ca.fmax(xF + cap(-(g1 + H12 * (x2b - xK)) / a11, xF), lo1), hi1)
    x1b = ca.fmin(ca.fmax(x1, lo1), hi1)
    x2_given1 = ca.fmin(ca.fmax(xK + cap(-(g2 + H12 * (x1b - xF)) / a22, xK), lo2), hi2)
    xF_2d = ca.if_else(ca.logic_and(out2, ca.logic_not(out1)), x1_given2, x1b)
    xK_2d = ca.if_else(ca.logic_and(out1, ca.logic_not(out2)), x2_given1, x2b)
    # a parameter on a bound whose gradient pushes it outward stays there; the other takes its 1-D step
    tol = 1e-9
    act1 = ca.logic_or(ca.logic_and(xF <= lo1 * (1 + tol), g1 > 0), ca.logic_and(xF >= hi1 * (1 - tol), g1 < 0))
    act2 = ca.logic_or(ca.logic_and(xK <= lo2 * (1 + tol), g2 > 0), ca.logic_and(xK >= hi2 * (1 - tol), g2 < 0))
    xF_1d = ca.fmin(ca.fmax(xF + cap(-g1 / a11, xF), lo1), hi1)
    xK_1d = ca.fmin(ca.fmax(xK + cap(-g2 / a22, xK), lo2), hi2)
    xF_new = ca.if_else(act1, xF, ca.if_else(act2, xF_1d, xF_2d))
    xK_new = ca.if_else(act2, xK, ca.if_else(act1, xK_1d, xK_2d))
    dxe = ca.vertcat(xF_new - xF, xK_new - xK)
    # decrease of the cost predicted by the quadratic model along the step taken
    decrement = -(g1 * dxe[0] + g2 * dxe[1]) - 0.5 * (H11 * dxe[0] ** 2 + 2 * H12 * dxe[0] * dxe[1] + H22 * dxe[1] ** 2)
    lo, hi = SLIP_BOUNDS
    Zfollow = ca.fmin(ca.fmax(Zopt - (dxe[0] * follow[0, :] + dxe[1] * follow[1, :]), lo), hi)
    Znew = ca.if_else(D[len(ROWS) - 1, :] > 0, Zfollow, Zopt)
    return ca.Function(
        f"{name}_{n}",
        [D, Z, P],
        [ca.vertcat(xF_new, xK_new), Znew, ca.vertcat(tot, decrement)],
        ["D", "Z", "P"],
        ["x", "Z_new", "sums"],
    )


def _predict(row, p):
    """A new sample's latent slip and profiled residual at the parameters ``p`` (SX), and ``res(i)``."""
    P = {name: p[j] for j, name in enumerate(PARAMS)}
    lo, hi = SLIP_BOUNDS

    def res(i):
        return _residuals(row, i, P["xF"], P["xK"], P["F_ref"], P["K_ref"], P["l"])

    s = ca.fmin(ca.fmax(1 - row[0] / ca.fmax(row[1], _MIN_FLOOR), lo), hi)
    e_w, e_T = res(s)
    best = e_w**2 + e_T**2
    for u in PREDICT_START_U:
        cand = ca.fmin(ca.fmax(u * P["xK"] * P["K_ref"] / P["l"], lo), hi)
        e_w, e_T = res(cand)
        c = e_w**2 + e_T**2
        better = c < best
        s, best = ca.if_else(better, cand, s), ca.if_else(better, c, best)
    s = _slip_gn(row, s, P["xF"], P["xK"], P["F_ref"], P["K_ref"], P["l"], PREDICT_ITERATIONS)
    e_w, e_T = res(s)
    wres = ca.sign(e_T) * ca.sqrt(e_w**2 + e_T**2)
    return s, wres, res


@locked_cache(maxsize=1)
def predict_kernel() -> ca.Function:
    """A new sample's profiled residual: ``(row, P) -> [slip, wres]``.

    The latent slip starts at the cheapest of the measured slip (clipped to the slip bounds)
    and the points :data:`PREDICT_START_U` of the thrust-slip curve at the current estimate, and
    takes :data:`PREDICT_ITERATIONS` Gauss-Newton steps on ``e_w^2 + e_T^2``; ``wres`` is the
    batch fit's profiled residual ``sign(e_T) sqrt(e_w^2 + e_T^2)``.
    """
    row = ca.SX.sym("row", len(ROWS))
    p = ca.SX.sym("p", len(PARAMS))
    s, wres, _ = _predict(row, p)
    return ca.Function("online_predict", [row, p], [ca.vertcat(s, wres)], ["row", "P"], ["out"], {"cse": True})


@locked_cache(maxsize=1)
def predict_held_kernel() -> ca.Function:
    """The prediction of :func:`predict_kernel` at the held estimate, with its uncertainty: ``(row, P, V) -> out``.

    ``V`` is the held covariance over the scaled ``(xF, xK)`` as ``(V11, V12, V22)``; ``out`` is
    ``[slip, wres, var]`` with ``var = J V J'`` the variance of the whitened thrust residual that
    the held estimate's uncertainty adds (``J`` its gradient in ``(xF, xK)`` at the slip).
    """
    row = ca.SX.sym("row", len(ROWS))
    p = ca.SX.sym("p", len(PARAMS))
    V = ca.SX.sym("V", 3)
    s, wres, res = _predict(row, p)
    i = ca.SX.sym("i")
    _, e_T = res(i)
    J = ca.substitute(ca.gradient(e_T, ca.vertcat(p[PARAMS.index("xF")], p[PARAMS.index("xK")])), i, s)
    var = J[0] ** 2 * V[0] + 2 * J[0] * J[1] * V[1] + J[1] ** 2 * V[2]
    return ca.Function(
        "online_predict_held", [row, p, V], [ca.vertcat(s, wres, var)], ["row", "P", "V"], ["out"], {"cse": True}
    )


#: Compiler flags of the kernels' library: ``-O3`` (they run at every sample; the same numbers as ``-O2``
#: bit for bit, :data:`~soiltrack.identify.jitcache.FLAGS_O3`; the tracking step about 12 % faster:
#: docs/speed.md).
KERNEL_FLAGS = jitcache.FLAGS_O3


def library_name(n: int) -> str:
    """The cache name of the kernels' library of capacity ``n``."""
    return f"soiltrack_online_{n}"


def kernel_functions(n: int) -> list[ca.Function]:
    """The Functions of :class:`Kernels` of capacity ``n``, in its order (one generated C file)."""
    prep = prepare_kernel()
    prep_all = prep.map(f"online_prepare_all_{n}", "serial", n, [1], [])
    return [
        _step(n, SLIP_ITERATIONS, SLIP_STEP_FRACTIONS, "online_step"),
        _step(n, TRACK_SLIP_ITERATIONS, TRACK_STEP_FRACTIONS, "online_track"),
        predict_kernel(),
        prep,
        prep_all,
        predict_held_kernel(),
    ]


class Kernels:
    """The compiled Functions of one horizon capacity: ``step``, ``track``, ``predict``, ``prepare``, ``prepare_all``,
    ``predict_held``.

    ``step`` is the Newton step of a horizon whose iteration has not converged (start, after a
    change of terrain: :data:`SLIP_ITERATIONS` safeguarded slip steps); ``track`` the step of a
    converged one (:data:`TRACK_SLIP_ITERATIONS`: less work per sample). Both share the inputs
    and outputs.

    ``backend`` says what evaluates them (C code from the per-user cache, or CasADi's
    virtual machine when no compiler is available: same numbers, slower); ``library`` is the
    shared library's path (``None`` for the virtual machine).
    """

    def __init__(self, n: int) -> None:
        comp = jitcache.load(kernel_functions(n), library_name(n), wait=True, flags=KERNEL_FLAGS)
        self.step, self.track, self.predict, self.prepare, self.prepare_all, self.predict_held = comp.functions
        self.backend = comp.backend
        self.library = comp.path if comp.is_c else None
        self.capacity = n


@locked_cache(maxsize=8)
def kernels(n: int) -> Kernels:
    """The :class:`Kernels` of capacity ``n`` (built and compiled once per process and machine)."""
    return Kernels(n)
