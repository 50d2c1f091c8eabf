"""The command-line tool: contracts, exit codes and bad-input behaviour."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from soiltrack.cli import main
from soiltrack.soilmodel import VEHICLES, DriveLog, SlipData, read_csv

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

DRIVE_COLUMNS = ["time_s", "sprocket_torque_Nm", "sprocket_speed_rad_s", "vehicle_speed_m_s"]
WONG = os.path.join(ROOT, "examples", "data", "wong2001_p176.csv")
HEAVY_JSON = os.path.join(ROOT, "examples", "data", "heavy_vehicle.json")


def run_module(*args):
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run(
        [sys.executable, "-m", "soiltrack", *args], capture_output=True, text=True, cwd=ROOT, env=env, timeout=300
    )


def test_simulate_drive_log_follows_csv_contract(tmp_path):
    out = str(tmp_path / "log.csv")
    assert (
        main(["simulate", "--vehicle", "heavy", "--terrain", "lete_sand", "--seed", "1", "-o", out, "--duration", "20"])
        == 0
    )
    header = open(out).readline().strip().split(",")
    assert header[:4] == DRIVE_COLUMNS
    log = read_csv(out)
    assert isinstance(log, DriveLog) and log.n_samples > 100
    assert np.all(np.diff(log.time) > 0)


def test_simulate_is_reproducible_by_seed(tmp_path):
    a, b, c = (str(tmp_path / f"{k}.csv") for k in "abc")
    for path, seed in ((a, "3"), (b, "3"), (c, "4")):
        assert (
            main(
                [
                    "simulate",
                    "--vehicle",
                    "light",
                    "--terrain",
                    "dry_sand",
                    "--seed",
                    seed,
                    "--duration",
                    "5",
                    "-o",
                    path,
                ]
            )
            == 0
        )
    assert open(a).read() == open(b).read() != open(c).read()


def test_simulate_sweep_with_effect_and_loads(tmp_path):
    out = str(tmp_path / "sweep.csv")
    assert (
        main(
            [
                "simulate",
                "--kind",
                "sweep",
                "--vehicle",
                "light",
                "--soil",
                "2,30,0.01",
                "--loads",
                "300,600",
                "--effect",
                "hump_shear=0.3",
                "--seed",
                "2",
                "-o",
                out,
            ]
        )
        == 0
    )
    d = read_csv(out)
    assert isinstance(d, SlipData) and sorted(d.distinct_loads) == [300.0, 600.0]


def test_fit_json_contract_on_bundled_data(capsys):
    rc = main(["fit", WONG, "--vehicle", HEAVY_JSON, "--json"])
    js = json.loads(capsys.readouterr().out)
    for k in [
        "model",
        "method",
        "status",
        "success",
        "n_samples",
        "rmse_N",
        "solve_time_s",
        "parameters",
        "combinations",
    ]:
        assert k in js
    assert (rc == 0) == js["success"] and rc in (0, 1)
    assert js["n_samples"] == 3
    for name in ("cohesion_kpa", "friction_angle_deg", "shear_modulus_m"):
        p = js["parameters"][name]
        assert set(p) >= {"value", "stderr", "ci95", "identifiable", "at_bound"}
    # one normal load: c and phi are not separable (docs/paper.md)
    assert js["parameters"]["cohesion_kpa"]["identifiable"] is False
    assert js["parameters"]["friction_angle_deg"]["identifiable"] is False


def test_fit_report_and_plot(tmp_path, capsys):
    png = str(tmp_path / "fit.png")
    main(["fit", WONG, "--vehicle", "heavy", "--model", "cohesion-free", "--plot", png])
    out = capsys.readouterr().out
    assert "friction" in out.lower()
    assert os.path.getsize(png) > 10_000


@pytest.mark.parametrize(
    "text,column,row",
    [
        ("slip,tractive_force_N\n0.01,1000\n0.02,nan\n0.05,3000\n0.1,3500\n", "tractive_force_N", 2),
        ("slip,tractive_force_N\n0.01,1000\n1.5,2000\n0.05,3000\n", "slip", 2),
        ("slip,tractive_force_N\n0.01,1000\n0.02,x\n0.05,3000\n", "tractive_force_N", 2),
    ],
)
@pytest.mark.slow
def test_fit_bad_csv_exits_2_naming_column_and_row(tmp_path, text, column, row):
    bad = tmp_path / "bad.csv"
    bad.write_text(text)
    p = run_module("fit", str(bad), "--vehicle", HEAVY_JSON, "--json")
    assert p.returncode == 2
    assert "Traceback" not in p.stderr
    assert column in p.stderr and f"row {row}" in p.stderr and str(bad) in p.stderr
    assert p.stdout == ""


@pytest.mark.parametrize(
    "args,needle",
    [
        (["fit", "nope.csv", "--vehicle", "heavy"], "nope.csv"),
        (["fit", WONG, "--vehicle", "nope.json"], "nope.json"),
        (["simulate", "--terrain", "moon_dust", "-o", "-"], "moon_dust"),
        (["simulate", "--effect", "warp_drive=1", "-o", "-"], "warp_drive"),
        (["simulate", "--soil", "1,2", "-o", "-"], "--soil"),
        (["fit", WONG, "--vehicle", "heavy", "--bias-correction", "simex"], "drive logs only"),
    ],
)
def test_bad_arguments_exit_2(args, needle, capsys):
    assert main(args) == 2
    err = capsys.readouterr().err
    assert needle in err


def test_bad_vehicle_json_exits_2(tmp_path, capsys):
    v = VEHICLES["heavy"].to_dict() | {"mass_kg": -5}
    p = tmp_path / "v.json"
    p.write_text(json.dumps(v))
    assert main(["fit", WONG, "--vehicle", str(p)]) == 2
    err = capsys.readouterr().err
    assert "mass_kg" in err and str(p) in err
