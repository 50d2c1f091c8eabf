"""Command line of issue 38: ``simulate --change``, ``track``'s new fields and its p_traversable column."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from online_oracle import SOILS, simulate, write_csv
from soiltrack.cli import main


def _run(args, capsys):
    rc = main(args)
    out = capsys.readouterr()
    lines = [json.loads(x) for x in out.out.splitlines() if x.strip().startswith("{")]
    return rc, lines, out


def _read(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def test_simulate_change_writes_the_new_soil_from_its_time_on(tmp_path, capsys):
    base = ["simulate", "--kind", "drive", "--vehicle", "light", "--duration", "20", "--seed", "3"]
    assert main(base + ["-o", str(tmp_path / "a.csv")]) == 0
    assert main(base + ["--change", "10:snow", "--change", "15:1.0,25,0.02", "-o", str(tmp_path / "b.csv")]) == 0
    a, b = _read(tmp_path / "a.csv"), _read(tmp_path / "b.csv")
    assert a.keys() == b.keys() and a["time_s"].size == b["time_s"].size
    before = a["time_s"] <= 10.0
    for k in ("sprocket_torque_Nm", "sprocket_speed_rad_s", "vehicle_speed_m_s"):
        np.testing.assert_array_equal(a[k][before], b[k][before])  # same seed, same soil until the change
    after = a["time_s"] > 10.5
    assert np.max(np.abs(a["sprocket_speed_rad_s"][after] - b["sprocket_speed_rad_s"][after])) > 0.1


@pytest.mark.parametrize(
    "spec, named",
    [
        ("x:snow", "--change"),
        ("10", "--change"),
        ("10:mud", "mud"),
        ("30:snow", "outside the log"),
        ("10:1,2", "--change"),
        ("10:1,25,3000", "K"),
        ("10:nan,25,0.01", "--change"),
    ],
)
def test_simulate_change_bad_input_exits_2(spec, named, tmp_path, capsys):
    args = ["simulate", "--kind", "drive", "--vehicle", "light", "--duration", "20", "--seed", "3"]
    rc = main(args + ["--change", spec, "-o", str(tmp_path / "x.csv")])
    err = capsys.readouterr().err
    assert rc == 2 and "--change" in err and named in err and "Traceback" not in err


def test_simulate_change_refused_for_a_sweep(capsys):
    assert main(["simulate", "--kind", "sweep", "--change", "10:snow", "--seed", "1"]) == 2
    assert "--change" in capsys.readouterr().err


@pytest.mark.slow
def test_track_reports_the_held_estimate_the_change_window_and_p_traversable(tmp_path, capsys):
    pulls = [(1.0, 4.0, 0.95), (12.0, 15.0, 0.95), (30.0, 33.0, 0.95)]
    weak = (700.0, SOILS["weak"][1], 0.012)
    cols = simulate("heavy", lambda t: SOILS["lete_sand"] if t < 21.0 else weak, 36.0, pulls, seed=404)
    path = tmp_path / "log.csv"
    write_csv(cols, str(path))
    rc, lines, _ = _run(
        ["track", str(path), "--vehicle", "heavy", "--every", "50", "--grade-deg", "5", "--json"], capsys
    )
    assert rc == 0
    steps, summary = lines[:-1], lines[-1]["summary"]
    for st in steps:
        assert {"informed_at_s", "change_window_s", "change_time_s", "held"} <= st.keys()
    held = [st for st in steps if st["held"] and 20.0 <= st["time_s"] <= 29.0]
    assert held and all(st["max_thrust_stderr_N"] is not None for st in held)
    assert all(st["informed_at_s"] is not None and st["informed_at_s"] <= 15.0 for st in held)
    assert all(st["p_traversable"] is not None for st in held if "shear_modulus" in st["identifiable"])
    flagged = [st for st in steps if st["change_detected"]]
    assert len(flagged) == 1
    lo, hi = flagged[0]["change_window_s"]
    assert lo <= 21.0 <= hi
    (c,) = summary["changes"]
    assert {"time_s", "window_s", "detected_at_s"} <= c.keys()
    assert c["window_s"] == [lo, hi] and c["detected_at_s"] == flagged[0]["time_s"]
    # the table prints p_traversable too
    rc, _, out = _run(["track", str(path), "--vehicle", "heavy", "--every", "250", "--grade-deg", "5"], capsys)
    assert "p_trav" in out.out and "(held)" in out.out
