"""Drive-log fits with unmodelled effects: three residual channels, effect parameters, latent slips.

The nominal output-error problem (:mod:`.nlp`) uses two channels per sample, the
encoder (speed residual) and the sprocket thrust. Most drive-log effects (docs/physics.md, "Unmodelled effects")
show only in the HULL force balance ``m dv/dt = F(i) - R(v, i)``, so the joint problem adds it
as a third channel. Per used sample ``k``, with ``theta = (F_lim, K, effect parameters)`` and the
latent slip ``i_k``::

    d_s = v_k - r_eff w_k (1 - i_k)                              speed (encoder) residual, m/s
    T_k = (M_k' - tau_loss(w_k) - I dw_k/dt) / r_eff              sprocket thrust, N
    d_T = T_k - F(i_k)                                           thrust residual, N
    d_H = F(i_k) - R(v_k, i_k) - m_eff a_k                        hull balance residual, N

whitened as ``e_w = d_s / sigma_s``, ``e_T = (d_T - rho d_s) / sigma_T|s`` (as in the nominal
problem; ``sigma_s`` and ``sigma_T`` follow ``r_eff``) and ``e_H = d_H / sigma_H`` with
``sigma_H = m_eff sigma_a`` (it depends on ``mass_error``: errors in the acceleration regressor
are weighted as such, Deming-style); IPOPT minimises ``sum |e_k|^2 / 2``. ``M_k'`` and
``dw_k/dt`` are those of the discrete sprocket equation (:func:`.prepare.prepare_drive_log`).
The acceleration ``a_k`` is the IMU column ``vehicle_accel_m_s2`` when the log has it (noise
model estimated from that column), else the central difference of the measured vehicle speed
(``sigma_a`` from the speed noise; about ``sqrt(2) sigma_v / (2 h)``, so the hull channel then
carries little per sample).

All physics comes from :mod:`soiltrack.soilmodel.effects`: ``thrust_with_effects`` (shear-shape
effects), ``motion_resistance`` (grade, speed_resistance, slip_sinkage, the normal load of
grade and mass_error), ``torque_loss`` (drivetrain_friction), ``effective_radius``
(radius_error, in the slip kinematics and the torque arm), ``effective_mass`` (mass_error).

Soil parametrisation. A drive log has one normal load, so the soil enters through the log's
thrust limit ``F_lim = A c + N tan(phi)`` at its ACTUAL normal load ``N = W (1 + delta)
cos(theta)`` and K. The thrust is ``thrust_with_effects`` evaluated with the cohesion-free law at
``tan(phi) = F_lim / N`` (identical to the full law for every effect except
``pressure_distribution``, whose load shift acts on the frictional part only: the split of
``F_lim`` into cohesion and friction is not identifiable from one load, and the fit treats it
as frictional). Consequently ``grade`` and ``mass_error`` do not show in the thrust-slip relation
(their ``cos(theta)`` and ``1 + delta`` are absorbed by ``F_lim``); they show in the hull channel.
The reported ``(c, phi)`` is a point of the ridge ``A c + N tan(phi) = F_lim`` at the fitted N.

Covariance: the sandwich ``A^-1 B A^-1`` of the profiled M-estimator (as for the nominal fit,
:mod:`.covariance`), here from CasADi's exact per-sample Hessian of
``|e_k|^2 / 2`` in ``(theta, i_k)``. Parameters with ``fixed`` values are not estimated.
Identifiability: a direction of ``A`` with a relative eigenvalue below ``1e-10`` is not
identifiable; an effect parameter whose estimate correlates with another estimate (soil or
effect) beyond :data:`~..estimates.least_squares.WEAK_CORRELATION` is flagged with the correlation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import casadi as ca
import numpy as np

from ...soilmodel.data import DriveLog
from ...soilmodel.effects import (
    EFFECTS,
    EffectSet,
    effect_symbols,
    effective_mass,
    effective_normal_load,
    effective_radius,
    motion_resistance,
    parameter_bounds,
    parameter_scale,
    thrust_with_effects,
    torque_loss,
)
from ...soilmodel.errors import DataError
from ...soilmodel.threadsafe import locked_cache
from ...soilmodel.dense_call import call_dense
from ...soilmodel.vehicle import Vehicle
from .noise import noise_model
from .prepare import SLIP_BOUNDS, PreparedLog

__all__ = [
    "JointData",
    "joint_data",
    "parse_fixed",
    "effect_layout",
    "residual_function",
    "derivative_function",
    "sensitivity_function",
    "joint_solver",
    "padded_data",
    "SlipSolver",
    "best_slips",
    "sample_outputs",
    "chunked_outputs",
    "cse_function",
    "SAMPLE_FUNCTIONS",
    "HULL_ROW",
    "CHANNELS",
    "DATA_ROWS",
]

#: Residual channels of a drive log (raw residuals: measured minus predicted).
CHANNELS = ("sprocket_speed_rad_s", "thrust_N", "hull_N")
#: Rows of the per-sample data matrix handed to the residual function.
DATA_ROWS = ("v", "w", "M", "dw_dt", "a", "sigma_v", "sigma_w_slip", "sigma_T", "cov_sT", "inv_sigma_H")
#: Index of the hull channel's weight in :data:`DATA_ROWS` (0 switches the channel off).
HULL_ROW = DATA_ROWS.index("inv_sigma_H")

_QUIET: dict[str, Any] = {"expand": True, "print_time": False, "ipopt.sb": "yes", "ipopt.print_level": 0}


@dataclass(frozen=True)
class JointData:
    """Per-sample data of the joint problem (used samples only; rows of :data:`DATA_ROWS`).

    ``D`` is ``(9, n)``; ``sigma_hull`` (N) is ``inf`` where no acceleration exists;
    ``accel_source`` is ``"imu"`` or ``"speed-difference"``; ``accel_noise`` the noise model
    ``(a, b)`` of the acceleration, m/s^2.
    """

    D: np.ndarray
    sigma_hull: np.ndarray
    accel_source: str
    accel_noise: tuple[float, float]


def joint_data(
    log: DriveLog,
    vehicle: Vehicle,
    prep: PreparedLog,
    sigma_accel: float | None = None,
    accel_noise: tuple[float, float] | None = None,
) -> JointData:
    """Assemble the per-sample data of the joint problem from the log and its preparation.

    The torque and sprocket acceleration behind each thrust are the preparation's (its torque hold
    and discretisation). ``accel_noise`` (``(a, b)``, m/s^2) overrides the estimate (held-out blocks
    use the fit's).
    """
    idx = np.nonzero(prep.keep)[0]
    t, v = log.time, log.vehicle_speed
    n_all = t.size
    M_used, dwdt = prep.torque_used, prep.dw_dt  # the preparation's discretisation of the sprocket equation
    m = vehicle.mass
    if log.vehicle_accel is not None:
        acc = np.asarray(log.vehicle_accel, dtype=float)
        nm = accel_noise if accel_noise is not None else noise_model(acc, sigma_accel)
        a = acc[idx]
        s_a = np.hypot(nm[0], nm[1] * a)
        source = "imu"
    else:
        va, vb = prep.noise["vehicle_speed"]
        s_v = np.hypot(va, vb * v)
        a = np.full(idx.size, np.nan)
        s_a = np.full(idx.size, np.inf)
        ok = (idx >= 1) & (idx + 1 < n_all)
        j = idx[ok]
        dt = t[j + 1] - t[j - 1]
        a[ok] = (v[j + 1] - v[j - 1]) / dt
        s_a[ok] = np.sqrt(s_v[j + 1] ** 2 + s_v[j - 1] ** 2) / dt
        nm = (float(np.median(s_a[ok])) if np.any(ok) else math.inf, 0.0)
        source = "speed-difference"
    sigma_H = m * s_a
    good = np.isfinite(a) & np.isfinite(sigma_H) & (sigma_H > 0)
    inv_H = np.where(good, 1.0 / np.where(good, sigma_H, 1.0), 0.0)
    # noise parts at the nominal radius; the residual function rescales them with r_eff
    va, vb = prep.noise["vehicle_speed"]
    wa, wb = prep.noise["sprocket_speed"]
    s_v = np.hypot(va, vb * prep.vehicle_speed)
    one_minus_i = np.clip(1.0 - prep.slip_measured, 1.0 - SLIP_BOUNDS[1], 1.0 - SLIP_BOUNDS[0])
    sw_slip = one_minus_i * np.hypot(wa, wb * prep.sprocket_speed)
    cov = prep.coupling * prep.sigma_speed**2
    D = np.vstack(
        [
            prep.vehicle_speed,
            prep.sprocket_speed,
            M_used,
            dwdt,
            np.where(good, a, 0.0),
            s_v,
            sw_slip,
            prep.sigma_thrust,
            cov,
            inv_H,
        ]
    )
    return JointData(
        D=D, sigma_hull=np.where(good, sigma_H, np.inf), accel_source=source, accel_noise=(float(nm[0]), float(nm[1]))
    )


def parse_fixed(fixed: Any) -> dict[str, float]:
    """``fixed`` as ``{"effect.param": value}``.

    Accepts ``{"grade": 0.05}`` (primary parameter), ``{"grade": {"theta_rad": 0.05}}`` or
    ``{"grade.theta_rad": 0.05}``; values are checked against the parameter's admissible range.
    """
    if fixed is None:
        return {}
    if not isinstance(fixed, Mapping):
        raise DataError(
            f"fixed must be a mapping like {{'grade': 0.05}} or {{'grade.theta_rad': 0.05}}, got {type(fixed).__name__}"
        )
    out: dict[str, float] = {}
    for key, val in fixed.items():
        name, dot, param = str(key).partition(".")
        if name not in EFFECTS:
            raise DataError(f"fixed: unknown effect {name!r}; valid: {sorted(EFFECTS)}")
        spec = EFFECTS[name]
        items = val.items() if isinstance(val, Mapping) else [(param if dot else spec.primary, val)]
        for p, x in items:
            ps = spec.param(str(p))
            if ps.integer:
                raise DataError(f"fixed: {name}.{ps.name} is a fixed integer of the effect, give it in effects")
            try:
                xf = float(x)
            except (TypeError, ValueError):
                raise DataError(f"fixed: {name}.{ps.name} must be a number, got {x!r}") from None
            if not (math.isfinite(xf) and ps.lower <= xf <= ps.upper):
                raise DataError(
                    f"fixed: {name}.{ps.name} = {x!r} outside its admissible range [{ps.lower:g}, {ps.upper:g}]"
                )
            out[f"{name}.{ps.name}"] = xf
    return out


def effect_layout(labels: list[str], vehicle: Vehicle) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lower and upper physical bounds and typical scales of the effect parameters (as for slip fits:
    :func:`~soiltrack.soilmodel.effects.parameter_bounds` and ``parameter_scale``)."""
    lo, hi, sc = [], [], []
    for lab in labels:
        name, _, p = lab.partition(".")
        a, b = parameter_bounds(name, p, vehicle)
        lo.append(a)
        hi.append(b)
        sc.append(parameter_scale(name, p, vehicle))
    return np.array(lo, dtype=float), np.array(hi, dtype=float), np.array(sc, dtype=float)


@locked_cache(maxsize=32)
def residual_function(vehicle: Vehicle, structure: EffectSet) -> tuple[ca.Function, tuple[str, ...]]:
    """Per-sample residuals ``(theta, i, d) -> (e[3], raw[3], F, T)`` and the effect labels.

    ``theta = [F_lim, K, effect parameters...]`` (labels in that order after ``F_lim, K``),
    ``d`` the rows of :data:`DATA_ROWS`. ``raw`` are measured minus predicted, per channel of
    :data:`CHANNELS`: encoder minus ``v / (r_eff (1 - i))``, ``T - F(i)``, ``m_eff a - (F - R)``.
    """
    mapping, vec, labels = effect_symbols(structure, ca.SX, vehicle)
    Flim, K, slip = ca.SX.sym("F_lim"), ca.SX.sym("K"), ca.SX.sym("slip")
    d = ca.SX.sym("d", len(DATA_ROWS))
    v, w, Mu, dwdt, a, s_v, sw_slip, sT, cov, isH = (d[j] for j in range(len(DATA_ROWS)))
    W, I = vehicle.weight, vehicle.sprocket_inertia
    r_eff = effective_radius(vehicle, mapping)
    m_eff = effective_mass(vehicle, mapping)
    N = effective_normal_load(W, vehicle, mapping)
    # the log's thrust limit F_lim = N tan(phi): the soil law of soilmodel at tan(phi) = F_lim / N
    F = thrust_with_effects(slip, 0.0, ca.atan(Flim / N), K, W, vehicle, mapping, "cohesion-free")
    loss = torque_loss(w, vehicle, mapping)
    T = (Mu - loss - I * dwdt) / r_eff
    d_s = v - r_eff * w * (1 - slip)
    R = motion_resistance(v, slip, vehicle, mapping)
    hull = m_eff * a - (F - R)
    # sigma_H = m_eff sigma_a: the acceleration noise scales with the actual mass (a weight fixed at
    # the nominal mass would make the hull channel an ordinary regression on the noisy acceleration,
    # attenuating mass_error: measured -9 % on delta = 0.1, light vehicle)
    # the speed and thrust noise scale with the effective radius (radius_error), like the hull
    # noise with the mass: weights fixed at the nominal r would attenuate eps (measured +10 %)
    ratio = r_eff / vehicle.sprocket_radius
    ss2 = s_v**2 + (r_eff * sw_slip) ** 2
    sTe = sT / ratio
    rho = cov / ss2
    sTc = ca.sqrt(ca.fmax(sTe**2 - rho * cov, 0.0) + 1e-300)
    e = ca.vertcat(d_s / ca.sqrt(ss2), (T - F - rho * d_s) / sTc, -hull * isH * (vehicle.mass / m_eff))
    raw = ca.vertcat(w - v / (r_eff * (1 - slip)), T - F, hull)
    theta = ca.vertcat(Flim, K, vec)
    fn = ca.Function(
        "drivelog_joint_residual", [theta, slip, d], [e, raw, F, T], ["theta", "slip", "d"], ["e", "raw", "F", "T"]
    )
    return fn, tuple(labels)


def _sample_symbols(vehicle: Vehicle, structure: EffectSet) -> tuple[ca.Function, ca.SX, ca.SX, ca.SX]:
    """The per-sample residual function and fresh symbols of its inputs ``(theta, i, d)``."""
    res, _ = residual_function(vehicle, structure)
    return res, ca.SX.sym("theta", res.size1_in(0)), ca.SX.sym("slip"), ca.SX.sym("d", len(DATA_ROWS))


@locked_cache(maxsize=32)
def derivative_function(vehicle: Vehicle, structure: EffectSet) -> ca.Function:
    """Per-sample ``(theta, i, d) -> (e, de/dtheta, de/di, Hessian of |e|^2/2 in (theta, i))`` by AD."""
    res, theta, slip, d = _sample_symbols(vehicle, structure)
    e = res(theta, slip, d)[0]
    z = ca.vertcat(theta, slip)
    H = ca.hessian(0.5 * ca.sumsqr(e), z)[0]
    return ca.Function(
        "drivelog_joint_derivatives", [theta, slip, d], [e, ca.jacobian(e, theta), ca.jacobian(e, slip), H]
    )


@locked_cache(maxsize=32)
def sensitivity_function(vehicle: Vehicle, structure: EffectSet) -> ca.Function:
    """Per-sample ``(theta, i, d) -> (e, de/dtheta, de/di, draw/di)`` by AD: :func:`derivative_function` without
    the Hessian (for score tests and sensitivities; with every candidate effect on, the Hessian's ``(p + 1)^2``
    entries were most of the evaluation), and the derivative of the channels' residuals ``raw`` (measured units,
    :func:`residual_function`) with respect to the slip (the latent slip's leverage on each channel)."""
    res, theta, slip, d = _sample_symbols(vehicle, structure)
    e, raw = res(theta, slip, d)[:2]
    return ca.Function(
        "drivelog_joint_sensitivities",
        [theta, slip, d],
        [e, ca.jacobian(e, theta), ca.jacobian(e, slip), ca.jacobian(raw, slip)],
    )


@locked_cache(maxsize=32)
def _slip_newton_function(vehicle: Vehicle, structure: EffectSet) -> ca.Function:
    """Per-sample ``(theta, i, d) -> (c, dc/di, d2c/di2, |de/di|^2)`` with ``c = |e|^2 / 2``.

    The last output is the Gauss-Newton curvature (never negative).
    """
    res, theta, slip, d = _sample_symbols(vehicle, structure)
    e = res(theta, slip, d)[0]
    c = 0.5 * ca.sumsqr(e)
    g, h = ca.gradient(c, slip), ca.hessian(c, slip)[0]
    return ca.Function("drivelog_joint_slip_newton", [theta, slip, d], [c, g, h, ca.sumsqr(ca.jacobian(e, slip))])


#: Samples per call of the compiled slip kernels (a log's samples are padded to a multiple of it).
SLIP_CHUNK = 64
#: Step fractions the compiled slip step tries itself (1, 1/2, 1/4, 1/8); a sample none of them lets
#: descend (rare: the far, flat part of the thrust-slip curve) gets the halvings down to 2^-29 in Python.
SLIP_STEP_FRACTIONS = 4
#: Halvings of a slip step at most (then the step is 2^-30 of the Newton step, taken as it is).
_MAX_HALVINGS = 30


@locked_cache(maxsize=32)
def _slip_step_function(vehicle: Vehicle, structure: EffectSet) -> ca.Function:
    """Per-sample safeguarded Newton step of the latent slip: ``(theta, i, d) -> (i_new, c_new, ok, step, c)``.

    ``c = |e|^2 / 2`` at ``i``; the step is Newton's ``-c' / c''`` where ``c'' > 0``, else the Gauss-Newton
    ``-c' / |de/di|^2`` (a descent direction of the right length scale where the cost is not convex in the
    slip); ``i_new`` is ``i`` plus the largest of :data:`SLIP_STEP_FRACTIONS` fractions ``1, 1/2, ...`` of it
    that does not raise the cost (``ok = 1``), inside the slip bounds; ``ok = 0`` (and ``i_new = i``) if none.
    One call per Newton iteration of every sample: the data cross from numpy to CasADi once per iteration
    (the conversions, not the arithmetic, were most of the time of the former per-fraction calls).
    """
    res, theta, slip, d = _sample_symbols(vehicle, structure)
    newton = _slip_newton_function(vehicle, structure)
    c, g, h, hgn = newton(theta, slip, d)
    lo, hi = SLIP_BOUNDS
    step = ca.fmin(ca.fmax(-g / ca.if_else(h > 0, h, ca.fmax(hgn, 1e-300)), lo - hi), hi - lo)
    bar = c * (1 + 1e-12) + 1e-300
    s_new, c_new, ok = slip, c, ca.SX(0)
    for k in reversed(range(SLIP_STEP_FRACTIONS)):  # smallest first: the largest fraction that descends wins
        cand = ca.fmin(ca.fmax(slip + 0.5**k * step, lo), hi)
        ck = 0.5 * ca.sumsqr(res(theta, cand, d)[0])
        good = ck <= bar
        s_new, c_new, ok = ca.if_else(good, cand, s_new), ca.if_else(good, ck, c_new), ca.if_else(good, 1, ok)
    return ca.Function("drivelog_joint_slip_step", [theta, slip, d], [s_new, c_new, ok, step, c])


def cse_function(fn: ca.Function) -> ca.Function:
    """``fn`` (an SX Function) with its common subexpressions merged, for CasADi's virtual machine.

    ``ca.cse`` computes each value once: the same operations on the same operands, so the same numbers
    (checked bit for bit in the tests). The slip step's four candidate costs share everything that does
    not depend on the slip (930 -> 607 instructions with grade): the virtual machine, which answers until
    the C code is compiled, runs it 2.3 times faster. The C compiler finds most of it itself (6 %), and
    merging costs about 10 ms per function, so the compiled libraries are generated from ``fn`` as it is.
    """
    return _rebuilt(fn, "_cse", ca.cse)


def _rebuilt(fn: ca.Function, suffix: str, outputs) -> ca.Function:
    """The SX Function ``fn`` rebuilt with ``outputs(its outputs)`` (same inputs and names, ``suffix`` added)."""
    ins = fn.sx_in()
    return ca.Function(fn.name() + suffix, ins, outputs(fn.call(ins)), fn.name_in(), fn.name_out())


@locked_cache(maxsize=32)
def _slip_cost_function(vehicle: Vehicle, structure: EffectSet) -> ca.Function:
    """Per-sample cost ``(theta, i, d) -> |e|^2 / 2``."""
    res, theta, slip, d = _sample_symbols(vehicle, structure)
    return ca.Function("drivelog_joint_slip_cost", [theta, slip, d], [0.5 * ca.sumsqr(res(theta, slip, d)[0])])


@locked_cache(maxsize=32)
def _slip_kernels(vehicle: Vehicle, structure: EffectSet):
    """The slip step and the cost, mapped over :data:`SLIP_CHUNK` samples, from C code when the per-user
    cache has it.

    :func:`~soiltrack.identify.jitcache.load` without waiting: the virtual machine answers until the
    C library, compiled once per machine in the background, is there (the same operations, the same
    numbers); the per-sample Newton iterations of a 3,000-sample log are most of a diagnosis's time.
    """
    from ..jitcache import load

    step = _slip_step_function(vehicle, structure)
    kernels = load(
        [step.map(SLIP_CHUNK), _slip_cost_function(vehicle, structure).map(SLIP_CHUNK)], "drivelog_slip", wait=False
    )
    if not kernels.is_c:  # until the C code is there: the step with its common subexpressions merged
        kernels.functions = [cse_function(step).map(SLIP_CHUNK), kernels.functions[1]]
    return kernels


class _Chunked:
    """Per-sample evaluation of a chunk-mapped kernel ``(theta, i, d)`` over the samples of ``D``.

    ``theta`` is one column (broadcast to every sample by CasADi); the samples are padded with
    samples at rest (:func:`padded_data`) to a multiple of :data:`SLIP_CHUNK`. ``D`` is
    converted to CasADi once, for calls on all its samples; a call on a subset (``idx``) converts
    that subset.
    """

    def __init__(self, fn: ca.Function, D: np.ndarray) -> None:
        self.fn = fn
        self.D = np.asarray(D, dtype=float)
        self._full: np.ndarray | None = None

    def __call__(self, th: np.ndarray, slip: np.ndarray, idx: np.ndarray | None = None) -> list[np.ndarray]:
        slip = np.asarray(slip, dtype=float).ravel()
        n = slip.size
        k = -(-n // SLIP_CHUNK)
        size = k * SLIP_CHUNK
        if idx is None:
            size = -(-slip.size // SLIP_CHUNK) * SLIP_CHUNK
            if self._full is None or self._full.shape[1] != size:
                # data already padded (the profiled fit pads them once) are used as they are: no copy
                self._full = self.D if self.D.shape[1] == size else padded_data(self.D, size)
            outs = chunked_outputs(self.fn, th, slip, self._full)
        else:
            outs = chunked_outputs(self.fn, th, slip, self.D[:, idx])
        return [o.ravel() for o in outs]


#: Most chunks of :data:`SLIP_CHUNK` samples evaluated by one mapped call (16,384 samples): a longer log is
#: evaluated in pieces. A cached map of a whole long log held memory in proportion to its size (measured
#: 74 MB retained after a 180,000-sample fit, 19 sizes of shrinking active sets).
MAP_PIECE = 256


def chunked_outputs(fn: ca.Function, theta: np.ndarray, slip: np.ndarray, D: np.ndarray) -> list[np.ndarray]:
    """Outputs of ``fn``, a per-sample function mapped over :data:`SLIP_CHUNK` samples, over the ``n`` samples
    of ``D``, as ``per_sample.map(n)`` gives them: each the ``rows x (n cols)`` array (sample ``k`` in columns
    ``k cols ... (k + 1) cols - 1``).

    ``theta`` is one column for every sample; ``slip`` one value per sample; ``D`` the samples' data, or the
    data already padded (:func:`padded_data`) to the next multiple of :data:`SLIP_CHUNK`. The samples are
    padded with samples at rest, evaluated in ``ceil(n / SLIP_CHUNK)`` chunks through
    :func:`~soiltrack.soilmodel.dense_call.call_dense`, and the padding dropped.
    """
    s_in = np.asarray(slip, dtype=float).ravel()
    n = s_in.size
    k = -(-n // SLIP_CHUNK)
    size = k * SLIP_CHUNK
    D = np.asarray(D, dtype=float)
    Dp = D if D.shape[1] == size else padded_data(D, size)
    s = np.zeros((1, size))
    s[0, :n] = s_in
    th = np.asarray(theta, dtype=float).reshape(-1, 1)
    if k <= MAP_PIECE:
        outs = call_dense(_mapped(fn, k), th, s, Dp)
    else:  # a long log in pieces of MAP_PIECE chunks: bounded maps and temporaries, the same per-sample values
        w = MAP_PIECE * SLIP_CHUNK
        pieces = [
            call_dense(_mapped(fn, -(-min(w, size - a) // SLIP_CHUNK)), th, s[:, a : a + w], Dp[:, a : a + w])
            for a in range(0, size, w)
        ]
        outs = [np.hstack([p[j] for p in pieces]) for j in range(len(pieces[0]))]
    return [o.reshape(o.shape[0], size, o.shape[1] // size)[:, :n, :].reshape(o.shape[0], -1) for o in outs]


#: The per-sample functions :func:`sample_outputs` evaluates, in the order of their compiled library.
SAMPLE_FUNCTIONS = ("residual", "derivative", "sensitivity")


@locked_cache(maxsize=32)
def _sample_kernels(vehicle: Vehicle, structure: EffectSet):
    """:func:`residual_function`, :func:`derivative_function` and :func:`sensitivity_function` mapped over
    :data:`SLIP_CHUNK` samples, from C code when the per-user cache has it (compiled once per machine, after
    the process that first needs it exits: ``load(defer=True)``; the virtual machine until then)."""
    from ..jitcache import load

    fns = (
        residual_function(vehicle, structure)[0],
        derivative_function(vehicle, structure),
        sensitivity_function(vehicle, structure),
    )
    return load([_dense_outputs(f).map(SLIP_CHUNK) for f in fns], "drivelog_samples", wait=False, defer=True)


def _dense_outputs(fn: ca.Function) -> ca.Function:
    """``fn`` with every output dense (structural zeros written as zeros: the same values), so that
    :func:`~soiltrack.soilmodel.dense_call.call_dense` takes its buffer path (a sparse Jacobian output sent
    the derivatives through the plain call and its conversions: 15 ms on 3,072 samples, 0.8 ms through the
    buffer)."""
    return _rebuilt(fn, "_dense", lambda outs: [ca.densify(o) for o in outs])


def sample_outputs(
    vehicle: Vehicle, structure: EffectSet, which: str, theta: np.ndarray, slip: np.ndarray, D: np.ndarray
) -> list[np.ndarray]:
    """Outputs of a per-sample function of the model over the samples of ``D``, as ``fn.map(n)`` gives them.

    ``which`` is one of :data:`SAMPLE_FUNCTIONS` (:func:`residual_function`, :func:`derivative_function`,
    :func:`sensitivity_function`); ``theta`` one column for every sample, ``slip`` one value per sample.
    Each output is the ``rows x (n cols)`` array of the map over the ``n`` samples (sample ``k`` in columns
    ``k cols ... (k + 1) cols - 1``): the same numbers, evaluated from the chunked kernels (C code once
    compiled) through :func:`~soiltrack.soilmodel.dense_call.call_dense` instead of a map built and called
    with conversions per evaluation (``python benchmarks/bench_drivelog_engine.py --kernels``: the derivatives
    on 2,704 samples 23.2 -> 0.80 ms).
    """
    if which not in SAMPLE_FUNCTIONS:
        raise ValueError(f"sample_outputs: which must be one of {SAMPLE_FUNCTIONS}, got {which!r}")
    kernels = _sample_kernels(vehicle, structure)
    kernels.upgrade()
    return chunked_outputs(kernels.functions[SAMPLE_FUNCTIONS.index(which)], theta, slip, D)


def _slip_pair(vehicle: Vehicle, structure: EffectSet, D: np.ndarray) -> tuple[_Chunked, _Chunked]:
    """``(slip step, cost)`` per sample of ``D``: C code if loaded, else the virtual machine."""
    k = _slip_kernels(vehicle, structure)
    k.upgrade()
    return _Chunked(k.functions[0], D), _Chunked(k.functions[1], D)


class SlipSolver:
    """The latent slips of one set of samples ``D`` for any parameters: the per-sample minimum of ``|e_k|^2 / 2``.

    Safeguarded Newton (steps halved until the cost does not rise) inside the slip bounds, all
    samples at once; the same per-sample problem that the fit profiles out. Where the cost is not
    convex in the slip (a noisy measured slip far out on the flat part of the thrust-slip curve)
    the step is the Gauss-Newton one, ``-dc/di / |de/di|^2``, a descent direction of the right
    length scale (a gradient step of 1e-3 / |c''| crawled there: measured 2,400 of 2,704 samples of
    a heavy log still moving after 40 iterations). Build it once per data set and call it with many
    parameter values: the data cross to CasADi once.
    """

    def __init__(self, vehicle: Vehicle, structure: EffectSet, D: np.ndarray) -> None:
        self.step_k, self.cost_k = _slip_pair(vehicle, structure, D)

    def costs(self, theta: np.ndarray, slip: np.ndarray) -> np.ndarray:
        """Per-sample cost ``|e_k|^2 / 2`` at ``theta`` and the given slips."""
        return self.cost_k(np.asarray(theta, dtype=float).reshape(-1, 1), slip)[0]

    def solve(self, theta: np.ndarray, slip0: np.ndarray, iterations: int = 40) -> np.ndarray:
        """Per-sample minima from ``slip0`` (at most ``iterations`` Newton iterations per sample)."""
        theta = np.asarray(theta, dtype=float).reshape(-1, 1)
        lo, hi = SLIP_BOUNDS
        s = np.clip(np.asarray(slip0, dtype=float).ravel(), lo, hi)
        n = s.size
        # per-sample active set: a sample whose step fell below 1e-10 is done (each sample's Newton iteration
        # is independent of the others); while most samples are active, all are evaluated from the data
        # converted once, and the inactive ones' results are dropped
        act = np.arange(n)
        for _ in range(iterations):
            if act.size == 0:
                break
            whole = 4 * act.size > n
            out = self.step_k(theta, s if whole else s[act], None if whole else act)
            s_new, ok, step, c = (o[act] if whole else o for o in (out[0], out[2], out[3], out[4]))
            sa = s[act]
            pend = np.nonzero(ok == 0)[0]
            s_new = np.where(ok != 0, s_new, sa + 0.5**_MAX_HALVINGS * step)
            # samples no fraction of the compiled step let descend: the further halvings, 6 per call
            for k0 in range(SLIP_STEP_FRACTIONS, _MAX_HALVINGS, 6):
                if pend.size == 0:
                    break
                tk = 0.5 ** np.arange(k0, min(k0 + 6, _MAX_HALVINGS))
                cand = np.clip(sa[pend, None] + tk[None, :] * step[pend, None], lo, hi)
                cn = self.cost_k(theta, cand.ravel(), np.repeat(act[pend], tk.size))[0].reshape(pend.size, -1)
                good = cn <= c[pend, None] * (1 + 1e-12) + 1e-300
                hit = np.any(good, axis=1)
                s_new[pend[hit]] = cand[hit, np.argmax(good[hit], axis=1)]
                pend = pend[~hit]
            s_new = np.clip(s_new, lo, hi)
            moved = np.abs(s_new - sa) >= 1e-10
            s[act] = s_new
            act = act[moved]
        return s

    def best(self, theta: np.ndarray, starts: list[np.ndarray], iterations: int = 40) -> np.ndarray:
        """Per-sample minima from several starts, keeping the lowest cost.

        The per-sample cost can have two minima (e.g. with ``slip_sinkage`` the hull balance
        ``F(i) - W mu_s |i|`` is not monotone in the slip: a spinning track has a second, low-slip
        solution); starting from the inverse thrust-slip curve AND from the slip measured from the
        speeds (accurate at large slip) finds the right one.
        """
        best: np.ndarray | None = None
        best_c: np.ndarray | None = None
        for s0 in starts:
            s = self.solve(theta, s0, iterations)
            c = self.costs(theta, s)
            if best is None or best_c is None:
                best, best_c = s, c
            else:
                better = c < best_c
                best, best_c = np.where(better, s, best), np.where(better, c, best_c)
        if best is None:
            raise ValueError("SlipSolver.best: no start slips given")
        return best


def best_slips(
    vehicle: Vehicle,
    structure: EffectSet,
    theta: np.ndarray,
    D: np.ndarray,
    starts: list[np.ndarray],
    iterations: int = 40,
) -> np.ndarray:
    """Latent slips of the samples ``D`` at ``theta``, the best of several starts (:meth:`SlipSolver.best`)."""
    return SlipSolver(vehicle, structure, D).best(theta, starts, iterations)


def _mapped(fn: ca.Function, n: int) -> ca.Function:
    """``fn.map(n)``, cached per size on the function object (maps are cheap but not free to build)."""
    cache = _MAP_CACHE.setdefault(id(fn), (fn, {}))[1]
    m = cache.get(n)
    if m is None:
        if len(cache) > 256:  # bounded: the sizes of one log's shrinking active sets
            cache.clear()
        m = cache[n] = fn.map(n)
    return m


_MAP_CACHE: dict[int, tuple[ca.Function, dict[int, ca.Function]]] = {}


def padded_data(D: np.ndarray, size: int) -> np.ndarray:
    """The per-sample data ``D`` (rows of :data:`DATA_ROWS`) padded to ``size`` samples for a cached solver.

    A padding sample is a vehicle at rest: no speed, torque, acceleration or hull weight, unit speed and
    thrust noise. Its residuals are zero at zero slip whatever the parameters (no torque loss at ``w = 0``,
    no speed for ``r_eff`` to scale, ``F(0) = 0``), so it is inert: its latent slip stays at 0 and it adds
    nothing to the cost or its derivatives. (Padding with ``v = r w = 1`` was not: with
    ``drivetrain_friction`` its thrust ``-tau_loss / r`` pulled 1 N-noise samples along every step of
    ``tau``, an ill-conditioned valley IPOPT crawled through, and biased the fit; with ``radius_error``
    its speed residual depended on ``eps``.)
    """
    n = D.shape[1]
    Dp = np.hstack([D, np.zeros((D.shape[0], size - n))])
    Dp[DATA_ROWS.index("sigma_v"), n:] = 1.0
    Dp[DATA_ROWS.index("sigma_T"), n:] = 1.0
    return Dp


#: Samples per call of the compiled NLP kernels: every padded size of a joint problem
#: (:func:`~.nlp.padded_size`: 64, 96, 128, 192, ...) is a multiple of it.
NLP_CHUNK = 32


@locked_cache(maxsize=32)
def _hessian_sample_function(vehicle: Vehicle, structure: EffectSet) -> ca.Function:
    """Per-sample ``(theta, i, d) -> (upper triangle of the theta block, theta-i column and i-i entry)`` of the
    Hessian of ``|e|^2 / 2`` in ``(theta, i)`` (AD of :func:`_slip_cost_function`; the theta block by column)."""
    cost1 = _slip_cost_function(vehicle, structure)
    p_dim = cost1.size1_in(0)
    th1, s1, d1 = (ca.SX.sym(cost1.name_in(j), cost1.sparsity_in(j)) for j in range(3))
    H1 = ca.hessian(cost1(th1, s1, d1), ca.vertcat(th1, s1))[0]
    tri = [(i, j) for j in range(p_dim) for i in range(j + 1)]
    return ca.Function(
        "drivelog_joint_hessian1", [th1, s1, d1], [ca.vertcat(*[H1[i, j] for i, j in tri]), H1[:, p_dim]]
    )


@locked_cache(maxsize=32)
def _nlp_kernels(vehicle: Vehicle, structure: EffectSet):
    """The joint NLP's per-sample cost, its reverse derivative and the per-sample Hessian, mapped over
    :data:`NLP_CHUNK` samples, from C code when the per-user cache has it.

    :func:`~soiltrack.identify.jitcache.load` without waiting, compiled once per machine after the process
    that first needs it exits (``defer=True``); the virtual machine until then. The reverse derivative is
    generated into the same library under the name CasADi looks for (``adj1_<name>``), so that IPOPT's
    gradient, CasADi's reverse AD of the objective's graph, evaluates the same per-sample operations from C.
    """
    from ..jitcache import load

    return load(_nlp_kernel_functions(vehicle, structure), "drivelog_nlp", wait=False, defer=True)


def _nlp_kernel_functions(vehicle: Vehicle, structure: EffectSet) -> list[ca.Function]:
    """The functions of :func:`_nlp_kernels`' library: cost map, its reverse derivative, Hessian map."""
    cost = _slip_cost_function(vehicle, structure).map(NLP_CHUNK)
    return [cost, cost.reverse(1), _hessian_sample_function(vehicle, structure).map(NLP_CHUNK)]


def nlp_backend(vehicle: Vehicle, structure: EffectSet, n: int) -> bool:
    """Whether the joint solver of ``n`` (padded) samples can evaluate its per-sample functions from C now.

    False while the library compiles in the background (the virtual machine answers meanwhile, with the
    same numbers), without a compiler, or for a size that is not a multiple of :data:`NLP_CHUNK`.
    """
    if n % NLP_CHUNK:
        return False
    k = _nlp_kernels(vehicle, structure)
    k.upgrade()
    return k.is_c


@locked_cache(maxsize=16)
def joint_solver(
    vehicle: Vehicle,
    structure: EffectSet,
    n: int,
    max_iter: int,
    tol: float,
    print_level: int,
    compiled: bool = False,
) -> ca.Function:
    """IPOPT solver of the joint problem with ``n`` (padded) samples.

    Variables ``[theta / scale (2 + n_e), i_1 / i_ref, ..., i_n / i_ref]``; parameters
    ``[scale (2 + n_e), i_ref, D (10 n, column-major per sample), pad (n)]``. Padding samples
    (:func:`padded_data`) are inert and have ``pad = 1`` (a unit penalty pins their latent slip at 0).
    IPOPT gets the exact Hessian from :func:`_hessian_of_lagrangian`; the barrier parameter is adaptive.
    ``compiled``: the per-sample cost, its reverse derivative and Hessian from the C library of
    :func:`_nlp_kernels` (see :func:`nlp_backend`), else CasADi's virtual machine; the graph around them,
    and so every number IPOPT sees, is the same.
    """
    res, _ = residual_function(vehicle, structure)
    p_dim = res.size1_in(0)
    x = ca.MX.sym("x", p_dim + n)
    p = ca.MX.sym("p", p_dim + 1 + len(DATA_ROWS) * n + n)
    scale = p[:p_dim]
    i_ref = p[p_dim]
    D = ca.reshape(p[p_dim + 1 : p_dim + 1 + len(DATA_ROWS) * n], len(DATA_ROWS), n)
    pad = p[p_dim + 1 + len(DATA_ROWS) * n :]
    theta = x[:p_dim] * scale
    z = x[p_dim:]
    if compiled:
        kernels = _nlp_kernels(vehicle, structure)
        if not kernels.is_c or n % NLP_CHUNK:
            raise ValueError(f"joint_solver: no compiled kernels for {n} samples ({kernels.backend})")
        cost_map = kernels.functions[0].map(n // NLP_CHUNK)
        hess_map = kernels.functions[2].map(n // NLP_CHUNK)
    else:
        cost_map = _slip_cost_function(vehicle, structure).map(n)
        hess_map = _hessian_sample_function(vehicle, structure).map(n)
    # MX graph over the mapped per-sample cost (not expanded): built in about a third of the time
    # of the inlined SX graph (3,000 samples: 3.8 s against 10.4 s first call, same optimum);
    # derivatives are maps of the per-sample SX derivatives
    f = ca.sum2(cost_map(ca.repmat(theta, 1, n), (z * i_ref).T, D)) + 0.5 * ca.sumsqr(pad * z)
    # adaptive barrier parameter: the fits start near their optimum (the nominal fit's soil, the latent slips
    # at their per-sample minimum) with no bound active but K's, and the monotone rule spent most iterations
    # lowering mu from 0.1 (measured on 60 s logs, same optima to 10 digits: light 30/20/25/26 -> 18/11/13/17
    # iterations for the nominal / drivetrain_friction / grade / speed_resistance fits, heavy 57/16/27/20 ->
    # 51/10/13/13); the convergence test (tol) is unchanged. The fits now start at the profiled optimum
    # (drivelog_profiled): no bound push (the default 1 % of a range moved a drivetrain loss off its optimum)
    # and a small barrier parameter, capped (free to grow, the adaptive rule raised it to about 1 and the fit
    # took 91 iterations to come back; with the cap 4-9)
    opts = dict(
        _QUIET,
        **{
            "ipopt.max_iter": max_iter,
            "ipopt.tol": tol,
            "ipopt.print_level": print_level,
            "ipopt.mu_strategy": "adaptive",
            "expand": False,
            "ipopt.bound_push": 1e-8,
            "ipopt.bound_frac": 1e-8,
            "ipopt.mu_init": 1e-8,
            "ipopt.mu_max": 1e-5,
            "hess_lag": _hessian_of_lagrangian(hess_map, x, p, theta, z, scale, i_ref, D, pad),
        },
    )
    return ca.nlpsol(f"drivelog_joint_{n}", "ipopt", {"x": x, "p": p, "f": f}, opts)


def _hessian_of_lagrangian(
    hess_map: ca.Function, x: ca.MX, p: ca.MX, theta: ca.MX, z: ca.MX, scale: ca.MX, i_ref: ca.MX, D: ca.MX, pad: ca.MX
) -> ca.Function:
    """The exact Hessian of the joint cost for IPOPT, from ONE map of the per-sample Hessians.

    The cost is a sum of per-sample terms in ``(theta, i_k)``: its Hessian is an arrowhead (a dense
    ``theta`` block, one ``theta``-``i_k`` column and one diagonal entry per sample). CasADi's own Hessian of
    the mapped graph colours it into ``p + 1`` forward-over-reverse sweeps of the whole map (measured 27-40 ms
    per evaluation on 3,072 samples, about 60 % of IPOPT's time); the per-sample ``(p + 1)^2`` Hessian
    (:func:`_hessian_sample_function`, ``hess_map`` its map over the samples) mapped once is the same matrix
    (to rounding, checked in the tests) in 9 ms. Output: the upper triangle (``triu:hess:gamma:x:x`` of the
    solver interface) with the objective multiplier ``lam_f``; no constraints.
    """
    p_dim = theta.numel()
    n = z.numel()
    tri = [(i, j) for j in range(p_dim) for i in range(j + 1)]  # upper triangle of the theta block, by column
    Htt, Hs = hess_map(ca.repmat(theta, 1, n), (z * i_ref).T, D)
    tt = ca.sum2(Htt) * ca.vertcat(*[scale[i] * scale[j] for i, j in tri])  # chain rule to x = theta / scale
    cross = Hs[:p_dim, :] * ca.repmat(scale * i_ref, 1, n)
    diag = Hs[p_dim, :] * i_ref**2 + (pad**2).T
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", 0, 1)
    nz = lam_f * ca.vertcat(tt, ca.reshape(ca.vertcat(cross, diag), -1, 1))
    # nonzeros in column order: the theta block's upper triangle, then per sample its theta column and diagonal
    rows = [i for i, _ in tri] + [r for k in range(n) for r in list(range(p_dim)) + [p_dim + k]]
    cols = [j for _, j in tri] + [p_dim + k for k in range(n) for _ in range(p_dim + 1)]
    sp = ca.Sparsity.triplet(p_dim + n, p_dim + n, rows, cols)
    return ca.Function(
        "nlp_hess_l", [x, p, lam_f, lam_g], [ca.MX(sp, nz)], ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"]
    )
