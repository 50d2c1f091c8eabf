"""The ``soiltrack`` command: one subcommand per job, each in its own ``cmd_*`` module.

Exit status: 0 success; 1 the solver failed or its answer is not usable (results are still
printed, with the reason); 2 bad input (the message names the file, the column and the row;
no traceback).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from typing import Sequence

from .cliutil import EXIT_INPUT, EXIT_OK
from .soilmodel import DataError

#: Subcommand modules, in the order of the help text; each has ``add_parser(subparsers)``.
COMMAND_MODULES = (
    "cmd_simulate",
    "cmd_fit",
    "cmd_track",
    "cmd_margin",
    "cmd_profile",
    "cmd_route",
    "cmd_diagnose",
    "cmd_drive",
    "cmd_predict",
    "cmd_fleet",
)

EPILOG = """\
exit status:
  0  success
  1  the solver failed or its answer is not usable (the report or JSON is still printed, with the reason)
  2  bad input: the message names the file, column or argument, and the row

example:
  soiltrack simulate --kind sweep --vehicle light --terrain sandy_loam --loads 300,450 --seed 1 -o sweep.csv
  soiltrack fit sweep.csv --vehicle light --plot fit.png

'soiltrack COMMAND --help' describes each command."""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``soiltrack`` command."""
    p = argparse.ArgumentParser(
        prog="soiltrack",
        description="Soil-parameter identification and traversability for tracked vehicles.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    from . import __version__

    p.add_argument("--version", action="version", version=f"soiltrack {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(f"{__package__}.{name}").add_parser(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv:  # bare `soiltrack`: the help, not a usage error (a new user's first command)
        parser.print_help()
        return EXIT_OK
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except DataError as e:
        print(f"soiltrack {args.command}: error: {e}", file=sys.stderr)
        return EXIT_INPUT
    except BrokenPipeError:  # pragma: no cover
        return EXIT_OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
