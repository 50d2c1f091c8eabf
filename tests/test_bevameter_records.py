"""Bevameter tests as recorded: a shear annulus's torque against rotation, plates by radius and force."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from soiltrack.cli import main
from soiltrack.identify.soiltests import fit_soil_test
from soiltrack.soilmodel import DataError, PlateTest
from soiltrack.soilmodel.bevameter import annulus_torque
from soiltrack.soilmodel.bevameter_records import AnnulusTest, read_bevameter_record

RI, RO = 0.15, 0.20  # the ring of a published virtual bevameter (m)
C, PHI, K = 2.5e3, math.radians(24.0), 0.012


def _write(path, cols: dict) -> str:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(list(cols))
        for row in zip(*cols.values()):
            w.writerow([repr(float(v)) for v in row])
    return str(path)


def _torque_closed_form(theta, sigma, c, phi, K, ri, ro):
    """2 pi (c + sigma tan phi) int r^2 (1 - exp(-r theta / K)) dr, by the antiderivative."""
    a = theta / K

    def F(r):
        return r**3 / 3 + np.exp(-a * r) * (r**2 / a + 2 * r / a**2 + 2 / a**3)

    return 2 * math.pi * (c + sigma * math.tan(phi)) * (F(ro) - F(ri))


def test_annulus_quadrature_against_the_closed_form_and_a_dense_rule():
    theta = np.array([0.01, 0.05, 0.2, 1.0, 3.0, 6.0])  # theta r_o / K from 0.17 to 100
    T = annulus_torque(theta, 20e3, C, PHI, K, RI, RO)
    exact = _torque_closed_form(theta, 20e3, C, PHI, K, RI, RO)
    assert np.max(np.abs(T / exact - 1)) < 1e-11
    # small rotations (the closed form cancels there): a dense trapezoid rule
    r = np.linspace(RI, RO, 200001)
    for th in (1e-5, 1e-3):
        y = r**2 * (C + 20e3 * math.tan(PHI)) * -np.expm1(-r * th / K)
        dense = 2 * math.pi * float(np.sum((y[1:] + y[:-1]) * np.diff(r)) / 2)
        assert annulus_torque(th, 20e3, C, PHI, K, RI, RO) == pytest.approx(dense, rel=1e-8)


def _annulus_rows(rng, sd_T=0.5):
    loads = np.repeat([300.0, 600.0, 900.0], 16)  # N on the ring
    area = math.pi * (RO**2 - RI**2)
    deg = np.tile(np.concatenate([np.linspace(0.5, 15, 12), [25, 35, 45, 60]]), 3)  # steady-state rows at the end
    T = _torque_closed_form(np.radians(deg), loads / area, C, PHI, K, RI, RO)
    return loads, deg, T + rng.normal(0, sd_T, T.size)


def test_annulus_record_read_with_options_and_fitted(tmp_path, capsys):
    rng = np.random.default_rng(1)
    loads, deg, T = _annulus_rows(rng)
    path = _write(tmp_path / "ring.csv", {"normal_load_kN": loads / 1e3, "rotation_deg": deg, "torque_Nm": T})
    rec = read_bevameter_record(path, inner_radius_m=RI, outer_radius_m=RO)
    assert isinstance(rec, AnnulusTest)
    np.testing.assert_allclose(rec.normal_pressure, loads / (math.pi * (RO**2 - RI**2)), rtol=1e-12)
    rc = main(["fit", path, "--inner-radius-m", str(RI), "--outer-radius-m", str(RO), "--json"])
    js = json.loads(capsys.readouterr().out)
    assert rc == 0 and js["kind"] == "shear_test"
    assert any("normal_load_kN read as normal_load_N" in n for n in js["columns_read"])
    p = js["parameters"]
    for key, true in (("cohesion_kpa", C / 1e3), ("friction_angle_deg", math.degrees(PHI)), ("shear_modulus_m", K)):
        lo, hi = p[key]["ci95"]
        assert lo <= true <= hi, (key, p[key])
        assert abs(p[key]["value"] / true - 1) < 0.10
    assert any("integrated across the ring" in n for n in js["notes"])
    assert js["covariance"]["parameters"] == ["cohesion", "friction_angle", "shear_modulus"]


def test_annulus_missing_radius_is_refused(tmp_path, capsys):
    rng = np.random.default_rng(2)
    loads, deg, T = _annulus_rows(rng)
    path = _write(tmp_path / "ring.csv", {"normal_load_N": loads, "rotation_deg": deg, "torque_Nm": T})
    rc = main(["fit", path, "--inner-radius-m", str(RI)])
    err = capsys.readouterr().err
    assert rc == 2 and "outer_radius_m" in err and "--outer-radius-m" in err and "Traceback" not in err
    both = _write(
        tmp_path / "both.csv",
        {"normal_load_N": loads, "normal_pressure_Pa": loads, "rotation_deg": deg, "torque_Nm": T},
    )
    with pytest.raises(DataError, match="exactly one of"):
        read_bevameter_record(both, inner_radius_m=RI, outer_radius_m=RO)


@pytest.mark.slow
def test_annulus_intervals_cover_at_close_to_the_nominal_rate():
    rng = np.random.default_rng(7)
    hits = np.zeros(3)
    n = 60
    for _ in range(n):
        loads, deg, T = _annulus_rows(rng)
        area = math.pi * (RO**2 - RI**2)
        test = AnnulusTest(loads / area, np.radians(deg), T, np.full(T.size, RI), np.full(T.size, RO))
        fit = fit_soil_test(test)
        for k, (key, true) in enumerate(
            (("cohesion_kpa", C / 1e3), ("friction_angle_deg", math.degrees(PHI)), ("shear_modulus_m", K))
        ):
            lo, hi = fit.parameters[key].edge_ci95  # the truths in kPa, deg, m
            hits[k] += lo <= true <= hi
    rate = hits / n
    assert np.all(rate >= 0.85), rate  # 95 % nominal; 60 replicates: a binomial 2.5 % quantile near 0.88


def test_circular_plates_by_radius_and_force_recovered(tmp_path, capsys):
    rng = np.random.default_rng(4)
    kc, kphi, n = 20e3, 900e3, 1.05
    r = np.repeat([0.2, 0.3], 12)
    z = np.tile(np.linspace(0.005, 0.06, 12), 2)
    F = math.pi * r**2 * (kc / r + kphi) * z**n * np.exp(rng.normal(0, 0.01, z.size))
    path = _write(tmp_path / "plates.csv", {"plate_radius_m": r, "force_N": F, "sinkage_mm": 1e3 * z})
    rec = read_bevameter_record(path)
    assert isinstance(rec, PlateTest)
    np.testing.assert_allclose(rec.plate_width, r)
    np.testing.assert_allclose(rec.pressure, F / (math.pi * r**2))
    rc = main(["fit", path, "--json"])
    js = json.loads(capsys.readouterr().out)
    assert rc == 0
    for key, true in (("bekker_kc", kc / 1e3), ("bekker_kphi", kphi / 1e3), ("bekker_n", n)):
        lo, hi = js["parameters"][key]["ci95"]
        assert lo <= true <= hi, (key, js["parameters"][key])


def test_rectangular_plate_needs_its_length_for_a_force(tmp_path):
    z = np.linspace(0.005, 0.05, 6)
    path = _write(tmp_path / "p.csv", {"plate_width_m": np.full(6, 0.1), "force_N": 1e4 * z, "sinkage_m": z})
    with pytest.raises(DataError, match="plate_length_m"):
        read_bevameter_record(path)
    path = _write(
        tmp_path / "q.csv",
        {"plate_width_m": np.full(6, 0.1), "plate_length_m": np.full(6, 0.5), "force_N": 1e4 * z, "sinkage_m": z},
    )
    rec = read_bevameter_record(path)
    np.testing.assert_allclose(rec.pressure, 1e4 * z / 0.05)
    np.testing.assert_allclose(rec.plate_width, 0.1)


def _negative_kc_plates(tmp_path):
    rng = np.random.default_rng(5)
    kc, kphi, n = -30e3, 1200e3, 1.0
    b = np.repeat([0.2, 0.3], 12)
    z = np.tile(np.linspace(0.005, 0.06, 12), 2)
    p = (kc / b + kphi) * z**n * np.exp(rng.normal(0, 0.01, z.size))
    return _write(tmp_path / "plates.csv", {"plate_width_m": b, "pressure_Pa": p, "sinkage_m": z})


def test_negative_kc_held_at_0_with_the_unconstrained_value(tmp_path, capsys):
    path = _negative_kc_plates(tmp_path)
    assert main(["fit", path, "--json"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert js["parameters"]["bekker_kc"]["value"] == 0.0 and js["parameters"]["bekker_kc"]["at_bound"]
    note = next(n for n in js["notes"] if n.startswith("k_c is held at its bound 0"))
    assert "unconstrained fit gives k_c = -" in note and "negative_kc" in note
    lo, hi = (float(v) for v in note.split("95 % [")[1].split("]")[0].split(", "))
    assert lo <= -30.0 <= hi and hi < 0  # the unconstrained interval holds the truth
    assert main(["fit", path, "--json", "--negative-kc"]) == 0
    js = json.loads(capsys.readouterr().out)
    lo, hi = js["parameters"]["bekker_kc"]["ci95"]
    assert lo <= -30.0 <= hi and hi < 0
    assert any("the data say so" in n for n in js["notes"])


def test_negative_kc_refused_elsewhere(capsys):
    import os

    wong = os.path.join(
        os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "examples", "data", "wong2001_p176.csv"
    )
    assert main(["fit", wong, "--vehicle", "heavy", "--negative-kc"]) == 2
    assert "plate tests only" in capsys.readouterr().err
