"""The on-line estimate's memory (issue 38): the held estimate between excitations, its growing
covariance, changes of terrain between pulls, on logs of an independent simulator (tests/online_oracle.py,
plain Python; its seeds here were not used to tune the estimator)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from online_oracle import SOILS, VEHICLES as OV, f_max, random_pulls, simulate
from soiltrack.identify import OnlineEstimator, OnlineSettings
from soiltrack.soilmodel import VEHICLES

KEYS = ("time_s", "sprocket_torque_Nm", "sprocket_speed_rad_s", "vehicle_speed_m_s")


def _replay(est, cols):
    return [est.update(*row) for row in zip(*(cols[k] for k in KEYS))]


def _weaker(frac: float, veh: dict):
    """LETE sand with F_max lowered by ``frac`` (c and tan(phi) scaled), K unchanged."""
    c, phi, K = SOILS["lete_sand"]
    F0 = f_max((c, phi, K), veh)
    c1 = c * (1 - frac)
    return c1, math.atan(((1 - frac) * F0 - 2 * veh["b"] * veh["l"] * c1) / veh["W"]), K


@pytest.fixture(scope="module")
def heavy_two_pulls():
    pulls = [(1.0, 4.0, 0.95), (26.0, 29.0, 0.95)]
    return simulate("heavy", lambda t: SOILS["lete_sand"], 32.0, pulls, seed=101)


def test_held_estimate_between_pulls_is_the_last_identified_with_variance_growing_at_the_rate(heavy_two_pulls):
    s = OnlineSettings()
    hist = _replay(OnlineEstimator(VEHICLES["heavy"], s), heavy_two_pulls)
    t = np.array([e.time_s for e in hist])
    gap = [e for e, tk in zip(hist, t) if 10.0 <= tk <= 25.0]  # the first pull has left the 5 s horizon
    assert all(e.held for e in gap)
    e0 = gap[0]
    assert e0.identifiable[:2] == ("slope", "max_thrust")
    assert e0.informed_at_s is not None and 2.0 <= e0.informed_at_s <= 4.0  # a sample of the pull
    # the last identified values, unchanged ...
    last_fused = [e for e, tk in zip(hist, t) if tk < 10.0 and not e.held][-1]
    for e in gap:
        assert e.max_thrust_N == last_fused.max_thrust_N
        assert e.shear_modulus_m == last_fused.shear_modulus_m
        assert e.informed_at_s == e0.informed_at_s
        assert e.converged and e.identifiable == e0.identifiable
    # ... with variances growing by (rate x value)^2 per second (the random walk)
    F, K = last_fused.max_thrust_N, last_fused.shear_modulus_m
    for e in gap[:: len(gap) // 10]:
        dt = e.time_s - last_fused.time_s
        assert e.max_thrust_stderr_N**2 == pytest.approx(
            last_fused.max_thrust_stderr_N**2 + (s.drift_max_thrust_rel * F) ** 2 * dt, rel=1e-9
        )
        if last_fused.shear_modulus_stderr_m is not None:  # K identified too (else its error is not reported)
            assert e.shear_modulus_stderr_m**2 == pytest.approx(
                last_fused.shear_modulus_stderr_m**2 + (s.drift_shear_modulus_rel * K) ** 2 * dt, rel=1e-9
            )
            assert e.covariance[0, 1] == pytest.approx(last_fused.covariance[0, 1], rel=1e-12)
    # the truth inside the held 95 % interval, and the second pull's estimate tighter than the held one
    F_true = f_max(SOILS["lete_sand"], OV["heavy"])
    assert abs(gap[-1].max_thrust_N - F_true) <= 1.96 * gap[-1].max_thrust_stderr_N
    assert hist[-1].max_thrust_stderr_N < gap[-1].max_thrust_stderr_N
    assert abs(hist[-1].max_thrust_N / F_true - 1) <= 0.05


def test_window_estimator_kept_as_an_option(heavy_two_pulls):
    """``memory=False``: the horizon's fit alone, nothing held once the pull has left it."""
    hist = _replay(OnlineEstimator(VEHICLES["heavy"], OnlineSettings(memory=False)), heavy_two_pulls)
    gap = [e for e in hist if 10.0 <= e.time_s <= 25.0]
    assert not any(e.held for e in gap)
    assert all(e.max_thrust_stderr_N is None for e in gap)


def _change_case(vehicle: str, pulls, t_change: float, seed: int, grade_deg: float = 0.0):
    veh = OV[vehicle]
    new = _weaker(0.28, veh)
    cols = simulate(
        vehicle,
        lambda t: SOILS["lete_sand"] if t < t_change else new,
        pulls[-1][1] + 3.0,
        pulls,
        grade_deg=grade_deg,
        seed=seed,
    )
    est = OnlineEstimator(VEHICLES[vehicle], OnlineSettings(grade_rad=math.radians(grade_deg)))
    hist = _replay(est, cols)
    t = np.array(cols["time_s"])
    inf = np.nonzero((t >= t_change) & (np.array(cols["thrust"]) >= 0.5 * np.array(cols["F_max"])))[0]
    return est, hist, float(t[inf[0]]), cols


@pytest.mark.slow
@pytest.mark.parametrize(
    "vehicle, pulls, t_change, grade",
    [
        ("heavy", [(1.0, 4.0, 0.95), (12.0, 15.0, 0.95), (30.0, 33.0, 0.95)], 21.0, 0.0),
        ("light", [(1.0, 1.3, 0.95), (9.0, 9.25, 0.95), (17.0, 17.3, 0.95), (31.0, 31.2, 0.95)], 24.0, 10.0),
    ],
)
def test_change_between_pulls_detected_at_the_next_pull(vehicle, pulls, t_change, grade):
    est, hist, t_inf, cols = _change_case(vehicle, pulls, t_change, seed=202, grade_deg=grade)
    flagged = [e for e in hist if e.change_detected]
    assert len(flagged) == 1, [e.time_s for e in flagged]
    e = flagged[0]
    assert t_inf <= e.time_s <= t_inf + 1.0  # within 1 s after the first informative sample on the new soil
    lo, hi = e.change_window_s
    assert lo <= t_change <= hi  # the window holds the true time ...
    assert lo >= pulls[-2][0]  # ... and starts at the last pull on the old soil
    assert lo <= e.change_time_s <= hi
    c = est.changes[0]
    assert c["window_s"] == [lo, hi] and c["detected_at_s"] == e.time_s and c["time_s"] == e.change_time_s
    # the old soil's information dropped: the estimate at the end is the new soil's
    F_new = cols["F_max"][-1]
    assert abs(hist[-1].max_thrust_N / F_new - 1) <= 0.05
    assert abs(hist[-1].max_thrust_N - F_new) <= 1.96 * hist[-1].max_thrust_stderr_N


@pytest.mark.slow
@pytest.mark.parametrize("vehicle, length", [("heavy", (2.0, 4.0)), ("light", (0.1, 0.3))])
def test_no_alarm_on_uniform_soil_with_sporadic_pulls(vehicle, length):
    _uniform(vehicle, length, coverage=False)


@pytest.mark.slow
@pytest.mark.parametrize("vehicle, length", [("heavy", (2.0, 4.0)), ("light", (0.1, 0.3))])
def test_held_intervals_hold_the_truth_on_uniform_soil(vehicle, length):
    """The light vehicle's 0.1-0.3 s pulls: with the end-point rule the held value carried its bias
    (+2.6 % median, 78 % coverage measured); the slip-relaxation rule (the default) removes it."""
    _uniform(vehicle, length, coverage=True)


def _uniform(vehicle, length, coverage: bool):
    from online_oracle import random_pulls

    pulls = random_pulls(180.0, (5.0, 30.0), length, (0.9, 0.97), seed=303)
    cols = simulate(vehicle, lambda t: SOILS["lete_sand"], 180.0, pulls, seed=303)
    est = OnlineEstimator(VEHICLES[vehicle])
    hist = _replay(est, cols)
    assert est.changes == []
    F_true = cols["F_max"][0]
    ident = [e for e in hist if e.max_thrust_stderr_N is not None]
    assert ident and all(e.max_thrust_N is not None for e in hist if e.time_s > ident[0].time_s)
    # held between pulls: identified from the first pull on (F_max and its interval at every update)
    first = ident[0].time_s
    assert all(e.max_thrust_stderr_N is not None for e in hist if e.time_s > first + 1.0)
    if coverage:
        cover = np.mean([abs(e.max_thrust_N - F_true) <= 1.96 * e.max_thrust_stderr_N for e in ident])
        assert cover >= 0.8


def test_settings_of_the_memory_checked():
    from soiltrack.soilmodel import DataError

    for bad in (dict(drift_max_thrust_rel=-1.0), dict(detect_window_chi2=0.0), dict(memory="yes")):
        with pytest.raises(DataError):
            OnlineSettings(**bad)
    assert OnlineSettings(drift_max_thrust_rel=0.0).drift_max_thrust_rel == 0.0


@pytest.mark.slow
def test_a_pull_ramp_horizon_raises_no_alarm_on_uniform_soil():
    """Horizons seeing only a pull's ramp (no sample at 80 % of their F_max) are not tested against the held estimate.

    The uniform heavy log of the benchmark (seed 900, the one that showed the mechanism; the log is cut at 170 s):
    with the plateau rule switched off (``detect_window_min_load`` ~ 0) a ramp horizon's F_max (177 +- 10 kN,
    correlation 0.95 with K, truth 202 kN) raises a false alarm at 162.8 s; with the rule, none.
    """
    pulls = random_pulls(170.0, (5, 30), (2.0, 4.0), (0.9, 0.97), 900)
    cols = simulate("heavy", lambda t: SOILS["lete_sand"], 170.0, pulls, grade_deg=0.0, seed=900)
    truth = f_max(SOILS["lete_sand"], OV["heavy"])
    off = OnlineEstimator(VEHICLES["heavy"], OnlineSettings(detect_window_min_load=1e-9))
    _replay(off, cols)
    assert len(off.changes) >= 1 and off.changes[0]["test"] == "horizon"  # the mechanism is there without the rule
    est = OnlineEstimator(VEHICLES["heavy"], OnlineSettings())
    hist = _replay(est, cols)
    assert est.changes == []
    held = [e for e in hist if e.max_thrust_stderr_N is not None and e.time_s > 20.0]
    assert held and all(abs(e.max_thrust_N - truth) <= 3.0 * e.max_thrust_stderr_N for e in held[-50:])


def test_plateau_setting_is_checked():
    with pytest.raises(Exception, match="detect_window_min_load"):
        OnlineSettings(detect_window_min_load=0.0)


@pytest.mark.slow
def test_a_held_estimate_of_one_excitation_declares_no_change():
    """A held estimate resting on one excitation is started again, not contradicted (``detect_min_excitations``).

    The heavy vehicle on 10 deg (uniform soil, the benchmark's scenario seed 8): the first pull's ramp held 154 +- 8 kN,
    the horizon on the same pull's plateau said 228 +- 9 kN (truth 199 kN): with the rule off a false alarm at 7.1 s.
    """
    pulls = random_pulls(120.0, (20, 30), (2.0, 4.0), (0.9, 0.97), 8)[:1]
    cols = simulate("heavy", lambda t: SOILS["lete_sand"], 12.0, pulls, grade_deg=10.0, seed=8)
    g = math.radians(10.0)
    # the mechanism is there without the rule - and without the first estimate's likelihood-ratio check
    # (identify_reject_factor): that check alone no longer holds the ramp's 120 +- 7 kN at 1.98 s (the first
    # held estimate is 203 +- 10 kN at 2.38 s), so it raises no alarm either
    off = OnlineEstimator(
        VEHICLES["heavy"], OnlineSettings(grade_rad=g, detect_min_excitations=1, identify_reject_chi2=1e-9)
    )
    _replay(off, cols)
    assert len(off.changes) >= 1
    lr_only = OnlineEstimator(VEHICLES["heavy"], OnlineSettings(grade_rad=g, detect_min_excitations=1))
    _replay(lr_only, cols)
    assert lr_only.changes == []
    est = OnlineEstimator(VEHICLES["heavy"], OnlineSettings(grade_rad=g))
    hist = _replay(est, cols)
    assert est.changes == []
    truth = cols["F_max"][-1]
    assert hist[-1].max_thrust_stderr_N is not None and abs(hist[-1].max_thrust_N / truth - 1) <= 0.1


def test_excitation_setting_is_checked():
    with pytest.raises(Exception, match="detect_min_excitations"):
        OnlineSettings(detect_min_excitations=0)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_a_gentle_start_up_is_not_an_identified_max_thrust(seed):
    """A gentle pull at the start (thrust to 30 % of F_max for 1.3 s, heavy vehicle, 25 Hz, then cruising):
    the first horizons hold 3-20 samples of the curve's initial slope. Before ``identify_min_samples`` and the
    converged-iterate rule, a horizon of 8 samples (or one whose iteration had not converged) reported F_max
    identified near the thrust it saw; it was held and nothing after corrected it. Measured on these seeds:
    first identified 51.6 +- 5.7, 66.7 +- 7.6, 87.7 +- 11.1, 35.4 +- 6.6 kN against 202.1 kN (worst z -26.4,
    -23.2, -10.3, -37.6); now F_max is not identified (the slope only)."""
    cols = simulate("heavy", lambda t: SOILS["lete_sand"], 8.0, [(0.2, 1.5, 0.3)], rate=25.0, seed=seed)
    truth = cols["F_max"][0]
    for e in _replay(OnlineEstimator(VEHICLES["heavy"]), cols):
        if "max_thrust" in e.identifiable:
            z = (e.max_thrust_N - truth) / e.max_thrust_stderr_N
            assert abs(z) < 4.0, (e.time_s, e.max_thrust_N, e.max_thrust_stderr_N, truth)


def test_identify_min_samples_is_checked():
    with pytest.raises(Exception, match="identify_min_samples"):
        OnlineSettings(identify_min_samples=0)


@pytest.mark.slow
def test_nothing_held_nothing_tested():
    """Before anything is held the CUSUM does not run: the light vehicle, flat, pulls every 20-30 s (the
    benchmark's scenario seed 12, uniform up to 50 s) raised a false alarm at 47.06 s against the horizon's own
    iterate (residuals +3 to +7 over a 0.1 s pull), which no horizon had fused."""
    pulls = random_pulls(120.0, (20, 30), (0.1, 0.3), (0.9, 0.97), 12)
    cols = simulate("light", lambda t: SOILS["lete_sand"], 50.0, pulls, grade_deg=0.0, seed=12)
    est = OnlineEstimator(VEHICLES["light"])
    _replay(est, cols)
    assert est.changes == []


@pytest.mark.slow
def test_few_plateau_samples_need_a_larger_contradiction():
    """The horizon test's threshold grows as its plateau thins (``detect_window_plateau_samples``).

    The tuning set's first log (``bench_online.py --set tuning``: heavy, flat, pulls every 4-6 s, F_max down 29 %
    at 71.37 s, seed 3001): 0.4 s into the pull at 59.3 s a horizon with 3-4 samples on its plateau said F_max
    179 +- 6 kN against a held 205 +- 2 kN (truth 202 kN), d2 45.8 and 35.0: with the threshold unscaled
    (``detect_window_plateau_samples=1``) a false alarm at 59.78 s; now none, and the change is flagged at the
    first pull on the new soil (d2 259 from 5 plateau samples) with its window holding the true time."""
    veh = OV["heavy"]
    old = SOILS["lete_sand"]
    c, phi, K = old
    s = 1 - 0.2873030873840089
    c1 = c * s
    new = (c1, math.atan((s * f_max(old, veh) - 2 * veh["b"] * veh["l"] * c1) / veh["W"]), K)
    tc = 71.36700734450065
    pulls = random_pulls(150.0, (4.0, 6.0), (2.0, 4.0), (0.9, 0.97), 3001)
    cols = simulate("heavy", lambda t: old if t < tc else new, 90.0, pulls, seed=3001)
    off = OnlineEstimator(VEHICLES["heavy"], OnlineSettings(detect_window_plateau_samples=1))
    _replay(off, cols)
    assert off.changes and off.changes[0]["detected_at_s"] < tc  # the mechanism is there without the rule
    est = OnlineEstimator(VEHICLES["heavy"])
    _replay(est, cols)
    assert len(est.changes) == 1
    ch = est.changes[0]
    assert tc < ch["detected_at_s"] <= 76.2 and ch["window_s"][0] <= tc <= ch["window_s"][1]
    with pytest.raises(Exception, match="detect_window_plateau_samples"):
        OnlineSettings(detect_window_plateau_samples=0)
