"""Stuck prediction and slip-optimal traction against hand calculations."""

import dataclasses
import math

import numpy as np
import pytest

from soiltrack.planning import slip_optimal, stuck
from soiltrack.soilmodel import TERRAINS, VEHICLES

HEAVY = dataclasses.replace(VEHICLES["heavy"], ground_clearance=0.4)


def F(soil, veh, N, i):
    A = 2 * veh.track_width * veh.track_length
    x = i * veh.track_length / soil.shear_modulus
    return (A * soil.cohesion + N * math.tan(soil.friction_angle)) * (1 - (1 - math.exp(-x)) / x)


def test_spin_threshold_and_slip_at_torque():
    soil = TERRAINS["dry_sand"]
    st = stuck(soil, HEAVY, grade_deg=15, torque=30e3)
    N = HEAVY.weight * math.cos(math.radians(15))
    assert st.spin_thrust_N == pytest.approx(F(soil, HEAVY, N, 0.999), rel=1e-9)
    assert st.spin_torque_Nm == pytest.approx(0.3 * st.spin_thrust_N, rel=1e-12)
    assert not st.stuck and st.spins_at_torque is False
    assert F(soil, HEAVY, N, st.slip_at_torque) == pytest.approx(30e3 / 0.3, rel=1e-9)
    assert stuck(soil, HEAVY, grade_deg=15, torque=60e3).spins_at_torque is True
    assert st.spin_track_speed_m_s == pytest.approx(600e3 / st.spin_thrust_N)
    # clayey soil on 15 deg: the required thrust exceeds what any slip gives
    assert stuck(TERRAINS["clayey_soil"], HEAVY, grade_deg=15).stuck


def test_belly_contact_follows_the_stated_slip_sinkage_law():
    snow = TERRAINS["snow"]
    veh = dataclasses.replace(HEAVY, ground_clearance=1.0)
    st = stuck(snow, veh)
    z0 = st.static_sinkage_m
    p = veh.weight / veh.contact_area
    assert z0 == pytest.approx((p / (snow.k_c / veh.track_width + snow.k_phi)) ** (1 / snow.n), rel=1e-9)
    i = st.belly_slip
    assert 0 < i < 1 and z0 * (1 + i) / (1 - 0.5 * i) == pytest.approx(1.0, rel=1e-9)
    assert stuck(snow, dataclasses.replace(HEAVY, ground_clearance=0.3)).belly_slip == 0.0


def test_slip_optima_are_the_maxima_of_the_hand_curves():
    soil = TERRAINS["lete_sand"]
    opt = slip_optimal(soil, HEAVY, sprocket_speed=10.0)
    N = HEAVY.weight
    k = soil.k_c / HEAVY.track_width + soil.k_phi
    z0 = (N / HEAVY.contact_area / k) ** (1 / soil.n)
    R = 0.05 * N + 2 * HEAVY.track_width * k * z0 ** (soil.n + 1) / (soil.n + 1)
    assert opt.resistance_N == pytest.approx(R, rel=1e-9)
    s = np.linspace(1e-4, 0.99, 200001)
    Fh = np.array([F(soil, HEAVY, N, x) for x in s[::50]])
    sg = s[::50]
    P = (Fh - R) * 0.3 * 10.0 * (1 - sg)
    eta = (Fh - R) * (1 - sg) / Fh
    assert opt.max_drawbar_power_W >= P.max() * (1 - 1e-9)
    assert opt.slip_max_power == pytest.approx(sg[np.argmax(P)], abs=3e-4)
    assert opt.max_efficiency >= eta.max() * (1 - 1e-9)
    assert opt.slip_max_efficiency == pytest.approx(sg[np.argmax(eta)], abs=3e-4)
    assert opt.slip_max_efficiency < opt.slip_max_power
