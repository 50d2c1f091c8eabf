"""The profiled start of the joint drive-log fit (identify/drivelog_profiled.py).

The profiled cost ``phi(theta) = sum_k min_i |e_k(theta, i)|^2 / 2`` has the gradient and Hessian
the module assembles from CasADi's per-sample derivatives; the start only moves IPOPT's starting
point, never its optimum.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from soiltrack.identify.drivelog.joint import SlipSolver, effect_layout, joint_data, residual_function
from soiltrack.identify.drivelog.prepare import prepare_drive_log
from soiltrack.identify.drivelog.lm_start import _Sums, profiled_start
from soiltrack.identify.fitting import fit
from soiltrack.soilmodel import TERRAINS, VEHICLES
from soiltrack.soilmodel.effects import effect_structure, parse_effects
from soiltrack.soilmodel.simulation import simulate_drive_log

HEAVY = VEHICLES["heavy"]


@pytest.fixture(scope="module")
def grade_log():
    return simulate_drive_log(
        HEAVY, TERRAINS["lete_sand"], seed=2, effects={"grade": math.radians(2.0)}, duration_s=30.0
    )


def _problem(log, names):
    prep = prepare_drive_log(log, HEAVY)
    jd = joint_data(log, HEAVY, prep)
    st = effect_structure(parse_effects(names), HEAVY)
    return prep, jd, st


def test_profiled_gradient_and_hessian_match_finite_differences(grade_log):
    """Gradient and Schur-complement Hessian of the profiled cost against central differences of the
    profiled cost itself (slips re-solved at every perturbed theta)."""
    prep, jd, st = _problem(grade_log, ["grade"])
    slips = SlipSolver(HEAVY, st, jd.D)
    sums = _Sums(HEAVY, st, jd.D)
    theta = np.array([1.1 * float(np.max(prep.thrust)), 0.02, 0.02])
    starts = [np.clip(prep.slip_measured, -0.9, 0.9)]

    def phi(th):
        s = slips.best(th, starts)
        return float(np.sum(slips.costs(th, s))), s

    c0, s0 = phi(theta)
    c, g, Hr, _ = sums(theta, s0)
    assert c == pytest.approx(c0, rel=1e-12)
    h = np.array([theta[0] * 1e-5, theta[1] * 1e-5, 1e-6])
    gfd = np.array(
        [(phi(theta + h[j] * np.eye(3)[j])[0] - phi(theta - h[j] * np.eye(3)[j])[0]) / (2 * h[j]) for j in range(3)]
    )
    assert np.allclose(g, gfd, rtol=1e-4, atol=1e-6 * np.max(np.abs(gfd))), (g, gfd)
    Hfd = np.column_stack(
        [
            (
                sums(theta + h[j] * np.eye(3)[j], phi(theta + h[j] * np.eye(3)[j])[1])[1]
                - sums(theta - h[j] * np.eye(3)[j], phi(theta - h[j] * np.eye(3)[j])[1])[1]
            )
            / (2 * h[j])
            for j in range(3)
        ]
    )
    scale = np.sqrt(np.outer(np.diag(np.abs(Hfd)), np.diag(np.abs(Hfd))))
    assert np.all(np.abs(Hr - Hfd) <= 1e-3 * scale + 1e-9 * np.max(scale)), (Hr, Hfd)


def test_profiled_start_lowers_the_cost_and_respects_bounds(grade_log):
    prep, jd, st = _problem(grade_log, ["grade"])
    labels = list(residual_function(HEAVY, st)[1])
    elo, ehi, esc = effect_layout(labels, HEAVY)
    lo = np.concatenate([[1e3, 0.006], elo])
    hi = np.concatenate([[5e5, 0.05], ehi])
    scale = np.concatenate([[1e5, 0.017], esc])
    th0 = np.array([1.2 * float(np.max(prep.thrust)), 0.049, 0.0])
    starts = [np.clip(prep.slip_measured, -0.9, 0.9)]
    slips = SlipSolver(HEAVY, st, jd.D)
    c0 = float(np.sum(slips.costs(th0, slips.best(th0, starts))))
    ps = profiled_start(HEAVY, st, jd.D, th0, lo, hi, scale, starts)
    assert ps.converged and ps.iterations > 0
    assert ps.cost < 0.5 * c0
    assert np.all(ps.theta >= lo) and np.all(ps.theta <= hi)
    assert ps.cost == pytest.approx(float(np.sum(slips.costs(ps.theta, ps.slip))), rel=1e-12)
    # the grade it finds is the simulated one (2 deg), roughly: it is a start, IPOPT polishes
    assert abs(ps.theta[2] - math.radians(2.0)) < 0.3 * math.radians(2.0), ps.theta


@pytest.mark.parametrize("names", [["grade"], ["drivetrain_friction"]])
@pytest.mark.slow
def test_profiled_start_changes_the_start_not_the_optimum(grade_log, names):
    """IPOPT from the profiled start and from the plain start (nominal soil, effect off) end at the same
    optimum; the fit reports the profiled iterations it took."""
    a = fit(grade_log, HEAVY, effects=names)
    b = fit(grade_log, HEAVY, effects=names, _plain_start=True)
    assert a.success and b.success, (a.message, b.message)
    assert "profiled_start" in a.extra and "profiled_start" not in b.extra
    assert all(p["converged"] for p in a.extra["profiled_start"]["steps"])
    assert a.cost == pytest.approx(b.cost, rel=1e-8)
    ja, jb = a.extra["joint_parameters"], b.extra["joint_parameters"]
    assert ja["shear_modulus_m"] == pytest.approx(jb["shear_modulus_m"], rel=1e-4)
    for k, v in ja["effects"].items():
        assert v == pytest.approx(jb["effects"][k], rel=1e-4, abs=1e-9), k


def test_profiled_start_returns_the_start_when_the_cost_is_not_finite(grade_log):
    prep, jd, st = _problem(grade_log, ["grade"])
    D = jd.D.copy()
    D[0, 5] = np.nan  # one sample's speed
    th0 = np.array([1.2 * float(np.max(prep.thrust)), 0.02, 0.0])
    lo, hi = np.array([1e3, 0.006, -0.5]), np.array([5e5, 0.05, 0.5])
    ps = profiled_start(
        HEAVY, st, D, th0, lo, hi, np.array([1e5, 0.017, 0.05]), [np.clip(prep.slip_measured, -0.9, 0.9)]
    )
    assert not ps.converged and ps.iterations == 0
    assert np.array_equal(ps.theta, th0)


@pytest.mark.slow
def test_the_plain_starts_run_when_ipopt_cannot_certify_the_profiled_start(grade_log, monkeypatch):
    """IPOPT's status from the profiled start is the fit's only if it converged; otherwise the plain starts run
    and the status from the profiled start is reported beside the fit's own."""
    import soiltrack.identify.drivelog.nlp as nlp

    real = nlp.call_solver
    calls = []

    def first_fails(solver, *a, **k):
        out, st = real(solver, *a, **k)
        calls.append(st.get("return_status"))
        if len(calls) == 1:  # the first run, from the profiled start: reported as not converged
            st = dict(st, success=False, return_status="Search_Direction_Becomes_Too_Small")
        return out, st

    monkeypatch.setattr(nlp, "call_solver", first_fails)
    r = fit(grade_log, HEAVY, effects=["grade"], multistart=False, torque_hold="zoh")
    assert r.success and r.status == "Solve_Succeeded"
    assert len(calls) == 2  # the profiled start, then the plain start
    assert r.extra["profiled_start"]["ipopt_status_from_it"] == "Search_Direction_Becomes_Too_Small"
    ref = fit(grade_log, HEAVY, effects=["grade"], multistart=False, torque_hold="zoh")
    assert r.cost == pytest.approx(ref.cost, rel=1e-8)
