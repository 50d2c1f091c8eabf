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
