"""Forward prediction for design: what pull, thrust, torque and sinkage a wheel or track gives on a soil.

The physics is :mod:`soiltrack.soilmodel.prediction` (one CasADi Function per gear, composed of the
library's one home of each term). This module gathers the soil - a terrain preset, numbers, or
one or more fits (``soiltrack fit --json`` of a track sweep, a wheel sweep, a bevameter shear test
and/or plate test) - with its uncertainty, and propagates it to the outputs by the delta method:
``var y = g C g^T`` with ``g`` the exact gradient (CasADi AD) and ``C`` the fits' covariance
(block-diagonal across independent fits), 95 % bounds ``y +- 1.96 sd``. A prediction whose
gradient has a component along a direction the fitted data did not see (the fit's null space;
e.g. k_c / b + k_phi at another wheel width than the fitted one) has no bounds (null) and the
notes say why. The bounds are the prediction's from the soil's uncertainty: a measurement adds its
own noise and the model's error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..soilmodel import DataError, Soil, Vehicle, choose_scale, format_force
from ..soilmodel.jsonread import load_json_file
from ..soilmodel.prediction import (
    PREDICTION_OUTPUTS,
    PREDICTION_PARAMETERS,
    evaluate_prediction,
    track_prediction_function,
    wheel_prediction_function,
)
from ..soilmodel.rigid_wheel import RigidWheel

__all__ = ["SoilEstimate", "Prediction", "soil_estimate", "fits_estimate", "predict", "Z95", "NULL_TOL", "LOAD_RTOL"]

#: Normal quantile of the 95 % bounds.
Z95 = 1.959963984540054
#: |g . v| below this fraction of sum |g_k v_k| counts as orthogonal to a null direction v (estimable).
NULL_TOL = 1e-6
#: The wheel carries the load when the stresses at the solved sinkage give it within this fraction.
LOAD_RTOL = 1e-6
_NQ = len(PREDICTION_PARAMETERS)
# JSON edge key -> (parameter index, factor edge -> SI)
_EDGE = {
    "cohesion_kpa": (0, 1e3),
    "friction_angle_deg": (1, math.pi / 180.0),
    "shear_modulus_m": (2, 1.0),
    "bekker_kc": (3, 1e3),
    "bekker_kphi": (4, 1e3),
    "bekker_n": (5, 1.0),
    "slip_sinkage": (6, 1.0),
}
_LABEL = {
    "cohesion": "c",
    "friction_angle": "phi",
    "shear_modulus": "K",
    "bekker_kc": "k_c",
    "bekker_kphi": "k_phi",
    "bekker_n": "n",
    "slip_sinkage": "s",
}


@dataclass(frozen=True)
class SoilEstimate:
    """The soil's parameters (SI, :data:`PREDICTION_PARAMETERS` order) with what is known of them.

    Attributes
    ----------
    mean
        Values (NaN where not given).
    known
        Which entries are given.
    cov
        Covariance (SI), ``None`` without uncertainty (a preset or numbers).
    null_space
        Directions (SI) the fitted data do not see.
    sources
        Where the values came from, in words.
    notes
        What the reader should know (a fit not usable, a parameter on a bound).
    """

    mean: np.ndarray
    known: np.ndarray
    cov: np.ndarray | None = None
    null_space: tuple[np.ndarray, ...] = ()
    sources: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()


def soil_estimate(soil: Soil) -> SoilEstimate:
    """A preset or given soil (no uncertainty); Bekker known when the soil has them, s = 0."""
    vals = [soil.cohesion, soil.friction_angle, soil.shear_modulus, soil.k_c, soil.k_phi, soil.n, 0.0]
    mean = np.array([np.nan if v is None else float(v) for v in vals])
    return SoilEstimate(mean, np.isfinite(mean), None, (), (soil.name or "given soil",))


def _num(x: Any, src: str, key: str) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(float(x)):
        raise DataError(f"field '{key}' must be a finite number, got {x!r}", file=src, column=key)
    return float(x)


def _block(cov: Any, src: str) -> tuple[list[int], np.ndarray, list[np.ndarray]]:
    """The indices, matrix and SI null directions of a fit JSON's ``covariance`` block."""
    names = [str(n) for n in cov.get("parameters", [])]
    bad = [n for n in names if n not in PREDICTION_PARAMETERS]
    if bad:
        raise DataError(f"covariance.parameters names {bad[0]!r}, not a soil parameter", file=src, column="covariance")
    if cov.get("units", "SI") != "SI":
        raise DataError("covariance.units must be 'SI'", file=src, column="covariance.units")
    idx = [PREDICTION_PARAMETERS.index(n) for n in names]
    M = np.asarray(cov.get("matrix"), dtype=float)
    if M.shape != (len(idx), len(idx)) or not np.all(np.isfinite(M)):
        raise DataError(f"covariance.matrix must be a finite {len(idx)} x {len(idx)} matrix", file=src)
    nulls = []
    for v in cov.get("null_space") or []:
        full = np.zeros(_NQ)
        full[idx] = np.asarray(v, dtype=float)
        nulls.append(full)
    return idx, M, nulls


def _one_fit(path: str, gear: Vehicle | RigidWheel, load: float | None):
    """``(values {index: SI}, cov rows/matrix or None, null dirs, notes, label)`` of one fit JSON."""
    obj = load_json_file(path, "fit JSON")
    if not isinstance(obj, dict):
        raise DataError("fit JSON must be an object (what `soiltrack fit --json` prints)", file=path)
    if obj.get("success") is not True:
        raise DataError("the fit did not succeed: no soil to predict with", file=path, column="success")
    notes = []
    if obj.get("outcome") in ("poor_fit", "not_usable", "failed"):
        notes.append(f"{path}: the fit's outcome is {obj['outcome']!r} ({obj.get('outcome_reason') or 'see the fit'})")
    gear_json = obj.get("running_gear")  # ``{"kind": ...}`` (a bare string in files of earlier versions)
    gear_kind = gear_json.get("kind") if isinstance(gear_json, dict) else gear_json
    kind = obj.get("kind") or ("rigid_wheel" if gear_kind == "rigid_wheel" else "track")
    if kind == "track":
        return _track_fit(path, gear, load, notes)
    params = obj.get("parameters")
    if not isinstance(params, dict):
        raise DataError("missing field 'parameters'", file=path, column="parameters")
    vals = {}
    for key, (k, fac) in _EDGE.items():
        p = params.get(key)
        if not isinstance(p, dict):
            continue
        if kind != "rigid_wheel" and not p.get("identifiable"):
            continue  # a bevameter test that does not identify it: the parameter is not given
        vals[k] = _num(p.get("value"), path, f"parameters.{key}.value") * fac
        if p.get("at_bound"):
            notes.append(
                f"{path}: {key} is on a bound of the fit ({p.get('note') or 'the data want a value beyond it'})"
            )
    cov = obj.get("covariance")
    block = _block(cov, path) if isinstance(cov, dict) else None
    if block is None:
        notes.append(f"{path}: no covariance block in the fit JSON: its parameters are taken without uncertainty")
    return vals, block, notes, f"{kind.replace('_', ' ')} fit {path}"


def _track_fit(path: str, gear: Vehicle | RigidWheel, load: float | None, notes: list[str]):
    """A track fit's c, phi, K (the ridge mapped to the load) with their covariance (planning.uncertainty)."""
    if not isinstance(gear, Vehicle):
        raise DataError(
            "a track's fit identifies the soil under a track's uniform pressure; for a wheel give a wheel "
            "fit or bevameter fits (shear and plate)",
            file=path,
        )
    from .uncertainty import load_fit_json

    u = load_fit_json(path, gear)
    W = gear.weight if load is None else load
    mean = u.soils_at(u.mean, W)[0]
    J = u.jacobian_at(W)
    C = J @ u.cov @ J.T
    notes.append(f"{path}: {u.describe(W)}")
    return {0: float(mean[0]), 1: float(mean[1]), 2: float(mean[2])}, ([0, 1, 2], C, []), notes, f"track fit {path}"


def fits_estimate(paths: list[str], gear: Vehicle | RigidWheel, load: float | None = None) -> SoilEstimate:
    """The soil of one or more fit JSONs (independent: block-diagonal covariance); each parameter from one fit."""
    mean = np.full(_NQ, np.nan)
    cov = np.zeros((_NQ, _NQ))
    have_cov = np.zeros(_NQ, dtype=bool)
    nulls: list[np.ndarray] = []
    notes: list[str] = []
    sources = []
    owner: dict[int, str] = {}
    for path in paths:
        vals, block, n, label = _one_fit(path, gear, load)
        for k, v in vals.items():
            if k in owner and not (k == 6 and v == 0.0):
                raise DataError(
                    f"{PREDICTION_PARAMETERS[k]} is given by two fits ({owner[k]} and {path}): "
                    "give each parameter once",
                    file=path,
                )
            owner[k] = path
            mean[k] = v
        if block is not None:
            idx, M, nv = block
            cov[np.ix_(idx, idx)] = M
            have_cov[idx] = True
            nulls += nv
        notes += n
        sources.append(label)
    if np.isnan(mean[6]):
        mean[6] = 0.0
    known = np.isfinite(mean)
    cov_out = cov if have_cov[known & (np.arange(_NQ) < 6)].any() else None
    missing_cov = [PREDICTION_PARAMETERS[k] for k in range(6) if known[k] and not have_cov[k]]
    if cov_out is not None and missing_cov:
        notes.append(f"taken without uncertainty (no covariance in their fit): {', '.join(missing_cov)}")
    return SoilEstimate(mean, known, cov_out, tuple(nulls), tuple(sources), tuple(notes))


@dataclass(frozen=True)
class Prediction:
    """Predicted outputs against slip, with 95 % bounds (``None`` entries where there are none).

    Attributes
    ----------
    gear
        The running gear (a :class:`Vehicle` or :class:`RigidWheel`).
    slip, load
        Where it is predicted (slip; normal load, N).
    values
        ``{output: (n,) array}`` for :data:`PREDICTION_OUTPUTS` (NaN where the gear cannot carry the load).
    lower, upper
        The bounds per output, NaN where there are none.
    estimate
        The soil used.
    notes
        Plain-words statements (sources, what has no bounds and why).
    """

    gear: Any
    slip: np.ndarray
    load: float
    values: dict
    lower: dict
    upper: dict
    estimate: SoilEstimate
    notes: tuple[str, ...] = field(default=())

    def to_dict(self) -> dict:
        """The ``soiltrack predict --json`` object (never NaN: null instead)."""

        def lst(a):
            return [None if not math.isfinite(float(x)) else float(x) for x in a]

        keys = {"drawbar_pull": "drawbar_pull_N", "thrust": "thrust_N", "torque": "torque_Nm", "sinkage": "sinkage_m"}
        out: dict[str, Any] = {
            "running_gear": "rigid_wheel" if isinstance(self.gear, RigidWheel) else "track",
            "normal_load_N": float(self.load),
            "slip": [float(s) for s in self.slip],
        }
        for o, key in keys.items():
            out[key] = lst(self.values[o])
            lo, hi = lst(self.lower[o]), lst(self.upper[o])
            out[key + "_lo"] = lo if any(v is not None for v in lo) else None
            out[key + "_hi"] = hi if any(v is not None for v in hi) else None
        out["soil"] = {
            k: (None if not self.estimate.known[j] else float(self.estimate.mean[j] / _EDGE[k][1]))
            for k, (j, _) in _EDGE.items()
        }
        out["uncertainty"] = (
            None
            if self.estimate.cov is None
            else "delta method (exact gradient) over the fits' covariance, 95 % normal bounds"
        )
        out["sources"] = list(self.estimate.sources)
        out["notes"] = list(self.notes)
        return out

    def report(self) -> str:
        """A plain-text table: slip, pull, thrust, torque, sinkage (with their bounds)."""
        g = self.gear
        head = (
            f"rigid wheel r = {g.radius:g} m, b = {g.width:g} m, h = {g.grouser_height:g} m"
            if isinstance(g, RigidWheel)
            else f"tracked vehicle {g.name or ''} (l = {g.track_length:g} m, b = {g.track_width:g} m)"
        )
        lines = [f"{head}; normal load {format_force(self.load)}; soil from {', '.join(self.estimate.sources)}"]
        fs = choose_scale(np.concatenate([self.values["drawbar_pull"], self.values["thrust"]]), "N")
        ts = choose_scale(self.values["torque"], "N m")
        lines.append(
            f"{'slip':>6} {'drawbar pull ' + fs.unit:>28} {'thrust ' + fs.unit:>28} {'torque ' + ts.unit:>28} "
            f"{'sinkage mm':>24}"
        )

        def cell(o, k, scale=1.0, w=28):
            v, lo, hi = self.values[o][k], self.lower[o][k], self.upper[o][k]
            if not math.isfinite(v):
                return f"{'n/a':>{w}}"
            b = f" [{lo * scale:.4g}, {hi * scale:.4g}]" if math.isfinite(lo) else ""
            return f"{f'{v * scale:.4g}{b}':>{w}}"

        for k, s in enumerate(self.slip):
            lines.append(
                f"{s:>6.3f} {cell('drawbar_pull', k, fs.factor)} {cell('thrust', k, fs.factor)} "
                f"{cell('torque', k, ts.factor)} {cell('sinkage', k, 1e3, 24)}"
            )
        lines.append(
            "bounds: "
            + (
                "95 %, from the soil's uncertainty"
                if self.estimate.cov is not None
                else "none (the soil is given without uncertainty)"
            )
        )
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)


def _require(est: SoilEstimate, idx: range, what: str) -> None:
    missing = [PREDICTION_PARAMETERS[k] for k in idx if not est.known[k]]
    if missing:
        raise DataError(
            f"{what} needs {', '.join(_LABEL[m] for m in missing)}: give --soil C_KPA,PHI_DEG,K_M,KC,KPHI,N, a terrain "
            "with Bekker values, or a fit that identified them (a plate test for k_c, k_phi, n)"
        )


def predict(gear: Vehicle | RigidWheel, est: SoilEstimate, slips, load: float | None = None) -> Prediction:
    """Pull, thrust, torque and sinkage of ``gear`` on the soil ``est`` at each slip (see the module text).

    Raises
    ------
    DataError
        Slip outside [0, 1), a wheel without its load or without the soil's Bekker parameters.
    """
    slips = np.asarray(slips, dtype=float).ravel()
    lowest = -1.0 if isinstance(gear, RigidWheel) else 0.0
    if slips.size == 0 or not np.all(np.isfinite(slips)) or np.any((slips < lowest) | (slips >= 1)):
        raise DataError(
            "the slips must lie in [-1, 1) for a wheel (skid down to a locked wheel) and in [0, 1) for a track "
            "(its skid is not predicted)"
        )
    notes = list(est.notes)
    _require(est, range(3), "a prediction")
    q = np.where(est.known, est.mean, 0.0)
    if isinstance(gear, RigidWheel):
        if load is None or not (load > 0 and math.isfinite(load)):
            raise DataError("--load: a rigid wheel has no mass; give its normal load in N (> 0)")
        _require(est, range(3, 6), "a rigid wheel's sinkage")
        fn = wheel_prediction_function(gear.radius, gear.width, gear.grouser_height)
        y, G, wl = evaluate_prediction(fn, slips, load, q)
        ok = np.abs(wl - load) <= LOAD_RTOL * load
        if not ok.all():
            notes.append(
                f"the wheel cannot carry {load:g} N on this soil at {np.count_nonzero(~ok)} slips (it would sink past "
                "its axle): no values there"
            )
    else:
        W = gear.weight if load is None else float(load)
        if not (W > 0 and math.isfinite(W)):
            raise DataError("--load must be a normal load > 0 N")
        bekker = bool(est.known[3:6].all())
        fn = track_prediction_function("full", bekker)
        y, G, _ = evaluate_prediction(
            fn, slips, W, q, gear.track_length, gear.track_width, gear.sprocket_radius, gear.rolling_resistance
        )
        ok = np.ones(slips.size, dtype=bool)
        if not bekker:
            y[:, 3] = np.nan
            notes.append("no Bekker parameters: no compaction resistance in the drawbar pull and no sinkage")
        notes.append(
            "drawbar pull = thrust - rolling resistance mu_r W - Bekker compaction; torque = sprocket radius x thrust "
            "(both sprockets, steady speed); sinkage: static (no slip sinkage)"
        )
        load = W
    y[~ok] = np.nan
    lo, hi = np.full_like(y, np.nan), np.full_like(y, np.nan)
    if est.cov is not None:
        lo, hi = _bounds(y, G, est, ok, notes)
    values = {o: y[:, k] for k, o in enumerate(PREDICTION_OUTPUTS)}
    return Prediction(
        gear,
        slips,
        float(load),
        values,
        {o: lo[:, k] for k, o in enumerate(PREDICTION_OUTPUTS)},
        {o: hi[:, k] for k, o in enumerate(PREDICTION_OUTPUTS)},
        est,
        tuple(notes),
    )


def _bounds(y: np.ndarray, G: np.ndarray, est: SoilEstimate, ok: np.ndarray, notes: list[str]):
    """Delta-method 95 % bounds; NaN where not estimable (a null direction of the fit) or not carried."""
    C = est.cov
    assert C is not None  # called only with a covariance
    var = np.einsum("noi,ij,noj->no", G, C, G)
    sd = np.sqrt(np.maximum(var, 0.0))
    est_ok = np.ones(y.shape, dtype=bool)
    for v in est.null_space:
        dot = np.abs(G @ v)
        scale = np.abs(G) @ np.abs(v)
        est_ok &= dot <= NULL_TOL * np.maximum(scale, 1e-300)
    est_ok &= ok[:, None] & np.isfinite(y)
    bad = [PREDICTION_OUTPUTS[k] for k in range(y.shape[1]) if (~est_ok[:, k] & ok & np.isfinite(y[:, k])).any()]
    if bad:
        notes.append(
            f"no bounds for {', '.join(bad)}: the prediction depends on a combination of the parameters the "
            "fitted data did not see (a null direction of the fit, e.g. Bekker k_c / b + k_phi at another width)"
        )
    lo = np.where(est_ok, y - Z95 * sd, np.nan)
    hi = np.where(est_ok, y + Z95 * sd, np.nan)
    return lo, hi
