"""The skid-steer model (soilmodel.steering): straight-line limit, symmetry, an independent quadrature."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from soiltrack.soilmodel import TERRAINS, VEHICLES, DataError, Soil, Vehicle, tractive_force
from soiltrack.soilmodel.steering import (
    SteeringSettings,
    hull_forces_function,
    steady_turn,
    vehicle_parameters,
)

G = 9.81
HEAVY = dataclasses.replace(VEHICLES["heavy"], tread=2.5, cg_height=1.0)
SOILS = [TERRAINS["lete_sand"], TERRAINS["clayey_soil"], TERRAINS["dry_sand"]]


def _soilvec(soil: Soil) -> list[float]:
    return [soil.cohesion, soil.friction_angle, soil.shear_modulus]


@pytest.mark.parametrize("soil", SOILS, ids=lambda s: s.name)
def test_straight_line_limit_is_eq2(soil):
    """Om = v = 0, equal sprockets: the two tracks' shear is Eq. 2 (the library's own function)."""
    slips = np.array([0.003, 0.01, 0.05, 0.2, 0.6])
    w = 2.0 / HEAVY.sprocket_radius
    ref = tractive_force(slips, soil, HEAVY)
    for settings, rtol in ((SteeringSettings(60, 2), 1e-7), (SteeringSettings(), 2e-4)):
        hf = hull_forces_function(settings)
        got = []
        for i in slips:
            Fx, net, W = hf(
                [HEAVY.sprocket_radius * w * (1 - i), 0, 0], [w, w], _soilvec(soil), 0.0, vehicle_parameters(HEAVY)
            )
            got.append(float(Fx[0] + Fx[1]))
            assert abs(float(net[1])) < 1e-6 * HEAVY.weight and abs(float(net[2])) < 1e-6 * HEAVY.weight
            assert float(W[0]) == pytest.approx(HEAVY.weight / 2, rel=1e-12)
        np.testing.assert_allclose(got, ref, rtol=rtol)


def test_mirror_symmetry():
    soil = TERRAINS["lete_sand"]
    a = steady_turn(6.0, 8.0, soil, HEAVY)
    b = steady_turn(8.0, 6.0, soil, HEAVY)
    assert a.converged and b.converged
    assert a.yaw_rate > 0 > b.yaw_rate
    assert b.yaw_rate == pytest.approx(-a.yaw_rate, rel=1e-7)
    assert b.lateral_speed == pytest.approx(-a.lateral_speed, rel=1e-6)
    assert b.forward_speed == pytest.approx(a.forward_speed, rel=1e-9)
    assert b.torque_left == pytest.approx(a.torque_right, rel=1e-7)
    assert b.torque_right == pytest.approx(a.torque_left, rel=1e-7)
    assert b.slip_left == pytest.approx(a.slip_right, rel=1e-7)
    assert b.load_left == pytest.approx(a.load_right, rel=1e-9)


@pytest.mark.parametrize("soil", SOILS, ids=lambda s: s.name)
@pytest.mark.parametrize("ratio", [1.1, 1.5, 2.5])
def test_turn_radius_and_torques_physical(soil, ratio):
    """Left turn: radius beyond the kinematic one, the outer (right) track pulls harder, inner brakes.

    At a moderate speed (0.9 m/s inner belt); near the soil's lateral limit the vehicle slides out
    of the turn (large sideslip) and its radius falls below the kinematic one (docs/physics.md).
    """
    st = steady_turn(3.0, 3.0 * ratio, soil, HEAVY)
    assert abs(st.sideslip_deg) < 10
    assert st.converged
    assert st.radius > st.kinematic_radius > 0
    assert st.torque_right > st.torque_left
    assert st.slip_right > 0 > st.slip_left  # outer slips, inner skids
    assert st.load_right > st.load_left  # load transfer to the outer track


# --- an independent model: plain numpy, shear displacement integrated numerically ---------------
def _numpy_track(u, v, Om, belt, yc, Wk, soil, veh, nx=3000, ny=40):
    """Forces of one track: trapezoid along (from the front), midpoint across, j by cumulative sums."""
    l, b = veh.track_length, veh.track_width
    x = np.linspace(l / 2, -l / 2, nx + 1)  # from the front
    y = yc - b / 2 + b * (np.arange(ny) + 0.5) / ny
    X, Y = np.meshgrid(x, y, indexing="ij")
    t = (l / 2 - X) / belt
    vx = u - Om * Y - belt
    vy = v + Om * X
    gx = vx * np.cos(Om * t) - vy * np.sin(Om * t)  # ground-frame sliding velocity
    gy = vx * np.sin(Om * t) + vy * np.cos(Om * t)
    dt = (x[0] - x[1]) / belt
    jx = np.vstack([np.zeros((1, ny)), np.cumsum(0.5 * (gx[1:] + gx[:-1]) * dt, axis=0)])
    jy = np.vstack([np.zeros((1, ny)), np.cumsum(0.5 * (gy[1:] + gy[:-1]) * dt, axis=0)])
    j = np.hypot(jx, jy)
    p = Wk / (b * l)
    tau = (soil.cohesion + p * math.tan(soil.friction_angle)) * (1 - np.exp(-j / soil.shear_modulus))
    sp = np.hypot(vx, vy) + 1e-300
    wx = np.full(nx + 1, l / nx)
    wx[[0, -1]] *= 0.5
    dA = wx[:, None] * (b / ny)
    fx, fy = -tau * vx / sp * dA, -tau * vy / sp * dA
    return fx.sum(), fy.sum(), (X * fy - Y * fx).sum()


def _newton(res, z0: np.ndarray, tol: float = 1e-13, max_iter: int = 100) -> np.ndarray:
    """A plain damped Newton solve of ``res(z) = 0`` with a forward-difference Jacobian (independent of the
    library's CasADi rootfinder)."""
    z = np.asarray(z0, dtype=float)
    r = np.asarray(res(z), dtype=float)
    for _ in range(max_iter):
        if np.max(np.abs(r)) < tol:
            break
        h = 1e-7 * np.maximum(1.0, np.abs(z))
        J = np.column_stack([(np.asarray(res(z + h[k] * np.eye(z.size)[k])) - r) / h[k] for k in range(z.size)])
        dz = np.linalg.solve(J, -r)
        step = 1.0
        while step > 1e-6:
            r_new = np.asarray(res(z + step * dz), dtype=float)
            if np.max(np.abs(r_new)) < np.max(np.abs(r)):
                break
            step /= 2
        z, r = z + step * dz, r_new
    return z


def _numpy_steady(wl, wr, soil, veh):
    r, B, m, h, mu = veh.sprocket_radius, veh.tread, veh.mass, veh.cg_height, veh.rolling_resistance
    W = m * G

    def res(z):
        u, v, Om = z
        dW = m * u * Om * h / B
        Wl, Wr = W / 2 - dW, W / 2 + dW
        fl = _numpy_track(u, v, Om, r * wl, B / 2, Wl, soil, veh)
        fr = _numpy_track(u, v, Om, r * wr, -B / 2, Wr, soil, veh)
        X = fl[0] + fr[0] - mu * (Wl + Wr)
        N = fl[2] + fr[2] + B / 2 * mu * (Wl - Wr)
        return [(X + m * v * Om) / W, (fl[1] + fr[1] - m * u * Om) / W, N / (W * veh.track_length)]

    z = _newton(res, np.array([0.5 * r * (wl + wr), 0.0, 0.6 * r * (wr - wl) / B]))
    u, v, Om = z
    dW = m * u * Om * h / B
    tl = r * _numpy_track(u, v, Om, r * wl, B / 2, W / 2 - dW, soil, veh)[0]
    tr = r * _numpy_track(u, v, Om, r * wr, -B / 2, W / 2 + dW, soil, veh)[0]
    return math.hypot(u, v) / Om, tl, tr, max(abs(e) for e in res(z))


@pytest.mark.slow
@pytest.mark.parametrize("soil", SOILS, ids=lambda s: s.name)
@pytest.mark.parametrize("ratio", [1.2, 2.0])
def test_steady_turn_against_independent_numpy_quadrature(soil, ratio):
    R, tl, tr, resid = _numpy_steady(6.0, 6.0 * ratio, soil, HEAVY)
    assert resid < 1e-6
    st = steady_turn(6.0, 6.0 * ratio, soil, HEAVY)
    assert st.radius == pytest.approx(R, rel=5e-3)
    assert st.torque_left == pytest.approx(tl, rel=5e-3)
    assert st.torque_right == pytest.approx(tr, rel=5e-3)


@pytest.mark.slow  # long: builds the 200 x 16 reference rule (quick loop: README); CI runs it
@pytest.mark.parametrize("ratio", [1.1, 2.5])
def test_quadrature_converges(ratio):
    """The default rule within 3e-3 of a 200 x 16 one; a finer rule closer."""
    soil = TERRAINS["clayey_soil"]
    ref = steady_turn(6.0, 6.0 * ratio, soil, HEAVY, settings=SteeringSettings(200, 16))
    errs = []
    for s in (SteeringSettings(), SteeringSettings(40, 6)):
        st = steady_turn(6.0, 6.0 * ratio, soil, HEAVY, settings=s)
        errs.append(
            max(
                abs(st.torque_left / ref.torque_left - 1),
                abs(st.torque_right / ref.torque_right - 1),
                abs(st.radius / ref.radius - 1),
            )
        )
    assert errs[0] < 3e-3
    assert errs[1] < errs[0]


def test_vehicle_json_steering_fields(tmp_path):
    d = VEHICLES["heavy"].to_dict()
    d.update({"tread_m": 2.5, "yaw_inertia_kg_m2": 1.0e5, "cg_height_m": 1.1})
    v = Vehicle.from_dict(d)
    assert (v.tread, v.yaw_inertia, v.cg_height) == (2.5, 1.0e5, 1.1)
    assert Vehicle.from_json(v.to_json()).tread == 2.5
    d["tread_m"] = 0.4  # narrower than a track
    with pytest.raises(DataError, match="tread"):
        Vehicle.from_dict(d)
    with pytest.raises(DataError, match="tread_m"):
        steady_turn(6.0, 7.0, TERRAINS["lete_sand"], VEHICLES["heavy"])


@pytest.mark.parametrize("radius", [10.0, -6.0])
def test_slip_limited_motion_reaches_the_slip_and_is_the_motion_inverse(radius):
    """The accelerating turn at which one track runs at a given slip: the motion inverse at that acceleration
    gives back the same sprocket speeds, a little less acceleration gives less slip, a little more gives more."""
    from soiltrack.soilmodel.steering import motion_inverse_function, slip_limited_motion_function
    from soiltrack.soilmodel.threadsafe import call_solver

    soil, u, r, B = TERRAINS["lete_sand"], 1.5, HEAVY.sprocket_radius, HEAVY.tread
    veh = vehicle_parameters(HEAVY)
    Om = u / radius
    for target, right in ((0.2, radius > 0), (-0.2, radius < 0)):  # the outer track driving, the inner braking
        w_guess = (u + Om * B / 2) / r if not right else (u - Om * B / 2) / r  # the free (other) sprocket
        p = np.concatenate([[u, 1 / radius, target, float(right)], _soilvec(soil), veh])
        z, _ = call_solver(slip_limited_motion_function(), [w_guess, 0.0, 0.0], p)
        w_free, v, a = (float(x) for x in np.asarray(z, dtype=float).ravel())
        assert a * target > 0.1  # a real acceleration (driving) or braking, m/s^2
        y = -B / 2 if right else B / 2
        w_fixed = (u - Om * y) / (r * (1 - target))
        slips = []
        for f in (0.98, 1.0, 1.02):
            q = np.concatenate([[u, Om, f * a, f * a / radius], _soilvec(soil), veh])
            z0 = [w_free, w_fixed, v] if right else [w_fixed, w_free, v]
            zz = np.asarray(call_solver(motion_inverse_function(), z0, q)[0], dtype=float).ravel()
            wl, wr = float(zz[0]), float(zz[1])
            w = wr if right else wl
            slips.append(1 - (u - Om * y) / (r * w))
            if f == 1.0:
                assert (wr if not right else wl) == pytest.approx(w_free, rel=1e-8)
                assert float(zz[2]) == pytest.approx(v, rel=1e-6, abs=1e-9)
        assert slips[1] == pytest.approx(target, abs=1e-9)
        assert abs(slips[0]) < abs(target) < abs(slips[2])
