"""Safe, streaming reading of the CSV contract's numeric columns (limits said, every bad row named).

:func:`soiltrack.soilmodel.read_csv` decides the file's kind from its header; this module reads
the rows. It never holds the file's text in memory: each row is parsed as it is read into one
compact float array per column, so memory grows with the numbers kept (8 bytes a value), and
a file with more data rows than :func:`max_rows` is refused as soon as the reader passes the
limit (before the rest of the file is read). The rows are parsed in chunks (:data:`CHUNK_ROWS`; the
values of a chunk's column converted at once), with the same checks, messages and row numbers
whatever the chunk size. Every bad value or row is collected - the error
names how many there are and the first few (:data:`~soiltrack.soilmodel.errors.SHOWN_ROWS`),
not only the first. Encodings other than UTF-8 (a UTF-16 export, a binary file), fields
longer than CSV's field limit and values beyond :data:`MAX_ABS_VALUE` are refused with the
file, the column and the row named.
"""

from __future__ import annotations

import codecs
import csv
import math
import re
import os
from array import array
from typing import Iterator

import numpy as np

from .errors import SHOWN_ROWS, DataError, rows_text

__all__ = [
    "MAX_ROWS",
    "count_rows",
    "check_row_limit",
    "MAX_ROWS_ENV",
    "MAX_ABS_VALUE",
    "CHUNK_ROWS",
    "CHUNK_ROWS_ENV",
    "chunk_rows",
    "iter_chunks",
    "max_rows",
    "check_encoding",
    "read_header",
    "read_columns",
    "bad_rows_error",
]

#: Default largest number of data rows read into memory (a one-hour drive log at 500 Hz has 1.8
#: million); ``$SOILTRACK_MAX_ROWS`` or ``read_csv(..., max_rows=N)`` changes it.
MAX_ROWS = 2_000_000
#: Environment variable that sets the row limit.
MAX_ROWS_ENV = "SOILTRACK_MAX_ROWS"
#: Rows parsed per chunk (a chunk's text is the only text held: about 100 bytes a row); the checks, the
#: messages and the rows they name do not depend on it. ``$SOILTRACK_CHUNK_ROWS`` or ``chunk=`` changes it.
CHUNK_ROWS = 65_536
#: Environment variable that sets the chunk size.
CHUNK_ROWS_ENV = "SOILTRACK_CHUNK_ROWS"
#: Largest magnitude of any value in a data file (SI units). No force, torque, speed, time or
#: load of a tracked vehicle comes near it, and sums of squares of larger values overflow
#: float64 in the fits (a torque of 1e308 made the drive-log fit fail with a linear-algebra error).
MAX_ABS_VALUE = 1e12

_BOMS = (
    (codecs.BOM_UTF32_LE, "UTF-32"),
    (codecs.BOM_UTF32_BE, "UTF-32"),
    (codecs.BOM_UTF16_LE, "UTF-16"),
    (codecs.BOM_UTF16_BE, "UTF-16"),
)


def max_rows(limit: int | None = None) -> int:
    """The row limit in force: ``limit`` if given, else ``$SOILTRACK_MAX_ROWS``, else :data:`MAX_ROWS`."""
    if limit is None:
        env = os.environ.get(MAX_ROWS_ENV)
        if env is None or not env.strip():
            return MAX_ROWS
        try:
            limit = int(env)
        except ValueError:
            raise DataError(f"${MAX_ROWS_ENV} must be a whole number of rows, got {env!r}") from None
    if isinstance(limit, bool) or int(limit) < 1:
        raise DataError(f"the row limit must be a whole number >= 1, got {limit!r}")
    return int(limit)


def check_encoding(path: str, head: bytes, what: str = "text file") -> None:
    """Refuse UTF-16/32 and binary content (from the file's first bytes) naming the file."""
    for bom, name in _BOMS:
        if head.startswith(bom):
            raise DataError(f"the {what} is {name} text: save it as UTF-8", file=path)
    if b"\0" in head:
        if len(head) >= 2 and (head[1:2] == b"\0" or head[0:1] == b"\0") and head.count(b"\0") * 3 >= len(head):
            raise DataError(f"the {what} looks like UTF-16 text without a byte-order mark: save it as UTF-8", file=path)
        raise DataError(
            f"not a text file (NUL bytes in the first {len(head)} bytes): expected a UTF-8 {what}", file=path
        )


def _rows(path: str) -> Iterator[tuple[int, list[str]]]:
    """Non-blank CSV rows with their index (0 = the header); DataError naming the row on any read error."""
    try:
        with open(path, "rb") as fb:
            head = fb.read(4096)
    except OSError as e:
        raise DataError(f"cannot read: {e.strerror}", file=path) from None
    check_encoding(path, head, "CSV file")
    k = 0
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            try:
                for cells in reader:
                    if any(cell.strip() for cell in cells):  # blank lines carry nothing
                        yield k, cells
                        k += 1
            except csv.Error as e:
                what = str(e)
                if "field larger than field limit" in what:
                    what = (
                        f"a field longer than {csv.field_size_limit():,} characters (a missing closing "
                        "quote, "
                        "or not a CSV file)"
                    )
                raise DataError(f"unreadable CSV: {what}", file=path, row=k if k else None) from None
            except UnicodeDecodeError:
                raise DataError("not a UTF-8 text file", file=path, row=k if k else None) from None
    except OSError as e:
        raise DataError(f"cannot read: {e.strerror}", file=path) from None


def read_header(path: str) -> list[str]:
    """The header row (names stripped); DataError for an empty or unreadable file."""
    for _, cells in _rows(path):
        return [h.strip() for h in cells]
    raise DataError("empty file: expected a header row", file=path)


class _BadRows:
    """Bad values collected while reading: the count and the first few, per reason."""

    def __init__(self) -> None:
        self.rows: list[int] = []
        self.count = 0
        self.first: tuple[str, str | None] | None = None  # (reason, column) of the first bad row
        self.columns: set[str] = set()
        self._last = -1  # the last row counted (``rows`` stops growing after the first few)

    def add(self, row: int, reason: str, column: str | None) -> None:
        if column is not None:
            self.columns.add(column)
        if self._last == row:
            return  # one row counted once, however many of its columns are bad
        self._last = row
        self.count += 1
        if len(self.rows) < SHOWN_ROWS:
            self.rows.append(row)
        if self.first is None:
            self.first = (reason, column)


def bad_rows_error(mask: np.ndarray, path: str, column: str | None, reason: str) -> DataError:
    """A DataError naming how many rows ``mask`` (over 0-based data rows) marks and the first few."""
    idx = np.nonzero(mask)[0]
    rows = [int(i) + 1 for i in idx[:SHOWN_ROWS]]
    text = reason if idx.size == 1 else f"{reason} - {idx.size} of {mask.size} rows: {rows_text(rows, idx.size)}"
    return DataError(text, file=path, column=column, rows=rows, count=int(idx.size))


#: A number written with a decimal comma (``0,0098``).
_DECIMAL_COMMA = re.compile(r"^[+-]?\d+,\d+$")


def _parse(text: str) -> tuple[float, str | None]:
    t = text.strip()
    try:
        v = float(t)
    except ValueError:
        comma = " (a decimal comma? the files use a decimal point)" if _DECIMAL_COMMA.match(t) else ""
        return math.nan, (f"'{t[:40]}{'...' if len(t) > 40 else ''}' is not a number{comma}" if t else "empty value")
    if not math.isfinite(v):
        return v, f"value '{t}' is not a finite number"
    if abs(v) > MAX_ABS_VALUE:
        return (
            v,
            f"value {v:.6g} is beyond any physical value in these files (|x| <= {MAX_ABS_VALUE:g} in SI units)",
        )
    return v, None


def chunk_rows(chunk: int | None = None) -> int:
    """Rows parsed per chunk: ``chunk`` if given, else ``$SOILTRACK_CHUNK_ROWS``, else :data:`CHUNK_ROWS`."""
    if chunk is None:
        env = os.environ.get(CHUNK_ROWS_ENV)
        if env is None or not env.strip():
            return CHUNK_ROWS
        try:
            chunk = int(env)
        except ValueError:
            raise DataError(f"${CHUNK_ROWS_ENV} must be a whole number of rows, got {env!r}") from None
    if isinstance(chunk, bool) or int(chunk) < 1:
        raise DataError(f"the chunk size must be a whole number of rows >= 1, got {chunk!r}")
    return int(chunk)


def iter_chunks(path: str, size: int) -> Iterator[tuple[list[str], list[tuple[int, list[str]]]]]:
    """The header, then the data rows in lists of at most ``size`` ``(row, cells)``: the first item is
    ``(header, [])``; ``row`` is the row's number (1 = the first data row; blank lines are skipped, not counted)."""
    chunk: list[tuple[int, list[str]]] = []
    for r, cells in _rows(path):
        if r == 0:
            yield [h.strip() for h in cells], []
            continue
        chunk.append((r, cells))
        if len(chunk) >= size:
            yield [], chunk
            chunk = []
    if chunk:
        yield [], chunk


def _column_values(texts: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Values of one column's cells and the mask of the cells :func:`_parse` refuses (vectorised; the cells that
    do not convert at once are parsed one by one)."""
    try:
        vals = np.array(texts, dtype=float)
    except ValueError:
        vals = np.array([_parse(t)[0] for t in texts], dtype=float)
        bad = np.array([_parse(t)[1] is not None for t in texts], dtype=bool)
        return vals, bad
    return vals, ~np.isfinite(vals) | (np.abs(vals) > MAX_ABS_VALUE)


def _parse_chunk(chunk, idx: dict[str, int], width: int, bad: "_BadRows") -> dict[str, np.ndarray]:
    """The ``used`` columns of one chunk of rows; bad values and rows recorded in ``bad`` in file order (row by
    row, column by column: the same order, counts and messages as a row-by-row read)."""
    n = len(chunk)
    ok_width = np.array([len(cells) == width for _, cells in chunk], dtype=bool)
    out, masks = {}, {}
    for c, j in idx.items():
        texts = [cells[j] if len(cells) == width else "nan" for _, cells in chunk]
        vals, m = _column_values(texts)
        vals[~ok_width] = math.nan
        out[c], masks[c] = vals, m & ok_width
    any_bad = ~ok_width
    for m in masks.values():
        any_bad = any_bad | m
    for k in np.nonzero(any_bad)[0] if n else []:
        r, cells = chunk[k]
        if not ok_width[k]:
            bad.add(r, f"expected {width} fields, found {len(cells)}", None)
            continue
        for c, j in idx.items():
            if masks[c][k]:
                bad.add(r, _parse(cells[j])[1] or "not a number", c)
    return out


def count_rows(path: str, block: int = 1 << 20) -> int:
    """Data rows of a CSV file (its lines after the header; a last line without a newline counts), read in blocks."""
    lines, last = 0, b"\n"
    try:
        with open(path, "rb") as fh:
            while True:
                buf = fh.read(block)
                if not buf:
                    break
                lines += buf.count(b"\n")
                last = buf[-1:]
    except OSError as e:
        raise DataError(f"cannot read: {e.strerror}", file=path) from None
    lines += last != b"\n"
    return max(lines - 1, 0)


def check_row_limit(path: str, limit: int | None = None) -> None:
    """Refuse, before any parsing, a file with more lines after its header than the row limit (``max_rows``).

    Only a file larger than 4 bytes a row at the limit is counted (1 MB blocks, no parse: about a second for
    a few hundred MB); the streaming reader checks the rows themselves anyway.
    """
    lim = max_rows(limit)
    try:
        big = os.path.getsize(path) > 4 * lim
    except OSError:
        return  # the reader names the problem
    if not big:
        return
    n = count_rows(path)
    if n > lim:
        raise DataError(
            f"{n:,} lines after the header, more than the limit of {lim:,} data rows: files are read into memory "
            f"(raise it with ${MAX_ROWS_ENV}=N or read_csv(..., max_rows=N), or decimate the log); refused before "
            "reading",
            file=path,
            row=lim + 1,
        )


def read_columns(
    path: str, header: list[str], used: list[str], limit: int | None = None, *, chunk: int | None = None
) -> dict[str, np.ndarray]:
    """The ``used`` columns of the data rows as float arrays (streamed in chunks of ``chunk`` rows, see
    :func:`chunk_rows` and the module notes; the rows named in errors are the file's).

    Raises
    ------
    DataError
        A row with the wrong number of fields, a non-numeric, NaN, infinite or absurdly large
        value (all such rows counted, the first few named), more data rows than the limit, no
        data rows, or an unreadable file.
    """
    lim = max_rows(limit)
    check_row_limit(path, lim)  # counted before the parse (a long log refused in about a second)
    size = chunk_rows(chunk)
    idx = {c: header.index(c) for c in used}
    cols = {c: array("d") for c in used}
    width = len(header)
    bad = _BadRows()
    n = 0
    for _, rows in iter_chunks(path, size):
        if not rows:
            continue
        n = rows[-1][0]
        if n > lim:
            raise DataError(
                f"more than {lim:,} data rows: files are read into memory and this one is larger than "
                f"the limit (raise it with ${MAX_ROWS_ENV}=N or read_csv(..., max_rows=N), about "
                f"{8 * len(used)} bytes a row, or decimate the log)",
                file=path,
                row=lim + 1,
            )
        for c, vals in _parse_chunk(rows, idx, width, bad).items():
            cols[c].frombytes(vals.tobytes())
    if bad.count:
        reason, column = bad.first  # type: ignore[misc]
        if bad.count > 1:
            named = f" (columns {', '.join(sorted(bad.columns))})" if len(bad.columns) > 1 else ""
            reason = f"{reason} - {bad.count} bad rows{named}: {rows_text(bad.rows, bad.count)}"
        raise DataError(
            reason,
            file=path,
            column=column if len(bad.columns) <= 1 else None,
            rows=bad.rows,
            count=bad.count,
        )
    if n == 0:
        raise DataError("no data rows after the header", file=path)
    return {c: np.frombuffer(a, dtype=float) if len(a) else np.zeros(0) for c, a in cols.items()}
