"""``soiltrack predict``: values and 95 % bounds against independent computations (plain numpy)."""

from __future__ import annotations

import csv
import json
import math
import os

import numpy as np
import pytest

import wheel_oracle as oracle
from soiltrack.cli import main
from soiltrack.planning.prediction import SoilEstimate, predict
from soiltrack.soilmodel import TERRAINS, VEHICLES
from soiltrack.soilmodel.rigid_wheel import RigidWheel

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
WONG = os.path.join(ROOT, "examples", "data", "wong2001_p176.csv")
WHEEL = {"running_gear": "rigid_wheel", "wheel_radius_m": 0.1, "wheel_width_m": 0.08, "grouser_height_m": 0.0}


@pytest.fixture()
def wheel_json(tmp_path):
    p = tmp_path / "wheel.json"
    p.write_text(json.dumps(WHEEL))
    return str(p)


def _run(capsys, *args):
    rc = main(["predict", *args])
    out = capsys.readouterr()
    return rc, out.out, out.err


def _write(path, cols: dict) -> str:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(list(cols))
        for row in zip(*cols.values()):
            w.writerow([repr(float(v)) for v in row])
    return str(path)


def _track_closed_form(i, c, phi, K, W, l, b, mu, r, kc=None, kphi=None, n=None):
    """Eq. 2 and Bekker's static sinkage and compaction, written out in numpy."""
    A = 2 * b * l
    with np.errstate(divide="ignore", invalid="ignore"):
        F = (A * c + W * math.tan(phi)) * (1 - K / (i * l) * (1 - np.exp(-i * l / K)))
    F = np.where(i == 0, 0.0, F)
    if kc is None:
        return F - mu * W, F, r * F, None
    k = kc / b + kphi
    z0 = (W / A / k) ** (1 / n)
    R = 2 * b * k * z0 ** (n + 1) / (n + 1)
    return F - mu * W - R, F, r * F, np.full(i.shape, z0)


def test_track_on_a_terrain_matches_the_closed_form(capsys):
    rc, out, _ = _run(capsys, "--vehicle", "heavy", "--terrain", "lete_sand", "--slip", "0:0.5:0.05", "--json")
    assert rc == 0
    js = json.loads(out)
    i = np.array(js["slip"])
    assert i.size == 11 and i[-1] == pytest.approx(0.5)
    v, s = VEHICLES["heavy"], TERRAINS["lete_sand"]
    dp, F, T, z = _track_closed_form(
        i,
        s.cohesion,
        s.friction_angle,
        s.shear_modulus,
        v.weight,
        v.track_length,
        v.track_width,
        v.rolling_resistance,
        v.sprocket_radius,
        s.k_c,
        s.k_phi,
        s.n,
    )
    np.testing.assert_allclose(js["thrust_N"], F, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(js["drawbar_pull_N"], dp, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(js["torque_Nm"], T, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(js["sinkage_m"], z, rtol=1e-9)
    assert js["thrust_N_lo"] is None and js["uncertainty"] is None


def test_wheel_on_given_soil_matches_the_oracle(capsys, wheel_json):
    c, phi, K, kc, kphi, n = 1.3, 31.1, 0.012, 102.0, 5301.0, 0.79  # LETE sand (kPa, deg, m, kN/m^(n+1), kN/m^(n+2))
    rc, out, _ = _run(
        capsys,
        "--vehicle",
        wheel_json,
        "--soil",
        f"{c},{phi},{K},{kc},{kphi},{n}",
        "--load",
        "60",
        "--slip",
        "0.1:0.7:0.3",
        "--json",
    )
    assert rc == 0
    js = json.loads(out)
    k = kc * 1e3 / WHEEL["wheel_width_m"] + kphi * 1e3
    r, b = WHEEL["wheel_radius_m"], WHEEL["wheel_width_m"]
    for j, i in enumerate(js["slip"]):
        z = oracle.sinkage(i, 60.0, c * 1e3, math.radians(phi), K, k, n, r, b)
        dp, _, T = oracle.forces(i, z, c * 1e3, math.radians(phi), K, k, n, r, b)
        dp0, _, _ = oracle.forces(i, z, 0.0, 0.0, K, k, n, r, b)  # no shear: the compaction alone
        assert js["sinkage_m"][j] == pytest.approx(z, rel=2e-3)
        assert js["drawbar_pull_N"][j] == pytest.approx(dp, rel=5e-3, abs=5e-3)
        assert js["thrust_N"][j] == pytest.approx(dp - dp0, rel=5e-3)
        assert js["torque_Nm"][j] == pytest.approx(T, rel=5e-3)
    assert js["drawbar_pull_N_lo"] is None


def _bevameter_files(tmp_path, c, phi, K, kc, kphi, n, seed=3):
    """A shear test at three pressures and plates of two widths, written from the laws in numpy with noise."""
    rng = np.random.default_rng(seed)
    sig = np.repeat([10e3, 20e3, 30e3], 15)
    j = np.tile(np.linspace(0.001, 0.06, 15), 3)
    tau = (c + sig * math.tan(phi)) * (1 - np.exp(-j / K))
    tau = tau + rng.normal(0, 150.0, tau.size)
    shear = _write(
        tmp_path / "shear.csv", {"normal_pressure_Pa": sig, "shear_displacement_m": j, "shear_stress_Pa": tau}
    )
    bw = np.repeat([0.05, 0.1], 12)
    z = np.tile(np.linspace(0.004, 0.05, 12), 2)
    p = (kc / bw + kphi) * z**n * np.exp(rng.normal(0, 0.02, z.size))
    plate = _write(tmp_path / "plate.csv", {"plate_width_m": bw, "pressure_Pa": p, "sinkage_m": z})
    return shear, plate


def _fit_json(capsys, path, out):
    rc = main(["fit", path, "--json"])
    text = capsys.readouterr().out
    assert rc == 0
    with open(out, "w") as fh:
        fh.write(text)
    return json.loads(text)


def test_wheel_from_bevameter_fits_bounds_match_an_independent_delta_method(tmp_path, capsys, wheel_json):
    shear, plate = _bevameter_files(tmp_path, 2.0e3, math.radians(30.0), 0.015, 50e3, 2000e3, 0.9)
    js_s = _fit_json(capsys, shear, tmp_path / "shear.json")
    js_p = _fit_json(capsys, plate, tmp_path / "plate.json")
    assert js_s["covariance"]["parameters"] == ["cohesion", "friction_angle", "shear_modulus"]
    rc, out, _ = _run(
        capsys,
        "--vehicle",
        wheel_json,
        "--fit",
        str(tmp_path / "shear.json"),
        "--fit",
        str(tmp_path / "plate.json"),
        "--load",
        "80",
        "--slip",
        "0.2:0.6:0.4",
        "--json",
    )
    assert rc == 0
    js = json.loads(out)
    q = np.array(js_s["covariance"]["values"] + js_p["covariance"]["values"])
    C = np.zeros((6, 6))
    C[:3, :3] = js_s["covariance"]["matrix"]
    C[3:, 3:] = js_p["covariance"]["matrix"]
    r, b = WHEEL["wheel_radius_m"], WHEEL["wheel_width_m"]

    def outputs(i, p):
        c, phi, K, kc, kphi, n = p
        k = kc / b + kphi
        z = oracle.sinkage(i, 80.0, c, phi, K, k, n, r, b)
        dp, _, T = oracle.forces(i, z, c, phi, K, k, n, r, b)
        return np.array([dp, T, z])

    for j, i in enumerate(js["slip"]):
        y0 = outputs(i, q)
        G = np.empty((3, 6))
        for m in range(6):
            h = 1e-4 * abs(q[m])
            e = np.zeros(6)
            e[m] = h
            G[:, m] = (outputs(i, q + e) - outputs(i, q - e)) / (2 * h)
        sd = np.sqrt(np.einsum("oi,ij,oj->o", G, C, G))
        for o, key in enumerate(("drawbar_pull_N", "torque_Nm", "sinkage_m")):
            assert js[key][j] == pytest.approx(y0[o], rel=5e-3, abs=2e-3)
            half = 0.5 * (js[key + "_hi"][j] - js[key + "_lo"][j])
            assert half == pytest.approx(1.959964 * sd[o], rel=0.03)
    assert js["uncertainty"].startswith("delta method")


def test_track_fit_bounds_at_the_fitted_load_are_those_of_fmax_and_K(tmp_path, capsys):
    rc = main(["fit", WONG, "--vehicle", "heavy", "--json"])
    fit = json.loads(capsys.readouterr().out)
    assert rc == 0
    path = tmp_path / "fit.json"
    path.write_text(json.dumps(fit))
    v = VEHICLES["heavy"]
    rc, out, _ = _run(capsys, "--vehicle", "heavy", "--fit", str(path), "--slip", "0.02:0.1:0.04", "--json")
    assert rc == 0
    js = json.loads(out)
    fm = next(c for c in fit["combinations"] if c["name"].startswith("F_max@"))
    kk = next(c for c in fit["combinations"] if c["name"] == "K")
    rho = fit["identifiability"]["fmax_K_correlation"][f"{v.weight:.6g}"]
    Fm, K, sF, sK = fm["value"], kk["value"], fm["stderr"], kk["stderr"]
    C = np.array([[sF**2, rho * sF * sK], [rho * sF * sK, sK**2]])
    i = np.array(js["slip"])
    l = v.track_length
    g = 1 - K / (i * l) * (1 - np.exp(-i * l / K))
    dg = -(1 / (i * l)) * (1 - np.exp(-i * l / K)) + (1 / K) * np.exp(-i * l / K)  # dg/dK
    F = Fm * g
    G = np.stack([g, Fm * dg], axis=1)
    sd = np.sqrt(np.einsum("ni,ij,nj->n", G, C, G))
    np.testing.assert_allclose(js["thrust_N"], F, rtol=1e-6)
    np.testing.assert_allclose(0.5 * (np.array(js["thrust_N_hi"]) - js["thrust_N_lo"]), 1.959964 * sd, rtol=1e-3)
    np.testing.assert_allclose(js["torque_Nm"], v.sprocket_radius * F, rtol=1e-6)
    assert js["sinkage_m"] == [None] * i.size  # no Bekker parameters in a thrust fit


def test_a_prediction_along_a_null_direction_has_no_bounds():
    s = TERRAINS["lete_sand"]
    wheel = RigidWheel(0.1, 0.08)
    mean = np.array([s.cohesion, s.friction_angle, s.shear_modulus, s.k_c, s.k_phi, s.n, 0.0])
    C = np.diag([100.0**2, 0.01**2, 0.001**2, 0.0, 0.0, 0.0, 0.0])
    C[3:5, 3:5] = [[1e8, 0], [0, 1e8]]
    b_fit = 0.05  # fitted at another width: only k_c / 0.05 + k_phi seen
    v = np.zeros(7)
    v[3], v[4] = 1.0, -1.0 / b_fit
    v /= np.linalg.norm(v)
    est = SoilEstimate(mean, np.ones(7, dtype=bool), C, (v,), ("test",))
    p = predict(wheel, est, [0.2, 0.5], 50.0)
    assert np.all(np.isnan(p.lower["sinkage"])) and any("null direction" in n for n in p.notes)
    same = predict(RigidWheel(0.1, b_fit), est, [0.2, 0.5], 50.0)
    assert np.all(np.isfinite(same.lower["sinkage"]))


@pytest.mark.parametrize(
    "args, words",
    [
        (["--terrain", "lete_sand", "--slip", "0:0.5:0.1"], "--load"),
        (["--soil", "1,30,0.01", "--load", "20", "--slip", "0:0.5:0.1"], "k_c, k_phi, n"),
        (["--terrain", "lete_sand", "--load", "20", "--slip=-1.5:0.5:0.1"], "[-1, 1)"),
        (["--terrain", "lete_sand", "--load", "20", "--slip", "0:0.5:0"], "STEP must be > 0"),
        (["--terrain", "lete_sand", "--load", "20", "--slip", "0:0.5"], "A:B:STEP"),
        (["--terrain", "lete_sand", "--soil", "1,30,0.01", "--load", "20", "--slip", "0:0.5:0.1"], "exactly one"),
        (["--terrain", "lete_sand", "--load", "-3", "--slip", "0:0.5:0.1"], "--load"),
    ],
)
def test_bad_input_exits_2(capsys, wheel_json, args, words):
    rc, _, err = _run(capsys, "--vehicle", wheel_json, *args)
    assert rc == 2 and words in err and "Traceback" not in err


def test_a_wheel_that_cannot_carry_the_load_exits_1_with_nulls(capsys, wheel_json):
    rc, out, _ = _run(
        capsys, "--vehicle", wheel_json, "--terrain", "snow", "--load", "5000", "--slip", "0.1:0.3:0.1", "--json"
    )
    js = json.loads(out)
    assert rc == 1 and None in js["drawbar_pull_N"] and any("cannot carry" in n for n in js["notes"])


def test_plot(tmp_path, capsys, wheel_json):
    png = str(tmp_path / "p.png")
    rc, _, err = _run(
        capsys, "--vehicle", wheel_json, "--terrain", "lete_sand", "--load", "40", "--slip", "0:0.9:0.1", "--plot", png
    )
    assert rc == 0 and os.path.getsize(png) > 10_000 and png in err


def test_wheel_skid_prediction_down_to_a_locked_wheel(capsys, wheel_json):
    rc, out, _ = _run(
        capsys, "--vehicle", wheel_json, "--terrain", "lete_sand", "--load", "60", "--slip=-1:0.5:0.5", "--json"
    )
    js = json.loads(out)
    assert rc == 0 and js["slip"] == [-1.0, -0.5, 0.0, 0.5]
    assert js["drawbar_pull_N"][0] < js["drawbar_pull_N"][1] < js["drawbar_pull_N"][2] < js["drawbar_pull_N"][3]
    assert js["torque_Nm"][0] < 0 < js["torque_Nm"][3]


def test_track_skid_is_refused(capsys):
    rc, _, err = _run(capsys, "--vehicle", "light", "--terrain", "lete_sand", "--slip=-0.5:0.5:0.1")
    assert rc == 2 and "for a track" in err


@pytest.mark.slow
def test_a_wheel_fit_json_predicts_the_wheel(tmp_path, capsys, wheel_json):
    """A rigid wheel's `fit --json` (its `running_gear` an object with `kind`) is read as a wheel's fit,
    not refused as a track's, and predicts the simulated wheel's drawbar pull."""
    r, b = WHEEL["wheel_radius_m"], WHEEL["wheel_width_m"]
    soil = (1500.0, math.radians(30.0), 0.012, 1.4e6, 1.0)  # c, phi, K, k_c / b + k_phi, n
    i, dp, W, z = oracle.sweep(
        [0.1, 0.2, 0.3, 0.45, 0.6, 0.8], [60.0, 100.0], *soil, r, b, sd_dp=0.2, sd_z=2e-4, seed=1
    )
    data = _write(tmp_path / "wheel.csv", {"slip": i, "drawbar_pull_N": dp, "normal_load_N": W, "sinkage_m": z})
    assert main(["fit", data, "--vehicle", wheel_json, "--fix", "bekker_kc=0", "--json"]) == 0
    fit = tmp_path / "fit.json"
    fit.write_text(capsys.readouterr().out)
    assert json.loads(fit.read_text())["kind"] == "rigid_wheel"
    rc, out, err = _run(
        capsys, "--vehicle", wheel_json, "--fit", str(fit), "--load", "80", "--slip", "0.3:0.3:0.1", "--json"
    )
    assert rc == 0, err
    js = json.loads(out)
    zt = oracle.sinkage(0.3, 80.0, *soil, r, b)
    truth = oracle.forces(0.3, zt, *soil, r, b)[0]
    assert js["drawbar_pull_N"][0] == pytest.approx(truth, rel=0.1)
    assert js["drawbar_pull_N_lo"][0] < js["drawbar_pull_N"][0] < js["drawbar_pull_N_hi"][0]
