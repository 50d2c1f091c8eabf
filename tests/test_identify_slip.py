"""Identification from tractive force-slip data: IPOPT, the seed's methods, fit_many, profiles."""

import json
import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from soiltrack.identify import FitFailed, fit, fit_many, profile_likelihood
from soiltrack.identify.sweep.model import predict
from soiltrack.soilmodel import PRACTICAL_BOUNDS, VEHICLES, DataError, SlipData, Soil, read_csv, tractive_force
from soiltrack.soilmodel.traction import tractive_force_sensitivities

HEAVY = VEHICLES["heavy"]
LIGHT = VEHICLES["light"]
WONG = SlipData([0.0248, 0.0344, 0.0700], [207.32e3, 223.81e3, 259.81e3], source="wong2001_p176")
TRUE = Soil.from_kpa_deg(5.0, 30.0, 0.02)


def strict_json(text):
    def bad(c):
        raise AssertionError(f"JSON carries {c}")

    return json.loads(text, parse_constant=bad)


def simulate(rng, n_per_load, loads, noise_rel, soil=TRUE, vehicle=HEAVY, slip_max=0.4, model="full"):
    slip = np.tile(np.linspace(0.01, slip_max, n_per_load), len(loads))
    W = np.repeat(loads, n_per_load)
    F = tractive_force(slip, soil, vehicle, model=model, normal_load=W)
    sigma = noise_rel * float(np.max(F))
    return SlipData(slip, F + sigma * rng.standard_normal(F.size), W), sigma


def test_fit_model_is_the_soilmodel():
    # the slip fits' residual model (rig measurement with no effect) is Eq. 2 itself, with its AD derivatives
    slip = np.concatenate([[0.0, 1e-6, 1e-3], np.linspace(0.01, 0.95, 40)])
    W = np.linspace(1e5, 4e5, slip.size)
    F, J = predict(TRUE.as_vector(), slip, W, HEAVY)
    np.testing.assert_array_equal(F, tractive_force(slip, TRUE, HEAVY, normal_load=W))
    np.testing.assert_allclose(J, tractive_force_sensitivities(slip, TRUE, HEAVY, normal_load=W), rtol=1e-13)


@pytest.mark.parametrize("noise", [0.0, 0.002, 0.01])
def test_recovery_several_loads(noise):
    rng = np.random.default_rng(10)
    data, _ = simulate(rng, 8, [0.5 * HEAVY.weight, 0.75 * HEAVY.weight, HEAVY.weight], noise)
    res = fit(data, HEAVY)
    assert res.success and res.soil is not None
    for name, true in zip(("cohesion", "friction_angle", "shear_modulus"), TRUE.as_vector()):
        pe = res.parameters[name]
        assert pe.identifiable
        if noise == 0:
            assert pe.value == pytest.approx(true, rel=1e-6)
        else:
            assert abs(pe.value - true) < 4 * pe.stderr
    if noise == 0:
        assert res.rmse < 1e-3


@pytest.mark.parametrize("noise", [0.002, 0.01, 0.03])
def test_recovery_single_load_gives_fmax_and_K(noise):
    rng = np.random.default_rng(11)
    data, _ = simulate(rng, 12, [HEAVY.weight], noise)
    res = fit(data, HEAVY)
    assert res.success
    assert not res.parameters["cohesion"].identifiable and not res.parameters["friction_angle"].identifiable
    assert res.soil is None
    fmax = res.combinations[0]
    true_fmax = HEAVY.contact_area * TRUE.cohesion + HEAVY.weight * math.tan(TRUE.friction_angle)
    assert abs(fmax.value - true_fmax) < 4 * fmax.stderr
    K = res.parameters["shear_modulus"]
    assert K.identifiable and abs(K.value - TRUE.shear_modulus) < 4 * K.stderr
    # the c interval shows the ridge: it contains the truth
    lo, hi = res.parameters["cohesion"].ci95
    assert lo <= TRUE.cohesion <= hi


def test_cphi_identifiable_only_with_two_loads():
    rng = np.random.default_rng(12)
    one, _ = simulate(rng, 10, [HEAVY.weight], 0.005)
    two, _ = simulate(rng, 5, [0.5 * HEAVY.weight, HEAVY.weight], 0.005)
    r1, r2 = fit(one, HEAVY), fit(two, HEAVY)
    assert [r1.parameters[n].identifiable for n in ("cohesion", "friction_angle")] == [False, False]
    assert [r2.parameters[n].identifiable for n in ("cohesion", "friction_angle")] == [True, True]
    assert "not separable" in r1.report()


def test_coverage_of_95_percent_intervals():
    """200 replicate fits: each parameter's interval covers the truth about 95 % of the time."""
    rng = np.random.default_rng(13)
    loads = [0.5 * HEAVY.weight, HEAVY.weight]
    sets = [simulate(rng, 6, loads, 0.01)[0] for _ in range(200)]
    results = fit_many(sets, HEAVY, model="full", method="ipopt", progress=False)
    n = len(results)
    assert all(r.success for r in results)
    lo_ok, hi_ok = 0.95 - 3 * math.sqrt(0.95 * 0.05 / n), 0.95 + 3 * math.sqrt(0.95 * 0.05 / n)
    for j, name in enumerate(("cohesion", "friction_angle", "shear_modulus")):
        hits = sum(r.parameters[name].ci95[0] <= TRUE.as_vector()[j] <= r.parameters[name].ci95[1] for r in results)
        assert lo_ok <= hits / n <= min(1.0, hi_ok), (name, hits / n)


def test_coverage_with_known_sigma_single_load_fmax():
    rng = np.random.default_rng(14)
    sets, sig = [], None
    for _ in range(200):
        d, sig = simulate(rng, 8, [HEAVY.weight], 0.01)
        sets.append(d)
    results = fit_many(sets, HEAVY, progress=False, sigma=sig)
    true_fmax = HEAVY.contact_area * TRUE.cohesion + HEAVY.weight * math.tan(TRUE.friction_angle)
    hits = sum(r.combinations[0].ci95[0] <= true_fmax <= r.combinations[0].ci95[1] for r in results)
    n = len(results)
    assert 0.95 - 3 * math.sqrt(0.95 * 0.05 / n) <= hits / n <= 1.0
    assert all(r.sigma_known for r in results)


def test_wong_data_honest_residuals_and_identifiability():
    res = fit(WONG, HEAVY)
    assert res.success
    rel = np.abs(res.residuals) / WONG.tractive_force
    assert rel.max() > 0.005  # the data do not fit Eq. 2 exactly (docs/paper.md: ~2.2 % at the seed's values)
    assert res.rmse > 1e3
    assert res.soil is None
    assert not res.parameters["cohesion"].identifiable and not res.parameters["friction_angle"].identifiable
    assert res.parameters["shear_modulus"].identifiable
    # the optimiser's ridge point is arbitrary: it must not be reported as "on a bound"
    assert not res.parameters["friction_angle"].at_bound and not res.parameters["cohesion"].at_bound
    assert not any("bound" in w for w in res.warnings)
    assert res.dof == 1 and res.combinations[0].stderr is not None
    assert np.all(res.theta >= PRACTICAL_BOUNDS.lower) and np.all(res.theta <= PRACTICAL_BOUNDS.upper)
    text = res.report()
    assert "NOT IDENTIFIABLE" in text and "residuals" in text
    strict_json(res.to_json())


def test_wong_file_reads_and_fits_like_memory_data():
    res = fit(read_csv("examples/data/wong2001_p176.csv"), HEAVY)
    ref = fit(WONG, HEAVY)
    assert res.combinations[0].value == pytest.approx(ref.combinations[0].value, rel=1e-6)


def test_cohesion_free_on_wong_hits_phi_bound():
    res = fit(WONG, HEAVY, model="cohesion-free")
    phi = res.parameters["friction_angle"]
    assert phi.at_bound and phi.bound_side == "upper"
    assert phi.value <= PRACTICAL_BOUNDS.friction_angle[1] + 1e-12
    assert math.degrees(phi.value) == pytest.approx(40.0, abs=1e-6)
    assert any("upper bound" in w for w in res.warnings)
    d = strict_json(res.to_json())
    assert d["parameters"]["friction_angle_deg"]["at_bound"] is True


def test_newton_on_seed_data_reports_singularity_without_nan():
    res = fit(WONG, HEAVY, method="newton")
    assert not res.success and res.status == "Singular_Jacobian"
    assert res.soil is None
    assert "singular" in res.message.lower() and "F_max" in res.message
    d = strict_json(res.to_json())
    assert all(p["value"] is None for p in d["parameters"].values())
    assert np.all(np.isfinite(res.theta))
    with pytest.raises(FitFailed):
        fit(WONG, HEAVY, method="newton", strict=True)


def test_newton_solves_square_system_at_two_loads():
    slip = np.array([0.02, 0.1, 0.05])
    W = np.array([0.5, 0.5, 1.0]) * HEAVY.weight
    data = SlipData(slip, tractive_force(slip, TRUE, HEAVY, normal_load=W), W)
    res = fit(data, HEAVY, method="newton", x0=Soil.from_kpa_deg(4.0, 28.0, 0.018))
    assert res.success, res.message
    assert np.allclose(res.theta, TRUE.as_vector(), rtol=1e-8)
    assert "Newton-Raphson" in res.extra["algorithm"]


def test_newton_with_more_points_says_gauss_newton():
    rng = np.random.default_rng(15)
    data, _ = simulate(rng, 5, [0.5 * HEAVY.weight, HEAVY.weight], 0.005)
    res = fit(data, HEAVY, method="newton", x0=Soil.from_kpa_deg(4.0, 28.0, 0.018))
    assert "Gauss-Newton" in res.extra["algorithm"]
    ref = fit(data, HEAVY)
    assert res.success, res.message
    np.testing.assert_allclose(res.theta, ref.theta, rtol=1e-9)  # measured: 8e-11


def test_least_squares_reports_what_it_does():
    res = fit(WONG, HEAVY, method="least-squares")
    assert "Levenberg-Marquardt" in res.message and "unconstrained" in res.message
    assert res.soil is None  # one load: c and phi not identifiable, whatever ridge point LM stopped at
    ref = fit(WONG, HEAVY)
    assert res.combinations[0].value == pytest.approx(ref.combinations[0].value, rel=1e-4)
    strict_json(res.to_json())
    rng = np.random.default_rng(16)
    data, _ = simulate(rng, 5, [0.5 * HEAVY.weight, HEAVY.weight], 0.0)
    res2 = fit(data, HEAVY, method="least-squares", x0=Soil.from_kpa_deg(10.0, 25.0, 0.03))
    assert res2.success and np.allclose(res2.theta, TRUE.as_vector(), rtol=1e-5)


def test_ipopt_respects_bounds_on_steep_data():
    strong = Soil.from_kpa_deg(0.5, 44.0, 0.02)  # phi beyond the practical range
    rng = np.random.default_rng(17)
    data, _ = simulate(rng, 6, [0.5 * HEAVY.weight, HEAVY.weight], 0.002, soil=strong)
    res = fit(data, HEAVY)
    assert np.all(res.theta >= PRACTICAL_BOUNDS.lower) and np.all(res.theta <= PRACTICAL_BOUNDS.upper)
    assert res.parameters["friction_angle"].at_bound
    assert res.active_bounds.get("friction_angle") == "upper"


def test_light_vehicle_and_missing_loads_use_vehicle_weight():
    rng = np.random.default_rng(18)
    slip = np.linspace(0.01, 0.5, 10)
    soil = Soil.from_kpa_deg(1.0, 30.0, 0.01)
    F = tractive_force(slip, soil, LIGHT)
    res = fit(SlipData(slip, F + 0.5 * rng.standard_normal(10)), LIGHT)
    assert res.success and res.normal_loads.tolist() == [pytest.approx(LIGHT.weight)]
    assert abs(res.parameters["shear_modulus"].value - 0.01) < 4 * res.parameters["shear_modulus"].stderr


def test_bad_inputs_raise_data_error():
    with pytest.raises(DataError) as e:
        fit(SlipData([0.01, 0.02], [1e5, 1.2e5], source="two.csv"), HEAVY)
    assert "two.csv" in str(e.value) and "tractive_force_N" in str(e.value)
    fit(SlipData([0.01, 0.02], [1e5, 1.2e5]), HEAVY, model="cohesion-free")  # 2 unknowns: fine
    with pytest.raises(DataError):
        fit(SlipData([0.01], [1e5]), HEAVY, model="cohesion-free")
    with pytest.raises(DataError):
        fit({"slip": [0.1]}, HEAVY)
    with pytest.raises(DataError):
        fit(WONG, "heavy")
    with pytest.raises(DataError):
        fit(WONG, HEAVY, model="wet")
    with pytest.raises(DataError):
        fit(WONG, HEAVY, method="magic")
    with pytest.raises(DataError):
        fit(WONG, HEAVY, sigma=-1.0)
    with pytest.raises(DataError):
        fit(WONG, HEAVY, x0=[500.0, 35.0, 0.02])  # degrees instead of radians
    with pytest.raises(DataError):
        fit(WONG, HEAVY, unknown_option=1)
    with pytest.raises(DataError):
        fit_many([WONG], HEAVY, model="wet", progress=False)


def test_fit_many_equals_individual_fits():
    rng = np.random.default_rng(19)
    multi = [simulate(rng, 4, [0.5 * HEAVY.weight, HEAVY.weight], 0.01)[0] for _ in range(8)]
    single = [simulate(rng, 9, [HEAVY.weight], 0.01)[0] for _ in range(5)]
    for sets in (multi, single):
        batch = fit_many(sets, HEAVY, progress=False)
        loop = [fit(d, HEAVY) for d in sets]
        for b, s in zip(batch, loop):
            assert b.success and s.success
            assert b.cost == pytest.approx(s.cost, rel=1e-7)
            for cb, cs in zip(b.combinations, s.combinations):
                assert cb.value == pytest.approx(cs.value, rel=1e-5)
                assert cb.stderr == pytest.approx(cs.stderr, rel=1e-3)
            for name in ("cohesion", "friction_angle", "shear_modulus"):
                pb, ps = b.parameters[name], s.parameters[name]
                assert pb.identifiable == ps.identifiable
                if pb.identifiable:
                    assert pb.value == pytest.approx(ps.value, rel=1e-5)


def test_fit_many_executor_mixed_sizes_and_methods():
    rng = np.random.default_rng(20)
    sets = [simulate(rng, n, [0.5 * HEAVY.weight, HEAVY.weight], 0.01)[0] for n in (3, 4, 3, 5)] + [WONG]
    ref = fit_many(sets, HEAVY, progress=False)
    with ThreadPoolExecutor(2) as ex:
        par = fit_many(sets, HEAVY, progress=False, executor=ex, chunk_size=2)
    assert [r.cost for r in par] == pytest.approx([r.cost for r in ref], rel=1e-9)
    newton = fit_many([WONG], HEAVY, method="newton", progress=False)
    assert newton[0].status == "Singular_Jacobian"
    with pytest.raises(FitFailed):
        fit_many([WONG], HEAVY, method="newton", progress=False, strict=True)


def test_fit_many_progress_goes_to_stderr(capsys):
    rng = np.random.default_rng(21)
    fit_many([simulate(rng, 4, [HEAVY.weight], 0.01)[0] for _ in range(3)], HEAVY, progress=True)
    out = capsys.readouterr()
    assert out.out == "" and "fit_many: 3/3" in out.err


def test_profile_likelihood_matches_linear_interval_and_shows_ridge():
    rng = np.random.default_rng(22)
    data, _ = simulate(rng, 6, [0.5 * HEAVY.weight, HEAVY.weight], 0.005)
    res = fit(data, HEAVY)
    prof = profile_likelihood(data, HEAVY, "K", values=np.linspace(0.017, 0.023, 31), fit_result=res)
    lo, hi = prof.interval
    K = res.parameters["shear_modulus"]
    assert lo == pytest.approx(K.ci95[0], rel=0.02) and hi == pytest.approx(K.ci95[1], rel=0.02)
    assert not prof.open_lower and not prof.open_upper
    flat = profile_likelihood(WONG, HEAVY, "c", n_points=9)
    assert flat.open_upper  # c is unbounded by one-load data up to the bound
    strict_json(json.dumps(flat.to_dict()))


def test_strict_raises_only_on_failure():
    res = fit(WONG, HEAVY, strict=True)  # succeeds (non-identifiability is reported, not a failure)
    assert res.success
    with pytest.raises(FitFailed) as e:
        fit(WONG, HEAVY, method="newton", strict=True)
    assert e.value.result.status == "Singular_Jacobian"


def test_drive_log_is_dispatched():
    from soiltrack.soilmodel import TERRAINS, simulate_drive_log

    light = VEHICLES["light"]
    log = simulate_drive_log(light, TERRAINS["dry_sand"], seed=1, duration_s=10.0)  # a valid 500-sample log
    res = fit(log, light)
    assert res.data_kind == "drive" and res.success, res.message
