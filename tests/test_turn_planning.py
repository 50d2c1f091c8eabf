"""Turns in planning: p_turn_feasible from the soil's uncertainty; ROUTE.json patches with radius_m."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from soiltrack.cli import main
from soiltrack.identify import fit
from soiltrack.planning.turning import min_turn_radius, turn_margin, turn_probability
from soiltrack.planning.uncertainty import SoilUncertainty
from soiltrack.soilmodel import PRACTICAL_BOUNDS, TERRAINS, VEHICLES, Soil, simulate_slip_sweep

HEAVY = dataclasses.replace(VEHICLES["heavy"], tread=2.5, cg_height=1.0)
SAND = TERRAINS["lete_sand"]


def _uncertain(soil: Soil, rel: float) -> SoilUncertainty:
    """c, phi, K with independent relative standard errors ``rel`` around ``soil``."""
    mean = np.array([soil.cohesion, soil.friction_angle, soil.shear_modulus])
    return SoilUncertainty(
        "parameters",
        "full",
        ("cohesion", "friction_angle", "shear_modulus"),
        mean,
        np.diag((rel * mean) ** 2),
        HEAVY.weight,
        PRACTICAL_BOUNDS,
        "test: independent relative errors",
        HEAVY.contact_area,
    )


def test_p_turn_feasible_inside_outside_and_monotone():
    unc = _uncertain(SAND, 0.15)
    r0 = min_turn_radius(HEAVY, SAND, 2.0)
    assert r0 is not None and r0 > 0.5 * HEAVY.tread
    radii = [0.55 * r0, 0.9 * r0, r0, 1.1 * r0, 4 * r0]
    ps = [turn_probability(HEAVY, unc, radius_m=R, speed_m_s=2.0, n_samples=200).p for R in radii]
    assert ps[0] <= 0.02 and ps[-1] >= 0.98  # far outside ~0, far inside ~1
    assert all(a <= b for a, b in zip(ps, ps[1:]))  # monotone (same samples at every radius)
    assert 0.1 < ps[2] < 0.9  # at the mean soil's limit the soil's uncertainty matters
    right = turn_probability(HEAVY, unc, radius_m=-r0, speed_m_s=2.0, n_samples=200)  # mirror
    assert right.p == pytest.approx(ps[2], abs=1e-12)
    pr = turn_probability(HEAVY, unc, radius_m=1.1 * r0, speed_m_s=2.0, n_samples=200)
    assert pr.stderr == pytest.approx(math.sqrt(pr.p * (1 - pr.p) / 200))
    assert sum(pr.limited_by.values()) == pytest.approx(1 - pr.p) and "Monte Carlo" in pr.method
    m = turn_margin(HEAVY, SAND, radius_m=4 * r0, speed_m_s=2.0)
    assert m.probability is None and m.to_dict()["p_turn_feasible"] is None
    assert "without uncertainty" in m.to_dict()["p_turn_method"]


def test_margin_cli_p_turn_feasible_from_fit(tmp_path, capsys):
    data = simulate_slip_sweep(VEHICLES["heavy"], Soil.from_kpa_deg(1.3, 31.1, 0.012), seed=5)
    fj = tmp_path / "fit.json"
    fj.write_text(fit(data, VEHICLES["heavy"]).to_json())
    d = HEAVY.to_dict()
    d.pop("name", None)
    vj = tmp_path / "veh.json"
    vj.write_text(json.dumps(d))
    out = {}
    for R in ("10", "1.6"):
        rc = main(["margin", "--vehicle", str(vj), "--fit", str(fj), "--turn-radius", R, "--speed", "2", "--json"])
        out[R] = (rc, json.loads(capsys.readouterr().out))
    rc, js = out["10"]
    assert rc == 0 and js["turn_feasible"] is True and js["p_turn_feasible"] >= 0.98
    assert js["p_turn_samples"] > 0 and "Monte Carlo" in js["p_turn_method"]
    rc, js = out["1.6"]
    assert rc == 1 and js["turn_feasible"] is False and js["p_turn_feasible"] <= 0.02
    assert js["p_turn_limited_by"]["soil"] >= 0.98
