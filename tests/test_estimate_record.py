"""The one record (identify.estimates.estimate.Estimate) and the one combination rule, on the kinds folded onto it."""

import dataclasses
import json
import math

import numpy as np
import pytest

from conftest import bench_module
from soiltrack.identify.estimates.estimate import Estimate, estimate_dict, estimate_json, estimate_report
from soiltrack.identify.estimates.records import Combination, combination_determined
from soiltrack.identify.soiltests import fit_plate_test, fit_shear_test
from soiltrack.soilmodel import plate_pressure, read_csv, shear_stress

BEV = bench_module("bevameter_to_track")
SOIL = BEV.SANDY_LOAM

#: Keys every fit JSON on the record carries (one layout).
LAYOUT = {
    "kind", "source", "method", "status", "success", "outcome", "outcome_reason", "running_gear", "converged",
    "iterations", "n_samples", "rows_dropped", "solve_time_s", "levels", "parameters", "combinations",
    "identifiable", "active_bounds", "determined", "dof", "lack_of_fit", "notes", "covariance", "residuals",
}  # fmt: skip


def _fit(tmp_path, kind, seed=2, **kw):
    p = tmp_path / f"{kind}{seed}.csv"
    (BEV.shear_csv if kind == "shear" else BEV.plate_csv)(str(p), SOIL, seed, **kw)
    test = read_csv(str(p))
    return test, (fit_shear_test if kind == "shear" else fit_plate_test)(test)


def test_a_shear_and_a_plate_fit_are_one_record_with_one_layout(tmp_path):
    _, s = _fit(tmp_path, "shear")
    _, p = _fit(tmp_path, "plate", widths=(0.1,))
    assert type(s) is Estimate and type(p) is Estimate
    for r in (s, p):
        d = estimate_dict(r)
        assert LAYOUT <= set(d) and d == r.to_dict()
        assert json.loads(estimate_json(r)) == json.loads(r.to_json())
        assert estimate_report(r) == r.report() and r.report().splitlines()[0] == "outcome: usable"
        assert d["residuals"]["sign"] == "measured - model" and len(d["residuals"]["values"]) == r.n_samples
        assert d["running_gear"]["kind"] == "bevameter"
    assert estimate_dict(s)["covariance"]["parameters"] == ["cohesion", "friction_angle", "shear_modulus"]
    assert estimate_dict(p)["covariance"] is None  # one width: k_c and k_phi not identified
    (c,) = estimate_dict(p)["combinations"]
    assert c["name"] == "bekker_k_eq" and c["determined"] is True and c["plate_width_m"] == 0.1


def test_the_record_is_frozen(tmp_path):
    _, s = _fit(tmp_path, "shear")
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.kind = "plate_test"  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.solver.converged = False  # type: ignore[misc]


def test_residuals_are_measured_minus_model(tmp_path):
    test, s = _fit(tmp_path, "shear")
    P = s.parameters
    model = shear_stress(
        test.shear_displacement, test.normal_pressure, P["cohesion_kpa"].value, P["friction_angle_deg"].value,
        P["shear_modulus_m"].value,
    )  # fmt: skip
    np.testing.assert_allclose(s.residuals[0].values, (test.shear_stress - model) / 1e3, rtol=0, atol=1e-9)
    assert math.isclose(s.rmse(), float(np.sqrt(np.mean(((test.shear_stress - model) / 1e3) ** 2))), rel_tol=1e-9)
    test, p = _fit(tmp_path, "plate")
    P = p.parameters
    model = plate_pressure(test.sinkage, test.plate_width, P["bekker_kc"].value, P["bekker_kphi"].value,
                           P["bekker_n"].value)  # fmt: skip
    np.testing.assert_allclose(p.residuals[0].values, (test.pressure - model) / 1e3, rtol=0, atol=1e-9)


def test_one_rule_decides_whether_a_combination_is_determined():
    base = Combination("k", 10.0, 1.0, (8.0, 12.0), "kPa", "a combination")
    assert combination_determined(base) == (True, "")
    assert not combination_determined(dataclasses.replace(base, estimable=False))[0]
    assert not combination_determined(dataclasses.replace(base, stderr=None))[0]
    pinned = dataclasses.replace(base, ci95=(10.0, 12.0), note="the lower end of the 95 % interval is cut")
    assert combination_determined(pinned) == (False, "pinned at a bound")
    on = dataclasses.replace(base, terms_on_bounds=("a", "b"), all_terms_on_bounds=True)
    assert combination_determined(on) == (False, "its terms are on their bounds (a, b)")
    assert combination_determined(dataclasses.replace(base, range=(0.0, 100.0)))[0]  # 4 of 100: narrow
    wide, why = combination_determined(dataclasses.replace(base, range=(8.0, 13.0)))  # 4 of 5: most of it
    assert not wide and why
    assert dataclasses.replace(base, terms_on_bounds=("a",)).determined == (True, "")


def test_a_combination_the_data_do_not_determine_prints_no_number(tmp_path):
    _, p = _fit(tmp_path, "plate", widths=(0.1,))
    c = p.combinations["bekker_k_eq"]
    bad = dataclasses.replace(p, combinations={"bekker_k_eq": dataclasses.replace(c, stderr=None, ci95=(None, None))})
    line = [x for x in bad.report().splitlines() if "k_c / b + k_phi (plate_width_m" in x]
    assert line and "NOT DETERMINED" in line[0] and f"{c.value:.4g}" not in line[0]
    assert "bekker_k_eq" not in bad.determined and "bekker_k_eq" in p.determined
