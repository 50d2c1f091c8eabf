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
from .nlp import g_inverse, pad
from .prepare import SLIP_BOUNDS, PreparedLog
from .profiled import nominal_data

__all__ = ["profile_flatness", "PROFILE_MIN_RISE"]

#: Smallest rise of the profiled cost at F_max -+ 2 SE (4 expected) for the standard error to hold.
#: Below it the likelihood is more than twice as wide as the standard error says on that side.
PROFILE_MIN_RISE = 1.0
#: Golden-section steps on log K per profiled point (the K bracket shrinks by 0.618 per step).
_K_STEPS = 18


def profile_flatness(
    prep: PreparedLog, vehicle: Vehicle, Fmax: float, K: float, sF: float, s2: float, Kb: tuple[float, float]
) -> tuple[float, float]:
    """Rise of the profiled cost (K re-fitted, over ``s2``) at ``F_max - 2 sF`` and ``F_max + 2 sF``.

    ``inf`` for a side outside ``F_max > 0``. Each value is 4 where the quadratic picture holds.
    """
    n = prep.n_used
    size = -(-n // SLIP_CHUNK) * SLIP_CHUNK
    D = np.asfortranarray(padded_data(nominal_data(prep, vehicle), size))
    solver = SlipSolver(vehicle, effect_structure(None, vehicle), D)
    l = vehicle.track_length
    lo_s, hi_s = SLIP_BOUNDS[0] + 1e-3, SLIP_BOUNDS[1] - 1e-3
    s_meas = pad(np.clip(prep.slip_measured, lo_s, hi_s), size)

    def cost(F: float, k: float) -> float:
        y = np.clip(np.abs(prep.thrust) / F, 0.0, 0.98)
        s_inv = pad(np.clip(np.sign(prep.thrust) * g_inverse(y) * k / l, lo_s, hi_s), size)
        th = np.array([F, k])
        return 2.0 * float(np.sum(solver.costs(th, solver.best(th, [s_inv, s_meas]))))

    def profiled(F: float) -> float:
        a, b = math.log(max(Kb[0], K / 50.0)), math.log(min(Kb[1], K * 50.0))
        g = (math.sqrt(5.0) - 1.0) / 2.0
        x1, x2 = b - g * (b - a), a + g * (b - a)
        f1, f2 = cost(F, math.exp(x1)), cost(F, math.exp(x2))
        for _ in range(_K_STEPS):
            if f1 <= f2:
                b, x2, f2 = x2, x1, f1
                x1 = b - g * (b - a)
                f1 = cost(F, math.exp(x1))
            else:
                a, x1, f1 = x1, x2, f2
                x2 = a + g * (b - a)
                f2 = cost(F, math.exp(x2))
        return min(f1, f2)

    c0 = cost(Fmax, K)
    s2 = s2 if s2 > 0 else 1.0
    lower = (profiled(Fmax - 2.0 * sF) - c0) / s2 if Fmax - 2.0 * sF > 0 else math.inf
    upper = (profiled(Fmax + 2.0 * sF) - c0) / s2
    return float(lower), float(upper)
