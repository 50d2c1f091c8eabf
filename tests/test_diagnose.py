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
    _, screens = screen(sweep(noise="none"), VEH, list(SWEEP_EFFECTS))
    return {s.effect: s for s in screens}


def test_score_is_zero_at_the_nominal_model_on_effect_free_noise_free_data(clean_screens):
    # the nominal fit matches noise-free effect-free data to the solver's tolerance: the cosine between
    # residuals and every effect's projected sensitivity is at the level of that tolerance
    for name, s in clean_screens.items():
        assert s.screenable, name
        assert s.score < 1e-3, (name, s.score)


@pytest.mark.parametrize("name", sorted(SWEEP_EFFECTS))
def test_score_is_nonzero_with_the_effect(name, clean_screens):
    _, screens = screen(sweep({name: SWEEP_EFFECTS[name]}, noise="none"), VEH, [name])
    s = screens[0]
    # measured cosines 0.3 to 1 (radius_error's local sensitivity is the weakest)
    assert s.score > 0.2 and s.score > 100 * clean_screens[name].score, (name, s.score)


@pytest.mark.parametrize("seed", [1, 2])
def test_none_on_effect_free_data(seed):
    d = diagnose(sweep(seed=seed), VEH)
    assert d.verdict == "none" and d.confidence > 0.5
    assert d.shrink is None and d.soil_after is None and isinstance(d.soil_before, dict)


@pytest.mark.parametrize("name", ["hump_shear", "slip_sinkage", "radius_error"])
@pytest.mark.slow
def test_clean_case_is_diagnosed_and_the_gap_shrinks(name):
    # radius_error: the nominal fit of this sweep converges but fails issue 7's plausibility checks (rows at
    # small slip far off the curve); the diagnosis uses its converged answer and says so
    d = diagnose(sweep({name: SWEEP_EFFECTS[name]}), VEH)
    if name == "slip_sinkage":
        # hump_shear, listed confusable, predicts the held-out blocks exactly as well (measured shrink 0.8198
        # against 0.8200; weights 0.28 and 0.72 on all the data): named, with confidence 0.5 and the pair listed
        assert d.verdict == name and d.confidence == 0.5, (d.verdict, d.confidence)
        assert any(set(p) == {"slip_sinkage", "hump_shear"} for p, _, _ in d.confusable)
        assert any("predicts the held-out blocks as well" in t for t in d.notes)
    else:
        assert d.verdict == name and d.confidence > 0.5, (d.verdict, d.confidence)
    assert d.shrink > 0.5
    ch = next(iter(d.holdout_rmse_before))
    assert d.holdout_rmse_after[ch] < 0.5 * d.holdout_rmse_before[ch]
    assert d.ranking[0].effect == name and d.ranking[0].parameters
    if name == "radius_error":
        assert d.converged and any("plausibility checks" in t for t in d.notes), d.notes


def test_leaving_out_the_true_effect_is_never_a_confident_wrong_name():
    d = diagnose(
        sweep({"hump_shear": 0.3}),
        VEH,
        candidates=["grade", "slip_sinkage", "speed_resistance", "radius_error", "mass_error"],
    )
    assert d.verdict == "unexplained" or d.confidence <= 0.5, (d.verdict, d.confidence)


@pytest.mark.parametrize("name", ["slip_sinkage", "radius_error"])
@pytest.mark.slow
def test_leave_one_out_without_weighing_the_left_out_effect(name):
    # the true effect neither among the candidates nor weighed from outside them: a candidate that imitates it
    # (hump_shear stretched to its bound for slip_sinkage; grade for radius_error, leaving a smooth gap) must
    # not be named with confidence
    cands = [e for e in SWEEP_EFFECTS if e != name]
    d = diagnose(sweep({name: SWEEP_EFFECTS[name]}), VEH, candidates=cands, weigh_outside=False)
    assert d.verdict == "unexplained" or d.confidence <= 0.5, (d.verdict, d.confidence, d.reason)


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
    }.items():
        assert isinstance(js[k], t), k
    assert set(js["ranking"][0]) >= {
        "effect",
        "weight",
        "holdout_rmse_before",
        "holdout_rmse_after",
        "shrink",
        "parameters",
    }
    assert abs(sum(e["weight"] for e in js["ranking"]) - 1.0) < 1e-9
    assert all(s["dimension"] in ("channel", "slip", "speed", "time") for s in js["localisation"])
    shares = [s["share"] for s in js["localisation"]]
    assert shares == sorted(shares, reverse=True)
    slip = [s for s in js["localisation"] if s["dimension"] == "slip"]
    assert slip[0]["significant"] and abs(sum(s["share"] for s in slip) - 1.0) < 1e-9
    text = d.report()
    assert "hump_shear" in text and "shrink" in text and "nan" not in text.lower()
    png = d.plot(str(tmp_path / "d.png"))
    assert open(png, "rb").read(8) == b"\x89PNG\r\n\x1a\n"


def test_three_points_say_how_little_they_support():
    from soiltrack.soilmodel import read_csv
    import os

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    d = diagnose(read_csv(os.path.join(root, "examples", "data", "wong2001_p176.csv")), VEHICLES["heavy"])
    assert d.verdict == "none" and d.confidence == 0.0
    assert "3 samples cannot show a gap" in d.reason
    assert json.loads(d.to_json())["soil_after"] is None
    assert not any(isinstance(v, float) and not math.isfinite(v) for v in json.loads(d.to_json()).values())


def test_drive_log_score_for_drivetrain_friction():
    # drivetrain_friction shows only in drive logs. The nominal drive-log model (implicit-Euler sprocket
    # equation) matches the simulator's noise-free log only to its discretisation, so the score is not
    # exactly zero without the effect: measured gain 5.5 without, 3.0e5 with (whitened units)
    Wr = VEH.weight * VEH.sprocket_radius
    gains = []
    for eff in (None, {"drivetrain_friction": 0.03 * Wr}):
        log = simulate(VEH, SOIL, kind="drive", effects=eff, seed=1, duration_s=10.0, noise="none")
        res, screens = screen(log, VEH, ["drivetrain_friction"], hac_lag=None)
        assert res.success and res.extra["screening_stationarity"] < 1e-5  # a consistent pair at an optimum
        gains.append(screens[0])
    assert gains[1].gain > 1e3 * gains[0].gain and gains[1].score > 0.99


def test_none_on_an_effect_free_drive_log():
    log = simulate(VEH, SOIL, kind="drive", seed=1, duration_s=15.0)
    d = diagnose(log, VEH)
    assert d.verdict == "none" and d.confidence > 0.5 and d.converged
    assert set(d.holdout_rmse_before) == {"sprocket_speed_rad_s", "thrust_N", "hull_N"}
    assert {s.dimension for s in d.localisation} == {"channel", "time", "speed", "slip"}


def test_a_failed_nominal_fit_is_reported_not_hidden(monkeypatch, tmp_path):
    # stub of the fit interface (tests only): every fit fails, as IPOPT may on hostile data
    from types import SimpleNamespace

    import soiltrack.identify.fitting as fitting

    def failing_fit(data, vehicle, model="full", effects=(), fixed=None, **kw):
        k = 3 + len(effects or ())
        return SimpleNamespace(
            success=False,
            status="Maximum_Iterations_Exceeded",
            message="stub",
            parameter_names=("cohesion", "friction_angle", "shear_modulus") + tuple(f"{e}.x" for e in (effects or ())),
            jacobian=np.zeros((data.n_samples, k)),
            weighted_residuals=np.zeros(data.n_samples),
            parameters={},
            combinations=[],
            extra={},
            active_bounds={},
            data_kind="slip",
        )

    monkeypatch.setattr(fitting, "fit", failing_fit)
    d = diagnose(sweep(), VEH)
    assert d.verdict == "unexplained" and d.confidence == 0.0 and not d.converged
    assert "could not be fitted" in d.reason and "Maximum_Iterations_Exceeded" in d.reason
    js = json.loads(d.to_json())
    assert js["soil_after"] is None and isinstance(js["soil_before"], dict)
    d.plot(str(tmp_path / "f.png"))
    assert "could not be fitted" in d.report()


def test_f_test_and_lack_of_fit_on_known_cases():
    from soiltrack.identify.diagnosis.sweep_parts import f_sf, lack_of_fit
    from soiltrack.identify.diagnosis.selection import hat_basis

    # tabulated critical values of the F distribution (1 % and 5 %)
    for f, d1, d2, p in ((3.51, 5, 40, 0.01), (2.08, 10, 40, 0.05), (7.31, 1, 40, 0.01)):
        assert abs(f_sf(f, d1, d2) - p) < 0.001, (f, d1, d2, f_sf(f, d1, d2))
    # a linear model y = a + b x: white residuals leave nothing for a flexible term, a smooth bump does
    rng = np.random.default_rng(3)
    x = np.linspace(0.0, 1.0, 60)
    J = np.column_stack([np.ones_like(x), x])
    B = hat_basis(x, np.linspace(0.0, 1.0, 8))
    ps = [lack_of_fit(rng.normal(size=x.size), J, B, np.ones_like(x)) for _ in range(200)]
    assert 0.0 < np.mean(np.array(ps) < 0.05) < 0.12  # about 5 % under the null
    # a bump whose sum of squares (about 80) is far above the noise's 60 +- 11: any valid test must see it
    bump = 3.0 * np.exp(-(((x - 0.3) / 0.12) ** 2)) + rng.normal(size=x.size)
    assert lack_of_fit(bump, J, B, np.ones_like(x)) < 1e-3
