"""Errors raised for bad input: they name the file, the column and the row."""
from __future__ import annotations


class DataError(ValueError):
    """Bad input data or parameters.

    Parameters
    ----------
    message
        What is wrong, in plain words.
    file, column, row
        Where it is wrong: the file's path, the column's name and the 1-based data row
        (the header is row 0, so data row 1 is line 2 of the file). Any may be ``None``.
    rows
        Every offending 1-based data row when several are refused together (``row`` is the first).
    """

    def __init__(self, message: str, *, file: str | None = None, column: str | None = None,
                 row: int | None = None, rows: tuple[int, ...] | None = None) -> None:
        self.file, self.column, self.row, self.reason = file, column, row, message
        self.rows = rows
        where = []
        if file is not None:
            where.append(f"file {file}")
        if column is not None:
            where.append(f"column '{column}'")
        if row is not None:
            where.append(f"row {row} (line {row + 1})")
        super().__init__(f"{', '.join(where)}: {message}" if where else message)
