"""Absurd command-line values refused before any work: a seed, a drawbar pull, a distance.

Each check raises :class:`~soiltrack.soilmodel.DataError` naming the argument, so that the
command exits 2 with one line instead of an answer built on a value no run can have (a
``--drawbar-N=-1e9`` was planned as "required -1e+06 kN, TRAVERSABLE", ``--distance 1e300``
ended "short by 0 kN", ``--seed -1`` raised a traceback).
"""

from __future__ import annotations

import sys

from .planning.route import MAX_ROUTE_LENGTH_M
from .soilmodel import DataError, Vehicle

__all__ = ["MAX_DRAWBAR_RATIO", "check_seed", "check_drawbar", "check_distance"]

#: Largest drawbar pull asked of a vehicle, as a multiple of its weight. A tracked vehicle's
#: tractive coefficient rarely exceeds 1 and never 10 (even the light vehicle's cohesive thrust
#: on a 69 kPa clay is about 23 times its weight at full slip, which is no drawbar to plan with).
MAX_DRAWBAR_RATIO = 10.0


def check_seed(seed: int | None, option: str = "--seed") -> int | None:
    """A random seed: a whole number >= 0 (numpy's generators refuse negative seeds)."""
    if seed is not None and seed < 0:
        raise DataError(f"argument {option} must be a whole number >= 0, got {seed}")
    return seed


def check_drawbar(drawbar_N: float | None, vehicle: Vehicle, option: str = "--drawbar-N") -> float | None:
    """A drawbar pull, N: at most ``MAX_DRAWBAR_RATIO`` x W; a negative one is a push of at most W (said)."""
    if drawbar_N is None:
        return None
    W = vehicle.weight
    if drawbar_N > MAX_DRAWBAR_RATIO * W:
        raise DataError(
            f"argument {option} = {drawbar_N:g} N is more than {MAX_DRAWBAR_RATIO:g} times the vehicle's "
            f"weight ({W:.6g} N): no tracked vehicle pulls that (a unit slip, kN for N?)"
        )
    if drawbar_N < 0:
        if -drawbar_N > W:
            raise DataError(
                f"argument {option} = {drawbar_N:g} N: a negative drawbar pull is a push on the vehicle, "
                f"and one larger than its weight ({W:.6g} N) is not a push it can be given"
            )
        print(
            f"note: {option} = {drawbar_N:g} N is negative: taken as a push of {-drawbar_N:g} N that helps the vehicle",
            file=sys.stderr,
        )
    return drawbar_N


def check_distance(distance_m: float | None, option: str = "--distance") -> float | None:
    """A distance, m: at most the longest route planned at once (:data:`MAX_ROUTE_LENGTH_M`)."""
    if distance_m is not None and distance_m > MAX_ROUTE_LENGTH_M:
        raise DataError(
            f"argument {option} = {distance_m:g} m is beyond any route planned at once (at most "
            f"{MAX_ROUTE_LENGTH_M:g} m)"
        )
    return distance_m
