"""Bevameter soil tests: files simulated by plain numpy (benchmarks/bevameter_to_track.py), fitted."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT, bench_module
from soiltrack.cli import main
from soiltrack.identify.soiltests import fit_plate_test, fit_shear_test, fit_soil_test, predict_drawbar_pull
from soiltrack.soilmodel import VEHICLES, DataError, PlateTest, ShearTest, read_csv

BEV = bench_module("bevameter_to_track")
SOIL = BEV.SANDY_LOAM
REPS = 40
#: Of REPS replicates at a 95 % level, fewer than this many hits has probability < 0.5 % (binomial).
MIN_HITS = 33


def _shear(tmp_path, seed, soil=SOIL, **kw):
    p = tmp_path / f"shear{seed}.csv"
    BEV.shear_csv(str(p), soil, seed, **kw)
    return read_csv(str(p))


def _plate(tmp_path, seed, soil=SOIL, **kw):
    p = tmp_path / f"plate{seed}.csv"
    BEV.plate_csv(str(p), soil, seed, **kw)
    return read_csv(str(p))


def test_files_are_recognised_by_their_columns(tmp_path):
    assert isinstance(_shear(tmp_path, 0), ShearTest)
    assert isinstance(_plate(tmp_path, 0), PlateTest)


def test_shear_test_recovers_c_phi_K_within_intervals(tmp_path):
    truth = {
        "cohesion_kpa": SOIL["c"] / 1e3,
        "friction_angle_deg": math.degrees(SOIL["phi"]),
        "shear_modulus_m": SOIL["K"],
    }
    hits = dict.fromkeys(truth, 0)
    for seed in range(REPS):
        r = fit_shear_test(_shear(tmp_path, seed))
        assert r.success and r.converged and r.identifiable == list(truth)
        for k, v in truth.items():
            lo, hi = r.parameters[k].edge_ci95
            hits[k] += lo <= v <= hi
    assert min(hits.values()) >= MIN_HITS, hits


def test_plate_test_recovers_kc_kphi_n_within_intervals(tmp_path):
    truth = {"bekker_kc": SOIL["k_c"] / 1e3, "bekker_kphi": SOIL["k_phi"] / 1e3, "bekker_n": SOIL["n"]}
    hits = dict.fromkeys(truth, 0)
    for seed in range(REPS):
        r = fit_plate_test(_plate(tmp_path, seed))
        assert r.success and r.identifiable == list(truth)
        for k, v in truth.items():
            lo, hi = r.parameters[k].edge_ci95
            hits[k] += lo <= v <= hi
    assert min(hits.values()) >= MIN_HITS, hits


def test_one_plate_width_identifies_only_the_combination(tmp_path):
    b = 0.1
    r = fit_plate_test(_plate(tmp_path, 3, widths=(b,)))
    assert r.success
    assert not r.parameters["bekker_kc"].identifiable and r.parameters["bekker_kc"].value is None
    assert not r.parameters["bekker_kphi"].identifiable and r.parameters["bekker_kphi"].value is None
    assert r.parameters["bekker_n"].identifiable
    k_eq = r.combinations["bekker_k_eq"]
    lo, hi = k_eq.ci95
    assert lo <= (SOIL["k_c"] / b + SOIL["k_phi"]) / 1e3 <= hi
    assert k_eq.at == {"plate_width_m": b}


def test_one_normal_pressure_identifies_only_the_shear_strength(tmp_path):
    s = 20e3
    r = fit_shear_test(_shear(tmp_path, 4, pressures=(s,)))
    assert r.success
    assert [k for k, p in r.parameters.items() if not p.identifiable] == ["cohesion_kpa", "friction_angle_deg"]
    assert r.parameters["cohesion_kpa"].value is None and r.parameters["friction_angle_deg"].ci95 == (None, None)
    lo, hi = r.combinations["shear_strength_kpa"].ci95
    assert lo <= (SOIL["c"] + s * math.tan(SOIL["phi"])) / 1e3 <= hi
    lo, hi = r.parameters["shear_modulus_m"].ci95
    assert lo <= SOIL["K"] <= hi


@pytest.mark.parametrize("seed, on_bound", [(5, True), (0, False)])
def test_a_cohesionless_soil_ends_on_the_cohesion_bound_and_says_so(tmp_path, seed, on_bound):
    r = fit_shear_test(_shear(tmp_path, seed, soil=dict(SOIL, c=0.0)))
    c = r.parameters["cohesion_kpa"]
    assert c.at_bound is on_bound and (r.active_bounds == ["cohesion_kpa"]) is on_bound
    assert (c.value == 0.0) is on_bound and c.value >= 0.0
    assert c.ci95[0] == 0.0 and c.ci95[1] > 0.0


@pytest.mark.slow
def test_prediction_of_a_track_drawbar_pull_covers_the_truth(tmp_path):
    slips = np.array([0.05, 0.3])
    vehicle = VEHICLES["light"]
    truth = BEV.true_drawbar_pull(SOIL, slips, vehicle.weight, vehicle.track_length, vehicle.track_width)
    hits = np.zeros(slips.size)
    for seed in range(REPS):
        pr = predict_drawbar_pull(
            fit_shear_test(_shear(tmp_path, seed)), fit_plate_test(_plate(tmp_path, seed)), vehicle, slips
        )
        assert np.all(pr.upper > pr.lower) and np.all(np.isfinite(pr.drawbar_pull))
        hits += (pr.lower <= truth) & (truth <= pr.upper)
    assert hits.min() >= MIN_HITS, hits


def test_prediction_refuses_a_plate_test_of_one_width(tmp_path):
    fs = fit_shear_test(_shear(tmp_path, 1))
    fp = fit_plate_test(_plate(tmp_path, 1, widths=(0.1,)))
    with pytest.raises(DataError) as e:
        predict_drawbar_pull(fs, fp, VEHICLES["light"], [0.1])
    assert e.value.reason.count("bekker_kc") == 1


@pytest.mark.slow
def test_cli_fits_a_bevameter_file_without_vehicle(tmp_path):
    path = tmp_path / "shear.csv"
    BEV.shear_csv(str(path), SOIL, 7)
    p = subprocess.run(
        [sys.executable, "-m", "soiltrack", "fit", str(path), "--json"], capture_output=True, text=True, cwd=ROOT
    )
    assert p.returncode == 0, p.stderr
    js = json.loads(p.stdout)
    assert js["kind"] == "shear_test" and js["success"] is True
    for k in ("cohesion_kpa", "friction_angle_deg", "shear_modulus_m"):
        par = js["parameters"][k]
        assert par["identifiable"] is True and len(par["ci95"]) == 2
        assert par["ci95"][0] <= par["value"] <= par["ci95"][1]
    plate = tmp_path / "plate.csv"
    BEV.plate_csv(str(plate), SOIL, 7, widths=(0.1,))
    p = subprocess.run(
        [sys.executable, "-m", "soiltrack", "fit", str(plate), "--json"], capture_output=True, text=True, cwd=ROOT
    )
    assert p.returncode == 0, p.stderr
    js = json.loads(p.stdout)
    assert [c["name"] for c in js["combinations"]] == ["bekker_k_eq"]
    assert js["combinations"][0]["plate_width_m"] == 0.1
    kc = js["parameters"]["bekker_kc"]
    assert kc["value"] is None and kc["identifiable"] is False


def test_cli_refuses_sweep_options_on_a_bevameter_file_and_a_sweep_without_vehicle(tmp_path, capsys):
    path = tmp_path / "plate.csv"
    BEV.plate_csv(str(path), SOIL, 8)
    assert main(["fit", str(path), "--vehicle", "light"]) == 2
    sweep = tmp_path / "sweep.csv"
    sweep.write_text("slip,tractive_force_N\n0.1,100\n0.2,150\n0.3,170\n0.4,180\n")
    assert main(["fit", str(sweep)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err


def test_bad_bevameter_rows_name_the_column_and_row(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("normal_pressure_Pa,shear_displacement_m,shear_stress_Pa\n1e4,0,0\n-1e4,0.01,500\n")
    with pytest.raises(DataError) as e:
        read_csv(str(path))
    assert (e.value.column, e.value.row) == ("normal_pressure_Pa", 2)


def test_fit_soil_test_dispatches_by_kind(tmp_path):
    assert fit_soil_test(_plate(tmp_path, 2)).kind == "plate_test"
    assert fit_soil_test(_shear(tmp_path, 2)).kind == "shear_test"


def test_shear_tests_without_displacement_or_with_negative_stress_are_refused():
    sig = [1e4] * 5 + [2e4] * 5
    with pytest.raises(DataError) as e:
        fit_shear_test(ShearTest(sig, [0.0] * 10, [1.0] * 10))
    assert e.value.column == "shear_displacement_m"
    with pytest.raises(DataError) as e:
        fit_shear_test(ShearTest(sig, np.tile(np.linspace(0.01, 0.1, 5), 2), [-5e3] * 10))
    assert e.value.column == "shear_stress_Pa"
