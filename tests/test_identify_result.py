"""FitResult / build_result: statistics, identifiability, JSON contract (no solver involved)."""

import json
import math
import pickle
import re

import numpy as np
import pytest

from soiltrack.identify import FitResult, build_result
from soiltrack.identify.estimates.distributions import norm_ppf, t_ppf
from soiltrack.soilmodel import PRACTICAL_BOUNDS, SEED_ACTUAL, VEHICLES, Soil, tractive_force
from soiltrack.soilmodel.traction import tractive_force_sensitivities

HEAVY = VEHICLES["heavy"]
CONTRACT_KEYS = {
    "model",
    "method",
    "status",
    "success",
    "n_samples",
    "rmse_N",
    "solve_time_s",
    "parameters",
    "combinations",
}
PARAM_KEYS = {"value", "stderr", "ci95", "identifiable", "at_bound"}


def strict_json(text: str) -> dict:
    def bad(c):
        raise AssertionError(f"JSON carries {c}")

    return json.loads(text, parse_constant=bad)


def check_contract(res: FitResult) -> dict:
    d = strict_json(res.to_json())
    assert CONTRACT_KEYS <= set(d)
    assert set(d["parameters"]) == {"cohesion_kpa", "friction_angle_deg", "shear_modulus_m"}
    for p in d["parameters"].values():
        assert PARAM_KEYS <= set(p)
        assert isinstance(p["ci95"], list) and len(p["ci95"]) == 2
        assert isinstance(p["identifiable"], bool) and isinstance(p["at_bound"], bool)
    for cb in d["combinations"]:
        assert {"name", "value", "stderr"} <= set(cb)
    return d


def _result(slip, loads, soil=SEED_ACTUAL, noise=None, model="full", sigma_known=False, **kw):
    slip = np.asarray(slip, float)
    loads = np.broadcast_to(np.asarray(loads, float), slip.shape)
    F = tractive_force(slip, soil, HEAVY, model=model, normal_load=loads)
    data = F + (0 if noise is None else noise)
    r = F - data
    J = tractive_force_sensitivities(slip, soil, HEAVY, model=model, normal_load=loads)
    args = dict(
        data_kind="slip",
        model=model,
        method="ipopt",
        theta=soil.as_vector() * ([1, 1, 1] if model == "full" else [0, 1, 1]),
        jacobian=J,
        weighted_residuals=r,
        residuals=r,
        residual_unit="N",
        n_samples=slip.size,
        normal_loads=loads,
        vehicle=HEAVY,
        bounds=PRACTICAL_BOUNDS,
        status="Solve_Succeeded",
        success=True,
        message="test",
        iterations=1,
        solve_time=0.0,
        sigma_known=sigma_known,
    )
    args.update(kw)
    return build_result(**args)


def test_t_and_normal_quantiles_match_tables():
    # standard two-sided 95 % table values
    for dof, val in [(1, 12.706), (2, 4.303), (3, 3.182), (5, 2.571), (10, 2.228), (30, 2.042), (120, 1.980)]:
        assert t_ppf(0.975, dof) == pytest.approx(val, abs=6e-4)
    assert norm_ppf(0.975) == pytest.approx(1.959964, abs=1e-6)


def test_single_load_cphi_not_separable_and_ridge_interval():
    rng = np.random.default_rng(0)
    slip = np.linspace(0.01, 0.3, 8)
    res = _result(slip, HEAVY.weight, noise=2e3 * rng.standard_normal(8))
    assert res.rank == 2
    p = res.parameters
    assert not p["cohesion"].identifiable and not p["friction_angle"].identifiable
    assert p["shear_modulus"].identifiable and p["shear_modulus"].stderr > 0
    assert p["cohesion"].value is None and p["friction_angle"].value is None
    assert res.soil is None and "NOT an estimate" in res.ridge_point.name
    fmax = res.combinations[0]
    assert fmax.name.startswith("F_max") and fmax.stderr is not None and fmax.stderr > 0
    # the c interval is the ridge range for F_max within its CI, inside the bounds
    A, W = HEAVY.contact_area, HEAVY.weight
    lo, hi = p["cohesion"].ci95
    assert lo == pytest.approx(max(0.0, (fmax.ci95[0] - W * math.tan(PRACTICAL_BOUNDS.friction_angle[1])) / A))
    assert hi == pytest.approx(min(69e3, (fmax.ci95[1] - W * math.tan(PRACTICAL_BOUNDS.friction_angle[0])) / A))
    assert any("not separable" in s for s in res.identifiability["statements"])
    null = res.identifiability["null_space"][0]
    assert abs(null["shear_modulus_m"]) < 1e-8 and abs(null["cohesion_kpa"]) > 0.1
    d = check_contract(res)
    assert d["parameters"]["cohesion_kpa"]["identifiable"] is False
    # the JSON contract wants a number: the ridge centre, flagged as such (never an estimate)
    assert d["parameters"]["cohesion_kpa"]["value_is_ridge_point"] is True
    assert d["parameters"]["cohesion_kpa"]["value"] == pytest.approx(res.ridge_point.cohesion_kpa)
    assert res.covariance is None  # rank deficient: no parameter covariance


def test_two_loads_identify_all_with_finite_stderr():
    rng = np.random.default_rng(1)
    slip = np.tile(np.linspace(0.01, 0.3, 5), 2)
    loads = np.repeat([0.6 * HEAVY.weight, HEAVY.weight], 5)
    res = _result(slip, loads, noise=1e3 * rng.standard_normal(10))
    assert res.rank == 3 and res.soil is not None
    for pe in res.parameters.values():
        assert pe.identifiable and pe.stderr is not None and math.isfinite(pe.stderr) and pe.stderr > 0
    assert len([c for c in res.combinations if c.name.startswith("F_max")]) == 2
    assert res.covariance is not None and np.allclose(res.covariance, res.covariance.T)
    check_contract(res)


def test_covariance_is_s2_inverse_gram():
    rng = np.random.default_rng(2)
    slip = np.tile(np.linspace(0.01, 0.3, 6), 2)
    loads = np.repeat([0.5 * HEAVY.weight, HEAVY.weight], 6)
    noise = 1e3 * rng.standard_normal(12)
    res = _result(slip, loads, noise=noise)
    J = res.jacobian
    s2 = float(noise @ noise) / (12 - 3)
    assert np.allclose(res.covariance, s2 * np.linalg.inv(J.T @ J), rtol=1e-8)
    q = t_ppf(0.975, 9)
    K = res.parameters["shear_modulus"]
    assert K.ci95[0] == pytest.approx(K.value - q * K.stderr)


def test_zero_dof_gives_null_stderr_and_valid_json():
    slip = np.array([0.01, 0.05, 0.2])
    loads = np.array([0.5, 1.0, 1.0]) * HEAVY.weight
    res = _result(slip, loads, noise=np.array([1e3, -2e3, 5e2]))
    assert res.dof == 0
    assert all(pe.stderr is None for pe in res.parameters.values())
    d = check_contract(res)
    assert d["parameters"]["shear_modulus_m"]["stderr"] is None
    assert d["parameters"]["shear_modulus_m"]["ci95"] == [None, None]
    assert any("degrees of freedom" in w for w in res.warnings)


def test_non_finite_numbers_are_a_failure_not_an_answer():
    slip = np.linspace(0.01, 0.3, 5)
    res = _result(slip, HEAVY.weight, theta=np.array([np.nan, 0.5, np.inf]))
    assert not res.success and res.soil is None
    d = check_contract(res)
    assert d["success"] is False
    assert all(p["value"] is None for p in d["parameters"].values())


def test_cohesion_free_cohesion_is_fixed_and_labelled():
    rng = np.random.default_rng(3)
    slip = np.linspace(0.01, 0.3, 6)
    soil = Soil.from_kpa_deg(0.0, 30.0, 0.02)
    res = _result(slip, HEAVY.weight, soil=soil, model="cohesion-free", noise=1e3 * rng.standard_normal(6))
    c = res.parameters["cohesion"]
    assert c.fixed and c.value == 0.0 and not c.identifiable
    assert res.parameters["friction_angle"].identifiable
    assert res.soil is not None and res.soil.cohesion == 0.0
    d = check_contract(res)
    assert d["parameters"]["cohesion_kpa"]["fixed"] is True


def test_bound_flag_and_warning():
    rng = np.random.default_rng(4)
    slip = np.tile(np.linspace(0.01, 0.3, 5), 2)
    loads = np.repeat([0.5 * HEAVY.weight, HEAVY.weight], 5)
    soil = Soil.from_kpa_deg(3.0, 40.0, 0.02)  # phi exactly on the practical upper bound
    res = _result(slip, loads, soil=soil, noise=1e3 * rng.standard_normal(10))
    phi = res.parameters["friction_angle"]
    assert phi.at_bound and phi.bound_side == "upper"
    assert phi.ci95[1] <= PRACTICAL_BOUNDS.friction_angle[1]
    assert res.active_bounds == {"friction_angle": "upper"}
    assert any("upper bound" in w for w in res.warnings)


def test_weak_identifiability_at_small_slip():
    rng = np.random.default_rng(5)
    slip = np.linspace(0.0002, 0.002, 10)  # only the start of the curve
    soil = Soil.from_kpa_deg(0.0, 30.0, 0.02)
    res = _result(slip, HEAVY.weight, soil=soil, model="cohesion-free", noise=50 * rng.standard_normal(10))
    assert res.parameters["shear_modulus"].weakly_identifiable
    assert any("start of the thrust-slip curve" in s for s in res.identifiability["statements"])
    slope = [c for c in res.combinations if c.name.startswith("initial_slope")][0]
    assert not slope.weakly_identifiable and slope.stderr / slope.value < 0.01


def test_drive_kind_result_rmse_key_is_null():
    rng = np.random.default_rng(6)
    n = 200
    J = rng.standard_normal((n, 3))
    rw = rng.standard_normal(n)
    res = build_result(
        data_kind="drive",
        model="full",
        method="ipopt",
        theta=SEED_ACTUAL.as_vector(),
        jacobian=J,
        weighted_residuals=rw,
        residuals=0.01 * rw,
        residual_unit="rad/s",
        n_samples=n,
        normal_loads=np.array([HEAVY.weight]),
        vehicle=HEAVY,
        bounds=PRACTICAL_BOUNDS,
        status="Solve_Succeeded",
        success=True,
        message="",
        iterations=3,
        solve_time=0.1,
    )
    d = check_contract(res)
    assert d["rmse_N"] is None and d["residual_unit"] == "rad/s" and d["rmse"] > 0
    assert "rad/s" in res.report()


def test_build_result_rejects_bad_shapes():
    with pytest.raises(ValueError):
        build_result(
            data_kind="slip",
            model="full",
            method="ipopt",
            theta=np.zeros(3),
            jacobian=np.zeros((4, 2)),
            weighted_residuals=np.zeros(4),
            residuals=np.zeros(4),
            residual_unit="N",
            n_samples=4,
            normal_loads=np.ones(1),
            vehicle=HEAVY,
            bounds=PRACTICAL_BOUNDS,
            status="",
            success=True,
            message="",
            iterations=0,
            solve_time=0.0,
        )


# ------------------------------------------------------------------------------------------------
# laziness contract: statistics computed on first access, the same whether and when they are read
# ------------------------------------------------------------------------------------------------
STATS = ("_stats", "rank", "dof", "cost", "s2", "parameters", "combinations", "identifiability", "warnings")


def _everything(res) -> dict:
    """Every statistic and view of a result, as plain comparable values (exact)."""
    out = {
        "rank": res.rank,
        "dof": res.dof,
        "cost": res.cost,
        "s2": res.s2,
        "singular": res.scaled_singular_values.tolist(),
        "covariance": None if res.covariance is None else res.covariance.tolist(),
        "warnings": res.warnings,
        "identifiability": json.dumps(res.identifiability, sort_keys=True),
        "report": re.sub(r"iterations, [0-9.]+ m?s", "iterations", res.report()),
    }  # without the solve time
    d = json.loads(res.to_json())
    d.pop("solve_time_s", None)
    d.pop("extra", None)  # the solver's own timings
    out["json"] = json.dumps(d, sort_keys=True)
    for name, pe in res.parameters.items():
        out[name] = (pe.value, pe.stderr, tuple(pe.ci95), pe.identifiable, pe.weakly_identifiable, pe.at_bound)
    out["combinations"] = [(c.name, c.value, c.stderr) for c in res.combinations]
    return out


def _lazy_cases():
    from soiltrack.soilmodel import SlipData

    rng = np.random.default_rng(21)
    slip = np.linspace(0.01, 0.4, 40)
    cf = Soil.from_kpa_deg(0.0, 33.0, 0.015)
    F = tractive_force(slip, cf, HEAVY, model="cohesion-free")
    yield "cohesion-free", SlipData(slip, F * (1 + 0.01 * rng.standard_normal(40))), {"model": "cohesion-free"}
    F = tractive_force(slip, SEED_ACTUAL, HEAVY)
    yield "one load (ridge)", SlipData(slip, F + 2e3 * rng.standard_normal(40)), {}
    W = np.repeat([0.5 * HEAVY.weight, HEAVY.weight], 20)
    F = tractive_force(slip, SEED_ACTUAL, HEAVY, normal_load=W)
    yield "two loads (ipopt)", SlipData(slip, F + 2e3 * rng.standard_normal(40), W), {"engine": "ipopt"}
    F = tractive_force(slip, cf, HEAVY, model="cohesion-free")
    yield "kN in an N column", SlipData(slip, F / 1e3), {"model": "cohesion-free"}


@pytest.mark.parametrize("case", list(range(4)))
def test_statistics_are_lazy_and_the_same_whenever_read(case):
    from soiltrack.identify import fit

    name, data, kw = list(_lazy_cases())[case]
    looked = fit(data, HEAVY, **kw)
    before = _everything(looked)  # read everything at once
    untouched = fit(data, HEAVY, **kw)
    assert not any(k in untouched.__dict__ for k in STATS), name  # fit computed no statistic
    # what decides success is eager and independent of whether anyone looked
    assert (untouched.success, untouched.status, untouched.input_warnings, untouched.message) == (
        looked.success,
        looked.status,
        looked.input_warnings,
        looked.message,
    ), name
    assert np.array_equal(untouched.theta, looked.theta) and untouched.rmse == looked.rmse
    # a pickled untouched result computes its statistics after unpickling: the same numbers
    back = pickle.loads(pickle.dumps(untouched))
    assert not any(k in back.__dict__ for k in STATS)
    assert _everything(back) == before, name
    assert _everything(untouched) == before, name  # read in another order: the same
    # a pickled looked-at result carries what was computed
    again = pickle.loads(pickle.dumps(looked))
    assert "_stats" in again.__dict__ and _everything(again) == before, name
    if name == "kN in an N column":
        assert not looked.success and "answer not usable" in looked.status


def test_batched_results_pickle_their_own_slice_and_replace_keeps_statistics():
    import dataclasses
    from soiltrack.identify import fit_many
    from soiltrack.soilmodel import SlipData

    rng = np.random.default_rng(22)
    slip = np.linspace(0.01, 0.3, 12)
    sets = [
        SlipData(
            slip,
            tractive_force(slip, Soil.from_kpa_deg(0.0, rng.uniform(20, 38), 0.02), HEAVY, model="cohesion-free")
            * (1 + 0.02 * rng.standard_normal(12)),
        )
        for _ in range(5)
    ]
    res = fit_many(sets, HEAVY, model="cohesion-free", progress=False)
    blob = pickle.dumps(res[3])
    assert len(blob) < len(pickle.dumps(res)) / 2  # one fit's slice, not the batch's arrays
    back = pickle.loads(blob)
    assert _everything(back) == _everything(res[3])
    copy = dataclasses.replace(res[3], extra={"note": 1})
    assert _everything(copy)["json"] != "" and copy.rank == res[3].rank and copy.cost == res[3].cost
