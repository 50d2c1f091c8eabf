"""Issue 39 item 9: the wheel fit's curve follows the per-row model points (it was drawn at the median load
with a straight-line sinkage trend, far from them), and the planning figures are written."""

import numpy as np
import pytest

from soiltrack.soilmodel.wheel_sweep import WheelSweep
from soiltrack.wheel_plots import _curve_inputs


def test_wheel_curve_runs_along_each_slip_levels_mean_load_and_sinkage():
    slip = np.array([0.23, 0.2301, 0.2299, 0.5, 0.5002, 0.75, 0.7499, 0.9, 0.9])
    W = np.array([24.0, 25.0, 26.0, 22.0, 24.0, 21.6, 25.0, 26.1, 25.9])
    z = np.array([0.017, 0.0175, 0.019, 0.0225, 0.023, 0.025, 0.0256, 0.0259, 0.0257])
    data = WheelSweep(slip=slip, drawbar_pull=np.ones_like(slip), normal_load=W, sinkage=z)
    i, Wc, zc, how = _curve_inputs(data)
    assert "4 slip levels" in how  # repeats within 1e-3 of slip are one level
    for lo, hi in ((0, 3), (3, 5), (5, 7), (7, 9)):
        s0 = slip[lo:hi].mean()
        assert np.interp(s0, i, Wc) == pytest.approx(W[lo:hi].mean(), rel=1e-3)
        assert np.interp(s0, i, zc) == pytest.approx(z[lo:hi].mean(), rel=1e-3)
    assert i[0] == pytest.approx(slip[:3].mean()) and i[-1] == pytest.approx(0.9)
