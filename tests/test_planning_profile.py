"""Optimal-control profiles: replayed open-loop through the full dynamics, routes, infeasibility."""

import dataclasses
import math

import numpy as np
import pytest

from soiltrack.planning import profile, replay, route_from_dict, route_profile
from soiltrack.soilmodel import TERRAINS, VEHICLES, DataError

HEAVY = VEHICLES["heavy"]
G = 9.81


def check_replay(res, veh, v_end):
    """Replay the ZOH torque with CVODES (8 points per interval) and check speeds and limits."""
    assert res.success, res.message
    rp = replay(res, veh, substeps=8)
    lim = res.limits
    # planned final speed reached (measured deviations: below 0.1 % on the cases below)
    assert rp.speed[-1] == pytest.approx(v_end, rel=5e-3)
    # planned speeds at every mesh point (measured: below 3e-3 m/s)
    assert np.max(np.abs(rp.speed[rp.node] - np.asarray(res.series["speed_m_s"]))) < 1e-2
    # limits between the mesh points too
    assert np.max(np.abs(rp.slip)) <= lim["max_slip"]
    assert np.max(np.abs(rp.torque)) <= lim["max_torque_Nm"] * (1 + 1e-9)
    assert np.max(rp.power) <= lim["max_power_W"] * (1 + 1e-9)
    # the planned time is the replayed time, series have equal lengths
    assert rp.time[-1] == pytest.approx(res.total_time_s, rel=1e-12)
    n = {len(v) for v in res.series.values()}
    assert len(n) == 1
    return rp


@pytest.fixture(scope="module")
def min_time():
    return profile(
        TERRAINS["lete_sand"], HEAVY, v0=0.5, v1=3.0, distance=30.0, max_slip=0.2, objective="time", intervals=40
    )


@pytest.mark.parametrize("terrain", ["lete_sand", "clayey_soil"])
def test_min_time_profile_replayed_open_loop_keeps_limits(terrain):
    res = profile(TERRAINS[terrain], HEAVY, v0=0.5, v1=3.0, distance=30.0, max_slip=0.2, intervals=40)
    check_replay(res, HEAVY, 3.0)
    assert res.series["distance_m"][-1] == pytest.approx(30.0)


def test_braking_profile_and_light_vehicle():
    res = profile(TERRAINS["clayey_soil"], HEAVY, v0=3.0, v1=0.5, distance=30.0, max_slip=0.2, intervals=40)
    check_replay(res, HEAVY, 0.5)
    assert min(res.series["slip"]) < -0.1  # it brakes hard (skid), within the limit
    light = VEHICLES["light"]
    check_replay(profile(TERRAINS["dry_sand"], light, v0=0.2, v1=1.5, distance=5.0, intervals=30), light, 1.5)


def test_energy_objective_is_slower_and_cheaper(min_time):
    e = profile(
        TERRAINS["lete_sand"], HEAVY, v0=0.5, v1=3.0, distance=30.0, max_slip=0.2, objective="energy", intervals=40
    )
    check_replay(e, HEAVY, 3.0)
    assert e.energy_J < min_time.energy_J
    assert e.total_time_s > min_time.total_time_s
    # the sprocket energy can be no less than the kinetic energy gained plus the rolling work
    m, W = HEAVY.mass, HEAVY.weight
    assert e.energy_J > 0.5 * m * (3.0**2 - 0.5**2) + 0.05 * W * 30.0


def test_warm_resolve_reuses_the_problem(min_time):
    kw = dict(v0=0.5, v1=3.0, distance=30.0, max_slip=0.2, intervals=40)
    first = profile(TERRAINS["lete_sand"], HEAVY, **kw)
    again = profile(TERRAINS["lete_sand"], HEAVY, **kw)
    assert again.warm_start
    assert again.total_time_s == pytest.approx(min_time.total_time_s, rel=1e-6)
    assert again.iterations <= 3  # warm from its own solution (measured: 1-2 iterations)
    # a new target speed and a new soil re-solve the same built problem, warm
    other = profile(TERRAINS["dry_sand"], HEAVY, **dict(kw, v1=2.5))
    assert other.warm_start and other.success and first.success


def test_route_patch_boundaries_on_the_mesh_and_replay():
    route = route_from_dict(
        {
            "v0_m_s": 1.0,
            "v_end_m_s": 2.0,
            "objective": "time",
            "max_slip": 0.2,
            "patches": [
                {"length_m": 20, "terrain": "lete_sand"},
                {"length_m": 10, "terrain": "clayey_soil", "grade_deg": 10},
                {
                    "length_m": 15,
                    "soil": {"cohesion_kpa": 1.0, "friction_angle_deg": 30, "shear_modulus_m": 0.02},
                    "grade_deg": -5,
                },
            ],
        }
    )
    res = route_profile(route, HEAVY, intervals=45)
    check_replay(res, HEAVY, 2.0)
    x, p = np.asarray(res.series["distance_m"]), np.asarray(res.series["patch"])
    for b in (20.0, 30.0):
        assert np.min(np.abs(x - b)) < 1e-9
    assert set(p) == {0, 1, 2}
    assert np.all(x[p == 1][:-1] >= 20.0 - 1e-9) and np.all(x[p == 1] <= 30.0 + 1e-9)
    assert "patch" in res.to_dict(route=True)


def test_infeasible_patch_is_named_with_numbers():
    route = route_from_dict(
        {
            "v0_m_s": 1.0,
            "v_end_m_s": 2.0,
            "patches": [
                {"length_m": 20, "terrain": "lete_sand"},
                {"length_m": 10, "terrain": "clayey_soil", "grade_deg": 40},
            ],
        }
    )
    res = route_profile(route, HEAVY)
    assert not res.success and res.reason["patch"] == 1
    soil = TERRAINS["clayey_soil"]
    W, th = HEAVY.weight, math.radians(40)
    N = W * math.cos(th)
    b, l = HEAVY.track_width, HEAVY.track_length
    k = soil.k_c / b + soil.k_phi
    z0 = (N / (2 * b * l) / k) ** (1 / soil.n)
    need = 0.05 * N + 2 * b * k * z0 ** (soil.n + 1) / (soil.n + 1) + W * math.sin(th)
    assert res.reason["required_N"] == pytest.approx(need, rel=1e-9)
    assert res.reason["limit"] == "soil"  # no slip gives 2.4 times the soil's limit
    assert res.reason["short_by_N"] == pytest.approx(need - res.reason["available_N"], rel=1e-12)
    assert "patch 1" in res.message and res.series["time_s"] == []


def test_torque_and_power_limits_named():
    weak = dataclasses.replace(HEAVY, max_sprocket_torque=10_000.0)
    res = profile(TERRAINS["lete_sand"], weak, v0=1.0, v1=2.0, distance=50.0, grade_deg=10)
    assert not res.success and res.reason["limit"] == "torque"
    assert res.reason["available_N"] == pytest.approx(10_000.0 / 0.3)
    res = profile(TERRAINS["lete_sand"], HEAVY, v0=1.0, v1=20.0, distance=50.0, grade_deg=10)
    assert not res.success and res.reason["limit"] == "power"


@pytest.mark.parametrize(
    "kw", [dict(v0=-1.0), dict(max_slip=1.2), dict(intervals=1), dict(distance=-3.0), dict(objective="fast")]
)
def test_bad_arguments(kw):
    args = dict(v0=0.5, v1=3.0, distance=30.0)
    args.update(kw)
    with pytest.raises(DataError) as e:
        profile(TERRAINS["lete_sand"], HEAVY, **args)
    assert list(kw)[0] in str(e.value)


def test_route_json_errors_name_the_field():
    with pytest.raises(DataError, match=r"patches\[0\]\.length_m"):
        route_from_dict({"patches": [{"length_m": -5, "terrain": "lete_sand"}]})
    with pytest.raises(DataError, match=r"patches\[1\]\.terrain"):
        route_from_dict({"patches": [{"length_m": 5, "terrain": "lete_sand"}, {"length_m": 5, "terrain": "mud"}]})


@pytest.mark.slow
def test_robust_profile_keeps_the_slip_limit_for_most_sampled_soils():
    from soiltrack.identify import fit
    from soiltrack.soilmodel import SensorNoise, Soil, simulate_slip_sweep

    data = simulate_slip_sweep(HEAVY, Soil.from_kpa_deg(1.3, 31.1, 0.012), seed=3, noise=SensorNoise(force_rel=0.05))
    f = fit(data, HEAVY, model="cohesion-free")
    res = profile(
        f, HEAVY, v0=1.0, v1=3.0, distance=30.0, grade_deg=10, intervals=30, confidence=0.9, robust_samples=40
    )
    check_replay(res, HEAVY, 3.0)
    rb = res.robust
    # measured with 100 soils: 2 % of them break the slip limit with the robust plan, 27 % with the nominal one
    assert rb["violation_fraction"] <= 0.1
    assert rb["nominal_violation_fraction"] > rb["violation_fraction"]
    with pytest.raises(DataError, match="confidence"):
        profile(TERRAINS["lete_sand"], HEAVY, v0=1.0, v1=3.0, distance=30.0, confidence=0.9)


def test_torque_rate_and_duration():
    res = profile(TERRAINS["lete_sand"], HEAVY, v0=0.5, v1=3.0, distance=30.0, intervals=30, torque_rate=1e5)
    check_replay(res, HEAVY, 3.0)
    M = np.asarray(res.series["sprocket_torque_Nm"][:-1])
    dt = np.diff(res.series["time_s"])
    assert np.all(np.abs(np.diff(M)) <= 1e5 * 0.5 * (dt[1:] + dt[:-1]) * (1 + 1e-6))
    assert res.active_limits["torque_rate"] > 0
    d = profile(TERRAINS["lete_sand"], HEAVY, v0=1.0, v1=2.0, duration=10.0, objective="energy", intervals=20)
    assert d.success and d.total_time_s == pytest.approx(10.0, rel=1e-8)
    check_replay(d, HEAVY, 2.0)
    with pytest.raises(DataError, match="objective"):
        profile(TERRAINS["lete_sand"], HEAVY, v0=1.0, v1=2.0, duration=10.0, objective="time")
