"""Memory and time of a drive-log fit, estimated from the row count before the work, and the limit it must fit.

A fit that the machine cannot hold must be refused with the numbers, not killed by the kernel's
out-of-memory killer half way (issue 40: a 2,000,000-row log took 24 GB and was killed with no
message). The estimate is a linear model of the measured cost per row of each way of fitting,
``base + per_row * rows`` bytes and ``per_row_s * rows`` seconds, with the constants measured by
``python benchmarks/bench_scale.py`` on this project's 2-core machine (shared: the times are those
of a loaded machine, the memory is not affected). The memory constants carry a 25 % margin over the
measured slopes; the times are rough (a factor of 2 either way on another machine).

The limit: ``--max-memory BYTES`` (suffixes k, M, G), or ``auto`` (the default) =
:data:`AVAILABLE_FRACTION` of the memory the kernel reports available (``MemAvailable`` of
``/proc/meminfo``; elsewhere ``os.sysconf``'s available physical pages).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

from ...soilmodel.csvread import count_rows
from ...soilmodel.errors import DataError
from .nlp import padded_size

__all__ = [
    "FitCost",
    "estimate_fit_cost",
    "available_memory",
    "memory_limit",
    "parse_memory",
    "count_rows",
    "check_fit_budget",
    "AVAILABLE_FRACTION",
]

#: Fraction of the available memory a fit may use by default (``--max-memory auto``): the rest is left to
#: the other processes of a shared machine and to the estimate's error.
AVAILABLE_FRACTION = 0.5
#: Memory of the process before any data (Python, numpy, CasADi loaded, the kernels), bytes; measured 52-70 MB
#: at start, but the profiled fit's peak has a larger fixed part: on logs from independent code (light vehicle,
#: 50 Hz) 295 MB at 180,000 rows and 1,675 MB at 2,000,000 (``/usr/bin/time -v soiltrack fit LOG --vehicle light
#: --json``), a slope of 0.76 kB a row over about 160 MB; 80 MB here under-estimated the hour (260 MB).
BASE_BYTES = 160e6
#: Peak bytes per row, by way of fitting (measured slope x 1.25). "profiled": the nominal fit with the latent
#: slips eliminated (:mod:`.profiled`; measured 131 MB at 50,000 rows, 217 MB at 180,000, 1,617 MB at 2,000,001:
#: 0.6-0.8 kB per row, reading, the discretisation check and the JSON output included); "ipopt": one IPOPT
#: variable per slip, per padded sample (measured 73-75 kB);
#: "joint": fits with effects (IPOPT over the mapped kernels; measured 4.1 kB per padded sample).
BYTES_PER_ROW = {"profiled": 1.0e3, "ipopt": 94e3, "joint": 5.2e3}
#: Seconds per row, by way of fitting, on the loaded 2-core machine (the CLI's two fits of the discretisation
#: check included): profiled 0.16 ms (CPU time on logs from independent code: 28 s on 180,000 rows, 313 s on
#: 2,000,000; the wall time is several times that under load), ipopt 3.1 ms, joint 3.3 ms.
SECONDS_PER_ROW = {"profiled": 1.6e-4, "ipopt": 3.1e-3, "joint": 3.3e-3}
#: Most rows fitted with IPOPT's latent slips under ``latent_slips="auto"`` (= :data:`.fit.PROFILED_ABOVE`,
#: counted on rows: the used samples are fewer).
_IPOPT_ROWS = 10_000


@dataclass(frozen=True)
class FitCost:
    """Estimated peak memory and time of one fit of ``rows`` rows.

    ``how`` is the way of fitting the estimate is for (``"profiled"``, ``"ipopt"``, ``"joint"``).
    """

    rows: int
    how: str
    bytes: float
    seconds: float

    def text(self) -> str:
        """The estimate in words."""
        mem = format_bytes(self.bytes)
        return f"about {mem} of memory and {self.seconds:.0f} s ({self.how} fit of {self.rows:,} rows)"


def format_bytes(x: float) -> str:
    """``x`` bytes as kB, MB or GB (decimal)."""
    for unit, f in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if x >= f:
            return f"{x / f:.3g} {unit}"
    return f"{x:.0f} B"


def estimate_fit_cost(rows: int, *, effects: bool = False, latent_slips: str = "auto") -> FitCost:
    """Peak memory (bytes) and time (s) of a drive-log fit of ``rows`` rows, from the measured per-row costs.

    ``effects``: a fit with unmodelled effects (the joint IPOPT problem); ``latent_slips`` as for
    :func:`~.fit.fit_drive_log` (``"auto"`` profiles the slips out above 10,000 rows).
    """
    rows = int(rows)
    if rows < 0:
        raise ValueError(f"estimate_fit_cost: rows must be >= 0, got {rows}")
    if effects:
        how = "joint"
    elif latent_slips == "ipopt" or (latent_slips == "auto" and rows <= _IPOPT_ROWS):
        how = "ipopt"
    else:
        how = "profiled"
    per = padded_size(max(rows, 1)) if how in ("ipopt", "joint") else rows
    return FitCost(rows, how, BASE_BYTES + BYTES_PER_ROW[how] * per, SECONDS_PER_ROW[how] * rows)


def available_memory() -> float | None:
    """Memory the kernel reports available, bytes (``MemAvailable``; else ``os.sysconf``); None if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES")) * float(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


_UNITS = {"": 1.0, "k": 1e3, "m": 1e6, "g": 1e9, "t": 1e12, "kib": 1024.0, "mib": 1024.0**2, "gib": 1024.0**3}


def parse_memory(text: str, option: str = "--max-memory") -> float | None:
    """``BYTES`` (a number with an optional k, M, G, T, KiB, MiB, GiB suffix; ``B`` allowed) or ``auto`` (None)."""
    t = str(text).strip()
    if t.lower() == "auto":
        return None
    m = re.fullmatch(r"([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([kKmMgGtT](?:i[bB])?)?[bB]?", t)
    if not m:
        raise DataError(f"{option} expects a number of bytes (suffix k, M, G, e.g. 2G) or auto, got {text!r}")
    val = float(m.group(1)) * _UNITS[(m.group(2) or "").lower()]
    if not (math.isfinite(val) and val > 0):
        raise DataError(f"{option} expects a number of bytes > 0 or auto, got {text!r}")
    return val


def memory_limit(max_memory: float | None = None) -> tuple[float | None, str]:
    """The limit in force, bytes (None: unknown, no check) and where it comes from, in words."""
    if max_memory is not None:
        return float(max_memory), "--max-memory"
    avail = available_memory()
    if avail is None:
        return None, "the available memory is unknown"
    return AVAILABLE_FRACTION * avail, (
        f"--max-memory auto: {AVAILABLE_FRACTION:.0%} of the {format_bytes(avail)} the machine has available"
    )


def check_fit_budget(
    rows: int,
    *,
    source: str | None = None,
    max_memory: float | None = None,
    effects: bool = False,
    latent_slips: str = "auto",
    extra_bytes: float = 0.0,
    what: str | None = None,
) -> FitCost:
    """The estimate of a fit (:func:`estimate_fit_cost`, plus ``extra_bytes``), or a DataError (exit 2) naming it,
    the limit (:func:`memory_limit`) and the options when the limit cannot hold it. ``what`` names the work
    in the message (default: the fit)."""
    cost = estimate_fit_cost(rows, effects=effects, latent_slips=latent_slips)
    if extra_bytes:
        cost = FitCost(cost.rows, cost.how, cost.bytes + float(extra_bytes), cost.seconds)
    limit, why = memory_limit(max_memory)
    if limit is not None and cost.bytes > limit:
        raise DataError(
            f"{what or 'this fit'} would need {cost.text()}, more than the limit of {format_bytes(limit)} "
            f"({why}); refused before the work. Options: decimate the log (keep every k-th row; a coarser log "
            "resolves the slip's response to torque steps less well), fit it in segments (--segments 60s or "
            "--segments auto: the memory of the log's columns and one fit of at most 100,000 rows), or raise "
            f"the limit (--max-memory BYTES, e.g. --max-memory {max(1, math.ceil(cost.bytes / 1e9))}G)",
            file=source,
        )
    return cost
