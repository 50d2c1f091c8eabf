"""Dynamics (Eqs. 1, 3, 4), the quasi-static slip inverse, and the simulator."""

import math

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from soiltrack.soilmodel import (
    EFFECTS,
    SEED_ACTUAL,
    TERRAINS,
    VEHICLES,
    DataError,
    DriveLog,
    SensorNoise,
    SlipData,
    Vehicle,
    dynamics_function,
    max_thrust,
    simulate,
    simulate_drive_log,
    simulate_slip_sweep,
    slip_from_thrust,
    slip_from_thrust_function,
    tractive_force,
    tractive_force_with_effects,
)
from soiltrack.soilmodel.simulation import default_speed_profile, drive_limits

HEAVY, LIGHT = VEHICLES["heavy"], VEHICLES["light"]
SAND = TERRAINS["dry_sand"]
GENTLE = [(0.0, 0.0), (0.5, 0.0), (5.0, 1.0), (8.0, 1.0)]  # a gentle ramp to 1 m/s, then hold


def off_spec(name):
    return {name: {p.name: p.off_value for p in EFFECTS[name].params}}


# --- dynamics -------------------------------------------------------------------------------------------


def test_dynamics_equations_pointwise():
    """The Function implements Eqs. 1, 4 and the thrust balance, checked against the traction module."""
    f = dynamics_function(HEAVY, SEED_ACTUAL)
    r, I, m, W, mu = (HEAVY.sprocket_radius, HEAVY.sprocket_inertia, HEAVY.mass, HEAVY.weight, HEAVY.rolling_resistance)
    for v, w, M in ((2.0, 7.0, 20e3), (0.5, 1.8, 5e4), (3.0, 10.5, -2e3), (1.0, 4.0, 0.0)):
        xdot, slip, F, R, loss = (np.asarray(o, dtype=float).ravel() for o in f([v, w], M))
        i = 1 - v / (r * w)
        assert slip[0] == pytest.approx(i, rel=1e-14, abs=1e-16)
        F_ref = float(tractive_force(i, SEED_ACTUAL, HEAVY))
        assert F[0] == pytest.approx(F_ref, rel=1e-13)
        assert R[0] == W * mu and loss[0] == 0.0
        assert m * xdot[0] == pytest.approx(F_ref - W * mu, rel=1e-12)  # Eq. 1
        assert I * xdot[1] == pytest.approx(M - r * F_ref, rel=1e-12, abs=1e-9)  # thrust balance
    # skid (v > r w): Eq. 4 still, i = 1 - v/(r w) < 0, and F(i) = -F(|i|)
    xdot, slip, F, R, loss = (np.asarray(o, dtype=float).ravel() for o in f([3.0, 9.0], -2e3))
    assert slip[0] == pytest.approx(1 - 3.0 / 2.7, rel=1e-14)
    assert F[0] == pytest.approx(-float(tractive_force(3.0 / 2.7 - 1, SEED_ACTUAL, HEAVY)), rel=1e-12)
    # locked sprocket, vehicle moving: full skid, finite
    assert float(f([1.0, 0.0], 0.0)[1]) == -1.0
    seed = dynamics_function(HEAVY, SEED_ACTUAL, sprocket_equation="seed")
    xdot = np.asarray(seed([2.0, 7.0], 20e3)[0]).ravel()
    F_ref = float(tractive_force(1 - 2.0 / (r * 7.0), SEED_ACTUAL, HEAVY))
    assert I * xdot[1] == pytest.approx(20e3 - (F_ref - W * mu) * r, rel=1e-12)  # Eq. 3 as printed


def test_dynamics_symbolic_soil_and_cache():
    f = dynamics_function(LIGHT)
    g = dynamics_function(LIGHT, SAND)
    assert f is dynamics_function(LIGHT) and g is dynamics_function(LIGHT, SAND, None)
    a = np.asarray(f([0.5, 6.5], 1.0, SAND.as_vector())[0])
    b = np.asarray(g([0.5, 6.5], 1.0)[0])
    assert np.array_equal(a, b)
    with pytest.raises(DataError, match="sprocket_equation"):
        dynamics_function(LIGHT, SAND, sprocket_equation="printed")


@pytest.mark.parametrize(
    "x", [[0.0, 0.0], [0.0, 1e-9], [1e-9, 0.0], [0.5, 0.0], [0.0, 5.0], [-0.3, -4.0], [0.2, -1.0], [1e-300, 1e-300]]
)
def test_dynamics_no_nan_near_standstill(x):
    f = dynamics_function(
        LIGHT,
        SAND,
        {
            "drivetrain_friction": {"tau_c": 0.2, "tau_v": 0.01},
            "grade": 0.1,
            "slip_sinkage": 0.1,
            "speed_resistance": 0.05,
        },
    )
    for M in (0.0, 5.0, -5.0):
        out = np.concatenate([np.asarray(o, dtype=float).ravel() for o in f(x, M)])
        assert np.all(np.isfinite(out))
    out = [np.asarray(o, dtype=float).ravel() for o in dynamics_function(LIGHT, SAND)([0.0, 0.0], 0.0)]
    assert np.all(out[0] == 0.0)  # at rest with no torque: stays at rest


@pytest.mark.parametrize("name", list(EFFECTS))
def test_dynamics_off_equals_nominal_exactly(name):
    f0 = dynamics_function(HEAVY, SEED_ACTUAL)
    f1 = dynamics_function(HEAVY, SEED_ACTUAL, off_spec(name))
    for x, M in (([2.0, 7.0], 2e4), ([0.005, 0.1], 3e3), ([3.0, 9.0], -1e3), ([0.0, 0.0], 0.0)):
        for a, b in zip(f0(x, M), f1(x, M)):
            assert np.array_equal(np.asarray(a), np.asarray(b))


def test_effects_act_on_the_right_terms():
    x, M = [2.0, 7.0], 2e4
    r, m = HEAVY.sprocket_radius, HEAVY.mass
    base = [np.asarray(o, dtype=float).ravel() for o in dynamics_function(HEAVY, SEED_ACTUAL)(x, M)]
    # mass_error: a heavier vehicle accelerates less for the same state
    heavy = [
        np.asarray(o, dtype=float).ravel() for o in dynamics_function(HEAVY, SEED_ACTUAL, {"mass_error": 0.3})(x, M)
    ]
    F13 = float(tractive_force(base[1][0], SEED_ACTUAL, HEAVY, normal_load=1.3 * HEAVY.weight))
    assert heavy[0][0] == pytest.approx((F13 - 1.3 * HEAVY.weight * 0.05) / (1.3 * m), rel=1e-12)
    # radius_error: slip and torque arm use r (1 + eps)
    rad = [
        np.asarray(o, dtype=float).ravel() for o in dynamics_function(HEAVY, SEED_ACTUAL, {"radius_error": 0.03})(x, M)
    ]
    i_eff = 1 - 2.0 / (1.03 * r * 7.0)
    assert rad[1][0] == pytest.approx(i_eff, rel=1e-13)
    assert rad[0][1] * HEAVY.sprocket_inertia == pytest.approx(M - 1.03 * r * rad[2][0], rel=1e-12)
    # drivetrain friction: less torque reaches the sprocket
    dt = [
        np.asarray(o, dtype=float).ravel()
        for o in dynamics_function(HEAVY, SEED_ACTUAL, {"drivetrain_friction": {"tau_c": 300.0, "tau_v": 20.0}})(x, M)
    ]
    assert dt[4][0] == 300.0 + 20.0 * 7.0
    assert dt[0][1] == pytest.approx(base[0][1] - 440.0 / HEAVY.sprocket_inertia, rel=1e-12)


# --- quasi-static slip --------------------------------------------------------------------------------


@given(
    st.floats(-0.97, 0.97),
    st.sampled_from([None, {"pressure_distribution": {"e": 0.3, "alpha": 0.2}}, {"grade": 0.1, "mass_error": 0.2}]),
)
@settings(max_examples=40, deadline=None)
def test_slip_from_thrust_inverts(frac, eff):
    F_top = float(tractive_force_with_effects(0.999, SEED_ACTUAL, HEAVY, eff))
    F = frac * F_top
    s, ok = slip_from_thrust(F, SEED_ACTUAL, HEAVY, eff, return_reachable=True)
    assert ok and abs(s) < 1
    assert float(tractive_force_with_effects(s, SEED_ACTUAL, HEAVY, eff)) == pytest.approx(F, rel=1e-9, abs=1e-6)
    g = slip_from_thrust_function(HEAVY, eff)
    s2 = float(g(F, *SEED_ACTUAL.as_vector(), HEAVY.weight))
    assert s2 == pytest.approx(float(s), rel=1e-7, abs=1e-12)


def test_slip_from_thrust_to_rounding_and_peak_on_the_curve():
    """The multisection inversion is exact to rounding (F at the slip gives the thrust back to 1e-12), many
    thrusts and loads in one call; the peak it reports lies on the curve and no grid point of F exceeds it."""
    F_lim = float(max_thrust(SEED_ACTUAL, HEAVY))
    F = np.linspace(-0.75, 0.75, 25) * F_lim  # below the peak at the lightest load (0.8 W)
    N = np.linspace(0.8, 1.2, 25) * HEAVY.weight
    s, ok = slip_from_thrust(F, SEED_ACTUAL, HEAVY, normal_load=N, return_reachable=True)
    assert ok.all()
    back = np.array(
        [float(tractive_force(si, SEED_ACTUAL, HEAVY, normal_load=ni)) for si, ni in zip(np.abs(s), N)]
    ) * np.sign(s)
    np.testing.assert_allclose(back, F, rtol=1e-12, atol=1e-9 * F_lim)
    grid = np.linspace(0.0, 0.999, 20001)
    Fg = tractive_force(grid, SEED_ACTUAL, HEAVY)
    s_pk, reachable = slip_from_thrust([2 * F_lim], SEED_ACTUAL, HEAVY, return_reachable=True)
    assert not reachable[0]
    F_pk = float(tractive_force(float(s_pk[0]), SEED_ACTUAL, HEAVY))
    assert F_pk >= Fg.max() * (1 - 1e-12)


def test_slip_from_thrust_unreachable_and_hump():
    F_lim = max_thrust(SEED_ACTUAL, HEAVY)
    s, ok = slip_from_thrust([0.0, 0.5 * F_lim, 1.1 * F_lim], SEED_ACTUAL, HEAVY, return_reachable=True)
    assert s[0] == 0.0 and ok.tolist() == [True, True, False] and np.all(np.isfinite(s)) and s[2] < 1
    hump = {"hump_shear": {"drop": 0.4}}
    grid = np.linspace(0.001, 0.9, 2000)
    F = tractive_force_with_effects(grid, SEED_ACTUAL, HEAVY, hump)
    s_pk = grid[np.argmax(F)]
    s, ok = slip_from_thrust(
        [0.5 * F.max(), 0.999 * F.max(), 1.01 * F.max()], SEED_ACTUAL, HEAVY, hump, return_reachable=True
    )
    assert ok.tolist() == [True, True, False]
    assert np.all(s <= s_pk + 1e-3)  # the rising branch
    g = slip_from_thrust_function(HEAVY)
    Fs = ca.MX.sym("F")
    dsdF = ca.Function("d", [Fs], [ca.jacobian(g(Fs, *SEED_ACTUAL.as_vector(), HEAVY.weight), Fs)])
    s1 = float(g(1e5, *SEED_ACTUAL.as_vector(), HEAVY.weight))
    i = ca.SX.sym("i")
    from soiltrack.soilmodel import thrust_with_effects

    dFdi = ca.Function(
        "dF", [i], [ca.jacobian(thrust_with_effects(i, *SEED_ACTUAL.as_vector(), HEAVY.weight, HEAVY), i)]
    )
    assert float(dsdF(1e5)) == pytest.approx(1 / float(dFdi(s1)), rel=1e-8)  # implicit-function derivative


# --- drive-log simulation -----------------------------------------------------------------------------


def test_noise_free_log_satisfies_the_equations():
    """Truth signals satisfy Eqs. 1, 3 (thrust balance), 4; integration checked in integral form."""
    for veh, soil in ((LIGHT, SAND), (HEAVY, TERRAINS["lete_sand"])):
        log, tr = simulate_drive_log(
            veh, soil, noise="none", duration_s=8.0, sample_rate_hz=1000.0, speed_profile=GENTLE, return_truth=True
        )
        r, I, m = veh.sprocket_radius, veh.sprocket_inertia, veh.mass
        W, mu = veh.weight, veh.rolling_resistance
        v, w, M = tr["v"], tr["w"], tr["torque"]
        assert np.array_equal(log.vehicle_speed, v) and np.array_equal(log.sprocket_torque, M)
        moving = v > 0.05
        i = 1 - v[moving] / (r * w[moving])  # Eq. 4
        assert np.allclose(tr["slip"][moving], i, rtol=0, atol=1e-14)
        F = tractive_force(i, soil, veh)  # independent of the dynamics module
        assert np.allclose(m * tr["accel"][moving], F - W * mu, rtol=1e-12, atol=1e-9 * W)  # Eq. 1
        assert np.allclose(I * tr["dw_dt"][moving], M[moving] - r * F, rtol=1e-12, atol=1e-9 * W * r)
        # integral form of (1) + (3): I dw + r m dv = (M - r W mu_r) dt over each ZOH interval, exact up
        # to the integrator's tolerance, whatever the slip transients inside the interval
        h = 1.0 / 1000.0
        k = np.nonzero(moving[:-1] & moving[1:])[0]
        res = I * np.diff(w)[k] + r * m * np.diff(v)[k] - (M[k] - r * W * mu) * h
        scale = r * m * np.max(np.abs(np.diff(v)))
        assert np.max(np.abs(res)) < 1e-6 * scale
        # Eq. 1 over each interval by the trapezoid rule: small except in the short slip transients
        lhs = m * np.diff(v)[k]
        rhs = (
            0.5
            * (
                F[np.searchsorted(np.nonzero(moving)[0], k)]
                + F[np.searchsorted(np.nonzero(moving)[0], k + 1)]
                - 2 * W * mu
            )
            * h
        )
        assert np.median(np.abs(lhs - rhs)) < 1e-5 * np.max(np.abs(F)) * h


def test_seed_sprocket_equation_option():
    log, tr = simulate_drive_log(
        LIGHT,
        SAND,
        noise="none",
        duration_s=6.0,
        sample_rate_hz=200.0,
        speed_profile=GENTLE,
        sprocket_equation="seed",
        return_truth=True,
    )
    r, I, m, h = LIGHT.sprocket_radius, LIGHT.sprocket_inertia, LIGHT.mass, 1 / 200.0
    k = np.nonzero(tr["v"][:-1] > 0.05)[0]
    res = I * np.diff(tr["w"])[k] + r * m * np.diff(tr["v"])[k] - tr["torque"][k] * h  # (1) + printed (3)
    assert np.max(np.abs(res)) < 1e-6 * r * m * np.max(np.abs(np.diff(tr["v"])))
    hold = (tr["time"] > 6.5) if tr["time"][-1] > 6.5 else (tr["time"] > 5.5)
    # the printed Eq. 3 needs (almost) no torque at constant speed - the reason it is not the default
    assert np.max(np.abs(tr["torque"][hold])) < 0.05 * LIGHT.weight * LIGHT.rolling_resistance * r


def test_default_log_has_gentle_and_hard_driving():
    # its speed is not checked here: tests check correctness, never wall-clock time
    log, tr = simulate_drive_log(LIGHT, SAND, seed=0, return_truth=True)
    assert isinstance(log, DriveLog) and log.n_samples == 3001 and log.vehicle_accel is not None
    assert log.time[-1] == pytest.approx(60.0)
    F_lim = max_thrust(SAND, LIGHT)
    frac = tr["thrust"] / F_lim
    assert np.mean(np.abs(frac) < 0.2) > 0.8  # mostly gentle
    assert np.sum(frac > 0.8) >= 5  # hard starts near the traction limit
    lim = drive_limits(LIGHT)
    assert np.all(np.abs(tr["torque"]) <= lim.max_sprocket_torque * (1 + 1e-12))
    assert np.all(np.abs(tr["torque"] * tr["w"]) <= lim.max_power * 1.05)
    assert np.max(np.abs(tr["v"] - tr["v_ref"])[tr["time"] > 45]) < 0.05  # tracks the reference
    for key in ("v", "w", "slip", "thrust", "torque", "accel"):
        assert np.all(np.isfinite(tr[key]))


def test_assumed_limits_when_vehicle_gives_none():
    bare = Vehicle(
        mass=100.0,
        track_length=0.8,
        track_width=0.15,
        sprocket_radius=0.1,
        sprocket_inertia=0.2,
        rolling_resistance=0.06,
    )
    lim = drive_limits(bare)
    assert lim.torque_assumed and lim.power_assumed
    assert lim.max_sprocket_torque == pytest.approx(0.8 * bare.weight * 0.1)
    assert lim.max_power == pytest.approx(1500.0)
    log, tr = simulate_drive_log(bare, SAND, seed=1, duration_s=10.0, return_truth=True)
    assert tr["limits"] == lim and np.all(np.isfinite(log.sprocket_torque))


@pytest.mark.parametrize("name", list(EFFECTS))
@pytest.mark.slow
def test_simulated_log_effect_off_equals_nominal_exactly(name):
    kw = dict(noise="none", duration_s=6.0, sample_rate_hz=50.0, return_truth=True)
    a, ta = simulate_drive_log(HEAVY, SEED_ACTUAL, **kw)
    b, tb = simulate_drive_log(HEAVY, SEED_ACTUAL, effects=off_spec(name), **kw)
    for col in ("sprocket_torque", "sprocket_speed", "vehicle_speed", "vehicle_accel"):
        assert np.array_equal(getattr(a, col), getattr(b, col)), col


def _hold(veh, soil, effects, v=1.0):
    """Mean torque and signals during a constant-speed hold."""
    log, tr = simulate_drive_log(
        veh,
        soil,
        effects=effects,
        noise="none",
        duration_s=20.0,
        sample_rate_hz=50.0,
        speed_profile=[(0, 0), (0.5, 0), (5.0, v), (20.0, v)],
        return_truth=True,
    )
    hold = tr["time"] > 17.0  # the PI integrator has absorbed the unknown extra load by then
    return {k: np.mean(tr[k][hold]) for k in ("torque", "slip", "slip_apparent", "v", "w", "thrust")}


@pytest.mark.slow
def test_effect_signatures_in_drive_logs():
    r, W, mu = LIGHT.sprocket_radius, LIGHT.weight, LIGHT.rolling_resistance
    base = _hold(LIGHT, SAND, None)
    assert base["torque"] == pytest.approx(r * W * mu, rel=1e-4)  # thrust balance: M = r W mu_r
    th = 0.05
    g = _hold(LIGHT, SAND, {"grade": th})
    assert g["torque"] == pytest.approx(r * W * (mu * math.cos(th) + math.sin(th)), rel=1e-4)  # more torque
    d = _hold(LIGHT, SAND, {"drivetrain_friction": {"tau_c": 0.1, "tau_v": 0.01}})
    assert d["torque"] - base["torque"] == pytest.approx(0.1 + 0.01 * d["w"], rel=1e-3)
    s = _hold(LIGHT, SAND, {"speed_resistance": 0.02})
    assert s["torque"] == pytest.approx(r * W * (mu + 0.02 * 1.0), rel=1e-4)
    eps = 0.03
    e = _hold(LIGHT, SAND, {"radius_error": eps})
    # apparent slip (nominal r) = 1 - (1 - i)(1 + eps): offset by about -eps
    assert e["slip_apparent"] - e["slip"] == pytest.approx(-eps * (1 - e["slip"]), rel=1e-6)
    assert e["torque"] == pytest.approx((1 + eps) * r * W * mu, rel=1e-4)  # longer torque arm
    k = _hold(LIGHT, SAND, {"slip_sinkage": 1.0})
    assert k["torque"] > base["torque"] * (1 + 0.5 * base["slip"] / mu)
    assert k["slip"] > base["slip"]
    # mass error: a torque-limited hard start (heavy vehicle on strong clay) accelerates less
    kw = dict(noise="none", duration_s=20.0, return_truth=True)
    clay = TERRAINS["heavy_clay"]
    _, t0 = simulate_drive_log(HEAVY, clay, **kw)
    _, t1 = simulate_drive_log(HEAVY, clay, effects={"mass_error": 0.5}, **kw)
    early = t0["time"] < 3.0
    a0, a1 = np.max(t0["accel"][early]), np.max(t1["accel"][early])
    T_r = drive_limits(HEAVY).max_sprocket_torque / HEAVY.sprocket_radius
    m_eq = HEAVY.mass + HEAVY.sprocket_inertia / HEAVY.sprocket_radius**2
    # rigid-body estimate (T/r - R)/(m + I/r^2) of both, to within the slip dynamics' share
    assert a0 == pytest.approx((T_r - HEAVY.weight * 0.05) / m_eq, rel=0.01)
    assert a1 == pytest.approx((T_r - 1.5 * HEAVY.weight * 0.05) / (m_eq + 0.5 * HEAVY.mass), rel=0.01)
    # on loose sand the light vehicle is traction-limited: a payload barely changes its acceleration
    _, u0 = simulate_drive_log(LIGHT, SAND, **kw)
    _, u1 = simulate_drive_log(LIGHT, SAND, effects={"mass_error": 0.5}, **kw)
    assert np.max(u1["accel"][early]) == pytest.approx(np.max(u0["accel"][early]), rel=0.15)


@pytest.mark.slow
def test_noise_levels_and_seeds():
    noise = SensorNoise()
    a, tr = simulate_drive_log(HEAVY, SEED_ACTUAL, seed=7, return_truth=True)
    b = simulate_drive_log(HEAVY, SEED_ACTUAL, seed=7)
    c = simulate_drive_log(HEAVY, SEED_ACTUAL, seed=8)
    for col in ("sprocket_torque", "sprocket_speed", "vehicle_speed", "vehicle_accel"):
        assert np.array_equal(getattr(a, col), getattr(b, col))
        assert not np.array_equal(getattr(a, col), getattr(c, col))
    lim = drive_limits(HEAVY)
    checks = [
        (a.vehicle_speed - tr["v"], np.full(tr["v"].shape, noise.gnss_speed)),
        (a.vehicle_accel - tr["accel"], np.full(tr["v"].shape, noise.imu_accel)),
        (a.sprocket_speed - tr["w"], np.hypot(noise.encoder_abs, noise.encoder_rel * tr["w"])),
        (
            a.sprocket_torque - tr["torque"],
            np.hypot(noise.torque_fs * lim.max_sprocket_torque, noise.torque_rel * tr["torque"]),
        ),
    ]
    n = tr["v"].size
    for err, sd in checks:
        z = err / sd
        assert abs(np.mean(z)) < 4 / math.sqrt(n)  # unbiased
        assert np.std(z) == pytest.approx(1.0, abs=4 * math.sqrt(0.5 / n))  # at the documented level
    quiet = simulate_drive_log(HEAVY, SEED_ACTUAL, seed=7, noise=SensorNoise.none())
    assert np.array_equal(quiet.vehicle_speed, tr["v"])
    with pytest.raises(DataError):
        SensorNoise(gnss_speed=-1.0)
    with pytest.raises(DataError):
        simulate_drive_log(HEAVY, SEED_ACTUAL, noise="loud")


def test_drive_log_with_effects_and_cohesion_free_model_is_finite():
    eff = {
        "grade": -0.05,
        "speed_resistance": 0.01,
        "slip_sinkage": 0.2,
        "drivetrain_friction": 0.5,
        "radius_error": -0.02,
        "hump_shear": 0.3,
        "pressure_distribution": {"e": 0.2, "alpha": 0.3},
        "mass_error": 0.2,
    }
    log, tr = simulate_drive_log(
        LIGHT, SAND, effects=eff, model="cohesion-free", seed=3, duration_s=20.0, return_truth=True
    )
    for col in log.columns().values():
        assert np.all(np.isfinite(col))
    assert "grade" in log.source and "mass_error" in log.source


# --- sweeps ----------------------------------------------------------------------------------------------


def test_sweep_several_loads_noise_free():
    loads = [0.6 * HEAVY.weight, HEAVY.weight, 1.3 * HEAVY.weight]
    data = simulate_slip_sweep(HEAVY, SEED_ACTUAL, normal_loads=loads, noise="none")
    assert isinstance(data, SlipData) and data.distinct_loads.size == 3
    assert data.n_samples == 3 * 22
    assert np.array_equal(
        data.tractive_force, tractive_force(data.slip, SEED_ACTUAL, HEAVY, normal_load=data.normal_load)
    )
    one = simulate(HEAVY, SEED_ACTUAL, kind="sweep", noise="none", slips=[0.02, 0.05])
    assert one.normal_load is None and one.n_samples == 2


def test_sweep_effects():
    s = np.linspace(0.01, 0.8, 40)
    kw = dict(slips=s, noise="none", return_truth=True)
    d0, t0 = simulate_slip_sweep(HEAVY, SEED_ACTUAL, **kw)
    dh, th = simulate_slip_sweep(HEAVY, SEED_ACTUAL, effects={"hump_shear": 0.4}, **kw)
    k = int(np.argmax(dh.tractive_force))
    assert 0 < k < s.size - 1 and dh.tractive_force[-1] < 0.9 * dh.tractive_force[k]
    dp = simulate_slip_sweep(HEAVY, SEED_ACTUAL, effects={"pressure_distribution": 0.4}, slips=s, noise="none")
    assert dp.tractive_force[0] > d0.tractive_force[0]
    eps = 0.02
    dr, tr = simulate_slip_sweep(HEAVY, SEED_ACTUAL, effects={"radius_error": eps}, **kw)
    assert np.allclose(1 - (1 - tr["slip_true"]) * (1 + eps), s, rtol=0, atol=1e-14)  # measured = apparent
    assert np.allclose(dr.tractive_force, tractive_force(tr["slip_true"], SEED_ACTUAL, HEAVY), rtol=1e-13)
    dk = simulate_slip_sweep(HEAVY, SEED_ACTUAL, effects={"slip_sinkage": 0.1}, slips=s, noise="none")
    assert np.allclose(d0.tractive_force - dk.tractive_force, HEAVY.weight * 0.1 * s, rtol=1e-9)
    dd = simulate_slip_sweep(HEAVY, SEED_ACTUAL, effects={"drivetrain_friction": 500.0}, slips=s, noise="none")
    assert np.array_equal(dd.tractive_force, d0.tractive_force)  # the rig's load cell sees no drivetrain
    for name in EFFECTS:
        do = simulate_slip_sweep(HEAVY, SEED_ACTUAL, effects=off_spec(name), slips=s, noise="none")
        assert np.array_equal(do.tractive_force, d0.tractive_force) and np.array_equal(do.slip, d0.slip)


def test_sweep_noise_and_seed():
    a, t = simulate_slip_sweep(LIGHT, SAND, seed=4, return_truth=True, slips=np.linspace(0.05, 0.6, 400))
    b = simulate_slip_sweep(LIGHT, SAND, seed=4, slips=np.linspace(0.05, 0.6, 400))
    assert np.array_equal(a.tractive_force, b.tractive_force) and np.array_equal(a.slip, b.slip)
    z = (a.tractive_force - t["tractive_force"]) / (0.01 * np.abs(t["tractive_force"]))
    assert np.std(z) == pytest.approx(1.0, abs=0.15)
    assert np.std(a.slip - t["slip"]) == pytest.approx(0.002, rel=0.15)
    assert np.all((a.slip >= 0) & (a.slip < 1))


def test_simulate_dispatch_and_errors():
    log = simulate(LIGHT, SAND, seed=1, duration_s=4.0, sample_rate_hz=25.0)
    assert isinstance(log, DriveLog) and log.n_samples == 101
    with pytest.raises(DataError, match="kind"):
        simulate(LIGHT, SAND, kind="pull")
    with pytest.raises(DataError, match="sweep"):
        simulate(LIGHT, SAND, slips=[0.1])
    with pytest.raises(DataError, match="drive"):
        simulate(LIGHT, SAND, kind="sweep", duration_s=3.0)
    with pytest.raises(DataError, match="slips"):
        simulate_slip_sweep(LIGHT, SAND, slips=[0.1, 1.0])
    with pytest.raises(DataError, match="normal_loads"):
        simulate_slip_sweep(LIGHT, SAND, normal_loads=[-3.0])
    with pytest.raises(DataError, match="unknown effect"):
        simulate(LIGHT, SAND, effects=["wind=3"])
    with pytest.raises(DataError, match="speed_profile"):
        simulate_drive_log(LIGHT, SAND, speed_profile=[1, 2, 3])
    with pytest.raises(DataError, match="duration_s"):
        simulate_drive_log(LIGHT, SAND, duration_s=float("nan"))
    prof = default_speed_profile(HEAVY, 60.0)
    assert prof(np.array([0.0]))[0] == 0.0 and np.max(prof(np.linspace(0, 60, 601))) == pytest.approx(3.0)
