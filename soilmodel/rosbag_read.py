"""Drive logs as robots record them: ROS 2 bags (SQLite ``.db3``, MCAP) and ROS 1 ``.bag`` files.

Read through the pure-Python ``rosbags`` package, an optional extra (``pip install 'soiltrack[ros]'``).
A mapping names, for each of the library's drive-log columns, a topic and a field of its messages:
``"sprocket_torque_Nm=/drive/state:effort[0],vehicle_speed_m_s=/gnss/speed:data,..."`` or a JSON file
``{"topics": {"sprocket_torque_Nm": "/drive/state:effort[0]", ...}, "clock": NAME, "rate_hz": R}`` (or
the ``topics`` object alone). A field is a dotted path with optional indices (``twist.linear.x``,
``effort[1]``); an array of one value needs no index.

Units: the values are taken in the units the library's column names state (N m, rad/s, m/s, m/s^2) -
ROS's own convention (REP 103: SI units); nothing is converted.

Time: a message's ``header.stamp`` where it has a header (and the stamp is set), else the time the bag
recorded it. One clock: by default the time stamps of the first mapped sprocket channel (or ``clock``: a
column name); with ``rate_hz`` a uniform clock at that rate. Every other channel is resampled onto it by
linear interpolation (``numpy.interp``), only over the span every channel covers (no extrapolation; the
rows of the clock outside it are dropped and counted). ``time_s`` is the clock's time since its first
row. What was read and how it was resampled is in :func:`bag_notes` (the report's and JSON's
``columns_read``). The columns then go through the same record and checks as a CSV drive log
(:func:`~.data.drive_log_from_columns`: lengths, finite values, strictly increasing time, two-track
columns combined).
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from .data import DRIVE_COLUMNS, DRIVE_OPTIONAL, drive_log_from_columns
from .errors import DataError
from .tracks import TWO_TRACK_COLUMNS, YAW_COLUMN

__all__ = ["BagMapping", "BagStreamReader", "parse_topics", "read_bag", "read_bag_columns", "bag_notes"]

#: Columns a bag may be mapped onto (``time_s`` is the clock's, never a field).
BAG_COLUMNS = (*DRIVE_COLUMNS[1:], *DRIVE_OPTIONAL, *TWO_TRACK_COLUMNS, YAW_COLUMN)
_NOTES: dict[str, list[str]] = {}
_PART = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)((?:\[[0-9]+\])*)$")


@dataclass(frozen=True)
class BagMapping:
    """Columns onto ``(topic, field)``; ``clock`` (a column name, or None: the first sprocket channel) and
    ``rate_hz`` (a uniform clock, or None: the clock channel's own stamps)."""

    topics: dict[str, tuple[str, str]]
    clock: str | None = None
    rate_hz: float | None = None


def _entry(name: str, value: str, where: str | None) -> tuple[str, str]:
    if name not in BAG_COLUMNS:
        raise DataError(
            f"unknown drive-log column {name!r} in the bag mapping (expected some of {list(BAG_COLUMNS)})",
            column=name,
            file=where,
        )
    topic, sep, field = str(value).rpartition(":")
    if not sep or not topic or not field:
        raise DataError(f"{name}={value!r}: expected TOPIC:FIELD, e.g. /left_drive/state:effort", column=name)
    for part in field.split("."):
        if not _PART.match(part):
            raise DataError(f"{name}={value!r}: {field!r} is not a field path (e.g. twist.linear.x, effort[0])")
    return topic, field


def parse_topics(spec: Any) -> BagMapping:
    """A :class:`BagMapping` from ``"NAME=TOPIC:FIELD,..."`` (items ``clock=NAME``, ``rate_hz=R`` allowed), a JSON
    file's path, or a dict; DataError naming the item that is wrong."""
    if isinstance(spec, BagMapping):
        return spec
    where = None
    if isinstance(spec, (str, os.PathLike)) and str(spec).lower().endswith(".json"):
        where = os.fspath(spec)
        try:
            with open(where, encoding="utf-8") as fh:
                spec = json.load(fh)
        except (OSError, ValueError) as e:
            raise DataError(f"cannot read the bag mapping: {e}", file=where) from None
    if isinstance(spec, str):
        items: dict[str, Any] = {}
        for item in filter(None, (x.strip() for x in spec.split(","))):
            name, sep, value = item.partition("=")
            if not sep:
                raise DataError(f"--topics item {item!r}: expected NAME=TOPIC:FIELD")
            items[name.strip()] = value.strip()
        spec = items
    if not isinstance(spec, dict):
        raise DataError(f"a bag mapping is NAME=TOPIC:FIELD items or a JSON object, got {type(spec).__name__}")
    spec = dict(spec)
    clock, rate = spec.pop("clock", None), spec.pop("rate_hz", None)
    topics = spec.pop("topics", None)
    if topics is None:
        topics = spec
    elif spec:
        raise DataError(
            f"unknown key(s) {sorted(spec)} in the bag mapping (expected topics, clock, rate_hz)", file=where
        )
    out = {str(k): _entry(str(k), v, where) for k, v in topics.items()}
    if rate is not None:
        try:
            rate = float(rate)
        except ValueError:
            rate = math.nan
        if not (math.isfinite(rate) and rate > 0):
            raise DataError(f"rate_hz must be a number > 0, got {rate!r}", file=where, column="rate_hz")
    if clock is not None and clock not in out:
        raise DataError(f"clock={clock!r} is not a mapped column ({sorted(out)})", file=where, column="clock")
    return BagMapping(topics=out, clock=clock, rate_hz=rate)


def _value(msg: Any, field: str, topic: str, name: str, source: str) -> float:
    obj = msg
    for part in field.split("."):
        m = _PART.match(part)
        assert m is not None  # checked by parse_topics
        attr, idx = m.group(1), [int(i) for i in re.findall(r"\[([0-9]+)\]", m.group(2))]
        if not hasattr(obj, attr):
            fields = [f for f in getattr(obj, "__dataclass_fields__", {}) if not f.startswith("_")]
            raise DataError(
                f"topic {topic} ({getattr(msg, '__msgtype__', type(msg).__name__)}) has no field {field!r} "
                f"(at {attr!r}; its fields: {fields})",
                file=source,
                column=name,
            )
        obj = getattr(obj, attr)
        for i in idx:
            try:
                obj = obj[i]
            except (IndexError, TypeError):
                raise DataError(
                    f"topic {topic}: field {field!r} has no element {i} (a message holds {np.size(obj)})",
                    file=source,
                    column=name,
                ) from None
    arr = np.asarray(obj)
    if arr.ndim and arr.size == 1:
        arr = arr.reshape(())
    if arr.dtype.kind not in "fiub":
        raise DataError(
            f"topic {topic}: field {field!r} is not a number (a {type(obj).__name__})", file=source, column=name
        )
    if arr.ndim:
        raise DataError(
            f"topic {topic}: field {field!r} is not one number ({arr.size} values): give an index, e.g. {field}[0]",
            file=source,
            column=name,
        )
    return float(arr)


def _stamp(msg: Any, recorded_ns: int) -> tuple[int, bool]:
    """Nanoseconds (integers: an epoch's seconds as a float keep only ~0.2 us) and whether from the header."""
    st = getattr(getattr(msg, "header", None), "stamp", None)
    if st is not None:
        ns = int(getattr(st, "sec", 0)) * 1_000_000_000 + int(getattr(st, "nanosec", 0))
        if ns > 0:
            return ns, True
    return int(recorded_ns), False


def _open_reader(path: str):
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise DataError(
            "reading ROS bags needs the optional extra: pip install 'soiltrack[ros]' (the rosbags package)",
            file=path,
        ) from None
    from pathlib import Path

    return AnyReader([Path(path)], default_typestore=get_typestore(Stores.LATEST))


def _channels(path: str, mapping: BagMapping) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict[str, str]]:
    """Per column its times and values as recorded (in bag order, sorted by time), and each column's time source."""
    try:
        reader = _open_reader(path)
        reader.open()
    except DataError:
        raise
    except Exception as e:  # noqa: BLE001 - the package's own reason, with the file
        raise DataError(f"cannot read the ROS bag ({type(e).__name__}: {e})", file=path) from None
    try:
        by_topic: dict[str, list] = {}
        for c in reader.connections:
            by_topic.setdefault(c.topic, []).append(c)
        wanted: dict[str, list[str]] = {}
        for name, (topic, _) in mapping.topics.items():
            if topic not in by_topic:
                raise DataError(
                    f"topic {topic} (for {name}) is not in the bag (its topics: {sorted(by_topic)})",
                    file=path,
                    column=name,
                )
            wanted.setdefault(topic, []).append(name)
        times: dict[str, list[int]] = {n: [] for n in mapping.topics}
        vals: dict[str, list[float]] = {n: [] for n in mapping.topics}
        header: dict[str, bool] = {}
        conns = [c for t in wanted for c in by_topic[t]]
        for conn, recorded, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            t, stamped = _stamp(msg, recorded)
            for name in wanted[conn.topic]:
                times[name].append(t)
                vals[name].append(_value(msg, mapping.topics[name][1], conn.topic, name, path))
                header[name] = header.get(name, True) and stamped
    finally:
        reader.close()
    out_t, out_v, how = {}, {}, {}
    first = [ts[0] for ts in times.values() if ts]
    t0 = min(first) if first else 0
    for name in mapping.topics:  # seconds since the first stamp of all (exact to the nanosecond's float)
        secs = (np.asarray(times[name], dtype=np.int64) - t0).astype(float) / 1e9  # correctly rounded: 0.06 is 0.06
        v = np.asarray(vals[name], float)
        if secs.size < 2:
            topic = mapping.topics[name][0]
            raise DataError(f"topic {topic} (for {name}) has {secs.size} message(s): a drive log needs more", file=path)
        order = np.argsort(secs, kind="stable")
        out_t[name], out_v[name] = secs[order], v[order]
        how[name] = "header stamps" if header[name] else "recorded times"
    return out_t, out_v, how


def read_bag_columns(
    path: str | os.PathLike, topics: Any, *, two_track: bool = False
) -> tuple[dict[str, np.ndarray], list[str]]:
    """The bag's channels on one clock as ``{column: values}`` (``time_s`` included), and the notes saying how.

    The one check of the mapping's required columns: the two-track columns when ``two_track`` is true or the
    mapping names any of them, else the straight-line sprocket columns; ``vehicle_speed_m_s`` always.
    """
    path = os.fspath(path)
    mapping = parse_topics(topics)
    names = set(mapping.topics)
    two = two_track or bool(names & set(TWO_TRACK_COLUMNS))
    sprocket = TWO_TRACK_COLUMNS if two else DRIVE_COLUMNS[1:3]
    for col in (*sprocket, "vehicle_speed_m_s"):
        if col not in names:
            raise DataError(
                f"the bag mapping has no topic for the required column {col} (mapped: {sorted(names)})",
                file=path,
                column=col,
            )
    t, v, how = _channels(path, mapping)
    ref = mapping.clock or sprocket[0]
    lo = max(float(x[0]) for x in t.values())
    hi = min(float(x[-1]) for x in t.values())
    if not hi > lo:
        raise DataError("the mapped topics do not overlap in time: no common span to resample onto", file=path)
    if mapping.rate_hz is None:
        clock = t[ref][(t[ref] >= lo) & (t[ref] <= hi)]
        said = f"the time stamps of {ref} ({mapping.topics[ref][0]}, {how[ref]})"
    else:
        clock = lo + np.arange(int(math.floor((hi - lo) * mapping.rate_hz + 1e-9)) + 1) / mapping.rate_hz
        said = f"a uniform clock at {mapping.rate_hz:g} Hz"
    dropped = int(t[ref].size - clock.size) if mapping.rate_hz is None else 0
    cols = {"time_s": clock - clock[0]}
    for name in mapping.topics:
        if np.any(np.diff(t[name]) <= 0):
            k = int(np.argmax(np.diff(t[name]) <= 0)) + 1
            raise DataError(
                f"topic {mapping.topics[name][0]}: time must be strictly increasing (message {k + 1} repeats "
                f"time {t[name][k]:.9g} s)",
                file=path,
                column=name,
            )
        cols[name] = np.interp(clock, t[name], v[name])  # the clock's own channel: its values exactly
    rate = (clock.size - 1) / (clock[-1] - clock[0]) if clock.size > 1 else math.nan
    notes = [
        f"ROS bag {path}: " + ", ".join(f"{n}={tp}:{f} ({how[n]})" for n, (tp, f) in mapping.topics.items()),
        "units as the column names state (N m, rad/s, m/s, m/s^2; ROS REP 103 SI), nothing converted",
        f"resampled onto {said} by linear interpolation over the span every topic covers: {clock.size} rows at "
        f"{rate:.4g} Hz mean"
        + (f", {dropped} rows of the clock outside that span dropped" if dropped else "")
        + "; time_s = the clock's time since its first row",
        *_gaps(t, mapping),
    ]
    return cols, notes


#: A topic's silence longer than this many of its median periods is said in the notes (interpolated across).
GAP_PERIODS = 5.0


def _gaps(t: dict[str, np.ndarray], mapping: BagMapping) -> list[str]:
    """Notes of the topics with a gap the interpolation bridges (longer than :data:`GAP_PERIODS` periods)."""
    out = []
    for name, ts in t.items():
        dt = np.diff(ts)
        k = int(np.argmax(dt))
        if dt[k] > GAP_PERIODS * float(np.median(dt)):
            out.append(
                f"{mapping.topics[name][0]} ({name}) is silent for {dt[k]:.3g} s from {ts[k]:.6g} s (the median "
                f"period is {float(np.median(dt)):.3g} s): its values are interpolated across the gap"
            )
    return out


def read_bag(path: str | os.PathLike, topics: Any):
    """A ROS bag as a :class:`~.data.DriveLog` (module notes); DataError naming the topic or field that is wrong."""
    path = os.fspath(path)
    cols, notes = read_bag_columns(path, topics)
    _NOTES[path] = notes
    return drive_log_from_columns(cols, path)


def bag_notes(path: str | os.PathLike) -> list[str]:
    """What the last :func:`read_bag` of ``path`` read and how it resampled (empty before)."""
    return list(_NOTES.get(os.fspath(path), []))


class BagStreamReader:
    """A bag as :class:`~.drive_stream.DriveStreamReader` offers a CSV to a replay: ``source``, ``two_track``,
    ``used``, :meth:`check`, and its columns as one chunk (the bag is resampled as a whole: its memory is the
    log's columns)."""

    def __init__(self, path: str | os.PathLike, topics: Any, *, columns: dict[str, str] | None = None) -> None:
        self.source = os.fspath(path)
        if topics is None:
            raise DataError(
                "a ROS bag needs --topics NAME=TOPIC:FIELD[,...] (or a JSON mapping file)", file=self.source
            )
        if columns:
            raise DataError("--columns applies to CSV files; a bag's columns are named by --topics", file=self.source)
        cols, notes = read_bag_columns(self.source, topics)
        _NOTES[self.source] = notes
        drive_log_from_columns(cols, self.source)  # the CSV drive log's checks (finite, increasing time)
        self.two_track = any(c in cols for c in TWO_TRACK_COLUMNS)
        self.used = list(cols)
        for v in cols.values():
            v.setflags(write=False)
        self._cols = cols

    def __iter__(self):
        yield self._cols

    def check(self) -> int:
        """The rows (the bag was checked on opening)."""
        return int(self._cols["time_s"].size)
