"""Turns in planning: p_turn_feasible from the soil's uncertainty; ROUTE.json patches with radius_m."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from soiltrack.cli import main
from soiltrack.identify import fit
from soiltrack.planning.turning import MAX_SIDESLIP_DEG, min_turn_radius, motion_points, turn_margin, turn_probability
from soiltrack.planning.uncertainty import SoilUncertainty
from soiltrack.soilmodel import PRACTICAL_BOUNDS, TERRAINS, VEHICLES, Soil, simulate_slip_sweep

HEAVY = dataclasses.replace(VEHICLES["heavy"], tread=2.5, cg_height=1.0)
SAND = TERRAINS["lete_sand"]


def _uncertain(soil: Soil, rel: float) -> SoilUncertainty:
    """c, phi, K with independent relative standard errors ``rel`` around ``soil``."""
    mean = np.array([soil.cohesion, soil.friction_angle, soil.shear_modulus])
    return SoilUncertainty(
        "parameters",
        "full",
        ("cohesion", "friction_angle", "shear_modulus"),
        mean,
        np.diag((rel * mean) ** 2),
        HEAVY.weight,
        PRACTICAL_BOUNDS,
        "test: independent relative errors",
        HEAVY.contact_area,
    )


@pytest.mark.slow  # about 10 s CPU (tens of seconds wall on a loaded machine)
def test_p_turn_feasible_inside_outside_and_monotone():
    unc = _uncertain(SAND, 0.15)
    r0 = min_turn_radius(HEAVY, SAND, 2.0)
    assert r0 is not None and r0 > 0.5 * HEAVY.tread
    radii = [0.55 * r0, 0.9 * r0, r0, 1.1 * r0, 4 * r0]
    ps = [turn_probability(HEAVY, unc, radius_m=R, speed_m_s=2.0, n_samples=200).p for R in radii]
    assert ps[0] <= 0.02 and ps[-1] >= 0.98  # far outside ~0, far inside ~1
    assert all(a <= b for a, b in zip(ps, ps[1:]))  # monotone (same samples at every radius)
    assert 0.1 < ps[2] < 0.9  # at the mean soil's limit the soil's uncertainty matters
    right = turn_probability(HEAVY, unc, radius_m=-r0, speed_m_s=2.0, n_samples=200)  # mirror
    assert right.p == pytest.approx(ps[2], abs=1e-12)
    pr = turn_probability(HEAVY, unc, radius_m=1.1 * r0, speed_m_s=2.0, n_samples=200)
    assert pr.stderr == pytest.approx(math.sqrt(pr.p * (1 - pr.p) / 200))
    assert sum(pr.limited_by.values()) == pytest.approx(1 - pr.p) and "Monte Carlo" in pr.method
    m = turn_margin(HEAVY, SAND, radius_m=4 * r0, speed_m_s=2.0)
    assert m.probability is None and m.to_dict()["p_turn_feasible"] is None
    assert "without uncertainty" in m.to_dict()["p_turn_method"]


@pytest.mark.slow  # about 10 s CPU (tens of seconds wall on a loaded machine)
def test_margin_cli_p_turn_feasible_from_fit(tmp_path, capsys):
    data = simulate_slip_sweep(VEHICLES["heavy"], Soil.from_kpa_deg(1.3, 31.1, 0.012), seed=5)
    fj = tmp_path / "fit.json"
    fj.write_text(fit(data, VEHICLES["heavy"]).to_json())
    d = HEAVY.to_dict()
    d.pop("name", None)
    vj = tmp_path / "veh.json"
    vj.write_text(json.dumps(d))
    out = {}
    for R in ("10", "1.6"):
        rc = main(["margin", "--vehicle", str(vj), "--fit", str(fj), "--turn-radius", R, "--speed", "2", "--json"])
        out[R] = (rc, json.loads(capsys.readouterr().out))
    rc, js = out["10"]
    assert rc == 0 and js["turn_feasible"] is True and js["p_turn_feasible"] >= 0.98
    assert js["p_turn_samples"] > 0 and "Monte Carlo" in js["p_turn_method"]
    rc, js = out["1.6"]
    assert rc == 1 and js["turn_feasible"] is False and js["p_turn_feasible"] <= 0.02
    assert js["p_turn_limited_by"]["soil"] >= 0.98


# --- ROUTE.json radius_m: route and profile through turns ---------------------------------------
def _route(radius, terrain="lete_sand", v=2.0):
    turn = {"length_m": 15, "terrain": terrain}
    if radius is not None:
        turn["radius_m"] = radius
    return {
        "v0_m_s": v,
        "v_end_m_s": v,
        "objective": "time",
        "max_slip": 0.2,
        "patches": [{"length_m": 20, "terrain": terrain}, turn, {"length_m": 20, "terrain": terrain}],
    }


def _plan(obj, max_speed=2.0):
    from soiltrack.planning import route_profile
    from soiltrack.planning.route import route_from_dict

    return route_profile(route_from_dict(obj), HEAVY, max_speed=max_speed)


@pytest.mark.slow  # the turn terms and the OCP with the turn rows: minutes of wall time on a loaded machine
def test_route_left_and_right_turns_mirrored_straight_unchanged():
    straight, left, right = (_plan(_route(r)) for r in (None, 10.0, -10.0))
    assert straight.success and left.success and right.success
    assert straight.turns == () and "turns" not in straight.to_dict(route=True)
    # the turn's steady speed limit is above --max-speed here: the speed profile is that of the straight
    # route; the optimiser's torque carries the turn's extra resistance on top (the steering model's)
    for k in ("speed_m_s", "time_s"):
        np.testing.assert_allclose(left.series[k], straight.series[k], rtol=1e-5, atol=1e-6 * max(straight.series[k]))
        np.testing.assert_allclose(right.series[k], straight.series[k], rtol=1e-5, atol=1e-6 * max(straight.series[k]))
    np.testing.assert_allclose(left.series["sprocket_torque_Nm"], right.series["sprocket_torque_Nm"], rtol=1e-5)
    js_l, js_r = left.to_dict(route=True), right.to_dict(route=True)
    on = [j for j, r in enumerate(js_l["radius_m"]) if r is not None]
    assert len(on) >= 3 and [js_r["radius_m"][j] for j in on] == [-10.0] * len(on)
    np.testing.assert_allclose([js_l["torque_left_Nm"][j] for j in on], [js_r["torque_right_Nm"][j] for j in on], 1e-4)
    np.testing.assert_allclose([js_l["torque_right_Nm"][j] for j in on], [js_r["torque_left_Nm"][j] for j in on], 1e-4)
    np.testing.assert_allclose([js_l["slip_right"][j] for j in on], [js_r["slip_left"][j] for j in on], 1e-4)
    j = on[len(on) // 2]
    assert js_l["torque_right_Nm"][j] > 0 > js_l["torque_left_Nm"][j]  # left turn: the right track is outer
    # the optimiser's total torque there is the steering model's sum plus r times the Bekker compaction
    # resistance, which the steering model does not have (steady: within 1 %; measured without the
    # compaction term: 5107 against 4956 N m)
    total = js_l["torque_left_Nm"][j] + js_l["torque_right_Nm"][j]
    total += HEAVY.sprocket_radius * left.patches[1]["compaction_N"]
    assert js_l["sprocket_torque_Nm"][j] == pytest.approx(total, rel=0.01)
    assert js_l["sprocket_torque_Nm"][j] > straight.series["sprocket_torque_Nm"][j]
    # the turn's torques are the steering model's steady turn at the planned speed (constant 2 m/s here)
    m = turn_margin(HEAVY, SAND, radius_m=10.0, speed_m_s=2.0)
    assert js_l["torque_right_Nm"][j] == pytest.approx(m.torque_right_Nm, rel=1e-3)
    assert js_l["torque_left_Nm"][j] == pytest.approx(m.torque_left_Nm, rel=1e-3)
    off = [j for j, r in enumerate(js_l["radius_m"]) if r is None]
    assert all(
        js_l["torque_left_Nm"][j] == js_l["torque_right_Nm"][j] == 0.5 * js_l["sprocket_torque_Nm"][j] for j in off
    )
    (t,) = js_l["turns"]
    assert t["patch"] == 1 and t["feasible"] is True and t["limited_by"] is None


@pytest.mark.slow  # the turn terms and the OCP with the turn rows: about 10 s CPU
def test_route_turn_too_tight_at_2_m_s_is_slowed_for():
    clay = TERRAINS["clayey_soil"]
    r0 = min_turn_radius(HEAVY, clay, 2.0)
    assert r0 is not None
    tight, ok = _plan(_route(0.95 * r0, "clayey_soil")), _plan(_route(1.05 * r0, "clayey_soil"))
    assert ok.success and ok.turns[0]["feasible"] is True
    # too tight at 2 m/s: the optimiser slows down for it (the turn's steady speed limit in the OCP) and,
    # accelerating out of the turn, keeps the accelerating turn's sideslip within the limit (its sideslip rows:
    # before them the after-solve check refused this plan, sideslip 10.1 deg > 10 from 0.087 m/s^2 in the turn)
    assert tight.success and tight.turns[0]["feasible"] is True, tight.message
    s = tight.series
    v, t, k = (np.asarray(s[key], dtype=float) for key in ("speed_m_s", "time_s", "patch"))
    on = np.flatnonzero(k == 1)
    on = np.append(on, on[-1] + 1)  # the turn's end node turns too (the after-solve check's points)
    assert max(v[on]) < 2.0 * (1 - 1e-3)
    du = np.gradient(v, t)[on]
    assert np.max(np.abs(du)) > 0.05  # the plan does accelerate in the turn (the case the steady limits missed)
    sv = np.array([[clay.cohesion, clay.friction_angle, clay.shear_modulus]] * on.size)
    R = 0.95 * r0
    solved, _wl, _wr, lat, _tl, _tr = motion_points(HEAVY, sv, v[on], v[on] / R, du, du / R)
    beta = np.degrees(np.arctan2(np.abs(lat), v[on]))
    assert solved.all() and beta.max() <= MAX_SIDESLIP_DEG and beta.max() > 0.97 * MAX_SIDESLIP_DEG  # at the limit


def test_route_turn_no_speed_holds_not_traversable(tmp_path, capsys):
    # no speed holds this one (the inner sprocket would reverse): infeasible before the solver, limit named
    pivot = _plan(_route(1.3, "clayey_soil"))
    assert not pivot.success and pivot.status == "infeasible"
    assert pivot.reason["patch"] == 1 and pivot.reason["limit"] == "soil"
    assert "patch 1" in pivot.message and "even at" in pivot.message
    d = HEAVY.to_dict()
    d.pop("name", None)
    vj, rj = tmp_path / "v.json", tmp_path / "r.json"
    vj.write_text(json.dumps(d))
    rj.write_text(json.dumps(_route(1.3, "clayey_soil")))
    rc = main(["route", str(rj), "--vehicle", str(vj), "--max-speed", "2", "--json"])
    js = json.loads(capsys.readouterr().out)
    assert rc == 1 and js["success"] is False and js["reason"]["limit"] == "soil" and js["reason"]["patch"] == 1


@pytest.mark.parametrize(
    "radius,words",
    [
        (0, "patches[1].radius_m = 0"),
        (1.0, "half the tread"),
        (-1.25, "half the tread"),
        ("ten", "patches[1].radius_m"),
    ],
)
def test_route_bad_radius_exit_2(tmp_path, capsys, radius, words):
    d = HEAVY.to_dict()
    d.pop("name", None)
    vj, rj = tmp_path / "v.json", tmp_path / "r.json"
    vj.write_text(json.dumps(d))
    rj.write_text(json.dumps(_route(radius)))
    rc = main(["route", str(rj), "--vehicle", str(vj)])
    err = capsys.readouterr().err
    assert rc == 2 and words in err and "Traceback" not in err
    rc = main(["route", str(rj), "--vehicle", "heavy"])  # no tread_m
    err = capsys.readouterr().err
    assert rc == 2 and ("tread_m" in err or words in err)


@pytest.mark.slow  # about 10 s CPU (tens of seconds wall on a loaded machine)
def test_profile_turn_radius_cli(tmp_path, capsys):
    d = HEAVY.to_dict()
    d.pop("name", None)
    vj = tmp_path / "v.json"
    vj.write_text(json.dumps(d))
    base = ["profile", "--vehicle", str(vj), "--terrain", "lete_sand", "--v0", "2", "--v1", "2", "--distance", "20"]
    rc = main([*base, "--max-speed", "2", "--turn-radius", "-10", "--json"])
    js = json.loads(capsys.readouterr().out)
    assert rc == 0 and js["turns"][0]["radius_m"] == -10.0 and js["turns"][0]["feasible"] is True
    assert js["torque_left_Nm"][5] > 0 > js["torque_right_Nm"][5]  # right turn: the left track is outer
    # time-optimal from 1 to 2 m/s: the straight plan's acceleration (about 5 m/s^2) would leave the outer track
    # no traction to turn; the optimiser, which sees the outer track's slip-limited torque, accelerates less
    rc = main([*base[:-6], "--v0", "1", "--v1", "2", "--distance", "30", "--turn-radius", "-8", "--json"])
    js = json.loads(capsys.readouterr().out)
    assert rc == 0 and js["success"] is True and js["turns"][0]["feasible"] is True
    assert js["turns"][0]["max_slip_outer"] <= 0.2 + 1e-6
    rc = main([*base, "--turn-radius", "0"])
    assert rc == 2 and "--turn-radius" in capsys.readouterr().err
    rc = main([*base, "--turn-radius", "5", "--grade-deg", "4"])
    assert rc == 2 and "grade" in capsys.readouterr().err
