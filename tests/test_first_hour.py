"""A new user's first hour (issue 7): each item as the user met it, through the CLI where it is bad input."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from soiltrack.cli import main
from soiltrack.identify import fit
from soiltrack.soilmodel import TERRAINS, VEHICLES, DataError, Vehicle, max_thrust, simulate, tractive_force
from soiltrack.soilmodel.data import write_csv

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LIGHT = VEHICLES["light"]
LIGHT_JSON = os.path.join(ROOT, "examples", "data", "light_vehicle.json")


def run_module(*args, cwd=ROOT):
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run(
        [sys.executable, "-m", "soiltrack", *args], capture_output=True, text=True, cwd=cwd, env=env, timeout=300
    )


def bad_input(capsys, *argv, says=()):
    """Run the CLI in-process: exit 2, a message on stderr that says ``says``, nothing raised."""
    rc = main(list(argv))
    err = capsys.readouterr().err
    assert rc == 2, err
    assert "error:" in err and "Traceback" not in err
    for s in says:
        assert s in err, err
    return err


@pytest.fixture(scope="module")
def sweep_csv(tmp_path_factory):
    """The light vehicle's default sweep on dry sand (22 slips up to 0.7), one normal load."""
    path = str(tmp_path_factory.mktemp("first") / "sweep.csv")
    write_csv(simulate(LIGHT, TERRAINS["dry_sand"], kind="sweep", seed=1), path)
    return path


# --- item 2: predictions from a FitResult at one normal load -------------------------------------
@pytest.fixture(scope="module")
def one_load_fit():
    sweep = simulate(LIGHT, TERRAINS["sandy_loam"], kind="sweep", normal_loads=[300.0], seed=1)
    return fit(sweep, LIGHT)


def test_readme_example_at_one_load_predicts_from_the_result(one_load_fit):
    res = one_load_fit
    assert res.success and res.soil is None  # c and phi not separable: no soil, as before
    F = tractive_force([0.05, 0.2], res, LIGHT)
    # the prediction is the fitted curve: at the fitted load its limit is the F_max combination
    fmax = next(cb for cb in res.combinations if cb.name.startswith("F_max"))
    assert max_thrust(res, LIGHT) == pytest.approx(fmax.value, rel=1e-12)
    # and it does not depend on which ridge point the optimiser stopped at
    A, W = LIGHT.contact_area, 300.0
    c2 = res.theta[0] + 100.0
    phi2 = np.arctan((fmax.value - A * c2) / W)
    from soiltrack.soilmodel import Soil

    other = tractive_force([0.05, 0.2], Soil(c2, phi2, res.theta[2]), LIGHT)
    np.testing.assert_allclose(F, other, rtol=1e-12)
    # the data are reproduced to within the noise
    assert np.all(np.abs(F - tractive_force([0.05, 0.2], Soil(*res.theta), LIGHT)) < 1e-9)


def test_one_load_prediction_refused_elsewhere_and_none_explained(one_load_fit):
    with pytest.raises(DataError, match="not separable.*W = 450 N"):
        tractive_force([0.1], one_load_fit, LIGHT, normal_load=450.0)
    with pytest.raises(DataError, match="pass the FitResult itself"):
        tractive_force([0.1], one_load_fit.soil, LIGHT)


def test_two_load_result_predicts_like_its_soil():
    sweep = simulate(LIGHT, TERRAINS["sandy_loam"], kind="sweep", normal_loads=[300.0, 450.0], seed=1)
    res = fit(sweep, LIGHT)
    assert res.soil is not None
    np.testing.assert_array_equal(
        tractive_force([0.05, 0.2], res, LIGHT, normal_load=600.0),
        tractive_force([0.05, 0.2], res.soil, LIGHT, normal_load=600.0),
    )


# --- item 4: output paths and absurd sizes ---------------------------------------------------------
@pytest.mark.parametrize(
    "opt,path,says",
    [
        ("--plot", "/nonexistent_dir/x.png", "does not exist"),
        ("--plot", "out.xyz", "unknown figure format '.xyz'"),
        ("--plot", "{tmp}", "is a folder"),
        ("--plot", "{tmp}/noext", "no file extension"),
    ],
)
def test_fit_bad_plot_path(capsys, sweep_csv, tmp_path, opt, path, says):
    bad_input(capsys, "fit", sweep_csv, "--vehicle", "light", opt, path.format(tmp=tmp_path), says=[opt, says])
    assert os.listdir(tmp_path) == []  # nothing written, not even tmp/noext.png


@pytest.mark.parametrize(
    "args,says",
    [
        (["-o", "/nonexistent_dir/x.csv"], ["-o/--output", "does not exist"]),
        (["--plot", "/nonexistent_dir/x.png"], ["--plot", "does not exist"]),
        (["--duration", "1e9", "--rate", "1e6"], ["--duration", "--rate", "samples; at most"]),
        (["--loads", "300"], ["--loads applies to slip sweeps only"]),
        (["--effect", "grade"], ["--effect 'grade' needs a value"]),
        (["--kind", "sweep", "--duration", "5"], ["--duration applies to drive logs only"]),
    ],
)
def test_simulate_bad_arguments(capsys, args, says):
    bad_input(capsys, "simulate", "--vehicle", "light", *args, says=says)


def test_fit_says_where_the_figure_went(capsys, sweep_csv, tmp_path):
    png = str(tmp_path / "fit.png")
    assert main(["fit", sweep_csv, "--vehicle", "light", "--plot", png]) in (0, 1)
    assert f"wrote the figure to {png}" in capsys.readouterr().err
    assert os.path.getsize(png) > 1000


@pytest.mark.slow
def test_no_traceback_through_the_real_command(tmp_path):
    """The same paths as a user runs them: a separate process, exit 2, one line, no traceback."""
    for args in (
        ["simulate", "-o", "/nonexistent_dir/x.csv"],
        ["simulate", "--kind", "sweep", "--plot", str(tmp_path / "x.xyz")],
    ):
        p = run_module(*args)
        assert p.returncode == 2 and "Traceback" not in p.stderr and "error:" in p.stderr, p.stderr


# --- item 6: fewer distinct slips than the curve needs ---------------------------------------------
def test_same_slip_rows_are_bad_input(capsys, tmp_path):
    path = tmp_path / "same.csv"
    path.write_text("slip,tractive_force_N\n" + "".join(f"0.02,{30 + k}\n" for k in range(4)))
    bad_input(capsys, "fit", str(path), "--vehicle", "light", says=["column 'slip'", "two or more different slips"])


# --- item 9: vehicle JSON with a BOM, absurd numbers, semicolon CSV -----------------------------------
def test_vehicle_json_with_utf8_bom_is_read(tmp_path):
    p = tmp_path / "bom.json"
    p.write_bytes(b"\xef\xbb\xbf" + open(LIGHT_JSON, "rb").read())
    assert Vehicle.from_json(str(p)).mass == pytest.approx(Vehicle.from_json(LIGHT_JSON).mass)


@pytest.mark.parametrize(
    "key,value",
    [("mass_kg", 1e300), ("track_length_m", 500.0), ("sprocket_radius_m", 1e-9), ("max_sprocket_torque_Nm", 1e20)],
)
def test_absurd_vehicle_numbers_refused_with_field(capsys, sweep_csv, tmp_path, key, value):
    obj = json.load(open(LIGHT_JSON))
    obj[key] = value
    p = tmp_path / "v.json"
    p.write_text(json.dumps(obj))
    bad_input(capsys, "fit", sweep_csv, "--vehicle", str(p), says=[f"column '{key}'", "plausible range"])


def test_semicolon_csv_names_the_separator(capsys, tmp_path):
    p = tmp_path / "semi.csv"
    p.write_text("slip;tractive_force_N\n0.02;30\n0.05;50\n0.1;60\n")
    bad_input(capsys, "fit", str(p), "--vehicle", "light", says=["separated by ';'", "comma-separated"])


# --- item 10: help texts and options that do not apply -----------------------------------------------
def test_help_texts(capsys):
    for argv in (["--help"], ["fit", "--help"], ["simulate", "--help"]):
        with pytest.raises(SystemExit):
            main(argv)
    out = " ".join(capsys.readouterr().out.split())  # argparse wraps to the terminal width
    assert "exit status:" in out and "example:" in out  # top level
    for col in ("time_s", "sprocket_torque_Nm", "sprocket_speed_rad_s", "vehicle_speed_m_s", "vehicle_accel_m_s2"):
        assert col in out  # fit --help lists the drive-log columns
    assert "cohesion-free: F_max = W tan(phi)" in out and "seed paper's unbounded methods" in out
    assert "(default: 60)" in out and "(default: 50)" in out and "(default: lete_sand)" in out


def test_options_that_do_not_apply_are_refused(capsys, sweep_csv, tmp_path):
    bad_input(
        capsys,
        "fit",
        sweep_csv,
        "--vehicle",
        "light",
        "--method",
        "newton",
        "--engine",
        "compiled",
        says=["--engine compiled applies to --method ipopt"],
    )
    log = str(tmp_path / "log.csv")
    assert main(["simulate", "--vehicle", "light", "--duration", "3", "--seed", "1", "-o", log]) == 0
    capsys.readouterr()
    bad_input(capsys, "fit", log, "--vehicle", "light", "--sigma", "2", says=["--sigma applies to slip data only"])


# --- items 3, 8, 11: figures that show what the fit used and say when it failed ------------------------
@pytest.fixture()
def captured(monkeypatch):
    """Capture the figure ``plot_fit`` would save (checked for content, then closed)."""
    from soiltrack import plots

    figs = []

    def keep(fig, path):
        figs.append(fig)
        return path

    monkeypatch.setattr(plots, "save_figure", keep)
    yield figs
    import matplotlib.pyplot as plt

    for f in figs:
        plt.close(f)


def test_failed_fit_figure_says_failed(captured, sweep_csv):
    from soiltrack.plots import plot_fit
    from soiltrack.soilmodel import read_csv

    data = read_csv(sweep_csv)
    res = fit(data, LIGHT, method="newton")
    assert not res.success
    plot_fit(data, LIGHT, res, "f.png")
    ax, axr = captured[0].axes[:2]
    labels = [ln.get_label() for ln in ax.get_lines()]
    assert "FAILED" in ax.get_title() and not any("fitted" in lab for lab in labels)
    assert "last iterate of the FAILED fit" in labels
    assert "(N)" in axr.get_ylabel() and "%" not in axr.get_ylabel()  # absolute residuals, unit by magnitude


@pytest.mark.slow
def test_drive_log_figure_shows_the_samples_that_fix_fmax(captured):
    from soiltrack.identify.drivelog.fit import prepare_drive_log
    from soiltrack.plots import plot_fit

    log = simulate(LIGHT, TERRAINS["dry_sand"], seed=1)  # default profile: two hard pulls
    res = fit(log, LIGHT)
    plot_fit(log, LIGHT, res, "d.png")
    ax = captured[0].axes[0]
    prep = prepare_drive_log(log, LIGHT)
    strong = prep.slip_measured[prep.thrust > 0.5 * prep.thrust.max()]
    lo, hi = ax.get_xlim()
    assert strong.size >= 5 and np.all((strong >= lo) & (strong <= hi))  # issue: 14 of 16 were cut off
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any("95 % band" in t for t in texts) and any("thrust bin" in t for t in texts), texts
    assert any(f"{prep.n_used} samples used" in t for t in texts)


# --- item 1: wrong data are not a success --------------------------------------------------------------
def _fit_json(capsys, tmp_path, rows, name):
    p = tmp_path / f"{name}.csv"
    p.write_text("slip,tractive_force_N\n" + "".join(f"{i!r},{F!r}\n" for i, F in rows))
    rc = main(["fit", str(p), "--vehicle", "light", "--json"])
    return rc, json.loads(capsys.readouterr().out)


@pytest.fixture(scope="module")
def clean_rows(sweep_csv):
    from soiltrack.soilmodel import read_csv

    d = read_csv(sweep_csv)
    return list(zip(d.slip.tolist(), d.tractive_force.tolist()))


def test_clean_sweep_is_a_success_without_plausibility_findings(capsys, tmp_path, clean_rows):
    rc, js = _fit_json(capsys, tmp_path, clean_rows, "clean")
    assert rc == 0 and js["success"]
    assert not any("NOT USABLE" in w or "outlier" in w or "negative" in w for w in js["warnings"])


def test_forces_in_kn_under_an_n_header_are_not_a_success(capsys, tmp_path, clean_rows):
    rc, js = _fit_json(capsys, tmp_path, [(i, F / 1e3) for i, F in clean_rows], "kn")
    assert rc == 1 and js["success"] is False
    text = " ".join(js["warnings"])
    assert "kN in an N column" in text and "F_max" in text and "smallest value the bounds allow" in text


def test_negative_thrust_and_gross_outlier_are_named_by_row(capsys, tmp_path, clean_rows):
    rows = list(clean_rows)
    rows[3] = (rows[3][0], -5.0)
    rc, js = _fit_json(capsys, tmp_path, rows, "neg")
    assert rc == 1 and js["success"] is False
    text = " ".join(js["warnings"])
    assert "row(s) 4: negative tractive force" in text and "row(s) 4 lie far off the rest" in text
    rows = list(clean_rows)
    rows[4] = (rows[4][0], 1e12)
    rc, js = _fit_json(capsys, tmp_path, rows, "big")
    assert rc == 1 and js["success"] is False
    text = " ".join(js["warnings"])
    assert "row(s) 5: the tractive force" in text and "strongest soil within the bounds" in text


def test_limit_just_beyond_a_bound_is_a_warning_not_a_failure():
    """Wong's data, cohesion-free: phi wants slightly more than the seed's 40 deg bound - usable, said."""
    from soiltrack.soilmodel import read_csv

    wong = read_csv(os.path.join(ROOT, "examples", "data", "wong2001_p176.csv"))
    res = fit(wong, VEHICLES["heavy"], model="cohesion-free")
    assert res.success
    w = " ".join(res.warnings)
    assert "largest value the bounds allow" in w and "widen them" in w and "NOT USABLE" not in w


def test_plausibility_unit_checks():
    from soiltrack.identify.sweep.plausibility import check_slip_data
    from soiltrack.soilmodel import PRACTICAL_BOUNDS

    slip = np.linspace(0.02, 0.5, 10)
    F = tractive_force(slip, TERRAINS["dry_sand"], LIGHT)
    load = np.full(10, LIGHT.weight)
    assert check_slip_data(slip, F, load, LIGHT, "full", PRACTICAL_BOUNDS) == []
    codes = [f.code for f in check_slip_data(slip, F / 1e3, load, LIGHT, "full", PRACTICAL_BOUNDS)]
    assert codes == ["force_scale_low"]


# --- items 5, 7, 10: the report and the JSON say each thing once, in units a person reads -------------
def test_relative_sigma_leaves_a_trace(capsys, sweep_csv):
    main(["fit", sweep_csv, "--vehicle", "light", "--sigma", "relative", "--json"])
    assert json.loads(capsys.readouterr().out)["sigma_model"] == "relative"
    main(["fit", sweep_csv, "--vehicle", "light", "--sigma", "relative"])
    out = capsys.readouterr().out
    assert "noise: proportional to the force" in out and "estimated from the residuals at about" in out
    main(["fit", sweep_csv, "--vehicle", "light", "--sigma", "2"])
    assert "sigma given per sample and taken as known" in capsys.readouterr().out


def test_one_k_interval_cut_at_the_bound_and_said(capsys):
    wong = os.path.join(ROOT, "examples", "data", "wong2001_p176.csv")
    main(["fit", wong, "--vehicle", os.path.join(ROOT, "examples", "data", "heavy_vehicle.json"), "--json"])
    js = json.loads(capsys.readouterr().out)
    pk = js["parameters"]["shear_modulus_m"]
    ck = next(c for c in js["combinations"] if c["name"] == "K")
    assert pk["ci95"] == ck["ci95"] and ck["ci95"][0] >= 0.006  # was [-0.0065, ...] beside [0.006, ...]
    assert "lower end of the 95 % interval is cut at the bound 0.006 m" in ck["note"]
    assert "lower end of the 95 % interval is cut at the bound 0.006 m" in pk["note"]
    for c in js["combinations"]:
        assert c["ci95"][0] is None or c["ci95"][0] >= 0  # no negative K, K/l or slope


def test_report_units_by_magnitude_and_each_thing_once(capsys, sweep_csv):
    main(["fit", sweep_csv, "--vehicle", "light"])
    out = capsys.readouterr().out
    assert " kN" not in out.replace("kN/slip", "")  # 300 N vehicle: forces in N (was "RMSE 0.003376 kN")
    assert "RMSE " in out and out.split("RMSE ")[1].split(",")[0].endswith(" N")
    assert "F_max@W=" not in out and "F_max at W = 300 N" in out
    assert out.count("c and phi are not separable") == 1
    assert "scaled singular values" in out and "relative to the strongest" in out
    assert "null direction" not in out and "leaves the fitted curve unchanged" in out


# --- item 11: smaller ones ----------------------------------------------------------------------------
def test_quick_paper_run_does_not_overwrite_the_full_report():
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "reproduce_paper", os.path.join(ROOT, "examples", "reproduce_paper.py")
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.default_out(True) != mod.default_out(False)


def test_fit_many_progress_in_a_log_has_no_carriage_returns(capsys):
    from soiltrack.identify import fit_many

    ds = [simulate(LIGHT, TERRAINS["dry_sand"], kind="sweep", seed=s) for s in range(8)]
    fit_many(ds, LIGHT, progress=True, chunk_size=2)
    err = capsys.readouterr().err
    assert "\r" not in err and err.count("\n") >= 2 and "8/8 fits" in err


def test_fit_many_runs_the_same_plausibility_checks_as_fit(clean_rows):
    """fit and fit_many agree on success: the vectorised batch engine ran no plausibility checks."""
    from soiltrack.identify import fit, fit_many
    from soiltrack.soilmodel import VEHICLES, SlipData

    light = VEHICLES["light"]
    i = np.array([r[0] for r in clean_rows])
    F = np.array([r[1] for r in clean_rows])
    kn = SlipData(slip=i, tractive_force=F / 1e3)
    neg = SlipData(slip=i, tractive_force=np.where(np.arange(F.size) == 3, -5.0, F))
    sets = [SlipData(slip=i, tractive_force=F), kn, neg] * 4  # 12 same-size sets: the vectorised engine
    many = fit_many(sets, light, engine="vectorized")
    for d, r in zip(sets, many):
        one = fit(d, light)
        assert r.success == one.success and r.status == one.status, (r.status, one.status)
        assert [w for w in r.warnings if "NOT USABLE" in w] == [w for w in one.warnings if "NOT USABLE" in w]
    assert [r.success for r in many[:3]] == [True, False, False]
