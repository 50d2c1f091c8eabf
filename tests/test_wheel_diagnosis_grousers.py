"""The wheel diagnosis weighs grousers (Bekker's grouser term, the height fitted) with its one decision rule."""

from __future__ import annotations

import json
import math

import pytest

import wheel_oracle as oracle
from soiltrack.cli import main
from soiltrack.identify.wheel import WheelFitOptions
from soiltrack.identify.wheel.diagnosis import diagnose_wheel
from soiltrack.soilmodel.rigid_wheel import RigidWheel
from soiltrack.soilmodel.wheel_sweep import WheelSweep, write_wheel_sweep

R, B, C, PHI = 0.15, 0.08, 2000.0, math.radians(30)
#: c and phi held (as from a shear test): Bekker's factors multiply them, so h needs one of them known
HELD = {"bekker_kc": 0.0, "cohesion": C, "friction_angle": PHI}


def _sweep(h: float, seed: int) -> WheelSweep:
    s, dp, W, z = oracle.sweep(
        [0.05, 0.15, 0.3, 0.45, 0.7],
        [60.0, 100.0],
        C,
        PHI,
        0.015,
        1.2e6,
        1.1,
        R,
        B,
        h=h,
        sd_dp=0.3,
        sd_z=3e-4,
        seed=seed,
    )
    return WheelSweep(slip=s, drawbar_pull=dp, normal_load=W, sinkage=z)


@pytest.mark.slow
def test_grousered_data_on_a_smooth_wheels_json_are_diagnosed_as_grousers():
    d = diagnose_wheel(_sweep(0.012, 3), RigidWheel(radius=R, width=B), WheelFitOptions(fixed=HELD))
    assert d.verdict == "grousers", d.report()
    row = next(r for r in d.ranking if r["effect"] == "grousers")
    assert row["admissible"] is True and row["p_value"] < 0.01
    assert 0.010 < row["parameters"]["grouser_height_m"] < 0.014  # truth 12 mm
    assert d.to_dict()["soil_after"] is not None
    assert "grousers: Bekker's grouser term with the height fitted" in d.report()


@pytest.mark.slow
def test_smooth_data_are_not_diagnosed_as_grousers():
    d = diagnose_wheel(_sweep(0.0, 4), RigidWheel(radius=R, width=B), WheelFitOptions(fixed=HELD))
    assert d.verdict != "grousers", d.report()
    row = next(r for r in d.ranking if r["effect"] == "grousers")
    assert row["p_value"] is not None and (row["p_value"] >= 0.01 or not row["admissible"])


@pytest.mark.slow  # long end-to-end (quick loop: README); CI runs it
def test_grousers_are_not_weighed_with_c_and_phi_both_fitted():
    d = diagnose_wheel(
        _sweep(0.0, 5),
        RigidWheel(radius=R, width=B),
        WheelFitOptions(fixed={"bekker_kc": 0.0}),
        candidates=("grousers",),
    )
    assert all(r["effect"] != "grousers" for r in d.ranking)
    assert any("grousers: not weighed" in n and "confounded" in n for n in d.notes)


@pytest.mark.slow
def test_a_grousered_wheels_json_height_too_low_is_diagnosed_as_grousers():
    # the JSON says 6 mm, the data were made with 12 mm: the fitted height is the hypothesis
    d = diagnose_wheel(
        _sweep(0.012, 7), RigidWheel(radius=R, width=B, grouser_height=0.006), WheelFitOptions(fixed=HELD)
    )
    assert d.verdict == "grousers", d.report()
    row = next(r for r in d.ranking if r["effect"] == "grousers")
    assert 0.010 < row["parameters"]["grouser_height_m"] < 0.014


@pytest.mark.slow  # long end-to-end (quick loop: README); CI runs it
def test_cohesion_held_at_zero_does_not_make_grousers_weighable():
    opts = WheelFitOptions(fixed={"cohesion": 0.0, "bekker_kc": 0.0})
    d = diagnose_wheel(_sweep(0.0, 5), RigidWheel(radius=R, width=B), opts, candidates=("grousers",))
    assert any("grousers: not weighed" in n for n in d.notes)


def _cli_files(tmp_path):
    data = _sweep(0.012, 3)
    csv_path = tmp_path / "g.csv"
    write_wheel_sweep(data, str(csv_path))
    wheel = tmp_path / "w.json"
    wheel.write_text(json.dumps({"running_gear": "rigid_wheel", "wheel_radius_m": R, "wheel_width_m": B}))
    return str(csv_path), str(wheel)


@pytest.mark.slow
def test_cli_diagnose_with_the_soil_held_says_grousers(tmp_path, capsys):
    csv_path, wheel = _cli_files(tmp_path)
    fix = ["--fix", "cohesion_kpa=2", "--fix", "friction_angle_deg=30", "--fix", "bekker_kc=0"]
    rc = main(["diagnose", csv_path, "--vehicle", wheel, "--json", *fix])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["verdict"] == "grousers"


def test_cli_diagnose_fix_on_a_track_exits_2(tmp_path, capsys):
    csv_path, _ = _cli_files(tmp_path)
    rc = main(["diagnose", csv_path, "--vehicle", "light", "--fix", "friction_angle_deg=30"])
    assert rc == 2 and "--fix applies to a rigid wheel" in capsys.readouterr().err
