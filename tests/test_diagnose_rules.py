"""Verdict rules on sweeps: an effect fitted with the wrong physical sign, a candidate that explains most of a
gap but leaves a smooth residual, and the share of the gap above the noise the verdict removes."""

import json

import pytest

from soiltrack.identify import diagnose
from soiltrack.identify.diagnosis.sweep_parts import PARTIAL_SHRINK, decide_sweep
from soiltrack.soilmodel import EFFECTS, TERRAINS, VEHICLES, SensorNoise, simulate
from conftest import independent_check, independent_log, independent_sweep

HEAVY = VEHICLES["heavy"]
SLIPS = tuple(round(0.01 + k * (0.69 / 59), 4) for k in range(60))
LOW = SensorNoise(force_rel=0.005, slip_abs=0.0005)


def test_partial_explanation_is_named_with_half_confidence():
    w = {"none": 0.0, "discrepancy": 0.0, "hump_shear": 1.0}
    v = decide_sweep(w, ["hump_shear"], True, {"hump_shear": 1e-4}, shrink={"hump_shear": 0.88})
    assert v.name == "hump_shear" and v.confidence == 0.5 and "most of the gap" in v.reason
    v = decide_sweep(w, ["hump_shear"], True, {"hump_shear": 1e-4}, shrink={"hump_shear": PARTIAL_SHRINK - 0.2})
    assert v.name == "unexplained" and v.confidence == pytest.approx(1.0 - (PARTIAL_SHRINK - 0.2))
    v = decide_sweep(w, ["hump_shear"], True, {"hump_shear": 0.5}, shrink={"hump_shear": 0.88})
    assert v.name == "hump_shear" and v.confidence == 1.0  # no smooth residual: its weight


@pytest.fixture(scope="module")
def sinkage_sweep():
    # heavy vehicle, LETE sand, low noise, a resistance growing with slip (mu_s = 0.15), seed 3: with the rig's
    # track speed u fixed, speed_resistance with mu_v < 0 imitates it (-mu_v u (1 - i) grows with i)
    return simulate(
        HEAVY, TERRAINS["lete_sand"], kind="sweep", effects={"slip_sinkage": 0.15}, seed=3, slips=SLIPS, noise=LOW
    )


@pytest.mark.slow
def test_an_effect_of_the_wrong_sign_is_not_named_with_confidence(sinkage_sweep):
    cands = [e for e, s in EFFECTS.items() if "sweep" in s.shows_in and e != "slip_sinkage"]
    d = diagnose(sinkage_sweep, HEAVY, candidates=cands)
    # measured before the rule: speed_resistance 0.89 (mu_v = -0.30 +- 0.005)
    assert d.verdict == "speed_resistance" and d.confidence <= 0.5
    assert any("opposite sign to its meaning" in n for n in d.notes)


def test_the_physical_lookalike_is_named_instead(sinkage_sweep):
    d = diagnose(sinkage_sweep, HEAVY)
    # measured before the rule: speed_resistance 0.888 against slip_sinkage 0.111 (shrink 0.89 and 0.85)
    assert d.verdict == "slip_sinkage" and 0 < d.confidence <= 0.5
    mu_s = next(e for e in d.ranking if e.effect == "slip_sinkage").parameters["mu_s"]["value"]
    assert mu_s == pytest.approx(0.15, rel=0.1)
    assert any("physical sign" in n for n in d.notes)


def test_gap_shrink_is_the_share_of_the_misfit_above_the_noise(sinkage_sweep):
    d = diagnose(sinkage_sweep, HEAVY)
    j = json.loads(d.to_json())
    assert j["gap_shrink"] == pytest.approx(d.gap_shrink)
    # removing the noise from before and after can only raise the share: gap_shrink >= shrink when after <= before
    assert 0.0 <= d.shrink <= d.gap_shrink <= 1.0
    assert "misfit above the noise shrinks by" in d.report()
    none = diagnose(simulate(HEAVY, TERRAINS["lete_sand"], kind="sweep", seed=1, slips=SLIPS, noise=LOW), HEAVY)
    assert none.verdict != "none" or none.gap_shrink is None


@pytest.mark.slow
def test_a_softening_soil_outside_the_library_form_is_named_at_half_confidence(tmp_path):
    # Wong's type B law (independent numpy) is not the library's hump_shear form: it explains 88 % of the
    # held-out gap and leaves a smooth residual; measured before the rule: "unexplained", confidence 0.00
    d = diagnose(independent_sweep(tmp_path / "hump.csv", 0, hump=(0.55, 0.025)), HEAVY)
    assert d.verdict == "hump_shear" and d.confidence == 0.5 and "most of the gap" in d.reason


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.slow
def test_a_load_cell_flat_at_its_limit_is_unexplained_not_an_effect(tmp_path, seed):
    # a load cell saturating at 80 % of the peak, noise added after the clip (outside the library; independent
    # numpy): 58 of 60 readings flat. Measured before the plateau check: hump_shear 0.50 on all three seeds (seed 1
    # with a held-out shrink of -0.16); the rival rule of test_diagnose.py had capped it at 0.5
    d = diagnose(independent_sweep(tmp_path / "clipped.csv", seed, clip=0.8), HEAVY)
    assert d.verdict == "unexplained"
    note = next(n for n in d.notes if "flat at" in n)
    level = float(note.split("flat at ")[1].split(" N")[0])
    assert level == pytest.approx(_oracle_clip(0.8), rel=0.005)


def _oracle_clip(share: float) -> float:
    """The clip level of the oracle's sweep: ``share`` of its noise-free drawbar-pull peak (default soil)."""
    import numpy as np

    ic = independent_check()
    i = np.linspace(0.02, 0.7, 60)
    D = ic.thrust_quadrature(i, ic.W0, 1300.0, np.radians(31.1), 0.012) - ic.W0 * ic.MU
    return share * float(D.max())


def test_find_plateau_needs_the_soil_below_to_rise_to_the_level():
    import numpy as np
    from soiltrack.identify.diagnosis.sweep_parts import find_plateau

    slip = np.linspace(0.02, 0.7, 30)
    flat = np.full(30, 100.0) + np.where(np.arange(30) % 2, 1.0, -1.0)
    flat[:2] = [60.0, 90.0]
    sig = np.ones(30)
    p = find_plateau(flat, slip, sig, lambda idx: None)  # two readings below: the soil passes through them
    assert p is not None and len(p.rows) == 28 and p.level == pytest.approx(100.0, abs=0.1)
    assert p.slip_range[0] == pytest.approx(slip[2])
    # a soil fitted below that stays under the level at the plateau's slips: nothing is clipped
    low = flat.copy()
    low[:6] = [40.0, 50.0, 60.0, 70.0, 80.0, 90.0]

    def soil(curve):  # a "fit" below: the given curve's residuals on idx, its predictions on the rest
        return lambda idx: (low[idx] - curve[idx], np.delete(curve, idx))

    k = np.arange(30.0)
    rises = find_plateau(low, slip, sig, soil(40.0 + 10.0 * k))
    assert len(rises.rows) == 24 and float(rises.z @ rises.z) == pytest.approx(24.0)
    stays = find_plateau(low, slip, sig, soil(np.minimum(40.0 + 10.0 * k, 50.0)))
    # only the level through all but the two lowest readings is left, and it fits far worse
    assert len(stays.rows) == 28 and float(stays.z @ stays.z) > 10 * float(rises.z @ rises.z)


def test_a_flexible_term_that_does_not_predict_held_out_blocks_is_no_gap():
    w = {"none": 0.06, "discrepancy": 0.80, "grade": 0.05, "mass_error": 0.09}
    # the flexible term wins on all the data and ALSO predicts the held-out blocks: a real gap
    assert decide_sweep(w, [], True, {}, disc_held_p=1e-4).name == "unexplained"
    # it wins on all the data only: a chance feature of the noise; nothing screens significant -> none
    v = decide_sweep(w, [], True, {}, disc_held_p=0.17)
    assert v.name == "none" and "no structured gap is confirmed" in v.reason
    assert v.confidence == pytest.approx(1.0 - 0.09 / 0.20)
    # a candidate with a significant score of its own is named, at 0.5 at most
    v = decide_sweep(w, ["mass_error"], True, {}, disc_held_p=0.17)
    assert v.name == "mass_error" and v.confidence == pytest.approx(0.09 / 0.20)  # its share, under 0.5


@pytest.mark.slow
def test_an_effect_free_clayey_sweep_from_independent_code_is_none(tmp_path):
    # independent oracle, effect-free, c = 4.14 kPa, phi = 13 deg, K = 6 mm, seed 0: residuals white but with a
    # chance lag-1 correlation of 0.26, so the noise floor is low (255 N against about 300 N) and a 10-knot
    # flexible term wins on all the data; it predicts the held-out blocks no better (p = 0.17).
    # Measured before the rule: unexplained, confidence 0.94.
    import numpy as np

    d = diagnose(independent_sweep(tmp_path / "clay.csv", 0, c=4140.0, phi=np.radians(13.0), K=0.006), HEAVY)
    assert d.verdict == "none"
    assert "no structured gap is confirmed" in d.reason


def test_isolated_outliers_finds_lone_readings_and_spares_noise_steps_and_growth():
    import numpy as np
    from soiltrack.identify.diagnosis.gap import OUTLIER_Z, isolated_outliers

    rng = np.random.default_rng(7)
    x = np.linspace(0.02, 0.7, 60)
    r = rng.normal(0.0, 1.0, 60)
    assert isolated_outliers(r, x) == []
    spiked = r.copy()
    spiked[[17, 41]] += [12.0, -10.0]
    found = isolated_outliers(spiked[::-1], x[::-1])  # in any row order
    assert sorted(59 - k for k, _ in found) == [17, 41] and all(abs(z) > OUTLIER_Z for _, z in found)
    step = r.copy()
    step[30:] += 15.0  # a step (a change of terrain, a sharp bend) is not a lone reading
    assert isolated_outliers(step, x) == []
    pair = r.copy()
    pair[[20, 21]] += 15.0  # two neighbours off together: not isolated
    assert isolated_outliers(pair, x) == []
    grows = rng.normal(0.0, 1.0, 60) * np.linspace(0.2, 3.0, 60)  # noise growing along the sweep
    assert isolated_outliers(grows, x) == []
    # a signal stepping to a limit where its noise grows 20-fold (a torque at its limit): with the sides'
    # noise levels estimated apart, the readings after the step are not lone readings
    limit = np.where(np.arange(60) < 30, 1.0 + 0.05 * rng.normal(size=60), 100.0 + 1.0 * rng.normal(size=60))
    assert isolated_outliers(limit, x, split_sides=True) == []
    glitch = limit.copy()
    glitch[45] += 30.0
    assert [k for k, _ in isolated_outliers(glitch, x, split_sides=True)] == [45]
    # Gaussian noise: no false flag in 500 series of 60
    assert sum(bool(isolated_outliers(rng.normal(size=60), x)) for _ in range(500)) == 0


@pytest.mark.slow
def test_a_sweep_with_two_glitches_says_so_and_what_it_is_without_them(tmp_path):
    import numpy as np

    path = tmp_path / "spiked.csv"
    data = independent_sweep(path, 10)
    a = np.loadtxt(path, delimiter=",", skiprows=1)
    a[[17, 41], 1] += 8000.0  # two glitches of 8 kN on a noise of about 600 N
    np.savetxt(path, a, delimiter=",", header="slip,drawbar_pull_N,normal_load_N", comments="", fmt="%.5f")
    from soiltrack.soilmodel import read_csv

    d = diagnose(read_csv(str(path)), HEAVY)
    note = next(n for n in d.notes if "far off their neighbours" in n)
    assert note.startswith("rows 18, 42 ")
    assert d.verdict in ("none", "unexplained") and d.confidence <= 1.0
    assert "without them the verdict is none" in note
    # the clean sweep has no such note
    assert not any("far off" in n for n in diagnose(data, HEAVY).notes)


@pytest.mark.slow
def test_speed_glitches_in_a_log_are_named_and_the_verdict_without_them_is_given(tmp_path):
    # independent numpy log (heavy vehicle, 60 s at 20 Hz, effect-free), three GNSS speed glitches. Measured before:
    # unexplained 1.00 through a "change of terrain" at 44.1-47.05 s around the third one, with nothing said of them
    def glitch(a):
        a[[300, 610, 905], 3] += [1.5, -1.2, 2.0]

    d = diagnose(independent_log(tmp_path / "glitchy.csv", 5, edit=glitch), VEHICLES["heavy"])
    note = next(n for n in d.notes if n.startswith("lone readings"))
    assert "vehicle_speed_m_s: row 301 (t = 15 s), row 611 (t = 30.5 s), row 906 (t = 45.25 s)" in note
    assert "the verdict is none" in note


def test_isolated_outliers_with_trend_finds_a_glitch_on_a_ramp_but_no_step():
    import numpy as np
    from soiltrack.identify.diagnosis.gap import isolated_outliers

    rng = np.random.default_rng(3)
    t = np.arange(200) * 0.05
    ramp = 500.0 * np.arange(200) + rng.normal(0.0, 100.0, 200)  # a torque ramping 5 noise levels per sample
    assert isolated_outliers(ramp, t, trend=True) == []
    spiked = ramp.copy()
    spiked[[60, 140]] += [20000.0, -15000.0]
    # without the trend the neighbours of a glitch on the ramp differ by ten noise levels: "not a lone reading"
    assert isolated_outliers(spiked, t) == []
    assert sorted(k for k, _ in isolated_outliers(spiked, t, trend=True)) == [60, 140]
    step = ramp.copy()
    step[100:] += 5000.0  # a step on the ramp is still not a lone reading
    assert isolated_outliers(step, t, trend=True) == []
    bend = np.where(np.arange(200) < 100, 500.0, -500.0).cumsum() + rng.normal(0.0, 100.0, 200)  # a kink
    assert isolated_outliers(bend, t, trend=True) == []


@pytest.mark.slow
def test_torque_glitches_in_a_log_are_named_but_not_readings_at_the_drivetrain_limit(tmp_path):
    # independent numpy log (heavy vehicle, 60 s at 20 Hz, effect-free), two torque glitches of +20 and -15 kN m on
    # a torque ramping by about 500 N m per sample. Measured before: verdict none, nothing said of them
    import numpy as np
    from soiltrack.identify.diagnosis.diagnose import _lone_torque

    def glitch(a):
        a[[200, 700], 1] += [20000.0, -15000.0]

    d = diagnose(independent_log(tmp_path / "torque.csv", 6, edit=glitch), VEHICLES["heavy"])
    note = next(n for n in d.notes if n.startswith("lone readings"))
    assert "sprocket_torque_Nm: row 201 (t = 10 s), row 701 (t = 35 s)" in note
    assert d.verdict == "none" and "the verdict is none" in note
    # a reading that dips between neighbours at the drivetrain's limit is the controller, not a glitch
    T = np.full(200, 40.0) + np.random.default_rng(0).normal(0.0, 0.05, 200)
    T[100] = 36.0
    t = np.arange(200) * 0.02
    assert _lone_torque(T, t, VEHICLES["light"]) == []  # the light vehicle's limit is 40 N m
    T[:] = 10.0 + np.random.default_rng(0).normal(0.0, 0.05, 200)
    T[100] = 14.0
    assert [k for k, _ in _lone_torque(T, t, VEHICLES["light"])] == [100]


@pytest.mark.slow
def test_a_stretched_candidate_that_leaves_a_gap_gives_way_to_one_in_range():
    # heavy vehicle, LETE sand, a 25 % mass error, default noise, seed 3 (a case of benchmarks/bench_diagnose.py):
    # slip_sinkage ended on its bound mu_s = 2 in every training fit, still left a smooth gap and outweighed
    # mass_error (0.58 against 0.39, both shrinking the held-out error by 26 %). Measured before the rule:
    # `unexplained` 0.42. mass_error, inside its range and without a smooth gap, is named; the two stay confusable.
    log = simulate(
        HEAVY,
        TERRAINS["lete_sand"],
        kind="drive",
        effects={"mass_error": 0.25},
        seed=3,
        duration_s=60.0,
        noise=SensorNoise(),
    )
    d = diagnose(log, HEAVY)
    assert d.verdict == "mass_error" and d.confidence <= 0.5, (d.verdict, d.confidence, d.notes)
    delta = next(e for e in d.ranking if e.effect == "mass_error").parameters["delta"]["value"]
    assert abs(delta - 0.25) < 0.02, delta
    assert any("stretched to imitate another effect" in n for n in d.notes)
    assert any({"mass_error", "slip_sinkage"} <= set(g) for g in (grp for grp, _, _ in d.confusable))
    assert next(e for e in d.ranking if e.effect == "slip_sinkage").weight == 0.0
