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
    assert [set(c.effects) for c in d.confusable] == [{"grade", "drivetrain_friction"}]
    assert d.confusable[0].correlation == pytest.approx(1.0) and d.confusable[0].experiment
    assert math.isnan(d.confusable[0].separation)  # close weights made them confusable
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


def test_a_difference_of_evidence_in_its_standard_errors():
    from soiltrack.identify.diagnosis.selection import difference_z

    u = np.array([1.0, 3.0, 2.0, 2.0])  # sum 8, sd sqrt(0.5), sqrt(4) sd = 1.414...
    assert difference_z(u) == pytest.approx(8 / (2 * math.sqrt(0.5)))
    assert difference_z(-u, offset=-1.0) == pytest.approx(9 / (2 * math.sqrt(0.5)))
    assert difference_z(-u) == difference_z(u)
    assert difference_z(np.full(5, 1.0)) == math.inf and difference_z(np.zeros(5)) == 0.0
    assert difference_z(np.array([1.0, np.inf])) == math.inf


def test_held_out_separation_groups_the_samples_into_the_bootstrap_blocks():
    """Two hypotheses whose density differs by one per sample in 10 blocks of 4 with a spread of block sums:
    the separation is the blocks' sum over sqrt(10) times their standard deviation, either way round."""
    n, block = 40, 4
    za = np.zeros(n)
    gain = np.repeat(RNG.uniform(0.0, 2.0, n // block), block)  # per-sample density gain of b, constant in a block
    zb = -np.sqrt(2 * gain)  # -z^2/2 = -gain: b predicts worse by gain per sample
    a, b = hyp("a", "candidate", za), hyp("b", "candidate", zb)
    sums = gain.reshape(-1, block).sum(axis=1)
    want = sums.sum() / (math.sqrt(sums.size) * sums.std())
    ev = HeldOutEvidence(block=block, n_bootstrap=50)
    assert ev.separation(a, b) == pytest.approx(want) and ev.separation(b, a) == pytest.approx(want)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**16), st.integers(0, 3), st.integers(0, 3))
def test_penalised_separation_is_symmetric_and_counts_the_penalty(seed, ka, kb):
    rng = np.random.default_rng(seed)
    a = hyp("a", "candidate", rng.standard_normal(30), k=ka)
    b = hyp("b", "candidate", 1.3 * rng.standard_normal(30), k=kb)
    ev = PenalisedEvidence(n_bootstrap=50)
    assert ev.separation(a, b) == pytest.approx(ev.separation(b, a))
    # the profiled terms sum to the profiled log-likelihood -n/2 log(mean z^2)
    la = -15 * math.log(np.mean(a.z**2)) - ka
    lb = -15 * math.log(np.mean(b.z**2)) - kb
    from soiltrack.identify.diagnosis.selection import difference_z

    q = lambda h: -0.5 * math.log(np.mean(h.z**2)) - 0.5 * h.z**2 / np.mean(h.z**2) + 0.5  # noqa: E731
    d = q(a) - q(b)
    assert np.sum(d) + kb - ka == pytest.approx(la - lb)
    assert ev.separation(a, b) == pytest.approx(difference_z(d, kb - ka))


def test_collinear_effects_within_two_standard_errors_are_confusable_whatever_their_weights():
    u = np.ones(10) / math.sqrt(10)
    e = RNG.standard_normal(N)
    hs = [hyp("none", "nominal", 3 * e), hyp("radius_error", "candidate", e), hyp("grade", "candidate", e)]
    raw = {"none": 0.0, "grade": 0.97, "radius_error": 0.03}
    dirs = {"grade": u, "radius_error": u}
    for sep, shared in ((1.5, True), (2.5, False)):
        sh = share_confusable(hs, raw, dirs, S, lambda a, b: sep)
        assert bool(sh.confusable) is shared and (not shared or sh.confusable[0].separation == sep)
        assert sh.weights["grade"] == (pytest.approx(0.5) if shared else 0.97)
    # different signatures: the separation does not matter
    v = np.r_[1.0, -1.0, np.zeros(8)] / math.sqrt(2)
    assert not share_confusable(hs, raw, {"grade": u, "radius_error": v}, S, lambda a, b: 0.1).confusable
    # the flexible term (no direction) is judged by its weight alone
    hf = [hyp("none", "nominal", 3 * e), hyp("grade", "candidate", e), hyp("discrepancy", "flexible", e, k=12)]
    far = {"none": 0.0, "grade": 0.95, "discrepancy": 0.05}
    assert not share_confusable(hf, far, {"grade": u}, S, lambda a, b: 0.1).confusable


def test_a_twin_the_data_cannot_tell_apart_carries_the_explanation_of_its_group():
    """The heaviest candidate removes less than half of the nominal excess; its twin (collinear, within the
    noise of it) removes all of it: the group explains the gap and the candidate is named at the shared
    weight. The flexible term (no direction) does not carry an effect's explanation."""
    e = RNG.standard_normal(N)
    e /= np.sqrt(np.mean(e**2))
    hs = [
        hyp("none", "nominal", 1.1 * e),
        hyp("radius_error", "candidate", 1.08 * e),  # removes 1 - 0.1664 / 0.21 = 21 %
        hyp("speed_scale", "outside", 0.95 * e),
        hyp("discrepancy", "flexible", 0.95 * e, k=12),
    ]
    raw = {"none": 0.0, "radius_error": 0.06, "speed_scale": 0.9, "discrepancy": 0.04}
    u = np.ones(10) / math.sqrt(10)
    sh = share_confusable(hs, raw, {"radius_error": u, "speed_scale": u}, S, lambda a, b: 1.5)
    d = decide(hs, sh.weights, gap(1e-9), S, confusable=sh.confusable)
    assert hs[1].explained(hs[0]) == pytest.approx(1 - (1.08**2 - 1) / (1.1**2 - 1))
    assert (d.verdict, d.confidence) == ("radius_error", pytest.approx(0.48))
    assert d.explained == pytest.approx(hs[1].explained(hs[0]))
    # told apart (beyond two standard errors): the speed scale is the heaviest and the cause
    sh = share_confusable(hs, raw, {"radius_error": u, "speed_scale": u}, S, lambda a, b: 3.0)
    d = decide(hs, sh.weights, gap(1e-9), S, confusable=sh.confusable)
    assert (d.verdict, d.cause, d.confidence) == ("unexplained", "speed_scale", pytest.approx(0.94))
    # a candidate paired only with the flexible term keeps its own test
    flex = {"none": 0.0, "radius_error": 0.45, "speed_scale": 0.0, "discrepancy": 0.55}
    sh = share_confusable(hs, flex, {"radius_error": u}, S)
    d = decide(hs, sh.weights, gap(1e-9), S, confusable=sh.confusable)
    assert [set(c.effects) for c in sh.confusable] == [{"radius_error", "discrepancy"}]
    assert (d.verdict, d.cause) == ("unexplained", None)


def test_a_channel_whose_latent_slip_takes_most_of_its_noise_keeps_its_noise_level():
    # a hull balance whose latent slip leaves a fifth of its noise: the nominal model's z^2 near 0.2 is what a
    # right model leaves there, not a noise level five times too high
    m = np.ones(N, bool)
    z = RNG.standard_normal(N)
    r = {"hull": np.sqrt(0.2) * z / np.sqrt(np.mean(z**2)), "speed": 0.5 * z / np.sqrt(np.mean(z**2))}
    sigma = {"hull": np.ones(N), "speed": np.ones(N)}
    f = Frame(sigma, {"hull": m, "speed": m}, {"hull": np.full(N, 0.2), "speed": np.full(N, 1.0)})
    g = f.at_most_nominal(r)
    assert g.sigma["hull"] == pytest.approx(np.ones(N))
    assert g.sigma["speed"] == pytest.approx(np.full(N, 0.5))
    # without the expected share (a sweep's frame) the hull's level is lowered to the nominal error's
    assert Frame(sigma, {"hull": m, "speed": m}).at_most_nominal(r).sigma["hull"] == pytest.approx(
        np.full(N, np.sqrt(0.2))
    )
    # half the expected share left: lowered by the square root of the ratio
    h = Frame(sigma, {"hull": m}, {"hull": np.full(N, 0.4)}).at_most_nominal(r)
    assert h.sigma["hull"] == pytest.approx(np.full(N, np.sqrt(0.5)))


def test_the_share_explained_is_measured_on_the_floor_not_on_the_weights_standardisation():
    e = RNG.standard_normal(N)
    f = Frame({"c": np.ones(N)}, {"c": np.ones(N, bool)})
    g0 = f.z({"c": 2.0 * e})
    nominal = Hypothesis("none", "nominal", 0, {"c": 2.0 * e}, z=0.3 * e).with_gap(f)
    effect = Hypothesis("grade", "candidate", 1, {"c": 1.1 * e}, z=0.2 * e).with_gap(f, g0)
    q = float(np.mean(e**2))
    assert effect.explained(nominal) == pytest.approx(1 - (1.21 * q - 1) / (4 * q - 1))
    # without a floor standardisation the weights' z serve (a sweep): both within the noise, nothing to explain
    assert math.isnan(hyp("grade", "candidate", 0.2 * e).explained(hyp("none", "nominal", 0.3 * e)))


def test_none_has_the_weight_of_the_no_gap_hypothesis_as_confidence():
    """Issue 37 item 4: an effect-free sweep's nominal weight is shared with effects that fit it as well;
    ``none`` then carries the weight of every hypothesis the evidence does not tell from the nominal model."""
    e = RNG.standard_normal(N)
    hs = [
        hyp("none", "nominal", e),
        hyp("grade", "candidate", e),
        hyp("radius_error", "candidate", e),
        hyp("discrepancy", "flexible", e),
    ]
    w = {"none": 0.03, "grade": 0.32, "radius_error": 0.32, "discrepancy": 0.33}
    apart = {"grade": 0.5, "radius_error": 1.9, "discrepancy": 3.0}  # standard errors from the nominal model
    sep = lambda a, b: apart[a.name if a.name != "none" else b.name]  # noqa: E731
    d = decide(hs, w, gap(0.5), S, separation=sep)
    assert d.verdict == "none" and d.confidence == pytest.approx(0.03 + 0.32 + 0.32)
    assert "no-gap hypothesis (0.67)" in d.reason and "grade, radius_error" in d.reason
    assert decide(hs, w, gap(0.5), S).confidence == 0.03  # without the separation: the nominal model's own
    far = lambda a, b: 5.0  # noqa: E731
    assert decide(hs, w, gap(0.5), S, separation=far).confidence == 0.03
