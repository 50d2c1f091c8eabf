"""What a new user hit (issue 19, section 4): each item retried through the command line.

Items 4.1, 4.7-4.10, 4.12-4.14 (the fit side) and 4.16. Each test asserts exit codes, JSON
numbers, the figure written (and the numbers it plots), never the wording of a message.
"""

import json
import os
import re
import shutil
import subprocess

import numpy as np
import pytest

import soiltrack.plots as plots
from soiltrack.cli import main
from soiltrack.soilmodel import (
    TERRAINS,
    VEHICLES,
    DataError,
    Soil,
    Vehicle,
    read_csv,
    simulate,
    tractive_force_with_effects,
    write_csv,
)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LIGHT = VEHICLES["light"]
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
WHEEL_JSON = os.path.join(ROOT, "examples", "data", "cmu-3dterra", "smooth_wheel.json")


def run(capsys, *argv):
    """The CLI in-process: ``(exit status, stdout, stderr)``."""
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return rc, out, err


def figures(monkeypatch):
    """Record every figure the CLI saves: a list of ``[(ylabel, [ydata arrays of lines and collections])]``
    per axes, filled just before the figure is written and closed."""
    saved = []
    original = plots.save_figure

    def record(fig, path):
        axes = []
        for ax in fig.axes:
            ys = [np.asarray(line.get_ydata(), dtype=float) for line in ax.get_lines()]
            ys += [np.asarray(c.get_offsets(), dtype=float)[:, 1] for c in ax.collections if len(c.get_offsets())]
            axes.append((ax.get_ylabel(), ys, {line.get_label(): line for line in ax.get_lines()}))
        saved.append(axes)
        return original(fig, path)

    monkeypatch.setattr(plots, "save_figure", record)
    return saved


def is_png(path) -> bool:
    with open(path, "rb") as fh:
        return fh.read(8) == PNG_MAGIC and os.path.getsize(path) > 10_000


@pytest.fixture(scope="module")
def light_sweep(tmp_path_factory):
    """The light vehicle's sweep at 300 and 450 N on sandy loam (README's first example)."""
    path = tmp_path_factory.mktemp("newuser") / "sweep.csv"
    assert (
        main(
            [
                "simulate",
                "--kind",
                "sweep",
                "--vehicle",
                "light",
                "--terrain",
                "sandy_loam",
                "--loads",
                "300,450",
                "--seed",
                "1",
                "-o",
                str(path),
            ]
        )
        == 0
    )
    return path


# --- 4.1 a drive-log fit with an effect plots -------------------------------------------------
@pytest.mark.slow
def test_drive_log_fit_with_an_effect_plots_the_curve_with_the_effect(tmp_path, capsys, monkeypatch):
    story, png = tmp_path / "story.csv", tmp_path / "f.png"
    rc, _, _ = run(
        capsys,
        "simulate",
        "--vehicle",
        "light",
        "--terrain",
        "dry_sand",
        "--effect",
        "grade=0.05",
        "--seed",
        "7",
        "--duration",
        "40",
        "-o",
        story,
    )
    assert rc == 0
    saved = figures(monkeypatch)
    rc, out, _ = run(capsys, "fit", story, "--vehicle", "light", "--effect", "grade", "--plot", png)
    assert rc == 0 and is_png(png)
    rc, out, _ = run(capsys, "fit", story, "--vehicle", "light", "--effect", "grade", "--json")
    j = json.loads(out)
    # the drawn curve is soilmodel's thrust with the fitted grade (normal load W cos(theta)) at the fitted soil
    _, _, lines = saved[0][0]
    curve = next(line for label, line in lines.items() if label.startswith("fitted F(i)"))
    grid, drawn = np.asarray(curve.get_xdata(), float), np.asarray(curve.get_ydata(), float)
    p = j["parameters"]
    soil = Soil.from_kpa_deg(
        p["cohesion_kpa"]["value"], p["friction_angle_deg"]["value"], p["shear_modulus_m"]["value"]
    )
    theta = j["effects"]["grade"]["theta_rad"]["value"]
    expected = tractive_force_with_effects(grid, soil, LIGHT, {"grade": theta})
    assert abs(theta - 0.05) < 0.005
    np.testing.assert_allclose(drawn, expected, rtol=1e-9, atol=1e-9)  # N: a light vehicle is drawn in N


# --- 4.7 --soil checked like the vehicle file -------------------------------------------------
def test_soil_outside_the_range_of_soils_exits_2_in_every_command(tmp_path, capsys):
    out = tmp_path / "s.csv"
    for soil in ("1.7,29,10", "1.7,0.5,0.01", "1700,29,0.01"):  # K in mm, phi in radians, c in Pa
        assert run(capsys, "simulate", "--kind", "sweep", "--vehicle", "light", "--soil", soil, "-o", out)[0] == 2
        assert run(capsys, "margin", "--vehicle", "light", "--soil", soil, "--json")[0] == 2
        assert (
            run(
                capsys,
                "profile",
                "--vehicle",
                "light",
                "--soil",
                soil,
                "--v0",
                "0.5",
                "--v1",
                "1",
                "--duration",
                "5",
                "--json",
            )[0]
            == 2
        )
    assert not out.exists()


def test_soil_outside_the_practical_range_warns_on_stderr(tmp_path, capsys):
    out = tmp_path / "s.csv"
    base = run(
        capsys, "simulate", "--kind", "sweep", "--vehicle", "light", "--soil", "1.7,29,0.01", "--seed", "1", "-o", out
    )
    for soil in ("1.7,29,0.003", "1.7,4,0.01", "100,29,0.01"):  # K 3 mm, phi 4 deg, c 100 kPa: real but rare
        rc, _, err = run(
            capsys, "simulate", "--kind", "sweep", "--vehicle", "light", "--soil", soil, "--seed", "1", "-o", out
        )
        assert rc == 0 and len(err.splitlines()) == len(base[2].splitlines()) + 1


# --- 4.8 loads of another vehicle ----------------------------------------------------------
def test_a_light_sweep_fitted_with_the_heavy_vehicle_is_not_usable(light_sweep, capsys):
    rc, out, _ = run(capsys, "fit", light_sweep, "--vehicle", "heavy", "--json")
    j = json.loads(out)
    assert rc == 1 and j["success"] is False and j["outcome"] == "not_usable"
    assert len([w for w in j["warnings"] if "NOT USABLE" in w]) == 1
    rc, out, _ = run(capsys, "fit", light_sweep, "--vehicle", "light", "--json")
    assert rc == 0 and json.loads(out)["outcome"] == "usable"


def test_the_load_check_passes_a_rig_at_a_few_times_the_weight():
    from soiltrack.identify.sweep.plausibility import LOAD_FACTOR, check_loads

    W = LIGHT.weight
    assert check_loads(np.array([0.5, 1.0, 3.0]) * W, LIGHT) == []
    assert [f.usable for f in check_loads(np.full(4, W / (1.5 * LOAD_FACTOR)), LIGHT)] == [False]
    assert [f.usable for f in check_loads(np.full(4, W * 1.5 * LOAD_FACTOR), LIGHT)] == [False]


# --- 4.9 simulate says its seed ------------------------------------------------------------
@pytest.mark.parametrize(
    "gear", [["--vehicle", "light"], ["--vehicle", WHEEL_JSON, "--loads", "100,200"]], ids=["track", "rigid wheel"]
)
def test_simulate_without_a_seed_says_it_and_the_run_repeats(gear, tmp_path, capsys):
    a, b, again = tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "again.csv"
    seeds = []
    for path in (a, b):
        rc, _, err = run(capsys, "simulate", "--kind", "sweep", *gear, "-o", path)
        assert rc == 0
        seeds.append(int(re.search(r"--seed (\d+)", err).group(1)))
    assert seeds[0] != seeds[1] and a.read_bytes() != b.read_bytes()
    rc, _, err = run(capsys, "simulate", "--kind", "sweep", *gear, "--seed", seeds[0], "-o", again)
    assert rc == 0 and again.read_bytes() == a.read_bytes()
    assert re.search(r"--seed \d+", err) is None  # a given seed is not repeated back


# --- 4.10 units by magnitude in figures and reports -----------------------------------------
def test_light_vehicle_figures_are_in_newtons(light_sweep, tmp_path, capsys, monkeypatch):
    saved = figures(monkeypatch)
    assert (
        run(
            capsys,
            "simulate",
            "--kind",
            "sweep",
            "--vehicle",
            "light",
            "--terrain",
            "sandy_loam",
            "--seed",
            "1",
            "-o",
            tmp_path / "s.csv",
            "--plot",
            tmp_path / "data.png",
        )[0]
        == 0
    )
    assert run(capsys, "fit", light_sweep, "--vehicle", "light", "--plot", tmp_path / "fit.png")[0] == 0
    data = read_csv(str(light_sweep))
    ((_, data_ys, _),) = saved[0]
    (_, fit_ys, _), _ = saved[1]
    for ys in (data_ys, fit_ys):
        peak = max(float(np.max(np.abs(y))) for y in ys if y.size)
        assert 1.0 <= peak < 1000.0  # a mantissa by magnitude: 300 N is 300, not 0.3 (kN)
    # the fit figure draws the forces themselves (N), the data figure too
    assert max(float(np.max(y)) for y in fit_ys if y.size) == pytest.approx(float(np.max(data.values)), rel=0.2)


# a number and its unit; a standard error ("SE 0.08 kN") shares its value's unit and is not checked
NUMBER_UNIT = re.compile(r"(?<![\w.])(?<!SE )([-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?) (kN|N|%|ms|s)(?![\w/])")


def magnitudes_ok(report: str) -> list[str]:
    """Numbers with units that a unit by magnitude would not print: ``0.027 kN``, ``2460 N``, ``5.4e+02 %``."""
    bad = []
    for m in NUMBER_UNIT.finditer(report):
        x, unit = float(m.group(1)), m.group(2)
        if (
            "e" in m.group(1)
            or (unit == "kN" and not 1 <= abs(x) < 1000)
            or (unit == "N" and abs(x) >= 1000)
            or (unit == "ms" and x >= 1000)
        ):
            bad.append(m.group(0))
    return bad


@pytest.mark.slow
def test_a_gentle_light_drive_log_report_has_units_by_magnitude(tmp_path, capsys):
    log = simulate(
        LIGHT, TERRAINS["dry_sand"], kind="drive", seed=3, duration_s=30, speed_profile=[(0, 0.3), (5, 0.6), (30, 0.7)]
    )
    path = tmp_path / "gentle.csv"
    write_csv(log, path)
    rc, out, _ = run(capsys, "fit", path, "--vehicle", "light")
    assert rc == 0 and NUMBER_UNIT.search(out) is not None
    assert magnitudes_ok(out) == []


def test_sweep_reports_have_units_by_magnitude(light_sweep, capsys):
    for vehicle in ("light", os.path.join(ROOT, "examples", "data", "heavy_vehicle.json")):
        data = light_sweep if vehicle == "light" else os.path.join(ROOT, "examples", "data", "wong2001_p176.csv")
        rc, out, _ = run(capsys, "fit", data, "--vehicle", vehicle)
        assert rc == 0 and magnitudes_ok(out) == []


# --- 4.12 outputs in named, ignored folders -------------------------------------------------
def load_script(path):
    import importlib.util

    spec = importlib.util.spec_from_file_location(os.path.splitext(os.path.basename(path))[0], path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.skipif(
    shutil.which("git") is None
    or not os.path.isdir(os.path.join(ROOT, ".git"))
    and not os.path.isfile(os.path.join(ROOT, ".git")),
    reason="not a git checkout",
)
def test_example_and_benchmark_figures_go_to_ignored_folders():
    story = load_script(os.path.join(ROOT, "examples", "diagnose_story.py"))
    bench = load_script(os.path.join(ROOT, "benchmarks", "bench_diagnose.py"))
    for path in (os.path.join(story.DEFAULT_OUT, "diagnosis_sweep.png"), bench.DEFAULT_PNG):
        assert os.path.isabs(path) and os.path.dirname(path) != ROOT
        ignored = subprocess.run(["git", "check-ignore", "-q", os.path.relpath(path, ROOT)], cwd=ROOT)
        assert ignored.returncode == 0, path
    tracked = subprocess.run(["git", "ls-files", "*.png"], cwd=ROOT, capture_output=True, text=True).stdout.split()
    assert [p for p in tracked if "/" not in p] == []  # no figure at the repository root


# --- 4.13 fit --help and --interval-method -------------------------------------------------
def test_fit_help_lists_every_file_kind_and_interval_method(light_sweep, capsys):
    with pytest.raises(SystemExit) as e:
        main(["fit", "--help"])
    assert e.value.code == 0
    helptext = capsys.readouterr().out
    for column in ("tractive_force_N", "drawbar_pull_N", "sprocket_torque_Nm", "normal_load_N"):
        assert column in helptext
    options = set(re.findall(r"(--[a-z-]+)", helptext))
    assert "--interval-method" in options and "--intervals" not in options and "--bounds" in options
    rc, out, _ = run(capsys, "fit", light_sweep, "--vehicle", "light", "--interval-method", "profile", "--json")
    assert rc == 0 and json.loads(out)["success"] is True


# --- 4.14 one vocabulary, SE, the JSON typo, the residual sign -------------------------------
def test_outcome_is_one_vocabulary_across_solvers(light_sweep, capsys):
    statuses, outcomes = set(), set()
    for opts in ([], ["--method", "least-squares"]):
        rc, out, _ = run(capsys, "fit", light_sweep, "--vehicle", "light", "--json", *opts)
        j = json.loads(out)
        assert rc == 0 and j["success"]
        statuses.add(j["status"])
        outcomes.add(j["outcome"])
    assert len(statuses) == 2 and outcomes == {"usable"}  # two solvers' words, one outcome
    wong = os.path.join(ROOT, "examples", "data", "wong2001_p176.csv")
    rc, out, _ = run(capsys, "fit", wong, "--vehicle", "heavy", "--json", "--method", "newton")  # singular
    assert rc == 1 and json.loads(out)["outcome"] == "failed"


def test_the_standard_error_is_labelled_and_matches_the_json(capsys):
    wong = os.path.join(ROOT, "examples", "data", "wong2001_p176.csv")
    _, report, _ = run(capsys, "fit", wong, "--vehicle", "heavy")
    _, out, _ = run(capsys, "fit", wong, "--vehicle", "heavy", "--json")
    fmax = next(c for c in json.loads(out)["combinations"] if c["name"].startswith("F_max"))
    m = re.search(r"F_max at W = 329 kN +([\d.]+) kN \(SE ([\d.]+) kN\), 95 % \[([\d.]+), ([\d.]+)\] kN", report)
    value, se, lo, hi = (float(x) * 1e3 for x in m.groups())
    assert value == pytest.approx(fmax["value"], rel=1e-4) and se == pytest.approx(fmax["stderr"], rel=1e-2)
    assert (lo, hi) == (pytest.approx(fmax["ci95"][0], rel=1e-3), pytest.approx(fmax["ci95"][1], rel=1e-3))
    assert (hi - lo) / 2 > 10 * se  # the interval is not value +- SE: 1 residual dof, t = 12.7


def test_a_typo_in_the_vehicle_file_is_named(tmp_path, capsys):
    d = json.loads(LIGHT.to_json())
    d["mass_kgg"] = d.pop("mass_kg")
    path = tmp_path / "typo.json"
    path.write_text(json.dumps(d))
    with pytest.raises(DataError) as e:
        Vehicle.from_json(str(path))
    assert e.value.column == "mass_kgg"
    wong = os.path.join(ROOT, "examples", "data", "wong2001_p176.csv")
    rc, _, err = run(capsys, "fit", wong, "--vehicle", path)
    assert rc == 2 and "mass_kgg" in err


def test_residuals_are_measured_minus_model(tmp_path, capsys):
    data = simulate(LIGHT, TERRAINS["sandy_loam"], kind="sweep", seed=1, normal_loads=[300.0, 450.0])
    force = data.values.copy()
    force[5] += 15.0  # one reading 15 N above the curve
    path = tmp_path / "bumped.csv"
    write_csv(type(data)(slip=data.slip, tractive_force=force, normal_load=data.normal_load), path)
    rc, out, _ = run(capsys, "fit", path, "--vehicle", "light", "--json")
    j = json.loads(out)
    r = np.array(j["residuals"]["values"])
    assert j["residuals"]["unit"] == "N" and r.size == force.size
    assert r[5] > 10.0 and r[5] == pytest.approx(np.max(r))


@pytest.mark.slow
def test_drive_log_residuals_have_one_sign_with_and_without_effects(tmp_path, capsys):
    log = tmp_path / "log.csv"
    assert (
        run(
            capsys,
            "simulate",
            "--vehicle",
            "light",
            "--terrain",
            "dry_sand",
            "--seed",
            "2",
            "--duration",
            "30",
            "-o",
            log,
        )[0]
        == 0
    )
    res = []
    for opts in ([], ["--effect", "grade", "--torque-hold", "zoh"]):
        rc, out, _ = run(capsys, "fit", log, "--vehicle", "light", "--json", *opts)
        assert rc == 0
        res.append(np.array(json.loads(out)["residuals"]["values"]))
    assert res[0].size == res[1].size
    assert np.corrcoef(res[0], res[1])[0, 1] > 0.9  # no grade in the log: the same residuals, the same sign


# --- 4.16 fit --bounds ---------------------------------------------------------------------
def test_fit_bounds_widen_phi_below_6_degrees(tmp_path, capsys):
    path = tmp_path / "slippery.csv"
    assert (
        run(
            capsys,
            "simulate",
            "--kind",
            "sweep",
            "--vehicle",
            "light",
            "--soil",
            "0,4,0.01",
            "--loads",
            "300,450",
            "--seed",
            "2",
            "-o",
            path,
        )[0]
        == 0
    )
    phis = {}
    for bounds in (None, "wide", "0,69,2,40,0.006,0.05"):
        rc, out, _ = run(
            capsys,
            "fit",
            path,
            "--vehicle",
            "light",
            "--model",
            "cohesion-free",
            "--json",
            *(["--bounds", bounds] if bounds else []),
        )
        j = json.loads(out)
        phis[bounds] = j["parameters"]["friction_angle_deg"]
        # the practical bounds pin phi at 6 deg, and the curve then misses the repeats (a poor fit, exit 1)
        assert (rc, j["outcome"]) == ((1, "poor_fit") if bounds is None else (0, "usable"))
    assert phis[None]["value"] == pytest.approx(6.0) and phis[None]["at_bound"]
    for b in ("wide", "0,69,2,40,0.006,0.05"):
        assert abs(phis[b]["value"] - 4.0) < 0.2 and not phis[b]["at_bound"]
        assert phis[b]["ci95"][0] < 4.0 < phis[b]["ci95"][1]
    for bad in ("loose", "0,69,0,40,0.006,0.05", "0,69,6,40,0.05,0.006", "1,2,3"):
        assert run(capsys, "fit", path, "--vehicle", "light", "--bounds", bad)[0] == 2
