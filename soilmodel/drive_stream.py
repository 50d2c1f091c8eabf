"""A drive log read as a stream of samples: missing or non-finite readings kept as gaps.

:func:`~.data.read_csv` refuses a drive log with an empty or non-finite value (a fit needs
every reading). A log replayed sample by sample (``soiltrack track``, the on-line estimator)
instead skips such a sample and counts it, as a vehicle's computer would when a channel drops
out. :func:`read_drive_stream` therefore keeps empty cells and ``nan``/``inf`` as NaN and
refuses only what no stream can carry: a missing file or column, text that is not a number,
a row with the wrong number of fields, time stamps that do not increase.
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass

import numpy as np

from .errors import DataError
from .tracks import TWO_TRACK_COLUMNS, YAW_COLUMN

__all__ = ["DriveStream", "read_drive_stream", "STREAM_COMBINED", "STREAM_OPTIONAL"]

#: The combined (one-channel) sprocket columns of a drive log.
STREAM_COMBINED = ("sprocket_torque_Nm", "sprocket_speed_rad_s")
#: Optional columns of a streamed drive log.
STREAM_OPTIONAL = ("vehicle_accel_m_s2", YAW_COLUMN)


@dataclass(frozen=True, eq=False)
class DriveStream:
    """The columns of a drive log with gaps (NaN) where a reading is missing or not finite.

    Attributes
    ----------
    columns
        ``{column name: values}`` in the CSV contract's names (SI); NaN marks a gap.
    two_track
        Whether the log has the left/right sprocket columns (else the combined ones).
    source
        The file's path.
    """

    columns: dict
    two_track: bool
    source: str

    @property
    def n_samples(self) -> int:
        """Number of rows."""
        return int(self.columns["time_s"].size)

    def column(self, name: str) -> np.ndarray | None:
        """One column, or ``None`` when the log does not have it."""
        return self.columns.get(name)


def _cell(text: str, path: str, column: str, row: int) -> float:
    t = text.strip()
    if not t:
        return math.nan
    try:
        return float(t)
    except ValueError:
        raise DataError(
            f"'{t}' is not a number (an empty cell or nan marks a missing reading)",
            file=path,
            column=column,
            row=row,
        ) from None


def read_drive_stream(path: str | os.PathLike, *, columns: dict[str, str] | None = None) -> DriveStream:
    """Read a drive log (combined or two-track columns) keeping missing readings as NaN.

    ``columns`` maps the file's columns onto the library's names; unit suffixes convert
    (:mod:`soiltrack.soilmodel.columns`).

    Raises
    ------
    DataError
        A missing file, a missing column, both combined and two-track columns, text that is not
        a number, a row with the wrong number of fields, no data rows, or time stamps (where
        present) that do not strictly increase; the message names the file, column and row.
    """
    path = os.fspath(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = [r for r in csv.reader(fh) if any(cell.strip() for cell in r)]
    except OSError as e:
        raise DataError(f"cannot read: {e.strerror}", file=path) from None
    except UnicodeDecodeError:
        raise DataError("not a UTF-8 text file", file=path) from None
    if not rows:
        raise DataError("empty file: expected a header row", file=path)
    from .columns import plan_columns
    from .data import KNOWN_COLUMNS

    plan = plan_columns([h.strip() for h in rows[0]], known=KNOWN_COLUMNS, mapping=columns, source=path)
    header = list(plan.header)
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise DataError(f"duplicate column(s) {dup}", file=path, column=dup[0])
    two_track = any(c in header for c in TWO_TRACK_COLUMNS)
    if two_track and any(c in header for c in STREAM_COMBINED):
        raise DataError(
            f"both combined columns {list(STREAM_COMBINED)} and two-track columns given: a drive log "
            "has one or the other",
            file=path,
            column=next(c for c in STREAM_COMBINED if c in header),
        )
    sprocket = TWO_TRACK_COLUMNS if two_track else STREAM_COMBINED
    required = ("time_s", *sprocket, "vehicle_speed_m_s")
    for col in required:
        if col not in header:
            raise DataError(f"missing required column of a drive log (header has {header})", file=path, column=col)
    if len(rows) < 2:
        raise DataError("no data rows after the header", file=path)
    used = [c for c in (*required, *STREAM_OPTIONAL) if c in header]
    idx = {c: header.index(c) for c in used}
    data = {c: np.empty(len(rows) - 1) for c in used}
    for r, cells in enumerate(rows[1:], start=1):
        if len(cells) != len(header):
            raise DataError(f"expected {len(header)} fields, found {len(cells)}", file=path, row=r)
        for c in used:
            data[c][r - 1] = _cell(cells[idx[c]], path, c, r)
    data = plan.apply(data)
    t = data["time_s"]
    fin = np.nonzero(np.isfinite(t))[0]
    bad = np.nonzero(np.diff(t[fin]) <= 0)[0]
    if bad.size:
        k = int(fin[bad[0] + 1])
        raise DataError(
            f"time must be strictly increasing ({t[fin[bad[0]]]:.6g} then {t[k]:.6g})",
            file=path,
            column="time_s",
            row=k + 1,
        )
    for v in data.values():
        v.setflags(write=False)
    return DriveStream(columns=data, two_track=two_track, source=path)
