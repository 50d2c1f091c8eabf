"""Column mapping and unit suffixes of exported CSV files: one home for reading a rig's own names.

A rig or logger exports its own column names and units (``Fx``, ``depth_mm``, ``load_kN``). The
readers of this library (:func:`~soiltrack.soilmodel.read_csv`, the wheel sweep, the drive-log
stream) take the library's names in SI units. This module turns a file's header into the
library's names before the readers recognise the file's kind:

- an explicit mapping ``{NAME: SOURCE}`` (``--columns NAME=SOURCE[,NAME=SOURCE...]`` on the
  command line) reads the file's column SOURCE as the library's column NAME;
- a unit suffix (:data:`UNITS`: ``_mm``, ``_kN``, ``_kPa``, ``_percent``, ``_deg``, ``_rpm``,
  ``_ms``, ...) on SOURCE, or on a header column whose stem is a library column's stem
  (``sinkage_mm`` for ``sinkage_m``), converts the values to the library's unit, and the plan
  says so (:attr:`ColumnPlan.notes`: the readers' callers print them in their reports);
- a suffix of another kind of quantity than the library column's (``vehicle_speed_ms``: ``_ms``
  is milliseconds, a time, where a speed is expected) is ambiguous and refused with a hint;
- where the file already has the library's own column, a suffixed copy is left unread and the
  plan says so.

The plan is a pure function of the header (:func:`plan_columns`); the values are converted by
:meth:`ColumnPlan.apply` after the reader parsed them, before any range check.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Mapping

import numpy as np

from .errors import DataError

__all__ = ["UNITS", "Conversion", "ColumnPlan", "split_unit", "plan_columns", "parse_columns_arg"]

#: Unit suffix -> (kind of quantity, factor to that kind's SI unit). The library's own columns end
#: in the SI suffix of their quantity (``slip`` has none: a fraction; slip angles are in degrees).
UNITS: dict[str, tuple[str, float]] = {
    "m": ("length", 1.0),
    "mm": ("length", 1e-3),
    "cm": ("length", 1e-2),
    "N": ("force", 1.0),
    "kN": ("force", 1e3),
    "Pa": ("pressure", 1.0),
    "kPa": ("pressure", 1e3),
    "MPa": ("pressure", 1e6),
    "Nm": ("torque", 1.0),
    "N_m": ("torque", 1.0),
    "kNm": ("torque", 1e3),
    "kN_m": ("torque", 1e3),
    "rad": ("angle", 1.0),
    "deg": ("angle", math.pi / 180.0),
    "rad_s": ("angular speed", 1.0),
    "rpm": ("angular speed", 2.0 * math.pi / 60.0),
    "deg_s": ("angular speed", math.pi / 180.0),
    "m_s": ("speed", 1.0),
    "mm_s": ("speed", 1e-3),
    "km_h": ("speed", 1.0 / 3.6),
    "m_s2": ("acceleration", 1.0),
    "s": ("time", 1.0),
    "ms": ("time", 1e-3),
    "percent": ("fraction", 0.01),
}
_BY_LENGTH = sorted(UNITS, key=len, reverse=True)


def split_unit(name: str) -> tuple[str, str | None]:
    """``"sinkage_mm"`` -> ``("sinkage", "mm")``; a name without a known suffix -> ``(name, None)``."""
    for u in _BY_LENGTH:
        if name.endswith("_" + u) and len(name) > len(u) + 1:
            return name[: -len(u) - 1], u
    return name, None


def _kind(unit: str | None) -> tuple[str, float]:
    return ("fraction", 1.0) if unit is None else UNITS[unit]


@dataclass(frozen=True)
class Conversion:
    """One column read under the library's name.

    Attributes
    ----------
    name
        The library's column name.
    source
        The file's column it is read from.
    factor
        The values are multiplied by this (1: read as they are).
    note
        What was done, in words (for the report).
    """

    name: str
    source: str
    factor: float
    note: str


@dataclass(frozen=True)
class ColumnPlan:
    """A file's header in the library's names, and the conversions that go with it.

    Attributes
    ----------
    header
        The header with the mapped and converted columns renamed (same length and order).
    conversions
        One :class:`Conversion` per renamed column.
    skipped
        Sentences about suffixed columns left unread (the library's own column is present).
    """

    header: tuple[str, ...]
    conversions: tuple[Conversion, ...] = ()
    skipped: tuple[str, ...] = ()

    @property
    def notes(self) -> tuple[str, ...]:
        """Every conversion and skipped column in words (empty: the file was read as it is)."""
        return tuple(c.note for c in self.conversions) + self.skipped

    def apply(self, data: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The parsed columns (library names) with the conversion factors applied (a new dict)."""
        out = dict(data)
        for c in self.conversions:
            if c.factor != 1.0 and c.name in out:
                out[c.name] = np.asarray(out[c.name], dtype=float) * c.factor
        return out


def _factor(source: str, name: str, where: str, file: str | None) -> tuple[float, str]:
    """Factor from ``source``'s unit suffix to ``name``'s, and the words; DataError across kinds."""
    _, su = split_unit(source)
    _, nu = split_unit(name)
    if su is None:
        return 1.0, f"{source} read as {name} (no unit suffix on {source}: taken to be in {name}'s unit)"
    (sk, sf), (nk, nf) = _kind(su), _kind(nu)
    if sk != nk:
        raise DataError(
            f"{where}: the suffix '_{su}' of {source} is a unit of {sk}, but {name} is a {nk}"
            + (" ('_ms' means milliseconds; a speed is '_m_s')" if su == "ms" and nk == "speed" else "")
            + f": rename the column in the file (or map a column in {name}'s unit)",
            file=file,
            column=source,
        )
    f = sf / nf
    if f == 1.0:
        return 1.0, f"{source} read as {name}"
    return f, f"{source} read as {name}, converted from {su} to {nu or 'a fraction'} (x {f:.6g})"


def plan_columns(
    header: Iterable[str],
    *,
    known: Iterable[str],
    mapping: Mapping[str, str] | None = None,
    source: str | None = None,
) -> ColumnPlan:
    """The library's names for a file's header: explicit ``mapping`` first, then unit suffixes.

    Parameters
    ----------
    header
        The file's header (names stripped).
    known
        The library's column names the readers take.
    mapping
        ``{library name: file column}`` (``--columns``), or ``None``.
    source
        The file, named in errors.

    Raises
    ------
    DataError
        A mapping onto an unknown library name or from a column the file lacks, a library name
        mapped twice or already in the file, or a unit suffix of another kind of quantity.
    """
    head = list(header)
    known = tuple(known)
    convs: list[Conversion] = []
    taken: set[int] = set()
    for name, src in (mapping or {}).items():
        where = f"--columns {name}={src}"
        if name not in known:
            raise DataError(f"{where}: {name!r} is not a column the library reads; it reads {sorted(known)}")
        if src not in head:
            raise DataError(f"{where}: the file has no column {src!r} (its header is {head})", file=source)
        if name in head and name != src:
            raise DataError(
                f"{where}: the file already has a column {name!r}; map only columns the file names otherwise",
                file=source,
                column=name,
            )
        k = head.index(src)
        f, note = _factor(src, name, where, source)
        head[k] = name
        taken.add(k)
        convs.append(Conversion(name, src, f, note))
    stems: dict[str, list[str]] = {}
    for n in known:
        stems.setdefault(split_unit(n)[0], []).append(n)
    skipped = []
    for k, h in enumerate(list(head)):
        if k in taken or h in known:
            continue
        stem, unit = split_unit(h)
        if unit is None or stem not in stems:
            continue
        for name in stems[stem]:
            if name in head:
                skipped.append(f"{h} not read: the file has {name}")
                break
            f, note = _factor(h, name, f"column {h}", source)
            head[k] = name
            convs.append(Conversion(name, h, f, note))
            break
    return ColumnPlan(tuple(head), tuple(convs), tuple(skipped))


def parse_columns_arg(text: str | None) -> dict[str, str] | None:
    """``"NAME=SOURCE[,NAME=SOURCE...]"`` -> ``{NAME: SOURCE}`` (``None`` for ``None``); DataError otherwise."""
    if text is None:
        return None
    out: dict[str, str] = {}
    for item in text.split(","):
        if not item.strip():
            continue
        name, sep, src = item.partition("=")
        name, src = name.strip(), src.strip()
        if not sep or not name or not src:
            raise DataError(f"--columns expects NAME=SOURCE[,NAME=SOURCE...], got {item.strip()!r}")
        if name in out:
            raise DataError(f"--columns maps {name!r} twice")
        if src in out.values():
            raise DataError(f"--columns reads the file's column {src!r} twice")
        out[name] = src
    if not out:
        raise DataError(f"--columns expects NAME=SOURCE[,NAME=SOURCE...], got {text!r}")
    return out
