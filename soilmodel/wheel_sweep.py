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

from .columns import plan_columns
from .csvread import bad_rows_error, read_columns, read_header
from .data import KNOWN_COLUMNS, bad_rows, raise_rows
from .errors import DataError

__all__ = [
    "WheelSweep",
    "read_wheel_sweep",
    "write_wheel_sweep",
    "check_sweep_for_wheel",
    "pull_sign_problem",
    "SINKAGE_COLUMN",
    "WHEEL_COLUMNS",
    "SIGN_MIN_ROWS",
    "TORQUE_COLUMN",
    "TORQUE_STD_COLUMN",
    "WHEEL_KNOWN_COLUMNS",
]

#: The measured sinkage column, m.
SINKAGE_COLUMN = "sinkage_m"
#: The required columns of a wheel sweep.
WHEEL_COLUMNS = ("slip", "drawbar_pull_N", "normal_load_N")
#: The wheel's measured torque and its standard deviation (optional; a fitted channel).
TORQUE_COLUMN, TORQUE_STD_COLUMN = "wheel_torque_Nm", "wheel_torque_std_N_m"
#: Fewest driving rows (slip > 0) on which the sign of the pull is judged.
SIGN_MIN_ROWS = 3
#: Rank correlation of pull and slip below which a sweep's pull runs against its slip.
SIGN_RANK_CORRELATION = -0.5


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
    torque
        Measured wheel torque per row, N m (``wheel_torque_Nm``; + driving), or ``None``.
    torque_std
        The torque reading's standard deviation per row, N m (``wheel_torque_std_N_m``, > 0): a
        relative weight of the torque channel's rows, or ``None``.
    """

    slip: np.ndarray
    drawbar_pull: np.ndarray
    normal_load: np.ndarray
    sinkage: np.ndarray | None = None
    source: str = "<memory>"
    dropped: int = 0
    torque: np.ndarray | None = None
    torque_std: np.ndarray | None = None

    def __post_init__(self) -> None:
        for name in ("slip", "drawbar_pull", "normal_load", "sinkage", "torque", "torque_std"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _frozen(getattr(self, name)))
        cols = {"slip": self.slip, "drawbar_pull_N": self.drawbar_pull, "normal_load_N": self.normal_load}
        if len({v.size for v in cols.values()}) != 1:
            raise DataError(f"columns differ in length: { {k: v.size for k, v in cols.items()} }", file=self.source)
        for col, v in cols.items():
            if not np.all(np.isfinite(v)):
                raise bad_rows_error(~np.isfinite(v), self.source, col, "not a finite number")
        out = (self.slip < -1) | (self.slip >= 1)
        if out.any():
            raise bad_rows_error(
                out, self.source, "slip", "slip must lie in [-1, 1) (-1: a locked wheel, < 0: skid, > 0: driving)"
            )
        if not np.all(self.normal_load > 0):
            raise bad_rows_error(~(self.normal_load > 0), self.source, "normal_load_N", "normal load must be > 0 N")
        self._check_torque()
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

    def _check_torque(self) -> None:
        if self.torque_std is not None and self.torque is None:
            raise DataError(f"{TORQUE_STD_COLUMN} without {TORQUE_COLUMN}", file=self.source, column=TORQUE_STD_COLUMN)
        for col, v, positive in ((TORQUE_COLUMN, self.torque, False), (TORQUE_STD_COLUMN, self.torque_std, True)):
            if v is None:
                continue
            if v.size != self.slip.size:
                raise DataError(f"{col} has {v.size} values for {self.slip.size} rows", file=self.source, column=col)
            bad = ~np.isfinite(v) | ((v <= 0) if positive else False)
            if np.any(bad):
                raise bad_rows_error(bad, self.source, col, "must be a finite number" + (" > 0" if positive else ""))

    @property
    def n_samples(self) -> int:
        """Number of rows."""
        return int(self.slip.size)

    @property
    def has_torque(self) -> bool:
        """True when the wheel's torque was measured."""
        return self.torque is not None

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
            torque=None if self.torque is None else self.torque[idx],
            torque_std=None if self.torque_std is None else self.torque_std[idx],
        )

    def columns(self) -> dict[str, np.ndarray]:
        """The sweep as ``{column: values}`` in the CSV contract's names."""
        out = {"slip": self.slip, "drawbar_pull_N": self.drawbar_pull, "normal_load_N": self.normal_load}
        if self.sinkage is not None:
            out[SINKAGE_COLUMN] = self.sinkage
        if self.torque is not None:
            out[TORQUE_COLUMN] = self.torque
        if self.torque_std is not None:
            out[TORQUE_STD_COLUMN] = self.torque_std
        return out


#: Every column a wheel sweep may have (the names a column mapping may target).
WHEEL_KNOWN_COLUMNS = (*KNOWN_COLUMNS, TORQUE_COLUMN, TORQUE_STD_COLUMN)


def _header(path: str, columns: dict[str, str] | None) -> list[str] | None:
    """The header of a CSV in the library's names (None when the file cannot be read: read_csv then says why)."""
    try:
        head = read_header(path)
    except DataError:
        return None
    return list(plan_columns(head, known=WHEEL_KNOWN_COLUMNS, mapping=columns, source=path).header)


def read_wheel_sweep(
    path: str | os.PathLike,
    *,
    driving_only: bool = False,
    slip_angle: float | None = None,
    columns: dict[str, str] | None = None,
) -> WheelSweep:
    """Read a wheel sweep ``slip,drawbar_pull_N,normal_load_N[,sinkage_m]``.

    Rows at negative slip (skid, down to -1: a locked wheel) are kept and fitted by the skid model
    (:mod:`.wheel`); ``driving_only`` drops them. ``slip_angle=0`` keeps only the rows at slip angle
    0 (other slip angles are refused otherwise). The count of rows dropped is kept in
    :attr:`WheelSweep.dropped`. ``columns`` maps the file's columns onto the library's names and
    unit suffixes convert (``sinkage_mm``: :mod:`soiltrack.soilmodel.columns`).

    Raises
    ------
    DataError
        An unreadable file or value (as :func:`~soiltrack.soilmodel.read_csv`), a file that is not drawbar-pull
        data, slip outside [-1, 1), a missing ``normal_load_N`` (a rig's load is per row and required) or a bad sinkage;
        the message names the file, the column and the row.
    """
    path = os.fspath(path)
    header = _header(path, columns)
    if header is not None and "tractive_force_N" not in header:
        for col in WHEEL_COLUMNS:
            if col not in header:
                raise DataError(
                    f"missing required column of a wheel sweep (header has {header}; a rig's wheel "
                    "has no mass, so the load is required per row)",
                    file=path,
                    column=col,
                )
    plan = plan_columns(read_header(path), known=WHEEL_KNOWN_COLUMNS, mapping=columns, source=path)
    header = list(plan.header)
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise DataError(f"duplicate column(s) {dup}", file=path, column=dup[0])
    if "tractive_force_N" in header:
        raise DataError(
            f"a rigid wheel's sweep needs the columns {list(WHEEL_COLUMNS)} (drawbar pull against slip); "
            "this file is tractive force data",
            file=path,
            column="drawbar_pull_N",
        )
    used = [
        c for c in (*WHEEL_COLUMNS, SINKAGE_COLUMN, "slip_angle_deg", TORQUE_COLUMN, TORQUE_STD_COLUMN) if c in header
    ]
    data = plan.apply(read_columns(path, header, used))
    keep, dropped = _kept_rows(data, path, driving_only, slip_angle)
    return WheelSweep(
        slip=data["slip"][keep],
        drawbar_pull=data["drawbar_pull_N"][keep],
        normal_load=data["normal_load_N"][keep],
        sinkage=data[SINKAGE_COLUMN][keep] if SINKAGE_COLUMN in data else None,
        source=path,
        dropped=dropped,
        torque=data[TORQUE_COLUMN][keep] if TORQUE_COLUMN in data else None,
        torque_std=data[TORQUE_STD_COLUMN][keep] if TORQUE_STD_COLUMN in data else None,
    )


def _kept_rows(data: dict, path: str, driving_only: bool, slip_angle: float | None) -> tuple[np.ndarray, int]:
    """Rows kept by ``--slip-angle 0`` and ``--driving-only`` (a slip angle other than 0 refused without it)."""
    keep = np.ones(data["slip"].size, dtype=bool)
    angle = data.get("slip_angle_deg")
    if slip_angle is not None:
        if slip_angle != 0:
            raise DataError(
                f"--slip-angle {slip_angle:g}: the model is straight-line; only 0 can be kept",
                file=path,
                column="slip_angle_deg",
            )
        if angle is None:
            raise DataError("--slip-angle given but the file has no slip_angle_deg column", file=path)
        keep &= angle == 0
    elif angle is not None:
        raise_rows(
            [
                q
                for q in [
                    bad_rows(
                        angle != 0,
                        "at a non-zero slip angle (combined slip), outside the straight-line model",
                        "slip_angle_deg",
                        "--slip-angle 0 (read_wheel_sweep(..., slip_angle=0))",
                    )
                ]
                if q is not None
            ],
            path,
        )
    if driving_only:
        keep &= data["slip"] >= 0
    if not keep.any():
        raise DataError(f"no rows left after dropping {keep.size} (--driving-only, --slip-angle)", file=path)
    return keep, int(keep.size - np.count_nonzero(keep))


def _ranks(x: np.ndarray) -> np.ndarray:
    """Ranks of ``x`` (ties get their mean rank)."""
    order = np.argsort(x, kind="mergesort")
    r = np.empty(x.size)
    r[order] = np.arange(x.size, dtype=float)
    for v in np.unique(x):
        tie = x == v
        r[tie] = r[tie].mean()
    return r


def _rank_correlation(a: np.ndarray, b: np.ndarray) -> float:
    ra, rb = _ranks(a) - (a.size - 1) / 2, _ranks(b) - (b.size - 1) / 2
    den = float(np.sqrt((ra @ ra) * (rb @ rb)))
    return float(ra @ rb) / den if den > 0 else 0.0


def pull_sign_problem(slip: np.ndarray, pull: np.ndarray) -> str | None:
    """Why the pull's sign contradicts the slip across a sweep, in words, or ``None``.

    The pull of a wheel (or track) rises with its slip: negative when braked or locked (slip < 0),
    positive and rising at the start of driving. A sweep contradicts that when its pull falls as
    the slip rises (Spearman rank correlation below :data:`SIGN_RANK_CORRELATION`) and either
    it has skid and driving rows, or every driving row pulls backwards (at least
    :data:`SIGN_MIN_ROWS` of them): the sign of the pull (or of the slip) is flipped.
    """
    slip, pull = np.asarray(slip, dtype=float), np.asarray(pull, dtype=float)
    drive = slip > 0
    if np.count_nonzero(drive) < SIGN_MIN_ROWS or slip.size < SIGN_MIN_ROWS + 1:
        return None
    both = bool(np.any(slip < 0))
    rho = _rank_correlation(slip, pull)
    if rho >= SIGN_RANK_CORRELATION or not (both or np.all(pull[drive] < 0)):
        return None
    where = (
        "from skid to driving" if both else f"and is negative at all {np.count_nonzero(drive)} driving rows (slip > 0)"
    )
    return (
        f"the drawbar pull falls as the slip rises (rank correlation {rho:.2f}) {where}: its sign (or the "
        "slip's) looks flipped; drawbar_pull_N is + forward (a driving wheel pulls) and the slip is > 0 when "
        "driving: negate the column in the file"
    )


def check_sweep_for_wheel(data: WheelSweep, radius: float) -> None:
    """Refuse a sweep that cannot be this wheel's: sinkage beyond the radius, a pull against the slip.

    Raises
    ------
    DataError
        Rows whose sinkage exceeds the wheel's radius (named; with the hint that the values look
        like millimetres when they do), or a pull whose sign contradicts the slip
        (:func:`pull_sign_problem`).
    """
    if data.sinkage is not None:
        deep = data.sinkage > radius
        if deep.any():
            idx = np.nonzero(deep)[0]
            rows = [int(k) + 1 for k in idx]
            z = data.sinkage
            mm = bool(np.median(z) / 1e3 < radius)
            hint = (
                f"; the values ({np.min(z):.3g} to {np.max(z):.3g}) look like millimetres: name the column "
                f"sinkage_mm (it is then converted) or map it with --columns sinkage_m=NAME_mm"
                if mm and np.median(z) > 1.0
                else "; the Wong-Reece arc ends at the axle"
            )
            shown = ", ".join(map(str, rows[:20])) + (f", ... ({len(rows)} rows)" if len(rows) > 20 else "")
            raise DataError(
                f"{len(rows)} of {z.size} rows have a sinkage larger than the wheel's radius {radius:g} m "
                f"(rows {shown}; largest {np.max(z):.4g} m){hint}",
                file=data.source,
                column=SINKAGE_COLUMN,
                rows=rows,
            )
    why = pull_sign_problem(data.slip, data.drawbar_pull)
    if why is not None:
        raise DataError(why, file=data.source, column="drawbar_pull_N")


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
