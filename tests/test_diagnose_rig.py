"""Sweeps shaped like a test rig's: zero-slip rows, few points, a soil outside the practical range."""
import math
import os

import numpy as np

from soiltrack.identify import diagnose
from soiltrack.soilmodel import SlipData, Vehicle

HERE = os.path.dirname(os.path.abspath(__file__))
HEAVY = Vehicle.from_json(os.path.join(os.path.dirname(HERE), "examples", "data", "heavy_vehicle.json"))
SLIPS = np.array([0.0, 0.0, 0.02, 0.04, 0.06, 0.08, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.7])


def _fmax(c=1.3e3, phi_deg=31.1, W=329e3, A=2.8):
    return A * c + W * math.tan(math.radians(phi_deg))


def test_a_humped_rig_sweep_with_zero_slip_rows_is_diagnosed():
    # a strain-softening sweep with two rows at zero slip: the plateau check fits the soil on the readings
    # below each trial level, and one of those subsets has a single nonzero slip; that fit is impossible
    # and must count as a failed trial, not stop the diagnosis as bad input (it used to exit 2)
    rng = np.random.default_rng(5)
    jr = SLIPS * 2.8
    shape = (1 - np.exp(-jr / 0.02)) * (1 + 0.6 * np.exp(-jr / 0.3))
    dp = 0.8 * _fmax() * shape - 0.05 * 329e3 + 800.0 * rng.standard_normal(SLIPS.size)
    d = diagnose(SlipData(slip=SLIPS, drawbar_pull=dp, source="rig.csv"), HEAVY)
    assert d.converged and d.verdict == "hump_shear", (d.verdict, d.notes)
    # the gap is 35 x the noise floor: the probability that noise leaves it must say so (it read 0.26, the
    # dispersion taken from the held-out errors of the best candidate, which are misfit, not noise)
    ch = "drawbar_pull_N"
    assert d.holdout_rmse_before[ch] > 10 * d.noise[ch]
    assert d.gap_p_value < 1e-6
