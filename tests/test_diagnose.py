"""End-to-end diagnosis on simulated sweeps: score tests, verdicts, shrink, report/JSON/plot."""

import json
import math

import numpy as np
import pytest

from soiltrack.identify import Diagnosis, diagnose
from soiltrack.identify.diagnosis.screening import screen
from soiltrack.soilmodel import TERRAINS, VEHICLES, SensorNoise, simulate

VEH = VEHICLES["light"]
SOIL = TERRAINS["lete_sand"]
SLIPS = np.round(np.linspace(0.01, 0.7, 60), 4)
LOW_NOISE = SensorNoise(force_rel=0.005, slip_abs=0.0005)
SWEEP_EFFECTS = {
    "grade": 0.05,
    "speed_resistance": 0.05,
    "slip_sinkage": 0.1,
    "radius_error": 0.05,
    "hump_shear": 0.3,
    "pressure_distribution": 0.3,
    "mass_error": 0.2,
}


def sweep(effects=None, seed=1, noise=LOW_NOISE):
    return simulate(VEH, SOIL, kind="sweep", effects=effects, seed=seed, slips=SLIPS, noise=noise)


@pytest.fixture(scope="module")
def clean_screens():
    _, screens, _ = screen(sweep(noise="none"), VEH, list(SWEEP_EFFECTS))
    return {s.effect: s for s in screens}


def test_score_is_zero_at_the_nominal_model_on_effect_free_noise_free_data(clean_screens):
    # the nominal fit matches noise-free effect-free data to the solver's tolerance: the cosine between
    # residuals and every effect's projected sensitivity is at the level of that tolerance
    for name, s in clean_screens.items():
        assert s.screenable, name
        assert s.score < 1e-3, (name, s.score)


@pytest.mark.parametrize("name", sorted(SWEEP_EFFECTS))
def test_score_is_nonzero_with_the_effect(name, clean_screens):
    _, screens, _ = screen(sweep({name: SWEEP_EFFECTS[name]}, noise="none"), VEH, [name])
    s = screens[0]
    # measured cosines 0.3 to 1 (radius_error's local sensitivity is the weakest)
    assert s.score > 0.2 and s.score > 100 * clean_screens[name].score, (name, s.score)


def _consistent(d):
    """The verdict, confidence and ranking agree by construction."""
    w = {e.effect: e.weight for e in d.ranking}
    assert abs(sum(w.values()) - 1.0) < 1e-9
    if d.verdict not in ("none", "unexplained"):
        assert d.confidence == w[d.verdict] and d.ranking[0].effect == d.verdict
    elif d.verdict == "unexplained":
        assert d.confidence == pytest.approx(sum(e.weight for e in d.ranking if e.family in ("flexible", "outside")))
    else:  # the no-gap hypothesis: the nominal model and what the evidence does not tell from it (issue 37)
        assert w["none"] <= d.confidence <= 1.0 + 1e-12 and "no-gap hypothesis" in d.reason


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
def test_none_on_effect_free_data(seed):
    d = diagnose(sweep(seed=seed), VEH)
    _consistent(d)
    assert d.verdict == "none" and not d.gap.present
    assert d.shrink is None and d.soil_after is None and isinstance(d.soil_before, dict)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["hump_shear", "slip_sinkage", "radius_error"])
def test_clean_case_is_diagnosed_and_the_gap_shrinks(name):
    d = diagnose(sweep({name: SWEEP_EFFECTS[name]}), VEH)
    _consistent(d)
    assert d.verdict == name and d.confidence > 0.9, (d.verdict, d.confidence)
    assert d.gap.present and d.explained > 0.5 and d.shrink > 0.5
    ch = next(iter(d.holdout_rmse_before))
    assert d.holdout_rmse_after[ch] < 0.5 * d.holdout_rmse_before[ch]
    assert d.ranking[0].parameters and d.soil_after is not None


@pytest.mark.slow
@pytest.mark.parametrize("name", ["hump_shear", "slip_sinkage"])
def test_leaving_out_the_true_effect_is_never_a_confident_wrong_name(name):
    cands = [e for e in SWEEP_EFFECTS if e != name]
    for outside in (True, False):
        d = diagnose(sweep({name: SWEEP_EFFECTS[name]}), VEH, candidates=cands, weigh_outside=outside)
        _consistent(d)
        assert d.verdict == "unexplained" or d.confidence <= 0.5, (outside, d.verdict, d.confidence)


@pytest.mark.slow
def test_report_json_and_plot(tmp_path):
    d = diagnose(sweep({"hump_shear": 0.3}), VEH)
    assert isinstance(d, Diagnosis)
    js = json.loads(d.to_json())
    for k, t in {
        "verdict": str,
        "confidence": float,
        "ranking": list,
        "confusable": list,
        "localisation": list,
        "soil_before": dict,
        "gap_tests": list,
        "excluded": list,
    }.items():
        assert isinstance(js[k], t), k
    assert js["verdict"] == "hump_shear" and js["cause"] is None and js["residual_sign"] == "measured - model"
    assert set(js["ranking"][0]) >= {
        "effect",
        "weight",
        "holdout_rmse_before",
        "holdout_rmse_after",
        "shrink",
        "parameters",
    }
    assert js["confidence"] == js["ranking"][0]["weight"]
    assert {t["test"] for t in js["gap_tests"]} == {
        "flexible term beats nominal",
        "heaviest beats nominal",
        "lack of fit",
    }  # no repeated rows: no pure-error test
    # one family of tests of one question: each held to alpha = 0.01 shared among them (Bonferroni)
    assert all(t["level"] == pytest.approx(0.01 / len(js["gap_tests"])) for t in js["gap_tests"])
    assert {x["effect"] for x in js["excluded"]} >= {"clipped_sensor"}
    shares = [s["share"] for s in js["localisation"]]
    assert shares == sorted(shares, reverse=True)
    png = d.plot(str(tmp_path / "d.png"))
    assert open(png, "rb").read(8) == b"\x89PNG\r\n\x1a\n"


def test_three_points_say_how_little_they_support():
    from soiltrack.soilmodel import read_csv
    import os

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    d = diagnose(read_csv(os.path.join(root, "examples", "data", "wong2001_p176.csv")), VEHICLES["heavy"])
    assert d.verdict == "none" and d.confidence == 0.0 and d.ranking == ()
    js = json.loads(d.to_json())
    assert js["soil_after"] is None
    assert not any(isinstance(v, float) and not math.isfinite(v) for v in js.values())


def test_lack_of_fit_f_test_on_a_linear_model():
    from soiltrack.identify.diagnosis.sweep_parts import lack_of_fit
    from soiltrack.identify.diagnosis.selection import hat_basis

    rng = np.random.default_rng(0)
    x = np.linspace(0, 1, 60)
    J = np.column_stack([np.ones(60), x])
    B = hat_basis(x, np.linspace(0, 1, 8))
    noise = rng.standard_normal(60)
    assert lack_of_fit(noise, J, B, np.ones(60)) > 0.01
    assert lack_of_fit(noise + 3 * np.sin(6 * x), J, B, np.ones(60)) < 1e-6


def test_lack_of_fit_holds_a_parameter_that_ended_on_its_bound():
    """A misfit along a parameter's own column is explained when the parameter is free, and is lack of fit
    when the parameter ended on a bound (it cannot move on towards the residuals)."""
    from soiltrack.identify.diagnosis.sweep_parts import lack_of_fit
    from soiltrack.identify.diagnosis.selection import hat_basis

    rng = np.random.default_rng(1)
    x = np.linspace(0, 1, 60)
    J = np.column_stack([np.ones(60), np.exp(-x / 0.2)])
    B = hat_basis(x, np.linspace(0, 1, 8))
    r = 4.0 * J[:, 1] + rng.standard_normal(60)
    free, held = lack_of_fit(r, J, B, np.ones(60)), lack_of_fit(r, J, B, np.ones(60), held=[1])
    assert free > 0.01
    assert held < 1e-6
    # held on noise alone: one more column for the basis, and still no lack of fit
    assert lack_of_fit(rng.standard_normal(60), J, B, np.ones(60), held=[1]) > 0.01
