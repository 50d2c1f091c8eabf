"""``soiltrack track``: JSON lines and summary, skipped samples, two-track logs, bad input exits 2."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import bench_module
from soiltrack.cli import main
from soiltrack.soilmodel import TERRAINS, VEHICLES, simulate_drive_log, write_csv

STEP_KEYS = {
    "time_s",
    "max_thrust_N",
    "max_thrust_stderr_N",
    "shear_modulus_m",
    "shear_modulus_stderr_m",
    "identifiable",
    "change_detected",
    "samples_used",
    "samples_skipped",
    "p_traversable",
}
SUMMARY_KEYS = {
    "updates",
    "update_time_median_s",
    "update_time_p99_s",
    "changes",
    "samples_turning",
    "samples_skipped",
}


@pytest.fixture(scope="module")
def log():
    return simulate_drive_log(VEHICLES["light"], TERRAINS["lete_sand"], seed=2, duration_s=30, sample_rate_hz=50)


def _run(args, capsys):
    rc = main(args)
    out = capsys.readouterr()
    lines = [json.loads(x) for x in out.out.splitlines() if x.strip().startswith("{")]
    return rc, lines, out.err


@pytest.mark.slow
def test_json_lines_and_summary(tmp_path, capsys):
    log, _ = bench_module("bench_online").change_log(50.0, seed=11, duration_s=12.0, change=False)
    path = tmp_path / "log.csv"
    write_csv(log, path)
    rc, lines, _ = _run(
        ["track", str(path), "--vehicle", "light", "--every", "10", "--grade-deg", "5", "--json"], capsys
    )
    assert rc == 0
    steps, summary = lines[:-1], lines[-1]["summary"]
    assert all(STEP_KEYS <= set(s) for s in steps)
    assert SUMMARY_KEYS <= set(summary)
    assert summary["updates"] == log.n_samples
    assert len(steps) == log.n_samples // 10 + 1
    assert summary["samples_skipped"] == 0 and summary["changes"] == []
    p = [s["p_traversable"] for s in steps if s["p_traversable"] is not None]
    assert p and all(0.0 <= x <= 1.0 for x in p)
    # p_traversable only where F_max and K are both identified and the iteration has converged
    assert all(
        (s["p_traversable"] is None) == (s["shear_modulus_stderr_m"] is None or not s["converged"]) for s in steps
    )


def test_missing_readings_are_skipped_and_counted(log, tmp_path, capsys):
    path = tmp_path / "gaps.csv"
    write_csv(log, path)
    rows = path.read_text().splitlines()
    gaps = [50, 51, 300, 700, 701, 702, 1200]
    for j, k in enumerate(gaps):
        cells = rows[k].split(",")
        cells[1 + j % 3] = "" if j % 2 else "nan"
        rows[k] = ",".join(cells)
    path.write_text("\n".join(rows) + "\n")
    rc, lines, _ = _run(["track", str(path), "--vehicle", "light", "--every", "100", "--json"], capsys)
    assert rc == 0
    assert lines[-1]["summary"]["samples_skipped"] == len(gaps)
    assert lines[-2]["samples_skipped"] == len(gaps)


def test_two_track_log_turns_counted(log, tmp_path, capsys):
    cols = bench_module("bench_online").two_track(log, [(12.0, 13.0)], seed=1)
    names = [c for c in cols if not c.startswith("_")]
    path = tmp_path / "tracks.csv"
    np.savetxt(path, np.column_stack([cols[c] for c in names]), delimiter=",", header=",".join(names), comments="")
    rc, lines, _ = _run(["track", str(path), "--vehicle", "light", "--every", "100", "--json"], capsys)
    n_turn = int(np.count_nonzero(cols["_turning"]))
    assert rc == 0
    # the light vehicle has no tread_m: no turning sample is fitted by the steering model, each is counted
    summary = lines[-1]["summary"]
    assert summary["samples_turning"] == 0
    assert n_turn <= summary["samples_turning_not_fitted"]["no_tread"] <= n_turn + 2
    assert sum(summary["samples_turning_not_fitted"].values()) == summary["samples_turning_not_fitted"]["no_tread"]


def test_log_grade_sets_the_normal_load_and_c_phi_are_never_identified(log, tmp_path, capsys):
    path = tmp_path / "log.csv"
    write_csv(log.subset(slice(0, 600)), path)
    W = VEHICLES["light"].weight
    for grade, load in ((None, W), ("6", W * math.cos(math.radians(6.0)))):
        extra = [] if grade is None else ["--log-grade-deg", grade]
        rc, lines, _ = _run(["track", str(path), "--vehicle", "light", "--every", "50", "--json", *extra], capsys)
        steps, summary = lines[:-1], lines[-1]["summary"]
        assert rc in (0, 1)
        assert all(st["normal_load_N"] == pytest.approx(load, rel=1e-12) for st in steps)
        assert summary["normal_load_N"] == pytest.approx(load, rel=1e-12)
        assert summary["log_grade_deg"] == (0.0 if grade is None else 6.0)
        assert all(st["not_identifiable"][-2:] == ["cohesion", "friction_angle"] for st in steps)
        assert all(not {"cohesion", "friction_angle"} & set(st["identifiable"]) for st in steps)
        assert summary["not_identifiable"][-2:] == ["cohesion", "friction_angle"]


@pytest.mark.parametrize(
    "case",
    ["missing_file", "missing_column", "text", "window", "every", "grade", "time", "log_grade", "log_grade_text"],
)
def test_bad_input_exits_2(case, log, tmp_path, capsys):
    path = tmp_path / "log.csv"
    write_csv(log.subset(slice(0, 200)), path)
    args = ["track", str(path), "--vehicle", "light", "--json"]
    if case == "missing_file":
        args[1] = str(tmp_path / "none.csv")
    elif case == "missing_column":
        rows = path.read_text().splitlines()
        path.write_text("\n".join(",".join(r.split(",")[:3]) for r in rows) + "\n")
    elif case == "text":
        rows = path.read_text().splitlines()
        rows[5] = "abc," + rows[5].split(",", 1)[1]
        path.write_text("\n".join(rows) + "\n")
    elif case == "time":
        rows = path.read_text().splitlines()
        rows[7], rows[8] = rows[8], rows[7]
        path.write_text("\n".join(rows) + "\n")
    elif case == "window":
        args += ["--window", "-1"]
    elif case == "every":
        args += ["--every", "0.5"]
    elif case == "grade":
        args += ["--grade-deg", "95"]
    elif case == "log_grade":
        args += ["--log-grade-deg", "80"]
    elif case == "log_grade_text":
        args += ["--log-grade-deg", "steep"]
    rc = main(args)
    err = capsys.readouterr().err
    assert rc == 2
    assert "Traceback" not in err
