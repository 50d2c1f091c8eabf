"""The joint drive-log NLP evaluated from compiled C kernels gives the virtual machine's numbers exactly."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from soiltrack.identify.drivelog import joint as J
from soiltrack.identify.drivelog.prepare import prepare_drive_log
from soiltrack.identify.jitcache import compiler, load
from soiltrack.soilmodel import TERRAINS, VEHICLES, simulate
from soiltrack.soilmodel.effects import effect_structure, parse_effects


def _problem(names, vehicle="light", seconds=1.2, seed=3):
    v = VEHICLES[vehicle]
    log = simulate(v, TERRAINS["dry_sand"], kind="drive", effects={"grade": 0.03}, seed=seed, duration_s=seconds)
    prep = prepare_drive_log(log, v)
    jd = J.joint_data(log, v, prep)
    st = effect_structure(parse_effects(names or None), v)
    return v, st, prep, jd


def _compiled(v, st, N):
    if compiler() is None:
        pytest.skip("no C compiler: the virtual machine is used, nothing to compare")
    assert load(J._nlp_kernel_functions(v, st), "drivelog_nlp", wait=True).is_c
    assert J.nlp_backend(v, st, N)


@pytest.mark.parametrize("names", [[], ["drivetrain_friction", "grade"]])
def test_compiled_nlp_functions_equal_the_virtual_machine(names):
    # IPOPT's objective, gradient and Hessian of the Lagrangian: bit for bit, padding samples included
    v, st, prep, jd = _problem(names)
    n, N = prep.n_used, 64
    assert n < N
    _compiled(v, st, N)
    vm = J.joint_solver(v, st, N, 500, 1e-9, 0, False)
    cc = J.joint_solver(v, st, N, 500, 1e-9, 0, True)
    pd = vm.size1_in("x0") - N
    rng = np.random.default_rng(2)
    scale = np.concatenate([[300.0, 0.017], np.full(pd - 2, 0.3)])
    i_ref = 0.017 / v.track_length
    p = np.concatenate(
        [scale, [i_ref], J.padded_data(jd.D, N).reshape(-1, order="F"), np.r_[np.zeros(n), np.ones(N - n)]]
    )
    x = np.concatenate([[1.1, 0.8], rng.uniform(-0.1, 0.1, pd - 2), rng.uniform(0.0, 2.0, n), np.zeros(N - n)])
    for name, args in (("nlp_f", (x, p)), ("nlp_grad_f", (x, p)), ("nlp_hess_l", (x, p, 0.7, np.zeros(0)))):
        a, b = vm.get_function(name)(*args), cc.get_function(name)(*args)
        a, b = (list(o) if isinstance(o, (list, tuple)) else [o] for o in (a, b))
        assert len(a) == len(b) >= 1
        for oa, ob in zip(a, b):
            oa, ob = np.asarray(ca.DM(oa).full()), np.asarray(ca.DM(ob).full())
            assert np.all(np.isfinite(oa)) and np.max(np.abs(oa)) > 0
            assert np.array_equal(oa, ob), (name, float(np.max(np.abs(oa - ob))))


def test_compiled_nlp_solve_equals_the_virtual_machine():
    # the same IPOPT run: iterations, optimum and status
    v, st, prep, jd = _problem(["grade"], vehicle="heavy", seconds=3.0, seed=1)
    n = prep.n_used
    N = 192
    assert n <= N and N % J.NLP_CHUNK == 0
    _compiled(v, st, N)
    scale = np.array([0.6 * v.weight, 0.02, 0.05])
    i_ref = 0.02 / v.track_length
    p = np.concatenate(
        [scale, [i_ref], J.padded_data(jd.D, N).reshape(-1, order="F"), np.r_[np.zeros(n), np.ones(N - n)]]
    )
    x0 = np.concatenate([[1.0, 1.0, 0.0], np.clip(prep.slip_measured, 0.0, 0.9) / i_ref, np.zeros(N - n)])
    lo, hi = J.SLIP_BOUNDS
    lbx = np.concatenate([[0.05, 0.3, -1.0], np.full(N, lo / i_ref)])
    ubx = np.concatenate([[3.0, 2.5, 1.0], np.full(N, hi / i_ref)])
    out = []
    for compiled in (False, True):
        solver = J.joint_solver(v, st, N, 500, 1e-9, 0, compiled)
        sol = solver(x0=x0, p=p, lbx=lbx, ubx=ubx)
        stats = solver.stats()
        out.append((np.asarray(sol["x"]).ravel(), stats["iter_count"], stats["return_status"]))
    (xa, ia, sa), (xb, ib, sb) = out
    assert sa == sb == "Solve_Succeeded"
    assert ia == ib and ia > 1
    assert np.array_equal(xa, xb)


@pytest.mark.parametrize("compiled", [False, True])
def test_profiled_sums_equal_casadis_summing_map(compiled):
    # the profiled start's sums (chunked kernel, per-sample outputs summed in numpy) are CasADi's summing
    # map's numbers exactly, from the virtual machine and from C
    from soiltrack.identify.drivelog import lm_start as L

    v, st, prep, jd = _problem(["grade", "drivetrain_friction"], vehicle="heavy", seconds=3.0, seed=2)
    n = prep.n_used
    assert n % J.SLIP_CHUNK != 0  # padded
    f1 = L._sums_function(v, st)
    if compiled:
        if compiler() is None:
            pytest.skip("no C compiler: the virtual machine is used, nothing to compare")
        assert load([f1.map(J.SLIP_CHUNK)], "drivelog_sums", wait=True).is_c
    sums = L._Sums(v, st, jd.D)
    if compiled:
        assert L._sums_kernels(v, st).is_c
    else:  # the virtual machine's chunked map, whatever the cache holds
        sums.fn = f1.map(J.SLIP_CHUNK)
    rng = np.random.default_rng(5)
    th = np.array([0.5 * v.weight, 0.015, 0.02, 150.0, 0.5])
    slip = np.clip(prep.slip_measured + rng.normal(0, 0.01, n), -0.5, 0.9)
    ref = f1.map("ref_sums", "serial", n, [], [0, 1, 2, 3])(th.reshape(-1, 1), slip.reshape(1, -1), jd.D)
    got = sums(th, slip)
    for a, b in zip(ref, got):
        a = np.asarray(ca.DM(a).full())
        b = np.atleast_2d(np.asarray(b, dtype=float)).reshape(a.shape)
        assert np.all(np.isfinite(a)) and np.max(np.abs(a)) > 0
        assert np.array_equal(a, b), float(np.max(np.abs(a - b)))


@pytest.mark.parametrize("compiled", [False, True])
def test_sample_outputs_equal_the_map(compiled, monkeypatch):
    # residuals, derivatives and sensitivities over the samples (chunked kernels, padded) are fn.map(n)'s
    # numbers exactly, from the virtual machine and from C
    v, st, prep, jd = _problem(["grade", "radius_error"], vehicle="light", seconds=3.0, seed=4)
    n = prep.n_used
    assert n % J.SLIP_CHUNK != 0
    fns = (J.residual_function(v, st)[0], J.derivative_function(v, st), J.sensitivity_function(v, st))
    if compiled:
        if compiler() is None:
            pytest.skip("no C compiler: the virtual machine is used, nothing to compare")
        assert load([J._dense_outputs(f).map(J.SLIP_CHUNK) for f in fns], "drivelog_samples", wait=True).is_c
    kernels = J._sample_kernels(v, st)
    kernels.upgrade()
    if compiled:
        assert kernels.is_c
    else:  # the virtual machine's chunked maps, whatever the cache holds
        kernels = type(kernels)(kernels.names, [J._dense_outputs(f).map(J.SLIP_CHUNK) for f in fns], kernels.backend)
    th = np.array([300.0, 0.02, 0.03, 0.01])
    rng = np.random.default_rng(6)
    slip = np.clip(prep.slip_measured + rng.normal(0, 0.01, n), -0.5, 0.9)
    monkeypatch.setattr(J, "_sample_kernels", lambda vehicle, structure: kernels)
    for which, fn in zip(J.SAMPLE_FUNCTIONS, fns):
        ref = fn.map(n)(np.repeat(th.reshape(-1, 1), n, axis=1), slip.reshape(1, -1), jd.D)
        got = J.sample_outputs(v, st, which, th, slip, jd.D)
        assert len(got) == fn.n_out()
        for a, b in zip(ref, got):
            a = np.asarray(ca.DM(a).full())
            assert a.shape == b.shape and np.max(np.abs(a)) > 0
            assert np.array_equal(a, b, equal_nan=True), (which, float(np.nanmax(np.abs(a - b))))


@pytest.mark.parametrize("names", [["grade"], ["slip_sinkage", "drivetrain_friction"]])
def test_merged_subexpressions_give_the_same_numbers(names):
    # the virtual machine's copies of the slip step and the profiled sums (ca.cse) compute each value once:
    # fewer instructions, the same outputs bit for bit
    from soiltrack.identify.drivelog import lm_start as L

    v, st, prep, jd = _problem(names, vehicle="heavy", seconds=3.0, seed=2)
    n = prep.n_used
    rng = np.random.default_rng(7)
    th = np.r_[[0.5 * v.weight, 0.015], rng.uniform(0.0, 0.05, J.residual_function(v, st)[0].size1_in(0) - 2)]
    slip = np.clip(prep.slip_measured + rng.normal(0, 0.02, n), -0.5, 0.9).reshape(1, -1)
    for f in (J._slip_step_function(v, st), L._sums_function(v, st)):
        g = J.cse_function(f)
        assert g.n_instructions() < f.n_instructions()
        a, b = f.map(n)(th.reshape(-1, 1), slip, jd.D), g.map(n)(th.reshape(-1, 1), slip, jd.D)
        for x, y in zip(a, b):
            x, y = np.asarray(ca.DM(x).full()), np.asarray(ca.DM(y).full())
            assert np.max(np.abs(x[np.isfinite(x)])) > 0
            assert np.array_equal(x, y, equal_nan=True)
