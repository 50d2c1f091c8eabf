"""Bounded IPOPT fit of the rigid wheel to a wheel sweep (:func:`fit_wheel`)."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Mapping

import casadi as ca
import numpy as np

from ...soilmodel.errors import DataError
from ...soilmodel.rigid_wheel import RigidWheel
from ...soilmodel.soil import Soil
from ...soilmodel.threadsafe import best_of_starts
from ...soilmodel.wheel import DEFAULT_WHEEL_SETTINGS, WheelSettings, evaluate, wheel_forces_function
from ...soilmodel.wheel_sweep import WheelSweep, check_sweep_for_wheel
from .problem import DEFAULT_WHEEL_BOUNDS, PARAMETER_SCALES, WHEEL_PARAMETERS, WheelBounds, wheel_solver
from .result import WheelFitResult, build_wheel_result

__all__ = [
    "fit_wheel",
    "WheelFitOptions",
    "soil_from_wheel_fit",
    "START_FRICTION_DEG",
    "START_SHEAR_MODULUS_M",
    "WHEEL_EFFECTS",
]

#: Friction angles (deg) of the multi-start grid; each start is one bounded IPOPT solve.
START_FRICTION_DEG = (20.0, 30.0, 38.0)
#: Shear moduli (m) of the multi-start grid.
START_SHEAR_MODULUS_M = (0.008, 0.025)
#: Cohesion (Pa) of every start (a small positive value, away from its bound).
START_COHESION_PA = 500.0
#: Bekker exponent of every start, and the share of k = k_c / b + k_phi started as k_c / b.
START_BEKKER_N = 1.0
START_KC_SHARE = 0.1
#: Starts keep this fraction of each free parameter's bound range away from its bounds.
START_BOUND_MARGIN = 1e-3
#: Bekker k = k_c / b + k_phi (N/m^(n+2)) of every start when no sinkage is measured (a loose sand's).
START_BEKKER_K = 1.5e6
#: Effects the wheel fit can add (each a parameter of :data:`WHEEL_PARAMETERS`, 0 when off).
WHEEL_EFFECTS = ("slip_sinkage",)


@dataclass(frozen=True)
class WheelFitOptions:
    """Typed options of :func:`fit_wheel`.

    Parameters
    ----------
    fixed
        Parameters held at a value, ``{name: SI value}`` with names of :data:`WHEEL_PARAMETERS`
        (``{"cohesion": 0.0}`` is the cohesion-free model; ``{"bekker_kc": ..., "bekker_kphi": ...,
        "bekker_n": ...}`` a known Bekker soil, e.g. a plate test's). Everything else is fitted: with
        a measured sinkage its balance with the load carries the Bekker parameters; without it they rest on
        the drawbar pull alone and the identifiability report says how little that pins down.
    effects
        Effects fitted with the soil: ``("slip_sinkage",)`` frees the slip-sinkage coefficient s
        (held at 0, the textbook wheel, otherwise).
    bounds
        :class:`WheelBounds` of the seven parameters.
    settings
        :class:`~soiltrack.soilmodel.wheel.WheelSettings` of the wheel model (c1, c2, nodes).
    start
        A warm start: all seven parameters (SI, in :data:`WHEEL_PARAMETERS` order), e.g. another fit's
        ``theta`` on nearly the same data. One solve from it (moved inside the bounds) replaces the
        multi-start grid; when it does not converge, the grid is solved as without it.
    """

    fixed: Mapping[str, float] = field(default_factory=dict)
    effects: tuple[str, ...] = ()
    bounds: WheelBounds = DEFAULT_WHEEL_BOUNDS
    settings: WheelSettings = DEFAULT_WHEEL_SETTINGS
    start: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        for e in self.effects:
            if e not in WHEEL_EFFECTS:
                raise DataError(f"unknown wheel effect {e!r}; the wheel model has {list(WHEEL_EFFECTS)}")
        for name, v in self.fixed.items():
            if name not in WHEEL_PARAMETERS:
                raise DataError(
                    f"unknown wheel parameter {name!r} to hold fixed; expected one of {list(WHEEL_PARAMETERS)}"
                )
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise DataError(f"fixed value of {name} must be a finite number, got {v!r}")
            lo, hi = (
                self.bounds.lower[WHEEL_PARAMETERS.index(name)],
                self.bounds.upper[WHEEL_PARAMETERS.index(name)],
            )
            if not lo <= v <= hi:
                raise DataError(f"fixed value of {name} ({v:.6g} SI) lies outside its bounds [{lo:.6g}, {hi:.6g}]")
        if self.start is not None:
            st = np.asarray(self.start, dtype=float).ravel()
            if st.size != len(WHEEL_PARAMETERS) or not np.all(np.isfinite(st)):
                raise DataError(
                    f"start must be {len(WHEEL_PARAMETERS)} finite numbers ({', '.join(WHEEL_PARAMETERS)}, SI), "
                    f"got {self.start!r}"
                )


def _starts(
    data: WheelSweep, wheel: RigidWheel, free: np.ndarray, fixed: np.ndarray, opts: WheelFitOptions
) -> list[np.ndarray]:
    """Start points (SI, all six parameters) of the multi-start grid."""
    starts = []
    for phi in START_FRICTION_DEG:
        for K in START_SHEAR_MODULUS_M:
            th = fixed.copy()
            for k, v in ((0, START_COHESION_PA), (1, math.radians(phi)), (2, K), (5, START_BEKKER_N)):
                if free[k]:
                    th[k] = v
            if free[3] or free[4]:
                kc, kphi = th[3], th[4]
                th[3], th[4] = 0.0, 1.0
                # the load scales with k at fixed n and sinkage: one evaluation at k = 1 sets it
                k1 = _unit_load_scale(data, wheel, th, opts) if data.has_sinkage else START_BEKKER_K
                th[3] = START_KC_SHARE * k1 * wheel.width if free[3] else kc
                th[4] = max(k1 - th[3] / wheel.width, 0.0) if free[4] else kphi
            lo, hi = np.array(opts.bounds.lower), np.array(opts.bounds.upper)
            inner = np.clip(th, lo + START_BOUND_MARGIN * (hi - lo), hi - START_BOUND_MARGIN * (hi - lo))
            starts.append(np.where(free, inner, th))
    return starts


def _unit_load_scale(data: WheelSweep, wheel: RigidWheel, th: np.ndarray, opts: "WheelFitOptions") -> float:
    """k (N/m^(n+2)) at which the modelled load matches the measured one in the median (sinkage measured)."""
    fn = wheel_forces_function(wheel.radius, wheel.width, wheel.grouser_height, opts.settings)
    # at k = 1 and c = 0 the vertical force is proportional to k
    _, w1, _ = evaluate(fn, data.slip, data.sinkage, 0.0, th[1], th[2], 0.0, 1.0, th[5], 0.0)
    return float(np.median(data.normal_load / np.maximum(w1, 1e-300)))


def _p(data: WheelSweep, th: np.ndarray) -> np.ndarray:
    z = data.sinkage if data.sinkage is not None else np.zeros(data.n_samples)
    torque = []
    if data.torque is not None:  # the torque and its rows' weights (1 / relative standard deviation)
        sd = data.torque_std
        w = np.ones(data.n_samples) if sd is None else float(np.exp(np.mean(np.log(sd)))) / sd
        torque = [data.torque, w]
    return np.concatenate([data.slip, z, data.normal_load, data.drawbar_pull, *torque, th])


def _solve_starts(
    solver: ca.Function, starts: list[np.ndarray], free: np.ndarray, p: np.ndarray, lbx: np.ndarray, ubx: np.ndarray
) -> tuple[tuple, int]:
    """Solve from every start (SI, all parameters): :func:`~soiltrack.soilmodel.threadsafe.best_of_starts`."""
    return best_of_starts(solver, [(th0 / PARAMETER_SCALES)[free] for th0 in starts], p=p, lbx=lbx, ubx=ubx)


def fit_wheel(data: WheelSweep, wheel: RigidWheel, options: WheelFitOptions = WheelFitOptions()) -> WheelFitResult:
    """Identify c, phi, K (and the Bekker k_c, k_phi, n) from a wheel sweep with bounded IPOPT.

    Every start of a small grid (:data:`START_FRICTION_DEG` x :data:`START_SHEAR_MODULUS_M`) is
    solved (or one warm start, :attr:`WheelFitOptions.start`, the grid only when it fails); the best
    converged solve is the answer. The result says whether it converged, which
    parameters sit on a bound and what the data identify (from the Jacobian's rank and null space).
    """
    if not isinstance(data, WheelSweep):
        raise DataError(f"fit_wheel takes a WheelSweep, got {type(data).__name__}")
    check_sweep_for_wheel(data, wheel.radius)  # sinkage beyond the radius, a pull against the slip
    st = options.settings
    if np.any(data.slip < 0) and not st.c1 - st.c2 > 0:
        raise DataError(
            f"skid rows need theta_m = (c1 + c2 i) theta_1 inside the arc down to i = -1: c1 > c2, got c1 = {st.c1}, "
            f"c2 = {st.c2}",
            file=data.source,
        )
    sink = data.has_sinkage
    free = np.array(
        [
            name not in options.fixed and (name not in WHEEL_EFFECTS or name in options.effects)
            for name in WHEEL_PARAMETERS
        ]
    )
    fixed = np.array([float(options.fixed.get(name, 0.0)) for name in WHEEL_PARAMETERS])
    nf = int(free.sum())
    if data.n_samples * (2 if sink else 1) <= nf:
        raise DataError(f"{data.n_samples} rows cannot carry {nf} free parameters", file=data.source)
    t0 = time.perf_counter()
    solver, resid = wheel_solver(
        wheel, options.settings, data.n_samples, sink, tuple(bool(f) for f in free), data.has_torque
    )
    lo, hi = np.array(options.bounds.lower), np.array(options.bounds.upper)
    lbx, ubx = (lo / PARAMETER_SCALES)[free], (hi / PARAMETER_SCALES)[free]
    p = _p(data, np.where(free, 0.0, fixed))
    starts: list[np.ndarray] = []
    best, n_ok = None, 0
    if options.start is not None:  # one warm solve, moved inside the bounds as the grid's starts are
        margin = START_BOUND_MARGIN * (hi - lo)
        starts = [np.where(free, np.clip(np.asarray(options.start, dtype=float), lo + margin, hi - margin), fixed)]
        best, n_ok = _solve_starts(solver, starts, free, p, lbx, ubx)
    if best is None or best[0]:  # no warm start, or it did not converge: the grid
        grid = _starts(data, wheel, free, fixed, options)
        cand, k = _solve_starts(solver, grid, free, p, lbx, ubx)
        starts += grid
        n_ok += k
        best = cand if best is None or cand[:2] < best[:2] else best
    failed, f, x, status, iters = best
    r_dp, r_w, J_dp, J_w, th, r_t, J_t = (np.asarray(v, dtype=float) for v in resid(x, p))
    torque = {"residual_torque": r_t.ravel(), "jac_torque": J_t} if data.has_torque else {}
    return build_wheel_result(
        **torque,
        data=data,
        wheel=wheel,
        options=options,
        free=free,
        theta=th.ravel(),
        residual_dp=r_dp.ravel(),
        residual_z=r_w.ravel(),
        jac_dp=J_dp,
        jac_z=J_w,
        converged=not failed,
        status=status,
        iterations=iters,
        starts=len(starts),
        starts_converged=n_ok,
        solve_time_s=time.perf_counter() - t0,
    )


def soil_from_wheel_fit(result: WheelFitResult) -> Soil:
    """The identified soil as a :class:`~soiltrack.soilmodel.Soil` (with its Bekker values)."""
    v = result.theta
    return Soil(
        cohesion=float(v[0]),
        friction_angle=float(v[1]),
        shear_modulus=float(v[2]),
        n=float(v[5]),
        k_c=float(v[3]),
        k_phi=float(v[4]),
        name="identified from a wheel sweep",
    )


#: The NLP parameter vector of a sweep (data, then the held values), public for the joint fit.
sweep_parameters = _p
