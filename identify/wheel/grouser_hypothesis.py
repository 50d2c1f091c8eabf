"""The ``grousers`` hypothesis of the wheel diagnosis: Bekker's grouser term with the height fitted.

Extra thrust that the nominal wheel (its JSON's grouser height held) cannot carry may come from
grousers: Bekker's side shear between the grousers multiplies c by ``1 + 2h/b`` and tan(phi) by
``1 + 0.64 (h/b) arccot(h/b)`` (:mod:`soiltrack.soilmodel.grousers`), with the shear radius r + h.
The hypothesis fits the height h in ``[0, r/2]`` (a profile: the wheel fit at each h, warm started
from the nominal, a grid then a golden-section refinement) with everything else as the nominal.

Because the factors multiply c and tan(phi), h is confounded with them when both are fitted on one
sweep: the hypothesis is weighed only when phi, or c above 0, is held (a shear test, a terrain). Its
held-out error holds h at its all-rows value in each left-out fold (one parameter's optimism: said in
the diagnosis notes).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any, Callable

import numpy as np

from ...soilmodel.rigid_wheel import RigidWheel
from ...soilmodel.search import golden_section
from ...soilmodel.wheel_sweep import WheelSweep
from .fitting import WheelFitOptions, fit_wheel
from .result import WheelFitResult, grousers_separable

__all__ = ["GROUSER_HYPOTHESIS", "grouser_height_bounds", "grouser_hypothesis", "grousers_weighable"]

#: The hypothesis' name in the diagnosis' ranking.
GROUSER_HYPOTHESIS = "grousers"
#: Grid of the profile over h, as fractions of the radius (then refined between neighbours).
GROUSER_GRID = (0.0, 1 / 128, 1 / 64, 1 / 32, 1 / 16, 1 / 8, 1 / 4, 1 / 2)
#: Golden-section steps of the refinement (the bracket shrinks by 0.618 per step).
GOLDEN_STEPS = 14


def grouser_height_bounds(wheel: RigidWheel) -> tuple[float, float]:
    """The fitted height's bounds: 0 (a smooth wheel) to half the radius (a paddle, beyond Bekker's form)."""
    return 0.0, wheel.radius / 2


def grousers_weighable(options: WheelFitOptions) -> bool:
    """Whether h can be told from the soil: phi held, or c held above 0 (Bekker's factors multiply c and tan(phi)).

    c held at 0 (``--model cohesion-free``) does not count: the factor on c then multiplies nothing.
    """
    return grousers_separable(dict(options.fixed))


def _profile(fit_at: Callable[[float], tuple[float, WheelFitResult]], hi: float) -> tuple[float, float, WheelFitResult]:
    """Minimise the objective over h in [0, hi]: the grid, then golden section between the best's neighbours."""
    grid = [g * 2 * hi for g in GROUSER_GRID]
    vals = [fit_at(h) for h in grid]
    k = int(np.argmin([v[0] for v in vals]))
    best = (grid[k], *vals[k])
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    br = golden_section(fit_at, a, b, steps=GOLDEN_STEPS, key=lambda v: v[0])
    for x, f in ((br.x1, br.f1), (br.x2, br.f2)):
        if f[0] < best[1]:
            best = (x, *f)
    return best


def grouser_hypothesis(
    data: WheelSweep,
    wheel: RigidWheel,
    options: WheelFitOptions,
    nominal: WheelFitResult,
    objective: Callable[[WheelFitResult, WheelSweep], float],
) -> dict[str, Any]:
    """Fit the grouser height (profile) and return the diagnosis' hypothesis row.

    Returns a dict with ``effect``, ``fit`` (the wheel fit at the best h), ``height`` (m), ``wheel``
    (the wheel with that height), ``admissible`` and ``bound_side`` (h on 0 or r/2: inadmissible,
    the track's rule), ``k`` (the nominal's free parameters + 1).
    """
    opts = replace(options, effects=(), start=tuple(nominal.theta))
    lo, hi = grouser_height_bounds(wheel)

    def fit_at(h: float) -> tuple[float, WheelFitResult]:
        r = fit_wheel(data, replace(wheel, grouser_height=h), opts)
        return (objective(r, data) if r.success else math.inf), r

    h, _, fit = _profile(fit_at, hi)
    tol = 1e-3 * (hi - lo)
    side = "lower" if h <= lo + tol else "upper" if h >= hi - tol else None
    return {
        "effect": GROUSER_HYPOTHESIS,
        "fit": fit,
        "height": float(h),
        "wheel": replace(wheel, grouser_height=float(h)),
        "options": opts,
        "admissible": side is None,
        "bound_side": side,
        "bound_value": lo if side == "lower" else hi,
        "k": sum(not e.fixed for e in nominal.parameters.values()) + 1,
    }
