"""``fit``: one entry point for tractive force-slip data and drive logs."""

from __future__ import annotations

import warnings

from dataclasses import replace
from typing import TYPE_CHECKING, Any, overload

from ..soilmodel.data import DriveLog, PlateTest, ShearTest, SlipData
from ..soilmodel.rigid_wheel import RigidWheel
from ..soilmodel.wheel_sweep import WheelSweep
from ..soilmodel.errors import DataError
from ..soilmodel.soil import PRACTICAL_BOUNDS, SoilBounds
from ..soilmodel.threadsafe import fit_section
from ..soilmodel.vehicle import Vehicle
from .sweep.compiled_lm import fit_compiled
from .engines import check_engine, jit_mode, normalise_status
from .sweep.ipopt import fit_ipopt
from .sweep.start import x0_vector
from .sweep.joint import fit_joint
from .estimates.joint_likelihood import PROFILE_IPOPT_OPTIONS, check_intervals, with_profile_intervals
from .sweep.problem import FitFailed, check_common, make_problem
from .estimates.result import FitResult, record_with
from .sweep.seed_methods import fit_least_squares, fit_newton
from .settings import SETTING_NAMES, FitSettings
from .consistency import check_consistency, with_consistency
from .sweep.resistance import RESISTANCE_MODES, assumed_resistance, fit_resistance
from .sweep.model import SweepResiduals
from .sweep.rig import load_separation, rig_extra, std_weights
from .sweep.slip_noise import check_slip_noise, fit_with_slip_noise
from .drivelog.torque_hold import fit_both_holds
from .dispatch import check_fit_options, fit_other_kind

if TYPE_CHECKING:
    from .datasets.result import JointFitResult
    from .estimates.estimate import Estimate
    from .wheel.result import WheelFitResult

__all__ = ["fit"]


@overload
def fit(data: SlipData | DriveLog, running_gear: Vehicle, **kwargs: Any) -> FitResult: ...
@overload
def fit(data: WheelSweep | SlipData, running_gear: RigidWheel, **kwargs: Any) -> WheelFitResult: ...
@overload
def fit(data: ShearTest | PlateTest, running_gear: None = None, **kwargs: Any) -> Estimate: ...
@overload
def fit(data: list | tuple, running_gear: Any = None, **kwargs: Any) -> JointFitResult: ...


def fit(
    data,
    running_gear=None,
    *,
    model: str = "full",
    method: str = "ipopt",
    bounds=None,
    x0=None,
    strict: bool = False,
    engine: str | None = None,
    effects=None,
    fixed=None,
    settings: FitSettings | None = None,
    consistency: bool = True,
    **options,
):
    """Identify the soil from measured data of any kind: :class:`FitResult` for a vehicle's sweep or log,
    :class:`~.wheel.WheelFitResult` for a wheel, :class:`~.estimates.estimate.Estimate` for a bevameter test,
    each with its ``outcome`` (:mod:`.outcome`); keyword-only options checked up front (:mod:`.dispatch`).

    Parameters
    ----------
    data : SlipData, DriveLog, WheelSweep, ShearTest or PlateTest, or a list of them
        A list: one soil shared by all (wheel sweeps and bevameter tests; running_gear one for all or a
        list, one per data set), :func:`soiltrack.identify.datasets.fit_datasets`.
        Tractive force-slip or drawbar pull-slip samples (any number, one or several normal
        loads; a missing ``normal_load`` means the vehicle's weight) or a drive log (dispatched
        to :func:`soiltrack.identify.drivelog.fit.fit_drive_log`). Drawbar pull is modelled as
        ``F(i) - R`` with ``R`` the motion resistance (``mu_r W`` for the nominal model). A wheel
        sweep (or drawbar-pull :class:`SlipData`, load per row); a bevameter test (no running gear).
    running_gear : Vehicle, RigidWheel or None
        The tracked vehicle, the rigid wheel, or None for a bevameter test. For a wheel: ``model``
        (``"cohesion-free"`` holds c at 0), ``fixed`` (``{parameter: SI value}``), ``effects``
        (``("slip_sinkage",)``), ``bounds`` (a ``WheelBounds``) and ``strict`` apply.
    model : {"full", "cohesion-free"}
        Eq. 2, or Eq. 8 (c fixed at 0).
    method : {"ipopt", "newton", "least-squares"}
        ``"ipopt"`` (default): bounded weighted least squares, cached IPOPT solver, start from
        a variable-projection grid. ``"newton"`` and ``"least-squares"``: the seed's methods,
        unbounded, with honest failure reports (see :mod:`soiltrack.identify.sweep.seed_methods`).
    bounds : SoilBounds
        Box bounds (used by IPOPT; the seed's methods only report against them).
    x0 : Soil or array_like, optional
        Start point ``[c (Pa), phi (rad), K (m)]``.
    strict : bool
        Raise :class:`FitFailed` when the fit does not succeed.
    engine : {"auto", "ipopt", "compiled", "vectorized"}, optional
        What solves ``method="ipopt"`` on slip data (same estimator and optimum; :mod:`soiltrack.identify.engines`).
        Default ``"auto"``: the compiled LM engine (C code from the per-user cache, else the virtual machine while
        it compiles), which hands any fit it cannot certify to IPOPT; ``result.extra["engine"]`` says which solved.
    consistency : bool
        Run the data's cross-channel consistency checks (see Notes). ``False`` is for a caller
        that checked the whole data set once and refits parts of it (the diagnosis): a part of a
        log has less power for the checks, not less consistency.
    settings : FitSettings, optional
        Typed solver settings (engine, ``n_grid``, ``ipopt_options``, ``max_iter``); the
        keywords of the same names override its fields.
    effects : sequence of str or EffectSet, optional
        Unmodelled effects (docs/physics.md, "Unmodelled effects", :data:`soiltrack.soilmodel.EFFECTS`) whose
        parameters are fitted jointly with the soil by IPOPT, within their physical ranges
        (integer shape parameters such as ``n_w`` stay at their defaults). The result reports
        them in ``result.effects`` like the soil's parameters.
    fixed : dict, optional
        ``{"effect.param": value}`` (SI): effect parameters held at a value; their Jacobian
        column is still reported (``result.jacobian``, ``result.parameter_names``).
    **options
        ``rig_speed`` (m/s, the rig's track speed for ``speed_resistance``, default 0.5), ``sigma`` (N, scalar or
        per sample; default: equal weights, noise from the residuals) and ``sigma_known`` (bool) describe the data;
        ``slip_noise`` (``"auto"``, ``"off"`` or the slip's standard deviation; default ``"auto"`` with effects,
        else ``"off"``) says whether the measured slip is noisy (:mod:`soiltrack.identify.sweep.slip_noise`:
        effective-variance weights, adopted by ``auto`` only when a likelihood-ratio test finds
        the noise); ``intervals`` (``"auto"``, ``"linear"``, ``"profile"``; default ``"auto"``
        with effects, else ``"linear"``) says which 95 % intervals come from the profile
        likelihood (:mod:`soiltrack.identify.estimates.joint_likelihood`; ``auto``: the weakly identifiable
        and at-bound parameters). Either one other than off/linear makes the fit an IPOPT joint
        fit. ``resistance`` (``"assumed"``, default, ``"fit"`` or ``"fit-sinkage"``) says whether a
        drawbar-pull sweep's resistance is the vehicle's ``mu_r W``, ``mu_r W`` with mu_r fitted with
        the soil, or ``k_z z W`` with k_z fitted from the data's sinkage
        (:mod:`soiltrack.identify.sweep.resistance`). A ``tractive_force_std_N`` /
        ``drawbar_pull_std_N`` column of the data gives relative weights when ``sigma`` is not
        given (:mod:`soiltrack.identify.sweep.rig`). ``n_grid``, ``ipopt_options`` and
        ``max_iter`` are :class:`FitSettings` fields.
        Drive-log options are passed on; ``max_memory`` (bytes, default half the available memory) refuses
        a drive-log fit whose estimated memory exceeds it, before the work (:mod:`.drivelog.budget`).

    Returns
    -------
    FitResult, WheelFitResult, Estimate (bevameter) or JointFitResult (a list of data sets: :mod:`.datasets`)

    Raises
    ------
    DataError
        Wrong types, too few samples for the free parameters (naming file and column).
    FitFailed
        With ``strict=True`` when the fit did not succeed.

    Notes
    -----
    Every result carries the data-consistency checks of :mod:`soiltrack.identify.consistency`
    (``extra["consistency"]``): a mislabelled file (one sprocket's torque, time in ms, speed in
    km/h or rpm, loads in kN, repeated rows) is said in the warnings, and the result fails
    (``success`` False) where the answer cannot stand.
    """
    running_gear = _renamed_running_gear(running_gear, options)
    if isinstance(data, (list, tuple)):  # several data sets on one soil (identify/datasets)
        return _fit_several(data, running_gear, model=model, bounds=bounds, effects=effects, fixed=fixed, **options)
    kw = {"model": model, "method": method, "bounds": bounds, "x0": x0, "engine": engine, "effects": effects}
    if check_fit_options(data, running_gear, options=options, fixed=fixed, settings=settings, **kw) is not None:
        return fit_other_kind(
            data, running_gear, model=model, bounds=bounds, effects=effects, fixed=fixed, strict=strict
        )
    vehicle, bounds = running_gear, PRACTICAL_BOUNDS if bounds is None else bounds
    # the solver lock (re-entrant) held for the whole fit: a fork never copies a thread mid-solve (soilmodel.threadsafe)
    with fit_section():
        res = _fit_unchecked(data, vehicle, model, method, bounds, x0, engine, effects, fixed, settings, options)
        if consistency and isinstance(data, (SlipData, DriveLog)):
            res = with_consistency(res, check_consistency(data, vehicle))
    if strict and not res.success:
        raise FitFailed(res)
    return res


def _fit_several(data, running_gear, **kwargs):
    """Several data sets on one soil, with the consistency test (:mod:`soiltrack.identify.datasets`)."""
    from .datasets.fit import fit_joint_call

    return fit_joint_call(data, running_gear, **kwargs)


def _renamed_running_gear(running_gear, options: dict):
    """The running gear, given as ``running_gear`` or by its old keyword ``vehicle`` (deprecated), not both."""
    if "vehicle" in options:  # the keyword's name before the running gear of every kind
        if running_gear is not None:
            raise DataError("fit: give the running gear once (running_gear, or its old name vehicle), not both")
        warnings.warn("fit(vehicle=...) is now fit(running_gear=...)", DeprecationWarning, stacklevel=3)
        running_gear = options.pop("vehicle")
    return running_gear


def _fit_unchecked(
    data,
    vehicle: Vehicle,
    model: str,
    method: str,
    bounds: SoilBounds,
    x0,
    engine: str | None,
    effects,
    fixed,
    settings: FitSettings | None,
    options: dict,
) -> FitResult:
    """``fit`` without the consistency checks (never strict: ``fit`` raises after the checks)."""
    if isinstance(data, DriveLog):
        return _fit_log(data, vehicle, model, method, bounds, x0, engine, effects, fixed, settings, options)
    if not isinstance(data, SlipData):
        raise DataError(f"fit takes SlipData or DriveLog, got {type(data).__name__}")
    sigma = options.pop("sigma", None)
    sigma_known = options.pop("sigma_known", None)
    slip_noise = options.pop("slip_noise", None)
    intervals = options.pop("intervals", None)
    resistance = options.pop("resistance", None)
    if resistance not in (None, *RESISTANCE_MODES):
        raise DataError(f"resistance must be one of {RESISTANCE_MODES}, got {resistance!r}")
    if resistance in ("fit", "fit-sinkage"):

        def fit_at(d: SlipData, v: Vehicle, final: bool) -> FitResult:
            return fit(
                d,
                v,
                model=model,
                method=method,
                bounds=bounds,
                x0=x0,
                strict=False,
                engine=engine,
                effects=effects,
                fixed=fixed,
                settings=settings,
                sigma=sigma,
                sigma_known=sigma_known,
                slip_noise=slip_noise,
                intervals=intervals if final else "linear",
                **options,
            )

        rig_speed = options.get("rig_speed")
        return fit_resistance(
            data, vehicle, fit_at, resistance, SweepResiduals() if rig_speed is None else SweepResiduals(rig_speed)
        )
    std = std_weights(data)
    if sigma is None and std is not None:  # the rig's per-row std: relative weights, level estimated
        sigma, sigma_known = std, (False if sigma_known is None else sigma_known)
    separation = load_separation(data) if model == "full" else None
    if separation is not None and separation.fragile and intervals is None and method == "ipopt":
        intervals = "auto"  # c and phi rest on the load's spread: their intervals from the profile likelihood
    rig = {"rig_speed": options.pop("rig_speed")} if "rig_speed" in options else {}
    pb = make_problem(
        data,
        vehicle,
        model,
        bounds,
        sigma=sigma,
        sigma_known=sigma_known,
        method=method,
        effects=effects,
        fixed=fixed,
        **rig,
    )
    x0v = None if x0 is None else x0_vector(x0)
    st = _resolved_settings(settings, engine, options)
    return _with_rig(data, _solve_sweep(pb, x0v, st, method, fixed, slip_noise, intervals), separation)


def _fit_log(data: DriveLog, vehicle, model, method, bounds, x0, engine, effects, fixed, settings, options: dict):
    """A drive log: the sweep-only options refused, the rest handed to the drive-log fit."""
    check_common(vehicle, model, method, bounds)
    for opt in ("slip_noise", "intervals"):
        if options.get(opt) is not None:
            raise DataError(
                f"{opt} applies to slip sweeps; a drive log's slip is already a latent variable of "
                "its fit (its noise comes from the speed channels)",
                file=data.source,
            )
        options.pop(opt, None)
    from .drivelog.fit import fit_drive_log  # written separately; imported lazily

    if effects is not None:
        options["effects"] = effects
    if fixed is not None:
        options["fixed"] = fixed
    if settings is not None or engine is not None:
        check_engine(FitSettings.resolve(settings, engine=engine).engine)
    if effects is not None and options.get("torque_hold") is None:
        # the hold is not stated: intervals cover both (soiltrack.identify.drivelog.torque_hold)
        options.pop("torque_hold", None)
        return fit_both_holds(
            lambda hold: fit_drive_log(
                data, vehicle, model, bounds, x0, False, method=method, torque_hold=hold, **options
            )
        )
    return fit_drive_log(data, vehicle, model, bounds, x0, False, method=method, **options)


def _resolved_settings(settings: FitSettings | None, engine: str | None, options: dict) -> FitSettings:
    """The typed settings with the keywords of the same names applied; an unknown option is refused."""
    if options:
        given = {k: options.pop(k) for k in SETTING_NAMES if k in options}
        _check_options(options, set(SETTING_NAMES))
        return FitSettings.resolve(settings, engine=engine, **given)
    return FitSettings.resolve(settings, engine=engine)  # the common case: no settings keywords


def _solve_sweep(pb, x0v, st: FitSettings, method: str, fixed, slip_noise, intervals) -> FitResult:
    """Solve a slip problem: jointly by IPOPT (effects, slip noise, profile intervals), else by the engine or method."""
    joint = pb.has_effects
    if slip_noise is not None or intervals is not None or joint:
        slip_noise = check_slip_noise(("auto" if joint else "off") if slip_noise is None else slip_noise)
        intervals = check_intervals(("auto" if joint else "linear") if intervals is None else intervals)
        joint = joint or slip_noise != "off" or intervals != "linear"
    if joint:  # joint soil-and-effects fit (or slip noise, profile intervals): IPOPT (whatever the engine)
        if method != "ipopt":
            raise DataError(
                f"effects, slip noise and profile intervals are fitted by IPOPT only (method='ipopt'), "
                f"not by the seed's method {method!r}"
            )
        if st.max_iter is not None:
            raise DataError("max_iter applies to method='newton' or 'least-squares'")
        return _fit_joint_sweep(pb, x0v, st, slip_noise, intervals)
    if fixed:
        raise DataError("fixed holds effect parameters: give the effects too (effects=[...])")
    if method == "ipopt":
        if st.max_iter is not None:
            raise DataError(
                "max_iter applies to method='newton' or 'least-squares'; for IPOPT use "
                "ipopt_options={'ipopt.max_iter': N}"
            )
        if st.engine == "ipopt":
            return normalise_status(fit_ipopt(pb, x0v, ipopt_options=st.ipopt_dict, n_grid=st.n_grid), "ipopt")
        # compiled LM (a single dataset is "vectorized" trivially); IPOPT if not certified
        res = fit_compiled(pb, x0v, n_grid=st.n_grid, ipopt_options=st.ipopt_dict, jit=jit_mode(st.engine))
        if res.extra.get("engine") == "ipopt":
            normalise_status(res)
        return res
    if method == "newton":
        return fit_newton(pb, x0v, max_iter=st.max_iter or 50)
    return fit_least_squares(pb, x0v, max_iter=st.max_iter or 500)


def _with_rig(data: SlipData, res: FitResult, separation) -> FitResult:
    """The result with what a rig sweep adds to its ``extra`` (:func:`~.sweep.rig.rig_extra`)."""
    more = rig_extra(data, res, separation)
    if data.measured == "drawbar_pull":
        more["resistance"] = assumed_resistance(res)
    if not more:
        return res
    return record_with(res, extra={**(res.extra if isinstance(res.extra, dict) else {}), **more})


def _fit_joint_sweep(pb, x0v, st: FitSettings, slip_noise, intervals: str) -> FitResult:
    """IPOPT joint fit of a sweep, with slip-noise weights and profile intervals as asked."""
    opts, n_grid = st.ipopt_dict, st.n_grid

    def solve(q, start_x):
        return fit_joint(q, x0v if start_x is None else None, ipopt_options=opts, n_grid=n_grid, start_x=start_x)

    res, noise, pb_final = fit_with_slip_noise(pb, solve, slip_noise)
    extra = dict(res.extra)
    extra["slip_noise"] = noise.to_dict()
    extra["sigma_model"] = "slip_noise" if noise.adopted else pb.noise_model
    warns = tuple(res.input_warnings) + ((noise.note,) if noise.note and (noise.adopted or not noise.converged) else ())
    res = replace(res, extra=extra, input_warnings=warns)
    res = with_profile_intervals(
        pb_final,
        res,
        lambda q, hold, sx: fit_joint(
            q, ipopt_options={**PROFILE_IPOPT_OPTIONS, **(opts or {})}, n_grid=n_grid, hold=hold, start_x=sx
        ),
        intervals,
    )
    return normalise_status(res, "ipopt")


def _check_options(options: dict, allowed: set) -> None:
    unknown = sorted(set(options) - allowed)
    if unknown:
        also = ["intervals", "sigma", "sigma_known", "slip_noise"]
        raise DataError(f"unknown option(s) {unknown}; allowed here: {sorted(allowed) + also}")
