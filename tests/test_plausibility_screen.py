"""The compiled engine's screen of the plausibility checks never hides a finding, and lets clean fits skip them."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from soiltrack.identify.sweep import compiled_lm
from soiltrack.identify.sweep import problem
from soiltrack.identify.sweep.plausibility import (
    _limit_on_bound,
    assess,
    check_slip_data,
    check_slip_fit,
    corner_soils,
    limit_screen_expr,
    screen_expr,
)
from soiltrack.soilmodel import PRACTICAL_BOUNDS, VEHICLES, SlipData, Soil, tractive_force

HEAVY = VEHICLES["heavy"]
THETA_MID = np.array([0.0, 0.5 * sum(PRACTICAL_BOUNDS.friction_angle), 0.5 * sum(PRACTICAL_BOUNDS.shear_modulus)])


def _screen_function(n: int) -> ca.Function:
    rows = [ca.MX.sym(k, 1, n) for k in ("slip", "F", "r", "weak", "strong", "real")]
    return ca.Function("screen", rows, [screen_expr(*rows)])


def _screen(slip, force, r, lo, hi, real=None) -> float:
    n = len(slip)
    real = np.ones(n) if real is None else real
    return float(_screen_function(n)(*(np.asarray(a, float).reshape(1, -1) for a in (slip, force, r, lo, hi, real))))


def _findings(slip, force, r, lo, hi):
    """Everything but F_max on a bound (theta in the middle of the bounds: that check has nothing to say)."""
    load = np.full(len(slip), HEAVY.weight)
    found = check_slip_data(slip, force, load, HEAVY, "cohesion-free", PRACTICAL_BOUNDS, curves=(lo, hi))
    found += check_slip_fit(slip, force, load, r, THETA_MID, HEAVY, "cohesion-free", PRACTICAL_BOUNDS)
    return [f.code for f in found if f.code != "limit_on_bound"]


@st.composite
def rows(draw):
    n = draw(st.integers(2, 24))
    fl = lambda a, b: st.floats(a, b, allow_nan=False, allow_infinity=False)  # noqa: E731
    slip = np.array(draw(st.lists(fl(-0.05, 0.8), min_size=n, max_size=n)))
    lo = np.array(draw(st.lists(fl(1.0, 1e5), min_size=n, max_size=n)))
    hi = lo * np.array(draw(st.lists(fl(1.0, 60.0), min_size=n, max_size=n)))
    # forces from well below the weakest soil / 5 to well above 5 x the strongest, some negative
    force = lo * np.array(draw(st.lists(fl(-0.5, 400.0), min_size=n, max_size=n)))
    noise = draw(st.sampled_from([0.0, 1e-3, 0.01, 0.05, 0.3]))
    r = force * noise * np.array(draw(st.lists(fl(-1.0, 1.0), min_size=n, max_size=n)))
    if draw(st.booleans()):  # one wild row, off by a share of the force scale around the outlier thresholds
        k = draw(st.integers(0, n - 1))
        r[k] += draw(fl(-0.4, 0.4)) * float(np.quantile(np.abs(force), 0.9))
    return slip, force, r, lo, hi


@settings(max_examples=300, deadline=None)
@given(rows())
@pytest.mark.slow
def test_screen_is_open_whenever_a_check_finds_something(case):
    slip, force, r, lo, hi = case
    found = _findings(slip, force, r, lo, hi)
    if found:
        assert _screen(slip, force, r, lo, hi) == 1.0, found


def test_screen_opens_on_each_kind_of_finding_and_on_nan():
    slip = np.linspace(0.02, 0.4, 20)
    lo, hi = np.full(20, 1e3), np.full(20, 1e5)
    force = np.full(20, 2e4) * (1 + 0.01 * np.sin(np.arange(20)))
    r = 100.0 * np.cos(np.arange(20))
    assert _findings(slip, force, r, lo, hi) == [] and _screen(slip, force, r, lo, hi) == 0.0
    cases = {
        "force_scale_low": (force / 1000, r / 1000),
        "negative_thrust": (np.r_[-5.0, force[1:]], r),
        "force_above_any_soil": (np.r_[force[:-1], 1e6], r),
        "residuals_large": (force, 0.9 * force),
        "outlier": (force, np.r_[r[:-1], 1e4]),
    }
    for code, (F, rr) in cases.items():
        assert code in _findings(slip, F, rr, lo, hi), code
        assert _screen(slip, F, rr, lo, hi) == 1.0, code
    assert _screen(slip, force, np.r_[r[:-1], math.nan], lo, hi) == 1.0


def test_padding_rows_do_not_count():
    slip = np.linspace(0.02, 0.4, 10)
    lo, hi, force, r = np.full(10, 1e3), np.full(10, 1e5), np.full(10, 2e4), np.full(10, 50.0) * (-1) ** np.arange(10)
    pad = lambda a, v: np.r_[a, np.full(6, v)]  # noqa: E731
    s = _screen(pad(slip, 0.0), pad(force, -1e9), pad(r, 1e9), pad(lo, 0.0), pad(hi, 0.0), pad(np.ones(10), 0.0))
    assert s == _screen(slip, force, r, lo, hi) == 0.0


@pytest.mark.parametrize("n", [3, 40, 100])
def test_clean_fit_passes_the_screen_and_gives_the_same_result_as_the_full_checks(n):
    i = np.linspace(0.01, 0.4, n)
    F = np.asarray(tractive_force(i, Soil.from_kpa_deg(0.0, 30.0, 0.02), HEAVY, model="cohesion-free")).ravel()
    F = F * (1 + 0.01 * np.cos(7 * np.arange(n)))
    pb = problem.make_problem(SlipData(i, F), HEAVY, "cohesion-free", PRACTICAL_BOUNDS)
    sol = compiled_lm.solve(pb)
    assert sol.certified and sol.screen == 0.0
    args = (pb.slip, pb.force, pb.load, sol.residuals, sol.theta, HEAVY, pb.model, pb.bounds, sol.curves)
    assert assess(*args, sol.screen) == assess(*args)


def test_screen_counts_exactly_enough_rows_for_the_force_scale():
    """n = 10: the 90th percentile of |F| lies between the two largest; one row off by 11 % of it is an outlier."""
    slip = np.linspace(0.05, 0.5, 10)
    force = np.r_[np.full(8, 100.0), 1e4, 2e4]  # 90th percentile 11,000 N
    r = np.r_[1.0 * (-1) ** np.arange(9), 1200.0]
    lo, hi = np.full(10, 100.0), np.full(10, 1e5)
    assert "outlier" in _findings(slip, force, r, lo, hi)
    assert _screen(slip, force, r, lo, hi) == 1.0


# ---- the Breusch-Pagan screen (noise growing with the force) ----------------------------------------------
def _bp_screen(force, r, real=None) -> float:
    n = len(force)
    rows = [ca.MX.sym(k, 1, n) for k in ("F", "r", "real")]
    f = ca.Function("bp", rows, [problem.heteroscedasticity_screen_expr(*rows)])
    real = np.ones(n) if real is None else real
    return float(f(*(np.asarray(a, float).reshape(1, -1) for a in (force, r, real))))


@st.composite
def noise_cases(draw):
    n = draw(st.integers(2, 60))
    fl = lambda a, b: st.floats(a, b, allow_nan=False, allow_infinity=False)  # noqa: E731
    force = np.array(draw(st.lists(fl(-1e3, 1e6), min_size=n, max_size=n)))
    base = draw(st.sampled_from([0.0, 1.0, 100.0]))
    grow = draw(st.sampled_from([0.0, 1e-3, 0.01, 0.1]))  # spread growing with the force
    z = np.array(draw(st.lists(fl(-3.0, 3.0), min_size=n, max_size=n)))
    return force, (base + grow * np.abs(force)) * z


@settings(max_examples=300, deadline=None)
@given(noise_cases())
@pytest.mark.slow
def test_bp_screen_is_open_whenever_the_statistic_warns(case):
    force, r = case
    stat = float(problem.heteroscedasticity(force, r, np.ones(force.size)))
    if np.isfinite(stat) and stat > problem.BP_CRITICAL:
        assert _bp_screen(force, r) == 1.0, stat


def test_bp_screen_closes_on_constant_noise_and_opens_on_growing_noise_and_ignores_padding():
    rng = np.random.default_rng(5)
    force = np.linspace(1e3, 1e5, 80)
    r_const, r_grow = rng.normal(0, 300, 80), rng.normal(0, 1, 80) * 0.02 * force
    assert float(problem.heteroscedasticity(force, r_const, np.ones(80))) < problem.BP_CRITICAL
    assert _bp_screen(force, r_const) == 0.0
    assert float(problem.heteroscedasticity(force, r_grow, np.ones(80))) > problem.BP_CRITICAL
    assert _bp_screen(force, r_grow) == 1.0
    pad = lambda a, v: np.r_[a, np.full(8, v)]  # noqa: E731
    assert _bp_screen(pad(force, 0.0), pad(r_const, 1e9), pad(np.ones(80), 0.0)) == 0.0


def test_fit_gives_the_same_noise_warning_with_and_without_the_screen():
    rng = np.random.default_rng(2)
    i = np.geomspace(0.0005, 0.4, 100)
    F = np.asarray(tractive_force(i, Soil.from_kpa_deg(0.0, 30.0, 0.02), HEAVY, model="cohesion-free")).ravel()
    for noisy in (F + rng.normal(0, 200, 100), F * (1 + rng.normal(0, 0.03, 100))):
        pb = problem.make_problem(SlipData(i, noisy), HEAVY, "cohesion-free", PRACTICAL_BOUNDS)
        sol = compiled_lm.solve(pb)
        assert sol.certified
        assert pb.noise_warning(sol.residuals, sol.bp_screen) == pb.noise_warning(sol.residuals)
    assert sol.bp_screen == 1.0 and pb.noise_warning(sol.residuals)  # the growing noise is warned about


# ---- the screen of F_max on a bound ---------------------------------------------------------------------------
def _limit_screen(theta, load, model, bounds=PRACTICAL_BOUNDS, real=None) -> float:
    n = len(load)
    c, phi = ca.MX.sym("c"), ca.MX.sym("phi")
    W, rl = ca.MX.sym("W", 1, n), ca.MX.sym("real", 1, n)
    weak, strong = corner_soils(bounds, model)
    f = ca.Function(
        "limit", [c, phi, W, rl], [limit_screen_expr(c, phi, W, weak, strong, HEAVY.contact_area, model, rl)]
    )
    real = np.ones(n) if real is None else real
    return float(f(theta[0], theta[1], np.asarray(load, float).reshape(1, -1), np.asarray(real, float).reshape(1, -1)))


@st.composite
def limit_cases(draw):
    model = draw(st.sampled_from(["full", "cohesion-free"]))
    n = draw(st.integers(1, 12))
    loads = draw(st.lists(st.sampled_from([1e5, 2.5e5, 329e3, 4e5]), min_size=n, max_size=n))
    (c_lo, c_hi), (p_lo, p_hi) = PRACTICAL_BOUNDS.cohesion, PRACTICAL_BOUNDS.friction_angle
    # c, phi on, just inside and just outside the edges of the band at each end, or anywhere in between
    rel = st.sampled_from([0.0, 1e-12, 1e-6, 1e-4, 9e-4, 1e-3, 1.1e-3, 0.01])
    u = draw(st.one_of(rel, rel.map(lambda t: 1.0 - t), st.floats(0.0, 1.0)))
    v = draw(st.one_of(st.just(u), rel, rel.map(lambda t: 1.0 - t), st.floats(0.0, 1.0)))
    c = 0.0 if model == "cohesion-free" else c_lo + u * (c_hi - c_lo)
    phi = p_lo + v * (p_hi - p_lo)
    return model, np.array(loads), np.array([c, phi, 0.02])


@settings(max_examples=400, deadline=None)
@given(limit_cases())
@pytest.mark.slow
def test_limit_screen_is_open_whenever_fmax_on_a_bound_is_found(case):
    model, load, theta = case
    force = np.full(load.size, 1e5)
    found = _limit_on_bound(force, load, np.zeros(load.size), *theta, HEAVY, model, PRACTICAL_BOUNDS)
    if found:
        assert _limit_screen(theta, load, model) == 1.0, [f.message for f in found]


def test_limit_screen_closes_inside_opens_on_the_bounds_and_on_nan_and_ignores_padding():
    W = np.full(5, HEAVY.weight)
    p_lo, p_hi = PRACTICAL_BOUNDS.friction_angle
    mid = np.array([0.0, 0.5 * (p_lo + p_hi), 0.02])
    assert _limit_screen(mid, W, "cohesion-free") == 0.0
    assert _limit_screen(np.array([0.0, p_lo, 0.02]), W, "cohesion-free") == 1.0
    assert _limit_screen(np.array([0.0, p_hi, 0.02]), W, "cohesion-free") == 1.0
    assert _limit_screen(np.array([0.0, math.nan, 0.02]), W, "cohesion-free") == 1.0
    pad = np.r_[W, np.full(3, 1e-30)]
    assert _limit_screen(mid, pad, "cohesion-free", real=np.r_[np.ones(5), np.zeros(3)]) == 0.0


def test_fit_on_a_bound_gives_the_same_result_with_and_without_the_limit_screen():
    i = np.linspace(0.01, 0.3, 30)
    for soil in (Soil.from_kpa_deg(0.0, 45.0, 0.02), Soil.from_kpa_deg(0.0, 30.0, 0.02)):
        F = np.asarray(tractive_force(i, soil, HEAVY, model="cohesion-free")).ravel()
        pb = problem.make_problem(SlipData(i, F), HEAVY, "cohesion-free", PRACTICAL_BOUNDS)
        sol = compiled_lm.solve(pb)
        assert sol.certified
        args = (pb.slip, pb.force, pb.load, sol.residuals, sol.theta, HEAVY, pb.model, pb.bounds, sol.curves)
        assert assess(*args, sol.screen, sol.limit_screen) == assess(*args, sol.screen) == assess(*args)
        assert assess(*args, 0.0, sol.limit_screen) == assess(*args, 0.0)
        assert sol.limit_screen == (1.0 if soil.friction_angle > PRACTICAL_BOUNDS.friction_angle[1] else 0.0)
