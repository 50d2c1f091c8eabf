"""Drive-log diagnosis: the change-of-terrain and delay tools, and the outside causes they name."""

import json
import numpy as np
import pytest

from soiltrack.identify import diagnose
from soiltrack.identify.diagnosis import DiagnoseSettings
from soiltrack.identify.diagnosis.log_parts import delay_scan, shift_speed, terrain_window
from soiltrack.soilmodel import TERRAINS, VEHICLES, DriveLog, Vehicle, simulate


def _scores(patch, n=1500, seed=0, change=(-0.3, 0.0)):
    """Per-sample whitened residuals and soil sensitivities of a nominal fit to a run with a soft patch.

    Three channels; the sensitivities vary along the run (thrust high in bursts, low while cruising);
    inside ``patch`` the soil differs by ``delta`` (so the residual of the whole-run soil carries
    ``-J @ delta`` on top of unit noise), less the part the nominal (whole-run) soil absorbs.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.02
    push = 0.3 + 2.0 * (np.sin(2 * np.pi * t / 7.0) > 0.3)  # bursts of hard pushing
    J = rng.standard_normal((n, 3, 2)) * push[:, None, None]
    J[:, :, 1] *= 0.5
    inside = (t >= patch[0]) & (t < patch[1])
    delta = np.array(change)
    # e(theta_0) = e(theta_true) + J (theta_0 - theta_true): the residual of the whole-run soil inside
    e = rng.standard_normal((n, 3)) - np.where(inside[:, None], np.einsum("kcp,p->kc", J, delta), 0.0)
    # the nominal fit: one least-squares soil step for the whole run (residuals orthogonal to J)
    A = np.einsum("kcp,kcq->pq", J, J)
    step = np.linalg.solve(A, np.einsum("kcp,kc->p", J, e))
    e = e - np.einsum("kcp,p->kc", J, step)
    return e, J, t


def test_terrain_window_brackets_a_soft_patch():
    e, J, t = _scores((12.0, 20.0))
    w = terrain_window(e, J, t, scale=(1.0, 1.0))
    assert w.significant and w.p_value < 1e-6
    # the bracket holds the patch; the evidence window lies inside the bracket and overlaps the patch
    assert w.start <= 12.0 + 0.5 and w.end >= 20.0 - 0.5
    assert w.start <= w.evidence_start <= w.evidence_end <= w.end
    assert w.evidence_start < 20.0 and w.evidence_end > 12.0
    # informative data everywhere: the bracket is not the whole run
    assert w.start > 5.0 and w.end < 25.0
    assert w.fmax_change < 0  # softer inside (relative to the unit scale)


def test_terrain_window_is_quiet_on_noise():
    for seed in (4, 5, 6):
        e, J, t = _scores((12.0, 20.0), change=(0.0, 0.0), seed=seed)
        w = terrain_window(e, J, t)
        assert not w.significant and w.p_value > 0.05


def test_delay_scan_finds_a_lag_in_synthetic_residuals():
    rng = np.random.default_rng(5)
    n = 3000
    w = np.cumsum(rng.standard_normal(n)) * 0.05 + 10.0  # sprocket speed, a random walk
    wl = np.r_[np.nan, 0.5 * (w[:-2] + w[2:]), np.nan]
    r = np.full(n, np.nan)
    r[20:] = (wl[20:] - w[12:-8]) + 0.02 * rng.standard_normal(n - 20)  # late by 8 samples
    s = delay_scan(r, w)
    assert s["lag"] == 8 and s["p_value"] < 1e-6 and s["coef"] == pytest.approx(1.0, abs=0.05)
    s0 = delay_scan(0.02 * rng.standard_normal(n), w)
    assert s0["p_value"] > 0.01


def test_shift_speed_undoes_a_delay():
    t = np.arange(50) * 0.02
    v = 1.0 + t
    log = DriveLog(t, np.ones(50), np.full(50, 10.0), np.r_[np.full(3, v[0]), v[:-3]])
    back = shift_speed(log, 3)
    assert np.allclose(back.vehicle_speed[:-3], v[:-3])


def _consistent(d):
    w = {e.effect: e.weight for e in d.ranking}
    if d.verdict == "unexplained":
        assert d.confidence == pytest.approx(sum(e.weight for e in d.ranking if e.family in ("flexible", "outside")))
    elif d.verdict == "none":  # the no-gap hypothesis's weight (issue 37): at least the nominal model's
        assert w["none"] <= d.confidence <= 1.0 + 1e-12 and "no-gap hypothesis" in d.reason
    else:
        assert d.confidence == w[d.verdict]


def _diagnosed(vehicle: str, effects: dict, seed: int, duration_s: float, terrain: str = "lete_sand"):
    """The diagnosis of a simulated drive log, its verdict's confidence checked against its weight."""
    v = VEHICLES[vehicle]
    d = diagnose(simulate(v, TERRAINS[terrain], kind="drive", effects=effects, seed=seed, duration_s=duration_s), v)
    _consistent(d)
    return d


@pytest.mark.slow
def test_a_delayed_speed_sensor_is_unexplained_with_the_delay_named():
    vehicle, soil = VEHICLES["light"], TERRAINS["lete_sand"]
    log = simulate(vehicle, soil, kind="drive", seed=1, duration_s=30.0)
    v = np.asarray(log.vehicle_speed)
    late = DriveLog(
        log.time,
        log.sprocket_torque,
        log.sprocket_speed,
        np.r_[np.full(10, v[0]), v[:-10]],
        log.vehicle_accel,
        source="speed sensor 10 samples late",
    )
    d = diagnose(late, vehicle)
    _consistent(d)
    assert (d.verdict, d.cause) == ("unexplained", "delay"), (d.verdict, d.cause, d.reason)
    h = float(np.median(np.diff(log.time)))
    assert abs(d.cause_detail["lag_s"] - 10 * h) <= 2 * h
    js = d.to_dict()
    assert js["cause"] == "delay" and js["lag_s"] == d.cause_detail["lag_s"]


@pytest.mark.slow
def test_a_gap_the_screens_miss_still_gets_the_effects_refitted():
    # heavy vehicle, slip sinkage mu_s = 0.15, seed 3 (a case of the diagnosis grid): no effect's score test is
    # significant and the flexible term does not beat the nominal model, but the nominal held-out error exceeds
    # the noise (p = 2e-4). The effects were not refitted and the verdict was unexplained 0.58 with a change of
    # terrain heaviest; the gap test that needs no effect now also asks for the refits
    d = _diagnosed("heavy", {"slip_sinkage": 0.15}, seed=3, duration_s=60.0)
    alpha = DiagnoseSettings().alpha
    assert d.gap.p_of("flexible term beats nominal") >= alpha and d.gap.p_of("nominal error vs noise") < alpha
    assert d.verdict == "slip_sinkage" and d.confidence > 0.9, (d.verdict, d.reason)
    lo, hi = d.ranking[0].parameters["mu_s"]["ci95"]
    assert lo <= 0.15 <= hi


@pytest.mark.slow
def test_a_grade_on_uniform_soil_is_no_change_of_terrain():
    d = _diagnosed("light", {"grade": 0.05}, seed=7, duration_s=40.0)
    assert d.cause != "terrain_change" and d.verdict in ("grade", "drivetrain_friction", "mass_error"), d.verdict
    assert "terrain_change" not in [e.effect for e in d.ranking[:1]]


@pytest.mark.slow
def test_a_soft_patch_is_unexplained_and_never_an_effect():
    # heavy vehicle on LETE sand with 24-39 s driven on dry sand (spliced from two runs with the same speed
    # reference). The change-of-terrain hypothesis is judged on held-out samples like any other; on this log the
    # held-out samples inside the window carry little of it, so it is not named, but no effect is either
    v = VEHICLES["heavy"]
    a = simulate(v, TERRAINS["lete_sand"], kind="drive", seed=1, duration_s=60.0)
    b = simulate(v, TERRAINS["dry_sand"], kind="drive", seed=1, duration_s=60.0)
    m = (a.time >= 24.0) & (a.time < 39.0)
    cols = {
        k: np.where(m, getattr(b, k), getattr(a, k))
        for k in ("sprocket_torque", "sprocket_speed", "vehicle_speed", "vehicle_accel")
    }
    d = diagnose(
        DriveLog(a.time, cols["sprocket_torque"], cols["sprocket_speed"], cols["vehicle_speed"], cols["vehicle_accel"]),
        v,
    )
    _consistent(d)
    assert d.verdict == "unexplained" and d.gap.present, (d.verdict, d.reason)
    # considered: weighed, or left out with its reason (on this version its slope inside the window ends on an
    # edge of the range searched from the soil refitted outside it: dry sand's thrust limit is not LETE sand's)
    assert "terrain_change" in [e.effect for e in d.ranking] + [x.name for x in d.excluded]
    if d.cause == "terrain_change":
        w0, w1 = d.cause_detail["window_s"]
        assert 24.0 - 15.0 <= w0 < w1 <= 39.0 + 15.0  # within twice the true window


def _independent_log(tmp_path, seed, **kw):
    """A drive log made by the plain-numpy generator of benchmarks/independent_check.py (not soilmodel)."""
    from conftest import bench_module

    from soiltrack.soilmodel import read_csv

    ic = bench_module("independent_check")
    path = tmp_path / f"log_{seed}.csv"
    ic.log_csv(str(path), seed, **kw)
    return read_csv(str(path)), Vehicle.from_json(ic.VEHICLE)


@pytest.mark.slow
def test_a_speed_sensor_reading_high_is_unexplained_with_its_gain(tmp_path):
    """GNSS speed 3 % high: it offsets the slip like a radius error but leaves the torque arm alone."""
    log, v = _independent_log(tmp_path, 1, speed_scale=1.03)
    d = diagnose(log, v)
    _consistent(d)
    assert (d.verdict, d.cause) == ("unexplained", "speed_scale"), (d.verdict, d.reason)
    assert abs(d.cause_detail["gain"] - 0.03) < 0.01
    assert d.confidence == pytest.approx(sum(e.weight for e in d.ranking if e.family in ("flexible", "outside")))


@pytest.mark.slow
def test_a_radius_error_is_not_taken_for_a_speed_sensor(tmp_path):
    log, v = _independent_log(tmp_path, 2, radius=0.04)
    d = diagnose(log, v)
    _consistent(d)
    # the evidence itself puts the radius error first (raw weights 0.96 and 0.04 on this version); within two
    # standard errors of each other (1.8) the two share their weight, and the candidate is named
    raw = {e.effect: e.evidence_weight for e in d.ranking}
    assert d.verdict == "radius_error" and raw["radius_error"] > raw["speed_scale"]
    assert d.weight_of("radius_error") >= d.weight_of("speed_scale")


@pytest.mark.slow
def test_torque_glitches_are_lone_readings_left_out_and_name_no_effect(tmp_path):
    """Two logger glitches of the torque (+25 and -18 kN m at rows 300 and 800): a glitch is not a gap."""
    log, v = _independent_log(tmp_path, 2, torque_glitches=((300, 25000.0), (800, -18000.0)))
    d = diagnose(log, v)
    _consistent(d)
    assert d.verdict in ("none", "unexplained") and d.cause is None, (d.verdict, d.reason)
    # the thrust residual at row k is the step from row k - 1 (torque held over it): the glitches of rows
    # 300 and 800 show at 301 and 801
    assert d.lone_readings == {"thrust_N": (301, 801)}, d.lone_readings
    assert json.loads(d.to_json())["lone_readings"]


_TIED_WITH_A_MASS_ERROR = pytest.mark.xfail(
    strict=True,
    reason=(
        "known miss: on seed 2 a mass error of -1.2 % (+-0.5 %) ties with the change of terrain on held-out "
        "evidence (0.49 and 0.49); it explains 5 % of the gap, so no effect is named, and the verdict is "
        "unexplained without a cause"
    ),
)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, pytest.param(2, marks=_TIED_WITH_A_MASS_ERROR)])
def test_a_soft_patch_from_independent_code_is_a_change_of_terrain_inside_twice_its_window(tmp_path, seed):
    """Soil 200 Pa, 12 deg, K 50 mm from 20 to 35 s in a run on 1.3 kPa, 31 deg, 12 mm."""
    log, v = _independent_log(tmp_path, seed, patch=(20.0, 35.0, (200.0, np.radians(12.0), 0.05)))
    d = diagnose(log, v)
    _consistent(d)
    assert (d.verdict, d.cause) == ("unexplained", "terrain_change"), (d.verdict, d.reason)
    w0, w1 = d.cause_detail["window_s"]
    assert 20.0 - 15.0 <= w0 < w1 <= 35.0 + 15.0  # within twice the true window
    assert d.ranking[0].parameters["slope_change"]["value"] < 0  # softer inside


@pytest.mark.slow
def test_a_mass_error_is_not_charged_for_the_larger_residual_its_mass_gives():
    """The hull balance of a 10 % heavier vehicle is the measured acceleration times 1.1 m: its residual and its
    noise grow together, and the measured acceleration's density does not change. Charged ``log 1.1`` per
    sample as a larger noise, the mass error lost to a drivetrain loss (0.65 against 0.35, heavy vehicle on dry
    sand, the diagnosis grid's seed 1)."""
    d = _diagnosed("heavy", {"mass_error": 0.1}, 1, 60.0, terrain="dry_sand")
    assert d.verdict == "mass_error", (d.verdict, d.reason)
    assert d.confidence > 0.5
    lo, hi = d.ranking[0].parameters["delta"]["ci95"]
    assert lo < 0.1 < hi


S_CONFUSABLE = DiagnoseSettings().confusable_separation


def _light_radius_log(terrain: str, eps: float, seed: int) -> DriveLog:
    """The diagnosis grid's light-vehicle log with doubled noise and a radius error ``eps`` (one minute)."""
    from soiltrack.soilmodel import SensorNoise

    noise = SensorNoise(
        encoder_rel=0.01, encoder_abs=0.02, gnss_speed=0.1, imu_accel=0.1, torque_rel=0.02, torque_fs=0.002
    )
    return simulate(
        VEHICLES["light"],
        TERRAINS[terrain],
        kind="drive",
        effects={"radius_error": eps},
        seed=seed,
        noise=noise,
        duration_s=60.0,
    )


@pytest.mark.slow
def test_a_radius_error_and_a_speed_sensor_scale_share_their_weight_when_the_data_cannot_tell_them_apart():
    """Both scale the apparent slip; only a radius error changes the torque arm, which the soil's thrust limit
    absorbs but for the hull balance. On the grid's light-vehicle log with doubled noise (radius error 2 %, seed
    3) the two weigh 0.81 and 0.19 from the evidence alone, 1.0 standard error apart; their sensitivities are
    collinear, so they are confusable, share their weight, and the pair is listed with its separating
    experiment; the candidate is named first."""
    v = VEHICLES["light"]
    log = _light_radius_log("lete_sand", 0.02, 3)
    d = diagnose(log, v)
    _consistent(d)
    w = {e.effect: e.weight for e in d.ranking}
    assert w["radius_error"] == w["speed_scale"] == pytest.approx(0.5, abs=0.01)
    pairs = [set(c.effects) for c in d.confusable]
    assert {"radius_error", "speed_scale"} in pairs
    # a candidate explains the gap as well as the cause outside the candidates: the gap is not unexplained
    assert (d.verdict, d.confidence) == ("radius_error", w["radius_error"])
    eps = next(e for e in d.ranking if e.effect == "radius_error").parameters["eps"]["ci95"]
    assert eps[0] < 0.02 < eps[1]


@pytest.mark.slow
def test_collinear_hypotheses_within_two_standard_errors_share_and_their_group_explains_the_gap():
    """The grid's light log on dry sand with doubled noise (radius error 2 %, seed 2): the evidence alone
    weighs the radius error 0.88 and the speed scale 0.12 (a factor 7, beyond the weight test's factor 5), 1.3
    standard errors of the block sums apart. Within two standard errors, with collinear sensitivities, the two
    are confusable: they share, and the candidate is named. Its own refit removes 46 % of the nominal excess,
    the speed scale 89 %: the group explains the gap. (Before the evidence weighed the channels by the
    sensors' noise, the speed scale led here at 0.97.)"""
    v = VEHICLES["light"]
    log = _light_radius_log("dry_sand", 0.02, 2)
    d = diagnose(log, v)
    _consistent(d)
    w = {e.effect: e.weight for e in d.ranking}
    raw = {e.effect: e.evidence_weight for e in d.ranking}
    assert raw["speed_scale"] < 0.2 * raw["radius_error"]  # the weights alone would have told them apart
    assert w["radius_error"] == w["speed_scale"] == pytest.approx(0.5, abs=0.01)
    assert (d.verdict, d.confidence, d.cause) == ("radius_error", w["radius_error"], None)
    assert {"radius_error", "speed_scale"} in [set(c.effects) for c in d.confusable]
    ex = {e.effect: e.explained for e in d.ranking}
    assert ex["radius_error"] < 0.5 <= ex["speed_scale"]
    # the report and the JSON give the separation that decided (below 2)
    detail = next(c for c in d.to_dict()["confusable_detail"] if set(c["effects"]) == {"radius_error", "speed_scale"})
    assert 0.5 < detail["separation_se"] < S_CONFUSABLE
    # with the criterion off (no pair within 0 standard errors) the weights decide: the radius error alone is
    # heaviest and removes less than half of the excess
    d0 = diagnose(log, v, settings=DiagnoseSettings(confusable_separation=0.0))
    assert (d0.verdict, d0.cause) == ("unexplained", None)
