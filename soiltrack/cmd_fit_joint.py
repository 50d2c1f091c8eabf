"""``soiltrack fit A.csv B.csv ... [--vehicle a.json --vehicle b.json ...]``: one soil for several data sets."""

from __future__ import annotations

import argparse
import copy
import sys

from .cliutil import running_gear_arg
from .identify.outcome import exit_code
from .columns_cli import columns_arg
from .soilmodel import DataError
from .soilmodel.rigid_wheel import RigidWheel
from .soilmodel.vehicle import Vehicle

__all__ = ["single_file_args", "joint_fit_command"]

#: Options refused in a joint fit, with their defaults.
_REFUSED = {"plot": None, "segments": None, "negative_kc": False, "method": "ipopt", "sigma": None, "resistance": None}


def single_file_args(a: argparse.Namespace) -> bool:
    """Turn ``a.data`` / ``a.vehicle`` (lists) into one file and one vehicle; False when several files are given."""
    files = list(a.data) if isinstance(a.data, (list, tuple)) else [a.data]
    vehicles = a.vehicle if isinstance(a.vehicle, (list, tuple)) else ([] if a.vehicle is None else [a.vehicle])
    if len(files) > 1:
        a.data, a.vehicle = files, list(vehicles)
        return False
    if len(vehicles) > 1:
        raise DataError(f"--vehicle given {len(vehicles)} times for one file ({files[0]}): give it once")
    if getattr(a, "fit_grouser_height", False):
        raise DataError(
            "--fit-grouser-height needs several files: on one wheel the grouser height is confounded with c and "
            "phi (fit it beside a smooth wheel of the same soil)"
        )
    a.data, a.vehicle = files[0], (vehicles[0] if vehicles else None)
    return True


def _read(a: argparse.Namespace, path: str, gear, read_record):
    """One file as a wheel sweep (with a rigid wheel), a track sweep or a drive log (with a tracked vehicle) or a
    bevameter test (shear, annulus, plate)."""
    from .soilmodel import DriveLog, PlateTest, ShearTest, SlipData, read_csv
    from .soilmodel.wheel_sweep import read_wheel_sweep

    from .soilmodel.csvread import read_header

    if isinstance(gear, RigidWheel) and "slip" in read_header(path) + [n for n, _ in _mapped(a)]:
        return read_wheel_sweep(path, driving_only=a.driving_only, slip_angle=a.slip_angle, columns=columns_arg(a))
    one = copy.copy(a)
    one.data = path
    record = read_record(one)
    if record is not None:
        return record
    data = read_csv(path, columns=columns_arg(a))
    if isinstance(data, (ShearTest, PlateTest)) or (
        isinstance(data, (SlipData, DriveLog)) and isinstance(gear, Vehicle)
    ):
        return data
    raise DataError(
        "a joint fit takes wheel sweeps (--vehicle WHEEL.json), track sweeps and drive logs (--vehicle VEHICLE) and "
        f"bevameter tests; this file is a {type(data).__name__}"
        + (" without a --vehicle" if gear is None else f" with a {type(gear).__name__}"),
        file=path,
    )


def _mapped(a: argparse.Namespace) -> list[tuple[str, str]]:
    """The ``--columns`` pairs (library name, source)."""
    m = columns_arg(a) or {}
    return list(m.items()) if isinstance(m, dict) else list(m)


def joint_fit_command(a: argparse.Namespace, read_record) -> int:
    """Fit the files ``a.data`` on one soil; exit 0 when the joint fit is usable, 1 otherwise, 2 for bad input.

    ``read_record(namespace)``: the file ``namespace.data`` as a bevameter record, or None (``fit``'s reader).
    """
    from .identify import fit
    from .wheel_cli import wheel_effects_arg, wheel_fixed_arg, wheel_settings_arg

    files, vehicles = a.data, a.vehicle
    if len(vehicles) not in (0, 1, len(files)):
        raise DataError(
            f"--vehicle: give it once for all {len(files)} files or once per file in order ({len(files)}), "
            f"got {len(vehicles)}"
        )
    for name, default in _REFUSED.items():
        if getattr(a, name, default) != default:
            raise DataError(f"--{name.replace('_', '-')} does not apply to a joint fit of several files (yet)")
    gears: list[Vehicle | RigidWheel | None] = [running_gear_arg(v) for v in vehicles]
    per_file = gears * len(files) if len(gears) == 1 else (gears or [None] * len(files))
    datasets = [_read(a, path, g, read_record) for path, g in zip(files, per_file)]
    free_h = [
        k
        for k, g in enumerate(per_file)
        if getattr(a, "fit_grouser_height", False) and isinstance(g, RigidWheel) and g.grouser_height > 0
    ]
    if getattr(a, "fit_grouser_height", False) and not free_h:
        raise DataError("--fit-grouser-height: no wheel of these files has grouser_height_m > 0 in its JSON")
    result = fit(
        datasets,
        per_file,
        free_grousers=free_h,
        effects=wheel_effects_arg(a, wheel_only=not any(isinstance(g, Vehicle) for g in per_file)),
        fixed=wheel_fixed_arg(getattr(a, "fix", None), a.model),
        wheel_settings=wheel_settings_arg(a),
        labels=list(files),
    )
    print(result.to_json() if a.json else result.report())
    if not a.json:
        print(f"(one soil for {len(files)} files; --json gives datasets and consistency)", file=sys.stderr)
    return exit_code(result.fit_outcome)
