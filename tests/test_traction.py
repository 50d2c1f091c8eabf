"""Physics invariants of the tractive force (Eq. 2 / Eq. 8)."""

import math
from decimal import Decimal, getcontext

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from soiltrack.soilmodel import TERRAINS, VEHICLES, Soil, Vehicle, max_thrust, tractive_force
from soiltrack.soilmodel.traction import thrust_function, tractive_force_sensitivities

HEAVY, LIGHT = VEHICLES["heavy"], VEHICLES["light"]
LETE = TERRAINS["lete_sand"]

soils = st.builds(Soil.from_kpa_deg, st.floats(0, 69), st.floats(6, 45), st.floats(0.006, 0.05))
vehicles = st.builds(
    lambda m, l, b: Vehicle(m, l, b, 0.3, 1.0, 0.05), st.floats(10, 60000), st.floats(0.2, 5), st.floats(0.05, 1)
)


def decimal_force(i: float, soil: Soil, v: Vehicle) -> Decimal:
    """Eq. 2 in 50-digit decimal arithmetic, independent of CasADi."""
    getcontext().prec = 50
    x = Decimal(i) * Decimal(v.track_length) / Decimal(soil.shear_modulus)
    g = 1 - (1 - (-x).exp()) / x
    fmax = Decimal(v.contact_area) * Decimal(soil.cohesion) + Decimal(v.weight) * Decimal(math.tan(soil.friction_angle))
    return fmax * g


@pytest.mark.parametrize("i", [0.001, 0.01, 0.05, 0.2])
def test_matches_independent_high_precision(i):
    F = float(tractive_force(i, LETE, HEAVY))
    ref = decimal_force(i, LETE, HEAVY)
    assert abs((Decimal(F) - ref) / ref) < Decimal("1e-12")


def test_small_slip_series_branch_is_accurate():
    for i in [1e-12, 1e-8, 1e-5, 1e-3, 0.0042, 0.0043, 0.01]:  # both sides of the series switch (x = 0.05)
        F = float(tractive_force(i, LETE, HEAVY))
        ref = decimal_force(i, LETE, HEAVY)
        assert abs((Decimal(F) - ref) / ref) < Decimal("1e-12"), i


def test_zero_slip_is_zero_with_finite_derivative():
    assert float(tractive_force(0.0, LETE, HEAVY)) == 0.0
    i = ca.SX.sym("i")
    f = thrust_function("full")
    args = [LETE.cohesion, LETE.friction_angle, LETE.shear_modulus, HEAVY.weight, HEAVY.track_length, HEAVY.track_width]
    F = f(i, *args)
    dF = ca.Function("d", [i], [ca.jacobian(F, i)])(0.0)
    fmax = max_thrust(LETE, HEAVY)
    assert np.isfinite(float(dF))
    assert float(dF) == pytest.approx(fmax * HEAVY.track_length / (2 * LETE.shear_modulus), rel=1e-12)
    sens = tractive_force_sensitivities(0.0, LETE, HEAVY)
    assert np.all(np.isfinite(sens)) and np.all(sens == 0)


def test_skid_is_odd():
    i = np.array([0.003, 0.02, 0.3])
    assert np.array_equal(tractive_force(-i, LETE, HEAVY), -tractive_force(i, LETE, HEAVY))


@settings(max_examples=60, deadline=None)
@given(soil=soils, vehicle=vehicles)
def test_monotone_bounded_and_limit_at_full_slip(soil, vehicle):
    i = np.linspace(0, 1, 401)
    F = tractive_force(i, soil, vehicle)
    fmax = max_thrust(soil, vehicle)
    assert np.all(np.isfinite(F))
    assert np.all(np.diff(F) > 0)
    assert np.all(F < fmax)
    K_l = soil.shear_modulus / vehicle.track_length
    # F(1) = F_max (1 - K/l (1 - exp(-l/K))): within F_max K/l exp(-l/K) of F_max (1 - K/l)
    assert abs(F[-1] / fmax - (1 - K_l)) <= K_l * math.exp(-1 / K_l) + 1e-12


@settings(max_examples=40, deadline=None)
@given(soil=soils, vehicle=vehicles, i=st.floats(1e-4, 0.95))
def test_cohesion_free_drops_exactly_Ac(soil, vehicle, i):
    full = float(tractive_force(i, soil, vehicle, "full"))
    free = float(tractive_force(i, soil, vehicle, "cohesion-free"))
    g = free / (vehicle.weight * math.tan(soil.friction_angle))
    assert full - free == pytest.approx(vehicle.contact_area * soil.cohesion * g, rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("vehicle", [HEAVY, LIGHT])
def test_ad_sensitivities_match_finite_differences(vehicle):
    i = np.array([0.002, 0.03, 0.1, 0.5])
    soil = TERRAINS["dry_sand"]
    J = tractive_force_sensitivities(i, soil, vehicle)
    p = soil.as_vector()
    h = np.array([1.0, 1e-6, 1e-7])
    for k in range(3):
        up, dn = p.copy(), p.copy()
        up[k] += h[k]
        dn[k] -= h[k]
        fd = (tractive_force(i, Soil(*up), vehicle) - tractive_force(i, Soil(*dn), vehicle)) / (2 * h[k])
        np.testing.assert_allclose(J[:, k], fd, rtol=1e-6)


def test_c_and_phi_columns_are_exactly_proportional_at_one_load():
    """docs/paper.md: c and phi enter only through F_max at one normal load."""
    i = np.linspace(0.005, 0.5, 20)
    J = tractive_force_sensitivities(i, LETE, HEAVY)
    ratio = J[:, 0] / J[:, 1]
    expected = HEAVY.contact_area * math.cos(LETE.friction_angle) ** 2 / HEAVY.weight
    np.testing.assert_allclose(ratio, expected, rtol=1e-12)


def test_closed_form_equals_quadrature_of_shear_integral():
    """F = 2 b * integral_0^l (c + p tan phi) (1 - exp(-i x / K)) dx with uniform p = W / A."""
    soil, v = TERRAINS["sandy_loam"], LIGHT
    p = v.weight / v.contact_area
    nodes, weights = np.polynomial.legendre.leggauss(200)
    for i in [0.001, 0.02, 0.1, 0.6]:
        # composite Gauss-Legendre over 50 panels resolves the boundary layer near x = 0
        edges = np.linspace(0, v.track_length, 51)
        total = 0.0
        for a, b in zip(edges[:-1], edges[1:]):
            x = 0.5 * (b - a) * nodes + 0.5 * (a + b)
            tau = (soil.cohesion + p * math.tan(soil.friction_angle)) * (1 - np.exp(-i * x / soil.shear_modulus))
            total += 0.5 * (b - a) * np.sum(weights * tau)
        assert float(tractive_force(i, soil, v)) == pytest.approx(2 * v.track_width * total, rel=1e-10)


def test_per_sample_normal_load_broadcasts():
    i = np.array([0.05, 0.05])
    W = np.array([HEAVY.weight, 2 * HEAVY.weight])
    F = tractive_force(i, LETE, HEAVY, normal_load=W)
    assert F[1] > F[0]
    assert F[0] == pytest.approx(float(tractive_force(0.05, LETE, HEAVY)), rel=1e-14)


def test_unknown_model_is_refused():
    with pytest.raises(ValueError, match="unknown model"):
        tractive_force(0.1, LETE, HEAVY, model="bogus")


def test_shear_bracket_inverse_round_trip():
    """The inverse (start points of the drive-log fits) is the one bracket's, to about 1e-5."""
    import casadi as ca
    from soiltrack.soilmodel.traction import shear_bracket, shear_bracket_inverse

    y = np.concatenate([[0.0, 1e-7, 1e-3], np.linspace(0.01, 0.999, 300)])
    x = shear_bracket_inverse(y)
    xs = ca.SX.sym("x")
    g = np.asarray(ca.Function("g", [xs], [shear_bracket(xs)]).map(y.size)(x.reshape(1, -1))).ravel()
    assert np.all(np.diff(x) > 0) and x[0] == 0.0
    assert np.allclose(g, y, rtol=1e-5, atol=1e-12)
    assert np.array_equal(shear_bracket_inverse(np.array([1.5, -0.2])), shear_bracket_inverse(np.array([0.999, 0.0])))
