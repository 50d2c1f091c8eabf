"""Measured data containers and CSV I/O (docs/data-formats.md).

Two kinds of file, told apart by their columns:

- tractive force-slip data: ``slip,tractive_force_N`` and optionally ``normal_load_N``;
- drawbar-pull data: ``slip,drawbar_pull_N`` and optionally ``normal_load_N`` (drawbar pull =
  thrust - motion resistance, what a test rig measures);
- both slip kinds, as rigs record them, optionally add per row ``sinkage_m``, the reading's
  standard deviation (``tractive_force_std_N`` or ``drawbar_pull_std_N``, a weight) and
  ``slip_angle_deg``; rows at negative slip or a non-zero slip angle are outside the
  straight driving model: refused with their count and rows unless dropped explicitly
  (``read_csv(path, driving_only=True, slip_angle=0.0)``), the count kept in
  :attr:`SlipData.dropped`;
- drive logs: ``time_s,sprocket_torque_Nm,sprocket_speed_rad_s,vehicle_speed_m_s`` and
  optionally ``vehicle_accel_m_s2``;
- two-track drive logs: the same with ``sprocket_torque_left_Nm, sprocket_torque_right_Nm,
  sprocket_speed_left_rad_s, sprocket_speed_right_rad_s`` (and optionally ``yaw_rate_rad_s``)
  instead of the combined torque and speed: summed torque, mean speed, turning samples marked
  (:mod:`.tracks`);
- bevameter shear tests: ``normal_pressure_Pa,shear_displacement_m,shear_stress_Pa``;
- bevameter plate sinkage tests: ``plate_width_m,pressure_Pa,sinkage_m``.

Bad input is refused with a :class:`~soiltrack.soilmodel.errors.DataError` that names the
file, the column and the data row (row 1 is the first line after the header).
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass
from typing import cast

import numpy as np

from .columns import ColumnPlan, plan_columns
from .csvread import MAX_ABS_VALUE, bad_rows_error, read_columns, read_header
from .errors import DataError
from .tracks import TWO_TRACK_COLUMNS, YAW_COLUMN, combine_tracks, turning_mask

SLIP_COLUMNS = ("slip", "tractive_force_N")
DRAWBAR_COLUMNS = ("slip", "drawbar_pull_N")
SLIP_OPTIONAL = ("normal_load_N", "sinkage_m", "tractive_force_std_N", "drawbar_pull_std_N", "slip_angle_deg")
#: What a slip sweep measured -> its CSV column.
MEASURED_COLUMNS = {"tractive_force": "tractive_force_N", "drawbar_pull": "drawbar_pull_N"}
#: What a slip sweep measured -> the column of its per-row standard deviation.
STD_COLUMNS = {"tractive_force": "tractive_force_std_N", "drawbar_pull": "drawbar_pull_std_N"}
#: Rows named in full in a refusal up to this many; beyond it the count and the first ones.
MAX_ROWS_NAMED = 20
DRIVE_COLUMNS = ("time_s", "sprocket_torque_Nm", "sprocket_speed_rad_s", "vehicle_speed_m_s")
DRIVE_OPTIONAL = ("vehicle_accel_m_s2",)
SHEAR_COLUMNS: tuple[str, ...] = ("normal_pressure_Pa", "shear_displacement_m", "shear_stress_Pa")
PLATE_COLUMNS: tuple[str, ...] = ("plate_width_m", "pressure_Pa", "sinkage_m")
NO_COLUMNS: tuple[str, ...] = ()
#: Every column :func:`read_csv` reads (the names a column mapping may target, :mod:`.columns`).
KNOWN_COLUMNS: tuple[str, ...] = tuple(
    dict.fromkeys(
        (*SLIP_COLUMNS, *DRAWBAR_COLUMNS, *SLIP_OPTIONAL, *DRIVE_COLUMNS, *DRIVE_OPTIONAL, *SHEAR_COLUMNS)
        + (*PLATE_COLUMNS, *TWO_TRACK_COLUMNS, YAW_COLUMN)
    )
)


def _frozen(a) -> np.ndarray:
    arr = np.array(a, dtype=float).reshape(-1)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class SlipData:
    """Slip-sweep measurements: tractive force or drawbar pull against slip.

    Exactly one of ``tractive_force`` and ``drawbar_pull`` is given; :attr:`measured` says which.

    Parameters
    ----------
    slip
        Track slip i in [0, 1).
    tractive_force
        Tractive force of both tracks, N (``None`` for drawbar-pull data).
    normal_load
        Normal load W per sample, N, or ``None`` (then the vehicle's weight is used).
        Samples at two or more loads make c and phi separable.
    source
        Where the data came from (file path or label), used in messages.
    drawbar_pull
        Drawbar pull ``thrust - motion resistance`` of both tracks, N (``None`` for tractive
        force data).
    sinkage
        Measured sinkage per row, m (``sinkage_m``), or ``None``.
    force_std
        Standard deviation of each reading of the measured force, N (``tractive_force_std_N`` or
        ``drawbar_pull_std_N``), or ``None``; fits weigh each row by ``1 / std^2``.
    slip_angle
        Slip angle per row, deg (``slip_angle_deg``), or ``None``; must be 0 (the model is
        straight-line).
    dropped
        Rows left out when the data were read, as ``((reason, option, rows), ...)`` with the
        1-based rows of the file (see :func:`read_csv`).
    """

    slip: np.ndarray
    tractive_force: np.ndarray | None = None
    normal_load: np.ndarray | None = None
    source: str = "<memory>"
    drawbar_pull: np.ndarray | None = None
    sinkage: np.ndarray | None = None
    force_std: np.ndarray | None = None
    slip_angle: np.ndarray | None = None
    dropped: tuple = ()

    def __post_init__(self) -> None:
        if (self.tractive_force is None) == (self.drawbar_pull is None):
            raise DataError("give exactly one of tractive_force and drawbar_pull", file=self.source)
        object.__setattr__(self, "slip", _frozen(self.slip))
        for name in ("tractive_force", "drawbar_pull", "normal_load", "sinkage", "force_std", "slip_angle"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _frozen(getattr(self, name)))
        cols = self.columns()
        _check_lengths(cols, self.source)
        _check_finite(cols, self.source)
        problems = [
            bad_rows(
                self.slip < 0,
                "at negative slip (skid: braking, a locked wheel), outside the driving model (slip in [0, 1))",
                "slip",
                "--driving-only (read_csv(..., driving_only=True))",
            )
        ]
        if self.slip_angle is not None:
            problems.append(
                bad_rows(
                    self.slip_angle != 0,
                    "at a non-zero slip angle (combined slip), outside the straight-line model",
                    "slip_angle_deg",
                    "--slip-angle 0 (read_csv(..., slip_angle=0))",
                )
            )
        raise_rows([q for q in problems if q is not None], self.source)
        _check_range(self.slip, "slip", self.source, lo=0.0, hi=1.0, hi_open=True, what="slip must lie in [0, 1)")
        if self.normal_load is not None:
            _check_range(
                self.normal_load, "normal_load_N", self.source, lo=0.0, lo_open=True, what="normal load must be > 0 N"
            )
        if self.sinkage is not None:
            _check_range(self.sinkage, "sinkage_m", self.source, lo=0.0, what="sinkage must be >= 0 m")
        if self.force_std is not None:
            raise_rows(
                [
                    q
                    for q in [
                        bad_rows(
                            self.force_std <= 0,
                            "with a standard deviation <= 0 (a reading's weight is 1 / std^2)",
                            STD_COLUMNS[self.measured],
                            None,
                        )
                    ]
                    if q
                ],
                self.source,
            )

    def columns(self) -> dict[str, np.ndarray]:
        """The sweep as ``{column name: values}`` in the CSV contract's names (given columns only)."""
        cols = {"slip": self.slip, self.channel: self.values}
        for name, col in (
            ("normal_load", "normal_load_N"),
            ("sinkage", "sinkage_m"),
            ("force_std", STD_COLUMNS[self.measured]),
            ("slip_angle", "slip_angle_deg"),
        ):
            if getattr(self, name) is not None:
                cols[col] = getattr(self, name)
        return cols

    @property
    def dropped_count(self) -> int:
        """Number of rows left out when the data were read."""
        return sum(len(rows) for _, _, rows in self.dropped)

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.slip.size)

    @property
    def measured(self) -> str:
        """``"tractive_force"`` or ``"drawbar_pull"``: what the force column holds."""
        return "tractive_force" if self.tractive_force is not None else "drawbar_pull"

    @property
    def channel(self) -> str:
        """CSV column of the measured force: ``"tractive_force_N"`` or ``"drawbar_pull_N"``."""
        return MEASURED_COLUMNS[self.measured]

    @property
    def values(self) -> np.ndarray:
        """The measured force, N (tractive force or drawbar pull, see :attr:`measured`)."""
        # exactly one of the two is given (checked on construction)
        return cast(np.ndarray, self.tractive_force if self.tractive_force is not None else self.drawbar_pull)

    def subset(self, index) -> "SlipData":
        """The rows selected by ``index`` (slice, integer array or boolean mask), same type.

        The source is annotated with the data rows taken (row 1 = first data row).
        """
        idx = _rows(index, self.n_samples, self.source)
        kw = {
            name: None if getattr(self, name) is None else getattr(self, name)[idx]
            for name in ("tractive_force", "drawbar_pull", "normal_load", "sinkage", "force_std", "slip_angle")
        }
        return SlipData(slip=self.slip[idx], source=_annotate(self.source, idx), dropped=self.dropped, **kw)

    def loads(self, default: float | None = None) -> np.ndarray:
        """Per-sample normal load, N (``default`` where the data carry none)."""
        if self.normal_load is not None:
            return self.normal_load
        if default is None:
            raise DataError("the data carry no normal_load_N column; give the vehicle's weight", file=self.source)
        out = np.empty(self.slip.shape)
        out.fill(float(default))  # np.full without its Python wrapper
        return out

    @property
    def distinct_loads(self) -> np.ndarray:
        """Distinct normal loads in the data (empty when the data carry none)."""
        if self.normal_load is None:
            return np.array([])
        from .ridge import distinct_loads

        return distinct_loads(self.normal_load)


@dataclass(frozen=True, eq=False)
class DriveLog:
    """A straight-line drive log: sprocket torque and speed, vehicle speed, optional IMU.

    Parameters
    ----------
    time
        Time stamps, s, strictly increasing.
    sprocket_torque
        Sprocket torque of both tracks M_s, N m.
    sprocket_speed
        Sprocket angular speed w, rad/s (encoder).
    vehicle_speed
        Vehicle speed v, m/s (e.g. GNSS).
    vehicle_accel
        Vehicle acceleration dv/dt, m/s^2 (IMU), or ``None``.
    source
        Where the data came from, used in messages.
    turning
        Boolean mask of the samples where the vehicle turns (a two-track log, see
        :mod:`.tracks`), or ``None`` (a straight-line log). Turning samples stay in the log
        (the sprocket equation needs consecutive samples) and are left out of the straight-line
        model by every drive-log path, which reports their count.
    """

    time: np.ndarray
    sprocket_torque: np.ndarray
    sprocket_speed: np.ndarray
    vehicle_speed: np.ndarray
    vehicle_accel: np.ndarray | None = None
    source: str = "<memory>"
    turning: np.ndarray | None = None

    def __post_init__(self) -> None:
        for name in ("time", "sprocket_torque", "sprocket_speed", "vehicle_speed", "vehicle_accel"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _frozen(getattr(self, name)))
        cols = dict(zip(DRIVE_COLUMNS, (self.time, self.sprocket_torque, self.sprocket_speed, self.vehicle_speed)))
        if self.vehicle_accel is not None:
            cols["vehicle_accel_m_s2"] = self.vehicle_accel
        _check_lengths(cols, self.source)
        _check_finite(cols, self.source)
        if self.turning is not None:
            turning = np.array(self.turning, dtype=bool).reshape(-1)
            turning.setflags(write=False)
            object.__setattr__(self, "turning", turning)
            _check_lengths({"time_s": self.time, "turning": turning}, self.source)
        _check_increasing(self.time, "time_s", self.source)

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.time.size)

    @property
    def n_turning(self) -> int:
        """Number of turning samples (0 for a straight-line log)."""
        return 0 if self.turning is None else int(np.count_nonzero(self.turning))

    def subset(self, index) -> "DriveLog":
        """The rows selected by ``index`` (slice, integer array or boolean mask), same type.

        The source is annotated with the data rows taken (row 1 = first data row); the rows
        must stay in time order.
        """
        idx = _rows(index, self.n_samples, self.source)
        return DriveLog(
            time=self.time[idx],
            sprocket_torque=self.sprocket_torque[idx],
            sprocket_speed=self.sprocket_speed[idx],
            vehicle_speed=self.vehicle_speed[idx],
            vehicle_accel=None if self.vehicle_accel is None else self.vehicle_accel[idx],
            source=_annotate(self.source, idx),
            turning=None if self.turning is None else self.turning[idx],
        )

    def columns(self) -> dict[str, np.ndarray]:
        """The log as ``{column name: values}`` in the CSV contract's names."""
        out = dict(zip(DRIVE_COLUMNS, (self.time, self.sprocket_torque, self.sprocket_speed, self.vehicle_speed)))
        if self.vehicle_accel is not None:
            out["vehicle_accel_m_s2"] = self.vehicle_accel
        return out


@dataclass(frozen=True, eq=False)
class ShearTest:
    """A bevameter shear test (shear ring or shear box): shear stress against shear displacement.

    Parameters
    ----------
    normal_pressure
        Normal pressure sigma on the shear surface per row, Pa (> 0). Rows at two or more
        pressures separate cohesion and friction; at one pressure only ``c + sigma tan(phi)``.
    shear_displacement
        Shear displacement j, m (>= 0).
    shear_stress
        Measured shear stress tau, Pa.
    source
        Where the data came from, used in messages.
    """

    normal_pressure: np.ndarray
    shear_displacement: np.ndarray
    shear_stress: np.ndarray
    source: str = "<memory>"

    def __post_init__(self) -> None:
        for name in ("normal_pressure", "shear_displacement", "shear_stress"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        cols = dict(zip(SHEAR_COLUMNS, (self.normal_pressure, self.shear_displacement, self.shear_stress)))
        _check_lengths(cols, self.source)
        _check_finite(cols, self.source)
        _check_range(
            self.normal_pressure,
            "normal_pressure_Pa",
            self.source,
            lo=0.0,
            lo_open=True,
            what="normal pressure must be > 0 Pa",
        )
        _check_range(
            self.shear_displacement,
            "shear_displacement_m",
            self.source,
            lo=0.0,
            what="shear displacement must be >= 0 m",
        )

    @property
    def n_samples(self) -> int:
        """Number of rows."""
        return int(self.shear_stress.size)

    def columns(self) -> dict[str, np.ndarray]:
        """The test as ``{column name: values}`` in the CSV contract's names."""
        return dict(zip(SHEAR_COLUMNS, (self.normal_pressure, self.shear_displacement, self.shear_stress)))


@dataclass(frozen=True, eq=False)
class PlateTest:
    """A bevameter plate sinkage test: pressure against sinkage for one or more plate widths.

    Parameters
    ----------
    plate_width
        Plate width b per row (smaller dimension; the radius of a circular plate), m (> 0).
        Two or more widths separate k_c and k_phi; one width gives only ``k_c / b + k_phi``.
    pressure
        Plate pressure p, Pa (a load cell's offset may make readings near zero sinkage negative).
    sinkage
        Sinkage z, m (>= 0).
    source
        Where the data came from, used in messages.
    """

    plate_width: np.ndarray
    pressure: np.ndarray
    sinkage: np.ndarray
    source: str = "<memory>"

    def __post_init__(self) -> None:
        for name in ("plate_width", "pressure", "sinkage"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        cols = dict(zip(PLATE_COLUMNS, (self.plate_width, self.pressure, self.sinkage)))
        _check_lengths(cols, self.source)
        _check_finite(cols, self.source)
        _check_range(
            self.plate_width, "plate_width_m", self.source, lo=0.0, lo_open=True, what="plate width must be > 0 m"
        )
        _check_range(self.sinkage, "sinkage_m", self.source, lo=0.0, what="sinkage must be >= 0 m")

    @property
    def n_samples(self) -> int:
        """Number of rows."""
        return int(self.pressure.size)

    def columns(self) -> dict[str, np.ndarray]:
        """The test as ``{column name: values}`` in the CSV contract's names."""
        return dict(zip(PLATE_COLUMNS, (self.plate_width, self.pressure, self.sinkage)))


def name_rows(rows) -> str:
    """``"rows 3, 7, 9"`` for all rows up to :data:`MAX_ROWS_NAMED`, else the count and the first ones."""
    rows = [int(r) for r in rows]
    if len(rows) <= MAX_ROWS_NAMED:
        return ("row " if len(rows) == 1 else "rows ") + ", ".join(map(str, rows))
    return f"rows {', '.join(map(str, rows[:MAX_ROWS_NAMED]))}, ... (the first {MAX_ROWS_NAMED} of {len(rows)})"


def bad_rows(bad: np.ndarray, what: str, column: str, option: str | None) -> tuple[str, str, tuple] | None:
    """``(message, column, rows)`` naming the count and rows where ``bad`` holds, or ``None`` if none.

    ``option`` names what drops them explicitly (said in the message), or ``None``.
    """
    idx = np.nonzero(bad)[0]
    if not idx.size:
        return None
    rows = tuple(int(k) + 1 for k in idx)
    drop = f"; drop them explicitly with {option}" if option else ""
    return f"{len(rows)} of {bad.size} rows {what}: {name_rows(rows)}{drop}", column, rows


def raise_rows(problems: list, source: str) -> None:
    """Raise one DataError for all of :func:`bad_rows`' problems (none: nothing happens).

    Its ``column`` and ``row`` are the first problem's; ``rows`` all the rows named, sorted.
    """
    if not problems:
        return
    rows = tuple(sorted({r for _, _, rr in problems for r in rr}))
    raise DataError(
        "; and ".join(m for m, _, _ in problems), file=source, column=problems[0][1], row=problems[0][2][0], rows=rows
    )


def _rows(index, n: int, source: str) -> np.ndarray:
    """Integer row indices (0-based) selected by ``index``; DataError when empty or out of range."""
    try:
        idx = np.arange(n)[index]
    except (IndexError, TypeError, ValueError) as e:
        raise DataError(f"bad row selection {index!r}: {e}", file=source) from None
    idx = np.atleast_1d(idx)
    if idx.size == 0:
        raise DataError(f"row selection {index!r} selects no rows", file=source)
    return idx


def _annotate(source: str, idx: np.ndarray) -> str:
    a, b = int(idx[0]) + 1, int(idx[-1]) + 1
    if idx.size == b - a + 1 and np.all(np.diff(idx) == 1):
        return f"{source} rows {a}-{b}"
    return f"{source} rows {a}-{b} ({idx.size} selected)"


def _check_lengths(cols: dict, source: str) -> None:
    n = {k: v.size for k, v in cols.items()}
    if len(set(n.values())) > 1:
        raise DataError(f"columns differ in length: {n}", file=source)


def _check_finite(cols: dict, source: str) -> None:
    """Every value finite and within MAX_ABS_VALUE; all bad rows of the first bad column counted."""
    for name, values in cols.items():
        if values.size == 0:
            continue
        nonfinite = ~np.isfinite(values)
        if nonfinite.any():
            k = int(np.argmax(nonfinite))
            raise bad_rows_error(nonfinite, source, name, f"value {values[k]} is not a finite number")
        huge = np.abs(values) > MAX_ABS_VALUE
        if huge.any():
            k = int(np.argmax(huge))
            raise bad_rows_error(
                huge,
                source,
                name,
                f"value {values[k]:.6g} is beyond any physical value in "
                f"these data (|x| <= {MAX_ABS_VALUE:g} in SI units)",
            )


def _check_increasing(values: np.ndarray, column: str, source: str) -> None:
    """Strictly increasing values; every row that does not increase counted (the first few named)."""
    bad = np.zeros(values.shape, dtype=bool)
    bad[1:] = np.diff(values) <= 0
    if bad.any():
        k = int(np.argmax(bad))
        raise bad_rows_error(
            bad, source, column, f"time must be strictly increasing ({values[k - 1]:.6g} then {values[k]:.6g})"
        )


def _check_range(values, column, source, *, lo=None, hi=None, lo_open=False, hi_open=False, what="") -> None:
    bad = np.zeros(values.shape, dtype=bool)
    if lo is not None:
        bad |= (values <= lo) if lo_open else (values < lo)
    if hi is not None:
        bad |= (values >= hi) if hi_open else (values > hi)
    if bad.any():
        k = int(np.argmax(bad))
        raise bad_rows_error(bad, source, column, f"{what}, got {values[k]:.6g}")


def read_csv(
    path: str | os.PathLike,
    *,
    driving_only: bool = False,
    slip_angle: float | None = None,
    max_rows: int | None = None,
    columns: dict[str, str] | None = None,
) -> SlipData | DriveLog | ShearTest | PlateTest:
    """Read a slip sweep, a drive log or a bevameter test (recognised by the columns).

    Parameters
    ----------
    path
        The CSV file.
    driving_only
        Slip sweeps: drop the rows at negative slip (skid) instead of refusing them.
    slip_angle
        Slip sweeps: keep only the rows at this slip angle (only 0 is accepted: the model is
        straight-line) instead of refusing the others. The rows dropped by either option are
        counted in :attr:`SlipData.dropped`.
    max_rows
        Most data rows read into memory (default ``$SOILTRACK_MAX_ROWS`` or 2,000,000): the rows
        are streamed (:mod:`soiltrack.soilmodel.csvread`), a larger file is refused as soon as the
        reader passes the limit, and every bad row is counted, the first few named.
    columns
        ``{library column: file column}`` read under the library's name; a unit suffix on the
        file's column (or on a column whose stem is a library column's, e.g. ``sinkage_mm``)
        converts the values (:mod:`soiltrack.soilmodel.columns`; what was converted:
        ``plan_columns(read_header(path), known=KNOWN_COLUMNS, mapping=columns).notes``).

    Raises
    ------
    DataError
        For a missing file, an unknown or incomplete header, a non-numeric, NaN or infinite
        value, slip outside [0, 1), non-increasing time, or a row with the wrong number of
        fields; the message names the file, the column and the row.
    """
    path = os.fspath(path)
    header = read_header(path)  # encoding checked, blank lines skipped (soilmodel.csvread)
    plan = plan_columns(header, known=KNOWN_COLUMNS, mapping=columns, source=path)  # mapping, unit suffixes
    header = list(plan.header)
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise DataError(f"duplicate column(s) {dup}", file=path, column=dup[0])
    if "drawbar_pull_N" in header and "tractive_force_N" in header:
        raise DataError(
            "both tractive_force_N and drawbar_pull_N given: a sweep measures one of them",
            file=path,
            column="drawbar_pull_N",
        )
    if "shear_stress_Pa" in header or "shear_displacement_m" in header:
        kind, required, optional = "shear", SHEAR_COLUMNS, NO_COLUMNS
    elif "plate_width_m" in header or "pressure_Pa" in header:
        kind, required, optional = "plate", PLATE_COLUMNS, NO_COLUMNS
    elif "drawbar_pull_N" in header:
        kind, required, optional = "drawbar", DRAWBAR_COLUMNS, SLIP_OPTIONAL
    elif "slip" in header or "tractive_force_N" in header:
        kind, required, optional = "slip", SLIP_COLUMNS, SLIP_OPTIONAL
    elif any(c in header for c in TWO_TRACK_COLUMNS):
        return _read_two_track(path, header, max_rows, plan)
    elif any(c in header for c in DRIVE_COLUMNS):
        kind, required, optional = "drive", DRIVE_COLUMNS, DRIVE_OPTIONAL
    else:
        sep = next((s for s in (";", "\t", "|") if len(header) == 1 and s in header[0]), None)
        hint = (
            (
                f" - the header is separated by {'a tab' if sep == chr(9) else repr(sep)}: soiltrack reads "
                "comma-separated CSV with a decimal point (save or export as 'CSV, comma')"
            )
            if sep
            else ""
        )
        raise DataError(
            f"unrecognised columns {header}: expected {list(SLIP_COLUMNS)} (tractive force-slip "
            f"data), {list(DRAWBAR_COLUMNS)} (drawbar-pull data), {list(DRIVE_COLUMNS)} (drive log), "
            f"{list(SHEAR_COLUMNS)} (bevameter shear test) or {list(PLATE_COLUMNS)} (plate sinkage "
            f"test){hint}",
            file=path,
        )
    for col in required:
        if col not in header:
            raise DataError(f"missing required column (header has {header})", file=path, column=col)
    used = [c for c in (*required, *optional) if c in header]
    data = plan.apply(read_columns(path, header, used, max_rows))  # streamed, row limit, bad rows counted
    if kind in ("drawbar", "slip"):
        return _slip_data(kind, data, path, driving_only, slip_angle)
    for opt, val in (("driving_only", driving_only), ("slip_angle", slip_angle)):
        if val not in (False, None):
            raise DataError(f"{opt} applies to slip sweeps only, not to this {kind} file", file=path)
    if kind == "shear":
        return ShearTest(
            normal_pressure=np.asarray(data["normal_pressure_Pa"]),
            shear_displacement=np.asarray(data["shear_displacement_m"]),
            shear_stress=np.asarray(data["shear_stress_Pa"]),
            source=path,
        )
    if kind == "plate":
        return PlateTest(
            plate_width=np.asarray(data["plate_width_m"]),
            pressure=np.asarray(data["pressure_Pa"]),
            sinkage=np.asarray(data["sinkage_m"]),
            source=path,
        )
    return drive_log_from_columns(data, path)


def drive_log_from_columns(data: dict, source: str) -> DriveLog:
    """The :class:`DriveLog` of parsed columns (a CSV's, or a ROS bag's: :mod:`.rosbag_read`): combined or
    two-track (summed torque, mean sprocket speed, turning samples marked), with the log's own checks."""
    if any(c in data for c in TWO_TRACK_COLUMNS):
        torque, speed = combine_tracks(*(data[c] for c in TWO_TRACK_COLUMNS))
        turning = turning_mask(
            data["sprocket_speed_left_rad_s"], data["sprocket_speed_right_rad_s"], data.get(YAW_COLUMN)
        )
    else:
        torque, speed, turning = data["sprocket_torque_Nm"], data["sprocket_speed_rad_s"], None
    return DriveLog(
        time=data["time_s"],
        sprocket_torque=torque,
        sprocket_speed=speed,
        vehicle_speed=data["vehicle_speed_m_s"],
        vehicle_accel=data.get("vehicle_accel_m_s2"),
        source=source,
        turning=turning,
    )


def _read_two_track(path: str, header: list[str], max_rows: int | None, plan: ColumnPlan) -> DriveLog:
    """A two-track drive log: summed torque, mean sprocket speed, turning samples marked."""
    combined = [c for c in ("sprocket_torque_Nm", "sprocket_speed_rad_s") if c in header]
    if combined:
        raise DataError(
            f"both the combined column {combined[0]} and two-track columns given: a drive log has "
            f"either {list(DRIVE_COLUMNS)} or the left/right columns {list(TWO_TRACK_COLUMNS)}",
            file=path,
            column=combined[0],
        )
    required = ("time_s", *TWO_TRACK_COLUMNS, "vehicle_speed_m_s")
    for col in required:
        if col not in header:
            raise DataError(
                f"missing required column of a two-track drive log (header has {header})", file=path, column=col
            )
    used = [c for c in (*required, *DRIVE_OPTIONAL, YAW_COLUMN) if c in header]
    data = plan.apply(read_columns(path, header, used, max_rows))  # streamed, row limit, bad rows counted
    return drive_log_from_columns(data, path)


def _slip_data(kind: str, data: dict, path: str, driving_only: bool, slip_angle: float | None) -> SlipData:
    """A :class:`SlipData` from the parsed columns, the rows the options drop left out and counted."""
    measured = "drawbar_pull" if kind == "drawbar" else "tractive_force"
    other = STD_COLUMNS["tractive_force" if kind == "drawbar" else "drawbar_pull"]
    if other in data:
        raise DataError(
            f"{other} is the standard deviation of the other quantity; this file measures "
            f"{MEASURED_COLUMNS[measured]} (its column is {STD_COLUMNS[measured]})",
            file=path,
            column=other,
        )
    if slip_angle is not None and slip_angle != 0:
        raise DataError(
            f"--slip-angle {slip_angle:g}: the model is straight-line; only 0 can be kept",
            file=path,
            column="slip_angle_deg",
        )
    arr = {c: np.asarray(v, dtype=float) for c, v in data.items()}
    keep = np.ones(arr["slip"].size, dtype=bool)
    dropped = []
    if slip_angle is not None:
        if "slip_angle_deg" not in arr:
            raise DataError("--slip-angle given but the file has no slip_angle_deg column", file=path)
        off = np.isfinite(arr["slip_angle_deg"]) & (arr["slip_angle_deg"] != slip_angle)
        if off.any():
            dropped.append(
                (
                    f"at a slip angle other than {slip_angle:g} deg",
                    "--slip-angle",
                    tuple(int(k) + 1 for k in np.nonzero(off)[0]),
                )
            )
        keep &= ~off
    if driving_only:
        skid = keep & np.isfinite(arr["slip"]) & (arr["slip"] < 0)
        if skid.any():
            dropped.append(
                ("at negative slip (skid)", "--driving-only", tuple(int(k) + 1 for k in np.nonzero(skid)[0]))
            )
        keep &= ~skid
    if not keep.any():
        raise DataError(f"no rows left after dropping {sum(len(r) for _, _, r in dropped)}", file=path)
    kept = np.nonzero(keep)[0]
    col = {c: v[keep] for c, v in arr.items()}
    try:
        return SlipData(
            slip=col["slip"],
            normal_load=col.get("normal_load_N"),
            source=path,
            sinkage=col.get("sinkage_m"),
            force_std=col.get(STD_COLUMNS[measured]),
            slip_angle=col.get("slip_angle_deg"),
            dropped=tuple(dropped),
            **{measured: col[MEASURED_COLUMNS[measured]]},
        )
    except DataError as e:  # rows of the kept data -> rows of the file
        if e.rows is None and e.row is None or not dropped:
            raise
        named = e.rows if e.rows is not None else (int(e.row or 1),)
        rows = tuple(int(kept[r - 1]) + 1 for r in named)
        n_drop = sum(len(r) for _, _, r in dropped)
        raise DataError(
            f"{e.reason.replace(name_rows(named), name_rows(rows))} (rows of the file; {n_drop} rows dropped before)",
            file=path,
            column=e.column,
            row=rows[0],
            rows=rows if e.rows else None,
        ) from None


def write_csv(data: SlipData | DriveLog | ShearTest | PlateTest, path) -> None:
    """Write slip data, a drive log or a bevameter test in the CSV contract (full float precision).

    ``path`` is a file path or an open text stream (e.g. ``sys.stdout``).
    """
    if isinstance(data, SlipData):
        cols = data.columns()
    elif isinstance(data, (DriveLog, ShearTest, PlateTest)):
        cols = data.columns()
    else:
        raise TypeError(f"write_csv takes SlipData, DriveLog, ShearTest or PlateTest, got {type(data).__name__}")
    if hasattr(path, "write"):
        _write_rows(path, cols)
        return
    with open(os.fspath(path), "w", newline="", encoding="utf-8") as fh:
        _write_rows(fh, cols)


def _write_rows(fh, cols: dict) -> None:
    w = csv.writer(fh, lineterminator="\n")
    w.writerow(list(cols))
    for row in zip(*cols.values()):
        w.writerow([repr(float(v)) for v in row])
