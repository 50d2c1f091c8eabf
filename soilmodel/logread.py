"""One place that turns a path into data: a CSV (:func:`~.data.read_csv`) or a ROS bag (:mod:`.rosbag_read`).

Used by ``fit_many`` for the paths of a fleet (read in the worker) and by the command line
(``soiltrack.cliutil.read_data_arg``), so that a bag is taken wherever a drive-log CSV is.
"""

from __future__ import annotations

import os
from typing import Any

from .errors import DataError

__all__ = ["is_bag", "read_data", "read_two_track_data", "data_columns", "BAG_SUFFIXES"]

#: File endings of ROS bags: ROS 1 ``.bag``, ROS 2 SQLite ``.db3``, MCAP ``.mcap``.
BAG_SUFFIXES = (".bag", ".db3", ".mcap")


def is_bag(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a ROS bag: a ``.bag``/``.db3``/``.mcap`` file, or a ROS 2 bag folder (``metadata.yaml``)."""
    p = os.fspath(path)
    if os.path.isdir(p):
        return os.path.isfile(os.path.join(p, "metadata.yaml"))
    return p.lower().endswith(BAG_SUFFIXES)


def read_data(path: str | os.PathLike, *, topics: Any = None, **csv_options: Any):
    """The data of ``path``: a ROS bag read as a drive log through ``topics``, else :func:`~.data.read_csv`.

    Parameters
    ----------
    path
        A CSV file or a ROS bag (:func:`is_bag`).
    topics
        The bag's mapping (:func:`~.rosbag_read.parse_topics`: ``"NAME=TOPIC:FIELD,..."``, a JSON file or a
        dict); required for a bag, refused for a CSV.
    **csv_options
        Keywords of :func:`~.data.read_csv` (``columns``, ``max_rows``, ...).
    """
    if is_bag(path):
        from .rosbag_read import read_bag

        if topics is None:
            raise DataError(
                "a ROS bag needs --topics NAME=TOPIC:FIELD[,...] (or a JSON mapping file) to map its messages "
                "onto the drive log's columns",
                file=os.fspath(path),
            )
        extra = {k: v for k, v in csv_options.items() if v not in (None, False)}
        if extra:
            raise DataError(f"option(s) {sorted(extra)} apply to CSV files, not to a ROS bag", file=os.fspath(path))
        return read_bag(path, topics)
    if topics is not None:
        raise DataError("--topics applies to ROS bags (.bag, .db3, .mcap, a bag folder) only", file=os.fspath(path))
    from .data import read_csv

    return read_csv(path, **csv_options)


def data_columns(path: str | os.PathLike, *, topics: Any = None) -> list[str]:
    """The columns ``path`` gives: a CSV's header, or a bag's mapped columns (with ``time_s``) through ``topics``."""
    if is_bag(path):
        from .rosbag_read import parse_topics

        if topics is None:
            return []
        return ["time_s", *parse_topics(topics).topics]
    from .csvread import read_header

    return read_header(os.fspath(path))


def read_two_track_data(path: str | os.PathLike, *, topics: Any = None):
    """A two-track drive log keeping each track's channels (:class:`~.turning.TwoTrackLog`): from a CSV
    (:func:`~.turning.read_two_track`) or from a ROS bag through ``topics`` (the bag's channels resampled
    onto one clock as for :func:`read_data`); DataError naming the file and the missing column."""
    from .turning import read_two_track, two_track_log_from_columns

    if not is_bag(path):
        return read_two_track(path)
    from .rosbag_read import read_bag_columns

    p = os.fspath(path)
    if topics is None:
        read_data(p)  # the same refusal as a straight-line fit's: a bag needs --topics
    cols, _ = read_bag_columns(p, topics, two_track=True)
    return two_track_log_from_columns(cols, source=p)
