"""On-line estimator: agreement with the batch fit, change detection, gentle driving, gaps."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import bench_module
from soiltrack.identify import OnlineEstimate, OnlineEstimator, OnlineSettings, fit
from soiltrack.soilmodel import TERRAINS, VEHICLES, max_thrust, simulate_drive_log

LIGHT = VEHICLES["light"]
Z95 = 1.959963984540054


@pytest.fixture(scope="module")
def bench():
    return bench_module("bench_online")


@pytest.fixture(scope="module")
def sand_log():
    return simulate_drive_log(LIGHT, TERRAINS["lete_sand"], seed=2, duration_s=40, sample_rate_hz=50)


def _replay(est, log, upto=None):
    out = []
    for k in range(log.n_samples if upto is None else upto + 1):
        out.append(est.update(log.time[k], log.sprocket_torque[k], log.sprocket_speed[k], log.vehicle_speed[k]))
    return out


def _batch(log, k, window):
    k0 = int(np.searchsorted(log.time, log.time[k] - window)) - 1
    return fit(log.subset(slice(max(k0, 0), k + 1)), LIGHT)


def test_estimate_is_a_frozen_record_with_the_planning_fields(sand_log):
    e = _replay(OnlineEstimator(LIGHT), sand_log, upto=400)[-1]
    assert isinstance(e, OnlineEstimate)
    with pytest.raises(AttributeError):
        e.max_thrust_N = 1.0
    for name in (
        "time_s",
        "max_thrust_N",
        "max_thrust_stderr_N",
        "shear_modulus_m",
        "shear_modulus_stderr_m",
        "covariance",
        "normal_load_N",
        "identifiable",
        "slip",
        "change_detected",
        "samples_used",
        "samples_skipped",
        "converged",
        "status",
    ):
        assert hasattr(e, name)
    assert e.normal_load_N == pytest.approx(LIGHT.weight)


@pytest.mark.slow
def test_agrees_with_the_batch_fit_of_the_same_window_within_its_95_percent_interval(sand_log):
    """Estimated noise levels (as the batch fit estimates them, from the window).

    The horizon's own fit (``memory=False``): with the memory on, the reported value is the horizon
    fused with its arrival cost (tests/test_online_memory.py).
    """
    window = 5.0
    # the batch fit's default discretisation (end-point) on both sides: with the relaxation rule (the
    # on-line default) the horizon's newest five samples wait for their slip trend, so it holds fewer
    # samples than the batch window (the relaxation rule against the batch one: the known-noise test)
    est = OnlineEstimator(LIGHT, OnlineSettings(window_s=window, memory=False, relaxation=False))
    hist = _replay(est, sand_log)
    checked = 0
    for t in (5.0, 6.0, 23.0, 24.0, 25.0, 26.0):
        k = int(round(t * 50))
        e = hist[k]
        r = _batch(sand_log, k, window)
        sF = r.extra.get("max_thrust_stderr_N")
        if e.max_thrust_stderr_N is None or sF is None:
            continue
        checked += 1
        assert abs(e.max_thrust_N - r.extra["max_thrust_N"]) <= Z95 * sF, t
        sK = r.extra.get("shear_modulus_stderr_m")
        assert abs(e.shear_modulus_m - r.extra["shear_modulus_m"]) <= Z95 * sK, t
        assert abs(e.samples_used - r.extra["samples_used"]) <= 0.05 * r.extra["samples_used"]
    assert checked >= 4


@pytest.mark.parametrize(
    "relaxation",
    [
        False,
        pytest.param(
            True,
            marks=pytest.mark.xfail(
                strict=True,
                reason="issue 38, open: on-line 305.0 N against the batch relaxation fit of the same samples 304.2 N "
                "(0.26 %, 0.1 SE; 304.1 N before the samples were held back); cause not established",
            ),
        ),
    ],
)
def test_with_known_noise_the_online_optimum_is_the_batch_optimum(sand_log, relaxation):
    """The horizon's fit against the batch fit of the same window, with the same discretisation.

    ``relaxation=False``: the end-point rule of both. ``True`` (the on-line default): the batch fit's
    ``discretisation="relaxation"`` of the samples in the horizon's fit (the newest five wait for their
    slip trend); the on-line weights differ in their pilot soil, so K (on the batch fit's bound here)
    is not compared.
    """
    sig = dict(sigma_torque=0.04, sigma_sprocket_speed=0.005, sigma_vehicle_speed=0.05)
    window, k = 5.0, int(round(25.0 * 50))
    settings = OnlineSettings(window_s=window, detect_threshold=1e9, memory=False, relaxation=relaxation, **sig)
    est = OnlineEstimator(LIGHT, settings)
    e = _replay(est, sand_log, upto=k)[-1]
    end = k + 1 - len(est.held_back())  # the samples in the horizon's fit (the newest wait for their slip trend)
    r = fit(
        sand_log.subset(slice(int(np.searchsorted(sand_log.time, sand_log.time[k] - window)) - 1, end)),
        LIGHT,
        discretisation="relaxation" if relaxation else "end-point",
        **sig,
    )
    assert e.converged
    assert e.max_thrust_N == pytest.approx(r.extra["max_thrust_N"], rel=2e-3)
    if not relaxation:
        assert e.shear_modulus_m == pytest.approx(r.extra["shear_modulus_m"], rel=1e-2)
    assert e.max_thrust_stderr_N == pytest.approx(r.extra["max_thrust_stderr_N"], rel=2e-2)


@pytest.mark.slow
def test_change_of_terrain_detected_dated_and_the_new_soil_learnt(bench):
    log, truth = bench.change_log(50.0, seed=11)
    hist = _replay(OnlineEstimator(LIGHT), log)
    changes = [(e.time_s, e.change_time_s) for e in hist if e.change_detected]
    assert len(changes) == 1
    detected, dated = changes[0]
    assert 0.0 <= detected - bench.CHANGE_TIME_S <= 1.0
    assert abs(dated - bench.CHANGE_TIME_S) <= 2.0
    F_new = max_thrust(TERRAINS["snow"], LIGHT, normal_load=LIGHT.weight * math.cos(math.radians(bench.GRADE_DEG)))
    e = hist[int(round((bench.CHANGE_TIME_S + 5.0) * 50))]
    assert "max_thrust" in e.identifiable
    assert abs(e.max_thrust_N / F_new - 1) <= 0.05
    assert e.samples_used <= 5.0 * 50 + 1


@pytest.mark.slow
@pytest.mark.parametrize("name", ["light", "heavy"])
def test_no_change_flagged_on_uniform_soil(name):
    veh = VEHICLES[name]
    log = simulate_drive_log(veh, TERRAINS["lete_sand"], seed=1, duration_s=60, sample_rate_hz=50)
    est = OnlineEstimator(veh)
    hist = _replay(est, log)
    assert not any(e.change_detected for e in hist)
    assert est.changes == []


@pytest.mark.slow
def test_gentle_driving_is_not_reported_as_identifying_f_max():
    gentle = [(0.0, 0.0), (2.0, 0.0), (12.0, 1.2), (30.0, 1.2)]  # 0.12 m/s^2 ramp, cruise
    log = simulate_drive_log(
        LIGHT, TERRAINS["lete_sand"], seed=4, duration_s=30, sample_rate_hz=50, speed_profile=gentle
    )
    hist = _replay(OnlineEstimator(LIGHT), log)
    late = [e for e in hist if e.time_s > 4.0]
    assert all(e.identifiable in ((), ("slope",)) for e in late)
    assert all(
        e.max_thrust_stderr_N is None and e.shear_modulus_stderr_m is None and e.covariance is None for e in late
    )
    # the batch fit of the last window agrees: a gentle log, F_max undetermined (25 % or worse)
    r = fit(log.subset(slice(log.n_samples - 252, log.n_samples)), LIGHT)
    assert r.extra["regime"] == "gentle"


def test_dropouts_are_skipped_and_counted(sand_log):
    rng = np.random.default_rng(0)
    k_end = int(round(25.0 * 50))  # the horizon holds the second hard start
    drop = np.sort(rng.choice(np.arange(100, k_end), size=40, replace=False))
    est = OnlineEstimator(LIGHT, OnlineSettings(detect_threshold=1e9))
    ref = OnlineEstimator(LIGHT, OnlineSettings(detect_threshold=1e9))
    for k in range(k_end + 1):
        row = [
            sand_log.time[k],
            sand_log.sprocket_torque[k],
            sand_log.sprocket_speed[k],
            sand_log.vehicle_speed[k],
        ]
        r = ref.update(*row)
        if k in drop:
            row[1 + k % 3] = float("nan") if k % 2 else None
        e = est.update(*row)
    assert e.samples_skipped == drop.size
    assert e.samples_seen == k_end + 1
    assert e.samples_used < r.samples_used
    # the estimate rests on fewer samples, not on wrong ones: within the full one's 95 % interval
    assert r.max_thrust_stderr_N is not None and e.max_thrust_stderr_N is not None
    assert abs(e.max_thrust_N - r.max_thrust_N) <= Z95 * r.max_thrust_stderr_N


def test_irregular_time_steps(sand_log):
    rng = np.random.default_rng(1)
    keep = np.concatenate([[0], np.sort(rng.choice(np.arange(1, sand_log.n_samples), size=1500, replace=False))])
    sub = sand_log.subset(keep)  # steps of 1, 2, 3 ... sample intervals
    steps = np.diff(sub.time)
    assert steps.min() < steps.max() / 2
    est = OnlineEstimator(LIGHT, OnlineSettings(detect_threshold=1e9))
    hist = _replay(est, sub)
    ident = [e for e in hist if "max_thrust" in e.identifiable and 23.0 < e.time_s < 27.0]
    assert ident, "a hard start in the last horizons is identified"
    F_true = max_thrust(TERRAINS["lete_sand"], LIGHT)
    assert all(abs(e.max_thrust_N - F_true) <= 3 * e.max_thrust_stderr_N for e in ident)


def test_two_track_update_leaves_turns_out(bench, sand_log):
    turns = [(12.0, 13.0), (23.5, 24.5)]  # while moving (a turn at standstill shows nothing)
    cols = bench.two_track(sand_log, turns, seed=3)
    n_turn = int(np.count_nonzero(cols["_turning"]))
    k_end = int(round(26.0 * 50))
    straight = OnlineEstimator(LIGHT, OnlineSettings(detect_threshold=1e9))
    tracks = OnlineEstimator(LIGHT, OnlineSettings(detect_threshold=1e9))
    naive = OnlineEstimator(LIGHT, OnlineSettings(detect_threshold=1e9))
    for k in range(k_end + 1):
        args = [
            cols[c][k]
            for c in (
                "time_s",
                "sprocket_torque_left_Nm",
                "sprocket_torque_right_Nm",
                "sprocket_speed_left_rad_s",
                "sprocket_speed_right_rad_s",
                "vehicle_speed_m_s",
            )
        ]
        e = tracks.update_tracks(*args, yaw_rate=cols["yaw_rate_rad_s"][k])
        n = naive.update(args[0], args[1] + args[2], 0.5 * (args[3] + args[4]), args[5])
        s = straight.update(
            sand_log.time[k],
            sand_log.sprocket_torque[k],
            sand_log.sprocket_speed[k],
            sand_log.vehicle_speed[k],
        )
    # LIGHT has no tread_m: the steering model cannot fit the turns; they are counted as not fitted
    assert e.samples_turning == 0 and tracks.turning.not_fitted["no_tread"] == tracks.turning.samples_not_fitted
    assert n_turn <= tracks.turning.samples_not_fitted <= n_turn + 2 * len(turns)
    assert e.samples_used < s.samples_used
    # the turns left out: the estimate stays within the straight-line one's interval
    assert s.max_thrust_stderr_N is not None
    assert abs(e.max_thrust_N - s.max_thrust_N) <= Z95 * s.max_thrust_stderr_N
    assert n.samples_turning == 0 and n.samples_used > e.samples_used


@pytest.mark.slow
def test_two_track_columns_summed_and_turning_marked(bench, sand_log, tmp_path):
    from soiltrack.soilmodel import read_csv

    cols = bench.two_track(sand_log, [(10.0, 12.0)], seed=5)
    path = tmp_path / "tracks.csv"
    names = [c for c in cols if not c.startswith("_")]
    np.savetxt(path, np.column_stack([cols[c] for c in names]), delimiter=",", header=",".join(names), comments="")
    log = read_csv(path)
    assert np.allclose(log.sprocket_torque, cols["sprocket_torque_left_Nm"] + cols["sprocket_torque_right_Nm"])
    assert np.allclose(
        log.sprocket_speed, 0.5 * (cols["sprocket_speed_left_rad_s"] + cols["sprocket_speed_right_rad_s"])
    )
    truth = cols["_turning"]
    assert np.all(log.turning[truth])  # every turning sample recognised
    assert np.count_nonzero(log.turning & ~truth) <= 2  # only a turn's edges besides
    # the batch fit leaves them out and says how many
    r = fit(log, LIGHT)
    assert r.extra["samples_turning"] == log.n_turning
    r0 = fit(sand_log, LIGHT)
    assert r.extra["samples_used"] <= r0.extra["samples_used"] - np.count_nonzero(truth)
