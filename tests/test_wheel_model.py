"""The rigid wheel (soilmodel/wheel.py) against an independent numpy oracle; its physics and derivatives."""

from __future__ import annotations

import json
import math

import casadi as ca
import numpy as np
import pytest

import wheel_oracle as oracle
from soiltrack.soilmodel import DataError
from soiltrack.soilmodel.rigid_wheel import RigidWheel, read_running_gear
from soiltrack.soilmodel.vehicle import Vehicle
from soiltrack.soilmodel.wheel import (
    WheelSettings,
    evaluate,
    sinkage_from_load_function,
    wheel_expr,
    wheel_forces_function,
)

R, B = 0.058, 0.05
# (c Pa, phi rad, K m, k N/m^(n+2), n): a loose sand, a cohesive loam, a stiff soil with small n
SOILS = [
    (1000.0, math.radians(30), 0.012, 1.55e6, 1.1),
    (4000.0, math.radians(22), 0.02, 0.9e6, 0.7),
    (200.0, math.radians(36), 0.006, 5.0e6, 0.5),
]


def cas(soil, k_c=0.0):
    """The model's soil arguments (c, phi, K, k_c, k_phi, n) of an oracle soil (c, phi, K, k, n)."""
    return soil[0], soil[1], soil[2], k_c, soil[3] - k_c / B, soil[4]


@pytest.mark.parametrize("soil", SOILS)
@pytest.mark.parametrize("h", [0.0, 0.008])
@pytest.mark.parametrize("i,z", [(0.1, 0.012), (0.45, 0.02), (0.85, 0.03)])
def test_forces_match_the_numpy_oracle(soil, h, i, z):
    f = wheel_forces_function(R, B, h)
    got = np.array([float(v) for v in f(i, z, *cas(soil, k_c=2e4), 0.0)])
    ref = np.array(oracle.forces(i, z, *soil, R, B, h))
    scale = np.abs(ref[1])  # the load sets the force scale (the pull may pass through zero)
    assert np.all(np.abs(got - ref) <= 2e-4 * scale), (got, ref)


def test_slip_sinkage_effect_matches_the_oracle():
    soil = SOILS[0]
    got = np.array([float(v) for v in wheel_forces_function(R, B)(0.6, 0.02, *cas(soil), 1.5)])
    ref = np.array(oracle.forces(0.6, 0.02, *soil, R, B, s=1.5))
    assert np.all(np.abs(got - ref) <= 2e-4 * abs(ref[1]))
    plain = np.array([float(v) for v in wheel_forces_function(R, B)(0.6, 0.02, *cas(soil), 0.0)])
    assert got[1] < 0.7 * plain[1]  # stresses divided by 1 + 1.5 * 0.6 = 1.9


def test_more_nodes_converge_to_the_oracle():
    soil = SOILS[2]  # n = 0.5: the root singularity at theta_1 is the hardest case
    ref = np.array(oracle.forces(0.5, 0.02, *soil, R, B))
    err = []
    for nodes in (12, 48, 200):
        f = wheel_forces_function(R, B, 0.0, WheelSettings(nodes=nodes))
        err.append(np.max(np.abs(np.array([float(v) for v in f(0.5, 0.02, *cas(soil), 0.0)]) - ref) / abs(ref[1])))
    assert err[0] > err[1] > err[2]
    assert err[2] < 1e-6


@pytest.mark.parametrize("soil", SOILS)
@pytest.mark.parametrize("W", [10.0, 25.0])
def test_pull_rises_with_slip_at_a_given_load(soil, W):
    # (at a sinkage beyond about half the radius theta_m's forward shift can make the pull peak earlier)
    i = np.linspace(0.0, 0.95, 40)
    (z,) = evaluate(sinkage_from_load_function(R, B), i, W, *cas(soil), 0.0)
    assert np.all(z < 0.5 * R)
    dp, wl, tq = evaluate(wheel_forces_function(R, B), i, z, *cas(soil), 0.0)
    assert np.all(np.diff(dp) > 0)
    assert z[-1] > z[0]  # theta_m moves forward: at full slip the same load needs more sinkage
    assert np.all(tq > 0)
    assert np.allclose(wl, W, rtol=1e-9)


def test_pull_at_zero_slip_is_the_rolling_resistance_side():
    # with no slip the shear is small and the normal stress's horizontal part (compaction) dominates
    dp, _, _ = evaluate(wheel_forces_function(R, B), 0.0, 0.025, 0.0, math.radians(30), 0.012, 0.0, 1.5e6, 1.1, 0.0)
    assert dp < 0


def test_grousers_raise_the_pull():
    soil = SOILS[0]
    smooth = float(wheel_forces_function(R, B, 0.0)(0.3, 0.02, *cas(soil), 0.0)[0])
    grousered = float(wheel_forces_function(R, B, 0.01)(0.3, 0.02, *cas(soil), 0.0)[0])
    assert grousered > smooth


@pytest.mark.parametrize("soil", SOILS)
@pytest.mark.parametrize("W", [10.0, 25.0, 60.0])
def test_sinkage_from_load_balances_the_load(soil, W):
    z = float(sinkage_from_load_function(R, B)(0.3, W, *cas(soil), 0.0))
    assert 0 < z < R
    _, wl, _ = (float(v) for v in wheel_forces_function(R, B)(0.3, z, *cas(soil), 0.0))
    assert wl == pytest.approx(W, rel=1e-9)
    assert z == pytest.approx(oracle.sinkage(0.3, W, *soil, R, B), rel=1e-3)


def test_sinkage_grows_with_load_and_with_slip_sinkage():
    soil = SOILS[0]
    fn = sinkage_from_load_function(R, B)
    (z,) = evaluate(fn, 0.5, np.array([10.0, 20.0, 40.0]), *cas(soil), 0.0)
    assert np.all(np.diff(z) > 0)
    (zs,) = evaluate(fn, np.array([0.1, 0.5, 0.9]), 20.0, *cas(soil), 2.0)
    assert np.all(np.diff(zs) > 0)


def test_derivatives_match_finite_differences():
    names = ["i", "z", "c", "phi", "K", "k_c", "k_phi", "n", "s"]
    x0 = np.array([0.4, 0.02, 1500.0, 0.5, 0.012, 2e4, 1.5e6, 0.9, 0.3])
    xs = ca.SX.sym("x", 9)
    out = ca.vertcat(*wheel_expr(*[xs[q] for q in range(8)], R, B, 0.005, slip_sinkage=xs[8]))
    f = ca.Function("f", [xs], [out])
    J = np.asarray(ca.Function("J", [xs], [ca.jacobian(out, xs)])(x0))
    for k, name in enumerate(names):
        dx = 1e-6 * max(abs(x0[k]), 1e-3)
        e = np.zeros(9)
        e[k] = dx
        fd = (np.asarray(f(x0 + e)) - np.asarray(f(x0 - e))).ravel() / (2 * dx)
        assert np.allclose(J[:, k], fd, rtol=1e-5, atol=1e-6 * np.abs(J).max()), name


def test_derivative_of_solved_sinkage_matches_finite_differences():
    fn = sinkage_from_load_function(R, B)
    xs = ca.MX.sym("x", 9)
    z = fn(*[xs[q] for q in range(9)])
    x0 = np.array([0.4, 25.0, 1500, 0.5, 0.012, 2e4, 1.5e6, 0.9, 0.3])
    J = np.asarray(ca.Function("J", [xs], [ca.jacobian(z, xs)])(x0)).ravel()
    for k in range(9):
        dx = 1e-6 * max(abs(x0[k]), 1e-3)
        e = np.zeros(9)
        e[k] = dx
        fd = (float(fn(*(x0 + e))) - float(fn(*(x0 - e)))) / (2 * dx)
        assert fd == pytest.approx(J[k], rel=1e-4, abs=1e-12), k


def test_settings_are_checked():
    with pytest.raises(DataError):
        WheelSettings(c1=0.9, c2=0.2)
    with pytest.raises(DataError):
        WheelSettings(nodes=1)
    s = WheelSettings(c1=0.3, c2=0.2)
    a = float(wheel_forces_function(R, B, 0.0, s)(0.5, 0.02, *cas(SOILS[0]), 0.0)[0])
    ref = oracle.forces(0.5, 0.02, *SOILS[0], R, B, c1=0.3, c2=0.2)[0]
    assert a == pytest.approx(ref, rel=1e-3)


def test_running_gear_json(tmp_path):
    p = tmp_path / "w.json"
    p.write_text(
        json.dumps(
            {
                "running_gear": "rigid_wheel",
                "wheel_radius_m": 0.058,
                "wheel_width_m": 0.05,
                "grouser_height_m": 0.005,
            }
        )
    )
    w = read_running_gear(str(p))
    assert isinstance(w, RigidWheel) and w.shear_radius == pytest.approx(0.063)
    assert isinstance(read_running_gear(RigidWheel(0.1, 0.05).to_json()), RigidWheel)
    v = read_running_gear(
        json.dumps(
            {
                "mass_kg": 30,
                "track_length_m": 0.5,
                "track_width_m": 0.1,
                "sprocket_radius_m": 0.08,
                "sprocket_inertia_kg_m2": 0.05,
                "rolling_resistance": 0.05,
            }
        )
    )
    assert isinstance(v, Vehicle)
    with pytest.raises(DataError) as e:
        read_running_gear(
            json.dumps({"running_gear": "rigid_wheel", "wheel_radius_m": 0.058, "wheel_width_m": 0.05, "mass_kg": 3})
        )
    assert e.value.column == "mass_kg"
    with pytest.raises(DataError) as e:
        read_running_gear(json.dumps({"running_gear": "rigid_wheel", "wheel_width_m": 0.05}))
    assert e.value.column == "wheel_radius_m"
    with pytest.raises(DataError) as e:
        read_running_gear(json.dumps({"running_gear": "legs", "wheel_width_m": 0.05}))
    assert e.value.column == "running_gear"
