"""The wheel diagnosis: an effect that ends on its bound is inadmissible as a verdict, and the report says why."""

from __future__ import annotations

import math

import pytest

import wheel_oracle as oracle
from soiltrack.identify.wheel import WheelFitOptions
from soiltrack.identify.wheel.diagnosis import diagnose_wheel
from soiltrack.identify.wheel.problem import DEFAULT_WHEEL_BOUNDS, WheelBounds
from soiltrack.soilmodel.rigid_wheel import RigidWheel
from soiltrack.soilmodel.wheel_sweep import WheelSweep

R, B = 0.15, 0.08


@pytest.mark.slow
def test_slip_sinkage_on_its_bound_is_not_the_verdict():
    s, dp, W, z = oracle.sweep(
        [0.05, 0.25, 0.45, 0.7],
        [60.0, 100.0],
        1000.0,
        math.radians(30),
        0.012,
        1.5e6,
        1.1,
        R,
        B,
        s=3.0,
        sd_dp=0.2,
        sd_z=2e-4,
        seed=7,
    )
    data = WheelSweep(slip=s, drawbar_pull=dp, normal_load=W, sinkage=z)
    upper = list(DEFAULT_WHEEL_BOUNDS.upper)
    upper[6] = 0.3  # the truth (s = 3) lies beyond: the fit must end on this bound
    bounds = WheelBounds(lower=DEFAULT_WHEEL_BOUNDS.lower, upper=tuple(upper))
    d = diagnose_wheel(data, RigidWheel(radius=R, width=B), WheelFitOptions(bounds=bounds, fixed={"bekker_kc": 0.0}))
    row = next(r for r in d.ranking if r["effect"] == "slip_sinkage")
    assert row["admissible"] is False
    assert d.verdict != "slip_sinkage"
    assert "inadmissible" in d.report() and "upper bound" in d.report()
    # with room the effect is found (the same data, the default bounds)
    d2 = diagnose_wheel(data, RigidWheel(radius=R, width=B), WheelFitOptions(fixed={"bekker_kc": 0.0}))
    assert d2.verdict == "slip_sinkage"
    assert next(r for r in d2.ranking if r["effect"] == "slip_sinkage")["admissible"] is True
