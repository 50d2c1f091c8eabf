"""The compiled single-fit engine (``fit(..., engine="compiled")``, small groups in ``fit_many``).

It must give the IPOPT path's optimum and the same FitResult content (uncertainty,
identifiability, warnings), respect the bounds, never return NaN, and hand any fit it cannot
certify over to IPOPT. Sample sizes are few (each (variant, n) is compiled once).
"""
import json
import math
import pickle

import casadi as ca
import numpy as np
import pytest

from soiltrack.identify import compiled_lm, fit, fit_many
from soiltrack.identify.problem import make_problem
from soiltrack.soilmodel import PRACTICAL_BOUNDS, VEHICLES, DataError, SlipData, Soil, SoilBounds, tractive_force

HEAVY = VEHICLES["heavy"]
WONG = SlipData([0.0248, 0.0344, 0.0700], [207.32e3, 223.81e3, 259.81e3], source="wong2001_p176")
N = 8  # samples per random dataset


def random_data(rng, model, loads, noise=0.02, slip_max=0.4, n=N):
    soil = Soil.from_kpa_deg(rng.uniform(0, 60) if model == "full" else 0.0, rng.uniform(8, 39),
                             rng.uniform(0.007, 0.045))
    slip = np.sort(rng.uniform(0.0, slip_max, n))
    W = np.resize(np.asarray(loads, float), n)
    F = tractive_force(slip, soil, HEAVY, model=model, normal_load=W)
    return SlipData(slip, F + noise * np.max(np.abs(F)) * rng.standard_normal(n), W)


def assert_same_result(a, b, rel=1e-5):
    """Same optimum (to solver tolerance) and the same statistical content."""
    assert a.success and b.success
    assert a.method == b.method == "ipopt"
    assert a.extra["engine"] == "compiled-lm"
    assert a.cost == pytest.approx(b.cost, rel=1e-9, abs=1e-12 * float(np.sum(b.residuals ** 2) + 1))
    assert a.rank == b.rank and a.dof == b.dof and a.free == b.free
    for name in ("cohesion", "friction_angle", "shear_modulus"):
        pa, pb = a.parameters[name], b.parameters[name]
        assert (pa.identifiable, pa.weakly_identifiable, pa.at_bound, pa.bound_side, pa.fixed) == \
            (pb.identifiable, pb.weakly_identifiable, pb.at_bound, pb.bound_side, pb.fixed), name
        for x, y in ((pa.value, pb.value), (pa.stderr, pb.stderr), (pa.ridge_value, pb.ridge_value),
                     *zip(pa.ci95, pb.ci95)):
            assert (x is None) == (y is None)
            if x is not None:
                assert x == pytest.approx(y, rel=rel, abs=1e-9)
    assert [c.name for c in a.combinations] == [c.name for c in b.combinations]
    for ca_, cb in zip(a.combinations, b.combinations):
        assert ca_.value == pytest.approx(cb.value, rel=rel)
        assert (ca_.stderr is None) == (cb.stderr is None)
        if ca_.stderr is not None:
            assert ca_.stderr == pytest.approx(cb.stderr, rel=1e-3)
        assert (ca_.estimable, ca_.weakly_identifiable) == (cb.estimable, cb.weakly_identifiable)
    assert a.warnings == b.warnings
    assert a.identifiability["statements"] == b.identifiability["statements"]
    assert (a.soil is None) == (b.soil is None)
    da, db = json.loads(a.to_json()), json.loads(b.to_json())
    assert set(da) == set(db) and set(da["parameters"]) == set(db["parameters"])
    assert da["extra"]["engine"] == "compiled-lm"


@pytest.mark.parametrize("model,loads", [
    ("cohesion-free", [HEAVY.weight]),
    ("cohesion-free", [0.5 * HEAVY.weight, HEAVY.weight]),
    ("full", [HEAVY.weight]),  # c-phi ridge: solved in (F_max, K), ridge point as IPOPT
    ("full", [0.5 * HEAVY.weight, HEAVY.weight]),
])
def test_agrees_with_ipopt_on_random_datasets(model, loads):
    rng = np.random.default_rng((1 if model == "full" else 2) * 10 + len(loads))
    for k in range(6):
        gentle = k % 3 == 2  # small slips only: F_max and K strongly correlated
        data = random_data(rng, model, loads, noise=0.01 if gentle else 0.03, slip_max=0.04 if gentle else 0.4)
        a = fit(data, HEAVY, model=model, engine="compiled")
        b = fit(data, HEAVY, model=model, engine="ipopt")
        assert b.extra["engine"] == "ipopt"
        assert_same_result(a, b)
        assert np.all(np.isfinite(a.theta))


def test_wong_points_as_ipopt_and_bound_reported():
    for model in ("full", "cohesion-free"):
        a = fit(WONG, HEAVY, model=model, engine="compiled")
        b = fit(WONG, HEAVY, model=model)
        assert_same_result(a, b, rel=1e-6)
    a = fit(WONG, HEAVY, model="cohesion-free", engine="compiled")
    assert a.parameters["friction_angle"].at_bound and a.parameters["friction_angle"].bound_side == "upper"
    assert math.degrees(a.theta[1]) == pytest.approx(40.0, abs=1e-9)
    assert a.theta[1] <= PRACTICAL_BOUNDS.friction_angle[1]


def test_bounds_respected_with_tight_bounds_and_given_start():
    rng = np.random.default_rng(3)
    tight = SoilBounds.from_kpa_deg((1.0, 2.0), (20.0, 25.0), (0.03, 0.04))
    for model, loads in (("full", [0.5 * HEAVY.weight, HEAVY.weight]), ("cohesion-free", [HEAVY.weight])):
        data = random_data(rng, model, loads)
        for x0 in (None, Soil.from_kpa_deg(60.0, 39.0, 0.007)):  # start far outside the box
            a = fit(data, HEAVY, model=model, bounds=tight, x0=x0, engine="compiled")
            b = fit(data, HEAVY, model=model, bounds=tight, x0=x0)
            # the truth lies far outside these bounds: the solver converges, the plausibility check may
            # then call the bound-fixed answer not usable (issue 7), which is right
            assert np.all(np.isfinite(a.theta)) and (a.success or a.status.endswith("(answer not usable)"))
            free = list(a.free)
            assert np.all(a.theta[free] >= tight.lower[free]) and np.all(a.theta[free] <= tight.upper[free])
            assert a.cost == pytest.approx(b.cost, rel=1e-8)
            assert a.active_bounds == b.active_bounds


def test_not_certified_is_handed_to_ipopt(monkeypatch):
    rng = np.random.default_rng(4)
    data = random_data(rng, "full", [0.5 * HEAVY.weight, HEAVY.weight])
    ref = fit(data, HEAVY)
    monkeypatch.setattr(compiled_lm, "KKT_TOL", -1.0)  # nothing can be certified
    monkeypatch.setattr(compiled_lm, "ZERO_COST", -1.0)
    res = fit(data, HEAVY, engine="compiled")
    assert res.success and res.extra["engine"] == "ipopt"
    assert "did not certify" in res.message and res.status in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
    assert res.cost == pytest.approx(ref.cost, rel=1e-9)
    one = fit(WONG, HEAVY, engine="compiled")  # one-load full data handed over too
    assert one.extra["engine"] == "ipopt" and one.success
    assert one.combinations[0].value == pytest.approx(fit(WONG, HEAVY).combinations[0].value, rel=1e-7)


def test_never_nan_on_awkward_data():
    """Zero-slip rows, an exact fit, a constant force, huge noise: finite answers or an honest hand-over."""
    rng = np.random.default_rng(5)
    slip = np.linspace(0.0, 0.3, N)
    soil = Soil.from_kpa_deg(0.0, 30.0, 0.02)
    exact = tractive_force(slip, soil, HEAVY, model="cohesion-free")
    cases = [SlipData(slip, exact), SlipData(slip, np.full(N, 1e5)),
             SlipData(slip, exact * (1 + rng.standard_normal(N))), SlipData(slip, -exact + 1.0)]
    for d in cases:
        for model in ("cohesion-free", "full"):
            r = fit(d, HEAVY, model=model, engine="compiled")
            assert np.all(np.isfinite(r.theta))
            assert r.extra["engine"] in ("compiled-lm", "ipopt")
            strict_json = json.loads(r.to_json(), parse_constant=lambda c: pytest.fail(f"JSON carries {c}"))
            assert strict_json["extra"]["engine"] == r.extra["engine"]
    r = fit(cases[0], HEAVY, model="cohesion-free", engine="compiled")  # exact data: exact recovery
    assert r.extra["engine"] == "compiled-lm"
    assert r.theta[1] == pytest.approx(soil.friction_angle, rel=1e-9)
    assert r.theta[2] == pytest.approx(soil.shear_modulus, rel=1e-9)


def test_closed_form_derivatives_match_casadi_ad():
    for p in (2, 3):
        _, ev, _ = compiled_lm._point_functions(p, 3)
        z = ca.SX.sym("z", p)
        sx = [ca.SX.sym(k) for k in ("s", "F", "W", "sig", "l", "b")]
        rw = compiled_lm._fit_residuals(z, ca.vertcat(*sx), 1, p)
        J = ca.jacobian(rw, z)
        f = 0.5 * rw * rw
        ad = ca.Function("ad", [z] + sx, [ca.vertcat(f, ca.vec(J.T * rw), ca.vec(ca.hessian(f, z)[0]),
                                                     ca.vec(J.T * J.T))])
        rng = np.random.default_rng(p)
        for _ in range(300):
            zz = ([rng.uniform(0, 69)] if p == 3 else []) + [rng.uniform(0.1, 0.7), rng.uniform(0.6, 5.0)]
            s = float(rng.choice([0.0, rng.uniform(0, 0.9), rng.uniform(0, 1e-3), 1e-7]))
            args = [zz, s, rng.uniform(-1e5, 3e5), rng.uniform(1e4, 4e5), rng.uniform(0.5, 2), 2.8, 0.5]
            a, b = np.array(ev(*args)).ravel(), np.array(ad(*args)).ravel()
            assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(b))


def test_virtual_machine_fallback_agrees():
    """Without a C compiler the same Function runs in CasADi's virtual machine."""
    pb = make_problem(WONG, HEAVY, "cohesion-free", PRACTICAL_BOUNDS)
    x = np.concatenate([pb.slip, pb.force, pb.load, pb.sigma, [HEAVY.track_length, HEAVY.track_width],
                        [PRACTICAL_BOUNDS.friction_angle[0], PRACTICAL_BOUNDS.shear_modulus[0] / 1e-2],
                        [PRACTICAL_BOUNDS.friction_angle[1], PRACTICAL_BOUNDS.shear_modulus[1] / 1e-2], [0, 0], [0]])
    vm = compiled_lm._Caller(compiled_lm.compiled_solver(2, 3, 25, jit=False))(x)
    jit = compiled_lm._caller(2, 3, 25)(x)
    assert np.allclose(vm, jit, rtol=1e-12, atol=1e-9)


def test_api_engine_values_fit_many_and_pickle():
    rng = np.random.default_rng(6)
    sets = [random_data(rng, "full", [0.5 * HEAVY.weight, HEAVY.weight]) for _ in range(3)]
    small = fit_many(sets, HEAVY, progress=False)  # small group: compiled engine
    assert [r.extra["engine"] for r in small] == ["compiled-lm"] * 3
    vec = fit_many(sets, HEAVY, progress=False, engine="vectorized")
    assert [r.extra["engine"] for r in vec] == ["batch-lm"] * 3
    for a, b in zip(small, vec):
        assert a.cost == pytest.approx(b.cost, rel=1e-9)
    auto = fit(sets[0], HEAVY, engine="auto")
    assert auto.extra["engine"] == "compiled-lm"
    assert fit(sets[0], HEAVY, method="newton", engine="compiled").method == "newton"  # engine: ipopt only
    with pytest.raises(DataError):
        fit(sets[0], HEAVY, engine="fast")
    back = pickle.loads(pickle.dumps(small[0]))
    assert back.cost == small[0].cost and back.extra["engine"] == "compiled-lm"


def test_single_fit_core_statistics_equal_the_batched_ones():
    """build_result's single-fit fast path gives the batched statistics (rank decisions identical)."""
    from soiltrack.identify.result import _core_stats, _core_stats_one
    rng = np.random.default_rng(7)
    for _ in range(400):
        n, p = int(rng.integers(1, 12)), int(rng.choice([2, 3]))
        J = rng.standard_normal((n, p)) * 10 ** rng.uniform(-5, 5, p)
        kind = int(rng.integers(0, 5))
        if kind == 1 and p == 3:
            J[:, 1] = 2.5 * J[:, 0]  # exact ridge
        elif kind == 2:
            J[:, 0] = 0.0
        elif kind == 3:
            J[rng.integers(0, n), rng.integers(0, p)] = np.nan
        rw = rng.standard_normal(n)
        if kind == 4:
            rw[0] = np.inf
        for sk in (False, True):
            a, b = _core_stats(J[None], rw[None], np.arange(p), sk), _core_stats_one(J, rw, sk)
            assert set(a) == set(b)
            for k in ("rank", "dof", "nonnull", "Dok"):
                assert np.array_equal(a[k], b[k]), k
            for k in ("D", "S", "Pinv", "ssr", "s2"):
                assert a[k].shape == b[k].shape
                scale = np.nanmax(np.abs(a[k])) if np.any(np.isfinite(a[k])) else 1.0
                assert np.allclose(a[k], b[k], rtol=1e-12, atol=1e-12 * scale, equal_nan=True), k
