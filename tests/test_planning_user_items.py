"""What a new user hit in margin / profile / route (issue 19, items 2, 4, 5, 6, 10, 13) and the import rules."""

import ast
import json
import math
import os

import numpy as np
import pytest

import soiltrack.planning as planning
from soiltrack.cli import build_parser, main
from soiltrack.planning import profile, route_from_dict, route_profile
from soiltrack.planning.profile import STANDSTILL_SPEED
from soiltrack.soilmodel import (
    TERRAINS,
    VEHICLES,
    DataError,
    Soil,
    choose_scale,
    format_energy,
    format_force,
    format_power,
    format_torque,
    slip_from_thrust,
    thrust_function,
)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HEAVY, LIGHT = VEHICLES["heavy"], VEHICLES["light"]


def run(capsys, *argv):
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture(scope="module")
def light_fit_json(tmp_path_factory):
    """FIT.json of the issue: a light vehicle's simulated drive log fitted by `soiltrack fit --json`."""
    d = tmp_path_factory.mktemp("fit")
    log, fj = d / "drive.csv", d / "FIT.json"
    assert main(["simulate", "--vehicle", "light", "--terrain", "sandy_loam", "--seed", "1", "-o", str(log)]) == 0
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["fit", str(log), "--vehicle", "light", "--json"]) == 0
    fj.write_text(buf.getvalue())
    return fj


# --- item 2: --plot checked before the work -----------------------------------------------------------------
@pytest.mark.parametrize("bad", ["no_such_folder/p.png", "p.notanimageformat"])
@pytest.mark.parametrize(
    "cmd",
    [
        ["margin", "--vehicle", "heavy", "--terrain", "dry_sand", "--grade-deg", "5"],
        ["profile", "--vehicle", "heavy", "--terrain", "lete_sand", "--v0", "0.5", "--v1", "3", "--distance", "30"],
        ["route", "ROUTE", "--vehicle", "heavy"],
    ],
)
def test_bad_plot_path_exits_2_before_the_work(capsys, tmp_path, cmd, bad):
    route = tmp_path / "route.json"
    route.write_text(
        json.dumps(
            {
                "v0_m_s": 1.0,
                "v_end_m_s": 2.0,
                "objective": "time",
                "max_slip": 0.2,
                "patches": [{"length_m": 10.0, "terrain": "dry_sand", "grade_deg": 0.0}],
            }
        )
    )
    argv = [str(route) if a == "ROUTE" else a for a in cmd] + ["--plot", str(tmp_path / bad)]
    rc, out, err = run(capsys, *argv)
    assert rc == 2
    assert out == ""  # nothing planned: the path is refused first
    assert "--plot" in err and "Traceback" not in err
    assert not (tmp_path / bad).exists()


# --- item 4: standstills and active limits ----------------------------------------------------------------
@pytest.mark.slow
def test_energy_plan_reports_its_standstill_and_active_limits(capsys, light_fit_json):
    rc, out, _ = run(
        capsys,
        "profile",
        "--vehicle",
        "light",
        "--fit",
        light_fit_json,
        "--v0",
        "0.5",
        "--v1",
        "1.5",
        "--duration",
        "8",
        "--objective",
        "energy",
        "--json",
    )
    js = json.loads(out)
    assert rc == 0 and js["success"] is True
    assert len(js["standstills"]) >= 1
    t, v = np.asarray(js["time_s"]), np.asarray(js["speed_m_s"])
    for w in js["standstills"]:
        assert 0.0 <= w["start_s"] < w["end_s"] <= 8.0 + 1e-9
        assert w["duration_s"] == pytest.approx(w["end_s"] - w["start_s"])
        inside = (t >= w["start_s"] - 1e-12) & (t <= w["end_s"] + 1e-12)
        assert inside.sum() >= 2 and np.all(v[inside] < STANDSTILL_SPEED)
    # every run of two or more mesh points below the standstill speed is reported
    below = v < STANDSTILL_SPEED
    covered = np.zeros_like(below)
    for w in js["standstills"]:
        covered |= (t >= w["start_s"] - 1e-12) & (t <= w["end_s"] + 1e-12)
    runs = below & (np.r_[below[1:], False] | np.r_[False, below[:-1]])
    assert np.array_equal(runs, covered)
    assert set(js["active_limits"]) >= {"slip", "torque", "power", "torque_rate"}
    assert all(isinstance(n, int) and 0 <= n <= len(t) - 1 for n in js["active_limits"].values())


def test_time_plan_counts_its_active_limits():
    res = profile(TERRAINS["lete_sand"], HEAVY, v0=0.5, v1=3.0, distance=30.0, intervals=30)
    assert res.success and res.standstills == ()
    assert res.active_limits["power"] > 0  # the heavy vehicle's minimum-time plan rides its power limit


# --- item 5: a consistent first point ---------------------------------------------------------------------
def _steady_thrust_check(js, vehicle, soil, resistance_N):
    r = vehicle.sprocket_radius
    v0, w0, i0 = js["speed_m_s"][0], js["sprocket_speed_rad_s"][0], js["slip"][0]
    assert i0 == pytest.approx(1.0 - v0 / (r * w0), abs=1e-12)  # the slip is the speeds' slip
    assert abs(i0) <= js["limits"]["max_slip"]
    # steady: the first point's thrust carries the resistance at v0 (what slip_from_thrust inverts)
    assert js["thrust_N"][0] == pytest.approx(resistance_N, rel=1e-6)
    i_ss = float(slip_from_thrust(np.array([resistance_N]), soil, vehicle)[0])
    assert i0 == pytest.approx(i_ss, rel=1e-6)


@pytest.mark.parametrize("objective,kw", [("time", {"distance": 30.0}), ("energy", {"duration": 8.0})])
@pytest.mark.slow
def test_first_point_is_the_steady_state_at_v0(objective, kw):
    soil = TERRAINS["dry_sand"]
    res = profile(soil, LIGHT, v0=0.5, v1=1.5, objective=objective, intervals=30, **kw)
    assert res.success and res.initial_slip_source == "steady"
    js = res.to_dict()
    p = js["patches"][0]
    _steady_thrust_check(js, LIGHT, soil, p["rolling_N"] + p["compaction_N"] + p["grade_N"])
    # and the largest slip reported is not that of an unconstrained first point
    assert abs(js["slip"][0]) < 0.05


def test_route_first_point_is_steady_and_a_given_slip_is_kept(capsys, tmp_path):
    route = route_from_dict(
        {
            "v0_m_s": 1.0,
            "v_end_m_s": 2.0,
            "objective": "time",
            "max_slip": 0.2,
            "patches": [
                {"length_m": 10.0, "terrain": "dry_sand", "grade_deg": 5.0},
                {"length_m": 10.0, "terrain": "sandy_loam", "grade_deg": 0.0},
            ],
        }
    )
    res = route_profile(route, HEAVY, intervals=30)
    js = res.to_dict(route=True)
    p = js["patches"][0]
    N = p["normal_load_N"]
    soil = TERRAINS["dry_sand"]
    R = p["rolling_N"] + p["compaction_N"] + p["grade_N"]
    assert res.success and js["thrust_N"][0] == pytest.approx(R, rel=1e-6)
    i_ss = float(slip_from_thrust(np.array([R]), soil, HEAVY, normal_load=N)[0])
    assert js["slip"][0] == pytest.approx(i_ss, rel=1e-6)
    given = profile(soil, HEAVY, v0=1.0, v1=2.0, distance=20.0, intervals=30, slip0=0.05)
    assert given.success and given.initial_slip_source == "given"
    assert given.series["slip"][0] == pytest.approx(0.05, abs=1e-9)
    with pytest.raises(DataError):
        profile(soil, HEAVY, v0=1.0, v1=2.0, distance=20.0, intervals=30, slip0=0.3)  # beyond the 20 % limit
    rc, _, err = run(
        capsys,
        "profile",
        "--vehicle",
        "heavy",
        "--terrain",
        "dry_sand",
        "--v0",
        "1",
        "--v1",
        "2",
        "--distance",
        "20",
        "--initial-slip",
        "0.3",
    )
    assert rc == 2 and "Traceback" not in err


@pytest.mark.slow
def test_plans_from_rest_and_to_rest():
    up = profile(TERRAINS["lete_sand"], HEAVY, v0=0.0, v1=3.0, distance=30.0, intervals=30)
    assert up.success and up.initial_slip_source == "rest" and up.series["slip"][0] == 0.0
    down = profile(TERRAINS["lete_sand"], HEAVY, v0=2.0, v1=0.0, distance=30.0, intervals=30)
    assert down.success and down.series["speed_m_s"][-1] == 0.0
    assert down.series["sprocket_speed_rad_s"][-1] == pytest.approx(0.0, abs=1e-6)  # IPOPT bound tolerance


# --- item 6: the speed limit and the peak speed ----------------------------------------------------------
@pytest.mark.slow
def test_readme_example_peak_speed_and_max_speed(capsys):
    base = [
        "profile",
        "--vehicle",
        "heavy",
        "--terrain",
        "lete_sand",
        "--v0",
        "0.5",
        "--v1",
        "3",
        "--distance",
        "30",
        "--intervals",
        "40",
        "--json",
    ]
    rc, out, _ = run(capsys, *base)
    free = json.loads(out)
    assert rc == 0 and free["peak_speed_m_s"] >= max(free["speed_m_s"]) > 5.0  # it overshoots v1 = 3 m/s
    assert free["limits"]["max_speed_m_s"] is None
    rc, out, _ = run(capsys, *base, "--max-speed", "4")
    lim = json.loads(out)
    assert rc == 0 and lim["success"] is True
    assert lim["peak_speed_m_s"] <= 4.0 * (1 + 1e-6) and max(lim["speed_m_s"]) <= 4.0 * (1 + 1e-6)
    assert lim["peak_speed_m_s"] == pytest.approx(4.0, rel=1e-4)  # it rides the limit
    assert lim["active_limits"]["speed"] > 0
    assert lim["total_time_s"] > free["total_time_s"]
    rc, out, err = run(capsys, *base, "--max-speed", "2")  # below the target speed
    assert rc == 2 and out == "" and "--max-speed" not in out


def test_max_speed_api_checks():
    with pytest.raises(DataError):
        profile(TERRAINS["lete_sand"], HEAVY, v0=0.5, v1=3.0, distance=30.0, max_speed=-1.0)
    with pytest.raises(DataError):
        profile(TERRAINS["lete_sand"], HEAVY, v0=0.5, v1=3.0, distance=30.0, max_speed=2.5)


# --- item 10: units by magnitude ---------------------------------------------------------------------------
def test_units_by_magnitude():
    assert format_force(66.87) == "66.87 N"
    assert format_force(0.9666) == "0.9666 N"
    assert format_force(289760.0) == "289.8 kN"
    assert format_force(-1234.0) == "-1.234 kN"
    assert format_force(999.96) == "1 kN"  # rounds to 1000: written in the next unit
    assert format_torque(16.97) == "16.97 N m" and format_torque(80e3) == "80 kN m"
    assert format_power(600e3) == "600 kW" and format_energy(2.132e6) == "2.132 MJ"
    assert format_force(float("nan")) == "n/a"
    s = choose_scale([12.0, 3.4e5, float("inf")], "N")
    assert (s.factor, s.unit) == (1e-3, "kN")
    assert choose_scale([0.0], "N m").unit == "N m"


def test_light_vehicle_report_numbers_in_newtons():
    res = profile(TERRAINS["dry_sand"], LIGHT, v0=0.2, v1=1.5, distance=5.0, intervals=20)
    js = res.to_dict()
    # the numbers the report writes, through the one helper: all below 1 kN for the light vehicle
    assert max(abs(x) for x in js["sprocket_torque_Nm"]) < 1e3 and min(js["margin_N"]) < 1e3
    assert format_torque(max(abs(x) for x in js["sprocket_torque_Nm"])).endswith(" N m")


# --- item 13: help texts ------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["margin", "profile", "route"])
def test_help_has_description_and_example(name, capsys):
    sub = next(a for a in build_parser()._actions if a.dest == "command").choices[name]
    assert sub.description and len(sub.description.split()) > 20
    assert sub.epilog.startswith("example:") and f"soiltrack {name} " in sub.epilog
    assert all(a.help for a in sub._actions if a.option_strings and a.dest != "help")
    with pytest.raises(SystemExit) as e:
        main([name, "--help"])
    assert e.value.code == 0


# --- house rules: no private cross-module import, one name per concept ------------------------------------------
def _modules():
    for folder in ("planning",):
        for f in sorted(os.listdir(os.path.join(ROOT, folder))):
            if f.endswith(".py"):
                yield os.path.join(ROOT, folder, f)
    for f in ("cmd_margin.py", "cmd_profile.py", "cmd_route.py"):
        yield os.path.join(ROOT, "soiltrack", f)


def test_no_private_name_imported_from_another_module():
    bad = []
    for path in _modules():
        tree = ast.parse(open(path, encoding="utf-8").read())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                bad += [
                    f"{os.path.basename(path)}: {node.module}.{a.name}"
                    for a in node.names
                    if a.name.startswith("_") and a.name != "__version__"
                ]
            if (
                isinstance(node, ast.Attribute)
                and node.attr.startswith("_")
                and not node.attr.startswith("__")
                and isinstance(node.value, ast.Name)
                and node.value.id in ("margin", "ocp", "profile", "replay")
            ):
                bad.append(f"{os.path.basename(path)}: {node.value.id}.{node.attr}")
    assert bad == []


def test_speed_plan_is_the_only_name():
    assert hasattr(planning, "SpeedPlan") and "SpeedPlan" in planning.__all__
    assert not hasattr(planning, "ProfileResult") and "ProfileResult" not in planning.__all__
    assert isinstance(
        profile(TERRAINS["lete_sand"], HEAVY, v0=0.5, v1=3.0, distance=30.0, intervals=20), planning.SpeedPlan
    )


def test_soil_thrust_is_the_model_core():
    from soiltrack.planning.forces import soil_thrust

    s = TERRAINS["dry_sand"]
    f = thrust_function("full")
    expect = float(
        f(0.2, s.cohesion, s.friction_angle, s.shear_modulus, HEAVY.weight, HEAVY.track_length, HEAVY.track_width)
    )
    assert soil_thrust(s.as_vector(), 0.2, HEAVY.weight, HEAVY, "full")[0] == pytest.approx(expect, rel=1e-14)
    assert math.isfinite(expect) and isinstance(Soil(*s.as_vector()), Soil)
