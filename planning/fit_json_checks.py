"""Checks of the numbers in a ``--fit`` file (what ``soiltrack fit --json`` printed) before planning.

:func:`~soiltrack.planning.uncertainty.load_fit_json` reads the file; :func:`check_fit_numbers`
refuses what no fit can have produced, naming the field: a soil parameter outside its physical
range (:data:`~soiltrack.soilmodel.physical.PHYSICAL_RANGES`; c = 1e300 kPa was silently capped
near 69 kPa and planned with), a negative or non-finite standard error, a non-positive normal
load or F_max, a covariance with a negative variance.
"""

from __future__ import annotations

import math
from typing import Any

from ..soilmodel import DataError
from ..soilmodel.physical import PHYSICAL_RANGES, check_physical

__all__ = ["check_fit_numbers"]


def _finite(x: Any, src: str, field: str) -> float | None:
    if x is None:
        return None
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(float(x)):
        raise DataError(f"field '{field}' must be a finite number, got {x!r}", file=src, column=field)
    return float(x)


def check_fit_numbers(obj: dict, src: str) -> None:
    """Refuse non-physical values in a fit JSON object (DataError naming the field)."""
    params = obj.get("parameters")
    if isinstance(params, dict):
        for key in PHYSICAL_RANGES:
            p = params.get(key)
            if not isinstance(p, dict):
                continue
            v = _finite(p.get("value"), src, f"parameters.{key}.value")
            if v is not None:
                check_physical(key, v, file=src, field=f"parameters.{key}.value")
            se = _finite(p.get("stderr"), src, f"parameters.{key}.stderr")
            if se is not None and se < 0:
                raise DataError(
                    f"a standard error cannot be negative, got {se:g}",
                    file=src,
                    column=f"parameters.{key}.stderr",
                )
    for k, c in enumerate(obj.get("combinations") or []):
        if not isinstance(c, dict):
            continue
        name = str(c.get("name", k))
        v = _finite(c.get("value"), src, f"combinations.{name}.value")
        if v is not None and v <= 0 and (name.startswith("F_max") or name == "K"):
            raise DataError(f"{name} must be > 0, got {v:g}", file=src, column=f"combinations.{name}.value")
        if name == "K" and v is not None:
            check_physical("shear_modulus_m", v, file=src, field="combinations.K.value")
        se = _finite(c.get("stderr"), src, f"combinations.{name}.stderr")
        if se is not None and se < 0:
            raise DataError(
                f"a standard error cannot be negative, got {se:g}",
                file=src,
                column=f"combinations.{name}.stderr",
            )
    loads = obj.get("normal_loads_N")
    if isinstance(loads, list):
        for k, w in enumerate(loads):
            v = _finite(w, src, f"normal_loads_N[{k}]")
            if v is not None and v <= 0:
                raise DataError(f"a normal load must be > 0 N, got {v:g}", file=src, column=f"normal_loads_N[{k}]")
    cov = obj.get("covariance")
    if isinstance(cov, dict) and isinstance(cov.get("matrix"), list):
        for k, row in enumerate(cov["matrix"]):
            if isinstance(row, list) and k < len(row):
                d = _finite(row[k], src, f"covariance.matrix[{k}][{k}]")
                if d is not None and d < 0:
                    raise DataError(
                        f"a variance cannot be negative, got {d:g}",
                        file=src,
                        column=f"covariance.matrix[{k}][{k}]",
                    )
