"""The bulk steps of ``fit_many`` and the record copy give what the one-at-a-time steps give (issue 37).

``assess_many`` against ``assess`` item by item, ``repeat_free`` against ``slip_levels``, ``record_with``
against ``dataclasses.replace``: on random data with answers on and off the bounds, one load or several.
"""

import dataclasses

import numpy as np
import pytest

from soiltrack.identify import fit
from soiltrack.identify.estimates.result import record_with
from soiltrack.identify.sweep import compiled_lm
from soiltrack.identify.sweep.plausibility import assess, assess_many
from soiltrack.identify.sweep.problem import make_problem
from soiltrack.identify.sweep.rig import SLIP_REPEAT_TOL, repeat_free, slip_levels
from soiltrack.soilmodel import PRACTICAL_BOUNDS, VEHICLES, SlipData, Soil, tractive_force

HEAVY = VEHICLES["heavy"]
WONG_SLIP = np.array([0.0248, 0.0344, 0.0700])
WONG_FORCE = np.array([207.32e3, 223.81e3, 259.81e3])


def _problems(rng, n_sets: int, n: int, model: str, loads: bool) -> list:
    out = []
    for k in range(n_sets):
        if n == 3:  # Wong's points with noise: phi on its upper bound for most (F_max on a bound)
            s = WONG_SLIP * (1 + rng.uniform(-0.03, 0.03, 3))
            F = WONG_FORCE * (1 + rng.uniform(-0.03, 0.03, 3)) * (1.0 if k % 3 else rng.choice([0.05, 0.1, 2.2, 3.0]))
            W = None
        else:
            soil = Soil(rng.uniform(0, 5e3), rng.uniform(0.15, 0.75), rng.uniform(0.004, 0.06))
            s = np.sort(rng.uniform(0.005, 0.35, n))
            W = HEAVY.weight * rng.choice([0.7, 1.0, 1.3], n) if loads else None
            F = tractive_force(s, soil, HEAVY, normal_load=W) * (1 + 0.02 * rng.standard_normal(n))
        d = SlipData(s, F) if W is None else SlipData(s, F, normal_load=W)
        out.append(make_problem(d, HEAVY, model, PRACTICAL_BOUNDS))
    return out


@pytest.mark.parametrize(
    "n, model, loads",
    [(3, "cohesion-free", False), (3, "full", False), (12, "cohesion-free", False), (12, "full", True)],
)
def test_assess_many_gives_what_assess_gives(n, model, loads):
    rng = np.random.default_rng(37 + n)
    pbs = _problems(rng, 90, n, model, loads)
    sols = compiled_lm.solve_many(pbs)
    P = [pb for pb, s in zip(pbs, sols) if s.certified]
    S = [s for s in sols if s.certified]
    assert len(P) >= 40
    bulk = assess_many(P, S, HEAVY, model, PRACTICAL_BOUNDS)
    one = [
        assess(
            pb.slip,
            pb.force,
            pb.load,
            s.residuals,
            s.theta,
            HEAVY,
            model,
            PRACTICAL_BOUNDS,
            s.curves,
            s.screen,
            s.limit_screen,
        )
        for pb, s in zip(P, S)
    ]
    assert bulk == one
    if n == 3 and model == "cohesion-free":  # the stacked F_max-on-a-bound path was taken, and found something
        said = [w for found, _ in bulk for w in found if "thrust limit F_max" in w]
        assert sum("smallest value" in w for w in said) >= 3 and sum("largest value" in w for w in said) >= 10
        assert any("NOT USABLE: the thrust limit" in w for found, _ in bulk for w in found)  # far beyond a bound


def test_repeat_free_is_slip_levels_without_a_repeat():
    rng = np.random.default_rng(5)
    slips = np.round(rng.uniform(0.0, 0.2, (400, 6)), 3)  # on a 1e-3 grid: gaps near the tolerance
    slips[::7, 1] = slips[::7, 0] + SLIP_REPEAT_TOL  # a gap of exactly the tolerance: a repeat
    free = repeat_free(slips)
    levels = [len(set(slip_levels(row).tolist())) == row.size for row in slips]
    assert free.tolist() == levels
    assert 0 < free.sum() < len(free)


def test_record_with_is_dataclasses_replace():
    d = SlipData(WONG_SLIP, WONG_FORCE)
    res = fit(d, HEAVY, model="cohesion-free")
    _ = res.parameters, res.rank  # statistics computed on the original: not carried over
    a = dataclasses.replace(res, extra={"x": 1}, status="changed")
    b = record_with(res, extra={"x": 1}, status="changed")
    assert type(a) is type(b)
    for f in dataclasses.fields(res):
        va, vb = getattr(a, f.name), getattr(b, f.name)
        assert (va is vb) or (np.array_equal(va, vb) if isinstance(va, np.ndarray) else va == vb), f.name
    assert "_stats" not in b.__dict__ and b.to_dict() == a.to_dict()
    with pytest.raises(TypeError):
        record_with(res, no_such_field=1)
