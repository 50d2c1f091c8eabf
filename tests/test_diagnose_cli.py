"""``soiltrack diagnose``: bad input exits 2 with the file, column or argument named and no traceback."""

import json
import os

import pytest

from soiltrack.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
WONG = os.path.join(ROOT, "examples", "data", "wong2001_p176.csv")


def _csv(tmp_path, text, name="d.csv"):
    p = tmp_path / name
    p.write_text(text)
    return str(p)


@pytest.mark.parametrize(
    "text,needle",
    [
        ("slip,force\n0.1,100\n0.2,200\n", "tractive_force_N"),  # wrong column
        ("slip,tractive_force_N\n0.1,100\n0.2,nan\n", "row"),  # NaN, row named
        ("slip,tractive_force_N\n0.1,100\n1.2,200\n", "slip"),  # slip outside [0, 1)
        ("time_s,sprocket_torque_Nm,sprocket_speed_rad_s,vehicle_speed_m_s\n0,1,1,0.1\n0,1,1,0.1\n", "time_s"),
    ],
)
def test_bad_data_exits_2_naming_the_problem(tmp_path, capsys, text, needle):
    path = _csv(tmp_path, text)
    assert main(["diagnose", path, "--vehicle", "heavy", "--json"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and needle in err and "d.csv" in err


def test_bad_arguments_exit_2(tmp_path, capsys):
    assert main(["diagnose", WONG, "--vehicle", "heavy", "--candidates", "grade,warp_drive"]) == 2
    err = capsys.readouterr().err
    assert "warp_drive" in err and "grade" in err
    assert main(["diagnose", WONG, "--vehicle", "no_such_vehicle.json"]) == 2
    assert "no_such_vehicle.json" in capsys.readouterr().err
    assert main(["diagnose", str(tmp_path / "missing.csv"), "--vehicle", "heavy"]) == 2
    assert "missing.csv" in capsys.readouterr().err
    assert main(["diagnose", WONG, "--vehicle", "heavy", "--candidates", ","]) == 2
    assert "--candidates" in capsys.readouterr().err


@pytest.mark.slow
def test_progress_on_stderr_and_quiet(tmp_path, capsys):
    # the stages of a diagnosis, one line each on stderr with the time since the start; stdout keeps the JSON alone
    import json

    from soiltrack.soilmodel import TERRAINS, VEHICLES, simulate, write_csv

    path = str(tmp_path / "sweep.csv")
    write_csv(
        simulate(VEHICLES["heavy"], TERRAINS["lete_sand"], kind="sweep", effects={"slip_sinkage": 0.12}, seed=1), path
    )
    assert main(["diagnose", path, "--vehicle", "heavy", "--json"]) == 0
    out, err = capsys.readouterr()
    json.loads(out)
    lines = err.strip().splitlines()
    assert lines[0].startswith("[") and "screening" in lines[0]
    assert any("on the training blocks" in line for line in lines), lines
    assert main(["diagnose", path, "--vehicle", "heavy", "--json", "--quiet"]) == 0
    out, err = capsys.readouterr()
    json.loads(out)
    assert err == ""


@pytest.mark.parametrize("plot", ["no_such_dir/d.png", "d.notanimage"])
def test_a_bad_plot_path_exits_2_before_the_work(tmp_path, capsys, plot):
    assert main(["diagnose", WONG, "--vehicle", "heavy", "--plot", str(tmp_path / plot)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "--plot" in err


def test_torque_hold_auto_is_accepted_and_applies_to_logs_only(capsys):
    # auto is the default and means "not given" (the sampled torque weighed as an outside cause); zoh on a sweep
    # is refused
    assert main(["diagnose", WONG, "--vehicle", "heavy", "--torque-hold", "auto", "--json", "--quiet"]) == 0
    assert json.loads(capsys.readouterr().out)["verdict"] == "none"
    assert main(["diagnose", WONG, "--vehicle", "heavy", "--torque-hold", "zoh"]) == 2
