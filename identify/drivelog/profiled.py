"""The nominal output-error fit of a long drive log with the latent slips eliminated exactly.

:func:`~.nlp.solve_output_error` hands IPOPT one variable per sample (the latent slip) and an
expanded symbolic graph of the whole log: measured 73 kB of peak memory per (padded) sample and
about 3 ms per sample on the light vehicle (``python benchmarks/bench_scale.py``), so a one-hour
50 Hz log needs 13 GB. The problem separates: for fixed ``(F_max, K)`` every slip is the minimum of
its own sample's cost. This solver keeps only the two soil parameters as iterates and profiles the
slips out - per-sample safeguarded Newton steps in the compiled, chunk-mapped kernels of
:mod:`.joint` (:class:`~.joint.SlipSolver`; no graph grows with the log), projected
Levenberg-Marquardt on the profiled cost with its exact Hessian (:func:`~.lm_start.profiled_start`,
the Schur complement of each sample's ``(theta, i)`` Hessian). The per-sample cost is the nominal
two-channel one (speed and thrust, whitened as in :mod:`.nlp`): the joint residual of
:mod:`.joint` with no effect and the hull channel off, its data rows built from the preparation
so that every residual is the nominal fit's.

The minimum is the same as IPOPT's (the profiled cost and the full cost share their minimisers);
the status says which solver found it (``"Profiled_LM_Converged"``). Memory: a few arrays of the
log's length (about 1 kB per sample in all, measured), time linear in the log.
"""

from __future__ import annotations

import math
import time as _time
from typing import Any

import numpy as np

from ...soilmodel.effects import effect_structure
from ...soilmodel.vehicle import Vehicle
from .joint import DATA_ROWS, SLIP_CHUNK, padded_data
from .lm_start import profiled_start
from .nlp import g_inverse, pad
from .prepare import SLIP_BOUNDS, PreparedLog

__all__ = ["solve_output_error_profiled", "nominal_data", "PROFILED_MAX_ITER"]

#: Levenberg-Marquardt steps at most per start (the fits measured converge in 5-15).
PROFILED_MAX_ITER = 60
#: Relative decrease of the profiled cost taken as converged.
PROFILED_TOL = 1e-12


def nominal_data(prep: PreparedLog, vehicle: Vehicle) -> np.ndarray:
    """The rows of :data:`~.joint.DATA_ROWS` whose joint residual (no effect) is the nominal fit's.

    The torque row carries ``r T + I dw/dt`` (so the joint thrust ``(M - I dw/dt) / r`` is the
    preparation's, with either sprocket equation), the speed noise the whole ``sigma_s`` (its
    encoder part zero), the covariance ``rho sigma_s^2``; no hull channel.
    """
    n = prep.n_used
    r, inertia = vehicle.sprocket_radius, vehicle.sprocket_inertia
    rows = {
        "v": prep.vehicle_speed,
        "w": prep.sprocket_speed,
        "M": r * prep.thrust + inertia * prep.dw_dt,
        "dw_dt": prep.dw_dt,
        "a": np.zeros(n),
        "sigma_v": prep.sigma_speed,
        "sigma_w_slip": np.zeros(n),
        "sigma_T": prep.sigma_thrust,
        "cov_sT": prep.coupling * prep.sigma_speed**2,
        "inv_sigma_H": np.zeros(n),
    }
    return np.vstack([rows[k] for k in DATA_ROWS])


def solve_output_error_profiled(
    prep: PreparedLog,
    vehicle: Vehicle,
    F_ref: float,
    K_ref: float,
    Fb,
    Kb,
    starts,
    max_iter: int,
    tol: float,
    print_level: int,
) -> tuple[dict[str, Any], float, float, np.ndarray]:
    """The output-error fit by profiled Levenberg-Marquardt; the same returns as :func:`~.nlp.solve_output_error`.

    ``max_iter``, ``tol`` and ``print_level`` are IPOPT's settings and do not apply (the steps are
    :data:`PROFILED_MAX_ITER`); the next start is tried only if a fit ends on a bound or does not converge.
    """
    del max_iter, tol, print_level
    structure = effect_structure(None, vehicle)
    n = prep.n_used
    size = -(-n // SLIP_CHUNK) * SLIP_CHUNK
    # padded once with inert samples (at rest: zero residuals, slips pinned at 0) and stored column by column:
    # the slip kernels, the cost and the profiled sums then share this one array, with no copy per call
    D = np.asfortranarray(padded_data(nominal_data(prep, vehicle), size))
    l = vehicle.track_length
    lo_s, hi_s = SLIP_BOUNDS[0] + 1e-3, SLIP_BOUNDS[1] - 1e-3
    slip_meas = pad(np.clip(prep.slip_measured, lo_s, hi_s), size)
    lower, upper = np.array([Fb[0], Kb[0]]), np.array([Fb[1], Kb[1]])
    scale = np.array([F_ref, K_ref])
    best: dict[str, Any] | None = None
    total = 0.0
    for j, (F0, K0) in enumerate(starts):
        t0 = _time.perf_counter()
        y = np.clip(np.abs(prep.thrust) / F0, 0.0, 0.98)
        slip_inv = pad(np.clip(np.sign(prep.thrust) * g_inverse(y) * K0 / l, lo_s, hi_s), size)
        ps = profiled_start(
            vehicle,
            structure,
            D,
            np.array([F0, K0]),
            lower,
            upper,
            scale,
            [slip_inv, slip_meas],
            max_iter=PROFILED_MAX_ITER,
            tol=PROFILED_TOL,
        )
        total += _time.perf_counter() - t0
        ok = bool(ps.converged and np.all(np.isfinite(ps.theta)) and math.isfinite(ps.cost))
        cand: dict[str, Any] = {
            "theta": ps.theta,
            "slip": ps.slip,
            "f": float(ps.cost),
            "ok": ok,
            "status": "Profiled_LM_Converged" if ok else "Profiled_LM_Not_Converged",
            "iterations": int(ps.iterations),
            "starts_tried": j + 1,
        }
        if best is None or (cand["ok"], -cand["f"]) > (best["ok"], -best["f"]):
            best = cand
        best["starts_tried"] = j + 1
        Fm, K = best["theta"]
        on_bound = any(abs(val - b) <= 1e-6 * (hi - lo) for val, (lo, hi) in ((Fm, Fb), (K, Kb)) for b in (lo, hi))
        if best["ok"] and not on_bound:
            break
    if best is None:
        raise ValueError("solve_output_error_profiled: no start points given")
    best["time"] = total
    theta, slip = best.pop("theta"), best.pop("slip")[:n]
    best["x"] = np.concatenate([theta / scale, slip])
    return best, float(theta[0]), float(theta[1]), np.asarray(slip, dtype=float)
