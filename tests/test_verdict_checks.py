"""The last checks on a named verdict (identify/verdict_checks.py)."""

import math

import pytest
from hypothesis import given, strategies as st

from soiltrack.identify.diagnosis.selection import Verdict
from soiltrack.identify.diagnosis.verdict_checks import check_verdict, explained_fraction


def test_explained_fraction_values():
    # nominal: 2x the noise variance (excess 1); effect brings it to the noise: all explained
    assert explained_fraction(200.0, 100.0, 100) == pytest.approx(1.0)
    assert explained_fraction(200.0, 150.0, 100) == pytest.approx(0.5)
    assert explained_fraction(200.0, 80.0, 100) == pytest.approx(1.0)  # below the floor counts as all
    assert explained_fraction(200.0, 250.0, 100) == pytest.approx(-0.5)  # worse than nominal
    assert math.isnan(explained_fraction(90.0, 80.0, 100))  # no excess: nothing to explain
    assert math.isnan(explained_fraction(200.0, math.inf, 100))


@given(st.floats(1.01, 1e3), st.floats(0.0, 1e3))
def test_explained_fraction_at_most_one(before_per_sample, after_per_sample):
    f = explained_fraction(100 * before_per_sample, 100 * after_per_sample, 100)
    assert f <= 1.0
    # monotone: a model with a smaller held-out error explains at least as much
    g = explained_fraction(100 * before_per_sample, 100 * after_per_sample * 0.5, 100)
    assert g >= f


def test_no_gap_and_no_significant_gain_gives_none():
    v, note = check_verdict(
        Verdict("mass_error", 0.52, "x"),
        gap_p=0.88,
        beats_nominal_p=0.3,
        shrink=0.001,
        explained=math.nan,
        no_gap_confidence=1.0,
    )
    assert v.name == "none" and v.confidence == 1.0 and "no gap" in v.reason and "mass_error" in note


def test_an_effect_that_explains_little_is_not_named():
    v, note = check_verdict(
        Verdict("drivetrain_friction", 1.0, "x"),
        gap_p=1e-9,
        beats_nominal_p=1e-6,
        shrink=0.02,
        explained=0.1,
        no_gap_confidence=1.0,
    )
    assert v.name == "unexplained" and v.confidence == pytest.approx(0.9) and "10 %" in v.reason


def test_a_good_verdict_passes_unchanged():
    v0 = Verdict("grade", 0.97, "grade predicts best")
    v, note = check_verdict(v0, gap_p=1e-12, beats_nominal_p=1e-12, shrink=0.6, explained=0.95, no_gap_confidence=1.0)
    assert v is v0 and note is None
    # a weak but real effect: gap not significant on its own, but the effect beats the nominal model
    v, note = check_verdict(v0, gap_p=0.2, beats_nominal_p=1e-4, shrink=0.2, explained=0.9, no_gap_confidence=1.0)
    assert v is v0 and note is None


@pytest.mark.parametrize("name", ["none", "unexplained"])
def test_none_and_unexplained_pass(name):
    v0 = Verdict(name, 0.6, "r")
    assert check_verdict(v0, gap_p=0.0, beats_nominal_p=1.0, shrink=0.0, explained=0.0, no_gap_confidence=0.1)[0] is v0


def test_a_significant_but_negligible_gain_without_a_gap_gives_none():
    v, note = check_verdict(
        Verdict("drivetrain_friction", 0.998, "x"),
        gap_p=0.96,
        beats_nominal_p=1e-5,
        shrink=0.02,
        explained=math.nan,
        no_gap_confidence=1.0,
    )
    assert v.name == "none" and "2.0 %" in v.reason


def test_lookalikes_name_library_effects_and_reach_the_notes():
    import numpy as np

    from soiltrack.identify import diagnose
    from soiltrack.identify.diagnosis.selection import LOOKALIKES
    from soiltrack.soilmodel import EFFECTS, TERRAINS, VEHICLES, SensorNoise, simulate

    assert set(LOOKALIKES) <= set(EFFECTS)
    v = VEHICLES["light"]
    d = simulate(
        v,
        TERRAINS["lete_sand"],
        kind="sweep",
        effects={"slip_sinkage": 0.1},
        seed=1,
        slips=np.round(np.linspace(0.01, 0.7, 60), 4),
        noise=SensorNoise(force_rel=0.005, slip_abs=0.0005),
    )
    dg = diagnose(d, v)
    assert dg.verdict == "slip_sinkage"
    assert any(n.startswith("slip_sinkage also stands for any resistance that grows with the slip") for n in dg.notes)
    assert not any(
        "also stands for" in n
        for n in diagnose(
            simulate(
                v,
                TERRAINS["lete_sand"],
                kind="sweep",
                seed=1,
                slips=np.round(np.linspace(0.01, 0.7, 60), 4),
                noise=SensorNoise(force_rel=0.005, slip_abs=0.0005),
            ),
            v,
        ).notes
    )
