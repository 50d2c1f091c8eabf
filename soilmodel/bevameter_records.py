"""Bevameter tests as bevameters record them: a shear annulus's torque against rotation, a plate's force.

CSV columns (SI; unit suffixes and ``--columns`` as for every reader, :mod:`.columns`):

shear annulus
    ``normal_load_N`` or ``normal_pressure_Pa``, ``rotation_rad`` or ``rotation_deg``,
    ``torque_Nm``, and the ring's ``inner_radius_m``, ``outer_radius_m`` (columns, or given to
    :func:`read_bevameter_record` / ``--inner-radius-m``, ``--outer-radius-m``). The normal
    pressure is the load over the ring's area ``pi (r_o^2 - r_i^2)``; the torque model integrates
    the shear law across the ring (:func:`~.bevameter.annulus_torque_expr`): no ring-mean
    approximation. Steady-state rows (large rotations) are rows like the others.
plates as recorded
    ``plate_radius_m`` (a circular plate) or ``plate_width_m`` with an optional ``plate_length_m``
    (a rectangular plate; b is the smaller side), with ``force_N`` or ``pressure_Pa``, and
    ``sinkage_m``. The force is divided by the plate's area; Bekker's b is the radius of a
    circular plate and the smaller side of a rectangular one. The result is a
    :class:`~.data.PlateTest`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from .columns import ColumnPlan, plan_columns
from .csvread import read_columns, read_header
from .data import KNOWN_COLUMNS, PlateTest, bad_rows_error
from .errors import DataError

__all__ = [
    "AnnulusTest",
    "ANNULUS_COLUMNS",
    "PLATE_RECORD_COLUMNS",
    "RECORD_COLUMNS",
    "is_bevameter_record",
    "read_bevameter_record",
]

#: Columns a shear annulus record may have.
ANNULUS_COLUMNS = (
    "normal_load_N",
    "normal_pressure_Pa",
    "rotation_rad",
    "rotation_deg",
    "torque_Nm",
    "inner_radius_m",
    "outer_radius_m",
)
#: Columns a plate record may have.
PLATE_RECORD_COLUMNS = ("plate_radius_m", "plate_width_m", "plate_length_m", "force_N", "pressure_Pa", "sinkage_m")
#: Every column of a bevameter record (the names a column mapping may target).
RECORD_COLUMNS = tuple(dict.fromkeys((*KNOWN_COLUMNS, *ANNULUS_COLUMNS, *PLATE_RECORD_COLUMNS)))


def _frozen(a) -> np.ndarray:
    arr = np.array(a, dtype=float).reshape(-1)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class AnnulusTest:
    """A shear annulus test: torque against rotation at set normal pressures.

    Parameters
    ----------
    normal_pressure
        Normal pressure on the ring per row, Pa (> 0).
    rotation
        Rotation of the annulus, rad (>= 0).
    torque
        Measured torque, N m.
    inner_radius, outer_radius
        The ring's radii per row, m (0 <= r_i < r_o).
    source
        Where the data came from, used in messages.
    """

    normal_pressure: np.ndarray
    rotation: np.ndarray
    torque: np.ndarray
    inner_radius: np.ndarray
    outer_radius: np.ndarray
    source: str = "<memory>"

    def __post_init__(self) -> None:
        names = ("normal_pressure", "rotation", "torque", "inner_radius", "outer_radius")
        for name in names:
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        n = {self.__dict__[k].size for k in names}
        if len(n) != 1:
            raise DataError("the annulus test's columns differ in length", file=self.source)
        checks = (
            (~np.isfinite(self.torque), "torque_Nm", "the torque must be a finite number"),
            (~(self.normal_pressure > 0), "normal_pressure_Pa", "the normal pressure must be > 0 Pa"),
            (~(self.rotation >= 0), "rotation_rad", "the rotation must be >= 0"),
            (~(self.inner_radius >= 0), "inner_radius_m", "the inner radius must be >= 0 m"),
            (~(self.outer_radius > self.inner_radius), "outer_radius_m", "the outer radius must exceed the inner"),
        )
        for bad, col, what in checks:
            if bad.any():
                raise bad_rows_error(bad, self.source, col, what)

    @property
    def n_samples(self) -> int:
        """Number of rows."""
        return int(self.torque.size)

    @property
    def ring_area(self) -> np.ndarray:
        """``pi (r_o^2 - r_i^2)`` per row, m^2."""
        return math.pi * (self.outer_radius**2 - self.inner_radius**2)


def is_bevameter_record(header: list[str]) -> bool:
    """True when the header (library names) is an annulus's torque record or a plate's record."""
    annulus = "torque_Nm" in header and ("rotation_rad" in header or "rotation_deg" in header)
    plate = "plate_radius_m" in header or ("force_N" in header and "sinkage_m" in header)
    return annulus or plate or ("plate_length_m" in header)


def _radius(data: dict, name: str, given: float | None, n: int, path: str) -> np.ndarray:
    if name in data and given is not None:
        raise DataError(f"{name} is both a column and an option: give it once", file=path, column=name)
    if name in data:
        return data[name]
    if given is None:
        opt = "--" + name.replace("_", "-")
        raise DataError(f"a shear annulus needs its {name} (a column, or {opt})", file=path, column=name)
    if not (math.isfinite(given) and given >= 0):
        raise DataError(f"{name} must be a finite number >= 0 m, got {given!r}", file=path)
    return np.full(n, float(given))


def _one_of(header: list[str], names: tuple[str, str], path: str, what: str) -> str:
    have = [c for c in names if c in header]
    if len(have) != 1:
        raise DataError(
            f"{what}: give exactly one of {list(names)} (the header has {'both' if have else 'neither'})",
            file=path,
            column=names[0],
        )
    return have[0]


def read_bevameter_record(
    path: str | os.PathLike,
    *,
    inner_radius_m: float | None = None,
    outer_radius_m: float | None = None,
    columns: dict[str, str] | None = None,
) -> AnnulusTest | PlateTest:
    """Read a shear annulus's or a plate's record (see the module text); DataError naming file, column, rows."""
    path = os.fspath(path)
    plan: ColumnPlan = plan_columns(read_header(path), known=RECORD_COLUMNS, mapping=columns, source=path)
    header = list(plan.header)
    if "torque_Nm" in header:
        load = _one_of(header, ("normal_load_N", "normal_pressure_Pa"), path, "a shear annulus")
        rot = _one_of(header, ("rotation_rad", "rotation_deg"), path, "a shear annulus")
        used = [load, rot, "torque_Nm"] + [c for c in ("inner_radius_m", "outer_radius_m") if c in header]
        data = plan.apply(read_columns(path, header, used))
        n = data["torque_Nm"].size
        ri = _radius(data, "inner_radius_m", inner_radius_m, n, path)
        ro = _radius(data, "outer_radius_m", outer_radius_m, n, path)
        theta = data[rot] * (math.pi / 180.0 if rot == "rotation_deg" else 1.0)
        sigma = data[load] / (math.pi * (ro**2 - ri**2)) if load == "normal_load_N" else data[load]
        return AnnulusTest(sigma, theta, data["torque_Nm"], ri, ro, source=path)
    if inner_radius_m is not None or outer_radius_m is not None:
        raise DataError("--inner-radius-m / --outer-radius-m apply to a shear annulus (torque_Nm) only", file=path)
    size = _one_of(header, ("plate_radius_m", "plate_width_m"), path, "a plate test")
    load = _one_of(header, ("force_N", "pressure_Pa"), path, "a plate test")
    if "sinkage_m" not in header:
        raise DataError(f"missing required column of a plate test (header has {header})", file=path, column="sinkage_m")
    if size == "plate_radius_m" and "plate_length_m" in header:
        raise DataError("plate_length_m is for a rectangular plate; a circular one has plate_radius_m only", file=path)
    used = [size, load, "sinkage_m"] + (["plate_length_m"] if "plate_length_m" in header else [])
    data = plan.apply(read_columns(path, header, used))
    s = data[size]
    for col in used:
        if col in ("plate_radius_m", "plate_width_m", "plate_length_m") and not np.all(data[col] > 0):
            raise bad_rows_error(~(data[col] > 0), path, col, "a plate's size must be > 0 m")
    area: np.ndarray | None
    if size == "plate_radius_m":
        b, area = s, math.pi * s**2
    else:
        length = data.get("plate_length_m")
        b = s if length is None else np.minimum(s, length)
        area = None if length is None else s * length
    if load == "force_N":
        if area is None:
            raise DataError(
                "force_N on a plate of width only: give plate_length_m (rectangular) or plate_radius_m (circular), "
                "or pressure_Pa",
                file=path,
                column="force_N",
            )
        p = data["force_N"] / area
    else:
        p = data["pressure_Pa"]
    return PlateTest(plate_width=b, pressure=p, sinkage=data["sinkage_m"], source=path)
