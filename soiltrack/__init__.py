"""soiltrack: soil-parameter identification and traversability planning for tracked vehicles.

One import package with three subpackages:

- :mod:`soiltrack.soilmodel` - the vehicle and track-terrain model (CasADi), effects, simulator, data I/O;
- :mod:`soiltrack.identify` - bounded IPOPT identification, the seed's methods, uncertainty, diagnosis;
- :mod:`soiltrack.planning` - traversability margins and traction planning.
"""

from __future__ import annotations

import os as _os

__version__ = "0.1.0"

# Running from a source checkout (repository root on sys.path, package not installed in
# this layout): the subpackages live in sibling folders, so let the import system find them.
_here = _os.path.dirname(_os.path.abspath(__file__))
_root = _os.path.dirname(_here)
if not _os.path.isdir(_os.path.join(_here, "soilmodel")) and _os.path.isfile(
    _os.path.join(_root, "soilmodel", "__init__.py")
):
    __path__.append(_root)  # type: ignore[name-defined]  # noqa: F821

from . import soilmodel  # noqa: E402
from .soilmodel import (  # noqa: E402
    TERRAINS,
    VEHICLES,
    Soil,
    Vehicle,
    read_csv,
    simulate,
    tractive_force,
)

from . import identify, planning  # noqa: E402
from .identify import FitResult, fit, fit_many  # noqa: E402

__all__ = [
    "__version__",
    "soilmodel",
    "identify",
    "planning",
    "FitResult",
    "TERRAINS",
    "VEHICLES",
    "Soil",
    "Vehicle",
    "read_csv",
    "simulate",
    "tractive_force",
    "fit",
    "fit_many",
]
