"""A tractive force-slip identification problem: validated arrays, weights, scaling, result.

Shared by every slip-data method (IPOPT, Newton-Raphson, least squares, the batch engine,
profiles), so that they all solve the same weighted least-squares problem

    minimise  0.5 * sum_k ((F(i_k; c, phi, K, W_k) - F_k) / sigma_k)^2

and report through the same :func:`~soiltrack.identify.estimates.result.build_result`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from ...soilmodel.data import SlipData
from ...soilmodel.effects import (
    DEFAULT_RIG_SPEED,
    EFFECTS,
    EffectSet,
    effect_structure,
    effect_symbols,
    parameter_bounds,
    parse_effects,
)
from ...soilmodel.errors import DataError
from ...soilmodel.ridge import ridge_centre  # noqa: F401 - re-exported: the one ridge marker
from ...soilmodel.soil import SoilBounds
from ...soilmodel.traction import MODELS
from ...soilmodel.vehicle import Vehicle
from ..estimates.result import FitResult, build_result
from .model import SweepResiduals, nominal_offset, predict
from .plausibility import slip_checks

__all__ = [
    "SlipProblem",
    "make_problem",
    "checked_problems",
    "FitFailed",
    "SCALE",
    "METHODS",
    "n_free",
    "ridge_centre",
    "weights",
]

#: Variable scaling used by the solvers: c in kPa, phi in rad, K in cm.
SCALE = np.array([1e3, 1.0, 1e-2])
METHODS = ("ipopt", "newton", "least-squares")


class FitFailed(RuntimeError):
    """Raised by ``fit(..., strict=True)`` when the fit did not succeed; ``.result`` holds it."""

    def __init__(self, result: FitResult) -> None:
        self.result = result
        super().__init__(
            f"soil identification failed ({result.model}, {result.method}): {result.status}: {result.message}"
        )


#: Breusch-Pagan statistic above which the residual spread is said to grow with the force (chi2(1), p = 0.01).
BP_CRITICAL = 6.635


def heteroscedasticity(force: np.ndarray, residuals: np.ndarray, sigma: np.ndarray) -> np.ndarray | np.float64:
    """Koenker's Breusch-Pagan statistic ``n R^2`` of the squared weighted residuals on the
    squared fitted force, per dataset (leading axes broadcast; NaN where it does not apply).

    Under constant noise it is about chi-square with 1 degree of freedom. Only computed for
    eight or more samples.
    """
    force, residuals, sigma = (np.asarray(a, dtype=float) for a in (force, residuals, sigma))
    if force.ndim == residuals.ndim == sigma.ndim == 1 and force.size == residuals.size == sigma.size:
        return _heteroscedasticity_1d(force, residuals, sigma)  # one dataset: the same numbers, fewer calls
    force, residuals, sigma = np.broadcast_arrays(force, residuals, sigma)
    n = force.shape[-1]
    if n < 8:
        return np.full(force.shape[:-1], np.nan)
    e2 = (residuals / sigma) ** 2
    x = ((force + residuals) / sigma) ** 2
    x = x - x.mean(axis=-1, keepdims=True)
    y = e2 - e2.mean(axis=-1, keepdims=True)
    with np.errstate(all="ignore"):
        r2 = (x * y).sum(-1) ** 2 / ((x * x).sum(-1) * (y * y).sum(-1))
        slope_positive = (x * y).sum(-1) > 0
    return np.where(slope_positive, n * r2, 0.0)


def _heteroscedasticity_1d(force: np.ndarray, residuals: np.ndarray, sigma: np.ndarray | None) -> np.float64:
    """:func:`heteroscedasticity` of one dataset (the same arithmetic, scalar results; ``sigma=None``:
    all ones, whose divisions change nothing)."""
    n = force.size
    if n < 8:
        return np.float64(np.nan)
    e2 = residuals / sigma if sigma is not None else residuals.copy()
    e2 *= e2
    x = force + residuals
    if sigma is not None:
        x /= sigma
    x *= x
    x -= np.add.reduce(x) / n  # x - x.mean()
    e2 -= np.add.reduce(e2) / n
    sxy = float(np.add.reduce(x * e2))
    den = float(np.add.reduce(x * x)) * float(np.add.reduce(e2 * e2))
    if not sxy > 0:
        return np.float64(0.0)
    return np.float64(n * (sxy * sxy / den if den != 0 else math.inf))


#: Relative slack of :func:`heteroscedasticity_screen_expr` against rounding.
BP_SCREEN_SLACK = 1e-6


def heteroscedasticity_screen_expr(force, residuals, real):
    """CasADi expression: 0 when :func:`heteroscedasticity` of equal weights is surely at most
    :data:`BP_CRITICAL` (no warning), else 1.

    The same two-pass centred sums as the numpy statistic, evaluated where the residuals are
    (the compiled engine's residual Function), so that a clean fit skips the numpy call; a 1
    runs it, so the warning and its number come from :func:`heteroscedasticity` alone. 0 also
    needs finite numbers and centred sums well above rounding (``sum (x - mean)^2 > 1e-6 sum
    x^2`` for both regressors), and fewer than eight rows always give 0 (no statistic).

    Parameters
    ----------
    force, residuals : casadi.MX or SX, row vectors
        Measured force and model minus data (N); equal weights (the statistic is unchanged by
        a common scale).
    real : same shape
        Positive for a data row, 0 for a padding row (ignored).
    """
    on = real > 0
    n = ca.sum2(ca.if_else(on, 1, 0))
    nn = ca.fmax(n, 1)
    x = ca.if_else(on, (force + residuals) ** 2, 0)
    y = ca.if_else(on, residuals**2, 0)
    xc = ca.if_else(on, x - ca.sum2(x) / nn, 0)
    yc = ca.if_else(on, y - ca.sum2(y) / nn, 0)
    sxy, sxx, syy = ca.sum2(xc * yc), ca.sum2(xc * xc), ca.sum2(yc * yc)
    vals = ca.vertcat(force, residuals)
    finite = ca.sum2(ca.if_else(on, 2 - ca.sum1(ca.fabs(vals) < ca.inf), 0)) == 0
    well = ca.logic_and(sxx > 1e-6 * ca.sum2(x * x), syy > 1e-6 * ca.sum2(y * y))
    stat = n * sxy * sxy / ca.if_else(well, sxx * syy, 1)
    low = ca.logic_or(sxy <= 0, stat <= BP_CRITICAL * (1 - BP_SCREEN_SLACK))
    return ca.if_else(n < 8, 0, ca.if_else(ca.logic_and(ca.logic_and(finite, well), low), 0, 1))


def heteroscedasticity_warning(stat: float) -> tuple[str, ...]:
    """Plain-words warning when the Breusch-Pagan statistic says the noise grows with the force."""
    if not np.isfinite(stat) or stat <= BP_CRITICAL:
        return ()
    return (
        f"the residual spread grows with the force (Breusch-Pagan n R^2 = {stat:.3g} > {BP_CRITICAL}, "
        "p < 0.01): with equal weights the intervals are too narrow, mostly for F_max; refit with "
        "sigma='relative' (noise proportional to the force, e.g. a load cell's % of reading) or give "
        "sigma per sample",
    )


def relative_sigma(force: np.ndarray) -> np.ndarray:
    """Weights for noise proportional to the force: ``|F_k|``, floored at 1 % of ``max |F|``."""
    a = np.abs(np.asarray(force, dtype=float))
    floor = 0.01 * np.max(a, axis=-1, keepdims=True)
    return np.maximum(a, np.where(floor > 0, floor, 1.0))


def weights(
    values: np.ndarray,
    sigma=None,
    sigma_known: bool | None = None,
    *,
    source: str | None = None,
    column: str | None = None,
) -> tuple[np.ndarray, bool]:
    """The one weighting rule of slip fits: per-sample ``sigma`` (N) and whether it is the true noise level.

    ``sigma=None``: equal weights, level estimated (``sigma_known`` default False).
    ``"relative"``: :func:`relative_sigma` of the measured values, level estimated; refused with
    ``sigma_known=True`` (relative weights carry no level). A number or array: that noise
    level (``sigma_known`` default True).

    Raises
    ------
    DataError
        Unknown string, non-finite or non-positive sigma, or ``"relative"`` with ``sigma_known=True``.
    """
    values = np.asarray(values, dtype=float)
    if sigma is None:
        ones = np.empty(values.shape)
        ones.fill(1.0)
        return ones, (False if sigma_known is None else bool(sigma_known))
    if isinstance(sigma, str):
        if sigma != "relative":
            raise DataError(f"sigma must be a number, an array or 'relative', got {sigma!r}")
        if sigma_known:
            raise DataError(
                "sigma='relative' gives relative weights only: the noise level is estimated (sigma_known must be False)"
            )
        return relative_sigma(values), False
    sig = np.broadcast_to(np.asarray(sigma, dtype=float), values.shape).astype(float)
    if not np.all(np.isfinite(sig)) or np.any(sig <= 0):
        raise DataError("sigma must be finite and > 0 N", file=source, column=column)
    return sig, (True if sigma_known is None else bool(sigma_known))


def n_free(model: str) -> int:
    """Number of free parameters: 3 (full) or 2 (cohesion-free)."""
    return 3 if model == "full" else 2


@dataclass(frozen=True, eq=False)
class SlipProblem:
    """Validated slip data with weights, ready for any solver (SI).

    ``force`` is the tractive force, or for drawbar-pull data the equivalent tractive force
    ``drawbar pull + offset`` (``offset``: the nominal resistance, see
    :func:`~soiltrack.identify.sweep.model.nominal_offset`); the residuals are the same.
    ``effects`` (the structure: which effects are on) and ``fixed`` (``((label, value), ...)``)
    are set for joint soil-and-effect fits; ``rig_speed`` is the rig's track speed (m/s).
    """

    slip: np.ndarray
    force: np.ndarray
    load: np.ndarray
    sigma: np.ndarray
    sigma_known: bool
    vehicle: Vehicle
    bounds: SoilBounds
    model: str
    source: str
    measured: str = "tractive_force"
    offset: np.ndarray | None = None
    effects: EffectSet | None = None
    fixed: tuple = ()
    rig_speed: float = DEFAULT_RIG_SPEED
    effect_start: tuple = ()
    noise_model: str = "equal"  # "equal" weights, "relative" (proportional to the force) or "given" sigma

    @property
    def measured_values(self) -> np.ndarray:
        """The data as measured (tractive force or drawbar pull), N."""
        return self.force if self.offset is None else self.force - self.offset

    @property
    def has_effects(self) -> bool:
        """Whether effect parameters are fitted (or held) with the soil."""
        return bool(self.effects)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.slip.size)

    @property
    def free(self) -> list[int]:
        """Indices of the free parameters in ``[c, phi, K]``."""
        return [0, 1, 2] if self.model == "full" else [1, 2]

    def residuals(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Raw residuals (N), weighted residuals and their Jacobian (n, 3) at ``theta``."""
        F, J = predict(np.asarray(theta, float), self.slip, self.load, self.vehicle, None, self.model)
        r = F - self.force
        return r, r / self.sigma, J / self.sigma[:, None]

    def noise_warning(self, r: np.ndarray, screen: float | None = None) -> tuple[str, ...]:
        """A warning when equal weights meet noise that grows with the force (see :func:`heteroscedasticity`).

        ``screen``: :func:`heteroscedasticity_screen_expr` of these residuals, if the solver has
        it; 0 means no warning without computing the statistic.
        """
        sig = self.sigma
        if self.sigma_known or sig.size < 8 or screen == 0.0:
            return ()  # (fewer than 8 samples: the statistic is not computed)
        lo = np.minimum.reduce(sig)
        if lo != np.maximum.reduce(sig):
            return ()
        r = np.asarray(r, dtype=float)
        stat: np.ndarray | np.float64
        if r.shape == sig.shape:  # one dataset (equal weights of 1: nothing to divide by)
            stat = _heteroscedasticity_1d(self.force, r, None if lo == 1.0 else sig)
        else:
            stat = heteroscedasticity(self.force, r, sig)
        return heteroscedasticity_warning(float(stat))

    def result(
        self,
        theta: np.ndarray,
        *,
        method: str,
        status: str,
        success: bool,
        message: str,
        iterations: int,
        solve_time: float,
        warnings=(),
        extra: dict | None = None,
    ) -> FitResult:
        """Evaluate residuals at ``theta`` and build the :class:`FitResult`."""
        theta = np.asarray(theta, dtype=float).copy()
        if self.model == "cohesion-free":
            theta[0] = 0.0
        with np.errstate(all="ignore"):
            r, rw, J = self.residuals(theta)
        warnings = tuple(warnings) + self.noise_warning(r)
        return build_result(
            data_kind="slip",
            model=self.model,
            method=method,
            theta=theta,
            jacobian=J,
            weighted_residuals=rw,
            residuals=r,
            residual_unit="N",
            n_samples=self.n,
            normal_loads=self.load,
            vehicle=self.vehicle,
            bounds=self.bounds,
            status=status,
            success=success,
            message=message,
            iterations=iterations,
            solve_time=solve_time,
            sigma_known=self.sigma_known,
            warnings=warnings,
            extra={"sigma_model": self.noise_model, **(extra or {})},
            **self.checked_kwargs(r, theta),
        )

    def checked_kwargs(self, residuals, theta, samples: tuple | None = None) -> dict:
        """:meth:`result_kwargs` with the plausibility checks run on ``samples`` (default: these data's rows)."""
        kw = self.result_kwargs()
        found = samples if samples is not None else kw.pop("samples")
        kw.pop("samples", None)
        plausibility = slip_checks(found, residuals, theta, self.load, self.vehicle, self.model, self.bounds)
        return {**kw, "plausibility": plausibility}

    def result_kwargs(self, curves: tuple | None = None, screen: float | None = None) -> dict:
        """What every slip result records about these data: pass to ``build_result(..., **pb.result_kwargs())``.

        ``curves``: the weakest and strongest soil's thrust at every sample, when the solver
        computed them (:func:`~soiltrack.identify.sweep.plausibility.corner_curves`); ``screen``: the
        solver's :func:`~soiltrack.identify.sweep.plausibility.screen_expr` with them.
        """
        samples = (
            (self.slip, self.force, self.load)
            if curves is None
            else (self.slip, self.force, self.load, curves)
            if screen is None
            else (self.slip, self.force, self.load, curves, screen)
        )
        return {"measured": self.measured, "residual_model": _sweep_residuals(self.rig_speed), "samples": samples}


@lru_cache(maxsize=64)
def _sweep_residuals(rig_speed: float) -> SweepResiduals:
    return SweepResiduals(rig_speed)  # immutable: one per rig speed


def check_common(vehicle, model: str, method: str, bounds) -> None:
    """Type checks shared by all entry points (DataError with a plain message)."""
    if not isinstance(vehicle, Vehicle):
        raise DataError(f"vehicle must be a soiltrack Vehicle, got {type(vehicle).__name__}")
    if model not in MODELS:
        raise DataError(f"unknown model {model!r}; expected one of {MODELS}")
    if method not in METHODS:
        raise DataError(f"unknown method {method!r}; expected one of {METHODS}")
    if not isinstance(bounds, SoilBounds):
        raise DataError(f"bounds must be a SoilBounds, got {type(bounds).__name__}")
    if bounds.friction_angle[0] <= 0 or bounds.friction_angle[1] >= math.pi / 2:
        raise DataError("bounds on the friction angle must lie inside (0, 90) deg")
    if bounds.shear_modulus[0] <= 0:
        raise DataError("the lower bound on K must be > 0 m")
    if bounds.cohesion[0] < 0:
        raise DataError("the lower bound on cohesion must be >= 0 Pa")


def make_problem(
    data: SlipData,
    vehicle: Vehicle,
    model: str,
    bounds: SoilBounds,
    sigma=None,
    sigma_known: bool | None = None,
    method: str = "ipopt",
    effects=None,
    fixed=None,
    rig_speed: float = DEFAULT_RIG_SPEED,
) -> SlipProblem:
    """Validate slip data and build a :class:`SlipProblem`.

    Parameters
    ----------
    data : SlipData
    vehicle : Vehicle
    model : {"full", "cohesion-free"}
    bounds : SoilBounds
    sigma : float, array_like or "relative", optional
        Standard deviation of the tractive-force noise per sample (N). ``None``: equal
        weights, noise level estimated from the residuals. ``"relative"``: noise proportional
        to the force (weights ``|F_k|``, floored at 1 % of the largest), level estimated.
    sigma_known : bool, optional
        Whether ``sigma`` is the true noise level (normal intervals) or only relative weights
        (scaled by the residual variance, t intervals). Defaults to ``sigma is not None``.
    effects : sequence of effect names or EffectSet, optional
        Effects whose parameters are fitted with the soil (docs/physics.md, "Unmodelled effects").
    fixed : dict, optional
        ``{"effect.param": value}``: effect parameters held at a value (SI).
    rig_speed : float
        Track speed ``r w`` of the rig, m/s (vehicle speed for ``speed_resistance``).

    Raises
    ------
    DataError
        Wrong types, too few samples for the free parameters, bad sigma.
    """
    check_common(vehicle, model, method, bounds)
    return checked_problem(data, vehicle, model, bounds, sigma, sigma_known, method, effects, fixed, rig_speed)


def checked_problem(
    data: SlipData,
    vehicle: Vehicle,
    model: str,
    bounds: SoilBounds,
    sigma=None,
    sigma_known: bool | None = None,
    method: str = "ipopt",
    effects=None,
    fixed=None,
    rig_speed: float = DEFAULT_RIG_SPEED,
) -> SlipProblem:
    """:func:`make_problem` for a caller that checked the vehicle, model, method and bounds once
    (:func:`check_common`) for many data sets (``fit_many``): the data's own checks only."""
    if not isinstance(data, SlipData):
        raise DataError(f"expected SlipData or DriveLog, got {type(data).__name__}")
    if not (isinstance(rig_speed, (int, float)) and math.isfinite(rig_speed) and rig_speed > 0):
        raise DataError(f"rig_speed must be a finite number > 0 m/s, got {rig_speed!r}")
    if effects is None and fixed is None:  # the common case: no effects
        structure, fixed_t, e_start = None, (), ()
    else:
        structure, fixed_t, e_start = _effects_and_fixed(effects, fixed, vehicle)
    if structure and method != "ipopt":
        raise DataError(f"effects are fitted by method='ipopt' only, not {method!r}")
    n_eff = len(effect_symbols(structure, vehicle=vehicle)[2]) - len(fixed_t) if structure else 0
    p = n_free(model) + n_eff
    if data.n_samples < p:
        raise DataError(
            f"{data.n_samples} sample(s) cannot identify the {p} free parameters of the {model} model"
            f"{' with the effects' if n_eff else ''} (need at least {p} rows)",
            file=data.source,
            column=data.channel,
        )
    load = data.loads(vehicle.weight)
    load = load.astype(float) if data.normal_load is not None else load  # a copy of the data's; np.full is new
    sig, known = weights(data.values, sigma, sigma_known, source=data.source, column=data.channel)
    positive = data.slip[data.slip > 0]
    if positive.size < 2 or not np.count_nonzero(positive != positive[0]):  # fewer than 2 distinct nonzero slips:
        # F(i) = F_max g(i l / K): one slip gives one number, not both F_max and K
        if not data.slip.any():  # all slips zero
            raise DataError(
                "all slips are zero: the tractive force carries no information on the soil",
                file=data.source,
                column="slip",
            )
        raise DataError(
            f"all nonzero slips are equal (i = {float(np.max(data.slip)):.6g}): one point of the "
            "thrust-slip curve cannot separate F_max from K; measure at two or more different slips "
            "(ideally spread up to the traction limit)",
            file=data.source,
            column="slip",
        )
    offset = None
    force = np.array(data.values, float)
    if data.measured == "drawbar_pull":
        offset = nominal_offset(data.slip, load, vehicle, rig_speed)
        force = force + offset
    noise_model = "equal" if sigma is None else "relative" if isinstance(sigma, str) else "given"
    return SlipProblem(
        slip=np.array(data.slip, float),
        force=force,
        load=load,
        noise_model=noise_model,
        sigma=sig,
        sigma_known=known,
        vehicle=vehicle,
        bounds=bounds,
        model=model,
        source=data.source,
        measured=data.measured,
        offset=offset,
        effects=structure if structure else None,
        fixed=fixed_t,
        rig_speed=float(rig_speed),
        effect_start=e_start,
    )


def checked_problems(
    datasets: list, vehicle: Vehicle, model: str, bounds: SoilBounds, sigma_known: bool | None = None
) -> list[SlipProblem | None]:
    """:func:`checked_problem` of many plain sweeps at once (``fit_many``, vehicle and bounds checked once, no
    ``sigma``): the same problems, their arrays rows of one stacked array per length.

    A plain sweep is :class:`SlipData` of the tractive force without a normal-load column, with enough rows
    for the model's free parameters and two or more distinct nonzero slips (what :func:`checked_problem`
    checks, decided for a length's datasets at once). Any other item is ``None``: the caller sets it up with
    :func:`checked_problem` (which says what is wrong with it).
    """
    out: list[SlipProblem | None] = [None] * len(datasets)
    groups: dict[int, list[int]] = {}
    p = n_free(model)
    for k, d in enumerate(datasets):
        if type(d) is SlipData and d.normal_load is None and d.tractive_force is not None and d.slip.size >= p:
            groups.setdefault(d.slip.size, []).append(k)
    known = False if sigma_known is None else bool(sigma_known)
    W = float(vehicle.weight)
    rig_speed = float(DEFAULT_RIG_SPEED)
    new = object.__new__
    for n, idx in groups.items():
        S = np.array([datasets[k].slip for k in idx], dtype=float)
        F = np.array([datasets[k].tractive_force for k in idx], dtype=float)
        L = np.empty(S.shape)
        L.fill(W)
        sig = np.empty(S.shape)
        sig.fill(1.0)
        pos = S > 0
        with np.errstate(invalid="ignore"):
            distinct = np.where(pos, S, np.inf).min(axis=1) != np.where(pos, S, -np.inf).max(axis=1)
        ok = (np.count_nonzero(pos, axis=1) >= 2) & distinct
        for k, good, s_r, f_r, l_r, w_r in zip(idx, ok.tolist(), list(S), list(F), list(L), list(sig)):
            if not good:
                continue  # checked_problem raises the error that names it
            pb = out[k] = new(SlipProblem)  # SlipProblem(...) without the frozen dataclass's per-field setattr
            pb.__dict__.update(
                slip=s_r,
                force=f_r,
                load=l_r,
                noise_model="equal",
                sigma=w_r,
                sigma_known=known,
                vehicle=vehicle,
                bounds=bounds,
                model=model,
                source=datasets[k].source,
                measured="tractive_force",
                offset=None,
                effects=None,
                fixed=(),
                rig_speed=rig_speed,
                effect_start=(),
            )
    return out


def _effects_and_fixed(effects, fixed, vehicle: Vehicle) -> tuple[EffectSet, tuple, tuple]:
    """Validate ``effects`` (names or an EffectSet) and ``fixed`` ``{"effect.param": value}``.

    Returns the structure (which effects, integer parameters), the fixed ``((label, value), ...)``
    and start values ``((label, value), ...)`` (the values of a given EffectSet or dict).
    """
    if isinstance(effects, str):
        effects = [effects]
    given = parse_effects(effects) if effects else EffectSet()
    structure = effect_structure(given, vehicle) if effects else EffectSet()
    start = tuple(
        (f"{n}.{p.name}", given.value(n, p.name, vehicle))
        for n in given.names
        for p in EFFECTS[n].params
        if not p.integer
    )
    if fixed is None:
        return structure, (), start
    if not hasattr(fixed, "items"):
        raise DataError(f"fixed must be a dict {{'effect.param': value}}, got {type(fixed).__name__}")
    labels = effect_symbols(structure, vehicle=vehicle)[2] if structure else []
    out = []
    for label, value in fixed.items():
        if label not in labels:
            name = str(label).partition(".")[0]
            hint = f"the fitted effect parameters are {labels}" if labels else "no effect is fitted"
            if name in EFFECTS and name not in structure:
                hint = f"effect '{name}' is not among the fitted effects ({list(structure.names)})"
            raise DataError(f"fixed: unknown parameter {label!r}; {hint}")
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise DataError(f"fixed: {label} must be a number, got {value!r}") from None
        name, pname = label.split(".", 1)
        lo, hi = parameter_bounds(name, pname, vehicle)
        if not (math.isfinite(v) and lo <= v <= hi):
            raise DataError(f"fixed: {label} = {value!r} is outside its physical range [{lo:g}, {hi:g}]")
        out.append((label, v))
    order = {lab: k for k, lab in enumerate(labels)}
    return structure, tuple(sorted(out, key=lambda t: order[t[0]])), start
