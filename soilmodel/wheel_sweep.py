"""Single-wheel rig sweeps: drawbar pull against slip with the load (and sinkage) per row.

CSV (docs/data-formats.md): ``slip,drawbar_pull_N,normal_load_N[,sinkage_m]``. A rig's wheel has no
mass, so the measured normal load is required in every row; the measured sinkage, where given,
sets the wheel's entry angle and makes the Bekker stiffness identifiable from the load balance.
Other columns (repeat numbers, standard deviations, raw sensor channels) are read past.
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass

import numpy as np

from .data import SlipData, read_csv
from .errors import DataError

__all__ = ["WheelSweep", "read_wheel_sweep", "write_wheel_sweep", "SINKAGE_COLUMN", "WHEEL_COLUMNS"]

#: The measured sinkage column, m.
SINKAGE_COLUMN = "sinkage_m"
#: The required columns of a wheel sweep.
WHEEL_COLUMNS = ("slip", "drawbar_pull_N", "normal_load_N")


def _frozen(a) -> np.ndarray:
    arr = np.array(a, dtype=float).reshape(-1)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class WheelSweep:
    """A single-wheel rig sweep.

    Parameters
    ----------
    slip
        Wheel slip i in [0, 1) (driving).
    drawbar_pull
        Net longitudinal force on the wheel, N (+ forward).
    normal_load
        Measured vertical load per row, N (> 0).
    sinkage
        Measured sinkage per row, m (> 0), or ``None``.
    source
        Where the data came from, used in messages.
    dropped
        Rows of the file left out when it was read (``--driving-only``, ``--slip-angle 0``).
    """

    slip: np.ndarray
    drawbar_pull: np.ndarray
    normal_load: np.ndarray
    sinkage: np.ndarray | None = None
    source: str = "<memory>"
    dropped: int = 0

    def __post_init__(self) -> None:
        for name in ("slip", "drawbar_pull", "normal_load", "sinkage"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _frozen(getattr(self, name)))
        # slip range, finiteness and positive loads are checked by SlipData, with file, column and row
        SlipData(slip=self.slip, drawbar_pull=self.drawbar_pull, normal_load=self.normal_load, source=self.source)
        if self.sinkage is not None:
            if self.sinkage.size != self.slip.size:
                raise DataError(
                    f"{SINKAGE_COLUMN} has {self.sinkage.size} values for {self.slip.size} rows",
                    file=self.source,
                    column=SINKAGE_COLUMN,
                )
            bad = np.nonzero(~np.isfinite(self.sinkage) | (self.sinkage <= 0))[0]
            if bad.size:
                raise DataError(
                    f"sinkage must be a finite number > 0 m ({bad.size} row(s): "
                    f"{', '.join(str(int(k) + 1) for k in bad[:10])}), got {self.sinkage[bad[0]]:.6g}",
                    file=self.source,
                    column=SINKAGE_COLUMN,
                    row=int(bad[0]) + 1,
                )

    @property
    def n_samples(self) -> int:
        """Number of rows."""
        return int(self.slip.size)

    @property
    def has_sinkage(self) -> bool:
        """True when the sinkage was measured."""
        return self.sinkage is not None

    def subset(self, index) -> "WheelSweep":
        """The rows selected by ``index`` (slice, integer array or boolean mask)."""
        idx = np.atleast_1d(np.arange(self.n_samples)[index])
        if idx.size == 0:
            raise DataError(f"row selection {index!r} selects no rows", file=self.source)
        return WheelSweep(
            slip=self.slip[idx],
            drawbar_pull=self.drawbar_pull[idx],
            normal_load=self.normal_load[idx],
            sinkage=None if self.sinkage is None else self.sinkage[idx],
            source=f"{self.source} ({idx.size} of {self.n_samples} rows)",
        )

    def columns(self) -> dict[str, np.ndarray]:
        """The sweep as ``{column: values}`` in the CSV contract's names."""
        out = {"slip": self.slip, "drawbar_pull_N": self.drawbar_pull, "normal_load_N": self.normal_load}
        if self.sinkage is not None:
            out[SINKAGE_COLUMN] = self.sinkage
        return out


def _header(path: str) -> list[str] | None:
    """The header of a CSV (None when the file cannot be read: read_csv then says why)."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            for row in csv.reader(fh):
                if any(cell.strip() for cell in row):
                    return [h.strip() for h in row]
    except (OSError, UnicodeDecodeError):
        return None
    return None


def read_wheel_sweep(
    path: str | os.PathLike, *, driving_only: bool = False, slip_angle: float | None = None
) -> WheelSweep:
    """Read a wheel sweep ``slip,drawbar_pull_N,normal_load_N[,sinkage_m]``.

    ``driving_only`` and ``slip_angle`` drop the rows at negative slip or another slip angle
    as :func:`~soiltrack.soilmodel.read_csv` does (refused otherwise); their count is kept in
    :attr:`WheelSweep.dropped`.

    Raises
    ------
    DataError
        For anything :func:`~soiltrack.soilmodel.read_csv` refuses, a file that is not drawbar-pull
        data, a missing ``normal_load_N`` (a rig's load is per row and required) or a bad sinkage;
        the message names the file, the column and the row.
    """
    path = os.fspath(path)
    header = _header(path)
    if header is not None and "tractive_force_N" not in header:
        for col in WHEEL_COLUMNS:
            if col not in header:
                raise DataError(
                    f"missing required column of a wheel sweep (header has {header}; a rig's wheel "
                    "has no mass, so the load is required per row)",
                    file=path,
                    column=col,
                )
    data = read_csv(path, driving_only=driving_only, slip_angle=slip_angle)
    if not isinstance(data, SlipData) or data.measured != "drawbar_pull":
        raise DataError(
            f"a rigid wheel's sweep needs the columns {list(WHEEL_COLUMNS)} (drawbar pull against slip); "
            "this file is " + ("a drive log" if not isinstance(data, SlipData) else "tractive force data"),
            file=path,
            column="drawbar_pull_N",
        )
    if data.normal_load is None:
        raise DataError(
            "missing required column: a rigid wheel on a rig has no mass, so the measured normal load "
            "is required in every row",
            file=path,
            column="normal_load_N",
        )
    sink = data.sinkage
    assert data.drawbar_pull is not None  # (checked above: the column is required)
    return WheelSweep(
        slip=data.slip,
        drawbar_pull=data.drawbar_pull,
        normal_load=data.normal_load,
        sinkage=sink,
        source=path,
        dropped=data.dropped_count,
    )


def write_wheel_sweep(data: WheelSweep, path) -> None:
    """Write a wheel sweep as CSV (full float precision); ``path`` a file path or an open text stream."""
    cols = data.columns()

    def rows(fh) -> None:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(list(cols))
        for row in zip(*cols.values()):
            w.writerow([repr(float(v)) for v in row])

    if hasattr(path, "write"):
        rows(path)
        return
    with open(os.fspath(path), "w", newline="", encoding="utf-8") as fh:
        rows(fh)
