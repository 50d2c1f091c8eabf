"""The data step: candidates, folds, the nominal fit's residuals and the noise floor.

:class:`Setup` is what every later step of the diagnosis reads: the fit runner, the nominal fit
on all the data and its residuals (measured - model), the hold-out folds, the natural variable
(time for a log, slip for a sweep) and the noise floor per channel and sample
(:func:`~.gap.noise_profile` of the residuals in that order).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ...soilmodel.data import DriveLog
from ...soilmodel.effects import EFFECTS
from ...soilmodel.errors import DataError
from .fits import FitRunner
from .gap import blocked_folds, isolated_outliers, noise_profile
from .hypotheses import Frame
from .screening import newey_west_lag
from .settings import DiagnoseSettings
from .sweep_parts import sweep_folds

__all__ = ["lone_readings", "Setup", "check_candidates", "noise_floors", "make_folds", "sweep_noise_model"]

#: Slip step of the central difference of a sweep model's slope dF/di (the slip is a fraction).
SLOPE_STEP = 1e-5


def check_candidates(candidates: Any, is_log: bool) -> tuple[str, ...]:
    """The candidate effects: the given names checked, or every effect that shows in this kind of data.

    Raises
    ------
    DataError
        An unknown effect name.
    """
    kind = "drive" if is_log else "sweep"
    if candidates is None:
        return tuple(n for n, e in EFFECTS.items() if kind in e.shows_in)
    if isinstance(candidates, str):
        candidates = [c for c in candidates.split(",") if c.strip()]
    out: list[str] = []
    for c in candidates:
        c = str(c).strip()
        if c not in EFFECTS:
            raise DataError(f"unknown candidate effect {c!r}; valid: {', '.join(EFFECTS)}")
        if c not in out:
            out.append(c)
    return tuple(out)


def noise_floors(
    resid: dict[str, np.ndarray], order: np.ndarray, window: int | None = None
) -> tuple[dict[str, np.ndarray], set[str]]:
    """The noise floor per sample of each channel's residuals along ``order`` (moving ``window`` of
    neighbours; None: :func:`~.gap.noise_profile`'s default).

    Returns the floors (NaN where a residual is not finite) and the channels without measurable
    noise (a noise-free simulated run), whose floor is set to a negligible value instead of zero.
    """
    floors, flat = {}, set()
    for ch, rr in resid.items():
        ok = np.isfinite(rr)
        o = order[ok[order]]
        prof = noise_profile(rr[o], window=window)
        if not np.all(prof > 0):
            scale = float(np.max(np.abs(rr[ok]))) if np.any(ok) else 0.0
            prof = np.full(o.size, max(1e-12, 1e-9 * scale))
            flat.add(ch)
        sg = np.full(rr.size, np.nan)
        sg[o] = prof
        floors[ch] = sg
    return floors, flat


def sweep_noise_model(res: Any, data: Any) -> np.ndarray | None:
    """A sweep's noise level per row from its nominal fit's own noise model, when that fit adopted noise on the
    measured slip (:mod:`~..sweep.slip_noise`): ``sqrt(s^2 + (sigma_i dF/di)^2)``, the slope ``dF/di`` by a
    central difference of the fit's own prediction. None when the fit took the slip as exact (the noise floor
    then comes from second differences of the residuals). The second differences cannot follow a noise that
    falls tenfold over the first rows of a sweep, as slip noise on the steep start of the curve does."""
    sn = (getattr(res, "extra", None) or {}).get("slip_noise") or {}
    s, si = sn.get("force_sigma_N"), sn.get("slip_sigma")
    if not sn.get("adopted") or s is None or si is None or getattr(data, "force_std", None) is not None:
        return None
    slip = np.asarray(data.slip, dtype=float)
    try:
        up, dn = (res.predict(replace(data, slip=slip + d)) for d in (SLOPE_STEP, -SLOPE_STEP))
    except DataError:
        return None
    slope = (np.asarray(up, dtype=float) - np.asarray(dn, dtype=float)) / (2 * SLOPE_STEP)
    out = np.sqrt(float(s) ** 2 + (float(si) * slope) ** 2)
    return out if np.all(np.isfinite(out)) and np.all(out > 0) else None


def make_folds(data: Any, order: np.ndarray, s: DiagnoseSettings) -> list[tuple[np.ndarray, np.ndarray]]:
    """A log: one fold (fit on the even blocks in time, predict the odd ones); a sweep: every block
    held out once over :attr:`~.settings.DiagnoseSettings.sweep_folds` folds (blocks in slip)."""
    n = data.n_samples
    if isinstance(data, DriveLog):
        return [(np.sort(order[a]), np.sort(order[b])) for a, b in blocked_folds(n, s.log_blocks)][:1]
    return sweep_folds(order, s.sweep_blocks, s.sweep_folds)


@dataclass(frozen=True, eq=False)
class Setup:
    """Everything the later steps read (see the module docstring).

    Attributes
    ----------
    runner
        The fits.
    nominal_fit
        The nominal model on all the data (the screening fit).
    residuals
        Its residuals per channel, full length.
    sigma
        Noise floor per channel and sample (the residuals' own noise level: the gap tests, the
        localisation, the report).
    flat
        Channels without measurable noise.
    folds
        ``(train, test)`` sample indices.
    x
        The natural variable per sample (time, s, or slip).
    order
        Sample indices in natural order.
    noise_from_fit
        A sweep's noise level comes from its fit's slip-noise model (:func:`sweep_noise_model`).
    lone
        Per channel, the rows whose residual is a lone reading (:func:`lone_readings`).
    sensor_sigma
        A log's: the sensors' noise per channel and sample as the nominal fit's noise model carries it into
        each channel (the fit weighs the channels by it; so does the evidence, :meth:`frame`); None: a sweep.
    expected
        A log's expected squared standardised residual per channel and sample of a right model, on
        :attr:`sensor_sigma` (the share of the noise its latent slip leaves,
        :attr:`.hypotheses.Frame.expected`); None: a sweep.
    sensitivities
        A log's: the nominal fit's per-sample whitened residuals and sensitivities from the screening
        (:class:`~..drivelog.sensitivity.DriveLogSensitivities`, the soil's columns first, then the library
        effects'), for the later score tests on the same fit; None: a sweep.
    """

    runner: FitRunner
    nominal_fit: Any
    residuals: dict[str, np.ndarray]
    sigma: dict[str, np.ndarray]
    flat: frozenset
    folds: list
    x: np.ndarray
    order: np.ndarray
    noise_from_fit: bool = False
    lone: dict = field(default_factory=dict)
    sensor_sigma: dict[str, np.ndarray] | None = None
    expected: dict[str, np.ndarray] | None = None
    sensitivities: Any = None

    def frame(self, residuals: dict[str, np.ndarray], sensor: bool = False) -> Frame:
        """The evidence's samples: where ``residuals`` (held-out ones, or all) and the noise floor are known,
        less the lone readings (:attr:`lone`: one glitch would otherwise make a gap on its own, and weigh the
        hypotheses by how they treat one wrong number). ``sensor`` (a log): standardised by the sensors'
        noise (:attr:`sensor_sigma`) with its expected share (:attr:`expected`), as the weights take them;
        else by the noise floor, as the gap tests do."""
        mask = {ch: np.isfinite(residuals[ch]) & (np.nan_to_num(self.sigma[ch]) > 0) for ch in self.channels}
        for ch, rows in self.lone.items():
            mask[ch][list(rows)] = False
        if not sensor or self.sensor_sigma is None:
            return Frame(self.sigma, mask)
        sg = self.sensor_sigma
        mask = {ch: m & (np.nan_to_num(sg[ch]) > 0) for ch, m in mask.items()}
        return Frame(sg, mask, self.expected)

    @property
    def data(self) -> Any:
        """The diagnosed data."""
        return self.runner.data

    @property
    def is_log(self) -> bool:
        """Whether the data are a drive log."""
        return self.runner.is_log

    @property
    def settings(self) -> DiagnoseSettings:
        """The settings."""
        return self.runner.settings

    @property
    def channels(self) -> list[str]:
        """The residual channels."""
        return list(self.residuals)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.data.n_samples)

    @property
    def n_knots(self) -> int:
        """Knots of the flexible term."""
        return self.settings.knots(self.n, self.is_log)

    @property
    def dm_lag(self) -> int:
        """Newey-West lag of the Diebold-Mariano tests (0 for a sweep's independent samples)."""
        return newey_west_lag(self.n) if self.is_log else 0

    @property
    def compared(self) -> dict[str, np.ndarray]:
        """Per channel, the samples the evidence compares: a log's held-out ones, all of a sweep's."""
        ok = {ch: np.isfinite(self.residuals[ch]) & (np.nan_to_num(self.sigma[ch]) > 0) for ch in self.channels}
        if not self.is_log:
            return ok
        held = np.zeros(self.n, dtype=bool)
        for _, te in self.folds:
            held[te] = True
        return {ch: m & held for ch, m in ok.items()}


def lone_readings(residuals: dict[str, np.ndarray], x: np.ndarray) -> dict[str, tuple[int, ...]]:
    """Per channel, the rows where a residual is a lone reading far off its neighbours (in the order of ``x``,
    time or slip; :func:`~.gap.isolated_outliers`): a glitch of a sensor or a logger, not a trend an effect
    could explain. Channels without one are left out."""
    out: dict[str, tuple[int, ...]] = {}
    for ch, res in residuals.items():
        r = np.asarray(res, dtype=float)
        ok = np.flatnonzero(np.isfinite(r))
        rows = tuple(sorted(int(ok[k]) for k, _ in isolated_outliers(r[ok], np.asarray(x)[ok])))
        if rows:
            out[ch] = rows
    return out
