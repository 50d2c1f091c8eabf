"""estimate_noise_profile's bin statistics from one sort per bin size: np.median's numbers, bin by bin, bit for bit."""

from __future__ import annotations

import numpy as np

from soiltrack.identify.drivelog import noise as NZ


def _parts(x):
    d = x[3:-1] - 2.0 * x[2:-2] + x[1:-3]
    xc = 0.5 * (np.abs(x[:-4]) + np.abs(x[4:]))
    return d, xc, np.argsort(xc)


def test_bin_statistics_equal_the_bin_by_bin_medians_bit_for_bit():
    rng = np.random.default_rng(4902)
    checked = 0
    for trial in range(600):
        n = int(rng.integers(40, 600))
        x = rng.normal(size=n) * rng.uniform(0.01, 1000) + rng.uniform(-1000, 1000) + np.cumsum(rng.normal(size=n))
        if trial % 3 == 0:
            x = np.round(x, int(rng.integers(0, 3)))  # ties
        n_bins = int(rng.choice([3, 5, 7, 8, 16]))
        if n < 5 * n_bins:
            continue
        parts = _parts(x)
        fast, ref = NZ._bin_stats(*parts, n_bins), NZ._bin_stats_loop(*parts, n_bins)
        assert all(np.array_equal(a, b) for a, b in zip(fast, ref)), trial
        checked += 1
    assert checked > 400


def test_bin_statistics_with_a_nan_take_the_bin_by_bin_route():
    x = np.cumsum(np.random.default_rng(4903).normal(size=200))
    x[57] = np.nan
    fast, ref = NZ._bin_stats(*_parts(x), 8), NZ._bin_stats_loop(*_parts(x), 8)
    assert np.isnan(fast[1]).any()
    assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(fast, ref))
