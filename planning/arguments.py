"""Checks of the planning functions' numeric arguments: one home for the message of a bad number."""

from __future__ import annotations

import math

import numpy as np

from ..soilmodel import DataError

__all__ = ["check_number"]


def check_number(
    name: str, x: object, lo: float = -math.inf, hi: float = math.inf, lo_open: bool = False, hi_open: bool = False
) -> float:
    """``x`` as a float when it is a finite number inside ``[lo, hi]`` (open ends as given).

    Parameters
    ----------
    name
        The argument's name, for the message.
    x
        The value given.
    lo, hi, lo_open, hi_open
        The admissible interval and whether each end is excluded.

    Returns
    -------
    float

    Raises
    ------
    DataError
        Not a finite number, or outside the interval (the argument named).
    """
    if isinstance(x, bool) or not isinstance(x, (int, float, np.floating, np.integer)) or not math.isfinite(float(x)):
        raise DataError(f"argument {name} must be a finite number, got {x!r}")
    v = float(x)
    if (v < lo or (lo_open and v == lo)) or (v > hi or (hi_open and v == hi)):
        raise DataError(
            f"argument {name} = {v:g} is outside {'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
        )
    return v
