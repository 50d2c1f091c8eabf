"""The one decision rule, the evidence and the gap tests on hand-made hypotheses (fast, no fits)."""

import math

import numpy as np
import pytest

from soiltrack.identify.diagnosis import DiagnoseSettings
from hypothesis import given, settings
from hypothesis import strategies as st

from soiltrack.identify.diagnosis.decision import decide, share_confusable
from soiltrack.identify.diagnosis.selection import shared_weights
from soiltrack.identify.diagnosis.evidence import HeldOutEvidence, PenalisedEvidence
from soiltrack.identify.diagnosis.gap_test import decide_gap
from soiltrack.identify.diagnosis.hypotheses import Frame, Hypothesis

S = DiagnoseSettings()
RNG = np.random.default_rng(3)
N = 400


def hyp(name, family, z, **kw):
    return Hypothesis(name, family, kw.pop("k", 1), {"c": z}, z=np.asarray(z, float), **kw)


def gap(p):
    return decide_gap({"nominal error vs noise": p}, S.alpha)


def test_no_gap_is_none_with_the_nominal_weight_as_confidence():
    hs = [hyp("none", "nominal", RNG.standard_normal(N)), hyp("grade", "candidate", RNG.standard_normal(N))]
    w = {"none": 0.7, "grade": 0.3}
    d = decide(hs, w, gap(0.5), S)
    assert d.verdict == "none" and d.confidence == 0.7 and d.cause is None


def test_a_candidate_that_explains_the_gap_is_named_with_its_weight():
    e = RNG.standard_normal(N)
    hs = [
        hyp("none", "nominal", 3 * e),
        hyp("grade", "candidate", e),
        hyp("discrepancy", "flexible", 1.2 * e),
    ]
    w = {"none": 0.0, "grade": 0.8, "discrepancy": 0.2}
    d = decide(hs, w, gap(1e-9), S)
    assert d.verdict == "grade" and d.confidence == 0.8 and d.explained > 0.9


def test_a_candidate_that_explains_too_little_gives_unexplained_with_the_outside_weight():
    e = RNG.standard_normal(N)
    # nominal excess 9 - 1 = 8; the candidate leaves 6.25 - 1 = 5.25: explains 34 %
    hs = [
        hyp("none", "nominal", 3 * e),
        hyp("radius_error", "candidate", 2.5 * e),
        hyp("delay", "outside", 2.6 * e, detail={"lag_s": 0.25}),
    ]
    w = {"none": 0.0, "radius_error": 0.7, "delay": 0.3}
    d = decide(hs, w, gap(1e-9), S)
    assert d.verdict == "unexplained" and d.cause is None and d.confidence == pytest.approx(0.3)
    assert d.explained == pytest.approx(1 - (2.5**2 * np.mean(e**2) - 1) / (9 * np.mean(e**2) - 1))


def test_an_outside_cause_is_named_with_its_detail_and_the_outside_weight():
    e = RNG.standard_normal(N)
    hs = [
        hyp("none", "nominal", 3 * e),
        hyp("grade", "candidate", 2 * e),
        hyp("discrepancy", "flexible", 1.5 * e),
        hyp("delay", "outside", e, detail={"lag_s": 0.25, "lag_samples": 25}),
    ]
    w = {"none": 0.0, "grade": 0.1, "discrepancy": 0.2, "delay": 0.7}
    d = decide(hs, w, gap(1e-9), S)
    assert (d.verdict, d.cause, d.cause_detail["lag_s"]) == ("unexplained", "delay", 0.25)
    assert d.confidence == pytest.approx(0.9)


def test_close_collinear_effects_are_confusable_with_their_experiment_and_no_cap():
    e = RNG.standard_normal(N)
    hs = [
        hyp("none", "nominal", 3 * e),
        hyp("grade", "candidate", e),
        hyp("drivetrain_friction", "candidate", e),
    ]
    raw = {"none": 0.0, "grade": 0.55, "drivetrain_friction": 0.45}
    u = np.ones(10) / math.sqrt(10)
    shared = share_confusable(hs, raw, {"grade": u, "drivetrain_friction": u}, S)
    d = decide(hs, shared.weights, gap(1e-9), S, confusable=shared.confusable)
    # the pair shares its weight: the confidence is the shared weight, no cap
    assert d.verdict == "grade" and d.confidence == pytest.approx(0.5)
    assert [set(p) for p, _, _ in d.confusable] == [{"grade", "drivetrain_friction"}]
    assert d.confusable[0][1] == pytest.approx(1.0) and d.confusable[0][2]
    # the decision lists the pairs that shared, found once on the weights before sharing
    assert d.confusable == shared.confusable


def test_confusable_effects_share_their_weight_and_the_simplest_is_named():
    e = RNG.standard_normal(N)
    hs = [
        hyp("none", "nominal", 3 * e),
        hyp("drivetrain_friction", "candidate", e, k=2),
        hyp("grade", "candidate", e),
        hyp("speed_resistance", "candidate", 2 * e),
    ]
    raw = {"none": 0.0, "drivetrain_friction": 0.76, "grade": 0.24, "speed_resistance": 0.0}
    u = np.ones(10) / math.sqrt(10)
    sh = share_confusable(hs, raw, {"grade": u, "drivetrain_friction": u, "speed_resistance": u[::-1]}, S)
    w = sh.weights
    assert w["grade"] == w["drivetrain_friction"] == pytest.approx(0.5)
    assert sum(w.values()) == pytest.approx(1.0)
    d = decide(hs, w, gap(1e-9), S, confusable=sh.confusable)
    # the data cannot tell them apart: the one with fewer parameters, at the shared weight
    assert (d.verdict, d.confidence) == ("grade", pytest.approx(0.5))
    # sensitivities not collinear: no sharing
    v = np.r_[1.0, -1.0, np.zeros(8)] / math.sqrt(2)
    w2 = share_confusable(hs, raw, {"grade": u, "drivetrain_friction": v}, S).weights
    assert (w2["drivetrain_friction"], w2["grade"]) == (0.76, 0.24)
    # weights far apart (a factor above 1 / confusable_ratio): no sharing
    far = {"none": 0.0, "drivetrain_friction": 0.9, "grade": 0.1, "speed_resistance": 0.0}
    assert share_confusable(hs, far, {"grade": u, "drivetrain_friction": u}, S).weights["grade"] == 0.1


def test_the_flexible_term_shares_with_an_effect_of_close_weight_and_the_effect_is_named():
    e = RNG.standard_normal(N)
    hs = [
        hyp("none", "nominal", 3 * e),
        hyp("speed_resistance", "candidate", e),
        hyp("discrepancy", "flexible", e, k=12),
    ]
    raw = {"none": 0.0, "speed_resistance": 0.37, "discrepancy": 0.63}
    sh = share_confusable(hs, raw, {"speed_resistance": np.ones(4)}, S)
    d = decide(hs, sh.weights, gap(1e-9), S, confusable=sh.confusable)
    assert (d.verdict, d.confidence) == ("speed_resistance", pytest.approx(0.5))
    clear = {"none": 0.0, "speed_resistance": 0.1, "discrepancy": 0.9}
    sh = share_confusable(hs, clear, {"speed_resistance": np.ones(4)}, S)
    d = decide(hs, sh.weights, gap(1e-9), S, confusable=sh.confusable)
    assert (d.verdict, d.confidence) == ("unexplained", pytest.approx(0.9))


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(0.0, 1.0), min_size=2, max_size=6),
    st.lists(st.tuples(st.integers(0, 5), st.integers(0, 5)), max_size=6),
    st.lists(st.integers(0, 4), min_size=6, max_size=6),
)
def test_shared_weights_keep_the_sum_equalise_groups_and_order_the_result(ws, links, ks):
    names = [f"h{i}" for i in range(len(ws))]
    w = dict(zip(names, ws))
    pairs = [((names[a], names[b]), 1.0) for a, b in links if a < len(names) and b < len(names) and a != b]
    n_par = dict(zip(names, ks))
    cands = set(names[::2])
    out = shared_weights(w, pairs, n_par, cands)
    assert set(out) == set(w) and sum(out.values()) == pytest.approx(sum(w.values()))
    for (a, b), _ in pairs:
        assert out[a] == pytest.approx(out[b])
    keys = list(out)
    for x, y in zip(keys, keys[1:]):  # heaviest first; among equals the candidates, then the fewest parameters
        assert out[x] > out[y] - 1e-12
        if out[x] == out[y]:
            assert (x not in cands, n_par[x]) <= (y not in cands, n_par[y])


def test_evidence_weights_sum_to_one_and_favour_the_better_prediction():
    e = RNG.standard_normal(N)
    hs = [hyp("none", "nominal", 2 * e, k=0), hyp("grade", "candidate", e, k=1)]
    for ev in (HeldOutEvidence(block=5, n_bootstrap=200), PenalisedEvidence(n_bootstrap=200)):
        w = ev.weights(hs)
        assert sum(w.values()) == pytest.approx(1.0) and w["grade"] > 0.99


def test_penalised_evidence_charges_parameters_that_fit_nothing():
    e = RNG.standard_normal(60)
    w = PenalisedEvidence(n_bootstrap=200).weights(
        [hyp("none", "nominal", e, k=0), hyp("discrepancy", "flexible", 0.999 * e, k=12)]
    )
    assert w["none"] > 0.99


def test_frame_fills_unpredicted_samples_with_the_nominal_values():
    f = Frame({"c": np.full(4, 2.0)}, {"c": np.array([True, True, False, True])})
    z0 = f.z({"c": np.array([2.0, 4.0, 9.0, 6.0])})
    assert z0.tolist() == [1.0, 2.0, 3.0]
    assert f.z({"c": np.array([0.0, np.nan, 1.0, 2.0])}, z0).tolist() == [0.0, 2.0, 1.0]


def test_gap_decision_keeps_only_the_tests_made():
    g = decide_gap({"a": 0.5, "b": None, "c": 0.001}, 0.01)
    assert [t.name for t in g.tests] == ["a", "c"] and g.present and g.p_of("b") == 1.0
    assert not decide_gap({"a": 0.5}, 0.01).present


def test_settings_knots():
    assert S.knots(3001, True) == 20 and S.knots(600, True) == 8 and S.knots(60, False) == 10


def test_the_gap_tests_share_the_family_level():
    """Two tests at p = 0.008 each: significant alone at 0.01, not when they share it (0.005 each)."""
    one = decide_gap({"a": 0.008}, 0.01)
    two = decide_gap({"a": 0.008, "b": 0.008}, 0.01)
    assert one.present and [t.level for t in one.tests] == [0.01]
    assert not two.present and [t.level for t in two.tests] == [0.005, 0.005]
    assert decide_gap({"a": 0.004, "b": 0.5}, 0.01).present


@settings(max_examples=40, deadline=None)
@given(st.floats(0.5, 2.0), st.integers(0, 2**16))
def test_a_residual_that_only_rescales_the_measured_noise_keeps_its_density(g, seed):
    """A hypothesis whose residual and noise are the nominal ones times ``g`` (its gain on the measured signal:
    a mass error's hull balance) predicts the measurements alike, so it scores the nominal model's density;
    the same noise growth without the gain (the encoder noise through a radius error) costs ``log g`` per sample."""
    r = np.random.default_rng(seed).standard_normal(50)
    f = Frame({"c": np.ones(50)}, {"c": np.ones(50, bool)})
    one = {"c": np.ones(50)}
    nom = Hypothesis("none", "nominal", 0, {"c": r}, noise=one, gain=one).scored(f)
    scaled = {"c": np.full(50, g)}
    rescaled = Hypothesis("m", "candidate", 1, {"c": g * r}, noise=scaled, gain=scaled).scored(f, None, nom)
    noisier = Hypothesis("n", "candidate", 1, {"c": g * r}, noise=scaled, gain=one).scored(f, None, nom)
    assert np.allclose(rescaled.z, nom.z) and np.allclose(rescaled.log_scale, 0.0)
    assert np.allclose(noisier.z, nom.z) and np.allclose(noisier.log_scale, math.log(g))
    w = HeldOutEvidence(block=5, n_bootstrap=50).weights([nom, rescaled])
    assert w["none"] == pytest.approx(0.5, abs=1e-9)
