"""Closed-loop control (soiltrack.planning.control): limits, slip optimum, stuck events, terrain changes,
user plants, and the `soiltrack drive` command. Numbers, checked on the library's plant and on an
independent numpy plant (tests/control_plant.py)."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))
from control_plant import drive, from_vehicle, stuck_events  # noqa: E402

from soiltrack.planning import route_from_dict  # noqa: E402
from soiltrack.planning.control import (  # noqa: E402
    PlantSettings,
    TerrainPatch,
    TrackPlant,
    make_controller,
    run_closed_loop,
)
from soiltrack.planning.control.optimum import optimal_slip, optimal_slip_reference  # noqa: E402
from soiltrack.soilmodel import TERRAINS, VEHICLES, DataError  # noqa: E402

HEAVY, LIGHT = VEHICLES["heavy"], VEHICLES["light"]


def _route(v0, v1, patches, max_slip=0.3):
    return route_from_dict({"v0_m_s": v0, "v_end_m_s": v1, "max_slip": max_slip, "patches": patches})


def _jh(V, route, soils, mus=None, **kw):
    mus = mus or [0.0] * len(soils)
    pat = [
        (p.length_m, s.cohesion, s.friction_angle, s.shear_modulus, p.grade_deg, m)
        for p, s, m in zip(route.patches, soils, mus)
    ]
    return from_vehicle(V, pat, v0=route.v0_m_s, **kw)


# a traversable heavy route: flat, a 20 deg climb on a weaker soil than planned, flat
CLIMB = _route(
    0.3,
    3.0,
    [
        {"length_m": 15, "terrain": "lete_sand"},
        {"length_m": 25, "terrain": "lete_sand", "grade_deg": 20},
        {"length_m": 10, "terrain": "lete_sand"},
    ],
)
CLIMB_TRUE = [TERRAINS["lete_sand"], TERRAINS["dry_sand"], TERRAINS["lete_sand"]]


def test_optimum_agrees_with_the_traction_study():
    for V, F, K, g in ((HEAVY, 200e3, 0.012, 0.0), (LIGHT, 210.0, 0.025, 18.0), (HEAVY, 170e3, 0.025, 15.0)):
        fast, ref = optimal_slip(V, F, K, g), optimal_slip_reference(V, F, K, g)
        assert abs(fast - ref) < 0.004, (fast, ref)
    assert optimal_slip(LIGHT, 100.0, 0.02, 40.0) is None  # no drawbar pull at any slip


@pytest.mark.parametrize("mu_s", [0.0, 0.5])
def test_library_plant_agrees_with_independent_plant_at_constant_torque(mu_s):
    route = _route(1.0, 1.0, [{"length_m": 100, "terrain": "lete_sand", "grade_deg": 5}])
    lib = TrackPlant(HEAVY, [TerrainPatch(100, TERRAINS["lete_sand"], 5.0, mu_s)], PlantSettings(v0=1.0))
    ind = _jh(HEAVY, route, [TERRAINS["lete_sand"]], [mu_s])
    for _ in range(250):  # 5 s at 45 kN m
        m = lib.step(45e3)
        ind.step(45e3)
    assert m["vehicle_speed_m_s"] == pytest.approx(ind.v, rel=0.01)
    assert lib.slip == pytest.approx(ind.slip, rel=0.03)


def test_sinkage_estimator_recovers_mu_s_from_the_hull_balance():
    """Samples of an exact hull balance with mu_s = 0.8 (and 0): the block least squares gives it back."""
    from soiltrack.planning.control.belief import SinkageEstimator, patch_load

    V, g = HEAVY, 5.0
    N = patch_load(V, g)
    R0 = V.rolling_resistance * N + V.weight * math.sin(math.radians(g))
    rng = np.random.default_rng(1)
    for mu in (0.8, 0.0):
        est = SinkageEstimator(V, g)
        dt, n = 0.02, 100
        i = 0.03 + 0.05 * (1 + np.sin(np.arange(n + 1) / 7))  # slips of 3 % to 13 %
        F = 1.4e5 * (1 - np.exp(-i * 40))
        v = np.empty(n + 1)
        v[0] = 2.0
        for k in range(n):
            v[k + 1] = v[k] + dt * (F[k] - R0 - N * mu * i[k]) / V.mass
        w = v / (V.sprocket_radius * (1 - i))
        for k in range(n):  # the sprocket balance: M = r F + I dw/dt
            M = V.sprocket_radius * F[k] + V.sprocket_inertia * (w[k + 1] - w[k]) / dt
            est.update(k * dt, M, w[k], v[k] + rng.normal(0, 0.002))
        val = est.value
        assert val is not None and val[0] == pytest.approx(mu, abs=0.03) and val[1] < 0.05


def test_optimum_with_slip_sinkage_is_the_net_power_optimum():
    """optimal_slip with mu_s maximises (F(i) - R - N mu_s i)(1 - i) (brute force on a fine grid)."""
    from soiltrack.planning.control.belief import patch_load
    from soiltrack.soilmodel.traction import slip_factor

    V, K, g = HEAVY, 0.025, 10.0
    N = patch_load(V, g)
    F = 1.19e5
    R = V.rolling_resistance * N + V.weight * math.sin(math.radians(g))
    i = np.linspace(1e-4, 0.5, 20001)
    gi = np.array([float(slip_factor(x, V.track_length, K)) for x in i[::20]])
    P = (F * gi - R - N * 1.0 * i[::20]) * (1 - i[::20])
    ref = i[::20][int(np.argmax(P))]
    opt = optimal_slip(V, F, K, g, 1.0)
    assert opt == pytest.approx(ref, abs=0.004)
    assert opt < optimal_slip(V, F, K, g) - 0.05  # sinkage moves the optimum well below the JH one


def test_controller_slip_inverse_agrees_with_soilmodel():
    from soiltrack.planning.control.belief import SoilBelief
    from soiltrack.soilmodel.traction import shear_bracket_inverse

    ctl = make_controller("slip", HEAVY, target_speed_m_s=1.0)
    b = SoilBelief(1e5, 0.02, "prior")
    for y in (0.05, 0.3, 0.7, 0.95, 0.99):
        ref = float(shear_bracket_inverse(y)) * 0.02 / HEAVY.track_length
        assert ctl._slip_for(b, y * 1e5) == pytest.approx(ref, rel=2e-4)


@pytest.mark.parametrize("kind", ["pi", "slip", pytest.param("mpc", marks=pytest.mark.slow)])  # mpc: long (quick loop)
def test_limits_held_on_the_independent_plant(kind):
    ctl = make_controller(kind, HEAVY, route=CLIMB)
    plant = _jh(HEAVY, CLIMB, CLIMB_TRUE, sigma_v=0.005, sigma_w=0.02)
    a, arrived = drive(ctl, plant, CLIMB.length_m, 60.0)
    M, w_meas = a[1:, 4], a[:-1, 6]  # each torque with the sprocket speed measured when it was commanded
    assert arrived
    assert np.max(np.abs(a[:, 4])) <= HEAVY.max_sprocket_torque * (1 + 1e-12)
    assert np.max(M * w_meas) <= HEAVY.max_power * (1 + 1e-9)
    assert np.min(a[:, 4]) >= -0.5 * HEAVY.max_sprocket_torque - 1e-9
    if kind != "pi":
        assert np.max(a[:, 3]) <= 0.3  # the route's slip limit, on the true slip


def test_slip_controller_settles_at_the_estimates_optimal_slip():
    """Uniform soil, a climb that keeps the slip loop limiting while the vehicle accelerates."""
    route = _route(0.3, 3.0, [{"length_m": 60, "terrain": "lete_sand", "grade_deg": 25}])
    ctl = make_controller("slip", HEAVY, route=route, probe=False)
    plant = TrackPlant(HEAVY, [TerrainPatch(60, TERRAINS["lete_sand"], 25.0)], PlantSettings(v0=0.3))
    m = plant.step(0.0)
    rows = []
    for _ in range(400):
        M = ctl.command(m)
        m = plant.step(M)
        rows.append((plant.slip, ctl.slip_ceiling, ctl.limiting))
    lim = [(s, c) for s, c, how in rows if how == "slip"]
    assert len(lim) > 50  # 1 s or more with the slip loop limiting
    s, c = np.array(lim[-25:]).T  # its last half second
    b = ctl.belief.belief(0, 0)
    assert c[-1] == pytest.approx(optimal_slip(HEAVY, b.max_thrust_N, b.shear_modulus_m, 25.0))
    assert np.median(s) == pytest.approx(c[-1], abs=0.02)


@pytest.mark.parametrize("kind", ["slip", pytest.param("mpc", marks=pytest.mark.slow)])  # mpc: long (quick loop)
def test_true_soil_no_stuck_event_on_a_traversable_route(kind):
    ctl = make_controller(kind, HEAVY, route=CLIMB, soil="true", true_soils=CLIMB_TRUE)
    plant = _jh(HEAVY, CLIMB, CLIMB_TRUE, sigma_v=0.005, sigma_w=0.02)
    a, arrived = drive(ctl, plant, CLIMB.length_m, 60.0)
    assert arrived and stuck_events(a) == 0


@pytest.mark.slow
def test_untraversable_climb_stop_with_reason_and_pi_digs_in():
    """Snow at 27 deg under the heavy vehicle: R > F_max at any slip; planned as LETE sand."""
    route = _route(
        0.3, 2.0, [{"length_m": 12, "terrain": "lete_sand"}, {"length_m": 20, "terrain": "lete_sand", "grade_deg": 27}]
    )
    true = [TERRAINS["lete_sand"], TERRAINS["snow"]]
    res = {}
    for name, kind, kw in (
        ("pi", "pi", {}),
        ("slip", "slip", {}),
        ("true", "slip", {"soil": "true", "true_soils": true}),
    ):
        ctl = make_controller(kind, HEAVY, route=route, **kw)
        a, arrived = drive(ctl, _jh(HEAVY, route, true, sigma_v=0.005, sigma_w=0.02), route.length_m, 40.0)
        res[name] = (a, arrived, ctl)
    assert stuck_events(res["pi"][0]) >= 1 and not res["pi"][1]
    for name in ("slip", "true"):
        a, arrived, ctl = res[name]
        assert not arrived and stuck_events(a) == 0
        stops = [e for e in ctl.events if e["kind"] == "stop"]
        assert stops and stops[-1]["patch"] == 1 and stops[-1]["required_N"] > stops[-1]["available_N"]
    assert res["true"][0][-1, 1] < 12.0  # the true-soil controller stops before the climb


def test_change_of_terrain_is_followed():
    ctl = make_controller("slip", HEAVY, route=CLIMB)
    plant = TrackPlant(
        HEAVY,
        [TerrainPatch(p.length_m, s, p.grade_deg) for p, s in zip(CLIMB.patches, CLIMB_TRUE)],
        PlantSettings(v0=0.3, sigma_vehicle_speed=0.005, sigma_sprocket_speed=0.02, sigma_torque=400.0),
    )
    r = run_closed_loop(ctl, plant, distance_m=CLIMB.length_m, target_speed_m_s=3.0, max_slip=0.3, max_time_s=60.0)
    assert r.arrived and r.metrics["stuck_events"] == 0
    S = r.series
    on_climb = [k for k, p in enumerate(S["patch"]) if p == 1]
    k = on_climb[-1]
    assert S["belief_max_thrust_N"][k] == pytest.approx(S["true_max_thrust_N"][k], rel=0.10)  # dry sand, not LETE
    planned = 0.5 * 2.8 * 2 * 1.3e3 + 329e3 * math.cos(math.radians(20)) * math.tan(math.radians(31.1))
    assert abs(S["belief_max_thrust_N"][k] - planned) > 0.05 * planned
    # the traction probe only where the limit binds: the climb (resistance ~0.7 of the believed pull), not
    # the flat patches (~0.08, below probe_need 0.2), where a probe spends energy on slip and overspeed
    kinds = {(e["kind"], e["patch"]) for e in ctl.events if e["kind"].startswith("probe")}
    assert ("probe", 1) in kinds and ("probe_skipped", 0) in kinds
    assert ("probe", 0) not in kinds and ("probe", 2) not in kinds
    need = [e["need"] for e in ctl.events if e["kind"] == "probe"]
    assert need and min(need) >= 0.2


@pytest.mark.slow
def test_mpc_keeps_pace_with_the_true_soil_on_a_weaker_climb():
    """Heavy CLIMB planned as LETE sand, dry sand under the climb: the MPC on its on-line estimate, with and
    without the filtered hull-force residual (``mpc_disturbance_s``), arrives within 3 % of the time of the same
    MPC given the true soil. (With the previous on-line estimator it lagged by 12.9 % without the option; the
    estimator's relaxation rule and ramp-horizon rule closed that gap: 17.14 s against 16.96 s.)"""
    kinds = {"true": {"soil": "true", "true_soils": CLIMB_TRUE}, 0.0: {"mpc_disturbance_s": 0.0}}
    kinds[1.0] = {"mpc_disturbance_s": 1.0}
    t = {}
    for key, kw in kinds.items():
        ctl = make_controller("mpc", HEAVY, route=CLIMB, **kw)
        a, arrived = drive(ctl, _jh(HEAVY, CLIMB, CLIMB_TRUE, sigma_v=0.005, sigma_w=0.02), CLIMB.length_m, 60.0)
        assert arrived and stuck_events(a) == 0
        t[key] = a[-1, 0]
    assert t[0.0] <= 1.03 * t["true"]
    assert t[1.0] <= 1.03 * t["true"]


# light: flat, then a snow climb planned as LETE sand (the belief overrates F_max: 294 N against 200 N)
SNOW_CLIMB = _route(
    0.3,
    1.5,
    [{"length_m": 4, "terrain": "lete_sand"}, {"length_m": 12, "terrain": "lete_sand", "grade_deg": 25}],
)
SNOW_CLIMB_TRUE = [TERRAINS["lete_sand"], TERRAINS["snow"]]


@pytest.mark.parametrize("floor", [True, False])
def test_mpc_speed_floor_holds_the_pace_on_an_overrated_soil(floor):
    """The MPC on the planned soil (no estimator) on a climb whose soil is weaker than planned: its plan's slips
    are too small (the believed curve gives the thrust at less slip) and it predicts an acceleration that does
    not come. With the speed floor (the speed loop's integral under the optimal-slip ceiling) it arrives within
    10 % of the true-soil MPC's time; without it, it does not (measured: it stalls on the climb within 60 s)."""
    t = {}
    for key, kw in (("true", {"soil": "true", "true_soils": SNOW_CLIMB_TRUE}), ("nominal", {"soil": "nominal"})):
        ctl = make_controller("mpc", LIGHT, route=SNOW_CLIMB, mpc_speed_floor=floor, **kw)
        plant = _jh(LIGHT, SNOW_CLIMB, SNOW_CLIMB_TRUE, sigma_v=0.005, sigma_w=0.02)
        a, arrived = drive(ctl, plant, SNOW_CLIMB.length_m, 60.0)
        assert stuck_events(a) == 0
        t[key] = a[-1, 0] if arrived else math.inf
    assert math.isfinite(t["true"])
    assert (t["nominal"] <= 1.10 * t["true"]) == floor


# light: flat, then snow at 32 deg planned as LETE sand (needs ~40 % slip, beyond the 0.3 limit: the benchmark's steep)
STEEP_LIGHT = _route(
    0.3,
    1.5,
    [{"length_m": 12, "terrain": "lete_sand"}, {"length_m": 20, "terrain": "lete_sand", "grade_deg": 32}],
)
STEEP_LIGHT_TRUE = [TERRAINS["lete_sand"], TERRAINS["snow"]]


def test_standing_after_a_stop_does_not_change_the_belief_or_resume():
    """The MPC on its estimate stops on a climb it cannot carry within the slip limit. Standing with no drive
    torque the samples carry no thrust (the slip is 0/0, noise): the belief of the climb must not move and the
    governor must not resume. (Before ``learn_min_speed`` the estimator was fed those samples: its F_max of the
    climb wandered 239-250 N while standing here, and at an earlier estimator's commit the governor resumed 2.6 s
    after the stop and spun at the limit for 31 s.)"""
    # the stall rule off (stall_s): the stop here is the belief's (the estimate's F_max identified while the
    # tracks spun), which the governor could revisit; a stall stop never is (test_stall_stops_where_...)
    ctl = make_controller("mpc", LIGHT, route=STEEP_LIGHT, stall_s=1e6)
    plant = _jh(LIGHT, STEEP_LIGHT, STEEP_LIGHT_TRUE, sigma_v=0.005, sigma_w=0.02)
    meas, held, t_stop = plant.step(0.0), [], None
    while meas["time_s"] < 25.0:
        M = ctl.command(meas)
        meas = plant.step(M)
        if t_stop is None and any(e["kind"] == "stop" for e in ctl.events):
            t_stop = meas["time_s"]
        if t_stop is not None and meas["time_s"] > t_stop + 1.0:
            assert M <= 0.0 and ctl.last["v_ref"] == 0.0  # holds: no drive torque, no resume
            b = ctl.belief.belief(1, 1)
            held.append((b.max_thrust_N, b.shear_modulus_m, b.slip_sinkage))
    stops = [e for e in ctl.events if e["kind"] == "stop"]
    assert stops and stops[0]["patch"] == 1 and stops[0]["limit"] == "slip"
    assert not [e for e in ctl.events if e["kind"] == "resume"]
    assert len(held) > 400 and len(set(held)) == 1  # ~13 s standing, one belief


def test_stall_stops_where_the_belief_says_go():
    """Heavy vehicle, 3 m/s, snow at 27 deg planned as LETE sand (beyond F_max at any slip): the estimator does not
    identify F_max while the tracks spin at rest (identify_min_samples), so the belief keeps the planned soil and
    says go. The stall rule (``stall_s``) stops the drive and says why. (Before it: no stop, 30 s above the slip
    limit in the benchmark's 62 s, 45.8 s in 94 s.)"""
    route = _route(
        0.3, 3.0, [{"length_m": 12, "terrain": "lete_sand"}, {"length_m": 20, "terrain": "lete_sand", "grade_deg": 27}]
    )
    true = [TERRAINS["lete_sand"], TERRAINS["snow"]]
    ctl = make_controller("slip", HEAVY, route=route)
    plant = _jh(HEAVY, route, true, sigma_v=0.005, sigma_w=0.02)
    a, arrived = drive(ctl, plant, route.length_m, 30.0)
    assert not arrived and stuck_events(a) == 0
    stops = [e for e in ctl.events if e["kind"] == "stop"]
    assert stops and stops[-1]["patch"] == 1 and stops[-1]["limit"] == "stall" and "stalled" in stops[-1]["reason"]
    assert not [e for e in ctl.events if e["kind"] == "resume"]
    above = float(np.sum(a[:, 3] > 0.3)) * 0.02  # true slip above the limit, s
    assert above < 3.0
    after = a[:, 0] > stops[-1]["time_s"] + 0.1
    assert after.any() and np.all(a[after, 4] <= 0.0)  # holds: no drive torque


def test_user_plant_object_accepted():
    route = _route(0.5, 1.0, [{"length_m": 5, "terrain": "lete_sand"}])
    plant = _jh(LIGHT, route, [TERRAINS["lete_sand"]])
    ctl = make_controller("slip", LIGHT, route=route)
    r = run_closed_loop(ctl, plant, distance_m=5.0, target_speed_m_s=1.0, max_slip=0.3, max_time_s=30.0)
    assert r.arrived and r.metrics["stuck_events"] == 0 and r.metrics["tracking_rmse_m_s"] < 0.3
    assert r.series["true_max_thrust_N"][0] is None  # no truth from a user plant: measured signals

    class Broken:
        pass

    with pytest.raises(DataError, match="step"):
        run_closed_loop(ctl, Broken(), distance_m=5.0, target_speed_m_s=1.0, max_slip=0.3, max_time_s=1.0)


def test_time_cpu_off_reads_no_cpu_clock_and_commands_the_same():
    route = _route(0.5, 1.0, [{"length_m": 5, "terrain": "lete_sand"}])
    out = {}
    for flag in (True, False):
        ctl = make_controller("slip", LIGHT, route=route, time_cpu=flag)
        plant = _jh(LIGHT, route, [TERRAINS["lete_sand"]], sigma_v=0.005, sigma_w=0.02)
        a, _ = drive(ctl, plant, 5.0, 2.0)
        out[flag] = a[:, 4]
        assert len(ctl.step_times_s) == len(a) and len(ctl.step_cpu_s) == (len(a) if flag else 0)
    assert np.array_equal(out[True], out[False])


def test_two_track_measurement_gives_a_pair():
    ctl = make_controller("pi", LIGHT, target_speed_m_s=1.0)
    out = ctl.command(
        {"time_s": 0.0, "sprocket_speed_left_rad_s": 10.0, "sprocket_speed_right_rad_s": 10.0, "vehicle_speed_m_s": 0.5}
    )
    assert isinstance(out, tuple) and out[0] == out[1] > 0
    with pytest.raises(DataError, match="vehicle_speed_m_s"):
        ctl.command({"time_s": 0.1, "sprocket_speed_rad_s": 1.0})


# ---------------------------------------------------------------- command line
def _run(*args, timeout=300):
    return subprocess.run(
        [sys.executable, "-m", "soiltrack", "drive", *args], capture_output=True, text=True, timeout=timeout
    )


def _write(tmp_path, obj, name="route.json"):
    p = tmp_path / name
    p.write_text(json.dumps(obj))
    return str(p)


ROUTE = {
    "v0_m_s": 0.5,
    "v_end_m_s": 1.0,
    "max_slip": 0.3,
    "patches": [
        {"length_m": 4, "terrain": "lete_sand"},
        {"length_m": 4, "terrain": "lete_sand", "grade_deg": 10, "true_terrain": "dry_sand"},
    ],
}


@pytest.mark.parametrize(
    "patch, args, needle",
    [
        ({}, ["--controller", "fuzzy"], "--controller"),
        ({"patches": [{"length_m": 4, "terrain": "lete_sand", "true_terrain": "mud"}]}, [], "patches[0].true_terrain"),
        (
            {"patches": [{"length_m": 4, "terrain": "lete_sand", "true_terrain": "snow", "true_soil": {}}]},
            [],
            "not both",
        ),
        (
            {
                "patches": [
                    {"length_m": 4, "terrain": "lete_sand", "true_soil": {"cohesion_kpa": 1, "friction_angle_deg": 30}}
                ]
            },
            [],
            "true_soil.shear_modulus_m",
        ),
        ({"patches": [{"length_m": -4, "terrain": "lete_sand"}]}, [], "patches[0].length_m"),
        (
            {"patches": [{"length_m": 4, "terrain": "lete_sand"}, {"length_m": 4, "true_slip_sinkage": 3}]},
            [],
            "patches[1].true_slip_sinkage",
        ),
        ({}, ["--dt", "5"], "--dt"),
        ({}, ["--speed", "-1"], "--speed"),
    ],
)
def test_drive_bad_input_exit_2(tmp_path, patch, args, needle):
    path = _write(tmp_path, dict(ROUTE, **patch))
    a = ["--controller", "pi"] if "--controller" not in args else []
    p = _run(path, "--vehicle", "light", *a, *args)
    assert p.returncode == 2, p.stderr
    assert needle in p.stderr and "Traceback" not in p.stderr


def test_drive_missing_vehicle_exit_2(tmp_path):
    p = _run(_write(tmp_path, ROUTE), "--vehicle", str(tmp_path / "nope.json"), "--controller", "slip")
    assert p.returncode == 2 and "nope.json" in p.stderr and "Traceback" not in p.stderr


@pytest.mark.slow
def test_drive_json_and_plot(tmp_path):
    png = str(tmp_path / "d.png")
    p = _run(_write(tmp_path, ROUTE), "--vehicle", "light", "--controller", "slip", "--json", "--plot", png)
    assert p.returncode == 0, p.stderr
    js = json.loads(p.stdout)
    assert js["controller"] == "slip" and js["arrived"] is True and js["reason"] is None
    keys = {
        "time_s",
        "energy_J",
        "tracking_rmse_m_s",
        "peak_slip",
        "time_above_slip_limit_s",
        "stuck_events",
        "adapt_time_s",
    }
    assert keys <= set(js["metrics"])
    assert {"pi", "fixed_slip", "nominal_soil", "true_soil"} <= set(js["baselines"])
    assert all(keys <= set(m) for m in js["baselines"].values())
    n = len(js["series"]["time_s"])
    assert n > 10 and all(len(v) == n for v in js["series"].values())
    assert js["metrics"]["time_s"] == pytest.approx(js["series"]["time_s"][-1])
    assert os.path.getsize(png) > 10_000


# the dig route (benchmarks/bench_control.py "dig", heavy): start at 1 m/s on a 10 deg snow rise with slip
# sinkage mu_s = 1 (net pull peaks at 5.7 % slip, below the resistance at 20 %), then 40 m of dry sand at 24 deg
# (about 10 % slip to hold the speed); planned with the true soils, the sinkage unknown to the plan
DIG = _route(
    1.0,
    3.0,
    [
        {"length_m": 15, "terrain": "snow", "grade_deg": 10},
        {"length_m": 8, "terrain": "lete_sand"},
        {"length_m": 40, "terrain": "dry_sand", "grade_deg": 24},
        {"length_m": 8, "terrain": "lete_sand"},
    ],
)
DIG_TRUE = [TERRAINS["snow"], TERRAINS["lete_sand"], TERRAINS["dry_sand"], TERRAINS["lete_sand"]]
DIG_MU = [1.0, 0.0, 0.0, 0.0]


@pytest.mark.slow
def test_dig_route_no_fixed_limit_gets_through_the_estimate_does():
    """The issue's case: pi digs in on the soft rise, 20 % digs in there too, 7 % stalls on the loose climb;
    the slip controller learns the sinkage on-line (its ceiling drops below the net-pull peak) and arrives."""
    out = {}
    for name, kind, kw in (
        ("pi", "pi", {}),
        ("fixed_7", "fixed_slip", {"fixed_slip": 0.07}),
        ("fixed_20", "fixed_slip", {"fixed_slip": 0.2}),
        ("slip", "slip", {}),
    ):
        ctl = make_controller(kind, HEAVY, route=DIG, **kw)
        arr, arrived = drive(ctl, _jh(HEAVY, DIG, DIG_TRUE, DIG_MU, sigma_v=0.005, sigma_w=0.02), 71.0, 90.0)
        out[name] = (arrived, stuck_events(arr), arr[:, 1].max())
    assert not out["pi"][0] and out["pi"][1] >= 1 and out["pi"][2] < 15  # dug in on the soft rise
    assert not out["fixed_20"][0] and out["fixed_20"][2] < 15  # dug in on the soft rise
    assert not out["fixed_7"][0] and out["fixed_7"][2] > 23  # through the soft rise, stalled on the climb
    assert out["slip"][0] and out["slip"][1] == 0
