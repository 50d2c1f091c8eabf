"""`soiltrack margin`, `profile`, `route`: JSON contracts, exit codes, bad input."""

import json
import os
import subprocess
import sys

import pytest

from soiltrack.cli import main
from soiltrack.identify import fit
from soiltrack.soilmodel import VEHICLES, Soil, simulate_slip_sweep

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
V120 = os.path.join(ROOT, "examples", "data", "heavy_120kN.json")
MARGIN_KEYS = {
    "available_N",
    "required_N",
    "margin_N",
    "margin_ratio",
    "traversable",
    "p_traversable",
    "slip_required",
    "max_grade_deg",
    "limited_by",
    "soil_limit_N",
    "drivetrain_limit_N",
    "required",
}
SERIES = (
    "time_s",
    "distance_m",
    "speed_m_s",
    "sprocket_speed_rad_s",
    "slip",
    "sprocket_torque_Nm",
    "thrust_N",
    "margin_N",
)


def run(capsys, *argv):
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.mark.parametrize(
    "terrain,grade,rc_expected", [("dry_sand", "15", 0), ("clayey_soil", "15", 1), ("clayey_soil", "0", 0)]
)
def test_margin_fig7_exit_codes_and_json(capsys, terrain, grade, rc_expected):
    rc, out, _ = run(capsys, "margin", "--vehicle", V120, "--terrain", terrain, "--grade-deg", grade, "--json")
    js = json.loads(out)
    assert rc == rc_expected and js["traversable"] is (rc == 0)
    assert MARGIN_KEYS <= set(js)
    assert set(js["required"]) == {"rolling_N", "compaction_N", "grade_N", "inertia_N", "drawbar_N"}
    assert js["p_traversable"] is None


def test_margin_from_fit_json_and_plot(capsys, tmp_path):
    data = simulate_slip_sweep(VEHICLES["heavy"], Soil.from_kpa_deg(1.3, 31.1, 0.012), seed=5)
    path = tmp_path / "fit.json"
    path.write_text(fit(data, VEHICLES["heavy"]).to_json())
    png = tmp_path / "m.png"
    rc, out, _ = run(
        capsys, "margin", "--vehicle", "heavy", "--fit", str(path), "--grade-deg", "10", "--json", "--plot", str(png)
    )
    js = json.loads(out)
    assert rc == 0 and 0.0 <= js["p_traversable"] <= 1.0 and js["worst_case_margin_N"] <= js["margin_N"]
    assert png.stat().st_size > 1000


def test_profile_json_series_and_plot(capsys, tmp_path):
    png = tmp_path / "p.png"
    rc, out, _ = run(
        capsys,
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
        "--max-slip",
        "0.2",
        "--intervals",
        "30",
        "--json",
        "--plot",
        str(png),
    )
    js = json.loads(out)
    assert rc == 0 and js["success"] is True
    assert len({len(js[k]) for k in SERIES}) == 1 and len(js["time_s"]) == 31
    assert js["speed_m_s"][-1] == pytest.approx(3.0) and max(abs(s) for s in js["slip"]) <= 0.2
    assert js["sprocket_torque_Nm"][-1] == js["sprocket_torque_Nm"][-2]
    for k in ("status", "message", "objective", "total_time_s", "energy_J", "solve_time_s"):
        assert k in js
    assert png.stat().st_size > 1000


def test_route_infeasible_exit_1_names_patch(capsys, tmp_path):
    route = tmp_path / "route.json"
    route.write_text(
        json.dumps(
            {
                "v0_m_s": 1.0,
                "v_end_m_s": 2.0,
                "objective": "time",
                "max_slip": 0.2,
                "patches": [
                    {"length_m": 20, "terrain": "lete_sand", "grade_deg": 0},
                    {"length_m": 10, "terrain": "clayey_soil", "grade_deg": 40},
                ],
            }
        )
    )
    rc, out, _ = run(capsys, "route", str(route), "--vehicle", "heavy", "--json")
    js = json.loads(out)
    assert rc == 1 and js["success"] is False and js["reason"]["patch"] == 1
    assert set(js["reason"]) == {"patch", "limit", "required_N", "available_N", "short_by_N"}


@pytest.mark.parametrize(
    "argv,named",
    [
        (["margin", "--vehicle", "heavy", "--terrain", "no_such"], "--terrain"),
        (["margin", "--vehicle", "heavy", "--terrain", "dry_sand", "--max-slip", "1.5"], "max_slip"),
        (["margin", "--vehicle", "heavy", "--fit", "/nonexistent/fit.json"], "fit.json"),
        (
            ["profile", "--vehicle", "heavy", "--terrain", "lete_sand", "--v0", "-1", "--v1", "3", "--distance", "30"],
            "--v0",
        ),
        (["profile", "--vehicle", "heavy", "--terrain", "lete_sand", "--v0", "1", "--v1", "3"], "distance"),
        (["route", "/nonexistent/route.json", "--vehicle", "heavy"], "route.json"),
    ],
)
def test_bad_input_exit_2_names_the_argument(capsys, argv, named):
    rc, out, err = run(capsys, *argv)
    assert rc == 2 and named in err and "Traceback" not in err


def test_route_bad_field_exit_2_without_traceback(tmp_path):
    route = tmp_path / "route.json"
    route.write_text('{"patches": [{"length_m": -5, "terrain": "lete_sand"}]}')
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    p = subprocess.run(
        [sys.executable, "-m", "soiltrack", "route", str(route), "--vehicle", "heavy", "--json"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env=env,
        timeout=300,
    )
    assert p.returncode == 2 and "patches[0].length_m" in p.stderr and "Traceback" not in p.stderr
