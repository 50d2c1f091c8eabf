"""A drive log read as a stream of samples: missing or non-finite readings kept as gaps.

:func:`~.data.read_csv` refuses a drive log with an empty or non-finite value (a fit needs
every reading). A log replayed sample by sample (``soiltrack track``, the on-line estimator)
instead skips such a sample and counts it, as a vehicle's computer would when a channel drops
out. :func:`read_drive_stream` therefore keeps empty cells and ``nan``/``inf`` as NaN and
refuses only what no stream can carry: a missing file or column, text that is not a number,
a row with the wrong number of fields, time stamps that do not increase.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from .csvread import CHUNK_ROWS_ENV, chunk_rows, iter_chunks
from .errors import DataError
from .tracks import TWO_TRACK_COLUMNS, YAW_COLUMN

__all__ = ["DriveStream", "DriveStreamReader", "read_drive_stream", "STREAM_COMBINED", "STREAM_OPTIONAL"]

#: The combined (one-channel) sprocket columns of a drive log.
STREAM_COMBINED = ("sprocket_torque_Nm", "sprocket_speed_rad_s")
#: Rows per chunk of :class:`DriveStreamReader` (a chunk's text and Python rows, about 700 bytes a row, are the
#: replay's only memory that grows with the chunk: 6 MB).
STREAM_CHUNK_ROWS = 8192
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


class DriveStreamReader:
    """A drive log read chunk by chunk (constant memory): the header checked on opening, each chunk's rows on
    reading, with the messages and file rows of :func:`read_drive_stream` (which is this reader's chunks joined).

    Attributes
    ----------
    source, two_track, used
        The file, whether it has the two-track columns, and the columns read (contract names).
    chunk
        Rows per chunk (default :data:`STREAM_CHUNK_ROWS`, or ``$SOILTRACK_CHUNK_ROWS``).
    plan
        The file's columns under the library's names, with their unit conversions
        (:func:`soiltrack.soilmodel.columns.plan_columns`; ``columns`` maps file columns onto names).
    """

    def __init__(
        self, path: str | os.PathLike, *, chunk: int | None = None, columns: dict[str, str] | None = None
    ) -> None:
        from .columns import plan_columns
        from .data import KNOWN_COLUMNS

        self.source = os.fspath(path)
        env = os.environ.get(CHUNK_ROWS_ENV)
        self.chunk = chunk_rows(chunk if chunk is not None or (env and env.strip()) else STREAM_CHUNK_ROWS)
        self.plan = plan_columns(self._header(), known=KNOWN_COLUMNS, mapping=columns, source=self.source)
        header = list(self.plan.header)
        dup = sorted({h for h in header if header.count(h) > 1})
        if dup:
            raise DataError(f"duplicate column(s) {dup}", file=self.source, column=dup[0])
        self.two_track = any(c in header for c in TWO_TRACK_COLUMNS)
        if self.two_track and any(c in header for c in STREAM_COMBINED):
            raise DataError(
                f"both combined columns {list(STREAM_COMBINED)} and two-track columns given: a drive log "
                "has one or the other",
                file=self.source,
                column=next(c for c in STREAM_COMBINED if c in header),
            )
        sprocket = TWO_TRACK_COLUMNS if self.two_track else STREAM_COMBINED
        required = ("time_s", *sprocket, "vehicle_speed_m_s")
        for col in required:
            if col not in header:
                raise DataError(
                    f"missing required column of a drive log (header has {header})", file=self.source, column=col
                )
        self.header = header
        self.used = [c for c in (*required, *STREAM_OPTIONAL) if c in header]

    def _header(self) -> list[str]:
        for head, _ in self._chunks():
            return head
        raise DataError("empty file: expected a header row", file=self.source)

    def _chunks(self):
        return iter_chunks(self.source, self.chunk)

    def __iter__(self):
        """Chunks ``{column: values}`` (NaN for a gap) in file order; DataError at the first bad row."""
        path, header = self.source, self.header
        idx = {c: header.index(c) for c in self.used}
        t_last = math.nan
        seen = False
        for _, rows in self._chunks():
            if not rows:
                continue
            data = {c: np.empty(len(rows)) for c in self.used}
            for k, (r, cells) in enumerate(rows):
                if len(cells) != len(header):
                    raise DataError(f"expected {len(header)} fields, found {len(cells)}", file=path, row=r)
                for c in self.used:
                    data[c][k] = _cell(cells[idx[c]], path, c, r)
            data = self.plan.apply(data)
            t = data["time_s"]
            fin = np.nonzero(np.isfinite(t))[0]
            tf = np.concatenate([[t_last], t[fin]]) if math.isfinite(t_last) else t[fin]
            off = 1 if math.isfinite(t_last) else 0
            bad = np.nonzero(np.diff(tf) <= 0)[0]
            if bad.size:
                k = int(fin[bad[0] + 1 - off])
                raise DataError(
                    f"time must be strictly increasing ({tf[bad[0]]:.6g} then {t[k]:.6g})",
                    file=path,
                    column="time_s",
                    row=rows[k][0],
                )
            if fin.size:
                t_last = float(t[fin[-1]])
            seen = True
            for v in data.values():
                v.setflags(write=False)
            yield data
        if not seen:
            raise DataError("no data rows after the header", file=path)

    def check(self) -> int:
        """Read the whole file once (constant memory) and return its data rows; DataError as :meth:`__iter__`."""
        return sum(int(c["time_s"].size) for c in self)


def read_drive_stream(
    path: str | os.PathLike, *, chunk: int | None = None, columns: dict[str, str] | None = None
) -> DriveStream:
    """Read a drive log (combined or two-track columns) keeping missing readings as NaN.

    The rows are read in chunks (:class:`DriveStreamReader`); a replay that must not hold the log iterates
    the reader itself. ``columns`` maps the file's columns onto the library's names; unit suffixes
    convert (:mod:`soiltrack.soilmodel.columns`).

    Raises
    ------
    DataError
        A missing file, a missing column, both combined and two-track columns, text that is not
        a number, a row with the wrong number of fields, no data rows, or time stamps (where
        present) that do not strictly increase; the message names the file, column and row.
    """
    reader = DriveStreamReader(path, chunk=chunk, columns=columns)
    parts: dict[str, list[np.ndarray]] = {c: [] for c in reader.used}
    for data in reader:
        for c, v in data.items():
            parts[c].append(v)
    data = {c: np.concatenate(v) for c, v in parts.items()}
    for v in data.values():
        v.setflags(write=False)
    return DriveStream(columns=data, two_track=reader.two_track, source=reader.source)
