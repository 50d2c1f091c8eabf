"""Fit several data sets on one soil (:func:`fit_datasets`), with the consistency test.

Every data set is first fitted alone (its own fit: the library's fit of its kind for the outcome,
and the same block of :mod:`.problem` solved alone for the likelihood); then all together with
the soil shared and each wheel's slip-sinkage coefficient its own. The likelihood-ratio
statistic ``2 sum_d (f_d(joint) - f_d(own))`` (f_d the block's negative log-likelihood) is
chi-square with ``sum_d rank_d - rank_joint`` degrees of freedom (ranks of the Jacobians: what
each fit identifies) when the data sets share one soil. The data set with the largest share of
the statistic is the one that disagrees most; each shared parameter's shift is
``(own - joint) / own standard error``.
"""

from __future__ import annotations

import math
import time
from typing import Any, Mapping, Sequence

import numpy as np

from ...soilmodel.bevameter_records import AnnulusTest
from ...soilmodel.data import DriveLog, PlateTest, ShearTest, SlipData
from ...soilmodel.errors import DataError
from ...soilmodel.rigid_wheel import RigidWheel
from ...soilmodel.threadsafe import best_of_starts
from ...soilmodel.vehicle import Vehicle
from ...soilmodel.wheel import DEFAULT_WHEEL_SETTINGS, WheelSettings
from ...soilmodel.wheel_sweep import WheelSweep
from ..estimates.least_squares import core_stats_one, identified_columns
from ..wheel.fitting import START_BOUND_MARGIN, WheelFitOptions, fit_wheel
from ..wheel.problem import DEFAULT_WHEEL_BOUNDS, PARAMETER_SCALES, WHEEL_PARAMETERS, WheelBounds
from .problem import (
    GROUSER_SCALE,
    N_SHARED,
    N_SPECIFIC,
    SHARED,
    SUMMARY_CHANNEL,
    TRACK_KINDS,
    BlockSpec,
    block_touches,
    box8,
    joint_solver,
)
from .result import JointFitResult, build_joint_result

__all__ = ["fit_datasets", "fit_joint_call"]

#: Starts of a block without a usable own fit (SI): c, phi (deg), K, n.
_START_PHI_DEG = (20.0, 30.0, 38.0)
_START_K_M = (0.008, 0.025)


def _as_block(
    data, gear, settings: WheelSettings, effects: tuple[str, ...], free_grouser: bool = False
) -> tuple[BlockSpec, np.ndarray, Any]:
    """The block spec, data vector and (for a drive log) own fit of one data set (checked: kind against gear)."""
    if isinstance(gear, Vehicle) or isinstance(data, DriveLog):
        return _track_block(data, gear)
    if isinstance(data, (ShearTest, AnnulusTest, PlateTest)):
        if isinstance(data, ShearTest):
            return (
                BlockSpec("shear", data.n_samples),
                np.concatenate([data.normal_pressure, data.shear_displacement, data.shear_stress]),
                None,
            )
        if isinstance(data, AnnulusTest):
            cols = [data.normal_pressure, data.rotation, data.torque, data.inner_radius, data.outer_radius]
            return (
                BlockSpec("annulus", data.n_samples),
                np.concatenate([np.broadcast_to(c, data.n_samples) for c in cols]),
                None,
            )
        z, pr = data.sinkage, data.pressure
        z_ref = float(np.exp(np.mean(np.log(z[(z > 0) & (pr > 0)]))))
        return BlockSpec("plate", data.n_samples), np.concatenate([data.plate_width, z, pr, [z_ref]]), None
    if not isinstance(gear, RigidWheel):
        raise DataError(
            f"a {type(data).__name__} in a joint fit needs a RigidWheel (or, for SlipData, a tracked Vehicle), "
            f"got {type(gear).__name__}",
            file=getattr(data, "source", None),
        )
    if isinstance(data, SlipData):
        from ..dispatch import wheel_sweep_of

        data = wheel_sweep_of(data)
    if not isinstance(data, WheelSweep):
        raise DataError(f"not a data set the joint fit takes: {type(data).__name__}")
    from ..wheel.fitting import sweep_parameters

    spec = BlockSpec(
        "wheel",
        data.n_samples,
        wheel=gear,
        settings=settings,
        sinkage=data.has_sinkage,
        torque=data.has_torque,
        specific_free="slip_sinkage" in effects,
        grouser_free=free_grouser,
    )
    return spec, sweep_parameters(data, np.zeros(0)), None


def _track_block(data, gear) -> tuple[BlockSpec, np.ndarray, Any]:
    """A tracked vehicle's slip sweep (its rows) or drive log (its own fit's F_max and K, whitened)."""
    src = getattr(data, "source", None)
    if not isinstance(gear, Vehicle):
        raise DataError(
            f"a {type(data).__name__} in a joint fit needs a tracked Vehicle, got {type(gear).__name__}", file=src
        )
    if isinstance(data, SlipData):
        pb, weighted = _sweep_problem(data, gear)
        spec = BlockSpec("track", data.n_samples, vehicle=gear, measured=data.measured, weighted=weighted)
        return spec, np.concatenate([pb.slip, pb.load, data.values, pb.sigma]), None
    if not isinstance(data, DriveLog):
        raise DataError(
            f"a {type(data).__name__} in a joint fit needs a RigidWheel; with a tracked Vehicle a joint fit takes "
            "slip sweeps (SlipData) and drive logs",
            file=src,
        )
    from ..drivelog.fit import fit_drive_log

    own = fit_drive_log(data, gear)
    return BlockSpec("drivelog", data.n_samples, vehicle=gear), _summary_vector(own, gear, src), own


def _sweep_problem(data: SlipData, gear: Vehicle) -> tuple[Any, bool]:
    """The single fit's problem of a track sweep (:func:`soiltrack.identify.fit`'s rule: a per-row std column,
    :func:`~soiltrack.identify.sweep.rig.std_weights`, gives relative weights, the level estimated) and whether
    it is weighted (a std column; else every weight is 1)."""
    from ...soilmodel.soil import PRACTICAL_BOUNDS
    from ..sweep.problem import make_problem
    from ..sweep.rig import std_weights

    std = std_weights(data)
    return make_problem(data, gear, "full", PRACTICAL_BOUNDS, sigma=std, sigma_known=False), std is not None


def _summary_vector(own, gear: Vehicle, src) -> np.ndarray:
    """``[F_max, K, L (row-major), W, A]`` of a drive log's own fit, ``L^T L`` the inverse covariance of
    (F_max, K); K left out (its row of L zero) where the log does not determine it."""
    ex = own.extra if own.success else {}
    F, sF = ex.get("max_thrust_N"), ex.get("max_thrust_stderr_N")
    if F is None or sF is None or not (math.isfinite(F) and math.isfinite(sF) and sF > 0):
        raise DataError(
            f"the drive log's own fit is {own.outcome} ({own.fit_outcome.reason or 'no F_max standard error'}): a "
            "drive log joins a joint fit through its determined F_max and K",
            file=src,
        )
    K, sK, rho = ex.get("shear_modulus_m"), ex.get("shear_modulus_stderr_m"), ex.get("corr_max_thrust_shear_modulus")
    if K is not None and sK is not None and math.isfinite(sK) and sK > 0:
        rho = float(rho) if rho is not None and math.isfinite(rho) else 0.0
        cov = np.array([[sF**2, rho * sF * sK], [rho * sF * sK, sK**2]])
        L = np.linalg.inv(np.linalg.cholesky(cov))
    else:
        K, L = 0.0, np.array([[1.0 / sF, 0.0], [0.0, 0.0]])
    return np.concatenate([[F, K], L.ravel(), [gear.weight, gear.contact_area]])


def _gears(datasets: Sequence, gears) -> list:
    """One gear per data set (one for all, or a list of the same length)."""
    if gears is None or isinstance(gears, (RigidWheel, Vehicle)):
        return [None if isinstance(d, (ShearTest, AnnulusTest, PlateTest)) else gears for d in datasets]
    gears = list(gears)
    if len(gears) not in (1, len(datasets)):
        raise DataError(
            f"running_gear: give one for all data sets or one per data set ({len(datasets)}), got {len(gears)}"
        )
    if len(gears) == 1:
        gears = gears * len(datasets)
    return [None if isinstance(d, (ShearTest, AnnulusTest, PlateTest)) else g for d, g in zip(datasets, gears)]


def _solve(specs, shared_free, p, starts, lbx, ubx) -> dict[str, Any]:
    """Solve from every start; the best (a converged solve first, then the least objective)."""
    solver, ev = joint_solver(tuple(specs), tuple(shared_free))
    best, n_ok = best_of_starts(solver, [np.clip(x0, lbx, ubx) for x0 in starts], p=p, lbx=lbx, ubx=ubx)
    failed, f, x, status, iters = best
    scales = _scales(specs, shared_free)
    outs = [np.asarray(v, dtype=float) for v in ev(x * scales, p)]
    return {
        "converged": not failed,
        "f": f,
        "x_si": x * scales,
        "status": status,
        "iterations": iters,
        "starts": len(starts),
        "starts_converged": n_ok,
        **_statistics(specs, outs),
    }


def _scales(specs, shared_free) -> np.ndarray:
    sc8 = np.append(PARAMETER_SCALES, GROUSER_SCALE)
    return np.array([sc8[k] for _, k in _layout(specs, shared_free)], dtype=float)


def _statistics(specs, outs: list[np.ndarray]) -> dict[str, Any]:
    """Each channel weighted by its own noise level; rank, covariance, identifiability (core_stats)."""
    theta, f_blocks = outs[0].ravel(), outs[1].ravel()
    rws, Js, noise, q = [], [], [], 2
    for spec in specs:
        sds = {}
        for name in spec.channels:
            r, J, floor = outs[q].ravel(), outs[q + 1], float(outs[q + 2].ravel()[0])
            q += 3
            s = math.sqrt(float(r @ r) / r.size)
            sds[name] = s
            # a drive log's summary is whitened by its own fit's covariance: known scale 1
            s_eff = 1.0 if name == SUMMARY_CHANNEL else math.hypot(s, floor)
            rws.append(r / s_eff)
            Js.append(J.reshape(r.size, -1) / s_eff)
        noise.append(sds)
    J = np.vstack(Js)
    rw = np.concatenate(rws)
    finite = bool(np.all(np.isfinite(J)) and np.all(np.isfinite(rw)))
    nvar = J.shape[1]
    if nvar == 0:
        return {
            "theta": theta,
            "f_blocks": f_blocks,
            "noise_sd": noise,
            "rank": 0,
            "finite": finite,
            "cov": np.zeros((0, 0)),
            "ident": np.zeros(0, bool),
            "dof": rw.size,
            "n_rows": rw.size,
        }
    known = all(name == SUMMARY_CHANNEL for sp in specs for name in sp.channels)
    st = core_stats_one(np.where(np.isfinite(J), J, 0.0), np.where(np.isfinite(rw), rw, 0.0), known)
    D, V, Pinv = st["D"][0], st["V"][0], st["Pinv"][0]
    nonnull, rank, dof, s2 = st["nonnull"][0], int(st["rank"][0]), int(st["dof"][0]), float(st["s2"][0])
    null = V[:, ~nonnull]
    ident = identified_columns(null, st["Dok"][0])
    cov = s2 * Pinv / np.outer(D, D) if math.isfinite(s2) else np.full((nvar, nvar), np.nan)
    return {
        "theta": theta,
        "f_blocks": f_blocks,
        "noise_sd": noise,
        "rank": rank,
        "finite": finite,
        "cov": cov,
        "ident": ident,
        "dof": dof,
        "n_rows": rw.size,
    }


def _layout(specs, shared_free) -> list[tuple[int, int]]:
    """``(block, index into its 8-vector)`` of every NLP variable: the shared soil, then s and h per block."""
    out = [(0, k) for k in range(N_SHARED) if shared_free[k]]
    for d, sp in enumerate(specs):
        out += [(d, N_SHARED)] if sp.specific_free else []
        out += [(d, N_SHARED + 1)] if sp.grouser_free else []
    return out


def _problem(specs, data_p, fixed: Mapping[str, float], bounds: WheelBounds):
    """Free mask, held values, variable bounds and the NLP parameter vector of blocks ``specs``."""
    touched = np.zeros(N_SHARED, bool)
    for s in specs:
        touched |= np.array(block_touches(s))
    shared_free = tuple(bool(touched[k] and SHARED[k] not in fixed) for k in range(N_SHARED))
    held = np.array([float(fixed.get(n, 0.0)) for n in SHARED])
    held_spec = [
        v
        for sp in specs
        for v in (float(fixed.get("slip_sinkage", 0.0)), sp.wheel.grouser_height if sp.wheel is not None else 0.0)
    ]
    lay = _layout(specs, shared_free)
    boxes = [box8(sp, bounds) for sp in specs]
    lbx = np.array([boxes[d][0][k] / boxes[d][2][k] for d, k in lay])
    ubx = np.array([boxes[d][1][k] / boxes[d][2][k] for d, k in lay])
    p = np.concatenate([held, held_spec, *data_p])
    return shared_free, p, lbx, ubx, lay


def _x_from_theta(th8s: list[np.ndarray], specs, shared_free, bounds: WheelBounds) -> np.ndarray:
    """Scaled variables from an 8-vector per block (the shared part from the first), inside the bounds."""
    x = []
    for d, k in _layout(specs, shared_free):
        lo, hi, sc = box8(specs[d], bounds)
        m = START_BOUND_MARGIN * (hi[k] - lo[k])
        x.append(float(np.clip(th8s[d][k], lo[k] + m, hi[k] - m)) / sc[k])
    return np.array(x, dtype=float)


def _default_starts(spec: BlockSpec, d: np.ndarray) -> list[np.ndarray]:
    """Start 7-vectors of a block without an own fit's values (a grid in phi and K; Bekker from the plate)."""
    out = []
    kphi = 1.5e6
    if spec.kind == "plate":
        z, pr = d[spec.n : 2 * spec.n], d[2 * spec.n : 3 * spec.n]
        use = z > 0
        kphi = float(np.median(pr[use] / z[use])) if np.any(use) else kphi
    for phi in _START_PHI_DEG:
        for K in _START_K_M:
            h = spec.wheel.grouser_height if spec.wheel is not None else 0.0
            out.append(np.array([500.0, math.radians(phi), K, 0.0, kphi, 1.0, 0.0, h]))
    return out


def _own_theta(data, gear, spec, fixed, effects, bounds, settings, official=None) -> tuple[list[np.ndarray], Any]:
    """The library's own fit of one data set (its outcome) and start 8-vectors from it."""
    if spec.kind in TRACK_KINDS:
        if official is None:
            from .. import fit as single_fit  # the public face (identify.fitting calls this module: no cycle)

            # the library's single fit of the sweep (its weights, outcome, lack of fit against the repeats)
            official = single_fit(data, gear)
        starts = [_default8(official.theta)] if official.success and np.all(np.isfinite(official.theta)) else []
        return starts, official
    if spec.kind == "wheel":
        from ..dispatch import wheel_sweep_of

        opts = WheelFitOptions(fixed=dict(fixed), effects=effects, bounds=bounds, settings=settings)
        res = fit_wheel(wheel_sweep_of(data), gear, opts)
        return [np.append(np.asarray(res.theta, dtype=float), gear.grouser_height)], res
    from ..soiltests import fit_soil_test

    test_fit = fit_soil_test(data)
    starts = []
    if test_fit.covariance is not None:  # every parameter identified
        vals = test_fit.covariance.values
        th = _default8()
        if spec.kind == "plate":
            th[3:6] = vals
        else:
            th[0:3] = vals
        starts.append(th)
    return starts, test_fit


def _default8(csk=None) -> np.ndarray:
    """A start 8-vector: c, phi, K from ``csk`` (default 500 Pa, 30 deg, 0.02 m), a middling Bekker soil."""
    c, phi, K = (500.0, math.radians(30.0), 0.02) if csk is None else (float(v) for v in csk)
    return np.array([c, phi, K, 0.0, 1.5e6, 1.0, 0.0, 0.0])


def _own_fits(datasets, gears, blocks, fixed, effects, bounds, settings) -> list[dict[str, Any]]:
    """Each data set's block solved alone (started from the library's own fit of its kind, or a grid)."""
    own = []
    for d, g, (spec, dp, official0) in zip(datasets, gears, blocks):
        starts7, official = _own_theta(d, g, spec, fixed, effects, bounds, settings, official0)
        if not starts7 or spec.kind in TRACK_KINDS:
            starts7 = starts7 + _default_starts(spec, dp)
        sf, p, lbx, ubx, _ = _problem([spec], [dp], fixed, bounds)
        sol = _solve([spec], sf, p, [_x_from_theta([t], [spec], sf, bounds) for t in starts7], lbx, ubx)
        own.append({"solution": sol, "shared_free": sf, "official": official, "theta8": _full8(sol, [spec])[0]})
    return own


def fit_datasets(
    datasets: Sequence,
    running_gear=None,
    *,
    labels: Sequence[str] | None = None,
    effects: Sequence[str] = (),
    fixed: Mapping[str, float] | None = None,
    bounds: WheelBounds = DEFAULT_WHEEL_BOUNDS,
    settings: WheelSettings = DEFAULT_WHEEL_SETTINGS,
    free_grousers: Sequence[int] = (),
) -> JointFitResult:
    """Fit one soil shared by several data sets (wheel sweeps and bevameter tests).

    Parameters
    ----------
    datasets
        Two or more :class:`~soiltrack.soilmodel.wheel_sweep.WheelSweep` (or drawbar-pull
        SlipData with the load per row; with a tracked Vehicle a track sweep, weighted by its per-row std
        column as its single fit is, or a drive log), :class:`~soiltrack.soilmodel.ShearTest`,
        :class:`~soiltrack.soilmodel.bevameter_records.AnnulusTest` or
        :class:`~soiltrack.soilmodel.PlateTest`.
    running_gear
        One :class:`RigidWheel` for all wheel sweeps or one per data set (None for a bevameter test).
    labels
        Names of the data sets in the report (default their files).
    effects
        ``("slip_sinkage",)``: each wheel's own slip-sinkage coefficient (gear-specific) is fitted. With a
        tracked vehicle's data set (a track sweep, a drive log) any effect is refused, naming the data set
        and the effect: their blocks are the models without effects.
    fixed
        Soil parameters held (``{name: SI value}``, names of the wheel fit).
    bounds, settings
        The wheel fit's bounds and model settings (used by every block).
    free_grousers
        Indices of the wheel data sets whose grouser height is fitted (gear-specific, started from the
        wheel's ``grouser_height``, bounded by [0, 0.5 r]); the others hold their wheel's.

    Returns
    -------
    JointFitResult
        The joint soil with its intervals, each data set's own fit, and ``consistency``.
    """
    datasets = list(datasets)
    if len(datasets) < 2:
        raise DataError(f"a joint fit needs at least two data sets, got {len(datasets)}")
    fixed = dict(fixed or {})
    effects = tuple(effects)
    gears = _gears(datasets, running_gear)
    labels = (
        list(labels)
        if labels is not None
        else [getattr(d, "source", f"data set {k + 1}") for k, d in enumerate(datasets)]
    )
    _refuse_track_effects(datasets, gears, labels, effects)
    WheelFitOptions(fixed=fixed, effects=effects, bounds=bounds, settings=settings)  # checks names and values
    t0 = time.perf_counter()
    free_h = set(int(k) for k in free_grousers)
    bad = sorted(k for k in free_h if not (0 <= k < len(datasets)) or not isinstance(gears[k], RigidWheel))
    if bad:
        raise DataError(f"free_grousers: data set(s) {bad} are not wheel sweeps of this fit (0-based indices)")
    blocks = [_as_block(d, g, settings, effects, k in free_h) for k, (d, g) in enumerate(zip(datasets, gears))]
    specs = [b[0] for b in blocks]
    own = _own_fits(datasets, gears, blocks, fixed, effects, bounds, settings)
    shared_free, p, lbx, ubx, _ = _problem(specs, [b[1] for b in blocks], fixed, bounds)
    starts = _joint_starts(own, specs, shared_free, bounds)
    joint = _solve(specs, shared_free, p, starts, lbx, ubx)
    return build_joint_result(
        leave_one_out=_leave_one_out(own, specs, [b[1] for b in blocks], joint, fixed, bounds),
        labels=labels,
        datasets=datasets,
        gears=gears,
        specs=specs,
        own=own,
        joint=joint,
        shared_free=shared_free,
        theta8=_full8(joint, specs),
        fixed=fixed,
        bounds=bounds,
        solve_time_s=time.perf_counter() - t0,
    )


def _refuse_track_effects(datasets, gears, labels, effects: tuple[str, ...]) -> None:
    """Effects with a tracked vehicle's data set are refused, naming the data set and the effects: the joint
    fit's track and drive-log blocks are the models without effects (never silently dropped)."""
    if not effects:
        return
    for d, g, lab in zip(datasets, gears, labels):
        if isinstance(g, Vehicle) or isinstance(d, DriveLog):
            kind = "drive log" if isinstance(d, DriveLog) else "track sweep"
            raise DataError(
                f"effect(s) {', '.join(map(repr, effects))} with the {kind} {lab!r}: a joint fit has no effects for "
                "a tracked vehicle's data (its block is the model without them, and an effect of the wheels only "
                "would leave the track's unmodelled); fit it alone with its effects (soiltrack.identify.fit(data, "
                "vehicle, effects=[...]), `soiltrack fit FILE --vehicle V --effect NAME`) or drop the effect",
                file=getattr(d, "source", None),
            )


def _lr_p(own, sol) -> float | None:
    """p-value of the likelihood-ratio test of the joint solution ``sol`` against the own fits ``own``."""
    from ..estimates.distributions import chi2_sf

    stat = 2 * sum(float(sol["f_blocks"][d]) - float(o["solution"]["f_blocks"][0]) for d, o in enumerate(own))
    dof = int(sum(o["solution"]["rank"] for o in own) - sol["rank"])
    if not (math.isfinite(stat) and dof > 0 and sol["converged"]):
        return None
    return float(chi2_sf(max(stat, 0.0), dof))


def _leave_one_out(own, specs, data_p, joint, fixed, bounds) -> list[float | None] | None:
    """Where one soil is refused and there are three or more data sets: per data set the test's p-value of
    the others (each such joint solved again, started from the others' own fits); None otherwise."""
    from ..outcome import OUTCOME_SETTINGS

    p_all = _lr_p(own, joint)
    if len(specs) < 3 or p_all is None or p_all >= OUTCOME_SETTINGS.lack_of_fit_level:
        return None
    out: list[float | None] = []
    for d in range(len(specs)):
        keep = [e for e in range(len(specs)) if e != d]
        sp, ow = [specs[e] for e in keep], [own[e] for e in keep]
        sf, p, lbx, ubx, _ = _problem(sp, [data_p[e] for e in keep], fixed, bounds)
        sol = _solve(sp, sf, p, _joint_starts(ow, sp, sf, bounds), lbx, ubx)
        out.append(_lr_p(ow, sol))
    return out


def _full8(sol, specs) -> list[np.ndarray]:
    """Each block's 8-vector (7 wheel parameters, grouser height) at a solution (held values where not free)."""
    th = sol["theta"]
    return [
        np.concatenate([th[:N_SHARED], th[N_SHARED + N_SPECIFIC * d : N_SHARED + N_SPECIFIC * (d + 1)]])
        for d in range(len(specs))
    ]


def _joint_starts(own, specs, shared_free, bounds) -> list[np.ndarray]:
    """One start per data set: its own fit for what it touches, the other parameters from the first data set
    that touches them, every block's own gear-specific value."""
    out = []
    for d, spec in enumerate(specs):
        base = own[d]["theta8"].copy()
        touch = np.array(block_touches(spec))
        for e, other in enumerate(specs):
            t_o = np.array(block_touches(other))
            fill = ~touch & t_o
            base[:N_SHARED][fill] = own[e]["theta8"][:N_SHARED][fill]
            touch |= t_o
        th8s = [np.concatenate([base[:N_SHARED], own[e]["theta8"][N_SHARED:]]) for e in range(len(specs))]
        out.append(_x_from_theta(th8s, specs, shared_free, bounds))
    return out


_ = WHEEL_PARAMETERS  # the vector order every 7-vector here follows


def fit_joint_call(datasets, running_gear, *, model: str, bounds, effects, fixed, **options) -> JointFitResult:
    """:func:`soiltrack.identify.fit` on a list: the keywords that apply handed to :func:`fit_datasets`."""
    kw: dict[str, Any] = {}
    for name in ("labels", "free_grousers"):
        if name in options:
            kw[name] = options.pop(name)
    if "wheel_settings" in options:  # the wheel model's settings (fit's own ``settings`` are a track's)
        kw["settings"] = options.pop("wheel_settings")
    if options:
        raise DataError(f"fit: option(s) {', '.join(map(repr, sorted(options)))} do not apply to a joint fit")
    held = dict(fixed or {})
    if model == "cohesion-free":
        held.setdefault("cohesion", 0.0)
    if bounds is not None:
        kw["bounds"] = bounds
    return fit_datasets(datasets, running_gear, effects=tuple(effects or ()), fixed=held, **kw)
