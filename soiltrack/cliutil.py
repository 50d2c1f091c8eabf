"""Shared pieces of the ``soiltrack`` command: exit codes, vehicle and soil arguments.

Exit status: 0 success; 1 the solver failed (results are still printed, with the reason);
2 bad input (the message names the file, the column and the row; no traceback).
"""

from __future__ import annotations

import math
import os
import sys

from .soilmodel import PRACTICAL_BOUNDS, TERRAINS, VEHICLES, WIDE_BOUNDS, DataError, Soil, Vehicle
from .soilmodel.rigid_wheel import RigidWheel, read_running_gear

EXIT_OK, EXIT_SOLVER, EXIT_INPUT = 0, 1, 2


def vehicle_arg(arg: str) -> Vehicle:
    """A preset name or a vehicle JSON path -> :class:`Vehicle` (DataError naming the file)."""
    if arg in VEHICLES:
        return VEHICLES[arg]
    if not os.path.exists(arg):
        raise DataError(f"no such vehicle file, and not a preset name (presets: {sorted(VEHICLES)})", file=arg)
    return Vehicle.from_json(arg)


def running_gear_arg(arg: str) -> Vehicle | RigidWheel:
    """A preset name, a vehicle JSON or a rigid-wheel JSON (``"running_gear": "rigid_wheel"``)."""
    if arg in VEHICLES:
        return VEHICLES[arg]
    if not os.path.exists(arg):
        raise DataError(f"no such vehicle file, and not a preset name (presets: {sorted(VEHICLES)})", file=arg)
    return read_running_gear(arg)


def soil_arg(terrain: str | None, soil: str | None) -> Soil:
    """``--terrain NAME`` or ``--soil C_KPA,PHI_DEG,K_M`` -> :class:`Soil` (default LETE sand)."""
    if soil:
        parts = soil.split(",")
        if len(parts) != 3:
            raise DataError(f"--soil expects C_KPA,PHI_DEG,K_M (three numbers), got {soil!r}")
        try:
            c, phi, K = (float(p) for p in parts)
        except ValueError:
            raise DataError(f"--soil expects three numbers C_KPA,PHI_DEG,K_M, got {soil!r}") from None
        for w in check_soil(c, phi, K, "--soil"):
            print(f"soiltrack: warning: {w}", file=sys.stderr)
        return Soil.from_kpa_deg(c, phi, K, name=f"soil c = {c:g} kPa, phi = {phi:g} deg, K = {K:g} m")
    key = terrain or "lete_sand"
    if key not in TERRAINS:
        raise DataError(f"unknown terrain {key!r}; presets: {sorted(TERRAINS)}")
    return TERRAINS[key]


def check_soil(c_kpa: float, phi_deg: float, K_m: float, what: str = "--soil") -> list[str]:
    """Check a soil given at the edges (kPa, deg, m) like a vehicle file; returns warnings.

    Outside the range a measured soil can have (``WIDE_BOUNDS``: c 0-200 kPa, phi 1-55 deg, K
    0.002-0.25 m) it is refused (DataError naming ``what``, the parameter and the unit it was
    probably given in: K in mm, phi in radians, c in Pa); outside the seed's practical range
    (``PRACTICAL_BOUNDS``) it is accepted with a warning, to be printed on stderr.
    """
    vals = {"c": c_kpa, "phi": phi_deg, "K": K_m}
    bad = [k for k, v in vals.items() if not math.isfinite(v)]
    if bad:
        raise DataError(f"{what}: {', '.join(bad)} must be a finite number")
    # the unit a number beyond the range was probably given in (too large: Pa, mm; too small: radians)
    hints = {
        "c": lambda v, high: f" (if that is Pa, it is {v / 1e3:.4g} kPa)" if high else "",
        "phi": lambda v, high: (
            f" (if that is radians, it is {math.degrees(v):.4g} deg)" if not high and 0 < math.degrees(v) < 90 else ""
        ),
        "K": lambda v, high: f" (if that is mm, it is {v / 1e3:.4g} m)" if high else "",
    }
    units = {"c": "kPa", "phi": "deg", "K": "m"}
    warnings = []
    for j, key in enumerate(vals):
        v = vals[key]
        f = (1e-3, 180.0 / math.pi, 1.0)[j]  # SI -> edge unit (kPa, deg, m)
        lo, hi = WIDE_BOUNDS.lower[j] * f, WIDE_BOUNDS.upper[j] * f
        plo, phi_ = PRACTICAL_BOUNDS.lower[j] * f, PRACTICAL_BOUNDS.upper[j] * f
        if not lo <= v <= hi:
            raise DataError(
                f"{what}: {key} = {v:g} {units[key]} is outside the range of measured soils "
                f"[{lo:g}, {hi:g}] {units[key]}{hints[key](v, v > hi)}; expected "
                "C_KPA,PHI_DEG,K_M"
            )
        if not plo <= v <= phi_:
            warnings.append(
                f"{what}: {key} = {v:g} {units[key]} is outside the practical range "
                f"[{plo:g}, {phi_:g}] {units[key]} (the default bounds of a fit)"
                f"{hints[key](v, v > phi_)}: check the number and its unit"
            )
    return warnings


def floats_arg(text: str, what: str) -> list[float]:
    """Comma-separated finite numbers of the argument ``what`` (DataError otherwise)."""
    try:
        vals = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise DataError(f"{what} expects comma-separated numbers, got {text!r}") from None
    if not vals or not all(math.isfinite(v) for v in vals):
        raise DataError(f"{what} expects finite numbers, got {text!r}")
    return vals


#: Most samples a simulated drive log may have (a one-hour log at 500 Hz is 1.8 million).
MAX_SAMPLES = 2_000_000


def figure_formats() -> dict[str, str]:
    """File extensions matplotlib can write (``{"png": "Portable Network Graphics", ...}``)."""
    from matplotlib.figure import Figure

    return Figure().canvas.get_supported_filetypes()


def output_path(path: str, option: str, *, figure: bool = False) -> str:
    """Check an output path before any work is done (DataError naming the option otherwise).

    The folder must exist (the missing folders of a relative path are created, said on stderr) and
    the path must not be a folder, and it must open for writing (probed, then removed if it did not
    exist); a figure path must end in an extension matplotlib writes (``.png``, ``.pdf``, ``.svg``,
    ...), so that nothing is silently written under another name.
    """
    if not path or not path.strip():
        raise DataError(f"{option} needs a file name")
    if os.path.isdir(path):
        raise DataError(
            f"{option} {path!r} is a folder; give a file name inside it, e.g. "
            f"{os.path.join(path, 'fit.png' if figure else 'out.csv')!r}"
        )
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder) and not os.path.isabs(path):
        _make_folder(folder, path, option)
    if not os.path.isdir(folder):
        raise DataError(f"{option} {path!r}: the folder {folder!r} does not exist")
    if not os.access(folder, os.W_OK):
        raise DataError(f"{option} {path!r}: the folder {folder!r} is not writable")
    if figure:
        _check_figure_format(path, option)
    _probe_write(path, option)
    return path


def _make_folder(folder: str, path: str, option: str) -> None:
    """Create the missing folders of a relative output path (``-o out/sweep.csv`` in a fresh clone), said on stderr.

    Only for a relative path: a missing folder of an absolute path is more likely a typo, and is refused.
    """
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as e:
        raise DataError(f"{option} {path!r}: cannot create the folder {folder!r}: {e.strerror or e}") from None
    print(f"soiltrack: created the folder {os.path.relpath(folder)!r} for {option}", file=sys.stderr)


def _probe_write(path: str, option: str) -> None:
    """Open ``path`` for appending (and remove it again if it did not exist): the path can be written.

    ``os.access`` says yes to root everywhere (``/proc``, read-only mounts); only an open tells.
    """
    existed = os.path.exists(path)
    try:
        with open(path, "ab"):
            pass
    except OSError as e:
        raise DataError(f"{option} {path!r}: cannot be written: {e.strerror or e}") from None
    if not existed:
        try:
            os.remove(path)
        except OSError:  # pragma: no cover - written a moment ago
            pass


def _check_figure_format(path: str, option: str) -> None:
    """A figure path must end in an extension matplotlib writes."""
    ext = os.path.splitext(path)[1].lower().lstrip(".")
    formats = figure_formats()
    if ext not in formats:
        raise DataError(
            f"{option} {path!r}: "
            + (f"unknown figure format '.{ext}'" if ext else "no file extension")
            + f"; use one of {', '.join('.' + e for e in sorted(formats))} (e.g. fit.png)"
        )


def read_data_arg(a, path: str, **csv_options):
    """The one place a command turns a data path into data: a CSV (``read_csv``) or a ROS bag (``--topics``)."""
    from .soilmodel.logread import read_data

    return read_data(path, topics=getattr(a, "topics", None), **csv_options)


def drive_stream_arg(a, path: str, columns: dict[str, str] | None = None):
    """A drive log read chunk by chunk for a replay (``DriveStreamReader``), or a ROS bag's (one chunk)."""
    from .soilmodel.logread import is_bag

    if is_bag(path):
        from .soilmodel.rosbag_read import BagStreamReader

        return BagStreamReader(path, getattr(a, "topics", None), columns=columns)
    from .soilmodel.drive_stream import DriveStreamReader

    return DriveStreamReader(path, columns=columns)
