"""Exported files as they are: --columns mapping, unit suffixes, and the wheel sweep's input checks."""

from __future__ import annotations

import csv
import json
import math
import os

import numpy as np
import pytest

from soiltrack.cli import main
from soiltrack.soilmodel import DataError, read_csv
from soiltrack.soilmodel.columns import parse_columns_arg, plan_columns, split_unit
from soiltrack.soilmodel.data import KNOWN_COLUMNS
from soiltrack.soilmodel.drive_stream import read_drive_stream
from soiltrack.soilmodel.wheel_sweep import WheelSweep, check_sweep_for_wheel, pull_sign_problem, read_wheel_sweep

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CMU = os.path.join(ROOT, "examples", "data", "cmu-3dterra")
WONG = os.path.join(ROOT, "examples", "data", "wong2001_p176.csv")


def _write(path, cols: dict) -> str:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(list(cols))
        for row in zip(*cols.values()):
            w.writerow([repr(float(v)) for v in row])
    return str(path)


def _cmu_driving() -> dict:
    with open(os.path.join(CMU, "smooth_wheel_driving.csv")) as fh:
        rows = list(csv.DictReader(fh))
    return {k: np.array([float(r[k]) for r in rows]) for k in ("slip", "drawbar_pull_N", "normal_load_N", "sinkage_m")}


def test_split_unit_takes_the_longest_suffix():
    assert split_unit("sinkage_mm") == ("sinkage", "mm")
    assert split_unit("wheel_torque_std_N_m") == ("wheel_torque_std", "N_m")
    assert split_unit("sprocket_speed_rad_s") == ("sprocket_speed", "rad_s")
    assert split_unit("vehicle_accel_m_s2") == ("vehicle_accel", "m_s2")
    assert split_unit("slip") == ("slip", None)


@pytest.mark.parametrize(
    "header, name, factor",
    [
        ("sinkage_mm", "sinkage_m", 1e-3),
        ("drawbar_pull_kN", "drawbar_pull_N", 1e3),
        ("normal_pressure_kPa", "normal_pressure_Pa", 1e3),
        ("slip_percent", "slip", 0.01),
        ("sprocket_speed_rpm", "sprocket_speed_rad_s", 2 * math.pi / 60),
        ("time_ms", "time_s", 1e-3),
        ("slip_angle_rad", "slip_angle_deg", 180 / math.pi),
    ],
)
def test_a_unit_suffix_converts_and_says_so(header, name, factor):
    plan = plan_columns(["a", header], known=KNOWN_COLUMNS)
    assert plan.header == ("a", name)
    (c,) = plan.conversions
    assert c.factor == pytest.approx(factor, rel=1e-12)
    assert header in plan.notes[0] and name in plan.notes[0]
    out = plan.apply({name: np.array([2.0])})
    assert out[name][0] == pytest.approx(2.0 * factor)


def test_the_library_column_wins_over_a_suffixed_copy():
    plan = plan_columns(["slip", "sinkage_mm", "sinkage_m"], known=KNOWN_COLUMNS)
    assert plan.header == ("slip", "sinkage_mm", "sinkage_m") and not plan.conversions
    assert plan.notes == ("sinkage_mm not read: the file has sinkage_m",)


def test_a_suffix_of_another_quantity_is_refused_with_the_hint():
    with pytest.raises(DataError) as e:
        plan_columns(["time_s", "vehicle_speed_ms"], known=KNOWN_COLUMNS, source="log.csv")
    assert "milliseconds" in str(e.value) and "_m_s" in str(e.value) and e.value.column == "vehicle_speed_ms"
    with pytest.raises(DataError, match="unit of length"):
        plan_columns(["Fx_mm"], known=KNOWN_COLUMNS, mapping={"drawbar_pull_N": "Fx_mm"})


def test_explicit_mapping_checks_names_and_sources():
    plan = plan_columns(
        ["i", "Fx", "depth_mm"],
        known=KNOWN_COLUMNS,
        mapping=parse_columns_arg("slip=i,drawbar_pull_N=Fx,sinkage_m=depth_mm"),
    )
    assert plan.header == ("slip", "drawbar_pull_N", "sinkage_m")
    assert [c.factor for c in plan.conversions] == [1.0, 1.0, 1e-3]
    with pytest.raises(DataError, match="not a column the library reads"):
        plan_columns(["Fx"], known=KNOWN_COLUMNS, mapping={"pull": "Fx"})
    with pytest.raises(DataError, match="no column 'Fy'"):
        plan_columns(["Fx"], known=KNOWN_COLUMNS, mapping={"drawbar_pull_N": "Fy"})
    with pytest.raises(DataError, match="already has a column"):
        plan_columns(["Fx", "drawbar_pull_N"], known=KNOWN_COLUMNS, mapping={"drawbar_pull_N": "Fx"})
    for bad in ("slip", "slip=", "=i", "slip=i,slip=j", "slip=i,drawbar_pull_N=i"):
        with pytest.raises(DataError, match="--columns"):
            parse_columns_arg(bad)


def test_read_csv_maps_and_converts(tmp_path):
    with open(WONG) as fh:
        rows = list(csv.DictReader(fh))
    i = np.array([float(r["slip"]) for r in rows])
    F = np.array([float(r["tractive_force_N"]) for r in rows])
    path = _write(tmp_path / "export.csv", {"i_percent": 100 * i, "Fx_kN": F / 1e3})
    d = read_csv(path, columns={"slip": "i_percent", "tractive_force_N": "Fx_kN"})
    np.testing.assert_allclose(d.slip, i, rtol=1e-12)
    np.testing.assert_allclose(d.tractive_force, F, rtol=1e-12)


def test_fit_cli_with_columns_gives_the_same_fit_and_says_so(tmp_path, capsys):
    with open(WONG) as fh:
        rows = list(csv.DictReader(fh))
    i = np.array([float(r["slip"]) for r in rows])
    F = np.array([float(r["tractive_force_N"]) for r in rows])
    path = _write(tmp_path / "export.csv", {"i_percent": 100 * i, "Fx_kN": F / 1e3})
    assert main(["fit", WONG, "--vehicle", "heavy", "--json"]) == 0
    ref = json.loads(capsys.readouterr().out)
    rc = main(["fit", path, "--vehicle", "heavy", "--json", "--columns", "slip=i_percent,tractive_force_N=Fx_kN"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and ref["columns_read"] == []
    assert any("Fx_kN read as tractive_force_N" in n and "x 1000" in n for n in out["columns_read"])
    for k in ("cohesion_kpa", "friction_angle_deg", "shear_modulus_m"):
        assert out["parameters"][k]["value"] == pytest.approx(ref["parameters"][k]["value"], rel=1e-6)
    main(["fit", path, "--vehicle", "heavy", "--columns", "slip=i_percent,tractive_force_N=Fx_kN"])
    assert capsys.readouterr().out.startswith("columns: i_percent read as slip, converted from percent")


def test_fit_cli_bad_mapping_exits_2(tmp_path, capsys):
    rc = main(["fit", WONG, "--vehicle", "heavy", "--columns", "slip=nope"])
    err = capsys.readouterr().err
    assert rc == 2 and "no column 'nope'" in err and WONG in err and "Traceback" not in err


def test_drive_stream_maps_and_converts(tmp_path):
    t = np.arange(5) * 0.1
    path = _write(
        tmp_path / "log.csv",
        {
            "t_ms": 1e3 * t,
            "torque_kNm": np.full(5, 0.2),
            "sprocket_speed_rpm": np.full(5, 60.0),
            "vehicle_speed_m_s": np.full(5, 0.5),
        },
    )
    s = read_drive_stream(path, columns={"time_s": "t_ms", "sprocket_torque_Nm": "torque_kNm"})
    np.testing.assert_allclose(s.columns["time_s"], t, atol=1e-12)
    np.testing.assert_allclose(s.columns["sprocket_torque_Nm"], 200.0)
    np.testing.assert_allclose(s.columns["sprocket_speed_rad_s"], 2 * math.pi)


def test_track_cli_takes_columns(tmp_path, capsys):
    rc = main(["track", os.path.join(tmp_path, "none.csv"), "--vehicle", "light", "--columns", "time_s"])
    assert rc == 2 and "--columns expects NAME=SOURCE" in capsys.readouterr().err


# ---- the wheel sweep: sinkage in mm, a flipped pull, --driving-only ----


def test_wheel_sweep_reads_sinkage_mm(tmp_path):
    d = _cmu_driving()
    path = _write(
        tmp_path / "w.csv",
        {
            "slip": d["slip"],
            "drawbar_pull_N": d["drawbar_pull_N"],
            "normal_load_N": d["normal_load_N"],
            "sinkage_mm": 1e3 * d["sinkage_m"],
        },
    )
    s = read_wheel_sweep(path)
    np.testing.assert_allclose(s.sinkage, d["sinkage_m"], rtol=1e-12)


@pytest.mark.parametrize("command", ["fit", "diagnose"])
def test_sinkage_in_mm_under_sinkage_m_is_refused_with_the_hint(tmp_path, capsys, command):
    d = _cmu_driving()
    path = _write(
        tmp_path / "w.csv",
        {
            "slip": d["slip"],
            "drawbar_pull_N": d["drawbar_pull_N"],
            "normal_load_N": d["normal_load_N"],
            "sinkage_m": 1e3 * d["sinkage_m"],
        },
    )
    rc = main([command, path, "--vehicle", os.path.join(CMU, "smooth_wheel.json")])
    err = capsys.readouterr().err
    assert rc == 2 and "Traceback" not in err
    assert "12 of 12 rows have a sinkage larger than the wheel's radius 0.058 m" in err
    assert "millimetres" in err and "sinkage_mm" in err and "sinkage_m'" in err and path in err
    assert "finite numbers" not in err


@pytest.mark.parametrize("command", ["fit", "diagnose"])
def test_flipped_pull_is_refused(tmp_path, capsys, command):
    d = _cmu_driving()
    path = _write(
        tmp_path / "w.csv",
        {
            "slip": d["slip"],
            "drawbar_pull_N": -d["drawbar_pull_N"],
            "normal_load_N": d["normal_load_N"],
            "sinkage_m": d["sinkage_m"],
        },
    )
    rc = main([command, path, "--vehicle", os.path.join(CMU, "smooth_wheel.json")])
    err = capsys.readouterr().err
    assert rc == 2 and "looks flipped" in err and "drawbar_pull_N" in err and "Traceback" not in err


def test_pull_sign_rule_on_the_measured_sweep():
    with open(os.path.join(CMU, "smooth_wheel_trials_beta0.csv")) as fh:
        rows = list(csv.DictReader(fh))
    i = np.array([float(r["slip"]) for r in rows])
    dp = np.array([float(r["drawbar_pull_N"]) for r in rows])
    assert pull_sign_problem(i, dp) is None  # skid and driving, as measured
    assert "from skid to driving" in pull_sign_problem(i, -dp)
    drive = i > 0
    assert pull_sign_problem(i[drive], dp[drive]) is None
    assert "negative at all 12 driving rows" in pull_sign_problem(i[drive], -dp[drive])
    # a wheel that cannot pull but whose pull rises with slip is not called flipped
    assert pull_sign_problem(np.array([0.1, 0.3, 0.5, 0.7]), np.array([-3.0, -2.0, -1.5, -1.0])) is None


def test_check_accepts_the_measured_wheel():
    d = _cmu_driving()
    check_sweep_for_wheel(WheelSweep(d["slip"], d["drawbar_pull_N"], d["normal_load_N"], d["sinkage_m"]), 0.058)


def test_diagnose_wheel_honours_driving_only(monkeypatch, capsys):
    import soiltrack.identify.wheel.diagnosis as diag

    seen = {}

    def fake(data, wheel, options, candidates=None):
        seen["rows"] = data.n_samples
        raise DataError("stop here")

    monkeypatch.setattr(diag, "diagnose_wheel", fake)
    rc = main(
        [
            "diagnose",
            os.path.join(CMU, "smooth_wheel_trials_beta0.csv"),
            "--vehicle",
            os.path.join(CMU, "smooth_wheel.json"),
            "--driving-only",
        ]
    )
    assert rc == 2 and "stop here" in capsys.readouterr().err and seen["rows"] == 12
