"""Grousers beyond the shear radius: Bekker's side-shear multipliers (soilmodel/grousers.py).

The oracle (tests/wheel_oracle.py) writes the grousered shear strength out in numpy on its own
trapezoid grid; the model must match it, reduce exactly to the smooth wheel at h = 0, give more
thrust with taller grousers, and a fit with the grousers held must recover the simulated soil.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import wheel_oracle as oracle
from soiltrack.identify.wheel import WheelFitOptions, fit_wheel
from soiltrack.soilmodel.grousers import grouser_factors_expr
from soiltrack.soilmodel.rigid_wheel import RigidWheel
from soiltrack.soilmodel.wheel import WheelSettings, wheel_forces_function
from soiltrack.soilmodel.wheel_sweep import WheelSweep

R, B = 0.15, 0.08
SOIL = (1000.0, math.radians(30.0), 0.012, 0.0, 1.5e6, 1.1)  # c, phi, K, k_c, k_phi, n


def _row(h, i=0.3, z=0.02, settings=None):
    f = wheel_forces_function(R, B, h) if settings is None else wheel_forces_function(R, B, h, settings)
    return np.array([float(v) for v in f(i, z, *SOIL, 0.0)])


def test_factors_are_exactly_one_without_grousers_and_bekkers_form_with():
    assert grouser_factors_expr(0.0, B) == (1.0, 1.0)
    fc, fphi = grouser_factors_expr(0.01, B)
    x = 0.01 / B
    assert fc == pytest.approx(1 + 2 * x, rel=1e-15)
    assert fphi == pytest.approx(1 + 0.64 * x * math.atan(1 / x), rel=1e-14)


def test_zero_height_is_exactly_the_smooth_wheel():
    smooth = _row(0.0, settings=WheelSettings(grouser_model="shear_radius"))
    assert np.array_equal(_row(0.0), smooth)  # no grouser term at all: the same numbers, bit for bit
    assert np.allclose(_row(1e-12), smooth, rtol=1e-9, atol=0.0)  # and continuous as h -> 0


def test_thrust_and_torque_increase_with_the_grouser_height():
    pulls = [_row(h)[0] for h in (0.0, 0.003, 0.006, 0.012, 0.024)]
    assert all(b > a for a, b in zip(pulls, pulls[1:])), pulls
    # beyond the shear radius: more than the rescaled K alone
    assert _row(0.01)[0] > _row(0.01, settings=WheelSettings(grouser_model="shear_radius"))[0]


@pytest.mark.parametrize("i,z", [(0.1, 0.012), (0.5, 0.025), (0.85, 0.03)])
def test_grousered_forces_match_the_oracle(i, z):
    got = _row(0.01, i=i, z=z)
    c, phi, K, _, k_phi, n = SOIL
    ref = np.array(oracle.forces(i, z, c, phi, K, k_phi, n, R, B, h=0.01))
    assert np.all(np.abs(got - ref) <= 2e-4 * abs(ref[1])), (got, ref)


@pytest.mark.slow
def test_a_grousered_sweep_is_recovered_with_the_grousers_held():
    c, phi, K, _, k_phi, n = SOIL
    h = 0.012
    s, dp, W, z = oracle.sweep(
        [0.05, 0.15, 0.3, 0.5, 0.7], [60.0, 100.0], c, phi, K, k_phi, n, R, B, h=h, sd_dp=0.3, sd_z=3e-4, seed=4
    )
    data = WheelSweep(slip=s, drawbar_pull=dp, normal_load=W, sinkage=z)
    res = fit_wheel(data, RigidWheel(radius=R, width=B, grouser_height=h), WheelFitOptions(fixed={"bekker_kc": 0.0}))
    assert res.success
    for key, v in (("cohesion_kpa", c / 1e3), ("friction_angle_deg", math.degrees(phi)), ("shear_modulus_m", K)):
        e = res.parameters[key]
        assert e.edge_ci95[0] <= v <= e.edge_ci95[1], (key, e.edge_ci95, v)
    # the shear radius alone books the grousers' side thrust as soil strength
    old = fit_wheel(
        data,
        RigidWheel(radius=R, width=B, grouser_height=h),
        WheelFitOptions(fixed={"bekker_kc": 0.0}, settings=WheelSettings(grouser_model="shear_radius")),
    )

    def strength(r):  # the shear strength at 20 kPa, Pa
        p = r.parameters
        return p["cohesion_kpa"].value * 1e3 + 20e3 * math.tan(math.radians(p["friction_angle_deg"].value))

    assert strength(old) > 1.1 * strength(res)


@pytest.mark.slow
def test_a_grousered_wheel_alone_with_c_and_phi_fitted_is_a_poor_fit_naming_the_spacing():
    """The grouser spacing is not modelled (docs/physics.md): one grousered wheel's fit with c and phi both free
    books whatever the grousers do beyond Bekker's term as soil strength, and says so; phi held, it does not."""
    c, phi, K, _, k_phi, n = SOIL
    s, dp, W, z = oracle.sweep(
        [0.05, 0.15, 0.3, 0.5, 0.7], [60.0, 100.0], c, phi, K, k_phi, n, R, B, h=0.012, sd_dp=0.3, sd_z=3e-4, seed=5
    )
    data = WheelSweep(slip=s, drawbar_pull=dp, normal_load=W, sinkage=z)
    wheel = RigidWheel(radius=R, width=B, grouser_height=0.012)
    res = fit_wheel(data, wheel, WheelFitOptions(fixed={"bekker_kc": 0.0}))
    assert res.success and res.outcome == "poor_fit"
    assert "grouser spacing is not modelled" in res.fit_outcome.reason and "h = 12 mm" in res.fit_outcome.reason
    assert json.loads(res.to_json())["outcome"] == "poor_fit"
    held = fit_wheel(data, wheel, WheelFitOptions(fixed={"bekker_kc": 0.0, "friction_angle": phi}))
    assert held.outcome == "usable", held.fit_outcome.reason
    smooth = fit_wheel(data, RigidWheel(radius=R, width=B), WheelFitOptions(fixed={"bekker_kc": 0.0}))
    assert "grouser" not in (smooth.fit_outcome.reason or "")
