"""``--columns NAME=SOURCE[,...]`` on every command that reads a CSV, and saying what it converted.

The mapping and the unit suffixes are :mod:`soiltrack.soilmodel.columns`; this module adds the
option to a parser, turns it into the readers' ``columns`` argument, and puts the conversions
into the output: a ``columns:`` line before a text report, a ``"columns_read"`` list in a JSON
object (empty when the file was read as it is).
"""

from __future__ import annotations

import argparse
import json

from .soilmodel.columns import parse_columns_arg, plan_columns
from .soilmodel.csvread import read_header
from .soilmodel.data import KNOWN_COLUMNS
from .soilmodel.errors import DataError

__all__ = ["add_columns_argument", "columns_arg", "column_notes", "with_column_notes"]

COLUMNS_HELP = (
    "read the file's column SOURCE as the library's column NAME (e.g. drawbar_pull_N=Fx,sinkage_m=depth_mm); "
    "a unit suffix on SOURCE (_mm, _kN, _kPa, _deg, _percent, _rpm, _ms) converts it, and a column named "
    "like a library column with another unit suffix (sinkage_mm) is converted without it; the report says so"
)


TOPICS_HELP = (
    "a ROS bag given as the data (ROS 2 .db3/.mcap or its folder, ROS 1 .bag; pip install 'soiltrack[ros]'): "
    "the topic and message field of each drive-log column, e.g. sprocket_torque_Nm=/drive/state:effort[0],"
    "sprocket_speed_rad_s=/drive/state:velocity[0],vehicle_speed_m_s=/gnss/speed:data (clock=NAME, rate_hz=R "
    "choose the clock), or a JSON file of the same; units as the column names state; resampled by linear "
    "interpolation onto one clock, said in the report"
)


def add_columns_argument(p: argparse.ArgumentParser) -> None:
    """Add ``--columns NAME=SOURCE[,...]`` to a subcommand's parser."""
    p.add_argument("--columns", metavar="NAME=SOURCE[,...]", default=None, help=COLUMNS_HELP)
    if "--topics" not in p._option_string_actions:  # drive logs as ROS bags (soilmodel.rosbag_read)
        p.add_argument("--topics", metavar="NAME=TOPIC:FIELD[,...]|MAP.json", default=None, help=TOPICS_HELP)


def columns_arg(a: argparse.Namespace) -> dict[str, str] | None:
    """The parsed ``--columns`` of a namespace (``None`` when not given)."""
    return parse_columns_arg(getattr(a, "columns", None))


def column_notes(path: str, mapping: dict[str, str] | None, known: tuple[str, ...] = KNOWN_COLUMNS) -> list[str]:
    """What reading ``path`` with ``mapping`` converted or left unread, in words (empty: read as it is)."""
    from .soilmodel.logread import is_bag

    if is_bag(path):  # a ROS bag: its topics, units and resampling (soilmodel.rosbag_read)
        from .soilmodel.rosbag_read import bag_notes

        return bag_notes(path)
    try:
        head = read_header(path)
    except DataError:  # the reader itself says why
        return []
    return list(plan_columns(head, known=known, mapping=mapping, source=path).notes)


def with_column_notes(text: str, notes: list[str], as_json: bool) -> str:
    """``text`` (a report, or one JSON object when ``as_json``) with the column notes in it."""
    if as_json:
        obj = json.loads(text)
        if isinstance(obj, dict):
            obj["columns_read"] = list(notes)
            return json.dumps(obj, indent=2)  # the same numbers as the text it came from
        return text
    if not notes:
        return text
    return "columns: " + "; ".join(notes) + "\n" + text
