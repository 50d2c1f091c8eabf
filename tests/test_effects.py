"""Unmodelled effects: nesting (off == nominal, exactly), closed forms vs quadrature, directions."""

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
    EffectSet,
    Soil,
    effect_symbols,
    parse_effects,
    thrust_with_effects,
    tractive_force,
    tractive_force_with_effects,
)
from soiltrack.soilmodel.effects import (
    effective_mass,
    effective_normal_load,
    effective_radius,
    motion_resistance,
    pressure_profile,
    softening_shear,
    torque_loss,
    wong_type_b_shear,
)
from soiltrack.soilmodel.traction import thrust_expr

HEAVY, LIGHT = VEHICLES["heavy"], VEHICLES["light"]
SLIPS = np.array([0.0, 1e-9, 1e-6, 1e-4, 0.003, 0.0248, 0.0344, 0.07, 0.2, 0.5, 0.95, -1e-5, -0.04, -0.6])

soils = st.builds(Soil.from_kpa_deg, st.floats(0, 69), st.floats(6, 45), st.floats(0.006, 0.05))


def off_spec(name):
    """The effect switched on with every parameter at its off value."""
    return {name: {p.name: p.off_value for p in EFFECTS[name].params}}


_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(30)


def quad_force(i, soil, veh, W=None, e=0.0, alpha=0.0, n_w=5, drop=0.0, k_ratio=5.0, model="full"):
    """F = 2 b * integral of (c + p(x) tan phi) s(|i| x) dx by numerical quadrature (independent of CasADi).

    Composite 30-point Gauss-Legendre on panels graded geometrically towards x = 0 (where the shear
    curve varies on the scale K/|i|) merged with 100 uniform panels (for the road-wheel cosine).
    """
    l, b = veh.track_length, veh.track_width
    W = veh.weight if W is None else W
    c = soil.cohesion if model == "full" else 0.0
    K, tphi = soil.shear_modulus, math.tan(soil.friction_angle)
    p_mean = W / (2 * b * l)
    if i == 0:
        return 0.0
    first = min(l / 100, 1e-4 * K / abs(i))
    edges = np.unique(np.concatenate([[0.0], np.geomspace(first, l, 300), np.linspace(0, l, 101)]))
    a, bb = edges[:-1, None], edges[1:, None]
    x = 0.5 * (bb - a) * _GL_NODES + 0.5 * (a + bb)
    p = p_mean * (1 + e * (2 * x / l - 1) + alpha * np.cos(2 * np.pi * n_w * x / l))
    j = abs(i) * x
    shear = -np.expm1(-j / K) * (1 - drop * -np.expm1(-j / (k_ratio * K)))
    val = float(np.sum(0.5 * (bb - a) * _GL_WEIGHTS * (c + p * tphi) * shear))
    return math.copysign(2 * b * val, i)


# --- registry and parsing ------------------------------------------------------------------------------


def test_registry_names_are_the_contract():
    assert list(EFFECTS) == [
        "grade",
        "speed_resistance",
        "slip_sinkage",
        "drivetrain_friction",
        "radius_error",
        "hump_shear",
        "pressure_distribution",
        "mass_error",
    ]
    for name, spec in EFFECTS.items():
        assert spec.name == name
        assert spec.primary in spec.param_names
        for p in spec.params:
            assert p.lower <= p.off_value <= p.upper
    assert EFFECTS["drivetrain_friction"].primary == "tau_c"
    assert EFFECTS["pressure_distribution"].primary == "e"


def test_parse_forms_agree():
    a = parse_effects({"grade": 0.03, "drivetrain_friction": {"tau_c": 100.0, "tau_v": 2.0}})
    b = parse_effects(["grade=0.03", "drivetrain_friction=100", "drivetrain_friction.tau_v=2"])
    c = parse_effects("drivetrain_friction.tau_v=2, grade=0.03,drivetrain_friction.tau_c=100")
    assert a == b == c and hash(a) == hash(b)
    assert a.names == ("grade", "drivetrain_friction")
    assert a.params("drivetrain_friction") == {"tau_c": 100.0, "tau_v": 2.0}
    assert a.params("mass_error") == {"delta": 0.0}  # off -> off values
    assert parse_effects(a) is a
    assert parse_effects(a.to_dict()) == a
    assert parse_effects(None) == EffectSet() == parse_effects([]) == parse_effects({})
    assert not parse_effects(None)
    assert parse_effects({"grade": False, "mass_error": True}).names == ("mass_error",)


def test_parse_defaults_and_vehicle_wheels():
    es = parse_effects(["hump_shear", "pressure_distribution=0.2"])
    assert es.params("hump_shear") == {"drop": 0.0, "k_ratio": 5.0}
    assert es.params("pressure_distribution")["n_w"] is None
    assert es.value("pressure_distribution", "n_w", HEAVY) == 5.0
    assert es.value("pressure_distribution", "n_w", LIGHT) == 4.0
    assert "vehicle" in str(es)


@pytest.mark.parametrize(
    "spec, words",
    [
        ({"gravity": 0.1}, ["unknown effect 'gravity'", "grade", "mass_error"]),
        (["grade.phi=0.1"], ["no parameter 'phi'", "theta_rad"]),
        (["drivetrain_friction.tau=1"], ["tau_c", "tau_v"]),
        (["grade=abc"], ["must be a number"]),
        (["grade=nan"], ["finite"]),
        ({"grade": math.inf}, ["finite"]),
        ({"grade": [0.1]}, ["must be a number"]),
        ({"grade": {"theta_rad": True}}, ["must be a number"]),
        (["grade="], ["missing value"]),
        (["grade=0.1", "grade.theta_rad=0.2"], ["given twice"]),
        ({"pressure_distribution": {"e": 0.7, "alpha": 0.5}}, ["negative"]),
        ({"pressure_distribution": {"n_w": 4.5}}, ["integer"]),
        ({"hump_shear": {"drop": 1.5}}, ["outside its admissible range"]),
        ({"radius_error": -2.0}, ["outside"]),
        (42, ["cannot read effects"]),
        ([3.0], ["must be a string"]),
    ],
)
def test_parse_errors(spec, words):
    with pytest.raises(DataError) as err:
        parse_effects(spec)
    for w in words:
        assert w in str(err.value)


@given(st.dictionaries(st.sampled_from(list(EFFECTS)), st.floats(-0.3, 0.3), max_size=8))
@settings(max_examples=60, deadline=None)
def test_parse_roundtrip(d):
    d = {k: (abs(v) if k in ("hump_shear",) else v) for k, v in d.items()}
    es = parse_effects(d)
    assert parse_effects(es.to_dict()) == es
    assert parse_effects([f"{k}={v!r}" for k, v in d.items()]) == es
    assert set(es.names) == set(d)


# --- nesting: effect off == nominal, exactly ------------------------------------------------------------


@pytest.mark.parametrize("name", list(EFFECTS))
@pytest.mark.parametrize("model", ["full", "cohesion-free"])
def test_thrust_off_equals_nominal_exactly(name, model):
    for veh, soil in ((HEAVY, SEED_ACTUAL), (LIGHT, TERRAINS["dry_sand"])):
        nominal = tractive_force(SLIPS, soil, veh, model=model)
        with_off = tractive_force_with_effects(SLIPS, soil, veh, off_spec(name), model=model)
        assert np.array_equal(nominal, with_off)
        assert tractive_force_with_effects(0.0, soil, veh, off_spec(name), model=model) == 0.0


def test_all_off_together_equals_nominal_exactly():
    spec = {}
    for n in EFFECTS:
        spec.update(off_spec(n))
    for W in (HEAVY.weight, 0.5 * HEAVY.weight):
        assert np.array_equal(
            tractive_force(SLIPS, SEED_ACTUAL, HEAVY, normal_load=W),
            tractive_force_with_effects(SLIPS, SEED_ACTUAL, HEAVY, spec, normal_load=W),
        )
    v = np.array([0.0, 0.003, 0.5, 3.0])
    i = np.array([0.0, 0.1, 0.02, 0.5])
    for vv, ii in zip(v, i):
        R0 = float(motion_resistance(vv, ii, HEAVY, None))
        R1 = float(motion_resistance(vv, ii, HEAVY, spec))
        assert R0 == R1
    assert float(torque_loss(5.0, HEAVY, spec)) == 0.0
    assert float(effective_radius(HEAVY, spec)) == HEAVY.sprocket_radius
    assert float(effective_mass(HEAVY, spec)) == HEAVY.mass
    assert float(effective_normal_load(HEAVY.weight, HEAVY, spec)) == HEAVY.weight


@given(soils, st.floats(-0.99, 0.99), st.sampled_from(list(EFFECTS)))
@settings(max_examples=80, deadline=None)
def test_off_equals_nominal_property(soil, slip, name):
    assert np.array_equal(
        tractive_force(slip, soil, LIGHT), tractive_force_with_effects(slip, soil, LIGHT, off_spec(name))
    )


def test_symbolic_effect_parameters_nest():
    """Identification builds the model with effect parameters as symbols: at 0 it is the nominal model."""
    mapping, vec, labels = effect_symbols(["hump_shear", "pressure_distribution", "grade", "mass_error"], vehicle=HEAVY)
    assert labels == [
        "grade.theta_rad",
        "hump_shear.drop",
        "hump_shear.k_ratio",
        "pressure_distribution.e",
        "pressure_distribution.alpha",
        "mass_error.delta",
    ]  # registry order
    i = ca.SX.sym("i")
    F = thrust_with_effects(i, *SEED_ACTUAL.as_vector(), HEAVY.weight, HEAVY, mapping)
    fn = ca.Function("f", [i, vec], [F])
    F0 = ca.Function(
        "f0", [i], [thrust_expr(i, *SEED_ACTUAL.as_vector(), HEAVY.weight, HEAVY.track_length, HEAVY.track_width)]
    )
    q_off = [0.0, 0.0, 5.0, 0.0, 0.0, 0.0]
    for s in SLIPS:
        assert float(fn(s, q_off)) == float(F0(s))
    # finite derivatives with respect to every effect parameter, including at slip 0
    J = ca.Function("J", [i, vec], [ca.jacobian(F, ca.vertcat(i, vec))])
    for s in (0.0, 1e-7, 0.05):
        assert np.all(np.isfinite(np.asarray(J(s, [0.05, 0.2, 3.0, 0.1, 0.2, 0.1]))))


# --- closed forms vs quadrature --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kw",
    [
        dict(e=0.3),
        dict(e=-0.5),
        dict(alpha=0.4),
        dict(alpha=-0.3, n_w=3),
        dict(e=-0.2, alpha=0.5, n_w=7),
        dict(drop=0.4),
        dict(drop=0.3, k_ratio=0.5),
        dict(drop=0.3, k_ratio=2.0, e=0.2, alpha=0.3),
    ],
)
@pytest.mark.parametrize("model", ["full", "cohesion-free"])
def test_closed_form_matches_quad(kw, model):
    spec = {}
    if "e" in kw or "alpha" in kw:
        spec["pressure_distribution"] = {"e": kw.get("e", 0.0), "alpha": kw.get("alpha", 0.0), "n_w": kw.get("n_w", 5)}
    if "drop" in kw:
        spec["hump_shear"] = {"drop": kw["drop"], "k_ratio": kw.get("k_ratio", 5.0)}
    for veh, soil in ((HEAVY, SEED_ACTUAL), (LIGHT, TERRAINS["clayey_soil"])):
        for i in (1e-7, 1e-4, 0.003, 0.0248, 0.1, 0.5, 0.99, -0.2):
            got = float(tractive_force_with_effects(i, soil, veh, spec, model=model))
            ref = quad_force(i, soil, veh, model=model, **kw)
            assert got == pytest.approx(ref, rel=1e-11, abs=1e-12 * abs(ref) + 1e-300)


@given(
    soils,
    st.floats(1e-6, 0.99),
    st.floats(-0.5, 0.5),
    st.floats(-0.5, 0.5),
    st.integers(1, 12),
    st.floats(0.0, 0.9),
    st.floats(0.1, 50.0),
)
@settings(max_examples=40, deadline=None)
def test_closed_form_matches_quad_property(soil, i, e, alpha, n_w, drop, k_ratio):
    spec = {
        "pressure_distribution": {"e": e, "alpha": alpha, "n_w": n_w},
        "hump_shear": {"drop": drop, "k_ratio": k_ratio},
    }
    got = float(tractive_force_with_effects(i, soil, HEAVY, spec))
    ref = quad_force(i, soil, HEAVY, e=e, alpha=alpha, n_w=n_w, drop=drop, k_ratio=k_ratio)
    assert got == pytest.approx(ref, rel=1e-9)


def test_no_nan_near_zero_slip_and_derivatives():
    spec = {"pressure_distribution": {"e": 0.3, "alpha": 0.2}, "hump_shear": 0.3}
    i = ca.SX.sym("i")
    F = thrust_with_effects(i, *SEED_ACTUAL.as_vector(), HEAVY.weight, HEAVY, spec)
    f = ca.Function("f", [i], [F, ca.jacobian(F, i), ca.hessian(F, i)[0]])
    for s in (0.0, 1e-300, 1e-12, -1e-12, 0.999):
        out = [float(o) for o in f(s)]
        assert all(math.isfinite(o) for o in out)
    F0, dF0, _ = (float(o) for o in f(0.0))
    assert F0 == 0.0
    assert float(f(-1e-15)[1]) == pytest.approx(dF0, rel=1e-12)  # odd: same slope from both sides
    # the small-slip slope: F_max l / (2K) (1 + e/3) for the linear shift (cosine: O(X) at 0), softening adds nothing
    W, tphi = HEAVY.weight, math.tan(SEED_ACTUAL.friction_angle)
    fmax = HEAVY.contact_area * SEED_ACTUAL.cohesion + W * tphi
    slope = (fmax + W * tphi * 0.3 / 3) * HEAVY.track_length / (2 * SEED_ACTUAL.shear_modulus)
    assert dF0 == pytest.approx(slope, rel=1e-12)


# --- directions -----------------------------------------------------------------------------------------


def test_hump_shear_peak_then_drop():
    s = np.linspace(0.001, 0.9, 400)
    F0 = tractive_force(s, SEED_ACTUAL, HEAVY)
    F = tractive_force_with_effects(s, SEED_ACTUAL, HEAVY, {"hump_shear": {"drop": 0.4, "k_ratio": 5.0}})
    assert np.all(np.diff(F0) > 0)  # Janosi-Hanamoto rises monotonically
    k = int(np.argmax(F))
    assert 0 < k < s.size - 1  # interior peak ...
    assert F[-1] < 0.92 * F[k]  # ... then a clear drop
    assert np.all(F <= F0 + 1e-9)  # softening never adds strength
    # residual: the force tends to (1 - drop) of the Janosi-Hanamoto force at large slip
    assert F[-1] / F0[-1] == pytest.approx(0.6, abs=0.05)
    # the point law: peak then residual 1 - drop
    j = np.linspace(0, 50 * SEED_ACTUAL.shear_modulus, 2000)
    tau = softening_shear(j, SEED_ACTUAL.shear_modulus, 0.4, 5.0)
    assert tau.max() > tau[-1] + 0.05 and tau[-1] == pytest.approx(0.6, abs=1e-3)
    assert np.array_equal(softening_shear(j, 0.01, 0.0), -np.expm1(-j / 0.01))


def test_wong_type_b_reference_form():
    K_w = 0.02
    j = np.linspace(0, 0.5, 100001)
    tau = wong_type_b_shear(j, 0.6, K_w)
    assert wong_type_b_shear(K_w, 0.6, K_w) == pytest.approx(1.0, rel=1e-12)
    assert j[np.argmax(tau)] == pytest.approx(K_w, rel=0.1) and 1.0 <= tau.max() < 1.05
    assert tau[-1] == pytest.approx(0.6, rel=1e-6)


def test_pressure_distribution_directions_and_profile():
    x = np.linspace(0, HEAVY.track_length, 2001)
    p = pressure_profile(x, HEAVY, {"pressure_distribution": {"e": 0.3, "alpha": 0.2}})
    assert np.trapezoid(p, x) / HEAVY.track_length == pytest.approx(HEAVY.mean_pressure, rel=1e-6)
    assert p[-1] > p[0]  # e > 0: rear-heavy
    s = np.array([0.002, 0.01, 0.05])
    F0 = tractive_force(s, SEED_ACTUAL, HEAVY)
    rear = tractive_force_with_effects(s, SEED_ACTUAL, HEAVY, {"pressure_distribution": 0.3})
    front = tractive_force_with_effects(s, SEED_ACTUAL, HEAVY, {"pressure_distribution": -0.3})
    assert np.all(rear > F0) and np.all(front < F0)  # rear load meets the larger shear displacement
    big = tractive_force_with_effects(0.99, SEED_ACTUAL, HEAVY, {"pressure_distribution": 0.3})
    assert big == pytest.approx(float(tractive_force(0.99, SEED_ACTUAL, HEAVY)), rel=0.02)  # saturated: same


def test_load_and_resistance_effects_directions():
    W, mu = HEAVY.weight, HEAVY.rolling_resistance
    th = 0.1
    assert float(motion_resistance(2.0, 0.05, HEAVY, {"grade": th})) == pytest.approx(
        W * (mu * math.cos(th) + math.sin(th)), rel=1e-14
    )
    assert float(motion_resistance(2.0, 0.05, HEAVY, {"speed_resistance": 0.01})) == pytest.approx(
        W * (mu + 0.02), rel=1e-14
    )
    assert float(motion_resistance(2.0, 0.05, HEAVY, {"slip_sinkage": 0.2})) == pytest.approx(
        W * (mu + 0.01), rel=1e-14
    )
    assert float(motion_resistance(2.0, 0.05, HEAVY, {"mass_error": 0.1})) == pytest.approx(W * 1.1 * mu, rel=1e-14)
    assert float(torque_loss(4.0, HEAVY, {"drivetrain_friction": {"tau_c": 100.0, "tau_v": 2.0}})) == 108.0
    assert float(effective_radius(HEAVY, {"radius_error": 0.02})) == pytest.approx(0.306, rel=1e-14)
    # grade and payload change the normal load, hence the thrust
    F_grade = float(tractive_force_with_effects(0.05, SEED_ACTUAL, HEAVY, {"grade": th}))
    assert F_grade == pytest.approx(
        float(tractive_force(0.05, SEED_ACTUAL, HEAVY, normal_load=W * math.cos(th))), rel=1e-14
    )
    F_mass = float(tractive_force_with_effects(0.05, SEED_ACTUAL, HEAVY, {"mass_error": 0.2}))
    assert F_mass == pytest.approx(float(tractive_force(0.05, SEED_ACTUAL, HEAVY, normal_load=1.2 * W)), rel=1e-14)
    # standstill: Coulomb-like terms pass smoothly through zero, no NaN
    for v in (0.0, 1e-12, -0.003):
        assert math.isfinite(float(motion_resistance(v, 0.0, HEAVY, {"slip_sinkage": 0.1})))
    assert float(motion_resistance(0.0, 0.0, HEAVY)) == 0.0
