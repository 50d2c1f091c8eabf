"""The compiled LM engine and the engine vocabulary (``fit(..., engine=...)``, ``fit_many``).

Every engine must reach the IPOPT path's optimum and give the same FitResult content
(uncertainty, identifiability, warnings, status), respect the bounds, never return NaN, and
hand any fit it cannot certify over to IPOPT. The C code is cached on disk (a second process
does not compile again); the virtual machine evaluates the same Function. Sample sizes are
few (each size class is compiled once).
"""

import json
import math
import os
import pickle
import subprocess
import sys
import time

import numpy as np
import pytest

from soiltrack.identify import FitSettings, fit, fit_many, jitcache
from soiltrack.identify.sweep import compiled_lm
from soiltrack.identify.engines import ENGINES
from soiltrack.identify.sweep.problem import make_problem
from soiltrack.soilmodel import (
    PRACTICAL_BOUNDS,
    VEHICLES,
    DataError,
    SlipData,
    Soil,
    SoilBounds,
    tractive_force,
    tractive_force_sensitivities,
)

HEAVY = VEHICLES["heavy"]
WONG = SlipData([0.0248, 0.0344, 0.0700], [207.32e3, 223.81e3, 259.81e3], source="wong2001_p176")
N = 8  # samples per random dataset
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def random_data(rng, model, loads, noise=0.02, slip_max=0.4, n=N):
    soil = Soil.from_kpa_deg(
        rng.uniform(0, 60) if model == "full" else 0.0, rng.uniform(8, 39), rng.uniform(0.007, 0.045)
    )
    slip = np.sort(rng.uniform(0.0, slip_max, n))
    W = np.resize(np.asarray(loads, float), n)
    F = tractive_force(slip, soil, HEAVY, model=model, normal_load=W)
    return SlipData(slip, F + noise * np.max(np.abs(F)) * rng.standard_normal(n), W)


def identified(res):
    """What the data identify: (c, phi, K), or (F_max, K) at one normal load (c-phi ridge)."""
    if res.model == "full" and len(res.normal_loads) == 1:
        return np.array([res.combinations[0].value, res.theta[2]])
    return np.asarray(res.theta, float)[list(res.free)]


def assert_same_result(a, b, rel=1e-5, engine="compiled"):
    """Same optimum (to solver tolerance) and the same statistical content."""
    assert a.success and b.success
    assert a.method == b.method == "ipopt"
    assert a.status == b.status == "converged"
    assert a.extra["engine"] == engine
    assert a.cost == pytest.approx(b.cost, rel=1e-9, abs=1e-12 * float(np.sum(b.residuals**2) + 1))
    assert a.rank == b.rank and a.dof == b.dof and a.free == b.free
    for name in ("cohesion", "friction_angle", "shear_modulus"):
        pa, pb = a.parameters[name], b.parameters[name]
        assert (pa.identifiable, pa.weakly_identifiable, pa.at_bound, pa.bound_side, pa.fixed) == (
            pb.identifiable,
            pb.weakly_identifiable,
            pb.at_bound,
            pb.bound_side,
            pb.fixed,
        ), name
        for x, y in (
            (pa.value, pb.value),
            (pa.stderr, pb.stderr),
            (pa.ridge_value, pb.ridge_value),
            *zip(pa.ci95, pb.ci95),
        ):
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
    assert da["extra"]["engine"] == engine


CASES = [
    ("cohesion-free", [HEAVY.weight]),
    ("cohesion-free", [0.5 * HEAVY.weight, HEAVY.weight]),
    ("full", [HEAVY.weight]),  # c-phi ridge: solved in (F_max, K), ridge point as IPOPT
    ("full", [0.5 * HEAVY.weight, HEAVY.weight]),
]


@pytest.mark.parametrize("model,loads", CASES)
def test_engines_agree_with_ipopt_to_1e8(model, loads):
    """Every engine reaches IPOPT's optimum: identified parameters to 1e-8, cost to 1e-12 (relative).

    Measured on these datasets: largest relative difference of the identified parameters
    about 6e-9 (IPOPT's own stopping tolerance), of the cost about 3e-14.
    """
    rng = np.random.default_rng((1 if model == "full" else 2) * 10 + len(loads))
    sets = []
    for k in range(6):
        gentle = k % 3 == 2  # small slips only: F_max and K strongly correlated
        sets.append(
            random_data(
                rng,
                model,
                loads,
                noise=0.01 if gentle else 0.03,
                slip_max=0.04 if gentle else 0.4,
                n=int(rng.integers(5, 30)),
            )
        )
    ref = [fit(d, HEAVY, model=model, engine="ipopt") for d in sets]
    runs = {e: [fit(d, HEAVY, model=model, engine=e) for d in sets] for e in ("compiled", "auto", "vectorized")}
    runs["fit_many vectorized"] = fit_many(sets, HEAVY, model=model, engine="vectorized", progress=False)
    runs["fit_many ipopt"] = fit_many(sets, HEAVY, model=model, engine="ipopt", progress=False)
    for name, res in runs.items():
        for a, b in zip(res, ref):
            assert a.success and a.status == b.status == "converged", name
            assert np.all(np.isfinite(a.theta))
            assert a.cost == pytest.approx(b.cost, rel=1e-12, abs=1e-300), name
            np.testing.assert_allclose(identified(a), identified(b), rtol=1e-8, err_msg=name)
    for a, b in zip(runs["compiled"], ref):
        assert_same_result(a, b)


def test_wong_points_as_ipopt_and_bound_reported():
    for model in ("full", "cohesion-free"):
        a = fit(WONG, HEAVY, model=model, engine="compiled")
        b = fit(WONG, HEAVY, model=model, engine="ipopt")
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
            b = fit(data, HEAVY, model=model, bounds=tight, x0=x0, engine="ipopt")
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
    ref = fit(data, HEAVY, engine="ipopt")
    monkeypatch.setattr(compiled_lm, "KKT_TOL", -1.0)  # nothing can be certified
    monkeypatch.setattr(compiled_lm, "ZERO_COST", -1.0)
    for res in (fit(data, HEAVY, engine="compiled"), fit_many([data], HEAVY, progress=False)[0]):
        assert res.success and res.extra["engine"] == "ipopt"
        assert res.extra["handed_over_from"] in ("compiled", "compiled-vm")
        assert "did not certify" in res.message
        assert res.status == ref.status == "converged"
        assert res.extra["solver_status"] in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
        assert res.cost == pytest.approx(ref.cost, rel=1e-9)
    one = fit(WONG, HEAVY, engine="compiled")  # one-load full data handed over too
    assert one.extra["engine"] == "ipopt" and one.success
    assert one.combinations[0].value == pytest.approx(fit(WONG, HEAVY, engine="ipopt").combinations[0].value, rel=1e-7)


def test_never_nan_on_awkward_data():
    """Zero-slip rows, an exact fit, a constant force, huge noise: finite answers or an honest hand-over."""
    rng = np.random.default_rng(5)
    slip = np.linspace(0.0, 0.3, N)
    soil = Soil.from_kpa_deg(0.0, 30.0, 0.02)
    exact = tractive_force(slip, soil, HEAVY, model="cohesion-free")
    cases = [
        SlipData(slip, exact),
        SlipData(slip, np.full(N, 1e5)),
        SlipData(slip, exact * (1 + rng.standard_normal(N))),
        SlipData(slip, -exact + 1.0),
    ]
    for d in cases:
        for model in ("cohesion-free", "full"):
            r = fit(d, HEAVY, model=model, engine="compiled")
            assert np.all(np.isfinite(r.theta))
            assert r.extra["engine"] in ("compiled", "ipopt")
            strict_json = json.loads(r.to_json(), parse_constant=lambda c: pytest.fail(f"JSON carries {c}"))
            assert strict_json["extra"]["engine"] == r.extra["engine"]
    r = fit(cases[0], HEAVY, model="cohesion-free", engine="compiled")  # exact data: exact recovery
    assert r.extra["engine"] == "compiled"
    assert r.theta[1] == pytest.approx(soil.friction_angle, rel=1e-9)
    assert r.theta[2] == pytest.approx(soil.shear_modulus, rel=1e-9)


def test_residuals_and_jacobian_are_the_soilmodel_physics():
    """The kernel's residuals and Jacobian equal soilmodel's tractive force and its AD sensitivities."""
    rng = np.random.default_rng(8)
    for model, loads in CASES:
        d = random_data(rng, model, loads, n=11)  # padded to 16 rows
        pb = make_problem(d, HEAVY, model, PRACTICAL_BOUNDS, sigma=rng.uniform(1e3, 5e3, 11))
        sol = compiled_lm.solve(pb)
        assert sol.certified
        soil = Soil(*sol.theta)
        F = tractive_force(d.slip, soil, HEAVY, model=model, normal_load=d.normal_load)
        J = tractive_force_sensitivities(d.slip, soil, HEAVY, model=model, normal_load=d.normal_load)
        np.testing.assert_allclose(sol.residuals, F - d.tractive_force, rtol=0, atol=1e-9 * np.max(np.abs(F)))
        np.testing.assert_allclose(sol.jacobian, J / pb.sigma[:, None], rtol=1e-12, atol=1e-300)


def test_size_classes_share_one_kernel():
    assert [compiled_lm.size_class(n) for n in (1, 3, 4, 5, 8, 9, 100, 128, 129)] == [4, 4, 4, 8, 8, 16, 128, 128, 256]
    assert compiled_lm.kernel(2, "cohesion-free", 5) is compiled_lm.kernel(2, "cohesion-free", 7)
    rng = np.random.default_rng(9)
    sets = [random_data(rng, "cohesion-free", [HEAVY.weight], n=n) for n in (5, 6, 7, 8)]  # all in class 8
    for d in sets:
        a, b = (
            fit(d, HEAVY, model="cohesion-free", engine="compiled"),
            fit(d, HEAVY, model="cohesion-free", engine="ipopt"),
        )
        assert a.n_samples == d.n_samples and a.residuals.shape == (d.n_samples,)
        assert a.cost == pytest.approx(b.cost, rel=1e-12)


def test_virtual_machine_agrees_with_c_code():
    """The same Function evaluated by CasADi's virtual machine and by the compiled C code."""
    if jitcache.compiler() is None:
        pytest.skip("no C compiler on PATH (or SOILTRACK_NO_JIT set): the C code cannot be tested here")
    k = compiled_lm.kernel(2, "cohesion-free", 3, 25, jit="wait")
    assert k.compiled.is_c and k.engine == "compiled", k.backend  # the JIT really ran (no silent fallback)
    assert k.solver.f.class_name() != k.vm[0].class_name()  # an external library, not the MX Function
    pb = make_problem(WONG, HEAVY, "cohesion-free", PRACTICAL_BOUNDS)
    x = compiled_lm.input_vector(pb, nc=k.n)
    vm = compiled_lm._Caller(k.vm[0])(x)
    c = k.solver(x)
    assert c[-1] == 1.0  # certified
    assert np.allclose(vm, c, rtol=1e-12, atol=1e-9)


def _fresh_process(code: str, cache: str) -> str:
    env = dict(os.environ, SOILTRACK_CACHE_DIR=cache, PYTHONPATH=ROOT)
    env.pop("SOILTRACK_NO_JIT", None)
    return subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True, timeout=300
    ).stdout.strip()


CHILD = (
    "from soiltrack.identify import fit; from soiltrack.soilmodel import VEHICLES, SlipData; "
    "r = fit(SlipData([0.0248, 0.0344, 0.07], [207.32e3, 223.81e3, 259.81e3]), VEHICLES['heavy'], "
    "model='cohesion-free', engine='{e}'); print(r.extra['engine'], '|', r.extra['engine_backend'], '|', "
    "repr(r.theta[1]))"
)


@pytest.mark.slow
def test_disk_cache_second_process_does_not_compile(tmp_path):
    if jitcache.compiler() is None:
        pytest.skip("no C compiler on PATH (or SOILTRACK_NO_JIT set)")
    cache = str(tmp_path / "cache")
    first = _fresh_process(CHILD.format(e="compiled"), cache).split(" | ")
    assert first[:2] == ["compiled", jitcache.C_NEW]
    libs = [f for f in os.listdir(cache) if f.endswith(".so")]
    assert len(libs) == 1 and not [f for f in os.listdir(cache) if f.endswith((".tmp", ".c"))]
    second = _fresh_process(CHILD.format(e="compiled"), cache).split(" | ")
    assert second[:2] == ["compiled", jitcache.C_CACHED] and second[2] == first[2]


@pytest.mark.slow
def test_auto_never_waits_and_picks_up_the_background_compilation(tmp_path, monkeypatch):
    """engine="auto" with an empty cache: the virtual machine now, said so; C code once compiled."""
    if jitcache.compiler() is None:
        pytest.skip("no C compiler on PATH (or SOILTRACK_NO_JIT set)")
    monkeypatch.setenv("SOILTRACK_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(compiled_lm, "_KERNELS", {})
    a = fit(WONG, HEAVY, model="cohesion-free")  # default engine: auto
    assert a.extra["engine"] == "compiled-vm" and a.extra["engine_backend"] == jitcache.VM_PENDING
    deadline = time.time() + 240
    while not [f for f in os.listdir(tmp_path) if f.endswith(".so")] and time.time() < deadline:
        time.sleep(0.2)
    b = fit(WONG, HEAVY, model="cohesion-free")
    assert b.extra["engine"] == "compiled" and b.extra["engine_backend"] == jitcache.C_CACHED
    assert b.theta[1] == pytest.approx(a.theta[1], rel=1e-13) and b.cost == pytest.approx(a.cost, rel=1e-12)


@pytest.mark.parametrize("how", ["no compiler", "SOILTRACK_NO_JIT"])
def test_no_compiler_falls_back_to_the_virtual_machine_and_says_so(monkeypatch, how):
    if how == "no compiler":
        monkeypatch.setattr(jitcache, "compiler", lambda: None)
        expected = jitcache.VM_NO_CC
    else:
        monkeypatch.setenv("SOILTRACK_NO_JIT", "1")
        expected = jitcache.VM_OFF
    monkeypatch.setattr(compiled_lm, "_KERNELS", {})
    r = fit(WONG, HEAVY, model="cohesion-free", engine="compiled")
    assert r.extra["engine"] == "compiled-vm" and r.extra["engine_backend"] == expected
    many = fit_many([WONG], HEAVY, model="cohesion-free", progress=False)[0]
    assert many.extra["engine"] == "vectorized-vm" and many.extra["engine_backend"] == expected
    ref = fit(WONG, HEAVY, model="cohesion-free", engine="ipopt")
    assert r.cost == pytest.approx(ref.cost, rel=1e-12) and r.status == ref.status == "converged"


def test_one_vocabulary_settings_and_statuses():
    rng = np.random.default_rng(6)
    sets = [random_data(rng, "full", [0.5 * HEAVY.weight, HEAVY.weight]) for _ in range(3)]
    assert ENGINES == ("auto", "ipopt", "compiled", "vectorized")
    labels = {e: [r.extra["engine"] for r in fit_many(sets, HEAVY, progress=False, engine=e)] for e in ENGINES}
    assert labels["ipopt"] == ["ipopt"] * 3 and labels["compiled"] == ["compiled"] * 3
    assert labels["vectorized"] == ["vectorized"] * 3 and set(labels["auto"]) <= {"vectorized", "vectorized-vm"}
    statuses = {
        r.status
        for e in ENGINES
        for r in [fit(sets[0], HEAVY, engine=e)] + fit_many(sets, HEAVY, engine=e, progress=False)
    }
    assert statuses == {"converged"}
    for bad in ("fast", "loop"):
        with pytest.raises(DataError, match="engine"):
            fit(sets[0], HEAVY, engine=bad)
        with pytest.raises(DataError, match="engine"):
            fit_many(sets, HEAVY, engine=bad, progress=False)
    with pytest.raises(DataError, match="n_grid"):
        FitSettings(n_grid=0)
    with pytest.raises(DataError, match="unknown option"):
        fit(sets[0], HEAVY, n_grids=3)
    st = FitSettings(engine="ipopt", n_grid=13, ipopt_options={"ipopt.max_iter": 200})
    a, b = (
        fit(sets[0], HEAVY, settings=st),
        fit(sets[0], HEAVY, engine="ipopt", n_grid=13, ipopt_options={"ipopt.max_iter": 200}),
    )
    assert a.extra["engine"] == b.extra["engine"] == "ipopt" and a.cost == b.cost
    assert fit(sets[0], HEAVY, settings=st, engine="compiled").extra["engine"] == "compiled"  # keyword wins
    assert fit(sets[0], HEAVY, method="newton", engine="compiled").method == "newton"  # engine: ipopt only
    back = pickle.loads(pickle.dumps(fit_many(sets, HEAVY, progress=False, engine="compiled")[0]))
    assert back.extra["engine"] == "compiled"


def test_single_fit_core_statistics_equal_the_batched_ones():
    """build_result's single-fit fast path gives the batched statistics (rank decisions identical)."""
    from soiltrack.identify.estimates.least_squares import core_stats, core_stats_one

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
            a, b = core_stats(J[None], rw[None], sk), core_stats_one(J, rw, sk)
            assert set(a) == set(b)
            for k in ("rank", "dof", "nonnull", "Dok"):
                assert np.array_equal(a[k], b[k]), k
            for k in ("D", "S", "Pinv", "ssr", "s2"):
                assert a[k].shape == b[k].shape
                scale = np.nanmax(np.abs(a[k])) if np.any(np.isfinite(a[k])) else 1.0
                assert np.allclose(a[k], b[k], rtol=1e-12, atol=1e-12 * scale, equal_nan=True), k


def test_solve_many_gives_exactly_what_solve_gives():
    """The stacked packing of fit_many's engine feeds the Function the same inputs as a single solve."""
    rng = np.random.default_rng(10)
    pbs = []
    for model, loads in CASES:
        for n in (3, 5, 20, 20, 37):
            if model == "full" and n < 3:
                continue
            d = random_data(rng, model, loads, n=n)
            pbs.append(make_problem(d, HEAVY, model, PRACTICAL_BOUNDS, sigma=rng.uniform(1e3, 5e3, n)))
    many = compiled_lm.solve_many(pbs)
    for pb, a in zip(pbs, many):
        b = compiled_lm.solve(pb)
        assert a.certified == b.certified and a.iterations == b.iterations and a.engine == b.engine
        assert np.array_equal(a.theta, b.theta) and np.array_equal(a.start, b.start)
        assert np.array_equal(a.residuals, b.residuals) and np.array_equal(a.jacobian, b.jacobian)
        assert all(np.array_equal(x, y) for x, y in zip(a.curves, b.curves))
        assert (a.screen, a.bp_screen, a.limit_screen) == (b.screen, b.bp_screen, b.limit_screen)


def input_state(pb):
    """The solver's input buffer after a solve: what input_vector says it is."""
    sol = compiled_lm.solve(pb)
    k = compiled_lm.kernel(sol.p, pb.model, pb.n)
    return np.array_equal(k.solver.x, compiled_lm.input_vector(pb, nc=k.n))


def test_the_buffer_fill_is_input_vector_and_records_have_every_field():
    """solve fills the solver's buffer in one copy: exactly input_vector; Solution and FitResult are built
    without their dataclass __init__: every field is there, in field order."""
    import dataclasses
    from soiltrack.identify.estimates.result import FitResult

    rng = np.random.default_rng(11)
    for model, loads in CASES:
        for n in (3, 16, 17, 40, 100):
            d = random_data(rng, model, loads, n=n)
            for sigma in (None, "relative", rng.uniform(1e3, 5e3, n)):
                pb = make_problem(d, HEAVY, model, PRACTICAL_BOUNDS, sigma=sigma)
                assert input_state(pb)
    sol = compiled_lm.solve(pb)
    assert list(sol.__dict__) == [f.name for f in dataclasses.fields(compiled_lm.Solution)]
    for res in (
        fit(d, HEAVY, model=model),
        fit(d, HEAVY, model=model, engine="ipopt"),
        fit(d, HEAVY, model=model, method="newton"),
    ):
        assert list(res.__dict__)[: len(dataclasses.fields(FitResult))] == [
            f.name for f in dataclasses.fields(FitResult)
        ]
        assert not any(type(v) is object for v in res.__dict__.values())


def test_plausibility_curves_of_the_kernel_are_the_soilmodel_ones():
    """The weakest/strongest soil curves the compiled residual Function returns for the plausibility
    checks equal soilmodel's thrust (to rounding), and the checks then find exactly the same."""
    from soiltrack.identify.sweep import plausibility

    rng = np.random.default_rng(12)
    found, checked = set(), 0
    for model, loads in CASES:
        for n in (5, 20, 37):
            d = random_data(rng, model, loads, n=n)
            F = np.array(d.tractive_force)
            if n == 20:
                F[3] *= 30.0  # a gross outlier / a row above any soil
            if n == 37:
                F = F / 1e3  # kN in an N column
            pb = make_problem(SlipData(d.slip, F, d.normal_load), HEAVY, model, PRACTICAL_BOUNDS)
            sol = compiled_lm.solve(pb)
            if not sol.certified:
                continue
            lo, hi = plausibility.corner_curves(pb.slip, pb.load, HEAVY, model, PRACTICAL_BOUNDS)
            assert np.allclose(sol.curves[0], lo, rtol=1e-13, atol=0) and np.allclose(sol.curves[1], hi, rtol=1e-13)
            args = (pb.slip, pb.force, pb.load, sol.residuals, sol.theta, HEAVY, model, PRACTICAL_BOUNDS)
            warnings, usable = plausibility.assess(*args, sol.curves)
            assert (warnings, usable) == plausibility.assess(*args)
            found |= {w.split(":")[0] for w in warnings if w.startswith("NOT USABLE")}
            checked += 1
    assert checked >= 3 * len(CASES) - 2 and found == {"NOT USABLE"}  # the bad rows were seen


def test_fast_robust_statistics_equal_numpy():
    """The partition-based median and quantile of the plausibility checks are numpy's, bit for bit."""
    from soiltrack.identify.sweep.plausibility import _median, _quantile
    from soiltrack.identify.sweep.problem import _heteroscedasticity_1d, heteroscedasticity

    rng = np.random.default_rng(13)
    for n in list(range(1, 40)) + [100, 101, 128, 1000]:
        x = rng.standard_normal(n) * 10 ** rng.uniform(-3, 6)
        assert _median(x) == np.median(x) and _median(np.abs(x), finite=True) == np.median(np.abs(x))
        for q in (0.1, 0.5, 0.9, 0.99):
            assert _quantile(np.abs(x), q) == np.quantile(np.abs(x), q)
        F, r, s = rng.uniform(1, 1e5, n), rng.standard_normal(n) * 1e3, np.full(n, rng.uniform(0.5, 2))
        one, stacked = heteroscedasticity(F, r, s), heteroscedasticity(F[None], r[None], s[None])[0]
        assert (np.isnan(one) and np.isnan(stacked)) or one == stacked
        ones = heteroscedasticity(F[None], r[None], np.ones((1, n)))[0]
        assert (np.isnan(ones) and n < 8) or _heteroscedasticity_1d(F, r, None) == ones  # weights of 1: no division
    assert np.isnan(_median(np.array([1.0, np.nan, 2.0])))


def test_twenty_lengths_share_a_few_size_classes(monkeypatch):
    """fit_many on 20 datasets of 20 lengths builds one kernel per size class, not one per length."""
    monkeypatch.setattr(compiled_lm, "_KERNELS", {})
    rng = np.random.default_rng(11)
    lengths = [5 + 10 * k for k in range(20)]  # 5 ... 195
    sets = [random_data(rng, "cohesion-free", [HEAVY.weight], n=n) for n in lengths]
    res = fit_many(sets, HEAVY, model="cohesion-free", progress=False)
    assert all(r.success and r.status == "converged" for r in res)
    assert len(compiled_lm._KERNELS) == len({compiled_lm.size_class(n) for n in lengths}) == 6
