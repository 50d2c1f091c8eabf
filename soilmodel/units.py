"""Units by magnitude for reports and figures: one home for choosing N or kN, W or kW, ...

A light vehicle's thrust is tens of newtons and a heavy one's hundreds of kilonewtons; a report
written in one fixed unit shows ``0.06687 kN`` for the first. The functions here choose the SI
prefix from the magnitude (the largest value, for several numbers shown together), so that the
mantissa is at least 1 and below 1000; values below 1 of the base unit stay in the base unit
(``0.5 N m``, never ``500 mN m``: engineers read forces and torques in N and kN).

:func:`choose_scale` gives a :class:`Scale` for a set of numbers (a table, a sum and its items,
an axis); :func:`format_force`, :func:`format_torque`, :func:`format_power` and
:func:`format_energy` format one number. For a figure, plot ``values * scale.factor`` and label
the axis with ``scale.unit``::

    s = choose_scale(thrust_N, "N")
    ax.plot(slip, thrust_N * s.factor)
    ax.set_ylabel(f"thrust ({s.unit})")
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass
from functools import lru_cache
from typing import Iterable

import numpy as np

__all__ = [
    "Scale",
    "choose_scale",
    "format_value",
    "format_force",
    "format_torque",
    "format_power",
    "format_energy",
    "PREFIXES",
    "SIGNIFICANT_DIGITS",
]

#: SI prefixes used, with their powers of ten (the base unit below 1000).
PREFIXES = (("", 0), ("k", 3), ("M", 6), ("G", 9))
#: Significant digits of a formatted number.
SIGNIFICANT_DIGITS = 4


@dataclass(frozen=True)
class Scale:
    """A unit chosen for a set of numbers.

    Attributes
    ----------
    factor
        Multiply a value in the base unit by this to get it in :attr:`unit` (``1e-3`` for kN).
    unit
        The unit with its prefix (``"kN"``, ``"kN m"``, ``"W"``).
    """

    factor: float
    unit: str

    def format(self, value: float | None, digits: int = SIGNIFICANT_DIGITS) -> str:
        """``value`` (base unit) written in this unit, e.g. ``"66.87 N"``; ``"n/a"`` for ``None``/NaN."""
        if value is None or not math.isfinite(float(value)):
            return "n/a"
        x = float(value) * self.factor
        return f"{x:.{digits}g} {self.unit}"


def choose_scale(values: float | Iterable[float] | np.ndarray, unit: str) -> Scale:
    """The prefix of ``unit`` for numbers of this magnitude (set by the largest finite ``|value|``).

    Parameters
    ----------
    values
        One number or several, in the base unit (N, N m, W, J, ...); non-finite ones are ignored.
    unit
        The base unit. A prefix goes in front of its first symbol (``"N m"`` -> ``"kN m"``).

    Returns
    -------
    Scale
    """
    if isinstance(values, (float, int)):  # one number (the common case): no array
        peak = abs(float(values)) if math.isfinite(values) else 0.0
    else:
        a = np.abs(np.asarray(values, dtype=float).ravel())
        a = a[np.isfinite(a)]
        peak = float(a.max()) if a.size else 0.0
    return _scale(_prefix_index(peak), unit)


def _prefix_index(peak: float) -> int:
    """Index in :data:`PREFIXES` of the prefix for a largest ``|value|`` of ``peak`` (finite, >= 0): the last
    switch point at or below it (the switch points increase)."""
    return max(bisect_right(_SWITCH, peak) - 1, 0)


#: 999.95 kN would print as "1000 kN": each prefix is taken from the rounding point of the digits shown
_SWITCH = tuple(10.0**e * (1 - 0.5 * 10.0**-SIGNIFICANT_DIGITS) for _, e in PREFIXES)


@lru_cache(maxsize=256)
def _scale(k: int, unit: str) -> Scale:
    """The :class:`Scale` of prefix ``PREFIXES[k]`` for ``unit`` (immutable: one per prefix and unit)."""
    prefix, power = PREFIXES[k]
    return Scale(10.0**-power, prefix + unit)


def format_value(value: float | None, unit: str, digits: int = SIGNIFICANT_DIGITS) -> str:
    """One number in ``unit`` (base unit) with the prefix of its magnitude."""
    if value is None:
        return "n/a"
    x = float(value)
    if not math.isfinite(x):
        return "n/a"
    return _scale(_prefix_index(abs(x)), unit).format(x, digits)  # choose_scale(value, unit) of one number


def format_force(value_N: float | None) -> str:
    """A force in N or kN or MN (``66.87 N``, ``289.8 kN``)."""
    return format_value(value_N, "N")


def format_torque(value_Nm: float | None) -> str:
    """A torque in N m or kN m (``16.97 N m``, ``80 kN m``)."""
    return format_value(value_Nm, "N m")


def format_power(value_W: float | None) -> str:
    """A power in W, kW or MW."""
    return format_value(value_W, "W")


def format_energy(value_J: float | None) -> str:
    """An energy in J, kJ or MJ."""
    return format_value(value_J, "J")
