#!/usr/bin/env python
"""False flags and detection of :func:`soiltrack.identify.diagnosis.gap.isolated_outliers` (lone readings).

Three series kinds, each 60 samples:

* residuals like the independent sweeps' (force noise 650 N plus slip noise 0.001 times dF/di of
  a soil with F_max = 200 kN, K = 12 mm, track 2.8 m; 1,000 draws): false flags, and how often
  a single glitch of 7 kN at a random row is found;
* Gaussian white noise (4,000 draws): false flags;
* white noise whose level grows 15-fold along the series (2,000 draws): false flags.

Run:  python benchmarks/outlier_rates.py
"""

from __future__ import annotations

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from soiltrack.identify.diagnosis.gap import isolated_outliers  # noqa: E402


def main() -> int:
    i = np.linspace(0.02, 0.7, 60)
    fmax, k_m, length = 2e5, 0.012, 2.8
    x = i * length / k_m
    dfdi = fmax * (1 - np.exp(-x) * (1 + x)) / (i * x)  # d/di of F_max (1 - (1 - exp(-x)) / x)
    sd = np.sqrt(650.0**2 + (0.001 * dfdi) ** 2)
    rng = np.random.default_rng(0)
    false = found = 0
    for _ in range(1000):
        e = rng.normal(0.0, 1.0, 60) * sd
        false += bool(isolated_outliers(e, i))
        k = int(rng.integers(5, 55))
        g = e.copy()
        g[k] += rng.choice([-1.0, 1.0]) * 7000.0
        found += any(j == k for j, _ in isolated_outliers(g, i))
    print(f"sweep-like residuals: false flags {false}/1000, a 7 kN glitch found {found}/1000")
    rng = np.random.default_rng(0)
    g = sum(bool(isolated_outliers(rng.normal(size=60), np.arange(60))) for _ in range(4000))
    print(f"Gaussian white noise: false flags {g}/4000")
    rng = np.random.default_rng(2)
    h = sum(
        bool(isolated_outliers(rng.normal(size=60) * np.linspace(0.2, 3.0, 60), np.arange(60))) for _ in range(2000)
    )
    print(f"noise growing 15-fold along the series: false flags {h}/2000")
    return 0


if __name__ == "__main__":
    import argparse

    argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0]).parse_args()
    raise SystemExit(main())
