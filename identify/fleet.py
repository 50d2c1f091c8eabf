"""Rows of a fleet's results, written as the fits finish: ``fit_many(..., out="results.csv")``.

One row per drive log (``segment`` empty) or per segment of a log's soil map (``fit_many(...,
segments="60s")``), in the order the fits finish; ``index`` is the item's place in the input and
``source`` its file. A log that could not be read or fitted has one row with ``outcome`` "failed", the
reason in ``reason`` and the exception's type in ``error``; nothing else is lost. CSV by default;
a path ending in ``.parquet`` writes Parquet (one row group per finished item) when ``pyarrow`` is
importable (not a dependency of soiltrack: without it such a path is refused before any fit).
"""

from __future__ import annotations

import csv
import math
import os
from typing import Any, Iterable

from ..soilmodel.errors import DataError
from .segments import Segment, SegmentMap, segment_of

__all__ = ["FLEET_COLUMNS", "FleetWriter", "fleet_rows"]

#: Columns of the results file, in order.
FLEET_COLUMNS = (
    "index",
    "source",
    "segment",
    "start_s",
    "end_s",
    "rows",
    "distance_m",
    "outcome",
    "max_thrust_N",
    "max_thrust_ci95_lo",
    "max_thrust_ci95_hi",
    "max_thrust_stderr_N",
    "shear_modulus_m",
    "shear_modulus_ci95_lo",
    "shear_modulus_ci95_hi",
    "shear_modulus_stderr_m",
    "cohesion_kpa",
    "friction_angle_deg",
    "discretisation",
    "reason",
    "error",
)

_NO_SPAN: dict[str, Any] = dict(start_s=None, end_s=None, distance_m=None, rows=None)


def _source(item: Any, result: Any) -> str:
    if isinstance(item, (str, os.PathLike)):
        return os.fspath(item)
    src = getattr(result, "source", None) or getattr(item, "source", None)
    return src if isinstance(src, str) else f"<{type(item).__name__}>"


def _row(index: int, source: str, segment: int | None, seg: Segment, error: str = "") -> dict[str, Any]:
    F, K = seg.max_thrust_ci95 or (None, None), seg.shear_modulus_ci95 or (None, None)
    return dict(
        index=index,
        source=source,
        segment=segment,
        start_s=seg.start_s,
        end_s=seg.end_s,
        rows=seg.rows,
        distance_m=seg.distance_m,
        outcome=seg.outcome,
        max_thrust_N=seg.max_thrust_N,
        max_thrust_ci95_lo=F[0],
        max_thrust_ci95_hi=F[1],
        max_thrust_stderr_N=seg.max_thrust_stderr_N,
        shear_modulus_m=seg.shear_modulus_m,
        shear_modulus_ci95_lo=K[0],
        shear_modulus_ci95_hi=K[1],
        shear_modulus_stderr_m=seg.shear_modulus_stderr_m,
        cohesion_kpa=seg.cohesion_kpa,
        friction_angle_deg=seg.friction_angle_deg,
        discretisation=seg.discretisation,
        reason=seg.reason or "; ".join(f"{k} not identified: {why}" for k, why in seg.not_identified) or None,
        error=error,
    )


def fleet_rows(index: int, item: Any, result: Any) -> list[dict[str, Any]]:
    """The rows of one finished item: a :class:`~.segments.SegmentMap` (one per segment) or a fit result."""
    if isinstance(result, SegmentMap):
        src = _source(item, result)
        return [_row(index, src, j, s) for j, s in enumerate(result.segments)]
    span = result.extra.get("log_span") or _NO_SPAN
    try:
        seg = segment_of(result, dict(span))
    except Exception as e:  # noqa: BLE001 - a result the row cannot summarise: its row says why
        seg = segment_of(_Failed(f"{result.message} (its summary failed: {type(e).__name__}: {e})"), dict(span))
    return [_row(index, _source(item, result), None, seg, str(result.extra.get("error", "") or ""))]


class _Failed:
    """Just enough of a failed result for :func:`~.segments.segment_of`."""

    status = "not fitted"

    def __init__(self, message: str) -> None:
        self.message = message


def _cell(v: Any) -> Any:
    if v is None:
        return ""
    if isinstance(v, float) and not math.isfinite(v):
        return ""  # never NaN/inf in a results file: an empty cell
    return v


class FleetWriter:
    """Append rows to ``path`` as they come (CSV, or Parquet for ``*.parquet`` with pyarrow); a context manager."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = os.fspath(path)
        self.parquet = self.path.lower().endswith(".parquet")
        if self.parquet:
            try:
                import pyarrow  # noqa: F401
            except ImportError:
                raise DataError(
                    "writing Parquet needs pyarrow (pip install 'soiltrack[parquet]' or pip install pyarrow; "
                    "not a dependency of soiltrack): give a .csv path instead",
                    file=self.path,
                ) from None
        self._fh: Any = None
        self._pq: Any = None
        self.rows = 0

    def __enter__(self) -> "FleetWriter":
        if not self.parquet:
            self._fh = open(self.path, "w", newline="", encoding="utf-8")
            self._csv = csv.DictWriter(self._fh, fieldnames=FLEET_COLUMNS)
            self._csv.writeheader()
            self._fh.flush()
        return self

    def write(self, rows: Iterable[dict[str, Any]]) -> None:
        """Write ``rows`` now (flushed: a reader sees every finished item)."""
        rows = [{k: _cell(r.get(k)) for k in FLEET_COLUMNS} for r in rows]
        if not rows:
            return
        self.rows += len(rows)
        if not self.parquet:
            self._csv.writerows(rows)
            self._fh.flush()
            return
        import pyarrow as pa
        import pyarrow.parquet as pq

        cols = {k: [None if r[k] == "" else r[k] for r in rows] for k in FLEET_COLUMNS}
        table = pa.table({k: pa.array(v, type=_ARROW_TYPES[k](pa)) for k, v in cols.items()})
        if self._pq is None:
            self._pq = pq.ParquetWriter(self.path, table.schema)
        self._pq.write_table(table)

    def __exit__(self, *exc: Any) -> None:
        if self._fh is not None:
            self._fh.close()
        if self._pq is not None:
            self._pq.close()


_TEXT = ("source", "outcome", "discretisation", "reason", "error")
_INT = ("index", "segment", "rows")
_ARROW_TYPES = {
    k: (lambda pa: pa.string()) if k in _TEXT else (lambda pa: pa.int64()) if k in _INT else (lambda pa: pa.float64())
    for k in FLEET_COLUMNS
}
