"""Soil identification from a straight-line drive log (sprocket torque, sprocket speed, vehicle speed).

Formulation
-----------
The obvious approach - compute the slip from the two speeds, ``i_m = 1 - v/(r w)``, and fit
the thrust from the sprocket equation against ``F(i_m)`` ("equation error") - is an
error-in-variables trap: at the small slips of a tracked vehicle on sand (a few tenths of a
percent to a few percent) the slip noise ``sigma_i ~ sigma_v / v`` is as large as the slip
itself, so the regressor is noisy and least squares is biased. On the library's simulated
logs with its default (realistic) sensor noise it returns F_max 88 % low and K on its upper
bound. This module implements it only for comparison (``formulation="equation-error"``).

The default, ``formulation="output-error"``, predicts the sprocket speed instead. At every
sample ``k`` the TRUE slip ``i_k`` is an NLP variable (a latent state, bounded to
[-0.95, 0.98]); the sprocket equation (thrust balance of DESIGN section 3,
``I dw/dt = M_s - r F(i)``) ties it to the measured torque, the kinematics ``v = r w (1 - i)``
tie it to the encoder and the speed sensor::

    d_s[k] = v_k - r w_k (1 - i_k)                      (speed residual: encoder vs. prediction)
    d_T[k] = T_k - F(i_k; F_max, K)                     (thrust residual)
    T_k    = (M_{k-1} - I (w_k - w_{k-1}) / h) / r      (discrete sprocket equation)

and IPOPT minimises ``sum(e_w^2 + e_T^2)`` with ``e_w = d_s / sigma_s`` and
``e_T = (d_T - rho d_s) / sigma_T|s`` (the pair whitened, see below) over
``(F_max, K, i_1..i_n)`` inside the soil's practical ranges. With ``sigma_T -> 0`` this is
the output-error problem "slip as NLP variables with equality constraints ``F(i_k) = T_k``,
compare the predicted sprocket speed ``v_k / (r (1 - i_k))`` with the encoder"; keeping a
thrust residual instead of an equality accounts for the noise in the torque regressor (near
the traction limit a noisy ``T_k`` can exceed ``F_max``, and the equality form becomes
infeasible or biased upwards). Both residuals are linear in every measured quantity, so no
measured value sits inside a nonlinearity: the errors in the regressors (torque, v, w) enter
additively.

Discrete sprocket equation, stiff slip. The torque of a digital drive is a command held from
one sample to the next (the library's simulator does the same). Over the interval ending at
sample k, ``I (w_k - w_{k-1}) = h M_{k-1} - r * integral(F dt)``; the slip settles within
milliseconds of a torque change (stiff), so over the interval it sits on its quasi-static
value - the one sampled at ``t_k`` - and the integral is ``h F(i_k)``: implicit Euler, the
L-stable quasi-static limit, exact for the encoder part (no smoothing or differentiation of
the encoder; noise-free simulated logs are recovered to 0.01 %). Where the thrust jumps
within an interval (a spinning track that grips again) the two differ by up to half the jump;
such samples (change to a neighbour beyond 4 noise standard deviations) get half the jump
added to their standard deviation. ``torque_hold="sample"`` uses
``T_k = (M_k - I (w_{k+1} - w_{k-1}) / (2 h)) / r`` for torque sampled from a continuous signal.

Noise. Each channel has the model ``sigma = sqrt(a^2 + (b x)^2)`` (absolute plus relative
part), given as options or estimated from the log itself (robust MAD of second differences,
binned by level: :func:`estimate_noise_profile`). Then
``sigma_s^2 = sigma_v^2 + r^2 (1 - i)^2 sigma_w,k^2`` and
``sigma_T^2 = (sigma_M,k-1^2 + (I/h)^2 (sigma_w,k^2 + sigma_w,k-1^2)) / r^2``. The encoder
reading ``w_k`` enters both residuals of sample k; their covariance
``I (1 - i) sigma_w,k^2 / h`` is removed by conditioning (``rho = cov / sigma_s^2``,
``sigma_T|s^2 = sigma_T^2 - rho cov``). The slip information of a sample is
``(r w / sigma_s)^2``, so slow samples (slip noise about ``sigma_v / v``) are down-weighted
automatically; samples with ``v`` or ``r w`` below 3 noise levels (slip undefined) and
clearly braking samples (the skid law ``F(i) = -F(|i|)`` is only a first approximation) are
dropped and counted in the result.

Identifiability. A flat drive log has one normal load ``W``, so c and phi enter only through
``F_max = A c + W tan(phi)`` (cohesion-free: ``W tan(phi)``); the NLP is solved in
``(F_max, K)`` and the Jacobian handed to :func:`~soiltrack.identify.result.build_result` is
``d e / d(c, phi, K)`` by the chain rule, whose c and phi columns are exactly proportional
(the result object then reports F_max, K, K/l and the initial slope, and the c-phi ridge).
The latent slips are profiled out (Gauss-Newton, exact to first order) by projecting each
sample's whitened residual pair onto the direction orthogonal to its slip derivative: one
reduced residual per sample, the "effective variance" residual
``d_T / sqrt(sigma_T|s^2 + (F'(i_k) + rho r w_k)^2 sigma_i^2)``, ``sigma_i = sigma_s / (r w_k)``;
so the degrees of freedom are those of the profiled problem.

Covariance (output-error). Not the Gauss-Newton ``s^2 (J^T J)^-1`` of the profiled residuals,
which was measured to be optimistic (200 seeds, light vehicle on dry sand: standardised errors
with standard deviation 1.23 for F_max and 1.19 for K; 95 % intervals held F_max 179 and K
173 times of 200), but the sandwich ``A^-1 B A^-1`` of the profiled M-estimator
(:func:`_profiled_covariance`): ``A`` the observed information of the profiled cost from the
exact per-sample Hessian (the residual-curvature terms Gauss-Newton drops are not small when the
slip noise is comparable with ``K / l``), ``B`` the empirical variance of the per-sample scores.
The Jacobian handed to the result object is the profiled one times a 2x2 matrix chosen so that
the result's ``s^2 (J^T J)^-1`` equals the sandwich (``extra["covariance"] = "sandwich"``; it
falls back to Gauss-Newton, ``"gauss-newton"``, if the observed information is not positive
definite). Measured: F_max 188/200 (94 %), K 179/200 (89.5 %), standardised-error standard
deviations 1.07 and 1.08 (``python benchmarks/drivelog_coverage.py --seeds 200``).

Gentle versus hard driving. At small slip ``F ~ F_max l i / (2 K)``: a log whose thrust stays
well below ``F_max`` pins down only this initial slope. The fit reports the correlation of the
``F_max`` and ``K`` estimates, their standard errors and the slope with its standard error,
and classifies the log: ``"gentle"`` (correlation >= 0.99, or F_max standard error >= 25 %,
or F_max on a bound), ``"hard"`` (F_max within 5 % and K within 25 % standard error), else
``"intermediate"`` - each said in plain words in the result's warnings, with the experiment
that would help.

Known limits (measured on the library's simulator, default noise, 200 seeds): K comes out low
by about 3 % on average (-2.7 % +- 0.9 %; F_max is unbiased, +0.1 % +- 0.1 %), so the 95 %
intervals of K hold the truth about 90 % of the time, the misses mostly on the low side. The
bias is the incidental-parameter (error-in-variables) bias of estimating one latent slip per
sample when the slip noise (``sigma_v / v`` about 0.03 on the light vehicle) is not small
against the curvature scale ``K / l`` (0.05) of the thrust-slip curve: with ten times less
GNSS noise it disappears (+0.5 % +- 0.3 %, 80 seeds); noise-free logs are recovered to
0.03 %, and the true noise model instead of the estimated one does not remove it (-2.6 % +-
1.6 %, 57 seeds). The second-order (delta-method) bias of the profiled score accounts for only
about a quarter of it (+0.7 %), so no such correction is applied by default; the opt-in
``bias_correction="simex"`` (:func:`_simex_correct`: refits with added speed noise, quadratic
extrapolation to none) removes it at the cost of 12 refits (see benchmarks/README.md for the
measured bias and coverage before and after). The encoder reading ``w_k``
is also in ``T_{k+1}``; this negative correlation of neighbouring scores is left out of ``B``
(conservative, see :func:`_profiled_covariance`). For a heavy vehicle on firm sand (``K / l``
about 0.4 %) GNSS speed noise of 0.05 m/s leaves K poorly determined; the result says so.
"""
from __future__ import annotations

import dataclasses
import math
import time as _time
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from ..soilmodel.data import DriveLog
from ..soilmodel.errors import DataError
from ..soilmodel.soil import PRACTICAL_BOUNDS, SoilBounds
from ..soilmodel.threadsafe import call_solver, locked_cache
from ..soilmodel.traction import check_model, shear_bracket
from ..soilmodel.vehicle import Vehicle
from .problem import FitFailed
from .result import FitResult, build_result

__all__ = ["fit_drive_log", "FORMULATIONS", "DriveLogFitError", "estimate_noise", "estimate_noise_profile",
           "prepare_drive_log", "PreparedLog", "padded_size"]

#: Formulations of :func:`fit_drive_log`.
FORMULATIONS = ("output-error", "equation-error")

#: Factor from the median absolute deviation to the standard deviation of a normal distribution.
_MAD_TO_SIGMA = 1.482602218505602

#: Fewest usable samples accepted (two identifiable combinations, a noise level, and margin).
MIN_USABLE_SAMPLES = 10

#: Latent slip bounds (skid down to -0.95, driving slip up to 0.98).
SLIP_BOUNDS = (-0.95, 0.98)

#: Correlation of the F_max and K estimates above which a log is "gentle" (only the slope).
GENTLE_CORRELATION = 0.99
#: Relative standard error of F_max above which F_max is called undetermined.
GENTLE_REL_STDERR = 0.25
#: Relative standard error of F_max below which F_max counts as pinned down (a "hard" pull).
HARD_REL_STDERR = 0.05
#: Relative standard error of K below which K counts as pinned down (with F_max: a "hard" pull).
K_REL_STDERR = 0.25

_OPTION_NAMES = ("sigma_torque", "sigma_sprocket_speed", "sigma_vehicle_speed", "torque_hold",
                 "min_speed", "sprocket_equation", "max_iter", "tol", "print_level", "multistart")


class DriveLogFitError(FitFailed):
    """Raised by :func:`fit_drive_log` with ``strict=True`` when no trustworthy estimate exists.

    A :class:`~soiltrack.identify.problem.FitFailed`; ``.result`` holds the failed result.
    """


# --------------------------------------------------------------------------------------------
# data preparation
# --------------------------------------------------------------------------------------------
def estimate_noise(x: np.ndarray) -> float:
    """Standard deviation of white measurement noise on a smooth signal, from the data alone.

    Uses the second differences ``d = x[k+1] - 2 x[k] + x[k-1]`` (variance ``6 sigma^2`` for
    white noise; a smooth signal contributes only ``h^2 x''``) and a median absolute deviation,
    so isolated steps in the signal do not inflate the estimate. Returns 0.0 for fewer than
    five samples or a noise-free signal.
    """
    x = np.asarray(x, dtype=float)
    if x.size < 5:
        return 0.0
    d = x[2:] - 2.0 * x[1:-1] + x[:-2]
    mad = float(np.median(np.abs(d - np.median(d))))
    return _MAD_TO_SIGMA * mad / math.sqrt(6.0)


def estimate_noise_profile(x: np.ndarray, n_bins: int = 8) -> tuple[float, float]:
    """Noise model ``sigma(x) = sqrt(a^2 + (b x)^2)`` (absolute plus relative part) from the data alone.

    Sensors such as torque cells and encoders have noise that grows with the reading. The
    second differences (see :func:`estimate_noise`) are grouped into ``n_bins`` equally
    populated bins by the level ``|x|`` (taken two samples either side, so that binning does
    not select on the noise itself); a robust (MAD) variance per bin is fitted to
    ``a^2 + b^2 mean(x^2)`` by least squares (weights: square root of the bin count) with
    non-negative coefficients. Returns ``(a, b)``; ``b = 0`` for a constant noise level.
    The relative part is estimated mostly from the many moderate readings; a log with very few
    large readings gets a less certain ``b`` (the covariance is scaled by the residual
    variance anyway).
    """
    x = np.asarray(x, dtype=float)
    if x.size < 5 * n_bins:
        return estimate_noise(x), 0.0
    # level of the reading at k from x[k-2] and x[k+2]: independent of the noise in d[k]
    d = x[3:-1] - 2.0 * x[2:-2] + x[1:-3]
    xc = 0.5 * (np.abs(x[:-4]) + np.abs(x[4:]))
    order = np.argsort(xc)
    rows, var, cnt = [], [], []
    for chunk in np.array_split(order, n_bins):
        dd = d[chunk]
        mad = float(np.median(np.abs(dd - np.median(dd))))
        rows.append([1.0, float(np.mean(xc[chunk] ** 2))])
        var.append((_MAD_TO_SIGMA * mad) ** 2 / 6.0)
        cnt.append(chunk.size)
    X, y, wt = np.array(rows), np.array(var), np.sqrt(np.array(cnt, dtype=float))
    fits = {}
    for cols in ((0,), (1,), (0, 1)):  # non-negative least squares on two coefficients
        A = X[:, cols] * wt[:, None]
        coef, *_ = np.linalg.lstsq(A, y * wt, rcond=None)
        if np.any(coef < 0):
            continue
        full = np.zeros(2)
        full[list(cols)] = coef
        fits[cols] = (float(np.sum(((X @ full - y) * wt) ** 2)), full)
    one = [fits[c] for c in ((0,), (1,)) if c in fits]
    if not one and (0, 1) not in fits:
        return estimate_noise(x), 0.0
    best = min(one, key=lambda f: f[0]) if one else fits[(0, 1)]
    if (0,) in fits and (1,) in fits and fits[(1,)][0] > 0.8 * fits[(0,)][0]:
        best = fits[(0,)]  # a purely relative model only when it fits clearly better
    # two coefficients only when they explain clearly more (readings spread enough to tell)
    if (0, 1) in fits and (not one or fits[(0, 1)][0] < 0.5 * best[0]):
        best = fits[(0, 1)]
    a2, b2 = best[1]
    return math.sqrt(a2), math.sqrt(b2)


@dataclass(frozen=True)
class PreparedLog:
    """The samples of a drive log that enter the fit, and their noise levels (SI).

    ``thrust`` is the thrust from the sprocket equation over the interval ending at each used
    sample (see :func:`prepare_drive_log`); ``slip_measured`` is ``1 - v/(r w)`` (for reference
    and for the equation-error comparison only). ``keep`` marks the used samples of the log.
    ``noise`` holds the noise model ``(a, b)`` per channel: ``sigma = sqrt(a^2 + (b x)^2)``.
    The speed and thrust residuals of one sample share the encoder noise of ``w_k`` (with
    ``torque_hold="zoh"``); ``coupling`` and ``sigma_thrust_cond`` whiten that 2x2 covariance.
    """

    keep: np.ndarray
    vehicle_speed: np.ndarray
    sprocket_speed: np.ndarray
    thrust: np.ndarray
    slip_measured: np.ndarray
    sigma_speed: np.ndarray          # sigma_s: of v - r w (1 - i), m/s
    sigma_thrust: np.ndarray         # sigma_T, N
    coupling: np.ndarray             # rho = cov(speed, thrust residual noise) / sigma_s^2, N s/m
    sigma_thrust_cond: np.ndarray    # sigma_T given the speed residual, sqrt(sigma_T^2 - rho^2 sigma_s^2), N
    noise: dict
    sigma_known: bool
    dropped: dict

    @property
    def n_used(self) -> int:
        """Number of samples used."""
        return int(self.thrust.size)


def _noise_model(x: np.ndarray, given: float | None) -> tuple[float, float]:
    if given is not None:
        return float(given), 0.0
    a, b = estimate_noise_profile(x)
    floor = 1e-4 * float(np.max(np.abs(x))) + 1e-12  # a 0.01 % resolution floor keeps noise-free data sane
    return max(a, floor), b


def prepare_drive_log(log: DriveLog, vehicle: Vehicle, *, sigma_torque: float | None = None,
                      sigma_sprocket_speed: float | None = None, sigma_vehicle_speed: float | None = None,
                      torque_hold: str = "zoh", min_speed: float = 0.0,
                      sprocket_equation: str = "thrust", fixed_keep: np.ndarray | None = None) -> PreparedLog:
    """Check a drive log, estimate its noise, compute the sprocket thrust and select samples.

    The sprocket equation ``I dw/dt = M_s - r F(i)`` is used in discrete form, without any
    smoothing of the encoder:

    - ``torque_hold="zoh"`` (default; the torque is a command held from each sample to the
      next, as a digital drive controller and the library's simulator do): implicit Euler over
      the interval ending at sample k, ``r F(i_k) = M_{k-1} - I (w_k - w_{k-1}) / h``. It is
      exact for the encoder part, and for the stiff slip dynamics (slip settles within
      milliseconds of a torque change, so over most of the interval the slip sits on its
      quasi-static value, the one sampled at t_k) it is the L-stable quasi-static limit.
    - ``torque_hold="sample"`` (torque measured at the sample instants of a continuous signal):
      ``r F(i_k) = M_k - I (w_{k+1} - w_{k-1}) / (2 h)``.

    With the seed's printed sprocket equation (``sprocket_equation="seed"``) ``W mu_r`` is added.

    Raises
    ------
    DataError
        Too few samples, no positive vehicle or sprocket speed, or fewer than
        :data:`MIN_USABLE_SAMPLES` usable samples; the message names the file and column.
    """
    if not isinstance(log, DriveLog):
        raise TypeError(f"fit_drive_log takes a DriveLog, got {type(log).__name__}")
    if sprocket_equation not in ("thrust", "seed"):
        raise DataError(f"unknown sprocket_equation {sprocket_equation!r}; expected 'thrust' or 'seed'")
    if torque_hold not in ("zoh", "sample"):
        raise DataError(f"unknown torque_hold {torque_hold!r}; expected 'zoh' or 'sample'")
    n = log.n_samples
    if n < MIN_USABLE_SAMPLES:
        raise DataError(f"a drive log needs at least {MIN_USABLE_SAMPLES} samples to identify F_max and K, "
                        f"got {n}", file=log.source, column="time_s")
    t = log.time
    v = log.vehicle_speed
    w = log.sprocket_speed
    M = log.sprocket_torque
    r, I, W = vehicle.sprocket_radius, vehicle.sprocket_inertia, vehicle.weight
    if not np.any(v > 0):
        raise DataError("no sample with a positive vehicle speed: a standing (or reversing) vehicle shows "
                        "nothing of the soil", file=log.source, column="vehicle_speed_m_s")
    if not np.any(w > 0):
        raise DataError("no sample with a positive sprocket speed: the tracks never turned forwards",
                        file=log.source, column="sprocket_speed_rad_s")
    for name, val in (("sigma_torque", sigma_torque), ("sigma_sprocket_speed", sigma_sprocket_speed),
                      ("sigma_vehicle_speed", sigma_vehicle_speed), ("min_speed", min_speed)):
        if val is not None and not (isinstance(val, (int, float)) and math.isfinite(val) and val >= 0):
            raise DataError(f"{name} must be a finite number >= 0, got {val!r}")
    sigma_known = None not in (sigma_torque, sigma_sprocket_speed, sigma_vehicle_speed)
    # Noise models sigma = sqrt(a^2 + (b x)^2): given (constant), or estimated from the log.
    nm = {"torque": _noise_model(M, sigma_torque), "sprocket_speed": _noise_model(w, sigma_sprocket_speed),
          "vehicle_speed": _noise_model(v, sigma_vehicle_speed)}
    s_M = np.hypot(nm["torque"][0], nm["torque"][1] * M)
    s_w = np.hypot(nm["sprocket_speed"][0], nm["sprocket_speed"][1] * w)
    s_v = np.hypot(nm["vehicle_speed"][0], nm["vehicle_speed"][1] * v)

    thrust = np.full(n, np.nan)
    sigma_T = np.full(n, np.inf)
    if torque_hold == "zoh":
        h = np.diff(t)
        thrust[1:] = (M[:-1] - I * np.diff(w) / h) / r
        sigma_T[1:] = np.sqrt(s_M[:-1] ** 2 + (I / h) ** 2 * (s_w[1:] ** 2 + s_w[:-1] ** 2)) / r
    else:
        h2 = t[2:] - t[:-2]
        thrust[1:-1] = (M[1:-1] - I * (w[2:] - w[:-2]) / h2) / r
        sigma_T[1:-1] = np.sqrt(s_M[1:-1] ** 2 + (I / h2) ** 2 * (s_w[2:] ** 2 + s_w[:-2] ** 2)) / r
    if sprocket_equation == "seed":  # I dw/dt = M_s - (F - W mu_r) r, as printed in the seed
        thrust = thrust + W * vehicle.rolling_resistance
    edge = ~np.isfinite(thrust)
    # Discretisation error: the discrete sprocket equation gives the thrust averaged over the
    # interval, the slip is sampled at its end. Where the thrust jumps within an interval (a
    # spinning track that grips again, a torque step at the traction limit) the two differ by
    # up to half the jump. Where the change to a neighbouring interval exceeds what the noise
    # allows (4 standard deviations), that half jump is added to the sample's variance.
    jump = np.zeros(n)
    fin = np.isfinite(thrust)
    d = np.where(fin[1:] & fin[:-1], np.abs(np.diff(np.where(fin, thrust, 0.0))), 0.0)
    sd = np.sqrt(np.where(fin[1:] & fin[:-1], sigma_T[1:] ** 2 + sigma_T[:-1] ** 2, np.inf))
    big = np.where(d > 4.0 * 1.25 * sd, d, 0.0)
    jump[1:] = np.maximum(jump[1:], big)
    jump[:-1] = np.maximum(jump[:-1], big)
    sigma_T = np.sqrt(sigma_T ** 2 + (0.5 * jump) ** 2)
    n_jump = int(np.count_nonzero(jump > 0))

    floor = np.maximum(max(float(min_speed), 1e-3), 3.0 * np.maximum(s_v, r * s_w))
    slow = ~edge & ~((v >= floor) & (r * w >= floor))
    braking = ~edge & ~slow & (thrust < -3.0 * sigma_T)
    keep = ~(edge | slow | braking)
    if fixed_keep is not None:  # SIMEX refits: the sample selection of the uncorrected fit
        keep = np.asarray(fixed_keep, dtype=bool).copy()
        slow, braking, edge = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), ~keep
    n_keep = int(np.count_nonzero(keep))
    if n_keep < MIN_USABLE_SAMPLES:
        raise DataError(f"only {n_keep} samples have vehicle and track speeds above 3 noise levels "
                        f"(about {float(np.median(floor)):.3g} m/s) while driving; at least {MIN_USABLE_SAMPLES} "
                        f"are needed", file=log.source, column="vehicle_speed_m_s")
    vk, wk = v[keep], w[keep]
    slip_m = 1.0 - vk / (r * wk)
    one_minus_i = np.clip(1.0 - slip_m, 1.0 - SLIP_BOUNDS[1], 1.0 - SLIP_BOUNDS[0])
    sigma_s = np.sqrt(s_v[keep] ** 2 + (r * one_minus_i * s_w[keep]) ** 2)
    sT = sigma_T[keep]
    if torque_hold == "zoh":  # w_k enters both residuals: -r (1 - i) dw_k and -I dw_k / (h r)
        hk = np.diff(t)[np.nonzero(keep)[0] - 1]
        cov = I * one_minus_i * s_w[keep] ** 2 / hk
    else:                     # the central difference does not contain w_k
        cov = np.zeros_like(sT)
    rho = cov / sigma_s ** 2
    sT_cond = np.sqrt(np.maximum(sT ** 2 - rho * cov, 0.0) + 1e-300)
    return PreparedLog(keep=keep, vehicle_speed=vk, sprocket_speed=wk, thrust=thrust[keep], slip_measured=slip_m,
                       sigma_speed=sigma_s, sigma_thrust=sT, coupling=rho, sigma_thrust_cond=sT_cond, noise=nm,
                       sigma_known=sigma_known,
                       dropped={"slow": int(np.count_nonzero(slow)), "braking": int(np.count_nonzero(braking)),
                                "edge": int(np.count_nonzero(edge)), "speed_floor_m_s": float(np.median(floor)),
                                "thrust_jumps": n_jump})


# --------------------------------------------------------------------------------------------
# the NLPs (built once per formulation and padded log length, data as parameters)
# --------------------------------------------------------------------------------------------
def _bracket_signed(slip, lk):
    """``sign(i) g(|i| l / K)`` with ``lk = l / K``."""
    return ca.sign(slip) * shear_bracket(ca.fabs(slip) * lk)


_QUIET = {"expand": True, "print_time": False, "ipopt.sb": "yes", "ipopt.print_level": 0}


def padded_size(n: int) -> int:
    """Problem size the NLP is built for: the next of 64, 96, 128, 192, 256, ... (2^k or 1.5 2^k).

    Logs of similar length share one cached solver; the extra samples get zero weight.
    """
    size = 64
    while True:
        if n <= size:
            return size
        if n <= size * 3 // 2:
            return size * 3 // 2
        size *= 2


@locked_cache(maxsize=16)
def _output_error_solver(n: int, max_iter: int, tol: float, print_level: int) -> ca.Function:
    """IPOPT solver for the output-error (latent slip) problem with ``n`` (padded) samples.

    Variables ``[F_max / F_ref, K / K_ref, i_1 / i_ref, ..., i_n / i_ref]``; parameters
    ``[F_ref, K_ref, i_ref, r, l, v(n), w(n), T(n), 1/sigma_s(n), 1/sigma_T|s(n), rho(n), pad(n)]``.
    The residual pair of each sample is whitened (its speed and thrust noise are correlated
    through the encoder): ``e_w = d_s / sigma_s``, ``e_T = (d_T - rho d_s) / sigma_T|s``.
    Padding samples have zero weights and ``pad = 1`` (a unit penalty pins their latent slip).
    """
    x = ca.SX.sym("x", 2 + n)
    p = ca.SX.sym("p", 5 + 7 * n)
    F_ref, K_ref, i_ref, r, l = (p[j] for j in range(5))
    v, w, T, iss, isT, rho, pad = (p[5 + j * n:5 + (j + 1) * n] for j in range(7))
    Fmax, K = x[0] * F_ref, x[1] * K_ref
    z = x[2:]
    slip = z * i_ref
    d_s = v - r * w * (1 - slip)
    e_w = d_s * iss
    e_T = (T - Fmax * _bracket_signed(slip, l / K) - rho * d_s) * isT
    f = 0.5 * (ca.sumsqr(e_w) + ca.sumsqr(e_T) + ca.sumsqr(pad * z))
    opts = dict(_QUIET, **{"ipopt.max_iter": max_iter, "ipopt.tol": tol, "ipopt.print_level": print_level})
    return ca.nlpsol(f"drivelog_oe_{n}", "ipopt", {"x": x, "p": p, "f": f}, opts)


@locked_cache(maxsize=16)
def _equation_error_solver(n: int, max_iter: int, tol: float, print_level: int) -> ca.Function:
    """IPOPT solver for the naive equation-error problem (slip from the measured speeds)."""
    x = ca.SX.sym("x", 2)
    p = ca.SX.sym("p", 3 + 3 * n)
    F_ref, K_ref, l = p[0], p[1], p[2]
    slip, T, isT = (p[3 + j * n:3 + (j + 1) * n] for j in range(3))
    e_T = (T - x[0] * F_ref * _bracket_signed(slip, l / (x[1] * K_ref))) * isT
    f = 0.5 * ca.sumsqr(e_T)
    opts = dict(_QUIET, **{"ipopt.max_iter": max_iter, "ipopt.tol": tol, "ipopt.print_level": print_level})
    return ca.nlpsol(f"drivelog_ee_{n}", "ipopt", {"x": x, "p": p, "f": f}, opts)


@locked_cache(maxsize=1)
def _pointwise() -> ca.Function:
    """``(slip, F_max, K, l) -> (F, dF/dslip, dF/dF_max, dF/dK)`` by AD (vectorises over rows)."""
    s, Fm, K, l = (ca.SX.sym(k) for k in ("slip", "Fmax", "K", "l"))
    F = Fm * _bracket_signed(s, l / K)
    return ca.Function("drivelog_pointwise", [s, Fm, K, l],
                       [F, ca.jacobian(F, s), ca.jacobian(F, Fm), ca.jacobian(F, K)],
                       ["slip", "Fmax", "K", "l"], ["F", "dF_ds", "dF_dFmax", "dF_dK"])


def _eval_pointwise(slip: np.ndarray, Fmax: float, K: float, l: float) -> tuple[np.ndarray, ...]:
    out = _pointwise()(slip.reshape(1, -1), Fmax, K, l)
    return tuple(np.asarray(o, dtype=float).reshape(-1) for o in out)


@locked_cache(maxsize=1)
def _pointwise_hessian() -> ca.Function:
    """``(slip, F_max, K, l) -> 3x3 Hessian of F`` w.r.t. ``(F_max, K, slip)`` by AD (maps over rows)."""
    s, Fm, K, l = (ca.SX.sym(k) for k in ("slip", "Fmax", "K", "l"))
    F = Fm * _bracket_signed(s, l / K)
    return ca.Function("drivelog_pointwise_hess", [s, Fm, K, l], [ca.hessian(F, ca.vertcat(Fm, K, s))[0]])


def _profiled_covariance(prep: "PreparedLog", r: float, slip: np.ndarray, Fmax: float, K: float, l: float,
                         F: np.ndarray, dF_ds: np.ndarray, dF_dFm: np.ndarray, dF_dK: np.ndarray):
    """Sandwich covariance of ``(F_max, K)`` for the output-error estimator with profiled slips.

    The estimator minimises ``sum_k c_k(theta, i_k)`` with ``c_k = (e_w^2 + e_T^2) / 2``; each
    latent slip is a per-sample nuisance parameter. Profiling it out gives the M-estimator
    ``sum_k psi_k(theta) = 0`` with the per-sample score ``psi_k = e_T de_T/dtheta`` (envelope
    theorem), whose asymptotic covariance is ``A^-1 B A^-1`` (Huber sandwich):

    - ``A = sum_k (H_tt - H_ti H_it / H_ii)``: the observed information of the profiled cost,
      from the EXACT per-sample Hessian ``H`` in ``(F_max, K, i_k)``, including the residual
      curvature terms ``e_T d^2 e_T`` that Gauss-Newton drops. They are not negligible here:
      the slip noise (``sigma_v / v`` about 0.03 on the light vehicle) is comparable with the
      curvature scale ``K / l`` of the thrust-slip curve, so the profiled cost is curved in a way
      the first-order (Gauss-Newton) information misses. Samples whose latent slip ends on a
      bound are not profiled (their slip is fixed there).
    - ``B = sum_k psi_k psi_k^T``: the empirical variance of the scores. It carries what the
      model-based information ``A`` leaves out - the second-order (error-in-variables) spread of
      the profiled scores and any misfit of the estimated noise model - without assuming the
      information identity ``B = A``. The encoder reading ``w_k`` also enters ``T_{k+1}``, which
      makes neighbouring scores NEGATIVELY correlated (``-I w_k / h`` and ``+I w_k / h``); the
      lag-1 cross products (Newey-West, lag 1) would subtract that, and are left out: omitting a
      negative term errs on the safe side, and measured over 100 seeds the lag-1 version was
      optimistic for F_max (standardised errors with standard deviation 1.29, coverage 90 %),
      the version used here is not (1.09, 94 %; K: 1.11 and 1.08) - the remaining spread it
      absorbs is not modelled (e.g. which samples get the thrust-jump inflation varies with the
      noise).

    Returns ``(V, A, B)`` or ``None`` when ``A`` is not positive definite.
    """
    n = slip.size
    rw = r * prep.sprocket_speed
    ss, sc, rho = prep.sigma_speed, prep.sigma_thrust_cond, prep.coupling
    d_s = prep.vehicle_speed - rw * (1 - slip)
    e_T = (prep.thrust - F - rho * d_s) / sc
    g_w = rw / ss                                                      # de_w / di (e_w is linear)
    g_T = np.column_stack([-dF_dFm / sc, -dF_dK / sc, -(dF_ds + rho * rw) / sc])
    hF = np.asarray(_pointwise_hessian()(slip.reshape(1, -1), Fmax, K, l), dtype=float)
    hF = np.transpose(hF.reshape(3, n, 3), (1, 0, 2))                  # (n, 3, 3)
    H = g_T[:, :, None] * g_T[:, None, :] - (e_T / sc)[:, None, None] * hF
    H[:, 2, 2] += g_w ** 2
    lo, hi = SLIP_BOUNDS
    free = (slip > lo + 1e-6) & (slip < hi - 1e-6) & (H[:, 2, 2] > 1e-12 * np.max(np.abs(H[:, 2, 2])))
    Hii = np.where(free, H[:, 2, 2], 1.0)
    cross = np.where(free[:, None, None], H[:, :2, 2:3] * H[:, 2:3, :2] / Hii[:, None, None], 0.0)
    A = np.sum(H[:, :2, :2] - cross, axis=0)
    psi = e_T[:, None] * g_T[:, :2]
    B = psi.T @ psi
    try:
        if not np.all(np.isfinite(A)) or not np.all(np.isfinite(B)) or np.any(np.linalg.eigvalsh(A) <= 0):
            return None
        Ai = np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return None
    V = Ai @ B @ Ai
    V = 0.5 * (V + V.T)
    if not np.all(np.isfinite(V)) or np.any(np.linalg.eigvalsh(V) <= 0):
        return None
    return V, A, B


def _g_inverse(y: np.ndarray) -> np.ndarray:
    """x >= 0 with ``1 - (1 - exp(-x))/x = y`` for y in [0, 1) (vectorised bisection)."""
    y = np.clip(np.asarray(y, dtype=float), 0.0, 0.999)
    lo, hi = np.zeros_like(y), np.full_like(y, 1e4)
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            g = np.where(mid < 1e-8, mid / 2, 1.0 + np.expm1(-mid) / np.where(mid == 0, 1.0, mid))
        lower = g < y
        lo, hi = np.where(lower, mid, lo), np.where(lower, hi, mid)
    return 0.5 * (lo + hi)


# --------------------------------------------------------------------------------------------
# the fit
# --------------------------------------------------------------------------------------------
def _fmax_bounds(bounds: SoilBounds, vehicle: Vehicle, model: str) -> tuple[float, float]:
    W, A = vehicle.weight, vehicle.contact_area
    lo = W * math.tan(bounds.friction_angle[0])
    hi = W * math.tan(bounds.friction_angle[1])
    if model == "full":
        lo += A * max(bounds.cohesion[0], 0.0)
        hi += A * bounds.cohesion[1]
    return lo, hi


def _ridge_point(Fmax: float, vehicle: Vehicle, bounds: SoilBounds, model: str,
                 c_hint: float | None) -> np.ndarray:
    """A ``(c, phi)`` on the ridge ``A c + W tan(phi) = F_max`` inside the bounds.

    The point is NOT an estimate of c and phi (only their combination is identifiable; the
    result object says so and reports the ridge's extent). It keeps ``c_hint`` (the initial
    guess's cohesion) when that is feasible, else the middle of the feasible cohesion range,
    so that neither coordinate sits on a bound merely by the choice of the point. For the
    cohesion-free model c = 0 and ``phi = atan(F_max / W)``.
    """
    W, A = vehicle.weight, vehicle.contact_area
    (clo, chi), (plo, phi_hi) = bounds.cohesion, bounds.friction_angle
    if model == "cohesion-free":
        return np.array([0.0, min(max(math.atan(Fmax / W), plo), phi_hi)])
    c_min = max(clo, (Fmax - W * math.tan(phi_hi)) / A)
    c_max = max(min(chi, (Fmax - W * math.tan(plo)) / A), c_min)
    c = 0.5 * (c_min + c_max) if c_hint is None else min(max(c_hint, c_min), c_max)
    phi = math.atan(max(Fmax - A * c, 0.0) / W)
    return np.array([c, min(max(phi, plo), phi_hi)])


def _pad(a: np.ndarray, size: int, value: float = 0.0) -> np.ndarray:
    return np.concatenate([a, np.full(size - a.size, value)])


def _run_starts(solver: ca.Function, make_x0, p, lbx, ubx, starts, Fb, Kb, F_ref, K_ref) -> dict:
    """Solve from the first start; try the next ones only if it failed or ended on a bound."""
    best = None
    total = 0.0
    for j, (Fmax0, K0) in enumerate(starts):
        t0 = _time.perf_counter()
        sol, st = call_solver(solver, x0=make_x0(Fmax0, K0), p=p, lbx=lbx, ubx=ubx)
        total += _time.perf_counter() - t0
        xs = np.asarray(sol["x"], dtype=float).reshape(-1)
        fval = float(sol["f"])
        ok = bool(st.get("success", False)) and bool(np.all(np.isfinite(xs))) and math.isfinite(fval)
        cand = {"x": xs, "f": fval, "ok": ok, "status": str(st.get("return_status", "unknown")),
                "iterations": int(st.get("iter_count", -1)), "starts_tried": j + 1}
        if best is None or (cand["ok"], -cand["f"]) > (best["ok"], -best["f"]):
            best = cand
        best["starts_tried"] = j + 1
        F, K = best["x"][0] * F_ref, best["x"][1] * K_ref
        on_bound = any(abs(val - b) <= 1e-6 * (hi - lo) for val, (lo, hi) in ((F, Fb), (K, Kb)) for b in (lo, hi))
        if best["ok"] and not on_bound:
            break
    best["time"] = total
    return best


def _solve_output_error(prep: PreparedLog, vehicle: Vehicle, F_ref: float, K_ref: float, Fb, Kb,
                        starts, max_iter: int, tol: float, print_level: int):
    n = prep.n_used
    N = padded_size(n)
    l, r = vehicle.track_length, vehicle.sprocket_radius
    i_ref = K_ref / l
    solver = _output_error_solver(N, max_iter, tol, print_level)
    p = np.concatenate([[F_ref, K_ref, i_ref, r, l], _pad(prep.vehicle_speed, N), _pad(prep.sprocket_speed, N),
                        _pad(prep.thrust, N), _pad(1.0 / prep.sigma_speed, N), _pad(1.0 / prep.sigma_thrust_cond, N),
                        _pad(prep.coupling, N), _pad(np.zeros(n), N, 1.0)])
    lbx = np.concatenate([[Fb[0] / F_ref, Kb[0] / K_ref], np.full(N, SLIP_BOUNDS[0] / i_ref)])
    ubx = np.concatenate([[Fb[1] / F_ref, Kb[1] / K_ref], np.full(N, SLIP_BOUNDS[1] / i_ref)])

    def make_x0(Fmax0: float, K0: float) -> np.ndarray:
        # latent slips from the inverse thrust-slip curve at the start values
        y = np.clip(np.abs(prep.thrust) / Fmax0, 0.0, 0.98)
        slip0 = np.clip(np.sign(prep.thrust) * _g_inverse(y) * K0 / l, SLIP_BOUNDS[0] + 1e-3, SLIP_BOUNDS[1] - 1e-3)
        return np.concatenate([[Fmax0 / F_ref, K0 / K_ref], _pad(slip0 / i_ref, N)])

    best = _run_starts(solver, make_x0, p, lbx, ubx, starts, Fb, Kb, F_ref, K_ref)
    xs = best["x"]
    return best, xs[0] * F_ref, xs[1] * K_ref, xs[2:2 + n] * i_ref


def _solve_equation_error(prep: PreparedLog, vehicle: Vehicle, F_ref: float, K_ref: float, Fb, Kb,
                          starts, max_iter: int, tol: float, print_level: int):
    n = prep.n_used
    N = padded_size(n)
    l = vehicle.track_length
    solver = _equation_error_solver(N, max_iter, tol, print_level)
    slip = np.clip(prep.slip_measured, SLIP_BOUNDS[0], SLIP_BOUNDS[1])
    p = np.concatenate([[F_ref, K_ref, l], _pad(slip, N), _pad(prep.thrust, N), _pad(1.0 / prep.sigma_thrust, N)])
    lbx = [Fb[0] / F_ref, Kb[0] / K_ref]
    ubx = [Fb[1] / F_ref, Kb[1] / K_ref]
    best = _run_starts(solver, lambda F0, K0: np.array([F0 / F_ref, K0 / K_ref]), p, lbx, ubx, starts, Fb, Kb,
                       F_ref, K_ref)
    return best, best["x"][0] * F_ref, best["x"][1] * K_ref, slip


def fit_drive_log(log: DriveLog, vehicle: Vehicle, model: str = "full", bounds: SoilBounds = PRACTICAL_BOUNDS,
                  x0=None, strict: bool = False, *, method: str = "ipopt", formulation: str = "output-error",
                  bias_correction: str | None = None, **options: Any) -> FitResult:
    """Identify the soil under a tracked vehicle from a straight-line drive log.

    Parameters
    ----------
    log
        The drive log (time, sprocket torque of both tracks, sprocket speed, vehicle speed).
    vehicle
        The vehicle (geometry, sprocket radius and inertia, mass).
    model
        ``"full"`` (Eq. 2) or ``"cohesion-free"`` (Eq. 8). A drive log has one normal load,
        so for the full model only ``F_max = A c + W tan(phi)`` and K are identifiable.
    bounds
        Box bounds on ``[c, phi, K]`` (default: the seed's practical ranges); they bound
        ``F_max`` to ``[A c_lo + W tan(phi_lo), A c_hi + W tan(phi_hi)]``.
    x0
        Optional initial guess ``[c (Pa), phi (rad), K (m)]`` (a :class:`Soil` also works).
    strict
        Raise :class:`DriveLogFitError` instead of returning a failed result.
    method
        Only ``"ipopt"``.
    formulation
        ``"output-error"`` (default: latent slip, predicted sprocket speed; see the module
        docstring) or ``"equation-error"`` (slip from the measured speeds; biased, for
        comparison only).
    **options
        ``sigma_torque`` (N m), ``sigma_sprocket_speed`` (rad/s), ``sigma_vehicle_speed`` (m/s):
        constant sensor noise levels (default: a noise model ``sqrt(a^2 + (b x)^2)`` per
        channel estimated from the log; all three given means ``sigma_known=True``);
        ``min_speed`` (m/s): extra speed floor below which samples are dropped (default: 3
        noise levels); ``sprocket_equation``: ``"thrust"`` (default, ``I dw/dt = M_s - r F``)
        or ``"seed"`` (as printed in the seed); ``torque_hold``: ``"zoh"`` (default, torque
        held from each sample to the next) or ``"sample"`` (torque sampled from a continuous
        signal), see :func:`prepare_drive_log`; ``max_iter`` (500), ``tol`` (1e-9),
        ``print_level`` (0): IPOPT settings; ``multistart`` (True): if the first solve fails or
        ends on a bound, also start from a second point (K on the other side of the range).

    bias_correction
        ``None`` (default: no correction) or ``"simex"``: opt-in simulation-extrapolation
        correction of the error-in-variables bias of F_max and K caused by the vehicle-speed
        noise (output-error only; see :func:`_simex_correct`). Options ``simex_replicates``
        (even, default 4: antithetic pairs per noise level) and ``simex_seed`` (default 0).
        Costs ``3 x simex_replicates`` extra fits.

    Returns
    -------
    FitResult
        Built by :func:`soiltrack.identify.result.build_result` with ``data_kind="drive"``.
        ``extra`` holds the identifiable combinations (``max_thrust_N``, ``initial_slope_N``
        with standard errors, their correlation), the driving regime, the sample counts and
        the noise levels used, and ``covariance``: ``"sandwich"`` (output-error: the standard
        errors and intervals are those of the sandwich covariance, see the module docstring) or
        ``"gauss-newton"`` (equation-error, or the fallback). A failed solve is a result with
        ``success=False``.

    Raises
    ------
    DataError
        Bad input (too few samples, no motion, unknown option); names file and column.
    DriveLogFitError
        With ``strict=True``, when the solver fails or returns a non-finite point.
    """
    if bias_correction is not None:
        return _simex_fit(log, vehicle, model, bounds, x0, strict, method, formulation, bias_correction, options)
    check_model(model)
    if method != "ipopt":
        raise DataError(f"unknown method {method!r} for a drive log; expected 'ipopt'")
    if formulation not in FORMULATIONS:
        raise DataError(f"unknown formulation {formulation!r}; expected one of {FORMULATIONS}")
    unknown = sorted(set(options) - set(_OPTION_NAMES) - {"_fixed_keep"})
    if unknown:
        raise DataError(f"unknown option(s) {unknown} for a drive-log fit; expected some of {list(_OPTION_NAMES)}")
    if bounds is None:
        bounds = PRACTICAL_BOUNDS
    prep = prepare_drive_log(
        log, vehicle, sigma_torque=options.get("sigma_torque"),
        sigma_sprocket_speed=options.get("sigma_sprocket_speed"),
        sigma_vehicle_speed=options.get("sigma_vehicle_speed"),
        torque_hold=str(options.get("torque_hold", "zoh")),
        min_speed=options.get("min_speed", 0.0),
        sprocket_equation=str(options.get("sprocket_equation", "thrust")), fixed_keep=options.get("_fixed_keep"))
    max_iter = int(options.get("max_iter", 500))
    tol = float(options.get("tol", 1e-9))
    print_level = int(options.get("print_level", 0))

    W, A, l = vehicle.weight, vehicle.contact_area, vehicle.track_length
    Fb = _fmax_bounds(bounds, vehicle, model)
    Kb = tuple(bounds.shear_modulus)
    F_ref = 0.5 * (Fb[0] + Fb[1])
    K_ref = math.sqrt(Kb[0] * Kb[1])

    # start values: x0 if given, else above the largest thrust seen, K in the middle (log scale)
    c_hint = None
    if x0 is not None:
        x0v = np.asarray(x0.as_vector() if hasattr(x0, "as_vector") else x0, dtype=float).reshape(-1)
        if x0v.size != 3 or not np.all(np.isfinite(x0v)):
            raise DataError(f"x0 must be three finite numbers [c (Pa), phi (rad), K (m)], got {x0!r}")
        c_hint = float(x0v[0]) if model == "full" else None
        F0 = (A * x0v[0] if model == "full" else 0.0) + W * math.tan(x0v[1])
        K0 = float(x0v[2])
    else:
        F0 = 1.2 * float(np.quantile(np.abs(prep.thrust), 0.99))
        K0 = K_ref
    F0 = min(max(F0, Fb[0] + 1e-3 * (Fb[1] - Fb[0])), Fb[1] - 1e-3 * (Fb[1] - Fb[0]))
    K0 = min(max(K0, Kb[0] * 1.001), Kb[1] * 0.999)
    starts = [(F0, K0)]
    if options.get("multistart", True):
        K_alt = min(max(K0 * (3.0 if K0 < K_ref else 1.0 / 3.0), Kb[0] * 1.001), Kb[1] * 0.999)
        starts.append((min(max(1.5 * F0, Fb[0]), Fb[1] * 0.999), K_alt))

    solve = _solve_output_error if formulation == "output-error" else _solve_equation_error
    best, Fmax, K, slip = solve(prep, vehicle, F_ref, K_ref, Fb, Kb, starts, max_iter, tol, print_level)

    # residuals and the profiled Jacobian at the solution ------------------------------------
    n = prep.n_used
    F, dF_ds, dF_dFm, dF_dK = _eval_pointwise(slip, Fmax, K, l)
    sT = prep.sigma_thrust
    if formulation == "output-error":
        rw_k = vehicle.sprocket_radius * prep.sprocket_speed
        sc = prep.sigma_thrust_cond
        # effective variance of the thrust residual after profiling out the latent slip
        s_eff = np.sqrt(sc ** 2 + ((dF_ds + prep.coupling * rw_k) * prep.sigma_speed / rw_k) ** 2)
        d_s = prep.vehicle_speed - rw_k * (1 - slip)
        e_T = (prep.thrust - F - prep.coupling * d_s) / sc
        e_w = d_s / prep.sigma_speed
        # projected (profiled) residual, model minus data: |(e_w, e_T)| at the optimum
        wres = -np.sign(e_T) * np.sqrt(e_T ** 2 + e_w ** 2)
        # raw residual: predicted minus measured sprocket speed, v_k / (r (1 - i_k)) - w_k, rad/s
        res = d_s / (vehicle.sprocket_radius * (1 - slip))
        unit = "rad/s"
    else:
        s_eff = sT
        res = F - prep.thrust                                 # model minus data, N
        wres = res / s_eff
        unit = "N"
    J2 = np.column_stack([dF_dFm, dF_dK]) / s_eff[:, None]    # d wres / d(F_max, K)
    covariance_kind = "gauss-newton"
    if formulation == "output-error" and best["ok"] and np.all(np.isfinite(J2)) and np.all(np.isfinite(wres)):
        # Sandwich covariance (see _profiled_covariance). The shared result object computes
        # s2 (J^T J)^-1; the Jacobian handed to it is J2 R with a 2x2 R chosen so that this
        # equals the sandwich: R^T (J2^T J2) R = s2 V^-1 (a change of basis within the span of
        # J2's columns: the rank, the null space and the chain rule to (c, phi, K) are unchanged).
        sand = _profiled_covariance(prep, vehicle.sprocket_radius, slip, Fmax, K, l, F, dF_ds, dF_dFm, dF_dK)
        if sand is not None:
            V = sand[0]
            s2_rb = 1.0 if prep.sigma_known else float(np.sum(wres ** 2)) / max(n - 2, 1)
            try:
                Lg = np.linalg.cholesky(J2.T @ J2)
                Lv = np.linalg.cholesky(s2_rb * np.linalg.inv(V))
                R = np.linalg.solve(Lg.T, Lv.T)
                if np.all(np.isfinite(R)):
                    J2 = J2 @ R
                    covariance_kind = "sandwich"
            except np.linalg.LinAlgError:
                pass

    finite = all(math.isfinite(z) for z in (Fmax, K)) and np.all(np.isfinite(wres)) and np.all(np.isfinite(J2))
    success = bool(best["ok"] and finite)
    warnings: list[str] = []
    extra: dict[str, Any] = {
        "formulation": formulation,
        "samples_total": log.n_samples,
        "samples_used": n,
        "samples_dropped_slow": prep.dropped["slow"],
        "samples_dropped_braking": prep.dropped["braking"],
        "samples_thrust_jump_inflated": prep.dropped["thrust_jumps"],
        "speed_floor_m_s": prep.dropped["speed_floor_m_s"],
        "noise_model": {  # sigma = sqrt(abs^2 + (rel * reading)^2), given or estimated from the log
            "torque_Nm": {"abs": prep.noise["torque"][0], "rel": prep.noise["torque"][1]},
            "sprocket_speed_rad_s": {"abs": prep.noise["sprocket_speed"][0], "rel": prep.noise["sprocket_speed"][1]},
            "vehicle_speed_m_s": {"abs": prep.noise["vehicle_speed"][0], "rel": prep.noise["vehicle_speed"][1]},
            "estimated": not prep.sigma_known},
        "torque_hold": str(options.get("torque_hold", "zoh")),
        "sprocket_equation": str(options.get("sprocket_equation", "thrust")),
        "covariance": covariance_kind,
    }
    dropped = prep.dropped["slow"] + prep.dropped["braking"] + prep.dropped["edge"]
    if prep.dropped["slow"] + prep.dropped["braking"]:
        warnings.append(
            f"{dropped} of {log.n_samples} samples not used: {prep.dropped['slow']} standing, reversing or with vehicle or track speed "
            f"below 3 noise levels (about {prep.dropped['speed_floor_m_s']:.3g} m/s: slip undefined or lost in the "
            f"speed noise), {prep.dropped['braking']} braking (negative thrust: the skid law F(i) = -F(|i|) is only "
            f"a first approximation), {prep.dropped['edge']} at the ends of the log (no sprocket-speed difference)")
    if formulation == "equation-error":
        warnings.append("equation-error formulation: slip computed from the noisy measured speeds is used as an "
                        "exact regressor, which biases F_max and K (error-in-variables); use the default "
                        "output-error formulation for estimates")

    if not success:
        msg = (f"drive-log fit failed: IPOPT returned {best['status']}"
               + ("" if finite else " with non-finite values"))
        theta = np.full(3, np.nan)
        jac = np.zeros((n, 3))
        failed = build_result(data_kind="drive", model=model, method=method, theta=theta, jacobian=jac,
                            weighted_residuals=np.where(np.isfinite(wres), wres, 0.0),
                            residuals=np.where(np.isfinite(res), res, 0.0), residual_unit=unit, n_samples=n,
                            normal_loads=np.full(n, W), vehicle=vehicle, bounds=bounds, status=best["status"],
                            success=False, message=msg, iterations=best["iterations"], solve_time=best["time"],
                            sigma_known=prep.sigma_known, warnings=tuple(warnings), extra=extra)
        if strict:
            raise DriveLogFitError(failed)
        return failed

    # (c, phi) on the ridge, and the Jacobian in [c, phi, K] by the chain rule ----------------
    c, phi = _ridge_point(Fmax, vehicle, bounds, model, c_hint)
    theta = np.array([c, phi, K])
    dFm_dc = A if model == "full" else 0.0
    dFm_dphi = W / math.cos(phi) ** 2
    jac = np.column_stack([J2[:, 0] * dFm_dc, J2[:, 0] * dFm_dphi, J2[:, 1]])

    # identifiable combinations and the driving regime -------------------------------------
    dof = max(n - 2, 1)
    s2 = 1.0 if prep.sigma_known else float(np.sum(wres ** 2)) / dof
    info = J2.T @ J2
    try:
        cov2 = s2 * np.linalg.inv(info)
        cov_ok = bool(np.all(np.isfinite(cov2))) and cov2[0, 0] > 0 and cov2[1, 1] > 0
    except np.linalg.LinAlgError:
        cov_ok = False
    slope = Fmax * l / (2 * K)
    # the largest thrust the log certainly reached (2 standard deviations below the estimate)
    thrust_peak = float(max(np.max(prep.thrust - 2.0 * sT), 0.0))
    utilisation = thrust_peak / Fmax
    n_high = int(np.count_nonzero(prep.thrust - 2.0 * sT > 0.7 * Fmax))
    extra.update({"max_thrust_N": Fmax, "shear_modulus_m": K, "initial_slope_N": slope,
                  "thrust_peak_N": thrust_peak, "thrust_utilisation": utilisation, "samples_above_70pct": n_high,
                  "slip_max": float(np.max(slip)),
                  "thrust_residual_rms_N": float(np.sqrt(np.mean((wres * s_eff) ** 2))),
                  "reduced_chi2": float(np.sum(wres ** 2)) / dof})
    at_bound = []
    for name, val, (lo, hi) in (("F_max", Fmax, Fb), ("K", K, Kb)):
        if val <= lo + 1e-6 * (hi - lo) or val >= hi - 1e-6 * (hi - lo):
            at_bound.append(name)
    corr, s_slope, relF, relK = float("nan"), float("nan"), float("inf"), float("inf")
    if cov_ok:
        sF, sK = math.sqrt(cov2[0, 0]), math.sqrt(cov2[1, 1])
        corr = float(cov2[0, 1] / (sF * sK))
        gslope = np.array([l / (2 * K), -Fmax * l / (2 * K * K)])
        s_slope = float(math.sqrt(max(gslope @ cov2 @ gslope, 0.0)))
        relF, relK = sF / Fmax, sK / K
        extra.update({"max_thrust_stderr_N": sF, "shear_modulus_stderr_m": sK, "corr_max_thrust_shear_modulus": corr,
                      "initial_slope_stderr_N": s_slope})
    if not cov_ok or abs(corr) >= GENTLE_CORRELATION or relF >= GENTLE_REL_STDERR or "F_max" in at_bound:
        regime = "gentle"
    elif relF <= HARD_REL_STDERR and relK <= K_REL_STDERR and "K" not in at_bound:
        regime = "hard"
    else:
        regime = "intermediate"
    extra["regime"] = regime

    slope_txt = (f"F_max l/(2K) = {slope:.4g} N" + (f" +- {s_slope:.2g} N" if math.isfinite(s_slope) else "")
                 + " (thrust per unit slip at small slip)")
    pct = (lambda x: f"{100 * x:.0f} %" if math.isfinite(x) else "undetermined")
    if regime == "gentle":
        warnings.append(
            f"gentle driving: the largest thrust in this log is about {thrust_peak / 1e3:.4g} kN, well below the "
            f"soil's thrust limit, so the log only shows the initial slope {slope_txt}; F_max and K are not "
            f"separable (correlation of their estimates {corr:.3f}, standard error of F_max {pct(relF)}). "
            f"To identify them, drive a hard pull near the traction limit (e.g. a hard acceleration from low "
            f"speed, a drawbar pull or a climb)")
    elif regime == "intermediate" and relF <= HARD_REL_STDERR:
        i_lo, i_hi = K / l, 10 * K / l
        warnings.append(
            f"the log reaches the traction limit (F_max = {Fmax / 1e3:.4g} kN +- {pct(relF)}), but K is poorly "
            f"determined (standard error {pct(relK)}{', on a bound' if 'K' in at_bound else ''}): the samples sit "
            f"either near zero slip or at full track spin, with few in between ({n_high} samples above 70 % of "
            f"F_max). The best determined small-slip quantity is the initial slope {slope_txt}. A sustained pull "
            f"at 50-90 % of the traction limit (slip about {i_lo:.3g} to {i_hi:.3g}) would pin K down")
    elif regime == "intermediate":
        warnings.append(
            f"F_max and K are only partly separated (correlation {corr:.3f}, standard errors: F_max {pct(relF)}, "
            f"K {pct(relK)}); the largest thrust seen is about {thrust_peak / 1e3:.4g} kN. The best determined "
            f"quantity is the initial slope {slope_txt}. A harder pull, nearer the traction limit, would pin F_max "
            f"and K down")
    else:
        extra["note"] = (f"hard pull: the thrust reached about {pct(utilisation)} of the fitted limit; F_max and K "
                         f"are separated (correlation {corr:.3f}, standard errors: F_max {pct(relF)}, K {pct(relK)})")
    if at_bound:
        warnings.append(f"{' and '.join(at_bound)} ended on the bound implied by the soil ranges: "
                        f"the data or the bounds are questionable")

    msg = (f"drive-log fit ({formulation}) converged: F_max = {Fmax:.5g} N, K = {1000 * K:.4g} mm, "
           f"{regime} log, {n} samples used")
    return build_result(data_kind="drive", model=model, method=method, theta=theta, jacobian=jac,
                        weighted_residuals=wres, residuals=res, residual_unit=unit, n_samples=n,
                        normal_loads=np.full(n, W), vehicle=vehicle, bounds=bounds, status=best["status"],
                        success=True, message=msg, iterations=best["iterations"], solve_time=best["time"],
                        sigma_known=prep.sigma_known, warnings=tuple(warnings), extra=extra)


# --------------------------------------------------------------------------------------------
# opt-in bias correction (SIMEX)
# --------------------------------------------------------------------------------------------
#: Bias corrections of :func:`fit_drive_log` (``None`` means none).
BIAS_CORRECTIONS = ("simex",)
#: Extra vehicle-speed noise levels of SIMEX, in units of the estimated noise variance.
SIMEX_LAMBDAS = (0.5, 1.0, 2.0)
#: SIMEX refits use the sample selection of the uncorrected fit.
_SIMEX_FIXED_SELECTION = True


def _simex_weights(lambdas=(0.0,) + SIMEX_LAMBDAS, at: float = -1.0) -> np.ndarray:
    """Weights ``c`` with ``sum c_j y_j`` = the least-squares quadratic in lambda through ``y_j``, at ``at``."""
    lam = np.asarray(lambdas, dtype=float)
    X = np.column_stack([np.ones_like(lam), lam, lam ** 2])
    return np.array([1.0, at, at * at]) @ np.linalg.pinv(X)


def _simex_fit(log, vehicle, model, bounds, x0, strict, method, formulation, bias_correction, options):
    if bias_correction not in BIAS_CORRECTIONS:
        raise DataError(f"unknown bias_correction {bias_correction!r}; expected None or one of {BIAS_CORRECTIONS}")
    if formulation != "output-error":
        raise DataError("bias_correction is only available for the output-error formulation")
    options = dict(options)
    n_rep = options.pop("simex_replicates", 4)
    seed = options.pop("simex_seed", 0)
    if isinstance(n_rep, bool) or not isinstance(n_rep, int) or n_rep < 2 or n_rep % 2:
        raise DataError(f"simex_replicates must be an even integer >= 2, got {n_rep!r}")
    t0 = _time.perf_counter()
    base = fit_drive_log(log, vehicle, model, bounds, x0, strict, method=method, formulation=formulation, **options)
    if not base.success:
        return base
    return _simex_correct(base, log, vehicle, model, bounds if bounds is not None else PRACTICAL_BOUNDS, x0,
                          method, options, n_rep, seed, t0)


def _simex_correct(base: FitResult, log: DriveLog, vehicle: Vehicle, model: str, bounds: SoilBounds, x0,
                   method: str, options: dict, n_rep: int, seed: int, t0: float) -> FitResult:
    """SIMEX correction of F_max and K for the vehicle-speed (GNSS) noise.

    The bias of the output-error fit grows with the vehicle-speed noise variance (an
    error-in-variables effect of the latent per-sample slips; see the module docstring).
    SIMEX measures that growth on the log itself: white Gaussian noise of variance
    ``lambda sigma_v^2`` (``sigma_v`` the noise model estimated from the log, or the given
    ``sigma_vehicle_speed``) is added to the vehicle speed for ``lambda`` in
    :data:`SIMEX_LAMBDAS`, the log is refitted (``simex_replicates`` times per level, in
    antithetic pairs ``+-z`` sharing the draws across the levels), and a quadratic in
    ``lambda`` fitted by least squares to the estimate at ``lambda = 0`` and the replicate
    means is extrapolated to ``lambda = -1`` (no speed noise).

    Applied only to ``"hard"`` logs (F_max and K both pinned down, neither on a bound); for
    gentle and intermediate logs the result is the uncorrected fit with
    ``extra["bias_correction"]["applied"] = False``, the reason, and a warning.

    Covariance of the corrected estimate: the sandwich covariance of the uncorrected fit plus
    the Monte Carlo variance of the extrapolation (from the spread of the per-pair
    extrapolations); the reported standard errors and intervals of F_max and K are those of
    this sum, centred on the corrected estimate (Jacobian rescaled as for the sandwich). The
    residuals and the regime are those of the uncorrected fit.
    """
    if base.extra.get("regime") != "hard":
        # Gentle or intermediate log (K, or F_max and K together, poorly determined, or on a bound):
        # the refitted K wanders over its range or sits on a bound, the extrapolation is no bias
        # estimate (measured, heavy vehicle on LETE sand: it cost F_max coverage). Not applied.
        extra = dict(base.extra)
        extra["bias_correction"] = {"method": "simex", "applied": False, "replicates": 0,
                                    "reason": f"{base.extra.get('regime')} log: only applied to hard logs",
                                    "time_s": _time.perf_counter() - t0}
        return dataclasses.replace(base, extra=extra, input_warnings=tuple(base.input_warnings) + (
            f"SIMEX bias correction not applied: {base.extra.get('regime')} log (F_max and K not both pinned "
            f"down, see above); estimates uncorrected",))
    W, l = vehicle.weight, vehicle.track_length
    c0, phi0, K0 = (float(z) for z in base.theta)
    jac0 = np.asarray(base.jacobian, dtype=float)
    dFm_dphi0 = W / math.cos(phi0) ** 2
    J2 = np.column_stack([jac0[:, 1] / dFm_dphi0, jac0[:, 2]])
    F0 = float(base.extra["max_thrust_N"])
    s2 = float(base.s2)
    cov0 = s2 * np.linalg.inv(J2.T @ J2)

    nm = base.extra["noise_model"]["vehicle_speed_m_s"]
    v = np.asarray(log.vehicle_speed, dtype=float)
    given = options.get("sigma_vehicle_speed")
    sig_v = (np.full(v.size, float(given)) if given is not None
             else np.sqrt(nm["abs"] ** 2 + (nm["rel"] * v) ** 2))
    keep = None
    if _SIMEX_FIXED_SELECTION:  # the uncorrected fit's samples (the speed floor would rise with the added noise)
        keep = prepare_drive_log(
            log, vehicle, sigma_torque=options.get("sigma_torque"),
            sigma_sprocket_speed=options.get("sigma_sprocket_speed"), sigma_vehicle_speed=given,
            torque_hold=str(options.get("torque_hold", "zoh")), min_speed=options.get("min_speed", 0.0),
            sprocket_equation=str(options.get("sprocket_equation", "thrust"))).keep
    rng = np.random.default_rng(seed)
    pairs = n_rep // 2
    z = rng.standard_normal((pairs, v.size))
    est = np.full((pairs, 2, len(SIMEX_LAMBDAS), 2), np.nan)   # pair, sign, level, (F_max, K)
    n_fail = 0
    for p in range(pairs):
        for si, sign in enumerate((1.0, -1.0)):
            for j, lam in enumerate(SIMEX_LAMBDAS):
                opts = dict(options)
                if keep is not None:
                    opts["_fixed_keep"] = keep
                if given is not None:
                    opts["sigma_vehicle_speed"] = float(given) * math.sqrt(1.0 + lam)
                noisy = dataclasses.replace(log, vehicle_speed=v + sign * math.sqrt(lam) * sig_v * z[p])
                try:
                    r = fit_drive_log(noisy, vehicle, model, bounds, base.theta, False, method=method, **opts)
                except DataError:
                    r = None
                if r is None or not r.success:
                    n_fail += 1
                    continue
                est[p, si, j] = (r.extra["max_thrust_N"], r.extra["shear_modulus_m"])
    if n_fail:
        # a failed refit would bias the level means; keep the uncorrected fit and say so
        extra = dict(base.extra)
        extra["bias_correction"] = {"method": "simex", "applied": False, "replicates": n_rep,
                                    "failed_refits": n_fail, "time_s": _time.perf_counter() - t0}
        return dataclasses.replace(base, extra=extra, input_warnings=tuple(base.input_warnings) + (
            f"SIMEX bias correction not applied: {n_fail} of {3 * n_rep} refits failed; estimates uncorrected",))

    w = _simex_weights()
    theta0 = np.array([F0, K0])
    per_pair = est.mean(axis=1)                       # pair, level, param (antithetic means)
    level_means = per_pair.mean(axis=0)               # level, param
    corrected = w[0] * theta0 + w[1:] @ level_means
    e_p = w[0] * theta0 + np.einsum("j,pjk->pk", w[1:], per_pair)
    cov_mc = (np.cov(e_p.T, ddof=1) / pairs) if pairs > 1 else np.zeros((2, 2))
    if pairs == 1:  # one pair: the antithetic halves give a (conservative) spread
        e_h = w[0] * theta0 + np.einsum("j,sjk->sk", w[1:], est[0])
        cov_mc = np.cov(e_h.T, ddof=1) / 2.0
    cov = cov0 + cov_mc
    Fb = _fmax_bounds(bounds, vehicle, model)
    Kb = tuple(bounds.shear_modulus)
    Fc = min(max(float(corrected[0]), Fb[0]), Fb[1])
    Kc = min(max(float(corrected[1]), Kb[0]), Kb[1])

    # Jacobian in (F_max, K) rescaled so that s2 (J^T J)^-1 = cov, then the chain rule to (c, phi, K)
    R = np.linalg.solve(np.linalg.cholesky(J2.T @ J2).T, np.linalg.cholesky(s2 * np.linalg.inv(cov)).T)
    J2c = J2 @ R
    c_hint = None
    if x0 is not None and model == "full":
        c_hint = float(np.asarray(x0.as_vector() if hasattr(x0, "as_vector") else x0, dtype=float).reshape(-1)[0])
    c, phi = _ridge_point(Fc, vehicle, bounds, model, c_hint)
    A = vehicle.contact_area
    jac = np.column_stack([J2c[:, 0] * (A if model == "full" else 0.0), J2c[:, 0] * W / math.cos(phi) ** 2, J2c[:, 1]])

    sF, sK = math.sqrt(cov[0, 0]), math.sqrt(cov[1, 1])
    gslope = np.array([l / (2 * Kc), -Fc * l / (2 * Kc * Kc)])
    extra = dict(base.extra)
    extra.update({
        "max_thrust_N": Fc, "shear_modulus_m": Kc, "initial_slope_N": Fc * l / (2 * Kc),
        "max_thrust_stderr_N": sF, "shear_modulus_stderr_m": sK,
        "corr_max_thrust_shear_modulus": float(cov[0, 1] / (sF * sK)),
        "initial_slope_stderr_N": float(math.sqrt(max(gslope @ cov @ gslope, 0.0))),
        "covariance": f"{base.extra['covariance']}+simex",
        "bias_correction": {
            "method": "simex", "applied": True, "lambdas": list(SIMEX_LAMBDAS), "replicates": n_rep,
            "antithetic_pairs": pairs, "seed": seed, "extrapolation": "quadratic in lambda, to -1",
            "uncorrected": {"max_thrust_N": F0, "shear_modulus_m": K0,
                            "max_thrust_stderr_N": math.sqrt(cov0[0, 0]), "shear_modulus_stderr_m": math.sqrt(cov0[1, 1])},
            "correction": {"max_thrust_N": Fc - F0, "shear_modulus_m": Kc - K0},
            "level_means": {"max_thrust_N": level_means[:, 0].tolist(), "shear_modulus_m": level_means[:, 1].tolist()},
            "monte_carlo_stderr": {"max_thrust_N": math.sqrt(cov_mc[0, 0]), "shear_modulus_m": math.sqrt(cov_mc[1, 1])},
            "covariance": "uncorrected sandwich + Monte Carlo variance of the extrapolation",
            "time_s": _time.perf_counter() - t0},
    })
    msg = (f"{base.message}; SIMEX-corrected: F_max = {Fc:.5g} N, K = {1000 * Kc:.4g} mm "
           f"({3 * n_rep} refits)")
    return build_result(data_kind="drive", model=model, method=method, theta=np.array([c, phi, Kc]), jacobian=jac,
                        weighted_residuals=base.weighted_residuals, residuals=base.residuals,
                        residual_unit=base.residual_unit, n_samples=base.n_samples,
                        normal_loads=np.full(base.n_samples, W), vehicle=vehicle, bounds=bounds, status=base.status,
                        success=True, message=msg, iterations=base.iterations,
                        solve_time=base.solve_time, sigma_known=base.sigma_known,
                        warnings=tuple(base.input_warnings), extra=extra)
