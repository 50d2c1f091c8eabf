"""Does the likelihood of F_max match its standard error? A two-point profile check.

The standard error of F_max is the curvature of the cost at its minimum. Where the thrust-slip
curve bends sharply near the estimate (a few large-thrust samples at low speed, whose slip the
speeds hardly measure, as in a start from rest), the cost can rise steeply on one side and stay
almost flat beyond: measured on a 20 s gentle start from rest (light vehicle, dry sand, seed 3)
F_max 93.5 N, SE 4.5 N, while the cost with K re-fitted rises by only 0.4 at +2 SE and by 4.1 at
the true 263.5 N. :func:`profile_flatness` evaluates the profiled cost (K re-fitted, the latent
slips profiled out as in :mod:`.profiled`) at ``F_max -+ 2 SE``; the quadratic picture predicts a
rise of 4 (in units of the reduced chi-square).
"""

from __future__ import annotations

import math

import numpy as np

from ...soilmodel.effects import effect_structure
from ...soilmodel.vehicle import Vehicle
from .joint import SLIP_CHUNK, SlipSolver, padded_data
from .lm_start import profiled_start
from .nlp import g_inverse, pad
from .prepare import SLIP_BOUNDS, PreparedLog
from .profiled import PROFILED_MAX_ITER, PROFILED_TOL, nominal_data

__all__ = ["profile_flatness", "PROFILE_MIN_RISE"]

#: Smallest rise of the profiled cost at F_max -+ 2 SE (4 expected) for the standard error to hold.
#: Below it the likelihood is more than twice as wide as the standard error says on that side.
PROFILE_MIN_RISE = 1.0


def profile_flatness(
    prep: PreparedLog, vehicle: Vehicle, Fmax: float, K: float, sF: float, s2: float, Kb: tuple[float, float]
) -> tuple[float, float]:
    """Rise of the profiled cost (K re-fitted, over ``s2``) at ``F_max - 2 sF`` and ``F_max + 2 sF``.

    ``inf`` for a side outside ``F_max > 0``. Each value is 4 where the quadratic picture holds.
    K is re-fitted at each F by the fit's own projected Levenberg-Marquardt with F held
    (:func:`~.lm_start.profiled_start`, exact profiled Hessian, a few warm-started slip solves;
    a golden-section search over log K took 40 cold solves: measured 16.5 s of a 21.6 s fit of
    30,000 rows before, see docs/drivelogs.md), started on the ridge of constant small-slip slope
    ``F l / (2K)``.
    """
    n = prep.n_used
    size = -(-n // SLIP_CHUNK) * SLIP_CHUNK
    D = np.asfortranarray(padded_data(nominal_data(prep, vehicle), size))
    structure = effect_structure(None, vehicle)
    solver = SlipSolver(vehicle, structure, D)
    l = vehicle.track_length
    lo_s, hi_s = SLIP_BOUNDS[0] + 1e-3, SLIP_BOUNDS[1] - 1e-3
    s_meas = pad(np.clip(prep.slip_measured, lo_s, hi_s), size)

    def s_inv(F: float, k: float) -> np.ndarray:
        y = np.clip(np.abs(prep.thrust) / F, 0.0, 0.98)
        return pad(np.clip(np.sign(prep.thrust) * g_inverse(y) * k / l, lo_s, hi_s), size)

    def profiled(F: float) -> float:
        k0 = min(max(K * F / Fmax, Kb[0]), Kb[1])
        ps = profiled_start(
            vehicle,
            structure,
            D,
            np.array([F, k0]),
            np.array([F, Kb[0]]),
            np.array([F, Kb[1]]),
            np.array([Fmax, K]),
            [s_inv(F, k0), s_meas],
            max_iter=PROFILED_MAX_ITER,
            tol=PROFILED_TOL,
        )
        # the per-sample costs summed as at the optimum below (the same additions)
        return 2.0 * float(np.sum(solver.costs(ps.theta, ps.slip)))

    th = np.array([Fmax, K])
    c0 = 2.0 * float(np.sum(solver.costs(th, solver.best(th, [s_inv(Fmax, K), s_meas]))))
    s2 = s2 if s2 > 0 else 1.0
    lower = (profiled(Fmax - 2.0 * sF) - c0) / s2 if Fmax - 2.0 * sF > 0 else math.inf
    upper = (profiled(Fmax + 2.0 * sF) - c0) / s2
    return float(lower), float(upper)
