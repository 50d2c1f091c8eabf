"""Soil uncertainty for planning, from a :class:`~soiltrack.identify.FitResult`, its JSON, or an on-line estimate.

The fit's Gaussian (linearised) uncertainty is carried over what the data determine:

``"parameters"``
    c, phi, K identified (several normal loads) - or phi, K for the cohesion-free model:
    ``q = [c, phi, K]`` (or ``[phi, K]``) with their covariance.
``"ridge"``
    Full model at ONE normal load W0: c and phi are not separable, only
    ``F_max(W0) = A c + W0 tan(phi)`` and K are: ``q = [F_max(W0), K]``. At another normal
    load N the soil limit is ``F_max(N) = F_max(W0) - (W0 - N) tan(phi)``, which depends on
    where on the ridge the soil is. :meth:`SoilUncertainty.soils_at` takes the WORST point of
    the ridge inside the bounds (largest phi when N < W0, e.g. on a grade; smallest when
    N > W0, a payload) for every value of F_max: a conservative answer, never a ridge point
    presented as known. At N = W0 the answer does not depend on phi at all.

An on-line estimate (what ``soiltrack.identify.OnlineEstimator`` gives after each update, or any
object with the attributes of :data:`ESTIMATE_FIELDS`) carries ``F_max`` at its normal load and
``K`` with their 2 x 2 covariance: the ridge above, with that load as W0
(:func:`uncertainty_from_estimate`).

Samples are drawn from the Gaussian and clipped to the fit's bounds (the physically admissible
box); the delta method uses the same mapping, differentiated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..soilmodel import PRACTICAL_BOUNDS, DataError, Soil, SoilBounds, Vehicle, format_force
from ..soilmodel.jsonread import load_json_file
from .fit_json_checks import check_fit_numbers
from .fit_vehicle import FitContext, check_fit_vehicle, read_fit_context

__all__ = [
    "SoilUncertainty",
    "uncertainty_from_fit",
    "uncertainty_from_estimate",
    "is_online_estimate",
    "load_fit_json",
    "CHI2_95",
    "ESTIMATE_FIELDS",
]

#: 95 % quantiles of the chi-square distribution with 1, 2, 3 degrees of freedom.
CHI2_95 = {1: 3.841458820694124, 2: 5.991464547107979, 3: 7.814727903251179}
#: Public attributes of an on-line estimate (``soiltrack.identify.OnlineEstimator``'s per-update record):
#: ``max_thrust_N`` (F_max at ``normal_load_N``), ``shear_modulus_m``, ``covariance`` (2 x 2, SI, over
#: [max_thrust_N, shear_modulus_m]; ``None`` while not identifiable), ``normal_load_N``, ``identifiable``
#: (names of what the data identify so far), ``converged``.
ESTIMATE_FIELDS = ("max_thrust_N", "shear_modulus_m", "covariance", "normal_load_N", "identifiable", "converged")


@dataclass(frozen=True)
class SoilUncertainty:
    """A Gaussian over what the fit determines, and how to turn it into soils.

    Attributes
    ----------
    kind
        ``"parameters"`` or ``"ridge"`` (see the module docstring).
    model
        ``"full"`` or ``"cohesion-free"``.
    names
        Names of the entries of ``mean`` (``"cohesion"``, ``"friction_angle"``,
        ``"shear_modulus"`` in SI, or ``"F_max"`` in N).
    mean, cov
        Mean vector and covariance matrix (SI).
    fitted_load
        The fit's normal load W0, N (the first one when there are several).
    bounds
        Box of admissible c, phi, K (the fit's bounds, or the practical range for JSON input).
    source
        Where the covariance came from, in words.
    area
        Contact area A of both tracks of the fitted vehicle, m^2 (maps F_max to the ridge).
    success
        Whether the fit succeeded.
    context
        What the fit JSON says beyond the soil (outcome, running gear, effects); ``None`` for a
        ``FitResult`` or an on-line estimate.
    """

    kind: str
    model: str
    names: tuple[str, ...]
    mean: np.ndarray
    cov: np.ndarray
    fitted_load: float
    bounds: SoilBounds
    source: str
    area: float
    success: bool = True
    context: FitContext | None = None

    @property
    def dim(self) -> int:
        """Number of uncertain quantities."""
        return len(self.names)

    def sample(self, n: int, seed: int | None = 0) -> np.ndarray:
        """``n`` Gaussian samples of ``q``, shape ``(n, dim)`` (reproducible through ``seed``)."""
        rng = np.random.default_rng(seed)
        L = _psd_sqrt(self.cov)
        return self.mean + rng.standard_normal((n, self.dim)) @ L.T

    def soils_at(self, q: np.ndarray, normal_load: float) -> np.ndarray:
        """``[c, phi, K]`` rows (SI) for each row of ``q`` at normal load ``normal_load``, N.

        Clipped to the bounds. For the ridge, phi is the worst point of the ridge inside the
        bounds for that F_max (see the module docstring).
        """
        q = np.atleast_2d(np.asarray(q, dtype=float))
        lo, hi = self.bounds.lower, self.bounds.upper
        out = np.empty((q.shape[0], 3))
        if self.kind == "parameters":
            if self.model == "cohesion-free":
                out[:, 0] = 0.0
                out[:, 1:] = q
            else:
                out[:] = q
            out = np.clip(out, lo, hi)
            if self.model == "cohesion-free":
                out[:, 0] = 0.0
            return out
        # ridge: q = [F_max(W0), K]
        A = self.area
        W0 = self.fitted_load
        F0 = q[:, 0]
        # phi range along the ridge A c + W0 tan(phi) = F0 with c, phi inside the bounds
        p_lo = np.maximum(lo[1], np.arctan(np.maximum(F0 - A * hi[0], 0.0) / W0))
        p_hi = np.minimum(hi[1], np.arctan(np.maximum(F0 - A * lo[0], 0.0) / W0))
        p_hi = np.maximum(p_hi, p_lo)
        phi = p_hi if normal_load < W0 else p_lo  # the weaker soil at N (equal at N = W0)
        out[:, 1] = phi
        out[:, 0] = np.clip((F0 - W0 * np.tan(phi)) / A, lo[0], hi[0])
        out[:, 2] = np.clip(q[:, 1], lo[2], hi[2])
        return out

    def jacobian_at(self, normal_load: float) -> np.ndarray:
        """``d[c, phi, K]/dq`` at the mean (3 x dim): the chain rule of :meth:`soils_at`.

        Exact for ``"parameters"``; for the ridge the mapping is piecewise (the worst phi is set
        by a phi bound or by a cohesion bound, and then moves with F_max), so it is differentiated
        by central differences of a tenth of a standard deviation.
        """
        if self.kind == "parameters":
            if self.model == "cohesion-free":
                return np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
            return np.eye(3)
        J = np.empty((3, self.dim))
        for j in range(self.dim):
            h = 0.1 * math.sqrt(max(self.cov[j, j], 0.0)) or 1e-6 * max(abs(self.mean[j]), 1.0)
            e = np.zeros(self.dim)
            e[j] = h
            J[:, j] = (self.soils_at(self.mean + e, normal_load)[0] - self.soils_at(self.mean - e, normal_load)[0]) / (
                2 * h
            )
        return J

    def mean_soil(self, normal_load: float, name: str = "fitted soil") -> Soil:
        """The soil at the mean of ``q`` (worst ridge point at ``normal_load`` for the ridge)."""
        c, phi, K = self.soils_at(self.mean, normal_load)[0]
        return Soil(float(c), float(phi), float(K), name=name)

    def describe(self, normal_load: float) -> str:
        """What the uncertainty is and, for the ridge, how the margin at ``normal_load`` uses it."""
        if self.kind == "parameters":
            return f"soil uncertainty: {', '.join(self.names)} with their covariance ({self.source})"
        same = abs(normal_load - self.fitted_load) <= 1e-9 * self.fitted_load
        base = (
            f"c and phi were not separable (one normal load, W0 = {format_force(self.fitted_load)}): the fit "
            f"determines only F_max(W0) and K ({self.source})"
        )
        if same:
            return base + "; at this same load the margin depends on F_max only and is as tight as F_max"
        side = "largest" if normal_load < self.fitted_load else "smallest"
        return (
            base + f"; at N = {format_force(normal_load)} it depends on where on the ridge the soil is, so the "
            f"worst case over the ridge inside the bounds is used ({side} phi): the margin is conservative and "
            "wider than F_max alone would give"
        )


def _psd_sqrt(C: np.ndarray) -> np.ndarray:
    w, V = np.linalg.eigh(0.5 * (C + C.T))
    return V * np.sqrt(np.clip(w, 0.0, None))


def uncertainty_from_fit(fit: Any) -> SoilUncertainty:
    """Build a :class:`SoilUncertainty` from a ``FitResult`` (public attributes only).

    The fit's outcome, running gear (its vehicle) and effects are kept in ``context``, as for a fit
    JSON (:func:`load_fit_json`); planning with another vehicle than the fit's is said, not refused
    (in Python the caller passes the fit on purpose).

    Raises
    ------
    DataError
        The fit failed, or it carries no usable uncertainty.
    """
    u = _soil_of_fit(fit)
    return replace(u, context=_context_of_fit(fit))


def _context_of_fit(fit: Any) -> FitContext:
    """Outcome, running gear and effect values of a ``FitResult`` (public attributes only)."""
    v = fit.vehicle
    gear = {
        "kind": "track",
        "name": getattr(v, "name", "") or "fit's vehicle",
        "weight_N": float(v.weight),
        "contact_area_m2": float(v.contact_area),
        "track_length_m": float(v.track_length),
    }
    effects = {
        name: {p: float(e.value) for p, e in params.items() if e.value is not None}
        for name, params in (getattr(fit, "effects", None) or {}).items()
    }
    outcome: Any = getattr(fit, "outcome", None)
    outcome = {"converged": "usable", "not usable": "not_usable"}.get(outcome, outcome)
    return FitContext("the FitResult", outcome, None, gear, effects)


def _soil_of_fit(fit: Any) -> SoilUncertainty:
    """The soil's Gaussian of a ``FitResult``."""
    if not fit.success:
        raise DataError(f"the fit did not succeed ({fit.status}): no soil to plan with")
    loads = np.asarray(fit.normal_loads, dtype=float)
    W0 = float(loads[0])
    theta = np.asarray(fit.theta, dtype=float)
    bounds = fit.bounds
    cov = fit.covariance
    area = fit.vehicle.contact_area
    if cov is not None:
        # a fit with effects carries their parameters after the soil's: the soil's marginal covariance
        # is its leading 3 x 3 block (the effects are not planned with, only the soil)
        cov = np.asarray(cov, dtype=float)[: theta.size, : theta.size]
        if fit.model == "cohesion-free":
            return SoilUncertainty(
                "parameters",
                fit.model,
                ("friction_angle", "shear_modulus"),
                theta[1:].copy(),
                cov[1:, 1:].copy(),
                W0,
                bounds,
                "covariance of the fit",
                float(area),
            )
        return SoilUncertainty(
            "parameters",
            fit.model,
            ("cohesion", "friction_angle", "shear_modulus"),
            theta.copy(),
            cov.copy(),
            W0,
            bounds,
            "covariance of the fit",
            float(area),
        )
    combos = {cb.name: cb for cb in fit.combinations}
    fm = next((cb for n, cb in combos.items() if n.startswith("F_max@")), None)
    k = combos.get("K")
    if fm is None or k is None or fm.stderr is None or k.stderr is None:
        raise DataError(
            "the fit gives no standard errors for F_max and K (no residual degrees of freedom?): "
            "no uncertainty to plan with; pass a Soil instead"
        )
    rho = fit.identifiability.get("fmax_K_correlation", {}).get(f"{W0:.6g}") or 0.0
    return _ridge(
        fm.value,
        fm.stderr,
        k.value,
        k.stderr,
        rho,
        W0,
        bounds,
        fit.model,
        area,
        "F_max and K standard errors and their correlation from the fit",
    )


def is_online_estimate(obj: Any) -> bool:
    """Whether ``obj`` has every attribute of :data:`ESTIMATE_FIELDS` (duck-typed on-line estimate)."""
    return all(hasattr(obj, f) for f in ESTIMATE_FIELDS)


def uncertainty_from_estimate(
    estimate: Any, vehicle: Vehicle, bounds: SoilBounds = PRACTICAL_BOUNDS
) -> SoilUncertainty:
    """Build a :class:`SoilUncertainty` (ridge: F_max at the estimate's load and K) from an on-line estimate.

    Parameters
    ----------
    estimate
        Any object with the attributes of :data:`ESTIMATE_FIELDS` (e.g. the record of
        ``soiltrack.identify.OnlineEstimator`` after an update).
    vehicle
        The vehicle driving (its contact area maps F_max to the ridge of c and phi).
    bounds
        Box of admissible c, phi, K (default: the practical soil range).

    Returns
    -------
    SoilUncertainty

    Raises
    ------
    DataError
        The estimate has not converged, has no covariance yet (not identifiable), or a field is
        not a finite number / a 2 x 2 symmetric positive semi-definite matrix (named).
    """
    if not is_online_estimate(estimate):
        missing = [f for f in ESTIMATE_FIELDS if not hasattr(estimate, f)]
        raise DataError(f"an on-line estimate needs the attributes {list(ESTIMATE_FIELDS)}; missing {missing}")
    ident = tuple(str(x) for x in (estimate.identifiable or ()))
    if not bool(estimate.converged):
        raise DataError(
            "the on-line estimate has not converged: no soil to plan with yet (identifiable so far: "
            f"{', '.join(ident) or 'nothing'})"
        )
    if estimate.covariance is None:
        raise DataError(
            "the on-line estimate has no covariance: F_max and K are not identifiable yet (identifiable "
            f"so far: {', '.join(ident) or 'nothing'}); drive harder (larger slips) or pass a Soil"
        )
    F = _finite(estimate.max_thrust_N, "max_thrust_N", positive=True)
    K = _finite(estimate.shear_modulus_m, "shear_modulus_m", positive=True)
    W0 = _finite(estimate.normal_load_N, "normal_load_N", positive=True)
    try:
        cov = np.array(estimate.covariance, dtype=float)
    except (TypeError, ValueError):
        raise DataError(
            f"estimate field 'covariance' must be a 2 x 2 matrix of numbers, got {estimate.covariance!r}"
        ) from None
    if cov.shape != (2, 2) or not np.all(np.isfinite(cov)):
        raise DataError(
            f"estimate field 'covariance' must be a finite 2 x 2 matrix over [max_thrust_N, "
            f"shear_modulus_m], got shape {cov.shape}"
        )
    if (
        abs(cov[0, 1] - cov[1, 0]) > 1e-9 * math.sqrt(abs(cov[0, 0] * cov[1, 1]))
        or np.linalg.eigvalsh(0.5 * (cov + cov.T)).min() < -1e-12 * max(np.abs(np.diag(cov)).max(), 1e-300)
        or min(np.diag(cov)) < 0
    ):
        raise DataError("estimate field 'covariance' must be symmetric positive semi-definite")
    return SoilUncertainty(
        "ridge",
        "full",
        ("F_max", "shear_modulus"),
        np.array([F, K]),
        0.5 * (cov + cov.T),
        W0,
        bounds,
        "covariance of the on-line estimate over F_max and K",
        float(vehicle.contact_area),
    )


def _finite(x: Any, name: str, positive: bool = False) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise DataError(f"estimate field '{name}' must be a number, got {x!r}") from None
    if isinstance(x, bool) or not math.isfinite(v) or (positive and v <= 0):
        raise DataError(f"estimate field '{name}' must be a finite{' positive' if positive else ''} number, got {x!r}")
    return v


def _ridge(F, sF, K, sK, rho, W0, bounds, model, area, source) -> SoilUncertainty:
    cov = np.array([[sF * sF, rho * sF * sK], [rho * sF * sK, sK * sK]])
    return SoilUncertainty(
        "ridge", model, ("F_max", "shear_modulus"), np.array([F, K], dtype=float), cov, W0, bounds, source, float(area)
    )


def load_fit_json(path: str, vehicle: Vehicle, *, allow_other_vehicle: bool = False) -> SoilUncertainty:
    """Read what ``soiltrack fit --json`` printed and build a :class:`SoilUncertainty`.

    Uses the ``"covariance"`` block (``{"parameters", "matrix", "units": "SI"}``) when present;
    otherwise rebuilds the covariance from the standard errors and the correlation matrix (or,
    for c and phi at one load, from F_max's and K's standard errors and their correlation) and
    says so in ``source``. The JSON carries no bounds: the practical soil range is used. The
    fit's ``running_gear`` is checked against ``vehicle``
    (:func:`~soiltrack.planning.fit_vehicle.check_fit_vehicle`: refused beyond the tolerance unless
    ``allow_other_vehicle``); its contact area maps F_max to the ridge (the vehicle's when the JSON
    records none). Outcome, running gear and effects are kept in ``context``.

    Raises
    ------
    DataError
        Unreadable file, invalid JSON, missing or non-numeric field (named), failed fit.
    """
    obj = load_json_file(path, "fit JSON")  # encoding, depth, syntax (soilmodel.jsonread)
    src = str(path)
    if not isinstance(obj, dict):
        raise DataError("fit JSON must be an object (what `soiltrack fit --json` prints)", file=src)
    check_fit_numbers(obj, src)  # physical ranges, standard errors >= 0 (planning.fit_json_checks)
    for key in ("model", "success", "parameters"):
        if key not in obj:
            raise DataError(
                f"missing field '{key}' (expected what `soiltrack fit --json` prints)", file=src, column=key
            )
    if obj["success"] is not True:
        raise DataError("the fit did not succeed: no soil to plan with", file=src, column="success")
    model = obj["model"]
    if model not in ("full", "cohesion-free"):
        raise DataError(f"unknown model {model!r}", file=src, column="model")
    params = obj["parameters"]
    ctx = check_fit_vehicle(read_fit_context(obj, src), vehicle, allow_other=allow_other_vehicle)
    loads = obj.get("normal_loads_N") or [vehicle.weight]
    W0 = _num(loads[0], src, "normal_loads_N")
    bounds = PRACTICAL_BOUNDS
    gear_area = (ctx.running_gear or {}).get("contact_area_m2")
    area = (
        float(gear_area)
        if isinstance(gear_area, (int, float)) and not isinstance(gear_area, bool) and gear_area > 0
        else vehicle.contact_area
    )
    scale = {"cohesion_kpa": 1e3, "friction_angle_deg": math.pi / 180.0, "shear_modulus_m": 1.0}
    names_si = {"cohesion_kpa": "cohesion", "friction_angle_deg": "friction_angle", "shear_modulus_m": "shear_modulus"}

    def par(key):
        p = params.get(key)
        if not isinstance(p, dict):
            raise DataError(f"missing parameters.{key}", file=src, column=f"parameters.{key}")
        return p

    keys = ["friction_angle_deg", "shear_modulus_m"] if model == "cohesion-free" else list(scale)
    idents = [bool(par(k).get("identifiable")) for k in keys]
    if all(idents):
        mean = np.array([_num(par(k).get("value"), src, f"parameters.{k}.value") * scale[k] for k in keys])
        cov_block = obj.get("covariance")
        if isinstance(cov_block, dict) and cov_block.get("matrix") is not None:
            order = [str(n) for n in cov_block.get("parameters", [])]
            M = np.asarray(cov_block["matrix"], dtype=float)
            try:
                idx = [order.index(names_si[k]) if names_si[k] in order else order.index(k) for k in keys]
            except ValueError:
                raise DataError(
                    f"covariance.parameters {order} does not name {keys}", file=src, column="covariance"
                ) from None
            cov = M[np.ix_(idx, idx)]
            if cov_block.get("units", "SI") != "SI":
                raise DataError("covariance.units must be 'SI'", file=src, column="covariance.units")
            if not np.all(np.isfinite(cov)):
                raise DataError("covariance matrix has non-finite entries", file=src, column="covariance.matrix")
            source = "covariance matrix of the fit JSON"
        else:
            se = np.array([_num(par(k).get("stderr"), src, f"parameters.{k}.stderr") * scale[k] for k in keys])
            corr_full = (obj.get("identifiability") or {}).get("correlation")
            if corr_full is None:
                R = np.eye(len(keys))
                source = "standard errors of the fit JSON, correlations absent (taken as 0)"
            else:
                order = ["cohesion_kpa", "friction_angle_deg", "shear_modulus_m"]
                idx = [order.index(k) for k in keys]
                Rf = np.array([[np.nan if x is None else x for x in row] for row in corr_full], dtype=float)
                R = np.nan_to_num(Rf[np.ix_(idx, idx)], nan=0.0)
                source = "rebuilt from the standard errors and correlations of the fit JSON (no covariance block)"
            cov = R * np.outer(se, se)
        return SoilUncertainty(
            "parameters",
            model,
            tuple(names_si[k] for k in keys),
            mean,
            cov,
            W0,
            bounds,
            source,
            float(area),
            context=ctx,
        )
    return replace(_ridge_from_json(obj, src, W0, bounds, model, area), context=ctx)


def _ridge_from_json(obj: dict, src: str, W0: float, bounds, model: str, area: float) -> SoilUncertainty:
    """The ridge (full model, one load) of a fit JSON: F_max and K with their correlation."""
    combos = obj.get("combinations") or []
    fm = next((c for c in combos if isinstance(c, dict) and str(c.get("name", "")).startswith("F_max@")), None)
    kk = next((c for c in combos if isinstance(c, dict) and c.get("name") == "K"), None)
    if fm is None or kk is None:
        raise DataError(
            "c and phi are not identified and the JSON has no F_max / K combinations", file=src, column="combinations"
        )
    F, sF = (
        _num(fm.get("value"), src, "combinations.F_max.value"),
        _num(fm.get("stderr"), src, "combinations.F_max.stderr"),
    )
    K, sK = _num(kk.get("value"), src, "combinations.K.value"), _num(kk.get("stderr"), src, "combinations.K.stderr")
    rho = ((obj.get("identifiability") or {}).get("fmax_K_correlation") or {}).get(f"{W0:.6g}")
    rho = 0.0 if rho is None else float(rho)
    return _ridge(
        F,
        sF,
        K,
        sK,
        rho,
        W0,
        bounds,
        model,
        area,
        "F_max and K standard errors and their correlation from the fit JSON",
    )


def _num(x, src: str, field: str) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(float(x)):
        raise DataError(f"field '{field}' must be a finite number, got {x!r}", file=src, column=field)
    return float(x)
