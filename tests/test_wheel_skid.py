"""The rigid wheel at skid: Wong's skid shear displacement down to a locked wheel, bulldozing, skid rows fitted."""

from __future__ import annotations

import math

import numpy as np
import pytest

import wheel_oracle as oracle
from soiltrack.identify.wheel import WheelFitOptions, fit_wheel
from soiltrack.soilmodel.rigid_wheel import RigidWheel
from soiltrack.soilmodel.wheel import WheelSettings, bulldozing_expr, evaluate, wheel_forces_function
from soiltrack.soilmodel.wheel_sweep import WheelSweep

R, B = 0.1, 0.08
C, PHI, K = 1.5e3, math.radians(30.0), 0.01
KC, KPHI, N = 20e3, 1500e3, 1.0
KEQ = KC / B + KPHI


def _skid_forces(i, z, c=C, phi=PHI, K=K, unit_weight=None):
    """Pull, load, torque of a skidding wheel in numpy: the oracle's normal stress, the skid shear written out."""
    th1 = math.acos(1 - z / R)
    thm = (0.4 + 0.15 * i) * th1
    out = np.zeros(3)
    for lo, hi in ((0.0, thm), (thm, th1)):
        th = np.linspace(lo, hi, 4001)
        sig, _ = oracle.stresses(th, i, th1, 0.0, 0.0, K, KEQ, N, R, 0.0, 0.4, 0.15)
        j = (
            R * ((1 + i) * (th1 - th) - (math.sin(th1) - np.sin(th)))
            if i < 0
            else R * ((th1 - th) - (1 - i) * (math.sin(th1) - np.sin(th)))
        )
        tau = np.sign(j) * (c + sig * math.tan(phi)) * (1 - np.exp(-np.abs(j) / K))
        for k, y in enumerate((tau * np.cos(th) - sig * np.sin(th), sig * np.cos(th) + tau * np.sin(th), tau)):
            out[k] += float(np.sum((y[1:] + y[:-1]) * np.diff(th)) / 2)
    dp, wl, tq = R * B * out[0], R * B * out[1], R**2 * B * out[2]
    if unit_weight is not None:
        t = math.tan(phi)
        nq = math.exp(math.pi * t) * math.tan(math.pi / 4 + phi / 2) ** 2
        nc, ng = (nq - 1) / t, 2 * (nq + 1) * t
        kpc, kpg = (nc - t) * math.cos(phi) ** 2, (2 * ng / t + 1) * math.cos(phi) ** 2
        dp -= B * (0.67 * c * z * kpc + 0.5 * z**2 * unit_weight * kpg)
    return dp, wl, tq


def _model(i, z, settings=WheelSettings()):
    f = wheel_forces_function(R, B, 0.0, settings)
    return [float(v) for v in evaluate(f, i, z, C, PHI, K, KC, KPHI, N, 0.0)]


@pytest.mark.parametrize("i", [-1.0, -0.7, -0.2, -0.01])
def test_skid_forces_match_an_independent_computation(i):
    z = 0.02
    dp, wl, tq = _model(i, z)
    ref = _skid_forces(i, z)
    assert dp == pytest.approx(ref[0], rel=2e-3, abs=1e-3)
    assert wl == pytest.approx(ref[1], rel=2e-3)
    assert tq == pytest.approx(ref[2], rel=2e-3, abs=1e-5)


def test_locked_wheel_brakes_and_the_model_is_continuous_at_zero_slip():
    dp, _, tq = _model(-1.0, 0.02)
    assert dp < 0 and tq < 0  # a locked wheel is dragged: the soil pulls back, the brake holds a torque
    below, above = _model(-1e-9, 0.02), _model(1e-9, 0.02)
    np.testing.assert_allclose(below, above, rtol=1e-6, atol=1e-9)
    # the pull rises with the slip from a locked wheel to driving
    pulls = [_model(i, 0.02)[0] for i in (-1.0, -0.5, -0.1, 0.0, 0.2, 0.6)]
    assert np.all(np.diff(pulls) > 0)


def test_bulldozing_matches_the_written_out_form():
    gamma = 1500 * 9.81
    dp = _model(-0.5, 0.03, WheelSettings(bulldozing_unit_weight=gamma))[0]
    assert dp == pytest.approx(_skid_forces(-0.5, 0.03, unit_weight=gamma)[0], rel=2e-3)
    assert float(bulldozing_expr(0.0, C, PHI, B, gamma)) == 0.0


SKID_SLIPS = (-1.0, -0.7, -0.5, -0.3, -0.1, 0.1, 0.3, 0.5, 0.7, 0.9)
BEKKER_HELD = {"bekker_kc": KC, "bekker_kphi": KPHI, "bekker_n": N}


def skid_sweep(seed: int, sd_dp: float = 0.1, sd_z: float = 0.0005) -> WheelSweep:
    """A sweep from a locked wheel to driving at 60 and 90 N, simulated in numpy (sinkage by bisection), with
    reading noise on the pull (N) and the sinkage (m; 0.5 mm, the library's simulated rig's)."""
    rng = np.random.default_rng(seed)
    i = np.tile(np.array(SKID_SLIPS), 2)
    W = np.repeat([60.0, 90.0], len(SKID_SLIPS))
    z, dp = np.empty(i.size), np.empty(i.size)
    for k in range(i.size):
        lo, hi = 1e-6, 0.9 * R
        for _ in range(45):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if _skid_forces(i[k], mid)[1] < W[k] else (lo, mid)
        z[k] = 0.5 * (lo + hi)
        dp[k] = _skid_forces(i[k], z[k])[0]
    return WheelSweep(i, dp + rng.normal(0, sd_dp, dp.size), W, z + rng.normal(0, sd_z, z.size))


@pytest.mark.slow
def test_skid_rows_fit_and_recover_the_soil():
    """Skid and driving rows simulated independently, fitted with Bekker held: the soil within its intervals."""
    fit = fit_wheel(skid_sweep(3), RigidWheel(R, B), WheelFitOptions(fixed=BEKKER_HELD))
    assert fit.success
    for key, true in (("cohesion_kpa", C / 1e3), ("friction_angle_deg", math.degrees(PHI)), ("shear_modulus_m", K)):
        lo, hi = fit.parameters[key].edge_ci95
        assert lo <= true <= hi, (key, fit.parameters[key])
