"""One-dimensional minimum search: the golden-section bracket shared by the 1-D profiles.

One home for the golden-section step used where a scalar is profiled after a grid has chosen
its basin: the slip-noise variance ratio (:mod:`soiltrack.identify.sweep.slip_noise`) and the
grouser height of a wheel (:mod:`soiltrack.identify.wheel.grouser_hypothesis`). The caller's
function may return any value; ``key`` says what of it is minimised (the objective of a
``(objective, fit)`` pair), so that the evaluated points' results are kept, not recomputed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

__all__ = ["GOLDEN_RATIO", "GoldenBracket", "golden_section"]

#: The interior points' fraction of the bracket, ``(sqrt(5) - 1) / 2``.
GOLDEN_RATIO = (math.sqrt(5.0) - 1.0) / 2.0

V = TypeVar("V")


@dataclass(frozen=True)
class GoldenBracket(Generic[V]):
    """The final bracket ``[a, b]`` of a golden-section search and its two interior points.

    ``x1 < x2`` inside ``[a, b]``; ``f1``, ``f2`` are what the function returned there.
    """

    a: float
    b: float
    x1: float
    f1: V
    x2: float
    f2: V

    @property
    def midpoint(self) -> float:
        """``(a + b) / 2``: the minimiser's estimate."""
        return 0.5 * (self.a + self.b)


def golden_section(
    f: Callable[[float], V],
    a: float,
    b: float,
    *,
    tol: float | None = None,
    steps: int | None = None,
    key: Callable[[V], Any] | None = None,
) -> GoldenBracket[V]:
    """Golden-section search for a minimum of ``f`` on ``[a, b]``.

    Parameters
    ----------
    f : callable
        The function, one call per new point (two to start, one per step).
    a, b : float
        The bracket (a grid's neighbours of its best point).
    tol : float, optional
        Stop when the bracket is at most this wide.
    steps : int, optional
        Stop after this many steps. At least one of ``tol`` and ``steps`` must be given.
    key : callable, optional
        What of ``f``'s value is compared (default the value itself).

    Returns
    -------
    GoldenBracket
    """
    if tol is None and steps is None:
        raise ValueError("golden_section needs tol or steps")
    k = (lambda v: v) if key is None else key
    g = GOLDEN_RATIO
    x1, x2 = b - g * (b - a), a + g * (b - a)
    f1, f2 = f(x1), f(x2)
    n = 0
    while (steps is None or n < steps) and (tol is None or abs(b - a) > tol):
        if k(f1) < k(f2):
            b, x2, f2 = x2, x1, f1
            x1 = b - g * (b - a)
            f1 = f(x1)
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + g * (b - a)
            f2 = f(x2)
        n += 1
    return GoldenBracket(a, b, x1, f1, x2, f2)
