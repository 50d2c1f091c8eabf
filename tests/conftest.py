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


def independent_sweep(path, seed: int, **kw):
    """A sweep CSV from the plain-numpy oracle of ``benchmarks/independent_check.py`` (not soilmodel), read back."""
    import importlib.util

    from soiltrack.soilmodel import read_csv

    spec = importlib.util.spec_from_file_location("independent_check",
                                                  os.path.join(ROOT, "benchmarks", "independent_check.py"))
    ic = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ic)
    ic.sweep_csv(str(path), seed, **kw)
    return read_csv(str(path))
