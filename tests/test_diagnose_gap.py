"""Localisation, screening and decision logic of the diagnosis on synthetic residual arrays (no fits)."""

import math

import numpy as np
import pytest

from soiltrack.identify.diagnosis.gap import (
    blocked_folds,
    chi2_isf,
    chi2_sf,
    change_window,
    lag_peak,
    localise,
    noise_profile,
    long_run_factor,
    noise_floor,
    whiteness,
)
from soiltrack.identify.diagnosis.screening import project_off, score_test
from soiltrack.identify.diagnosis.selection import (
    confusable_groups,
    dm_test,
    fit_discrepancy,
    hat_basis,
    separating_experiment,
)


def test_chi2_matches_known_quantiles():
    # textbook values: chi2(1) 95 % = 3.841, chi2(10) 99 % = 23.209, chi2(100) 95 % = 124.342
    assert chi2_sf(3.841459, 1) == pytest.approx(0.05, abs=1e-6)
    assert chi2_sf(23.209251, 10) == pytest.approx(0.01, abs=1e-6)
    assert chi2_isf(0.05, 100) == pytest.approx(124.342, abs=1e-3)
    assert chi2_sf(0.0, 3) == 1.0 and chi2_sf(math.inf, 3) == 0.0


def test_blocked_folds_are_contiguous_alternate_and_cover():
    (a, b), (c, d) = blocked_folds(100, 10)
    assert np.array_equal(a, d) and np.array_equal(b, c)
    assert np.array_equal(np.sort(np.concatenate([a, b])), np.arange(100))
    # 10 blocks of 10: held-out part = blocks 1, 3, 5, 7, 9
    assert np.array_equal(b[:10], np.arange(10, 20)) and b.size == 50


def test_noise_floor_ignores_a_smooth_gap():
    rng = np.random.default_rng(0)
    t = np.linspace(0, 1, 2000)
    r = 5.0 * np.sin(2 * np.pi * t) + 0.3 * rng.standard_normal(t.size)
    assert noise_floor(r) == pytest.approx(0.3, rel=0.08)
    assert long_run_factor(0.3 * rng.standard_normal(2000)) == pytest.approx(1.0, abs=0.3)


def test_change_window_finds_a_shifted_block_with_start_and_end():
    rng = np.random.default_rng(1)
    t = np.arange(3000) * 0.02  # 60 s at 50 Hz
    r = rng.standard_normal(t.size)
    r[(t >= 21.0) & (t < 37.0)] += 0.5  # a softer patch from 21 s to 37 s
    w = change_window(r, t, 1.0, channel="thrust_N")
    assert w.significant
    assert w.start == pytest.approx(21.0, abs=0.7) and w.end == pytest.approx(37.0, abs=0.7)
    assert w.shift == pytest.approx(0.5, abs=0.1)
    # pure noise: no significant window
    w0 = change_window(rng.standard_normal(t.size), t, 1.0)
    assert not w0.significant


def test_localise_points_at_the_range_and_channel():
    rng = np.random.default_rng(2)
    n = 1200
    slip = np.linspace(0.01, 0.7, n)
    a = rng.standard_normal(n)
    a[slip > 0.5] += 2.0
    b = rng.standard_normal(n)
    segs = localise({"F": a, "G": b}, {"F": 1.0, "G": 1.0}, {"slip": slip})
    top = segs[0]
    assert top.dimension == "channel" and top.channel == "F" and top.significant
    sl = [s for s in segs if s.dimension == "slip"]
    best = max(sl, key=lambda s: s.share)
    assert best.channel == "F" and best.range[0] > 0.45 and best.significant
    assert not any(s.significant for s in sl if s.channel == "G")
    assert sum(s.share for s in sl) == pytest.approx(1.0)


def test_lag_peak_shows_a_delay():
    rng = np.random.default_rng(3)
    x = np.convolve(rng.standard_normal(3000), np.ones(5) / 5, mode="same")
    r = 0.2 * rng.standard_normal(3000)
    r[7:] += x[:-7]  # residuals follow the input 7 samples late
    lg = lag_peak(r, x)
    assert lg["lag"] == 7 and lg["corr"] > 5 * lg["bound"]
    assert whiteness(r)["white"] is False
    assert whiteness(rng.standard_normal(3000))["white"] is True


def test_score_test_zero_without_and_large_with_the_effect():
    rng = np.random.default_rng(4)
    n = 400
    x = np.linspace(0, 1, n)
    J_soil = np.column_stack([np.ones(n), x])
    Z = np.column_stack([x**2])
    # residuals at the nominal fit: exactly zero (noise-free, effect-free) -> score 0
    s0 = score_test("e", J_soil, Z, np.zeros(n))
    assert s0.score == 0.0 and s0.statistic == 0.0
    # an effect the soil can absorb (in its column space) leaves no score after projection
    r_abs = project_off(np.column_stack([3 * x**2]), J_soil).ravel() * 0 + (0.5 + 2 * x)
    assert score_test("e", J_soil, np.column_stack([1 + x]), r_abs).screenable is False
    # the effect in the residuals (projected off the soil, as at a least-squares optimum)
    r = project_off(Z * 2.0, J_soil).ravel() + 0.05 * rng.standard_normal(n)
    s1 = score_test("e", J_soil, Z, r)
    assert s1.p_value < 1e-10 and s1.score > 0.5
    # noise only: p-value not small (seeded)
    s2 = score_test("e", J_soil, Z, project_off(0.05 * rng.standard_normal((n, 1)), J_soil).ravel())
    assert s2.p_value > 0.01
    # HAC variance is more cautious on correlated residuals than the lag-0 (White) one
    rc = np.convolve(rng.standard_normal(n + 20), np.ones(20) / 20, mode="valid")[:n]
    rc = project_off(rc[:, None], J_soil).ravel()
    assert score_test("e", J_soil, Z, rc, hac_lag=20).statistic < score_test("e", J_soil, Z, rc, hac_lag=0).statistic


def test_discrepancy_spline_predicts_a_smooth_gap_between_blocks():
    x = np.linspace(0, 1, 200)
    y = np.sin(3 * x)
    for tr, te in blocked_folds(200, 10):  # one fold extrapolates linearly to the end block
        pred, k = fit_discrepancy(x[tr], y[tr], x[te], 8)
        assert k == 8 and np.max(np.abs(pred - y[te])) < 0.04  # measured 0.026 and 0.022
    B = hat_basis(x, np.linspace(0, 1, 5))
    assert np.allclose(B.sum(axis=1), 1.0)


def test_diebold_mariano_needs_more_than_one_lucky_residual():
    rng = np.random.default_rng(6)
    a = rng.standard_normal(300)
    assert dm_test(a + 1.0, a) < 1e-6  # a steady gain over 300 samples
    b = a.copy()
    b[0] = 0.0
    a2 = a.copy()
    a2[0] = 8.0  # one big residual in model a only
    assert dm_test(a2, b) > 0.05
    assert dm_test(a, a + 1.0) > 0.99


def test_confusable_pairs_and_experiments():
    d = np.array([1.0, 2.0, 3.0])
    dirs = {"grade": d, "mass_error": 2 * d, "radius_error": np.array([1.0, -1.0, 0.0]), "hump_shear": -d}
    pairs = confusable_groups({"grade": 0.45, "mass_error": 0.40, "radius_error": 0.01, "hump_shear": 0.001}, dirs)
    assert [p for p, _, _ in pairs] == [("grade", "mass_error")] and pairs[0][1] == pytest.approx(1.0)
    # collinear sensitivities but clearly different weights: the refit told them apart
    assert confusable_groups({"grade": 0.95, "hump_shear": 0.01, "radius_error": 0.04}, dirs) == []
    # close weights but unrelated sensitivities: not confusable (each changes something different)
    assert confusable_groups({"grade": 0.5, "radius_error": 0.5}, dirs) == []
    assert "payload" in separating_experiment("mass_error", "grade")
    assert "coast-down" in separating_experiment("drivetrain_friction", "speed_resistance")
    assert "high slip" in separating_experiment("slip_sinkage", "hump_shear")


def test_noise_profile_follows_a_varying_noise_level():
    rng = np.random.default_rng(5)
    x = np.linspace(0, 1, 3000)
    sd = 0.1 + 0.9 * x  # noise grows tenfold along the data
    r = np.sin(4 * x) + sd * rng.standard_normal(x.size)
    prof = noise_profile(r)
    assert prof[100] == pytest.approx(sd[100], rel=0.2) and prof[2900] == pytest.approx(sd[2900], rel=0.2)
    # standardised by the profile, the noise is unit-variance everywhere
    z = (r - np.sin(4 * x)) / prof
    assert np.std(z[:1000]) == pytest.approx(1.0, abs=0.15) and np.std(z[-1000:]) == pytest.approx(1.0, abs=0.15)


def test_range_share_is_on_the_scale_of_the_localisation_bins():
    # a change window's entry sits beside localise's time ranges: a window covering exactly two of the six
    # ranges has their summed share, one covering one of them that range's share (misfit only in channel b)
    from soiltrack.identify.diagnosis.gap import localise, range_share

    t = np.arange(600.0)
    zb = np.where((t >= 200) & (t < 400), 3.0, 0.0)
    R = {"a": np.zeros(600), "b": zb}
    sig = {"a": np.ones(600), "b": np.ones(600)}
    segs = [s for s in localise(R, sig, {"time": t}) if s.dimension == "time" and s.channel == "b"]
    inside = [s for s in segs if s.range[0] >= 200 and s.range[1] < 400]
    assert len(inside) == 2 and sum(s.share for s in inside) == pytest.approx(1.0)
    ch, share = range_share(R, sig, t, 200.0, 399.0)
    assert ch == "b" and share == pytest.approx(sum(s.share for s in inside))
    ch, share = range_share(R, sig, t, inside[0].range[0], inside[0].range[1])
    assert ch == "b" and share == pytest.approx(inside[0].share)
    assert range_share(R, sig, t, 0.0, 150.0)[1] == 0.0


@pytest.mark.parametrize("split", [False, True])
def test_local_noise_medians_follow_their_definition(split):
    # the vectorised local medians of isolated_outliers against the definition read literally, reading by reading:
    # half second differences on each side, leaving out the three the reading enters, a side counting from 3 values
    from soiltrack.identify.diagnosis.gap import local_medians

    rng = np.random.default_rng(7)
    for n, half in ((9, 3), (40, 5), (300, 21), (301, 150)):
        d = np.abs(rng.normal(size=n - 2)) * (1 + (np.arange(n - 2) > n // 2))
        got = local_medians(d, n, half, split)
        for k in range(2, n - 2):
            left, right = d[max(0, k - 2 - half) : k - 2], d[k + 1 : k + 1 + half]
            if split:
                sides = [float(np.median(v)) for v in (left, right) if v.size >= 3]
                want = max(sides) if sides else 0.0
            else:
                both = np.concatenate([left, right])
                want = float(np.median(both)) if both.size >= 3 else 0.0
            assert got[k] == pytest.approx(want, rel=1e-14, abs=0.0), (n, half, k)
