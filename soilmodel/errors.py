"""Errors raised for bad input: they name the file, the column (or field) and the rows."""
from __future__ import annotations

__all__ = ["DataError", "SHOWN_ROWS"]

#: How many bad rows a message names one by one (the rest are counted).
SHOWN_ROWS = 5


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
    rows, count
        When several rows are bad: the first few of them (1-based, at most :data:`SHOWN_ROWS`
        are named in the message) and how many there are in all. ``row`` is then the first.

    Attributes
    ----------
    file, column, row, rows, count, reason
        The structured fields (``reason`` is ``message``); ``field`` is ``column``.
    """

    def __init__(self, message: str, *, file: str | None = None, column: str | None = None,
                 row: int | None = None, rows: tuple[int, ...] | list[int] | None = None,
                 count: int | None = None) -> None:
        rows_t = tuple(int(r) for r in rows) if rows is not None else ((row,) if row is not None else ())
        if row is None and rows_t:
            row = rows_t[0]
        self.file, self.column, self.row, self.reason = file, column, row, message
        self.rows = rows_t
        self.count = int(count) if count is not None else len(rows_t)
        where = []
        if file is not None:
            where.append(f"file {file}")
        if column is not None:
            where.append(f"column '{column}'")
        if self.count > 1 and rows_t:
            shown = ", ".join(str(r) for r in rows_t[:SHOWN_ROWS])
            more = self.count - min(len(rows_t), SHOWN_ROWS)
            where.append(f"{self.count} bad rows: {shown}" + (f" and {more} more" if more > 0 else ""))
        elif row is not None:
            where.append(f"row {row} (line {row + 1})")
        super().__init__(f"{', '.join(where)}: {message}" if where else message)

    @property
    def field(self) -> str | None:
        """The JSON field or argument named (the same as :attr:`column`)."""
        return self.column
