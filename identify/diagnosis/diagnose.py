"""The sim-to-real gap diagnosis as one comparison of hypotheses (docs/diagnosis.md).

The procedure, one step per module:

1. **Data** (:mod:`.setup`, :mod:`.fits`, :mod:`.hold`): the candidates, the fit runner, the folds;
   a drive log's torque hold when not given.
2. **Screening** (:mod:`.screening`): the nominal model on all the data, with every library
   effect's score test; it ranks the effects for refitting and gives their sensitivities.
3. **The gap** (:mod:`.gap`, :mod:`.gap_test`): the noise floor, the held-out error of the nominal
   model, the tests that say whether there is a gap.
4. **Hypotheses** (:mod:`.library`, :mod:`.outside`): the nominal model, the library's effects, the
   flexible term and the causes outside the library, each fitted, with its parameter count and its
   admissibility.
5. **Evidence** (:mod:`.evidence`): one set of weights over the admissible hypotheses (held-out for
   a log, penalised in-sample for a sweep).
6. **Verdict** (:mod:`.decision`): one rule; the confidence is the verdict's weight.
7. **Localisation** (:mod:`.localisation`): where the nominal misfit lies.
8. **Result** (:mod:`.result`, :mod:`.report`, :mod:`.plot`): the report, the JSON, the figure.

Residuals are measured - model throughout.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any, Callable, Sequence

import numpy as np

from ...soilmodel.data import DriveLog, SlipData
from ...soilmodel.effects import EFFECTS
from ...soilmodel.errors import DataError
from ...soilmodel.soil import PARAMETER_NAMES, PRACTICAL_BOUNDS, SoilBounds
from ...soilmodel.vehicle import Vehicle
from ..consistency import ConsistencyReport, check_consistency
from ..sweep.rig import pure_error_test
from ..sweep.sinkage_channel import slip_sinkage_evidence
from .decision import share_confusable, UNEXPLAINED, Decision, decide
from .evidence import HeldOutEvidence, PenalisedEvidence
from .fits import FitRunner, channels, effect_parameters, log_noise, soil_summary, usable
from .gap import long_run_factor
from .gap_test import GapDecision, decide_gap
from .hold import HoldChoice, choose_hold
from .hypotheses import NOMINAL, Frame, Hypothesis
from .library import effect_hypothesis, flexible_hypothesis, nominal_hypothesis
from .localisation import localisation
from .outside import outside_hypotheses
from .result import Diagnosis, Excluded, RankEntry
from .screening import Screen, screen
from .selection import LOOKALIKES, dm_test, gap_p_value, hat_basis
from .sweep_parts import fit_jacobian, lack_of_fit
from .settings import DEFAULT_SETTINGS, DiagnoseSettings
from .setup import Setup, check_candidates, lone_readings, make_folds, noise_floors, sweep_noise_model

__all__ = ["diagnose", "Diagnosis", "RankEntry", "TORQUE_HOLDS"]

#: Accepted ``torque_hold`` values; None and ``"auto"``: not given, chosen on the held-out blocks
#: (:mod:`.hold`).
TORQUE_HOLDS = (None, "auto", "zoh", "sample")


def _runner(
    data: Any,
    vehicle: Vehicle,
    model: str,
    torque_hold: str | None,
    bounds: SoilBounds | None,
    settings: DiagnoseSettings,
) -> FitRunner:
    if not isinstance(data, (SlipData, DriveLog)):
        raise DataError(f"diagnose takes SlipData or DriveLog, got {type(data).__name__}")
    if not isinstance(vehicle, Vehicle):
        raise DataError(f"vehicle must be a Vehicle, got {type(vehicle).__name__}")
    if torque_hold not in TORQUE_HOLDS:
        raise DataError(f"torque_hold must be 'auto', 'zoh' or 'sample', got {torque_hold!r}")
    # the data's consistency is checked once, on all of it (diagnose); the refits of its parts skip it
    options: dict[str, Any] = {"bounds": PRACTICAL_BOUNDS if bounds is None else bounds, "consistency": False}
    if isinstance(data, DriveLog):
        options["torque_hold"] = torque_hold if torque_hold in ("zoh", "sample") else "zoh"
    return FitRunner(
        data,
        vehicle,
        model,
        options,
        settings,
        hold_given=torque_hold if torque_hold in ("zoh", "sample") else None,
    )


def _setup(runner: FitRunner, nominal_fit: Any, sensitivities: Any = None) -> Setup:
    data = runner.data
    x = np.asarray(data.time if isinstance(data, DriveLog) else data.slip, dtype=float)
    order = np.arange(data.n_samples) if runner.is_log else np.argsort(x, kind="stable")
    sensor, expected = None, None
    if isinstance(data, DriveLog):  # runner.is_log
        # the evidence weighs a log's channels by the sensors' noise, as the fit does; the latent slip of each
        # sample takes up part of it (expected: the share it leaves)
        R, sensor, expected = log_noise(nominal_fit, data)
        if np.all(np.isfinite(nominal_fit.theta)):
            runner.x0 = np.asarray(nominal_fit.theta, dtype=float)
    else:
        R = channels(nominal_fit, data)
    sigma, flat = noise_floors(R, order, runner.settings.noise_window(data.n_samples, runner.is_log))
    # a sweep: the nominal fit with its slip-noise model (the screening fit takes the slip as exact)
    model_sigma = None if runner.is_log else sweep_noise_model(runner.run(None, slip_noise="auto"), data)
    if model_sigma is not None:
        sigma = {ch: model_sigma for ch in sigma}
    folds = make_folds(data, order, runner.settings)
    return Setup(
        runner,
        nominal_fit,
        R,
        sigma,
        frozenset(flat),
        folds,
        x,
        order,
        model_sigma is not None,
        lone_readings(R, x),
        sensor,
        expected,
        sensitivities,
    )


def _refits(
    screens: list[Screen], cands: tuple[str, ...], hint: bool, setup: Setup, outside_too: bool
) -> list[tuple[str, str]]:
    """``(effect, family)`` of the library effects to refit: all on a sweep; on a log the strongest by score
    gain (candidates, then those outside them), none when nothing screens significant and no gap is hinted."""
    s = setup.settings
    ok = [x for x in screens if x.screenable]
    if not setup.is_log:
        twins = set() if outside_too else _twins(ok, cands, s.confusable_corr)
        return [
            (x.effect, "candidate" if x.effect in cands else "outside")
            for x in ok
            if x.effect in cands or outside_too or x.effect in twins
        ]
    thr = s.alpha / max(1, len([x for x in ok if x.effect in cands]))
    if not hint and not any(x.p_value < thr for x in ok if x.effect in cands):
        return []
    by_gain = sorted(ok, key=lambda x: -x.gain)
    out = [(x.effect, "candidate") for x in by_gain if x.effect in cands][: s.log_refits]
    if outside_too:
        out += [(x.effect, "outside") for x in by_gain if x.effect not in cands][: s.log_outside_refits]
    return out


def _twins(screens: list[Screen], cands: tuple[str, ...], min_corr: float) -> set[str]:
    """Library effects outside the candidates whose sensitivity is collinear with a candidate's (``|corr| >=
    min_corr``): the data cannot tell them apart from it, so they are weighed even when the effects outside the
    candidates are not; otherwise the candidate's weight would only say that its twin was left out."""
    d = {x.effect: x.direction for x in screens if x.direction is not None and np.linalg.norm(x.direction) > 0}
    out = set()
    for e, de in d.items():
        if e in cands:
            continue
        for c in cands:
            dc = d.get(c)
            if dc is not None and abs(float(de @ dc)) / (np.linalg.norm(de) * np.linalg.norm(dc)) >= min_corr:
                out.add(e)
    return out


def _frame(setup: Setup, nominal: Hypothesis, held: bool) -> Frame:
    """The evidence's samples (``held``: the held-out residuals of every fold) with the noise floor
    (:meth:`~.setup.Setup.frame`: lone readings left out)."""
    return setup.frame(nominal.heldout() if held else nominal.residuals)


def _sweep_noise(setup: Setup, hyps: list[Hypothesis]) -> Setup:
    """A sweep's noise floor (when it does not come from the fit's slip-noise model) from the residuals of the
    effect that fits it best (when better than nominal): where the nominal model misses a sharp bend, its second
    differences carry the bend and overstate the noise."""
    if setup.noise_from_fit:
        return setup
    frame = _frame(setup, hyps[0], held=False)
    ss = {
        h.name: float(np.nansum(frame.z(h.residuals) ** 2))
        for h in hyps
        if h.family in ("nominal", "candidate", "outside") and h.admissible and h.fit is not None
    }
    ss_nom = float(np.nansum(frame.z(setup.residuals) ** 2))
    if not ss or min(ss.values()) >= ss_nom:
        return setup
    best = next(h for h in hyps if h.name == min(ss, key=lambda k: ss[k]))
    sigma, _ = noise_floors(best.residuals, setup.order, setup.settings.noise_window(setup.n, False))
    return replace(setup, sigma=sigma)


def _hypotheses(
    setup: Setup,
    base: tuple[Hypothesis, list, list],
    screens: list[Screen],
    cands: tuple[str, ...],
    weigh_outside: bool,
    say: Callable[[str], None],
) -> tuple[Setup, list[Hypothesis]]:
    """Every hypothesis fitted: ``base`` is the nominal one with its training fits and residuals."""
    nominal, train_fits, train_res = base
    flexible = flexible_hypothesis(setup, nominal, train_res)
    fz = _frame(setup, nominal, held=True)
    # a gap hinted by either test that needs no effect: the flexible term beats the nominal model, or (a log)
    # the nominal held-out error exceeds the noise; without either and without a significant screen, no refit
    z0, alpha = fz.z(nominal.heldout()), setup.settings.alpha
    hint = dm_test(z0, fz.z(flexible.heldout(), z0), setup.dm_lag) < alpha or (
        setup.is_log and _nominal_vs_noise(setup, nominal, fz) < alpha
    )
    hyps = [nominal, flexible]
    for name, fam in _refits(screens, cands, hint, setup, weigh_outside):
        say(f"{name} refitted ({fam})")
        hyps.append(effect_hypothesis(setup, name, fam))
    say("causes outside the library")
    hyps += outside_hypotheses(setup, nominal, train_res, train_fits[0], hyps[2:])
    if not setup.is_log:
        setup = _sweep_noise(setup, hyps)
    return setup, hyps


def _directions(screens: list[Screen], scored: list[Hypothesis]) -> dict:
    """The sensitivity directions of the screened effects and of the hypotheses that carry one (the speed scale,
    which shares a radius error's slip signature: the confusable check compares them like two effects)."""
    dirs = {s.effect: s.direction for s in screens if s.direction is not None}
    dirs.update({h.name: h.direction for h in scored if h.direction is not None})
    return dirs


def _data_step(
    runner: FitRunner, cands: tuple[str, ...], say: Callable[[str], None]
) -> tuple[Any, list[Screen], Setup | None, tuple[Hypothesis, list, list] | None, HoldChoice | None]:
    """Screening, the setup and the nominal hypothesis; for a log whose torque hold was not given, the hold
    chosen on the held-out blocks (:mod:`.hold`) and, when it is the sampled one, all of it again with it."""
    data = runner.data
    kind = "drive" if runner.is_log else "sweep"
    library = cands + tuple(e for e, spec in EFFECTS.items() if kind in spec.shows_in and e not in cands)
    chosen: HoldChoice | None = None
    for attempt in range(2):
        say(f"screening: the nominal model on all {data.n_samples} samples, with the score tests")
        nominal_fit, screens, sens = screen(
            data,
            runner.vehicle,
            library,
            model=runner.model,
            hac_lag=None if runner.is_log else 0,
            fit_options=runner.options,
        )
        if data.n_samples < runner.settings.min_samples or not usable(nominal_fit, runner.is_log):
            return nominal_fit, screens, None, None, chosen
        setup = _setup(runner, nominal_fit, sens)
        say("the nominal model and the flexible term on the training blocks")
        base = nominal_hypothesis(setup)
        if not runner.is_log or attempt == 1:
            return nominal_fit, screens, setup, base, chosen
        if runner.hold_given is not None:
            return nominal_fit, screens, setup, base, HoldChoice(runner.hold_given, True)
        chosen = choose_hold(setup, base[0], base[2])
        if chosen.hold == "zoh":
            return nominal_fit, screens, setup, base, chosen
        say("the sampled torque predicts the held-out blocks better: everything refitted with it")
        runner.options["torque_hold"] = "sample"
        runner.x0 = None
    raise AssertionError("unreachable: the second pass returns")


def _score(setup: Setup, hyps: list[Hypothesis]) -> tuple[list[Hypothesis], Frame]:
    """Every hypothesis with its z on the evidence's frame (the nominal values fill what one leaves
    unpredicted). On a log the frame weighs the channels by the sensors' noise, as the fits do, with the share
    of it each sample's latent slip leaves as the expected value, and the noise level at most the nominal
    model's held-out error per channel (:meth:`Frame.at_most_nominal`)."""
    if not setup.is_log:
        frame = _frame(setup, hyps[0], held=False)
        z0 = frame.z(hyps[0].residuals)
        return [h.scored(frame, z0, hyps[0]) for h in hyps], frame
    frame = setup.frame(hyps[0].heldout(), sensor=True).at_most_nominal(hyps[0].residuals)
    # the share of the gap explained: on the same samples, standardised by the noise floor (calibrated on the
    # residuals themselves), at most the nominal model's held-out error per channel
    floor = Frame(setup.sigma, frame.mask).at_most_nominal(hyps[0].residuals)
    z0, g0 = frame.z(hyps[0].residuals), floor.z(hyps[0].residuals)
    return [h.scored(frame, z0, hyps[0]).with_gap(floor, g0) for h in hyps], frame


def _nominal_vs_noise(setup: Setup, nominal: Hypothesis, hold: Frame) -> float:
    """A log's gap test of the nominal held-out error against the noise floor (chi-square; a log's floor is
    measured on thousands of samples, and correlated residuals count less: the long-run variance factor)."""
    z = hold.z(nominal.heldout())
    infl = max(long_run_factor(nominal.heldout()[ch][m] / setup.sigma[ch][m]) for ch, m in hold.mask.items())
    return gap_p_value(float(z @ z), z.size, infl)


def _gap(
    setup: Setup, hyps: list[Hypothesis], weights: dict[str, float], hold: Frame, window_p: float | None
) -> GapDecision:
    """The gap tests (:mod:`.gap_test`) on the held-out residuals, a log's soil-window score test
    (``window_p``, None when not made) and a sweep's lack-of-fit tests."""
    s = setup.settings
    by = {h.name: h for h in hyps}
    z_nom = hold.z(by[NOMINAL].heldout())
    p: dict[str, float | None] = {}
    if setup.is_log:
        p["nominal error vs noise"] = _nominal_vs_noise(setup, by[NOMINAL], hold)
        p["soil differs within a time window"] = window_p
    p["flexible term beats nominal"] = dm_test(z_nom, hold.z(by["discrepancy"].heldout(), z_nom), setup.dm_lag)
    top = by[max(weights, key=lambda k: weights[k])]
    if top.family != "nominal" and top.held is not None:
        zt = hold.z(top.held, z_nom, top.scale)
        ok = bool(np.all(np.isfinite(zt)))
        shrink = 1.0 - float(np.sqrt((zt @ zt) / max(z_nom @ z_nom, 1e-300))) if ok else 0.0
        p["heaviest beats nominal"] = dm_test(z_nom, zt, setup.dm_lag) if shrink >= s.min_shrink else None
    if not setup.is_log:
        p["lack of fit"] = _lack_of_fit(setup, setup.residuals, setup.nominal_fit)
        p["pure-error lack of fit"] = _pure_error(setup)
    return decide_gap(p, s.alpha)


def _lack_of_fit(setup: Setup, residuals: dict[str, np.ndarray], res: Any) -> float:
    """A sweep's lack-of-fit F test: a flexible term in slip on top of fit ``res`` (residuals
    ``residuals``), its own parameters refitted with it (in-sample, like a sweep's evidence; free of the
    noise level, only its shape matters). The nominal screening fit holds the effects off: its soil
    columns only."""
    ch = setup.channels[0]
    r, sg = residuals[ch], setup.sigma[ch]
    ok = np.isfinite(r) & (np.nan_to_num(sg) > 0)
    knots = np.unique(np.quantile(setup.x[ok], np.linspace(0.0, 1.0, max(2, setup.n_knots))))
    J = fit_jacobian(res, setup.data)
    names = PARAMETER_NAMES + tuple(getattr(res, "effect_labels", ()) or ())
    if res is setup.nominal_fit:
        J, names = J[:, : len(PARAMETER_NAMES)], names[: len(PARAMETER_NAMES)]
    active = dict(getattr(res, "active_bounds", None) or {})
    held = [j for j, name in enumerate(names) if name in active]
    return lack_of_fit(r[ok], J[ok], hat_basis(setup.x, knots)[ok], sg[ok], held)


def _pure_error(setup: Setup) -> float | None:
    """A sweep's pure-error lack-of-fit test of the nominal model when rows repeat a slip level (rig trials are
    repeated; :func:`~..sweep.rig.pure_error_test`, the rig fit's own test), on the standardised residuals."""
    ch, data, nom = setup.channels[0], setup.data, setup.nominal_fit
    z = setup.residuals[ch] / setup.sigma[ch]
    ok = np.isfinite(z)
    n_par = int(np.sum([not getattr(pe, "fixed", False) for pe in (nom.parameters or {}).values()]))
    lof = pure_error_test(np.asarray(data.slip, dtype=float)[ok], z[ok], n_par)
    return None if lof is None else float(lof.p_value)


def _rmse(held: dict[str, np.ndarray], frame: Frame) -> dict[str, float]:
    return {
        ch: float(np.sqrt(np.mean(held[ch][m] ** 2))) if np.any(m) else float("nan") for ch, m in frame.mask.items()
    }


def _ranking(
    hyps: list[Hypothesis], weights: dict[str, float], raw: dict[str, float], hold: Frame
) -> tuple[RankEntry, ...]:
    """The ranking in the order of ``weights`` (shared among confusable effects; ties: the order of ``weights``,
    which puts the larger weight before sharing, ``raw``, first)."""
    nominal = hyps[0]
    z0 = hold.z(nominal.heldout())
    before = _rmse(nominal.heldout(), hold)
    out = []
    pos = {k: i for i, k in enumerate(weights)}
    for h in sorted(hyps, key=lambda h: (-weights[h.name], pos[h.name])):
        after, shrink = before, None
        if h.held is not None and h.family != "nominal":
            zh = hold.z(h.held, z0, h.scale)
            after = _rmse(
                {ch: np.where(np.isnan(h.heldout()[ch]), nominal.heldout()[ch], h.heldout()[ch]) for ch in h.heldout()},
                hold,
            )
            shrink = 1.0 - float(np.sqrt((zh @ zh) / max(z0 @ z0, 1e-300))) if np.all(np.isfinite(zh)) else None
        ex = h.explained(nominal) if h.family != "nominal" else None
        out.append(
            RankEntry(
                h.name,
                h.family,
                weights[h.name],
                h.n_params,
                before,
                after,
                shrink,
                None if ex is None or not np.isfinite(ex) else float(ex),
                h.parameters,
                h.detail,
                raw[h.name],
            )
        )
    return tuple(out)


def _verdict_fit(setup: Setup, dec: Decision, by: dict[str, Hypothesis]) -> Any:
    """The verdict's effect fitted on all the data (a sweep's is made already), or None."""
    if dec.verdict not in by or by[dec.verdict].family != "candidate":
        return None
    h = by[dec.verdict]
    if h.fit is not None:
        return h.fit
    return setup.runner.run(None, (dec.verdict,))


def diagnose(
    data: SlipData | DriveLog,
    vehicle: Vehicle,
    *,
    model: str = "full",
    candidates: Sequence[str] | None = None,
    weigh_outside: bool = True,
    torque_hold: str | None = None,
    bounds: SoilBounds | None = None,
    settings: DiagnoseSettings = DEFAULT_SETTINGS,
    progress: Callable[[str], None] | None = None,
) -> Diagnosis:
    """Diagnose the gap between the nominal model and a drive log or a slip sweep.

    Parameters
    ----------
    data
        A drive log or a tractive-force / drawbar-pull sweep (:func:`~soiltrack.soilmodel.read_csv`).
    vehicle
        The nominal vehicle.
    model
        ``"full"`` or ``"cohesion-free"``.
    candidates
        Effect names that may be named (default: every effect that shows in this kind of data).
    weigh_outside
        Also weigh the library effects left out of ``candidates`` (as hypotheses outside them).
    torque_hold
        Drive logs: ``"zoh"`` (held, a logged command) or ``"sample"`` (a sampled transducer signal);
        None or ``"auto"``: the one of the two with which the nominal model predicts the held-out blocks
        better (held unless sampled is significantly better, :mod:`.hold`); the report says which.
    bounds
        Soil bounds of every fit (default: the practical range; a soil beyond it is an outside cause).
    settings
        Thresholds, levels and counts (:class:`~.settings.DiagnoseSettings`).
    progress
        Called with a short line at each step (the command line prints them on stderr).

    Returns
    -------
    Diagnosis

    Raises
    ------
    DataError
        Unknown candidate, wrong data type, bad ``torque_hold``.
    """
    t0 = time.perf_counter()
    runner = _runner(data, vehicle, model, torque_hold, bounds, settings)
    cands = check_candidates(candidates, runner.is_log)
    say = progress if progress is not None else (lambda msg: None)
    consistency = check_consistency(data, vehicle)
    if not consistency.passed:
        return _inconsistent(runner, cands, consistency, t0)
    nominal_fit, screens, setup_or_none, base, choice = _data_step(runner, cands, say)
    if setup_or_none is None or base is None:
        return _no_comparison(runner, cands, nominal_fit, screens, choice, t0)
    setup, hyps = _hypotheses(setup_or_none, base, screens, cands, weigh_outside, say)
    admissible = [h for h in hyps if h.admissible]
    scored, frame = _score(setup, admissible)
    block = max(1, setup.n // settings.log_blocks) if runner.is_log else 1
    evidence = (
        HeldOutEvidence(block, settings.n_bootstrap) if runner.is_log else PenalisedEvidence(settings.n_bootstrap)
    )
    raw = evidence.weights(scored)
    dirs = _directions(screens, scored)
    shared = share_confusable(scored, raw, dirs, settings, evidence.separation)
    weights = shared.weights
    hold = _frame(setup, scored[0], held=True)
    terrain = next((h for h in hyps if h.name == "terrain_change"), None)
    window_p = None if terrain is None else terrain.detail.get("score_p_value")
    gap = _gap(setup, scored, weights, hold, window_p)
    dec = decide(scored, weights, gap, settings, confusable=shared.confusable, separation=evidence.separation)
    say("the verdict's fit on all the data")
    return _result(
        setup,
        cands,
        screens,
        scored,
        [h for h in hyps if not h.admissible],
        (weights, raw),
        gap,
        dec,
        evidence.describes,
        hold,
        choice,
        t0,
    )


def _result(
    setup: Setup,
    cands: tuple[str, ...],
    screens: list[Screen],
    hyps: list[Hypothesis],
    excluded: list[Hypothesis],
    weights: tuple[dict[str, float], dict[str, float]],
    gap: GapDecision,
    dec: Decision,
    evidence: str,
    hold: Frame,
    choice: HoldChoice | None,
    t0: float,
) -> Diagnosis:
    by = {h.name: h for h in hyps}
    ranking = _ranking(hyps, *weights, hold)
    vfit = _verdict_fit(setup, dec, by)
    shown = dec.heaviest if dec.verdict == UNEXPLAINED else dec.verdict
    entry = next(e for e in ranking if e.effect == shown)
    notes = [f"{dec.verdict} also stands for {LOOKALIKES[dec.verdict]}"] if dec.verdict in LOOKALIKES else []
    turning = int(getattr(setup.data, "n_turning", 0) or 0)
    if turning:
        notes.append(
            f"{turning} of {setup.n} samples turning (two-track log): left out of the straight-line "
            "model, with the sample after each turn"
        )
    if setup.flat:
        notes.append(f"no measurable noise in {', '.join(sorted(setup.flat))}: its noise floor is set negligible")
    for ch, rows in setup.lone.items():
        notes.append(
            f"{ch}: {len(rows)} lone reading(s) left out of the evidence and the gap tests, rows "
            f"{', '.join(str(r) for r in rows[:10])}{' ...' if len(rows) > 10 else ''} "
            "(far off both neighbours: a glitch, or a one-sample transient that no hypothesis here models)"
        )
    params = dict(entry.parameters)
    if vfit is not None and usable(vfit, setup.is_log):
        params = effect_parameters(vfit, dec.verdict)
        ranking = tuple(replace(e, parameters=params) if e.effect == dec.verdict else e for e in ranking)
    conv = usable(setup.nominal_fit, setup.is_log) and (vfit is None or usable(vfit, setup.is_log))
    named = dec.verdict not in (NOMINAL, UNEXPLAINED)
    held_x = {ch: setup.x[m] for ch, m in hold.mask.items()}
    curves = {
        "held_x": held_x,
        "x_label": "time" if setup.is_log else "slip",
        "before": {ch: by[NOMINAL].heldout()[ch][m] for ch, m in hold.mask.items()},
        "after": None
        if dec.verdict == NOMINAL or by[shown].held is None
        else {ch: by[shown].heldout()[ch][m] for ch, m in hold.mask.items()},
    }
    return Diagnosis(
        data_kind="drive" if setup.is_log else "sweep",
        n_samples=setup.n,
        candidates=cands,
        verdict=dec.verdict,
        confidence=float(dec.confidence),
        reason=dec.reason,
        cause=dec.cause,
        cause_detail=dec.cause_detail,
        ranking=ranking,
        excluded=tuple(Excluded(h.name, h.family, h.why) for h in excluded),
        evidence=evidence,
        gap=gap,
        screens=tuple(screens),
        confusable=dec.confusable,
        localisation=tuple(localisation(setup)),
        noise={ch: float(np.sqrt(np.nanmean(s**2))) for ch, s in setup.sigma.items()},
        holdout_rmse_before=entry.holdout_rmse_before,
        holdout_rmse_after=None if dec.verdict == NOMINAL else entry.holdout_rmse_after,
        shrink=entry.shrink if dec.verdict != NOMINAL else None,
        explained=entry.explained if dec.verdict != NOMINAL else None,
        soil_before=soil_summary(setup.nominal_fit),
        soil_after=soil_summary(vfit) if named and vfit is not None else None,
        converged=bool(conv),
        torque_hold=choice,
        notes=tuple(notes),
        elapsed_s=time.perf_counter() - t0,
        curves=curves,
        sinkage=_sinkage(setup),
        lone_readings=dict(setup.lone),
    )


def _inconsistent(runner: FitRunner, cands: tuple[str, ...], report: ConsistencyReport, t0: float) -> Diagnosis:
    """Data that fail the cross-channel consistency checks (a mislabelled channel, a unit) are not diagnosed:
    no gap is read against a model of the wrong data (``unexplained``, confidence 0, not converged)."""
    fatal = [f for f in report.findings if f.severity == "fatal"]
    reason = (
        "the data fail the consistency checks (" + ", ".join(f.check for f in fatal) + "): a channel's label or "
        "unit does not match the vehicle; no gap is read against a model of the wrong data"
    )
    return Diagnosis(
        data_kind="drive" if runner.is_log else "sweep",
        n_samples=runner.data.n_samples,
        candidates=cands,
        verdict=UNEXPLAINED,
        confidence=0.0,
        reason=reason,
        cause="inconsistent_data",
        cause_detail={"checks": [f.check for f in fatal]},
        ranking=(),
        excluded=(),
        evidence="none",
        gap=GapDecision(()),
        screens=(),
        confusable=(),
        localisation=(),
        noise={},
        holdout_rmse_before={},
        holdout_rmse_after=None,
        shrink=None,
        explained=None,
        soil_before={},
        soil_after=None,
        converged=False,
        torque_hold=None,
        notes=(reason,) + tuple(f.message for f in fatal),
        elapsed_s=time.perf_counter() - t0,
    )


def _sinkage(setup: Setup) -> Any:
    """A sweep's measured sinkage against the slip (:func:`~..sweep.sinkage_channel.slip_sinkage_evidence`):
    the slip-sinkage signature, shown beside the comparison (None without a ``sinkage_m`` channel)."""
    data = setup.data
    if setup.is_log or getattr(data, "sinkage", None) is None:
        return None
    return slip_sinkage_evidence(data, setup.runner.vehicle)


def _no_comparison(
    runner: FitRunner,
    cands: tuple[str, ...],
    res: Any,
    screens: list[Screen],
    choice: HoldChoice | None,
    t0: float,
) -> Diagnosis:
    """Too few samples for a hold-out, or no nominal fit: nothing can be compared; say which."""
    n = runner.data.n_samples
    ok = usable(res, runner.is_log)
    if not ok:
        verdict, reason = (
            UNEXPLAINED,
            (
                f"the nominal model could not be fitted ({getattr(res, 'status', 'failed')}): "
                "without it there is no gap to explain"
            ),
        )
    else:
        verdict, reason = (
            NOMINAL,
            (
                f"{n} samples cannot show a gap: a hold-out needs at least "
                f"{runner.settings.min_samples}; 'none' here means no evidence either way"
            ),
        )
    rms: dict[str, float] = {}
    if ok:
        try:
            rms = {ch: float(np.sqrt(np.nanmean(v**2))) for ch, v in channels(res, runner.data).items()}
        except DataError:
            rms = {}
    return Diagnosis(
        data_kind="drive" if runner.is_log else "sweep",
        n_samples=n,
        candidates=cands,
        verdict=verdict,
        confidence=0.0,
        reason=reason,
        cause=None,
        cause_detail={},
        ranking=(),
        excluded=(),
        evidence="none",
        gap=GapDecision(()),
        screens=tuple(screens),
        confusable=(),
        localisation=(),
        noise={},
        holdout_rmse_before=rms,
        holdout_rmse_after=None,
        shrink=None,
        explained=None,
        soil_before=soil_summary(res),
        soil_after=None,
        converged=ok,
        torque_hold=choice,
        notes=(reason,),
        elapsed_s=time.perf_counter() - t0,
    )
