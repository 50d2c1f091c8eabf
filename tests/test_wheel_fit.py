"""Identification with the rigid wheel: recovery from sweeps simulated by an independent implementation."""

from __future__ import annotations

import math

import numpy as np
import pytest

import wheel_oracle as oracle
from soiltrack.identify.wheel import WheelFitOptions, fit_wheel, pure_error
from soiltrack.soilmodel import DataError
from soiltrack.soilmodel.rigid_wheel import RigidWheel
from soiltrack.soilmodel.wheel_sweep import WheelSweep

R, B = 0.058, 0.05
WHEEL = RigidWheel(R, B)
SLIPS = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9]
# (c Pa, phi rad, K m, k = k_c/b + k_phi, n)
SOILS = [(1000.0, math.radians(30), 0.012, 1.55e6, 1.1), (4000.0, math.radians(22), 0.02, 0.9e6, 0.7)]
TRUE_KEYS = (("cohesion_kpa", 1e-3, 0), ("friction_angle_deg", 180 / math.pi, 1), ("shear_modulus_m", 1.0, 2))


def _sweep(soil, loads, seed, with_sinkage=True, sd_z=0.0002):
    i, dp, W, z = oracle.sweep(SLIPS, loads, *soil, R, B, sd_dp=0.005 * float(np.mean(loads)), sd_z=sd_z, seed=seed)
    return WheelSweep(slip=i, drawbar_pull=dp, normal_load=W, sinkage=z if with_sinkage else None)


@pytest.mark.slow
def test_recovery_from_an_independent_implementation():
    covered, total = 0, 0
    for soil in SOILS:
        for loads in ([20.0], [15.0, 30.0, 45.0]):
            for seed in (0, 1):
                r = fit_wheel(_sweep(soil, loads, seed), WHEEL)
                assert r.success
                for key, fac, k in TRUE_KEYS:
                    e = r.parameters[key]
                    assert e.identifiable  # c, phi, K: in the row space (weakly at one load)
                    total += 1
                    covered += e.edge_ci95[0] <= soil[k] * fac <= e.edge_ci95[1]
                # one wheel width: k_c and k_phi are not separable, their combination is
                assert not r.parameters["bekker_kc"].identifiable and not r.parameters["bekker_kphi"].identifiable
                assert r.parameters["bekker_kc"].ci95 == (None, None)
                kb = next(c for c in r.combinations if c.name == "k_c / b + k_phi")
                assert kb.estimable
                assert r.rank == 5 and len(r.null_space) == 1
                nd = r.null_space[0]
                # the direction (dk_c, dk_phi) = (b, -1) t, which keeps k_c / b + k_phi (edge units: kN)
                assert nd["bekker_kc"] / nd["bekker_kphi"] == pytest.approx(-B, rel=1e-6)
                assert (
                    max(abs(nd[k]) for k in ("cohesion_kpa", "friction_angle_deg", "shear_modulus_m", "bekker_n"))
                    < 1e-6
                )
    assert covered / total >= 0.85, (covered, total)


@pytest.mark.slow
def test_one_load_separates_c_and_phi_only_weakly_three_loads_well():
    one = fit_wheel(_sweep(SOILS[0], [20.0], 2), WHEEL)
    three = fit_wheel(_sweep(SOILS[0], [15.0, 30.0, 45.0], 2), WHEEL)
    assert (
        one.parameters["cohesion_kpa"].weakly_identifiable and one.parameters["friction_angle_deg"].weakly_identifiable
    )
    assert not three.parameters["cohesion_kpa"].weakly_identifiable
    assert not three.parameters["friction_angle_deg"].weakly_identifiable
    w1 = np.diff(one.parameters["friction_angle_deg"].edge_ci95)[0]
    w3 = np.diff(three.parameters["friction_angle_deg"].edge_ci95)[0]
    assert w3 < 0.5 * w1


@pytest.mark.slow
def test_sinkage_solved_from_the_load_with_a_known_bekker_soil():
    soil = SOILS[0]
    d = _sweep(soil, [20.0, 35.0], 3, with_sinkage=False)
    k_phi = soil[3]  # k_c = 0: all of k in k_phi
    r = fit_wheel(d, WHEEL, WheelFitOptions(fixed={"bekker_kc": 0.0, "bekker_kphi": k_phi, "bekker_n": soil[4]}))
    assert r.success and not r.sinkage_measured
    for key, fac, k in TRUE_KEYS:
        e = r.parameters[key]
        assert e.identifiable and e.edge_ci95[0] <= soil[k] * fac <= e.edge_ci95[1], key
    z_true = np.array([oracle.sinkage(i, W, *soil, R, B) for i, W in zip(d.slip, d.normal_load)])
    assert np.allclose(r.predict_sinkage(d), z_true, rtol=5e-3)
    assert r.rmse_sinkage is None and r.parameters["bekker_n"].fixed


@pytest.mark.slow
def test_bound_pinned_values_are_flagged():
    soil = (
        0.0,
        math.radians(30),
        0.012,
        1.55e6,
        1.1,
    )  # no cohesion: with this seed c ends on its lower bound
    r = fit_wheel(_sweep(soil, [20.0, 35.0], 4), WHEEL, WheelFitOptions(fixed={"bekker_n": 1.1}))
    c = r.parameters["cohesion_kpa"]
    assert c.value == 0.0 and c.at_bound and c.bound_side == "lower"
    assert r.to_dict()["parameters"]["cohesion_kpa"]["at_bound"] is True
    assert len(r.warnings) == 1
    assert c.ci95[0] == 0.0 and c.ci95[1] > 0  # intersected with the bounds


def test_pure_error_groups_repeats_by_slip_and_load():
    slip = np.array([0.2, 0.2, 0.21, 0.5, 0.5, 0.5])
    load = np.array([20.0, 21.0, 20.5, 20.0, 40.0, 41.0])
    dp = np.array([1.0, 2.0, 3.0, 5.0, 7.0, 9.0])
    ss, dof, groups = pure_error(dp, slip, load)
    assert groups == 3 and dof == 3
    assert ss == pytest.approx(2.0 + 2.0)


def test_too_few_rows_are_refused():
    d = _sweep(SOILS[0], [20.0], 0).subset(slice(0, 3))
    with pytest.raises(DataError):
        fit_wheel(d, WHEEL)
    with pytest.raises(DataError):
        WheelFitOptions(fixed={"mass": 1.0})
    with pytest.raises(DataError):
        WheelFitOptions(effects=("grade",))


@pytest.mark.slow
def test_a_warm_start_solves_once_and_lands_on_the_grids_answer():
    """A start at another fit's answer on nearly the same data (a left-out slip level) is one solve, and it
    ends where the multi-start grid ends; a start that is not seven finite numbers is refused."""
    d = _sweep(SOILS[0], [20.0], 0)
    full = fit_wheel(d, WHEEL)
    part = d.subset(np.abs(d.slip - 0.5) > 1e-9)  # one slip level left out, as the diagnosis does
    grid = fit_wheel(part, WHEEL)
    warm = fit_wheel(part, WHEEL, WheelFitOptions(start=tuple(full.theta)))
    assert full.success and grid.success and warm.success
    assert (grid.starts, warm.starts) == (6, 1)
    assert warm.rmse_drawbar_pull == pytest.approx(grid.rmse_drawbar_pull, rel=1e-6)
    assert warm.rmse_sinkage == pytest.approx(grid.rmse_sinkage, rel=1e-6)
    np.testing.assert_allclose(warm.theta[:3], grid.theta[:3], rtol=1e-3)
    with pytest.raises(DataError, match="start"):
        WheelFitOptions(start=(1.0, 2.0))
    with pytest.raises(DataError, match="start"):
        WheelFitOptions(start=tuple(full.theta[:-1]) + (math.nan,))
