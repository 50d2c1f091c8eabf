"""Issue 39: plans a user can trust (downhill margins, a fit of another vehicle, fitted effects in plans,
slope stability, output paths checked before the work, signed extremes)."""

import json
import math
import os

import numpy as np
import pytest

from soiltrack.cli import main
from soiltrack.planning import margin
from soiltrack.planning.fit_vehicle import VEHICLE_TOLERANCE
from soiltrack.planning.stability import sliding_limit_deg, tipping_limit_deg
from soiltrack.soilmodel import TERRAINS, VEHICLES, Vehicle

LIGHT = VEHICLES["light"]


def run(capsys, *args):
    rc = main(list(args))
    out, err = capsys.readouterr()
    return rc, out, err


def gear(v: Vehicle, name: str) -> dict:
    """The running_gear block of DESIGN section 9, as i37's fit JSON writes it."""
    return {
        "kind": "track",
        "name": name,
        "weight_N": v.weight,
        "contact_area_m2": v.contact_area,
        "track_length_m": v.track_length,
        "wheel_radius_m": None,
        "wheel_width_m": None,
    }


@pytest.fixture(scope="module")
def fits(tmp_path_factory):
    """fit --json of a light-vehicle sweep with slip_sinkage, and of the Wong heavy-vehicle points,
    with the keys of the fit JSON contract added (outcome, running_gear)."""
    d = tmp_path_factory.mktemp("fits")
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    sweep = str(d / "sweep.csv")
    assert (
        main(
            "simulate --kind sweep --vehicle light --terrain sandy_loam --loads 300,450 --effect slip_sinkage=0.1 "
            f"--seed 1 -o {sweep}".split()
        )
        == 0
    )
    out = {}
    for key, args, g in (
        ("light_ss", [sweep, "--vehicle", "light", "--effect", "slip_sinkage"], gear(LIGHT, "light")),
        (
            "heavy",
            [os.path.join(root, "examples", "data", "wong2001_p176.csv"), "--vehicle", "heavy"],
            gear(VEHICLES["heavy"], "heavy"),
        ),
    ):
        p = d / f"{key}.json"
        import contextlib
        import io

        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            main(["fit", *args, "--json"])
        obj = json.loads(buf.getvalue())
        # the fit JSON records its running gear (the contract's keys); a fit JSON of an older version has none
        rg = obj["running_gear"]
        assert rg["kind"] == "track"
        for k in ("contact_area_m2", "track_length_m"):
            assert rg[k] == pytest.approx(g[k], rel=1e-9)
        # the light sweep's rows are at 300 and 450 N: the fit has no single weight (null, as for a rig)
        assert rg["weight_N"] == (None if key == "light_ss" else pytest.approx(g["weight_N"], rel=1e-9))
        plain = d / f"{key}_plain.json"
        plain.write_text(json.dumps({k: v for k, v in obj.items() if k != "running_gear"}))
        obj.update(outcome="usable", outcome_reason=None)
        p.write_text(json.dumps(obj))
        out[key], out[key + "_plain"] = str(p), str(plain)
        bad = dict(obj, outcome="poor_fit", outcome_reason="lack of fit p = 0.0003")
        (d / f"{key}_poor.json").write_text(json.dumps(bad))
        out[key + "_poor"] = str(d / f"{key}_poor.json")
    return out


# ---------------------------------------------------------------- 1. downhill: both directions
@pytest.mark.parametrize("grade", [-60.0, -40.0])
def test_steep_downhill_beyond_the_soils_braking_limit_is_not_traversable(grade):
    m = margin(TERRAINS["dry_sand"], LIGHT, grade_deg=grade)
    assert m.direction == "braking" and m.required_N < 0
    assert m.margin_N == pytest.approx(m.available_N - abs(m.required_N))
    assert not m.traversable and m.margin_N < 0
    if grade == -60.0:
        assert m.slip_required is None  # no skid delivers that braking thrust
    else:
        assert m.slip_required < -m.max_slip  # a skid beyond the allowed one would (measured -24 %)


def test_minus_60_on_dry_sand_numbers(capsys):
    rc, out, _ = run(capsys, "margin", "--vehicle", "light", "--terrain", "dry_sand", "--grade-deg", "-60", "--json")
    js = json.loads(out)
    assert rc == 1 and js["traversable"] is False and js["direction"] == "braking"
    # measured: available braking 138.7 N against a required -252 N: short by 113.4 N
    assert js["available_N"] == pytest.approx(138.7, abs=0.1)
    assert js["required_N"] == pytest.approx(-252.0, abs=0.1)
    assert js["margin_N"] == pytest.approx(-113.4, abs=0.1)


def test_gentle_downhill_is_traversable_with_a_skid():
    m = margin(TERRAINS["dry_sand"], LIGHT, grade_deg=-5.0)
    assert m.traversable and m.direction == "braking"
    assert m.slip_required is not None and -0.01 < m.slip_required < 0  # measured -0.399 %
    assert m.min_grade_deg is not None and m.min_grade_deg == pytest.approx(-38.2, abs=0.1)


def test_minus_30_light_vs_heavy_on_dry_sand():
    """The light vehicle's cohesion share (A c = 104 N of 300 N) holds -30 deg at a 20 % skid (margin 46.45 N);
    the heavy one, where cohesion is negligible, slides beyond phi + asin(A c cos(phi) / W) = 28.4 deg."""
    light = margin(TERRAINS["dry_sand"], LIGHT, grade_deg=-30.0)
    assert light.traversable and light.margin_N == pytest.approx(46.45, abs=0.05)
    heavy = margin(TERRAINS["dry_sand"], VEHICLES["heavy"], grade_deg=-30.0)
    assert heavy.sliding_limit_deg == pytest.approx(28.4, abs=0.1)
    assert not heavy.traversable and any("sliding limit" in n for n in heavy.notes)


def test_uphill_unchanged_and_driving():
    m = margin(TERRAINS["dry_sand"], LIGHT, grade_deg=10.0)
    assert m.direction == "driving" and m.traversable
    assert m.margin_N == pytest.approx(129.2, abs=0.1)
    assert m.max_grade_deg == pytest.approx(33.5, abs=0.1)


# ---------------------------------------------------------------- 2. a fit of another vehicle
def test_fit_of_the_heavy_vehicle_refused_for_the_light_one(capsys, fits):
    rc, out, err = run(capsys, "margin", "--vehicle", "light", "--fit", fits["heavy"], "--grade-deg", "10")
    assert rc == 2 and out == "" and "Traceback" not in err
    assert "heavy" in err and "light" in err and f"tolerance {VEHICLE_TOLERANCE * 100:g} %" in err
    assert "--allow-other-vehicle" in err


@pytest.mark.parametrize("cmd", ["profile", "route"])
def test_every_planning_command_checks_the_fit_vehicle(capsys, fits, tmp_path, cmd):
    if cmd == "profile":
        args = ["profile", "--vehicle", "light", "--fit", fits["heavy"], "--v0", "0.5", "--v1", "1", "--distance", "2"]
    else:
        r = tmp_path / "route.json"
        r.write_text(json.dumps({"v0_m_s": 0.5, "v_end_m_s": 1.0, "objective": "time", "max_slip": 0.2,
                                 "patches": [{"length_m": 2}]}))  # fmt: skip
        args = ["route", str(r), "--vehicle", "light", "--fit", fits["heavy"]]
    rc, _, err = run(capsys, *args)
    assert rc == 2 and "running_gear" in err and "Traceback" not in err


def test_allow_other_vehicle_scales_on_purpose_and_says_so(capsys, fits):
    rc, out, _ = run(
        capsys, "margin", "--vehicle", "light", "--fit", fits["heavy"], "--grade-deg", "10", "--allow-other-vehicle"
    )
    first = out.splitlines()[0]
    assert rc == 0 and "another vehicle, scaled on purpose" in first


def test_same_vehicle_accepted_and_within_tolerance(capsys, fits):
    rc, out, _ = run(capsys, "margin", "--vehicle", "heavy", "--fit", fits["heavy"], "--grade-deg", "10")
    assert rc == 0 and " - " not in out.splitlines()[0]  # nothing to say on the first line


def test_fit_without_running_gear_says_the_vehicle_cannot_be_checked(capsys, fits):
    rc, out, _ = run(capsys, "margin", "--vehicle", "light", "--fit", fits["light_ss_plain"], "--grade-deg", "10")
    assert rc == 0 and "cannot be checked" in out.splitlines()[0]


def test_outcome_not_usable_on_the_first_line(capsys, fits):
    rc, out, _ = run(capsys, "margin", "--vehicle", "light", "--fit", fits["light_ss_poor"], "--grade-deg", "10")
    assert "outcome is poor_fit" in out.splitlines()[0]
    rc, out, _ = run(
        capsys, "profile", "--vehicle", "light", "--fit", fits["light_ss_poor"], "--v0", "0.5", "--v1", "1",
        "--distance", "2",
    )  # fmt: skip
    assert rc == 0 and "outcome is poor_fit" in out.splitlines()[0]


# ---------------------------------------------------------------- 3. fitted effects
def test_slip_sinkage_resistance_in_the_margins_required_thrust(capsys, fits):
    rc, out, _ = run(capsys, "margin", "--vehicle", "light", "--fit", fits["light_ss"], "--json")
    js = json.loads(out)
    mu_s = json.load(open(fits["light_ss"]))["effects"]["slip_sinkage"]["mu_s"]["value"]
    assert js["effects_planned"] == ["slip_sinkage"] and js["effects_left_out"] == []
    # W (mu_r + mu_s i) at the allowed slip 0.2: the effect adds mu_s 0.2 W = 7.3 N on the flat
    assert js["required"]["effects_N"] == pytest.approx(mu_s * 0.2 * LIGHT.weight, rel=1e-9)
    assert js["required"]["effects_N"] == pytest.approx(7.32, abs=0.01)
    assert js["required_N"] == pytest.approx(sum(js["required"].values()), rel=1e-12)


def test_profile_plans_with_slip_sinkage_and_names_what_it_leaves_out(capsys, fits, tmp_path):
    from soiltrack.planning import load_fit_json, profile, replay

    u = load_fit_json(fits["light_ss"], LIGHT)
    res = profile(u, LIGHT, v0=0.5, v1=1.5, distance=2.0, max_speed=2.0)
    obj = json.load(open(fits["light_ss"]))
    nominal_obj = dict(obj, effects={})
    p0 = tmp_path / "nominal.json"
    p0.write_text(json.dumps(nominal_obj))
    nom = profile(load_fit_json(str(p0), LIGHT), LIGHT, v0=0.5, v1=1.5, distance=2.0, max_speed=2.0)
    mu_s = obj["effects"]["slip_sinkage"]["mu_s"]["value"]
    assert res.success and nom.success and res.headline == ()  # slip_sinkage planned: nothing left out
    assert np.allclose(res.mesh["mu_s"], mu_s) and "mu_s" not in nom.mesh
    assert res.energy_J > nom.energy_J  # measured 107.8 J against 106.8 J: the slip resistance costs work
    rp = replay(res, LIGHT)  # the open-loop replay includes the resistance: the plan is kept
    assert rp.speed[-1] == pytest.approx(1.5, rel=1e-3)
    # an effect the profile does not plan with is named on the first line
    obj2 = dict(obj)
    obj2["effects"] = dict(obj["effects"], hump_shear={"drop": {"value": 0.2}, "k_ratio": {"value": 5.0}})
    p2 = tmp_path / "hump.json"
    p2.write_text(json.dumps(obj2))
    rc, out, _ = run(
        capsys, "profile", "--vehicle", "light", "--fit", str(p2), "--v0", "0.5", "--v1", "1", "--distance", "2",
        "--json",
    )  # fmt: skip
    js = json.loads(out)
    assert rc == 0 and any("left out: hump_shear" in n for n in js["fit_notes"])
    assert not any("slip_sinkage" in n for n in js["fit_notes"])


def test_hump_shear_effect_lowers_the_available_thrust():
    nominal = margin(TERRAINS["dry_sand"], LIGHT)
    soft = margin(TERRAINS["dry_sand"], LIGHT, effects={"hump_shear": {"drop": 0.3, "k_ratio": 5.0}})
    assert soft.effects_planned == ("hump_shear",)
    assert soft.soil_limit_N < nominal.soil_limit_N  # the softening soil gives less at 20 % slip


# ---------------------------------------------------------------- 4. slope stability
def test_tipping_limit_formula_and_steepest_grade(tmp_path, capsys):
    v = json.loads(LIGHT.to_json())
    v["cg_height_m"] = 0.5
    p = tmp_path / "light_cg.json"
    p.write_text(json.dumps(v))
    veh = Vehicle.from_json(str(p))
    assert tipping_limit_deg(veh) == pytest.approx(math.degrees(math.atan(0.25 / 0.5)))  # 26.57 deg
    m = margin(TERRAINS["dry_sand"], veh, grade_deg=20)
    assert m.traversable and m.max_grade_deg == pytest.approx(26.565, abs=1e-3)  # traction alone: 33.5 deg
    assert m.min_grade_deg == pytest.approx(-26.565, abs=1e-3)
    rc, out, _ = run(capsys, "margin", "--vehicle", str(p), "--terrain", "dry_sand", "--grade-deg", "30", "--json")
    js = json.loads(out)
    assert rc == 1 and js["traversable"] is False and js["margin_N"] > 0  # thrust enough, but it tips
    assert js["tipping_checked"] is True and any("tipping limit" in n for n in js["notes"])


def test_without_cg_height_tipping_is_not_checked():
    m = margin(TERRAINS["dry_sand"], LIGHT)
    assert m.tipping_limit_deg is None and "tipping not checked" in m.report()


def test_sliding_limit_formula():
    s = TERRAINS["dry_sand"]
    phi, c = s.friction_angle, s.cohesion
    expect = math.degrees(phi + math.asin(LIGHT.contact_area * c * math.cos(phi) / LIGHT.weight))
    assert sliding_limit_deg(c, phi, LIGHT) == pytest.approx(expect)
    assert sliding_limit_deg(0.0, phi, LIGHT) == pytest.approx(math.degrees(phi))  # friction only: phi


def test_cg_height_refused_when_not_positive(tmp_path, capsys):
    v = json.loads(LIGHT.to_json())
    v["cg_height_m"] = 0
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(v))
    rc, _, err = run(capsys, "margin", "--vehicle", str(p), "--terrain", "dry_sand")
    assert rc == 2 and "cg_height_m" in err


# ---------------------------------------------------------------- 5./6. output paths
@pytest.mark.parametrize(
    "args",
    [
        ["margin", "--vehicle", "light", "--terrain", "dry_sand"],
        ["profile", "--vehicle", "light", "--terrain", "dry_sand", "--v0", "0.5", "--v1", "1", "--distance", "2"],
        ["simulate", "--kind", "sweep", "--vehicle", "light"],
    ],
)
def test_unwritable_plot_path_exit_2_before_the_work(capsys, args):
    rc, out, err = run(capsys, *args, "--plot", "/proc/soiltrack_x.png")
    assert rc == 2 and "Traceback" not in err and "/proc/soiltrack_x.png" in err and "cannot be written" in err
    assert out == ""  # refused before the work: nothing printed


def test_unwritable_plot_path_route_and_diagnose(capsys, tmp_path):
    r = tmp_path / "route.json"
    r.write_text(json.dumps({"v0_m_s": 0.5, "v_end_m_s": 1.0, "objective": "time", "max_slip": 0.2,
                             "patches": [{"length_m": 2, "terrain": "dry_sand"}]}))  # fmt: skip
    rc, _, err = run(capsys, "route", str(r), "--vehicle", "light", "--plot", "/proc/x.png")
    assert rc == 2 and "cannot be written" in err
    rc, _, err = run(capsys, "diagnose", str(r), "--vehicle", "light", "--plot", "/proc/x.png")
    assert rc == 2 and "cannot be written" in err


def test_relative_output_folder_is_created(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    rc, _, err = run(capsys, "simulate", "--kind", "sweep", "--vehicle", "light", "--seed", "1", "-o", "out/s.csv")
    assert rc == 0 and (tmp_path / "out" / "s.csv").stat().st_size > 0 and "created the folder 'out'" in err
    # an absolute path's missing folder is still refused (a typo more likely than a wish for a new tree)
    rc, _, err = run(capsys, "simulate", "--kind", "sweep", "--vehicle", "light", "-o", str(tmp_path / "no" / "s.csv"))
    assert rc == 2 and "does not exist" in err


def test_probe_leaves_no_file_behind(capsys, tmp_path):
    p = tmp_path / "m.png"
    rc, _, _ = run(capsys, "margin", "--vehicle", "light", "--terrain", "dry_sand", "--soil", "1,30,0.01")
    assert rc == 2  # --terrain and --soil together: refused after the path check
    rc, _, _ = run(
        capsys, "margin", "--vehicle", "light", "--terrain", "dry_sand", "--soil", "1,30,0.01", "--plot", str(p)
    )
    assert rc == 2 and not p.exists()


# ---------------------------------------------------------------- 8. signed extremes
def test_route_report_signed_extremes(capsys, tmp_path):
    r = tmp_path / "route.json"
    r.write_text(json.dumps({"v0_m_s": 0.5, "v_end_m_s": 0.5, "objective": "time", "max_slip": 0.2,
                             "patches": [{"length_m": 2, "terrain": "dry_sand"}]}))  # fmt: skip
    rc, out, _ = run(capsys, "route", str(r), "--vehicle", "light", "--max-speed", "1.5", "--json")
    js = json.loads(out)
    rc2, rep, _ = run(capsys, "route", str(r), "--vehicle", "light", "--max-speed", "1.5")
    assert rc == rc2 == 0
    smax, smin = max(js["slip"]), min(js["slip"])
    assert smax > 0 > smin
    assert f"largest driving slip {smax * 100:.3g} %" in rep and f"largest braking slip {smin * 100:.3g} %" in rep
    assert "largest braking torque -" in rep


# ---------------------------------------------------------------- 10. help text
def test_diagnose_model_has_help(capsys):
    with pytest.raises(SystemExit):
        main(["diagnose", "--help"])
    out = capsys.readouterr().out
    assert "cohesion-free (phi, K; Eq. 8)" in " ".join(out.split())


# ---------------------------------------------------------------- 10. smaller
def test_bad_rows_counted_once_per_row_with_a_decimal_comma_hint(capsys, tmp_path):
    p = tmp_path / "comma.csv"
    p.write_text(
        "slip,tractive_force_N,normal_load_N\n"
        + "".join(f'"0,{k:02d}","7{k},5","300,0"\n' for k in range(1, 45))  # 44 rows, 3 bad values each
    )
    rc, _, err = run(capsys, "fit", str(p), "--vehicle", "light")
    assert rc == 2 and "44 bad rows" in err and "(the first 20 of 44)" in err and "decimal comma" in err


def test_bare_soiltrack_prints_the_help(capsys):
    rc, out, _ = run(capsys)
    assert rc == 0 and "usage: soiltrack" in out and "simulate" in out


def test_a_fit_result_in_python_carries_its_effects_and_vehicle():
    from soiltrack.identify import fit
    from soiltrack.soilmodel import simulate

    data = simulate(LIGHT, TERRAINS["sandy_loam"], kind="sweep", effects={"slip_sinkage": 0.1}, seed=1)
    res = fit(data, LIGHT, effects=["slip_sinkage"])
    m = margin(res, LIGHT, grade_deg=10)
    mu_s = res.effects["slip_sinkage"]["mu_s"].value
    assert m.effects_planned == ("slip_sinkage",)
    assert m.required["effects_N"] == pytest.approx(mu_s * 0.2 * m.normal_load_N, rel=1e-9)
    assert m.headline == ()  # the fit's own vehicle: nothing to say
    other = margin(res, VEHICLES["heavy"], grade_deg=10)  # said, not refused, in Python
    assert any("another vehicle" in h for h in other.headline)
