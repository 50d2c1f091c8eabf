"""Fit a bevameter shear test: c, phi and K from shear stress against displacement at set pressures.

The model is the one Janosi-Hanamoto law of :func:`soiltrack.soilmodel.shear_stress_expr`. At
two or more normal pressures c, phi and K are identified; at one pressure sigma only the shear
strength ``c + sigma tan(phi)`` and K are (the report says so and gives that combination,
never a point of the c-phi line as an estimate).
"""

from __future__ import annotations

import math

import numpy as np

from ...soilmodel import WIDE_BOUNDS, DataError, ShearTest, SoilBounds, shear_stress_expr
from ...soilmodel.bevameter import ANNULUS_NODES, annulus_torque_expr, ring_torque_per_stress
from ...soilmodel.bevameter_records import AnnulusTest
from ...soilmodel.ridge import distinct_loads
from .intervals import at_bounds, edge_parameters
from .lsq import ResidualModel, solve_bounded
from ..estimates.records import ParameterEstimate
from ..estimates.estimate import Estimate
from .result import one_level_combination, soil_test_estimate

__all__ = ["fit_shear_test", "K_SCALE", "K_STARTS"]

#: Scale of K inside the solver, m (K is solved for in centimetres).
K_SCALE = 0.01
#: Start values of K, m (one IPOPT start each).
K_STARTS = (0.003, 0.01, 0.04)


def _full(x, D, a):
    ts = a[0]
    tau = shear_stress_expr(D[:, 1], D[:, 0], x[0] * ts, x[1], x[2] * K_SCALE)
    return (tau - D[:, 2]) / ts


def _strength(x, D, a):
    ts = a[0]
    tau = shear_stress_expr(D[:, 1], 0.0, x[0] * ts, 0.0, x[1] * K_SCALE)  # c + sigma tan(phi) as one number
    return (tau - D[:, 2]) / ts


FULL = ResidualModel("shear_full", 3, 3, 1, _full)
STRENGTH = ResidualModel("shear_strength", 2, 3, 1, _strength)


def _annulus(x, D, a, strength: bool):
    """Annulus rows ``[sigma, theta, T / ring, r_i, r_o]``: the torque integrated across the ring, per unit ring."""
    ts = a[0]
    if strength:
        T = annulus_torque_expr(D[:, 1], 0.0, x[0] * ts, 0.0, x[1] * K_SCALE, D[:, 3], D[:, 4])
    else:
        T = annulus_torque_expr(D[:, 1], D[:, 0], x[0] * ts, x[1], x[2] * K_SCALE, D[:, 3], D[:, 4])
    ring = 2 * math.pi * (D[:, 4] ** 3 - D[:, 3] ** 3) / 3
    return (T / ring - D[:, 2]) / ts


ANNULUS_FULL = ResidualModel("annulus_full", 3, 5, 1, lambda x, D, a: _annulus(x, D, a, False))
ANNULUS_STRENGTH = ResidualModel("annulus_strength", 2, 5, 1, lambda x, D, a: _annulus(x, D, a, True))


def _rows(test: ShearTest | AnnulusTest):
    """``(sigma, displacement-like, stress-like, D, full model, strength model, note)`` of either test."""
    if isinstance(test, AnnulusTest):
        ring = ring_torque_per_stress(test.inner_radius, test.outer_radius)
        tau = test.torque / ring  # the ring-mean stress, only for starts and scaling: the model integrates
        D = np.column_stack([test.normal_pressure, test.rotation, tau, test.inner_radius, test.outer_radius])
        note = (
            f"shear annulus r_i {np.min(test.inner_radius):.4g}-r_o {np.max(test.outer_radius):.4g} m: the torque "
            f"is the shear law integrated across the ring with j = r theta ({ANNULUS_NODES}-point Gauss-Legendre, "
            "relative error below 1e-12); residuals in torque per ring (T / (2 pi (r_o^3 - r_i^3) / 3), kPa)"
        )
        return test.normal_pressure, test.rotation, tau, D, ANNULUS_FULL, ANNULUS_STRENGTH, note
    D = np.column_stack([test.normal_pressure, test.shear_displacement, test.shear_stress])
    return test.normal_pressure, test.shear_displacement, test.shear_stress, D, FULL, STRENGTH, None


def _start_strength(sigma: np.ndarray, tau: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """Largest stress per pressure level (the strength it approaches)."""
    return np.array([tau[np.isclose(sigma, s, rtol=1e-9, atol=0.0)].max() for s in levels])


def fit_shear_test(test: ShearTest | AnnulusTest, bounds: SoilBounds = WIDE_BOUNDS) -> Estimate:
    """Fit c, phi and K (or the shear strength and K at one pressure) to a bevameter shear test.

    Parameters
    ----------
    test
        The readings (:class:`~soiltrack.soilmodel.ShearTest`).
    bounds
        Box bounds on c, phi, K (default the wide soil range: c 0-200 kPa, phi 1-55 deg,
        K 2-250 mm).

    Returns
    -------
    Estimate
        ``cohesion_kpa``, ``friction_angle_deg``, ``shear_modulus_m`` with 95 % intervals;
        at one pressure c and phi are ``identifiable: false`` and the combination
        ``shear_strength_kpa`` (``c + sigma tan(phi)``) is reported instead.

    Raises
    ------
    DataError
        Too few rows for the parameters, or no non-zero stress.
    """
    sigma, j, tau, D, full_model, strength_model, ring_note = _rows(test)
    levels = distinct_loads(sigma)
    separable = levels.size >= 2
    m = 3 if separable else 2
    if test.n_samples <= m:
        raise DataError(
            f"{test.n_samples} rows cannot fit {m} parameters with an interval (need at least {m + 1})",
            file=test.source,
        )
    ts = _stress_scale(test, j, tau, m)
    peaks = _start_strength(sigma, tau, levels)
    fit = (_two_or_more_pressures if separable else _one_pressure)(
        test, levels, peaks, ts, bounds, full_model if separable else strength_model, D
    )
    sol, params, combos, notes, si, values_si, flags = fit
    if ring_note is not None:
        notes.append(ring_note)
    if np.any(flags):
        notes.append(
            "on a bound: "
            + ", ".join(p.key for p in params if p.at_bound)
            + " (a warning about the data or the bounds)"
        )
    return soil_test_estimate(
        kind="shear_test",
        source=test.source,
        params=params,
        combos=combos,
        sol=sol,
        n_samples=test.n_samples,
        residuals_kpa=-np.asarray(sol.residuals, dtype=float) * ts / 1e3,  # measured minus model
        levels={"normal_pressures_kpa": [float(s) / 1e3 for s in levels]},
        notes=notes,
        covariance_si=si,
        values_si=values_si,
    )


def _stress_scale(test, j, tau, m: int) -> float:
    """The largest |shear stress| (Pa, the fit's scale); DataError when the rows cannot fit ``m`` parameters."""
    ts = float(np.max(np.abs(tau)))
    if ts <= 0:
        raise DataError("every shear stress is zero", file=test.source, column="shear_stress_Pa")
    moved = j > 0
    if np.count_nonzero(moved) < m:
        raise DataError(
            f"{np.count_nonzero(moved)} rows with a shear displacement above 0: the "
            f"stress-displacement curve needs at least {m}",
            file=test.source,
            column="shear_displacement_m",
        )
    if np.median(tau[moved]) <= 0:
        raise DataError(
            "most shear stresses at a positive displacement are <= 0: the soil resists shearing "
            "with a positive stress (a sign convention of the logger?)",
            file=test.source,
            column="shear_stress_Pa",
        )
    return ts


def _two_or_more_pressures(test, levels, peaks, ts: float, bounds: SoilBounds, full_model, D) -> tuple:
    """c, phi and K from two or more normal pressures: ``(sol, params, combos, notes, si, values_si, flags)``."""
    (c_lo, c_hi), (p_lo, p_hi), (k_lo, k_hi) = bounds.cohesion, bounds.friction_angle, bounds.shear_modulus
    slope, icpt = np.polyfit(levels, peaks, 1)
    c0 = float(np.clip(icpt, c_lo, c_hi)) / ts
    phi0 = float(np.clip(math.atan(max(slope, 1e-6)), p_lo, p_hi))
    lower = np.array([c_lo / ts, p_lo, k_lo / K_SCALE])
    upper = np.array([c_hi / ts, p_hi, k_hi / K_SCALE])
    starts = [np.array([c0, phi0, K / K_SCALE]) for K in K_STARTS]
    sol = solve_bounded(full_model, D, np.array([ts]), starts, lower, upper)
    c, phi, K = sol.x[0] * ts, sol.x[1], sol.x[2] * K_SCALE
    values = np.array([c / 1e3, math.degrees(phi), K])
    T = np.diag([ts / 1e3, 180.0 / math.pi, K_SCALE])
    flags = at_bounds(sol.x, lower, upper)
    specs = [
        ("cohesion_kpa", "cohesion c", "kPa", c_lo / 1e3, c_hi / 1e3),
        ("friction_angle_deg", "friction angle phi", "deg", math.degrees(p_lo), math.degrees(p_hi)),
        ("shear_modulus_m", "shear modulus K", "m", k_lo, k_hi),
    ]
    params, cov = edge_parameters(sol, test.n_samples, values, T, specs, flags)
    combos: dict = {}
    notes = [
        f"{levels.size} normal pressures ({levels.min() / 1e3:.4g}-{levels.max() / 1e3:.4g} kPa) separate "
        "cohesion and friction"
    ]
    si = (
        None
        if cov is None or not all(p.identifiable for p in params)
        else np.diag([1e3, math.pi / 180.0, 1.0]) @ cov @ np.diag([1e3, math.pi / 180.0, 1.0])
    )
    values_si = (c, phi, K)
    return sol, params, combos, notes, si, values_si, flags


def _one_pressure(test, levels, peaks, ts: float, bounds: SoilBounds, strength_model, D) -> tuple:
    """The shear strength at one normal pressure and K (c and phi not identified): as :func:`_two_or_more_pressures`."""
    (c_lo, c_hi), (p_lo, p_hi), (k_lo, k_hi) = bounds.cohesion, bounds.friction_angle, bounds.shear_modulus
    s0 = float(levels[0])
    t_lo, t_hi = c_lo + s0 * math.tan(p_lo), c_hi + s0 * math.tan(p_hi)
    lower = np.array([t_lo / ts, k_lo / K_SCALE])
    upper = np.array([t_hi / ts, k_hi / K_SCALE])
    starts = [np.array([peaks[0] / ts, K / K_SCALE]) for K in K_STARTS]
    sol = solve_bounded(strength_model, D, np.array([ts]), starts, lower, upper)
    values = np.array([sol.x[0] * ts / 1e3, sol.x[1] * K_SCALE])
    T = np.diag([ts / 1e3, K_SCALE])
    flags = at_bounds(sol.x, lower, upper)
    specs = [
        ("shear_strength_kpa", "shear strength", "kPa", t_lo / 1e3, t_hi / 1e3),
        ("shear_modulus_m", "shear modulus K", "m", k_lo, k_hi),
    ]
    both, cov = edge_parameters(sol, test.n_samples, values, T, specs, flags)
    strength, k_par = both
    why = (
        f"one normal pressure ({s0 / 1e3:.4g} kPa): only c + sigma tan(phi) is identified; a test at two "
        "or more normal pressures separates c and phi"
    )
    params = [
        ParameterEstimate("cohesion", None, None, (None, None), False, note=why),
        ParameterEstimate("friction_angle", None, None, (None, None), False, note=why),
        k_par,
    ]
    combos = {
        "shear_strength_kpa": one_level_combination(
            "shear_strength_kpa",
            "c + sigma tan(phi)",
            f"shear strength at the one normal pressure {s0 / 1e3:.4g} kPa",
            strength,
            {"normal_pressure_kpa": s0 / 1e3},
        )
    }
    notes = [why]
    si, values_si = None, (None, None, sol.x[1] * K_SCALE)
    return sol, params, combos, notes, si, values_si, flags
