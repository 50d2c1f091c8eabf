"""``soiltrack fleet LOG... --vehicle V --out results.csv``: many drive logs fitted in parallel, one row each.

The logs are fitted by :func:`~soiltrack.identify.fit_many` (each read in its worker) on a process pool
(``--workers``) or a dask cluster (``--scheduler ADDRESS``, or ``local`` for a LocalCluster; needs
``soiltrack[dask]``); the rows are written to ``--out`` as the fits finish
(:mod:`soiltrack.identify.fleet`); a log that cannot be read or fitted gets a row with its reason.
"""

from __future__ import annotations

import argparse
import contextlib
import multiprocessing
import sys
from collections import Counter

from .cliutil import EXIT_OK, EXIT_SOLVER, output_path, vehicle_arg
from .soilmodel import DataError

__all__ = ["add_parser"]


@contextlib.contextmanager
def _executor(a: argparse.Namespace):
    """The executor of ``--scheduler`` / ``--workers``, shut down after the fleet."""
    if a.scheduler is None:
        from concurrent.futures import ProcessPoolExecutor

        ctx = multiprocessing.get_context("fork") if "fork" in multiprocessing.get_all_start_methods() else None
        with ProcessPoolExecutor(a.workers, mp_context=ctx) as ex:
            yield ex
        return
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise DataError("--scheduler needs dask.distributed: pip install 'soiltrack[dask]'") from None
    if a.scheduler == "local":
        with (
            LocalCluster(n_workers=a.workers, threads_per_worker=1, dashboard_address=None) as cl,
            Client(cl) as client,
        ):
            yield client.get_executor()
        return
    try:
        client = Client(a.scheduler, timeout="20s")
    except OSError as e:
        raise DataError(f"cannot reach the dask scheduler {a.scheduler!r}: {e}") from None
    with client:
        yield client.get_executor()


def _cmd_fleet(a: argparse.Namespace) -> int:
    from .identify import fit_many
    from .identify.segments import parse_segments

    if a.workers < 1:
        raise DataError(f"--workers must be >= 1, got {a.workers}")
    if a.segments is not None:
        parse_segments(a.segments)  # a bad duration refused before the work
    vehicle = vehicle_arg(a.vehicle)
    out = output_path(a.out, "--out")
    with _executor(a) as ex:
        results = fit_many(
            a.logs, vehicle, executor=ex, chunk_size=1, out=out, segments=a.segments, topics=a.topics, progress=True
        )
    outcomes: Counter = Counter()
    for r in results:
        segs = getattr(r, "segments", None)
        if segs is not None:
            outcomes.update(s.outcome for s in segs)
        else:
            outcomes["failed" if r.status == "not fitted" else r.to_dict()["outcome"]] += 1
    said = ", ".join(f"{n} {k}" for k, n in sorted(outcomes.items()))
    print(f"soiltrack fleet: {len(results)} logs, rows in {out}: {said}")
    for k, r in enumerate(results):
        if getattr(r, "status", None) == "not fitted":
            print(f"soiltrack fleet: {r.message}", file=sys.stderr)
    return EXIT_OK if set(outcomes) <= {"usable"} else EXIT_SOLVER


def add_parser(sub) -> None:
    """Register the ``fleet`` subcommand."""
    p = sub.add_parser(
        "fleet",
        help="many drive logs fitted in parallel (a process pool or a dask cluster), one row each in a CSV",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example:\n  soiltrack fleet runs/*.csv --vehicle light --out fleet.csv --workers 2\n"
        "  soiltrack fleet runs/*.csv --vehicle light --out map.csv --segments 60s --scheduler local",
    )
    p.add_argument("logs", nargs="+", help="drive-log CSV files or ROS bags (with --topics)")
    p.add_argument(
        "--topics", metavar="NAME=TOPIC:FIELD[,...]|MAP.json", default=None, help="the ROS bags' mapping (as fit)"
    )
    p.add_argument("--vehicle", required=True, help="vehicle JSON file or preset name (heavy, light)")
    p.add_argument(
        "--out",
        required=True,
        help="results file: one row per log (or per segment), written as the fits finish (CSV; .parquet with pyarrow)",
    )
    p.add_argument("--segments", metavar="DURATION|auto", default=None, help="a soil map per log (as fit --segments)")
    p.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS|local",
        default=None,
        help="run on a dask cluster: a scheduler's address (tcp://host:8786) or local (a LocalCluster of --workers)",
    )
    p.set_defaults(func=_cmd_fleet)
