"""One home for statistics and physics: engines and methods agree, one weighting rule, one load count."""

import numpy as np
import pytest

from soiltrack.identify import fit
from soiltrack.identify.sweep.problem import make_problem, weights
from soiltrack.soilmodel import (
    PRACTICAL_BOUNDS,
    TERRAINS,
    VEHICLES,
    DataError,
    SensorNoise,
    SlipData,
    simulate_slip_sweep,
    tractive_force,
)
from soiltrack.soilmodel.ridge import LOAD_RTOL, distinct_loads, ridge_centre

HEAVY = VEHICLES["heavy"]
LOAM = TERRAINS["sandy_loam"]


@pytest.fixture(scope="module")
def two_load_sweeps():
    noise = SensorNoise(force_rel=0.01, slip_abs=0.0)
    return [
        simulate_slip_sweep(
            HEAVY,
            LOAM,
            normal_loads=[HEAVY.weight, 0.6 * HEAVY.weight],
            slips=np.linspace(0.02, 0.5, 8),
            seed=s,
            noise=noise,
        )
        for s in range(3)
    ]


@pytest.mark.parametrize("method", ["newton", "least-squares"])
def test_ipopt_and_seed_methods_agree(two_load_sweeps, method):
    # measured: parameters within 1.4e-8 standard errors, fitted forces within 2.4e-11 of max |F|, cost 1e-14
    for d in two_load_sweeps:
        a, b = fit(d, HEAVY), fit(d, HEAVY, method=method)
        assert a.success and b.success
        se = np.array([p.stderr for p in a.parameters.values()])
        assert np.all(np.abs(b.theta - a.theta) <= 1e-7 * se), (b.theta - a.theta) / se
        assert np.abs(b.residuals - a.residuals).max() <= 1e-9 * np.abs(d.values).max()
        assert b.cost == pytest.approx(a.cost, rel=1e-10)


def test_ipopt_and_least_squares_agree_cohesion_free(two_load_sweeps):
    for d in two_load_sweeps:
        a, b = fit(d, HEAVY, model="cohesion-free"), fit(d, HEAVY, model="cohesion-free", method="least-squares")
        assert a.success and b.success
        np.testing.assert_allclose(b.theta[1:], a.theta[1:], rtol=1e-8)  # measured: 7e-9


def test_residuals_come_from_the_soilmodel(two_load_sweeps):
    d = two_load_sweeps[0]
    pb = make_problem(d, HEAVY, "full", PRACTICAL_BOUNDS)
    r, rw, J = pb.residuals(LOAM.as_vector())
    F = tractive_force(d.slip, LOAM, HEAVY, normal_load=d.normal_load)
    np.testing.assert_array_equal(r, F - d.values)
    assert J.shape == (d.n_samples, 3)


def test_one_weighting_rule():
    d = simulate_slip_sweep(HEAVY, LOAM, seed=1)
    with pytest.raises(DataError, match="relative weights only"):
        fit(d, HEAVY, sigma="relative", sigma_known=True)
    with pytest.raises(DataError, match="relative weights only"):
        make_problem(d, HEAVY, "full", PRACTICAL_BOUNDS, sigma="relative", sigma_known=True)
    sig, known = weights(d.values, 500.0)
    assert known and np.all(sig == 500.0)
    sig, known = weights(d.values, "relative")
    assert not known and np.all(sig >= 0.01 * np.abs(d.values).max())
    with pytest.raises(DataError, match="finite and > 0"):
        weights(d.values, -1.0, source="x.csv", column="tractive_force_N")


def test_one_load_count_with_one_tolerance():
    W = HEAVY.weight
    assert distinct_loads([W, W * (1 + 0.1 * LOAD_RTOL)]).size == 1
    assert distinct_loads([W, W * (1 + 10 * LOAD_RTOL)]).size == 2
    d = simulate_slip_sweep(HEAVY, LOAM, noise="none")
    near = SlipData(
        slip=d.slip, tractive_force=d.values, normal_load=W * (1 + 0.1 * LOAD_RTOL * (np.arange(d.n_samples) % 2))
    )
    assert near.distinct_loads.size == 1
    res = fit(near, HEAVY)
    assert len(res.normal_loads) == 1 and res.soil is None  # the c-phi ridge, said once
    # the ridge marker is the centre of the feasible ridge at the fitted F_max, whatever the path
    fm = res.combinations[0].value
    c, phi = ridge_centre(fm, W, HEAVY.contact_area, PRACTICAL_BOUNDS)
    np.testing.assert_allclose(res.theta[:2], [c, phi], rtol=1e-12)
    joint = fit(near, HEAVY, effects=["grade"], fixed={"grade.theta_rad": 0.0})
    np.testing.assert_allclose(joint.theta, res.theta, rtol=1e-9)  # measured: 3e-11
