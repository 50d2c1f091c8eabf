"""The independent two-track turning simulator (benchmarks/turning_independent.py) and the library against it.

The simulator imports nothing of soiltrack: its straight steady state must be Eq. 2 restated, its
left and right turns mirror images, and a long constant turn must settle where the library's
``steady_turn`` puts it for the same sprocket speeds (issue 42's acceptance: radius and both
torques within 5 %).
"""

from __future__ import annotations

import ast
import dataclasses
import math
import os
import sys

import numpy as np
import pytest

BENCH = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "benchmarks")
sys.path.insert(0, BENCH)
import turning_independent as ti  # noqa: E402

#: The acceptance's tolerance of the steady turn (issue 42): radius and both torques.
STEADY_TOL = 0.05


def test_the_simulator_imports_nothing_of_soiltrack():
    src = open(os.path.join(BENCH, "turning_independent.py"), encoding="utf-8").read()
    mods = set()
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, ast.Import):
            mods |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            mods.add((node.module or "").split(".")[0])
    assert mods <= {"__future__", "argparse", "json", "math", "dataclasses", "numpy"}, mods


def test_straight_cruise_settles_on_eq2():
    """Driving straight at constant speed, each track's force is Eq. 2 at its slip (noise-free)."""
    veh, soil = ti.Vehicle(), ti.SOILS["lete_sand"]
    drive = dataclasses.replace(ti.Drive(), warmup_s=3.0)
    (log,) = ti.simulate([1], 4.0, soil, veh, grid=ti.Grid(40, 3, 0.01), drive=drive, noise=None, plans=[([], 2.0)])
    tr = log["truth"]
    i = 1 - tr["u"][-1] / (veh.radius * tr["w_left"][-1])
    x = i * veh.length / soil.K
    eq2 = 0.5 * soil.max_thrust(veh) * (1 - (1 - math.exp(-x)) / x)
    assert i > 0
    assert tr["Fx_left"][-1] == pytest.approx(eq2, rel=1e-3)
    assert tr["Fx_left"][-1] == pytest.approx(0.5 * veh.mu_r * veh.weight, rel=1e-3)  # thrust = resistance


@pytest.mark.slow
def test_a_long_turn_settles_on_the_library_steady_turn_and_mirrors():
    """10 m left and right turns held 12 s: mirror images, and the library's steady turn within 5 %."""
    from soiltrack.identify.turning import fit_turning  # noqa: F401  (the package imports)
    from soiltrack.soilmodel import Soil, Vehicle
    from soiltrack.soilmodel.steering import steady_turn

    veh, s = ti.Vehicle(), ti.SOILS["clayey_soil"]
    plans = [([(0.5, 1e3, "turn", R)], 2.0) for R in (10.0, -10.0)]
    drive = dataclasses.replace(ti.Drive(), warmup_s=2.0)
    left, right = ti.simulate([1, 2], 12.0, s, veh, grid=ti.Grid(40, 3, 0.01), drive=drive, noise=None, plans=plans)
    L, R = left["truth"], right["truth"]
    assert L["yaw_rate"][-1] > 0.05
    assert R["yaw_rate"][-1] == pytest.approx(-L["yaw_rate"][-1], rel=1e-6)
    assert R["w_left"][-1] == pytest.approx(L["w_right"][-1], rel=1e-6)
    assert R["torque_left"][-1] == pytest.approx(L["torque_right"][-1], rel=1e-5)
    assert abs(np.diff(L["yaw_rate"][-10:])).max() < 1e-4 * abs(L["yaw_rate"][-1])  # settled
    vehicle = Vehicle(**_vehicle_kwargs(veh))
    soil = Soil(cohesion=s.c, friction_angle=math.radians(s.phi_deg), shear_modulus=s.K)
    t = steady_turn(L["w_left"][-1], L["w_right"][-1], soil, vehicle)
    R_sim = math.hypot(L["u"][-1], L["v"][-1]) / L["yaw_rate"][-1]
    assert t.converged
    assert t.radius == pytest.approx(R_sim, rel=STEADY_TOL)
    assert t.torque_left == pytest.approx(L["torque_left"][-1], rel=STEADY_TOL)
    assert t.torque_right == pytest.approx(L["torque_right"][-1], rel=STEADY_TOL)
    assert t.torque_left < 0 < t.torque_right  # the inner track brakes


def _vehicle_kwargs(v: ti.Vehicle) -> dict:
    return dict(
        mass=v.mass,
        track_length=v.length,
        track_width=v.width,
        sprocket_radius=v.radius,
        sprocket_inertia=v.inertia,
        rolling_resistance=v.mu_r,
        max_sprocket_torque=2 * v.max_torque,
        max_power=2 * v.max_power,
        tread=v.tread,
        yaw_inertia=v.yaw_inertia,
        cg_height=v.cg_height,
    )
