"""The rigid wheel on the command line: simulate, fit, diagnose; bad input exits 2; the example runs."""

from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

import wheel_oracle as oracle
from soiltrack.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CMU = os.path.join(ROOT, "examples", "data", "cmu-3dterra")
WHEEL = {
    "running_gear": "rigid_wheel",
    "wheel_radius_m": 0.058,
    "wheel_width_m": 0.05,
    "grouser_height_m": 0.0,
}


@pytest.fixture()
def wheel_json(tmp_path):
    p = tmp_path / "wheel.json"
    p.write_text(json.dumps(WHEEL))
    return str(p)


def _write(path, cols: dict) -> str:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(list(cols))
        for row in zip(*cols.values()):
            w.writerow([repr(float(v)) for v in row])
    return str(path)


@pytest.mark.slow
def test_fit_of_an_independently_simulated_sweep(tmp_path, wheel_json, capsys):
    soil = (1500.0, math.radians(28), 0.015, 1.2e6, 1.0)
    i, dp, W, z = oracle.sweep(
        [0.1, 0.3, 0.5, 0.7, 0.9], [18.0, 30.0], *soil, 0.058, 0.05, sd_dp=0.1, sd_z=2e-4, seed=5
    )
    path = _write(tmp_path / "s.csv", {"slip": i, "drawbar_pull_N": dp, "normal_load_N": W, "sinkage_m": z})
    rc = main(["fit", path, "--vehicle", wheel_json, "--json", "--fix", "bekker_n=1.0"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["success"] is True and out["status"] == "converged"
    p = out["parameters"]
    assert set(p) >= {
        "cohesion_kpa",
        "friction_angle_deg",
        "shear_modulus_m",
        "bekker_kc",
        "bekker_kphi",
        "bekker_n",
    }
    assert p["bekker_n"]["fixed"] is True and p["bekker_n"]["value"] == 1.0
    assert p["bekker_kc"]["identifiable"] is False and p["bekker_kphi"]["identifiable"] is False
    K = p["shear_modulus_m"]
    assert K["identifiable"] is True and K["ci95"][0] <= 0.015 <= K["ci95"][1]
    assert out["sinkage"] == "measured"
    assert out["identifiability"]["rank"] == 4  # c, phi, K and k_c/b + k_phi
    assert len(out["identifiability"]["null_space"]) == 1


@pytest.mark.slow
def test_simulate_then_fit_and_plot(tmp_path, wheel_json, capsys):
    csv_path = str(tmp_path / "sim.csv")
    rc = main(
        [
            "simulate",
            "--kind",
            "sweep",
            "--vehicle",
            wheel_json,
            "--terrain",
            "dry_sand",
            "--loads",
            "20,35",
            "--slips",
            "0.1,0.3,0.5,0.7,0.9",
            "--seed",
            "2",
            "-o",
            csv_path,
        ]
    )
    assert rc == 0
    with open(csv_path) as fh:
        header = fh.readline().strip().split(",")
    assert header == ["slip", "drawbar_pull_N", "normal_load_N", "sinkage_m"]
    png = str(tmp_path / "fit.png")
    rc = main(["fit", csv_path, "--vehicle", wheel_json, "--plot", png])
    assert rc == 0 and os.path.getsize(png) > 10_000
    capsys.readouterr()


@pytest.mark.parametrize("drop,column", [("normal_load_N", "normal_load_N"), ("drawbar_pull_N", "drawbar_pull_N")])
def test_missing_column_exits_2(tmp_path, wheel_json, capsys, drop, column):
    cols = {
        "slip": [0.2, 0.5, 0.8],
        "drawbar_pull_N": [0.5, 1.0, 1.2],
        "normal_load_N": [20.0, 20, 20],
        "sinkage_m": [0.02, 0.021, 0.022],
    }
    del cols[drop]
    path = _write(tmp_path / "bad.csv", cols)
    for cmd in ("fit", "diagnose"):
        rc = main([cmd, path, "--vehicle", wheel_json])
        err = capsys.readouterr().err
        assert rc == 2
        assert f"column '{column}'" in err and "Traceback" not in err


def test_bad_inputs_exit_2(tmp_path, wheel_json, capsys):
    good = _write(
        tmp_path / "g.csv",
        {
            "slip": [0.2, 0.5, 0.8, 0.9],
            "drawbar_pull_N": [0.5, 1.0, 1.2, 1.3],
            "normal_load_N": [20.0, 20, 20, 20],
            "sinkage_m": [0.02, 0.021, -0.022, 0.02],
        },
    )
    assert main(["fit", good, "--vehicle", wheel_json]) == 2  # negative sinkage, row 3
    assert "row 3" in capsys.readouterr().err
    massy = tmp_path / "m.json"
    massy.write_text(json.dumps({**WHEEL, "mass_kg": 3.0}))
    assert main(["fit", good, "--vehicle", str(massy)]) == 2
    assert main(["fit", good, "--vehicle", wheel_json, "--fix", "gravity=3"]) == 2
    assert main(["fit", good, "--vehicle", wheel_json, "--sigma", "0.1"]) == 2
    assert main(["fit", good, "--vehicle", wheel_json, "--effect", "grade"]) == 2
    assert main(["simulate", "--kind", "sweep", "--vehicle", wheel_json, "--terrain", "dry_sand"]) == 2  # no --loads
    assert main(["simulate", "--kind", "sweep", "--vehicle", wheel_json, "--soil", "1,30,0.01", "--loads", "20"]) == 2
    capsys.readouterr()


@pytest.mark.slow
def test_diagnose_names_slip_sinkage(tmp_path, wheel_json, capsys):
    csv_path = str(tmp_path / "ss.csv")
    assert (
        main(
            [
                "simulate",
                "--kind",
                "sweep",
                "--vehicle",
                wheel_json,
                "--terrain",
                "dry_sand",
                "--loads",
                "22",
                "--slips",
                "0.1,0.1,0.3,0.3,0.5,0.5,0.7,0.7,0.9,0.9",
                "--effect",
                "slip_sinkage=2",
                "--seed",
                "4",
                "-o",
                csv_path,
            ]
        )
        == 0
    )
    rc = main(["diagnose", csv_path, "--vehicle", wheel_json, "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0
    assert out["verdict"] == "slip_sinkage" and out["confidence"] > 0.9
    assert out["shrink"] > 0
    assert out["slip_sinkage_signature"]["p_value"] < 0.01
    ss = next(r for r in out["ranking"] if r["effect"] == "slip_sinkage")
    assert ss["parameters"]["slip_sinkage"] > 0


@pytest.mark.slow
def test_diagnose_a_textbook_sweep_says_none(tmp_path, wheel_json, capsys):
    csv_path = str(tmp_path / "tb.csv")
    assert (
        main(
            [
                "simulate",
                "--kind",
                "sweep",
                "--vehicle",
                wheel_json,
                "--terrain",
                "dry_sand",
                "--loads",
                "22",
                "--slips",
                "0.1,0.1,0.3,0.3,0.5,0.5,0.7,0.7,0.9,0.9",
                "--seed",
                "4",
                "-o",
                csv_path,
            ]
        )
        == 0
    )
    rc = main(["diagnose", csv_path, "--vehicle", wheel_json, "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["verdict"] == "none"
    assert out["soil_after"] is None


@pytest.mark.slow
def test_the_real_data_example_runs(tmp_path):
    sys.path.insert(0, os.path.join(ROOT, "examples"))
    try:
        import wheel_real_data
    finally:
        sys.path.pop(0)
    png = str(tmp_path / "w.png")
    res = wheel_real_data.main(["--out", png])
    assert os.path.getsize(png) > 10_000
    assert res["nominal_success"] is True
    assert res["verdict"] == "slip_sinkage"
    v = np.array(list(res["loso_rmse_N"].values()))
    assert np.all(np.isfinite(v)) and np.all(v > res["repeat_scatter_N"])
    assert res["repeat_scatter_N"] == pytest.approx(0.300, abs=5e-4)


def test_bundled_data_carry_their_licence():
    with open(os.path.join(CMU, "LICENSE.txt")) as fh:
        text = fh.read()
    assert "MIT License" in text and "Carnegie Mellon University" in text
    with open(os.path.join(CMU, "smooth_wheel_driving.csv")) as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 12
    assert sorted({round(float(r["slip"]), 2) for r in rows}) == [0.23, 0.5, 0.75, 0.9]


def test_module_entry_point(tmp_path, wheel_json):
    p = subprocess.run(
        [sys.executable, "-m", "soiltrack", "fit", "nope.csv", "--vehicle", wheel_json],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert p.returncode == 2 and "Traceback" not in p.stderr


def test_skid_rows_are_kept_for_the_skid_model(capsys):
    # correction (issue 41): skid rows are fitted by the skid model, no longer refused
    from soiltrack.soilmodel.wheel_sweep import read_wheel_sweep

    data = read_wheel_sweep(os.path.join(CMU, "smooth_wheel_trials_beta0.csv"))
    assert data.n_samples == 27 and int(np.count_nonzero(data.slip < 0)) == 15 and data.slip.min() == -1.0
    wheel = os.path.join(CMU, "smooth_wheel.json")
    rc = main(["fit", os.path.join(CMU, "smooth_wheel_driving.csv"), "--vehicle", wheel, "--resistance", "fit"])
    assert rc == 2


@pytest.mark.slow
def test_skid_rows_dropped_on_request(capsys):
    wheel = os.path.join(CMU, "smooth_wheel.json")
    rc = main(
        [
            "fit",
            os.path.join(CMU, "smooth_wheel_trials_beta0.csv"),
            "--vehicle",
            wheel,
            "--driving-only",
            "--json",
        ]
    )
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["n_samples"] == 12 and out["rows_dropped"] == 15
