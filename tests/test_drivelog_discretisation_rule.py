"""One discretisation rule for every drive-log fit, and the relaxation rule's curvature term (issue 40).

The check of the held-torque discretisation (both rules fitted, the relaxation fit reported where they
disagree beyond DISCRETISATION_SHIFT_SE) is part of the fit itself: the command line, ``fit(log, vehicle)``,
segment maps and ``fit_many`` report the same fit, and the result says which rule and why.
"""

from __future__ import annotations

import csv
import importlib
import json
import os
import sys

import casadi as ca
import numpy as np
import pytest

from soiltrack.identify import fit, fit_many
from soiltrack.identify.segments import fit_segments
from soiltrack.soilmodel import TERRAINS, VEHICLES, simulate_drive_log, write_csv
from soiltrack.soilmodel.dynamics import held_torque_stencil_expr, held_torque_weight_expr

LIGHT = VEHICLES["light"]
SAND = TERRAINS["lete_sand"]


def _weights(x: float, curvature: float, spread: int = 1) -> np.ndarray:
    s = ca.SX.sym("x")
    w = held_torque_stencil_expr(s, curvature, spread)
    return np.array(ca.Function("w", [s], [ca.vertcat(*w)])(x)).ravel()


def _phi(x: float) -> float:
    s = ca.SX.sym("x")
    return float(ca.Function("phi", [s], [held_torque_weight_expr(s)])(x))


def test_stencil_limits_and_the_cell_mean_reconstruction():
    for x in (0.0, 0.2, 1.0, 5.0, 40.0):
        assert np.sum(_weights(x, 2.0 / 3.0)) == pytest.approx(1.0, abs=1e-14)  # a constant thrust is kept
        p = _phi(x)
        np.testing.assert_allclose(_weights(x, 0.0), [0.0, 1.0 - p, p, 0.0], atol=1e-15)  # the first-order rule
    # slow relaxation: the fourth-order point value from four cell means; exact on a cubic
    c = _weights(0.0, 2.0 / 3.0)
    np.testing.assert_allclose(c, np.array([-1.0, 7.0, 7.0, -1.0]) / 12.0, rtol=1e-12)
    F = lambda t: 2.0 - 3.0 * t + 0.7 * t**2 + 0.4 * t**3  # noqa: E731
    G = lambda t: 2.0 * t - 1.5 * t**2 + 0.7 * t**3 / 3 + 0.1 * t**4  # noqa: E731 - its antiderivative
    means = [G(j) - G(j - 1) for j in range(0, 4)]  # T_{k-1}..T_{k+2} around the sample at t = 1
    assert float(c @ means) == pytest.approx(F(1.0), rel=1e-12)
    assert float(_weights(0.0, 0.0) @ means) != pytest.approx(F(1.0), rel=1e-3)  # the first-order rule is not
    # a wider spread (T_{k-3}, T_k, T_{k+1}, T_{k+4}) reads the same curvature: exact on the cubic too
    wide = [G(j) - G(j - 1) for j in (-2, 1, 2, 5)]
    assert float(_weights(0.0, 2.0 / 3.0, 3) @ wide) == pytest.approx(F(1.0), rel=1e-12)
    # the slip settles at once: the end-point rule
    np.testing.assert_allclose(_weights(1e5, 2.0 / 3.0), [0.0, 1.0, 0.0, 0.0], atol=2e-5)


def _log(seed: int = 3, duration: float = 10.0):
    return simulate_drive_log(LIGHT, SAND, seed=seed, duration_s=duration)


def test_python_fit_runs_the_check_like_the_command_line(tmp_path, capsys):
    """``fit(log, vehicle)`` with no rule compares both and says which it reports and why; the CLI's is the same."""
    from soiltrack.cli import main

    log = _log()
    res = fit(log, LIGHT)
    chk = res.extra["discretisation_check"]
    assert chk["compared"] and chk["reported"] == res.extra["discretisation"]
    assert "standard errors" in chk["reason"]
    path = tmp_path / "log.csv"
    write_csv(log, path)
    capsys.readouterr()
    assert main(["fit", str(path), "--vehicle", "light", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["extra"]["discretisation_check"]["reported"] == chk["reported"]
    assert out["extra"]["max_thrust_N"] == pytest.approx(res.extra["max_thrust_N"], rel=1e-6)


def test_the_result_says_why_the_rules_were_not_compared():
    log = _log()
    cases = {
        "given": ({"discretisation": "relaxation"}, "relaxation", "given"),
        "sample": ({"torque_hold": "sample"}, "end-point", "torque_hold='sample'"),
        "effects": ({"effects": ["grade"], "torque_hold": "zoh"}, "end-point", "effects"),
        "off": ({"discretisation_check": False}, "end-point", "discretisation_check=False"),
    }
    for kw, rule, word in cases.values():
        chk = fit(log, LIGHT, **kw).extra["discretisation_check"]
        assert not chk["compared"] and chk["reported"] == rule and word in chk["reason"]


@pytest.mark.slow  # 2.5 s: the quick loop stays under 90 s; CI runs it
def test_segments_and_fit_many_report_the_fit_s_own_rule(tmp_path):
    """A segment map's rows and a fleet's rows carry the rule of the fit behind them (the fit's check)."""
    log = _log(seed=5, duration=40.0)
    smap = fit_segments(log, LIGHT, "20s")
    assert len(smap.segments) >= 1
    for s in smap.segments:
        assert s.discretisation in ("end-point", "relaxation", "end-point+relaxation")
        assert s.to_dict()["discretisation"] == s.discretisation
    part = log.subset(np.arange(0, 1001))  # the first 20 s: a segment of its own
    alone = fit(part, LIGHT)
    assert alone.extra["discretisation_check"]["compared"]
    out = tmp_path / "fleet.csv"
    (res,) = fit_many([part], LIGHT, out=out, progress=False)
    assert res.extra["discretisation_check"]["reported"] == alone.extra["discretisation_check"]["reported"]
    assert res.extra["max_thrust_N"] == pytest.approx(alone.extra["max_thrust_N"], rel=1e-9)
    with open(out, newline="") as fh:
        (row,) = list(csv.DictReader(fh))
    assert row["discretisation"] == alone.extra["discretisation"]


def _sim():
    bench = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "benchmarks")
    if bench not in sys.path:
        sys.path.insert(0, bench)
    return importlib.import_module("drivelog_independent")


@pytest.mark.slow
def test_curvature_term_removes_the_relaxation_rule_s_fmax_bias(monkeypatch):
    """Noise-free independent hard pulls (1 min, seed 1; a tuning seed), the curvature term from the four
    nearest interval means (spread 1: the fourth-order reconstruction): first-order rule F_max -0.29 %,
    with the curvature term -0.05 % (5 min, seeds 1-2: -0.36/-0.38 % against -0.09/-0.09 %)."""
    from test_drivelog_independent import _drive_log

    sim = _sim()
    (log,) = sim.simulate([1], duration_s=60.0, noise=None)
    F_true, data = log["truth"]["F_max"], _drive_log(log)
    err = {}
    monkeypatch.setattr("soiltrack.identify.drivelog.relaxation.RELAXATION_SPREAD", 1)
    for c in (0.0, 2.0 / 3.0):
        monkeypatch.setattr("soiltrack.identify.drivelog.relaxation.RELAXATION_CURVATURE", c)
        err[c] = 100 * (fit(data, LIGHT, discretisation="relaxation").extra["max_thrust_N"] / F_true - 1)
    assert err[0.0] < -0.2
    assert abs(err[2.0 / 3.0]) < 0.1
