"""The model hypotheses: the nominal model, the library's effects and the flexible discrepancy term.

Each is fitted the same way: on a drive log on the training blocks, predicting the held-out ones;
on a sweep on all the data (its in-sample residuals are the evidence) and on each fold's training
blocks (its held-out residuals give the shrink). The flexible term adds, to the nominal model's
prediction, a linear spline (hat functions on quantile knots) fitted to the nominal residuals: in
time for a log, in slip for a sweep. It is a two-stage fit standing for any smooth gap.

An effect is admissible when its fits converged and none of its parameters ended on a bound (an
effect stretched to its bound imitates something it is not).
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from ...soilmodel.effects import EFFECTS
from ...soilmodel.errors import DataError
from .fits import channels, effect_parameters, log_channels, usable
from .hypotheses import DISCREPANCY, NOMINAL, Hypothesis
from .selection import fit_discrepancy
from .setup import Setup

__all__ = ["nominal_hypothesis", "flexible_hypothesis", "flexible_on", "effect_hypothesis", "held_out"]


def held_out(
    setup: Setup,
    fit_on: Callable[[np.ndarray], Any],
    noise_out: dict[str, np.ndarray] | None = None,
    gain_out: dict[str, np.ndarray] | None = None,
) -> tuple[dict[str, np.ndarray], list, list]:
    """Held-out residuals of the model ``fit_on(train) -> fit`` over the folds.

    Returns the held-out residuals per channel (full length, NaN where not held out or not
    predicted), the training fits, and the training residuals per fold (full length). ``noise_out``
    (a log's), when given, is filled with each fit's own noise level at the samples it predicts, ``gain_out``
    with each residual's derivative with respect to its measured signal (:func:`~.fits.log_channels`).
    A log's fit is evaluated on the whole log and picked (each prediction uses the measured
    inputs at its own sample); a sweep's on the held-out rows.
    """
    n = setup.n
    held = {ch: np.full(n, np.nan) for ch in setup.channels}
    fits, train_res = [], []
    for tr, te in setup.folds:
        res = fit_on(tr)
        fits.append(res)
        tres = {ch: np.full(n, np.nan) for ch in setup.channels}
        try:
            if setup.is_log:
                full, sig, gain = log_channels(res, setup.data)
                for out, src in ((noise_out, sig), (gain_out, gain)):
                    if out is not None:
                        for ch in setup.channels:
                            out.setdefault(ch, np.full(n, np.nan))[te] = src[ch][te]
                pick_te = {ch: full[ch][te] for ch in setup.channels}
                pick_tr = {ch: full[ch][tr] for ch in setup.channels}
            else:
                pick_te = channels(res, setup.data.subset(te))
                pick_tr = channels(res, setup.data.subset(tr))
        except DataError:
            pick_te = {ch: np.full(te.size, np.inf) for ch in setup.channels}
            pick_tr = {ch: np.full(tr.size, np.nan) for ch in setup.channels}
        for ch in setup.channels:
            held[ch][te] = pick_te[ch]
            tres[ch][tr] = pick_tr[ch]
        train_res.append(tres)
    return held, fits, train_res


def nominal_hypothesis(setup: Setup) -> tuple[Hypothesis, list, list]:
    """The nominal model, its training fits and its training residuals per fold (for the flexible term,
    the delay and the change of terrain)."""
    noise: dict[str, np.ndarray] = {}
    gain: dict[str, np.ndarray] = {}
    held, fits, train_res = held_out(setup, lambda tr: setup.runner.run_warm(tr), noise, gain)
    ok = all(usable(f, setup.is_log) for f in fits)
    resid = held if setup.is_log else setup.residuals
    return (
        Hypothesis(
            NOMINAL,
            "nominal",
            0,
            resid,
            admissible=ok,
            why="" if ok else "a training fit failed",
            held=held,
            fit=setup.nominal_fit,
            noise=noise or None,
            gain=gain or None,
        ),
        fits,
        train_res,
    )


def _spline(setup: Setup, x_tr: np.ndarray, r_tr: np.ndarray, x_at: np.ndarray) -> np.ndarray:
    ok = np.isfinite(r_tr)
    if np.count_nonzero(ok) < 2:
        return np.zeros(x_at.size)
    return fit_discrepancy(x_tr[ok], r_tr[ok], x_at, setup.n_knots)[0]


def flexible_on(setup: Setup, held: dict[str, np.ndarray], train_res: list) -> dict[str, np.ndarray]:
    """Held-out residuals of a model with the flexible term on top: a spline in the natural variable fitted
    to its training residuals of each fold, subtracted from its held-out residuals."""
    x = setup.x
    out = {ch: np.array(held[ch], copy=True) for ch in setup.channels}
    for (tr, te), tres in zip(setup.folds, train_res):
        for ch in setup.channels:
            out[ch][te] = held[ch][te] - _spline(setup, x[tr], tres[ch][tr], x[te])
    return out


def flexible_hypothesis(setup: Setup, nominal: Hypothesis, train_res: list) -> Hypothesis:
    """The flexible discrepancy term on top of the nominal model (``n_knots`` parameters per channel)."""
    held = flexible_on(setup, nominal.heldout(), train_res)
    if setup.is_log:
        resid = held
    else:
        resid = {ch: r - _spline(setup, setup.x, r, setup.x) for ch, r in setup.residuals.items()}
    return Hypothesis(DISCREPANCY, "flexible", setup.n_knots * len(setup.channels), resid, held=held)


def _stretched(fits: list, name: str) -> list[str]:
    """Parameters of effect ``name`` on a bound in any of ``fits``."""
    return sorted(
        {
            p
            for f in fits
            if f is not None and getattr(f, "success", False)
            for p, d in effect_parameters(f, name).items()
            if d.get("at_bound")
        }
    )


def _wrong_sign(params: dict, name: str) -> list[str]:
    """Parameters of effect ``name`` whose fitted value has the opposite of their physical sign
    (:attr:`~soiltrack.soilmodel.effect_registry.ParamSpec.physical_sign`: a loss or a resistance that the data
    want negative is another effect imitating this one)."""
    spec = EFFECTS[name]
    out = []
    for p in spec.params:
        v = (params.get(p.name) or {}).get("value")
        if p.physical_sign and v is not None and float(v) * p.physical_sign < 0:
            out.append(f"{p.name} = {float(v):.3g}")
    return out


def simplest_form(name: str) -> dict[str, float]:
    """``{"effect.param": value}``: the secondary parameters of effect ``name`` held at their defaults (the
    off value, or the stated default), so that each effect enters the comparison in its simplest form, its
    primary parameter alone (a drivetrain loss as Coulomb friction). A secondary parameter would otherwise
    buy a hypothesis a little held-out accuracy from the model's form, not from the effect; the verdict's
    own fit frees them."""
    spec = EFFECTS[name]
    return {
        f"{name}.{p.name}": float(p.default if p.default is not None else p.off_value)
        for p in spec.params
        if p.name != spec.primary and not p.integer
    }


def effect_hypothesis(setup: Setup, name: str, family: str) -> Hypothesis:
    """Library effect ``name`` refitted with the soil (``family``: ``"candidate"`` or ``"outside"``), in its
    simplest form (:func:`simplest_form`)."""
    run = setup.runner
    eff = (name,)
    hold = simplest_form(name)
    extra = {"fixed": hold} if hold else {}
    full = None
    unpredicted = {ch: np.full(setup.n, np.inf) for ch in setup.channels}
    noise: dict[str, np.ndarray] = {}
    gain: dict[str, np.ndarray] = {}
    if setup.is_log:
        held, fits, train_res = held_out(setup, lambda tr: run.run_warm(tr, eff, **extra), noise, gain)
        resid = held
    else:
        full = run.run(None, eff, **extra)
        try:
            resid = channels(full, setup.data) if usable(full, False) else unpredicted
        except DataError:
            resid = unpredicted

        def fit_fold(tr: np.ndarray) -> Any:
            res = run.run(tr, eff, **extra)
            return res if usable(res, False) or not usable(full, False) else run.refit_from(full, tr, eff, **extra)

        held, fits, train_res = held_out(setup, fit_fold)
    ref = fits[0] if setup.is_log else full
    conv = all(usable(f, setup.is_log) for f in fits) and (full is None or usable(full, False))
    at = _stretched(fits + ([full] if full is not None else []), name)
    why = (
        ""
        if conv and not at
        else (
            "a fit did not converge"
            if not conv
            else f"{', '.join(at)} ended on {'its bound' if len(at) == 1 else 'their bounds'}"
        )
    )
    n_par = len(getattr(ref, "effect_labels", ()) or ()) - len(getattr(ref, "fixed_labels", ()) or ())
    params = effect_parameters(ref, name) if ref is not None and usable(ref, setup.is_log) else {}
    wrong = _wrong_sign(params, name) if not why else []
    if wrong:
        why = f"{', '.join(wrong)}: of the wrong physical sign"
    return Hypothesis(
        name,
        family,
        max(1, n_par),
        resid,
        admissible=not why,
        why=why,
        held=held,
        parameters=params,
        fit=full,
        train_residuals=train_res,
        noise=(noise or None) if setup.is_log else None,
        gain=(gain or None) if setup.is_log else None,
    )
