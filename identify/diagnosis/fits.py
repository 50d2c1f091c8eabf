"""The diagnosis' access to the fits: one runner, residual channels, the soil and effect summaries.

Every model evaluation of the diagnosis goes through :func:`~soiltrack.identify.fitting.fit` and
its results (no physics here). :class:`FitRunner` holds what every fit of one diagnosis shares
(the data, the vehicle, the model, the torque hold, the soil bounds and the warm start) in one
object, so that no state travels through closures.

Residual convention: measured - model, everywhere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...soilmodel.data import DriveLog, SlipData
from ...soilmodel.errors import DataError
from ...soilmodel.soil import PRACTICAL_BOUNDS
from ...soilmodel.vehicle import Vehicle
from ..drivelog.residuals import drive_log_residuals, evaluate_residuals
from ..drivelog.sensitivity import latent_slip_expectation
from ..estimates.records import solver_converged
from ..fitting import fit
from ..sweep.model import SweepResiduals
from .settings import DiagnoseSettings
from .sweep_parts import effect_start

__all__ = [
    "FitRunner",
    "channels",
    "soil_summary",
    "effect_parameters",
    "outside_practical",
    "finite",
    "SOIL_KEYS",
    "usable",
]

#: Soil parameter names of a fit -> the contract's soil keys.
SOIL_KEYS = {
    "cohesion": "cohesion_kpa",
    "friction_angle": "friction_angle_deg",
    "shear_modulus": "shear_modulus_m",
}


def finite(x: Any) -> float | None:
    """A finite float or None (JSON never carries NaN or inf)."""
    try:
        x = float(x)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def usable(res: Any, is_log: bool) -> bool:
    """A fit the diagnosis may use: successful, or (a sweep) converged and only flagged implausible.

    A converged sweep fit that fails the plausibility checks (large residuals, rows far off the
    curve) is what a missing effect does to the nominal model: its answer is used.
    """
    return res is not None and (bool(res.success) or (not is_log and solver_converged(res)))


@dataclass
class FitRunner:
    """The fits of one diagnosis: the data, the vehicle and the options every fit shares.

    Attributes
    ----------
    data, vehicle, model
        What is diagnosed, the nominal vehicle and the soil model (``"full"`` or ``"cohesion-free"``).
    options
        Keyword arguments of every fit (the soil bounds; a log's torque hold).
    settings
        The diagnosis settings (iteration limits).
    x0
        Warm start of a drive log's fits (the nominal full-data answer), None until known.
    hold_given
        A drive log's torque hold when the caller gave it (None: not given).
    """

    data: SlipData | DriveLog
    vehicle: Vehicle
    model: str
    options: dict
    settings: DiagnoseSettings
    x0: np.ndarray | None = field(default=None)
    hold_given: str | None = None

    @property
    def is_log(self) -> bool:
        """Whether the data are a drive log."""
        return isinstance(self.data, DriveLog)

    def run(
        self, idx: np.ndarray | None, effects: tuple[str, ...] = (), start: dict | None = None, **extra: Any
    ) -> Any:
        """Fit the nominal model (``effects=()``) or the model with ``effects`` on the samples ``idx``.

        ``idx`` None: all the data. ``start``: the effects' start values (``{effect: {param: value}}``).
        ``extra`` overrides the shared options (e.g. ``bounds``,
        ``torque_hold``, ``max_iter``). A drive log's fits use the hull channel and one start
        from the warm answer when known; a sweep's effect fit that stalls is retried once with
        :attr:`DiagnoseSettings.retry_max_iter` iterations.
        """
        d = self.data if idx is None else self.data.subset(np.asarray(idx))
        kw = dict(self.options)
        if effects:
            kw["effects"] = dict(start) if start is not None else list(effects)
        if self.is_log:
            kw["hull_channel"] = True
            if self.x0 is not None and "x0" not in extra:
                kw.update(x0=self.x0, multistart=False)
        elif effects:
            kw.update(slip_noise="off", intervals="linear")  # held-out errors are compared, not intervals
        kw.update(extra)
        res = fit(d, self.vehicle, model=self.model, **kw)
        if not self.is_log and effects and not usable(res, False) and "ipopt_options" not in extra:
            kw["ipopt_options"] = {"ipopt.max_iter": self.settings.retry_max_iter}
            res = fit(d, self.vehicle, model=self.model, **kw)
        return res

    def run_on(self, data: DriveLog, idx: np.ndarray) -> Any:
        """The nominal model fitted (warm, few iterations) on the samples ``idx`` of another version of the
        log (a channel corrected)."""
        kw = dict(self.options, hull_channel=True, max_iter=self.settings.warm_max_iter)
        if self.x0 is not None:
            kw.update(x0=self.x0, multistart=False)
        return fit(data.subset(np.asarray(idx)), self.vehicle, model=self.model, **kw)

    def run_warm(self, idx: np.ndarray | None, effects: tuple[str, ...] = (), **extra: Any) -> Any:
        """:meth:`run` warm-started with few iterations, then from the fit's own starts if that fails."""
        if self.x0 is None or not self.is_log:
            return self.run(idx, effects, **extra)
        res = self.run(idx, effects, max_iter=self.settings.warm_max_iter, **extra)
        if usable(res, True):
            return res
        return self.run(idx, effects, x0=None, **extra)

    def refit_from(self, start: Any, idx: np.ndarray | None, effects: tuple[str, ...], **extra: Any) -> Any:
        """Refit ``effects`` on ``idx`` from another fit's answer (soil and effect parameters); ``extra`` as in
        :meth:`run`."""
        st = effect_start(start)
        return self.run(
            idx,
            effects,
            start={e: dict(st.get(e, {})) or True for e in effects},
            x0=np.asarray(start.theta, dtype=float),
            **extra,
        )


def log_channels(
    res: Any, data: DriveLog
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict[str, np.ndarray]]:
    """A drive-log fit's residuals (measured - model), its own noise model's standard deviation and each
    residual's gain (its derivative with respect to the measured signal it is formed from), per channel at
    full length (NaN where the fit uses no sample). The noise model belongs to the fit: a mass error scales
    the hull balance's noise with the mass, a radius error the thrust's with the radius; the gain says how
    much of that is only the residual's scale (the same measured noise, seen through another factor).

    Raises
    ------
    DataError
        The fit predicts nothing (it did not succeed).
    """
    if not res.success:
        raise DataError("the fit did not succeed; it predicts nothing", file=data.source)
    out = drive_log_residuals(res, data, res.vehicle, model=res.model)
    return _full_length(out, "channels", data), _full_length(out, "sigma", data), _full_length(out, "gain", data)


def _full_length(out: dict, part: str, data: DriveLog) -> dict[str, np.ndarray]:
    """``out[part]`` (:func:`~..drivelog.residuals.drive_log_residuals`, per used sample) per channel over the
    log's samples, NaN where the fit uses none."""
    keep = np.asarray(out["keep"])
    idx = np.nonzero(keep)[0] if keep.dtype == bool else keep.astype(int)
    full = {}
    for k, v in out[part].items():
        a = np.full(data.n_samples, np.nan)
        a[idx] = np.asarray(v, dtype=float).ravel()
        full[k] = a
    return full


def log_noise(res: Any, data: DriveLog) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict[str, np.ndarray]]:
    """A drive-log fit's residuals (measured - model), its noise level per channel (its noise model: the
    sensors' noise carried into each channel) and the expected squared standardised residual of a right model
    (the share of that noise the sample's latent slip leaves,
    :func:`~..drivelog.sensitivity.latent_slip_expectation`), at full length (NaN where the fit uses no
    sample), from one evaluation of the fit on the log.

    Raises
    ------
    DataError
        The fit predicts nothing (it did not succeed).
    """
    if not res.success:
        raise DataError("the fit did not succeed; it predicts nothing", file=data.source)
    evaluated = evaluate_residuals(res, data, res.vehicle, None)
    out = evaluated[0]
    expected = latent_slip_expectation(res, data, res.vehicle, evaluated=evaluated)
    return _full_length(out, "channels", data), _full_length(out, "sigma", data), expected


def channels(res: Any, data: SlipData | DriveLog) -> dict[str, np.ndarray]:
    """Residuals (measured - model) per channel at full length: NaN where the fit uses no sample.

    Raises
    ------
    DataError
        The fit predicts nothing (it did not succeed).
    """
    m = data.n_samples
    if isinstance(data, DriveLog):
        return log_channels(res, data)[0]
    rm = getattr(res, "residual_model", None)
    items = (rm if isinstance(rm, SweepResiduals) else SweepResiduals()).residuals_on(
        res, data, accept_implausible=True
    )
    out = {}
    for k, v in items.items():
        v = np.asarray(v, dtype=float).ravel()
        if v.size < m:
            v = np.concatenate([np.full(m - v.size, np.nan), v])
        out[k] = v[-m:]
    return out


def effect_parameters(res: Any, name: str) -> dict:
    """``{param: {value, stderr, ci95, identifiable, at_bound}}`` of effect ``name`` in fit ``res``."""
    out: dict[str, dict] = {}
    for p, est in ((getattr(res, "effects", {}) or {}).get(name) or {}).items():
        d = est.to_dict() if hasattr(est, "to_dict") else dict(est) if isinstance(est, dict) else {"value": est}
        out[p] = {
            k: (finite(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else v)
            for k, v in d.items()
            if k in ("value", "stderr", "ci95", "identifiable", "at_bound")
        }
        if isinstance(out[p].get("ci95"), (list, tuple)):
            out[p]["ci95"] = [finite(v) for v in out[p]["ci95"]]
    return out


def outside_practical(res: Any) -> list[str]:
    """The soil keys of fit ``res`` whose identifiable, free value lies outside the practical range."""
    out = []
    params = getattr(res, "parameters", None) or {}
    for j, (name, key) in enumerate(SOIL_KEYS.items()):
        pe = params.get(name)
        if pe is None or not pe.identifiable or pe.fixed or pe.value is None:
            continue
        lo, hi = PRACTICAL_BOUNDS.lower[j], PRACTICAL_BOUNDS.upper[j]
        if not lo * (1 - 1e-6) <= float(pe.value) <= hi * (1 + 1e-6):
            out.append(key)
    return out


def soil_summary(res: Any) -> dict:
    """The soil of a fit: values (None where not identifiable), F_max, and flags about them."""
    out: dict[str, Any] = {}
    params = getattr(res, "parameters", None) or {}
    ident: dict[str, bool] = {}
    weak: list[str] = []
    for name, key in SOIL_KEYS.items():
        pe = params.get(name)
        if pe is None:
            out[key] = None
            continue
        out[key] = finite(pe.to_dict()["value"]) if pe.identifiable or pe.fixed else None
        ident[name] = bool(pe.identifiable)
        if pe.identifiable and not pe.fixed and getattr(pe, "weakly_identifiable", False):
            weak.append(key)
    out["max_thrust_N"] = None
    for cb in getattr(res, "combinations", None) or ():
        if cb.name.startswith("F_max@"):
            out["max_thrust_N"] = finite(cb.value) if cb.estimable else None
            if cb.estimable and cb.weakly_identifiable:
                weak.append("max_thrust_N")
            break
    out["identifiable"] = ident
    out["converged"] = bool(getattr(res, "success", False))
    active = dict(getattr(res, "active_bounds", None) or {})
    out["at_bound"] = {SOIL_KEYS[k]: side for k, side in active.items() if k in SOIL_KEYS}
    out["outside_practical_range"] = outside_practical(res)
    out["weakly_identifiable"] = weak
    return out
