"""CSV and JSON contracts: round trips and every bad-input path."""

import json
import math

import numpy as np
import pytest

from soiltrack.soilmodel import VEHICLES, DataError, DriveLog, SlipData, Soil, Vehicle, read_csv, write_csv


def write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def test_slip_round_trip(tmp_path):
    d = SlipData([0.01, 0.05, 0.2], [1e3, 2e3, 2.5e3], normal_load=[300.0, 300.0, 600.0])
    p = str(tmp_path / "s.csv")
    write_csv(d, p)
    back = read_csv(p)
    assert isinstance(back, SlipData)
    assert np.array_equal(back.slip, d.slip) and np.array_equal(back.tractive_force, d.tractive_force)
    assert np.array_equal(back.normal_load, d.normal_load)
    assert list(back.distinct_loads) == [300.0, 600.0]


def test_drive_round_trip_with_and_without_imu(tmp_path):
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.01, 0.03, 50))
    for accel in (None, rng.normal(size=50)):
        d = DriveLog(t, rng.normal(size=50) * 1e3, rng.uniform(1, 5, 50), rng.uniform(0, 2, 50), accel)
        p = str(tmp_path / "d.csv")
        write_csv(d, p)
        back = read_csv(p)
        assert isinstance(back, DriveLog)
        for k, v in d.columns().items():
            assert np.array_equal(back.columns()[k], v), k
        assert (back.vehicle_accel is None) == (accel is None)


def test_column_order_and_extra_columns_are_free(tmp_path):
    p = write(tmp_path, "x.csv", "note,tractive_force_N,slip\na,100,0.1\nb,200,0.2\n")
    d = read_csv(p)
    assert list(d.slip) == [0.1, 0.2] and list(d.tractive_force) == [100, 200]


BAD = [
    ("slip,tractive_force_N\n0.01,1000\n0.02,nan\n", "tractive_force_N", 2, "not a finite"),
    ("slip,tractive_force_N\n0.01,1000\n0.02,inf\n", "tractive_force_N", 2, "not a finite"),
    ("slip,tractive_force_N\n0.01,abc\n", "tractive_force_N", 1, "not a number"),
    ("slip,tractive_force_N\n0.01,\n", "tractive_force_N", 1, "empty"),
    ("slip,tractive_force_N\n0.01,10\n1.0,20\n", "slip", 2, "[0, 1)"),
    ("slip,tractive_force_N\n-0.1,10\n", "slip", 1, "[0, 1)"),
    ("slip,tractive_force_N,normal_load_N\n0.1,10,-5\n", "normal_load_N", 1, "> 0"),
    ("slip\n0.1\n", "tractive_force_N", None, "missing required column"),
    ("time_s,sprocket_torque_Nm,sprocket_speed_rad_s\n0,1,2\n", "vehicle_speed_m_s", None, "missing"),
    (
        "time_s,sprocket_torque_Nm,sprocket_speed_rad_s,vehicle_speed_m_s\n0,1,2,3\n0.1,1,2,3\n0.1,1,2,3\n",
        "time_s",
        3,
        "strictly increasing",
    ),
    (
        "time_s,sprocket_torque_Nm,sprocket_speed_rad_s,vehicle_speed_m_s\n0,1,2,3\n0.1,1,NaN,3\n",
        "sprocket_speed_rad_s",
        2,
        "not a finite",
    ),
]


@pytest.mark.parametrize("text,column,row,msg", BAD)
def test_bad_csv_names_file_column_row(tmp_path, text, column, row, msg):
    p = write(tmp_path, "bad.csv", text)
    with pytest.raises(DataError) as e:
        read_csv(p)
    assert e.value.file == p and p in str(e.value)
    assert e.value.column == column and f"'{column}'" in str(e.value)
    assert e.value.row == row
    if row is not None:
        assert f"row {row}" in str(e.value)
    assert msg in str(e.value)


@pytest.mark.parametrize(
    "text,msg",
    [
        ("", "empty file"),
        ("slip,tractive_force_N\n", "no data rows"),
        ("a,b\n1,2\n", "unrecognised columns"),
        ("slip,tractive_force_N\n0.1,2,3\n", "expected 2 fields"),
        ("slip,slip,tractive_force_N\n0.1,0.1,2\n", "duplicate"),
    ],
)
def test_bad_csv_structure(tmp_path, text, msg):
    p = write(tmp_path, "bad.csv", text)
    with pytest.raises(DataError, match=msg.replace("(", r"\(")):
        read_csv(p)


def test_missing_file(tmp_path):
    with pytest.raises(DataError, match="cannot read"):
        read_csv(str(tmp_path / "nope.csv"))


def test_in_memory_data_is_validated_too():
    with pytest.raises(DataError, match="row 2"):
        SlipData([0.1, 1.2], [1, 2])
    with pytest.raises(DataError, match="differ in length"):
        SlipData([0.1, 0.2], [1])


def test_vehicle_json_round_trip(tmp_path):
    for v in VEHICLES.values():
        p = tmp_path / "v.json"
        p.write_text(v.to_json())
        back = Vehicle.from_json(str(p))
        assert back.to_dict() == v.to_dict()
        assert json.loads(v.to_json())["mass_kg"] == v.mass


@pytest.mark.parametrize(
    "patch,column,msg",
    [
        ({"mass_kg": -1}, "mass_kg", "> 0"),
        ({"track_length_m": 0}, "track_length_m", "> 0"),
        ({"mass_kg": "heavy"}, "mass_kg", "must be a number"),
        ({"rolling_resistance": 1.5}, "rolling_resistance", "< 1"),
        ({"road_wheels": 2.5}, "road_wheels", "positive integer"),
        ({"max_power_W": float("nan")}, "max_power_W", "finite"),
    ],
)
def test_vehicle_json_bad_fields(tmp_path, patch, column, msg):
    obj = VEHICLES["light"].to_dict() | patch
    p = tmp_path / "v.json"
    p.write_text(json.dumps(obj, allow_nan=True))
    with pytest.raises(DataError) as e:
        Vehicle.from_json(str(p))
    assert e.value.column == column and msg in str(e.value) and str(p) in str(e.value)


def test_vehicle_json_missing_field_and_bad_json(tmp_path):
    obj = VEHICLES["light"].to_dict()
    del obj["sprocket_radius_m"]
    p = tmp_path / "v.json"
    p.write_text(json.dumps(obj))
    with pytest.raises(DataError, match="sprocket_radius_m"):
        Vehicle.from_json(str(p))
    p.write_text("{not json")
    with pytest.raises(DataError, match="invalid JSON"):
        Vehicle.from_json(str(p))


def test_soil_validation_and_units():
    s = Soil.from_kpa_deg(1.3, 31.1, 0.012)
    assert s.cohesion == 1300.0 and s.friction_angle == pytest.approx(math.radians(31.1))
    assert s.cohesion_kpa == pytest.approx(1.3) and s.friction_angle_deg == pytest.approx(31.1)
    for bad in [(-1, 30, 0.01), (1, 0, 0.01), (1, 90, 0.01), (1, 30, 0.0), (float("nan"), 30, 0.01)]:
        with pytest.raises(DataError):
            Soil.from_kpa_deg(*bad)
