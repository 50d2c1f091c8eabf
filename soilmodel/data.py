"""Measured data containers and CSV I/O (DESIGN.md section 7).

Two kinds of file, told apart by their columns:

- tractive force-slip data: ``slip,tractive_force_N`` and optionally ``normal_load_N``;
- drawbar-pull data: ``slip,drawbar_pull_N`` and optionally ``normal_load_N`` (drawbar pull =
  thrust - motion resistance, what a test rig measures);
- drive logs: ``time_s,sprocket_torque_Nm,sprocket_speed_rad_s,vehicle_speed_m_s`` and
  optionally ``vehicle_accel_m_s2``;
- two-track drive logs: the same with ``sprocket_torque_left_Nm, sprocket_torque_right_Nm,
  sprocket_speed_left_rad_s, sprocket_speed_right_rad_s`` (and optionally ``yaw_rate_rad_s``)
  instead of the combined torque and speed: summed torque, mean speed, turning samples marked
  (:mod:`.tracks`).

Bad input is refused with a :class:`~soiltrack.soilmodel.errors.DataError` that names the
file, the column and the data row (row 1 is the first line after the header).
"""
from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass

import numpy as np

from .errors import DataError
from .tracks import TWO_TRACK_COLUMNS, YAW_COLUMN, combine_tracks, turning_mask

SLIP_COLUMNS = ("slip", "tractive_force_N")
DRAWBAR_COLUMNS = ("slip", "drawbar_pull_N")
SLIP_OPTIONAL = ("normal_load_N",)
#: What a slip sweep measured -> its CSV column.
MEASURED_COLUMNS = {"tractive_force": "tractive_force_N", "drawbar_pull": "drawbar_pull_N"}
DRIVE_COLUMNS = ("time_s", "sprocket_torque_Nm", "sprocket_speed_rad_s", "vehicle_speed_m_s")
DRIVE_OPTIONAL = ("vehicle_accel_m_s2",)


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
    """

    slip: np.ndarray
    tractive_force: np.ndarray | None = None
    normal_load: np.ndarray | None = None
    source: str = "<memory>"
    drawbar_pull: np.ndarray | None = None

    def __post_init__(self) -> None:
        if (self.tractive_force is None) == (self.drawbar_pull is None):
            raise DataError("give exactly one of tractive_force and drawbar_pull", file=self.source)
        object.__setattr__(self, "slip", _frozen(self.slip))
        for name in ("tractive_force", "drawbar_pull", "normal_load"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _frozen(getattr(self, name)))
        cols = {"slip": self.slip, self.channel: self.values}
        if self.normal_load is not None:
            cols["normal_load_N"] = self.normal_load
        _check_lengths(cols, self.source)
        _check_finite(cols, self.source)
        _check_range(self.slip, "slip", self.source, lo=0.0, hi=1.0, hi_open=True, what="slip must lie in [0, 1)")
        if self.normal_load is not None:
            _check_range(self.normal_load, "normal_load_N", self.source, lo=0.0, lo_open=True,
                         what="normal load must be > 0 N")

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
        return self.tractive_force if self.tractive_force is not None else self.drawbar_pull

    def subset(self, index) -> "SlipData":
        """The rows selected by ``index`` (slice, integer array or boolean mask), same type.

        The source is annotated with the data rows taken (row 1 = first data row).
        """
        idx = _rows(index, self.n_samples, self.source)
        kw = {"drawbar_pull" if self.measured == "drawbar_pull" else "tractive_force": self.values[idx]}
        return SlipData(slip=self.slip[idx], normal_load=None if self.normal_load is None else self.normal_load[idx],
                        source=_annotate(self.source, idx), **kw)

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
        bad = np.nonzero(np.diff(self.time) <= 0)[0]
        if bad.size:
            k = int(bad[0]) + 1
            raise DataError(f"time must be strictly increasing ({self.time[k - 1]:.6g} then {self.time[k]:.6g})",
                            file=self.source, column="time_s", row=k + 1)

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
        return DriveLog(time=self.time[idx], sprocket_torque=self.sprocket_torque[idx],
                        sprocket_speed=self.sprocket_speed[idx], vehicle_speed=self.vehicle_speed[idx],
                        vehicle_accel=None if self.vehicle_accel is None else self.vehicle_accel[idx],
                        source=_annotate(self.source, idx),
                        turning=None if self.turning is None else self.turning[idx])

    def columns(self) -> dict[str, np.ndarray]:
        """The log as ``{column name: values}`` in the CSV contract's names."""
        out = dict(zip(DRIVE_COLUMNS, (self.time, self.sprocket_torque, self.sprocket_speed, self.vehicle_speed)))
        if self.vehicle_accel is not None:
            out["vehicle_accel_m_s2"] = self.vehicle_accel
        return out


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
    for name, values in cols.items():
        bad = np.nonzero(~np.isfinite(values))[0]
        if bad.size:
            k = int(bad[0])
            raise DataError(f"value {values[k]} is not a finite number", file=source, column=name, row=k + 1)


def _check_range(values, column, source, *, lo=None, hi=None, lo_open=False, hi_open=False, what="") -> None:
    bad = np.zeros(values.shape, dtype=bool)
    if lo is not None:
        bad |= (values <= lo) if lo_open else (values < lo)
    if hi is not None:
        bad |= (values >= hi) if hi_open else (values > hi)
    idx = np.nonzero(bad)[0]
    if idx.size:
        k = int(idx[0])
        raise DataError(f"{what}, got {values[k]:.6g}", file=source, column=column, row=k + 1)


def _parse_float(text: str, path: str, column: str, row: int) -> float:
    t = text.strip()
    try:
        v = float(t)
    except ValueError:
        raise DataError(f"'{t}' is not a number" if t else "empty value", file=path, column=column, row=row) from None
    if not math.isfinite(v):
        raise DataError(f"value '{t}' is not a finite number", file=path, column=column, row=row)
    return v


def read_csv(path: str | os.PathLike) -> SlipData | DriveLog:
    """Read tractive force-slip data, drawbar-pull data or a drive log (recognised by the columns).

    Raises
    ------
    DataError
        For a missing file, an unknown or incomplete header, a non-numeric, NaN or infinite
        value, slip outside [0, 1), non-increasing time, or a row with the wrong number of
        fields; the message names the file, the column and the row.
    """
    path = os.fspath(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = list(csv.reader(fh))
    except OSError as e:
        raise DataError(f"cannot read: {e.strerror}", file=path) from None
    except UnicodeDecodeError:
        raise DataError("not a UTF-8 text file", file=path) from None
    rows = [r for r in rows if any(cell.strip() for cell in r)]  # blank lines carry nothing
    if not rows:
        raise DataError("empty file: expected a header row", file=path)
    header = [h.strip() for h in rows[0]]
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise DataError(f"duplicate column(s) {dup}", file=path, column=dup[0])
    if "drawbar_pull_N" in header and "tractive_force_N" in header:
        raise DataError("both tractive_force_N and drawbar_pull_N given: a sweep measures one of them", file=path,
                        column="drawbar_pull_N")
    if "drawbar_pull_N" in header:
        kind, required, optional = "drawbar", DRAWBAR_COLUMNS, SLIP_OPTIONAL
    elif "slip" in header or "tractive_force_N" in header:
        kind, required, optional = "slip", SLIP_COLUMNS, SLIP_OPTIONAL
    elif any(c in header for c in TWO_TRACK_COLUMNS):
        return _read_two_track(path, header, rows[1:])
    elif any(c in header for c in DRIVE_COLUMNS):
        kind, required, optional = "drive", DRIVE_COLUMNS, DRIVE_OPTIONAL
    else:
        sep = next((s for s in (";", "\t", "|") if len(header) == 1 and s in header[0]), None)
        hint = (f" - the header is separated by {'a tab' if sep == chr(9) else repr(sep)}: soiltrack reads "
                "comma-separated CSV with a decimal point (save or export as 'CSV, comma')") if sep else ""
        raise DataError(f"unrecognised columns {header}: expected {list(SLIP_COLUMNS)} (tractive force-slip "
                        f"data), {list(DRAWBAR_COLUMNS)} (drawbar-pull data) or {list(DRIVE_COLUMNS)} (drive log){hint}",
                        file=path)
    for col in required:
        if col not in header:
            raise DataError(f"missing required column (header has {header})", file=path, column=col)
    used = [c for c in (*required, *optional) if c in header]
    idx = {c: header.index(c) for c in used}
    data: dict[str, list[float]] = {c: [] for c in used}
    for r, cells in enumerate(rows[1:], start=1):
        if len(cells) != len(header):
            raise DataError(f"expected {len(header)} fields, found {len(cells)}", file=path, row=r)
        for c in used:
            data[c].append(_parse_float(cells[idx[c]], path, c, r))
    if not rows[1:]:
        raise DataError("no data rows after the header", file=path)
    if kind == "drawbar":
        return SlipData(slip=data["slip"], drawbar_pull=data["drawbar_pull_N"],
                        normal_load=data.get("normal_load_N"), source=path)
    if kind == "slip":
        return SlipData(slip=data["slip"], tractive_force=data["tractive_force_N"],
                        normal_load=data.get("normal_load_N"), source=path)
    return DriveLog(time=data["time_s"], sprocket_torque=data["sprocket_torque_Nm"],
                    sprocket_speed=data["sprocket_speed_rad_s"], vehicle_speed=data["vehicle_speed_m_s"],
                    vehicle_accel=data.get("vehicle_accel_m_s2"), source=path)


def _read_two_track(path: str, header: list[str], body: list[list[str]]) -> DriveLog:
    """A two-track drive log: summed torque, mean sprocket speed, turning samples marked."""
    combined = [c for c in ("sprocket_torque_Nm", "sprocket_speed_rad_s") if c in header]
    if combined:
        raise DataError(f"both the combined column {combined[0]} and two-track columns given: a drive log has "
                        f"either {list(DRIVE_COLUMNS)} or the left/right columns {list(TWO_TRACK_COLUMNS)}",
                        file=path, column=combined[0])
    required = ("time_s", *TWO_TRACK_COLUMNS, "vehicle_speed_m_s")
    for col in required:
        if col not in header:
            raise DataError(f"missing required column of a two-track drive log (header has {header})", file=path,
                            column=col)
    used = [c for c in (*required, *DRIVE_OPTIONAL, YAW_COLUMN) if c in header]
    if not body:
        raise DataError("no data rows after the header", file=path)
    data: dict[str, list[float]] = {c: [] for c in used}
    for r, cells in enumerate(body, start=1):
        if len(cells) != len(header):
            raise DataError(f"expected {len(header)} fields, found {len(cells)}", file=path, row=r)
        for c in used:
            data[c].append(_parse_float(cells[header.index(c)], path, c, r))
    torque, speed = combine_tracks(*(data[c] for c in TWO_TRACK_COLUMNS))
    turning = turning_mask(data["sprocket_speed_left_rad_s"], data["sprocket_speed_right_rad_s"],
                           data.get(YAW_COLUMN))
    return DriveLog(time=data["time_s"], sprocket_torque=torque, sprocket_speed=speed,
                    vehicle_speed=data["vehicle_speed_m_s"], vehicle_accel=data.get("vehicle_accel_m_s2"),
                    source=path, turning=turning)


def write_csv(data: SlipData | DriveLog, path) -> None:
    """Write slip data (tractive force or drawbar pull) or a drive log in the CSV contract (full float precision).

    ``path`` is a file path or an open text stream (e.g. ``sys.stdout``).
    """
    if isinstance(data, SlipData):
        cols = {"slip": data.slip, data.channel: data.values}
        if data.normal_load is not None:
            cols["normal_load_N"] = data.normal_load
    elif isinstance(data, DriveLog):
        cols = data.columns()
    else:
        raise TypeError(f"write_csv takes SlipData or DriveLog, got {type(data).__name__}")
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
