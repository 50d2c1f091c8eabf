"""Fit a plate sinkage test: Bekker k_c, k_phi and n from pressure against sinkage.

The model is the one Bekker law of :func:`soiltrack.soilmodel.plate_pressure_expr`. The solver
works with ``A = k z_ref^n / p_scale`` (``z_ref`` the geometric mean sinkage, ``p_scale`` the
largest pressure): the pressure at the data's typical sinkage, weakly correlated with n.
Plates of two or more widths identify k_c and k_phi; one width b identifies only
``k_c / b + k_phi`` (and n): then k_c and k_phi are ``identifiable: false`` and the
combination ``bekker_k_eq`` is reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...soilmodel import DataError, PlateTest, plate_pressure_expr
from ...soilmodel.ridge import distinct_loads
from .intervals import at_bounds, edge_parameters
from .lsq import ResidualModel, solve_bounded
from ..estimates.records import ParameterEstimate
from ..estimates.estimate import Estimate
from .result import one_level_combination, soil_test_estimate

__all__ = ["fit_plate_test", "PlateBounds", "PLATE_BOUNDS", "N_STARTS", "UNBOUNDED_FACTOR"]

#: Extra start values of n besides the log-log regression's (one IPOPT start each).
N_STARTS = (0.5, 1.0, 1.5)
#: Upper bound of the scaled moduli, times the regression's scaled pressure: no bound in practice
#: (k_c and k_phi are only bounded below, by 0), but a finite box for IPOPT.
UNBOUNDED_FACTOR = 1e3


@dataclass(frozen=True)
class PlateBounds:
    """Bounds of a plate fit. k_c and k_phi are >= 0 and otherwise free (tabulated soils: k_c
    0.99-102 kN/m^(n+1), k_phi 197-5301 kN/m^(n+2)); the exponent n lies in ``n``
    (tabulated 0.13 for heavy clay to 1.6 for snow).
    """

    n: tuple[float, float] = (0.05, 2.5)
    #: False: k_c >= 0, and where the fit ends on 0 the unconstrained value is reported beside it;
    #: True: k_c is free (plate tests often give a negative k_c; the report flags it).
    negative_kc: bool = False

    def __post_init__(self) -> None:
        lo, hi = self.n
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
            raise DataError(f"bounds on the Bekker exponent n must satisfy 0 < lower < upper, got {self.n}")


#: Default bounds of a plate fit.
PLATE_BOUNDS = PlateBounds()


def _moduli(x, a):
    """k_c, k_phi in SI from the solver's A_c, A_phi, n (``a = [p_scale, z_ref]``)."""
    f = a[0] / a[1] ** x[2]
    return x[0] * f, x[1] * f


def _full(x, D, a):
    k_c, k_phi = _moduli(x, a)
    return (plate_pressure_expr(D[:, 1], D[:, 0], k_c, k_phi, x[2], a[1]) - D[:, 2]) / a[0]


def _one_width(x, D, a):
    k_eq = x[0] * a[0] / a[1] ** x[1]
    return (plate_pressure_expr(D[:, 1], 1.0, 0.0, k_eq, x[1], a[1]) - D[:, 2]) / a[0]


FULL = ResidualModel("plate_full", 3, 3, 2, _full)
ONE_WIDTH = ResidualModel("plate_one_width", 2, 3, 2, _one_width)


def _loglog_start(b: np.ndarray, z: np.ndarray, p: np.ndarray, widths: np.ndarray) -> tuple[float, np.ndarray]:
    """n and k_eq per width (SI) from ``log p = log k_eq(b) + n log z`` on the rows with z, p > 0."""
    use = (z > 0) & (p > 0)
    groups = [np.isclose(b[use], w, rtol=1e-9, atol=0.0) for w in widths]
    X = np.column_stack([np.log(z[use])] + [g.astype(float) for g in groups])
    coef = np.linalg.lstsq(X, np.log(p[use]), rcond=None)[0]
    return float(coef[0]), np.exp(coef[1:])


def _plate_specs(bounds: PlateBounds) -> list:
    return [
        ("bekker_kc", "Bekker k_c", "kN/m^(n+1)", -math.inf if bounds.negative_kc else 0.0, math.inf),
        ("bekker_kphi", "Bekker k_phi", "kN/m^(n+2)", 0.0, math.inf),
        ("bekker_n", "Bekker exponent n", "-", *bounds.n),
    ]


def _kc_notes(bounds: PlateBounds, kc: float, free, sol, rows: int, ps: float, z_ref: float, specs) -> list[str]:
    """What a negative k_c means here: flagged when fitted freely, the unconstrained value when held at 0."""
    if bounds.negative_kc:
        if kc >= 0:
            return []
        return [
            f"k_c = {kc:.4g} kN/m^(n+1) < 0: the data say so (fitted freely); a negative k_c has no reading as a "
            "cohesive modulus - it is the plates' size effect in Bekker's form - and makes the pressure of a plate "
            f"narrower than -k_c / k_phi negative: do not extrapolate to narrower running gear"
        ]
    if free is None:
        return []
    n = float(free.x[2])
    f = ps / z_ref**n / 1e3
    kc_f, kphi_f = free.x[0] * f, free.x[1] * f
    lz = math.log(z_ref)
    T = np.array([[f, 0.0, -kc_f * lz], [0.0, f, -kphi_f * lz], [0.0, 0.0, 1.0]])
    neg = [("bekker_kc", "Bekker k_c", "kN/m^(n+1)", -math.inf, math.inf), *specs[1:]]
    (p_kc, _, _), _ = edge_parameters(free, rows, np.array([kc_f, kphi_f, n]), T, neg, np.zeros(3, dtype=bool))
    kc_lo, kc_hi = p_kc.edge_ci95
    ci = "" if kc_lo is None or kc_hi is None else f", 95 % [{kc_lo:.4g}, {kc_hi:.4g}]"
    rms = math.sqrt(free.cost / rows) * ps / 1e3
    return [
        f"k_c is held at its bound 0: the unconstrained fit gives k_c = {kc_f:.4g} kN/m^(n+1){ci} (k_phi "
        f"{kphi_f:.4g}, n {n:.4g}; rms misfit {rms:.4g} kPa against {math.sqrt(sol.cost / rows) * ps / 1e3:.4g}). "
        "Held because a negative k_c makes a narrow enough plate's pressure negative; "
        "PlateBounds(negative_kc=True) fits it freely (flagged)"
    ]


def fit_plate_test(test: PlateTest, bounds: PlateBounds = PLATE_BOUNDS) -> Estimate:
    """Fit Bekker k_c, k_phi, n (or ``k_c / b + k_phi`` and n at one width) to a plate sinkage test.

    Parameters
    ----------
    test
        The readings (:class:`~soiltrack.soilmodel.PlateTest`).
    bounds
        Box bounds (:class:`PlateBounds`, edge units).

    Returns
    -------
    Estimate
        ``bekker_kc`` (kN/m^(n+1)), ``bekker_kphi`` (kN/m^(n+2)), ``bekker_n`` with 95 % intervals.

    Raises
    ------
    DataError
        Too few rows with a positive sinkage and pressure for the parameters.
    """
    b, p, z = test.plate_width, test.pressure, test.sinkage
    widths = distinct_loads(b)  # distinct values within the library's one tolerance
    separable = widths.size >= 2
    m = 3 if separable else 2
    informative = int(np.count_nonzero((z > 0) & (p > 0)))
    if informative <= m:
        raise DataError(
            f"{informative} rows with a positive sinkage and pressure cannot fit {m} parameters "
            f"with an interval (need at least {m + 1})",
            file=test.source,
        )
    pb = _scaled_problem(b, z, p, widths, bounds)
    fit = (_fit_two_or_more_widths if separable else _fit_one_width)(test, widths, pb, bounds)
    sol, params, combos, notes, si, values_si, flags = fit
    if np.any(flags):
        notes.append(
            "on a bound: "
            + (", ".join(q.key for q in params if q.at_bound) or "k_c / b + k_phi")
            + " (a warning about the data or the bounds)"
        )
    return soil_test_estimate(
        kind="plate_test",
        source=test.source,
        params=params,
        combos=combos,
        sol=sol,
        n_samples=test.n_samples,
        residuals_kpa=-np.asarray(sol.residuals, dtype=float) * pb.ps / 1e3,  # measured minus model
        levels={"plate_widths_m": [float(v) for v in widths]},
        notes=notes,
        covariance_si=si,
        values_si=values_si,
    )


@dataclass(frozen=True)
class _PlateProblem:
    """A plate test scaled for the solver, with the log-log regression's start."""

    D: np.ndarray  #: rows ``[b, z, p]``
    aux: np.ndarray  #: scales ``[p_s, z_ref]``
    ps: float  #: the largest pressure (Pa)
    z_ref: float  #: the geometric mean sinkage (m)
    n0: float  #: the regression's exponent
    k_eq0: np.ndarray  #: the regression's ``k_c / b + k_phi`` per width (kN units)
    n_starts: list  #: start values of n

    def scaled(self, k_si, n):
        """A modulus in the solver's scaled units."""
        return k_si * self.z_ref**n / self.ps


def _scaled_problem(b, z, p, widths, bounds: PlateBounds) -> _PlateProblem:
    """Scales, data rows and the start of n from the log-log regression."""
    z_ref = float(np.exp(np.mean(np.log(z[(z > 0) & (p > 0)]))))
    ps = float(np.max(p))
    aux = np.array([ps, z_ref])
    D = np.column_stack([b, z, p])
    n0, k_eq0 = _loglog_start(b, z, p, widths)
    n_lo, n_hi = bounds.n
    n_starts = [float(np.clip(n0, n_lo, n_hi)), *N_STARTS]

    return _PlateProblem(D, aux, ps, z_ref, n0, k_eq0, n_starts)


def _fit_two_or_more_widths(test: PlateTest, widths, pb: _PlateProblem, bounds: PlateBounds) -> tuple:
    """k_c, k_phi and n from two or more widths: ``(sol, params, combos, notes, si, values_si, flags)``."""
    n_lo, n_hi = bounds.n
    D, aux, ps, z_ref = pb.D, pb.aux, pb.ps, pb.z_ref
    n0, k_eq0, n_starts, scaled = pb.n0, pb.k_eq0, pb.n_starts, pb.scaled
    kc0, kphi0 = np.linalg.lstsq(np.column_stack([1.0 / widths, np.ones_like(widths)]), k_eq0, rcond=None)[0]
    kc0, kphi0 = max(kc0, 0.0), max(kphi0, 0.0)
    starts = []
    for n in n_starts:  # the regression's moduli at its n; at other n, the same pressure at z_ref
        f = 1.0 if n == n_starts[0] else z_ref ** (n0 - n)
        starts.append(np.array([scaled(kc0 * f, n), scaled(kphi0 * f, n), n]))
    big = UNBOUNDED_FACTOR * max(1.0, float(np.max(k_eq0)) * z_ref**n0 / ps)
    lower = np.array([0.0, 0.0, n_lo])
    upper = np.array([big, big, n_hi])
    sol = solve_bounded(FULL, D, aux, starts, lower, upper)
    free = None
    if bounds.negative_kc or at_bounds(sol.x, lower, upper)[0]:
        lower_free = np.array([-big, 0.0, n_lo])
        free = solve_bounded(FULL, D, aux, [*starts, sol.x], lower_free, upper)
        if bounds.negative_kc:
            sol, lower = free, lower_free
    n = float(sol.x[2])
    f = ps / z_ref**n / 1e3  # A -> kN/m^(n+...)
    kc, kphi = sol.x[0] * f, sol.x[1] * f
    values = np.array([kc, kphi, n])
    lz = math.log(z_ref)
    T = np.array([[f, 0.0, -kc * lz], [0.0, f, -kphi * lz], [0.0, 0.0, 1.0]])
    flags = at_bounds(sol.x, lower, upper)
    specs = _plate_specs(bounds)
    params, cov = edge_parameters(sol, test.n_samples, values, T, specs, flags)
    combos: dict = {}
    notes = [f"{widths.size} plate widths ({widths.min():.4g}-{widths.max():.4g} m) separate k_c and k_phi"]
    notes += _kc_notes(bounds, kc, free, sol, test.n_samples, ps, z_ref, specs)
    S = np.diag([1e3, 1e3, 1.0])
    si = None if cov is None or not all(q.identifiable for q in params) else S @ cov @ S
    values_si = (kc * 1e3, kphi * 1e3, n)
    return sol, params, combos, notes, si, values_si, flags


def _fit_one_width(test: PlateTest, widths, pb: _PlateProblem, bounds: PlateBounds) -> tuple:
    """``k_c / b + k_phi`` and n at one width (k_c, k_phi not identified): as :func:`_fit_two_or_more_widths`."""
    n_lo, n_hi = bounds.n
    D, aux, ps, z_ref = pb.D, pb.aux, pb.ps, pb.z_ref
    n0, k_eq0, n_starts, scaled = pb.n0, pb.k_eq0, pb.n_starts, pb.scaled
    w = float(widths[0])
    starts = [np.array([scaled(k_eq0[0] * (1.0 if n == n_starts[0] else z_ref ** (n0 - n)), n), n]) for n in n_starts]
    big = UNBOUNDED_FACTOR * max(1.0, float(k_eq0[0]) * z_ref**n0 / ps)
    lower = np.array([0.0, n_lo])
    upper = np.array([big, n_hi])
    sol = solve_bounded(ONE_WIDTH, D, aux, starts, lower, upper)
    n = float(sol.x[1])
    f = ps / z_ref**n / 1e3
    k_eq = sol.x[0] * f
    T = np.array([[f, -k_eq * math.log(z_ref)], [0.0, 1.0]])
    flags = at_bounds(sol.x, lower, upper)
    specs = [
        ("bekker_k_eq", "k_c / b + k_phi", "kN/m^(n+2)", 0.0, math.inf),
        ("bekker_n", "Bekker exponent n", "-", *bounds.n),
    ]
    (k_par, n_par), cov = edge_parameters(sol, test.n_samples, np.array([k_eq, n]), T, specs, flags)
    why = (
        f"one plate width (b = {w:.4g} m): only k_c / b + k_phi is identified; plates of two or more "
        "widths separate k_c and k_phi"
    )
    params = [
        ParameterEstimate("bekker_kc", None, None, (None, None), False, note=why),
        ParameterEstimate("bekker_kphi", None, None, (None, None), False, note=why),
        n_par,
    ]
    combos = {
        "bekker_k_eq": one_level_combination(
            "bekker_k_eq",
            "k_c / b + k_phi",
            f"Bekker stiffness of the one plate width b = {w:.4g} m",
            k_par,
            {"plate_width_m": w},
        )
    }
    notes = [why]
    si, values_si = None, (None, None, n)
    return sol, params, combos, notes, si, values_si, flags
