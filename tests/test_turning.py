"""Turning logs: the two-track simulator, `simulate --two-track --turns`, soil from turns, `fit --motion`."""

from __future__ import annotations

import csv
import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest

from soiltrack.identify.turning import fit_turning
from soiltrack.soilmodel import TERRAINS, VEHICLES, DataError
from soiltrack.soilmodel.turning import read_two_track, simulate_turning_log

HEAVY = dataclasses.replace(VEHICLES["heavy"], tread=2.5, cg_height=1.0)
TURNS = "4:10:15,13:19:-8,22:27:25"


def _run(*args):
    return subprocess.run([sys.executable, "-m", "soiltrack", *args], capture_output=True, text=True, timeout=600)


@pytest.fixture
def vehicle_json(tmp_path):
    d = HEAVY.to_dict()
    d.pop("name", None)
    p = tmp_path / "heavy_tread.json"
    p.write_text(json.dumps(d))
    return str(p)


def test_simulator_mirror_and_kinematics():
    """A left turn and the same right turn: the tracks' channels swap, the yaw rate changes sign."""
    kw = dict(duration_s=8.0, sample_rate_hz=10.0, noise="none", return_truth=True)
    _, a = simulate_turning_log(HEAVY, TERRAINS["lete_sand"], turns="2:7:10", **kw)
    _, b = simulate_turning_log(HEAVY, TERRAINS["lete_sand"], turns="2:7:-10", **kw)
    np.testing.assert_allclose(a["torque_left"], b["torque_right"], rtol=1e-7, atol=1e-6)
    np.testing.assert_allclose(a["w_left"], b["w_right"], rtol=1e-9)
    np.testing.assert_allclose(a["yaw_rate"], -b["yaw_rate"], atol=1e-12)
    k = 50  # mid-turn: u / Om = 10 m, the outer (right) track faster and pulling, the inner braking
    assert a["u"][k] / a["yaw_rate"][k] == pytest.approx(10.0, rel=1e-9)
    assert a["w_right"][k] > a["w_left"][k] and a["torque_right"][k] > 0 > a["torque_left"][k]


def test_simulate_cli_writes_two_track_columns(tmp_path, vehicle_json):
    out = tmp_path / "turn.csv"
    p = _run(
        "simulate",
        "--vehicle",
        vehicle_json,
        "--two-track",
        "--turns",
        "2:5:10",
        "--duration",
        "6",
        "--rate",
        "10",
        "--seed",
        "1",
        "-o",
        str(out),
    )
    assert p.returncode == 0, p.stderr
    rows = list(csv.reader(out.open()))
    assert rows[0] == [
        "time_s",
        "sprocket_torque_left_Nm",
        "sprocket_torque_right_Nm",
        "sprocket_speed_left_rad_s",
        "sprocket_speed_right_rad_s",
        "vehicle_speed_m_s",
        "yaw_rate_rad_s",
    ]
    log = read_two_track(str(out))
    assert log.n_samples == 61
    mid = (log.time > 3) & (log.time < 4.5)
    assert np.all(log.yaw_rate[mid] > 0.1) and np.all(log.speed_right[mid] > log.speed_left[mid])
    assert log.turning()[mid].all() and not log.turning()[log.time < 1.5].any()


@pytest.mark.parametrize(
    "args, words",
    [
        (["--turns", "2:5:10"], "--two-track"),  # turns without --two-track
        (["--two-track", "--turns", "2:5:1.0"], "half the tread"),
        (["--two-track", "--turns", "2:5:10,4:6:-10"], "overlap"),
        (["--two-track", "--turns", "2:9:10"], "T0 < T1"),
        (["--two-track", "--turns", "2:5"], "T0:T1:RADIUS_M"),
        (["--two-track", "--kind", "sweep"], "drive logs only"),
    ],
)
def test_simulate_cli_bad_turns_exit_2(vehicle_json, args, words):
    p = _run("simulate", "--vehicle", vehicle_json, "--duration", "6", "--rate", "10", "--seed", "1", *args)
    assert p.returncode == 2 and "Traceback" not in p.stderr and words in p.stderr, p.stderr


def test_simulate_cli_without_tread_exit_2():
    p = _run("simulate", "--vehicle", "heavy", "--two-track", "--turns", "2:5:10", "--duration", "6", "--seed", "1")
    assert p.returncode == 2 and "tread_m" in p.stderr and "Traceback" not in p.stderr


@pytest.mark.slow  # long end-to-end (quick loop: README); CI runs it
def test_turn_too_tight_for_the_soil_refused():
    with pytest.raises(DataError, match="cannot give this motion"):
        simulate_turning_log(HEAVY, TERRAINS["clayey_soil"], turns="2:5:1.3", duration_s=6, sample_rate_hz=10)


def test_fit_cli_bad_input_exit_2(tmp_path, vehicle_json):
    log = simulate_turning_log(HEAVY, TERRAINS["lete_sand"], turns="2:5:10", duration_s=6, sample_rate_hz=10, seed=2)
    two = tmp_path / "two.csv"
    log.write_csv(str(two))
    comb = tmp_path / "comb.csv"  # a yaw rate without the two-track columns
    with comb.open("w") as fh:
        fh.write("time_s,sprocket_torque_Nm,sprocket_speed_rad_s,vehicle_speed_m_s,yaw_rate_rad_s\n")
        for k in range(log.n_samples):
            fh.write(
                f"{log.time[k]},{log.torque_left[k] + log.torque_right[k]},"
                f"{0.5 * (log.speed_left[k] + log.speed_right[k])},{log.vehicle_speed[k]},{log.yaw_rate[k]}\n"
            )
    no_yaw = tmp_path / "noyaw.csv"
    cols = {k: v for k, v in log.columns().items() if k != "yaw_rate_rad_s"}
    with no_yaw.open("w") as fh:
        fh.write(",".join(cols) + "\n")
        for row in zip(*cols.values()):
            fh.write(",".join(repr(float(x)) for x in row) + "\n")
    for args, words in (
        ([str(comb), "--vehicle", vehicle_json], "yaw rate without the two-track columns"),
        ([str(two), "--vehicle", "heavy", "--motion", "turning"], "tread_m"),
        ([str(no_yaw), "--vehicle", vehicle_json, "--motion", "turning"], "yaw_rate_rad_s"),
    ):
        p = _run("fit", *args, "--json")
        assert p.returncode == 2 and words in p.stderr and "Traceback" not in p.stderr, (args, p.stderr)


def _truth(soil):
    return HEAVY.contact_area * soil.cohesion + HEAVY.weight * np.tan(soil.friction_angle), soil.shear_modulus


@pytest.mark.slow
def test_soil_recovered_from_turns_within_intervals():
    """Turning samples alone: F_max and K inside their 95 % intervals for most seeds (nominal: 95 %)."""
    soil = TERRAINS["lete_sand"]
    Ft, Kt = _truth(soil)
    inside = []
    for seed in range(1, 5):
        log = simulate_turning_log(HEAVY, soil, turns=TURNS, duration_s=30, sample_rate_hz=25, seed=seed)
        f = fit_turning(log, HEAVY, motion="turning")
        assert f.outcome == "usable", f.outcome_reason
        inside.append(f.max_thrust_ci95[0] <= Ft <= f.max_thrust_ci95[1])
        inside.append(f.shear_modulus_ci95[0] <= Kt <= f.shear_modulus_ci95[1])
        assert abs(f.max_thrust / Ft - 1) < 0.05
    assert sum(inside) >= 7  # of 8: P(at most 6 inside | 95 % each) = 0.6 %


@pytest.mark.slow
def test_by_motion_turns_determine_what_straight_driving_does_not(tmp_path, vehicle_json):
    """Gentle straight driving pins only the initial slope; the turns pin F_max and K (CLI JSON)."""
    log = simulate_turning_log(HEAVY, TERRAINS["lete_sand"], turns=TURNS, duration_s=30, sample_rate_hz=25, seed=7)
    path = tmp_path / "log.csv"
    log.write_csv(str(path))
    p = _run("fit", str(path), "--vehicle", vehicle_json, "--motion", "turning", "--json")
    assert p.returncode == 0, p.stderr
    js = json.loads(p.stdout)
    bm = js["by_motion"]
    assert set(bm) == {"straight", "turning", "all", "agreement_se"}
    assert bm["straight"]["outcome"] == "not_usable" and bm["straight"]["max_thrust_N"] is None
    assert bm["turning"]["outcome"] == "usable" and js["outcome"] == "usable"
    Ft, Kt = _truth(TERRAINS["lete_sand"])
    assert abs(js["max_thrust_N"] / Ft - 1) < 0.05
    slope = Ft * HEAVY.track_length / (2 * Kt)  # what the straight samples determine
    lo, hi = bm["straight"]["initial_slope_ci95"]
    assert lo < slope < hi
    assert js["c_phi_separable"] is False  # the load transfer of these turns is too small (SE of the share)
    assert bm["all"]["outcome"] == "usable"


# --- margin --turn-radius -----------------------------------------------------------------------
@pytest.mark.slow  # long end-to-end (quick loop: README); CI runs it
def test_turn_margin_both_sides_of_the_limit():
    from soiltrack.planning.turning import turn_margin

    soil = TERRAINS["clayey_soil"]
    m = turn_margin(HEAVY, soil, radius_m=10.0, speed_m_s=2.0)
    assert m.turn_feasible and m.turn_limited_by is None
    assert m.torque_right_Nm > 0 > m.torque_left_Nm and m.slip_outer > 0 > m.slip_inner
    r = m.min_turn_radius_m
    assert 0.5 * HEAVY.tread < r < 10.0
    above = turn_margin(HEAVY, soil, radius_m=-1.01 * r, speed_m_s=2.0)  # mirror: a right turn, same limit
    below = turn_margin(HEAVY, soil, radius_m=0.99 * r, speed_m_s=2.0)
    assert above.turn_feasible and not below.turn_feasible and below.turn_limited_by == "soil"
    assert above.torque_left_Nm > 0 > above.torque_right_Nm  # right turn: the left track is outer
    # the torque limit: half the vehicle's max_sprocket_torque per sprocket, just above / below the need
    need = m.torque_right_Nm
    for factor, ok in ((1.02, True), (0.98, False)):
        veh = dataclasses.replace(HEAVY, max_sprocket_torque=2 * need * factor)
        t = turn_margin(veh, soil, radius_m=10.0, speed_m_s=2.0)
        assert t.turn_feasible is ok and t.turn_limited_by == (None if ok else "torque")
    faster = turn_margin(HEAVY, soil, radius_m=10.0, speed_m_s=4.0)
    assert faster.min_turn_radius_m > r  # faster: a wider smallest radius


@pytest.mark.slow  # long end-to-end (quick loop: README); CI runs it
def test_margin_cli_turn(vehicle_json):
    p = _run(
        "margin", "--vehicle", vehicle_json, "--terrain", "lete_sand", "--turn-radius", "10", "--speed", "2", "--json"
    )
    assert p.returncode == 0, p.stderr
    js = json.loads(p.stdout)
    for k in (
        "torque_left_Nm",
        "torque_right_Nm",
        "slip_outer",
        "slip_inner",
        "min_turn_radius_m",
        "turn_feasible",
        "available_N",
        "traversable",
    ):
        assert k in js
    assert js["turn_feasible"] is True and js["torque_right_Nm"] > js["torque_left_Nm"]
    p = _run("margin", "--vehicle", vehicle_json, "--terrain", "lete_sand", "--turn-radius", "1.0", "--speed", "2")
    assert p.returncode == 2 and "half the tread" in p.stderr and "Traceback" not in p.stderr
    p = _run("margin", "--vehicle", "heavy", "--terrain", "lete_sand", "--turn-radius", "10", "--speed", "2")
    assert p.returncode == 2 and "tread_m" in p.stderr
    p = _run("margin", "--vehicle", vehicle_json, "--terrain", "lete_sand", "--turn-radius", "10")
    assert p.returncode == 2 and "--speed" in p.stderr
    p = _run(
        "margin", "--vehicle", vehicle_json, "--terrain", "clayey_soil", "--turn-radius", "2", "--speed", "4", "--json"
    )
    assert p.returncode == 1 and json.loads(p.stdout)["turn_feasible"] is False
