"""The result of an identification: estimates, uncertainty and what the data can pin down.

Every fitting method (IPOPT, the seed's Newton-Raphson and least squares, the drive-log
identification) ends in :func:`build_result`, which turns the optimum ``theta``, the
Jacobian of the weighted residuals and the residuals into a :class:`FitResult`.

Statistics (local, linearised at the optimum)
---------------------------------------------
* Columns of the Jacobian of the free parameters are scaled to unit norm (scale-free), and the
  scaled matrix is decomposed (QR then SVD). Singular values below ``RANK_TOL`` times the
  largest are structural zeros: the rank is the number of identifiable directions. A
  parameter is *identifiable* when it has no component in the null space.
* Covariance: ``s^2 (J^T J)^+`` (pseudo-inverse over the identifiable subspace). When
  ``sigma_known`` is false, ``s^2 = SSR / (n - rank)`` with ``SSR`` the sum of squared weighted
  residuals, and 95 % intervals use the Student t quantile with ``n - rank`` degrees of
  freedom; when true, ``s^2 = 1`` and the normal quantile. With ``n - rank = 0`` and unknown
  sigma no standard error exists (``None``, said in the text).
* A parameter or combination is *weakly identifiable* when its variance inflation in the
  column-scaled problem exceeds ``1 / (1 - 0.99^2)`` (multiple correlation with the other
  directions above 0.99).
* Identifiable combinations (``A c + W tan(phi)`` at each distinct normal load, ``K``,
  ``K / l``, the initial slope ``F_max l / (2 K)``) get a standard error when their gradient
  lies in the row space of the Jacobian (estimable); otherwise ``None``.
* Parameters on a bound: the linearised standard error ignores the bound (it is the local
  curvature of the cost); the 95 % interval is clipped to the bounds and a note says so.
  :func:`~soiltrack.identify.profile_likelihood` gives the honest interval there.
* c and phi not separable (full model, one normal load): both are marked not identifiable,
  their ``value`` is ``None`` and their ``ci95`` is the range they take along the
  bounds-feasible ridge ``A c + W tan(phi) = F_max`` for ``F_max`` within its 95 % interval.
  ``FitResult.soil`` is then ``None``; the optimiser's arbitrary ridge point is available
  as ``FitResult.ridge_point`` (a :class:`Soil` whose name says it is not an estimate).
* A failed fit (solver status, non-finite numbers, singular Newton system, ...) carries no
  estimate: parameter values, standard errors and intervals are ``None``, ``combinations``
  is empty and ``soil`` is ``None``; the last iterate stays visible as ``ridge_value`` /
  ``ridge_point`` for diagnosis, labelled as such. Estimates of the unconstrained seed
  methods that fall outside the bounds are reported as ``outside_bounds`` (not clipped).
* JSON (``to_json``) never carries NaN or Infinity: unavailable numbers are ``null`` and the
  reason is in the ``note`` / ``warnings`` text. For drive logs ``rmse_N`` is ``null`` and
  ``rmse`` / ``residual_unit`` carry the residual size in its own unit.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Sequence

import numpy as np

from ..soilmodel.soil import PARAMETER_NAMES, Soil, SoilBounds
from ..soilmodel.vehicle import Vehicle
from .stats import norm_ppf, t_ppf

__all__ = ["FitResult", "ParameterEstimate", "Combination", "build_result", "RANK_TOL", "WEAK_CORRELATION"]

#: Relative singular value (column-scaled Jacobian) below which a direction is unidentifiable.
RANK_TOL = 1e-8
#: Multiple correlation above which a parameter or combination is called weakly identifiable.
WEAK_CORRELATION = 0.99
_WEAK_VIF = 1.0 / (1.0 - WEAK_CORRELATION ** 2)
#: Relative distance to a bound (fraction of the bound range) below which a parameter is on it.
BOUND_TOL = 1e-5
_NULL_TOL = 1e-4

_EDGE = {  # SI name -> (JSON key, edge unit, factor SI -> edge, label, SI unit)
    "cohesion": ("cohesion_kpa", "kPa", 1e-3, "cohesion c", "Pa"),
    "friction_angle": ("friction_angle_deg", "deg", 180.0 / math.pi, "friction angle phi", "rad"),
    "shear_modulus": ("shear_modulus_m", "m", 1.0, "shear modulus K", "m"),
}


def _f(x) -> float | None:
    """float or None for anything non-finite (JSON never carries NaN/Infinity)."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


@dataclass(frozen=True)
class ParameterEstimate:
    """One soil parameter, SI units.

    Attributes
    ----------
    name : str
        ``"cohesion"``, ``"friction_angle"`` or ``"shear_modulus"``.
    value : float or None
        Estimate (Pa, rad, m); ``None`` when the data do not identify it.
    stderr : float or None
        Linearised standard error; ``None`` when unavailable (reason in ``note``).
    ci95 : tuple of (float or None)
        95 % interval (clipped to the bounds; for a non-identifiable parameter, the range it can
        take while the fit stays within its uncertainty, or the bounds).
    identifiable, weakly_identifiable : bool
        Whether the data pin it down; weakly: correlation with other directions > 0.99.
    at_bound : bool
        Whether the estimate lies on a bound; ``bound_side`` is ``"lower"``/``"upper"``.
    fixed : bool
        Held fixed by the model (cohesion in the cohesion-free model), not estimated.
    ridge_value : float or None
        The optimiser's point, for diagnostics only when not identifiable (NOT an estimate).
    note : str
        Plain-words remarks.
    """

    name: str
    value: float | None
    stderr: float | None
    ci95: tuple[float | None, float | None]
    identifiable: bool
    weakly_identifiable: bool = False
    at_bound: bool = False
    bound_side: str | None = None
    fixed: bool = False
    ridge_value: float | None = None
    note: str = ""
    si_unit: str = ""
    correlated_with: str | None = None
    correlation: float | None = None

    @property
    def unit(self) -> str:
        """SI unit (``"Pa"``, ``"rad"``, ``"m"``; an effect parameter's own unit)."""
        return _EDGE[self.name][4] if self.name in _EDGE else self.si_unit

    @property
    def edge_unit(self) -> str:
        """Unit at the edges (``"kPa"``, ``"deg"``, ``"m"``; effect parameters: SI)."""
        return _EDGE[self.name][1] if self.name in _EDGE else self.si_unit

    def _edge(self, x):
        return None if x is None else x * (_EDGE[self.name][2] if self.name in _EDGE else 1.0)

    @property
    def edge_value(self) -> float | None:
        """Value in kPa / deg / m."""
        return self._edge(self.value)

    @property
    def edge_stderr(self) -> float | None:
        """Standard error in kPa / deg / m."""
        return self._edge(self.stderr)

    @property
    def edge_ci95(self) -> tuple[float | None, float | None]:
        """95 % interval in kPa / deg / m."""
        return (self._edge(self.ci95[0]), self._edge(self.ci95[1]))

    # convenience names terramechanics users reach for
    @property
    def value_kpa(self) -> float | None:
        """Value in kPa (cohesion)."""
        return None if self.value is None else self.value * 1e-3

    @property
    def value_deg(self) -> float | None:
        """Value in degrees (friction angle)."""
        return None if self.value is None else math.degrees(self.value)

    def to_dict(self) -> dict:
        """JSON-ready dict in edge units (kPa, deg, m); never NaN."""
        lo, hi = self.edge_ci95
        return {"value": _f(self.edge_value), "stderr": _f(self.edge_stderr), "ci95": [_f(lo), _f(hi)],
                "identifiable": bool(self.identifiable), "at_bound": bool(self.at_bound),
                "bound_side": self.bound_side, "weakly_identifiable": bool(self.weakly_identifiable),
                "fixed": bool(self.fixed), "ridge_value": _f(self._edge(self.ridge_value)), "note": self.note,
                **({} if self.name in _EDGE else {"unit": self.si_unit, "correlated_with": self.correlated_with,
                                                  "correlation": _f(self.correlation)})}


@dataclass(frozen=True)
class Combination:
    """An identifiable combination of the parameters, e.g. ``F_max = A c + W tan(phi)``.

    Attributes
    ----------
    name : str
        Machine-friendly name, e.g. ``"F_max@W=329000N"``, ``"K"``, ``"K/l"``.
    value : float
        Value in ``unit`` (SI).
    stderr : float or None
        Linearised standard error; ``None`` when not estimable or no degrees of freedom.
    ci95 : tuple
        95 % interval (``None`` ends when unavailable).
    unit, description : str
        SI unit and plain-words meaning.
    estimable : bool
        Whether the data determine it (its gradient lies in the Jacobian's row space).
    weakly_identifiable : bool
        Variance inflation above the 0.99-correlation level.
    """

    name: str
    value: float
    stderr: float | None
    ci95: tuple[float | None, float | None]
    unit: str
    description: str
    estimable: bool = True
    weakly_identifiable: bool = False

    def to_dict(self) -> dict:
        """JSON-ready dict (SI units as named); never NaN."""
        return {"name": self.name, "value": _f(self.value), "stderr": _f(self.stderr),
                "ci95": [_f(self.ci95[0]), _f(self.ci95[1])], "unit": self.unit,
                "description": self.description, "estimable": bool(self.estimable),
                "weakly_identifiable": bool(self.weakly_identifiable)}


# --------------------------------------------------------------------------------------------
# batched core statistics (one code path for a single fit and for fit_many)
# --------------------------------------------------------------------------------------------
def _core_stats(J: np.ndarray, rw: np.ndarray, free: np.ndarray, sigma_known: bool) -> dict[str, np.ndarray]:
    """Identifiability and covariance for a stack of fits.

    J: (N, n, p) Jacobian of weighted residuals w.r.t. the FREE parameters; rw: (N, n).
    Returns arrays, all per fit: D (N,p) column scales, S (N,p) relative singular values
    (descending, zeros padded), V (N,p,p) right singular vectors (columns), rank (N,),
    Pinv (N,p,p) = (Js^T Js)^+ in scaled coordinates, ssr (N,), dof (N,), s2 (N,).
    """
    N, n, p = J.shape
    D = np.sqrt(np.einsum("kij,kij->kj", J, J))
    ok = np.isfinite(D) & (D > 0)
    Dsafe = np.where(ok, D, 1.0)
    Js = np.where(ok[:, None, :], J / Dsafe[:, None, :], 0.0)
    Js = np.where(np.isfinite(Js), Js, 0.0)
    if n > p:
        R = np.linalg.qr(Js, mode="r")
    else:
        R = Js
    _, S, Vt = np.linalg.svd(R, full_matrices=True)
    if S.shape[1] < p:
        S = np.concatenate([S, np.zeros((N, p - S.shape[1]))], axis=1)
    smax = S[:, :1]
    Srel = np.where(smax > 0, S / np.where(smax > 0, smax, 1.0), 0.0)
    nonnull = Srel > RANK_TOL
    rank = nonnull.sum(axis=1)
    inv2 = np.where(nonnull, 1.0 / np.where(nonnull, S, 1.0) ** 2, 0.0)
    V = np.swapaxes(Vt, 1, 2)
    Pinv = np.einsum("kij,kj,klj->kil", V, inv2, V)
    rw = np.where(np.isfinite(rw), rw, np.nan)
    ssr = np.einsum("ki,ki->k", rw, rw)
    dof = n - rank
    if sigma_known:
        s2 = np.ones(N)
    else:
        s2 = np.where(dof > 0, ssr / np.maximum(dof, 1), np.nan)
    return {"D": Dsafe, "Dok": ok, "S": Srel, "V": V, "rank": rank, "Pinv": Pinv, "ssr": ssr, "dof": dof,
            "s2": s2, "nonnull": nonnull}


def _core_stats_one(J: np.ndarray, rw: np.ndarray, sigma_known: bool) -> dict[str, np.ndarray]:
    """:func:`_core_stats` for ONE fit (J: (n, p), rw: (n,)): the same quantities (leading axis
    of length 1) without the stacked-array bookkeeping, which dominates a single fit's
    result-building time. The singular values and right singular vectors come from one thin
    SVD of the column-scaled Jacobian (mathematically those of its R factor, which the batched
    path decomposes; both are backward stable, so they agree to rounding)."""
    n, p = J.shape
    D = np.sqrt(np.einsum("ij,ij->j", J, J))
    Dl = D.tolist()
    if all(d > 0 and math.isfinite(d) for d in Dl):  # finite column norms: J is finite
        ok = np.ones(p, dtype=bool)
        Dsafe = D
        Js = J / D
    else:
        ok = np.isfinite(D) & (D > 0)
        Dsafe = np.where(ok, D, 1.0)
        Js = np.where(ok[None, :], J / Dsafe, 0.0)
        Js = np.where(np.isfinite(Js), Js, 0.0)
    _, S, Vt = np.linalg.svd(Js, full_matrices=n < p)
    Sl = S.tolist() + [0.0] * (p - S.shape[0])
    smax = Sl[0]
    Srel = [s / smax for s in Sl] if smax > 0 else [0.0] * p
    nonnull = [s > RANK_TOL for s in Srel]
    rank = sum(nonnull)
    V = Vt.T
    Pinv = (V * np.array([1.0 / (s * s) if nn else 0.0 for s, nn in zip(Sl, nonnull)])) @ Vt
    ssr = float(rw @ rw)
    if not math.isfinite(ssr):  # the batched path maps non-finite residuals to NaN
        ssr = math.nan
    dof = n - rank
    s2 = 1.0 if sigma_known else (ssr / dof if dof > 0 else math.nan)
    return {"D": Dsafe[None], "Dok": ok[None], "S": np.array([Srel]), "V": V[None], "rank": np.array([rank]),
            "Pinv": Pinv[None], "ssr": np.array([ssr]), "dof": np.array([dof]), "s2": np.array([s2]),
            "nonnull": np.array([nonnull])}


def _quantile(dof: int, sigma_known: bool) -> float | None:
    if sigma_known:
        return norm_ppf(0.975)
    if dof <= 0:
        return None
    return t_ppf(0.975, float(dof))


# --------------------------------------------------------------------------------------------
# FitResult
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class FitResult:
    """Outcome of a soil-parameter identification (in the spirit of scipy's ``OptimizeResult``).

    Eagerly stored: the optimum, residuals, solver status and the linear-algebra core of the
    uncertainty analysis. Derived views (``parameters``, ``combinations``, ``identifiability``,
    ``warnings``, ``soil``, ``report()``, ``to_dict()``) are computed on first access.

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

    data_kind: str
    model: str
    method: str
    theta: np.ndarray
    jacobian: np.ndarray
    weighted_residuals: np.ndarray
    residuals: np.ndarray
    residual_unit: str
    n_samples: int
    normal_loads: np.ndarray
    vehicle: Vehicle
    bounds: SoilBounds
    status: str
    success: bool
    message: str
    iterations: int
    solve_time: float
    sigma_known: bool
    rmse: float
    cost: float
    rank: int
    dof: int
    s2: float | None
    free: tuple[int, ...]
    _core: tuple = field(repr=False)  # (batched core statistics dict, index of this fit)
    input_warnings: tuple[str, ...] = ()
    extra: dict = field(default_factory=dict)
    effect_labels: tuple[str, ...] = ()
    effect_values: Any = None
    effect_bounds: tuple = ()
    effect_units: tuple = ()
    effect_structure: Any = None
    fixed_labels: tuple[str, ...] = ()
    measured: str | None = None
    residual_model: Any = None

    def __getstate__(self) -> dict:
        """Pickle only this fit's slice of the (possibly batched) core statistics."""
        state = dict(self.__dict__)
        core, k = self._core
        if next(iter(core.values())).shape[0] != 1:
            state["_core"] = ({key: v[k:k + 1] for key, v in core.items()}, 0)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)

    # per-fit views of the (possibly batched) core statistics, taken on first use
    @cached_property
    def scaled_singular_values(self) -> np.ndarray:
        """Singular values of the column-scaled Jacobian, relative to the largest (descending)."""
        return self._core[0]["S"][self._core[1]]

    @cached_property
    def _V(self) -> np.ndarray:
        return self._core[0]["V"][self._core[1]]

    @cached_property
    def _D(self) -> np.ndarray:
        return self._core[0]["D"][self._core[1]]

    @cached_property
    def _Dok(self) -> np.ndarray:
        return self._core[0]["Dok"][self._core[1]]

    @cached_property
    def _Pinv(self) -> np.ndarray:
        return self._core[0]["Pinv"][self._core[1]]

    @cached_property
    def _nonnull(self) -> np.ndarray:
        return self._core[0]["nonnull"][self._core[1]]

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
        out[:g.size] = g
        return out

    def _effective_load(self, W: float) -> tuple[float, np.ndarray]:
        """Actual normal load ``N`` at nominal load ``W`` with the fitted effects, and ``dN/de``."""
        if not self.effect_labels:
            return W, np.zeros(0)
        from ..soilmodel.effects import normal_load_function
        N, dN = normal_load_function(self.vehicle, self.effect_structure)(W, np.asarray(self.effect_values, float))
        return float(N), np.asarray(dN, dtype=float).ravel()

    def _fmax(self, W: float) -> tuple[float, np.ndarray]:
        """``F_max = A c + N tan(phi)`` at nominal load ``W`` and its gradient over :attr:`parameter_names`."""
        c, phi = float(self.theta[0]), float(self.theta[1])
        A = self.vehicle.contact_area
        cf = self.model == "cohesion-free"
        N, dN = self._effective_load(W)
        t = math.tan(phi)
        fm = N * t + (0.0 if cf else A * c)
        g = self._full([0.0 if cf else A, N / math.cos(phi) ** 2, 0.0])
        g[3:] = t * dN
        return fm, g

    @property
    def n_parameters(self) -> int:
        """Number of free parameters of the model (3 full, 2 cohesion-free)."""
        return len(self.free)

    @property
    def quantile(self) -> float | None:
        """Two-sided 95 % quantile used (t with ``dof`` or normal), ``None`` if ``dof == 0``."""
        return _quantile(self.dof, self.sigma_known)

    @cached_property
    def _null(self) -> np.ndarray:
        """Null-space basis (scaled coordinates of the free parameters), shape (p, k)."""
        return self._V[:, ~self._nonnull]

    @cached_property
    def _identifiable_free(self) -> np.ndarray:
        null = self._null
        if null.shape[1] == 0:
            comp = np.zeros(len(self.free))
        else:
            comp = np.sqrt((null ** 2).sum(axis=1))
        return (comp < _NULL_TOL) & self._Dok

    @cached_property
    def _cov_free(self) -> np.ndarray | None:
        """Covariance of the free parameters in SI (pseudo-inverse), None without s^2."""
        if self.s2 is None or not math.isfinite(self.s2):
            return None
        D = self._D
        return self.s2 * self._Pinv / np.outer(D, D)

    @cached_property
    def covariance(self) -> np.ndarray | None:
        """Covariance of ``[c, phi, K]`` (SI); ``None`` if rank deficient or no dof."""
        C = self._cov_free
        if C is None or self.rank < len(self.free) or not np.all(np.isfinite(C)):
            return None
        out = np.zeros((self._n_all, self._n_all))
        idx = np.array(self.free)
        out[np.ix_(idx, idx)] = C
        return out

    @cached_property
    def correlation(self) -> np.ndarray | None:
        """Correlation matrix of ``[c, phi, K]`` (fixed parameters: zero rows, unit diagonal)."""
        C = self.covariance
        if C is None:
            return None
        d = np.sqrt(np.diag(C))
        with np.errstate(invalid="ignore", divide="ignore"):
            R = C / np.outer(np.where(d > 0, d, 1.0), np.where(d > 0, d, 1.0))
        np.fill_diagonal(R, 1.0)
        return R

    def _vif(self, g_scaled: np.ndarray) -> float:
        nrm = float(g_scaled @ g_scaled)
        return float(g_scaled @ self._Pinv @ g_scaled) / nrm if nrm > 0 else math.inf

    def _estimable(self, g_scaled: np.ndarray) -> bool:
        null = self._null
        nrm = float(np.linalg.norm(g_scaled))
        if nrm == 0:
            return True
        return null.shape[1] == 0 or float(np.linalg.norm(g_scaled @ null)) / nrm < _NULL_TOL

    def _combo_stderr(self, g_free: np.ndarray) -> tuple[float | None, bool, bool]:
        """(stderr, estimable, weak) of a linear functional with SI gradient g over free params."""
        g_s = g_free / self._D
        est = self._estimable(g_s)
        weak = est and self._vif(g_s) > _WEAK_VIF
        C = self._cov_free
        if not est or C is None:
            return None, est, weak
        var = float(g_free @ C @ g_free)
        return (math.sqrt(var) if var >= 0 and math.isfinite(var) else None), est, weak

    # ---------------------------------------------------------------------------- bounds
    @cached_property
    def _bound_flags(self) -> list[str | None]:
        lo, hi = self.bounds.lower, self.bounds.upper
        out: list[str | None] = []
        for j in range(3):
            if j not in self.free:
                out.append(None)
                continue
            tol = BOUND_TOL * (hi[j] - lo[j])
            if self.theta[j] < lo[j] - tol:
                out.append("below")
            elif self.theta[j] > hi[j] + tol:
                out.append("above")
            elif self.theta[j] <= lo[j] + tol:
                out.append("lower")
            elif self.theta[j] >= hi[j] - tol:
                out.append("upper")
            else:
                out.append(None)
        return out

    @property
    def active_bounds(self) -> dict[str, str]:
        """``{parameter name: "lower"|"upper"}`` for free parameters that ended on a bound."""
        return {n: p.bound_side for n, p in self.parameters.items() if p.at_bound and p.bound_side}

    @property
    def outside_bounds(self) -> dict[str, str]:
        """``{parameter name: "below"|"above"}`` for estimates outside the bounds (unconstrained methods)."""
        return {PARAMETER_NAMES[j]: s for j, s in enumerate(self._bound_flags) if s in ("below", "above")}

    # ---------------------------------------------------------------------------- ridge
    @cached_property
    def _cphi_ridge(self) -> bool:
        """Full model, c and phi both unidentifiable, one normal load: the classic ridge."""
        if self.model != "full" or len(self.normal_loads) != 1:
            return False
        ident = self._identifiable_free
        return not ident[0] and not ident[1]

    def _ridge_intervals(self, fmax: "Combination") -> tuple[tuple, tuple, str]:
        A = self.vehicle.contact_area
        W = self._effective_load(float(self.normal_loads[0]))[0]
        (c_lo, c_hi), (p_lo, p_hi) = self.bounds.cohesion, self.bounds.friction_angle
        F_lo = fmax.ci95[0] if fmax.ci95[0] is not None else fmax.value
        F_hi = fmax.ci95[1] if fmax.ci95[1] is not None else fmax.value
        c_a = max(c_lo, (F_lo - W * math.tan(p_hi)) / A)
        c_b = min(c_hi, (F_hi - W * math.tan(p_lo)) / A)
        ph_a = max(p_lo, math.atan((F_lo - A * c_hi) / W))
        ph_b = min(p_hi, math.atan((F_hi - A * c_lo) / W))
        how = ("F_max within its 95 % interval" if fmax.ci95[0] is not None
               else "F_max at its estimate (no interval: no residual degrees of freedom)")
        if c_a > c_b or ph_a > ph_b:
            return (None, None), (None, None), (f"no point of the ridge A c + W tan(phi) = F_max with {how} "
                                                "lies within the bounds")
        return (c_a, c_b), (ph_a, ph_b), (f"range along the ridge A c + W tan(phi) = F_max (W = {W / 1e3:.6g} kN) "
                                          f"with {how}, within the bounds")

    # ---------------------------------------------------------------------------- views
    @cached_property
    def combinations(self) -> list[Combination]:
        """Identifiable combinations: ``F_max`` at each distinct load, ``K``, ``K/l``, initial slope.

        Empty when the fit failed (no estimate of anything).
        """
        if not self.success:
            return []
        c, phi, K = (float(x) for x in self.theta)
        A, l = self.vehicle.contact_area, self.vehicle.track_length
        q = self.quantile
        idx = np.array(self.free)
        out: list[Combination] = []

        def add(name, value, g3, unit, desc):
            se, est, weak = self._combo_stderr(self._full(g3)[idx])
            ci = (value - q * se, value + q * se) if (se is not None and q is not None) else (None, None)
            out.append(Combination(name, float(value), se, ci, unit, desc, est, weak))

        cf = self.model == "cohesion-free"
        actual = ""
        for W in self.normal_loads:
            W = float(W)
            fm, gF = self._fmax(W)
            if self.effect_labels:
                actual = f" (actual normal load N = {self._effective_load(W)[0] / 1e3:.6g} kN with the fitted effects)"
            add(f"F_max@W={W:.6g}N", fm, gF, "N",
                f"soil thrust limit {'N tan(phi)' if cf else 'A c + N tan(phi)'} at W = {W / 1e3:.6g} kN{actual}"
                if self.effect_labels else
                f"soil thrust limit {'W tan(phi)' if cf else 'A c + W tan(phi)'} at W = {W / 1e3:.6g} kN")
        add("K", K, [0.0, 0.0, 1.0], "m", "shear deformation modulus K")
        add("K/l", K / l, [0.0, 0.0, 1.0 / l], "-", f"K over the track length l = {l:.6g} m")
        for W in self.normal_loads:
            W = float(W)
            fm, gF = self._fmax(W)
            s0 = fm * l / (2.0 * K)
            g = gF * l / (2.0 * K) + self._full([0.0, 0.0, -fm * l / (2.0 * K * K)])
            add(f"initial_slope@W={W:.6g}N", s0, g, "N/slip", f"small-slip slope dF/di = F_max l / (2 K) at W = "
                f"{W / 1e3:.6g} kN")
        return out

    @cached_property
    def parameters(self) -> dict[str, ParameterEstimate]:
        """Per parameter (``cohesion``, ``friction_angle``, ``shear_modulus``): estimate and uncertainty."""
        q = self.quantile
        C = self._cov_free
        ident = self._identifiable_free
        lo, hi = self.bounds.lower, self.bounds.upper
        flags = self._bound_flags
        out: dict[str, ParameterEstimate] = {}
        ridge = None
        if self._cphi_ridge and self.success:
            fmax = self.combinations[0]
            ridge = self._ridge_intervals(fmax)
        for j, name in enumerate(PARAMETER_NAMES):
            val = float(self.theta[j])
            if j not in self.free:
                out[name] = ParameterEstimate(name, 0.0, None, (0.0, 0.0), identifiable=False, fixed=True,
                                              note="fixed at 0 by the cohesion-free model (not estimated)")
                continue
            k = self.free.index(j)
            side = flags[j]
            notes = []
            if not self.success:
                out[name] = ParameterEstimate(name, None, None, (None, None), bool(ident[k]), False, False, None,
                                              ridge_value=val if math.isfinite(val) else None,
                                              note="the fit failed: no estimate (ridge_value is the last iterate, "
                                                   "NOT an estimate)")
                continue
            outside = side in ("below", "above")
            if outside:
                notes.append(f"{'below' if side == 'below' else 'above'} the bounds (unconstrained method)")
                side = None
            g = np.zeros(len(self.free))
            g[k] = 1.0
            g_s = g / self._D
            weak = bool(ident[k]) and self._vif(g_s) > _WEAK_VIF
            if ident[k]:
                se = None
                if C is not None:
                    v = C[k, k]
                    se = math.sqrt(v) if (v >= 0 and math.isfinite(v)) else None
                if se is None:
                    notes.append("no standard error: " + ("no residual degrees of freedom (n = rank)"
                                                          if self.dof <= 0 else "covariance not finite"))
                if se is not None and q is not None and outside:
                    ci = (val - q * se, val + q * se)
                elif se is not None and q is not None:
                    ci = (max(lo[j], val - q * se), min(hi[j], val + q * se))
                else:
                    ci = (None, None)
                if side is not None:
                    notes.append(f"on the {side} bound: the standard error is the local curvature ignoring the "
                                 "bound and the interval is clipped to the bounds; use profile_likelihood for an "
                                 "honest interval")
                if weak:
                    notes.append("weakly identifiable (correlation with other parameter directions > 0.99)")
                out[name] = ParameterEstimate(name, val, se, ci, True, weak, side is not None, side,
                                              note="; ".join(notes))
            else:
                if ridge is not None and j in (0, 1):
                    ci = ridge[j]
                    note = ("not identifiable: c and phi enter only through F_max = A c + W tan(phi) at one "
                            "normal load; interval = " + ridge[2])
                else:
                    ci = (float(lo[j]), float(hi[j]))
                    note = "not identifiable from these data; interval = the bounds"
                # the optimiser's point on a ridge is arbitrary: "on a bound" only if the whole range is
                pinned = ci[0] is not None and ci[1] is not None and ci[1] - ci[0] <= BOUND_TOL * (hi[j] - lo[j])
                nb_side = side if (pinned and side in ("lower", "upper")) else None
                out[name] = ParameterEstimate(name, None, None, ci, False, False, nb_side is not None, nb_side,
                                              ridge_value=val, note=note)
        return out

    def _partner(self, k: int, identifiable: bool) -> tuple[str | None, float | None]:
        """The free parameter most correlated with free parameter ``k`` and that correlation.

        Identifiable: the largest pairwise correlation of the estimates. Not identifiable: the
        parameter moving most with it along the null space (correlation +-1, sign of the
        estimates' co-movement)."""
        names = [self.parameter_names[j] for j in self.free]
        if len(names) < 2:
            return None, None
        if identifiable:
            P = self._Pinv
            d = np.sqrt(np.clip(np.diag(P), 0.0, None))
            if d[k] <= 0:
                return None, None
            with np.errstate(all="ignore"):
                row = P[k] / (d[k] * np.where(d > 0, d, np.inf))
            row[k] = 0.0
            row = np.where(np.isfinite(row) & self._identifiable_free, row, 0.0)
            m = int(np.argmax(np.abs(row)))
            return names[m], float(np.clip(row[m], -1.0, 1.0))
        null = self._null
        if null.shape[1] == 0:
            return None, None
        v = null @ null[k]  # null-space direction closest to this parameter's axis (scaled coordinates)
        w = np.abs(v)
        w[k] = 0.0
        m = int(np.argmax(w))
        if w[m] < _NULL_TOL:
            return None, None
        return names[m], float(np.sign(v[k] * v[m]))

    @cached_property
    def effects(self) -> dict[str, dict[str, ParameterEstimate]]:
        """Per effect, per parameter: estimate and uncertainty, with the soil's honesty.

        ``{effect: {param: ParameterEstimate}}`` in SI (each parameter's own unit). A parameter
        the data cannot separate from the soil or another effect is not identifiable (value
        ``None``, interval = its bounds) and ``correlated_with`` / ``correlation`` name the
        parameter it is confounded with; a weakly identifiable one carries the same. Parameters
        held by ``fixed`` are marked ``fixed`` with their value. Empty without effects.
        """
        out: dict[str, dict[str, ParameterEstimate]] = {}
        if not self.effect_labels:
            return out
        q = self.quantile
        C = self._cov_free
        ident = self._identifiable_free
        for m, label in enumerate(self.effect_labels):
            name, pname = label.split(".", 1)
            j = 3 + m
            val = float(self.effect_values[m])
            lo, hi = (float(x) for x in self.effect_bounds[m])
            unit = self.effect_units[m] if m < len(self.effect_units) else ""
            d = out.setdefault(name, {})
            if label in self.fixed_labels:
                d[pname] = ParameterEstimate(label, val, None, (val, val), identifiable=False, fixed=True,
                                             si_unit=unit, note=f"held fixed at {val:g} {unit} (not estimated)")
                continue
            k = self.free.index(j)
            if not self.success:
                d[pname] = ParameterEstimate(label, None, None, (None, None), bool(ident[k]), si_unit=unit,
                                             ridge_value=val if math.isfinite(val) else None,
                                             note="the fit failed: no estimate (ridge_value is the last iterate, "
                                                  "NOT an estimate)")
                continue
            tol = BOUND_TOL * (hi - lo)
            side = "lower" if val <= lo + tol else ("upper" if val >= hi - tol else None)
            partner, rho = self._partner(k, bool(ident[k]))
            if ident[k]:
                g_s = np.zeros(len(self.free))
                g_s[k] = 1.0 / self._D[k]
                vif = self._vif(g_s)
                weak = vif > _WEAK_VIF
                se = None
                if C is not None:
                    v = C[k, k]
                    se = math.sqrt(v) if (v >= 0 and math.isfinite(v)) else None
                ci = (max(lo, val - q * se), min(hi, val + q * se)) if (se is not None and q is not None) \
                    else (None, None)
                notes = []
                if se is None:
                    notes.append("no standard error: " + ("no residual degrees of freedom (n = rank)"
                                                          if self.dof <= 0 else "covariance not finite"))
                if side is not None:
                    notes.append(f"on the {side} bound of its physical range [{lo:g}, {hi:g}] {unit}: the standard "
                                 "error ignores the bound and the interval is clipped")
                if weak:
                    mult = math.sqrt(max(0.0, 1.0 - 1.0 / vif)) if math.isfinite(vif) else 1.0
                    notes.append(f"weakly identifiable: multiple correlation {mult:.5f} with the other parameters"
                                 + (f", most with {partner} ({rho:+.4f})" if partner else ""))
                d[pname] = ParameterEstimate(label, val, se, ci, True, bool(weak), side is not None, side,
                                             note="; ".join(notes), si_unit=unit, correlated_with=partner,
                                             correlation=rho)
            else:
                with_ = f" from {partner}" if partner else ""
                d[pname] = ParameterEstimate(label, None, None, (lo, hi), False, ridge_value=val, si_unit=unit,
                                             correlated_with=partner, correlation=rho,
                                             note=f"not identifiable: the data cannot separate it{with_}; "
                                                  "interval = its physical range")
        return out

    @cached_property
    def effect_set(self):
        """The fitted effects as an :class:`~soiltrack.soilmodel.EffectSet` (fitted and fixed values),
        usable in ``simulate`` / ``tractive_force_with_effects``; ``None`` without effects or when
        the fit failed. Parameters the data do not identify keep the optimiser's value."""
        if not self.effect_labels or not self.success:
            return None
        from ..soilmodel.effects import EFFECTS, parse_effects
        vals: dict[str, dict[str, float]] = {}
        for label, v in zip(self.effect_labels, np.asarray(self.effect_values, float)):
            name, pname = label.split(".", 1)
            vals.setdefault(name, {})[pname] = float(v)
        for name in self.effect_structure.names:
            for p in EFFECTS[name].params:
                if p.integer:
                    vals.setdefault(name, {})[p.name] = self.effect_structure.value(name, p.name, self.vehicle)
        try:
            return parse_effects(vals)
        except Exception:  # noqa: BLE001 - a non-finite or inadmissible point carries no effect set
            return None

    def residuals_on(self, data) -> dict[str, np.ndarray]:
        """Raw residuals ``measured - predicted`` of the fitted model on OTHER data of the same kind.

        For slip data the channel is ``"tractive_force_N"`` or ``"drawbar_pull_N"`` (what ``data``
        measured), in N. The prediction hook is :attr:`residual_model`, any object with a method
        ``residuals_on(result, data) -> dict[str, ndarray]`` (picklable); slip fits use
        :class:`~soiltrack.identify.sweep_model.SweepResiduals` when none is set.

        Raises
        ------
        DataError
            Wrong kind of data, a failed fit, or a prediction the fit does not determine (c and
            phi on their ridge, asked at another normal load).
        """
        model = self.residual_model
        if model is None and self.data_kind == "slip":
            from .sweep_model import SweepResiduals
            model = SweepResiduals()
        if model is None:
            from ..soilmodel.errors import DataError
            raise DataError(f"residuals_on is not available for {self.data_kind} fits (no residual model)")
        return model.residuals_on(self, data)

    def _fmax_K_correlation(self) -> dict[str, float | None]:
        """Correlation of the F_max estimate at each load with the K estimate (scale-free)."""
        out: dict[str, float | None] = {}
        if not self.success:
            return out
        idx = np.array(self.free)
        Pinv = self._Pinv / np.outer(self._D, self._D)  # (J^T J)^+ in SI; s^2 cancels in a correlation
        gK = self._full([0.0, 0.0, 1.0])[idx]
        for W in self.normal_loads:
            gF = self._fmax(float(W))[1][idx]
            if not (self._estimable(gF / self._D) and self._estimable(gK / self._D)):
                out[f"{float(W):.6g}"] = None
                continue
            v1, v2, c12 = gF @ Pinv @ gF, gK @ Pinv @ gK, gF @ Pinv @ gK
            out[f"{float(W):.6g}"] = float(c12 / math.sqrt(v1 * v2)) if v1 > 0 and v2 > 0 else None
        return out

    @cached_property
    def identifiability(self) -> dict[str, Any]:
        """Rank, scaled singular values, null-space directions and plain-words statements."""
        p = len(self.free)
        names = [self.parameter_names[j] for j in self.free]
        null_dirs = []
        for col in self._null.T:
            d = col / self._D  # back to SI parameter space
            d = d * np.array([_EDGE[n][2] if n in _EDGE else 1.0 for n in names])  # edge units: kPa, deg, m
            d = d / np.linalg.norm(d)
            if d[np.argmax(np.abs(d))] < 0:
                d = -d
            null_dirs.append({(_EDGE[names[k]][0] if names[k] in _EDGE else names[k]): float(d[k]) for k in range(p)})
        statements: list[str] = []
        params = self.parameters
        if self._cphi_ridge:
            W = float(self.normal_loads[0])
            statements.append(
                f"c and phi are not separable: all data are at one normal load (W = {W / 1e3:.6g} kN), where they "
                "enter only through F_max = A c + W tan(phi); infinitely many (c, phi) give the same curve. "
                "The data pin down F_max and K. Data at two or more normal loads (payload change, slope) or a "
                "prior are needed to separate c and phi.")
        for name, pe in params.items():
            if pe.fixed:
                continue
            if not pe.identifiable and not (self._cphi_ridge and name in ("cohesion", "friction_angle")):
                statements.append(f"{_EDGE[name][3]} is not identifiable from these data.")
            elif pe.weakly_identifiable:
                statements.append(f"{_EDGE[name][3]} is only weakly identifiable (correlated above "
                                  f"{WEAK_CORRELATION} with other parameter directions).")
        for name, ps in self.effects.items():
            for pname, pe in ps.items():
                if pe.fixed or not self.success:
                    continue
                partner = f" from {pe.correlated_with}" if pe.correlated_with else ""
                rho = f" (correlation {pe.correlation:+.4f})" if pe.correlation is not None else ""
                if not pe.identifiable:
                    statements.append(f"effect parameter {name}.{pname} is not identifiable from these data: they "
                                      f"cannot separate it{partner}{rho}.")
                elif pe.weakly_identifiable:
                    statements.append(f"effect parameter {name}.{pname} is only weakly identifiable: the data hardly "
                                      f"separate it from the soil and the other effects ({pe.note.split(': ', 1)[-1]}).")
        fk_corr = self._fmax_K_correlation()
        weak_combos = [cb for cb in self.combinations if cb.weakly_identifiable and cb.name.startswith("F_max")
                       and not self.effect_labels]  # with effects, F_max may be weak through an effect
        high = {w: r for w, r in fk_corr.items() if r is not None and abs(r) > WEAK_CORRELATION}
        if weak_combos or high or (params["shear_modulus"].weakly_identifiable and not self.effect_labels):
            rtxt = (" (correlation " + ", ".join(f"{r:+.4f} at W = {float(w) / 1e3:.6g} kN" for w, r in high.items())
                    + ")") if high else ""
            statements.append(
                f"F_max and K are strongly correlated{rtxt}: the data show mainly the start of the thrust-slip curve, "
                "whose slope F_max l / (2 K) is determined but not F_max and K separately; data at larger slip "
                "(near the traction limit) separate them.")
        if not statements:
            statements.append("all free parameters are identifiable from these data.")
        corr = None
        if self.correlation is not None:
            corr = [[_f(x) for x in row] for row in self.correlation]
        return {"rank": int(self.rank), "n_parameters": p, "parameters": names,
                "fmax_K_correlation": fk_corr,
                "scaled_singular_values": [float(s) for s in self.scaled_singular_values],
                "null_space": null_dirs, "correlation": corr, "statements": statements,
                "rank_tolerance": RANK_TOL}

    @cached_property
    def warnings(self) -> tuple[str, ...]:
        """Warnings in plain words (input warnings first)."""
        w = list(self.input_warnings)
        if not self.success:
            w.append(f"the fit did not succeed ({self.status}): {self.message}")
        for name, d in self.outside_bounds.items():
            j = PARAMETER_NAMES.index(name)
            f, u = _EDGE[name][2], _EDGE[name][1]
            w.append(f"{_EDGE[name][3]} = {self.theta[j] * f:.5g} {u} lies {d} its bounds "
                     f"[{self.bounds.lower[j] * f:.5g}, {self.bounds.upper[j] * f:.5g}] {u}: the {self.method} "
                     "method is unconstrained")
        for name, pe in self.parameters.items():
            if pe.at_bound and name == "cohesion" and pe.bound_side == "lower" and self.bounds.cohesion[0] == 0:
                w.append("cohesion c ended on its lower bound 0 kPa: the data show no cohesion (consistent with a "
                         "cohesionless soil; the cohesion-free model may be the better description)")
            elif pe.at_bound:
                w.append(f"{_EDGE[name][3]} ended on its {pe.bound_side} bound "
                         f"({pe.edge_value if pe.value is not None else (pe.ridge_value or 0) * _EDGE[name][2]:.6g} "
                         f"{pe.edge_unit}): a warning about the data or the bounds")
        for s in self.identifiability["statements"]:
            if not s.startswith("all free"):
                w.append(s)
        for name, ps in self.effects.items():
            for pname, pe in ps.items():
                if pe.at_bound:
                    w.append(f"effect parameter {name}.{pname} ended on its {pe.bound_side} bound "
                             f"({pe.value:.6g} {pe.si_unit}): a warning about the data or the range")
        if self.dof <= 0 and not self.sigma_known:
            w.append("no residual degrees of freedom (as many identifiable directions as samples): no standard "
                     "errors, and an exact fit says nothing about the noise")
        return tuple(w)

    @cached_property
    def soil(self) -> Soil | None:
        """The identified soil, or ``None`` when the fit failed or a free parameter is not identifiable."""
        if not self.success or not all(self.parameters[PARAMETER_NAMES[j]].identifiable for j in self.free if j < 3):
            return None
        return self._soil_at(self.theta, f"identified ({self.model}, {self.method})")

    @cached_property
    def ridge_point(self) -> Soil | None:
        """The optimiser's point as a Soil, labelled; NOT an estimate when ``soil`` is None."""
        label = ("optimiser's point on an unidentifiable ridge - NOT an estimate" if self.soil is None
                 else f"identified ({self.model}, {self.method})")
        return self._soil_at(self.theta, label)

    @staticmethod
    def _soil_at(theta, name: str) -> Soil | None:
        try:
            return Soil(float(theta[0]), float(theta[1]), float(theta[2]), name=name)
        except Exception:  # non-finite or outside the physical domain
            return None

    # ---------------------------------------------------------------------------- output
    def to_dict(self) -> dict:
        """The CLI JSON object (edge units, never NaN; see the module docs)."""
        rmse = _f(self.rmse)
        d = {
            "model": self.model, "method": self.method, "status": self.status, "success": bool(self.success),
            "n_samples": int(self.n_samples),
            "rmse_N": rmse if self.residual_unit == "N" else None,
            "solve_time_s": _f(self.solve_time),
            "parameters": {_EDGE[n][0]: self._parameter_json(pe) for n, pe in self.parameters.items()},
            "combinations": [cb.to_dict() for cb in self.combinations],
            "data_kind": self.data_kind, "rmse": rmse, "residual_unit": self.residual_unit,
            "cost": _f(self.cost), "iterations": int(self.iterations), "message": self.message,
            "dof": int(self.dof), "sigma_known": bool(self.sigma_known),
            "normal_loads_N": [float(w) for w in self.normal_loads],
            "identifiability": self.identifiability, "warnings": list(self.warnings),
            "active_bounds": self.active_bounds,
            "measured": self.measured,
            "parameter_names": list(self.parameter_names),
            "effects": {n: {k: pe.to_dict() for k, pe in ps.items()} for n, ps in self.effects.items()},
            "covariance": self._covariance_json(),
        }
        if self.extra:
            d["extra"] = json.loads(json.dumps(self.extra, default=_json_default, allow_nan=True),
                                    parse_constant=lambda _: None)
        return d

    def _covariance_json(self) -> dict:
        """``{"parameters", "matrix", "units"}``: the covariance over :attr:`parameter_names` in SI,
        ``matrix`` null when unavailable (rank deficient, no dof, failed fit), entries never NaN."""
        C = self.covariance if self.success else None
        return {"parameters": list(self.parameter_names),
                "matrix": None if C is None else [[_f(x) for x in row] for row in C], "units": "SI"}

    def _parameter_json(self, pe: ParameterEstimate) -> dict:
        """A parameter's JSON entry. The CLI contract wants a number in ``value``: for a successful fit
        whose parameter is not identifiable (c, phi at one load), that number is the centre of the
        feasible ridge, flagged ``identifiable: false`` and ``value_is_ridge_point: true``, with
        ``ci95`` the range the ridge allows - a marker, not an estimate. A failed fit keeps ``null``."""
        d = pe.to_dict()
        on_ridge = (self.success and d["value"] is None and not pe.identifiable and not pe.fixed
                    and d["ridge_value"] is not None)
        if on_ridge:
            d["value"] = d["ridge_value"]
        d["value_is_ridge_point"] = bool(on_ridge)
        return d

    def to_json(self, indent: int | None = 2) -> str:
        """:meth:`to_dict` as JSON text (strict: no NaN/Infinity)."""
        return json.dumps(self.to_dict(), indent=indent, allow_nan=False)

    def _drive_log_lines(self) -> list[str]:
        """Report lines for drive-log fits: formulation, regime and any bias correction."""
        x = self.extra if isinstance(self.extra, dict) else {}
        L = []
        if "regime" in x or "formulation" in x:
            L.append(f"drive log: {x.get('formulation', '?')} formulation, {x.get('samples_used', '?')} of "
                     f"{x.get('samples_total', '?')} samples used, regime {x.get('regime', '?')}"
                     + (f" - {x['note']}" if x.get("note") else ""))
        bc = x.get("bias_correction")
        if isinstance(bc, dict):
            if bc.get("applied"):
                unc, cor = bc.get("uncorrected", {}), bc.get("correction", {})
                K0, dK = unc.get("shear_modulus_m"), cor.get("shear_modulus_m")
                F0, dF = unc.get("max_thrust_N"), cor.get("max_thrust_N")
                parts = []
                if F0 and dF is not None:
                    parts.append(f"F_max {F0:.5g} N {dF:+.3g} N")
                if K0 and dK is not None:
                    parts.append(f"K {K0:.5g} m {dK:+.3g} m")
                L.append(f"bias correction: {bc.get('method', '?').upper()} applied ({bc.get('replicates', '?')} "
                         f"replicates; {', '.join(parts)}); intervals include its Monte Carlo variance")
            else:
                L.append(f"bias correction: {bc.get('method', '?').upper()} NOT applied"
                         + (f" - {bc['reason']}" if bc.get("reason") else ""))
        return L

    def report(self) -> str:
        """A human-readable multi-line report (kPa, deg, m, kN)."""
        L: list[str] = []
        loads = ", ".join(f"{w / 1e3:.6g} kN" for w in self.normal_loads)
        L.append(f"soiltrack identification - model {self.model}, method {self.method}")
        what = f" ({self.measured.replace('_', ' ')})" if self.measured else ""
        L.append(f"data: {self.data_kind}{what}, {self.n_samples} samples, normal load(s): {loads}")
        L.append(f"vehicle: {self.vehicle.name or 'unnamed'} (l = {self.vehicle.track_length:.4g} m, "
                 f"b = {self.vehicle.track_width:.4g} m, A = {self.vehicle.contact_area:.4g} m^2)")
        L.append(f"status: {self.status} ({'success' if self.success else 'FAILED'}), {self.iterations} iterations, "
                 f"{self.solve_time * 1e3:.3g} ms")
        unit = self.residual_unit
        if unit == "N":
            L.append(f"fit: RMSE {self.rmse / 1e3:.4g} kN, cost {self.cost:.6g}, residual dof {self.dof}")
        else:
            L.append(f"fit: RMSE {self.rmse:.4g} {unit}, cost {self.cost:.6g}, residual dof {self.dof}")
        q = self.quantile
        if self.sigma_known:
            L.append("noise: sigma given; 95 % intervals use the normal quantile 1.96")
        elif q is not None:
            L.append(f"noise: sigma estimated from the residuals; 95 % intervals use Student t ({self.dof} dof, "
                     f"quantile {q:.4g})")
        else:
            L.append("noise: unknown and no residual degrees of freedom -> no standard errors")
        L.extend(self._drive_log_lines())
        L.append("parameters (95 % intervals):")
        for name, pe in self.parameters.items():
            lab = f"  {_EDGE[name][3]:<20}"
            u = pe.edge_unit
            lo, hi = pe.edge_ci95
            rng = f"[{lo:.4g}, {hi:.4g}] {u}" if lo is not None and hi is not None else "[unavailable]"
            if pe.fixed:
                L.append(f"{lab}0 {u} (fixed by the cohesion-free model)")
            elif pe.value is None and not self.success:
                L.append(f"{lab}no estimate (the fit failed)" + ("" if pe.identifiable else "; not identifiable"))
            elif not pe.identifiable:
                L.append(f"{lab}NOT IDENTIFIABLE; possible range {rng}")
            else:
                se = f" +- {pe.edge_stderr:.3g}" if pe.stderr is not None else " (no stderr)"
                flag = " [ON " + pe.bound_side.upper() + " BOUND]" if pe.at_bound else ""
                weak = " [weakly identifiable]" if pe.weakly_identifiable else ""
                L.append(f"{lab}{pe.edge_value:.5g}{se} {u}, 95 % {rng}{flag}{weak}")
        if self.effects:
            L.append("effect parameters (95 % intervals, SI):")
        for name, ps in self.effects.items():
            for pname, pe in ps.items():
                lab = f"  {name + '.' + pname:<20}"
                u = pe.si_unit
                lo, hi = pe.ci95
                rng = f"[{lo:.4g}, {hi:.4g}] {u}" if lo is not None and hi is not None else "[unavailable]"
                if pe.fixed:
                    L.append(f"{lab}{pe.value:.5g} {u} (held fixed, not estimated)")
                elif pe.value is None and not self.success:
                    L.append(f"{lab}no estimate (the fit failed)")
                elif not pe.identifiable:
                    w = f" from {pe.correlated_with}" if pe.correlated_with else ""
                    L.append(f"{lab}NOT IDENTIFIABLE (not separable{w}); range {rng}")
                else:
                    se = f" +- {pe.stderr:.3g}" if pe.stderr is not None else " (no stderr)"
                    flag = " [ON " + pe.bound_side.upper() + " BOUND]" if pe.at_bound else ""
                    weak = (f" [weakly identifiable: correlation {pe.correlation:+.4f} with {pe.correlated_with}]"
                            if pe.weakly_identifiable and pe.correlated_with else
                            (" [weakly identifiable]" if pe.weakly_identifiable else ""))
                    L.append(f"{lab}{pe.value:.5g}{se} {u}, 95 % {rng}{flag}{weak}")
        L.append("identifiable combinations:" + ("" if self.combinations else " none (the fit failed)"))
        for cb in self.combinations:
            if cb.unit.startswith("N"):
                v, se, u = cb.value / 1e3, (None if cb.stderr is None else cb.stderr / 1e3), "k" + cb.unit
            else:
                v, se, u = cb.value, cb.stderr, cb.unit
            if not cb.estimable:
                L.append(f"  {cb.name:<26} not estimable from these data")
                continue
            s = f" +- {se:.3g}" if se is not None else " (no stderr)"
            L.append(f"  {cb.name:<26} {v:.5g}{s} {u}{' [weak]' if cb.weakly_identifiable else ''}  ({cb.description})")
        ident = self.identifiability
        L.append(f"identifiability: rank {ident['rank']} of {ident['n_parameters']}; scaled singular values "
                 + ", ".join(f"{s:.3g}" for s in ident["scaled_singular_values"]))
        for d in ident["null_space"]:
            L.append("  null direction: " + ", ".join(f"{k} {v:+.3g}" for k, v in d.items())
                     + " (unit vector in kPa / deg / m: moving along it leaves the fit unchanged)")
        for s in ident["statements"]:
            L.append("  - " + s)
        if self.ridge_point is not None and self.soil is None:
            rp = self.ridge_point
            what = "optimiser's ridge point" if self.success else "last iterate of the failed fit"
            L.append(f"  ({what}, NOT an estimate: c = {rp.cohesion_kpa:.4g} kPa, "
                     f"phi = {rp.friction_angle_deg:.4g} deg, K = {rp.shear_modulus:.4g} m)")
        if self.n_samples <= 20:
            sc, u = (1e-3, "kN") if unit == "N" else (1.0, unit)
            L.append(f"residuals (model - data, {u}): " + ", ".join(f"{r * sc:+.4g}" for r in self.residuals))
        if self.warnings:
            L.append("warnings:")
            for w in self.warnings:
                L.append("  ! " + w)
        return "\n".join(L)

    def __str__(self) -> str:  # pragma: no cover - convenience
        return self.report()


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, (Soil, Vehicle, SoilBounds)):
        return str(o)
    return repr(o)


# --------------------------------------------------------------------------------------------
# entry points
# --------------------------------------------------------------------------------------------
def _free_indices(model: str) -> tuple[int, ...]:
    if model == "full":
        return (0, 1, 2)
    if model == "cohesion-free":
        return (1, 2)
    raise ValueError(f"unknown model {model!r}")


def _assemble(core: dict, k: int, *, data_kind, model, method, theta, jacobian, weighted_residuals, residuals,
              residual_unit, n_samples, normal_loads, vehicle, bounds, status, success, message, iterations,
              solve_time, sigma_known, warnings, extra, free, **effect_fields) -> FitResult:
    res = np.asarray(residuals, dtype=float)
    rw = np.asarray(weighted_residuals, dtype=float)
    finite = bool(np.isfinite(theta).all() and np.isfinite(res).all() and np.isfinite(rw).all())
    warn = list(warnings)
    if not finite:
        success = False
        status = status if "non-finite" in status else f"{status} (non-finite numbers)"
        warn.append("the solver returned non-finite numbers; no estimate is given")
    s2 = float(core["s2"][k])
    return FitResult(
        data_kind=data_kind, model=model, method=method, theta=theta, jacobian=jacobian,
        weighted_residuals=rw, residuals=res, residual_unit=residual_unit, n_samples=int(n_samples),
        normal_loads=normal_loads, vehicle=vehicle, bounds=bounds, status=str(status), success=bool(success),
        message=str(message), iterations=int(iterations), solve_time=float(solve_time),
        sigma_known=bool(sigma_known),
        rmse=math.sqrt(float(np.dot(res.ravel(), res.ravel())) / res.size) if res.size else math.nan,
        cost=0.5 * float(core["ssr"][k]), rank=int(core["rank"][k]), dof=int(core["dof"][k]),
        s2=s2 if math.isfinite(s2) and finite else None, free=free, _core=(core, k),
        input_warnings=tuple(warn), extra=dict(extra or {}), **effect_fields)


def _distinct_loads(normal_loads) -> np.ndarray:
    w = np.atleast_1d(np.asarray(normal_loads, dtype=float)).ravel()
    if w.size and math.isfinite(w[0]) and (w == w[0]).all():  # one load (the common case)
        return w[:1].copy()
    w = w[np.isfinite(w)]
    if w.size == 0:
        return w
    w = np.sort(w)
    keep = np.concatenate([[True], np.diff(w) > 1e-9 * np.abs(w[1:])])
    return w[keep]


def build_result(*, data_kind: str, model: str, method: str, theta: np.ndarray, jacobian: np.ndarray,
                 weighted_residuals: np.ndarray, residuals: np.ndarray, residual_unit: str, n_samples: int,
                 normal_loads: np.ndarray, vehicle: Vehicle, bounds: SoilBounds, status: str, success: bool,
                 message: str, iterations: int, solve_time: float, sigma_known: bool = False,
                 warnings: Sequence[str] = (), extra: dict | None = None, effect_labels: Sequence[str] = (),
                 effect_values=None, effect_bounds: Sequence = (), effect_units: Sequence[str] = (),
                 effect_structure=None, fixed_labels: Sequence[str] = (), measured: str | None = None,
                 residual_model=None) -> FitResult:
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

    Returns
    -------
    FitResult
    """
    if data_kind not in ("slip", "drive"):
        raise ValueError(f"data_kind must be 'slip' or 'drive', got {data_kind!r}")
    free = _free_indices(model)
    theta = np.asarray(theta, dtype=float).reshape(3).copy()
    J = np.asarray(jacobian, dtype=float)
    rw = np.asarray(weighted_residuals, dtype=float).ravel()
    labels = tuple(effect_labels)
    m = len(labels)
    if J.ndim != 2 or J.shape[1] != 3 + m or J.shape[0] != rw.size:
        raise ValueError(f"jacobian must have shape (n_res, 3 + {m}) = ({rw.size}, {3 + m}), got {J.shape}")
    effect_fields: dict[str, Any] = {"measured": measured, "residual_model": residual_model}
    if m:
        fixed_labels = tuple(fixed_labels)
        unknown = set(fixed_labels) - set(labels)
        if unknown:
            raise ValueError(f"fixed_labels {sorted(unknown)} are not effect parameters {labels}")
        free = free + tuple(3 + k for k, lab in enumerate(labels) if lab not in fixed_labels)
        effect_fields.update(effect_labels=labels, effect_values=np.asarray(effect_values, float).reshape(m).copy(),
                             effect_bounds=tuple((float(a), float(b)) for a, b in effect_bounds),
                             effect_units=tuple(effect_units), effect_structure=effect_structure,
                             fixed_labels=fixed_labels)
        core = _core_stats_one(J[:, list(free)], rw, sigma_known)
    else:
        core = _core_stats_one(J[:, free[0]:], rw, sigma_known)  # free = (0, 1, 2) or (1, 2)
    return _assemble(core, 0, data_kind=data_kind, model=model, method=method, theta=theta, jacobian=J,
                     weighted_residuals=rw, residuals=residuals, residual_unit=residual_unit, n_samples=n_samples,
                     normal_loads=_distinct_loads(normal_loads), vehicle=vehicle, bounds=bounds, status=status,
                     success=success, message=message, iterations=iterations, solve_time=solve_time,
                     sigma_known=sigma_known, warnings=warnings, extra=extra, free=free, **effect_fields)


def build_results_batch(*, model: str, method: str, theta: np.ndarray, jacobian: np.ndarray,
                        weighted_residuals: np.ndarray, residuals: np.ndarray, normal_loads: np.ndarray,
                        vehicle: Vehicle, bounds: SoilBounds, status: Sequence[str], success: Sequence[bool],
                        message: Sequence[str], iterations: Sequence[int], solve_time: Sequence[float],
                        sigma_known: bool = False, extra: Sequence[dict] | None = None,
                        warnings: Sequence[Sequence[str]] | None = None) -> list[FitResult]:
    """Vectorised :func:`build_result` for N same-size slip fits (stacked arrays, leading axis N).

    Same statistics as :func:`build_result` (one code path, :func:`_core_stats`); the per-fit
    scalars are computed for all fits at once and the objects are filled directly, which keeps
    the cost per result at a few microseconds.
    """
    free = _free_indices(model)
    theta = np.asarray(theta, dtype=float)
    J = np.asarray(jacobian, dtype=float)
    rw = np.asarray(weighted_residuals, dtype=float)
    res = np.asarray(residuals, dtype=float)
    N, n = rw.shape
    core = _core_stats(J[:, :, list(free)], rw, np.array(free), sigma_known)
    finite = np.all(np.isfinite(theta), axis=1) & np.all(np.isfinite(res), axis=1) & np.all(np.isfinite(rw), axis=1)
    rmse = np.sqrt(np.mean(res ** 2, axis=1))
    cost = 0.5 * core["ssr"]
    s2 = core["s2"]
    W = np.sort(np.asarray(normal_loads, dtype=float), axis=1)
    keep = np.concatenate([np.ones((N, 1), bool), np.diff(W, axis=1) > 1e-9 * np.abs(W[:, 1:])], axis=1)
    single = keep.sum(axis=1) == 1
    # per-row views and Python scalars prepared in bulk (iteration over an array is a C loop)
    ok_l = (np.asarray(success, dtype=bool) & finite).tolist()
    fin_l = finite.tolist()
    s2_l = np.where(np.isfinite(s2) & finite, s2, np.nan).tolist()
    loads_l = [W[k, :1] if single[k] else W[k][keep[k]] for k in range(N)] if not single.all() else list(W[:, :1])
    rows = zip(list(theta), list(J), list(rw), list(res), loads_l, ok_l, fin_l, status, message,
               np.asarray(iterations).tolist(), np.asarray(solve_time, dtype=float).tolist(), rmse.tolist(),
               cost.tolist(), core["rank"].tolist(), core["dof"].tolist(), s2_l, range(N),
               extra if extra is not None else [None] * N)
    out = []
    new = object.__new__
    sk = bool(sigma_known)
    nonfinite = ("the solver returned non-finite numbers; no estimate is given",)
    for (th, Jk, rwk, rk, Wk, ok, fin, st, msg, it, stime, rm, co, rank, dof, s2k, k, ex) in rows:
        obj = new(FitResult)
        obj.__dict__.update(
            data_kind="slip", model=model, method=method, theta=th, jacobian=Jk, weighted_residuals=rwk,
            residuals=rk, residual_unit="N", n_samples=n, normal_loads=Wk, vehicle=vehicle, bounds=bounds,
            status=str(st) if fin else f"{st} (non-finite numbers)", success=ok, message=str(msg), iterations=it,
            solve_time=stime, sigma_known=sk, rmse=rm, cost=co, rank=rank, dof=dof,
            s2=None if s2k != s2k else s2k, free=free, _core=(core, k), input_warnings=(() if fin else nonfinite)
            + (tuple(warnings[k]) if warnings is not None else ()),
            extra=dict(ex) if ex else {})
        out.append(obj)
    return out
