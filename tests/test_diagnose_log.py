"""Drive-log diagnosis: change of soil in time (synthetic scores) and a speed-sensor delay (short simulated log)."""

import numpy as np
import pytest

from soiltrack.identify import diagnose
from soiltrack.identify.diagnosis.log_parts import delay_scan, shift_speed, terrain_window
from soiltrack.soilmodel import TERRAINS, VEHICLES, DriveLog, simulate
from conftest import independent_log


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
    assert "soil differs" in w.describe()


def test_terrain_window_is_quiet_on_noise():
    for seed in (4, 5, 6):
        e, J, t = _scores((12.0, 20.0), change=(0.0, 0.0), seed=seed)
        w = terrain_window(e, J, t)
        assert not w.significant and w.p_value > 0.05
        assert "no significant change" in w.describe()


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


@pytest.mark.slow
def test_a_delayed_speed_sensor_is_not_named_as_an_effect():
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
    named = d.verdict not in ("none", "unexplained")
    assert not (named and d.confidence > 0.5), (d.verdict, d.confidence, d.reason)
    scan = d.lags["delay scan: speed residual vs sprocket-speed change over k samples"]
    assert scan["significant"] and abs(scan["lag"] - 10) <= 2
    assert "late" in d.report()
    assert d.to_json()  # JSON-clean (no NaN)


@pytest.mark.slow
def test_a_grade_that_a_drivetrain_loss_imitates_is_not_named_with_confidence():
    """Light vehicle, 6 % grade: a Coulomb drivetrain loss tau_c / r = W sin(theta) explains the log as well
    (held-out shrink 0.73 for both, measured, Diebold-Mariano p = 0.25). Whichever of the pair is named, it is
    named with confidence 0.5 at most and the pair is listed, even though the stacking weights are 0.73/0.27
    (measured) and the pair was already listed by its sensitivities."""
    v = VEHICLES["light"]
    log = simulate(v, TERRAINS["lete_sand"], kind="drive", effects={"grade": 0.06}, seed=1, duration_s=60)
    d = diagnose(log, v)
    assert d.verdict in ("grade", "drivetrain_friction"), d.verdict
    assert d.converged
    assert d.confidence <= 0.5, (d.verdict, d.confidence)
    assert any(set(p) == {"grade", "drivetrain_friction"} for p, _, _ in d.confusable), d.confusable


@pytest.mark.slow
def test_an_effects_signature_in_time_is_not_a_change_of_terrain():
    # light vehicle, LETE sand, a 2 % radius error, the bench's doubled sensor noise, seed 1: the held-out gain of
    # radius_error is within the noise, but the nominal model's soil "differs" at 3.3-15 s (p = 3e-12); on the
    # radius_error fit no window differs. Measured before the rule: unexplained 1.00 (a change of terrain).
    from soiltrack.soilmodel import SensorNoise

    noise = SensorNoise(
        encoder_rel=0.01, encoder_abs=0.02, gnss_speed=0.1, imu_accel=0.1, torque_rel=0.02, torque_fs=0.002
    )
    v = VEHICLES["light"]
    log = simulate(
        v, TERRAINS["lete_sand"], kind="drive", effects={"radius_error": 0.02}, seed=1, noise=noise, duration_s=60.0
    )
    d = diagnose(log, v)
    assert d.verdict == "radius_error" and d.confidence <= 0.5
    assert any("signature in time, not a change of terrain" in n for n in d.notes)


@pytest.mark.slow
def test_an_effect_screening_left_out_is_tried_before_a_change_of_terrain():
    # heavy vehicle, LETE sand, slip_sinkage mu_s = 0.15, the bench's default noise, seed 1: no score test is
    # significant, so no candidate was refitted, but the nominal model's soil "differs" at 29.6-33.9 s (a hard
    # acceleration: high slip, so high slip-sinkage resistance; p = 8e-8). Measured before the rule: unexplained
    # 1.00 (a change of terrain). The strongest candidates by score are now fitted on the training part and the
    # window sought on their fits; slip_sinkage removes it and is named at 0.5, scored like a refitted candidate.
    v = VEHICLES["heavy"]
    log = simulate(v, TERRAINS["lete_sand"], kind="drive", effects={"slip_sinkage": 0.15}, seed=1, duration_s=60.0)
    d = diagnose(log, v)
    assert d.verdict == "slip_sinkage" and d.confidence <= 0.5, (d.verdict, d.confidence)
    assert any("signature in time, not a change of terrain" in n for n in d.notes)
    assert d.shrink is not None and d.shrink > 0.0
    mu_s = next(e.parameters for e in d.ranking if e.effect == "slip_sinkage")["mu_s"]
    assert abs(mu_s["value"] - 0.15) < 3 * mu_s["stderr"], mu_s


@pytest.mark.slow
def test_a_soft_patch_is_in_the_contracts_localisation():
    # heavy vehicle on LETE sand with 24-39 s driven on dry sand (the log spliced from two runs with the same speed
    # reference, as benchmarks/bench_diagnose.py does): the change of soil in time is the significant "time" entry of
    # the JSON's localisation (docs/data-formats.md), its range where the change shows (the change window's evidence),
    # inside the patch. Measured before the entry existed: the window only in the extra "change_window" field.
    import json

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
    j = json.loads(d.to_json())
    cw = j["change_window"]
    assert cw["significant"] and cw["start"] <= 24.0 + 1.0 and cw["end"] >= 39.0 - 1.0, cw
    entry = [
        e
        for e in j["localisation"]
        if e["dimension"] == "time" and e["significant"] and e["range"] == [cw["evidence_start"], cw["evidence_end"]]
    ]
    assert len(entry) == 1, j["localisation"]
    lo, hi = entry[0]["range"]
    assert 24.0 - 1.0 <= lo < hi <= 39.0 + 1.0, entry
    assert 0.0 <= entry[0]["share"] <= 1.0 and entry[0]["n"] > 0
    assert d.verdict == "unexplained" or d.confidence <= 0.5
    # said once in the report: the change's own line, not again as a localisation line
    assert not any(f"time {lo:.4g} to {hi:.4g}" in line for line in d.report().splitlines())


@pytest.mark.slow
def test_a_speed_sensor_scale_error_is_told_from_a_radius_error_by_the_torque_arm(tmp_path):
    # plain-numpy heavy logs, seed 5: the vehicle-speed column read 3 % high (a GNSS scale error, outside the
    # library), against seed 1 with a true 4 % radius error. Both offset the slip alike; only the radius divides the
    # sprocket thrust. Measured before the check: the scale error named radius_error with confidence 1.00 (eps 0.029)
    from soiltrack.identify.diagnosis.log_parts import torque_arm_check

    heavy = VEHICLES["heavy"]

    def reads_high(a):
        a[:, 3] *= 1.03

    d = diagnose(independent_log(tmp_path / "gnss.csv", 5, edit=reads_high), heavy)
    assert d.verdict == "unexplained", (d.verdict, d.confidence, d.reason)
    assert "vehicle-speed sensor" in d.reason
    assert any(e.effect == "radius_error" for e in d.ranking)
    d = diagnose(independent_log(tmp_path / "radius.csv", 1, radius=0.04), heavy)
    assert d.verdict == "radius_error" and d.confidence > 0.5, (d.verdict, d.confidence)
    assert any("the torque arm follows the slip offset" in n for n in d.notes)
    assert not any("also stands for a scale error of the vehicle-speed sensor" in n for n in d.notes)
    # the check itself on a simulated log: kappa within its noise of 0, several standard errors from eps
    from soiltrack.identify import fit

    log = simulate(
        VEHICLES["light"], TERRAINS["lete_sand"], kind="drive", effects={"radius_error": 0.02}, seed=1, duration_s=60.0
    )
    r = fit(log, VEHICLES["light"], effects=["radius_error"], hull_channel=True)
    eps = r.extra["joint_parameters"]["effects"]["radius_error.eps"]
    arm = torque_arm_check(r, log, VEHICLES["light"], eps)
    assert abs(eps - 0.02) < 0.003 and arm.z_radius < 2.58 <= arm.z_speed_scale, arm
