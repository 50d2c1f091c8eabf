"""Shared pieces of the ``soiltrack`` command: exit codes, vehicle and soil arguments.

Exit status: 0 success; 1 the solver failed (results are still printed, with the reason);
2 bad input (the message names the file, the column and the row; no traceback).
"""
from __future__ import annotations

import math
import os

from .soilmodel import TERRAINS, VEHICLES, DataError, Soil, Vehicle

EXIT_OK, EXIT_SOLVER, EXIT_INPUT = 0, 1, 2


def vehicle_arg(arg: str) -> Vehicle:
    """A preset name or a vehicle JSON path -> :class:`Vehicle` (DataError naming the file)."""
    if arg in VEHICLES:
        return VEHICLES[arg]
    if not os.path.exists(arg):
        raise DataError(f"no such vehicle file, and not a preset name (presets: {sorted(VEHICLES)})", file=arg)
    return Vehicle.from_json(arg)


def soil_arg(terrain: str | None, soil: str | None) -> Soil:
    """``--terrain NAME`` or ``--soil C_KPA,PHI_DEG,K_M`` -> :class:`Soil` (default LETE sand)."""
    if soil:
        parts = soil.split(",")
        if len(parts) != 3:
            raise DataError(f"--soil expects C_KPA,PHI_DEG,K_M (three numbers), got {soil!r}")
        try:
            c, phi, K = (float(p) for p in parts)
        except ValueError:
            raise DataError(f"--soil expects three numbers C_KPA,PHI_DEG,K_M, got {soil!r}") from None
        return Soil.from_kpa_deg(c, phi, K, name="command line")
    key = terrain or "lete_sand"
    if key not in TERRAINS:
        raise DataError(f"unknown terrain {key!r}; presets: {sorted(TERRAINS)}")
    return TERRAINS[key]


def floats_arg(text: str, what: str) -> list[float]:
    """Comma-separated finite numbers of the argument ``what`` (DataError otherwise)."""
    try:
        vals = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise DataError(f"{what} expects comma-separated numbers, got {text!r}") from None
    if not vals or not all(math.isfinite(v) for v in vals):
        raise DataError(f"{what} expects finite numbers, got {text!r}")
    return vals
