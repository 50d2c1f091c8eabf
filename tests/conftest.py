import os

import matplotlib
from hypothesis import settings

matplotlib.use("Agg")

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Reproducible property tests (same examples on every run and in CI); set HYPOTHESIS_PROFILE=explore
# to search with fresh random examples.
settings.register_profile("repeatable", derandomize=True, deadline=None, print_blob=True)
settings.register_profile("explore", deadline=None, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "repeatable"))


def bench_module(name: str):
    """A script of ``benchmarks/`` (their plain-numpy data makers, not soilmodel), loaded as a module."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, os.path.join(ROOT, "benchmarks", name + ".py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def independent_check():
    """The plain-numpy oracle ``benchmarks/independent_check.py`` (not soilmodel), loaded as a module."""
    return bench_module("independent_check")


def independent_sweep(path, seed: int, **kw):
    """A sweep CSV from the plain-numpy oracle of ``benchmarks/independent_check.py``, read back."""
    from soiltrack.soilmodel import read_csv

    independent_check().sweep_csv(str(path), seed, **kw)
    return read_csv(str(path))


def independent_log(path, seed: int, edit=None, **kw):
    """A drive-log CSV from the plain-numpy oracle (heavy vehicle, 60 s at 20 Hz), read back.

    ``edit(a)`` changes the array of the CSV's columns (time, torque, sprocket speed, vehicle speed,
    acceleration) in place before it is written back: glitches, a scaled channel.
    """
    import numpy as np

    from soiltrack.soilmodel import read_csv

    independent_check().log_csv(str(path), seed, **kw)
    if edit is not None:
        a = np.loadtxt(str(path), delimiter=",", skiprows=1)
        edit(a)
        np.savetxt(
            str(path),
            a,
            delimiter=",",
            comments="",
            fmt="%.6g",
            header="time_s,sprocket_torque_Nm,sprocket_speed_rad_s,vehicle_speed_m_s,vehicle_accel_m_s2",
        )
    return read_csv(str(path))
