"""Drive-log identification (soiltrack.identify.drivelog.fit) on logs from the library's simulator.

The logs are 60 s at 50 Hz from :func:`soiltrack.soilmodel.simulation.simulate_drive_log` with
its default, realistic sensor noise (GNSS speed 0.05 m/s, encoder 0.5 % + 0.01 rad/s, torque
1 % + 0.1 % of full scale) and its default speed profile (mostly gentle driving with two hard
starts that reach the traction limit), unless a test says otherwise.

Tolerances are those the method is claimed to meet (docs/paper.md: F_max within a few
percent, K within 5-20 %); where a tolerance is wider, the test says why.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from soiltrack.identify.drivelog.fit import (
    DriveLogFitError,
    estimate_noise_profile,
    fit_drive_log,
    padded_size,
    prepare_drive_log,
)
from soiltrack.identify.drivelog.nlp import _output_error_solver
from soiltrack.identify.fitting import fit
from soiltrack.identify.sweep.problem import FitFailed
from soiltrack.soilmodel import TERRAINS, VEHICLES, DataError, DriveLog, max_thrust
from soiltrack.soilmodel.simulation import simulate_drive_log

LIGHT, HEAVY = VEHICLES["light"], VEHICLES["heavy"]
DRY_SAND, LETE_SAND = TERRAINS["dry_sand"], TERRAINS["lete_sand"]


def _errors(res, vehicle, soil):
    """Relative errors of F_max and K, and whether the 95 % intervals hold the truth."""
    F_true, K_true = max_thrust(soil, vehicle), soil.shear_modulus
    fmax = next(c for c in res.combinations if c.name.startswith("F_max"))
    k = res.parameters["shear_modulus"]
    return {
        "F": fmax.value / F_true - 1.0,
        "K": k.value / K_true - 1.0,
        "F_in": fmax.ci95[0] <= F_true <= fmax.ci95[1],
        "K_in": k.ci95[0] <= K_true <= k.ci95[1],
    }


class _LightFits:
    """Light vehicle (W = 300 N) on dry sand, default profile, noise seeds 0-7, simulated and fitted
    when first asked for: a quick test that needs one seed does not pay for eight fits."""

    n_seeds = 8

    def __init__(self) -> None:
        self._logs: dict = {}
        self._fits: dict = {}

    def log(self, seed: int):
        if seed not in self._logs:
            self._logs[seed] = simulate_drive_log(LIGHT, DRY_SAND, seed=seed)
        return self._logs[seed]

    def __getitem__(self, seed: int):
        if seed not in self._fits:
            self._fits[seed] = fit_drive_log(self.log(seed), LIGHT)
        return self.log(seed), self._fits[seed]

    def __iter__(self):
        return (self[seed] for seed in range(self.n_seeds))


@pytest.fixture(scope="module")
def light_fits():
    """Light vehicle (W = 300 N) on dry sand, default profile, 8 noise seeds, fitted on demand."""
    return _LightFits()


@pytest.mark.slow
def test_light_vehicle_recovers_fmax_and_k(light_fits):
    errs = [_errors(res, LIGHT, DRY_SAND) for _, res in light_fits]
    for (_, res), e in zip(light_fits, errs):
        assert res.success, res.message
        assert res.data_kind == "drive"
        assert abs(e["F"]) < 0.04, e  # F_max within a few percent, every seed
        assert abs(e["K"]) < 0.35, e  # single seeds: K within ~3 of its ~11 % stderr
        assert res.extra["regime"] == "hard"
    # on average: F_max within 1.5 %, K within 20 % (measured: about 1 % and 12 %)
    assert np.mean([abs(e["F"]) for e in errs]) < 0.015
    assert np.mean([abs(e["K"]) for e in errs]) < 0.20


@pytest.mark.slow
def test_light_vehicle_interval_coverage(light_fits):
    """95 % intervals hold the truth at the measured rate over 8 seeds.

    Measured with ``python benchmarks/drivelog_coverage.py --seeds 200`` (sandwich covariance
    of the profiled estimator, see ``drivelog_covariance.profiled_covariance``): F_max 188/200 (94 %),
    K 179/200 (89.5 %; K is about 3 % low on average, so its misses are mostly on the low
    side). With the former Gauss-Newton covariance: F_max 179/200, K 173/200. On these 8 seeds:
    F_max 8/8, K 7/8 (before: 7/8 and 5/8). The bounds asserted are those a method with the
    measured rates fails with probability below 1 % (binomial, n = 8): F_max at least 6 of 8
    (p = 0.94: P(X <= 5) = 0.96 %), K at least 5 of 8 (p = 0.895: P(X <= 4) = 0.6 %).
    Eight seeds cannot tell 89.5 % from 95 % coverage; the benchmark does that.
    """
    errs = [_errors(res, LIGHT, DRY_SAND) for _, res in light_fits]
    assert sum(e["F_in"] for e in errs) >= 6
    assert sum(e["K_in"] for e in errs) >= 5
    assert all(res.extra["covariance"] == "sandwich" for _, res in light_fits)


@pytest.mark.slow  # builds an exact IPOPT re-solve of 3,001 latent slips: 5-7 s of the quick loop's 90 s
def test_covariance_is_the_profiled_sandwich(light_fits):
    """The reported (F_max, K) covariance is A^-1 B A^-1 of the profiled estimator.

    Recomputed here from the solution (same solver, started at the optimum): the standard
    errors handed through the shared result object must be those of the sandwich, and the
    observed information A must be symmetric positive definite, B positive semi-definite.
    """
    from soiltrack.identify.drivelog import covariance as C
    from soiltrack.identify.drivelog import nlp as D
    from soiltrack.soilmodel.soil import PRACTICAL_BOUNDS

    log, res = light_fits[0]
    e = res.extra
    prep = prepare_drive_log(log, LIGHT)
    Fb = D.fmax_bounds(PRACTICAL_BOUNDS, LIGHT, "full")
    Kb = tuple(PRACTICAL_BOUNDS.shear_modulus)
    F_ref, K_ref = 0.5 * (Fb[0] + Fb[1]), math.sqrt(Kb[0] * Kb[1])
    _, Fm, K, slip = D.solve_output_error(
        prep, LIGHT, F_ref, K_ref, Fb, Kb, [(e["max_thrust_N"], e["shear_modulus_m"])], 500, 1e-9, 0
    )
    assert Fm == pytest.approx(e["max_thrust_N"], rel=1e-5) and K == pytest.approx(e["shear_modulus_m"], rel=1e-4)
    l = LIGHT.track_length
    F, dF_ds, dF_dFm, dF_dK = D.eval_pointwise(slip, Fm, K, l)
    V, A, B = C.profiled_covariance(prep, LIGHT.sprocket_radius, slip, Fm, K, l, F, dF_ds, dF_dFm, dF_dK)
    assert np.allclose(A, A.T) and np.all(np.linalg.eigvalsh(A) > 0)
    assert np.all(np.linalg.eigvalsh(B) >= 0)
    assert e["max_thrust_stderr_N"] == pytest.approx(math.sqrt(V[0, 0]), rel=1e-3)
    assert e["shear_modulus_stderr_m"] == pytest.approx(math.sqrt(V[1, 1]), rel=1e-3)
    assert res.parameters["shear_modulus"].stderr == pytest.approx(math.sqrt(V[1, 1]), rel=1e-3)


@pytest.mark.slow  # long end-to-end (quick loop: README); CI runs it
def test_light_vehicle_result_contents(light_fits):
    log, res = light_fits[0]
    e = res.extra
    # c and phi are not separable from one normal load: the Jacobian columns are proportional
    J = res.jacobian
    cos = abs(J[:, 0] @ J[:, 1]) / (np.linalg.norm(J[:, 0]) * np.linalg.norm(J[:, 1]))
    assert cos == pytest.approx(1.0, abs=1e-12)
    assert res.rank == 2
    assert res.parameters["cohesion"].value is None and not res.parameters["cohesion"].identifiable
    assert res.parameters["shear_modulus"].identifiable
    assert res.soil is None  # no (c, phi) point is presented as an estimate
    assert any("not separable" in w for w in res.warnings)
    # identifiable combinations and their uncertainty, consistent with the shared result object
    fmax = next(c for c in res.combinations if c.name.startswith("F_max"))
    assert fmax.value == pytest.approx(e["max_thrust_N"], rel=1e-9)
    assert fmax.stderr == pytest.approx(e["max_thrust_stderr_N"], rel=1e-6)
    slope = next(c for c in res.combinations if c.name.startswith("initial_slope"))
    assert slope.value == pytest.approx(e["initial_slope_N"], rel=1e-9)
    assert -0.99 < e["corr_max_thrust_shear_modulus"] < 0.99
    # sample bookkeeping: standstill samples are dropped and counted
    assert e["samples_used"] + e["samples_dropped_slow"] + e["samples_dropped_braking"] < log.n_samples
    assert e["samples_dropped_slow"] > 0
    assert res.n_samples == e["samples_used"] == res.weighted_residuals.size
    assert 0.7 < e["reduced_chi2"] < 1.5  # the estimated noise model is consistent
    assert np.all(np.isfinite(res.residuals)) and np.all(np.isfinite(res.jacobian))
    d = json.loads(res.to_json())  # strict JSON: no NaN anywhere
    assert d["data_kind"] == "drive" and d["extra"]["regime"] == "hard"


@pytest.mark.slow  # long end-to-end (quick loop: README); CI runs it
def test_noise_model_is_estimated_from_the_log(light_fits):
    log, res = light_fits[1]
    nm = res.extra["noise_model"]
    assert nm["estimated"]
    assert nm["vehicle_speed_m_s"]["abs"] == pytest.approx(0.05, rel=0.15)  # GNSS 0.05 m/s
    assert nm["sprocket_speed_rad_s"]["rel"] == pytest.approx(0.005, rel=0.25)  # encoder 0.5 %
    a, b = estimate_noise_profile(np.full(500, 3.0) + 0.1 * np.random.default_rng(0).standard_normal(500))
    assert math.hypot(a, 3.0 * b) == pytest.approx(0.1, rel=0.15)  # constant signal: 0.1 at 3.0


@pytest.mark.slow
def test_equation_error_is_biased_where_output_error_is_not(light_fits):
    """Slip from noisy speeds as an exact regressor (equation error) is the EIV trap."""
    log, res_oe = light_fits[0]
    res_ee = fit_drive_log(log, LIGHT, formulation="equation-error")
    e_oe, e_ee = _errors(res_oe, LIGHT, DRY_SAND), _errors(res_ee, LIGHT, DRY_SAND)
    assert abs(e_oe["F"]) < 0.04
    assert abs(e_ee["F"]) > 0.3 or abs(e_ee["K"]) > 0.5  # measured: F_max -88 %, K +100 % (on bounds)
    assert not (e_ee["F_in"] and e_ee["K_in"])
    assert any("equation-error" in w for w in res_ee.warnings)


@pytest.mark.slow
def test_heavy_vehicle_hard_starts_pin_fmax_and_say_k_is_weak():
    """Heavy vehicle on LETE sand: K/l = 0.4 %, below what 0.05 m/s GNSS noise resolves well.

    The hard starts reach the traction limit (track spin), so F_max comes out within a few
    percent; the log has few samples at intermediate slip, so K is uncertain, and the result
    must say so rather than present a precise K.
    """
    for seed in (0, 1):
        log = simulate_drive_log(HEAVY, LETE_SAND, seed=seed)
        res = fit_drive_log(log, HEAVY)
        e = _errors(res, HEAVY, LETE_SAND)
        assert res.success
        assert abs(e["F"]) < 0.03, e  # measured: 0.6 % and 1.1 %
        assert e["K_in"]  # the wide K interval holds the truth
        assert res.extra["shear_modulus_stderr_m"] / res.extra["shear_modulus_m"] > 0.25
        assert res.extra["regime"] == "intermediate"
        assert any("K is poorly determined" in w for w in res.warnings)


@pytest.mark.slow
def test_gentle_log_is_flagged():
    """Cruising well below the traction limit shows only the initial slope F_max l / (2K)."""

    def gentle(t):
        t = np.asarray(t, dtype=float)
        return np.clip(t / 8.0, 0.0, 1.0) * (1.2 + 0.3 * np.sin(2 * np.pi * t / 12.0))

    log = simulate_drive_log(LIGHT, DRY_SAND, seed=3, speed_profile=gentle)
    res = fit_drive_log(log, LIGHT)
    e = res.extra
    assert res.success
    assert e["regime"] == "gentle"
    assert e["thrust_peak_N"] < 0.15 * max_thrust(DRY_SAND, LIGHT)
    assert abs(e["corr_max_thrust_shear_modulus"]) > 0.99 or e["max_thrust_stderr_N"] > e["max_thrust_N"]
    msg = next(w for w in res.warnings if w.startswith("gentle driving"))
    assert "initial slope F_max l/(2K)" in msg and "not separable" in msg and "hard pull" in msg
    # the slope itself is what the log carries: its interval must hold the true slope
    true_slope = max_thrust(DRY_SAND, LIGHT) * LIGHT.track_length / (2 * DRY_SAND.shear_modulus)
    q = res.quantile
    assert abs(e["initial_slope_N"] - true_slope) < q * e["initial_slope_stderr_N"]


@pytest.mark.slow  # a 4 s fit; the quick loop keeps the other recovery tests
def test_noise_free_log_is_recovered_exactly():
    """Without noise the discrete sprocket equation (implicit Euler, ZOH torque) is exact."""
    log = simulate_drive_log(HEAVY, LETE_SAND, noise="none")
    res = fit_drive_log(log, HEAVY)
    e = _errors(res, HEAVY, LETE_SAND)
    assert abs(e["F"]) < 1e-3 and abs(e["K"]) < 1e-2, e


@pytest.mark.slow  # 5.9 s: the model's fits run both discretisation rules since stop 49
def test_cohesion_free_model_identifies_phi(light_fits):
    log = light_fits.log(2)
    res = fit_drive_log(log, LIGHT, model="cohesion-free")
    assert res.success
    phi = res.parameters["friction_angle"]
    assert phi.identifiable and phi.value is not None
    # phi absorbs the cohesion term: W tan(phi) = F_max
    assert LIGHT.weight * math.tan(phi.value) == pytest.approx(res.extra["max_thrust_N"], rel=1e-6)
    assert res.parameters["cohesion"].fixed


def test_solver_is_built_once_per_padded_size(light_fits):
    log = light_fits.log(3)
    n = prepare_drive_log(log, LIGHT).n_used
    fit_drive_log(log, LIGHT, multistart=False)  # builds what this padded size needs (if no earlier test did)
    before = _output_error_solver.cache_info()
    fit_drive_log(log, LIGHT, multistart=False)
    after = _output_error_solver.cache_info()
    assert after.misses == before.misses and after.hits > before.hits
    assert padded_size(n) >= n and padded_size(n) < 1.5 * n + 64


@pytest.mark.slow
def test_failure_is_reported_not_hidden(light_fits):
    log = light_fits.log(4)
    res = fit_drive_log(log, LIGHT, max_iter=2, multistart=False)
    assert not res.success
    assert "failed" in res.message
    assert res.soil is None
    json.loads(res.to_json())  # still valid JSON, no NaN
    with pytest.raises(DriveLogFitError) as ei:
        fit_drive_log(log, LIGHT, max_iter=2, multistart=False, strict=True)
    assert isinstance(ei.value, FitFailed) and not ei.value.result.success


@pytest.mark.slow  # 2.8 s: the quick loop stays under 90 s; CI runs it
def test_library_fit_dispatches_drive_logs(light_fits):
    log, res = light_fits[1]
    via_fit = fit(log, LIGHT)
    assert via_fit.data_kind == "drive"
    assert via_fit.extra["max_thrust_N"] == pytest.approx(res.extra["max_thrust_N"], rel=1e-9)


def _log(n, v, w, M, source="run.csv"):
    t = np.arange(n) * 0.02
    return DriveLog(
        time=t,
        sprocket_torque=np.full(n, M, dtype=float) if np.isscalar(M) else M,
        sprocket_speed=np.full(n, w, dtype=float) if np.isscalar(w) else w,
        vehicle_speed=np.full(n, v, dtype=float) if np.isscalar(v) else v,
        source=source,
    )


def test_bad_inputs_name_file_and_column():
    with pytest.raises(DataError) as ei:
        fit_drive_log(_log(5, 1.0, 13.0, 2.0), LIGHT)
    assert ei.value.file == "run.csv" and ei.value.column == "time_s"
    with pytest.raises(DataError) as ei:
        fit_drive_log(_log(200, 0.0, 13.0, 2.0), LIGHT)
    assert ei.value.file == "run.csv" and ei.value.column == "vehicle_speed_m_s"
    with pytest.raises(DataError) as ei:
        fit_drive_log(_log(200, 1.0, 0.0, 2.0), LIGHT)
    assert ei.value.column == "sprocket_speed_rad_s"
    # moving, but only a handful of samples above the noise: refused, not fitted
    v = np.zeros(200)
    v[100:105] = 1.0
    with pytest.raises(DataError) as ei:
        fit_drive_log(_log(200, v, v / 0.08, 1.0), LIGHT)
    assert ei.value.column == "vehicle_speed_m_s" and "at least" in str(ei.value)
    good = _log(200, 1.0, 13.0, 2.0)
    with pytest.raises(DataError):
        fit_drive_log(good, LIGHT, formulation="magic")
    with pytest.raises(DataError):
        fit_drive_log(good, LIGHT, no_such_option=1)
    with pytest.raises(DataError):
        fit_drive_log(good, LIGHT, sigma_torque=-1.0)


@pytest.mark.slow
def test_simex_bias_correction_is_opt_in_and_recorded(light_fits):
    """bias_correction="simex": refits with extra GNSS-speed noise, extrapolated to none.

    The default path is untouched (no "bias_correction" in extra); the corrected fit records
    the method, the replicate count and the uncorrected estimate, moves K up (the uncorrected
    K is biased low by the speed noise, see benchmarks/README.md) and widens its interval by
    the Monte Carlo variance of the extrapolation, centred on the corrected estimate.
    """
    log, base = light_fits[1]
    assert "bias_correction" not in base.extra
    res = fit_drive_log(log, LIGHT, bias_correction="simex", simex_replicates=2)
    assert res.success, res.message
    bc = res.extra["bias_correction"]
    assert bc["method"] == "simex" and bc["applied"] and bc["replicates"] == 2
    assert bc["lambdas"] == [0.5, 1.0, 2.0]
    unc = bc["uncorrected"]
    assert unc["shear_modulus_m"] == base.extra["shear_modulus_m"]  # same uncorrected fit
    assert unc["max_thrust_N"] == base.extra["max_thrust_N"]
    k, k0 = res.parameters["shear_modulus"], base.parameters["shear_modulus"]
    assert k.value > k0.value  # corrected upwards
    assert k.value - k0.value == pytest.approx(bc["correction"]["shear_modulus_m"])
    assert abs(k.value / DRY_SAND.shear_modulus - 1) < 0.35
    assert k.stderr >= k0.stderr  # + extrapolation variance
    assert k.stderr == pytest.approx(res.extra["shear_modulus_stderr_m"], rel=1e-9)
    assert k.ci95[0] < k.value < k.ci95[1]
    kc = next(c for c in res.combinations if c.name == "K")  # one K interval (issue 7): the
    assert kc.value == pytest.approx(k.value, rel=1e-9) and kc.ci95 == pytest.approx(k.ci95, rel=1e-12)  # parameter's
    fmax = next(c for c in res.combinations if c.name.startswith("F_max"))
    assert fmax.value == pytest.approx(res.extra["max_thrust_N"], rel=1e-9)
    assert fmax.stderr == pytest.approx(res.extra["max_thrust_stderr_N"], rel=1e-6)
    assert res.extra["covariance"] == "sandwich+simex"
    json.loads(res.to_json())
    with pytest.raises(DataError):
        fit_drive_log(log, LIGHT, bias_correction="jackknife")


@pytest.mark.slow
def test_simex_is_not_applied_to_a_log_that_does_not_pin_k():
    """Heavy vehicle on LETE sand ("intermediate" log, K poorly determined): no SIMEX.

    Measured on 20 seeds: there the refitted K wanders over its range and the extrapolation
    cost F_max coverage (16/20 instead of 20/20), so the correction is skipped and says so.
    """
    log = simulate_drive_log(HEAVY, LETE_SAND, seed=0)
    base = fit_drive_log(log, HEAVY)
    res = fit_drive_log(log, HEAVY, bias_correction="simex")
    assert res.extra["regime"] == "intermediate"
    assert res.extra["bias_correction"]["applied"] is False
    assert res.extra["shear_modulus_m"] == base.extra["shear_modulus_m"]
    assert res.extra["max_thrust_N"] == base.extra["max_thrust_N"]
    assert any("SIMEX bias correction not applied" in w for w in res.warnings)


def test_k_on_its_bound_leaves_fmax_identified_only_when_pinned_down():
    """K on a bound: F_max's interval is the one of K held there - the log is "gentle" (F_max not determined)
    unless F_max's own standard error is within 5 % (a pull to the traction limit pins it whatever K is)."""
    from soiltrack.identify.drivelog.regime import classify_regime

    def regime(rel_F, at_bound):
        F, K = 265.0, 0.006
        sF, sK, corr = rel_F * F, 0.5 * K, 0.9
        cov = np.array([[sF**2, corr * sF * sK], [corr * sF * sK, sK**2]])
        return classify_regime(F, K, 0.5, cov, at_bound, 200.0, 0.75, 10)[0]

    assert regime(0.10, ["K"]) == "gentle"
    assert regime(0.10, []) == "intermediate"
    assert regime(0.03, ["K"]) == "intermediate"


@pytest.mark.parametrize("seed", [3, pytest.param(4, marks=pytest.mark.slow)])  # seed 4: 6.6 s (two-rule check)
def test_a_start_from_rest_gives_no_confident_wrong_fmax(seed):
    # 20 s of a gentle profile from rest: the large thrust comes only in the first half second, at speeds whose
    # slip the log hardly measures. Seed 3 used to fit "hard", F_max 93.5 +- 4.5 N (truth 263.5 N, 38 SE off),
    # while F_max's profiled cost rises by only 0.65 at +-2 SE. Either the interval holds the truth or F_max is
    # reported as not determined (independent of the regime rule: the truth from the soil itself).
    light, soil = VEHICLES["light"], TERRAINS["dry_sand"]
    log = simulate_drive_log(
        light,
        soil,
        seed=seed,
        duration_s=40,
        speed_profile=lambda t: 1.2 + 0.3 * np.sin(2 * np.pi * np.asarray(t) / 12),
    )
    res = fit(log.subset(np.nonzero(log.time < 20)[0]), light)
    truth = max_thrust(soil, light)
    name = next(cb.name for cb in res.combinations if cb.name.startswith("F_max"))
    if name in res.undetermined_combinations:
        assert res.extra["regime"] == "gentle"
    else:
        Fm, se = res.extra["max_thrust_N"], res.extra["max_thrust_stderr_N"]
        assert abs(Fm - truth) < 3 * se, (Fm, se, truth)
