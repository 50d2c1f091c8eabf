"""Errors raised for bad input: they name the file, the column (or field) and the rows."""

from __future__ import annotations

__all__ = ["DataError", "SHOWN_ROWS", "rows_text"]

#: How many bad rows a message names one by one (the rest are counted).
SHOWN_ROWS = 20


def rows_text(rows, count: int | None = None) -> str:
    """``"rows 3, 7, 9"``, or with more than :data:`SHOWN_ROWS` (or ``count`` larger than given) the first
    ones
    and the count: ``"rows 3, 7, ... (the first 20 of 312)"``."""
    rows = [int(r) for r in rows]
    n = len(rows) if count is None else int(count)
    if n <= SHOWN_ROWS and n == len(rows):
        return ("row " if n == 1 else "rows ") + ", ".join(map(str, rows))
    shown = rows[:SHOWN_ROWS]
    return f"rows {', '.join(map(str, shown))}, ... (the first {len(shown)} of {n})"


class DataError(ValueError):
    """Bad input data or parameters.

    Parameters
    ----------
    message
        What is wrong, in plain words.
    file, column, row
        Where it is wrong: the file's path, the column's (or JSON field's, or argument's) name
        and the 1-based data row (the header is row 0, so data row 1 is line 2 of the file).
        Any may be ``None``.
    rows
        The offending 1-based data rows when several are refused together (every one, or the
        first few when ``count`` says there are more); ``row`` is the first.
    count
        How many rows are bad in all (default: ``len(rows)``, or 1 with only ``row``).

    Attributes
    ----------
    file, column, row, rows, count, reason
        The structured fields (``reason`` is ``message``); ``field`` is ``column``.
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        column: str | None = None,
        row: int | None = None,
        rows: tuple[int, ...] | list[int] | None = None,
        count: int | None = None,
    ) -> None:
        self.rows = tuple(int(r) for r in rows) if rows is not None else None
        if row is None and self.rows:
            row = self.rows[0]
        self.file, self.column, self.row, self.reason = file, column, row, message
        self.count = int(count) if count is not None else (len(self.rows) if self.rows else int(row is not None))
        where = []
        if file is not None:
            where.append(f"file {file}")
        if column is not None:
            where.append(f"column '{column}'")
        if row is not None:
            where.append(f"row {row} (line {row + 1})")
        super().__init__(f"{', '.join(where)}: {message}" if where else message)

    @property
    def field(self) -> str | None:
        """The JSON field or argument named (the same as :attr:`column`)."""
        return self.column
