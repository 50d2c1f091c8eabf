"""Traversability margins: hand calculations on the presets, Fig. 7, uncertainty from a fit."""

import dataclasses
import json
import math

import numpy as np
import pytest

from soiltrack.identify import fit
from soiltrack.planning import load_fit_json, margin, uncertainty_from_fit
from soiltrack.soilmodel import TERRAINS, VEHICLES, DataError, Soil, simulate_slip_sweep

G = 9.81
HEAVY = VEHICLES["heavy"]
#: The seed's Fig. 7 vehicle: 120 kN of drivetrain thrust (torque limit 36 kN m at r = 0.3 m).
V120 = dataclasses.replace(HEAVY, max_sprocket_torque=36_000.0, max_power=None)


def hand_soil_thrust(soil, veh, N, i):
    """Eq. 2 written out independently of the library."""
    A = 2 * veh.track_width * veh.track_length
    x = i * veh.track_length / soil.shear_modulus
    return (A * soil.cohesion + N * math.tan(soil.friction_angle)) * (1 - (1 - math.exp(-x)) / x)


def hand_compaction(soil, veh, N):
    b, l = veh.track_width, veh.track_length
    k = soil.k_c / b + soil.k_phi
    z0 = (N / (2 * b * l) / k) ** (1 / soil.n)
    return 2 * b * k * z0 ** (soil.n + 1) / (soil.n + 1)


def hand_margin(soil, veh, grade_deg, i_max=0.2, drivetrain=120e3):
    th = math.radians(grade_deg)
    W = veh.mass * G
    N = W * math.cos(th)
    req = veh.rolling_resistance * N + hand_compaction(soil, veh, N) + W * math.sin(th)
    avail = min(hand_soil_thrust(soil, veh, N, i_max), drivetrain)
    return avail, req


@pytest.mark.parametrize(
    "name,grade,go",
    [("dry_sand", 0, True), ("clayey_soil", 0, True), ("dry_sand", 15, True), ("clayey_soil", 15, False)],
)
def test_fig7_margins_match_hand_calculation(name, grade, go):
    soil = TERRAINS[name]
    m = margin(soil, V120, grade_deg=grade)
    avail, req = hand_margin(soil, V120, grade)
    assert m.available_N == pytest.approx(avail, rel=1e-9)
    assert m.required_N == pytest.approx(req, rel=1e-9)
    assert m.margin_N == pytest.approx(avail - req, rel=1e-9)
    assert m.traversable is go
    assert sum(m.required.values()) == pytest.approx(m.required_N, rel=1e-12)
    assert m.required["grade_N"] == pytest.approx(V120.mass * G * math.sin(math.radians(grade)), rel=1e-12)
    # docs/paper.md (Fig. 7): about 101 kN required on 15 deg before compaction
    if grade == 15:
        assert m.required_N - m.required["compaction_N"] == pytest.approx(101e3, rel=0.01)
    assert m.limited_by == ("drivetrain" if name == "dry_sand" else "soil")


def test_slip_required_delivers_the_required_thrust_and_gradeability_is_the_zero_of_the_margin():
    soil = TERRAINS["dry_sand"]
    m = margin(soil, V120, grade_deg=10, accel=0.2, drawbar_N=5e3)
    assert m.traversable
    assert hand_soil_thrust(soil, V120, m.normal_load_N, m.slip_required) == pytest.approx(m.required_N, rel=1e-9)
    g = m.max_grade_deg
    at = margin(soil, V120, grade_deg=g, accel=0.2, drawbar_N=5e3)
    assert abs(at.margin_N) < 1.0  # N, out of ~100 kN
    assert margin(soil, V120, grade_deg=g + 0.1, accel=0.2, drawbar_N=5e3).margin_N < 0
    assert margin(TERRAINS["clayey_soil"], V120, grade_deg=15).slip_required is None


def test_power_limit_at_speed_and_missing_limits():
    soil = TERRAINS["lete_sand"]
    m = margin(soil, HEAVY, speed=5.0)
    assert m.drivetrain_limit_N == pytest.approx(min(80e3 / 0.3, 600e3 / 5.0))
    assert m.limited_by == "drivetrain"
    bare = dataclasses.replace(HEAVY, max_sprocket_torque=None, max_power=None)
    m2 = margin(soil, bare)
    assert m2.drivetrain_limit_N is None and m2.limited_by == "soil"
    assert json.dumps(m2.to_dict(), allow_nan=False)


@pytest.mark.parametrize(
    "kw", [dict(max_slip=1.5), dict(max_slip=0.0), dict(grade_deg=80.0), dict(accel=float("nan")), dict(speed=-1.0)]
)
def test_bad_arguments_are_named(kw):
    with pytest.raises(DataError) as e:
        margin(TERRAINS["dry_sand"], HEAVY, **kw)
    assert list(kw)[0] in str(e.value)


# --- with a fit --------------------------------------------------------------------------------
TRUE = Soil.from_kpa_deg(1.3, 31.1, 0.012)


@pytest.fixture(scope="module")
def fits():
    data = simulate_slip_sweep(HEAVY, TRUE, seed=3)
    return {m: fit(data, HEAVY, model=m) for m in ("full", "cohesion-free")}


def test_ridge_margin_at_the_fitted_load_uses_fmax_only(fits):
    f = fits["full"]
    u = uncertainty_from_fit(f)
    assert u.kind == "ridge"
    fm = next(c for c in f.combinations if c.name.startswith("F_max@"))
    K = next(c for c in f.combinations if c.name == "K").value
    m = margin(f, HEAVY)
    x = 0.2 * HEAVY.track_length / K
    assert m.soil_limit_N == pytest.approx(fm.value * (1 - (1 - math.exp(-x)) / x), rel=1e-9)
    assert "depends on F_max only" in m.uncertainty


def test_ridge_margin_on_a_grade_is_the_worst_point_of_the_ridge(fits):
    f = fits["full"]
    fm = next(c for c in f.combinations if c.name.startswith("F_max@")).value
    K = next(c for c in f.combinations if c.name == "K").value
    W0, A = HEAVY.weight, HEAVY.contact_area
    m = margin(f, HEAVY, grade_deg=20)
    # every point of the ridge A c + W0 tan(phi) = F_max inside the bounds gives at least this thrust
    lo, hi = f.bounds.lower, f.bounds.upper
    phis = np.linspace(lo[1], hi[1], 200)
    cs = (fm - W0 * np.tan(phis)) / A
    ok = (cs >= lo[0]) & (cs <= hi[0])
    assert ok.sum() > 10
    thrusts = [hand_soil_thrust(Soil(c, p, K), HEAVY, m.normal_load_N, 0.2) for c, p in zip(cs[ok], phis[ok])]
    assert m.soil_limit_N <= min(thrusts) + 1e-6 * m.soil_limit_N
    assert m.soil_limit_N == pytest.approx(min(thrusts), rel=1e-3)
    assert "worst case over the ridge" in m.uncertainty


@pytest.mark.parametrize("model", ["full", "cohesion-free"])
def test_delta_method_agrees_with_monte_carlo_and_p_crosses_one_half_at_the_margin_sign_change(fits, model):
    f = fits[model]
    base = margin(f, HEAVY, grade_deg=5)
    # drawbar pulls that put the margin at -1.5, -0.5, +0.5, +1.5 standard deviations of the soil limit
    spread = (base.margin_N - base.worst_case_margin_N) / math.sqrt(5.991)  # ~ one sd, from the 95 % worst case
    assert spread > 0
    ps = []
    for k in (-1.5, -0.5, 0.5, 1.5):
        m = margin(f, HEAVY, grade_deg=5, drawbar_N=base.margin_N - k * spread)
        assert abs(m.p_traversable_delta - m.p_traversable_mc) <= 0.02
        assert (m.margin_N >= 0) == (k >= 0)
        assert (m.p_traversable > 0.5) == (m.margin_N > 0)
        ps.append(m.p_traversable)
    assert ps == sorted(ps)


def test_fit_json_without_covariance_is_rebuilt_and_agrees_with_the_fit(fits, tmp_path):
    f = fits["cohesion-free"]
    path = tmp_path / "fit.json"
    path.write_text(f.to_json())
    u = load_fit_json(str(path), HEAVY)
    assert "rebuilt" in u.source or "covariance matrix" in u.source
    a = margin(f, HEAVY, grade_deg=5)
    b = margin(u, HEAVY, grade_deg=5)
    assert b.margin_N == pytest.approx(a.margin_N, rel=1e-9)
    assert b.p_traversable_delta == pytest.approx(a.p_traversable_delta, abs=1e-6)
    bad = tmp_path / "bad.json"
    bad.write_text('{"model": "full", "success": true}')
    with pytest.raises(DataError, match="parameters"):
        load_fit_json(str(bad), HEAVY)


def test_fig7_example_writes_the_figure_with_the_consistent_reading(tmp_path):
    import importlib.util
    import os

    path = os.path.join(
        os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "examples", "fig7_traversability.py"
    )
    spec = importlib.util.spec_from_file_location("fig7_example", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    seed, margins = mod.compute()
    assert seed["dry_sand"] == pytest.approx(2.8 * 1.04e3 + 329e3 * math.tan(math.radians(28)), rel=1e-6)
    assert seed["clayey_soil"] == pytest.approx(2.8 * 4.14e3 + 329e3 * math.tan(math.radians(13)), rel=1e-6)
    go = {k: m.traversable for k, m in margins.items()}
    assert go == {
        ("dry_sand", 0.0): True,
        ("clayey_soil", 0.0): True,
        ("dry_sand", 15.0): True,
        ("clayey_soil", 15.0): False,
    }
    out = tmp_path / "fig7.png"
    assert mod.main(["--out", str(out)]) == 0 and out.stat().st_size > 10_000


def test_fit_json_covariance_block_is_used_when_present(fits, tmp_path):
    f = fits["cohesion-free"]
    obj = json.loads(f.to_json())
    obj["covariance"] = {
        "parameters": ["cohesion", "friction_angle", "shear_modulus"],
        "matrix": np.asarray(f.covariance).tolist(),
        "units": "SI",
    }
    path = tmp_path / "fit_cov.json"
    path.write_text(json.dumps(obj))
    u = load_fit_json(str(path), HEAVY)
    assert u.source == "covariance matrix of the fit JSON"
    np.testing.assert_allclose(u.cov, np.asarray(f.covariance)[1:, 1:], rtol=1e-12)
    assert margin(u, HEAVY, grade_deg=5).p_traversable_delta == pytest.approx(
        margin(f, HEAVY, grade_deg=5).p_traversable_delta, abs=1e-9
    )


def test_margin_takes_a_fit_with_effects_and_plans_with_its_soil_block():
    """A FitResult with an effect (covariance 4 x 4) gives the soil's marginal uncertainty (was a ValueError)."""
    from soiltrack.identify import fit
    from soiltrack.planning import margin
    from soiltrack.planning.uncertainty import uncertainty_from_fit
    from soiltrack.soilmodel import TERRAINS, VEHICLES, simulate_slip_sweep

    light = VEHICLES["light"]
    data = simulate_slip_sweep(
        light, TERRAINS["sandy_loam"], normal_loads=(300.0, 450.0), seed=1, effects={"slip_sinkage": 0.1}
    )
    res = fit(data, light, effects=["slip_sinkage"])
    assert res.success and np.asarray(res.covariance).shape == (4, 4)
    u = uncertainty_from_fit(res)
    assert u.cov.shape == (3, 3)
    assert np.allclose(u.cov, np.asarray(res.covariance)[:3, :3])
    m = margin(res, light, grade_deg=10)
    assert m.p_traversable is not None and 0.0 <= m.p_traversable <= 1.0
