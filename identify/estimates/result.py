"""The result record of an identification and its builders.

Every fitting method (IPOPT, the seed's Newton-Raphson and least squares, the compiled and batch
engines, the drive-log identification) ends in :func:`build_result` (or
:func:`build_results_batch`), which turns the optimum ``theta`` (and any effect parameters), the
Jacobian of the weighted residuals and the residuals into a :class:`FitResult`.

The record stores the optimum, residuals, solver status and the core statistics
(:mod:`.least_squares`); its views live with their concepts: :mod:`.views` (parameters,
effects, combinations, the soil), :mod:`.identifiability` (null space, ridge, confounding) and
:mod:`.report` (report, warnings, JSON). Value types: :mod:`.records`.
"""

from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, fields
from functools import cached_property
from typing import Any, Sequence

import numpy as np

from ...soilmodel.ridge import LOAD_RTOL, distinct_loads
from ...soilmodel.soil import PARAMETER_NAMES, SoilBounds
from ...soilmodel.traction import max_thrust_function
from ...soilmodel.vehicle import Vehicle
from .least_squares import RANK_TOL, WEAK_CORRELATION, core_stats, core_stats_one, quantile, WEAK_VIF  # noqa: F401
from .records import EDGE_UNITS, NOT_USABLE, Combination, ParameterEstimate, check_loads, finite_or_none  # noqa: F401
from .views import EstimateViews
from .identifiability import BOUND_TOL, NULL_TOL, IdentifiabilityViews  # noqa: F401
from .report import ReportViews, json_default  # noqa: F401

__all__ = [
    "FitResult",
    "ParameterEstimate",
    "Combination",
    "build_result",
    "build_results_batch",
    "RANK_TOL",
    "WEAK_CORRELATION",
]


@dataclass(frozen=True, eq=False)
class FitResult(EstimateViews, IdentifiabilityViews, ReportViews):
    """Outcome of a soil-parameter identification (in the spirit of scipy's ``OptimizeResult``).

    Eagerly stored: the optimum, residuals and the solver status with everything that decides
    it (finite numbers, the plausibility checks). The core statistics (``rank``, ``dof``,
    ``cost``, ``s2``, the SVD of the scaled Jacobian) and the views built on them
    (``parameters``, ``combinations``, ``identifiability``, ``covariance``, ``warnings``,
    ``soil``, ``report()``, ``to_dict()``) are computed on first access, from the stored
    Jacobian and residuals, and then kept: the same numbers whenever (and whether) they are read.
    A pickled result carries what was computed and computes the rest after unpickling.

    Attributes
    ----------
    data_kind : str
        ``"slip"`` or ``"drive"``.
    model, method : str
        ``"full"``/``"cohesion-free"``; ``"ipopt"``/``"newton"``/``"least-squares"``.
    theta : ndarray
        Optimiser's point ``[c (Pa), phi (rad), K (m)]`` (c = 0 for cohesion-free). Part of it
        may be an arbitrary ridge point: read ``parameters`` for what is identified.
    covariance : ndarray or None
        3x3 covariance of ``[c, phi, K]`` (SI; zero rows for fixed parameters), ``None`` when
        the problem is rank deficient or has no residual degrees of freedom.
    residuals : ndarray
        Model minus data in ``residual_unit``.
    weighted_residuals, jacobian : ndarray
        Residuals over sigma and their Jacobian w.r.t. theta (as passed in).
    rmse, cost : float
        Root-mean-square raw residual; ``0.5 * sum(weighted_residuals**2)``.
    status, success, message, iterations, solve_time
        Solver outcome as checked by soiltrack (not just the solver's word).
    n_samples : int
    normal_loads : ndarray
        Distinct normal loads, N.
    rank, dof : int
        Rank of the scaled Jacobian; residual degrees of freedom ``n - rank``.
    """

    # the fields: :class:`~.record_fields.RecordFields` (their one home)

    def __getstate__(self) -> dict:
        """Pickle only this fit's slice of batched core statistics (never computed ones: they follow)."""
        state = dict(self.__dict__)
        for key in ("_core", "_stats"):
            ck = state.get(key)
            if ck is not None and next(iter(ck[0].values())).shape[0] != 1:
                core, k = ck
                state[key] = ({name: v[k : k + 1] for name, v in core.items()}, 0)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)

    # ---------------------------------------------------------------------------- core statistics (lazy)
    @cached_property
    def _stats(self) -> tuple[dict, int]:
        """``(core statistics dict, index)``: the batch's, or computed now from this fit's Jacobian.

        Nothing that decides ``success`` or ``status`` reads it: a fit that is never inspected
        never pays for the SVD.
        """
        if self._core is not None:
            return self._core
        J = self.jacobian
        cols = J[:, self.free[0] :] if not self.effect_labels else J[:, list(self.free)]
        # a C-ordered copy: the same bytes (and so the same last digits) whatever the stored array's
        # layout, e.g. before and after pickling (the layout of a batch's stacked columns, too)
        return core_stats_one(np.ascontiguousarray(cols), self.weighted_residuals, self.sigma_known), 0

    @cached_property
    def rank(self) -> int:
        """Rank of the column-scaled Jacobian of the free parameters (identifiable directions)."""
        core, k = self._stats
        return int(core["rank"][k])

    @cached_property
    def dof(self) -> int:
        """Residual degrees of freedom ``n - rank``."""
        core, k = self._stats
        return int(core["dof"][k])

    @cached_property
    def cost(self) -> float:
        """``0.5 * sum(weighted_residuals**2)``."""
        core, k = self._stats
        return 0.5 * float(core["ssr"][k])

    @cached_property
    def s2(self) -> float | None:
        """Residual variance factor of the covariance (1 with known sigma), None when undefined."""
        core, k = self._stats
        s2 = float(core["s2"][k])
        return s2 if math.isfinite(s2) and self._finite else None

    # per-fit views of the (possibly batched) core statistics, taken on first use
    @cached_property
    def scaled_singular_values(self) -> np.ndarray:
        """Singular values of the column-scaled Jacobian, relative to the largest (descending)."""
        return self._stats[0]["S"][self._stats[1]]

    @cached_property
    def _V(self) -> np.ndarray:
        return self._stats[0]["V"][self._stats[1]]

    @cached_property
    def _D(self) -> np.ndarray:
        return self._stats[0]["D"][self._stats[1]]

    @cached_property
    def _Dok(self) -> np.ndarray:
        return self._stats[0]["Dok"][self._stats[1]]

    @cached_property
    def _Pinv(self) -> np.ndarray:
        return self._stats[0]["Pinv"][self._stats[1]]

    @cached_property
    def _nonnull(self) -> np.ndarray:
        return self._stats[0]["nonnull"][self._stats[1]]

    # ---------------------------------------------------------------------------- basics
    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Every column of :attr:`jacobian`: the soil's ``cohesion, friction_angle, shear_modulus``,
        then the effect parameters as ``"effect.param"`` (fixed ones included)."""
        return tuple(PARAMETER_NAMES) + tuple(self.effect_labels)

    @property
    def _n_all(self) -> int:
        return 3 + len(self.effect_labels)

    def _full(self, g) -> np.ndarray:
        """A gradient over the first entries of :attr:`parameter_names`, padded with zeros."""
        out = np.zeros(self._n_all)
        g = np.asarray(g, dtype=float)
        out[: g.size] = g
        return out

    def _effective_load(self, W: float) -> tuple[float, np.ndarray]:
        """Actual normal load ``N`` at nominal load ``W`` with the fitted effects, and ``dN/de``."""
        if not self.effect_labels:
            return W, np.zeros(0)
        from ...soilmodel.effects import normal_load_function

        N, dN = normal_load_function(self.vehicle, self.effect_structure)(W, np.asarray(self.effect_values, float))
        return float(N), np.asarray(dN, dtype=float).ravel()

    def _fmax(self, W: float) -> tuple[float, np.ndarray]:
        """``F_max = A c + N tan(phi)`` at nominal load ``W`` and its gradient over :attr:`parameter_names`."""
        N, dN = self._effective_load(W)
        fm, d = max_thrust_function(self.model)(self.theta[0], self.theta[1], N, self.vehicle.contact_area)
        d = np.asarray(d, dtype=float).ravel()  # dF_max / d[c, phi, N]
        g = self._full(d[:2])
        g[3:] = d[2] * dN
        return float(fm), g

    @property
    def n_parameters(self) -> int:
        """Number of free parameters of the model (3 full, 2 cohesion-free)."""
        return len(self.free)

    @property
    def quantile(self) -> float | None:
        """Two-sided 95 % quantile used (t with ``dof`` or normal), ``None`` if ``dof == 0``."""
        return quantile(self.dof, self.sigma_known)

    def predict(self, slip, normal_load=None, measured: str | None = None) -> np.ndarray:
        """What the fitted slip model predicts a rig reports at ``slip`` (N), e.g. for a fitted curve.

        ``predict(data)`` with a :class:`~soiltrack.soilmodel.SlipData` gives the model's value of
        the data's measured channel (tractive force or drawbar pull) at each of its rows, at
        each row's normal load: ``data.values - result.predict(data)`` are its residuals, e.g.
        on held-out rows for cross-validation.

        Parameters
        ----------
        slip : array_like or SlipData
            Slips (as the rig measures them), or data whose rows to predict (then
            ``normal_load`` and ``measured`` come from the data and must not be given).
        normal_load : float or array_like, optional
            Nominal normal load, N (default the vehicle's weight).
        measured : {"tractive_force", "drawbar_pull"}, optional
            What to predict (default: what the fitted data measured).

        Raises
        ------
        DataError
            Not a slip fit, a failed fit, or a load the fit does not determine (c-phi ridge).
        """
        from ...soilmodel.data import SlipData
        from ...soilmodel.errors import DataError

        if isinstance(slip, SlipData):
            if normal_load is not None or measured is not None:
                raise DataError(
                    "predict(data) takes the normal load and the measured channel from the data; "
                    "give slips to predict at another load or channel",
                    file=slip.source,
                )
            return slip.values - self.residuals_on(slip)[slip.channel]
        s = np.atleast_1d(np.asarray(slip, dtype=float))
        if self.data_kind != "slip":
            raise DataError("predict is for slip fits; use residuals_on for drive logs")
        m = measured or self.measured or "tractive_force"
        W = None if normal_load is None else np.broadcast_to(np.asarray(normal_load, dtype=float), s.shape)
        zeros = np.zeros(s.shape)
        probe = SlipData(
            slip=np.clip(s, 0.0, np.nextafter(1.0, 0.0)),
            normal_load=W,
            source="prediction grid",
            tractive_force=zeros if m == "tractive_force" else None,
            drawbar_pull=zeros if m == "drawbar_pull" else None,
        )
        return -next(iter(self.residuals_on(probe).values()))

    def residuals_on(self, data) -> dict[str, np.ndarray]:
        """Raw residuals ``measured - predicted`` of the fitted model on OTHER data of the same kind.

        For slip data the channel is ``"tractive_force_N"`` or ``"drawbar_pull_N"`` (what ``data``
        measured), in N. The prediction hook is :attr:`residual_model`, any object with a method
        ``residuals_on(result, data) -> dict[str, ndarray]`` (picklable); slip fits use
        :class:`~soiltrack.identify.sweep.model.SweepResiduals` when none is set.

        Raises
        ------
        DataError
            Wrong kind of data, a failed fit, or a prediction the fit does not determine (c and
            phi on their ridge, asked at another normal load).
        """
        model = self.residual_model
        if model is None:
            from ...soilmodel.errors import DataError

            raise DataError(f"residuals_on is not available for {self.data_kind} fits (no residual model)")
        return model.residuals_on(self, data)


# --------------------------------------------------------------------------------------------
# entry points
# --------------------------------------------------------------------------------------------
#: Fields of :class:`FitResult` in order, with their defaults (``_NO_DEFAULT`` for the required ones):
#: :func:`build_result` fills a copy (the same attributes, in the same order, as ``FitResult(...)``,
#: without the frozen dataclass's one ``object.__setattr__`` call per field).
_NO_DEFAULT = object()
_RESULT_DEFAULTS = {f.name: (f.default if f.default is not MISSING else _NO_DEFAULT) for f in fields(FitResult)}


def _free_indices(model: str) -> tuple[int, ...]:
    if model == "full":
        return (0, 1, 2)
    if model == "cohesion-free":
        return (1, 2)
    raise ValueError(f"unknown model {model!r}")


_distinct_loads = distinct_loads


def _all_finite(x: np.ndarray) -> bool:
    """Whether every entry is finite (``np.isfinite(x).all()``, counted without a ufunc reduction)."""
    return np.count_nonzero(np.isfinite(x)) == x.size


def _finite_values(x: np.ndarray) -> bool:
    """:func:`_all_finite` of a short array (theta: three numbers) without numpy calls."""
    return all(map(math.isfinite, x.tolist())) if x.ndim == 1 else _all_finite(x)


def build_result(
    *,
    data_kind: str,
    model: str,
    method: str,
    theta: np.ndarray,
    jacobian: np.ndarray,
    weighted_residuals: np.ndarray,
    residuals: np.ndarray,
    residual_unit: str,
    n_samples: int,
    normal_loads: np.ndarray,
    vehicle: Vehicle,
    bounds: SoilBounds,
    status: str,
    success: bool,
    message: str,
    iterations: int,
    solve_time: float,
    sigma_known: bool = False,
    warnings: Sequence[str] = (),
    extra: dict | None = None,
    effect_labels: Sequence[str] = (),
    effect_values=None,
    effect_bounds: Sequence = (),
    effect_units: Sequence[str] = (),
    effect_structure=None,
    fixed_labels: Sequence[str] = (),
    measured: str | None = None,
    residual_model=None,
    plausibility: tuple[tuple[str, ...], bool] | None = None,
) -> FitResult:
    """Build a :class:`FitResult` from an optimum and its Jacobian (shared by all fitting methods).

    Parameters
    ----------
    data_kind : {"slip", "drive"}
    model : {"full", "cohesion-free"}
    method : {"ipopt", "newton", "least-squares"}
    theta : ndarray, shape (3,)
        ``[c (Pa), phi (rad), K (m)]``; c = 0 (fixed) for the cohesion-free model.
    jacobian : ndarray, shape (n_res, 3)
        d(weighted residuals)/d theta (cohesion column ignored for the cohesion-free model).
    weighted_residuals : ndarray, shape (n_res,)
        Residuals over sigma (dimensionless).
    residuals : ndarray, shape (n_res,)
        Raw residuals (model - data) in ``residual_unit``, for RMSE and the report.
    residual_unit : str
        ``"N"`` for slip data, e.g. ``"rad/s"`` for drive logs.
    n_samples : int
        Number of data samples.
    normal_loads : ndarray
        Normal loads in the data (N); duplicates are removed.
    vehicle, bounds
        Vehicle used and the bounds of the fit.
    status, success, message, iterations, solve_time
        Solver outcome, already checked by the caller; non-finite numbers force ``success=False``.
    sigma_known : bool
        If false, the covariance is scaled by ``s^2 = SSR / (n - rank)`` and intervals use Student t.
    warnings : sequence of str
        Extra warnings from the caller.
    extra : dict, optional
        Anything else worth keeping (serialised under ``"extra"`` in JSON).
    effect_labels, effect_values, effect_bounds, effect_units, effect_structure
        Effect parameters fitted with the soil: labels ``"effect.param"`` (Jacobian columns 3...),
        values (SI), physical ranges ``(lo, hi)``, units, and the ``EffectSet`` of which effects
        are on (integer parameters resolved).
    fixed_labels
        Effect parameters held at their value: their Jacobian column is kept (score tests) but
        they are not free.
    measured
        What slip data measured (``"tractive_force"`` / ``"drawbar_pull"``).
    residual_model
        Object with ``residuals_on(result, data) -> dict`` for :meth:`FitResult.residuals_on`.
    plausibility : (warnings, usable), optional, slip data only
        The verdict of the slip data's plausibility checks, run by the data kind
        (:func:`~soiltrack.identify.sweep.plausibility.slip_checks`): their warnings are added, and an
        answer they find not usable (a force scale no soil within the bounds gives, F_max fixed by a
        bound, residuals as large as the data, a gross outlier) has ``success=False``. Not given: only
        the rows' loads against the vehicle's weight (:func:`~.records.check_loads`).

    Returns
    -------
    FitResult
    """
    if data_kind not in ("slip", "drive"):
        raise ValueError(f"data_kind must be 'slip' or 'drive', got {data_kind!r}")
    theta, J, rw = _checked_arrays(theta, jacobian, weighted_residuals, len(effect_labels))
    if data_kind == "slip":
        if plausibility is None:  # no checks of the data: the loads against the vehicle all the same
            loads = check_loads(normal_loads, vehicle)
            plausibility = (tuple("NOT USABLE: " + f.message for f in loads), not loads)
        warnings, success, status, message = _with_plausibility(
            plausibility, (tuple(warnings), success, status, message)
        )
    free, effect_fields = _effect_fields(
        model, effect_labels, effect_values, effect_bounds, effect_units, effect_structure, fixed_labels
    )
    effect_fields.update(measured=measured, residual_model=residual_model)
    res = np.asarray(residuals, dtype=float)
    rmse, finite, success, status, warn = _finite_check(
        theta, res, rw, effect_fields.get("effect_values"), tuple(warnings), success, status
    )
    state = dict(_RESULT_DEFAULTS)  # every field (extra, the one with a factory, is always given)
    state.update(data_kind=data_kind, model=model, method=method, theta=theta, jacobian=J, weighted_residuals=rw)
    state.update(residuals=res, residual_unit=residual_unit, n_samples=int(n_samples), vehicle=vehicle, bounds=bounds)
    state.update(normal_loads=_distinct_loads(normal_loads), status=str(status), success=bool(success))
    state.update(message=str(message), iterations=int(iterations), solve_time=float(solve_time))
    state.update(sigma_known=bool(sigma_known), rmse=rmse, free=free, _finite=finite, input_warnings=warn)
    state.update(extra=dict(extra or {}), **effect_fields)
    obj = object.__new__(FitResult)
    obj.__dict__.update(state)
    return obj


_FIELD_NAMES: dict[type, tuple[str, ...]] = {}


def record_with(res: FitResult, **changes: Any) -> FitResult:
    """A new record: ``res``'s fields with ``changes`` (what ``dataclasses.replace`` gives, without the frozen
    ``__init__``'s one ``object.__setattr__`` per field); statistics computed on ``res`` are not carried over.

    Raises
    ------
    TypeError
        A name in ``changes`` that is not a field.
    """
    cls = type(res)
    names = _FIELD_NAMES.get(cls)
    if names is None:
        names = _FIELD_NAMES.setdefault(cls, tuple(f.name for f in fields(cls)))
    unknown = set(changes).difference(names)
    if unknown:
        raise TypeError(f"record_with: {sorted(unknown)} are not fields of {cls.__name__}")
    d = res.__dict__
    obj = object.__new__(cls)
    obj.__dict__.update({k: d[k] for k in names}, **changes)
    return obj


def _checked_arrays(theta, jacobian, weighted_residuals, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``theta`` (3,) as a float copy, the Jacobian and the weighted residuals; ValueError on a wrong shape."""
    if type(theta) is np.ndarray and theta.shape == (3,) and theta.dtype == np.float64:
        theta = theta.copy()
    else:
        theta = np.asarray(theta, dtype=float).reshape(3).copy()
    J = np.asarray(jacobian, dtype=float)
    rw = np.asarray(weighted_residuals, dtype=float).ravel()
    if J.ndim != 2 or J.shape[1] != 3 + m or J.shape[0] != rw.size:
        raise ValueError(f"jacobian must have shape (n_res, 3 + {m}) = ({rw.size}, {3 + m}), got {J.shape}")
    return theta, J, rw


def _with_plausibility(plausibility: tuple[tuple[str, ...], bool], verdict: tuple) -> tuple:
    """Slip data: the plausibility checks' warnings added; an answer they refuse is not a success.

    ``verdict = (warnings, success, status, message)`` as the solver left them; returns them updated.
    """
    warnings, success, status, message = verdict
    found, usable = plausibility
    warnings = tuple(warnings) + tuple(found)
    if not usable and success:
        success, status = False, f"{status} {NOT_USABLE}"
        message = f"{message}; the data or the answer fail the plausibility checks (see the warnings)"
    return warnings, success, status, message


def _effect_fields(
    model, effect_labels, effect_values, effect_bounds, effect_units, effect_structure, fixed_labels
) -> tuple[tuple[int, ...], dict[str, Any]]:
    """The free parameter indices (soil, then the effects not held) and the result's effect fields."""
    free = _free_indices(model)
    labels = tuple(effect_labels)
    m = len(labels)
    effect_fields: dict[str, Any] = {}
    if m:
        fixed_labels = tuple(fixed_labels)
        unknown = set(fixed_labels) - set(labels)
        if unknown:
            raise ValueError(f"fixed_labels {sorted(unknown)} are not effect parameters {labels}")
        free = free + tuple(3 + k for k, lab in enumerate(labels) if lab not in fixed_labels)
        effect_fields.update(
            effect_labels=labels,
            effect_values=np.asarray(effect_values, float).reshape(m).copy(),
            effect_bounds=tuple((float(a), float(b)) for a, b in effect_bounds),
            effect_units=tuple(effect_units),
            effect_structure=effect_structure,
            fixed_labels=fixed_labels,
        )
    return free, effect_fields


def _finite_check(theta, res, rw, ev, warnings: tuple, success: bool, status: str):
    """``(rmse, finite, success, status, warnings)``: non-finite numbers make no estimate, and say so."""
    rv = res.ravel()
    ss = float(np.dot(rv, rv))  # finite only if every residual is (squares cannot cancel an inf or a NaN)
    finite = (
        _finite_values(theta)
        and (math.isfinite(ss) or _all_finite(res))
        and _all_finite(rw)
        and (ev is None or _all_finite(ev))
    )
    warn = tuple(warnings)
    if not finite:
        success = False
        status = status if "non-finite" in status else f"{status} (non-finite numbers)"
        warn += ("the solver returned non-finite numbers; no estimate is given",)
    return (math.sqrt(ss / res.size) if res.size else math.nan), finite, success, status, warn


def build_results_batch(
    *,
    model: str,
    method: str,
    theta: np.ndarray,
    jacobian: np.ndarray,
    weighted_residuals: np.ndarray,
    residuals: np.ndarray,
    normal_loads: np.ndarray,
    vehicle: Vehicle,
    bounds: SoilBounds,
    status: Sequence[str],
    success: Sequence[bool],
    message: Sequence[str],
    iterations: Sequence[int],
    solve_time: Sequence[float],
    sigma_known: bool = False,
    extra: Sequence[dict] | None = None,
    warnings: Sequence[Sequence[str]] | None = None,
    measured: str | None = None,
    residual_model=None,
) -> list[FitResult]:
    """Vectorised :func:`build_result` for N same-size slip fits (stacked arrays, leading axis N).

    ``measured`` and ``residual_model`` (shared by the batch, as
    :meth:`~soiltrack.identify.sweep.problem.SlipProblem.result_kwargs` gives them) are recorded on
    every result.

    Same statistics as :func:`build_result` (one code path, :func:`core_stats`); the per-fit
    scalars are computed for all fits at once and the objects are filled directly, which keeps
    the cost per result at a few microseconds.
    """
    free = _free_indices(model)
    theta = np.asarray(theta, dtype=float)
    J = np.asarray(jacobian, dtype=float)
    rw = np.asarray(weighted_residuals, dtype=float)
    res = np.asarray(residuals, dtype=float)
    N, n = rw.shape
    core = core_stats(J[:, :, list(free)], rw, sigma_known)
    finite = np.all(np.isfinite(theta), axis=1) & np.all(np.isfinite(res), axis=1) & np.all(np.isfinite(rw), axis=1)
    rmse = np.sqrt(np.mean(res**2, axis=1))
    W = np.sort(np.asarray(normal_loads, dtype=float), axis=1)
    keep = np.concatenate([np.ones((N, 1), bool), np.diff(W, axis=1) > LOAD_RTOL * np.abs(W[:, 1:])], axis=1)
    single = keep.sum(axis=1) == 1
    # per-row views and Python scalars prepared in bulk (iteration over an array is a C loop)
    ok_l = (np.asarray(success, dtype=bool) & finite).tolist()
    fin_l = finite.tolist()
    loads_l = [W[k, :1] if single[k] else W[k][keep[k]] for k in range(N)] if not single.all() else list(W[:, :1])
    rows = zip(
        list(theta),
        list(J),
        list(rw),
        list(res),
        loads_l,
        ok_l,
        fin_l,
        status,
        message,
        np.asarray(iterations).tolist(),
        np.asarray(solve_time, dtype=float).tolist(),
        rmse.tolist(),
        range(N),
        extra if extra is not None else [None] * N,
    )
    out = []
    new = object.__new__
    sk = bool(sigma_known)
    nonfinite = ("the solver returned non-finite numbers; no estimate is given",)
    for th, Jk, rwk, rk, Wk, ok, fin, st, msg, it, stime, rm, k, ex in rows:
        obj = new(FitResult)
        obj.__dict__.update(
            data_kind="slip",
            model=model,
            method=method,
            theta=th,
            jacobian=Jk,
            weighted_residuals=rwk,
            residuals=rk,
            residual_unit="N",
            n_samples=n,
            normal_loads=Wk,
            vehicle=vehicle,
            bounds=bounds,
            status=str(st) if fin else f"{st} (non-finite numbers)",
            success=ok,
            message=str(msg),
            iterations=it,
            solve_time=stime,
            sigma_known=sk,
            rmse=rm,
            free=free,
            _core=(core, k),
            _finite=fin,
            input_warnings=(() if fin else nonfinite) + (tuple(warnings[k]) if warnings is not None else ()),
            extra=dict(ex) if ex else {},
            measured=measured,
            residual_model=residual_model,
        )
        out.append(obj)
    return out
