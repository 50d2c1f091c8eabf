"""Re-planning while driving (issue 22, deliverable 3): on-line estimates in margin/profile, the Replanner."""

from dataclasses import dataclass

import numpy as np
import pytest

from soiltrack.planning import Replanner, margin, profile, uncertainty_from_estimate
from soiltrack.soilmodel import TERRAINS, VEHICLES, DataError, Soil, max_thrust

HEAVY, LIGHT = VEHICLES["heavy"], VEHICLES["light"]


@dataclass(frozen=True)
class Estimate:
    """The public attributes of soiltrack.identify.OnlineEstimator's per-update estimate (a local stand-in)."""

    max_thrust_N: float
    shear_modulus_m: float
    covariance: np.ndarray | None
    normal_load_N: float
    identifiable: tuple
    converged: bool


def estimate_of(soil: Soil, vehicle, rel_F=0.03, rel_K=0.1, rho=0.3, **kw) -> Estimate:
    F = float(max_thrust(soil, vehicle))
    sF, sK = rel_F * F, rel_K * soil.shear_modulus
    cov = np.array([[sF * sF, rho * sF * sK], [rho * sF * sK, sK * sK]])
    base = dict(
        max_thrust_N=F,
        shear_modulus_m=soil.shear_modulus,
        covariance=cov,
        normal_load_N=vehicle.weight,
        identifiable=("max_thrust", "shear_modulus"),
        converged=True,
    )
    base.update(kw)
    return Estimate(**base)


def plain(soil: Soil) -> Soil:
    """The soil without Bekker parameters (an estimate carries none: no compaction resistance)."""
    return Soil(soil.cohesion, soil.friction_angle, soil.shear_modulus)


def test_margin_takes_an_online_estimate_like_a_fit():
    soil = plain(TERRAINS["sandy_loam"])
    est = estimate_of(soil, HEAVY)
    m_est = margin(est, HEAVY, grade_deg=0.0, drawbar_N=20e3)
    m_soil = margin(soil, HEAVY, grade_deg=0.0, drawbar_N=20e3)
    # on the flat the load is the estimate's: the available thrust is that of the soil itself
    assert m_est.available_N == pytest.approx(m_soil.available_N, rel=1e-9)
    assert m_est.margin_N == pytest.approx(m_soil.margin_N, rel=1e-9)
    assert 0.0 <= m_est.p_traversable <= 1.0 and m_est.worst_case_margin_N < m_est.margin_N
    # a demand right at the available thrust is a coin toss
    edge = margin(est, HEAVY, drawbar_N=m_soil.margin_N + 20e3)
    assert edge.p_traversable == pytest.approx(0.5, abs=0.05)
    # on a grade the ridge's weakest soil is used: never more than the soil itself gives
    g_est, g_soil = margin(est, HEAVY, grade_deg=15.0), margin(soil, HEAVY, grade_deg=15.0)
    assert g_est.available_N <= g_soil.available_N * (1 + 1e-9)


def test_estimate_refused_without_covariance_or_convergence():
    soil = plain(TERRAINS["sandy_loam"])
    with pytest.raises(DataError):
        margin(estimate_of(soil, HEAVY, covariance=None, identifiable=("slope",)), HEAVY)
    with pytest.raises(DataError):
        margin(estimate_of(soil, HEAVY, converged=False), HEAVY)
    with pytest.raises(DataError):
        uncertainty_from_estimate(estimate_of(soil, HEAVY, covariance=np.eye(3)), HEAVY)
    with pytest.raises(DataError):
        uncertainty_from_estimate(estimate_of(soil, HEAVY, max_thrust_N=float("nan")), HEAVY)
    with pytest.raises(DataError):
        uncertainty_from_estimate(estimate_of(soil, HEAVY, covariance=np.array([[1.0, 2.0], [2.0, 1.0]])), HEAVY)


def test_uncertainty_from_estimate_is_the_ridge_at_its_load():
    soil = plain(TERRAINS["dry_sand"])
    est = estimate_of(soil, LIGHT)
    u = uncertainty_from_estimate(est, LIGHT)
    assert u.kind == "ridge" and u.fitted_load == LIGHT.weight
    assert np.allclose(u.mean, [est.max_thrust_N, est.shear_modulus_m]) and np.allclose(u.cov, est.covariance)
    c, phi, K = u.soils_at(u.mean, LIGHT.weight)[0]
    assert LIGHT.contact_area * c + LIGHT.weight * np.tan(phi) == pytest.approx(est.max_thrust_N, rel=1e-9)


def test_profile_takes_an_online_estimate():
    soil = plain(TERRAINS["dry_sand"])
    a = profile(estimate_of(soil, HEAVY), HEAVY, v0=0.5, v1=3.0, distance=30.0, intervals=30)
    b = profile(soil, HEAVY, v0=0.5, v1=3.0, distance=30.0, intervals=30)
    assert a.success and b.success
    assert a.total_time_s == pytest.approx(b.total_time_s, rel=1e-5)


def test_replanner_warm_and_equal_to_a_cold_plan():
    rp = Replanner(HEAVY, distance=30.0, v1=3.0, intervals=40)
    first = rp.replan(TERRAINS["lete_sand"], v0=0.5)
    assert first.success and not first.warm_start
    second = rp.replan(TERRAINS["dry_sand"], v0=0.5)
    assert second.success and second.warm_start
    cold = profile(TERRAINS["dry_sand"], HEAVY, v0=0.5, v1=3.0, distance=30.0, intervals=40)
    assert second.total_time_s == pytest.approx(cold.total_time_s, rel=1e-5)
    # a re-plan from the current state: new speed and slip, a new soil (an on-line estimate)
    third = rp.replan(estimate_of(plain(TERRAINS["sandy_loam"]), HEAVY), v0=1.2, slip0=0.03)
    assert third.success and third.warm_start and third.series["slip"][0] == pytest.approx(0.03, abs=1e-9)
    assert third.series["speed_m_s"][0] == pytest.approx(1.2) and rp.count == 3 and rp.last is third
    rp.reset()
    assert not rp.replan(TERRAINS["lete_sand"], v0=0.5).warm_start


def test_replanner_bad_arguments():
    with pytest.raises(DataError):
        Replanner(HEAVY, v1=3.0)  # neither distance nor duration
    with pytest.raises(DataError):
        Replanner(HEAVY, v1=3.0, distance=30.0, objective="fast")
    with pytest.raises(DataError):
        Replanner(HEAVY, v1=-1.0, distance=30.0)
