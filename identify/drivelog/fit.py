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
[-0.95, 0.98]); the sprocket equation (thrust balance of docs/physics.md,
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
The slip is not always stiff against the sample interval: after a torque step it relaxes with
``tau = I w / ((1 - i) r dF/di)``, about 4 ms for the light vehicle at a few percent of slip and far
longer on the flat of the curve, so at 50 Hz the interval's mean thrust lags its end. On hard pulls
this puts F_max a few percent high with intervals that miss it (noise-free pulls at 50 Hz: +3.3 %,
10 standard errors; 8 deg pulls with noise: 8 of 20 intervals hold the truth).
``discretisation="relaxation"`` takes the thrust at sample k as ``(1 - phi_k) T_k + phi_k T_{k+1}``
with the slip-relaxation weight ``phi_k`` (:mod:`.relaxation`, at the soil of a first fit with the
end-point rule; 20 of 20 on those pulls), but on the default profile its intervals are a little
narrow (60 seeds: F_max 52 and K 49 of 60 hold the truth, against 56 and 55 with the end-point rule),
for a reason not yet found, so neither rule is the default alone: without ``discretisation`` the fit
is made with both and reports the relaxation fit where the two disagree beyond
:data:`DISCRETISATION_SHIFT_SE` standard errors, else the end-point fit (:func:`_discretisation_check`;
``extra["discretisation_check"]["reason"]`` says which and why). This one rule serves every caller: the
command line, ``identify.fit``, segment maps and ``fit_many``. The relaxation rule carries a curvature
term (:func:`~soiltrack.soilmodel.dynamics.held_torque_stencil_expr`, :mod:`.relaxation`).
``python benchmarks/drivelog_discretisation.py`` and ``benchmarks/drivelog_independent_bias.py`` measure both.

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
``(F_max, K)`` and the Jacobian handed to :func:`~..estimates.result.build_result` is
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
(:func:`~.covariance.profiled_covariance`): ``A`` the observed information of the profiled cost from the
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
``bias_correction="simex"`` (:func:`~.simex._simex_correct`: refits with added speed noise, quadratic
extrapolation to none) removes it at the cost of 12 refits (see benchmarks/README.md for the
measured bias and coverage before and after). The encoder reading ``w_k``
is also in ``T_{k+1}``; this negative correlation of neighbouring scores is left out of ``B``
(conservative, see :func:`~.covariance.profiled_covariance`). For a heavy vehicle on firm sand (``K / l``
about 0.4 %) GNSS speed noise of 0.05 m/s leaves K poorly determined; the result says so.

Effects and the hull channel. ``effects=[...]`` (docs/physics.md, "Unmodelled effects") fits the effects'
parameters jointly with the thrust limit and K, and adds the hull force balance
``m dv/dt = F(i) - R(v, i)`` as a third residual channel (IMU column, else speed differences):
:mod:`.joint` states the problem, :mod:`.joint_fit` solves it. Without effects
the fit is the two-channel one above (unchanged); ``hull_channel=True`` adds the hull channel to a
nominal fit. Measured over the same 20 noise seeds (light vehicle, dry sand, effect-free logs,
``python benchmarks/drivelog_coverage.py --seeds 20 [--hull]``): F_max spread 1.24 % -> 0.60 %,
K spread 12.8 % -> 7.6 %, K bias -6.2 % +- 2.9 -> -0.6 % +- 1.7, 95 % intervals F 19/20 and K
17/20 -> 19/20 and 19/20, at about 4x the fit time. It is not the default: an effect in the hull
balance that the nominal model lacks (a grade) then biases F_max (measured +1.2 to +1.8
standard errors on 3 deg), while the two-channel fit does not see it; held-out residuals
(:func:`.residuals.drive_log_residuals`, ``FitResult.residuals_on``) show it in the
``hull_N`` channel either way.

Modules: :mod:`.noise` (noise levels from the log), :mod:`.prepare` (checks,
thrust, sample selection), :mod:`.nlp` (the NLPs and their solves),
:mod:`.covariance` (sandwich), :mod:`.regime` (gentle/hard),
:mod:`.simex` (opt-in bias correction), :mod:`.joint` /
:mod:`.joint_fit` (effects, hull channel), :mod:`.residuals` (held-out
residuals), :mod:`.sensitivity` (per-sample residuals and sensitivities for score tests);
this module is the entry, :func:`fit_drive_log`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Callable

import numpy as np

from ...soilmodel.data import DriveLog
from ...soilmodel.errors import DataError
from ...soilmodel.soil import PRACTICAL_BOUNDS, SoilBounds
from ...soilmodel.traction import check_model
from ...soilmodel.units import format_force
from ...soilmodel.vehicle import Vehicle
from . import covariance as _covariance
from .noise import estimate_noise, estimate_noise_profile
from .nlp import eval_pointwise, fmax_bounds, padded_size, ridge_point, solve_equation_error, solve_output_error
from .profiled import solve_output_error_profiled
from .profile_check import profile_flatness
from .prepare import MIN_USABLE_SAMPLES, SLIP_BOUNDS, PreparedLog, prepare_drive_log
from .relaxation import DISCRETISATIONS
from .joint_fit import fit_joint
from .regime import classify_regime
from .residuals import DriveLogResiduals, drive_log_residuals
from .sensitivity import DriveLogSensitivities, drive_log_sensitivities
from .simex import BIAS_CORRECTIONS, SIMEX_LAMBDAS, simex_fit
from ..sweep.problem import FitFailed
from ..estimates.result import FitResult, build_result

__all__ = [
    "fit_drive_log",
    "FORMULATIONS",
    "DriveLogFitError",
    "estimate_noise",
    "estimate_noise_profile",
    "prepare_drive_log",
    "PreparedLog",
    "padded_size",
    "MIN_USABLE_SAMPLES",
    "SLIP_BOUNDS",
    "BIAS_CORRECTIONS",
    "SIMEX_LAMBDAS",
    "drive_log_residuals",
    "DriveLogResiduals",
    "drive_log_sensitivities",
    "DriveLogSensitivities",
]

#: Formulations of :func:`fit_drive_log`.
FORMULATIONS = ("output-error", "equation-error")

_OPTION_NAMES = (
    "sigma_torque",
    "sigma_sprocket_speed",
    "sigma_vehicle_speed",
    "torque_hold",
    "min_speed",
    "sprocket_equation",
    "max_iter",
    "tol",
    "print_level",
    "multistart",
    "profiled_start",
    "hull_channel",
    "sigma_accel",
    "discretisation",
    "discretisation_check",
    "latent_slips",
)
#: How the output-error fit treats the latent slips: ``"ipopt"`` (one IPOPT variable each), ``"profiled"``
#: (eliminated per sample, :mod:`.profiled`), ``"auto"`` (profiled above :data:`PROFILED_ABOVE` used samples).
LATENT_SLIPS = ("auto", "ipopt", "profiled")
#: Used samples above which ``latent_slips="auto"`` profiles the slips out (the IPOPT problem's memory grows
#: by about 73 kB per sample: 0.9 GB here; :mod:`.budget`).
PROFILED_ABOVE = 10_000
#: |shift| of F_max or K, in the end-point fit's standard errors, beyond which the discretisation check
#: (the default of every drive-log fit without ``discretisation``) reports the relaxation fit instead, with a
#: warning. On ordinary logs the two rules differ by noise (measured on default profiles, light and heavy
#: vehicle, 36 logs: at most 1.9 standard errors, 5 of 36 beyond 1); on 8 deg hard pulls at 50 Hz by about
#: 3; on the independent simulator's hard pulls (benchmarks/drivelog_independent.py) K by 4-7, where the
#: end-point rule puts K 5.5 % low (0 of 8 intervals hold it) and the relaxation rule holds it.
DISCRETISATION_SHIFT_SE = 2.0


class DriveLogFitError(FitFailed):
    """Raised by :func:`fit_drive_log` with ``strict=True`` when no trustworthy estimate exists.

    A :class:`~soiltrack.identify.sweep.problem.FitFailed`; ``.result`` holds the failed result.
    """


def fit_drive_log(
    log: DriveLog,
    vehicle: Vehicle,
    model: str = "full",
    bounds: SoilBounds = PRACTICAL_BOUNDS,
    x0=None,
    strict: bool = False,
    *,
    method: str = "ipopt",
    formulation: str = "output-error",
    bias_correction: str | None = None,
    effects: Any = None,
    fixed: Any = None,
    **options: Any,
) -> FitResult:
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
        ends on a bound, also start from a second point (K on the other side of the range);
        ``profiled_start`` (True): a few profiled Levenberg-Marquardt steps before IPOPT (False:
        IPOPT from the start as given, the latent slips by Newton steps: a warm start from a
        nearby answer); ``hull_channel`` (default: on exactly when effects are fitted): use the hull force
        balance as a third residual channel (``True`` also for a nominal fit, e.g. to compare a
        nominal and an effect fit on equal terms; ``False`` with effects: fit them from the speed
        and thrust channels only); ``sigma_accel`` (m/s^2): constant noise of the IMU
        acceleration column (default: estimated from the log); ``discretisation``:
        ``"end-point"`` or ``"relaxation"``, the held-torque sprocket equation (default: both
        fitted, the one the discretisation check picks reported; see the module notes;
        ``extra["discretisation"]`` says which one the fit used and ``extra["discretisation_check"]``
        why); ``discretisation_check=False``: the end-point rule without the check.

    effects
        Unmodelled effects (docs/physics.md, "Unmodelled effects") whose parameters are fitted jointly with F_max and
        K: a list of names (``["grade", "mass_error"]``) or anything
        :func:`~soiltrack.soilmodel.effects.parse_effects` takes (given values are start values).
        Adds the hull force balance as a third residual channel (see
        :mod:`.joint`). ``None`` (default): the nominal fit.
    fixed
        Effect parameters held at given values, e.g. ``{"grade": 0.05}`` or
        ``{"drivetrain_friction.tau_v": 0.0}`` (the effect is switched on).
    bias_correction
        ``None`` (default: no correction) or ``"simex"``: opt-in simulation-extrapolation
        correction of the error-in-variables bias of F_max and K caused by the vehicle-speed
        noise (output-error only; see :func:`~.simex._simex_correct`). Options ``simex_replicates``
        (even, default 4: antithetic pairs per noise level) and ``simex_seed`` (default 0).
        Costs ``3 x simex_replicates`` extra fits.

    Returns
    -------
    FitResult
        Built by :func:`soiltrack.identify.estimates.result.build_result` with ``data_kind="drive"``.
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
    joint = bool(effects) or bool(fixed) or options.get("hull_channel", False) is True
    rule = _discretisation_rule(options, joint, formulation)
    kw: dict[str, Any] = dict(
        method=method, formulation=formulation, bias_correction=bias_correction, effects=effects, fixed=fixed
    )
    if rule == "check":  # no rule given: both, the one the check picks reported (module notes)
        return _fit_checking_discretisation(log, vehicle, model, bounds, x0, strict, {**kw, **options})
    if rule is None:
        why = f"discretisation={options['discretisation']!r} given: that rule, not compared"
    else:
        why, options = rule, {**options, "discretisation": "end-point"}
    res = _fit_one_rule(log, vehicle, model, bounds, x0, strict, **kw, **options)
    chk = {"compared": False, "reported": res.extra.get("discretisation", "end-point"), "reason": why}
    return replace(res, extra={**res.extra, "discretisation_check": chk})


def _fit_one_rule(
    log: DriveLog,
    vehicle: Vehicle,
    model: str,
    bounds: SoilBounds,
    x0,
    strict: bool,
    *,
    method: str = "ipopt",
    formulation: str = "output-error",
    bias_correction: str | None = None,
    effects: Any = None,
    fixed: Any = None,
    **options: Any,
) -> FitResult:
    """:func:`fit_drive_log` under the discretisation in ``options`` (no check)."""
    joint = bool(effects) or bool(fixed) or options.get("hull_channel", False) is True
    if bias_correction is not None:
        if joint:
            raise DataError("bias_correction is not available with effects or the hull channel")
        return simex_fit(
            _fit_one_rule, log, vehicle, model, bounds, x0, strict, method, formulation, bias_correction, options
        )
    _check_arguments(model, method, formulation, options)
    if joint and formulation != "output-error":
        raise DataError("effects and the hull channel need the output-error formulation")
    bounds = PRACTICAL_BOUNDS if bounds is None else bounds
    s = _set_up(log, vehicle, model, bounds, x0, formulation, options)
    if joint:
        extra, warnings = _base_extra(log, s.prep, formulation, options, "sandwich")
        res, ok = fit_joint(
            log, vehicle, s.prep, model, bounds, effects, fixed, s.starts, s.c_hint, method, options, extra, warnings
        )
        if strict and not ok:
            raise DriveLogFitError(res)
        return res
    return _nominal_fit(log, vehicle, s, _Call(model, bounds, method, formulation, strict, options))


@dataclass(frozen=True)
class _Setup:
    """The prepared log and the solver's settings of one drive-log fit (between :func:`_set_up` and the solve)."""

    prep: PreparedLog  #: the checked samples, thrust and noise levels
    Fb: tuple  #: bounds of the thrust limit F_max (N), from the soil bounds
    Kb: tuple  #: bounds of K (m)
    F_ref: float  #: scale of F_max (mid-range)
    K_ref: float  #: scale of K (geometric mid-range)
    starts: list[tuple[float, float]]  #: start points (F_max, K)
    c_hint: float | None  #: cohesion of the start, to pick the point on the c-phi ridge
    solve: Callable[..., Any]  #: the NLP solve of the formulation
    max_iter: int  #: IPOPT iterations
    tol: float  #: IPOPT tolerance
    print_level: int  #: IPOPT print level


@dataclass(frozen=True)
class _Call:
    """The caller's choices that the result needs (model, bounds, formulation, options)."""

    model: str  #: "full" or "cohesion-free"
    bounds: SoilBounds  #: the soil's box bounds
    method: str  #: "ipopt"
    formulation: str  #: "output-error" or "equation-error"
    strict: bool  #: raise on a failed fit
    options: dict  #: the remaining options


def _discretisation_rule(options: dict, joint: bool, formulation: str) -> str | None:
    """How the held-torque discretisation of this fit is chosen; pops ``discretisation_check``.

    None: the caller gave ``discretisation`` (that rule, no check). ``"check"``: both rules, the one
    :func:`_discretisation_check` picks reported (the default). Otherwise the reason the check does not
    apply (the end-point rule is fitted): ``discretisation_check=False``, a sampled torque, effects or the
    hull channel, the equation-error formulation.
    """
    asked = options.pop("discretisation_check", None)
    if options.get("discretisation") is not None:
        return None
    options.pop("discretisation", None)
    if asked is False:
        return "discretisation_check=False: the end-point rule, not compared"
    if options.get("torque_hold", "zoh") != "zoh":
        return "torque sampled (torque_hold='sample'): its central difference, no held-torque discretisation"
    if joint:
        return "effects or the hull channel fitted: the end-point rule (the check compares nominal fits)"
    if formulation != "output-error":
        return "equation-error formulation: the end-point rule (the check compares output-error fits)"
    return "check"


def _fit_checking_discretisation(log, vehicle, model, bounds, x0, strict, kw: dict) -> FitResult:
    """The end-point fit and, to compare, the relaxation fit (:func:`_discretisation_check`)."""
    res = _fit_one_rule(log, vehicle, model, bounds, x0, strict, **{**kw, "discretisation": "end-point"})
    # the default fit is the relaxation fit's pilot: its soil is handed over, not fitted again
    return _discretisation_check(
        res,
        lambda: _fit_one_rule(
            log,
            vehicle,
            model,
            bounds,
            x0,
            False,
            **{**kw, "discretisation": "relaxation", "_pilot": _soil_of(res)},
        ),
    )


def _set_up(log: DriveLog, vehicle: Vehicle, model: str, bounds: SoilBounds, x0, formulation: str, options: dict):
    """Prepare the log, the bounds and start points of (F_max, K), the solve; the relaxation pilot if asked."""
    prep = prepare_drive_log(log, vehicle, **_prepare_options(options), fixed_keep=options.get("_fixed_keep"))
    max_iter = int(options.get("max_iter", 500))
    tol = float(options.get("tol", 1e-9))
    print_level = int(options.get("print_level", 0))
    Fb = fmax_bounds(bounds, vehicle, model)
    Kb = tuple(bounds.shear_modulus)
    F_ref = 0.5 * (Fb[0] + Fb[1])
    K_ref = math.sqrt(Kb[0] * Kb[1])
    starts, c_hint = _start_points(prep, vehicle, model, x0, Fb, Kb, K_ref, bool(options.get("multistart", True)))
    solve = solve_output_error if formulation == "output-error" else solve_equation_error
    if formulation == "output-error" and _profiled(options, prep.n_used):
        solve = solve_output_error_profiled
    pilot: tuple[float, float] | None = options.get("_pilot") or _relaxation_pilot(
        prep, vehicle, options, solve, (F_ref, K_ref, Fb, Kb, starts, max_iter, tol, print_level)
    )
    if pilot is not None:  # the held-torque discretisation at the pilot's soil; the pilot starts the fit
        prep = prepare_drive_log(
            log, vehicle, **_prepare_options(options), fixed_keep=options.get("_fixed_keep"), relaxation_at=pilot
        )
        starts = [pilot] + [s for s in starts if s != pilot]
    return _Setup(prep, Fb, Kb, F_ref, K_ref, starts, c_hint, solve, max_iter, tol, print_level)


def _nominal_fit(log: DriveLog, vehicle: Vehicle, s: _Setup, call: _Call) -> FitResult:
    """Solve the two-channel fit in (F_max, K) and build its result (failed or converged)."""
    prep, formulation = s.prep, call.formulation
    best, Fmax, K, slip = s.solve(
        prep, vehicle, s.F_ref, s.K_ref, s.Fb, s.Kb, s.starts, s.max_iter, s.tol, s.print_level
    )
    pr = _profiled_residuals(prep, vehicle, formulation, best["ok"], slip, Fmax, K)

    finite = (
        all(math.isfinite(z) for z in (Fmax, K)) and np.all(np.isfinite(pr["wres"])) and np.all(np.isfinite(pr["J2"]))
    )
    success = bool(best["ok"] and finite)
    extra, warnings = _base_extra(log, prep, formulation, call.options, pr["covariance"])
    n = prep.n_used
    common = dict(
        data_kind="drive",
        model=call.model,
        method=call.method,
        residual_unit=pr["unit"],
        n_samples=n,
        normal_loads=np.full(n, vehicle.weight),
        vehicle=vehicle,
        bounds=call.bounds,
        status=best["status"],
        iterations=best["iterations"],
        solve_time=best["time"],
        sigma_known=prep.sigma_known,
        residual_model=DriveLogResiduals(hull_in_fit=False),
    )
    if not success:
        msg = f"drive-log fit failed: IPOPT returned {best['status']}" + ("" if finite else " with non-finite values")
        wres, res = pr["wres"], pr["res"]
        failed = build_result(
            theta=np.full(3, np.nan),
            jacobian=np.zeros((n, 3)),
            weighted_residuals=np.where(np.isfinite(wres), wres, 0.0),
            residuals=np.where(np.isfinite(res), res, 0.0),
            success=False,
            message=msg,
            warnings=tuple(warnings),
            extra=extra,
            **common,
        )
        if call.strict:
            raise DriveLogFitError(failed)
        return failed
    return _converged_result(vehicle, s, call, pr, (Fmax, K, slip), extra, warnings, common)


def _converged_result(
    vehicle: Vehicle, s: _Setup, call: _Call, pr: dict, solved: tuple, extra: dict, warnings: list, common: dict
) -> FitResult:
    """The converged fit: (c, phi) on the ridge, the identifiable combinations, the driving regime."""
    Fmax, K, slip = solved
    prep, model, W, n = s.prep, call.model, vehicle.weight, s.prep.n_used
    # (c, phi) on the ridge, and the Jacobian in [c, phi, K] by the chain rule
    c, phi = ridge_point(Fmax, vehicle, call.bounds, model, s.c_hint)
    J2 = pr["J2"]
    dFm_dc = vehicle.contact_area if model == "full" else 0.0
    jac = np.column_stack([J2[:, 0] * dFm_dc, J2[:, 0] * (W / math.cos(phi) ** 2), J2[:, 1]])

    # identifiable combinations and the driving regime
    wres = pr["wres"]
    dof = max(n - 2, 1)
    s2 = 1.0 if prep.sigma_known else float(np.sum(wres**2)) / dof
    cov2: np.ndarray | None
    try:
        cov2 = s2 * np.linalg.inv(J2.T @ J2)
        if not (np.all(np.isfinite(cov2)) and cov2[0, 0] > 0 and cov2[1, 1] > 0):
            cov2 = None
    except np.linalg.LinAlgError:
        cov2 = None
    l = vehicle.track_length
    sT = prep.sigma_thrust
    # the largest thrust the log certainly reached (2 standard deviations below the estimate)
    thrust_peak = float(max(np.max(prep.thrust - 2.0 * sT), 0.0))
    utilisation = thrust_peak / Fmax
    n_high = int(np.count_nonzero(prep.thrust - 2.0 * sT > 0.7 * Fmax))
    extra.update(
        {
            "max_thrust_N": Fmax,
            "shear_modulus_m": K,
            "initial_slope_N": Fmax * l / (2 * K),
            "thrust_peak_N": thrust_peak,
            "thrust_utilisation": utilisation,
            "samples_above_70pct": n_high,
            "slip_max": float(np.max(slip)),
            "thrust_residual_rms_N": float(np.sqrt(np.mean((wres * pr["s_eff"]) ** 2))),
            "reduced_chi2": float(np.sum(wres**2)) / dof,
        }
    )
    at_bound = [
        name
        for name, val, (lo, hi) in (("F_max", Fmax, s.Fb), ("K", K, s.Kb))
        if val <= lo + 1e-6 * (hi - lo) or val >= hi - 1e-6 * (hi - lo)
    ]
    rise = None  # does F_max's likelihood match its standard error (a start from rest: far wider)?
    if call.formulation == "output-error" and cov2 is not None and not at_bound and cov2[0, 0] < (0.25 * Fmax) ** 2:
        rise = profile_flatness(prep, vehicle, Fmax, K, math.sqrt(cov2[0, 0]), s2, s.Kb)
    regime, regime_extra, regime_warnings = classify_regime(
        Fmax, K, l, cov2, at_bound, thrust_peak, utilisation, n_high, profile_rise=rise
    )
    extra.update(regime_extra)
    warnings.extend(regime_warnings)
    msg = (
        f"drive-log fit ({call.formulation}) converged: F_max = {Fmax:.5g} N, K = {1000 * K:.4g} mm, "
        f"{regime} log, {n} samples used"
    )
    return build_result(
        theta=np.array([c, phi, K]),
        jacobian=jac,
        weighted_residuals=wres,
        residuals=pr["res"],
        success=True,
        message=msg,
        warnings=tuple(warnings),
        extra=extra,
        **common,
    )


def _profiled(options: dict, n_used: int) -> bool:
    """Whether the nominal output-error fit profiles the latent slips out (:mod:`.profiled`)."""
    how = options.get("latent_slips", "auto")
    return how == "profiled" or (how == "auto" and n_used > PROFILED_ABOVE)


def _check_arguments(model: str, method: str, formulation: str, options: dict) -> None:
    check_model(model)
    if method != "ipopt":
        raise DataError(f"unknown method {method!r} for a drive log; expected 'ipopt'")
    if formulation not in FORMULATIONS:
        raise DataError(f"unknown formulation {formulation!r}; expected one of {FORMULATIONS}")
    disc = options.get("discretisation", DISCRETISATIONS[0])
    if disc not in DISCRETISATIONS:
        raise DataError(f"unknown discretisation {disc!r}; expected one of {DISCRETISATIONS}")
    if disc == "relaxation" and options.get("torque_hold", "zoh") != "zoh":
        raise DataError(
            "discretisation='relaxation' is for a torque held between samples (torque_hold='zoh'); "
            "a sampled torque (torque_hold='sample') has its own central difference"
        )
    if options.get("latent_slips", "auto") not in LATENT_SLIPS:
        raise DataError(f"unknown latent_slips {options['latent_slips']!r}; expected one of {LATENT_SLIPS}")
    unknown = sorted(set(options) - set(_OPTION_NAMES) - {"_fixed_keep", "_plain_start", "_pilot"})
    if unknown:
        raise DataError(f"unknown option(s) {unknown} for a drive-log fit; expected some of {list(_OPTION_NAMES)}")


def _discretisation_check(res: FitResult, refit) -> FitResult:
    """The fit of a held-torque log under the discretisation that suits it, with the other rule's fit beside it.

    ``res`` is the end-point fit; ``refit()`` gives the same fit under the slip-relaxation weights.
    ``extra["discretisation_check"]`` holds both fits' F_max and K and the shifts in ``res``'s standard
    errors. Within :data:`DISCRETISATION_SHIFT_SE` the end-point fit is returned; beyond it (the slip does
    not settle within a sample after the torque steps: hard pulls) the relaxation fit is returned, with a
    warning, because there the end-point rule is the biased one (``"reported"`` says which; see the
    module notes and :data:`DISCRETISATION_SHIFT_SE`); ``"reason"`` says why. A failed end-point fit is
    not compared.
    """
    ex = res.extra
    if not res.success:
        chk0 = {"compared": False, "reported": "end-point", "reason": "the end-point fit failed: not compared"}
        return replace(res, extra={**ex, "discretisation_check": chk0})
    alt = refit()
    chk: dict[str, Any] = {"compared": bool(alt.success and alt.extra.get("discretisation") == "relaxation")}
    if not chk["compared"]:
        chk["reason"] = "the fit with the relaxation weights did not converge (or used none): the end-point fit"
        chk["reported"] = "end-point"
        return replace(res, extra={**ex, "discretisation_check": chk})
    a = alt.extra
    shift = {
        key: float((a[key] - ex[key]) / ex[se]) if ex.get(se) and math.isfinite(ex[se]) and ex[se] > 0 else None
        for key, se in (("max_thrust_N", "max_thrust_stderr_N"), ("shear_modulus_m", "shear_modulus_stderr_m"))
    }
    big = [k for k, v in shift.items() if v is not None and abs(v) > DISCRETISATION_SHIFT_SE]
    chk.update(
        relaxation_max_thrust_N=float(a["max_thrust_N"]),
        relaxation_max_thrust_stderr_N=a["max_thrust_stderr_N"],
        relaxation_shear_modulus_m=float(a["shear_modulus_m"]),
        end_point_max_thrust_N=float(ex["max_thrust_N"]),
        end_point_max_thrust_stderr_N=ex["max_thrust_stderr_N"],
        end_point_shear_modulus_m=float(ex["shear_modulus_m"]),
        max_thrust_shift_se=shift["max_thrust_N"],
        shear_modulus_shift_se=shift["shear_modulus_m"],
        reported="relaxation" if big else "end-point",
        reason=(
            f"the two rules disagree beyond {DISCRETISATION_SHIFT_SE:g} standard errors ({', '.join(big)}): "
            "the relaxation fit"
            if big
            else f"the two rules agree within {DISCRETISATION_SHIFT_SE:g} standard errors: the end-point fit"
        ),
    )
    if not big:
        return replace(res, extra={**ex, "discretisation_check": chk})
    warn = (
        f"the two discretisations of the held-torque sprocket equation disagree here (after torque steps the "
        f"slip does not settle within a sample): with the slip's relaxation F_max = "
        f"{format_force(a['max_thrust_N'])} and K = {1e3 * a['shear_modulus_m']:.3g} mm, with the end-point rule "
        f"F_max = {format_force(ex['max_thrust_N'])} ({_se_words(shift['max_thrust_N'])} away) and K = "
        f"{1e3 * ex['shear_modulus_m']:.3g} mm ({_se_words(shift['shear_modulus_m'])}); reported: the relaxation "
        "fit, the one that holds the truth on such logs (the end-point rule is biased there; docs/drivelogs.md). "
        "--discretisation end-point (Python: discretisation='end-point') gives the other",
    )
    return replace(alt, extra={**a, "discretisation_check": chk}, input_warnings=tuple(alt.input_warnings) + warn)


def _soil_of(res: FitResult) -> tuple[float, float]:
    """``(F_lim, K)`` of a converged drive-log fit (the pilot of its relaxation refit)."""
    return float(res.extra["max_thrust_N"]), float(res.extra["shear_modulus_m"])


def _se_words(shift: float | None) -> str:
    return "standard error unknown" if shift is None else f"{shift:+.1f} standard errors"


def _relaxation_pilot(
    prep: PreparedLog, vehicle: Vehicle, options: dict, solve, args: tuple
) -> tuple[float, float] | None:
    """``(F_lim, K)`` of a fit with the end-point rule, where the held-torque relaxation applies; else None.

    The slip-relaxation weights of the discretisation (:mod:`.relaxation`) depend on the slope of the
    thrust-slip curve, so on the soil; this pilot fit gives it. None with ``torque_hold="sample"``,
    ``discretisation="end-point"``, or a pilot that did not converge to a finite point (the fit then
    keeps the end-point rule, and says so in ``extra["discretisation"]``).
    """
    if options.get("discretisation", DISCRETISATIONS[0]) != "relaxation" or options.get("torque_hold", "zoh") != "zoh":
        return None
    F_ref, K_ref, Fb, Kb, starts, max_iter, tol, print_level = args
    best, Fmax, K, _slip = solve(prep, vehicle, F_ref, K_ref, Fb, Kb, starts, max_iter, tol, print_level)
    if not (best["ok"] and math.isfinite(Fmax) and math.isfinite(K) and Fmax > 0 and K > 0):
        return None
    return float(Fmax), float(K)


def _prepare_options(options: dict) -> dict:
    """The keyword arguments of :func:`prepare_drive_log` taken from the fit's options."""
    return {
        "sigma_torque": options.get("sigma_torque"),
        "sigma_sprocket_speed": options.get("sigma_sprocket_speed"),
        "sigma_vehicle_speed": options.get("sigma_vehicle_speed"),
        "torque_hold": str(options.get("torque_hold", "zoh")),
        "min_speed": options.get("min_speed", 0.0),
        "sprocket_equation": str(options.get("sprocket_equation", "thrust")),
    }


def _start_points(
    prep: PreparedLog, vehicle: Vehicle, model: str, x0, Fb, Kb, K_ref: float, multistart: bool
) -> tuple[list[tuple[float, float]], float | None]:
    """Start values ``[(F_max, K), ...]`` and the cohesion hint for the ridge point.

    ``x0`` if given, else 1.2 times the 99th percentile of the thrust and K in the middle of its
    range (log scale); with ``multistart`` a second start with K on the other side of the range.
    """
    W, A = vehicle.weight, vehicle.contact_area
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
    if multistart:
        K_alt = min(max(K0 * (3.0 if K0 < K_ref else 1.0 / 3.0), Kb[0] * 1.001), Kb[1] * 0.999)
        starts.append((min(max(1.5 * F0, Fb[0]), Fb[1] * 0.999), K_alt))
    return starts, c_hint


def _profiled_residuals(
    prep: PreparedLog, vehicle: Vehicle, formulation: str, ok: bool, slip: np.ndarray, Fmax: float, K: float
) -> dict[str, Any]:
    """Residuals at the solution and the profiled Jacobian ``d wres / d(F_max, K)``.

    Output-error: one reduced residual per sample (the latent slip profiled out), and the
    Jacobian rescaled so that the result's ``s^2 (J^T J)^-1`` is the sandwich covariance
    (:func:`~.covariance.profiled_covariance`). Returns a dict with ``wres``, ``res``
    (raw, in ``unit``), ``unit``, ``J2``, ``s_eff`` (effective thrust-residual sigma, N) and
    ``covariance`` (``"sandwich"`` or ``"gauss-newton"``).
    """
    n = prep.n_used
    l, r = vehicle.track_length, vehicle.sprocket_radius
    F, dF_ds, dF_dFm, dF_dK = eval_pointwise(slip, Fmax, K, l)
    if formulation == "output-error":
        rw_k = r * prep.sprocket_speed
        sc = prep.sigma_thrust_cond
        # effective variance of the thrust residual after profiling out the latent slip
        s_eff = np.sqrt(sc**2 + ((dF_ds + prep.coupling * rw_k) * prep.sigma_speed / rw_k) ** 2)
        d_s = prep.vehicle_speed - rw_k * (1 - slip)
        e_T = (prep.thrust - F - prep.coupling * d_s) / sc
        e_w = d_s / prep.sigma_speed
        # projected (profiled) residual, model minus data: |(e_w, e_T)| at the optimum
        wres = -np.sign(e_T) * np.sqrt(e_T**2 + e_w**2)
        # raw residual: predicted minus measured sprocket speed, v_k / (r (1 - i_k)) - w_k, rad/s
        res = d_s / (r * (1 - slip))
        unit = "rad/s"
    else:
        s_eff = prep.sigma_thrust
        res = F - prep.thrust  # model minus data, N
        wres = res / s_eff
        unit = "N"
    J2 = np.column_stack([dF_dFm, dF_dK]) / s_eff[:, None]  # d wres / d(F_max, K)
    kind = "gauss-newton"
    if formulation == "output-error" and ok and np.all(np.isfinite(J2)) and np.all(np.isfinite(wres)):
        # Sandwich covariance. The shared result object computes s2 (J^T J)^-1; the Jacobian
        # handed to it is J2 R with a 2x2 R chosen so that this equals the sandwich:
        # R^T (J2^T J2) R = s2 V^-1 (a change of basis within the span of J2's columns: the rank,
        # the null space and the chain rule to (c, phi, K) are unchanged).
        sand = _covariance.profiled_covariance(prep, r, slip, Fmax, K, l, F, dF_ds, dF_dFm, dF_dK)
        if sand is not None:
            V = sand[0]
            s2_rb = 1.0 if prep.sigma_known else float(np.sum(wres**2)) / max(n - 2, 1)
            try:
                Lg = np.linalg.cholesky(J2.T @ J2)
                Lv = np.linalg.cholesky(s2_rb * np.linalg.inv(V))
                R = np.linalg.solve(Lg.T, Lv.T)
                if np.all(np.isfinite(R)):
                    J2 = J2 @ R
                    kind = "sandwich"
            except np.linalg.LinAlgError:
                pass
    return {"wres": wres, "res": res, "unit": unit, "J2": J2, "s_eff": s_eff, "covariance": kind}


def _base_extra(
    log: DriveLog, prep: PreparedLog, formulation: str, options: dict, covariance_kind: str
) -> tuple[dict[str, Any], list[str]]:
    """The sample counts, noise model and settings for ``FitResult.extra``, and the input warnings."""
    warnings: list[str] = []
    n = prep.n_used
    extra: dict[str, Any] = {
        "formulation": formulation,
        "samples_total": log.n_samples,
        "samples_used": n,
        "samples_dropped_slow": prep.dropped["slow"],
        "samples_dropped_braking": prep.dropped["braking"],
        "samples_thrust_jump_inflated": prep.dropped["thrust_jumps"],
        "samples_turning": prep.dropped["turning"],
        "speed_floor_m_s": prep.dropped["speed_floor_m_s"],
        "noise_model": {  # sigma = sqrt(abs^2 + (rel * reading)^2), given or estimated from the log
            "torque_Nm": {"abs": prep.noise["torque"][0], "rel": prep.noise["torque"][1]},
            "sprocket_speed_rad_s": {"abs": prep.noise["sprocket_speed"][0], "rel": prep.noise["sprocket_speed"][1]},
            "vehicle_speed_m_s": {"abs": prep.noise["vehicle_speed"][0], "rel": prep.noise["vehicle_speed"][1]},
            "estimated": not prep.sigma_known,
        },
        "torque_hold": str(options.get("torque_hold", "zoh")),
        "sprocket_equation": str(options.get("sprocket_equation", "thrust")),
        "covariance": covariance_kind,
        # the held-torque sprocket equation: "relaxation" (the thrust at the sample from two interval
        # means, weighted by the slip's relaxation at the pilot soil "relaxation_at": [F_lim N, K m])
        # or "end-point" (asked for, torque sampled, or no converged pilot)
        "discretisation": "relaxation" if np.any(prep.relaxation > 0) else "end-point",
        "relaxation_at": list(prep.relaxation_at) if prep.relaxation_at and np.any(prep.relaxation > 0) else None,
        "relaxation_weight_median": float(np.median(prep.relaxation)) if prep.n_used else 0.0,
    }
    dropped = prep.dropped["slow"] + prep.dropped["braking"] + prep.dropped["edge"]
    if prep.dropped["slow"] + prep.dropped["braking"]:
        warnings.append(
            f"{dropped} of {log.n_samples} samples not used: {prep.dropped['slow']} standing, reversing or "
            "with vehicle or track speed "
            f"below 3 noise levels (about {prep.dropped['speed_floor_m_s']:.3g} m/s: slip undefined or lost in the "
            f"speed noise), {prep.dropped['braking']} braking (negative thrust: the skid law F(i) = -F(|i|) is only "
            f"a first approximation), {prep.dropped['edge']} at the ends of the log (no sprocket-speed difference)"
        )
    if prep.dropped["turning"]:
        warnings.append(
            f"{prep.dropped['turning']} of {log.n_samples} samples turning (two-track log: left and right "
            f"sprocket speeds, or the yaw rate, beyond their noise): left out of the straight-line model with "
            f"the sample after each turn ({prep.dropped['turning_left_out']} samples in all)"
        )
    if formulation == "equation-error":
        warnings.append(
            "equation-error formulation: slip computed from the noisy measured speeds is used as an "
            "exact regressor, which biases F_max and K (error-in-variables); use the default "
            "output-error formulation for estimates"
        )
    return extra, warnings
