"""``python -m soiltrack`` runs the command-line tool."""

import sys

from .cli import main

if __name__ == "__main__":  # imported (e.g. by a documentation tool), it does nothing
    sys.exit(main())
