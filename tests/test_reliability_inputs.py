"""Malformed input: every case exits 2 with one line (no traceback), and the error's structured fields
name the file, the field or column and the rows (issue 23, item 4; issue 19, item 4.15)."""

import csv
import json

import numpy as np
import pytest

from soiltrack.cli import main
from soiltrack.planning import load_fit_json, read_route
from soiltrack.soilmodel import TERRAINS, VEHICLES, DataError, SlipData, Vehicle, read_csv, write_csv
from soiltrack.soilmodel.csvread import MAX_ROWS, MAX_ROWS_ENV
from soiltrack.soilmodel.errors import SHOWN_ROWS
from soiltrack.soilmodel.jsonread import MAX_JSON_DEPTH, json_depth
from soiltrack.soilmodel.simulation import simulate

LIGHT = VEHICLES["light"]


def _cli(args, capsys) -> tuple[int, str]:
    rc = main(args)
    err = capsys.readouterr().err
    return rc, err


def _one_error_line(err: str, command: str) -> bool:
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    return "Traceback" not in err and len(lines) == 1 and lines[0].startswith(f"soiltrack {command}: error:")


@pytest.fixture(scope="module")
def sweep_csv(tmp_path_factory):
    p = tmp_path_factory.mktemp("sweep") / "sweep.csv"
    write_csv(simulate(LIGHT, TERRAINS["sandy_loam"], kind="sweep", seed=1, normal_loads=[300, 450]), str(p))
    return str(p)


@pytest.fixture(scope="module")
def fit_json(tmp_path_factory, sweep_csv):
    from soiltrack.identify import fit

    res = fit(read_csv(sweep_csv), LIGHT)
    assert res.success
    p = tmp_path_factory.mktemp("fit") / "fit.json"
    p.write_text(res.to_json())
    return json.loads(res.to_json())


# ------------------------------------------------------------------ JSON: depth and encoding
def _deep(path, wrap):
    n = 200_000
    path.write_text(wrap("[" * n + "]" * n))
    return str(path)


@pytest.mark.parametrize("kind", ["vehicle", "fit", "route"])
def test_json_nested_200000_levels_exits_2(tmp_path, capsys, sweep_csv, kind):
    wrap = (lambda s: '{"patches": ' + s + "}") if kind == "route" else (lambda s: s)
    path = _deep(tmp_path / f"{kind}.json", wrap)
    assert json_depth(open(path).read()) > MAX_JSON_DEPTH
    args = {
        "vehicle": ["fit", sweep_csv, "--vehicle", path],
        "fit": ["margin", "--vehicle", "light", "--fit", path],
        "route": ["route", path, "--vehicle", "light"],
    }[kind]
    rc, err = _cli(args, capsys)
    assert rc == 2 and _one_error_line(err, args[0])
    loader = {"vehicle": Vehicle.from_json, "fit": lambda p: load_fit_json(p, LIGHT), "route": read_route}[kind]
    with pytest.raises(DataError) as e:
        loader(path)
    assert e.value.file == path


@pytest.mark.parametrize("encoding", ["utf-16", "utf-16-le", "binary"])
@pytest.mark.parametrize("kind", ["fit", "route"])
def test_utf16_or_binary_json_exits_2(tmp_path, capsys, fit_json, kind, encoding):
    obj = fit_json if kind == "fit" else {"patches": [{"length_m": 10, "terrain": "lete_sand"}]}
    path = tmp_path / f"{kind}.json"
    if encoding == "binary":
        path.write_bytes(bytes(range(256)) * 4)
    else:
        path.write_bytes(json.dumps(obj).encode(encoding))
    args = (
        ["margin", "--vehicle", "light", "--fit", str(path)]
        if kind == "fit"
        else ["route", str(path), "--vehicle", "light"]
    )
    rc, err = _cli(args, capsys)
    assert rc == 2 and _one_error_line(err, args[0])
    with pytest.raises(DataError) as e:
        load_fit_json(str(path), LIGHT) if kind == "fit" else read_route(str(path))
    assert e.value.file == str(path)


def test_utf8_bom_json_is_read(tmp_path):
    p = tmp_path / "route.json"
    p.write_bytes(b"\xef\xbb\xbf" + json.dumps({"patches": [{"length_m": 10, "terrain": "lete_sand"}]}).encode())
    assert read_route(str(p)).length_m == 10


# ------------------------------------------------------------------ simulate --seed -1
def test_simulate_negative_seed_exits_2(tmp_path, capsys):
    rc, err = _cli(["simulate", "--kind", "sweep", "--seed", "-1", "-o", str(tmp_path / "x.csv")], capsys)
    assert rc == 2 and _one_error_line(err, "simulate")
    assert not (tmp_path / "x.csv").exists()


# ------------------------------------------------------------------ CSV
def test_csv_field_longer_than_the_limit_names_the_row(tmp_path, capsys):
    p = tmp_path / "long.csv"
    p.write_text('slip,tractive_force_N\n0.1,100\n0.2,"' + "1" * 140_000 + "\n0.3,150\n")
    with pytest.raises(DataError) as e:
        read_csv(str(p))
    assert e.value.file == str(p) and e.value.row == 2
    for cmd in ("fit", "diagnose"):
        rc, err = _cli([cmd, str(p), "--vehicle", "light"], capsys)
        assert rc == 2 and _one_error_line(err, cmd)


def test_drive_log_torque_1e308_is_refused_naming_column_and_row(tmp_path, capsys):
    log = simulate(LIGHT, TERRAINS["sandy_loam"], kind="drive", seed=1, duration_s=10)
    p = tmp_path / "log.csv"
    write_csv(log, str(p))
    rows = list(csv.reader(open(p)))
    col = rows[0].index("sprocket_torque_Nm")
    rows[5][col] = "1e308"
    with open(p, "w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    with pytest.raises(DataError) as e:
        read_csv(str(p))
    assert (e.value.file, e.value.column, e.value.row) == (str(p), "sprocket_torque_Nm", 5)
    rc, err = _cli(["fit", str(p), "--vehicle", "light"], capsys)
    assert rc == 2 and _one_error_line(err, "fit")


def test_in_memory_torque_1e308_is_refused():
    log = simulate(LIGHT, TERRAINS["sandy_loam"], kind="drive", seed=1, duration_s=5)
    M = np.array(log.sprocket_torque)
    M[[3, 9]] = 1e308
    with pytest.raises(DataError) as e:
        type(log)(log.time, M, log.sprocket_speed, log.vehicle_speed)
    assert (e.value.column, e.value.rows, e.value.count) == ("sprocket_torque_Nm", (4, 10), 2)


def test_every_bad_row_is_counted_and_the_first_few_named(tmp_path):
    n_bad = 30
    lines = ["slip,tractive_force_N"]
    bad_rows = []
    for r in range(1, 121):
        if r % 3 == 0 and len(bad_rows) < n_bad:
            lines.append(f"{r / 200:.4f},oops")
            bad_rows.append(r)
        else:
            lines.append(f"{r / 200:.4f},{100 + r}")
    p = tmp_path / "bad.csv"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError) as e:
        read_csv(str(p))
    assert e.value.count == n_bad
    assert e.value.rows == tuple(bad_rows[:SHOWN_ROWS])
    assert e.value.column == "tractive_force_N" and e.value.row == bad_rows[0]


def test_bad_rows_of_a_range_check_are_all_counted():
    slip = np.linspace(0.05, 0.6, 20)
    slip[[2, 4, 6, 8, 10, 12, 14]] = 1.5
    with pytest.raises(DataError) as e:
        SlipData(slip, tractive_force=np.linspace(10, 100, 20))
    assert (e.value.column, e.value.count, e.value.rows) == ("slip", 7, (3, 5, 7, 9, 11, 13, 15))


def test_non_increasing_time_rows_are_all_counted():
    t = np.arange(20.0)
    t[[5, 11]] = t[[4, 10]]
    z = np.ones(20)
    from soiltrack.soilmodel import DriveLog

    with pytest.raises(DataError) as e:
        DriveLog(t, z, z, z)
    assert (e.value.column, e.value.count, e.value.rows) == ("time_s", 2, (6, 12))


def test_row_limit_is_configurable_and_refuses_before_reading_on(tmp_path, monkeypatch, capsys):
    p = tmp_path / "rows.csv"
    with open(p, "w") as fh:
        fh.write("slip,tractive_force_N\n")
        for k in range(1000):
            fh.write(f"{0.01 + 0.0005 * k:.5f},{100 + k}\n")
    assert read_csv(str(p)).n_samples == 1000
    with pytest.raises(DataError) as e:
        read_csv(str(p), max_rows=500)
    assert (e.value.file, e.value.row) == (str(p), 501)
    monkeypatch.setenv(MAX_ROWS_ENV, "999")
    rc, err = _cli(["fit", str(p), "--vehicle", "light"], capsys)
    assert rc == 2 and _one_error_line(err, "fit")
    monkeypatch.setenv(MAX_ROWS_ENV, "many")
    with pytest.raises(DataError):
        read_csv(str(p))
    monkeypatch.delenv(MAX_ROWS_ENV)
    assert MAX_ROWS == 2_000_000


@pytest.mark.slow
def test_five_million_rows_refused_with_bounded_memory(tmp_path):
    """A 5-million-row log is refused at the default limit (a child process; its peak memory measured)."""
    import subprocess
    import sys

    p = tmp_path / "big.csv"
    with open(p, "w") as fh:
        fh.write("time_s,sprocket_torque_Nm,sprocket_speed_rad_s,vehicle_speed_m_s\n")
        for k in range(50):  # time increases: rows differ only in time
            fh.write("".join(f"{(k * 100_000 + j) * 0.01:.2f},10.5,12.25,0.95\n" for j in range(100_000)))
    code = (
        "import sys\nfrom soiltrack.soilmodel import read_csv, DataError\n"
        "try:\n    read_csv(sys.argv[1])\nexcept DataError as e:\n    print(e.row)\n"
        # the peak of this process's own memory (VmHWM, kB): getrusage's ru_maxrss keeps the forking
        # parent's peak across exec on Linux (1.7 GB at the end of a long pytest run)
        "print(next(l.split()[1] for l in open('/proc/self/status') if l.startswith('VmHWM')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code, str(p)], capture_output=True, text=True, timeout=600)
    row, kb = out.stdout.split()
    assert int(row) == MAX_ROWS + 1
    assert int(kb) < 400_000  # 2 million rows x 4 columns x 8 bytes = 64 MB of numbers, plus the interpreter


# ------------------------------------------------------------------ route file
def _route(tmp_path, obj) -> str:
    p = tmp_path / "route.json"
    p.write_text(json.dumps(obj))
    return str(p)


@pytest.mark.parametrize(
    "patches,field",
    [
        ([{"length_m": 10, "terrain": ["lete_sand"]}], "patches[0].terrain"),
        ([{"length_m": 1e308, "terrain": "lete_sand"}], "patches[0].length_m"),
        ([{"length_m": 1.0, "terrain": "lete_sand"}] * 200_000, "patches"),
        (
            [
                {
                    "length_m": 10,
                    "soil": {"cohesion_kpa": 1e300, "friction_angle_deg": 30, "shear_modulus_m": 0.01},
                }
            ],
            "patches[0].soil.cohesion_kpa",
        ),
    ],
)
@pytest.mark.slow
def test_bad_route_exits_2_naming_the_field(tmp_path, capsys, patches, field):
    path = _route(tmp_path, {"patches": patches})
    with pytest.raises(DataError) as e:
        read_route(path)
    assert (e.value.file, e.value.field) == (path, field)
    rc, err = _cli(["route", path, "--vehicle", "light"], capsys)
    assert rc == 2 and _one_error_line(err, "route")
    assert "--intervals" not in err  # never blames an option that was not given


# ------------------------------------------------------------------ --fit values
@pytest.mark.parametrize(
    "edit,field",
    [
        (
            lambda o: o["parameters"]["cohesion_kpa"].__setitem__("value", 1e300),
            "parameters.cohesion_kpa.value",
        ),
        (
            lambda o: o["parameters"]["friction_angle_deg"].__setitem__("value", 85.0),
            "parameters.friction_angle_deg.value",
        ),
        (
            lambda o: o["parameters"]["shear_modulus_m"].__setitem__("value", 10.0),
            "parameters.shear_modulus_m.value",
        ),
        (
            lambda o: o["parameters"]["cohesion_kpa"].__setitem__("stderr", -0.1),
            "parameters.cohesion_kpa.stderr",
        ),
        (
            lambda o: o["parameters"]["friction_angle_deg"].__setitem__("value", -3.0),
            "parameters.friction_angle_deg.value",
        ),
    ],
)
def test_absurd_fit_values_are_refused(tmp_path, capsys, fit_json, edit, field):
    obj = json.loads(json.dumps(fit_json))
    edit(obj)
    p = tmp_path / "fit.json"
    p.write_text(json.dumps(obj))
    with pytest.raises(DataError) as e:
        load_fit_json(str(p), LIGHT)
    assert (e.value.file, e.value.field) == (str(p), field)
    rc, err = _cli(["margin", "--vehicle", "light", "--fit", str(p)], capsys)
    assert rc == 2 and _one_error_line(err, "margin")


def test_the_fit_json_as_printed_is_accepted(tmp_path, fit_json):
    p = tmp_path / "fit.json"
    p.write_text(json.dumps(fit_json))
    assert load_fit_json(str(p), LIGHT).model == "full"


# ------------------------------------------------------------------ absurd arguments
@pytest.mark.parametrize(
    "args",
    [
        ["margin", "--vehicle", "light", "--terrain", "lete_sand", "--drawbar-N=-1e9"],
        ["margin", "--vehicle", "light", "--terrain", "lete_sand", "--drawbar-N=1e9"],
        [
            "profile",
            "--vehicle",
            "light",
            "--terrain",
            "lete_sand",
            "--v0",
            "0.5",
            "--v1",
            "1",
            "--distance",
            "1e300",
        ],
    ],
)
def test_absurd_arguments_exit_2(capsys, args):
    rc, err = _cli(args, capsys)
    assert rc == 2 and _one_error_line(err, args[0])


def test_a_small_negative_drawbar_is_a_push(capsys):
    rc = main(["margin", "--vehicle", "light", "--terrain", "lete_sand", "--drawbar-N=-50", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["traversable"] is True
