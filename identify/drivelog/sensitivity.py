"""Per-sample residuals and parameter sensitivities of a fitted drive-log model (public API).

A drive-log fit profiles out one latent slip per sample, and the Jacobian it hands to the result
object is a stand-in with the right ``J^T J`` only (:mod:`.joint_fit`). Score tests
(:mod:`..diagnosis.screening`) and the search for a change of terrain (:mod:`..diagnosis.log_parts`) need the real
per-sample thing: the whitened residuals ``e_k`` (three channels per used sample) and
``de_k/dtheta`` from the drive-log model's own CasADi derivative function
(:func:`~.joint.sensitivity_function`, the physics of :mod:`soiltrack.soilmodel`), at the
fitted parameters and the latent slips :func:`~.residuals.drive_log_residuals` solves,
with ``de_k/dtheta`` projected off ``de_k/di_k`` (the profiled sensitivity: at the per-sample
optimum ``e_k`` is orthogonal to ``de_k/di_k``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ...soilmodel.data import DriveLog
from ...soilmodel.vehicle import Vehicle
from .joint import CHANNELS, sample_outputs
from .prepare import SLIP_BOUNDS
from .residuals import evaluate_residuals

__all__ = ["DriveLogSensitivities", "drive_log_sensitivities", "latent_slip_expectation"]


#: Labels of the soil's columns, first in every :class:`DriveLogSensitivities`: the thrust limit and K.
SOIL_LABELS = ("F_max", "K")


@dataclass(frozen=True, eq=False)
class DriveLogSensitivities:
    """Whitened residuals and their profiled sensitivities, sample by sample.

    Attributes
    ----------
    residuals
        ``(n, c)`` whitened residuals of the ``n`` used samples, ``c`` channels (speed, thrust,
        hull; the hull row is zero when the fit did not use that channel). Dimensionless.
    jacobian
        ``(n, c, p)`` derivative of ``residuals`` with respect to the parameters ``labels``, with
        the latent slip profiled out.
    labels
        ``("F_max", "K", "effect.param", ...)``: ``F_max`` is the log's thrust limit (N), ``K``
        the shear modulus (m), then the effect parameters of ``effects`` (at the fit's values, or
        at their off values when the fit did not carry them).
    keep
        Boolean mask over the log's samples: which samples are used (rows of ``residuals``).
    time_s
        Time of the used samples, s.
    """

    residuals: np.ndarray
    jacobian: np.ndarray
    labels: tuple[str, ...]
    keep: np.ndarray
    time_s: np.ndarray

    @property
    def n_channels(self) -> int:
        """Residual channels per sample."""
        return int(self.residuals.shape[1])

    def stacked(self) -> tuple[np.ndarray, np.ndarray]:
        """``(J, r)`` stacked sample by sample: ``(c n, p)`` and ``(c n,)``."""
        n, c, p = self.jacobian.shape
        return self.jacobian.reshape(n * c, p), self.residuals.reshape(n * c)

    def soil(self) -> DriveLogSensitivities:
        """The same residuals with the soil's columns only (``F_max``, ``K``): what a fit without effects gives."""
        return replace(self, jacobian=self.jacobian[:, :, : len(SOIL_LABELS)], labels=SOIL_LABELS)


def drive_log_sensitivities(result: Any, log: DriveLog, vehicle: Vehicle, effects: Any = None) -> DriveLogSensitivities:
    """Per-sample whitened residuals and profiled sensitivities of a drive-log fit on ``log``.

    Parameters
    ----------
    result
        A converged drive-log :class:`~..estimates.result.FitResult` (or the parameter mapping
        :func:`~.residuals.drive_log_residuals` takes).
    log, vehicle
        The log to evaluate on (usually the one fitted) and the nominal vehicle.
    effects
        Effect names to switch on at their off values (default: those of the fit): a nominal fit
        then gives the candidates' sensitivity columns without carrying them in its NLP.

    Returns
    -------
    DriveLogSensitivities

    Raises
    ------
    DataError
        The fit did not succeed, or the log has too few usable samples.
    """
    out, ctx = evaluate_residuals(result, log, vehicle, effects)
    theta, structure, D = ctx["theta"], ctx["structure"], ctx["D"]
    n = D.shape[1]
    e, Jt, gi, _ = sample_outputs(vehicle, structure, "sensitivity", theta, out["slip"], D)
    c, p = e.shape[0], theta.size
    e = e.T  # (n, c)
    Jt = Jt.reshape(c, n, p).transpose(1, 0, 2)  # (n, c, p)
    gi = gi.T  # (n, c)
    gn = np.sum(gi**2, axis=1)
    ok = gn > 1e-300
    Jt[ok] -= gi[ok, :, None] * (np.einsum("kc,kcp->kp", gi[ok], Jt[ok]) / gn[ok, None])[:, None, :]
    e = np.where(np.isfinite(e), e, 0.0)
    Jt = np.where(np.isfinite(Jt), Jt, 0.0)
    keep = np.asarray(out["keep"])
    if keep.dtype != bool:
        mask = np.zeros(log.n_samples, dtype=bool)
        mask[keep.astype(int)] = True
        keep = mask
    return DriveLogSensitivities(e, Jt, SOIL_LABELS + tuple(ctx["labels"]), keep, np.asarray(out["time_s"], float))


def latent_slip_expectation(
    result: Any, log: DriveLog, vehicle: Vehicle, evaluated: tuple[dict, dict] | None = None
) -> dict[str, np.ndarray]:
    """Expected squared standardised residual per channel and sample of a drive-log fit, given the
    latent slip each sample solves for: ``1 - h_c`` with the leverage ``h_c = (g_c / sigma_c)^2 / |de/di|^2``.

    The latent slip of a sample is fitted to that sample's own readings, so it takes up part of their noise:
    one degree of freedom of the sample's channels. ``g_c`` is the derivative of channel ``c``'s residual
    (measured units) with respect to the slip, ``sigma_c`` the fit's noise level of that channel
    (:func:`~.residuals.drive_log_residuals`), ``de/di`` that of the whitened residual vector the slip is
    solved on (all by AD from the model's own functions). To first order, ``r_c / sigma_c`` then has
    variance ``1 - h_c`` (the channels' leverages sum to one: the sample keeps ``channels - 1`` degrees of
    freedom); a slip on its bound takes up nothing (1). Returns ``{channel: array}`` over the log's
    samples (NaN where the fit uses none). ``evaluated``: what
    :func:`~.residuals.evaluate_residuals` gave for ``result`` on ``log`` (its fit's effects), when the
    caller has it already.
    """
    out, ctx = evaluate_residuals(result, log, vehicle, None) if evaluated is None else evaluated
    theta, structure, D = ctx["theta"], ctx["structure"], ctx["D"]
    slip = np.asarray(out["slip"], dtype=float)
    _, _, gi, graw = sample_outputs(vehicle, structure, "sensitivity", theta, slip, D)
    gn = np.sum(gi**2, axis=0)
    lo, hi = SLIP_BOUNDS
    free = (gn > 1e-300) & (slip > lo + 1e-9) & (slip < hi - 1e-9)
    expect = {}
    for j, ch in enumerate(CHANNELS):
        a2 = (graw[j] / np.asarray(out["sigma"][ch], dtype=float)) ** 2
        h = np.where(free, a2 / np.where(free, gn, 1.0), 0.0)
        expect[ch] = np.full(log.n_samples, np.nan)
        expect[ch][_used(out["keep"])] = np.clip(np.where(np.isfinite(h), 1.0 - h, 1.0), 0.0, 1.0)
    return expect


def _used(keep: Any) -> np.ndarray:
    """The used samples' indices from a ``keep`` (a mask or indices)."""
    keep = np.asarray(keep)
    return np.nonzero(keep)[0] if keep.dtype == bool else keep.astype(int)
